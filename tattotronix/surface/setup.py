"""The work surface a drawing goes on, from its settings (``surface=forearm|mesh``).

:func:`work_surface` builds it once: the forearm phantom (:class:`~tattotronix.surface.cone.
EllipticCone`, posed on the bench) or a mesh from a file (:func:`~tattotronix.surface.mesh.
load_mesh`), its triangle mesh in the arm's frame (mm) for the plants, the collision model
and the figures, and the design's placement on it. :meth:`WorkSurface.chart` lays a design
there: the phantom's exact development, or a mesh's conformal map of the patch the design
covers. The flat panel (``surface=panel``, the default) is not a work surface here: the
panel's pipeline is unchanged.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from tattotronix.config.schema import SurfaceConfig, SurfaceKind
from tattotronix.errors import TattotronixError
from tattotronix.surface.chart import Chart
from tattotronix.surface.cone import EllipticCone
from tattotronix.surface.mesh import MeshChart, load_mesh

__all__ = ["WorkSurface", "bench_pose", "work_surface"]

Array = NDArray[np.float64]
Faces = NDArray[np.int64]

#: the phantom's mesh for the plants and figures: sections along it, points around each
PHANTOM_MESH = (80, 160)


def bench_pose(origin_mm: list[float], yaw_deg: float) -> Array:
    """4x4 (mm): the limb's frame at ``origin_mm`` in the arm's, turned ``yaw_deg`` about
    the vertical (90: the limb's axis along the arm's ``+y``)."""
    if len(origin_mm) != 3:
        raise TattotronixError(f"surface.origin_mm must be [x, y, z] mm, got {origin_mm}")
    c, s = math.cos(math.radians(yaw_deg)), math.sin(math.radians(yaw_deg))
    pose = np.eye(4)
    pose[:3, :3] = [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]
    pose[:3, 3] = origin_mm
    return pose


@dataclass(frozen=True)
class WorkSurface:
    """A curved work surface on the bench.

    Attributes:
        kind: ``forearm`` or ``mesh``.
        vertices: (V, 3) the surface's mesh in the arm's frame, mm.
        faces: (F, 3) its triangles, wound outward.
        cone: the phantom (None for a mesh).
        settings: where the design goes (``surface``).
        pose: 4x4 (mm) from the limb's (or the mesh file's) frame to the arm's.
    """

    kind: str
    vertices: Array
    faces: Faces
    cone: EllipticCone | None
    settings: SurfaceConfig
    pose: Array

    @property
    def axis(self) -> Array:
        """The limb's axis (the design's ``u`` at no turn) in the arm's frame."""
        return np.asarray(self.pose[:3, 0], dtype=np.float64)

    def placement_mm(self) -> Array:
        """The design's centre on the surface, arm frame, mm."""
        s = self.settings
        if self.cone is not None:
            x = np.array([float(s.along_mm)])
            return np.asarray(self.cone.posed(self.cone.point(
                x, np.radians([float(s.around_deg)])))[0], dtype=np.float64)
        if s.mesh_at_mm is None:
            return np.asarray(self.vertices[int(np.argmax(self.vertices[:, 2]))],
                              dtype=np.float64)
        at = np.asarray(s.mesh_at_mm, dtype=np.float64)
        return np.asarray(self.pose[:3, :3] @ at + self.pose[:3, 3], dtype=np.float64)

    def chart(self, radius_mm: float) -> Chart:
        """The chart of the design placed by the settings; ``radius_mm`` is the design's
        half diagonal (a mesh's patch covers it with a margin).

        Raises:
            TattotronixError: a placement off the phantom, or a mesh patch that is not a
                disk.
        """
        s = self.settings
        if self.cone is not None:
            return self.cone.chart(float(s.along_mm), float(s.around_deg), float(s.turn_deg))
        return MeshChart(self.vertices, self.faces, self.placement_mm(),
                         1.25 * radius_mm + 2.0, reference=self.axis,
                         rotate_deg=float(s.turn_deg))


def work_surface(s: SurfaceConfig) -> WorkSurface:
    """The work surface of ``surface`` settings.

    Raises:
        TattotronixError: ``surface=panel`` (no curved surface), a phantom that does not
            fit its sizes, a mesh file missing or bad (one line, from
            :func:`~tattotronix.surface.mesh.load_mesh`).
    """
    pose = bench_pose(list(s.origin_mm), float(s.yaw_deg))
    if s.kind is SurfaceKind.forearm:
        p = s.phantom
        cone = EllipticCone(float(p.length_mm), float(p.elbow_width_mm),
                            float(p.wrist_width_mm), float(p.depth_ratio), pose)
        if not 0.0 <= float(s.along_mm) <= cone.length_mm:
            raise TattotronixError(
                f"surface.along_mm={float(s.along_mm):g} is off the phantom (0 to "
                f"{cone.length_mm:g} mm from its elbow end)")
        v, f = cone.mesh(*PHANTOM_MESH)
        return WorkSurface("forearm", v, f, cone, s, pose)
    if s.kind is SurfaceKind.mesh:
        if not s.mesh_file:
            raise TattotronixError("surface=mesh needs surface.mesh_file=PATH (an STL, PLY "
                                   "or OBJ), with surface.mesh_unit_mm (10 for cm)")
        v, f = load_mesh(s.mesh_file, float(s.mesh_unit_mm), pose)
        return WorkSurface("mesh", v, f, None, s, pose)
    raise TattotronixError("surface=panel is the flat panel, not a curved surface: give "
                           "surface=forearm or surface=mesh")
