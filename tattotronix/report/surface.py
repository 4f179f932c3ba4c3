"""The figure of a drawing on a curved surface: where the arm can tattoo on the phantom,
with the design laid on it (issue 33)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from tattotronix.app.onskin import SkinDrawing, SkinRun
from tattotronix.errors import TattotronixError
from tattotronix.kinematics.onsurface import PointsReach, SurfaceReach
from tattotronix.path.kinds import MARK
from tattotronix.plants import Workpiece
from tattotronix.plotting import pyplot
from tattotronix.report.animation import RenderResult, drawing_clip
from tattotronix.report.render3d import SkinInk, render_drawing_3d
from tattotronix.robot.description import RobotDescription
from tattotronix.surface.chart import Chart

__all__ = ["limb_ink_figure", "skin_drawing_video", "skin_ink", "surface_figure"]

#: the ink drawn on the limb: one dot per pixel of this pitch (or the raster's, if coarser)
LIMB_INK_PITCH_MM = 0.15
#: the patch of skin shown around the design, mm past its ink
LIMB_MARGIN_MM = 15.0


def surface_figure(d: SkinDrawing, reach: SurfaceReach | PointsReach | None, path: Path,
                   title: str) -> None:
    """Left: the reachability map over the phantom, unrolled (along its axis, around it),
    coloured by the task Jacobian's condition number where the needle reaches along the
    normal, grey where it does not, with the design's marking points on it (on a mesh:
    its tested points in 3-D, coloured the same way). Right: the limb and the design's
    needle path on it, seen from the side of the arm's base."""
    plt = pyplot()
    fig = plt.figure(figsize=(12.0, 5.2))
    mark = d.skin.kind == MARK
    xyz = d.skin.xyz_mm
    cone = d.surface.cone
    if isinstance(reach, PointsReach):
        _points_reach_axes(fig, reach, xyz[mark])
    elif isinstance(reach, SurfaceReach) and cone is not None:
        ax = fig.add_subplot(1, 2, 1)
        cond = np.where(reach.reachable, reach.cond, np.nan)
        ext = (reach.around_deg[0], reach.around_deg[-1], reach.along_mm[0],
               reach.along_mm[-1])
        ax.imshow(np.where(reach.reachable, 0.0, 1.0), cmap="Greys", vmin=0, vmax=3,
                  origin="lower", aspect="auto", extent=ext, interpolation="nearest")
        im = ax.imshow(cond, cmap="viridis", origin="lower", aspect="auto", extent=ext,
                       interpolation="nearest")
        fig.colorbar(im, ax=ax, label="condition number (where reached)")
        # the design's marking points in the phantom's (around, along) coordinates
        inv = np.linalg.inv(cone.pose)
        local = xyz[mark] @ inv[:3, :3].T + inv[:3, 3]
        a, b = cone.semi_axes(local[:, 0])
        theta = np.degrees(np.arctan2(local[:, 2] / b, local[:, 1] / a)) % 360.0
        ax.plot(theta, local[:, 0], ",", color="crimson", alpha=0.6)
        share = 100.0 * float(reach.reachable.mean())
        ax.set_title(f"needle along the normal reaches {share:.0f} % of the phantom\n"
                     "(grey: out of reach; red: the design)", fontsize=10)
        side = cone.posed(np.array([[0.0, 1.0, 0.0]]), vectors=True)[0]
        k = int(np.argmax(np.abs(side[:2])))
        towards = {(0, True): "+x (away from the base)", (0, False): "-x (the base)",
                   (1, True): "+y", (1, False): "-y"}[(k, bool(side[k] > 0))]
        ax.set_xlabel(f"around the limb, deg (90: the top, 0: the side towards the arm's "
                      f"{towards})")
        ax.set_ylabel("along the limb from the elbow end, mm")
    else:
        ax = fig.add_subplot(1, 2, 1)
        ax.plot(d.skin.uvz_mm[mark, 0], d.skin.uvz_mm[mark, 1], ",", color="crimson")
        ax.set_aspect("equal")
        ax.set_title("the design in its chart (mm on the skin)", fontsize=10)
        ax.set_xlabel("u, mm")
        ax.set_ylabel("v, mm")
    ax3 = fig.add_subplot(1, 2, 2, projection="3d")
    v, f = d.surface.vertices, d.surface.faces
    ax3.plot_trisurf(v[:, 0], v[:, 1], v[:, 2], triangles=f, color="peachpuff",
                     alpha=0.35, linewidth=0.0, shade=True)
    ax3.plot(xyz[mark, 0], xyz[mark, 1], xyz[mark, 2], ",", color="crimson")
    step = max(1, int(mark.sum()) // 40)
    pts = xyz[mark][::step]
    ax3.quiver(pts[:, 0], pts[:, 1], pts[:, 2], *(-12.0 * d.skin.axis[mark][::step].T),
               color="k", linewidth=0.5, arrow_length_ratio=0.0)
    ax3.scatter([0.0], [0.0], [0.0], color="k", marker="^", s=40)
    ax3.text(0.0, 0.0, 5.0, "arm base", fontsize=8)
    lo, hi = v.min(axis=0), v.max(axis=0)
    lo[:2] = np.minimum(lo[:2], -10.0)  # the arm's base in view
    lo[2] = 0.0
    ax3.set_xlim(lo[0], hi[0])
    ax3.set_ylim(lo[1], hi[1])
    ax3.set_zlim(lo[2], hi[2])
    ax3.set_box_aspect(tuple(float(x) for x in hi - lo))  # true proportions
    ax3.locator_params(nbins=5)
    ax3.set_xlabel("x, mm")
    ax3.set_ylabel("y, mm")
    ax3.set_zlabel("z, mm")
    ax3.view_init(elev=25.0, azim=-150.0)
    mark_vertical = d.from_vertical_deg[mark]
    ax3.set_title(f"the design on the limb: IK {100 * float(d.ik.converged.mean()):.1f} %, "
                  f"tilt error {float(d.tilt_deg.max()):.1e} deg,\nneedle "
                  f"{float(mark_vertical.min()):.0f} to {float(mark_vertical.max()):.0f} deg "
                  "from vertical (ticks: 12 mm of needle)", fontsize=10)
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=110, metadata={"Software": None})
    plt.close(fig)


def _points_reach_axes(fig: Any, reach: PointsReach, design_mm: NDArray[np.float64]) -> None:
    """The mesh's tested points in 3-D: coloured by the condition number where the needle
    reaches along the normal, grey where it does not; the design in red."""
    ax = fig.add_subplot(1, 2, 1, projection="3d")
    p = reach.xyz_m * 1000.0
    ok = reach.reachable
    ax.scatter(*p[~ok].T, color="0.7", s=6, depthshade=False)
    sc = ax.scatter(*p[ok].T, c=reach.cond[ok], cmap="viridis", s=8, depthshade=False)
    fig.colorbar(sc, ax=ax, label="condition number (where reached)", shrink=0.7)
    ax.plot(*design_mm.T, ",", color="crimson")
    lo, hi = p.min(axis=0), p.max(axis=0)
    ax.set_box_aspect(tuple(float(x) for x in np.maximum(hi - lo, 1.0)))
    ax.locator_params(nbins=5)
    ax.set_xlabel("x, mm")
    ax.set_ylabel("y, mm")
    ax.set_zlabel("z, mm")
    ax.view_init(elev=25.0, azim=-150.0)
    ax.set_title(f"needle along the normal reaches {100.0 * float(ok.mean()):.0f} % of "
                 f"{len(ok)} points of the mesh\n(grey: out of reach; red: the design)",
                 fontsize=10)


def _view(direction: NDArray[np.float64]) -> tuple[float, float]:
    """Matplotlib's (elevation, azimuth), degrees, of a view looking back along
    ``direction`` (from its tip towards the origin)."""
    x, y, z = (float(c) for c in direction / np.linalg.norm(direction))
    return float(np.degrees(np.arcsin(np.clip(z, -1.0, 1.0)))), float(np.degrees(
        np.arctan2(y, x)))


def limb_ink_figure(d: SkinDrawing, run: SkinRun, path: Path, title: str) -> None:
    """The simulated ink on the limb in 3-D: every inked pixel of the run's raster (in the
    design's chart) carried onto the skin by the chart, over the patch of skin around it.
    Left: seen along the skin's normal at the design's centre (the design as it reads on
    the skin); right: seen along the limb's axis, a little down the normal (how it wraps
    around the limb)."""
    plt = pyplot()
    grid = run.grid
    step = max(1, int(round(LIMB_INK_PITCH_MM / grid.res_mm)))
    rows, cols = np.nonzero(run.sim_ink[::step, ::step])
    uv = np.column_stack(grid.to_mm(cols * step, rows * step)) - np.asarray(d.centre_mm)
    ink = d.chart.to_surface(uv) if len(uv) else None
    centre = d.chart.to_surface(np.zeros((1, 2)))
    v, f = d.surface.vertices, d.surface.faces
    if ink is not None:
        lo, hi = ink.xyz.min(axis=0) - LIMB_MARGIN_MM, ink.xyz.max(axis=0) + LIMB_MARGIN_MM
    else:
        lo = centre.xyz[0] - 2 * LIMB_MARGIN_MM
        hi = centre.xyz[0] + 2 * LIMB_MARGIN_MM
    mid = v[f].mean(axis=1)
    near = np.all((mid >= lo) & (mid <= hi), axis=1)
    fig = plt.figure(figsize=(12.0, 5.6))
    normal = centre.normal[0]
    # the limb's axis: the mesh's longest principal direction; looking along it (and a
    # little down the normal) shows the design's curve around the limb
    spread = v - v.mean(axis=0)
    axis = np.linalg.svd(spread, full_matrices=False)[2][0]
    axis = axis - (axis @ normal) * normal
    axis = axis / np.linalg.norm(axis) if np.linalg.norm(axis) > 1e-9 else np.array(
        [1.0, 0.0, 0.0])
    for i, (look, what) in enumerate(((normal, "along the skin's normal at its centre"),
                                      (axis + 0.6 * normal, "along the limb"))):
        ax = fig.add_subplot(1, 2, i + 1, projection="3d")
        if near.any():
            ax.plot_trisurf(v[:, 0], v[:, 1], v[:, 2], triangles=f[near], color="peachpuff",
                            alpha=0.55, linewidth=0.0, shade=True)
        if ink is not None:
            dots = ink.xyz + 0.05 * ink.normal  # on the skin, not inside its shading
            ax.scatter(dots[:, 0], dots[:, 1], dots[:, 2], s=0.4, c="#1b1f3b", marker=".",
                       linewidths=0.0, depthshade=False)
        span = hi - lo
        ax.set_xlim(lo[0], hi[0])
        ax.set_ylim(lo[1], hi[1])
        ax.set_zlim(lo[2], hi[2])
        ax.set_box_aspect(tuple(float(x) for x in span))  # true proportions
        ax.locator_params(nbins=4)
        ax.set_xlabel("x, mm")
        ax.set_ylabel("y, mm")
        ax.set_zlabel("z, mm")
        elev, azim = _view(look)
        ax.view_init(elev=elev, azim=azim)
        if i == 0:  # the depth axis, seen end on
            ax.set_zticks([])
            ax.set_zlabel("")
        ax.set_title(f"seen {what}", fontsize=10)
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=110, metadata={"Software": None})
    plt.close(fig)


#: bare skin kept around the design in the 3-D video's ink raster, mm
VIDEO_MARGIN_MM = 4.0
#: the 3-D video's ink texel on the skin, mm
VIDEO_INK_RES_MM = 0.1
#: the 3-D video's frame rate (a GIF: the 2-D animation's GIF rate)
VIDEO_FPS = 12.5


def skin_ink(d: SkinDrawing, run: SkinRun, *, margin_mm: float = VIDEO_MARGIN_MM,
             res_mm: float = VIDEO_INK_RES_MM) -> SkinInk:
    """The skin as the 3-D video's ink canvas: the limb's mesh, each vertex near the
    design located in the design's chart (from the planned skin point nearest it, refined
    by the chart's own inverse, as the simulated tips are), and the run's tips in the
    chart (the reference's where the run's ink is not scored)."""
    from scipy.spatial import cKDTree

    verts = np.asarray(d.surface.vertices, dtype=np.float64)
    u0, v0, u1, v1 = d.box_mm
    cu, cv = d.centre_mm
    box = (u0 + cu - margin_mm, v0 + cv - margin_mm, u1 + cu + margin_mm, v1 + cv + margin_mm)
    dist, near = cKDTree(d.skin.xyz_mm).query(verts)
    uv = np.full((len(verts), 2), np.nan)
    # only vertices within the raster's reach of the design: the chart's inverse starts
    # from the nearest planned point, and a vertex across the limb has no point near it
    close = np.flatnonzero(dist <= 2 * margin_mm)
    got, height = _locate_each(d.chart, verts[close], d.skin.uvz_mm[near[close], :2])
    ok = np.all(np.isfinite(got), axis=1) & (np.abs(height) <= 0.5)
    uv[close[ok]] = got[ok] + np.asarray(d.centre_mm)
    tips = run.uvz_mm if len(run.uvz_mm) else run.uvz_ref_mm
    limb = Workpiece(verts / 1000.0, np.asarray(d.surface.faces, dtype=np.int64))
    return SkinInk(limb, uv, np.asarray(tips, dtype=np.float64), box, res_mm)


def _locate_each(chart: Chart, xyz_mm: NDArray[np.float64], guess_uv_mm: NDArray[np.float64]
                 ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """:meth:`Chart.locate` of each point, NaN where the chart cannot carry it back (a
    vertex past a scan's patch): the points in halves, down to the ones it refuses."""
    if len(xyz_mm) == 0:
        return np.zeros((0, 2)), np.zeros(0)
    try:
        return chart.locate(xyz_mm, guess_uv_mm)
    except TattotronixError:
        if len(xyz_mm) == 1:
            return np.full((1, 2), np.nan), np.full(1, np.nan)
    h = len(xyz_mm) // 2
    a, b = (_locate_each(chart, xyz_mm[s], guess_uv_mm[s]) for s in (slice(0, h),
                                                                   slice(h, None)))
    return np.concatenate([a[0], b[0]]), np.concatenate([a[1], b[1]])


def skin_drawing_video(d: SkinDrawing, run: SkinRun, desc: RobotDescription, urdf: Path,
                       mjcf: Path, name: str, gif: Path, mp4: Path | None = None
                       ) -> RenderResult:
    """The drawing on the skin in 3-D, as a GIF and (given ``mp4``) an MP4
    (:func:`~tattotronix.report.render3d.render_drawing_3d`, at the 2-D animation's GIF
    rate: every frame rendered is kept): the arm as the simulated run moved it, the limb
    in the panel's place, the ink growing on it where the simulated tip was in the skin,
    seen close, through a long lens (the design and the pen over it, not the whole arm)."""
    traj, sim = d.trajectory, run.loop.run
    scored = len(run.uvz_mm) > 0
    clip = drawing_clip(desc, urdf, name, traj.t, traj.q, traj.kind, traj.tcp, traj.marked,
                        np.zeros(3), run_t=sim.t, run_q=sim.q, run_tip_m=run.tip_m,
                        run_label=("the simulated run" if scored else
                                   "the simulated run (its ink not scored: the "
                                   "reference's shown)"), fps=VIDEO_FPS)
    return render_drawing_3d(clip, mjcf, gif, mp4, gif_every=1, skin=skin_ink(d, run))
