"""Mask to toolpath in one call: strokes, ordering, 3-D path, timing, arm frame, metrics.

The original's ordering is planned beside ours on the same strokes (same pitch, same
resampling), with the original's lift rule: it stays down across any gap whose straight line
is on ink, however long, where ours stays down only where that is also faster than a lift.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from tattotronix.art.grid import InkMask
from tattotronix.errors import TattotronixError
from tattotronix.io.jsontypes import JsonDict
from tattotronix.path.order import MAX_PASSES, Order, OrderResult, optimise_order, original_order
from tattotronix.path.panel import check_fits, to_arm
from tattotronix.path.params import ToolpathParams
from tattotronix.path.path3d import Path3D, build_path
from tattotronix.path.strokes import Drawing, build_drawing
from tattotronix.path.timing import PathMetrics, measure, timestamps

__all__ = ["Toolpath", "plan_toolpath"]

log = logging.getLogger("tattotronix.path")


@dataclass(frozen=True)
class Toolpath:
    """A planned toolpath and its figures.

    Attributes:
        drawing: the strokes (original order) and region figures.
        order: our drawing order.
        path: the 3-D path in the panel frame (mm).
        t_s: (N,) planned timestamps, s.
        xyz_m: (N, 3) the path in the arm frame, m.
        metrics: figures of our path.
        original: figures of the path under the original's ordering rule.
        ordering: how the order was found.
    """

    drawing: Drawing
    order: Order
    path: Path3D
    t_s: NDArray[np.float64]
    xyz_m: NDArray[np.float64]
    metrics: PathMetrics
    original: PathMetrics
    ordering: OrderResult

    def metrics_dict(self) -> JsonDict:
        """The metrics file: our figures, the original ordering's, and the ratios."""
        ours, orig = self.metrics, self.original

        def ratio(a: float, b: float) -> float | None:
            return None if b == 0 else round(a / b, 6)

        return {
            **ours.as_dict(),
            "regions": self.drawing.regions,
            "holes": self.drawing.holes,
            "strokes": len(self.drawing.strokes),
            "dropped_loops": self.drawing.dropped_loops,
            "original_order": {
                **orig.as_dict(),
                "regions": self.drawing.regions,
                "holes": self.drawing.holes,
            },
            "improvement": {
                "travel_ratio": ratio(ours.travel_mm, orig.travel_mm),
                "entries_ratio": ratio(ours.entries, orig.entries),
                "time_ratio": ratio(ours.time_s, orig.time_s),
                "time_saved_s": round(orig.time_s - ours.time_s, 6),
            },
            "ordering": {
                "between_strokes_s": round(self.ordering.cost_s, 6),
                "between_strokes_greedy_s": round(self.ordering.greedy_cost_s, 6),
                "between_strokes_original_s": round(self.ordering.original_cost_s, 6),
                "two_opt_passes": self.ordering.passes,
                "two_opt_moves": self.ordering.moves,
                "reversed_strokes": self.ordering.reversed,
                "kept_original": self.ordering.kept_original,
            },
        }


def plan_toolpath(mask: InkMask, params: ToolpathParams, max_passes: int = MAX_PASSES
                  ) -> Toolpath:
    """Plan the needle path for an ink mask.

    Args:
        mask: the ink mask.
        params: the toolpath parameters.
        max_passes: the ordering search's budget of 2-opt passes (work, not time).

    Returns:
        The toolpath, with the original ordering's figures beside ours.

    Raises:
        TattotronixError: the drawing does not fit the panel, or has no ink region to draw.
    """
    check_fits(mask, params)
    drawing = build_drawing(mask, params)
    if not drawing.strokes:
        raise TattotronixError(
            f"the mask has no ink region of at least {params.min_region_mm2} mm^2 "
            "(mask.min_region_mm2): nothing to draw; check the artwork or the mask method"
        )
    result = optimise_order(drawing, mask, params, max_passes=max_passes)
    path = build_path(result.order.points(drawing, params.step_mm), mask, params)
    baseline = build_path(
        original_order(drawing).points(drawing, params.step_mm), mask, params, math.inf
    )
    t = timestamps(path, params)
    ours, orig = measure(path, params), measure(baseline, params)
    log.info(
        "ordered %d strokes in %.2f s (%d 2-opt passes): %.1f s between strokes, "
        "%.1f s greedy, %.1f s in the original's order",
        len(drawing.strokes), result.elapsed_s, result.passes, result.cost_s,
        result.greedy_cost_s, result.original_cost_s,
    )
    return Toolpath(drawing, result.order, path, t, to_arm(path.uvz_mm, params), ours, orig,
                    result)
