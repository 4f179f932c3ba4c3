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

__all__ = ["MAX_US", "MIN_US", "hold_pulses", "parse_width"]

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


def hold_pulses(board: PCA9685, channel: int, first_us: float | str, lines: Iterable[str],
                say: Callable[[str], None] = print) -> list[int]:
    """Hold ``first_us`` (us, a number or its text) on ``channel``, then each width read
    from ``lines``.

    A bad line is reported and skipped (the last good pulse keeps holding). An empty line
    or the end of ``lines`` switches the channel off. Returns the counts sent.

    Raises:
        TattotronixError: a bad channel or first width.
    """
    if isinstance(channel, bool) or not isinstance(channel, int) or not 0 <= channel < CHANNELS:
        raise TattotronixError(f"channel={channel!r}: give a channel 0..{CHANNELS - 1}")
    sent: list[int] = []

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
                send(parse_width(line))
            except TattotronixError as exc:
                say(f"ignored: {exc}")
    finally:
        board.off(channel)
        say(f"channel {channel}: off")
    return sent
