"""A chart: the map from a design's plane onto a curved work surface, and its distortion.

A design is planned in its own plane, in millimetres measured on the skin (``u``, ``v``,
the origin at the placement point). A :class:`Chart` carries each design point onto the
surface: its 3-D position and the surface's unit outward normal (mm, in the surface's
frame: the arm's, once the surface is posed on the bench). :func:`distortion` measures how
far the map is from an isometry over a design's footprint, the same way for every chart:
at samples over the footprint, the two singular values ``s1 >= s2`` of the map's
Jacobian give the area distortion ``|s1 s2 - 1|`` and the angle distortion
``s1 / s2 - 1`` (both 0 for an isometry).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from tattotronix.errors import TattotronixError

__all__ = ["LOCATE_TOL_MM", "Chart", "Distortion", "SurfacePoints", "distortion"]

#: how close :meth:`Chart.locate` must carry each point back to itself, mm
LOCATE_TOL_MM = 1e-6

Array = NDArray[np.float64]


@dataclass(frozen=True)
class SurfacePoints:
    """Design points carried onto the surface.

    Attributes:
        xyz: (N, 3) positions on the surface, mm.
        normal: (N, 3) unit outward normals (away from the limb: the needle goes in along
            ``-normal``).
    """

    xyz: Array
    normal: Array


class Chart(ABC):
    """A map from the design plane (``u``, ``v`` mm, the origin at the placement point)
    onto a surface."""

    @abstractmethod
    def to_surface(self, uv_mm: Array) -> SurfacePoints:
        """The surface points of (N, 2) design points, mm.

        Raises:
            TattotronixError: a point the chart does not cover (off the surface, or past
                the patch a mesh chart was made on), naming it.
        """

    def locate(self, xyz_mm: Array, guess_uv_mm: Array, rounds: int = 12,
               tol_mm: float = 1e-9) -> tuple[Array, Array]:
        """The design point and height of 3-D points near the surface: the inverse of the
        carry ``(u, v, h) -> X(u, v) + h n(u, v)`` (:mod:`tattotronix.path.onskin`), so a
        simulated needle tip is put back where the plan would have put it.

        Newton's method on the three equations from ``guess_uv_mm`` (the planned point
        each tip follows; the height's guess along its normal), the Jacobian by central
        differences. It converges while the height is within the surface's radius of
        curvature, as a needle's is.

        Args:
            xyz_mm: (N, 3) points, mm (the surface's frame).
            guess_uv_mm: (N, 2) design points near each one's answer.
            rounds: the most Newton steps.
            tol_mm: a step below this ends the rounds.

        Returns:
            (N, 2) design points, mm, and (N,) heights along the outward normal, mm
            (negative: in the skin).

        Raises:
            TattotronixError: a guess per point missing, a design point the chart does not
                cover (:meth:`to_surface`'s message), or a point Newton's method did not
                carry back to within :data:`LOCATE_TOL_MM` (naming it: too far from the
                surface, or from its guess).
        """
        p = np.asarray(xyz_mm, dtype=np.float64).reshape(-1, 3)
        uv = np.array(guess_uv_mm, dtype=np.float64).reshape(-1, 2)
        if len(uv) != len(p):
            raise TattotronixError(f"{len(p)} points and {len(uv)} guesses: give one each")
        on = self.to_surface(uv)
        height = np.einsum("nk,nk->n", p - on.xyz, on.normal)
        d = 1e-3
        probe = np.array([[d, 0.0], [-d, 0.0], [0.0, d], [0.0, -d]])
        for _ in range(rounds):
            at = self.to_surface(np.concatenate([uv] + [uv + e for e in probe]))
            g = (at.xyz + np.tile(height, 5)[:, None] * at.normal).reshape(5, len(uv), 3)
            n0 = at.normal[:len(uv)]
            jac = np.stack([(g[1] - g[2]) / (2 * d), (g[3] - g[4]) / (2 * d), n0],
                           axis=2)  # (N, 3, 3)
            step = np.linalg.solve(jac, (p - g[0])[..., None])[..., 0]
            uv += step[:, :2]
            height += step[:, 2]
            if float(np.abs(step).max(initial=0.0)) < tol_mm:
                break
        on = self.to_surface(uv)
        miss = np.linalg.norm(on.xyz + height[:, None] * on.normal - p, axis=1)
        if len(miss) and float(miss.max()) > LOCATE_TOL_MM:
            i = int(np.argmax(miss))
            raise TattotronixError(
                f"the point {p[i].round(3).tolist()} mm could not be put back on the design "
                f"(the carry misses it by {miss[i]:.3g} mm after {rounds} rounds): it is too "
                "far from the surface, or from the planned point it was located from")
        return uv, height


@dataclass(frozen=True)
class Distortion:
    """How far a chart is from an isometry over a design's footprint (0: none).

    Attributes:
        area_worst, area_mean: ``|s1 s2 - 1|`` over the footprint's samples.
        angle_worst, angle_mean: ``s1 / s2 - 1``, the same way.
        worst_at_mm: the design point (u, v) where either is worst.
        samples: how many points it was measured at.
    """

    area_worst: float
    area_mean: float
    angle_worst: float
    angle_mean: float
    worst_at_mm: tuple[float, float]
    samples: int

    def as_dict(self) -> dict[str, float | int | list[float]]:
        """The figures, for metrics (percent, rounded)."""
        return {"area_worst_pct": round(100 * self.area_worst, 4),
                "area_mean_pct": round(100 * self.area_mean, 4),
                "angle_worst_pct": round(100 * self.angle_worst, 4),
                "angle_mean_pct": round(100 * self.angle_mean, 4),
                "worst_at_mm": [round(c, 2) for c in self.worst_at_mm],
                "samples": self.samples}

    def check(self, bound: float) -> None:
        """Refuse a placement whose worst distortion passes ``bound`` (a fraction).

        Raises:
            TattotronixError: naming the worst figure and where it is in the design.
        """
        worst = max(self.area_worst, self.angle_worst)
        if worst > bound:
            kind = "area" if self.area_worst >= self.angle_worst else "angle"
            u, v = self.worst_at_mm
            raise TattotronixError(
                f"the design would be distorted by {100 * worst:.2f} % ({kind}) on the "
                f"surface at design ({u:.1f}, {v:.1f}) mm, over the bound of "
                f"{100 * bound:.2f} %: place it where the surface is flatter, make it "
                "smaller, or raise the bound")


def distortion(chart: Chart, box_mm: tuple[float, float, float, float],
               step_mm: float = 1.0) -> Distortion:
    """The chart's distortion over the design box ``(u0, v0, u1, v1)`` mm: its Jacobian
    by central differences (a hundredth of ``step_mm``) at the centres of a grid of
    ``step_mm`` cells, so the surface's curvature between the samples does not count.

    Raises:
        TattotronixError: an empty box, or one the chart does not cover.
    """
    u0, v0, u1, v1 = box_mm
    if not (u1 > u0 and v1 > v0 and step_mm > 0):
        raise TattotronixError(f"an empty footprint {box_mm} (or a step of {step_mm} mm)")
    nu = max(1, int(np.ceil((u1 - u0) / step_mm)))
    nv = max(1, int(np.ceil((v1 - v0) / step_mm)))
    du, dv = (u1 - u0) / nu, (v1 - v0) / nv
    uu, vv = np.meshgrid(u0 + du * (np.arange(nu) + 0.5), v0 + dv * (np.arange(nv) + 0.5))
    centre = np.column_stack([uu.ravel(), vv.ravel()])
    h = step_mm / 100
    probes = np.concatenate([centre + [h, 0.0], centre - [h, 0.0],
                             centre + [0.0, h], centre - [0.0, h]])
    xyz = chart.to_surface(probes).xyz.reshape(4, len(centre), 3)
    jac = np.stack([xyz[0] - xyz[1], xyz[2] - xyz[3]], axis=2) / (2 * h)  # (N, 3, 2)
    s = np.linalg.svd(jac, compute_uv=False)
    area_d = np.abs(s[:, 0] * s[:, 1] - 1.0)
    angle_d = s[:, 0] / np.maximum(s[:, 1], 1e-12) - 1.0
    worst = int(np.argmax(np.maximum(area_d, angle_d)))
    return Distortion(float(area_d.max()), float(area_d.mean()), float(angle_d.max()),
                      float(angle_d.mean()),
                      (float(centre[worst, 0]), float(centre[worst, 1])), len(centre))
