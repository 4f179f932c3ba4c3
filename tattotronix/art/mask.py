"""Grey raster to ink mask (docs/original.md, "2.1 Artwork and mask" and "2.2 Regions";
docs/toolpath.md, "Artwork to ink mask"), through OpenCV.

Two methods (:class:`~tattotronix.config.schema.MaskMethod`):

* ``threshold`` (logos, lettering, flat art): Otsu's threshold; the darker side is ink
  unless it is the majority, in which case the lighter side is (ink is the minority, so
  artwork on a black field still yields the artwork). The log says so in one line when
  it happens; ``mask.auto_invert=false`` always takes the darker side.
* ``edges`` (photographs): Gaussian blur (``edge_sigma_px``), Sobel along both axes,
  gradient magnitude; ink where the magnitude exceeds ``mean + edge_k * std``.

Then regions (8-connected ink) smaller than ``min_region_mm2`` are dropped, and holes
(4-connected background components that do not reach the border) are counted.
"""

from __future__ import annotations

import logging
from dataclasses import asdict, dataclass
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from tattotronix.art.grid import InkMask
from tattotronix.art.place import Placement, check_on_panel, ink_extent_mm, place_grey
from tattotronix.config.schema import MaskConfig, MaskMethod
from tattotronix.errors import TattotronixError
from tattotronix.io.jsontypes import JsonDict

__all__ = [
    "MaskMethodError",
    "MaskStats",
    "NoInkError",
    "Regions",
    "count_holes",
    "edge_ink",
    "label_regions",
    "make_mask",
    "mask_method",
    "otsu_ink",
]

log = logging.getLogger(__name__)
_DEFAULTS = MaskConfig()  # make_mask's keyword defaults are the schema's

ALLOWED_METHODS: tuple[str, ...] = tuple(m.value for m in MaskMethod)

EDGE_MIN_MAGNITUDE = 0.5
"""Gradient magnitudes (Sobel, grey levels per px) at or below this are never edges:
float round-off on a flat image is not a drawing."""


class NoInkError(TattotronixError):
    """The artwork has nothing to draw (flat, or every region too small)."""


class MaskMethodError(TattotronixError, ValueError):
    """An unknown mask method; the message lists the allowed values."""


@dataclass(frozen=True)
class MaskStats:
    """What the mask stage reports (``data/metrics/mask/<name>.json``).

    Attributes:
        method: ``threshold`` or ``edges``.
        res_mm: grid pitch, mm per pixel.
        width_mm: grid width, mm.
        height_mm: grid height, mm.
        width_px: grid width, px.
        height_px: grid height, px.
        ink_pct: share of the grid that is ink after dropping small regions, percent.
        regions: 8-connected ink regions kept (area >= ``min_region_mm2``).
        holes: enclosed background components (4-connected), over all regions.
        dropped_regions: regions dropped for being smaller than ``min_region_mm2``.
        min_region_mm2: the drop limit, mm^2.
        smallest_region_mm2: area of the smallest kept region, mm^2.
        largest_region_mm2: area of the largest kept region, mm^2.
        threshold: the Otsu grey level (``threshold``; ink is one side of it) or the
            gradient-magnitude cut (``edges``).
        inverted: ``threshold`` only: True when the light side was taken as ink
            (art on a dark field).
    """

    method: str
    res_mm: float
    width_mm: float
    height_mm: float
    width_px: int
    height_px: int
    ink_pct: float
    regions: int
    holes: int
    dropped_regions: int
    min_region_mm2: float
    smallest_region_mm2: float
    largest_region_mm2: float
    threshold: float
    inverted: bool

    def as_dict(self) -> JsonDict:
        """Plain JSON-ready dict."""
        return asdict(self)


@dataclass(frozen=True)
class Regions:
    """8-connected ink regions of a mask.

    Attributes:
        labels: (H, W) int32, 0 background, 1..n the regions.
        areas_px: (n,) pixel count of region i+1.
    """

    labels: NDArray[np.int32]
    areas_px: NDArray[np.int64]

    @property
    def count(self) -> int:
        """Number of regions."""
        return int(self.areas_px.size)


def mask_method(method: str | MaskMethod) -> MaskMethod:
    """The :class:`MaskMethod` a config value names.

    Raises:
        MaskMethodError: ``method`` is not one of the allowed values.
    """
    if isinstance(method, MaskMethod):
        return method
    try:
        return MaskMethod(str(method))
    except ValueError:
        raise MaskMethodError(
            f"unknown mask method '{method}': allowed values are {', '.join(ALLOWED_METHODS)}"
            " (mask.method=...)"
        ) from None


def _as_uint8(grey: NDArray[np.generic]) -> NDArray[np.uint8]:
    if grey.dtype == np.uint8:
        return np.ascontiguousarray(grey)
    return np.clip(np.rint(grey), 0, 255).astype(np.uint8)


def otsu_ink(grey: NDArray[np.generic], auto_invert: bool = True
             ) -> tuple[NDArray[np.bool_], float, bool]:
    """Otsu's threshold with the minority polarity rule.

    Args:
        grey: (H, W) grey levels 0..255 (any real dtype; rounded to 8 bits).
        auto_invert: take the light side when the dark side is the majority; False: the
            dark side is always ink.

    Returns:
        ``(ink, t, inverted)``: the ink mask; the Otsu level t (dark is ``grey <= t``);
        whether the light side was taken because the dark side was the majority.
    """
    g8 = _as_uint8(grey)
    t, dark8 = cv2.threshold(g8, 0, 1, cv2.THRESH_BINARY_INV | cv2.THRESH_OTSU)
    dark = dark8.astype(bool)
    if dark.mean() <= 0.5 or not auto_invert:
        return dark, float(t), False
    return ~dark, float(t), True


def edge_ink(
    grey: NDArray[np.generic], sigma_px: float, k: float
) -> tuple[NDArray[np.bool_], float]:
    """Edges of a photograph as ink.

    Args:
        grey: (H, W) grey levels 0..255.
        sigma_px: Gaussian blur sigma, px.
        k: ink where the gradient magnitude exceeds ``mean + k * std``.

    Returns:
        ``(ink, cut)``: the ink mask and the magnitude cut (grey levels per px).
    """
    g: NDArray[Any] = np.asarray(grey, dtype=np.float32)
    if sigma_px > 0:
        g = np.asarray(cv2.GaussianBlur(g, (0, 0), sigmaX=sigma_px, sigmaY=sigma_px,
                                        borderType=cv2.BORDER_REFLECT))
    gx = cv2.Sobel(g, cv2.CV_32F, 1, 0, ksize=3, borderType=cv2.BORDER_REFLECT)
    gy = cv2.Sobel(g, cv2.CV_32F, 0, 1, ksize=3, borderType=cv2.BORDER_REFLECT)
    mag = cv2.magnitude(gx, gy).astype(np.float64)
    cut = max(float(mag.mean() + k * mag.std()), EDGE_MIN_MAGNITUDE)
    return mag > cut, cut


def label_regions(ink: NDArray[np.bool_]) -> Regions:
    """8-connected ink regions (OpenCV connected components)."""
    n, labels, stats, _ = cv2.connectedComponentsWithStats(
        ink.astype(np.uint8), connectivity=8, ltype=cv2.CV_32S
    )
    return Regions(np.asarray(labels, dtype=np.int32),
                   np.asarray(stats[1:n, cv2.CC_STAT_AREA], dtype=np.int64))


def count_holes(ink: NDArray[np.bool_]) -> int:
    """Enclosed background components: 4-connected, not reaching the grid border.

    4-connected background is the consistent pair of 8-connected ink.
    """
    background = np.pad(~ink, 1, constant_values=True).astype(np.uint8)
    n, _ = cv2.connectedComponents(background, connectivity=4)
    # labels: 0 ink, one for the outside (holds the padded corner), the rest are holes
    return max(int(n) - 2, 0)


def _say_dropped(regions: Regions, dropped: NDArray[np.bool_], px_mm2: float,
                 min_region_mm2: float, xs: NDArray[np.float64], ys: NDArray[np.float64],
                 level: int) -> None:
    """One line for the regions the mask leaves out for being small: how many, their area,
    the largest and where it is. A warning for flat art (a logo's dot or short line is
    drawing, not noise); for a photograph's edges, where specks are the rule, information."""
    areas = regions.areas_px[dropped] * px_mm2
    largest = int(np.flatnonzero(dropped)[np.argmax(areas)]) + 1
    rows, cols = np.nonzero(regions.labels == largest)
    log.log(level, "mask: %d ink region(s) smaller than mask.min_region_mm2=%g mm^2 are left "
            "out, %.2f mm^2 in all (the largest %.2f mm^2, at panel (%.1f, %.1f) mm): lower "
            "mask.min_region_mm2 to draw them", int(dropped.sum()), min_region_mm2,
            float(areas.sum()), float(areas.max()), float(xs[cols].mean()),
            float(ys[rows].mean()))


def make_mask(
    grey: NDArray[np.generic],
    res_mm: float,
    method: str | MaskMethod = _DEFAULTS.method,
    min_region_mm2: float = _DEFAULTS.min_region_mm2,
    edge_sigma_px: float = _DEFAULTS.edge_sigma_px,
    edge_k: float = _DEFAULTS.edge_k,
    auto_invert: bool = _DEFAULTS.auto_invert,
    place: Placement | None = None,
) -> tuple[InkMask, MaskStats]:
    """Ink mask of a grey raster on the mask grid.

    Args:
        grey: (H, W) grey levels 0 black .. 255 white; row 0 is the top.
        res_mm: grid pitch, mm per pixel.
        method: ``threshold`` or ``edges`` (see the module docstring).
        min_region_mm2: drop 8-connected regions smaller than this, mm^2.
        edge_sigma_px: ``edges``: Gaussian blur sigma, px.
        edge_k: ``edges``: the cut is ``mean + edge_k * std`` of the gradient magnitude.
        auto_invert: ``threshold``: draw the light side when the dark side covers more
            than half the canvas (logged in one line); False: always the dark side.
        place: where the drawing goes on the panel (:func:`tattotronix.art.place.place_grey`:
            the raster is turned before it is thresholded); None: centred.

    Returns:
        The mask with its panel grid, and its statistics.

    Raises:
        MaskMethodError: an unknown method (the message lists the allowed ones).
        NoInkError: nothing is left to draw.
    """
    kind = mask_method(method)
    grey = np.asarray(grey)
    if grey.ndim != 2 or grey.size == 0:
        raise TattotronixError(f"the artwork raster must be a 2-D grey image, got {grey.shape}")
    if not res_mm > 0:
        raise TattotronixError(f"bad mask.res_mm={res_mm}: it must be positive")
    place = place or Placement()
    grey, xs, ys = place_grey(grey, res_mm, place)
    inverted = False
    if kind is MaskMethod.threshold:
        raw, level, inverted = otsu_ink(grey, auto_invert)
        if inverted:
            log.info("mask: inverted: the dark side covers %.1f %% of the canvas, so the light "
                     "side is drawn as ink (mask.auto_invert=false draws the dark side)",
                     100.0 * (1.0 - raw.mean()))
    else:
        raw, level = edge_ink(grey, edge_sigma_px, edge_k)

    px_mm2 = res_mm * res_mm
    regions = label_regions(raw)
    keep = regions.areas_px * px_mm2 >= min_region_mm2
    h, w = grey.shape
    if not keep.any():
        largest = float(regions.areas_px.max() * px_mm2) if regions.count else 0.0
        if regions.count:
            why = (
                f"all {regions.count} ink regions are smaller than mask.min_region_mm2="
                f"{min_region_mm2:g} mm^2 (largest {largest:.2f} mm^2); draw it larger "
                "(mask.width_mm) or lower mask.min_region_mm2"
            )
        else:
            why = f"the {kind.value} method finds no ink in it"
        raise NoInkError(f"the artwork has no drawable ink: {why}")
    if not keep.all():
        _say_dropped(regions, ~keep, px_mm2, min_region_mm2, xs, ys,
                     logging.WARNING if kind is MaskMethod.threshold else logging.INFO)
    lut = np.concatenate([[False], keep])
    ink = lut[regions.labels]
    kept_px = regions.areas_px[keep]

    mask = InkMask(ink, float(res_mm), xs, ys, place)
    width_mm, height_mm = mask.size_mm
    stats = MaskStats(
        method=kind.value,
        res_mm=float(res_mm),
        width_mm=float(width_mm),
        height_mm=float(height_mm),
        width_px=int(w),
        height_px=int(h),
        ink_pct=float(100.0 * ink.mean()),
        regions=int(keep.sum()),
        holes=count_holes(ink),
        dropped_regions=int((~keep).sum()),
        min_region_mm2=float(min_region_mm2),
        smallest_region_mm2=float(kept_px.min() * px_mm2),
        largest_region_mm2=float(kept_px.max() * px_mm2),
        threshold=float(level),
        inverted=bool(inverted),
    )
    log.info(
        "mask (%s): %.1f x %.1f mm, ink %.2f %%, %d regions (%d dropped), %d holes",
        stats.method, width_mm, height_mm, stats.ink_pct, stats.regions,
        stats.dropped_regions, stats.holes,
    )
    return mask, stats


def mask_on_panel(grey: NDArray[np.generic], res_mm: float, settings: MaskConfig,
                  panel_mm: tuple[float, float], transparent: bool = False
                  ) -> tuple[InkMask, MaskStats]:
    """The ink mask of an artwork raster at the ``mask`` settings, placed on the panel
    (``mask.anchor``, ``mask.at_mm``, ``mask.rotate_deg``), refused when its ink leaves it.

    Args:
        grey: (H, W) grey levels on the artwork's grid.
        res_mm: the grid's pitch, mm.
        settings: the ``mask`` settings.
        panel_mm: the panel's (width, height), mm (``robot.panel.size``).
        transparent: the artwork's canvas is transparent (never auto-inverted).

    Raises:
        TattotronixError: as :func:`make_mask`, and a drawing off the panel.
    """
    shape = np.shape(grey)
    place = (Placement.of((int(shape[0]), int(shape[1])), res_mm, settings.anchor,
                          settings.at_mm, settings.rotate_deg) if len(shape) == 2 else None)
    mask, stats = make_mask(grey, res_mm, settings.method, settings.min_region_mm2,
                            edge_sigma_px=settings.edge_sigma_px, edge_k=settings.edge_k,
                            auto_invert=settings.auto_invert and not transparent, place=place)
    check_on_panel(ink_extent_mm(mask.ink, mask.xs, mask.ys, mask.res_mm), panel_mm,
                   "the drawing")
    return mask, stats
