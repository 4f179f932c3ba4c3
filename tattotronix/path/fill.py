"""Boustrophedon hatch fill at exactly the stroke pitch.

Scanlines sit at ``y = ys[0] - k * pitch`` (k = 0, 1, ...), counted from the top row of
the grid as in the original, but at the exact pitch: the original rounded the pitch to a
whole number of mask rows (1.2 mm became 1.25 mm at 0.25 mm per pixel).

Clipping: a scanline is clipped against the mask row nearest to it, so under the
nearest-pixel reading of the mask every point of every hatch segment is on ink. When a
scanline falls exactly halfway between two rows, a column counts only if it is ink in both,
so the segment is on ink whichever row a reader rounds to. Runs of one pixel are dropped
(as in the original: a run must be longer than one pixel). The segments run between the
centres of the run's end pixels, which is where the traced outlines pass.

Direction alternates per inked scanline of each region (a scanline whose runs are all
single pixels still counts as inked, as in the original).

Other angles (``toolpath.fill_angle_deg``) hatch the label image turned by that angle
(nearest pixel, on a grid of the same pitch) with the same scanlines, and turn the
segments back; a cross-hatch (``toolpath.fill_style=cross``) adds a second pass at the
angle plus 90 degrees, after the first in each region.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

__all__ = ["FILL_STYLES", "MIN_RUN_PX", "Hatch", "fill_regions", "hatch", "hatch_at"]

#: the fill styles (``toolpath.fill_style``) made of hatch runs: one hatch, a cross-hatch
#: of two, a hatch at the needle's width (solid); ``concentric`` rings are traced in
#: :mod:`tattotronix.path.inset`
FILL_STYLES = ("hatch", "cross", "solid")

MIN_RUN_PX = 2  # shortest run of ink pixels that yields a hatch segment
INSET_PX = 1  # pull each end of a run of 4 px or more in by this many pixels
_TIE_PX = 1e-9  # a scanline this close to halfway between rows is a tie


@dataclass(frozen=True)
class Hatch:
    """Hatch segments in the original's drawing order.

    Sorted by region label, then scanline (top down), then along the row in the
    scanline's direction. Each segment is drawn from ``a_mm`` to ``b_mm``.

    Attributes:
        label: (m,) region label of each segment.
        line: (m,) scanline index k (y = ys[0] - k * pitch).
        a_mm: (m, 2) start point, mm.
        b_mm: (m, 2) end point, mm.
    """

    label: NDArray[np.int32]
    line: NDArray[np.intp]
    a_mm: NDArray[np.float64]
    b_mm: NDArray[np.float64]


def hatch(
    labels: NDArray[np.int32],
    xs: NDArray[np.float64],
    ys: NDArray[np.float64],
    res_mm: float,
    pitch_mm: float,
    inset_px: int = INSET_PX,
) -> Hatch:
    """Hatch every labelled region with horizontal scanlines at ``pitch_mm``.

    Args:
        labels: (H, W) region labels, 0 for background.
        xs: (W,) column x, mm (uniform grid at ``res_mm``).
        ys: (H,) row y, mm, decreasing.
        res_mm: grid pitch, mm.
        pitch_mm: scanline spacing, mm (> 0).
        inset_px: pull both ends of a run in by this many pixels, as long as at least
            ``MIN_RUN_PX`` pixels remain.

    Returns:
        The hatch segments (see :class:`Hatch`).
    """
    h, w = labels.shape
    f = np.arange(int(np.floor((h - 1) * res_mm / pitch_mm + _TIE_PX)) + 1) * (pitch_mm / res_mm)
    lower = np.floor(f).astype(np.intp)
    row = np.floor(f + 0.5).astype(np.intp)
    tie = (np.abs(f - lower - 0.5) < _TIE_PX) & (lower + 1 < h)
    lab = labels[np.minimum(row, h - 1)]
    if tie.any():
        up, down = labels[lower[tie]], labels[lower[tie] + 1]
        lab[tie] = np.where(up == down, up, 0)

    padded = np.pad(lab, ((0, 0), (1, 1)))
    change = padded[:, 1:] != padded[:, :-1]
    s_line, s_col = np.nonzero(change & (padded[:, 1:] != 0))
    _, e_col = np.nonzero(change & (padded[:, :-1] != 0))  # exclusive ends, same order
    run_label = lab[s_line, s_col]

    # direction: alternate per inked scanline within each region, top down
    key = run_label.astype(np.int64) * len(f) + s_line
    ukey, inverse = np.unique(key, return_inverse=True)
    ulabel = ukey // len(f)
    first = np.searchsorted(ulabel, ulabel, side="left")
    flip = ((np.arange(len(ukey)) - first) % 2 == 1)[inverse]

    keep = (e_col - s_col) >= MIN_RUN_PX
    s_line, s_col, e_col, run_label, flip = (
        v[keep] for v in (s_line, s_col, e_col, run_label, flip)
    )
    inset = np.minimum(inset_px, (e_col - s_col - MIN_RUN_PX) // 2)
    x0, x1 = xs[s_col + inset], xs[e_col - 1 - inset]
    y = ys[0] - s_line * pitch_mm
    order = np.lexsort((np.where(flip, -x0, x0), s_line, run_label))
    a = np.column_stack([np.where(flip, x1, x0), y])[order]
    b = np.column_stack([np.where(flip, x0, x1), y])[order]
    return Hatch(run_label[order].astype(np.int32), s_line[order], a, b)


def _turn(points: NDArray[np.float64], deg: float) -> NDArray[np.float64]:
    """(m, 2) points turned by ``deg`` degrees (anticlockwise) about the origin."""
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    return points @ np.array([[c, s], [-s, c]])


def hatch_at(
    labels: NDArray[np.int32],
    xs: NDArray[np.float64],
    ys: NDArray[np.float64],
    res_mm: float,
    pitch_mm: float,
    angle_deg: float,
    inset_px: int = INSET_PX,
) -> Hatch:
    """:func:`hatch` with scanlines at ``angle_deg`` degrees from the x axis
    (anticlockwise); 0 (or 180) is :func:`hatch` itself."""
    if math.isclose(math.remainder(angle_deg, 180.0), 0.0, abs_tol=1e-12):
        return hatch(labels, xs, ys, res_mm, pitch_mm, inset_px)
    h, w = labels.shape
    corners = np.array([[xs[0], ys[0]], [xs[-1], ys[0]], [xs[0], ys[-1]], [xs[-1], ys[-1]]])
    uv = _turn(corners, -angle_deg)  # the frame in which the scanlines are horizontal
    u0, v0 = float(uv[:, 0].min()), float(uv[:, 1].max())
    cols = int(math.ceil((uv[:, 0].max() - u0) / res_mm)) + 1
    rows = int(math.ceil((v0 - uv[:, 1].min()) / res_mm)) + 1
    c, s = math.cos(math.radians(angle_deg)), math.sin(math.radians(angle_deg))
    # each turned pixel (col, row) reads the source pixel its centre falls on
    m = np.array([[c, s, (c * u0 - s * v0 - xs[0]) / res_mm],
                  [-s, c, (ys[0] - s * u0 - c * v0) / res_mm]])
    turned = cv2.warpAffine(labels.astype(np.float32), m, (cols, rows),
                            flags=cv2.INTER_NEAREST | cv2.WARP_INVERSE_MAP,
                            borderMode=cv2.BORDER_CONSTANT, borderValue=0.0)
    us = u0 + np.arange(cols, dtype=np.float64) * res_mm
    vs = v0 - np.arange(rows, dtype=np.float64) * res_mm
    flat = hatch(turned.astype(np.int32), us, vs, res_mm, pitch_mm, inset_px)
    return Hatch(flat.label, flat.line, _turn(flat.a_mm, angle_deg),
                 _turn(flat.b_mm, angle_deg))


def fill_regions(
    labels: NDArray[np.int32],
    xs: NDArray[np.float64],
    ys: NDArray[np.float64],
    res_mm: float,
    pitch_mm: float,
    angle_deg: float = 0.0,
    style: str = "hatch",
    inset_px: int = INSET_PX,
) -> Hatch:
    """The fill of every region: a hatch at ``angle_deg`` (``style`` ``hatch``, or
    ``solid``, for which the caller passes the needle's width as ``pitch_mm``), or a
    cross-hatch (``cross``: a second pass at ``angle_deg + 90``, after the first in each
    region)."""
    if style not in FILL_STYLES:
        raise ValueError(f"fill style {style!r}: use one of {', '.join(FILL_STYLES)}")
    first = hatch_at(labels, xs, ys, res_mm, pitch_mm, angle_deg, inset_px)
    if style != "cross":
        return first
    second = hatch_at(labels, xs, ys, res_mm, pitch_mm, angle_deg + 90.0, inset_px)
    offset = int(first.line.max()) + 1 if len(first.line) else 0
    label = np.concatenate([first.label, second.label])
    order = np.argsort(label, kind="stable")  # each region: its first pass, then its second
    return Hatch(label[order], np.concatenate([first.line, second.line + offset])[order],
                 np.concatenate([first.a_mm, second.a_mm])[order],
                 np.concatenate([first.b_mm, second.b_mm])[order])
