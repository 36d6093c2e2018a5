"""Child processes that must not outlive the process that started them."""

from __future__ import annotations

import os
import signal
import sys
import threading
from typing import Callable

from . import watchdog


def die_with_parent(parent: int) -> None:
    """Call first thing in a child process: when `parent` dies (even by
    SIGKILL) the kernel sends this process SIGKILL too (Linux prctl), so
    that no worker is left running on its own."""
    if sys.platform.startswith("linux"):
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        pr_set_pdeathsig = 1
        libc.prctl(pr_set_pdeathsig, signal.SIGKILL)
    if os.getppid() != parent:  # the parent died before prctl took effect
        os._exit(1)


def fork_is_safe() -> bool:
    """Whether this process may fork a child that goes on running Python:
    Linux (prctl ties the child to its parent) and no other thread (a lock
    another thread held at the fork would stay locked in the child)."""
    # The watchdog's thread sleeps in os.read, holding no lock.
    others = [t for t in threading.enumerate()
              if t is not threading.current_thread() and not watchdog.is_watchdog(t)]
    return sys.platform.startswith("linux") and hasattr(os, "fork") and not others


class Child:
    """A forked child process, with a pipe to it (``job_fd``) and one back
    (``answer_fd``). ``close`` ends it (SIGKILL), reaps it and closes the
    pipes; it may be called any number of times."""

    def __init__(self, pid: int, job_fd: int, answer_fd: int):
        self.pid: int | None = pid
        self.job_fd: int | None = job_fd
        self.answer_fd: int | None = answer_fd
        # Killed and reaped when the watchdog ends a run whose main thread is stuck.
        self._abandon = watchdog.on_abandon(self._kill, process=True)

    def _kill(self) -> None:
        pid = self.pid
        if pid is not None:
            try:
                os.kill(pid, signal.SIGKILL)
                os.waitpid(pid, 0)
            except OSError:
                pass

    def take_job_fd(self) -> int | None:
        """The pipe to the child, which the caller now owns (and closes)."""
        fd, self.job_fd = self.job_fd, None
        return fd

    def take_answer_fd(self) -> int | None:
        """The pipe from the child, which the caller now owns (and closes)."""
        fd, self.answer_fd = self.answer_fd, None
        return fd

    def reap(self) -> int | None:
        """Wait for the child to end: its exit status, or None when it was already reaped."""
        pid, self.pid = self.pid, None
        watchdog.forget(self._abandon)
        if pid is None:
            return None
        try:
            return os.waitpid(pid, 0)[1]  # retried after a signal by os.waitpid itself
        except ChildProcessError:
            return None

    def close(self) -> None:
        for fd in (self.take_job_fd(), self.take_answer_fd()):
            if fd is not None:
                os.close(fd)
        if self.pid is not None:
            try:
                os.kill(self.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
            self.reap()


def fork_child(body: Callable[[int, int, int], None]) -> Child:
    """Fork a child that runs ``body(parent pid, job_fd, answer_fd)`` (its
    ends of the two pipes) and then leaves by os._exit: status 0, or 1 when
    body raised (anything: nothing may escape a forked child into the
    parent's code, and the parent's atexit handlers are not its own).
    Raises OSError when there are no more processes or pipes."""
    job_r, job_w = os.pipe()
    answer_r, answer_w = os.pipe()
    for stream in (sys.stdout, sys.stderr):  # else the child would write their buffers again
        if stream is not None:  # None: the stream was closed when the command started
            stream.flush()
    parent = os.getpid()
    try:
        pid = os.fork()
    except OSError:
        for fd in (job_r, job_w, answer_r, answer_w):
            os.close(fd)
        raise
    if pid == 0:
        code = 0
        try:
            os.close(job_w)
            os.close(answer_r)
            body(parent, job_r, answer_w)
        except BaseException:  # noqa: BLE001 (see above)
            code = 1
        finally:
            os._exit(code)
    os.close(job_r)
    os.close(answer_w)
    return Child(pid, job_w, answer_r)
