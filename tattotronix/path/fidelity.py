"""Ink against the artwork: what the needle draws, compared with what was designed.

The ink is rasterised at the needle's width (every run of consecutive points below the
panel surface is a polyline that wide) on a grid finer than the mask (``draw.ink_res_mm``),
in panel millimetres (the mask's frame: ``u`` is the mask's ``xs``, ``v`` its ``ys``). The
artwork is the ink mask, each fine pixel taking the mask pixel it falls in. Reported
(:class:`ArtworkFidelity`):

* **bleed**: the share of the ink outside the artwork, and how far outside it reaches at
  worst (mm);
* **coverage**: the share of the artwork inked (all ink; for a planned path also by the
  outlines' ink and by the fill's ink alone);
* **edge error**: for every pixel on the artwork's edge, the distance to the nearest edge
  of the ink (mm): mean and worst. An outline run on the artwork's edge puts half the
  needle's width outside it, so its edge error is about half the needle width.
* **line width** (line art drawn along its centreline): per line, the median of the
  drawn width (twice the distance from the centreline to the ink's edge) against the
  median designed width (the artwork's, read the same way when the line was planned):
  their means over the lines, and the worst difference.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import overload

import cv2
import numpy as np
from numpy.typing import NDArray

from tattotronix.art.grid import InkMask
from tattotronix.io.jsontypes import JsonDict
from tattotronix.path.inset import pixel_width

__all__ = ["MISSED_MIN_NEEDLES2", "ArtworkFidelity", "InkGrid", "LineWidth", "MissedPart",
           "PlannedInk", "artwork_fidelity", "missed_message", "missed_reach_mm",
           "artwork_on", "below_runs", "distance_at", "distance_to", "fidelity_image",
           "grid_over", "line_runs", "line_width", "planned_ink", "rasterise_runs",
           "save_png"]

Array = NDArray[np.float64]
Mask = NDArray[np.bool_]
_SHIFT = 4  # cv2 fixed-point bits: 1/16 px
_CROSS = cv2.getStructuringElement(cv2.MORPH_CROSS, (3, 3))


#: pixel coordinates: indices (``np.nonzero``'s) or fractional
_Coords = NDArray[np.intp] | NDArray[np.float64]


@dataclass(frozen=True)
class InkGrid:
    """A raster over the panel plane.

    Attributes:
        u0_mm, v0_mm: panel coordinates of pixel (0, 0)'s centre, mm (row 0 is the top,
            highest ``v``).
        res_mm: pixel size, mm.
        shape: (rows, cols).
    """

    u0_mm: float
    v0_mm: float
    res_mm: float
    shape: tuple[int, int]

    def to_px(self, uv_mm: Array) -> Array:
        """(N, 2) panel mm -> (N, 2) pixel (col, row) coordinates (float)."""
        col = (uv_mm[:, 0] - self.u0_mm) / self.res_mm
        row = (self.v0_mm - uv_mm[:, 1]) / self.res_mm
        return np.stack([col, row], axis=1)

    @overload
    def to_mm(self, col: float, row: float) -> tuple[float, float]: ...
    @overload
    def to_mm(self, col: _Coords, row: _Coords) -> tuple[Array, Array]: ...

    def to_mm(self, col: float | _Coords, row: float | _Coords
              ) -> tuple[float | Array, float | Array]:
        """Pixel coordinates (fractional; numbers, or arrays of any lengths) -> panel mm:
        ``col`` to ``u``, ``row`` to ``v``, the inverse of :meth:`to_px`."""
        u = self.u0_mm + col * self.res_mm
        v = self.v0_mm - row * self.res_mm
        return (float(u), float(v)) if np.ndim(u) == 0 and np.ndim(v) == 0 else \
            (np.asarray(u, dtype=np.float64), np.asarray(v, dtype=np.float64))


def grid_over(points_mm: Sequence[Array], res_mm: float, margin_mm: float = 1.0) -> InkGrid:
    """A grid of ``res_mm`` pixels covering every (N, 2) point set (plus a margin)."""
    allp = np.concatenate([p[:, :2] for p in points_mm if len(p)] or [np.zeros((1, 2))])
    lo = allp.min(axis=0) - margin_mm
    hi = allp.max(axis=0) + margin_mm
    cols = int(np.ceil((hi[0] - lo[0]) / res_mm)) + 1
    rows = int(np.ceil((hi[1] - lo[1]) / res_mm)) + 1
    return InkGrid(u0_mm=float(lo[0]), v0_mm=float(hi[1]), res_mm=float(res_mm),
                   shape=(rows, cols))


def _run_bounds(uvz_mm: Array, split: NDArray[np.integer] | None
                ) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """(starts, stops) of the runs of consecutive points below the surface (z < 0); a
    change of ``split`` (a stroke id per point) also ends a run."""
    below = uvz_mm[:, 2] < 0.0
    joined = below[1:] & below[:-1]  # point i and i + 1 belong to one run
    if split is not None:
        joined &= split[1:] == split[:-1]
    first, last = below.copy(), below.copy()
    first[1:] &= ~joined
    last[:-1] &= ~joined
    return np.flatnonzero(first), np.flatnonzero(last) + 1


def below_runs(uvz_mm: Array, split: NDArray[np.integer] | None = None) -> list[Array]:
    """The runs of consecutive points below the surface (z < 0), as (m, 2) panel mm; a
    change of ``split`` (a stroke id per point) also ends a run."""
    starts, stops = _run_bounds(uvz_mm, split)
    return [uvz_mm[a:b, :2] for a, b in zip(starts, stops, strict=True)]


def rasterise_runs(runs: Sequence[Array], grid: InkGrid, needle_mm: float) -> Mask:
    """Ink of polylines (panel mm) at the needle's width: True where inked."""
    img = np.zeros(grid.shape, dtype=np.uint8)
    if not runs:
        return img.astype(bool)
    # cv2 inks the pixel centres within thickness/2 of the line, both edges included, so
    # a band of thickness t covers about t + 1 pixels: t = width/res - 1 (within a pixel)
    thick = max(1, int(round(needle_mm / grid.res_mm)) - 1)
    px = [np.rint(grid.to_px(r) * (1 << _SHIFT)).astype(np.int32) for r in runs]
    cv2.polylines(img, [p.reshape(-1, 1, 2) for p in px if len(p) > 1], isClosed=False,
                  color=1, thickness=thick, lineType=cv2.LINE_8, shift=_SHIFT)
    radius = max(1, int(round(needle_mm / grid.res_mm / 2 - 0.5)))
    for p in px:
        if len(p) == 1:  # a single point: a dot
            cv2.circle(img, (int(p[0, 0]), int(p[0, 1])), radius << _SHIFT, 1, -1,
                       cv2.LINE_8, _SHIFT)
    return img.astype(bool)


def artwork_on(mask: InkMask, grid: InkGrid) -> Mask:
    """The artwork on ``grid``: each pixel takes the mask pixel its centre falls in."""
    rows, cols = grid.shape
    u, v = grid.to_mm(np.arange(cols), np.arange(rows))
    mc = np.floor((u - mask.xs[0]) / mask.res_mm + 0.5).astype(np.int64)
    mr = np.floor((mask.ys[0] - v) / mask.res_mm + 0.5).astype(np.int64)
    h, w = mask.ink.shape
    okc, okr = (mc >= 0) & (mc < w), (mr >= 0) & (mr < h)
    out = np.zeros(grid.shape, dtype=bool)
    # rows, then columns: two gathers of whole lines (a 2-D fancy index is slower), into
    # the block of the grid the mask covers (the indices grow with u and fall with v)
    r, c = np.flatnonzero(okr), np.flatnonzero(okc)
    if r.size and c.size:
        out[r[0]:r[-1] + 1, c[0]:c[-1] + 1] = np.take(np.take(mask.ink, mr[r], axis=0),
                                                      mc[c], axis=1)
    return out


def _edge(img: Mask) -> Mask:
    """The pixels of ``img`` with a 4-neighbour outside it."""
    inner = cv2.erode(img.astype(np.uint8), _CROSS, borderValue=0)
    return img & ~inner.astype(bool)


def distance_to(img: Mask) -> NDArray[np.float32]:
    """Distance of every pixel to the nearest pixel of ``img`` (px; inf if none)."""
    if not img.any():
        return np.full(img.shape, np.inf, dtype=np.float32)
    dist = cv2.distanceTransform((~img).astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
    return np.asarray(dist, dtype=np.float32)


#: :func:`distance_at` searches a tree of the target's edge when the pixels asked about
#: are at most this share of the grid; more, and one distance transform is quicker
_TREE_SHARE = 1 / 16


def distance_at(img: Mask, where: Mask) -> NDArray[np.float32]:
    """``distance_to(img)[where]``: the distance of each pixel of ``where`` to the nearest
    pixel of ``img`` (px; inf if ``img`` is empty), without a distance transform of the
    whole grid when ``where`` is a small part of it.

    The nearest pixel of ``img`` to a pixel outside it has a 4-neighbour outside ``img``
    (a step from it towards the pixel, along its larger offset, comes strictly closer), so
    a k-d tree of ``img``'s edge (:func:`_edge`) gives the exact Euclidean distance, as
    the precise transform does.
    """
    n = int(where.sum())
    if n == 0:
        return np.zeros(0, dtype=np.float32)
    if not img.any():
        return np.full(n, np.inf, dtype=np.float32)
    if n > _TREE_SHARE * where.size:
        return distance_to(img)[where]
    from scipy.spatial import cKDTree

    rows, cols = np.nonzero(where)
    out = np.zeros(n, dtype=np.float64)
    away = ~img[rows, cols]
    if away.any():
        er, ec = np.nonzero(_edge(img))
        tree = cKDTree(np.column_stack([er, ec]).astype(np.float64))
        out[away], _ = tree.query(np.column_stack([rows[away], cols[away]]).astype(np.float64))
    return out.astype(np.float32)


@dataclass(frozen=True)
class LineWidth:
    """Drawn against designed width of the lines drawn along their centreline (mm).

    Attributes:
        lines: how many lines. designed_mean_mm, drawn_mean_mm: the means over the lines
        of each line's median width. worst_diff_mm: the largest difference of the two
        medians of one line.
    """

    lines: int
    designed_mean_mm: float
    drawn_mean_mm: float
    worst_diff_mm: float

    def metrics(self) -> JsonDict:
        """JSON-ready."""
        return asdict(self)


def line_width(ink: Mask, grid: InkGrid, lines: Sequence[Array], designed_mm: Sequence[float]
               ) -> LineWidth | None:
    """The drawn width of each line (panel mm points along its centreline) against its
    designed width; None when there is no line."""
    if not lines:
        return None
    inside = np.asarray(cv2.distanceTransform(ink.astype(np.uint8), cv2.DIST_L2,
                                              cv2.DIST_MASK_PRECISE), dtype=np.float64)
    rows, cols = grid.shape
    drawn = []
    for pts in lines:
        px = np.rint(grid.to_px(pts)).astype(np.int64)
        ok = (px[:, 0] >= 0) & (px[:, 0] < cols) & (px[:, 1] >= 0) & (px[:, 1] < rows)
        d = inside[px[ok, 1], px[ok, 0]]
        drawn.append(float(np.median(pixel_width(d, grid.res_mm))) if len(d) else 0.0)
    want = np.asarray(designed_mm, dtype=np.float64)
    got = np.asarray(drawn)
    return LineWidth(len(lines), float(want.mean()), float(got.mean()),
                     float(np.abs(got - want).max()))


@dataclass(frozen=True)
class ArtworkFidelity:
    """Ink against the artwork (see the module docstring; lengths in mm, shares 0..1).

    Attributes:
        bleed_share: inked pixels outside the artwork over inked pixels.
        bleed_max_mm: the farthest inked pixel from the artwork.
        coverage: artwork pixels inked over artwork pixels.
        coverage_outlines, coverage_fill: the same for the outlines' and the fill's ink
            alone (None where the ink is not split by stroke kind).
        edge_mean_mm, edge_max_mm: distance from the artwork's edge to the ink's edge.
        res_mm: the grid's pixel.
        line_width: the lines' drawn against designed width (None: no line art).
    """

    bleed_share: float
    bleed_max_mm: float
    coverage: float
    coverage_outlines: float | None
    coverage_fill: float | None
    edge_mean_mm: float
    edge_max_mm: float
    res_mm: float
    line_width: LineWidth | None = None

    def metrics(self) -> JsonDict:
        """JSON-ready (the ``artwork`` section of a metrics file)."""
        return {"bleed_share": self.bleed_share, "bleed_max_mm": self.bleed_max_mm,
                "coverage": self.coverage, "coverage_outlines": self.coverage_outlines,
                "coverage_fill": self.coverage_fill, "edge_mean_mm": self.edge_mean_mm,
                "edge_max_mm": self.edge_max_mm, "res_mm": self.res_mm,
                "line_width": None if self.line_width is None else self.line_width.metrics()}


def artwork_fidelity(art: Mask, ink: Mask, res_mm: float, outlines: Mask | None = None,
                     fill: Mask | None = None, lines: LineWidth | None = None
                     ) -> ArtworkFidelity:
    """Compare ink with the artwork on one grid (``res_mm`` pixels).

    Args:
        art: the artwork on the grid (:func:`artwork_on`).
        ink: all the ink.
        res_mm: the pixel, mm.
        outlines, fill: the outlines' and the fill's ink alone, if known.
        lines: the line art's width (:func:`line_width`), if any.
    """
    n_ink, n_art = int(ink.sum()), int(art.sum())
    outside = ink & ~art
    bleed_max = float(distance_at(art, outside).max()) * res_mm if outside.any() else 0.0
    art_edge = _edge(art)
    to_ink_edge = distance_at(_edge(ink), art_edge)

    def cover(m: Mask) -> float:
        return float((m & art).sum()) / n_art if n_art else 0.0

    return ArtworkFidelity(
        bleed_share=float(outside.sum()) / n_ink if n_ink else 0.0,
        bleed_max_mm=bleed_max,
        coverage=cover(ink),
        coverage_outlines=None if outlines is None else cover(outlines),
        coverage_fill=None if fill is None else cover(fill),
        edge_mean_mm=float(to_ink_edge.mean()) * res_mm if len(to_ink_edge) else 0.0,
        edge_max_mm=float(to_ink_edge.max()) * res_mm if len(to_ink_edge) else 0.0,
        res_mm=float(res_mm),
        line_width=lines,
    )


@dataclass(frozen=True)
class MissedPart:
    """A part of the artwork no ink comes near (see :meth:`PlannedInk.missed`).

    Attributes:
        at_mm: its centre (u, v), panel mm. size_mm: its box (width, height), mm.
        area_mm2: its area beyond the reach, mm^2.
    """

    at_mm: tuple[float, float]
    size_mm: tuple[float, float]
    area_mm2: float

    def metrics(self) -> JsonDict:
        """JSON-ready."""
        return {"at_mm": [round(v, 2) for v in self.at_mm],
                "size_mm": [round(v, 2) for v in self.size_mm],
                "area_mm2": round(self.area_mm2, 3)}

    def describe(self) -> str:
        """One phrase that names it: where, and how big."""
        return (f"{self.size_mm[0]:.1f} x {self.size_mm[1]:.1f} mm at "
                f"({self.at_mm[0]:.1f}, {self.at_mm[1]:.1f}) mm")


def missed_reach_mm(pitch_mm: float, needle_mm: float, mask_res_mm: float) -> float:
    """How far from any ink a drawn part of the artwork can lie: half the fill's pitch
    (between two hatch runs) or a needle's width (a sharp corner the needle's round end
    cannot fill), whichever is more, and two mask pixels (the mask's steps)."""
    return max(pitch_mm / 2, needle_mm) + 2 * mask_res_mm


#: the smallest part reported missed, in needle widths squared
MISSED_MIN_NEEDLES2 = 4.0


def missed_message(name: str, parts: Sequence[MissedPart], reach_mm: float,
                   figure: str) -> str:
    """One line naming the parts of ``name``'s artwork its plan leaves without ink."""
    shown = "; ".join(p.describe() for p in parts[:3])
    more = f"; and {len(parts) - 3} more" if len(parts) > 3 else ""
    return (f"{name}: {len(parts)} part(s) of the artwork get no ink within "
            f"{reach_mm:.2f} mm, so the drawing leaves them out: {shown}{more} (see "
            f"{figure}; a part narrower than the needle, or smaller than "
            "mask.min_region_mm2, is not drawn: draw the artwork larger, or use a finer "
            "mask.res_mm or a narrower toolpath.needle_width_mm)")


@dataclass(frozen=True)
class PlannedInk:
    """A planned path's ink against its artwork.

    Attributes:
        art: the artwork on the grid. ink: the ink. fidelity: the comparison.
        grid: the grid both lie on.
    """

    art: Mask
    ink: Mask
    fidelity: ArtworkFidelity
    grid: InkGrid

    def missed_by(self, pitch_mm: float, needle_mm: float, mask_res_mm: float,
                  bands: bool = False) -> tuple[list[MissedPart], float]:
        """:meth:`missed` at :func:`missed_reach_mm` of a plan's pitch, needle and mask
        pixel (``bands``: ``toolpath.lines_only``), and that reach, mm."""
        reach = missed_reach_mm(pitch_mm, needle_mm, mask_res_mm)
        return self.missed(reach, needle_mm, bands=bands), reach

    def missed(self, reach_mm: float, needle_mm: float, bands: bool = False
               ) -> list[MissedPart]:
        """The parts of the artwork farther than ``reach_mm`` from any ink (8-connected,
        each at least :data:`MISSED_MIN_NEEDLES2` needle widths squared), largest first:
        a line the plan lost, a region it dropped. The fill's gaps and the needle's round
        corners lie within :func:`missed_reach_mm` of the ink, and are not missed.

        ``bands``: every part is drawn as one line along its middle, however wide (the
        edges of a photograph): the reach grows by the widest band's half-width near
        each pixel, less half the needle."""
        reach = np.float32(reach_mm / self.grid.res_mm)
        if bands:
            inside = np.asarray(cv2.distanceTransform(self.art.astype(np.uint8),
                                                      cv2.DIST_L2, 3), dtype=np.float32)
            half = int(np.ceil(inside.max()))
            if half > 0:
                near = cv2.dilate(inside, np.ones((2 * half + 1, 2 * half + 1), np.uint8))
                needle_px = np.float32(needle_mm / 2 / self.grid.res_mm)
                reach = reach + np.maximum(near - needle_px, 0)
        far = self.art & (distance_to(self.ink) > reach)
        if not far.any():
            return []
        n, _, stats, _ = cv2.connectedComponentsWithStats(far.astype(np.uint8), connectivity=8)
        res = self.grid.res_mm
        parts = []
        for k in range(1, n):
            x, y, w, h, area = (int(v) for v in stats[k, :5])
            if area * res * res < MISSED_MIN_NEEDLES2 * needle_mm ** 2:
                continue
            at = self.grid.to_mm(x + (w - 1) / 2, y + (h - 1) / 2)
            parts.append(MissedPart(at, (w * res, h * res), area * res * res))
        return sorted(parts, key=lambda p: -p.area_mm2)


def planned_ink(mask: InkMask, uvz_mm: Array, stroke: NDArray[np.integer],
                stroke_fill: NDArray[np.bool_], needle_mm: float, res_mm: float,
                stroke_width_mm: NDArray[np.float64] | None = None) -> PlannedInk:
    """The ink a planned path draws, against the artwork (the mask), on a ``res_mm`` grid
    over the mask.

    Args:
        mask: the ink mask the path was planned from.
        uvz_mm: (N, 3) the path, panel mm (the mask's frame).
        stroke: (N,) position in the drawing order of each point's stroke.
        stroke_fill: (strokes,) whether each drawn stroke (in drawing order) is fill.
        needle_mm: the needle's line width.
        res_mm: the grid's pixel (finer than the mask's).
        stroke_width_mm: (strokes,) the designed width of each drawn stroke that is a
            line along a centreline (NaN for the others), for the line width.
    """
    corners = np.array([[mask.xs[0], mask.ys[0]], [mask.xs[-1], mask.ys[-1]]])
    grid = grid_over([corners, uvz_mm[uvz_mm[:, 2] < 0.0]], res_mm)
    starts, stops = _run_bounds(uvz_mm, stroke)
    runs = [uvz_mm[a:b, :2] for a, b in zip(starts, stops, strict=True)]
    fill_run = np.asarray(stroke_fill, dtype=bool)[stroke[starts]]
    outlines = rasterise_runs([r for r, f in zip(runs, fill_run, strict=True) if not f], grid,
                              needle_mm)
    fill = rasterise_runs([r for r, f in zip(runs, fill_run, strict=True) if f], grid,
                          needle_mm)
    ink = outlines | fill
    art = artwork_on(mask, grid)
    lines = None
    if stroke_width_mm is not None:
        lines = line_width(ink, grid, *line_runs(uvz_mm, stroke, stroke_width_mm))
    return PlannedInk(art, ink, artwork_fidelity(art, ink, res_mm, outlines, fill, lines), grid)


def line_runs(uvz_mm: Array, stroke: NDArray[np.integer], stroke_width_mm: NDArray[np.float64]
              ) -> tuple[list[Array], list[float]]:
    """The marking runs of the strokes that are lines (a designed width, not NaN) and
    their designed widths."""
    starts, stops = _run_bounds(uvz_mm, stroke)
    width = np.asarray(stroke_width_mm, dtype=np.float64)[stroke[starts]]
    keep = np.flatnonzero(np.isfinite(width))
    return ([uvz_mm[starts[i]:stops[i], :2] for i in keep], [float(width[i]) for i in keep])


def fidelity_image(art: Mask, ink: Mask) -> NDArray[np.uint8]:
    """(H, W, 3) RGB overlay: ink on the artwork dark grey, the artwork left uninked light
    grey, the bleed (ink outside the artwork) red, the rest white."""
    rgb = np.full(art.shape + (3,), 255, dtype=np.uint8)
    rgb[art & ~ink] = (200, 200, 200)
    rgb[art & ink] = (40, 40, 40)
    rgb[ink & ~art] = (230, 30, 30)
    return rgb


def save_png(rgb: NDArray[np.uint8], res_mm: float, path: Path) -> None:
    """Write an image of ``res_mm`` pixels as a PNG that states its scale (dpi)."""
    from PIL import Image

    dpi = 25.4 / res_mm
    Image.fromarray(rgb).save(path, format="PNG", dpi=(dpi, dpi))
