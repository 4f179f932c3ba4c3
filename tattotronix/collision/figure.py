"""The collision stage's figure: clearance of the closest pairs along the trajectory."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike

from tattotronix.collision.check import TrajectoryClearance
from tattotronix.report.figures import clearance_figure as _figure

__all__ = ["clearance_figure"]


def clearance_figure(rep: TrajectoryClearance, t: ArrayLike, kind: ArrayLike,
                     path: Path) -> Path:
    """Draw ``rep`` (a checked trajectory) to ``path``."""
    w = rep.worst
    title = (f"least clearance {rep.min_clearance_m[w] * 1000:.2f} mm "
             f"({rep.pair_names[w].replace('|', ' / ')}), margin {rep.margin_m * 1000:g} mm; "
             f"{rep.samples} poses, {rep.bisected} segments bisected")
    return _figure(rep.pair_names, rep.series_m, rep.min_clearance_m, np.asarray(t),
                   kind, rep.margin_m, path, title)
