"""Needle-width compensation costs no needle entries (issue 30, item 4).

The compensated hatch runs a needle inside the inset outline (``FILL_INSET_NEEDLES`` in
tattotronix/path/inset.py), so its runs are joined by drags through the ink as the
original's are: with compensation the built-in drawings and a logo take at most as many
needle entries as without, and no drag inks outside the artwork.
"""

from __future__ import annotations

import dataclasses

import cv2
import numpy as np
import pytest

from tattotronix.art.grid import InkMask
from tattotronix.config.params import compose_settings
from tattotronix.config.schema import MaskConfig, PanelConfig, ToolpathConfig
from tattotronix.path.fidelity import planned_ink
from tattotronix.path.params import ToolpathParams
from tattotronix.path.plan import Toolpath, plan_toolpath
from tattotronix.path.regions import find_regions
from tattotronix.path.strokes import StrokeKind

PARAMS = ToolpathParams.from_settings(ToolpathConfig(), MaskConfig(), PanelConfig())
NEEDLE = PARAMS.needle_width_mm
FINE = 0.025  # the toolpath stage's ink grid (toolpath.ink_res_mm), mm
BLEED_MM = 0.05  # the project's goal for the farthest bleed of the planned ink


def logo_mask(res_mm: float = 0.25) -> InkMask:
    """A logo-sized drawing (150 x 40 mm): "TATTO" (the A and the O have holes), a disc,
    a bar, a triangle and a thin underline."""
    w, h = int(150 / res_mm), int(40 / res_mm)
    img = np.zeros((h, w), np.uint8)
    cv2.putText(img, "TATTO", (20, 120), cv2.FONT_HERSHEY_SIMPLEX, 3.6, 1, 22, cv2.LINE_AA)
    cv2.circle(img, (460, 60), 40, 1, -1)
    cv2.rectangle(img, (520, 30), (580, 130), 1, -1)
    cv2.fillPoly(img, [np.array([[440, 120], [480, 150], [400, 150]], np.int32)], 1)
    cv2.line(img, (20, 145), (380, 140), 1, 3)
    return InkMask.centred(img > 0, res_mm)


def random_mask(seed: int, n: int = 120, res_mm: float = 0.25) -> InkMask:
    """A seeded random drawing on an ``n`` x ``n`` grid: one to four blobs (ellipses), rings
    (with their hole), thin bars and polygons."""
    rng = np.random.default_rng(seed)
    img = np.zeros((n, n), np.uint8)
    for _ in range(int(rng.integers(1, 5))):
        kind = int(rng.integers(0, 4))
        c = (int(rng.integers(15, n - 15)), int(rng.integers(15, n - 15)))
        if kind == 0:
            axes = (int(rng.integers(6, 30)), int(rng.integers(6, 30)))
            cv2.ellipse(img, c, axes, float(rng.uniform(0, 180)), 0, 360, 1, -1)
        elif kind == 1:
            cv2.circle(img, c, int(rng.integers(12, 35)), 1, int(rng.integers(4, 12)))
        elif kind == 2:
            end = (int(rng.integers(5, n - 5)), int(rng.integers(5, n - 5)))
            cv2.line(img, c, end, 1, int(rng.integers(2, 7)))
        else:
            pts = rng.integers(5, n - 5, (int(rng.integers(3, 7)), 2)).astype(np.int32)
            cv2.fillPoly(img, [pts], 1)
    return InkMask.centred(img > 0, res_mm)


def _plans(mask: InkMask, params: ToolpathParams) -> tuple[Toolpath, Toolpath]:
    """(without, with) compensation."""
    return (plan_toolpath(mask, dataclasses.replace(params, compensate=False)),
            plan_toolpath(mask, dataclasses.replace(params, compensate=True)))


def _bleed_mm(mask: InkMask, tp: Toolpath, kinds: tuple[StrokeKind, ...]) -> float:
    """The farthest the ink of the strokes of ``kinds`` (and of the drags leading to them,
    each inked as part of the stroke it leads to) reaches outside the artwork, mm."""
    seq = tp.order.sequence
    uvz = tp.path.uvz_mm.copy()
    uvz[~np.isin(tp.drawing.kinds[seq][tp.path.stroke], kinds), 2] = 1.0  # lifted
    return planned_ink(mask, uvz, tp.path.stroke, tp.drawing.is_fill[seq], NEEDLE,
                       FINE).fidelity.bleed_max_mm


def test_the_logo_has_the_issues_regions_and_holes() -> None:
    mask = logo_mask()
    _, regions = find_regions(mask.ink, mask.res_mm, PARAMS.min_region_mm2,
                              PARAMS.min_loop_px)
    assert len(regions) >= 9
    assert sum(r.hole_count for r in regions) >= 2


@pytest.mark.parametrize("name", ["emblem", "lineart", "logo"])
def test_compensation_takes_no_more_needle_entries(name: str) -> None:
    if name == "logo":
        mask, params = logo_mask(), PARAMS
    else:
        from tattotronix.app.pipeline import mask_of

        over = ["artwork.source=lineart", "mask.res_mm=0.1"] if name == "lineart" else []
        cfg = compose_settings(over)
        mask = mask_of(cfg, cfg.artwork.source, name)
        params = ToolpathParams.from_settings(cfg.toolpath, cfg.mask, cfg.robot.panel)
    plain, comp = _plans(mask, params)
    assert comp.metrics.entries <= plain.metrics.entries, name
    assert comp.path.drags > 0
    # the outlines, fill and drags (line art's ink is the needle's width, whatever the
    # line's): within the ink raster's own pixel of the goal
    body = (StrokeKind.OUTER, StrokeKind.HOLE, StrokeKind.FILL)
    assert _bleed_mm(mask, comp, body) <= BLEED_MM + FINE


def test_random_drawings_take_fewer_entries_and_keep_the_ink_inside() -> None:
    entries = np.zeros((20, 2), int)
    for seed in range(20):
        mask = random_mask(seed)
        plain, comp = _plans(mask, PARAMS)
        entries[seed] = plain.metrics.entries, comp.metrics.entries
        # the hatch and the drags joining it (an outline's own bleed is the inset's,
        # up to 0.125 mm at a sharp corner of these drawings, with or without this fix)
        assert _bleed_mm(mask, comp, (StrokeKind.FILL,)) <= BLEED_MM + FINE, seed
        # over the set, compensation costs no entries (measured: 101 with it against 102
    # without; 183 before the hatch ran a needle inside the inset). A single drawing may
    # still take up to 5 more (8 of the 20): a curved band whose runs a straight drag a
    # needle inside the artwork cannot join (the uncompensated drags cut across its edge)
    assert entries[:, 1].sum() <= entries[:, 0].sum(), entries.tolist()
    assert (entries[:, 1] <= entries[:, 0] + 5).all()


def zigzag_mask(width_px: int, turn_deg: float, res_mm: float = 0.1) -> InkMask:
    """Line art as users draw it: zigzags (sharp 53 degree vertices) of a stroke
    ``width_px`` wide, turned ``turn_deg`` about the centre, on a ``res_mm`` grid."""
    n = int(60 / res_mm)
    img = np.zeros((n, n), np.uint8)
    for row in range(3):
        y0 = 12 + 18 * row
        pts = np.array([[6 + 4 * k, y0 + (4 if k % 2 else -4)] for k in range(12)], float)
        cv2.polylines(img, [np.rint(pts / res_mm * 16).astype(np.int32)], False, 1,
                      width_px, cv2.LINE_8, shift=4)
    turn = cv2.getRotationMatrix2D((n / 2, n / 2), turn_deg, 1.0)
    img = cv2.warpAffine(img.astype(np.float32), turn, (n, n), flags=cv2.INTER_LINEAR)
    return InkMask.centred(img >= 0.5, res_mm)


@pytest.mark.parametrize(("width_px", "turn_deg", "most"),
                         [(3, 0.0, 3), (4, 20.0, 5), (4, 35.0, 9), (7, 20.0, 9)])
def test_a_zigzag_runs_on_through_its_corners(width_px: int, turn_deg: float,
                                              most: int) -> None:
    """A zigzag's vertex is wider than its legs: its skeleton grows a spur toward the
    vertex's tip, and a knot or two of skeleton crumbs, and a thick vertex gets an inset
    of its own. The spur is pruned (up to three half-widths long), the crumbs dropped and
    the vertex drawn along the line, so the line runs on through its corners, and
    compensation takes no more entries than the original's strokes. Before, every leg was
    a stroke of its own: 29 entries on the artworks benchmark's line art turned 20
    degrees, against 23 without compensation; now 15."""
    mask = zigzag_mask(width_px, turn_deg)
    plain, comp = _plans(mask, PARAMS)
    assert comp.metrics.entries <= plain.metrics.entries
    assert comp.metrics.entries <= most  # three zigzags
