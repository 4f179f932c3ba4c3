"""Robot description: generation time, and per-call cost of each loader's kinematics and dynamics.

Ratios are against Pinocchio measured in the same run.
"""

from __future__ import annotations

import tempfile
from collections.abc import Callable
from pathlib import Path

import numpy as np
from run import Row, median_time

from tattotronix.config.params import compose_settings
from tattotronix.report.robot import generate
from tattotronix.robot.description import build_description
from tattotronix.robot.loaders import MujocoArm, PinocchioArm, PybulletArm
from tattotronix.robot.mjcf import to_mjcf
from tattotronix.robot.urdf import to_urdf

CALLS = 2000


def bench(repeat: int) -> list[Row]:
    cfg = compose_settings()
    desc = build_description(cfg.robot)
    rows: list[Row] = []
    t, _ = median_time(lambda: generate(desc), repeat)
    rows.append(("generate + load 3 engines + report", t, "s", "the robot stage's work"))
    qs = np.random.default_rng(0).uniform(desc.lower, desc.upper, size=(CALLS, len(desc.joints)))
    with tempfile.TemporaryDirectory() as tmp:
        urdf, mjcf = Path(tmp, "r.urdf"), Path(tmp, "r.xml")
        urdf.write_text(to_urdf(desc))
        mjcf.write_text(to_mjcf(desc))
        bullet = PybulletArm(urdf, desc.gravity)
        arms = {"pinocchio": PinocchioArm(urdf, desc.gravity), "mujoco": MujocoArm(mjcf),
                "pybullet": bullet}
        base: dict[str, float] = {}
        for what in ("frames", "mass_matrix", "gravity"):
            for name, arm in arms.items():
                fn = getattr(arm, what)
                def calls(fn: Callable[[np.ndarray], object] = fn) -> list[object]:
                    return [fn(q) for q in qs]

                t, _ = median_time(calls, repeat)
                per_call = t / CALLS * 1e6
                base.setdefault(what, per_call)
                rows.append((f"{what} [{name}]", per_call, "us/call",
                             f"{per_call / base[what]:.2f}x pinocchio"))
        bullet.close()
    return rows
