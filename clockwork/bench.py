"""``clockwork bench``: accuracy against run time, beside other masters.

Every error is measured against a monolithic scipy solution of the same
equations (clockwork.reference: DOP853, rtol 1e-12, located discontinuities,
periodic-orbit shooting), and that reference is itself checked first
(``reference_checks``): against the AGM period of the free pendulum,
against Hoyng's stationary Eqs. (19)/(20), between its shooting and its
plain integration, between two tolerances, and against the co-simulation.

Problems and their errors:

- ``steady``: steady-state rate error E_T in s/day of the Ziemkiewicz
  Fig. 4(a) clock (Pendulum + GrasshopperEscapement, phi_r = 2 deg,
  Q = 1000, L = 1 m, m = 1 kg, g = 9.81) at 5 and 7 deg, and of the Fig. 2(b)
  chronometer (window (-2, 0) deg: the push before the lowest point, E_E < 0,
  see the seeds README), each torque refined on the reference so that the
  mean turning amplitude is exactly 5 or 7 deg;
- ``hoyng``: accumulated time error (s) at tick 1000 of Hoyng's torque-jump
  scene (L = g = 1, mu 2e-5 -> 4e-5 at t/2pi = 150, eps = 2.5e-4,
  phi0 = 0.03, start on the stationary swing of Eq. 19);
- ``chaos``: errors of long-time statistics of the two-oscillator clock of
  Ziemkiewicz Sec. VIII (mean rate in s/day, rms of a2 relative), since
  trajectories part after a few Lyapunov times.

Rows: master configurations (MasterSettings: Gauss-Seidel/Jacobi, input
extrapolation, event location, iterative coupling, Richardson; damping in
the Pendulum or in a Drag FMU) across communication steps and FMU
tolerances; a plain long run beside the steady-state shooting; peers on the
same FMUs through the SSP export (fmpy, libcosim, ecos; each in a
subprocess via tests/interop/run_tool.py, so that a crash is a result) and
scipy itself.

Timing: medians of repeated runs, in this process for clockwork and scipy
(building and freeing the FMU instances included); for a peer, the wall time
of run_tool.py inside its subprocess after the tool's modules are imported
(loading the FMUs, stepping and saving included; the interpreter's start-up
and the imports not).
"""

from __future__ import annotations

import csv
import dataclasses
import datetime
import importlib.util
import json
import math
import os
import platform
import shutil
import signal
import statistics
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import analytic, reference
from .errors import SimulationError
from .master import MasterSettings
from .steady import Shooter, find_steady_state

ROOT = Path(__file__).resolve().parents[1]
RUN_TOOL = ROOT / "tests" / "interop" / "run_tool.py"
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


def _atol(rtol: float) -> float:
    # Angles ~0.1 rad, speeds ~0.3 rad/s, a2 ~1e-3 rad: two decades below rtol.
    return rtol * 1e-2


# --- configuration ----------------------------------------------------------


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
    repeats: int = 3  # timing repeats of runs shorter than repeat_below_s
    repeat_below_s: float = 2.0
    targets: bool = True  # whole-process and long-run targets (fig4a run, bench_master, Hoyng Fig. 6)
    fig6_periods: tuple = (2000, 8000)
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
        peer_timeout_s=300.0,
    )


# --- rows and timing ----------------------------------------------------------


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


def _timed(fn, cfg: BenchConfig):
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


def _fmt(x, digits: int = 3) -> str:
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "-"
    if isinstance(x, float):
        return f"{x:.{digits}g}"
    return str(x)


def _settings(fam: Family, step: float, extra: dict) -> MasterSettings:
    values = dict(step=step)
    values.update(fam.settings)
    values.update(extra)
    return MasterSettings(**values)


def _label(step: float, rtol: float | None, extra: dict) -> str:
    parts = [f"h = {step:.4g} s"]
    if rtol is not None:
        parts.append(f"rtol = {rtol:.0e}")
    parts += [f"{k} = {v:g}" for k, v in extra.items()]
    return ", ".join(parts)


# --- reference solutions ------------------------------------------------------


@dataclass
class SteadyPoint:
    key: str
    title: str
    params: reference.ClockParams  # the monolithic model
    ref: reference.SteadyState  # at rtol 1e-12
    target_deg: float

    @property
    def chronometer(self) -> bool:
        return self.params.escapement == "chronometer"

    @property
    def E_T(self) -> float:
        return self.ref.E_T

    @property
    def amplitude(self) -> float:
        """Mean of the two turning amplitudes, rad."""
        return 0.5 * (self.ref.amplitude + self.ref.amplitude_left)

    @property
    def guess(self) -> float:
        """Energy-balance amplitude (rad): what a user knows before solving."""
        p = self.params
        work = 4 * p.torque * p.phi_r if not self.chronometer else p.torque * (p.alpha_m2 - p.alpha_m1)
        return math.sqrt(work * p.Q / (math.pi * p.m * p.g * p.L))

    def pendulum(self, rtol: float, split: bool = False) -> dict:
        p = self.params
        return dict(L=p.L, m=p.m, g=p.g, Q=0.0 if split else p.Q, rtol=rtol, atol=_atol(rtol))

    def escapement(self) -> tuple[str, dict]:
        p = self.params
        if self.chronometer:
            return "ChronometerEscapement", dict(torque=p.torque, alpha_m1=p.alpha_m1, alpha_m2=p.alpha_m2)
        return "GrasshopperEscapement", dict(torque=p.torque, phi_r=p.phi_r)

    def drag_c1(self) -> float:
        """The Pendulum's linear damping as a Drag coefficient: m L^2 omega0 / Q (N.m.s/rad)."""
        p = self.params
        return p.inertia * p.omega0 / p.Q


STEADY_POINTS = {
    "fig4a_5deg": ("Ziemkiewicz Fig. 4(a) clock at 5 deg", "grasshopper", 5.0),
    "fig4a_7deg": ("Ziemkiewicz Fig. 4(a) clock at 7 deg", "grasshopper", 7.0),
    "fig2b_chronometer": ("Ziemkiewicz Fig. 2(b) chronometer, window (-2, 0) deg, at 5 deg", "chronometer", 5.0),
}


def _mean_amplitude(ss: reference.SteadyState) -> float:
    return 0.5 * (ss.amplitude + ss.amplitude_left)


def steady_point(key: str) -> SteadyPoint:
    """The operating point with its torque refined on the reference so that
    the mean turning amplitude is the target to 1e-10 (relative)."""
    title, esc, target_deg = STEADY_POINTS[key]
    A = target_deg * DEG
    base = dict(L=1.0, m=1.0, g=9.81, Q=1000.0)
    if esc == "grasshopper":
        params = reference.ClockParams(escapement="grasshopper", phi_r=2 * DEG, **base)
        M = analytic.grasshopper_torque_for_amplitude(A, params.phi_r, params.Q, params.m, params.L, params.g)
    else:
        params = reference.ClockParams(escapement="chronometer", alpha_m1=-2 * DEG, alpha_m2=0.0, **base)
        # Energy balance: M (alpha_m2 - alpha_m1) = pi m g L A^2 / Q.
        M = math.pi * params.m * params.g * params.L * A**2 / (params.Q * (params.alpha_m2 - params.alpha_m1))
    # A grows like sqrt(M): secant steps on (ln M, ln A).
    pts = []
    x = math.log(M)
    for _ in range(30):
        params = dataclasses.replace(params, torque=math.exp(x))
        ss = reference.steady_state(params)
        if ss.stalled:
            raise SimulationError(f"bench: {key}: the reference stalls at torque {math.exp(x)!r} N.m")
        y = math.log(_mean_amplitude(ss) / A)
        if abs(y) < 1e-10:
            return SteadyPoint(key, title, params, ss, target_deg)
        pts.append((x, y))
        if len(pts) >= 2 and pts[-1][1] != pts[-2][1]:
            (x0, y0), (x1, y1) = pts[-2], pts[-1]
            x = x1 - y1 * (x1 - x0) / (y1 - y0)
        else:
            x -= 2.0 * y
    raise SimulationError(f"bench: {key}: no torque found for {target_deg} deg")


@dataclass(frozen=True)
class Hoyng:
    eps: float = 2.5e-4
    mu0: float = 2e-5
    mu1: float = 4e-5
    phi0: float = 0.03
    jump_periods: int = 150
    ticks: int = 1000

    @property
    def Q(self) -> float:
        return analytic.Q_from_epsilon(self.eps)

    @property
    def lam0(self) -> float:
        return analytic.hoyng_stationary_amplitude(self.mu0, self.eps, self.phi0)

    @property
    def t_jump(self) -> float:
        return self.jump_periods * TWO_PI  # omega0 = 1

    def params(self, mu: float) -> reference.ClockParams:
        return reference.ClockParams(L=1.0, g=1.0, m=1.0, Q=self.Q, escapement="grasshopper", torque=mu,
                                     phi_r=self.phi0)


def hoyng_reference(h: Hoyng, rtol: float = reference.RTOL) -> np.ndarray:
    """Tick times (s) of the monolithic solution, start on the stationary swing (phi = 0, w = lambda)."""
    a = reference.simulate(h.params(h.mu0), 0.0, h.lam0, h.t_jump, rtol=rtol, atol=_atol(rtol))
    t_end = (h.ticks + 1.5) * TWO_PI
    b = reference.simulate(h.params(h.mu1), a.y[0], a.y[1], t_end, t0=h.t_jump, mode=a.mode, rtol=rtol,
                           atol=_atol(rtol))
    ticks = np.concatenate([a.ticks, b.ticks])
    if len(ticks) < h.ticks:
        raise SimulationError(f"bench: the Hoyng reference has only {len(ticks)} ticks")
    return ticks


TWIN_DPHI = 1e-6 * DEG  # the twins' initial difference, rad (Z Fig. 10b)


@dataclass(frozen=True)
class Chaos:
    """Ziemkiewicz Sec. VIII: gamma1 = pi/500 (Q ~ 500), gamma2 = gamma1/100,
    omega02 = 7 omega01, kappa = 1e7, C1 = 1, C2 = 2.5; M_F = 0.5 N.cm,
    phi_r = 2 deg, start at 7 deg at rest (Fig. 10); no velocity-dependent
    friction (the reference has none)."""

    t_end: float = 400.0
    transient: float = 100.0
    sample: float = 0.05
    torque: float = 0.005
    phi_start: float = 7 * DEG

    @property
    def omega01(self) -> float:
        return math.sqrt(9.81)

    @property
    def Q(self) -> float:
        return self.omega01 / (math.pi / 500.0)

    @property
    def T0(self) -> float:
        return TWO_PI / self.omega01

    def vibration(self) -> dict:
        return dict(gamma2=math.pi / 500.0 / 100.0, omega02=7.0 * self.omega01, kappa=1e7, C1=1.0, C2=2.5)

    def params(self) -> reference.ClockParams:
        return reference.ClockParams(Q=self.Q, torque=self.torque, phi_r=2 * DEG,
                                     vibration=reference.Vibration(**self.vibration()))

    def grid(self) -> np.ndarray:
        n = int(math.floor(self.t_end / self.sample + 1e-9))
        return self.sample * np.arange(n + 1)

    def lambda2(self, t_grid, run: dict, twin: dict) -> float:
        """Ziemkiewicz's lambda2 over the whole run (1/s): the least-squares
        slope of ln d2 over [0, t_end], d2 the twins' distance in the
        mechanism's phase space (analyses/chaos.py, Fig. 10b)."""
        from .analyses.chaos import running_exponent

        d2 = np.hypot(run["a2_series"] - twin["a2_series"],
                      (run["a2dot_series"] - twin["a2dot_series"]) / self.vibration()["omega02"])
        lam = running_exponent(np.asarray(t_grid), d2)
        if not np.isfinite(lam[-1]):
            raise SimulationError("bench: the twins did not part: no lambda2")
        return float(lam[-1])

    def statistics(self, ticks, t_grid, a2) -> dict:
        """Mean rate (s/day, positive: slow) from the ticks in the window, rms of a2 (rad)."""
        ticks = np.asarray(ticks)
        ticks = ticks[(ticks >= self.transient) & (ticks <= self.t_end)]
        t_grid, a2 = np.asarray(t_grid), np.asarray(a2)
        keep = t_grid >= self.transient - 1e-9
        if len(ticks) < 3 or not keep.any():
            raise SimulationError("bench: too few ticks or samples in the statistics window")
        period = (ticks[-1] - ticks[0]) / (len(ticks) - 1)
        return {"rate_s_per_day": (period / self.T0 - 1.0) * DAY, "a2_rms": float(np.sqrt(np.mean(a2[keep] ** 2))),
                "ticks": int(len(ticks))}


def chaos_reference(c: Chaos, rtol: float = reference.RTOL, dphi: float = 0.0) -> dict:
    """Statistics, and the a2, a2dot samples (``*_series``) for lambda2."""
    r = reference.simulate(c.params(), c.phi_start + dphi, 0.0, c.t_end, dense=True, rtol=rtol, atol=_atol(rtol))
    t = c.grid()
    y = r.sol(t)
    stats = c.statistics(r.ticks, t, y[2])
    stats["a2_series"], stats["a2dot_series"] = y[2], y[3]
    return stats


def _public(stats: dict) -> dict:
    return {k: v for k, v in stats.items() if not k.endswith("_series")}


# --- reference checks ---------------------------------------------------------


def reference_checks(point: SteadyPoint | None = None) -> list[dict]:
    """The reference against closed forms, itself and the co-simulation.

    Each check has a bound with its reason; `ok` is value <= bound.
    """
    checks = []

    def add(name, value, bound, unit, reason):
        checks.append({"check": name, "value": float(value), "bound": float(bound), "unit": unit,
                       "ok": bool(abs(value) <= bound), "reason": reason})

    # 1. Free pendulum against the AGM period.
    A = 5 * DEG
    free = reference.ClockParams(Q=0.0, escapement="none")
    r = reference.simulate(free, A, 0.0, 3.5 * free.T0)
    T = float(np.mean(np.diff(r.ticks)))
    T_agm = analytic.exact_period(A, free.L, free.g)
    add("free pendulum at 5 deg: period / AGM period - 1", T / T_agm - 1.0, 100 * reference.RTOL, "-",
        "a hundred times the integrator's rtol")

    # 2. Shooting against plain integration along the orbit it found.
    pt = point or steady_point("fig4a_5deg")
    ss = pt.ref
    run = reference.simulate(pt.params, ss.amplitude, 0.0, 20.5 * ss.period)
    periods = np.diff(run.ticks)
    add(f"{pt.key}: 20 periods integrated from the shot orbit: max |T_i/T - 1|",
        float(np.max(np.abs(periods / ss.period - 1.0))), 100 * reference.RTOL, "-",
        "a hundred times the integrator's rtol")
    add(f"{pt.key}: amplitude after 20 periods / shot amplitude - 1",
        float(run.turn_phi[run.turn_phi > 0][-1] / ss.amplitude - 1.0), 100 * reference.RTOL, "-",
        "a hundred times the integrator's rtol")

    # 3. Self-convergence: rtol 1e-12 against 1e-10.
    coarse = reference.steady_state(pt.params, rtol=1e-10)
    add(f"{pt.key}: E_T at rtol 1e-10 minus E_T at 1e-12", (coarse.E_T - ss.E_T) * DAY, 0.01 * TARGET_S_PER_DAY,
        "s/day", "1 % of the 1e-3 s/day the bench resolves")

    # 4. Hoyng's stationary swing, Eqs. (19) and (20), normalized units.
    h = Hoyng()
    hs = reference.steady_state(h.params(h.mu0))
    lam = h.lam0
    add("Hoyng point A: turning amplitude / Eq. (19) lambda - 1", _mean_amplitude(hs) / lam - 1.0,
        lam**2 / 16.0 + h.eps, "-", "first-order quantities lambda^2/16 + eps left out of Eq. (19)")
    rate = 1.0 / (1.0 + hs.E_T) - 1.0  # psi-dot - 1 = T0/T - 1
    eq20 = analytic.hoyng_stationary_rate(h.mu0, h.eps, h.phi0)
    esc = eq20 + lam**2 / 16.0
    # Second order in eps, lambda^2/16 and the escapement term, as in analyses/hoyng.py.
    add("Hoyng point A: rate psi-dot - 1 minus Eq. (20)", rate - eq20, (h.eps + lam**2 / 16.0 + abs(esc)) ** 2,
        "-", "second-order terms of the KBM averaging (products and squares of eps, lambda^2/16, escapement term)")

    # 5. The co-simulation's most accurate configuration against the reference.
    fam = Family("check", {}, ())
    E_T = master_steady(pt, fam, 0.5, 1e-12, {}, tolerance=1e-6 / DAY)
    add(f"{pt.key}: co-simulation (shooting, h = 0.5 s, FMU rtol 1e-12) E_T minus reference",
        (E_T - ss.E_T) * DAY, 0.01 * TARGET_S_PER_DAY, "s/day", "1 % of the 1e-3 s/day the bench resolves")
    return checks


# --- clockwork rows ----------------------------------------------------------------


def _system(components, links, settings, record):
    from .system import System

    return System(components, links, settings, record=record)


def _steady_components(pt: SteadyPoint, fam: Family, rtol: float, start: dict | None = None):
    pend = pt.pendulum(rtol, fam.split)
    if start:
        pend.update(start)
    esc_model, esc = pt.escapement()
    comps = {"pendulum": ("Pendulum", pend), "escapement": (esc_model, esc)}
    links = list(GRASSHOPPER_LINKS)
    if fam.split:
        comps["drag"] = ("Drag", {"c1": pt.drag_c1()})
        links += DRAG_LINKS
    return comps, links


def build_time(pt: SteadyPoint, cfg: BenchConfig) -> float:
    """Median wall time (s) of building and freeing the two-FMU system alone."""
    comps, links = _steady_components(pt, Family("build"), 1e-12)

    def build():
        with _system(comps, links, MasterSettings(step=0.5), {"pendulum": ["tick_time", "tick_w", "amplitude"]}):
            pass

    build()  # the first build also extracts the FMUs
    return _timed(build, dataclasses.replace(cfg, repeats=max(cfg.repeats, 5)))[1]


def master_steady(pt: SteadyPoint, fam: Family, step: float, rtol: float, extra: dict,
                  tolerance: float = 1e-4 / DAY) -> float:
    """E_T of the periodic orbit found by shooting (clockwork.steady)."""
    comps, links = _steady_components(pt, fam, rtol)
    with _system(comps, links, _settings(fam, step, extra), {"pendulum": ["tick_time", "tick_w", "amplitude"]}) as s:
        params = {k: dict(v) for k, (_, v) in comps.items()}
        p = pt.params
        shooter = Shooter(s.master, params, "pendulum", dict(L=p.L, g=p.g))
        a_min = 0.0 if pt.chronometer else p.phi_r
        st = find_steady_state(shooter, pt.guess, a_min, tolerance=tolerance)
    if st.stalled:
        raise SimulationError(f"stalled: {st.reason}")
    return st.E_T


def master_long_run(pt: SteadyPoint, fam: Family, step: float, rtol: float, change_tol: float,
                    max_periods: int) -> tuple[float, int]:
    """Plain run from the energy-balance amplitude at rest until the period
    changes by less than change_tol (relative) from one period to the next.
    Returns (E_T of the last period, periods run)."""
    comps, links = _steady_components(pt, fam, rtol, start={"phi_start": pt.guess, "w_start": 0.0})
    T0 = pt.params.T0
    with _system(comps, links, _settings(fam, step, {}), {"pendulum": ["tick_time"]}) as s:
        m = s.master
        port = m.ports["pendulum"]
        i_tick = port.out_names.index("tick_time")
        out = port.out
        ticks = []
        last = out[i_tick]
        prev_T = None
        while len(ticks) < max_periods + 1:
            m.step(step)
            tt = out[i_tick]
            if tt != last:
                last = tt
                ticks.append(tt)
                if len(ticks) >= 2:
                    T = ticks[-1] - ticks[-2]
                    if prev_T is not None and abs(T - prev_T) / T0 < change_tol:
                        return T / T0 - 1.0, len(ticks) - 1
                    prev_T = T
            if m.t > (max_periods + 3) * 2 * T0:
                break
    raise SimulationError(f"no convergence to {change_tol * DAY:g} s/day within {len(ticks) - 1} periods")


def scipy_long_run(pt: SteadyPoint, rtol: float, change_tol: float, max_periods: int) -> tuple[float, int]:
    """The plain long run of master_long_run, monolithic: (E_T, periods)."""
    T0 = pt.params.T0
    r = None
    ticks = np.empty(0)
    while len(ticks) < max_periods + 1:
        if r is None:
            r = reference.simulate(pt.params, pt.guess, 0.0, 50 * T0, rtol=rtol, atol=_atol(rtol))
        else:
            r = reference.simulate(pt.params, r.y[0], r.y[1], r.t + 50 * T0, t0=r.t, mode=r.mode, rtol=rtol,
                                   atol=_atol(rtol))
        ticks = np.concatenate([ticks, r.ticks])
        T = np.diff(ticks)
        change = np.abs(np.diff(T)) / T0
        hit = np.nonzero(change < change_tol)[0]
        if hit.size:
            k = hit[0] + 1
            return T[k] / T0 - 1.0, k + 1
    raise SimulationError(f"no convergence to {change_tol * DAY:g} s/day within {len(ticks) - 1} periods")


def master_hoyng(h: Hoyng, fam: Family, step: float, rtol: float, extra: dict) -> float:
    """Time (s) of tick number h.ticks."""
    pend = dict(L=1.0, g=1.0, m=1.0, Q=0.0 if fam.split else h.Q, phi_start=0.0, w_start=h.lam0,
                rtol=rtol, atol=_atol(rtol))
    comps = {"pendulum": ("Pendulum", pend),
             "escapement": ("GrasshopperEscapement", dict(torque=h.mu0, phi_r=h.phi0))}
    links = list(GRASSHOPPER_LINKS)
    if fam.split:
        comps["drag"] = ("Drag", {"c1": 1.0 / h.Q})  # m L^2 omega0 / Q with m = L = omega0 = 1
        links += DRAG_LINKS
    ticks: list[float] = []
    with _system(comps, links, _settings(fam, step, extra), {"pendulum": ["tick_time"]}) as s:
        m = s.master
        port = m.ports["pendulum"]
        i_tick = port.out_names.index("tick_time")
        out = port.out
        last = [out[i_tick]]

        def on_point(_):
            tt = out[i_tick]
            if tt != last[0]:
                last[0] = tt
                ticks.append(tt)

        m.run_until(h.t_jump, on_point)
        s.instances["escapement"].set_values({"torque": h.mu1})
        m.discontinuity()
        t = m.t
        while len(ticks) < h.ticks:
            t += TWO_PI
            m.run_until(t, on_point)
            if t > 2.0 * h.ticks * TWO_PI:
                raise SimulationError(f"only {len(ticks)} ticks in {t:g} s")
    return ticks[h.ticks - 1]


def master_chaos(c: Chaos, fam: Family, step: float, rtol: float, extra: dict, dphi: float = 0.0) -> dict:
    vib = dict(c.vibration(), inertia=1.0, rtol=rtol, atol=_atol(rtol))
    comps = {"pendulum": ("Pendulum", dict(L=1.0, m=1.0, g=9.81, Q=c.Q, phi_start=c.phi_start + dphi, w_start=0.0,
                                           rtol=rtol, atol=_atol(rtol))),
             "escapement": ("GrasshopperEscapement", dict(torque=c.torque, phi_r=2 * DEG)),
             "vibration": ("MechanismVibration", vib)}
    links = GRASSHOPPER_LINKS + VIBRATION_LINKS
    t_grid = c.grid()
    a2, a2dot = np.empty(len(t_grid)), np.empty(len(t_grid))
    ticks = []
    with _system(comps, links, _settings(fam, step, extra),
                 {"pendulum": ["tick_time"], "vibration": ["a2", "a2dot"]}) as s:
        m = s.master
        pp, vp = m.ports["pendulum"], m.ports["vibration"]
        i_tick, i_a2, i_v2 = (pp.out_names.index("tick_time"), vp.out_names.index("a2"),
                              vp.out_names.index("a2dot"))
        last = pp.out[i_tick]
        a2[0], a2dot[0] = vp.out[i_a2], vp.out[i_v2]
        for k in range(1, len(t_grid)):  # a sample interval is far shorter than a period: one tick at most
            m.run_until(t_grid[k])
            a2[k], a2dot[k] = vp.out[i_a2], vp.out[i_v2]
            tt = pp.out[i_tick]
            if tt != last:
                last = tt
                ticks.append(tt)
    stats = c.statistics(ticks, t_grid, a2)
    stats["a2_series"], stats["a2dot_series"] = a2, a2dot
    return stats


def _try(row: Row, fn, cfg: BenchConfig):
    """Run fn timed into row; a failure is the row's status."""
    try:
        res, wall, n = _timed(fn, cfg)
    except SimulationError as e:
        row.status = f"failed: {' '.join(str(e).split())[:200]}"
        return None
    except Exception as e:  # noqa: BLE001  (a benchmark row reports any failure)
        row.status = f"failed: {type(e).__name__}: {' '.join(str(e).split())[:200]}"
        return None
    row.wall_s, row.repeats = wall, n
    return res


# --- peers ---------------------------------------------------------------------


def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return repr(float(v)) if isinstance(v, float) else str(v)
    return json.dumps(v)


def scene_toml(title: str, components: dict, links: list[str], step: float, stop: float) -> str:
    lines = ["connections = ["] + [f'  "{c}",' for c in links] + ["]", ""]
    lines += ["[scene]", f"title = {json.dumps(title)}", ""]
    for name, (fmu, params) in components.items():
        ps = ", ".join(f"{k} = {_toml_value(v)}" for k, v in params.items())
        lines += [f"[components.{name}]", f'fmu = "{fmu}"', f"parameters = {{ {ps} }}", ""]
    lines += ["[experiment]", "start = 0.0", f"stop = {stop!r}", "", "[master]", f"step = {step!r}", ""]
    return "\n".join(lines)


def export_scene(path: Path, text: str) -> Path:
    """Write a scene file and its SSP archive beside it; returns the archive."""
    from .scene import load_scene
    from .ssp import export_ssp

    path.write_text(text)
    ssp = path.with_suffix(".ssp")
    export_ssp(load_scene(path), ssp)
    return ssp


def tool_available(tool: str) -> str | None:
    """None when the tool's Python package can be found, else the reason."""
    module = PEER_MODULES.get(tool)
    if module is None:
        return f"unknown tool {tool!r}"
    try:
        found = importlib.util.find_spec(module) is not None
    except ModuleNotFoundError:
        found = False
    return None if found else f"not installed ({module} not importable)"


# Runs run_tool.py as __main__ in a fresh interpreter and writes the wall
# time of that script alone (the tool's modules imported beforehand): FMU
# loading, initialization, stepping and saving, but not the interpreter and
# import start-up, like clockwork's own rows which include building the system.
_TIMER = """
import importlib, runpy, sys, time
script, modules, time_file = sys.argv[1], sys.argv[2], sys.argv[3]
for m in filter(None, modules.split(",")):
    importlib.import_module(m)
sys.argv = [script] + sys.argv[4:]
t0 = time.perf_counter()
code = 0
try:
    runpy.run_path(script, run_name="__main__")
except SystemExit as e:
    code = e.code
if not code:
    open(time_file, "w").write(repr(time.perf_counter() - t0))
sys.exit(code)
"""
_PRELOAD = {
    "fmpy": "numpy,clockwork.ssp,fmpy.ssp.simulation",
    "libcosim": "numpy,clockwork.ssp,libcosimpy.CosimExecution,libcosimpy.CosimLogging,libcosimpy.CosimObserver",
    "ecos": "numpy,clockwork.ssp,ecospy",
}


def run_peer(cfg: BenchConfig, tool: str, ssp: Path, steps: int, step: float, names: list[str],
             out: Path) -> tuple[dict | None, float, float, str]:
    """run_tool.py in a subprocess: (arrays or None, script wall s, process wall s, status)."""
    if not Path(cfg.run_tool).exists():
        return None, math.nan, math.nan, f"not run: {cfg.run_tool} is missing"
    time_file = out.with_suffix(".time")
    time_file.unlink(missing_ok=True)
    cmd = [sys.executable, "-c", _TIMER, str(cfg.run_tool), _PRELOAD.get(tool, ""), str(time_file),
           tool, str(ssp), "--steps", str(steps), "--step", repr(step), "--out", str(out), *names]
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT)] + ([env["PYTHONPATH"]] if env.get("PYTHONPATH") else []))
    t0 = time.perf_counter()
    try:
        p = subprocess.run(cmd, capture_output=True, text=True, timeout=cfg.peer_timeout_s, env=env)
    except subprocess.TimeoutExpired:
        return None, math.nan, time.perf_counter() - t0, f"timed out after {cfg.peer_timeout_s:g} s"
    process = time.perf_counter() - t0
    if p.returncode != 0:
        if p.returncode < 0:
            try:
                what = f"crashed ({signal.Signals(-p.returncode).name})"
            except ValueError:
                what = f"crashed (signal {-p.returncode})"
        else:
            what = f"exited with {p.returncode}"
        tail = " ".join((p.stderr or p.stdout).strip().splitlines()[-1:])[:200]
        return None, math.nan, process, f"{what}: {tail}" if tail else what
    try:
        wall = float(time_file.read_text())
        with np.load(out) as data:
            return {k: data[k] for k in data.files}, wall, process, "ok"
    except Exception as e:  # noqa: BLE001
        return None, math.nan, process, f"no readable result: {type(e).__name__}: {e}"


class PeerRunner:
    """Peers in subprocesses, repeated like clockwork's rows when short."""

    def __init__(self, cfg: BenchConfig, work: Path):
        self.cfg, self.work = cfg, work

    def run(self, row: Row, tool: str, ssp: Path, steps: int, step: float, names: list[str]):
        reason = tool_available(tool)
        if reason is not None:
            row.status = reason
            return None
        walls, processes = [], []
        while True:
            res, wall, process, status = run_peer(self.cfg, tool, ssp, steps, step, names,
                                                  self.work / f"{ssp.stem}.{tool}.npz")
            if res is None:
                row.status = status
                if math.isfinite(process):
                    row.note = f"after {process:.3g} s"
                return None
            walls.append(wall)
            processes.append(process)
            if len(walls) >= self.cfg.repeats or wall >= self.cfg.repeat_below_s:
                break
        row.wall_s, row.repeats = statistics.median(walls), len(walls)
        row.note = f"whole process {statistics.median(processes):.3g} s"
        return res


def _ticks(values: np.ndarray) -> np.ndarray:
    v = np.asarray(values, dtype=float)
    v = v[v > 0.0]
    if v.size == 0:
        return v
    return v[np.r_[True, np.diff(v) != 0.0]]


# --- the problems ----------------------------------------------------------------


def bench_steady(cfg: BenchConfig, pt: SteadyPoint, peers: PeerRunner, log) -> list[Row]:
    rows = []
    prob = pt.key
    unit = "s/day"
    tol = cfg.shooting_tolerance_s_per_day / DAY
    for fam in cfg.steady_families:
        for step, rtol, extra in fam.points:
            row = Row(prob, fam.name, "clockwork", _label(step, rtol, extra), unit=unit, step_s=step, rtol=rtol,
                      note="periodic-orbit shooting (clockwork.steady)")
            E_T = _try(row, lambda: master_steady(pt, fam, step, rtol, extra, tolerance=tol), cfg)
            if E_T is not None:
                row.error = abs(E_T - pt.E_T) * DAY
            rows.append(row)
            log(row)
    default = Family("plain long run")
    for ctol in cfg.long_run_tolerances:
        row = Row(prob, "plain long run (default settings)", "clockwork",
                  f"h = 0.5 s, rtol = 1e-12, until the period changes < {ctol:g} s/day", unit=unit, step_s=0.5,
                  rtol=1e-12)
        res = _try(row, lambda: master_long_run(pt, default, 0.5, 1e-12, ctol / DAY, cfg.long_run_max_periods), cfg)
        if res is not None:
            row.error = abs(res[0] - pt.E_T) * DAY
            row.note = f"{res[1]} periods from the energy-balance amplitude at rest"
        rows.append(row)
        log(row)
    for rtol in cfg.scipy_rtols:
        row = Row(prob, "scipy DOP853 shooting", "scipy", f"rtol = {rtol:.0e}", unit=unit, rtol=rtol,
                  note="reference.steady_state")
        ss = _try(row, lambda: reference.steady_state(pt.params, rtol=rtol), cfg)
        if ss is not None:
            row.error = abs(ss.E_T - pt.E_T) * DAY
        rows.append(row)
        log(row)
    n = cfg.peer_periods
    for rtol in cfg.scipy_rtols:
        row = Row(prob, "scipy DOP853 integration", "scipy", f"rtol = {rtol:.0e}, {n} periods from the reference orbit",
                  unit=unit, rtol=rtol)

        def run():
            r = reference.simulate(pt.params, pt.ref.amplitude, 0.0, (n + 1.0) * pt.ref.period, rtol=rtol,
                                   atol=_atol(rtol))
            return r.ticks

        ticks = _try(row, run, cfg)
        if ticks is not None:
            row.error = abs((ticks[n] - ticks[0]) / n / pt.params.T0 - 1.0 - pt.E_T) * DAY
        rows.append(row)
        log(row)
    for ctol in cfg.scipy_long_run_tolerances:
        row = Row(prob, "scipy DOP853 plain long run", "scipy",
                  f"rtol = 1e-10, until the period changes < {ctol:g} s/day", unit=unit, rtol=1e-10)
        res = _try(row, lambda: scipy_long_run(pt, 1e-10, ctol / DAY, cfg.long_run_max_periods), cfg)
        if res is not None:
            row.error = abs(res[0] - pt.E_T) * DAY
            row.note = f"{res[1]} periods from the energy-balance amplitude at rest"
        rows.append(row)
        log(row)
    if prob in cfg.peer_points:
        rows += _steady_peers(cfg, pt, peers, log)
    return rows


def _steady_peers(cfg: BenchConfig, pt: SteadyPoint, peers: PeerRunner, log) -> list[Row]:
    """Fixed-step peers, started on the reference's periodic orbit (at the right
    turning point), `peer_periods` periods: the period averaged over them."""
    rows = []
    n = cfg.peer_periods
    fam = Family("peer")
    for step in cfg.peer_steps:
        steps = math.ceil((n + 1.0) * pt.ref.period / step)
        comps, links = _steady_components(pt, fam, 1e-12, start={"phi_start": pt.ref.amplitude, "w_start": 0.0})
        ssp = None
        for tool in cfg.peer_tools:
            row = Row(pt.key, f"{tool} (fixed step)", tool,
                      f"h = {step:.4g} s, FMU rtol = 1e-12, {n} periods from the reference orbit", unit="s/day",
                      step_s=step, rtol=1e-12)
            rows.append(row)
            missing = tool_available(tool)
            if missing is not None:
                row.status = missing
                log(row)
                continue
            if ssp is None:
                try:
                    ssp = export_scene(peers.work / f"{pt.key}_h{step:g}.toml",
                                       scene_toml(f"bench {pt.key}", comps, links, step, steps * step))
                except Exception as e:  # noqa: BLE001
                    row.status = f"export failed: {type(e).__name__}: {e}"
                    log(row)
                    continue
            res = peers.run(row, tool, ssp, steps, step, ["pendulum.tick_time"])
            if res is not None:
                ticks = _ticks(res["pendulum.tick_time"])
                if len(ticks) < n + 1:
                    row.status = f"only {len(ticks)} ticks"
                else:
                    row.error = abs((ticks[n] - ticks[0]) / n / pt.params.T0 - 1.0 - pt.E_T) * DAY
            log(row)
    return rows


def bench_hoyng(cfg: BenchConfig, log) -> tuple[list[Row], dict]:
    h = Hoyng(jump_periods=cfg.hoyng_jump_periods, ticks=cfg.hoyng_ticks)
    t0 = time.perf_counter()
    ref_ticks = hoyng_reference(h)
    ref_wall = time.perf_counter() - t0
    ref = float(ref_ticks[h.ticks - 1])
    check = hoyng_reference(h, rtol=1e-11)
    info = {"tick_s": ref, "wall_s": ref_wall, "rtol_1e-11_minus_1e-12_s": float(check[h.ticks - 1] - ref)}
    rows = []
    prob = "hoyng"
    for fam in cfg.hoyng_families:
        for step, rtol, extra in fam.points:
            row = Row(prob, fam.name, "clockwork", _label(step, rtol, extra), unit="s", step_s=step, rtol=rtol)
            t = _try(row, lambda: master_hoyng(h, fam, step, rtol, extra), cfg)
            if t is not None:
                row.error = abs(t - ref)
            rows.append(row)
            log(row)
    for rtol in cfg.hoyng_scipy_rtols:
        row = Row(prob, "scipy DOP853 integration", "scipy", f"rtol = {rtol:.0e}", unit="s", rtol=rtol)
        ticks = _try(row, lambda: hoyng_reference(h, rtol=rtol), cfg)
        if ticks is not None:
            row.error = abs(ticks[h.ticks - 1] - ref)
        rows.append(row)
        log(row)
    for tool in cfg.peer_tools:
        rows.append(Row(prob, f"{tool} (fixed step)", tool, "-", unit="s", status="not run",
                        note="the torque jump is a parameter change during the run, which an SSP archive "
                             "cannot express"))
    return rows, info


def bench_chaos(cfg: BenchConfig, peers: PeerRunner, log) -> tuple[list[Row], dict]:
    c = Chaos(t_end=cfg.chaos_t_end, transient=cfg.chaos_transient, sample=cfg.chaos_sample)
    t0 = time.perf_counter()
    ref = chaos_reference(c)
    ref_wall = time.perf_counter() - t0
    # The statistics' own scatter: the reference from an angle 1e-6 deg larger (Z Fig. 10b).
    # The twin 1e-6 deg higher (Z Fig. 10b) gives the statistics' own scatter
    # and, with the reference, the reference's lambda2.
    other = chaos_reference(c, dphi=TWIN_DPHI)
    floor = {"rate_s_per_day": abs(other["rate_s_per_day"] - ref["rate_s_per_day"]),
             "a2_rms_relative": abs(other["a2_rms"] / ref["a2_rms"] - 1.0)}
    lambda2_ref = c.lambda2(c.grid(), ref, other)
    info = {"reference": _public(ref), "wall_s": ref_wall, "floor": floor, "t_end_s": c.t_end,
            "transient_s": c.transient, "lambda2_reference_per_s": lambda2_ref}
    rows = []

    def add(fam_name, tool, label, step, rtol, fn, note="", twin_fn=None):
        r1 = Row("chaos_rate", fam_name, tool, label, unit="s/day", step_s=step, rtol=rtol, note=note)
        stats = fn(r1)
        r2 = dataclasses.replace(r1, problem="chaos_a2rms", unit="relative")
        if stats is not None:
            r1.error = abs(stats["rate_s_per_day"] - ref["rate_s_per_day"])
            r2.error = abs(stats["a2_rms"] / ref["a2_rms"] - 1.0)
            r2.wall_s, r2.repeats, r2.note = r1.wall_s, r1.repeats, r1.note
        else:
            r2.status, r2.note = r1.status, r1.note
        rows.extend([r1, r2])
        if twin_fn is not None:
            # lambda2 needs the twin run too: its wall time is both runs'.
            r3 = dataclasses.replace(r1, problem="chaos_lambda2", unit="1/s", error=math.nan, wall_s=math.nan)
            if stats is not None:
                twin = twin_fn(r3)
                if twin is not None:
                    try:
                        lam = c.lambda2(c.grid(), stats, twin)
                        r3.error = abs(lam - lambda2_ref)
                        r3.note = f"lambda2 = {lam:.4g} 1/s"
                        r3.wall_s = r1.wall_s + r3.wall_s
                    except SimulationError as e:
                        r3.status = str(e)
            else:
                r3.status = r1.status
            rows.append(r3)
        log(r1)

    for fam in cfg.chaos_families:
        for step, rtol, extra in fam.points:
            add(fam.name, "clockwork", _label(step, rtol, extra), step, rtol,
                lambda row: _try(row, lambda: master_chaos(c, fam, step, rtol, extra), cfg),
                twin_fn=lambda row: _try(row, lambda: master_chaos(c, fam, step, rtol, extra, TWIN_DPHI), cfg))
    for rtol in cfg.chaos_scipy_rtols:
        add("scipy DOP853 integration", "scipy", f"rtol = {rtol:.0e}", None, rtol,
            lambda row: _try(row, lambda: chaos_reference(c, rtol=rtol), cfg),
            twin_fn=lambda row: _try(row, lambda: chaos_reference(c, rtol=rtol, dphi=TWIN_DPHI), cfg))
    names = ["pendulum.tick_time", "vibration.a2"]
    for step in cfg.chaos_peer_steps:
        steps = round(c.t_end / step)
        comps = {"pendulum": ("Pendulum", dict(L=1.0, m=1.0, g=9.81, Q=c.Q, phi_start=c.phi_start, w_start=0.0,
                                               rtol=1e-10, atol=1e-12)),
                 "escapement": ("GrasshopperEscapement", dict(torque=c.torque, phi_r=2 * DEG)),
                 "vibration": ("MechanismVibration", dict(c.vibration(), inertia=1.0, rtol=1e-10, atol=1e-12))}
        ssp = None
        for tool in cfg.chaos_peer_tools:
            def run_one(row, tool=tool, step=step, steps=steps, comps=comps):
                nonlocal ssp
                if tool_available(tool) is not None:
                    row.status = tool_available(tool)
                    return None
                if ssp is None:
                    ssp = export_scene(peers.work / f"chaos_h{step:g}.toml",
                                       scene_toml("bench chaos", comps, GRASSHOPPER_LINKS + VIBRATION_LINKS,
                                                  step, steps * step))
                res = peers.run(row, tool, ssp, steps, step, names)
                if res is None:
                    return None
                t = np.asarray(res["time"])
                on = np.abs(t / c.sample - np.round(t / c.sample)) < 1e-6
                t_grid = np.r_[0.0, t[on]]
                a2 = np.r_[0.0, np.asarray(res["vibration.a2"])[on]]  # a2_start = 0
                try:
                    return c.statistics(_ticks(res["pendulum.tick_time"]), t_grid, a2)
                except SimulationError as e:
                    row.status = str(e)
                    return None

            add(f"{tool} (fixed step)", tool, f"h = {step:.4g} s, FMU rtol = 1e-10", step, 1e-10, run_one)
    return rows, info


# --- targets (full run only) -------------------------------------------------------


def _subprocess_wall(cmd: list[str], env: dict, timeout: float) -> tuple[float, subprocess.CompletedProcess]:
    t0 = time.perf_counter()
    p = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=timeout, cwd=ROOT)
    return time.perf_counter() - t0, p


def target_fig4a(cfg: BenchConfig, work: Path, log) -> dict:
    """`clockwork run scenarios/ziemkiewicz_fig4a.toml` as a whole process,
    its wall time per point, and each point's E_T against the reference."""
    env = dict(os.environ, CLOCKWORK_CACHE="off")
    walls = []
    out = work / "fig4a_run"
    for k in range(max(1, cfg.repeats)):
        if out.exists():
            shutil.rmtree(out)
        wall, p = _subprocess_wall([sys.executable, "-m", "clockwork", "run", "scenarios/ziemkiewicz_fig4a.toml",
                                    "--out", str(out), "--no-progress"], env, 1800)
        if p.returncode != 0:
            return {"status": f"clockwork run failed: {p.stderr.strip()[-300:]}"}
        walls.append(wall)
        log(f"fig4a run {k + 1}: {wall:.2f} s")
    summary = json.loads((out / "summary.json").read_text())
    points = summary["points"]
    errors = []
    for pnt in points:
        r = pnt.get("result", pnt)
        torque = r.get("torque_Nm")
        if torque is None or r.get("stalled"):
            continue
        ss = reference.steady_state(reference.ClockParams(torque=torque, phi_r=2 * DEG, Q=1000.0))
        if ss.stalled:
            continue
        errors.append(abs(r["E_T_s_per_day"] - ss.E_T * DAY))
    n = summary.get("points_total", len(points))
    med = statistics.median(walls)
    return {"status": "ok", "process_wall_s": walls, "median_wall_s": med, "points": n,
            "wall_per_point_s": med / n, "in_run_wall_s": summary.get("wall_time_s"),
            "max_error_s_per_day": max(errors) if errors else math.nan, "points_compared": len(errors)}


def target_bench_master(work: Path) -> dict:
    script = ROOT / "benchmarks" / "bench_master.py"
    if not script.exists():
        return {"status": "benchmarks/bench_master.py missing"}
    wall, p = _subprocess_wall([sys.executable, str(script), "--steps", "20000", "--repeats", "5"],
                               dict(os.environ), 1800)
    if p.returncode != 0:
        return {"status": f"failed: {p.stderr.strip()[-300:]}"}
    return {"status": "ok", "table": p.stdout.strip(), "wall_s": wall}


def target_fig6(cfg: BenchConfig, work: Path, log) -> dict:
    """Hoyng Fig. 6 (4.8e6 periods, noisy torque) estimated from two shorter
    runs with the noise on from the start: wall = a + b periods."""
    env = dict(os.environ, CLOCKWORK_CACHE="off")
    pts = []
    for n in cfg.fig6_periods:
        out = work / f"fig6_{n}"
        if out.exists():
            shutil.rmtree(out)
        wall, p = _subprocess_wall([sys.executable, "-m", "clockwork", "run", "scenarios/hoyng_fig6.toml", "--out",
                                    str(out), "--no-progress", "--set", f"experiment.stop={n * TWO_PI!r}",
                                    "--set", "escapement.noise_start=0"], env, 3600)
        if p.returncode != 0:
            return {"status": f"clockwork run failed: {p.stderr.strip()[-300:]}"}
        pts.append((n, wall))
        log(f"fig6 {n} periods: {wall:.2f} s")
    (n1, w1), (n2, w2) = pts[0], pts[-1]
    b = (w2 - w1) / (n2 - n1)
    a = w1 - b * n1
    full = 4.8e6
    return {"status": "ok", "runs": pts, "per_period_ms": b * 1e3, "startup_s": a, "estimate_s": a + b * full,
            "periods": full}


# --- outputs ------------------------------------------------------------------------

PROBLEM_TITLES = {
    "fig4a_5deg": ("Fig. 4(a) clock, 5 deg: steady-state rate error", "s/day"),
    "fig4a_7deg": ("Fig. 4(a) clock, 7 deg: steady-state rate error", "s/day"),
    "fig2b_chronometer": ("Fig. 2(b) chronometer, 5 deg: steady-state rate error", "s/day"),
    "hoyng": ("Hoyng torque jump: time error at tick 1000", "s"),
    "chaos_rate": ("Chaotic clock (Z Sec. VIII): mean-rate error", "s/day"),
    "chaos_a2rms": ("Chaotic clock (Z Sec. VIII): a2 rms error", "relative"),
    "chaos_lambda2": ("Chaotic clock (Z Sec. VIII): lambda2 error (twin runs)", "1/s"),
}
CSV_FIELDS = ["problem", "family", "tool", "label", "step_s", "rtol", "error", "unit", "wall_s", "repeats",
              "status", "note"]


def write_csv(path: Path, rows: list[Row]) -> None:
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=CSV_FIELDS)
        w.writeheader()
        for r in rows:
            d = dataclasses.asdict(r)
            w.writerow({k: ("" if d[k] is None or (isinstance(d[k], float) and math.isnan(d[k])) else d[k])
                        for k in CSV_FIELDS})


def plot_work_precision(path: Path, rows: list[Row], info: dict) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import matplotlib.ticker

    problems = [p for p in PROBLEM_TITLES if any(r.problem == p for r in rows)]
    if not problems:
        return
    ncol = min(3, len(problems))
    nrow = math.ceil(len(problems) / ncol)
    fig, axes = plt.subplots(nrow, ncol, figsize=(6.2 * ncol, 4.8 * nrow), squeeze=False)
    families = list(dict.fromkeys(r.family for r in rows))
    cmap = plt.get_cmap("tab20")
    markers = {"clockwork": "o", "scipy": "x", "fmpy": "s", "libcosim": "D", "ecos": "^"}
    handles = {}
    for ax, prob in zip(axes.flat, problems):
        title, unit = PROBLEM_TITLES[prob]
        for fam in families:
            # In the order the family sweeps its setting (a line per family).
            pts = [(r.wall_s, r.error) for r in rows
                   if r.problem == prob and r.family == fam and r.status == "ok"
                   and math.isfinite(r.error) and math.isfinite(r.wall_s)]
            if not pts:
                continue
            tool = next(r.tool for r in rows if r.family == fam)
            x = [max(p[0], 1e-4) for p in pts]
            y = [max(p[1], 1e-14) for p in pts]  # an exact zero still shows
            style = "--" if fam.startswith("plain long run") else "-"
            (line,) = ax.plot(x, y, style, marker=markers.get(tool, "o"), color=cmap(families.index(fam) % 20),
                              ms=5, lw=1.2, label=fam)
            handles.setdefault(fam, line)
        if prob in ("fig4a_5deg", "fig4a_7deg", "fig2b_chronometer"):
            ax.axhline(TARGET_S_PER_DAY, color="k", lw=0.8, ls=":")
            ax.text(ax.get_xlim()[0] if ax.lines else 1e-3, TARGET_S_PER_DAY, " 1e-3 s/day", va="bottom", fontsize=7)
        floor = (info.get("chaos") or {}).get("floor", {})
        if prob == "chaos_rate" and floor:
            ax.axhline(floor["rate_s_per_day"], color="grey", lw=0.8, ls=":")
        if prob == "chaos_a2rms" and floor:
            ax.axhline(floor["a2_rms_relative"], color="grey", lw=0.8, ls=":")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
        ax.set_xlabel("wall time per run (s)")
        ax.set_ylabel(f"error ({unit})")
        ax.set_title(title, fontsize=9)
        ax.grid(True, which="major", alpha=0.3)
    for ax in list(axes.flat)[len(problems):]:
        ax.axis("off")
    fig.tight_layout()
    fig.legend(list(handles.values()), list(handles.keys()), loc="upper center", bbox_to_anchor=(0.5, 0.0),
               ncol=3, fontsize=7, frameon=False)
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)


def _md_table(header: list[str], body: list[list]) -> list[str]:
    out = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    out += ["| " + " | ".join(_fmt(c).replace("|", "\\|") for c in row) + " |" for row in body]
    return out


def summarize_targets(rows: list[Row], targets: dict) -> list[dict]:
    """Per steady point: the fastest clockwork row within 1e-3 s/day beside each peer's best."""
    out = []
    for prob in ("fig4a_5deg", "fig4a_7deg", "fig2b_chronometer"):
        if not any(r.problem == prob for r in rows):
            continue
        mine = [r for r in rows if r.problem == prob and r.family == DEFAULT_FAMILY and r.status == "ok"
                and r.error <= TARGET_S_PER_DAY]
        best = min(mine, key=lambda r: r.wall_s) if mine else None
        entry = {"problem": prob, "clockwork": best, "peers": {}}
        peers = {"clockwork: plain long run": [r for r in rows if r.problem == prob
                                               and r.family.startswith("plain long run")]}
        peers.update({t: [r for r in rows if r.problem == prob and r.tool == t] for t in ("fmpy", "libcosim", "ecos")})
        for r in rows:
            if r.problem == prob and r.tool == "scipy":
                peers.setdefault(r.family, []).append(r)
        for tool, candidates in peers.items():
            peer_rows = [r for r in candidates if r.status == "ok" and math.isfinite(r.error)]
            if not peer_rows:
                status = candidates[0].status if candidates else "not run"
                entry["peers"][tool] = {"status": status}
                continue
            reach = [r for r in peer_rows if r.error <= TARGET_S_PER_DAY]
            if reach:
                fastest = min(reach, key=lambda r: r.wall_s)
                entry["peers"][tool] = {"reaches": True, "row": fastest,
                                        "ratio": fastest.wall_s / best.wall_s if best else math.nan}
            else:
                bestp = min(peer_rows, key=lambda r: r.error)
                est = _extrapolate(peer_rows) if tool in PEER_MODULES else None
                entry["peers"][tool] = {"reaches": False, "row": bestp, "estimate": est}
        out.append(entry)
    return out


def _extrapolate(peer_rows: list[Row]) -> dict | None:
    """Error ~ C h^p from the two finest fixed steps: the step and the wall
    time (~1/h) that 1e-3 s/day would take."""
    rs = sorted((r for r in peer_rows if r.step_s), key=lambda r: r.step_s)
    if len(rs) < 2 or rs[0].error <= 0 or rs[1].error <= 0 or rs[0].step_s == rs[1].step_s:
        return None
    a, b = rs[0], rs[1]
    p = math.log(b.error / a.error) / math.log(b.step_s / a.step_s)
    if not p > 0.1:
        return {"order": p}
    h = a.step_s * (TARGET_S_PER_DAY / a.error) ** (1.0 / p)
    return {"order": p, "step_s": h, "wall_s": a.wall_s * a.step_s / h}


def write_markdown(path: Path, cfg: BenchConfig, rows: list[Row], checks: list[dict], info: dict,
                   targets: dict, command: str) -> None:
    L = [f"# clockwork bench ({cfg.name})", ""]
    m = info["machine"]
    L += [f"Command: `{command}`  ", f"Date: {info['date']}, wall time {info['wall_s']:.0f} s  ",
          f"Machine: {m['cpus']} CPUs, {m['platform']}, Python {m['python']}; load average "
          f"{m['load_start']} at the start, {m['load_end']} at the end (the machine is shared: absolute times are "
          f"noisy, ratios measured side by side in this run are the better numbers)", ""]
    L += ["## Reference agreement (checked before anything is measured against the reference)", ""]
    L += _md_table(["check", "value", "bound", "unit", "ok", "bound from"],
                   [[c["check"], c["value"], c["bound"], c["unit"], "yes" if c["ok"] else "**NO**", c["reason"]]
                    for c in checks])
    L.append("")
    if "steady_points" in info:
        if "build_s" in info:
            L += [f"Building and freeing the Pendulum + escapement system alone takes {info['build_s'] * 1e3:.1f} ms "
                  "(median); every clockwork row of the steady-state problems includes it.", ""]
        L += ["Operating points (torques refined on the reference, rtol 1e-12):", ""]
        L += _md_table(["point", "torque (N.m)", "mean amplitude (deg)", "E_T reference (s/day)",
                        "reference wall (s)"],
                       [[k, v["torque_Nm"], v["amplitude_deg"], v["E_T_s_per_day"], v["wall_s"]]
                        for k, v in info["steady_points"].items()])
        L.append("")
    if info.get("hoyng"):
        hy = info["hoyng"]
        L += [f"Hoyng reference: tick {cfg.hoyng_ticks} at {hy['tick_s']!r} s (rtol 1e-11 differs by "
              f"{hy['rtol_1e-11_minus_1e-12_s']:.2g} s), {hy['wall_s']:.1f} s wall.", ""]
    if info.get("chaos"):
        ch = info["chaos"]
        ref = ch["reference"]
        L += [f"Chaos reference ({ch['t_end_s']:g} s, statistics from {ch['transient_s']:g} s on): mean rate "
              f"{ref['rate_s_per_day']:.6g} s/day over {ref['ticks']} ticks, a2 rms {ref['a2_rms']:.6g} rad; "
              f"{ch['wall_s']:.1f} s wall. Statistics floor (the same reference from 1e-6 deg more): "
              f"{ch['floor']['rate_s_per_day']:.2g} s/day, {ch['floor']['a2_rms_relative']:.2g} relative in the "
              f"a2 rms. Errors at or below the floor mean the trajectory is followed. lambda2 of the reference "
              f"twins (1e-6 deg apart, fitted over [0, {ch['t_end_s']:g}] s): "
              f"{ch['lambda2_reference_per_s']:.4g} 1/s; the lambda2 rows run the twin too and are not "
              f"measured for the peers.", ""]
    if targets:
        L += ["## Targets", ""]
        L += _targets_md(targets)
    L += ["## Rows", "",
          "Error against the reference; wall time is the median of the repeats (clockwork and scipy: in this "
          "process, building and freeing the FMU instances included; peers: run_tool.py in its subprocess "
          "after the tool's imports, loading the FMUs included; the note gives the whole process). "
          "Fixed-step peers start on the reference's periodic orbit, which only the "
          "reference knows, and are measured over "
          f"{cfg.peer_periods} periods: the protocol most favourable to them.", ""]
    for prob, (title, unit) in PROBLEM_TITLES.items():
        rs = [r for r in rows if r.problem == prob]
        if not rs:
            continue
        L += [f"### {title}", ""]
        L += _md_table(["family", "tool", "setting", f"error ({unit})", "wall (s)", "runs", "status", "note"],
                       [[r.family, r.tool, r.label, r.error, r.wall_s, r.repeats, r.status, r.note] for r in rs])
        L.append("")
    path.write_text("\n".join(L) + "\n")


def cfg_periods(r: Row) -> str:
    return r.label.split(", ")[-1] if "periods" in r.label else "run"


def _targets_md(t: dict) -> list[str]:
    L = []
    for e in t.get("speed", []):
        best = e["clockwork"]
        L.append(f"- {e['problem']}: clockwork's shooting with default settings, fastest within 1e-3 s/day: "
                 + (f"{best.label}: {best.error:.2g} s/day in {best.wall_s * 1e3:.1f} ms" if best else "none"))
        for tool, p in e["peers"].items():
            if "row" not in p:
                L.append(f"  - {tool}: {p['status']}")
            elif p["reaches"]:
                L.append(f"  - {tool}: reaches it ({p['row'].label}: {p['row'].error:.2g} s/day) in "
                         f"{p['row'].wall_s:.3g} s: **{p['ratio']:.3g} x** clockwork's time")
            else:
                r = p["row"]
                est = p.get("estimate") or {}
                more = ""
                if est.get("step_s"):
                    more = (f"; error ~ h^{est['order']:.2f}, 1e-3 s/day would need h ~ {est['step_s']:.2g} s, "
                            f"~{est['wall_s']:.3g} s for the same {cfg_periods(r)}")
                L.append(f"  - {tool}: does not reach it; best {r.error:.3g} s/day ({r.label}, {r.wall_s:.3g} s)"
                         + more)
    f4 = t.get("fig4a")
    if f4:
        if f4.get("status") == "ok":
            L.append(f"- `clockwork run scenarios/ziemkiewicz_fig4a.toml` (CLOCKWORK_CACHE=off), whole process: "
                     f"median {f4['median_wall_s']:.2f} s over {len(f4['process_wall_s'])} runs "
                     f"({', '.join(f'{w:.2f}' for w in f4['process_wall_s'])}), {f4['points']} points: "
                     f"**{f4['wall_per_point_s']:.3f} s per point** (target 0.2 s); inside the run "
                     f"{f4['in_run_wall_s']:.2f} s. Largest |E_T - reference| over the "
                     f"{f4['points_compared']} points: **{f4['max_error_s_per_day']:.2g} s/day** (target 1e-3).")
        else:
            L.append(f"- fig4a run: {f4['status']}")
    bm = t.get("bench_master")
    if bm:
        if bm.get("status") == "ok":
            L += ["- `python benchmarks/bench_master.py --steps 20000 --repeats 5` (target: master overhead "
                  "<= 3 us per FMU per step, the last column):", ""] + ["  " + x for x in bm["table"].splitlines()]
        else:
            L.append(f"- bench_master: {bm['status']}")
    f6 = t.get("fig6")
    if f6:
        if f6.get("status") == "ok":
            runs = ", ".join(f"{n} periods {w:.1f} s" for n, w in f6["runs"])
            L.append(f"- Hoyng Fig. 6 as a full co-simulation (4.8e6 periods, noise on): from `clockwork run "
                     f"scenarios/hoyng_fig6.toml --set experiment.stop=<N 2pi> --set escapement.noise_start=0` "
                     f"({runs}): {f6['per_period_ms']:.3f} ms per period, estimate **{f6['estimate_s']:.0f} s** "
                     f"(target < 1000 s).")
        else:
            L.append(f"- Hoyng Fig. 6: {f6['status']}")
    L.append("")
    return L


# --- the run ---------------------------------------------------------------------------


def _machine() -> dict:
    load = os.getloadavg() if hasattr(os, "getloadavg") else (math.nan,) * 3
    return {"cpus": os.cpu_count(), "platform": platform.platform(), "python": platform.python_version(),
            "load": [round(x, 2) for x in load]}


def run_bench(out: Path, cfg: BenchConfig | None = None, progress: bool = True, command: str = "clockwork bench",
              checks_only: bool = False) -> dict:
    """Run the benchmark into `out`: bench.csv, bench.md, bench.json, work_precision.png."""
    cfg = cfg or full_config()
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    work = out / "work"
    work.mkdir(exist_ok=True)
    t_start = time.perf_counter()
    load_start = _machine()["load"]

    def log(x):
        if not progress:
            return
        if isinstance(x, Row):
            x = (f"  {x.problem:<18} {x.family[:48]:<48} {x.label[:44]:<44} "
                 f"err {_fmt(x.error):>9} {x.unit:<8} wall {_fmt(x.wall_s):>8} s  "
                 f"{x.status if x.status != 'ok' else ''}")
        print(x, flush=True)

    info: dict = {}
    rows: list[Row] = []
    points = {}
    for key in cfg.steady_points:
        t0 = time.perf_counter()
        points[key] = steady_point(key)
        pt = points[key]
        info.setdefault("steady_points", {})[key] = {
            "torque_Nm": pt.params.torque, "amplitude_deg": math.degrees(pt.amplitude),
            "E_T_s_per_day": pt.E_T * DAY, "wall_s": time.perf_counter() - t0}
    log("reference checks ...")
    checks = reference_checks(points.get("fig4a_5deg"))
    for c in checks:
        log(f"  {'ok ' if c['ok'] else 'BAD'} {c['check']}: {c['value']:.3g} (bound {c['bound']:.3g} {c['unit']})")
    if not all(c["ok"] for c in checks):
        log("the reference does not pass its checks: errors below are measured against it anyway, see bench.md")
    targets: dict = {}
    if not checks_only:
        peers = PeerRunner(cfg, work)
        for key, pt in points.items():
            log(f"{key}: torque {pt.params.torque:.6g} N.m, E_T {pt.E_T * DAY:.6f} s/day")
            if "build_s" not in info:
                info["build_s"] = build_time(pt, cfg)
            rows += bench_steady(cfg, pt, peers, log)
        if cfg.hoyng:
            log("hoyng torque jump ...")
            r, info["hoyng"] = bench_hoyng(cfg, log)
            rows += r
        if cfg.chaos:
            log("chaotic clock ...")
            r, info["chaos"] = bench_chaos(cfg, peers, log)
            rows += r
        if cfg.targets:
            log("targets: fig4a run, bench_master, Hoyng Fig. 6 ...")
            targets["fig4a"] = target_fig4a(cfg, work, log)
            targets["bench_master"] = target_bench_master(work)
            targets["fig6"] = target_fig6(cfg, work, log)
        targets["speed"] = summarize_targets(rows, targets)
    info["date"] = datetime.datetime.now().isoformat(timespec="seconds")
    info["wall_s"] = time.perf_counter() - t_start
    m = _machine()
    info["machine"] = {"cpus": m["cpus"], "platform": m["platform"], "python": m["python"],
                       "load_start": load_start, "load_end": m["load"]}
    write_csv(out / "bench.csv", rows)
    plot_work_precision(out / "work_precision.png", rows, info)
    write_markdown(out / "bench.md", cfg, rows, checks, info, targets, command)
    blob = {"config": cfg.name, "command": command, "info": info, "checks": checks,
            "rows": [dataclasses.asdict(r) for r in rows],
            "targets": json.loads(json.dumps(targets, default=lambda o: dataclasses.asdict(o)
                                             if dataclasses.is_dataclass(o) else repr(o)))}
    (out / "bench.json").write_text(json.dumps(blob, indent=1, default=repr) + "\n")
    return blob
