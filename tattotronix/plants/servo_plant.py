"""The servo plant (``backend=servo``): the arm on its hobby servos, playing the servo program
(docs/servos.md, "The servo model").

Built on the generated MJCF, with the servo's own loop inside MuJoCo:

* a ``position`` actuator per joint, ``kp = stall_nm / band``, its force clamped to the
  stall torque (``forcerange``): the drive saturates once the error passes the band;
* the motor's back-EMF as joint damping ``stall_nm / speed_rad_s``: at full drive the
  joint cannot pass its no-load speed; the motor's inertia through the gears as
  ``armature``;
* the dead band: the drive acts only on the error beyond half the band, so the servo
  stops at the band's edge and stays there until the command leaves the band: its
  target is the command through a play of the band's width (:func:`play`, per frame;
  MuJoCo's ``frictionloss`` is a soft constraint that creeps, so it cannot hold a band);
* the latency as MuJoCo's actuator delay buffer (``delay``, zero-order hold);
* the 50 Hz frame as the control held over each frame (``lag=false``: interpolated
  between frames, with a stiff critically damped loop instead).

The servo's output shaft is the engine's joint; the link follows it through the gears'
play (:func:`tattotronix.hardware.servo_model.play`), which is what the tip and the ink
see. ``mujoco.rollout`` steps a stretch of frames in C.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from itertools import accumulate
from pathlib import Path
from typing import Protocol

import numpy as np

from tattotronix.plants.base import Array, PlantSettings
from tattotronix.plants.mujoco_plant import _apply_settings
from tattotronix.robot.loaders import load_mujoco_spec

__all__ = ["PulseLine", "ServoArm", "ServoRun", "ServoSpec", "play"]

#: frames per rollout call: long enough to leave Python rarely, short enough to report
#: progress and keep one call's states small
_CHUNK_S = 5.0


class PulseLine(Protocol):
    """A servo's calibrated line and travel (a
    :class:`~tattotronix.hardware.servos.ServoChannel`)."""

    @property
    def zero_us(self) -> float: ...
    @property
    def us_per_rad(self) -> float: ...
    @property
    def min_us(self) -> float: ...
    @property
    def max_us(self) -> float: ...


@dataclass(frozen=True)
class ServoSpec:
    """One joint's servo, as the servo plant models it (SI; switched-off parts are zero).

    Attributes:
        type: the catalogue name (``MG996R``).
        bus: a serial bus servo (positions in encoder steps) rather than a PWM one.
        deadband_rad: the dead band's whole width, rad.
        stall_nm: the drive's torque at full output, N m.
        speed_rad_s: the no-load speed, rad/s.
        band_rad: the error at which the drive saturates, rad.
        backlash_rad: the gears' play, rad.
        nonlinearity_rad: the pulse map's largest bend, rad.
        armature_kgm2: the motor's inertia seen at the joint, kg m^2.
        latency_s: from a command to the drive acting on it, s.
        step_rad: a bus servo's encoder step, rad (0 for PWM).
        count: servos driving the joint together (the shoulder's mirrored pair: 2); the
            torque and the inertia are theirs summed.
        lag: the drive as built: proportional over ``band_rad``, late by ``latency_s``,
            each frame held (False: the stiff, exact loop the plant's ``lag=false`` runs,
            which nothing needs to lead or push).
    """

    type: str
    bus: bool
    deadband_rad: float
    stall_nm: float
    speed_rad_s: float
    band_rad: float
    backlash_rad: float
    nonlinearity_rad: float
    armature_kgm2: float
    latency_s: float
    step_rad: float
    count: int = 1
    lag: bool = True

    @property
    def kp(self) -> float:
        """The drive's proportional gain, N m/rad (stall torque over the band)."""
        return self.stall_nm / self.band_rad

    @property
    def back_emf(self) -> float:
        """The motor's speed damping, N m s/rad (stall torque over the no-load speed)."""
        return self.stall_nm / self.speed_rad_s

    def true_angle(self, servo: PulseLine, pulse_us: Array) -> Array:
        """The angle (rad) this servo turns to for pulse widths (us) on ``servo`` (whose
        line, ``zero_us`` and ``us_per_rad``, is the calibration's)."""
        p = np.asarray(pulse_us, dtype=np.float64)
        line = (p - servo.zero_us) / servo.us_per_rad
        if self.nonlinearity_rad == 0.0:
            return line
        half = 0.5 * (servo.max_us - servo.min_us)
        s = np.clip((p - 0.5 * (servo.max_us + servo.min_us)) / half, -1.0, 1.0)
        return line + self.nonlinearity_rad * np.sin(np.pi * s)


def play(x: Array, width: float, start: float | None = None) -> Array:
    """Backlash as the play operator: the output follows ``x`` only once ``x`` is more
    than ``width / 2`` away, ``y_k = clamp(y_{k-1}, x_k - width/2, x_k + width/2)``.

    Args:
        x: (K,) the driving angle (the servo's output shaft), rad.
        width: the play, rad (0: ``y = x``).
        start: ``y`` before the first sample (default ``x[0]``, centred in the play).
    """
    x = np.asarray(x, dtype=np.float64)
    if width <= 0 or len(x) == 0:
        return x.copy()
    h = 0.5 * width
    y0 = float(x[0]) if start is None else float(start)
    lo, hi = x - h, x + h
    if len(x) < _PLAY_STEPS_BELOW or not (np.isfinite(y0) and np.all(np.isfinite(x))):
        return _play_steps(lo, hi, y0)
    return _play_blocks(lo, hi, y0)


#: signals shorter than this are played one sample at a time (:func:`_play_steps`)
_PLAY_STEPS_BELOW = 4096


def _block_len(k: int) -> int:
    """Samples per block of :func:`_play_blocks` for ``k`` samples: about ``sqrt(k)``,
    which balances its two loops (the steps of a block, in numpy across the blocks, and
    the blocks, in Python); any length gives the same numbers."""
    return max(16, math.isqrt(k))


def _clamp(y: Array, lo: Array, hi: Array) -> Array:
    """The play operator's step, ``lo`` if ``y < lo``, else ``hi`` if ``y > hi``, else
    ``y``, element by element."""
    return np.where(y < lo, lo, np.where(y > hi, hi, y))


def _play_steps(lo: Array, hi: Array, y0: float) -> Array:
    """The play operator one sample at a time."""
    def step(y: float, k: int) -> float:
        return lo_l[k] if y < lo_l[k] else (hi_l[k] if y > hi_l[k] else y)

    lo_l, hi_l = lo.tolist(), hi.tolist()
    return np.fromiter(accumulate(range(len(lo_l)), step, initial=y0), dtype=np.float64,
                       count=len(lo_l) + 1)[1:]


def _play_blocks(lo: Array, hi: Array, y0: float) -> Array:
    """The play operator over blocks of samples side by side, the same numbers as
    :func:`_play_steps` (finite input) in a tenth of the time.

    A run of steps is itself a clamp, to the band its steps narrow ``(-inf, inf)`` to
    (each step only ever picks one of its bounds or what it was given). So each block's
    band is found with the blocks in parallel, the value entering each block follows from
    the one before through its band, and then every block runs its own steps from there,
    in parallel.
    """
    k = len(lo)
    block = _block_len(k)
    blocks = -(-k // block)
    pad = blocks * block - k  # the last block runs on past the end on its last bounds
    # (step in block, block): each step of every block is one contiguous row
    los = np.ascontiguousarray(
        np.concatenate([lo, np.full(pad, lo[-1])]).reshape(blocks, block).T)
    his = np.ascontiguousarray(
        np.concatenate([hi, np.full(pad, hi[-1])]).reshape(blocks, block).T)
    band_lo = np.full(blocks, -np.inf)
    band_hi = np.full(blocks, np.inf)
    for step_lo, step_hi in zip(los, his, strict=True):
        band_lo = _clamp(band_lo, step_lo, step_hi)
        band_hi = _clamp(band_hi, step_lo, step_hi)
    entering = np.empty(blocks)
    y = y0
    for b, (a, c) in enumerate(zip(band_lo.tolist(), band_hi.tolist(), strict=True)):
        entering[b] = y
        y = a if y < a else (c if y > c else y)
    out = np.empty((block, blocks))
    ys = entering
    for j, (step_lo, step_hi) in enumerate(zip(los, his, strict=True)):
        ys = out[j] = _clamp(ys, step_lo, step_hi)
    return out.T.reshape(-1)[:k]


@dataclass(frozen=True)
class ServoRun:
    """What the servo arm did, every plant step.

    Attributes:
        t: (K,) step times, s.
        shaft: (K, n) the servos' output shafts, rad.
        q: (K, n) the links (after the gears' play), rad.
        qd: (K, n) the shafts' rates, rad/s.
        tau: (K, n) the servos' torques, N m.
        target: (K, n) the angle each servo was driving to (its command, after latency).
        healthy: the engine reported no instability and the state stayed finite.
    """

    t: Array
    shaft: Array
    q: Array
    qd: Array
    tau: Array
    target: Array
    healthy: bool


class ServoArm:
    """The generated MJCF with each joint's motor replaced by its servo (module docstring).

    Args:
        mjcf: the generated MJCF.
        settings: the plant settings (step, gravity, limits, contacts).
        specs: each joint's servo (:func:`~tattotronix.hardware.servo_model.joint_servos`).
        lag: model the servo's loop (else a stiff loop of ``ideal_wn``, no latency).
        ideal_wn: the stiff loop's bandwidth, rad/s.
        q0: the pose the stiff loop's inertia is taken at, rad.
    """

    def __init__(self, mjcf: Path, settings: PlantSettings, specs: Sequence[ServoSpec], *,
                 lag: bool, ideal_wn: float, q0: Array):
        import mujoco
        from mujoco import rollout

        self._mj = mujoco
        self._rollout = rollout
        self.specs = tuple(specs)
        self.lag = bool(lag)
        self.dt = float(settings.dt_s)
        spec = load_mujoco_spec(mjcf)
        joints = [a.target for a in spec.actuators]
        self.joint_names = tuple(joints)
        if len(joints) != len(self.specs):
            raise ValueError(f"{len(self.specs)} servos for {len(joints)} joints")
        for a in list(spec.actuators):
            spec.delete(a)
        inertia = _joint_inertia(mjcf, settings, q0) if not lag else None
        for i, (name, s) in enumerate(zip(joints, self.specs, strict=True)):
            a = spec.add_actuator(name=f"servo_{name}", target=name,
                                  trntype=mujoco.mjtTrn.mjTRN_JOINT)
            j = spec.joint(name)
            if lag:
                kp = s.kp
                a.set_to_position(kp=kp)
                a.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE
                a.forcerange = [-s.stall_nm, s.stall_nm]
                j.damping = [s.back_emf, 0.0, 0.0]
                if s.latency_s > 0:
                    a.delay = s.latency_s
                    a.nsample = int(math.ceil(s.latency_s / self.dt)) + 2
                    a.interp = 0
            else:
                assert inertia is not None
                mass = inertia[i] + s.armature_kgm2
                kp = mass * ideal_wn ** 2
                a.set_to_position(kp=kp, kv=2.0 * mass * ideal_wn)
                a.forcelimited = mujoco.mjtLimited.mjLIMITED_FALSE
                j.damping = [0.0, 0.0, 0.0]
            a.ctrllimited = mujoco.mjtLimited.mjLIMITED_FALSE
            # the drive's force as the engine applied it (after the delay and the clamp)
            spec.add_sensor(name=f"tau_{name}", type=mujoco.mjtSensor.mjSENS_ACTUATORFRC,
                            objtype=mujoco.mjtObj.mjOBJ_ACTUATOR, objname=f"servo_{name}")
            j.armature = s.armature_kgm2
        m = spec.compile()
        damping = m.dof_damping.copy()
        _apply_settings(m, settings)
        m.dof_damping[:] = damping + settings.damping  # the back-EMF, plus any friction
        m.opt.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
        self.model = m
        self.data = mujoco.MjData(m)
        self.n = int(m.nv)
        self._kind = mujoco.mjtState.mjSTATE_FULLPHYSICS
        self._q0 = 1
        self._v0 = 1 + int(m.nq)
        self._bad = int(mujoco.mjtWarning.mjWARN_BADQACC)

    def run(self, command: Array, frame_hz: float, q0: Array,
            progress: Callable[[float], None] | None = None) -> ServoRun:
        """Play ``command`` (F, n): the angle each servo is sent every frame, rad.

        The arm starts at rest at ``q0`` (the servos' first command held long before).
        With ``lag`` each frame's command is held over the frame; without, it is
        interpolated between frames.

        Args:
            command: (F, n) the angle each servo turns to for its frame's pulse, rad
                (before its dead band).
            frame_hz: frames per second.
            q0: the starting pose, rad.
            progress: called with the simulated seconds done, after each stretch.
        """
        mj, m, d = self._mj, self.model, self.data
        command = np.column_stack([play(command[:, i], s.deadband_rad)
                                   for i, s in enumerate(self.specs)])
        per_frame = 1.0 / (frame_hz * self.dt)
        steps = int(round((len(command) - 1) * per_frame)) + 1
        ts = np.arange(steps, dtype=np.float64) * self.dt
        tf = np.arange(len(command)) / frame_hz
        if self.lag:
            idx = np.minimum(np.floor(ts * frame_hz + 1e-9).astype(np.intp), len(command) - 1)
            ctrl = command[idx]
        else:
            ctrl = np.column_stack([np.interp(ts, tf, command[:, i])
                                    for i in range(self.n)])
        mj.mj_resetData(m, d)
        d.qpos[:] = q0
        d.ctrl[:] = command[0]
        if m.nhistory:  # the delay buffers start full of the first command
            for i in range(m.nu):
                samples = int(m.actuator_history[i, 0])
                if samples:  # a servo without latency has no buffer
                    mj.mj_initCtrlHistory(m, d, i, None,
                                          np.full(samples, float(command[0, i])))
        mj.mj_forward(m, d)
        state = np.empty(mj.mj_stateSize(m, self._kind))
        mj.mj_getState(m, d, state, self._kind)
        n = self.n
        shaft = np.empty((steps, n))
        qd = np.empty((steps, n))
        tau = np.empty((steps, n))
        chunk = max(1, int(round(_CHUNK_S / self.dt)))
        healthy = True
        for start in range(0, steps, chunk):
            stop = min(steps, start + chunk)
            states, sensors = self._rollout.rollout(m, d, state[None], ctrl[None, start:stop])
            states = states[0]
            shaft[start] = state[self._q0:self._q0 + n]
            qd[start] = state[self._v0:self._v0 + n]
            shaft[start + 1:stop] = states[:-1, self._q0:self._q0 + n]
            qd[start + 1:stop] = states[:-1, self._v0:self._v0 + n]
            tau[start:stop] = sensors[0][:, :n]
            state = states[-1].copy()
            healthy = healthy and not d.warning[self._bad].number
            if progress is not None:
                progress(stop * self.dt)
        target = self._delayed(ctrl)
        q = np.column_stack([play(shaft[:, i], s.backlash_rad)
                             for i, s in enumerate(self.specs)])
        healthy = healthy and bool(np.all(np.isfinite(shaft)))
        return ServoRun(t=ts, shaft=shaft, q=q, qd=qd, tau=tau, target=target,
                        healthy=healthy)

    def _delayed(self, ctrl: Array) -> Array:
        """The command each drive acts on at each step: ``ctrl`` later by the latency
        (MuJoCo's delay buffer acts ``ceil(latency / dt)`` steps later)."""
        out = np.empty_like(ctrl)
        for i, s in enumerate(self.specs):
            lag = math.ceil(s.latency_s / self.dt - 1e-9) if self.lag else 0
            lag = min(len(ctrl), lag)
            out[:lag, i] = ctrl[0, i]
            out[lag:, i] = ctrl[:len(ctrl) - lag, i]
        return out


def _joint_inertia(mjcf: Path, settings: PlantSettings, q0: Array) -> Array:
    """Each joint's own inertia (the mass matrix's diagonal) at ``q0``, kg m^2."""
    import mujoco

    from tattotronix.robot.loaders import load_mujoco

    m = load_mujoco(mjcf)
    _apply_settings(m, settings)
    d = mujoco.MjData(m)
    d.qpos[:] = q0
    mujoco.mj_forward(m, d)
    full = np.zeros((m.nv, m.nv))
    mujoco.mj_fullM(m, d, full)
    return np.diag(full).copy()
