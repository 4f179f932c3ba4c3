"""The joint-space needle path the time law runs along (the ``ik`` stage's output).

A path is a polyline of ``N`` points: joint angles ``q`` (rad), the FK tip ``tcp`` of each
(m, arm frame), a point kind (0 travel, 1 mark, 2 approach; docs/original.md, "2.6 The
3-D path") and the panel coordinates ``uvz_mm`` (for messages). Segment ``i -> i+1`` is
*marking* when both ends are mark points, *approach* when either end is an approach
point, and travel otherwise (docs/original.md, "2.7 Panel to arm frame, timing"), exactly
as the toolpath stage times it.

The path parameter ``s`` is the tip's arc length along the chords between consecutive
``tcp`` (m), so a path speed ``ds/dt`` is a tip speed and a feed (mm/s) caps it directly.

Travel chords are long (up to ~50 mm between strokes, 5.5 and 9.5 mm for plunge and
retract), and a chord sampled only at its two ends cannot carry an acceleration ramp, nor
can joints interpolated between two clearance points keep the tip inside the clearance
band. :func:`densify` therefore splits every chord longer than ``max_step_m`` into equal
steps along the straight Cartesian line and solves IK for the inserted points (the needle
kept on its axis), warm-started from the chord's own start so they stay on its branch.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from tattotronix.errors import TattotronixError
from tattotronix.io.artifacts import IkRecord
from tattotronix.kinematics import Chain, IkOptions, solve_path
from tattotronix.path.kinds import APPROACH, MARK, TRAVEL

#: a bend this share under the corner radius is still held at the feed: the hatch's round
#: turns (:mod:`tattotronix.path.turns`) are drawn at exactly half the pitch, and their
#: radius read back from the IK's tip points is a hair under it
CORNER_RADIUS_TOL = 0.02

__all__ = [
    "APPROACH",
    "CORNER_RADIUS_TOL",
    "MARK",
    "TRAVEL",
    "JointPath",
    "corner_points",
    "cusp_points",
    "densify",
    "marking_reversals",
    "path_derivatives",
    "segment_kinds",
    "spaced",
    "turn_radii",
]

Array = NDArray[np.float64]


@dataclass(frozen=True)
class JointPath:
    """A needle path in joint space.

    Attributes:
        joints: joint names, base outward.
        q: (N, n) joint angles, rad.
        tcp: (N, 3) FK tip of ``q`` in the arm frame, m.
        kind: (N,) int8 point kinds: 0 travel, 1 mark, 2 approach.
        uvz_mm: (N, 3) panel coordinates, mm (z relative to the surface); lengths and
            messages use them.
        source: (N,) index of each point in the IK output, -1 for points :func:`densify`
            inserted.
    """

    joints: tuple[str, ...]
    q: Array
    tcp: Array
    kind: NDArray[np.int8]
    uvz_mm: Array
    source: NDArray[np.int64]

    def __post_init__(self) -> None:
        n_pts = len(self.q)
        if self.q.ndim != 2 or self.q.shape[1] != len(self.joints):
            raise TattotronixError(f"q must be (N, {len(self.joints)}) rad, got {self.q.shape}")
        for name, arr, shape in (("tcp", self.tcp, (n_pts, 3)), ("kind", self.kind, (n_pts,)),
                                 ("uvz_mm", self.uvz_mm, (n_pts, 3)),
                                 ("source", self.source, (n_pts,))):
            if arr.shape != shape:
                raise TattotronixError(f"path {name} must be {shape}, got {arr.shape}")
        if not (np.all(np.isfinite(self.q)) and np.all(np.isfinite(self.tcp))):
            raise TattotronixError("the path has non-finite joint angles or tip positions")
        bad = np.setdiff1d(np.unique(self.kind), [TRAVEL, MARK, APPROACH])
        if bad.size:
            raise TattotronixError(f"unknown point kinds {bad.tolist()} (0 travel, 1 mark, "
                                   "2 approach)")

    @classmethod
    def from_arrays(cls, joints: tuple[str, ...] | list[str], q: ArrayLike, tcp: ArrayLike,
                    kind: ArrayLike, uvz_mm: ArrayLike | None = None) -> JointPath:
        """Build a path from arrays; ``source`` is 0..N-1.

        ``uvz_mm`` defaults to the tip in arm-frame millimetres (the same lengths).
        """
        qa = np.asarray(q, dtype=np.float64)
        tip = np.asarray(tcp, dtype=np.float64)
        uvz = tip * 1000.0 if uvz_mm is None else np.asarray(uvz_mm, dtype=np.float64)
        return cls(tuple(str(j) for j in joints), qa, tip, np.asarray(kind, dtype=np.int8),
                   uvz, np.arange(len(qa), dtype=np.int64))

    @classmethod
    def from_npz(cls, file: str | Path) -> JointPath:
        """Load the ``ik`` stage's ``data/ik/<name>.npz``
        (:class:`tattotronix.io.artifacts.IkRecord`).

        Raises:
            TattotronixError: a key is missing or the file is unreadable (the message names
                the 'ik' stage).
        """
        r = IkRecord.load(file)
        return cls.from_arrays(r.joints, r.q, r.tcp, r.kind, r.uvz_mm)

    def __len__(self) -> int:
        return len(self.kind)

    def slice(self, start: int, stop: int) -> JointPath:
        """Points ``start`` to ``stop - 1`` (their ``source`` kept)."""
        return JointPath(self.joints, self.q[start:stop], self.tcp[start:stop],
                         self.kind[start:stop], self.uvz_mm[start:stop],
                         self.source[start:stop])

    def hops(self, clearance_mm: float) -> NDArray[np.bool_]:
        """(N-1,) chords that are travel between strokes: both ends travel points at the
        clearance height (``uvz_mm`` z), at different panel points."""
        k, z = self.kind, self.uvz_mm[:, 2]
        up = (k == TRAVEL) & (z >= clearance_mm - 1e-6)
        apart = np.linalg.norm(np.diff(self.uvz_mm[:, :2], axis=0), axis=1) > 1e-6
        return up[:-1] & up[1:] & apart

    def segment_lengths(self) -> Array:
        """(N-1,) tip chord lengths, m."""
        return np.linalg.norm(np.diff(self.tcp, axis=0), axis=1)

    def arc_length(self) -> Array:
        """(N,) tip arc length from the first point, m (the path parameter ``s``)."""
        return np.concatenate(([0.0], np.cumsum(self.segment_lengths())))

    def segment_kinds(self) -> NDArray[np.int8]:
        """(N-1,) segment kinds: 1 marking, 2 approach, 0 travel (docs/original.md, "2.7
        Panel to arm frame, timing")."""
        return segment_kinds(self.kind)

    def marked(self) -> NDArray[np.bool_]:
        """(N,) ``marked[i] = kind[i-1] == 1 and kind[i] == 1``; ``marked[0] = False``."""
        out = np.zeros(len(self.kind), bool)
        out[1:] = (self.kind[:-1] == MARK) & (self.kind[1:] == MARK)
        return out

    def entries(self) -> int:
        """Needle entries: travel to non-travel transitions, +1 if the path starts down."""
        k = self.kind
        if len(k) == 0:
            return 0
        return int(((k[:-1] == TRAVEL) & (k[1:] != TRAVEL)).sum()) + int(k[0] != TRAVEL)

    def marked_length_m(self) -> float:
        """Length of the marking segments (both ends mark points), m, measured on the
        panel coordinates as the toolpath stage measures ``marked_mm``."""
        seg = np.linalg.norm(np.diff(self.uvz_mm, axis=0), axis=1)
        return float(seg[self.segment_kinds() == MARK].sum()) / 1000.0


def segment_kinds(kind: NDArray[np.int8]) -> NDArray[np.int8]:
    """(N-1,) segment kinds from point kinds: 1 marking (both ends mark points), 2 approach
    (either end an approach point), 0 travel (docs/original.md, "2.7 Panel to arm frame,
    timing")."""
    k = np.asarray(kind)
    seg = np.zeros(max(len(k) - 1, 0), np.int8)
    seg[(k[:-1] == MARK) & (k[1:] == MARK)] = MARK
    seg[(k[:-1] == APPROACH) | (k[1:] == APPROACH)] = APPROACH
    return seg


#: a joint has reversed while marking once it has moved back by more than this from the
#: furthest it went (rad; 0.006 deg: under any servo's play or dead band, above the IK's
#: rounding, so a still joint's jitter is not counted)
REVERSAL_MIN_RAD = 1e-4


def marking_reversals(q: ArrayLike, kind: ArrayLike,
                      min_rad: float = REVERSAL_MIN_RAD) -> NDArray[np.int64]:
    """(n,) how often each joint turns back while the needle marks (issue 34: backlash
    bites there, where no lift lets the gears settle).

    Each stretch of marking segments is followed on its own: a joint's direction is set
    by its first move of more than ``min_rad``, and a reversal counted each time it then
    moves back by more than ``min_rad`` from the furthest point it reached.

    Args:
        q: (N, n) joint angles of the path's points, rad.
        kind: (N,) point kinds (0 travel, 1 mark, 2 approach).
        min_rad: the hysteresis, rad.
    """
    qa = np.asarray(q, dtype=np.float64)
    seg = segment_kinds(np.asarray(kind)) == MARK
    counts = np.zeros(qa.shape[1], np.int64)
    edges = np.flatnonzero(np.diff(np.r_[0, seg.astype(np.int8), 0]))
    for lo, hi in zip(edges[::2], edges[1::2], strict=True):  # segments lo..hi-1
        run = qa[lo:hi + 1]
        for j in range(qa.shape[1]):
            x = run[:, j]
            if np.ptp(x) <= min_rad:
                continue
            direction, extreme = 0, float(x[0])
            for v in x[1:].tolist():
                if direction == 0:
                    if abs(v - extreme) > min_rad:
                        direction, extreme = (1 if v > extreme else -1), v
                elif direction * (v - extreme) > 0:
                    extreme = v  # further the same way
                elif direction * (extreme - v) > min_rad:
                    counts[j] += 1
                    direction, extreme = -direction, v
    return counts


def densify(path: JointPath, chain: Chain, max_step_m: float,
            ik: IkOptions | None = None,
            keep: NDArray[np.bool_] | None = None) -> JointPath:
    """Split every chord longer than ``max_step_m`` into equal steps, with IK at new points.

    Inserted points lie on the straight line between the chord's tips; their kind is 2 if
    either end is an approach point, 1 if both ends are mark points, else 0, so every
    sub-segment keeps its chord's segment kind and the needle entries do not change.
    Their joint angles come from :func:`tattotronix.kinematics.solve_path`, one batch for
    all chords, each chord's points preceded by its start point and followed by its end
    point (so each is warm-started from its own chord); the re-solved ends must agree with
    the path's own ``q``, which proves the inserted points are on the path's branch.

    Args:
        path: the path.
        chain: the kinematic model.
        max_step_m: the longest chord kept as is, m.
        ik: keyword arguments for ``solve_path`` (``needle_axis``, ``dls_lambda``,
            ``max_iter``, ``tol``, ``anchor_spacing_m``); its defaults otherwise.
        keep: (N-1,) chords never split (planned travel hops), default none.

    Returns:
        The denser path (the same object when no chord is too long).

    Raises:
        TattotronixError: ``max_step_m`` is not positive, IK fails at an inserted point,
            or a re-solved chord end left the path's solution branch.
    """
    if not max_step_m > 0:
        raise TattotronixError(f"the densify step must be > 0 m, got {max_step_m}")
    seg = path.segment_lengths()
    n_sub = np.maximum(np.ceil(seg / max_step_m - 1e-9).astype(np.int64), 1)
    if keep is not None:
        n_sub[np.asarray(keep, dtype=bool)] = 1
    if len(path) == 2 and n_sub[0] == 1 and seg[0] > 0:
        n_sub[0] = 2  # rest to rest over one chord needs a point in between
    long_ = np.flatnonzero(n_sub > 1)
    if long_.size == 0:
        return path
    # the IK batch: per long chord, [start, inserted..., end]
    fracs = [np.arange(m + 1) / m for m in n_sub[long_]]
    owner = np.repeat(long_, n_sub[long_] + 1)
    frac = np.concatenate(fracs)
    a, b = path.tcp[owner], path.tcp[owner + 1]
    targets = a + frac[:, None] * (b - a)
    res = solve_path(chain, targets, seed=path.q[long_[0]], **(ik or {}))
    if not res.ok:
        j = int(res.failed[0])
        i = int(owner[j])
        uvz = path.uvz_mm[i] + frac[j] * (path.uvz_mm[i + 1] - path.uvz_mm[i])
        raise TattotronixError(
            f"IK failed at a point inserted on the chord after path point {i} "
            f"(panel {uvz[0]:.2f}, {uvz[1]:.2f}, {uvz[2]:.2f} mm): residual "
            f"{res.residual[j]:.3g}, {res.reason[j]}; the straight move between the two "
            "points leaves the arm's reach: move or shrink the drawing (nothing written)")
    ends = (frac == 0.0) | (frac == 1.0)
    expect = np.where((frac == 0.0)[:, None], path.q[owner], path.q[np.minimum(owner + 1,
                                                                                len(path) - 1)])
    drift = np.abs(res.q[ends] - expect[ends]).max()
    if drift > 1e-3:
        raise TattotronixError(
            f"IK on the densified chords left the path's solution branch (chord ends moved "
            f"{drift:.3g} rad); set a smaller densify step")
    inner = ~ends
    # assemble: original points and inserted ones in path order
    counts = n_sub.copy()  # points contributed by each chord start: itself + inserted
    total = int(counts.sum()) + 1
    q = np.empty((total, path.q.shape[1]))
    tcp = np.empty((total, 3))
    uvz = np.empty((total, 3))
    kind = np.empty(total, np.int8)
    source = np.full(total, -1, np.int64)
    start = np.concatenate(([0], np.cumsum(counts)))  # new index of each original point
    q[start] = path.q
    tcp[start] = path.tcp
    uvz[start] = path.uvz_mm
    kind[start] = path.kind
    source[start] = path.source
    # inserted rows: chord i's points go right after start[i]
    rank = np.concatenate([np.arange(1, m) for m in n_sub[long_]])
    dst = start[owner[inner]] + rank
    k0, k1 = path.kind[owner[inner]], path.kind[owner[inner] + 1]
    q[dst] = res.q[inner]
    tcp[dst], _ = chain.fk(res.q[inner])
    ua, ub = path.uvz_mm[owner[inner]], path.uvz_mm[owner[inner] + 1]
    uvz[dst] = ua + frac[inner][:, None] * (ub - ua)
    kind[dst] = np.where((k0 == APPROACH) | (k1 == APPROACH), APPROACH,
                         np.where((k0 == MARK) & (k1 == MARK), MARK, TRAVEL))
    return JointPath(path.joints, q, tcp, kind, uvz, source)


def path_derivatives(q: Array, s: Array) -> tuple[Array, Array]:
    """First and second derivatives of ``q`` with respect to the arc length ``s``.

    Three-point finite differences on the non-uniform grid (exact for a quadratic through
    three consecutive points): with ``D-``, ``D+`` the chord slopes before and after
    point ``i`` and ``h-``, ``h+`` their lengths, ``q' = (h- D+ + h+ D-) / (h- + h+)`` and
    ``q'' = 2 (D+ - D-) / (h- + h+)``. End points take their chord's slope and their
    neighbour's ``q''``.

    Args:
        q: (N, n) joint angles, rad.
        s: (N,) strictly increasing arc length, m.

    Returns:
        ``dq_ds`` (N, n) rad/m and ``d2q_ds2`` (N, n) rad/m^2.
    """
    n_pts = len(q)
    d1 = np.zeros_like(q)
    d2 = np.zeros_like(q)
    if n_pts < 2:
        return d1, d2
    h = np.diff(s)
    slope = np.diff(q, axis=0) / h[:, None]
    d1[0], d1[-1] = slope[0], slope[-1]
    if n_pts >= 3:
        hm, hp = h[:-1, None], h[1:, None]
        d1[1:-1] = (hm * slope[1:] + hp * slope[:-1]) / (hm + hp)
        d2[1:-1] = 2.0 * (slope[1:] - slope[:-1]) / (hm + hp)
        d2[0], d2[-1] = d2[1], d2[-2]
    return d1, d2


def corner_points(tcp: Array, corner_radius_m: float) -> NDArray[np.bool_]:
    """(N,) the points where the tip path bends tighter than ``corner_radius_m``, less
    :data:`CORNER_RADIUS_TOL` (a bend drawn at exactly that radius is held at the feed,
    and read back from IK tip points it is a hair under it)."""
    return turn_radii(tcp) < corner_radius_m * (1.0 - CORNER_RADIUS_TOL)


def cusp_points(tcp: Array, on: NDArray[np.bool_], angle_deg: float = 150.0
                ) -> NDArray[np.int64]:
    """Interior points where the tip path turns back by more than ``angle_deg`` (a
    cusp: a stroke joined to the next by a short drag the other way) with both chords on
    ``on`` segments ((N - 1,) bool; the marking); ascending, none next to another."""
    n_pts = len(tcp)
    if n_pts < 3:
        return np.zeros(0, dtype=np.int64)
    d = np.diff(tcp, axis=0)
    h = np.linalg.norm(d, axis=1)
    cos = np.einsum("ij,ij->i", d[:-1], d[1:]) / np.maximum(h[:-1] * h[1:], 1e-300)
    hit = (cos < math.cos(math.radians(angle_deg))) & on[:-1] & on[1:]
    hit &= (h[:-1] > 0) & (h[1:] > 0)
    return spaced(np.flatnonzero(hit) + 1)


def spaced(points: NDArray[np.integer]) -> NDArray[np.int64]:
    """Ascending ``points`` less each one right after one kept (rest points of a time
    law: a stretch between two rests needs a point inside it)."""
    keep: list[int] = []
    for i in np.asarray(points, dtype=np.int64).tolist():
        if not keep or i - keep[-1] > 1:
            keep.append(i)
    return np.asarray(keep, dtype=np.int64)


def turn_radii(tcp: Array) -> Array:
    """(N,) local radius of the tip path at each point, m: the circle whose chords are
    the mean adjacent chord and turn by the turn angle between them (``h / (2 sin(a /
    2))``: exact on a circle sampled in equal chords).

    ``inf`` where the path goes straight on and at both ends.
    """
    n_pts = len(tcp)
    r = np.full(n_pts, math.inf)
    if n_pts < 3:
        return r
    d = np.diff(tcp, axis=0)
    h = np.linalg.norm(d, axis=1)
    a, b = d[:-1], d[1:]
    ang = np.arctan2(np.linalg.norm(np.cross(a, b), axis=1), np.einsum("ij,ij->i", a, b))
    with np.errstate(divide="ignore"):
        r[1:-1] = np.where(ang > 0, 0.25 * (h[:-1] + h[1:]) / np.sin(0.5 * ang), math.inf)
    return r
