"""The toolpath as an SVG in millimetres (tattotronix/path/export.py), read back with
svgelements (what vpype reads SVG with): the page's physical size, the layers as vpype
numbers them, every marking polyline on the plan's own points in its kind's layer, travel
in the travel layer, y down, and the same bytes for the same plan."""

from __future__ import annotations

import io
import re
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
import svgelements

from tattotronix.art.grid import InkMask
from tattotronix.path.export import (
    DRAG_LAYER,
    LAYER_OF_KIND,
    LAYERS,
    TRAVEL_LAYER,
    panel_extent_mm,
    path_svg,
    stroke_directions,
    stroke_starts,
    toolpath_svg,
)
from tattotronix.path.kinds import APPROACH, MARK, TRAVEL
from tattotronix.path.path3d import Path3D
from tattotronix.path.plan import Toolpath, plan_toolpath
from tattotronix.path.strokes import StrokeKind
from tests.test_toolpath import RES, SHAPES, default_params, multi_region_mask

ROOT = Path(__file__).resolve().parents[1]
PX_PER_MM = 96 / 25.4  # svgelements (and vpype) work in CSS pixels
NEEDLE_MM = 0.3
INKSCAPE_LABEL = "{http://www.inkscape.org/namespaces/inkscape}label"
INKSCAPE_MODE = "{http://www.inkscape.org/namespaces/inkscape}groupmode"
UM = 1e-3  # 1 µm, mm


@dataclass
class ReadLayer:
    """One top-level group as read back: its label, id, stroke colour and width (mm), its
    polylines (panel mm) and their stroke colours."""

    label: str
    id: str
    colour: str
    width_mm: float
    polylines: list[np.ndarray]
    colours: set[str]


def read_svg(text: str, extent: tuple[float, float, float, float]
             ) -> tuple[float, float, dict[int, ReadLayer]]:
    """(width mm, height mm, layers by vpype's layer ID) of an SVG, each polyline mapped
    back to the panel frame: u = x + u_min, v = v_max - y."""
    u0, _, _, v1 = extent
    svg = svgelements.SVG.parse(io.StringIO(text))
    layers: dict[int, ReadLayer] = {}
    for i, g in enumerate(e for e in svg if isinstance(e, svgelements.Group)):
        assert g.values.get(INKSCAPE_MODE) == "layer"
        label, gid = g.values.get(INKSCAPE_LABEL) or "", g.values.get("id") or ""
        # vpype read: the label's digits, else the id's, else the order (vpype 1.13 takes
        # the first group of digits: the labels have one, so both rules agree)
        digits = re.sub("[^0-9]", "", label) or re.sub("[^0-9]", "", gid)
        lid = int(digits) if digits else i + 1
        assert re.findall("[0-9]+", label) == [str(lid)]
        assert re.sub("[^0-9]", "", gid) == str(lid)
        polys, colours = [], set()
        for e in g.select():
            if isinstance(e, svgelements.Polyline):
                xy = np.array([(p.x, p.y) for p in e.points]) / PX_PER_MM
                polys.append(np.column_stack([xy[:, 0] + u0, v1 - xy[:, 1]]))
                colours.add(str(e.stroke))
                assert e.stroke_width / PX_PER_MM == pytest.approx(NEEDLE_MM)
        # the group's own stroke-width is in user units: mm (the viewBox is in mm)
        layers[lid] = ReadLayer(label, gid, str(g.values.get("stroke")),
                                float(g.values["stroke-width"]), polys, colours)
    return svg.width / PX_PER_MM, svg.height / PX_PER_MM, layers


def _mask() -> InkMask:
    """The 'B' (outer outline, two holes, fill) with a thin bar across it (a line)."""
    ink = SHAPES["B"][0].copy()
    ink[10:12, 5:150] = True
    return InkMask.centred(ink, RES)


@pytest.fixture(scope="module")
def plan() -> Toolpath:
    return plan_toolpath(_mask(), default_params())


def _extent() -> tuple[float, float, float, float]:
    return panel_extent_mm(default_params().panel_size_mm)


def _find(uv: np.ndarray, poly: np.ndarray, used: np.ndarray) -> int:
    """The first row a where the path's points a, a + 1, ... are the polyline's vertices
    (to 1 µm) and its segments are not taken yet."""
    m = len(poly)
    for a in np.flatnonzero(np.abs(uv - poly[0]).max(axis=1) <= UM):
        if a + m <= len(uv) and np.abs(uv[a:a + m] - poly).max() <= UM \
                and not used[a:a + m - 1].any():
            return int(a)
    raise AssertionError(f"polyline from {poly[0]} to {poly[-1]} is not on the path")


def test_round_trip(plan: Toolpath) -> None:
    """Read back: the panel's size; the layers with vpype's IDs, one colour each; every
    drawn segment of the path in exactly one marking polyline, on the plan's points, in the
    layer of its stroke's kind (or the drag layer, a straight line into the next stroke's
    start); travel from each lift to the next plunge."""
    extent = _extent()
    text = toolpath_svg(plan, NEEDLE_MM, extent, "B")
    width, height, layers = read_svg(text, extent)
    pw, ph = default_params().panel_size_mm
    assert (width, height) == pytest.approx((pw, ph))
    assert 'width="200mm" height="140mm" viewBox="0 0 200 140"' in text
    assert sorted(layers) == [layer.number for layer in LAYERS]
    for layer in LAYERS:
        got = layers[layer.number]
        assert got.label == layer.label and got.id == f"layer{layer.number}"
        assert got.colour == layer.colour and got.width_mm == pytest.approx(NEEDLE_MM)
        assert got.colours <= {layer.colour}  # vpype read --attr stroke: the same layers
    assert len({layer.colour for layer in LAYERS}) == len(LAYERS)

    path = plan.path
    uv, stroke = path.uvz_mm[:, :2], path.stroke
    down = path.kind != TRAVEL
    ink = down[:-1] & down[1:]
    kinds = plan.drawing.kinds[plan.order.sequence]
    starts = stroke_starts(plan.drawing, plan.order)
    dirs = stroke_directions(plan.drawing, plan.order)
    turns = 0
    used = np.zeros(len(ink), dtype=bool)
    dots = 0
    for layer in LAYERS[:-1]:
        for poly in layers[layer.number].polylines:
            dot = len(poly) == 2 and np.array_equal(poly[0], poly[1])
            poly = poly[:1] if dot else poly
            a = _find(uv, poly, used)
            rows = np.arange(a, a + len(poly))
            assert down[rows].all()
            used[rows[:-1]] = True
            dots += dot
            if layer is DRAG_LAYER:  # from one stroke's end into the next one's start
                k = stroke[rows[-1]]
                assert stroke[rows[0]] == k - 1 and (stroke[rows[1:]] == k).all()
                rel = poly[-1] - starts[k]
                if np.abs(rel).max() <= UM:  # a straight drag, to the stroke's start
                    d = (poly[-1] - poly[0]) / np.linalg.norm(poly[-1] - poly[0])
                    off = (poly - poly[0]) @ np.array([-d[1], d[0]])
                    assert np.abs(off).max() <= 2 * UM  # a straight line
                else:  # a round turn, to the run trimmed along its line
                    along = rel @ dirs[k]
                    assert along > 0 and np.abs(rel - along * dirs[k]).max() <= UM
                    turns += 1
            else:
                owners = stroke[rows if dot else rows[1:]]
                assert len(set(owners.tolist())) == 1
                assert LAYER_OF_KIND[StrokeKind(int(kinds[owners[0]]))] is layer
    assert np.array_equal(used, ink)  # every drawn segment once
    assert dots == int((down & ~np.r_[False, ink] & ~np.r_[ink, False]).sum())
    counts = {layer.name: len(layers[layer.number].polylines) for layer in LAYERS}
    assert min(counts[n] for n in ("outer outline", "hole outline", "fill row", "line",
                                   "drag", "travel")) > 0, counts
    assert counts["drag"] == path.drags
    assert turns > 0  # the shape's hatch has round turns, drawn in the drag layer

    # travel: from a lift (a point in the skin, then one above it) to the next plunge
    lifts = {tuple(np.round(uv[i], 3)) for i in np.flatnonzero(down[:-1] & ~down[1:])}
    plunges = {tuple(np.round(uv[i], 3)) for i in np.flatnonzero(path.kind == APPROACH)}
    travel_mm = 0.0
    for poly in layers[TRAVEL_LAYER.number].polylines:
        assert tuple(np.round(poly[0], 3)) in lifts and tuple(np.round(poly[-1], 3)) in plunges
        travel_mm += float(np.linalg.norm(np.diff(poly, axis=0), axis=1).sum())
    step = np.linalg.norm(np.diff(uv, axis=0), axis=1)
    assert travel_mm == pytest.approx(float(step[~ink].sum()), abs=1e-2)


def test_y_down_and_corners() -> None:
    """A point at the page's top-left corner in the panel (u_min, v_max) is at the SVG's
    (0, 0); (u_max, v_min) at (width, height); travel is in its own layer."""
    extent = (-10.0, 10.0, -5.0, 5.0)
    z = [8.0, -1.5]
    pts = [((-10, 5, z[0]), TRAVEL, 0), ((-10, 5, z[1]), APPROACH, 0),
           ((0, 0, z[1]), MARK, 0), ((10, -5, z[1]), MARK, 0), ((10, -5, z[0]), TRAVEL, 0),
           ((-5, -5, z[0]), TRAVEL, 1), ((-5, -5, z[1]), APPROACH, 1),
           ((5, -4, z[1]), MARK, 1), ((5, -4, z[0]), TRAVEL, 1)]
    path = Path3D(np.array([p for p, _, _ in pts], dtype=float),
                  np.array([k for _, k, _ in pts], dtype=np.int8),
                  np.array([s for _, _, s in pts], dtype=np.int32), 0)
    text = path_svg(path, np.array([StrokeKind.OUTER, StrokeKind.FILL], dtype=np.int8),
                    np.array([[-10.0, 5.0], [-5.0, -5.0]]), NEEDLE_MM, extent)
    assert 'width="20mm" height="10mm" viewBox="0 0 20 10"' in text
    svg = svgelements.SVG.parse(io.StringIO(text))
    (outline,) = [e for e in svg.elements() if isinstance(e, svgelements.Polyline)
                  and e.stroke == LAYER_OF_KIND[StrokeKind.OUTER].colour]
    xy = np.array([(p.x, p.y) for p in outline.points]) / PX_PER_MM
    assert np.allclose(xy, [[0, 0], [10, 5], [20, 10]], atol=1e-9)
    assert (svg.width / PX_PER_MM, svg.height / PX_PER_MM) == pytest.approx((20, 10))
    _, _, layers = read_svg(text, extent)
    (travel,) = layers[TRAVEL_LAYER.number].polylines
    assert np.allclose(travel, [[10, -5], [-5, -5]])
    (fill,) = layers[LAYER_OF_KIND[StrokeKind.FILL].number].polylines
    assert np.allclose(fill, [[-5, -5], [5, -4]])
    assert '<polyline points="0.000,0.000 10.000,5.000 20.000,10.000"/>' in text


def test_same_plan_same_bytes(plan: Toolpath) -> None:
    """Planned again from the same mask: the same bytes (no time, no machine in the file);
    a point moved by 2 µm changes them (the coordinates keep 1 µm)."""
    extent = _extent()
    text = toolpath_svg(plan, NEEDLE_MM, extent, "B")
    again = toolpath_svg(plan_toolpath(_mask(), default_params()), NEEDLE_MM, extent, "B")
    assert again.encode() == text.encode()
    assert "-0.000" not in text
    seq = plan.order.sequence
    moved = plan.path.uvz_mm.copy()
    moved[len(moved) // 2, 0] += 2 * UM
    other = path_svg(Path3D(moved, plan.path.kind, plan.path.stroke, plan.path.drags),
                     plan.drawing.kinds[seq], stroke_starts(plan.drawing, plan.order),
                     NEEDLE_MM, extent, "B", stroke_directions(plan.drawing, plan.order))
    assert other != text and len(other) == len(text)


def test_bad_extent_and_needle_are_refused() -> None:
    path = Path3D(np.zeros((0, 3)), np.zeros(0, np.int8), np.zeros(0, np.int32), 0)
    none = np.zeros(0, np.int8), np.zeros((0, 2))
    with pytest.raises(ValueError, match="empty SVG extent"):
        path_svg(path, *none, NEEDLE_MM, (0.0, 0.0, 0.0, 1.0))
    with pytest.raises(ValueError, match="needle width"):
        path_svg(path, *none, 0.0, (0.0, 1.0, 0.0, 1.0))


@pytest.mark.slow
def test_stage_writes_the_svg_of_its_npz(tmp_path: Path) -> None:
    """The toolpath stage writes ``toolpath/<name>.svg`` beside the npz: the panel's size,
    and its marking polylines are the stored path's points in the skin."""
    (tmp_path / "mask").mkdir()
    multi_region_mask().save(tmp_path / "mask" / "test.npz")
    res = subprocess.run(
        [sys.executable, "stages/toolpath.py", f"paths.data={tmp_path}", "artwork.name=test"],
        cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr
    text = (tmp_path / "toolpath" / "test.svg").read_text(encoding="utf-8")
    assert "<title>test</title>" in text
    width, height, layers = read_svg(text, _extent())
    assert (width, height) == pytest.approx((200, 140))
    with np.load(tmp_path / "toolpath" / "test.npz", allow_pickle=False) as z:
        uv, kind = z["uvz_mm"][:, :2], z["kind"]
    # the same points, each to within a micrometre: the SVG's three decimals (a tie such
    # as -4.2875 may round either way in its text and in numpy) read back through the
    # page's transform
    skin = uv[kind != TRAVEL]
    drawn = np.concatenate([poly for layer in LAYERS[:-1]
                            for poly in layers[layer.number].polylines])
    from scipy.spatial import cKDTree

    assert cKDTree(skin).query(drawn, p=np.inf)[0].max() <= 0.001
    assert cKDTree(drawn).query(skin, p=np.inf)[0].max() <= 0.001
    assert not [p for p in tmp_path.rglob("*") if ".tmp" in p.name]
