"""Stage `actuator`: what hobby servos allow at the needle (docs/actuators.md; the
original's study: docs/original.md, "6.6 The actuator study").

Reads data/trajectories/<name>.npz (run the 'trajectory' stage first). Writes
data/metrics/actuator/<name>.json (the declared steps and dead bands, each option's rest
band per joint, worst and typical lateral error, worst depth error, times the line; the
worst-pose levers; the band every joint must hold), data/studies/actuator/<name>.npz (the
per-option worst lateral error along the drawing, every 4th pose: too long for a metrics
file under git) and the figure data/figures/<name>/actuator.png.

The study settings and options come from ``cfg.study.actuator``; the servo per joint and
the dead bands from ``cfg.robot``; the PCA9685 frame rate from the servo calibration
(``hardware.calibration_file`` if set, else ``hardware.servos``); the line width from
``toolpath.needle_width_mm`` and the plunge from ``toolpath.plunge_mm``.
"""

from __future__ import annotations

import logging
from typing import Any

from tattotronix.art.artwork import artwork_name
from tattotronix.config.schema import Config
from tattotronix.hardware.arm import calibration_from_config
from tattotronix.io.artifacts import StudySeriesRecord, TrajectoryRecord
from tattotronix.io.outputs import Outputs
from tattotronix.kinematics import Chain
from tattotronix.robot.description import build_description
from tattotronix.stage import run_stage
from tattotronix.studies import actuator as study

log = logging.getLogger("tattotronix.actuator")


def main(cfg: Config, out: Outputs) -> None:
    """Run the actuator study on one artwork's trajectory; write metrics, series, figure."""
    name = artwork_name(cfg.artwork)
    src = out.require(out.input(*TrajectoryRecord.path("", name=name).parts),
                      "trajectory")
    desc = build_description(cfg.robot)
    chain = Chain.from_description(desc)
    frame_hz = calibration_from_config(cfg.hardware, desc.joint_names).frame_hz
    res = study.study_from_config(cfg, chain, TrajectoryRecord.load(src), frame_hz=frame_hz)

    target = StudySeriesRecord.path(out.root, "actuator", name)
    series: dict[str, Any] = study.series_arrays(res)
    StudySeriesRecord(series).save(out.tmp_path(target),
                                   out.provenance(cfg, {"trajectory": src}))
    study.figure(res, out.tmp_path(out.path("figures", name, "actuator.png")), name)
    metrics = {"name": name, **study.metrics(res),
               "series_file": target.relative_to(out.root).as_posix()}
    out.write_json(out.path("metrics", "actuator", f"{name}.json"), metrics)

    d = res.declared
    log.info("actuator %s: %d poses (every %d marking point); PCA9685 step %.7g us, "
             "line %g mm, plunge %g mm", name, len(res.poses.t_s), res.poses.every,
             d.pca9685_step_us, res.line_mm, res.plunge_mm)
    for o in res.options:
        log.info("actuator %s: %s: rest %s deg; lateral worst %.3f mm (median of per-pose "
                 "worst %.3f), typical %.3f mm, depth worst %.3f mm, %.2f x line", name,
                 o.name, ", ".join(f"{e:.4f}" for e in o.rest_deg), o.lateral_worst,
                 o.lateral_worst_median, o.lateral_rms_median, o.depth_worst,
                 res.times_line(o))
    log.info("actuator %s: worst-pose levers lateral / depth mm/deg: %s", name,
             "; ".join(f"{j} {a:.3f} / {b:.3f}" for j, a, b in
                       zip(res.joints, res.lever_lateral_worst, res.lever_depth_worst,
                           strict=True)))
    log.info("actuator %s: %g deg of play at every joint: %.3f mm lateral; every joint must "
             "hold %.4f deg; %g deg of backlash costs up to %.3f mm", name, res.play_deg,
             res.play_lateral_mm_per_deg * res.play_deg, res.required_deg, res.backlash_deg,
             res.backlash_lateral_mm)


if __name__ == "__main__":
    run_stage("actuator", main)
