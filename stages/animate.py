"""Stage `animate`: the drawing animation of one artwork.

Reads data/trajectories/<name>.npz ('trajectory' stage) and data/robot/tattotronix.urdf
('robot' stage), and data/runs/<name>-mujoco/log.npz ('simulate' stage) when it exists:
then the arm and the ink follow the simulated run (ink where the simulated tip went below
the panel surface); without it, the planned trajectory (said on every frame). Writes
data/figures/<name>/drawing.gif and, when imageio-ffmpeg is installed,
data/figures/<name>/drawing.mp4.
"""

from __future__ import annotations

import logging

import numpy as np

from tattotronix.art.artwork import artwork_name
from tattotronix.config.schema import Config
from tattotronix.io.artifacts import RunLogRecord, TrajectoryRecord, run_label
from tattotronix.io.outputs import Outputs
from tattotronix.report.animation import drawing_clip, mp4_available, render_drawing
from tattotronix.robot.description import build_description
from tattotronix.stage import run_stage
from tattotronix.trajectory import load_trajectory

log = logging.getLogger("tattotronix.animation")

BACKEND = "mujoco"  # the simulate stage's plant


def main(cfg: Config, out: Outputs) -> None:
    """Render the drawing of the configured artwork."""
    name = artwork_name(cfg.artwork)
    desc = build_description(cfg.robot)
    traj = load_trajectory(TrajectoryRecord.require(out.data, name=name))
    urdf = out.require(out.input("robot", f"{desc.name}.urdf"), "robot")
    run_file = RunLogRecord.path(out.data, label=run_label(name, BACKEND))
    run: dict[str, np.ndarray] = {}
    if run_file.exists():
        rec = RunLogRecord.load_run(out.data, name, BACKEND)
        run = {"run_t": rec.t, "run_q": rec.q, "run_tip_m": rec.tip}
    else:
        log.info("animate %s: no run log at %s: rendering the planned trajectory (run the "
                 "'simulate' stage to draw what the arm did)", name, run_file)
    clip = drawing_clip(desc, urdf, name, traj.t, traj.q, traj.kind, traj.tcp, traj.marked,
                        cfg.toolpath.panel_origin, run_label=f"the simulated run ({BACKEND})",
                        **run)
    fig_dir = out.path("figures", name)
    gif = out.tmp_path(fig_dir / "drawing.gif")
    mp4 = None
    if mp4_available():
        mp4 = out.tmp_path(fig_dir / "drawing.mp4")
    else:
        log.info("animate %s: imageio-ffmpeg is not installed: drawing.mp4 not written "
                 "(pip install imageio-ffmpeg)%s", name,
                 "; the one there is stale" if (fig_dir / "drawing.mp4").exists() else "")
    res = render_drawing(clip, gif=gif, mp4=mp4)
    log.info("animate %s: %d frames (%.1f s of drawing in %.1f s, x%.1f), GIF %d frames%s; "
             "%.1f s (%s)", name, res.frames, clip.duration_s, clip.video_s, clip.compression,
             res.gif_frames, ", MP4" if res.mp4 else "", res.wall_s,
             ", ".join(f"{k} {v:.1f} s" for k, v in res.timings_s.items()))


if __name__ == "__main__":
    run_stage("animate", main)
