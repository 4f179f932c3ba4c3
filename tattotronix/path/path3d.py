"""Ordered strokes to the 3-D needle path: lifts, plunges with a slow approach, drags.

Points are (u, v, z) in panel millimetres, z relative to the surface (negative: in the
work), each with a kind: 0 travel, 1 mark, 2 approach (docs/original.md, "2.6 The 3-D
path"; ours: docs/toolpath.md, "The 3-D path").

* Plunge at a stroke's first point p: (p, +clearance) travel, (p, -plunge + approach)
  travel, (p, -plunge) approach.
* Between strokes the needle stays down only when :func:`~tattotronix.path.costs.can_drag`
  allows it (the straight line is on ink, and no longer than ``drag_max_mm``); the drag is
  resampled at the marking step like a stroke. Otherwise it retracts straight up to
  clearance.
* A point within 1e-9 mm of its predecessor is dropped (the plunge's landing point and the
  stroke's first point coincide), keeping the first: so the landing point is an approach
  point and the first step of a stroke is timed as approach, as in the original.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from tattotronix.art.grid import InkMask
from tattotronix.path.costs import SAME_POINT_MM, can_drag
from tattotronix.path.params import ToolpathParams
from tattotronix.path.polyline import equal_chords
from tattotronix.path.turns import TURN_MAX_STAGGER_MM, TURN_RADIUS_PITCHES, round_turns

__all__ = ["APPROACH", "MARK", "TRAVEL", "Path3D", "build_path", "build_path_flat",
           "step_lengths"]

from tattotronix.path.kinds import APPROACH, MARK, TRAVEL


def step_lengths(points: NDArray[np.float64]) -> NDArray[np.float64]:
    """(N - 1,) lengths of the steps between consecutive points, (N, 2) or (N, 3).

    The very values of ``np.linalg.norm(np.diff(points, axis=0), axis=1)`` (the squares
    summed in the same order), without its slow reduction over a short axis.
    """
    d = points[1:] - points[:-1]
    sq = d[:, 0] * d[:, 0]
    for c in range(1, d.shape[1]):
        sq += d[:, c] * d[:, c]
    return np.sqrt(sq)


@dataclass(frozen=True)
class Path3D:
    """The needle path in the panel frame.

    Attributes:
        uvz_mm: (N, 3) points, mm; z relative to the panel surface.
        kind: (N,) int8, 0 travel, 1 mark, 2 approach.
        stroke: (N,) int32, position in the drawing order of the stroke a point draws or
            leads into (a retract belongs to the stroke it ends; a plunge or a drag to the
            stroke it starts).
        drags: gaps crossed with the needle down.
    """

    uvz_mm: NDArray[np.float64]
    kind: NDArray[np.int8]
    stroke: NDArray[np.int32]
    drags: int


def build_path(
    strokes: Sequence[NDArray[np.float64]], mask: InkMask, params: ToolpathParams,
    drag_max_mm: float | None = None,
) -> Path3D:
    """Join ordered, resampled strokes into one 3-D path.

    Args:
        strokes: (m_i, 2) points per stroke in drawing order, mm, oriented as drawn.
        mask: the ink mask (drags must stay on ink).
        params: lift geometry and the resampling step.
        drag_max_mm: longest gap crossed with the needle down, mm; default
            ``params.drag_max_mm`` (``inf`` gives the original's rule: any gap on ink).

    Returns:
        The path.
    """
    if not strokes:
        return build_path_flat(np.zeros((0, 2)), np.zeros(1, np.intp), mask, params, drag_max_mm)
    bounds = np.concatenate([[0], np.cumsum([len(s) for s in strokes])]).astype(np.intp)
    return build_path_flat(np.concatenate(strokes), bounds, mask, params, drag_max_mm)


def build_path_flat(
    points: NDArray[np.float64], bounds: NDArray[np.intp], mask: InkMask,
    params: ToolpathParams, drag_max_mm: float | None = None,
    turnable: NDArray[np.bool_] | None = None,
) -> Path3D:
    """:func:`build_path` of strokes laid out one after the other (no loop per stroke).

    Args:
        points: (M, 2) the resampled points of every stroke in drawing order, mm.
        bounds: (n + 1,) stroke ``k`` is ``points[bounds[k]:bounds[k + 1]]`` (at least one
            point each).
        mask: the ink mask (drags must stay on ink).
        params: lift geometry and the resampling step.
        drag_max_mm: as for :func:`build_path`.
        turnable: (n - 1,) the gaps between two fill runs: where such a gap is crossed
            with the needle down, the straight jog may become a round turn
            (:func:`~tattotronix.path.turns.round_turns`); None: straight jogs only.

    Returns:
        The path, equal to what :func:`build_path` makes of the same strokes (without
        ``turnable``).
    """
    reach = params.drag_max_mm if drag_max_mm is None else drag_max_mm
    n = len(bounds) - 1
    if n <= 0:
        return Path3D(np.zeros((0, 3)), np.zeros(0, np.int8), np.zeros(0, np.int32), 0)
    pts = np.asarray(points, dtype=np.float64)
    m = np.diff(bounds)
    ends = pts[bounds[1:-1] - 1]  # (n - 1, 2): where the needle is after stroke k
    starts = pts[bounds[1:-1]]  # (n - 1, 2): where stroke k + 1 starts
    stay = can_drag(mask, ends, starts, reach)
    turns = None
    if turnable is not None and n > 1:
        turns = round_turns(pts, bounds, np.asarray(turnable, bool) & stay, mask,
                            params.step_mm, TURN_RADIUS_PITCHES * params.pitch_mm,
                            TURN_MAX_STAGGER_MM)
    if turns is not None:
        pts, bounds = turns.points, turns.bounds
        m = np.diff(bounds)
        ends, starts = pts[bounds[1:-1] - 1], pts[bounds[1:-1]]

    # the drag across each gap crossed with the needle down: a straight line in equal
    # chords no longer than a step (no remainder chord beside the corner it meets)
    drag_k = np.flatnonzero(stay)
    gap_pts, gap_ob = equal_chords(ends[drag_k], starts[drag_k], params.step_mm)
    if turns is not None and turns.arcs:  # the turns' arcs in place of their straight jogs
        inner = [turns.arcs[k] if k in turns.arcs else gap_pts[gap_ob[i] + 1:gap_ob[i + 1] - 1]
                 for i, k in enumerate(drag_k.tolist())]
        sizes = np.array([len(x) + 2 for x in inner], dtype=np.intp)
        gap_ob = np.concatenate([[0], np.cumsum(sizes)]).astype(np.intp)
        gap_pts = np.zeros((int(gap_ob[-1]), 2))
        for i, x in enumerate(inner):
            gap_pts[gap_ob[i] + 1:gap_ob[i + 1] - 1] = x
    gap_n = np.maximum(np.diff(gap_ob) - 2, 0)  # the inner points only

    down = np.concatenate([[False], stay])  # stroke k is reached with the needle down
    retract = np.concatenate([[False], ~stay])  # stroke k starts with a retract of k - 1
    pre = np.where(down, 0, 3 + retract)
    pre[down] = gap_n
    size = pre + m
    off = np.concatenate([[0], np.cumsum(size)])
    total = int(off[-1]) + 1
    z_clear, z_app, z_mark = params.clearance_mm, params.approach_z_mm, params.mark_z_mm
    uvz = np.empty((total, 3))
    uvz[:, 2] = z_mark
    kind = np.full(total, MARK, np.int8)
    idx = np.empty(total, np.int32)

    # the strokes' own points
    shift = off[:-1] + pre - bounds[:-1]  # row in the path - row in ``points``
    dest = np.arange(int(bounds[-1])) + np.repeat(shift, m)
    uvz[dest, :2] = pts
    idx[dest] = np.repeat(np.arange(n, dtype=np.int32), m)
    # retracts: the previous stroke's end at clearance
    r = np.flatnonzero(retract)
    at = off[r]
    uvz[at, :2] = pts[bounds[r] - 1]
    uvz[at, 2] = z_clear
    kind[at] = TRAVEL
    idx[at] = r - 1
    # plunges: over the start at clearance, at the approach start, then down (approach)
    p = np.flatnonzero(~down)
    at = off[p] + retract[p]
    for i, (zz, kk) in enumerate(((z_clear, TRAVEL), (z_app, TRAVEL), (z_mark, APPROACH))):
        uvz[at + i, :2] = pts[bounds[p]]
        uvz[at + i, 2] = zz
        kind[at + i] = kk
        idx[at + i] = p
    # drags: the inner points of each gap, marking, belonging to the stroke they lead to
    if len(drag_k):
        gk = drag_k + 1
        g_owner = np.repeat(np.arange(len(drag_k)), gap_n)
        g_rel = np.arange(int(gap_n.sum())) - np.repeat(np.cumsum(gap_n) - gap_n, gap_n)
        uvz[off[gk][g_owner] + g_rel, :2] = gap_pts[gap_ob[:-1][g_owner] + 1 + g_rel]
        idx[off[gk][g_owner] + g_rel] = gk[g_owner]
    # the final retract
    uvz[-1, :2], uvz[-1, 2], kind[-1], idx[-1] = pts[-1], z_clear, TRAVEL, n - 1

    keep = np.concatenate([[True], step_lengths(uvz) > SAME_POINT_MM])
    d = starts - ends
    gaps = np.sqrt(d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1]) > SAME_POINT_MM
    return Path3D(uvz[keep], kind[keep], idx[keep], int((stay & gaps).sum()))
