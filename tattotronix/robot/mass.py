"""Mass properties of the printed arm: mesh integration plus catalogue servos.

Method (the original's: docs/original.md, "7 Mass-properties method"):

* each link's STL mesh, drawn in its own link frame, is scaled by ``robot.mesh_scale``
  (centimetres to metres) and integrated with the divergence theorem over the signed
  tetrahedra (link origin, a, b, c). The reference point is the link origin on purpose:
  the meshes have open 3 mm bores, so the volume of parts whose gaps enclose a net area
  depends on the reference point, and the original's published table (docs/original.md,
  "1.7 Mass properties") uses the link origin;
* the shell density is ``pla_density * printed_fraction`` (kg/m^3);
* every servo in ``robot.servo_mounts`` is a solid catalogue box (axes along the link
  axes, ``size`` taken as x, y, z) centred on the origin of the joint it drives, in the
  frame of the link before that joint; the tool servo sits on the tool axis (y, z of
  ``tool0``) at the bracket shell's centroid x;
* parts combine by adding masses, mass-weighting the CoM and shifting each inertia to the
  combined CoM (parallel axis).

Everything is SI inside: m, kg, kg m^2. Inertia is about the CoM, in link axes.

``python -m tattotronix.devtools.tables mass --cad-dir DIR [--write]`` integrates the
meshes and, with ``--write``, rewrites ``conf/robot/inertials/printed.yaml``.
"""

from __future__ import annotations

import hashlib
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from tattotronix.config.schema import JointConfig, RobotConfig, Tool
from tattotronix.errors import TattotronixError
from tattotronix.io.jsontypes import JsonDict
from tattotronix.robot.stl import mesh_dir_files, read_stl, resolve_cad_dir

__all__ = [
    "C0",
    "INERTIALS_FILE",
    "MassProperties",
    "box_properties",
    "closure_residual",
    "combine",
    "inertia_problems",
    "link_names",
    "link_properties",
    "mass_report",
    "mesh_properties",
    "mesh_sha256",
    "parallel_axis",
    "point_mass",
    "printed_table",
    "resolve_cad_dir",
    "servo_parts",
    "shell_density",
    "table_difference",
    "table_from_config",
    "table_yaml",
    "validate_inertia",
]

#: Second-moment covariance of the canonical tetrahedron (0, e1, e2, e3).
C0 = np.array([[2.0, 1.0, 1.0], [1.0, 2.0, 1.0], [1.0, 1.0, 2.0]]) / 120.0

#: The generated inertial table, relative to the project root.
INERTIALS_FILE = Path("conf/robot/inertials/printed.yaml")


def _frozen_array(x: Any, shape: tuple[int, ...]) -> np.ndarray:
    arr = np.array(x, dtype=np.float64).reshape(shape)
    arr.setflags(write=False)
    return arr


@dataclass(frozen=True, eq=False)
class MassProperties:
    """Rigid-body mass properties in one frame.

    Attributes:
        mass: kg.
        com: centre of mass, shape (3,), m.
        inertia: inertia tensor about the CoM in the frame's axes, shape (3, 3), kg m^2.
        volume_m3: enclosed volume of the mesh shell (m^3), when integrated from a mesh.
        area_m2: surface area of the mesh (m^2), when integrated from a mesh.
        closure_residual: ``||1/2 sum (b-a) x (c-a)|| / area`` (dimensionless), when
            integrated from a mesh; zero for a closed surface.
    """

    mass: float
    com: np.ndarray
    inertia: np.ndarray
    volume_m3: float | None = None
    area_m2: float | None = None
    closure_residual: float | None = None
    parts: tuple[str, ...] = field(default=())

    def __post_init__(self) -> None:
        object.__setattr__(self, "mass", float(self.mass))
        object.__setattr__(self, "com", _frozen_array(self.com, (3,)))
        object.__setattr__(self, "inertia", _frozen_array(self.inertia, (3, 3)))

    def inertia_about(self, point: Sequence[float] | np.ndarray) -> np.ndarray:
        """Inertia tensor about ``point`` (m, same frame), kg m^2 (parallel axis)."""
        d = self.com - np.asarray(point, dtype=np.float64)
        return self.inertia + parallel_axis(self.mass, d)

    def inertia6(self) -> list[float]:
        """``[ixx, ixy, ixz, iyy, iyz, izz]`` (kg m^2), the URDF / config order."""
        i = self.inertia
        return [i[0, 0], i[0, 1], i[0, 2], i[1, 1], i[1, 2], i[2, 2]]

    def as_inertial(self) -> JsonDict:
        """``{mass, com, inertia}`` with plain floats (the ``InertialConfig`` layout)."""
        return {
            "mass": self.mass,
            "com": [float(v) for v in self.com],
            "inertia": [float(v) for v in self.inertia6()],
        }

    @classmethod
    def from_inertial(
        cls, mass: float, com: Sequence[float], inertia6: Sequence[float]
    ) -> MassProperties:
        """Build from the config layout (``inertia`` = ixx, ixy, ixz, iyy, iyz, izz)."""
        xx, xy, xz, yy, yz, zz = (float(v) for v in inertia6)
        tensor = np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])
        return cls(mass=float(mass), com=np.asarray(com, dtype=np.float64), inertia=tensor)


def parallel_axis(mass: float, d: Sequence[float] | np.ndarray) -> np.ndarray:
    """Parallel-axis term ``m (|d|^2 I - d d^T)`` (kg m^2) for a CoM offset ``d`` (m)."""
    d = np.asarray(d, dtype=np.float64)
    return mass * (float(d @ d) * np.eye(3) - np.outer(d, d))


def combine(parts: Iterable[MassProperties]) -> MassProperties:
    """Combine rigid parts expressed in one frame (masses add, parallel-axis shift).

    Volume, area and closure residual are carried over only when exactly one part has
    them (the shell of a link), so a link keeps its shell's mesh figures.

    Raises:
        TattotronixError: no parts, or a non-positive total mass.
    """
    parts = list(parts)
    if not parts:
        raise TattotronixError("cannot combine an empty list of mass properties")
    mass = float(sum(p.mass for p in parts))
    if not mass > 0:
        raise TattotronixError(f"combined mass must be positive, got {mass} kg")
    com = np.sum([p.mass * p.com for p in parts], axis=0) / mass
    inertia = np.sum([p.inertia_about(com) for p in parts], axis=0)
    meshes = [p for p in parts if p.volume_m3 is not None]
    mesh = meshes[0] if len(meshes) == 1 else None
    return MassProperties(
        mass=mass,
        com=com,
        inertia=0.5 * (inertia + inertia.T),
        volume_m3=None if mesh is None else mesh.volume_m3,
        area_m2=None if mesh is None else mesh.area_m2,
        closure_residual=None if mesh is None else mesh.closure_residual,
        parts=tuple(name for p in parts for name in p.parts),
    )


def inertia_problems(inertia: np.ndarray, rtol: float = 1e-9) -> list[str]:
    """What is wrong with an inertia tensor about the CoM (empty when it is valid).

    Checks: symmetric, positive definite, and the triangle inequality of the principal
    moments (each <= the sum of the other two), all relative to the largest moment.

    Args:
        inertia: (3, 3) kg m^2.
        rtol: tolerance relative to the largest principal moment.
    """
    i = np.asarray(inertia, dtype=np.float64)
    if i.shape != (3, 3) or not np.all(np.isfinite(i)):
        return [f"not a finite 3x3 tensor: {i.tolist()}"]
    problems = []
    scale = float(np.max(np.abs(i))) or 1.0
    asym = float(np.max(np.abs(i - i.T)))
    if asym > rtol * scale:
        problems.append(f"not symmetric (max |I - I^T| = {asym:.3e})")
    moments = np.linalg.eigvalsh(0.5 * (i + i.T))
    if moments[0] <= 0:
        problems.append(f"not positive definite (principal moments {moments.tolist()})")
    tol = rtol * float(np.max(np.abs(moments)))
    for k in range(3):
        others = moments.sum() - moments[k]
        if moments[k] > others + tol:
            problems.append(
                f"principal moment {moments[k]:.6e} exceeds the sum of the other two "
                f"({others:.6e}): violates the triangle inequality"
            )
    return problems


def validate_inertia(name: str, props: MassProperties, rtol: float = 1e-9) -> None:
    """Raise when ``props`` is not a physical rigid body.

    Raises:
        TattotronixError: non-positive mass, or an invalid inertia tensor (names ``name``).
    """
    problems = [] if props.mass > 0 else [f"mass {props.mass} kg is not positive"]
    problems += inertia_problems(props.inertia, rtol)
    if problems:
        raise TattotronixError(f"{name}: invalid mass properties: " + "; ".join(problems))


def closure_residual(triangles: np.ndarray) -> float:
    """``||1/2 sum (b-a) x (c-a)|| / total area``: zero for a closed surface (no units)."""
    tri = np.asarray(triangles, dtype=np.float64)
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    area = 0.5 * float(np.linalg.norm(cross, axis=1).sum())
    if area <= 0:
        raise TattotronixError("mesh has zero surface area")
    return float(np.linalg.norm(0.5 * cross.sum(axis=0))) / area


def mesh_properties(triangles: np.ndarray, density: float, name: str = "mesh") -> MassProperties:
    """Integrate a uniform-density solid bounded by a triangle mesh.

    Divergence theorem over the signed tetrahedra (origin, a, b, c); the origin of the
    coordinates is the reference point (for an open mesh the result depends on it).

    Args:
        triangles: (N, 3, 3) vertices in m, counter-clockwise seen from outside.
        density: kg/m^3.
        name: label used in error messages and in ``parts``.

    Returns:
        Mass properties with CoM, inertia about the CoM, volume, area, closure residual.

    Raises:
        TattotronixError: the enclosed volume is not positive (inside-out or degenerate).
    """
    tri = np.asarray(triangles, dtype=np.float64)
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    det = np.einsum("ij,ij->i", a, np.cross(b, c))  # 6 x signed tetra volume
    volume = float(det.sum()) / 6.0
    if not volume > 0:
        raise TattotronixError(
            f"{name}: enclosed volume {volume:.6e} m^3 is not positive "
            "(inside-out or degenerate mesh)"
        )
    centroid = (det[:, None] * (a + b + c)).sum(axis=0) / (24.0 * volume)
    # E has the vertices as columns: E[n] = [a b c]; C = sum det E C0 E^T
    e = np.transpose(tri, (0, 2, 1))
    cov = np.einsum("n,nij,jk,nlk->il", det, e, C0, e)
    i0 = density * (np.trace(cov) * np.eye(3) - cov)
    mass = density * volume
    inertia = i0 - parallel_axis(mass, centroid)
    cross = np.cross(b - a, c - a)
    area = 0.5 * float(np.linalg.norm(cross, axis=1).sum())
    residual = float(np.linalg.norm(0.5 * cross.sum(axis=0))) / area
    return MassProperties(
        mass=mass,
        com=centroid,
        inertia=0.5 * (inertia + inertia.T),
        volume_m3=volume,
        area_m2=area,
        closure_residual=residual,
        parts=(name,),
    )


def box_properties(
    mass: float, size: Sequence[float], centre: Sequence[float], name: str = "box"
) -> MassProperties:
    """A solid box with its axes along the frame axes.

    Args:
        mass: kg.
        size: edge lengths along x, y, z (m).
        centre: box centre (m).
        name: label for ``parts``.

    Returns:
        ``I = m/12 diag(b^2 + c^2, a^2 + c^2, a^2 + b^2)`` about the centre.
    """
    sx, sy, sz = (float(v) for v in size)
    diag = mass / 12.0 * np.array([sy**2 + sz**2, sx**2 + sz**2, sx**2 + sy**2])
    return MassProperties(
        mass=mass, com=np.asarray(centre, dtype=np.float64), inertia=np.diag(diag), parts=(name,)
    )


def point_mass(mass: float, position: Sequence[float], name: str = "point") -> MassProperties:
    """A point mass (kg) at ``position`` (m): zero inertia about itself."""
    return MassProperties(
        mass=mass,
        com=np.asarray(position, dtype=np.float64),
        inertia=np.zeros((3, 3)),
        parts=(name,),
    )


def shell_density(robot_cfg: RobotConfig) -> float:
    """Printed-shell density ``pla_density * printed_fraction`` (kg/m^3)."""
    return float(robot_cfg.pla_density) * float(robot_cfg.printed_fraction)


def link_names(robot_cfg: RobotConfig) -> list[str]:
    """Every link of the tree: the base, then each joint's child in table order."""
    return [str(robot_cfg.base_link)] + [str(j.child) for j in robot_cfg.joints]


def _joint(robot_cfg: RobotConfig, name: str) -> JointConfig:
    for j in robot_cfg.joints:
        if j.name == name:
            return j
    raise TattotronixError(
        f"servo_mounts: unknown joint {name!r} (joints: "
        + ", ".join(str(j.name) for j in robot_cfg.joints)
        + ', or "tool")'
    )


def servo_parts(robot_cfg: RobotConfig, link: str,
                shell: MassProperties | None) -> list[MassProperties]:
    """The catalogue servo boxes mounted on ``link`` (link frame, m / kg).

    Args:
        robot_cfg: the robot config (``servos``, ``servo_mounts``, ``joints``, ``tool0``).
        link: the link name.
        shell: the link's shell; its centroid x places a tool servo (may be None when
            the link has no tool servo).

    Raises:
        TattotronixError: a mount names an unknown servo or joint, or a joint whose
            parent is not ``link``.
    """
    parts = []
    for mount in robot_cfg.servo_mounts:
        if mount.link != link:
            continue
        if mount.servo not in robot_cfg.servos:
            raise TattotronixError(
                f"servo_mounts: unknown servo {mount.servo!r} on {link} (catalogue: "
                + ", ".join(sorted(robot_cfg.servos))
                + ")"
            )
        servo = robot_cfg.servos[mount.servo]
        if mount.at == "tool":
            tool0 = robot_cfg.tool0
            if tool0.parent != link:
                raise TattotronixError(
                    f"servo_mounts: tool servo on {link}, but tool0 hangs from {tool0.parent}"
                )
            if shell is None:
                raise TattotronixError(f"servo_mounts: tool servo on {link} needs its shell")
            centre = [float(shell.com[0]), float(tool0.xyz[1]), float(tool0.xyz[2])]
        else:
            joint = _joint(robot_cfg, mount.at)
            if joint.parent != link:
                raise TattotronixError(
                    f"servo_mounts: the {mount.at} servo must sit on {joint.parent} "
                    f"(the link before the joint), not on {link}"
                )
            centre = [float(v) for v in joint.xyz]
        count = int(mount.count)
        if count < 1:
            raise TattotronixError(f"servo_mounts: count {count} on {link} must be >= 1")
        parts.append(
            box_properties(
                count * float(servo.mass),
                list(servo.size),
                centre,
                name=f"{count}x{mount.servo}@{mount.at}",
            )
        )
    return parts


def link_properties(
    robot_cfg: RobotConfig, link: str, triangles: np.ndarray, name: str | None = None
) -> MassProperties:
    """One link: its printed shell (mesh in the link frame, file units) plus its servos.

    Args:
        robot_cfg: the robot config.
        link: the link name.
        triangles: (N, 3, 3) mesh vertices in the file's units (scaled by ``mesh_scale``).
        name: label for the shell in ``parts`` (default ``<link>.stl``).

    Returns:
        The combined link, carrying the shell's volume, area and closure residual.
    """
    tri = np.asarray(triangles, dtype=np.float64) * float(robot_cfg.mesh_scale)
    shell = mesh_properties(tri, shell_density(robot_cfg), name=name or f"{link}.stl")
    props = combine([shell, *servo_parts(robot_cfg, link, shell)])
    validate_inertia(link, props)
    return props


def _mesh_files(robot_cfg: RobotConfig, cad_dir: str | Path | None = None) -> dict[str, Path]:
    cad = cad_dir if cad_dir is not None else robot_cfg.cad_dir
    if cad is None:
        raise TattotronixError(
            "robot.cad_dir is null: set it to the folder of per-link STL meshes "
            "(e.g. robot.cad_dir=../shared/cad/meshes) to integrate the mass properties"
        )
    return mesh_dir_files(resolve_cad_dir(cad), link_names(robot_cfg))


def printed_table(
    robot_cfg: RobotConfig, cad_dir: str | Path | None = None
) -> dict[str, MassProperties]:
    """Integrate every link's mesh and add its servos: the ``printed`` inertial table.

    Args:
        robot_cfg: the robot config; meshes come from ``robot_cfg.cad_dir`` unless
            ``cad_dir`` is given.
        cad_dir: optional override of the mesh directory.

    Returns:
        ``{link: MassProperties}`` in tree order (link frame, SI).

    Raises:
        TattotronixError: no mesh directory, a missing or bad mesh, a bad servo mount.
    """
    files = _mesh_files(robot_cfg, cad_dir)
    return {
        link: link_properties(robot_cfg, link, read_stl(path), name=path.name)
        for link, path in files.items()
    }


def mesh_sha256(robot_cfg: RobotConfig, cad_dir: str | Path | None = None) -> dict[str, str]:
    """The sha256 of each link's mesh file (provenance)."""
    files = _mesh_files(robot_cfg, cad_dir)
    return {link: hashlib.sha256(p.read_bytes()).hexdigest() for link, p in files.items()}


def table_from_config(robot_cfg: RobotConfig) -> dict[str, MassProperties]:
    """The committed ``printed`` table of the config as ``{link: MassProperties}``.

    Raises:
        TattotronixError: a link of the tree has no entry.
    """
    missing = [lk for lk in link_names(robot_cfg) if lk not in robot_cfg.printed]
    if missing:
        raise TattotronixError(
            f"robot.printed lacks {', '.join(missing)}: regenerate it with "
            "`python -m tattotronix.devtools.tables mass --cad-dir DIR --write`"
        )
    return {
        link: MassProperties.from_inertial(
            robot_cfg.printed[link].mass,
            list(robot_cfg.printed[link].com),
            list(robot_cfg.printed[link].inertia),
        )
        for link in link_names(robot_cfg)
    }


_YAML_HEADER = """\
# GENERATED from the CAD meshes by `python -m tattotronix.devtools.tables mass --cad-dir DIR --write`:
# do not edit. `python stages/mass.py robot.cad_dir=DIR` reports its distance to the meshes.
# Printed shells (mesh volume x pla_density x printed_fraction) plus catalogue servos;
# mass kg, com m (link frame), inertia kg m^2 about the CoM in link axes:
# [ixx, ixy, ixz, iyy, iyz, izz].
"""  # noqa: E501


def table_yaml(table: Mapping[str, MassProperties]) -> str:
    """The exact text of ``conf/robot/inertials/printed.yaml`` for ``table``.

    One line per link: com "%.6f", mass "%.9g", inertia "%.6e".
    """
    lines = [_YAML_HEADER.rstrip("\n")]
    for link, p in table.items():
        com = ", ".join(f"{v:.6f}" for v in p.com)
        inertia = ", ".join(f"{v:.6e}" for v in p.inertia6())
        lines.append(f"{link}: {{mass: {p.mass:.9g}, com: [{com}], inertia: [{inertia}]}}")
    return "\n".join(lines) + "\n"


def table_difference(
    a: Mapping[str, MassProperties], b: Mapping[str, MassProperties]
) -> dict[str, dict[str, float]]:
    """Per-link differences of ``a`` against ``b``.

    Returns:
        ``{link: {mass_rel, com_mm, inertia_rel, max_rel}}``: relative mass difference,
        CoM distance (mm), largest inertia-entry difference relative to the largest
        principal moment of ``b``, and the larger of the two relative figures.
    """
    out = {}
    for link in b:
        if link not in a:
            continue
        pa, pb = a[link], b[link]
        mass_rel = abs(pa.mass - pb.mass) / pb.mass
        scale = float(np.max(np.abs(np.linalg.eigvalsh(pb.inertia))))
        inertia_rel = float(np.max(np.abs(pa.inertia - pb.inertia))) / scale
        out[link] = {
            "mass_rel": mass_rel,
            "com_mm": 1e3 * float(np.linalg.norm(pa.com - pb.com)),
            "inertia_rel": inertia_rel,
            "max_rel": max(mass_rel, inertia_rel),
        }
    return out


def _tool_is_pen(robot_cfg: RobotConfig) -> bool:
    return robot_cfg.tool is Tool.tattoo


def mass_report(table: Mapping[str, MassProperties], robot_cfg: RobotConfig) -> JsonDict:
    """Metrics of an inertial table (for ``data/metrics/mass.json``).

    Servo masses come from the config's catalogue and mounts; the shell is the rest.
    Mesh figures (volume cm^3, area cm^2, closure residual) appear when the table was
    integrated from meshes.

    Args:
        table: ``{link: MassProperties}``.
        robot_cfg: the robot config (servos, servo_mounts, pen, tool, base_link).

    Returns:
        ``{"links": {link: {...}}, "totals": {...}}``; masses in g per link, kg in totals.
    """
    servo_kg = {link: 0.0 for link in table}
    for mount in robot_cfg.servo_mounts:
        if mount.link in servo_kg:
            servo_kg[mount.link] += int(mount.count) * float(robot_cfg.servos[mount.servo].mass)
    links: dict[str, Any] = {}
    for link, p in table.items():
        row: dict[str, Any] = {
            "shell_g": 1e3 * (p.mass - servo_kg[link]),
            "servos_g": 1e3 * servo_kg[link],
            "total_g": 1e3 * p.mass,
            "com_mm": [1e3 * float(v) for v in p.com],
            "principal_moments_kg_m2": [float(v) for v in np.linalg.eigvalsh(p.inertia)],
        }
        if p.volume_m3 is not None:
            row["volume_cm3"] = 1e6 * p.volume_m3
        if p.area_m2 is not None:
            row["area_cm2"] = 1e4 * p.area_m2
        if p.closure_residual is not None:
            row["closure_residual"] = p.closure_residual
        links[link] = row
    arm = sum(p.mass for p in table.values())
    servos = sum(servo_kg.values())
    pen = float(robot_cfg.pen.mass) if _tool_is_pen(robot_cfg) else 0.0
    base = str(robot_cfg.base_link)
    moving = sum(p.mass for lk, p in table.items() if lk != base) + pen
    totals: dict[str, Any] = {
        "arm_kg": arm,
        "moving_kg": moving,
        "pen_kg": pen,
        "shells_kg": arm - servos,
        "servos_kg": servos,
        "servos_share_pct": 100.0 * servos / arm,
        "shell_density_kg_m3": shell_density(robot_cfg),
    }
    if all(p.volume_m3 is not None for p in table.values()):
        totals["volume_cm3"] = 1e6 * sum(float(p.volume_m3 or 0.0) for p in table.values())
    return {"links": links, "totals": totals}
