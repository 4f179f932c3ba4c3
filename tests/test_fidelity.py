"""Ink against the artwork (tattotronix/path/fidelity.py): bleed, coverage and edge error
on shapes whose answer is known, a property over random rectangles and insets, and the
planned ink of a real toolpath."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tattotronix.art.grid import InkMask
from tattotronix.config.schema import FillStyle, MaskConfig, PanelConfig, ToolpathConfig
from tattotronix.path.fidelity import (
    artwork_fidelity,
    artwork_on,
    below_runs,
    fidelity_image,
    grid_over,
    planned_ink,
    rasterise_runs,
)
from tattotronix.path.params import ToolpathParams
from tattotronix.path.plan import plan_toolpath

RES = 0.025  # mm: the grid the issue measured on
NEEDLE = 0.3


def _square(half_mm: float, res_mm: float = 0.25, size_mm: float = 30.0) -> InkMask:
    n = int(round(size_mm / res_mm))
    mask = InkMask.centred(np.zeros((n, n), dtype=bool), res_mm)
    inside = (np.abs(mask.xs)[None, :] <= half_mm) & (np.abs(mask.ys)[:, None] <= half_mm)
    return InkMask(inside, res_mm, mask.xs, mask.ys)


def _loop(half_mm: float, step_mm: float = 0.1) -> np.ndarray:
    """A closed square outline of half-side ``half_mm``, as panel points below the surface."""
    t = np.arange(-half_mm, half_mm, step_mm)
    side = [np.c_[t, np.full_like(t, -half_mm)], np.c_[np.full_like(t, half_mm), t],
            np.c_[-t, np.full_like(t, half_mm)], np.c_[np.full_like(t, -half_mm), -t]]
    uv = np.vstack([*side, side[0][:1]])
    return np.c_[uv, np.full(len(uv), -1.0)]


def _fidelity(mask: InkMask, uvz: np.ndarray):
    corners = np.array([[mask.xs[0], mask.ys[0]], [mask.xs[-1], mask.ys[-1]]])
    grid = grid_over([corners], RES)
    art = artwork_on(mask, grid)
    ink = rasterise_runs(below_runs(uvz), grid, NEEDLE)
    return art, ink, artwork_fidelity(art, ink, RES)


def test_the_artwork_on_a_grid_of_its_own_pixel_is_the_mask() -> None:
    mask = _square(5.0)
    corners = np.array([[mask.xs[0], mask.ys[0]], [mask.xs[-1], mask.ys[-1]]])
    grid = grid_over([corners], mask.res_mm, margin_mm=0.0)
    assert np.array_equal(artwork_on(mask, grid), mask.ink)


def test_an_outline_on_the_edge_bleeds_half_the_needle_and_an_inset_one_does_not() -> None:
    """The measurement the issue describes: an outline run on the artwork's edge puts half
    the needle's width outside it; inset by half the needle, none (to a pixel)."""
    # the mask's edge lies half a mask pixel beyond the outermost inked pixel centre
    mask = _square(10.0)
    edge = 10.0 + mask.res_mm / 2
    _, _, on = _fidelity(mask, _loop(edge))
    assert on.bleed_max_mm == pytest.approx(NEEDLE / 2, abs=2 * RES)
    assert on.edge_mean_mm == pytest.approx(NEEDLE / 2, abs=2 * RES)
    assert 0.3 < on.bleed_share < 0.7  # half the band is outside
    _, _, inset = _fidelity(mask, _loop(edge - NEEDLE / 2))
    assert inset.bleed_max_mm <= 2 * RES and inset.bleed_share < 0.05
    assert inset.edge_mean_mm <= 2 * RES
    # an outline alone covers a thin frame of the square, not its inside
    assert inset.coverage < 0.1


def test_ink_that_is_the_artwork_covers_it_all_and_bleeds_nothing() -> None:
    art = np.zeros((40, 60), dtype=bool)
    art[10:30, 5:50] = True
    f = artwork_fidelity(art, art.copy(), RES)
    assert (f.coverage, f.bleed_share, f.bleed_max_mm, f.edge_max_mm) == (1.0, 0.0, 0.0, 0.0)
    rgb = fidelity_image(art, art)
    assert (rgb[art] == (40, 40, 40)).all() and (rgb[~art] == 255).all()


@settings(max_examples=25, deadline=None)
@given(cells=st.integers(12, 48), inset=st.floats(NEEDLE / 2 + 2 * RES, 2.0))
def test_an_outline_inset_by_half_the_needle_keeps_the_ink_inside(cells: int,
                                                                 inset: float) -> None:
    half = cells * 0.25  # on a mask pixel centre, so the mask's edge is half a pixel out
    mask = _square(half)
    edge = half + mask.res_mm / 2  # where the mask's ink ends
    _, ink, f = _fidelity(mask, _loop(edge - inset))
    assert ink.any()
    assert f.bleed_max_mm <= RES * 1.5 and f.bleed_share < 0.02


@pytest.mark.parametrize("compensate", [True, False])
def test_a_planned_toolpath_reports_outline_and_fill_coverage(compensate: bool) -> None:
    mask = _square(6.0, size_mm=20.0)
    params = dataclasses.replace(
        ToolpathParams.from_settings(ToolpathConfig(), MaskConfig(), PanelConfig()),
        compensate=compensate)
    tp = plan_toolpath(mask, params)
    fill = tp.drawing.is_fill[tp.order.sequence]
    got = planned_ink(mask, tp.path.uvz_mm, tp.path.stroke, fill, NEEDLE, 0.05)
    f = got.fidelity
    assert f.coverage_outlines is not None and f.coverage_fill is not None
    assert max(f.coverage_outlines, f.coverage_fill) <= f.coverage
    assert f.coverage <= f.coverage_outlines + f.coverage_fill + 1e-9
    if compensate:  # half a needle inside the edge: no ink outside, the edges met
        assert f.bleed_max_mm == 0.0 and f.edge_mean_mm < 0.1
    else:  # the original runs the outline on the edge pixels: ink outside, under a needle
        assert 0.0 < f.bleed_max_mm <= NEEDLE and 0.0 < f.edge_mean_mm < NEEDLE
    assert got.ink.shape == got.art.shape


# --- fill styles -----------------------------------------------------------------------

def _labels(mask: InkMask) -> np.ndarray:
    from tattotronix.path.regions import find_regions

    return find_regions(mask.ink, mask.res_mm, 0.5, 8)[0]


def _disc_and_bar(res_mm: float = 0.25) -> InkMask:
    mask = InkMask.centred(np.zeros((120, 160), dtype=bool), res_mm)
    x, y = mask.xs[None, :], mask.ys[:, None]
    ink = (np.hypot(x + 8, y) <= 9) | ((np.abs(x - 10) <= 4) & (np.abs(y) <= 12))
    return InkMask(ink, res_mm, mask.xs, mask.ys)


def test_a_hatch_at_zero_degrees_is_the_original_hatch() -> None:
    from tattotronix.path.fill import hatch, hatch_at

    mask = _disc_and_bar()
    lab = _labels(mask)
    a = hatch(lab, mask.xs, mask.ys, mask.res_mm, 1.2)
    for deg in (0.0, 180.0, -180.0):
        b = hatch_at(lab, mask.xs, mask.ys, mask.res_mm, 1.2, deg)
        for key in ("label", "line", "a_mm", "b_mm"):
            assert np.array_equal(getattr(a, key), getattr(b, key)), (deg, key)


@settings(max_examples=20, deadline=None)
@given(deg=st.floats(-179.0, 179.0), pitch=st.floats(0.5, 2.0))
def test_a_hatch_at_any_angle_runs_along_it_and_stays_on_the_ink(deg: float,
                                                                pitch: float) -> None:
    from tattotronix.path.fill import hatch_at

    mask = _disc_and_bar()
    h = hatch_at(_labels(mask), mask.xs, mask.ys, mask.res_mm, pitch, deg)
    assert len(h.label) > 0
    d = h.b_mm - h.a_mm
    c, s = np.cos(np.radians(deg)), np.sin(np.radians(deg))
    across = np.abs(d[:, 0] * s - d[:, 1] * c)
    assert across.max() < 1e-9 * max(1.0, float(np.abs(d).max()))  # parallel to the angle
    # every point of every segment is within a mask pixel of the ink (two nearest-pixel
    # readings: the turn and the scanline)
    import cv2

    dist = cv2.distanceTransform((~mask.ink).astype(np.uint8), cv2.DIST_L2, 5)
    t = np.linspace(0.0, 1.0, 11)[:, None, None]
    pts = (h.a_mm[None] * (1 - t) + h.b_mm[None] * t).reshape(-1, 2)
    col = np.rint((pts[:, 0] - mask.xs[0]) / mask.res_mm).astype(int)
    row = np.rint((mask.ys[0] - pts[:, 1]) / mask.res_mm).astype(int)
    assert dist[row, col].max() <= 1.5


def test_each_fill_style_trades_coverage_for_time() -> None:
    """Each style goes through the same ordering and the same fidelity figures; a denser
    style buys coverage with marking time, and none inks outside the artwork."""
    mask = _disc_and_bar()
    figures = {}
    for style in FillStyle:
        cfg = ToolpathConfig(fill_style=style, fill_angle_deg=30.0, compensate=True)
        params = ToolpathParams.from_settings(cfg, MaskConfig(), PanelConfig())
        tp = plan_toolpath(mask, params)
        fill = tp.drawing.is_fill[tp.order.sequence]
        ink = planned_ink(mask, tp.path.uvz_mm, tp.path.stroke, fill, NEEDLE, 0.05)
        assert ink.fidelity.bleed_max_mm <= 0.05
        figures[style.value] = (ink.fidelity.coverage, tp.metrics.time_s, int(fill.sum()))
    (cov_h, time_h, n_h), (cov_c, time_c, n_c) = figures["hatch"], figures["cross"]
    assert n_c > 1.6 * n_h and cov_c > 1.1 * cov_h and time_c > time_h
    cov_s, time_s, _ = figures["solid"]
    assert cov_s > 0.95 and cov_s > cov_c and time_s > time_c  # the needle's width apart
    cov_r, time_r, n_r = figures["concentric"]
    # rings at the hatch's pitch: about the hatch's coverage, less than solid
    assert n_r > 0 and abs(cov_r - cov_h) < 0.2 * cov_h and cov_r < cov_s and time_r < time_s


# --- the ink figures (tattotronix/path/inkfigure.py) -----------------------------------------

def test_worst_spot_is_the_farthest_pixel_in_the_densest_cluster() -> None:
    from tattotronix.path.inkfigure import worst_spot

    where = np.zeros((60, 80), dtype=bool)
    far = np.zeros(where.shape, dtype=np.float32)
    where[5, 5] = where[40, 60] = where[41, 60] = where[40, 61] = True
    far[where] = 1.0  # all equally far: the cluster wins
    assert worst_spot(far, where, 5) in {(40, 60), (41, 60), (40, 61)}
    far[5, 5] = 2.0  # farther: it wins alone
    assert worst_spot(far, where, 5) == (5, 5)
    assert worst_spot(far, np.zeros_like(where), 5) is None


def test_ink_figures_are_written_with_or_without_a_difference(tmp_path: Path) -> None:
    from PIL import Image

    from tattotronix.path.fidelity import InkGrid
    from tattotronix.path.inkfigure import DPI, FIGSIZE, artwork_ink_figure, plan_ink_figure

    grid = InkGrid(u0_mm=-10.0, v0_mm=6.0, res_mm=0.05, shape=(240, 400))
    plan = np.zeros(grid.shape, dtype=bool)
    plan[100:106, 50:350] = True  # a 0.3 mm line, 15 mm long
    sim = plan.copy()
    sim[106, 200:203] = True  # three pixels of drift
    art = np.zeros(grid.shape, dtype=bool)
    art[98:108, 40:360] = True
    for name, draw in (("plan.png", lambda p: plan_ink_figure(sim, plan, grid, p, "t")),
                       ("same.png", lambda p: plan_ink_figure(plan, plan, grid, p, "t")),
                       ("art.png", lambda p: artwork_ink_figure(
                           art, sim, grid, p, "t", artwork_fidelity(art, sim, 0.05)))):
        draw(tmp_path / name)
        with Image.open(tmp_path / name) as im:
            assert im.format == "PNG"
            assert im.size == (round(FIGSIZE[0] * DPI), round(FIGSIZE[1] * DPI))


@given(seed=st.integers(0, 2**32 - 1))
@settings(max_examples=60, deadline=None)
def test_distances_at_a_few_pixels_are_the_transforms(seed: int) -> None:
    """``distance_at`` (a k-d tree of the target's edge for a few pixels, the transform
    for many) gives the precise distance transform's distances, to its float32."""
    from tattotronix.path.fidelity import distance_at, distance_to

    rng = np.random.default_rng(seed)
    h, w = (int(x) for x in rng.integers(1, 120, 2))
    img = rng.random((h, w)) < rng.choice([0.0, 0.001, 0.05, 0.5])
    where = rng.random((h, w)) < rng.choice([0.001, 0.02, 0.3])
    got = distance_at(img, where)
    want = distance_to(img)[where]
    assert got.dtype == np.float32 and got.shape == want.shape
    np.testing.assert_allclose(got, want, rtol=2e-6, atol=0)
