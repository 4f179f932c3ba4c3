"""The robot stage's work: generate URDF and MJCF, load them everywhere, report zero pose.

The report composes the robot models with the layers above them (the collision pairs, the
effective inertia of the control layer), so it lives here and not in :mod:`tattotronix.robot`.
"""

from __future__ import annotations

import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from tattotronix.collision.pairs import body_pairs
from tattotronix.control.dynamics import effective_inertia
from tattotronix.io.jsontypes import JsonDict
from tattotronix.robot.description import RobotDescription
from tattotronix.robot.loaders import MujocoArm, PinocchioArm, PybulletArm
from tattotronix.robot.mjcf import to_mjcf
from tattotronix.robot.urdf import to_urdf

__all__ = ["RobotModels", "collision_pairs_report", "generate", "zero_pose_report"]


@dataclass(frozen=True)
class RobotModels:
    """The generated model texts and the report on them."""

    urdf: str
    mjcf: str
    report: JsonDict


def _agreement(d: RobotDescription, pin: PinocchioArm, others: dict[str, Any],
               poses: int, seed: int) -> dict[str, dict[str, float]]:
    """Worst disagreement with Pinocchio over random poses within the limits."""
    rng = np.random.default_rng(seed)
    out = {name: {"frame_pos_m": 0.0, "mass_matrix_rel": 0.0, "gravity_rel": 0.0}
           for name in others}
    for _ in range(poses):
        q = rng.uniform(d.lower, d.upper)
        f0, m0, g0 = pin.frames(q), pin.mass_matrix(q), pin.gravity(q)
        for name, arm in others.items():
            f = arm.frames(q)
            w = out[name]
            w["frame_pos_m"] = max(w["frame_pos_m"], max(
                float(np.abs(f0[k] - f[k]).max()) for k in d.frame_names))
            w["mass_matrix_rel"] = max(w["mass_matrix_rel"], float(
                np.abs(arm.mass_matrix(q) - m0).max() / np.abs(m0).max()))
            w["gravity_rel"] = max(w["gravity_rel"], float(
                np.abs(arm.gravity(q) - g0).max() / max(np.abs(g0).max(), 1e-12)))
    return out


def zero_pose_report(d: RobotDescription, urdf: Path, mjcf: Path,
                     poses: int = 20, seed: int = 0) -> JsonDict:
    """Zero-pose figures, mass totals, and the loaders' agreement (Pinocchio as reference).

    Lengths in the report are mm (``_mm``), masses kg, torques N m, inertias kg m^2.
    """
    pin = PinocchioArm(urdf, d.gravity)
    q0 = np.zeros(len(d.joints))
    frames = pin.frames(q0)  # also leaves every frame placement in pin.data.oMf
    highest = -np.inf
    for link in d.links:
        placement = pin.data.oMf[pin.model.getFrameId(link)]
        for g in d.geometry[link]:
            pts = g.points() @ placement.rotation.T + placement.translation
            highest = max(highest, float(pts[:, 2].max()))
    m0 = pin.mass_matrix(q0)
    bullet = PybulletArm(urdf, d.gravity)
    try:
        agreement = _agreement(d, pin, {"mujoco": MujocoArm(mjcf), "pybullet": bullet},
                               poses, seed)
    finally:
        bullet.close()
    mm = {name: [round(float(v) * 1000, 4) for v in frames[name]] for name in d.frame_names}
    return {
        "frames_zero_mm": mm,
        "tcp_zero_mm": mm[d.tip_frame],
        "tool0_zero_mm": mm["tool0"],
        "wrist_axis_mm": mm[d.joints[3].child][2],
        "highest_point_mm": round(highest * 1000, 3),
        "geometry": "mesh" if d.cad_dir else "primitive",
        "mass_model": d.mass_model,
        "tool": d.tool,
        "gravity_m_s2": d.gravity,
        "arm_mass_kg": round(d.arm_mass(), 6),
        "moving_mass_kg": round(d.moving_mass(), 6),
        "gravity_zero_nm": [round(float(v), 7) for v in pin.gravity(q0)],
        "j_eff_zero": [float(f"{v:.6e}") for v in effective_inertia(m0)],
        "m_diag_zero": [float(f"{v:.6e}") for v in np.diag(m0)],
        "joints": {j.name: {"lower": j.lower, "upper": j.upper, "effort_nm": j.effort,
                            "velocity_rad_s": j.velocity} for j in d.joints},
        "loader_agreement": {"poses": poses, "seed": seed, **agreement},
        "collision_pairs": collision_pairs_report(d),
    }


def collision_pairs_report(d: RobotDescription) -> JsonDict:
    """The allowed (never checked) collision pairs, derived from the tree, with reasons."""
    pairs = body_pairs(d)
    links = [p for p in pairs if not p.environment]
    return {
        "link_pairs": len(links),
        "allowed_link_pairs": sum(not p.checked for p in links),
        "checked_pairs": sum(p.checked for p in pairs),
        "allowed": [{"pair": [p.a, p.b], "reason": p.reason} for p in pairs if not p.checked],
        "needle": "the pen's needle cone may enter the panel (that one shape pair is not "
                  "checked); the collision stage holds its depth to toolpath.plunge_mm",
    }


def generate(d: RobotDescription) -> RobotModels:
    """URDF and MJCF texts, checked by loading them in all three engines."""
    urdf, mjcf = to_urdf(d), to_mjcf(d)
    with tempfile.TemporaryDirectory(prefix="tattotronix-robot-") as tmp:
        u, m = Path(tmp, "robot.urdf"), Path(tmp, "robot.xml")
        u.write_text(urdf)
        m.write_text(mjcf)
        report = zero_pose_report(d, u, m)
    return RobotModels(urdf, mjcf, report)
