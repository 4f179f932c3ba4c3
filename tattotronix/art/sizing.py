"""The drawing's size and the mask grid's pitch, chosen from the artwork itself.

* **Size.** An SVG whose ``width`` is in a physical unit (mm, cm, in, pt, pc) is drawn at
  that size, unless ``mask.width_mm`` says otherwise; any other artwork (a raster, an SVG
  sized in px or unitless) is ``mask.default_width_mm`` wide.
* **Pitch.** ``mask.res_mm`` is the coarsest grid the mask is made on. A stroked SVG line
  spanning fewer than ``mask.min_line_px`` pixels of it is thresholded into dashes (a 0.5
  mm line at 0.25 mm: 23 to 45 % of its length kept), so the pitch is refined, to a value
  from :data:`PITCH_LADDER`, until the thinnest stroke spans that many pixels. The
  refinement is logged, naming the line that asked for it.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from pathlib import Path

from tattotronix.errors import TattotronixError

__all__ = ["PITCH_LADDER", "Stroke", "drawing_width_mm", "grid_pitch_mm", "svg_strokes",
           "thinnest_stroke"]

log = logging.getLogger(__name__)

#: the grid pitches a refinement may choose, mm (each divides 1 mm into whole pixels or
#: halves, so grids stay aligned with the millimetre)
PITCH_LADDER = (0.25, 0.2, 0.125, 0.1, 0.08, 0.0625, 0.05, 0.04, 0.025, 0.02)

#: 0.3 mm over 0.1 mm is 2.9999999999999996 in floating point: counted as 3
_ROUNDING = 1 + 1e-9


@dataclass(frozen=True)
class Stroke:
    """A stroked SVG element: what names it (``<polyline id="wave">``) and its width on the
    drawing, mm."""

    what: str
    width_mm: float


def drawing_width_mm(width_mm: float | None, default_width_mm: float | None,
                     own_mm: float | None = None, *, height_mm: float | None = None,
                     aspect: float | None = None) -> float:
    """How wide the drawing is, mm: ``width_mm`` when set; else ``height_mm`` times the
    artwork's ``aspect`` (width over height) when that is set; else the artwork's own
    physical width ``own_mm`` (an SVG's,
    :func:`tattotronix.art.artwork.svg_physical_width_mm`); else ``default_width_mm``.

    Raises:
        TattotronixError: both a width and a height, or no width at all (neither is set
            and the SVG has none).
    """
    if width_mm is not None and height_mm is not None:
        raise TattotronixError(
            f"mask.width_mm={width_mm:g} and mask.height_mm={height_mm:g} are both set: "
            "set one (the other follows from the artwork's aspect)")
    if width_mm is not None:
        return float(width_mm)
    if height_mm is not None:
        if aspect is None or not (math.isfinite(aspect) and aspect > 0):
            raise TattotronixError(f"mask.height_mm={height_mm:g}: the artwork has no "
                                   "aspect to size it by")
        return float(height_mm) * float(aspect)
    if own_mm is not None:
        return float(own_mm)
    if default_width_mm is None:
        raise TattotronixError("the artwork has no physical size: set mask.width_mm")
    return float(default_width_mm)


def svg_strokes(path: Path, mm_per_px: float) -> list[Stroke]:
    """Every stroked element of an SVG (filled or not) with its stroke width, mm.

    Args:
        path: the SVG file.
        mm_per_px: mm on the drawing per CSS px of the SVG (its drawn width over its
            intrinsic width).
    """
    from svgelements import SVG, Shape

    try:
        svg = SVG.parse(str(path), reify=True)
    except Exception as exc:  # svgelements raises many kinds on bad input
        raise TattotronixError(f"artwork {path}: cannot read its strokes ({exc})") from None
    found = []
    for el in svg.elements():
        if not isinstance(el, Shape) or el.stroke is None or el.stroke.value is None:
            continue
        if el.stroke.alpha == 0:
            continue
        width_px = float(el.implicit_stroke_width or 0.0)
        if width_px <= 0:
            continue
        tag = type(el).__name__.lower()
        ident = el.values.get("id") if hasattr(el, "values") else None
        what = f'<{tag} id="{ident}">' if ident else f"<{tag}>"
        found.append(Stroke(what, width_px * mm_per_px))
    return found


def thinnest_stroke(strokes: list[Stroke]) -> Stroke | None:
    """The thinnest of ``strokes`` (None: there are none)."""
    return min(strokes, key=lambda s: s.width_mm, default=None)


def grid_pitch_mm(res_mm: float, thinnest: Stroke | None, min_line_px: float) -> float:
    """The mask grid's pitch: ``res_mm``, refined to the coarsest pitch of
    :data:`PITCH_LADDER` at which the thinnest stroke spans ``min_line_px`` pixels.

    Never coarser than ``res_mm``; ``min_line_px`` 0 or no stroke: ``res_mm``. A stroke
    too thin for the finest pitch gets the finest (logged as a warning).
    """
    want = thinnest.width_mm / min_line_px * _ROUNDING if thinnest and min_line_px > 0 else 0
    if want == 0 or res_mm <= want:
        return float(res_mm)
    finer = [p for p in PITCH_LADDER if p < res_mm]
    pick = next((p for p in finer if p <= want), finer[-1] if finer else res_mm)
    assert thinnest is not None
    if pick > want:
        log.warning("mask: the thinnest line, %s, is %.3g mm wide: even at %.3g mm/px it "
                    "spans %.1f px (mask.min_line_px=%g)", thinnest.what, thinnest.width_mm,
                    pick, thinnest.width_mm / pick, min_line_px)
    else:
        log.info("mask: %.3g mm/px instead of %.3g, so the thinnest line, %s (%.3g mm), "
                 "spans %.1f px (mask.min_line_px=%g)", pick, res_mm, thinnest.what,
                 thinnest.width_mm, thinnest.width_mm / pick, min_line_px)
    return float(pick)
