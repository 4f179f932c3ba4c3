"""Work surfaces (issue 33): how fast a design is charted onto the forearm phantom and onto
a mesh of it, and how far each chart is from an isometry.

* ``cone chart``: the phantom's exact chart (its development), then 100,000 design points
  carried onto it.
* ``mesh``: the phantom as a closed STL of 25,600 faces (``EllipticCone.mesh``) read and
  checked; its chart (geodesic patch, LSCM) of a 60 mm design; the same 100,000 points.
* ``distortion``: worst area and angle distortion of both charts over a 50 x 50 mm design
  at five placements around the limb (the cone's is exact, so the mesh's is the cost of
  its triangles), and the worst distance between them (the mesh chart's ``u`` follows
  the limb's axis projected onto the surface, the cone's its generator: off the top,
  they differ by the taper's slope).
* ``reach``: the reachability map of the phantom lying across the arm's reach (its axis
  along the arm frame's y, its underside on the bench) at four distances from the base:
  the share of a 23 x 36 grid the needle reaches 1.5 mm in along the inward normal, the
  worst tilt error, and the time of the map.

    python benchmarks/bench_surface.py [--repeat 3]
"""

from __future__ import annotations

import math
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from run import Row, bench_main, median_time

from tattotronix.config.params import compose_settings
from tattotronix.kinematics import Chain, ik_options
from tattotronix.kinematics.onsurface import cone_reach
from tattotronix.robot.description import build_description
from tattotronix.surface.chart import distortion
from tattotronix.surface.cone import EllipticCone
from tattotronix.surface.mesh import MeshChart, load_mesh

PHANTOM = EllipticCone(220.0, 80.0, 55.0, 0.75)
#: (along the axis mm, around deg): the patch (45 mm) clear of the ends (over an end, its
#: crease is a distortion of tens of percent, which the bound refuses)
PLACEMENTS = ((110.0, 90.0), (60.0, 60.0), (160.0, 120.0), (110.0, 30.0), (70.0, 90.0))


def bench(repeat: int) -> list[Row]:
    rng = np.random.default_rng(0)
    pts = rng.uniform(-25.0, 25.0, (100_000, 2))
    rows: list[Row] = []
    t_cone, _ = median_time(lambda: PHANTOM.chart(110.0, 90.0).to_surface(pts), repeat)
    rows.append(("cone chart + 100k points", t_cone, "s", "exact development"))
    with tempfile.TemporaryDirectory() as tmp:
        import trimesh

        v, f = PHANTOM.mesh(80, 160)
        stl = Path(tmp) / "phantom.stl"
        trimesh.Trimesh(v, f, process=False).export(stl)
        t_load, (verts, faces) = median_time(lambda: load_mesh(stl), repeat)
        rows.append(("mesh read and checked", t_load, "s", f"{len(faces)} faces"))
        top = PHANTOM.point(np.array([110.0]), np.array([math.pi / 2]))[0]
        t_chart, chart = median_time(lambda: MeshChart(verts, faces, top, 45.0), repeat)
        rows.append(("mesh chart (patch, LSCM)", t_chart, "s", "45 mm geodesic radius"))
        t_map, _ = median_time(lambda: chart.to_surface(pts), repeat)
        rows.append(("mesh chart: 100k points", t_map, "s", ""))
        worst_cone = worst_mesh = gap = 0.0
        for x, theta in PLACEMENTS:
            exact = PHANTOM.chart(x, theta)
            at = PHANTOM.point(np.array([x]), np.array([math.radians(theta)]))[0]
            mesh = MeshChart(verts, faces, at, 45.0)
            box = (-25.0, -25.0, 25.0, 25.0)
            dc, dm = distortion(exact, box), distortion(mesh, box)
            worst_cone = max(worst_cone, dc.area_worst, dc.angle_worst)
            worst_mesh = max(worst_mesh, dm.area_worst, dm.angle_worst)
            grid = pts[:2000]
            gap = max(gap, float(np.linalg.norm(exact.to_surface(grid).xyz
                                                - mesh.to_surface(grid).xyz, axis=1).max()))
    rows += [("distortion, cone chart (worst)", 100 * worst_cone, "%",
              f"{len(PLACEMENTS)} placements, 50 x 50 mm; goal <= 0.5 %"),
             ("distortion, mesh chart (worst)", 100 * worst_mesh, "%", "the same"),
             ("mesh chart from the exact (worst)", gap, "mm", "2,000 points a placement")]
    cfg = compose_settings()
    chain = Chain.from_description(build_description(cfg.robot))
    for x_mm in (130.0, 150.0, 170.0, 190.0):
        pose = np.eye(4)
        pose[:3, :3] = [[0, -1, 0], [1, 0, 0], [0, 0, 1]]  # limb x -> arm y
        pose[:3, 3] = [x_mm, -110.0, 30.0]
        limb = EllipticCone(220.0, 80.0, 55.0, 0.75, pose)
        t0 = time.perf_counter()
        reach = cone_reach(chain, limb, 1.5, ik_options(cfg.ik), list(cfg.ik.seed))
        t_reach = time.perf_counter() - t0
        ok = reach.reachable
        rows.append((f"reach, axis {x_mm:.0f} mm from the base", 100.0 * float(ok.mean()),
                     "%", f"tilt error <= {np.nanmax(reach.tilt_deg):.4f} deg, steepest "
                     f"{reach.from_vertical_deg[ok].max():.0f} deg from vertical, "
                     f"{t_reach:.1f} s"))
    return rows


def main(argv: Sequence[str] | None = None) -> int:
    return bench_main(bench, __doc__ or "", argv, repeat=3)


if __name__ == "__main__":
    raise SystemExit(main())
