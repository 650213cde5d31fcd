"""A child process ends with the process that started it (the pools of the worker runtime,
the dashboard's figure processes): a leaf every tier may use, the standard library only."""

from __future__ import annotations

import ctypes
import multiprocessing
import os
import signal
import sys

__all__ = ["exit_with_parent"]

#: prctl(2) option: the signal this process gets when its parent dies
PR_SET_PDEATHSIG = 1


def exit_with_parent() -> None:
    """Linux: have the kernel send SIGTERM to this process when the thread that started it
    ends, even by the parent's SIGKILL, so that no orphaned pool process is left running a
    batch (elsewhere: no-op). Call it first in a ``multiprocessing`` child (the embedded
    server's pool, the CLI's ``--workers`` pool)."""
    parent = multiprocessing.parent_process()
    if not sys.platform.startswith("linux") or parent is None:
        return
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(PR_SET_PDEATHSIG, signal.SIGTERM)
    except (OSError, AttributeError):
        return
    # the parent died before prctl took effect (compare pids: the parent may itself be pid 1,
    # as in the Docker image)
    if os.getppid() != parent.pid:
        os._exit(0)
