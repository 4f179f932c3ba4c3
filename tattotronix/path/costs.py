"""The time cost of getting from the end of one stroke to the start of the next.

Between two strokes the needle either stays in the work and drags straight across (only
when that line stays on ink and is shorter than :attr:`ToolpathParams.drag_max_mm`), or
lifts: retract to clearance, travel straight at clearance, descend, approach slowly. The
ordering minimises the sum of these costs; the 3-D path builder makes the same choice, so
the ordering's objective is the planned time up to a constant (the marking itself).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from tattotronix.art.grid import InkMask
from tattotronix.path.inklookup import lines_on_ink
from tattotronix.path.params import ToolpathParams

__all__ = ["SAME_POINT_MM", "TransitionCosts", "can_drag"]

SAME_POINT_MM = 1e-9  # a stroke starting where the last ended needs no move at all


def can_drag(
    mask: InkMask, a_mm: NDArray[np.float64], b_mm: NDArray[np.float64], drag_max_mm: float
) -> NDArray[np.bool_]:
    """Whether the needle may stay down from each ``a`` to each ``b``.

    Args:
        mask: the ink mask.
        a_mm: (n, 2) where the needle is, mm.
        b_mm: (n, 2) where the next stroke starts, mm.
        drag_max_mm: longest gap crossed with the needle down, mm (``inf``: any).

    Returns:
        (n,) bool: the gap is (nearly) zero, or no longer than ``drag_max_mm`` with the
        straight line between the points on ink all the way.
    """
    a = np.asarray(a_mm, dtype=np.float64).reshape(-1, 2)
    b = np.asarray(b_mm, dtype=np.float64).reshape(-1, 2)
    d = np.linalg.norm(b - a, axis=1)
    ok = d <= SAME_POINT_MM
    test = ~ok & (d <= drag_max_mm)
    ok[test] = lines_on_ink(mask, a[test], b[test])
    return ok


class TransitionCosts:
    """Transition costs (s) between a fixed set of stroke endpoints.

    Lifts cost ``entry_cost_s + d / feed_travel``; drags cost ``d / feed_mark`` and are
    precomputed for every pair of endpoints within ``drag_max_mm`` (a k-d tree query,
    then one vectorised on-ink test).

    Attributes:
        pts: (m, 2) endpoints, mm.
        lift_s: the fixed cost of a needle entry, s.
        inv_travel: 1 / travel feed, s/mm.
        src, dst: (k,) directed endpoint pairs that may be crossed with the needle down,
            sorted by ``src`` then ``dst``.
        drag_s: (k,) their drag cost, s.
    """

    def __init__(
        self, pts: NDArray[np.float64], mask: InkMask, params: ToolpathParams,
        drag_max_mm: float | None = None,
    ):
        self.pts = np.asarray(pts, dtype=np.float64)
        self.lift_s = params.entry_cost_s
        self.inv_travel = 1.0 / params.feed_travel_mm_s
        inv_mark = 1.0 / params.feed_mark_mm_s
        reach = params.drag_max_mm if drag_max_mm is None else drag_max_mm
        m = len(self.pts)
        if m and not np.isfinite(reach):
            reach = float(np.ptp(self.pts, axis=0).max()) * 2.0 + 1.0
        pairs = (
            cKDTree(self.pts).query_pairs(reach, output_type="ndarray")
            if m > 1 else np.zeros((0, 2), np.intp)
        )
        pairs = pairs[can_drag(mask, self.pts[pairs[:, 0]], self.pts[pairs[:, 1]], reach)]
        src = np.concatenate([pairs[:, 0], pairs[:, 1]])
        dst = np.concatenate([pairs[:, 1], pairs[:, 0]])
        key = src.astype(np.int64) * m + dst
        order = np.argsort(key)
        self.m = m
        self.src, self.dst, self.key = src[order], dst[order], key[order]
        d = np.linalg.norm(self.pts[self.src] - self.pts[self.dst], axis=1)
        self.drag_s = np.where(d <= SAME_POINT_MM, 0.0, d * inv_mark)
        self.indptr = np.searchsorted(self.src, np.arange(m + 1))

    def lift(self, d_mm: NDArray[np.float64]) -> NDArray[np.float64]:
        """Cost of a lift over a horizontal distance ``d_mm``, s."""
        return self.lift_s + d_mm * self.inv_travel

    def between(self, a: NDArray[np.intp], b: NDArray[np.intp]) -> NDArray[np.float64]:
        """Cost from endpoints ``a`` to endpoints ``b`` (broadcast), s."""
        a, b = np.broadcast_arrays(np.asarray(a), np.asarray(b))
        cost = self.lift(np.linalg.norm(self.pts[a] - self.pts[b], axis=-1))
        if len(self.key):
            k = a.astype(np.int64) * self.m + b
            idx = np.minimum(np.searchsorted(self.key, k), len(self.key) - 1)
            hit = self.key[idx] == k
            cost[hit] = self.drag_s[idx[hit]]
        return cost

    def from_endpoint(self, a: int) -> NDArray[np.float64]:
        """Cost from endpoint ``a`` to every endpoint, (m,) s."""
        x, y = self.pts[:, 0], self.pts[:, 1]
        cost = self.lift(np.hypot(x - x[a], y - y[a]))
        lo, hi = self.indptr[a], self.indptr[a + 1]
        cost[self.dst[lo:hi]] = self.drag_s[lo:hi]
        return cost

    def corrections(self) -> tuple[NDArray[np.intp], NDArray[np.intp], NDArray[np.float64]]:
        """Every directed drag pair and its cost minus the lift cost, s (<= 0)."""
        d = np.linalg.norm(self.pts[self.src] - self.pts[self.dst], axis=1)
        return self.src, self.dst, self.drag_s - self.lift(d)
