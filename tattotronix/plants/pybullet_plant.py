"""The PyBullet plant: the generated URDF under torque control (semi-implicit Euler)."""

from __future__ import annotations

import logging
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike

from tattotronix.plants.base import Array, Plant, PlantSettings, Workpiece, has_display
from tattotronix.robot.loaders import load_pybullet

__all__ = ["PybulletPlant"]


class PybulletPlant(Plant):
    """PyBullet with the URDF's own inertias (``URDF_USE_INERTIA_FROM_FILE``).

    The default velocity motors are switched off (zero force), so the joints take only
    the applied torque; link damping is zero (PyBullet's default is 0.04), joint damping
    is ``plant.damping``. Without ``plant.joint_limits`` the ranges are lifted; with
    ``plant.contacts`` a bench box is added (the arm's own links never collide). A
    ``workpiece`` (a limb in the panel's place) is a visual mesh with no collision shape.
    """

    backend = "pybullet"

    def __init__(self, urdf: Path, settings: PlantSettings, *, viewer: bool = False,
                 workpiece: Workpiece | None = None):
        from tattotronix.robot.loaders import import_pybullet

        p = import_pybullet()
        self._p = p
        gui = viewer and has_display()
        if viewer and not gui:
            logging.getLogger("tattotronix.plants").warning(
                "viewer=true needs a display (none found): running without one")
        self.client = p.connect(p.GUI if gui else p.DIRECT)
        self._gui = gui
        cid = self.client
        p.setGravity(0, 0, -settings.gravity, physicsClientId=cid)
        p.setPhysicsEngineParameter(fixedTimeStep=settings.dt_s, numSubSteps=0,
                                    physicsClientId=cid)
        self.body = load_pybullet(p, urdf, cid)  # a corrupt file: named, with its stage
        idx, names, tip = [], [], -1
        for i in range(p.getNumJoints(self.body, physicsClientId=cid)):
            info = p.getJointInfo(self.body, i, physicsClientId=cid)
            if info[2] == p.JOINT_REVOLUTE:
                idx.append(i)
                names.append(info[1].decode())
            if info[12].decode() == settings.tip_frame:
                tip = i
        self.joint_names = tuple(names)
        super().__init__(settings, len(idx))
        self._idx = idx
        self._tip = tip
        for link in range(-1, p.getNumJoints(self.body, physicsClientId=cid)):
            p.changeDynamics(self.body, link, linearDamping=0.0, angularDamping=0.0,
                             physicsClientId=cid)
        for i in idx:
            p.changeDynamics(self.body, i, jointDamping=settings.damping, physicsClientId=cid)
            if not settings.joint_limits:  # lower > upper: no limit
                p.changeDynamics(self.body, i, jointLowerLimit=1.0, jointUpperLimit=-1.0,
                                 physicsClientId=cid)
        # switch off the default velocity motors: torque control only
        p.setJointMotorControlArray(self.body, idx, p.VELOCITY_CONTROL,
                                    forces=[0.0] * len(idx), physicsClientId=cid)
        if settings.contacts:
            self._add_bench()
        self.workpiece_body = None if workpiece is None else self._add_workpiece(workpiece)
        self._tau = [0.0] * self.n
        self._t = 0.0
        self._wall0 = 0.0

    def _add_bench(self) -> None:
        p, cid = self._p, self.client
        half = [0.35, 0.25, 0.375]
        shape = p.createCollisionShape(p.GEOM_BOX, halfExtents=half, physicsClientId=cid)
        p.createMultiBody(0.0, shape, basePosition=[0, 0, -half[2]], physicsClientId=cid)

    def _add_workpiece(self, w: Workpiece) -> int:
        p, cid = self._p, self.client
        shape = p.createVisualShape(
            p.GEOM_MESH, vertices=np.asarray(w.vertices_m, dtype=np.float64).tolist(),
            indices=np.asarray(w.faces, dtype=np.int64).ravel().tolist(),
            rgbaColor=list(w.rgba), physicsClientId=cid)
        return int(p.createMultiBody(0.0, -1, shape, physicsClientId=cid))

    def _read(self) -> None:
        states = self._p.getJointStates(self.body, self._idx, physicsClientId=self.client)
        self._q[:] = [s[0] for s in states]
        self._qd[:] = [s[1] for s in states]

    def reset(self, q: ArrayLike, qd: ArrayLike | None = None) -> None:
        p, cid = self._p, self.client
        v = np.zeros(self.n) if qd is None else np.asarray(qd, dtype=np.float64)
        for i, qi, vi in zip(self._idx, np.asarray(q, dtype=np.float64), v, strict=True):
            p.resetJointState(self.body, i, float(qi), float(vi), physicsClientId=cid)
        self._tau = [0.0] * self.n
        self._t = 0.0
        self._wall0 = time.perf_counter()
        self._read()

    def apply(self, tau: Sequence[float]) -> None:
        self._tau = list(tau)

    def step(self, n: int = 1) -> None:
        p, cid, body, idx = self._p, self.client, self.body, self._idx
        torque, step = p.TORQUE_CONTROL, p.stepSimulation
        for _ in range(n):  # applied torques last one step: re-apply (zero-order hold)
            p.setJointMotorControlArray(body, idx, torque, forces=self._tau,
                                        physicsClientId=cid)
            step(physicsClientId=cid)
        self._t += n * self.dt
        self._read()

    def tip_pose(self) -> tuple[Array, Array]:
        p = self._p
        st = p.getLinkState(self.body, self._tip, computeForwardKinematics=True,
                            physicsClientId=self.client)
        rot = np.asarray(p.getMatrixFromQuaternion(st[5]), dtype=np.float64).reshape(3, 3)
        return np.asarray(st[4], dtype=np.float64), rot

    def sync_viewer(self) -> None:
        if not self._gui:
            return
        ahead = self._t - (time.perf_counter() - self._wall0)
        if ahead > 0:
            time.sleep(ahead)

    def close(self) -> None:
        if self._p.isConnected(self.client):
            self._p.disconnect(self.client)
