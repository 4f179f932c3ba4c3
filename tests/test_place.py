"""The drawing's place on the panel (tattotronix/art/place.py; issue 30, item 2): an anchor
point lands at ``mask.at_mm``, the drawing turns ``mask.rotate_deg`` about it, its width or
its height sets its size, and a drawing whose ink leaves the panel, or that the arm cannot
reach, is refused at the mask, before any work."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial import cKDTree

from tattotronix.app.pipeline import drawing_inputs, mask_of, plan_drawing
from tattotronix.art.grid import InkMask
from tattotronix.art.mask import make_mask
from tattotronix.art.place import ANCHOR_SIDES, Placement, ink_extent_mm
from tattotronix.config.params import compose_settings
from tattotronix.config.schema import Anchor
from tattotronix.errors import TattotronixError
from tattotronix.robot.description import RobotDescription

from .conftest import PYTHON, ROOT, small_art, stage_env

SMALL = ["mask.width_mm=24", "mask.min_region_mm2=0.5"]


def _grey(h: int = 40, w: int = 60) -> np.ndarray:
    """A white canvas with a dark L in its top-left quarter (so a turn shows)."""
    g = np.full((h, w), 255.0)
    g[4:24, 6:14] = 0.0
    g[16:24, 6:30] = 0.0
    return g


def _centroid(m: InkMask) -> np.ndarray:
    r, c = np.nonzero(m.ink)
    return np.array([m.xs[c].mean(), m.ys[r].mean()])


def test_the_default_place_is_the_centred_grid() -> None:
    """Centre anchor, at [0, 0], no turn: the mask the pipeline has always made, bit for bit."""
    m, _ = make_mask(_grey(), 0.5, min_region_mm2=0.0)
    ref = InkMask.centred(m.ink, 0.5)
    assert m.place.identity and np.array_equal(m.xs, ref.xs) and np.array_equal(m.ys, ref.ys)


@pytest.mark.parametrize("anchor", list(Anchor))
def test_each_anchor_lands_at_at_mm(anchor: Anchor) -> None:
    """The anchor's point of the grid's extent (its centre: the grid's (0, 0)) is at_mm."""
    res, at = 0.5, (-31.25, 12.5)
    grey = _grey()
    m, _ = make_mask(grey, res, min_region_mm2=0.0,
                     place=Placement.of(grey.shape, res, anchor, at, 0.0))
    su, sv = ANCHOR_SIDES[anchor]
    u = {-1: m.xs[0] - res / 2, 0: m.xs[len(m.xs) // 2], 1: m.xs[-1] + res / 2}[su]
    v = {-1: m.ys[-1] - res / 2, 0: m.ys[len(m.ys) // 2 - 1], 1: m.ys[0] + res / 2}[sv]
    assert (u, v) == pytest.approx(at, abs=1e-9)


@pytest.mark.parametrize("deg", [30.0, 90.0, -135.0, 200.0])
def test_a_turned_drawing_turns_about_its_anchor(deg: float) -> None:
    """The ink turned anticlockwise about the anchor: its area within 4 %, its centroid
    where the turn puts the unturned one (within a pixel)."""
    res, at = 0.5, (10.0, -5.0)
    grey = _grey()
    flat, _ = make_mask(grey, res, min_region_mm2=0.0)
    place = Placement.of(grey.shape, res, Anchor.top_left, at, deg)
    turned, _ = make_mask(grey, res, min_region_mm2=0.0, place=place)
    assert turned.ink.sum() == pytest.approx(flat.ink.sum(), rel=0.04)
    t = math.radians(deg)
    corner = np.array([flat.xs[0] - res / 2, flat.ys[0] + res / 2])  # the top-left anchor
    rot = np.array([[math.cos(t), -math.sin(t)], [math.sin(t), math.cos(t)]])
    expect = rot @ (_centroid(flat) - corner) + np.asarray(at)
    assert np.linalg.norm(_centroid(turned) - expect) < res
    assert place.apply(corner[None, :])[0] == pytest.approx(at, abs=1e-9)


def test_a_drawing_off_the_panel_is_refused_naming_what_moves_it() -> None:
    cfg = compose_settings(["mask.width_mm=60", "mask.at_mm=[90,0]"])
    with pytest.raises(TattotronixError) as err:
        mask_of(cfg, None, "emblem")
    msg = str(err.value)
    assert "off the 200 x 140 mm panel" in msg and "mask.at_mm" in msg, msg
    # 190 mm wide, the emblem's ink is 164 x 101 mm: it fits; turned by 90 degrees, it is
    # taller than the 140 mm panel
    mask_of(compose_settings(["mask.width_mm=190"]), None, "emblem")
    with pytest.raises(TattotronixError, match="larger than the 200 x 140 mm panel"):
        mask_of(compose_settings(["mask.width_mm=190", "mask.rotate_deg=90"]), None, "emblem")
    # at the corner, inside: accepted, and its ink's extent is there
    m = mask_of(compose_settings(["mask.width_mm=60", "mask.anchor=bottom_left",
                                  "mask.at_mm=[-100,-70]"]), None, "emblem")
    u0, u1, v0, v1 = ink_extent_mm(m.ink, m.xs, m.ys, m.res_mm) or (0, 0, 0, 0)
    assert u0 >= -100 - 1e-6 and v0 >= -70 - 1e-6 and u1 < -30 and v1 < 0


def test_the_mask_stage_refuses_an_off_panel_drawing_in_one_line(tmp_path: Path) -> None:
    """By hand, as a user would: the artwork stage, then the mask stage with the drawing
    placed off the panel: exit 2, one line, no mask written."""
    import subprocess

    art = small_art(tmp_path / "small.png")
    data = tmp_path / "data"
    common = [f"paths.data={data}", f"artwork.source={art}", *SMALL]
    env = stage_env()
    first = subprocess.run([PYTHON, "stages/artwork.py", *common], cwd=ROOT, env=env,
                           text=True, capture_output=True, timeout=300)
    assert first.returncode == 0, first.stderr
    r = subprocess.run([PYTHON, "stages/mask.py", *common, "mask.at_mm=[95,60]"], cwd=ROOT,
                       env=env, text=True, capture_output=True, timeout=300)
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "off the 200 x 140 mm panel" in lines[0], r.stderr
    assert not [p for p in data.rglob("*") if p.parent.name == "mask"]


def test_a_drawing_out_of_reach_is_refused_before_any_work() -> None:
    """The panel's far corners (210 mm out from the base, plus 100) are out of the arm's
    reach: the small drawing there is refused at its mask, naming the corner and the
    settings; at the near corners it is drawn."""
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        art = small_art(Path(tmp) / "small.png")
        far = compose_settings([*SMALL, "mask.anchor=top_right", "mask.at_mm=[100,70]"])
        with pytest.raises(TattotronixError) as err:
            mask_of(far, art, "small")
        near = compose_settings([*SMALL, "mask.anchor=top_left", "mask.at_mm=[-100,70]"])
        assert mask_of(near, art, "small").ink.any()
    msg = str(err.value)
    assert msg.startswith("the drawing is out of the arm's reach where it is placed: ")
    assert "mask.at_mm" in msg and msg.endswith("nothing was planned")


#: the README's placement example ("The stages")
README_EXAMPLE = ["mask.width_mm=100", "mask.anchor=top_left", "mask.at_mm=[-95,55]",
                  "mask.rotate_deg=15"]


def test_the_readme_placement_example_fits_the_panel_and_the_reach() -> None:
    """The example the README gives is accepted as written (its first version left the
    panel by 1.4 mm once turned)."""
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    assert f"python stages/draw.py {' '.join(README_EXAMPLE)}" in readme
    m = mask_of(compose_settings(README_EXAMPLE), None, "emblem")
    u0, u1, v0, v1 = ink_extent_mm(m.ink, m.xs, m.ys, m.res_mm) or (0, 0, 0, 0)
    assert -100 <= u0 < u1 <= 100 and -70 <= v0 < v1 <= 70


def test_height_sets_the_size_and_both_are_refused() -> None:
    m = mask_of(compose_settings(["mask.height_mm=40"]), None, "emblem")
    assert m.ink.shape[0] * m.res_mm == pytest.approx(40.0, abs=m.res_mm)
    with pytest.raises(TattotronixError, match="both set: set one"):
        mask_of(compose_settings(["mask.height_mm=40", "mask.width_mm=60"]), None, "emblem")


def test_vector_lines_go_where_the_mask_goes(tmp_path: Path) -> None:
    """An SVG of stroked lines in vector mode, turned and moved: the toolpath's vector lines
    lie on the placed mask's ink (every vertex within a pixel of it)."""
    from tattotronix.path.params import ToolpathParams
    from tattotronix.path.plan import plan_toolpath

    svg = tmp_path / "zig.svg"
    svg.write_text('<svg xmlns="http://www.w3.org/2000/svg" width="60mm" height="30mm" '
                   'viewBox="0 0 60 30"><g fill="none" stroke="black" stroke-width="0.5">'
                   '<polyline points="5,5 20,25 35,5 50,25"/><circle cx="45" cy="10" r="4"/>'
                   '</g></svg>')
    cfg = compose_settings([f"artwork.source={svg}", "artwork.vector=true",
                            "mask.rotate_deg=37", "mask.anchor=top_left",
                            "mask.at_mm=[-60,40]", "mask.min_region_mm2=0"])
    mask, vector = drawing_inputs(cfg, svg, "zig")
    assert vector is not None and vector.paths and not mask.place.identity
    placed = vector.placed(mask.place)
    pts = np.concatenate(placed.paths)
    col = np.clip(np.round((pts[:, 0] - mask.xs[0]) / mask.res_mm).astype(int), 0,
                  len(mask.xs) - 1)
    row = np.clip(np.round((mask.ys[0] - pts[:, 1]) / mask.res_mm).astype(int), 0,
                  len(mask.ys) - 1)
    near = np.zeros_like(mask.ink)
    for dr in (-1, 0, 1):  # within a pixel of ink
        for dc in (-1, 0, 1):
            near |= np.roll(np.roll(mask.ink, dr, 0), dc, 1)
    assert near[row, col].mean() == 1.0
    params = ToolpathParams.from_settings(cfg.toolpath, cfg.mask, cfg.robot.panel)
    tp = plan_toolpath(mask, params, vector=vector)
    assert tp.metrics.entries >= 1


@pytest.mark.slow
def test_a_placed_drawing_is_drawn_there(desc: RobotDescription) -> None:
    """The small drawing turned 45 degrees with its top-right corner at the panel's
    (80, 50) mm: the planned needle marks where the placed mask has ink, in the arm frame
    (every marking tip within half a needle of an ink pixel, and the tips span the
    placed ink's extent to within a pitch)."""
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        art = small_art(Path(tmp) / "small.png")
        cfg = compose_settings([*SMALL, "mask.rotate_deg=45", "mask.anchor=top_right",
                                "mask.at_mm=[80,50]"])
        mask = mask_of(cfg, art, "small")
        art_h, art_w = mask_of(compose_settings(SMALL), art, "small").ink.shape
        traj = plan_drawing(cfg, art, "small", desc)
    origin = np.asarray(cfg.toolpath.panel_origin) * 1e3
    tips = traj.tcp[traj.kind == 1] * 1e3 - origin
    rows, cols = np.nonzero(mask.ink)
    ink_uv = np.column_stack([mask.xs[cols], mask.ys[rows]])
    d, _ = cKDTree(ink_uv).query(tips[:, :2])
    assert d.max() <= mask.res_mm * 0.75 + cfg.toolpath.needle_width_mm / 2
    u0, u1, v0, v1 = ink_extent_mm(mask.ink, mask.xs, mask.ys, mask.res_mm) or (0, 0, 0, 0)
    pitch = cfg.toolpath.pitch_mm
    assert tips[:, 0].min() < u0 + pitch and tips[:, 0].max() > u1 - pitch
    assert tips[:, 1].min() < v0 + pitch and tips[:, 1].max() > v1 - pitch
    # the unturned grid's top-right corner is at (80, 50)
    corner = mask.place.apply(np.array([[(art_w - 1) / 2 * mask.res_mm,
                                         (art_h - 1) / 2 * mask.res_mm]]))[0]
    assert corner == pytest.approx([80.0, 50.0], abs=1e-9) and u0 > 30 and v0 > 0
