"""Running out of a resource is a failed run (exit 1) naming the file, not
bad input; a closed standard stream is no traceback; and what matplotlib
would print or leave behind when the cache location is unusable stays
under the one-line discipline."""

from __future__ import annotations

import os
import re
import resource
import subprocess
import sys
from pathlib import Path

import pytest

from cwtest import CLOCK_SCENE, FMU_DIR, ROOT, fmu_file

SWEEP = ('\n[sweep]\naxes = [ { parameter = "escapement.torque", values = ["0.4 N.cm", "0.5 N.cm"] } ]\n'
         '\n[[plot]]\nkind = "sweep"\nx = "escapement.torque"\ny = "ticks"\n')


@pytest.fixture
def env(tmp_path):
    fmu_file("Pendulum")
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    (tmp_path / "s.toml").write_text(CLOCK_SCENE.format(stop=2.0, sweep=SWEEP))
    return dict(os.environ, TMPDIR=str(tmp), CLOCKWORK_FMU_DIR=str(FMU_DIR), PYTHONPATH=str(ROOT),
                CLOCKWORK_CACHE=str(tmp_path / "cache"))


def _clockwork(args, env, preexec=None):
    return subprocess.run([sys.executable, "-m", "clockwork", *map(str, args)], env=env, capture_output=True,
                          text=True, preexec_fn=preexec, timeout=300)


def _one_line(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("clockwork: error: ") and "Traceback" not in err, err
    return lines[0]


def _file_limit(nbytes: int):
    def limit():
        resource.setrlimit(resource.RLIMIT_FSIZE, (nbytes, nbytes))
    return limit


# What each command writes that grows past a file size limit.
LIMITED = {
    "run (result files)": (lambda d: ["run", d / "s.toml", "--out", d / "out", "--no-progress"], 6000, "cache"),
    "run (unzipping FMUs, cache off)": (lambda d: ["run", d / "s.toml", "--out", d / "out", "--no-progress"],
                                        6000, "off"),
    "export-ssp": (lambda d: ["export-ssp", d / "s.toml", "--out", d / "x.ssp", "--point", 0], 20000, "cache"),
    "export-suite": (lambda d: ["export-suite", d / "kit", "--only", "Pendulum"], 20000, "cache"),
}


@pytest.mark.parametrize("case", list(LIMITED))
def test_a_file_size_limit_is_a_failed_run_naming_the_file(tmp_path, env, case):
    argv, nbytes, cache = LIMITED[case]
    if cache == "off":
        env["CLOCKWORK_CACHE"] = "off"
    r = _clockwork(argv(tmp_path), env, _file_limit(nbytes))
    assert r.returncode == 1, r.stderr
    line = _one_line(r.stderr)
    assert re.search(r" /\S+: File too large", line), line  # the file is named
    assert ".staging" not in line
    assert not list(Path(env["TMPDIR"]).iterdir())
    assert not [p for p in tmp_path.rglob("*") if p.name.endswith(".part") or p.name.startswith(".staging")]


def test_out_of_memory_is_one_line(tmp_path, env):
    """A MemoryError (here from an address-space limit) is a failed run, not a traceback."""
    code = ("import sys, resource\nfrom clockwork import cli\n"
            "def boom(args):\n    raise MemoryError\n"
            "cli.cmd_validate = boom\nsys.exit(cli.main(sys.argv[1:]))\n")
    r = subprocess.run([sys.executable, "-c", code, "validate", tmp_path / "s.toml"], env=env,
                       capture_output=True, text=True)
    assert r.returncode == 1
    assert "out of memory" in _one_line(r.stderr)


def _close(*fds):
    def close():
        for fd in fds:
            os.close(fd)
    return close


@pytest.mark.parametrize("closed", [(1,), (2,), (1, 2), (0, 1, 2)], ids=["stdout", "stderr", "both", "all"])
@pytest.mark.parametrize("command", ["run", "list", "info", "validate", "bad"])
def test_a_closed_standard_stream_is_no_traceback(tmp_path, env, closed, command):
    d = tmp_path
    argv = {"run": ["run", d / "s.toml", "--out", d / "out", "--no-progress"], "list": ["list"],
            "info": ["info", "Pendulum"], "validate": ["validate", d / "s.toml"],
            "bad": ["validate", d / "missing.toml"]}[command]
    r = subprocess.run([sys.executable, "-m", "clockwork", *map(str, argv)], env=env, stdout=subprocess.PIPE
                       if 1 not in closed else None, stderr=subprocess.PIPE if 2 not in closed else None,
                       text=True, preexec_fn=_close(*closed), timeout=300)
    assert r.returncode == (2 if command == "bad" else 0), r.stderr
    if 2 not in closed:
        assert "Traceback" not in r.stderr and (command == "bad") == bool(r.stderr.strip()), r.stderr
    if command == "run":
        assert (d / "out" / "summary.json").exists()
        assert not [p for p in (d / "out").iterdir() if p.name not in ("summary.json", "sweep.csv", "points",
                                                                        "plot1_sweep.png")]
    assert not list(Path(env["TMPDIR"]).iterdir())


UNUSABLE = {
    "home and cache a file": {"HOME": "{d}/file", "XDG_CACHE_HOME": "", "CLOCKWORK_CACHE": "{d}/file"},
    "cache off, home below a file": {"HOME": "{d}/file/home", "CLOCKWORK_CACHE": "off"},
    "MPLCONFIGDIR unusable": {"MPLCONFIGDIR": "{d}/file/mpl", "CLOCKWORK_CACHE": "off"},
}


@pytest.mark.parametrize("case", list(UNUSABLE))
def test_matplotlib_prints_nothing_and_leaves_nothing_when_the_cache_is_unusable(tmp_path, env, case):
    (tmp_path / "file").write_text("not a folder")
    env.pop("MPLCONFIGDIR", None)  # (HOME is a file: nothing can be made below it, even by root)
    env.update({k: v.format(d=tmp_path) for k, v in UNUSABLE[case].items()})
    r = _clockwork(["run", tmp_path / "s.toml", "--out", tmp_path / "out", "--no-progress"], env)
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "out" / "plot1_sweep.png").exists()
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert all(ln.startswith("clockwork: warning: the point cache") for ln in lines), r.stderr
    assert len(lines) <= 1
    assert not list(Path(env["TMPDIR"]).iterdir()), list(Path(env["TMPDIR"]).iterdir())
