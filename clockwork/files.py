"""Opening a file a user named, for reading: the one place it is done.

A path from the user (a scene, an SSP, an FMU, an input file, a results
folder's files) may name something that is not a regular file: a FIFO,
whose open() blocks until a writer appears; a socket; a character device
such as /dev/zero or /dev/urandom, which never ends; a directory. Each is
refused with `NotRegularFile` (an OSError whose str() is one line saying
what it is and what was expected) before anything is read: the file is
opened with O_NONBLOCK, which a FIFO without a writer does not block on,
and judged by fstat() of what was opened (no window between a check and
the open). A regular file's size is known before it is read, so a bound on
it refuses a huge (or sparse) file without reading a byte.
"""

from __future__ import annotations

import errno
import fcntl
import os
import stat
from pathlib import Path
from typing import BinaryIO

_KINDS = ((stat.S_ISDIR, "a directory"), (stat.S_ISFIFO, "a FIFO (named pipe)"), (stat.S_ISSOCK, "a socket"),
          (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"))


class NotRegularFile(OSError):
    """A path that names something other than a regular file (or one over
    a size bound). str() is the detail, without the path."""

    def __init__(self, path, detail: str):
        super().__init__(None, detail)  # strerror: what handlers of OSError print
        self.path = str(path)
        self.detail = detail

    def __str__(self) -> str:
        return self.detail


def kind_of(mode: int) -> str:
    """What a file of this st_mode is, for a message ("a FIFO (named pipe)")."""
    return next((name for test, name in _KINDS if test(mode)), "not a regular file")


def open_regular(path: str | os.PathLike, expected: str = "a regular file", limit: int | None = None) -> BinaryIO:
    """The regular file at `path`, open for reading in binary; NotRegularFile
    when it is anything else ("is a FIFO (named pipe), expected <expected>")
    or holds more than `limit` bytes; FileNotFoundError and other OSErrors
    as open() raises them."""
    try:
        fd = os.open(os.fspath(path), os.O_RDONLY | os.O_NONBLOCK | os.O_CLOEXEC | getattr(os, "O_NOCTTY", 0))
    except OSError as e:
        if e.errno in (errno.ENXIO, errno.EOPNOTSUPP):  # a socket cannot be opened: say what it is
            try:
                st = os.stat(path)
            except OSError:
                raise e from None
            if not stat.S_ISREG(st.st_mode):
                raise NotRegularFile(path, f"is {kind_of(st.st_mode)}, expected {expected}") from None
        raise
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            raise NotRegularFile(path, f"is {kind_of(st.st_mode)}, expected {expected}")
        if limit is not None and st.st_size > limit:
            raise NotRegularFile(path, f"{st.st_size:,} bytes: expected {expected} of at most {limit:,} bytes")
        fcntl.fcntl(fd, fcntl.F_SETFL, fcntl.fcntl(fd, fcntl.F_GETFL) & ~os.O_NONBLOCK)
        return os.fdopen(fd, "rb")
    except BaseException:
        os.close(fd)
        raise


def read_regular(path: str | os.PathLike, expected: str = "a regular file", limit: int | None = None) -> bytes:
    """The bytes of the regular file at `path` (open_regular's checks), at
    most `limit` of them (a file that grows while read is cut there and
    refused)."""
    with open_regular(path, expected, limit) as f:
        data = f.read() if limit is None else f.read(limit + 1)
    if limit is not None and len(data) > limit:
        raise NotRegularFile(path, f"more than {limit:,} bytes: expected {expected} of at most {limit:,} bytes")
    return data


def check_regular(path: str | os.PathLike, expected: str = "a regular file") -> None:
    """NotRegularFile unless `path` is a regular file (or does not exist:
    the caller's open then says so); by stat, for paths handed to a library
    that opens them itself."""
    try:
        st = os.stat(path)
    except OSError:
        return
    if not stat.S_ISREG(st.st_mode):
        raise NotRegularFile(Path(path), f"is {kind_of(st.st_mode)}, expected {expected}")


def absent(path: str | os.PathLike, expected: str, missing: str = "no such file") -> str:
    """Why `path` is not the `expected` thing it should be, for a message:
    `missing` where nothing is there, else what is there instead ("is a
    FIFO (named pipe), expected <expected>")."""
    try:
        st = os.stat(path)
    except OSError:
        return missing
    kind = kind_of(st.st_mode) if not stat.S_ISREG(st.st_mode) else "a regular file"
    return f"is {kind}, expected {expected}"
