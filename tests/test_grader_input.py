"""The grader's input: a signal given twice is bad input, a UTF-8 byte order
mark is read, and a big result is read as a stream."""

from __future__ import annotations

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
