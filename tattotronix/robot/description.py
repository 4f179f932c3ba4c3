"""The immutable robot description, built once from ``cfg.robot``.

Everything downstream (URDF, MJCF, the Pinocchio, MuJoCo and PyBullet loaders, the mass
stage, reports) reads this one object; nothing re-types the joint table.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from tattotronix.config.schema import MassModel, RobotConfig, Tool
from tattotronix.errors import TattotronixError
from tattotronix.robot.stl import mesh_dir_files, read_stl, resolve_cad_dir

__all__ = [
    "Frame",
    "Geometry",
    "Inertial",
    "Joint",
    "RobotDescription",
    "build_description",
    "rpy_matrix",
]

PEN_LINK = "tattoo_pen_link"


def rpy_matrix(rpy: NDArray[np.float64] | list[float]) -> NDArray[np.float64]:
    """URDF roll-pitch-yaw (fixed axes X, Y, Z) to a rotation matrix: Rz(y) Ry(p) Rx(r)."""
    r, p, y = (float(a) for a in rpy)
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    return np.array(
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
    )


@dataclass(frozen=True)
class Inertial:
    """Mass (kg), CoM in the link frame (m), inertia about the CoM in link axes (kg m^2)."""

    mass: float
    com: NDArray[np.float64]
    inertia: NDArray[np.float64]  # (3, 3)

    @staticmethod
    def from_list(mass: float, com: ArrayLike, six: Sequence[float]) -> Inertial:
        """From ``[ixx, ixy, ixz, iyy, iyz, izz]``."""
        ixx, ixy, ixz, iyy, iyz, izz = (float(v) for v in six)
        tensor = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
        return Inertial(float(mass), np.asarray(com, dtype=float), tensor)

    @staticmethod
    def solid_box(mass: float, centre: ArrayLike, size: Sequence[float]) -> Inertial:
        """A solid box: m (b^2 + c^2) / 12 about each axis."""
        a, b, c = (float(v) for v in size)
        diag = mass / 12.0 * np.array([b * b + c * c, a * a + c * c, a * a + b * b])
        return Inertial(float(mass), np.asarray(centre, dtype=float), np.diag(diag))

    @staticmethod
    def solid_cylinder_z(mass: float, centre: ArrayLike, radius: float,
                         length: float) -> Inertial:
        """A solid cylinder along z: m (3 r^2 + h^2) / 12 across, m r^2 / 2 along."""
        across = mass * (3 * radius**2 + length**2) / 12.0
        along = mass * radius**2 / 2.0
        tensor = np.diag([across, across, along])
        return Inertial(float(mass), np.asarray(centre, dtype=float), tensor)

    @property
    def six(self) -> tuple[float, float, float, float, float, float]:
        """``(ixx, ixy, ixz, iyy, iyz, izz)``."""
        t = self.inertia
        return tuple(float(v) for v in (t[0, 0], t[0, 1], t[0, 2], t[1, 1], t[1, 2], t[2, 2]))  # type: ignore[return-value]


@dataclass(frozen=True)
class Geometry:
    """What a link looks like and collides as: a mesh file (scaled) or a primitive."""

    kind: str  # "mesh" | "box" | "cylinder"
    origin: NDArray[np.float64]  # position in the link frame, m
    size: NDArray[np.float64]  # box (3,) full size; cylinder (radius, length); mesh: scale (3,)
    mesh: Path | None = None

    def points(self) -> NDArray[np.float64]:
        """Points of the geometry in its link frame (m): mesh vertices or primitive corners."""
        if self.kind == "mesh":
            assert self.mesh is not None
            return read_stl(self.mesh).reshape(-1, 3) * self.size + self.origin
        if self.kind == "box":
            half = np.asarray(self.size) / 2
            corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1)
                                for sz in (-1, 1)])
            return corners * half + self.origin
        radius, length = self.size
        ang = np.linspace(0, 2 * np.pi, 32, endpoint=False)
        ring = np.stack([radius * np.cos(ang), radius * np.sin(ang), np.zeros_like(ang)], axis=1)
        return np.concatenate([ring - [0, 0, length / 2], ring + [0, 0, length / 2]]) + self.origin


@dataclass(frozen=True)
class Joint:
    """A revolute joint: fixed origin in the parent frame, then rotation about ``axis``."""

    name: str
    parent: str
    child: str
    xyz: NDArray[np.float64]
    rpy: NDArray[np.float64]
    axis: NDArray[np.float64]
    lower: float
    upper: float
    effort: float
    velocity: float


@dataclass(frozen=True)
class Frame:
    """A frame rigidly attached to ``parent`` (URDF: a link behind a fixed joint)."""

    name: str
    parent: str
    xyz: NDArray[np.float64]
    rpy: NDArray[np.float64]


@dataclass(frozen=True)
class RobotDescription:
    """The arm, its tool and its world, in SI units.

    Attributes:
        name: model name.
        links: body links in tree order, base first (``base_link`` ... ``tool_mount_link``,
            then ``tattoo_pen_link`` when the tattoo tool is mounted).
        joints: the revolute joints, base outward.
        frames: massless frames (``tool0``, ``tattoo_tcp``) and the fixed pen link's mount.
        inertials: per body link.
        geometry: per body link (visual and collision).
        gravity: magnitude, m/s^2, along -z.
        mass_model: ``printed`` or ``box``.
        tool: ``tattoo`` or ``none``.
        bench_size, panel_centre, panel_size: world geometry, m (bench top at z = 0).
        cad_dir: the CAD mesh folder, or None (primitive geometry).
        pen_barrel_length: the pen's barrel from ``tool0``, m; the rest of the pen, to the
            tip, is the needle cone (0 without the tattoo tool).
    """

    name: str
    links: tuple[str, ...]
    joints: tuple[Joint, ...]
    frames: tuple[Frame, ...]
    inertials: dict[str, Inertial]
    geometry: dict[str, tuple[Geometry, ...]]
    gravity: float
    mass_model: str
    tool: str
    bench_size: NDArray[np.float64]
    panel_centre: NDArray[np.float64]
    panel_size: NDArray[np.float64]
    cad_dir: Path | None
    pen_barrel_length: float = 0.0

    @property
    def joint_names(self) -> tuple[str, ...]:
        """``joint_1`` ... ``joint_5``."""
        return tuple(j.name for j in self.joints)

    @property
    def lower(self) -> NDArray[np.float64]:
        """Lower joint limits, rad."""
        return np.array([j.lower for j in self.joints])

    @property
    def upper(self) -> NDArray[np.float64]:
        """Upper joint limits, rad."""
        return np.array([j.upper for j in self.joints])

    @property
    def frame_names(self) -> tuple[str, ...]:
        """Every named frame: the links, then the massless frames."""
        return self.links + tuple(f.name for f in self.frames if f.name not in self.links)

    @property
    def tip_frame(self) -> str:
        """The frame paths are planned for: ``tattoo_tcp``, or ``tool0`` without a tool."""
        return "tattoo_tcp" if self.tool == "tattoo" else "tool0"

    def parent_of(self, name: str) -> str | None:
        """The parent link or frame of a link or frame (None for the base)."""
        for j in self.joints:
            if j.child == name:
                return j.parent
        for f in self.frames:
            if f.name == name:
                return f.parent
        return None

    def moving_mass(self) -> float:
        """Mass of everything from the first joint's child outward, kg."""
        return sum(i.mass for link, i in self.inertials.items() if link != self.links[0])

    def arm_mass(self) -> float:
        """Mass of the arm's own links (the tool excluded), kg."""
        return sum(i.mass for link, i in self.inertials.items() if link != PEN_LINK)

    def total_mass(self) -> float:
        """Mass of every body link, kg."""
        return sum(i.mass for i in self.inertials.values())


def _vec(values: Iterable[float], n: int, where: str) -> NDArray[np.float64]:
    arr = np.asarray(list(values), dtype=float)
    if arr.shape != (n,) or not np.all(np.isfinite(arr)):
        raise TattotronixError(f"{where} must be {n} finite numbers, got {list(values)}")
    return arr


def build_description(robot: RobotConfig) -> RobotDescription:
    """Validate the ``robot`` settings and build the description.

    Raises:
        TattotronixError: a joint limit with lower >= upper, a broken chain, an unknown
            mass model or tool, a missing inertial, or a ``cad_dir`` missing a mesh.
    """
    r = robot
    mass_model = str(r.mass_model.value if isinstance(r.mass_model, MassModel) else r.mass_model)
    tool = str(r.tool.value if isinstance(r.tool, Tool) else r.tool)
    if mass_model not in ("printed", "box"):
        raise TattotronixError(
            f"robot.mass_model={mass_model!r} is not allowed: choose printed or box"
        )
    if tool not in ("tattoo", "none"):
        raise TattotronixError(f"robot.tool={tool!r} is not allowed: choose tattoo or none")

    joints: list[Joint] = []
    links = [str(r.base_link)]
    for i, jc in enumerate(r.joints):
        where = f"robot.joints[{i}] ({jc.name})"
        if str(jc.parent) != links[-1]:
            raise TattotronixError(
                f"{where}: parent {jc.parent!r} should be {links[-1]!r} (a serial chain)"
            )
        lower, upper = float(jc.lower), float(jc.upper)
        if not lower < upper:
            raise TattotronixError(
                f"{where}: joint limit lower={lower} must be below upper={upper} (rad)"
            )
        axis = _vec(jc.axis, 3, f"{where}.axis")
        if np.linalg.norm(axis) == 0:
            raise TattotronixError(f"{where}.axis is zero")
        joints.append(
            Joint(str(jc.name), str(jc.parent), str(jc.child), _vec(jc.xyz, 3, f"{where}.xyz"),
                  _vec(jc.rpy, 3, f"{where}.rpy"), axis / np.linalg.norm(axis), lower, upper,
                  float(jc.effort), float(jc.velocity))
        )
        links.append(str(jc.child))
    arm_links = tuple(links)

    frames = [
        Frame(str(r.tool0.name), str(r.tool0.parent), _vec(r.tool0.xyz, 3, "robot.tool0.xyz"),
              _vec(r.tool0.rpy, 3, "robot.tool0.rpy"))
    ]
    if frames[0].parent not in arm_links:
        raise TattotronixError(f"robot.tool0.parent={frames[0].parent!r} is not a link")

    # Inertials: the chosen table for the arm links, plus the pen.
    inertials: dict[str, Inertial] = {}
    for link in arm_links:
        if link not in (r.printed if mass_model == "printed" else r.box):
            raise TattotronixError(f"robot.{mass_model} has no inertial for link {link!r}")
        if mass_model == "printed":
            e = r.printed[link]
            inertials[link] = Inertial.from_list(e.mass, e.com, e.inertia)
        else:
            b = r.box[link]
            inertials[link] = Inertial.solid_box(b.mass, b.centre, b.size)
        if not inertials[link].mass > 0:
            raise TattotronixError(f"robot.{mass_model}.{link}.mass must be positive")

    cad_dir = resolve_cad_dir(str(r.cad_dir)) if r.cad_dir else None
    geometry: dict[str, tuple[Geometry, ...]] = {}
    if cad_dir is not None:
        scale = np.full(3, float(r.mesh_scale))
        for link, path in mesh_dir_files(cad_dir, arm_links).items():
            geometry[link] = (Geometry("mesh", np.zeros(3), scale, path),)
    else:
        for link in arm_links:
            b = r.box[link]
            geometry[link] = (Geometry("box", _vec(b.centre, 3, f"robot.box.{link}.centre"),
                                       _vec(b.size, 3, f"robot.box.{link}.size")),)

    body_links = list(arm_links)
    barrel = 0.0
    if tool == "tattoo":
        pen = r.pen
        length, radius = float(pen.length), float(pen.radius)
        barrel = float(pen.barrel_length)
        if not 0 < barrel < length:
            raise TattotronixError(f"robot.pen.barrel_length={barrel} must lie between 0 and "
                                   f"the pen's length {length} (m): the needle is the rest")
        frames.append(Frame(PEN_LINK, frames[0].name, np.zeros(3), np.zeros(3)))
        frames.append(Frame(str(r.tcp.name), PEN_LINK, _vec(r.tcp.xyz, 3, "robot.tcp.xyz"),
                            _vec(r.tcp.rpy, 3, "robot.tcp.rpy")))
        centre = np.array([0.0, 0.0, length / 2])
        inertials[PEN_LINK] = Inertial.solid_cylinder_z(float(pen.mass), centre, radius, length)
        geometry[PEN_LINK] = (Geometry("cylinder", centre, np.array([radius, length])),)
        body_links.append(PEN_LINK)

    return RobotDescription(
        name=str(r.name),
        links=tuple(body_links),
        joints=tuple(joints),
        frames=tuple(frames),
        inertials=inertials,
        geometry=geometry,
        gravity=float(r.gravity),
        mass_model=mass_model,
        tool=tool,
        bench_size=_vec(r.bench.size, 3, "robot.bench.size"),
        panel_centre=_vec(r.panel.centre, 3, "robot.panel.centre"),
        panel_size=_vec(r.panel.size, 3, "robot.panel.size"),
        cad_dir=cad_dir,
        pen_barrel_length=barrel if tool == "tattoo" else 0.0,
    )
