"""The PCA9685 driver: prescaler, exact register bytes, refusals and the safe exits.

Byte-exact expectations are the original's (docs/original.md, "6.2 The PCA9685 driver");
the transcript line format is the one other tools rely on (README, "The real arm").
Nothing here sleeps or touches real hardware: the oscillator wait is injected and the bus
is :class:`RecordingBus`.
"""

from __future__ import annotations

import json
import math
import os
import signal
import threading
from collections.abc import Iterator

import pytest
from hypothesis import given
from hypothesis import strategies as st

from tattotronix.errors import TattotronixError
from tattotronix.hardware.pca9685 import (
    LED0_ON_L,
    MODE1,
    PCA9685,
    PRESCALE,
    BusError,
    HardwareError,
    NotStartedError,
    OutOfRangeError,
    RecordingBus,
    open_bus,
    prescaler,
    round_half_away,
)

START = [
    (0x00, [0x10]),  # MODE1 SLEEP
    (0xFE, [0x79]),  # PRESCALE 121
    (0x01, [0x04]),  # MODE2 OUTDRV
    (0x00, [0x20]),  # MODE1 AI, awake
    (0xFA, [0x00, 0x00, 0x00, 0x10]),  # all off
]
ALL_OFF = (0xFA, [0x00, 0x00, 0x00, 0x10])


def no_sleep(_s: float) -> None:
    """The oscillator wait, skipped."""


def board(bus: RecordingBus | None = None, **kw: object) -> tuple[PCA9685, RecordingBus]:
    bus = bus if bus is not None else RecordingBus()
    return PCA9685(bus, sleep=no_sleep, **kw), bus  # type: ignore[arg-type]


def started(bus: RecordingBus | None = None) -> tuple[PCA9685, RecordingBus]:
    pwm, bus = board(bus)
    pwm.start(50.0)
    return pwm, bus


@pytest.fixture
def restore_signals() -> Iterator[None]:
    """Start the test with Python's own SIGINT/SIGTERM/SIGHUP dispositions (pytest run as
    a background job or under ``nohup`` inherits SIGINT or SIGHUP ignored, which the
    board rightly leaves alone), and put the handlers back whatever the test did."""
    saved = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)}
    signal.signal(signal.SIGINT, signal.default_int_handler)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    signal.signal(signal.SIGHUP, signal.SIG_DFL)
    yield
    for s, h in saved.items():
        signal.signal(s, h)


# ------------------------------------------------------------------------------- prescaler


@pytest.mark.parametrize(
    ("frequency_hz", "expected"), [(50.0, 121), (60.0, 101), (5000.0, 3), (1.0, 255)]
)
def test_prescaler_reference_values(frequency_hz: float, expected: int) -> None:
    assert prescaler(frequency_hz) == expected
    assert prescaler(frequency_hz, 25e6) == expected


def test_prescaler_uses_the_oscillator() -> None:
    # a board measured at 26 MHz: round(26e6 / 204800) - 1 = 126
    assert prescaler(50.0, 26e6) == 126


def test_round_half_away() -> None:
    assert [round_half_away(x) for x in (0.5, 1.5, 2.5, -0.5, -2.5, 2.4999)] == [
        1, 2, 3, -1, -3, 2,
    ]


@pytest.mark.parametrize("bad", [0.0, -50.0, math.nan, math.inf, -math.inf])
def test_prescaler_refuses_bad_frequency(bad: float) -> None:
    with pytest.raises(ValueError, match="frame rate") as info:
        prescaler(bad)
    assert isinstance(info.value, TattotronixError)
    assert repr(bad) in str(info.value) or str(bad) in str(info.value)


@pytest.mark.parametrize("bad", [0.0, -25e6, math.nan, math.inf])
def test_prescaler_refuses_bad_oscillator(bad: float) -> None:
    with pytest.raises(ValueError, match="oscillator_hz"):
        prescaler(50.0, bad)
    with pytest.raises(OutOfRangeError, match="oscillator_hz"):
        PCA9685(RecordingBus(), oscillator_hz=bad)


def test_prescaler_refuses_non_numbers() -> None:
    with pytest.raises(ValueError, match="'50'"):
        prescaler("50")  # type: ignore[arg-type]
    with pytest.raises(ValueError):
        prescaler(True)


# ------------------------------------------------------------------------------- bytes


def test_start_writes_exact_bytes_in_order() -> None:
    waits: list[tuple[float, int]] = []
    bus = RecordingBus()
    pwm = PCA9685(bus, sleep=lambda s: waits.append((s, len(bus.writes))))
    pwm.start(50.0)
    assert bus.pairs() == START
    assert all(w["addr"] == 0x40 for w in bus.writes)
    # the 500 us settle comes after waking (4 writes) and before the all-off
    assert waits == [(500e-6, 4)]
    assert pwm.prescale == 121
    assert pwm.count_us == pytest.approx(4.88)
    assert pwm.frame_hz == pytest.approx(25e6 / (4096 * 122))
    assert pwm.frame_hz == pytest.approx(50.03, abs=0.005)


def test_start_uses_single_byte_then_block_writes() -> None:
    calls: list[str] = []

    class Spy(RecordingBus):
        def write_byte_data(self, i2c_addr: int, register: int, value: int,
                            force: object = None) -> None:
            calls.append("byte")
            super().write_byte_data(i2c_addr, register, value)

        def write_i2c_block_data(self, i2c_addr: int, register: int, data: object,
                                 force: object = None) -> None:
            calls.append("block")
            super().write_i2c_block_data(i2c_addr, register, data)  # type: ignore[arg-type]

    pwm = PCA9685(Spy(), sleep=no_sleep)
    pwm.start(50.0)
    pwm.set_counts(0, 100)
    pwm.off(0)
    pwm.all_off()
    assert calls == ["byte"] * 4 + ["block"] * 4


def test_start_at_60_hz_writes_prescale_101() -> None:
    pwm, bus = board()
    pwm.start(60.0)
    assert bus.pairs()[1] == (PRESCALE, [101])


def test_start_reads_prescale_back() -> None:
    class Forgetful(RecordingBus):
        def read_byte_data(self, i2c_addr: int, register: int, force: object = None) -> int:
            return 0x1E  # the power-on prescale: the write did not stick

    pwm, bus = board(Forgetful())
    with pytest.raises(BusError, match="reads back PRESCALE 30 after 121"):
        pwm.start(50.0)
    assert not pwm.started
    # verification is only a read: the transcript is the same
    pwm2, bus2 = board(Forgetful())
    pwm2.start(50.0, verify=False)
    assert bus2.pairs() == START


def test_set_counts_channel_3_to_307() -> None:
    pwm, bus = started()
    pwm.set_counts(3, 307)
    assert bus.pairs()[-1] == (0x12, [0x00, 0x00, 0x33, 0x01])


def test_off_channel_15() -> None:
    pwm, bus = started()
    pwm.off(15)
    assert bus.pairs()[-1] == (0x42, [0x00, 0x00, 0x00, 0x10])


def test_all_off_bytes() -> None:
    pwm, bus = started()
    pwm.all_off()
    assert bus.pairs()[-1] == ALL_OFF


def test_pulse_to_counts() -> None:
    pwm, _ = started()
    assert pwm.pulse_to_counts(1500.0) == 307
    assert pwm.counts_to_us(307) == pytest.approx(1498.16)
    assert pwm.pulse_to_counts(0.0) == 0
    assert pwm.pulse_to_counts(-100.0) == 0
    assert pwm.pulse_to_counts(1e9) == 4095
    # a half count rounds away from zero
    assert pwm.pulse_to_counts(307.5 * pwm.count_us) == 308
    with pytest.raises(ValueError, match="pulse width"):
        pwm.pulse_to_counts(math.nan)


@pytest.mark.parametrize("channel", [16, -1, 100])
def test_channel_outside_board_refused(channel: int) -> None:
    pwm, bus = started()
    n = len(bus.writes)
    with pytest.raises(ValueError, match=f"channel {channel} does not exist"):
        pwm.set_counts(channel, 307)
    with pytest.raises(OutOfRangeError, match=f"channel {channel}"):
        pwm.off(channel)
    assert len(bus.writes) == n  # nothing written


@pytest.mark.parametrize("counts", [4096, -1, 10_000])
def test_counts_outside_frame_refused(counts: int) -> None:
    pwm, bus = started()
    with pytest.raises(ValueError, match=f"off count {counts} is outside 0...4095"):
        pwm.set_counts(0, counts)
    assert bus.pairs() == START


@pytest.mark.parametrize("counts", [307.0, "307", True, None])
def test_counts_must_be_an_int(counts: object) -> None:
    pwm, _ = started()
    with pytest.raises(ValueError, match="integer"):
        pwm.set_counts(0, counts)  # type: ignore[arg-type]


def test_numpy_integers_accepted() -> None:
    np = pytest.importorskip("numpy")
    pwm, bus = started()
    pwm.set_counts(np.int64(3), np.int32(307))
    assert bus.pairs()[-1] == (0x12, [0x00, 0x00, 0x33, 0x01])


@pytest.mark.parametrize("address", [128, -1, 0x80, True])
def test_address_must_be_7_bit(address: int) -> None:
    with pytest.raises(ValueError, match="address"):
        PCA9685(RecordingBus(), address=address)


def test_other_address_is_used() -> None:
    pwm, bus = board(address=0x41)
    pwm.start(50.0)
    assert {w["addr"] for w in bus.writes} == {0x41}


def test_calls_before_start_are_refused() -> None:
    pwm, bus = board()
    with pytest.raises(NotStartedError, match=r"before start\(\)"):
        pwm.set_counts(0, 307)
    with pytest.raises(NotStartedError, match="0x40"):
        pwm.off(0)
    with pytest.raises(NotStartedError):
        _ = pwm.count_us
    with pytest.raises(NotStartedError):
        pwm.pulse_to_counts(1500.0)
    assert bus.writes == []
    # a stop is never refused
    pwm.all_off()
    assert bus.pairs() == [ALL_OFF]


@given(channel=st.integers(0, 15), counts=st.integers(0, 4095))
def test_written_block_decodes_back(channel: int, counts: int) -> None:
    pwm, bus = started()
    pwm.set_counts(channel, counts)
    w = bus.writes[-1]
    assert w["addr"] == 0x40
    assert (w["reg"] - LED0_ON_L) % 4 == 0
    on_l, on_h, off_l, off_h = w["data"]
    assert (on_l, on_h) == (0, 0)
    assert off_h & 0x10 == 0  # never the full-off bit
    assert ((w["reg"] - LED0_ON_L) // 4, off_l | (off_h << 8)) == (channel, counts)


# ------------------------------------------------------------------------------- transcript


def test_transcript_line_format() -> None:
    pwm, bus = board()
    pwm.start(50.0)
    lines = bus.transcript_lines()
    assert lines[0] == '{"addr": 64, "reg": 0, "data": [16]}'
    assert lines[-1] == '{"addr": 64, "reg": 250, "data": [0, 0, 0, 16]}'
    assert [json.loads(x) for x in lines] == bus.writes
    assert bus.transcript() == "".join(x + "\n" for x in lines)


def test_reads_are_not_recorded_and_return_writes() -> None:
    pwm, bus = started()
    n = len(bus.writes)
    assert bus.read_byte_data(0x40, PRESCALE) == 121
    assert bus.read_byte_data(0x40, MODE1) == 0x20
    pwm.set_counts(3, 307)
    assert [bus.read_byte_data(0x40, 0x12 + i) for i in range(4)] == [0, 0, 0x33, 0x01]
    assert len(bus.writes) == n + 1
    assert RecordingBus(memory=False).read_byte_data(0x40, MODE1) == 0


# ------------------------------------------------------------------------------- safe exits


def test_context_ends_all_off_on_normal_exit() -> None:
    bus = RecordingBus()
    with PCA9685(bus, sleep=no_sleep) as pwm:
        pwm.start(50.0)
        pwm.set_counts(0, 307)
    assert bus.pairs()[-1] == ALL_OFF
    assert not bus.closed  # the bus belongs to whoever opened it


def test_context_ends_all_off_on_exception() -> None:
    bus = RecordingBus()
    with pytest.raises(RuntimeError, match="boom"), PCA9685(bus, sleep=no_sleep) as pwm:
        pwm.start(50.0)
        pwm.set_counts(0, 307)
        raise RuntimeError("boom")
    assert bus.pairs()[-1] == ALL_OFF
    assert bus.pairs()[-2] == (0x06, [0, 0, 0x33, 0x01])


def test_context_restores_handlers(restore_signals: None) -> None:
    def mine(signum: int, frame: object) -> None:  # pragma: no cover - never called
        pass

    signal.signal(signal.SIGTERM, mine)
    before_int = signal.getsignal(signal.SIGINT)
    pwm, _ = board()
    with pwm:
        assert signal.getsignal(signal.SIGINT) == pwm._on_signal
        assert signal.getsignal(signal.SIGTERM) == pwm._on_signal
        assert signal.getsignal(signal.SIGHUP) == pwm._on_signal
    assert signal.getsignal(signal.SIGINT) is before_int
    assert signal.getsignal(signal.SIGTERM) is mine


def test_sigint_switches_off_and_raises_keyboard_interrupt(restore_signals: None) -> None:
    signal.signal(signal.SIGINT, signal.default_int_handler)
    bus = RecordingBus()
    pwm = PCA9685(bus, sleep=no_sleep)
    with pytest.raises(KeyboardInterrupt), pwm:
        pwm.start(50.0)
        pwm.set_counts(0, 307)
        n = len(bus.writes)
        signal.raise_signal(signal.SIGINT)
        pytest.fail("KeyboardInterrupt did not propagate")  # pragma: no cover
    # the handler switched everything off at once, and the exit did again
    assert bus.pairs()[n] == ALL_OFF
    assert bus.pairs()[-1] == ALL_OFF
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_sigint_chains_to_the_previous_python_handler(restore_signals: None) -> None:
    seen: list[int] = []
    signal.signal(signal.SIGINT, lambda signum, frame: seen.append(signum))
    bus = RecordingBus()
    pwm = PCA9685(bus, sleep=no_sleep)
    with pytest.raises(KeyboardInterrupt), pwm:
        pwm.start(50.0)
        os.kill(os.getpid(), signal.SIGINT)
        pytest.fail("KeyboardInterrupt did not propagate")  # pragma: no cover
    assert seen == [signal.SIGINT]
    assert bus.pairs()[-1] == ALL_OFF


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGHUP])
def test_sigterm_and_sighup_switch_off_and_exit_128_plus(restore_signals: None,
                                                         sig: signal.Signals) -> None:
    """SIGTERM (143) and a hang-up (129: the terminal closed) stop alike."""
    signal.signal(sig, signal.SIG_DFL)
    bus = RecordingBus()
    pwm = PCA9685(bus, sleep=no_sleep)
    with pytest.raises(SystemExit) as info, pwm:
        pwm.start(50.0)
        pwm.set_counts(1, 320)
        n = len(bus.writes)
        signal.raise_signal(sig)
        pytest.fail("SystemExit did not propagate")  # pragma: no cover
    assert info.value.code == 128 + sig
    assert bus.pairs()[n] == ALL_OFF
    assert signal.getsignal(sig) == signal.SIG_DFL


def test_ignored_signal_stays_ignored(restore_signals: None) -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    pwm, bus = board()
    with pwm:
        pwm.start(50.0)
        assert signal.getsignal(signal.SIGINT) == signal.SIG_IGN
        signal.raise_signal(signal.SIGINT)  # ignored: nothing happens
    assert signal.getsignal(signal.SIGINT) == signal.SIG_IGN
    assert bus.pairs()[-1] == ALL_OFF


def test_no_handlers_from_another_thread(restore_signals: None) -> None:
    before = signal.getsignal(signal.SIGINT)
    result: list[object] = []
    bus = RecordingBus()

    def run() -> None:
        with PCA9685(bus, sleep=no_sleep) as pwm:
            pwm.start(50.0)
            result.append(signal.getsignal(signal.SIGINT))

    t = threading.Thread(target=run)
    t.start()
    t.join()
    assert result == [before]
    assert bus.pairs()[-1] == ALL_OFF


def test_handle_signals_false_installs_nothing(restore_signals: None) -> None:
    before = signal.getsignal(signal.SIGINT)
    with PCA9685(RecordingBus(), sleep=no_sleep, handle_signals=False):
        assert signal.getsignal(signal.SIGINT) is before


def test_context_cannot_be_entered_twice() -> None:
    pwm, _ = board()
    with pwm, pytest.raises(HardwareError, match="entered twice"), pwm:
        pass  # pragma: no cover


# ------------------------------------------------------------------------------- bus errors


def test_i2c_error_half_way_names_the_board_and_still_switches_off() -> None:
    bus = RecordingBus(fail_after=6)  # start's 5 writes and one channel succeed
    with pytest.raises(BusError) as info, PCA9685(bus, sleep=no_sleep) as pwm:
        pwm.start(50.0)
        pwm.set_counts(0, 307)
        pwm.set_counts(3, 307)  # the 7th write fails
    msg = str(info.value)
    assert "0x40" in msg
    assert "0x12" in msg and "LED3_ON_L" in msg
    assert "Remote I/O error" in msg
    assert "that `i2cdetect -y 1` lists the board at 0x40" in msg and "wiring" in msg
    assert isinstance(info.value, TattotronixError)
    assert isinstance(info.value.__cause__, OSError)
    assert bus.attempts == 8  # the failed write, then the exit's all-off
    assert bus.pairs()[-1] == ALL_OFF


def test_i2c_error_during_start() -> None:
    bus = RecordingBus(fail_after=1)
    pwm = PCA9685(bus, sleep=no_sleep)
    with pytest.raises(BusError, match=r"0x40 failed \(register 0xfe PRESCALE"):
        pwm.start(50.0)
    assert not pwm.started


def test_dead_bus_keeps_the_original_error() -> None:
    bus = RecordingBus(fail_after=5, fail_count=None)  # every write after start fails
    with pytest.raises(BusError) as info, PCA9685(bus, sleep=no_sleep) as pwm:
        pwm.start(50.0)
        pwm.set_counts(0, 307)
    assert "LED0_ON_L" in str(info.value)
    notes = getattr(info.value, "__notes__", [])
    assert any("switching all PCA9685 outputs off failed too" in n for n in notes)
    assert bus.attempts == 7  # the exit still tried the all-off


def test_exit_error_raised_when_nothing_else_failed() -> None:
    bus = RecordingBus(fail_after=5)
    with pytest.raises(BusError, match="ALL_LED_ON_L"), PCA9685(bus, sleep=no_sleep) as pwm:
        pwm.start(50.0)


# ------------------------------------------------------------------------------- open_bus


def test_open_bus_missing_device() -> None:
    with pytest.raises(TattotronixError) as info:
        open_bus("/dev/i2c-99")
    msg = str(info.value)
    assert "/dev/i2c-99" in msg
    assert "dtparam=i2c_arm=on" in msg
    assert "dry_run=true" in msg
    assert info.value.__cause__ is None and info.value.__suppress_context__


def test_open_bus_board_not_answering(monkeypatch: pytest.MonkeyPatch) -> None:
    import smbus2

    closed: list[bool] = []

    class Silent:
        def __init__(self, device: object) -> None:
            assert device == "/dev/i2c-1"

        def read_byte_data(self, addr: int, reg: int) -> int:
            raise OSError(121, "Remote I/O error")

        def close(self) -> None:
            closed.append(True)

    monkeypatch.setattr(smbus2, "SMBus", Silent)
    with pytest.raises(TattotronixError) as info:
        open_bus("/dev/i2c-1", 0x40)
    msg = str(info.value)
    assert "0x40" in msg and "/dev/i2c-1" in msg and "Remote I/O error" in msg
    assert closed == [True]


def test_open_bus_answering(monkeypatch: pytest.MonkeyPatch) -> None:
    import smbus2

    class Answering(RecordingBus):
        def __init__(self, device: object) -> None:
            super().__init__()

    monkeypatch.setattr(smbus2, "SMBus", Answering)
    bus = open_bus("/dev/i2c-1", 0x40)
    assert isinstance(bus, Answering) and bus.writes == []


@pytest.mark.parametrize("address", [128, -1])
def test_open_bus_address_range(address: int) -> None:
    with pytest.raises(ValueError, match="0...127"):
        open_bus("/dev/i2c-99", address)
