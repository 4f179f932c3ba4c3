"""Wall time per named step of the toolpath planner (for the benchmark and the logs)."""

from __future__ import annotations

import time

__all__ = ["Laps"]


class Laps:
    """A stopwatch that books the time since the last lap to a named step.

    ``lap(name)`` adds the wall time since the previous lap (or since the stopwatch was
    made) to ``name``; ``skip()`` drops it. The figures never change what is planned.
    """

    def __init__(self) -> None:
        self.seconds: dict[str, float] = {}
        self._t = time.perf_counter()

    def lap(self, name: str) -> None:
        """Book the time since the last lap to ``name``."""
        t = time.perf_counter()
        self.seconds[name] = self.seconds.get(name, 0.0) + (t - self._t)
        self._t = t

    def skip(self) -> None:
        """Restart the clock without booking the time since the last lap."""
        self._t = time.perf_counter()
