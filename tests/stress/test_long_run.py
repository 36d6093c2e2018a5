"""Phase drift of a long run: Hoyng's clock at point C (Fig. 3, Sec. V.B).

Hoyng's normalized pendulum (L = g = m = 1: omega0 = 1 rad/s, T0 = 2 pi s,
Q = 1/(2 eps)) with the model escapement (GrasshopperEscapement, torque mu0,
phi_r = phi0). Started on its co-simulated limit cycle (phi = 0, w = W* from
shooting), the k-th tick must come at k T; the reference T is the exact
orbit period of the monolithic scipy shooting (rtol 1e-12). The drift
t_k - k T_ref must stay within benchmarks/stability.py `drift_budget`,
derived from the per-period error measured by shooting plus the rounding
of absolute time.

His 110-day run is 4.8e6 periods (t up to 3.0e7 s). CI runs 2000 periods
from t = 0 and 300 periods from t = 3.0e7 s (the end of the 110 days: the
same floating-point time resolution); CLOCKWORK_STRESS=full runs the whole
4.8e6 periods (about 2 h at 1.4 ms per period; docs/stress.md).
"""

import math

import pytest

from stress_support import fmus, size  # noqa: F401 (first: puts benchmarks/ on sys.path)
import stability as st  # noqa: E402
from clockwork.errors import SimulationError  # noqa: E402
from clockwork.engine import MasterSettings  # noqa: E402

STEP = 1.0  # s in Hoyng's units, ~6 steps per period


@pytest.fixture(scope="module")
def orbit():
    ref = st.hoyng_reference()
    W, T_cs = st.cosim_limit_cycle(STEP)
    return ref, W, T_cs


def test_cosim_orbit_period_matches_the_reference(orbit):
    """Within 10 rtol of the FMUs' integrators (1e-11)."""
    ref, _, T_cs = orbit
    assert abs(T_cs - ref.period) / ref.period < 1e-10, (T_cs, ref.period)
    # Hoyng: at C the clock runs at its nominal rate to ~1e-8 (it gains about 1e-8).
    assert -3e-8 < ref.E_T < 0.0


@pytest.mark.parametrize("start,periods", [(0.0, size(2000, int(st.HOYNG_PERIODS_110_DAYS))),
                                           (st.HOYNG_PERIODS_110_DAYS * 2 * math.pi, size(300, 2000))],
                         ids=["from t=0", "from 110 days"])
def test_drift_stays_within_budget(orbit, start, periods):
    ref, W, T_cs = orbit
    r = st.drift_run(periods, start_time=start, step=STEP, W=W)
    assert r["periods"] == periods
    t_end = start + r["periods"] * ref.period
    budget = st.drift_budget(r["periods"], T_cs - ref.period, start, t_end)
    assert abs(r["drift_end_s"]) <= budget, (r["drift_end_s"], budget)
    assert r["max_abs_drift_s"] <= budget, (r["max_abs_drift_s"], budget)


def test_event_location_at_large_absolute_time_with_default_tolerance():
    pend, esc = st.hoyng_parameters()
    with st.clock_system(dict(pend, phi_start=0.0, w_start=0.0495), esc, MasterSettings(step=STEP),
                         start_time=1.0e6) as s:
        try:
            s.master.run_until(1.0e6 + 3 * 2 * math.pi)
        except SimulationError as e:
            pytest.fail(str(e))
        assert s.master.stats.events == 6
