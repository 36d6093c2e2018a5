"""The FMI 3.0 build of every FMU (fmus/fmi3/<Name>.fmu): the same model core
as the FMI 2.0 build behind the fmi3 face (src_c/runtime/cw_fmi3.c).

What is checked: fmpy's validation and simulation with Event Mode and early
return; the modelDescription.xml against the FMI 2.0 one; the FMI 3.0 state
machine under any call order (refused calls give fmi3Error with a message,
nothing crashes); instances that do not share anything; FMU states saved,
serialized and restored bit for bit; the same bits as the FMI 2.0 build on a
driven run; and early return at the pendulum's own events."""

from __future__ import annotations

import ctypes
import math
import random
import tomllib
import zipfile

import numpy as np
import pytest
from fmpy import read_model_description, simulate_fmu
from fmpy.validation import validate_fmu

from cwtest import ROOT, fmu_file
from fmu3_driver import Instance3, find_fmu3
from fmu_driver import DISCARD, ERROR, OK, WARNING, FmuError, Instance

# Every model folder: a new model is tested as FMI 3.0 without a change here.
MODELS = sorted(p.parent.name for p in (ROOT / "src_c" / "models").glob("*/model.toml"))
# The models whose events are their own (docs/design.md, "Early return").
EARLY_RETURN = {m for m in MODELS
                if tomllib.loads((ROOT / "src_c" / "models" / m / "model.toml").read_text())["model"].get("early_return")}


def signal(name: str, t: float, k: int, var=None) -> float:
    """A deterministic input in range for every model: a swinging pendulum
    for the escapements (phi through +-phi_r), small torques, gravity near 1;
    any other input near its start, inside its range."""
    if name == "phi":
        return 0.3 * math.sin(math.pi * t)
    if name == "w":
        return 0.3 * math.pi * math.cos(math.pi * t)
    if name == "g_factor":
        return 1.0 + 0.1 * math.sin(5 * t)
    x = 1e-3 * math.sin(3 * t + k)
    if var is not None:
        x += float(var.start or 0.0)
        lo = -math.inf if var.min is None else float(var.min)
        hi = math.inf if var.max is None else float(var.max)
        x = min(max(x, lo), hi)
    return x


def inputs_of(md) -> list[str]:
    return [v.name for v in md.modelVariables if v.causality == "input"]


def outputs_of(md) -> list[str]:
    return [v.name for v in md.modelVariables if v.causality == "output"]


@pytest.mark.parametrize("model", MODELS)
def test_validates_and_has_the_fmi3_layout(model):
    path = find_fmu3(model)
    assert validate_fmu(str(path)) == []
    names = set(zipfile.ZipFile(path).namelist())
    for entry in ("modelDescription.xml", f"binaries/x86_64-linux/{model}.so",
                  "terminalsAndIcons/icon.png", "documentation/index.html",
                  "documentation/licenses/LICENSE.txt", "sources/buildDescription.xml",
                  "sources/cw_fmi3.c", "sources/model.c"):
        assert entry in names, entry
    assert "sources/cw_fmi2.c" not in names
    page = zipfile.ZipFile(path).read("documentation/index.html").decode()
    assert "FMI 3.0 Co-Simulation FMU" in page and "fmi2" not in page


@pytest.mark.parametrize("model", MODELS)
def test_model_description_matches_the_fmi2_build(model):
    md2 = read_model_description(str(fmu_file(model)))
    md3 = read_model_description(str(find_fmu3(model)))
    assert md3.fmiVersion == "3.0" and md3.instantiationToken == md2.guid
    types = {"Real": "Float64", "Integer": "Int32", "Boolean": "Boolean"}
    v2 = {v.name: v for v in md2.modelVariables}
    v3 = {v.name: v for v in md3.modelVariables}
    (time,) = [v for v in md3.modelVariables if v.causality == "independent"]
    assert time.name == "time" and time.valueReference == max(v.valueReference for v in md2.modelVariables) + 1
    assert set(v3) - {"time"} == set(v2)
    for name, a in v2.items():
        b = v3[name]
        assert (types[a.type], a.valueReference, a.causality, a.variability, a.unit, a.start, a.min, a.max) == \
               (b.type, b.valueReference, b.causality, b.variability, b.unit, b.start, b.min, b.max), name
    # The same dependencies, by variable rather than by index or reference.
    def structure(unknowns):
        return {u.variable.name: (None if u.dependencies is None else
                                  sorted(zip([d.name for d in u.dependencies], u.dependenciesKind or [])))
                for u in unknowns}
    assert structure(md3.outputs) == structure(md2.outputs)
    assert structure(md3.initialUnknowns) == structure(md2.initialUnknowns)
    cs = md3.coSimulation
    # Intermediate update (FMI 3.0's replacement for input derivatives) for
    # the models with Float64 inputs, on each of those inputs.
    real_inputs = [n for n, a in v2.items() if a.causality == "input" and a.type == "Real"]
    assert cs.hasEventMode and cs.providesIntermediateUpdate == bool(real_inputs)
    xml = zipfile.ZipFile(find_fmu3(model)).read("modelDescription.xml").decode()
    assert xml.count('intermediateUpdate="true"') == len(real_inputs)
    assert ('recommendedIntermediateInputSmoothness="2"' in xml) == bool(real_inputs)
    assert cs.mightReturnEarlyFromDoStep == (model in EARLY_RETURN)
    assert cs.canGetAndSetFMUstate and cs.canSerializeFMUstate and cs.canHandleVariableCommunicationStepSize
    assert cs.maxOutputDerivativeOrder == md2.coSimulation.maxOutputDerivativeOrder


@pytest.mark.parametrize("model", MODELS)
def test_fmpy_simulates_with_event_mode_and_early_return(model):
    path = find_fmu3(model)
    md = read_model_description(str(path))
    ins = inputs_of(md)
    t = np.linspace(0.0, 4.0, 401)
    v = {x.name: x for x in md.modelVariables}
    signals = np.array([tuple([tk] + [signal(nm, tk, k, v[nm]) for k, nm in enumerate(ins)]) for tk in t],
                       dtype=[("time", float)] + [(nm, float) for nm in ins]) if ins else None
    result = simulate_fmu(str(path), stop_time=4.0, output_interval=0.05, input=signals,
                          use_event_mode=True, early_return_allowed=True)
    assert result["time"][-1] == pytest.approx(4.0)
    for name in result.dtype.names:
        assert np.all(np.isfinite(result[name].astype(float))), name
    # Early returns add communication points only for the models whose events are
    # their own (the Pendulum ticks and turns within 4 s; AveragedPendulum does not stall).
    regular = np.isclose(result["time"] / 0.05, np.round(result["time"] / 0.05), rtol=0, atol=1e-9)
    if model not in EARLY_RETURN:
        assert regular.all()
    if model == "Pendulum":
        assert not regular.all()


# ---------------------------------------------------------------- driven runs

# Parameters that make a driven run exercise more: the escapement's noise
# (renewed at upward zero crossings, from its RNG state).
DRIVEN_PARAMS = {"GrasshopperEscapement": {"noise_rms": 0.2, "noise_seed": 7}}


def driven_run(model: str, fmi: int, steps: int = 400, h: float = 0.01, event_mode: bool = False):
    """Every output after every step, the inputs held over each step."""
    params = DRIVEN_PARAMS.get(model)
    if fmi == 2:
        inst = Instance(fmu_file(model), params=params)
    else:
        inst = Instance3(find_fmu3(model), params=params, event_mode=event_mode)
    with inst as p:
        ins, outs = inputs_of(p.md), outputs_of(p.md)
        rows = []
        for n in range(steps):
            values = {nm: signal(nm, p.time, k, p.vars[nm]) for k, nm in enumerate(ins)}
            if fmi == 3 and event_mode:
                # The importer's event at every point: the modes are committed
                # in Event Mode, and again (without effect) by fmi3DoStep.
                p.check(p.raw.fmi3EnterEventMode(p.c), "fmi3EnterEventMode")
                p.check(p.set(**values), "set")
                p.settle()
            elif values:
                p.check(p.set(**values), "set")
            st = p.step(h)
            p.check(st if fmi == 2 else st.status, "step")
            rows.append([float(x) for x in p.get_many(outs)])
        return np.array(rows)


@pytest.mark.parametrize("event_mode", [False, True])
@pytest.mark.parametrize("model", MODELS)
def test_driven_run_gives_the_fmi2_bits(model, event_mode):
    a = driven_run(model, 2)
    b = driven_run(model, 3, event_mode=event_mode)
    assert a.shape == b.shape and np.all(np.isfinite(a))
    assert np.array_equal(a.view(np.uint64), b.view(np.uint64))


# ---------------------------------------------------------------- state machine

class Machine:
    """The FMI 3.0 Co-Simulation state machine as the standard draws it,
    for the calls the test makes; None means: refused (fmi3Error)."""

    def __init__(self, event_mode: bool):
        self.event_mode = event_mode
        self.state = "Instantiated"

    def after(self, call: str) -> str | None:
        s, e = self.state, self.event_mode
        table = {
            "enter_init": {"Instantiated": "InitializationMode"},
            "exit_init": {"InitializationMode": "EventMode" if e else "StepMode"},
            "enter_event": {"StepMode": "EventMode"} if e else {},
            "update": {"EventMode": "EventMode"},
            "enter_step": {"EventMode": "StepMode"},
            "do_step": {"StepMode": "StepMode"},
            "terminate": {"EventMode": "Terminated", "StepMode": "Terminated"},
            "reset": dict.fromkeys(["Instantiated", "InitializationMode", "EventMode", "StepMode",
                                    "Terminated"], "Instantiated"),
            "get": dict.fromkeys(["InitializationMode", "EventMode", "StepMode", "Terminated"]),
            "set_input": dict.fromkeys(["Instantiated", "InitializationMode", "EventMode", "StepMode"]),
            "get_state": dict.fromkeys(["Instantiated", "InitializationMode", "EventMode", "StepMode",
                                        "Terminated"]),
        }[call]
        if s not in table:
            return None
        return table[s] or s


CALLS = ["enter_init", "exit_init", "enter_event", "update", "enter_step", "do_step", "terminate",
         "reset", "get", "set_input", "get_state", "set_state"]


def make_call(p: Instance3, call: str, saved: list) -> int:
    if call == "enter_init":
        return p.enter_init(p.time)
    if call == "exit_init":
        return p.exit_init()
    if call == "enter_event":
        return p.raw.fmi3EnterEventMode(p.c)
    if call == "update":
        return p.update_discrete_states()[0]
    if call == "enter_step":
        return p.raw.fmi3EnterStepMode(p.c)
    if call == "do_step":
        return p.step(0.05).status
    if call == "terminate":
        return p.raw.fmi3Terminate(p.c)
    if call == "reset":
        return p.raw.fmi3Reset(p.c)
    name = outputs_of(p.md)[0]
    vr = (ctypes.c_uint32 * 1)(p.vr(name))
    if call == "get":
        out = (ctypes.c_double * 1)()
        return p.raw.fmi3GetFloat64(p.c, vr, 1, out, 1) if p.vars[name].type == "Float64" else \
            p.raw.fmi3GetInt32(p.c, vr, 1, (ctypes.c_int32 * 1)(), 1)
    if call == "set_input":
        ins = inputs_of(p.md)
        return p.set(**{ins[0]: float(p.vars[ins[0]].start or 0.0)}) if ins else None
    if call == "get_state":
        state = ctypes.c_void_p()
        st = p.raw.fmi3GetFMUState(p.c, ctypes.byref(state))
        if st == OK:
            saved.append(state)
        return st
    raise AssertionError(call)


@pytest.mark.parametrize("event_mode", [False, True])
@pytest.mark.parametrize("model", MODELS)
def test_state_machine_in_any_call_order(model, event_mode):
    rng = random.Random(f"{model}{event_mode}")
    with Instance3(find_fmu3(model), event_mode=event_mode, initialize=False) as p:
        m = Machine(event_mode)
        saved: list = []  # (FMU state, machine state, time)
        for n in range(400):
            call = rng.choice(CALLS)
            if call == "set_state":
                if not saved:
                    continue
                state, mstate, t = rng.choice(saved)
                assert p.set_state(state) == OK, p.log_text()
                m.state, p.time = mstate, t
                continue
            before = len(p.errors())
            expected = m.after(call)
            states: list = []
            st = make_call(p, call, states)
            if st is None:  # no input to set
                continue
            if expected is None:
                assert st == ERROR, (n, call, m.state, p.log_text())
                assert len(p.errors()) > before, (call, m.state)  # said why
                assert "may not be called in state" in p.errors()[-1].text or call == "enter_event"
            else:
                assert st == OK, (n, call, m.state, p.log_text())
                m.state = expected
                if call in ("reset", "enter_init"):
                    p.time = 0.0
                for s in states:
                    saved.append((s, m.state, p.time))
        for state, _, _ in saved:
            p.free_state(state)


def test_refused_and_inapplicable_functions():
    with Instance3(find_fmu3("GrasshopperEscapement")) as p:
        vr = (ctypes.c_uint32 * 1)(p.vr("tau"))
        u64 = (ctypes.c_uint64 * 1)()
        checks = {
            "fmi3GetUInt64": lambda: p.raw.fmi3GetUInt64(p.c, vr, 1, u64, 1),
            "fmi3GetClock": lambda: p.raw.fmi3GetClock(p.c, vr, 1, (ctypes.c_bool * 1)()),
            "fmi3EnterConfigurationMode": lambda: p.raw.fmi3EnterConfigurationMode(p.c),
            "fmi3EnterEventMode": lambda: p.raw.fmi3EnterEventMode(p.c),  # eventModeUsed = false
            "fmi3GetFloat64": lambda: p.raw.fmi3GetFloat64(p.c, vr, 1, (ctypes.c_double * 2)(), 2),
            "fmi3EnterContinuousTimeMode": lambda: p.raw.fmi3EnterContinuousTimeMode(p.c),
            "fmi3EvaluateDiscreteStates": lambda: p.raw.fmi3EvaluateDiscreteStates(p.c),
            "fmi3GetNumberOfVariableDependencies":
                lambda: p.raw.fmi3GetNumberOfVariableDependencies(p.c, 0, ctypes.byref(ctypes.c_size_t())),
        }
        for fn, call in checks.items():
            n = len(p.errors())
            assert call() == ERROR, fn
            assert len(p.errors()) == n + 1 and p.errors()[-1].text.startswith(fn), (fn, p.log_text())
        # None of them hurt the instance: it still steps.
        assert p.step(0.01).status == OK
        # The independent variable reads as the time.
        t = (ctypes.c_double * 1)()
        time_vr = (ctypes.c_uint32 * 1)(p.md.modelVariables[0].valueReference)
        assert p.md.modelVariables[0].name == "time"
        assert p.raw.fmi3GetFloat64(p.c, time_vr, 1, t, 1) == OK and t[0] == p.time == 0.01


@pytest.mark.parametrize("token", ["{00000000-0000-0000-0000-000000000000}", ""])
def test_wrong_instantiation_token_gives_null_with_a_reason(token):
    with pytest.raises(FmuError, match="instantiationToken .* does not match"):
        Instance3(find_fmu3("Drag"), token=token)


def test_model_exchange_is_refused():
    from fmpy.fmi3 import FMU3Model, fmi3LogMessageCallback
    from fmu_driver import unpack

    md, unzipdir = unpack(find_fmu3("Drag"))
    said = []
    log = fmi3LogMessageCallback(lambda env, st, cat, msg: said.append(msg.decode()))
    lib = FMU3Model(guid=md.guid, unzipDirectory=unzipdir, modelIdentifier="Drag", instanceName="x")
    try:
        assert not lib.dll.fmi3InstantiateModelExchange(b"x", md.instantiationToken.encode(), None,
                                                        False, False, None, log)
        assert said and "Co-Simulation FMU only" in said[0]
    finally:
        lib.freeLibrary()


# ---------------------------------------------------------------- instances and states

def test_instances_share_nothing():
    with Instance3(find_fmu3("Pendulum"), params={"phi_start": 0.1}, name="a") as a, \
         Instance3(find_fmu3("Pendulum"), params={"phi_start": 0.5, "L": 2.0}, name="b") as b:
        for _ in range(100):
            a.check(a.step(0.01).status, "a")
            b.check(b.step(0.01).status, "b")
        pa, pb = a.get("phi"), b.get("phi")
    with Instance3(find_fmu3("Pendulum"), params={"phi_start": 0.1}) as alone:
        for _ in range(100):
            alone.step(0.01)
        assert alone.get("phi") == pa != pb


@pytest.mark.parametrize("model", MODELS)
def test_state_round_trip_is_bit_exact(model):
    with Instance3(find_fmu3(model), event_mode=True) as p, Instance3(find_fmu3(model), name="twin") as twin:
        ins, outs = inputs_of(p.md), outputs_of(p.md)
        for n in range(50):
            p.set(**{nm: signal(nm, p.time, k, p.vars[nm]) for k, nm in enumerate(ins)})
            p.check(p.step(0.02).status, "step")
        state, t_saved = p.get_state(), p.time
        data = p.serialize(state)
        later = []
        for n in range(30):
            p.set(**{nm: signal(nm, p.time, k, p.vars[nm]) for k, nm in enumerate(ins)})
            p.check(p.step(0.02).status, "step")
            later.append(p.get_many(outs))
        # Back in time on the same instance, and forward in a fresh one, from the bytes.
        assert p.set_state(state) == OK
        st, copy = twin.deserialize(data)
        assert st == OK, twin.log_text()
        assert twin.set_state(copy) == OK, twin.log_text()
        for inst in (p, twin):
            inst.time = t_saved
            for n in range(30):
                inst.set(**{nm: signal(nm, inst.time, k, inst.vars[nm]) for k, nm in enumerate(ins)})
                inst.check(inst.step(0.02).status, "step")
                assert inst.get_many(outs) == later[n]
        p.free_state(state)
        twin.free_state(copy)
        # A damaged state is refused whole, with a reason.
        bad = bytearray(data)
        bad[40] ^= 1
        st, _ = twin.deserialize(bytes(bad))
        assert st == ERROR and "checksum" in twin.errors()[-1].text


def test_an_fmi2_state_restores_in_the_fmi3_build():
    """One state layout, one model token: a state serialized by the FMI 2.0
    build continues in the FMI 3.0 build with the same bits."""
    with Instance(fmu_file("Pendulum"), params={"phi_start": 0.3}) as p2:
        p2.advance(0.05, 20)
        data, t_saved = p2.serialize(p2.get_state()), p2.time
        p2.advance(0.05, 20)
        want = p2.get_many(outputs_of(p2.md))
    with Instance3(find_fmu3("Pendulum")) as p3:
        st, state = p3.deserialize(data)
        assert st == OK and p3.set_state(state) == OK, p3.log_text()
        p3.time = t_saved
        for _ in range(20):
            p3.check(p3.step(0.05).status, "step")
        assert p3.get_many(outputs_of(p3.md)) == want
        p3.free_state(state)


# ---------------------------------------------------------------- early return

def test_early_return_at_the_tick_and_turning_points():
    """With a half-period step, every fmi3DoStep ends at the next tick or
    turning point: lastSuccessfulTime is tick_time exactly, phi = 0 (tick)
    or w = 0 (turn) there, and Event Mode is asked for."""
    params = {"phi_start": -0.2, "Q": 0.0}
    with Instance3(find_fmu3("Pendulum"), params=params, event_mode=True, early_return=True) as p, \
         Instance(fmu_file("Pendulum"), params=params) as ref:
        ticks, turns = 0, 0
        tick_times = []
        while p.time < 10.0:
            t0 = p.time
            r = p.step(0.9)
            p.check(r.status, "fmi3DoStep")
            phi, w, n_tick, tick_time, n_turn = p.get_many(["phi", "w", "tick_count", "tick_time", "turn_count"])
            if r.early_return:
                assert r.event_handling_needed and t0 < r.last_successful_time < t0 + 0.9
                if n_tick == ticks + 1:
                    assert tick_time == r.last_successful_time and phi == 0.0 and w > 0
                    tick_times.append(tick_time)
                else:
                    assert n_turn == turns + 1 and w == 0.0
                ticks, turns = n_tick, n_turn
                assert p.raw.fmi3EnterEventMode(p.c) == OK
                p.settle()
            else:
                assert (n_tick, n_turn) == (ticks, turns)  # no event was skipped
                assert not r.event_handling_needed and r.last_successful_time == t0 + 0.9
        assert len(tick_times) >= 4 and turns >= 2 * len(tick_times) - 1
        # The FMI 2.0 build, with fixed steps, finds the same ticks (each located
        # to the integrator's tolerance, rtol = 1e-10, on a 2 s period).
        ref_ticks = []
        while ref.time < tick_times[-1] + 0.1:
            ref.advance(0.01)
            if ref.get("tick_count") > len(ref_ticks):
                ref_ticks.append(ref.get("tick_time"))
        assert np.max(np.abs(np.array(ref_ticks[:len(tick_times)]) - tick_times)) < 1e-9


def test_no_early_return_unless_allowed():
    with Instance3(find_fmu3("Pendulum"), params={"phi_start": -0.2}, event_mode=True) as p:
        for _ in range(10):
            r = p.step(0.9)
            assert r.status == OK and not r.early_return and not r.event_handling_needed
        assert p.get("tick_count") >= 4
    # An escapement's switch depends on its input: the importer locates it.
    with Instance3(find_fmu3("GrasshopperEscapement"), event_mode=True, early_return=True) as e:
        modes = set()
        for n in range(200):
            e.set(phi=signal("phi", e.time, 0), w=signal("w", e.time, 1))
            r = e.step(0.05)
            assert r.status == OK and not r.early_return and not r.event_handling_needed
            modes.add(e.get("mode"))
        assert modes == {-1, 1}


def test_without_event_mode_an_early_return_asks_for_no_event_mode():
    with Instance3(find_fmu3("Pendulum"), params={"phi_start": -0.2}, early_return=True) as p:
        r = p.step(0.9)
        assert r.status == OK and r.early_return and not r.event_handling_needed
        assert p.get("tick_time") == r.last_successful_time == p.time


def test_early_return_at_the_stall():
    """AveragedPendulum's stall is its own event: with drive 0 the amplitude
    decays as lambda^2 = lambda0^2 exp(-omega0 t / Q), and fmi3DoStep ends
    where lambda = phi_r, with `stalled` true there and lambda = phi_r exactly."""
    lam0, q, phi_r = 0.1, 50.0, 0.03
    omega0 = math.sqrt(9.81)
    t_stall = math.log(lam0 ** 2 / phi_r ** 2) * q / omega0
    with Instance3(find_fmu3("AveragedPendulum"), params={"amplitude_start": lam0, "Q": q, "phi_r": phi_r},
                   event_mode=True, early_return=True) as p:
        returns = []
        while p.time < 100.0:
            r = p.step(1.0)
            p.check(r.status, "fmi3DoStep")
            if r.early_return:
                returns.append(r.last_successful_time)
                assert r.event_handling_needed and p.get_many(["amplitude", "stalled"]) == [phi_r, True]
                assert p.raw.fmi3EnterEventMode(p.c) == OK
                p.settle()
            else:
                assert p.get("stalled") == (p.time > t_stall)
        # One stall; its time to the integrator's tolerance: an error rtol in
        # lambda^2 moves it by rtol Q / omega0.
        assert len(returns) == 1 and abs(returns[0] - t_stall) < 1e-10 * q / omega0


def test_the_sources_build_with_fmi3_headers_only(tmp_path):
    """The archive's sources/ (as buildDescription.xml lists them) compile with
    FMI 3.0's headers alone, and the library answers."""
    import os
    import shutil
    import subprocess
    import xml.etree.ElementTree as ET

    import fmpy

    path = find_fmu3("Pendulum")
    with zipfile.ZipFile(path) as z:
        z.extractall(tmp_path / "fmu")
    headers = tmp_path / "headers"
    headers.mkdir()
    for h in ("fmi3Functions.h", "fmi3FunctionTypes.h", "fmi3PlatformTypes.h"):
        shutil.copy(os.path.join(os.path.dirname(fmpy.__file__), "c-code", h), headers)
    sources = tmp_path / "fmu" / "sources"
    build = ET.parse(sources / "buildDescription.xml").getroot()
    files = [str(sources / f.get("name")) for f in build.iter("SourceFile")]
    lib = tmp_path / "Pendulum.so"
    cc = os.environ.get("CC", "cc")
    r = subprocess.run([cc, "-std=c99", "-shared", "-fPIC", "-O0", f"-I{sources}", f"-I{headers}", *files,
                        "-lm", "-o", str(lib)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    version = ctypes.CDLL(str(lib)).fmi3GetVersion
    version.restype = ctypes.c_char_p
    assert version() == b"3.0"


def test_intermediate_update_hands_the_pendulum_its_inputs_at_each_stage():
    """With an intermediateUpdate callback, fmi3DoStep asks for the inputs at
    the times its integrator needs them (inside the step, in Intermediate
    Update Mode: set requested, get not allowed, no early return), where
    only Float64 inputs may be set and every other call is refused. Fed
    the polynomial an FMI 2.0 instance gets from
    fmi2SetRealInputDerivatives, evaluated as the runtime evaluates it, the
    FMI 3.0 Pendulum gives the FMI 2.0 bits."""
    params = {"phi_start": 0.2, "Q": 200.0}
    u0, d1, d2, h = 1e-3, -4e-3, 2.5e-3, 0.05
    calls, refused = [], []

    def feed(inst, t, set_requested, get_allowed, step_finished, can_return_early):
        calls.append((inst.time, t, set_requested, get_allowed, step_finished, can_return_early))
        if len(calls) == 1:  # what Intermediate Update Mode refuses
            refused.append(inst.set(L=2.0))
            refused.append(inst.step(h).status)
            phi = (ctypes.c_uint32 * 1)(inst.vr("phi"))
            refused.append(inst.raw.fmi3GetFloat64(inst.c, phi, 1, (ctypes.c_double * 1)(), 1))
        tref = inst.time  # the step's communication point, where u0 was set
        dt = t - tref
        assert inst.set(tau_external=u0 + dt * (d1 + 0.5 * dt * d2)) == OK

    phi2, phi3 = [], []
    with Instance(fmu_file("Pendulum"), params=params) as p2, \
         Instance3(find_fmu3("Pendulum"), params=params, intermediate_update=feed) as p3:
        for _ in range(8):
            p2.check(p2.set(tau_external=u0), "set")
            p2.check(p2.set_input_derivatives({"tau_external": {1: d1, 2: d2}}), "derivatives")
            p2.check(p2.step(h), "step")
            p3.check(p3.set(tau_external=u0), "set")
            start = len(calls)
            r = p3.step(h)
            assert r.status == OK, p3.log_text()
            assert len(calls) - start >= 4  # the RK stages of at least one internal step
            phi2.append(p2.get_many(["phi", "w", "a"]))
            phi3.append(p3.get_many(["phi", "w", "a"]))
        assert refused == [ERROR, ERROR, ERROR] and len(p3.errors()) == 3
    assert phi2 == phi3
    assert all(tc <= t <= tc + h and tuple(flags) == (True, False, False, False) for tc, t, *flags in calls)
    # Without a callback nothing asks: the inputs hold over the step.
    with Instance3(find_fmu3("Pendulum"), params=params) as p3:
        p3.check(p3.set(tau_external=u0), "set")
        assert p3.step(h).status == OK


EVENT_OUTPUTS = ["phi", "w", "a", "energy", "tick_count", "tick_time", "tick_w", "turn_count", "amplitude", "period"]


def _output_derivatives(p) -> list[float]:
    vrs = (ctypes.c_uint32 * 4)(*[p.vr(n) for n in ("phi", "phi", "w", "w")])
    orders = (ctypes.c_int32 * 4)(1, 2, 1, 2)
    values = (ctypes.c_double * 4)()
    p.check(p.raw.fmi3GetOutputDerivatives(p.c, vrs, 4, orders, values, 4), "fmi3GetOutputDerivatives")
    return list(values)


def _after_early_return(p, kind: str) -> list:
    """What instance p shows after call sequence `kind`, made right after an
    early return (p stands at the event)."""
    if kind == "get":
        return p.get_many(EVENT_OUTPUTS)
    if kind == "output derivatives":
        return _output_derivatives(p) + p.get_many(EVENT_OUTPUTS)
    if kind in ("state", "serialized state"):
        t_event, state = p.time, p.get_state()
        for _ in range(4):  # on to the next event, whose state is left pending in turn
            r = p.step(0.9)
            p.check(r.status, "fmi3DoStep")
            if r.early_return:
                break
        assert r.early_return
        if kind == "serialized state":
            st, copy = p.deserialize(p.serialize(state))
            p.check(st, "fmi3DeserializeFMUState")
            p.free_state(state)
            state = copy
        p.check(p.set_state(state), "fmi3SetFMUState")
        p.free_state(state)
        p.time = t_event
        return p.get_many(EVENT_OUTPUTS)
    if kind == "input set":  # the event's state is the one the old input reached
        p.check(p.set(tau_external=0.02), "fmi3SetFloat64")
        return p.get_many(EVENT_OUTPUTS)
    if kind == "short step":  # ends before the integrator's own step: starts from the event's state
        r = p.step(1e-4)
        p.check(r.status, "fmi3DoStep")
        assert not r.early_return
        return p.get_many(EVENT_OUTPUTS)
    if kind == "event mode":
        assert p.raw.fmi3EnterEventMode(p.c) == OK
        p.settle()
        return p.get_many(EVENT_OUTPUTS)
    if kind == "terminate":
        assert p.raw.fmi3Terminate(p.c) == OK
        return p.get_many(EVENT_OUTPUTS)
    raise AssertionError(kind)


@pytest.mark.parametrize("kind", ["get", "output derivatives", "state", "serialized state", "input set",
                                  "short step", "event mode", "terminate"])
def test_the_state_at_an_early_return_is_the_same_whatever_looks_at_it_first(kind):
    """After an early return the Pendulum computes its state at the event only
    when something needs it (the importer usually steps on without looking).
    Whatever call comes first (a getter, output derivatives, an FMU state
    saved and restored or serialized, an input set, a step that ends before
    the integrator's own step, Event Mode, fmi3Terminate), it sees the state
    an instance that read its outputs first sees, bit for bit, and both go
    on alike."""
    params = {"phi_start": -0.2, "Q": 50.0}
    opened = dict(params=params, event_mode=True, early_return=True)
    with Instance3(find_fmu3("Pendulum"), name="first", **opened) as p, \
         Instance3(find_fmu3("Pendulum"), name="read", **opened) as ref:
        early = 0
        while early < 5:
            r, r_ref = p.step(0.9), ref.step(0.9)
            p.check(r.status, "fmi3DoStep")
            assert r == r_ref
            if not r.early_return:
                assert p.get_many(EVENT_OUTPUTS) == ref.get_many(EVENT_OUTPUTS)
                continue
            early += 1
            at_event = ref.get_many(EVENT_OUTPUTS)
            assert all(math.isfinite(x) for x in at_event)
            seen = _after_early_return(p, kind)
            assert seen == _after_early_return(ref, kind), (kind, early)
            if kind != "short step":  # the state is the event's still (a, energy follow the input)
                assert seen[-len(at_event):][:2] == at_event[:2]
                assert kind == "input set" or seen[-len(at_event):] == at_event
            if kind == "terminate":
                return
            if kind != "event mode":
                for inst in (p, ref):
                    assert inst.raw.fmi3EnterEventMode(inst.c) == OK
                    inst.settle()
            assert p.get_many(EVENT_OUTPUTS) == ref.get_many(EVENT_OUTPUTS)


def test_early_return_goes_on_with_the_integrators_own_steps():
    """After an early return at a tick or turning point, the next fmi3DoStep
    from the event goes on from the end of the internal step that held it:
    stepping on to each communication point, the FMI 3.0 Pendulum gives the
    FMI 2.0 build's bits at every one, ticks, amplitudes and tick speeds
    included."""
    params = {"phi_start": -0.2, "Q": 50.0}
    names = ["phi", "w", "a", "tick_count", "tick_time", "tick_w", "turn_count", "amplitude", "period"]
    early = 0
    with Instance3(find_fmu3("Pendulum"), params=params, event_mode=True, early_return=True) as p, \
         Instance(fmu_file("Pendulum"), params=params) as ref:
        for k in range(1, 41):
            end = 0.25 * k
            ref.check(ref.step(0.25), "fmi2DoStep")
            while p.time < end:
                h = end - p.time
                while p.time + h < end:
                    h = math.nextafter(h, math.inf)
                while p.time + h > end:
                    h = math.nextafter(h, 0.0)
                r = p.step(h)
                p.check(r.status, "fmi3DoStep")
                if r.early_return:
                    early += 1
                    assert p.raw.fmi3EnterEventMode(p.c) == OK
                    p.settle()
            assert p.get_many(names) == ref.get_many(names), k
    assert early >= 8
