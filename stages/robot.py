"""Stage `robot`: generate data/robot/tattotronix.{urdf,xml} and the zero-pose report, and
publish the robot settings they came from (data/robot/config.json: every stage that builds
the description depends on this file, not on the `robot` params, so dvc.lock holds them
once).

    python stages/robot.py [robot.mass_model=box] [robot.tool=none] [robot.cad_dir=DIR]
"""

from __future__ import annotations

import logging

from tattotronix.config.schema import Config, to_dict
from tattotronix.io.outputs import Outputs
from tattotronix.report.robot import generate
from tattotronix.robot.description import build_description
from tattotronix.stage import run_stage

log = logging.getLogger("tattotronix.robot")


def main(cfg: Config, out: Outputs) -> None:
    """Build the description, generate both model files, and report on them."""
    desc = build_description(cfg.robot)
    models = generate(desc)
    out.write_text(out.path("robot", f"{desc.name}.urdf"), models.urdf)
    out.write_text(out.path("robot", f"{desc.name}.xml"), models.mjcf)
    out.write_json(out.path("metrics", "robot.json"), models.report)
    out.write_json(out.path("robot", "config.json"), to_dict(cfg.robot))
    r = models.report
    log.info("tcp at zero pose %s mm, highest point %.2f mm, moving mass %.4f kg (%s, %s)",
             r["tcp_zero_mm"], r["highest_point_mm"], r["moving_mass_kg"], r["mass_model"],
             r["geometry"])


if __name__ == "__main__":
    run_stage("robot", main)
