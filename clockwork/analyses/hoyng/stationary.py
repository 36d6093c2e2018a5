"""Hoyng Fig. 3 and App. C: the stationary rate, simulated beside theory.

``hoyng_stationary``: the co-simulated periodic orbit (shooting, like
``steady_state``) of a Pendulum with a GrasshopperEscapement (Hoyng's model
escapement, phi0 = phi_r) or a narrow ChronometerEscapement window (App.
C's single impulse at the window's centre phi1, energy e = torque * width
per period). Beside the simulated rate psi-dot - 1 = T0/T - 1: Eq. (19)/(20),
or Eq. (C6). An AveragedPendulum in the scene is made the pendulum's twin
(same L, g, m, Q, escapement geometry and drive), started 10 % off its
stationary amplitude and run for 40/eps into its stationary state.
"""

from __future__ import annotations

import math

from ...errors import SimulationError
from ...physics import analytic
from ...scene.kinds import Invalid
from .. import escapements, keys
from ..context import build_system, parameters
from ..registry import register
from ..steady_state import COLUMNS as STEADY_COLUMNS, MAX_PERIODS, TOLERANCE, clock_check, steady_state
from .common import DAY, TWO_PI, hoyng_components, normalized, second_order, subscene, twin_values


_KEYS = {"tolerance_s_per_day": TOLERANCE, "max_periods": MAX_PERIODS}


def _check(scene, point: dict) -> None:
    pend, esc, avgs = hoyng_components(scene)
    if pend is None or esc is None:
        raise Invalid("kind", "a scene with a Pendulum and an escapement for hoyng_stationary")
    clock_check(subscene(scene, set(scene.components) - set(avgs)), point, "hoyng_stationary")


def _twin_columns(avg: str) -> tuple[str, str]:
    """The result's (rate, amplitude) columns of an AveragedPendulum twin."""
    return f"rate_{avg}", f"amplitude_{avg}_rad"


# What hoyng_stationary adds to the steady state's result (some per escapement, some not when stalled).
ADDED_COLUMNS = {"kind_hoyng", "eps", "mu", "phi0_rad", "rate_eq20", "lambda_eq19_rad", "rate_eq16_bessel", "e",
                 "phi1_rad", "window_rad", "rate_C6", "lambda_C4_rad", "rate_theory", "rate_theory_s_per_day",
                 "rate_circular_term", "rate_escapement_term", "next_order_bound", "rate_sim", "rate_sim_s_per_day",
                 "amplitude_rad", "rate_diff", "amplitude_rel_diff"}


def columns(scene) -> set[str]:
    return STEADY_COLUMNS | ADDED_COLUMNS | {c for a in hoyng_components(scene)[2] for c in _twin_columns(a)}


@register("hoyng_stationary", set(_KEYS), keys.table_converter(_KEYS), columns=columns, series=set(), check=_check)
def hoyng_stationary(scene, point: dict, progress: bool = False) -> dict:
    pend, esc, avgs = hoyng_components(scene)
    if pend is None or esc is None:
        raise SimulationError("hoyng_stationary needs a Pendulum and an escapement")
    params = parameters(scene, point)
    esc_model = scene.components[esc].model_description.modelName
    pp, ep = params[pend], params[esc]
    n = normalized(pp, esc_model, ep)
    eps = n["eps"]
    cosim = subscene(scene, set(scene.components) - set(avgs))
    out = steady_state(cosim, point, progress=progress)
    res = out["result"]
    res["kind_hoyng"] = esc_model
    res["eps"] = eps
    stalled = bool(res.get("stalled"))
    if esc_model == "GrasshopperEscapement":
        mu, phi0 = n["mu"], n["phi0"]
        res["mu"] = mu
        res["phi0_rad"] = phi0
        lam = analytic.hoyng_stationary_amplitude(mu, eps, phi0) if mu > analytic.hoyng_min_torque(eps, phi0) else math.nan
        rate_theory = analytic.hoyng_stationary_rate(mu, eps, phi0)
        circ = mu * phi0 / (8.0 * math.pi * eps)
        esc = rate_theory + circ
        res["rate_eq20"] = rate_theory
        res["lambda_eq19_rad"] = lam
        res["rate_eq16_bessel"] = float(analytic.hoyng_rate(lam, mu, phi0, bessel=True)) if math.isfinite(lam) else math.nan
    else:
        e, phi1 = n["e"], n["phi1"]
        res["e"] = e
        res["phi1_rad"] = phi1
        res["window_rad"] = n["width"]
        lam = math.sqrt(e / (TWO_PI * eps))
        rate_theory = analytic.single_impulse_stationary_rate(e, eps, phi1) if abs(phi1) < lam else math.nan
        circ = e / (32.0 * math.pi * eps)
        esc = rate_theory + circ
        res["rate_C6"] = rate_theory
        res["lambda_C4_rad"] = lam
    res["rate_theory"] = rate_theory
    res["rate_theory_s_per_day"] = rate_theory * DAY
    res["rate_circular_term"] = -circ
    res["rate_escapement_term"] = esc
    res["next_order_bound"] = second_order(eps, circ, esc)
    if not stalled:
        T = res["period_s"]
        rate = n["T0"] / T - 1.0
        res["rate_sim"] = rate
        res["rate_sim_s_per_day"] = rate * DAY
        res["amplitude_rad"] = math.radians(res["amplitude_deg"])
        res["rate_diff"] = rate - rate_theory
        res["amplitude_rel_diff"] = res["amplitude_rad"] / lam - 1.0
    for a in avgs:
        r_avg, lam_avg = _averaged_stationary(scene, point, a, pp, esc_model, ep, n, lam)
        rate_column, amplitude_column = _twin_columns(a)
        res[rate_column] = r_avg
        res[amplitude_column] = lam_avg
    return out


def _averaged_stationary(scene, point, avg, pp, esc_model, ep, n, lam):
    """Stationary (rate - 1, amplitude) of the AveragedPendulum twin, by running it."""
    if not math.isfinite(lam) or n["eps"] <= 0:
        return math.nan, math.nan
    sub = subscene(scene, {avg})
    pt = {k: v for k, v in point.items() if k[0] == avg}
    pt.update(twin_values(avg, pp, esc_model, ep))
    drive = escapements.ESCAPEMENTS[esc_model].drive(ep, n)
    pt[(avg, "drive")] = drive
    pt[(avg, "amplitude_start")] = 1.1 * lam
    pt[(avg, "phase_start")] = 0.0
    horizon = 40.0 / (n["eps"] * n["w0"])  # lambda^2 relaxes as exp(-2 eps t): e^-80
    pt[("master", "step")] = horizon / 20.0
    pt[("master", "max_step")] = horizon / 20.0
    pt[("experiment", "start")] = 0.0
    system = build_system(sub, pt, record={avg: ["amplitude", "rate"]})
    with system:
        system.master.run_until(horizon)
        return system.output(avg, "rate") - 1.0, system.output(avg, "amplitude")
