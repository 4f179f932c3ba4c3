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
from tattotronix.path.polyline import resample

__all__ = ["APPROACH", "MARK", "TRAVEL", "Path3D", "build_path"]

from tattotronix.path.kinds import APPROACH, MARK, TRAVEL


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
    reach = params.drag_max_mm if drag_max_mm is None else drag_max_mm
    if not strokes:
        return Path3D(np.zeros((0, 3)), np.zeros(0, np.int8), np.zeros(0, np.int32), 0)
    ends = np.array([s[-1] for s in strokes[:-1]]).reshape(-1, 2)
    starts = np.array([s[0] for s in strokes[1:]]).reshape(-1, 2)
    stay = can_drag(mask, ends, starts, reach)

    z_clear, z_app, z_mark = params.clearance_mm, params.approach_z_mm, params.mark_z_mm
    xy: list[NDArray[np.float64]] = []
    z: list[NDArray[np.float64]] = []
    kind: list[NDArray[np.int8]] = []
    idx: list[NDArray[np.int32]] = []

    def put(p: NDArray[np.float64], zz: float | NDArray[np.float64], k: int, s: int) -> None:
        p = np.atleast_2d(p)
        xy.append(p)
        z.append(np.broadcast_to(np.asarray(zz, dtype=np.float64), (len(p),)))
        kind.append(np.full(len(p), k, np.int8))
        idx.append(np.full(len(p), s, np.int32))

    for s, pts in enumerate(strokes):
        if s > 0 and stay[s - 1]:
            gap = resample(np.vstack([ends[s - 1], pts[0]]), params.step_mm)[1:-1]
            if len(gap):
                put(gap, z_mark, MARK, s)
        else:
            if s > 0:
                put(ends[s - 1], z_clear, TRAVEL, s - 1)
            put(np.repeat(pts[:1], 2, axis=0), np.array([z_clear, z_app]), TRAVEL, s)
            put(pts[0], z_mark, APPROACH, s)
        put(pts, z_mark, MARK, s)
    put(strokes[-1][-1], z_clear, TRAVEL, len(strokes) - 1)

    uvz = np.column_stack([np.concatenate(xy), np.concatenate(z)])
    k, i = np.concatenate(kind), np.concatenate(idx)
    keep = np.concatenate([[True], np.linalg.norm(np.diff(uvz, axis=0), axis=1) > SAME_POINT_MM])
    gaps = np.linalg.norm(starts - ends, axis=1) > SAME_POINT_MM
    return Path3D(uvz[keep], k[keep], i[keep], int((stay & gaps).sum()))
