"""What the chaos analyses (Ziemkiewicz Sec. VIII, Figs. 8-11) share.

``Parts``: the scene's pendulum, escapement and vibrating mechanism with
their effective parameters; ``convert_keys``: the analysis keys; sampling
on the grid, Hermite interpolation inside a step, and twin systems run in
lockstep.
"""

from __future__ import annotations

import math

import numpy as np

from ...errors import SimulationError
from ...scene.kinds import Invalid
from .. import keys
from ..context import experiment, find_component, master_settings, parameters


_SPAN = "shorter than the experiment"
_STEPS = "the runs over the periods within the 1e10 steps bound (the finest step)"
_PYTHON_STEPS = "paper_span over the finest paper_steps within the 1e9 Python steps bound"
_GRID = "a whole multiple of master.step, at most the experiment's span"
KEYS = {
    "transient": keys.duration(0, None, lo_open=False, also=f"{_SPAN}, leaving samples after it"),
    "sample_interval": keys.duration(0, None, also=f"{_GRID} (taken at communication points)"),
    "fit_start": keys.duration(0, None, lo_open=False, also=_SPAN),
    "perturbation": keys.angle_in(0, 180, also="phi_start + perturbation within the Pendulum FMU's range "
                                                "of phi_start"),
    # A free swing of 150 deg takes 1.76 small-angle periods: within the
    # 2 per period step_accuracy waits for its ticks.
    "amplitude": keys.angle_in(0, 150),
    "periods": keys.count(1, keys.MAX_COUNT, also=_STEPS),
    "fixed_steps": keys.durations(0, None, also=f"each within the Pendulum FMU's range of h_max; {_STEPS}"),
    "comm_steps": keys.durations(0, None, also=_STEPS),
    "paper_steps": keys.durations(0, None, also=_PYTHON_STEPS),
    "paper_span": keys.duration(0, None, also=_PYTHON_STEPS),
    "rtols": keys.number_list(0.0, 0.1, also="each (and a hundredth of it, the atol) within the Pendulum FMU's "
                                             "ranges of rtol and atol"),
}
convert_keys = keys.table_converter(KEYS)
# lyapunov samples by running both twins to each sample time: any interval.
LYAPUNOV_KEYS = {**KEYS, "sample_interval": keys.duration(0, None, also="at most the experiment's span")}


def check_parts(needs_vibration: bool = False, escapement: bool = False, on_grid: bool = False,
                samples_after_transient: int = 1):
    """The check of a chaos kind: the components Parts asks for, and its
    keys against the span and the step at each point (each is what the run
    would refuse, or a key that would be silently ignored)."""
    def check(scene, point: dict) -> None:
        cfg = scene.analysis or {}
        kind = cfg.get("kind", "")
        pendulum = find_component(scene, "Pendulum")
        if pendulum is None:
            raise Invalid("kind", f"a scene with a Pendulum component for {kind}")
        if needs_vibration and (find_component(scene, "MechanismVibration") is None
                                or find_component(scene, "GrasshopperEscapement") is None):
            raise Invalid("kind", f"a scene with a GrasshopperEscapement and a MechanismVibration for {kind}")
        if escapement and find_component(scene, "GrasshopperEscapement") is None:
            raise Invalid("kind", f"a scene with a GrasshopperEscapement for {kind}")
        start, stop = experiment(scene, point)
        span = stop - start
        step = master_settings(scene, point).step
        interval = cfg.get("sample_interval")
        if interval is not None:
            if interval > span:
                raise Invalid("sample_interval", f"at most the experiment's span, {span:g} s")
            if on_grid and abs(interval / step - round(interval / step)) > 1e-6 * max(1.0, interval / step):
                raise Invalid("sample_interval", f"a whole multiple of master.step = {step:g} s (samples are "
                                                 "taken at communication points)")
        every = interval or step
        transient = cfg.get("transient", 0.0)
        if transient and (span - transient) / every < samples_after_transient:
            raise Invalid("transient", f"a transient that leaves {samples_after_transient} samples of "
                                       f"{every:g} s before experiment.stop (the span is {span:g} s)")
        if cfg.get("fit_start", 0.0) >= span:
            raise Invalid("fit_start", f"a time before the end of the experiment, less than {span:g} s")
        pp = parameters(scene, point)[pendulum]
        if "perturbation" in cfg:
            keys.within_fmu(scene, "perturbation", pendulum, "phi_start", (pp["phi_start"] + cfg["perturbation"],),
                            "the twin's phi_start + perturbation")
        for h in cfg.get("fixed_steps", ()):
            keys.within_fmu(scene, "fixed_steps", pendulum, "h_max", (h,), "a fixed step")
        for r in cfg.get("rtols", ()):
            keys.within_fmu(scene, "rtols", pendulum, "rtol", (r,), "an rtol")
            keys.within_fmu(scene, "rtols", pendulum, "atol", (r * 1e-2,), "its atol, rtol/100")
    return check


class Parts:
    """Instance names and effective parameters of a chaos scene (FMU start values
    where the scene sets none)."""

    def __init__(self, scene, point: dict, needs_vibration: bool = False):
        kind = (scene.analysis or {}).get("kind", "time_series")
        self.pendulum = find_component(scene, "Pendulum")
        self.escapement = find_component(scene, "GrasshopperEscapement")
        self.vibration = find_component(scene, "MechanismVibration")
        if self.pendulum is None:
            raise SimulationError(f"{kind}: the scene needs a Pendulum component")
        self.params = parameters(scene, point)
        self.pp = self.params[self.pendulum]
        self.esc = self.params.get(self.escapement, {})
        self.vib = self.params.get(self.vibration, {})
        self.omega0 = math.sqrt(self.pp["g"] / self.pp["L"])
        self.start, self.stop = experiment(scene, point)  # s
        self.transient = (scene.analysis or {}).get("transient", 0.0)  # s, skipped by the statistics
        if needs_vibration and (self.vibration is None or self.escapement is None):
            raise SimulationError(f"{kind} needs a GrasshopperEscapement and a MechanismVibration")


def on_grid(master, interval: float | None) -> bool:
    """True at communication points on the sample grid (events add points off it)."""
    step = master.settings.step
    k = (master.t - master.start_time) / step
    if abs(k - round(k)) > 1e-6:
        return False
    if not interval:
        return True
    j = (master.t - master.start_time) / interval
    return abs(j - round(j)) < 1e-6 * max(1.0, interval / step)


def hermite(t: float, t0: float, t1: float, f0: float, f1: float, d0: float, d1: float) -> float:
    """Cubic Hermite interpolant of f on [t0, t1] with slopes d0, d1 at its ends."""
    h = t1 - t0
    s = (t - t0) / h
    s2, s3 = s * s, s * s * s
    return ((2 * s3 - 3 * s2 + 1) * f0 + (s3 - 2 * s2 + s) * h * d0
            + (-2 * s3 + 3 * s2) * f1 + (s3 - s2) * h * d1)


def json_list(a) -> list:
    """JSON has no NaN: None instead."""
    return [float(v) if math.isfinite(v) else None for v in np.asarray(a, dtype=float)]


def stats_of(m) -> dict:
    return vars(m.stats).copy()


def lockstep(systems, stop: float, interval: float, on_sample, progress: bool, label: str) -> None:
    """Advance every system to each sample time in turn; call on_sample(t)."""
    from tqdm import tqdm

    m0 = systems[0].master
    t0 = m0.t
    n = int(math.floor((stop - t0) / interval + 1e-9))
    with tqdm(total=n, disable=not progress, delay=1.0, desc=label, unit="sample") as bar:
        for k in range(1, n + 1):
            t = min(stop, t0 + k * interval)
            for s in systems:
                s.master.run_until(t)
            on_sample(t)
            bar.update()
