"""Stage `animate`: the drawing animation of one artwork, in 2-D and in 3-D.

Reads data/trajectories/<name>.npz ('trajectory' stage), data/robot/tattotronix.urdf and
data/robot/tattotronix.xml ('robot' stage), and data/runs/<name>-mujoco/log.npz
('simulate' stage) when it exists: then the arm and the ink follow the simulated run (ink
where the simulated tip went below the panel surface); without it, the planned trajectory
(said on every frame). Writes data/figures/<name>/drawing.gif (the arm in elevation, the
panel face-on) and data/figures/<name>/drawing3d.gif (MuJoCo's offscreen renderer: the
arm, the panel and the ink in 3-D), and, when imageio-ffmpeg is installed, the same as
drawing.mp4 and drawing3d.mp4.
"""

from __future__ import annotations

# first: a Ctrl-C while the libraries below import ends in one line (tattotronix/__init__.py)
import tattotronix  # noqa: F401

# isort: split
import logging
from pathlib import Path

from tattotronix.art.artwork import artwork_name
from tattotronix.config.schema import Config
from tattotronix.io.artifacts import RunLogRecord, TrajectoryRecord, run_label
from tattotronix.io.outputs import Outputs
from tattotronix.report.animation import DrawingClip, RenderResult, drawing_clip, mp4_available
from tattotronix.report.render3d import render_drawing_both, select_gl
from tattotronix.robot.description import build_description
from tattotronix.stage import run_stage

log = logging.getLogger("tattotronix.animation")

BACKEND = "mujoco"  # the simulate stage's plant


def main(cfg: Config, out: Outputs) -> None:
    """Render the drawing of the configured artwork."""
    gl = select_gl()  # MuJoCo's OpenGL platform: before anything imports mujoco
    name = artwork_name(cfg.artwork)
    desc = build_description(cfg.robot)
    traj = TrajectoryRecord.load(out.require(
        out.input(*TrajectoryRecord.path("", name=name).parts), "trajectory"))
    urdf = out.require(out.input("robot", f"{desc.name}.urdf"), "robot")
    mjcf = out.require(out.input("robot", f"{desc.name}.xml"), "robot")
    run_rel = RunLogRecord.path("", label=run_label(name, BACKEND)).parts
    run_file = out.input(*run_rel)  # a simulate run by hand's log, else the pipeline's
    rec = (RunLogRecord.load_run(out.input_root(*run_rel), name, BACKEND)
           if run_file.exists() else None)
    if rec is None:
        log.info("animate %s: no run log at %s: rendering the planned trajectory (run the "
                 "'simulate' stage to draw what the arm did)", name, run_file)
    clip = drawing_clip(desc, urdf, name, traj.t, traj.q, traj.kind, traj.tcp, traj.marked,
                        cfg.toolpath.panel_origin, run_label=f"the simulated run ({BACKEND})",
                        run_t=None if rec is None else rec.t,
                        run_q=None if rec is None else rec.q,
                        run_tip_m=None if rec is None else rec.tip)
    fig_dir = out.path("figures", name)
    two_d, three_d = render_drawing_both(clip, mjcf, _videos(out, fig_dir, "drawing", name),
                                         _videos(out, fig_dir, "drawing3d", name))
    _log_render(name, "drawing (2-D)", clip, two_d)
    _log_render(name, f"drawing3d (MuJoCo, MUJOCO_GL={gl or 'its default'})", clip, three_d)


def _videos(out: Outputs, fig_dir: Path, stem: str, name: str) -> tuple[Path, Path | None]:
    """The GIF and, when imageio-ffmpeg is installed, the MP4 to write (temporaries)."""
    gif = out.tmp_path(fig_dir / f"{stem}.gif")
    if mp4_available():
        return gif, out.tmp_path(fig_dir / f"{stem}.mp4")
    log.info("animate %s: imageio-ffmpeg is not installed: %s.mp4 not written (pip install "
             "imageio-ffmpeg)%s", name, stem,
             "; the one there is stale" if (fig_dir / f"{stem}.mp4").exists() else "")
    return gif, None


def _log_render(name: str, what: str, clip: DrawingClip, res: RenderResult) -> None:
    log.info("animate %s: %s: %d frames (%.1f s of drawing in %.1f s, x%.1f), GIF %d "
             "frames%s; %.1f s (%s)", name, what, res.frames, clip.duration_s, clip.video_s,
             clip.compression, res.gif_frames, ", MP4" if res.mp4 else "", res.wall_s,
             ", ".join(f"{k} {v:.1f} s" for k, v in res.timings_s.items()))

if __name__ == "__main__":
    run_stage("animate", main)
