"""Forked worker processes: how many this process may use, and how a worker leaves
Ctrl-C to the stage (which ends its pool, and so the worker, as it stops)."""

from __future__ import annotations

import os
import signal

__all__ = ["ignore_ctrl_c", "usable_cores"]


def usable_cores() -> int:
    """The cores this process may run on (its affinity where the OS has one)."""
    if hasattr(os, "sched_getaffinity"):
        return len(os.sched_getaffinity(0))
    return os.cpu_count() or 1


def ignore_ctrl_c() -> None:
    """A pool's initializer: the worker leaves Ctrl-C to the stage, which stops the pool
    (and so the worker)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
