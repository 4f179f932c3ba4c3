"""MJCF text from the robot description (for MuJoCo).

Radians explicitly (MJCF defaults to degrees), explicit inertias (``inertiafromgeom``
off, so meshes never change the dynamics), torque actuators limited to the effort limit.
``tool0`` and ``tattoo_tcp`` are sites: frames without a body of their own, so they add
no mass. The panel is visual only (the needle enters it); bench and ground are solid.
"""

from __future__ import annotations

from xml.sax.saxutils import quoteattr

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from tattotronix.robot.description import Geometry, RobotDescription, rpy_matrix
from tattotronix.robot.urdf import fmt

__all__ = ["to_mjcf"]

# Collision classes: the arm collides with the world, never with itself.
ARM_CONTACT = 'contype="2" conaffinity="1"'
WORLD_CONTACT = 'contype="1" conaffinity="2"'
VISUAL_ONLY = 'contype="0" conaffinity="0"'


def _quat(rot: NDArray[np.float64]) -> str:
    return fmt(Rotation.from_matrix(rot).as_quat(scalar_first=True))


def _pose(xyz: NDArray[np.float64], rot: NDArray[np.float64]) -> str:
    if np.allclose(rot, np.eye(3), atol=0, rtol=0):
        return f'pos="{fmt(xyz)}"'
    return f'pos="{fmt(xyz)}" quat="{_quat(rot)}"'


def _geom(link: str, i: int, g: Geometry, indent: str) -> str:
    name = f'name="{link}_geom{i}"'
    if g.kind == "mesh":
        return (f'{indent}<geom {name} type="mesh" mesh="{link}" pos="{fmt(g.origin)}" '
                f'{ARM_CONTACT} rgba="0.85 0.85 0.82 1"/>\n')
    if g.kind == "box":
        return (f'{indent}<geom {name} type="box" size="{fmt(np.asarray(g.size) / 2)}" '
                f'pos="{fmt(g.origin)}" {ARM_CONTACT} rgba="0.85 0.85 0.82 1"/>\n')
    radius, length = (float(v) for v in g.size)
    return (f'{indent}<geom {name} type="cylinder" size="{radius!r} {length / 2!r}" '
            f'pos="{fmt(g.origin)}" {ARM_CONTACT} rgba="0.13 0.17 0.28 1"/>\n')


def to_mjcf(d: RobotDescription) -> str:
    """Generate the MJCF model of the arm on its bench, with the panel."""
    children: dict[str, list[tuple[str, NDArray[np.float64], NDArray[np.float64], str]]] = {}
    for j in d.joints:
        children.setdefault(j.parent, []).append(("joint", j.xyz, rpy_matrix(j.rpy), j.name))
    # Fixed frames: bodies (the pen) or sites (tool0, tcp), placed in their nearest body.
    for f in d.frames:
        children.setdefault(f.parent, []).append(("frame", f.xyz, rpy_matrix(f.rpy), f.name))
    joints = {j.name: j for j in d.joints}

    def emit(body: str, indent: str) -> list[str]:
        out: list[str] = []
        inert = d.inertials[body]
        ixx, ixy, ixz, iyy, iyz, izz = inert.six
        out.append(f'{indent}<inertial pos="{fmt(inert.com)}" mass="{inert.mass!r}" '
                   f'fullinertia="{fmt([ixx, iyy, izz, ixy, ixz, iyz])}"/>\n')
        for i, g in enumerate(d.geometry[body]):
            out.append(_geom(body, i, g, indent))
        out.extend(emit_children(body, np.zeros(3), np.eye(3), indent))
        return out

    def emit_children(name: str, p: NDArray[np.float64], rot: NDArray[np.float64],
                      indent: str) -> list[str]:
        """Children of link/frame ``name`` whose pose in the enclosing body is (p, rot)."""
        out: list[str] = []
        for kind, xyz, r, child in children.get(name, []):
            cp, crot = p + rot @ xyz, rot @ r
            if kind == "joint":
                j = joints[child]
                child_link = j.child
                out.append(f'{indent}<body name="{child_link}" {_pose(cp, crot)}>\n')
                out.append(f'{indent}  <joint name="{j.name}" type="hinge" axis="{fmt(j.axis)}" '
                           f'range="{j.lower!r} {j.upper!r}" damping="0" armature="0" '
                           f'frictionloss="0"/>\n')
                out.extend(emit(child_link, indent + "  "))
                out.append(f"{indent}</body>\n")
            elif child in d.inertials:  # a fixed body (the pen): welded, no joint
                out.append(f'{indent}<body name="{child}" {_pose(cp, crot)}>\n')
                out.extend(emit(child, indent + "  "))
                out.append(f"{indent}</body>\n")
            else:
                out.append(f'{indent}<site name="{child}" {_pose(cp, crot)} size="0.002"/>\n')
                out.extend(emit_children(child, cp, crot, indent))
        return out

    assets = "".join(
        f'    <mesh name="{link}" file={quoteattr(str(g.mesh))} scale="{fmt(g.size)}"/>\n'
        for link in d.links for g in d.geometry[link] if g.kind == "mesh"
    )
    bench_half = d.bench_size / 2
    base = d.links[0]
    body = "".join(emit(base, "      "))
    actuators = "".join(
        f'    <motor name="{j.name}" joint="{j.name}" gear="1" '
        f'ctrlrange="{-j.effort!r} {j.effort!r}"/>\n' for j in d.joints
    )
    return (
        f'<mujoco model="{d.name}">\n'
        "  <!-- GENERATED from conf/robot by the robot stage -->\n"
        '  <compiler angle="radian" inertiafromgeom="false" autolimits="true"/>\n'
        f'  <option gravity="0 0 {-d.gravity!r}" timestep="0.001"/>\n'
        + (f"  <asset>\n{assets}  </asset>\n" if assets else "")
        + "  <worldbody>\n"
        '    <light name="key" pos="0.3 -0.5 1.0" dir="-0.3 0.5 -1" directional="true"/>\n'
        f'    <geom name="ground" type="plane" size="2 2 0.01" '
        f'pos="0 0 {-float(d.bench_size[2])!r}" '
        f'{WORLD_CONTACT} rgba="0.6 0.6 0.6 1"/>\n'
        f'    <geom name="bench" type="box" size="{fmt(bench_half)}" '
        f'pos="0 0 {-float(bench_half[2])!r}" {WORLD_CONTACT} rgba="0.55 0.42 0.3 1"/>\n'
        f'    <geom name="panel" type="box" size="{fmt(d.panel_size / 2)}" '
        f'pos="{fmt(d.panel_centre)}" {VISUAL_ONLY} rgba="0.95 0.9 0.82 1"/>\n'
        f'    <body name="{base}" pos="0 0 0">\n{body}    </body>\n'
        "  </worldbody>\n"
        f"  <actuator>\n{actuators}  </actuator>\n"
        "</mujoco>\n"
    )
