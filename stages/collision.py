"""Stage `collision`: prove a trajectory free of collisions, or report one pose.

    python stages/collision.py [artwork.name=NAME] [robot.cad_dir=DIR]
    python stages/collision.py pose=[q1,q2,q3,q4,q5]

Without ``pose``: reads data/trajectories/<name>.npz and checks every sample and the
motion between samples against the margin (``collision.*``); writes
data/metrics/collision/<name>.json (``min_clearance_mm``, ``worst_pair``,
``collisions``, the clearance of every pair) and data/figures/<name>/clearance.png, or
refuses (writing nothing) naming the time, the pose and the pair.

With ``pose``: prints that pose's clearance report as one JSON object on stdout
(``collisions``, ``min_clearance_mm``, ``worst_pair``, ...) and writes nothing.
"""

from __future__ import annotations

import json
import logging

from tattotronix.art.artwork import artwork_name
from tattotronix.collision.check import CollisionRefused, check_trajectory
from tattotronix.collision.model import CollisionModel, parse_pose
from tattotronix.config.schema import Config
from tattotronix.io.artifacts import TrajectoryRecord
from tattotronix.io.outputs import Outputs
from tattotronix.io.provenance import file_sha256
from tattotronix.report.figures import clearance_figure
from tattotronix.robot.description import build_description
from tattotronix.stage import logs_to_stderr, run_stage

log = logging.getLogger("tattotronix.collision")


def main(cfg: Config, out: Outputs) -> None:
    """Check one artwork's trajectory, or report one pose."""
    desc = build_description(cfg.robot)
    margin = cfg.collision.margin_m
    if cfg.pose is not None:
        logs_to_stderr()
        model = CollisionModel(desc)
        report = model.pose_report(parse_pose(cfg.pose, desc))
        print(json.dumps(report.to_json(margin, model.geometry), allow_nan=False), flush=True)
        return
    name = artwork_name(cfg.artwork)
    src = out.require(out.input(*TrajectoryRecord.path("", name=name).parts),
                      "trajectory")
    traj = TrajectoryRecord.load(src)
    model = CollisionModel(desc)
    rep = check_trajectory(model, traj.t, traj.q, margin_m=margin,
                           plunge_m=cfg.toolpath.plunge_m,
                           resolution_m=cfg.collision.resolution_m, tcp=traj.tcp)
    if not rep.ok:
        raise CollisionRefused(rep)
    metrics = {"name": name, "geometry": model.geometry, **rep.metrics(),
               "trajectory_sha256": file_sha256(src)}
    fig = out.path("figures", name, "clearance.png")
    clearance_figure(rep, traj.t, traj.kind, out.tmp_path(fig))
    out.write_json(out.path("metrics", "collision", f"{name}.json"), metrics)
    out.write_timings("collision", name, rep.timings_s)
    log.info("collision %s (%s): %d poses, %d segments bisected; least clearance %.2f mm "
             "(%s), margin %g mm; needle %.3f mm deep (plunge %g mm); %.2f s", name,
             model.geometry, rep.samples, rep.bisected, metrics["min_clearance_mm"],
             " and ".join(map(str, pair)) if isinstance(pair := metrics["worst_pair"], list)
             else str(pair), metrics["margin_mm"],
             metrics["needle_depth_max_mm"], metrics["plunge_mm"], rep.timings_s["total"])


if __name__ == "__main__":
    run_stage("collision", main)
