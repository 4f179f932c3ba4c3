"""Step responses of the joint loop: each joint stepped in turn on the ``model`` plant
(Pinocchio's ABA) under the shared controller, beside the coupled linear loop and the
single-axis design (python-control). The figures stage draws them (``steps.png``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from tattotronix.config.schema import ControllerConfig, PlantConfig
from tattotronix.io.jsontypes import JsonDict
from tattotronix.robot.description import RobotDescription

__all__ = ["StepSet", "linear_step", "step_set", "tuning_pose"]

Array = NDArray[np.float64]


@dataclass(frozen=True)
class StepSet:
    """A step on each joint in turn (the others holding), closed loop, one controller.

    Attributes:
        structure: the controller structure (``pid_g``: PI-D + gravity; ``pid_g_v``: PID
            + gravity, the derivative on the error).
        wn: bandwidth, rad/s.
        rate_hz: controller rate, Hz.
        step_rad: the step, rad.
        tune_q: (n,) the pose stepped from (and tuned at), rad.
        joint_names: the joints.
        t: (K,) time from the step, s.
        response: (n, K) joint i's travel when joint i is stepped, in units of the step
            (simulated on the ``model`` plant).
        linear: (n, K) the same from the coupled linear loop ``M(q0)`` (python-control).
        single_axis: (K,) the single-axis closed loop's step response (python-control).
        overshoot_pct: (n,) simulated overshoot, %.
        linear_overshoot_pct: (n,) coupled linear overshoot, %.
        single_axis_pct: the single-axis overshoot, % (24.9 PI-D, 20.6 PID).
        saturated: (n,) the torque reached its limit during joint i's step.
        peak_torque_nm: (n,) the largest |tau| (any joint) during joint i's step, N m.
    """

    structure: str
    wn: float
    rate_hz: float
    step_rad: float
    tune_q: Array
    joint_names: tuple[str, ...]
    t: Array
    response: Array
    linear: Array
    single_axis: Array
    overshoot_pct: Array
    linear_overshoot_pct: Array
    single_axis_pct: float
    saturated: NDArray[np.bool_]
    peak_torque_nm: Array

    @property
    def derivative_on_error(self) -> bool:
        """PID (velocity feedforward on) rather than PI-D."""
        return self.structure in ("pid_g_v", "computed_torque")

    @property
    def label(self) -> str:
        """``PI-D + g`` or ``PID + g (+ v)``."""
        return {"pid": "PI-D", "pid_g": "PI-D + g", "pid_g_v": "PID + g + v",
                "computed_torque": "computed torque"}.get(self.structure, self.structure)

    def summary(self) -> JsonDict:
        """JSON-ready overshoots per joint."""
        return {"structure": self.structure, "wn": self.wn, "step_deg": math.degrees(
            self.step_rad), "single_axis_pct": self.single_axis_pct,
            "overshoot_pct": dict(zip(self.joint_names, self.overshoot_pct.tolist(),
                                      strict=True)),
            "linear_overshoot_pct": dict(zip(self.joint_names,
                                             self.linear_overshoot_pct.tolist(), strict=True)),
            "saturated": [j for j, s in zip(self.joint_names, self.saturated, strict=True)
                          if s]}


def linear_step(mass_matrix: ArrayLike, kp: ArrayLike, ki: ArrayLike, kd: ArrayLike,
                derivative_on_error: bool, t: ArrayLike) -> Array:
    """Unit-step responses of the linearised coupled loop ``M qdd = tau`` under the
    per-joint PID (gravity cancelled by its feedforward), by python-control.

    State ``(q, p, I)`` with ``p = M qd - Kd' r`` (``Kd' = Kd`` when the derivative acts on
    the error, else 0), which keeps the step's velocity impulse out of the state.

    Args:
        mass_matrix: (n, n) M at the pose, kg m^2.
        kp, ki, kd: (n,) gains, N m/rad, N m/(rad s), N m s/rad.
        derivative_on_error: PID (True) or PI-D (False).
        t: (K,) times, s.

    Returns:
        (n, n, K): output ``i`` (joint angle, per unit step) for a step on input ``j``.
    """
    import control

    m = np.asarray(mass_matrix, float)
    n = len(m)
    mi = np.linalg.inv(m)
    kp_, ki_, kd_ = (np.diag(np.asarray(v, float)) for v in (kp, ki, kd))
    kde = kd_ if derivative_on_error else np.zeros((n, n))
    z, eye = np.zeros((n, n)), np.eye(n)
    a = np.block([[z, mi, z], [-kp_, -kd_ @ mi, ki_], [-eye, z, z]])
    b = np.vstack([mi @ kde, kp_ - kd_ @ mi @ kde, eye])
    c = np.hstack([eye, z, z])
    sys = control.ss(a, b, c, np.zeros((n, n)))
    resp = control.step_response(sys, T=np.asarray(t, float))
    return np.asarray(resp.outputs, dtype=np.float64).reshape(n, n, -1)


def _single_axis(derivative_on_error: bool, wn: float, t: Array) -> Array:
    import control

    num = [3.0 * wn, 3.0 * wn**2, wn**3] if derivative_on_error else [3.0 * wn**2, wn**3]
    sys = control.tf(num, [1.0, 3.0 * wn, 3.0 * wn**2, wn**3])
    return np.asarray(control.step_response(sys, T=t).outputs, dtype=np.float64).ravel()


def step_set(desc: RobotDescription, urdf: Path, tune_q: ArrayLike, wn: float,
             structure: str, rate_hz: float, dt_s: float,
             torque_limit_nm: float | ArrayLike, step_rad: float = math.radians(5.0),
             periods: float = 10.0) -> StepSet:
    """Step each joint in turn by ``step_rad`` from ``tune_q`` on the ``model`` plant
    (Pinocchio ABA) under the shared controller tuned at ``tune_q``.

    The reference jumps one tick after the start (the arm starts at rest, held by the
    gravity feedforward). With the derivative on the error (``pid_g_v``) the step's
    rate, an impulse, is given as ``step / T`` for that one tick, as the continuous PID
    sees it. The run lasts ``periods / wn`` after the step.

    Args:
        desc: the robot description.
        urdf: the generated URDF.
        tune_q: (n,) pose, rad.
        wn: bandwidth, rad/s.
        structure: ``pid``, ``pid_g``, ``pid_g_v`` or ``computed_torque``.
        rate_hz: controller rate, Hz.
        dt_s: plant step, s.
        torque_limit_nm: per-joint limit, N m.
        step_rad: step size, rad.
        periods: run length in units of ``1 / wn``.
    """
    from tattotronix.control.analysis import step_overshoot_pct
    from tattotronix.control.controller import Controller, Gains
    from tattotronix.control.dynamics import Dynamics
    from tattotronix.control.reference import Reference
    from tattotronix.control.simulate import simulate
    from tattotronix.plants import PlantSettings, make_plant

    q0 = np.asarray(tune_q, float)
    dyn = Dynamics(urdf, desc.gravity)
    n = dyn.n
    gains = Gains.tuned_at(dyn, q0, wn)
    period = 1.0 / rate_hz
    ticks = max(int(math.ceil(periods / wn / period)), 20) + 2
    tk = period * np.arange(ticks, dtype=np.float64)
    # the default plant (no friction, no limits, no contacts) at the given step
    settings = PlantSettings.from_settings(replace(PlantConfig(), dt_s=dt_s), desc.gravity,
                                         desc.tip_frame)
    resp = np.empty((n, ticks - 1))
    sat = np.zeros(n, bool)
    peak = np.zeros(n)
    for j in range(n):
        ctl = Controller(dyn, gains, structure, rate_hz, torque_limit_nm)
        q = np.tile(q0, (ticks, 1))
        q[1:, j] += step_rad
        qd = np.zeros_like(q)
        if ctl.derivative_on_error:
            qd[1, j] = step_rad / period
        ref = Reference(t=tk, q=q, qd=qd, qdd=np.zeros_like(q), period_s=period)
        with make_plant("model", settings, urdf=urdf, mjcf=urdf, joint_names=desc.joint_names,
                        lower=desc.lower, upper=desc.upper) as plant:
            run = simulate(plant, ctl, ref, sample_every=10, abort_error_rad=10.0)
        got = np.full(ticks, np.nan)
        got[:len(run.q)] = run.q[:, j]
        resp[j] = (got[1:] - q0[j]) / step_rad
        sat[j] = run.verdict == "saturated"
        peak[j] = run.peak_torque_nm
    t = tk[:-1]  # from the step (tick 1)
    lin_all = linear_step(dyn.mass_matrix(q0), gains.kp, gains.ki, gains.kd,
                          structure in ("pid_g_v", "computed_torque"), t)
    lin = np.array([lin_all[j, j] for j in range(n)])
    doe = structure in ("pid_g_v", "computed_torque")
    single = _single_axis(doe, wn, t)

    def over(r: Array) -> Array:
        return np.asarray(100.0 * (np.nanmax(r, axis=-1) - 1.0), dtype=np.float64)

    return StepSet(structure=structure, wn=float(wn), rate_hz=float(rate_hz),
                   step_rad=float(step_rad), tune_q=q0, joint_names=desc.joint_names, t=t,
                   response=resp, linear=lin, single_axis=single, overshoot_pct=over(resp),
                   linear_overshoot_pct=over(lin), single_axis_pct=step_overshoot_pct(doe),
                   saturated=sat, peak_torque_nm=peak)


def tuning_pose(ctl: ControllerConfig, t: Array, q: Array, qd: Array) -> Array:
    """The controller's tuning pose: ``controller.tune_q``, or the reference mid-way
    through the whole drawing (what the simulate stage tunes at)."""
    from tattotronix.control.reference import reference_at_ticks

    if ctl.tune_q is not None:
        return np.asarray(ctl.tune_q, dtype=np.float64)
    return reference_at_ticks(t, q, qd, 1.0 / float(ctl.rate_hz)).middle_pose()
