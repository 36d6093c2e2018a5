"""Atomic result writers and the output-directory check (clockwork/results.py)."""

import hashlib
import json
import os

import numpy as np
import pytest

from clockwork.results import files as results
from clockwork.errors import UsageError
from clockwork.hashing import sha256_file
from clockwork.results.files import (
    check_output_dir,
    write_csv_atomic,
    write_json_atomic,
    write_text_atomic,
)


def leftovers(d):
    return [p.name for p in d.iterdir() if p.name.endswith(".part")]


def test_text_replaces_and_leaves_no_temp(tmp_path):
    f = tmp_path / "a.txt"
    write_text_atomic(f, "one\n")
    write_text_atomic(f, "two\n")
    assert f.read_text() == "two\n"
    assert leftovers(tmp_path) == []


def test_failed_write_keeps_old_file(tmp_path, monkeypatch):
    f = tmp_path / "a.txt"
    write_text_atomic(f, "old\n")

    def broken_fsync(fd):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(results.os, "fsync", broken_fsync)
    with pytest.raises(OSError):
        write_text_atomic(f, "new\n")
    assert f.read_text() == "old\n"
    assert leftovers(tmp_path) == []


def test_json_sorted_indented_numpy(tmp_path):
    f = tmp_path / "r.json"
    write_json_atomic(f, {"b": np.float64(0.1), "a": np.arange(3), "c": np.int64(7), "d": (1, 2)})
    text = f.read_text()
    assert text == json.dumps({"a": [0, 1, 2], "b": 0.1, "c": 7, "d": [1, 2]}, sort_keys=True, indent=2) + "\n"


@pytest.mark.parametrize("bad, written", [(float("nan"), None), (np.array([1.0, np.inf]), [1.0, None]),
                                          ({"x": -np.inf}, {"x": None}), ([np.float32("nan")], [None])])
def test_json_is_strict_nan_becomes_null(tmp_path, bad, written):
    f = tmp_path / "r.json"
    write_json_atomic(f, {"v": bad})
    text = f.read_text()
    for word in ("NaN", "Infinity"):
        assert word not in text

    def refuse(name):
        raise ValueError(name)

    assert json.loads(text, parse_constant=refuse) == {"v": written}
    assert leftovers(tmp_path) == []


def test_csv_round_trip_exact(tmp_path):
    rng = np.random.default_rng(1)
    t = np.linspace(0.0, 1.0, 101)
    x = rng.standard_normal(101) * 1e-7
    n = np.arange(101, dtype=np.int64)
    b = n % 2 == 0
    f = tmp_path / "r.csv"
    write_csv_atomic(f, ["time", "pendulum.phi", "pendulum.tick_count", "flag"], [t, x, n, b])
    lines = f.read_text().splitlines()
    assert lines[0] == "time,pendulum.phi,pendulum.tick_count,flag"
    assert len(lines) == 102
    cols = list(zip(*(ln.split(",") for ln in lines[1:])))
    assert np.array_equal(np.array([float(s) for s in cols[0]]), t)
    assert np.array_equal(np.array([float(s) for s in cols[1]]), x)  # bit-exact, not approximately
    assert cols[2][:3] == ("0", "1", "2") and cols[3][:2] == ("1", "0")
    assert lines[2].split(",")[0] == "0.01"  # shortest repr, not %.17g


def test_csv_checks(tmp_path):
    f = tmp_path / "r.csv"
    with pytest.raises(ValueError, match="different lengths"):
        write_csv_atomic(f, ["a", "b"], [np.zeros(3), np.zeros(4)])
    with pytest.raises(ValueError, match="2 header names for 1 columns"):
        write_csv_atomic(f, ["a", "b"], [np.zeros(3)])
    with pytest.raises(ValueError, match="newline"):
        write_csv_atomic(f, ["a\nb"], [np.zeros(3)])
    assert not f.exists()
    # FMI names may hold commas and quotes (a[1,2]): quoted as CSV fields.
    write_csv_atomic(f, ["time", "x.a[1,2]", 'x."q"'], [np.zeros(1), np.ones(1), ["a,b"]])
    assert f.read_text() == 'time,"x.a[1,2]","x.""q"""\n0.0,1.0,"a,b"\n'


def test_sha256_file(tmp_path):
    f = tmp_path / "x.bin"
    data = os.urandom(3 << 20)
    f.write_bytes(data)
    assert sha256_file(f) == hashlib.sha256(data).hexdigest()


def test_check_output_dir(tmp_path):
    d = tmp_path / "out"
    assert check_output_dir(d) == d and d.is_dir()
    assert check_output_dir(d) == d  # existing is fine
    assert check_output_dir(tmp_path / "no" / "out").is_dir()  # parents are created
    with pytest.raises(UsageError, match="empty"):
        check_output_dir("")
    (tmp_path / "file").write_text("x")
    with pytest.raises(UsageError, match="not a directory"):
        check_output_dir(tmp_path / "file")
    with pytest.raises(UsageError, match="is a file, not a directory"):
        check_output_dir(tmp_path / "file" / "below" / "out")
    assert leftovers(d) == []


@pytest.mark.skipif(os.geteuid() == 0, reason="root can write into a read-only directory")
def test_check_output_dir_unwritable(tmp_path):
    d = tmp_path / "ro"
    d.mkdir()
    d.chmod(0o500)
    try:
        with pytest.raises(UsageError, match="not writable"):
            check_output_dir(d)
        with pytest.raises(UsageError, match="cannot create"):
            check_output_dir(d / "sub")
    finally:
        d.chmod(0o700)


def test_check_output_dir_permission_errors_simulated(tmp_path, monkeypatch):
    # The chmod tests above are skipped as root; this exercises the same paths by faking EACCES.
    d = tmp_path / "d"
    d.mkdir()

    def denied(*args, **kwargs):
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(results.tempfile, "mkstemp", denied)
    with pytest.raises(UsageError, match=r"output directory .*d is not writable: Permission denied"):
        check_output_dir(d)
    monkeypatch.setattr(type(d), "mkdir", denied)
    with pytest.raises(UsageError, match=r"cannot create output directory .*sub: Permission denied"):
        check_output_dir(d / "sub")


@pytest.mark.parametrize("shape", ["random", "increasing", "steps", "two points"])
def test_pchip_is_scipys_pchip(shape):
    """The headlines' own PCHIP (no scipy.interpolate at start-up) against
    scipy's PchipInterpolator: flat pieces, extrema, two points, and the
    end pieces continued outside the nodes."""
    from scipy.interpolate import PchipInterpolator

    from clockwork.results.headlines.pchip import pchip

    rng = np.random.default_rng(7)
    for _ in range(40):
        n = 2 if shape == "two points" else int(rng.integers(3, 25))
        x = np.cumsum(rng.uniform(0.01, 2.0, n))
        y = {"random": rng.normal(size=n), "increasing": np.cumsum(rng.uniform(0, 1, n)),
             "steps": np.round(rng.normal(size=n)), "two points": rng.normal(size=n)}[shape]
        at = np.linspace(x[0] - 0.5, x[-1] + 0.5, 301)
        want = PchipInterpolator(x, y)(at)
        got = pchip(x, y, at)
        assert np.max(np.abs(got - want) / (1.0 + np.abs(want))) < 1e-13
        assert pchip(x, y, float(x[1])) == pytest.approx(y[1], rel=1e-15, abs=1e-15)


def test_a_csv_is_written_a_slice_at_a_time(tmp_path):
    """The text of a result CSV is never whole in memory: the strings of every
    value, then the lines, then the text, then its bytes cost about 100
    bytes per recorded value on top of the values (1.9e7 values: 2.6 GB
    where the bound said 640 MB). Same bytes as the text made whole."""
    import tracemalloc

    from clockwork.results.report import _Numbers

    n, width = 50_000, 20
    columns = [[k * 0.001 + j / 7 for k in range(n)] for j in range(width)]
    columns[3][5] = None  # recorded before the first read: written as nan
    tracemalloc.start()
    try:
        results.write_csv_atomic(tmp_path / "a.csv", [f"c{j}" for j in range(width)],
                                 [_Numbers(c) for c in columns])
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 16e6, peak  # 65,536 values' text at a time (about 11 MB); before: 1e6 values' text, 150 MB
    whole = [",".join(f"c{j}" for j in range(width))]
    whole += [",".join("nan" if c[k] is None else repr(c[k]) for c in columns) for k in range(n)]
    assert (tmp_path / "a.csv").read_text() == "\n".join(whole) + "\n"


def test_a_json_file_is_written_a_slice_at_a_time(tmp_path):
    """A sweep point's series went to points/<key>.json as one text, then
    its bytes: about 150 bytes per value on top of the values. The same
    bytes as json_text, written a MiB at a time."""
    import tracemalloc

    obj = {"series": {f"c{j}": [k * 0.001 + j / 7 for k in range(50_000)] for j in range(4)},
           "result": {"x": float("nan"), "y": np.float64(2.5)}}
    tracemalloc.start()
    try:
        results.write_json_atomic(tmp_path / "p.json", obj)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert (tmp_path / "p.json").read_text() == results.json_text(obj)
    assert peak < 12e6, peak  # the copies of the lists (16 bytes a value) and a MiB of text; before: 30 MB
