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
design it is in. The joint path is then timed by the panel's time law (the tip's acceleration
while marking limited by ``surface.tip_accel_mm_s2``, its travel the
carried one: lifted along the normal, at the clearance from the skin, and no step longer
than the densify step, so none is split with one needle axis) and checked for collisions
with the limb in the panel's place, every link and the pen's barrel at the margin.

:func:`simulate_on_surface` plays the timed drawing closed loop on a simulated plant (the
panel's controller and plant settings) and scores it as on the panel: the tracking errors
of the tip (3-D, so the skin's curvature changes nothing), and the ink. The ink is where
the simulated tip is in the skin, along the surface's normal: each tip is put back in the
design's chart (:meth:`~tattotronix.surface.chart.Chart.locate`, from the planned point
nearest it) with its height over the surface, and rasterised there at the needle's width,
so the skin's ink is compared with the planned ink and with the artwork by the panel's own
measures (:mod:`tattotronix.path.fidelity`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from tattotronix.app.pipeline import draft_drawing
from tattotronix.app.simulate import run_closed_loop
from tattotronix.art.mask import InkMask
from tattotronix.collision.check import TrajectoryClearance, check_trajectory
from tattotronix.collision.model import CollisionModel
from tattotronix.config.schema import Config
from tattotronix.control.drawing import ClosedLoop, Drawing, finite_json
from tattotronix.control.ink import InkComparison, compare_ink
from tattotronix.control.tracking import TrackingErrors
from tattotronix.errors import TattotronixError
from tattotronix.io.jsontypes import JsonDict
from tattotronix.kinematics import Chain
from tattotronix.kinematics.ik import IkOptions, IkResult, ik_options, solve_path
from tattotronix.kinematics.onsurface import angle_deg
from tattotronix.path.fidelity import (
    ArtworkFidelity,
    InkGrid,
    artwork_fidelity,
    artwork_on,
    below_runs,
    grid_over,
    rasterise_runs,
)
from tattotronix.path.kinds import MARK
from tattotronix.path.onskin import SkinPath, carry_path
from tattotronix.path.plan import Toolpath
from tattotronix.plants import BACKENDS as PLANTS
from tattotronix.plants import Workpiece
from tattotronix.robot.description import RobotDescription
from tattotronix.surface.chart import Chart, Distortion, distortion
from tattotronix.surface.setup import WorkSurface, work_surface
from tattotronix.trajectory import (
    JointLimits,
    JointPath,
    Trajectory,
    TrajectoryParams,
    plan_trajectory,
)

__all__ = ["SkinDrawing", "SkinRun", "plan_on_surface", "simulate_on_surface"]

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
        mask: the ink mask the design was planned on (the artwork, design-plane mm).
        toolpath: the design's toolpath in its own plane (as on the panel).
        centre_mm: the design-plane point put on the placement (the marking points'
            bounding box's centre), mm.
        box_mm: the marking points' footprint ``(u0, v0, u1, v1)`` about it, mm.
        chart: the design's chart on the surface (design coordinates about ``centre_mm``).
        distortion: the chart's distortion over the footprint.
        skin: the path on the surface (design coordinates about ``centre_mm``).
        ik: the IK of every skin point, the needle along the inward normal.
        tilt_deg: (N,) angle from the reached needle axis to the inward normal.
        from_vertical_deg: (N,) the needle's angle from straight down.
        trajectory: the joint path timed (straight travel: the carried path's own).
        clearance: the collision check of the trajectory with the limb.
    """

    surface: WorkSurface
    mask: InkMask
    toolpath: Toolpath
    centre_mm: tuple[float, float]
    box_mm: tuple[float, float, float, float]
    chart: Chart
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
    return (f"{int(failed.sum())} of its {len(failed)} points ({share:.2g} %), within "
            f"design u {lo[0]:.1f}..{hi[0]:.1f} mm and "
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
    draft = draft_drawing(cfg, source, name, desc, reach=False)
    tp = draft.toolpath
    uvz = np.asarray(tp.path.uvz_mm, dtype=np.float64)
    kind = np.asarray(tp.path.kind, dtype=np.int8)
    centre, box = _footprint(uvz, kind)
    design = uvz - np.array([centre[0], centre[1], 0.0])
    chart = surface.chart(radius_mm=math.hypot(box[2] - box[0], box[3] - box[1]) / 2)
    dist = distortion(chart, box, DISTORTION_STEP_MM)
    dist.check(float(cfg.surface.max_distortion_pct) / 100.0)
    timing = replace(TrajectoryParams.from_settings(cfg.trajectory, cfg.toolpath, cfg.speed),
                     travel="straight", tip_accel_m_s2=cfg.surface.tip_accel_m_s2)
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
    return SkinDrawing(surface, draft.mask, tp, centre, box, chart, dist, skin, res, tilt,
                       vertical, traj, clear)


@dataclass(frozen=True)
class SkinRun:
    """A drawing on the skin simulated closed loop, its ink in the design's chart.

    Attributes:
        loop: the closed-loop run.
        errors: the tip's tracking errors.
        grid: the ink raster, over the design plane (the artwork's mm).
        uvz_mm, uvz_ref_mm: (S, 3) every simulated and reference tip in the chart: design
            point and height over the skin along its normal (negative: in the skin); no
            simulated tip where the ink is not scored.
        sim_ink, plan_ink: the simulated and the planned ink on ``grid``.
        art: the artwork on ``grid``.
        ink: the simulated ink against the planned ink.
        artwork: the simulated ink against the artwork (None: a run that saturated or
            diverged is not scored; ``reason`` says why).
        reason: why the ink is not scored ("" when it is).
        tip_m: (S, 3) every simulated tip, arm frame, m (the film's ink source).
    """

    loop: ClosedLoop
    errors: TrackingErrors
    grid: InkGrid
    uvz_mm: Array
    uvz_ref_mm: Array
    sim_ink: NDArray[np.bool_]
    plan_ink: NDArray[np.bool_]
    art: NDArray[np.bool_]
    ink: InkComparison
    artwork: ArtworkFidelity | None
    reason: str
    tip_m: Array

    def summary(self) -> JsonDict:
        """The run's figures (the surface stage's ``run`` metrics): the panel run's
        tracking figures and verdict, the ink against the plan and against the artwork,
        and the deepest and shallowest simulated marking depth."""
        figures = self.loop.metrics(self.errors)
        # at the run's samples; none where the ink is not scored (the tips not located)
        depth = (-self.uvz_mm[self.loop.samples()][self.errors.down, 2]
                 if len(self.uvz_mm) else np.zeros(0))
        figures.update(finite_json({
            **self.ink.metrics(),
            "artwork": None if self.artwork is None else self.artwork.metrics(),
            "artwork_reason": self.reason,
            "depth_mm": ({"min": round(float(depth.min()), 5),
                          "max": round(float(depth.max()), 5)} if len(depth) else None)}))
        return figures


def _in_chart(d: SkinDrawing, tips_mm: Array) -> Array:
    """Tips (arm frame, mm) as artwork-plane points and heights over the skin: each from
    the planned skin point nearest it (:meth:`Chart.locate`)."""
    from scipy.spatial import cKDTree

    _, near = cKDTree(d.skin.xyz_mm).query(tips_mm)
    uv, height = d.chart.locate(tips_mm, d.skin.uvz_mm[near, :2])
    return np.column_stack([uv + np.asarray(d.centre_mm), height])


def simulate_on_surface(cfg: Config, data: Path, desc: RobotDescription, d: SkinDrawing,
                        name: str, *, progress: bool = False, viewer: bool = False
                        ) -> SkinRun:
    """Play ``d`` closed loop on ``cfg.backend`` (a simulated plant), the limb in the
    plant in the panel's place, and score its tracking and its ink on the skin (module
    docstring). ``viewer``: watch it in the engine's viewer, where a display exists.

    Raises:
        TattotronixError: a backend that is not a simulated plant (the servo plant and the
            arm draw on the panel only, for now), or what the closed loop refuses.
    """
    backend = cfg.backend.name
    if backend not in PLANTS:
        raise TattotronixError(
            f"backend={backend}: a drawing on the skin is simulated on "
            f"{', '.join(PLANTS)} (the servo plant and the arm draw on the panel only)")
    traj = d.trajectory
    drawing = Drawing(name=name, t=np.asarray(traj.t), q=np.asarray(traj.q),
                      qd=np.asarray(traj.qd), kind=np.asarray(traj.kind, dtype=np.int8),
                      origin="planned")
    # the limb in the panel's place, in the plant (its viewer) as in the collision check
    limb = Workpiece(d.surface.vertices / 1000.0, d.surface.faces)
    loop = run_closed_loop(cfg, data, desc, drawing, progress=progress, viewer=viewer,
                           workpiece=limb)
    chain = Chain.from_description(desc)
    run = loop.run
    k = len(run.t)
    tip_m = chain.fk(run.q)[0] if k else np.zeros((0, 3))
    ref_m = chain.fk(run.ref.q[:k])[0] if k else np.zeros((0, 3))
    err = loop.errors(chain, float(cfg.draw.settle_periods), (tip_m, ref_m))
    reason = loop.judge(err).unscored_ink()
    # a run that saturated or diverged is not scored, and its tips may be far off the skin
    uvz = _in_chart(d, tip_m * 1e3) if k and not reason else np.zeros((0, 3))
    uvz_ref = _in_chart(d, ref_m * 1e3) if k else np.zeros((0, 3))
    res, needle, mask = float(cfg.draw.ink_res_mm), float(cfg.toolpath.needle_width_mm), d.mask
    corners = np.array([[mask.xs[0], mask.ys[0]], [mask.xs[-1], mask.ys[-1]]])
    grid = grid_over([uvz[uvz[:, 2] < 0], uvz_ref[uvz_ref[:, 2] < 0], corners], res)
    sim_ink = rasterise_runs(below_runs(uvz), grid, needle)
    plan_ink = rasterise_runs(below_runs(uvz_ref), grid, needle)
    ink = compare_ink(sim_ink, plan_ink, res)
    if reason:
        ink = ink.unscored(reason)
    art = artwork_on(mask, grid)
    fidelity = None if reason else artwork_fidelity(art, sim_ink, res)
    return SkinRun(loop, err, grid, uvz, uvz_ref, sim_ink, plan_ink, art, ink, fidelity,
                   reason, tip_m)
