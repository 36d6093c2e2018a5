"""Hoyng Figs. 4, 5: the clock's answer to a jump of the driving torque.

``hoyng_torque_jump``: start on the stationary swing (phi = 0, dphi/dt =
lambda of Eq. 19), switch escapement.torque at ``jump_at_periods``; rates
from the tick periods (Eq. 22), amplitudes from the Pendulum's turning
points, beside Eq. (16) with Eq. (18); the phase shift Delta psi measured
and from clockwork.physics.analytic.
"""

from __future__ import annotations

import math

import numpy as np

from ...errors import SimulationError
from ...physics import analytic
from ...scene.kinds import Invalid
from .. import keys
from ..context import build_system, experiment
from ..registry import register
from ..time_series import run_with_progress
from .common import TWO_PI, check_grasshopper_clock, grasshopper_clock, linfit, second_order


_KEYS = {"jump_at_periods": keys.number(0, keys.MAX_COUNT, lo_open=True, also="required; the jump, "
                                        "jump_at_periods nominal periods after experiment.start, inside the experiment"),
         "torque_after": keys.torque_in(0, None, also="required; within the GrasshopperEscapement FMU's range of torque"),
         "stationary_start": keys.flag(),
         "tail_start_periods": keys.number(0, keys.MAX_COUNT, lo_open=True)}


def _check(scene, point: dict) -> None:
    """What hoyng_torque_jump refuses at run time: both keys given, the jump
    inside the experiment, a torque the escapement takes."""
    check_grasshopper_clock(scene, "hoyng_torque_jump")
    cfg = scene.analysis or {}
    for key in ("jump_at_periods", "torque_after"):
        if key not in cfg:
            raise Invalid(key, f"a value: hoyng_torque_jump needs analysis.{key}")
    pend, esc, _, _, _, _, n = grasshopper_clock(scene, point, "hoyng_torque_jump")
    start, stop = experiment(scene, point)
    t_jump = start + cfg["jump_at_periods"] * n["T0"]
    if not start < t_jump < stop:
        raise Invalid("jump_at_periods", f"a jump inside the experiment: at most {(stop - start) / n['T0']:.6g} "
                                         f"nominal periods of {n['T0']:.6g} s")
    keys.within_fmu(scene, "torque_after", esc, "torque", (cfg["torque_after"],), "the torque after the jump")


# The result's keys (the literal `res` below and what follows it).
COLUMNS = {"eps", "mu0", "mu1", "phi0_rad", "periods", "jump_at_periods", "rate_before", "rate_eq20_A",
           "lambda_eq19_A_rad", "amplitude_before_rad", "rate_after_jump", "rate_eq16_after_jump",
           "rate_eq16_at_jump", "rate_eq20_B", "lambda_eq19_B_rad", "amplitude_final_rad",
           "amplitude_eq18_max_rel_diff", "rate_eq16_max_diff", "next_order_bound_amplitude",
           "next_order_bound_rate", "delta_psi_sim", "rate_final", "delta_psi_eq", "t_end_s"}


@register("hoyng_torque_jump", set(_KEYS), keys.table_converter(_KEYS), columns=COLUMNS, check=_check,
          series={"tick_time_s", "periods", "rate", "rate_eq16_eq18", "amplitude_rad", "amplitude_eq18_rad"})
def hoyng_torque_jump(scene, point: dict, progress: bool = False) -> dict:
    cfg = scene.analysis or {}
    pend, esc, _, params, pp, ep, n = grasshopper_clock(scene, point, "hoyng_torque_jump")
    eps, mu0, phi0, w0 = n["eps"], n["mu"], n["phi0"], n["w0"]
    if "torque_after" not in cfg or "jump_at_periods" not in cfg:
        raise SimulationError("hoyng_torque_jump needs analysis.jump_at_periods and analysis.torque_after")
    mu1 = cfg["torque_after"] / n["mgl"]
    start, stop = experiment(scene, point)
    t_jump = start + cfg["jump_at_periods"] * n["T0"]
    if not start < t_jump < stop:
        raise SimulationError("hoyng_torque_jump: the jump must fall inside the experiment")
    lam0 = analytic.hoyng_stationary_amplitude(mu0, eps, phi0)
    pt = dict(point)
    if cfg.get("stationary_start", True):
        pt[(pend, "phi_start")] = 0.0
        pt[(pend, "w_start")] = lam0 * w0  # Eq. (19): phi = 0, dphi/dtau = lambda
    system = build_system(scene, pt, record={pend: ["tick_time", "amplitude", "phi"]})
    ticks, amps, phi_t, phi_v = [], [], [], []
    phi_until = min(stop, 2.0 * t_jump)
    with system:
        m = system.master
        port = m.ports[pend]
        i_tick, i_amp, i_phi = (port.out_names.index(x) for x in ("tick_time", "amplitude", "phi"))
        out = port.out
        last = [out[i_tick]]

        def on_point(master):
            tt = out[i_tick]
            if tt != last[0]:
                last[0] = tt
                ticks.append(tt)
                amps.append(out[i_amp])
            if master.t <= phi_until:
                phi_t.append(master.t)
                phi_v.append(out[i_phi])

        phi_t.append(m.t)
        phi_v.append(out[i_phi])
        run_with_progress(m, t_jump, on_point, progress, label=f"{scene.path.stem} (before jump)")
        system.instances[esc].set_values({"torque": cfg["torque_after"]})
        m.discontinuity()  # the escapement's outputs are read again after its next commit
        run_with_progress(m, stop, on_point, progress, label=f"{scene.path.stem} (after jump)")
        stats = vars(m.stats).copy()
    t = np.asarray(ticks)
    if len(t) < 20:
        raise SimulationError(f"hoyng_torque_jump: only {len(t)} ticks")
    tau = w0 * (t - start)
    tau_j = w0 * (t_jump - start)
    rate = TWO_PI / np.diff(tau) - 1.0  # Eq. (22)
    tau_mid = 0.5 * (tau[1:] + tau[:-1])
    # The amplitude output at a tick is |phi| at the left turning point, a quarter period earlier.
    tau_amp = tau - 0.5 * math.pi
    amp = np.asarray(amps)

    def lam18(x):
        return analytic.hoyng_amplitude_after_jump(np.asarray(x) - tau_j, mu0, mu1, eps, phi0)

    mu_at = np.where(tau_mid < tau_j, mu0, mu1)
    rate16 = np.array([analytic.hoyng_rate(l, m_, phi0) for l, m_ in zip(lam18(tau_mid), mu_at)])
    amp18 = lam18(tau_amp)
    before = tau[1:] < tau_j
    after = tau[:-1] >= tau_j  # periods that start after the jump
    res = {"eps": eps, "mu0": mu0, "mu1": mu1, "phi0_rad": phi0, "periods": len(t),
           "jump_at_periods": cfg["jump_at_periods"]}
    res["rate_before"] = float(np.mean(rate[before][-20:]))
    res["rate_eq20_A"] = analytic.hoyng_stationary_rate(mu0, eps, phi0)
    res["lambda_eq19_A_rad"] = lam0
    res["amplitude_before_rad"] = float(amp[tau_amp < tau_j][-1])
    k_after = int(np.argmax(after))
    res["rate_after_jump"] = float(rate[k_after])
    res["rate_eq16_after_jump"] = float(rate16[k_after])
    res["rate_eq16_at_jump"] = float(analytic.hoyng_rate(lam0, mu1, phi0))
    res["rate_eq20_B"] = analytic.hoyng_stationary_rate(mu1, eps, phi0)
    res["lambda_eq19_B_rad"] = analytic.hoyng_stationary_amplitude(mu1, eps, phi0)
    res["amplitude_final_rad"] = float(amp[-1])
    post_amp = tau_amp >= tau_j
    res["amplitude_eq18_max_rel_diff"] = float(np.max(np.abs(amp[post_amp] / amp18[post_amp] - 1.0)))
    res["rate_eq16_max_diff"] = float(np.max(np.abs(rate[after] - rate16[after])))
    lamB = res["lambda_eq19_B_rad"]
    # Relative amplitude: first-order quantities eps and lambda^2/16 (turning point vs KBM lambda).
    res["next_order_bound_amplitude"] = lamB**2 / 16.0 + eps
    # Rate: second order, largest right after the jump (mu1 at lambda_A).
    res["next_order_bound_rate"] = second_order(
        eps, lam0**2 / 16.0, res["rate_eq16_at_jump"] + lam0**2 / 16.0)
    # Delta psi = int (rate - rate_B) dt from the jump on: fit the tail with
    # psi = a + b tau + c exp(-2 eps (tau - tau_j)); then Delta psi = a + b tau_j - psi(tau_j).
    psi = TWO_PI * np.arange(1, len(t) + 1)
    tail_from = tau_j + cfg.get("tail_start_periods", 0.0) * TWO_PI
    if not cfg.get("tail_start_periods"):
        tail_from = tau_j + 1.5 / eps
    tail = tau >= tail_from
    pre = np.nonzero(tau < tau_j)[0]
    if tail.sum() >= 20 and len(pre) >= 10:
        x = tau[tail] - tau_j
        X = np.column_stack([np.ones_like(x), x, np.exp(-2.0 * eps * x)])
        coef, *_ = np.linalg.lstsq(X, psi[tail], rcond=None)
        a, b = coef[0], coef[1]
        # psi(tau_j) from the stationary pre-jump rate, extrapolated from the last 20 ticks.
        k = pre[-20:]
        a0, b0 = linfit(tau[k], psi[k])
        psi_j = a0 + b0 * tau_j
        res["delta_psi_sim"] = float(a - psi_j)  # a is psi at tau_j on the final line
        res["rate_final"] = float(b - 1.0)
    else:
        res["delta_psi_sim"] = math.nan
        res["rate_final"] = float(np.mean(rate[-20:]))
    res["delta_psi_eq"] = analytic.hoyng_phase_shift(mu0, mu1, eps, phi0)
    res["t_end_s"] = stop
    series = {
        "tick_time_s": t[1:].tolist(),
        "periods": (tau[1:] / TWO_PI).tolist(),
        "rate": rate.tolist(),
        "rate_eq16_eq18": rate16.tolist(),
        "amplitude_rad": amp[1:].tolist(),
        "amplitude_eq18_rad": amp18[1:].tolist(),
    }
    return {"kind": "hoyng_torque_jump", "result": res, "series": series, "ticks": ticks,
            "statistics": stats, "phi_series": {"time_s": phi_t, "phi_rad": phi_v}}
