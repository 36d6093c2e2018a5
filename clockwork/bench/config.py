"""The benchmark's configuration: master families, steps, tolerances, peers; rows and their timing."""

from __future__ import annotations

import math
import statistics
import time
from dataclasses import dataclass, field
from pathlib import Path


from ..engine.settings import MasterSettings
from ..physics import analytic


ROOT = Path(__file__).resolve().parents[2]


RUN_TOOL = Path(__file__).resolve().parent / "peer_tool.py"


DAY = analytic.SECONDS_PER_DAY


DEG = math.pi / 180.0


TWO_PI = 2.0 * math.pi


TARGET_S_PER_DAY = 1e-3  # steady-state rate error the bench targets


DEFAULT_FAMILY = "GS, ZOH, events located (default)"


PEER_MODULES = {"fmpy": "fmpy.ssp.simulation", "libcosim": "libcosimpy", "ecos": "ecospy"}


GRASSHOPPER_LINKS = ["pendulum.phi -> escapement.phi", "pendulum.w -> escapement.w",
                     "escapement.tau -> pendulum.tau_escapement"]


DRAG_LINKS = ["pendulum.w -> drag.w", "drag.tau -> pendulum.tau_drag"]


VIBRATION_LINKS = ["pendulum.phi -> vibration.a1", "vibration.tau -> pendulum.tau_coupling"]


def atol(rtol: float) -> float:
    # Angles ~0.1 rad, speeds ~0.3 rad/s, a2 ~1e-3 rad: two decades below rtol.
    return rtol * 1e-2


@dataclass(frozen=True)
class Family:
    """A master configuration; `points` are (step s, FMU rtol, extra settings)."""

    name: str
    settings: dict = field(default_factory=dict)
    points: tuple = ()
    split: bool = False  # damping in a Drag FMU (Pendulum Q = 0) instead of the Pendulum


def grid(steps, rtols, **extra) -> tuple:
    return tuple((h, r, dict(extra)) for h in steps for r in rtols)


@dataclass
class BenchConfig:
    name: str = "full"
    steady_points: tuple = ("fig4a_5deg", "fig4a_7deg", "fig2b_chronometer")
    steady_families: tuple = ()
    shooting_tolerance_s_per_day: float = 1e-4  # find_steady_state's stop on the rate change
    long_run_tolerances: tuple = (1e-3, 1e-4, 1e-5, 1e-6, 1e-7)  # s/day change of the period between periods
    long_run_max_periods: int = 20000
    scipy_long_run_tolerances: tuple = (1e-5, 1e-6)  # the same criterion for a monolithic plain run
    scipy_rtols: tuple = (1e-6, 1e-8, 1e-10, 1e-11)
    peer_tools: tuple = ("fmpy", "libcosim", "ecos")
    peer_steps: tuple = (1e-2, 1e-3, 1e-4)
    peer_points: tuple = ("fig4a_5deg", "fig4a_7deg", "fig2b_chronometer")
    peer_periods: int = 10
    peer_timeout_s: float = 600.0
    hoyng: bool = True
    hoyng_ticks: int = 1000
    hoyng_jump_periods: int = 150
    hoyng_families: tuple = ()
    hoyng_scipy_rtols: tuple = (1e-6, 1e-8, 1e-10)
    chaos: bool = True
    chaos_t_end: float = 400.0  # s
    chaos_transient: float = 100.0  # s, left out of the statistics
    chaos_sample: float = 0.05  # s, a2 sampling interval (a multiple of every step used)
    chaos_families: tuple = ()
    chaos_scipy_rtols: tuple = (1e-8, 1e-10)
    chaos_peer_tools: tuple = ("fmpy", "libcosim", "ecos")
    chaos_peer_steps: tuple = (2e-3, 1e-3)
    model_exchange: bool = True  # the pendulum as a Model Exchange FMU (bench/exchange.py)
    me_ticks: int = 50
    me_rtols: tuple = (1e-6, 1e-8, 1e-10)
    me_solvers: tuple = ("dop853", "dp54", "cvode")
    repeats: int = 3  # timing repeats of runs shorter than repeat_below_s
    repeat_below_s: float = 2.0
    targets: bool = True  # whole-process and long-run targets (fig4a run, bench_master, Hoyng Fig. 6)
    # Long enough that the difference of the two walls (about 5 s with the
    # compiled core) stands far above the noise of start-up (0.1 s).
    fig6_periods: tuple = (4000, 100000)
    run_tool: Path = RUN_TOOL


def _steady_families(quick: bool) -> tuple:
    if quick:
        return (
            Family("GS, ZOH, events located (default)", {}, grid([0.5], [1e-8, 1e-12])),
            Family("Jacobi", {"order": "jacobi"}, grid([0.5], [1e-12])),
            Family("extrapolation order 1", {"extrapolation": 1}, grid([0.5], [1e-12])),
            Family("extrapolation order 2", {"extrapolation": 2}, grid([0.5], [1e-12])),
            Family("iterative coupling (2 iterations)", {"iterations": 2}, grid([0.5], [1e-12])),
            Family("Richardson step control", {"richardson": True}, grid([0.5], [1e-12])),
            Family("events not located", {"event_location": False}, grid([1e-2, 1e-3], [1e-12])),
            Family("damping in Drag FMU, ZOH", {}, grid([0.1, 1e-2], [1e-12]), split=True),
            Family("damping in Drag FMU, extrapolation 2", {"extrapolation": 2}, grid([0.1, 1e-2], [1e-12]),
                   split=True),
        )
    return (
        Family("GS, ZOH, events located (default)", {}, grid([0.5], [1e-6, 1e-8, 1e-10, 1e-12])),
        Family("default settings, h = 0.1 s", {}, grid([0.1], [1e-8, 1e-12])),
        Family("Jacobi", {"order": "jacobi"}, grid([0.5], [1e-8, 1e-12])),
        Family("extrapolation order 1", {"extrapolation": 1}, grid([0.5], [1e-8, 1e-12])),
        Family("extrapolation order 2", {"extrapolation": 2}, grid([0.5], [1e-8, 1e-12])),
        Family("iterative coupling (2 iterations)", {"iterations": 2}, grid([0.5], [1e-8, 1e-12])),
        Family("Richardson step control", {"richardson": True},
               grid([0.5], [1e-12], richardson_tolerance=1e-6) + grid([0.5], [1e-12], richardson_tolerance=1e-9)),
        Family("events not located", {"event_location": False}, grid([1e-2, 1e-3, 1e-4], [1e-12])),
        Family("damping in Drag FMU, ZOH", {}, grid([0.1, 1e-2, 1e-3], [1e-12]), split=True),
        Family("damping in Drag FMU, extrapolation 2", {"extrapolation": 2}, grid([0.1, 1e-2, 1e-3], [1e-12]),
               split=True),
        Family("damping in Drag FMU, 2 iterations", {"iterations": 2}, grid([0.1, 1e-2], [1e-12]), split=True),
        Family("damping in Drag FMU, Richardson", {"richardson": True, "extrapolation": 2},
               grid([0.1], [1e-12], richardson_tolerance=1e-6) + grid([0.1], [1e-12], richardson_tolerance=1e-9),
               split=True),
    )


def _hoyng_families(quick: bool) -> tuple:
    big = TWO_PI  # the master caps it near a fifth of a period (event look-ahead)
    if quick:
        return (
            Family("GS, ZOH, events located (default)", {}, grid([big], [1e-10, 1e-12])),
            Family("events not located", {"event_location": False}, grid([0.1], [1e-12])),
            Family("damping in Drag FMU, ZOH", {}, grid([big], [1e-12]), split=True),
            Family("damping in Drag FMU, extrapolation 2", {"extrapolation": 2}, grid([big], [1e-12]), split=True),
        )
    return (
        Family("GS, ZOH, events located (default)", {}, grid([big], [1e-8, 1e-10, 1e-12])),
        Family("Jacobi", {"order": "jacobi"}, grid([big], [1e-12])),
        Family("events not located", {"event_location": False}, grid([0.1, 0.01], [1e-12])),
        Family("damping in Drag FMU, ZOH", {}, grid([big, 0.1], [1e-12]), split=True),
        Family("damping in Drag FMU, extrapolation 2", {"extrapolation": 2}, grid([big, 0.1], [1e-12]), split=True),
    )


def _chaos_families(quick: bool) -> tuple:
    if quick:
        return (
            Family("GS, ZOH, events located (default)", {}, grid([2e-3], [1e-10])),
            Family("extrapolation order 2", {"extrapolation": 2}, grid([2e-3], [1e-10])),
        )
    return (
        Family("GS, ZOH, events located (default)", {}, grid([4e-3, 2e-3, 1e-3], [1e-10])),
        Family("extrapolation order 2", {"extrapolation": 2}, grid([4e-3, 2e-3, 1e-3], [1e-10])),
        Family("Jacobi", {"order": "jacobi"}, grid([2e-3], [1e-10])),
        Family("iterative coupling (1 iteration)", {"iterations": 1}, grid([2e-3, 1e-3], [1e-10])),
        Family("events not located", {"event_location": False}, grid([1e-3], [1e-10])),
    )


def full_config() -> BenchConfig:
    return BenchConfig(steady_families=_steady_families(False), hoyng_families=_hoyng_families(False),
                       chaos_families=_chaos_families(False))


def quick_config() -> BenchConfig:
    return BenchConfig(
        name="quick", steady_points=("fig4a_5deg",), steady_families=_steady_families(True),
        long_run_tolerances=(1e-3, 1e-5), scipy_rtols=(1e-8, 1e-11), scipy_long_run_tolerances=(1e-5,), peer_steps=(1e-2, 1e-3),
        peer_points=("fig4a_5deg",), hoyng_families=_hoyng_families(True), hoyng_scipy_rtols=(1e-8,),
        chaos_t_end=100.0, chaos_transient=20.0, chaos_families=_chaos_families(True), chaos_scipy_rtols=(),
        chaos_peer_tools=("ecos",), chaos_peer_steps=(2e-3,), repeats=1, targets=False,
        peer_timeout_s=300.0, me_ticks=20, me_rtols=(1e-6, 1e-10),
    )


@dataclass
class Row:
    problem: str
    family: str
    tool: str  # clockwork | scipy | fmpy | libcosim | ecos
    label: str
    error: float = math.nan
    unit: str = ""
    wall_s: float = math.nan
    repeats: int = 0
    step_s: float | None = None
    rtol: float | None = None
    status: str = "ok"
    note: str = ""


def timed(fn, cfg: BenchConfig):
    """(result of the last call, median wall time s, calls). Runs under
    0.1 s, whose times scatter most on a shared machine, get 2 r + 1 calls."""
    t0 = time.perf_counter()
    out = fn()
    times = [time.perf_counter() - t0]
    n = cfg.repeats if times[0] >= 0.1 else 2 * cfg.repeats + 1
    while len(times) < n and times[0] < cfg.repeat_below_s:
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return out, statistics.median(times), len(times)


def fmt(x, digits: int = 3) -> str:
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "-"
    if isinstance(x, float):
        return f"{x:.{digits}g}"
    return str(x)


def master_settings(fam: Family, step: float, extra: dict) -> MasterSettings:
    values = dict(step=step)
    values.update(fam.settings)
    values.update(extra)
    return MasterSettings(**values)


def row_label(step: float, rtol: float | None, extra: dict) -> str:
    parts = [f"h = {step:.4g} s"]
    if rtol is not None:
        parts.append(f"rtol = {rtol:.0e}")
    parts += [f"{k} = {v:g}" for k, v in extra.items()]
    return ", ".join(parts)
