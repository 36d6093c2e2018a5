"""Where tools/setup.sh, main.sh and test.sh install and run: tools/python.sh.

$PYTHON if given, else the active virtual environment, else the checkout's
own .venv, created when missing; never the system's Python. Each case
sources the script in a scratch copy of tools/ with a clean environment.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from cwtest import ROOT


def _source(tmp_path: Path, **env) -> tuple[str, str, str]:
    """(PYTHON, the first PATH entry, stdout) after sourcing tools/python.sh in a copy."""
    (tmp_path / "tools").mkdir(exist_ok=True)
    shutil.copy(ROOT / "tools" / "python.sh", tmp_path / "tools" / "python.sh")
    base = {k: v for k, v in os.environ.items() if k not in ("PYTHON", "VIRTUAL_ENV", "CLOCKWORK_VENV")}
    # the interpreter running the tests is the python3 the script finds
    base["PATH"] = f"{Path(sys.executable).parent}{os.pathsep}{base.get('PATH', '')}"
    base.update(env)
    r = subprocess.run(["bash", "-c", 'source tools/python.sh && echo "$PYTHON" && echo "${PATH%%:*}"'],
                       cwd=tmp_path, env=base, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    lines = r.stdout.strip().splitlines()
    return lines[-2], lines[-1], r.stdout


def test_a_given_python_is_used(tmp_path):
    python, first, _ = _source(tmp_path, PYTHON=sys.executable)
    assert python == sys.executable and first == str(Path(sys.executable).parent)
    assert not (tmp_path / ".venv").exists()


def test_an_active_virtual_environment_is_used(tmp_path):
    venv = tmp_path / "mine"
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(venv)], check=True)
    python, first, _ = _source(tmp_path, VIRTUAL_ENV=str(venv))
    assert python == str(venv / "bin" / "python") and first == str(venv / "bin")
    assert not (tmp_path / ".venv").exists()


def test_without_either_the_checkouts_venv_is_created_and_used(tmp_path):
    python, first, out = _source(tmp_path)
    venv = (tmp_path / ".venv").resolve()
    assert python == str(venv / "bin" / "python") and first == str(venv / "bin")
    assert "created the virtual environment .venv" in out
    assert (venv / "bin" / "pip").exists()  # setup installs with pip into it
    again = _source(tmp_path)
    assert again[0] == python and "created" not in again[2]  # made once


def test_a_python_older_than_3_11_is_refused(tmp_path):
    fake = tmp_path / "old" / "python"
    fake.parent.mkdir()
    fake.write_text("#!/bin/sh\nexit 1\n")
    fake.chmod(0o755)
    (tmp_path / "tools").mkdir()
    shutil.copy(ROOT / "tools" / "python.sh", tmp_path / "tools" / "python.sh")
    r = subprocess.run(["bash", "-c", "source tools/python.sh"], cwd=tmp_path, capture_output=True, text=True,
                       env={"PATH": os.environ["PATH"], "PYTHON": str(fake)})
    assert r.returncode == 1 and "3.11" in r.stderr


@pytest.mark.parametrize("script", ["setup.sh", "main.sh", "test.sh"])
def test_the_commands_source_it_before_any_python(script):
    lines = (ROOT / "tools" / script).read_text().splitlines()
    body = [ln for ln in lines if ln.strip() and not ln.lstrip().startswith("#")]
    at = body.index("source tools/python.sh")
    import re

    assert not any(re.search(r"python|\bpip\b|clockwork", ln, re.I) for ln in body[:at]), body[:at]
    assert not any("python3" in ln for ln in body[at + 1:]), "a bare python3 after the choice"


def test_the_test_command_runs_the_serial_tests_alone_after_the_parallel_pass():
    """pytest-xdist runs modules side by side; the tests marked serial (a
    signal sent after a fixed start-up wait, a bound on how soon a run
    ends) run afterwards with no worker beside them."""
    lines = [ln for ln in (ROOT / "tools" / "test.sh").read_text().splitlines() if "-m pytest" in ln]
    assert len(lines) == 2, lines
    parallel, serial = lines
    assert "-n " in parallel and '-m "not serial"' in parallel, parallel
    assert "no:xdist" in serial and "-m serial" in serial, serial


def test_every_signal_test_is_marked_serial():
    r = subprocess.run([sys.executable, "-m", "pytest", "--collect-only", "-q", "-p", "no:cacheprovider",
                        "-m", "not serial", str(ROOT / "tests" / "test_signals.py")],
                       capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert "test_signals.py::" not in r.stdout, r.stdout
    assert "deselected" in r.stdout, r.stdout
