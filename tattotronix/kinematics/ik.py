"""Whole-path inverse kinematics: the tip on the target with the needle along a given axis.

Explained in docs/kinematics.md, "Inverse kinematics"; the original's method is
docs/original.md, "3.1 The task Jacobian", "3.2 The solver" and "3.3 Refusals".

**Task.** Five coordinates: the tip position (3) and the needle axis (2). The needle is a
body of revolution, so the spin about it is free and the solver works with a 5x5 task
Jacobian: the three linear rows of the world-aligned geometric Jacobian, then two tilt
rows ``u . (w_i x z)`` and ``v . (w_i x z)``, with ``w_i`` the angular column, ``z`` the
current needle axis and ``u``, ``v`` a basis normal to it (``a = x`` unless
``|z . x| > 0.9``, then ``y``; ``u = normalise(z x a)``; ``v = z x u``). By the triple
product, ``u . (w x z) = w . v`` and ``v . (w x z) = -w . u``, which is how they are formed.

**Solver** (damped least squares): error ``e = [p_des - p; u . (z_des - z); v . (z_des -
z)]``; step ``dq = J^T (J J^T + lambda I)^-1 e`` (``dls_lambda`` added as is, not squared);
``q <- clip(q + dq, lower, upper)``. Convergence ``|e| < tol`` is tested at the top of
each iteration, at most ``max_iter`` of them. A point that does not converge reports the
residual ``|[p_des - p, z_des - z]|`` and a reason: ``joint limit`` when a clamp bit in
its last step, else ``unreachable``.

**Speed.** :func:`solve_point` is the single-point reference on Pinocchio (the trusted
solver, and what the original ran per point). :func:`solve_path` runs the same iteration
on every point of a path at once, in lockstep, in structure-of-arrays numpy (see
:mod:`tattotronix.kinematics.chain`); a point stops changing once it has converged. The
warm start still follows the path order, as a sequential solve does:

1. *Anchors*: the first point, both ends of every step at least ``anchor_spacing_m``
   long (travel between strokes), and a point every ``anchor_spacing_m`` of path.
2. The anchors are solved together from the seed, then re-solved each from its
   predecessor's solution until every anchor is what a solve warm-started from its
   predecessor gives (same solution branch): a parallel-in-time fixed point, which
   usually settles in one round.
3. Every other point starts from the interpolation (by path length) of the solutions of
   the anchors around it, and all are solved at once.
4. A point whose solution is not on its predecessor's branch (a joint step above
   ``branch_tol_rad``, more for long steps), or that failed, is solved again
   warm-started from its predecessor, in batched rounds, until nothing changes.
5. Where the first points failed from the seed (a path that starts far from it: a needle
   tilted along a limb's normal), they are solved again backwards, each from the point
   after it, from the first one that converged.

So every accepted point is a converged solution of the same iteration, on the branch a
warm-started path solve follows; seeded with the same ``q``, the batched iteration
repeats Pinocchio's to rounding (tested). :func:`verify` checks every solution against
Pinocchio's FK. One deliberate difference: a point is never warm-started from a failed
predecessor. A failed solve ends clamped in a joint-limit corner, and a sequential
solve warm-started from there usually fails at every later point too, so it would
report a whole tail of failures for one unreachable point; here each failure is a point
that fails from the best warm start available. A path with any failure is refused
either way (:meth:`IkResult.raise_if_failed`), naming the first failing point, which is
the same in both.

Use (what the ``ik`` stage does)::

    chain = Chain.from_description(desc)
    ref = PinocchioTip.from_urdf(out.input("robot", "tattotronix.urdf"), desc.tip_frame)
    res = solve_path(chain, xyz_m, dls_lambda=..., max_iter=..., tol=..., seed=...,
                     needle_axis=..., progress=bar)
    res.raise_if_failed(uvz_mm)           # IkFailure: the stage writes nothing
    check = verify(ref, res, xyz_m)       # IkVerificationError on a model mismatch
    metrics = {**res.summary(), **conditioning(chain, res.q).summary(), **check.summary()}

The ``ik`` config group this module expects (``tattotronix.config.schema``)::

    @dataclass
    class IkConfig:
        \"\"\"Whole-path IK (damped least squares on the 5x5 task Jacobian).\"\"\"

        dls_lambda: float = 1e-3       # the DLS lambda, added to J J^T as is
        max_iter: int = 200
        tol: float = 1e-6              # |e|, mixed m / unitless
        seed: list[float] = field(default_factory=lambda: [0.0, 0.6, -0.9, 0.0, -1.2])
        needle_axis: list[float] = field(default_factory=lambda: [0.0, 0.0, -1.0])
        anchor_spacing_m: float = 0.005  # batched solver: anchor every 5 mm of path
        verify_pos_tol_m: float = 2e-6  # Pinocchio FK check of every solution
        verify_axis_tol_rad: float = 2e-6
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TypedDict

import numpy as np
from numpy.typing import ArrayLike, NDArray

from tattotronix.config.schema import IkConfig
from tattotronix.errors import TattotronixError
from tattotronix.io.jsontypes import JsonDict
from tattotronix.kinematics.chain import Chain, Num, SoaState, Vec3
from tattotronix.robot.description import RobotDescription
from tattotronix.robot.loaders import (
    STANDARD_GRAVITY,
    load_pinocchio,
    model_refused,
    pinocchio_model,
)

__all__ = [
    "Conditioning",
    "IkFailure",
    "IkOptions",
    "IkResult",
    "IkVerificationError",
    "PinocchioTip",
    "PointResult",
    "Verification",
    "conditioning",
    "solve_path",
    "solve_path_sequential",
    "solve_point",
    "solve_points",
    "task_jacobian",
    "verify",
]

Array = NDArray[np.float64]
Progress = Callable[[int, int], None]


class IkOptions(TypedDict, total=False):
    """Solver settings of :func:`solve_path` (besides the targets and the seed), as the
    ``ik`` config group gives them (:func:`ik_options`)."""

    needle_axis: ArrayLike
    dls_lambda: float
    max_iter: int
    tol: float
    anchor_spacing_m: float


def ik_options(ik: IkConfig) -> IkOptions:
    """The solver's settings from the ``ik`` config group (the seed apart: a caller seeds
    from where it is)."""
    return {"needle_axis": list(ik.needle_axis), "dls_lambda": float(ik.dls_lambda),
            "max_iter": int(ik.max_iter), "tol": float(ik.tol),
            "anchor_spacing_m": float(ik.anchor_spacing_m)}

# the schema's defaults: the original's settings (docs/original.md, "3.2 The solver")
_DEFAULTS = IkConfig()
DLS_LAMBDA = _DEFAULTS.dls_lambda
MAX_ITER = _DEFAULTS.max_iter
TOL = _DEFAULTS.tol
SEED = tuple(_DEFAULTS.seed)
NEEDLE_AXIS = tuple(_DEFAULTS.needle_axis)
ANCHOR_SPACING_M = _DEFAULTS.anchor_spacing_m
BRANCH_TOL_RAD = 0.05
BLOCK = 65536  # points solved in one lockstep batch
JOINT_LIMIT = "joint limit"
UNREACHABLE = "unreachable"


class IkFailure(TattotronixError):
    """IK did not converge at every point; the message names the first failing point."""


class IkVerificationError(TattotronixError):
    """A solution does not put Pinocchio's tip on its target (a model mismatch)."""


# --- result types --------------------------------------------------------------------------

@dataclass(frozen=True)
class PointResult:
    """One IK solve.

    Attributes:
        q: (n,) joint angles, rad.
        converged: ``|e| < tol`` was reached.
        residual: ``|e|`` when converged, else ``|[p_des - p, z_des - z]|`` (m and
            unitless mixed).
        iterations: steps taken.
        reason: ``""`` when converged, else ``joint limit`` or ``unreachable``.
        at_limit: (n,) joints whose clamp bit in the last step.
    """

    q: Array
    converged: bool
    residual: float
    iterations: int
    reason: str
    at_limit: NDArray[np.bool_]


@dataclass(frozen=True)
class IkResult:
    """IK over a whole path.

    Attributes:
        q: (N, n) joint angles, rad.
        converged: (N,) bool.
        residual: (N,) ``|e|`` for converged points, ``|[p_des - p, z_des - z]|`` else.
        iterations: (N,) iterations of the solve that produced each point.
        reason: (N,) ``""``, ``joint limit`` or ``unreachable``.
        at_limit: (N, n) joints whose clamp bit in the last step of a failed point.
        solve_s: the solver's own wall time, s.
        joint_names: the joints, base outward.
        stats: how the work was split (anchors, rounds, re-solved points, point-iterations).
    """

    q: Array
    converged: NDArray[np.bool_]
    residual: Array
    iterations: NDArray[np.int64]
    reason: NDArray[np.str_]
    at_limit: NDArray[np.bool_]
    solve_s: float
    joint_names: tuple[str, ...] = ()
    stats: JsonDict = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        """Every point converged."""
        return bool(np.all(self.converged))

    @property
    def points(self) -> int:
        """Number of points."""
        return len(self.converged)

    @property
    def converged_pct(self) -> float:
        """Share of converged points, %."""
        return 100.0 * float(np.mean(self.converged)) if self.points else 100.0

    @property
    def worst_residual(self) -> float:
        """The largest residual."""
        return float(self.residual.max()) if self.points else 0.0

    def timings(self) -> dict[str, float]:
        """Wall time of the solve and its rate (never in a metrics file: they vary)."""
        return {"solve_s": self.solve_s,
                "points_per_s": self.points / self.solve_s if self.solve_s > 0 else 0.0}

    def summary(self) -> JsonDict:
        """Metrics: ``points``, ``converged_pct``, ``worst_residual``, ``failed``,
        ``iterations_mean``, ``iterations_max`` (wall times are in :meth:`timings`)."""
        return {
            "points": self.points,
            "converged_pct": self.converged_pct,
            "worst_residual": self.worst_residual,
            "failed": int((~self.converged).sum()),
            "iterations_mean": float(self.iterations.mean()) if self.points else 0.0,
            "iterations_max": int(self.iterations.max()) if self.points else 0,
        }

    @property
    def failed(self) -> NDArray[np.intp]:
        """Indices of the points that did not converge, in path order."""
        return np.flatnonzero(~self.converged)

    def raise_if_failed(self, uvz_mm: ArrayLike | None = None,
                        targets_m: ArrayLike | None = None) -> None:
        """Raise :class:`IkFailure` naming the first failing point, if any failed.

        Args:
            uvz_mm: (N, 3) panel coordinates, mm, to name the point by (preferred).
            targets_m: (N, 3) arm-frame targets, m, used when ``uvz_mm`` is not given.
        """
        bad = self.failed
        if not len(bad):
            return
        i = int(bad[0])
        if uvz_mm is not None:
            u = np.asarray(uvz_mm, dtype=float)[i]
            where = f"panel ({u[0]:.2f}, {u[1]:.2f}, {u[2]:.2f}) mm"
        elif targets_m is not None:
            x = np.asarray(targets_m, dtype=float)[i] * 1000.0
            where = f"arm frame ({x[0]:.2f}, {x[1]:.2f}, {x[2]:.2f}) mm"
        else:
            where = "an unnamed position"
        reason = str(self.reason[i])
        if reason == JOINT_LIMIT and self.joint_names:
            joints = [self.joint_names[k] for k in np.flatnonzero(self.at_limit[i])]
            reason += f" ({', '.join(joints)})"
        raise IkFailure(
            f"IK failed at {len(bad)} of {self.points} path points; the first is point {i} at "
            f"{where}: residual {self.residual[i]:.3g} after {int(self.iterations[i])} "
            f"iterations, {reason}. The arm cannot reach it with the needle on its axis: "
            f"move or shrink the drawing (nothing written)"
        )


# --- the batched iteration -----------------------------------------------------------------

def _basis(z: Vec3) -> tuple[Vec3, Vec3]:
    """``u, v`` normal to ``z`` (see module docstring)."""
    z0, z1, z2 = z
    flip = np.abs(z0) > 0.9
    if isinstance(flip, np.ndarray) and flip.any():
        ux: Num = np.where(flip, -z2, 0.0)
        uy: Num = np.where(flip, 0.0, z2)
        uz: Num = np.where(flip, z0, -z1)
    elif isinstance(flip, np.bool_ | bool) and flip:
        ux, uy, uz = -z2, 0.0, z0
    else:
        ux, uy, uz = 0.0, z2, -z1  # z x x-hat
    inv = 1.0 / np.sqrt(ux * ux + uy * uy + uz * uz)
    u = (ux * inv if not isinstance(ux, float) else ux,
         uy * inv if not isinstance(uy, float) else uy,
         uz * inv)
    v = (z1 * u[2] - z2 * u[1], z2 * u[0] - z0 * u[2], z0 * u[1] - z1 * u[0])
    return u, v


def _dot(a: Sequence[Num], b: Sequence[Num]) -> Num:
    """Sum of products, skipping constant zeros."""
    acc: Num | None = None
    for x, y in zip(a, b, strict=True):
        if (isinstance(x, float) and x == 0.0) or (isinstance(y, float) and y == 0.0):
            continue
        acc = x * y if acc is None else acc + x * y
    return 0.0 if acc is None else acc


def _task_rows(st: SoaState) -> tuple[list[list[Num]], Vec3, Vec3]:
    """The 5 x n task Jacobian as rows of entries, and the basis ``u, v``."""
    u, v = _basis(st.z)
    lin = st.linear_columns()
    rows: list[list[Num]] = [[c[r] for c in lin] for r in range(3)]
    rows.append([_dot(w, v) for w in st.axes])  # u . (w x z)
    rows.append([-_dot(w, u) for w in st.axes])  # v . (w x z)
    return rows, u, v


def _errors(st: SoaState, u: Vec3, v: Vec3, p_des: Sequence[Num], z_des: Sequence[Num]
            ) -> tuple[list[Num], Num]:
    """Task error ``e`` (5 entries) and its squared norm."""
    e: list[Num] = [p_des[k] - st.p[k] for k in range(3)]
    dz = [z_des[k] - st.z[k] for k in range(3)]
    e.append(_dot(u, dz))
    e.append(_dot(v, dz))
    return e, _dot(e, e)


def _full_residual(st: SoaState, p_des: Sequence[Num], z_des: Sequence[Num]) -> Array:
    d = [p_des[k] - st.p[k] for k in range(3)] + [z_des[k] - st.z[k] for k in range(3)]
    return np.sqrt(np.asarray(_dot(d, d), dtype=float))


def _dls_step(rows: list[list[Num]], e: list[Num], dls_lambda: float) -> list[Array]:
    """``J^T (J J^T + dls_lambda I)^-1 e`` by an unrolled Cholesky factorisation."""
    m = len(rows)
    a = [[_dot(rows[i], rows[j]) for j in range(i + 1)] for i in range(m)]
    for i in range(m):
        a[i][i] = a[i][i] + dls_lambda
    low: list[list[Any]] = [[None] * m for _ in range(m)]
    inv_d: list[Any] = [None] * m
    for j in range(m):
        d = a[j][j]
        for k in range(j):
            d = d - low[j][k] * low[j][k]
        inv_d[j] = 1.0 / np.sqrt(d)
        low[j][j] = d * inv_d[j]
        for i in range(j + 1, m):
            s = a[i][j]
            for k in range(j):
                s = s - low[i][k] * low[j][k]
            low[i][j] = s * inv_d[j]
    y: list[Any] = [None] * m
    for i in range(m):
        s = e[i]
        for k in range(i):
            s = s - low[i][k] * y[k]
        y[i] = s * inv_d[i]
    for i in reversed(range(m)):
        s = y[i]
        for k in range(i + 1, m):
            s = s - low[k][i] * y[k]
        y[i] = s * inv_d[i]
    n = len(rows[0])
    return [np.asarray(_dot([rows[r][c] for r in range(m)], y), dtype=float)
            for c in range(n)]


@dataclass
class _Batch:
    """Per-point outcome of one lockstep solve (arrays over the points solved)."""

    q: Array  # (n, M) rows
    converged: NDArray[np.bool_]
    residual: Array
    iterations: NDArray[np.int64]
    at_limit: NDArray[np.bool_]  # (n, M)
    point_iterations: int = 0


def _take(x: Num, keep: NDArray[np.bool_]) -> Num:
    return x if isinstance(x, float) else x[keep]


def _as_entries(rows: Array | None, const: Sequence[float] | None) -> list[Num]:
    if rows is not None:
        return list(rows)
    assert const is not None
    return [float(c) for c in const]


def _solve_lockstep(
    chain: Chain, p_des: Array, z_des_rows: Array | None, z_des_const: Sequence[float] | None,
    seeds: Array, *, dls_lambda: float, max_iter: int, tol: float,
    progress: Callable[[int], None] | None = None,
) -> _Batch:
    """Damped least squares on M points at once; a point stops once it has converged.

    Args:
        chain: the kinematic model.
        p_des: (3, M) target rows, m.
        z_des_rows: (3, M) unit needle axes, or None with ``z_des_const`` for one axis.
        z_des_const: one unit needle axis for every point.
        seeds: (n, M) starting joint rows, rad.
        dls_lambda, max_iter, tol: see :func:`solve_path`.
        progress: called with the number of points finished so far.
    """
    n, m = seeds.shape
    out = _Batch(q=seeds.copy(), converged=np.zeros(m, bool), residual=np.zeros(m),
                 iterations=np.zeros(m, np.int64), at_limit=np.zeros((n, m), bool))
    lo, hi = chain.lower[:, None], chain.upper[:, None]
    idx = np.arange(m)
    q = seeds.copy()
    pd, zr = p_des, z_des_rows
    clamp = np.zeros((n, m), bool)
    tol2 = tol * tol
    finished = 0
    for it in range(max_iter + 1):
        st = chain.soa(np.cos(q), np.sin(q))
        zd = _as_entries(zr, z_des_const)
        rows, u, v = _task_rows(st)
        e, e2 = _errors(st, u, v, list(pd), zd)
        e2 = np.asarray(e2, dtype=float)
        if it == max_iter:  # out of iterations: the full, unprojected residual
            out.q[:, idx] = q
            out.residual[idx] = _full_residual(st, list(pd), zd)
            out.iterations[idx] = it
            out.at_limit[:, idx] = clamp
            break
        done = e2 < tol2
        if done.any():
            di = idx[done]
            out.q[:, di] = q[:, done]
            out.converged[di] = True
            out.residual[di] = np.sqrt(e2[done])
            out.iterations[di] = it
            finished += int(done.sum())
            if progress is not None:
                progress(finished)
            keep = ~done
            if not keep.any():
                break
            idx, q, pd = idx[keep], q[:, keep], pd[:, keep]
            zr = zr[:, keep] if zr is not None else None
            rows = [[_take(x, keep) for x in r] for r in rows]
            e = [_take(x, keep) for x in e]
        out.point_iterations += len(idx)
        dq = _dls_step(rows, e, dls_lambda)
        raw = q + np.stack(dq)
        q = np.clip(raw, lo, hi)
        clamp = q != raw
    return out


def solve_points(chain: Chain, targets_m: ArrayLike, seeds: ArrayLike, *,
                 needle_axis: ArrayLike = NEEDLE_AXIS, dls_lambda: float = DLS_LAMBDA,
                 max_iter: int = MAX_ITER, tol: float = TOL
                 ) -> tuple[Array, NDArray[np.bool_]]:
    """IK for independent points, each from its own seed, in one batch (no path: no
    warm start from a neighbour, no anchors): ``(q (N, n), converged (N,))``.

    Args:
        chain: the kinematic model.
        targets_m: (N, 3) tip targets, m.
        seeds: (N, n) the joint angles each point starts from, rad.
        needle_axis: (3,) wanted tip +z for every point, or (N, 3) per point.
        dls_lambda, max_iter, tol: as :func:`solve_path`.

    Raises:
        TattotronixError: targets, axes or seeds of the wrong shape, or bad settings.
    """
    x, z_const, z_rows, _ = _path_inputs(targets_m, needle_axis, np.zeros(chain.n), chain.n)
    _check_settings(dls_lambda, max_iter, tol, ANCHOR_SPACING_M)
    q0 = np.asarray(seeds, dtype=float)
    if q0.shape != (len(x), chain.n) or not np.all(np.isfinite(q0)):
        raise TattotronixError(f"IK seeds must be ({len(x)}, {chain.n}) finite joint angles "
                               f"(rad), got {q0.shape}")
    if not len(x):
        return np.zeros((0, chain.n)), np.zeros(0, bool)
    b = _solve_lockstep(chain, np.ascontiguousarray(x.T), z_rows, z_const,
                        np.ascontiguousarray(q0.T), dls_lambda=dls_lambda,
                        max_iter=max_iter, tol=tol)
    return np.ascontiguousarray(b.q.T), b.converged


# --- the whole path -----------------------------------------------------------------------

def _anchors(x: Array, spacing: float) -> tuple[NDArray[np.intp], Array]:
    """Anchor indices (sorted) and the cumulative path length (m) at every point."""
    step = np.linalg.norm(np.diff(x, axis=0), axis=1)
    s = np.concatenate(([0.0], np.cumsum(step)))
    n_pts = len(x)
    mark = np.zeros(n_pts, bool)
    mark[[0, n_pts - 1]] = True
    big = np.flatnonzero(step >= spacing)
    mark[big] = True
    mark[big + 1] = True
    # one every `spacing` of path: where floor(s / spacing) changes
    mark[1:] |= np.floor(s[1:] / spacing) != np.floor(s[:-1] / spacing)
    return np.flatnonzero(mark), s


def _interpolated_seeds(anchors: NDArray[np.intp], s: Array, qa: Array, ok: NDArray[np.bool_],
                        n_pts: int) -> Array:
    """Seeds (n, N) for every point: linear in path length between its anchors' solutions
    (a failed anchor hands over its neighbour's solution)."""
    qa = qa.copy()
    # a failed anchor takes the previous converged anchor's solution (or the next one's)
    if not ok.all() and ok.any():
        good = np.flatnonzero(ok)
        prev = np.searchsorted(good, np.arange(len(ok)), side="right") - 1
        src = np.where(prev >= 0, good[np.maximum(prev, 0)], good[0])
        qa[:, ~ok] = qa[:, src[~ok]]
    k = np.searchsorted(anchors, np.arange(n_pts), side="right") - 1  # anchor at or before
    k = np.minimum(k, len(anchors) - 2) if len(anchors) > 1 else k
    if len(anchors) == 1:
        return np.repeat(qa, n_pts, axis=1)
    a, b = anchors[k], anchors[k + 1]
    span = s[b] - s[a]
    w = np.where(span > 0, (s - s[a]) / np.where(span > 0, span, 1.0), 0.0)
    w = np.clip(w, 0.0, 1.0)
    return qa[:, k] + w * (qa[:, k + 1] - qa[:, k])


def _settle(
    solve: Callable[[NDArray[np.intp], Array], _Batch], q: Array, conv: NDArray[np.bool_],
    res: Array, iters: NDArray[np.int64], at_limit: NDArray[np.bool_], todo: NDArray[np.intp],
    check: Callable[[NDArray[np.intp]], NDArray[np.bool_]], same_tol: float,
) -> tuple[int, int]:
    """Re-solve the points ``todo`` of a sequence (indices >= 1) warm-started from their
    predecessors' solutions, in batched rounds, until the sequence is settled.

    A re-solved point whose solution changed (moved more than ``same_tol`` rad, or changed
    its convergence) makes its successor a candidate, kept when ``check`` says so. A point
    whose predecessor failed is not re-solved from it: a failed solve ends in a clamped
    corner that a warm start rarely leaves, so failures would cascade down the path.
    The arrays ((n, M) ``q`` and ``at_limit``, (M,) the rest) are updated in place.

    Returns:
        (rounds, points re-solved).
    """
    solved = 0
    rounds = 0
    n_seq = q.shape[1]
    todo = todo[conv[todo - 1]]
    while len(todo):
        rounds += 1
        b = solve(todo, q[:, todo - 1])
        solved += len(todo)
        moved = np.abs(b.q - q[:, todo]).max(axis=0) > same_tol
        changed = moved | (b.converged != conv[todo])
        q[:, todo], conv[todo], res[todo] = b.q, b.converged, b.residual
        iters[todo], at_limit[:, todo] = b.iterations, b.at_limit
        nxt = todo[changed] + 1
        nxt = nxt[nxt < n_seq]
        nxt = nxt[conv[nxt - 1]]
        todo = nxt[check(nxt)]
    return rounds, solved


def _check_settings(dls_lambda: float, max_iter: int, tol: float,
                    anchor_spacing_m: float) -> None:
    """Refuse solver settings that cannot work, naming their ``ik`` key: a lambda <= 0
    (the damped normal equations may have no square root), no iteration at all, a
    tolerance or anchor spacing that is not a positive number."""
    checks = (
        ("ik.dls_lambda", dls_lambda, "a finite number > 0 (the damping, e.g. 1e-3)"),
        ("ik.max_iter", max_iter, "an integer >= 1 (iterations per solve, e.g. 200)"),
        ("ik.tol", tol, "a finite number > 0 (the convergence bound, e.g. 1e-6)"),
        ("ik.anchor_spacing_m", anchor_spacing_m, "a finite number > 0 m (e.g. 0.005)"),
    )
    for key, value, want in checks:
        if isinstance(value, bool) or not isinstance(value, int | float | np.number):
            ok = False
        elif key == "ik.max_iter":
            ok = isinstance(value, int | np.integer) and value >= 1
        else:
            ok = math.isfinite(value) and value > 0
        if not ok:
            raise TattotronixError(f"{key} must be {want} (got {value!r})")


def solve_path(
    chain: Chain,
    targets_m: ArrayLike,
    *,
    needle_axis: ArrayLike = NEEDLE_AXIS,
    seed: ArrayLike = SEED,
    dls_lambda: float = DLS_LAMBDA,
    max_iter: int = MAX_ITER,
    tol: float = TOL,
    anchor_spacing_m: float = ANCHOR_SPACING_M,
    branch_tol_rad: float = BRANCH_TOL_RAD,
    progress: Progress | None = None,
) -> IkResult:
    """IK for every point of a path, batched (see the module docstring for the method).

    Args:
        chain: the kinematic model (:meth:`Chain.from_description`).
        targets_m: (N, 3) tip targets in the arm frame, m, in path order.
        needle_axis: (3,) wanted tip +z for every point, or (N, 3) per point.
        seed: (n,) joint angles the first point starts from, rad.
        dls_lambda: the damped-least-squares lambda added to ``J J^T`` (as is, not
            squared).
        max_iter: most iterations per solve.
        tol: convergence threshold on the task error ``|e|`` (m and unitless mixed).
        anchor_spacing_m: path length between anchors, m; steps at least this long (travel)
            get anchors at both ends.
        branch_tol_rad: largest joint step between consecutive points accepted without
            re-solving the later point from the earlier one's solution, rad.
        progress: called as ``progress(done, total)`` while points finish.

    Returns:
        The solutions; ``result.raise_if_failed(uvz_mm)`` refuses a path with failures.

    Raises:
        TattotronixError: targets not (N, 3) finite, a bad needle axis or seed, or a
            solver setting that cannot work (named as its ``ik`` key).
    """
    t0 = time.perf_counter()
    _check_settings(dls_lambda, max_iter, tol, anchor_spacing_m)
    x, z_const, z_rows, q0 = _path_inputs(targets_m, needle_axis, seed, chain.n)
    ps = _PathSolve.start(chain, x, z_rows, z_const, dls_lambda, max_iter, tol)
    n_pts = len(x)
    stats: dict[str, Any] = {"method": "batched", "points": n_pts}
    if n_pts:
        same_tol = branch_tol_rad / 50  # two solves of one point agreeing: the same solution
        # 1-2. anchors: from the seed, then each from its predecessor until settled
        anchors, s = _anchors(x, anchor_spacing_m)
        qa, ca, rounds_a = ps.solve_anchors(anchors, q0, same_tol)
        stats.update(anchors=len(anchors), anchor_rounds=rounds_a)
        if progress is not None:
            progress(len(anchors), n_pts)
        # 3. everything else from interpolated seeds, at once
        ps.solve_between(anchors, s, qa, ca, progress)
        # 4. off-branch or failed points again, from their predecessors, until settled
        rounds_f, resolved = ps.settle_branches(s, branch_tol_rad, anchor_spacing_m, same_tol)
        # 5. a failed start of the path, backwards from its first solved point
        head = ps.settle_head()
        if head:
            stats["head_resolved"] = head
        stats.update(fix_rounds=rounds_f, resolved=resolved, point_iterations=ps.work)
        if progress is not None:
            progress(n_pts, n_pts)
    return ps.result(stats, time.perf_counter() - t0)


def _path_inputs(targets_m: ArrayLike, needle_axis: ArrayLike, seed: ArrayLike, n: int
                 ) -> tuple[Array, tuple[float, ...] | None, Array | None, Array]:
    """:func:`solve_path`'s inputs checked: the (N, 3) targets, the needle axis (one for
    every point, or (3, N) rows), and the (n, 1) seed.

    Raises:
        TattotronixError: as :func:`solve_path`.
    """
    x = np.asarray(targets_m, dtype=float)
    if x.ndim != 2 or x.shape[1] != 3 or not np.all(np.isfinite(x)):
        raise TattotronixError(f"IK targets must be (N, 3) finite positions in m, got {x.shape}")
    axis = _unit(needle_axis, "needle_axis")
    z_const: tuple[float, ...] | None = None
    z_rows: Array | None = None
    if axis.ndim == 1:
        z_const = tuple(float(c) for c in axis)
    else:
        if axis.shape != x.shape:
            raise TattotronixError(f"needle_axis must be (3,) or {x.shape}, got {axis.shape}")
        z_rows = np.ascontiguousarray(axis.T)
    q0 = np.asarray(seed, dtype=float).reshape(-1, 1)
    if q0.shape != (n, 1) or not np.all(np.isfinite(q0)):
        raise TattotronixError(f"the IK seed must be {n} finite joint angles (rad), got "
                               f"{np.ravel(seed).tolist()}")
    return x, z_const, z_rows, q0


@dataclass
class _PathSolve:
    """A whole-path solve under way (:func:`solve_path`'s parts share it): the targets and
    settings, and every point's solution so far, as (n, N) and (N,) rows.

    Attributes:
        work: point-iterations spent so far.
    """

    chain: Chain
    p_rows: Array
    z_rows: Array | None
    z_const: tuple[float, ...] | None
    dls_lambda: float
    max_iter: int
    tol: float
    q: Array
    conv: NDArray[np.bool_]
    res: Array
    iters: NDArray[np.int64]
    at_limit: NDArray[np.bool_]
    work: int = 0

    @classmethod
    def start(cls, chain: Chain, x: Array, z_rows: Array | None,
              z_const: tuple[float, ...] | None, dls_lambda: float, max_iter: int,
              tol: float) -> _PathSolve:
        """No point solved yet."""
        n_pts, n = len(x), chain.n
        return cls(chain, np.ascontiguousarray(x.T), z_rows, z_const, dls_lambda, max_iter,
                   tol, q=np.empty((n, n_pts)), conv=np.zeros(n_pts, bool),
                   res=np.zeros(n_pts), iters=np.zeros(n_pts, np.int64),
                   at_limit=np.zeros((n, n_pts), bool))

    def solve(self, idx: NDArray[np.intp], seeds: Array,
              report: Callable[[int], None] | None = None) -> _Batch:
        """Solve the points ``idx`` from ``seeds`` ((n, len(idx))) in lockstep, in blocks
        (which bound the memory on huge paths); nothing is stored."""
        parts = []
        for lo in range(0, len(idx), BLOCK):
            k = idx[lo:lo + BLOCK]
            offset = lo

            def sub(done: int, offset: int = offset) -> None:
                if report is not None:
                    report(offset + done)

            parts.append(_solve_lockstep(
                self.chain, self.p_rows[:, k], None if self.z_rows is None else
                self.z_rows[:, k], self.z_const, seeds[:, lo:lo + BLOCK],
                dls_lambda=self.dls_lambda, max_iter=self.max_iter, tol=self.tol,
                progress=sub))
        b = parts[0] if len(parts) == 1 else _Batch(
            q=np.concatenate([p.q for p in parts], axis=1),
            converged=np.concatenate([p.converged for p in parts]),
            residual=np.concatenate([p.residual for p in parts]),
            iterations=np.concatenate([p.iterations for p in parts]),
            at_limit=np.concatenate([p.at_limit for p in parts], axis=1),
            point_iterations=sum(p.point_iterations for p in parts))
        self.work += b.point_iterations
        return b

    def _store(self, idx: NDArray[np.intp], q: Array, conv: NDArray[np.bool_], res: Array,
               iters: NDArray[np.int64], at_limit: NDArray[np.bool_]) -> None:
        self.q[:, idx], self.conv[idx], self.res[idx] = q, conv, res
        self.iters[idx], self.at_limit[:, idx] = iters, at_limit

    def solve_anchors(self, anchors: NDArray[np.intp], q0: Array, same_tol: float
                      ) -> tuple[Array, NDArray[np.bool_], int]:
        """Solve the anchors from the seed ``q0``, then each again from its predecessor
        until they settle; store them. Their (n, m) solutions, convergence and rounds."""
        m = len(anchors)
        b0 = self.solve(anchors, np.repeat(q0, m, axis=1))
        qa, ca, ra, ia, la = b0.q, b0.converged, b0.residual, b0.iterations, b0.at_limit

        def solve_anchors(k: NDArray[np.intp], seeds: Array) -> _Batch:
            return self.solve(anchors[k], seeds)

        rounds, _ = _settle(solve_anchors, qa, ca, ra, ia, la, np.arange(1, m),
                            lambda k: np.ones(len(k), bool), same_tol)
        # the first anchor (point 0) was solved from the seed in round 0: that is its answer
        self._store(anchors, qa, ca, ra, ia, la)
        return qa, ca, rounds

    def solve_between(self, anchors: NDArray[np.intp], s: Array, qa: Array,
                      ca: NDArray[np.bool_], progress: Progress | None) -> None:
        """Solve every point but the anchors at once, each from the anchors' solutions
        interpolated along the path (``s``, its arc length); store them."""
        n_pts, m = len(self.conv), len(anchors)
        rest = np.setdiff1d(np.arange(n_pts), anchors, assume_unique=True)
        if not len(rest):
            return
        seeds = _interpolated_seeds(anchors, s, qa, ca, n_pts)[:, rest]

        def report(done: int) -> None:
            if progress is not None:
                progress(m + done, n_pts)

        b = self.solve(rest, seeds, report)
        self._store(rest, b.q, b.converged, b.residual, b.iterations, b.at_limit)

    def settle_branches(self, s: Array, branch_tol_rad: float, anchor_spacing_m: float,
                        same_tol: float) -> tuple[int, int]:
        """Solve the off-branch or failed points again from their predecessors until
        settled (:func:`_settle`); (rounds, points re-solved)."""
        q, conv = self.q, self.conv

        def off_branch(j: NDArray[np.intp], recheck_far: bool = False) -> NDArray[np.bool_]:
            step = s[j] - s[j - 1]
            limit = branch_tol_rad * np.maximum(1.0, step / (0.1 * anchor_spacing_m))
            jump = np.abs(q[:, j] - q[:, j - 1]).max(axis=0) > limit
            near = step < anchor_spacing_m
            # after a long step the joint step says nothing: re-solve when the point before
            # it has changed (a settled anchor pair otherwise)
            return conv[j - 1] & (~conv[j] | (jump & near) | (recheck_far & ~near))

        cand = np.arange(1, len(conv))
        todo = cand[off_branch(cand)]
        return _settle(self.solve, q, conv, self.res, self.iters, self.at_limit, todo,
                       lambda j: off_branch(j, recheck_far=True), same_tol)

    def settle_head(self) -> int:
        """The points before the first converged one solved again, backwards, each from the
        one after it; the number solved.

        The first point starts from the seed alone, and every later one from a neighbour:
        where the path begins far from the seed (a needle tilted along a limb's normal) the
        seed's solve can fail although the arm reaches the point, and no predecessor is
        there to retry it from (:meth:`settle_branches` starts at the second point)."""
        if not len(self.conv) or self.conv[0] or not self.conv.any():
            return 0
        first = int(np.argmax(self.conv))
        for j in range(first - 1, -1, -1):
            idx = np.array([j], dtype=np.intp)
            b = self.solve(idx, self.q[:, j + 1:j + 2].copy())
            if not b.converged[0]:
                return first - 1 - j
            self._store(idx, b.q, b.converged, b.residual, b.iterations, b.at_limit)
        return first

    def result(self, stats: dict[str, Any], solve_s: float) -> IkResult:
        """The solutions, each failure named (``joint limit`` or ``unreachable``)."""
        conv = self.conv
        reason = np.full(len(conv), "", dtype="<U11")
        failed = ~conv
        reason[failed] = np.where(self.at_limit[:, failed].any(axis=0), JOINT_LIMIT,
                                  UNREACHABLE)
        return IkResult(q=np.ascontiguousarray(self.q.T), converged=conv, residual=self.res,
                        iterations=self.iters, reason=reason,
                        at_limit=np.ascontiguousarray(self.at_limit.T), solve_s=solve_s,
                        joint_names=self.chain.joint_names, stats=stats)


# --- task Jacobian and conditioning --------------------------------------------------------

def task_jacobian(chain: Chain, q: ArrayLike) -> Array:
    """The 5 x n task Jacobian (docs/original.md, "3.1 The task Jacobian") at ``q`` ((N, n)
    rad): (N, 5, n).

    Rows 0-2: the tip's linear Jacobian (m/rad); rows 3-4: the needle's tilt,
    ``u . (w_i x z)`` and ``v . (w_i x z)`` (1/rad), with ``u, v`` normal to the current
    needle axis ``z``.
    """
    rows_q = chain.as_rows(q)
    st = chain.soa(np.cos(rows_q), np.sin(rows_q))
    rows, _, _ = _task_rows(st)
    out = np.empty((rows_q.shape[1], len(rows), chain.n))
    for r, row in enumerate(rows):
        for c, entry in enumerate(row):
            out[:, r, c] = entry
    return out


@dataclass(frozen=True)
class Conditioning:
    """Singular values of the 5x5 task Jacobian along a path.

    Attributes:
        sigma: (N, 5) singular values, largest first (m/rad and 1/rad mixed).
        cond: (N,) condition number sigma_1 / sigma_5.
        manipulability: (N,) Yoshikawa's ``sqrt(det(J J^T))`` (the product of sigma).
        weakest: (N, n) the right singular vector of sigma_5 (the joint-space direction
            that moves the task least), sign chosen so its largest component is positive.
    """

    sigma: Array
    cond: Array
    manipulability: Array
    weakest: Array

    @property
    def worst(self) -> int:
        """Index of the worst-conditioned point (largest ``cond``)."""
        return int(np.argmax(self.cond))

    def summary(self) -> JsonDict:
        """Ranges (``[min, max]``) of sigma_1, sigma_5, cond and manipulability, and the
        worst-conditioned point with its weakest direction."""
        def rng(a: Array) -> list[float]:
            return [float(a.min()), float(a.max())]

        w = self.worst
        return {
            "sigma1": rng(self.sigma[:, 0]),
            "sigma5": rng(self.sigma[:, -1]),
            "cond": rng(self.cond),
            "manipulability": rng(self.manipulability),
            "worst_index": w,
            "worst_cond": float(self.cond[w]),
            "worst_weakest_direction": [float(v) for v in self.weakest[w]],
        }


def conditioning(chain: Chain, q: ArrayLike) -> Conditioning:
    """Singular values, condition number and manipulability of the task Jacobian at
    every configuration of ``q`` ((N, n) rad), by one batched SVD.

    Raises:
        TattotronixError: ``q`` is empty.
    """
    jac = task_jacobian(chain, q)
    if not len(jac):
        raise TattotronixError("conditioning needs at least one configuration")
    _, sigma, vt = np.linalg.svd(jac)
    weakest = vt[:, -1, :]
    big = np.take_along_axis(weakest, np.abs(weakest).argmax(axis=1)[:, None], axis=1)
    weakest = weakest * np.where(big < 0, -1.0, 1.0)
    with np.errstate(divide="ignore"):
        cond = sigma[:, 0] / sigma[:, -1]
    return Conditioning(sigma=sigma, cond=cond, manipulability=np.prod(sigma, axis=1),
                        weakest=weakest)


# --- the Pinocchio reference ---------------------------------------------------------------

@dataclass(frozen=True, eq=False)
class PinocchioTip:
    """Pinocchio's model of the arm and the tip frame: the trusted reference.

    Attributes:
        model: the ``pinocchio.Model`` (fixed base) of the generated URDF: the process's
            shared, read-only one (``pinocchio_model`` in tattotronix/robot/loaders.py).
        frame_id: the tip frame's id.
        tip_frame: its name.
        lower, upper: (n,) joint limits, rad (from the model).
    """

    model: Any  # Any: pinocchio.Model (pinocchio ships no type stubs)
    frame_id: int
    tip_frame: str
    lower: Array
    upper: Array

    @classmethod
    def from_urdf_text(cls, urdf: str, tip_frame: str, *,
                       gravity: float = STANDARD_GRAVITY) -> PinocchioTip:
        """From URDF text (``tattotronix.robot.urdf.to_urdf``). ``gravity`` (m/s^2) only
        picks which shared model to use: the kinematics do not depend on it."""
        return cls._of_model(pinocchio_model(urdf, gravity), tip_frame)

    @classmethod
    def _of_model(cls, model: Any, tip_frame: str,  # Any: pinocchio.Model
                  where: str = "the URDF") -> PinocchioTip:
        if not model.existFrame(tip_frame):
            raise TattotronixError(f"{where} has no frame {tip_frame!r} for the IK tip")
        return cls(model=model, frame_id=int(model.getFrameId(tip_frame)), tip_frame=tip_frame,
                   lower=np.array(model.lowerPositionLimit, dtype=float),
                   upper=np.array(model.upperPositionLimit, dtype=float))

    @classmethod
    def from_urdf(cls, path: str | os.PathLike[str], tip_frame: str, *,
                  gravity: float = STANDARD_GRAVITY) -> PinocchioTip:
        """From a URDF file (the robot stage's ``data/robot/tattotronix.urdf``).

        Raises:
            TattotronixError: the file is missing, not a URDF, or has no ``tip_frame``;
                the message names it and the ``robot`` stage.
        """
        model = load_pinocchio(Path(path), gravity)
        if not model.existFrame(tip_frame):
            raise model_refused(Path(path), f"it has no frame {tip_frame!r} for the IK tip")
        return cls._of_model(model, tip_frame)

    @classmethod
    def from_description(cls, desc: RobotDescription, tip: str | None = None) -> PinocchioTip:
        """Generate the URDF of ``desc`` and load it."""
        from tattotronix.robot.urdf import to_urdf

        return cls.from_urdf_text(to_urdf(desc), tip or desc.tip_frame, gravity=desc.gravity)

    def fk(self, q: ArrayLike) -> tuple[Array, Array]:
        """Tip position (N, 3) m and tip +z axis (N, 3) at ``q`` ((N, n) rad), one by one."""
        import pinocchio as pin

        qq = np.atleast_2d(np.asarray(q, dtype=float))
        data = self.model.createData()
        p, z = np.empty((len(qq), 3)), np.empty((len(qq), 3))
        for k, qk in enumerate(qq):
            pin.framesForwardKinematics(self.model, data, qk)
            m = data.oMf[self.frame_id]
            p[k], z[k] = m.translation, m.rotation[:, 2]
        return p, z


def _unit(v: ArrayLike, what: str) -> Array:
    a = np.asarray(v, dtype=float)
    norm = np.linalg.norm(a, axis=-1, keepdims=True)
    if not np.all(np.isfinite(a)) or np.any(norm == 0):
        raise TattotronixError(f"{what} must be finite, non-zero vectors")
    return a / norm


def solve_point(
    ref: PinocchioTip,
    target_m: ArrayLike,
    *,
    needle_axis: ArrayLike = NEEDLE_AXIS,
    q0: ArrayLike = SEED,
    dls_lambda: float = DLS_LAMBDA,
    max_iter: int = MAX_ITER,
    tol: float = TOL,
    data: Any = None,  # Any: a pinocchio.Data (pinocchio ships no type stubs)
) -> PointResult:
    """The single-point reference solver, on Pinocchio's frame Jacobian.

    Args:
        ref: the Pinocchio model and tip frame.
        target_m: (3,) tip target in the arm frame, m.
        needle_axis: (3,) wanted tip +z (normalised here).
        q0: (n,) starting joint angles, rad.
        dls_lambda: the damped-least-squares lambda added to ``J J^T``.
        max_iter: most iterations.
        tol: convergence threshold on ``|e|``.
        data: a ``pinocchio.Data`` to reuse (one is made when None).

    Returns:
        The solve; see :class:`PointResult`.
    """
    import pinocchio as pin
    from scipy.linalg.lapack import dposv

    model, fid, lwa = ref.model, ref.frame_id, pin.LOCAL_WORLD_ALIGNED
    data = data if data is not None else model.createData()
    xd, yd, zd = (float(c) for c in np.asarray(target_m, dtype=float))
    axd, ayd, azd = (float(c) for c in _unit(needle_axis, "needle_axis"))
    lo, hi = ref.lower, ref.upper
    q = np.array(q0, dtype=float)
    n = len(q)
    at_limit = np.zeros(n, bool)
    task = np.empty((5, n))
    tilt = np.empty((2, 3))
    diag = np.arange(5)
    for it in range(max_iter):
        jac = pin.computeFrameJacobian(model, data, q, fid, lwa)
        m = data.oMf[fid]
        px, py, pz = m.translation.tolist()
        zx, zy, zz = m.rotation[:, 2].tolist()
        if abs(zx) > 0.9:
            ux, uy, uz = -zz, 0.0, zx  # z x y-hat
        else:
            ux, uy, uz = 0.0, zz, -zy  # z x x-hat
        nu = math.sqrt(ux * ux + uy * uy + uz * uz)
        ux, uy, uz = ux / nu, uy / nu, uz / nu
        vx, vy, vz = zy * uz - zz * uy, zz * ux - zx * uz, zx * uy - zy * ux
        dx, dy, dz = axd - zx, ayd - zy, azd - zz
        e = np.array((xd - px, yd - py, zd - pz, ux * dx + uy * dy + uz * dz,
                      vx * dx + vy * dy + vz * dz))
        err = math.sqrt(float(e @ e))
        if err < tol:
            return PointResult(q, True, err, it, "", np.zeros(n, bool))
        # tilt rows u . (w_i x z), v . (w_i x z): with w x z = S w, S = [z]x^T, each row
        # is (S^T u) . w_i
        tilt[0] = (uz * zy - uy * zz, ux * zz - uz * zx, uy * zx - ux * zy)
        tilt[1] = (vz * zy - vy * zz, vx * zz - vz * zx, vy * zx - vx * zy)
        task[:3] = jac[:3]
        task[3:] = tilt @ jac[3:]
        a = task @ task.T
        a[diag, diag] += dls_lambda
        y = dposv(a, e)[1]
        raw = q + task.T @ y
        q = np.minimum(np.maximum(raw, lo), hi)
        at_limit = q != raw
    pin.framesForwardKinematics(model, data, q)
    m = data.oMf[fid]
    d = np.concatenate((np.array((xd, yd, zd)) - m.translation,
                        np.array((axd, ayd, azd)) - m.rotation[:, 2]))
    return PointResult(q, False, float(np.sqrt(d @ d)), max_iter,
                       JOINT_LIMIT if at_limit.any() else UNREACHABLE, at_limit)


def solve_path_sequential(
    ref: PinocchioTip,
    targets_m: ArrayLike,
    *,
    needle_axis: ArrayLike = NEEDLE_AXIS,
    seed: ArrayLike = SEED,
    dls_lambda: float = DLS_LAMBDA,
    max_iter: int = MAX_ITER,
    tol: float = TOL,
    progress: Progress | None = None,
) -> IkResult:
    """The reference path solve: :func:`solve_point` per point, each warm-started from
    the previous point's solution (the first from ``seed``). Slow; for checks and
    benchmarks."""
    t0 = time.perf_counter()
    x = np.asarray(targets_m, dtype=float)
    zs = np.broadcast_to(np.asarray(needle_axis, dtype=float), x.shape)
    n_pts, n = len(x), ref.model.nq
    q = np.empty((n_pts, n))
    conv = np.zeros(n_pts, bool)
    res = np.zeros(n_pts)
    iters = np.zeros(n_pts, np.int64)
    reason = np.full(n_pts, "", dtype="<U11")
    at_limit = np.zeros((n_pts, n), bool)
    data = ref.model.createData()
    qk = np.asarray(seed, dtype=float)
    for k in range(n_pts):
        r = solve_point(ref, x[k], needle_axis=zs[k], q0=qk, dls_lambda=dls_lambda,
                        max_iter=max_iter, tol=tol, data=data)
        q[k], conv[k], res[k], iters[k], reason[k], at_limit[k] = (
            r.q, r.converged, r.residual, r.iterations, r.reason, r.at_limit)
        qk = r.q
        if progress is not None and (k % 1000 == 999 or k == n_pts - 1):
            progress(k + 1, n_pts)
    names = tuple(str(s) for s in list(ref.model.names)[1:])
    return IkResult(q=q, converged=conv, residual=res, iterations=iters, reason=reason,
                    at_limit=at_limit, solve_s=time.perf_counter() - t0, joint_names=names,
                    stats={"method": "sequential", "point_iterations": int(iters.sum())})


@dataclass(frozen=True)
class Verification:
    """Pinocchio's FK at the solutions against the targets.

    Attributes:
        checked: number of points checked (the converged ones).
        max_position_error_m: largest tip distance from its target, m.
        max_axis_error_rad: largest angle between the needle and its wanted axis, rad.
        worst_index: the point with the largest position error (-1 when none checked).
        ok: both within tolerance.
    """

    checked: int
    max_position_error_m: float
    max_axis_error_rad: float
    worst_index: int
    ok: bool

    def summary(self) -> JsonDict:
        """For the metrics file."""
        return {"verified_points": self.checked,
                "verify_max_position_error_m": self.max_position_error_m,
                "verify_max_axis_error_rad": self.max_axis_error_rad}


def verify(
    ref: PinocchioTip,
    result: IkResult,
    targets_m: ArrayLike,
    *,
    needle_axis: ArrayLike = NEEDLE_AXIS,
    pos_tol_m: float = 2e-6,
    axis_tol_rad: float = 2e-6,
    raise_on_failure: bool = True,
) -> Verification:
    """Check every converged solution with Pinocchio's FK (independent of the chain model).

    Args:
        ref: Pinocchio's model of the same arm (from the generated URDF).
        result: what :func:`solve_path` returned.
        targets_m: (N, 3) the targets it was given, m.
        needle_axis: (3,) or (N, 3) the wanted needle axes.
        pos_tol_m: largest accepted tip position error, m.
        axis_tol_rad: largest accepted needle axis error, rad.
        raise_on_failure: raise instead of returning a failed check.

    Raises:
        IkVerificationError: a solution misses its target in Pinocchio's FK (when
            ``raise_on_failure``): the chain model and the URDF disagree.
    """
    x = np.asarray(targets_m, dtype=float)
    zd = np.broadcast_to(_unit(needle_axis, "needle_axis"), x.shape)
    idx = np.flatnonzero(result.converged)
    if not len(idx):
        return Verification(0, 0.0, 0.0, -1, True)
    p, z = ref.fk(result.q[idx])
    pos = np.linalg.norm(p - x[idx], axis=1)
    cross = np.linalg.norm(np.cross(z, zd[idx]), axis=1)
    ang = np.arctan2(cross, np.einsum("ij,ij->i", z, zd[idx]))
    w = int(np.argmax(pos))
    ok = bool(pos.max() <= pos_tol_m and ang.max() <= axis_tol_rad)
    out = Verification(len(idx), float(pos.max()), float(ang.max()), int(idx[w]), ok)
    if not ok and raise_on_failure:
        a = int(idx[int(np.argmax(ang))])
        raise IkVerificationError(
            f"IK check against Pinocchio failed: point {out.worst_index} is "
            f"{out.max_position_error_m:.3g} m from its target (tolerance {pos_tol_m:g}), "
            f"point {a} has the needle {out.max_axis_error_rad:.3g} rad off its axis "
            f"(tolerance {axis_tol_rad:g}); the IK chain and the URDF disagree: regenerate "
            f"the robot (python stages/robot.py)"
        )
    return out
