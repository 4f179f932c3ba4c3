"""Stage `deploy`: compile a trajectory into the servo program (PCA9685 counts per frame).

Reads data/trajectories/<name>.npz, the collision stage's verdict on it
(data/metrics/collision/<name>.json: refuses a trajectory that was not checked, or not
clean) and the servo calibration (conf/hardware, or
hardware.calibration_file); writes data/deploy/<name>.npz (t, q, counts, channels,
frame_hz, count_us, provenance) and data/metrics/deploy/<name>.json: frames, the largest count step
per channel, the quantisation error per joint (deg) and the tip error it implies.
"""

from __future__ import annotations

import logging
from pathlib import Path

from tattotronix.app.arm import build_program
from tattotronix.art.artwork import artwork_name
from tattotronix.config.schema import Config
from tattotronix.hardware.gate import require_checked
from tattotronix.io.artifacts import ServoProgramRecord, TrajectoryRecord
from tattotronix.io.jsontypes import json_number, json_object
from tattotronix.io.outputs import Outputs
from tattotronix.kinematics import Chain
from tattotronix.robot.description import build_description
from tattotronix.stage import run_stage

log = logging.getLogger("tattotronix.deploy")


def main(cfg: Config, out: Outputs) -> None:
    """Compile the program of one artwork and write it with its metrics."""
    name = artwork_name(cfg.artwork)
    src = out.require(out.input(*TrajectoryRecord.path("", name=name).parts),
                      "trajectory")
    require_checked(out.input("metrics", "collision", f"{name}.json"), src)
    traj = TrajectoryRecord.load(src)
    desc = build_description(cfg.robot)
    program, calib = build_program(cfg, desc, traj.t, traj.q, traj.qd)
    inputs = {"trajectory": src}
    if cfg.hardware.calibration_file:
        inputs["calibration"] = Path(str(cfg.hardware.calibration_file))
    program.record().save(out.tmp_path(ServoProgramRecord.path(out.root, name=name)),
                          out.provenance(cfg, inputs))
    m = {"name": name, **program.metrics(calib, Chain.from_description(desc))}
    out.write_json(out.path("metrics", "deploy", f"{name}.json"), m)
    log.info("deploy %s: %d frames, %.2f us a count; quantisation up to %.3f deg, tip %.2f mm "
             "worst (%.2f mean)", name, m["frames"], m["count_us"],
             max(json_number(v) for v in json_object(m["quantisation_deg"]).values()),
             m["quantisation_tip_mm_max"], m["quantisation_tip_mm_mean"])


if __name__ == "__main__":
    run_stage("deploy", main)
