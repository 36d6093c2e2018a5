"""The README's main command, as a newcomer runs it: on a fresh copy of the
checkout, in a fresh virtual environment, `bash tools/main.sh` must set up,
run Ziemkiewicz Fig. 4(a) and leave its results in out/ziemkiewicz_fig4a.

A fresh clone once stopped with exit 2 after setup (its out/ did not exist)
while every other test passed; this test keeps that class of failure out.
The venv sees the system's packages (nothing to download) but installs the
copy's own clockwork, so nothing of this checkout's build is reused.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys

import pytest

from cwtest import ROOT

pytestmark = pytest.mark.slow


def _tracked_files() -> list[str]:
    r = subprocess.run(["git", "ls-files", "-z", "--cached", "--others", "--exclude-standard"], cwd=ROOT,
                       capture_output=True, check=True)
    return [f for f in r.stdout.decode().split("\0") if f and (ROOT / f).is_file()]


@pytest.mark.skipif(shutil.which("git") is None or not (ROOT / ".git").exists(), reason="needs a git checkout")
def test_main_command_on_a_fresh_copy(tmp_path):
    clone = tmp_path / "clockwork"
    for f in _tracked_files():  # what a clone of this commit would hold (and work in progress)
        (clone / f).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(ROOT / f, clone / f)
    venv = tmp_path / "venv"
    subprocess.run([sys.executable, "-m", "venv", "--system-site-packages", str(venv)], check=True)
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "CLOCKWORK_FMU_DIR", "VIRTUAL_ENV")}
    # The venv active, as `source venv/bin/activate` leaves it: setup installs into it (tools/python.sh).
    env.pop("PYTHON", None)
    env.update(PATH=f"{venv / 'bin'}{os.pathsep}{env.get('PATH', '')}", VIRTUAL_ENV=str(venv),
               CLOCKWORK_CACHE=str(tmp_path / "cache"), TMPDIR=str(tmp_path))
    r = subprocess.run(["bash", "tools/main.sh"], cwd=clone, env=env, capture_output=True, text=True, timeout=1800)
    assert r.returncode == 0, (r.stdout[-3000:], r.stderr[-3000:])
    out = clone / "out" / "ziemkiewicz_fig4a"
    summary = json.loads((out / "summary.json").read_text())
    assert summary["points_total"] == 24 and summary["points_failed"] == 0
    assert all((out / f).is_file() for f in summary["files"])
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    which = subprocess.run([str(venv / "bin" / "python"), "-c", "import clockwork; print(clockwork.__file__)"],
                           cwd=elsewhere, env=env, capture_output=True, text=True)
    assert str(clone) in which.stdout, which  # the copy's package ran, not this checkout's
    assert not (clone / ".venv").exists()  # the active venv was used, no other made
