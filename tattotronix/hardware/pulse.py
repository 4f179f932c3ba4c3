"""Hold one servo pulse for calibration (``stages/servo_pulse.py``; README, "Calibrating the
servos").

One channel, one width in 400..2600 us; further widths are read line by line; an empty
line (or the end of input) switches that channel off and ends. The width actually sent
is the nearest count (4.88 us at 50 Hz), and is reported.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable

from tattotronix.errors import TattotronixError
from tattotronix.hardware.pca9685 import CHANNELS, PCA9685
from tattotronix.hardware.servos import HOBBY_MAX_US, HOBBY_MIN_US

__all__ = ["MAX_US", "MIN_US", "hold_pulses", "parse_reading", "parse_width"]

MIN_US, MAX_US = HOBBY_MIN_US, HOBBY_MAX_US  # what a hobby servo accepts (servos.py)


def parse_width(text: str) -> float:
    """A pulse width in us from user input.

    Raises:
        TattotronixError: not a number, or outside 400..2600 us.
    """
    try:
        width = float(text)
    except ValueError:
        raise TattotronixError(f"'{text.strip()}' is not a pulse width: give microseconds "
                               f"between {MIN_US:g} and {MAX_US:g}, or an empty line to stop"
                               ) from None
    if not (math.isfinite(width) and MIN_US <= width <= MAX_US):
        raise TattotronixError(f"{text.strip()} us is outside {MIN_US:g}..{MAX_US:g} us")
    return width


def parse_reading(text: str) -> tuple[float, float | None]:
    """A line of input: a width (us), optionally followed by the angle (deg) measured at
    the width held before it (``1700 23.5``: record 23.5 deg at the last width, then hold
    1700 us; ``- 23.5``: record it and hold on).

    Raises:
        TattotronixError: not a width, or an angle that is not a number.
    """
    parts = text.split()
    if len(parts) == 2:
        try:
            angle = float(parts[1])
        except ValueError:
            raise TattotronixError(f"'{parts[1]}' is not an angle in degrees") from None
        if not math.isfinite(angle):
            raise TattotronixError(f"{parts[1]} is not a finite angle")
        return (math.nan if parts[0] == "-" else parse_width(parts[0])), angle
    if len(parts) > 2:
        raise TattotronixError(f"'{text.strip()}': give a width, or a width and the angle "
                               "measured at the last one")
    return parse_width(text), None


def hold_pulses(board: PCA9685, channel: int, first_us: float | str, lines: Iterable[str],
                say: Callable[[str], None] = print,
                record: Callable[[float, float], None] | None = None) -> list[int]:
    """Hold ``first_us`` (us, a number or its text) on ``channel``, then each width read
    from ``lines``.

    A bad line is reported and skipped (the last good pulse keeps holding). An empty line
    or the end of ``lines`` switches the channel off. Returns the counts sent.

    With ``record``, a line may also carry the angle measured at the width held before it
    (:func:`parse_reading`); ``record(width_sent_us, angle_deg)`` keeps the pair (the
    width actually sent, the nearest count's).

    Raises:
        TattotronixError: a bad channel or first width.
    """
    if isinstance(channel, bool) or not isinstance(channel, int) or not 0 <= channel < CHANNELS:
        raise TattotronixError(f"channel={channel!r}: give a channel 0..{CHANNELS - 1}")
    sent: list[int] = []

    def held_us() -> float:
        return board.counts_to_us(sent[-1])

    def send(width: float) -> None:
        counts = board.pulse_to_counts(width)
        board.set_counts(channel, counts)
        sent.append(counts)
        say(f"channel {channel}: {width:g} us -> {counts} counts = "
            f"{board.counts_to_us(counts):.2f} us (new width, or empty line to stop)")

    send(parse_width(str(first_us)))
    try:
        for line in lines:
            if not line.strip():
                break
            try:
                width, angle = parse_reading(line) if record else (parse_width(line), None)
                if angle is not None and record is not None:
                    record(held_us(), angle)
                    say(f"recorded {angle:g} deg at {held_us():.2f} us")
                if not math.isnan(width):
                    send(width)
            except TattotronixError as exc:
                say(f"ignored: {exc}")
    finally:
        board.off(channel)
        say(f"channel {channel}: off")
    return sent
