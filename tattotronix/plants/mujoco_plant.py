"""The MuJoCo plant: the generated MJCF with its torque motors (semi-implicit Euler)."""

from __future__ import annotations

import time
from collections.abc import Sequence
from pathlib import Path

from numpy.typing import ArrayLike

from tattotronix.plants.base import Array, Plant, PlantSettings, has_display
from tattotronix.robot.loaders import load_mujoco

__all__ = ["MujocoPlant"]


class MujocoPlant(Plant):
    """MuJoCo with the MJCF's ``motor`` actuators (torque, clamped at the effort limit).

    ``plant.contacts=false`` (default) switches contacts off; the panel never collides
    either way. ``plant.joint_limits=false`` (default) lifts the joint ranges, as in the
    model plant. ``plant.damping`` sets every joint's viscous damping.
    """

    backend = "mujoco"

    def __init__(self, mjcf: Path, settings: PlantSettings, *, viewer: bool = False):
        import mujoco

        self._mj = mujoco
        m = load_mujoco(mjcf)  # a missing or corrupt file: named, with the stage to re-run
        m.opt.timestep = settings.dt_s
        m.opt.integrator = mujoco.mjtIntegrator.mjINT_EULER
        m.opt.gravity[:] = (0.0, 0.0, -settings.gravity)
        if not settings.contacts:
            m.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONTACT
        if not settings.joint_limits:
            m.jnt_limited[:] = 0
        if not (settings.contacts or settings.joint_limits):
            # nothing left for the constraint solver: skip its pipeline (1.7 us a step)
            m.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONSTRAINT
        m.dof_damping[:] = settings.damping
        self.model = m
        self.data = mujoco.MjData(m)
        self.joint_names = tuple(mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, i)
                                 for i in range(m.njnt))
        super().__init__(settings, int(m.nv))
        self._site = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, settings.tip_frame)
        self._bad = int(mujoco.mjtWarning.mjWARN_BADQACC)
        self._viewer = None
        self._wall0 = 0.0
        if viewer and has_display():
            import mujoco.viewer

            self._viewer = mujoco.viewer.launch_passive(m, self.data)
        elif viewer:
            import logging

            logging.getLogger("tattotronix.plants").warning(
                "viewer=true needs a display (none found): running without one")

    @property
    def q(self) -> Array:
        return self.data.qpos

    @property
    def qd(self) -> Array:
        return self.data.qvel

    def reset(self, q: ArrayLike, qd: ArrayLike | None = None) -> None:
        mj, d = self._mj, self.data
        mj.mj_resetData(self.model, d)
        d.qpos[:] = q
        d.qvel[:] = 0.0 if qd is None else qd
        mj.mj_forward(self.model, d)
        self._wall0 = time.perf_counter()

    def apply(self, tau: Sequence[float]) -> None:
        self.data.ctrl[:] = tau

    def step(self, n: int = 1) -> None:
        self._mj.mj_step(self.model, self.data, n)

    def tip_pose(self) -> tuple[Array, Array]:
        self._mj.mj_kinematics(self.model, self.data)
        d = self.data
        return d.site_xpos[self._site].copy(), d.site_xmat[self._site].reshape(3, 3).copy()

    def healthy(self) -> bool:
        # MuJoCo resets the state itself on a non-finite acceleration: count the warning
        return self.data.warning[self._bad].number == 0 and super().healthy()

    def sync_viewer(self) -> None:
        if self._viewer is None:
            return
        if not self._viewer.is_running():
            raise KeyboardInterrupt("viewer closed")
        ahead = self.data.time - (time.perf_counter() - self._wall0)
        if ahead > 0:  # watch in real time
            time.sleep(ahead)
        self._viewer.sync()

    def close(self) -> None:
        if self._viewer is not None:
            self._viewer.close()
            self._viewer = None
