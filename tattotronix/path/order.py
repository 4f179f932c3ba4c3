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
from scipy.spatial import cKDTree

from tattotronix.art.grid import InkMask
from tattotronix.path.costs import TransitionCosts, can_drag
from tattotronix.path.laps import Laps
from tattotronix.path.params import ToolpathParams
from tattotronix.path.polyline import oriented, resample_many
from tattotronix.path.strokes import StrokeSet

__all__ = ["Order", "OrderResult", "optimise_order", "original_order"]

_GAIN_TOL_S = 1e-9  # a move must save more than this to count
_BLOCK_ROWS = 256  # 2-opt rows scored at once (bounds memory to ~ rows x n)
_TRIANGLE_BLOCK_ROWS = 64  # the same with the lift costs looked up (scores j >= i only)
MAX_PASSES = 200  # 2-opt passes in all: a budget of work, never of wall time
#: most strokes for which the greedy computes a row of costs per step; above, it asks a
#: k-d tree for the nearest open endpoints (the same tours, ties apart, far faster)
GREEDY_ROWS_MAX = 2000
#: move scores a 2-opt search spends on passes that score every move (n^2 a pass); the
#: passes past it score the moves near each stroke's ends only (neighbour lists). Every
#: drawing under it is ordered as with no limit; an SVG of 10,341 strokes took 128 full
#: passes, 178 s (benchmarks/bench_ordering.py)
TWO_OPT_FULL_WORK = 10**9
_NEIGHBOURS = 10  # nearest endpoints (and cheapest drags) a near move may join


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

    def points(self, drawing: StrokeSet, step_mm: float) -> list[NDArray[np.float64]]:
        """Each stroke resampled at ``step_mm``, in drawing order, oriented as ordered."""
        pts, bounds = self.resampled(drawing, step_mm)
        return [pts[bounds[k] : bounds[k + 1]] for k in range(len(bounds) - 1)]

    def resampled(
        self, drawing: StrokeSet, step_mm: float,
        canonical: tuple[NDArray[np.float64], NDArray[np.intp]] | None = None,
    ) -> tuple[NDArray[np.float64], NDArray[np.intp]]:
        """:meth:`points`, laid out one stroke after the other: ``(pts, bounds)``.

        Args:
            drawing: the strokes.
            step_mm: the resampling step, mm.
            canonical: the strokes resampled in their own order and direction from vertex
                0 (``resample_many(drawing.vertices, drawing.bounds, step_mm)``), if made
                already: the strokes drawn that way are taken from it, not resampled again.
        """
        seq = np.asarray(self.sequence, dtype=np.intp)
        closed = drawing.closed[seq]
        seam = np.asarray(self.seam, dtype=np.intp)
        rev = np.asarray(self.reverse, dtype=bool)
        vb = drawing.bounds
        fresh = rev | (closed & (seam != 0)) if canonical is not None else np.ones(len(seq), bool)
        # the strokes not in ``canonical``, oriented, resampled together
        f = np.flatnonzero(fresh)
        sizes = (vb[1:] - vb[:-1])[seq[f]]
        fb = np.concatenate([[0], np.cumsum(sizes)]).astype(np.intp)
        src = np.repeat(vb[seq[f]] - fb[:-1], sizes) + np.arange(int(fb[-1]))
        order = oriented(fb, closed[f], seam[f], rev[f])
        new_pts, new_b = resample_many(drawing.vertices[src[order]], fb, step_mm)
        if canonical is None:
            return new_pts, new_b
        can_pts, can_b = canonical
        # gather: each position from its source, canonical or fresh
        start = can_b[seq]
        count = can_b[seq + 1] - start
        start[f] = new_b[:-1] + len(can_pts)
        count[f] = np.diff(new_b)
        bounds = np.concatenate([[0], np.cumsum(count)]).astype(np.intp)
        rows = np.repeat(start - bounds[:-1], count) + np.arange(int(bounds[-1]))
        return np.concatenate([can_pts, new_pts])[rows], bounds


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


def original_order(drawing: StrokeSet) -> Order:
    """The original's order: the drawing's own (regions left to right, outline, holes, fill)."""
    n = len(drawing.strokes)
    return Order(np.arange(n), np.zeros(n, bool), np.zeros(n, np.intp))


def _endpoints(drawing: StrokeSet, seam: NDArray[np.intp]) -> NDArray[np.float64]:
    """(2n, 2): row 2i is stroke i's start, row 2i + 1 its end, for the given seams."""
    vb, closed = drawing.bounds, drawing.closed
    first, last = vb[:-1], vb[1:] - 1
    at_seam = first + np.asarray(seam, dtype=np.intp) % np.maximum(last - first, 1)
    pts = np.empty((2 * len(drawing.strokes), 2))
    pts[0::2] = drawing.vertices[np.where(closed, at_seam, first)]
    pts[1::2] = drawing.vertices[np.where(closed, at_seam, last)]
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

    def __init__(self, drawing: StrokeSet, enabled: bool):
        self.enabled = enabled
        self.outline = ~drawing.is_fill
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


@dataclass
class _Locks:
    """The ``outlines_first`` rule as a greedy tour starts: per endpoint, 0 or + inf (a
    fill row waiting for its region's outlines); per region, the outlines not yet drawn;
    per region, its fill rows' endpoints (opened when the last outline is drawn); per
    endpoint, whether it is an outline's."""

    shut: NDArray[np.float64]
    remaining: NDArray[np.intp]
    fill_ends: list[NDArray[np.intp]]
    outline_end: NDArray[np.bool_]

    @classmethod
    def of(cls, prec: _Precedence, m: int) -> _Locks:
        shut = np.zeros(m)
        remaining = np.bincount(prec.region[prec.outline], minlength=prec.regions)
        fill_ends: list[NDArray[np.intp]] = []
        outline_end = np.repeat(prec.outline, 2) if prec.enabled else np.zeros(m, bool)
        if prec.enabled:
            shut[np.repeat(~prec.outline & (remaining[prec.region] > 0), 2)] = np.inf
            for r in range(prec.regions):
                fills = np.flatnonzero((prec.region == r) & ~prec.outline)
                fill_ends.append(np.sort(np.concatenate([2 * fills, 2 * fills + 1])))
        return cls(shut, remaining, fill_ends, outline_end)


def _greedy(
    costs: TransitionCosts, prec: _Precedence, firsts: list[int]
) -> list[tuple[NDArray[np.intp], NDArray[np.bool_]]]:
    """Nearest neighbour in time from each endpoint of ``firsts``, with reversal and
    precedence; the tours are built side by side, one stroke of each per step.

    Endpoint ``e = 2 i + o`` enters stroke ``i`` (reversed when ``o`` is 1); the needle
    leaves it at ``e ^ 1``. Endpoints of strokes drawn or blocked cost infinity more.
    """
    n = len(costs.pts) // 2
    tours = len(firsts)
    full = costs.matrix()
    locks = _Locks.of(prec, 2 * n)
    shut = np.tile(locks.shut, (tours, 1))  # + inf: stroke drawn, or a fill waiting
    shut_strokes = shut.reshape(tours, n, 2)
    remaining = np.tile(locks.remaining, (tours, 1))
    fill_ends, outline_end = locks.fill_ends, locks.outline_end
    visits = np.empty((n, tours), np.intp)
    tt = np.arange(tours)
    e = np.asarray(firsts, dtype=np.intp)
    for k in range(n):
        if k > 0:
            cost = full[e ^ 1] if full is not None else np.stack(
                [costs.from_endpoint(int(x)) for x in e ^ 1])
            e = (cost + shut).argmin(axis=1)
        visits[k] = e
        shut_strokes[tt, e >> 1] = np.inf
        if outline_end[e].any():
            for t in np.flatnonzero(outline_end[e]):
                r = prec.region[e[t] >> 1]
                remaining[t, r] -= 1
                if remaining[t, r] == 0:
                    shut[t, fill_ends[r]] = 0.0
    return [(visits[:, t] >> 1, (visits[:, t] & 1).astype(bool)) for t in range(tours)]


def _greedy_near(costs: TransitionCosts, prec: _Precedence, first: int
                 ) -> tuple[NDArray[np.intp], NDArray[np.bool_]]:
    """:func:`_greedy` for one tour, the next stroke found with a k-d tree of the endpoints
    not yet drawn (for large drawings, where a row of costs per step is most of the work).

    The cheapest lift is to the nearest open endpoint, and every drag from the needle's
    endpoint is scored too, so the choice is :func:`_greedy`'s (ties apart). The tree is
    rebuilt when half its endpoints are drawn."""
    m = len(costs.pts)
    n = m // 2
    locks = _Locks.of(prec, m)
    shut, remaining = locks.shut, locks.remaining
    fill_ends, outline_end = locks.fill_ends, locks.outline_end
    drawn = np.zeros(m, bool)
    by_cost = costs.dst[np.lexsort((costs.drag_s, costs.src))]  # each src's drags, cheapest first
    tree_ids = np.arange(m)
    tree = cKDTree(costs.pts)
    drawn_since = 0
    visits = np.empty(n, np.intp)
    e = first
    for k in range(n):
        if k > 0:
            e = _nearest_open(costs, by_cost, tree, tree_ids, shut, e ^ 1)
        visits[k] = e
        s = e >> 1
        shut[2 * s : 2 * s + 2] = np.inf
        drawn[2 * s : 2 * s + 2] = True
        drawn_since += 2
        if outline_end[e]:
            r = prec.region[s]
            remaining[r] -= 1
            if remaining[r] == 0:
                shut[fill_ends[r]] = 0.0
        if 2 * drawn_since >= len(tree_ids) and k + 1 < n:
            tree_ids = np.flatnonzero(~drawn)
            tree = cKDTree(costs.pts[tree_ids])
            drawn_since = 0
    return visits >> 1, (visits & 1).astype(bool)


def _nearest_open(costs: TransitionCosts, by_cost: NDArray[np.intp], tree: cKDTree,
                  tree_ids: NDArray[np.intp], shut: NDArray[np.float64], a: int) -> int:
    """The open endpoint cheapest to reach from endpoint ``a`` (lowest id on a tie): the
    cheapest open drag from ``a`` (``by_cost``: each endpoint's drag partners, cheapest
    first) and the nearest open endpoints of the tree, asked for more until one is open
    (the whole row past 256)."""
    drags = by_cost[costs.indptr[a] : costs.indptr[a + 1]]
    drags = drags[shut[drags] == 0.0][:1]
    k = 16
    while k <= 256 and k < 4 * len(tree_ids):
        kk = min(k, len(tree_ids))
        _, idx = tree.query(costs.pts[a], k=kk)
        ids = tree_ids[np.atleast_1d(idx)]
        if np.any(shut[ids] == 0.0):
            cand = np.unique(np.concatenate([ids, drags]))
            cand = cand[shut[cand] == 0.0]
            return int(cand[np.argmin(costs.between(np.full(len(cand), a), cand))])
        k *= 4
    return int(np.argmin(costs.from_endpoint(a) + shut))


def _two_opt(
    costs: TransitionCosts, seq: NDArray[np.intp], rev: NDArray[np.bool_], prec: _Precedence,
    max_passes: int,
) -> tuple[NDArray[np.intp], NDArray[np.bool_], int, int]:
    """Improve by reversing runs of strokes until no move helps or ``max_passes`` passes
    have run (a work budget, not a time budget: the result never depends on the machine).

    A pass scores every move (:func:`_score_all`) while the passes so far and this one
    score at most :data:`TWO_OPT_FULL_WORK` moves; the passes after score the moves whose
    new transitions join near endpoints (:func:`_score_near`)."""
    seq, rev = seq.copy(), rev.copy()
    n, m = len(seq), len(costs.pts)
    passes = moves = 0
    if n < 2:
        return seq, rev, passes, moves
    near: tuple[NDArray[np.intp], NDArray[np.intp]] | None = None
    corrections, lifts = costs.corrections(), costs.lifts()
    work = 0
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
        ends = _Ends(entry, exit_, pos, is_exit, t_prev, t_next, reach)
        if near is None and work + n * n <= TWO_OPT_FULL_WORK:
            work += n * n
            best, best_j = _score_all(costs, ends, corrections, lifts)
        else:
            near = _near_pairs(costs) if near is None else near
            best, best_j = _score_near(costs, ends, *near)
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


@dataclass(frozen=True)
class _Ends:
    """One 2-opt pass's view of the order: per position its entry and exit endpoints, the
    transitions before and after it and its precedence reach; per endpoint its position
    and whether it is an exit."""

    entry: NDArray[np.intp]
    exit: NDArray[np.intp]
    pos: NDArray[np.intp]
    is_exit: NDArray[np.bool_]
    t_prev: NDArray[np.float64]
    t_next: NDArray[np.float64]
    reach: NDArray[np.intp]


def _moves_of(pairs_src: NDArray[np.intp], pairs_dst: NDArray[np.intp], ends: _Ends
              ) -> tuple[NDArray[np.intp], NDArray[np.intp], NDArray[np.intp]]:
    """The moves (reverse positions i..j) whose new transitions include ``src -> dst``,
    as (indices into the pairs, i, j): the move's first new transition is exit[i-1] ->
    exit[j] (two exits), its second entry[i] -> entry[j+1] (two entries)."""
    is_exit, pos = ends.is_exit, ends.pos
    sel_a = np.flatnonzero(is_exit[pairs_src] & is_exit[pairs_dst])
    sel_b = np.flatnonzero(~is_exit[pairs_src] & ~is_exit[pairs_dst])
    k = np.concatenate([sel_a, sel_b])
    i = np.concatenate([pos[pairs_src[sel_a]] + 1, pos[pairs_src[sel_b]]])
    j = np.concatenate([pos[pairs_dst[sel_a]], pos[pairs_dst[sel_b]] - 1])
    return k, i, j


def _score_all(costs: TransitionCosts, ends: _Ends,
               corrections: tuple[NDArray[np.intp], NDArray[np.intp], NDArray[np.float64]],
               lifts: NDArray[np.float64] | None
               ) -> tuple[NDArray[np.float64], NDArray[np.intp]]:
    """Per row i, the gain of its best move (reverse i..j; negative saves time) and its j,
    every j scored, in row blocks (``corrections`` and ``lifts``: the costs' own, made
    once per search)."""
    entry, exit_, reach = ends.entry, ends.exit, ends.reach
    t_prev, t_next = ends.t_prev, ends.t_next
    n = len(entry)
    jj = np.arange(n)
    src, dst, corr = corrections
    # drag corrections: term A c(exit[i-1], exit[j]); term B c(entry[i], entry[j+1])
    k, ci, cj = _moves_of(src, dst, ends)
    cc = corr[k]
    ok = (ci < n) & (cj >= ci)
    ci, cj, cc = ci[ok], cj[ok], cc[ok]
    by_row = np.argsort(ci, kind="stable")
    ci, cj, cc = ci[by_row], cj[by_row], cc[by_row]
    ex, en = costs.pts[exit_], costs.pts[entry]
    best = np.full(n, np.inf)
    best_j = np.zeros(n, np.intp)
    block = _BLOCK_ROWS if lifts is None else _TRIANGLE_BLOCK_ROWS
    for i0 in range(0, n, block):
        ii = np.arange(i0, min(n, i0 + block))
        # the moves of these rows end in columns j in [i0, max reach): the others are
        # never allowed (j < i, or past the reach), so they are not scored
        j1 = int(reach[ii].max())
        cols = jj[i0:j1]
        if lifts is not None:  # the same lift costs, looked up
            a = lifts[exit_[np.maximum(ii - 1, 0)]][:, exit_[cols]]
        else:
            prev = ex[np.maximum(ii - 1, 0)]
            a = costs.lift(np.hypot(prev[:, :1] - ex[cols, 0], prev[:, 1:] - ex[cols, 1]))
        a[ii == 0] = 0.0
        b = np.zeros_like(a)
        inner = cols[cols < n - 1]
        if lifts is not None:
            b[:, : len(inner)] = lifts[entry[ii]][:, entry[inner + 1]]
        else:
            b[:, : len(inner)] = costs.lift(
                np.hypot(en[ii, :1] - en[inner + 1, 0], en[ii, 1:] - en[inner + 1, 1])
            )
        d = a + b - t_prev[ii, None] - t_next[None, cols]
        lo, hi = np.searchsorted(ci, [ii[0], ii[-1] + 1])
        in_cols = cj[lo:hi] < j1
        np.add.at(d, (ci[lo:hi][in_cols] - i0, cj[lo:hi][in_cols] - i0),
                  cc[lo:hi][in_cols])
        d[(cols[None, :] < ii[:, None]) | (cols[None, :] >= reach[ii, None])] = np.inf
        arg = d.argmin(axis=1)
        best_j[ii] = i0 + arg
        best[ii] = d[np.arange(len(ii)), arg]
    return best, best_j


def _near_pairs(costs: TransitionCosts) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """(src, dst) endpoint pairs a move of :func:`_score_near` may join: each endpoint to
    its :data:`_NEIGHBOURS` nearest, and to its :data:`_NEIGHBOURS` cheapest drag partners
    (a drag may beat a nearer lift)."""
    pts = costs.pts
    k = min(_NEIGHBOURS + 1, len(pts))
    _, nb = cKDTree(pts).query(pts, k=k)
    nb = np.asarray(nb, dtype=np.intp).reshape(len(pts), k)
    by_cost = np.lexsort((costs.drag_s, costs.src))
    rank = np.arange(len(by_cost)) - costs.indptr[costs.src[by_cost]]
    cheap = by_cost[rank < _NEIGHBOURS]
    src = np.concatenate([np.repeat(np.arange(len(pts)), k), costs.src[cheap]])
    dst = np.concatenate([nb.ravel(), costs.dst[cheap]])
    keep = src != dst
    return src[keep], dst[keep]


def _score_near(costs: TransitionCosts, ends: _Ends, src: NDArray[np.intp],
                dst: NDArray[np.intp]) -> tuple[NDArray[np.float64], NDArray[np.intp]]:
    """:func:`_score_all` for the moves one of whose new transitions is a pair of
    :func:`_near_pairs` (the neighbour lists of 2-opt for large tours: a move that joins
    two far endpoints by both its new transitions seldom saves time)."""
    entry, exit_ = ends.entry, ends.exit
    n = len(entry)
    _, i, j = _moves_of(src, dst, ends)
    ok = (i < n) & (j >= i) & (j < ends.reach[np.minimum(i, n - 1)])
    i, j = i[ok], j[ok]
    a = np.zeros(len(i))
    has_a = i > 0
    a[has_a] = costs.between(exit_[i[has_a] - 1], exit_[j[has_a]])
    b = np.zeros(len(i))
    has_b = j < n - 1
    b[has_b] = costs.between(entry[i[has_b]], entry[j[has_b] + 1])
    d = a + b - ends.t_prev[i] - ends.t_next[j]
    best = np.full(n, np.inf)
    best_j = np.zeros(n, np.intp)
    if len(i):
        order = np.lexsort((j, d, i))  # by row, then gain, then the smaller j
        i, j, d = i[order], j[order], d[order]
        first = np.flatnonzero(np.concatenate([[True], i[1:] != i[:-1]]))
        best[i[first]] = d[first]
        best_j[i[first]] = j[first]
    return best, best_j


_SeamCosts = dict[tuple[int, float, float], NDArray[np.float64]]


def _ring_costs(
    drawing: StrokeSet, mask: InkMask, params: ToolpathParams, costs: TransitionCosts,
    wanted: list[tuple[int, float, float]], cache: _SeamCosts,
) -> None:
    """Fill ``cache[(s, x, y)]``: the cost between the point (x, y) and every vertex of
    the ring of outline ``s`` (a drag where :func:`can_drag` allows it, else a lift),
    for the keys not there yet, all in one batch."""
    todo = [key for key in dict.fromkeys(wanted) if key not in cache]
    if not todo:
        return
    vb, verts = drawing.bounds, drawing.vertices
    s = np.array([key[0] for key in todo], dtype=np.intp)
    q_all = np.array([key[1:] for key in todo], dtype=np.float64)
    ring_n = vb[s + 1] - vb[s] - 1
    rb = np.concatenate([[0], np.cumsum(ring_n)]).astype(np.intp)
    owner = np.repeat(np.arange(len(todo)), ring_n)
    ring = verts[vb[s][owner] + np.arange(int(rb[-1])) - rb[:-1][owner]]
    q = q_all[owner]
    d = ring - q
    dist = np.sqrt(d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1])  # as np.linalg.norm(axis=1)
    c = costs.lift(dist)
    near = np.flatnonzero(dist <= params.drag_max_mm)
    drag = near[can_drag(mask, q[near], ring[near], params.drag_max_mm)]
    c[drag] = dist[drag] * (1.0 / params.feed_mark_mm_s)
    for k, key in enumerate(todo):
        cache[key] = c[rb[k] : rb[k + 1]]


def _optimise_seams(
    drawing: StrokeSet, seq: NDArray[np.intp], rev: NDArray[np.bool_], seam: NDArray[np.intp],
    mask: InkMask, params: ToolpathParams, costs: TransitionCosts,
    cache: _SeamCosts | None = None,
) -> NDArray[np.intp]:
    """Per closed outline (by stroke), the vertex minimising the move in plus the move out.

    The outlines are taken in drawing order, each seeing the seam already chosen for the
    stroke before it; all outlines that follow a run of ``w`` outlines are settled together
    in wave ``w`` (no loop over vertices). ``cache`` keeps the cost of each ring from each
    point across calls (the rounds of :func:`optimise_order` see mostly the same ones).
    """
    cache = {} if cache is None else cache
    seam = seam.copy()
    pts = costs.pts.copy()
    entry, exit_ = _ends(seq, rev)
    n = len(seq)
    closed = drawing.closed[seq]
    vb, verts = drawing.bounds, drawing.vertices
    # wave of each outline: how many outlines come right before it
    run = np.zeros(n, np.intp)
    for k in range(1, n):  # cheap: integers only
        run[k] = run[k - 1] + 1 if closed[k - 1] else 0
    for wave in range(int(run[closed].max(initial=-1)) + 1):
        pos = np.flatnonzero(closed & (run == wave))
        s = seq[pos]
        sides: list[list[tuple[int, float, float]]] = []
        for k, sk in zip(pos.tolist(), s.tolist(), strict=True):
            near_pts = ([pts[exit_[k - 1]]] if k > 0 else []) + (
                [pts[entry[k + 1]]] if k + 1 < n else [])
            sides.append([(sk, float(p[0]), float(p[1])) for p in near_pts])
        _ring_costs(drawing, mask, params, costs, [key for ks in sides for key in ks], cache)
        ring_n = vb[s + 1] - vb[s] - 1
        totals = []
        for keys, size in zip(sides, ring_n.tolist(), strict=True):
            total = np.zeros(size)
            for key in keys:  # in, then out: as the sum is taken
                total += cache[key]
            totals.append(total)
        total = np.concatenate(totals)
        rb = np.concatenate([[0], np.cumsum(ring_n)]).astype(np.intp)
        owner = np.repeat(np.arange(len(pos)), ring_n)
        local = np.arange(int(rb[-1])) - rb[:-1][owner]
        # per outline: the first vertex of least total, kept if it beats the current seam
        low = np.minimum.reduceat(total, rb[:-1]) if len(total) else total
        at_low = np.flatnonzero(total == low[owner])
        _, first = np.unique(owner[at_low], return_index=True)  # the first one wins
        best = local[at_low[first]]
        current = total[rb[:-1] + seam[s] % ring_n]
        better = low < current - _GAIN_TOL_S
        seam[s[better]] = best[better]
        chosen = verts[vb[s[better]] + best[better]]
        pts[2 * s[better]] = pts[2 * s[better] + 1] = chosen
    return seam


def optimise_order(
    drawing: StrokeSet, mask: InkMask, params: ToolpathParams, max_passes: int = MAX_PASSES,
    rounds: int = 3, laps: Laps | None = None,
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
        laps: books the time spent on the costs (``costs``) and on the search
            (``ordering``).

    Returns:
        The order and its figures.
    """
    t0 = time.perf_counter()
    laps = laps or Laps()
    n = len(drawing.strokes)
    prec = _Precedence(drawing, params.outlines_first)
    seam = np.zeros(n, np.intp)
    laps.lap("ordering")
    costs = TransitionCosts(_endpoints(drawing, seam), mask, params)
    laps.lap("costs")
    original = original_order(drawing)
    original_cost = float(_transitions(costs, original.sequence, original.reverse).sum())
    if n < 2:
        laps.lap("ordering")
        return OrderResult(original, original_cost, original_cost, original_cost, 0, 0, 0,
                           True, time.perf_counter() - t0)

    # greedy from the extreme endpoints of the strokes that may come first
    may_start = prec.outline if prec.enabled and prec.outline.any() else np.ones(n, bool)
    ids = np.flatnonzero(np.repeat(may_start, 2))
    p = costs.pts[ids]
    starts = {int(ids[np.argmin(p[:, 0])]), int(ids[np.argmax(p[:, 0])]),
              int(ids[np.argmin(p[:, 1])]), int(ids[np.argmax(p[:, 1])])}
    if n > GREEDY_ROWS_MAX:
        tours = [_greedy_near(costs, prec, e) for e in sorted(starts)]
    else:
        tours = _greedy(costs, prec, sorted(starts))  # at most four: the extremes in u and v
    tour_costs = [float(_transitions(costs, *tour).sum()) for tour in tours]
    seq, rev = tours[int(np.argmin(tour_costs))]
    greedy_cost = min(tour_costs)

    passes = moves = 0
    seam_cache: _SeamCosts = {}
    for _ in range(rounds):
        seq, rev, p_, m_ = _two_opt(costs, seq, rev, prec, max_passes - passes)
        passes, moves = passes + p_, moves + m_
        new_seam = _optimise_seams(drawing, seq, rev, seam, mask, params, costs, seam_cache)
        changed = not np.array_equal(new_seam, seam)
        seam = new_seam
        if changed:
            laps.lap("ordering")
            pts = _endpoints(drawing, seam)
            moved = np.any(pts != costs.pts, axis=1)
            costs = TransitionCosts(pts, mask, params, reuse=costs, moved=moved)
            laps.lap("costs")
        if not changed or passes >= max_passes:
            break
    cost = float(_transitions(costs, seq, rev).sum())
    ours = Order(seq, rev, seam[seq])
    kept = cost >= original_cost
    if kept:
        ours, cost = original, original_cost
    open_rev = int((ours.reverse & ~drawing.closed[ours.sequence]).sum())
    laps.lap("ordering")
    return OrderResult(ours, cost, greedy_cost, original_cost, passes, moves, open_rev, kept,
                       time.perf_counter() - t0)
