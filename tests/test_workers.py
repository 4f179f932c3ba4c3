"""A study's pool ends, even when a worker is stuck in C (``io/workers.py``)."""

from __future__ import annotations

import ctypes
import multiprocessing
import os
import signal
import sys
import threading
import time

import pytest

from tattotronix.io.workers import worker_signals
from tattotronix.stage import stop_signals


def _stuck_in_c(_: int) -> int:
    """Lock a POSIX mutex twice: the thread blocks in the kernel (a futex), where no Python
    signal handler can run, for good."""
    libc = ctypes.CDLL(None)
    mutex = ctypes.create_string_buffer(64)  # zeroed: PTHREAD_MUTEX_INITIALIZER on glibc
    libc.pthread_mutex_lock(mutex)
    libc.pthread_mutex_lock(mutex)
    return 0


def _ends_in(initializer: object, seconds: float) -> bool:
    """Start a one-worker pool as a stage does (inside ``stop_signals``, whose handler the
    worker inherits), let the worker get stuck in C, and end the pool as leaving its
    ``with`` block does; True if that took under ``seconds``."""
    with stop_signals():
        pool = multiprocessing.get_context("fork").Pool(1, initializer)
        (worker,) = pool._pool  # noqa: SLF001 (to clean up after a failure)
        pool.map_async(_stuck_in_c, [0])
        time.sleep(0.5)  # the worker is in the mutex now
        ender = threading.Thread(target=pool.terminate, daemon=True)
        ender.start()
        ender.join(seconds)
        if ender.is_alive():  # hung: end the worker by force, so the test can report it
            os.kill(worker.pid, signal.SIGKILL)
            ender.join()
            return False
    return True


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's mutex layout")
def test_a_worker_stuck_in_c_dies_when_the_pool_ends() -> None:
    assert _ends_in(worker_signals, 10.0)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's mutex layout")
def test_without_it_the_pool_would_hang() -> None:
    """The case the initializer exists for: the stage's handler, inherited, never runs."""
    assert not _ends_in(None, 3.0)


def test_a_worker_leaves_ctrl_c_to_the_stage_and_sigterm_to_the_os() -> None:
    with stop_signals(), multiprocessing.get_context("fork").Pool(1, worker_signals) as pool:
        sigint, sigterm = pool.apply(_handlers)
    assert sigint == signal.SIG_IGN and sigterm == signal.SIG_DFL


def _handlers() -> tuple[object, object]:
    return signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM)
