"""The drawing's place on the panel: an anchor point, where it lands, and a rotation.

The artwork is sized on its own grid, centred on the drawing (:meth:`InkMask.centred`).
``mask.anchor`` names a point of that grid: its centre (the default, where the drawing
has always gone), or a corner or the middle of a side of its extent. The drawing turns
``mask.rotate_deg`` anticlockwise about that point, which lands at ``mask.at_mm`` (mm from
the panel's centre, u along the arm's x, v along its y). As one map of the drawing's
centred frame ``p`` to the panel: ``R p + shift``, ``shift = at - R anchor``.

The mask stage places the artwork raster (:func:`place_grey`: turned on a canvas grown to
hold it, bilinear on the grey tones, before thresholding, so the edge stays as smooth as
the unturned one) and stores ``(rotate_deg, shift)`` with the mask (:attr:`InkMask.place`)
so the toolpath puts an SVG's vector lines in the same place. A drawing whose ink leaves
the panel is refused there, before any work, naming the settings that move it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from tattotronix.config.schema import Anchor
from tattotronix.errors import TattotronixError

__all__ = ["ANCHOR_SIDES", "Placement", "check_on_panel", "ink_extent_mm", "place_grey"]

#: each anchor's side along u and v: -1 left / bottom, 0 the centre, +1 right / top
ANCHOR_SIDES: dict[Anchor, tuple[int, int]] = {
    Anchor.centre: (0, 0), Anchor.top_left: (-1, 1), Anchor.top: (0, 1),
    Anchor.top_right: (1, 1), Anchor.left: (-1, 0), Anchor.right: (1, 0),
    Anchor.bottom_left: (-1, -1), Anchor.bottom: (0, -1), Anchor.bottom_right: (1, -1),
}
_TOL_MM = 1e-6


@dataclass(frozen=True)
class Placement:
    """The map of the drawing's centred frame to the panel: ``R(rotate_deg) p + shift``.

    Attributes:
        rotate_deg: anticlockwise turn, degrees.
        shift_mm: (u, v) where the drawing's centred origin lands, mm.
    """

    rotate_deg: float = 0.0
    shift_mm: tuple[float, float] = (0.0, 0.0)

    @classmethod
    def of(cls, shape: tuple[int, int], res_mm: float, anchor: Anchor,
           at_mm: Sequence[float], rotate_deg: float) -> Placement:
        """The placement of a ``shape`` (H, W) grid at ``res_mm`` whose ``anchor`` lands at
        ``at_mm``, turned ``rotate_deg`` about it.

        Raises:
            TattotronixError: ``at_mm`` is not two finite numbers.
        """
        at = [float(a) for a in at_mm]
        if len(at) != 2 or not all(math.isfinite(a) for a in at):
            raise TattotronixError(f"mask.at_mm must be two numbers [u, v] in mm, got {at_mm}")
        h, w = shape
        su, sv = ANCHOR_SIDES[anchor]
        # the centred grid's extent: columns (c - W/2) res, rows (H/2 - 1 - r) res, each
        # pixel half a pitch either side of its centre
        u = {-1: -(w + 1) / 2 * res_mm, 0: 0.0, 1: (w - 1) / 2 * res_mm}[su]
        v = {-1: -(h + 1) / 2 * res_mm, 0: 0.0, 1: (h - 1) / 2 * res_mm}[sv]
        ru, rv = _rotate(np.array([[u, v]]), rotate_deg)[0]
        return cls(float(rotate_deg), (at[0] - float(ru), at[1] - float(rv)))

    @property
    def identity(self) -> bool:
        """Whether the drawing stays where the centred grid puts it."""
        return self.rotate_deg % 360.0 == 0.0 and self.shift_mm == (0.0, 0.0)

    def apply(self, points_mm: NDArray[np.float64]) -> NDArray[np.float64]:
        """(N, 2) points of the drawing's centred frame on the panel, mm."""
        p = np.asarray(points_mm, dtype=np.float64)
        if self.identity:
            return p
        return _rotate(p, self.rotate_deg) + np.asarray(self.shift_mm)

    def as_array(self) -> NDArray[np.float64]:
        """``[rotate_deg, shift_u, shift_v]`` (what a mask file stores)."""
        return np.array([self.rotate_deg, *self.shift_mm], dtype=np.float64)

    @classmethod
    def from_array(cls, a: NDArray[np.float64]) -> Placement:
        """What :meth:`as_array` gave."""
        return cls(float(a[0]), (float(a[1]), float(a[2])))


def _rotate(p: NDArray[np.float64], deg: float) -> NDArray[np.float64]:
    if deg % 360.0 == 0.0:
        return np.asarray(p, dtype=np.float64)
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    return np.asarray(p, dtype=np.float64) @ np.array([[c, s], [-s, c]])


def place_grey(grey: NDArray[np.generic], res_mm: float, place: Placement
               ) -> tuple[NDArray[np.generic], NDArray[np.float64], NDArray[np.float64]]:
    """The artwork raster on the panel: turned (bilinear) on a canvas grown to hold it,
    the new corners in the background tone (the median of the raster's border), and the
    panel coordinates of its columns and rows.

    Args:
        grey: (H, W) grey tones on the centred grid.
        res_mm: the grid's pitch, mm.
        place: where it goes.

    Returns:
        ``(grey, xs, ys)``: the placed raster, its columns' u and its rows' v, mm (as
        :class:`~tattotronix.art.grid.InkMask` holds them: xs increasing, ys decreasing).
    """
    h, w = np.shape(grey)
    if place.rotate_deg % 360.0 != 0.0:
        t = math.radians(place.rotate_deg)
        c, s = abs(math.cos(t)), abs(math.sin(t))
        w2 = int(math.ceil(w * c + h * s - 1e-9))
        h2 = int(math.ceil(w * s + h * c - 1e-9))
        # target pixel (c', r') -> its centred point -> turned back -> source pixel (c, r)
        # target pixel (c', r') is p' = ((c' - W'/2) res, (H'/2 - 1 - r') res); its source
        # point p = R^T p' is pixel (p_u / res + W/2, H/2 - 1 - p_v / res)
        co, si = math.cos(t), math.sin(t)
        m = np.array([[co, -si, -co * w2 / 2 + si * (h2 / 2 - 1) + w / 2],
                      [si, co, h / 2 - 1 - si * w2 / 2 - co * (h2 / 2 - 1)]])
        border = np.concatenate([grey[0], grey[-1], grey[:, 0], grey[:, -1]])
        grey = cv2.warpAffine(np.asarray(grey, dtype=np.float32), m, (w2, h2),
                              flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
                              borderMode=cv2.BORDER_CONSTANT,
                              borderValue=float(np.median(border))).astype(np.float64)
        h, w = h2, w2
    xs = (np.arange(w) - w / 2) * res_mm + place.shift_mm[0]
    ys = ((np.arange(h) - h / 2) * res_mm)[::-1] + place.shift_mm[1]
    return grey, xs, ys.copy()


def ink_extent_mm(ink: NDArray[np.bool_], xs: NDArray[np.float64], ys: NDArray[np.float64],
                  res_mm: float) -> tuple[float, float, float, float] | None:
    """(u_min, u_max, v_min, v_max) of the inked pixels, mm; None without ink."""
    rows = np.flatnonzero(ink.any(axis=1))
    cols = np.flatnonzero(ink.any(axis=0))
    if rows.size == 0:
        return None
    half = res_mm / 2
    return (float(xs[cols[0]] - half), float(xs[cols[-1]] + half),
            float(ys[rows[-1]] - half), float(ys[rows[0]] + half))


def check_on_panel(extent: tuple[float, float, float, float] | None,
                   panel_mm: tuple[float, float], what: str) -> None:
    """Refuse a drawing whose ink leaves the panel.

    Args:
        extent: the ink's (u_min, u_max, v_min, v_max), mm (None: no ink, nothing to check).
        panel_mm: the panel's (width, height), mm, centred on its origin.
        what: names the drawing in the message.

    Raises:
        TattotronixError: naming the drawing's span, the panel's and the settings.
    """
    if extent is None:
        return
    u0, u1, v0, v1 = extent
    pw, ph = panel_mm
    if u1 - u0 > pw + _TOL_MM or v1 - v0 > ph + _TOL_MM:
        raise TattotronixError(
            f"{what} is {u1 - u0:.1f} x {v1 - v0:.1f} mm of ink, larger than the "
            f"{pw:.0f} x {ph:.0f} mm panel: lower mask.width_mm (or mask.height_mm), "
            "turn it with mask.rotate_deg, or crop the artwork")
    if u0 < -pw / 2 - _TOL_MM or u1 > pw / 2 + _TOL_MM or v0 < -ph / 2 - _TOL_MM \
            or v1 > ph / 2 + _TOL_MM:
        raise TattotronixError(
            f"{what}'s ink spans u [{u0:.1f}, {u1:.1f}] x v [{v0:.1f}, {v1:.1f}] mm, off "
            f"the {pw:.0f} x {ph:.0f} mm panel (u [{-pw / 2:.0f}, {pw / 2:.0f}], v "
            f"[{-ph / 2:.0f}, {ph / 2:.0f}] from its centre): move it with mask.at_mm "
            "and mask.anchor, or make it smaller")
