"""Tracking error, exactly as the original defined it (docs/original.md, "5.5 Tracking error").

* The error is the 3-D distance between the tip at the simulated ``q`` and the tip at the
  reference ``q_r`` at the same instant (lag and depth included), sampled every
  ``sample_s`` (20 ms).
* A trajectory segment marks when both its points are marking points
  (``kind_i == kind_{i+1} == 1``); a sample is *down* when ``interp(t, t_points[:-1],
  m) > 0.5``.
* Needle entries are the rising edges of *down*; *settled* samples are the down samples
  outside ``[entry, entry + settle_periods / wn)`` after every entry.
* Reported: settled mean and max, marking mean and max (all down samples), travel mean
  (samples not down), in micrometres. A statistic with no sample to take it over is
  None, and ``tracking_reason`` says why (:data:`ERROR_KEYS`; a run that diverged has
  none at all: :meth:`TrackingErrors.unscored`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from tattotronix.config.schema import DrawConfig
from tattotronix.io.jsontypes import JsonDict
from tattotronix.trajectory.path import MARK

__all__ = ["ERROR_KEYS", "TrackingErrors", "busiest_window", "down_at", "entry_times",
           "tracking_errors"]

Array = NDArray[np.float64]
UM_PER_M = 1e6

#: the error statistics of :meth:`TrackingErrors.metrics`, each with why it can be None
ERROR_KEYS: dict[str, str] = {
    "settled_mean_um": "no settled marking sample",
    "settled_max_um": "no settled marking sample",
    "marking_mean_um": "no marking sample",
    "marking_max_um": "no marking sample",
    "entry_max_um": "no marking sample within the settling time after an entry",
    "travel_mean_um": "no travel sample",
    "worst_um": "no sample",
    "worst_at_s": "no sample",
    "marking_worst_at_s": "no marking sample",
}


def down_at(t_points: Array, kind: NDArray[np.int8], t: Array) -> NDArray[np.bool_]:
    """Whether the needle is marking at times ``t`` (the original's interpolated flag,
    docs/original.md, "5.5 Tracking error")."""
    m = ((kind[:-1] == MARK) & (kind[1:] == MARK)).astype(np.float64)
    return np.interp(t, t_points[:-1], m) > 0.5


def entry_times(t_points: Array, kind: NDArray[np.int8]) -> Array:
    """Needle entries along a trajectory: times where a marking segment follows a
    non-marking one (or starts the drawing), s."""
    m = (kind[:-1] == MARK) & (kind[1:] == MARK)
    rising = np.flatnonzero(m & ~np.concatenate(([False], m[:-1])))
    return t_points[rising]


def busiest_window(t_points: Array, kind: NDArray[np.int8],
                   length_s: float = 12.0) -> tuple[float, float]:
    """The ``length_s`` window with the most needle entries (docs/original.md, "5.5
    Tracking error").

    For each entry time ``t_e`` count entries in ``[t_e, t_e + length)``; start at the
    entry with the most (the first such). Returns ``(start_s, length_s)``.
    """
    te = entry_times(t_points, kind)
    if len(te) == 0:
        return 0.0, min(length_s, float(t_points[-1]))
    counts = np.searchsorted(te, te + length_s, side="left") - np.arange(len(te))
    start = float(te[int(np.argmax(counts))])
    return start, min(length_s, float(t_points[-1]) - start)


@dataclass(frozen=True)
class TrackingErrors:
    """The sampled errors and their summary.

    Attributes:
        t: (S,) sample times, s.
        error_m: (S,) 3-D tip error, m.
        down: (S,) marking samples.
        settled: (S,) marking samples outside the settling time after an entry.
        entries: needle entries among the samples.
    """

    t: Array
    error_m: Array
    down: NDArray[np.bool_]
    settled: NDArray[np.bool_]
    entries: int

    def _stats(self) -> JsonDict:
        e = self.error_m * UM_PER_M

        def stat(sel: NDArray[np.bool_], f: Any) -> float | None:
            return float(f(e[sel])) if sel.any() else None

        return {
            "settled_mean_um": stat(self.settled, np.mean),
            "settled_max_um": stat(self.settled, np.max),
            "marking_mean_um": stat(self.down, np.mean),
            "marking_max_um": stat(self.down, np.max),
            "entry_max_um": stat(self.down & ~self.settled, np.max),
            "travel_mean_um": stat(~self.down, np.mean),
            "worst_um": float(e.max()) if len(e) else None,
            "worst_at_s": float(self.t[int(np.argmax(e))]) if len(e) else None,
            "marking_worst_at_s": float(self.t[self.down][int(np.argmax(e[self.down]))])
            if self.down.any() else None,
            "samples": int(len(e)),
            "marking_samples": int(self.down.sum()),
            "entries": self.entries,
        }

    def metrics(self) -> JsonDict:
        """``settled_mean_um``, ``settled_max_um``, ``marking_mean_um``, ``marking_max_um``,
        ``travel_mean_um``, ``entry_max_um`` (the worst marking sample within the settling
        time after an entry), ``worst_um`` and where, ``samples``, ``entries``; a
        statistic with no sample is None, and ``tracking_reason`` names each and why
        ("" when every one is given)."""
        m = self._stats()
        why: dict[str, list[str]] = {}
        for key, reason in ERROR_KEYS.items():
            if m[key] is None:
                why.setdefault(reason, []).append(key)
        m["tracking_reason"] = "; ".join(f"{', '.join(keys)}: {reason}"
                                         for reason, keys in why.items())
        return m

    def unscored(self, reason: str) -> JsonDict:
        """:meth:`metrics` with every error statistic None, for ``reason`` (a run that
        diverged: its errors before the blow-up say nothing of the drawing, and the
        worst is unbounded); the sample counts stay."""
        m = self._stats()
        m.update(dict.fromkeys(ERROR_KEYS))
        m["tracking_reason"] = reason
        return m


def tracking_errors(t: Array, tip: Array, tip_ref: Array, t_points: Array,
                    kind: NDArray[np.int8], wn: float,
                    settle_periods: float = DrawConfig().settle_periods) -> TrackingErrors:
    """Score sampled tips against the reference (see the module docstring).

    Args:
        t: (S,) sample times, s (trajectory time).
        tip, tip_ref: (S, 3) simulated and reference tip positions, m.
        t_points, kind: the trajectory's point times and kinds.
        wn: the controller bandwidth, rad/s (settling time ``settle_periods / wn``).
        settle_periods: settling time in units of ``1 / wn``.
    """
    err = np.linalg.norm(np.asarray(tip) - np.asarray(tip_ref), axis=1)
    down = down_at(t_points, kind, t)
    rising = np.flatnonzero(down & ~np.concatenate(([False], down[:-1])))
    if len(down) and down[0]:
        rising = rising[rising != 0]  # a run that starts marking has no entry there
    settled = down.copy()
    settle = settle_periods / wn
    for i in rising:
        settled &= ~((t >= t[i]) & (t < t[i] + settle))
    return TrackingErrors(t=np.asarray(t), error_m=err, down=down, settled=settled,
                          entries=int(len(rising)))
