"""Stage `kinematics`: the kinematics study of one artwork (docs/kinematics.md; the
original's: docs/original.md, "1.3 Zero pose" and "3.4 Conditioning, reachability,
placement").

Reads data/ik/<name>.npz (run the 'ik' stage first). Writes
data/metrics/kinematics/<name>.json (zero-pose frames; sigma_1, sigma_5, condition and
manipulability along the path, the worst-conditioned point and its weakest direction;
panel reachability; the placement table; the workspace ranges) and the figures
data/figures/<name>/manipulability.png, reachability.png, workspace.png, placement.png.

The study settings (grid size, placements, workspace samples) come from
``cfg.study.kinematics``; the IK settings (seed, dls_lambda, iterations, tolerance, needle
axis) from ``cfg.ik``.
"""

from __future__ import annotations

# first: a Ctrl-C while the libraries below import ends in one line (tattotronix/__init__.py)
import tattotronix  # noqa: F401

# isort: split
import logging
import time
from pathlib import Path
from typing import Any

import numpy as np

from tattotronix.art.artwork import artwork_name
from tattotronix.config.schema import Config
from tattotronix.errors import TattotronixError
from tattotronix.io.artifacts import IkRecord
from tattotronix.io.jsontypes import json_floats
from tattotronix.io.outputs import Outputs
from tattotronix.kinematics import Chain, PinocchioTip
from tattotronix.robot.description import build_description
from tattotronix.stage import run_stage
from tattotronix.studies import kinematics as study

log = logging.getLogger("tattotronix.kinematics")


def _load_ik(src: Path, n_joints: int) -> IkRecord:
    rec = IkRecord.load(src)
    n = len(rec.q)
    if (rec.q.shape != (n, n_joints) or rec.uvz_mm.shape != (n, 3)
            or rec.xyz_m.shape != (n, 3) or len(rec.kind) != n or n == 0):
        raise TattotronixError(f"{src} does not hold a solved path for {n_joints} joints; "
                               "re-run the 'ik' stage")
    return rec


def main(cfg: Config, out: Outputs) -> None:
    """Run the study on one artwork's solved path; write the metrics and four figures."""
    name = artwork_name(cfg.artwork)
    desc = build_description(cfg.robot)
    src = out.require(out.input(*IkRecord.path("", name=name).parts), "ik")
    chain = Chain.from_description(desc)
    ik = _load_ik(src, chain.n)
    ikc = cfg.ik
    sc = cfg.study.kinematics
    settings: dict[str, Any] = {"seed": list(ikc.seed), "needle_axis": list(ikc.needle_axis),
                                "dls_lambda": ikc.dls_lambda, "max_iter": ikc.max_iter,
                                "tol": ikc.tol}
    # the panel origin the toolpath stage used: xyz_m = origin + uvz_mm / 1000
    origin_m = np.median(ik.xyz_m - ik.uvz_mm / 1000.0, axis=0)
    times: dict[str, float] = {}

    t = time.perf_counter()
    ref = PinocchioTip.from_description(desc)
    zero = study.zero_pose_frames(desc, ref)
    times["zero_pose_s"] = time.perf_counter() - t

    t = time.perf_counter()
    pc = study.path_conditioning(chain, ik.q, ik.uvz_mm)
    times["path_conditioning_s"] = time.perf_counter() - t

    t = time.perf_counter()
    reach = study.panel_reachability(chain, desc, sc.reach_nx, sc.reach_ny, ref=ref,
                                     **settings)
    times["reachability_s"] = time.perf_counter() - t
    log.info("kinematics %s: panel reachable %.3f %% (%d of %d cells; failing on the outer "
             "x edge only: %s), %.2f s", name, reach.percent, int(reach.reachable.sum()),
             reach.reachable.size, reach.failures_on_outer_x_edge, reach.solve_s)

    def row_done(p: study.Placement) -> None:
        log.info("kinematics %s: placement %s (reach %g mm, r_max %.1f mm): sigma5 min %.5f, "
                 "cond max %.2f, %.2f %% converged, %.2f s", name, p.label, p.reach_mm,
                 p.r_max_mm, p.sigma5_min, p.cond_max, p.converged_pct, p.solve_s)

    t = time.perf_counter()
    sweep = study.placement_sweep(chain, ik.uvz_mm, ik.kind,
                                  list(sc.placement_widths_mm), list(sc.placement_offsets_mm),
                                  origin_m=origin_m,
                                  anchor_spacing_m=ikc.anchor_spacing_m, progress=row_done,
                                  **settings)
    times["placement_s"] = time.perf_counter() - t

    t = time.perf_counter()
    ws = study.workspace_samples(chain, sc.workspace_samples, sc.workspace_seed)
    times["workspace_s"] = time.perf_counter() - t

    t = time.perf_counter()
    fig_dir = out.path("figures", name)
    panel_mm = [float(v) * 1000.0 for v in desc.panel_size]
    study.manipulability_figure(pc, ik.kind, panel_mm,
                                out.tmp_path(fig_dir / "manipulability.png"), name)
    study.reachability_figure(reach, ik.uvz_mm, ik.kind, panel_mm,
                              out.tmp_path(fig_dir / "reachability.png"), name)
    study.workspace_figure(ws, desc, out.tmp_path(fig_dir / "workspace.png"), reach)
    study.placement_figure(sweep, out.tmp_path(fig_dir / "placement.png"), reach, chain, name)
    times["figures_s"] = time.perf_counter() - t

    metrics: dict[str, Any] = {
        "name": name,
        "zero_pose": zero.summary(),
        "path": pc.summary(),
        "reachability": reach.summary(),
        "placement": sweep.summary(),
        "workspace": ws.summary(chain),
        "panel_origin_m": [float(v) for v in origin_m],
    }
    out.write_json(out.path("metrics", "kinematics", f"{name}.json"), metrics)
    times["reachability_solve_s"] = reach.solve_s
    times.update({f"placement_{p.label}_solve_s": p.solve_s for p in sweep.rows})
    out.write_timings("kinematics", name, times)
    s = pc.summary()
    log.info("kinematics %s: %d points, sigma5 %.5f .. %.5f, cond %.2f .. %.2f, worst at "
             "(%.2f, %.2f) mm", name, s["points"], *json_floats(s["sigma5"]),
             *json_floats(s["cond"]), *json_floats(s["worst_point_mm"])[:2])


if __name__ == "__main__":
    run_stage("kinematics", main)
