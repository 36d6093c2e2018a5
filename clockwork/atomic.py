"""Files written atomically: readers never see a half-written file.

A writer puts the data into a temporary file in the target's directory
(named .<name>.<pid>.<random>.part), flushes and fsyncs it, then renames it
over the target with os.replace, which is atomic on POSIX within a
filesystem. A process killed in between leaves its .part file; the pid in
the name tells a later run that nobody is writing it any more
(``remove_stale_parts``).
"""

from __future__ import annotations

import errno
import os
import tempfile
from pathlib import Path
from typing import Iterable

PART = ".part"  # the suffix of a file being written


def remove_stale_parts(folder: Path, every: bool = False) -> int:
    """Remove the .part files in `folder` that no live process is writing
    (with `every`, all of them: the caller holds the folder). Returns how many."""
    removed = 0
    try:
        # Under the caller's lock any .part is debris; otherwise only our own hidden ones.
        entries = list(Path(folder).glob(f"*{PART}" if every else f".*{PART}"))
    except OSError:
        return 0
    for f in entries:
        pid = _writer_pid(f.name)
        if not every and pid is not None and (pid == os.getpid() or alive(pid)):
            continue
        try:
            f.unlink()
            removed += 1
        except OSError:
            pass
    return removed


def _writer_pid(name: str) -> int | None:
    # .<target name>.<pid>.<random>.part: the pid is the second field from the end
    fields = name[: -len(PART)].split(".")
    return int(fields[-2]) if len(fields) >= 3 and fields[-2].isdigit() else None


def alive(pid: int) -> bool:
    """Whether process `pid` runs (owned by anyone)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:
        return True  # exists, owned by someone else
    return True


def write_bytes_atomic(path: str | os.PathLike, data: bytes | Iterable[bytes]) -> Path:
    """`data`, or the chunks it yields (a large file is then never whole in memory)."""
    path = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.{os.getpid()}.", suffix=PART, dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as f:
            if isinstance(data, (bytes, bytearray, memoryview)):
                f.write(data)
            else:
                for chunk in data:
                    f.write(chunk)
            f.flush()
            os.fsync(f.fileno())
        os.chmod(tmp, 0o644)
        os.replace(tmp, path)
    except BaseException as e:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        if isinstance(e, OSError) and e.filename in (None, tmp):
            # A failed write names no file, a failed rename the .part file: name the target.
            raise OSError(e.errno, e.strerror, str(path)) from None
        raise
    fsync_dir(path.parent)
    return path


def write_bytes_unnamed(path: str | os.PathLike, data: bytes | Iterable[bytes]) -> Path:
    """write_bytes_atomic, written into an unnamed file (Linux O_TMPFILE)
    that is given its name only once complete: a process killed while
    writing it (a sweep killed between points) leaves nothing behind. A
    target that exists already is replaced through a .part name linked in
    the instant before the rename. Where the file system has no O_TMPFILE
    (or /proc is not mounted), as write_bytes_atomic."""
    path = Path(path)
    flag = getattr(os, "O_TMPFILE", None)
    if flag is None or not os.path.isdir("/proc/self/fd"):
        return write_bytes_atomic(path, data)
    try:
        folder = os.open(path.parent, os.O_RDONLY | os.O_DIRECTORY)
    except OSError as e:
        raise OSError(e.errno, e.strerror, str(path)) from None
    try:
        try:
            fd = os.open(".", flag | os.O_WRONLY, 0o644, dir_fd=folder)
        except OSError as e:
            if e.errno in (errno.EOPNOTSUPP, errno.EISDIR, errno.EINVAL):
                return write_bytes_atomic(path, data)
            raise
        with os.fdopen(fd, "wb") as f:
            for chunk in (data,) if isinstance(data, (bytes, bytearray, memoryview)) else data:
                f.write(chunk)
            f.flush()
            os.fsync(f.fileno())
            os.fchmod(f.fileno(), 0o644)
            # With a dir_fd, os.link is linkat(AT_SYMLINK_FOLLOW): the link
            # is to the open file, not to /proc's symbolic link.
            unnamed = f"/proc/self/fd/{f.fileno()}"
            try:
                os.link(unnamed, path.name, dst_dir_fd=folder)
            except FileExistsError:
                tmp = f".{path.name}.{os.getpid()}.{os.urandom(4).hex()}{PART}"
                os.link(unnamed, tmp, dst_dir_fd=folder)
                try:
                    os.replace(tmp, path.name, src_dir_fd=folder, dst_dir_fd=folder)
                except BaseException:
                    os.unlink(tmp, dir_fd=folder)
                    raise
        try:
            os.fsync(folder)  # the new name, durable
        except OSError:
            pass
    except OSError as e:
        raise OSError(e.errno, e.strerror, str(path)) from None
    finally:
        os.close(folder)
    return path


def fsync_dir(d: Path) -> None:
    # Makes the rename itself durable; not possible on every platform.
    try:
        fd = os.open(d, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def write_text_atomic(path: str | os.PathLike, text: str) -> Path:
    return write_bytes_atomic(path, text.encode("utf-8"))
