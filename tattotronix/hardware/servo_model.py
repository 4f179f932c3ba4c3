"""How a hobby servo turns a command into a joint angle, and what the servo program can do
about it (docs/servos.md).

A servo is described by its catalogue entry (``robot.servos.<type>``, with the sources of
its figures in docs/servos.md); :func:`joint_servos` gives each joint its servo, as mounted
(``robot.servo_mounts``) or one type on every joint (``servo.type``).

The parts of the model that are not physics (the physics is the MuJoCo servo plant,
:mod:`tattotronix.plants.servo_plant`):

* :meth:`~tattotronix.plants.servo_plant.ServoSpec.true_angle`, the servo's own
  pulse-to-angle map: the calibration's line
  plus a bend of up to ``nonlinearity_deg``, ``nonlinearity * sin(pi s)`` with ``s`` the
  width's place in the servo's travel (-1 at ``min_us``, +1 at ``max_us``);
* :func:`~tattotronix.plants.servo_plant.play`, gear backlash (and the dead band) as the
  play operator: the link stays put until the servo
  has taken up the play, ``y_k = clamp(y_{k-1}, x_k - b/2, x_k + b/2)``;
* :func:`measure_fit`, the calibration procedure of ``stages/servo_pulse.py`` on a
  simulated servo: the servo is sent ``fit_points`` widths across its travel and the angle
  is read to ``protractor_deg``; the pairs are what a calibration file's ``points`` hold;
* :func:`compensate`, the servo program's corrections: the sag (each frame's angle plus
  the torque the joint needs there over the servo's gain: a proportional servo holds a
  load only that far short of its command), backlash (each joint arrives at every marking
  stroke moving one chosen way, and where the plan reverses the command jumps the play
  first) and the dead band (each move is pushed past half the band, so the servo stops
  where it was sent instead of short of it); :func:`servo_lead_s`, how far ahead a
  joint's commands are sent so that a late servo arrives on time.

Units: rad inside (``_deg``, ``_us``, ``_ms`` as named).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import replace
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from tattotronix.config.schema import (
    CompensateConfig,
    HardwareConfig,
    RobotConfig,
    ServoPlantConfig,
    ServoSpreadConfig,
)
from tattotronix.errors import TattotronixError
from tattotronix.hardware.servos import Calibration, PulseFit, ServoChannel
from tattotronix.plants.servo_plant import ServoSpec

__all__ = ["SERVO_FIGURES", "SPREAD_FIELDS", "compensate", "joint_servos",
           "load_servo_figures", "measure_fit", "servo_figures", "servo_lead_s", "spread_servos",
           "with_measured_fits"]

Array = NDArray[np.float64]


def joint_servos(robot: RobotConfig, joint_names: Sequence[str], calib: Calibration,
                 servo: ServoPlantConfig, measured: Mapping[str, Mapping[str, float]]
                 | None = None) -> tuple[ServoSpec, ...]:
    """Each joint's servo: the mounted one (``robot.servo_mounts``) or ``servo.type`` on
    every joint, with the imperfections ``servo`` switches off set to zero, and the
    figures ``measured`` gives (joint -> ``backlash_deg`` / ``deadband_deg``:
    :func:`load_servo_figures`) in place of the catalogue's.

    Raises:
        TattotronixError: an unknown servo type, or a joint with no servo mounted.
    """
    catalogue = {str(k): v for k, v in robot.servos.items()}
    mounted = {str(m.at): str(m.servo) for m in robot.servo_mounts}
    counts = {str(m.at): int(m.count) for m in robot.servo_mounts}
    out = []
    for name in joint_names:
        kind = str(servo.type) if servo.type is not None else mounted.get(name)
        if kind is None:
            raise TattotronixError(f"no servo is mounted at {name} (robot.servo_mounts): "
                                   "mount one, or give servo.type")
        if kind not in catalogue:
            raise TattotronixError(f"servo.type={kind}: not in the catalogue robot.servos "
                                   f"({', '.join(sorted(catalogue))})")
        c = catalogue[kind]
        bus = str(getattr(c.command, "value", c.command)) == "bus"
        step = math.radians(float(c.step_deg))
        if bus and step <= 0:
            raise TattotronixError(f"robot.servos.{kind}: a bus servo needs its step_deg")
        us_per_rad = abs(calib.joint(name).a.us_per_rad)
        count = counts.get(name, 1)
        # a bus servo holds within one encoder step either way
        band = 2.0 * step if bus else float(c.deadband_us) / us_per_rad
        out.append(ServoSpec(
            type=kind, bus=bus,
            deadband_rad=band if servo.deadband else 0.0,
            stall_nm=count * float(c.stall_nm), speed_rad_s=float(c.speed_rad_s),
            band_rad=math.radians(float(c.band_deg)),
            backlash_rad=math.radians(float(c.backlash_deg)) if servo.backlash else 0.0,
            nonlinearity_rad=(math.radians(float(c.nonlinearity_deg))
                              if servo.nonlinearity and not bus else 0.0),
            armature_kgm2=count * float(c.armature_kgm2),
            latency_s=float(c.latency_ms) * 1e-3 if servo.lag else 0.0,
            step_rad=step if servo.quantise else 0.0, count=count, lag=bool(servo.lag)))
        own = (measured or {}).get(name, {})
        if "backlash_deg" in own and servo.backlash:
            out[-1] = replace(out[-1], backlash_rad=math.radians(float(own["backlash_deg"])))
        if "deadband_deg" in own and servo.deadband:
            out[-1] = replace(out[-1], deadband_rad=math.radians(float(own["deadband_deg"])))
    return tuple(out)


#: the figures a servo-figures file may give per joint, and their largest sane value, deg
SERVO_FIGURES = {"backlash_deg": 20.0, "deadband_deg": 20.0}


def servo_figures(hw: HardwareConfig, joint_names: Sequence[str]
                  ) -> dict[str, dict[str, float]] | None:
    """The identified figures ``hardware.servo_figures_file`` gives (None: unset)."""
    if not hw.servo_figures_file:
        return None
    return load_servo_figures(Path(str(hw.servo_figures_file)), joint_names)


def load_servo_figures(path: Path, joint_names: Sequence[str]
                       ) -> dict[str, dict[str, float]]:
    """A servo-figures file (``hardware.servo_figures_file``, written by
    ``stages/calibrate.py photo=...``): ``joints: {<joint>: {backlash_deg: ..,
    deadband_deg: ..}}``, each figure a finite number in ``[0, 20]`` deg.

    Raises:
        TattotronixError: a missing or unreadable file, an unknown joint or figure, or a
            value out of range (every problem, in one message naming the file).
    """
    import yaml

    try:
        data = yaml.safe_load(Path(path).read_text(encoding="utf-8"))
    except (OSError, yaml.YAMLError) as exc:
        raise TattotronixError(f"hardware.servo_figures_file={path}: cannot read it "
                               f"({type(exc).__name__}): run stages/calibrate.py photo=...") \
            from None
    joints = data.get("joints") if isinstance(data, dict) else None
    if not isinstance(joints, dict):
        raise TattotronixError(f"hardware.servo_figures_file={path}: no 'joints' mapping")
    problems: list[str] = []
    out: dict[str, dict[str, float]] = {}
    for joint, figures in joints.items():
        if str(joint) not in joint_names:
            problems.append(f"joints.{joint}: not a joint of the arm ({', '.join(joint_names)})")
            continue
        if not isinstance(figures, dict):
            problems.append(f"joints.{joint}: a mapping of figures, not {figures!r}")
            continue
        for key, value in figures.items():
            hi = SERVO_FIGURES.get(str(key))
            if hi is None:
                continue  # the file's notes (the fit's factors, residuals)
            ok = isinstance(value, int | float) and not isinstance(value, bool) \
                and math.isfinite(value) and 0.0 <= value <= hi
            if not ok:
                problems.append(f"joints.{joint}.{key}: a number of degrees in [0, {hi:g}], "
                                f"not {value!r}")
                continue
            out.setdefault(str(joint), {})[str(key)] = float(value)
    if problems:
        raise TattotronixError(f"hardware.servo_figures_file={path}: " + "; ".join(problems))
    return out


#: the spread's setting (``ServoSpreadConfig.<key>_pct``) -> the servo's figures it moves
SPREAD_FIELDS: dict[str, tuple[str, ...]] = {
    "deadband": ("deadband_rad",), "stall": ("stall_nm",), "speed": ("speed_rad_s",),
    "band": ("band_rad",), "backlash": ("backlash_rad",),
    "nonlinearity": ("nonlinearity_rad",), "armature": ("armature_kgm2",),
    "latency": ("latency_s",),
}


def spread_servos(specs: Sequence[ServoSpec], spread: ServoSpreadConfig,
                  rng: np.random.Generator) -> tuple[ServoSpec, ...]:
    """One arm's servos as built, drawn from the catalogue's ``specs`` and ``spread``:
    each figure of each joint's servo times ``1 + p u``, ``p`` its spread (% / 100) and
    ``u`` uniform in [-1, 1], every figure and joint on its own. A figure that is zero
    (switched off, or none: a bus servo's bend) stays zero; a bus servo's dead band is
    its encoder step, exact. The draws come in a fixed order (joint, then
    :data:`SPREAD_FIELDS`), so a seed gives the same arms whatever the spreads."""
    out = []
    for s in specs:
        changes: dict[str, float] = {}
        for key, names in SPREAD_FIELDS.items():
            u = float(rng.uniform(-1.0, 1.0))
            p = float(getattr(spread, f"{key}_pct")) / 100.0
            for name in names:
                value = float(getattr(s, name))
                if value == 0.0 or (s.bus and key == "deadband"):
                    continue
                changes[name] = value * (1.0 + p * u)
        out.append(replace(s, **changes))  # type: ignore[arg-type]
    return tuple(out)


def measure_fit(spec: ServoSpec, servo: ServoChannel, points: int, order: int,
                protractor_deg: float) -> PulseFit:
    """The calibration procedure (``stages/servo_pulse.py ... record=``) on a simulated
    servo: ``points`` widths evenly across ``[min_us, max_us]``, each angle read to
    ``protractor_deg``, fitted by a polynomial of ``order``."""
    widths = np.linspace(servo.min_us, servo.max_us, int(points))
    deg = np.degrees(spec.true_angle(servo, widths))
    if protractor_deg > 0:
        deg = np.round(deg / protractor_deg) * protractor_deg
    return PulseFit(tuple(zip(widths.tolist(), deg.tolist(), strict=True)), int(order))


def with_measured_fits(calib: Calibration, specs: Sequence[ServoSpec],
                       servo: ServoPlantConfig) -> Calibration:
    """``calib`` with every PWM joint's servo A measured (:func:`measure_fit`) and fitted,
    as a user's calibration file holds it after ``servo_pulse.py ... record=``."""
    joints = []
    for j, spec in zip(calib.joints, specs, strict=True):
        if spec.bus:
            joints.append(j)
            continue
        fit = measure_fit(spec, j.a, servo.fit_points, servo.fit_order, servo.protractor_deg)
        joints.append(replace(j, a=replace(j.a, fit=fit)))
    return replace(calib, joints=tuple(joints))


def _direction(q: Array, eps: float) -> Array:
    """(F,) +1 / -1: the way ``q`` next moves by more than ``eps`` (looking ahead), held
    where it stays put; the first move's way before it."""
    d = np.zeros(len(q))
    way = 0.0
    anchor = float(q[-1]) if len(q) else 0.0
    # walk backwards: the way of the next move bigger than eps from this frame
    for k in range(len(q) - 1, -1, -1):
        if abs(anchor - q[k]) > eps:
            way = math.copysign(1.0, anchor - q[k])
            anchor = float(q[k])
        d[k] = way
    first = next((x for x in d if x != 0.0), 1.0)
    d[d == 0.0] = first
    return d


def servo_lead_s(specs: Sequence[ServoSpec], frame_hz: float) -> Array:
    """(n,) how far ahead each joint's commands are sent, s: the servo's latency, half a
    frame (a command held over its frame acts, on average, half a frame late) and the
    servo's own lag, the time constant of its drive against its back-EMF
    (``back_emf / kp = band / speed``: at a steady speed a proportional servo trails its
    command by that long). None for a servo without lag (``ServoSpec.lag``)."""
    return np.array([s.latency_s + 0.5 / float(frame_hz) + s.back_emf / s.kp if s.lag
                     else 0.0 for s in specs], dtype=np.float64)


def compensate(q: Array, specs: Sequence[ServoSpec], switches: CompensateConfig,
               torque_nm: Array | None = None) -> Array:
    """The servo program's corrections of the frame angles ``q`` (F, n), rad.

    * sag (with ``torque_nm``, (F, n) the torque each joint needs at each frame, N m):
      ``q + tau / kp`` (nothing on a servo without lag, ``ServoSpec.lag``). A servo's
      drive gives ``kp`` times its error, so holding ``tau`` it rests ``tau / kp`` short
      of its command; sent that much further, it rests on the goal (before the dead band,
      which the dead band's push below takes up);
    * backlash: ``q + d b/2``, ``d`` the way the joint moves next (:func:`_direction`,
      looking ahead past moves under a tenth of the play), so every joint reaches each
      stroke already pressed the way it will move, and the play is taken up where the
      plan reverses, before the link must follow;
    * dead band: ``+ d_k w/2`` where ``d_k`` is the way of this frame's move from where the
      servo rests: the servo stops half a band short of its command, so the command is
      pushed half a band past the goal; where the goal moved less than the servo's
      resolution, the command is held.
    """
    out = np.array(q, dtype=np.float64, copy=True)
    if switches.sag:
        if torque_nm is None or np.shape(torque_nm) != out.shape:
            raise TattotronixError("the sag correction needs the torque of every joint at "
                                   f"every frame, {out.shape}; got "
                                   f"{None if torque_nm is None else np.shape(torque_nm)}")
        gain = np.array([s.kp if s.lag else math.inf for s in specs])  # stiff: no sag
        out += np.asarray(torque_nm, dtype=np.float64) / gain
    if switches.backlash:
        for i, s in enumerate(specs):
            if s.backlash_rad > 0:
                out[:, i] += 0.5 * s.backlash_rad * _direction(q[:, i], 0.1 * s.backlash_rad)
    if switches.deadband:
        for i, s in enumerate(specs):
            w = s.deadband_rad
            if w <= 0:
                continue
            goal = out[:, i]
            rest = float(goal[0])
            cmd = float(goal[0])
            col = np.empty(len(goal))
            for k, g in enumerate(goal.tolist()):
                if abs(g - rest) > 0.05 * w:  # a move the servo should make
                    cmd = g + math.copysign(0.5 * w, g - rest)
                    rest = g
                col[k] = cmd
            out[:, i] = col
    return out
