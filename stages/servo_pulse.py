"""Calibration helper: hold one pulse on one PCA9685 channel (docs/original.md, "6.5
Calibrating a servo").

    python stages/servo_pulse.py channel=N width_us=W [dry_run=true] [hardware.* overrides]
    python stages/servo_pulse.py channel=N width_us=W joint=joint_1 record=FILE

Holds W us (400..2600) on channel N, then reads new widths from standard input, one per
line; an empty line (or end of input) switches the channel off and exits. With
``joint=`` and ``record=``, a line may add the angle (deg) measured at the width held
before it (``1700 23.5``, or ``- 23.5`` to stay): each pair is added to
``joints.<joint>.points`` in FILE (a calibration file; made from the configured
calibration if missing), checked and saved at once; ``deploy`` then inverts the fit
(docs/servos.md, "Calibration that fixes what it can"). The board and
address come from conf/hardware (or hardware.calibration_file). See README, "Calibrating
the servos".
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

from tattotronix.errors import TattotronixError
from tattotronix.hardware.pca9685 import PCA9685, RecordingBus, open_bus
from tattotronix.hardware.pulse import hold_pulses
from tattotronix.hardware.servos import Calibration


def recorder(path: Path, joint: str, calib: Calibration) -> Callable[[float, float], None]:
    """Adds ``(width_us, angle_deg)`` to ``joints.<joint>.points`` in the calibration file
    ``path`` (from ``calib`` if it does not exist yet), validated and written each time."""
    import yaml

    from tattotronix.hardware.servos import Calibration as Calib

    if joint not in calib.joint_names:
        raise TattotronixError(f"joint={joint}: the arm's joints are "
                               f"{', '.join(calib.joint_names)}")

    def record(width_us: float, angle_deg: float) -> None:
        data: Any = (yaml.safe_load(path.read_text()) if path.exists() else None) \
            or calib.to_mapping()  # Any: YAML's mapping, checked whole below
        points = data["joints"][joint].setdefault("points", [])
        points[:] = [p for p in points if float(p[0]) != round(width_us, 3)]
        points.append([round(width_us, 3), float(angle_deg)])
        fit = None
        if len(points) > 1:  # a fit needs two; the file is checked whole before it is kept
            fit = Calib.from_mapping(data, calib.joint_names, source=str(path)).joint(joint).a.fit
        tmp = path.with_suffix(path.suffix + ".tmp")
        tmp.write_text(yaml.safe_dump(data, sort_keys=False))
        tmp.replace(path)
        if fit is not None:
            print(f"{joint}: {len(points)} widths measured; the order-{fit.order} fit passes "
                  f"within {fit.residual_deg():.2f} deg of their angles", flush=True)

    return record


def main(argv: list[str]) -> int:
    """Parse ``channel=``, ``width_us=``, ``dry_run=``; the rest are config overrides."""
    from tattotronix.config.params import compose_settings
    from tattotronix.hardware.arm import calibration_from_config
    from tattotronix.robot.description import build_description

    own: dict[str, str] = {}
    rest = []
    for arg in argv:
        key, _, value = arg.partition("=")
        if key in ("channel", "width_us", "dry_run", "joint", "record"):
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
        record = None
        if ("joint" in own) != ("record" in own):
            raise TattotronixError("give both joint=NAME and record=FILE to record angles")
        if "record" in own:
            record = recorder(Path(own["record"]), own["joint"], calib)
        bus = RecordingBus() if dry else open_bus(calib.device, calib.address)
        with PCA9685(bus, calib.address, calib.oscillator_hz) as board:
            board.start(calib.frame_hz)
            hold_pulses(board, channel, own["width_us"], sys.stdin, record=record)
        if isinstance(bus, RecordingBus):  # a dry run: what it would have sent
            sys.stdout.write(bus.transcript())
    except TattotronixError as exc:
        print(f"servo_pulse: error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
