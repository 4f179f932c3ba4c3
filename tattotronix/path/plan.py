"""Mask to toolpath in one call: strokes, ordering, 3-D path, timing, arm frame, metrics.

The original's ordering is planned beside ours on the same strokes (same pitch, same
resampling), with the original's lift rule: it stays down across any gap whose straight line
is on ink, however long, where ours stays down only where that is also faster than a lift.

Budget: a fine pitch or step multiplies the work. Before each costly step the work is
estimated and refused over a stated budget, with the estimate in the message
(:func:`check_fill_budget`, :func:`check_order_budget`, :func:`check_points_budget`): the
fill's scanlines x mask columns before hatching, the strokes before ordering them (the
search is quadratic in strokes), the path's points before resampling.

A needle that cannot draw the artwork is refused after planning (:func:`check_needle`):
when most of the ink the path lays down, at the needle's width, falls outside the
artwork (more than :data:`MAX_BLEED_SHARE` of it), the drawing is not the artwork.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from tattotronix.art.grid import InkMask
from tattotronix.art.vector import VectorLines
from tattotronix.errors import TattotronixError
from tattotronix.io.jsontypes import JsonDict
from tattotronix.path.fidelity import ArtworkFidelity, PlannedInk, planned_ink
from tattotronix.path.fill import MIN_RUN_PX
from tattotronix.path.laps import Laps
from tattotronix.path.order import MAX_PASSES, Order, OrderResult, optimise_order
from tattotronix.path.panel import check_fits, to_arm
from tattotronix.path.params import ToolpathParams
from tattotronix.path.path3d import Path3D, build_path_flat
from tattotronix.path.polyline import resample_many
from tattotronix.path.regions import find_regions
from tattotronix.path.strokes import StrokeKind, StrokeSet, regions_drawing
from tattotronix.path.timing import PathMetrics, measure, segment_lengths, timestamps

__all__ = ["MAX_BLEED_SHARE", "MAX_FILL_CELLS", "MAX_POINTS", "MAX_STROKES", "Toolpath",
           "check_fill_budget", "check_needle", "check_order_budget", "check_points_budget",
           "plan_toolpath"]

log = logging.getLogger("tattotronix.path")

#: most fill scanlines x mask columns hatched at once (~12 bytes each in temporaries)
MAX_FILL_CELLS = 20_000_000
#: most strokes ordered: the search is quadratic in strokes (measured on the built-in
#: emblem: 10 379 strokes at toolpath.pitch_mm=0.05 took 108 s and 0.8 GB)
MAX_STROKES = 12_000
#: most points on the path: the trajectory stage holds ~2.2 kB a point (measured on the
#: built-in emblem: 3.2 million points at toolpath.step_mm=0.001 took 7.2 GB)
MAX_POINTS = 1_000_000
#: the largest share of a drawing's planned ink that may fall outside the artwork: "most of
#: the ink outside" (more than half) is a needle that cannot draw it. The built-in artworks
#: bleed 0.1 % (emblem) to 1.4 % (lineart); the emblem at toolpath.needle_width_mm=8, 73 %.
MAX_BLEED_SHARE = 0.5
#: the needle check's coarse screen: this many pixels across the needle (at least a quarter
#: of a mask pixel each, never coarser than the mask)
_CHECK_PX_PER_NEEDLE = 4
#: bytes of temporaries per fill cell, and per ordered stroke squared (for messages)
_CELL_BYTES = 12
_STROKE2_BYTES = 8


def _gib(n_bytes: float) -> str:
    gib = n_bytes / 2**30
    return f"{gib:.2f} GiB" if gib < 10 else f"{gib:,.0f} GiB"


def check_fill_budget(mask: InkMask, params: ToolpathParams) -> None:
    """Refuse a pitch whose fill would hatch more than :data:`MAX_FILL_CELLS` cells, or
    make more than :data:`MAX_STROKES` strokes, before hatching anything.

    The strokes are counted from the mask: each scanline reads its nearest mask row, whose
    runs of at least ``MIN_RUN_PX`` ink pixels each become a fill stroke.

    Raises:
        TattotronixError: over budget; the message gives the estimate and what to raise.
    """
    h, w = mask.ink.shape
    res, pitch = mask.res_mm, params.fill_pitch_mm
    span = (h - 1) * res / pitch
    lines = math.floor(span + 1e-9) + 1 if math.isfinite(span) else math.inf
    cells = lines * w
    if cells > MAX_FILL_CELLS:
        raise TattotronixError(
            f"toolpath.pitch_mm={pitch:g} on this {h * res:.1f} mm tall mask needs {lines:.4g} "
            f"fill scanlines x {w} columns = {cells:.3g} cells (~{_gib(cells * _CELL_BYTES)}), "
            f"over the toolpath's budget of {MAX_FILL_CELLS:.3g}: raise toolpath.pitch_mm "
            "(or mask.res_mm)")
    padded = np.pad(mask.ink, ((0, 0), (1, 1))).astype(np.int8)
    step = np.diff(padded, axis=1)
    start_r, start_c = np.nonzero(step == 1)
    _, end_c = np.nonzero(step == -1)
    runs = np.bincount(start_r[(end_c - start_c) >= MIN_RUN_PX], minlength=h)
    # scanline k reads row floor(k q + 1/2), q = pitch / res: row r is read by the k in
    # [(r - 1/2) / q, (r + 1/2) / q)
    q = pitch / res
    r = np.arange(h, dtype=np.float64)
    reads = (np.clip(np.ceil((r + 0.5) / q), 0, lines)
             - np.clip(np.ceil((r - 0.5) / q), 0, lines))
    strokes = int((reads * runs).sum())
    check_order_budget(strokes, params)


def check_order_budget(strokes: int, params: ToolpathParams) -> None:
    """Refuse ordering more than :data:`MAX_STROKES` strokes.

    Raises:
        TattotronixError: over budget; the message gives the count and what to raise.
    """
    if strokes > MAX_STROKES:
        raise TattotronixError(
            f"toolpath.pitch_mm={params.pitch_mm:g} makes about {strokes} strokes, over the "
            f"toolpath's budget of {MAX_STROKES} (ordering them is quadratic: "
            f"~{_gib(strokes**2 * _STROKE2_BYTES)}): raise toolpath.pitch_mm, or draw a "
            "smaller or simpler artwork")


def check_points_budget(drawing: StrokeSet, params: ToolpathParams) -> None:
    """Refuse resampling the strokes into more than :data:`MAX_POINTS` points.

    Raises:
        TattotronixError: over budget; the message gives the count and what to raise.
    """
    lengths = _stroke_lengths(drawing)
    points = int(np.floor(lengths / params.step_mm).sum()) + 2 * len(lengths)
    if points > MAX_POINTS:
        raise TattotronixError(
            f"toolpath.step_mm={params.step_mm:g} makes about {points} points along "
            f"{lengths.sum():.0f} mm of strokes, over the toolpath's budget of {MAX_POINTS} "
            f"(the trajectory stage holds ~2.2 kB a point: ~{_gib(points * 2200)}): raise "
            "toolpath.step_mm")


def _stroke_lengths(drawing: StrokeSet) -> NDArray[np.float64]:
    """(n,) chord length of each stroke's vertices, mm (summed per stroke as ``np.sum``)."""
    v, vb = drawing.vertices, drawing.bounds
    seg = np.linalg.norm(np.diff(v, axis=0), axis=1)
    out = np.zeros(len(vb) - 1)
    for size in np.unique(np.diff(vb)):  # strokes of one vertex count: one row each
        rows = np.flatnonzero(np.diff(vb) == size)
        if size > 1:
            out[rows] = seg[vb[rows][:, None] + np.arange(size - 1)].sum(axis=1)
    return out


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
        timings_s: wall time of each step of the planning, s (``checks``, ``regions``,
            ``fill``, ``resample``, ``costs``, ``ordering``, ``original``, ``path``,
            ``metrics``); for the benchmark and the logs, never part of the plan.
    """

    drawing: StrokeSet
    order: Order
    path: Path3D
    t_s: NDArray[np.float64]
    xyz_m: NDArray[np.float64]
    metrics: PathMetrics
    original: PathMetrics
    ordering: OrderResult
    timings_s: Mapping[str, float] = field(default_factory=dict, compare=False)

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


    def ink(self, mask: InkMask, needle_mm: float, res_mm: float) -> PlannedInk:
        """The ink this path draws, at ``needle_mm`` wide on a ``res_mm`` grid, against
        the artwork ``mask`` it was planned from (:func:`~tattotronix.path.fidelity.planned_ink`;
        the lines along centrelines with their designed widths)."""
        seq = self.order.sequence
        return planned_ink(mask, self.path.uvz_mm, self.path.stroke, self.drawing.is_fill[seq],
                           needle_mm, res_mm, self.drawing.width_mm[seq])


def check_needle(tp: Toolpath, mask: InkMask, needle_mm: float, res_mm: float,
                 measured: ArtworkFidelity | None = None) -> None:
    """Refuse a needle that cannot draw the artwork: more than :data:`MAX_BLEED_SHARE` of
    the ink the path lays down, at the needle's width, outside the artwork, as the
    toolpath stage measures it (on a ``res_mm`` grid: ``toolpath.ink_res_mm``).

    ``measured`` is that measure when the caller has it (the toolpath stage). Else a
    coarse one first (a quarter of the needle a pixel, within the mask's pixel: a few
    hundredths of a second, and it reads more bleed, not less, than the fine one on the
    built-in artworks); only when it finds over half the limit is the fine one made.

    Raises:
        TattotronixError: the needle is too wide for the artwork, naming
            ``toolpath.needle_width_mm``.
    """
    if measured is None:
        seq = tp.order.sequence
        fill = tp.drawing.is_fill[seq]
        coarse = min(mask.res_mm, max(needle_mm / _CHECK_PX_PER_NEEDLE, mask.res_mm / 4))
        screen = planned_ink(mask, tp.path.uvz_mm, tp.path.stroke, fill, needle_mm,
                             max(coarse, res_mm)).fidelity
        if screen.bleed_share <= MAX_BLEED_SHARE / 2:
            return
        measured = planned_ink(mask, tp.path.uvz_mm, tp.path.stroke, fill, needle_mm,
                               res_mm).fidelity
    if measured.bleed_share > MAX_BLEED_SHARE:
        raise TattotronixError(
            f"toolpath.needle_width_mm={needle_mm:g} cannot draw this artwork: "
            f"{100 * measured.bleed_share:.1f} % of the ink it would lay down falls outside "
            f"the artwork (up to {measured.bleed_max_mm:.2f} mm outside; more than "
            f"{100 * MAX_BLEED_SHARE:g} % is refused), so the drawing would not be the "
            "artwork: give the needle's real width, a narrower needle, or draw the artwork "
            "larger (mask.width_mm)")


def plan_toolpath(mask: InkMask, params: ToolpathParams, max_passes: int = MAX_PASSES,
                  vector: VectorLines | None = None) -> Toolpath:
    """Plan the needle path for an ink mask.

    Args:
        mask: the ink mask.
        params: the toolpath parameters.
        max_passes: the ordering search's budget of 2-opt passes (work, not time).
        vector: the artwork's own lines (``artwork.vector``; used when compensating), in
            the artwork's centred frame: they go where the mask was placed.

    Returns:
        The toolpath, with the original ordering's figures beside ours.

    Raises:
        TattotronixError: the drawing does not fit the panel, has no ink region to draw,
            or would take more work than the budget (:func:`check_fill_budget`, ...).
    """
    laps = Laps()
    check_fits(mask, params)
    if vector is not None:
        vector = vector.placed(mask.place)
    check_fill_budget(mask, params)
    laps.lap("checks")
    labels, regions = find_regions(
        mask.ink, mask.res_mm, params.min_region_mm2, params.min_loop_px
    )
    laps.lap("regions")
    drawing = regions_drawing(mask, labels, regions, params, vector)
    laps.lap("fill")
    if not drawing.strokes and regions and params.compensate:
        raise TattotronixError(
            f"toolpath.needle_width_mm={params.needle_width_mm:g} leaves nothing to draw: "
            f"no part of the artwork's {len(regions)} ink region(s) is drawable with the "
            "needle's compensation (toolpath.compensate, toolpath.line_max_mm="
            f"{params.line_max_mm:g}); give the needle's real width, a narrower needle, or "
            "draw the artwork larger (mask.width_mm)")
    if not drawing.strokes:
        raise TattotronixError(
            f"the mask has no ink region of at least {params.min_region_mm2} mm^2 "
            "(mask.min_region_mm2): nothing to draw; check the artwork or the mask method"
        )
    check_order_budget(len(drawing.strokes), params)
    check_points_budget(drawing, params)
    laps.lap("checks")
    on_ink = drawing.drag_mask if drawing.drag_mask is not None else mask
    result = optimise_order(drawing, on_ink, params, max_passes=max_passes, laps=laps)
    laps.skip()
    # every stroke resampled once as drawn in the original's order; ours reuses the strokes
    # it draws the same way
    canonical = resample_many(drawing.vertices, drawing.bounds, params.step_mm)
    pts, bounds = result.order.resampled(drawing, params.step_mm, canonical)
    laps.lap("resample")
    fill = drawing.kinds[result.order.sequence] == StrokeKind.FILL
    path = build_path_flat(pts, bounds, on_ink, params, turnable=fill[:-1] & fill[1:])
    laps.lap("path")
    baseline = build_path_flat(*canonical, on_ink, params, math.inf)
    orig = measure(baseline, params)
    laps.lap("original")
    seg = segment_lengths(path.uvz_mm)
    t = timestamps(path, params, seg)
    ours = measure(path, params, t, seg)
    xyz = to_arm(path.uvz_mm, params)
    laps.lap("metrics")
    log.info(
        "ordered %d strokes in %.2f s (%d 2-opt passes): %.1f s between strokes, "
        "%.1f s greedy, %.1f s in the original's order",
        len(drawing.strokes), result.elapsed_s, result.passes, result.cost_s,
        result.greedy_cost_s, result.original_cost_s,
    )
    return Toolpath(drawing, result.order, path, t, xyz, ours, orig, result, laps.seconds)
