"""The actuator study: what hobby servos allow at the needle (docs/actuators.md; the
original's: docs/original.md, "6.6 The actuator study").

A hobby servo takes a position pulse every frame and closes its own loop. Two floors lie
under its error that no controller above it can remove:

* the **dead band** (declared in the servo catalogue, ``robot.servos.<name>.deadband_us``):
  the servo rests anywhere inside it, centred on the command (half the band either way);
* the **command step**: the PCA9685 divides a servo frame into 4096 counts
  (``1e6 / frame_hz / 4096`` us, 4.8828125 us at 50 Hz); the Arduino ``Servo`` library
  steps the pulse by 1 us; a bus servo with a 12-bit encoder holds within one count,
  360 / 4096 deg (assumed).

With the declared scale ``us_per_deg`` (2000 us over 180 deg), a pulse-driven joint rests
within ``e_i = (step_us + deadband_us) / 2 / us_per_deg`` degrees either way; a bus joint
within ``bus_step_deg``. Which servo drives a joint comes from ``robot.servo_mounts``
(joint_2's mirrored pair is modelled as one servo of its type).

At every ``every``-th marking point of a drawing's trajectory the tip sensitivity is the
position rows of the tip's geometric Jacobian in mm per degree. With the panel horizontal
in the arm frame (x, y in the panel, z the depth):

* the **worst lateral error** at a pose is the largest ``||J_xy dq||`` over the box
  ``|dq_i| <= e_i``: a convex function, so its maximum is at one of the ``2^n`` corners
  (:func:`worst_lateral_mm`, vectorised over poses and corners);
* the **typical lateral error** is ``sqrt(sum_i lever_xy,i^2 e_i^2 / 3)`` (independent
  errors, uniform in their band), its median over the poses being the published figure;
* the **worst depth error** at a pose is ``sum_i |J_z,i| e_i``.

"Play": the worst lateral error with ``play_deg`` at every joint; it is linear in the
common band, so it gives the one band every joint must hold to keep the tip inside the
ink line (``required_deg``) and what ``backlash_deg`` of backlash costs.

Units: SI inside the kinematics (m, rad); the study's figures are in degrees and mm, as
the names say (``_deg``, ``_mm``, ``_mm_per_deg``, ``_us``).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from tattotronix.config.schema import ActuatorOption, ActuatorStudyConfig, Config, RobotConfig
from tattotronix.errors import TattotronixError
from tattotronix.hardware.pca9685 import COUNTS
from tattotronix.io.artifacts import TrajectoryRecord
from tattotronix.io.jsontypes import JsonDict
from tattotronix.kinematics import Chain
from tattotronix.plotting import pyplot
from tattotronix.trajectory import MARK

__all__ = [
    "COMMANDS",
    "SERIES_EVERY",
    "ActuatorStudy",
    "Declared",
    "OptionResult",
    "Poses",
    "actuator_study",
    "box_corners",
    "declared",
    "depth_worst_mm",
    "figure",
    "lateral_rms_mm",
    "metrics",
    "pca9685_step_us",
    "rest_error_deg",
    "series_arrays",
    "study_from_config",
    "study_poses",
    "tip_sensitivity",
    "worst_lateral_mm",
]

Array = NDArray[np.float64]

#: The pulse commands an option may name: the PCA9685 board, the Arduino Servo library.
COMMANDS = ("pca9685", "arduino")
#: Every how many poses the time series keeps (the original: every 4th).
SERIES_EVERY = 4
MM_PER_DEG_PER_M_PER_RAD = math.pi / 180.0 * 1000.0  # (m/rad) -> (mm/deg)


def pca9685_step_us(frame_hz: float, counts: int = COUNTS) -> float:
    """The PCA9685's pulse step: one count of a servo frame.

    Args:
        frame_hz: the servo frame rate, Hz (``hardware.servos.frame_hz``, 50).
        counts: counts per frame (the board's 4096).

    Returns:
        ``1e6 / frame_hz / counts``, us (4.8828125 at 50 Hz).

    Raises:
        TattotronixError: a frame rate that is not a positive number.
    """
    if not (isinstance(frame_hz, int | float) and math.isfinite(frame_hz) and frame_hz > 0):
        raise TattotronixError(f"the servo frame rate must be a positive number of Hz, got "
                               f"{frame_hz!r}: set hardware.servos.frame_hz (50)")
    return 1e6 / float(frame_hz) / counts


# --- what is declared --------------------------------------------------------------------

@dataclass(frozen=True)
class Declared:
    """The declared numbers the rest errors come from.

    Attributes:
        joints: the joints, base outward.
        us_per_deg: pulse-to-angle scale, us/deg (11.111: 2000 us over 180 deg).
        pca9685_step_us: the PCA9685 pulse step, us.
        arduino_step_us: the Arduino ``Servo`` library's pulse step, us.
        bus_step_deg: a bus servo's step (one encoder count), deg.
        servo_by_joint: joint -> the catalogue servo that drives it.
        deadband_us: catalogue servo -> its dead band, us (the servos of
            ``servo_by_joint`` only).
        frame_hz: the servo frame rate the PCA9685 step comes from, Hz.
    """

    joints: tuple[str, ...]
    us_per_deg: float
    pca9685_step_us: float
    arduino_step_us: float
    bus_step_deg: float
    servo_by_joint: dict[str, str]
    deadband_us: dict[str, float]
    frame_hz: float

    def step_us(self, command: str) -> float:
        """The pulse step of a command (``pca9685`` or ``arduino``), us."""
        return self.pca9685_step_us if command == "pca9685" else self.arduino_step_us

    def summary(self) -> JsonDict:
        """The ``declared`` block of the metrics file."""
        return {
            "us_per_deg": float(self.us_per_deg),
            "pca9685_step_us": float(self.pca9685_step_us),
            "arduino_step_us": float(self.arduino_step_us),
            "bus_step_deg": float(self.bus_step_deg),
            "servo_by_joint": dict(self.servo_by_joint),
            "deadband_us": {k: float(v) for k, v in self.deadband_us.items()},
            "frame_hz": float(self.frame_hz),
        }


def declared(study: ActuatorStudyConfig, robot: RobotConfig, frame_hz: float,
             joint_names: Sequence[str]) -> Declared:
    """Collect the declared numbers from the config.

    Args:
        study: ``cfg.study.actuator`` (:class:`~tattotronix.config.schema.ActuatorStudyConfig`).
        robot: ``cfg.robot`` (its ``servos`` catalogue and ``servo_mounts``).
        frame_hz: the servo frame rate, Hz (``hardware.servos.frame_hz``).
        joint_names: the arm's joints, base outward.

    Returns:
        The declared scale, steps, servo per joint and dead bands.

    Raises:
        TattotronixError: a joint no servo mount drives, or two mounts of different servos
            on one joint, a mount naming a servo not in the catalogue, or a scale or step
            that is not a positive number.
    """
    mounts: dict[str, str] = {}
    for m in robot.servo_mounts:
        at, servo = str(m.at), str(m.servo)
        if at not in joint_names:
            continue  # the tool servo ("tool") drives no joint of the chain
        if at in mounts and mounts[at] != servo:
            raise TattotronixError(
                f"robot.servo_mounts: {at} is driven by both {mounts[at]} and {servo}; the "
                "actuator study models a joint's servos (a mirrored pair) as one servo type")
        mounts[at] = servo
    missing = [j for j in joint_names if j not in mounts]
    if missing:
        raise TattotronixError(f"robot.servo_mounts: no servo drives {missing}; add a mount "
                               f"with 'at' naming each joint of {list(joint_names)}")
    catalogue = {str(k): v for k, v in robot.servos.items()}
    unknown = sorted({s for s in mounts.values() if s not in catalogue})
    if unknown:
        raise TattotronixError(f"robot.servo_mounts name servos {unknown} that are not in the "
                               f"catalogue robot.servos ({sorted(catalogue)})")
    deadband = {s: float(catalogue[s].deadband_us) for s in dict.fromkeys(mounts.values())}
    for key, value in (("us_per_deg", study.us_per_deg),
                       ("arduino_step_us", study.arduino_step_us),
                       ("bus_step_deg", study.bus_step_deg)):
        if not (math.isfinite(float(value)) and float(value) > 0):
            raise TattotronixError(f"study.actuator.{key} must be a positive number, got "
                                   f"{value!r}")
    bad_band = {s: b for s, b in deadband.items() if not (math.isfinite(b) and b >= 0)}
    if bad_band:
        raise TattotronixError(f"robot.servos dead bands {bad_band} must be >= 0 us")
    return Declared(
        joints=tuple(joint_names),
        us_per_deg=float(study.us_per_deg),
        pca9685_step_us=pca9685_step_us(frame_hz),
        arduino_step_us=float(study.arduino_step_us),
        bus_step_deg=float(study.bus_step_deg),
        servo_by_joint={j: mounts[j] for j in joint_names},
        deadband_us=deadband,
        frame_hz=float(frame_hz),
    )


def _check_option(option: ActuatorOption, joints: Sequence[str]) -> None:
    name = getattr(option, "name", "?")
    if option.command not in COMMANDS:
        raise TattotronixError(
            f"actuator option {name!r}: command {option.command!r} is not one of "
            f"{list(COMMANDS)} (study.actuator.options)")
    unknown = [str(j) for j in option.bus_joints if j not in joints]
    if unknown:
        raise TattotronixError(
            f"actuator option {name!r}: bus_joints {unknown} are not joints of the arm; "
            f"allowed: {list(joints)} (study.actuator.options)")


def rest_error_deg(decl: Declared, option: ActuatorOption) -> Array:
    """Each joint's rest error under an option, deg (either way of the command).

    ``(step_us + deadband_us) / 2 / us_per_deg`` for a pulse-driven joint (step of the
    option's command, dead band of the joint's servo); ``bus_step_deg`` for a bus joint.

    Args:
        decl: the declared numbers.
        option: the option (``name``, ``command``, ``bus_joints``).

    Returns:
        (n,) the rest error per joint, deg, in ``decl.joints`` order.

    Raises:
        TattotronixError: an unknown command or an unknown joint in ``bus_joints``.
    """
    _check_option(option, decl.joints)
    step = decl.step_us(option.command)
    bus = {str(j) for j in option.bus_joints}
    return np.array([
        decl.bus_step_deg if j in bus
        else (step + decl.deadband_us[decl.servo_by_joint[j]]) / 2.0 / decl.us_per_deg
        for j in decl.joints
    ], dtype=float)


# --- poses and the tip sensitivity -------------------------------------------------------

@dataclass(frozen=True)
class Poses:
    """The poses of the study: every ``every``-th marking point of a trajectory.

    Attributes:
        q: (N, n) joint angles, rad.
        t_s: (N,) trajectory time, s.
        index: (N,) the points' indices in the trajectory.
        every: the stride over the marking points.
    """

    q: Array
    t_s: Array
    index: NDArray[np.int64]
    every: int


def study_poses(traj: TrajectoryRecord, every: int) -> Poses:
    """Every ``every``-th marking point (``kind == MARK``) of a trajectory, from the first.

    Args:
        traj: the stored trajectory (:func:`tattotronix.trajectory.load_trajectory`).
        every: the stride (``study.actuator.every``, 5).

    Returns:
        The poses.

    Raises:
        TattotronixError: ``every`` below 1, or a trajectory with no marking point.
    """
    if int(every) != every or every < 1:
        raise TattotronixError(f"study.actuator.every must be a whole number >= 1, got "
                               f"{every!r}")
    marking = np.flatnonzero(np.asarray(traj.kind) == MARK)
    if len(marking) == 0:
        raise TattotronixError(
            f"the trajectory has no marking points (kind == {MARK}) among its "
            f"{len(traj.kind)} points: nothing to study; re-run the 'toolpath', 'ik' and "
            "'trajectory' stages on an artwork with ink")
    idx = marking[::int(every)].astype(np.int64)
    return Poses(q=np.asarray(traj.q, dtype=float)[idx],
                 t_s=np.asarray(traj.t, dtype=float)[idx], index=idx, every=int(every))


def tip_sensitivity(chain: Chain, q: ArrayLike) -> Array:
    """The tip's position sensitivity to each joint, mm per degree.

    Args:
        chain: the kinematic model.
        q: (N, n) joint angles, rad.

    Returns:
        (N, 3, n): rows x, y, z of the arm frame; the position rows of the world-aligned
        geometric Jacobian (:meth:`Chain.jacobian`, m/rad) times ``pi / 180 * 1000``.
    """
    jac = chain.jacobian(np.atleast_2d(np.asarray(q, dtype=float)))
    return np.asarray(jac[:, :3, :] * MM_PER_DEG_PER_M_PER_RAD, dtype=float)


def box_corners(e: ArrayLike) -> Array:
    """The ``2^n`` corners of the box ``|dq_i| <= e_i``.

    Args:
        e: (n,) half-widths.

    Returns:
        (2^n, n) every sign combination of ``e`` (the first all minus, the last all plus).
    """
    ee = np.asarray(e, dtype=float).ravel()
    n = len(ee)
    bits = (np.arange(2 ** n)[:, None] >> np.arange(n)[::-1]) & 1
    return np.asarray((2.0 * bits - 1.0) * ee, dtype=float)


def worst_lateral_mm(j_xy: ArrayLike, e_deg: ArrayLike) -> Array:
    """The worst in-panel tip error at each pose with each joint anywhere in its band.

    ``max ||J_xy dq||`` over the box ``|dq_i| <= e_i``. The norm of a linear map is convex,
    so the maximum over the box is at a corner: the ``2^n`` corners are evaluated for all
    poses at once.

    Args:
        j_xy: (N, 2, n) the in-panel rows of the tip sensitivity, mm/deg.
        e_deg: (n,) the band half-widths, deg.

    Returns:
        (N,) the worst lateral error per pose, mm.
    """
    j = np.asarray(j_xy, dtype=float)
    corners = box_corners(e_deg)  # (C, n)
    d = np.einsum("kri,ci->kcr", j, corners)  # (N, C, 2)
    return np.asarray(np.sqrt((d * d).sum(axis=2)).max(axis=1), dtype=float)


def lateral_rms_mm(lever_xy: ArrayLike, e_deg: ArrayLike) -> Array:
    """The typical in-panel tip error: independent joint errors, uniform in their bands.

    Args:
        lever_xy: (N, n) ``||(J_x,i, J_y,i)||`` per joint, mm/deg.
        e_deg: (n,) the band half-widths, deg.

    Returns:
        (N,) ``sqrt(sum_i lever_xy,i^2 e_i^2 / 3)`` per pose, mm.
    """
    lev = np.asarray(lever_xy, dtype=float)
    e = np.asarray(e_deg, dtype=float)
    return np.asarray(np.sqrt((lev ** 2 * e ** 2).sum(axis=1) / 3.0), dtype=float)


def depth_worst_mm(j_z: ArrayLike, e_deg: ArrayLike) -> Array:
    """The worst depth (z) tip error at each pose: ``sum_i |J_z,i| e_i``, mm.

    Args:
        j_z: (N, n) the z row of the tip sensitivity, mm/deg.
        e_deg: (n,) the band half-widths, deg.

    Returns:
        (N,) mm.
    """
    return np.asarray(np.abs(np.asarray(j_z, dtype=float)) @ np.asarray(e_deg, dtype=float),
                      dtype=float)


# --- the study ---------------------------------------------------------------------------

@dataclass(frozen=True)
class OptionResult:
    """One way of driving the servos, along the drawing.

    Attributes:
        name: the option's name.
        command: ``pca9685`` or ``arduino``.
        bus_joints: the joints on bus servos.
        rest_deg: (n,) the rest error per joint, deg.
        lateral_worst_mm: (N,) the worst lateral error per pose, mm.
        lateral_rms_mm: (N,) the typical lateral error per pose, mm.
        depth_worst_mm: (N,) the worst depth error per pose, mm.
    """

    name: str
    command: str
    bus_joints: tuple[str, ...]
    rest_deg: Array
    lateral_worst_mm: Array
    lateral_rms_mm: Array
    depth_worst_mm: Array

    @property
    def lateral_worst(self) -> float:
        """The worst lateral error over the poses, mm."""
        return float(self.lateral_worst_mm.max())

    @property
    def lateral_worst_median(self) -> float:
        """The median over the poses of the per-pose worst lateral error, mm."""
        return float(np.median(self.lateral_worst_mm))

    @property
    def lateral_rms_median(self) -> float:
        """The typical lateral error: the median over the poses, mm."""
        return float(np.median(self.lateral_rms_mm))

    @property
    def depth_worst(self) -> float:
        """The worst depth error over the poses, mm."""
        return float(self.depth_worst_mm.max())


@dataclass(frozen=True)
class ActuatorStudy:
    """The study of one drawing.

    Attributes:
        declared: the declared numbers.
        poses: the poses.
        lever_xy: (N, n) lateral lever per pose and joint, ``||(J_x,i, J_y,i)||``, mm/deg.
        lever_z: (N, n) depth lever per pose and joint, ``|J_z,i|``, mm/deg.
        play_lateral_mm: (N,) worst lateral error with ``play_deg`` at every joint, mm.
        options: the options' results, in the config's order.
        line_mm: the ink line width, mm (``toolpath.needle_width_mm``).
        plunge_mm: the marking depth, mm (``toolpath.plunge_mm``).
        play_deg: the play at every joint of the "play" figure, deg.
        backlash_deg: the backlash whose cost is reported, deg.
        series_every: the time series keeps every this-many poses.
    """

    declared: Declared
    poses: Poses
    lever_xy: Array
    lever_z: Array
    play_lateral_mm: Array
    options: tuple[OptionResult, ...]
    line_mm: float
    plunge_mm: float
    play_deg: float
    backlash_deg: float
    series_every: int = SERIES_EVERY

    @property
    def joints(self) -> tuple[str, ...]:
        """The joints, base outward."""
        return self.declared.joints

    @property
    def lever_lateral_worst(self) -> Array:
        """(n,) each joint's largest lateral lever over the poses, mm/deg."""
        return np.asarray(self.lever_xy.max(axis=0), dtype=float)

    @property
    def lever_depth_worst(self) -> Array:
        """(n,) each joint's largest depth lever over the poses, mm/deg."""
        return np.asarray(self.lever_z.max(axis=0), dtype=float)

    @property
    def play_lateral_mm_per_deg(self) -> float:
        """The worst lateral error over the poses per degree of play at every joint, mm/deg.

        The corner maximum is linear in a common band, so this is the worst lateral error
        with ``play_deg`` at every joint divided by ``play_deg``.
        """
        return float(self.play_lateral_mm.max()) / self.play_deg

    @property
    def required_deg(self) -> float:
        """The band every joint must hold, worst way round, to stay inside the line, deg."""
        return self.line_mm / self.play_lateral_mm_per_deg

    @property
    def backlash_lateral_mm(self) -> float:
        """The worst lateral error ``backlash_deg`` of backlash at every joint costs, mm."""
        return self.play_lateral_mm_per_deg * self.backlash_deg

    @property
    def series_t_s(self) -> Array:
        """The time series' times (every ``series_every``-th pose), s."""
        return self.poses.t_s[::self.series_every]

    def series_lateral_worst_mm(self, option: OptionResult) -> Array:
        """An option's worst lateral error at the series' poses, mm."""
        return option.lateral_worst_mm[::self.series_every]

    def times_line(self, option: OptionResult) -> float:
        """An option's worst lateral error in line widths."""
        return option.lateral_worst / self.line_mm


def actuator_study(
    chain: Chain,
    traj: TrajectoryRecord,
    decl: Declared,
    options: Iterable[ActuatorOption],
    *,
    every: int,
    line_mm: float,
    plunge_mm: float,
    play_deg: float,
    backlash_deg: float,
    series_every: int = SERIES_EVERY,
) -> ActuatorStudy:
    """Run the actuator study on one drawing's trajectory.

    Args:
        chain: the kinematic model (its joints must be ``decl.joints``).
        traj: the drawing's stored trajectory.
        decl: the declared numbers (:func:`declared`).
        options: the ways of driving the servos (``study.actuator.options``).
        every: poses are every ``every``-th marking point.
        line_mm: the ink line width, mm.
        plunge_mm: the marking depth, mm.
        play_deg: the play at every joint of the "play" figure, deg.
        backlash_deg: the backlash whose cost is reported, deg.
        series_every: the time series keeps every this-many poses.

    Returns:
        The study.

    Raises:
        TattotronixError: an option with an unknown command or joint, no options, two
            options of one name, a trajectory of other joints or with no marking point, or
            non-positive ``line_mm``, ``play_deg`` or ``series_every``.
    """
    opts = list(options)
    if not opts:
        raise TattotronixError("study.actuator.options is empty: name at least one option")
    names = [str(o.name) for o in opts]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise TattotronixError(f"study.actuator.options: the names {dup} are used twice")
    for o in opts:
        _check_option(o, decl.joints)
    if tuple(chain.joint_names) != decl.joints or tuple(traj.joints) != decl.joints:
        raise TattotronixError(
            f"the trajectory's joints {list(traj.joints)} are not the arm's "
            f"{list(decl.joints)}: re-run the 'ik' and 'trajectory' stages")
    for key, value in (("toolpath.needle_width_mm", line_mm),
                       ("study.actuator.play_deg", play_deg)):
        if not (math.isfinite(value) and value > 0):
            raise TattotronixError(f"{key} must be a positive number, got {value!r}")
    if int(series_every) != series_every or series_every < 1:
        raise TattotronixError(f"series_every must be a whole number >= 1, got "
                               f"{series_every!r}")
    poses = study_poses(traj, every)
    sens = tip_sensitivity(chain, poses.q)
    j_xy, j_z = sens[:, :2, :], sens[:, 2, :]
    lever_xy = np.asarray(np.linalg.norm(j_xy, axis=1), dtype=float)
    lever_z = np.asarray(np.abs(j_z), dtype=float)
    results = []
    for o in opts:
        e = rest_error_deg(decl, o)
        results.append(OptionResult(
            name=str(o.name), command=str(o.command),
            bus_joints=tuple(str(j) for j in o.bus_joints), rest_deg=e,
            lateral_worst_mm=worst_lateral_mm(j_xy, e),
            lateral_rms_mm=lateral_rms_mm(lever_xy, e),
            depth_worst_mm=depth_worst_mm(j_z, e)))
    play = worst_lateral_mm(j_xy, np.full(len(decl.joints), float(play_deg)))
    return ActuatorStudy(
        declared=decl, poses=poses, lever_xy=lever_xy, lever_z=lever_z,
        play_lateral_mm=play, options=tuple(results), line_mm=float(line_mm),
        plunge_mm=float(plunge_mm), play_deg=float(play_deg),
        backlash_deg=float(backlash_deg), series_every=int(series_every))


def study_from_config(cfg: Config, chain: Chain, traj: TrajectoryRecord,
                      frame_hz: float | None = None) -> ActuatorStudy:
    """The study with every setting from the settings.

    Args:
        cfg: the settings (``study.actuator``, ``robot``, ``hardware``, ``draw``,
            ``toolpath``).
        chain: the kinematic model.
        traj: the drawing's stored trajectory.
        frame_hz: the servo frame rate, Hz; default ``hardware.servos.frame_hz``.

    Returns:
        The study.
    """
    sc = cfg.study.actuator
    hz = float(cfg.hardware.servos["frame_hz"]) if frame_hz is None else float(frame_hz)
    decl = declared(sc, cfg.robot, hz, chain.joint_names)
    return actuator_study(
        chain, traj, decl, sc.options, every=int(sc.every),
        line_mm=float(cfg.toolpath.needle_width_mm), plunge_mm=float(cfg.toolpath.plunge_mm),
        play_deg=float(sc.play_deg), backlash_deg=float(sc.backlash_deg))


# --- outputs -----------------------------------------------------------------------------

def _floats(a: ArrayLike) -> list[float]:
    return [float(v) for v in np.ravel(np.asarray(a, dtype=float))]


def metrics(result: ActuatorStudy, series: bool = False) -> JsonDict:
    """The metrics file's content (the original's keys; plain floats, lists and dicts).

    Args:
        result: the study.
        series: put the time series in (``series_t_s`` and each option's
            ``series_lateral_worst_mm``, as the original); off, they are left to
            :func:`series_arrays` (an npz beside the metrics) and only their length is
            given (``series_points``).

    Returns:
        ``declared``, ``line_mm``, ``plunge_depth_mm``, ``poses``, ``joints``,
        ``lever_lateral_mm_per_deg``, ``lever_depth_mm_per_deg`` (worst pose, per joint),
        ``play_lateral_mm_per_deg``, ``required_deg``, ``options`` {name: ``rest_deg``,
        ``lateral_worst_mm``, ``lateral_worst_median_mm``, ``lateral_rms_median_mm``,
        ``depth_worst_mm``, ``times_line``}, and ``every``, ``play_deg``, ``backlash_deg``,
        ``backlash_lateral_mm``, ``series_every``, ``series_points``.

    Raises:
        TattotronixError: a value is not finite (it would not be valid JSON).
    """
    options: dict[str, Any] = {}
    for o in result.options:
        entry: dict[str, Any] = {
            "command": o.command,
            "bus_joints": list(o.bus_joints),
            "rest_deg": _floats(o.rest_deg),
            "lateral_worst_mm": o.lateral_worst,
            "lateral_worst_median_mm": o.lateral_worst_median,
            "lateral_rms_median_mm": o.lateral_rms_median,
            "depth_worst_mm": o.depth_worst,
            "times_line": result.times_line(o),
        }
        if series:
            entry["series_lateral_worst_mm"] = _floats(result.series_lateral_worst_mm(o))
        options[o.name] = entry
    out: dict[str, Any] = {
        "declared": result.declared.summary(),
        "line_mm": result.line_mm,
        "plunge_depth_mm": result.plunge_mm,
        "poses": int(len(result.poses.t_s)),
        "every": result.poses.every,
        "joints": list(result.joints),
        "lever_lateral_mm_per_deg": _floats(result.lever_lateral_worst),
        "lever_depth_mm_per_deg": _floats(result.lever_depth_worst),
        "play_deg": result.play_deg,
        "play_lateral_mm_per_deg": result.play_lateral_mm_per_deg,
        "required_deg": result.required_deg,
        "backlash_deg": result.backlash_deg,
        "backlash_lateral_mm": result.backlash_lateral_mm,
        "series_every": result.series_every,
        "series_points": int(len(result.series_t_s)),
        "options": options,
    }
    if series:
        out["series_t_s"] = _floats(result.series_t_s)
    _check_finite(out, "metrics")
    return out


def _check_finite(obj: Any, where: str) -> None:
    if isinstance(obj, float):
        if not math.isfinite(obj):
            raise TattotronixError(f"actuator study: {where} is {obj} (not finite)")
    elif isinstance(obj, Mapping):
        for k, v in obj.items():
            _check_finite(v, f"{where}.{k}")
    elif isinstance(obj, list):
        for i, v in enumerate(obj):
            _check_finite(v, f"{where}[{i}]")


def series_arrays(result: ActuatorStudy) -> dict[str, np.ndarray]:
    """The time series for an npz (``allow_pickle=False`` safe).

    Returns:
        ``t_s`` (M,) s; ``options`` (K,) the option names; ``lateral_worst_mm`` (K, M), each
        option's worst lateral error at every ``series_every``-th pose, mm; ``rest_deg``
        (K, n); ``joints`` (n,).
    """
    return {
        "t_s": np.asarray(result.series_t_s, dtype=float),
        "options": np.array([o.name for o in result.options]),
        "lateral_worst_mm": np.array([result.series_lateral_worst_mm(o)
                                      for o in result.options], dtype=float),
        "rest_deg": np.array([o.rest_deg for o in result.options], dtype=float),
        "joints": np.array(result.joints),
    }


# --- the figure --------------------------------------------------------------------------

_COLOURS = ("#c92a2a", "#f08c00", "#1971c2", "#2b8a3e", "#7048e8", "#495057")


def figure(result: ActuatorStudy, path: Path, title: str = "") -> None:
    """The study in one PNG.

    Left: each joint's worst-pose lever (lateral and depth, mm/deg). Middle: each option's
    worst lateral error along the drawing against the ink line. Right: each joint's rest
    band under each option against the band every joint must hold to stay in the line.

    Args:
        result: the study.
        path: the PNG to write.
        title: prefixed to the figure's title (the drawing's name).
    """
    plt = pyplot()

    joints = result.joints
    n = len(joints)
    x = np.arange(n)
    fig, axes = plt.subplots(1, 3, figsize=(18, 6.2), dpi=110,
                             gridspec_kw={"width_ratios": [1.0, 1.6, 1.25]})

    ax = axes[0]
    lat, dep = result.lever_lateral_worst, result.lever_depth_worst
    b1 = ax.bar(x - 0.2, lat, 0.4, color="#1971c2", label="lateral ||(J_x, J_y)||")
    b2 = ax.bar(x + 0.2, dep, 0.4, color="#adb5bd", label="depth |J_z|")
    for bars in (b1, b2):
        ax.bar_label(bars, fmt="%.2f", fontsize=7, padding=1)
    ax.set_xticks(x, [f"{j}\n{result.declared.servo_by_joint[j]}" for j in joints], fontsize=8)
    ax.set_ylabel("tip movement per degree at the joint (mm/deg)")
    ax.set_title(f"lever of each joint at its worst pose\n(max over {len(result.poses.t_s)} "
                 f"poses: every {result.poses.every}th marking point)", fontsize=9)
    ax.legend(fontsize=8, loc="upper right")
    ax.grid(axis="y", alpha=0.3)
    ax.set_ylim(0, max(float(lat.max()), float(dep.max())) * 1.18)

    ax = axes[1]
    t = result.series_t_s
    for k, o in enumerate(result.options):
        c = _COLOURS[k % len(_COLOURS)]
        ax.plot(t, result.series_lateral_worst_mm(o), "-", color=c, lw=0.8, alpha=0.9,
                label=f"{o.name}: worst {o.lateral_worst:.2f} mm = "
                      f"{result.times_line(o):.1f} × line")
    ax.axhline(result.line_mm, color="black", lw=1.6, ls="--",
               label=f"ink line width {result.line_mm:g} mm")
    top = max(max(o.lateral_worst for o in result.options), result.line_mm)
    ax.set_ylim(0, top * 1.7)
    ax.set_xlabel("time along the drawing (s)")
    ax.set_ylabel("worst in-panel tip error at the pose (mm)")
    ax.set_title("worst lateral error along the drawing, each joint anywhere in its rest "
                 f"band\n(every {result.series_every}th pose; max over the $2^{{{n}}}$ corners of "
                 "the joint box)", fontsize=9)
    ax.legend(fontsize=7.5, loc="upper left", ncol=1, framealpha=0.95)
    ax.grid(alpha=0.3)

    ax = axes[2]
    k_opt = len(result.options)
    width = 0.8 / max(k_opt, 1)
    for k, o in enumerate(result.options):
        ax.bar(x - 0.4 + width * (k + 0.5), o.rest_deg, width,
               color=_COLOURS[k % len(_COLOURS)], label=o.name)
    req = result.required_deg
    ax.axhline(req, color="black", lw=1.6, ls="--",
               label=f"every joint must hold ±{req:.4f}° to stay in the "
                     f"{result.line_mm:g} mm line\n({result.play_lateral_mm_per_deg:.2f} mm "
                     "per degree of play at every joint, worst way round)")
    ax.set_yscale("log")
    ax.set_ylim(req / 2.0, max(float(o.rest_deg.max()) for o in result.options) * 6.0)
    ax.set_xticks(x, list(joints), fontsize=8)
    ax.set_ylabel("rest band, either way (deg, log)")
    ax.set_title("rest band of each joint per option\n(step + dead band) / 2 / "
                 f"{result.declared.us_per_deg:g} µs/°; bus servos "
                 f"{result.declared.bus_step_deg:.4f}°", fontsize=9)
    ax.legend(fontsize=7.5, loc="upper left", framealpha=0.95)
    ax.grid(axis="y", alpha=0.3, which="both")

    worst = result.options[0]
    depth = f"worst depth {worst.depth_worst:.2f} mm vs the {result.plunge_mm:g} mm plunge"
    fig.suptitle(f"{title + ': ' if title else ''}what hobby servos allow at the needle "
                 f"({worst.name}: {depth}; {result.backlash_deg:g} deg of backlash costs up "
                 f"to {result.backlash_lateral_mm:.2f} mm)", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, format="png")
    plt.close(fig)
