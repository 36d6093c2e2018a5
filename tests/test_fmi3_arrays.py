"""FMI 3.0 array variables: parameters, recording and connections, on both engines.

The FMU is tests/data/fmi3/linear.c (tests/fmi3_linear.py describes it, CMake builds it):
dx/dt = A x + B u, y = C x + D u with n = 3 states (a structural
parameter), A 3x3, B 3x2, C 2x3, D 2x2, x0 3, an input u (2), outputs y (2)
and x (3), a scalar input w and output s = sum(x) + w, an Int32 input k (3)
mirrored by kk. Its getters and setters check nValues, so a master that
passes it wrong fails. An array is recorded element by element, named as
fmpy names them (``y[0]``, ``A[1,2]``: indices from 0, row-major).
"""

from __future__ import annotations

import csv
import json
import re

import fmpy
import numpy as np
import pytest

from clockwork.fmi.description import read_fmu, variables
from clockwork.engine.recording import Recorder
from clockwork.engine.settings import MasterSettings
from clockwork.engine.system import System
from cwtest import assert_one_line_error, run_cli
from fmi3_linear import fmu  # noqa: F401 (the test FMU, a fixture)

ENGINES = ["python", "compiled"]
A = [[-1.0, 0.5, 0.0], [0.0, -2.0, 0.25], [0.1, 0.0, -3.0]]


def scene(tmp_path, fmu, body="", connections=(), outputs=("a.y", "a.x"), a="", b=None, name="s.toml"):
    links = ", ".join(f'"{c}"' for c in connections)
    comp_b = f'[components.b]\nfmu = "{fmu}"\nparameters = {{ {b} }}\n' if b is not None else ""
    f = tmp_path / name
    f.write_text(f"""connections = [{links}]
[scene]
title = "arrays"
[components.a]
fmu = "{fmu}"
parameters = {{ {a} }}
{comp_b}[experiment]
stop = 1.0
[master]
step = 0.1
[record]
outputs = [{", ".join(f'"{o}"' for o in outputs)}]
{body}""")
    return f


def read_csv(path):
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    return {h: [r[k] for r in rows[1:]] for k, h in enumerate(rows[0])}


def test_the_description_names_every_element_and_takes_shapes_from_dimensions(fmu):
    """Shapes from <Dimension start> and from the structural parameter n's
    start value; elements named as fmpy names them, in row-major order."""
    md = read_fmu(fmu)[0]
    v = variables(md)
    assert v["A"].shape == (3, 3) and v["B"].shape == (3, 2) and v["C"].shape == (2, 3) and v["u"].shape == (2,)
    assert [n for n in v if n.startswith("C[")] == ["C[0,0]", "C[0,1]", "C[0,2]", "C[1,0]", "C[1,1]", "C[1,2]"]
    assert v["C[0,1]"].start == "0" and v["C[1,1]"].start == "1"  # start="1 0 0 0 1 0", row by row
    assert v["y[1]"].causality == "output" and v["y[1]"].type == "Real"


def test_info_shows_each_arrays_shape(capsys, fmu):
    rc, out, err = run_cli(capsys, ["info", fmu])
    assert rc == 0, err
    line = next(x for x in out.splitlines() if x.split()[:1] == ["A"])
    assert "Float64[3x3]" in line and "-1 0 0 0 -2 0 0 0 -3" in line


@pytest.mark.parametrize("engine", ENGINES)
def test_one_fmu_gives_fmpys_numbers_to_the_bit(fmu, engine):
    """Array parameters (a 2-D one), an array input set as a parameter and
    array outputs, recorded per element: fmpy.simulate_fmu's numbers."""
    step, stop = 0.1, 2.0
    u = [1.0, -2.0]
    ref = fmpy.simulate_fmu(str(fmu), stop_time=stop, output_interval=step, output=["y", "x", "s"],
                            start_values={"A": list(np.ravel(A)), "u": u})
    with System({"a": (str(fmu), {"A": A, "u": u})}, [], MasterSettings(step=step, engine=engine),
                record={"a": ["y", "x", "s"]}) as s:
        assert s.master.engine == engine
        rec = Recorder(s.master, [("a", "y"), ("a", "x"), ("a", "s")])
        rec.start()
        s.master.run_until(stop, rec)
    assert rec.names == ["a.y[0]", "a.y[1]", "a.x[0]", "a.x[1]", "a.x[2]", "a.s"]
    assert rec.columns["time"] == list(ref["time"])
    for i in range(2):
        assert rec.columns[f"a.y[{i}]"] == list(ref["y"][:, i]), i
    for i in range(3):
        assert rec.columns[f"a.x[{i}]"] == list(ref["x"][:, i]), i
    assert rec.columns["a.s"] == list(ref["s"])
    assert len(set(rec.columns["a.x[0]"])) > 5  # it moves (A couples the states)


@pytest.mark.parametrize("engine", ENGINES)
def test_arrays_connect_element_by_element_in_order(fmu, engine):
    """a.y -> b.u (2 -> 2): each element reaches its own, in order; b swaps
    them (D = [[0, 1], [1, 0]], C = 0); an element feeds a scalar input."""
    params = {"a": {"A": A, "u": [1.0, -2.0]}, "b": {"D": [[0, 1], [1, 0]], "C": [[0, 0, 0], [0, 0, 0]]}}
    with System({"a": (str(fmu), params["a"]), "b": (str(fmu), params["b"])},
                ["a.y -> b.u", "a.y[1] -> b.w"], MasterSettings(step=0.1, engine=engine),
                record={"a": ["y"], "b": ["u", "y", "s", "w"]}) as s:
        assert s.master.engine == engine
        rec = Recorder(s.master, [("a", "y"), ("b", "u"), ("b", "y"), ("b", "w")])
        rec.start()
        s.master.run_until(1.0, rec)
    c = rec.columns
    for i in range(2):
        assert c[f"b.u[{i}]"] == c[f"a.y[{i}]"]
        assert c[f"b.y[{1 - i}]"] == c[f"a.y[{i}]"]
    assert c["b.w"] == c["a.y[1]"]
    assert c["a.y[0]"] != c["a.y[1]"]


@pytest.mark.parametrize("engine", ENGINES)
def test_a_part_of_an_array_is_read_element_by_element(fmu, engine):
    """Elements recorded out of order or alone (not whole arrays in order)
    are read one by one, beside scalars and whole arrays: the same values
    as a whole-array read."""
    def run(record):
        with System({"a": (str(fmu), {"A": A, "u": [1.0, -2.0]})}, [], MasterSettings(step=0.1, engine=engine),
                    record={"a": [name for name in record]}) as s:
            rec = Recorder(s.master, [("a", name) for name in record])
            rec.start()
            s.master.run_until(1.0, rec)
        return rec.columns

    whole = run(["y", "x", "s"])
    parts = run(["x[2]", "s", "y[1]", "x[0]"])
    for name in ("x[2]", "s", "y[1]", "x[0]"):
        assert parts[f"a.{name}"] == whole[f"a.{name}"], name


def test_both_adapters_serve_output_derivatives_of_elements(fmu):
    """fmi3GetOutputDerivatives on element codes, through the Python
    adapter and the core's cw3_getOutputDerivatives: whole arrays in order
    (one call, orders per array) and anything else (element by element)
    give the FMU's own values of whole-array calls."""
    import ctypes
    from ctypes import POINTER, c_double, c_int, c_size_t, c_uint, c_void_p

    from clockwork.engine.compiled import load_core

    core = load_core().cw3_getOutputDerivatives
    core.argtypes = [c_void_p, POINTER(c_uint), c_size_t, POINTER(c_int), POINTER(c_double)]
    core.restype = c_int
    with System({"a": (str(fmu), {"A": A, "u": [1.0, -2.0]})}, [], MasterSettings(step=0.1, engine="python")) as s:
        s.master.run_until(0.3)
        inst = s.instances["a"]
        direct = inst._slave.dll.fmi3GetOutputDerivatives
        direct.argtypes = [c_void_p, POINTER(c_uint), c_size_t, POINTER(c_int), POINTER(c_double), c_size_t]
        ref = {}
        for name, size in (("x", 3), ("y", 2)):
            for order in (1, 2):
                out = (c_double * size)()
                vr = (c_uint * 1)(inst.arrays[name][0])
                assert direct(inst.component, vr, 1, (c_int * 1)(order), out, size) == 0
                ref[(name, order)] = list(out)
        requests = [[("x[0]", 1), ("x[1]", 1), ("x[2]", 1)],
                    [("x[2]", 2), ("x[0]", 1)],
                    [("y[0]", 1), ("y[1]", 1), ("x[0]", 2), ("x[1]", 2), ("x[2]", 2)],
                    [("y[1]", 2), ("y[0]", 2), ("x[1]", 1)]]
        for request in requests:
            n = len(request)
            vrs = (c_uint * n)(*[inst.variables[name].vr for name, _ in request])
            orders = (c_int * n)(*[order for _, order in request])
            want = [ref[(name[0], order)][inst.variables[name].index] for name, order in request]
            for adapter in (lambda out: inst.c_getOutputDerivatives(inst.component, vrs, n, orders, out),
                            lambda out: core(ctypes.addressof(inst.events), vrs, n, orders, out)):
                out = (c_double * n)()
                assert adapter(out) == 0
                assert list(out) == want, request
        assert len({tuple(v) for v in ref.values()}) == 4  # the four are not alike


def test_both_engines_give_the_same_bits_through_a_scene(capsys, tmp_path, fmu):
    """A scene: array parameters from the file and from --set (a whole
    array and one element), array links, every element recorded."""
    outs = {}
    for engine in ENGINES:
        f = scene(tmp_path, fmu, connections=["a.y -> b.u"], outputs=["a.y", "b.y", "b.x", "a.A"],
                  a='u = [1.0, "-2 m"]', b="D = [[0, 1], [1, 0]]", name=f"{engine}.toml")
        out = tmp_path / engine
        rc, _, err = run_cli(capsys, ["run", f, "--out", out, "--no-progress", "--set", f"master.engine={engine}",
                                      "--set", f"a.A={json.dumps(A)}", "--set", "a.A[2,2]=-4",
                                      "--set", "b.x0[1]=3"])
        assert rc == 0, err
        outs[engine] = read_csv(out / "timeseries.csv")
        assert json.loads((out / "summary.json").read_text())["result"]["engine"] == engine
    a = outs["python"]
    assert list(a) == ["time", "a.y[0]", "a.y[1]", "b.y[0]", "b.y[1]", "b.x[0]", "b.x[1]", "b.x[2]",
                       *(f"a.A[{i},{j}]" for i in range(3) for j in range(3))]
    assert a == outs["compiled"]
    assert a["a.A[0,1]"][0] == "0.5" and a["a.A[2,2]"][0] == "-4.0"  # the element wins over the array
    assert a["b.x[1]"][0] == "3.0" and a["b.x[0]"][0] == "1.0"  # the others keep their start values


def test_an_int32_array_link_runs_in_the_python_engine(capsys, tmp_path, fmu):
    """A link of Int32 arrays (not Real): "auto" gives it to the Python engine, which passes every element."""
    f = scene(tmp_path, fmu, connections=["a.kk -> b.k"], outputs=["b.kk"], a="k = [7, -8, 9]", b="")
    out = tmp_path / "out"
    rc, _, err = run_cli(capsys, ["run", f, "--out", out, "--no-progress"])
    assert rc == 0, err
    cols = read_csv(out / "timeseries.csv")
    assert [cols[f"b.kk[{i}]"][-1] for i in range(3)] == ["7.0", "-8.0", "9.0"]
    assert json.loads((out / "summary.json").read_text())["result"]["engine"] == "python"


def test_without_record_every_element_of_every_output_is_recorded(capsys, tmp_path, fmu):
    f = tmp_path / "s.toml"
    f.write_text(scene(tmp_path, fmu).read_text().replace('[record]\noutputs = ["a.y", "a.x"]\n', ""))
    out = tmp_path / "out"
    rc, _, err = run_cli(capsys, ["run", f, "--out", out, "--no-progress"])
    assert rc == 0, err
    assert list(read_csv(out / "timeseries.csv")) == ["time", "a.y[0]", "a.y[1]", "a.x[0]", "a.x[1]", "a.x[2]",
                                                      "a.kk[0]", "a.kk[1]", "a.kk[2]", "a.s"]


def test_a_sweep_runs_over_one_element(capsys, tmp_path, fmu):
    f = scene(tmp_path, fmu, body='[sweep]\naxes = [ { parameter = "a.x0[2]", values = [2.0, 4.0] } ]\n')
    out = tmp_path / "out"
    rc, _, err = run_cli(capsys, ["run", f, "--out", out, "--no-progress"])
    assert rc == 0, err
    points = [json.loads(p.read_text()) for p in (out / "points").glob("*.json")]
    assert sorted(p["series"]["a.x[2]"][0] for p in points) == [2.0, 4.0]


@pytest.mark.parametrize("setting, needles", [
    ('a = "A = [1, 0, 0, 0, 1, 0, 0, 0, 1]"', ["components.a.parameters.A", "an array of 3 arrays of 3 values"]),
    ('a = "A = [1, 0, 0]"', ["components.a.parameters.A[0] = 1", "an array of 3 values"]),
    ('a = "A = [[1, 0], [0, 1]]"', ["components.a.parameters.A", "an array of 3 arrays of 3 values",
                                    "A is 3x3"]),
    ('a = "u = [1, 2, 3]"', ["components.a.parameters.u", "an array of 2 values"]),
    ('a = "u = 1.0"', ["components.a.parameters.u", "an array of 2 values"]),
    ('a = "u = [1, true]"', ["components.a.parameters.u[1]", "a number"]),
    ('a = "k = [1, 2, 3000000000]"', ["components.a.parameters.k[2]", "[-2147483648, 2147483647]"]),
    ('a = "n = 2"', ["components.a.parameters.n", "structural parameter", "configuration mode"]),
    ('b = "", connections=["a.x -> b.u"]', ["connections[0]", "a.x is 3, b.u is 2"]),
    ('b = "", connections=["a.s -> b.u"]', ["connections[0]", "b.u is an array (2) and a.s a scalar"]),
    ('b = "", connections=["a.y -> b.w"]', ["connections[0]", "a.y is an array (2) and b.w a scalar",
                                            "a.y[0]"]),
    ('b = "", connections=["a.y[0] -> b.u[0]"]', ["connections", "b.u is an input array of 2 values",
                                                  "1 of them"]),
    ('body = \'[sweep]\\naxes = [ { parameter = "a.A", values = [1, 2] } ]\\n\'',
     ["sweep.axes[0].parameter", "a.A is an array", "a.A[0,0]"]),
])
def test_bad_shapes_are_refused_at_validate_in_one_line(capsys, tmp_path, fmu, setting, needles):
    f = eval(f"scene(tmp_path, fmu, {setting})")  # noqa: S307 (the test's own table)
    rc, _, err = run_cli(capsys, ["validate", f])
    assert_one_line_error(rc, err, str(f), *needles)


@pytest.mark.parametrize("value, needles", [("[[1, 0], [0, 1]]", ["--set a.A", "A is 3x3"]),
                                            ("7", ["--set a.A", "an array of 3 arrays"]),
                                            ("[1, 2]", ["--set a.n", "structural parameter"])])
def test_set_checks_the_shape_of_an_array(capsys, tmp_path, fmu, value, needles):
    f = scene(tmp_path, fmu)
    key = "a.n" if "structural parameter" in needles else "a.A"
    rc, _, err = run_cli(capsys, ["validate", f, "--set", f"{key}={value}"])
    assert_one_line_error(rc, err, *needles)


def test_a_structural_parameter_is_refused_through_the_python_api_too(fmu):
    from clockwork.errors import SimulationError

    with pytest.raises(SimulationError, match="a.n is a structural parameter"):
        System({"a": (str(fmu), {"n": 2})}, [], MasterSettings(step=0.1))


@pytest.mark.parametrize("params, needle", [
    ({"A": [[-1.0, 0.5, 0.0], [0.0, "x", 0.25], [0.1, 0.0, -3.0]]}, "a.A = "),
    ({"A": A, "u": [1.0, None]}, "a.u = "),
    ({"A": A, "u": (1.0, True)}, "a.u = "),
    ({"A": A, "k": [7, 8.5, 9]}, "a.k = "),
])
def test_an_array_parameter_with_an_element_of_another_type_is_a_usage_error(fmu, params, needle):
    """The Python API checks an array's every element against its type
    (lists, tuples, nested or not), as it checks a scalar's value."""
    from clockwork.errors import UsageError

    with pytest.raises(UsageError, match="every element is") as info:
        System({"a": (str(fmu), params)}, [], MasterSettings(step=0.1))
    assert needle in str(info.value)


def test_an_array_parameter_given_a_scalar_or_a_numpy_array_is_a_usage_error(fmu):
    import numpy as np

    from clockwork.errors import UsageError

    for value in (1.0, np.array(A)):
        with pytest.raises(UsageError, match="a.A = .*expected a list of values"):
            System({"a": (str(fmu), {"A": value})}, [], MasterSettings(step=0.1))
    with System({"a": (str(fmu), {"A": tuple(map(tuple, A)), "u": (1.0, -2.0)})}, [], MasterSettings(step=0.1)) as s:
        assert s.value("a", "u") == [1.0, -2.0]


def test_fmpy_validates_the_test_fmu(fmu):
    from fmpy.validation import validate_fmu

    assert validate_fmu(str(fmu)) == []


def _description_only(tmp_path, name, body):
    import zipfile

    path = tmp_path / f"{name}.fmu"
    with zipfile.ZipFile(path, "w") as z:
        z.writestr("modelDescription.xml", f"""<?xml version="1.0"?>
<fmiModelDescription fmiVersion="3.0" modelName="{name}" instantiationToken="x">
  <CoSimulation modelIdentifier="M"/><ModelVariables>{body}</ModelVariables><ModelStructure/>
</fmiModelDescription>""")
    return path


OUT = '<Float64 name="a" valueReference="1" causality="output">{}</Float64>'
SIZE = '<UInt64 name="n" valueReference="2" causality="structuralParameter" variability="fixed"{}/>'


@pytest.mark.parametrize("body, needle", [
    (OUT.format('<Dimension valueReference="99"/>'), "Dimension valueReference='99': 99 is not the valueReference of a variable"),
    (OUT.format('<Dimension start="-1"/>'), "Dimension start='-1': expected an integer in [0, 4294967295]"),
    (OUT.format('<Dimension start="2.5"/>'), "Dimension start='2.5': expected an integer"),
    (OUT.format("<Dimension/>"), "Dimension: expected either start or valueReference"),
    (SIZE.format("") + OUT.format('<Dimension valueReference="2"/>'), "the size n, whose start value (none)"),
    (SIZE.format(' start="x"') + OUT.format('<Dimension valueReference="2"/>'), "UInt64 'n' start='x': expected an integer (UInt64)"),
    ('<Float64 name="p" valueReference="2" causality="parameter" variability="fixed" start="2"/>'
     + OUT.format('<Dimension valueReference="2"/>'), "must name a structural parameter"),
    (OUT.format('<Dimension start="1000"/><Dimension start="1001"/>'), "more than 100,000 elements"),
    (OUT.format('<Dimension start="2"/>') + '<Float64 name="a[1]" valueReference="2" causality="output"/>',
     "the element a[1] of the array a has the name of another variable"),
    ('<Binary name="a" valueReference="1" causality="output"><Dimension start="2"/></Binary>',
     "an array of Binary values (a)"),
])
def test_a_broken_array_declaration_is_one_line(capsys, tmp_path, body, needle):
    """Every way a <Dimension> can fail to give a size (most of them said by
    fmi/description_check.py, a size variable without a start by
    description._dimension_problem), an element name that is taken, too
    many elements and an unsupported element type: one line naming the FMU,
    from read_fmu and from validate."""
    from clockwork.fmi.description import FmuError

    path = _description_only(tmp_path, "Broken", body)
    with pytest.raises(FmuError, match=re.escape(needle)):
        read_fmu(path, need_binary=False)
    f = tmp_path / "s.toml"
    f.write_text(f'[scene]\ntitle = "t"\n[components.a]\nfmu = "{path.name}"\n[experiment]\nstop = 1\n')
    rc, _, err = run_cli(capsys, ["validate", f])
    assert_one_line_error(rc, err, "components.a.fmu", str(path), needle)


def test_an_empty_array_loads_with_no_elements(tmp_path):
    md = read_fmu(_description_only(tmp_path, "Empty", OUT.format('<Dimension start="0"/>')), need_binary=False)[0]
    assert variables(md)["a"].shape == (0,) and not [n for n in variables(md) if n.startswith("a[")]


def test_an_empty_array_may_say_its_empty_start_list(tmp_path):
    """start="" is an empty xs:list, valid for an array of size 0 (the schema's list type)."""
    body = '<Float64 name="a" valueReference="1" causality="parameter" variability="fixed" start=""><Dimension ' \
           'start="0"/></Float64>'
    md = read_fmu(_description_only(tmp_path, "EmptyStart", body), need_binary=False)[0]
    assert variables(md)["a"].shape == (0,)


def test_an_fmu_alone_records_its_array_outputs_as_fmpy_does(tmp_path, capsys, fmu):
    """`clockwork run X.fmu` and `clockwork.simulate(X.fmu)` record every
    output, arrays included (element by element in the CSV; in the
    structured array one field of the array's shape, as fmpy returns it),
    with fmpy.simulate_fmu's numbers at the same step."""
    import clockwork

    ref = fmpy.simulate_fmu(str(fmu), output_interval=0.1)
    got = clockwork.simulate(str(fmu))
    # the same fields in fmpy's order (by type: the Float64 arrays and s, then the Int32 kk)
    assert got.dtype.names == ref.dtype.names
    for name in ref.dtype.names:
        assert got.dtype[name] == ref.dtype[name], name
        assert np.array_equal(got[name], ref[name]), name
    assert len(set(got["x"][:, 0])) > 5  # it moves
    out = tmp_path / "out"
    rc, _, err = run_cli(capsys, ["run", fmu, "--out", out, "--no-progress", "--no-plot"])
    assert rc == 0, err
    columns = read_csv(out / "timeseries.csv")
    names = [h.split(".", 1)[1] for h in columns if h != "time"]
    assert names == ["y[0]", "y[1]", "x[0]", "x[1]", "x[2]", "s", "kk[0]", "kk[1]", "kk[2]"], names
    x2 = next(h for h in columns if h.endswith(".x[2]"))
    assert [float(x) for x in columns[x2]] == list(ref["x"][:, 2])
