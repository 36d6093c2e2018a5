"""What each analysis kind keeps in memory and how long it steps, estimated
from the scene before the work starts (``check_bounds``; the validator runs
it for every point whose span or step an axis changes).

The estimates count what the kind's code appends per pendulum period (one
tick, an upward zero crossing, per period), per sample of
``analysis.sample_interval`` and per communication step, over its span:
the experiment's, or ``analysis.periods`` nominal periods. time_series and
ticks are counted in clockwork.run.catalog (record.interval, outputs).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from ..errors import SceneError
from .context import find_component, parameters

MAX_KEPT_VALUES = 20_000_000  # about 820 MB of Python floats in lists (BYTES_PER_VALUE each)
# A kept value's cost at a run's peak: a float (24) and its place in a list
# (8, and the list's growth), measured at 41 with the result CSV written
# (docs/reliability.md, "Bounds known before the work starts").
BYTES_PER_VALUE = 41
MAX_STEPS = 10_000_000_000  # communication steps of one point: hours at the compiled core's 0.3 us per FMU-step
MAX_PYTHON_STEPS = 1_000_000_000  # steps of a loop in Python (ziemkiewicz_fig11's Eq. A1 takes 2e8, minutes)
MAX_LIST = 1000  # entries of a list an analysis runs one co-simulation per entry of


@dataclass(frozen=True)
class Kept:
    """Values a kind keeps: `per_period` per nominal period, `per_step` per
    communication step, `sample_columns` per sample of analysis.sample_interval
    (the communication step when not given), over the experiment's span or,
    when `periods` is set, over analysis.periods nominal periods (default
    `periods`). `runs` lists the analysis keys whose every entry is a run
    over the span."""
    per_period: float = 0.0
    per_step: float = 0.0
    sample_columns: int = 0
    periods: int | None = None
    runs: tuple[str, ...] = ()
    steps: tuple[str, ...] = ()  # keys of `runs` that list steps: the finest sets the work
    own_span: tuple[str, float, str] | None = None  # (span key, its default s, steps key): a run of its own


# Every kind but time_series and ticks; a kind not here has no span-long memory
# (steady-state searches end on their tolerance, their counts bounded by keys.positive_int).
KEPT: dict[str, Kept] = {
    "hoyng_long_run": Kept(per_period=3),  # torque changes (time, value) per crossing, 1 in sample_every ticks
    "hoyng_averaged_run": Kept(per_period=1),  # the noise per period, samples per sample_periods
    "hoyng_torque_jump": Kept(per_period=2, per_step=2),  # tick and amplitude; phi per step up to the jump
    "free_period": Kept(per_period=1, periods=3),
    "steady_orbit": Kept(per_step=4, periods=2),  # time, phi, w, tau per communication point
    "step_accuracy": Kept(per_period=1, periods=100, runs=("fixed_steps", "rtols", "comm_steps", "paper_steps"),
                          steps=("fixed_steps", "comm_steps"), own_span=("paper_span", 2000.0, "paper_steps")),
    "rate_error": Kept(per_period=2),  # ticks of the coupled and the uncoupled clock
    "lyapunov": Kept(sample_columns=3),  # time, d1, d2
    "vibration_series": Kept(per_period=2, sample_columns=7),
    "poincare": Kept(per_period=6),
    "limit_cycle": Kept(per_period=3, sample_columns=4),  # turning points (2) and switches per period
    "disturbance": Kept(per_period=8),
}


def nominal_period(scene, point: dict | None = None) -> float | None:
    """2 pi sqrt(L/g) of the scene's Pendulum (or AveragedPendulum), s; None without one."""
    inst = find_component(scene, ("Pendulum", "AveragedPendulum"))
    if inst is None:
        return None
    pp = parameters(scene, point)[inst]
    L, g = pp.get("L"), pp.get("g")
    if not (isinstance(L, (int, float)) and isinstance(g, (int, float)) and L > 0 and g > 0):
        return None
    return 2.0 * math.pi * math.sqrt(L / g)


# The kinds that search steady states by shooting: each map evaluation steps
# one period in a Python loop (engine.shooting), a search takes up to
# SHOOTING_EVALUATIONS of them, and a kind several searches.
STEADY_KINDS = ("steady_state", "escapement_steady_state", "steady_orbit", "disturbance", "hoyng_stationary",
                "barometric_coefficient", "thermal_coefficient", "weather_year")
SHOOTING_EVALUATIONS = 31  # find_steady_state: a first map and 30 secant steps
# Steps of one steady-state search: each a master.step() called from Python
# (7-25 us with the FMUs' work), so 1e8 is about an hour.
MAX_SHOOTING_STEPS = 100_000_000


def check_bounds(scene, kind: str) -> None:
    """Refuse a point whose analysis would keep more than MAX_KEPT_VALUES or
    take more than MAX_STEPS communication steps (a steady-state search more
    than MAX_SHOOTING_STEPS steps of the shooting's Python loop), naming the
    key to change."""
    cfg = scene.analysis or {}
    kept = KEPT.get(kind)
    if kind in STEADY_KINDS:
        T0 = nominal_period(scene)
        search = SHOOTING_EVALUATIONS * T0 / scene.master.step if T0 else 0.0
        if search > MAX_SHOOTING_STEPS:
            raise SceneError(f"one steady-state search of {kind} takes up to {SHOOTING_EVALUATIONS} periods of "
                             f"{T0:.4g} s in steps of {scene.master.step:g} s, about {search:.3g} steps in Python, "
                             f"more than {MAX_SHOOTING_STEPS:.0e} (hours): give a longer master.step",
                             scene.path, "master.step")
    if kept is None and kind not in ("time_series", "ticks"):
        return  # steady-state searches: no span-long run
    step = scene.master.step
    T0 = nominal_period(scene)
    if kept is not None and kept.periods is not None:
        if T0 is None:
            return  # the kind refuses a scene without a pendulum when it runs
        n_periods = cfg.get("periods", kept.periods)
        span, span_key, shorter = n_periods * T0, "analysis.periods", "fewer analysis.periods"
    else:
        span = scene.experiment.stop - scene.experiment.start
        n_periods = span / T0 if T0 else 0.0
        span_key, shorter = "experiment.stop", "a shorter span (experiment.stop)"
    for key in (kept.runs if kept else ()):
        if len(cfg.get(key, ())) > MAX_LIST:
            raise SceneError(f"{len(cfg[key])} entries, each a run: give at most {MAX_LIST}", scene.path,
                             f"analysis.{key}")
    # The finest step a run of the kind takes: the master's, or an entry of a list of steps.
    finest, finest_key = step, "master.step"
    for key in (kept.steps if kept else ()):
        if cfg.get(key) and min(cfg[key]) < finest:
            finest, finest_key = min(cfg[key]), f"analysis.{key}"
    steps = span / finest
    if steps > MAX_STEPS:
        raise SceneError(f"{kind} over {span:g} s in steps of {finest:g} s takes about {steps:.3g} steps, more than "
                         f"{MAX_STEPS:.0e} (hours of stepping): give {shorter} or a longer {finest_key}",
                         scene.path, finest_key if finest_key != "master.step" else span_key)
    if kept is None:
        return
    if kept.own_span is not None:  # a run of its own, stepped in Python
        span_k, default, steps_k = kept.own_span
        own = cfg.get(span_k, default) / min(cfg.get(steps_k) or [math.inf])
        if own > MAX_PYTHON_STEPS:
            raise SceneError(f"{span_k} over the finest of {steps_k} takes about {own:.3g} steps in Python, more than "
                             f"{MAX_PYTHON_STEPS:.0e}: give a shorter {span_k} or longer {steps_k}",
                             scene.path, f"analysis.{steps_k}")
    interval = cfg.get("sample_interval") or step
    terms = {span_key: kept.per_period * n_periods + kept.per_step * span / step,
             "analysis.sample_interval": kept.sample_columns * span / interval}
    n = sum(terms.values()) * max(1, sum(len(cfg.get(k, ())) for k in kept.steps))
    if n > MAX_KEPT_VALUES:
        key = max(terms, key=terms.get)
        advice = ("a longer analysis.sample_interval or " if key == "analysis.sample_interval" else "") + shorter
        raise SceneError(f"{kind} over {span:g} s keeps about {n:.3g} values in memory, more than "
                         f"{MAX_KEPT_VALUES:.0e} (about {MAX_KEPT_VALUES * BYTES_PER_VALUE / 1e6:.0f} MB): give {advice}",
                         scene.path, key)
