"""A needle path planned in the design's plane, carried onto a curved surface (issue 33).

The toolpath is planned in the design plane as on the panel (``u``, ``v`` mm, ``z`` the
height over the surface: negative in the skin). :func:`carry_path` lays it on the surface
through a :class:`~tattotronix.surface.chart.Chart`: a point goes to the surface point of
its ``(u, v)`` moved ``z`` along the surface's outward normal there, so the marking depth
and the clearance are measured along the normal, and the needle's axis at every point is
the inward normal. Then:

* every stroke (a run of marking points) is resampled at equal arc length on the surface,
  with as many points as it had (the chart is an isometry, or within its distortion
  bound of one, so the steps change by at most that much);
* every step is split in the design plane until its chord is within ``sag_mm`` of the
  carried midpoint, so the straight moves between points neither cut into the skin
  nor lose clearance over its curvature (travel between strokes is long), and no longer
  than ``max_step_mm`` (the time law then splits none with one needle axis).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from tattotronix.errors import TattotronixError
from tattotronix.path.kinds import MARK
from tattotronix.surface.chart import Chart

__all__ = ["SkinPath", "carry_path"]

Array = NDArray[np.float64]
#: rounds of splitting before a step that still sags is an error (2^12 pieces)
_MAX_SPLITS = 12


@dataclass(frozen=True)
class SkinPath:
    """A needle path on a curved surface.

    Attributes:
        xyz_mm: (N, 3) needle tip positions, mm (the surface's frame).
        axis: (N, 3) unit needle axes, pointing into the skin (the inward normal).
        kind: (N,) int8, 0 travel, 1 mark, 2 approach (as on the panel).
        uvz_mm: (N, 3) each point's design coordinates and height over the surface
            along its normal (negative: the marking depth).
    """

    xyz_mm: Array
    axis: Array
    kind: NDArray[np.int8]
    uvz_mm: Array


def _carry(chart: Chart, uvz: Array) -> tuple[Array, Array]:
    on = chart.to_surface(uvz[:, :2])
    return on.xyz + uvz[:, 2:3] * on.normal, -on.normal


def _resample_strokes(chart: Chart, uvz: Array, kind: NDArray[np.int8]) -> Array:
    """Each run of marking points at equal arc length on the surface (as many points;
    its ends kept)."""
    out = uvz.copy()
    mark = kind == MARK
    edges = np.flatnonzero(np.diff(np.concatenate(([0], mark.astype(np.int8), [0]))))
    for start, stop in zip(edges[::2], edges[1::2], strict=True):
        lo = max(int(start) - 1, 0)  # the stroke starts where its approach lands
        run = slice(lo, int(stop))
        pts = uvz[run]
        if len(pts) < 3:
            continue
        xyz, _ = _carry(chart, pts)
        s = np.concatenate(([0.0], np.cumsum(np.linalg.norm(np.diff(xyz, axis=0), axis=1))))
        if s[-1] <= 0:
            continue
        target = np.linspace(0.0, s[-1], len(pts))
        # arc length on the surface against the design's own arc length
        d = np.concatenate(([0.0], np.cumsum(np.linalg.norm(np.diff(pts[:, :2], axis=0),
                                                            axis=1))))
        at = np.interp(target, s, d)
        for k in range(3):
            out[run, k] = np.interp(at, d, pts[:, k])
    return out


def carry_path(uvz_mm: Array, kind: NDArray[np.int8], chart: Chart, sag_mm: float = 0.01,
               max_step_mm: float = np.inf) -> SkinPath:
    """Carry a design-plane needle path onto the surface of ``chart`` (module docstring).

    Args:
        uvz_mm: (N, 3) the path in the design plane, z over the surface (mm).
        kind: (N,) its points' kinds.
        chart: the design's chart on the surface.
        sag_mm: the most a straight step may stray from the carried path.
        max_step_mm: the longest step (the time law's densify step: a longer one would be
            split by IK with one needle axis, not the surface's).

    Raises:
        TattotronixError: a point the chart does not cover (naming it), or a step that
            still sags after :data:`_MAX_SPLITS` rounds.
    """
    uvz = np.asarray(uvz_mm, dtype=np.float64)
    kinds = np.asarray(kind, dtype=np.int8)
    if uvz.ndim != 2 or uvz.shape[1] != 3 or len(uvz) != len(kinds) or len(uvz) < 2:
        raise TattotronixError(f"a path needs (N, 3) points and N kinds, N >= 2; got "
                               f"{uvz.shape} and {kinds.shape}")
    if not sag_mm > 0 or not max_step_mm > 0:
        raise TattotronixError(f"sag_mm={sag_mm}, max_step_mm={max_step_mm}: give positive "
                               "lengths in mm")
    uvz = _resample_strokes(chart, uvz, kinds)
    xyz, axis = _carry(chart, uvz)
    for _ in range(_MAX_SPLITS):
        mid = 0.5 * (uvz[1:] + uvz[:-1])
        mid_xyz, _ = _carry(chart, mid)
        sag = np.linalg.norm(mid_xyz - 0.5 * (xyz[1:] + xyz[:-1]), axis=1)
        step = np.linalg.norm(np.diff(xyz, axis=0), axis=1)
        split = np.flatnonzero((sag > sag_mm) | (step > max_step_mm))
        if split.size == 0:
            return SkinPath(xyz, axis, kinds, uvz)
        at = split + 1  # insert each midpoint before its step's far end (its kind)
        uvz = np.insert(uvz, at, mid[split], axis=0)
        kinds = np.insert(kinds, at, kinds[split + 1])
        xyz, axis = _carry(chart, uvz)
    raise TattotronixError(f"the path still strays over {sag_mm} mm from the surface's "
                           f"shape after {_MAX_SPLITS} rounds of splitting its steps")
