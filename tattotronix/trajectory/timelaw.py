"""Time-optimal path speed under joint velocity and acceleration limits (discrete TOPP).

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
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from tattotronix.errors import TattotronixError
from tattotronix.robot.description import RobotDescription

__all__ = ["JointLimits", "TimeLaw", "time_parameterise"]

Array = NDArray[np.float64]
_MAX_PASSES = 50  # forward/backward repeats before giving up (one on real paths)
_REL_TOL = 1e-9  # rounding slack in the feasibility tests (relative to a limit)
_SHRINK = 1.0 - 1e-9  # the limits the passes use, relative to the true ones


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

    @property
    def duration_s(self) -> float:
        """Total time, s."""
        return float(self.t[-1]) if len(self.t) else 0.0

    def check(self, limits: JointLimits, rel_tol: float = 1e-6) -> None:
        """Raise ``AssertionError`` when a velocity or acceleration exceeds its limit."""
        v = np.abs(self.qd).max(axis=0) / limits.velocity if len(self.qd) else 0.0
        a = (np.abs(self.qdd_ends).max(axis=(0, 1)) / limits.acceleration
             if len(self.qdd_ends) else 0.0)
        if np.any(v > 1 + rel_tol) or np.any(a > 1 + rel_tol):
            raise AssertionError(f"time law out of limits: velocity/limit {v}, "
                                 f"acceleration/limit {a}")


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


def _feasible(p: Array, q: Array, a: Array, x0: Array, x1: Array) -> NDArray[np.bool_]:
    """(M,) whether each pair ``(x0, x1)`` keeps every row within its limit."""
    lhs = np.abs(p * x0[:, None] + q * x1[:, None])
    return np.all(lhs <= a * (1.0 + _REL_TOL) + 1e-300, axis=1)


def _passes(cap: Array, p: Array, q: Array, a2: Array, fa: Array, fb: Array, ba: Array,
            bb: Array) -> tuple[Array, int]:
    """One forward and one backward pass under ``cap``: (x = sdot^2 per point, points
    stepped one at a time)."""
    n_pts = len(cap)
    stepped = 0
    x = np.empty(n_pts)
    x[0] = 0.0
    ok = _feasible(p, q, a2, cap[:-1], cap[1:])
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
    ok = _feasible(p, q, a2, fwd[:-1], fwd[1:])
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


def time_parameterise(s: Array, dq: Array, d2q: Array, sdot_cap: Array,
                      limits: JointLimits) -> TimeLaw:
    """The fastest rest-to-rest time law along a path under the caps and joint limits.

    Args:
        s: (N,) strictly increasing arc length, m.
        dq: (N, n) ``dq/ds``, rad/m.
        d2q: (N, n) ``d^2q/ds^2``, rad/m^2.
        sdot_cap: (N,) path-speed cap per point (the feed), m/s.
        limits: joint velocity and acceleration limits.

    Returns:
        The time law (see the module docstring).

    Raises:
        TattotronixError: fewer than 3 points (rest to rest needs one in between), a
            chord of zero length, or a cap of zero inside the path.
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
    # a hair inside the limits, so rounding in the recurrences never lands above them
    vel, acc = limits.velocity * _SHRINK, limits.acceleration * _SHRINK
    with np.errstate(divide="ignore"):
        v_cap = np.min(vel / np.abs(dq), axis=1) ** 2  # inf where no joint moves
        a_cap = np.min(acc / np.abs(d2q), axis=1)
        chord = np.min(acc / np.abs(np.diff(dq, axis=0) / h[:, None]), axis=1)
    a_cap[:-1] = np.minimum(a_cap[:-1], chord)
    a_cap[1:] = np.minimum(a_cap[1:], chord)
    cap = np.minimum(np.minimum(np.asarray(sdot_cap, dtype=np.float64) ** 2, v_cap), a_cap)
    cap[0] = cap[-1] = 0.0
    if not np.all(cap[1:-1] > 0):
        i = int(np.flatnonzero(~(cap[1:-1] > 0))[0]) + 1
        raise TattotronixError(f"the path speed cap is zero at point {i}: a feed of 0")
    p, q = _rows(dq, d2q, h)
    a2 = np.concatenate((acc, acc, acc, acc))
    fa, fb = _bound(q, p, a2)  # forward: x_{i+1} <= fa + fb x_i
    ba, bb = _bound(p, q, a2)  # backward: x_i <= ba + bb x_{i+1}
    stepped = 0

    # Forward then backward pass. Where the forward pass finds no reachable next state
    # (x_i too fast for what follows), it leaves the next point at its cap and the
    # backward pass slows x_i; the passes repeat on the slower profile until every
    # interval is feasible (once, on every path but the most jagged).
    upper = cap
    for _ in range(_MAX_PASSES):
        x, n_stepped = _passes(upper, p, q, a2, fa, fb, ba, bb)
        stepped += n_stepped
        if np.all(_feasible(p, q, a2, x[:-1], x[1:])) or np.array_equal(x, upper):
            break
        upper = x
    x[0] = 0.0

    sdot = np.sqrt(x)
    u = np.diff(x) / (2.0 * h)
    denom = sdot[:-1] + sdot[1:]
    if not np.all(denom > 0):
        i = int(np.flatnonzero(~(denom > 0))[0])
        raise TattotronixError(f"the time law stalls between points {i} and {i + 1}")
    dt = 2.0 * h / denom
    t = np.concatenate(([0.0], np.cumsum(dt)))
    sddot = np.empty(n_pts)
    sddot[0], sddot[-1] = u[0], u[-1]
    sddot[1:-1] = 0.5 * (u[:-1] + u[1:])
    qd = dq * sdot[:, None]
    qdd = d2q * x[:, None] + dq * sddot[:, None]
    ends = np.empty((n_pts - 1, 2, n))
    ends[:, 0] = d2q[:-1] * x[:-1, None] + dq[:-1] * u[:, None]
    ends[:, 1] = d2q[1:] * x[1:, None] + dq[1:] * u[:, None]
    return TimeLaw(t=t, s=np.asarray(s, dtype=np.float64), sdot=sdot, sddot=sddot, qd=qd,
                   qdd=qdd, qdd_ends=ends, stepped=stepped,
                   solve_s=time.perf_counter() - t0)
