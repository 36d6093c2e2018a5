"""GrasshopperEscapement and ChronometerEscapement through fmpy's FMU2Slave.

The grasshopper escapement is a relay with hysteresis (Ziemkiewicz Eq. 6 =
Hoyng's model escapement): the tests feed scripted swings of (phi, w) at
communication points and check the torque's sign against the motion, the
left/right-limit semantics of docs/design.md, the work per period
(Ziemkiewicz Eq. B3: 4 torque phi_r), the profiles and the torque noise.
"""

from __future__ import annotations

import math
import shutil

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

DEG = math.pi / 180.0
FMI2_ERROR = 3


class Instance:
    """One FMU instance with name-based access and captured log messages."""

    def __init__(self, unpacked, params=None, inputs=None, start_time=0.0):
        md, unzipdir = unpacked
        self.vars = {v.name: v for v in md.modelVariables}
        self.messages: list[tuple[int, str, str]] = []

        def log(env, name, status, category, message):
            self.messages.append((status, category.decode(), message.decode()))

        cb = fmi2CallbackFunctions()
        cb.logger = fmi2CallbackLoggerTYPE(log)
        cb.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
        cb.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
        self._callbacks = cb  # keep the C callbacks alive
        self.fmu = FMU2Slave(
            guid=md.guid,
            unzipDirectory=unzipdir,
            modelIdentifier=md.coSimulation.modelIdentifier,
            instanceName="esc",
        )
        self.fmu.instantiate(callbacks=cb)
        self.fmu.setupExperiment(startTime=start_time)
        self.fmu.enterInitializationMode()
        self.set(**(params or {}))
        self.set(**(inputs or {}))
        self.t = start_time

    def initialize(self):
        self.fmu.exitInitializationMode()
        return self

    def set(self, **values):
        for name, value in values.items():
            v = self.vars[name]
            if v.type == "Integer":
                self.fmu.setInteger([v.valueReference], [int(value)])
            else:
                self.fmu.setReal([v.valueReference], [float(value)])

    def get(self, name):
        v = self.vars[name]
        if v.type == "Integer":
            return self.fmu.getInteger([v.valueReference])[0]
        return self.fmu.getReal([v.valueReference])[0]

    def step(self, h):
        self.fmu.doStep(self.t, h)
        self.t += h

    def errors(self):
        return [m for s, _, m in self.messages if s >= FMI2_ERROR]

    def close(self):
        self.fmu.freeInstance()


@pytest.fixture(scope="module")
def grasshopper():
    path = fmu_file("GrasshopperEscapement")
    unzipdir = extract(path)
    yield read_model_description(path), unzipdir
    shutil.rmtree(unzipdir, ignore_errors=True)


@pytest.fixture(scope="module")
def chronometer():
    path = fmu_file("ChronometerEscapement")
    unzipdir = extract(path)
    yield read_model_description(path), unzipdir
    shutil.rmtree(unzipdir, ignore_errors=True)


@pytest.mark.parametrize("name", ["GrasshopperEscapement", "ChronometerEscapement"])
def test_fmpy_validate_is_clean(name):
    assert validate_fmu(str(fmu_file(name))) == []


# ---------------------------------------------------------------------------
# Grasshopper: scripted swings


def run_swing(unpacked, amplitude, phi_r, torque=0.004, periods=1, n=4000):
    """phi = -A cos(2 pi t), w = dphi/dt at n points per period (period 1 s),
    starting at the left turning point; doStep between points."""
    h = 1.0 / n
    t = np.arange(periods * n + 1) * h
    phi = -amplitude * np.cos(2 * np.pi * t)
    w = 2 * np.pi * amplitude * np.sin(2 * np.pi * t)
    inst = Instance(unpacked, {"phi_r": phi_r, "torque": torque},
                    {"phi": phi[0], "w": w[0]}).initialize()
    tau, mode, ind = [], [], []
    for k in range(len(t)):
        inst.set(phi=phi[k], w=w[k])
        tau.append(inst.get("tau"))
        mode.append(inst.get("mode"))
        ind.append(inst.get("event_indicator"))
        if k < len(t) - 1:
            inst.step(h)
    inst.close()
    return phi, w, np.array(tau), np.array(mode), np.array(ind)


def test_relay_over_a_swing(grasshopper):
    A, phi_r, M = 5 * DEG, 2 * DEG, 0.004
    phi, w, tau, mode, ind = run_swing(grasshopper, A, phi_r, M)
    right, left = w > 0, w < 0

    # Moving right: drive with the motion until phi reaches +phi_r ...
    before = right & (phi < phi_r)
    assert before.sum() > 100
    assert np.all(tau[before] == M) and np.all(mode[before] == 1)
    # ... then recoil (torque against the motion) up to the turning point.
    recoil_right = right & (phi >= phi_r)
    assert recoil_right.sum() > 100
    assert np.all(tau[recoil_right] == -M) and np.all(mode[recoil_right] == -1)
    # The switch is at the first point past the threshold.
    k_up = int(np.argmax(phi >= phi_r))
    assert mode[k_up - 1] == 1 and mode[k_up] == -1
    assert ind[k_up] <= 0 and ind[k_up - 1] > 0

    # Turning point (w changes sign): the torque is continuous there.
    k_turn = int(np.argmax(w <= 0))  # the first point at or past the turn
    k_turn = k_turn if abs(w[k_turn]) < abs(w[k_turn - 1]) else k_turn - 1
    assert np.all(tau[k_turn - 2:k_turn + 3] == -M)

    # Moving left: drive with the motion until -phi_r, then recoil again.
    drive_left = left & (phi > -phi_r)
    assert drive_left.sum() > 100
    assert np.all(tau[drive_left] == -M) and np.all(mode[drive_left] == -1)
    recoil_left = left & (phi <= -phi_r)
    assert recoil_left.sum() > 100
    assert np.all(tau[recoil_left] == M) and np.all(mode[recoil_left] == 1)
    k_down = int(np.argmax(left & (phi <= -phi_r)))
    assert mode[k_down - 1] == -1 and mode[k_down] == 1
    assert ind[k_down] <= 0

    # The event indicator is positive everywhere except at the two switches.
    assert set(np.flatnonzero(ind <= 0)) == {k_up, k_down}

    # Sign relative to the motion: drive before the switch, recoil after.
    assert np.all(tau[before] * w[before] > 0)
    assert np.all(tau[recoil_right] * w[recoil_right] < 0)
    assert np.all(tau[drive_left] * w[drive_left] > 0)
    assert np.all(tau[recoil_left] * w[recoil_left] < 0)

    # Work over the closed swing, tau held over each interval (the value
    # for the next step): 4 M phi_r (Ziemkiewicz B3); each of the two
    # switches lags the threshold by less than one interval.
    dphi = np.diff(phi)
    work = float(np.sum(tau[:-1] * dphi))
    assert abs(work - 4 * M * phi_r) <= 4 * M * np.max(np.abs(dphi))
    assert work > 0.99 * 4 * M * phi_r  # the bound above is < 1 % here


def test_stall_below_phi_r(grasshopper):
    # Amplitude 1.5 deg < phi_r = 2 deg: the relay never switches, the torque
    # is conservative and does no work over a closed swing.
    M = 0.004
    phi, w, tau, mode, ind = run_swing(grasshopper, 1.5 * DEG, 2 * DEG, M, periods=2)
    assert np.all(mode == 1)
    assert np.all(tau == M)
    assert np.all(ind > 0)
    assert abs(float(np.sum(tau[:-1] * np.diff(phi)))) < 1e-12 * M


def test_event_indicator_is_left_limit(grasshopper):
    phi_r, M = 2 * DEG, 0.004
    inst = Instance(grasshopper, {"phi_r": phi_r, "torque": M},
                    {"phi": 0.0, "w": 0.1}).initialize()
    assert inst.get("mode") == 1 and inst.get("tau") == M
    assert inst.get("event_indicator") == pytest.approx(phi_r, rel=1e-15)

    # Exactly at the threshold the switch has happened (indicator <= 0).
    inst.set(phi=phi_r)
    assert inst.get("mode") == -1 and inst.get("event_indicator") == 0.0
    assert inst.get("tau") == -M

    phi = phi_r + 0.1 * DEG
    inst.set(phi=phi)
    assert inst.get("mode") == -1  # right limit
    assert inst.get("tau") == -M
    assert inst.get("event_indicator") == pytest.approx(phi_r - phi, rel=1e-14)
    assert inst.get("event_indicator") < 0  # left limit: old mode

    # Without a doStep nothing is committed: back below the threshold the
    # mode is +1 again.
    inst.set(phi=0.0)
    assert inst.get("mode") == 1 and inst.get("tau") == M
    inst.set(phi=phi)
    assert inst.get("mode") == -1

    inst.step(1e-3)  # commits the switch
    assert inst.get("mode") == -1
    assert inst.get("event_indicator") == pytest.approx(phi_r + phi, rel=1e-14)
    assert inst.get("event_indicator") > 0

    # Going back below +phi_r does not switch back: hysteresis.
    inst.set(phi=0.0, w=-0.1)
    inst.step(1e-3)
    assert inst.get("mode") == -1 and inst.get("tau") == -M
    inst.close()


def test_input_derivatives_are_followed(grasshopper):
    phi_r = 2 * DEG
    inst = Instance(grasshopper, {"phi_r": phi_r}, {"phi": 0.0, "w": 1.0}).initialize()
    vr_phi = inst.vars["phi"].valueReference
    inst.fmu.setRealInputDerivatives([vr_phi], [1], [1.0])  # dphi/dt = 1 rad/s
    inst.step(0.01)
    assert inst.get("mode") == 1  # phi = 0.01 rad < phi_r
    inst.step(0.04)  # phi extrapolated to 0.05 rad > phi_r
    assert inst.get("mode") == -1
    assert inst.get("event_indicator") == pytest.approx(phi_r - 0.05, rel=1e-12)
    inst.close()


@pytest.mark.parametrize(
    "phi_deg, w, expected",
    [(0.0, 0.0, 1), (1.9, 0.1, 1), (2.0, 0.1, -1), (3.0, 0.0, -1),
     (0.0, -0.1, -1), (-1.9, -0.1, -1), (-2.0, -0.1, 1), (-3.0, -0.1, 1)],
)
def test_initial_mode_from_inputs(grasshopper, phi_deg, w, expected):
    inst = Instance(grasshopper, {"phi_r": 2 * DEG},
                    {"phi": phi_deg * DEG, "w": w}).initialize()
    assert inst.get("mode") == expected
    assert inst.get("event_indicator") > 0  # the derived mode holds
    inst.close()


@pytest.mark.parametrize("mode_start", [-1, 1])
def test_mode_start_overrides(grasshopper, mode_start):
    inst = Instance(grasshopper, {"mode_start": mode_start, "torque": 0.01},
                    {"phi": 0.0, "w": 0.1}).initialize()
    assert inst.get("mode") == mode_start
    assert inst.get("tau") == mode_start * 0.01
    inst.close()


def profile_factor(profile, phi, angle):
    x = abs(phi) / angle
    return {0: 1.0, 1: 0.5 + x, 2: max(0.0, 1.5 - x)}[profile]


@pytest.mark.parametrize("profile", [0, 1, 2])
def test_angle_profiles(grasshopper, profile):
    M, angle = 0.004, 12 * DEG
    inst = Instance(grasshopper, {"profile": profile, "profile_angle": angle,
                                  "torque": M}, {"phi": 0.0, "w": 0.1}).initialize()
    got = []
    for deg in [0.0, 1.0, 3.0, 6.0, 12.0, 24.0, -6.0, -12.0]:
        inst.set(phi=deg * DEG)
        tau, mode = inst.get("tau"), inst.get("mode")
        expected = profile_factor(profile, deg * DEG, angle)
        assert abs(tau) == pytest.approx(M * expected, rel=1e-14, abs=1e-300)
        if expected > 0:
            assert math.copysign(1, tau) == mode
        got.append(abs(tau) / M)
    # Spot values named in the brief: 50 %..150 % (1), 150 %..50 % (2).
    if profile == 1:
        assert got[0] == pytest.approx(0.5) and got[4] == pytest.approx(1.5)
    if profile == 2:
        assert got[0] == pytest.approx(1.5) and got[4] == pytest.approx(0.5)
        assert got[5] == 0.0
    inst.close()


def test_harrison_profile(grasshopper):
    M, phi_r = 0.004, 2 * DEG
    inst = Instance(grasshopper, {"profile": 3, "torque": M, "phi_r": phi_r},
                    {"phi": -1 * DEG, "w": 0.1}).initialize()
    assert inst.get("tau") == M  # driving right
    inst.set(phi=3 * DEG)  # past +phi_r still moving right: recoil
    assert inst.get("mode") == -1
    assert inst.get("tau") == pytest.approx(-M * 2 / 3, rel=1e-15)
    inst.step(0.01)
    inst.set(w=0.0)  # turning point: the drive value
    assert inst.get("tau") == -M
    inst.set(w=-0.1)  # driving left
    assert inst.get("tau") == -M
    inst.step(0.01)
    inst.set(phi=-3 * DEG)  # past -phi_r moving left: recoil
    assert inst.get("mode") == 1
    assert inst.get("tau") == pytest.approx(M * 2 / 3, rel=1e-15)
    inst.close()


def test_velocity_gain(grasshopper):
    M = 0.004
    inst = Instance(grasshopper, {"torque": M, "velocity_gain": 2.0},
                    {"phi": 0.0, "w": 0.1}).initialize()
    assert inst.get("tau") == M
    for v in (0.5, -0.5):
        inst.set(vibration_velocity=v)
        assert inst.get("tau") == pytest.approx(2 * M, rel=1e-15)
        assert inst.get("torque_amplitude") == M  # the noise-only amplitude
    inst.close()


def test_torque_is_tunable(grasshopper):
    inst = Instance(grasshopper, {"torque": 0.004}, {"phi": 0.0, "w": 0.1}).initialize()
    inst.step(0.01)
    inst.set(torque=0.006)
    assert inst.get("tau") == 0.006 and inst.get("torque_amplitude") == 0.006
    inst.close()


# ---------------------------------------------------------------------------
# Grasshopper: torque noise


def noise_run(unpacked, seed, rms, renewals, noise_start=0.0, h=0.01,
              snapshot=None, M=0.004):
    """Alternate phi = -0.01, +0.01 rad; every upward crossing is a renewal.
    Returns the deltas read after each crossing (pending value) and, if
    snapshot = k, the FMU state saved before the k-th crossing."""
    inst = Instance(unpacked, {"torque": M, "noise_rms": rms, "noise_seed": seed,
                               "noise_start": noise_start},
                    {"phi": -0.01, "w": 0.0}).initialize()
    deltas, saved = [], None
    for j in range(renewals):
        if j == snapshot:
            saved = (inst.fmu.getFMUState(), inst.t)
        inst.set(phi=0.01)
        deltas.append(inst.get("torque_amplitude") / M - 1.0)
        inst.step(h)
        inst.set(phi=-0.01)
        inst.step(h)
    return inst, deltas, saved


def test_noise_is_reproducible_and_seed_dependent(grasshopper):
    a = noise_run(grasshopper, 7, 0.05, 200)
    b = noise_run(grasshopper, 7, 0.05, 200)
    c = noise_run(grasshopper, 8, 0.05, 200)
    assert a[1] == b[1]
    assert np.all(np.array(a[1]) != np.array(c[1]))
    assert len(set(a[1])) == len(a[1])  # renewed every crossing
    for run in (a, b, c):
        run[0].close()


def test_noise_renewal_semantics(grasshopper):
    M, rms = 0.004, 0.05
    inst = Instance(grasshopper, {"torque": M, "noise_rms": rms},
                    {"phi": -0.01, "w": 0.0}).initialize()
    assert inst.get("torque_amplitude") == M  # no deviation before a renewal
    inst.set(phi=0.01)
    pending = inst.get("torque_amplitude")
    assert pending != M
    # Reading the pending value does not advance the generator, and input
    # changes between communication points commit nothing.
    inst.set(phi=0.005)
    assert inst.get("torque_amplitude") == pending
    inst.set(phi=-0.01)
    assert inst.get("torque_amplitude") == M
    inst.set(phi=0.01)
    assert inst.get("torque_amplitude") == pending
    inst.step(0.01)  # commit
    assert inst.get("torque_amplitude") == pending
    assert inst.get("tau") == pytest.approx(pending, rel=1e-15)  # mode +1
    # No renewal while phi stays >= 0, nor on a downward crossing.
    for phi in (0.02, 0.0, -0.01):
        inst.set(phi=phi)
        inst.step(0.01)
        assert inst.get("torque_amplitude") == pending
    inst.close()


def test_noise_rms_statistics(grasshopper):
    rms, n = 0.05, 2000
    inst, deltas, _ = noise_run(grasshopper, 12345, rms, n)
    inst.close()
    d = np.array(deltas)
    # Sample rms of n N(0, rms^2) deviates: standard error rms / sqrt(2 n).
    assert abs(np.sqrt(np.mean(d**2)) - rms) <= 4 * rms / np.sqrt(2 * n)
    assert abs(np.mean(d)) <= 4 * rms / np.sqrt(n)


def test_no_renewal_before_noise_start(grasshopper):
    # Crossings at t = 0, 0.02, 0.04, ...; noise_start between two of them.
    inst, deltas, _ = noise_run(grasshopper, 3, 0.05, 40, noise_start=0.505)
    inst.close()
    ref, ref_deltas, _ = noise_run(grasshopper, 3, 0.05, 15)
    ref.close()
    first = 26  # t = 0.52 s
    assert all(x == 0.0 for x in deltas[:first])
    assert all(x != 0.0 for x in deltas[first:])
    # The generator is not advanced before noise_start.
    assert deltas[first:] == ref_deltas[:len(deltas) - first]


def test_fmu_state_reproduces_noise(grasshopper):
    n, k = 60, 25
    inst, deltas, (state, t_saved) = noise_run(grasshopper, 99, 0.05, n, snapshot=k)
    # Back to the snapshot and replay the same inputs.
    inst.fmu.setFMUState(state)
    inst.t = t_saved
    replay = []
    for _ in range(n - k):
        inst.set(phi=0.01)
        replay.append(inst.get("torque_amplitude") / 0.004 - 1.0)
        inst.step(0.01)
        inst.set(phi=-0.01)
        inst.step(0.01)
    assert replay == deltas[k:]

    # The same through serialization, into a fresh instance.
    blob = inst.fmu.serializeFMUState(state)
    inst.fmu.freeFMUState(state)
    inst.close()
    other = Instance(grasshopper).initialize()
    restored = other.fmu.deserializeFMUState(blob)
    other.fmu.setFMUState(restored)
    other.t = t_saved
    again = []
    for _ in range(n - k):
        other.set(phi=0.01)
        again.append(other.get("torque_amplitude") / 0.004 - 1.0)
        other.step(0.01)
        other.set(phi=-0.01)
        other.step(0.01)
    assert again == deltas[k:]
    other.close()


# ---------------------------------------------------------------------------
# Chronometer


@pytest.mark.parametrize("window_deg", [(-2.0, 2.0), (-2.0, 0.0), (0.0, 2.0)])
def test_chronometer_window(chronometer, window_deg):
    a1, a2 = (x * DEG for x in window_deg)
    M = 0.01
    inst = Instance(chronometer, {"alpha_m1": a1, "alpha_m2": a2, "torque": M}).initialize()
    assert inst.get("work_per_period") == pytest.approx(M * (a2 - a1), rel=1e-15)
    angles = sorted(set(np.linspace(-5, 5, 41) * DEG) | {a1, a2})
    inside_seen = 0
    for phi in angles:
        for w in (0.1, 0.0, -0.1):
            inst.set(phi=phi, w=w)
            expected = M if (a1 <= phi < a2 and w > 0) else 0.0
            assert inst.get("tau") == expected, (phi / DEG, w)
            inside_seen += expected > 0
            assert inst.get("event_indicator_lower") == pytest.approx(phi - a1, abs=1e-15)
            assert inst.get("event_indicator_upper") == pytest.approx(a2 - phi, abs=1e-15)
        inst.step(0.001)
    assert inside_seen > 3
    # Edges: alpha_m1 belongs to the window, alpha_m2 does not.
    inst.set(phi=a1, w=0.1)
    assert inst.get("tau") == M
    inst.set(phi=a2)
    assert inst.get("tau") == 0.0
    inst.close()


@pytest.mark.parametrize("window_deg", [(1.0, 1.0), (2.0, -2.0)])
def test_chronometer_refuses_empty_window(chronometer, window_deg):
    inst = Instance(chronometer, {"alpha_m1": window_deg[0] * DEG,
                                  "alpha_m2": window_deg[1] * DEG})
    with pytest.raises(FMICallException) as e:
        inst.initialize()
    assert e.value.status == FMI2_ERROR
    assert any("alpha_m1" in m and "alpha_m2" in m for m in inst.errors())
    inst.close()


def test_chronometer_torque_tunable(chronometer):
    inst = Instance(chronometer, {"torque": 0.01}, {"phi": 0.0, "w": 0.1}).initialize()
    inst.step(0.001)
    inst.set(torque=0.02)
    assert inst.get("tau") == 0.02
    assert inst.get("work_per_period") == pytest.approx(0.02 * 4 * DEG, rel=1e-14)
    inst.close()


# ---------------------------------------------------------------------------
# Bad input, both FMUs

FIXTURES = ["grasshopper", "chronometer"]
FIXED = {"grasshopper": ("phi_r", 0.01), "chronometer": ("alpha_m1", -0.01)}


@pytest.mark.parametrize("which", FIXTURES)
def test_nan_input_is_refused(request, which):
    inst = Instance(request.getfixturevalue(which)).initialize()
    with pytest.raises(FMICallException) as e:
        inst.set(phi=float("nan"))
    assert e.value.status == FMI2_ERROR
    assert any("phi" in m for m in inst.errors())
    inst.close()


@pytest.mark.parametrize("which", FIXTURES)
def test_fixed_parameter_after_initialization_is_refused(request, which):
    name, value = FIXED[which]
    inst = Instance(request.getfixturevalue(which)).initialize()
    with pytest.raises(FMICallException) as e:
        inst.set(**{name: value})
    assert e.value.status == FMI2_ERROR
    assert any(name in m for m in inst.errors())
    inst.close()


@pytest.mark.parametrize("which", FIXTURES)
@pytest.mark.parametrize("initialized", [False, True])
def test_negative_torque_is_refused(request, which, initialized):
    inst = Instance(request.getfixturevalue(which))
    if initialized:
        inst.initialize()
    with pytest.raises(FMICallException) as e:
        inst.set(torque=-0.001)
    assert e.value.status == FMI2_ERROR
    assert any("torque" in m for m in inst.errors())
    inst.close()


def test_profile_out_of_range_is_refused(grasshopper):
    inst = Instance(grasshopper)
    with pytest.raises(FMICallException):
        inst.set(profile=4)
    assert any("profile" in m for m in inst.errors())
    inst.close()
