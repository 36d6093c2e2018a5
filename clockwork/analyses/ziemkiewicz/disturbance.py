"""Ziemkiewicz Fig. 7: a point disturbance on the steady orbit.

``disturbance`` starts on the steady orbit, doubles gravity for 1 ms at a
zero crossing (or a turning point), and follows the momentary period, the
amplitude and the accumulated time error.
"""

from __future__ import annotations

import math

import numpy as np

from ...errors import SimulationError
from ..context import experiment
from ..registry import register
from .clock import DAY, Clock, advance_to, check_clock, convert_keys, steady_for


SAMPLED = ("time", "period_s", "dT_over_T", "amplitude_deg", "time_error_s")  # per tick
SERIES = SAMPLED + ("dA_deg",)  # and the amplitude's change, after the run
# What disturbance adds to the clock's result (the out.update below).
KICK_COLUMNS = {"kick_start_s", "kick_at", "kick_duration_s", "g_factor", "phi_at_kick_deg", "w_at_kick_rad_per_s",
                "stationary_period_s", "baseline_max_abs_dT_over_T", "max_abs_dT_over_T", "max_dT_over_T_signed",
                "max_abs_dA_deg", "time_error_end_s", "time_error_max_abs_s", "ticks"}


@register("disturbance", {"amplitude", "kick_time", "kick_duration", "g_factor", "kick_at",
                          "tolerance_s_per_day", "max_periods"}, convert_keys, check=check_clock,
          columns=Clock.RESULT_COLUMNS | KICK_COLUMNS,
          series=SERIES)
def disturbance(scene, point: dict, progress: bool = False) -> dict:
    """Point disturbance g' = g_factor g for kick_duration on the steady orbit (Fig. 7).

    The run starts at experiment.start on the steady orbit at an upward zero
    crossing; the kick starts at the first upward zero crossing at or after
    kick_time (or the right turning point after it, kick_at =
    "turning_point"). The momentary period is the time between ticks; the
    time error sums T_n - T_stationary (s, positive: the clock lags).
    """
    cfg = scene.analysis or {}
    start, stop = experiment(scene, point)
    t_kick = cfg.get("kick_time", start)
    duration = cfg.get("kick_duration", 1e-3)
    factor = cfg.get("g_factor", 2.0)
    at = cfg.get("kick_at", "zero_crossing")
    with Clock(scene, point) as c:
        st = steady_for(c, cfg)
        # Tight steady orbit: the pre-kick periods are the baseline.
        st = c.steady(guess=st.amplitude, tolerance=min(c.tolerance, 1e-6 / DAY))
        W, T = c.orbit_start(st), st.period
        params = {k: dict(v) for k, v in c.params.items()}
        params[c.pendulum].update(phi_start=0.0, w_start=W)
        m = c.system.master
        sysm = c.system
        offset = 0.0
        if at == "turning_point":
            from scipy.optimize import brentq

            def w_after(tau):
                m.reinitialize(params)
                advance_to(m, m.t + tau)
                return sysm.output(c.pendulum, "w")

            offset = brentq(w_after, 0.1 * T, 0.45 * T, xtol=1e-13)
        m.reinitialize(params)
        t0 = m.t
        n = max(0, math.ceil((t_kick - t0) / T - 1e-9))
        tk = t0 + n * T + offset
        if tk + duration >= stop:
            raise SimulationError(f"the kick at {tk:.6g} s does not end before experiment.stop")
        ticks: list[float] = []
        amps: list[float] = []
        rows = {k: [] for k in SAMPLED}
        state = {"tick": sysm.output(c.pendulum, "tick_time"), "amp": sysm.output(c.pendulum, "amplitude"),
                 "err": 0.0}

        def watch():
            a = sysm.output(c.pendulum, "amplitude")
            if a != state["amp"]:
                state["amp"] = a
                amps.append(a)
            tt = sysm.output(c.pendulum, "tick_time")
            if tt != state["tick"]:
                state["tick"] = tt
                if ticks:
                    Tn = tt - ticks[-1]
                    state["err"] += Tn - T
                    rows["time"].append(tt)
                    rows["period_s"].append(Tn)
                    rows["dT_over_T"].append(Tn / T - 1.0)
                    rows["amplitude_deg"].append(math.degrees(0.5 * (amps[-1] + amps[-2])) if len(amps) > 1
                                                 else math.nan)
                    rows["time_error_s"].append(state["err"])
                ticks.append(tt)

        # The start is itself a tick (phi = 0 rising): count it.
        ticks.append(t0)
        advance_to(m, tk, watch)
        phi_kick = sysm.output(c.pendulum, "phi")
        w_kick = sysm.output(c.pendulum, "w")
        pend = sysm.instances[c.pendulum]

        def set_g(value: float, until: float) -> None:
            # An input jump is a discontinuity like an event: the next step
            # checkpoints (so a replay never undoes the change) and restarts
            # input extrapolation.
            pend.set_values({"g_factor": value})
            m.discontinuity()
            saved = m.stats.states_saved
            m.step(min(m.settings.step, until - m.t))
            watch()
            if m.stats.states_saved == saved:
                raise SimulationError("no checkpoint after changing g_factor: a replay could undo it", time=m.t)
            advance_to(m, until, watch)

        set_g(factor, tk + duration)
        set_g(1.0, stop)
        stats = vars(m.stats).copy()
        out = c.result(st)
    t = np.asarray(rows["time"])
    rel = np.asarray(rows["dT_over_T"])
    amp = np.asarray(rows["amplitude_deg"])
    err = np.asarray(rows["time_error_s"])
    before = t < tk
    after = ~before
    A_ss = math.degrees(st.amplitude)
    k_max = int(np.argmax(np.abs(rel[after]))) if after.any() else 0
    out.update({
        "kick_start_s": tk,
        "kick_at": at,
        "kick_duration_s": duration,
        "g_factor": factor,
        "phi_at_kick_deg": math.degrees(phi_kick),
        "w_at_kick_rad_per_s": w_kick,
        "stationary_period_s": T,
        "baseline_max_abs_dT_over_T": float(np.max(np.abs(rel[before]))) if before.any() else None,
        "max_abs_dT_over_T": float(np.abs(rel[after])[k_max]) if after.any() else None,
        "max_dT_over_T_signed": float(rel[after][k_max]) if after.any() else None,
        "max_abs_dA_deg": float(np.nanmax(np.abs(amp[after] - A_ss))) if after.any() else None,
        "time_error_end_s": float(err[-1]) if len(err) else None,
        "time_error_max_abs_s": float(np.max(np.abs(err))) if len(err) else None,
        "ticks": len(ticks),
    })
    rows["dA_deg"] = list(amp - A_ss)
    return {"kind": "disturbance", "result": out, "series": rows, "statistics": stats}
