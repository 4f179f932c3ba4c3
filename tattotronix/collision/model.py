"""The collision model: Pinocchio's GeometryModel with coal shapes, from the description.

* **Links**: the convex hull of each CAD mesh when ``robot.cad_dir`` is set, otherwise the
  committed k-DOP polytope (:mod:`~tattotronix.collision.shapes`); a link missing from the
  k-DOP table falls back to its ``robot.box``.
* **The pen** is two shapes: the barrel (a cylinder from ``tool0`` over
  ``robot.pen.barrel_length``) and the needle (the cone from the barrel to the tip).
* **Environment**: the bench (a solid box under z = 0) and the panel. The needle may enter
  the panel: that one geometry pair is not checked, and the tip's depth below the panel
  surface is checked against ``toolpath.plunge_mm`` instead (:meth:`needle_depth_m`).
  The barrel and every link may not. For a drawing on a curved surface (issue 33) the
  limb lies on the bench in the panel's place: the convex hull of its mesh (exact for
  the phantom, which is convex; a scan's hull is larger than the scan, so the check errs
  safe), which the needle alone may enter (its depth is the path's, set along the
  surface's normal: :func:`~tattotronix.path.onskin.carry_path`).
* **Pairs**: the checked body pairs of :func:`~tattotronix.collision.pairs.body_pairs`; a
  body pair's clearance is the least distance over its geometry pairs (negative: depth of
  penetration, from coal's GJK/EPA on convex shapes).
* **Motion bounds** (:meth:`motion_bound_m`): how far any point of a body can move between
  two poses on the straight joint-space line, ``sum_j |dq_j| R_jb`` with ``R_jb`` the
  body's reach from joint ``j``'s origin. The trajectory check uses them to prove the
  motion between samples free (:mod:`~tattotronix.collision.check`).

Units: m and rad inside; reports say mm where their keys do.
"""

from __future__ import annotations

import time
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from tattotronix.collision.pairs import ENVIRONMENT, LIMB, ON_SKIN, BodyPair, body_pairs
from tattotronix.collision.shapes import kdop_vertices, load_kdops, mesh_vertices
from tattotronix.errors import TattotronixError
from tattotronix.io.jsontypes import JsonDict
from tattotronix.robot.description import PEN_LINK, RobotDescription
from tattotronix.robot.loaders import pinocchio_model
from tattotronix.robot.urdf import to_urdf

__all__ = ["NEEDLE", "CollisionModel", "PoseReport", "parse_pose"]

Array = NDArray[np.float64]
#: the name of the pen's needle shape (the only one allowed into the panel)
NEEDLE = f"{PEN_LINK}/needle"


def _convex(points: Array) -> Any:
    import coal

    vec = coal.StdVec_Vec3s()
    for p in np.asarray(points, dtype=np.float64):
        vec.append(p)
    return coal.Convex.convexHull(vec, False, "Qt")


def parse_pose(pose: Iterable[float], desc: RobotDescription) -> Array:
    """A pose from the command line (``pose=[q1,...,q5]``, rad).

    Raises:
        TattotronixError: not one finite number per joint.
    """
    n = len(desc.joints)
    try:
        q = np.asarray(list(pose), dtype=np.float64)
    except (TypeError, ValueError):
        raise TattotronixError(f"pose={pose!r}: give {n} joint angles in rad, e.g. "
                               f"pose=[{','.join(['0'] * n)}]") from None
    if q.shape != (n,) or not np.all(np.isfinite(q)):
        raise TattotronixError(f"pose={list(pose)}: give {n} finite joint angles in rad "
                               f"({', '.join(desc.joint_names)})")
    return q


@dataclass(frozen=True)
class PoseReport:
    """The clearance of one pose (what ``stages/collision.py pose=[...]`` prints).

    Attributes:
        pose: joint angles, rad.
        clearance_m: checked body pair name -> clearance, m (negative: penetration).
        collisions: the pairs with clearance <= 0.
        min_clearance_m: the least clearance.
        worst_pair: the pair with it.
        needle_depth_m: how deep the tip is below the panel surface (<= 0: above it;
            ``-inf`` when it is not over the panel, ``null`` in JSON).
        within_limits: every joint inside its limits.
    """

    pose: Array
    clearance_m: dict[str, float]
    collisions: list[list[str]]
    min_clearance_m: float
    worst_pair: list[str]
    needle_depth_m: float
    within_limits: bool

    def to_json(self, margin_m: float, geometry: str) -> JsonDict:
        """The object ``collision.py pose=[...]`` prints, an interface other tools rely on
        (README, "Collision safety and planned travel"): ``collisions``,
        ``min_clearance_mm``, ``worst_pair``, and the rest of the report."""
        return {
            "collisions": self.collisions,
            "min_clearance_mm": round(self.min_clearance_m * 1000, 4),
            "worst_pair": self.worst_pair,
            "pose": [float(v) for v in self.pose],
            "within_limits": self.within_limits,
            "margin_mm": margin_m * 1000,
            "within_margin": [p.split("|") for p, c in self.clearance_m.items()
                              if c < margin_m],
            "needle_depth_mm": round(self.needle_depth_m * 1000, 4)
            if np.isfinite(self.needle_depth_m) else None,
            "geometry": geometry,
            "clearance_mm": {p: round(c * 1000, 4) for p, c in
                             sorted(self.clearance_m.items(), key=lambda kv: kv[1])},
        }


class CollisionModel:
    """Self- and environment-collision distances of the arm at any pose.

    Args:
        desc: the robot description (its ``cad_dir`` picks mesh hulls or k-DOPs).
        kdops: ``{link: offsets}``; default the committed table.
        limb_m: (V, 3) the vertices of a limb on the bench (arm frame, m): the
            environment is then the bench and the limb, without the panel.
    """

    def __init__(self, desc: RobotDescription, kdops: dict[str, Array] | None = None,
                 limb_m: ArrayLike | None = None):
        import coal
        import pinocchio as pin

        t0 = time.perf_counter()
        self._pin = pin
        self.desc = desc
        # the shared, read-only kinematic model; the geometry below is this model's own
        self.model = pinocchio_model(to_urdf(desc), desc.gravity)
        self.data = self.model.createData()
        self.geometry = "mesh hulls" if desc.cad_dir else "k-DOP"
        table = load_kdops() if kdops is None else kdops
        gm = pin.GeometryModel()
        owner: list[str] = []  # body of each geometry object

        def add(name: str, body: str, frame: str | None, local: Any, shape: Any) -> None:
            if frame is None:
                gm.addGeometryObject(pin.GeometryObject(name, 0, 0, local, shape))
            else:
                fid = self.model.getFrameId(frame)
                fr = self.model.frames[fid]
                gm.addGeometryObject(pin.GeometryObject(name, fr.parentJoint, fid,
                                                        fr.placement * local, shape))
            owner.append(body)

        eye = np.eye(3)
        for link in desc.links:
            if link == PEN_LINK:
                continue
            for k, g in enumerate(desc.geometry[link]):
                if g.kind == "mesh":
                    assert g.mesh is not None
                    shape = _convex(mesh_vertices(g.mesh, g.size))
                elif link in table:
                    shape = _convex(kdop_vertices(table[link]))
                elif g.kind == "box":
                    shape = coal.Box(*g.size)
                else:
                    shape = coal.Cylinder(float(g.size[0]), float(g.size[1]))
                origin = np.zeros(3) if g.kind == "mesh" or link in table else g.origin
                add(f"{link}/{k}", link, link, pin.SE3(eye, origin), shape)
        if desc.tool == "tattoo":
            pen_len, radius, barrel = self._pen_dims()
            add(f"{PEN_LINK}/barrel", PEN_LINK, PEN_LINK,
                pin.SE3(eye, np.array([0.0, 0.0, barrel / 2])), coal.Cylinder(radius, barrel))
            add(NEEDLE, PEN_LINK, PEN_LINK,
                pin.SE3(eye, np.array([0.0, 0.0, (barrel + pen_len) / 2])),
                coal.Cone(radius, pen_len - barrel))
        bench = desc.bench_size
        add("bench", "bench", None, pin.SE3(eye, np.array([0.0, 0.0, -bench[2] / 2])),
            coal.Box(*bench))
        self.on_skin = limb_m is not None
        if limb_m is None:
            add("panel", "panel", None, pin.SE3(eye, desc.panel_centre),
                coal.Box(*desc.panel_size))
        else:
            add(LIMB, LIMB, None, pin.SE3(eye, np.zeros(3)),
                _convex(np.asarray(limb_m, dtype=np.float64)))
        skin = {NEEDLE, "panel" if limb_m is None else LIMB}

        self.pairs: list[BodyPair] = body_pairs(desc, ON_SKIN if self.on_skin else ENVIRONMENT)
        self.checked: list[BodyPair] = [p for p in self.pairs if p.checked]
        index = {p.name: i for i, p in enumerate(self.checked)}
        names = [g.name for g in gm.geometryObjects]
        pair_of: list[int] = []
        for i in range(len(names)):
            for j in range(i + 1, len(names)):
                key = f"{owner[i]}|{owner[j]}"
                if key not in index or {names[i], names[j]} == skin:
                    continue
                gm.addCollisionPair(pin.CollisionPair(i, j))
                pair_of.append(index[key])
        self.geom_model = gm
        self.geom_data = pin.GeometryData(gm)
        self._pair_of = np.asarray(pair_of, dtype=np.int64)
        self._owner = owner
        self.pair_names: list[str] = [p.name for p in self.checked]
        self._reach = self._body_reach()
        self._tcp = self.model.getFrameId(desc.tip_frame)
        self._tool0 = self.model.getFrameId("tool0")
        self.build_s = time.perf_counter() - t0

    # ----------------------------------------------------------------------- geometry
    def _pen_dims(self) -> tuple[float, float, float]:
        """(length, radius, barrel length) of the pen, m, from its description."""
        radius, length = (float(v) for v in self.desc.geometry[PEN_LINK][0].size)
        return length, radius, self.desc.pen_barrel_length

    def _body_reach(self) -> Array:
        """(n_joints + 1, n_bodies) reach of each body from each joint's origin, m.

        Row 0 is the world (unused). Zero where the joint does not move the body.
        """
        m, gm = self.model, self.geom_model
        bodies = sorted(set(self._owner), key=self._owner.index)
        self.bodies = bodies
        reach = np.zeros((m.njoints, len(bodies)))
        for go, body in zip(gm.geometryObjects, self._owner, strict=True):
            shape = go.geometry
            shape.computeLocalAABB()
            centre = go.placement.act(np.asarray(shape.aabb_center))
            radius = float(np.linalg.norm(centre)) + float(shape.aabb_radius)
            jb = go.parentJoint
            link_len = 0.0
            while jb > 0:  # joints from the body's own joint down to the base
                reach[jb, bodies.index(body)] = max(reach[jb, bodies.index(body)],
                                                    radius + link_len)
                link_len += float(np.linalg.norm(m.jointPlacements[jb].translation))
                jb = m.parents[jb]
        return reach

    # ----------------------------------------------------------------------- queries
    def clearance(self, q: ArrayLike) -> Array:
        """Clearance of every checked pair at each pose, (N, P) m (or (P,) for one pose).

        Raises:
            TattotronixError: poses that are not (N, n) finite angles.
        """
        pin = self._pin
        qa = np.asarray(q, dtype=np.float64)
        one = qa.ndim == 1
        qa = np.atleast_2d(qa)
        if qa.shape[1] != self.model.nq or not np.all(np.isfinite(qa)):
            raise TattotronixError(f"poses must be {self.model.nq} finite joint angles (rad), "
                                   f"got shape {qa.shape}")
        n_pairs = len(self.checked)
        out = np.full((len(qa), n_pairs), np.inf)
        res = self.geom_data.distanceResults
        m, d, gm, gd = self.model, self.data, self.geom_model, self.geom_data
        raw = np.empty(len(self._pair_of))
        for i, row in enumerate(qa):
            pin.computeDistances(m, d, gm, gd, row)
            raw[:] = [r.min_distance for r in res]
            np.minimum.at(out[i], self._pair_of, raw)
        return out[0] if one else out

    def motion_bound_m(self, q0: Array, q1: Array) -> Array:
        """Upper bound on each checked pair's relative motion along the joint lines
        ``q0 -> q1`` (row-wise), (N, P) m."""
        dq = np.abs(np.atleast_2d(q1) - np.atleast_2d(q0))  # (N, n)
        body = dq @ self._reach[1:]  # (N, n_bodies)
        idx = {b: i for i, b in enumerate(self.bodies)}
        a = np.array([idx[p.a] for p in self.checked])
        b = np.array([idx[p.b] for p in self.checked])
        return body[:, a] + body[:, b]

    def frames(self, q: ArrayLike) -> tuple[Array, Array, Array]:
        """(tcp (N, 3), tool0 origin (N, 3), tool axis (N, 3)) at each pose, m."""
        pin = self._pin
        qa = np.atleast_2d(np.asarray(q, dtype=np.float64))
        tcp, tool0, axis = (np.empty((len(qa), 3)) for _ in range(3))
        for i, row in enumerate(qa):
            pin.framesForwardKinematics(self.model, self.data, row)
            tcp[i] = self.data.oMf[self._tcp].translation
            t0 = self.data.oMf[self._tool0]
            tool0[i], axis[i] = t0.translation, t0.rotation[:, 2]
        return tcp, tool0, axis

    def pen_lowest_z(self, q: ArrayLike) -> Array:
        """Height of the lowest point of the pen (barrel and needle) at each pose, m."""
        _, radius, barrel = self._pen_dims()
        tcp, tool0, axis = self.frames(q)
        rim = radius * np.sqrt(np.clip(1.0 - axis[:, 2] ** 2, 0.0, None))
        ends = np.column_stack([tool0[:, 2], tool0[:, 2] + barrel * axis[:, 2]]) - rim[:, None]
        return np.minimum(ends.min(axis=1), tcp[:, 2])

    def needle_depth_m(self, tcp: Array) -> Array:
        """Depth of the tip below the panel surface where it is over the panel, else
        ``-inf``, (N,) m (``-inf`` everywhere on the limb: there the path sets the depth
        along the surface's normal)."""
        if self.on_skin:
            return np.full(len(np.atleast_2d(tcp)), -np.inf)
        c, s = self.desc.panel_centre, self.desc.panel_size
        top = c[2] + s[2] / 2
        tip = np.atleast_2d(tcp)
        over = np.all(np.abs(tip[:, :2] - c[:2]) <= s[:2] / 2, axis=1)
        return np.where(over, top - tip[:, 2], -np.inf)

    def pose_report(self, q: ArrayLike) -> PoseReport:
        """The clearance report of one pose."""
        qa = np.asarray(q, dtype=np.float64).reshape(-1)
        c = self.clearance(qa)
        worst = int(np.argmin(c))
        tcp, _, _ = self.frames(qa)
        d = self.desc
        return PoseReport(
            pose=qa, clearance_m={n: float(v) for n, v in zip(self.pair_names, c, strict=True)},
            collisions=[n.split("|") for n, v in zip(self.pair_names, c, strict=True) if v <= 0],
            min_clearance_m=float(c[worst]), worst_pair=self.pair_names[worst].split("|"),
            needle_depth_m=float(self.needle_depth_m(tcp)[0]),
            within_limits=bool(np.all(qa >= d.lower - 1e-12) and np.all(qa <= d.upper + 1e-12)))
