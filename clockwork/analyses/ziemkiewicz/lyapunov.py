"""Ziemkiewicz Fig. 10(b): Lyapunov exponents from twin runs.

``lyapunov``: twin runs started delta apart; for every t the least-squares
exponent of the phase-space distance over [fit_start, t]
(``running_exponent``).
"""

from __future__ import annotations

import math

import numpy as np

from .. import keys
from ..context import build_system
from ..registry import register
from .clock import DEG
from .parts import LYAPUNOV_KEYS, Parts, check_parts, json_list, lockstep, stats_of


def running_exponent(t: np.ndarray, d: np.ndarray, t_from: float = 0.0) -> np.ndarray:
    """For every t_k: least-squares slope of ln d over the samples in [t_from, t_k] (1/s).

    NaN where fewer than 3 samples or d has zeros (no difference to fit)."""
    t = np.asarray(t, dtype=float)
    d = np.asarray(d, dtype=float)
    out = np.full(len(t), np.nan)
    use = (t >= t_from) & (d > 0)
    if use.sum() < 3:
        return out
    idx = np.flatnonzero(use)
    x, y = t[idx], np.log(d[idx])
    x0 = x[0]
    x = x - x0  # conditioning
    n = np.arange(1, len(x) + 1, dtype=float)
    sx, sy = np.cumsum(x), np.cumsum(y)
    sxx, sxy = np.cumsum(x * x), np.cumsum(x * y)
    den = n * sxx - sx * sx
    with np.errstate(invalid="ignore", divide="ignore"):
        slope = (n * sxy - sx * sy) / den
    slope[:2] = np.nan
    out[idx] = slope
    return out


# The keys of the result built at the end of lyapunov.
COLUMNS = {"C1", "C2", "perturbation_deg", "lambda1_end_per_s", "lambda2_end_per_s", "lambda1_late_per_s",
           "lambda2_late_per_s", "d1_start_rad", "d1_end_rad", "d2_end_rad", "d1_growth", "d2_growth"}


@register("lyapunov", {"perturbation", "sample_interval", "fit_start"}, keys.table_converter(LYAPUNOV_KEYS),
          columns=COLUMNS,
          check=check_parts(needs_vibration=True),
          series={"time", "d1", "d2", "lambda1", "lambda2"})
def lyapunov(scene, point: dict, progress: bool = False) -> dict:
    """Twin runs from phi_start and phi_start + perturbation (Ziemkiewicz Eq. 8).

    The distance of each oscillator is taken in its phase space,
    d1 = sqrt(da1^2 + (dw1/omega01)^2), d2 = sqrt(da2^2 + (da2dot/omega02)^2),
    so that it does not pass through zero twice a period as |da| does;
    lambda_i(t) is the least-squares slope of ln d_i over [fit_start, t].
    lambda_late is the slope over the second half of the run alone: an
    exponential divergence keeps it at lambda, a divergence that grows like
    a power of t makes it fall like 1/t.
    """
    cfg = scene.analysis or {}
    parts = Parts(scene, point, needs_vibration=True)
    pend, vib = parts.pendulum, parts.vibration
    start, stop = parts.start, parts.stop
    delta = cfg.get("perturbation", 1e-6 * DEG)
    interval = cfg.get("sample_interval", 0.05)
    fit_start = start + cfg.get("fit_start", 0.0)
    twin = dict(point)
    twin[(pend, "phi_start")] = parts.pp["phi_start"] + delta
    record = {vib: ["a2", "a2dot"], pend: ["w"]}
    w01, w02 = parts.omega0, parts.vib["omega02"]
    rows = {"time": [], "d1": [], "d2": []}
    with build_system(scene, point, record=record) as s1, build_system(scene, twin, record=record) as s2:

        def on_sample(t):
            d1 = math.hypot(s1.output(pend, "phi") - s2.output(pend, "phi"),
                            (s1.output(pend, "w") - s2.output(pend, "w")) / w01)
            d2 = math.hypot(s1.output(vib, "a2") - s2.output(vib, "a2"),
                            (s1.output(vib, "a2dot") - s2.output(vib, "a2dot")) / w02)
            rows["time"].append(t)
            rows["d1"].append(d1)
            rows["d2"].append(d2)

        lockstep([s1, s2], stop, interval, on_sample, progress, scene.path.stem)
        stats = stats_of(s1.master)
    t = np.asarray(rows["time"])
    lam1 = running_exponent(t, rows["d1"], fit_start)
    lam2 = running_exponent(t, rows["d2"], fit_start)
    half = start + 0.5 * (stop - start)
    late1 = running_exponent(t, rows["d1"], max(half, fit_start))
    late2 = running_exponent(t, rows["d2"], max(half, fit_start))
    rows["lambda1"] = json_list(lam1)
    rows["lambda2"] = json_list(lam2)

    def last(x):
        x = np.asarray(x)
        return float(x[-1]) if len(x) and np.isfinite(x[-1]) else None

    def growth(d):
        d = np.asarray(d)
        sel = d[t >= fit_start]
        return float(sel[-1] / sel[0]) if len(sel) and sel[0] > 0 else None

    result = {
        "C1": parts.vib["C1"],
        "C2": parts.vib["C2"],
        "perturbation_deg": math.degrees(delta),
        "lambda1_end_per_s": last(lam1),
        "lambda2_end_per_s": last(lam2),
        "lambda1_late_per_s": last(late1),
        "lambda2_late_per_s": last(late2),
        "d1_start_rad": float(rows["d1"][0]) if rows["d1"] else None,
        "d1_end_rad": float(rows["d1"][-1]) if rows["d1"] else None,
        "d2_end_rad": float(rows["d2"][-1]) if rows["d2"] else None,
        "d1_growth": growth(rows["d1"]),
        "d2_growth": growth(rows["d2"]),
    }
    return {"kind": "lyapunov", "result": result, "series": rows, "statistics": stats}
