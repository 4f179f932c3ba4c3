"""Stage ``surface``: a drawing on a curved work surface (issue 33; docs/surface.md).

Run with ``surface=forearm`` (the built-in phantom) or ``surface=mesh
surface.mesh_file=PATH``. Plans the artwork's design in its own plane, lays it on the
surface at ``surface.along_mm``/``around_deg``/``turn_deg`` (the chart's distortion over
the design checked against ``surface.max_distortion_pct``), carries the needle path onto
it along the normals and solves the IK with the needle along the inward normal at every
point, then plays it closed loop on ``backend`` (a simulated plant) and scores the tip's
tracking and the ink in the skin against the plan and the artwork, in the design's chart
(tattotronix/app/onskin.py); on the phantom, maps where the arm can put the needle along
the normal (tattotronix/kinematics/onsurface.py). Writes ``data/surface/<name>.npz`` (the
surface's mesh, the skin path, the joint angles, the reachability map),
``data/metrics/surface/<name>.json`` (its ``run`` section: the simulation) and
``data/figures/surface/<name>.png``, ``<name>-ink.png`` (the simulated ink against the
artwork, in the design's chart), ``<name>-limb.png`` (that ink carried onto the limb, in
3-D) and ``<name>-drawing3d.gif`` and ``.mp4`` (the drawing as a film: MuJoCo's offscreen
renderer, the pen as the run moved it, the ink growing on the limb, seen close).
``viewer=true`` shows the run, the limb in the panel's place, in the engine's viewer where
a display exists.
"""

from __future__ import annotations

# first: a Ctrl-C while the libraries below import ends in one line (tattotronix/__init__.py)
import tattotronix  # noqa: F401

# isort: split
import logging

import numpy as np
from numpy.typing import ArrayLike

from tattotronix.app.onskin import plan_on_surface, simulate_on_surface
from tattotronix.art.artwork import artwork_name
from tattotronix.config.schema import Config
from tattotronix.control.verdict import length_text
from tattotronix.io.artifacts import PROVENANCE_KEY
from tattotronix.io.npz import save_npz
from tattotronix.io.outputs import Outputs
from tattotronix.kinematics import Chain
from tattotronix.kinematics.ik import ik_options
from tattotronix.kinematics.onsurface import PointsReach, SurfaceReach, cone_reach, mesh_reach
from tattotronix.path.inkfigure import artwork_ink_figure
from tattotronix.report.render3d import select_gl
from tattotronix.report.surface import limb_ink_figure, skin_drawing_video, surface_figure
from tattotronix.robot.description import build_description
from tattotronix.stage import run_stage

log = logging.getLogger("tattotronix.surface")


def main(cfg: Config, out: Outputs) -> None:
    """Lay the design on the surface, solve it, map the reach; write the outputs."""
    gl = select_gl()  # the video's OpenGL platform: before anything imports mujoco
    name = artwork_name(cfg.artwork)
    desc = build_description(cfg.robot)
    d = plan_on_surface(cfg, cfg.artwork.source, name, desc)
    run = simulate_on_surface(cfg, out.data, desc, d, name,
                              progress=bool(cfg.draw.progress), viewer=bool(cfg.viewer))
    s = cfg.surface
    chain, depth = Chain.from_description(desc), float(cfg.toolpath.plunge_mm)
    reach: SurfaceReach | PointsReach
    if d.surface.cone is not None:
        reach = cone_reach(chain, d.surface.cone, depth, ik_options(cfg.ik),
                           list(cfg.ik.seed), n_along=int(s.reach_along),
                           n_around=int(s.reach_around),
                           margin_mm=float(s.reach_margin_mm))
    else:  # a mesh: as many of its vertices as the phantom's grid has points
        reach = mesh_reach(chain, d.surface.vertices, d.surface.faces, depth,
                           ik_options(cfg.ik), list(cfg.ik.seed),
                           points=int(s.reach_along) * int(s.reach_around))
    metrics = d.summary()
    metrics["artwork_width_mm"] = (None if cfg.mask.width_mm is None
                                   else float(cfg.mask.width_mm))
    reach_figures = reach.summary()
    metrics["reach"] = reach_figures
    ran = run.summary()
    metrics["run"] = {"backend": cfg.backend.name, **ran}
    arrays: dict[str, ArrayLike] = {
        "vertices_mm": d.surface.vertices, "faces": d.surface.faces,
        "xyz_mm": d.skin.xyz_mm, "axis": d.skin.axis, "kind": d.skin.kind,
        "uvz_mm": d.skin.uvz_mm, "q": d.ik.q, "tilt_deg": d.tilt_deg}
    if isinstance(reach, SurfaceReach):
        arrays.update(reach_along_mm=reach.along_mm, reach_around_deg=reach.around_deg)
    else:
        arrays.update(reach_xyz_m=reach.xyz_m, reach_normal=reach.normal)
    arrays.update(reachable=reach.reachable, reach_tilt_deg=reach.tilt_deg,
                  reach_cond=reach.cond)
    arrays[PROVENANCE_KEY] = np.array(out.provenance(cfg, {}))
    save_npz(out.tmp_path(out.path("surface", f"{name}.npz")), arrays)
    out.write_json(out.path("metrics", "surface", f"{name}.json"), metrics)
    surface_figure(d, reach, out.tmp_path(out.path("figures", "surface", f"{name}.png")),
                   f"{name}: the design laid on the skin, the needle along the normal")
    artwork_ink_figure(
        run.art, run.sim_ink, run.grid,
        out.tmp_path(out.path("figures", "surface", f"{name}-ink.png")),
        f"{name} on the {d.surface.kind} ({cfg.backend.name}): the simulated ink in the "
        f"skin, in the design's chart, against the artwork (needle "
        f"{float(cfg.toolpath.needle_width_mm):g} mm)",
        run.artwork if run.artwork is not None else f"ink {run.reason}")
    limb_ink_figure(
        d, run, out.tmp_path(out.path("figures", "surface", f"{name}-limb.png")),
        f"{name} on the {d.surface.kind} ({cfg.backend.name}): the simulated ink on the "
        f"limb ({run.ink.text()})")
    video = skin_drawing_video(
        d, run, desc, out.require(out.input("robot", f"{desc.name}.urdf"), "robot"),
        out.require(out.input("robot", f"{desc.name}.xml"), "robot"), name,
        out.tmp_path(out.path("figures", "surface", f"{name}-drawing3d.gif")),
        out.tmp_path(out.path("figures", "surface", f"{name}-drawing3d.mp4")))
    log.info("surface %s: the 3-D film (MuJoCo, MUJOCO_GL=%s): %d frames, %.1f s", name,
             gl or "its default", video.frames, video.wall_s)
    dist = d.distortion
    log.info("surface %s: %d points, distortion area %.4f %% angle %.4f %%, IK %s %%, "
             "tilt worst %.2e deg, needle %s deg from vertical%s", name,
             len(d.skin.kind), 100 * dist.area_worst, 100 * dist.angle_worst,
             metrics["ik_converged_pct"], float(np.max(d.tilt_deg)),
             metrics["needle_from_vertical_deg"],
             f"; {reach_figures['reachable_pct']} % of the "
             f"{'phantom' if d.surface.cone is not None else 'mesh'} reachable")
    log.info("surface %s on %s: %s; marking max %s, settled mean %s; ink %s", name,
             cfg.backend.name, ran["verdict"], length_text(_um(ran["marking_max_um"])),
             length_text(_um(ran["settled_mean_um"])), run.ink.text())


def _um(value: object) -> float | None:
    return float(value) if isinstance(value, int | float) else None


if __name__ == "__main__":
    run_stage("surface", main)
