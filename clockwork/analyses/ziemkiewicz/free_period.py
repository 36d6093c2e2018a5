"""Ziemkiewicz Fig. 1: the period of a free pendulum against its amplitude.

``free_period`` releases the pendulum at rest from phi_start and takes the
period from the FMU's tick times, beside the exact (AGM) period and the
series of Eq. (2).
"""

from __future__ import annotations

import math

import numpy as np

from ...errors import SimulationError
from ...physics import analytic
from ...scene.kinds import Invalid
from ..context import build_system, find_component, parameters
from ..registry import register
from .clock import DAY, convert_keys


# The keys of the result built at the end of free_period.
COLUMNS = {"amplitude_deg", "turning_amplitude_deg", "period_s", "period_agm_s", "period_eq2_first_order_s",
           "period_eq2_second_order_s", "rel_diff_agm", "rel_diff_eq2_first_order", "E_C_sim_s_per_day",
           "E_C_agm_s_per_day", "periods"}


def _check(scene, point: dict) -> None:
    """What free_period refuses at run time: a Pendulum, released at rest."""
    pendulum = find_component(scene, "Pendulum")
    if pendulum is None:
        raise Invalid("kind", "a scene with a Pendulum component for free_period")
    if parameters(scene, point)[pendulum].get("w_start", 0.0) != 0.0:
        raise Invalid("kind", f"a pendulum released at rest for free_period (components.{pendulum}.parameters."
                              "w_start = 0)")


@register("free_period", {"periods"}, convert_keys, columns=COLUMNS, series=set(), check=_check)
def free_period(scene, point: dict, progress: bool = False) -> dict:
    """Period of a free pendulum from its tick times (Fig. 1)."""
    cfg = scene.analysis or {}
    n = cfg.get("periods", 3)
    pendulum = find_component(scene, "Pendulum")
    if pendulum is None:
        raise SimulationError("free_period needs a Pendulum component")
    pp = parameters(scene, point)[pendulum]
    A = abs(pp["phi_start"])
    if pp.get("w_start", 0.0) != 0.0:
        raise SimulationError("free_period releases the pendulum at rest: w_start must be 0")
    ticks: list[float] = []
    with build_system(scene, point, record={pendulum: ["tick_time", "amplitude"]}) as system:
        m = system.master
        T0 = analytic.small_angle_period(pp["L"], pp["g"])
        last = system.output(pendulum, "tick_time")
        while len(ticks) < n + 1:
            if m.t - m.start_time > (n + 2) * 4 * T0:
                raise SimulationError(f"free_period: fewer than {n + 1} ticks", time=m.t)
            m.step(m.settings.step)
            tt = system.output(pendulum, "tick_time")
            if tt != last:
                ticks.append(tt)
                last = tt
        turn_amp = system.output(pendulum, "amplitude")
        stats = vars(m.stats).copy()
    t = np.asarray(ticks)
    T = float((t[-1] - t[0]) / n)
    T_agm = analytic.exact_period(A, pp["L"], pp["g"])
    T_1 = analytic.series_period(A, pp["L"], pp["g"], terms=1)
    T_2 = analytic.series_period(A, pp["L"], pp["g"], terms=2)
    result = {
        "amplitude_deg": math.degrees(A),
        "turning_amplitude_deg": math.degrees(turn_amp),
        "period_s": T,
        "period_agm_s": T_agm,
        "period_eq2_first_order_s": T_1,
        "period_eq2_second_order_s": T_2,
        "rel_diff_agm": T / T_agm - 1.0,
        "rel_diff_eq2_first_order": T_1 / T_agm - 1.0,
        "E_C_sim_s_per_day": (T / T0 - 1.0) * DAY,
        "E_C_agm_s_per_day": analytic.circular_error(A) * DAY,
        "periods": n,
    }
    return {"kind": "free_period", "result": result, "ticks": ticks, "statistics": stats}
