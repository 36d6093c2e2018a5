"""The output directory of one run: created, locked, and swapped whole.

Opening it creates the directory with its parents, checks that it is a
writable directory, and locks it (``flock`` on the directory itself, which
the system releases when the process dies, however it dies): a second run
into the same directory is refused instead of mixed in. A directory
that holds other files and no earlier result is refused. Under the lock,
a commit that a killed run left unfinished is finished or undone (below),
then what it left behind (.part files, a staging folder) is removed.

A run writes its results into a staging folder inside the directory and
commits them at the end, as a journaled swap:

1. the journal (``<staging>/.journal``: the new and the earlier file names)
   is written atomically; from here on a commit can always be finished or
   undone;
2. the earlier result's files move into ``<staging>/.old``, summary.json
   first;
3. the new files move into the directory, summary.json last: the moment
   the new summary.json lands is the commit point;
4. the staging folder (journal, earlier files) is removed.

A failure in steps 1-3 (a rename refused, a full disk) undoes the moves in
this process and the earlier result is back as it was. A kill leaves the
journal; the next run into the directory finishes the commit when the new
summary.json is in place (roll forward) and undoes it otherwise (roll back),
before anything else. So the directory holds the complete earlier result or
the complete new one, never a mix, and the killed run's points are still in
``points/`` for the resume.
"""

from __future__ import annotations

import fcntl
import json
import os
import shutil
from pathlib import Path

from .. import watchdog
from ..errors import SimulationError, UsageError
from ..files import read_regular
from ..atomic import PART, fsync_dir, remove_stale_parts, write_text_atomic
from ..numbers import parse_json
from .files import check_output_dir

SUMMARY = "summary.json"
# Files a result may hold besides its plots; the plots are named in summary.json.
RESULT_FILES = ("timeseries.csv", "ticks.csv", "sweep.csv", "stability.csv", SUMMARY)
STAGING = ".staging."
_JOURNAL = ".journal"
_OLD = ".old"


class OutputDir:
    def __init__(self, path: str | os.PathLike):
        self.path = check_output_dir(path)
        self._lock_fd: int | None = None
        self.staging: Path | None = None

    def __enter__(self) -> "OutputDir":
        fd = os.open(self.path, os.O_RDONLY)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(fd)
            raise UsageError(f"output directory {self.path} is being written by another clockwork run") from None
        self._lock_fd = fd
        try:
            for old in sorted(self.path.glob(f"{STAGING}*")):
                if (old / _JOURNAL).exists():
                    _recover(self.path, old)
            self._refuse_foreign_files()
            for old in self.path.glob(f"{STAGING}*"):
                shutil.rmtree(old, ignore_errors=True)
            remove_stale_parts(self.path, every=True)
            remove_stale_parts(self.points, every=True)
            self.staging = self.path / f"{STAGING}{os.getpid()}"
            self.staging.mkdir()
            # Removed by the watchdog if it ends a run whose main thread is stuck.
            self._abandon = watchdog.on_abandon(self._abandoned)
        except BaseException:
            self._unlock()
            raise
        return self

    def _abandoned(self) -> None:
        """The staging folder of a run that ends without this process's
        `with` blocks: removed, unless a commit is under way (its journal
        says; the next run finishes or undoes it, as after a kill)."""
        if self.staging is not None and not (self.staging / _JOURNAL).exists():
            shutil.rmtree(self.staging, ignore_errors=True)

    def __exit__(self, *exc) -> None:
        watchdog.forget(getattr(self, "_abandon", None))
        if self.staging is not None:
            try:
                if (self.staging / _JOURNAL).exists():
                    _recover(self.path, self.staging)  # a commit cut short: never drop its journal
                else:
                    shutil.rmtree(self.staging, ignore_errors=True)
            except OSError:
                pass  # the journal stays for the next run
        self._unlock()

    def _unlock(self) -> None:
        if self._lock_fd is not None:
            os.close(self._lock_fd)  # releases the lock
            self._lock_fd = None

    def _refuse_foreign_files(self) -> None:
        """A directory that holds other files and no earlier result is someone else's."""
        if (self.path / SUMMARY).exists():
            return
        foreign = sorted(p.name for p in self.path.iterdir()
                         if not (p.name == "points" or p.name.startswith(".") or p.name in RESULT_FILES
                                 or p.name.endswith(PART)))
        if foreign:
            shown = ", ".join(foreign[:3]) + (f" and {len(foreign) - 3} more" if len(foreign) > 3 else "")
            raise UsageError(f"output directory {self.path} holds {shown} and no clockwork result: "
                             "give a new or empty directory (a run replaces what it finds there)")

    @property
    def points(self) -> Path:
        return self.path / "points"

    def commit(self) -> None:
        """Swap the staged result in (see the module docstring)."""
        staged = sorted(p.name for p in self.staging.iterdir() if not p.name.startswith("."))
        if SUMMARY not in staged:
            raise RuntimeError(f"{self.staging}: no {SUMMARY} to commit")
        earlier = sorted(n for n in _earlier_files(self.path) if (self.path / n).is_file())
        journal = {"new": [n for n in staged if n != SUMMARY] + [SUMMARY],
                   "old": sorted(earlier, key=lambda n: n != SUMMARY)}  # summary.json out first
        try:
            write_text_atomic(self.staging / _JOURNAL, json.dumps(journal))
            (self.staging / _OLD).mkdir()
            for name in journal["old"]:
                os.replace(self.path / name, self.staging / _OLD / name)
            for name in journal["new"]:
                os.replace(self.staging / name, self.path / name)
            fsync_dir(self.path)
        except BaseException as e:
            try:
                _recover(self.path, self.staging)
            except OSError:
                pass  # the journal stays; the next run finishes the undo
            if isinstance(e, OSError):
                raise SimulationError(f"cannot commit the result into {self.path}: "
                                      f"{e.filename or ''}: {e.strerror or e}; the earlier result is kept") from None
            raise
        shutil.rmtree(self.staging, ignore_errors=True)


def _recover(directory: Path, staging: Path) -> None:
    """Finish (new summary.json in place) or undo a journaled commit."""
    try:
        journal = parse_json(read_regular(staging / _JOURNAL))
        new, old = [_plain(n) for n in journal["new"]], [_plain(n) for n in journal["old"]]
    except (OSError, ValueError, KeyError, TypeError):
        # Written atomically, so not a cut-short write: a hand-damaged journal.
        # Whatever earlier files were moved aside go back.
        new, old = [], sorted(p.name for p in (staging / _OLD).glob("*"))
    if new and not (staging / SUMMARY).exists() and (directory / SUMMARY).exists():
        shutil.rmtree(staging, ignore_errors=True)  # committed: the earlier files go
        return
    for name in new:  # undo: the new files that moved in go back
        if not (staging / name).exists() and (directory / name).exists():
            os.replace(directory / name, staging / name)
    for name in old:
        if (staging / _OLD / name).exists():
            os.replace(staging / _OLD / name, directory / name)
    fsync_dir(directory)
    shutil.rmtree(staging, ignore_errors=True)


def _plain(name) -> str:
    """A journal entry: a plain file name of this directory, nothing that reaches elsewhere."""
    if not isinstance(name, str) or name != Path(name).name or name in ("", ".", ".."):
        raise ValueError(f"not a plain file name: {name!r}")
    return name


def _earlier_files(directory: Path) -> set[str]:
    names = set(RESULT_FILES)
    try:
        listed = parse_json(read_regular(directory / SUMMARY)).get("files", [])
    except (OSError, ValueError, AttributeError):
        return names  # no earlier result, or one that a killed run cut short
    # Only plain file names: a hand-edited summary must not reach elsewhere.
    names.update(n for n in listed if isinstance(n, str) and n == Path(n).name and not n.startswith("."))
    return names
