"""From an ink mask to strokes: outlines (outer and holes) and hatch fill, in mm.

The strokes come out in the original's order (docs/original.md, "2.2 Regions" to "2.4
Hatch fill"): regions left to right by the mean x of their pixels; within a region the
outer outline, the hole outlines, then the fill rows top down, alternating direction.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum

import numpy as np
from numpy.typing import NDArray

from tattotronix.art.grid import InkMask
from tattotronix.path.fill import hatch
from tattotronix.path.params import ToolpathParams
from tattotronix.path.polyline import close, resample, rotate_closed, smooth_closed
from tattotronix.path.regions import find_regions

__all__ = ["Drawing", "Stroke", "StrokeKind", "build_drawing"]


class StrokeKind(IntEnum):
    """What a stroke draws."""

    OUTER = 0
    HOLE = 1
    FILL = 2


@dataclass(frozen=True)
class Stroke:
    """One pen-down polyline before resampling.

    Attributes:
        kind: outer outline, hole outline or fill row.
        region: index of its region in the original (left-to-right) order.
        path_mm: (n, 2) vertices, mm; an outline repeats its first vertex at the end.
    """

    kind: StrokeKind
    region: int
    path_mm: NDArray[np.float64]

    @property
    def closed(self) -> bool:
        """Outlines are closed loops (they may start at any vertex)."""
        return self.kind != StrokeKind.FILL

    @property
    def is_outline(self) -> bool:
        """Outer or hole outline."""
        return self.kind != StrokeKind.FILL

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
class Drawing:
    """Every stroke of a mask, in the original's order, with the region figures.

    Attributes:
        strokes: the strokes, original order.
        regions: kept ink regions.
        holes: traced holes (counters) in the kept regions.
        dropped_loops: loops dropped for being shorter than ``min_loop_px``.
    """

    strokes: tuple[Stroke, ...]
    regions: int
    holes: int
    dropped_loops: int

    @property
    def kinds(self) -> NDArray[np.int8]:
        """(n,) stroke kinds."""
        return np.array([s.kind for s in self.strokes], dtype=np.int8)

    @property
    def region_of(self) -> NDArray[np.intp]:
        """(n,) region index of each stroke."""
        return np.array([s.region for s in self.strokes], dtype=np.intp)


def _loop_mm(mask: InkMask, loop_px: NDArray[np.int32]) -> NDArray[np.float64]:
    """Pixel loop -> smoothed closed polyline in mm."""
    pts = np.column_stack([mask.xs[loop_px[:, 1]], mask.ys[loop_px[:, 0]]])
    return close(smooth_closed(pts))


def build_drawing(mask: InkMask, params: ToolpathParams) -> Drawing:
    """Trace, smooth and hatch every region of the mask.

    Args:
        mask: the ink mask.
        params: toolpath parameters (pitch, minimum region and loop sizes).

    Returns:
        The strokes in the original's order and the region figures.
    """
    labels, regions = find_regions(
        mask.ink, mask.res_mm, params.min_region_mm2, params.min_loop_px
    )
    fill = hatch(labels, mask.xs, mask.ys, mask.res_mm, params.pitch_mm)
    region_labels = np.array([r.label for r in regions], dtype=np.int32)
    lo = np.searchsorted(fill.label, region_labels, side="left")
    hi = np.searchsorted(fill.label, region_labels, side="right")
    strokes: list[Stroke] = []
    for i, region in enumerate(regions):
        if region.outer is not None:
            strokes.append(Stroke(StrokeKind.OUTER, i, _loop_mm(mask, region.outer)))
        strokes.extend(Stroke(StrokeKind.HOLE, i, _loop_mm(mask, h)) for h in region.holes)
        strokes.extend(
            Stroke(StrokeKind.FILL, i, np.vstack([fill.a_mm[j], fill.b_mm[j]]))
            for j in range(lo[i], hi[i])
        )
    return Drawing(
        strokes=tuple(strokes),
        regions=len(regions),
        holes=sum(r.hole_count for r in regions),
        dropped_loops=sum(r.dropped_loops for r in regions),
    )
