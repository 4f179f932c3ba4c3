"""The panel: refuse drawings whose ink leaves it, map panel mm to the arm frame (m)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from tattotronix.art.grid import InkMask
from tattotronix.art.place import check_on_panel, ink_extent_mm
from tattotronix.path.params import ToolpathParams

__all__ = ["check_fits", "to_arm"]

MM_PER_M = 1000.0


def check_fits(mask: InkMask, params: ToolpathParams) -> None:
    """Refuse a drawing whose ink leaves the panel (where the mask stage put it).

    Raises:
        TattotronixError: naming the drawing's span, the panel's and the settings.
    """
    check_on_panel(ink_extent_mm(mask.ink, mask.xs, mask.ys, mask.res_mm),
                   params.panel_size_mm, "the drawing")


def to_arm(uvz_mm: NDArray[np.float64], params: ToolpathParams) -> NDArray[np.float64]:
    """Panel (u, v, z) mm to the arm frame (x, y, z) m: panel (0, 0, 0) is
    ``panel_origin`` (the centre of the panel surface)."""
    return np.asarray(params.panel_origin_m) + np.asarray(uvz_mm, dtype=np.float64) / MM_PER_M
