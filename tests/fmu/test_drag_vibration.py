"""Drag and MechanismVibration FMUs, driven through fmpy's FMU2Slave.

MechanismVibration is Ziemkiewicz Eq. (7), second line:
    a2'' + gamma2 a2' + omega02^2 a2 + kappa a2^3 + C2 a1(t) = 0,
with the torque tau = -C1 I a2 fed back to the pendulum. The linear cases
(kappa = 0) have closed-form solutions that the FMU must reproduce.

The accuracy checks set rtol = 1e-12 so that the integrator's own error
(rtol 1e-10 by default) stays well below the 1e-9 they assert: they test
the equations and the input handling, not the integrator, which has its
own tests.
"""

import math

import numpy as np
import pytest
from fmpy import extract, read_model_description
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import (
    FMU2Slave,
    calloc,
    fmi2CallbackAllocateMemoryTYPE,
    fmi2CallbackFreeMemoryTYPE,
    fmi2CallbackFunctions,
    fmi2CallbackLoggerTYPE,
    free,
)
from fmpy.validation import validate_fmu

from cwtest import fmu_file

OMEGA02 = 7.0 * math.sqrt(9.81)  # rad/s, the FMU's default
TIGHT = {"rtol": 1e-12, "atol": 1e-16}


@pytest.fixture(scope="module")
def unpacked(tmp_path_factory):
    """Each FMU extracted once per module: name -> (directory, description)."""
    out = {}
    for name in ("Drag", "MechanismVibration"):
        path = fmu_file(name)
        md = read_model_description(str(path))
        d = extract(str(path), unzipdir=str(tmp_path_factory.mktemp(name)))
        out[name] = (d, md)
    return out


class Slave:
    """An instantiated, initialized FMU with a log recorder."""

    def __init__(self, unpacked, name, params=None, start=0.0):
        d, md = unpacked[name]
        self.vr = {v.name: v.valueReference for v in md.modelVariables}
        self.log = []
        cb = fmi2CallbackFunctions()
        cb.logger = fmi2CallbackLoggerTYPE(self._logger)
        cb.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
        cb.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
        self.fmu = FMU2Slave(
            guid=md.guid,
            unzipDirectory=d,
            modelIdentifier=md.coSimulation.modelIdentifier,
            instanceName=name,
        )
        self.fmu.instantiate(callbacks=cb)
        self.fmu.setupExperiment(startTime=start)
        self.fmu.enterInitializationMode()
        for k, v in (params or {}).items():
            self.fmu.setReal([self.vr[k]], [v])
        self.fmu.exitInitializationMode()
        self.t = start

    def _logger(self, env, instance, status, category, message):
        self.log.append((status, category.decode(), message.decode()))

    def get(self, *names):
        vals = self.fmu.getReal([self.vr[n] for n in names])
        return vals[0] if len(names) == 1 else vals

    def set(self, **values):
        for k, v in values.items():
            self.fmu.setReal([self.vr[k]], [v])

    def set_derivative(self, name, order, value):
        self.fmu.setRealInputDerivatives([self.vr[name]], [order], [value])

    def step(self, h):
        self.fmu.doStep(self.t, h)
        self.t += h

    def close(self):
        self.fmu.terminate()
        self.fmu.freeInstance()


def assert_refused(unpacked, name, params, variable):
    """Initializing with `params` must fail with fmi2Error and an error
    message that names `variable`."""
    s = Slave.__new__(Slave)
    with pytest.raises(FMICallException) as e:
        Slave.__init__(s, unpacked, name, params)
    assert "error" in str(e.value)
    messages = [m for st, c, m in s.log if st == 3]
    assert any(f"{variable} = " in m for m in messages), messages
    s.fmu.freeInstance()


# ---------------------------------------------------------------- validate


@pytest.mark.parametrize("name", ["Drag", "MechanismVibration"])
def test_validate(name):
    assert validate_fmu(str(fmu_file(name))) == []


# ---------------------------------------------------------------- Drag


def test_drag_torque_values_and_signs(unpacked):
    c1, c2 = 0.013, 0.0021
    s = Slave(unpacked, "Drag", {"c1": c1, "c2": c2})
    for w in (-3.0, -0.5, -1e-3, 0.0, 1e-3, 0.5, 3.0):
        s.set(w=w)
        tau = s.get("tau")
        assert tau == pytest.approx(-(c1 * w + c2 * w * abs(w)), rel=1e-15, abs=0)
        assert np.sign(tau) == -np.sign(w)  # always opposes the motion
    # Quadratic part is odd in w as well: tau(-w) = -tau(w).
    s.set(w=2.0)
    plus = s.get("tau")
    s.set(w=-2.0)
    assert s.get("tau") == -plus
    s.close()


def test_drag_zero_coefficients_give_zero(unpacked):
    s = Slave(unpacked, "Drag")  # c1 = c2 = 0 by default
    for w in (-7.0, 0.0, 2.5):
        s.set(w=w)
        assert s.get("tau") == 0.0
    s.close()


def test_drag_tunable_and_follows_input_derivative(unpacked):
    s = Slave(unpacked, "Drag", {"c1": 0.01})
    s.set(w=1.0)
    s.step(0.1)
    s.set(c2=0.5)  # tunable during the simulation
    assert s.get("tau") == pytest.approx(-(0.01 + 0.5), rel=1e-15)
    # With a slope set, the output at the next point follows the input
    # extrapolated to that point.
    s.set(w=1.0)
    s.set_derivative("w", 1, 2.0)
    s.step(0.25)
    w = 1.0 + 2.0 * 0.25
    assert s.get("tau") == pytest.approx(-(0.01 * w + 0.5 * w * w), rel=1e-15)
    s.close()


def test_drag_refuses_bad_values(unpacked):
    assert_refused(unpacked, "Drag", {"c1": -1.0}, "c1")
    assert_refused(unpacked, "Drag", {"c2": float("inf")}, "c2")

    s = Slave(unpacked, "Drag")
    with pytest.raises(FMICallException):
        s.set(w=float("nan"))
    assert any("w = nan" in m for st, c, m in s.log if st == 3), s.log


# ---------------------------------------------------------------- vibration


def test_free_oscillation_is_a_cosine(unpacked):
    a0 = 0.01
    s = Slave(unpacked, "MechanismVibration",
              {"kappa": 0.0, "C2": 0.0, "gamma2": 0.0, "a2_start": a0, **TIGHT})
    period = 2 * math.pi / OMEGA02
    h = period / 37
    worst = 0.0
    for _ in range(37 * 20):  # 20 periods, steps not commensurate with it
        s.step(h)
        a2, a2dot = s.get("a2", "a2dot")
        wt = OMEGA02 * s.t
        worst = max(worst, abs(a2 - a0 * math.cos(wt)),
                    abs(a2dot + a0 * OMEGA02 * math.sin(wt)) / OMEGA02)
    assert worst < 1e-9 * a0
    s.close()


def test_static_deflection_is_the_centre(unpacked):
    C2, a1 = 2.5, 0.05
    centre = -C2 * a1 / OMEGA02**2
    s = Slave(unpacked, "MechanismVibration",
              {"kappa": 0.0, "C2": C2, "gamma2": 0.0, **TIGHT})
    s.set(a1=a1)
    h = 0.013
    samples = []
    for _ in range(400):
        s.step(h)
        a2 = s.get("a2")
        samples.append(a2)
        # Started at rest at 0: a2 = centre (1 - cos(omega02 t)).
        assert a2 == pytest.approx(centre * (1 - math.cos(OMEGA02 * s.t)),
                                   abs=1e-9 * abs(centre))
    assert 0.5 * (max(samples) + min(samples)) == pytest.approx(centre, rel=1e-3)
    s.close()

    # With damping the oscillation dies out onto the static deflection.
    s = Slave(unpacked, "MechanismVibration",
              {"kappa": 0.0, "C2": C2, "gamma2": 4.0, **TIGHT})
    s.set(a1=a1)
    s.step(15.0)  # amplitude factor exp(-gamma2 t / 2) = exp(-30)
    assert s.get("a2") == pytest.approx(centre, rel=1e-9)
    assert s.get("a2ddot") == pytest.approx(0.0, abs=1e-9 * abs(centre) * OMEGA02**2)
    s.close()


def _ramp_response(C2, r, t):
    """a2'' + w^2 a2 = -C2 r t from rest at 0."""
    w = OMEGA02
    return -(C2 * r / w**2) * (t - math.sin(w * t) / w)


def _parabola_response(C2, q, t):
    """a2'' + w^2 a2 = -C2 q t^2 / 2 from rest at 0."""
    w = OMEGA02
    A = -C2 * q / (2 * w**2)
    B = -2 * A / w**2
    return A * t * t + B * (1 - math.cos(w * t))


@pytest.mark.parametrize("master", ["once", "every_step", "hold"])
def test_ramp_input_through_input_derivatives(unpacked, master):
    C2, r, h = 2.5, 0.1, 0.05
    s = Slave(unpacked, "MechanismVibration",
              {"kappa": 0.0, "gamma2": 0.0, "C2": C2, **TIGHT})
    s.set(a1=0.0)
    if master == "once":
        s.set_derivative("a1", 1, r)
    worst = scale = 0.0
    for _ in range(100):
        if master != "once":
            s.set(a1=r * s.t)  # setting a value alone means: hold it
            if master == "every_step":
                s.set_derivative("a1", 1, r)
        s.step(h)
        exact = _ramp_response(C2, r, s.t)
        worst = max(worst, abs(s.get("a2") - exact))
        scale = max(scale, abs(exact))
    if master == "hold":
        # The control: a zero-order hold is visibly different, so the
        # other two cases do test that the derivative is used.
        assert worst > 1e-3 * scale
    else:
        assert worst < 1e-9 * scale
    s.close()


def test_second_order_input_derivative(unpacked):
    C2, q = 2.5, 0.4
    s = Slave(unpacked, "MechanismVibration",
              {"kappa": 0.0, "gamma2": 0.0, "C2": C2, **TIGHT})
    s.set(a1=0.0)
    s.set_derivative("a1", 2, q)
    worst = scale = 0.0
    for _ in range(60):
        s.step(0.05)
        exact = _parabola_response(C2, q, s.t)
        worst = max(worst, abs(s.get("a2") - exact))
        scale = max(scale, abs(exact))
    assert worst < 1e-9 * scale
    s.close()


def _count_periods(s, n_periods, h):
    """Step until a2 has crossed zero upward n_periods times."""
    prev, n = s.get("a2"), 0
    while n < n_periods:
        s.step(h)
        a2 = s.get("a2")
        if prev < 0 <= a2:
            n += 1
        prev = a2


def test_energy_conserved_duffing(unpacked):
    # a2 = 0.02 rad: kappa a2^2 = 4000 / s^2 against omega02^2 = 481 / s^2,
    # so the cubic term dominates.
    drift = {}
    for rtol in (1e-10, 1e-12):
        s = Slave(unpacked, "MechanismVibration",
                  {"gamma2": 0.0, "C2": 0.0, "kappa": 1e7, "a2_start": 0.02,
                   "rtol": rtol})
        s.set(a1=0.3)  # C2 = 0: the input must have no effect
        e0 = s.get("energy")
        assert e0 == pytest.approx(0.5 * OMEGA02**2 * 0.02**2 + 0.25 * 1e7 * 0.02**4,
                                   rel=1e-15)
        _count_periods(s, 100, 0.01)
        drift[rtol] = abs(s.get("energy") / e0 - 1)
        s.close()
    assert drift[1e-12] < 1e-9
    # The drift is the integrator's and shrinks with its tolerance; a
    # non-conservative right-hand side would not.
    assert drift[1e-12] < 0.2 * drift[1e-10]


def test_tau_and_output_derivatives(unpacked):
    C1, inertia = 1.5, 2.0
    s = Slave(unpacked, "MechanismVibration",
              {"C1": C1, "inertia": inertia, "a2_start": 0.003, "a2dot_start": -0.02})
    s.set(a1=0.1)
    s.set_derivative("a1", 1, 0.7)
    s.step(0.123)
    a2, a2dot, a2ddot, tau = s.get("a2", "a2dot", "a2ddot", "tau")
    assert tau == -C1 * inertia * a2
    f = s.fmu
    vr = s.vr
    d = f.getRealOutputDerivatives([vr["a2"], vr["a2"], vr["a2dot"], vr["tau"], vr["tau"]],
                                   [1, 2, 1, 1, 2])
    assert d == [a2dot, a2ddot, a2ddot, -C1 * inertia * a2dot, -C1 * inertia * a2ddot]
    # a2ddot is the equation of motion with the input at the current time.
    a1 = 0.1 + 0.7 * 0.123
    expect = (-6.283185307179586e-05 * a2dot - OMEGA02**2 * a2 - 1e7 * a2**3 - 2.5 * a1)
    assert a2ddot == pytest.approx(expect, rel=1e-12)
    # Central difference of tau over +-dt agrees with its first derivative.
    state = f.getFMUstate()
    dt = 1e-5
    s.step(dt)
    tau_plus = s.get("tau")
    f.setFMUstate(state)
    s.t -= dt
    f.freeFMUstate(state)
    with pytest.raises(FMICallException):
        f.getRealOutputDerivatives([vr["a2ddot"]], [1])  # not offered
    taylor = tau + d[3] * dt + 0.5 * d[4] * dt * dt
    assert tau_plus == pytest.approx(taylor, abs=1e-13)
    assert abs(tau_plus - (tau + d[3] * dt)) > 1e-11  # the d2 term matters
    s.close()


def _drive_steps(s, n, h):
    """Steps with a sinusoidal input given with its slope at every point."""
    out = []
    for _ in range(n):
        t = s.t
        s.set(a1=0.05 * math.sin(6.0 * t))
        s.set_derivative("a1", 1, 0.3 * math.cos(6.0 * t))
        s.step(h)
        out.append(s.get("a2", "a2dot", "a2ddot", "tau", "energy"))
    return out


def test_state_get_set_and_serialize_bit_for_bit(unpacked):
    params = {"a2_start": 0.01, "gamma2": 0.5}
    s = Slave(unpacked, "MechanismVibration", params)
    _drive_steps(s, 17, 0.037)
    t_saved = s.t
    at_saved = s.get("a2", "a2dot", "a2ddot", "tau", "energy")
    state = s.fmu.getFMUstate()
    blob = s.fmu.serializeFMUstate(state)
    reference = _drive_steps(s, 40, 0.037)

    s.fmu.setFMUstate(state)
    s.t = t_saved
    assert _drive_steps(s, 40, 0.037) == reference
    s.fmu.freeFMUstate(state)
    s.close()

    fresh = Slave(unpacked, "MechanismVibration")  # default parameters
    restored = fresh.fmu.deSerializeFMUstate(blob)
    fresh.fmu.setFMUstate(restored)
    fresh.fmu.freeFMUstate(restored)
    fresh.t = t_saved
    assert fresh.get("a2", "a2dot", "a2ddot", "tau", "energy") == at_saved
    assert _drive_steps(fresh, 40, 0.037) == reference
    fresh.close()


def test_failed_integration_is_discarded_and_state_kept(unpacked):
    # A softening spring this strong blows up in finite time.
    s = Slave(unpacked, "MechanismVibration",
              {"kappa": -1e15, "a2_start": 0.1, "C2": 0.0})
    s.step(0.5e-7)
    before = s.get("a2", "a2dot")
    with pytest.raises(FMICallException) as e:
        s.fmu.doStep(s.t, 1.0)
    assert "discard" in str(e.value)
    discards = [m for st, c, m in s.log if st == 2]
    assert len(discards) == 1, s.log
    assert f"from t = {s.t:.17g} to {s.t + 1.0:.17g}" in discards[0]
    assert "a2 = " in discards[0] and "a2dot = " in discards[0]
    assert s.get("a2", "a2dot") == before
    s.fmu.freeInstance()


@pytest.mark.parametrize(
    "name, value",
    [("rtol", 0.0), ("rtol", -1e-10), ("atol", 0.0), ("inertia", 0.0),
     ("omega02", 0.0), ("gamma2", -1.0), ("a1", float("nan"))],
)
def test_vibration_refuses_bad_values(unpacked, name, value):
    assert_refused(unpacked, "MechanismVibration", {name: value}, name)
