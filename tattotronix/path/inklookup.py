"""Is a panel point, or a straight line between two points, on ink? (nearest-pixel lookup)

A line is on ink when every pixel it passes through is ink, each pixel being the square
of panel points nearest to its centre, taken closed and grown by 1e-9 px on each side (so
a line through a pixel corner, or along a pixel edge, needs the pixels on both sides).
:func:`lines_on_ink` walks each line strip by strip across the grid (one strip per column,
or per row for a line that spans fewer rows than columns) and counts the background
pixels it covers in each strip from prefix sums, with no loop per line.
The former method, one sample inside each piece of the line between two cell edges
looked up with :func:`ink_at`, is the tests' reference (tests/test_path_fast.py).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from tattotronix.art.grid import InkMask

__all__ = ["grid_index", "ink_at", "lines_on_ink"]


_TIE = 1e-9  # a coordinate this close to halfway between two pixels is a tie


def grid_index(
    mask: InkMask, xy_mm: NDArray[np.float64], tie: float = 0.0
) -> tuple[NDArray[np.intp], NDArray[np.intp], NDArray[np.bool_]]:
    """Nearest grid (row, col) of panel points, and whether they fall inside the grid.

    Args:
        mask: the ink mask (uniform grid; ``xs`` increasing, ``ys`` decreasing).
        xy_mm: (..., 2) panel points, mm.
        tie: shift (in pixels) applied before rounding: a point halfway between two
            pixels goes to the lower index with ``-tie`` and to the upper with ``+tie``.

    Returns:
        ``(row, col, inside)``; row and col are clipped to the grid.
    """
    h, w = mask.ink.shape
    fc = (xy_mm[..., 0] - mask.xs[0]) / mask.res_mm
    fr = (mask.ys[0] - xy_mm[..., 1]) / mask.res_mm
    col = np.floor(fc + (0.5 + tie)).astype(np.intp)
    row = np.floor(fr + (0.5 + tie)).astype(np.intp)
    inside = (col >= 0) & (col < w) & (row >= 0) & (row < h)
    return np.clip(row, 0, h - 1), np.clip(col, 0, w - 1), inside


def ink_at(mask: InkMask, xy_mm: NDArray[np.float64]) -> NDArray[np.bool_]:
    """Ink at the nearest pixel of each point (False outside the grid).

    A point exactly halfway between pixels (within 1e-9 px) is on ink only if every
    pixel it could round to is ink, so the answer does not depend on a rounding rule.
    """
    xy = np.asarray(xy_mm, dtype=np.float64)
    r0, c0, in0 = grid_index(mask, xy, -_TIE)
    r1, c1, in1 = grid_index(mask, xy, _TIE)
    ink = mask.ink
    return in0 & in1 & ink[r0, c0] & ink[r1, c1] & ink[r0, c1] & ink[r1, c0]


def lines_on_ink(
    mask: InkMask, a_mm: NDArray[np.float64], b_mm: NDArray[np.float64], chunk: int = 1 << 20
) -> NDArray[np.bool_]:
    """Whether each straight line a -> b stays on ink, under the nearest-pixel reading.

    Every pixel whose square (closed, grown by 1e-9 px) the line meets must be ink and
    inside the grid. The line is cut into strips, one per grid column it meets (or per
    row, for a line that meets fewer rows than columns); in each strip the pixels it meets
    form one run, whose background pixels are counted from prefix sums
    (:attr:`InkMask.background_runs`).

    Args:
        mask: the ink mask.
        a_mm: (n, 2) line starts, mm.
        b_mm: (n, 2) line ends, mm.
        chunk: (line, strip) pairs evaluated at once (bounds memory).

    Returns:
        (n,) bool: every pixel the line passes through is ink.
    """
    a = np.asarray(a_mm, dtype=np.float64).reshape(-1, 2)
    b = np.asarray(b_mm, dtype=np.float64).reshape(-1, 2)
    if len(a) == 0:
        return np.ones(0, dtype=bool)
    h, w = mask.ink.shape
    # endpoints in pixel units: u along columns, v along rows
    u = (np.column_stack([a[:, 0], b[:, 0]]) - mask.xs[0]) / mask.res_mm
    v = (mask.ys[0] - np.column_stack([a[:, 1], b[:, 1]])) / mask.res_mm
    c0 = np.ceil(u.min(axis=1) - 0.5 - _TIE).astype(np.intp)
    c1 = np.floor(u.max(axis=1) + 0.5 + _TIE).astype(np.intp)
    r0 = np.ceil(v.min(axis=1) - 0.5 - _TIE).astype(np.intp)
    r1 = np.floor(v.max(axis=1) + 0.5 + _TIE).astype(np.intp)
    out = (c0 >= 0) & (c1 < w) & (r0 >= 0) & (r1 < h)
    by_col = (c1 - c0) <= (r1 - r0)
    col_runs, row_runs = mask.background_runs
    for pick, su, sv, lo, hi, vlo, vhi, runs in (
        (out & by_col, u, v, c0, c1, r0, r1, col_runs),
        (out & ~by_col, v, u, r0, r1, c0, c1, row_runs),
    ):
        idx = np.flatnonzero(pick)
        strips = hi[idx] - lo[idx] + 1
        step = max(1, chunk // max(1, int(strips.max(initial=1))))
        for i in range(0, len(idx), step):
            g = idx[i : i + step]
            out[g] = _strips_clear(su[g], sv[g], lo[g], hi[g], vlo[g], vhi[g], runs)
    return out


def _strips_clear(
    u: NDArray[np.float64], v: NDArray[np.float64], s0: NDArray[np.intp], s1: NDArray[np.intp],
    v0: NDArray[np.intp], v1: NDArray[np.intp], runs: NDArray[np.int32],
) -> NDArray[np.bool_]:
    """Per line (endpoints ``u``, ``v``, (n, 2), pixel units; strips ``s0..s1`` along u,
    pixels ``v0..v1`` across): no background pixel in the run it meets in any strip.
    ``runs[k, s]`` counts the background pixels before ``k`` in strip ``s``."""
    n = len(u)
    count = s1 - s0 + 1
    line = np.repeat(np.arange(n), count)
    s = np.arange(int(count.sum())) - np.repeat(np.cumsum(count) - count, count) + s0[line]
    ua, ub, va, vb = u[line, 0], u[line, 1], v[line, 0], v[line, 1]
    umin, umax = np.minimum(ua, ub), np.maximum(ua, ub)
    # the part of the line in strip s (grown by the tie), and its extent across
    x1 = np.maximum(umin, s - 0.5 - _TIE)
    x2 = np.minimum(umax, s + 0.5 + _TIE)
    with np.errstate(divide="ignore", invalid="ignore"):
        slope = (vb - va) / (ub - ua)
    flat = ~np.isfinite(slope) | (ub == ua)  # along v (or a point): the whole extent
    slope[flat] = 0.0
    y1 = np.where(flat, np.minimum(va, vb), va + slope * (x1 - ua))
    y2 = np.where(flat, np.maximum(va, vb), va + slope * (x2 - ua))
    k0 = np.ceil(np.minimum(y1, y2) - 0.5 - _TIE).astype(np.intp)
    k1 = np.floor(np.maximum(y1, y2) + 0.5 + _TIE).astype(np.intp)
    k0 = np.clip(k0, v0[line], v1[line])
    k1 = np.clip(k1, v0[line], v1[line])
    background = runs[k1 + 1, s] - runs[k0, s]
    return np.bincount(line, weights=background, minlength=n) == 0
