"""Panel placement: refuse drawings that do not fit, map panel mm to the arm frame (m)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from tattotronix.art.grid import InkMask
from tattotronix.errors import TattotronixError
from tattotronix.path.params import ToolpathParams

__all__ = ["check_fits", "extent_mm", "to_arm"]

MM_PER_M = 1000.0
_TOL_MM = 1e-6


def extent_mm(mask: InkMask) -> tuple[float, float, float, float]:
    """(u_min, u_max, v_min, v_max) covered by the mask's pixels, panel mm."""
    half = mask.res_mm / 2
    return (
        float(mask.xs.min() - half), float(mask.xs.max() + half),
        float(mask.ys.min() - half), float(mask.ys.max() + half),
    )


def check_fits(mask: InkMask, params: ToolpathParams) -> None:
    """Refuse a drawing whose mask does not fit the panel, centred on it.

    Raises:
        TattotronixError: naming the drawing's size and the panel's.
    """
    u0, u1, v0, v1 = extent_mm(mask)
    pw, ph = params.panel_size_mm
    w, h = u1 - u0, v1 - v0
    if w > pw + _TOL_MM or h > ph + _TOL_MM:
        raise TattotronixError(
            f"drawing is {w:.1f} x {h:.1f} mm (mask extent), larger than the "
            f"{pw:.0f} x {ph:.0f} mm panel: lower mask.width_mm or crop the artwork"
        )
    # the mask grid is centred on the drawing to within half a pixel
    slack = mask.res_mm + _TOL_MM
    if u0 < -pw / 2 - slack or u1 > pw / 2 + slack or v0 < -ph / 2 - slack or v1 > ph / 2 + slack:
        raise TattotronixError(
            f"drawing spans u [{u0:.1f}, {u1:.1f}] x v [{v0:.1f}, {v1:.1f}] mm, off the "
            f"{pw:.0f} x {ph:.0f} mm panel: the mask grid must be centred on the drawing"
        )


def to_arm(uvz_mm: NDArray[np.float64], params: ToolpathParams) -> NDArray[np.float64]:
    """Panel (u, v, z) mm to the arm frame (x, y, z) m: the drawing centre lands on
    ``panel_origin`` (the centre of the panel surface)."""
    return np.asarray(params.panel_origin_m) + np.asarray(uvz_mm, dtype=np.float64) / MM_PER_M
