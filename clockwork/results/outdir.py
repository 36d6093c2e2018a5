"""The output directory of one run: created, locked, and swapped whole.

Opening it creates the directory with its parents, checks that it is a
writable directory, and locks it (``flock`` on the directory itself, which
the system releases when the process dies, however it dies): a second run
into the same directory is refused instead of mixed in. A directory
that holds other files and no earlier result is refused. Under the lock,
what a killed run left behind (.part files, a staging folder) is removed.

A run writes its results into a staging folder inside the directory and
commits them at the end: the earlier summary.json goes first, the new files
are renamed into place, files of the earlier result that this run does not
make are removed, and the new summary.json comes last. A summary never
describes files of another run, and a run that fails before the commit
leaves the earlier result whole. Finished sweep points live in ``points/``
across runs, for resuming.
"""

from __future__ import annotations

import fcntl
import json
import os
import shutil
from pathlib import Path

from ..errors import UsageError
from ..atomic import PART, remove_stale_parts
from .files import check_output_dir

SUMMARY = "summary.json"
# Files a result may hold besides its plots; the plots are named in summary.json.
RESULT_FILES = ("timeseries.csv", "ticks.csv", "sweep.csv", SUMMARY)
_STAGING = ".staging."


class OutputDir:
    def __init__(self, path: str | os.PathLike):
        self.path = check_output_dir(path)
        self._lock_fd: int | None = None

    def __enter__(self) -> "OutputDir":
        fd = os.open(self.path, os.O_RDONLY)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(fd)
            raise UsageError(f"output directory {self.path} is being written by another clockwork run") from None
        self._lock_fd = fd
        self._refuse_foreign_files()
        for old in self.path.glob(f"{_STAGING}*"):
            shutil.rmtree(old, ignore_errors=True)
        remove_stale_parts(self.path, every=True)
        remove_stale_parts(self.points, every=True)
        self.staging = self.path / f"{_STAGING}{os.getpid()}"
        self.staging.mkdir()
        return self

    def __exit__(self, *exc) -> None:
        shutil.rmtree(self.staging, ignore_errors=True)
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
            os.close(self._lock_fd)
            self._lock_fd = None
            shown = ", ".join(foreign[:3]) + (f" and {len(foreign) - 3} more" if len(foreign) > 3 else "")
            raise UsageError(f"output directory {self.path} holds {shown} and no clockwork result: "
                             "give a new or empty directory (a run replaces what it finds there)")

    @property
    def points(self) -> Path:
        return self.path / "points"

    def commit(self) -> None:
        """Move the staged result into place (see the module docstring)."""
        staged = sorted(p.name for p in self.staging.iterdir())
        if SUMMARY not in staged:
            raise RuntimeError(f"{self.staging}: no {SUMMARY} to commit")
        earlier = self._earlier_files()
        (self.path / SUMMARY).unlink(missing_ok=True)
        for name in staged:
            if name != SUMMARY:
                os.replace(self.staging / name, self.path / name)
        for name in earlier - set(staged):
            target = self.path / name
            if target.is_file() and target.parent == self.path:
                target.unlink(missing_ok=True)
        os.replace(self.staging / SUMMARY, self.path / SUMMARY)

    def _earlier_files(self) -> set[str]:
        names = set(RESULT_FILES)
        try:
            listed = json.loads((self.path / SUMMARY).read_text()).get("files", [])
        except (OSError, ValueError, AttributeError):
            return names  # no earlier result, or one that a killed run cut short
        # Only plain file names: a hand-edited summary must not reach elsewhere.
        names.update(n for n in listed if isinstance(n, str) and n == Path(n).name and not n.startswith("."))
        return names
