"""The figure of a drawing on a curved surface: where the arm can tattoo on the phantom,
with the design laid on it (issue 33)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from tattotronix.app.onskin import SkinDrawing
from tattotronix.kinematics.onsurface import SurfaceReach
from tattotronix.path.kinds import MARK
from tattotronix.plotting import pyplot

__all__ = ["surface_figure"]


def surface_figure(d: SkinDrawing, reach: SurfaceReach | None, path: Path, title: str) -> None:
    """Left: the reachability map over the phantom, unrolled (along its axis, around it),
    coloured by the task Jacobian's condition number where the needle reaches along the
    normal, grey where it does not, with the design's marking points on it. Right: the
    limb and the design's needle path on it, seen from the side of the arm's base."""
    plt = pyplot()
    fig = plt.figure(figsize=(12.0, 5.2))
    mark = d.skin.kind == MARK
    xyz = d.skin.xyz_mm
    ax = fig.add_subplot(1, 2, 1)
    cone = d.surface.cone
    if reach is not None and cone is not None:
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
