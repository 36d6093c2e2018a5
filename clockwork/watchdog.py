"""A thread that ends the run when the main thread cannot.

Python runs a signal handler in the main thread only, between bytecodes: a
stop signal (SIGINT, SIGTERM, SIGHUP) that arrives while an FMU call blocks
(a ctypes call that never returns) would wait for it forever. Python's own
C handler also writes the signal's number to the wakeup fd
(`signal.set_wakeup_fd`), at once, from any thread; this module's thread
reads it. When the main thread has not taken the signal within `GRACE`
seconds (clockwork.cli's handler calls `taken`), or has not ended the run
`CLEANUP` seconds after taking it (its cleanup called into another FMU
that hangs), the thread does what the
main thread's `with` blocks would have done: the registered cleanups (the
worker and plot processes killed and reaped, the staging folder removed; a
commit under way is left to the next run, as a kill would be), then the
scratch folder; it prints the one line and ends the process with 128 + the
signal's number. The FMU call is abandoned with the process.

The compiled core's crash handler (src_c/master/cw_guard.c) writes to the
same pipe when an FMU crashed in a way it cannot return from: the thread
then ends the process as a failed run (exit code 1).

Nothing of this runs per step: the thread sleeps in os.read.
"""

from __future__ import annotations

import itertools
import os
import shutil
import signal
import sys
import threading
import time
from typing import Callable

from .errors import printable

GRACE = 0.4  # s the main thread has to take a stop signal itself
CLEANUP = 10.0  # s it then has to finish its cleanup (a second hung FMU call)
STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)
FATAL_SIGNALS = (signal.SIGSEGV, signal.SIGBUS, signal.SIGFPE, signal.SIGILL, signal.SIGABRT)

_lock = threading.Lock()
_pipe: tuple[int, int] | None = None
_thread: threading.Thread | None = None
_taken: list[int] = []
_cleanups: dict[int, tuple[int, Callable[[], None]]] = {}
_tokens = itertools.count()
_abandoning = threading.Event()
_watching = [0]  # a new number for every start() and stop(): a wait of an earlier one is over
_previous_fd = [-1]  # the wakeup fd before start()
_crash_text: list[Callable[[], str]] = []  # what names a crash the core could not return from


def start() -> None:
    """Watch for stop signals (call in the main thread, with the handlers of
    the stop signals installed). The thread and its pipe are made once; a
    later call (after stop) watches again."""
    global _pipe, _thread
    with _lock:
        _taken.clear()
        _watching[0] += 1
        if _thread is not None:
            try:
                _previous_fd[0] = signal.set_wakeup_fd(_pipe[1], warn_on_full_buffer=False)
            except ValueError:
                pass
            return
        r, w = os.pipe()
        os.set_blocking(w, False)
        try:
            _previous_fd[0] = signal.set_wakeup_fd(w, warn_on_full_buffer=False)
        except ValueError:  # not the main thread
            os.close(r)
            os.close(w)
            return
        _pipe = (r, w)
        os.register_at_fork(after_in_child=_in_child)
        _thread = threading.Thread(target=_watch, args=(r,), name="clockwork-watchdog", daemon=True)
        _thread.start()


def stop() -> None:
    """Stop watching for stop signals (the end of clockwork.cli.main, which
    may be called again in the same process); the thread and its pipe stay
    for the core's crash handler."""
    with _lock:
        if _pipe is not None:
            try:
                signal.set_wakeup_fd(_previous_fd[0])  # a program's own, when main() ran inside one
            except ValueError:
                pass
        _taken.clear()
        _watching[0] += 1


def is_watchdog(thread: threading.Thread) -> bool:
    """Whether `thread` is this module's (it holds no lock a fork could copy held)."""
    return thread is _thread


def crash_fd() -> int:
    """The pipe's write end for the core's crash handler, or -1."""
    return _pipe[1] if _pipe is not None else -1


def taken(signo: int) -> None:
    """The main thread's handler took the stop signal `signo`. When the
    watchdog is already ending the process, the main thread waits for that
    here (it must not clean up the same things at the same time)."""
    _taken.append(signo)
    while _abandoning.is_set():
        time.sleep(1)


def on_abandon(cleanup: Callable[[], None], process: bool = False) -> int:
    """Run `cleanup` (from the watchdog's thread) when the watchdog ends the
    process; returns a token for `forget`. Those that end a `process` run
    first (it may be writing into a folder another removes), then the
    others, each group last registered first."""
    token = next(_tokens)
    _cleanups[token] = (0 if process else 1, cleanup)
    return token


def forget(token: int | None) -> None:
    if token is not None:
        _cleanups.pop(token, None)


def describe_crash(text: Callable[[], str]) -> None:
    """`text()` names the FMU and call of a crash the core could not return from."""
    _crash_text[:] = [text]


def _in_child() -> None:
    # A forked child (a pool worker) has no watchdog: its own signals must
    # not reach the parent's pipe, which it would inherit.
    global _pipe, _thread
    if _pipe is None:
        return
    try:
        signal.set_wakeup_fd(-1)
    except ValueError:
        pass
    for fd in _pipe:
        try:
            os.close(fd)
        except OSError:
            pass
    _pipe, _thread = None, None
    _taken.clear()
    _cleanups.clear()


def _watch(fd: int) -> None:
    while True:
        try:
            data = os.read(fd, 64)
        except InterruptedError:
            continue
        except OSError:
            return
        if not data:
            return
        for signo in data:
            if signo in FATAL_SIGNALS:
                _abandon(_crash_line(signo), 1)
            elif signo in STOP_SIGNALS:
                _stop(signo)


def _stop(signo: int) -> None:
    """The main thread takes the signal within GRACE and ends the run within
    CLEANUP (its cleanup may call into another FMU that hangs); else this
    thread ends it. A stop() of the watching ends the wait."""
    watching = _watching[0]
    began = time.monotonic()
    while time.monotonic() - began < GRACE + CLEANUP:
        if _watching[0] != watching:
            return  # main() returned: nothing to end
        if not _taken and time.monotonic() - began > GRACE:
            break
        time.sleep(0.02)
    signo = _taken[0] if _taken else signo
    name = "interrupted" if signo == signal.SIGINT else f"interrupted by {signal.Signals(signo).name}"
    _abandon(f"clockwork: error: {name}", 128 + signo)


def _crash_line(signo: int) -> str:
    try:
        text = _crash_text[0]() if _crash_text else ""
    except Exception:  # noqa: BLE001 (the line must be printed whatever)
        text = ""
    return f"clockwork: error: {text or f'an FMU crashed ({signal.Signals(signo).name})'}"


def _abandon(line: str, code: int) -> None:
    """End the process as the main thread's cleanup would have: every
    registered cleanup, the scratch folder, the one line, exit `code`."""
    _abandoning.set()
    for _, _, cleanup in sorted(((group, -token, fn) for token, (group, fn) in list(_cleanups.items())),
                                key=lambda c: c[:2]):
        try:
            cleanup()
        except BaseException:  # noqa: BLE001 (the others must run)
            pass
    from . import paths  # the scratch folder the main thread would remove at exit

    if paths._scratch is not None and paths._scratch_parent is None:
        shutil.rmtree(paths._scratch, ignore_errors=True)
    try:
        os.write(2, (printable(" ".join(line.split())) + "\n").encode("utf-8", "replace"))
    except OSError:
        pass
    for stream in (sys.stdout,):
        try:
            stream.flush()
        except (OSError, ValueError, AttributeError):
            pass
    os._exit(code)
