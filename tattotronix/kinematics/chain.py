"""A vectorised forward-kinematics model of the serial chain, built from the description.

The chain is the one in :class:`~tattotronix.robot.description.RobotDescription`: each
revolute joint is a fixed origin (``xyz``, ``rpy`` in its parent frame) followed by a
rotation about ``axis``; after the last joint come the fixed frames down to the tip frame
(``tool0``, ``tattoo_pen_link``, ``tattoo_tcp``). Nothing is re-typed here, so the chain,
the URDF and every loader describe the same arm.

Everything is batched over ``N`` joint configurations: ``q`` is ``(N, n)`` (a single
``(n,)`` configuration is taken as ``N = 1``) and every result is an array shaped
``(N, ...)``. The :class:`Chain` is immutable (its arrays are read-only); each call makes
its own arrays, in the spirit of Pinocchio's Model/Data split.

How it is fast: internally every matrix entry is a separate length-``N`` array ("structure
of arrays"), so each arithmetic step is one contiguous numpy operation over all points.
Each joint is re-expressed, once at construction, as a rotation about its own z (a
constant change of frame ``P`` with ``P e_z = axis`` is folded into the next joint's fixed
origin), and entries that are exactly 0 or +-1 are folded away symbolically: for this arm,
whose axes are coordinate axes, the frame changes are signed permutations and cost
nothing. The arithmetic is the same product of transforms as the URDF's.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Union

import numpy as np
from numpy.typing import ArrayLike, NDArray

from tattotronix.errors import TattotronixError
from tattotronix.robot.description import RobotDescription, rpy_matrix

__all__ = ["Chain", "ChainState", "Num", "SoaState", "Vec3", "mat_entries"]

Array = NDArray[np.float64]
#: One entry of a structure-of-arrays quantity: a length-N array, or a constant.
Num = Union[float, Array]  # noqa: UP007 (a runtime alias)
#: A 3-vector as three entries.
Vec3 = tuple[Num, Num, Num]


# --- constant folding arithmetic on entries ------------------------------------------------

def _mul(a: Num, b: Num) -> Num:
    if isinstance(a, float):
        if a == 0.0:
            return 0.0
        if a == 1.0:
            return b
        if a == -1.0:
            return -b
    if isinstance(b, float):
        if b == 0.0:
            return 0.0
        if b == 1.0:
            return a
        if b == -1.0:
            return -a
    return a * b


def _add(a: Num, b: Num) -> Num:
    if isinstance(a, float) and a == 0.0:
        return b
    if isinstance(b, float) and b == 0.0:
        return a
    return a + b


def _sub(a: Num, b: Num) -> Num:
    if isinstance(b, float) and b == 0.0:
        return a
    if isinstance(a, float) and a == 0.0:
        return -b
    return a - b


def _dot3(a: Sequence[Num], b: Sequence[Num]) -> Num:
    return _add(_add(_mul(a[0], b[0]), _mul(a[1], b[1])), _mul(a[2], b[2]))


def _cross3(a: Sequence[Num], b: Sequence[Num]) -> Vec3:
    return (_sub(_mul(a[1], b[2]), _mul(a[2], b[1])),
            _sub(_mul(a[2], b[0]), _mul(a[0], b[2])),
            _sub(_mul(a[0], b[1]), _mul(a[1], b[0])))


def _mat_const(w: Sequence[Num], g: Array) -> list[Num]:
    """``W @ G`` with ``W`` as 9 row-major entries and ``G`` a constant 3x3."""
    out: list[Num] = []
    for r in range(3):
        for c in range(3):
            acc: Num = 0.0
            for k in range(3):
                acc = _add(acc, _mul(w[3 * r + k], float(g[k, c])))
            out.append(acc)
    return out


def _mat_vec_const(w: Sequence[Num], t: Array) -> Vec3:
    """``W @ t`` with ``t`` a constant 3-vector."""
    return tuple(  # type: ignore[return-value]
        _add(_add(_mul(w[3 * r], float(t[0])), _mul(w[3 * r + 1], float(t[1]))),
             _mul(w[3 * r + 2], float(t[2])))
        for r in range(3)
    )


def _rot_z(w: list[Num], c: Array, s: Array) -> list[Num]:
    """``W @ Rz(q)`` given ``cos q``, ``sin q``: columns 0 and 1 turn, column 2 stays."""
    out = list(w)
    for r in range(3):
        a, b = w[3 * r], w[3 * r + 1]
        out[3 * r] = _add(_mul(a, c), _mul(b, s))
        out[3 * r + 1] = _sub(_mul(b, c), _mul(a, s))
    return out


def mat_entries(entries: Sequence[Num], n_pts: int) -> Array:
    """Stack structure-of-arrays entries (constants broadcast) into an ``(N, k)`` array."""
    out = np.empty((n_pts, len(entries)))
    for i, e in enumerate(entries):
        out[:, i] = e
    return out


def _frame_to_z(a: Array) -> Array:
    """A rotation ``P`` whose third column is the unit axis ``a`` (signed permutation when
    ``a`` is a coordinate axis)."""
    k = int(np.argmin(np.abs(a)))
    x = np.zeros(3)
    x[k] = 1.0
    x = x - a * float(a @ x)
    x /= np.linalg.norm(x)
    y = np.cross(a, x)
    return np.column_stack((x, y, a))


def _frozen(a: ArrayLike) -> Array:
    out = np.array(a, dtype=float)
    out.setflags(write=False)
    return out


# --- results -------------------------------------------------------------------------------

@dataclass(frozen=True)
class SoaState:
    """Kinematics at N configurations as structure-of-arrays entries (internal form).

    Attributes:
        p: tip position entries (x, y, z), m.
        rot: tip rotation, 9 row-major entries.
        axes: per joint, its world axis (3 entries).
        origins: per joint, its world origin (3 entries), m.
    """

    p: Vec3
    rot: list[Num]
    axes: list[Vec3]
    origins: list[Vec3]

    @property
    def z(self) -> Vec3:
        """Tip frame +z (third column of ``rot``)."""
        return (self.rot[2], self.rot[5], self.rot[8])

    def linear_columns(self) -> list[Vec3]:
        """Per joint, ``z_i x (p_tip - p_i)`` (m/rad)."""
        return [_cross3(a, (_sub(self.p[0], o[0]), _sub(self.p[1], o[1]),
                            _sub(self.p[2], o[2])))
                for a, o in zip(self.axes, self.origins, strict=True)]


@dataclass(frozen=True)
class ChainState:
    """Kinematics of the chain at ``N`` configurations, in the arm (base) frame.

    Attributes:
        p: (N, 3) tip position, m.
        z: (N, 3) tip frame +z (the needle axis), unit.
        rotation: (N, 3, 3) tip frame orientation (columns: tip x, y, z in the arm frame).
        axes: (N, 3, n) world axis of each joint (the Jacobian's angular columns), unit.
        origins: (N, 3, n) world position of each joint's frame origin, m.
        jacobian: (N, 6, n) world-aligned geometric Jacobian at the tip: rows 0-2 linear,
            ``z_i x (p_tip - p_i)`` (m/rad); rows 3-5 angular, ``z_i`` (rad/rad). This is
            Pinocchio's ``LOCAL_WORLD_ALIGNED`` frame Jacobian.
    """

    p: Array
    z: Array
    rotation: Array
    axes: Array
    origins: Array
    jacobian: Array


# --- the model -----------------------------------------------------------------------------

@dataclass(frozen=True, eq=False)
class Chain:
    """The serial chain from the base link to the tip frame (immutable).

    Build it with :meth:`from_description`.

    Attributes:
        joint_names: the revolute joints, base outward.
        tip_frame: the frame the chain ends at (``tattoo_tcp`` with the pen mounted).
        lower: (n,) lower joint limits, rad.
        upper: (n,) upper joint limits, rad.
        origin_xyz: (n, 3) each joint's origin offset in its parent frame, m.
        origin_rot: (n, 3, 3) each joint's origin rotation (URDF rpy) in its parent frame.
        axis: (n, 3) each joint's unit axis in its own frame.
        tip_xyz: (3,) the tip frame's origin in the last joint's child frame, m.
        tip_rot: (3, 3) the tip frame's orientation in the last joint's child frame.
    """

    joint_names: tuple[str, ...]
    tip_frame: str
    lower: Array
    upper: Array
    origin_xyz: Array
    origin_rot: Array
    axis: Array
    tip_xyz: Array
    tip_rot: Array
    # z-aligned form: per joint the constant rotation G_i and offset t_i, then the tip's
    _g: tuple[Array, ...] = field(init=False, repr=False)
    _t: tuple[Array, ...] = field(init=False, repr=False)
    _tip_g: Array = field(init=False, repr=False)
    _tip_t: Array = field(init=False, repr=False)

    def __post_init__(self) -> None:
        prev = np.eye(3)  # P_{i-1}: the previous joint's z-aligned frame change
        gs, ts = [], []
        for c, a, t in zip(self.origin_rot, self.axis, self.origin_xyz, strict=True):
            p = _frame_to_z(np.asarray(a))
            gs.append(_frozen(prev.T @ c @ p))
            ts.append(_frozen(prev.T @ t))
            prev = p
        object.__setattr__(self, "_g", tuple(gs))
        object.__setattr__(self, "_t", tuple(ts))
        object.__setattr__(self, "_tip_g", _frozen(prev.T @ self.tip_rot))
        object.__setattr__(self, "_tip_t", _frozen(prev.T @ self.tip_xyz))

    @property
    def n(self) -> int:
        """Number of joints."""
        return len(self.joint_names)

    @classmethod
    def from_description(cls, desc: RobotDescription, tip: str | None = None) -> Chain:
        """The chain of ``desc`` down to ``tip`` (default: ``desc.tip_frame``).

        Raises:
            TattotronixError: ``tip`` does not hang (through fixed frames) from the last
                joint's child link.
        """
        tip = tip or desc.tip_frame
        last = desc.joints[-1].child
        frames = {f.name: f for f in desc.frames}
        rot, xyz = np.eye(3), np.zeros(3)
        name = tip
        while name != last:
            f = frames.get(name)
            if f is None:
                raise TattotronixError(
                    f"IK tip frame {tip!r} does not hang from {last!r} through fixed frames; "
                    f"choose one of {[last, *frames]}"
                )
            r = rpy_matrix(f.rpy)
            rot, xyz = r @ rot, r @ xyz + f.xyz  # parent <- f, then f <- tip
            name = f.parent
        return cls(
            joint_names=desc.joint_names,
            tip_frame=tip,
            lower=_frozen(desc.lower),
            upper=_frozen(desc.upper),
            origin_xyz=_frozen([j.xyz for j in desc.joints]),
            origin_rot=_frozen([rpy_matrix(j.rpy) for j in desc.joints]),
            axis=_frozen([j.axis for j in desc.joints]),
            tip_xyz=_frozen(xyz),
            tip_rot=_frozen(rot),
        )

    def as_rows(self, q: ArrayLike) -> Array:
        """``q`` as a C-contiguous ``(n, N)`` array of joint rows (rad).

        Raises:
            ValueError: ``q`` is not ``(N, n)`` or ``(n,)``.
        """
        arr = np.asarray(q, dtype=float)
        if arr.ndim == 1:
            arr = arr[None, :]
        if arr.ndim != 2 or arr.shape[1] != self.n:
            raise ValueError(f"q must be (N, {self.n}) joint angles (rad), got {arr.shape}")
        return np.ascontiguousarray(arr.T)

    def soa(self, cos_q: Array, sin_q: Array) -> SoaState:
        """Structure-of-arrays kinematics from ``cos q`` and ``sin q``, each ``(n, N)``.

        The solver's inner loop; most callers want :meth:`state` or :meth:`fk`.
        """
        w: list[Num] = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]
        o: Vec3 = (0.0, 0.0, 0.0)
        axes: list[Vec3] = []
        origins: list[Vec3] = []
        for i in range(self.n):
            dp = _mat_vec_const(w, self._t[i])
            o = (_add(o[0], dp[0]), _add(o[1], dp[1]), _add(o[2], dp[2]))
            w = _rot_z(_mat_const(w, self._g[i]), cos_q[i], sin_q[i])
            axes.append((w[2], w[5], w[8]))
            origins.append(o)
        dp = _mat_vec_const(w, self._tip_t)
        p = (_add(o[0], dp[0]), _add(o[1], dp[1]), _add(o[2], dp[2]))
        return SoaState(p=p, rot=_mat_const(w, self._tip_g), axes=axes, origins=origins)

    def state(self, q: ArrayLike) -> ChainState:
        """Tip pose, joint axes and origins and the Jacobian at ``q`` ((N, n) rad)."""
        rows = self.as_rows(q)
        n_pts = rows.shape[1]
        st = self.soa(np.cos(rows), np.sin(rows))
        lin = st.linear_columns()
        jac = np.empty((n_pts, 6, self.n))
        axes = np.empty((n_pts, 3, self.n))
        origins = np.empty((n_pts, 3, self.n))
        for i in range(self.n):
            for r in range(3):
                jac[:, r, i] = lin[i][r]
                jac[:, 3 + r, i] = st.axes[i][r]
                origins[:, r, i] = st.origins[i][r]
        axes[:] = jac[:, 3:, :]
        rotation = mat_entries(st.rot, n_pts).reshape(n_pts, 3, 3)
        return ChainState(p=mat_entries(st.p, n_pts), z=rotation[:, :, 2].copy(),
                          rotation=rotation, axes=axes, origins=origins, jacobian=jac)

    def fk(self, q: ArrayLike) -> tuple[Array, Array]:
        """Tip position (N, 3) m and needle axis, the tip frame +z (N, 3), at ``q`` (rad)."""
        rows = self.as_rows(q)
        st = self.soa(np.cos(rows), np.sin(rows))
        n_pts = rows.shape[1]
        return mat_entries(st.p, n_pts), mat_entries(st.z, n_pts)

    def jacobian(self, q: ArrayLike) -> Array:
        """(N, 6, n) world-aligned geometric Jacobian of the tip frame at ``q`` (rad).

        Rows 0-2: linear velocity of the tip point, ``z_i x (p_tip - p_i)`` (m/rad); rows
        3-5: angular velocity, ``z_i``. Pinocchio's ``LOCAL_WORLD_ALIGNED`` frame Jacobian.
        """
        return self.state(q).jacobian
