"""Child processes that must not outlive the process that started them."""

from __future__ import annotations

import os
import signal
import sys


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
