"""The one robot description: zero pose, the three loaders, the original's figures
(docs/original.md)."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from tattotronix.config.params import compose_settings
from tattotronix.control.dynamics import effective_inertia
from tattotronix.errors import TattotronixError
from tattotronix.report.robot import zero_pose_report
from tattotronix.robot.description import RobotDescription, build_description
from tattotronix.robot.loaders import MujocoArm, PinocchioArm, PybulletArm
from tattotronix.robot.urdf import to_urdf

from .conftest import write_models

# the original's figures: docs/original.md, "1.3 Zero pose", "5.1 The rigid-body model" and
# "5.3 Tuning by pole placement"
TCP_ZERO_MM = (258.96, -9.44, 245.58)
TOOL0_ZERO_MM = (213.96, -9.444, 245.5775)
GRAVITY_ZERO_NM = (0.0, -0.0904637, -0.0904613, -0.0018662, -0.0112560)
J_EFF_ZERO = (2.64494e-3, 2.71297e-3, 4.98531e-4, 7.65627e-6, 2.41508e-5)
M_DIAG_ZERO = (2.67522e-3, 5.84136e-3, 1.85147e-3, 9.53904e-6, 5.98222e-5)
POSES_5_1 = ((0, 0, 0, 0, 0), (0.3, -0.5, 0.7, 0.2, -0.4), (-0.8, 1.0, -0.6, 0.9, 1.1))
FRAMES = ("base_link", "shoulder_link", "upper_arm_link", "forearm_link", "wrist_link",
          "tool_mount_link", "tool0", "tattoo_tcp")


@pytest.fixture(scope="module")
def arms(desc: RobotDescription, models: tuple[Path, Path]):
    urdf, mjcf = models
    bullet = PybulletArm(urdf, desc.gravity)
    yield PinocchioArm(urdf, desc.gravity), MujocoArm(mjcf), bullet
    bullet.close()


def test_zero_pose_tcp_and_tool0(arms) -> None:
    pin, _, _ = arms
    f = pin.frames(np.zeros(5))
    assert np.allclose(f["tattoo_tcp"] * 1000, TCP_ZERO_MM, atol=0.01)
    assert np.allclose(f["tool0"] * 1000, TOOL0_ZERO_MM, atol=1e-4)
    assert f["wrist_link"][2] * 1000 == pytest.approx(242.0885, abs=1e-4)


def test_names_follow_the_interface(arms) -> None:
    for arm in arms:
        assert arm.joint_names == tuple(f"joint_{i}" for i in range(1, 6))
        assert set(FRAMES) <= set(arm.frames(np.zeros(5)))


def test_three_loaders_agree_at_random_poses(desc: RobotDescription, arms) -> None:
    pin, mj, bullet = arms
    rng = np.random.default_rng(20261121)
    for _ in range(20):
        q = rng.uniform(desc.lower, desc.upper)
        f0, m0, g0 = pin.frames(q), pin.mass_matrix(q), pin.gravity(q)
        for arm, pos_tol in ((mj, 1e-9), (bullet, 1e-7)):  # PyBullet rounds at ~1e-8 m
            f = arm.frames(q)
            for name in FRAMES:
                assert np.abs(f[name] - f0[name]).max() < pos_tol, (type(arm).__name__, name)
            assert np.abs(arm.mass_matrix(q) - m0).max() < 1e-6 * np.abs(m0).max()
            assert np.abs(arm.gravity(q) - g0).max() < 1e-6 * np.abs(g0).max()


def test_gravity_at_zero_pose_matches_reference(arms) -> None:
    for arm in arms:
        assert np.allclose(arm.gravity(np.zeros(5)), GRAVITY_ZERO_NM, atol=1e-4)


def test_effective_inertia_at_zero_pose_matches_reference(arms) -> None:
    pin, _, _ = arms
    m0 = pin.mass_matrix(np.zeros(5))
    assert np.allclose(effective_inertia(m0), J_EFF_ZERO, rtol=0.01)
    assert np.allclose(np.diag(m0), M_DIAG_ZERO, rtol=0.01)


def test_rnea_gravity_is_the_gradient_of_potential_energy(arms) -> None:
    import pinocchio as pin_

    pin, _, _ = arms
    h = 1e-6
    for pose in POSES_5_1:
        q = np.array(pose, dtype=float)
        grad = np.empty(5)
        for i in range(5):
            dq = np.zeros(5)
            dq[i] = h
            up = pin_.computePotentialEnergy(pin.model, pin.data, q + dq)
            down = pin_.computePotentialEnergy(pin.model, pin.data, q - dq)
            grad[i] = (up - down) / (2 * h)
        assert np.abs(pin.gravity(q) - grad).max() < 1e-8


def test_mass_matrix_symmetric_positive_definite(arms) -> None:
    pin, _, _ = arms
    m = pin.mass_matrix(np.array(POSES_5_1[1]))
    assert np.allclose(m, m.T, atol=1e-12)
    assert np.linalg.eigvalsh(m).min() > 0


def test_gravity_is_standard_in_every_loader(desc: RobotDescription, arms) -> None:
    pin, mj, _ = arms
    assert desc.gravity == 9.80665
    assert np.allclose(pin.model.gravity.linear, [0, 0, -9.80665])
    assert np.allclose(mj.model.opt.gravity, [0, 0, -9.80665])


def test_massless_frames_add_no_mass(desc: RobotDescription, arms) -> None:
    import mujoco
    import pybullet as p

    pin, mj, bullet = arms
    total = desc.total_mass()
    assert sum(i.mass for i in pin.model.inertias) == pytest.approx(total, abs=1e-12)
    assert float(np.sum(mj.model.body_mass)) == pytest.approx(total, abs=1e-12)
    links = {p.getJointInfo(bullet.body, i, physicsClientId=bullet.client)[12].decode(): i
             for i in range(p.getNumJoints(bullet.body, physicsClientId=bullet.client))}
    masses = {n: p.getDynamicsInfo(bullet.body, i, physicsClientId=bullet.client)[0]
              for n, i in links.items()}
    assert masses["tool0"] == 0.0 and masses["tattoo_tcp"] == 0.0  # not PyBullet's 1 kg
    assert sum(masses.values()) == pytest.approx(desc.moving_mass(), abs=1e-9)  # fixed base
    assert mujoco.mj_name2id(mj.model, mujoco.mjtObj.mjOBJ_SITE, "tattoo_tcp") >= 0


def test_mjcf_is_in_radians_with_torque_actuators(arms) -> None:
    _, mj, _ = arms
    assert np.allclose(mj.model.jnt_range, [[-1.57, 1.57]] * 5)
    assert np.allclose(mj.model.actuator_ctrlrange, [[-20, 20]] * 5)
    assert mj.model.nu == 5


def test_mass_model_switch_changes_only_inertials(desc: RobotDescription) -> None:
    box = build_description(compose_settings(["robot.mass_model=box"]).robot)
    strip = re.compile(r"<inertial>.*?</inertial>", re.S)
    a, b = to_urdf(desc), to_urdf(box)
    assert a != b
    assert strip.sub("", a) == strip.sub("", b)
    assert box.total_mass() == pytest.approx(3.95 + 0.02)


def test_tool_none_has_no_pen(tmp_path: Path) -> None:
    d = build_description(compose_settings(["robot.tool=none"]).robot)
    assert "tattoo_tcp" not in d.frame_names and "tattoo_pen_link" not in d.links
    urdf, _ = write_models(d, tmp_path)
    f = PinocchioArm(urdf, d.gravity).frames(np.zeros(5))
    assert np.allclose(f["tool0"] * 1000, TOOL0_ZERO_MM, atol=1e-4)
    assert d.tip_frame == "tool0"


@pytest.mark.parametrize(
    ("override", "words"),
    [
        ("robot.joints.1.lower=1.6", ["joint_2", "lower=1.6", "upper=1.57"]),
        ("robot.joints.0.upper=-1.57", ["joint_1", "lower"]),
    ],
)
def test_bad_joint_limits_are_refused(override: str, words: list[str]) -> None:
    with pytest.raises(TattotronixError) as err:
        build_description(compose_settings([override]).robot)
    assert all(w in str(err.value) for w in words)


def test_cad_dir_missing_a_mesh_is_refused(tmp_path: Path) -> None:
    for link in ("base_link", "shoulder_link", "upper_arm_link", "forearm_link", "wrist_link"):
        (tmp_path / f"{link}.stl").write_bytes(b"")
    with pytest.raises(TattotronixError, match="tool_mount_link.stl"):
        build_description(compose_settings([f"robot.cad_dir={tmp_path}"]).robot)
    with pytest.raises(TattotronixError, match="not found"):
        build_description(compose_settings([f"robot.cad_dir={tmp_path / 'nope'}"]).robot)


@pytest.mark.cad
def test_meshes_zero_pose_figures(cad_dir: Path, tmp_path: Path) -> None:
    d = build_description(compose_settings([f"robot.cad_dir={cad_dir}"]).robot)
    urdf, mjcf = write_models(d, tmp_path)
    report = zero_pose_report(d, urdf, mjcf, poses=3)
    assert report["geometry"] == "mesh"
    assert report["wrist_axis_mm"] == pytest.approx(242.09, abs=0.01)
    assert report["highest_point_mm"] == pytest.approx(291.69, abs=0.01)
    assert np.allclose(report["tcp_zero_mm"], TCP_ZERO_MM, atol=0.01)
    # the meshes load in every engine and the engines still agree
    assert report["loader_agreement"]["mujoco"]["frame_pos_m"] < 1e-9
    assert report["loader_agreement"]["pybullet"]["frame_pos_m"] < 1e-7
    assert 'type="mesh"' in mjcf.read_text() and "<mesh filename=" in urdf.read_text()
