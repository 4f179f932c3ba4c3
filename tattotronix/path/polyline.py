"""Polyline helpers in panel millimetres: smoothing, closing, length, arc-length resampling.

:func:`resample_many` resamples many polylines in one vectorised pass (no Python loop per
polyline) and gives, bit for bit, what :func:`resample` gives each of them: the same
arc lengths (a sequential sum per polyline), the same stations and the same interpolation
formula as ``numpy.interp``. :func:`oriented` lays out many polylines drawn from any vertex
(closed ones) and in either direction, for it.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = ["close", "equal_chords", "length_mm", "oriented", "resample", "resample_many",
           "rotate_closed",
           "smooth_closed", "stations"]

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


def oriented(
    bounds: NDArray[np.intp], closed: NDArray[np.bool_], seam: NDArray[np.intp],
    reverse: NDArray[np.bool_],
) -> NDArray[np.intp]:
    """Vertex indices of many polylines, each started at its seam and maybe reversed.

    Polyline ``i`` holds the vertices ``bounds[i]:bounds[i + 1]`` of a shared array (at
    least one each); a closed one repeats its first vertex at the end. As
    ``Stroke.points`` does for one: a closed polyline with a non-zero ``seam`` starts at
    vertex ``seam`` (:func:`rotate_closed`), then a reversed one runs backwards. Every
    polyline keeps its vertex count, so ``bounds`` still delimits the result.

    Returns:
        (bounds[-1],) indices into the shared vertex array.
    """
    n = np.diff(bounds)
    start = np.repeat(bounds[:-1], n)
    t = np.arange(int(bounds[-1])) - start
    size = np.repeat(n, n)
    t = np.where(np.repeat(reverse, n), size - 1 - t, t)
    ring = np.maximum(size - 1, 1)
    rot = np.repeat(closed & (seam != 0), n)
    shift = np.repeat(seam, n) % ring
    return np.asarray(start + np.where(rot, (shift + t) % ring, t), dtype=np.intp)


def _segmented_cumsum(values: NDArray[np.float64], counts: NDArray[np.intp]
                      ) -> NDArray[np.float64]:
    """Cumulative sums restarting at each group, each one sequential like ``np.cumsum``.

    A running sum over the whole array would round differently; each group is summed
    on its own, in rows of a zero-padded table (groups of similar length together).
    """
    out = np.empty_like(values)
    if len(values) == 0:
        return out
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    nonempty = counts > 0
    bucket = np.zeros(len(counts), np.intp)
    bucket[nonempty] = np.ceil(np.log2(counts[nonempty])).astype(np.intp)
    for b_id in np.unique(bucket[nonempty]):
        rows = np.flatnonzero(nonempty & (bucket == b_id))
        c, s0 = counts[rows], starts[rows]
        if b_id == 0:  # one value each
            out[s0] = values[s0]
            continue
        width = int(c.max())
        col = np.arange(int(c.sum())) - np.repeat(np.cumsum(c) - c, c)
        src = np.repeat(s0, c) + col
        table = np.zeros((len(rows), width))
        table[np.repeat(np.arange(len(rows)), c), col] = values[src]
        out[src] = np.cumsum(table, axis=1)[np.repeat(np.arange(len(rows)), c), col]
    return out


def _count_below(limit: NDArray[np.float64], step_mm: float, cap: NDArray[np.intp] | None = None
                 ) -> NDArray[np.intp]:
    """Per limit L: how many q = 0, 1, ... (at most ``cap + 1`` of them) have
    ``q * step_mm < L``, with q * step_mm rounded as ``np.arange(...) * step_mm`` rounds it."""
    with np.errstate(invalid="ignore", over="ignore"):
        c = np.ceil(limit / step_mm)
    c = np.clip(np.nan_to_num(c, nan=0.0), 0, None).astype(np.intp)
    if cap is not None:
        c = np.minimum(c, cap + 1)
    while True:  # the ratio may round either way: settle on the exact count
        down = (c > 0) & ((c - 1) * step_mm >= limit)
        up = (c * step_mm < limit) if cap is None else (c <= cap) & (c * step_mm < limit)
        if not (down.any() or up.any()):
            return c
        c = c - down + up


def equal_chords(a_mm: NDArray[np.float64], b_mm: NDArray[np.float64], step_mm: float
                 ) -> tuple[NDArray[np.float64], NDArray[np.intp]]:
    """Straight lines from each ``a`` to its ``b`` in equal chords no longer than
    ``step_mm`` (:func:`resample` would end each with a remainder chord, as short as a few
    micrometres, beside whatever corner the line meets).

    Args:
        a_mm, b_mm: (k, 2) the lines' ends, mm.
        step_mm: the longest chord, mm.

    Returns:
        ``(out, out_bounds)`` as :func:`resample_many` gives them: line ``i`` is
        ``out[out_bounds[i]:out_bounds[i + 1]]``, from ``a`` to ``b`` exactly (one point,
        ``b``, for a line with no length).
    """
    a = np.asarray(a_mm, dtype=np.float64).reshape(-1, 2)
    b = np.asarray(b_mm, dtype=np.float64).reshape(-1, 2)
    d = np.linalg.norm(b - a, axis=1)
    chords = np.where(d > _EPS_MM, np.maximum(np.ceil(d / step_mm - 1e-9), 1), 0)
    sizes = chords.astype(np.intp) + 1
    ob = np.concatenate([[0], np.cumsum(sizes)]).astype(np.intp)
    owner = np.repeat(np.arange(len(a)), sizes)
    frac = (np.arange(int(ob[-1])) - ob[owner]) / np.maximum(chords[owner], 1)
    out = a[owner] + frac[:, None] * (b - a)[owner]
    out[ob[1:] - 1] = b  # exactly the end (a line with no length: its one point)
    return out, ob


def resample_many(
    points: NDArray[np.float64], bounds: NDArray[np.intp], step_mm: float
) -> tuple[NDArray[np.float64], NDArray[np.intp]]:
    """:func:`resample` of many polylines at once, with the very same results.

    Args:
        points: (N, 2) vertices of every polyline, mm, one after the other.
        bounds: (k + 1,) polyline ``i`` is ``points[bounds[i]:bounds[i + 1]]`` (at least
            one vertex each).
        step_mm: the step, mm.

    Returns:
        ``(out, out_bounds)``: the resampled points of every polyline one after the other,
        polyline ``i`` being ``out[out_bounds[i]:out_bounds[i + 1]]``, equal to
        ``resample(points[bounds[i]:bounds[i + 1]], step_mm)``.
    """
    p = np.asarray(points, dtype=np.float64)
    bounds = np.asarray(bounds, dtype=np.intp)
    k = len(bounds) - 1
    n = np.diff(bounds)
    if k == 0:
        return np.zeros((0, 2)), np.zeros(1, np.intp)
    owner = np.repeat(np.arange(k), n)
    d = p[1:] - p[:-1]
    seg = np.sqrt(d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1])  # as np.linalg.norm(axis=1)
    long_seg = (owner[1:] == owner[:-1]) & (seg > _EPS_MM)
    keep = np.ones(len(p), bool)
    keep[1:] = long_seg
    keep[bounds[:-1]] = True
    q = p[keep]
    kept = np.bincount(owner[keep], minlength=k)  # vertices kept per polyline
    qb = np.concatenate([[0], np.cumsum(kept)])
    arc = np.zeros(len(q))  # s: 0 at each polyline's first kept vertex
    inner = np.ones(len(q), bool)
    inner[qb[:-1]] = False
    arc[inner] = _segmented_cumsum(seg[long_seg], kept - 1)
    total = arc[qb[1:] - 1]
    # stations: q step strictly below total - eps max(1, total), then the total
    qmax = np.ceil(total / step_mm).astype(np.intp)
    n_st = _count_below(total - _EPS_MM * np.maximum(1.0, total), step_mm, qmax)
    n_st[kept < 2] = 0
    n_out = n_st + 1
    ob = np.concatenate([[0], np.cumsum(n_out)])
    out = np.empty((int(ob[-1]), 2))
    out[ob[1:] - 1] = q[qb[1:] - 1]  # the end point, exactly
    # interpolate the stations below the total: j = the last vertex at or before them
    m = int(n_st.sum())
    if m:
        owner_q = np.repeat(np.arange(k), kept)
        a_v = _count_below(arc[inner], step_mm)  # stations strictly before each vertex
        owner_v = owner_q[inner]
        hit = a_v < n_st[owner_v]
        cum = np.cumsum(np.bincount(ob[owner_v[hit]] + a_v[hit], minlength=int(ob[-1])))
        before = np.concatenate([[0], cum[ob[1:-1] - 1]])  # marks of earlier polylines
        st_owner = np.repeat(np.arange(k), n_st)
        st_idx = np.arange(m) - np.repeat(ob[:-1] - np.arange(k), n_st)
        g = ob[st_owner] + st_idx  # the station's row in out
        j = (qb[:-1] - before)[st_owner] + cum[g]
        x = st_idx * step_mm
        sj, sj1 = arc[j], arc[j + 1]
        on_vertex = sj == x
        for c in (0, 1):
            fj, fj1 = q[j, c], q[j + 1, c]
            slope = (fj1 - fj) / (sj1 - sj)
            out[g, c] = np.where(on_vertex, fj, slope * (x - sj) + fj)
    return out, ob
