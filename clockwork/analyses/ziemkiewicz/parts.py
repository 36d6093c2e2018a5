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
from .. import keys
from ..context import experiment, find_component, parameters


_CONVERTERS = {
    "transient": keys.nonnegative_time,
    "sample_interval": keys.time,
    "fit_start": keys.nonnegative_time,
    "perturbation": keys.angle,
    "amplitude": keys.angle,
    "periods": keys.positive_int,
    "fixed_steps": keys.times,
    "comm_steps": keys.times,
    "paper_steps": keys.times,
    "paper_span": keys.time,
    "rtols": lambda k, v: keys.numbers(k, v, 0.0, 0.1),
}
convert_keys = keys.table_converter(_CONVERTERS)


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
