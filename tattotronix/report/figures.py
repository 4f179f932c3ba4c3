"""The pipeline's figures: the chain, joint trajectories, torques, step responses, tracking
and the mass model (README, "Figures"; the original's: docs/original.md, "The figures").

Each ``*_figure`` function takes plain data (arrays, small dataclasses) and the PNG to
write; none reads a file. The data come from the library, never re-implemented here:
Pinocchio FK of every named frame (:func:`arm_poses`), Pinocchio gravity along a
trajectory (:class:`~tattotronix.control.dynamics.Dynamics`), closed-loop steps of the
shared :class:`~tattotronix.control.controller.Controller` on the ``model`` plant
(:func:`step_set`), and python-control for the linear predictions.

:func:`draw_figures` is what ``stages/figures.py`` runs for one artwork: it loads the
stored trajectory, the MuJoCo run log and the URDF, and writes
``<data>/figures/<name>/{joints,torques,steps,tracking}.png``.

Units: SI inside (m, rad, s, N m, kg); figure axes in mm, µm, ms or g where they say so.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, cast

import numpy as np
from numpy.typing import ArrayLike, NDArray

from tattotronix.config.schema import Config, IkConfig
from tattotronix.control.steps import StepSet, step_set, tuning_pose
from tattotronix.errors import TattotronixError
from tattotronix.io.artifacts import RunLogRecord, TrajectoryRecord
from tattotronix.io.jsontypes import JsonValue
from tattotronix.io.outputs import Outputs
from tattotronix.path.kinds import MARK
from tattotronix.plotting import legend_proxy, place_labels, pyplot
from tattotronix.robot.description import RobotDescription

if TYPE_CHECKING:
    from tattotronix.collision.check import TrajectoryClearance

__all__ = [
    "DPI",
    "FIGSIZE",
    "ArmPoses",
    "arm_poses",
    "chain_figure",
    "draw_figures",
    "joints_figure",
    "mass_figure",
    "panel_pose",
    "steps_figure",
    "torques_figure",
    "tracking_figure",
]

log = logging.getLogger("tattotronix.figures")

Array = NDArray[np.float64]
_NEEDLE_AXIS = tuple(IkConfig().needle_axis)  # the schema's default (needle down)

#: Resolution of every figure, dots per inch.
DPI = 130
#: Figure sizes, inches (the PNG is ``round(w * DPI) x round(h * DPI)`` pixels).
FIGSIZE: dict[str, tuple[float, float]] = {
    "chain": (15.0, 7.4),
    "joints": (15.0, 9.0),
    "torques": (14.0, 9.5),
    "steps": (14.0, 9.0),
    "tracking": (14.0, 8.5),
    "mass": (14.0, 6.2),
    "clearance": (14.0, 7.0),
}
#: One colour per joint, base outward.
JOINT_COLOURS = ("#1971c2", "#e8590c", "#2b8a3e", "#c2255c", "#7048e8", "#495057")
MARK_SHADE = "#fff3bf"  # marking stretches
MM = 1000.0
UM = 1e6
#: Tip errors below this are drawn at it on log axes, um.
ERROR_FLOOR_UM = 1e-2


def _colour(i: int) -> str:
    return JOINT_COLOURS[i % len(JOINT_COLOURS)]


def _new_figure(kind: str) -> tuple[Any, Any]:
    plt = pyplot()
    return plt, plt.figure(figsize=FIGSIZE[kind], dpi=DPI)


def _save(plt: Any, fig: Any, path: Path) -> Path:
    fig.savefig(path, format="png", dpi=DPI)
    plt.close(fig)
    return Path(path)


def _shade(ax: Any, t: Array, on: NDArray[np.bool_], label: str | None = None) -> None:
    """Shade the stretches of ``t`` where ``on`` holds, full axis height."""
    if len(t) and np.any(on):
        ax.fill_between(t, 0, 1, where=on, step="post", transform=ax.get_xaxis_transform(),
                        color=MARK_SHADE, alpha=0.7, lw=0, zorder=0, label=label)


def _marking(kind: ArrayLike) -> NDArray[np.bool_]:
    """Per point: the segment starting there marks (both ends marking points)."""
    k = np.asarray(kind)
    m = np.zeros(len(k), bool)
    if len(k) > 1:
        m[:-1] = (k[:-1] == MARK) & (k[1:] == MARK)
    return m


# --- poses of every named frame ------------------------------------------------------------

@dataclass(frozen=True)
class ArmPoses:
    """Every named frame of the arm at ``K`` joint configurations (Pinocchio FK).

    Attributes:
        names: the frames, base outward (the description's links, then ``tool0``, ...).
        parents: (F,) index of each frame's parent in ``names`` (-1 for the base).
        q: (K, n) joint angles, rad.
        origins_m: (K, F, 3) frame origins in the arm frame, m.
        rotations: (K, F, 3, 3) frame orientations (columns: the frame's x, y, z axes).
        joint_names: the joints, base outward.
        joint_frames: (n,) index of each joint's child frame (the joint sits at its origin).
        joint_axes: (n, 3) each joint's unit axis in its child frame.
        tip: index of the tool tip frame.
    """

    names: tuple[str, ...]
    parents: NDArray[np.int64]
    q: Array
    origins_m: Array
    rotations: Array
    joint_names: tuple[str, ...]
    joint_frames: NDArray[np.int64]
    joint_axes: Array
    tip: int

    def chain(self) -> list[int]:
        """Frame indices from the base to the tip, following the parents."""
        out = [self.tip]
        while self.parents[out[-1]] >= 0:
            out.append(int(self.parents[out[-1]]))
        return out[::-1]

    def world_axes(self, k: int) -> Array:
        """(n, 3) joint axes in the arm frame at configuration ``k``."""
        return np.einsum("jab,jb->ja", self.rotations[k, self.joint_frames], self.joint_axes)


def arm_poses(desc: RobotDescription, urdf: Path, q: ArrayLike) -> ArmPoses:
    """Frame placements of every named frame at each row of ``q``, by Pinocchio on the
    generated URDF.

    Args:
        desc: the robot description (frame names, parents, joint axes).
        urdf: the generated ``data/robot/<name>.urdf``.
        q: (K, n) or (n,) joint angles, rad.

    Raises:
        TattotronixError: the URDF lacks a frame of the description, or ``q`` has the
            wrong width.
    """
    import pinocchio as pin

    from tattotronix.robot.loaders import load_pinocchio

    model = load_pinocchio(Path(urdf), desc.gravity)
    data = model.createData()
    qq = np.atleast_2d(np.asarray(q, dtype=np.float64))
    if qq.shape[1] != model.nq:
        raise TattotronixError(f"poses need {model.nq} joint angles per row, got {qq.shape[1]}")
    names = tuple(n for n in desc.frame_names if model.existFrame(n))
    missing = [n for n in desc.frame_names if n not in names]
    if missing:
        raise TattotronixError(f"{urdf} has no frame {missing}: re-run the 'robot' stage")
    ids = [model.getFrameId(n) for n in names]
    origins = np.empty((len(qq), len(names), 3))
    rots = np.empty((len(qq), len(names), 3, 3))
    for k, row in enumerate(qq):
        pin.framesForwardKinematics(model, data, np.ascontiguousarray(row))
        for f, fid in enumerate(ids):
            origins[k, f] = data.oMf[fid].translation
            rots[k, f] = data.oMf[fid].rotation
    index = {n: i for i, n in enumerate(names)}
    parents = np.array([index.get(desc.parent_of(n) or "", -1) for n in names], dtype=np.int64)
    return ArmPoses(
        names=names, parents=parents, q=qq, origins_m=origins, rotations=rots,
        joint_names=desc.joint_names,
        joint_frames=np.array([index[j.child] for j in desc.joints], dtype=np.int64),
        joint_axes=np.array([j.axis for j in desc.joints], dtype=np.float64),
        tip=index[desc.tip_frame])


def panel_pose(desc: RobotDescription, urdf: Path, target_m: ArrayLike,
               seed: ArrayLike, needle_axis: ArrayLike = _NEEDLE_AXIS) -> Array:
    """A drawing pose: the tip at ``target_m`` with the needle along ``needle_axis``
    (Pinocchio's single-point solver).

    Raises:
        TattotronixError: the solve did not converge (the message gives its reason).
    """
    from tattotronix.kinematics import PinocchioTip, solve_point

    ref = PinocchioTip.from_urdf(urdf, desc.tip_frame)
    res = solve_point(ref, target_m, needle_axis=needle_axis, q0=seed)
    if not res.converged:
        raise TattotronixError(f"no drawing pose at {np.round(np.asarray(target_m) * MM, 2)} "
                               f"mm: {res.reason} (residual {res.residual:.3g})")
    return np.asarray(res.q, dtype=np.float64)


# --- 1. the chain --------------------------------------------------------------------------

def _rect(ax: Any, x0: float, y0: float, w: float, h: float, **kw: Any) -> None:
    from matplotlib.patches import Rectangle

    ax.add_patch(Rectangle((x0, y0), w, h, **kw))


def chain_figure(poses: ArmPoses, labels: Sequence[str], panel_centre_m: ArrayLike,
                 panel_size_m: ArrayLike, panel_origin_m: ArrayLike, path: Path,
                 title: str = "the chain and its frames", triad_mm: float = 14.0) -> Path:
    """The arm in elevation (x-z) and plan (x-y): links as lines between the frame
    origins, RGB frame triads, joint axes, the bench top and the panel, the TCP in mm.

    Args:
        poses: the frames at one or more configurations; the first is drawn solid (with
            triads and frame names), the others dashed.
        labels: one legend label per configuration.
        panel_centre_m, panel_size_m: the panel box (``robot.panel``), m.
        panel_origin_m: the toolpath's panel origin (``toolpath.panel_origin``), m.
        path: the PNG to write.
        title: the figure title.
        triad_mm: length of the triad arrows, mm.
    """
    plt, fig = _new_figure("chain")
    gs = fig.add_gridspec(1, 2, width_ratios=(1.25, 1.0), wspace=0.12)
    ax_el, ax_pl = fig.add_subplot(gs[0]), fig.add_subplot(gs[1])
    centre = np.asarray(panel_centre_m, float) * MM
    size = np.asarray(panel_size_m, float) * MM
    origin = np.asarray(panel_origin_m, float) * MM
    chain = poses.chain()
    views = ((ax_el, (0, 2), ("x", "z")), (ax_pl, (0, 1), ("x", "y")))
    handles: list[Any] = []
    pose_colours = ("#212529", "#1971c2", "#2b8a3e", "#e8590c")
    for k in range(len(poses.q)):
        o = poses.origins_m[k] * MM
        colour = pose_colours[k % len(pose_colours)]
        ls = "-" if k == 0 else "--"
        tcp = o[poses.tip]
        for ax, (i, j), _ in views:
            ax.plot(o[chain, i], o[chain, j], ls, color=colour, lw=2.4 if k == 0 else 1.8,
                    marker="o", ms=4.5, mfc="white", mec=colour, zorder=3)
            ax.plot(tcp[i], tcp[j], "v" if k else "D", color=colour, ms=7, zorder=4)
        handles.append(legend_proxy("o", colour, labels[k] if k < len(labels) else f"pose {k}",
                                    ls=ls, lw=2))
        # TCP coordinates, mm (elevation: left of the tip; plan: below it)
        txt = f"{poses.names[poses.tip]}\n({tcp[0]:.2f}, {tcp[1]:.2f}, {tcp[2]:.2f}) mm"
        box = {"boxstyle": "round", "fc": "white", "ec": colour, "alpha": 0.9}
        ax_el.annotate(txt, xy=(tcp[0], tcp[2]), xytext=(-150 if k == 0 else 40, 28 + 8 * k),
                       textcoords="offset points", fontsize=8, color=colour, bbox=box,
                       arrowprops={"arrowstyle": "->", "color": colour, "lw": 0.8})
        ax_pl.annotate(txt, xy=(tcp[0], tcp[1]), xytext=(-140 if k == 0 else 25,
                                                          -70 if k == 0 else 55),
                       textcoords="offset points", fontsize=8, color=colour, bbox=box,
                       arrowprops={"arrowstyle": "->", "color": colour, "lw": 0.8})
    # triads, joint axes and names at the first configuration
    o = poses.origins_m[0] * MM
    rot = poses.rotations[0]
    # what the names must not cover, per view: the chains, the triads, the joint axes
    drawn: list[list[Array]] = [[poses.origins_m[k][chain][:, [i, j]] * MM
                                 for k in range(len(poses.q))] for _, (i, j), _ in views]
    shown: list[Array] = []
    for f in range(len(poses.names)):
        if any(np.linalg.norm(o[f] - p) < 1e-6 for p in shown):
            continue  # a frame at the same place as one drawn (tattoo_pen_link at tool0)
        shown.append(o[f])
        for v, (ax, (i, j), _) in enumerate(views):
            for a, c in enumerate(("#e03131", "#2f9e44", "#1c7ed6")):
                d = rot[f][:, a] * triad_mm
                if math.hypot(d[i], d[j]) > 0.5:
                    ax.annotate("", xy=(o[f, i] + d[i], o[f, j] + d[j]), xytext=(o[f, i], o[f, j]),
                                arrowprops={"arrowstyle": "-|>", "color": c, "lw": 1.1,
                                            "mutation_scale": 7}, zorder=5)
                    drawn[v].append(np.array([[o[f, i], o[f, j]],
                                              [o[f, i] + d[i], o[f, j] + d[j]]]))
    axes_w = poses.world_axes(0)
    joint_of = {int(jf): jn for jn, jf in enumerate(poses.joint_frames)}
    for jf, a in zip(poses.joint_frames, axes_w, strict=True):
        p = o[jf]
        for v, (ax, (i, j), _) in enumerate(views):
            d = a * 28.0
            if math.hypot(d[i], d[j]) < 0.3 * 28.0:  # the axis points out of the page
                ax.plot(p[i], p[j], "o", ms=9, mfc="none", mec="#862e9c", mew=1.2, zorder=6)
                ax.plot(p[i], p[j], ".", ms=4, color="#862e9c", zorder=6)
            else:
                ax.plot([p[i] - d[i], p[i] + d[i]], [p[j] - d[j], p[j] + d[j]], "-.",
                        color="#862e9c", lw=1.1, zorder=2)
                drawn[v].append(np.array([[p[i] - d[i], p[j] - d[j]], [p[i] + d[i], p[j] + d[j]]]))
    # bench top and panel
    allo = poses.origins_m.reshape(-1, 3) * MM
    xlo = min(float(allo[:, 0].min()), centre[0] - size[0] / 2) - 40
    xhi = max(float(allo[:, 0].max()), centre[0] + size[0] / 2) + 40
    ax_el.axhline(0.0, color="#495057", lw=1.2)
    _rect(ax_el, xlo - 100, -25, xhi - xlo + 200, 25, facecolor="#e9ecef", edgecolor="none",
          hatch="//", zorder=0)
    _rect(ax_el, centre[0] - size[0] / 2, centre[2] - size[2] / 2, size[0], size[2],
          facecolor="#d9c7a5", edgecolor="#8a7f70", lw=1.2, zorder=1)
    _rect(ax_pl, centre[0] - size[0] / 2, centre[1] - size[1] / 2, size[0], size[1],
          facecolor="#f4ece0", edgecolor="#8a7f70", lw=1.4, zorder=0)
    for ax, (i, j), _ in views:
        ax.plot(origin[i], origin[j], "P", color="#c92a2a", ms=8, mec="white", zorder=6)
    ax_pl.plot(0, 0, "+", color="black", ms=12, mew=1.5)
    handles += [
        legend_proxy("", "#e03131", "frame x axis", ls="-", lw=2),
        legend_proxy("", "#2f9e44", "frame y axis", ls="-", lw=2),
        legend_proxy("", "#1c7ed6", "frame z axis", ls="-", lw=2),
        legend_proxy("", "#862e9c", "joint axis (circle: normal to view)", ls="-.", lw=1.2),
        legend_proxy("s", "#d9c7a5", f"panel {size[0]:.0f} x {size[1]:.0f} x {size[2]:.0f} mm",
                     ms=9, mec="#8a7f70"),
        legend_proxy("P", "#c92a2a", f"panel origin ({origin[0]:.0f}, {origin[1]:.0f}, "
                                     f"{origin[2]:.0f}) mm", ms=8),
        legend_proxy("s", "#e9ecef", "bench (top at z = 0)", ms=9, mec="#495057"),
    ]
    zhi = float(allo[:, 2].max()) + 60
    ax_el.set_xlim(xlo, xhi)
    ax_el.set_ylim(-25, zhi)
    ylo = min(float(allo[:, 1].min()), centre[1] - size[1] / 2) - 40
    yhi = max(float(allo[:, 1].max()), centre[1] + size[1] / 2) + 40
    ax_pl.set_xlim(xlo, xhi)
    ax_pl.set_ylim(ylo, yhi)
    ax_el.set_title("elevation (x-z, seen from -y)", fontsize=9)
    ax_pl.set_title("plan (x-y, seen from above)", fontsize=9)
    for ax, _, (xname, yname) in views:
        ax.set_aspect("equal")
        ax.grid(alpha=0.3)
        ax.set_xlabel(f"arm {xname} (mm)")
        ax.set_ylabel(f"arm {yname} (mm)")
    ax_pl.legend(handles=handles, loc="upper left", fontsize=7.5, framealpha=0.92,
                 bbox_to_anchor=(0.0, -0.13), ncol=2)
    fig.suptitle(f"{title}\n(frame triads, names and joint axes at the first pose)",
                 fontsize=11)
    fig.subplots_adjust(left=0.05, right=0.98, top=0.91, bottom=0.08)
    # names where they cover least: in elevation every frame (a joint's frame with the
    # joint: "j2 upper_arm_link", in the joints' purple); in plan the joints
    frames = [f for f, name in enumerate(poses.names) if name != "tattoo_pen_link"]
    drawn[0].append(np.array([[xlo, 0.0], [xhi, 0.0]]))  # the bench top
    for v, (ax, (i, j), _) in enumerate(views):
        picked = frames if v == 0 else [int(jf) for jf in poses.joint_frames]
        taken: list[Any] = []
        for purple in (True, False):
            these = [f for f in picked if (f in joint_of) == purple]
            if not these:
                continue
            texts = [f"j{joint_of[f] + 1}" + (f" {poses.names[f]}" if v == 0 else "")
                     if purple else poses.names[f] for f in these]
            others = [(float(o[f, i]), float(o[f, j]), 5.0) for f in picked if f not in these]
            place_labels(ax, o[these][:, [i, j]], texts, 5.0, avoid=drawn[v], marks=others,
                         taken=taken, fontsize=8 if purple else 7,
                         color="#862e9c" if purple else "#343a40",
                         weight="bold" if purple and v == 1 else "normal", zorder=7,
                         bbox={"fc": "white", "ec": "none", "alpha": 0.75, "pad": 0.4})
    return _save(plt, fig, path)


# --- 2. joint trajectories -----------------------------------------------------------------

def joints_figure(t: ArrayLike, q: ArrayLike, qd: ArrayLike, qdd: ArrayLike, kind: ArrayLike,
                  joint_names: Sequence[str], lower: ArrayLike, upper: ArrayLike,
                  velocity_limit: ArrayLike, accel_limit: float, path: Path,
                  title: str = "", zoom_s: tuple[float, float] | None = None) -> Path:
    """q, qd and qdd of every joint against time over the whole drawing, with the joint
    limits and the marking stretches shaded; a zoom on a few seconds on the right.

    Args:
        t: (N,) point times, s.
        q, qd, qdd: (N, n) angles (rad), rates (rad/s), accelerations (rad/s^2).
        kind: (N,) point kinds (0 travel, 1 mark, 2 approach).
        joint_names: the joints.
        lower, upper: (n,) position limits, rad.
        velocity_limit: (n,) rate limits, rad/s.
        accel_limit: the trajectory's acceleration limit, rad/s^2.
        path: the PNG to write.
        title: first title words (the artwork's name).
        zoom_s: (start, length) of the zoom, s (default: 6 s around the middle entry).
    """
    tt = np.asarray(t, float)
    series = [np.asarray(a, float) for a in (q, qd, qdd)]
    mark = _marking(kind)
    n = series[0].shape[1]
    lo, hi = np.asarray(lower, float), np.asarray(upper, float)
    vl = np.broadcast_to(np.asarray(velocity_limit, float), (n,))
    limits = [(lo, hi), (-vl, vl), (np.full(n, -accel_limit), np.full(n, accel_limit))]
    if zoom_s is None:
        entries = np.flatnonzero(mark & ~np.concatenate(([False], mark[:-1])))
        mid = float(tt[entries[len(entries) // 2]]) if len(entries) else float(tt[-1]) / 2
        zoom_s = (max(0.0, mid - 2.0), 6.0)
    z0, z1 = zoom_s[0], min(zoom_s[0] + zoom_s[1], float(tt[-1]))
    plt, fig = _new_figure("joints")
    gs = fig.add_gridspec(3, 2, width_ratios=(2.4, 1.0), hspace=0.1, wspace=0.13)
    labels = ("angle q (rad)", "rate qd (rad/s)", "acceleration qdd (rad/s²)")
    zsel = (tt >= z0) & (tt <= z1)
    axes = np.empty((3, 2), dtype=object)
    for r in range(3):
        for c in range(2):
            ax = fig.add_subplot(gs[r, c], sharex=axes[0, c] if r else None)
            axes[r, c] = ax
            sel = slice(None) if c == 0 else zsel
            _shade(ax, tt[sel], mark[sel])
            for j in range(n):
                ax.plot(tt[sel], series[r][sel, j], lw=0.5 if c == 0 else 1.0,
                        color=_colour(j))
            llo, lhi = limits[r]
            same = np.allclose(llo, llo[0]) and np.allclose(lhi, lhi[0])
            for j in range(1 if same else n):
                colour = "#c92a2a" if same else _colour(j)
                ax.axhline(llo[j], color=colour, ls="--", lw=0.9)
                ax.axhline(lhi[j], color=colour, ls="--", lw=0.9)
            span = float(max(np.abs(llo).max(), np.abs(lhi).max()))
            ax.set_ylim(-1.12 * span, 1.12 * span)
            ax.grid(alpha=0.3)
            if c == 0:
                ax.set_ylabel(labels[r])
            else:
                ax.tick_params(labelleft=False)
            if r < 2:
                ax.tick_params(labelbottom=False)
        axes[0, 0].axvspan(z0, z1, color="#868e96", alpha=0.18, lw=0, zorder=0)
    axes[2, 0].set_xlabel("time (s)")
    axes[2, 1].set_xlabel("time (s)")
    axes[0, 0].set_xlim(float(tt[0]), float(tt[-1]))
    axes[0, 1].set_xlim(z0, z1)
    axes[0, 1].set_title(f"zoom: {z0:.1f} to {z1:.1f} s (grey band on the left)", fontsize=9)
    handles = [legend_proxy("", _colour(j), name, ls="-", lw=2)
               for j, name in enumerate(joint_names)]
    handles += [legend_proxy("", "#c92a2a", "limit (position, velocity, trajectory acceleration)",
                             ls="--", lw=1),
                legend_proxy("s", MARK_SHADE, "needle marking", ms=10)]
    fig.legend(handles=handles, loc="upper center", ncol=len(handles), fontsize=8,
               bbox_to_anchor=(0.5, 0.955), frameon=False)
    peak_v = np.abs(series[1]).max(axis=0)
    peak_a = np.abs(series[2]).max(axis=0)
    fig.suptitle(f"{title + ': ' if title else ''}joint trajectories ({len(tt)} points, "
                 f"{tt[-1]:.1f} s)   peak rate {peak_v.max():.2f} rad/s "
                 f"(limit {vl.max():g}), peak acceleration {peak_a.max():.2f} rad/s² "
                 f"(limit {accel_limit:g})", fontsize=11)
    fig.subplots_adjust(left=0.06, right=0.985, top=0.9, bottom=0.06)
    return _save(plt, fig, path)


# --- 3. gravity and torques ----------------------------------------------------------------

def torques_figure(t_plan: ArrayLike, gravity_nm: ArrayLike, t_run: ArrayLike,
                   tau_nm: ArrayLike, down: ArrayLike, joint_names: Sequence[str], path: Path,
                   title: str = "", torque_limit_nm: float | None = None,
                   backend: str = "mujoco") -> Path:
    """Per joint: the gravity torque G(q) along the planned trajectory (Pinocchio) and the
    torque the controller applied in the simulated run, with both peaks marked.

    Args:
        t_plan: (N,) trajectory point times, s.
        gravity_nm: (N, n) G(q) at the points, N m.
        t_run: (S,) run log sample times, s.
        tau_nm: (S, n) applied torque at the samples, N m.
        down: (S,) the needle was marking at the sample (shaded).
        joint_names: the joints.
        path: the PNG to write.
        title: first title words (the artwork's name).
        torque_limit_nm: the controller's limit (stated in the title).
        backend: the plant the run was on.
    """
    tp, g = np.asarray(t_plan, float), np.asarray(gravity_nm, float)
    tr, tau = np.asarray(t_run, float), np.asarray(tau_nm, float)
    dn = np.asarray(down, bool)
    n = g.shape[1]
    plt, fig = _new_figure("torques")
    axes: list[Any] = []
    for j in range(n):
        ax = fig.add_subplot(n, 1, j + 1, sharex=axes[0] if axes else None)
        axes.append(ax)
        _shade(ax, tr, dn)
        ax.plot(tr, tau[:, j], color=_colour(j), lw=0.6,
                label=f"applied torque, simulated ({backend})")
        ax.plot(tp, g[:, j], color="black", lw=0.9, label="gravity G(q), planned q (Pinocchio)")
        ig, it = int(np.argmax(np.abs(g[:, j]))), int(np.argmax(np.abs(tau[:, j])))
        ax.plot(tp[ig], g[ig, j], "o", ms=7, mfc="none", mec="black", mew=1.2)
        ax.plot(tr[it], tau[it, j], "v", ms=7, color="black")
        ax.text(1.003, 0.5, f"peak |G| {abs(g[ig, j]):.4f} N m\n  at {tp[ig]:.1f} s\n"
                f"peak |τ| {abs(tau[it, j]):.4f} N m\n  at {tr[it]:.1f} s",
                transform=ax.transAxes, fontsize=7.5, va="center", ha="left",
                bbox={"boxstyle": "round", "fc": "white", "ec": "#adb5bd"})
        lo = float(min(g[:, j].min(), tau[:, j].min()))
        hi = float(max(g[:, j].max(), tau[:, j].max()))
        pad = 0.08 * max(hi - lo, 1e-6)
        ax.set_ylim(lo - pad, hi + pad)
        ax.set_ylabel(f"{joint_names[j]}\n(N m)", fontsize=9)
        ax.grid(alpha=0.3)
        if j < n - 1:
            ax.tick_params(labelbottom=False)
    axes[-1].set_xlabel("time (s)")
    axes[0].set_xlim(float(min(tp[0], tr[0] if len(tr) else tp[0])),
                     float(max(tp[-1], tr[-1] if len(tr) else tp[-1])))
    handles = [legend_proxy("", "black", "gravity G(q) along the planned trajectory (Pinocchio)",
                            ls="-", lw=1),
               legend_proxy("", "#1971c2", f"applied torque in the simulated run ({backend}; "
                                           "joint colour)", ls="-", lw=1),
               legend_proxy("o", "none", "peak |G|", mec="black"),
               legend_proxy("v", "black", "peak |τ|"),
               legend_proxy("s", MARK_SHADE, "needle marking", ms=10)]
    fig.legend(handles=handles, loc="upper center", ncol=len(handles), fontsize=8,
               bbox_to_anchor=(0.47, 0.955), frameon=False)
    lim = f"; torque limit {torque_limit_nm:g} N m, far off scale" if torque_limit_nm else ""
    fig.suptitle(f"{title + ': ' if title else ''}gravity and applied joint torques along the "
                 f"drawing (peak |τ| {np.abs(tau).max():.3f} N m, peak |G| "
                 f"{np.abs(g).max():.3f} N m{lim})", fontsize=11)
    fig.subplots_adjust(left=0.085, right=0.87, top=0.91, bottom=0.06, hspace=0.1)
    fig.align_ylabels(axes)  # one column of joint names, clear of the widest tick labels
    return _save(plt, fig, path)


# --- 4. step responses ---------------------------------------------------------------------

def steps_figure(sets: Sequence[StepSet], path: Path, title: str = "") -> Path:
    """Step responses: one panel per (bandwidth, structure); in each, every joint's
    simulated response (solid), the coupled linear loop (thin dashed) and the single-axis
    prediction (black dashed), time in units of ``1 / wn``, with the overshoots listed.

    Args:
        sets: the step sets; panels are arranged by bandwidth (rows) and structure
            (columns).
        path: the PNG to write.
        title: first title words (the artwork's name).
    """
    wns = sorted({s.wn for s in sets}, reverse=True)
    structs = list(dict.fromkeys(s.structure for s in sets))
    plt, fig = _new_figure("steps")
    gs = fig.add_gridspec(len(wns), len(structs), hspace=0.32, wspace=0.1)
    first: Any = None
    for s in sets:
        r, c = wns.index(s.wn), structs.index(s.structure)
        ax = fig.add_subplot(gs[r, c], sharex=first, sharey=first)
        first = first or ax
        x = s.t * s.wn
        ax.axhline(1.0, color="#868e96", lw=0.8)
        ax.plot(x, s.single_axis, "--", color="black", lw=2.0, zorder=5)
        rows = [f"{'overshoot':<9}{'sim':>7}{'linear':>8}    ", "-" * 28]
        for j, name in enumerate(s.joint_names):
            ax.plot(x, s.response[j], "-", color=_colour(j), lw=1.4, drawstyle="steps-post")
            ax.plot(x, s.linear[j], ":", color=_colour(j), lw=1.2)
            mark = " sat" if s.saturated[j] else "    "
            rows.append(f"{name:<9}{s.overshoot_pct[j]:6.1f}%{s.linear_overshoot_pct[j]:7.1f}%"
                        f"{mark}")
        rows.append(f"{'1 axis':<9}{'':>7}{s.single_axis_pct:7.1f}%    ")
        if s.saturated.any():
            rows.append("sat: torque limit reached")
        ax.text(0.985, 0.04, "\n".join(r.ljust(28) for r in rows), transform=ax.transAxes,
                ha="right", va="bottom", family="monospace", fontsize=7.2,
                bbox={"boxstyle": "round", "fc": "white", "ec": "#adb5bd", "alpha": 0.92})
        ax.set_title(f"{s.label}, wn = {s.wn:g} rad/s, {s.rate_hz:g} Hz (wn T = "
                     f"{s.wn / s.rate_hz:.3g}); {math.degrees(s.step_rad):g} deg steps",
                     fontsize=9)
        ax.grid(alpha=0.3)
        if r == len(wns) - 1:
            ax.set_xlabel("time after the step × wn (1 = 1/wn)")
        else:
            ax.tick_params(labelbottom=False)
        if c == 0:
            ax.set_ylabel("joint travel / step")
        else:
            ax.tick_params(labelleft=False)
    if first is not None:
        first.set_xlim(0, float(max(s.t[-1] * s.wn for s in sets)))
        hi = max(float(np.nanmax(np.r_[s.response.ravel(), s.linear.ravel()])) for s in sets)
        first.set_ylim(-0.1, max(1.5, min(hi * 1.05, 4.0)))
    handles = [legend_proxy("", _colour(j), name, ls="-", lw=2)
               for j, name in enumerate(sets[0].joint_names)] if sets else []
    handles += [legend_proxy("", "#495057", "simulated, model plant (solid)", ls="-", lw=1.4),
                legend_proxy("", "#495057", "coupled linear loop, M(q0) (dotted)", ls=":", lw=1.4),
                legend_proxy("", "black", "single axis, python-control (dashed)", ls="--", lw=2)]
    fig.legend(handles=handles, loc="upper center", ncol=len(handles), fontsize=8,
               bbox_to_anchor=(0.5, 0.95), frameon=False)
    q0 = ", ".join(f"{v:.3f}" for v in sets[0].tune_q) if sets else ""
    fig.suptitle(f"{title + ': ' if title else ''}step responses, one joint stepped at a time "
                 f"from the tuning pose q0 = ({q0}) rad, the others holding", fontsize=11)
    fig.subplots_adjust(left=0.06, right=0.985, top=0.885, bottom=0.07)
    return _save(plt, fig, path)


# --- 5. tracking ---------------------------------------------------------------------------

def tracking_figure(t: ArrayLike, error_m: ArrayLike, down: ArrayLike, settled: ArrayLike,
                    path: Path, title: str = "", needle_um: float = 300.0,
                    target_um: float = 20.0, backend: str = "mujoco") -> Path:
    """The tip error along the drawing (um, log scale) coloured by state, the worst
    marking point marked, the needle width and the target as reference lines; below,
    the distribution (histogram and cumulative) of the settled marking error.

    Args:
        t: (S,) sample times, s.
        error_m: (S,) 3-D tip error against the reference, m.
        down: (S,) marking samples.
        settled: (S,) marking samples past the settling time after an entry.
        path: the PNG to write.
        title: first title words (the artwork's name).
        needle_um: the needle width, um (reference line).
        target_um: the worst-marking target, um (reference line).
        backend: the plant the run was on.
    """
    tt = np.asarray(t, float)
    e_raw = np.asarray(error_m, float) * UM
    e = np.maximum(e_raw, ERROR_FLOOR_UM)  # for the log axes
    dn, st = np.asarray(down, bool), np.asarray(settled, bool)
    entering = dn & ~st
    travel = ~dn
    plt, fig = _new_figure("tracking")
    gs = fig.add_gridspec(2, 2, height_ratios=(1.35, 1.0), hspace=0.32, wspace=0.16)
    ax = fig.add_subplot(gs[0, :])
    for sel, colour, label, size in (
            (travel, "#adb5bd", f"travel and approach ({int(travel.sum())})", 1.5),
            (entering, "#f08c00", f"marking, settling after an entry ({int(entering.sum())})",
             4.0),
            (st, "#1971c2", f"marking, settled ({int(st.sum())})", 1.5)):
        ax.scatter(tt[sel], e[sel], s=size, c=colour, lw=0, label=label, rasterized=True)
    ax.axhline(needle_um, color="#c92a2a", ls="--", lw=1.1,
               label=f"needle width {needle_um:g} µm")
    ax.axhline(target_um, color="#2b8a3e", ls="--", lw=1.1,
               label=f"target: worst marking < {target_um:g} µm")
    if dn.any():
        iw = int(np.flatnonzero(dn)[np.argmax(e[dn])])
        ax.plot(tt[iw], e[iw], "*", ms=16, mfc="#c92a2a", mec="black", mew=0.7, zorder=6)
        ax.annotate(f"worst marking: {e[iw]:.1f} µm at {tt[iw]:.2f} s"
                    f"{' (settled)' if st[iw] else ' (settling)'}", (tt[iw], e[iw]),
                    xytext=(-30, 18), textcoords="offset points", ha="right", fontsize=8,
                    bbox={"boxstyle": "round", "fc": "white", "ec": "#adb5bd"},
                    arrowprops={"arrowstyle": "->", "lw": 0.8})
    ax.set_yscale("log")
    ax.set_ylim(ERROR_FLOOR_UM * 0.8, max(float(e.max()), needle_um) * 2.5)
    ax.set_xlim(float(tt[0]), float(tt[-1]))
    ax.set_xlabel("time (s)")
    ax.set_ylabel(f"tip error |p - p_ref| (µm)\n(below {ERROR_FLOOR_UM:g} µm drawn at it)",
                  fontsize=9)
    ax.grid(alpha=0.3, which="both", lw=0.4)
    ax.legend(loc="lower left", bbox_to_anchor=(0.0, 1.0), fontsize=7.5, ncol=5,
              markerscale=4, frameon=False)

    es = e_raw[st]
    ah, ac = fig.add_subplot(gs[1, 0]), fig.add_subplot(gs[1, 1])
    if len(es):
        below = int((es < ERROR_FLOOR_UM).sum())
        bins = np.geomspace(ERROR_FLOOR_UM, max(float(es.max()), ERROR_FLOOR_UM) * 1.001, 60)
        ah.hist(es[es >= ERROR_FLOOR_UM], bins=bins, color="#1971c2", alpha=0.8)
        ah.set_title(f"histogram of the settled marking error ({below} samples, "
                     f"{100.0 * below / len(es):.1f} %, below {ERROR_FLOOR_UM:g} µm: not "
                     "binned)", fontsize=9)
        for v, ls, lab in ((float(es.mean()), "-", "mean"),
                           (float(np.percentile(es, 99)), "--", "99th percentile"),
                           (float(es.max()), ":", "max")):
            ah.axvline(v, color="black", ls=ls, lw=1.0, label=f"{lab} {v:.2f} µm")
        ah.set_xscale("log")
        ah.legend(fontsize=7.5, loc="upper left")
        for sel, colour, lab, ls in ((travel, "#adb5bd", "travel and approach", "-"),
                                     (dn, "#f08c00", "all marking", "-"),
                                     (st, "#1971c2", "settled marking", "--")):
            srt = np.sort(e[sel])
            if len(srt):
                ac.plot(srt, np.arange(1, len(srt) + 1) / len(srt) * 100.0, color=colour,
                        lw=1.6, ls=ls, label=f"{lab} (max {srt[-1]:.1f} µm)")
        ac.axvline(target_um, color="#2b8a3e", ls="--", lw=1.0)
        ac.axvline(needle_um, color="#c92a2a", ls="--", lw=1.0)
        ac.set_xscale("log")
        ac.legend(fontsize=7.5, loc="upper left")
    else:
        for a in (ah, ac):
            a.text(0.5, 0.5, "no settled marking samples", ha="center", va="center",
                   transform=a.transAxes)
    ah.set_xlabel("settled marking error (µm, log bins)")
    ah.set_ylabel("samples")
    if not len(es):
        ah.set_title("histogram of the settled marking error", fontsize=9)
    ac.set_xlabel("tip error (µm)")
    ac.set_ylabel("share of samples at or below (%)")
    ac.set_title("cumulative distribution", fontsize=9)
    ac.set_ylim(0, 101)
    for a in (ah, ac):
        a.grid(alpha=0.3, which="both", lw=0.4)
    stats = (f"settled mean {es.mean():.2f} µm, max {es.max():.1f} µm; " if len(es) else "")
    stats += f"marking max {e_raw[dn].max():.1f} µm" if dn.any() else "no marking"
    fig.suptitle(f"{title + ': ' if title else ''}tracking along the whole drawing "
                 f"(simulated, {backend}; {len(tt)} samples, {tt[-1] - tt[0]:.0f} s): "
                 f"{stats}", fontsize=11)
    fig.subplots_adjust(left=0.07, right=0.985, top=0.9, bottom=0.07)
    return _save(plt, fig, path)


# --- 6. the mass model ---------------------------------------------------------------------

def mass_figure(report: Mapping[str, JsonValue], path: Path, poses: ArmPoses | None = None,
                title: str = "the mass model") -> Path:
    """Per link: the printed shell and the servos (stacked bars, g) and the pen; the CoM of
    each link placed on the zero-pose arm (elevation, marker area ~ mass), or, without
    ``poses``, the CoM offsets in each link's frame.

    Args:
        report: the mass stage's ``data/metrics/mass.json`` (``links``: per link
            ``shell_g``, ``servos_g``, ``total_g``, ``com_mm``; ``totals``).
        path: the PNG to write.
        poses: the frames at the zero pose (first configuration used).
        title: first title words.
    """
    links = cast("Mapping[str, Any]", report["links"])  # JSON values, read by key
    totals = cast("Mapping[str, Any]", report.get("totals", {}))
    order = list(poses.names) if poses is not None else list(links)
    names = [n for n in order if n in links] + [n for n in links if n not in order]
    shell = np.array([float(links[n]["shell_g"]) for n in names])
    servo = np.array([float(links[n]["servos_g"]) for n in names])
    pen_g = float(totals.get("pen_kg", 0.0)) * 1e3
    plt, fig = _new_figure("mass")
    gs = fig.add_gridspec(1, 2, width_ratios=(1.0, 1.15), wspace=0.2)
    ab, ac = fig.add_subplot(gs[0]), fig.add_subplot(gs[1])
    x = np.arange(len(names) + (1 if pen_g else 0))
    labels = [n.replace("_link", "") for n in names] + (["tattoo pen"] if pen_g else [])
    ab.bar(x[:len(names)], shell, color="#ffc078", edgecolor="#d9480f", label="printed shell")
    ab.bar(x[:len(names)], servo, bottom=shell, color="#748ffc", edgecolor="#364fc7",
           label="servos")
    if pen_g:
        ab.bar(x[-1], pen_g, color="#ced4da", edgecolor="#495057", label="tool (pen)")
    tot = np.r_[shell + servo, [pen_g] if pen_g else []]
    for xi, v in zip(x, tot, strict=True):
        ab.text(xi, v + 2, f"{v:.1f} g", ha="center", va="bottom", fontsize=8)
    ab.set_xticks(x, labels, rotation=20, ha="right")
    ab.set_ylabel("mass (g)")
    ab.set_ylim(0, float(tot.max()) * 1.15)
    ab.grid(axis="y", alpha=0.3)
    ab.legend(fontsize=8, loc="upper right")
    ab.set_title("per link: printed shell and servos", fontsize=9)
    masses = shell + servo
    if poses is not None:
        o = poses.origins_m[0] * MM
        rot = poses.rotations[0]
        chain = poses.chain()
        ac.plot(o[chain, 0], o[chain, 2], "-", color="#212529", lw=2.0, marker="o", ms=4,
                mfc="white", zorder=2, label="the arm at the zero pose (frame origins)")
        idx = {n: i for i, n in enumerate(poses.names)}
        com_w = np.full((len(names), 3), np.nan)  # link CoMs in the arm frame, mm
        for k, n in enumerate(names):
            if n not in idx:
                continue
            f = idx[n]
            c = o[f] + rot[f] @ np.asarray(links[n]["com_mm"], float)
            com_w[k] = c
            ac.scatter(c[0], c[2], s=masses[k] * 4.0, color=_colour(k), alpha=0.75,
                       edgecolor="black", lw=0.6, zorder=3)
        # the moving links: all but the base (the first frame of the chain)
        moving = np.isfinite(com_w[:, 0]) & (np.array(names) != poses.names[chain[0]])
        m_moving = float(masses[moving].sum())
        if m_moving > 0:
            cg = (com_w[moving] * masses[moving, None]).sum(axis=0) / m_moving
            ac.plot(cg[0], cg[2], "X", ms=12, color="#c92a2a", mec="white", zorder=4,
                    label=f"CoM of the moving links (pen excluded), {m_moving:.0f} g: "
                          f"({cg[0]:.1f}, {cg[2]:.1f}) mm")
        ac.axhline(0.0, color="#495057", lw=1.0)
        pts = np.vstack([o[chain], com_w[np.isfinite(com_w[:, 0])]])
        ac.set_xlim(float(pts[:, 0].min()) - 30, float(pts[:, 0].max()) + 45)
        ac.set_ylim(-15, float(pts[:, 2].max()) + 45)
        ac.set_aspect("equal")
        ac.set_xlabel("arm x (mm)")
        ac.set_ylabel("arm z (mm)")
        ac.legend(fontsize=7.5, loc="lower right")
        ac.set_title("link centres of mass at the zero pose (elevation; marker area ~ mass)",
                     fontsize=9)
        fig.subplots_adjust(left=0.06, right=0.98, top=0.86, bottom=0.14)
        shown = np.isfinite(com_w[:, 0])
        # beside each marker (radius sqrt(area / pi), points), clear of the arm and the
        # other markers (the CoM cross among them)
        place_labels(ac, com_w[shown][:, [0, 2]],
                     [f"{n.replace('_link', '')}\n{m:.1f} g"
                      for n, m in zip(np.array(names)[shown], masses[shown], strict=True)],
                     np.sqrt(masses[shown] * 4.0 / math.pi), avoid=[o[chain][:, [0, 2]]],
                     marks=[(float(cg[0]), float(cg[2]), 7.0)] if m_moving > 0 else [],
                     fontsize=7.5, zorder=5)
    else:
        com = np.array([links[n]["com_mm"] for n in names], float)
        w = 0.27
        for a, lab in enumerate("xyz"):
            ac.bar(np.arange(len(names)) + (a - 1) * w, com[:, a], w, label=f"CoM {lab}")
        ac.set_xticks(np.arange(len(names)), [n.replace("_link", "") for n in names],
                      rotation=20, ha="right")
        ac.set_ylabel("CoM in the link frame (mm)")
        ac.legend(fontsize=8)
        ac.set_title("link centres of mass, link frames", fontsize=9)
    ac.grid(alpha=0.3)
    bits = []
    if "arm_kg" in totals:
        bits.append(f"arm {totals['arm_kg']:.3f} kg")
    if "moving_kg" in totals:
        bits.append(f"moving {totals['moving_kg']:.3f} kg (with the pen)")
    if "servos_share_pct" in totals:
        bits.append(f"servos {totals['servos_share_pct']:.1f} % of the arm")
    src = str(report.get("source", "")).split("(")[0].strip()
    fig.suptitle(f"{title}: {', '.join(bits)}" + (f"\nsource: {src}" if src else ""),
                 fontsize=11)
    fig.subplots_adjust(left=0.06, right=0.98, top=0.86, bottom=0.14)
    return _save(plt, fig, path)


# --- the stage body ------------------------------------------------------------------------

def draw_figures(cfg: Config, out: Outputs, name: str) -> dict[str, Path]:
    """Write ``figures/<name>/{joints,torques,steps,tracking}.png`` and the ``dvc plots``
    tables ``plots/<name>/{tracking,joints,joint_speed}.csv`` (:func:`plot_tables`).

    Reads the stored trajectory (the 'trajectory' stage), the MuJoCo run log (the
    'simulate' stage) and the URDF (the 'robot' stage).

    Returns:
        Figure name -> the (final) path written.
    """
    import time

    from tattotronix.control.dynamics import Dynamics
    from tattotronix.robot.description import build_description


    desc = build_description(cfg.robot)
    traj_file = TrajectoryRecord.require(out.data, name=name)
    urdf = out.require(out.input("robot", f"{desc.name}.urdf"), "robot")
    run = RunLogRecord.load_run(out.data, name, "mujoco")
    traj = TrajectoryRecord.load(traj_file)
    fig_dir = out.path("figures", name)
    written: dict[str, Path] = {}
    times: dict[str, float] = {}

    t0 = time.perf_counter()
    target = fig_dir / "joints.png"
    joints_figure(traj.t, traj.q, traj.qd, traj.qdd, traj.kind, traj.joints, desc.lower,
                  desc.upper, [j.velocity for j in desc.joints],
                  float(cfg.trajectory.accel_rad_s2), out.tmp_path(target), name)
    written["joints"] = target
    times["joints"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    dyn = Dynamics(urdf, desc.gravity)
    grav = np.array([dyn.gravity(row) for row in traj.q])
    ctl = cfg.controller
    effort = np.array([j.effort for j in desc.joints])
    limit: Any = effort if ctl.torque_limit_nm is None else float(ctl.torque_limit_nm)
    target = fig_dir / "torques.png"
    torques_figure(traj.t, grav, run.t, run.tau, run.down, traj.joints,
                   out.tmp_path(target), name, float(np.max(limit)))
    written["torques"] = target
    times["torques"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    tune_q = tuning_pose(cfg.controller, traj.t, traj.q, traj.qd)
    sets = []
    for wn in dict.fromkeys((float(ctl.wn), 20.0)):
        for structure in ("pid_g", "pid_g_v"):
            s = step_set(desc, urdf, tune_q, wn, structure, float(ctl.rate_hz),
                         float(cfg.plant.dt_s), limit)
            sets.append(s)
            sat = [j for j, on in zip(s.joint_names, s.saturated, strict=True) if on]
            log.info("figures %s: %s at wn %g: overshoot sim %s %%, coupled linear %s %%, "
                     "single axis %.1f %%%s", name, s.label, wn,
                     " ".join(f"{v:.1f}" for v in s.overshoot_pct),
                     " ".join(f"{v:.1f}" for v in s.linear_overshoot_pct), s.single_axis_pct,
                     f"; saturated: {', '.join(sat)}" if sat else "")
    target = fig_dir / "steps.png"
    steps_figure(sets, out.tmp_path(target), name)
    written["steps"] = target
    times["steps"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    target = fig_dir / "tracking.png"
    tracking_figure(run.t, run.error_m, run.down, run.settled,
                    out.tmp_path(target), name, needle_um=cfg.toolpath.needle_um)
    written["tracking"] = target
    times["tracking"] = time.perf_counter() - t0
    plots = out.path("plots", name)
    vel = np.array([j.velocity for j in desc.joints])
    for file, rows in plot_tables(traj.t, traj.q, traj.qd, traj.joints, desc.lower,
                                  desc.upper, vel, run.t, run.error_m, run.down).items():
        written[file] = out.write_csv(plots / file, rows)
    log.info("figures %s: %s", name, ", ".join(f"{k} {v:.2f} s" for k, v in times.items()))
    return written


#: rows of a ``dvc plots`` table along the drawing (each a time bin)
PLOT_ROWS = 800


def _bins(t: Array, n: int) -> list[NDArray[np.intp]]:
    """Indices of ``t`` in ``n`` equal time bins (empty bins left out)."""
    edges = np.linspace(t[0], t[-1], n + 1)
    which = np.clip(np.searchsorted(edges, t, side="right") - 1, 0, n - 1)
    order = np.argsort(which, kind="stable")
    splits = np.flatnonzero(np.diff(which[order])) + 1
    return [idx for idx in np.split(order, splits) if idx.size]


def plot_tables(t: ArrayLike, q: ArrayLike, qd: ArrayLike, joints: Sequence[str],
                lower: ArrayLike, upper: ArrayLike, velocity: ArrayLike, t_run: ArrayLike,
                error_m: ArrayLike, down: ArrayLike,
                rows: int = PLOT_ROWS) -> dict[str, list[dict[str, object]]]:
    """The drawing's ``dvc plots`` tables, each at most ``rows`` time bins long, so a
    worst value is never sampled away:

    * ``tracking.csv``: the tip's worst error in each bin (µm) and whether the needle was
      down in it;
    * ``joints.csv``: each joint's position as a share of its range (0-100 %, the limits);
    * ``joint_speed.csv``: each joint's fastest speed in the bin, as a share of its
      velocity limit (100 % is the limit).
    """
    t, q, qd = (np.asarray(a, dtype=np.float64) for a in (t, q, qd))
    lo, hi, vel = (np.asarray(a, dtype=np.float64) for a in (lower, upper, velocity))
    t_run, err = np.asarray(t_run, dtype=np.float64), np.asarray(error_m, dtype=np.float64)
    dn = np.asarray(down, dtype=bool)
    tables: dict[str, list[dict[str, object]]] = {"tracking.csv": [], "joints.csv": [],
                                                  "joint_speed.csv": []}
    if t_run.size:
        for idx in _bins(t_run, rows):
            e = err[idx]
            ok = np.isfinite(e)
            tables["tracking.csv"].append({
                "t_s": float(t_run[idx[0]]),
                "error_um": float(e[ok].max() * 1e6) if ok.any() else None,
                "needle_down": int(dn[idx].any())})
    for idx in _bins(t, rows):
        i = int(idx[len(idx) // 2])
        pos: dict[str, object] = {"t_s": float(t[i])}
        speed: dict[str, object] = {"t_s": float(t[idx[0]])}
        for j, joint in enumerate(joints):
            pos[f"{joint}_pct"] = float(100.0 * (q[i, j] - lo[j]) / (hi[j] - lo[j]))
            speed[f"{joint}_pct"] = float(100.0 * np.abs(qd[idx, j]).max() / vel[j])
        tables["joints.csv"].append(pos)
        tables["joint_speed.csv"].append(speed)
    return {k: v for k, v in tables.items() if v}


def clearance_figure(rep: TrajectoryClearance, t: ArrayLike, kind: ArrayLike, path: Path,
                     pairs: int = 6) -> Path:
    """The clearance of the closest pairs along a checked trajectory (collision stage).

    Left: each of the ``pairs`` closest pairs' clearance over time (mm, log scale), the
    margin dashed, marking shaded. Right: every checked pair's least clearance, sorted.
    The title names the least clearance, its pair, the margin and the check's effort.
    """
    pair_names, margin_m, w = rep.pair_names, rep.margin_m, rep.worst
    title = (f"least clearance {rep.min_clearance_m[w] * 1000:.2f} mm "
             f"({pair_names[w].replace('|', ' / ')}), margin {margin_m * 1000:g} mm; "
             f"{rep.samples} poses, {rep.bisected} segments bisected")
    plt, fig = _new_figure("clearance")
    tt, ser = np.asarray(t), np.asarray(rep.series_m) * MM
    least = np.asarray(rep.min_clearance_m) * MM
    order = np.argsort(least)
    ax = fig.add_axes((0.06, 0.27, 0.56, 0.63))
    _shade(ax, tt, _marking(kind), "marking")
    for i, p in enumerate(order[:pairs]):
        ax.plot(tt, np.maximum(ser[:, p], 1e-2), lw=0.9, color=_colour(i),
                label=f"{pair_names[p].replace('|', ' / ')} (least {least[p]:.2f} mm)")
    ax.axhline(margin_m * MM, color="#c92a2a", ls="--", lw=1.2,
               label=f"margin {margin_m * MM:g} mm")
    ax.set_yscale("log")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("clearance (mm)")
    # below the axes: inside, it would cover the curves
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.1), ncol=2, fontsize=8,
              frameon=False)
    ax.set_title("closest pairs along the drawing")
    bx = fig.add_axes((0.74, 0.1, 0.24, 0.8))
    y = np.arange(len(order))
    bx.barh(y, np.maximum(least[order], 1e-2), color="#1971c2")
    bx.set_yticks(y, [pair_names[p].replace("_link", "").replace("|", " / ") for p in order],
                  fontsize=7)
    bx.invert_yaxis()
    bx.set_xscale("log")
    bx.axvline(margin_m * MM, color="#c92a2a", ls="--", lw=1.2)
    bx.set_xlabel("least clearance (mm)")
    bx.set_title("every checked pair")
    fig.suptitle(title)
    return _save(plt, fig, path)
