"""The ink: what the needle draws where its tip is below the panel surface.

Tip positions (arm frame, m) become panel millimetres (``u = x - x0``, ``v = y - y0``,
depth ``z - z0`` against the panel origin on its surface); every run of consecutive
samples below the surface is drawn as a polyline of the needle's width (0.3 mm, to
within a pixel) on a raster of ``res_mm`` pixels. The simulated ink and the planned ink
are rasterised alike, on the same grid, and compared: IoU, and the worst deviation (the
symmetric Hausdorff distance between the two inked areas, mm).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from tattotronix.io.jsontypes import JsonDict

__all__ = ["InkGrid", "InkComparison", "compare_ink", "ink_grid", "rasterise_ink"]

Array = NDArray[np.float64]
_SHIFT = 4  # cv2 fixed-point bits: 1/16 px


@dataclass(frozen=True)
class InkGrid:
    """A raster over the panel plane.

    Attributes:
        u0_mm, v0_mm: panel coordinates of pixel (0, 0)'s centre, mm (row 0 is the top,
            highest ``v``).
        res_mm: pixel size, mm.
        shape: (rows, cols).
    """

    u0_mm: float
    v0_mm: float
    res_mm: float
    shape: tuple[int, int]

    def to_px(self, uv_mm: Array) -> Array:
        """(N, 2) panel mm -> (N, 2) pixel (col, row) coordinates (float)."""
        col = (uv_mm[:, 0] - self.u0_mm) / self.res_mm
        row = (self.v0_mm - uv_mm[:, 1]) / self.res_mm
        return np.stack([col, row], axis=1)


def _panel_mm(tip_m: Array, origin_m: ArrayLike) -> Array:
    return (np.asarray(tip_m, dtype=np.float64) - np.asarray(origin_m, dtype=np.float64)) * 1e3


def ink_grid(tips_m: list[Array], origin_m: ArrayLike, res_mm: float,
             margin_mm: float = 1.0) -> InkGrid:
    """A grid covering every below-surface tip of ``tips_m`` (plus a margin)."""
    pts = [p[p[:, 2] < 0.0, :2] for p in (_panel_mm(t, origin_m) for t in tips_m)]
    allp = np.concatenate([p for p in pts if len(p)] or [np.zeros((1, 2))])
    lo = allp.min(axis=0) - margin_mm
    hi = allp.max(axis=0) + margin_mm
    cols = int(np.ceil((hi[0] - lo[0]) / res_mm)) + 1
    rows = int(np.ceil((hi[1] - lo[1]) / res_mm)) + 1
    return InkGrid(u0_mm=float(lo[0]), v0_mm=float(hi[1]), res_mm=float(res_mm),
                   shape=(rows, cols))


def rasterise_ink(tip_m: Array, origin_m: ArrayLike, grid: InkGrid,
                  needle_mm: float) -> NDArray[np.bool_]:
    """Ink drawn by a tip path (samples in time order): True where inked."""
    uvz = _panel_mm(tip_m, origin_m)
    below = uvz[:, 2] < 0.0
    img = np.zeros(grid.shape, dtype=np.uint8)
    if not below.any():
        return img.astype(bool)
    px = np.rint(grid.to_px(uvz[:, :2]) * (1 << _SHIFT)).astype(np.int32)
    # cv2 inks the pixel centres within thickness/2 of the line, both edges included, so
    # a band of thickness t covers about t + 1 pixels: t = width/res - 1 (within a pixel)
    thick = max(1, int(round(needle_mm / grid.res_mm)) - 1)
    edges = np.diff(np.concatenate(([0], below.astype(np.int8), [0])))
    starts, stops = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    lines = [px[a:b].reshape(-1, 1, 2) for a, b in zip(starts, stops, strict=True)]
    cv2.polylines(img, lines, isClosed=False, color=1, thickness=thick, lineType=cv2.LINE_8,
                  shift=_SHIFT)
    radius = max(1, int(round(needle_mm / grid.res_mm / 2 - 0.5)))
    for a, b in zip(starts, stops, strict=True):
        if b - a == 1:  # a single sample: a dot
            c = (int(px[a, 0]), int(px[a, 1]))
            cv2.circle(img, c, radius << _SHIFT, 1, -1, cv2.LINE_8, _SHIFT)
    return img.astype(bool)


@dataclass(frozen=True)
class InkComparison:
    """Simulated ink against planned ink on one grid.

    Attributes:
        iou: intersection over union of the inked pixels.
        max_dev_mm: symmetric Hausdorff distance between the inked areas, mm.
        sim_px, plan_px: inked pixels.
    """

    iou: float
    max_dev_mm: float
    sim_px: int
    plan_px: int

    def metrics(self) -> JsonDict:
        """JSON-ready."""
        return {"ink_iou": self.iou, "ink_max_dev_mm": self.max_dev_mm,
                "ink_px": self.sim_px, "plan_ink_px": self.plan_px}


def _worst_distance_px(a: NDArray[np.bool_], b: NDArray[np.bool_]) -> float:
    """max over pixels of ``a`` of the distance to the nearest pixel of ``b`` (px)."""
    if not a.any():
        return 0.0
    if not b.any():
        return float("inf")
    dist = cv2.distanceTransform((~b).astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
    return float(dist[a].max())


def compare_ink(sim: NDArray[np.bool_], plan: NDArray[np.bool_], res_mm: float) -> InkComparison:
    """IoU and worst deviation of two ink rasters of the same grid."""
    inter = int(np.count_nonzero(sim & plan))
    union = int(np.count_nonzero(sim | plan))
    iou = inter / union if union else 1.0
    dev = max(_worst_distance_px(sim, plan), _worst_distance_px(plan, sim)) * res_mm
    return InkComparison(iou=float(iou), max_dev_mm=float(dev), sim_px=int(sim.sum()),
                         plan_px=int(plan.sum()))
