"""Collision checking: a 16 000-point trajectory, samples and swept motion, on one core.

The goal (issue 8) is under 2 s for 16 000 points. Timed on the first 16 000 points of the
built-in artwork's trajectory when the pipeline has made it (``data/trajectories/
emblem.npz``), else on a synthetic sweep through the drawing poses; both with the k-DOP
fallback geometry and, when ``TATTOTRONIX_CAD_DIR`` is set, with the CAD mesh hulls. The
ratio row compares against the goal.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
from run import Row, median_time

from tattotronix.collision.check import TrajectoryClearance, check_trajectory
from tattotronix.collision.model import CollisionModel
from tattotronix.config.params import compose_settings
from tattotronix.io.artifacts import TrajectoryRecord
from tattotronix.robot.description import build_description

TRAJ = TrajectoryRecord.path(Path(__file__).resolve().parents[1] / "data", name="emblem")
N_POINTS = 16_000
GOAL_S = 2.0


def _poses() -> tuple[np.ndarray, np.ndarray, str]:
    if TRAJ.exists():
        z = TrajectoryRecord.load(TRAJ)
        return z.t[:N_POINTS], z.q[:N_POINTS], "emblem"
    t = np.linspace(0.0, 160.0, N_POINTS)
    a = np.array([0.23, 0.53, 0.40, 0.0, 0.64])
    b = np.array([-0.2, 0.9, 0.8, 0.0, 0.9])
    s = 0.5 - 0.5 * np.cos(np.linspace(0, 8 * np.pi, N_POINTS))
    return t, a + s[:, None] * (b - a), "synthetic sweep"


def bench(repeat: int) -> list[Row]:
    t, q, label = _poses()
    rows: list[Row] = []
    setups: list[tuple[str, list[str]]] = [("k-DOP", [])]
    cad = os.environ.get("TATTOTRONIX_CAD_DIR")
    if cad:
        setups.append(("mesh hulls", [f"robot.cad_dir={cad}"]))
    for geometry, overrides in setups:
        cfg = compose_settings(overrides)
        model = CollisionModel(build_description(cfg.robot))
        margin = cfg.collision.margin_m
        plunge_m = float(cfg.toolpath.plunge_mm) / 1000
        resolution_m = float(cfg.collision.resolution_mm) / 1000

        def check(m: CollisionModel = model, g: float = margin, p: float = plunge_m,
                  r: float = resolution_m) -> TrajectoryClearance:
            return check_trajectory(m, t, q, margin_m=g, plunge_m=p, resolution_m=r)

        el, rep = median_time(check, repeat)
        met = rep.metrics()
        rows.append((f"check {len(q)} points [{label}, {geometry}]", el, "s",
                     f"{rep.samples} poses incl. {rep.samples - len(q)} bisections; least "
                     f"clearance {met['min_clearance_mm']:.2f} mm ({'|'.join(met['worst_pair'])})"
                     f"; {len(model.pair_names)} pairs; build {model.build_s:.2f} s"))
        rows.append((f"per pose [{label}, {geometry}]", el / rep.samples * 1e6, "us",
                     "all checked pairs, GJK on convex shapes"))
        rows.append((f"time over goal [{label}, {geometry}]", el / GOAL_S, "x",
                     f"goal {GOAL_S:g} s for {N_POINTS} points on one core"))
    return rows
