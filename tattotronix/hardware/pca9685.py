"""The PCA9685 16-channel PWM board on I2C (docs/original.md, "6.2 The PCA9685 driver").

Every servo pulse is timed by the board: one frame of 4096 counts at the frame rate set by
the prescaler, each channel switched on at count 0 and off at its own count. At 50 Hz and
the nominal 25 MHz oscillator one count lasts ``(121 + 1) / 25e6`` s = 4.88 us.

* :func:`prescaler` is the datasheet's prescale value for a frame rate.
* :class:`PCA9685` drives the board through any object with smbus2's ``SMBus`` methods
  (:class:`SMBusLike`). Channel writes are one 4-byte block write each, so a channel is
  never half-updated. Used as a context manager it always ends with every output off: on
  normal exit, on an exception, and on SIGINT/SIGTERM/SIGHUP.
* :class:`RecordingBus` stands in for the board (dry runs and tests): it records every
  write as ``{"addr": 64, "reg": 0, "data": [16]}`` (the ``i2c.jsonl`` transcript line).
* :func:`open_bus` opens the Linux I2C device and checks that the board answers, with
  messages a user can act on instead of a traceback.

Units: frequencies in Hz, pulse widths and count periods in microseconds (``_us``),
durations passed to ``sleep`` in seconds.
"""

from __future__ import annotations

import json
import logging
import math
import numbers
import signal
import threading
import time
from collections.abc import Callable, Sequence
from types import FrameType, TracebackType
from typing import Any, Protocol

from tattotronix.errors import TattotronixError

__all__ = [
    "ALL_LED_ON_L",
    "AI",
    "BusError",
    "CHANNELS",
    "COUNTS",
    "FULL_OFF",
    "HardwareError",
    "LED0_ON_L",
    "MODE1",
    "MODE2",
    "NotStartedError",
    "OUTDRV",
    "OutOfRangeError",
    "PCA9685",
    "PRESCALE",
    "RecordingBus",
    "SLEEP",
    "SMBusLike",
    "counts_block",
    "open_bus",
    "prescaler",
    "round_half_away",
]

log = logging.getLogger(__name__)

# Registers (docs/original.md, "6.2 The PCA9685 driver"; NXP's PCA9685 datasheet, 7.3).
MODE1 = 0x00
MODE2 = 0x01
LED0_ON_L = 0x06  # channel n at LED0_ON_L + 4 n: ON_L, ON_H, OFF_L, OFF_H
ALL_LED_ON_L = 0xFA
PRESCALE = 0xFE

# Bits.
SLEEP = 0x10  # MODE1: oscillator off (prescale writable only while asleep)
AI = 0x20  # MODE1: register auto-increment (block writes fill consecutive registers)
OUTDRV = 0x04  # MODE2: totem-pole outputs
FULL_OFF = 0x10  # LEDn_OFF_H: output fully off

CHANNELS = 16
COUNTS = 4096  # counts per frame; a channel's off count is 0 ... COUNTS - 1
PRESCALE_MIN, PRESCALE_MAX = 3, 255
OSCILLATOR_SETTLE_S = 500e-6  # datasheet: oscillator stable 500 us after waking
OFF_BLOCK = (0x00, 0x00, 0x00, FULL_OFF)  # on = 0, off = full-off bit


# what stops a process holding the board: Ctrl-C, kill, and a closed terminal (POSIX only)
_STOP_SIGNALS = tuple(getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP")
                      if hasattr(signal, name))


def _i2cdetect(address: int) -> str:
    """The end of a bus error's advice ("check ... and that <this>")."""
    return f"`i2cdetect -y 1` lists the board at 0x{address:02x}"


class HardwareError(TattotronixError):
    """Something about the servo hardware (board, bus, calibration) the user must fix."""


class OutOfRangeError(HardwareError, ValueError):
    """A channel, count, frequency or address outside what the board accepts."""


class NotStartedError(HardwareError, RuntimeError):
    """The board was used before :meth:`PCA9685.start` set its frame rate."""


class BusError(HardwareError):
    """An I2C transfer to the board failed (``OSError`` from the bus)."""


class SMBusLike(Protocol):
    """The part of ``smbus2.SMBus`` the driver uses (the real bus or :class:`RecordingBus`)."""

    def write_byte_data(self, i2c_addr: int, register: int, value: int, /) -> object:
        """Write one byte to a register."""

    def write_i2c_block_data(self, i2c_addr: int, register: int, data: list[int], /
                             ) -> object:
        """Write consecutive registers starting at ``register`` in one transfer."""

    def read_byte_data(self, i2c_addr: int, register: int, /) -> int:
        """Read one register."""

    def close(self) -> object:
        """Release the bus."""


def round_half_away(x: float) -> int:
    """Round to the nearest integer, halves away from zero (C's ``llround``).

    Used for the prescaler and for pulse-to-count conversions, so that a value exactly
    half-way between two counts always goes the same way as the C++ original.
    """
    return int(math.floor(x + 0.5)) if x >= 0 else -int(math.floor(-x + 0.5))


def _finite_positive(value: float, name: str, unit: str, what_to_do: str) -> float:
    """``value`` as a float, refused (naming it) unless it is a finite number above zero."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise OutOfRangeError(f"{name} must be a number in {unit}, got {value!r}: {what_to_do}")
    x = float(value)
    if not math.isfinite(x) or x <= 0:
        raise OutOfRangeError(f"{name} must be finite and above zero, got {value!r} {unit}: "
                              f"{what_to_do}")
    return x


def prescaler(frequency_hz: float, oscillator_hz: float = 25e6) -> int:
    """The PRESCALE register value for a frame rate (datasheet equation 1).

    ``clamp(round(osc / (4096 f)) - 1, 3, 255)``, rounding halves away from zero:
    121 at 50 Hz, 101 at 60 Hz, 3 at 5 kHz (clamped), 255 at 1 Hz (clamped).

    Args:
        frequency_hz: the wanted frame rate (Hz).
        oscillator_hz: the board's oscillator (Hz); nominally 25 MHz, calibrate per board.

    Raises:
        OutOfRangeError: (a ValueError) zero, negative or non-finite frequency or oscillator.
    """
    f = _finite_positive(frequency_hz, "frame rate", "Hz", "servos want 50 Hz")
    osc = _finite_positive(oscillator_hz, "oscillator_hz", "Hz",
                           "the PCA9685's internal oscillator is nominally 25e6")
    return max(PRESCALE_MIN, min(PRESCALE_MAX, round_half_away(osc / (COUNTS * f)) - 1))


def _check_channel(channel: Any) -> int:
    if isinstance(channel, bool) or not isinstance(channel, numbers.Integral):
        raise OutOfRangeError(f"PCA9685 channel must be an integer 0...15, got {channel!r}")
    if not 0 <= int(channel) < CHANNELS:
        raise OutOfRangeError(
            f"PCA9685 channel {channel} does not exist: the board has channels 0...15"
        )
    return int(channel)


def _check_counts(counts: Any) -> int:
    if isinstance(counts, bool) or not isinstance(counts, numbers.Integral):
        raise OutOfRangeError(f"PCA9685 off count must be an integer 0...4095, got {counts!r}")
    if not 0 <= int(counts) < COUNTS:
        raise OutOfRangeError(
            f"PCA9685 off count {counts} is outside 0...4095 (a frame has 4096 counts): "
            "convert pulse widths with pulse_to_counts(), which clamps"
        )
    return int(counts)


def _check_address(address: Any) -> int:
    if isinstance(address, bool) or not isinstance(address, numbers.Integral):
        raise OutOfRangeError(f"I2C address must be an integer 0...127, got {address!r}")
    if not 0 <= int(address) <= 0x7F:
        raise OutOfRangeError(
            f"I2C address {address} (0x{int(address):x}) is outside 0...127 (7-bit): "
            "the PCA9685 with no address jumpers is 0x40 (64)"
        )
    return int(address)


def counts_block(counts: int) -> list[int]:
    """The 4 bytes of a channel: on at count 0, off at ``counts`` (``[0, 0, lo, hi]``)."""
    return [0x00, 0x00, counts & 0xFF, (counts >> 8) & 0x0F]


def _register_name(reg: int) -> str:
    if reg == MODE1:
        return "MODE1"
    if reg == MODE2:
        return "MODE2"
    if reg == PRESCALE:
        return "PRESCALE"
    if reg == ALL_LED_ON_L:
        return "ALL_LED_ON_L"
    if LED0_ON_L <= reg < LED0_ON_L + 4 * CHANNELS and (reg - LED0_ON_L) % 4 == 0:
        return f"LED{(reg - LED0_ON_L) // 4}_ON_L"
    return "?"


class PCA9685:
    """The PCA9685 PWM board at ``address`` on ``bus``.

    Call :meth:`start` first (sets the frame rate, wakes the board, switches every output
    off), then :meth:`set_counts` / :meth:`off` per channel. :meth:`all_off` is a stop and
    is never refused.

    As a context manager it always ends with every output off (a hobby servo without
    pulses stops driving): on normal exit, on an exception, and on SIGINT / SIGTERM /
    SIGHUP (a closed terminal). While inside the context (entered from the main thread)
    their handlers switch everything off, call the handler that was installed before (if it
    was a Python callable), then raise ``KeyboardInterrupt`` (SIGINT) or ``SystemExit(128 +
    signum)`` (143 for SIGTERM, 129 for SIGHUP). A signal that was ignored (``SIG_IGN``,
    e.g. SIGHUP under ``nohup``) stays ignored. The previous
    handlers are restored on exit. The bus is not closed: whoever opened it closes it.

    Example::

        with open_bus() as bus, PCA9685(bus) as board:
            board.start(50.0)
            board.set_counts(0, board.pulse_to_counts(1500.0))

    Args:
        bus: an ``smbus2.SMBus`` or anything with its methods (:class:`SMBusLike`).
        address: the 7-bit I2C address (0x40 with no jumpers).
        oscillator_hz: the board's oscillator (Hz), nominally 25 MHz; boards measure 24 to
            27 MHz, so calibrate per board for accurate pulse widths.
        sleep: waits the given seconds (the 500 us oscillator settle); injectable for tests.
        handle_signals: install the SIGINT / SIGTERM / SIGHUP handlers inside the context.

    Raises:
        OutOfRangeError: address outside 0...127, oscillator not finite and positive.
    """

    def __init__(
        self,
        bus: SMBusLike,
        address: int = 0x40,
        oscillator_hz: float = 25e6,
        *,
        sleep: Callable[[float], None] = time.sleep,
        handle_signals: bool = True,
    ) -> None:
        self.bus = bus
        self.address = _check_address(address)
        self.oscillator_hz = _finite_positive(
            oscillator_hz, "oscillator_hz", "Hz", "the PCA9685's oscillator is nominally 25e6"
        )
        self._sleep = sleep
        self._handle_signals = handle_signals
        self._prescale: int | None = None
        self._entered = False
        self._previous: dict[int, Any] = {}

    # ----------------------------------------------------------------------------- state

    @property
    def started(self) -> bool:
        """Whether :meth:`start` has set the frame rate."""
        return self._prescale is not None

    def _require_started(self, what: str) -> int:
        if self._prescale is None:
            raise NotStartedError(
                f"PCA9685 at 0x{self.address:02x}: {what} before start(): call "
                "start(frame_hz) first (it sets the frame rate and switches all outputs off)"
            )
        return self._prescale

    @property
    def prescale(self) -> int:
        """The PRESCALE value written by :meth:`start` (121 at 50 Hz)."""
        return self._require_started("prescale asked")

    @property
    def count_us(self) -> float:
        """One count (us): ``(prescale + 1) / oscillator_hz`` (4.88 us at 50 Hz, 25 MHz)."""
        return (self._require_started("count_us asked") + 1) / self.oscillator_hz * 1e6

    @property
    def frame_hz(self) -> float:
        """The actual frame rate (Hz): ``osc / (4096 (prescale + 1))`` (50.03 Hz at 50)."""
        return self.oscillator_hz / (COUNTS * (self._require_started("frame_hz asked") + 1))

    def pulse_to_counts(self, pulse_us: float) -> int:
        """The off count for a pulse width: ``round(pulse_us / count_us)`` in 0...4095.

        1500 us -> 307 counts (1498.16 us) at 50 Hz. Rounds halves away from zero.

        Raises:
            NotStartedError: before :meth:`start`.
            OutOfRangeError: a non-finite pulse width.
        """
        count_us = self.count_us
        if isinstance(pulse_us, bool) or not isinstance(pulse_us, numbers.Real) or not (
            math.isfinite(float(pulse_us))
        ):
            raise OutOfRangeError(f"pulse width must be a finite number in us, got {pulse_us!r}")
        return max(0, min(COUNTS - 1, round_half_away(float(pulse_us) / count_us)))

    def counts_to_us(self, counts: int) -> float:
        """The pulse width (us) of an off count: ``counts * count_us``."""
        return _check_counts(counts) * self.count_us

    # ----------------------------------------------------------------------------- writes

    def _fail(self, reg: int, data: Sequence[int], err: OSError) -> BusError:
        return BusError(
            f"I2C write to the PCA9685 at 0x{self.address:02x} failed (register "
            f"0x{reg:02x} {_register_name(reg)}, data [{' '.join(f'{b:02x}' for b in data)}]):"
            f" {err}. Check the wiring (SDA, SCL, GND, VCC), that the board is powered and "
            f"that {_i2cdetect(self.address)}"
        )

    def _write_byte(self, reg: int, value: int) -> None:
        try:
            self.bus.write_byte_data(self.address, reg, value)
        except OSError as err:
            raise self._fail(reg, [value], err) from err

    def _write_block(self, reg: int, data: list[int]) -> None:
        try:
            self.bus.write_i2c_block_data(self.address, reg, data)
        except OSError as err:
            raise self._fail(reg, data, err) from err

    def start(self, frequency_hz: float = 50.0, *, verify: bool = True) -> None:
        """Set the frame rate, wake the board and switch every output off.

        Writes, in order: ``{MODE1: SLEEP}``, ``{PRESCALE: p}``, ``{MODE2: OUTDRV}``,
        ``{MODE1: AI}`` (awake, auto-increment), waits 500 us for the oscillator, then
        ``{ALL_LED_ON_L: 00 00 00 10}`` (all full-off). At 50 Hz ``p`` = 121 (0x79).

        Args:
            frequency_hz: the frame rate (Hz), 50 for hobby servos.
            verify: read PRESCALE back afterwards (a read, not a write: the transcript is
                the same) and refuse a board that did not keep it.

        Raises:
            OutOfRangeError: zero, negative or non-finite frequency.
            BusError: an I2C transfer failed, or the prescale did not read back.
        """
        p = prescaler(frequency_hz, self.oscillator_hz)
        self._write_byte(MODE1, SLEEP)
        self._write_byte(PRESCALE, p)
        self._write_byte(MODE2, OUTDRV)
        self._write_byte(MODE1, AI)
        self._sleep(OSCILLATOR_SETTLE_S)
        self._write_block(ALL_LED_ON_L, list(OFF_BLOCK))
        if verify:
            try:
                back = self.bus.read_byte_data(self.address, PRESCALE)
            except OSError as err:
                raise BusError(
                    f"I2C read of PRESCALE from the PCA9685 at 0x{self.address:02x} failed: "
                    f"{err}. Check the wiring and power, and that {_i2cdetect(self.address)}"
                ) from err
            if back != p:
                raise BusError(
                    f"the PCA9685 at 0x{self.address:02x} reads back PRESCALE {back} after "
                    f"{p} was written: is 0x{self.address:02x} really a PCA9685? Check the "
                    f"address jumpers and that {_i2cdetect(self.address)}"
                )
        self._prescale = p
        log.info(
            "PCA9685 at 0x%02x: prescale %d, frame %.3f Hz, one count %.3f us",
            self.address, p, self.frame_hz, self.count_us,
        )

    def set_counts(self, channel: int, counts: int) -> None:
        """Switch ``channel`` on at count 0 and off at ``counts`` (one 4-byte block write).

        Channel 3 at 307 counts writes ``{0x12: 00 00 33 01}``.

        Raises:
            NotStartedError: before :meth:`start`.
            OutOfRangeError: channel outside 0...15, counts not an integer in 0...4095.
            BusError: the I2C write failed.
        """
        ch = _check_channel(channel)
        c = _check_counts(counts)
        self._require_started(f"set_counts({ch}, {c})")
        self._write_block(LED0_ON_L + 4 * ch, counts_block(c))

    def off(self, channel: int) -> None:
        """Switch ``channel`` fully off: ``{0x06 + 4 ch: 00 00 00 10}``.

        Raises:
            NotStartedError: before :meth:`start`.
            OutOfRangeError: channel outside 0...15.
            BusError: the I2C write failed.
        """
        ch = _check_channel(channel)
        self._require_started(f"off({ch})")
        self._write_block(LED0_ON_L + 4 * ch, list(OFF_BLOCK))

    def all_off(self) -> None:
        """Switch every output fully off: ``{0xFA: 00 00 00 10}`` (ALL_LED full-off).

        A stop is never refused, so this also works before :meth:`start` (it relies on
        auto-increment, which :meth:`start` sets and which stays set while the board is
        powered; a board fresh from power-on has every output off anyway).

        Raises:
            BusError: the I2C write failed.
        """
        self._write_block(ALL_LED_ON_L, list(OFF_BLOCK))

    # ----------------------------------------------------------------------------- context

    def __enter__(self) -> PCA9685:
        if self._entered:
            raise HardwareError(
                f"PCA9685 at 0x{self.address:02x}: context entered twice; use one `with`"
            )
        self._entered = True
        if self._handle_signals and threading.current_thread() is threading.main_thread():
            for sig in _STOP_SIGNALS:
                previous = signal.getsignal(sig)
                if previous == signal.SIG_IGN:
                    continue  # the process chose to ignore it; so do we
                signal.signal(sig, self._on_signal)
                self._previous[sig] = previous
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        try:
            self.all_off()
        except BusError as err:
            if exc is None:
                raise
            log.error("switching the PCA9685 outputs off failed: %s", err)
            exc.add_note(f"switching all PCA9685 outputs off failed too: {err}")
        finally:
            self._restore_signals()
            self._entered = False

    def _restore_signals(self) -> None:
        for sig, previous in self._previous.items():
            # None: the handler was not installed from Python; the default is the best guess
            signal.signal(sig, signal.SIG_DFL if previous is None else previous)
        self._previous = {}

    def _on_signal(self, signum: int, frame: FrameType | None) -> None:
        """Switch every output off, chain to the previous handler, then stop."""
        try:
            self.all_off()
        except Exception as err:  # a stop must still stop: report and go on
            log.error("switching the PCA9685 outputs off on signal %d failed: %s", signum, err)
        previous = self._previous.get(signum)
        if callable(previous):
            previous(signum, frame)  # default_int_handler raises KeyboardInterrupt here
        if signum == signal.SIGINT:
            raise KeyboardInterrupt
        raise SystemExit(128 + signum)


class RecordingBus:
    """A fake ``SMBus`` that records every write (dry runs and tests).

    Every successful write is appended to :attr:`writes` as
    ``{"addr": 64, "reg": 0, "data": [16]}`` (single-byte writes have a one-element
    ``data``). Reads are not recorded; with ``memory`` (the default) they return what was
    last written to the register (block writes fill consecutive registers, as with
    auto-increment; unwritten registers read 0).

    Args:
        fail_after: when set, the first ``fail_after`` writes succeed and the next one
            raises ``OSError(121, "Remote I/O error")`` (an I2C NAK), to test a bus lost
            half-way. With ``fail_count`` = None every later write fails too.
        fail_count: how many consecutive writes fail once failing starts (default 1; None:
            all of them).
        memory: keep written registers so reads return them.
    """

    def __init__(
        self,
        fail_after: int | None = None,
        *,
        fail_count: int | None = 1,
        memory: bool = True,
    ) -> None:
        self.writes: list[dict[str, Any]] = []
        self.fail_after = fail_after
        self.fail_count = fail_count
        self.memory = memory
        self.attempts = 0  # writes tried, including failed ones
        self.failures = 0
        self.closed = False
        self._registers: dict[tuple[int, int], int] = {}

    def _maybe_fail(self, addr: int, reg: int) -> None:
        self.attempts += 1
        if self.fail_after is None or self.attempts <= self.fail_after:
            return
        if self.fail_count is not None and self.failures >= self.fail_count:
            return
        self.failures += 1
        raise OSError(121, f"Remote I/O error (RecordingBus: write {self.attempts} to "
                           f"0x{addr:02x} register 0x{reg:02x} made to fail)")

    def _record(self, addr: int, reg: int, data: list[int]) -> None:
        for b in data:
            if not (isinstance(b, int) and 0 <= b <= 0xFF):
                raise ValueError(f"I2C data bytes must be ints 0...255, got {data!r}")
        self._maybe_fail(addr, reg)
        self.writes.append({"addr": int(addr), "reg": int(reg), "data": [int(b) for b in data]})
        if self.memory:
            for i, b in enumerate(data):
                self._registers[(addr, (reg + i) & 0xFF)] = b

    def write_byte_data(self, i2c_addr: int, register: int, value: int,
                        force: bool | None = None) -> None:
        """Record a single-register write."""
        self._record(i2c_addr, register, [value])

    def write_i2c_block_data(
        self, i2c_addr: int, register: int, data: Sequence[int], force: bool | None = None
    ) -> None:
        """Record a block write (one transfer)."""
        self._record(i2c_addr, register, list(data))

    def read_byte_data(self, i2c_addr: int, register: int, force: bool | None = None) -> int:
        """The last value written to the register (0 if never written or without memory)."""
        return self._registers.get((i2c_addr, register), 0) if self.memory else 0

    def close(self) -> None:
        """Mark the bus closed (writes are still recorded)."""
        self.closed = True

    def __enter__(self) -> RecordingBus:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def pairs(self) -> list[tuple[int, list[int]]]:
        """The writes as ``(register, data)`` pairs (address dropped)."""
        return [(w["reg"], list(w["data"])) for w in self.writes]

    def transcript_lines(self) -> list[str]:
        """One JSON object per write, ``{"addr": 64, "reg": 0, "data": [16]}``."""
        return [json.dumps(w) for w in self.writes]

    def transcript(self) -> str:
        """The JSON lines joined, each ending in a newline (the ``i2c.jsonl`` content)."""
        return "".join(line + "\n" for line in self.transcript_lines())


def open_bus(device: str = "/dev/i2c-1", address: int = 0x40) -> SMBusLike:
    """Open the Linux I2C device and check that the PCA9685 answers at ``address``.

    Args:
        device: the I2C device file (bus 1 on a Raspberry Pi: ``/dev/i2c-1``).
        address: the board's 7-bit address (0x40).

    Returns:
        An open ``smbus2.SMBus`` (close it, or use it as a context manager).

    Raises:
        OutOfRangeError: address outside 0...127.
        HardwareError: the device does not exist or cannot be opened, or no board answers
            at ``address`` (the message says what to check).
    """
    addr = _check_address(address)
    try:
        from smbus2 import SMBus
    except ImportError as err:  # pragma: no cover - smbus2 is a dependency
        raise HardwareError(
            f"smbus2 is not installed ({err}): pip install smbus2, or use dry_run=true"
        ) from err
    try:
        bus = SMBus(device)
    except FileNotFoundError:
        raise HardwareError(
            f"I2C device {device} does not exist: enable I2C (dtparam=i2c_arm=on in "
            "/boot/firmware/config.txt, then reboot) on the Raspberry Pi, pick the right "
            "device, or run without hardware with dry_run=true"
        ) from None
    except PermissionError:
        raise HardwareError(
            f"no permission to open I2C device {device}: add your user to the i2c group "
            "(sudo usermod -aG i2c $USER, then log in again), or use dry_run=true"
        ) from None
    except (OSError, TypeError) as err:
        raise HardwareError(
            f"cannot open I2C device {device}: {err}. Check the device name, or use "
            "dry_run=true"
        ) from None
    try:
        bus.read_byte_data(addr, MODE1)
    except OSError as err:
        bus.close()
        raise HardwareError(
            f"no PCA9685 answers at address 0x{addr:02x} on {device} ({err}): check the "
            "wiring (SDA to pin 3, SCL to pin 5, VCC to 3.3 V, GND), the address jumpers, "
            "and that `i2cdetect -y <bus>` lists it"
        ) from None
    return bus
