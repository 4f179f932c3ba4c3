"""The drawing's size and grid pitch from the artwork itself (tattotronix/art/sizing.py):
an SVG's physical size, and thin strokes never thresholded into dashes."""

from __future__ import annotations

import json
import logging
import math
from pathlib import Path

import numpy as np
import pytest

from tattotronix.art.artwork import (
    ArtworkGrid,
    artwork_grid,
    load_artwork,
    svg_physical_width_mm,
)
from tattotronix.art.sizing import (
    PITCH_LADDER,
    Stroke,
    drawing_width_mm,
    grid_pitch_mm,
)
from tattotronix.config.schema import MaskConfig
from tattotronix.errors import TattotronixError

MASK = MaskConfig()
MAX_PX = 100_000_000


def _waves(tmp_path: Path, widths: tuple[float, ...], size: str = 'width="120mm" '
           'height="60mm"') -> Path:
    """Stroked sine waves, one per width (user units are mm at the SVG's own size)."""
    rows = []
    for i, w in enumerate(widths):
        y = 10 + 12 * i
        pts = " ".join(f"{x:.2f},{y + 3 * math.sin(x / 5):.3f}" for x in np.arange(5, 115, 0.5))
        rows.append(f'<polyline id="wave{i}" points="{pts}" stroke-width="{w}"/>')
    svg = tmp_path / "waves.svg"
    svg.write_text(f'<svg xmlns="http://www.w3.org/2000/svg" {size} viewBox="0 0 120 60">'
                   f'<g fill="none" stroke="black">{"".join(rows)}</g></svg>')
    return svg


def _load(svg: Path, width_mm: float | None = None, min_line_px: float = MASK.min_line_px):
    return load_artwork(svg, width_mm, MASK.res_mm, MAX_PX, default_width_mm=MASK.default_width_mm,
                        min_line_px=min_line_px)


def _line_shares(svg: Path, *overrides: str) -> tuple[float, np.ndarray]:
    """Plan the SVG at the defaults (plus ``overrides``): the grid pitch, and each stroked
    line's share of its length the needle passes along."""
    from tattotronix.app.pipeline import mask_of
    from tattotronix.art.artwork import read_svg, svg_intrinsic_size
    from tattotronix.art.vector import svg_lines
    from tattotronix.config.params import compose_settings
    from tattotronix.path.linecover import line_coverage
    from tattotronix.path.params import ToolpathParams
    from tattotronix.path.plan import plan_toolpath

    cfg = compose_settings([f"artwork.source={svg}", *overrides])
    mask = mask_of(cfg, svg, "waves")
    tp = plan_toolpath(mask, ToolpathParams.from_settings(cfg.toolpath, cfg.mask, cfg.robot.panel))
    lines = svg_lines(svg, svg_intrinsic_size(read_svg(svg)), mask.ink.shape, mask.res_mm, 0.05)
    marking = tp.path.uvz_mm[tp.path.kind == 1, :2]
    return mask.res_mm, line_coverage(lines.paths, lines.widths_mm, marking,
                                      cfg.toolpath.needle_width_mm, cfg.toolpath.step_mm)


def test_an_svg_with_a_physical_size_is_drawn_at_it_unless_a_width_is_set(tmp_path):
    svg = _waves(tmp_path, (1.0,))
    assert _load(svg).size_mm[0] == pytest.approx(120.0)
    assert _load(svg, width_mm=60.0).size_mm[0] == pytest.approx(60.0)
    for size, mm in (('width="12cm" height="6cm"', 120.0), ('width="4in" height="2in"', 101.6),
                     ('width="120" height="60"', MASK.default_width_mm),
                     ('width="100%" height="100%"', MASK.default_width_mm)):
        drawn = _load(_waves(tmp_path, (1.0,), size)).size_mm[0]
        assert drawn == pytest.approx(mm, abs=MASK.res_mm), size


def test_thin_strokes_at_the_default_resolution_are_whole_lines_not_dashes(tmp_path):
    """The issue's dashes: 0.5 to 0.65 mm lines at 0.25 mm/px were planned as dashes (23
    to 45 % of each line). With the pitch chosen from the thinnest stroke the needle
    passes along every whole line. Since a core too small to outline is line art and a
    line runs on through its corners, even the coarse grid (refinement off) draws them
    whole: measured 0.999 of the worst line, where it was under 0.8."""
    svg = _waves(tmp_path, (0.5, 0.65))
    res, coarse = _line_shares(svg, "mask.min_line_px=0")
    assert res == MASK.res_mm and coarse.min() >= 0.95, coarse

    res, shares = _line_shares(svg)
    assert res < MASK.res_mm and 0.5 / res >= MASK.min_line_px
    assert shares.min() >= 0.95, shares


def test_the_pitch_is_the_coarsest_of_the_ladder_that_gives_the_thinnest_line_its_pixels(
        caplog):
    assert grid_pitch_mm(0.25, None, 3) == 0.25
    assert grid_pitch_mm(0.25, Stroke("<path>", 0.8), 3) == 0.25  # 3.2 px: kept
    assert grid_pitch_mm(0.25, Stroke("<path>", 0.5), 0) == 0.25  # refinement off
    with caplog.at_level(logging.INFO, logger="tattotronix.art.sizing"):
        assert grid_pitch_mm(0.25, Stroke('<polyline id="w">', 0.5), 3) == 0.125
    assert '<polyline id="w">' in caplog.text
    assert grid_pitch_mm(0.25, Stroke("<path>", 0.65), 3) == 0.2
    assert grid_pitch_mm(0.1, Stroke("<path>", 0.3), 3) == 0.1  # never coarser than res_mm
    for width in np.linspace(0.07, 2.0, 40):
        pitch = grid_pitch_mm(0.25, Stroke("<path>", float(width)), 3)
        assert pitch <= 0.25 and pitch in (0.25, *PITCH_LADDER)
        assert width / pitch >= 3 - 1e-9
        coarser = [p for p in PITCH_LADDER if pitch < p <= 0.25]
        assert all(width / p < 3 for p in coarser)
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="tattotronix.art.sizing"):
        assert grid_pitch_mm(0.25, Stroke('<line id="hair">', 0.01), 3) == PITCH_LADDER[-1]
    assert 'hair' in caplog.text and "spans 0.5 px" in caplog.text


def test_physical_width_and_the_fallbacks():
    def own(width: str | None) -> float | None:
        attr = "" if width is None else f' width="{width}"'
        return svg_physical_width_mm(f'<svg xmlns="http://www.w3.org/2000/svg"{attr}/>')

    for width in ("25.4mm", "2.54cm", "1in", "72pt", "6pc"):
        assert own(width) == pytest.approx(25.4), width
    for other in (None, "100", "100px", "50%", "wide", "-3mm"):
        assert own(other) is None, other
    assert drawing_width_mm(80.0, 150.0, 10.0) == 80.0
    assert drawing_width_mm(None, 150.0, 10.0) == 10.0
    assert drawing_width_mm(None, 150.0, None) == 150.0
    with pytest.raises(TattotronixError, match="set mask.width_mm"):
        drawing_width_mm(None, None, None)


def test_the_mask_reads_the_grid_the_artwork_stage_chose(tmp_path):
    metrics = tmp_path / "art.json"
    metrics.write_text(json.dumps({"res_mm": 0.125, "raster_px": [960, 480]}))
    assert artwork_grid(metrics, (480, 960)) == ArtworkGrid(0.125, transparent=False)
    metrics.write_text(json.dumps({"res_mm": 0.125, "raster_px": [960, 480],
                                   "transparent": True}))
    assert artwork_grid(metrics, (480, 960)).transparent
    with pytest.raises(TattotronixError, match="re-run the 'artwork' stage"):
        artwork_grid(metrics, (240, 480))
    metrics.write_text("{")
    with pytest.raises(TattotronixError, match="cannot read the artwork's grid"):
        artwork_grid(metrics, (480, 960))


def test_strokes_over_half_a_transparent_canvas_are_the_ink_not_the_gaps(tmp_path):
    """A 10,000-path SVG whose strokes cover most of its (transparent) canvas was inverted,
    as light art on a dark field is: the mask drew the gaps between the strokes, and the
    vector lines (the strokes) measured as bleed. A transparent canvas is never inverted;
    an opaque dark field still is."""
    from tattotronix.app.pipeline import mask_of
    from tattotronix.config.params import compose_settings

    def bars(width: float) -> str:
        return "".join(f'<rect x="{x}" y="2" width="{width}" height="36"/>'
                       for x in range(2, 60, 4))

    # black bars over 3/4 of a transparent canvas; white bars on an opaque dark field
    for body in (f'<g fill="black">{bars(3)}</g>',
                 f'<rect width="60" height="40" fill="#222"/><g fill="white">{bars(1)}</g>'):
        svg = tmp_path / "bars.svg"
        svg.write_text(f'<svg xmlns="http://www.w3.org/2000/svg" width="60mm" height="40mm" '
                       f'viewBox="0 0 60 40">{body}</svg>')
        ink = mask_of(compose_settings([f"artwork.source={svg}"]), svg, "bars").ink
        h, w = ink.shape
        assert ink[h // 2, round(2.5 / 60 * w)], body  # the first bar is the ink
        assert not ink[h // 2, round(5.5 / 60 * w)], body  # the first gap is not
