"""Stage ``mass``: report the printed inertial table (and check it against the meshes).

* ``robot.cad_dir`` null: the committed table ``conf/robot/inertials/printed.yaml`` is
  used as is; ``data/metrics/mass.json`` says so and gives its totals.
* ``robot.cad_dir`` set: every link's mesh is integrated (``tattotronix.robot.mass``);
  the metrics add the per-link difference against the committed table and the sha256 of
  each mesh. The committed table is rewritten only by
  ``python -m tattotronix.devtools.tables mass --cad-dir DIR --write``.
"""

from __future__ import annotations

import logging

from tattotronix.config.schema import Config
from tattotronix.io.jsontypes import json_number, json_object
from tattotronix.io.outputs import Outputs
from tattotronix.robot.mass import (
    INERTIALS_FILE,
    inertia_problems,
    mass_report,
    mesh_sha256,
    printed_table,
    resolve_cad_dir,
    table_difference,
    table_from_config,
)
from tattotronix.stage import run_stage

log = logging.getLogger("tattotronix")

#: Largest relative difference (mass, inertia entries) still counted as "the same table":
#: the committed file rounds com to 1e-6 m and inertia to 7 significant digits.
SAME_TABLE_RTOL = 1e-5


def main(cfg: Config, out: Outputs) -> None:
    """Write ``data/metrics/mass.json``."""
    robot = cfg.robot
    committed = table_from_config(robot)
    if robot.cad_dir is None:
        report = mass_report(committed, robot)
        report["source"] = (
            f"committed table {INERTIALS_FILE} (robot.cad_dir is null: no meshes integrated)"
        )
        table = committed
    else:
        table = printed_table(robot)
        report = mass_report(table, robot)
        diff = table_difference(table, committed)
        worst = max(d["max_rel"] for d in diff.values())
        report["source"] = "meshes"
        report["cad_dir"] = str(resolve_cad_dir(robot.cad_dir))
        report["mesh_sha256"] = mesh_sha256(robot)
        report["committed_table"] = {
            "file": str(INERTIALS_FILE),
            "per_link": diff,
            "max_rel_diff": worst,
            "up_to_date": worst <= SAME_TABLE_RTOL,
        }
        if worst > SAME_TABLE_RTOL:
            log.warning(
                "mass: the committed table differs from the meshes by up to %.3g (relative);"
                " regenerate it: python -m tattotronix.devtools.tables mass --cad-dir %s --write",
                worst,
                report["cad_dir"],
            )
    report["inertia_problems"] = {
        link: probs for link, p in table.items() if (probs := inertia_problems(p.inertia))
    }
    t = json_object(report["totals"])
    log.info(
        "mass (%s): arm %.4f kg, moving %.4f kg incl. pen, servos %.1f %%",
        str(report["source"]).split(" ")[0],
        json_number(t["arm_kg"]),
        json_number(t["moving_kg"]),
        json_number(t["servos_share_pct"]),
    )
    out.write_json(out.path("metrics", "mass.json"), report)


if __name__ == "__main__":
    run_stage("mass", main)
