"""The drawing pipeline in one process: artwork -> mask -> toolpath -> IK -> trajectory.

The DVC stages run these steps one file at a time; ``draw.py artwork.source=PATH`` (or a
``speed`` the stored trajectory was not planned at) runs them here, in memory, with the
same library calls and the same settings.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from tattotronix.art.artwork import Artwork, load_artwork
from tattotronix.art.grid import InkMask
from tattotronix.art.mask import mask_on_panel
from tattotronix.art.vector import VectorLines, artwork_lines
from tattotronix.config.schema import Config, IkConfig
from tattotronix.errors import TattotronixError
from tattotronix.kinematics import Chain, IkResult, ik_options, solve_path
from tattotronix.path.params import ToolpathParams
from tattotronix.path.plan import Toolpath, check_needle, plan_toolpath
from tattotronix.robot.description import RobotDescription
from tattotronix.trajectory import JointLimits, JointPath, Trajectory, TrajectoryParams
from tattotronix.trajectory import plan_trajectory as _plan_trajectory
from tattotronix.trajectory.travel import TravelPlanner

__all__ = ["DraftedDrawing", "PlannedDrawing", "artwork_inputs", "check_reach",
           "draft_drawing", "drawing_inputs", "mask_of", "plan_drawing", "plan_drawing_all",
           "plan_drawing_on", "solve_ik", "straight_travel_baseline", "trajectory_from_path",
           "travel_planner"]

log = logging.getLogger("tattotronix.app.pipeline")


def solve_ik(chain: Chain, xyz_m: ArrayLike, uvz_mm: ArrayLike, ik: IkConfig,
             progress: Callable[[int, int], None] | None = None) -> IkResult:
    """Whole-path IK with the ``ik`` config group's settings (the ik stage's solve).

    Raises:
        IkFailure: a point failed (named in panel mm, with its residual and reason).
    """
    res = solve_path(chain, xyz_m, seed=list(ik.seed), progress=progress, **ik_options(ik))
    res.raise_if_failed(uvz_mm=uvz_mm)
    return res


def travel_planner(cfg: Config, desc: RobotDescription, chain: Chain,
                   limits: JointLimits) -> TravelPlanner:
    """The travel planner of the config: the collision model of ``desc``, the margin, the
    clearance height and the lifts."""
    from tattotronix.collision.model import CollisionModel

    panel_top = float(desc.panel_centre[2] + desc.panel_size[2] / 2)
    return TravelPlanner(
        chain, limits, CollisionModel(desc), margin_m=cfg.collision.margin_m,
        resolution_m=cfg.collision.resolution_m,
        clearance_z_m=panel_top + cfg.toolpath.clearance_m,
        lifts_m=cfg.trajectory.lifts_m, max_step_m=cfg.trajectory.max_step_m,
        ik=ik_options(cfg.ik), reach_m=cfg.trajectory.blend_reach_m)


def trajectory_from_path(cfg: Config, path: JointPath, desc: RobotDescription) -> Trajectory:
    """Time an IK path with the config's feeds, speed, limits and travel planning (the
    trajectory stage)."""
    params = TrajectoryParams.from_settings(cfg.trajectory, cfg.toolpath, cfg.speed)
    limits = JointLimits.from_description(desc, params.accel_rad_s2)
    chain = Chain.from_description(desc)
    planner = travel_planner(cfg, desc, chain, limits) if params.travel == "planned" else None
    return _plan_trajectory(path, chain, limits, params, ik=ik_options(cfg.ik),
                            planner=planner, panel_origin_m=list(cfg.toolpath.panel_origin))


def straight_travel_baseline(cfg: Config, path: JointPath, desc: RobotDescription
                             ) -> dict[str, float]:
    """The same path with the original's straight travel lines, timed by the same law
    (``trajectory.travel=straight``): what planned travel is compared with."""
    params = replace(TrajectoryParams.from_settings(cfg.trajectory, cfg.toolpath, cfg.speed),
                     travel="straight")
    limits = JointLimits.from_description(desc, params.accel_rad_s2)
    traj = _plan_trajectory(path, Chain.from_description(desc), limits, params,
                            ik=ik_options(cfg.ik))
    metrics: dict[str, Any] = traj.metrics()  # read back: JSON values
    return {"duration_s": traj.duration_s, "travel_s": metrics["travel_s"]}


def mask_of(cfg: Config, source: str | Path | None, name: str) -> InkMask:
    """The ink mask of an artwork, as the artwork and mask stages make it (placed on the
    panel).

    Raises:
        TattotronixError: unreadable art, or a mask the settings refuse (one off the panel
            or out of the arm's reach).
    """
    return drawing_inputs(cfg, source, name)[0]


def drawing_inputs(cfg: Config, source: str | Path | None, name: str,
                   desc: RobotDescription | None = None
                   ) -> tuple[InkMask, VectorLines | None]:
    """The ink mask of an artwork and its vector lines (``artwork.vector``; else None), as
    the artwork and mask stages make them (``desc``: the arm's description, for the reach
    check, if the caller has it built).

    Raises:
        TattotronixError: unreadable art, or a mask the settings refuse (one off the panel
            or out of the arm's reach).
    """
    _, mask, vector = artwork_inputs(cfg, source, name, desc)
    return mask, vector


def artwork_inputs(cfg: Config, source: str | Path | None, name: str,
                   desc: RobotDescription | None = None, *, reach: bool = True
                   ) -> tuple[Artwork, InkMask, VectorLines | None]:
    """:func:`drawing_inputs`, and the artwork on its grid (what the artwork stage writes).
    ``reach=False`` leaves out the panel's reach check (a design for a curved surface is
    checked there: :mod:`tattotronix.app.onskin`).

    Raises:
        TattotronixError: as :func:`drawing_inputs`.
    """
    m = cfg.mask
    art = load_artwork(source, m.width_mm, m.res_mm, cfg.artwork.max_pixels, name,
                       svg_local_files=cfg.artwork.svg_local_files,
                       default_width_mm=m.default_width_mm, min_line_px=m.min_line_px,
                       height_mm=m.height_mm)
    grey = art.as_uint8().astype(np.float64)  # what the artwork stage's PNG holds
    mask, _ = mask_on_panel(grey, art.res_mm, m, cfg.robot.panel.size_mm, art.transparent)
    if reach:
        check_reach(cfg, mask, desc)
    vector = (artwork_lines(source, art.shape, art.res_mm, cfg.toolpath.step_mm)
              if cfg.artwork.vector else None)
    return art, mask, vector


def check_reach(cfg: Config, mask: InkMask, desc: RobotDescription | None = None) -> None:
    """Refuse a drawing the arm cannot reach where it is placed, before any work: the
    needle on its axis at the marking depth and at the clearance height over each corner
    of the ink's convex hull, in turn (the far corners of the panel are out of reach).
    ``desc`` is the arm's description of ``cfg.robot``, if the caller has built it.

    Raises:
        TattotronixError: naming the first corner out of reach and the settings that move
            the drawing.
    """
    import cv2

    from tattotronix.robot.description import build_description

    rows, cols = np.nonzero(mask.ink)
    if rows.size == 0:
        return
    half = mask.res_mm / 2
    corners = np.concatenate([np.column_stack([mask.xs[cols] + du, mask.ys[rows] + dv])
                              for du in (-half, half) for dv in (-half, half)])
    hull = cv2.convexHull(corners.astype(np.float32))[:, 0, :].astype(np.float64)
    tp = cfg.toolpath
    uvz = np.concatenate([np.column_stack([hull, np.full(len(hull), z)])
                          for z in (-float(tp.plunge_mm), float(tp.clearance_mm))])
    xyz = np.asarray(tp.panel_origin, dtype=np.float64) + uvz / 1000.0
    desc = build_description(cfg.robot) if desc is None else desc
    res = solve_path(Chain.from_description(desc), xyz, seed=list(cfg.ik.seed),
                     **ik_options(cfg.ik))
    if res.ok:
        return
    i = int(res.failed[0])
    u, v, z = uvz[i]
    depth = "at the marking depth" if z < 0 else "at the clearance height"
    raise TattotronixError(
        f"the drawing is out of the arm's reach where it is placed: the needle cannot reach "
        f"the ink's corner at panel ({u:.1f}, {v:.1f}) mm {depth} ({res.reason[i]}); move "
        f"it with mask.at_mm and mask.anchor (the panel's centre is {tp.panel_origin[0] * 1e3:.0f}"
        " mm from the arm's base, along u), turn it (mask.rotate_deg) or make it smaller; "
        "nothing was planned")


def plan_drawing(cfg: Config, source: str | Path | None, name: str,
                 desc: RobotDescription) -> Trajectory:
    """Plan a drawing from its artwork file, in memory (every stage up to the trajectory).

    Raises:
        TattotronixError: whatever a stage would refuse (unreadable art, no ink, a drawing
            off the panel, unreachable points, a speed too high).
    """
    return plan_drawing_on(cfg, source, name, desc)[0]


def plan_drawing_on(cfg: Config, source: str | Path | None, name: str,
                    desc: RobotDescription) -> tuple[Trajectory, InkMask]:
    """:func:`plan_drawing`, and the ink mask it was planned on (a run scores its ink
    against it, so it is not made twice)."""
    planned = plan_drawing_all(cfg, source, name, desc)
    return planned.trajectory, planned.mask


@dataclass(frozen=True)
class DraftedDrawing:
    """The steps of a drawing up to its toolpath (no joint angles, no timing): the artwork
    on its grid and its vector lines (None unless ``artwork.vector``), the ink mask, and
    the toolpath (the needle's width checked against the artwork)."""

    artwork: Artwork
    lines: VectorLines | None
    mask: InkMask
    toolpath: Toolpath


def draft_drawing(cfg: Config, source: str | Path | None, name: str,
                  desc: RobotDescription, *, reach: bool = True) -> DraftedDrawing:
    """The artwork, mask and toolpath stages in memory: a fifth of a plan's time, what a
    page shows while the plan is timed. ``reach=False`` leaves out the panel's reach
    check (:func:`artwork_inputs`).

    Raises:
        TattotronixError: unreadable art, no ink, a drawing off the panel or out of reach,
            a needle too wide for it.
    """
    art, mask, vector = artwork_inputs(cfg, source, name, desc, reach=reach)
    params = ToolpathParams.from_settings(cfg.toolpath, cfg.mask, cfg.robot.panel)
    tp = plan_toolpath(mask, params, vector=vector)
    check_needle(tp, mask, params.needle_width_mm, cfg.toolpath.ink_res_mm)
    return DraftedDrawing(art, vector, mask, tp)


@dataclass(frozen=True)
class PlannedDrawing:
    """Every step of a drawing planned in memory: the artwork on its grid and its vector
    lines (None unless ``artwork.vector``), the ink mask it was planned on, the toolpath,
    the IK solution and path, and the trajectory."""

    artwork: Artwork
    lines: VectorLines | None
    mask: InkMask
    toolpath: Toolpath
    ik: IkResult
    path: JointPath
    trajectory: Trajectory


def plan_drawing_all(cfg: Config, source: str | Path | None, name: str,
                     desc: RobotDescription) -> PlannedDrawing:
    """:func:`plan_drawing`, keeping every step's result (the Python API's plan).

    Raises:
        TattotronixError: as :func:`plan_drawing`.
    """
    d = draft_drawing(cfg, source, name, desc)
    tp = d.toolpath
    chain = Chain.from_description(desc)
    res = solve_ik(chain, tp.xyz_m, tp.path.uvz_mm, cfg.ik)
    tcp, _ = chain.fk(res.q)
    path = JointPath.from_arrays(desc.joint_names, res.q, tcp, tp.path.kind, tp.path.uvz_mm)
    traj = trajectory_from_path(cfg, path, desc)
    log.info("planned %s in memory: %d points, %.1f s", name, len(traj.t), traj.duration_s)
    return PlannedDrawing(d.artwork, d.lines, d.mask, tp, res, path, traj)
