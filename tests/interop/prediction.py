"""What a fixed-step Jacobi master's error should be, from clockwork's accurate master.

A fixed-step master with zero-order hold (communication step h) differs
from the exact clock in ways that are, to first order in h, each the same
as a change of a parameter of the exact clock:

1. The escapement relay switches late. Its switch angle phi_r is crossed
   between two communication points and the new torque reaches the
   pendulum a delay d later: d in [0, h) when the torque is sampled fresh
   at the communication point (clockwork), d in [h, 2h) when it is the
   value read right after the escapement's step, i.e. from the previous
   point's inputs (fmpy, libcosim, ecos). Meanwhile the pendulum moves on
   at speed w = sqrt(2 g/L (cos phi_r - cos A)) (A its amplitude), less
   a d^2/2 with a the deceleration there: the relay acts as if its switch
   angle were phi_r + w d - |a| d^2/2, and every switch of the run lies
   between phi_r + w_lo d_lo - |a| d_lo^2/2 and phi_r + w_hi d_hi (w_lo,
   w_hi from the smallest and largest amplitude of the runs).
2. The drag torque -(c1 w + c2 w|w|) is applied late by a delay in the
   same range: -c w(t - d) = -c w(t) + c d a(t) to first order, a
   stiffness term that divides the inertia by (1 - c d/I), i.e. multiplies
   g by 1/(1 - c d/I), with c between c1 and c1 + 2 c2 max|w|.
3. fmpy's connectors start at 0: the escapement initializes from phi = w
   = 0 (relay mode +1), its torque reaches the pendulum as 0 in the first
   step and as +M (instead of -M) in the second, an extra angular impulse
   3 M h against the first swing of a pendulum released at rest from
   phi_start, where gravity accelerates it by a0 = (g/L) sin(phi_start):
   the whole motion starts 3 M h/(I a0) later (the same orbit, delayed);
   the mechanism mode sees a1 = 0 instead of phi_start in the first step:
   a2dot_start + C2 phi_start h.
4. The coupling of the two dynamic FMUs (pendulum, mechanism) is held over
   a step; its effect is what clockwork's own fixed-step run with the
   relay switched exactly (event location on, Jacobi, zero-order hold)
   shows, and is added as a tolerance of that size.

Every one of 1-3 moves the tick times and amplitudes one way (the later
the switch, the more energy per period and the slower the clock; a delayed
drag speeds it up), so the fixed-step run lies between the two accurate
runs with the parameters at the two ends of their ranges, to first order.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from clockwork.analyses.context import build_system


@dataclass
class Run:
    ticks: np.ndarray  # s, upward zero crossings of phi
    amplitudes: np.ndarray  # rad, |phi| at the turning points


def changes(values: np.ndarray) -> np.ndarray:
    """The successive new values of a discrete output sampled every step (0 = none yet)."""
    v = np.asarray(values, dtype=float)
    keep = np.concatenate(([v[0] != 0.0], v[1:] != v[:-1])) & (v != 0.0)
    return v[keep]


_runs: dict = {}


def accurate_run(scene, stop: float, point: dict | None = None) -> Run:
    """clockwork's master with the scene's own (accurate) settings (cached per process)."""
    key = (str(scene.path), scene.sha256, stop, tuple(sorted((point or {}).items())))
    if key not in _runs:
        _runs[key] = _accurate_run(scene, stop, point)
    return _runs[key]


def _accurate_run(scene, stop: float, point: dict | None) -> Run:
    ticks, amps = [], []
    with build_system(scene, point or {}, record={"pendulum": ["tick_time", "amplitude"]}) as sysm:
        def on_point(_m):
            tt = sysm.output("pendulum", "tick_time")
            a = sysm.output("pendulum", "amplitude")
            if tt != 0.0 and (not ticks or tt != ticks[-1]):
                ticks.append(tt)
            if a != 0.0 and (not amps or a != amps[-1]):
                amps.append(a)

        sysm.master.run_until(stop, on_point)
    return Run(np.array(ticks), np.array(amps))


def _value(scene, inst: str, name: str) -> float:
    comp = scene.components[inst]
    if name in comp.parameters:
        return float(comp.parameters[name])
    return float(next(v.start for v in comp.model_description.modelVariables if v.name == name))


@dataclass
class Interval:
    accurate: Run
    early: Run  # the run with every parameter at the end that gives the earliest ticks
    late: Run
    parameters: dict  # the two parameter points, for the report
    coupling: Run | None = None  # clockwork's fixed-step run with exact relay switches
    delay: float = 0.0  # s, by which fmpy's start delays every tick


def predict(scene, sampling: str, start: str, amplitudes: list[np.ndarray], stop: float) -> Interval:
    """The interval a fixed-step run (sampling 'fresh'/'held', start 'consistent'/'zero')
    should fall in; `amplitudes`: amplitude samples of the runs (rad) for w_lo, w_hi."""
    h = scene.master.step
    L, g = _value(scene, "pendulum", "L"), _value(scene, "pendulum", "g")
    m = _value(scene, "pendulum", "m")
    inertia = m * L * L
    phi_r = _value(scene, "escapement", "phi_r")
    torque = _value(scene, "escapement", "torque")
    accurate = accurate_run(scene, stop)
    a_all = np.concatenate([accurate.amplitudes] + [np.asarray(a) for a in amplitudes])
    A_lo, A_hi = float(a_all.min()), float(a_all.max())
    w_lo = math.sqrt(2.0 * g / L * (math.cos(phi_r) - math.cos(A_lo)))
    w_hi = math.sqrt(2.0 * g / L * (math.cos(phi_r) - math.cos(A_hi)))
    d_lo, d_hi = (0.0, h) if sampling == "fresh" else (h, 2.0 * h)
    acc = g / L * math.sin(phi_r) + torque / inertia  # |deceleration| bound past phi_r
    early = {("escapement", "phi_r"): phi_r + w_lo * d_lo - 0.5 * acc * d_lo**2}
    late = {("escapement", "phi_r"): phi_r + w_hi * d_hi}
    if "drag" in scene.components:
        c1, c2 = _value(scene, "drag", "c1"), _value(scene, "drag", "c2")
        w_max = math.sqrt(2.0 * g / L * (1.0 - math.cos(A_hi)))
        c_lo, c_hi = c1, c1 + 2.0 * c2 * w_max
        early[("pendulum", "g")] = g / (1.0 - c_hi * d_hi / inertia)
        late[("pendulum", "g")] = g / (1.0 - c_lo * d_lo / inertia)
    delay = 0.0
    if start == "zero":
        phi0 = _value(scene, "pendulum", "phi_start")
        if _value(scene, "pendulum", "w_start") != 0.0:
            raise ValueError("the start prediction assumes a pendulum released at rest")
        delay = 3.0 * torque * h / (inertia * g / L * math.sin(abs(phi0)))
        if "vibration" in scene.components:
            v0 = _value(scene, "vibration", "a2dot_start") + _value(scene, "vibration", "C2") * phi0 * h
            for p in (early, late):
                p[("vibration", "a2dot_start")] = v0
    coupling = None
    if "vibration" in scene.components:
        coupling = accurate_run(scene, stop, {("master", "order"): "jacobi", ("master", "extrapolation"): 0,
                                              ("master", "iterations"): 0})
    return Interval(accurate, accurate_run(scene, stop, early), accurate_run(scene, stop, late),
                    {"early": early, "late": late, "start_delay_s": delay}, coupling, delay)


def check(interval: Interval, ticks: np.ndarray, amplitudes: np.ndarray, n_ticks: int) -> dict:
    """Where the fixed-step run's ticks and amplitudes lie in the predicted interval.

    Returns the worst excess over the interval (s, rad; <= 0 inside) and the
    numbers for the report."""
    acc, early, late = interval.accurate, interval.early, interval.late
    n_amp = 2 * n_ticks
    for r in (acc, early, late, interval.coupling):
        if r is not None and (len(r.ticks) < n_ticks or len(r.amplitudes) < n_amp):
            raise AssertionError(f"an accurate run has only {len(r.ticks)} ticks")
    t = ticks[:n_ticks] - acc.ticks[:n_ticks]
    lo_t = early.ticks[:n_ticks] + interval.delay - acc.ticks[:n_ticks]
    hi_t = late.ticks[:n_ticks] + interval.delay - acc.ticks[:n_ticks]
    a = amplitudes[:n_amp] - acc.amplitudes[:n_amp]
    lo_a = np.minimum(early.amplitudes[:n_amp], late.amplitudes[:n_amp]) - acc.amplitudes[:n_amp]
    hi_a = np.maximum(early.amplitudes[:n_amp], late.amplitudes[:n_amp]) - acc.amplitudes[:n_amp]
    tol_t = tol_a = 0.0
    if interval.coupling is not None:
        tol_t = np.abs(interval.coupling.ticks[:n_ticks] - acc.ticks[:n_ticks])
        tol_a = np.abs(interval.coupling.amplitudes[:n_amp] - acc.amplitudes[:n_amp])
    lo_t, hi_t = np.minimum(lo_t, hi_t) - tol_t, np.maximum(lo_t, hi_t) + tol_t
    lo_a, hi_a = lo_a - tol_a, hi_a + tol_a
    excess_t = np.maximum(lo_t - t, t - hi_t)
    excess_a = np.maximum(lo_a - a, a - hi_a)
    return {
        "tick_error_s": float(t[-1]), "tick_interval_s": (float(lo_t[-1]), float(hi_t[-1])),
        "amplitude_error_rad": float(a[-1]), "amplitude_interval_rad": (float(lo_a[-1]), float(hi_a[-1])),
        "worst_tick_excess_s": float(excess_t.max()), "worst_tick_at": int(excess_t.argmax()) + 1,
        "worst_amplitude_excess_rad": float(excess_a.max()), "worst_amplitude_at": int(excess_a.argmax()) + 1,
    }
