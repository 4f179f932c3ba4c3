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
#: most entries of the cost matrices kept between every two endpoints (32 MiB each);
#: above it, rows are computed as needed
MAX_MATRIX = 1 << 22
_TRIANGLE_ROWS = 128


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
        drag_max_mm: float | None = None, *, reuse: TransitionCosts | None = None,
        moved: NDArray[np.bool_] | None = None,
    ):
        """Precompute the drag pairs of ``pts``.

        Args:
            pts: (m, 2) endpoints, mm.
            mask: the ink mask.
            params: feeds, lift geometry, ``drag_max_mm``.
            drag_max_mm: longest drag, mm; default ``params.drag_max_mm``.
            reuse: costs of the same endpoints before some of them moved (same mask,
                parameters and reach): its drag pairs between endpoints that did not move
                are kept, and only pairs with a moved endpoint are searched and tested.
                The result is the same as without it.
            moved: (m,) with ``reuse``: which endpoints moved.
        """
        self.pts = np.asarray(pts, dtype=np.float64)
        self.lift_s = params.entry_cost_s
        self.inv_travel = 1.0 / params.feed_travel_mm_s
        inv_mark = 1.0 / params.feed_mark_mm_s
        reach = params.drag_max_mm if drag_max_mm is None else drag_max_mm
        m = len(self.pts)
        self.m = m
        if m and not np.isfinite(reach):
            reach = float(np.ptp(self.pts, axis=0).max()) * 2.0 + 1.0
        self.reach = reach
        self._lifts: NDArray[np.float64] | None = None
        self._matrix: NDArray[np.float64] | None = None
        if reuse is not None and moved is not None and reuse.reach == reach and reuse.m == m:
            pairs = self._moved_pairs(reuse, moved, mask)
            if reuse._lifts is not None:  # the lifts between endpoints that stayed
                lifts = reuse._lifts.copy()
                mv = np.flatnonzero(moved)
                x, y = self.pts[:, 0], self.pts[:, 1]
                rows = self.lift(np.hypot(x[None, :] - x[mv, None], y[None, :] - y[mv, None]))
                lifts[mv, :] = rows
                lifts[:, mv] = rows.T
                self._lifts = lifts
        else:
            pairs = (
                cKDTree(self.pts).query_pairs(reach, output_type="ndarray")
                if m > 1 else np.zeros((0, 2), np.intp)
            )
            pairs = pairs[can_drag(mask, self.pts[pairs[:, 0]], self.pts[pairs[:, 1]], reach)]
        src = np.concatenate([pairs[:, 0], pairs[:, 1]])
        dst = np.concatenate([pairs[:, 1], pairs[:, 0]])
        key = src.astype(np.int64) * m + dst
        order = np.argsort(key)
        self.src, self.dst, self.key = src[order], dst[order], key[order]
        d = np.linalg.norm(self.pts[self.src] - self.pts[self.dst], axis=1)
        self.drag_s = np.where(d <= SAME_POINT_MM, 0.0, d * inv_mark)
        self.indptr = np.searchsorted(self.src, np.arange(m + 1))

    def _moved_pairs(self, old: TransitionCosts, moved: NDArray[np.bool_], mask: InkMask
                     ) -> NDArray[np.intp]:
        """(k, 2) drag pairs (i < j): ``old``'s between endpoints that stayed, and the pairs
        with a moved endpoint within reach (tested as ``cKDTree.query_pairs`` does: the
        squared distance against the squared reach) that pass :func:`can_drag`."""
        keep = (old.src < old.dst) & ~moved[old.src] & ~moved[old.dst]
        kept = np.column_stack([old.src[keep], old.dst[keep]])
        mv = np.flatnonzero(moved)
        d = self.pts[mv][:, None, :] - self.pts[None, :, :]
        near = d[..., 0] * d[..., 0] + d[..., 1] * d[..., 1] <= self.reach * self.reach
        near[np.arange(len(mv)), mv] = False
        i, j = np.nonzero(near)
        a, b = mv[i], j
        lo, hi = np.minimum(a, b), np.maximum(a, b)
        once = ~(moved[lo] & moved[hi]) | (a < b)  # a pair of two moved endpoints, once
        lo, hi = lo[once], hi[once]
        ok = can_drag(mask, self.pts[lo], self.pts[hi], self.reach)
        return np.concatenate([kept, np.column_stack([lo[ok], hi[ok]])]).astype(np.intp)

    def lifts(self, max_entries: int | None = None) -> NDArray[np.float64] | None:
        """(m, m) lift cost between every two endpoints (drags not applied; the
        ``hypot`` distance, as :meth:`from_endpoint`), made once; None when it would hold
        more than ``max_entries`` entries. One triangle is computed and mirrored
        (``hypot`` ignores the signs)."""
        m = self.m
        if m * m > (MAX_MATRIX if max_entries is None else max_entries):
            return None
        if self._lifts is None:
            x, y = self.pts[:, 0], self.pts[:, 1]
            lifts = np.empty((m, m))
            for r0 in range(0, m, _TRIANGLE_ROWS):
                r1 = min(m, r0 + _TRIANGLE_ROWS)
                block = self.lift(
                    np.hypot(x[None, r0:] - x[r0:r1, None], y[None, r0:] - y[r0:r1, None]))
                lifts[r0:r1, r0:] = block
                lifts[r0:, r0:r1] = block.T
            self._lifts = lifts
        return self._lifts

    def matrix(self, max_entries: int | None = None) -> NDArray[np.float64] | None:
        """(m, m) cost from every endpoint to every endpoint (row ``a`` is
        :meth:`from_endpoint` ``(a)``), made once; None when it would hold more than
        ``max_entries`` entries."""
        lifts = self.lifts(max_entries)
        if lifts is None:
            return None
        if self._matrix is None:
            cost = lifts.copy()
            cost[self.src, self.dst] = self.drag_s
            self._matrix = cost
        return self._matrix

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
