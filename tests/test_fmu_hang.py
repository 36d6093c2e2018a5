"""Signals while an FMU call blocks, and killed sweep workers.

An FMU whose doStep never returns (tests/data/fmi2/hostile.c, fault 4)
holds the main thread inside a ctypes call, where Python runs no signal
handler: the watchdog thread (clockwork/watchdog.py) ends the run within
a second of SIGTERM or SIGINT, exit code 128 + the signal, one line, the
scratch folder and the staging folder removed, the earlier result in the
directory intact; with pool workers too. A sweep worker that is killed
fails the run with one line; a point is written into an unnamed file, so
a process killed while writing it leaves no .part.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

import fmi2_hostile
from cwtest import ROOT, default_stop_signals, test_fmu

sys.path.insert(0, str(ROOT / "tools"))
from kill_sweep import descendants, running  # noqa: E402

# Signals sent after a fixed wait, and a bound on how soon a run ends.
pytestmark = pytest.mark.serial


@pytest.fixture(scope="module")
def hostile():
    return test_fmu("Hostile")


def _env(tmp_path: Path) -> tuple[dict, Path]:
    tmp = tmp_path / "tmp"
    tmp.mkdir(exist_ok=True)
    return dict(os.environ, TMPDIR=str(tmp), PYTHONPATH=str(ROOT), CLOCKWORK_CACHE="off"), tmp


def _sweep_scene(tmp_path: Path, fmu: Path) -> Path:
    return fmi2_hostile.sweep_scene(tmp_path, fmu, 4, [0.2, 0.3, 0.4, 0.5], "a sweep whose points hang")


def _wait_for_hang(proc, seconds: float = 3.0) -> None:
    time.sleep(seconds)  # start-up, then the FMU hangs at t = 0.3 s
    assert proc.poll() is None, "the run ended before the signal"


def _ended(proc, sig) -> str:
    sent = time.monotonic()
    proc.send_signal(sig)
    try:
        _, err = proc.communicate(timeout=5)  # never, before the watchdog
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.communicate()
        pytest.fail(f"the run did not end after {sig.name}")
    assert time.monotonic() - sent < 5
    assert proc.returncode == 128 + sig, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("clockwork: error: interrupted"), err
    return err


@pytest.mark.parametrize("engine", ["python", "compiled"])
@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT, signal.SIGHUP], ids=lambda s: s.name)
def test_a_signal_ends_a_run_whose_fmu_never_returns(tmp_path, hostile, sig, engine):
    env, tmp = _env(tmp_path)
    out = tmp_path / "out"
    base = [sys.executable, "-m", "clockwork", "run", str(hostile), "--out", str(out)]
    first = subprocess.run(base, env=env, capture_output=True, text=True, timeout=120)
    assert first.returncode == 0, first.stderr
    earlier = {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()}
    proc = subprocess.Popen(base + ["--set", "Hostile.fault=4", "--set", "Hostile.t_fault=0.3",
                                    "--set", f"master.engine={engine}"],
                            env=env, stderr=subprocess.PIPE, text=True, preexec_fn=default_stop_signals)
    _wait_for_hang(proc)
    family = descendants(proc.pid)
    _ended(proc, sig)
    time.sleep(0.2)
    assert not [p for p in family if running(p)], "the plot process outlived the run"
    assert not list(tmp.iterdir()), list(tmp.iterdir())
    assert {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()} == earlier
    assert not [p for p in out.iterdir() if p.name.startswith(".")], list(out.iterdir())


def test_a_signal_ends_a_sweep_whose_workers_hang(tmp_path, hostile):
    env, tmp = _env(tmp_path)
    scene = _sweep_scene(tmp_path, hostile)
    proc = subprocess.Popen([sys.executable, "-m", "clockwork", "run", str(scene), "--out", str(tmp_path / "out"),
                             "--no-plot", "--workers", "2"],
                            env=env, stderr=subprocess.PIPE, text=True, preexec_fn=default_stop_signals)
    _wait_for_hang(proc, 4.0)
    family = descendants(proc.pid)
    assert family, "no workers"
    _ended(proc, signal.SIGTERM)
    time.sleep(0.2)
    assert not [p for p in family if running(p)], "a worker outlived the run"
    assert not list(tmp.iterdir()), list(tmp.iterdir())


def test_a_killed_sweep_worker_fails_the_run_with_one_line(tmp_path, hostile):
    env, tmp = _env(tmp_path)
    scene = _sweep_scene(tmp_path, hostile)
    proc = subprocess.Popen([sys.executable, "-m", "clockwork", "run", str(scene), "--out", str(tmp_path / "out"),
                             "--no-plot", "--workers", "2"], env=env, stderr=subprocess.PIPE, text=True)
    _wait_for_hang(proc, 4.0)
    workers = descendants(proc.pid)
    os.kill(max(workers), signal.SIGKILL)
    try:
        _, err = proc.communicate(timeout=30)
    except subprocess.TimeoutExpired:
        proc.kill()
        pytest.fail("the pool hung after a worker was killed")
    assert proc.returncode == 1, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "sweep worker process ended abruptly (killed by SIGKILL)" in lines[0], err
    assert not list(tmp.iterdir())


def test_a_process_killed_while_writing_a_point_leaves_no_part_file(tmp_path):
    points = tmp_path / "points"
    points.mkdir()
    for existing in (False, True):
        target = points / "abc.json"
        if existing:
            target.write_text("{}")
        code = ("import os, signal\n"
                "os.fsync = lambda fd: os.kill(os.getpid(), signal.SIGKILL)  # killed in the middle of the write\n"
                "from clockwork.results.files import write_json_atomic\n"
                f"write_json_atomic({str(target)!r}, {{'x': 1}}, unnamed=True)\n")
        r = subprocess.run([sys.executable, "-c", code], env=dict(os.environ, PYTHONPATH=str(ROOT)))
        assert r.returncode == -signal.SIGKILL
        assert [p.name for p in points.iterdir()] == (["abc.json"] if existing else [])
