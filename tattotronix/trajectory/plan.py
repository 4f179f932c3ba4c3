"""The trajectory: time-stamped joint motion along the IK path, within the joint limits.

What :func:`plan_trajectory` does (``stages/trajectory.py`` calls it):

1. **Densify** (:func:`~tattotronix.trajectory.path.densify`): chords longer than
   ``max_step_m`` (travel, plunge, retract, approach) get points every ``max_step_m``
   on the straight tip line, with IK, so ramps can be drawn and the tip stays in the
   clearance band between samples.
2. **Caps**: each point's path-speed cap is the lower feed of its two segments:
   marking and approach at ``toolpath.feed_mark_mm_s`` x ``speed``, travel at
   ``trajectory.travel_feed_mm_s`` x ``speed``.
3. **Speed check** (:func:`speed_limit`): at every point the marking feed must be held
   (points on a marking or approach segment, except path ends and *corners*: bends
   tighter than ``corner_radius_m``, half the stroke pitch by default, where the law
   has to slow whatever the speed), the joint rates needed at ``feed x speed`` must be
   inside the limits: ``|dq/ds| F S <= v`` and ``|d2q/ds2| (F S)^2 <= a``. If not, the
   plan is refused (:class:`SpeedRefused`) naming the joint, the rate needed and the
   fastest speed, ``floor(100 S_max) / 100``, as the original's ``plan.py`` did.
4. **Blended travel** (``travel="planned"``, :mod:`~tattotronix.trajectory.travel`): the
   hops between strokes are never densified; each, and the moves from and to home, is
   replaced by one blended move (:meth:`~.travel.TravelPlanner.blend`: a quintic curve
   in joint space that continues the needle's vertical line at both ends), checked for
   collision and clearance. Blended moves have no feed cap: the joint limits bind.
5. **Time law** (:func:`~tattotronix.trajectory.timelaw.time_parameterise`): one law for
   the whole drawing, rest to rest, under the caps, the joints' velocity, acceleration
   and jerk limits and the tip's acceleration limit on marking and approach segments
   (docs/timelaw.md). With a jerk limit the needle also rests where it leaves the ink and
   where each approach begins.

Units: SI inside (m, rad, s); mm only in names that say so.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from tattotronix.config.schema import ToolpathConfig, TrajectoryConfig
from tattotronix.errors import TattotronixError
from tattotronix.io.artifacts import PROVENANCE_KEY, TRAJECTORY, TrajectoryRecord
from tattotronix.io.jsontypes import JsonDict
from tattotronix.kinematics import Chain, IkOptions
from tattotronix.trajectory.path import (
    APPROACH,
    CORNER_RADIUS_TOL,
    MARK,
    TRAVEL,
    JointPath,
    corner_points,
    cusp_points,
    densify,
    marking_reversals,
    path_derivatives,
    segment_kinds,
    spaced,
    turn_radii,
)
from tattotronix.trajectory.timelaw import (
    JointLimits,
    TimeLaw,
    TipLimit,
    sample_jerk,
    time_parameterise,
)
from tattotronix.trajectory.travel import Blend, TravelPlanner

__all__ = [
    "CORNER_RADIUS_TOL",
    "NPZ_KEYS",
    "MoveSummary",
    "SpeedLimit",
    "SpeedRefused",
    "Trajectory",
    "TrajectoryParams",
    "plan_trajectory",
    "speed_limit",
]

Array = NDArray[np.float64]
#: the keys of ``data/trajectories/<name>.npz``, an interface other tools rely on (README,
#: "The stages")
NPZ_KEYS = (*TRAJECTORY.keys, PROVENANCE_KEY)


@dataclass(frozen=True)
class TrajectoryParams:
    """How to time a path.

    Attributes:
        feed_mark_m_s: marking and approach feed (tip speed), m/s, at ``speed`` 1.
        travel_feed_m_s: cap on the tip speed of travel, m/s, at ``speed`` 1.
        accel_rad_s2: per-joint acceleration limit, rad/s^2 (not scaled by ``speed``).
        speed: rescales every feed (2 draws twice as fast where the limits allow).
        max_step_m: longest chord kept as is; longer ones are split (IK), m.
        corner_radius_m: bends tighter than this are corners, where the law may slow
            below the feed; elsewhere the feed must be held or the speed is refused, m.
        jerk_rad_s3: every joint's jerk limit, rad/s^3 (``None``: acceleration-limited).
        tip_accel_m_s2: the tip's acceleration limit while marking and on the approach,
            tangential and centripetal together, m/s^2 (``None``: none).
        reach_m: a blended travel move's tangent reach (its first try), m.
        travel: ``planned`` (joint-space moves between strokes, from and to home;
            :mod:`~tattotronix.trajectory.travel`) or ``straight`` (straight tip lines at
            clearance, timed by the time law, as the original).
        clearance_mm: the toolpath's clearance height above the panel (finds the hops).
        home: the home pose, rad (planned travel starts and ends there when
            ``from_home``).
        from_home: planned travel: start at home and return home.
        straight_feed_m_s: the original's travel feed (``toolpath.feed_travel_mm_s``),
            the baseline the saving of planned travel is reported against, m/s.
    """

    feed_mark_m_s: float
    travel_feed_m_s: float
    accel_rad_s2: float
    speed: float
    max_step_m: float
    corner_radius_m: float
    jerk_rad_s3: float | None
    tip_accel_m_s2: float | None
    reach_m: float
    travel: str
    clearance_mm: float
    home: tuple[float, ...]
    from_home: bool
    straight_feed_m_s: float

    @classmethod
    def from_settings(cls, tr: TrajectoryConfig, tp: ToolpathConfig, speed: float
                      ) -> TrajectoryParams:
        """From the settings: ``trajectory.*`` (``tr``), ``toolpath.feed_mark_mm_s`` (the
        one marking feed, in ``tp``), the root ``speed``; corners below half
        ``toolpath.pitch_mm``. Every value (and default) comes from there: this class holds
        none of its own."""
        return cls(
            feed_mark_m_s=tp.feed_mark_m_s,
            travel_feed_m_s=tr.travel_feed_m_s,
            accel_rad_s2=float(tr.accel_rad_s2),
            speed=float(speed),
            corner_radius_m=tp.pitch_m / 2,
            max_step_m=tr.max_step_m,
            jerk_rad_s3=None if tr.jerk_rad_s3 is None else float(tr.jerk_rad_s3),
            tip_accel_m_s2=tr.tip_accel_m_s2, reach_m=tr.blend_reach_m,
            travel=str(tr.travel), clearance_mm=float(tp.clearance_mm),
            home=tuple(float(v) for v in tr.home), from_home=bool(tr.from_home),
            straight_feed_m_s=tp.feed_travel_m_s,
        )

    def validate(self) -> None:
        """Raise :class:`TattotronixError` for a value the planner cannot use."""
        for name, value, key in (
                ("marking feed", self.feed_mark_m_s * 1000, "toolpath.feed_mark_mm_s"),
                ("travel feed", self.travel_feed_m_s * 1000, "trajectory.travel_feed_mm_s"),
                ("acceleration limit", self.accel_rad_s2, "trajectory.accel_rad_s2"),
                ("speed", self.speed, "speed"),
                ("densify step", self.max_step_m * 1000, "trajectory.max_step_mm"),
                ("corner radius", self.corner_radius_m, "corner_radius_m")):
            if not (math.isfinite(value) and value > 0):
                raise TattotronixError(f"the {name} must be a positive number, got {key}="
                                       f"{value:g}")
        if self.travel not in ("planned", "straight"):
            raise TattotronixError(f"trajectory.travel={self.travel!r}: choose planned or "
                                   "straight")
        if not all(math.isfinite(v) for v in self.home):
            raise TattotronixError(f"trajectory.home={list(self.home)} must be finite angles")
        for name, opt, key in (("jerk limit", self.jerk_rad_s3, "trajectory.jerk_rad_s3"),
                               ("tip acceleration limit", self.tip_accel_m_s2,
                                "trajectory.tip_accel_mm_s2")):
            if opt is not None and not (math.isfinite(opt) and opt > 0):
                raise TattotronixError(f"the {name} must be a positive number or null, got "
                                       f"{key}={opt:g}")


class SpeedRefused(TattotronixError):
    """``speed`` would need a joint rate beyond its limit to hold the marking feed."""

    def __init__(self, limit: SpeedLimit):
        super().__init__(limit.message())
        self.limit = limit


@dataclass(frozen=True)
class SpeedLimit:
    """How fast a drawing can go: the joint that binds while holding the marking feed.

    Attributes:
        speed: the requested speed.
        exact: the largest speed that holds the feed within the limits (``inf`` when no
            point holds a feed).
        fastest: ``exact`` floored to two decimals (what the refusal offers).
        joint: the binding joint ('' when none).
        quantity: ``velocity`` or ``acceleration``.
        need: the rate that joint needs at ``speed``, rad/s or rad/s^2.
        limit: its limit, same unit.
        index: the binding path point.
        uvz_mm: its panel coordinates, mm.
        radius_m: the tip path's radius of curvature there, m (``inf``: straight).
        held_points: points where the feed must be held.
    """

    speed: float
    exact: float
    fastest: float
    joint: str
    quantity: str
    need: float
    limit: float
    index: int
    uvz_mm: tuple[float, float, float]
    radius_m: float
    held_points: int

    @property
    def ok(self) -> bool:
        """The requested speed holds the feed within every limit."""
        return self.speed <= self.exact

    def message(self) -> str:
        """The refusal, in the original's words (docs/original.md, "3.3 Refusals")."""
        unit = "rad/s" if self.quantity == "velocity" else "rad/s^2"
        where = f"panel ({self.uvz_mm[0]:.2f}, {self.uvz_mm[1]:.2f}) mm"
        if self.quantity == "acceleration" and math.isfinite(self.radius_m):
            where += f", a bend of radius {self.radius_m * 1000:.2f} mm"
        return (f"speed={self.speed:g} is too fast for this drawing: to hold the marking "
                f"feed at {where}, {self.joint} would need {self.need:.2f} {unit} against "
                f"its {self.limit:g} {unit} limit; the fastest this drawing can go is "
                f"speed={self.fastest:.2f}")

    def raise_if_too_fast(self) -> None:
        """Raise :class:`SpeedRefused` unless :attr:`ok`."""
        if not self.ok:
            raise SpeedRefused(self)

    def summary(self) -> JsonDict:
        """JSON-ready figures (``None`` for an unbounded speed)."""
        finite = math.isfinite(self.exact)
        return {
            "fastest_speed": self.fastest if finite else None,
            "fastest_speed_exact": self.exact if finite else None,
            "fastest_speed_joint": self.joint or None,
            "fastest_speed_limited_by": self.quantity or None,
            "fastest_speed_uv_mm": [self.uvz_mm[0], self.uvz_mm[1]] if finite else None,
        }


def speed_limit(path: JointPath, dq: Array, d2q: Array, limits: JointLimits, *,
                feed_m_s: float, speed: float, corner_radius_m: float) -> SpeedLimit:
    """The fastest speed that holds the marking feed (see the module docstring, step 3).

    Args:
        path: the (densified) path.
        dq: (N, n) ``dq/ds``, rad/m.
        d2q: (N, n) ``d2q/ds2``, rad/m^2.
        limits: joint limits.
        feed_m_s: the marking feed at speed 1, m/s.
        speed: the requested speed.
        corner_radius_m: bends tighter than this are corners (exempt), m.
    """
    n_pts = len(path)
    seg = path.segment_kinds()
    slow_seg = seg != TRAVEL
    held = np.zeros(n_pts, bool)
    held[:-1] |= slow_seg
    held[1:] |= slow_seg
    held[[0, -1]] = False
    radius = turn_radii(path.tcp)
    held &= ~corner_points(path.tcp, corner_radius_m)
    idx = np.flatnonzero(held)
    if idx.size == 0:
        return SpeedLimit(speed, math.inf, math.inf, "", "", 0.0, 0.0, -1, (0.0, 0.0, 0.0),
                          math.inf, 0)
    f = feed_m_s
    # the speed at which each (point, joint) reaches its limit
    with np.errstate(divide="ignore"):
        s_vel = limits.velocity / (f * np.abs(dq[idx]))
        s_acc = np.sqrt(limits.acceleration / (f * f * np.abs(d2q[idx])))
    kv = np.unravel_index(int(np.argmin(s_vel)), s_vel.shape)
    ka = np.unravel_index(int(np.argmin(s_acc)), s_acc.shape)
    if s_vel[kv] <= s_acc[ka]:
        (row, j), quantity, exact = kv, "velocity", float(s_vel[kv])
        need = f * speed * abs(float(dq[idx[row], j]))
        lim = float(limits.velocity[j])
    else:
        (row, j), quantity, exact = ka, "acceleration", float(s_acc[ka])
        need = (f * speed) ** 2 * abs(float(d2q[idx[row], j]))
        lim = float(limits.acceleration[j])
    i = int(idx[row])
    fastest = math.floor(100.0 * exact) / 100.0 if math.isfinite(exact) else math.inf
    u = path.uvz_mm[i]
    return SpeedLimit(speed, exact, fastest, limits.joints[j], quantity, need, lim, i,
                      (float(u[0]), float(u[1]), float(u[2])), float(radius[i]), int(idx.size))


def _caps(seg: NDArray[np.int8], n_pts: int, mark: float, travel: float,
          free: NDArray[np.bool_] | None = None) -> Array:
    feed = np.where(seg == TRAVEL, travel, mark)
    if free is not None:
        feed = np.where(free, math.inf, feed)
    cap = np.full(n_pts, math.inf)
    cap[:-1] = feed
    cap[1:] = np.minimum(cap[1:], feed)
    return cap


@dataclass(frozen=True)
class MoveSummary:
    """One planned travel move, in the trajectory (see :mod:`~.travel`).

    Attributes:
        kind: ``hop``, ``from_home`` or ``to_home``.
        start_s: when it starts (at its first pose, the clearance point), s.
        duration_s: its time to its last pose, s.
        straight_m: straight tip distance between its ends, m.
        reach_m: the tangent reach that passed the checks, m.
    """

    kind: str
    start_s: float
    duration_s: float
    straight_m: float
    reach_m: float


@dataclass(frozen=True, kw_only=True)
class Trajectory(TrajectoryRecord):
    """A timed joint trajectory as planned: the record ``data/trajectories/<name>.npz``
    holds (:class:`~tattotronix.io.artifacts.TrajectoryRecord`, which every reader takes:
    a plan is played, checked and compiled as it is, and :meth:`save` writes it), and how
    it was planned.

    Attributes:
        joints, t, q, qd, qdd, kind, marked, tcp: the record's arrays (``t`` (N,) s from
            0, strictly increasing; ``q``, ``qd``, ``qdd`` (N, n) rad, rad/s, rad/s^2;
            ``kind`` (N,) int8, 0 travel, 1 mark, 2 approach; ``marked`` (N,) the segment
            ending at each point is ink; ``tcp`` (N, 3) the FK tip of ``q``, m).
        uvz_mm: (N, 3) panel coordinates, mm.
        source: (N,) index in the IK path, -1 for inserted points and planned moves.
        s: (N,) tip arc length, m.
        tip_speed: (N,) tip speed, m/s.
        qdd_ends: (N-1, 2, n) joint acceleration at both ends of each interval, rad/s^2.
        law: the time law of the whole drawing.
        moves: the planned travel moves, in order (none for straight travel).
        limits: the joint limits it keeps.
        params: the settings it was planned with.
        speed: the speed check.
        entries: needle entries.
        marked_m: marked length, m.
        timings_s: wall times of the steps (densify, derivatives, time law, travel), s.
    """

    uvz_mm: Array
    source: NDArray[np.int64]
    s: Array
    tip_speed: Array
    qdd_ends: Array
    law: TimeLaw
    moves: tuple[MoveSummary, ...]
    limits: JointLimits
    params: TrajectoryParams
    speed: SpeedLimit
    entries: int
    marked_m: float
    timings_s: dict[str, float] = field(default_factory=dict)

    @property
    def duration_s(self) -> float:
        """Total time, s."""
        return float(self.t[-1]) if len(self.t) else 0.0

    @property
    def marking_only_s(self) -> float:
        """Marked length over the marking feed (x speed), s."""
        return self.marked_m / (self.params.feed_mark_m_s * self.params.speed)

    def segment_kinds(self) -> NDArray[np.int8]:
        """(N-1,) 1 marking, 2 approach, 0 travel."""
        return segment_kinds(self.kind)

    def peak_tip_accel_marking(self) -> float:
        """The largest tip acceleration on the points of marking and approach segments,
        m/s^2 (zero when the law had no tip limit to measure it against)."""
        ink = self.segment_kinds() != TRAVEL
        pts = np.zeros(len(self.t), bool)
        pts[:-1] |= ink
        pts[1:] |= ink
        acc = self.law.tip_accel
        return float(acc[pts].max()) if pts.any() else 0.0

    def travel_metrics(self) -> JsonDict:
        """Planned travel: the moves, their time, and the saving over the original's
        straight travel at ``toolpath.feed_travel_mm_s`` (JSON-ready)."""
        hops = [m for m in self.moves if m.kind == "hop"]
        home = [m for m in self.moves if m.kind in ("from_home", "to_home")]
        hop_s = sum(m.duration_s for m in hops)
        base_feed = self.params.straight_feed_m_s * self.params.speed
        straight_s = sum(m.straight_m for m in self.moves if m.kind == "hop") / base_feed
        first = self.params.reach_m
        return {
            "travel": self.params.travel,
            "moves": len(self.moves),
            "hops": sum(m.kind == "hop" for m in self.moves),
            "lifts": sum(m.reach_m > first for m in self.moves),
            "hop_s": hop_s,
            "hop_straight_s": straight_s,
            "straight_feed_mm_s": base_feed * 1000.0,
            "travel_saved_s": straight_s - hop_s,
            "cycle_straight_travel_s": self.duration_s - hop_s + straight_s,
            "home_moves_s": sum(m.duration_s for m in home),
        }

    def metrics(self) -> JsonDict:
        """The stage's metrics (JSON-ready)."""
        seg = self.segment_kinds()
        dt = np.diff(self.t)
        chord = np.abs(np.diff(self.qd, axis=0)) / dt[:, None]  # mean accel per interval
        peak_v = np.abs(self.qd).max(axis=0)
        peak_a = np.abs(self.qdd_ends).max(axis=(0, 1))
        feed = self.params.feed_mark_m_s * self.params.speed
        mean_v = 0.5 * (self.tip_speed[:-1] + self.tip_speed[1:])
        h = np.diff(self.s)
        mark = seg == MARK
        slow_len = float(h[mark & (mean_v < 0.99 * feed)].sum())
        mark_len = float(h[mark].sum())
        names = self.joints
        out: dict[str, Any] = {
            "duration_s": self.duration_s,
            "marking_only_s": self.marking_only_s,
            "cycle_over_marking": self.duration_s / self.marking_only_s
            if self.marked_m > 0 else None,
            "marking_s": float(dt[mark].sum()),
            "approach_s": float(dt[seg == APPROACH].sum()),
            "travel_s": float(dt[seg == TRAVEL].sum()),
            "entries": self.entries,
            "speed": self.params.speed,
            "marked_mm": self.marked_m * 1000.0,
            "points": len(self.t),
            "points_inserted": int((self.source < 0).sum()),
            "peak_rate_rad_s": {j: float(v) for j, v in zip(names, peak_v, strict=True)},
            "peak_rate_rad_s_max": float(peak_v.max()),
            "peak_accel_rad_s2": {j: float(a) for j, a in zip(names, peak_a, strict=True)},
            "peak_accel_rad_s2_max": float(peak_a.max()),
            "peak_step_accel_rad_s2_max": float(chord.max()) if len(chord) else 0.0,
            "velocity_limit_rad_s": {j: float(v) for j, v in
                                     zip(names, self.limits.velocity, strict=True)},
            "accel_limit_rad_s2": float(self.limits.acceleration.max()),
            "feed_mark_mm_s": feed * 1000.0,
            "travel_feed_mm_s": self.params.travel_feed_m_s * self.params.speed * 1000.0,
            "marking_below_feed_pct": 100.0 * slow_len / mark_len if mark_len > 0 else 0.0,
            "peak_tip_speed_mm_s": float(self.tip_speed.max()) * 1000.0,
            "timelaw_stepped_points": self.law.stepped,
            "jerk_limit_rad_s3": self.params.jerk_rad_s3,
            "peak_jerk_rad_s3_max": float(sample_jerk(self.t, self.qdd).max(initial=0.0)),
            "jerk_window_s_max": self.law.window_s,
            "timelaw_repairs": self.law.repairs,
            "tip_accel_limit_mm_s2": None if self.params.tip_accel_m_s2 is None
            else self.params.tip_accel_m_s2 * 1000.0,
            "peak_tip_accel_marking_mm_s2": self.peak_tip_accel_marking() * 1000.0,
            # joint reversals while the needle is in (issue 34: where backlash bites)
            "marking_reversals": {j: int(c) for j, c in zip(
                names, marking_reversals(self.q, self.kind), strict=True)},
            **self.speed.summary(),
            **self.travel_metrics(),
        }
        return out

    @classmethod
    def load(cls, file: str | Path) -> TrajectoryRecord:  # type: ignore[override]
        """The stored record (:meth:`TrajectoryRecord.load`): how a trajectory was planned
        is not stored."""
        return TrajectoryRecord.load(file)


def _time_path(path: JointPath, params: TrajectoryParams, limits: JointLimits,
               free: NDArray[np.bool_] | None = None,
               derivatives: tuple[Array, Array, Array] | None = None) -> TimeLaw:
    """The one time law of a whole drawing: the feeds (none on ``free`` segments: the
    blended moves, bound by the joint limits alone), the joint limits, the tip's
    acceleration while marking and on the approach, and the jerk limit; at rest at both
    ends (and, with a jerk limit, where the needle leaves the ink and where each approach
    begins, and where the tip turns back while marking). ``derivatives``: ``(s, dq,
    d2q)`` of ``path`` when the caller has them."""
    if derivatives is None:
        s = path.arc_length()
        dq, d2q = path_derivatives(path.q, s)
    else:
        s, dq, d2q = derivatives
    seg = path.segment_kinds()
    caps = _caps(seg, len(path), params.feed_mark_m_s * params.speed,
                 params.travel_feed_m_s * params.speed, free)
    tip = None
    if params.tip_accel_m_s2 is not None:
        dp, d2p = path_derivatives(path.tcp, s)
        tip = TipLimit(dp, d2p, params.tip_accel_m_s2, seg != TRAVEL)
    # with a jerk limit, the needle comes to rest where it leaves the ink, where each
    # approach begins and where the tip turns back while marking (a cusp: passed at
    # speed, the tip acceleration's bound over its short chords let a 180 degree turn go
    # at 3 mm/s, and the controller left the line by 20.8 um there), and each stretch
    # between is filtered with the window it needs
    rests = None
    if params.jerk_rad_s3 is not None:
        ends = _travel_ends(seg)
        cusps = cusp_points(path.tcp, seg == MARK)
        clear = np.abs(cusps[:, None] - ends[None, :]).min(axis=1) > 1 if ends.size else (
            np.ones(cusps.size, dtype=bool))
        rests = np.union1d(ends, cusps[clear])  # none next to another
    law = time_parameterise(s, dq, d2q, caps, limits, tip=tip,
                            jerk_rad_s3=params.jerk_rad_s3, rests=rests)
    law.check(limits, jerk_rad_s3=params.jerk_rad_s3, tip=tip)
    return law


def _travel_ends(seg: NDArray[np.int8]) -> NDArray[np.int64]:
    """Interior points where travel begins or ends, none next to another."""
    travel = seg == TRAVEL
    return spaced(np.flatnonzero(travel[:-1] != travel[1:]) + 1)


def _up_tangent(path: JointPath, i: int, j: int) -> Array:
    """``dq/ds`` at point ``i`` pointing away from its neighbour ``j`` (rad per metre of
    tip travel): up the needle at a clearance point whose neighbour is below it."""
    if not 0 <= j < len(path):  # no such neighbour: a rest (home, or a waypoint)
        return np.zeros(path.q.shape[1])
    ds = float(np.linalg.norm(path.tcp[i] - path.tcp[j]))
    return (path.q[i] - path.q[j]) / ds if ds > 0 else np.zeros(path.q.shape[1])


@dataclass
class _Assembly:
    """The drawing's one path with the blended moves spliced in, as it grows."""

    path: JointPath
    origin: Array
    parts: dict[str, list[NDArray[Any]]] = field(default_factory=dict)
    free: list[NDArray[np.bool_]] = field(default_factory=list)
    moves: list[tuple[str, int, int, float, float]] = field(default_factory=list)
    size: int = 0

    def add_path(self, a: int, b: int) -> None:
        """Points ``a`` to ``b - 1`` of the path (a piece between two hops)."""
        p = self.path
        self._add(p.q[a:b], p.tcp[a:b], p.kind[a:b], p.uvz_mm[a:b], p.source[a:b])

    def add_blend(self, blend: Blend, first: bool, last: bool) -> None:
        """A blended move's points (its end poses only where no piece holds them)."""
        lo, hi = (0 if first else 1), (len(blend.q) if last else len(blend.q) - 1)
        start = self.size - (0 if first else 1)
        m = hi - lo
        self._add(blend.q[lo:hi], blend.tcp[lo:hi], np.full(m, TRAVEL, np.int8),
                  (blend.tcp[lo:hi] - self.origin) * 1000.0, np.full(m, -1, np.int64),
                  free=True)
        end = self.size - (1 if last else 0)
        self.moves.append((blend.kind, start, end, blend.straight_m, blend.reach_m))

    def _add(self, q: Array, tcp: Array, kind: NDArray[np.int8], uvz: Array,
             source: NDArray[np.int64], free: bool = False) -> None:
        for key, arr in (("q", q), ("tcp", tcp), ("kind", kind), ("uvz", uvz),
                         ("source", source)):
            self.parts.setdefault(key, []).append(arr)
        # the segments that end at these points (the first point's joins the last part)
        seg = np.full(len(q), free)
        if self.size == 0:
            seg = seg[1:]
        self.free.append(seg)
        self.size += len(q)

    def result(self) -> tuple[JointPath, NDArray[np.bool_]]:
        """The whole path, and which of its segments belong to a blended move."""
        cat = {k: np.concatenate(v) for k, v in self.parts.items()}
        path = JointPath(self.path.joints, cat["q"], cat["tcp"], cat["kind"].astype(np.int8),
                         cat["uvz"], cat["source"].astype(np.int64))
        return path, np.concatenate(self.free)


def _blended(dense: JointPath, planner: TravelPlanner, params: TrajectoryParams,
             origin: Array) -> _Assembly:
    """The drawing's path with every hop, and the moves from and to home, replaced by a
    blended move (:meth:`~.travel.TravelPlanner.blend`)."""
    n = len(dense)
    cut = np.flatnonzero(dense.hops(params.clearance_mm))
    hop_starts = set(cut.tolist())
    asm = _Assembly(dense, origin)
    home = np.asarray(params.home, dtype=np.float64)
    if home.shape != (dense.q.shape[1],):
        raise TattotronixError(f"trajectory.home needs {dense.q.shape[1]} angles, got "
                               f"{list(params.home)}")
    same = float(np.abs(home - dense.q[0]).max()) <= 1e-12
    if params.from_home and not same:
        zero = np.zeros_like(home)
        asm.add_blend(planner.blend(home, zero, dense.q[0], _up_tangent(dense, 0, 1),
                                    "from_home", "the move from home"), True, False)
    start = 0
    for i in cut:
        asm.add_path(start, int(i) + 1)
        a, b = int(i), int(i) + 1
        where = (f"the travel from panel ({dense.uvz_mm[a, 0]:.1f}, {dense.uvz_mm[a, 1]:.1f}) "
                 f"to ({dense.uvz_mm[b, 0]:.1f}, {dense.uvz_mm[b, 1]:.1f}) mm")
        # a clearance point between two hops is a waypoint: the moves rest there
        up_a = _up_tangent(dense, a, a - 1 if a - 1 not in hop_starts else -1)
        up_b = _up_tangent(dense, b, b + 1 if b not in hop_starts else -1)
        asm.add_blend(planner.blend(dense.q[a], up_a, dense.q[b], up_b, "hop", where),
                      False, False)
        start = b
    asm.add_path(start, n)
    if params.from_home:
        zero = np.zeros_like(home)
        back = planner.blend(dense.q[-1], _up_tangent(dense, n - 1, n - 2), home, zero,
                             "to_home", "the way home")
        asm.add_blend(back, False, True)
    return asm


def plan_trajectory(path: JointPath, chain: Chain, limits: JointLimits,
                    params: TrajectoryParams, *, ik: IkOptions | None = None,
                    check_speed: bool = True, planner: TravelPlanner | None = None,
                    panel_origin_m: ArrayLike = (0.0, 0.0, 0.0)) -> Trajectory:
    """Time an IK path (see the module docstring).

    Args:
        path: the IK path (:meth:`JointPath.from_npz`).
        chain: the kinematic model (densify's IK, the tip of the final ``q``).
        limits: joint velocity and acceleration limits.
        params: feeds, speed, densify step, corner radius, limits, travel mode.
        ik: keyword arguments for the densify IK (``needle_axis``, ``dls_lambda``, ...).
        check_speed: refuse a speed that cannot hold the marking feed.
        planner: plans and checks the travel moves (required for planned travel).
        panel_origin_m: the panel frame's origin in the arm frame (``uvz_mm`` of the
            blended moves' samples), m.

    Returns:
        The trajectory.

    Raises:
        SpeedRefused: ``params.speed`` cannot hold the marking feed within the limits.
        TattotronixError: bad parameters, a path the limits cannot time, IK failure on a
            densified chord, joint names that differ from the limits', or a travel move
            no reach makes safe.
    """
    params.validate()
    if tuple(path.joints) != tuple(limits.joints):
        raise TattotronixError(f"the path's joints {list(path.joints)} are not the robot's "
                               f"{list(limits.joints)}: re-run the 'ik' stage")
    planned = params.travel == "planned"
    if planned and planner is None:
        raise TattotronixError("planned travel needs a TravelPlanner (trajectory.travel="
                               "planned); pass one, or set trajectory.travel=straight")
    t0 = time.perf_counter()
    hops = path.hops(params.clearance_mm) if planned else np.zeros(len(path) - 1, bool)
    dense = densify(path, chain, params.max_step_m, ik, keep=hops)
    t1 = time.perf_counter()
    s_all = dense.arc_length()
    dq, d2q = path_derivatives(dense.q, s_all)
    t2 = time.perf_counter()
    check = speed_limit(dense, dq, d2q, limits, feed_m_s=params.feed_mark_m_s,
                        speed=params.speed, corner_radius_m=params.corner_radius_m)
    if check_speed:
        check.raise_if_too_fast()
    origin = np.asarray(panel_origin_m, dtype=np.float64)
    free = None
    moves: list[tuple[str, int, int, float, float]] = []
    whole = dense
    if planned:
        assert planner is not None
        asm = _blended(dense, planner, params, origin)
        whole, free = asm.result()
        moves = asm.moves
    t3 = time.perf_counter()
    law = _time_path(whole, params, limits, free,
                     None if planned else (s_all, dq, d2q))  # straight: the dense path
    t4 = time.perf_counter()
    summaries = tuple(MoveSummary(kind, float(law.t[a]), float(law.t[b] - law.t[a]),
                                  straight, reach)
                      for kind, a, b, straight, reach in moves)
    return Trajectory(
        joints=dense.joints, t=law.t, q=whole.q, qd=law.qd, qdd=law.qdd, kind=whole.kind,
        marked=whole.marked(), tcp=whole.tcp, uvz_mm=whole.uvz_mm, source=whole.source,
        s=law.s, tip_speed=law.sdot, qdd_ends=law.qdd_ends, law=law, moves=summaries,
        limits=limits, params=params, speed=check, entries=dense.entries(),
        marked_m=dense.marked_length_m(),
        timings_s={"densify": t1 - t0, "derivatives": t2 - t1, "travel": t3 - t2,
                   "time_law": t4 - t3, "total": t4 - t0})
