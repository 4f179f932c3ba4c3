"""Stage `robot_figures`: the figures of the arm itself (no artwork involved).

Reads data/robot/tattotronix.urdf ('robot' stage) and data/metrics/mass.json ('mass'
stage). Writes data/figures/robot/chain.png (every frame at the zero pose and at a drawing
pose, the tip at the panel origin with the needle down, in elevation and plan) and
data/figures/robot/mass.png (shell and servo mass per link, the link CoMs on the arm).
"""

from __future__ import annotations

# first: a Ctrl-C while the libraries below import ends in one line (tattotronix/__init__.py)
import tattotronix  # noqa: F401

# isort: split
import json
import logging

import numpy as np

from tattotronix.config.schema import Config
from tattotronix.errors import TattotronixError
from tattotronix.io.outputs import Outputs
from tattotronix.report.figures import arm_poses, chain_figure, mass_figure, panel_pose
from tattotronix.robot.description import build_description
from tattotronix.stage import run_stage

log = logging.getLogger("tattotronix.figures")


def main(cfg: Config, out: Outputs) -> None:
    """Draw the chain and the mass model."""
    desc = build_description(cfg.robot)
    urdf = out.require(out.input("robot", f"{desc.name}.urdf"), "robot")
    mass_file = out.require(out.input("metrics", "mass.json"), "mass")
    try:
        report = json.loads(mass_file.read_text(encoding="utf-8"))
        report["links"]
    except (OSError, ValueError, KeyError) as exc:
        raise TattotronixError(f"cannot read {mass_file} ({exc}): re-run the 'mass' stage") \
            from None
    origin = np.asarray(cfg.toolpath.panel_origin, dtype=np.float64)
    q_draw = panel_pose(desc, urdf, origin, cfg.ik.seed, cfg.ik.needle_axis)
    poses = arm_poses(desc, urdf, np.vstack([np.zeros(len(desc.joints)), q_draw]))
    fig_dir = out.path("figures", "robot")
    chain_figure(poses, ["zero pose (q = 0)", "drawing pose: tip at the panel origin,\n"
                         "needle down"],
                 desc.panel_centre, desc.panel_size, origin,
                 out.tmp_path(fig_dir / "chain.png"),
                 f"{desc.name}: the chain and its frames (Pinocchio FK of the generated URDF)")
    mass_figure(report, out.tmp_path(fig_dir / "mass.png"), poses,
                f"{desc.name}: the {desc.mass_model} mass model")
    log.info("robot figures: chain (drawing pose q = %s rad), mass", np.round(q_draw, 4))


if __name__ == "__main__":
    run_stage("robot_figures", main)
