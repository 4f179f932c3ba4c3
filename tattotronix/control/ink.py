"""The ink: what the needle draws where its tip is below the panel surface.

Tip positions (arm frame, m) become panel millimetres (``u = x - x0``, ``v = y - y0``,
depth ``z - z0`` against the panel origin on its surface); every run of consecutive
samples below the surface is drawn as a polyline of the needle's width (0.3 mm, to
within a pixel) on a raster of ``res_mm`` pixels. The simulated ink and the planned ink
are rasterised alike, on the same grid, and compared: IoU, and the worst deviation (the
symmetric Hausdorff distance between the two inked areas, mm). Where one of the two inks
is empty a score cannot be given: it is None with a reason (``ink_reason``), never a
perfect one (two empty inks are not a perfect match).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from tattotronix.io.jsontypes import JsonDict
from tattotronix.path.fidelity import (
    InkGrid,
    below_runs,
    distance_at,
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
        iou: intersection over union of the inked pixels (None: neither inked anything).
        max_dev_mm: symmetric Hausdorff distance between the inked areas, mm (None: one
            of them is empty, so there is no distance to give).
        sim_px, plan_px: inked pixels.
        reason: why a score is None ("" when both are given).
    """

    iou: float | None
    max_dev_mm: float | None
    sim_px: int
    plan_px: int
    reason: str = ""

    def metrics(self) -> JsonDict:
        """JSON-ready: ``ink_iou``, ``ink_max_dev_mm`` (null where not given),
        ``ink_reason`` (why), ``ink_px``, ``plan_ink_px``."""
        return {"ink_iou": self.iou, "ink_max_dev_mm": self.max_dev_mm,
                "ink_reason": self.reason, "ink_px": self.sim_px, "plan_ink_px": self.plan_px}

    def unscored(self, reason: str) -> InkComparison:
        """The same inks, not scored, for ``reason`` (a run that saturated or diverged)."""
        return InkComparison(None, None, self.sim_px, self.plan_px, reason)

    def text(self) -> str:
        """``IoU 0.9978, worst deviation 0.05 mm`` (or why not)."""
        if self.iou is None and self.max_dev_mm is None:
            return f"ink {self.reason}"
        iou = "-" if self.iou is None else f"{self.iou:.4f}"
        dev = "-" if self.max_dev_mm is None else f"{self.max_dev_mm:.2f} mm"
        return f"IoU {iou}, worst deviation {dev}" + (f" ({self.reason})" if self.reason
                                                      else "")


def _worst_distance_px(a: NDArray[np.bool_], b: NDArray[np.bool_]) -> float:
    """max over pixels of ``a`` of the distance to the nearest pixel of ``b`` (px)."""
    return float(distance_at(b, a).max()) if a.any() else 0.0


def compare_ink(sim: NDArray[np.bool_], plan: NDArray[np.bool_], res_mm: float) -> InkComparison:
    """IoU and worst deviation of two ink rasters of the same grid.

    An empty ink scores no deviation (there is no distance to nothing), and two empty
    inks no IoU either: None, with the reason.
    """
    sim_px, plan_px = int(np.count_nonzero(sim)), int(np.count_nonzero(plan))
    inter = int(np.count_nonzero(sim & plan))
    union = int(np.count_nonzero(sim | plan))
    if not sim_px or not plan_px:
        why = ("not scored: neither the run nor the plan inked anything" if not union else
               "no worst deviation: the run inked nothing" if not sim_px else
               "no worst deviation: the plan inks nothing here")
        return InkComparison(iou=inter / union if union else None, max_dev_mm=None,
                             sim_px=sim_px, plan_px=plan_px, reason=why)
    dev = max(_worst_distance_px(sim, plan), _worst_distance_px(plan, sim)) * res_mm
    return InkComparison(iou=float(inter / union), max_dev_mm=float(dev), sim_px=sim_px,
                         plan_px=plan_px)
