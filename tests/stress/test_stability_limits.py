"""Stability limits of the pendulum-vibration coupling (Ziemkiewicz Eq. 7).

Pendulum + MechanismVibration (C1 = 1, omega02 = 7 sqrt(9.81), gamma2 =
gamma1/100, pendulum undamped at 5 deg, mechanism started at 1 mrad) with
the communication step swept past the stability limit of each master
configuration. The measure (benchmarks/stability.py: `amplification`) is
the energy amplification per pendulum period beyond the monolithic
reference, of the mechanism's free mode and of the coupled energy H;
unstable above 1 % per period.

Delay theory at small steps: a coupling input held over a step (ZOH) lags
by h/2 on average. The mechanism's quasi-static response to the pendulum is
a stiffness k = C1 C2/(omega02^2 - omega01^2) in the loop; a loop delay d
turns it into a damping k d of the pendulum mode and an equal anti-damping
of the mechanism mode. Jacobi delays both directions (d = h), Gauss-Seidel
feeds the second FMU the first one's new value (a lead of h/2 against the
lag of h/2: d = 0). Per period T0 the energy then changes by k d T0.
"""

import math

import pytest

from stress_support import FULL, fmus, size  # noqa: F401 (first: puts benchmarks/ on sys.path)
import stability as st  # noqa: E402

COUPLINGS = size([st.Coupling(0.0, 5.0), st.Coupling(1e9, 5.0)],
                 [st.Coupling(k, c2) for k in (0.0, 1e7, 1e9) for c2 in (2.5, 5.0)])
# Growth at small steps is smooth (E_free varies by < 1 % there): few periods do.
SMALL_STEP_PERIODS = size(8, 40)


def _configs(richardson: bool):
    # Richardson with ZOH costs ~10 s per run (step doubling at 1e-8): full size only.
    return [c for c in st.all_configs()
            if c.richardson == richardson and (FULL or not (c.richardson and c.extrapolation == 0))]


@pytest.mark.parametrize("coupling", COUPLINGS, ids=lambda c: c.label)
def test_small_step_is_stable_for_every_configuration(coupling):
    bad = []
    for cfg in _configs(False) + _configs(True):
        for h in size([0.04], [0.01, 0.04]):
            r = st.amplification(coupling, cfg, h, SMALL_STEP_PERIODS)
            if r["unstable"]:
                bad.append((cfg.label, h, r["amplification"], r["error"]))
    assert not bad, bad


@pytest.mark.parametrize("h", size([0.02], [0.01, 0.02]))
def test_small_step_growth_follows_the_delay_theory(h):
    """Jacobi + ZOH: the mechanism mode gains and the pendulum mode loses
    k h T0 per period; Gauss-Seidel + ZOH has no loop delay. Allowed: the
    neglected (omega02 h)^2 of the small-delay expansion (0.05 and 0.19
    here) in the mechanism, (omega01 h)^2 < 0.004 in the pendulum."""
    c = st.Coupling(0.0, 5.0)
    k = c.C1 * c.C2 / (c.omega02**2 - st.OMEGA01**2)
    per_period = k * h * st.T0
    jacobi = st.amplification(c, st.Config("jacobi", 0), h, 40)
    gs = st.amplification(c, st.Config("gauss-seidel", 0), h, 40)
    slack = 1.5 * (c.omega02 * h) ** 2 + 0.05
    assert abs((jacobi["A_vib"] - 1.0) / per_period - 1.0) < slack, (jacobi["A_vib"], per_period)
    assert abs((1.0 - jacobi["A_energy"]) / per_period - 1.0) < 0.05, (jacobi["A_energy"], per_period)
    assert abs(gs["A_vib"] - 1.0) < 0.2 * per_period, (gs["A_vib"], per_period)
    assert abs(gs["A_energy"] - 1.0) < 0.05 * per_period, (gs["A_energy"], per_period)


def test_the_sweep_reaches_the_stability_limit():
    """Jacobi with quadratic extrapolation turns unstable within the swept
    steps (and, run on, diverges: test_divergence.py)."""
    c = st.Coupling(0.0, 5.0)
    rows = st.limit_sweep([c], [st.Config("jacobi", 2)], st.step_grid(size(0.16, 0.01), 1.3, 1), 40)
    limit, first_bad, _ = st.stability_limit(rows)
    table = [(r["step_s"], round(r["amplification"], 4), r["periods"]) for r in rows]
    assert limit >= size(0.16, 0.01), table
    assert first_bad is not None, table


@pytest.mark.parametrize("coupling", size(COUPLINGS[:1], COUPLINGS), ids=lambda c: c.label)
def test_fixed_point_iterations_hold_at_every_step(coupling):
    """Five fixed-point iterations per step (linear interpolation of the
    coupling signals) hold up to steps longer than a pendulum period
    (small steps: test_small_step_is_stable_for_every_configuration)."""
    bad = []
    for order in ("gauss-seidel", "jacobi"):
        for h in st.step_grid(size(0.32, 0.04), 2.6, 1):
            r = st.amplification(coupling, st.Config(order, 0, 5), h, 40)
            if r["unstable"]:
                bad.append((order, h, r["amplification"]))
    assert not bad, bad


def test_one_way_coupling_is_stable_at_any_step():
    """C2 = 0: the pendulum does not act on the mechanism, there is no loop to
    destabilize; every configuration holds at steps longer than a period."""
    c = st.Coupling(1e9, 0.0)
    bad = []
    for cfg in _configs(False):
        for h in (1.28, 2.56):
            r = st.amplification(c, cfg, h, size(8, 40))
            if r["unstable"]:
                bad.append((cfg.label, h, r["amplification"]))
    assert not bad, bad


def test_richardson_holds_at_a_step_far_past_the_limit():
    """Step-doubling control shrinks the step below the limit by itself."""
    c = st.Coupling(0.0, 5.0)
    for cfg in (st.Config("gauss-seidel", 1, richardson=True), st.Config("jacobi", 2, richardson=True)):
        r = st.amplification(c, cfg, 2.56, size(8, 40))
        assert not r["unstable"], (cfg.label, r["amplification"])


def _richardson_steps(max_step):
    from clockwork.engine import MasterSettings

    settings = MasterSettings(step=0.01, max_step=max_step, richardson=True, richardson_tolerance=1e-4)
    times = []
    with st.vibration_system(st.Coupling(0.0, 5.0), settings) as s:
        s.master.run_until(5.0, lambda m: times.append(m.t))
    return [b - a for a, b in zip([0.0] + times, times)]


def test_richardson_respects_max_step():
    """A loose tolerance lets the controller grow the step; max_step caps it."""
    assert max(_richardson_steps(None)) > 0.05
    steps = _richardson_steps(0.01)
    assert max(steps) <= 0.01 * (1 + 1e-9), max(steps)


def test_iterations_are_not_ignored_under_richardson():
    """Either the combination works (iterations happen) or it is refused."""
    from clockwork.errors import SceneError
    from clockwork.engine import MasterSettings

    outs = []
    for iterations in (0, 5):
        try:  # refused where the settings are made, or where the system is
            settings = MasterSettings(step=0.3, richardson=True, richardson_tolerance=1e-5, iterations=iterations)
            system = st.vibration_system(st.Coupling(0.0, 5.0), settings)
        except (ValueError, SceneError):
            return  # refused with a clear error: fine
        with system as s:
            s.master.run_until(4.0)
            outs.append((list(s.master.ports["pendulum"].out), s.master.stats.coupling_iterations))
    assert outs[1][1] > 0 and outs[0][0] != outs[1][0], outs


def test_energy_balance_of_the_measure():
    """The measure itself: along the monolithic solution of the stiffest
    coupling swept, H changes only by the gamma2 loss, dH/dt = -C1 gamma2 a2dot^2."""
    import numpy as np
    from scipy.integrate import trapezoid

    c = st.Coupling(1e9, 5.0)
    t = np.linspace(0.0, 10 * st.T0, 40001)
    y = st.vibration_reference(c, 10 * st.T0)(t)
    _, H = st.energies(c, y)
    loss = trapezoid(c.C1 * c.gamma2 * y[3] ** 2, t)
    assert loss > 0 and math.isclose(H[0] - H[-1], loss, rel_tol=1e-2), (H[0] - H[-1], loss)
