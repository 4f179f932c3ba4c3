"""Check a whole trajectory: every sample, and the motion between samples, proven free.

Between two samples the arm moves along the straight joint-space line (what the samples
describe). Any point of a body moves at most the body's motion bound
(:meth:`~tattotronix.collision.model.CollisionModel.motion_bound_m`), so a pair's clearance
along a segment with end clearances ``d0``, ``d1`` and relative bound ``B`` is at least
``(d0 + d1 - B) / 2``. Segments where that lower bound is under the margin are bisected,
the midpoint's clearance computed, and both halves re-tested, until every segment is
proven above the margin or its bound is below ``resolution_m`` (then the sampled minimum
is within ``resolution_m / 2`` of the true one). A graze of any depth above the resolution
between two samples is therefore caught, not only one that a sample lands in.

The tip's depth below the panel surface is held to the plunge depth at every sample (the
needle is the one shape allowed into the panel).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import TypedDict

import numpy as np
from numpy.typing import NDArray

from tattotronix.collision.model import CollisionModel
from tattotronix.errors import TattotronixError
from tattotronix.io.jsontypes import JsonDict

__all__ = ["CollisionEvent", "CollisionRefused", "TrajectoryClearance", "check_trajectory"]

Array = NDArray[np.float64]
_MAX_ROUNDS = 40  # bisection rounds (a bound halves each round)
_DEPTH_TOL_M = 1e-5  # the tip may end up to 10 um deeper than the plunge (IK lands within 1 um)


class CollisionEvent(TypedDict):
    """The first moment a pair comes under the margin: the pair (``a|b``), the time (s),
    the pose (rad) and the clearance there (mm)."""

    pair: str
    time_s: float
    pose: list[float]
    clearance_mm: float


@dataclass(frozen=True)
class TrajectoryClearance:
    """The clearance of a trajectory.

    Attributes:
        pair_names: the checked pairs.
        min_clearance_m: (P,) least clearance of each pair over samples and bisections.
        lower_bound_m: (P,) proven lower bound on each pair's clearance along the whole
            motion (the true least clearance lies between this and ``min_clearance_m``).
        at_time_s: (P,) when each pair's least clearance occurs.
        at_pose: (P, n) the pose there.
        events: the first offending moment of each pair under the margin:
            ``{"pair", "time_s", "pose", "clearance_mm"}``.
        margin_m: the clearance required.
        resolution_m: the motion bound at which bisection stops.
        needle_depth_max_m: deepest the tip goes below the panel surface.
        plunge_m: how deep it may go.
        samples: poses checked (trajectory samples plus bisection points).
        bisected: segments bisected at least once.
        series_m: (N, P) clearance of every pair at every trajectory sample (figures).
        timings_s: wall times.
    """

    pair_names: list[str]
    min_clearance_m: Array
    lower_bound_m: Array
    at_time_s: Array
    at_pose: Array
    events: list[CollisionEvent]
    margin_m: float
    resolution_m: float
    needle_depth_max_m: float
    plunge_m: float
    samples: int
    bisected: int
    series_m: Array = field(default_factory=lambda: np.zeros((0, 0)), repr=False)
    timings_s: dict[str, float] = field(default_factory=dict)

    @property
    def worst(self) -> int:
        """Index of the pair with the least clearance."""
        return int(np.argmin(self.min_clearance_m))

    @property
    def collisions(self) -> int:
        """Pairs that touch or penetrate somewhere (clearance <= 0)."""
        return int((self.min_clearance_m <= 0).sum())

    @property
    def ok(self) -> bool:
        """Every pair above the margin, and the needle no deeper than the plunge."""
        return not self.events and self.needle_depth_max_m <= self.plunge_m + _DEPTH_TOL_M

    def metrics(self) -> JsonDict:
        """The collision stage's metrics (JSON-ready)."""
        w = self.worst
        return {
            "min_clearance_mm": float(self.min_clearance_m[w] * 1000),
            "worst_pair": self.pair_names[w].split("|"),
            "worst_at_s": float(self.at_time_s[w]),
            "min_clearance_bound_mm": float(self.lower_bound_m.min() * 1000),
            "collisions": self.collisions,
            "below_margin": len(self.events),
            "margin_mm": self.margin_m * 1000,
            "resolution_mm": self.resolution_m * 1000,
            "needle_depth_max_mm": self.needle_depth_max_m * 1000,
            "plunge_mm": self.plunge_m * 1000,
            "pairs_checked": len(self.pair_names),
            "poses_checked": self.samples,
            "segments_bisected": self.bisected,
            "min_clearance_mm_by_pair": {
                n: round(float(c) * 1000, 4) for n, c in
                sorted(zip(self.pair_names, self.min_clearance_m, strict=True),
                       key=lambda kv: kv[1])},
        }

    def message(self) -> str:
        """What is wrong, naming the time, the pose and the pair (empty when ok)."""
        lines = []
        for e in self.events[:5]:
            pose = ", ".join(f"{v:.4f}" for v in e["pose"])
            what = "collide" if e["clearance_mm"] <= 0 else "come within the margin"
            lines.append(f"{e['pair'].replace('|', ' and ')} {what} at t = {e['time_s']:.3f} s "
                         f"(least clearance {e['clearance_mm']:.2f} mm, margin "
                         f"{self.margin_m * 1000:g} mm), pose [{pose}] rad")
        if self.needle_depth_max_m > self.plunge_m + _DEPTH_TOL_M:
            lines.append(f"the needle goes {self.needle_depth_max_m * 1000:.3f} mm into the "
                         f"panel, deeper than the plunge ({self.plunge_m * 1000:g} mm)")
        more = len(self.events) - 5
        return "; ".join(lines) + (f"; and {more} more pair(s)" if more > 0 else "")


class CollisionRefused(TattotronixError):
    """A trajectory that collides, comes within the margin, or plunges too deep."""

    def __init__(self, report: TrajectoryClearance):
        super().__init__(f"trajectory refused: {report.message()}")
        self.report = report


def check_trajectory(model: CollisionModel, t: Array, q: Array, *, margin_m: float,
                     plunge_m: float, resolution_m: float = 1e-4,
                     tcp: Array | None = None) -> TrajectoryClearance:
    """Clearance of every sample and of the motion between samples (module docstring).

    Args:
        model: the collision model.
        t: (N,) sample times, s.
        q: (N, n) joint angles, rad.
        margin_m: the clearance required, m.
        plunge_m: the deepest the tip may go below the panel surface, m.
        resolution_m: stop bisecting a segment whose motion bound is below this, m.
        tcp: (N, 3) the tip at each pose when the caller has it (a stored trajectory's
            ``tcp``), m; otherwise computed.

    Raises:
        TattotronixError: bad arguments.
    """
    t0 = time.perf_counter()
    ta, qa = np.asarray(t, dtype=np.float64), np.asarray(q, dtype=np.float64)
    if qa.ndim != 2 or len(ta) != len(qa) or len(qa) == 0:
        raise TattotronixError(f"need (N,) times and (N, n) poses, got {ta.shape}, {qa.shape}")
    if not (math.isfinite(margin_m) and margin_m >= 0):
        raise TattotronixError(f"collision.margin_mm must be a finite number >= 0 mm (got "
                               f"{margin_m * 1e3:g})")
    if not (math.isfinite(resolution_m) and resolution_m > 0):
        raise TattotronixError(f"collision.resolution_mm must be a finite number > 0 mm (got "
                               f"{resolution_m * 1e3:g})")
    clear = model.clearance(qa)
    t1 = time.perf_counter()
    n_pairs = clear.shape[1]
    best = clear.min(axis=0)
    at = clear.argmin(axis=0)
    best_t, best_q = ta[at].copy(), qa[at].copy()
    first_bad = np.full(n_pairs, np.inf)
    first_q = np.zeros((n_pairs, qa.shape[1]))
    bad = clear < margin_m
    for p in np.flatnonzero(bad.any(axis=0)):
        i = int(np.argmax(bad[:, p]))
        first_bad[p], first_q[p] = ta[i], qa[i]

    # segments: (t0, t1, q0, q1, d0, d1)
    floor = best.copy()  # a proven lower bound on each pair's clearance along the motion
    sa, sb = np.arange(len(qa) - 1), np.arange(1, len(qa))
    T0, T1, Q0, Q1, D0, D1 = ta[sa], ta[sb], qa[sa], qa[sb], clear[sa], clear[sb]
    samples, bisected = len(qa), 0
    for _ in range(_MAX_ROUNDS):
        if len(T0) == 0:
            break
        bound = model.motion_bound_m(Q0, Q1)
        lower = 0.5 * (D0 + D1 - bound)
        open_ = (lower < margin_m) & (bound >= resolution_m)
        split = open_.any(axis=1)
        if (~split).any():  # segments settled now: their bound holds along them
            floor = np.minimum(floor, lower[~split].min(axis=0))
        seg = np.flatnonzero(split)
        if seg.size == 0:
            break
        bisected += int(seg.size)
        Tm = 0.5 * (T0[seg] + T1[seg])
        Qm = 0.5 * (Q0[seg] + Q1[seg])
        Dm = model.clearance(Qm)
        samples += len(seg)
        lower_m = Dm.min(axis=0)
        better = lower_m < best
        if better.any():
            k = Dm.argmin(axis=0)
            best = np.where(better, lower_m, best)
            best_t = np.where(better, Tm[k], best_t)
            best_q = np.where(better[:, None], Qm[k], best_q)
        for p in np.flatnonzero((Dm < margin_m).any(axis=0)):
            under = np.flatnonzero(Dm[:, p] < margin_m)
            i = int(under[np.argmin(Tm[under])])  # the earliest (the list is not in order)
            if Tm[i] < first_bad[p]:
                first_bad[p], first_q[p] = Tm[i], Qm[i]
        T0, T1 = np.concatenate([T0[seg], Tm]), np.concatenate([Tm, T1[seg]])
        Q0, Q1 = np.concatenate([Q0[seg], Qm]), np.concatenate([Qm, Q1[seg]])
        D0, D1 = np.concatenate([D0[seg], Dm]), np.concatenate([Dm, D1[seg]])
    else:  # rounds ran out: what is left is only bounded
        if len(T0):
            floor = np.minimum(floor, (0.5 * (D0 + D1 - model.motion_bound_m(Q0, Q1))).min(0))
    t2 = time.perf_counter()
    tip = model.frames(qa)[0] if tcp is None else np.asarray(tcp, dtype=np.float64)
    depth = model.needle_depth_m(tip)
    depth_max = float(depth.max()) if np.isfinite(depth).any() else 0.0
    events = [CollisionEvent(pair=model.pair_names[p], time_s=float(first_bad[p]),
                             pose=[float(v) for v in first_q[p]],
                             clearance_mm=float(best[p] * 1000))
              for p in np.argsort(first_bad) if np.isfinite(first_bad[p])]
    return TrajectoryClearance(
        pair_names=list(model.pair_names), min_clearance_m=best, lower_bound_m=floor,
        at_time_s=best_t,
        at_pose=best_q, events=events, margin_m=margin_m, resolution_m=resolution_m,
        needle_depth_max_m=max(depth_max, 0.0), plunge_m=plunge_m, samples=samples,
        bisected=bisected, series_m=clear,
        timings_s={"samples": t1 - t0, "swept": t2 - t1, "total": time.perf_counter() - t0})

