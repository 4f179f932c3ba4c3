"""Ink regions and their boundary loops (outer outline and hole outlines).

Regions are 8-connected ink components; holes (counters) are the 4-connected background
components a region encloses, the consistent pairing for 8-connected foreground. Loops are
traced with OpenCV's border following (Suzuki-Abe, ``RETR_CCOMP`` and
``CHAIN_APPROX_NONE``) on each region alone, so an island inside a counter is never mixed
into the counter's loop. Like the reference's Moore tracer, the loops run through the
centres of the region's boundary pixels.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

__all__ = ["Region", "boundary_coverage", "find_regions", "trace_loops"]


@dataclass(frozen=True)
class Region:
    """One 8-connected ink region, with its traced loops in grid coordinates.

    Attributes:
        label: the region's value in the label image returned by :func:`find_regions`.
        pixels: its pixel count.
        mean_col: mean column of its pixels (the original orders regions by it).
        rows: the slice of grid rows its bounding box covers.
        cols: the slice of grid columns its bounding box covers.
        outer: (n, 2) int (row, col) of the outer loop, or None when shorter than the
            minimum loop length.
        holes: hole loops that were kept, each (n, 2) int (row, col).
        hole_count: every traced hole (4-connected enclosed background component).
        dropped_loops: loops dropped for being shorter than the minimum.
    """

    label: int
    pixels: int
    mean_col: float
    rows: slice
    cols: slice
    outer: NDArray[np.int32] | None
    holes: tuple[NDArray[np.int32], ...]
    hole_count: int
    dropped_loops: int

    @property
    def loops(self) -> list[NDArray[np.int32]]:
        """Every kept loop: the outer one first, then the holes."""
        return ([self.outer] if self.outer is not None else []) + list(self.holes)


def trace_loops(region: NDArray[np.bool_]) -> tuple[NDArray[np.int32], list[NDArray[np.int32]]]:
    """Trace the outer loop and the hole loops of one 8-connected region.

    Args:
        region: (H, W) bool image holding exactly one 8-connected component.

    Returns:
        The outer loop and the hole loops, each an (n, 2) int array of (row, col) pixel
        centres, consecutive entries 8-adjacent, the last 8-adjacent to the first (the
        first point is not repeated).
    """
    padded = np.pad(region, 1).astype(np.uint8)
    contours, hierarchy = cv2.findContours(padded, cv2.RETR_CCOMP, cv2.CHAIN_APPROX_NONE)
    if not contours:
        raise ValueError("trace_loops: the region is empty")
    parents = hierarchy[0, :, 3]
    loops = [c[:, 0, ::-1].astype(np.int32) - 1 for c in contours]  # (x, y) -> (row, col)
    outers = [lp for lp, p in zip(loops, parents, strict=True) if p < 0]
    if len(outers) != 1:
        raise ValueError(f"trace_loops: expected one 8-connected region, found {len(outers)}")
    holes = [lp for lp, p in zip(loops, parents, strict=True) if p >= 0]
    return outers[0], holes


def find_regions(
    ink: NDArray[np.bool_], res_mm: float, min_region_mm2: float, min_loop_px: int
) -> tuple[NDArray[np.int32], list[Region]]:
    """Label the mask 8-connected, drop small regions, trace each region's loops.

    Args:
        ink: (H, W) bool ink mask.
        res_mm: grid pitch, mm.
        min_region_mm2: regions smaller than this (pixel count x res^2) are dropped, mm^2.
        min_loop_px: loops with fewer pixels are dropped.

    Returns:
        The label image (0 background, dropped regions cleared) and the kept regions,
        ordered left to right by the mean column of their pixels (the original's order).
    """
    count, labels, stats, centroids = cv2.connectedComponentsWithStats(
        np.ascontiguousarray(ink, dtype=np.uint8), connectivity=8, ltype=cv2.CV_32S
    )
    area_px = stats[:, cv2.CC_STAT_AREA]
    keep = np.flatnonzero(area_px * res_mm**2 >= min_region_mm2)
    keep = keep[keep > 0]
    lut = np.zeros(count, np.int32)
    lut[keep] = keep
    labels = lut[labels]
    regions = []
    for lab in keep[np.argsort(centroids[keep, 0], kind="stable")]:
        x, y, w, h = stats[lab, :4]
        rows, cols = slice(int(y), int(y + h)), slice(int(x), int(x + w))
        outer, holes = trace_loops(labels[rows, cols] == lab)
        offset = np.array([rows.start, cols.start], np.int32)
        kept_holes = tuple(hl + offset for hl in holes if len(hl) >= min_loop_px)
        long_outer = len(outer) >= min_loop_px
        regions.append(
            Region(
                label=int(lab),
                pixels=int(area_px[lab]),
                mean_col=float(centroids[lab, 0]),
                rows=rows,
                cols=cols,
                outer=outer + offset if long_outer else None,
                holes=kept_holes,
                hole_count=len(holes),
                dropped_loops=int(not long_outer) + len(holes) - len(kept_holes),
            )
        )
    return labels, regions


def boundary_coverage(region: NDArray[np.bool_], loops: list[NDArray[np.int32]]) -> float:
    """Share of the region's boundary pixels that lie on some loop.

    Args:
        region: (H, W) bool image of one region.
        loops: (n, 2) int (row, col) loops in the same grid.

    Returns:
        Coverage in [0, 1]; the boundary is the region minus its (4-neighbour) erosion.
    """
    boundary = region & ~ndimage.binary_erosion(region)
    on_loop = np.zeros_like(region)
    for lp in loops:
        on_loop[lp[:, 0], lp[:, 1]] = True
    total = int(boundary.sum())
    return 1.0 if total == 0 else float((boundary & on_loop).sum()) / total
