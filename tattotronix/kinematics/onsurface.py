"""Where the arm can tattoo on a curved surface (issue 33): at each point of a grid over
the surface (the phantom: :func:`cone_reach`), or of a sample of a mesh's vertices (a scan:
:func:`mesh_reach`), can the needle reach it at the marking depth along the inward
normal, with what tilt error and conditioning.

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
from tattotronix.surface.mesh import vertex_normals

__all__ = ["PointsReach", "Reach", "SurfaceReach", "angle_deg", "cone_reach", "mesh_reach"]


def _serpentine(rows: int, cols: int) -> NDArray[np.int64]:
    """Indices of a ``rows x cols`` grid (row-major) in serpentine order."""
    idx = np.arange(rows * cols).reshape(rows, cols)
    idx[1::2] = idx[1::2, ::-1]
    return idx.ravel()

Array = NDArray[np.float64]
#: rounds of solving unreached points from a reached neighbour's pose
_GROW_ROUNDS = 50
#: the most vertices a mesh's map tests (its sampling and path are quadratic in them)
MAX_MESH_POINTS = 4000


def angle_deg(a: Array, b: Array) -> Array:
    """(N,) angles between unit vectors ``a`` (N, 3) and ``b`` ((N, 3) or (3,)), degrees:
    a needle's tilt from the inward normal, or its angle from straight down."""
    dot = np.sum(np.asarray(a) * np.asarray(b), axis=-1)
    return np.asarray(np.degrees(np.arccos(np.clip(dot, -1.0, 1.0))), dtype=np.float64)


@dataclass(frozen=True, kw_only=True)
class Reach:
    """What a reachability map found at its points.

    Attributes:
        xyz_m: the needle tip at the marking depth at each point, arm frame, m.
        reachable: IK converged with the needle along the inward normal.
        tilt_deg: angle from the reached needle axis to the inward normal (NaN where
            unreachable).
        cond: the task Jacobian's condition number there (NaN where unreachable).
        from_vertical_deg: the needle's angle from vertical (pointing down).
    """

    xyz_m: Array
    reachable: NDArray[np.bool_]
    tilt_deg: Array
    cond: Array
    from_vertical_deg: Array

    def summary(self) -> JsonDict:
        """Metrics: the reachable share, the worst tilt error and condition number where
        reached, and the steepest needle reached."""
        return _summary(self.reachable, self.tilt_deg, self.cond, self.from_vertical_deg)


@dataclass(frozen=True, kw_only=True)
class SurfaceReach(Reach):
    """Reachability over a grid on the phantom: every array (nx, nt[, 3]), rows along the
    limb, columns around it.

    Attributes:
        along_mm: (nx,) grid position along the limb's axis, mm.
        around_deg: (nt,) grid angle around it (90: the top), degrees.
    """

    along_mm: Array
    around_deg: Array


@dataclass(frozen=True, kw_only=True)
class PointsReach(Reach):
    """Reachability at scattered points of a surface (a sample of a mesh's vertices):
    every array (N[, 3]).

    Attributes:
        normal: (N, 3) the surface's outward unit normal at each point.
    """

    normal: Array


def _summary(ok: NDArray[np.bool_], tilt: Array, cond: Array, vertical: Array) -> JsonDict:
    return {
        "points": int(ok.size),
        "reachable_pct": round(100.0 * float(ok.mean()), 2),
        "tilt_worst_deg": round(float(np.nanmax(tilt)), 4) if ok.any() else None,
        "cond_worst": round(float(np.nanmax(cond)), 2) if ok.any() else None,
        "steepest_reached_deg": round(float(vertical[ok].max()), 2) if ok.any() else None,
    }


def _grow(chain: Chain, tip: Array, normal: Array, q: Array, converged: NDArray[np.bool_],
          nbrs: NDArray[np.int64], ik: IkOptions) -> None:
    """Solve each unreached point alone from a reached neighbour's pose (``nbrs``: (N, k)
    each point's neighbours, -1 for none), round after round while the reached set grows;
    ``q`` and ``converged`` are updated in place (the first neighbour's solution that
    converged is kept)."""
    tried: set[tuple[int, int]] = set()  # (point, neighbour) pairs already solved
    for _ in range(_GROW_ROUNDS):
        pairs = [(int(a), int(b)) for a in np.flatnonzero(~converged) for b in nbrs[a]
                 if b >= 0 and converged[b]]
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


def _quality(chain: Chain, q: Array, converged: NDArray[np.bool_], normal: Array
             ) -> tuple[Array, Array, Array]:
    """(N,) the tilt error and the condition number where reached (NaN elsewhere), and
    the needle's angle from vertical everywhere."""
    tilt = np.full(len(q), np.nan)
    cond = np.full(len(q), np.nan)
    if converged.any():
        _, z = chain.fk(q[converged])
        tilt[converged] = angle_deg(z, -normal[converged])
        cond[converged] = conditioning(chain, q[converged]).cond
    return tilt, cond, angle_deg(-normal, np.array([0.0, 0.0, -1.0]))


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
    i, j = np.divmod(np.arange(n_along * n_around), n_around)
    nbrs = np.column_stack([np.where(i > 0, (i - 1) * n_around + j, -1),
                            np.where(i < n_along - 1, (i + 1) * n_around + j, -1),
                            i * n_around + (j - 1) % n_around,
                            i * n_around + (j + 1) % n_around])
    _grow(chain, tip, normal, q, converged, nbrs, ik)
    tilt, cond, vertical = _quality(chain, q, converged, normal)

    def grid(a: NDArray[np.generic]) -> NDArray[np.generic]:
        return a.reshape(n_along, n_around, *a.shape[1:])

    return SurfaceReach(along_mm=along, around_deg=around,
                        xyz_m=grid(tip / 1000.0).astype(np.float64),
                        reachable=grid(converged).astype(bool),
                        tilt_deg=grid(tilt).astype(np.float64),
                        cond=grid(cond).astype(np.float64),
                        from_vertical_deg=grid(vertical).astype(np.float64))


def mesh_reach(chain: Chain, vertices_mm: Array, faces: NDArray[np.int64], depth_mm: float,
               ik: IkOptions, seed: ArrayLike, *, points: int = 828,
               neighbours: int = 6) -> PointsReach:
    """Reachability over a mesh (a scan): at ``points`` of its vertices spread evenly over
    it (farthest-point sampling, from the vertex nearest the arm's base), the needle
    ``depth_mm`` in along the smoothed vertex normal.

    The points are swept as one path (each next the nearest not yet visited), then each
    point missed is solved alone from a reached neighbour's pose (its ``neighbours``
    nearest), as on the phantom's grid.

    Args:
        chain: the kinematics.
        vertices_mm, faces: the mesh, posed in the arm's frame (mm), wound outward.
        depth_mm: the marking depth.
        ik: the IK settings (its needle axis is replaced by each point's inward normal).
        seed: the joint angles the sweep starts from, rad.
        points: how many vertices to test (all of them when the mesh has fewer; at
            most :data:`MAX_MESH_POINTS`).

    Raises:
        TattotronixError: fewer than 4 points asked.
    """
    from scipy.spatial import cKDTree

    if points < 4:
        raise TattotronixError(f"the reachability map needs at least 4 points, got {points}")
    v = np.asarray(vertices_mm, dtype=np.float64)
    normals = vertex_normals(v, np.asarray(faces, dtype=np.int64))
    pick = _farthest_points(v, min(points, len(v), MAX_MESH_POINTS))
    normal = normals[pick]
    tip = v[pick] - depth_mm * normal
    # one path through them, nearest next: warm starts from a neighbour
    pts = v[pick]
    order = [0]
    left = np.ones(len(pick), bool)
    left[0] = False
    for _ in range(len(pick) - 1):
        d = np.linalg.norm(pts - pts[order[-1]], axis=1)
        d[~left] = np.inf
        order.append(int(np.argmin(d)))
        left[order[-1]] = False
    path = np.array(order, dtype=np.int64)
    opts: IkOptions = {**ik, "needle_axis": -normal[path]}
    res = solve_path(chain, tip[path] / 1000.0, seed=seed, **opts)
    q = np.full((len(pick), chain.n), np.nan)
    converged = np.zeros(len(pick), bool)
    q[path[res.converged]] = res.q[res.converged]
    converged[path[res.converged]] = True
    k = min(neighbours + 1, len(pick))
    _, nbrs = cKDTree(pts).query(pts, k=k)
    _grow(chain, tip, normal, q, converged, np.asarray(nbrs, dtype=np.int64)[:, 1:], ik)
    tilt, cond, vertical = _quality(chain, q, converged, normal)
    return PointsReach(xyz_m=tip / 1000.0, normal=normal, reachable=converged,
                       tilt_deg=tilt, cond=cond, from_vertical_deg=vertical)


def _farthest_points(v: Array, n: int) -> NDArray[np.int64]:
    """``n`` vertex indices spread over ``v``: each the farthest from those before it,
    from the vertex nearest the origin (the arm's base)."""
    pick = [int(np.argmin(np.linalg.norm(v, axis=1)))]
    dist = np.linalg.norm(v - v[pick[0]], axis=1)
    for _ in range(n - 1):
        pick.append(int(np.argmax(dist)))
        np.minimum(dist, np.linalg.norm(v - v[pick[-1]], axis=1), out=dist)
    return np.array(pick, dtype=np.int64)
