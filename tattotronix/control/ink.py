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

import numpy as np
from numpy.typing import ArrayLike, NDArray

from tattotronix.io.jsontypes import JsonDict
from tattotronix.path.fidelity import (
    InkGrid,
    below_runs,
    distance_to,
    grid_over,
    rasterise_runs,
)

__all__ = ["InkGrid", "InkComparison", "compare_ink", "ink_grid", "rasterise_ink"]

Array = NDArray[np.float64]


def _panel_mm(tip_m: Array, origin_m: ArrayLike) -> Array:
    return (np.asarray(tip_m, dtype=np.float64) - np.asarray(origin_m, dtype=np.float64)) * 1e3


def ink_grid(tips_m: list[Array], origin_m: ArrayLike, res_mm: float,
             margin_mm: float = 1.0, cover_mm: Array | None = None) -> InkGrid:
    """A grid covering every below-surface tip of ``tips_m`` (plus a margin), and the
    (N, 2) panel points ``cover_mm`` (the artwork's corners, to compare with it)."""
    pts = [p[p[:, 2] < 0.0, :2] for p in (_panel_mm(t, origin_m) for t in tips_m)]
    if cover_mm is not None:
        pts.append(np.asarray(cover_mm, dtype=np.float64))
    return grid_over(pts, res_mm, margin_mm)


def rasterise_ink(tip_m: Array, origin_m: ArrayLike, grid: InkGrid,
                  needle_mm: float) -> NDArray[np.bool_]:
    """Ink drawn by a tip path (samples in time order): True where inked."""
    return rasterise_runs(below_runs(_panel_mm(tip_m, origin_m)), grid, needle_mm)


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
    return float(distance_to(b)[a].max()) if a.any() else 0.0


def compare_ink(sim: NDArray[np.bool_], plan: NDArray[np.bool_], res_mm: float) -> InkComparison:
    """IoU and worst deviation of two ink rasters of the same grid."""
    inter = int(np.count_nonzero(sim & plan))
    union = int(np.count_nonzero(sim | plan))
    iou = inter / union if union else 1.0
    dev = max(_worst_distance_px(sim, plan), _worst_distance_px(plan, sim)) * res_mm
    return InkComparison(iou=float(iou), max_dev_mm=float(dev), sim_px=int(sim.sum()),
                         plan_px=int(plan.sum()))
