"""The model plant: Pinocchio's ABA with semi-implicit Euler (the original's study plant)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike

from tattotronix.errors import TattotronixError
from tattotronix.plants.base import Array, Plant, PlantSettings
from tattotronix.robot.loaders import load_pinocchio

__all__ = ["ModelPlant"]


class ModelPlant(Plant):
    """``qdd = ABA(q, qd, tau - b qd)``; ``qd += qdd dt``; ``q += qd dt``.

    With ``joint_limits`` a joint that passes its limit is stopped there (an inelastic
    stop). There is no contact model: ``contacts`` is refused.
    """

    backend = "model"

    def __init__(self, urdf: Path, settings: PlantSettings, *, lower: ArrayLike,
                 upper: ArrayLike):
        import pinocchio as pin

        if settings.contacts:
            raise TattotronixError("the model plant has no contact model: set "
                                   "plant.contacts=false or use backend=mujoco|pybullet")
        self._aba = pin.aba
        self.model = load_pinocchio(urdf, settings.gravity)  # shared, read-only
        self.data = self.model.createData()
        self.joint_names = tuple(self.model.names[1:])
        super().__init__(settings, int(self.model.nv))
        self._tip = self.model.getFrameId(settings.tip_frame)
        self._pin = pin
        self._tau = np.zeros(self.n)
        self._lower = np.asarray(lower, dtype=np.float64)
        self._upper = np.asarray(upper, dtype=np.float64)

    def reset(self, q: ArrayLike, qd: ArrayLike | None = None) -> None:
        self._q[:] = q
        self._qd[:] = 0.0 if qd is None else qd
        self._tau[:] = 0.0

    def apply(self, tau: Sequence[float]) -> None:
        self._tau[:] = tau

    def step(self, n: int = 1) -> None:
        aba, model, data = self._aba, self.model, self.data
        q, qd, tau, dt = self._q, self._qd, self._tau, self.dt
        b = self.settings.damping
        for _ in range(n):
            qdd = aba(model, data, q, qd, tau - b * qd if b else tau)
            qd += qdd * dt
            q += qd * dt
        if self.settings.joint_limits:
            out = (q < self._lower) | (q > self._upper)
            if out.any():
                np.clip(q, self._lower, self._upper, out=q)
                qd[out] = 0.0

    def tip_pose(self) -> tuple[Array, Array]:
        pin = self._pin
        pin.forwardKinematics(self.model, self.data, self._q)
        f = pin.updateFramePlacement(self.model, self.data, self._tip)
        return f.translation.copy(), f.rotation.copy()
