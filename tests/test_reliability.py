"""A stranger's first hour: sweeps over every documented axis, a killed sweep
resumed, damaged points and cache entries, the temporary directory left
clean, and scenes that leave parameters at the FMU's start values."""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from clockwork import cli
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tools"))
from kill_sweep import descendants, running  # noqa: E402

from cwtest import CLOCK_SCENE, FMU_DIR, ROOT, fmu_file

CLOCK = CLOCK_SCENE


@pytest.fixture(autouse=True)
def _env(monkeypatch, tmp_path):
    fmu_file("Pendulum")
    monkeypatch.setenv("CLOCKWORK_FMU_DIR", str(FMU_DIR))
    monkeypatch.setenv("CLOCKWORK_CACHE", str(tmp_path / "cache"))


def _cli(*args):
    return [sys.executable, "-m", "clockwork", *map(str, args)]


def _env_for_subprocess(tmp_path: Path, **extra) -> dict:
    return dict(os.environ, CLOCKWORK_FMU_DIR=str(FMU_DIR), PYTHONPATH=str(ROOT), **extra)


# --- sweeps over every documented axis -------------------------------------------

# Two values for every axis docs/scenes.md allows: a parameter of each type,
# an unconnected input, every sweepable master key, the experiment's times.
AXES = {
    "pendulum.L": ['"1 m"', '"0.99 m"'],
    "pendulum.Q": [500, 1000],
    "escapement.torque": ['"0.4 N.cm"', '"0.5 N.cm"'],
    "pendulum.tau_coupling": [0.0, 1e-4],  # an input that no connection drives
    "master.step": ['"0.01 s"', '"0.02 s"'],
    "master.min_step": [1e-9, 1e-8],
    "master.max_step": [0.01, 0.02],
    "master.extrapolation": [0, 2],
    "master.iterations": [1, 2],
    "master.iteration_tolerance": [1e-10, 1e-8],
    "master.event_time_tolerance": [1e-10, 1e-9],
    "master.event_indicator_tolerance": [1e-12, 1e-10],
    "master.richardson_tolerance": [1e-6, 1e-5],
    "master.order": ['"jacobi"', '"gauss-seidel"'],
    "master.algebraic_loops": ['"solve"', '"delay"'],
    "master.event_location": ["true", "false"],
    "master.richardson": ["false", "true"],
    "experiment.start": [0.0, 0.1],
    "experiment.stop": [0.5, 0.6],
}


@pytest.mark.parametrize("axis", list(AXES))
def test_sweep_over_every_documented_axis(tmp_path, capsys, axis):
    values = ", ".join(str(v) for v in AXES[axis])
    plot = (f'\n[[plot]]\nkind = "sweep"\nx = "{axis}"\ny = ["ticks"]\nfile = "sweep_plot.png"\n')
    text = CLOCK.format(stop=0.5, sweep=f'\n[sweep]\naxes = [ {{ parameter = "{axis}", values = [{values}] }} ]\n'
                        + plot)
    scene = tmp_path / "axis.toml"
    scene.write_text(text)
    rc = cli.main(["run", str(scene), "--out", str(tmp_path / "out"), "--no-progress", "--workers", "1"])
    out, err = capsys.readouterr()
    assert rc == 0, err
    header, *rows = (tmp_path / "out" / "sweep.csv").read_text().splitlines()
    assert header.split(",")[0] == axis and len(rows) == 2
    assert (tmp_path / "out" / "sweep_plot.png").stat().st_size > 1000
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["points_failed"] == 0 and "sweep_plot.png" in summary["files"]


# --- a killed sweep, rerun ------------------------------------------------------------

KILL_SWEEP = '\n[sweep]\naxes = [ { parameter = "escapement.torque", start = "0.3 N.cm", stop = "0.6 N.cm", ' \
             'num = 12 } ]\n'


def test_killed_sweep_rerun_is_byte_identical_and_leaves_nothing(tmp_path):
    scene = tmp_path / "kill.toml"
    scene.write_text(CLOCK.format(stop=6.0, sweep=KILL_SWEEP))
    env = _env_for_subprocess(tmp_path, CLOCKWORK_CACHE="off")
    out = tmp_path / "killed"
    proc = subprocess.Popen(_cli("run", scene, "--out", out, "--workers", 2, "--no-progress"),
                            env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    workers: set[int] = set()
    try:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline:
            workers |= descendants(proc.pid)
            done = list((out / "points").glob("*.json")) if (out / "points").is_dir() else []
            if len(done) >= 3 and workers:
                break
            assert proc.poll() is None, proc.communicate()
            time.sleep(0.02)
        workers |= descendants(proc.pid)
        proc.send_signal(signal.SIGKILL)
        proc.wait(10)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert workers, "the sweep ran no worker processes"
    deadline = time.monotonic() + 10
    while any(running(w) for w in workers) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not [w for w in workers if running(w)], "orphan worker processes outlived the killed run"
    finished = len(list((out / "points").glob("*.json")))
    assert 3 <= finished < 12, "the run was not interrupted halfway"
    # What a killed writer leaves: .part files (with a dead pid in their names).
    (out / ".sweep.csv.99999999.k2j4.part").write_text("half")
    (out / "points" / ".x.json.99999999.q8z1.part").write_text("{")
    (out / "sweep.csv.part").write_text("half")

    r = subprocess.run(_cli("run", scene, "--out", out, "--workers", 2, "--no-progress"),
                       env=env, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    clean = tmp_path / "clean"
    r = subprocess.run(_cli("run", scene, "--out", clean, "--workers", 2, "--no-progress"),
                       env=env, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert (out / "sweep.csv").read_bytes() == (clean / "sweep.csv").read_bytes()
    resumed = json.loads((out / "summary.json").read_text())
    fresh = json.loads((clean / "summary.json").read_text())
    assert resumed["points_reused"] == finished
    assert resumed["points"] == fresh["points"]
    assert resumed["headlines"] == fresh["headlines"]
    assert not list(out.rglob("*.part")) and not list(out.glob(".staging*"))


# --- damaged points and cache entries ---------------------------------------------

DAMAGE = {
    "not JSON": "{ this is not json",
    "NaN": '{"kind": "time_series", "result": {"ticks": NaN}}',
    "wrong kind": '{"kind": "steady_state", "result": {}}',
    "not an object": "[1, 2, 3]",
    "empty": "",
    "result not a table": '{"kind": "time_series", "result": 3}',
}


@pytest.mark.parametrize("damage", list(DAMAGE))
def test_damaged_point_is_recomputed_with_one_warning(tmp_path, capsys, damage):
    scene = tmp_path / "s.toml"
    scene.write_text(CLOCK.format(stop=0.3, sweep=KILL_SWEEP.replace("num = 12", "num = 2")))
    out = tmp_path / "out"
    assert cli.main(["run", str(scene), "--out", str(out), "--no-progress", "--workers", "1"]) == 0
    before = (out / "sweep.csv").read_bytes()
    victim = sorted((out / "points").glob("*.json"))[0]
    victim.write_text(DAMAGE[damage])
    for entry in (tmp_path / "cache").rglob("*.json"):  # the same point's cache entry too
        if entry.name == victim.name:
            entry.write_text(DAMAGE[damage])
    capsys.readouterr()
    assert cli.main(["run", str(scene), "--out", str(out), "--no-progress", "--workers", "1"]) == 0
    _, err = capsys.readouterr()
    warnings = [ln for ln in err.splitlines() if ln.strip()]
    assert 1 <= len(warnings) <= 2 and all("warning" in ln and victim.name[:8] in ln for ln in warnings), err
    assert (out / "sweep.csv").read_bytes() == before
    json.loads(victim.read_text(), parse_constant=lambda c: pytest.fail(c))


def test_failed_point_is_retried(tmp_path, capsys):
    scene = tmp_path / "s.toml"
    scene.write_text(CLOCK.format(stop=0.3, sweep=KILL_SWEEP.replace("num = 12", "num = 2")))
    out = tmp_path / "out"
    assert cli.main(["run", str(scene), "--out", str(out), "--no-progress", "--workers", "1"]) == 0
    victim = sorted((out / "points").glob("*.json"))[0]
    stored = json.loads(victim.read_text())
    failed = {"point": stored.get("point", {}), "error": "t = 0.1 s: planted failure"}
    victim.write_text(json.dumps(failed))
    for entry in (tmp_path / "cache").rglob(victim.name):
        entry.unlink()
    capsys.readouterr()
    assert cli.main(["run", str(scene), "--out", str(out), "--no-progress", "--workers", "1"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["points_failed"] == 0 and summary["points_reused"] == 1


# --- the temporary directory -------------------------------------------------------

COMMANDS = [
    ("run", lambda d: ["run", d / "s.toml", "--out", d / "out", "--no-progress"]),
    ("sweep with workers", lambda d: ["run", d / "w.toml", "--out", d / "wout", "--no-progress", "--workers", 2]),
    ("validate", lambda d: ["validate", d / "s.toml"]),
    ("info", lambda d: ["info", "Pendulum"]),
    ("list", lambda d: ["list"]),
    ("export-ssp", lambda d: ["export-ssp", d / "s.toml", "--out", d / "s.ssp"]),
    ("bad input", lambda d: ["run", d / "s.toml", "--out", ""]),
    ("failed run", lambda d: ["run", d / "missing.toml", "--out", d / "x"]),
]


@pytest.mark.parametrize("name, argv", COMMANDS, ids=[c[0] for c in COMMANDS])
def test_no_file_is_left_in_the_temporary_directory(tmp_path, name, argv):
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    (tmp_path / "s.toml").write_text(CLOCK.format(stop=0.3, sweep=""))
    (tmp_path / "w.toml").write_text(CLOCK.format(stop=0.3, sweep=KILL_SWEEP.replace("num = 12", "num = 3")))
    env = _env_for_subprocess(tmp_path, TMPDIR=str(tmp), CLOCKWORK_CACHE=str(tmp_path / "cache"),
                              MPLCONFIGDIR=str(tmp_path / "mpl"))
    r = subprocess.run(_cli(*argv(tmp_path)), env=env, capture_output=True, text=True, timeout=300, cwd=tmp_path)
    assert "Traceback" not in r.stderr, r.stderr
    assert sorted(p.name for p in tmp.iterdir()) == [], r.stderr


def test_second_run_reuses_the_extracted_fmus(tmp_path):
    (tmp_path / "s.toml").write_text(CLOCK.format(stop=0.3, sweep=""))
    env = _env_for_subprocess(tmp_path, CLOCKWORK_CACHE=str(tmp_path / "cache"))
    for out in ("a", "b"):
        r = subprocess.run(_cli("run", tmp_path / "s.toml", "--out", tmp_path / out, "--no-progress"), env=env,
                           capture_output=True, text=True, timeout=300)
        assert r.returncode == 0, r.stderr
        extracted = {p: p.stat().st_mtime_ns for p in (tmp_path / "cache" / "fmus").rglob("*.so")}
        if out == "a":
            first = extracted
    assert len(first) == 2 and extracted == first  # the same files, not unzipped again


# --- parameters the scene leaves at the FMU's start values ---------------------------

def test_steady_state_with_l_m_g_unset(tmp_path, capsys):
    text = CLOCK.format(stop=1.0, sweep="").replace('kind = "time_series"', 'kind = "steady_state"')
    assert "L =" not in text and " m =" not in text and " g =" not in text
    (tmp_path / "s.toml").write_text(text)
    rc = cli.main(["run", str(tmp_path / "s.toml"), "--out", str(tmp_path / "out"), "--no-progress"])
    _, err = capsys.readouterr()
    assert rc == 0, err
    result = json.loads((tmp_path / "out" / "summary.json").read_text())["result"]
    assert 1.9 < result["period_s"] < 2.1  # L = 1 m, g = 9.81 m/s^2 from the FMU's start values


def test_the_steady_state_example_of_docs_scenes_runs(tmp_path, capsys):
    docs = (ROOT / "docs" / "scenes.md").read_text()
    blocks = re.findall(r"```toml\n(.*?)```", docs, re.S)
    examples = [b for b in blocks if 'kind = "steady_state"' in b and "[components." in b]
    assert examples, "docs/scenes.md shows no steady_state scene"
    for i, text in enumerate(examples):
        f = tmp_path / f"example{i}.toml"
        f.write_text(text)
        rc = cli.main(["run", str(f), "--out", str(tmp_path / f"out{i}"), "--no-progress", "--workers", "1"])
        _, err = capsys.readouterr()
        assert rc == 0, err


# --- a plot that fails, a disk that is full ------------------------------------------

def test_a_failing_plot_is_one_line_and_exit_1(tmp_path, capsys, monkeypatch):
    from clockwork.results.plots import registry

    def broken(*args, **kwargs):
        raise ValueError("the plotting library gave up")

    text = CLOCK.format(stop=0.3, sweep="") + '\n[[plot]]\nkind = "time_series"\nx = "time"\ny = ["pendulum.phi"]\n' \
                                              'file = "phi.png"\n'
    (tmp_path / "s.toml").write_text(text)
    monkeypatch.setitem(registry.PLOTS, "time_series", broken)
    rc = cli.main(["run", str(tmp_path / "s.toml"), "--out", str(tmp_path / "out"), "--no-progress"])
    _, err = capsys.readouterr()
    assert rc == 1, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "phi.png" in lines[0] and "gave up" in lines[0] and "Traceback" not in err, err
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["plots_failed"][0]["file"] == "phi.png"


@pytest.mark.parametrize("errno_name, code", [("ENOSPC", 1), ("EACCES", 2), ("EIO", 1)])
def test_os_error_while_writing_is_one_line(tmp_path, capsys, monkeypatch, errno_name, code):
    import errno

    from clockwork import atomic

    real = atomic.write_bytes_atomic if hasattr(atomic, "write_bytes_atomic") else None

    def full(path, *args, **kwargs):
        raise OSError(getattr(errno, errno_name), os.strerror(getattr(errno, errno_name)), str(path))

    (tmp_path / "s.toml").write_text(CLOCK.format(stop=0.3, sweep=""))
    out = tmp_path / "out"
    assert cli.main(["run", str(tmp_path / "s.toml"), "--out", str(out), "--no-progress"]) == 0
    before = {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()}
    capsys.readouterr()
    for name in dir(atomic):
        if name.startswith("write_") and callable(getattr(atomic, name)):
            monkeypatch.setattr(atomic, name, full)
    import clockwork.results.files as files
    for name in dir(files):
        if name.startswith("write_") and callable(getattr(files, name)):
            monkeypatch.setattr(files, name, full)
    rc = cli.main(["run", str(tmp_path / "s.toml"), "--out", str(out), "--no-progress",
                   "--set", "pendulum.Q=900"])
    _, err = capsys.readouterr()
    assert rc == code, err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert real is None or real is not full
    after = {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()}
    assert after == before  # the earlier result stays whole
