"""FMUs that break the rules in their callbacks, crash, or never return.

- The logger (cw_log.c) looks an FMU's componentEnvironment up in a
  registry of live instances and reads every string through the kernel:
  environments (void *)1, NULL, another instance's, unreadable instance
  names and messages, formats that ask for arguments that were not passed.
- A fatal signal inside an FMU's own code (a NULL dereference, SIGFPE,
  abort()) fails the run as an fmi2Fatal would: one line naming the
  instance, the call and the signal, the history up to the last good
  point, exit code 1, nothing left in $TMPDIR. On both engines.
- A sweep worker that dies fails the run with one line, not a traceback.

The FMU is tests/data/fmi2/hostile.c (tests/fmi2_hostile.py describes it, CMake builds it).
"""

from __future__ import annotations

import csv
import ctypes
import json
import os
import subprocess
import sys
from ctypes import c_char_p, c_int, c_void_p
from pathlib import Path

import pytest

import fmi2_hostile
from cwtest import ROOT, test_fmu


@pytest.fixture(scope="module")
def fmus():
    return {"hostile": test_fmu("Hostile"), "abort": test_fmu("AbortInit")}


def _run(tmp_path: Path, fmu: Path, *sets: str, out: str = "out"):
    tmp = tmp_path / "tmp"
    tmp.mkdir(exist_ok=True)
    env = dict(os.environ, TMPDIR=str(tmp), PYTHONPATH=str(ROOT), CLOCKWORK_CACHE="off")
    argv = [sys.executable, "-m", "clockwork", "run", str(fmu), "--out", str(tmp_path / out), "--no-plot"]
    for s in sets:
        argv += ["--set", s]
    r = subprocess.run(argv, env=env, capture_output=True, text=True, timeout=120)
    return r, tmp


def _one_line(r, code: int, *needles: str) -> str:
    assert r.returncode == code, (r.returncode, r.stderr)
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("clockwork: error: "), r.stderr
    for n in needles:
        assert n in lines[0], (n, lines[0])
    return lines[0]


# -- the logger ---------------------------------------------------------------


@pytest.mark.parametrize("reads", ["kernel", "direct"])
def test_the_logger_looks_environments_up_and_reads_nothing_it_was_not_given(reads):
    # Strings are read through process_vm_readv, or directly under the
    # crash handler once it is installed (as it is when an FMU is loaded).
    from clockwork.fmi import calls as fmu_module

    core = fmu_module.formatting_logger()
    assert core is not None, "the compiled core is not built"
    lib = core[1]
    if reads == "direct":
        assert lib.cw_crash_install(-1) == 0
    got = {"a": [], "b": []}
    sinks = {name: fmu_module._SINK(lambda i, s, c, t, name=name: got[name].append(t.decode()))
             for name in got}
    envs = {name: ctypes.cast(sink, c_void_p).value for name, sink in sinks.items()}
    for name in got:
        assert lib.cw_env_register(envs[name], name.encode(), sinks[name]) == 0
    logger = lib.cw_logger  # varargs: the arguments as ctypes objects
    logger.restype = None
    try:
        def log(env, name, fmt, *args):
            logger(c_void_p(env), name if name is None or isinstance(name, bytes) else c_void_p(name), c_int(0),
                   c_char_p(b"cat"), fmt if fmt is None or isinstance(fmt, bytes) else c_void_p(fmt), *args)

        log(envs["a"], b"a", b"x=%d %s %5.2f", c_int(5), c_char_p(b"hi"), ctypes.c_double(3.14159))
        assert got["a"][-1] == "x=5 hi  3.14"
        log(1, b"b", b"env one, name b")  # the Overture case: found by its name
        assert got["b"][-1] == "env one, name b"
        log(envs["b"], b"a", b"b's env, a's name")  # another instance's environment
        assert got["a"][-1] == "b's env, a's name"
        log(envs["a"], None, b"no name")
        assert got["a"][-1] == "no name"
        log(envs["b"], 8, b"unreadable name")  # the environment decides
        assert got["b"][-1] == "unreadable name"
        log(envs["a"], b"a", None)
        assert got["a"][-1] == ""
        log(envs["a"], b"a", 24)
        assert got["a"][-1] == "(the FMU logged an unreadable message)"
        log(envs["a"], b"a", b"bad %s|%s", c_void_p(8), c_char_p(None))
        assert got["a"][-1] == "bad (unreadable string)|(null)"
        target = c_int(7)
        log(envs["a"], b"a", b"n%n|%1$s|%d", ctypes.byref(target), c_int(1))  # %n writes nothing
        assert target.value == 7 and got["a"][-1] == "n|%1$s|%d"
        log(envs["a"], b"a", b"%q", c_int(1))
        assert got["a"][-1] == "%q"
        long_arg = b"y" * 100_000
        log(envs["a"], b"a", b"%s!", c_char_p(long_arg))
        assert got["a"][-1].startswith("yyy") and len(got["a"][-1]) < 70_000
        before = len(fmu_module.unattributed)
        log(1, b"nobody", b"to the fallback %d", c_int(3))
        log(None, None, b"no env, no name")
        assert [m[2] for m in list(fmu_module.unattributed)[before:]] == ["to the fallback 3", "no env, no name"]
        lib.cw_env_unregister(envs["a"])
        log(envs["a"], b"x", b"after free")  # a forgotten environment is never called
        assert fmu_module.unattributed[-1][2] == "after free"
    finally:
        for name in got:
            lib.cw_env_unregister(envs[name])


def test_strings_from_fmi1_and_fmi3_callbacks_are_read_without_trusting_them():
    from clockwork.fmi.calls import read_string

    assert read_string(None) == ""
    assert read_string(8) == "(the FMU passed an unreadable message)"
    text = ctypes.create_string_buffer(b"fine")
    assert read_string(ctypes.addressof(text)) == "fine"


@pytest.mark.parametrize("engine", ["python", "compiled"])
def test_an_fmu_that_logs_through_bad_environments_runs_and_its_error_reaches_its_line(tmp_path, fmus, engine):
    ok, tmp = _run(tmp_path, fmus["hostile"], f"master.engine={engine}", out="ok")
    assert ok.returncode == 0, ok.stderr
    r, tmp = _run(tmp_path, fmus["hostile"], "Hostile.fault=5", "Hostile.t_fault=0.3", f"master.engine={engine}")
    # logged through environment (void *)1 with its instance name, formatted
    _one_line(r, 1, "returned Error: hostile failure at t=0.4 (formatted)")
    assert not list(tmp.iterdir())


# -- crashes ------------------------------------------------------------------

FAULTS = {1: "SIGSEGV", 2: "SIGFPE", 3: "SIGABRT", 6: "SIGSEGV"}  # 6: a call of the NULL stepFinished


@pytest.mark.parametrize("engine", ["python", "compiled"])
@pytest.mark.parametrize("fault", sorted(FAULTS), ids=lambda f: f"{f}-{FAULTS[f]}")
def test_a_crash_in_do_step_is_a_failed_run_that_keeps_its_history(tmp_path, fmus, fault, engine):
    r, tmp = _run(tmp_path, fmus["hostile"], f"Hostile.fault={fault}", "Hostile.t_fault=0.3",
                  f"master.engine={engine}")
    _one_line(r, 1, "Hostile", "fmi2DoStep", FAULTS[fault], "crashed")
    out = tmp_path / "out"
    with open(out / "timeseries.csv") as f:
        rows = list(csv.reader(f))
    assert rows[0] == ["time", "Hostile.x"]
    assert [round(float(t), 9) for t, _ in rows[1:]] == [0.0, 0.1, 0.2, 0.3]  # the step from 0.3 crashed
    failed = json.loads((out / "summary.json").read_text())["result"]["failed"]
    assert failed["instance"] == "Hostile" and FAULTS[fault] in failed["message"]
    assert not list(tmp.iterdir()), list(tmp.iterdir())
    assert not [p for p in out.rglob("*") if p.name.endswith(".part") or p.name.startswith(".staging")]


@pytest.mark.parametrize("engine", ["python", "compiled"])
def test_an_abort_in_instantiate_is_a_failed_run(tmp_path, fmus, engine):
    r, tmp = _run(tmp_path, fmus["abort"], f"master.engine={engine}")
    _one_line(r, 1, "Hostile", "fmi2Instantiate", "SIGABRT")
    assert not list(tmp.iterdir())


def test_a_crash_in_a_sweep_worker_fails_that_point(tmp_path, fmus):
    scene = fmi2_hostile.sweep_scene(tmp_path, fmus["hostile"], 1, [0.2, 5], "hostile sweep")
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    env = dict(os.environ, TMPDIR=str(tmp), PYTHONPATH=str(ROOT), CLOCKWORK_CACHE="off")
    r = subprocess.run([sys.executable, "-m", "clockwork", "run", str(scene), "--out", str(tmp_path / "out"),
                        "--no-plot", "--workers", "2"], env=env, capture_output=True, text=True, timeout=120)
    _one_line(r, 1, "1 of 2 sweep points failed")
    points = json.loads((tmp_path / "out" / "summary.json").read_text())["points"]
    assert sum("SIGSEGV" in (p.get("error") or "") for p in points) == 1
    assert not list(tmp.iterdir())


@pytest.mark.parametrize("engine", ["python", "compiled"])
def test_a_crash_in_an_fmi3_do_step_is_a_failed_run(tmp_path, engine):
    fmu = test_fmu("fmi3/LinearCrash")  # linear.c that logs unreadable strings first, then crashes
    r, tmp = _run(tmp_path, fmu, "Linear.t_fail=0.45", f"master.engine={engine}")
    _one_line(r, 1, "Linear", "fmi3DoStep", "SIGSEGV", "crashed")
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["result"]["failed"]["instance"] == "Linear"
    assert not list(tmp.iterdir())


@pytest.mark.parametrize("engine", ["python", "compiled"])
def test_an_fmi1_fmu_that_logs_bad_strings_and_crashes_is_a_failed_run(tmp_path, engine):
    fmu = test_fmu("fmi1/HoldHostile")  # hold.c built with -DCW_HOSTILE
    r, tmp = _run(tmp_path, fmu, "master.step=0.1", f"master.engine={engine}")
    _one_line(r, 1, "fmiDoStep", "SIGSEGV", "crashed")
    with open(tmp_path / "out" / "timeseries.csv") as f:
        times = [round(float(row[0]), 9) for row in list(csv.reader(f))[1:]]
    assert times == [0.0, 0.1, 0.2, 0.3]
    assert not list(tmp.iterdir())


@pytest.mark.parametrize("engine", ["python", "compiled"])
def test_a_crash_the_handler_cannot_return_from_ends_the_run_with_one_line(tmp_path, engine):
    # Without unwind tables the handler cannot find the FMU's caller: it
    # parks the thread and the watchdog ends the run (no history kept).
    fmu = test_fmu("NoUnwind")  # hostile.c without unwind tables
    r, tmp = _run(tmp_path, fmu, "Hostile.fault=1", "Hostile.t_fault=0.3", f"master.engine={engine}")
    _one_line(r, 1, "Hostile", "fmi2DoStep", "SIGSEGV", "crashed")
    assert not list(tmp.iterdir())
    assert not [p for p in (tmp_path / "out").rglob("*") if p.name.endswith(".part") or p.name.startswith(".")]


def test_a_sweep_worker_ended_by_a_crash_fails_the_run_with_one_line(tmp_path):
    fmu = test_fmu("NoUnwind")
    scene = fmi2_hostile.sweep_scene(tmp_path, fmu, 1, [0.2, 5], "a sweep whose worker dies")
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    env = dict(os.environ, TMPDIR=str(tmp), PYTHONPATH=str(ROOT), CLOCKWORK_CACHE="off")
    r = subprocess.run([sys.executable, "-m", "clockwork", "run", str(scene), "--out", str(tmp_path / "out"),
                        "--no-plot", "--workers", "2"], env=env, capture_output=True, text=True, timeout=120)
    _one_line(r, 1, "sweep worker process ended abruptly")
    assert not list(tmp.iterdir())
