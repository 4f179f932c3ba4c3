"""The kinematics study: zero-pose frames, conditioning along the path, panel reachability,
the placement sweep and the workspace (docs/kinematics.md; the original's: docs/original.md,
"1.3 Zero pose" and "3.4 Conditioning, reachability, placement").

Everything here builds on :mod:`tattotronix.kinematics` (the chain model, the batched
path IK, the Pinocchio reference solver, the 5x5 task Jacobian); no IK is re-implemented.

* :func:`zero_pose_frames`: every frame at ``q = 0`` (Pinocchio FK on the generated URDF),
  the tool axis, the wrist axis height and the highest point of the link geometry.
* :func:`path_conditioning`: singular values, condition number and Yoshikawa
  manipulability of the task Jacobian at every path point; the worst-conditioned point
  (panel mm) and its weakest joint-space direction; the joint ranges and the task-Jacobian
  column norms at the worst point.
* :func:`panel_reachability`: the original's method. A ``nx x ny`` grid over the panel
  surface, the needle vertical (pointing down); each row is swept in +x with the
  single-point reference solver (:func:`~tattotronix.kinematics.solve_point`, Pinocchio),
  warm-started from the previous success and reset to the seed after a failure.
* :func:`placement_sweep`: the drawing scaled to width ``W`` and shifted ``offset`` in +x,
  re-solved with the whole-path IK; sigma_5 minimum, condition maximum (both over the
  converged points) and the converged share per placement. The *planned path is scaled in
  the panel plane* (u, v scaled about the centre of the drawing's marked extent; z, the
  clearance, approach and marking depths, unchanged) rather than re-planned from a mask at
  another width: conditioning is a function of each point's position, so the only thing a
  re-plan would change is the sampling density (pitch and step scale with W), and it costs
  ~100x more.
* :func:`workspace_samples`: uniform samples of the joint box, their tip positions.

**Why sigma_5 "depends only on the reach in +x".** With the needle held vertical on a
horizontal surface, the singular values of the task Jacobian are invariant under a
rotation of the target about the joint_1 axis (the position rows rotate with it and the two
tilt rows span the same horizontal plane), so along a path at fixed depth sigma_5 is a
function of the distance from the joint_1 axis alone, and falls as it grows. The
drawing's weakest point is its farthest one. For a drawing whose farthest point lies on
the x axis through the base (the original's logo, reaching out with a ring at v ~ 0),
that distance is ``panel x + W/2 + offset``: hence the original's finding. For a drawing
with its extreme at a corner (the built-in emblem) equal ``W/2 + offset`` is not equal
reach; the placement rows report the true farthest distance ``r_max_mm`` too.

Study settings are module constants until the ``study`` config group exists
(:data:`REACH_NX`, :data:`REACH_NY`, :data:`PLACEMENT_WIDTHS_MM`,
:data:`PLACEMENT_OFFSETS_MM`, :data:`WORKSPACE_SAMPLES`, :data:`WORKSPACE_SEED`).

Units: SI inside (m, rad); ``_mm`` where the name says so (panel coordinates, reports).
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from tattotronix.config.schema import KinematicsStudyConfig
from tattotronix.errors import TattotronixError
from tattotronix.io.jsontypes import JsonDict
from tattotronix.kinematics import (
    Chain,
    Conditioning,
    PinocchioTip,
    conditioning,
    solve_path,
    solve_point,
    task_jacobian,
)
from tattotronix.kinematics.ik import (
    ANCHOR_SPACING_M,
    DLS_LAMBDA,
    MAX_ITER,
    NEEDLE_AXIS,
    SEED,
    TOL,
)
from tattotronix.path.kinds import TRAVEL
from tattotronix.plotting import legend_proxy, place_labels, pyplot
from tattotronix.robot.description import RobotDescription

__all__ = [
    "PLACEMENT_OFFSETS_MM",
    "PLACEMENT_WIDTHS_MM",
    "REACH_NX",
    "REACH_NY",
    "WORKSPACE_SAMPLES",
    "WORKSPACE_SEED",
    "PathConditioning",
    "Placement",
    "PlacementSweep",
    "Reachability",
    "Workspace",
    "ZeroPose",
    "axis_distance_m",
    "manipulability_figure",
    "panel_reachability",
    "path_conditioning",
    "place_path",
    "placement_figure",
    "placement_sweep",
    "reachability_figure",
    "workspace_figure",
    "workspace_samples",
    "zero_pose_frames",
]

log = logging.getLogger("tattotronix.studies.kinematics")

Array = NDArray[np.float64]

# Defaults are the schema's (conf/study), which hold the original's values.
_DEFAULTS = KinematicsStudyConfig()
#: Reachability grid columns along the panel's x (reference: 33).
REACH_NX = _DEFAULTS.reach_nx
#: Reachability grid rows along the panel's y (reference: 23).
REACH_NY = _DEFAULTS.reach_ny
#: Placement sweep drawing widths, mm, paired with :data:`PLACEMENT_OFFSETS_MM`.
PLACEMENT_WIDTHS_MM: tuple[float, ...] = tuple(_DEFAULTS.placement_widths_mm)
#: Placement sweep shifts in +x, mm, paired with :data:`PLACEMENT_WIDTHS_MM`.
PLACEMENT_OFFSETS_MM: tuple[float, ...] = tuple(_DEFAULTS.placement_offsets_mm)
#: Uniform joint-box samples for the workspace figure (reference: 60 000).
WORKSPACE_SAMPLES = _DEFAULTS.workspace_samples
#: RNG seed of the workspace samples (reference: 0).
WORKSPACE_SEED = _DEFAULTS.workspace_seed

MM = 1000.0


def _floats(a: ArrayLike) -> list[float]:
    return [float(v) for v in np.ravel(np.asarray(a, dtype=float))]


def _finite_or_none(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None


def _range(a: Array) -> list[float] | None:
    a = np.asarray(a, dtype=float)
    a = a[np.isfinite(a)]
    return [float(a.min()), float(a.max())] if len(a) else None


# --- zero pose ---------------------------------------------------------------------------

@dataclass(frozen=True)
class ZeroPose:
    """The arm at ``q = 0`` ("home").

    Attributes:
        frames_mm: every link and frame origin in the arm frame, mm (Pinocchio FK).
        tip_frame: the tool tip frame (``tattoo_tcp``, or ``tool0`` without a tool).
        tool_axis: (3,) the tip frame's +z (the needle axis), unit.
        wrist_axis_mm: height of the wrist roll axis (joint_4's child frame z), mm.
        highest_point_mm: the highest vertex of the link geometry (meshes when
            ``robot.cad_dir`` is set, else the primitives), mm.
        geometry: ``mesh`` or ``primitive``.
        chain_tcp_error_mm: the chain model's tip against Pinocchio's, mm.
    """

    frames_mm: dict[str, tuple[float, float, float]]
    tip_frame: str
    tool_axis: Array
    wrist_axis_mm: float
    highest_point_mm: float
    geometry: str
    chain_tcp_error_mm: float

    @property
    def tcp_mm(self) -> tuple[float, float, float]:
        """The tip frame's origin, mm."""
        return self.frames_mm[self.tip_frame]

    def summary(self) -> JsonDict:
        """For the metrics file (mm rounded to 0.1 um)."""
        return {
            "frames_mm": {k: [round(v, 4) for v in p] for k, p in self.frames_mm.items()},
            "tcp_mm": [round(v, 4) for v in self.tcp_mm],
            "tool0_mm": [round(v, 4) for v in self.frames_mm.get("tool0", self.tcp_mm)],
            "tool_axis": [round(float(v), 9) for v in self.tool_axis],
            "wrist_axis_mm": round(self.wrist_axis_mm, 4),
            "highest_point_mm": round(self.highest_point_mm, 3),
            "geometry": self.geometry,
            "chain_tcp_error_mm": self.chain_tcp_error_mm,
        }


def zero_pose_frames(desc: RobotDescription, ref: PinocchioTip | None = None) -> ZeroPose:
    """Frames at the zero pose, by Pinocchio on the URDF generated from ``desc``.

    Args:
        desc: the robot description.
        ref: a Pinocchio model of it (built from ``desc`` when None).

    Returns:
        The zero-pose frames, tool axis, wrist height and highest geometry point.
    """
    import pinocchio as pin

    ref = ref or PinocchioTip.from_description(desc)
    model = ref.model
    data = model.createData()
    q0 = np.zeros(model.nq)
    pin.framesForwardKinematics(model, data, q0)
    frames: dict[str, tuple[float, float, float]] = {}
    for name in desc.frame_names:
        if model.existFrame(name):
            t = data.oMf[model.getFrameId(name)].translation * MM
            frames[name] = (float(t[0]), float(t[1]), float(t[2]))
    tip = data.oMf[ref.frame_id]
    highest = -math.inf
    for link in desc.links:
        if not model.existFrame(link):
            continue
        placement = data.oMf[model.getFrameId(link)]
        for g in desc.geometry.get(link, ()):
            pts = g.points() @ placement.rotation.T + placement.translation
            highest = max(highest, float(pts[:, 2].max()))
    chain_tcp, _ = Chain.from_description(desc, ref.tip_frame).fk(q0)
    wrist = desc.joints[3].child if len(desc.joints) > 3 else desc.joints[-1].child
    return ZeroPose(
        frames_mm=frames,
        tip_frame=ref.tip_frame,
        tool_axis=np.array(tip.rotation[:, 2], dtype=float),
        wrist_axis_mm=frames[wrist][2],
        highest_point_mm=highest * MM,
        geometry="mesh" if desc.cad_dir else "primitive",
        chain_tcp_error_mm=float(np.linalg.norm(chain_tcp[0] - tip.translation) * MM),
    )


# --- conditioning along the path ---------------------------------------------------------

@dataclass(frozen=True)
class PathConditioning:
    """The task Jacobian's conditioning along a solved path.

    Attributes:
        cond: the per-point singular values, condition numbers, manipulability and
            weakest directions (:class:`~tattotronix.kinematics.Conditioning`).
        uvz_mm: (N, 3) the path in panel coordinates, mm.
        worst_index: the worst-conditioned point (largest sigma_1 / sigma_5).
        worst_point_mm: (3,) its panel coordinates, mm.
        weakest_direction: (n,) the joint-space direction that moves the task least there
            (right singular vector of sigma_5, unit, largest component positive).
        worst_column_norms: (n,) the task-Jacobian column norms there (m/rad and 1/rad
            mixed): a small one is a joint that hardly moves the task.
        joint_range: (n, 2) each joint's [min, max] along the path, rad.
        joint_names: the joints, base outward.
    """

    cond: Conditioning
    uvz_mm: Array
    worst_index: int
    worst_point_mm: Array
    weakest_direction: Array
    worst_column_norms: Array
    joint_range: Array
    joint_names: tuple[str, ...]

    @property
    def sigma1(self) -> Array:
        """(N,) largest singular value."""
        return self.cond.sigma[:, 0]

    @property
    def sigma5(self) -> Array:
        """(N,) smallest singular value."""
        return self.cond.sigma[:, -1]

    def summary(self) -> JsonDict:
        """Ranges (``[min, max]``) of sigma_1, sigma_5, cond and manipulability; the worst
        point (panel mm), its condition, weakest direction and column norms; joint ranges."""
        c = self.cond
        return {
            "points": int(len(c.cond)),
            "sigma1": _range(self.sigma1),
            "sigma5": _range(self.sigma5),
            "cond": _range(c.cond),
            "manipulability": _range(c.manipulability),
            "worst_index": self.worst_index,
            "worst_point_mm": _floats(self.worst_point_mm),
            "worst_cond": float(c.cond[self.worst_index]),
            "worst_sigma5": float(self.sigma5[self.worst_index]),
            "weakest_direction": _floats(self.weakest_direction),
            "worst_column_norms": _floats(self.worst_column_norms),
            "joint_range": {j: _floats(r) for j, r in
                            zip(self.joint_names, self.joint_range, strict=True)},
        }


def path_conditioning(chain: Chain, q: ArrayLike, uvz_mm: ArrayLike) -> PathConditioning:
    """Conditioning of the 5x5 task Jacobian at every point of a solved path.

    Args:
        chain: the kinematic model.
        q: (N, n) joint angles along the path, rad (the ``ik`` stage's ``q``).
        uvz_mm: (N, 3) the same points in panel coordinates, mm.

    Returns:
        The per-point conditioning and the worst point.

    Raises:
        TattotronixError: an empty path, or ``q`` and ``uvz_mm`` of different lengths.
    """
    qq = np.atleast_2d(np.asarray(q, dtype=float))
    uvz = np.asarray(uvz_mm, dtype=float)
    if len(qq) == 0 or uvz.shape != (len(qq), 3):
        raise TattotronixError(
            f"path conditioning needs (N, {chain.n}) joint angles and (N, 3) panel points, got "
            f"{qq.shape} and {uvz.shape}: re-run the 'ik' stage"
        )
    c = conditioning(chain, qq)
    w = c.worst
    jac = task_jacobian(chain, qq[w])[0]
    return PathConditioning(
        cond=c, uvz_mm=uvz, worst_index=w, worst_point_mm=uvz[w].copy(),
        weakest_direction=c.weakest[w].copy(),
        worst_column_norms=np.linalg.norm(jac, axis=0),
        joint_range=np.column_stack((qq.min(axis=0), qq.max(axis=0))),
        joint_names=chain.joint_names,
    )


# --- panel reachability ------------------------------------------------------------------

@dataclass(frozen=True)
class Reachability:
    """Which cells of a grid over the panel surface the tip reaches with the needle vertical.

    Attributes:
        x_m: (nx,) grid x in the arm frame, m (panel edge to edge).
        y_m: (ny,) grid y in the arm frame, m.
        z_m: the surface height, m.
        centre_m: (3,) the panel's surface centre in the arm frame, m.
        reachable: (ny, nx) IK converged at the cell.
        residual: (ny, nx) the solve's residual.
        reason: (ny, nx) ``""``, ``joint limit`` or ``unreachable``.
        q: (ny, nx, n) the solutions, rad (NaN where the solve failed).
        sigma5: (ny, nx) smallest task-Jacobian singular value (NaN where failed).
        cond: (ny, nx) condition number (NaN where failed).
        solve_s: wall time of the sweep, s.
    """

    x_m: Array
    y_m: Array
    z_m: float
    centre_m: Array
    reachable: NDArray[np.bool_]
    residual: Array
    reason: NDArray[np.str_]
    q: Array
    sigma5: Array
    cond: Array
    solve_s: float

    @property
    def percent(self) -> float:
        """Share of reachable cells, %."""
        return 100.0 * float(self.reachable.mean())

    @property
    def failing(self) -> list[tuple[float, float, str]]:
        """The failing cells as (x, y) arm-frame mm and the reason, row by row."""
        rows, cols = np.nonzero(~self.reachable)
        return [(float(self.x_m[c] * MM), float(self.y_m[r] * MM), str(self.reason[r, c]))
                for r, c in zip(rows, cols, strict=True)]

    @property
    def failures_on_outer_x_edge(self) -> bool:
        """Every failing cell is in the grid's last column (the panel edge farthest out)."""
        return not bool((~self.reachable[:, :-1]).any())

    def summary(self) -> JsonDict:
        """Percentage, cell counts, failing cells (arm and panel mm), conditioning range."""
        cx, cy = float(self.centre_m[0]), float(self.centre_m[1])
        return {
            "grid": [len(self.x_m), len(self.y_m)],
            "surface_z_mm": round(self.z_m * MM, 6),
            "reachable_pct": self.percent,
            "cells": int(self.reachable.size),
            "reachable": int(self.reachable.sum()),
            "failing_mm": [[round(x, 4), round(y, 4)] for x, y, _ in self.failing],
            "failing_panel_mm": [[round(x - cx * MM, 4), round(y - cy * MM, 4)]
                                 for x, y, _ in self.failing],
            "failing_reasons": sorted({r for _, _, r in self.failing}),
            "failures_on_outer_x_edge": self.failures_on_outer_x_edge,
            "sigma5": _range(self.sigma5),
            "cond": _range(self.cond),
        }


def panel_reachability(
    chain: Chain,
    desc: RobotDescription,
    nx: int = REACH_NX,
    ny: int = REACH_NY,
    *,
    ref: PinocchioTip | None = None,
    seed: ArrayLike = SEED,
    needle_axis: ArrayLike = NEEDLE_AXIS,
    dls_lambda: float = DLS_LAMBDA,
    max_iter: int = MAX_ITER,
    tol: float = TOL,
) -> Reachability:
    """The original's panel reachability (docs/original.md, "3.4 Conditioning,
    reachability, placement").

    A ``nx x ny`` grid spans the panel surface edge to edge (``desc.panel_centre`` and
    ``desc.panel_size``; the surface is the panel's top). Each row is swept in +x with the
    single-point reference solver, each solve warm-started from the previous success and
    the first one, and the one after any failure, from ``seed``. The solutions'
    conditioning comes from the chain model.

    Args:
        chain: the kinematic model (for the conditioning at each reached cell).
        desc: the robot description (panel geometry; the Pinocchio model when ``ref`` is
            None).
        nx: grid columns along x.
        ny: grid rows along y.
        ref: the Pinocchio model and tip frame (built from ``desc`` when None).
        seed: (n,) the reset seed, rad.
        needle_axis: (3,) the wanted needle axis (vertical, pointing down).
        dls_lambda, max_iter, tol: the DLS settings (see
            :func:`~tattotronix.kinematics.solve_point`).

    Returns:
        The grid and which cells are reachable.

    Raises:
        TattotronixError: a grid smaller than 2 x 2.
    """
    if nx < 2 or ny < 2:
        raise TattotronixError(f"the reachability grid must be at least 2 x 2, got {nx} x {ny}")
    t0 = time.perf_counter()
    ref = ref or PinocchioTip.from_description(desc, chain.tip_frame)
    centre = np.asarray(desc.panel_centre, dtype=float)
    size = np.asarray(desc.panel_size, dtype=float)
    z = float(centre[2] + size[2] / 2)
    xs = np.linspace(centre[0] - size[0] / 2, centre[0] + size[0] / 2, nx)
    ys = np.linspace(centre[1] - size[1] / 2, centre[1] + size[1] / 2, ny)
    q0 = np.asarray(seed, dtype=float)
    n = len(q0)
    ok = np.zeros((ny, nx), bool)
    res = np.zeros((ny, nx))
    reason = np.full((ny, nx), "", dtype="<U11")
    qs = np.full((ny, nx, n), np.nan)
    data = ref.model.createData()
    for r, y in enumerate(ys):
        q = q0
        for c, x in enumerate(xs):
            p = solve_point(ref, (x, y, z), needle_axis=needle_axis, q0=q, dls_lambda=dls_lambda,
                            max_iter=max_iter, tol=tol, data=data)
            ok[r, c], res[r, c], reason[r, c] = p.converged, p.residual, p.reason
            if p.converged:
                qs[r, c] = p.q
                q = p.q
            else:
                q = q0
    sigma5 = np.full((ny, nx), np.nan)
    cond = np.full((ny, nx), np.nan)
    if ok.any():
        k = conditioning(chain, qs[ok])
        sigma5[ok], cond[ok] = k.sigma[:, -1], k.cond
    return Reachability(x_m=xs, y_m=ys, z_m=z, centre_m=np.array([centre[0], centre[1], z]),
                        reachable=ok, residual=res, reason=reason, q=qs, sigma5=sigma5,
                        cond=cond, solve_s=time.perf_counter() - t0)


# --- the placement sweep -----------------------------------------------------------------

def axis_distance_m(chain: Chain, points_m: ArrayLike) -> Array:
    """Distance of arm-frame points from the first joint's axis (the base yaw axis), m."""
    p = np.atleast_2d(np.asarray(points_m, dtype=float))
    a = chain.origin_rot[0] @ chain.axis[0]
    d = p - chain.origin_xyz[0]
    return np.asarray(np.linalg.norm(np.cross(d, a), axis=1), dtype=float)


def place_path(uvz_mm: ArrayLike, kind: ArrayLike, width_mm: float, offset_mm: float) -> Array:
    """The path scaled to ``width_mm`` wide and shifted ``offset_mm`` in +x (panel mm).

    The drawing's extent is that of its non-travel points (marking and approach); (u, v)
    are scaled about the extent's centre so the drawing is ``width_mm`` wide, then the
    centre is put at ``(offset_mm, 0)``: the drawing reaches ``width_mm / 2 + offset_mm``
    in +x. Depths (z: clearance, approach, marking) are kept.

    Args:
        uvz_mm: (N, 3) the planned path, panel mm.
        kind: (N,) path kinds (0 travel, 1 mark, 2 approach).
        width_mm: the drawing's new width, mm.
        offset_mm: shift of its centre in +x, mm.

    Returns:
        (N, 3) the placed path, panel mm.

    Raises:
        TattotronixError: a non-positive width, or a drawing with no width.
    """
    uvz = np.asarray(uvz_mm, dtype=float)
    k = np.asarray(kind)
    drawn = k != TRAVEL if (k != TRAVEL).any() else np.ones(len(k), bool)
    u0, u1 = float(uvz[drawn, 0].min()), float(uvz[drawn, 0].max())
    v0, v1 = float(uvz[drawn, 1].min()), float(uvz[drawn, 1].max())
    if width_mm <= 0 or u1 - u0 <= 0:
        raise TattotronixError(
            f"cannot place a drawing {u1 - u0:.3g} mm wide at width {width_mm:g} mm: the width "
            "must be positive"
        )
    s = width_mm / (u1 - u0)
    out = uvz.copy()
    out[:, 0] = (uvz[:, 0] - (u0 + u1) / 2) * s + offset_mm
    out[:, 1] = (uvz[:, 1] - (v0 + v1) / 2) * s
    return out


@dataclass(frozen=True)
class Placement:
    """One placement of the drawing and how the arm does on it.

    Attributes:
        width_mm: drawing width, mm.
        offset_mm: shift in +x, mm.
        reach_mm: ``width_mm / 2 + offset_mm``, how far the drawing reaches in +x from the
            panel centre, mm.
        r_max_mm: the drawing's farthest (non-travel) point from the joint_1 axis, mm.
        r_worst_mm: the smallest-sigma_5 converged point's distance from that axis, mm
            (``r_max_mm`` when the whole drawing converged and its farthest point is the
            weakest; NaN when nothing converged).
        points: path points.
        converged_pct: IK converged share, %.
        sigma5_min: smallest sigma_5 over the converged points (NaN when none).
        cond_max: largest condition number over the converged points (NaN when none).
        manipulability_min: smallest manipulability over the converged points.
        worst_point_mm: (3,) panel mm of the smallest-sigma_5 point (NaN when none).
        solve_s: IK wall time, s.
    """

    width_mm: float
    offset_mm: float
    reach_mm: float
    r_max_mm: float
    r_worst_mm: float
    points: int
    converged_pct: float
    sigma5_min: float
    cond_max: float
    manipulability_min: float
    worst_point_mm: Array
    solve_s: float

    @property
    def label(self) -> str:
        """``"150x30"``."""
        return f"{self.width_mm:g}x{self.offset_mm:g}"

    def summary(self) -> JsonDict:
        """For the metrics file (NaN as null)."""
        return {
            "width_mm": self.width_mm,
            "offset_mm": self.offset_mm,
            "reach_mm": self.reach_mm,
            "r_max_mm": round(self.r_max_mm, 4),
            "r_worst_mm": _finite_or_none(round(self.r_worst_mm, 4)),
            "points": self.points,
            "converged_pct": self.converged_pct,
            "sigma5_min": _finite_or_none(self.sigma5_min),
            "cond_max": _finite_or_none(self.cond_max),
            "manipulability_min": _finite_or_none(self.manipulability_min),
            "worst_point_mm": [_finite_or_none(v) for v in _floats(self.worst_point_mm)],
        }


@dataclass(frozen=True)
class PlacementSweep:
    """The placement table.

    Attributes:
        rows: one per placement, in the order given.
        method: how the drawing was re-placed (the planned path scaled in the panel plane).
    """

    rows: tuple[Placement, ...]
    method: str = "planned path scaled in the panel plane about its extent's centre"
    stats: JsonDict = field(default_factory=dict)

    def equal_reach_spread_pct(self) -> dict[str, float]:
        """For each reach shared by two or more placements, the spread of their sigma_5
        minima, ``(max - min) / max``, %. Keys are the reach in mm (``"75"``)."""
        out: dict[str, float] = {}
        reaches = sorted({round(p.reach_mm, 6) for p in self.rows})
        for r in reaches:
            s5 = np.array([p.sigma5_min for p in self.rows if round(p.reach_mm, 6) == r])
            s5 = s5[np.isfinite(s5)]
            if len(s5) >= 2:
                out[f"{r:g}"] = float(100.0 * (s5.max() - s5.min()) / s5.max())
        return out

    def summary(self) -> JsonDict:
        """Rows keyed by label (``"150x30"``), the method, and the equal-reach spreads."""
        return {
            "method": self.method,
            "rows": {p.label: p.summary() for p in self.rows},
            "equal_reach_sigma5_spread_pct": self.equal_reach_spread_pct(),
        }


def placement_sweep(
    chain: Chain,
    uvz_mm: ArrayLike,
    kind: ArrayLike,
    widths_mm: Sequence[float] = PLACEMENT_WIDTHS_MM,
    offsets_mm: Sequence[float] = PLACEMENT_OFFSETS_MM,
    *,
    origin_m: ArrayLike = (0.21, 0.0, 0.005),
    seed: ArrayLike = SEED,
    needle_axis: ArrayLike = NEEDLE_AXIS,
    dls_lambda: float = DLS_LAMBDA,
    max_iter: int = MAX_ITER,
    tol: float = TOL,
    anchor_spacing_m: float = ANCHOR_SPACING_M,
    progress: Callable[[Placement], None] | None = None,
) -> PlacementSweep:
    """Re-place the drawing at each (width, offset) pair and solve the whole path.

    Args:
        chain: the kinematic model.
        uvz_mm: (N, 3) the planned path, panel mm.
        kind: (N,) its kinds (0 travel, 1 mark, 2 approach).
        widths_mm: drawing widths, mm, paired element by element with ``offsets_mm``.
        offsets_mm: shifts in +x, mm.
        origin_m: (3,) the panel origin (surface centre) in the arm frame, m.
        seed, needle_axis, dls_lambda, max_iter, tol, anchor_spacing_m: IK settings (see
            :func:`~tattotronix.kinematics.solve_path`).
        progress: called with each finished row.

    Returns:
        The placement table. A placement the arm cannot draw in full is a row with its
        converged share below 100 %, not an error.

    Raises:
        TattotronixError: widths and offsets of different lengths, or a bad width.
    """
    if len(widths_mm) != len(offsets_mm):
        raise TattotronixError(
            f"placement widths ({len(widths_mm)}) and offsets ({len(offsets_mm)}) are paired "
            "and must have the same length"
        )
    t0 = time.perf_counter()
    k = np.asarray(kind)
    drawn = k != TRAVEL if (k != TRAVEL).any() else np.ones(len(k), bool)
    origin = np.asarray(origin_m, dtype=float)
    rows: list[Placement] = []
    for w, o in zip(widths_mm, offsets_mm, strict=True):
        uvz = place_path(uvz_mm, k, float(w), float(o))
        x = origin + uvz / MM
        res = solve_path(chain, x, needle_axis=needle_axis, seed=seed, dls_lambda=dls_lambda,
                         max_iter=max_iter, tol=tol, anchor_spacing_m=anchor_spacing_m)
        ok = res.converged
        s5 = cmax = mmin = r_worst = math.nan
        worst = np.full(3, np.nan)
        if ok.any():
            c = conditioning(chain, res.q[ok])
            i = int(np.argmin(c.sigma[:, -1]))
            s5, cmax = float(c.sigma[i, -1]), float(c.cond.max())
            mmin = float(c.manipulability.min())
            j = int(np.flatnonzero(ok)[i])
            worst = uvz[j].copy()
            r_worst = float(axis_distance_m(chain, x[j])[0] * MM)
        row = Placement(
            width_mm=float(w), offset_mm=float(o), reach_mm=float(w) / 2 + float(o),
            r_max_mm=float(axis_distance_m(chain, x[drawn]).max() * MM), r_worst_mm=r_worst,
            points=len(x),
            converged_pct=res.converged_pct, sigma5_min=s5, cond_max=cmax,
            manipulability_min=mmin, worst_point_mm=worst, solve_s=res.solve_s)
        rows.append(row)
        if progress is not None:
            progress(row)
    return PlacementSweep(rows=tuple(rows), stats={"elapsed_s": time.perf_counter() - t0})


# --- the workspace -----------------------------------------------------------------------

@dataclass(frozen=True)
class Workspace:
    """Uniform samples of the joint box and where they put the tip.

    Attributes:
        q: (N, n) joint samples, rad.
        tip_m: (N, 3) tip positions in the arm frame, m.
        axis: (N, 3) needle axes (tip frame +z), unit.
        seed: the RNG seed.
    """

    q: Array
    tip_m: Array
    axis: Array
    seed: int

    def summary(self, chain: Chain | None = None) -> JsonDict:
        """Sample count, seed, tip ranges (mm) and, with ``chain``, the farthest distance
        from the joint_1 axis (mm)."""
        lo, hi = self.tip_m.min(axis=0) * MM, self.tip_m.max(axis=0) * MM
        out: dict[str, Any] = {
            "samples": int(len(self.q)),
            "seed": self.seed,
            "x_mm": [float(lo[0]), float(hi[0])],
            "y_mm": [float(lo[1]), float(hi[1])],
            "z_mm": [float(lo[2]), float(hi[2])],
        }
        if chain is not None:
            out["r_max_mm"] = float(axis_distance_m(chain, self.tip_m).max() * MM)
        return out


def workspace_samples(chain: Chain, n: int = WORKSPACE_SAMPLES,
                      seed: int = WORKSPACE_SEED) -> Workspace:
    """``n`` joint configurations drawn uniformly from the joint box (``numpy``'s
    ``default_rng(seed)``), and the tip positions and needle axes there (batched FK)."""
    rng = np.random.default_rng(seed)
    q = rng.uniform(chain.lower, chain.upper, size=(n, chain.n))
    p, z = chain.fk(q)
    return Workspace(q=q, tip_m=p, axis=z, seed=seed)


# --- figures (matplotlib, Agg) -----------------------------------------------------------

def _panel_patch(ax: Any, w_mm: float, h_mm: float, cx: float = 0.0, cy: float = 0.0,
                 zorder: float = 0) -> None:
    from matplotlib.patches import Rectangle

    ax.add_patch(Rectangle((cx - w_mm / 2, cy - h_mm / 2), w_mm, h_mm, facecolor="none",
                           edgecolor="#8a7f70", lw=1.4, zorder=zorder, label="panel"))


def _side_colorbar(fig: Any, ax: Any, mappable: Any, label: str) -> None:
    """A colour bar glued to ``ax`` (which may have an equal aspect)."""
    from mpl_toolkits.axes_grid1 import make_axes_locatable

    cax = make_axes_locatable(ax).append_axes("right", size="3%", pad=0.1)
    fig.colorbar(mappable, cax=cax, label=label)


def manipulability_figure(pc: PathConditioning, kind: ArrayLike, panel_size_mm: Sequence[float],
                          path: Path, title: str = "") -> None:
    """sigma_5, condition number and manipulability along the path (worst point marked),
    and a panel-plane map of the condition number; saved as a PNG.

    Args:
        pc: the path's conditioning.
        kind: (N,) path kinds (the map shows marking and approach points).
        panel_size_mm: (width, height[, thickness]) of the panel, mm.
        path: the PNG to write.
        title: first title line (the artwork's name).
    """
    plt = pyplot()
    from matplotlib.gridspec import GridSpec

    k = np.asarray(kind)
    idx = np.arange(len(pc.sigma5))
    w = pc.worst_index
    fig = plt.figure(figsize=(15, 6.8), dpi=120)
    gs = GridSpec(3, 2, figure=fig, width_ratios=(1.0, 1.15), hspace=0.12, wspace=0.14)
    series = [(pc.sigma5, "σ₅ (smallest\nsingular value)", "#1971c2"),
              (pc.cond.cond, "condition number\nσ₁ / σ₅", "#c92a2a"),
              (pc.cond.manipulability, "manipulability\n$\\sqrt{\\det(J\\,J^T)}$", "#2b8a3e")]
    axes: list[Any] = []
    for r, (y, label, colour) in enumerate(series):
        ax = fig.add_subplot(gs[r, 0], sharex=axes[0] if axes else None)
        ax.plot(idx, y, lw=0.6, color=colour)
        ax.plot([w], [y[w]], "o", ms=7, mfc="none", mec="black", mew=1.5,
                label=f"worst-conditioned point #{w}")
        ax.axvline(w, color="black", lw=0.6, ls=":")
        ax.set_ylabel(label, fontsize=8)
        ax.grid(alpha=0.3)
        if r < 2:
            ax.tick_params(labelbottom=False)
        axes.append(ax)
    # above the axes: inside, it would cover the curve
    axes[0].legend(loc="lower right", bbox_to_anchor=(1.0, 1.0), fontsize=7, frameon=False,
                   borderaxespad=0.1)
    axes[-1].set_xlabel("path point (index along the path)")

    ax = fig.add_subplot(gs[:, 1])
    pw, ph = float(panel_size_mm[0]), float(panel_size_mm[1])
    _panel_patch(ax, pw, ph)
    uv = pc.uvz_mm
    drawn = k != TRAVEL
    sc = ax.scatter(uv[drawn, 0], uv[drawn, 1], c=pc.cond.cond[drawn], s=1.5, cmap="viridis",
                    lw=0, rasterized=True)
    ax.plot(*pc.worst_point_mm[:2], "*", ms=16, mfc="#c92a2a", mec="white", mew=0.8,
            label="worst-conditioned point")
    wd = ", ".join(f"{v:+.3f}" for v in pc.weakest_direction)
    ax.annotate(f"({pc.worst_point_mm[0]:.2f}, {pc.worst_point_mm[1]:.2f}) mm\n"
                f"cond {pc.cond.cond[w]:.1f}, σ₅ {pc.sigma5[w]:.4f}\n"
                f"weakest dq (j1..j{len(pc.weakest_direction)}): ({wd})",
                xy=pc.worst_point_mm[:2], xytext=(0.02, 0.03), textcoords="axes fraction",
                fontsize=7.5, va="bottom",
                bbox={"boxstyle": "round", "fc": "white", "ec": "#aaaaaa", "alpha": 0.9},
                arrowprops={"arrowstyle": "->", "color": "#555555", "lw": 0.8})
    ax.set_xlim(-pw / 2 - 5, pw / 2 + 5)
    ax.set_ylim(-ph / 2 - 5, ph / 2 + 5)
    ax.set_aspect("equal")
    ax.set_xlabel("panel u (mm, +x away from the base)")
    ax.set_ylabel("panel v (mm)")
    ax.legend(loc="upper left", fontsize=7)
    _side_colorbar(fig, ax, sc, "condition number (marking and approach points)")
    s: dict[str, Any] = pc.summary()  # read back: JSON values
    fig.suptitle(
        f"{title + ': ' if title else ''}task-Jacobian conditioning along the path "
        f"({s['points']} points)   σ₁ {s['sigma1'][0]:.4f} .. {s['sigma1'][1]:.4f}, "
        f"σ₅ {s['sigma5'][0]:.4f} .. {s['sigma5'][1]:.4f}, "
        f"cond {s['cond'][0]:.1f} .. {s['cond'][1]:.1f}", fontsize=10)
    fig.subplots_adjust(left=0.07, right=0.95, top=0.93, bottom=0.08)
    fig.savefig(path, format="png")
    plt.close(fig)


def reachability_figure(reach: Reachability, uvz_mm: ArrayLike, kind: ArrayLike,
                        panel_size_mm: Sequence[float], path: Path, title: str = "") -> None:
    """The panel grid: reachable cells coloured by condition number (log scale),
    unreachable cells red with a cross, and the drawing (its non-travel points) over it;
    saved as a PNG. Coordinates are panel mm (the panel centre at the origin), like the
    toolpath figure.
    """
    plt = pyplot()
    from matplotlib.colors import ListedColormap, LogNorm

    cx, cy = reach.centre_m[0] * MM, reach.centre_m[1] * MM
    xs, ys = reach.x_m * MM - cx, reach.y_m * MM - cy
    pw, ph = float(panel_size_mm[0]), float(panel_size_mm[1])
    fig, ax = plt.subplots(figsize=(11, 11 * ph / pw + 1.0), dpi=120)
    good = reach.cond[reach.reachable]
    norm = LogNorm(vmin=float(good.min()), vmax=float(good.max())) if len(good) else None
    mesh = ax.pcolormesh(xs, ys, np.where(reach.reachable, reach.cond, np.nan),
                         shading="nearest", cmap="viridis", norm=norm, zorder=0)
    bad = np.where(reach.reachable, np.nan, 1.0)
    ax.pcolormesh(xs, ys, bad, shading="nearest", cmap=ListedColormap(["#e03131"]), zorder=1)
    rr, cc = np.nonzero(~reach.reachable)
    ax.plot(xs[cc], ys[rr], "x", color="white", ms=7, mew=1.5, zorder=2)
    _panel_patch(ax, pw, ph, zorder=4)
    uvz = np.asarray(uvz_mm, dtype=float)
    drawn = np.asarray(kind) != TRAVEL
    ax.scatter(uvz[drawn, 0], uvz[drawn, 1], s=0.3, c="white", lw=0, alpha=0.8, zorder=3,
               rasterized=True)
    ax.set_aspect("equal")
    dx, dy = (xs[1] - xs[0]) / 2, (ys[1] - ys[0]) / 2
    ax.set_xlim(xs[0] - dx - 2, xs[-1] + dx + 2)
    ax.set_ylim(ys[0] - dy - 2, ys[-1] + dy + 2)
    ax.set_xlabel(f"panel u (mm; arm x = {cx:.0f} + u, +x away from the base)")
    ax.set_ylabel(f"panel v (mm; arm y = {cy:.0f} + v)")
    handles = [legend_proxy("s", "#e03131", f"unreachable ({len(rr)} cells)", ms=8, mec="white"),
               legend_proxy("s", "#3b528b", "reachable (colour: condition number)", ms=8),
               legend_proxy("s", "none", "panel edge", ms=8, mec="#8a7f70"),
               legend_proxy(".", "#adb5bd", "the drawing (white)", ms=6)]
    ax.legend(handles=handles, loc="upper center", bbox_to_anchor=(0.5, -0.1), ncol=4,
              fontsize=8, frameon=False)
    _side_colorbar(fig, ax, mesh, "condition number σ₁ / σ₅ at the cell")
    ax.set_title(
        f"{title + ': ' if title else ''}panel reachability, needle vertical at the surface "
        f"(z = {reach.z_m * MM:.1f} mm): {reach.percent:.3f} % of "
        f"{len(reach.x_m)} × {len(reach.y_m)} cells\n"
        "rows swept in +x, warm-started from the previous success, reset to the seed after "
        "a failure", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, format="png")
    plt.close(fig)


def workspace_figure(ws: Workspace, desc: RobotDescription, path: Path,
                     reach: Reachability | None = None, down_deg: float = 20.0) -> None:
    """The sampled workspace: elevation (x-z) and plan (x-y) views of the tip positions,
    the panel, the zero-pose tip; samples whose needle points within ``down_deg`` of
    straight down are highlighted; with ``reach``, the panel grid cells reached or not.
    Saved as a PNG."""
    plt = pyplot()

    p = ws.tip_m * MM
    down = ws.axis[:, 2] < -math.cos(math.radians(down_deg))
    centre = np.asarray(desc.panel_centre) * MM
    size = np.asarray(desc.panel_size) * MM
    surface = centre[2] + size[2] / 2
    tcp0, _ = Chain.from_description(desc).fk(np.zeros(len(desc.joints)))
    tcp0 = tcp0[0] * MM
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(15, 7), dpi=120)
    for ax, (i, j), names in ((a1, (0, 2), ("x", "z")), (a2, (0, 1), ("x", "y"))):
        ax.scatter(p[~down, i], p[~down, j], s=0.4, c="#adb5bd", lw=0, alpha=0.5,
                   rasterized=True)
        ax.scatter(p[down, i], p[down, j], s=0.8, c="#1971c2", lw=0, alpha=0.7, rasterized=True)
        ax.plot(tcp0[i], tcp0[j], "*", ms=14, mfc="#f08c00", mec="black", mew=0.6)
        ax.plot(0, 0, "+", color="black", ms=12, mew=1.5)
        ax.set_xlabel(f"arm {names[0]} (mm)")
        ax.set_ylabel(f"arm {names[1]} (mm)")
        ax.set_aspect("equal")
        ax.grid(alpha=0.3)
    common = [
        legend_proxy(".", "#adb5bd", f"tip, any needle axis ({int((~down).sum())})"),
        legend_proxy(".", "#1971c2", f"tip, needle within {down_deg:g}° of down "
                                     f"({int(down.sum())})"),
        legend_proxy("*", "#f08c00", "tip at the zero pose", ms=10, mec="black"),
        legend_proxy("+", "black", "joint_1 axis", ms=10),
    ]
    a1.plot([centre[0] - size[0] / 2, centre[0] + size[0] / 2], [surface, surface], "-",
            color="#c92a2a", lw=3)
    a1.axhline(0, color="#495057", lw=1)
    a1.legend(handles=[*common, legend_proxy("", "#c92a2a", "panel surface", ls="-", lw=3),
                       legend_proxy("", "#495057", "bench top (z = 0)", ls="-", lw=1)],
              loc="lower left", fontsize=7, framealpha=0.9)
    _panel_patch(a2, float(size[0]), float(size[1]), float(centre[0]), float(centre[1]))
    extra = [legend_proxy("s", "none", "panel", ms=8, mec="#8a7f70")]
    if reach is not None:
        ok = reach.reachable
        xx, yy = np.meshgrid(reach.x_m * MM, reach.y_m * MM)
        a2.plot(xx[ok], yy[ok], ".", ms=2, color="#2b8a3e")
        a2.plot(xx[~ok], yy[~ok], "x", ms=4, color="#c92a2a")
        extra += [legend_proxy(".", "#2b8a3e", "panel cells reached, needle vertical"),
                  legend_proxy("x", "#c92a2a", "panel cells not reached")]
    a2.legend(handles=[*common, *extra], loc="lower left", fontsize=7, framealpha=0.9)
    a1.set_title("elevation (x-z; every y)", fontsize=9)
    a2.set_title("plan (x-y; every z)", fontsize=9)
    fig.suptitle(f"workspace: {len(p)} uniform joint-box samples (seed {ws.seed}) and where "
                 "they put the tip", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, format="png")
    plt.close(fig)


def placement_figure(sweep: PlacementSweep, path: Path, reach: Reachability | None = None,
                     chain: Chain | None = None, title: str = "") -> None:
    """sigma_5 minimum and condition maximum against the reach in +x, and sigma_5 against
    the weakest point's distance from the joint_1 axis (with the panel grid's sigma_5 at
    each reachable cell, the same function of that distance); saved as a PNG."""
    plt = pyplot()

    rows = sweep.rows
    reach_mm = np.array([p.reach_mm for p in rows])
    s5 = np.array([p.sigma5_min for p in rows])
    cm = np.array([p.cond_max for p in rows])
    rw = np.array([p.r_worst_mm for p in rows])
    conv = np.array([p.converged_pct for p in rows])
    full = conv >= 100.0
    fig, axes = plt.subplots(1, 3, figsize=(16, 5.2), dpi=120)
    labelled: list[tuple[Any, Array, Array, list[str], list[Array]]] = []
    for ax, y, label in ((axes[0], s5, "σ₅ min (converged points)"),
                         (axes[1], cm, "condition number max (converged points)")):
        order = np.argsort(reach_mm, kind="stable")
        ax.plot(reach_mm[order], y[order], "-", color="#adb5bd", lw=1, zorder=0)
        ax.plot(reach_mm[full], y[full], "o", color="#1971c2", ms=7, label="100 % converged")
        ax.plot(reach_mm[~full], y[~full], "s", color="#c92a2a", ms=7,
                label="not all converged")
        labelled.append((ax, reach_mm, y, [
            p.label + ("" if p.converged_pct >= 100 else f"\n{p.converged_pct:.1f} % conv.")
            for p in rows], [np.column_stack([reach_mm[order], y[order]])]))
        ax.set_xlabel("reach in +x from the panel centre, W / 2 + offset (mm)")
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
        ax.margins(x=0.12, y=0.1)
    axes[1].set_yscale("log")
    axes[0].legend(fontsize=7, loc="upper right")
    ax = axes[2]
    if reach is not None and chain is not None:
        ok = reach.reachable
        xx, yy = np.meshgrid(reach.x_m, reach.y_m)
        pts = np.column_stack((xx[ok], yy[ok], np.full(int(ok.sum()), reach.z_m)))
        ax.plot(axis_distance_m(chain, pts) * MM, reach.sigma5[ok], ".", color="#adb5bd",
                ms=4, label=f"panel grid cells (surface, z = {reach.z_m * MM:.1f} mm)")
    ax.plot(rw[full], s5[full], "o", color="#1971c2", ms=7, label="placements")
    ax.plot(rw[~full], s5[~full], "s", color="#c92a2a", ms=7)
    labelled.append((ax, rw, s5, [p.label for p in rows], []))
    ax.set_xlabel("distance of the weakest point from the joint_1 axis (mm)")
    ax.set_ylabel("σ₅")
    ax.grid(alpha=0.3)
    ax.margins(x=0.1, y=0.08)
    ax.legend(fontsize=7, loc="lower left")
    fig.suptitle(f"{title + ': ' if title else ''}placement sweep (drawing scaled to width W, "
                 "shifted +offset in x): σ₅ is a function of the distance from the "
                 "joint_1 axis", fontsize=10)
    fig.tight_layout()
    for ax, x, y, texts, lines in labelled:  # beside their markers, on the final layout
        place_labels(ax, np.column_stack([x, y]), texts, 4.0, avoid=lines, fontsize=7)
    fig.savefig(path, format="png")
    plt.close(fig)
