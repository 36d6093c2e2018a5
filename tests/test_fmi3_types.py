"""Every FMI 3.0 variable type in parameters, recording and connections.

The FMU is tests/data/fmi3/alltypes.c (tests/fmi3_alltypes.py describes it, CMake builds it):
per type T a parameter p_T, an input u_T and an output y_T = u_T. Each type
goes through its own fmi3Get/Set function (the FMU fails a call of another
type's), an Enumeration through fmi3Get/SetInt64, a Binary is recorded and
set as hexadecimal digits. Integers of any size connect to each other and
to Enumerations, Float32 to Float64; other mixes are refused at validation.
"""

from __future__ import annotations

import json

import pytest

from cwtest import assert_one_line_error, run_cli, test_fmu
import fmi3_alltypes

TYPES = fmi3_alltypes.TYPES
INTEGERS = ("Int8", "UInt8", "Int16", "UInt16", "Int32", "UInt32", "Int64", "UInt64")
RANGES = {"Int8": (-2**7, 2**7 - 1), "UInt8": (0, 2**8 - 1), "Int16": (-2**15, 2**15 - 1),
          "UInt16": (0, 2**16 - 1), "Int32": (-2**31, 2**31 - 1), "UInt32": (0, 2**32 - 1),
          "Int64": (-2**63, 2**63 - 1), "UInt64": (0, 2**64 - 1)}
# A value of each type the FMU does not start with (TOML text, recorded column text).
VALUES = {"Float32": ("0.1", repr(float.fromhex("0x1.99999ap-4"))),  # 0.1 rounded to Float32
          "Float64": ("0.1", "0.1"), "Boolean": ("true", "1.0"), "String": ('"héllo, \\"x\\""', None),
          "Binary": ('"00ff10"', "00ff10"), "Enumeration": ('"high"', "3.0"),
          **{t: (str(RANGES[t][0] or RANGES[t][1]), repr(float(RANGES[t][0] or RANGES[t][1]))) for t in INTEGERS}}


@pytest.fixture(scope="module")
def fmu():
    return test_fmu("fmi3/AllTypes")


def scene(tmp_path, fmu, a_params="", b_params="", connections=(), outputs=(), engine="auto", name="s.toml"):
    links = ", ".join(f'"{c}"' for c in connections)
    record = f"[record]\noutputs = [{', '.join(repr(o) for o in outputs)}]\n" if outputs else ""
    f = tmp_path / name
    f.write_text(f"""connections = [{links}]
[scene]
title = "all types"
[components.a]
fmu = "{fmu}"
parameters = {{ {a_params} }}
[components.b]
fmu = "{fmu}"
parameters = {{ {b_params} }}
[experiment]
stop = 0.3
[master]
step = 0.1
engine = "{engine}"
{record}""")
    return f


def run(capsys, tmp_path, f, *extra):
    out = tmp_path / "out"
    rc, _, err = run_cli(capsys, ["run", f, "--out", out, "--no-progress", *extra])
    return rc, out, err


def columns(out):
    import csv

    with open(out / "timeseries.csv", newline="") as fh:
        rows = list(csv.reader(fh))
    return {h: [r[k] for r in rows[1:]] for k, h in enumerate(rows[0])}


def expected(kind):
    text, column = VALUES[kind]
    return 'héllo, "x"' if kind == "String" else column


@pytest.mark.parametrize("engine", ["auto", "python"])
def test_every_output_of_every_type_is_recorded(capsys, tmp_path, fmu, engine):
    """Without [record] every output is recorded: each through its own
    fmi3Get*, numbers as numbers, String as text, Binary as hex digits."""
    params = ", ".join(f"u_{t} = {VALUES[t][0]}" for t in TYPES)
    rc, out, err = run(capsys, tmp_path, scene(tmp_path, fmu, a_params=params, engine=engine))
    assert rc == 0, err
    cols = columns(out)
    assert len(cols["time"]) == 4
    for t in TYPES:
        assert cols[f"a.y_{t}"] == [expected(t)] * 4, t
        # b keeps the start values
        start = {"String": "start", "Binary": "", "Enumeration": "1.0", "Boolean": "0.0"}.get(t, "0.0")
        assert cols[f"b.y_{t}"] == [start] * 4, t


def test_parameters_of_every_type_reach_the_fmu_from_the_scene_and_from_set(capsys, tmp_path, fmu):
    outputs = [f"a.p_{t}" for t in TYPES] + [f"b.p_{t}" for t in TYPES]
    params = ", ".join(f"p_{t} = {VALUES[t][0]}" for t in TYPES)
    f = scene(tmp_path, fmu, a_params=params, outputs=outputs)
    sets = [a for t in TYPES for a in ("--set", f"b.p_{t}={VALUES[t][0]}")]
    rc, out, err = run(capsys, tmp_path, f, *sets)
    assert rc == 0, err
    cols = columns(out)
    for t in TYPES:
        assert cols[f"a.p_{t}"][0] == expected(t), t
        assert cols[f"b.p_{t}"][0] == expected(t), t


@pytest.mark.parametrize("kind", INTEGERS)
def test_an_integer_parameter_out_of_its_types_range_is_refused_at_validation(capsys, tmp_path, fmu, kind):
    lo, hi = RANGES[kind]
    for value in (lo - 1, hi + 1):
        for where in ("scene", "set"):
            if where == "scene":
                f, extra, key = scene(tmp_path, fmu, a_params=f"p_{kind} = {value}"), [], f"p_{kind}"
            else:
                f, extra, key = scene(tmp_path, fmu), ["--set", f"a.p_{kind}={value}"], f"a.p_{kind}"
            for cmd in ("validate", "run"):
                argv = [cmd, f, *extra] + (["--out", tmp_path / "out", "--no-progress"] if cmd == "run" else [])
                rc, _, err = run_cli(capsys, argv)
                assert_one_line_error(rc, err, str(f), key, f"[{lo}, {hi}]", kind)
    assert not (tmp_path / "out").exists()
    # The bounds themselves pass.
    f = scene(tmp_path, fmu, a_params=f"p_{kind} = {lo}, u_{kind} = {hi}")
    rc, out, err = run(capsys, tmp_path, f)
    assert rc == 0, err
    assert columns(out)[f"a.y_{kind}"][0] == repr(float(hi))


@pytest.mark.parametrize("param, value, needle", [
    ("p_Float32", "1e39", "a Float32 value"), ("p_Binary", '"0g"', "hexadecimal"), ("p_Binary", '"abc"', "hexadecimal"),
    ("p_Binary", "12", "hexadecimal"), ("p_Int8", "1.5", "an integer"), ("p_Int64", "true", "an integer"),
    ("p_Boolean", "1", "true or false"), ("p_Enumeration", "4", "Mode"), ("p_String", "3", "a string")])
def test_a_parameter_of_the_wrong_kind_is_refused_at_validation(capsys, tmp_path, fmu, param, value, needle):
    f = scene(tmp_path, fmu, a_params=f"{param} = {value}")
    rc, _, err = run_cli(capsys, ["validate", f])
    assert_one_line_error(rc, err, str(f), param, needle)


SAME = [(f"a.y_{t}", f"b.u_{t}") for t in TYPES]
MIXED = [("a.y_Float32", "b.u_Float64"), ("a.y_Float64", "b.u_Float32"), ("a.y_Int8", "b.u_UInt64"),
         ("a.y_UInt8", "b.u_Int16"), ("a.y_Int32", "b.u_Enumeration"), ("a.y_Enumeration", "b.u_Int8"),
         ("a.y_UInt32", "b.u_Int64"), ("a.y_Int16", "b.u_Int32")]


@pytest.mark.parametrize("engine", ["auto", "python"])
def test_each_type_connects_to_itself(capsys, tmp_path, fmu, engine):
    params = ", ".join(f"u_{t} = {VALUES[t][0]}" for t in TYPES)
    f = scene(tmp_path, fmu, a_params=params, connections=[f"{s} -> {d}" for s, d in SAME],
              outputs=[f"b.y_{t}" for t in TYPES], engine=engine)
    rc, out, err = run(capsys, tmp_path, f)
    assert rc == 0, err
    cols = columns(out)
    for t in TYPES:
        assert cols[f"b.y_{t}"] == [expected(t)] * 4, t
    if engine == "auto":  # the compiled core passes Real values only: the Python engine, and why
        summary = json.dumps(json.loads((out / "summary.json").read_text()))
        assert "the compiled core passes Real connections only" in summary


def test_compatible_types_connect_and_carry_the_value(capsys, tmp_path, fmu):
    params = "u_Float32 = 0.1, u_Float64 = 0.25, u_Int8 = 5, u_UInt8 = 200, u_Int32 = 2, u_Enumeration = 3, " \
             "u_UInt32 = 4294967295, u_Int16 = -32768"
    f = scene(tmp_path, fmu, a_params=params, connections=[f"{s} -> {d}" for s, d in MIXED],
              outputs=[d.replace("b.u_", "b.y_") for _, d in MIXED])
    rc, out, err = run(capsys, tmp_path, f)
    assert rc == 0, err
    cols = columns(out)
    want = {"b.y_Float64": VALUES["Float32"][1], "b.y_Float32": "0.25", "b.y_UInt64": "5.0", "b.y_Int16": "200.0",
            "b.y_Enumeration": "2.0", "b.y_Int8": "3.0", "b.y_Int64": "4294967295.0", "b.y_Int32": "-32768.0"}
    for name, value in want.items():
        assert cols[name][-1] == value, name


@pytest.mark.parametrize("src, dst", [
    ("Boolean", "Int8"), ("Float32", "Int8"), ("Float64", "Int64"), ("Int32", "Float64"), ("String", "Binary"),
    ("Binary", "String"), ("Int8", "Boolean"), ("Enumeration", "Float32"), ("UInt64", "String")])
def test_incompatible_types_are_refused_at_validation(capsys, tmp_path, fmu, src, dst):
    f = scene(tmp_path, fmu, connections=[f"a.y_{src} -> b.u_{dst}"])
    for argv in (["validate", f], ["run", f, "--out", tmp_path / "out", "--no-progress"]):
        rc, _, err = run_cli(capsys, argv)
        assert_one_line_error(rc, err, str(f), "connections[0]", f"a.y_{src} is {src}", f"b.u_{dst} is {dst}")
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("src, dst, value", [("Int16", "Int8", 300), ("Int8", "UInt8", -1),
                                             ("UInt64", "Int64", 2**63), ("Int64", "UInt32", 2**32)])
def test_a_value_out_of_the_inputs_range_fails_the_run_naming_the_link(capsys, tmp_path, fmu, src, dst, value):
    f = scene(tmp_path, fmu, a_params=f"u_{src} = {value}", connections=[f"a.y_{src} -> b.u_{dst}"])
    rc, out, err = run(capsys, tmp_path, f)
    assert_one_line_error(rc, err, f"a.y_{src} -> b.u_{dst}", str(value), dst, code=1)
    assert not (out / "timeseries.csv").exists()


def test_the_compiled_engine_refuses_non_real_links_and_says_why(capsys, tmp_path, fmu):
    f = scene(tmp_path, fmu, connections=["a.y_Float32 -> b.u_Float64"], engine="compiled")
    rc, _, err = run_cli(capsys, ["validate", f])
    assert_one_line_error(rc, err, "the compiled core passes Real connections only",
                          "a.y_Float32 -> b.u_Float64 is Float32")


def test_array_variables_of_several_types_load_with_their_shapes_and_starts(capsys, tmp_path):
    """FMI 3.0 arrays (<Dimension>) of Float64, Int8, Boolean and String
    load: validate passes, info shows each shape and every start value (a
    String array's from its <Start> elements). tests/test_fmi3_arrays.py
    runs arrays."""
    fmu = test_fmu("fmi3/Arrays")  # fmi3_alltypes.ARRAYS in its description
    rc, _, err = run_cli(capsys, ["validate", scene(tmp_path, fmu)])
    assert rc == 0, err
    rc, out, err = run_cli(capsys, ["info", fmu])
    assert rc == 0, err
    rows = {line.split()[0]: line for line in out.splitlines() if line.startswith("  a_")}
    assert sorted(rows) == sorted(fmi3_alltypes.ARRAYS)
    for name, shape, start in (("a_Float64", "Float64[3]", None), ("a_Int8", "Int8[2]", "1 2"),
                               ("a_Boolean", "Boolean[1]", "true"), ("a_String", "String[2]", "x y")):
        assert shape in rows[name] and (start is None or start in rows[name]), rows[name]


def test_export_ssp_carries_every_type_and_reads_back(capsys, tmp_path, fmu):
    """An exported scene with links of every type (SSP 1.0 connectors: a
    Float32 is a Real, an Int8 an Integer) reads back and runs to the
    scene's numbers; a Binary parameter, which an SSP 1.0 parameter set
    cannot carry, is refused in one line naming the key."""
    params = ", ".join(f"u_{t} = {VALUES[t][0]}" for t in TYPES if t != "Binary")
    f = scene(tmp_path, fmu, a_params=params, connections=[f"{s} -> {d}" for s, d in SAME],
              outputs=[f"b.y_{t}" for t in TYPES])
    rc, out, err = run(capsys, tmp_path, f)
    assert rc == 0, err
    ssp = tmp_path / "s.ssp"
    rc, _, err = run_cli(capsys, ["export-ssp", f, "--out", ssp])
    assert rc == 0, err
    out2 = tmp_path / "out_ssp"
    rc, _, err = run_cli(capsys, ["run", ssp, "--out", out2, "--no-progress"])
    assert rc == 0, err
    scene_cols, ssp_cols = columns(out), columns(out2)
    for t in TYPES:
        assert ssp_cols[f"b.y_{t}"] == scene_cols[f"b.y_{t}"], t
    f = scene(tmp_path, fmu, a_params='p_Binary = "00ff"', name="binary.toml")
    rc, _, err = run_cli(capsys, ["export-ssp", f, "--out", tmp_path / "b.ssp"])
    assert_one_line_error(rc, err, str(f), "components.a.parameters.p_Binary", "SSP 1.0")
    assert not (tmp_path / "b.ssp").exists()


@pytest.mark.parametrize("kind, start, stop, want", [("Int8", -128, 127, ["-128.0", "-43.0", "42.0", "127.0"]),
                                                     ("UInt16", 0, 300, ["0.0", "100.0", "200.0", "300.0"]),
                                                     ("Float32", 0.5, 2.0, ["0.5", "1.0", "1.5", "2.0"])])
def test_a_sweep_axis_runs_over_fmi3_number_types(capsys, tmp_path, fmu, kind, start, stop, want):
    """start/stop/num axes take Float32 and integers of every size (integers on integer points)."""
    f = scene(tmp_path, fmu, outputs=[f"a.y_{kind}"])
    f.write_text(f.read_text() + f'[sweep]\naxes = [ {{ parameter = "a.u_{kind}", start = {start}, stop = {stop}, '
                                 f'num = 4 }} ]\n')
    rc, out, err = run(capsys, tmp_path, f)
    assert rc == 0, err
    points = [json.loads(p.read_text()) for p in (out / "points").glob("*.json")]
    assert len(points) == 4
    got = sorted(p["series"][f"a.y_{kind}"][-1] for p in points)
    assert got == [float(x) for x in want]
    assert sorted(p["point"][f"a.u_{kind}"] for p in points) == [float(x) for x in want]


def test_a_sweep_axis_out_of_an_integer_types_range_is_refused_at_validation(capsys, tmp_path, fmu):
    f = scene(tmp_path, fmu)
    f.write_text(f.read_text() + '[sweep]\naxes = [ { parameter = "a.u_Int8", start = 0, stop = 200, num = 3 } ]\n')
    rc, _, err = run_cli(capsys, ["validate", f])
    assert_one_line_error(rc, err, str(f), "[-128, 127]")
