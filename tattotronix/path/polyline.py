"""Polyline helpers in panel millimetres: smoothing, closing, length, arc-length resampling."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = ["close", "length_mm", "resample", "rotate_closed", "smooth_closed", "stations"]

#: passes of the circular [1, 2, 1] / 4 kernel (docs/original.md, "2.3 Outline tracing")
SMOOTH_PASSES = 2
SMOOTH_MIN_POINTS = 5  # shorter loops are left as traced
_EPS_MM = 1e-9  # points closer than this are the same point


def smooth_closed(points: NDArray[np.float64], passes: int = SMOOTH_PASSES) -> NDArray[np.float64]:
    """Smooth a closed polyline by circular [1, 2, 1] / 4 passes.

    Args:
        points: (n, 2) vertices, mm, the first point not repeated at the end.
        passes: how many passes; each moves a vertex at most half a grid step.

    Returns:
        (n, 2) smoothed vertices (unchanged when n < 5).
    """
    p = np.asarray(points, dtype=np.float64)
    if len(p) < SMOOTH_MIN_POINTS:
        return p.copy()
    for _ in range(passes):
        p = 0.25 * np.roll(p, 1, axis=0) + 0.5 * p + 0.25 * np.roll(p, -1, axis=0)
    return p


def close(points: NDArray[np.float64]) -> NDArray[np.float64]:
    """Repeat the first vertex at the end (no-op when already closed)."""
    p = np.asarray(points, dtype=np.float64)
    if len(p) and np.linalg.norm(p[-1] - p[0]) <= _EPS_MM:
        return p
    return np.vstack([p, p[:1]])


def rotate_closed(closed: NDArray[np.float64], start: int) -> NDArray[np.float64]:
    """Start a closed polyline (first vertex repeated at the end) at vertex ``start``."""
    ring = closed[:-1]
    start %= len(ring)
    return np.vstack([ring[start:], ring[: start + 1]])


def length_mm(points: NDArray[np.float64]) -> float:
    """Total chord length of a polyline, mm."""
    return float(np.linalg.norm(np.diff(points, axis=0), axis=1).sum())


def stations(total_mm: float, step_mm: float) -> NDArray[np.float64]:
    """Arc-length positions of the resampled points, mm.

    ``0, step, 2 step, ...`` strictly below the total, then the total itself: every step
    is exactly ``step_mm`` except the last, which is in (0, step_mm].
    """
    inner = np.arange(int(np.ceil(total_mm / step_mm)) + 1) * step_mm
    inner = inner[inner < total_mm - _EPS_MM * max(1.0, total_mm)]
    return np.append(inner, total_mm)


def resample(points: NDArray[np.float64], step_mm: float) -> NDArray[np.float64]:
    """Resample a polyline at a constant arc-length step, keeping its end point.

    Args:
        points: (n, 2) vertices, mm. A closed polyline (first vertex repeated) stays
            closed: its last resampled point is its first.
        step_mm: the step, mm.

    Returns:
        (m, 2) points at :func:`stations` along the polyline; a single point when the
        polyline has no length.
    """
    p = np.asarray(points, dtype=np.float64)
    seg = np.linalg.norm(np.diff(p, axis=0), axis=1)
    keep = np.concatenate([[True], seg > _EPS_MM])
    p, seg = p[keep], seg[seg > _EPS_MM]
    if len(p) < 2:
        return p[:1].copy()
    s = np.concatenate([[0.0], np.cumsum(seg)])
    st = stations(float(s[-1]), step_mm)
    out = np.column_stack([np.interp(st, s, p[:, 0]), np.interp(st, s, p[:, 1])])
    out[-1] = p[-1]  # exactly the end point (closed stays closed)
    return out
