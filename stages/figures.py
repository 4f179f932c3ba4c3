"""Stage `figures`: the figures of one artwork's drawing.

Reads data/trajectories/<name>.npz ('trajectory' stage), data/runs/<name>-mujoco/log.npz
('simulate' stage) and data/robot/tattotronix.urdf ('robot' stage). Writes
data/figures/<name>/joints.png (q, qd, qdd against the limits), torques.png (gravity along
the trajectory and the simulated torque), steps.png (5 degree steps on the model plant at
the configured wn and at 20 rad/s, against python-control's linear loop) and
tracking.png (the tip error along the whole run and its distribution).
"""

from __future__ import annotations

from tattotronix.art.artwork import artwork_name
from tattotronix.config.schema import Config
from tattotronix.io.outputs import Outputs
from tattotronix.report.figures import draw_figures
from tattotronix.stage import run_stage


def main(cfg: Config, out: Outputs) -> None:
    """Draw the figures of the configured artwork."""
    draw_figures(cfg, out, artwork_name(cfg.artwork))


if __name__ == "__main__":
    run_stage("figures", main)
