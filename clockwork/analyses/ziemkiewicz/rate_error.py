"""Ziemkiewicz Fig. 10(a): the rate error caused by the vibration.

``rate_error``: momentary rate error per period against the same clock
without the vibration (C1 = C2 = 0, run in lockstep), and its sum, the
accumulated time error.
"""

from __future__ import annotations

import numpy as np

from ...errors import SimulationError
from ..context import build_system
from ..registry import register
from .parts import Parts, check_parts, convert_keys, lockstep, stats_of
from .clock import DAY


# The keys of the result built at the end of rate_error.
COLUMNS = {"transient_s", "periods", "momentary_mean_s_per_day", "momentary_std_s_per_day",
           "momentary_max_abs_s_per_day", "momentary_p2p_s_per_day", "accumulated_end_s", "accumulated_max_abs_s",
           "reference_period_end_s"}


@register("rate_error", {"transient"}, convert_keys, columns=COLUMNS, check=check_parts(needs_vibration=True),
          series={"time", "period_s", "reference_period_s", "momentary_s_per_day", "accumulated_s"})
def rate_error(scene, point: dict, progress: bool = False) -> dict:
    """Periods of the clock with the vibrating mechanism against the same
    clock with C1 = C2 = 0, started alike and run in lockstep.

    Momentary error of period n: (T_n / T_ref,n - 1) in s/day (positive:
    the clock loses); accumulated error: sum of T_n - T_ref,n (s). The
    statistics skip `transient` seconds.
    """
    parts = Parts(scene, point, needs_vibration=True)
    pend, vib = parts.pendulum, parts.vibration
    start, stop, transient = parts.start, parts.stop, parts.transient
    record = {pend: ["tick_time"]}
    uncoupled = dict(point)
    uncoupled[(vib, "C1")] = 0.0
    uncoupled[(vib, "C2")] = 0.0
    ticks: list[list[float]] = [[], []]
    with build_system(scene, point, record=record) as s1, build_system(scene, uncoupled, record=record) as s2:
        last = [s1.output(pend, "tick_time"), s2.output(pend, "tick_time")]

        def watch(k, s):
            def on_point(master):
                tt = s.output(pend, "tick_time")
                if tt != last[k]:
                    last[k] = tt
                    ticks[k].append(tt)
            return on_point

        s1.master.on_step = watch(0, s1)
        s2.master.on_step = watch(1, s2)
        lockstep([s1, s2], stop, max(1.0, s1.master.settings.step), lambda t: None, progress,
                  scene.path.stem)
        stats = stats_of(s1.master)
    n = min(len(ticks[0]), len(ticks[1]))
    if n < 3:
        raise SimulationError("rate_error: fewer than 3 ticks; run longer")
    t1, t2 = np.asarray(ticks[0][:n]), np.asarray(ticks[1][:n])
    T1, T2 = np.diff(t1), np.diff(t2)
    mom = (T1 / T2 - 1.0) * DAY
    acc = np.cumsum(T1 - T2)
    sel = t1[1:] >= start + transient
    m_sel = mom[sel]
    rows = {"time": list(t1[1:]), "period_s": list(T1), "reference_period_s": list(T2),
            "momentary_s_per_day": list(mom), "accumulated_s": list(acc)}
    result = {
        "transient_s": transient,
        "periods": int(n - 1),
        "momentary_mean_s_per_day": float(m_sel.mean()) if len(m_sel) else None,
        "momentary_std_s_per_day": float(m_sel.std()) if len(m_sel) else None,
        "momentary_max_abs_s_per_day": float(np.max(np.abs(m_sel))) if len(m_sel) else None,
        "momentary_p2p_s_per_day": float(np.ptp(m_sel)) if len(m_sel) else None,
        "accumulated_end_s": float(acc[-1]),
        "accumulated_max_abs_s": float(np.max(np.abs(acc))),
        "reference_period_end_s": float(T2[-1]),
    }
    return {"kind": "rate_error", "result": result, "series": rows, "statistics": stats}
