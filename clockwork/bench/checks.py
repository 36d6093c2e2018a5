"""The reference checked before any row: against closed forms, itself and the co-simulation."""

from __future__ import annotations


import numpy as np

from ..physics import analytic, reference
from .config import DAY, DEG, Family, TARGET_S_PER_DAY
from .masters import master_steady
from .problems import Hoyng, SteadyPoint, mean_amplitude, steady_point


def reference_checks(point: SteadyPoint | None = None) -> list[dict]:
    """The reference against closed forms, itself and the co-simulation.

    Each check has a bound with its reason; `ok` is value <= bound.
    """
    checks = []

    def add(name, value, bound, unit, reason):
        checks.append({"check": name, "value": float(value), "bound": float(bound), "unit": unit,
                       "ok": bool(abs(value) <= bound), "reason": reason})

    # 1. Free pendulum against the AGM period.
    A = 5 * DEG
    free = reference.ClockParams(Q=0.0, escapement="none")
    r = reference.simulate(free, A, 0.0, 3.5 * free.T0)
    T = float(np.mean(np.diff(r.ticks)))
    T_agm = analytic.exact_period(A, free.L, free.g)
    add("free pendulum at 5 deg: period / AGM period - 1", T / T_agm - 1.0, 100 * reference.RTOL, "-",
        "a hundred times the integrator's rtol")

    # 2. Shooting against plain integration along the orbit it found.
    pt = point or steady_point("fig4a_5deg")
    ss = pt.ref
    run = reference.simulate(pt.params, ss.amplitude, 0.0, 20.5 * ss.period)
    periods = np.diff(run.ticks)
    add(f"{pt.key}: 20 periods integrated from the shot orbit: max |T_i/T - 1|",
        float(np.max(np.abs(periods / ss.period - 1.0))), 100 * reference.RTOL, "-",
        "a hundred times the integrator's rtol")
    add(f"{pt.key}: amplitude after 20 periods / shot amplitude - 1",
        float(run.turn_phi[run.turn_phi > 0][-1] / ss.amplitude - 1.0), 100 * reference.RTOL, "-",
        "a hundred times the integrator's rtol")

    # 3. Self-convergence: rtol 1e-12 against 1e-10.
    coarse = reference.steady_state(pt.params, rtol=1e-10)
    add(f"{pt.key}: E_T at rtol 1e-10 minus E_T at 1e-12", (coarse.E_T - ss.E_T) * DAY, 0.01 * TARGET_S_PER_DAY,
        "s/day", "1 % of the 1e-3 s/day the bench resolves")

    # 4. Hoyng's stationary swing, Eqs. (19) and (20), normalized units.
    h = Hoyng()
    hs = reference.steady_state(h.params(h.mu0))
    lam = h.lam0
    add("Hoyng point A: turning amplitude / Eq. (19) lambda - 1", mean_amplitude(hs) / lam - 1.0,
        lam**2 / 16.0 + h.eps, "-", "first-order quantities lambda^2/16 + eps left out of Eq. (19)")
    rate = 1.0 / (1.0 + hs.E_T) - 1.0  # psi-dot - 1 = T0/T - 1
    eq20 = analytic.hoyng_stationary_rate(h.mu0, h.eps, h.phi0)
    esc = eq20 + lam**2 / 16.0
    # Second order in eps, lambda^2/16 and the escapement term, as in analyses/hoyng.py.
    add("Hoyng point A: rate psi-dot - 1 minus Eq. (20)", rate - eq20, (h.eps + lam**2 / 16.0 + abs(esc)) ** 2,
        "-", "second-order terms of the KBM averaging (products and squares of eps, lambda^2/16, escapement term)")

    # 5. The co-simulation's most accurate configuration against the reference.
    fam = Family("check", {}, ())
    E_T = master_steady(pt, fam, 0.5, 1e-12, {}, tolerance=1e-6 / DAY)
    add(f"{pt.key}: co-simulation (shooting, h = 0.5 s, FMU rtol 1e-12) E_T minus reference",
        (E_T - ss.E_T) * DAY, 0.01 * TARGET_S_PER_DAY, "s/day", "1 % of the 1e-3 s/day the bench resolves")
    return checks
