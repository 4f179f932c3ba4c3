"""Synthetic needle paths for IK tests and benchmarks (no artwork, mask or toolpath stage).

Strokes are polylines in panel millimetres (u along +x, v along +y from the panel origin);
:func:`stroke_path` turns them into a toolpath like the toolpath stage's
(``xyz_m``, ``uvz_mm``, ``kind``): each stroke is resampled at ``step_mm`` and entered by
a plunge (clearance, approach start, surface depth) and left by a retract to clearance,
as in docs/original.md, "2.6 The 3-D path", with the same panel-to-arm mapping ("2.7 Panel
to arm frame, timing").
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from tattotronix.path.kinds import APPROACH, MARK, TRAVEL

__all__ = ["SyntheticPath", "logo_like_strokes", "raster_strokes", "stroke_path"]

Array = NDArray[np.float64]


@dataclass(frozen=True)
class SyntheticPath:
    """A needle path in the toolpath stage's format.

    Attributes:
        xyz_m: (N, 3) tip targets in the arm frame, m.
        uvz_mm: (N, 3) panel coordinates, mm (z relative to the surface).
        kind: (N,) int8, 0 travel, 1 mark, 2 approach.
        strokes: number of strokes (needle entries).
    """

    xyz_m: Array
    uvz_mm: Array
    kind: NDArray[np.int8]
    strokes: int

    def __len__(self) -> int:
        return len(self.kind)


def _resample(points: Array, step_mm: float) -> Array:
    p = np.asarray(points, dtype=float)
    seg = np.linalg.norm(np.diff(p, axis=0), axis=1)
    s = np.concatenate(([0.0], np.cumsum(seg)))
    if s[-1] <= step_mm:
        return p[[0, -1]]
    st = np.arange(0.0, s[-1], step_mm)
    return np.column_stack([np.interp(st, s, p[:, k]) for k in range(2)])


def stroke_path(
    strokes: Sequence[Array],
    *,
    step_mm: float = 0.15,
    clearance_mm: float = 8.0,
    plunge_mm: float = 1.5,
    approach_mm: float = 4.0,
    origin_m: Sequence[float] = (0.21, 0.0, 0.005),
) -> SyntheticPath:
    """Resample strokes and join them with plunges and retracts.

    Args:
        strokes: (k, 2) polylines, panel mm.
        step_mm: resampling step along a stroke, mm.
        clearance_mm: travel height above the surface, mm.
        plunge_mm: marking depth below the surface, mm.
        approach_mm: the last part of the plunge, at marking feed, mm.
        origin_m: the panel origin (its surface) in the arm frame, m.

    Returns:
        The path; arm-frame targets are ``origin + (u, v, z) / 1000``.
    """
    uvz: list[Array] = []
    kinds: list[Array] = []
    for st in strokes:
        pts = _resample(st, step_mm)
        (u0, v0), (u1, v1) = pts[0], pts[-1]
        uvz.append(np.array([[u0, v0, clearance_mm], [u0, v0, approach_mm - plunge_mm]]))
        kinds.append(np.array([TRAVEL, TRAVEL]))
        uvz.append(np.column_stack((pts, np.full(len(pts), -plunge_mm))))
        kinds.append(np.r_[APPROACH, np.full(len(pts) - 1, MARK)])
        uvz.append(np.array([[u1, v1, clearance_mm]]))
        kinds.append(np.array([TRAVEL]))
    uvz_mm = np.concatenate(uvz)
    kind = np.concatenate(kinds).astype(np.int8)
    xyz_m = np.asarray(origin_m, dtype=float) + uvz_mm / 1000.0
    return SyntheticPath(xyz_m=xyz_m, uvz_mm=uvz_mm, kind=kind, strokes=len(strokes))


def raster_strokes(
    u_mm: tuple[float, float], v_mm: tuple[float, float], rows: int
) -> list[Array]:
    """Straight rows along u, ``rows`` of them evenly over ``v_mm``, alternating direction."""
    out = []
    for i, v in enumerate(np.linspace(v_mm[0], v_mm[1], rows)):
        a, b = (u_mm[0], u_mm[1]) if i % 2 == 0 else (u_mm[1], u_mm[0])
        out.append(np.array([[a, v], [b, v]]))
    return out


def _circle(cu: float, cv: float, r: float, a0: float = 0.0, a1: float = 2 * np.pi) -> Array:
    t = np.linspace(a0, a1, max(8, int(abs(a1 - a0) * r / 0.05)))
    return np.column_stack((cu + r * np.cos(t), cv + r * np.sin(t)))


def logo_like_strokes(width_mm: float = 150.0, pitch_mm: float = 1.2) -> list[Array]:
    """A ROS-logo-like drawing centred on the panel origin, ``width_mm`` wide.

    Nine dots on a 3 x 3 grid (outline, then fill rows at ``pitch_mm``, each row its own
    stroke) on the left; two rings (two circles each, drawn as quarter arcs) on the right,
    reaching the +u edge. At 0.15 mm steps: 16 434 points and 151 needle entries.
    """
    s = width_mm / 150.0
    r_dot = 8.2 * s
    out: list[Array] = []
    for cv in (25.0 * s, 0.0, -25.0 * s):
        for cu in (-62.0 * s, -37.0 * s, -12.0 * s):
            out.append(_circle(cu, cv, r_dot))
            ys = np.arange(-r_dot + pitch_mm / 2, r_dot, pitch_mm)
            for i, y in enumerate(ys):
                half = np.sqrt(max(r_dot**2 - y**2, 0.0)) - 0.3
                a, b = (cu - half, cu + half) if i % 2 == 0 else (cu + half, cu - half)
                out.append(np.array([[a, cv + y], [b, cv + y]]))
    for cu in (22.0 * s, 57.0 * s):
        for r in (14.0 * s, 18.0 * s):
            for k in range(4):
                out.append(_circle(cu, 0.0, r, k * np.pi / 2, (k + 1) * np.pi / 2))
    return out
