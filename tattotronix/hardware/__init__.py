"""Servo hardware: the PCA9685 PWM board on I2C and the servo calibration.

* :mod:`~tattotronix.hardware.pca9685`: the board driver (prescaler, atomic 4-byte channel
  writes, all outputs off on exit, exception and SIGINT/SIGTERM/SIGHUP), the
  :class:`RecordingBus` fake for dry runs and tests, and :func:`open_bus` for the Linux
  I2C device.
* :mod:`~tattotronix.hardware.arm`: ``draw.py backend=arm``, a drawing streamed to the
  board with safe stops and resume (after a crash too).
* :mod:`~tattotronix.hardware.servos`: joint angle (rad) to pulse width (us) to count, per
  servo (the mirrored second shoulder servo included), and the validated calibration file.
"""

from __future__ import annotations

from tattotronix.hardware.pca9685 import (
    PCA9685,
    BusError,
    HardwareError,
    NotStartedError,
    OutOfRangeError,
    RecordingBus,
    SMBusLike,
    open_bus,
    prescaler,
)
from tattotronix.hardware.servos import (
    DEFAULT_CALIBRATION,
    DEFAULT_JOINT_NAMES,
    Calibration,
    CalibrationError,
    JointServo,
    ServoChannel,
    default_calibration,
    default_calibration_mapping,
    load_calibration,
)

__all__ = [
    "DEFAULT_CALIBRATION",
    "DEFAULT_JOINT_NAMES",
    "PCA9685",
    "BusError",
    "Calibration",
    "CalibrationError",
    "HardwareError",
    "JointServo",
    "NotStartedError",
    "OutOfRangeError",
    "RecordingBus",
    "SMBusLike",
    "ServoChannel",
    "default_calibration",
    "default_calibration_mapping",
    "load_calibration",
    "open_bus",
    "prescaler",
]
