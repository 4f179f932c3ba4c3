"""Any triangle mesh from a file (a 3-D scan of a limb), checked, and its chart: a
least-squares conformal map of the patch around the placement.

:func:`load_mesh` reads an STL, PLY or OBJ with trimesh, scales it to millimetres and poses
it on the bench, and refuses in one line a mesh the planner cannot trust: unreadable,
empty, open (a limb is a closed surface), non-manifold, degenerate, or huge.

:class:`MeshChart` lays a design on it around a placement point: the patch of the surface
within a geodesic radius of the point (libigl's heat-method distances) is flattened by a
least-squares conformal map (libigl's LSCM), scaled to the patch's own area, and turned so
that the design's ``u`` runs along a reference direction (the limb's axis) projected onto
the surface there; ``u``, ``v`` and the outward normal are right-handed, as on the panel.
A design point is carried through the flattened triangle it falls in; its normal is the
surface's vertex normals, smoothed, interpolated there.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import sparse
from scipy.spatial import cKDTree

from tattotronix.errors import TattotronixError
from tattotronix.surface.chart import Chart, SurfacePoints

__all__ = ["MAX_FACES", "MAX_SIZE_MM", "MeshChart", "load_mesh", "vertex_normals"]

Array = NDArray[np.float64]
Faces = NDArray[np.int64]

#: the most faces a mesh may have (a limb scan decimated for planning has far fewer)
MAX_FACES = 1_000_000
#: the largest extent a mesh may have after its units, mm (the arm reaches ~0.3 m)
MAX_SIZE_MM = 1000.0
#: the share of zero-area faces a mesh may have (dropped); more is a broken mesh
MAX_DEGENERATE_SHARE = 0.01
#: passes of neighbour averaging that smooth the vertex normals
NORMAL_SMOOTHING = 3


def load_mesh(path: str | Path, unit_mm: float = 1.0, pose: ArrayLike | None = None
              ) -> tuple[Array, Faces]:
    """A closed triangle mesh's vertices (mm, posed on the bench) and faces (wound
    outward; zero-area faces dropped).

    Args:
        path: an STL, PLY or OBJ file.
        unit_mm: millimetres per file unit (10 for centimetres, 1000 for metres).
        pose: 4x4 transform (mm) from the file's frame (after ``unit_mm``) to the bench's.

    Raises:
        TattotronixError: unreadable, empty, open, non-manifold, degenerate or huge, in
            one line naming the file and what to do.
    """
    import trimesh

    file = Path(path)
    if not file.is_file():
        raise TattotronixError(f"mesh {file}: no such file")
    try:
        mesh = trimesh.load_mesh(file, process=True)
    except Exception as exc:  # trimesh raises whatever its loaders raise
        raise TattotronixError(f"mesh {file}: unreadable ({type(exc).__name__}: "
                               f"{str(exc).splitlines()[0] if str(exc) else 'no detail'})"
                               ) from None
    if isinstance(mesh, trimesh.Scene):
        mesh = mesh.dump(concatenate=True) if mesh.geometry else None
    if mesh is None or not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
        raise TattotronixError(f"mesh {file}: no triangles in it")
    if len(mesh.faces) > MAX_FACES:
        raise TattotronixError(f"mesh {file}: {len(mesh.faces)} faces, over {MAX_FACES}: "
                               "decimate it (e.g. MeshLab's quadric edge collapse)")
    if not (math.isfinite(unit_mm) and unit_mm > 0):
        raise TattotronixError(f"mesh units: {unit_mm} mm per file unit is not a positive "
                               "number")
    v = np.asarray(mesh.vertices, dtype=np.float64) * unit_mm
    if not np.isfinite(v).all():
        raise TattotronixError(f"mesh {file}: a vertex is not a finite number")
    size = float((v.max(axis=0) - v.min(axis=0)).max())
    if size > MAX_SIZE_MM:
        raise TattotronixError(
            f"mesh {file}: {size:.0f} mm across at {unit_mm:g} mm per unit, over "
            f"{MAX_SIZE_MM:g} mm: check its units (a scan in metres needs unit_mm=1000, "
            "in millimetres 1)")
    f = np.asarray(mesh.faces, dtype=np.int64)
    area = 0.5 * np.linalg.norm(np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]),
                                axis=1)
    flat = area <= 1e-9 * max(size, 1.0) ** 2
    if flat.mean() > MAX_DEGENERATE_SHARE:
        raise TattotronixError(
            f"mesh {file}: {int(flat.sum())} of {len(f)} faces have no area (degenerate): "
            "repair it (e.g. MeshLab's remove zero-area faces and duplicates)")
    edges = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    if (counts > 2).any():
        raise TattotronixError(
            f"mesh {file}: {int((counts > 2).sum())} edges are shared by more than two "
            "faces (non-manifold): repair it (e.g. MeshLab's non-manifold edge repair)")
    if (counts == 1).any():
        raise TattotronixError(
            f"mesh {file}: it is open ({int((counts == 1).sum())} edges on a hole's rim): "
            "a limb is a closed surface; close the scan (fill its holes) first")
    if pose is not None:
        t = np.asarray(pose, dtype=np.float64)
        if t.shape != (4, 4) or not np.allclose(t[:3, :3] @ t[:3, :3].T, np.eye(3),
                                                atol=1e-9):
            raise TattotronixError("the mesh's pose must be a 4x4 rigid transform")
        v = v @ t[:3, :3].T + t[:3, 3]
    # one winding, outward: a scan's faces may be wound either way
    fixed = trimesh.Trimesh(v, f[~flat], process=False)
    fixed.fix_normals()
    return np.asarray(fixed.vertices, dtype=np.float64), np.asarray(fixed.faces, np.int64)


def vertex_normals(v: Array, f: Faces) -> Array:
    """Area-weighted vertex normals of an outward-wound mesh, smoothed by
    :data:`NORMAL_SMOOTHING` passes of averaging over each vertex's neighbours."""
    fn = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])  # 2 area x normal
    n = np.zeros_like(v)
    for k in range(3):
        np.add.at(n, f[:, k], fn)
    rows = np.concatenate([f[:, 0], f[:, 1], f[:, 2], f[:, 1], f[:, 2], f[:, 0]])
    cols = np.concatenate([f[:, 1], f[:, 2], f[:, 0], f[:, 0], f[:, 1], f[:, 2]])
    adj = sparse.csr_matrix((np.ones(len(rows)), (rows, cols)), shape=(len(v), len(v)))
    adj.data[:] = 1.0
    adj = adj + sparse.identity(len(v), format="csr")
    for _ in range(NORMAL_SMOOTHING):
        n = n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
        n = adj @ n
    return np.asarray(n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300))


def _closest(v: Array, f: Faces, p: Array) -> tuple[int, Array, Array]:
    """The face nearest ``p``, the nearest point on it, and its barycentric coordinates
    (among the faces around the vertices nearest ``p``)."""
    import trimesh

    _, near = cKDTree(v).query(p, k=min(16, len(v)))
    cand = np.flatnonzero(np.isin(f, np.atleast_1d(near)).any(axis=1))
    pts = trimesh.triangles.closest_point(v[f[cand]], np.repeat(p[None, :], len(cand), 0))
    best = int(np.argmin(np.linalg.norm(pts - p, axis=1)))
    face = int(cand[best])
    bary = trimesh.triangles.points_to_barycentric(v[f[face]][None], pts[best][None])[0]
    return face, pts[best], np.asarray(bary, dtype=np.float64)


def _outward(v: Array, f: Faces) -> Faces:
    """The faces wound so their normals point out of the closed mesh (positive volume)."""
    vol = np.einsum("ij,ij->i", v[f[:, 0]], np.cross(v[f[:, 1]], v[f[:, 2]])).sum()
    return f if vol >= 0 else f[:, ::-1].copy()


class MeshChart(Chart):
    """A design's chart on a closed mesh: the LSCM of the patch around the placement."""

    def __init__(self, vertices: Array, faces: Faces, at_mm: ArrayLike, radius_mm: float,
                 reference: ArrayLike = (1.0, 0.0, 0.0), rotate_deg: float = 0.0):
        """Lay a design within ``radius_mm`` of the surface point nearest ``at_mm``.

        Args:
            vertices, faces: the mesh (:func:`load_mesh`).
            at_mm: the placement, near the surface (the nearest surface point is taken).
            radius_mm: the patch's geodesic radius: at least the design's half diagonal.
            reference: the direction the design's ``u`` follows (the limb's axis).
            rotate_deg: the design's turn from there, counter-clockwise seen from outside.

        Raises:
            TattotronixError: a patch that is not a disk (the radius wraps around the
                limb), or a reference direction along the surface's normal.
        """
        import igl

        v = np.asarray(vertices, dtype=np.float64)
        f = _outward(v, np.asarray(faces, dtype=np.int64))
        face, p, bary = _closest(v, f, np.asarray(at_mm, dtype=np.float64))
        seed = int(f[face][int(np.argmax(bary))])
        dist = _heat_distance(v, f, seed)
        inside = dist <= radius_mm
        pf = f[inside[f].all(axis=1)]
        pf = _component_with(pf, face_vertex=seed)
        if len(pf) == 0 or not inside[f[face]].all():
            raise TattotronixError(f"the patch of {radius_mm:g} mm around the placement "
                                   "holds no whole face: give a larger radius")
        used = np.unique(pf)
        index = np.full(len(v), -1, np.int64)
        index[used] = np.arange(len(used))
        pv, pf2 = v[used], index[pf]
        loops = _boundary_loops(pf2)
        euler = len(pv) - len(_edges(pf2)) + len(pf2)
        if len(loops) != 1 or euler != 1:
            raise TattotronixError(
                f"the surface within {radius_mm:g} mm of the placement is not a disk (it "
                "wraps around the limb, or has a handle): make the design smaller or "
                "place it where the limb is wider")
        loop = np.asarray(loops[0], dtype=np.int64)
        far = _farthest_pair(pv[loop])
        b = loop[list(far)]
        uv, _ = igl.lscm(pv, pf2, b, np.array([[0.0, 0.0], [1.0, 0.0]]))
        uv = np.asarray(uv, dtype=np.float64)
        # scale to the patch's own area, and wind as the surface is (seen from outside)
        a3 = 0.5 * np.linalg.norm(np.cross(pv[pf2[:, 1]] - pv[pf2[:, 0]],
                                           pv[pf2[:, 2]] - pv[pf2[:, 0]]), axis=1).sum()
        e1, e2 = uv[pf2[:, 1]] - uv[pf2[:, 0]], uv[pf2[:, 2]] - uv[pf2[:, 0]]
        a2 = 0.5 * (e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]).sum()
        if a2 < 0:
            uv[:, 1] = -uv[:, 1]
        uv *= math.sqrt(a3 / abs(a2))
        # the placement at the origin; u along the reference direction there
        tri = index[f[face]]
        origin = bary @ uv[tri]
        normal = np.cross(pv[tri[1]] - pv[tri[0]], pv[tri[2]] - pv[tri[0]])
        normal /= np.linalg.norm(normal)
        ref = np.asarray(reference, dtype=np.float64)
        ref_t = ref - normal * float(ref @ normal)
        if float(np.linalg.norm(ref_t)) < 1e-6 * max(float(np.linalg.norm(ref)), 1e-300):
            raise TattotronixError("the design's reference direction is along the surface's "
                                   "normal at the placement: give one along the limb")
        d3 = np.column_stack([pv[tri[1]] - pv[tri[0]], pv[tri[2]] - pv[tri[0]]])
        d2 = np.column_stack([uv[tri[1]] - uv[tri[0]], uv[tri[2]] - uv[tri[0]]])
        coef, *_ = np.linalg.lstsq(d3, ref_t, rcond=None)  # ref_t in the face's edges
        ref2 = d2 @ coef
        angle = math.atan2(ref2[1], ref2[0]) + math.radians(rotate_deg)
        c, s = math.cos(-angle), math.sin(-angle)
        turn = np.array([[c, -s], [s, c]])
        self.uv = (uv - origin) @ turn.T  # the design's coordinates of each vertex, mm
        self.vertices, self.faces = pv, pf2
        self.normals = vertex_normals(pv, pf2)
        self.placement = p
        self._centroids = cKDTree(self.uv[pf2].mean(axis=1))

    def to_surface(self, uv_mm: Array) -> SurfacePoints:
        q = np.asarray(uv_mm, dtype=np.float64).reshape(-1, 2)
        face, bary = self._locate(q)
        missing = face < 0
        if missing.any():
            i = int(np.flatnonzero(missing)[0])
            raise TattotronixError(
                f"design point {q[i].round(1).tolist()} mm is past the patch the design "
                "was laid on (the mesh ends, or wraps, within the design's reach of the "
                "placement): move it away from the edge (surface.mesh_at_mm), or make the "
                "design smaller")
        tri = self.faces[face]
        xyz = np.einsum("ij,ijk->ik", bary, self.vertices[tri])
        n = np.einsum("ij,ijk->ik", bary, self.normals[tri])
        return SurfacePoints(xyz, n / np.linalg.norm(n, axis=1, keepdims=True))

    def _locate(self, q: Array, k: int = 12) -> tuple[NDArray[np.int64], Array]:
        """The flattened face each point falls in (-1: none) and its barycentric
        coordinates there: among the faces of the ``k`` centroids nearest it, else (a
        long face whose centroid is farther than its small neighbours') among all."""
        k = min(k, len(self.faces))
        _, cand = self._centroids.query(q, k=k)
        cand = np.asarray(cand).reshape(len(q), k)
        face = np.full(len(q), -1, np.int64)
        bary = np.zeros((len(q), 3))
        for j in range(k):
            todo = face < 0
            if not todo.any():
                break
            c = cand[todo, j]
            tri = self.uv[self.faces[c]]  # (m, 3, 2)
            w = _barycentric(tri, q[todo])
            hit = (w >= -1e-9).all(axis=1)
            idx = np.flatnonzero(todo)[hit]
            face[idx] = c[hit]
            bary[idx] = w[hit]
        if (face < 0).any():
            tri = self.uv[self.faces]
            for i in np.flatnonzero(face < 0):
                w = _barycentric(tri, np.broadcast_to(q[i], (len(tri), 2)))
                inside = np.flatnonzero((w >= -1e-9).all(axis=1))
                if len(inside):
                    face[i], bary[i] = inside[0], w[inside[0]]
        return face, bary


def _barycentric(tri: Array, p: Array) -> Array:
    """(m, 3) barycentric coordinates of 2-D points ``p`` in triangles ``tri`` (m, 3, 2)."""
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    v0, v1, v2 = b - a, c - a, p - a
    den = v0[:, 0] * v1[:, 1] - v1[:, 0] * v0[:, 1]
    den = np.where(np.abs(den) < 1e-300, 1e-300, den)
    l1 = (v2[:, 0] * v1[:, 1] - v1[:, 0] * v2[:, 1]) / den
    l2 = (v0[:, 0] * v2[:, 1] - v2[:, 0] * v0[:, 1]) / den
    return np.column_stack([1.0 - l1 - l2, l1, l2])


def _heat_distance(v: Array, f: Faces, seed: int) -> Array:
    """Geodesic distances from vertex ``seed`` (libigl's heat method), mm."""
    import igl

    data = igl.HeatGeodesicsData()
    igl.heat_geodesics_precompute(v, f, data)
    return np.asarray(igl.heat_geodesics_solve(data, np.array([seed], dtype=np.int64)),
                      dtype=np.float64)


def _edges(f: Faces) -> Faces:
    e = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
    return np.asarray(np.unique(e, axis=0), dtype=np.int64)


def _boundary_loops(f: Faces) -> list[list[int]]:
    import igl

    return [list(map(int, loop)) for loop in igl.boundary_loop_all(f)]


def _component_with(f: Faces, face_vertex: int) -> Faces:
    """The faces of ``f`` edge-connected to one holding vertex ``face_vertex``."""
    if len(f) == 0:
        return f
    from scipy.sparse.csgraph import connected_components

    e = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    key = np.sort(e, axis=1)
    owner = np.tile(np.arange(len(f)), 3)
    order = np.lexsort((key[:, 1], key[:, 0]))
    ks, os_ = key[order], owner[order]
    same = (ks[1:] == ks[:-1]).all(axis=1)
    a, b = os_[:-1][same], os_[1:][same]
    g = sparse.coo_matrix((np.ones(len(a)), (a, b)), shape=(len(f), len(f)))
    _, label = connected_components(g, directed=False)
    with_seed = np.flatnonzero((f == face_vertex).any(axis=1))
    if len(with_seed) == 0:
        return f[:0]
    return f[label == label[with_seed[0]]]


def _farthest_pair(p: Array) -> tuple[int, int]:
    """Two points of ``p`` far apart (the farthest from the first, and from it)."""
    i = int(np.argmax(np.linalg.norm(p - p[0], axis=1)))
    j = int(np.argmax(np.linalg.norm(p - p[i], axis=1)))
    return i, j
