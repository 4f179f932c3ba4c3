"""artwork.vector: an SVG's stroked lines are where the renderer draws them, under every
transform (issue 30: nothing of the artwork lost or invented); what cannot be taken as a
vector is left to the mask and logged; ``<text>`` is drawn, never silently dropped."""

from __future__ import annotations

import logging
import math
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest
from numpy.typing import NDArray

from tattotronix.art.artwork import load_artwork
from tattotronix.art.mask import otsu_ink
from tattotronix.art.vector import VectorLines, artwork_lines

WIDTH_MM = 50.0  # the 100 x 100 px test canvas: 0.5 mm per CSS px
RES_MM = 0.125  # 4 grid px per CSS px
STEP_MM = 0.15
CANVAS = 100.0
VERTEX_TOL_PX = 1.5  # a vertex lies on ink or this close to it
COVER_MARGIN_PX = 1.5  # ink this far beyond half a stroke width still counts as covered
MIN_COVERED = 0.9  # of the ink pixels, within half a stroke width + the margin of a line


def _svg(body: str, defs: str = "") -> str:
    return ('<svg xmlns="http://www.w3.org/2000/svg" xmlns:xlink="http://www.w3.org/1999/xlink"'
            f' width="{CANVAS:g}" height="{CANVAS:g}"><defs>{defs}</defs>'
            f'<g fill="none" stroke="black">{body}</g></svg>')


def _load(tmp_path: Path, text: str, name: str = "art"
          ) -> tuple[NDArray[np.bool_], VectorLines]:
    """The ink mask (as the artwork stage computes it) and the vector lines of an SVG."""
    path = tmp_path / f"{name}.svg"
    path.write_text(text)
    art = load_artwork(path, WIDTH_MM, RES_MM, 10**8)
    ink, _, _ = otsu_ink(art.grey)
    return ink, artwork_lines(path, art.shape, art.res_mm, STEP_MM)


def _to_px(shape: tuple[int, int], xy: NDArray[np.float64]) -> NDArray[np.float64]:
    """Panel mm (the mask's frame) to (col, row) grid pixels."""
    h, w = shape
    x0, y0 = -w / 2 * RES_MM, (h - 1 - h / 2) * RES_MM
    return np.column_stack([(xy[:, 0] - x0) / RES_MM, (y0 - xy[:, 1]) / RES_MM])


def _vertex_off_ink_px(ink: NDArray[np.bool_], lines: VectorLines) -> float:
    """The largest distance of a vector vertex from ink, grid px."""
    dist = cv2.distanceTransform((~ink).astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
    h, w = ink.shape
    worst = 0.0
    for p in lines.paths:
        cr = np.rint(_to_px(ink.shape, p)).astype(int)
        inside = (cr[:, 0] >= 0) & (cr[:, 0] < w) & (cr[:, 1] >= 0) & (cr[:, 1] < h)
        if not inside.all():
            return math.inf
        worst = max(worst, float(dist[cr[:, 1], cr[:, 0]].max()))
    return worst


def _covered(ink: NDArray[np.bool_], lines: VectorLines) -> float:
    """The fraction of ink pixels within half a stroke width + the margin of a line."""
    band = np.zeros(ink.shape, np.uint8)
    for p, width in zip(lines.paths, lines.widths_mm, strict=True):
        pts = np.rint(_to_px(ink.shape, p) * 16).astype(np.int32).reshape(-1, 1, 2)
        thick = max(1, round(width / RES_MM + 2 * COVER_MARGIN_PX))
        cv2.polylines(band, [pts], isClosed=False, color=1, thickness=thick, shift=4)
    return float(band.astype(bool)[ink].mean())


# ----------------------------------------------------------------------------- property


def _m(a: float, b: float, c: float, d: float, e: float, f: float) -> NDArray[np.float64]:
    return np.array([[a, c, e], [b, d, f], [0.0, 0.0, 1.0]])


def _random_transform(rng: np.random.Generator) -> tuple[str, NDArray[np.float64]]:
    """An SVG transform attribute value and its matrix (moderate scale and skew)."""
    kind = rng.choice(["matrix", "rotate", "skewX", "skewY", "scale", "translate"])
    if kind == "rotate":
        a, cx, cy = rng.uniform(-180, 180), rng.uniform(20, 80), rng.uniform(20, 80)
        t = math.radians(a)
        rot = _m(math.cos(t), math.sin(t), -math.sin(t), math.cos(t), 0, 0)
        return f"rotate({a:.3f} {cx:.3f} {cy:.3f})", (
            _m(1, 0, 0, 1, cx, cy) @ rot @ _m(1, 0, 0, 1, -cx, -cy))
    if kind in ("skewX", "skewY"):
        a = rng.uniform(-20, 20)
        k = math.tan(math.radians(a))
        return f"{kind}({a:.3f})", _m(1, 0, k, 1, 0, 0) if kind == "skewX" else _m(
            1, k, 0, 1, 0, 0)
    if kind == "scale":
        s = rng.uniform(0.8, 1.25)
        r = rng.uniform(0.9, 1.1)
        return f"scale({s:.4f} {s * r:.4f})", _m(s, 0, 0, s * r, 0, 0)
    if kind == "translate":
        tx, ty = rng.uniform(-15, 15, 2)
        return f"translate({tx:.3f} {ty:.3f})", _m(1, 0, 0, 1, tx, ty)
    t = rng.uniform(-math.pi, math.pi)
    s = rng.uniform(0.8, 1.2)
    k = rng.uniform(-0.2, 0.2)
    a, b, c, d = s * math.cos(t), s * math.sin(t), -s * math.sin(t) + k, s * math.cos(t)
    e, f = rng.uniform(-10, 10, 2)
    return f"matrix({a:.5f} {b:.5f} {c:.5f} {d:.5f} {e:.4f} {f:.4f})", _m(a, b, c, d, e, f)


def _random_shape(rng: np.random.Generator) -> tuple[str, NDArray[np.float64]]:
    """A shape element (its attributes but stroke-width) centred near the canvas centre,
    and points whose hull holds it."""
    kind = rng.choice(["line", "polyline", "rect", "circle"])
    cx, cy = rng.uniform(35, 65, 2)
    if kind == "line":
        p = np.array([cx, cy]) + rng.uniform(-20, 20, (2, 2))
        return (f'<line x1="{p[0, 0]:.3f}" y1="{p[0, 1]:.3f}" x2="{p[1, 0]:.3f}" '
                f'y2="{p[1, 1]:.3f}"'), p
    if kind == "polyline":
        p = np.array([cx, cy]) + rng.uniform(-20, 20, (int(rng.integers(3, 6)), 2))
        return f'<polyline points="{" ".join(f"{x:.3f},{y:.3f}" for x, y in p)}"', p
    if kind == "rect":
        w, h = rng.uniform(8, 30, 2)
        p = np.array([[cx - w / 2, cy - h / 2], [cx + w / 2, cy + h / 2],
                      [cx - w / 2, cy + h / 2], [cx + w / 2, cy - h / 2]])
        return (f'<rect x="{cx - w / 2:.3f}" y="{cy - h / 2:.3f}" width="{w:.3f}" '
                f'height="{h:.3f}"'), p
    r = rng.uniform(5, 15)
    p = np.array([[cx - r, cy - r], [cx + r, cy + r], [cx - r, cy + r], [cx + r, cy - r]])
    return f'<circle cx="{cx:.3f}" cy="{cy:.3f}" r="{r:.3f}"', p


def _random_element(rng: np.random.Generator, k: int) -> tuple[str, str]:
    """(body, defs) text of one stroked shape under random nested transforms, some through
    ``<use>``; the whole of it on the canvas, its stroke 0.5 to 0.9 CSS px wide on the
    page."""
    while True:
        shape, pts = _random_shape(rng)
        m = np.eye(3)
        groups = []
        for _ in range(int(rng.integers(0, 3))):
            attr, g = _random_transform(rng)
            groups.append(attr)
            m = m @ g
        use = rng.random() < 0.35
        use_attr = ""
        if use:
            attr, g = _random_transform(rng)
            ux, uy = rng.uniform(-8, 8, 2)
            use_attr = f'transform="{attr}" x="{ux:.3f}" y="{uy:.3f}"'
            m = m @ g @ _m(1, 0, 0, 1, ux, uy)
        own = ""
        if rng.random() < 0.7:
            attr, g = _random_transform(rng)
            own = f' transform="{attr}"'
            m = m @ g
        page = (m @ np.vstack([pts.T, np.ones(len(pts))]))[:2].T
        sv = np.linalg.svd(m[:2, :2], compute_uv=False)
        if page.min() < 8 or page.max() > CANVAS - 8 or sv[0] > 1.6 * sv[1]:
            continue  # off the canvas, or too anisotropic a stroke: draw another
        width = rng.uniform(0.5, 0.9) / math.sqrt(abs(np.linalg.det(m[:2, :2])))
        el = f'{shape} stroke-width="{width:.4f}"{own}/>'
        defs = ""
        if use:
            defs = el.replace(shape[: shape.index(" ")], f'{shape[: shape.index(" ")]} id="s{k}"',
                              1)
            el = f'<use xlink:href="#s{k}" {use_attr}/>'
        for attr in reversed(groups):
            el = f'<g transform="{attr}">{el}</g>'
        return el, defs


@pytest.mark.parametrize("seed", range(30))
def test_vector_lines_lie_on_the_rendered_ink_under_random_transforms(
        tmp_path: Path, seed: int, caplog: pytest.LogCaptureFixture) -> None:
    """Random stroked lines, polylines, rects and circles under random nested transforms
    (matrix, rotate, skewX/Y, scale, translate, <use>): every vector vertex lies on the
    rendered ink, the lines cover the ink, and every element is taken as a vector."""
    rng = np.random.default_rng(seed)
    parts = [_random_element(rng, k) for k in range(int(rng.integers(1, 4)))]
    text = _svg("".join(b for b, _ in parts), "".join(d for _, d in parts))
    with caplog.at_level(logging.INFO, logger="tattotronix.art.vector"):
        ink, lines = _load(tmp_path, text)
    assert len(lines.paths) == len(parts), text
    assert "drawn from the mask" not in caplog.text
    assert _vertex_off_ink_px(ink, lines) <= VERTEX_TOL_PX, text
    assert _covered(ink, lines) >= MIN_COVERED, text
    # the stroke widths are the transformed ones: 0.5 to 0.9 CSS px = 0.25 to 0.45 mm,
    # within the spread a skew or unequal scale gives across the directions
    assert np.all((lines.widths_mm > 0.25 / 1.6) & (lines.widths_mm < 0.45 * 1.6)), text


# ----------------------------------------------------------------------------- regressions


def test_rotated_rect_is_drawn_where_rendered(tmp_path: Path) -> None:
    """A rotated <rect> (svgelements keeps its rotation in .transform; the untransformed
    coordinates put it 36.6 mm off at 100 mm wide): its corners are the rotated ones."""
    text = _svg('<rect x="30" y="30" width="40" height="25" stroke-width="0.8" '
                'transform="rotate(30 50 50)"/>')
    ink, lines = _load(tmp_path, text)
    assert len(lines.paths) == 1
    assert _vertex_off_ink_px(ink, lines) <= 1.0
    assert _covered(ink, lines) >= 0.97
    t = math.radians(30)
    corners = np.array([[30, 30], [70, 30], [70, 55], [30, 55]], dtype=float) - 50
    rotated = corners @ np.array([[math.cos(t), math.sin(t)], [-math.sin(t), math.cos(t)]]) + 50
    # CSS px to panel mm: 0.5 mm per px, y up, about the grid's centre pixel convention
    expect = np.column_stack([(rotated[:, 0] - 50) * 0.5 - RES_MM / 2,
                              (50 - rotated[:, 1]) * 0.5 - RES_MM / 2])
    got = lines.paths[0]
    for c in expect:
        assert np.min(np.hypot(*(got - c).T)) < 1e-6
    assert lines.widths_mm[0] == pytest.approx(0.4)


def test_skewed_path_follows_the_skew(tmp_path: Path) -> None:
    """A skewX path: its vertices are the skewed ones, and its stroke width across each
    segment is the skewed width (the vertical leg thins by cos 30 deg)."""
    text = _svg('<path d="M 10 40 L 40 40 L 40 80" stroke-width="0.8" '
                'transform="skewX(30)"/>')
    ink, lines = _load(tmp_path, text)
    assert len(lines.paths) == 1
    k = math.tan(math.radians(30))
    page = np.array([[10 + 40 * k, 40], [40 + 40 * k, 40], [40 + 80 * k, 80]])
    expect = np.column_stack([(page[:, 0] - 50) * 0.5 - RES_MM / 2,
                              (50 - page[:, 1]) * 0.5 - RES_MM / 2])
    np.testing.assert_allclose(lines.paths[0], expect, atol=1e-9)
    assert _vertex_off_ink_px(ink, lines) <= 1.0
    assert _covered(ink, lines) >= 0.95
    # 30 user units at width 0.4 mm, 40 / cos 30 at 0.4 cos 30 mm: the length-weighted mean
    legs = np.array([30.0, 40 / math.cos(math.radians(30))])
    across = np.array([0.4, 0.4 * math.cos(math.radians(30))])
    assert lines.widths_mm[0] == pytest.approx(np.average(across, weights=legs))


def test_what_is_not_a_vector_is_left_to_the_mask_and_logged(
        tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    """A dashed line and a clipped group are not taken as vectors (they would be drawn
    solid and whole): the log names them and says why; the plain line is taken."""
    text = _svg('<line id="plain" x1="10" y1="10" x2="90" y2="10" stroke-width="0.8"/>'
                '<line id="dashed" x1="10" y1="30" x2="90" y2="30" stroke-width="0.8" '
                'stroke-dasharray="4 4"/>'
                '<g clip-path="url(#c)"><line id="clipped" x1="10" y1="60" x2="90" y2="60" '
                'stroke-width="0.8"/></g>',
                '<clipPath id="c"><rect x="0" y="0" width="50" height="100"/></clipPath>')
    with caplog.at_level(logging.INFO, logger="tattotronix.art.vector"):
        ink, lines = _load(tmp_path, text)
    assert len(lines.paths) == 1
    np.testing.assert_allclose(lines.paths[0][:, 1], (50 - 10) * 0.5 - RES_MM / 2)
    assert "2 stroked element(s) drawn from the mask" in caplog.text
    assert "<line id=dashed> (a dashed stroke" in caplog.text
    assert "<line id=clipped> (clip-path on it or a group around it)" in caplog.text
    # the mask still has them: ink on the dashed row, and the clipped line only to x = 50
    h, w = ink.shape
    row = lambda y: int(round(y * 4 - 0.5))  # noqa: E731 - CSS px to grid row
    assert ink[row(30)].any()
    clipped = np.flatnonzero(ink[row(60)])
    assert clipped.size and clipped.max() < w / 2 + 2


def test_a_shared_definition_is_placed_by_each_use(tmp_path: Path) -> None:
    """One <defs> circle used three times under different transforms: three circles, each
    where the renderer puts it."""
    text = _svg('<use xlink:href="#c" transform="rotate(90 50 50)" x="10"/>'
                '<use xlink:href="#c" x="-20" y="5"/>'
                '<g transform="matrix(0.9 0.3 -0.2 1 5 -10)"><use xlink:href="#c" y="30"/></g>',
                '<circle id="c" cx="50" cy="30" r="8" stroke-width="0.8" '
                'transform="scale(1.1 0.9)"/>')
    ink, lines = _load(tmp_path, text)
    assert len(lines.paths) == 3
    assert _vertex_off_ink_px(ink, lines) <= VERTEX_TOL_PX
    assert _covered(ink, lines) >= 0.97


def test_a_stroke_width_that_varies_too_much_is_left_to_the_mask(
        tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    """A rect under scale(4 1): its sides are 4x wider across than its ends; one width
    per polyline cannot say so, so the mask draws it, and the log says why."""
    text = _svg('<rect id="flat" x="5" y="20" width="15" height="30" stroke-width="0.3" '
                'transform="scale(4 1)"/>')
    with caplog.at_level(logging.INFO, logger="tattotronix.art.vector"):
        ink, lines = _load(tmp_path, text)
    assert lines.paths == ()
    assert "<rect id=flat> (its stroke width varies 4.0x along it" in caplog.text
    assert ink.any()


# ----------------------------------------------------------------------------- text

TEXT_SVG = ('<svg xmlns="http://www.w3.org/2000/svg" width="100" height="100">'
            '<text id="hello" x="10" y="60" font-size="30" {}>Hello</text></svg>')


def _text_ink_box(tmp_path: Path, family: str = "") -> tuple[NDArray[np.bool_], tuple[
        float, float, float, float]]:
    path = tmp_path / "text.svg"
    path.write_text(TEXT_SVG.format(family))
    ink, _, _ = otsu_ink(load_artwork(path, WIDTH_MM, RES_MM, 10**8).grey)
    rows, cols = np.nonzero(ink)
    to_css = 1 / 4  # grid px to CSS px
    return ink, ((cols.min() + 0.5) * to_css, (cols.max() + 0.5) * to_css,
                 (rows.min() + 0.5) * to_css, (rows.max() + 0.5) * to_css)


@pytest.mark.parametrize("family", ["", 'font-family="serif"', 'font-family="NoSuchFont"'])
def test_text_is_drawn_where_its_letters_are(tmp_path: Path, family: str,
                                             caplog: pytest.LogCaptureFixture) -> None:
    """A text-only SVG is drawn, not refused as 'no drawable ink': ink from x = 10 along
    the baseline y = 60, cap height ~ 0.73 of the 30 px font; the log names the text."""
    with caplog.at_level(logging.INFO, logger="tattotronix.art.artwork"):
        ink, (x0, x1, y0, y1) = _text_ink_box(tmp_path, family)
    assert 9 < x0 < 14 and 70 < x1 < 100  # 'Hello' at 30 px is 70 to 80 px wide
    assert 35 < y0 < 42 and 58 < y1 < 61  # the 'H' and 'll' tops; no descender
    assert 0.02 < ink.mean() < 0.2
    assert "1 <text> element(s) (hello) drawn" in caplog.text


def test_text_is_drawn_without_system_fonts(tmp_path: Path, monkeypatch: pytest.MonkeyPatch
                                            ) -> None:
    """On a machine with no fonts installed resvg drew no <text> at all (the file was then
    refused as a flat image): the DejaVu fonts matplotlib ships draw it, the same ink as
    with the system's fonts."""
    import resvg_py

    with_system, box = _text_ink_box(tmp_path)
    render = resvg_py.svg_to_bytes

    def no_system_fonts(**kw: Any) -> bytes:
        kw["skip_system_fonts"] = True
        return bytes(render(**kw))

    monkeypatch.setattr(resvg_py, "svg_to_bytes", no_system_fonts)
    without, box2 = _text_ink_box(tmp_path)
    np.testing.assert_array_equal(without, with_system)
    assert box2 == box


def test_a_line_the_mask_drops_is_not_drawn_beside_the_ink_it_nearly_touches(
        tmp_path: Path) -> None:
    """A short stroked line smaller than mask.min_region_mm2 (its region dropped) ends
    0.15 mm from a kept shape: its band touched the shape, so the whole line was drawn
    off the artwork (a 10,000-line SVG: bleed up to 2.15 mm). Now a vector line is drawn
    only where the mask keeps ink, as the mask route draws it: this one not at all."""
    from tattotronix.app.pipeline import drawing_inputs
    from tattotronix.config.params import compose_settings
    from tattotronix.path.params import ToolpathParams
    from tattotronix.path.plan import plan_toolpath

    svg = tmp_path / "near.svg"
    svg.write_text('<svg xmlns="http://www.w3.org/2000/svg" width="30mm" height="20mm" '
                   'viewBox="0 0 30 20"><rect x="5" y="5" width="8" height="8"/>'
                   '<path d="M13.15,9 L15.15,9.3" stroke="black" stroke-width="0.4" '
                   'fill="none"/></svg>')
    bleeds, entries = {}, {}
    for vector in (False, True):
        cfg = compose_settings([f"artwork.source={svg}", f"artwork.vector={vector}"])
        mask, lines = drawing_inputs(cfg, svg, "near")
        params = ToolpathParams.from_settings(cfg.toolpath, cfg.mask, cfg.robot.panel)
        tp = plan_toolpath(mask, params, vector=lines)
        ink = tp.ink(mask, params.needle_width_mm, cfg.toolpath.ink_res_mm).fidelity
        bleeds[vector] = ink.bleed_max_mm
        entries[vector] = tp.metrics_dict()["entries"]
    assert bleeds[True] <= bleeds[False] + 1e-9, bleeds  # was 2.3 mm: the whole line
    assert entries[True] == entries[False], entries  # no stroke of its own
