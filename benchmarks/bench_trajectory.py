"""Trajectory: time-parameterisation wall time, points per second, cycle over marking.

On the built-in artwork's IK path when the ``ik`` stage has made it (``data/ik/emblem.npz``)
and on the 16 000-point logo-like synthetic path (IK solved here, not timed). The timed
call is the whole plan: densify (IK on inserted travel points), path derivatives, the
speed check and the forward/backward time law. ``cycle_over_marking`` is the planned
duration over the marking-only time (marked length / feed); the original needed 1.31.
The peak jerk (sampled: the change of acceleration between points over their time) and
the peak tip acceleration while marking are held against their limits
(``trajectory.jerk_rad_s3``, ``trajectory.tip_accel_mm_s2``; docs/timelaw.md).
"""

from __future__ import annotations

from pathlib import Path

from run import Row, median_time

from tattotronix.app.pipeline import travel_planner
from tattotronix.config.params import compose_settings
from tattotronix.io.artifacts import IkRecord
from tattotronix.kinematics import Chain, solve_path
from tattotronix.kinematics.synthetic import logo_like_strokes, stroke_path
from tattotronix.robot.description import build_description
from tattotronix.trajectory import (
    JointLimits,
    JointPath,
    TrajectoryParams,
    TravelPlanner,
    plan_trajectory,
)

EMBLEM = IkRecord.path(Path(__file__).resolve().parents[1] / "data", name="emblem")


def _rows(label: str, path: JointPath, chain: Chain, limits: JointLimits,
          params: TrajectoryParams, planner: TravelPlanner, repeat: int) -> list[Row]:
    t, traj = median_time(lambda: plan_trajectory(path, chain, limits, params,
                                                  planner=planner), repeat)
    m = traj.metrics()
    law = traj.timings_s["time_law"]
    return [
        (f"plan [{label}]", t, "s",
         f"{len(path)} IK points -> {m['points']} ({m['points_inserted']} inserted); "
         f"time law alone {law * 1000:.1f} ms, {m['timelaw_stepped_points']} points stepped"),
        (f"points per second [{label}]", len(path) / t, "points/s", "IK points over plan time"),
        (f"cycle_over_marking [{label}]", m["cycle_over_marking"], "x",
         f"{m['duration_s']:.1f} s for {m['marking_only_s']:.1f} s of marking; approach "
         f"{m['approach_s']:.1f} s, travel {m['travel_s']:.1f} s, {m['entries']} entries; "
         f"original 1.31"),
        (f"peak jerk [{label}]", m["peak_jerk_rad_s3_max"], "rad/s^3",
         f"limit {m['jerk_limit_rad_s3']}; filter window up to "
         f"{m['jerk_window_s_max'] * 1000:.0f} ms, {m['timelaw_repairs']} repair rounds"),
        (f"peak tip acceleration marking [{label}]", m["peak_tip_accel_marking_mm_s2"],
         "mm/s^2", f"limit {m['tip_accel_limit_mm_s2']}; marking below the feed "
         f"{m['marking_below_feed_pct']:.1f} % of its length"),
        (f"fastest speed [{label}]", m["fastest_speed"] or float("nan"), "x",
         f"limited by {m['fastest_speed_joint']} {m['fastest_speed_limited_by']}"),
        (f"planned travel saving [{label}]", m["travel_saved_s"], "s",
         f"{m['hops']} hops in {m['hop_s']:.2f} s against {m['hop_straight_s']:.2f} s straight "
         f"at {m['straight_feed_mm_s']:g} mm/s; travel planning "
         f"{traj.timings_s['travel'] * 1000:.0f} ms"),
    ]


def bench(repeat: int) -> list[Row]:
    cfg = compose_settings()
    desc = build_description(cfg.robot)
    chain = Chain.from_description(desc)
    params = TrajectoryParams.from_settings(cfg.trajectory, cfg.toolpath, cfg.speed)
    limits = JointLimits.from_description(desc, params.accel_rad_s2)
    planner = travel_planner(cfg, desc, chain, limits)
    rows: list[Row] = []
    if EMBLEM.exists():
        rows += _rows("emblem", JointPath.from_npz(EMBLEM), chain, limits, params, planner,
                      repeat)
    else:
        rows.append(("plan [emblem]", float("nan"), "s",
                     "data/ik/emblem.npz missing: run stages/ik.py"))
    sp = stroke_path(logo_like_strokes())
    res = solve_path(chain, sp.xyz_m)
    tcp, _ = chain.fk(res.q)
    synthetic = JointPath.from_arrays(chain.joint_names, res.q, tcp, sp.kind, sp.uvz_mm)
    rows += _rows("16k synthetic", synthetic, chain, limits, params, planner, repeat)
    return rows
