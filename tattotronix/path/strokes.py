"""From an ink mask to strokes: outlines (outer and holes), hatch fill, and with
needle-width compensation line art along its centreline and concentric rings, in mm.

The strokes come out in the original's order (docs/original.md, "2.2 Regions" to "2.4
Hatch fill"): regions left to right by the mean x of their pixels; within a region the
outer outline, the hole outlines (then the lines), then the fill rows top down,
alternating direction (or the rings).
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum
from functools import cached_property

import numpy as np
from numpy.typing import NDArray

from tattotronix.art.grid import InkMask
from tattotronix.art.vector import VectorLines
from tattotronix.path.fill import Hatch, fill_regions
from tattotronix.path.inset import compensate, concentric_rings
from tattotronix.path.params import ToolpathParams
from tattotronix.path.polyline import (
    _EPS_MM,
    SMOOTH_MIN_POINTS,
    SMOOTH_PASSES,
    resample,
    rotate_closed,
)
from tattotronix.path.regions import Region, find_regions

__all__ = ["FILL_KINDS", "StrokeSet", "Stroke", "StrokeKind", "assemble_drawing", "build_drawing",
           "compensated_drawing", "regions_drawing"]


class StrokeKind(IntEnum):
    """What a stroke draws: an outline (outer or hole; closed), a fill row (open), a line
    (the centreline of line art; open, or closed for a ring of line art) or a ring of a
    concentric fill (closed)."""

    OUTER = 0
    HOLE = 1
    FILL = 2
    LINE = 3
    RING = 4


#: kinds that fill a region (after its outlines and lines when ``outlines_first``)
FILL_KINDS = (StrokeKind.FILL, StrokeKind.RING)


@dataclass(frozen=True)
class Stroke:
    """One pen-down polyline before resampling.

    Attributes:
        kind: outer outline, hole outline or fill row.
        region: index of its region in the original (left-to-right) order.
        path_mm: (n, 2) vertices, mm; an outline repeats its first vertex at the end.
        width_mm: a line's designed width (the artwork's, along its centreline), mm; NaN
            for the other kinds.
    """

    kind: StrokeKind
    region: int
    path_mm: NDArray[np.float64]
    width_mm: float = float("nan")

    @property
    def closed(self) -> bool:
        """Outlines, rings and closed lines are loops (they may start at any vertex)."""
        if self.kind == StrokeKind.LINE:
            return len(self.path_mm) > 3 and bool(np.array_equal(self.path_mm[0],
                                                                  self.path_mm[-1]))
        return self.kind != StrokeKind.FILL

    @property
    def is_outline(self) -> bool:
        """Outer or hole outline, or a line: drawn before the fill."""
        return self.kind not in FILL_KINDS

    def points(self, step_mm: float, seam: int = 0, reverse: bool = False) -> NDArray[np.float64]:
        """The stroke resampled at ``step_mm``, from vertex ``seam`` (loops), maybe reversed.

        Args:
            step_mm: arc-length step, mm.
            seam: for a closed loop, the vertex it starts and ends at.
            reverse: traverse the other way.

        Returns:
            (m, 2) points, mm; each step is ``step_mm`` except the last one.
        """
        path = rotate_closed(self.path_mm, seam) if self.closed and seam else self.path_mm
        return resample(path[::-1] if reverse else path, step_mm)


@dataclass(frozen=True)
class StrokeSet:
    """Every stroke of a mask, in the original's order, with the region figures.

    Attributes:
        strokes: the strokes, original order.
        regions: kept ink regions.
        holes: traced holes (counters) in the kept regions.
        dropped_loops: loops dropped for being shorter than ``min_loop_px``.
        drag_mask: where the needle may drag across a gap (a line inside it keeps the ink
            inside the artwork); None: the mask itself, as the original.
    """

    strokes: tuple[Stroke, ...]
    regions: int
    holes: int
    dropped_loops: int
    drag_mask: InkMask | None = None

    @cached_property
    def kinds(self) -> NDArray[np.int8]:
        """(n,) stroke kinds."""
        return np.array([s.kind for s in self.strokes], dtype=np.int8)

    @cached_property
    def region_of(self) -> NDArray[np.intp]:
        """(n,) region index of each stroke."""
        return np.array([s.region for s in self.strokes], dtype=np.intp)

    @cached_property
    def closed(self) -> NDArray[np.bool_]:
        """(n,) whether each stroke is a closed loop (see :attr:`Stroke.closed`)."""
        return np.array([s.closed for s in self.strokes], dtype=bool)

    @cached_property
    def width_mm(self) -> NDArray[np.float64]:
        """(n,) each line's designed width, mm (NaN for the other kinds)."""
        return np.array([s.width_mm for s in self.strokes], dtype=np.float64)

    @cached_property
    def is_fill(self) -> NDArray[np.bool_]:
        """(n,) whether each stroke fills (a fill row or a concentric ring)."""
        return np.isin(self.kinds, FILL_KINDS)

    @cached_property
    def vertices(self) -> NDArray[np.float64]:
        """(N, 2) every stroke's vertices, one stroke after the other, mm."""
        if not self.strokes:
            return np.zeros((0, 2))
        return np.concatenate([s.path_mm for s in self.strokes])

    @cached_property
    def bounds(self) -> NDArray[np.intp]:
        """(n + 1,) stroke ``i`` is ``vertices[bounds[i]:bounds[i + 1]]``."""
        sizes = np.array([len(s.path_mm) for s in self.strokes], dtype=np.intp)
        return np.concatenate([[0], np.cumsum(sizes)]).astype(np.intp)


def _loops_mm(mask: InkMask, loops: list[NDArray[np.int32]]
              ) -> tuple[NDArray[np.float64], NDArray[np.intp]]:
    """Pixel loops -> smoothed closed polylines in mm, all at once (as :func:`smooth_closed`
    then :func:`close` would make each), laid out one after the other with their bounds."""
    if not loops:
        return np.zeros((0, 2)), np.zeros(1, np.intp)
    px = np.concatenate(loops)
    n = np.array([len(lp) for lp in loops], dtype=np.intp)
    lb = np.concatenate([[0], np.cumsum(n)])
    p = np.column_stack([mask.xs[px[:, 1]], mask.ys[px[:, 0]]])
    # circular [1, 2, 1] / 4 passes on the loops of SMOOTH_MIN_POINTS or more
    start, size = np.repeat(lb[:-1], n), np.repeat(n, n)
    t = np.arange(len(p)) - start
    prev = start + (t - 1) % size
    nxt = start + (t + 1) % size
    smooth = size >= SMOOTH_MIN_POINTS
    sp, pv, nx = np.flatnonzero(smooth), prev[smooth], nxt[smooth]
    for _ in range(SMOOTH_PASSES):
        new = 0.25 * p[pv] + 0.5 * p[sp] + 0.25 * p[nx]
        p[sp] = new
    # close: repeat the first vertex unless the last one is (nearly) on it
    first, last = p[lb[:-1]], p[lb[1:] - 1]
    d = last - first
    add = ~(np.sqrt(d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1]) <= _EPS_MM)
    out_n = n + add
    ob = np.concatenate([[0], np.cumsum(out_n)]).astype(np.intp)
    out = np.empty((int(ob[-1]), 2))
    owner = np.repeat(np.arange(len(loops)), n)
    out[ob[:-1][owner] + t] = p
    out[ob[1:][add] - 1] = first[add]
    return out, ob


def build_drawing(mask: InkMask, params: ToolpathParams,
                  vector: VectorLines | None = None) -> StrokeSet:
    """Trace, smooth and fill every region of the mask (:func:`regions_drawing`).

    Args:
        mask: the ink mask.
        params: toolpath parameters (pitch, minimum region and loop sizes, compensation).
        vector: the artwork's own lines (``artwork.vector``), if any.

    Returns:
        The strokes in the original's order and the region figures.
    """
    labels, regions = find_regions(
        mask.ink, mask.res_mm, params.min_region_mm2, params.min_loop_px
    )
    return regions_drawing(mask, labels, regions, params, vector)


def regions_drawing(mask: InkMask, labels: NDArray[np.int32], regions: list[Region],
                    params: ToolpathParams, vector: VectorLines | None = None) -> StrokeSet:
    """The strokes of traced regions (:func:`find_regions`): compensated for the needle's
    width (:func:`compensated_drawing`) when ``params.compensate``, else the original's
    outlines and hatch (:func:`assemble_drawing`)."""
    if params.compensate:
        return compensated_drawing(mask, labels, regions, params, vector)
    fill = fill_regions(labels, mask.xs, mask.ys, mask.res_mm, params.fill_pitch_mm,
                        params.fill_angle_deg, params.fill_style)
    return assemble_drawing(mask, regions, fill)


def assemble_drawing(mask: InkMask, regions: list[Region], fill: Hatch) -> StrokeSet:
    """The strokes of traced regions (:func:`find_regions`) and their hatch
    (:func:`hatch`), in the original's order (what :func:`build_drawing` returns)."""
    region_labels = np.array([r.label for r in regions], dtype=np.int32)
    lo = np.searchsorted(fill.label, region_labels, side="left")
    hi = np.searchsorted(fill.label, region_labels, side="right")
    loops: list[NDArray[np.int32]] = []
    loop_kind: list[StrokeKind] = []
    loop_region: list[int] = []
    for i, region in enumerate(regions):
        if region.outer is not None:
            loops.append(region.outer)
            loop_kind.append(StrokeKind.OUTER)
            loop_region.append(i)
        loops.extend(region.holes)
        loop_kind.extend([StrokeKind.HOLE] * len(region.holes))
        loop_region.extend([i] * len(region.holes))
    loop_v, lb = _loops_mm(mask, loops)
    fill_ab = np.stack([fill.a_mm, fill.b_mm], axis=1)  # (m, 2, 2): one fill stroke each
    strokes: list[Stroke] = []
    k = 0
    for i in range(len(regions)):
        while k < len(loops) and loop_region[k] == i:
            strokes.append(Stroke(loop_kind[k], i, loop_v[lb[k] : lb[k + 1]]))
            k += 1
        strokes.extend(Stroke(StrokeKind.FILL, i, fill_ab[j]) for j in range(lo[i], hi[i]))
    return StrokeSet(
        strokes=tuple(strokes),
        regions=len(regions),
        holes=sum(r.hole_count for r in regions),
        dropped_loops=sum(r.dropped_loops for r in regions),
    )


def compensated_drawing(mask: InkMask, labels: NDArray[np.int32], regions: list[Region],
                        params: ToolpathParams, vector: VectorLines | None = None) -> StrokeSet:
    """The strokes of the regions for a needle of finite width (:mod:`tattotronix.path.inset`):
    per region its inset's outer and hole outlines, its centreline strokes, then its fill
    (hatch runs in the fill area, a needle inside the inset's edge, or concentric rings in
    the inset); regions in the original's order.

    Args:
        mask: the ink mask.
        labels: the region labels (:func:`find_regions`).
        regions: the kept regions, in the original's order.
        params: the toolpath parameters (needle width, line threshold, fill).
        vector: the artwork's own lines (``artwork.vector``), if any.
    """
    comp = compensate(labels, mask, params.needle_width_mm, params.line_max_mm,
                      params.min_loop_px, vector, lines_only=params.lines_only)
    grid = comp.grid
    rings: dict[int, list[NDArray[np.float64]]] = {}
    fill = Hatch(np.zeros(0, np.int32), np.zeros(0, np.intp), np.zeros((0, 2)), np.zeros((0, 2)))
    if params.fill_style == "concentric":
        rings = concentric_rings(comp, params.pitch_mm, params.min_loop_px)
    else:
        fill = fill_regions(comp.fill, grid.xs, grid.ys, grid.res_mm, params.fill_pitch_mm,
                            params.fill_angle_deg, params.fill_style, inset_px=0)
    fill_ab = np.stack([fill.a_mm, fill.b_mm], axis=1)
    strokes: list[Stroke] = []
    for i, region in enumerate(regions):
        outers, holes = comp.loops.get(region.label, ([], []))
        strokes.extend(Stroke(StrokeKind.OUTER, i, lp) for lp in outers)
        strokes.extend(Stroke(StrokeKind.HOLE, i, lp) for lp in holes)
        strokes.extend(Stroke(StrokeKind.LINE, i, ln, float(np.median(w))) for ln, w in zip(
            comp.lines.get(region.label, []), comp.line_width_mm.get(region.label, []),
            strict=True))
        strokes.extend(Stroke(StrokeKind.RING, i, lp) for lp in rings.get(region.label, []))
        lo, hi = np.searchsorted(fill.label, [region.label, region.label + 1])
        strokes.extend(Stroke(StrokeKind.FILL, i, fill_ab[j]) for j in range(lo, hi))
    return StrokeSet(
        strokes=tuple(strokes),
        regions=len(regions),
        holes=sum(r.hole_count for r in regions),
        dropped_loops=sum(r.dropped_loops for r in regions),
        drag_mask=comp.safe,
    )
