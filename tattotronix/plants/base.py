"""The plant interface every backend implements, and the settings every backend is told."""

from __future__ import annotations

import os
import sys
from abc import ABC, abstractmethod
from collections.abc import Sequence
from dataclasses import dataclass
from types import TracebackType

import numpy as np
from numpy.typing import ArrayLike, NDArray

from tattotronix.config.schema import PlantConfig
from tattotronix.errors import TattotronixError

__all__ = ["EnginePid", "PidSpec", "Plant", "PlantSettings", "Workpiece", "has_display"]

Array = NDArray[np.float64]


@dataclass(frozen=True)
class PlantSettings:
    """What every backend is told (the ``plant`` settings, SI units): build it with
    :meth:`from_config`; it holds no defaults of its own (they are ``PlantConfig``'s).

    Attributes:
        dt_s: integration step, s.
        damping: viscous joint friction, N m s/rad.
        joint_limits: enforce the joint range.
        contacts: arm-bench contact (MuJoCo and PyBullet only).
        gravity: magnitude along -z, m/s^2.
        tip_frame: the tip's frame name (``tattoo_tcp``).
    """

    dt_s: float
    damping: float
    joint_limits: bool
    contacts: bool
    gravity: float
    tip_frame: str

    @classmethod
    def from_settings(cls, plant: PlantConfig, gravity: float, tip_frame: str) -> PlantSettings:
        """From the ``plant`` settings and the robot description's gravity and tip."""
        s = cls(dt_s=float(plant.dt_s), damping=float(plant.damping),
                joint_limits=bool(plant.joint_limits), contacts=bool(plant.contacts),
                gravity=float(gravity), tip_frame=tip_frame)
        if not (np.isfinite(s.dt_s) and s.dt_s > 0):
            raise TattotronixError(f"plant.dt_s={s.dt_s}: give a positive step in seconds")
        if not (np.isfinite(s.damping) and s.damping >= 0):
            raise TattotronixError(f"plant.damping={s.damping}: give a damping >= 0 N m s/rad")
        return s


@dataclass(frozen=True)
class Workpiece:
    """What the needle draws on in the panel's place (a limb, a scanned surface): a
    triangle mesh in the arm's base frame. Every plant shows it and none collides with it,
    as with the panel (the needle enters it); the ink is scored from the tip against the
    surface itself, not by the engine.

    Attributes:
        vertices_m: (V, 3) m.
        faces: (F, 3) vertex indices, wound outward.
        rgba: its colour.
    """

    vertices_m: Array
    faces: NDArray[np.int64]
    rgba: tuple[float, float, float, float] = (0.93, 0.80, 0.69, 1.0)

    def __post_init__(self) -> None:
        v, f = np.asarray(self.vertices_m), np.asarray(self.faces)
        if (v.ndim != 2 or v.shape[1] != 3 or len(v) < 3 or not np.all(np.isfinite(v))
                or f.ndim != 2 or f.shape[1] != 3 or len(f) == 0
                or f.min() < 0 or f.max() >= len(v)):
            raise TattotronixError(
                f"a workpiece needs (V, 3) finite vertices and (F, 3) faces indexing them, "
                f"got {v.shape} and {f.shape}")


@dataclass(frozen=True)
class PidSpec:
    """A joint PID the engine can run itself, every plant step (the shared controller's
    law, docs/control.md, "The controller"; the engine path: "The loop inside the engine")::

        I_k = I_{k-1} + dt (q_r - q)
        tau = clamp(Kp (q_r - q) + Ki I_k + Kd (v_r - qd) + [G(q)], -limit, limit)

    ``v_r`` is the reference rate (``qd_r``, derivative on the error) or zero (derivative
    on the measurement); ``G(q)`` is the plant's own gravity at the measured ``q``.

    Attributes:
        kp: (n,) N m/rad. ki: (n,) N m/(rad s). kd: (n,) N m s/rad.
        limit: (n,) torque limit, N m.
        gravity: add G(q).
    """

    kp: Array
    ki: Array
    kd: Array
    limit: Array
    gravity: bool


class EnginePid(ABC):
    """A plant running a :class:`PidSpec` inside its engine, a stretch of steps per call."""

    @abstractmethod
    def reset(self, q: ArrayLike, qd: ArrayLike) -> None:
        """Put the arm at ``q`` moving at ``qd``, the integral at zero."""

    @abstractmethod
    def run(self, q_ref: Array, v_ref: Array) -> tuple[Array, Array, Array]:
        """Step once per row of the references ((m, n), rad and rad/s).

        Returns:
            ``q`` and ``qd`` at the start of each step, and the torque held over it
            ((m, n) each); the state goes on from the end of the last step.
        """

    @abstractmethod
    def state(self) -> tuple[Array, Array]:
        """``(q, qd)`` now (copies)."""

    @abstractmethod
    def healthy(self) -> bool:
        """False once the engine reported instability or the state is not finite."""


class Plant(ABC):
    """A simulated arm. Use as a context manager (or call :meth:`close`).

    Attributes:
        backend: ``model``, ``mujoco`` or ``pybullet``.
        settings: the plant settings.
        n: number of joints.
    """

    backend: str = ""

    def __init__(self, settings: PlantSettings, n: int):
        self.settings = settings
        self.dt = settings.dt_s
        self.n = n
        self._q = np.zeros(n)
        self._qd = np.zeros(n)

    @property
    def q(self) -> Array:
        """Joint angles now, rad: a float64 array the plant updates in place (read it,
        do not write it)."""
        return self._q

    @property
    def qd(self) -> Array:
        """Joint rates now, rad/s (updated in place, like :attr:`q`)."""
        return self._qd

    @abstractmethod
    def reset(self, q: ArrayLike, qd: ArrayLike | None = None) -> None:
        """Put the arm at ``q`` (rad) moving at ``qd`` (rad/s, default at rest), time 0."""

    @abstractmethod
    def apply(self, tau: Sequence[float]) -> None:
        """Hold the joint torques ``tau`` (N m) until the next call."""

    @abstractmethod
    def step(self, n: int = 1) -> None:
        """Advance ``n`` integration steps of ``dt`` with the held torque."""

    @abstractmethod
    def tip_pose(self) -> tuple[Array, Array]:
        """The tip's position (3,) m and rotation (3, 3) in the arm frame, now."""

    def engine_pid(self, pid: PidSpec) -> EnginePid | None:
        """The engine running ``pid`` itself, or None where it cannot (the default): the
        closed loop then runs in Python, one :meth:`apply` and :meth:`step` per tick."""
        return None

    def healthy(self) -> bool:
        """False once the state is not finite (or the engine reported instability)."""
        return bool(np.all(np.isfinite(self.q)) and np.all(np.isfinite(self.qd)))

    def sync_viewer(self) -> None:  # noqa: B027 - optional hook
        """Refresh the viewer, if one is open."""

    def close(self) -> None:  # noqa: B027 - optional hook
        """Release the engine."""

    def __enter__(self) -> Plant:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()


def has_display() -> bool:
    """Whether a window can be opened here."""
    if sys.platform in ("darwin", "win32"):
        return True
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))
