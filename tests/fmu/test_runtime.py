"""The shared runtime (src_c/runtime/cw_runtime.c) through the Pendulum FMU:
the FMI 2.0 state machine, argument and range checks, and their messages."""

from __future__ import annotations

import ctypes
import math
import re

import pytest

from cwtest import fmu_file
from fmu_driver import DISCARD, ERROR, OK, FmuError, Instance, state_checksum, unpack

NUMBER = re.compile(r"[-+]?(?:nan|inf|(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)", re.I)

PARAMETERS = ["L", "m", "g", "Q", "phi_start", "w_start", "rtol", "atol", "h_max"]
INPUTS = ["tau_escapement", "tau_drag", "tau_coupling", "tau_external", "g_factor"]


@pytest.fixture(scope="module")
def fmu():
    return fmu_file("Pendulum")


def in_init_mode(fmu, **kw) -> Instance:
    p = Instance(fmu, initialize=False, **kw)
    assert p.setup() == OK and p.enter_init() == OK
    return p


def numbers_in(text: str) -> list[float]:
    return [float(x) for x in NUMBER.findall(text)]


def assert_refused(p: Instance, status: int, *words: str, value: float | None = None):
    """fmi2Error, and the last error message names every word (and the value)."""
    assert status == ERROR, p.log_text()
    errors = p.errors()
    assert errors, "nothing was logged"
    text = errors[-1].text
    assert errors[-1].category == "logStatusError"
    for w in words:
        assert w in text, f"{w!r} not in {text!r}"
    if value is not None:
        found = numbers_in(text)
        if math.isnan(value):
            assert any(math.isnan(x) for x in found), text
        else:
            assert value in found, f"{value!r} not in {text!r}"
    return text


# ---------------------------------------------------------------- values


@pytest.mark.parametrize(
    "name, value",
    [("L", 0.0), ("L", -1.0), ("m", 0.0), ("m", -2.5), ("g", 0.0), ("Q", -1.0),
     ("rtol", -1e-10), ("rtol", 0.0), ("atol", -1e-12), ("atol", 0.0), ("h_max", -0.1),
     ("phi_start", 4.0), ("g_factor", -0.5)],
)
def test_out_of_range_is_refused(fmu, name, value):
    with in_init_mode(fmu) as p:
        before = p.get(name)
        st = p.set(**{name: value})
        assert_refused(p, st, "fmi2SetReal", name, value=value)
        assert p.get(name) == before  # nothing was changed


@pytest.mark.parametrize("value", [math.nan, math.inf, -math.inf])
@pytest.mark.parametrize("name", PARAMETERS + INPUTS)
def test_non_finite_parameter_or_input_is_refused(fmu, name, value):
    with in_init_mode(fmu) as p:
        st = p.set(**{name: value})
        assert_refused(p, st, "fmi2SetReal", name, "finite", value=value)


@pytest.mark.parametrize("value", [math.nan, math.inf])
@pytest.mark.parametrize("name", INPUTS)
def test_non_finite_input_during_simulation_is_refused(fmu, name, value):
    with Instance(fmu) as p:
        p.advance(0.1)
        st = p.set(**{name: value})
        assert_refused(p, st, "fmi2SetReal", name, value=value)
    with Instance(fmu) as p:
        p.advance(0.1)
        st = p.set_input_derivatives({name: {1: value}})
        assert_refused(p, st, "fmi2SetRealInputDerivatives", name)


def test_a_refused_call_changes_nothing(fmu):
    """The runtime checks every value of a call before it sets any."""
    with in_init_mode(fmu) as p:
        st = p.set(L=2.0, m=-1.0)
        assert_refused(p, st, "m", value=-1.0)
        assert p.get("L") == 1.0


def test_wrong_value_references_are_refused(fmu):
    with Instance(fmu) as p:
        vr = (ctypes.c_uint * 1)(999)
        val = (ctypes.c_double * 1)()
        assert_refused(p, p.raw.fmi2GetReal(p.c, vr, 1, val), "fmi2GetReal", "999")
        ivr = (ctypes.c_uint * 1)(p.vr("tick_count"))
        assert_refused(p, p.raw.fmi2GetReal(p.c, ivr, 1, val), "fmi2GetReal", "Real")
        assert_refused(p, p.set(phi=0.1), "fmi2SetReal", "phi", "not a parameter or an input")
        assert_refused(p, p.set(tick_count=3), "fmi2SetInteger", "tick_count")


def test_input_derivative_orders(fmu):
    with Instance(fmu) as p:
        assert_refused(p, p.set_input_derivatives({"tau_drag": {3: 1.0}}), "order 3", "tau_drag")
        assert_refused(p, p.set_input_derivatives({"tau_drag": {0: 1.0}}), "order 0", "tau_drag")
        assert_refused(p, p.set_input_derivatives({"L": {1: 1.0}}), "not a Real input")
        assert_refused(p, p.set_input_derivatives({"phi": {1: 1.0}}), "not a Real input")
        assert p.set_input_derivatives({"tau_drag": {1: 1.0, 2: 2.0}}) == OK


# ---------------------------------------------------------------- state machine


@pytest.mark.parametrize("phase", ["Instantiated", "InitializationMode"])
def test_do_step_before_initialization(fmu, phase):
    p = Instance(fmu, initialize=False)
    with p:
        p.setup()
        if phase == "InitializationMode":
            p.enter_init()
        assert_refused(p, p.step(0.01), "fmi2DoStep", phase)
        # Refused without harm: the instance carries on from where it was.
        if phase == "Instantiated":
            assert p.enter_init() == OK
        assert p.exit_init() == OK
        assert p.step(0.01) == OK


def test_fixed_parameter_after_initialization(fmu):
    with Instance(fmu) as p:
        assert_refused(p, p.set(L=2.0), "fmi2SetReal", "'L'", "StepComplete", "fixed")
        assert p.get("L") == 1.0
        assert p.step(0.01) == OK  # a wrong-state call does not break the instance


def test_exit_initialization_twice(fmu):
    with Instance(fmu) as p:
        assert_refused(p, p.exit_init(), "fmi2ExitInitializationMode", "StepComplete")
        assert p.step(0.01) == OK


def test_enter_initialization_twice(fmu):
    with in_init_mode(fmu) as p:
        assert_refused(p, p.enter_init(), "fmi2EnterInitializationMode", "InitializationMode")
        assert p.exit_init() == OK


@pytest.mark.parametrize("initialized", [False, True])
def test_setup_experiment_after_initialization(fmu, initialized):
    p = Instance(fmu) if initialized else in_init_mode(fmu)
    with p:
        state = "StepComplete" if initialized else "InitializationMode"
        assert_refused(p, p.setup(1.0), "fmi2SetupExperiment", state)


def test_get_before_initialization_mode(fmu):
    with Instance(fmu, initialize=False) as p:
        vr = (ctypes.c_uint * 1)(p.vr("phi"))
        val = (ctypes.c_double * 1)()
        assert_refused(p, p.raw.fmi2GetReal(p.c, vr, 1, val), "fmi2GetReal", "Instantiated")


def test_calls_after_terminate(fmu):
    with Instance(fmu) as p:
        p.advance(0.1)
        assert p.raw.fmi2Terminate(p.c) == OK
        assert_refused(p, p.step(0.1), "fmi2DoStep", "Terminated")
        assert_refused(p, p.set(tau_drag=0.1), "fmi2SetReal", "Terminated")
        assert p.get("phi") == pytest.approx(0.17, abs=0.01)  # reading is still allowed
        assert_refused(p, p.raw.fmi2Terminate(p.c), "fmi2Terminate", "Terminated")


def test_error_state_blocks_stepping(fmu):
    with Instance(fmu) as p:
        assert p.set(tau_drag=math.nan) == ERROR
        assert_refused(p, p.step(0.01), "fmi2DoStep", "Error")


def test_reset_gives_a_fresh_instance(fmu):
    params = dict(L=0.7, Q=50, phi_start=0.3)
    with Instance(fmu, params) as p:
        p.advance(0.37, 20)
        assert p.raw.fmi2Reset(p.c) == OK
        p.initialize(params)
        p.advance(0.21, 30)
        after_reset = p.get_many(["phi", "w", "tick_count", "tick_time", "amplitude"])
    with Instance(fmu, params) as q:
        q.advance(0.21, 30)
        fresh = q.get_many(["phi", "w", "tick_count", "tick_time", "amplitude"])
    assert after_reset == fresh


# ---------------------------------------------------------------- instantiate


def _instantiate_raw(fmu, guid=None, kind=1, name=b"x"):
    """fmi2Instantiate directly: (component or None, messages)."""
    from fmpy.fmi2 import (
        FMU2Slave, calloc, fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE,
        fmi2CallbackFunctions, fmi2CallbackLoggerTYPE, free)

    md, unzipdir = unpack(fmu)
    messages = []
    cb = fmi2CallbackFunctions()
    cb.logger = fmi2CallbackLoggerTYPE(lambda env, n, st, cat, msg: messages.append((st, msg.decode())))
    cb.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
    cb.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
    slave = FMU2Slave(guid=md.guid, unzipDirectory=unzipdir, modelIdentifier="Pendulum")
    c = slave.dll.fmi2Instantiate(name, kind, (guid or md.guid).encode(), b"file:///tmp", ctypes.byref(cb), 0, 0)
    if c:
        slave.dll.fmi2FreeInstance(ctypes.c_void_p(c))
    slave.freeLibrary()
    return c, messages


def test_wrong_guid_returns_null(fmu):
    c, messages = _instantiate_raw(fmu, guid="{00000000-0000-0000-0000-000000000000}")
    assert c is None
    assert messages and messages[-1][0] == ERROR and "GUID" in messages[-1][1]
    with pytest.raises(FmuError, match="GUID"):
        Instance(fmu, guid="{bad}")


def test_model_exchange_and_empty_name_return_null(fmu):
    c, messages = _instantiate_raw(fmu, kind=0)
    assert c is None and "fmi2CoSimulation" in messages[-1][1]
    c, messages = _instantiate_raw(fmu, name=b"")
    assert c is None and "instanceName" in messages[-1][1]
    c, _ = _instantiate_raw(fmu)
    assert c is not None


# ---------------------------------------------------------------- doStep arguments


def test_communication_point_must_match(fmu):
    with Instance(fmu) as p:
        p.advance(0.1, 3)
        text = assert_refused(p, p.step(0.1, tc=p.time + 1e-6), "fmi2DoStep", "does not match")
        assert p.time in numbers_in(text)
        assert_refused(p, p.step(0.1, tc=0.0), "fmi2DoStep", "does not match")
        assert p.step(0.1) == OK  # refused, not broken


@pytest.mark.parametrize("h", [0.0, -0.01, -0.0, math.nan, math.inf])
def test_step_size_must_be_positive_and_finite(fmu, h):
    with Instance(fmu) as p:
        p.advance(0.1)
        assert_refused(p, p.step(h), "fmi2DoStep", "step size")
        assert p.step(0.1) == OK


def test_stop_time(fmu):
    with Instance(fmu, stop_time=1.0) as p:
        p.advance(0.25, 4)
        assert_refused(p, p.step(0.25), "fmi2DoStep", "stopTime")
    p = Instance(fmu, initialize=False)
    with p:
        assert_refused(p, p.setup(2.0, 1.0), "fmi2SetupExperiment", "stopTime")


def test_last_successful_time_and_status(fmu):
    from fmpy.fmi2 import fmi2DoStepStatus

    with Instance(fmu, start_time=3.0) as p:
        assert p.last_successful_time() == 3.0
        p.advance(0.125, 3)
        assert p.last_successful_time() == 3.375
        st = ctypes.c_int()
        assert p.raw.fmi2GetStatus(p.c, fmi2DoStepStatus, ctypes.byref(st)) == OK
        assert st.value == OK


# ---------------------------------------------------------------- logging


def test_debug_logging_categories(fmu):
    with Instance(fmu, logging_on=True, name="loud") as p:
        p.advance(0.5, 6)  # the first tick is at 3T/4 = 1.5 s
        events = [m for m in p.messages if m.category == "logEvents"]
        assert len(events) == p.get("tick_count") == 1
        assert "tick 1" in events[0].text
        cats = (ctypes.c_char_p * 1)(b"noSuchCategory")
        assert_refused(p, p.raw.fmi2SetDebugLogging(p.c, 1, 1, cats), "noSuchCategory")
        cats = (ctypes.c_char_p * 1)(b"logEvents")
        assert p.raw.fmi2SetDebugLogging(p.c, 0, 1, cats) == OK
        n = len(p.messages)
        p.advance(0.5, 8)
        assert p.get("tick_count") == 3 and len(p.messages) == n  # silenced
    with Instance(fmu, name="quiet") as q:
        q.advance(0.5, 10)
        assert q.messages == []  # nothing unless asked for or wrong


def test_percent_signs_cannot_reach_a_printf_logger(fmu):
    """Some environments pass the message to printf: caller text with '%'
    must not survive into it."""
    with Instance(fmu) as p:
        cats = (ctypes.c_char_p * 1)(b"log%s%n")
        text = assert_refused(p, p.raw.fmi2SetDebugLogging(p.c, 1, 1, cats), "log s n")
        assert "%" not in text


# ---------------------------------------------------------------- failures and memory


def test_discarded_step_and_recovery(fmu):
    """A torque that overflows the acceleration: the step is discarded with a
    reason, time stays at tc, and the master can go back to a saved state."""
    from fmpy.fmi2 import fmi2DoStepStatus

    with Instance(fmu, dict(m=1e-9, L=1e-6)) as p:
        p.advance(1e-4, 3)
        saved = p.get_state()
        t_saved = p.time
        phi_saved = p.get("phi")
        p.set(tau_external=1e300)
        assert p.step(1e-4) == DISCARD
        assert "discarded" in p.messages[-1].text and p.messages[-1].status == DISCARD
        assert p.last_successful_time() == t_saved
        st = ctypes.c_int()
        assert p.raw.fmi2GetStatus(p.c, fmi2DoStepStatus, ctypes.byref(st)) == OK
        assert st.value == DISCARD
        assert_refused(p, p.step(1e-4), "fmi2DoStep", "StepFailed")
        assert p.set_state(saved) == OK
        p.free_state(saved)
        assert p.get("phi") == phi_saved and p.get("tau_external") == 0.0
        assert p.step(1e-4) == OK


def _rss_bytes() -> int:
    import os

    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")


def test_instances_are_freed(fmu):
    """20000 instantiate/initialize/step/free cycles through the raw functions."""
    with Instance(fmu) as p:
        raw, md = p.raw, p.md
        cb = p._callbacks
        guid = md.guid.encode()

        def cycles(n):
            for _ in range(n):
                c = ctypes.c_void_p(raw.fmi2Instantiate(b"cycle", 1, guid, b"", ctypes.byref(cb), 0, 0))
                assert c.value
                assert raw.fmi2SetupExperiment(c, 0, 0.0, 0.0, 0, 0.0) == OK
                assert raw.fmi2EnterInitializationMode(c) == OK
                assert raw.fmi2ExitInitializationMode(c) == OK
                assert raw.fmi2DoStep(c, 0.0, 0.01, 1) == OK
                raw.fmi2FreeInstance(c)

        cycles(1000)
        before = _rss_bytes()
        cycles(20_000)
        grown = _rss_bytes() - before
    # One leaked instance is ~0.5 kB: a leak would show as ~10 MB.
    assert grown < 1 << 20, grown


# ---------------------------------------------------------------- states and parameter rules



def _patched(md, data: bytes, **changes) -> bytes:
    """The serialized state with variables (and `machine`) replaced and the
    checksum redone: a state that passes every layout check
    (docs/design.md: 32 header bytes, then the variables in table order)."""
    import struct

    out = bytearray(data)
    if "machine" in changes:
        struct.pack_into("<I", out, 20, changes.pop("machine"))
    off = 32
    for v in sorted(md.modelVariables, key=lambda v: v.valueReference):
        if v.name in changes:
            if v.type == "Real":
                struct.pack_into("<d", out, off, changes.pop(v.name))
            else:
                struct.pack_into("<i", out, off, changes.pop(v.name))
        if v.type != "Real":
            off += 4
        else:
            off += 32 if v.causality == "input" else 8  # inputs: value, d1, d2, t_ref
    assert not changes, changes
    out[-8:] = state_checksum(bytes(out[:-8])).to_bytes(8, "little")
    return bytes(out)


def _overwrite_state(state, data: bytes):
    """Put bytes into an FMU state the instance handed out. The runtime keeps
    a size_t byte count in front of the serialized layout; the bytes there are
    checked against fmi2SerializeFMUstate first."""
    offset = ctypes.sizeof(ctypes.c_size_t)
    assert ctypes.c_size_t.from_address(state.value).value == len(data)
    ctypes.memmove(state.value + offset, data, len(data))


@pytest.fixture(scope="module")
def chronometer():
    return fmu_file("ChronometerEscapement")


def _chronometer_run(p: Instance, n=5):
    out = []
    for k in range(n):
        p.set(phi=0.01 * k - 0.02, w=0.3)
        out.append(p.get_many(["tau", "event_indicator_lower", "work_per_period"]))
        assert p.step(0.001) == OK
    return out


def test_state_breaking_a_parameter_rule_is_refused(chronometer):
    """alpha_m1 < alpha_m2 is checked by the model at fmi2ExitInitializationMode;
    a saved state must not bring in alpha_m1 >= alpha_m2 (each value inside
    its own range) through fmi2DeSerializeFMUstate or fmi2SetFMUstate."""
    with Instance(chronometer, dict(torque=0.02)) as p:
        md = p.md
        _chronometer_run(p, 3)
        good = p.get_state()
        data = p.serialize(good)
        t_good = p.time
        reference = _chronometer_run(p)
        bad = _patched(md, data, alpha_m1=0.5)  # alpha_m2 is 0.0349

        # Deserialization refuses it, and says why.
        p.messages.clear()
        st, state = p.deserialize(bad)
        assert st == ERROR and not state.value
        text = p.log_text()
        assert "alpha_m1" in text and "fmi2DeSerializeFMUstate" in p.errors()[-1].text, text

        # fmi2SetFMUstate refuses the same bytes put into a state it issued.
        assert p.set_state(good) == OK
        p.time = t_good
        p.advance(0.001, 2)
        before = p.get_many(["alpha_m1", "alpha_m2", "torque", "tau", "phi"])
        crafted = p.get_state()
        assert p.serialize(crafted) != bad
        _overwrite_state(crafted, bad)
        p.messages.clear()
        assert p.set_state(crafted) == ERROR
        text = p.log_text()
        assert "alpha_m1" in text and "fmi2SetFMUstate" in p.errors()[-1].text, text
        assert p.get_many(["alpha_m1", "alpha_m2", "torque", "tau", "phi"]) == before

        # Still usable: a good state restores it, and it runs on as before.
        assert p.set_state(good) == OK
        p.time = t_good
        assert _chronometer_run(p) == reference
        for s in (good, crafted):
            assert p.free_state(s) == OK


def test_state_rules_apply_after_initialization_only(chronometer):
    """In Initialization Mode parameters may be inconsistent for a while (set
    one after the other); a state saved there is restored as it is, and the
    rule is applied when initialization ends."""
    p = Instance(chronometer, initialize=False)
    with p:
        assert p.setup() == OK and p.enter_init() == OK
        assert p.set(alpha_m1=0.5) == OK
        s = p.get_state()
        data = p.serialize(s)
        st, restored = p.deserialize(data)
        assert st == OK
        assert p.set_state(restored) == OK
        # The same parameters in a state marked as initialized are refused.
        st, _ = p.deserialize(_patched(p.md, data, machine=4))
        assert st == ERROR
        assert p.set_state(restored) == OK  # back in Initialization Mode
        assert_refused(p, p.exit_init(), "alpha_m1")
        for x in (s, restored):
            p.free_state(x)
