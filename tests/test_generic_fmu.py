"""Generic FMI 2.0 Co-Simulation correctness (issue 20): what any FMU and
any system file may hold, on both engines.

Link transformations and unit conversion, the names SSP and FMI allow,
direct feedthrough from dependencies on inputs only, every variable type,
an FMU that ends the simulation, the DefaultExperiment tolerance, FMU log
messages, and the extrapolation order an FMU accepts.
"""

from __future__ import annotations

import json

import pytest

from clockwork.engine import MasterSettings, System
from clockwork.fmi.variables import direct_feedthrough
from clockwork.engine.names import instance_name_problem, split_ref
from clockwork.engine.wiring import Link, parse_link
from clockwork.errors import SceneError, SimulationError
from clockwork.run.catalog import load_scene as load_with_kinds
from clockwork.scene import load_scene
from clockwork.scene.units import link_conversion
from cwtest import assert_one_line_error, run_cli, test_fmu

ENGINES = ("python", "compiled")


# -- link transformations ------------------------------------------------------

@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("factor, offset", [(2.0, 0.0), (1.0, 0.25), (-0.5, 1e-3)])
def test_an_input_receives_factor_times_output_plus_offset(engine, factor, offset):
    links = [Link("pendulum", "w", "drag", "w", factor, offset), Link("drag", "tau", "pendulum", "tau_drag")]
    comps = {"pendulum": ("Pendulum", dict(Q=1000.0, phi_start=0.1)), "drag": ("Drag", dict(c1=1e-4))}
    with System(comps, links, MasterSettings(step=0.01, engine=engine)) as s:
        for t in (0.0, 0.37, 1.0):
            s.master.run_until(t) if t else None
            w = s.value("pendulum", "w")
            assert s.value("drag", "w") == factor * w + offset
            assert s.output("drag", "tau") == -1e-4 * (factor * w + offset)


@pytest.mark.parametrize("settings", [dict(step=0.01), dict(step=0.02, extrapolation=2),
                                      dict(step=0.02, extrapolation=1, order="jacobi")])
def test_transformed_links_give_the_same_bits_on_both_engines(settings):
    comps = {"pendulum": ("Pendulum", dict(Q=1000.0, phi_start=0.1)),
             "escapement": ("GrasshopperEscapement", dict(torque=4e-3, phi_r=0.035)),
             "drag": ("Drag", dict(c1=2e-5))}
    links = [Link("pendulum", "phi", "escapement", "phi", 1.0, 1e-4), Link("pendulum", "w", "escapement", "w"),
             Link("escapement", "tau", "pendulum", "tau_escapement", 0.9),
             Link("pendulum", "w", "drag", "w", 3.0, -0.01), Link("drag", "tau", "pendulum", "tau_drag")]
    runs = []
    for engine in ENGINES:
        with System(comps, links, MasterSettings(engine=engine, **settings)) as s:
            s.master.run_until(3.0)
            runs.append((s.master.t, list(s.master.ports.buffer), s.master.stats))
    assert runs[0] == runs[1]


class _Unit:
    def __init__(self, name, factor=1.0, offset=0.0, **exponents):
        self.name = name
        self.baseUnit = type("Base", (), dict(factor=factor, offset=offset, **exponents))()
        self.displayUnits = []


class _Md:
    def __init__(self, *units):
        self.unitDefinitions = list(units)


def test_unit_conversion_comes_from_each_fmus_base_units():
    # Spellings meet by their SI base: Nm/A in one FMU, N.m/A in the other.
    a, b = _Md(_Unit("Nm/A", kg=1, m=2, s=-2, A=-1)), _Md(_Unit("N.m/A", kg=1, m=2, s=-2, A=-1))
    assert link_conversion(a, "Nm/A", b, "N.m/A") == (1.0, 0.0)
    # Scaled and shifted units: degC -> K -> degF.
    c = _Md(_Unit("degC", 1.0, 273.15, K=1))
    f = _Md(_Unit("degF", 5.0 / 9.0, 273.15 - 32.0 * 5.0 / 9.0, K=1))
    factor, offset = link_conversion(c, "degC", f, "degF")
    assert factor * 100.0 + offset == pytest.approx(212.0, abs=1e-12)
    assert factor * -40.0 + offset == pytest.approx(-40.0, abs=1e-12)
    # Different dimensions, or a unit an FMU does not define: no conversion.
    assert link_conversion(c, "degC", a, "Nm/A") is None
    assert link_conversion(c, "degC", _Md(), "K") is None


# -- names ---------------------------------------------------------------------

@pytest.mark.parametrize("name", ["0001_em", "edrive-mass", "sub.comp", "a b", "Ä"])
def test_ssp_and_fmi_instance_names_are_allowed(name):
    assert instance_name_problem(name) is None


@pytest.mark.parametrize("name", ["", " p", "p.", "a/b", "a\\b", "a->b", "a\nb"])
def test_names_that_cannot_be_an_instance_are_refused(name):
    assert instance_name_problem(name)


def test_references_split_at_the_longest_instance_name_that_fits():
    known = {"sub": {"comp.x"}, "sub.comp": {"der(x)", "MLoad.k", "a[1]"}}
    assert split_ref("sub.comp.der(x)", known) == ("sub.comp", "der(x)")
    assert split_ref("sub.comp.MLoad.k", known) == ("sub.comp", "MLoad.k")
    assert split_ref("sub.comp.a[1]", known) == ("sub.comp", "a[1]")
    assert split_ref("sub.comp.x", known) == ("sub", "comp.x")  # the longer name has no such variable
    assert split_ref("other.x", known) is None
    assert parse_link("sub.comp.der(x) -> sub.comp.x", known) == Link("sub.comp", "der(x)", "sub", "comp.x")


SCENE = """
connections = ["{a}.w -> {b}.w", "{b}.tau -> {a}.tau_drag"]
[scene]
title = "names"
[components."{a}"]
fmu = "Pendulum"
parameters = {{ Q = 500 }}
[components."{b}"]
fmu = "Drag"
[experiment]
stop = 0.1
[record]
outputs = ["{a}.phi", "{b}.tau"]
[[plot]]
kind = "time_series"
x = "time"
y = "{a}.phi"
"""


@pytest.mark.parametrize("a, b", [("0001_em", "edrive-mass"), ("sub.comp", "sub"), ("x.y.z", "x.y")])
def test_a_scene_with_such_names_loads_sets_and_runs(capsys, tmp_path, a, b):
    f = tmp_path / "names.toml"
    f.write_text(SCENE.format(a=a, b=b))
    scene = load_with_kinds(f, [f"{a}.Q=700", f"{b}.c1=1e-3"])
    assert scene.components[a].parameters["Q"] == 700.0
    assert scene.components[b].parameters["c1"] == 1e-3
    assert [tuple(c[:4]) for c in scene.connections] == [(a, "w", b, "w"), (b, "tau", a, "tau_drag")]
    assert scene.record.outputs == ((a, "phi"), (b, "tau"))
    code, out, err = run_cli(capsys, ["run", f, "--out", tmp_path / "out", "--no-progress"])
    assert code == 0, err
    header = (tmp_path / "out" / "timeseries.csv").read_text().splitlines()[0]
    assert header.split(",") == ["time", f"{a}.phi", f"{b}.tau"]
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert "plot1_time_series.png" in summary["files"] and not summary.get("plots_failed")
    # The plot reads the variable's unit through the same split: rad shown in degrees.
    from clockwork.results.plots.registry import display
    assert display(scene, f"{a}.phi", [0.0])[1] == f"{a}.phi (deg)"


# -- the test FMUs (tests/models, built into build/test-fmus) -----------------

def _types(**params):
    return (str(test_fmu("TestTypes")), params)


def _scene(tmp_path, text: str, name: str = "s.toml"):
    f = tmp_path / name
    f.write_text(text.replace("{types}", str(test_fmu("TestTypes"))).replace("{stair}", str(test_fmu("TestStair")))
                 .replace("{decay}", str(test_fmu("TestDecay"))))
    return f


def _run(capsys, tmp_path, scene, *extra, engine="auto"):
    out = tmp_path / f"out_{engine}"
    rc, stdout, err = run_cli(capsys, ["run", scene, "--out", out, "--no-progress",
                                       "--set", f"master.engine={engine}", *extra])
    return rc, out, err


def _csv(out):
    lines = (out / "timeseries.csv").read_text().splitlines()
    header = lines[0].split(",")
    return {h: [row.split(",")[k] for row in lines[1:]] for k, h in enumerate(header)}


# 1. Direct feedthrough only through dependencies on inputs.

def test_feedthrough_counts_dependencies_on_inputs_only():
    import fmpy

    md = fmpy.read_model_description(str(test_fmu("TestTypes")))
    deps = direct_feedthrough(md)
    inputs = {v.name for v in md.modelVariables if v.causality == "input"}
    assert all(set(d) <= inputs for d in deps.values())
    raw = {u.variable.name: [d.name for d in u.dependencies] for u in md.outputs}
    assert raw["y_state"] == ["x"] and deps["y_state"] == []  # a state: not feedthrough
    assert deps["y_real"] == ["u_real"]
    # A missing dependencies attribute means every input.
    for u in md.outputs:
        u.dependencies = None
    assert all(sorted(d) == sorted(inputs) for d in direct_feedthrough(md).values())


@pytest.mark.parametrize("engine", ENGINES)
def test_outputs_on_states_close_no_algebraic_loop(engine):
    # As emachine and edrive in OMSimulator's dcmotor: a feedthrough output
    # one way, an output of a state the other way.
    links = ["a.y_real -> b.u_real", "b.y_state -> a.u_real"]
    runs = []
    for e in ENGINES:
        with System({"a": _types(p_real=1.0), "b": _types(p_real=2.0)}, links,
                    MasterSettings(step=0.1, engine=e)) as s:
            s.master.run_until(1.0)
            runs.append((s.value("a", "x"), s.value("b", "x"), s.master.stats))
    assert runs[0] == runs[1]
    assert runs[0][1] > 1.0  # b integrates 1 + its own state
    # Through feedthrough outputs it is an algebraic loop (tests/test_loops.py),
    # here one without a solution (y = p + u both ways, p = 1): the run fails.
    with pytest.raises(SimulationError, match=r"t = 0\.0 s: algebraic loop a -> b -> a did not converge"):
        System({"a": _types(), "b": _types()}, ["a.y_real -> b.u_real", "b.y_real -> a.u_real"],
               MasterSettings(step=0.1, engine=engine))


# 2. Every variable type: parameters, recording, connections, checks at validation.

TYPES_SCENE = """
connections = ["a.y_int -> b.u_int", "a.y_bool -> b.u_bool", "a.y_enum -> b.u_enum", "a.y_real -> b.u_real", "a.y_str -> b.u_str"]
[scene]
title = "types"
[components.a]
fmu = "{types}"
parameters = { p_int = 5, p_bool = true, p_enum = "high", p_real = 0.5, p_str = "tick é" }
[components.b]
fmu = "{types}"
parameters = { p_int = -1, p_enum = 1, p_str = "tock " }
[experiment]
stop = 0.3
[master]
step = 0.1
"""


@pytest.mark.parametrize("engine", ["auto", "python"])
def test_every_type_is_set_recorded_and_connected(capsys, tmp_path, engine):
    rc, out, err = _run(capsys, tmp_path, _scene(tmp_path, TYPES_SCENE), engine=engine)
    assert rc == 0, err
    cols = _csv(out)
    # Recorded through the right fmi2Get* (Enumeration through fmi2GetInteger).
    assert set(cols["a.y_enum"]) == {"3.0"} and set(cols["b.y_enum"]) == {"3.0"}
    assert set(cols["a.y_int"]) == {"5.0"} and set(cols["b.y_int"]) == {"4.0"}
    assert set(cols["a.y_bool"]) == {"1.0"} and set(cols["b.y_bool"]) == {"1.0"}
    assert set(cols["b.y_real"]) == {"1.5"}  # gain.k p_real + u_real = 1 + 0.5
    # Strings set, passed on and recorded as text: y_str = p_str u_str.
    assert set(cols["a.y_str"]) == {"tick é"} and set(cols["b.y_str"]) == {"tock tick é"}
    summary = json.loads((out / "summary.json").read_text())
    assert summary["result"]["engine"] == "python"
    if engine == "auto":  # the core passes Real values only: Python, and why
        assert "Real connections only" in summary["result"]["engine_reason"]


def test_compiled_asked_for_discrete_links_is_refused_at_validation(capsys, tmp_path):
    f = _scene(tmp_path, TYPES_SCENE)
    rc, _, err = run_cli(capsys, ["validate", f, "--set", "master.engine=compiled"])
    assert_one_line_error(rc, err, str(f), "master.engine", "Real connections only")


@pytest.mark.parametrize("link, detail", [
    ("a.y_int -> b.u_bool", "type mismatch: a.y_int is Integer, b.u_bool is Boolean"),
    ("a.y_str -> b.u_int", "type mismatch: a.y_str is String, b.u_int is Integer"),
    ("a.y_bool -> b.u_enum", "type mismatch: a.y_bool is Boolean, b.u_enum is Enumeration"),
    ("a.y_real -> b.u_enum", "type mismatch: a.y_real is Real, b.u_enum is Enumeration"),
])
def test_a_connection_of_two_types_is_refused_at_validation(capsys, tmp_path, link, detail):
    f = _scene(tmp_path, TYPES_SCENE.replace(TYPES_SCENE.splitlines()[1], f'connections = ["{link}"]'))
    rc, _, err = run_cli(capsys, ["validate", f])
    assert_one_line_error(rc, err, str(f), "connections[0]", detail)


@pytest.mark.parametrize("axis", ["y", "x"])
def test_a_plot_of_a_string_column_is_refused_at_validation(capsys, tmp_path, axis):
    plot = {"y": '["a.y_real", "b.y_str"]', "x": '"b.y_str"'}[axis]
    other = {"y": 'x = "time"', "x": 'y = ["a.y_real"]'}[axis]
    f = _scene(tmp_path, TYPES_SCENE + '[record]\noutputs = ["a.y_real", "b.y_str"]\n'
               f'[[plot]]\nkind = "time_series"\n{axis} = {plot}\n{other}\n')
    for cmd in (["validate", f], ["run", f, "--out", tmp_path / "out", "--no-progress"]):
        rc, _, err = run_cli(capsys, cmd)
        assert_one_line_error(rc, err, str(f), f"plot[0].{axis}", "b.y_str is a String")
    assert not (tmp_path / "out").exists()


ENUM_INT_SCENE = TYPES_SCENE.replace(TYPES_SCENE.splitlines()[1],
                                    'connections = ["a.y_int -> b.u_enum", "a.y_enum -> b.u_int"]')


@pytest.mark.parametrize("engine", ["auto", "python"])
def test_integers_and_enumerations_connect_both_ways(capsys, tmp_path, engine):
    # An Enumeration's value is an integer; SSP leaves mixed types to the tool.
    f = _scene(tmp_path, ENUM_INT_SCENE.replace("p_int = 5", "p_int = 2"))
    rc, out, err = _run(capsys, tmp_path, f, engine=engine)
    assert rc == 0, err
    cols = _csv(out)
    assert set(cols["b.y_enum"]) == {"2.0"}  # max(b.p_enum = 1, a.y_int = 2 + 0)
    assert set(cols["b.y_int"]) == {"2.0"}  # b.p_int + a.y_enum = -1 + 3
    # An integer that is no item of the Enumeration: the FMU refuses it, a failed run.
    rc, out, err = _run(capsys, tmp_path, _scene(tmp_path, ENUM_INT_SCENE), engine=engine)
    assert rc == 1 and "u_enum = 5" in err and "[1, 3]" in err, err


@pytest.mark.parametrize("setting, expected", [
    ("a.p_int=1.5", "an integer"), ("a.p_bool=1", "true or false"), ("a.p_enum=\"max\"", "off, low, high"),
    ("a.p_enum=7", "1 (off), 2 (low), 3 (high)"), ("a.p_enum=0", "an item of Mode"), ("a.p_real=true", "a number"),
])
def test_a_parameter_of_the_wrong_type_is_refused_at_validation(capsys, tmp_path, setting, expected):
    f = _scene(tmp_path, TYPES_SCENE)
    rc, _, err = run_cli(capsys, ["validate", f, "--set", setting])
    assert_one_line_error(rc, err, str(f), setting.split("=")[0], expected)


class _TextInstance:
    """An instance whose variables are of every type (as Reference-FMUs' Feedthrough)."""

    def __init__(self):
        from clockwork.fmi.variables import Variable

        self.variables = {n: Variable(n, k, t, "output", "discrete", None, [])
                          for k, (n, t) in enumerate([("s", "String"), ("e", "Enumeration"), ("b", "Boolean")])}
        self.calls = []

    def get_values(self, names):
        self.calls.append(names)
        return [{"s": 'say "hi", then', "e": 3, "b": True}[n] for n in names]


def test_strings_are_recorded_as_text_and_enumerations_as_numbers():
    from clockwork.fmi.contract import Instance
    from clockwork.engine.recording import _DiscreteOutput

    inst = _TextInstance()
    assert [_DiscreteOutput(inst, n)[0] for n in ("s", "e", "b")] == ['say "hi", then', 3.0, 1.0]
    # get_values sends each type to its own fmi2Get*.
    calls = []
    fake = type("F", (), {"variables": inst.variables})()
    for kind in ("real", "integer", "boolean", "string"):
        setattr(fake, f"get_{kind}", lambda names, kind=kind: calls.append((kind, names)) or [0])
    Instance.get_values(fake, ["s", "e", "b"])
    assert calls == [("string", ["s"]), ("integer", ["e"]), ("boolean", ["b"])]


# 3. An FMU that ends the simulation.

STAIR_SCENE = """
[scene]
title = "stair"
[components.s]
fmu = "{stair}"
parameters = { end_time = 2.55 }
[experiment]
stop = 10
[master]
step = 0.1
"""


def test_an_fmu_that_ends_the_simulation_is_a_clean_end(capsys, tmp_path):
    outs = {}
    for engine in ENGINES:
        rc, out, err = _run(capsys, tmp_path, _scene(tmp_path, STAIR_SCENE), engine=engine)
        assert rc == 0, err
        outs[engine] = out
        cols = _csv(out)
        assert cols["time"][-1] == "2.5" and cols["s.counter"][-1] == "2.0"
        result = json.loads((out / "summary.json").read_text())["result"]
        assert result["ended"]["instance"] == "s"
        assert result["ended"]["last_point_s"] == 2.5 and result["t_end_s"] == 2.5
    assert (outs["python"] / "timeseries.csv").read_bytes() == (outs["compiled"] / "timeseries.csv").read_bytes()


@pytest.mark.parametrize("engine", ENGINES)
def test_an_fmi3_fmu_ends_the_simulation_as_an_fmi2_one_does(capsys, tmp_path, engine):
    """TestStair's FMI 3.0 build reports the model's end as terminateSimulation
    from fmi3DoStep: the same clean end, the same result.ended and the same
    series as its FMI 2.0 build (fmi2Discard + fmi2Terminated)."""
    stair3 = test_fmu("TestStair").parent / "fmi3" / "TestStair.fmu"
    assert stair3.is_file(), f"{stair3} is missing: build the test FMUs first (cmake --build build)"
    runs = {}
    for fmi, text in ((2, STAIR_SCENE), (3, STAIR_SCENE.replace('fmu = "{stair}"', f'fmu = "{stair3}"'))):
        rc, out, err = _run(capsys, tmp_path / str(fmi), _scene(tmp_path, text, f"s{fmi}.toml"), engine=engine)
        assert rc == 0, err
        runs[fmi] = (json.loads((out / "summary.json").read_text())["result"], (out / "timeseries.csv").read_text())
    (r2, csv2), (r3, csv3) = runs[2], runs[3]
    assert csv3 == csv2
    assert "terminateSimulation" in r3["ended"]["message"]
    for key in ("instance", "time_s", "last_point_s"):
        assert r3["ended"][key] == r2["ended"][key], key
    assert r3["t_end_s"] == r2["t_end_s"] == 2.5


DISCRETE_FMI3_SCENE = """
connections = ["s.counter -> t.u_int", "t.y_int -> s.offset", "t.y_bool -> s.flip", "s.odd -> u.u_bool",
               "s.shifted -> u.u_int"]
[scene]
title = "discrete links of an FMI 3.0 FMU"
[components.s]
fmu = "{stair}"
parameters = { end_time = 9.0 }
[components.t]
fmu = "{types}"
parameters = { p_int = 10, p_bool = true }
[components.u]
fmu = "{types}"
[experiment]
stop = 3.5
[master]
step = 0.5
[record]
outputs = ["s.counter", "s.shifted", "s.odd", "t.y_int", "u.y_int", "u.y_bool"]
"""


@pytest.mark.parametrize("engine", ["python", "auto"])
def test_int32_and_boolean_links_into_and_out_of_an_fmi3_fmu(capsys, tmp_path, engine):
    """TestStair's FMI 3.0 build between two FMI 2.0 instances: an Int32 and
    a Boolean output feed Integer and Boolean inputs, and Integer and Boolean
    outputs feed its Int32 and Boolean inputs; the same series as with its
    FMI 2.0 build."""
    stair3 = test_fmu("TestStair").parent / "fmi3" / "TestStair.fmu"
    csvs = {}
    for fmi, text in ((2, DISCRETE_FMI3_SCENE), (3, DISCRETE_FMI3_SCENE.replace('"{stair}"', f'"{stair3}"'))):
        rc, out, err = _run(capsys, tmp_path / str(fmi), _scene(tmp_path, text, f"d{fmi}.toml"), engine=engine)
        assert rc == 0, err
        csvs[fmi] = (out / "timeseries.csv").read_text()
    assert csvs[3] == csvs[2]
    cols = _csv(tmp_path / "3" / f"out_{engine}")
    counter = [float(int(float(x))) for x in cols["time"]]
    assert [float(x) for x in cols["s.counter"]] == counter
    # t.y_int = 10 + counter; s takes it as offset one point later (s goes
    # first: counter feeds t without feedthrough), shifted = counter + offset;
    # u adds its p_int = 2 at the same point.
    assert [float(x) for x in cols["t.y_int"]] == [c + 10 for c in counter]
    shifted = [c + 10 + before for c, before in zip(counter[1:], counter)]
    assert [float(x) for x in cols["s.shifted"]][1:] == shifted
    assert [float(x) for x in cols["u.y_int"]][1:] == [x + 2 for x in shifted]
    # flip = t.y_bool = true: odd is "counter is even", and u.y_bool = odd.
    assert [float(x) for x in cols["s.odd"]][1:] == [float(c % 2 == 0) for c in counter][1:]
    assert cols["u.y_bool"][1:] == cols["s.odd"][1:]


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("extra, needle", [
    (["--set", "s.terminate=false"], "s: the stair ends at t = 2.55 s; the step to 2.6 s is refused."),
    (["--set", "s.terminate=false", "--set", "s.quiet=true"], "(the FMU logged no message)"),
])
def test_a_discard_that_is_no_end_fails_with_the_fmus_message(capsys, tmp_path, engine, extra, needle):
    rc, out, err = _run(capsys, tmp_path, _scene(tmp_path, STAIR_SCENE), *extra, engine=engine)
    assert_one_line_error(rc, err, "discarded", needle, code=1)
    # A failed run keeps its history: the series until the last good point, and a summary that says so.
    failed = json.loads((out / "summary.json").read_text())["result"]["failed"]
    assert failed["instance"] == "s" and failed["time_s"] == failed["last_point_s"] == 2.5 and needle in failed["message"]
    assert _csv(out)["time"][-1] == "2.5"


# 4. The DefaultExperiment tolerance, and master.tolerance.

DECAY_SCENE = """
[scene]
title = "decay"
[components.d]
fmu = "{decay}"
[experiment]
stop = 1
[master]
step = 0.5
[record]
outputs = ["d.x"]
"""


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("extra, tolerance", [([], 1e-3), (["--set", "master.tolerance=1e-4"], 1e-4)])
def test_the_tolerance_reaches_fmi2SetupExperiment(capsys, tmp_path, engine, extra, tolerance):
    rc, out, err = _run(capsys, tmp_path, _scene(tmp_path, DECAY_SCENE), *extra, engine=engine)
    assert rc == 0, err
    x1 = float(_csv(out)["d.x"][-1])
    # TestDecay takes Euler steps as long as the tolerance (1e-2 when none is given).
    steps = round(1.0 / tolerance)
    assert x1 == pytest.approx((1.0 - tolerance) ** steps, rel=1e-9)
    assert x1 != pytest.approx((1.0 - 1e-2) ** 100, rel=1e-6)


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("extra, tolerance", [([], 1e-3), (["--set", "master.tolerance=1e-4"], 1e-4)])
def test_the_tolerance_reaches_fmi3EnterInitializationMode(capsys, tmp_path, engine, extra, tolerance):
    """TestDecay's FMI 3.0 build: the same tolerance reaches it, so it gives the FMI 2.0 build's bits."""
    decay3 = test_fmu("TestDecay").parent / "fmi3" / "TestDecay.fmu"
    assert decay3.is_file(), f"{decay3} is missing: build the test FMUs first (cmake --build build)"
    scene3 = DECAY_SCENE.replace('fmu = "{decay}"', f'fmu = "{decay3}"')
    rc, out, err = _run(capsys, tmp_path / "3", _scene(tmp_path, scene3, "s3.toml"), *extra, engine=engine)
    assert rc == 0, err
    rc2, out2, err2 = _run(capsys, tmp_path / "2", _scene(tmp_path, DECAY_SCENE), *extra, engine=engine)
    assert rc2 == 0, err2
    x1 = _csv(out)["d.x"][-1]
    assert x1 == _csv(out2)["d.x"][-1]
    assert float(x1) == pytest.approx((1.0 - tolerance) ** round(1.0 / tolerance), rel=1e-9)


def test_a_bad_tolerance_is_refused(capsys, tmp_path):
    f = _scene(tmp_path, DECAY_SCENE)
    for value in ("0", "-1e-3", "true", '"tight"'):
        rc, _, err = run_cli(capsys, ["validate", f, "--set", f"master.tolerance={value}"])
        assert_one_line_error(rc, err, str(f), "master.tolerance", "a relative tolerance > 0")


# 5. Units: a dimensionless output into an input with a unit; conversion.

UNITS_SCENE = """
connections = ["d.x -> a.u_real", "a.y_real -> b.u_mm", "a.y_k -> b.u_k"]
[scene]
title = "units"
[components.d]
fmu = "{decay}"
[components.a]
fmu = "{types}"
parameters = { p_real = "250 mm" }
[components.b]
fmu = "{types}"
[experiment]
stop = 0.3
[master]
step = 0.1
[record]
outputs = ["a.y_real", "b.y_mm", "b.y_k"]
"""


def test_a_dimensionless_output_may_feed_an_input_with_a_unit_and_validate_says_so(capsys, tmp_path):
    f = _scene(tmp_path, UNITS_SCENE)
    rc, out, err = run_cli(capsys, ["validate", f])
    assert rc == 0, err
    notes = [line for line in out.splitlines() if line.startswith("note: ")]
    assert notes == ["note: connections[0]: d.x is in no unit, a.u_real in m: the value passes unconverted"]
    assert out.splitlines()[-1].startswith("ok: ")


@pytest.mark.parametrize("engine", ENGINES)
def test_convertible_units_are_converted_and_spellings_meet(capsys, tmp_path, engine):
    f = _scene(tmp_path, UNITS_SCENE)
    scene = load_scene(f)
    assert tuple(scene.connections[1][4:6]) == (1000.0, 0.0)  # m -> mm
    assert tuple(scene.connections[2][4:6]) == (1.0, 0.0)  # N.m/A -> Nm/A: the same unit
    rc, out, err = _run(capsys, tmp_path, f, engine=engine)
    assert rc == 0, err
    cols = _csv(out)
    assert [float(x) for x in cols["b.y_mm"]] == [1000.0 * float(y) for y in cols["a.y_real"]]
    assert float(cols["b.y_mm"][0]) == pytest.approx(250.0 + 1000.0 * 1.0)


def test_units_of_different_dimensions_are_refused(capsys, tmp_path):
    f = _scene(tmp_path, UNITS_SCENE.replace('"a.y_k -> b.u_k"', '"a.y_real -> b.u_k"'))
    rc, _, err = run_cli(capsys, ["validate", f])
    assert_one_line_error(rc, err, str(f), "connections[2]", "unit mismatch: a.y_real is in m, b.u_k in Nm/A")


# 6. --set of a dotted parameter name; der(x) recorded; dotted instance names.

NAMES_SCENE = """
connections = ["sub.a.y_real -> sub.u_real"]
[scene]
title = "dotted"
[components."sub.a"]
fmu = "{types}"
[components.sub]
fmu = "{types}"
[experiment]
stop = 0.3
[master]
step = 0.1
[record]
outputs = ["sub.a.y_real", "sub.der(x)", "sub.x"]
"""


@pytest.mark.parametrize("engine", ENGINES)
def test_dotted_parameters_are_set_and_der_x_is_recorded(capsys, tmp_path, engine):
    f = _scene(tmp_path, NAMES_SCENE)
    rc, out, err = _run(capsys, tmp_path, f, "--set", "sub.a.gain.k=-0.4", "--set", "sub.gain.k=3",
                        engine=engine)
    assert rc == 0, err
    cols = _csv(out)
    assert set(cols["sub.a.y_real"]) == {"-0.4"}  # gain.k * p_real with p_real = 1
    assert set(cols["sub.der(x)"]) == {"-0.4"}  # dx/dt = u_real
    assert float(cols["sub.x"][-1]) == pytest.approx(-0.4 * 0.3)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["result"]["engine"] == ("python" if engine == "python" else "compiled")


# 7. FMU log messages: the printf format with its arguments.

@pytest.mark.parametrize("engine", ENGINES)
def test_fmu_log_messages_are_formatted(engine):
    with System({"s": (str(test_fmu("TestStair")), {"end_time": 9.0})}, [],
                MasterSettings(step=0.25, engine=engine), record={"s": ["counter"]}) as s:
        s.master.run_until(2.0)
        texts = [m for _, m in s.instances["s"].messages]
    assert texts == ["s reached level 1 at t = 1 s", "s reached level 2 at t = 2 s"]


def test_a_message_without_the_formatting_library_is_the_raw_format(monkeypatch):
    # Without lib/libcw_master.so the Python engine hands on the FMU's format as it is.
    from clockwork.fmi import calls as fmu

    monkeypatch.setattr(fmu, "_formatter", [None])
    with System({"s": (str(test_fmu("TestStair")), {"end_time": 9.0})}, [],
                MasterSettings(step=0.5, engine="python")) as s:
        s.master.run_until(1.0)
        assert [m for _, m in s.instances["s"].messages] == ["%s reached level %d at t = %g s"]


# 8. The extrapolation order an FMU accepts.

PENDULUM = ("Pendulum", dict(Q=1000.0, phi_start=0.1))


@pytest.mark.parametrize("extrapolation", [1, 2])
def test_an_fmu_that_cannot_interpolate_inputs_gets_zero_order_hold(capsys, extrapolation):
    results = []
    for order, engine in ((0, "python"), (extrapolation, "python"), (extrapolation, "compiled")):
        with System({"p": PENDULUM, "d": (str(test_fmu("TestDecay")), {})}, ["p.phi -> d.v"],
                    MasterSettings(step=0.05, extrapolation=order, event_location=False, engine=engine)) as s:
            s.master.run_until(1.0)
            results.append(s.value("d", "x"))
            notes = list(s.master.notes)
        assert notes == ([] if order == 0 else [
            "d cannot interpolate its inputs (canInterpolateInputs is false): zero-order hold for it instead "
            f"of master.extrapolation = {extrapolation}"])
    assert results[0] == results[1] == results[2]
    assert capsys.readouterr().err.count("clockwork: warning: d cannot interpolate") == 2


def test_an_fmu_that_refuses_order_2_gets_order_1_said_once(capsys):
    runs = []
    for engine in ENGINES:
        with System({"p": PENDULUM, "t": _types()}, ["p.phi -> t.u_real"],
                    MasterSettings(step=0.05, extrapolation=2, event_location=False, engine=engine)) as s:
            s.master.run_until(1.0)
            runs.append((s.value("t", "x"), s.value("t", "u_rate"), list(s.master.notes)))
    assert runs[0] == runs[1]
    x, rate, notes = runs[0]
    assert rate != 0.0  # slopes still reach it (order 1)
    assert notes == ["t refused input derivatives of order 2 (fmi2SetRealInputDerivatives): order 1 from t = 0.05 s on"]
    assert capsys.readouterr().err.count("clockwork: warning: t refused input derivatives of order 2") == 2
    # The same as asking for order 1 from the start, after the first smooth step.
    with System({"p": PENDULUM, "t": _types()}, ["p.phi -> t.u_real"],
                MasterSettings(step=0.05, extrapolation=1, event_location=False, engine="python")) as s:
        s.master.run_until(1.0)
        assert s.value("t", "x") == x


def test_a_discrete_link_from_an_output_without_feedthrough(capsys):
    # The destination may be set before its source was first read (the
    # feedthrough order says nothing about them): it starts from zero, as
    # a Real input does, and follows from the first read on.
    with System({"s": (str(test_fmu("TestStair")), {"end_time": 9.0}), "t": _types(p_int=10)},
                ["s.counter -> t.u_int"], MasterSettings(step=0.25)) as s:
        assert s.master.engine == "python" and "Real connections only" in s.master.engine_reason
        s.master.run_until(2.0)
        # s steps first (Gauss-Seidel in file order): t sees the counter of 2 s.
        assert s.instances["t"].get_integer(["y_int"]) == [12]
