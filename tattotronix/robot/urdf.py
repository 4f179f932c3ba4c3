"""URDF text from the robot description (for Pinocchio and PyBullet)."""

from __future__ import annotations

from xml.sax.saxutils import quoteattr

import numpy as np

from tattotronix.robot.description import Frame, Geometry, Inertial, RobotDescription

__all__ = ["to_urdf", "fmt"]


def fmt(values: object) -> str:
    """Space-separated floats with round-trip precision (``repr``)."""
    return " ".join(repr(float(v)) for v in np.ravel(values))  # type: ignore[call-overload]


def _inertial(i: Inertial) -> str:
    ixx, ixy, ixz, iyy, iyz, izz = i.six
    return (
        f'    <inertial>\n      <origin xyz="{fmt(i.com)}" rpy="0 0 0"/>\n'
        f'      <mass value="{i.mass!r}"/>\n'
        f'      <inertia ixx="{ixx!r}" ixy="{ixy!r}" ixz="{ixz!r}" iyy="{iyy!r}" '
        f'iyz="{iyz!r}" izz="{izz!r}"/>\n    </inertial>\n'
    )


# A frame with no body of its own must add no mass in any loader. PyBullet gives 1 kg to a
# link without an <inertial>, so massless frames carry an explicit zero one.
_ZERO_INERTIAL = (
    '    <inertial>\n      <origin xyz="0 0 0" rpy="0 0 0"/>\n      <mass value="0"/>\n'
    '      <inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/>\n    </inertial>\n'
)


def _shape(g: Geometry) -> str:
    if g.kind == "mesh":
        return f"<mesh filename={quoteattr(str(g.mesh))} scale=\"{fmt(g.size)}\"/>"
    if g.kind == "box":
        return f'<box size="{fmt(g.size)}"/>'
    radius, length = (float(v) for v in g.size)
    return f'<cylinder radius="{radius!r}" length="{length!r}"/>'


def _geometry(geoms: tuple[Geometry, ...]) -> str:
    out = []
    for tag in ("visual", "collision"):
        for g in geoms:
            out.append(
                f'    <{tag}>\n      <origin xyz="{fmt(g.origin)}" rpy="0 0 0"/>\n'
                f"      <geometry>{_shape(g)}</geometry>\n    </{tag}>\n"
            )
    return "".join(out)


def _fixed(name: str, f: Frame) -> str:
    return (
        f'  <joint name="{name}" type="fixed">\n    <parent link="{f.parent}"/>\n'
        f'    <child link="{f.name}"/>\n'
        f'    <origin xyz="{fmt(f.xyz)}" rpy="{fmt(f.rpy)}"/>\n  </joint>\n'
    )


def to_urdf(d: RobotDescription) -> str:
    """Generate the URDF: body links with inertials and geometry, revolute joints with
    limits (effort N m, velocity rad/s), and ``tool0`` / ``tattoo_tcp`` as massless links."""
    parts = [f'<?xml version="1.0"?>\n<!-- GENERATED from conf/robot by the robot stage -->\n'
             f'<robot name="{d.name}">\n']
    for link in d.links:
        parts.append(f'  <link name="{link}">\n{_inertial(d.inertials[link])}'
                     f"{_geometry(d.geometry[link])}  </link>\n")
    for f in d.frames:
        if f.name not in d.links:
            parts.append(f'  <link name="{f.name}">\n{_ZERO_INERTIAL}  </link>\n')
    for j in d.joints:
        parts.append(
            f'  <joint name="{j.name}" type="revolute">\n    <parent link="{j.parent}"/>\n'
            f'    <child link="{j.child}"/>\n    <origin xyz="{fmt(j.xyz)}" rpy="{fmt(j.rpy)}"/>\n'
            f'    <axis xyz="{fmt(j.axis)}"/>\n'
            f'    <limit lower="{j.lower!r}" upper="{j.upper!r}" effort="{j.effort!r}" '
            f'velocity="{j.velocity!r}"/>\n  </joint>\n'
        )
    names = {"tool0": "tool_mount_to_tool0", "tattoo_pen_link": "tool0_to_tattoo_pen",
             "tattoo_tcp": "tattoo_pen_to_tcp"}
    for f in d.frames:
        parts.append(_fixed(names.get(f.name, f"{f.parent}_to_{f.name}"), f))
    parts.append("</robot>\n")
    return "".join(parts)
