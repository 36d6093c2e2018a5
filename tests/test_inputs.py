"""Inputs driven from samples: fmpy's rules between samples (engine/samples.py
against fmpy's own Input), the same bits on both engines, input files for
FMUs, scenes and SSPs, and every class of bad file as one line naming the
file, the line and the column."""

from __future__ import annotations

import json
import math
import random

import numpy as np
import pytest
from fmpy.simulation import Input

from clockwork.engine.samples import Samples, Signal
from clockwork.run.catalog import load_scene
from clockwork.run.points import run_point
from cwtest import assert_one_line_error, run_cli, test_fmu

# A table with a step at 0.5 (the time twice), a ramp, a run of three rows at 1.2 and a last row.
TIMES = [0.0, 0.25, 0.5, 0.5, 0.8, 1.2, 1.2, 1.2, 1.5]
RAMP = [0.0, 1.0, 2.0, -1.0, 3.0, 0.5, 4.0, 2.0, 7.0]
HELD = [0.0, 0.0, 1.0, 1.0, 1.0, 2.0, 2.0, 3.0, 3.0]


def _probe_times():
    rng = random.Random(3)
    ts = [-1.0, 1.7] + TIMES + [t * (1 + 3e-10) for t in TIMES] + [t * (1 - 3e-10) for t in TIMES if t]
    ts += [rng.uniform(0.0, 1.6) for _ in range(200)]
    return ts


def test_values_between_samples_are_fmpys_to_the_bit():
    samples = Samples(TIMES, [Signal("m", "u", tuple(RAMP), True), Signal("m", "d", tuple(HELD), False)])
    t = np.array(TIMES)
    for time in _probe_times():
        for after in (False, True):
            want_u, _ = Input.interpolate(time, t, np.array([RAMP]), discrete=False, after_event=after)
            want_d, _ = Input.interpolate(time, t, np.array([HELD]), discrete=True, after_event=after)
            assert samples.at(time, after) == [float(want_u[0]), float(want_d[0])], (time, after)


def test_input_events_are_fmpys():
    """Steps and changes of the held signal (fmpy's findEvents), and the next one after a time."""
    class Var:
        def __init__(self, name, variability):
            self.name, self.variability = name, variability

    class Md:
        modelVariables = [Var("u", "continuous"), Var("d", "discrete")]

    table = np.array(list(zip(TIMES, RAMP, HELD)), dtype=[("time", float), ("u", float), ("d", float)])
    fmpy_events = [e for e in Input.findEvents(table, Md) if math.isfinite(e)]
    samples = Samples(TIMES, [Signal("m", "u", tuple(RAMP), True), Signal("m", "d", tuple(HELD), False)])
    assert list(samples.events) == fmpy_events == [0.5, 1.2]
    inp = Input.__new__(Input)
    inp.t, inp.t_events = table["time"], Input.findEvents(table, Md)
    for time in _probe_times():
        assert samples.next_event(time) == inp.nextEvent(time), time
        assert samples.event_at(time) == any(math.isclose(time, e) for e in fmpy_events)


def test_one_sample_holds_everywhere():
    s = Samples([2.0], [Signal("m", "u", (5.0,), True)])
    assert s.at(0.0, False) == s.at(9.0, True) == [5.0] and s.events == ()


# -- the two engines ---------------------------------------------------------

# A clock with a vibrating mechanism (smooth links into inputs that take
# polynomials: the discontinuity at an input event shows in the numbers).
CLOCK = """\
connections = ["pendulum.phi -> escapement.phi", "pendulum.w -> escapement.w",
               "escapement.tau -> pendulum.tau_escapement", "pendulum.phi -> vibration.a1",
               "vibration.tau -> pendulum.tau_coupling"]
[scene]
title = "clock with a pushed pendulum"
[components.pendulum]
fmu = "Pendulum"
parameters = {{ Q = 1000, phi_start = "6 deg" }}
[components.escapement]
fmu = "GrasshopperEscapement"
parameters = {{ torque = "0.4 N.cm", phi_r = "2 deg" }}
[components.vibration]
fmu = "MechanismVibration"
parameters = {{ omega02 = 20.4, C1 = 1.0, C2 = 2.5 }}
[experiment]
stop = 3.0
[master]
step = 0.01
extrapolation = {order}
engine = "{engine}"
[record]
outputs = ["pendulum.phi", "pendulum.w", "pendulum.a", "escapement.tau", "vibration.tau"]
[inputs]
file = "push.csv"
"""
# A torque pulse (a step up at an off-grid time, a ramp down) and gravity changed at steps.
PUSH = """time,pendulum.tau_external,pendulum.g_factor
0,0,1
0.733,0,1
0.733,0.002,1
1.2,0,1.5
1.2,0,1.0
2.05,0,2
"""


@pytest.mark.parametrize("order", [0, 1, 2])
def test_sampled_inputs_give_the_same_bits_on_both_engines(tmp_path, order):
    (tmp_path / "push.csv").write_text(PUSH)
    series = {}
    for engine in ("python", "compiled"):
        f = tmp_path / f"{engine}.toml"
        f.write_text(CLOCK.format(order=order, engine=engine))
        r = run_point(load_scene(f), {})
        assert r["result"]["engine"] == engine
        series[engine] = r["series"]
    assert series["python"] == series["compiled"]
    t = series["python"]["time"]
    assert 0.733 in t and 1.2 in t  # communication points land on the input events
    assert 0.73 in t and 0.74 in t  # and the grid goes on around them


def test_a_pushed_clock_differs_from_an_unpushed_one(tmp_path):
    """The input reaches the pendulum (a test of the test above)."""
    (tmp_path / "push.csv").write_text(PUSH)
    f = tmp_path / "s.toml"
    f.write_text(CLOCK.format(order=0, engine="auto"))
    pushed = run_point(load_scene(f), {})["series"]["pendulum.w"]
    f.write_text(CLOCK.format(order=0, engine="auto").replace('[inputs]\nfile = "push.csv"\n', ""))
    free = run_point(load_scene(f), {})["series"]["pendulum.w"]
    assert pushed[:74] == free[:74] and pushed[-1] != free[-1]


def test_inputs_of_other_types_run_in_python_and_say_why(tmp_path):
    (tmp_path / "in.csv").write_text("time,offset,flip\n0,0,false\n0.45,7,true\n")
    scene = load_scene(test_fmu("TestStair"), ["experiment.stop=1"], tmp_path / "in.csv")
    r = run_point(scene, {})
    assert r["result"]["engine"] == "python"
    assert "sets sampled Real inputs only (TestStair.offset is Integer)" in r["result"]["engine_reason"]
    s = r["series"]
    k = s["time"].index(0.45)  # an event off the grid: a communication point
    assert s["TestStair.shifted"][k] == 0 and s["TestStair.shifted"][k + 1] == 7  # before, then after it
    assert s["TestStair.odd"][k + 1] == 1.0


@pytest.mark.parametrize("columns, rows, column", [("offset", "0,1", "column 2 (TestStair.offset)"),
                                                    ("offset,flip", "0,0,true", "column 2 (TestStair.offset)"),
                                                    ("flip", "0,true", "column 2 (TestStair.flip)")])
def test_compiled_asked_for_with_an_integer_input_is_refused(capsys, tmp_path, columns, rows, column):
    """validate refuses what run refuses, both naming the input file and the column (before: validate
    passed, and run's line named no file)."""
    (tmp_path / "in.csv").write_text(f"time,{columns}\n{rows}\n")
    for cmd in (["validate", test_fmu("TestStair")], ["run", test_fmu("TestStair"), "--out", tmp_path / "r"]):
        rc, _, err = run_cli(capsys, [*cmd, "--input", tmp_path / "in.csv", "--set", "master.engine=\"compiled\""])
        assert_one_line_error(rc, err, f"{tmp_path / 'in.csv'}: {column}", "sets sampled Real inputs only",
                              'expected master.engine = "auto" or "python"', "--set master.engine", code=2)
    assert not (tmp_path / "r").exists()


@pytest.fixture(scope="module")
def linear_fmu():
    return test_fmu("fmi3/Linear")


@pytest.mark.parametrize("column, hint", [("u", "u[0], u[1]"), ("k", "k[0], k[1], k[2]")])
def test_an_input_column_for_a_whole_array_is_refused_naming_its_elements(capsys, tmp_path, linear_fmu, column,
                                                                         hint):
    """An FMI 3.0 array takes one value per element: a column of one number per row cannot set it
    (before: validate passed, and the run failed in fmi3SetFloat64)."""
    (tmp_path / "in.csv").write_text(f"time,{column}\n0,1\n1,2\n")
    for cmd in (["validate", linear_fmu], ["run", linear_fmu, "--out", tmp_path / "r", "--no-progress"]):
        rc, _, err = run_cli(capsys, [*cmd, "--input", tmp_path / "in.csv"])
        assert_one_line_error(rc, err, f"{tmp_path / 'in.csv'}: line 1, column 2 ({column})", "an array of",
                              f"expected a column per element ({hint}", code=2)
    assert not (tmp_path / "r").exists()


@pytest.mark.parametrize("engine", ["python", "compiled"])
def test_input_columns_for_array_elements_drive_them(capsys, tmp_path, linear_fmu, engine):
    """u[0] and u[1] as columns: y = C x + D u with D = 0 here, so x's inputs show in x (B u)."""
    (tmp_path / "in.csv").write_text("time,u[0],u[1]\n0,1,2\n2,1,2\n")
    (tmp_path / "zero.csv").write_text("time,u[0],u[1]\n0,0,0\n2,0,0\n")
    runs = {}
    for name in ("in", "zero"):
        rc, _, err = run_cli(capsys, ["run", linear_fmu, "--input", tmp_path / f"{name}.csv", "--out",
                                      tmp_path / name, "--no-progress", "--set", f"master.engine={engine}"])
        assert rc == 0, err
        lines = (tmp_path / name / "timeseries.csv").read_text().splitlines()
        runs[name] = dict(zip(lines[0].split(","), lines[-1].split(",")))
    assert float(runs["in"]["Linear.x[0]"]) > float(runs["zero"]["Linear.x[0]"])
    assert float(runs["in"]["Linear.x[1]"]) > float(runs["zero"]["Linear.x[1]"])


# -- files for FMUs, scenes and SSPs ----------------------------------------------------

def test_an_input_file_drives_an_fmu_from_the_command_line(capsys, tmp_path):
    (tmp_path / "v.csv").write_text("# a source term\ntime,v\n0,0\n0.5,2\n\n1,2\n")
    rc, out, err = run_cli(capsys, ["validate", test_fmu("TestDecay"), "--input", tmp_path / "v.csv"])
    assert rc == 0 and "inputs from v.csv: TestDecay.v" in out, err
    rc, _, err = run_cli(capsys, ["run", test_fmu("TestDecay"), "--input", tmp_path / "v.csv", "--out",
                                  tmp_path / "r", "--no-progress"])
    assert rc == 0, err
    summary = json.loads((tmp_path / "r" / "summary.json").read_text())
    assert summary["inputs"]["columns"] == ["TestDecay.v"] and summary["inputs"]["file"] == str(tmp_path / "v.csv")
    rc, _, err = run_cli(capsys, ["run", test_fmu("TestDecay"), "--out", tmp_path / "free", "--no-progress"])
    driven = (tmp_path / "r" / "timeseries.csv").read_text().splitlines()
    free = (tmp_path / "free" / "timeseries.csv").read_text().splitlines()
    assert driven[:2] == free[:2] and driven[-1] != free[-1]


def test_a_scene_names_its_input_file_relative_to_itself(tmp_path, monkeypatch):
    d = tmp_path / "scenes"
    d.mkdir()
    (d / "v.csv").write_text("time,decay.v\n0,1\n")
    (d / "s.toml").write_text('[scene]\ntitle = "t"\n[components.decay]\nfmu = "%s"\n[experiment]\nstop = 1\n'
                              '[inputs]\nfile = "v.csv"\n' % test_fmu("TestDecay"))
    monkeypatch.chdir(tmp_path)
    scene = load_scene(d / "s.toml")
    assert scene.inputs.columns == ["decay.v"] and scene.inputs.file == d / "v.csv"
    (tmp_path / "other.csv").write_text("time,v\n0,2\n")  # the command line's file wins, from the current folder
    assert load_scene(d / "s.toml", input_file="other.csv").inputs.samples.signals[0].values[0] == 2.0


def test_an_ssp_takes_instance_variable_columns(capsys, tmp_path):
    """An SSP written from a scene, driven by a file naming instance.variable."""
    (tmp_path / "s.toml").write_text(
        '[scene]\ntitle = "two decays"\n[components.a]\nfmu = "%s"\n[components.b]\nfmu = "%s"\n'
        '[experiment]\nstop = 1\n[master]\nstep = 0.1\n' % (test_fmu("TestDecay"), test_fmu("TestDecay")))
    rc, _, err = run_cli(capsys, ["export-ssp", tmp_path / "s.toml", "--out", tmp_path / "s.ssp"])
    assert rc == 0, err
    (tmp_path / "in.csv").write_text("time,b.v\n0,0\n1,5\n")
    rc, _, err = run_cli(capsys, ["run", tmp_path / "s.ssp", "--input", tmp_path / "in.csv", "--out", tmp_path / "r",
                                  "--no-progress"])
    assert rc == 0, err
    last = (tmp_path / "r" / "timeseries.csv").read_text().splitlines()[-1].split(",")
    assert float(last[1]) < float(last[2])  # a decays freely, b is fed
    (tmp_path / "bad.csv").write_text("time,v\n0,0\n")  # two components: the instance is needed
    rc, _, err = run_cli(capsys, ["validate", tmp_path / "s.ssp", "--input", tmp_path / "bad.csv"])
    assert_one_line_error(rc, err, "bad.csv", "line 1, column 2 (v)", "a.v, b.v", code=2)


def test_export_ssp_refuses_a_scene_with_inputs(capsys, tmp_path):
    (tmp_path / "v.csv").write_text("time,d.v\n0,1\n")
    (tmp_path / "s.toml").write_text('[scene]\ntitle = "t"\n[components.d]\nfmu = "%s"\n[experiment]\nstop = 1\n'
                                     '[inputs]\nfile = "v.csv"\n' % test_fmu("TestDecay"))
    rc, _, err = run_cli(capsys, ["export-ssp", tmp_path / "s.toml", "--out", tmp_path / "s.ssp"])
    assert_one_line_error(rc, err, "an SSP cannot carry", code=2)
    assert not (tmp_path / "s.ssp").exists()


# -- bad files, each class one line naming the file, the line and the column ---------------

BAD_FILES = [
    ("time;v\n0;1\n", "line 1, column 1 (time;v)", "expected the first column to be time (comma-separated"),
    ("t,v\n0,1\n", "line 1, column 1 (t)", "expected the first column to be time"),
    ("time,w\n0,1\n", "line 1, column 2 (w)", "no input of that name; expected one of the unconnected inputs: v"),
    ("time,vv\n0,1\n", "line 1, column 2 (vv)", "(did you mean v?)"),
    ("time,k\n0,1\n", "line 1, column 2 (k)", "is a parameter, not an input"),
    ("time,x\n0,1\n", "line 1, column 2 (x)", "is a output, not an input"),
    ("time,v,TestDecay.v\n0,1,1\n", "line 1, column 3 (TestDecay.v)", "is also column 2"),
    ("time,v,\n0,1,2\n", "line 1, column 3", "an empty column name"),
    ("time,v\n0,1\n1\n", "line 3", "1 values for 2 columns"),
    ("time,v\n0,1\n1,2,3\n", "line 3", "3 values for 2 columns"),
    ("time,v\n0,one\n", "line 2, column 2 (v)", "expected a decimal number (a Real input), got 'one'"),
    ("time,v\n0,1_0\n", "line 2, column 2 (v)", "expected a decimal number"),
    ("time,v\n0,nan\n", "line 2, column 2 (v)", "expected a decimal number"),
    ("time,v\n0,1e999\n", "line 2, column 2 (v)", "expected a finite number"),
    ("time,v\nsoon,1\n", "line 2, column 1 (time)", "expected a time in s"),
    ("time,v\n1e999,1\n", "line 2, column 1 (time)", "expected a finite time"),
    ("time,v\n0,1\n1,1\n0.5,1\n", "line 4, column 1 (time)", "is before the time of the row above"),
    ("time,v\n", None, "no samples"),
    ("", None, "empty"),
    ("\n# only a comment\n", None, "empty"),
    ('time,v\n0,"1\n', "line 2", "malformed CSV"),
]


@pytest.mark.parametrize("text, where, needle", BAD_FILES)
def test_a_bad_input_file_is_one_line_naming_the_place(capsys, tmp_path, text, where, needle):
    f = tmp_path / "in.csv"
    f.write_text(text)
    rc, _, err = run_cli(capsys, ["run", test_fmu("TestDecay"), "--input", f, "--out", tmp_path / "r"])
    assert_one_line_error(rc, err, str(f), *([where] if where else []), needle, code=2)
    assert not (tmp_path / "r").exists()


BAD_TYPED = [
    ("time,offset\n0,1.5\n", "line 2, column 2 (offset)", "expected an integer (Integer input)"),
    ("time,offset\n0,2000000000\n", "line 2, column 2 (offset)", "expected a value in [-1000000000, 1000000000]"),
    ("time,flip\n0,yes\n", "line 2, column 2 (flip)", "expected true, false, 1 or 0"),
    ("time,flip\n0,2\n", "line 2, column 2 (flip)", "expected true, false, 1 or 0"),
]


@pytest.mark.parametrize("text, where, needle", BAD_TYPED)
def test_a_bad_value_of_a_typed_input_is_one_line(capsys, tmp_path, text, where, needle):
    f = tmp_path / "in.csv"
    f.write_text(text)
    rc, _, err = run_cli(capsys, ["validate", test_fmu("TestStair"), "--input", f])
    assert_one_line_error(rc, err, str(f), where, needle, code=2)


@pytest.mark.parametrize("data, needle", [
    (b"time,v\n0,\xff\n", "not UTF-8 text (byte 9)"),
    (None, "no such input file"),
    ("dir", "is a directory"),
])
def test_an_unreadable_input_file_is_one_line(capsys, tmp_path, data, needle):
    f = tmp_path / "in.csv"
    if data == "dir":
        f.mkdir()
    elif data is not None:
        f.write_bytes(data)
    rc, _, err = run_cli(capsys, ["validate", test_fmu("TestDecay"), "--input", f])
    assert_one_line_error(rc, err, str(f), needle, code=2)


def test_an_input_both_connected_and_in_the_file_is_refused(capsys, tmp_path):
    (tmp_path / "in.csv").write_text("time,escapement.phi\n0,0\n")
    (tmp_path / "s.toml").write_text(CLOCK.format(order=0, engine="auto").replace("push.csv", "in.csv"))
    rc, _, err = run_cli(capsys, ["validate", tmp_path / "s.toml"])
    assert_one_line_error(rc, err, "in.csv", "line 1, column 2 (escapement.phi)",
                          "is connected: an input is either connected or driven from a file", code=2)


def test_an_input_both_set_and_in_the_file_is_refused(capsys, tmp_path):
    (tmp_path / "in.csv").write_text("time,v\n0,0\n")
    rc, _, err = run_cli(capsys, ["validate", test_fmu("TestDecay"), "--set", "v=1", "--input", tmp_path / "in.csv"])
    assert_one_line_error(rc, err, "in.csv", "column 2 (v)", "also given a value in the scene", code=2)


@pytest.mark.parametrize("table, key, needle", [
    ('[inputs]\nfile = "missing.csv"\n', "inputs.file", "no such input file"),
    ("[inputs]\nfile = 3\n", "inputs.file = 3", "expected the path of a CSV input file"),
    ('[inputs]\nfile = ""\n', "inputs.file", "expected the path of a CSV input file"),
    ("[inputs]\n", "inputs.file", "missing required key"),
    ('[inputs]\nfile = "v.csv"\ncolumns = 2\n', "inputs.columns", "unknown key"),
    ('inputs = "v.csv"\n', "inputs", "expected a table"),
])
def test_a_bad_inputs_table_is_one_line(capsys, tmp_path, table, key, needle):
    (tmp_path / "v.csv").write_text("time,d.v\n0,0\n")
    text = '%s[scene]\ntitle = "t"\n[components.d]\nfmu = "%s"\n[experiment]\nstop = 1\n' % (
        table if table.startswith("inputs =") else "", test_fmu("TestDecay"))
    if not table.startswith("inputs ="):
        text += table
    (tmp_path / "s.toml").write_text(text)
    rc, _, err = run_cli(capsys, ["validate", tmp_path / "s.toml"])
    assert_one_line_error(rc, err, "s.toml", key, needle, code=2)


def test_a_sweep_with_inputs_runs_in_workers_and_its_points_know_the_file(capsys, tmp_path):
    """Points in worker processes get the samples; a changed file is a new point (its content address)."""
    from clockwork.run.points import point_key

    (tmp_path / "v.csv").write_text("time,d.v\n0,0\n0.5,3\n")
    (tmp_path / "s.toml").write_text(
        '[scene]\ntitle = "t"\n[components.d]\nfmu = "%s"\n[experiment]\nstop = 1\n[inputs]\nfile = "v.csv"\n'
        '[record]\noutputs = ["d.x"]\n[sweep]\naxes = [{ parameter = "d.k", values = [0.5, 1.0, 2.0] }]\n'
        % test_fmu("TestDecay"))
    rc, _, err = run_cli(capsys, ["run", tmp_path / "s.toml", "--out", tmp_path / "r", "--workers", "2",
                                  "--no-progress"])
    assert rc == 0, err
    scene = load_scene(tmp_path / "s.toml")
    here = [run_point(scene.variant(p), {})["series"]["d.x"][-1] for p in scene.points()]
    stored = json.loads((tmp_path / "r" / "summary.json").read_text())
    assert stored["points_failed"] == 0 and stored["inputs"]["columns"] == ["d.v"]
    assert stored["files"] == ["sweep.csv", "summary.json"]  # no default plot of one point's series
    keys = [point_key(scene, p) for p in scene.points()]
    loaded = [json.loads((tmp_path / "r" / "points" / f"{k}.json").read_text()) for k in keys]
    assert [r["series"]["d.x"][-1] for r in loaded] == here
    (tmp_path / "v.csv").write_text("time,d.v\n0,0\n0.5,4\n")
    assert point_key(load_scene(tmp_path / "s.toml"), scene.points()[0]) != keys[0]


def test_an_input_file_is_read_in_memory_proportional_to_its_numbers(tmp_path):
    """A 100 MB input file took 858 MB to validate (the text whole, its lines,
    then a Python float of 32 bytes per 2-byte cell): now it is read a line
    at a time into arrays of doubles, about 4 bytes of memory a byte of file
    at worst (cells "0,"), and the bound on its size (128 MiB) is set by that."""
    import tracemalloc

    from clockwork.scene.inputs import MAX_INPUT_BYTES, read_inputs

    width = 100
    f = tmp_path / "zeros.csv"
    with open(f, "w") as out:
        out.write("time," + ",".join(f"u[{k}]" for k in range(1, width + 1)) + "\n")
        out.write((",".join(["0"] * (width + 1)) + "\n") * 5000)
    size = f.stat().st_size
    scene = load_scene(test_fmu("TestSink"))
    tracemalloc.start()
    try:
        inputs = read_inputs(f, scene.components)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert len(inputs.samples.times) == 5000 and len(inputs.samples.signals) == width
    assert peak < 4.5 * size + 200_000, (peak, size)  # before: 19 times the file
    assert MAX_INPUT_BYTES * 8 < 1.2e9  # Booleans at worst: 8 bytes a byte (and a transient copy)


def test_an_input_file_over_the_bound_is_refused_by_its_size(capsys, tmp_path):
    from clockwork.scene.inputs import MAX_INPUT_BYTES

    f = tmp_path / "big.csv"
    with open(f, "wb") as out:
        out.write(b"time,u[1]\n0,1\n")
        out.truncate(MAX_INPUT_BYTES + 1)  # sparse: no disk, and nothing read
    rc, _, err = run_cli(capsys, ["validate", test_fmu("TestSink"), "--input", f])
    assert_one_line_error(rc, err, str(f), f"at most {MAX_INPUT_BYTES} bytes")
    f.write_bytes(b"time,u[1]\n0," + b"1" * (1 << 22) + b"\n")
    rc, _, err = run_cli(capsys, ["validate", test_fmu("TestSink"), "--input", f])
    assert_one_line_error(rc, err, str(f), "line 2", "longer than")
