"""The mask stage: Otsu with the minority rule, edges, regions, holes, and the stage itself."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from PIL import Image

from tattotronix.art.artwork import load_artwork
from tattotronix.art.grid import InkMask
from tattotronix.art.mask import (
    ALLOWED_METHODS,
    MaskMethodError,
    NoInkError,
    count_holes,
    make_mask,
)
from tattotronix.config.schema import MaskConfig, MaskMethod
from tattotronix.errors import TattotronixError

ROOT = Path(__file__).resolve().parents[1]
MASK = MaskConfig()
RES = MASK.res_mm
METHODS = [m.value for m in MaskMethod]


def _mask(grey: np.ndarray, method: str, min_region_mm2: float = MASK.min_region_mm2,
          res_mm: float = RES):
    return make_mask(grey, res_mm, method, min_region_mm2, MASK.edge_sigma_px, MASK.edge_k)


def _rect_file(tmp_path: Path, invert: bool = False) -> Path:
    """300 x 200 px, white with a black 140 x 80 rectangle (or the negative)."""
    a = np.full((200, 300), 255, np.uint8)
    a[60:140, 80:220] = 0
    if invert:
        a = 255 - a
    p = tmp_path / ("neg.png" if invert else "rect.png")
    Image.fromarray(a).save(p)
    return p


# ----------------------------------------------------------------------------- methods


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("invert", [False, True], ids=["black_on_white", "white_on_black"])
def test_rectangle_100mm_both_methods_and_polarities(
    tmp_path: Path, method: str, invert: bool
) -> None:
    art = load_artwork(_rect_file(tmp_path, invert), 100.0, RES, 10**7)
    mask, stats = _mask(art.grey, method)
    ink = mask.ink
    assert 0 < ink.sum() < ink.size
    assert ink.mean() < 0.5
    assert stats.width_mm == pytest.approx(100.0, abs=1.0)
    assert mask.xs[-1] - mask.xs[0] + mask.res_mm == pytest.approx(100.0, abs=1.0)
    assert np.all(np.diff(mask.xs) > 0) and np.all(np.diff(mask.ys) < 0)
    if method == "threshold":
        # the rectangle is the ink whatever the field: 140 x 80 of 300 x 200 px
        assert stats.ink_pct == pytest.approx(100 * 140 * 80 / (300 * 200), abs=1.0)
        assert stats.inverted is invert
        assert (stats.regions, stats.holes) == (1, 0)
    else:
        # the rectangle's outline: one region around one hole
        assert (stats.regions, stats.holes) == (1, 1)


def _scene(data, h: int, w: int) -> tuple[np.ndarray, np.ndarray]:
    """Random rectangles and discs covering well under half the field."""
    shapes = np.zeros((h, w), bool)
    yy, xx = np.mgrid[0:h, 0:w]
    for _ in range(data.draw(st.integers(1, 4))):
        if data.draw(st.booleans()):
            r = data.draw(st.integers(6, 18))
            cy, cx = data.draw(st.integers(r, h - r - 1)), data.draw(st.integers(r, w - r - 1))
            shapes |= (yy - cy) ** 2 + (xx - cx) ** 2 <= r * r
        else:
            rh, rw = data.draw(st.integers(8, 30)), data.draw(st.integers(8, 30))
            y0, x0 = data.draw(st.integers(0, h - rh)), data.draw(st.integers(0, w - rw))
            shapes[y0:y0 + rh, x0:x0 + rw] = True
    return shapes, np.where(shapes, 0.0, 255.0)


@settings(max_examples=40, deadline=None)
@given(data=st.data(), invert=st.booleans(), ink_level=st.integers(0, 90),
       paper_level=st.integers(170, 255))
def test_threshold_polarity_property(data, invert: bool, ink_level: int,
                                     paper_level: int) -> None:
    h, w = 120, 160
    shapes, _ = _scene(data, h, w)
    if shapes.mean() >= 0.45:
        return
    grey = np.where(shapes, float(ink_level), float(paper_level))
    if invert:
        grey = 255.0 - grey
    mask, stats = _mask(grey, "threshold", min_region_mm2=0.0)
    assert mask.ink.mean() < 0.5
    np.testing.assert_array_equal(mask.ink, shapes)  # the shapes are the ink either way
    assert stats.inverted is invert


@settings(max_examples=25, deadline=None)
@given(data=st.data(), invert=st.booleans())
def test_edges_polarity_property(data, invert: bool) -> None:
    shapes, grey = _scene(data, 120, 160)
    if invert:
        grey = 255.0 - grey
    mask, _ = _mask(grey, "edges", min_region_mm2=0.0)
    assert 0.0 < mask.ink.mean() < 0.5
    # the ink follows the shapes' boundaries: all of it within 3 sigma + 1 px of one
    s8 = shapes.astype(np.uint8)
    cross = cv2.getStructuringElement(cv2.MORPH_CROSS, (3, 3))
    boundary = (s8 - cv2.erode(s8, cross, borderType=cv2.BORDER_REPLICATE)).astype(bool) | (
        cv2.dilate(s8, cross, borderType=cv2.BORDER_REPLICATE) - s8
    ).astype(bool)
    reach = 2 * round(3 * MASK.edge_sigma_px + 1) + 1
    near = cv2.dilate(boundary.astype(np.uint8), np.ones((reach, reach), np.uint8)) > 0
    assert near[mask.ink].all()


# ----------------------------------------------------------------------------- regions, holes


def test_regions_are_8_connected_and_small_ones_dropped() -> None:
    ink = np.zeros((80, 80), bool)
    ink[10:30, 10:30] = True
    ink[30:50, 30:50] = True  # touches the first only at a corner: same region
    ink[60:66, 60:66] = True  # 36 px = 2.25 mm^2 < 4 mm^2: dropped
    grey = np.where(ink, 0.0, 255.0)
    mask, stats = _mask(grey, "threshold")
    assert (stats.regions, stats.dropped_regions) == (1, 1)
    assert not mask.ink[60:66, 60:66].any()
    assert stats.smallest_region_mm2 == pytest.approx(800 * RES**2)


def test_a_dropped_region_is_named_in_one_line(caplog: pytest.LogCaptureFixture) -> None:
    """Small regions are left out (the original's rule, against a raster's noise), but a
    logo's dot is drawing: flat art (threshold) warns in one line with the count, the area,
    the largest and where it is, and the setting; a photograph's edges only inform."""
    ink = np.zeros((80, 80), bool)
    ink[10:50, 10:50] = True
    ink[60:66, 60:66] = True  # 2.25 mm^2
    ink[70:73, 10:13] = True  # 0.56 mm^2
    grey = np.where(ink, 0.0, 255.0)
    with caplog.at_level("INFO", logger="tattotronix.art.mask"):
        mask, _ = _mask(grey, "threshold")
    said = [r for r in caplog.records if "left out" in r.getMessage()]
    assert len(said) == 1 and said[0].levelname == "WARNING", caplog.text
    u = float(mask.xs[62:64].mean())
    v = float(mask.ys[62:64].mean())
    assert said[0].getMessage() == (
        "mask: 2 ink region(s) smaller than mask.min_region_mm2=4 mm^2 are left out, 2.81 "
        f"mm^2 in all (the largest 2.25 mm^2, at panel ({u:.1f}, {v:.1f}) mm): lower "
        "mask.min_region_mm2 to draw them")
    caplog.clear()
    with caplog.at_level("INFO", logger="tattotronix.art.mask"):
        _mask(grey, "threshold", min_region_mm2=0.5)
    assert not any("left out" in r.getMessage() for r in caplog.records)
    caplog.clear()
    with caplog.at_level("INFO", logger="tattotronix.art.mask"):
        _mask(grey, "edges")
    assert all(r.levelname == "INFO" for r in caplog.records if "left out" in r.getMessage())


def test_holes_use_4_connected_background() -> None:
    ring = np.zeros((40, 40), bool)
    ring[10:30, 10:30] = True
    ring[13:27, 13:27] = False
    assert count_holes(ring) == 1
    two = np.zeros((30, 60), bool)
    two[5:25, 5:25] = True
    two[10:20, 10:20] = False
    two[5:25, 35:55] = True
    two[8:12, 38:42] = False
    two[15:20, 45:50] = False
    assert count_holes(two) == 3
    assert count_holes(np.zeros((5, 5), bool)) == 0


def test_diagonal_gap_does_not_open_a_hole() -> None:
    # a diamond drawn with 8-connected (diagonal) steps: its inside is a hole
    ink = np.zeros((21, 21), bool)
    for i in range(10):
        for r, c in ((i, 10 + i), (10 + i, 20 - i), (20 - i, 10 - i), (10 - i, i)):
            ink[r, c] = True
    assert count_holes(ink) == 1


def test_size_in_mm_is_reported_for_a_drawing_larger_than_the_panel() -> None:
    grey = np.full((4, 1000), 255.0)
    grey[1:3, 100:900] = 0.0
    _, stats = _mask(grey, "threshold", min_region_mm2=0.0)
    assert stats.width_mm == pytest.approx(250.0) and stats.height_mm == pytest.approx(1.0)


# ----------------------------------------------------------------------------- errors


def test_unknown_method_lists_the_allowed_values() -> None:
    with pytest.raises(MaskMethodError) as info:
        _mask(np.zeros((10, 10)), "foo")
    assert isinstance(info.value, ValueError) and isinstance(info.value, TattotronixError)
    for name in ALLOWED_METHODS:
        assert name in str(info.value)
    assert set(ALLOWED_METHODS) == set(METHODS)


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("level", [0.0, 255.0])
def test_flat_image_has_no_drawable_ink(method: str, level: float) -> None:
    with pytest.raises(NoInkError, match="no drawable ink"):
        _mask(np.full((50, 60), level), method)


def test_specks_only_have_no_drawable_ink() -> None:
    grey = np.full((100, 100), 255.0)
    grey[10:12, 10:12] = 0.0
    grey[50:53, 70:73] = 0.0
    with pytest.raises(NoInkError, match="min_region_mm2"):
        _mask(grey, "threshold")


# ----------------------------------------------------------------------------- stage


def _run(*args: str) -> subprocess.CompletedProcess:
    env = dict(os.environ)
    env.pop("DVC_STAGE", None)
    return subprocess.run([sys.executable, *args], cwd=ROOT, env=env, text=True,
                          capture_output=True, timeout=120)


def test_stages_end_to_end_on_the_builtin(tmp_path: Path) -> None:
    data = f"paths.data={tmp_path}"
    missing = _run("stages/mask.py", data)
    assert missing.returncode == 2 and "'artwork'" in missing.stderr
    assert [p for p in tmp_path.rglob("*") if p.is_file()] == []

    art = _run("stages/artwork.py", data)
    assert art.returncode == 0, art.stderr
    raster = tmp_path / "artwork" / "emblem.png"
    with Image.open(raster) as im:
        assert im.mode == "L" and im.size == (round(MASK.default_width_mm / RES), 352)
    art_metrics = json.loads((tmp_path / "metrics" / "artwork" / "emblem.json").read_text())
    assert art_metrics["kind"] == "svg" and art_metrics["source"] == "builtin:emblem"
    assert art_metrics["width_mm"] == pytest.approx(MASK.default_width_mm)
    assert 0.05 < art_metrics["ink_fraction"] < 0.25

    run = _run("stages/mask.py", data)
    assert run.returncode == 0, run.stderr
    mask = InkMask.load(tmp_path / "mask" / "emblem.npz")
    assert mask.ink.shape == (352, 600) and mask.res_mm == RES
    with Image.open(tmp_path / "mask" / "emblem.png") as im:
        preview = np.asarray(im)
    np.testing.assert_array_equal(preview == 0, mask.ink)  # ink black on white
    m = json.loads((tmp_path / "metrics" / "mask" / "emblem.json").read_text())
    assert m["method"] == "threshold" and m["res_mm"] == RES
    assert m["width_mm"] == pytest.approx(150.0) and m["height_mm"] == pytest.approx(88.0)
    assert m["ink_pct"] == pytest.approx(100 * mask.ink.mean())
    assert m["regions"] >= 25 and m["holes"] >= 6
    assert not list(tmp_path.rglob(".*tmp*"))  # no temporaries left


def test_stage_rejects_an_unknown_method(tmp_path: Path) -> None:
    run = _run("stages/mask.py", "mask.method=foo", f"paths.data={tmp_path}")
    assert run.returncode != 0
    assert "mask.method" in run.stderr
    for name in METHODS:
        assert name in run.stderr
