"""Regenerate (or check) the tables the project derives from the CAD meshes.

Both are committed, so a clone without the meshes runs on them, and a test holds each to
the meshes where they are present:

* ``mass``: the printed inertial table (``conf/robot/inertials/printed.yaml``):
  :func:`tattotronix.robot.mass.printed_table`, the meshes integrated plus the catalogue
  servos;
* ``kdops``: the links' k-DOP collision polytopes (``tattotronix/collision/kdop.json``):
  :func:`tattotronix.collision.shapes.kdop_offsets` of each mesh.

Usage::

    python -m tattotronix.devtools.tables mass --cad-dir DIR [--write] [overrides ...]
    python -m tattotronix.devtools.tables kdops --cad-dir DIR [--write]

Without ``--write`` each prints what it finds; ``kdops`` exits 1 if the committed table is
further from the meshes than its rounding.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from typing import Any

import numpy as np

from tattotronix.collision import shapes
from tattotronix.config.params import PROJECT_ROOT, compose_settings
from tattotronix.errors import ConfigError, TattotronixError
from tattotronix.robot import mass
from tattotronix.robot.stl import mesh_dir_files

__all__ = ["kdops_main", "main", "mass_main"]


def mass_main(cad_dir: str, write: bool, overrides: Sequence[str]) -> int:
    """Integrate the meshes in ``cad_dir`` and print each link's mass; ``write`` rewrites
    the committed table."""
    from pathlib import Path

    try:
        cad = Path(cad_dir).expanduser().resolve()
        cfg = compose_settings([*overrides, f"robot.cad_dir={cad}"])
        table = mass.printed_table(cfg.robot)
        text = mass.table_yaml(table)
    except (TattotronixError, ConfigError) as exc:
        print(f"mass: error: {exc}", file=sys.stderr)
        return 2
    report: dict[str, Any] = mass.mass_report(table, cfg.robot)  # read back: JSON values
    for link, row in report["links"].items():
        print(f"{link:16s} V {row['volume_cm3']:8.3f} cm3  shell {row['shell_g']:7.2f} g  "
              f"servos {row['servos_g']:6.1f} g  total {row['total_g']:7.2f} g")
    t = report["totals"]
    print(f"arm {t['arm_kg']:.5f} kg, moving (incl. pen) {t['moving_kg']:.5f} kg")
    if write:
        target = PROJECT_ROOT / mass.INERTIALS_FILE
        tmp = target.with_name(f".{target.name}.tmp")
        tmp.write_text(text, encoding="utf-8")
        tmp.replace(target)
        print(f"wrote {target}")
    return 0


def kdops_main(cad_dir: str, write: bool) -> int:
    """Compare the committed k-DOP table with the meshes in ``cad_dir`` (0: within its
    rounding, 1: not); ``write`` rewrites it."""
    robot = compose_settings().robot
    links = [robot.base_link] + [j.child for j in robot.joints]
    scale = float(robot.mesh_scale)
    if write:
        shapes.write_kdops(cad_dir, links, scale)
        print(f"wrote {shapes.KDOP_FILE}")
        return 0
    files = mesh_dir_files(cad_dir, links)
    stored = shapes.load_kdops()
    worst = 0.0
    for link, f in files.items():
        fresh = shapes.kdop_offsets(shapes.mesh_vertices(f, scale))
        if link not in stored:
            print(f"{link}: not in {shapes.KDOP_FILE.name}")
            return 1
        worst = max(worst, float(np.abs(fresh - stored[link]).max()))
    print(f"largest difference from the meshes: {worst * 1000:.4f} mm")
    return 0 if worst <= shapes.KDOP_ROUND_M else 1


def main(argv: Sequence[str] | None = None) -> int:
    """The command line (see the module docstring)."""
    ap = argparse.ArgumentParser(prog="python -m tattotronix.devtools.tables",
                                 description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="table", required=True)
    m = sub.add_parser("mass", help="the printed inertial table, from the meshes")
    k = sub.add_parser("kdops", help="the links' k-DOP collision polytopes, from the meshes")
    for p in (m, k):
        p.add_argument("--cad-dir", required=True, help="folder of <link>.stl meshes (cm)")
        p.add_argument("--write", action="store_true", help="rewrite the committed table")
    m.add_argument("overrides", nargs="*", help="Hydra overrides (e.g. robot.mesh_scale=0.01)")
    args = ap.parse_args(argv)
    if args.table == "mass":
        return mass_main(args.cad_dir, args.write, args.overrides)
    return kdops_main(args.cad_dir, args.write)


if __name__ == "__main__":
    raise SystemExit(main())
