"""Stroke ordering: the original's rule, and ours (greedy, then 2-opt and seam moves).

The objective is the planned time spent between strokes (:mod:`tattotronix.path.costs`):
a needle entry costs over half a second at the default feeds (the lift, the travel back
down and the slow approach at the marking feed), so the search
mostly trades entries for drags along ink, then shortens the travel.

Ours:

1. Greedy nearest neighbour in time: from the current needle position, the cheapest
   unvisited stroke, entered at either end (strokes may be reversed). A few starting
   strokes are tried (the extreme endpoints of the drawing); the cheapest tour is kept.
2. 2-opt: reverse a run of consecutive strokes (which also reverses each of them). All
   O(n^2) moves are scored at once with numpy, in row blocks; every pass applies the best
   improving move of each row that does not touch another applied move.
3. Seams: a closed outline may start (and end) at any of its vertices; each takes the
   vertex that makes the move in plus the move out cheapest (a seam next to the first fill
   row lets the needle stay down into the fill). Then 2-opt runs again on the new ends.

With ``outlines_first`` every outline of a region comes before any of its fill rows (the
greedy only unlocks a region's fill once its outlines are drawn, and 2-opt rejects moves
that would break the rule). If the result is not cheaper than the original's order, the
original's order is kept, as vpype's linesort does.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from tattotronix.art.grid import InkMask
from tattotronix.path.costs import TransitionCosts, can_drag
from tattotronix.path.params import ToolpathParams
from tattotronix.path.strokes import Drawing, StrokeKind

__all__ = ["Order", "OrderResult", "optimise_order", "original_order"]

_GAIN_TOL_S = 1e-9  # a move must save more than this to count
_BLOCK_ROWS = 256  # 2-opt rows scored at once (bounds memory to ~ rows x n)
MAX_PASSES = 200  # 2-opt passes in all: a budget of work, never of wall time


@dataclass(frozen=True)
class Order:
    """A drawing order.

    Attributes:
        sequence: (n,) stroke indices in drawing order.
        reverse: (n,) per position, whether the stroke is drawn backwards.
        seam: (n,) per position, the vertex a closed outline starts at (0 for fill).
    """

    sequence: NDArray[np.intp]
    reverse: NDArray[np.bool_]
    seam: NDArray[np.intp]

    def points(self, drawing: Drawing, step_mm: float) -> list[NDArray[np.float64]]:
        """Each stroke resampled at ``step_mm``, in drawing order, oriented as ordered."""
        return [
            drawing.strokes[int(s)].points(step_mm, int(seam), bool(rev))
            for s, rev, seam in zip(self.sequence, self.reverse, self.seam, strict=True)
        ]


@dataclass(frozen=True)
class OrderResult:
    """An optimised order and how it was found.

    Attributes:
        order: the order.
        cost_s: its time between strokes (drags and lifts), s.
        greedy_cost_s: the same after the greedy step alone, s.
        original_cost_s: the same for the original's order, s.
        passes: 2-opt passes run.
        moves: 2-opt moves applied.
        reversed: strokes drawn backwards (open strokes only).
        kept_original: the original's order was not beaten and was kept.
        elapsed_s: wall time of the search, s.
    """

    order: Order
    cost_s: float
    greedy_cost_s: float
    original_cost_s: float
    passes: int
    moves: int
    reversed: int
    kept_original: bool
    elapsed_s: float


def original_order(drawing: Drawing) -> Order:
    """The original's order: the drawing's own (regions left to right, outline, holes, fill)."""
    n = len(drawing.strokes)
    return Order(np.arange(n), np.zeros(n, bool), np.zeros(n, np.intp))


def _endpoints(drawing: Drawing, seam: NDArray[np.intp]) -> NDArray[np.float64]:
    """(2n, 2): row 2i is stroke i's start, row 2i + 1 its end, for the given seams."""
    pts = np.empty((2 * len(drawing.strokes), 2))
    for i, s in enumerate(drawing.strokes):
        if s.closed:
            pts[2 * i] = pts[2 * i + 1] = s.path_mm[int(seam[i]) % (len(s.path_mm) - 1)]
        else:
            pts[2 * i], pts[2 * i + 1] = s.path_mm[0], s.path_mm[-1]
    return pts


def _ends(seq: NDArray[np.intp], rev: NDArray[np.bool_]
          ) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """Entry and exit endpoint ids per position."""
    entry = 2 * seq + rev
    return entry, 2 * seq + 1 - rev


def _transitions(costs: TransitionCosts, seq: NDArray[np.intp], rev: NDArray[np.bool_]
                 ) -> NDArray[np.float64]:
    entry, exit_ = _ends(seq, rev)
    return costs.between(exit_[:-1], entry[1:])


class _Precedence:
    """The ``outlines_first`` rule: a region's fill rows come after all its outlines."""

    def __init__(self, drawing: Drawing, enabled: bool):
        self.enabled = enabled
        self.outline = drawing.kinds != StrokeKind.FILL
        self.region = drawing.region_of
        self.regions = int(self.region.max()) + 1 if len(self.region) else 0

    def reach(self, seq: NDArray[np.intp]) -> NDArray[np.intp]:
        """Per position i: the first position a run starting at i may not include.

        A run [i, j] may be reversed iff it holds no outline and fill of one region, i.e.
        iff ``j < reach[i]``: the first fill at q >= i whose region has an outline at a
        position >= i (so between i and q, as the order is feasible).
        """
        n = len(seq)
        if not self.enabled or n == 0:
            return np.full(n, n, np.intp)
        outline = self.outline[seq]
        region = self.region[seq]
        last = np.full(self.regions, -1, np.intp)
        np.maximum.at(last, region[outline], np.flatnonzero(outline))
        lpos = np.where(outline, -1, last[region])  # fill at q needs its outlines <= lpos[q]
        # reach[i] = min{q : lpos[q] >= i}: suffix minimum over lpos values
        first_q = np.full(n + 1, n, np.intp)
        fills = np.flatnonzero(lpos >= 0)
        np.minimum.at(first_q, lpos[fills], fills)
        return np.minimum.accumulate(first_q[::-1])[::-1][:n]


def _greedy(
    costs: TransitionCosts, prec: _Precedence, first: int
) -> tuple[NDArray[np.intp], NDArray[np.bool_]]:
    """Nearest neighbour in time from endpoint ``first``, with reversal and precedence."""
    n = len(costs.pts) // 2
    visited = np.zeros(n, bool)
    remaining = np.bincount(prec.region[prec.outline], minlength=prec.regions)
    blocked = ~prec.outline & (remaining[prec.region] > 0) if prec.enabled else visited.copy()
    fills_of = [np.flatnonzero((prec.region == r) & ~prec.outline) for r in range(prec.regions)]
    seq = np.empty(n, np.intp)
    rev = np.empty(n, bool)
    cost = np.zeros((n, 2))
    i, o = divmod(first, 2)
    for k in range(n):
        if k > 0:
            cost[:] = costs.from_endpoint(2 * i + 1 - o).reshape(n, 2)  # from the last exit
            cost[visited | blocked] = np.inf
            i, o = divmod(int(np.argmin(cost)), 2)
        seq[k], rev[k] = i, bool(o)
        visited[i] = True
        if prec.enabled and prec.outline[i]:
            r = prec.region[i]
            remaining[r] -= 1
            if remaining[r] == 0:
                blocked[fills_of[r]] = False
    return seq, rev


def _two_opt(
    costs: TransitionCosts, seq: NDArray[np.intp], rev: NDArray[np.bool_], prec: _Precedence,
    max_passes: int,
) -> tuple[NDArray[np.intp], NDArray[np.bool_], int, int]:
    """Improve by reversing runs of strokes until no move helps or ``max_passes`` passes
    have run (a work budget, not a time budget: the result never depends on the machine)."""
    seq, rev = seq.copy(), rev.copy()
    n, m = len(seq), len(costs.pts)
    passes = moves = 0
    if n < 2:
        return seq, rev, passes, moves
    src, dst, corr = costs.corrections()
    jj = np.arange(n)
    while passes < max_passes:
        passes += 1
        entry, exit_ = _ends(seq, rev)
        t = costs.between(exit_[:-1], entry[1:])
        t_prev, t_next = np.concatenate([[0.0], t]), np.concatenate([t, [0.0]])
        reach = prec.reach(seq)
        pos = np.empty(m, np.intp)
        pos[entry] = pos[exit_] = jj
        is_exit = np.zeros(m, bool)
        is_exit[exit_] = True
        # drag corrections: term A c(exit[i-1], exit[j]); term B c(entry[i], entry[j+1])
        sel_a = is_exit[src] & is_exit[dst]
        sel_b = ~is_exit[src] & ~is_exit[dst]
        ci = np.concatenate([pos[src[sel_a]] + 1, pos[src[sel_b]]])
        cj = np.concatenate([pos[dst[sel_a]], pos[dst[sel_b]] - 1])
        cc = np.concatenate([corr[sel_a], corr[sel_b]])
        ok = (ci < n) & (cj >= ci)
        ci, cj, cc = ci[ok], cj[ok], cc[ok]
        by_row = np.argsort(ci, kind="stable")
        ci, cj, cc = ci[by_row], cj[by_row], cc[by_row]
        ex, en = costs.pts[exit_], costs.pts[entry]
        best = np.full(n, np.inf)
        best_j = np.zeros(n, np.intp)
        for i0 in range(0, n, _BLOCK_ROWS):
            ii = np.arange(i0, min(n, i0 + _BLOCK_ROWS))
            prev = ex[np.maximum(ii - 1, 0)]
            a = costs.lift(np.hypot(prev[:, :1] - ex[:, 0], prev[:, 1:] - ex[:, 1]))
            a[ii == 0] = 0.0
            b = np.zeros_like(a)
            b[:, :-1] = costs.lift(
                np.hypot(en[ii, :1] - en[1:, 0], en[ii, 1:] - en[1:, 1])
            )
            d = a + b - t_prev[ii, None] - t_next[None, :]
            lo, hi = np.searchsorted(ci, [ii[0], ii[-1] + 1])
            np.add.at(d, (ci[lo:hi] - i0, cj[lo:hi]), cc[lo:hi])
            d[(jj[None, :] < ii[:, None]) | (jj[None, :] >= reach[ii, None])] = np.inf
            best_j[ii] = d.argmin(axis=1)
            best[ii] = d[np.arange(len(ii)), best_j[ii]]
        cand = np.flatnonzero(best < -_GAIN_TOL_S)
        if len(cand) == 0:
            break
        busy = np.zeros(n, bool)
        for i in cand[np.argsort(best[cand], kind="stable")]:
            j = int(best_j[i])
            lo, hi = max(i - 1, 0), min(j + 1, n - 1)
            if busy[lo : hi + 1].any():
                continue
            busy[lo : hi + 1] = True
            seq[i : j + 1] = seq[i : j + 1][::-1].copy()
            rev[i : j + 1] = ~rev[i : j + 1][::-1]
            moves += 1
    return seq, rev, passes, moves


def _optimise_seams(
    drawing: Drawing, seq: NDArray[np.intp], rev: NDArray[np.bool_], seam: NDArray[np.intp],
    mask: InkMask, params: ToolpathParams, costs: TransitionCosts,
) -> NDArray[np.intp]:
    """Per closed outline (by stroke), the vertex minimising the move in plus the move out."""
    seam = seam.copy()
    pts = costs.pts.copy()
    entry, exit_ = _ends(seq, rev)
    inv_mark = 1.0 / params.feed_mark_mm_s
    for k, s in enumerate(seq):
        stroke = drawing.strokes[int(s)]
        if not stroke.closed:
            continue
        ring = stroke.path_mm[:-1]
        total = np.zeros(len(ring))
        for q in ([pts[exit_[k - 1]]] if k > 0 else []) + (
            [pts[entry[k + 1]]] if k + 1 < len(seq) else []
        ):
            dist = np.linalg.norm(ring - q, axis=1)
            c = costs.lift(dist)
            near = np.flatnonzero(dist <= params.drag_max_mm)
            drag = near[can_drag(mask, np.broadcast_to(q, (len(near), 2)), ring[near],
                                 params.drag_max_mm)]
            c[drag] = dist[drag] * inv_mark
            total += c
        best = int(np.argmin(total))
        if total[best] < total[int(seam[s]) % len(ring)] - _GAIN_TOL_S:
            seam[s] = best
            pts[2 * s] = pts[2 * s + 1] = ring[best]
    return seam


def optimise_order(
    drawing: Drawing, mask: InkMask, params: ToolpathParams, max_passes: int = MAX_PASSES,
    rounds: int = 3,
) -> OrderResult:
    """Order the strokes to cut the time between them (see the module docstring).

    Args:
        drawing: the strokes.
        mask: the ink mask (drags must stay on ink).
        params: feeds, lift geometry, ``lift_s`` and ``outlines_first``.
        max_passes: at most this many 2-opt passes in all (a budget of work, so the same
            drawing gives the same order on any machine; the built-in emblem converges in
            far fewer).
        rounds: at most this many rounds of 2-opt then seams.

    Returns:
        The order and its figures.
    """
    t0 = time.perf_counter()
    n = len(drawing.strokes)
    prec = _Precedence(drawing, params.outlines_first)
    seam = np.zeros(n, np.intp)
    costs = TransitionCosts(_endpoints(drawing, seam), mask, params)
    original = original_order(drawing)
    original_cost = float(_transitions(costs, original.sequence, original.reverse).sum())
    if n < 2:
        return OrderResult(original, original_cost, original_cost, original_cost, 0, 0, 0,
                           True, time.perf_counter() - t0)

    # greedy from the extreme endpoints of the strokes that may come first
    may_start = prec.outline if prec.enabled and prec.outline.any() else np.ones(n, bool)
    ids = np.flatnonzero(np.repeat(may_start, 2))
    p = costs.pts[ids]
    starts = {int(ids[np.argmin(p[:, 0])]), int(ids[np.argmax(p[:, 0])]),
              int(ids[np.argmin(p[:, 1])]), int(ids[np.argmax(p[:, 1])])}
    tours, tour_costs = [], []
    for first in sorted(starts):  # at most four: the extremes in u and v
        tours.append(_greedy(costs, prec, first))
        tour_costs.append(float(_transitions(costs, *tours[-1]).sum()))
    seq, rev = tours[int(np.argmin(tour_costs))]
    greedy_cost = min(tour_costs)

    passes = moves = 0
    for _ in range(rounds):
        seq, rev, p_, m_ = _two_opt(costs, seq, rev, prec, max_passes - passes)
        passes, moves = passes + p_, moves + m_
        new_seam = _optimise_seams(drawing, seq, rev, seam, mask, params, costs)
        changed = not np.array_equal(new_seam, seam)
        seam = new_seam
        if changed:
            costs = TransitionCosts(_endpoints(drawing, seam), mask, params)
        if not changed or passes >= max_passes:
            break
    cost = float(_transitions(costs, seq, rev).sum())
    ours = Order(seq, rev, seam[seq])
    kept = cost >= original_cost
    if kept:
        ours, cost = original, original_cost
    open_rev = int((ours.reverse & (drawing.kinds[ours.sequence] == StrokeKind.FILL)).sum())
    return OrderResult(ours, cost, greedy_cost, original_cost, passes, moves, open_rev, kept,
                       time.perf_counter() - t0)
