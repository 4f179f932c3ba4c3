"""Path speed under joint velocity, acceleration and jerk limits and the tip's
acceleration limit (discrete TOPP, then a jerk filter; docs/timelaw.md).

The path is fixed: joint angles ``q_i`` at arc lengths ``s_i`` (the tip's, m). The unknown
is the squared path speed ``x_i = sdot_i^2`` at every point, with the path acceleration
``u = sddot`` constant on each interval, so ``x_{i+1} = x_i + 2 u_i h_i`` (``h_i`` the
interval's length). Joint rates follow from the path derivatives (finite differences,
:func:`~tattotronix.trajectory.path.path_derivatives`)::

    qd  = q'(s) sdot
    qdd = q''(s) sdot^2 + q'(s) sddot

Constraints:

* ``x_i <= cap_i``: the feed (the path-speed cap), every joint's velocity limit
  (``|q'_ij| sdot <= v_j``), and ``|q''_ij| x_i <= a_j`` (a standstill in path
  acceleration keeps every joint inside its acceleration limit: the maximum velocity
  curve). Sharp corners have a large ``q''`` and so a low cap: the law slows through them.
* Interval ``i`` must keep ``|q''_pj x_p + q'_pj u_i| <= a_j`` at **both** its ends
  ``p = i, i+1``, for every joint, and also the interval's mean acceleration
  ``(qd_{i+1} - qd_i) / dt`` (what a consumer differentiating the samples sees; at a
  sharp corner it exceeds both end values when the speed changes across the interval):
  see :func:`_rows`. Each row is linear in ``(x_i, x_{i+1})``, so the feasible pairs
  form a convex polygon containing the diagonal ``x_i = x_{i+1} <= cap``.
* ``x = 0`` at the first and last point (rest to rest).

Algorithm (Bobrow / Shin-McKay on the discrete path): a forward pass takes the largest
``x_{i+1}`` reachable from ``x_i`` (capped), then a backward pass lowers each ``x_i`` to
the largest value from which ``x_{i+1}`` can still be reached. By convexity every final
pair is feasible, and the profile is the pointwise largest feasible one below the caps
on this grid (time-optimal for the model; two conservative choices: the acceleration cap
asks ``u = 0`` to be feasible, and the interval-mean row takes the worst ``m``). Both
passes are sequential recurrences, but on most of a drawing the cap
profile itself is feasible (marking at the feed): those stretches are copied with one
vectorised test and only points near ramps, corners and travel are stepped one by one.

Velocity and acceleration are then within the limits at every point, to rounding
(checked, :meth:`TimeLaw.check`). Accelerations are per interval end; the reported
``qdd`` at a point is the mean of the two interval ends meeting there (a convex mix, so
within the limits too).

The tip's acceleration limit (:class:`TipLimit`) enters the same passes as eight virtual
joints (:meth:`TipLimit.channels`). A jerk limit (``jerk_rad_s3``) caps the speed where the
path's own third derivative is large, then filters each stretch between rests with a
moving average in time (:func:`_box_filter_law`) and repairs the samples that still
exceed a limit (:func:`_jerk_pieces`); the filtered law keeps every limit, the feed
included, at every sample (and each interval's mean acceleration), with continuous
acceleration.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from tattotronix.errors import TattotronixError
from tattotronix.robot.description import RobotDescription

__all__ = ["JointLimits", "TimeLaw", "TipLimit", "sample_jerk", "sample_rate",
           "time_parameterise"]

Array = NDArray[np.float64]
_MAX_PASSES = 50  # forward/backward repeats before giving up (one on real paths)
_REL_TOL = 1e-9  # rounding slack in the feasibility tests (relative to a limit)
_SHRINK = 1.0 - 1e-9  # the limits the passes use, relative to the true ones
_TIP_DIRS = 8  # directions of the tip-acceleration polygon (a 16-gon)
_TIP_SHRINK = math.cos(math.pi / (2 * _TIP_DIRS))  # the 16-gon's inradius over the circle's
_JERK_GEOMETRY = 0.5  # share of the jerk limit the path's own third derivative may take
_WINDOW_MARGIN = 1.25  # the filter window over 2 a / J (room for the geometric share)
_MAX_REPAIRS = 60  # rounds of lowering caps where the filtered law exceeds a limit
_WIDEN_EVERY = 6  # rounds after which the filter window widens (and the caps reset)
_WIDEN = 1.5  # how much it widens
_MIN_WINDOW_S = 1e-3  # the shortest filter window, s
_REPAIR_MARGIN = 0.9  # a repaired cap sits this far under the speed^2 that fits
_MIN_CAP = 1e-12  # (m/s)^2: a repaired cap never reaches zero inside the path
_FEED_TOL = 1.0 + 1e-9  # a filtered speed may sit this far over the feed (rounding)
_REPAIR_REACH = 1.5  # windows either side of a point whose caps a repair lowers


@dataclass(frozen=True)
class JointLimits:
    """Per-joint limits the time law keeps.

    Attributes:
        joints: joint names, base outward.
        velocity: (n,) rad/s.
        acceleration: (n,) rad/s^2.
    """

    joints: tuple[str, ...]
    velocity: Array
    acceleration: Array

    def __post_init__(self) -> None:
        for what, arr in (("velocity", self.velocity), ("acceleration", self.acceleration)):
            if arr.shape != (len(self.joints),) or not np.all(np.isfinite(arr)) or np.any(
                    arr <= 0):
                raise TattotronixError(f"joint {what} limits must be {len(self.joints)} "
                                       f"positive numbers, got {arr.tolist()}")

    @classmethod
    def from_description(cls, desc: RobotDescription,
                         accel_rad_s2: float | list[float]) -> JointLimits:
        """Velocity limits from the robot description's joints (the URDF's), and the
        acceleration limit from config.

        Args:
            desc: the robot description.
            accel_rad_s2: the acceleration limit, rad/s^2 (one for all, or per joint).
        """
        names = desc.joint_names
        vel = np.array([float(j.velocity) for j in desc.joints])
        acc = np.broadcast_to(np.asarray(accel_rad_s2, dtype=np.float64), vel.shape).copy()
        return cls(names, vel, acc)


@dataclass(frozen=True)
class TimeLaw:
    """The time law along a path.

    Attributes:
        t: (N,) time of each point, s, from 0, strictly increasing.
        s: (N,) arc length, m.
        sdot: (N,) path speed, m/s.
        sddot: (N,) path acceleration, m/s^2 (mean of the two intervals at a point).
        qd: (N, n) joint velocity, rad/s.
        qdd: (N, n) joint acceleration, rad/s^2.
        qdd_ends: (N-1, 2, n) joint acceleration at the start and end of each interval,
            rad/s^2 (the law's acceleration is constant in ``s`` per interval, and the
            joints' jumps at points where curvature changes).
        stepped: points the two passes visited one at a time (the rest were copied).
        solve_s: wall time of the passes, s.
        tip_accel: (N,) the tip's acceleration magnitude, m/s^2 (zeros without a tip
            limit).
        window_s: the jerk filter's window, s (0: no jerk limit).
        repairs: rounds of lowered caps the jerk limit took.
    """

    t: Array
    s: Array
    sdot: Array
    sddot: Array
    qd: Array
    qdd: Array
    qdd_ends: Array
    stepped: int
    solve_s: float
    tip_accel: Array
    window_s: float = 0.0
    repairs: int = 0

    @property
    def duration_s(self) -> float:
        """Total time, s."""
        return float(self.t[-1]) if len(self.t) else 0.0

    def check(self, limits: JointLimits, rel_tol: float = 1e-6, *,
              jerk_rad_s3: float | None = None, tip: TipLimit | None = None) -> None:
        """Raise ``AssertionError`` when a velocity, an acceleration, a jerk (with a jerk
        limit) or the tip's acceleration (with a tip limit) exceeds its limit."""
        v = np.abs(self.qd).max(axis=0) / limits.velocity if len(self.qd) else 0.0
        a = (np.abs(self.qdd_ends).max(axis=(0, 1)) / limits.acceleration
             if len(self.qdd_ends) else 0.0)
        j = 0.0
        if jerk_rad_s3 is not None:
            j = float(sample_jerk(self.t, self.qdd).max(initial=0.0)) / jerk_rad_s3
        w = 0.0
        if tip is not None and jerk_rad_s3 is not None and tip.points().any():
            w = float(self.tip_accel[tip.points()].max() / tip.accel_m_s2)
        if (np.any(v > 1 + rel_tol) or np.any(a > 1 + rel_tol) or j > 1 + rel_tol
                or w > 1 + rel_tol):
            raise AssertionError(f"time law out of limits: velocity/limit {v}, "
                                 f"acceleration/limit {a}, jerk/limit {j:.6g}, tip "
                                 f"acceleration/limit {w:.6g}")


def sample_rate(t: Array, x: Array) -> Array:
    """(N-1, n) ``|x_{i+1} - x_i| / (t_{i+1} - t_i)``: what a consumer differentiating the
    samples sees (the interval's mean acceleration of ``qd``, its jerk of ``qdd``)."""
    return np.asarray(np.abs(np.diff(x, axis=0)) / np.diff(t)[:, None])


def sample_jerk(t: Array, qdd: Array) -> Array:
    """(N-1, n) the jerk at the samples: the change of acceleration from one sample to
    the next over their time, rad/s^3 (what the jerk limit holds)."""
    return sample_rate(t, qdd)


def _at_points(per_interval: Array) -> Array:
    """(N,) the larger of the two intervals meeting at each point (N-1 values given)."""
    out = np.zeros(len(per_interval) + 1)
    out[:-1] = per_interval
    out[1:] = np.maximum(out[1:], per_interval)
    return out


def _rows(dq: Array, d2q: Array, h: Array) -> tuple[Array, Array]:
    """Per interval and constraint row, the coefficients of ``x_i`` and ``x_{i+1}``.

    ``|P x_i + Q x_{i+1}| <= a`` per joint, four rows each (blocks of n): the joint
    acceleration at the interval's start and at its end, and the interval's mean
    acceleration ``(qd_{i+1} - qd_i) / dt = mean(q') u + kappa m`` with ``kappa =
    (q'_{i+1} - q'_i) / h`` and ``m = ((sdot_i + sdot_{i+1}) / 2)^2``, which lies
    between ``(x_i + x_{i+1}) / 4`` and ``(x_i + x_{i+1}) / 2``: both ends are imposed,
    so the mean acceleration is inside the limit whatever ``m`` is.
    """
    m, n = len(h), dq.shape[1]
    inv2h = (0.5 / h)[:, None]
    k0 = dq[:-1] * inv2h
    k1 = dq[1:] * inv2h
    mid = 0.5 * (k0 + k1)  # mean q' / 2h
    kappa = (dq[1:] - dq[:-1]) * (2.0 * inv2h)
    p = np.empty((m, 4, n))
    q = np.empty((m, 4, n))
    np.subtract(d2q[:-1], k0, out=p[:, 0])
    np.negative(k1, out=p[:, 1])
    np.subtract(0.5 * kappa, mid, out=p[:, 2])
    np.subtract(0.25 * kappa, mid, out=p[:, 3])
    q[:, 0] = k0
    np.add(d2q[1:], k1, out=q[:, 1])
    np.add(0.5 * kappa, mid, out=q[:, 2])
    np.add(0.25 * kappa, mid, out=q[:, 3])
    return p.reshape(m, 4 * n), q.reshape(m, 4 * n)


def _bound(coef_free: Array, coef_fixed: Array, a: Array) -> tuple[Array, Array]:
    """``free <= alpha + beta * fixed`` from ``|coef_free free + coef_fixed fixed| <= a``.

    Rows whose ``coef_free`` is 0 do not bound ``free`` (``alpha = inf``, ``beta = 0``).
    """
    nz = coef_free != 0
    alpha = np.divide(a, np.abs(coef_free), out=np.full_like(coef_free, np.inf), where=nz)
    beta = np.divide(coef_fixed, coef_free, out=np.zeros_like(coef_free), where=nz)
    np.negative(beta, out=beta)
    return alpha, beta


@dataclass(frozen=True)
class _Rows:
    """A path's constraint rows (:func:`_rows`) and the bounds the passes step by
    (:func:`_bound`). They depend on the path alone, not on the caps: a stretch between
    rests takes its slice of the whole path's (:meth:`slice`), and its repairs reuse it.

    Attributes:
        p, q: (M, R) coefficients of ``x_i`` and ``x_{i+1}`` per interval and row.
        lim: (M, R) each row's limit with the rounding slack the feasibility test allows.
        fa, fb: forward bounds, ``x_{i+1} <= fa + fb x_i``.
        ba, bb: backward bounds, ``x_i <= ba + bb x_{i+1}``.
    """

    p: Array
    q: Array
    lim: Array
    fa: Array
    fb: Array
    ba: Array
    bb: Array

    @classmethod
    def of(cls, s: Array, ch: _Channels) -> _Rows:
        """The rows of the path at arc lengths ``s`` with channels ``ch``."""
        p, q = _rows(ch.dq, ch.d2q, np.diff(s))
        a2 = np.tile(ch.acc, (1, 4))
        fa, fb = _bound(q, p, a2)
        ba, bb = _bound(p, q, a2)
        return cls(p, q, a2 * (1.0 + _REL_TOL) + 1e-300, fa, fb, ba, bb)

    def slice(self, part: slice) -> _Rows:
        """The rows of points ``part`` (a contiguous stretch: its intervals), as views."""
        stop = part.stop - 1 if part.stop is not None else None
        cut = slice(part.start, stop)
        return _Rows(self.p[cut], self.q[cut], self.lim[cut], self.fa[cut], self.fb[cut],
                     self.ba[cut], self.bb[cut])

    def feasible(self, x0: Array, x1: Array) -> NDArray[np.bool_]:
        """(M,) whether each pair ``(x0, x1)`` keeps every row within its limit."""
        lhs = self.p * x0[:, None]
        lhs += self.q * x1[:, None]
        np.abs(lhs, out=lhs)
        return np.all(lhs <= self.lim, axis=1)


def _passes(cap: Array, rows: _Rows) -> tuple[Array, int]:
    """One forward and one backward pass under ``cap``: (x = sdot^2 per point, points
    stepped one at a time)."""
    n_pts = len(cap)
    fa, fb, ba, bb = rows.fa, rows.fb, rows.ba, rows.bb
    stepped = 0
    x = np.empty(n_pts)
    x[0] = 0.0
    ok = rows.feasible(cap[:-1], cap[1:])
    bad = np.flatnonzero(~ok)
    i = 0
    while i < n_pts - 1:
        if x[i] == cap[i] and ok[i]:
            k = int(np.searchsorted(bad, i))
            j = int(bad[k]) if k < len(bad) else n_pts - 1
            x[i + 1:j + 1] = cap[i + 1:j + 1]
            i = j
            continue
        y = float(np.min(fa[i] + fb[i] * x[i]))
        # y < 0: nothing is reachable from x_i; the backward pass slows x_i instead
        x[i + 1] = min(cap[i + 1], y) if y > 0 else cap[i + 1]
        stepped += 1
        i += 1

    fwd = x.copy()
    ok = rows.feasible(fwd[:-1], fwd[1:])
    bad = np.flatnonzero(~ok)
    i = n_pts - 2
    while i >= 0:
        if x[i + 1] == fwd[i + 1] and ok[i]:
            k = int(np.searchsorted(bad, i, side="right")) - 1
            i = int(bad[k]) if k >= 0 else -1
            continue
        y = float(np.min(ba[i] + bb[i] * x[i + 1]))
        x[i] = min(fwd[i], max(y, 0.0))
        stepped += 1
        i -= 1
    x[0] = 0.0
    return x, stepped


@dataclass(frozen=True)
class TipLimit:
    """The tip's acceleration limit (tangential and centripetal together) where it applies.

    Attributes:
        dp: (N, 3) ``dp/ds`` of the tip path (finite differences), 1.
        d2p: (N, 3) ``d2p/ds2``, 1/m.
        accel_m_s2: the limit on ``|p'' sdot^2 + p' sddot|``, m/s^2.
        on: (N-1,) the intervals it applies to (marking and approach).
    """

    dp: Array
    d2p: Array
    accel_m_s2: float
    on: NDArray[np.bool_]

    def accel(self, sdot: Array, sddot: Array) -> Array:
        """(N,) the tip's acceleration magnitude at each point, m/s^2."""
        a = self.d2p * (sdot * sdot)[:, None] + self.dp * sddot[:, None]
        return np.asarray(np.linalg.norm(a, axis=1))

    def slice(self, part: slice) -> TipLimit:
        """The limit on points ``part`` (a contiguous stretch)."""
        stop = part.stop - 1 if part.stop is not None else None
        return TipLimit(self.dp[part], self.d2p[part], self.accel_m_s2,
                        self.on[part.start:stop])

    def points(self) -> NDArray[np.bool_]:
        """(N,) the points of an interval it applies to."""
        pts = np.zeros(len(self.on) + 1, bool)
        pts[:-1] |= self.on
        pts[1:] |= self.on
        return pts

    def channels(self) -> tuple[Array, Array]:
        """Virtual joints whose limits, together, keep the tip's acceleration inside the
        circle of radius ``accel_m_s2``.

        With ``t`` the unit tangent, ``p' = c t`` and ``p'' = alpha t + beta n``, the tip's
        acceleration is ``(c u + alpha x) t + beta x n``; channel ``k`` is its component
        along the direction ``theta_k = k pi / K`` of that plane (``K`` =
        :data:`_TIP_DIRS`), each limited to ``accel cos(pi / 2K)`` (:data:`_TIP_SHRINK`):
        the regular 2K-gon those limits cut out lies inside the circle.
        """
        c = np.linalg.norm(self.dp, axis=1)
        unit = np.divide(self.dp, c[:, None], out=np.zeros_like(self.dp),
                         where=c[:, None] > 0)
        alpha = np.einsum("ij,ij->i", self.d2p, unit)
        beta = np.linalg.norm(self.d2p - alpha[:, None] * unit, axis=1)
        theta = np.arange(_TIP_DIRS) * (math.pi / _TIP_DIRS)
        # exact zeros where a direction is normal to the tangent (cos(pi/2) is 6e-17,
        # and a bound divided by it cancels to noise)
        cos = np.where(np.abs(np.cos(theta)) < 1e-12, 0.0, np.cos(theta))
        dg = c[:, None] * cos
        d2g = alpha[:, None] * cos + beta[:, None] * np.sin(theta)
        return dg, d2g


def _box_filter_law(t: Array, s: Array, v: Array, u: Array, window: float
                    ) -> tuple[Array, Array, Array]:
    """Filter the path position ``s(t)`` with a moving average of ``window`` seconds.

    ``s(t)`` is the law's exact piecewise-quadratic position (at rest before 0 and after
    the end). The filtered ``s_f(t) = (1/W) int_{t-W/2}^{t+W/2} s`` has ``sdot_f`` the
    window's mean speed, ``sddot_f = (sdot(t + W/2) - sdot(t - W/2)) / W`` (continuous)
    and path jerk ``(sddot(t + W/2) - sddot(t - W/2)) / W``, at most twice the largest
    path acceleration over ``W``: the FIR jerk limiter of CNC feed planning (Biagiotti and
    Melchiorri, "Trajectory Planning for Automatic Machines and Robots", 2008). The
    geometric path is untouched: only its timing changes, and it lasts ``W`` longer.

    Returns:
        ``(t_f, sdot_f, sddot_f)`` at the points ``s`` (times from 0).
    """
    return _box_filter_laws([(t, s, v, u)], [window])[0]


class _Laws:
    """Several laws (stretches between rests) side by side, each with its filter window:
    the arrays of all of them end to end, so that one NumPy call serves every stretch
    (a drawing has dozens, and most of the filter's cost was per call)."""

    def __init__(self, laws: Sequence[tuple[Array, Array, Array, Array]],
                 windows: Sequence[float]) -> None:
        sizes = np.array([len(law[0]) for law in laws])
        self.start = np.concatenate(([0], np.cumsum(sizes)))
        self.last = self.start[1:] - 1
        self.t = np.concatenate([law[0] for law in laws])
        self.s = np.concatenate([law[1] for law in laws])
        self.v = np.concatenate([law[2] for law in laws])
        # per interval, padded by one so that a point's index is its interval's
        self.u = np.concatenate([np.append(law[3], 0.0) for law in laws])
        # the law's area (the integral of s) at each point, stretch by stretch
        self.cum = np.concatenate([np.concatenate(([0.0], np.cumsum(
            s[:-1] * np.diff(t) + v[:-1] * np.diff(t) ** 2 / 2 + u * np.diff(t) ** 3 / 6)))
            for t, s, v, u in laws])
        self.piece = np.repeat(np.arange(len(laws)), sizes)
        self.window = np.asarray(windows, dtype=np.float64)[self.piece]  # per point
        self.half = self.window / 2

    def at(self, tq: Array, idx: NDArray[np.intp]) -> tuple[Array, Array, Array]:
        """The law's area, position and speed at times ``tq`` (from each stretch's own
        start), ``tq[j]`` on the stretch of point ``idx[j]`` (``idx`` ascending)."""
        start, t = self.start, self.t
        k = np.empty(len(tq), np.intp)
        cuts = np.searchsorted(idx, start)
        for p in np.flatnonzero(np.diff(cuts)):
            a, b = cuts[p], cuts[p + 1]
            k[a:b] = np.searchsorted(t[start[p]:start[p + 1]], tq[a:b], side="right")
        pc = self.piece[idx]
        first, last = start[pc], self.last[pc]
        k += first - 1
        np.maximum(k, first, out=k)  # np.clip's, without its per-call checks
        np.minimum(k, last - 1, out=k)
        tau = tq - t[k]
        sk, vk, uk = self.s[k], self.v[k], self.u[k]
        vel = vk + uk * tau
        pos = sk + tau * (vk + vel) / 2
        inside = self.cum[k] + tau * (sk + tau * (vk / 2 + uk * tau / 6))
        t_end, s_end = t[last], self.s[last]
        before, after = tq < 0.0, tq > t_end
        return (np.where(before, self.s[first] * tq,
                         np.where(after, self.cum[last] + s_end * (tq - t_end), inside)),
                np.where(before, self.s[first], np.where(after, s_end, pos)),
                np.where(before | after, 0.0, vel))


def _box_filter_laws(laws: Sequence[tuple[Array, Array, Array, Array]],
                     windows: Sequence[float]) -> list[tuple[Array, Array, Array]]:
    """:func:`_box_filter_law` of each ``(t, s, sdot, u)`` with its window, all at once
    (each point's arithmetic is the same as alone, to the bit)."""
    law = _Laws(laws, windows)
    t, s, half, window = law.t, law.s, law.half, law.window
    # s_f(tau) = (A(tau + W/2) - A(tau - W/2)) / W with A the integral of s: a point's
    # filtered time solves s_f(tau) = s_i, and lies within W/2 of its own time (s_f is
    # between s(tau - W/2) and s(tau + W/2)). Halley's method in that bracket (the first
    # and second derivatives are the differences of s and sdot across the window, known
    # at no cost; near a rest s_f is cubic-like, where Newton's steps are slow),
    # bisecting where a step would leave it; each round only the points whose time
    # still moved by more than a picosecond.
    lo, hi = t - half, t + half
    tf = t.copy()
    goal = s * window
    ends = np.zeros(len(t), bool)
    ends[law.start[:-1]] = ends[law.last] = True
    todo = np.flatnonzero(~ends)  # the ends are set below
    tol = 1e-12
    for _ in range(100):
        tq, hq = tf[todo], half[todo]
        a1, p1, w1 = law.at(tq + hq, todo)
        a0, p0, w0 = law.at(tq - hq, todo)
        f = a1 - a0 - goal[todo]
        slope = p1 - p0
        bend = w1 - w0
        lo_t = np.where(f < 0, tq, lo[todo])
        hi_t = np.where(f > 0, tq, hi[todo])
        lo[todo], hi[todo] = lo_t, hi_t
        with np.errstate(divide="ignore", invalid="ignore"):
            nxt = tq - 2.0 * f * slope / (2.0 * slope * slope - f * bend)
        off = ~((nxt > lo_t) & (nxt < hi_t))
        nxt[off] = 0.5 * (lo_t[off] + hi_t[off])
        tf[todo] = nxt
        moving = (np.abs(nxt - tq) > tol)
        todo = todo[moving]
        if not todo.size:
            break
    tf[law.start[:-1]] = -half[law.start[:-1]]
    tf[law.last] = t[law.last] + half[law.last]
    every = np.arange(len(t))
    _, pp, vp = law.at(tf + half, every)
    _, pm, vm = law.at(tf - half, every)
    sdot_f, sddot_f = (pp - pm) / window, (vp - vm) / window
    sdot_f[ends] = 0.0  # at rest (the window's mean is 0 there, to rounding)
    sddot_f[ends] = 0.0
    tf += half
    return [(tf[a:b], sdot_f[a:b], sddot_f[a:b])
            for a, b in zip(law.start[:-1], law.start[1:], strict=True)]


@dataclass(frozen=True)
class _Channels:
    """The constraint channels of one path: the joints, then the tip's virtual joints."""

    dq: Array  # (N, C)
    d2q: Array  # (N, C)
    vel: Array  # (C,) velocity limits (inf for the tip's)
    acc: Array  # (N-1, C) acceleration limit per interval (inf where off)

    def slice(self, part: slice) -> _Channels:
        """The channels of points ``part`` (a contiguous stretch)."""
        stop = part.stop - 1 if part.stop is not None else None
        return _Channels(self.dq[part], self.d2q[part], self.vel,
                         self.acc[part.start:stop])


def _caps(s: Array, ch: _Channels, sdot_cap: Array, n_joints: int,
          jerk: float | None) -> Array:
    """The squared path-speed cap per point: feed, velocity, acceleration standstill, and
    with a jerk limit, the share of it the path's own third derivative takes at speed
    (``|dq3/ds3| sdot^3 <= share J``)."""
    h = np.diff(s)
    acc_pt = np.full(ch.dq.shape, np.inf)
    acc_pt[:-1] = ch.acc
    acc_pt[1:] = np.minimum(acc_pt[1:], ch.acc)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        v_cap = np.min(ch.vel / np.abs(ch.dq), axis=1) ** 2  # inf where no joint moves
        a_cap = np.nan_to_num(np.min(acc_pt / np.abs(ch.d2q), axis=1), nan=np.inf)
        chord = np.nan_to_num(np.min(ch.acc / np.abs(np.diff(ch.dq, axis=0) / h[:, None]),
                                     axis=1), nan=np.inf)
    a_cap[:-1] = np.minimum(a_cap[:-1], chord)
    a_cap[1:] = np.minimum(a_cap[1:], chord)
    cap = np.minimum(np.minimum(np.asarray(sdot_cap, dtype=np.float64) ** 2, v_cap), a_cap)
    if jerk is not None:
        third = np.abs(np.diff(ch.d2q[:, :n_joints], axis=0) / h[:, None]).max(axis=1)
        with np.errstate(divide="ignore"):
            j_cap = (_JERK_GEOMETRY * jerk / third) ** (2.0 / 3.0)
        cap[:-1] = np.minimum(cap[:-1], j_cap)
        cap[1:] = np.minimum(cap[1:], j_cap)
    cap[0] = cap[-1] = 0.0
    return cap


def _topp(cap: Array, rows: _Rows) -> tuple[Array, int]:
    """The largest feasible ``x = sdot^2`` under ``cap`` (the module docstring's passes).

    Rest points (a cap of 0) split the path: the passes restart from rest at each, so the
    law of a stretch between two rests is the same whether it is solved alone or with
    the whole path, to the bit (the jerk filter solves the whole path once, then each
    stretch it repairs on its own)."""
    stepped = 0
    # Where the forward pass finds no reachable next state (x_i too fast for what
    # follows), it leaves the next point at its cap and the backward pass slows x_i; the
    # passes repeat on the slower profile until every interval is feasible (once, on
    # every path but the most jagged).
    upper = cap
    for _ in range(_MAX_PASSES):
        x, n_stepped = _passes(upper, rows)
        stepped += n_stepped
        if np.all(rows.feasible(x[:-1], x[1:])) or np.array_equal(x, upper):
            break
        upper = x
    x[0] = 0.0
    return x, stepped


def _law_of(x: Array, h: Array) -> tuple[Array, Array, Array, Array]:
    """``(t, sdot, sddot, u)`` of the squared speeds ``x`` (``u`` per interval)."""
    sdot = np.sqrt(x)
    u = np.diff(x) / (2.0 * h)
    denom = sdot[:-1] + sdot[1:]
    if not np.all(denom > 0):
        i = int(np.flatnonzero(~(denom > 0))[0])
        raise TattotronixError(f"the time law stalls between points {i} and {i + 1}")
    t = np.concatenate(([0.0], np.cumsum(2.0 * h / denom)))
    sddot = np.empty(len(x))
    sddot[0], sddot[-1] = u[0], u[-1]
    sddot[1:-1] = 0.5 * (u[:-1] + u[1:])
    return t, sdot, sddot, u


def _slowdown(t: Array, sdot: Array, sddot: Array, dq: Array, d2q: Array, feed: Array,
              limits: JointLimits, tip: TipLimit | None, jerk: float
              ) -> tuple[Array, bool] | None:
    """Where the filtered law exceeds a limit at a sample (or, for acceleration, over an
    interval between samples): ``(need, jerk_exceeded)`` with
    ``need`` (N,) the factor each point's squared speed must shrink by (1 where it keeps
    every limit), or ``None`` when every sample keeps every limit. The feed (``feed``,
    the squared path-speed cap) and velocity scale with ``sdot``, acceleration with
    ``sdot^2`` and jerk with ``sdot^3``."""
    with np.errstate(divide="ignore", invalid="ignore"):
        # (the filter's mean of a speed held at the feed is the feed, to rounding)
        rf = np.nan_to_num(sdot * sdot / (feed * _FEED_TOL), nan=0.0, posinf=np.inf)
    qd = dq * sdot[:, None]
    qdd = d2q * (sdot * sdot)[:, None] + dq * sddot[:, None]
    rv = (np.abs(qd) / limits.velocity).max(axis=1)
    # at the samples, and each interval's mean (what a consumer differentiating them sees)
    ra = np.maximum((np.abs(qdd) / limits.acceleration).max(axis=1),
                    _at_points((sample_rate(t, qd) / limits.acceleration).max(axis=1)))
    if tip is not None:
        ra = np.maximum(ra, np.where(tip.points(), tip.accel(sdot, sddot)
                                     / tip.accel_m_s2, 0.0))
    rj = _at_points(sample_jerk(t, qdd).max(axis=1) / jerk)
    if rv.max() <= 1.0 and ra.max() <= 1.0 and rj.max() <= 1.0 and rf.max() <= 1.0:
        return None
    with np.errstate(divide="ignore"):
        need = np.minimum(np.minimum(1.0 / rv**2, 1.0 / ra), rj ** (-2.0 / 3.0))
        need = np.minimum(need, 1.0 / rf)
    return np.minimum(need, 1.0), bool(rj.max() > 1.0)


def _lower_caps(cap: Array, t: Array, sdot: Array, need: Array,
                strikes: NDArray[np.int64], window: float) -> Array:
    """The caps lowered, within :data:`_REPAIR_REACH` windows of every point that exceeds
    a limit, to the filtered speed there times the shrink it needs, and a margin that
    tightens each time the same point exceeds again (``strikes``)."""
    out = cap.copy()
    bad = np.flatnonzero(need < 1.0)
    target = sdot[bad] ** 2 * need[bad] * _REPAIR_MARGIN ** (1 + strikes[bad])
    reach = _REPAIR_REACH * window
    # at least the point's neighbours: the window's mean there is made of them
    lo = np.minimum(np.searchsorted(t, t[bad] - reach), np.maximum(bad - 1, 0))
    hi = np.maximum(np.searchsorted(t, t[bad] + reach, side="right"), bad + 2)
    for a, b, v in zip(lo, hi, target, strict=True):
        np.minimum(out[a:b], v, out=out[a:b])
    out[1:-1] = np.maximum(out[1:-1], _MIN_CAP)
    out[0] = out[-1] = 0.0
    return out


@dataclass(frozen=True)
class _Piece:
    """The filtered law of one stretch between rests."""

    t: Array
    sdot: Array
    sddot: Array
    window: float
    repairs: int
    stepped: int


@dataclass
class _Stretch:
    """One rest-to-rest stretch as the jerk filter repairs it (:func:`_jerk_pieces`): its
    path, its caps, its current law and window, and the repair's counters."""

    s: Array
    rows: _Rows
    cap: Array
    feed: Array
    dq: Array
    d2q: Array
    tip: TipLimit | None
    x: Array  # the time-optimal law's squared speeds under ``cap``
    window: float = 0.0
    repairs: int = 0
    stepped: int = 0
    since_widen: int = 0
    # set from the fields above: the steps of ``s``, the current law (``_law_of``), the
    # law the caps started from, and each point's count of repairs
    h: Array = field(init=False)
    t: Array = field(init=False)
    sdot: Array = field(init=False)
    u: Array = field(init=False)
    base: tuple[Array, Array, Array, Array] = field(init=False)
    strikes: NDArray[np.int64] = field(init=False)

    def __post_init__(self) -> None:
        self.h = np.diff(self.s)
        self.t, self.sdot, _, self.u = _law_of(self.x, self.h)
        self.base = (self.cap, self.t, self.sdot, self.u)
        self.strikes = np.zeros(len(self.s), np.int64)

    def law(self) -> tuple[Array, Array, Array, Array]:
        """``(t, s, sdot, u)``: the law the filter takes."""
        return self.t, self.s, self.sdot, self.u

    def start_window(self, jerk: float) -> None:
        """The first window: ``2 a_path / J`` (times :data:`_WINDOW_MARGIN`) with
        ``a_path`` the largest joint acceleration the law's path acceleration makes."""
        a_path = float(np.max(np.abs(self.dq[:-1] * self.u[:, None]).max(axis=1),
                              initial=0.0))
        self.window = max(_WINDOW_MARGIN * 2.0 * a_path / jerk, _MIN_WINDOW_S)

    def repair(self, filtered: tuple[Array, Array, Array], limits: JointLimits,
               jerk: float) -> _Piece | None:
        """The stretch's filtered law when it keeps every limit; else lower the caps (or
        widen the window) and plan again, and None."""
        tf, sdf, sddf = filtered
        found = _slowdown(tf, sdf, sddf, self.dq, self.d2q, self.feed, limits, self.tip,
                          jerk)
        if found is None:
            return _Piece(tf, sdf, sddf, self.window, self.repairs, self.stepped)
        if self.repairs == _MAX_REPAIRS:
            raise TattotronixError(
                f"the time law cannot keep the jerk limit {jerk:g} rad/s^3 on this path "
                f"after {_MAX_REPAIRS} repairs: raise trajectory.jerk_rad_s3")
        self.repairs += 1
        need, jerk_exceeded = found
        self.since_widen += 1
        if jerk_exceeded and self.since_widen >= _WIDEN_EVERY:
            # what lowered caps do not mend is the filter's own path jerk (the law's
            # acceleration switching within one window): widen it and start again
            self.window *= _WIDEN
            self.cap, self.t, self.sdot, self.u = self.base
            self.strikes[:] = 0
            self.since_widen = 0
            return None
        self.cap = _lower_caps(self.cap, tf, sdf, need, self.strikes, self.window)
        self.strikes += need < 1.0
        x, more = _topp(self.cap, self.rows)
        self.stepped += more
        self.t, self.sdot, _, self.u = _law_of(x, self.h)
        return None


def _jerk_pieces(stretches: list[_Stretch], limits: JointLimits, jerk: float
                 ) -> list[_Piece]:
    """The jerk-limited law of each rest-to-rest stretch: its time-optimal law filtered by
    its window (:meth:`_Stretch.start_window`); where a sample still exceeds a limit the
    caps around it are lowered and the law planned again, and every
    :data:`_WIDEN_EVERY` rounds the window widens instead (what lower caps do not mend is
    the filter's own path jerk). Each round filters every stretch still being repaired
    in one batch (:func:`_box_filter_laws`)."""
    for stretch in stretches:
        stretch.start_window(jerk)
    done: dict[int, _Piece] = {}
    todo = list(range(len(stretches)))
    while todo:
        filtered = _box_filter_laws([stretches[i].law() for i in todo],
                                    [stretches[i].window for i in todo])
        still = []
        for i, law in zip(todo, filtered, strict=True):
            piece = stretches[i].repair(law, limits, jerk)
            if piece is None:
                still.append(i)
            else:
                done[i] = piece
        todo = still
    return [done[i] for i in range(len(stretches))]


def time_parameterise(s: Array, dq: Array, d2q: Array, sdot_cap: Array,
                      limits: JointLimits, *, tip: TipLimit | None = None,
                      jerk_rad_s3: float | None = None,
                      rests: ArrayLike | None = None) -> TimeLaw:
    """The fastest rest-to-rest time law along a path under the caps and limits.

    Args:
        s: (N,) strictly increasing arc length, m.
        dq: (N, n) ``dq/ds``, rad/m.
        d2q: (N, n) ``d^2q/ds^2``, rad/m^2.
        sdot_cap: (N,) path-speed cap per point (the feed), m/s.
        limits: joint velocity and acceleration limits.
        tip: the tip's acceleration limit (``None``: none).
        jerk_rad_s3: every joint's jerk limit (``None``: acceleration-limited only). The
            law is then the time-optimal one under the caps, filtered by a moving average
            (:func:`_box_filter_law`) of ``2 a / J`` (times :data:`_WINDOW_MARGIN`); where
            a sample still exceeds a limit, the caps around it are lowered and the law is
            planned again, until none does.
        rests: interior points where the law comes to rest (the stretches between them
            are filtered each with its own window).

    Returns:
        The time law (see the module docstring).

    Raises:
        TattotronixError: fewer than 3 points (rest to rest needs one in between), a
            chord of zero length, a cap of zero inside the path, or a jerk limit the
            repairs cannot meet.
    """
    t0 = time.perf_counter()
    n_pts = len(s)
    n = dq.shape[1]
    if n_pts < 3:
        raise TattotronixError(f"a path needs at least 3 points to start and stop, got {n_pts}")
    h = np.diff(s)
    if not np.all(h > 0):
        i = int(np.flatnonzero(~(h > 0))[0])
        raise TattotronixError(f"path points {i} and {i + 1} coincide (zero-length step)")
    if jerk_rad_s3 is not None and not (math.isfinite(jerk_rad_s3) and jerk_rad_s3 > 0):
        raise TattotronixError(f"the jerk limit must be a positive number, got {jerk_rad_s3}")
    # a hair inside the limits, so rounding in the recurrences never lands above them
    vel, acc = limits.velocity * _SHRINK, limits.acceleration * _SHRINK
    acc_int = np.broadcast_to(acc, (n_pts - 1, n))
    dq_all, d2q_all, vel_all = dq, d2q, vel
    if tip is not None:
        dg, d2g = tip.channels()
        lim = tip.accel_m_s2 * _TIP_SHRINK * _SHRINK
        tip_acc = np.repeat(np.where(tip.on, lim, np.inf)[:, None], _TIP_DIRS, axis=1)
        acc_int = np.hstack([acc_int, tip_acc])
        dq_all, d2q_all = np.hstack([dq, dg]), np.hstack([d2q, d2g])
        vel_all = np.concatenate([vel, np.full(_TIP_DIRS, np.inf)])
    ch = _Channels(dq_all, d2q_all, vel_all, np.ascontiguousarray(acc_int))
    cap = _caps(s, ch, sdot_cap, n, jerk_rad_s3)
    inner = np.ones(n_pts, bool)
    inner[[0, -1]] = False
    stops = np.unique(np.asarray(rests if rests is not None else [], dtype=np.int64))
    if stops.size and (stops.min() < 0 or stops.max() >= n_pts):
        raise TattotronixError(f"rest points {stops.tolist()} outside the path's {n_pts}")
    inner[stops] = False
    cap[stops] = 0.0
    if not np.all(cap[inner] > 0):
        i = int(np.flatnonzero(inner & ~(cap > 0))[0])
        raise TattotronixError(f"the path speed cap is zero at point {i}: a feed of 0")
    rows = _Rows.of(s, ch)
    x, stepped = _topp(cap, rows)
    t, sdot, sddot, u = _law_of(x, h)
    feed = np.asarray(sdot_cap, dtype=np.float64) ** 2
    windows: list[float] = []
    repairs = 0
    if jerk_rad_s3 is not None:
        # each stretch between rests is filtered on its own, with the window its own
        # path accelerations need: short on the ink, where the tip limit keeps them small;
        # each starts from its part of the whole path's law (the rests split it)
        bounds = np.unique(np.concatenate(([0], stops, [n_pts - 1])))
        parts = [slice(int(lo), int(hi) + 1)
                 for lo, hi in zip(bounds[:-1], bounds[1:], strict=True)]
        stretches = [_Stretch(s[part], rows.slice(part), cap[part], feed[part], dq[part],
                              d2q[part], tip.slice(part) if tip is not None else None,
                              x[part]) for part in parts]
        t_parts, v_parts, a_parts = [np.zeros(1)], [np.zeros(1)], [np.zeros(1)]
        clock = 0.0
        for piece in _jerk_pieces(stretches, limits, jerk_rad_s3):
            t_parts.append(clock + piece.t[1:])
            v_parts.append(piece.sdot[1:])
            a_parts.append(piece.sddot[1:])
            clock += float(piece.t[-1])
            windows.append(piece.window)
            repairs += piece.repairs
            stepped += piece.stepped
        t, sdot, sddot = (np.concatenate(t_parts), np.concatenate(v_parts),
                          np.concatenate(a_parts))
    qd = dq * sdot[:, None]
    qdd = d2q * (sdot * sdot)[:, None] + dq * sddot[:, None]
    if jerk_rad_s3 is None:  # constant path acceleration per interval: both its ends
        xx = sdot * sdot
        ends = np.empty((n_pts - 1, 2, n))
        ends[:, 0] = d2q[:-1] * xx[:-1, None] + dq[:-1] * u[:, None]
        ends[:, 1] = d2q[1:] * xx[1:, None] + dq[1:] * u[:, None]
    else:  # continuous path acceleration: the points' own
        ends = np.stack([qdd[:-1], qdd[1:]], axis=1)
    tip_acc_m = tip.accel(sdot, sddot) if tip is not None else np.zeros(n_pts)
    return TimeLaw(t=t, s=np.asarray(s, dtype=np.float64), sdot=sdot, sddot=sddot, qd=qd,
                   qdd=qdd, qdd_ends=ends, stepped=stepped,
                   solve_s=time.perf_counter() - t0, tip_accel=tip_acc_m,
                   window_s=max(windows, default=0.0), repairs=repairs)
