"""The report figures, the drawing animation and their stages (figures, animate,
robot_figures)."""

from __future__ import annotations

import json
import math
import subprocess
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from tattotronix.config.params import compose_settings
from tattotronix.control import steps as S
from tattotronix.control.analysis import step_overshoot_pct
from tattotronix.kinematics import Chain, PinocchioTip, solve_point
from tattotronix.report import figures as F
from tattotronix.report.animation import (
    DrawingClip,
    drawing_clip,
    mp4_available,
    render_drawing,
)
from tattotronix.robot.description import RobotDescription
from tattotronix.robot.mass import mass_report, table_from_config

from .conftest import PYTHON, ROOT

NAME = "tiny"
JOINTS = tuple(f"joint_{i}" for i in range(1, 6))


def _png_size(path: Path, kind: str) -> None:
    assert path.exists() and path.stat().st_size > 10_000
    w, h = F.FIGSIZE[kind]
    with Image.open(path) as im:
        assert im.format == "PNG"
        assert im.size == (round(w * F.DPI), round(h * F.DPI))


# --- a tiny drawing: a 16 mm circle on the panel, travel in and out --------------------------

def _tiny_drawing(desc: RobotDescription, urdf: Path) -> dict[str, np.ndarray]:
    """Trajectory arrays (the npz layout) of a small drawing, by IK on the URDF."""
    origin = np.array([0.21, 0.0, 0.005])
    ang = np.linspace(0.0, 2.0 * math.pi, 61)
    mark = np.column_stack([0.008 * np.cos(ang), 0.008 * np.sin(ang), np.full(61, -0.0015)])
    up = np.array([[0.008, 0.0, 0.008]])
    pts = np.vstack([np.repeat(up, 4, axis=0) + [[0.03, 0, 0], [0.02, 0, 0], [0.01, 0, 0],
                                                    [0, 0, 0]],
                     [[0.008, 0.0, 0.0]], mark, [[0.008, 0.0, 0.008]], [[0.02, 0.0, 0.008]]])
    kind = np.array([0] * 4 + [2] + [1] * 61 + [0, 0], dtype=np.int8)
    ref = PinocchioTip.from_urdf(urdf, desc.tip_frame)
    q = np.empty((len(pts), 5))
    q0 = np.array([0.0, 0.6, -0.9, 0.0, -1.2])
    for i, p in enumerate(pts):
        res = solve_point(ref, origin + p, needle_axis=(0, 0, -1), q0=q0)
        assert res.converged
        q[i] = q0 = res.q
    t = np.linspace(0.0, 4.0, len(pts))
    qd = np.gradient(q, t, axis=0)
    qdd = np.gradient(qd, t, axis=0)
    tcp, _ = Chain.from_description(desc).fk(q)
    marked = np.r_[False, (kind[1:] == 1) & (kind[:-1] == 1)]
    return {"joints": np.array(JOINTS), "t": t, "q": q, "qd": qd, "qdd": qdd, "kind": kind,
            "marked": marked, "tcp": tcp, "provenance": np.array(json.dumps({"test": True}))}


def _run_log(desc: RobotDescription, traj: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """A run log (the simulate stage's layout) that follows the trajectory with noise."""
    from tattotronix.control.tracking import down_at

    rng = np.random.default_rng(0)
    t = np.arange(0.0, float(traj["t"][-1]), 0.02)
    q_ref = np.column_stack([np.interp(t, traj["t"], traj["q"][:, j]) for j in range(5)])
    q = q_ref + rng.normal(0.0, 2e-5, q_ref.shape)
    chain = Chain.from_description(desc)
    tip, _ = chain.fk(q)
    tip_ref, _ = chain.fk(q_ref)
    down = down_at(traj["t"], traj["kind"], t)
    return {"joints": traj["joints"], "t": t, "q": q, "qd": np.gradient(q, t, axis=0),
            "tau": rng.normal(0.0, 0.05, q.shape) - 0.1, "q_ref": q_ref,
            "qd_ref": np.gradient(q_ref, t, axis=0), "tip": tip, "tip_ref": tip_ref,
            "error_m": np.linalg.norm(tip - tip_ref, axis=1), "down": down, "settled": down,
            "provenance": np.array("{}")}


@pytest.fixture(scope="module")
def tiny(desc: RobotDescription, models: tuple[Path, Path]) -> dict[str, np.ndarray]:
    return _tiny_drawing(desc, models[0])


# --- the figure functions ------------------------------------------------------------------

def test_chain_figure_from_pinocchio_frames(desc: RobotDescription, models: tuple[Path, Path],
                                            tmp_path: Path) -> None:
    urdf = models[0]
    q_draw = F.panel_pose(desc, urdf, (0.21, 0.0, 0.005), (0.0, 0.6, -0.9, 0.0, -1.2))
    poses = F.arm_poses(desc, urdf, np.vstack([np.zeros(5), q_draw]))
    assert poses.names[0] == "base_link" and "tattoo_tcp" in poses.names
    # the published zero-pose TCP, and the drawing pose on the panel origin
    np.testing.assert_allclose(poses.origins_m[0, poses.tip] * 1e3, (258.96, -9.444, 245.5775),
                               atol=0.01)
    np.testing.assert_allclose(poses.origins_m[1, poses.tip], (0.21, 0.0, 0.005), atol=1e-6)
    assert [poses.names[i] for i in poses.chain()][-1] == "tattoo_tcp"
    out = F.chain_figure(poses, ["zero", "drawing"], desc.panel_centre, desc.panel_size,
                         (0.21, 0.0, 0.005), tmp_path / "chain.png")
    _png_size(out, "chain")


def test_joints_and_torques_figures(tiny: dict[str, np.ndarray], desc: RobotDescription,
                                    tmp_path: Path) -> None:
    F.joints_figure(tiny["t"], tiny["q"], tiny["qd"], tiny["qdd"], tiny["kind"], JOINTS,
                    desc.lower, desc.upper, [1.5] * 5, 10.0, tmp_path / "joints.png", NAME,
                    zoom_s=(1.0, 1.5))
    _png_size(tmp_path / "joints.png", "joints")
    log = _run_log(desc, tiny)
    grav = np.tile([0.0, -0.09, -0.09, -0.002, -0.01], (len(tiny["t"]), 1))
    F.torques_figure(tiny["t"], grav, log["t"], log["tau"], log["down"], JOINTS,
                     tmp_path / "torques.png", NAME, 20.0)
    _png_size(tmp_path / "torques.png", "torques")


def test_tracking_figure(tmp_path: Path) -> None:
    rng = np.random.default_rng(1)
    t = np.arange(0.0, 30.0, 0.02)
    down = (t % 5.0) < 4.0
    settled = down & ((t % 5.0) > 0.1)
    err = np.where(down, 10 ** rng.uniform(-8, -5, len(t)), 10 ** rng.uniform(-6, -3.5, len(t)))
    err[::97] = 0.0  # exact zeros are drawn at the floor
    F.tracking_figure(t, err, down, settled, tmp_path / "tracking.png", NAME)
    _png_size(tmp_path / "tracking.png", "tracking")


def test_mass_figure_with_and_without_poses(desc: RobotDescription, models: tuple[Path, Path],
                                            tmp_path: Path) -> None:
    robot = compose_settings().robot
    report = json.loads(json.dumps(mass_report(table_from_config(robot), robot)))
    poses = F.arm_poses(desc, models[0], np.zeros(5))
    F.mass_figure(report, tmp_path / "mass.png", poses)
    _png_size(tmp_path / "mass.png", "mass")
    F.mass_figure(report, tmp_path / "mass_plain.png")
    _png_size(tmp_path / "mass_plain.png", "mass")


def test_linear_step_of_one_axis_is_the_closed_form_overshoot() -> None:
    """One joint (M = J): python-control's coupled model reduces to the single axis,
    24.9 % (PI-D) and 20.6 % (PID), for any J and wn."""
    j, wn = 0.003, 37.0
    t = np.linspace(0.0, 20.0 / wn, 4001)
    for doe in (False, True):
        y = S.linear_step([[j]], [3 * j * wn**2], [j * wn**3], [3 * j * wn], doe, t)[0, 0]
        assert 100.0 * (y.max() - 1.0) == pytest.approx(step_overshoot_pct(doe), abs=0.05)
        assert y[-1] == pytest.approx(1.0, abs=1e-3)


def test_step_set_on_the_model_plant_matches_the_linear_loop(
        desc: RobotDescription, models: tuple[Path, Path], tmp_path: Path) -> None:
    """At wn = 20 rad/s (wn T = 0.02) and a small step the simulated arm is the coupled
    linear loop: overshoots within 1 point. Coupling makes them differ from the single
    axis (joint_3 overshoots most)."""
    q0 = [-0.128, 0.69, 0.23, 0.0, 0.65]
    s = S.step_set(desc, models[0], q0, 20.0, "pid_g", 1000.0, 0.001, 20.0,
                   math.radians(0.5), periods=8.0)
    assert not s.saturated.any()
    np.testing.assert_allclose(s.overshoot_pct, s.linear_overshoot_pct, atol=1.0)
    assert s.single_axis_pct == pytest.approx(24.9, abs=0.05)
    assert int(np.argmax(s.overshoot_pct)) == 2
    assert json.dumps(s.summary())
    v = S.StepSet(**{**s.__dict__, "structure": "pid_g_v", "wn": 160.0})  # layout only
    F.steps_figure([s, v], tmp_path / "steps.png", NAME)
    _png_size(tmp_path / "steps.png", "steps")


# --- the animation -------------------------------------------------------------------------

def _ink_pixels(frame: Image.Image, blank: Image.Image) -> int:
    """Pixels on the panel (right half, below the title) darker than on ``blank`` and ink-grey (not
    the coloured pen marker)."""
    a = np.asarray(frame.convert("RGB")).astype(int)
    b = np.asarray(blank.convert("RGB")).astype(int)
    h, w = a.shape[:2]
    a, b = a[h // 8:4 * h // 5, w // 2:], b[h // 8:4 * h // 5, w // 2:]  # no title, no bar
    darker = (b.sum(axis=2) - a.sum(axis=2)) > 80
    grey = (a.max(axis=2) - a.min(axis=2)) < 100
    return int((darker & grey).sum())


def test_animation_writes_gif_and_mp4_with_visible_ink(
        desc: RobotDescription, models: tuple[Path, Path], tiny: dict[str, np.ndarray],
        tmp_path: Path) -> None:
    log = _run_log(desc, tiny)
    clip = drawing_clip(desc, models[0], NAME, tiny["t"], tiny["q"], tiny["kind"],
                        tiny["tcp"], tiny["marked"], (0.21, 0.0, 0.005), run_t=log["t"],
                        run_q=log["q"], run_tip_m=log["tip"], fps=10.0)
    assert isinstance(clip, DrawingClip) and "simulated" in clip.source
    assert clip.compression == pytest.approx(1.0)  # 4 s: never slower than real time
    gif = tmp_path / "drawing.gif"
    mp4 = tmp_path / "drawing.mp4"
    res = render_drawing(clip, gif=gif, mp4=mp4, size_px=(512, 288), gif_width_px=380)
    with Image.open(gif) as im:
        assert im.n_frames == res.gif_frames > 1
        assert im.size == (380, 214)
        first = im.convert("RGB")
        im.seek(im.n_frames - 1)
        last = _ink_pixels(im, first)
    assert last > 40  # the ink grew, and it shows
    if mp4_available():
        assert res.mp4 == mp4 and mp4.stat().st_size > 5_000
        import imageio.v2 as imageio

        with imageio.get_reader(str(mp4)) as r:
            assert r.get_meta_data()["size"] == (512, 288)
            assert sum(1 for _ in r) == res.frames
    else:
        assert res.mp4 is None and not mp4.exists()


def test_animation_from_the_plan_says_so(desc: RobotDescription, models: tuple[Path, Path],
                                         tiny: dict[str, np.ndarray]) -> None:
    clip = drawing_clip(desc, models[0], NAME, tiny["t"], tiny["q"], tiny["kind"],
                        tiny["tcp"], tiny["marked"], (0.21, 0.0, 0.005), video_s=2.0,
                        fps=5.0)
    assert "planned trajectory" in clip.source
    assert len(clip.t) == 11 and clip.compression == pytest.approx(2.0)
    assert set(np.unique(clip.state)) <= {0, 1, 2} and (clip.state == 1).any()


# --- the stages ----------------------------------------------------------------------------

def _stage(script: str, data: Path, *overrides: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([PYTHON, f"stages/{script}.py", f"paths.data={data}", *overrides],
                          cwd=ROOT, capture_output=True, text=True, timeout=600)


def _layout(data: Path, desc: RobotDescription, tiny: dict[str, np.ndarray]) -> None:
    """What the trajectory, simulate and mass stages would have written."""
    (data / "trajectories").mkdir(parents=True)
    np.savez_compressed(data / "trajectories" / f"{NAME}.npz", **tiny)
    run = data / "runs" / f"{NAME}-mujoco"
    run.mkdir(parents=True)
    np.savez_compressed(run / "log.npz", **_run_log(desc, tiny))
    robot = compose_settings().robot
    (data / "metrics").mkdir(parents=True)
    (data / "metrics" / "mass.json").write_text(
        json.dumps(mass_report(table_from_config(robot), robot)))


@pytest.mark.slow
def test_stages_write_every_figure(draw_data: Path, desc: RobotDescription,
                                   tiny: dict[str, np.ndarray]) -> None:
    _layout(draw_data, desc, tiny)
    r = _stage("figures", draw_data, f"artwork.name={NAME}")
    assert r.returncode == 0, r.stderr
    for kind in ("joints", "torques", "steps", "tracking"):
        _png_size(draw_data / "figures" / NAME / f"{kind}.png", kind)
    r = _stage("animate", draw_data, f"artwork.name={NAME}")
    assert r.returncode == 0, r.stderr
    with Image.open(draw_data / "figures" / NAME / "drawing.gif") as im:
        assert im.n_frames > 1
    assert (draw_data / "figures" / NAME / "drawing.mp4").exists() == mp4_available()
    r = _stage("robot_figures", draw_data)
    assert r.returncode == 0, r.stderr
    _png_size(draw_data / "figures" / "robot" / "chain.png", "chain")
    _png_size(draw_data / "figures" / "robot" / "mass.png", "mass")
    leftovers = [p.name for p in draw_data.rglob(".*tmp*")]
    assert not leftovers, leftovers


def test_missing_inputs_name_the_stage_to_run(draw_data: Path) -> None:
    r = _stage("figures", draw_data, f"artwork.name={NAME}")
    assert r.returncode == 2 and "run the 'trajectory' stage first" in r.stderr
    assert "Traceback" not in r.stderr
    assert not (draw_data / "figures").exists()


def test_place_labels_keeps_names_off_the_markers_and_each_other() -> None:
    """Three markers close together: each name goes beside its own marker, clear of the
    others and of the other names."""
    from matplotlib.transforms import Bbox

    from tattotronix.plotting import place_labels, pyplot

    plt = pyplot()
    fig, ax = plt.subplots(figsize=(4, 3), dpi=100)
    xy = np.array([[1.0, 1.0], [1.05, 1.0], [1.0, 1.05]])
    ax.plot(xy[:, 0], xy[:, 1], "o", ms=10)
    ax.set_xlim(0.5, 1.5)
    ax.set_ylim(0.5, 1.5)
    labels = place_labels(ax, xy, ["first", "second", "third"], 5.0, fontsize=8)
    renderer = fig.canvas.get_renderer()
    boxes = [a.get_window_extent(renderer) for a in labels]
    px = ax.transData.transform(xy)
    markers = [Bbox.from_extents(*(p - 5 * 100 / 72), *(p + 5 * 100 / 72)) for p in px]
    for i, b in enumerate(boxes):
        assert not any(b.overlaps(m) for m in markers), labels[i].get_text()
        assert not any(b.overlaps(o) for j, o in enumerate(boxes) if j != i)
        assert ax.get_window_extent(renderer).contains(b.x0, b.y0)
    plt.close(fig)
