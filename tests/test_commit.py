"""The commit of a result directory under failure and kill at every step.

A commit swaps the staged result in (clockwork.results.outdir). Whatever
step fails or is killed, the directory must then hold the complete earlier
result or the complete new one (once the next run has opened it), and a
rerun must commit normally. The steps are every file-system call the commit
makes (rename, mkdir, fsync, unlink, rmdir); each is made to fail, or to
SIGKILL the process, in turn.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from clockwork.errors import ClockworkError
from clockwork.results.outdir import OutputDir

ROOT = Path(__file__).resolve().parents[1]
OLD = {"sweep.csv": "a\n1\n", "old_only.png": "old plot", "shared.png": "old shared"}
NEW = {"sweep.csv": "a\n2\n", "new_only.png": "new plot", "shared.png": "new shared"}
STEP_CALLS = ("replace", "rename", "mkdir", "fsync", "unlink", "rmdir")


def _stage(out: OutputDir, files: dict, tag: str) -> None:
    for name, text in files.items():
        (out.staging / name).write_text(text)
    summary = {"files": sorted(files) + ["summary.json"], "tag": tag}
    (out.staging / "summary.json").write_text(json.dumps(summary))


def _commit(d: Path, files: dict, tag: str) -> None:
    with OutputDir(d) as out:
        _stage(out, files, tag)
        out.commit()


def _content(d: Path) -> dict:
    """The visible result: every non-hidden file but the points."""
    return {p.name: p.read_text() for p in d.iterdir() if p.is_file() and not p.name.startswith(".")}


def _expected(files: dict, tag: str) -> dict:
    return {**files, "summary.json": json.dumps({"files": sorted(files) + ["summary.json"], "tag": tag})}


def _reopened(d: Path) -> dict:
    """The directory as the next run sees it (recovery done), left unchanged."""
    with OutputDir(d):
        pass
    assert not [p for p in d.iterdir() if p.name.startswith(".staging") or p.name.endswith(".part")]
    return _content(d)


class _Steps:
    """Counts the commit's file-system calls; at call `fail_at` runs `action`."""

    def __init__(self, monkeypatch, fail_at: int | None, action, persistent: bool = False):
        self.n = 0
        for name in STEP_CALLS:
            real = getattr(os, name)
            monkeypatch.setattr(os, name, self._wrap(real, fail_at, action, persistent))

    def _wrap(self, real, fail_at, action, persistent):
        def call(*a, **k):
            self.n += 1
            if fail_at is not None and (self.n == fail_at or (persistent and self.n > fail_at)):
                action()
            return real(*a, **k)
        return call


def _count_steps(tmp_path, monkeypatch) -> int:
    d = tmp_path / "count"
    _commit(d, OLD, "old")
    with OutputDir(d) as out:
        _stage(out, NEW, "new")
        with monkeypatch.context() as m:
            steps = _Steps(m, None, None)
            out.commit()
    return steps.n


def _refuse():
    raise PermissionError(1, "Operation not permitted (injected)")


@pytest.mark.parametrize("persistent", [False, True], ids=["one-failure", "every-later-call-fails"])
def test_a_failure_at_every_step_keeps_old_or_new(tmp_path, monkeypatch, persistent):
    total = _count_steps(tmp_path, monkeypatch)
    assert total >= 8  # journal, moves out, moves in, fsyncs, cleanup
    outcomes = set()
    for k in range(1, total + 1):
        d = tmp_path / f"d{k}"
        _commit(d, OLD, "old")
        with OutputDir(d) as out:
            _stage(out, NEW, "new")
            with monkeypatch.context() as m:
                _Steps(m, k, _refuse, persistent)
                try:
                    out.commit()
                    failed = False
                except ClockworkError as e:  # the project's one-line error, never a bare OSError
                    failed = True
                    assert "earlier result is kept" in str(e)
        seen = _reopened(d)
        assert seen in (_expected(OLD, "old"), _expected(NEW, "new")), (k, seen)
        if failed:
            assert seen == _expected(OLD, "old"), k
        outcomes.add("new" if seen == _expected(NEW, "new") else "old")
        _commit(d, NEW, "rerun")  # a rerun works
        assert _content(d) == _expected(NEW, "rerun")
    assert outcomes == {"old", "new"}


def kill_at(k: int) -> None:
    """From now on, SIGKILL this process at its k-th file-system call of
    STEP_CALLS (for the killer scripts, here and in test_failed_runs.py)."""
    n = [0]

    def wrap(real):
        def call(*a, **kw):
            n[0] += 1
            if n[0] == k:
                os.kill(os.getpid(), signal.SIGKILL)
            return real(*a, **kw)
        return call

    for name in STEP_CALLS:
        setattr(os, name, wrap(getattr(os, name)))


_KILLER = textwrap.dedent("""
    import sys
    sys.path.insert(0, {root!r}); sys.path.insert(0, {tests!r})
    from test_commit import NEW, _stage, kill_at
    from clockwork.results.outdir import OutputDir
    with OutputDir(sys.argv[1]) as out:
        _stage(out, NEW, "new")
        kill_at(int(sys.argv[2]))
        out.commit()
""")


def test_a_kill_at_every_step_keeps_old_or_new_and_a_rerun_works(tmp_path, monkeypatch):
    total = _count_steps(tmp_path, monkeypatch)
    script = tmp_path / "killer.py"
    script.write_text(_KILLER.format(root=str(ROOT), tests=str(ROOT / "tests")))
    outcomes = []
    for k in range(1, total + 2):  # the last one is not killed
        d = tmp_path / f"k{k}"
        _commit(d, OLD, "old")
        (d / "points").mkdir()
        (d / "points" / "p1.json").write_text("{}")  # a finished point, for the resume
        r = subprocess.run([sys.executable, str(script), str(d), str(k)], capture_output=True, text=True)
        killed = r.returncode == -signal.SIGKILL
        assert killed or (k == total + 1 and r.returncode == 0), (k, r.returncode, r.stderr)
        seen = _reopened(d)
        assert seen in (_expected(OLD, "old"), _expected(NEW, "new")), (k, seen)
        outcomes.append("new" if seen == _expected(NEW, "new") else "old")
        assert (d / "points" / "p1.json").exists()
        _commit(d, NEW, "rerun")
        assert _content(d) == _expected(NEW, "rerun")
    # Old until the new summary.json lands, new from there on.
    assert outcomes[0] == "old" and outcomes[-1] == "new"
    assert outcomes == sorted(outcomes, key=lambda o: o == "new")


def test_a_kill_mid_commit_then_a_real_run_resumes(tmp_path):
    """The leftovers of a killed commit do not make the directory look foreign."""
    from cwtest import CLOCK_SCENE, FMU_DIR
    scene = tmp_path / "clock.toml"
    scene.write_text(CLOCK_SCENE.format(stop=0.5, sweep=""))
    d = tmp_path / "out"
    _commit(d, OLD, "old")
    with OutputDir(d) as out:
        _stage(out, NEW, "new")
        # the state after the earlier files moved out and one new file moved in
        (out.staging / ".journal").write_text(json.dumps({"new": sorted(NEW) + ["summary.json"],
                                                          "old": ["summary.json"] + sorted(OLD)}))
        (out.staging / ".old").mkdir()
        for name in ["summary.json"] + sorted(OLD):
            os.replace(d / name, out.staging / ".old" / name)
        os.replace(out.staging / "new_only.png", d / "new_only.png")
        staging = out.staging
        out.staging = None  # as if killed: nothing cleaned up
    assert staging.exists()
    r = subprocess.run([sys.executable, "-m", "clockwork", "run", str(scene), "--out", str(d),
                        "--no-progress"], capture_output=True, text=True,
                       env=dict(os.environ, CLOCKWORK_CACHE="off", CLOCKWORK_FMU_DIR=str(FMU_DIR)))
    assert r.returncode == 0, r.stderr
    assert (d / "summary.json").exists() and "old_only.png" not in os.listdir(d)


@pytest.mark.parametrize("journal", ["{ not json", '{"new": ["../x"], "old": ["summary.json"]}', ""])
def test_a_damaged_journal_puts_the_earlier_result_back(tmp_path, journal):
    """A journal is written atomically, so a damaged one was damaged by hand:
    the earlier files moved aside go back, and nothing outside the directory is touched."""
    d = tmp_path / "out"
    _commit(d, OLD, "old")
    with OutputDir(d) as out:
        _stage(out, NEW, "new")
        (out.staging / ".old").mkdir()
        for name in ["summary.json"] + sorted(OLD):
            os.replace(d / name, out.staging / ".old" / name)
        (out.staging / ".journal").write_text(journal)
        out.staging = None  # as if killed
    assert _reopened(d) == _expected(OLD, "old")
