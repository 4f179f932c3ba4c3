"""A drawing on a curved surface, end to end in the library (issue 33): the ``surface``
settings, :func:`tattotronix.app.onskin.plan_on_surface` and the ``surface`` stage.

What is tested: the config group (``surface=panel`` the default, ``forearm`` and
``mesh`` composed from it); on the phantom, the emblem laid across the limb is solved at
every point with the needle along the inward normal (tilt error <= 1e-3 deg, needles 40+
deg from vertical at its ends), every marking point lies at the marking depth along its
normal from the phantom's exact surface, the drawing is timed without a step split and
is collision-free with the limb at the margin; the same design on the phantom exported
as a noisy STL plans with its distortion reported; refusals in one line: the panel (not
a curved surface), a mesh without a file, a distortion bound of 0, a placement on the
underside (naming the part out of reach), a limb placed where the arm folds into itself
(naming the links); the stage writes its npz, metrics and figure.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from tattotronix.app.onskin import SkinDrawing, plan_on_surface, simulate_on_surface
from tattotronix.config.params import compose_settings
from tattotronix.config.schema import SurfaceKind
from tattotronix.errors import TattotronixError
from tattotronix.path.kinds import MARK
from tattotronix.robot.description import build_description
from tests.test_surface import PHANTOM, _stl, phantom_mesh

ROOT = Path(__file__).resolve().parents[1]
#: the built-in drawing on the phantom (dvc.yaml, ``surfaces``): the emblem 60 mm wide
#: around the limb (surface=forearm's default placement)
ACROSS = ["surface=forearm", "mask.width_mm=60"]


def _plan(overrides: list[str]) -> SkinDrawing:
    cfg = compose_settings(overrides)
    return plan_on_surface(cfg, "emblem", "emblem", build_description(cfg.robot))


@pytest.fixture(scope="module")
def across() -> SkinDrawing:
    return _plan(ACROSS)


def test_the_surface_group_defaults_to_the_panel() -> None:
    assert compose_settings([]).surface.kind is SurfaceKind.panel
    fore = compose_settings(["surface=forearm"]).surface
    assert fore.kind is SurfaceKind.forearm and fore.phantom.elbow_width_mm == 80.0
    mesh = compose_settings(["surface=mesh", "surface.mesh_file=scan.stl"]).surface
    assert mesh.kind is SurfaceKind.mesh and mesh.mesh_file == "scan.stl"
    assert mesh.phantom == fore.phantom  # one set of defaults


def test_the_emblem_across_the_limb_is_solved_along_the_normal(across: SkinDrawing) -> None:
    d = across
    assert d.ik.converged.all()
    assert float(d.tilt_deg.max()) <= 1e-3
    mark = d.skin.kind == MARK
    assert float(d.from_vertical_deg[mark].max()) >= 40.0  # it wraps around the limb
    assert d.distortion.area_worst <= 0.005 and d.distortion.angle_worst <= 0.005
    # every marking point at the marking depth along its normal from the exact surface
    cone = d.surface.cone
    assert cone is not None
    plunge = float(compose_settings(ACROSS).toolpath.plunge_mm)
    skin = d.skin.xyz_mm[mark] - plunge * d.skin.axis[mark]  # back out along the normal
    inv = np.linalg.inv(cone.pose)
    local = skin @ inv[:3, :3].T + inv[:3, 3]
    a, b = cone.semi_axes(local[:, 0])
    assert np.abs(np.hypot(local[:, 1] / a, local[:, 2] / b) - 1.0).max() * b.min() < 1e-6
    # and the needle axis is the inward normal there
    theta = np.arctan2(local[:, 2] / b, local[:, 1] / a)
    normal = cone.posed(cone.normal(local[:, 0], theta), vectors=True)
    assert np.abs(d.skin.axis[mark] + normal).max() < 1e-9
    s = d.summary()
    assert s["ik_converged_pct"] == 100.0 and s["surface"] == "forearm"
    # timed as drawn (no step split by the time law), and collision-free with the limb in
    # the panel's place, every link and the pen at the margin
    assert len(d.trajectory.t) == len(d.skin.kind) and d.trajectory.duration_s > 0
    assert not d.clearance.events and "tattoo_pen_link|limb" in d.clearance.pair_names
    assert float(d.clearance.min_clearance_m.min()) >= 1e-3


def test_a_scanned_phantom_plans_with_its_distortion_reported(tmp_path: Path) -> None:
    v, f = phantom_mesh(PHANTOM)  # in the limb's own frame, posed as the phantom is
    file = _stl(tmp_path / "arm.stl", v, f)
    # the placement: the phantom's top at 150 mm along it
    top = PHANTOM.point(np.array([150.0]), np.radians([90.0]))[0]
    d = _plan(["surface=mesh", f"surface.mesh_file={file}",
               f"surface.mesh_at_mm=[{top[0]},{top[1]},{top[2]}]", "mask.width_mm=40",
               "surface.max_distortion_pct=5"])
    assert d.surface.kind == "mesh" and d.ik.converged.all() and not d.clearance.events
    assert 0.0 < d.distortion.area_worst < 0.05  # a scan is not exactly developable
    assert d.summary()["distortion"]["samples"] > 100


@pytest.mark.parametrize(("overrides", "match"), [
    ([], "surface=panel is the flat panel"),
    (["surface=mesh"], "needs surface.mesh_file"),
    (["surface=mesh", "surface.mesh_file=/nowhere/arm.stl"], "arm.stl"),
    ([*ACROSS, "surface.max_distortion_pct=0"], r"distorted by .* at design"),
    ([*ACROSS, "surface.around_deg=270"], r"over part of the design: .* within design u"),
    ([*ACROSS, "surface.origin_mm=[140,-110,30]", "surface.yaw_deg=90"],
     r"refused: .* collide at t ="),
    ([*ACROSS, "surface.along_mm=500"], "off the phantom"),
])
def test_bad_placements_are_refused_in_one_line(overrides: list[str], match: str) -> None:
    with pytest.raises(TattotronixError, match=match) as err:
        _plan(overrides)
    assert "\n" not in str(err.value)


def test_the_stage_writes_its_outputs(tmp_path: Path, draw_data: Path) -> None:
    """The README's command (the built-in drawing's name, a coarse reach map): the plan,
    the reach map, and the drawing simulated on MuJoCo with its ink scored in the skin."""
    env = {**os.environ, "MPLBACKEND": "Agg"}
    out = tmp_path / "out"
    run = subprocess.run(
        [sys.executable, str(ROOT / "stages" / "surface.py"), "artwork.name=emblem-forearm",
         "artwork.source=emblem", *ACROSS, "surface.reach_along=4", "surface.reach_around=8",
         "draw.progress=false", f"paths.data={draw_data}", f"paths.out={out}"],
        cwd=tmp_path, env=env, capture_output=True, text=True)
    assert run.returncode == 0, run.stdout[-2000:] + run.stderr[-2000:]
    tmp_path = out
    metrics = json.loads((tmp_path / "metrics" / "surface" / "emblem-forearm.json").read_text())
    sim = metrics["run"]
    assert sim["backend"] == "mujoco" and sim["verdict"] == "ok", sim
    # the tip tracks the skin path as it tracks the panel's, and its ink in the skin is
    # the plan's to a pixel, at the plunge depth along the normal
    assert sim["settled_mean_um"] <= 2.0 and sim["marking_max_um"] < 50.0, sim
    assert sim["ink_iou"] > 0.99 and sim["ink_max_dev_mm"] <= 0.05 + 1e-9, sim
    assert sim["depth_mm"]["min"] > 1.45 and sim["depth_mm"]["max"] < 1.55, sim
    assert sim["artwork"]["coverage"] > 0.7 and sim["artwork"]["bleed_max_mm"] <= 0.1 + 1e-9
    assert (tmp_path / "figures" / "surface" / "emblem-forearm-ink.png").stat().st_size > 10_000
    # the same ink carried onto the limb, in 3-D, two views
    with Image.open(tmp_path / "figures" / "surface" / "emblem-forearm-limb.png") as im:
        assert im.size[0] > 1000
    assert metrics["ik_converged_pct"] == 100.0
    assert metrics["needle_from_vertical_deg"]["max"] >= 40.0
    assert metrics["reach"]["points"] == 32
    arrays = np.load(tmp_path / "surface" / "emblem-forearm.npz")
    assert arrays["q"].shape == (metrics["points"], 5)
    assert arrays["reachable"].shape == (4, 8)
    assert (tmp_path / "figures" / "surface" / "emblem-forearm.png").stat().st_size > 10_000
    # the drawing as a 3-D film: the limb in the panel's place, the ink growing on it
    with Image.open(tmp_path / "figures" / "surface" / "emblem-forearm-drawing3d.gif") as im:
        assert im.n_frames > 100 and im.size == (640, 480)
        im.seek(0)
        first = np.asarray(im.convert("RGB"), dtype=int)
        im.seek(im.n_frames - 1)
        last = np.asarray(im.convert("RGB"), dtype=int)
    skin = (last[..., 0] > 180) & (last[..., 0] > last[..., 2] + 25)  # the limb's pink
    assert skin.sum() > 2000  # the limb is in the scene
    inked = (first.sum(axis=2) - last.sum(axis=2)) > 90  # darker at the end than at first
    assert inked.sum() > 100
    film = tmp_path / "figures" / "surface" / "emblem-forearm-drawing3d.mp4"
    assert film.stat().st_size > 10_000 and film.read_bytes()[4:8] == b"ftyp"  # an MP4


def test_a_scanned_limb_gets_its_own_reach_map(tmp_path: Path, draw_data: Path) -> None:
    """On a mesh the reach map is over its vertices (as many as the phantom's grid, spread
    evenly): the stage writes it in the metrics, the npz and the figure."""
    v, f = phantom_mesh(PHANTOM)
    file = _stl(tmp_path / "arm.stl", v, f)
    top = PHANTOM.point(np.array([150.0]), np.radians([90.0]))[0]
    out = tmp_path / "out"
    run = subprocess.run(
        [sys.executable, str(ROOT / "stages" / "surface.py"), "artwork.name=scan",
         "artwork.source=emblem", "surface=mesh", f"surface.mesh_file={file}",
         f"surface.mesh_at_mm=[{top[0]},{top[1]},{top[2]}]", "mask.width_mm=40",
         "surface.max_distortion_pct=5", "surface.reach_along=4", "surface.reach_around=8",
         "draw.progress=false", f"paths.data={draw_data}", f"paths.out={out}"],
        cwd=tmp_path, env={**os.environ, "MPLBACKEND": "Agg"}, capture_output=True,
        text=True)
    assert run.returncode == 0, run.stdout[-2000:] + run.stderr[-2000:]
    metrics = json.loads((out / "metrics" / "surface" / "scan.json").read_text())
    reach = metrics["reach"]
    assert reach["points"] == 32 and 0 < reach["reachable_pct"] < 100, reach
    assert reach["tilt_worst_deg"] < 1e-3
    arrays = np.load(out / "surface" / "scan.npz")
    assert arrays["reach_xyz_m"].shape == (32, 3) and arrays["reachable"].shape == (32,)
    # every tested tip is a vertex of the mesh, the marking depth in along its normal
    n = arrays["reach_normal"]
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-9)
    on = arrays["reach_xyz_m"] * 1000.0 + 1.5 * n
    from scipy.spatial import cKDTree
    gap, _ = cKDTree(arrays["vertices_mm"]).query(on)
    assert gap.max() < 1e-6
    assert (out / "figures" / "surface" / "scan.png").stat().st_size > 10_000


def test_the_skin_drawing_is_simulated_on_plants_only(across: SkinDrawing,
                                                      desc: object) -> None:
    cfg = compose_settings([*ACROSS, "backend=servo"])
    with pytest.raises(TattotronixError, match="backend=servo: a drawing on the skin is "
                                                "simulated on mujoco"):
        simulate_on_surface(cfg, Path("nowhere"), build_description(cfg.robot), across, "e")


def test_draw_py_refuses_a_curved_surface_instead_of_drawing_on_the_panel(
        draw_data: Path) -> None:
    """``draw.py surface=forearm`` would have drawn on the panel, silently: it is refused
    in one line that names the stage that draws on the skin, and writes nothing."""
    out = draw_data.parent / "out"
    run = subprocess.run(
        [sys.executable, str(ROOT / "stages" / "draw.py"), "surface=forearm", "art=emblem",
         f"paths.data={draw_data}", f"paths.out={out}"],
        cwd=draw_data.parent, env={**os.environ, "MPLBACKEND": "Agg"}, capture_output=True,
        text=True)
    assert run.returncode != 0
    said = (run.stdout + run.stderr).strip().splitlines()
    assert "surface=forearm: draw.py draws on the panel" in said[-1], said[-3:]
    assert "stages/surface.py surface=forearm" in said[-1]
    assert not (out / "metrics").exists()


def test_the_api_refuses_a_curved_surface_too() -> None:
    import tattotronix as tt

    with pytest.raises(TattotronixError, match="surface=forearm: tattotronix.plan draws on "
                                               "the panel"):
        tt.draft("emblem", overrides=["surface=forearm"])


def test_the_skin_has_its_own_tip_acceleration_limit(across: SkinDrawing) -> None:
    """surface.tip_accel_mm_s2 (50) times the marking on the skin, not the panel's
    trajectory.tip_accel_mm_s2 (100): the tip accelerates at most that much along the
    marked path, and the panel's limit no longer applies to the skin."""
    from tattotronix.kinematics import Chain

    cfg = compose_settings(ACROSS)
    assert cfg.surface.tip_accel_mm_s2 < cfg.trajectory.tip_accel_mm_s2
    traj = across.trajectory
    t, kind = np.asarray(traj.t), np.asarray(traj.kind)
    tip = Chain.from_description(build_description(cfg.robot)).fk(np.asarray(traj.q))[0]
    # the tip's acceleration from its path and the law (|p'' sdot^2 + p' sddot|), on
    # marking intervals away from the rests, where finite differences are steady
    v = np.gradient(tip, t, axis=0)
    a = np.linalg.norm(np.gradient(v, t, axis=0), axis=1) * 1000  # mm/s^2
    inner = (kind == MARK) & np.r_[False, kind[:-2] == MARK, False] & np.r_[
        False, kind[2:] == MARK, False]
    assert float(np.percentile(a[inner], 99)) <= 1.05 * cfg.surface.tip_accel_mm_s2
    # the same drawing at the panel's limit is faster, and faster only by the marking
    fast = _plan([*ACROSS, "surface.tip_accel_mm_s2=100"])
    assert fast.trajectory.t[-1] < traj.t[-1]
