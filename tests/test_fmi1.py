"""FMI 1.0 Co-Simulation FMUs: fmi/cs1.py's Instance1 and the compiled
core's cw1_* adapter, on the FMI 1.0 builds of the project's models
(the runtime's fmi1 face, src_c/runtime/cw_fmi1.c, built by CMake into
build/test-fmus/fmi1/ for the tests only).

The FMI 1.0 build runs the same C code as the FMI 2.0 build, so a system
with FMI 1.0 components gives the FMI 2.0 system's bits, on both engines,
mixed with FMI 2.0 and 3.0 FMUs. Negated aliases, a missing
DirectDependency and a Model Exchange only FMU are made by editing a copy
of a build's modelDescription.xml.
"""

from __future__ import annotations

import math
import re
import shutil
import zipfile
from pathlib import Path

import pytest

from clockwork.engine import MasterSettings, System
from clockwork.fmi.description import FmuError, read_fmu
from clockwork.fmi.variables import direct_feedthrough
from clockwork.fmi.cs1 import PENDING
from clockwork.engine.wiring import Link
from clockwork.errors import SceneError, SimulationError
from cwtest import FMU_DIR, ROOT, TEST_FMU_DIR, assert_one_line_error, run_cli, test_fmu

ENGINES = ("python", "compiled")
FMI1 = TEST_FMU_DIR / "fmi1"


def fmi1(name: str) -> str:
    return str(test_fmu(f"fmi1/{name}"))


def edited(src: str, dst: Path, edit) -> str:
    """A copy of the FMU `src` at `dst` whose modelDescription.xml is edit(text)."""
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dst, "w") as zout:
        for info in zin.infolist():
            data = zin.read(info.filename)
            if info.filename == "modelDescription.xml":
                data = edit(data.decode()).encode()
            zout.writestr(info, data)
    return str(dst)


def add_variables(rows: str):
    return lambda xml: xml.replace("  </ModelVariables>", rows + "\n  </ModelVariables>")


# --- the same bits as the FMI 2.0 build --------------------------------------------

def clock(pendulum: str, escapement: str, drag: str):
    return {"pendulum": (pendulum, dict(Q=1000.0, phi_start=math.radians(6))),
            "escapement": (escapement, dict(torque=4e-3, phi_r=math.radians(2))),
            "drag": (drag, dict(c1=2e-5, c2=2e-4))}


LINKS = ["pendulum.phi -> escapement.phi", "pendulum.w -> escapement.w", "escapement.tau -> pendulum.tau_escapement",
         "pendulum.w -> drag.w", "drag.tau -> pendulum.tau_drag"]


def run_clock(components, engine, **settings):
    with System(components, LINKS, MasterSettings(engine=engine, event_location=False, **settings),
                record={"pendulum": ["phi", "w"]}) as s:
        assert s.master.engine == engine
        series = []
        for k in range(1, 41):
            s.master.run_until(0.05 * k)
            series.append(list(s.master.ports.buffer))
        return series, s.master.stats


@pytest.mark.parametrize("settings", [dict(step=0.01), dict(step=0.01, order="jacobi"),
                                      dict(step=0.02, extrapolation=1), dict(step=0.02, extrapolation=2)])
@pytest.mark.parametrize("engine", ENGINES)
def test_fmi1_builds_give_the_fmi2_bits(engine, settings):
    """The clock with its pendulum and drag as FMI 1.0 FMUs (inputs with
    derivatives, outputs with derivatives, parameters) beside an FMI 2.0
    escapement: every output at every point equals the all-FMI 2.0 clock's."""
    reference = run_clock(clock("Pendulum", "GrasshopperEscapement", "Drag"), "python", **settings)
    got = run_clock(clock(fmi1("Pendulum"), "GrasshopperEscapement", fmi1("Drag")), engine, **settings)
    assert got == reference


@pytest.mark.parametrize("engine", ENGINES)
def test_mixed_with_fmi3(engine):
    """FMI 1.0, 2.0 and 3.0 FMUs in one system (event mode in the FMI 3.0
    escapement): the bits of the all-FMI 2.0 clock."""
    fmi3 = FMU_DIR / "fmi3" / "GrasshopperEscapement.fmu"
    if not fmi3.is_file():
        pytest.fail(f"{fmi3} is missing: build the FMUs first (cmake --build build)")
    reference = run_clock(clock("Pendulum", "GrasshopperEscapement", "Drag"), "python", step=0.01)
    got = run_clock(clock(fmi1("Pendulum"), str(fmi3), "Drag"), engine, step=0.01)
    assert got == reference


def test_restart_gives_the_bits_of_a_new_system():
    """System.restart: fmiResetSlave, the parameters, fmiInitializeSlave again."""
    comps = clock(fmi1("Pendulum"), fmi1("GrasshopperEscapement"), fmi1("Drag"))
    first = run_clock(comps, "compiled", step=0.01)
    with System(comps, LINKS, MasterSettings(engine="compiled", step=0.01, event_location=False)) as s:
        s.master.run_until(0.3)
        s.restart({n: p for n, (_, p) in comps.items()})
        series = []
        for k in range(1, 41):
            s.master.run_until(0.05 * k)
            series.append(list(s.master.ports.buffer))
    assert series == first[0]


# --- every FMI 1.0 type -------------------------------------------------------------

def test_every_type_in_parameters_links_and_recording():
    """Real, Integer, Boolean, Enumeration and String parameters, links
    from and into FMI 1.0 FMUs and recorded outputs (fmiBoolean is a char:
    the adapter converts it both ways)."""
    params = {"p_real": 2.0, "p_int": 3, "p_bool": True, "p_enum": 3, "p_str": "x"}
    comps = {"a": (fmi1("TestTypes"), params), "b": (str(test_fmu("TestTypes")), {}), "c": (fmi1("TestTypes"), {})}
    links = ["a.y_real -> b.u_real", "a.y_int -> b.u_int", "a.y_bool -> b.u_bool", "a.y_enum -> b.u_enum",
             "a.y_str -> b.u_str", "b.y_real -> c.u_real", "b.y_str -> c.u_str", "b.y_bool -> c.u_bool",
             "b.y_int -> c.u_int", "b.y_enum -> c.u_enum"]
    record = {"c": ["y_real", "y_int", "y_bool", "y_enum", "y_str", "y_state"]}
    with System(comps, links, MasterSettings(engine="auto", step=0.1), record=record) as s:
        assert s.master.engine == "python" and "Real connections only" in s.master.engine_reason
        s.master.run_until(1.0)
        a = s.instances["a"].get_values(["y_real", "y_int", "y_bool", "y_enum", "y_str"])
        c = s.instances["c"].get_values(["y_real", "y_int", "y_bool", "y_enum", "y_str", "y_state"])
    assert a == [2.0, 3, True, 3, "x"]
    # b: 1 + 2, 2 + 3, false xor true, max(2, 3), "tick" "x"; c: 1 + 3, 2 + 5, false xor true...
    assert c[:5] == [4.0, 7, True, 3, "ticktickx"] and c[5] == pytest.approx(3.0, rel=1e-12)


def test_input_derivatives_reach_an_fmi1_fmu_as_an_fmi2_one():
    """fmiSetRealInputDerivatives: with extrapolation the FMI 1.0 build sees
    the slope the FMI 2.0 build sees (u_rate), bit for bit."""
    comps = {"pendulum": ("Pendulum", dict(phi_start=0.1)), "one": (fmi1("TestTypes"), {}),
             "two": (str(test_fmu("TestTypes")), {})}
    links = ["pendulum.phi -> one.u_real", "pendulum.phi -> two.u_real"]
    for engine in ENGINES:
        with System(comps, links, MasterSettings(engine=engine, step=0.01, extrapolation=1)) as s:
            rates = []
            for k in range(1, 21):
                s.master.run_until(0.01 * k)
                rates.append([s.instances[n].get_values(["u_rate", "y_state"]) for n in ("one", "two")])
        assert all(one == two for one, two in rates) and any(one[0] != 0.0 for one, _ in rates)


@pytest.mark.parametrize("settings", [dict(), dict(algebraic_loops="delay", order="jacobi")])
@pytest.mark.parametrize("engine", ENGINES)
def test_an_algebraic_loop_of_fmi1_instances(engine, settings):
    """A real algebraic loop (TestSum as adder and gain 3: solved with the
    Newton fallback; or broken by a delay) of FMI 1.0 instances, mixed with
    an FMI 2.0 one: the all-FMI 2.0 loop's bits at every point. Its inputs
    are set and its outputs read after fmiInitializeSlave, where FMI 2.0
    does it in Initialization Mode."""
    def run(add, gain):
        comps = {"add": (add, {"c": 1.0}), "gain": (gain, {"k1": 3.0, "k2": 0.0})}
        with System(comps, ["add.y -> gain.u1", "gain.y -> add.u2"],
                    MasterSettings(engine=engine, step=0.125, **settings), record={"add": ["y"], "gain": ["y"]}) as s:
            seen = []
            for k in range(1, 9):
                s.master.run_until(0.125 * k)
                seen.append((s.output("add", "y"), s.output("gain", "y")))
            return seen, s.master.stats
    fmi2 = str(test_fmu("TestSum"))
    reference, stats = run(fmi2, fmi2)
    for add, gain in ((fmi1("TestSum"), fmi1("TestSum")), (fmi1("TestSum"), fmi2)):
        assert run(add, gain) == (reference, stats)
    if not settings:
        assert stats.loop_fallbacks > 0 and all(abs(a + 0.5) <= 1e-12 for a, _ in reference)


@pytest.mark.parametrize("engine", ENGINES)
def test_outputs_of_new_inputs_take_a_zero_step(engine):
    """FMI 1.0 computes outputs in fmiDoStep. Hold (tests/data/fmi1/hold.c)
    gives y = u as of its last step only; where the master sets u at a
    communication point and then reads y, the instance takes a step of size
    0 there first (FMI 1.0's iteration), so y is the pendulum's angle at the
    same point, not at the point before, on both engines alike."""
    comps = {"pendulum": ("Pendulum", dict(phi_start=0.1)), "hold": (fmi1("Hold"), {})}
    with System(comps, ["pendulum.phi -> hold.u"], MasterSettings(engine=engine, step=0.01),
                record={"pendulum": ["phi"], "hold": ["y"]}) as s:
        seen = []
        for k in range(1, 21):
            s.master.run_until(0.01 * k)
            seen.append((s.output("pendulum", "phi"), s.output("hold", "y")))
        zero_steps = s.instances["hold"].get_values(["zero_steps"])[0]
        counted = s.instances["hold"].adapter.zero_steps
    assert all(phi == y for phi, y in seen) and len({phi for phi, _ in seen}) == 20
    assert zero_steps == counted >= 20  # one per point at least, counted alike by the FMU and the adapter


# --- aliases and DirectDependency ---------------------------------------------------

NEGATED = """
    <ScalarVariable name="minus_y_real" valueReference="20" variability="continuous" causality="output"
        alias="negatedAlias"><Real/><DirectDependency><Name>u_real</Name></DirectDependency></ScalarVariable>
    <ScalarVariable name="same_y_real" valueReference="20" variability="continuous" causality="output"
        alias="alias"><Real/><DirectDependency><Name>u_real</Name></DirectDependency></ScalarVariable>
    <ScalarVariable name="minus_u_real" valueReference="10" variability="continuous" causality="input"
        alias="negatedAlias"><Real start="0"/></ScalarVariable>
    <ScalarVariable name="minus_p_real" valueReference="0" variability="parameter" causality="internal"
        alias="negatedAlias"><Real start="-1" fixed="true"/></ScalarVariable>
    <ScalarVariable name="minus_y_int" valueReference="21" variability="discrete" causality="output"
        alias="negatedAlias"><Integer/><DirectDependency><Name>u_int</Name></DirectDependency></ScalarVariable>
    <ScalarVariable name="not_y_bool" valueReference="22" variability="discrete" causality="output"
        alias="negatedAlias"><Boolean/><DirectDependency><Name>u_bool</Name></DirectDependency></ScalarVariable>"""


@pytest.fixture(scope="module")
def negated(tmp_path_factory):
    return edited(fmi1("TestTypes"), tmp_path_factory.mktemp("fmi1") / "Negated.fmu", add_variables(NEGATED))


@pytest.mark.parametrize("engine", ENGINES)
def test_negated_aliases_both_ways(negated, engine):
    """A negatedAlias shares its value reference with the variable it
    negates: parameters set through it, outputs read through it and inputs
    fed through it are negated, with their input derivatives; an alias is
    the same value."""
    comps = {"a": (negated, {"minus_p_real": -2.0}), "b": (negated, {}), "c": (str(test_fmu("TestTypes")), {})}
    links = ["a.minus_y_real -> b.minus_u_real", "b.minus_y_real -> c.u_real"]
    record = {"a": ["minus_y_real", "same_y_real", "y_real"], "b": ["y_real", "minus_y_real"], "c": ["y_real"]}
    with System(comps, links, MasterSettings(engine=engine, step=0.1), record=record) as s:
        s.master.run_until(0.5)
        out = {f"{i}.{n}": s.output(i, n) for i, names in record.items() for n in names}
    assert out == {"a.minus_y_real": -2.0, "a.same_y_real": 2.0, "a.y_real": 2.0,
                   "b.y_real": 3.0, "b.minus_y_real": -3.0, "c.y_real": -2.0}


def test_negated_integer_and_boolean(negated):
    with System({"a": (negated, {"p_int": 5, "p_bool": True})}, [], MasterSettings(engine="python", step=0.1),
                record={"a": ["minus_y_int", "not_y_bool", "y_bool"]}) as s:
        s.master.run_until(0.2)
        assert s.instances["a"].get_values(["minus_y_int", "y_int", "not_y_bool", "y_bool"]) == [-5, 5, False, True]


@pytest.mark.parametrize("engine", ENGINES)
def test_negated_input_derivatives_and_output_derivatives(tmp_path, negated, engine):
    """Through a negated alias the master's polynomials are negated too: an
    input fed through minus_u_real sees the slope that a link with factor
    -1 gives (u_rate), and the pendulum's output derivatives of a negated
    alias of phi (extrapolation = 2) are those of -phi: the same bits."""
    phi = next(v for v in read_fmu(fmi1("Pendulum"))[0].modelVariables if v.name == "phi")
    pendulum = edited(fmi1("Pendulum"), tmp_path / "P.fmu", add_variables(
        f'<ScalarVariable name="minus_phi" valueReference="{phi.valueReference}" variability="continuous" '
        'causality="output" alias="negatedAlias"><Real/><DirectDependency/></ScalarVariable>'))
    comps = {"pendulum": (pendulum, dict(phi_start=0.1)), "one": (negated, {}), "two": (negated, {})}
    links = [Link("pendulum", "minus_phi", "one", "u_real"), Link("pendulum", "phi", "two", "u_real", factor=-1.0)]
    links2 = [Link("pendulum", "phi", "one", "minus_u_real"), Link("pendulum", "phi", "two", "u_real", factor=-1.0)]
    for wiring in (links, links2):
        with System(comps, wiring, MasterSettings(engine=engine, step=0.01, extrapolation=2)) as s:
            seen = []
            for k in range(1, 21):
                s.master.run_until(0.01 * k)
                seen.append([s.instances[n].get_values(["u_rate", "y_state", "y_real"]) for n in ("one", "two")])
        assert all(one == two for one, two in seen), seen[:3]
        assert any(one[0] != 0.0 for one, _ in seen)


def test_direct_dependency_absent_means_every_input(tmp_path):
    """An output without DirectDependency depends on every input (FMI 1.0);
    an empty one on none; a name that is no variable is refused in one line."""
    md = read_fmu(fmi1("TestTypes"))[0]
    deps = direct_feedthrough(md)
    assert deps["y_state"] == [] and deps["y_real"] == ["u_real"]
    bare = edited(fmi1("TestTypes"), tmp_path / "Bare.fmu",
                  lambda x: re.sub(r"\s*<DirectDependency(/>|>.*?</DirectDependency>)", "", x, flags=re.S))
    inputs = [v.name for v in read_fmu(bare)[0].modelVariables if v.causality == "input"]
    assert all(d == inputs for d in direct_feedthrough(read_fmu(bare)[0]).values())
    typo = edited(fmi1("TestTypes"), tmp_path / "Typo.fmu", lambda x: x.replace("<Name>u_real</Name>",
                                                                                 "<Name>u_reel</Name>", 1))
    with pytest.raises(FmuError, match="DirectDependency of output y_real names 'u_reel'"):
        read_fmu(typo)


# --- what FMI 1.0 cannot do, refused at load --------------------------------------

ROLLBACK = [(dict(), "master.event_location", "locating events"),
            (dict(event_location=False, iterations=2), "master.iterations", "iterating the coupling"),
            (dict(event_location=False, richardson=True), "master.richardson", "step doubling")]


@pytest.mark.parametrize("settings,key,why", ROLLBACK)
def test_rollback_settings_are_refused_before_the_first_step(settings, key, why):
    comps = clock(fmi1("Pendulum"), fmi1("GrasshopperEscapement"), "Drag")
    with pytest.raises(SceneError) as e:
        System(comps, LINKS, MasterSettings(step=0.01, **settings))
    text = str(e.value)
    assert text.startswith(key) and "pendulum (Pendulum.fmu)" in text and "FMI 1.0 FMU, which has no FMU state" in text
    assert why in text and "\n" not in text


SCENE = """
connections = [
  "pendulum.phi -> escapement.phi",
  "pendulum.w -> escapement.w",
  "escapement.tau -> pendulum.tau_escapement",
]
[scene]
title = "FMI 1.0 clock"
[components.pendulum]
fmu = "{pendulum}"
parameters = {{ Q = 1000, phi_start = "6 deg" }}
[components.escapement]
fmu = "{escapement}"
parameters = {{ torque = "0.4 N.cm", phi_r = "2 deg" }}
[experiment]
stop = "2 s"
[master]
step = "0.01 s"
{master}
[record]
outputs = ["pendulum.phi"]
[analysis]
kind = "time_series"
"""


def test_a_scene_asks_for_event_location_one_line(tmp_path, capsys):
    toml = tmp_path / "clock.toml"
    toml.write_text(SCENE.format(pendulum=fmi1("Pendulum"), escapement=fmi1("GrasshopperEscapement"), master=""))
    rc, _, err = run_cli(capsys, ["validate", toml])
    assert_one_line_error(rc, err, "master.event_location", "components.pendulum (Pendulum.fmu)",
                          "FMI 1.0 FMU, which has no FMU state")
    rc, _, err = run_cli(capsys, ["run", toml, "--out", tmp_path / "out"])
    assert_one_line_error(rc, err, "master.event_location")
    assert not (tmp_path / "out").exists()


def test_a_scene_runs_the_same_bits_as_its_fmi2_twin(tmp_path, capsys):
    """validate and run on a scene of FMI 1.0 and 2.0 FMUs: the CSV of the
    all-FMI 2.0 scene, byte for byte."""
    csv = {}
    for name, pendulum in (("fmi1", fmi1("Pendulum")), ("fmi2", "Pendulum")):
        toml = tmp_path / f"{name}.toml"
        toml.write_text(SCENE.format(pendulum=pendulum, escapement="GrasshopperEscapement",
                                     master="event_location = false"))
        rc, out, err = run_cli(capsys, ["validate", toml])
        assert rc == 0 and out.startswith("ok: FMI 1.0 clock"), err
        rc, _, err = run_cli(capsys, ["run", toml, "--out", tmp_path / name])
        assert rc == 0, err
        csv[name] = (tmp_path / name / "timeseries.csv").read_bytes()
    assert csv["fmi1"] == csv["fmi2"] and len(csv["fmi1"]) > 1000


# --- statuses ----------------------------------------------------------------------------

def test_a_discarded_step_fails_the_run_naming_fmiDoStep():
    """FMI 1.0 has no fmiTerminated status: TestStair's discarded step at
    end_time is a failed run, named by its FMI 1.0 function."""
    with System({"stair": (fmi1("TestStair"), {"end_time": 0.35})}, [], MasterSettings(step=0.1)) as s:
        with pytest.raises(SimulationError) as e:
            s.master.run_until(1.0)
        assert s.master.ended is None
    assert re.search(r"stair: fmiDoStep from t = 0\.3\d* s with h = 0\.\d+ s was discarded: .*the stair ends at "
                     r"t = 0\.35 s", str(e.value)), str(e.value)


def test_pending_is_refused_in_one_line_and_the_step_cancelled():
    """An FMU that answers fmiPending (it was given no stepFinished
    callback, so it must not): the run fails in one line, and the instance
    cancels the step (fmiCancelStep) instead of terminating it when freed."""
    s = System({"d": (fmi1("TestDecay"), {})}, [], MasterSettings(engine="python", step=0.1))
    inst = s.instances["d"]
    calls = []
    cancel, terminate = inst._f_cancel, inst._f_terminate
    inst._f_cancel = lambda comp: calls.append("cancel") or cancel(comp)
    inst._f_terminate = lambda comp: calls.append("terminate") or terminate(comp)
    s.master.ports["d"].doStep = lambda comp, t, h, flag: PENDING
    with pytest.raises(SimulationError) as e:
        s.master.run_until(0.5)
    assert "fmiDoStep(0.0, 0.1) returned Pending: an asynchronous step" in str(e.value) and "\n" not in str(e.value)
    s.free()
    assert calls == ["cancel"]


def test_a_finished_run_terminates_the_slave():
    s = System({"d": (fmi1("TestDecay"), {})}, [], MasterSettings(step=0.1))
    inst = s.instances["d"]
    calls = []
    terminate = inst._f_terminate
    inst._f_terminate = lambda comp: calls.append("terminate") or terminate(comp)
    s.master.run_until(0.3)
    s.free()
    assert calls == ["terminate"]


# --- files ----------------------------------------------------------------------------------

def test_fmpy_validates_every_fmi1_build():
    """fmpy's validation (the FMI 1.0 schema) finds nothing to report in
    the FMI 1.0 builds of every model (fmugen's generate_xml1)."""
    from fmpy.validation import validate_fmu

    builds = sorted(FMI1.glob("*.fmu"))
    models = {p.parent.name for p in (ROOT / "src_c" / "models").glob("*/model.toml")}
    assert {p.stem for p in builds} >= models | {"TestTypes", "TestDecay", "TestStair", "TestForget"}
    for fmu in builds:
        assert validate_fmu(str(fmu)) == [], fmu


def test_info_on_an_fmi1_fmu(capsys):
    rc, out, err = run_cli(capsys, ["info", fmi1("TestTypes")])
    assert rc == 0, err
    assert out.startswith("TestTypes (FMI 1.0 Co-Simulation)")
    assert "canInterpolateInputs                     true" in out and "canRunAsynchronuously" in out


def test_a_description_without_implementation_is_model_exchange(tmp_path, capsys):
    """FMI 1.0 Model Exchange runs (tests/test_fmi1_me.py): a Co-Simulation
    FMU's description without <Implementation> reads as Model Exchange, and
    its binary, which has no fmiInstantiateModel, is refused in one line."""
    me = edited(fmi1("TestTypes"), tmp_path / "ME.fmu",
                lambda x: re.sub(r"\s*<Implementation>.*</Implementation>", "", x, flags=re.S))
    rc, out, err = run_cli(capsys, ["info", me])
    assert rc == 0 and "(FMI 1.0 Model Exchange)" in out, err
    rc, _, err = run_cli(capsys, ["run", me, "--out", tmp_path / "out", "--no-progress"])
    assert_one_line_error(rc, err, "ME.fmu", "cannot load the FMU's binary")


def test_a_guid_the_binary_refuses_is_one_line(tmp_path, capsys):
    """fmiInstantiateSlave returns no instance: bad input, with the FMU's
    own message; nothing is left to free."""
    other = edited(fmi1("TestDecay"), tmp_path / "Other.fmu", lambda x: re.sub(r'guid="[^"]*"', 'guid="{x}"', x))
    toml = tmp_path / "other.toml"
    toml.write_text(f'[scene]\ntitle = "g"\n[components.d]\nfmu = "{other}"\n[experiment]\nstop = 0.1\n'
                    '[master]\nstep = 0.1\n[record]\noutputs = ["d.x"]\n')
    rc, _, err = run_cli(capsys, ["run", toml, "--out", tmp_path / "out"])
    assert_one_line_error(rc, err, "Other.fmu: fmiInstantiateSlave made no instance (GUID {x})",
                          "GUID '{x}' does not match")


def test_a_bad_capability_is_refused_in_one_line(tmp_path, capsys):
    bad = edited(fmi1("TestTypes"), tmp_path / "Bad.fmu",
                 lambda x: x.replace('maxOutputDerivativeOrder="0"', 'maxOutputDerivativeOrder="two"'))
    rc, _, err = run_cli(capsys, ["info", bad])
    assert_one_line_error(rc, err, "Bad.fmu", "maxOutputDerivativeOrder='two'")


TYPES_SCENE = """
connections = ["a.y_real -> b.u_real", "a.y_int -> b.u_int", "a.y_enum -> b.u_enum", "a.y_str -> b.u_str",
               "a.y_bool -> b.u_bool"]
[scene]
title = "types"
[components.a]
fmu = "{a}"
parameters = {{ p_real = 1.25, p_enum = "high", p_str = "tick", p_bool = true, p_int = 7 }}
[components.b]
fmu = "{b}"
[experiment]
stop = 0.5
[master]
step = 0.1
[record]
outputs = ["a.y_str", "a.y_bool", "a.y_enum", "b.y_real", "b.y_int", "b.y_enum", "b.y_str", "b.y_bool"]
"""


def test_every_type_in_a_scene_and_its_exported_ssp(tmp_path, capsys):
    """A scene with an FMI 1.0 component: parameters of every type (an
    Enumeration by its item's name), links and recorded outputs of every
    type, String included; the FMI 2.0 twin's CSV byte for byte, and the
    same again from the SSP that export-ssp writes of it."""
    csv = {}
    for name, a in (("fmi1", fmi1("TestTypes")), ("fmi2", str(test_fmu("TestTypes")))):
        toml = tmp_path / f"{name}.toml"
        toml.write_text(TYPES_SCENE.format(a=a, b=test_fmu("TestTypes")))
        rc, _, err = run_cli(capsys, ["run", toml, "--out", tmp_path / name])
        assert rc == 0, err
        csv[name] = (tmp_path / name / "timeseries.csv").read_text()
    assert csv["fmi1"] == csv["fmi2"]
    assert csv["fmi1"].splitlines()[-1] == "0.5,tick,1.0,3.0,2.25,9.0,3.0,ticktick,1.0"
    ssp = tmp_path / "types.ssp"
    rc, _, err = run_cli(capsys, ["export-ssp", tmp_path / "fmi1.toml", "--out", ssp])
    assert rc == 0, err
    rc, _, err = run_cli(capsys, ["run", ssp, "--out", tmp_path / "ssp"])
    assert rc == 0, err
    assert (tmp_path / "ssp" / "timeseries.csv").read_text() == csv["fmi1"]


def _types_fixture(tmp_path: Path, a_fmu: str) -> Path:
    """tests/data/ssp/types without its unit conversions (FMI 1.0 units are
    names only), component a from `a_fmu`."""
    d = tmp_path / "types"
    shutil.copytree(ROOT / "tests" / "data" / "ssp" / "types", d)
    shutil.copy(test_fmu("TestTypes"), d / "resources" / "TestTypes.fmu")
    shutil.copy(a_fmu, d / "resources" / "A.fmu")
    ssd = d / "SystemStructure.ssd"
    text = ssd.read_text().replace('<ssd:Component name="a" source="resources/TestTypes.fmu">',
                                   '<ssd:Component name="a" source="resources/A.fmu">')
    text = text.replace('<ssd:Connection startElement="a" startConnector="y_real" endElement="b" '
                        'endConnector="u_mm"/>', "")
    ssd.write_text(text)
    ssv = d / "resources" / "a.ssv"
    ssv.write_text(ssv.read_text().replace('value="1500" unit="mm"', 'value="1.5"'))
    return ssd


def test_an_ssp_with_an_fmi1_component_gives_the_fmi2_bits(tmp_path, capsys):
    record = 'record.outputs=["a.y_real", "b.y_real", "b.y_int", "b.y_bool", "b.y_enum"]'
    csv = {}
    for name, fmu in (("fmi1", fmi1("TestTypes")), ("fmi2", str(test_fmu("TestTypes")))):
        ssd = _types_fixture(tmp_path / name, fmu)
        rc, out, err = run_cli(capsys, ["validate", ssd])
        assert rc == 0, err
        rc, _, err = run_cli(capsys, ["run", ssd, "--out", tmp_path / name / "out", "--set", record])
        assert rc == 0, err
        csv[name] = (tmp_path / name / "out" / "timeseries.csv").read_text()
    assert csv["fmi1"] == csv["fmi2"]
    assert csv["fmi1"].splitlines()[-1] == "0.1,1.5,3.75,2.0,1.0,3.0"


def test_an_fmi1_unit_converts_to_itself_only(tmp_path, capsys):
    """FMI 1.0 names its units without SI exponents: 1500 mm into a
    variable in m is refused in one line, never passed on as 1500 m."""
    ssd = _types_fixture(tmp_path, fmi1("TestTypes"))
    ssv = ssd.parent / "resources" / "a.ssv"
    ssv.write_text(ssv.read_text().replace('value="1.5"', 'value="1500" unit="mm"'))
    rc, _, err = run_cli(capsys, ["validate", ssd])
    assert_one_line_error(rc, err, "a.ssv", "the unit")


@pytest.mark.parametrize("name", ["GrasshopperEscapement", "ChronometerEscapement"])
def test_an_fmi1_escapement_alone_runs_as_fmpy_runs_it(name):
    """An FMU alone takes the master's defaults, and locating its events
    would roll it back, which an FMI 1.0 FMU cannot: the default was refused
    ("master.event_location: expected false") although the user asked for
    nothing and fmpy runs it. Alone it now runs on the grid with fmpy's
    numbers, on both engines; asking for event location is still refused."""
    import numpy as np
    from fmpy import simulate_fmu

    import clockwork

    path = fmi1(name)
    ref = simulate_fmu(path, output_interval=0.04)
    for engine in ("python", "compiled"):
        res = clockwork.simulate(path, step_size=0.04, master={"engine": engine})
        common = [n for n in ref.dtype.names if n in res.dtype.names and n != "time"]
        assert common
        t = np.intersect1d(res["time"], ref["time"])
        assert len(t) > 100
        for n in common:
            assert np.array_equal(res[n][np.isin(res["time"], t)], ref[n][np.isin(ref["time"], t)]), (engine, n)
    with pytest.raises(SceneError, match="event_location.*FMI 1.0 FMU, which has no FMU state"):
        clockwork.simulate(path, master={"event_location": True})
