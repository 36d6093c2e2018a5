"""The co-simulation master against the monolithic reference and theory."""

import dataclasses
import math

import numpy as np
import pytest
from scipy.integrate import quad, solve_ivp

from clockwork.physics import analytic, reference
from clockwork.errors import SimulationError
from clockwork.engine import MasterSettings
from clockwork.analyses.steady_state import energy_balance_amplitude, find_steady_state
from clockwork.engine.shooting import Shooter
from clockwork.engine import System

from cwtest import FMU_DIR, test_fmu

GRASSHOPPER_LINKS = [
    "pendulum.phi -> escapement.phi",
    "pendulum.w -> escapement.w",
    "escapement.tau -> pendulum.tau_escapement",
]
PEND = {"L": 1.0, "m": 1.0, "g": 9.81, "Q": 1000.0}


@pytest.fixture(autouse=True)
def _fmus(monkeypatch):
    monkeypatch.setenv("CLOCKWORK_FMU_DIR", str(FMU_DIR))


@pytest.fixture(autouse=True, params=["python", "compiled"])
def engine(request, monkeypatch):
    """Every test here on both engines: the Python reference loop and the
    compiled core (where the core does not reach, the Python master runs)."""
    from clockwork.engine import compiled, system

    def make(instances, links, settings, *args, **kw):
        wanted = request.param if request.param == "python" or not compiled.unsupported(settings) else "auto"
        return compiled.make_master(instances, links, dataclasses.replace(settings, engine=wanted), *args, **kw)

    monkeypatch.setattr(system, "make_master", make)
    return request.param


def grasshopper(torque, phi_r_deg=2.0, Q=1000.0, step=0.5, predict=True, **pend):
    params = {"pendulum": dict(Q=Q, rtol=1e-12, atol=1e-14, **pend),
              "escapement": dict(torque=torque, phi_r=math.radians(phi_r_deg))}
    sysm = System({"pendulum": ("Pendulum", params["pendulum"]),
                   "escapement": ("GrasshopperEscapement", params["escapement"])},
                  GRASSHOPPER_LINKS, MasterSettings(step=step, event_prediction=predict),
                  record={"pendulum": ["tick_time", "tick_w", "amplitude"]})
    return sysm, params


@pytest.mark.parametrize("torque", [0.002, 0.004])
def test_steady_state_rate_matches_monolithic_reference(torque):
    """Co-simulated steady-state rate within 1e-3 s/day of scipy DOP853 shooting."""
    sysm, params = grasshopper(torque)
    with sysm:
        pp = dict(PEND)
        guess = energy_balance_amplitude(pp, "GrasshopperEscapement", params["escapement"])
        shooter = Shooter(sysm.master, params, "pendulum", pp)
        ours = find_steady_state(shooter, guess, math.radians(2.0))
    ref = reference.steady_state(reference.ClockParams(escapement="grasshopper", torque=torque,
                                                       phi_r=math.radians(2.0), Q=1000.0))
    assert not ours.stalled and not ref.stalled
    diff_s_per_day = abs(ours.E_T - ref.E_T) * analytic.SECONDS_PER_DAY
    assert diff_s_per_day < 1e-3, (ours.E_T, ref.E_T)
    assert abs(ours.amplitude - ref.amplitude) < 1e-8


def test_switch_time_is_located_to_1e_10_s():
    """The first torque switch lands within 1e-10 s of the exact crossing of phi_r.

    Undamped pendulum from phi = 0 with speed w0 and constant torque M:
    w(phi)^2 = w0^2 + 2 (M/I) phi - 2 (g/L)(1 - cos phi); the crossing time
    of phi_r is the quadrature of dphi/w.
    """
    M, phi_r, w0 = 0.004, math.radians(2.0), 0.2
    sysm = System({"pendulum": ("Pendulum", dict(Q=0.0, phi_start=0.0, w_start=w0, rtol=1e-13, atol=1e-15)),
                   "escapement": ("GrasshopperEscapement", dict(torque=M, phi_r=phi_r))},
                  GRASSHOPPER_LINKS, MasterSettings(step=0.37))
    with sysm:
        m = sysm.master
        while m.stats.events == 0:
            m.step(0.37)
        t_landed = m.t
        mode = sysm.instances["escapement"].get_integer(["mode"])[0]
    # 1 - cos(phi) as 2 sin^2(phi/2): no cancellation at small angles. The
    # tolerance is what doubles reach on a time of 0.18 s: asked for 1e-15 s
    # absolute (5 ulp), quadpack warns that roundoff prevents it.
    speed = lambda phi: math.sqrt(w0 ** 2 + 2 * M * phi - 4 * 9.81 * math.sin(phi / 2) ** 2)
    t_exact, err = quad(lambda phi: 1.0 / speed(phi), 0.0, phi_r, epsabs=0.0, epsrel=1e-13)
    assert err < 1e-13
    assert mode == -1
    assert t_landed >= t_exact - 1e-12
    assert abs(t_landed - t_exact) < 1e-10, (t_landed, t_exact)


def test_event_location_makes_the_result_independent_of_the_step():
    results = []
    for step in (0.5, 0.05):
        sysm, _ = grasshopper(0.004, step=step, phi_start=math.radians(5))
        with sysm:
            sysm.master.run_until(40.0)
            results.append((sysm.output("pendulum", "tick_time"), sysm.output("pendulum", "phi")))
    assert abs(results[0][0] - results[1][0]) < 1e-10
    assert abs(results[0][1] - results[1][1]) < 1e-9


def _oscillator_events(derivative_error: float, predict: bool, t_end: float = 30.0):
    """An exact oscillator (TestOscillator) through the escapement's
    switches at |x| = 0.05: the times the master located them at, and its
    statistics. derivative_error makes the derivatives it reports wrong."""
    comps = {"osc": (str(test_fmu("TestOscillator")), dict(amplitude=0.1, omega=3.0,
                                                          derivative_error=derivative_error)),
             "escapement": ("GrasshopperEscapement", dict(torque=1e-3, phi_r=0.05))}
    times = []
    with System(comps, ["osc.x -> escapement.phi", "osc.v -> escapement.w"],
                MasterSettings(step=0.3, event_prediction=predict)) as s:
        m = s.master
        while m.t < t_end:
            events = m.stats.events
            m.step(min(0.3, t_end - m.t))
            if m.stats.events > events:
                times.append(m.t)
        return times, m.stats


def test_predicted_switches_are_landed_on_without_rollback():
    """With event prediction, each switch is landed on by steps shortened
    before they are taken (from the Hermite polynomial through the last
    step), with no rollback and no location trial, at the times the
    locator finds without prediction (to its 1e-10 s)."""
    located, plain = _oscillator_events(0.0, predict=False)
    predicted, stats = _oscillator_events(0.0, predict=True)
    assert len(located) == len(predicted) == 28
    assert stats.predicted_landings == stats.events == 28
    assert stats.rollbacks == stats.event_iterations == stats.mispredicted == 0
    assert plain.rollbacks == 56
    assert max(abs(a - b) for a, b in zip(located, predicted)) <= 1e-10


def test_a_missed_prediction_is_caught_by_the_safety_net():
    """Output derivatives 30 % wrong mislead the prediction: its steps cross
    a switch beyond the tolerance; those are replayed from the last
    checkpoint and located as without prediction, to the same bits."""
    located, _ = _oscillator_events(0.3, predict=False)
    predicted, stats = _oscillator_events(0.3, predict=True)
    assert stats.mispredicted > 10 and stats.replays == stats.mispredicted
    assert predicted == located


def test_without_event_location_the_switch_is_smeared():
    """The same clock without event location is wrong by O(step): the reason to locate."""
    ticks = {}
    for located in (True, False):
        sysm = System({"pendulum": ("Pendulum", dict(Q=1000.0, phi_start=math.radians(5))),
                       "escapement": ("GrasshopperEscapement", dict(torque=0.004, phi_r=math.radians(2)))},
                      GRASSHOPPER_LINKS, MasterSettings(step=0.05, event_location=located),
                      record={"pendulum": ["tick_time"]})
        with sysm:
            sysm.master.run_until(40.0)
            ticks[located] = sysm.output("pendulum", "tick_time")
    assert abs(ticks[True] - ticks[False]) > 1e-4


def test_rollback_is_deterministic():
    """Two identical runs with many rollbacks agree bit for bit (prediction
    off: it lands on most switches without one)."""
    runs = []
    for _ in range(2):
        sysm, _ = grasshopper(0.004, step=0.3, predict=False, phi_start=math.radians(6))
        with sysm:
            sysm.master.run_until(30.0)
            p = sysm.master.ports["pendulum"]
            runs.append((list(p.out), sysm.master.stats.rollbacks))
    assert runs[0][1] > 50
    assert runs[0][0] == runs[1][0]


def test_saving_state_only_when_needed_gives_the_same_bits():
    """Skipping fmi2GetFMUstate in steps predicted free of events changes nothing."""
    outs = []
    for always in (False, True):
        sysm, _ = grasshopper(0.004, step=0.02, phi_start=math.radians(6))
        with sysm:
            m = sysm.master
            if always:
                m.MAX_REPLAY_STEPS = 0  # checkpoint at every step
            m.run_until(10.0)
            outs.append((list(m.ports["pendulum"].out), m.stats.states_saved, m.stats.steps))
    assert outs[0][0] == outs[1][0]
    assert outs[0][1] < 0.5 * outs[0][2]  # most steps saved nothing
    assert outs[1][1] >= outs[1][2]


# -- convergence orders on a smooth coupled pair --------------------------------

VIB = dict(gamma2=0.05, omega02=5.0, kappa=0.0, C1=5.0, C2=5.0, a2_start=0.0, rtol=1e-12, atol=1e-15)


def coupled_reference(t_end):
    g, L = 9.81, 1.0
    w0 = math.sqrt(g / L)

    def rhs(t, y):
        phi, w, a2, v2 = y
        return [w, -(g / L) * math.sin(phi) - (w0 / 1000.0) * w - VIB["C1"] * a2,
                v2, -VIB["gamma2"] * v2 - VIB["omega02"] ** 2 * a2 - VIB["C2"] * phi]

    sol = solve_ivp(rhs, (0, t_end), [math.radians(10), 0.0, 0.0, 0.0], method="DOP853",
                    rtol=1e-13, atol=1e-15)
    return sol.y[:, -1]


def coupled_error(step, extrapolation, order="gauss-seidel", t_end=2.0):
    sysm = System({"pendulum": ("Pendulum", dict(Q=1000.0, rtol=1e-12, atol=1e-15)),
                   "vibration": ("MechanismVibration", VIB)},
                  ["pendulum.phi -> vibration.a1", "vibration.tau -> pendulum.tau_coupling"],
                  MasterSettings(step=step, extrapolation=extrapolation, order=order),
                  record={"pendulum": ["phi"]})
    with sysm:
        sysm.master.run_until(t_end)
        phi = sysm.output("pendulum", "phi")
    return abs(phi - coupled_reference(t_end)[0])


@pytest.mark.parametrize("extrapolation,expected", [(0, 1.0), (1, 2.0)])
def test_convergence_order_of_the_coupling(extrapolation, expected):
    steps = [0.02, 0.01, 0.005]
    errors = [coupled_error(h, extrapolation) for h in steps]
    slope = np.polyfit(np.log(steps), np.log(errors), 1)[0]
    assert abs(slope - expected) < 0.3, (errors, slope)


def test_jacobi_is_first_order_too():
    steps = [0.02, 0.01, 0.005]
    errors = [coupled_error(h, 0, order="jacobi") for h in steps]
    slope = np.polyfit(np.log(steps), np.log(errors), 1)[0]
    assert abs(slope - 1.0) < 0.3, (errors, slope)


def coupled_iterated_error(step):
    sysm = System({"pendulum": ("Pendulum", dict(Q=1000.0, rtol=1e-12, atol=1e-15)),
                   "vibration": ("MechanismVibration", VIB)},
                  ["pendulum.phi -> vibration.a1", "vibration.tau -> pendulum.tau_coupling"],
                  MasterSettings(step=step, iterations=10, iteration_tolerance=1e-14),
                  record={"pendulum": ["phi"]})
    with sysm:
        sysm.master.run_until(2.0)
        err = abs(sysm.output("pendulum", "phi") - coupled_reference(2.0)[0])
        iterations = sysm.master.stats.coupling_iterations / sysm.master.stats.steps
    return err, iterations


def test_strong_coupling_converges_to_a_second_order_scheme():
    """Iterating the step with linearly interpolated coupling signals is the
    trapezoidal-type fixed point: second order, and below plain ZOH."""
    steps = [0.02, 0.01, 0.005]
    results = [coupled_iterated_error(h) for h in steps]
    errors = [e for e, _ in results]
    slope = np.polyfit(np.log(steps), np.log(errors), 1)[0]
    assert abs(slope - 2.0) < 0.3, (errors, slope)
    assert errors[0] < coupled_error(0.02, 0)
    assert all(it < 10 for _, it in results)  # converged before the cap


def test_divergence_is_caught_and_named():
    """A coupling far beyond its stability limit diverges: reported, not written as NaN."""
    sysm = System({"pendulum": ("Pendulum", dict(Q=1000.0)),
                   "vibration": ("MechanismVibration", dict(VIB, C1=5e4, C2=5e4))},
                  ["pendulum.phi -> vibration.a1", "vibration.tau -> pendulum.tau_coupling"],
                  MasterSettings(step=0.5, event_location=False))
    with sysm, pytest.raises(SimulationError) as e:
        sysm.master.run_until(200.0)
    assert e.value.time is not None and e.value.instance in ("pendulum", "vibration")
    assert "t =" in str(e.value)


def test_stall_is_a_result():
    """Too little torque: no periodic orbit above phi_r, reported as a stall."""
    sysm, params = grasshopper(0.00002)
    with sysm:
        shooter = Shooter(sysm.master, params, "pendulum", dict(PEND))
        guess = energy_balance_amplitude(dict(PEND), "GrasshopperEscapement", params["escapement"])
        result = find_steady_state(shooter, guess, math.radians(2.0))
    assert result.stalled


def test_two_crossings_inside_one_long_step_are_not_missed():
    """A step long enough to contain both crossings of phi_r (up and back
    down) would hide them from a sign test at its ends; the master's
    Hermite check and step cap must still find every switch."""
    eps, mu, phi0 = 1.167245e-4, 1.5e-5, 0.03
    lam = phi0 * math.sqrt(2 * mu / (math.pi * eps * phi0))
    ticks = {}
    for step in (0.785, 2.5, math.pi):
        sysm = System({"pendulum": ("Pendulum", dict(L=1.0, g=1.0, m=1.0, Q=1 / (2 * eps), phi_start=0.0, w_start=lam)),
                       "escapement": ("GrasshopperEscapement", dict(torque=mu, phi_r=phi0))},
                      GRASSHOPPER_LINKS, MasterSettings(step=step), record={"pendulum": ["tick_time"]})
        with sysm:
            sysm.master.run_until(50 * 2 * math.pi)
            ticks[step] = (sysm.output("pendulum", "tick_time"), sysm.master.stats.events)
    assert ticks[0.785][1] == 100
    for step in (2.5, math.pi):
        assert ticks[step][1] == 100
        assert abs(ticks[step][0] - ticks[0.785][0]) < 1e-9


def test_richardson_control_tightens_with_its_tolerance():
    errors, steps = [], []
    ref = coupled_reference(2.0)[0]
    for tol in (1e-4, 1e-6, 1e-8):
        sysm = System({"pendulum": ("Pendulum", dict(Q=1000.0, rtol=1e-12, atol=1e-15)),
                       "vibration": ("MechanismVibration", VIB)},
                      ["pendulum.phi -> vibration.a1", "vibration.tau -> pendulum.tau_coupling"],
                      MasterSettings(step=0.05, richardson=True, richardson_tolerance=tol),
                      record={"pendulum": ["phi"]})
        with sysm:
            sysm.master.run_until(2.0)
            errors.append(abs(sysm.output("pendulum", "phi") - ref))
            steps.append(sysm.master.stats.steps)
            assert sysm.master.t == 2.0
    assert errors[0] > errors[1] > errors[2]
    assert steps[0] < steps[1] < steps[2]


def test_richardson_does_not_lose_a_crossing_in_the_first_half_step():
    """Step doubling splits each step in two; a switch in the first half
    must be seen by the sign test over the whole step, not only found later
    by the hidden-crossing fallback (which had cost about 5x the trials).
    The tick time after 40 s agrees with the plain located run. (Prediction
    off: the trials counted are the locator's.)"""
    ticks = {}
    for richardson in (False, True):
        sysm = System({"pendulum": ("Pendulum", dict(Q=1000.0, phi_start=math.radians(5), rtol=1e-12, atol=1e-14)),
                       "escapement": ("GrasshopperEscapement", dict(torque=0.004, phi_r=math.radians(2)))},
                      GRASSHOPPER_LINKS, MasterSettings(step=0.2, richardson=richardson, richardson_tolerance=1e-6,
                                                        event_prediction=False),
                      record={"pendulum": ["tick_time"]})
        with sysm:
            sysm.master.run_until(40.0)
            stats = sysm.master.stats
            ticks[richardson] = (sysm.output("pendulum", "tick_time"), stats.events, stats.event_iterations)
    assert ticks[True][1] == ticks[False][1] == 40
    assert ticks[True][2] <= 2 * ticks[False][2], ticks
    assert abs(ticks[True][0] - ticks[False][0]) < 1e-10, ticks


def test_an_fmu_failure_is_reported_with_its_own_message():
    """A blow-up inside an FMU's step (Duffing with kappa < 0 runs away) is
    reported with the FMU's log message, the time and the instance."""
    sysm = System({"pendulum": ("Pendulum", dict(Q=1000.0, phi_start=math.radians(10))),
                   "vibration": ("MechanismVibration", dict(VIB, kappa=-1e15, a2_start=0.1))},
                  ["pendulum.phi -> vibration.a1", "vibration.tau -> pendulum.tau_coupling"],
                  MasterSettings(step=0.5, event_location=False))
    with sysm, pytest.raises(SimulationError) as e:
        sysm.master.run_until(10.0)
    assert e.value.instance == "vibration"
    assert "MechanismVibration" in str(e.value) and "discarded" in str(e.value)


def test_output_derivatives_are_asked_for_only_after_initialization(monkeypatch):
    """fmi2GetRealOutputDerivatives is allowed once initialization is over
    (FMI 2.0 state machine): the master asks then, and the FMUs answer, so
    extrapolation uses their derivatives. Asked earlier, the FMU refused and
    the master fell back to finite differences without a word."""
    from clockwork.fmi import cs2 as fmu_module

    asked_in_init = []
    real = fmu_module.Instance.output_derivatives

    def watched(self, names, order):
        if not getattr(self, "_initialized_for_test", False):
            asked_in_init.append((self.name, tuple(names)))
        return real(self, names, order)

    real_exit = fmu_module.Instance.exit_init

    def exit_init(self):
        real_exit(self)
        self._initialized_for_test = True

    monkeypatch.setattr(fmu_module.Instance, "output_derivatives", watched)
    monkeypatch.setattr(fmu_module.Instance, "exit_init", exit_init)
    comps = {"pendulum": ("Pendulum", dict(Q=0.0, phi_start=0.1)),
             "vibration": ("MechanismVibration", dict(kappa=0.0, C1=1.0, C2=1.0))}
    links = ["pendulum.phi -> vibration.a1", "vibration.tau -> pendulum.tau_coupling"]
    with System(comps, links, MasterSettings(step=0.01, extrapolation=2, order="jacobi")) as s:
        assert asked_in_init == []
        sources = s.master.coupling.derivative_sources
        assert set(sources) == {("pendulum", 0), ("vibration", 0)}  # both inputs from FMU derivatives
        s.master.run_until(0.1)


def test_a_located_switch_takes_two_trials():
    """The first guess is the quintic Hermite root of the indicator (values,
    slopes and curvatures from the pendulum's output derivatives at both ends
    of the step); a second-order Newton step from it, aimed just past the
    root in time whichever side the guess landed on, finishes. Before: a
    cubic guess 1e-3 s off, a first-order Newton step that fell short of
    the root, 3.5 trials a switch."""
    eps, mu0, phi0 = 1.167245e-4, 1.5e-5, 0.03
    lam = analytic.hoyng_stationary_amplitude(mu0, eps, phi0)
    comps = {"pendulum": ("Pendulum", dict(L=1.0, g=1.0, m=1.0, Q=1.0 / (2.0 * eps), rtol=1e-10, atol=1e-12,
                                            phi_start=lam)),
             "escapement": ("GrasshopperEscapement", dict(torque=mu0, phi_r=phi0))}
    links = ["pendulum.phi -> escapement.phi", "pendulum.w -> escapement.w",
             "escapement.tau -> pendulum.tau_escapement"]
    with System(comps, links, MasterSettings(step=2 * math.pi, order="jacobi")) as s:
        m = s.master
        m.run_until(20 * 2 * math.pi)
        events, trials = m.stats.events, m.stats.event_iterations
        m.run_until(m.t + 100 * 2 * math.pi)
        events, trials = m.stats.events - events, m.stats.event_iterations - trials
    assert events == 200
    assert trials <= 2 * events, trials / events
