"""Planned timing and the path figures, as the original timed it (docs/original.md, "2.7
Panel to arm frame, timing").

A segment is *marking* when both its ends are mark points, *approach* when either end is an
approach point, and travel otherwise. Marking and approach run at the marking feed, travel
at the travel feed; constant feed per segment (no acceleration profile), ``dt = len / feed``.
``lift_s`` is an ordering weight only: it is not in the planned time.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
from numpy.typing import NDArray

from tattotronix.path.params import ToolpathParams
from tattotronix.path.path3d import APPROACH, MARK, TRAVEL, Path3D, step_lengths

__all__ = ["PathMetrics", "measure", "segment_lengths", "timestamps"]


def segment_lengths(uvz_mm: NDArray[np.float64]) -> NDArray[np.float64]:
    """(N-1,) segment lengths, mm."""
    return step_lengths(uvz_mm)


def _marking(kind: NDArray[np.int8]) -> NDArray[np.bool_]:
    return (kind[:-1] == MARK) & (kind[1:] == MARK)


def _slow(kind: NDArray[np.int8]) -> NDArray[np.bool_]:
    """Segments at the marking feed: marking or approach."""
    return _marking(kind) | (kind[:-1] == APPROACH) | (kind[1:] == APPROACH)


def timestamps(path: Path3D, params: ToolpathParams,
               seg: NDArray[np.float64] | None = None) -> NDArray[np.float64]:
    """(N,) planned time of each point, s, starting at 0 (``seg``: the path's
    :func:`segment_lengths`, if made already)."""
    if len(path.kind) == 0:
        return np.zeros(0)
    feed = np.where(_slow(path.kind), params.feed_mark_mm_s, params.feed_travel_mm_s)
    seg = segment_lengths(path.uvz_mm) if seg is None else seg
    return np.concatenate([[0.0], np.cumsum(seg / feed)])


@dataclass(frozen=True)
class PathMetrics:
    """The figures of one path.

    Attributes:
        points: path points.
        marked_mm: length of marking segments (both ends mark points), mm.
        travel_mm: every other segment (approach included), mm.
        entries: needle entries: travel to non-travel transitions, plus one if the
            path starts with a non-travel point.
        drags: gaps between strokes crossed with the needle down.
        time_s: planned time, s.
    """

    points: int
    marked_mm: float
    travel_mm: float
    entries: int
    drags: int
    time_s: float

    def as_dict(self) -> dict[str, float | int]:
        """Plain JSON-ready dict."""
        return asdict(self)


def measure(path: Path3D, params: ToolpathParams, t_s: NDArray[np.float64] | None = None,
            seg: NDArray[np.float64] | None = None) -> PathMetrics:
    """Measure a path: lengths, needle entries, planned time (``t_s``: its
    :func:`timestamps`, ``seg``: its :func:`segment_lengths`, if made already)."""
    k = path.kind
    seg = segment_lengths(path.uvz_mm) if seg is None else seg
    marking = _marking(k) if len(k) else np.zeros(0, bool)
    entries = int(((k[:-1] == TRAVEL) & (k[1:] != TRAVEL)).sum()) + int(
        len(k) > 0 and k[0] != TRAVEL
    )
    t = timestamps(path, params, seg) if t_s is None else t_s
    return PathMetrics(
        points=int(len(k)),
        marked_mm=float(seg[marking].sum()),
        travel_mm=float(seg[~marking].sum()),
        entries=entries,
        drags=path.drags,
        time_s=float(t[-1]) if len(t) else 0.0,
    )
