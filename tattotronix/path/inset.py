"""Needle-width compensation and line art, on a grid finer than the mask.

The needle inks a band ``needle_width_mm`` wide around its path. To keep the ink's edge on
the artwork's edge, the path runs half a needle width inside it; parts of the artwork too
narrow for that are drawn as one pass along their centreline (docs/toolpath.md, "Needle
width"). All of it is read off distance fields on a grid ``refine`` times finer than the
mask (about a sixth of the needle width per pixel; the artwork on it is the mask, each
fine pixel taking the mask pixel it falls in, as :mod:`tattotronix.path.fidelity` reads
it):

* ``d``: every artwork pixel's distance to the artwork's edge (OpenCV's exact Euclidean
  distance transform, less half a pixel: the edge lies between pixel centres).
* the widths are read on the artwork blurred by half a mask pixel and cut at half (its
  edges run through the middle of the mask's pixel steps, so a diagonal line is as wide
  all along): ``s`` is the distance to that smoothed edge.
* **core**: where ``s >= line_max / 2``: the centres of discs as wide as the line
  threshold that fit in the artwork.
* **thick part** (the morphological opening): within ``line_max / 2`` of the core. The
  rest of the artwork, narrower than ``line_max`` everywhere, is **line art**.
* **inset**: within ``line_max / 2 - needle / 2`` of the core, and ``s >= needle / 2``,
  each less a fine pixel of margin (the smoothed edge cuts the mask's pixel steps): a
  disc of the needle's width centred anywhere in it stays inside the artwork. Its
  boundary loops, smoothed and simplified, are the outlines, and the fill (hatch,
  cross-hatch, concentric or solid) runs inside it.
* **fill area**: the inset less a needle's width from its edge (:data:`FILL_INSET_NEEDLES`):
  the hatch runs there, so its ink meets the outlines' ink and a run stops a needle
  inside the outline. Two run ends on consecutive scanlines are then joined by a straight
  drag through the ink with a needle's width of room for the outline's bends and the
  mask's pixel steps; a run ending on the inset outline itself left one fine pixel of
  room, so most such joins left ``safe`` and became needle entries (issue 30: 48 -> 80 on
  the emblem). An inset narrower than two needles gets no hatch: its outlines' ink
  covers it all but a strip up to a needle wide along its middle.
* **line pieces of the inset**: an inset part too small to outline (a speck of a line
  about ``line_max`` wide), and one with no fill that is a line's corner or join (at most
  :data:`JOIN_MAX_LINE_MAX` ``line_max`` across, or a sliver) joined to line art, are
  taken out of the core: their part is line art, so the line is drawn all along, in one
  stroke through its corners.
* **safe**: where ``d >= needle / 2``: the needle may drag across a gap only along a
  line inside it.
* **centrelines**: each piece of line art at least ``line_max`` long is skeletonised
  (scikit-image's ``skeletonize`` on the smoothed artwork around it, so the centreline
  runs on through junctions) and the skeleton inside the piece drawn in the fewest
  strokes (:mod:`tattotronix.path.centreline`); vector lines (``artwork.vector``) take
  the place of the skeleton where they lie.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from tattotronix.art.grid import InkMask
from tattotronix.art.vector import VectorLines
from tattotronix.errors import TattotronixError
from tattotronix.path.centreline import skeleton_strokes
from tattotronix.path.polyline import resample

__all__ = ["FILL_INSET_NEEDLES", "MAX_FINE_PIXELS", "Compensated", "FineGrid", "compensate",
           "concentric_rings", "pixel_width", "refine_factor"]

#: the finest grid worked on: a fine pixel is at most a sixth of the needle width
FINE_PER_NEEDLE = 6
#: the inset's extra margin (fine px) and its loops' smoothing passes and simplification
#: tolerance (fine px): set so the smoothed loops keep the ink inside the mask's pixel
#: steps (tests/test_inset.py) with no tight corner the time law must slow for
INSET_MARGIN_PX = 1.0
LOOP_SMOOTH_PASSES = 12
LOOP_TOLERANCE_PX = 0.25
#: the largest thick part taken as a line's corner or join (drawn along the line's
#: centreline), in ``toolpath.line_max_mm`` each way
JOIN_MAX_LINE_MAX = 2.0
#: how far inside the inset's edge the hatch runs, in needle widths: one, so its ink meets
#: the outlines' ink edge to edge and the drags joining its runs have a needle's width of
#: room (measured: 0 gave the emblem 80 needle entries against 48 without compensation,
#: 0.5 gave 64, 1 gives 44; tests/test_compensation.py)
FILL_INSET_NEEDLES = 1.0
#: most fine pixels (~13 bytes each in distance fields and labels)
MAX_FINE_PIXELS = 80_000_000

Loop = NDArray[np.float64]


@dataclass(frozen=True)
class FineGrid:
    """The fine grid: pixel ``(row, col)`` has its centre at ``(xs[col], ys[row])`` mm.

    Attributes:
        xs: (W,) column x, mm (increasing). ys: (H,) row y, mm (decreasing).
        res_mm: the pixel, mm. factor: fine pixels per mask pixel (each way).
    """

    xs: NDArray[np.float64]
    ys: NDArray[np.float64]
    res_mm: float
    factor: int

    def to_mm(self, px: NDArray[np.integer] | NDArray[np.floating]) -> Loop:
        """(n, 2) (row, col) pixel coordinates -> (n, 2) (x, y) mm."""
        p = np.asarray(px, dtype=np.float64)
        return np.column_stack([self.xs[0] + p[:, 1] * self.res_mm,
                                self.ys[0] - p[:, 0] * self.res_mm])


@dataclass(frozen=True)
class Compensated:
    """The artwork split for a needle of finite width, on the fine grid.

    Attributes:
        grid: the fine grid.
        inset: (H, W) int32 region label of every fine pixel of the inset (0 elsewhere).
        fill: (H, W) int32 the same for the fill area: the inset's pixels at least
            :data:`FILL_INSET_NEEDLES` needle widths from its edge (where the hatch runs).
        loops: per region label, its inset's boundary loops: (outer loops, hole loops),
            each (n, 2) mm, closed (first vertex repeated).
        lines: per region label, its centreline strokes, each (n, 2) mm (a closed one
            repeats its first vertex).
        line_width_mm: per region label, per centreline stroke, the artwork's width along
            it (twice the distance to the edge; (n,) mm).
        safe: where a needle dot fits inside the artwork (the artwork eroded by half the
            needle width), on the fine grid: the needle may drag across a gap only along
            a line inside it.
    """

    grid: FineGrid
    safe: InkMask
    inset: NDArray[np.int32]
    fill: NDArray[np.int32]
    loops: dict[int, tuple[list[Loop], list[Loop]]]
    lines: dict[int, list[Loop]]
    line_width_mm: dict[int, list[NDArray[np.float64]]]


def refine_factor(res_mm: float, needle_mm: float) -> int:
    """Fine pixels per mask pixel: at most ``needle / FINE_PER_NEEDLE`` each (>= 1)."""
    return max(1, math.ceil(res_mm / (needle_mm / FINE_PER_NEEDLE) - 1e-9))


def _refine(labels: NDArray[np.int32], mask: InkMask, factor: int
            ) -> tuple[NDArray[np.int32], FineGrid]:
    """The label image on the fine grid (each fine pixel takes its mask pixel's label),
    padded by one mask pixel of background so the artwork's edge is never the grid's."""
    h, w = labels.shape
    cells = (h + 2) * (w + 2) * factor * factor
    if cells > MAX_FINE_PIXELS:
        raise TattotronixError(
            f"needle-width compensation works on a grid {factor}x finer than the mask: "
            f"{cells:.3g} pixels, over its budget of {MAX_FINE_PIXELS:.3g}; raise "
            "mask.res_mm or toolpath.needle_width_mm, or set toolpath.compensate=false")
    fine = np.repeat(np.repeat(np.pad(labels, 1), factor, axis=0), factor, axis=1)
    res = mask.res_mm / factor
    x0 = mask.xs[0] - mask.res_mm - mask.res_mm / 2 + res / 2
    y0 = mask.ys[0] + mask.res_mm + mask.res_mm / 2 - res / 2
    grid = FineGrid(x0 + np.arange(fine.shape[1]) * res, y0 - np.arange(fine.shape[0]) * res,
                    res, factor)
    return fine.astype(np.int32), grid


def _distance(inside: NDArray[np.bool_]) -> NDArray[np.float32]:
    """Each pixel's distance to the nearest pixel outside ``inside`` (px; 0 outside)."""
    return np.asarray(cv2.distanceTransform(inside.astype(np.uint8), cv2.DIST_L2,
                                            cv2.DIST_MASK_PRECISE), dtype=np.float32)


def _smoothed(art: NDArray[np.bool_], factor: int) -> NDArray[np.bool_]:
    """The artwork blurred by half a mask pixel (Gaussian) and cut at half: its edges
    run through the middle of the mask's pixel steps."""
    if factor <= 1:
        return art
    sigma = factor / 2
    blur = cv2.GaussianBlur(art.astype(np.float32), (0, 0), sigmaX=sigma, sigmaY=sigma)
    return np.asarray(blur > 0.5)


def _loops(region: NDArray[np.bool_], grid: FineGrid, offset: tuple[int, int],
           min_px: int) -> tuple[list[Loop], list[Loop]]:
    """Outer and hole boundary loops of a (cropped) binary image, closed, in mm; loops of
    fewer than ``min_px`` pixels are dropped."""
    contours, hierarchy = cv2.findContours(region.astype(np.uint8), cv2.RETR_CCOMP,
                                           cv2.CHAIN_APPROX_NONE)
    outers: list[Loop] = []
    holes: list[Loop] = []
    if not contours:
        return outers, holes
    for c, parent in zip(contours, hierarchy[0, :, 3], strict=True):
        if len(c) < min_px:
            continue
        rc = (c[:, 0, ::-1] + np.array(offset)).astype(np.float64)
        if len(rc) >= 5:  # circular [1, 2, 1] / 4 passes: the pixel steps out
            for _ in range(LOOP_SMOOTH_PASSES):
                rc = 0.25 * np.roll(rc, 1, axis=0) + 0.5 * rc + 0.25 * np.roll(rc, -1, axis=0)
        simple = cv2.approxPolyDP(rc[:, ::-1].astype(np.float32).reshape(-1, 1, 2),
                                  LOOP_TOLERANCE_PX, True)
        pts = simple[:, 0, ::-1].astype(np.float64) if len(simple) >= 3 else rc
        mm = grid.to_mm(np.vstack([pts, pts[:1]]))
        (outers if parent < 0 else holes).append(mm)
    return outers, holes


def _specks(binary: NDArray[np.bool_], min_px: int) -> NDArray[np.bool_]:
    """The 8-connected components of ``binary`` whose outer boundary has fewer than
    ``min_px`` pixels (:func:`_loops` drops their loops)."""
    contours, _ = cv2.findContours(binary.astype(np.uint8), cv2.RETR_EXTERNAL,
                                   cv2.CHAIN_APPROX_NONE)
    small = [c for c in contours if len(c) < min_px]
    out = np.zeros(binary.shape, np.uint8)
    if small:
        cv2.drawContours(out, small, -1, color=1, thickness=cv2.FILLED)
    return out.astype(bool) & binary


def _line_joins(inset: NDArray[np.bool_], thin: NDArray[np.bool_], fill_px: float,
                half_px: float, r_px: float, max_px: float) -> NDArray[np.bool_]:
    """The components of ``inset`` that belong to a line: with no fill (no pixel
    ``fill_px`` from their edge), either small (no wider than ``max_px`` either way: a
    corner or join, wider than the line's legs) or a sliver (no pixel ``r_px`` from their
    edge: a stretch of a line about ``line_max`` wide, which comes out of the mask a hair
    over the threshold here and under it there), and joined to line art (``thin``, a piece
    at least ``2 half_px`` each way) through other such parts within ``half_px`` of it."""
    none = np.zeros(inset.shape, dtype=bool)
    n, comp, stats, _ = cv2.connectedComponentsWithStats(inset.astype(np.uint8),
                                                          connectivity=8)
    if n <= 1:
        return none
    inside = _distance(inset) - 0.5
    candidate = np.ones(n, dtype=bool)
    candidate[0] = False
    candidate[np.unique(comp[inside >= fill_px])] = False
    small = (stats[:, cv2.CC_STAT_WIDTH] <= max_px) & (stats[:, cv2.CC_STAT_HEIGHT] <= max_px)
    sliver = np.ones(n, dtype=bool)
    sliver[np.unique(comp[inside >= r_px])] = False
    candidate &= small | sliver
    if not candidate.any():
        return none
    m, lines, lstats, _ = cv2.connectedComponentsWithStats(thin.astype(np.uint8),
                                                            connectivity=8)
    long_lines = lstats[:, cv2.CC_STAT_AREA] >= (2 * half_px) ** 2
    long_lines[0] = False
    if not long_lines.any():
        return none
    # the candidates and the line art, each grown by the thick part's reach: the parts
    # of one line touch
    r = int(math.ceil(half_px)) + 1
    disc = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1))
    grown = cv2.dilate(candidate[comp].astype(np.uint8), disc).astype(bool)
    k, joined = cv2.connectedComponents((grown | thin).astype(np.uint8), connectivity=8)
    on_line = np.zeros(k, dtype=bool)
    on_line[np.unique(joined[long_lines[lines]])] = True
    on_line[0] = False
    hit = np.zeros(n, dtype=bool)
    hit[np.unique(comp[on_line[joined] & inset])] = True
    return (candidate & hit)[comp]


def _region_of(labels: NDArray[np.int32], where: NDArray[np.bool_]) -> int:
    """The region label most of ``where`` lies on (0: none)."""
    counts = np.bincount(labels[where], minlength=1)
    counts[0] = 0
    return int(counts.argmax())


def _component_loops(binary: NDArray[np.bool_], labels: NDArray[np.int32], grid: FineGrid,
                     min_px: int) -> dict[int, tuple[list[Loop], list[Loop]]]:
    """Per region label, the outer and hole loops of every 8-connected component of
    ``binary`` (each in the region it lies on most)."""
    loops: dict[int, tuple[list[Loop], list[Loop]]] = {}
    n, comp, stats, _ = cv2.connectedComponentsWithStats(binary.astype(np.uint8),
                                                          connectivity=8)
    for k in range(1, n):
        x, y, w, h = stats[k, :4]
        crop = comp[y:y + h, x:x + w] == k
        lab = _region_of(labels[y:y + h, x:x + w], crop)
        if lab == 0:
            continue
        outers, holes = _loops(crop, grid, (int(y), int(x)), min_px)
        have = loops.setdefault(lab, ([], []))
        have[0].extend(outers)
        have[1].extend(holes)
    return loops


def compensate(labels: NDArray[np.int32], mask: InkMask, needle_mm: float, line_max_mm: float,
               min_loop_px: int, vector: VectorLines | None = None, *,
               lines_only: bool = False) -> Compensated:
    """Split every labelled region into its inset (outlines and fill) and its line art.

    Args:
        labels: (H, W) region labels on the mask grid (0 background).
        mask: the mask (its grid).
        needle_mm: the needle's line width, mm (> 0).
        line_max_mm: parts narrower than this are drawn along their centreline; 0: none
            (a part too narrow to inset is then not drawn).
        min_loop_px: loops shorter than this many mask pixels are dropped.
        vector: lines taken from the artwork's geometry (``artwork.vector``): those
            narrower than ``line_max_mm`` are drawn as they are, and the line art under
            them is not skeletonised.
        lines_only: every part is line art, however wide (the edges of a photograph,
            ``mask.method=edges``): no inset, no fill, one centreline per band.

    Returns:
        The inset, its loops and the centrelines (see :class:`Compensated`).
    """
    factor = refine_factor(mask.res_mm, needle_mm)
    fine, grid = _refine(labels, mask, factor)
    art = fine > 0
    depth = _distance(art) - 0.5  # px from the artwork's edge
    # widths are read on the artwork without the mask's pixel steps (a diagonal 0.8 mm
    # line is 0.6 to 0.75 mm wide across its steps): blurred by half a mask pixel
    smooth = _smoothed(art, factor)
    sdepth = _distance(smooth) - 0.5
    r_px = needle_mm / 2 / grid.res_mm
    half_px = max(line_max_mm / 2 / grid.res_mm, r_px)
    core = sdepth >= half_px if not lines_only else np.zeros(art.shape, dtype=bool)
    to_core = _distance(~core) if core.any() else np.full(art.shape, np.inf, np.float32)
    inset = (to_core <= half_px - r_px - INSET_MARGIN_PX) & (sdepth >= r_px + INSET_MARGIN_PX)
    # a part barely line_max wide (a 0.6 mm line turned 20 degrees) has a core of specks
    # whose insets are too small to outline: without them it is line art, drawn along its
    # centreline (with them it was neither, and was lost)
    fill_px = FILL_INSET_NEEDLES * needle_mm / grid.res_mm
    drop = _specks(inset, min_loop_px * factor)
    if line_max_mm > 0 and not lines_only:
        # a line's corner or join is wider than its legs (a zigzag's vertex), and a line
        # about line_max wide is over it in stretches: such a thick part with no fill on
        # a piece of line art is drawn along the line's centreline, so the line runs
        # through it in one stroke instead of stopping at it
        thin = smooth & ~(to_core <= half_px)
        drop |= _line_joins(inset & ~drop, thin, fill_px, half_px, r_px,
                            JOIN_MAX_LINE_MAX * line_max_mm / grid.res_mm)
    if drop.any():
        inset &= ~drop
        core &= ~drop
        to_core = _distance(~core) if core.any() else np.full(art.shape, np.inf, np.float32)
    inset_labels = np.where(inset, fine, 0).astype(np.int32)
    fill_labels = np.where(_distance(inset) - 0.5 >= fill_px, inset_labels, 0).astype(np.int32)

    loops = _component_loops(inset, fine, grid, min_loop_px * factor)

    lines: dict[int, list[Loop]] = {}
    widths: dict[int, list[NDArray[np.float64]]] = {}
    if line_max_mm > 0 or lines_only:
        thin = smooth & ~(to_core <= half_px)
        if vector is not None:
            thin &= ~_vector_lines(vector, fine, grid, line_max_mm, lines, widths)
        _centrelines(thin, smooth, fine, depth, grid, line_max_mm, lines, widths)
        _drop_crumbs(lines, widths, loops, line_max_mm / 2)
    safe = InkMask(depth >= r_px, grid.res_mm, grid.xs, grid.ys)
    return Compensated(grid, safe, inset_labels, fill_labels, loops, lines, widths)


def _centrelines(thin: NDArray[np.bool_], art: NDArray[np.bool_], fine: NDArray[np.int32],
                 depth: NDArray[np.float32], grid: FineGrid, line_max_mm: float,
                 lines: dict[int, list[Loop]], widths: dict[int, list[NDArray[np.float64]]]
                 ) -> None:
    """Centreline strokes of each piece of line art at least ``line_max_mm`` long (its
    area at least ``line_max_mm`` squared), added to ``lines`` and ``widths``."""
    from skimage.morphology import skeletonize

    line_px = line_max_mm / grid.res_mm
    n, comp, stats, _ = cv2.connectedComponentsWithStats(thin.astype(np.uint8), connectivity=8)
    margin = int(math.ceil(line_px)) + 1
    hh, ww = art.shape
    for k in range(1, n):
        if stats[k, cv2.CC_STAT_AREA] < line_px * line_px:
            continue  # a corner of a wider part, or a speck
        x, y, w, h = stats[k, :4]
        r0, r1 = max(0, y - margin), min(hh, y + h + margin)
        c0, c1 = max(0, x - margin), min(ww, x + w + margin)
        skel = skeletonize(art[r0:r1, c0:c1]) & (comp[r0:r1, c0:c1] == k)
        lab = _region_of(fine[y:y + h, x:x + w], comp[y:y + h, x:x + w] == k)
        if lab == 0:
            continue  # the smoothed artwork's, not the mask's
        for stroke in skeleton_strokes(skel, prune_px=line_px / 2,
                                       depth=depth[r0:r1, c0:c1] + 0.5):
            rc = stroke + np.array([r0, c0])
            if len(rc) < 2:
                continue
            lines.setdefault(lab, []).append(_smooth_open(grid.to_mm(rc)))
            width = pixel_width(depth[rc[:, 0], rc[:, 1]] + 0.5, grid.res_mm)
            widths.setdefault(lab, []).append(width)


def _arc_mm(p: Loop) -> float:
    return float(np.linalg.norm(np.diff(p, axis=0), axis=1).sum()) if len(p) > 1 else 0.0


def _drop_crumbs(lines: dict[int, list[Loop]], widths: dict[int, list[NDArray[np.float64]]],
                 loops: dict[int, tuple[list[Loop], list[Loop]]], crumb_mm: float) -> None:
    """Remove the crumbs from ``lines`` (and their ``widths``): centreline strokes shorter
    than ``crumb_mm`` within ``crumb_mm`` of a longer stroke or an outline of their
    region. They are knots of the skeleton where a line turns or meets a thick part;
    their ink is the neighbour's, and each drawn apart costs a needle entry. A short
    stroke on its own (a dot, a dash) is kept."""
    for lab, strokes in lines.items():
        length = [_arc_mm(s) for s in strokes]
        short = [i for i, n in enumerate(length) if n < crumb_mm]
        if not short:
            continue
        outers, holes = loops.get(lab, ([], []))
        others = [s for i, s in enumerate(strokes) if length[i] >= crumb_mm] + outers + holes
        if not others:
            continue
        near = np.vstack(others)
        gone = {i for i in short
                if np.sqrt(((strokes[i][:, None, :] - near[None]) ** 2).sum(axis=2)).min()
                <= crumb_mm}
        lines[lab] = [s for i, s in enumerate(strokes) if i not in gone]
        widths[lab] = [w for i, w in enumerate(widths[lab]) if i not in gone]


def _vector_lines(vector: VectorLines, fine: NDArray[np.int32], grid: FineGrid,
                  line_max_mm: float, lines: dict[int, list[Loop]],
                  widths: dict[int, list[NDArray[np.float64]]]) -> NDArray[np.bool_]:
    """Add the vector lines narrower than ``line_max_mm`` to ``lines`` (each in the region
    it lies on most; none: not drawn, like a dropped region) and return the fine pixels
    they cover (their width plus a mask pixel each side)."""
    covered = np.zeros(fine.shape, np.uint8)
    rows, cols = fine.shape
    for path, width in zip(vector.paths, vector.widths_mm, strict=True):
        if width >= line_max_mm or len(path) < 2:
            continue
        px = np.column_stack([(path[:, 0] - grid.xs[0]) / grid.res_mm,
                              (grid.ys[0] - path[:, 1]) / grid.res_mm])
        thick = max(1, int(round(width / grid.res_mm)) + 2 * grid.factor)
        # drawn in the line's own window of the grid (its box and a stroke's width), so
        # each line costs its size, not the whole grid's (10,000 lines: minutes to seconds)
        c0, r0 = np.maximum(np.floor(px.min(axis=0)).astype(int) - thick, 0)
        c1, r1 = np.minimum(np.ceil(px.max(axis=0)).astype(int) + thick + 1, (cols, rows))
        if c1 <= c0 or r1 <= r0:
            continue
        pts = np.rint((px - (c0, r0)) * 16).astype(np.int32).reshape(-1, 1, 2)
        band = np.zeros((r1 - r0, c1 - c0), np.uint8)
        cv2.polylines(band, [pts], isClosed=False, color=1, thickness=thick, shift=4)
        covered[r0:r1, c0:c1] |= band
        window = fine[r0:r1, c0:c1]
        lab = _region_of(window, band.astype(bool))
        if lab == 0:
            continue
        pieces = _on_ink(path, window, (r0, c0), grid, float(width))
        for piece in pieces:
            if piece is not path:
                lab = _region_of(window, _band(piece, window.shape, (r0, c0), grid, thick))
            if lab:
                lines.setdefault(lab, []).append(piece)
                widths.setdefault(lab, []).append(np.full(len(piece), float(width)))
    return covered.astype(bool)


def _band(path: Loop, shape: tuple[int, ...], origin: tuple[int, int], grid: FineGrid,
          thick: int) -> NDArray[np.bool_]:
    """The pixels of a window (its top-left pixel at ``origin``, row and column) that a
    polyline (mm) covers at ``thick`` pixels."""
    r0, c0 = origin
    px = np.column_stack([(path[:, 0] - grid.xs[0]) / grid.res_mm - c0,
                          (grid.ys[0] - path[:, 1]) / grid.res_mm - r0])
    band = np.zeros(shape[:2], np.uint8)
    cv2.polylines(band, [np.rint(px * 16).astype(np.int32).reshape(-1, 1, 2)],
                  isClosed=False, color=1, thickness=thick, shift=4)
    return band.astype(bool)


def _on_ink(path: Loop, window: NDArray[np.int32], origin: tuple[int, int], grid: FineGrid,
            min_mm: float) -> list[Loop]:
    """The pieces of a vector line (mm) that lie on the kept ink of ``window`` (its labels;
    a region the mask dropped, or no ink, is 0), a mask pixel's tolerance: the whole line,
    unchanged, when all of it does (a stroked line's centreline lies inside its ink); else
    its runs on ink at least ``min_mm`` long, resampled at half a fine pixel. So a line the
    mask dropped in part is drawn where the mask keeps it, never across the dropped part."""
    r0, c0 = origin
    k = 2 * grid.factor + 1
    near = cv2.dilate((window > 0).astype(np.uint8),
                      cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (k, k)))
    pts = resample(path, grid.res_mm / 2)
    col = np.rint((pts[:, 0] - grid.xs[0]) / grid.res_mm).astype(np.intp) - c0
    row = np.rint((grid.ys[0] - pts[:, 1]) / grid.res_mm).astype(np.intp) - r0
    inside = (row >= 0) & (row < near.shape[0]) & (col >= 0) & (col < near.shape[1])
    on = np.zeros(len(pts), bool)
    on[inside] = near[row[inside], col[inside]] > 0
    if on.all():
        return [path]
    edges = np.flatnonzero(np.diff(np.concatenate([[0], on.astype(np.int8), [0]])))
    pieces = [pts[a:b] for a, b in zip(edges[0::2], edges[1::2], strict=True)]
    return [q for q in pieces if len(q) >= 2 and _arc_mm(q) >= min_mm]


def pixel_width(distance_px: NDArray[np.floating], res_mm: float) -> NDArray[np.float64]:
    """The width of a band read at its centre from the distance transform (px to the
    nearest pixel outside): ``2 d - 1/2`` px, within half a pixel for any band (an odd
    width's centre pixel reads ``(w + 1) / 2``, an even width's ``w / 2``)."""
    return (2.0 * np.asarray(distance_px, dtype=np.float64) - 0.5) * res_mm


def _smooth_open(p: Loop, passes: int = 4) -> Loop:
    """[1, 2, 1] / 4 passes along an open polyline (a closed one stays closed), its ends
    kept: takes the pixel steps out of a skeleton's path."""
    p = p.copy()
    closed = len(p) > 3 and np.array_equal(p[0], p[-1])
    for _ in range(passes):
        if closed:
            ring = p[:-1]
            ring = 0.25 * np.roll(ring, 1, axis=0) + 0.5 * ring + 0.25 * np.roll(ring, -1, axis=0)
            p = np.vstack([ring, ring[:1]])
        elif len(p) > 2:
            p[1:-1] = 0.25 * p[:-2] + 0.5 * p[1:-1] + 0.25 * p[2:]
    return p


def concentric_rings(comp: Compensated, pitch_mm: float, min_loop_px: int
                     ) -> dict[int, list[Loop]]:
    """A contour-parallel fill: per region label, the loops ``pitch_mm / 2``,
    ``3 pitch_mm / 2``, ... inside its inset's boundary (outer and hole loops alike,
    outermost first): the first ring half a pitch in, so a band narrower than two
    pitches still gets one."""
    grid = comp.grid
    inside = comp.inset > 0
    depth = _distance(inside)
    pitch_px = pitch_mm / grid.res_mm
    rings: dict[int, list[Loop]] = {}
    k = 1
    while True:
        level = depth >= (k - 0.5) * pitch_px + 0.5
        if not level.any():
            return rings
        for lab, (outers, holes) in _component_loops(level, comp.inset, grid,
                                                     min_loop_px * grid.factor).items():
            rings.setdefault(lab, []).extend(outers + holes)
        k += 1
