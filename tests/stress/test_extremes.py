"""Extreme parameters of the Pendulum + GrasshopperEscapement clock.

Each case against an independent answer: the monolithic scipy reference
(clockwork.physics.reference), the exact free period (clockwork.physics.analytic), or the
same run at a small step.
"""

import math
import textwrap

import numpy as np
import pytest

from stress_support import fmus, size  # noqa: F401 (first: puts benchmarks/ on sys.path)
import stability as st  # noqa: E402
from clockwork.physics import analytic, reference  # noqa: E402
from clockwork.analyses import run_analysis  # noqa: E402
from clockwork.run import load_scene  # noqa: E402

PHI_R = math.radians(2.0)
TOLERANCE_S_PER_DAY = 1e-4  # asked of the shooting (tolerance_s_per_day)


@pytest.mark.parametrize("Q", size([5.0, 1e3, 1e5], [5.0, 30.0, 100.0, 1e3, 1e4, 1e5]))
def test_steady_state_from_q_5_to_1e5(Q):
    """Torque from the energy balance for 5 deg: heavily damped to nearly free."""
    M = st.torque_for_amplitude(math.radians(5.0), PHI_R, Q)
    ours = st.clock_steady_state(Q, M, PHI_R, tolerance_s_per_day=TOLERANCE_S_PER_DAY)
    ref = st.reference_steady_state(Q, M, PHI_R)
    assert not ours.stalled and not ref.stalled
    assert abs(ours.E_T - ref.E_T) * analytic.SECONDS_PER_DAY < TOLERANCE_S_PER_DAY, (ours.E_T, ref.E_T)
    assert ours.amplitude == pytest.approx(ref.amplitude, rel=1e-6)


@pytest.mark.parametrize("Q", size([1e7], [1e6, 1e7]))
@pytest.mark.xfail(strict=False, reason=(
    "measured gap at Q = 1e7: the shooting converges (residual 6e-17, period settled to 3e-13) but the fixed "
    "point is ill-conditioned: the map's slope is ~pi/Q = 3e-7, so the integrator's per-period error "
    "(rtol 1e-10) moves the orbit's amplitude by ~1e-5 relative: E_T differs from the reference by 1.3e-3 "
    "s/day (limit 1e-4); Q = 1e6 passes"))
def test_steady_state_at_q_1e6_and_beyond(Q):
    M = st.torque_for_amplitude(math.radians(5.0), PHI_R, Q)
    ours = st.clock_steady_state(Q, M, PHI_R, tolerance_s_per_day=TOLERANCE_S_PER_DAY)
    ref = st.reference_steady_state(Q, M, PHI_R)
    assert abs(ours.E_T - ref.E_T) * analytic.SECONDS_PER_DAY < TOLERANCE_S_PER_DAY, (ours.E_T, ref.E_T)


@pytest.mark.parametrize("amplitude_deg", size([0.1, 1.0, 90.0, 170.0], [0.1, 1, 5, 20, 45, 90, 120, 150, 170]))
@pytest.mark.parametrize("escapement", [False, True], ids=["free", "zero-torque escapement"])
def test_free_period_against_the_exact_period(amplitude_deg, escapement):
    """Undamped pendulum, rtol 1e-12: the period from 10 tick intervals is the
    AGM period to 1e-9 (1000 rtol: errors of ~100 internal steps per period
    add up, and dT/dA grows without bound towards 180 deg). A zero-torque
    escapement switches (located events) but changes nothing."""
    r = st.free_period(math.radians(amplitude_deg), escapement=escapement)
    assert r["ticks"] == 11
    assert abs(r["rel_error"]) < 1e-9, r
    assert r["amplitude_out_deg"] == pytest.approx(amplitude_deg, rel=1e-9)
    # Over 11 periods the relay flips twice a period (through -phi_r falling, +phi_r rising).
    expected_events = 22 if escapement and amplitude_deg > 2.0 else 0
    assert r["events"] == expected_events


@pytest.mark.parametrize("target_deg,phi_r_deg", size([(0.1, 0.04), (30.0, 2.0)],
                                                      [(0.1, 0.04), (1.0, 0.4), (3.0, 2.0), (10.0, 2.0),
                                                       (30.0, 2.0), (60.0, 2.0), (90.0, 2.0)]))
def test_clock_amplitude_against_the_reference(target_deg, phi_r_deg):
    M = st.torque_for_amplitude(math.radians(target_deg), math.radians(phi_r_deg), 1000.0)
    ours = st.clock_steady_state(1000.0, M, math.radians(phi_r_deg), tolerance_s_per_day=TOLERANCE_S_PER_DAY)
    ref = st.reference_steady_state(1000.0, M, math.radians(phi_r_deg))
    assert not ours.stalled
    assert abs(ours.E_T - ref.E_T) * analytic.SECONDS_PER_DAY < TOLERANCE_S_PER_DAY, (ours.E_T, ref.E_T)
    assert ours.amplitude == pytest.approx(ref.amplitude, rel=1e-6)


def test_over_the_top_is_reported_not_crashed():
    M = st.torque_for_amplitude(math.radians(150.0), PHI_R, 1000.0)
    try:
        ours = st.clock_steady_state(1000.0, M, PHI_R)
    except ValueError as e:
        pytest.fail(f"ValueError: {e}")
    except st.SimulationError:
        return
    assert ours.stalled or not math.isfinite(ours.amplitude) or ours.amplitude < math.pi


@pytest.mark.parametrize("ratio", [0.99, 1.01])
def test_phi_r_next_to_the_amplitude(ratio):
    """Energy-balance amplitude 1 % below phi_r: no orbit (stall); 1 % above:
    an orbit just above phi_r, as in the reference."""
    M = st.torque_for_amplitude(ratio * PHI_R, PHI_R, 1000.0)
    ours = st.clock_steady_state(1000.0, M, PHI_R, tolerance_s_per_day=1e-3)
    ref = st.reference_steady_state(1000.0, M, PHI_R)
    assert ours.stalled == ref.stalled == (ratio < 1.0)
    if not ours.stalled:
        assert PHI_R < ours.amplitude < 1.02 * PHI_R
        assert ours.amplitude == pytest.approx(ref.amplitude, rel=1e-6)
        assert abs(ours.E_T - ref.E_T) * analytic.SECONDS_PER_DAY < 1e-3


SCENE = textwrap.dedent("""\
    connections = [
      "pendulum.phi -> escapement.phi",
      "pendulum.w -> escapement.w",
      "escapement.tau -> pendulum.tau_escapement",
    ]

    [scene]
    title = "Stress: grasshopper clock at an extreme point"

    [components.pendulum]
    fmu = "Pendulum"
    parameters = {{ L = 1.0, m = 1.0, g = 9.81, Q = {Q}, phi_start = "6 deg", rtol = 1e-11, atol = 1e-13 }}

    [components.escapement]
    fmu = "GrasshopperEscapement"
    parameters = {{ torque = {torque}, phi_r = "2 deg" }}

    [experiment]
    stop = "{stop} s"

    [master]
    step = "{step} s"

    [record]
    outputs = ["pendulum.phi", "pendulum.amplitude"]
    ticks = "pendulum"

    [analysis]
    kind = "{kind}"
    """)


def _scene(tmp_path, kind, torque, stop=60.0, step=0.25, Q=1000.0):
    path = tmp_path / f"{kind}.toml"
    path.write_text(SCENE.format(kind=kind, torque=torque, stop=stop, step=step, Q=Q))
    return load_scene(path)


@pytest.mark.parametrize("case", ["zero torque", "1 % short of phi_r"])
def test_analyses_report_a_stall(tmp_path, case):
    """Through the scene analyses: steady_state says stalled, time_series runs
    through (Q = 50 so that the swing decays below phi_r within the run)."""
    Q = 50.0
    torque = 0.0 if case == "zero torque" else st.torque_for_amplitude(0.99 * PHI_R, PHI_R, Q)
    steady = run_analysis(_scene(tmp_path, "steady_state", torque, Q=Q), {})["result"]
    assert steady["stalled"] is True
    assert steady["amplitude_deg"] is None and steady["E_T_s_per_day"] is None
    series = run_analysis(_scene(tmp_path, "time_series", torque, stop=120.0, Q=Q), {})
    phi = np.asarray(series["series"]["pendulum.phi"])
    amplitude = np.asarray(series["series"]["pendulum.amplitude"])
    assert np.all(np.isfinite(phi)) and series["series"]["time"][-1] == pytest.approx(120.0)
    assert amplitude[-1] < PHI_R and np.max(np.abs(phi[-40:])) < PHI_R


def test_zero_torque_is_the_free_damped_pendulum(tmp_path):
    """Ticks of a clock with zero torque against the monolithic free pendulum."""
    out = run_analysis(_scene(tmp_path, "time_series", 0.0, stop=60.0, step=0.25), {})
    ref = reference.simulate(reference.ClockParams(Q=1000.0, escapement="none"), math.radians(6.0), 0.0, 60.0)
    ticks = np.asarray(out["ticks"])
    assert len(ticks) == len(ref.ticks) == 30
    assert np.max(np.abs(ticks - ref.ticks)) < 1e-8


def _one_step_case(stop):
    small = st.clock_run(0.01, stop)
    one = st.clock_run(stop, stop)
    return small, one


@pytest.mark.parametrize("stop", size([20.0, 100.0], [20.0, 100.0, 500.0]))
def test_one_step_for_the_whole_run(stop):
    """A step as long as the run: the first step is capped by the time scale
    the pendulum shows at the start (its d2phi/dt2 / phi), so no switch is
    hidden in it (at 100 s, a first step of stop/64 had hidden 2)."""
    small, one = _one_step_case(stop)
    assert one["events"] == small["events"]
    assert len(one["ticks"]) == len(small["ticks"])
    assert np.max(np.abs(np.subtract(one["ticks"], small["ticks"]))) < 1e-9
    assert one["phi"] == pytest.approx(small["phi"], abs=1e-9)


def test_one_step_for_the_whole_run_after_the_first_period():
    """After the first step, the step cap and the hidden-crossing check find
    every switch of a step as long as the run (stop = 2.5 T0)."""
    stop = 2.5 * analytic.small_angle_period(1.0, 9.81)
    small, one = _one_step_case(stop)
    assert one["events"] == small["events"] == 5
    assert np.max(np.abs(np.subtract(one["ticks"], small["ticks"]))) < 1e-9
    assert one["phi"] == pytest.approx(small["phi"], abs=1e-9)
