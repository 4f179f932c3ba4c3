"""The forearm phantom: a tapered elliptic cylinder, and its exact development.

In the limb's own frame (mm) the axis is ``+x`` from the elbow end (``x = 0``) to the
wrist end (``x = length``), and the section at ``x`` is the ellipse of semi-axes
``a(x)`` (along ``y``, half the width) and ``b(x) = depth_ratio a(x)`` (along ``z``, half
the thickness), ``a`` varying linearly from the elbow's to the wrist's. Both semi-axes
shrink in the same ratio, so the surface is a cone over an ellipse (a cylinder when the
widths are equal): it is developable, and :class:`ConeChart` unrolls it exactly.

A point is ``X(x, theta) = (x, a(x) cos theta, b(x) sin theta)``: ``theta = 90 deg`` is
the top of the limb (``+z``), and ``theta`` increases counter-clockwise looking from the
wrist towards the elbow. With the apex ``A`` where ``a`` vanishes, ``X = A + rho d(theta)``
(``d`` a unit direction, ``rho`` the distance from the apex), whose metric is
``d rho^2 + rho^2 |d'|^2 d theta^2``: in the plane, polar coordinates ``(rho, phi)`` with
``phi = int |d'(theta)| d theta`` lay the surface down with no distortion. A cylinder
unrolls to ``(x, s(theta))``, ``s`` the section's arc length.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from tattotronix.errors import TattotronixError
from tattotronix.surface.chart import Chart, SurfacePoints

__all__ = ["ConeChart", "EllipticCone"]

Array = NDArray[np.float64]
#: samples of theta over one turn for the development's angle (its error ~1e-9 mm)
_TURN_SAMPLES = 20_001


@dataclass(frozen=True)
class EllipticCone:
    """A tapered elliptic cylinder (the forearm phantom), posed on the bench.

    Attributes:
        length_mm: from the elbow end to the wrist end.
        elbow_width_mm, wrist_width_mm: the section's width (``2 a``) at each end.
        depth_ratio: thickness over width (``b / a``), the same at both ends.
        pose: 4x4 transform (mm) from the limb's frame to the bench's (the arm's).
    """

    length_mm: float
    elbow_width_mm: float
    wrist_width_mm: float
    depth_ratio: float
    pose: Array = field(default_factory=lambda: np.eye(4))

    def __post_init__(self) -> None:
        for name in ("length_mm", "elbow_width_mm", "wrist_width_mm", "depth_ratio"):
            v = float(getattr(self, name))
            if not (math.isfinite(v) and v > 0):
                raise TattotronixError(f"the phantom's {name} must be a positive number, "
                                       f"got {v}")
        pose = np.asarray(self.pose, dtype=np.float64)
        if pose.shape != (4, 4) or not np.allclose(pose[:3, :3] @ pose[:3, :3].T, np.eye(3),
                                                   atol=1e-9):
            raise TattotronixError("the phantom's pose must be a 4x4 rigid transform")

    @property
    def a0(self) -> float:
        return self.elbow_width_mm / 2

    @property
    def slope(self) -> float:
        """``da/dx``: the semi-axis's change per mm along the axis (0: a cylinder)."""
        return (self.wrist_width_mm - self.elbow_width_mm) / 2 / self.length_mm

    def semi_axes(self, x: Array) -> tuple[Array, Array]:
        a = self.a0 + self.slope * np.asarray(x, dtype=np.float64)
        return a, self.depth_ratio * a

    def point(self, x: Array, theta: Array) -> Array:
        """(N, 3) points ``X(x, theta)`` in the limb's frame, mm."""
        a, b = self.semi_axes(x)
        return np.column_stack([np.asarray(x, dtype=np.float64) * np.ones_like(a),
                                a * np.cos(theta), b * np.sin(theta)])

    def normal(self, x: Array, theta: Array) -> Array:
        """(N, 3) unit outward normals at ``X(x, theta)``, in the limb's frame."""
        a, b = self.semi_axes(x)
        th = np.asarray(theta, dtype=np.float64) * np.ones_like(a)
        r = self.depth_ratio
        # X_x = (1, a' cos, b' sin), X_theta = (0, -a sin, b cos); X_theta x X_x points out
        xx = np.column_stack([np.ones_like(a), self.slope * np.cos(th),
                              r * self.slope * np.sin(th)])
        xt = np.column_stack([np.zeros_like(a), -a * np.sin(th), b * np.cos(th)])
        n = np.cross(xt, xx)
        return n / np.linalg.norm(n, axis=1, keepdims=True)

    def mesh(self, n_along: int = 80, n_around: int = 160) -> tuple[Array, NDArray[np.int64]]:
        """The phantom as a closed triangle mesh, posed (mm), wound outward: ``n_along``
        sections of ``n_around`` points (vertex ``i * n_around + j`` is section ``i``'s
        ``j``-th, at ``theta = 2 pi j / n_around``), then the two ends' centres, each end
        closed by a fan."""
        xs = np.linspace(0.0, self.length_mm, n_along)
        ts = np.linspace(0.0, 2 * np.pi, n_around, endpoint=False)
        xg, tg = np.meshgrid(xs, ts, indexing="ij")
        pts = np.vstack([self.point(xg.ravel(), tg.ravel()),
                         [[0.0, 0.0, 0.0], [self.length_mm, 0.0, 0.0]]])
        idx = np.arange(n_along * n_around).reshape(n_along, n_around)
        nxt = np.roll(idx, -1, axis=1)
        a, b = idx[:-1].ravel(), nxt[:-1].ravel()
        c, d = idx[1:].ravel(), nxt[1:].ravel()
        c0, c1 = n_along * n_around, n_along * n_around + 1
        faces = np.concatenate([
            np.column_stack([a, d, c]), np.column_stack([a, b, d]),
            np.column_stack([np.full(n_around, c0), nxt[0], idx[0]]),
            np.column_stack([np.full(n_around, c1), idx[-1], nxt[-1]])]).astype(np.int64)
        return self.posed(pts), faces

    def posed(self, pts: Array, vectors: bool = False) -> Array:
        """Limb-frame points (or directions) in the bench's frame."""
        rot, t = self.pose[:3, :3], self.pose[:3, 3]
        return pts @ rot.T + (0.0 if vectors else t)

    def chart(self, at_x_mm: float, at_theta_deg: float, rotate_deg: float = 0.0
              ) -> ConeChart:
        """The chart of a design placed at ``X(at_x_mm, at_theta_deg)``, turned by
        ``rotate_deg`` counter-clockwise seen from outside (0: the design's ``u`` along the
        limb towards the wrist, ``v`` around it, so that ``u``, ``v`` and the outward
        normal are right-handed, as ``u``, ``v`` and up are on the panel: the design is
        seen unmirrored on the skin).

        Raises:
            TattotronixError: a placement point off the phantom.
        """
        if not (0.0 <= at_x_mm <= self.length_mm):
            raise TattotronixError(
                f"the design's placement point is {at_x_mm:.1f} mm along the phantom's "
                f"axis, off its 0..{self.length_mm:g} mm")
        return ConeChart(self, float(at_x_mm), math.radians(at_theta_deg),
                         math.radians(rotate_deg))


class ConeChart(Chart):
    """The exact (isometric) chart of a design on an :class:`EllipticCone`."""

    def __init__(self, cone: EllipticCone, x0: float, theta0: float, rot: float):
        self.cone = cone
        self.x0, self.theta0, self.rot = x0, theta0, rot
        c = cone.slope
        self.conical = abs(c) > 1e-12
        # one turn of theta centred on the placement: the development along it
        self.theta = np.linspace(theta0 - math.pi, theta0 + math.pi, _TURN_SAMPLES)
        speed = self._angular_speed(self.theta)
        steps = 0.5 * (speed[1:] + speed[:-1]) * np.diff(self.theta)
        self.phi = np.concatenate(([0.0], np.cumsum(steps)))
        self.phi -= np.interp(theta0, self.theta, self.phi)  # 0 at the placement
        if self.conical:
            self.x_apex = -cone.a0 / c  # where a(x) = 0
            self.rho0 = self._rho(np.array([x0]), np.array([theta0]))[0]
        cr, sr = math.cos(rot), math.sin(rot)
        self._turn = np.array([[cr, -sr], [sr, cr]])

    def _g(self, theta: Array) -> Array:
        """``|X - A| / |x_apex - x|`` along the generator at ``theta``."""
        c, r = abs(self.cone.slope), self.cone.depth_ratio
        return np.sqrt(1.0 + c * c * (np.cos(theta) ** 2 + r * r * np.sin(theta) ** 2))

    def _rho(self, x: Array, theta: Array) -> Array:
        return np.abs(self.x_apex - x) * self._g(theta)

    def _angular_speed(self, theta: Array) -> Array:
        """``|d'(theta)|`` of a cone's unit generator direction, or a cylinder's section
        arc-length rate ``|E'(theta)|``."""
        r = self.cone.depth_ratio
        if not self.conical:
            a = self.cone.a0
            return a * np.sqrt(np.sin(theta) ** 2 + r * r * np.cos(theta) ** 2)
        c = abs(self.cone.slope)
        w2 = 1.0 + c * c * (np.cos(theta) ** 2 + r * r * np.sin(theta) ** 2)
        dw2 = c * c * (np.sin(theta) ** 2 + r * r * np.cos(theta) ** 2)
        wdw = c * c * (r * r - 1.0) * np.sin(theta) * np.cos(theta)
        return np.sqrt(np.maximum(dw2 * w2 - wdw * wdw, 0.0)) / w2

    def _developed(self, uv_mm: Array) -> Array:
        """Design points in the development's coordinates: ``(x, s)`` for a cylinder,
        ``(rho, phi)`` for a cone."""
        uv = np.asarray(uv_mm, dtype=np.float64).reshape(-1, 2) @ self._turn.T
        # +v is towards decreasing theta: X_x, -X_theta and the outward normal
        # X_theta x X_x are right-handed
        along, around = uv[:, 0], -uv[:, 1]
        if not self.conical:
            return np.column_stack([self.x0 + along, around])
        # the development in the plane: the placement at (rho0, 0); towards the wrist is
        # towards the apex when the limb narrows (rho falls); theta grows with phi
        towards = -1.0 if self.x_apex > self.x0 else 1.0
        px = self.rho0 + towards * along
        py = around
        return np.column_stack([np.hypot(px, py), np.arctan2(py, px)])

    def to_surface(self, uv_mm: Array) -> SurfacePoints:
        dev = self._developed(uv_mm)
        lo, hi = float(self.phi[0]), float(self.phi[-1])
        if self.conical:
            rho, ang = dev[:, 0], dev[:, 1]
        else:
            ang = dev[:, 1]
        out = (ang < lo) | (ang > hi)
        if out.any():
            i = int(np.flatnonzero(out)[0])
            raise TattotronixError(
                f"design point {np.asarray(uv_mm).reshape(-1, 2)[i].round(1).tolist()} mm "
                "reaches past the far side of the phantom from the placement: make the "
                "design narrower across the limb")
        theta = np.interp(ang, self.phi, self.theta)
        if self.conical:
            x = self.x_apex - np.sign(self.x_apex - self.x0) * rho / self._g(theta)
        else:
            x = dev[:, 0]
        off = (x < -1e-9) | (x > self.cone.length_mm + 1e-9)
        if off.any():
            i = int(np.flatnonzero(off)[0])
            raise TattotronixError(
                f"design point {np.asarray(uv_mm).reshape(-1, 2)[i].round(1).tolist()} mm "
                f"falls {x[i]:.1f} mm along the phantom's axis, off its "
                f"0..{self.cone.length_mm:g} mm: move the design along the limb or make "
                "it smaller")
        cone = self.cone
        return SurfacePoints(cone.posed(cone.point(x, theta)),
                             cone.posed(cone.normal(x, theta), vectors=True))
