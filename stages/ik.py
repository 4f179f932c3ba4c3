"""Stage `ik`: joint angles for every toolpath point (batched DLS on the 5x5 task Jacobian).

Reads data/toolpath/<name>.npz and data/robot/tattotronix.urdf; writes data/ik/<name>.npz
(joints, q, kind, uvz_mm, xyz_m, tcp, residual, stroke, provenance) and
data/metrics/ik/<name>.json.
Refuses to write anything when a point fails: the message names the point (panel mm),
its residual and the reason.
"""

from __future__ import annotations

import logging

from tattotronix.app.pipeline import solve_ik
from tattotronix.app.records import save_ik
from tattotronix.art.artwork import artwork_name
from tattotronix.config.schema import Config
from tattotronix.io.artifacts import ToolpathRecord
from tattotronix.io.outputs import Outputs
from tattotronix.kinematics import Chain, PinocchioTip, conditioning, verify
from tattotronix.robot.description import build_description
from tattotronix.stage import run_stage

log = logging.getLogger("tattotronix.ik")


def main(cfg: Config, out: Outputs) -> None:
    """Solve, check against Pinocchio's FK on the generated URDF, write q and metrics."""
    name = artwork_name(cfg.artwork)
    desc = build_description(cfg.robot)
    urdf = out.require(out.input("robot", f"{desc.name}.urdf"), "robot")
    src = out.require(out.input(*ToolpathRecord.path("", name=name).parts), "toolpath")
    tpr = ToolpathRecord.load(src)
    ik = cfg.ik
    chain = Chain.from_description(desc)
    n = len(tpr.xyz_m)

    def progress(done: int, total: int) -> None:
        log.info("ik %s: %d / %d points", name, done, total)

    res = solve_ik(chain, tpr.xyz_m, tpr.uvz_mm, ik,
                   progress=progress if n > 50_000 else None)  # ~0.1 s per 20k points
    check = verify(PinocchioTip.from_urdf(urdf, desc.tip_frame), res, tpr.xyz_m,
                   needle_axis=list(ik.needle_axis), pos_tol_m=ik.verify_pos_tol_m,
                   axis_tol_rad=ik.verify_axis_tol_rad)
    conditions = conditioning(chain, res.q)
    cond = conditions.summary()
    cond["worst_point_mm"] = [float(v) for v in tpr.uvz_mm[conditions.worst]]
    tcp, _ = chain.fk(res.q)
    save_ik(out, cfg, name, desc.joint_names, res.q, tcp, res.residual, tpr,
            {"toolpath": src, "urdf": urdf})
    metrics = {"name": name, **res.summary(), **cond, **check.summary(),
               "joint_range": {j: [float(res.q[:, i].min()), float(res.q[:, i].max())]
                               for i, j in enumerate(desc.joint_names)}}
    out.write_json(out.path("metrics", "ik", f"{name}.json"), metrics)
    timings = res.timings()
    out.write_timings("ik", name, timings)
    log.info("ik %s: %d points, %.1f %% converged, worst residual %.2e, %.3f s "
             "(%.0f points/s), cond %.1f .. %.1f", name, res.points, res.converged_pct,
             res.worst_residual, res.solve_s, timings["points_per_s"],
             float(conditions.cond.min()), float(conditions.cond.max()))


if __name__ == "__main__":
    run_stage("ik", main)
