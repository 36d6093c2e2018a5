"""SIGTERM, SIGHUP and SIGINT sent to the run's own process alone.

Each ends the run like Ctrl-C: one stderr line, exit code 128 + the
signal's number, no worker or plot process left, nothing in $TMPDIR, no
staging folder or .part file in the result directory, and the finished
points kept: a rerun reuses them and finishes. The runs start with the
three signals at their defaults, whatever the test run has (under nohup it
ignores SIGHUP); a signal the run was started ignoring stays ignored, in
the run and its workers.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from cwtest import CLOCK_SCENE, FMU_DIR, ROOT, default_stop_signals, fmu_file

sys.path.insert(0, str(ROOT / "tools"))
from kill_sweep import descendants, running  # noqa: E402

# Signals sent after a fixed start-up wait, and a bound on how soon a run ends:
# run alone, not beside pytest-xdist workers that slow every start-up.
pytestmark = pytest.mark.serial

SWEEP = ('\n[sweep]\naxes = [ { parameter = "escapement.torque", start = "0.3 N.cm", stop = "0.6 N.cm", '
         'num = 8 } ]\n\n[[plot]]\nkind = "sweep"\nx = "escapement.torque"\ny = "ticks"\n')


@pytest.fixture(autouse=True)
def _fmus():
    fmu_file("Pendulum")


def _start(tmp_path: Path, workers: int, cache: str):
    scene = tmp_path / "s.toml"
    scene.write_text(CLOCK_SCENE.format(stop=300.0, sweep=SWEEP))
    tmp = tmp_path / "tmp"
    tmp.mkdir(exist_ok=True)
    env = dict(os.environ, TMPDIR=str(tmp), CLOCKWORK_FMU_DIR=str(FMU_DIR), PYTHONPATH=str(ROOT),
               CLOCKWORK_CACHE=cache if cache == "off" else str(tmp_path / "cache"))
    argv = [sys.executable, "-m", "clockwork", "run", str(scene), "--out", str(tmp_path / "out"),
            "--no-progress", "--workers", str(workers)]
    return argv, env, tmp


@pytest.mark.parametrize("cache", ["on", "off"])
@pytest.mark.parametrize("workers", [1, 2])
@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGHUP, signal.SIGINT], ids=lambda s: s.name)
def test_a_signal_to_the_parent_alone_leaves_nothing_and_keeps_the_points(tmp_path, sig, workers, cache):
    argv, env, tmp = _start(tmp_path, workers, cache)
    proc = subprocess.Popen(argv, env=env, stderr=subprocess.PIPE, text=True, preexec_fn=default_stop_signals)
    points = tmp_path / "out" / "points"
    deadline = time.monotonic() + 60
    while not list(points.glob("*.json")) and time.monotonic() < deadline and proc.poll() is None:
        time.sleep(0.02)
    family = descendants(proc.pid)
    assert proc.poll() is None and family, "the run ended before the signal"
    os.kill(proc.pid, sig)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 128 + sig, err
    assert len(err.strip().splitlines()) == 1 and err.startswith("clockwork: error: interrupted"), err
    time.sleep(0.2)
    assert not [p for p in family if running(p)], "a worker or the plot process outlived the run"
    assert not list(tmp.iterdir()), list(tmp.iterdir())
    out = tmp_path / "out"
    assert not [p for p in out.rglob("*") if p.name.endswith(".part") or p.name.startswith(".staging")]
    finished = len(list(points.glob("*.json")))
    assert 1 <= finished < 8
    if cache == "on":  # the rerun: the finished points are reused (from points/), the rest run
        r = subprocess.run(argv, env=env, capture_output=True, text=True, timeout=300)
        assert r.returncode == 0, r.stderr
        assert json.loads((out / "summary.json").read_text())["points_reused"] >= finished
        assert not list(tmp.iterdir())


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGHUP, signal.SIGINT], ids=lambda s: s.name)
def test_a_signal_ends_a_long_compiled_run_inside_one_core_call(tmp_path, sig):
    """One run_until of the compiled core that would take minutes (1e8 s of
    the clock, nothing recorded on the way that would fill a buffer) still
    ends within seconds of the signal: the core returns to Python every
    50 ms of wall time. The bound below is a bound on termination, not on
    speed: without the slices the run goes on for minutes."""
    argv, env, tmp = _start(tmp_path, 1, "off")
    scene = CLOCK_SCENE.format(stop=1e8, sweep="")
    scene = scene.replace('ticks = "pendulum"\n', 'interval = "1e6 s"\n').replace(
        "[master]\n", '[master]\nengine = "compiled"\n')
    (tmp_path / "s.toml").write_text(scene)
    argv = argv[:argv.index("--workers")]  # a single run: no pool, and no warning about one
    proc = subprocess.Popen(argv, env=env, stderr=subprocess.PIPE, text=True, preexec_fn=default_stop_signals)
    time.sleep(1.5)  # start-up takes ~0.5 s; then the run is inside the core
    assert proc.poll() is None, proc.communicate()[1]
    os.kill(proc.pid, sig)
    try:
        _, err = proc.communicate(timeout=10)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.communicate()
        pytest.fail(f"{sig.name} did not end the run inside the compiled core within 10 s")
    assert proc.returncode == 128 + sig, err
    assert len(err.strip().splitlines()) == 1 and err.startswith("clockwork: error: interrupted"), err
    assert not list(tmp.iterdir()), list(tmp.iterdir())
    out = tmp_path / "out"
    assert not [p for p in out.rglob("*") if p.name.endswith(".part") or p.name.startswith(".staging")]
    assert not (out / "summary.json").exists()


@pytest.mark.parametrize("workers", [1, 2])
def test_a_run_started_under_nohup_outlives_a_hang_up(tmp_path, workers):
    """SIGHUP ignored at the start (nohup) stays ignored: a hang-up sent to
    the whole process group, as a closing terminal sends it, ends neither
    the run nor its workers; the sweep finishes with every point."""
    def nohup():
        default_stop_signals()
        signal.signal(signal.SIGHUP, signal.SIG_IGN)

    argv, env, tmp = _start(tmp_path, workers, "off")
    proc = subprocess.Popen(argv, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=nohup, start_new_session=True)
    points = tmp_path / "out" / "points"
    deadline = time.monotonic() + 60
    while not list(points.glob("*.json")) and time.monotonic() < deadline and proc.poll() is None:
        time.sleep(0.02)
    assert proc.poll() is None, "the run ended before the hang-up"
    os.killpg(proc.pid, signal.SIGHUP)
    out, err = proc.communicate(timeout=300)
    assert proc.returncode == 0, err
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["points_total"] == 8 and not summary.get("points_failed"), summary
