"""Toolpath stage: tracer self-test, resampling, ordering, panel refusal, the stage itself."""

from __future__ import annotations

import dataclasses
import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy import ndimage

from tattotronix.art.grid import InkMask
from tattotronix.config.schema import MaskConfig, PanelConfig, ToolpathConfig
from tattotronix.errors import TattotronixError
from tattotronix.path.order import original_order
from tattotronix.path.params import ToolpathParams
from tattotronix.path.path3d import build_path_flat
from tattotronix.path.plan import Toolpath, plan_toolpath
from tattotronix.path.polyline import close, length_mm, resample, smooth_closed, stations
from tattotronix.path.regions import boundary_coverage, find_regions
from tattotronix.path.strokes import StrokeKind
from tattotronix.path.timing import measure

ROOT = Path(__file__).resolve().parents[1]
RES = 0.25


def default_params(**changes: object) -> ToolpathParams:
    """Parameters from the config schema's defaults (the one source of the numbers)."""
    params = ToolpathParams.from_settings(ToolpathConfig(), MaskConfig(), PanelConfig())
    return dataclasses.replace(params, **changes)


# ------------------------------------ tracer self-test (docs/original.md, "2.10 Tracer self-test")

_XS = np.arange(-20, 20, RES)
_YS = _XS[::-1].copy()
_X, _Y = np.meshgrid(_XS, _YS)
_R = np.hypot(_X, _Y)
_BOX = (np.abs(_X) <= 10) & (np.abs(_Y) <= 14)
_BARS = np.abs(np.abs(_Y) - 7) < 3
SHAPES = {
    "disc": (_R <= 15, 1),
    "annulus": ((_R >= 8) & (_R <= 15), 2),
    "C": ((_R >= 8) & (_R <= 15) & ~((_X > 0) & (np.abs(_Y) < 4)), 1),
    "E": (_BOX & ~((_X > -5) & _BARS), 1),
    "B": (_BOX & ~((np.abs(_X) < 5) & _BARS), 3),
}


@pytest.mark.parametrize("name", list(SHAPES))
def test_tracer_selftest(name: str) -> None:
    ink, loops_expected = SHAPES[name]
    params = default_params()
    labels, regions = find_regions(ink, RES, params.min_region_mm2, params.min_loop_px)
    assert len(regions) == 1
    region = regions[0]
    loops = region.loops
    assert len(loops) == loops_expected
    for loop in loops:  # closed: last pixel 8-adjacent to the first
        assert np.abs(loop[0] - loop[-1]).max() <= 1
        assert np.abs(np.diff(loop, axis=0)).max() <= 1
    mask = labels == region.label
    assert boundary_coverage(mask, loops) > 0.999
    # holes are the 4-connected background components the region encloses
    background, count = ndimage.label(np.pad(~mask, 1))
    assert region.hole_count == count - 1 == loops_expected - 1


def test_annulus_perimeters() -> None:
    """Smoothed, resampled loops within 2 % of 2 pi 15 and 2 pi 8 (original: 93.72, 50.98)."""
    ink, _ = SHAPES["annulus"]
    params = default_params()
    _, (region,) = find_regions(ink, RES, params.min_region_mm2, params.min_loop_px)
    perimeters = []
    for loop in region.loops:
        pts = np.column_stack([_XS[loop[:, 1]], _YS[loop[:, 0]]])
        perimeters.append(length_mm(resample(close(smooth_closed(pts)), params.step_mm)))
    outer, inner = sorted(perimeters, reverse=True)
    assert outer == pytest.approx(2 * math.pi * 15, rel=0.02)
    assert inner == pytest.approx(2 * math.pi * 8, rel=0.02)


# ----------------------------------------------------------------- polylines


def test_resample_keeps_end_and_step() -> None:
    square = close(np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]))
    out = resample(square, 0.15)
    assert np.array_equal(out[0], out[-1])  # a closed outline stays closed
    st = stations(4.0, 0.15)
    assert np.allclose(np.diff(st)[:-1], 0.15, atol=1e-12)
    assert 0 < np.diff(st)[-1] <= 0.15
    assert len(out) == len(st)
    line = resample(np.array([[0.0, 0.0], [0.3, 0.0]]), 0.15)  # an exact multiple
    assert np.allclose(np.diff(line[:, 0]), 0.15) and line[-1, 0] == 0.3
    short = resample(np.array([[0.0, 0.0], [0.1, 0.0]]), 0.15)
    assert len(short) == 2 and short[-1, 0] == 0.1


def test_hatch_at_exact_pitch() -> None:
    ink = np.zeros((200, 200), bool)
    ink[20:180, 20:180] = True
    mask = InkMask.centred(ink, RES)
    tp = plan_toolpath(mask, default_params())
    fills = [s for s in tp.drawing.strokes if s.kind == StrokeKind.FILL]
    ys = np.unique([s.path_mm[0, 1] for s in fills])
    assert np.allclose(np.diff(ys), default_params().pitch_mm)  # 1.2 mm, not 1.25


# ----------------------------------------------------------------- ordering


def multi_region_mask() -> InkMask:
    """Rings, bars and dots scattered so that left-to-right order zigzags."""
    h, w = 320, 560
    yy, xx = np.mgrid[0:h, 0:w]
    ink = np.zeros((h, w), bool)
    rng = np.random.default_rng(7)
    for cx in range(40, w - 40, 70):
        for cy in (60, 160, 260):
            kind = rng.integers(3)
            r = np.hypot(xx - cx, yy - cy)
            if kind == 0:
                ink |= (r <= 28) & (r >= 14)
            elif kind == 1:
                ink |= (np.abs(xx - cx) <= 26) & (np.abs(yy - cy) <= 10)
            else:
                ink |= r <= 18
    return InkMask.centred(ink, RES)


@pytest.fixture(scope="module")
def multi() -> Toolpath:
    """The planned toolpath of :func:`multi_region_mask` at the default parameters."""
    return plan_toolpath(multi_region_mask(), default_params())


def test_ordering_beats_original_rule(multi: Toolpath) -> None:
    tp = multi
    ours, orig = tp.metrics, tp.original
    assert ours.travel_mm < orig.travel_mm
    assert ours.entries <= orig.entries
    assert ours.time_s < orig.time_s
    assert not tp.ordering.kept_original
    # every stroke exactly once, reversal used
    seq = tp.order.sequence
    assert np.array_equal(np.sort(seq), np.arange(len(tp.drawing.strokes)))
    assert tp.ordering.reversed > 0
    # the path visits the strokes in order, each as one block
    assert np.all(np.diff(tp.path.stroke) >= 0)
    assert np.array_equal(np.unique(tp.path.stroke), np.arange(len(seq)))
    # outlines before fill within each region
    kinds, regions = tp.drawing.kinds[seq], tp.drawing.region_of[seq]
    for r in range(tp.drawing.regions):
        pos = np.flatnonzero(regions == r)
        outline = pos[kinds[pos] != StrokeKind.FILL]
        fill = pos[kinds[pos] == StrokeKind.FILL]
        assert outline.max() < fill.min()


def test_builtin_artwork_ordering_beats_original_rule() -> None:
    """Acceptance: on the built-in artwork, less travel and no more entries."""
    from tattotronix.art.artwork import load_artwork
    from tattotronix.art.mask import make_mask

    mcfg = MaskConfig()
    art = load_artwork(None, mcfg.width_mm, mcfg.res_mm, 40_000_000,
                       default_width_mm=mcfg.default_width_mm)
    mask, _ = make_mask(art.grey, mcfg.res_mm, mcfg.method, mcfg.min_region_mm2)
    tp = plan_toolpath(mask, default_params())
    assert tp.metrics.travel_mm < tp.original.travel_mm
    assert tp.metrics.entries <= tp.original.entries
    assert tp.metrics.time_s < tp.original.time_s


def test_ordering_objective_is_planned_time(multi: Toolpath) -> None:
    """Planned time = marking of the strokes + the ordering's between-stroke cost + ends,
    with straight jogs between the fill rows (the round turns only shorten it)."""
    params, tp = default_params(), multi
    strokes = tp.order.points(tp.drawing, params.step_mm)
    marking = sum(length_mm(p) for p in strokes) / params.feed_mark_mm_s
    first_entry = (params.clearance_mm - params.approach_z_mm) / params.feed_travel_mm_s + (
        params.approach_mm / params.feed_mark_mm_s
    )
    last_retract = (params.clearance_mm + params.plunge_mm) / params.feed_travel_mm_s
    expected = marking + tp.ordering.cost_s + first_entry + last_retract
    on_ink = tp.drawing.drag_mask or multi_region_mask()
    straight = build_path_flat(*tp.order.resampled(tp.drawing, params.step_mm), on_ink, params)
    assert measure(straight, params).time_s == pytest.approx(expected, rel=1e-9)
    assert tp.metrics.time_s <= expected * (1 + 1e-9)
    assert tp.t_s[-1] == pytest.approx(tp.metrics.time_s)
    assert np.all(np.diff(tp.t_s) > 0)


def test_original_order_is_the_reference_rule(multi: Toolpath) -> None:
    mask, params, tp = multi_region_mask(), default_params(), multi
    order = original_order(tp.drawing)
    regions = tp.drawing.region_of[order.sequence]
    assert np.all(np.diff(regions) >= 0)  # region by region, left to right
    means = [mask.xs[np.nonzero(lab)[1]].mean() for lab in _region_masks(mask, params)]
    assert means == sorted(means)


def _region_masks(mask: InkMask, params: ToolpathParams) -> list[np.ndarray]:
    labels, regions = find_regions(mask.ink, RES, params.min_region_mm2, params.min_loop_px)
    return [labels == r.label for r in regions]


def test_path_kinds_and_lifts(multi: Toolpath) -> None:
    params, tp = default_params(), multi
    uvz, kind = tp.path.uvz_mm, tp.path.kind
    assert np.all(uvz[kind == 1, 2] == -params.plunge_mm)
    assert np.all(uvz[kind == 2, 2] == -params.plunge_mm)
    assert set(np.unique(uvz[kind == 0, 2])) <= {params.clearance_mm, params.approach_z_mm}
    assert uvz[0, 2] == params.clearance_mm and uvz[-1, 2] == params.clearance_mm
    # every entry is (p, clearance) -> (p, approach start) -> (p, depth)
    entries = np.flatnonzero((kind[:-1] == 0) & (kind[1:] != 0)) + 1
    assert len(entries) == tp.metrics.entries
    assert np.all(kind[entries] == 2)
    assert np.allclose(uvz[entries - 1, :2], uvz[entries, :2])
    assert np.allclose(uvz[entries - 2, :2], uvz[entries, :2])
    # arm frame: the drawing centre on the panel origin
    assert np.allclose(tp.xyz_m, np.asarray(params.panel_origin_m) + uvz / 1000.0)


# ----------------------------------------------------------------- refusals


def test_drawing_larger_than_panel_is_refused() -> None:
    """The ink is what must fit: 210 mm of it is refused; 150 mm of ink on a 210 mm wide
    canvas (blank margins) is drawn."""
    ink = np.zeros((200, 840), bool)  # 210 x 50 mm at 0.25 mm
    ink[50:150, :] = True
    with pytest.raises(TattotronixError, match=r"210\.0 x 25\.0 mm of ink.*200 x 140 mm panel"):
        plan_toolpath(InkMask.centred(ink, RES), default_params())
    ink[:, :100] = ink[:, 700:] = False
    assert plan_toolpath(InkMask.centred(ink, RES), default_params()).metrics.entries >= 1


@pytest.mark.parametrize("pitch", [0.0, -1.2, float("nan")])
def test_bad_pitch_is_refused(pitch: float) -> None:
    with pytest.raises(TattotronixError, match=r"toolpath\.pitch_mm must be > 0"):
        default_params(pitch_mm=pitch)


def test_bad_approach_is_refused() -> None:
    with pytest.raises(TattotronixError, match=r"toolpath\.approach_mm"):
        default_params(approach_mm=20.0)


def test_empty_mask_is_refused() -> None:
    ink = np.zeros((100, 100), bool)
    ink[10:12, 10:12] = True  # 0.25 mm^2, under min_region_mm2
    with pytest.raises(TattotronixError, match="nothing to draw"):
        plan_toolpath(InkMask.centred(ink, RES), default_params())


# ----------------------------------------------------------------- the stage


def _run_stage(data: Path, *overrides: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "stages/toolpath.py", f"paths.data={data}", "artwork.name=test",
         *overrides],
        cwd=ROOT, capture_output=True, text=True, timeout=300,
    )


def test_stage_end_to_end(tmp_path: Path) -> None:
    (tmp_path / "mask").mkdir()
    multi_region_mask().save(tmp_path / "mask" / "test.npz")
    res = _run_stage(tmp_path)
    assert res.returncode == 0, res.stderr
    with np.load(tmp_path / "toolpath" / "test.npz", allow_pickle=False) as z:
        n = len(z["kind"])
        assert z["uvz_mm"].shape == (n, 3) and z["xyz_m"].shape == (n, 3)
        assert z["kind"].dtype == np.int8
        assert z["stroke"].shape == (n,) and z["t_s"].shape == (n,)
        assert len(z["stroke_kind"]) == z["stroke"].max() + 1
    metrics = json.loads((tmp_path / "metrics" / "toolpath" / "test.json").read_text())
    for key in ("points", "marked_mm", "travel_mm", "entries", "regions", "holes", "time_s"):
        assert key in metrics and key in metrics["original_order"]
    assert metrics["points"] == n
    png = tmp_path / "figures" / "test" / "toolpath.png"
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    leftovers = [p for p in tmp_path.rglob("*") if ".tmp" in p.name]
    assert not leftovers


def test_stage_missing_mask_names_the_mask_stage(tmp_path: Path) -> None:
    res = _run_stage(tmp_path)
    assert res.returncode == 2
    assert "'mask' stage" in res.stderr
    assert len(res.stderr.strip().splitlines()) == 1


def test_stage_bad_pitch_leaves_nothing(tmp_path: Path) -> None:
    (tmp_path / "mask").mkdir()
    multi_region_mask().save(tmp_path / "mask" / "test.npz")
    res = _run_stage(tmp_path, "toolpath.pitch_mm=0")
    assert res.returncode == 2
    assert "toolpath.pitch_mm must be >= 0.05 and <= 100 mm (got 0)" in res.stderr
    assert len(res.stderr.strip().splitlines()) == 1
    assert sorted(p.name for p in tmp_path.rglob("*")) == ["mask", "test.npz"]


def test_stage_too_large_leaves_nothing(tmp_path: Path) -> None:
    (tmp_path / "mask").mkdir()
    ink = np.zeros((200, 840), bool)
    ink[50:150, :] = True
    InkMask.centred(ink, RES).save(tmp_path / "mask" / "test.npz")
    res = _run_stage(tmp_path)
    assert res.returncode == 2
    assert "210.0 x 25.0 mm of ink" in res.stderr
    assert sorted(p.name for p in tmp_path.rglob("*")) == ["mask", "test.npz"]
