"""Where the arm can tattoo on a curved surface (issue 33): at each point of a grid over
the surface, can the needle reach it at the marking depth along the inward normal, with
what tilt error and conditioning.

The grid is swept as one path (a serpentine: section by section, back and forth around
the limb), so :func:`~tattotronix.kinematics.ik.solve_path` warm-starts each point from
its neighbour and re-solves across branch jumps; the points it missed are swept again in
the other direction (angle by angle along the limb); a point neither converges on is out
of reach, unless it converges when solved alone from a reached neighbour's pose (round
after round, while the reached set grows: :func:`~tattotronix.kinematics.ik.
solve_points`). The tilt error is the angle between the reached needle axis and the
inward normal; the conditioning is the task Jacobian's (:func:`~tattotronix.kinematics.
ik.conditioning`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from tattotronix.errors import TattotronixError
from tattotronix.io.jsontypes import JsonDict
from tattotronix.kinematics.chain import Chain
from tattotronix.kinematics.ik import (
    DLS_LAMBDA,
    MAX_ITER,
    TOL,
    IkOptions,
    conditioning,
    solve_path,
    solve_points,
)
from tattotronix.surface.cone import EllipticCone

__all__ = ["SurfaceReach", "angle_deg", "cone_reach"]


def _serpentine(rows: int, cols: int) -> NDArray[np.int64]:
    """Indices of a ``rows x cols`` grid (row-major) in serpentine order."""
    idx = np.arange(rows * cols).reshape(rows, cols)
    idx[1::2] = idx[1::2, ::-1]
    return idx.ravel()

Array = NDArray[np.float64]
#: rounds of solving unreached points from a reached neighbour's pose
_GROW_ROUNDS = 50


def angle_deg(a: Array, b: Array) -> Array:
    """(N,) angles between unit vectors ``a`` (N, 3) and ``b`` ((N, 3) or (3,)), degrees:
    a needle's tilt from the inward normal, or its angle from straight down."""
    dot = np.sum(np.asarray(a) * np.asarray(b), axis=-1)
    return np.asarray(np.degrees(np.arccos(np.clip(dot, -1.0, 1.0))), dtype=np.float64)


@dataclass(frozen=True)
class SurfaceReach:
    """Reachability over a grid on a surface (rows along the limb, columns around it).

    Attributes:
        along_mm: (nx,) grid position along the limb's axis, mm.
        around_deg: (nt,) grid angle around it (90: the top), degrees.
        xyz_m: (nx, nt, 3) the needle tip at the marking depth, arm frame, m.
        reachable: (nx, nt) IK converged with the needle along the inward normal.
        tilt_deg: (nx, nt) angle from the reached needle axis to the inward normal (NaN
            where unreachable).
        cond: (nx, nt) the task Jacobian's condition number there (NaN where unreachable).
        from_vertical_deg: (nx, nt) the needle's angle from vertical (pointing down).
    """

    along_mm: Array
    around_deg: Array
    xyz_m: Array
    reachable: NDArray[np.bool_]
    tilt_deg: Array
    cond: Array
    from_vertical_deg: Array

    def summary(self) -> JsonDict:
        """Metrics: the reachable share, the worst tilt error and condition number where
        reached, and the steepest needle reached."""
        ok = self.reachable
        return {
            "points": int(ok.size),
            "reachable_pct": round(100.0 * float(ok.mean()), 2),
            "tilt_worst_deg": round(float(np.nanmax(self.tilt_deg)), 4) if ok.any() else None,
            "cond_worst": round(float(np.nanmax(self.cond)), 2) if ok.any() else None,
            "steepest_reached_deg": round(float(self.from_vertical_deg[ok].max()), 2)
            if ok.any() else None,
        }


def cone_reach(chain: Chain, cone: EllipticCone, depth_mm: float, ik: IkOptions,
               seed: ArrayLike, *, n_along: int = 23, n_around: int = 36,
               margin_mm: float = 10.0) -> SurfaceReach:
    """Reachability over the phantom: ``n_along`` sections from ``margin_mm`` inside each
    end, ``n_around`` points each, the needle ``depth_mm`` in along the normal.

    Args:
        chain: the kinematics.
        cone: the phantom, posed in the arm's frame (mm).
        depth_mm: the marking depth.
        ik: the IK settings (:func:`~tattotronix.kinematics.ik_options`; its needle axis
            is replaced by each point's inward normal).
        seed: the joint angles the sweep starts from, rad.

    Raises:
        TattotronixError: a grid smaller than 2 x 4, or margins that leave no length.
    """
    if n_along < 2 or n_around < 4:
        raise TattotronixError(f"the reachability grid must be at least 2 x 4, got "
                               f"{n_along} x {n_around}")
    if not 0 <= margin_mm < cone.length_mm / 2:
        raise TattotronixError(f"margin_mm={margin_mm} leaves none of the phantom's "
                               f"{cone.length_mm:g} mm")
    along = np.linspace(margin_mm, cone.length_mm - margin_mm, n_along)
    around = np.linspace(0.0, 360.0, n_around, endpoint=False)
    xg, tg = np.meshgrid(along, np.radians(around), indexing="ij")
    x, t = xg.ravel(), tg.ravel()
    normal = cone.posed(cone.normal(x, t), vectors=True)
    tip = cone.posed(cone.point(x, t)) - depth_mm * normal
    opts: IkOptions = {**ik}
    q = np.full((len(x), chain.n), np.nan)
    converged = np.zeros(len(x), bool)
    # two serpentine sweeps, around the limb section by section and along it angle by
    # angle: a warm start that jumps branch in one is a neighbour's in the other
    by_angle = _serpentine(n_around, n_along)  # (angle, along) row-major: as ours
    for order in (_serpentine(n_along, n_around),
                  (by_angle % n_along) * n_around + by_angle // n_along):
        todo = order[~converged[order]]
        if not len(todo):
            break
        opts["needle_axis"] = -normal[todo]  # the inward normal at each point
        res = solve_path(chain, tip[todo] / 1000.0, seed=seed, **opts)
        q[todo[res.converged]] = res.q[res.converged]
        converged[todo[res.converged]] = True
    # the sweeps' warm starts can leave a point a neighbour reached: each such point is
    # solved alone from that neighbour's pose, round after round while the set grows
    grid_ok = converged.reshape(n_along, n_around)
    tried: set[tuple[int, int]] = set()  # (point, neighbour) pairs already solved
    for _ in range(_GROW_ROUNDS):
        pairs = [(i * n_around + j, a * n_around + b)
                 for i, j in zip(*np.nonzero(~grid_ok), strict=True)
                 for a, b in ((i - 1, j), (i + 1, j), (i, (j - 1) % n_around),
                              (i, (j + 1) % n_around))
                 if 0 <= a < n_along and grid_ok[a, b]]
        pairs = [pr for pr in pairs if pr not in tried]
        if not pairs:
            break
        tried.update(pairs)
        k, src = (np.array(v, dtype=np.int64) for v in zip(*pairs, strict=True))
        qk, ok = solve_points(chain, tip[k] / 1000.0, q[src], needle_axis=-normal[k],
                              dls_lambda=float(ik.get("dls_lambda", DLS_LAMBDA)),
                              max_iter=int(ik.get("max_iter", MAX_ITER)),
                              tol=float(ik.get("tol", TOL)))
        for kk, qq in zip(k[ok], qk[ok], strict=True):
            if not converged[kk]:  # the first neighbour's solution that converged
                q[kk], converged[kk] = qq, True
    tilt = np.full(len(x), np.nan)
    cond = np.full(len(x), np.nan)
    if converged.any():
        _, z = chain.fk(q[converged])
        tilt[converged] = angle_deg(z, -normal[converged])
        cond[converged] = conditioning(chain, q[converged]).cond
    vertical = angle_deg(-normal, np.array([0.0, 0.0, -1.0]))

    def grid(a: NDArray[np.generic]) -> NDArray[np.generic]:
        return a.reshape(n_along, n_around, *a.shape[1:])

    return SurfaceReach(along, around, grid(tip / 1000.0).astype(np.float64),
                        grid(converged).astype(bool), grid(tilt).astype(np.float64),
                        grid(cond).astype(np.float64), grid(vertical).astype(np.float64))
