"""The MuJoCo plant: the generated MJCF with its torque motors (semi-implicit Euler).

The joint PID can also run inside the engine (:meth:`MujocoPlant.engine_pid`): the motors
become MuJoCo's native ``pid`` actuators (inputs: the position and velocity setpoints;
``ki`` on an integral activation, ``actearly`` so the force uses the integral with this
step's error in it, no anti-windup, as ours), gravity compensation becomes actuator force
(body ``gravcomp`` with joint ``actuatorgravcomp``), and the joint's actuator force range
clamps the sum, as our controller clamps PID plus gravity. ``mujoco.rollout`` then steps a
whole stretch of setpoints in C, with no Python per step (docs/control.md, "The loop
inside the engine").
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from tattotronix.plants.base import (
    Array,
    EnginePid,
    PidSpec,
    Plant,
    PlantSettings,
    Workpiece,
    has_display,
)
from tattotronix.robot.loaders import load_mujoco, load_mujoco_spec

__all__ = ["WORKPIECE", "MujocoPlant", "MujocoPid", "with_workpiece"]


class MujocoPlant(Plant):
    """MuJoCo with the MJCF's ``motor`` actuators (torque, clamped at the effort limit).

    ``plant.contacts=false`` (default) switches contacts off; the panel never collides
    either way. ``plant.joint_limits=false`` (default) lifts the joint ranges, as in the
    model plant. ``plant.damping`` sets every joint's viscous damping. A ``workpiece``
    takes the panel's place (:func:`with_workpiece`).
    """

    backend = "mujoco"

    def __init__(self, mjcf: Path, settings: PlantSettings, *, viewer: bool = False,
                 workpiece: Workpiece | None = None):
        import mujoco

        self._mj = mujoco
        self._mjcf = Path(mjcf)
        self._workpiece = workpiece
        # a missing or corrupt file: named, with the stage to re-run
        m = (load_mujoco(mjcf) if workpiece is None
             else with_workpiece(load_mujoco_spec(mjcf), workpiece).compile())
        _apply_settings(m, settings)
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

    def engine_pid(self, pid: PidSpec) -> EnginePid | None:
        return MujocoPid(self._mjcf, self.settings, pid, workpiece=self._workpiece)

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


#: the name of the workpiece's mesh and geom in the model
WORKPIECE = "workpiece"


def with_workpiece(spec: Any, workpiece: Workpiece) -> Any:  # Any: mujoco.MjSpec
    """The MJCF's spec (``mujoco.MjSpec``) with ``workpiece`` in the panel's place: a mesh
    geom on the world body that collides with nothing (as the panel), its inertia taken as
    a shell (a scanned surface need not be closed; a world geom adds no mass anyway)."""
    import mujoco

    panel = next((g for g in spec.geoms if g.name == "panel"), None)
    if panel is not None:
        spec.delete(panel)
    mesh = spec.add_mesh(name=WORKPIECE)
    mesh.uservert = np.asarray(workpiece.vertices_m, dtype=np.float64).ravel().tolist()
    mesh.userface = np.asarray(workpiece.faces, dtype=np.int64).ravel().tolist()
    mesh.inertia = mujoco.mjtMeshInertia.mjMESH_INERTIA_SHELL
    spec.worldbody.add_geom(name=WORKPIECE, type=mujoco.mjtGeom.mjGEOM_MESH,
                            meshname=WORKPIECE, contype=0, conaffinity=0,
                            rgba=list(workpiece.rgba))
    return spec


def _apply_settings(m: Any, settings: PlantSettings) -> None:
    """Set a compiled model's options from the plant settings (``m``: mujoco.MjModel)."""
    import mujoco

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


#: MuJoCo's ``input`` bits of a ``pid`` actuator: the position and velocity setpoints
_PID_INPUTS = 1 | 2


class MujocoPid(EnginePid):
    """The generated MJCF with a native ``pid`` actuator on every joint (see the module
    docstring), stepped by ``mujoco.rollout``.

    Args:
        mjcf: the generated MJCF.
        settings: the plant settings (as the torque plant's).
        pid: the gains, the torque limit and whether gravity is compensated.
        workpiece: in the panel's place, as the torque plant's.
    """

    def __init__(self, mjcf: Path, settings: PlantSettings, pid: PidSpec, *,
                 workpiece: Workpiece | None = None):
        import mujoco
        from mujoco import rollout

        self._mj = mujoco
        self._rollout = rollout
        spec = load_mujoco_spec(mjcf)
        if workpiece is not None:
            with_workpiece(spec, workpiece)
        joints = [a.target for a in spec.actuators]
        # the motors clamp at their control range too: the tighter of the two holds
        motor = [float(np.min(np.abs(a.ctrlrange))) if a.ctrllimited else np.inf
                 for a in spec.actuators]
        limit = np.minimum(np.asarray(pid.limit, dtype=np.float64), motor)
        for a in list(spec.actuators):
            spec.delete(a)
        for i, name in enumerate(joints):
            a = spec.add_actuator(name=f"pid_{name}", target=name,
                                  trntype=mujoco.mjtTrn.mjTRN_JOINT)
            a.set_to_pid(kp=float(pid.kp[i]), kv=float(pid.kd[i]), ki=float(pid.ki[i]),
                         ctrlspec=_PID_INPUTS)
            a.actearly = True  # the force sees I_k = I_{k-1} + dt e_k, as ours
            a.ctrllimited = mujoco.mjtLimited.mjLIMITED_FALSE
            a.forcelimited = mujoco.mjtLimited.mjLIMITED_FALSE
            j = spec.joint(name)
            j.actfrclimited = mujoco.mjtLimited.mjLIMITED_TRUE
            j.actfrcrange = [-float(limit[i]), float(limit[i])]
            j.actgravcomp = bool(pid.gravity)
            spec.add_sensor(name=f"tau_{name}", type=mujoco.mjtSensor.mjSENS_JOINTACTFRC,
                            objtype=mujoco.mjtObj.mjOBJ_JOINT, objname=name)
        if pid.gravity:
            for body in spec.bodies[1:]:  # not the world
                body.gravcomp = 1.0
        m = spec.compile()
        _apply_settings(m, settings)
        self.model = m
        self.data = mujoco.MjData(m)
        self.n = int(m.nv)
        self._kind = mujoco.mjtState.mjSTATE_FULLPHYSICS
        self._nstate = mujoco.mj_stateSize(m, self._kind)
        # the state vector is (time, qpos, qvel, act, ...)
        self._q0 = 1
        self._v0 = 1 + int(m.nq)
        self._pos = m.actuator_ctrladr.astype(np.intp)  # each actuator's (pos, vel) inputs
        self._bad = int(mujoco.mjtWarning.mjWARN_BADQACC)
        self._state = np.zeros(self._nstate)
        self._warned = False

    def reset(self, q: ArrayLike, qd: ArrayLike) -> None:
        mj, d = self._mj, self.data
        mj.mj_resetData(self.model, d)
        d.qpos[:] = q
        d.qvel[:] = qd
        mj.mj_forward(self.model, d)
        mj.mj_getState(self.model, d, self._state, self._kind)
        self._warned = False

    def run(self, q_ref: Array, v_ref: Array) -> tuple[Array, Array, Array]:
        steps = len(q_ref)
        n, m = self.n, self.model
        ctrl = np.empty((1, steps, m.nu))
        ctrl[0][:, self._pos] = q_ref
        ctrl[0][:, self._pos + 1] = v_ref
        state, sensors = self._rollout.rollout(m, self.data, self._state[None], ctrl)
        states = state[0]
        q = np.empty((steps, n))
        qd = np.empty((steps, n))
        q[0] = self._state[self._q0:self._q0 + n]
        qd[0] = self._state[self._v0:self._v0 + n]
        q[1:] = states[:-1, self._q0:self._q0 + n]
        qd[1:] = states[:-1, self._v0:self._v0 + n]
        self._state = states[-1].copy()
        if self.data.warning[self._bad].number:
            self._warned = True
        return q, qd, np.ascontiguousarray(sensors[0][:, :n])

    def state(self) -> tuple[Array, Array]:
        n = self.n
        return (self._state[self._q0:self._q0 + n].copy(),
                self._state[self._v0:self._v0 + n].copy())

    def healthy(self) -> bool:
        return not self._warned and bool(np.all(np.isfinite(self._state)))
