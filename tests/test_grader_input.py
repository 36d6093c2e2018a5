"""The grader's input: a signal given twice is bad input, a UTF-8 byte order
mark is read, and a big result is read as a stream."""

from __future__ import annotations

import math
import subprocess
import sys

import pytest

from cwtest import FMU_DIR, ROOT, assert_one_line_error, fmu_file, run_cli
from clockwork import cli


@pytest.fixture(scope="module")
def ref(tmp_path_factory):
    """The GrasshopperClock case's reference: a result that passes."""
    import os

    fmu_file("Pendulum")
    os.environ["CLOCKWORK_FMU_DIR"] = str(FMU_DIR)
    d = tmp_path_factory.mktemp("kit") / "suite"
    assert cli.main(["export-suite", str(d), "--case", "GrasshopperClock"]) == 0 or \
        cli.main(["export-suite", str(d)]) == 0
    return next(d.rglob("GrasshopperClock_ref.csv"))


def _with_wrong_copy(ref, tmp_path, first: str, second: str, sep: str = ","):
    """`first` (a wrong copy of pendulum.phi: all zeros) before the real columns, renamed `second`."""
    lines = ref.read_text().splitlines()
    header = lines[0].split(",")
    header[1] = second
    out = [sep.join([header[0], first] + header[1:])]
    for ln in lines[1:]:
        c = ln.split(",")
        out.append(sep.join([c[0], "0.0"] + c[1:]))
    f = tmp_path / "dup.csv"
    f.write_text("\n".join(out) + "\n")
    return f


DUPLICATES = {
    "the same name": ("pendulum.phi", "pendulum.phi", ","),
    "quoted": ('"pendulum.phi"', "pendulum.phi", ","),
    "ecos' :: for .": ("pendulum::phi", "pendulum.phi", ","),
    "libcosim's bracket": ("pendulum.phi [0 Real OUT]", "pendulum.phi", ","),
    "semicolons": ("pendulum.phi", "pendulum.phi", ";"),
    "two suffix matches": ("model.root.pendulum.phi", "pendulum.phi", ","),
    "two longer suffix matches": ("a.pendulum.phi", "b.pendulum.phi", ","),
}


@pytest.mark.parametrize("case", list(DUPLICATES))
def test_a_signal_given_twice_is_bad_input(capsys, tmp_path, ref, case):
    f = _with_wrong_copy(ref, tmp_path, *DUPLICATES[case])
    rc, out, err = run_cli(capsys, ["compare", f, "GrasshopperClock"])
    assert_one_line_error(rc, err, str(f), "phi", code=2)
    assert "PASS" not in out


def test_a_signal_in_two_files_of_a_libcosim_directory_is_bad_input(capsys, tmp_path, ref):
    d = tmp_path / "cosim"
    d.mkdir()
    text = ref.read_text()
    (d / "a.csv").write_text(text)
    (d / "b.csv").write_text(text.replace("escapement.tau", "escapement.x"))
    rc, _, err = run_cli(capsys, ["compare", d, "GrasshopperClock"])
    assert_one_line_error(rc, err, "pendulum.phi", code=2)


def test_the_report_quotes_a_file_name_with_escape_bytes_escaped(capsys, tmp_path, ref):
    f = tmp_path / "r\x1b]0;x\x07.csv"
    f.write_text(ref.read_text())
    rc, out, err = run_cli(capsys, ["compare", f, "GrasshopperClock"])
    assert rc == 0 and "PASS" in out and "\x1b" not in out and "\x07" not in out, (out, err)
    assert r"r\x1b]0;x\x07.csv" in out


@pytest.mark.parametrize("sep", [",", ";"])
def test_a_byte_order_mark_is_read(capsys, tmp_path, ref, sep):
    rc, plain, _ = run_cli(capsys, ["compare", ref, "GrasshopperClock"])
    assert rc == 0 and plain.strip().endswith("PASS")
    f = tmp_path / "excel.csv"
    f.write_bytes(b"\xef\xbb\xbf" + ref.read_text().replace(",", sep).encode())
    rc, out, err = run_cli(capsys, ["compare", f, "GrasshopperClock"])
    assert rc == 0 and err == "", err
    assert out.replace(str(f), "X") == plain.replace(str(ref), "X")


_MEASURE = """
import resource, sys
from clockwork.kit.csvio import read_result
before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
r = read_result(sys.argv[1])
after = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
print(len(r.time), (after - before) // 1024)
"""


def test_a_big_result_is_read_as_a_stream(tmp_path):
    """Memory grows with the numbers (8 bytes each), not with the text."""
    rows, cols = 600_000, 4
    f = tmp_path / "big.csv"
    with open(f, "w") as out:
        out.write("time,pendulum.phi,pendulum.w,escapement.tau\n")
        line = ",0.10471975511965977,-0.010292407252460367,-0.004\n"
        out.writelines(f"{k * 1e-4!r}{line}" for k in range(rows))
    text_mib = f.stat().st_size / 2**20
    numbers_mib = rows * cols * 8 / 2**20
    r = subprocess.run([sys.executable, "-c", _MEASURE, str(f)], capture_output=True, text=True,
                       env={"PYTHONPATH": str(ROOT), "PATH": "/usr/bin:/bin"})
    assert r.returncode == 0, r.stderr
    n, grown_mib = map(int, r.stdout.split())
    assert n == rows
    assert text_mib > 30 and grown_mib < 3 * numbers_mib + 8, (grown_mib, numbers_mib, text_mib)


# --- what the csv module refuses, and number syntax only Python has ---------------------


def _with_field(ref, tmp_path, row: int, field: str, name: str = "r.csv"):
    """The reference with pendulum.phi of data row `row` replaced by `field`."""
    lines = ref.read_text().splitlines()
    cells = lines[row].split(",")
    cells[1] = field
    lines[row] = ",".join(cells)
    f = tmp_path / name
    f.write_text("\n".join(lines) + "\n")
    return f


LINES_THE_CSV_MODULE_REFUSES = {
    "a field over the csv module's limit": "1" * 140_000,
    "a NUL byte": "0.1\x000",
    "a line over the line bound": "1," * 600_000,
    "a quoted field over the limit": '"' + "2" * 140_000 + '"',
}


@pytest.mark.parametrize("case", list(LINES_THE_CSV_MODULE_REFUSES))
def test_a_line_the_csv_module_refuses_is_one_line(capsys, tmp_path, ref, case):
    f = _with_field(ref, tmp_path, 5, LINES_THE_CSV_MODULE_REFUSES[case])
    rc, _, err = run_cli(capsys, ["compare", f, "GrasshopperClock"])
    assert_one_line_error(rc, err, str(f), "line 6")
    assert len(err) < 400, err  # the field is not echoed whole


def test_a_header_over_the_line_bound_is_one_line(capsys, tmp_path):
    f = tmp_path / "wide.csv"
    f.write_text("time," + ",".join(f"c{k}" for k in range(200_000)) + "\n0," + "0," * 199_999 + "0\n")
    rc, _, err = run_cli(capsys, ["compare", f, "GrasshopperClock"])
    assert_one_line_error(rc, err, str(f), "line 1")


# What float() reads and no CSV writer writes: each would be graded as some other number.
PYTHON_ONLY_NUMBERS = ["0.17_45", "1_0", "1e1_0", "\uff11", "\u0661.\u0665", "0.1\u00a0", "\u2007" + "1",
                       "1e999", "-1e400", "9" * 400]


@pytest.mark.parametrize("text", PYTHON_ONLY_NUMBERS, ids=[ascii(t)[:16] for t in PYTHON_ONLY_NUMBERS])
def test_number_syntax_only_python_has_is_refused(capsys, tmp_path, ref, text):
    float(text)  # Python reads it
    f = _with_field(ref, tmp_path, 3, text)
    rc, _, err = run_cli(capsys, ["compare", f, "GrasshopperClock"])
    assert_one_line_error(rc, err, str(f), "line 4", "column 2")


@pytest.mark.parametrize("text", [" 0.1", "0.1 ", '"0.1"', "nan", "NaN", "-inf", "Infinity", "1E-3", "+.5"])
def test_what_csv_writers_write_is_read(tmp_path, ref, text):
    from clockwork.kit.csvio import read_result

    f = _with_field(ref, tmp_path, 3, text)
    r = read_result(f)
    v = r.columns["pendulum.phi"][2]
    assert str(v) == str(float(text.strip().strip('"')))


# --- the case file: strict JSON, each field of its type ----------------------------------

CASE_EDITS = {
    "NaN tolerance": ('"pendulum.phi": 1e-09', '"pendulum.phi": NaN', "JSON"),
    "Infinity tolerance": ('"ticks_s": 1e-09', '"ticks_s": Infinity', "JSON"),
    "-Infinity": ('"ticks_s": 1e-09', '"ticks_s": -Infinity', "JSON"),
    "a number beyond a double": ('"ticks_s": 1e-09', '"ticks_s": 1e999', "double"),
    "a key given twice": ('"ticks_s": 1e-09', '"ticks_s": 1e-09, "ticks_s": 1', "twice"),
    "a tolerance as a string": ('"ticks_s": 1e-09', '"ticks_s": "1e-09"', "tolerances.ticks_s"),
    "Python's 1_0 in a string": ('"pendulum.phi": 1e-09', '"pendulum.phi": "1_0"', "tolerances.tube.pendulum.phi"),
    "a tolerance of 0": ('"pendulum.w": 1e-09', '"pendulum.w": 0', "tolerances.tube.pendulum.w"),
    "a negative tolerance": ('"switches_s": 1e-05', '"switches_s": -1e-05', "tolerances.switches_s"),
    "a boolean tolerance": ('"ticks_s": 1e-09', '"ticks_s": true', "tolerances.ticks_s"),
    "a null tolerance": ('"ticks_s": 1e-09', '"ticks_s": null', "tolerances.ticks_s"),
    "a stop that is a list": ('"stop": 100.0', '"stop": [100.0]', "stop"),
    "a tick time as a string": ('"ticks": [', '"ticks": ["1_0", ', "events.ticks"),
    "no tube": ('"tube": {', '"tube_": {', "tolerances.tube"),
    "a signal name as a number": ('"phi": "pendulum.phi"', '"phi": 3', "signals.phi"),
}


@pytest.fixture
def case_dir(ref, tmp_path):
    import shutil

    d = tmp_path / "case"
    shutil.copytree(ref.parent, d)
    return d


@pytest.mark.parametrize("edit", list(CASE_EDITS))
def test_a_case_file_is_read_strictly(capsys, tmp_path, ref, case_dir, edit):
    old, new, needle = CASE_EDITS[edit]
    f = next(case_dir.glob("*_case.json"))
    text = f.read_text()
    assert old in text, old
    f.write_text(text.replace(old, new, 1))
    rc, out, err = run_cli(capsys, ["compare", ref, case_dir])
    assert_one_line_error(rc, err, str(f), needle)
    assert "PASS" not in out


def test_the_unedited_case_file_passes_its_own_reference(capsys, ref, case_dir):
    rc, out, err = run_cli(capsys, ["compare", ref, case_dir])
    assert rc == 0 and out.strip().endswith("verdict: PASS"), (out, err)


@pytest.mark.parametrize("tolerance, worst", [(math.nan, 0.1), (0.1, math.nan), (math.inf, 0.1)])
def test_nan_never_passes_a_check(tolerance, worst):
    from clockwork.kit.grade import Check

    assert not Check("tube x", tolerance, worst, True).ok


def test_a_nan_tube_width_fails_the_tube(ref):
    """The case computed in memory with a NaN width: the tube fails (it used
    to pass a result 50 % off, since nothing lies outside a NaN band)."""
    from clockwork.kit.csvio import read_result
    from clockwork.kit.grade import grade, load_case

    case = load_case(ref.parent)
    case.tolerances["tube"] = {s: math.nan for s in case.tolerances["tube"]}
    result = read_result(ref)
    result.columns = {k: v * 1.5 for k, v in result.columns.items()}
    g = grade(result, case)
    tubes = [c for c in g.checks if c.what.startswith("tube")]
    assert tubes and not any(c.ok for c in tubes) and not g.passed


# --- an output file that cannot be one ---------------------------------------------------

@pytest.mark.parametrize("how", ["an existing directory", "a missing directory", "empty"])
def test_compare_json_into_what_is_no_file_is_one_line(capsys, tmp_path, ref, how):
    target = {"an existing directory": tmp_path / "d", "a missing directory": tmp_path / "nope" / "g.json",
              "empty": ""}[how]
    (tmp_path / "d").mkdir()
    rc, _, err = run_cli(capsys, ["compare", ref, "GrasshopperClock", "--json", target])
    assert_one_line_error(rc, err, "--json")
    assert ".part" not in err
    assert not [p for p in tmp_path.rglob("*") if p.name.endswith(".part")]
    assert not list((tmp_path / "d").iterdir())


def test_export_ssp_onto_a_directory_is_one_line(capsys, tmp_path):
    (tmp_path / "x.ssp").mkdir()
    rc, _, err = run_cli(capsys, ["export-ssp", "core_grasshopper", "--out", tmp_path / "x.ssp"])
    assert_one_line_error(rc, err, "--out", "directory")
    assert ".part" not in err and not list((tmp_path / "x.ssp").iterdir())


def test_a_failed_rename_names_the_target_not_the_part_file(tmp_path):
    from clockwork.atomic import write_text_atomic

    (tmp_path / "d").mkdir()
    with pytest.raises(OSError) as e:
        write_text_atomic(tmp_path / "d", "x")
    assert e.value.filename == str(tmp_path / "d") and ".part" not in str(e.value)
    assert not [p for p in tmp_path.rglob("*.part")]
