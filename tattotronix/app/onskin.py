"""A drawing on a curved work surface (issue 33): the design planned in its own plane as
on the panel, laid on the skin by the surface's chart, and solved with the needle along
the inward normal at every point.

:func:`plan_on_surface` runs the artwork, mask and toolpath steps as a plan does
(:func:`~tattotronix.app.pipeline.draft_drawing`, without the panel's reach check: it
is not the skin's), centres the design on its marking points, measures the chart's distortion
over the design's footprint and refuses it past ``surface.max_distortion_pct``, carries
the path onto the surface (:func:`~tattotronix.path.onskin.carry_path`: heights along the
normal, equal arc length, no chord straying 0.01 mm) and solves the IK with each point's
needle axis. A point the arm cannot reach refuses the placement, naming the part of the
design it is in. The joint path is then timed by the panel's time law (its travel the
carried one: lifted along the normal, at the clearance from the skin, and no step longer
than the densify step, so none is split with one needle axis) and checked for collisions
with the limb in the panel's place, every link and the pen's barrel at the margin. The
simulated ink on the skin is the next step (docs/surface.md, "What is not done yet").
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from tattotronix.app.pipeline import draft_drawing
from tattotronix.collision.check import TrajectoryClearance, check_trajectory
from tattotronix.collision.model import CollisionModel
from tattotronix.config.schema import Config
from tattotronix.errors import TattotronixError
from tattotronix.io.jsontypes import JsonDict
from tattotronix.kinematics import Chain
from tattotronix.kinematics.ik import IkOptions, IkResult, ik_options, solve_path
from tattotronix.kinematics.onsurface import angle_deg
from tattotronix.path.kinds import MARK
from tattotronix.path.onskin import SkinPath, carry_path
from tattotronix.path.plan import Toolpath
from tattotronix.robot.description import RobotDescription
from tattotronix.surface.chart import Distortion, distortion
from tattotronix.surface.setup import WorkSurface, work_surface
from tattotronix.trajectory import (
    JointLimits,
    JointPath,
    Trajectory,
    TrajectoryParams,
    plan_trajectory,
)

__all__ = ["SkinDrawing", "plan_on_surface"]

Array = NDArray[np.float64]
#: the grid the chart's distortion is measured on over the design's footprint, mm
DISTORTION_STEP_MM = 1.0
#: the skin path's longest step, as a share of the time law's densify step (the IK's tip
#: is within its tolerance of the target, so a step at the limit could still be split)
STEP_SHARE = 0.9


@dataclass(frozen=True)
class SkinDrawing:
    """A design laid on a curved surface and solved.

    Attributes:
        surface: the work surface.
        toolpath: the design's toolpath in its own plane (as on the panel).
        centre_mm: the design-plane point put on the placement (the marking points'
            bounding box's centre), mm.
        box_mm: the marking points' footprint ``(u0, v0, u1, v1)`` about it, mm.
        distortion: the chart's distortion over the footprint.
        skin: the path on the surface (design coordinates about ``centre_mm``).
        ik: the IK of every skin point, the needle along the inward normal.
        tilt_deg: (N,) angle from the reached needle axis to the inward normal.
        from_vertical_deg: (N,) the needle's angle from straight down.
        trajectory: the joint path timed (straight travel: the carried path's own).
        clearance: the collision check of the trajectory with the limb.
    """

    surface: WorkSurface
    toolpath: Toolpath
    centre_mm: tuple[float, float]
    box_mm: tuple[float, float, float, float]
    distortion: Distortion
    skin: SkinPath
    ik: IkResult
    tilt_deg: Array
    from_vertical_deg: Array
    trajectory: Trajectory
    clearance: TrajectoryClearance

    def summary(self) -> JsonDict:
        """The drawing's figures on the skin (the surface stage's metrics)."""
        mark = self.skin.kind == MARK
        u0, v0, u1, v1 = self.box_mm
        steep = self.from_vertical_deg[mark]
        return {
            "surface": self.surface.kind,
            "design_mm": [round(u1 - u0, 3), round(v1 - v0, 3)],
            "distortion": self.distortion.as_dict(),
            "points": int(len(self.skin.kind)),
            "marking_points": int(mark.sum()),
            "ik_converged_pct": round(100.0 * float(self.ik.converged.mean()), 3),
            "tilt_worst_deg": round(float(np.max(self.tilt_deg)), 6),
            "needle_from_vertical_deg": {"min": round(float(steep.min()), 3),
                                         "max": round(float(steep.max()), 3)},
            "duration_s": round(float(self.trajectory.duration_s), 3),
            "collision": {
                "margin_mm": round(1000 * self.clearance.margin_m, 3),
                "min_clearance_mm": round(1000 * float(self.clearance.min_clearance_m.min()),
                                          4),
                "worst_pair": self.clearance.pair_names[self.clearance.worst],
                "events": len(self.clearance.events)},
        }


def _footprint(uvz: Array, kind: NDArray[np.int8]) -> tuple[tuple[float, float],
                                                            tuple[float, float, float, float]]:
    mark = uvz[kind == MARK, :2]
    if not len(mark):
        raise TattotronixError("the design has no marking point: nothing to lay on the skin")
    lo, hi = mark.min(axis=0), mark.max(axis=0)
    c = (lo + hi) / 2
    return ((float(c[0]), float(c[1])),
            (float(lo[0] - c[0]), float(lo[1] - c[1]), float(hi[0] - c[0]),
             float(hi[1] - c[1])))


def _unreached(uv: Array, failed: NDArray[np.bool_], box: tuple[float, float, float, float]
               ) -> str:
    """The part of the design its unreached points are in, in words."""
    u0, v0, u1, v1 = box
    bad = uv[failed]
    lo, hi = bad.min(axis=0), bad.max(axis=0)
    share = 100.0 * float(failed.mean())
    return (f"{share:.1f} % of its points, within design u {lo[0]:.1f}..{hi[0]:.1f} mm and "
            f"v {lo[1]:.1f}..{hi[1]:.1f} mm (the design spans u {u0:.1f}..{u1:.1f}, "
            f"v {v0:.1f}..{v1:.1f})")


def plan_on_surface(cfg: Config, source: str | Path | None, name: str,
                    desc: RobotDescription) -> SkinDrawing:
    """The design of ``source`` laid on ``cfg.surface`` and solved (module docstring).

    Raises:
        TattotronixError: ``surface=panel``, a bad mesh, unreadable art or no ink, a
            needle too wide for the art, a distortion past the bound (naming where), a
            design past the surface, a placement the arm cannot reach (naming the part),
            or a drawing that collides (naming the bodies and the time).
    """
    surface = work_surface(cfg.surface)
    tp = draft_drawing(cfg, source, name, desc, reach=False).toolpath
    uvz = np.asarray(tp.path.uvz_mm, dtype=np.float64)
    kind = np.asarray(tp.path.kind, dtype=np.int8)
    centre, box = _footprint(uvz, kind)
    design = uvz - np.array([centre[0], centre[1], 0.0])
    chart = surface.chart(radius_mm=math.hypot(box[2] - box[0], box[3] - box[1]) / 2)
    dist = distortion(chart, box, DISTORTION_STEP_MM)
    dist.check(float(cfg.surface.max_distortion_pct) / 100.0)
    timing = replace(TrajectoryParams.from_settings(cfg.trajectory, cfg.toolpath, cfg.speed),
                     travel="straight")
    skin = carry_path(design, kind, chart, max_step_mm=STEP_SHARE * 1000 * timing.max_step_m)
    chain = Chain.from_description(desc)
    opts: IkOptions = {**ik_options(cfg.ik), "needle_axis": skin.axis}
    res = solve_path(chain, skin.xyz_mm / 1000.0, seed=list(cfg.ik.seed), **opts)
    if not res.ok:
        failed = ~np.asarray(res.converged, dtype=bool)
        raise TattotronixError(
            f"the arm cannot put the needle along the skin's normal over part of the "
            f"design: {_unreached(skin.uvz_mm[:, :2], failed, box)}; move the design "
            "(surface.along_mm, surface.around_deg), the limb (surface.origin_mm, "
            "surface.yaw_deg), or make it smaller; nothing was planned")
    tcp, z = chain.fk(res.q)
    tilt = angle_deg(z, skin.axis)
    vertical = angle_deg(skin.axis, np.array([0.0, 0.0, -1.0]))
    path = JointPath.from_arrays(desc.joint_names, res.q, tcp, skin.kind, skin.uvz_mm)
    limits = JointLimits.from_description(desc, timing.accel_rad_s2)
    traj = plan_trajectory(path, chain, limits, timing)
    if len(traj.t) != len(path):  # a step the time law split, by IK with one axis
        raise TattotronixError(f"the skin path has steps over trajectory.max_step_mm="
                               f"{1000 * timing.max_step_m:g}: the time law split them")
    model = CollisionModel(desc, limb_m=surface.vertices / 1000.0)
    clear = check_trajectory(model, traj.t, traj.q, margin_m=float(cfg.collision.margin_m),
                             plunge_m=math.inf, resolution_m=float(cfg.collision.resolution_m),
                             tcp=traj.tcp)
    if clear.events:
        raise TattotronixError(f"the drawing on the limb is refused: {clear.message()}; "
                               "move the limb (surface.origin_mm, surface.yaw_deg) or the "
                               "design on it")
    return SkinDrawing(surface, tp, centre, box, dist, skin, res, tilt, vertical, traj, clear)
