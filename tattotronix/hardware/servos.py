"""Servo calibration: joint angle to pulse width to PCA9685 count (docs/original.md, "6.3
Pulse mapping").

Each servo maps a joint angle linearly to a pulse width and clamps it to its safe travel::

    pulse_us(angle) = clamp(zero_us + us_per_rad * angle, min_us, max_us)
    angle(pulse_us) = (pulse_us - zero_us) / us_per_rad

The shoulder (``joint_2``) has a second servo mounted facing the first; it turns the other
way, so its ``us_per_rad_b`` has the opposite sign, and it shares the first one's
``min_us`` / ``max_us``. The tool servo (a gripper leftover) is listed with its channel
only so the wiring is documented; it is never commanded, because the pen must not turn.

A calibration file (``servo_calibration.yaml``)::

    device: /dev/i2c-1
    address: 0x40
    frame_hz: 50.0
    oscillator_hz: 25.0e6        # measure per board: they range 24...27 MHz
    joints:
      joint_1: {channel: 0, zero_us: 1500, us_per_rad: 636.62, min_us: 500, max_us: 2500}
      joint_2: {channel: 1, zero_us: 1500, us_per_rad: 636.62, min_us: 500, max_us: 2500,
                channel_b: 2, zero_us_b: 1500, us_per_rad_b: -636.62}
      ...
    tool: {channel: 6}

A joint may also hold the pairs its servo was **measured** at (``stages/servo_pulse.py
joint=NAME record=FILE``): ``points: [[width_us, angle_deg], ...]``. Then servo A's
pulse-to-angle map is the least-squares polynomial of order ``fit_order`` (default 5,
lowered to the points' count less one) through them, and ``deploy`` inverts it
(:class:`PulseFit`); the straight line (``zero_us``, ``us_per_rad``) still names the joint
angle a count stands for in reports, and the twin servo B stays linear.

:meth:`Calibration.from_mapping` checks every key and value and reports **all** problems
in one :class:`CalibrationError`, each naming the joint and the key. The limits must lie
within the 400...2600 us a hobby servo accepts (``HOBBY_MIN_US``, ``HOBBY_MAX_US``; the
range ``stages/servo_pulse.py`` holds).

The declared values (:func:`default_calibration`) are catalogue figures, **not measured**:
calibrate each servo (README, "Calibrating the servos") before trusting the pulse widths.

Units: angles in rad, pulse widths in microseconds (``_us``), frequencies in Hz.
"""

from __future__ import annotations

import difflib
import math
import numbers
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from tattotronix.hardware.pca9685 import CHANNELS, COUNTS, HardwareError, round_half_away
from tattotronix.io.jsontypes import JsonDict

__all__ = [
    "Calibration",
    "CalibrationError",
    "DEFAULT_CALIBRATION",
    "DEFAULT_JOINT_NAMES",
    "HOBBY_MAX_US",
    "HOBBY_MIN_US",
    "JointServo",
    "PulseFit",
    "ServoChannel",
    "default_calibration",
    "default_calibration_mapping",
    "load_calibration",
]

DEFAULT_JOINT_NAMES: tuple[str, ...] = ("joint_1", "joint_2", "joint_3", "joint_4", "joint_5")

# Declared (catalogue) servo: 500...2500 us over 180 deg = 2000 / pi us/rad.
DECLARED_ZERO_US = 1500.0
DECLARED_US_PER_RAD = 636.62
DECLARED_MIN_US = 500.0
DECLARED_MAX_US = 2500.0
# What a hobby servo accepts at all: stages/servo_pulse.py refuses widths outside these
# (tattotronix/hardware/pulse.py), and a calibration may not reach beyond them either.
HOBBY_MIN_US = 400.0
HOBBY_MAX_US = 2600.0

JOINT_KEYS_A = ("channel", "zero_us", "us_per_rad", "min_us", "max_us")
JOINT_KEYS_B = ("channel_b", "zero_us_b", "us_per_rad_b")
JOINT_KEYS_FIT = ("points", "fit_order")
#: the pulse fit's order: on the catalogue's bend (2 deg, a sine over the travel), 9 widths
#: read to 0.5 deg, order 3 misses the servo's angle by up to 0.31 deg, order 5 by 0.075,
#: order 7 by 0.215 (it follows the readings' rounding); docs/servos.md
DEFAULT_FIT_ORDER = 5
TOP_KEYS = ("device", "address", "frame_hz", "oscillator_hz", "joints", "tool")
TOOL_KEYS = ("channel",)
MAX_OSCILLATOR_HZ = 50e6  # datasheet: EXTCLK up to 50 MHz
_TOL_US = 1e-9  # float slack when comparing a count's width with a pulse limit


class CalibrationError(HardwareError, ValueError):
    """The servo calibration is wrong; the message lists every problem with joint and key."""

    def __init__(self, problems: Sequence[str], source: str = "servo calibration"):
        self.problems = list(problems)
        n = len(self.problems)
        head = f"{source}: {n} problem{'s' if n != 1 else ''}"
        super().__init__(head + ":\n  - " + "\n  - ".join(self.problems))


# ---------------------------------------------------------------------------------- checks


def _is_number(x: Any) -> bool:
    return isinstance(x, numbers.Real) and not isinstance(x, bool)


def _fmt(x: Any) -> str:
    """A value for a message: whole floats without ``.0`` (as written in a file), else repr."""
    if isinstance(x, float) and math.isfinite(x) and x.is_integer() and abs(x) < 1e15:
        return str(int(x))
    return repr(x)


def _servo_problems(
    where: str,
    *,
    channel: Any,
    zero_us: Any,
    us_per_rad: Any,
    min_us: Any,
    max_us: Any,
    suffix: str = "",
    check_limits: bool = True,
    skip_none: bool = False,
) -> list[str]:
    """Problems with one servo's typed values (``where`` names the joint or the servo).

    With ``suffix`` ("_b") the channel, zero and scale keys carry it; min/max are shared
    (and checked only with ``check_limits``). With ``skip_none`` a None value is one whose
    problem was already reported (missing, or did not parse) and is not checked again.
    """
    out: list[str] = []
    ch_key, zero_key, scale_key = f"channel{suffix}", f"zero_us{suffix}", f"us_per_rad{suffix}"

    def skip(value: Any) -> bool:
        return skip_none and value is None

    if skip(channel):
        pass
    elif isinstance(channel, bool) or not isinstance(channel, numbers.Integral):
        out.append(
            f"{where}.{ch_key}: {_fmt(channel)} is not an integer (a PCA9685 output 0...15)"
        )
    elif not 0 <= int(channel) < CHANNELS:
        out.append(
            f"{where}.{ch_key}: channel {_fmt(channel)} does not exist (the PCA9685 has 0...15)"
        )
    if skip(us_per_rad):
        pass
    elif not _is_number(us_per_rad) or not math.isfinite(us_per_rad) or us_per_rad == 0:
        out.append(
            f"{where}.{scale_key}: {_fmt(us_per_rad)} must be finite and non-zero (us per rad; "
            f"the declared servo is +-{DECLARED_US_PER_RAD}, its sign the turning direction)"
        )
    limits_ok = True
    for key, value in (("min_us", min_us), ("max_us", max_us)):
        if skip(value):
            limits_ok = False
        elif not _is_number(value) or not math.isfinite(value):
            if check_limits:
                out.append(f"{where}.{key}: {_fmt(value)} must be a finite pulse width in us")
            limits_ok = False
    if limits_ok and check_limits:
        if min_us <= 0:
            out.append(f"{where}.min_us: {_fmt(min_us)} must be above 0 us (0 means no pulse)")
        elif min_us < HOBBY_MIN_US:
            out.append(
                f"{where}.min_us: {_fmt(min_us)} us is below {_fmt(HOBBY_MIN_US)} us, the "
                "narrowest pulse a hobby servo accepts (stages/servo_pulse.py refuses it too):"
                " measure the servo's end stop and set min_us a little inside it"
            )
        if max_us > HOBBY_MAX_US:
            out.append(
                f"{where}.max_us: {_fmt(max_us)} us is above {_fmt(HOBBY_MAX_US)} us, the "
                "widest pulse a hobby servo accepts (stages/servo_pulse.py refuses it too):"
                " measure the servo's end stop and set max_us a little inside it"
            )
    if limits_ok and min_us >= max_us:
        if check_limits:
            out.append(
                f"{where}.min_us/max_us: min_us {_fmt(min_us)} must be below max_us "
                f"{_fmt(max_us)} (set them a little inside the servo's end stops)"
            )
        limits_ok = False
    if skip(zero_us):
        pass
    elif not _is_number(zero_us) or not math.isfinite(zero_us):
        out.append(f"{where}.{zero_key}: {_fmt(zero_us)} must be a finite pulse width in us")
    elif limits_ok and not min_us <= zero_us <= max_us:
        out.append(
            f"{where}.{zero_key}: {_fmt(zero_us)} is outside [min_us, max_us] = "
            f"[{_fmt(min_us)}, {_fmt(max_us)}] (the zero pulse must be inside the servo's travel)"
        )
    return out


def _channel_clash_problems(users: Sequence[tuple[str, int]]) -> list[str]:
    """A channel used by two servos (``users`` = (``joint.key``, channel) pairs)."""
    by_channel: dict[int, list[str]] = {}
    for who, ch in users:
        by_channel.setdefault(ch, []).append(who)
    return [
        f"channel {ch} is used twice, by {' and '.join(who)}: give each servo its own "
        "PCA9685 output"
        for ch, who in sorted(by_channel.items())
        if len(who) > 1
    ]


def _board_problems(
    device: Any, address: Any, frame_hz: Any, oscillator_hz: Any, max_pulse_us: float | None
) -> list[str]:
    out: list[str] = []
    if not isinstance(device, str) or not device:
        out.append(f"device: {device!r} must be an I2C device path such as /dev/i2c-1")
    if isinstance(address, bool) or not isinstance(address, numbers.Integral):
        out.append(
            f"address: {_fmt(address)} must be an integer 0...127 (the PCA9685 is 0x40)"
        )
    elif not 0 <= int(address) <= 0x7F:
        out.append(f"address: {_fmt(address)} is outside 0...127 (7-bit; the PCA9685 is 0x40)")
    osc_ok = _is_number(oscillator_hz) and math.isfinite(oscillator_hz) and (
        0 < oscillator_hz <= MAX_OSCILLATOR_HZ
    )
    if not osc_ok:
        out.append(
            f"oscillator_hz: {_fmt(oscillator_hz)} must be above 0 and at most 50e6 Hz (nominal "
            "25e6; measure the board's)"
        )
    if not _is_number(frame_hz) or not math.isfinite(frame_hz) or frame_hz <= 0:
        out.append(
            f"frame_hz: {_fmt(frame_hz)} must be a positive frame rate in Hz (servos: 50)"
        )
    elif osc_ok:
        lo = oscillator_hz / (COUNTS * 256)
        hi = oscillator_hz / (COUNTS * 4)
        if not lo <= frame_hz <= hi:
            out.append(
                f"frame_hz: {_fmt(frame_hz)} Hz is outside what the PCA9685 can make with a "
                f"{oscillator_hz:g} Hz oscillator ({lo:.1f}...{hi:.0f} Hz; servos want 50)"
            )
        elif max_pulse_us is not None and max_pulse_us >= 1e6 / frame_hz:
            out.append(
                f"frame_hz: {_fmt(frame_hz)} Hz gives a {1e6 / frame_hz:.0f} us frame, too "
                f"short for the widest pulse max_us = {_fmt(max_pulse_us)} us"
            )
    return out


# ---------------------------------------------------------------------------------- model


@dataclass(frozen=True)
class PulseFit:
    """A servo's measured pulse-to-angle map: the least-squares polynomial through the
    ``(width_us, angle_deg)`` pairs the calibration recorded, and its inverse.

    Attributes:
        points: the measured pairs, widths strictly increasing after sorting.
        order: the polynomial's order (at most ``len(points) - 1``).

    Raises:
        CalibrationError: fewer than two points, a repeated width, or a fit that does not
            turn one way over the measured widths (it could not be inverted).
    """

    points: tuple[tuple[float, float], ...]
    order: int = DEFAULT_FIT_ORDER
    # the fit (centred widths, for conditioning) and its inverse table (angles, widths)
    _centre: float = field(init=False, repr=False, compare=False, default=0.0)
    _coef: np.ndarray = field(init=False, repr=False, compare=False,
                              default_factory=lambda: np.zeros(0))
    _table: tuple[np.ndarray, np.ndarray] = field(
        init=False, repr=False, compare=False,
        default_factory=lambda: (np.zeros(0), np.zeros(0)))

    def __post_init__(self) -> None:
        pts = sorted((float(w), float(a)) for w, a in self.points)
        problems: list[str] = []
        widths = [w for w, _ in pts]
        if len(pts) < 2:
            problems.append(f"points: {len(pts)} measured pair(s): measure at least two widths")
        elif len(set(widths)) != len(widths):
            problems.append("points: a width is measured twice: keep one angle per width")
        if problems:
            raise CalibrationError(problems)
        order = max(1, min(int(self.order), len(pts) - 1))
        object.__setattr__(self, "points", tuple(pts))
        object.__setattr__(self, "order", order)
        w = np.array(widths)
        object.__setattr__(self, "_centre", float(w.mean()))
        coef = np.polyfit(w - self._centre, np.radians([a for _, a in pts]), order)
        object.__setattr__(self, "_coef", coef)
        grid = np.linspace(w[0], w[-1], 4001)
        ang = np.polyval(coef, grid - self._centre)
        steps = np.diff(ang)
        if not (np.all(steps > 0) or np.all(steps < 0)):
            raise CalibrationError([
                f"points: the order-{order} fit through the measured pairs turns back between "
                f"{w[0]:g} and {w[-1]:g} us, so it has no inverse: lower fit_order or "
                "re-measure"])
        if steps[0] < 0:
            grid, ang = grid[::-1], ang[::-1]
        object.__setattr__(self, "_table", (ang, grid))

    @property
    def span_us(self) -> tuple[float, float]:
        """The measured widths' range, us."""
        return self.points[0][0], self.points[-1][0]

    def angle(self, pulse_us: np.ndarray | float) -> np.ndarray:
        """The fitted angle (rad) of pulse widths (us)."""
        return np.asarray(np.polyval(self._coef,
                                     np.asarray(pulse_us, dtype=float) - self._centre))

    def pulse_us(self, angle_rad: np.ndarray | float) -> np.ndarray:
        """The width (us) the fit maps to each angle (rad): the inverse, clamped to the
        measured widths (no extrapolation)."""
        ang, grid = self._table
        return np.asarray(np.interp(np.asarray(angle_rad, dtype=float), ang, grid))

    def residual_deg(self) -> float:
        """The largest distance of a measured angle from the fit, deg."""
        w = np.array([p[0] for p in self.points])
        a = np.array([p[1] for p in self.points])
        return float(np.max(np.abs(np.degrees(self.angle(w)) - a)))


@dataclass(frozen=True)
class ServoChannel:
    """One servo on one PCA9685 output and its linear pulse mapping.

    Attributes:
        channel: the PCA9685 output, 0...15.
        zero_us: the pulse width (us) at joint angle 0.
        us_per_rad: pulse change per joint radian (us/rad); its sign is the direction.
        min_us: the narrowest pulse sent (us), a little inside the travel's end.
        max_us: the widest pulse sent (us).

    Raises:
        CalibrationError: channel outside 0...15, scale zero or not finite, limits not
            ``400 <= min_us < max_us <= 2600`` (what a hobby servo accepts), zero outside
            them.
    """

    channel: int
    zero_us: float
    us_per_rad: float
    min_us: float
    max_us: float
    fit: PulseFit | None = None

    def __post_init__(self) -> None:
        problems = _servo_problems(
            f"servo on channel {self.channel}",
            channel=self.channel, zero_us=self.zero_us, us_per_rad=self.us_per_rad,
            min_us=self.min_us, max_us=self.max_us,
        )
        if problems:
            raise CalibrationError(problems)

    def pulse_us(self, angle_rad: float) -> float:
        """The pulse width (us) for a joint angle (rad), clamped to ``[min_us, max_us]``.

        Raises:
            ValueError: a NaN angle (infinite angles clamp to a limit).
        """
        if math.isnan(angle_rad):
            raise ValueError(f"servo on channel {self.channel}: angle is NaN")
        if self.fit is not None:
            pulse = float(self.fit.pulse_us(max(-1e3, min(1e3, float(angle_rad)))))
            return min(self.max_us, max(self.min_us, pulse))
        pulse = self.zero_us + self.us_per_rad * float(angle_rad)
        if math.isnan(pulse):  # 0 * inf cannot happen (us_per_rad != 0); kept for safety
            raise ValueError(f"servo on channel {self.channel}: angle {angle_rad} gives NaN")
        return min(self.max_us, max(self.min_us, pulse))

    def angle(self, pulse_us: float) -> float:
        """The joint angle (rad) of a pulse width (us): ``(pulse - zero_us) / us_per_rad``."""
        return (float(pulse_us) - self.zero_us) / self.us_per_rad

    def counts(self, angle_rad: float, count_us: float) -> int:
        """The PCA9685 off count for an angle, its width inside ``[min_us, max_us]``.

        The pulse is clamped to the limits, rounded to the nearest count (halves away from
        zero), and if rounding took it outside the limits it steps one count inward.

        Args:
            angle_rad: the joint angle (rad).
            count_us: one PCA9685 count (us), e.g. ``PCA9685.count_us`` (4.88 at 50 Hz).

        Raises:
            CalibrationError: no count width lies within ``[min_us, max_us]``.
            ValueError: NaN angle, or ``count_us`` not finite and positive.
        """
        _check_count_us(count_us)
        c = round_half_away(self.pulse_us(angle_rad) / count_us)
        if c * count_us > self.max_us + _TOL_US:
            c -= 1
        if c * count_us < self.min_us - _TOL_US:
            c += 1
        if not (0 <= c < COUNTS
                and self.min_us - _TOL_US <= c * count_us <= self.max_us + _TOL_US):
            raise self._no_count(count_us)
        return c

    def count_array(self, angle_rad: np.ndarray, count_us: float) -> np.ndarray:
        """:meth:`counts` of each of an array of angles (rad, none NaN), as int64: the same
        operations in the same order, element by element, so the same counts.

        Raises:
            CalibrationError: no count width lies within ``[min_us, max_us]``.
            ValueError: ``count_us`` not finite and positive.
        """
        _check_count_us(count_us)
        x = np.asarray(angle_rad, dtype=np.float64)
        if self.fit is not None:
            pulse = self.fit.pulse_us(np.minimum(1e3, np.maximum(-1e3, x)))
        else:
            pulse = self.zero_us + self.us_per_rad * x
        pulse = np.minimum(self.max_us, np.maximum(self.min_us, pulse))
        r = pulse / count_us
        c = np.where(r >= 0, np.floor(r + 0.5), -np.floor(-r + 0.5))  # round_half_away
        c = c - (c * count_us > self.max_us + _TOL_US)
        c = c + (c * count_us < self.min_us - _TOL_US)
        width = c * count_us
        if not np.all((c >= 0) & (c < COUNTS) & (width >= self.min_us - _TOL_US)
                      & (width <= self.max_us + _TOL_US)):
            raise self._no_count(count_us)
        return c.astype(np.int64)

    def _no_count(self, count_us: float) -> CalibrationError:
        return CalibrationError([
            f"servo on channel {self.channel}: no PCA9685 count of {count_us:.4g} us lies "
            f"within [min_us, max_us] = [{self.min_us}, {self.max_us}] (0...4095 counts):"
            " widen the limits or lower the frame rate"
        ])


def _check_count_us(count_us: float) -> None:
    if not _is_number(count_us) or not math.isfinite(count_us) or count_us <= 0:
        raise ValueError(f"count_us must be a finite positive width in us, got {count_us!r}")


@dataclass(frozen=True)
class JointServo:
    """The servo (or two) driving one joint.

    Attributes:
        joint: the joint's name (``joint_1`` ... ``joint_5``).
        a: the servo; ``a.angle`` of its pulse is the joint position reported.
        b: the optional second servo (the shoulder's mirrored one), with the same
            ``min_us`` / ``max_us`` as ``a``.

    Raises:
        CalibrationError: ``b`` on ``a``'s channel, or with other limits than ``a``.
    """

    joint: str
    a: ServoChannel
    b: ServoChannel | None = None

    def __post_init__(self) -> None:
        problems: list[str] = []
        if self.b is not None:
            if (self.b.min_us, self.b.max_us) != (self.a.min_us, self.a.max_us):
                problems.append(
                    f"{self.joint}: the second servo's limits [{self.b.min_us}, "
                    f"{self.b.max_us}] differ from the first's [{self.a.min_us}, "
                    f"{self.a.max_us}]; the two shoulder servos share min_us / max_us"
                )
            problems += _channel_clash_problems(
                [(f"{self.joint}.channel", self.a.channel),
                 (f"{self.joint}.channel_b", self.b.channel)]
            )
        if problems:
            raise CalibrationError(problems)

    def servos(self) -> tuple[ServoChannel, ...]:
        """The servos, ``a`` first."""
        return (self.a,) if self.b is None else (self.a, self.b)

    def channels(self) -> tuple[int, ...]:
        """The PCA9685 outputs, ``a``'s first."""
        return tuple(s.channel for s in self.servos())

    def pulses_us(self, angle_rad: float) -> dict[int, float]:
        """``{channel: pulse width (us)}`` for a joint angle (rad), each clamped."""
        return {s.channel: s.pulse_us(angle_rad) for s in self.servos()}

    def counts(self, angle_rad: float, count_us: float) -> dict[int, int]:
        """``{channel: off count}`` for a joint angle (rad) (see :meth:`ServoChannel.counts`)."""
        return {s.channel: s.counts(angle_rad, count_us) for s in self.servos()}


@dataclass(frozen=True)
class Calibration:
    """Every joint's servos plus the board settings (immutable; validated on creation).

    Attributes:
        joints: one :class:`JointServo` per joint, in joint order.
        tool_channel: the tool servo's output (documented wiring only; never driven), or None.
        oscillator_hz: the board's oscillator (Hz), calibrated per board (nominal 25e6).
        frame_hz: the servo frame rate (Hz).
        address: the board's 7-bit I2C address.
        device: the I2C device file.

    Raises:
        CalibrationError: every problem found (channels used twice, bad board settings).
    """

    joints: tuple[JointServo, ...]
    tool_channel: int | None = 6
    oscillator_hz: float = 25e6
    frame_hz: float = 50.0
    address: int = 0x40
    device: str = "/dev/i2c-1"

    def __post_init__(self) -> None:
        problems: list[str] = []
        names = [j.joint for j in self.joints]
        for name in sorted({n for n in names if names.count(n) > 1}):
            problems.append(f"joints.{name}: listed twice")
        users = [(f"{j.joint}.channel{'_b' if i else ''}", ch)
                 for j in self.joints for i, ch in enumerate(j.channels())]
        if self.tool_channel is not None:
            tool = self.tool_channel
            if isinstance(tool, bool) or not isinstance(tool, numbers.Integral):
                problems.append(f"tool.channel: {tool!r} is not an integer (0...15)")
            elif not 0 <= int(tool) < CHANNELS:
                problems.append(f"tool.channel: channel {tool} does not exist (0...15)")
            else:
                users.append(("tool.channel", int(tool)))
        problems += _channel_clash_problems(users)
        max_pulse = max((j.a.max_us for j in self.joints), default=None)
        problems += _board_problems(
            self.device, self.address, self.frame_hz, self.oscillator_hz, max_pulse
        )
        if problems:
            raise CalibrationError(problems)

    @property
    def joint_names(self) -> tuple[str, ...]:
        """The joints' names, in order."""
        return tuple(j.joint for j in self.joints)

    def joint(self, name: str) -> JointServo:
        """The servos of the joint called ``name``."""
        for j in self.joints:
            if j.joint == name:
                return j
        raise KeyError(f"no joint {name!r} in the calibration (joints: "
                       f"{', '.join(self.joint_names)})")

    def channels(self) -> tuple[int, ...]:
        """Every driven output, in joint order (the tool channel is not driven)."""
        return tuple(ch for j in self.joints for ch in j.channels())

    def _angles(self, q_rad: Sequence[float] | np.ndarray) -> list[float]:
        q = [float(x) for x in np.asarray(q_rad, dtype=float).reshape(-1)]
        if len(q) != len(self.joints):
            raise ValueError(
                f"expected {len(self.joints)} joint angles ({', '.join(self.joint_names)}), "
                f"got {len(q)}"
            )
        for j, x in zip(self.joints, q, strict=True):
            if math.isnan(x):
                raise ValueError(f"{j.joint}: commanded angle is NaN")
        return q

    def pulses_us(self, q_rad: Sequence[float] | np.ndarray) -> dict[int, float]:
        """``{channel: pulse width (us)}`` for a joint vector (rad), each clamped."""
        out: dict[int, float] = {}
        for j, x in zip(self.joints, self._angles(q_rad), strict=True):
            out.update(j.pulses_us(x))
        return out

    def counts(self, q_rad: Sequence[float] | np.ndarray, count_us: float) -> dict[int, int]:
        """``{channel: off count}`` for a joint vector (rad).

        Each pulse is clamped to its servo's ``[min_us, max_us]`` before rounding (halves
        away from zero) to the count period, and stepped one count inward if rounding left
        the limits, so a sent pulse never leaves them.

        Args:
            q_rad: one angle per joint (rad), in joint order.
            count_us: one PCA9685 count (us), ``PCA9685.count_us`` (4.88 at 50 Hz).

        Raises:
            ValueError: wrong number of angles, a NaN angle, or a bad ``count_us``.
            CalibrationError: no count lies within some servo's limits.
        """
        out: dict[int, int] = {}
        for j, x in zip(self.joints, self._angles(q_rad), strict=True):
            out.update(j.counts(x, count_us))
        return out

    def count_table(self, q_rad: np.ndarray, count_us: float) -> np.ndarray:
        """:meth:`counts` of every row of ``q_rad`` (frames, joints): an (frames, channels)
        int64 array, columns in :meth:`channels` order. The same counts as row by row
        (``tests/test_servos.py``), in milliseconds for a whole program, not seconds.

        Raises:
            ValueError: a row of the wrong length, a NaN angle, or a bad ``count_us``.
            CalibrationError: no count lies within some servo's limits.
        """
        q = np.asarray(q_rad, dtype=np.float64)
        if q.ndim != 2 or q.shape[1] != len(self.joints):
            self._angles(q[0] if q.ndim == 2 and len(q) else q)  # its message
            raise ValueError(f"expected frames x {len(self.joints)} joint angles, got the "
                             f"shape {q.shape}")
        for i, j in enumerate(self.joints):
            if np.isnan(q[:, i]).any():
                raise ValueError(f"{j.joint}: commanded angle is NaN")
        cols = [s.count_array(q[:, i], count_us)
                for i, j in enumerate(self.joints) for s in j.servos()]
        return np.stack(cols, axis=1) if cols else np.zeros((len(q), 0), dtype=np.int64)

    def positions(self, counts: Mapping[int, int], count_us: float) -> np.ndarray:
        """The joint angles (rad) that sent counts stand for (servo ``a``'s count per joint).

        This is an echo of what was sent (after limits and rounding), not a measurement.
        """
        return np.array(
            [j.a.angle(counts[j.a.channel] * count_us) for j in self.joints], dtype=float
        )

    # ------------------------------------------------------------------------------ loading

    @classmethod
    def from_mapping(
        cls,
        mapping: object,
        joint_names: Sequence[str] = DEFAULT_JOINT_NAMES,
        *,
        source: str = "servo calibration",
    ) -> Calibration:
        """Build and validate a calibration from a plain dict or an OmegaConf DictConfig.

        Every problem is collected (a channel used twice, a channel outside 0...15,
        ``min_us >= max_us``, ``min_us <= 0``, limits beyond the 400...2600 us a hobby
        servo accepts, a zero outside the limits, a zero or non-finite scale, a
        non-numeric value such as ``"15OO"``, a missing or unknown key, a missing or
        unknown joint) and reported together.

        Args:
            mapping: the calibration (keys as in the module docstring).
            joint_names: the arm's joints, in order.
            source: names the file in messages.

        Raises:
            CalibrationError: one message listing every problem, each naming joint and key.
        """
        data = _plain(mapping, source)
        problems: list[str] = []
        if not isinstance(data, Mapping):
            raise CalibrationError(
                [f"expected a mapping with keys {', '.join(TOP_KEYS)}, got "
                 f"{type(data).__name__}"], source,
            )
        _unknown_keys(data, TOP_KEYS, "", problems)
        device = data.get("device", "/dev/i2c-1")
        address = _integer(data.get("address", 0x40), "address", problems)
        frame_hz = _number(data.get("frame_hz", 50.0), "frame_hz", problems)
        oscillator_hz = _number(data.get("oscillator_hz", 25e6), "oscillator_hz", problems)

        tool_channel: int | None = None
        tool = data.get("tool")
        if tool is not None:
            if not isinstance(tool, Mapping):
                problems.append(f"tool: expected a mapping like {{channel: 6}}, got {tool!r}")
            else:
                _unknown_keys(tool, TOOL_KEYS, "tool.", problems)
                if "channel" not in tool:
                    problems.append("tool.channel: missing (the tool servo's output, 6)")
                else:
                    tool_channel = _integer(tool["channel"], "tool.channel", problems)

        joints_raw = data.get("joints")
        parsed: dict[str, dict[str, Any]] = {}
        if joints_raw is None:
            problems.append(
                f"joints: missing (one entry per joint: {', '.join(joint_names)})"
            )
        elif not isinstance(joints_raw, Mapping):
            problems.append(f"joints: expected a mapping of joint name to servo, got "
                            f"{type(joints_raw).__name__}")
        else:
            for name in joint_names:
                if name not in joints_raw:
                    problems.append(f"joints.{name}: missing (every joint needs its servo)")
            for name, entry in joints_raw.items():
                if name not in joint_names:
                    problems.append(
                        f"joints.{name}: unknown joint (the arm's joints are "
                        f"{', '.join(joint_names)}){_did_you_mean(str(name), joint_names)}"
                    )
                    continue
                values = _joint_values(str(name), entry, problems)
                if values is not None:
                    parsed[str(name)] = values

        # semantic checks on the values that parsed
        users: list[tuple[str, int]] = []
        for name, v in parsed.items():
            problems += _servo_problems(
                name, channel=v["channel"], zero_us=v["zero_us"], us_per_rad=v["us_per_rad"],
                min_us=v["min_us"], max_us=v["max_us"], skip_none=True,
            )
            users.append((f"{name}.channel", v["channel"]))
            if "channel_b" in v:
                problems += _servo_problems(
                    name, channel=v["channel_b"], zero_us=v["zero_us_b"],
                    us_per_rad=v["us_per_rad_b"], min_us=v["min_us"], max_us=v["max_us"],
                    suffix="_b", check_limits=False, skip_none=True,
                )
                users.append((f"{name}.channel_b", v["channel_b"]))
        if isinstance(tool_channel, int) and 0 <= tool_channel < CHANNELS:
            users.append(("tool.channel", tool_channel))
        elif tool_channel is not None:
            problems.append(f"tool.channel: channel {tool_channel} does not exist (0...15)")
        problems += _channel_clash_problems(
            [(who, ch) for who, ch in users if isinstance(ch, int) and 0 <= ch < CHANNELS]
        )
        max_pulses = [v["max_us"] for v in parsed.values() if v["max_us"] is not None]
        problems += _board_problems(
            device, address if address is not None else 0x40,
            frame_hz if frame_hz is not None else 50.0,
            oscillator_hz if oscillator_hz is not None else 25e6,
            max(max_pulses) if max_pulses else None,
        )
        if problems:
            raise CalibrationError(_unique(problems), source)

        joints = []
        for name in joint_names:
            v = parsed[name]
            a = ServoChannel(v["channel"], v["zero_us"], v["us_per_rad"], v["min_us"],
                             v["max_us"], v.get("fit"))
            b = None
            if "channel_b" in v:
                b = ServoChannel(v["channel_b"], v["zero_us_b"], v["us_per_rad_b"],
                                 v["min_us"], v["max_us"])
            joints.append(JointServo(name, a, b))
        assert address is not None and frame_hz is not None and oscillator_hz is not None
        return cls(
            joints=tuple(joints), tool_channel=tool_channel, oscillator_hz=oscillator_hz,
            frame_hz=frame_hz, address=address, device=device,
        )

    def to_mapping(self) -> JsonDict:
        """The calibration as a plain dict in the file's layout (``from_mapping`` inverse)."""
        joints: dict[str, dict[str, Any]] = {}
        for j in self.joints:
            entry: dict[str, Any] = {
                "channel": j.a.channel, "zero_us": j.a.zero_us, "us_per_rad": j.a.us_per_rad,
                "min_us": j.a.min_us, "max_us": j.a.max_us,
            }
            if j.b is not None:
                entry.update(channel_b=j.b.channel, zero_us_b=j.b.zero_us,
                             us_per_rad_b=j.b.us_per_rad)
            if j.a.fit is not None:
                entry.update(points=[list(p) for p in j.a.fit.points],
                             fit_order=j.a.fit.order)
            joints[j.joint] = entry
        out: dict[str, Any] = {
            "device": self.device, "address": self.address, "frame_hz": self.frame_hz,
            "oscillator_hz": self.oscillator_hz, "joints": joints,
        }
        if self.tool_channel is not None:
            out["tool"] = {"channel": self.tool_channel}
        return out


# ---------------------------------------------------------------------------------- parsing


def _plain(mapping: Any, source: str) -> Any:
    """A DictConfig as plain containers (interpolations resolved); anything else as is."""
    try:
        from omegaconf import DictConfig, ListConfig, OmegaConf
    except ImportError:  # pragma: no cover - omegaconf is a dependency
        return mapping
    if isinstance(mapping, DictConfig | ListConfig):
        try:
            return OmegaConf.to_container(mapping, resolve=True)
        except Exception as err:  # interpolation errors and the like
            raise CalibrationError([f"cannot resolve the values: {err}"], source) from None
    return mapping


def _unique(items: list[str]) -> list[str]:
    return list(dict.fromkeys(items))


def _did_you_mean(key: str, allowed: Sequence[str]) -> str:
    close = difflib.get_close_matches(key, list(allowed), n=1)
    return f"; did you mean {close[0]!r}?" if close else ""


def _unknown_keys(
    entry: Mapping[Any, Any], allowed: Sequence[str], prefix: str, problems: list[str]
) -> None:
    for key in entry:
        if key not in allowed:
            problems.append(
                f"{prefix}{key}: unknown key (allowed: {', '.join(allowed)})"
                + _did_you_mean(str(key), allowed)
            )


def _number(value: Any, where: str, problems: list[str]) -> float | None:
    """A finite float from a number or a string that parses completely; else a problem."""
    if isinstance(value, bool) or value is None:
        problems.append(f"{where}: {value!r} is not a number")
        return None
    if _is_number(value):
        x = float(value)
    elif isinstance(value, str):
        try:
            x = float(value.strip())
        except ValueError:
            problems.append(f"{where}: {value!r} is not a number (check for letters, e.g. "
                            "O for 0)")
            return None
    else:
        problems.append(f"{where}: {value!r} is not a number")
        return None
    if not math.isfinite(x):
        problems.append(f"{where}: {value!r} is not finite")
        return None
    return x


def _integer(value: Any, where: str, problems: list[str]) -> int | None:
    """An int from an int, an integral float or a string such as "6" or "0x40"."""
    if isinstance(value, bool) or value is None:
        problems.append(f"{where}: {value!r} is not an integer")
        return None
    if isinstance(value, numbers.Integral):
        return int(value)
    if _is_number(value):
        x = float(value)
        if math.isfinite(x) and x.is_integer():
            return int(x)
        problems.append(f"{where}: {value!r} is not a whole number")
        return None
    if isinstance(value, str):
        try:
            return int(value.strip(), 0)
        except ValueError:
            problems.append(f"{where}: {value!r} is not an integer")
            return None
    problems.append(f"{where}: {value!r} is not an integer")
    return None


def _joint_values(name: str, entry: Any, problems: list[str]) -> dict[str, Any] | None:
    """A joint entry's typed values (None for a key missing or not parsing, both reported).

    The second servo's keys are present only when the entry has any of them. Returns None
    when the entry is not a mapping.
    """
    if not isinstance(entry, Mapping):
        problems.append(
            f"joints.{name}: expected a mapping with keys {', '.join(JOINT_KEYS_A)}, got "
            f"{entry!r}"
        )
        return None
    _unknown_keys(entry, JOINT_KEYS_A + JOINT_KEYS_B + JOINT_KEYS_FIT, f"{name}.", problems)
    keys = list(JOINT_KEYS_A)
    if any(k in entry for k in JOINT_KEYS_B):
        keys += JOINT_KEYS_B
    values: dict[str, Any] = {}
    for key in keys:
        where = f"{name}.{key}"
        if key not in entry:
            hint = (" (a second servo needs channel_b, zero_us_b and us_per_rad_b)"
                    if key in JOINT_KEYS_B else "")
            problems.append(f"{where}: missing{hint}")
            values[key] = None
        elif key.startswith("channel"):
            values[key] = _integer(entry[key], where, problems)
        else:
            values[key] = _number(entry[key], where, problems)
    if "points" in entry:
        values["fit"] = _fit(name, entry["points"], entry.get("fit_order", DEFAULT_FIT_ORDER),
                             problems)
    return values


def _fit(name: str, points: Any, order: Any, problems: list[str]) -> PulseFit | None:
    """A joint's measured pairs as a :class:`PulseFit` (None and a problem if they are bad)."""
    where = f"{name}.points"
    if not isinstance(points, Sequence) or isinstance(points, str) or not all(
            isinstance(p, Sequence) and not isinstance(p, str) and len(p) == 2
            for p in points):
        problems.append(f"{where}: expected a list of [width_us, angle_deg] pairs, got "
                        f"{points!r}")
        return None
    pairs = []
    for i, (w, a) in enumerate(points):
        wv = _number(w, f"{where}[{i}] width", problems)
        av = _number(a, f"{where}[{i}] angle", problems)
        if wv is not None and av is not None:
            pairs.append((wv, av))
    k = _integer(order, f"{name}.fit_order", problems)
    if len(pairs) != len(points) or k is None:
        return None
    if not 1 <= k <= 7:
        problems.append(f"{name}.fit_order: {k} must be 1...7")
        return None
    try:
        return PulseFit(tuple(pairs), k)
    except CalibrationError as exc:
        problems += [f"{name}.{p}" for p in exc.problems]
        return None


def default_calibration_mapping() -> JsonDict:
    """The declared (catalogue, not measured) calibration as a plain dict (file layout)."""
    servo = {"zero_us": DECLARED_ZERO_US, "us_per_rad": DECLARED_US_PER_RAD,
             "min_us": DECLARED_MIN_US, "max_us": DECLARED_MAX_US}
    joints: dict[str, dict[str, Any]] = {
        "joint_1": {"channel": 0, **servo},
        "joint_2": {"channel": 1, **servo, "channel_b": 2, "zero_us_b": DECLARED_ZERO_US,
                    "us_per_rad_b": -DECLARED_US_PER_RAD},
        "joint_3": {"channel": 3, **servo},
        "joint_4": {"channel": 4, **servo},
        "joint_5": {"channel": 5, **servo},
    }
    return {"device": "/dev/i2c-1", "address": 0x40, "frame_hz": 50.0,
            "oscillator_hz": 25e6, "joints": joints, "tool": {"channel": 6}}


def default_calibration() -> Calibration:
    """The declared calibration: every servo 1500 us at zero, 636.62 us/rad, 500...2500 us.

    Channels 0...5 (joint_2 on 1 and, mirrored, 2), tool on 6 (never driven). Catalogue
    values, **not measured**: calibrate (README, "Calibrating the servos") before trusting
    them.
    """
    return Calibration.from_mapping(default_calibration_mapping(), DEFAULT_JOINT_NAMES,
                                    source="default servo calibration")


DEFAULT_CALIBRATION = default_calibration()


def load_calibration(
    path: str | Path, joint_names: Sequence[str] = DEFAULT_JOINT_NAMES
) -> Calibration:
    """Read and validate a servo calibration YAML file.

    Args:
        path: the YAML file.
        joint_names: the arm's joints, in order.

    Raises:
        CalibrationError: the file is missing, is not valid YAML, is not a mapping, or has
            problems (all listed, each naming the file, joint and key).
    """
    p = Path(path)
    source = f"servo calibration {p}"
    if not p.is_file():
        raise CalibrationError(
            ["file not found: copy the declared calibration (tattotronix.hardware.servos."
             "default_calibration_mapping) and calibrate it (README, 'Calibrating the "
             "servos')"],
            source,
        )
    try:
        import yaml
        from omegaconf import OmegaConf

        cfg = OmegaConf.load(p)
    except yaml.YAMLError as err:
        raise CalibrationError([f"not valid YAML: {' '.join(str(err).split())}"],
                               source) from None
    except Exception as err:  # omegaconf refusals (duplicate keys, unsupported values)
        raise CalibrationError([f"cannot read it: {' '.join(str(err).split())}"],
                               source) from None
    return Calibration.from_mapping(cfg, joint_names, source=source)
