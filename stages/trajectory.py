"""Stage `trajectory`: time the IK path within the joint limits and export the npz.

Reads data/ik/<name>.npz and data/robot/tattotronix.urdf (hashed into the provenance);
writes data/trajectories/<name>.npz (joints, t, q, qd, qdd, kind, marked, tcp,
provenance) and data/metrics/trajectory/<name>.json (with planned travel, also the
duration of the same path with straight travel lines, for comparison). Refuses (writing nothing) a
``speed`` that cannot hold the marking feed within the joint limits, naming the joint,
the rate it would need and the fastest speed the drawing can go.
"""

from __future__ import annotations

import logging

from tattotronix.app.pipeline import straight_travel_baseline, trajectory_from_path
from tattotronix.app.records import save_trajectory
from tattotronix.art.artwork import artwork_name
from tattotronix.config.schema import Config
from tattotronix.io.artifacts import IkRecord
from tattotronix.io.outputs import Outputs
from tattotronix.robot.description import build_description
from tattotronix.stage import run_stage
from tattotronix.trajectory import JointPath

log = logging.getLogger("tattotronix.trajectory")


def main(cfg: Config, out: Outputs) -> None:
    """Plan the trajectory of one artwork and write it with its metrics."""
    name = artwork_name(cfg.artwork)
    src = out.require(out.input(*IkRecord.path("", name=name).parts), "ik")
    desc = build_description(cfg.robot)
    urdf = out.require(out.input("robot", f"{desc.name}.urdf"), "robot")
    path = JointPath.from_npz(src)
    traj = trajectory_from_path(cfg, path, desc)
    save_trajectory(out, cfg, name, traj, {"ik": src, "urdf": urdf})
    metrics = {"name": name, **traj.metrics()}
    if traj.moves:
        base = straight_travel_baseline(cfg, path, desc)
        metrics["straight_travel_duration_s"] = base["duration_s"]
    out.write_json(out.path("metrics", "trajectory", f"{name}.json"), metrics)
    out.write_timings("trajectory", name, traj.timings_s)
    log.info("trajectory %s: %d points (%d inserted), %.1f s for %.1f s of marking "
             "(x%.3f), %d entries, peak %.2f rad/s, %.2f rad/s^2, fastest speed %s; "
             "planned in %.3f s", name, metrics["points"], metrics["points_inserted"],
             metrics["duration_s"], metrics["marking_only_s"], metrics["cycle_over_marking"],
             metrics["entries"], metrics["peak_rate_rad_s_max"],
             metrics["peak_accel_rad_s2_max"], metrics["fastest_speed"],
             traj.timings_s["total"])


if __name__ == "__main__":
    run_stage("trajectory", main)
