"""Forked worker processes: how many this process may use, and how a worker leaves
Ctrl-C to the stage (which ends its pool, and so the worker, as it stops) and dies at once
when the pool ends it."""

from __future__ import annotations

import os
import signal

__all__ = ["usable_cores", "worker_signals"]


def usable_cores() -> int:
    """The cores this process may run on (its affinity where the OS has one)."""
    if hasattr(os, "sched_getaffinity"):
        return len(os.sched_getaffinity(0))
    return os.cpu_count() or 1


def worker_signals() -> None:
    """A pool's initializer. The worker leaves Ctrl-C to the stage, which stops the pool
    (and so the worker). SIGTERM and SIGHUP take their default action, ending the worker
    at once: a worker inherits the stage's Python handler (``stage.stop_signals``), which
    runs only when the worker's main thread is back in the interpreter, so a worker blocked
    in C (waiting on a lock) would outlive the pool's ``terminate()``, and the stage would
    hang at its end."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    for name in ("SIGTERM", "SIGHUP"):
        sig = getattr(signal, name, None)
        if sig is not None and signal.getsignal(sig) != signal.SIG_IGN:
            signal.signal(sig, signal.SIG_DFL)
