"""Rigid-body dynamics of the arm from Pinocchio: RNEA, CRBA, ABA and the effective inertia.

``M(q) qdd + C(q, qd) qd + G(q) = tau`` (docs/control.md, "The rigid-body model"; the
original's: docs/original.md, "5.1 The rigid-body model"), gravity along -z at the
description's magnitude. The model is the process's shared, read-only one of the generated
URDF (``load_pinocchio`` in tattotronix/robot/loaders.py); a :class:`Dynamics` owns one
Pinocchio ``Data`` (per-run state), so use one per thread.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from tattotronix.robot.loaders import load_pinocchio

__all__ = ["Dynamics", "effective_inertia"]

Vec = NDArray[np.float64]


def effective_inertia(mass_matrix: ArrayLike) -> Vec:
    """J_eff,i = 1 / (M^-1)_ii: the inertia joint i sees with the others free (kg m^2).

    Args:
        mass_matrix: (n, n) joint-space mass matrix, or (k, n, n) for a batch.
    """
    m = np.asarray(mass_matrix, dtype=np.float64)
    return 1.0 / np.diagonal(np.linalg.inv(m), axis1=-2, axis2=-1)


class Dynamics:
    """Pinocchio's rigid-body algorithms on the generated URDF (SI units throughout).

    Args:
        urdf: the generated ``data/robot/<name>.urdf``.
        gravity: magnitude, m/s^2 (the description's; applied along -z).
    """

    def __init__(self, urdf: Path, gravity: float):
        import pinocchio as pin

        self._pin = pin
        self.urdf = Path(urdf)
        self.model = load_pinocchio(self.urdf, gravity)
        self.data = self.model.createData()
        self.joint_names: tuple[str, ...] = tuple(self.model.names[1:])
        self.n = int(self.model.nv)

    def _q(self, q: ArrayLike) -> Vec:
        return np.ascontiguousarray(q, dtype=np.float64)

    def rnea(self, q: ArrayLike, qd: ArrayLike, qdd: ArrayLike) -> Vec:
        """Inverse dynamics: the torques (N m) for ``qdd`` at ``(q, qd)``, gravity included."""
        return self._pin.rnea(self.model, self.data, self._q(q), self._q(qd),
                              self._q(qdd)).copy()

    def mass_matrix(self, q: ArrayLike) -> Vec:
        """M(q) by CRBA, symmetric (kg m^2)."""
        m = self._pin.crba(self.model, self.data, self._q(q))
        return np.triu(m) + np.triu(m, 1).T

    def gravity(self, q: ArrayLike) -> Vec:
        """G(q) (N m): the torques that hold the arm still at ``q``."""
        return self._pin.computeGeneralizedGravity(self.model, self.data, self._q(q)).copy()

    def coriolis_torque(self, q: ArrayLike, qd: ArrayLike) -> Vec:
        """C(q, qd) qd (N m): the velocity-product torques, gravity excluded."""
        q = self._q(q)
        nle = self._pin.nonLinearEffects(self.model, self.data, q, self._q(qd))
        return nle - self._pin.computeGeneralizedGravity(self.model, self.data, q)

    def aba(self, q: ArrayLike, qd: ArrayLike, tau: ArrayLike) -> Vec:
        """Forward dynamics: qdd (rad/s^2) under ``tau`` (N m) at ``(q, qd)``."""
        return self._pin.aba(self.model, self.data, self._q(q), self._q(qd),
                             self._q(tau)).copy()

    def gravity_view(self, q: Vec) -> Vec:
        """G(q) for the control loop: ``q`` must be a float64 (n,) array; the result is
        Pinocchio's buffer, valid until the next call (no checks, no copy)."""
        return self._pin.computeGeneralizedGravity(self.model, self.data, q)

    def rnea_view(self, q: Vec, qd: Vec, qdd: Vec) -> Vec:
        """RNEA for the control loop (float64 arrays in; Pinocchio's buffer out)."""
        return self._pin.rnea(self.model, self.data, q, qd, qdd)

    def effective_inertia(self, q: ArrayLike) -> Vec:
        """J_eff(q) (kg m^2), see :func:`effective_inertia`."""
        return effective_inertia(self.mass_matrix(q))

    def effective_inertia_along(self, q: ArrayLike) -> Vec:
        """J_eff at every row of ``q`` (k, n) -> (k, n)."""
        q = np.atleast_2d(np.asarray(q, dtype=np.float64))
        return effective_inertia(np.stack([self.mass_matrix(row) for row in q]))
