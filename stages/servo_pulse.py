"""Calibration helper: hold one pulse on one PCA9685 channel (docs/original.md, "6.5
Calibrating a servo").

    python stages/servo_pulse.py channel=N width_us=W [dry_run=true] [hardware.* overrides]

Holds W us (400..2600) on channel N, then reads new widths from standard input, one per
line; an empty line (or end of input) switches the channel off and exits. The board and
address come from conf/hardware (or hardware.calibration_file). See README, "Calibrating
the servos".
"""

from __future__ import annotations

import sys

from tattotronix.errors import TattotronixError
from tattotronix.hardware.pca9685 import PCA9685, RecordingBus, open_bus
from tattotronix.hardware.pulse import hold_pulses


def main(argv: list[str]) -> int:
    """Parse ``channel=``, ``width_us=``, ``dry_run=``; the rest are config overrides."""
    from tattotronix.config.params import compose_settings
    from tattotronix.hardware.arm import calibration_from_config
    from tattotronix.robot.description import build_description

    own: dict[str, str] = {}
    rest = []
    for arg in argv:
        key, _, value = arg.partition("=")
        if key in ("channel", "width_us", "dry_run"):
            own[key] = value
        else:
            rest.append(arg)
    try:
        if "channel" not in own or "width_us" not in own:
            raise TattotronixError("give channel=N and width_us=W (400..2600 us)")
        try:
            channel = int(own["channel"])
        except ValueError:
            raise TattotronixError(f"channel={own['channel']}: give 0..15") from None
        cfg = compose_settings(rest)
        calib = calibration_from_config(cfg.hardware, build_description(cfg.robot).joint_names)
        dry = own.get("dry_run", "false").lower() in ("1", "true", "yes")
        bus = RecordingBus() if dry else open_bus(calib.device, calib.address)
        with PCA9685(bus, calib.address, calib.oscillator_hz) as board:
            board.start(calib.frame_hz)
            hold_pulses(board, channel, own["width_us"], sys.stdin)
        if dry:
            sys.stdout.write(bus.transcript())
    except TattotronixError as exc:
        print(f"servo_pulse: error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
