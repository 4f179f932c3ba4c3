"""The actuator study (docs/actuators.md; docs/original.md, "6.6 The actuator study") and
its stage."""

from __future__ import annotations

import dataclasses
import json
import subprocess
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from tattotronix.config.params import compose_settings
from tattotronix.config.schema import ActuatorOption
from tattotronix.errors import TattotronixError
from tattotronix.io.artifacts import StudySeriesRecord, TrajectoryRecord, make_provenance
from tattotronix.kinematics import Chain, solve_path
from tattotronix.kinematics.synthetic import logo_like_strokes, stroke_path
from tattotronix.robot.description import RobotDescription
from tattotronix.studies.actuator import (
    ActuatorStudy,
    Declared,
    actuator_study,
    box_corners,
    declared,
    depth_worst_mm,
    lateral_rms_mm,
    metrics,
    pca9685_step_us,
    rest_error_deg,
    series_arrays,
    study_from_config,
    study_poses,
    tip_sensitivity,
    worst_lateral_mm,
)
from tattotronix.trajectory import MARK, TRAVEL

from .conftest import run_side_by_side, small_art

SMALL = ["mask.width_mm=24", "mask.min_region_mm2=0.5"]
OPTIONS = ("as built, PCA9685 at 50 Hz", "as built, Arduino Servo library",
           "bus servos on joints 1 to 3", "bus servos, 12-bit encoders")


@pytest.fixture(scope="module")
def cfg() -> Any:
    return compose_settings()


@pytest.fixture(scope="module")
def chain(desc: RobotDescription) -> Chain:
    return Chain.from_description(desc)


@pytest.fixture(scope="module")
def decl(cfg: Any, chain: Chain) -> Declared:
    return declared(cfg.study.actuator, cfg.robot, cfg.hardware.servos["frame_hz"],
                    chain.joint_names)


def _stored(q: np.ndarray, kind: np.ndarray, joints: tuple[str, ...]) -> TrajectoryRecord:
    n = len(q)
    z = np.zeros_like(q)
    return TrajectoryRecord(joints=joints, t=np.arange(n) * 0.025, q=q, qd=z, qdd=z,
                            kind=kind.astype(np.int8), marked=kind == MARK,
                            tcp=np.zeros((n, 3)), provenance={})


@pytest.fixture(scope="module")
def traj(chain: Chain) -> TrajectoryRecord:
    """A solved logo-like path (100 mm wide, 1 mm steps) as a stored trajectory."""
    path = stroke_path(logo_like_strokes(width_mm=100.0), step_mm=1.0)
    res = solve_path(chain, path.xyz_m)
    assert res.ok
    return _stored(res.q, path.kind, chain.joint_names)


@pytest.fixture(scope="module")
def result(cfg: Any, chain: Chain, traj: TrajectoryRecord) -> ActuatorStudy:
    return study_from_config(cfg, chain, traj)


# --- the declared numbers and the rest errors ----------------------------------------------

def test_declared_numbers_come_from_the_config(decl: Declared) -> None:
    assert decl.pca9685_step_us == 4.8828125  # 1e6 / 50 / 4096, exactly
    assert pca9685_step_us(60.0) == pytest.approx(1e6 / 60 / 4096)
    assert decl.us_per_deg == 11.111 and decl.arduino_step_us == 1.0
    assert decl.bus_step_deg == 360 / 4096
    assert decl.servo_by_joint == {"joint_1": "MG996R", "joint_2": "MG996R",
                                   "joint_3": "MG996R", "joint_4": "MG996R",
                                   "joint_5": "SG90"}
    assert decl.deadband_us == {"MG996R": 5.0, "SG90": 10.0}
    with pytest.raises(TattotronixError, match="frame_hz"):
        pca9685_step_us(0.0)


def test_rest_errors_are_the_published_ones(cfg: Any, decl: Declared) -> None:
    opts = {o.name: o for o in cfg.study.actuator.options}
    assert tuple(opts) == OPTIONS
    pca = rest_error_deg(decl, opts[OPTIONS[0]])
    ard = rest_error_deg(decl, opts[OPTIONS[1]])
    bus3 = rest_error_deg(decl, opts[OPTIONS[2]])
    bus = rest_error_deg(decl, opts[OPTIONS[3]])
    assert round(pca[0], 4) == 0.4447 and round(pca[4], 4) == 0.6697  # MG996R, SG90
    assert np.all(pca[:4] == pca[0])  # j1-j4 MG996R (joint_2's pair as one)
    assert round(ard[0], 3) == 0.270 and round(ard[4], 3) == 0.495
    np.testing.assert_allclose(bus3, [0.087890625] * 3 + [pca[3], pca[4]], rtol=0, atol=0)
    assert round(bus[0], 4) == 0.0879 and np.all(bus == 0.087890625)


def test_the_frame_rate_sets_the_pca9685_step(cfg: Any, chain: Chain) -> None:
    d60 = declared(cfg.study.actuator, cfg.robot, 60.0, chain.joint_names)
    opt = ActuatorOption(name="x", command="pca9685")
    e = rest_error_deg(d60, opt)
    assert e[0] == pytest.approx((1e6 / 60 / 4096 + 5.0) / 2 / 11.111, rel=1e-15)


@pytest.mark.parametrize("option, words", [
    (ActuatorOption(name="odd", command="teensy"), ["'odd'", "'teensy'", "pca9685", "arduino"]),
    (ActuatorOption(name="odd", command="pca9685", bus_joints=["joint_9"]),
     ["'odd'", "joint_9", "joint_1", "joint_5"]),
])
def test_unknown_command_or_joint_is_refused(decl: Declared, chain: Chain,
                                             traj: TrajectoryRecord, option: ActuatorOption,
                                             words: list[str]) -> None:
    for call in (lambda: rest_error_deg(decl, option),
                 lambda: actuator_study(chain, traj, decl, [option], every=5, line_mm=0.3,
                                        plunge_mm=1.5, play_deg=1.0, backlash_deg=0.1)):
        with pytest.raises(TattotronixError) as exc:
            call()
        for w in words:
            assert w in str(exc.value)


def test_a_joint_without_a_servo_is_refused(cfg: Any, chain: Chain) -> None:
    with pytest.raises(TattotronixError, match="no servo drives"):
        declared(cfg.study.actuator, cfg.robot, 50.0, (*chain.joint_names, "joint_6"))


# --- poses ---------------------------------------------------------------------------------

def test_poses_are_every_nth_marking_point(traj: TrajectoryRecord) -> None:
    p = study_poses(traj, 5)
    marking = np.flatnonzero(traj.kind == MARK)
    np.testing.assert_array_equal(p.index, marking[::5])
    np.testing.assert_array_equal(p.q, traj.q[marking[::5]])
    np.testing.assert_array_equal(p.t_s, traj.t[marking[::5]])
    assert len(study_poses(traj, 1).t_s) == len(marking)


def test_no_marking_points_is_refused(traj: TrajectoryRecord, chain: Chain,
                                      decl: Declared) -> None:
    empty = dataclasses.replace(traj, kind=np.full_like(traj.kind, TRAVEL))
    with pytest.raises(TattotronixError, match="no marking points"):
        study_poses(empty, 5)
    with pytest.raises(TattotronixError, match="no marking points"):
        actuator_study(chain, empty, decl, [ActuatorOption(name="a", command="pca9685")],
                       every=5, line_mm=0.3, plunge_mm=1.5, play_deg=1.0, backlash_deg=0.1)
    with pytest.raises(TattotronixError, match="every"):
        study_poses(traj, 0)


# --- the tip sensitivity and the error bounds ------------------------------------------------

def test_lever_is_the_jacobian_by_finite_differences(chain: Chain,
                                                     traj: TrajectoryRecord) -> None:
    q = study_poses(traj, 5).q[::97]
    sens = tip_sensitivity(chain, q)  # (N, 3, n) mm/deg
    assert sens.shape == (len(q), 3, chain.n)
    h = 1e-6  # rad
    for i in range(chain.n):
        dq = np.zeros(chain.n)
        dq[i] = h
        p1, _ = chain.fk(q + dq)
        p0, _ = chain.fk(q - dq)
        fd = (p1 - p0) / (2 * h) * 1000.0 * np.pi / 180.0  # m/rad -> mm/deg
        np.testing.assert_allclose(sens[:, :, i], fd, atol=1e-7)
    # joint_1 turns about the vertical: it never moves the tip in depth
    np.testing.assert_allclose(sens[:, 2, 0], 0.0, atol=1e-12)


def test_box_corners() -> None:
    c = box_corners([1.0, 2.0, 3.0])
    assert c.shape == (8, 3)
    assert {tuple(r) for r in c} == {(a, b, d) for a in (-1, 1) for b in (-2, 2)
                                     for d in (-3, 3)}


def test_corner_maximum_bounds_the_box(chain: Chain, traj: TrajectoryRecord,
                                       decl: Declared, cfg: Any) -> None:
    """At a few poses: 4000 random interior points of the box never exceed the corner
    maximum, which is attained at a corner (brute force, pose by pose)."""
    rng = np.random.default_rng(0)
    poses = study_poses(traj, 5).q
    e = rest_error_deg(decl, cfg.study.actuator.options[0])
    j_xy = tip_sensitivity(chain, poses[:: max(1, len(poses) // 4)])[:, :2, :]
    worst = worst_lateral_mm(j_xy, e)
    corners = [(2 * np.array(s) - 1) * e for s in np.ndindex(*(2,) * len(e))]
    for k, jk in enumerate(j_xy):
        inside = rng.uniform(-1.0, 1.0, (4000, len(e))) * e
        sampled = np.linalg.norm(inside @ jk.T, axis=1).max()
        at_corners = max(float(np.linalg.norm(jk @ c)) for c in corners)
        assert worst[k] >= sampled
        assert worst[k] == pytest.approx(at_corners, rel=1e-14)
        assert sampled > 0.7 * worst[k]  # the samples do come close


def test_typical_and_depth_formulas() -> None:
    j = np.array([[[3.0, 0.0], [0.0, 4.0], [1.0, -2.0]]])  # one pose, two joints
    e = np.array([0.5, 0.25])
    lever = np.linalg.norm(j[:, :2, :], axis=1)
    np.testing.assert_allclose(lever, [[3.0, 4.0]])
    assert lateral_rms_mm(lever, e)[0] == pytest.approx(np.sqrt((9 * 0.25 + 16 / 16) / 3))
    assert depth_worst_mm(j[:, 2, :], e)[0] == pytest.approx(1.0 * 0.5 + 2.0 * 0.25)
    # the worst corner of two orthogonal columns: both at full band
    assert worst_lateral_mm(j[:, :2, :], e)[0] == pytest.approx(np.hypot(1.5, 1.0))


# --- the result and the metrics ------------------------------------------------------------

def test_result_orders_the_options_and_play_is_linear(result: ActuatorStudy,
                                                       chain: Chain) -> None:
    lw = [o.lateral_worst for o in result.options]
    assert lw[0] > lw[1] > lw[2] > lw[3] > 0  # PCA9685 > Arduino > bus 1-3 > bus everywhere
    for o in result.options:
        assert o.lateral_worst >= o.lateral_worst_median >= o.lateral_rms_median > 0
        assert result.times_line(o) == pytest.approx(o.lateral_worst / 0.3)
    assert result.options[0].depth_worst > result.options[3].depth_worst
    # the corner maximum with a common band is linear in the band
    j_xy = tip_sensitivity(chain, result.poses.q)[:, :2, :]
    ones = np.ones(chain.n)
    np.testing.assert_allclose(worst_lateral_mm(j_xy, 0.1 * ones),
                               0.1 * worst_lateral_mm(j_xy, ones), rtol=1e-13)
    np.testing.assert_allclose(result.play_lateral_mm, worst_lateral_mm(j_xy, ones))
    assert result.required_deg == pytest.approx(0.3 / result.play_lateral_mm_per_deg)
    assert result.backlash_lateral_mm == pytest.approx(0.1 * result.play_lateral_mm_per_deg)
    lev = result.lever_lateral_worst
    assert result.play_lateral_mm_per_deg <= lev.sum() + 1e-12  # triangle inequality


def test_metrics_keys_and_plain_values(result: ActuatorStudy) -> None:
    m = metrics(result, series=True)
    text = json.dumps(m, allow_nan=False)
    assert "NaN" not in text
    assert {"declared", "line_mm", "plunge_depth_mm", "poses", "joints",
            "lever_lateral_mm_per_deg", "lever_depth_mm_per_deg", "play_lateral_mm_per_deg",
            "required_deg", "series_t_s", "options"} <= set(m)
    assert set(m["declared"]) >= {"us_per_deg", "pca9685_step_us", "arduino_step_us",
                                  "bus_step_deg", "servo_by_joint", "deadband_us"}
    assert m["line_mm"] == 0.3 and m["plunge_depth_mm"] == 1.5
    assert tuple(m["options"]) == OPTIONS
    for o in m["options"].values():
        assert {"rest_deg", "lateral_worst_mm", "lateral_worst_median_mm",
                "lateral_rms_median_mm", "depth_worst_mm", "times_line",
                "series_lateral_worst_mm"} <= set(o)
        assert len(o["series_lateral_worst_mm"]) == len(m["series_t_s"])
    assert len(m["series_t_s"]) == -(-m["poses"] // 4)
    short = metrics(result)
    assert "series_t_s" not in short and short["series_points"] == len(m["series_t_s"])
    s = series_arrays(result)
    assert s["lateral_worst_mm"].shape == (4, len(m["series_t_s"]))
    np.testing.assert_array_equal(s["t_s"], m["series_t_s"])


# --- the stage -----------------------------------------------------------------------------

def _assert_close(a: Any, b: Any, path: str = "") -> None:
    """Equal structure; floats equal to 1e-12 (relative or absolute)."""
    if isinstance(a, dict):
        assert isinstance(b, dict) and set(a) == set(b), path
        for k in a:
            _assert_close(a[k], b[k], f"{path}.{k}")
    elif isinstance(a, list):
        assert isinstance(b, list) and len(a) == len(b), path
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            _assert_close(x, y, f"{path}[{i}]")
    elif isinstance(a, float) or isinstance(b, float):
        assert a == pytest.approx(b, rel=1e-12, abs=1e-12), path
    else:
        assert a == b, path


@pytest.fixture(scope="module")
def stage_runs(tmp_path_factory: pytest.TempPathFactory,
               desc: RobotDescription) -> dict[str, tuple[subprocess.CompletedProcess[str], Path]]:
    """The stage on a small planned drawing, and on an empty data folder, side by side."""
    from tattotronix.app.pipeline import plan_drawing

    base = tmp_path_factory.mktemp("actuator_stage")
    good, empty = base / "good" / "data", base / "empty" / "data"
    (good / "trajectories").mkdir(parents=True)
    empty.mkdir(parents=True)
    art = small_art(base / "small.png")
    traj = plan_drawing(compose_settings(SMALL), art, "small", desc)
    traj.save(good / "trajectories" / "small.npz", make_provenance({}, {}, "test"))
    return run_side_by_side("actuator", {"good": good, "empty": empty},
                            "artwork.name=small", *SMALL)


def test_stage_writes_metrics_series_and_figure(stage_runs: Any, chain: Chain) -> None:
    run, data = stage_runs["good"]
    assert run.returncode == 0, run.stderr
    text = (data / "metrics" / "actuator" / "small.json").read_text()
    assert "NaN" not in text and "Infinity" not in text
    m = json.loads(text)
    assert m["name"] == "small" and set(m["options"]) == set(OPTIONS)  # keys sorted
    assert m["series_file"] == "studies/actuator/small.npz"
    assert round(m["options"][OPTIONS[0]]["rest_deg"][0], 4) == 0.4447
    png = data / "figures" / "small" / "actuator.png"
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "must hold" in run.stdout + run.stderr
    assert not [f for f in data.rglob("*") if ".tmp" in f.name]

    # regenerated in this process from the same trajectory: equal to 1e-12
    traj = TrajectoryRecord.load(data / "trajectories" / "small.npz")
    again = study_from_config(compose_settings(SMALL), chain, traj)
    _assert_close(m, {"name": "small", **metrics(again),
                      "series_file": "studies/actuator/small.npz"})
    z = StudySeriesRecord.load(data / "studies" / "actuator" / "small.npz", "actuator").series
    s = series_arrays(again)
    assert set(z) == set(s)
    for k, v in s.items():
        if v.dtype.kind == "f":
            np.testing.assert_allclose(z[k], v, rtol=1e-12, atol=1e-12)
        else:
            np.testing.assert_array_equal(z[k], v)


def test_stage_without_trajectory_names_the_trajectory_stage(stage_runs: Any) -> None:
    run, data = stage_runs["empty"]
    assert run.returncode == 2
    assert "'trajectory' stage" in run.stderr and "small.npz" in run.stderr
    assert "Traceback" not in run.stderr
    assert not (data / "metrics").exists() and not (data / "figures").exists()
