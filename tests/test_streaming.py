"""A run's series written to disk as the run goes (results.series), in
every format asked for: the same numbers in each, memory that does not
grow with the run's length, and a full disk that leaves nothing behind."""

from __future__ import annotations

import csv
import json
import os
import resource
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from cwtest import CLOCK_SCENE, FMU_DIR, assert_one_line_error, fmu_file, run_cli, test_fmu


@pytest.fixture(autouse=True)
def _env(monkeypatch, tmp_path):
    fmu_file("Pendulum")
    monkeypatch.setenv("CLOCKWORK_FMU_DIR", str(FMU_DIR))
    monkeypatch.setenv("CLOCKWORK_CACHE", str(tmp_path / "cache"))


def _scene(tmp_path, stop=2.0, edit=lambda s: s):
    f = tmp_path / "s.toml"
    f.write_text(edit(CLOCK_SCENE.format(stop=stop, sweep="")))
    return f


def _read_csv(path: Path) -> tuple[list[str], list[list[str]]]:
    with open(path, newline="", encoding="utf-8") as f:
        rows = list(csv.reader(f))
    return rows[0], [list(c) for c in zip(*rows[1:])] if len(rows) > 1 else [[] for _ in rows[0]]


def _bits(values) -> np.ndarray:
    return np.asarray(values, dtype=np.float64).view(np.int64)


def _numeric(fields: list[str]) -> bool:
    try:
        [float(x) for x in fields]
    except ValueError:
        return False
    return True


def assert_formats_equal_the_csv(out: Path, text_columns=()) -> None:
    """Each format read back holds the CSV's numbers to the bit (and its text)."""
    header, cols = _read_csv(out / "timeseries.csv")
    import pyarrow.parquet as pq

    table = pq.read_table(out / "timeseries.parquet")
    assert table.schema.names == header
    for name, col in zip(header, cols):
        got = table.column(name).to_pylist()
        if name in text_columns:
            assert [x or "" for x in got] == col, name
        else:
            assert np.array_equal(_bits([float(x) for x in col]), _bits(got)), name
    from scipy.io import loadmat

    mat = loadmat(out / "timeseries.mat", chars_as_strings=False)
    assert ["".join(r).rstrip() for r in mat["Aclass"]] == ["Atrajectory", "1.1", "", "binTrans"]
    names = ["".join(c).rstrip() for c in zip(*mat["name"])]
    numeric = [n for n in header if n not in text_columns]
    assert names == numeric
    info = mat["dataInfo"]
    assert info.shape == (4, len(names)) and list(info[:, 0]) == [0, 1, 0, -1]
    assert list(info[0, 1:]) == [2] * (len(names) - 1) and list(info[1, 1:]) == list(range(2, len(names) + 1))
    data = mat["data_2"]
    assert data.shape == (len(names), len(cols[0]))
    for k, name in enumerate(names):
        assert np.array_equal(_bits([float(x) for x in cols[header.index(name)]]), _bits(data[k])), name
    if cols[0]:
        assert list(mat["data_1"][0]) == [float(cols[0][0]), float(cols[0][-1])]


def _dymat_check(out: Path, header: list[str], units: dict[str, str]) -> None:
    DyMat = pytest.importorskip("DyMat")  # a Modelica result reader, where installed
    d = DyMat.DyMatFile(str(out / "timeseries.mat"))
    _, cols = _read_csv(out / "timeseries.csv")
    assert sorted(d.names()) == sorted(header[1:])
    for name, unit in units.items():
        assert d.description(name).endswith(f"[{unit}]"), (name, d.description(name))
    for name in header[1:]:
        assert np.array_equal(_bits(d.data(name)), _bits([float(x) for x in cols[header.index(name)]]))
    assert d.abscissa(header[1])[1] == "time"


FORMATS = ["--format", "csv,parquet", "--format", "mat"]


@pytest.mark.parametrize("engine", ["compiled", "python"])
def test_a_scene_in_every_format_holds_the_csvs_numbers(capsys, tmp_path, engine):
    pytest.importorskip("pyarrow")
    # 20 s at every 0.01 s step, ticks too: several chunks of rows, rows at located events
    f = _scene(tmp_path, stop=20.0, edit=lambda s: s.replace('outputs = ["pendulum.phi"]',
                                                             'outputs = ["pendulum.phi", "escapement.tau"]'))
    rc, out, err = run_cli(capsys, ["run", f, "--out", tmp_path / "out", "--no-progress", "--no-plot",
                                    "--set", f"master.engine={engine}", *FORMATS])
    assert rc == 0, err
    o = tmp_path / "out"
    assert json.loads((o / "summary.json").read_text())["files"][:3] == \
        ["timeseries.csv", "timeseries.parquet", "timeseries.mat"]
    assert_formats_equal_the_csv(o)
    header, cols = _read_csv(o / "timeseries.csv")
    assert len(cols[0]) > 2000
    _dymat_check(o, header, {"pendulum.phi": "rad", "escapement.tau": "N.m"})
    assert sorted(p.name for p in o.iterdir()) == ["summary.json", "ticks.csv", "timeseries.csv", "timeseries.mat",
                                                   "timeseries.parquet"]


def test_an_fmu_alone_in_every_format_holds_the_csvs_numbers(capsys, tmp_path):
    pytest.importorskip("pyarrow")
    rc, _, err = run_cli(capsys, ["run", fmu_file("Pendulum"), "--out", tmp_path / "out", "--no-progress",
                                  "--no-plot", *FORMATS])
    assert rc == 0, err
    assert_formats_equal_the_csv(tmp_path / "out")


@pytest.mark.parametrize("model", ["every type", "arrays"])
def test_fmi3_fmus_of_every_type_and_arrays_in_every_format(capsys, tmp_path, model):
    """FMI 3.0: an output of every type (Integer and Boolean columns, String
    and Binary as text: in Parquet, left out of MAT), and arrays element by element."""
    pytest.importorskip("pyarrow")
    fmu = test_fmu("fmi3/Linear" if model == "arrays" else "fmi3/AllTypes")
    rc, _, err = run_cli(capsys, ["run", fmu, "--out", tmp_path / "out", "--no-progress", "--no-plot",
                                  "--set", "experiment.stop=1", *FORMATS])
    assert rc == 0, err
    header, cols = _read_csv(tmp_path / "out" / "timeseries.csv")
    text = {n for n, c in zip(header, cols) if not _numeric(c)}
    if model == "arrays":
        assert any("[" in n for n in header) and not text
    else:
        assert any("Int8" in n for n in header) and any("Boolean" in n for n in header)
        assert text and all("String" in n or "Binary" in n for n in text)
    assert_formats_equal_the_csv(tmp_path / "out", text_columns=text)


def test_only_parquet_writes_no_csv_and_leaves_no_hidden_file(capsys, tmp_path):
    pytest.importorskip("pyarrow")
    f = _scene(tmp_path)
    rc, _, err = run_cli(capsys, ["run", f, "--out", tmp_path / "out", "--no-progress", "--format", "parquet"])
    assert rc == 0, err
    names = sorted(p.name for p in (tmp_path / "out").iterdir())
    assert "timeseries.parquet" in names and "timeseries.csv" not in names
    assert not [n for n in names if n.startswith(".")]


def test_record_format_is_a_scene_key(capsys, tmp_path):
    f = _scene(tmp_path, edit=lambda s: s.replace("[record]", '[record]\nformat = ["mat", "csv"]'))
    rc, _, err = run_cli(capsys, ["run", f, "--out", tmp_path / "out", "--no-progress", "--no-plot"])
    assert rc == 0, err
    assert (tmp_path / "out" / "timeseries.mat").is_file() and (tmp_path / "out" / "timeseries.csv").is_file()
    rc, _, err = run_cli(capsys, ["run", f, "--out", tmp_path / "out2", "--no-progress", "--no-plot",
                                  "--set", "record.format=csv"])
    assert rc == 0, err
    assert not (tmp_path / "out2" / "timeseries.mat").exists()


@pytest.mark.parametrize("value", ['"hdf5"', '["csv", "xlsx"]', "3", "[]", '""'])
def test_an_unknown_record_format_is_one_line(capsys, tmp_path, value):
    f = _scene(tmp_path, edit=lambda s: s.replace("[record]", f"[record]\nformat = {value}"))
    for argv in (["validate", f], ["run", f, "--out", tmp_path / "out", "--no-progress"]):
        rc, _, err = run_cli(capsys, argv)
        assert_one_line_error(rc, err, "record.format", "csv, parquet, mat", code=2)
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("given", ["hdf5", "csv,xlsx", "", "CSV;mat"])
def test_an_unknown_format_option_is_one_line(capsys, tmp_path, given):
    rc, _, err = run_cli(capsys, ["run", _scene(tmp_path), "--out", tmp_path / "out", "--format", given])
    assert_one_line_error(rc, err, "--format", "csv, parquet, mat", code=2)
    assert not (tmp_path / "out").exists()


def test_parquet_without_pyarrow_says_how_to_install_it_before_the_run(capsys, tmp_path, monkeypatch):
    for name in ("pyarrow", "pyarrow.parquet"):
        monkeypatch.setitem(sys.modules, name, None)  # import fails as if not installed
    f = _scene(tmp_path)
    rc, _, err = run_cli(capsys, ["run", f, "--out", tmp_path / "out", "--format", "csv,parquet"])
    assert_one_line_error(rc, err, "pip install", "clockwork[parquet]", code=2)
    assert not (tmp_path / "out").exists()
    f2 = _scene(tmp_path, edit=lambda s: s.replace("[record]", '[record]\nformat = "parquet"'))
    for argv in (["run", f2, "--out", tmp_path / "out", "--no-progress"], ["validate", f2]):
        rc, _, err = run_cli(capsys, argv)
        assert_one_line_error(rc, err, "pip install", code=2)
    assert not (tmp_path / "out").exists()


def _leftovers(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.rglob("*") if p.name.startswith(".") or p.name.endswith(".part"))


def test_a_full_disk_during_the_run_is_one_line_and_keeps_the_earlier_result(capsys, tmp_path, monkeypatch):
    import errno

    from clockwork.results import series

    f = _scene(tmp_path, stop=20.0)
    o = tmp_path / "out"
    rc, _, err = run_cli(capsys, ["run", f, "--out", o, "--no-progress", "--no-plot", "--format", "csv,mat"])
    assert rc == 0, err
    before = {p.name: p.read_bytes() for p in o.iterdir()}
    written = {"n": 0}
    put = series.SeriesWriter._put

    class Full:  # a file whose disk fills after 20 kB: write() fails as the system's would
        def __init__(self, f):
            self.f = f

        def write(self, data):
            written["n"] += len(data)
            if written["n"] > 20_000:
                raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
            return self.f.write(data)

    def full(fobj, path, data):
        put(Full(fobj), path, data)

    monkeypatch.setattr(series.SeriesWriter, "_put", staticmethod(full))
    rc, _, err = run_cli(capsys, ["run", f, "--out", o, "--no-progress", "--no-plot", "--format", "csv,mat",
                                  "--set", "pendulum.Q=900"])
    assert_one_line_error(rc, err, "No space left on device", str(o / "timeseries."), code=1)
    assert ".staging" not in err
    assert {p.name: p.read_bytes() for p in o.iterdir()} == before  # the earlier result, whole
    assert _leftovers(o) == []


def test_a_file_size_limit_in_a_child_is_one_line_and_leaves_nothing(tmp_path):
    """The kernel's own refusal (RLIMIT_FSIZE: EFBIG) in a real process."""
    f = _scene(tmp_path, stop=300.0)
    o = tmp_path / "out"

    def limit():
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # a write past the limit fails with EFBIG instead
        resource.setrlimit(resource.RLIMIT_FSIZE, (200_000, 200_000))

    r = subprocess.run([sys.executable, "-m", "clockwork", "run", str(f), "--out", str(o), "--no-progress",
                        "--no-plot"], capture_output=True, text=True, preexec_fn=limit,
                       env={**os.environ, "CLOCKWORK_CACHE": "off"})
    assert r.returncode == 1, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "File too large" in lines[0] and "timeseries.csv" in lines[0], r.stderr
    assert "Traceback" not in r.stderr
    assert sorted(p.name for p in o.iterdir()) == []  # no result, no staging folder, no .part


def test_a_run_killed_while_it_records_leaves_no_series_file(tmp_path):
    """SIGKILL mid-run: the series files are unnamed until complete (O_TMPFILE),
    so nothing of them is left; the next run into the directory is clean."""
    import time

    f = _scene(tmp_path, stop=5000.0, edit=lambda s: s.replace('ticks = "pendulum"', ""))
    o = tmp_path / "out"
    p = subprocess.Popen([sys.executable, "-m", "clockwork", "run", str(f), "--out", str(o), "--no-progress",
                          "--no-plot", "--format", "csv,parquet,mat"], stdout=subprocess.DEVNULL,
                         stderr=subprocess.DEVNULL, env={**os.environ, "CLOCKWORK_CACHE": "off"})
    try:
        deadline = time.monotonic() + 60
        # rows are being written once the process has open files in the staging folder
        while time.monotonic() < deadline:
            fds = Path(f"/proc/{p.pid}/fd")
            try:
                if any(".staging" in os.readlink(x) for x in fds.iterdir()):
                    break
            except OSError:
                pass
            time.sleep(0.05)
        time.sleep(0.5)
        assert p.poll() is None
    finally:
        p.kill()
        p.wait()
    left = [q for q in o.rglob("*") if not q.is_dir()]
    assert left == []
    f.write_text(CLOCK_SCENE.format(stop=1.0, sweep=""))
    r = subprocess.run([sys.executable, "-m", "clockwork", "run", str(f), "--out", str(o), "--no-progress",
                        "--no-plot"], capture_output=True, text=True, env={**os.environ, "CLOCKWORK_CACHE": "off"})
    assert r.returncode == 0, r.stderr
    assert sorted(q.name for q in o.iterdir()) == ["summary.json", "timeseries.csv"]  # no staging folder


def test_a_series_the_disk_cannot_hold_is_refused_before_the_run(capsys, tmp_path, monkeypatch):
    real = os.statvfs

    class Small:
        def __init__(self, st):
            self.f_frsize, self.f_bavail = st.f_frsize, 10

    monkeypatch.setattr(os, "statvfs", lambda p: Small(real(p)))
    f = _scene(tmp_path, stop=100.0)
    rc, _, err = run_cli(capsys, ["run", f, "--out", tmp_path / "out", "--no-progress", "--no-plot"])
    assert_one_line_error(rc, err, "MB free", "record.interval", "experiment.stop", code=2)
    assert [p.name for p in (tmp_path / "out").iterdir()] == []


def test_a_long_recording_is_no_longer_bound_by_memory(capsys, tmp_path):
    """More values than the 2e7 kept in memory: accepted by validate (a run
    checks the disk instead); a sweep's points are still kept in memory."""
    f = _scene(tmp_path, stop=3e5, edit=lambda s: s.replace('ticks = "pendulum"', ""))
    rc, out, err = run_cli(capsys, ["validate", f])
    assert rc == 0 and out.startswith("ok"), err
    sweep = '\n[sweep]\naxes = [ { parameter = "pendulum.Q", values = [500, 1000] } ]\n'
    f.write_text(CLOCK_SCENE.format(stop=3e5, sweep=sweep).replace('ticks = "pendulum"', ""))
    rc, _, err = run_cli(capsys, ["validate", f])
    assert_one_line_error(rc, err, "values in memory", code=2)


@pytest.mark.parametrize("engine", ["compiled", "python"])
def test_the_recorder_keeps_at_most_a_chunk(tmp_path, engine, monkeypatch):
    """Memory does not grow with the run: the recorder hands rows on a
    chunk at a time (the compiled core's buffer at most beside it)."""
    from clockwork.analyses import context, time_series
    from clockwork.engine import recording
    from clockwork.run.catalog import load_scene

    monkeypatch.setattr(recording, "CHUNK_VALUES", 500)
    kept, got = [], []

    class Sink:
        def write(self, columns):
            kept.append(len(columns[0]))
            got.append([list(c) for c in columns])

        def close(self):
            return {"written": sum(kept)}

        def abort(self):
            raise AssertionError("not aborted")

    scene = load_scene(_scene(tmp_path, stop=10.0), [f"master.engine={engine}"], streamed=True)
    with context.streaming_series(lambda names, text: Sink()):
        r = time_series.time_series(scene, {})
    assert r["series"] == {"written": sum(kept)} and sum(kept) >= 1000
    from clockwork.engine.compiled import ROWS_PER_CALL

    assert max(kept) <= 250 + ROWS_PER_CALL
    plain = time_series.time_series(load_scene(_scene(tmp_path, stop=10.0), [f"master.engine={engine}"]), {})
    assert [sum((g[0] for g in got), [])] == [plain["series"]["time"]]


def test_a_sweep_asked_for_a_format_says_it_writes_its_points_as_before(capsys, tmp_path):
    sweep = '\n[sweep]\naxes = [ { parameter = "pendulum.Q", values = [500, 1000] } ]\n'
    f = tmp_path / "s.toml"
    f.write_text(CLOCK_SCENE.format(stop=1.0, sweep=sweep))
    rc, _, err = run_cli(capsys, ["run", f, "--out", tmp_path / "out", "--no-progress", "--no-plot",
                                  "--format", "mat", "--workers", "1"])
    assert rc == 0, err
    assert err.count("\n") == 1 and "clockwork: warning: --format" in err and "points/" in err
    assert len(list((tmp_path / "out" / "points").glob("*.json"))) == 2
    assert not list((tmp_path / "out").glob("timeseries.*"))
