"""Servo calibration: the pulse mapping, the mirrored shoulder, validation and counts.

The mapping is the original's (docs/original.md, "6.3 Pulse mapping"). Stated tolerances:
pulse widths are compared to ``1e-9`` us (plain arithmetic); a count's width ``c *
count_us`` is checked against the limits with ``1e-9`` us of float slack, the same slack
the library allows.
"""

from __future__ import annotations

import copy
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from omegaconf import OmegaConf

from tattotronix.errors import TattotronixError
from tattotronix.hardware.pca9685 import PCA9685, RecordingBus
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

COUNT_US = 122 / 25e6 * 1e6  # one count at 50 Hz, 25 MHz (4.88 us)
TOL_US = 1e-9


def mapping() -> dict[str, Any]:
    return copy.deepcopy(default_calibration_mapping())


def problems_of(data: Any, joint_names: tuple[str, ...] = DEFAULT_JOINT_NAMES) -> list[str]:
    with pytest.raises(CalibrationError) as info:
        Calibration.from_mapping(data, joint_names)
    assert isinstance(info.value, TattotronixError)
    return info.value.problems


def only_problem(data: Any) -> str:
    found = problems_of(data)
    assert len(found) == 1, found
    return found[0]


# ------------------------------------------------------------------------------- mapping


def test_reference_mapping_example() -> None:
    s = ServoChannel(channel=0, zero_us=1450.0, us_per_rad=-600.0, min_us=500.0, max_us=2500.0)
    assert s.pulse_us(0.5) == pytest.approx(1150.0, abs=TOL_US)
    assert s.pulse_us(-10.0) == 2500.0
    assert s.pulse_us(10.0) == 500.0
    assert s.pulse_us(math.inf) == 500.0
    assert s.angle(1150.0) == pytest.approx(0.5)
    assert s.angle(s.pulse_us(0.3)) == pytest.approx(0.3)
    with pytest.raises(ValueError, match="NaN"):
        s.pulse_us(math.nan)


def test_mirrored_shoulder_moves_opposite() -> None:
    shoulder = DEFAULT_CALIBRATION.joint("joint_2")
    assert shoulder.channels() == (1, 2)
    pulses = shoulder.pulses_us(0.1)
    assert pulses[1] == pytest.approx(1500.0 + 63.662, abs=TOL_US)
    assert pulses[2] == pytest.approx(1500.0 - 63.662, abs=TOL_US)
    assert pulses[1] - 1500.0 == pytest.approx(1500.0 - pulses[2])
    # both clamp to the shared limits, at opposite ends
    assert shoulder.pulses_us(10.0) == {1: 2500.0, 2: 500.0}
    counts = DEFAULT_CALIBRATION.counts([0.0, 0.1, 0.0, 0.0, 0.0], COUNT_US)
    assert counts[1] > 307 > counts[2]
    assert counts[1] - 307 == 307 - counts[2]


def test_default_calibration_validates_and_matches_the_catalogue() -> None:
    cal = default_calibration()
    assert cal == DEFAULT_CALIBRATION
    assert cal.joint_names == DEFAULT_JOINT_NAMES
    assert cal.channels() == (0, 1, 2, 3, 4, 5)
    assert cal.tool_channel == 6
    assert (cal.address, cal.device, cal.frame_hz, cal.oscillator_hz) == (
        0x40, "/dev/i2c-1", 50.0, 25e6,
    )
    for j in cal.joints:
        assert (j.a.zero_us, j.a.us_per_rad, j.a.min_us, j.a.max_us) == (
            1500.0, 636.62, 500.0, 2500.0,
        )
    b = cal.joint("joint_2").b
    assert b is not None and (b.channel, b.zero_us, b.us_per_rad) == (2, 1500.0, -636.62)
    assert all(cal.joint(n).b is None for n in ("joint_1", "joint_3", "joint_4", "joint_5"))
    # round trip through the file layout
    assert Calibration.from_mapping(cal.to_mapping()) == cal


def test_zero_pose_is_307_counts_everywhere() -> None:
    pwm = PCA9685(RecordingBus(), sleep=lambda s: None)
    pwm.start(50.0)
    assert DEFAULT_CALIBRATION.counts(np.zeros(5), pwm.count_us) == dict.fromkeys(range(6), 307)
    assert DEFAULT_CALIBRATION.pulses_us([0.0] * 5) == dict.fromkeys(range(6), 1500.0)
    echo = DEFAULT_CALIBRATION.positions(dict.fromkeys(range(6), 307), pwm.count_us)
    assert echo == pytest.approx(np.full(5, (1498.16 - 1500.0) / 636.62), abs=1e-9)


def test_counts_refuses_bad_input() -> None:
    with pytest.raises(ValueError, match="expected 5 joint angles"):
        DEFAULT_CALIBRATION.counts([0.0] * 4, COUNT_US)
    with pytest.raises(ValueError, match="joint_3: commanded angle is NaN"):
        DEFAULT_CALIBRATION.counts([0.0, 0.0, math.nan, 0.0, 0.0], COUNT_US)
    with pytest.raises(ValueError, match="count_us"):
        DEFAULT_CALIBRATION.counts([0.0] * 5, 0.0)


def test_counts_step_inward_when_rounding_leaves_the_limits() -> None:
    # limits that are not count multiples: 500.0 / 4.88 = 102.46 -> 102 = 497.76 us (< min)
    s = ServoChannel(0, 1500.0, 636.62, 500.0, 2500.0)
    assert s.counts(-10.0, COUNT_US) == 103  # 502.64 us
    assert s.counts(10.0, COUNT_US) == 512  # 2498.56 us (512.3 rounds to 512, inside)
    tight = ServoChannel(0, 1500.0, 636.62, 1499.0, 1502.0)  # 307.17 ... 307.79 counts
    with pytest.raises(CalibrationError, match="no PCA9685 count"):
        tight.counts(0.0, COUNT_US)


@given(
    q=st.lists(
        st.one_of(
            st.floats(-4.0, 4.0),
            st.floats(-1e300, 1e300),
            st.sampled_from([math.inf, -math.inf, 0.0, 1.5707963, -1.5707963]),
        ),
        min_size=5,
        max_size=5,
    ),
    osc=st.floats(23e6, 27e6),
)
def test_counts_never_leave_the_limits(q: list[float], osc: float) -> None:
    count_us = (121 + 1) / osc * 1e6
    counts = DEFAULT_CALIBRATION.counts(q, count_us)
    assert set(counts) == set(DEFAULT_CALIBRATION.channels())
    for j in DEFAULT_CALIBRATION.joints:
        for s in j.servos():
            c = counts[s.channel]
            assert isinstance(c, int) and 0 <= c <= 4095
            assert s.min_us - TOL_US <= c * count_us <= s.max_us + TOL_US
            # and it is the nearest count to the clamped pulse unless that one was outside
            assert abs(c * count_us - s.pulse_us(q[DEFAULT_CALIBRATION.joints.index(j)])) <= (
                count_us + TOL_US
            )


def _fitted(cal: Calibration) -> Calibration:
    """``cal`` with a measured pulse map (a bent servo's) on every servo of joint 2."""
    from dataclasses import replace

    from tattotronix.hardware.servos import PulseFit

    widths = np.linspace(600.0, 2400.0, 9)
    deg = np.degrees((widths - 1500.0) / 636.62) + 3.0 * np.sin(np.pi * (widths - 600) / 1800)
    fit = PulseFit(tuple(zip(widths.tolist(), deg.tolist(), strict=True)), 3)
    j2 = cal.joint("joint_2")
    joints = tuple(replace(j, a=replace(j.a, fit=fit),
                           b=None if j.b is None else replace(j.b, fit=fit))
                   if j is j2 else j for j in cal.joints)
    return replace(cal, joints=joints)


@given(
    q=st.lists(st.lists(st.one_of(st.floats(-4.0, 4.0), st.floats(-1e300, 1e300),
                                  st.sampled_from([math.inf, -math.inf, 0.0, 1.5707963])),
                        min_size=5, max_size=5), min_size=1, max_size=40),
    osc=st.floats(23e6, 27e6),
    fitted=st.booleans(),
)
def test_a_whole_program_counts_as_frame_by_frame(q: list[list[float]], osc: float,
                                                  fitted: bool) -> None:
    """``count_table`` (a program's counts at once) is ``counts`` row by row, exactly."""
    cal = _fitted(DEFAULT_CALIBRATION) if fitted else DEFAULT_CALIBRATION
    count_us = (121 + 1) / osc * 1e6
    table = cal.count_table(np.array(q), count_us)
    rows = [[cal.counts(row, count_us)[ch] for ch in cal.channels()] for row in q]
    assert table.dtype == np.int64 and table.tolist() == rows


def test_a_whole_program_refuses_as_a_frame_does() -> None:
    q = np.zeros((3, 5))
    q[2, 2] = math.nan
    with pytest.raises(ValueError, match="joint_3: commanded angle is NaN"):
        DEFAULT_CALIBRATION.count_table(q, COUNT_US)
    with pytest.raises(ValueError, match="expected 5 joint angles"):
        DEFAULT_CALIBRATION.count_table(np.zeros((3, 4)), COUNT_US)
    with pytest.raises(ValueError, match="count_us"):
        DEFAULT_CALIBRATION.count_table(np.zeros((3, 5)), 0.0)
    tight = ServoChannel(0, 1500.0, 636.62, 1499.0, 1502.0)
    with pytest.raises(CalibrationError, match="no PCA9685 count"):
        tight.count_array(np.zeros(4), COUNT_US)


# ------------------------------------------------------------------------------- validation


def test_channel_used_twice_names_both_users() -> None:
    data = mapping()
    data["joints"]["joint_3"]["channel"] = 2
    msg = only_problem(data)
    assert "channel 2 is used twice" in msg
    assert "joint_2.channel_b" in msg and "joint_3.channel" in msg


def test_tool_channel_clash() -> None:
    data = mapping()
    data["tool"]["channel"] = 5
    msg = only_problem(data)
    assert "joint_5.channel" in msg and "tool.channel" in msg


@pytest.mark.parametrize(
    ("joint", "key", "value", "expected"),
    [
        ("joint_1", "channel", 16, "joint_1.channel: channel 16 does not exist"),
        ("joint_4", "channel", -1, "joint_4.channel: channel -1 does not exist"),
        ("joint_2", "channel_b", 99, "joint_2.channel_b: channel 99 does not exist"),
        ("joint_3", "min_us", 2500, "joint_3.min_us/max_us: min_us 2500"),
        ("joint_3", "max_us", 400, "joint_3.min_us/max_us: min_us 500"),
        ("joint_1", "zero_us", 2600, "joint_1.zero_us: 2600"),
        ("joint_2", "zero_us_b", 400, "joint_2.zero_us_b: 400 is outside [min_us, max_us]"),
        ("joint_5", "us_per_rad", 0, "joint_5.us_per_rad: 0 must be finite and non-zero"),
        ("joint_2", "us_per_rad_b", 0.0, "joint_2.us_per_rad_b: 0 must be finite"),
        ("joint_4", "us_per_rad", math.inf, "joint_4.us_per_rad: inf is not finite"),
        ("joint_4", "us_per_rad", math.nan, "joint_4.us_per_rad: nan is not finite"),
        ("joint_1", "zero_us", "15OO", "joint_1.zero_us: '15OO' is not a number"),
        ("joint_2", "max_us", "12abc", "joint_2.max_us: '12abc' is not a number"),
        ("joint_3", "min_us", True, "joint_3.min_us: True is not a number"),
        ("joint_1", "channel", "zero", "joint_1.channel: 'zero' is not an integer"),
        ("joint_1", "channel", 1.5, "joint_1.channel: 1.5 is not a whole number"),
        ("joint_1", "zero_us", [1500], "joint_1.zero_us: [1500] is not a number"),
        ("joint_1", "max_us", 9000, "joint_1.max_us: 9000 us is above 2600 us, the widest"),
        ("joint_4", "min_us", 100, "joint_4.min_us: 100 us is below 400 us, the narrowest"),
    ],
)
def test_each_problem_names_joint_and_key(joint: str, key: str, value: Any,
                                          expected: str) -> None:
    data = mapping()
    data["joints"][joint][key] = value
    found = problems_of(data)
    assert any(expected in p for p in found), found


def test_limits_stay_within_what_a_hobby_servo_accepts() -> None:
    """400...2600 us, the widths stages/servo_pulse.py holds: the calibration's limits may
    reach them but not go past, and each one beyond is named with its joint and key."""
    from tattotronix.hardware.pulse import MAX_US, MIN_US

    data = mapping()
    data["joints"]["joint_3"].update(min_us=MIN_US, max_us=MAX_US)
    Calibration.from_mapping(data)
    data["joints"]["joint_3"].update(min_us=MIN_US - 1, max_us=MAX_US + 1)
    found = problems_of(data)
    assert [p.split(":")[0] for p in found] == ["joint_3.min_us", "joint_3.max_us"]
    with pytest.raises(CalibrationError, match="max_us: 2700 us is above 2600"):
        ServoChannel(0, 1500.0, 636.62, 500.0, 2700.0)


def test_min_us_must_be_positive() -> None:
    data = mapping()
    data["joints"]["joint_1"]["min_us"] = 0
    data["joints"]["joint_1"]["zero_us"] = 0
    msg = only_problem(data)
    assert msg.startswith("joint_1.min_us: 0 must be above 0 us")


def test_missing_key() -> None:
    data = mapping()
    del data["joints"]["joint_4"]["zero_us"]
    assert only_problem(data).startswith("joint_4.zero_us: missing")


def test_incomplete_second_servo() -> None:
    data = mapping()
    del data["joints"]["joint_2"]["us_per_rad_b"]
    assert "joint_2.us_per_rad_b: missing" in only_problem(data)
    data = mapping()
    data["joints"]["joint_1"]["channel_b"] = 7
    found = problems_of(data)
    assert any("joint_1.zero_us_b: missing" in p for p in found)
    assert any("joint_1.us_per_rad_b: missing" in p for p in found)


def test_unknown_key_suggests_the_right_one() -> None:
    data = mapping()
    data["joints"]["joint_5"]["zero_usec"] = 1500
    msg = only_problem(data)
    assert msg.startswith("joint_5.zero_usec: unknown key")
    assert "did you mean 'zero_us'" in msg


def test_unknown_top_level_and_tool_keys() -> None:
    data = mapping()
    data["frame_rate_hz"] = 50
    data["tool"]["stop_us"] = 1500
    found = problems_of(data)
    assert any(p.startswith("frame_rate_hz: unknown key") and "frame_hz" in p for p in found)
    assert any(p.startswith("tool.stop_us: unknown key") for p in found)


def test_missing_and_unknown_joints() -> None:
    data = mapping()
    del data["joints"]["joint_3"]
    data["joints"]["joint_6"] = {"channel": 7, "zero_us": 1500, "us_per_rad": 636.62,
                                 "min_us": 500, "max_us": 2500}
    found = problems_of(data)
    assert any(p.startswith("joints.joint_3: missing") for p in found)
    assert any(p.startswith("joints.joint_6: unknown joint") for p in found)


def test_joint_entry_and_file_shape() -> None:
    data = mapping()
    data["joints"]["joint_1"] = 1500
    assert only_problem(data).startswith("joints.joint_1: expected a mapping")
    assert problems_of([1, 2])[0].startswith("expected a mapping")
    del data["joints"]
    assert only_problem(data).startswith("joints: missing")


def test_board_settings() -> None:
    data = mapping()
    data.update(address=0x80, frame_hz=0, oscillator_hz="25MHz", device="")
    found = problems_of(data)
    assert any(p.startswith("address: 128 is outside 0...127") for p in found)
    assert any(p.startswith("frame_hz: 0") for p in found)
    assert any(p.startswith("oscillator_hz: '25MHz' is not a number") for p in found)
    assert any(p.startswith("device: ''") for p in found)
    data = mapping()
    data["frame_hz"] = 2000.0  # beyond prescale 3 at 25 MHz (1526 Hz)
    assert "outside what the PCA9685 can make" in only_problem(data)
    data["frame_hz"] = 450.0  # a 2222 us frame cannot hold a 2500 us pulse
    assert "too short for the widest pulse" in only_problem(data)


def test_numbers_as_strings_and_hex_address() -> None:
    data = mapping()
    data["address"] = "0x40"
    data["oscillator_hz"] = "25.0e6"
    data["joints"]["joint_1"]["zero_us"] = " 1500 "
    data["joints"]["joint_1"]["channel"] = 0.0
    cal = Calibration.from_mapping(data)
    assert cal.address == 64 and cal.oscillator_hz == 25e6
    assert cal.joint("joint_1").a.zero_us == 1500.0 and cal.joint("joint_1").a.channel == 0


def test_several_problems_reported_at_once() -> None:
    data = mapping()
    data["joints"]["joint_1"]["zero_us"] = "15OO"
    data["joints"]["joint_1"]["min_us"] = 3000  # >= max_us, in the same joint
    data["joints"]["joint_2"]["us_per_rad_b"] = 0
    data["joints"]["joint_3"]["channel"] = 16
    data["joints"]["joint_4"]["channel"] = 5  # clashes with joint_5
    data["joints"]["joint_5"]["max_ms"] = 2.5
    del data["joints"]["joint_5"]["min_us"]
    with pytest.raises(CalibrationError) as info:
        Calibration.from_mapping(data, DEFAULT_JOINT_NAMES, source="servo calibration x.yaml")
    found = info.value.problems
    expected = [
        "joint_1.zero_us: '15OO'",
        "joint_1.min_us/max_us",
        "joint_2.us_per_rad_b",
        "joint_3.channel: channel 16",
        "channel 5 is used twice, by joint_4.channel and joint_5.channel",
        "joint_5.max_ms: unknown key",
        "joint_5.min_us: missing",
    ]
    for e in expected:
        assert sum(e in p for p in found) == 1, (e, found)
    assert len(found) == len(expected)
    msg = str(info.value)
    assert msg.startswith(f"servo calibration x.yaml: {len(expected)} problems:")
    assert all(e in msg for e in expected)


def test_omegaconf_dictconfig_accepted() -> None:
    cfg = OmegaConf.create(mapping())
    assert Calibration.from_mapping(cfg) == DEFAULT_CALIBRATION


def test_direct_construction_is_validated() -> None:
    with pytest.raises(CalibrationError, match="channel 16 does not exist"):
        ServoChannel(16, 1500.0, 636.62, 500.0, 2500.0)
    with pytest.raises(CalibrationError, match="must be finite and non-zero"):
        ServoChannel(0, 1500.0, 0.0, 500.0, 2500.0)
    a = ServoChannel(1, 1500.0, 636.62, 500.0, 2500.0)
    with pytest.raises(CalibrationError, match="share min_us / max_us"):
        JointServo("joint_2", a, ServoChannel(2, 1500.0, -636.62, 600.0, 2500.0))
    with pytest.raises(CalibrationError, match="channel 1 is used twice"):
        JointServo("joint_2", a, ServoChannel(1, 1500.0, -636.62, 500.0, 2500.0))
    with pytest.raises(CalibrationError, match="channel 1 is used twice"):
        Calibration((JointServo("joint_1", a), JointServo("joint_2", a)))
    with pytest.raises(CalibrationError, match="address"):
        Calibration((JointServo("joint_1", a),), address=200)


# ------------------------------------------------------------------------------- files


def test_load_calibration_file(tmp_path: Path) -> None:
    path = tmp_path / "servo_calibration.yaml"
    path.write_text(
        """\
device: /dev/i2c-1
address: 0x40
frame_hz: 50.0
oscillator_hz: 25.0e6
joints:
  joint_1: {channel: 0, zero_us: 1500, us_per_rad: 636.62, min_us: 500, max_us: 2500}
  joint_2: {channel: 1, zero_us: 1500, us_per_rad: 636.62, min_us: 500, max_us: 2500,
            channel_b: 2, zero_us_b: 1500, us_per_rad_b: -636.62}
  joint_3: {channel: 3, zero_us: 1500, us_per_rad: 636.62, min_us: 500, max_us: 2500}
  joint_4: {channel: 4, zero_us: 1500, us_per_rad: 636.62, min_us: 500, max_us: 2500}
  joint_5: {channel: 5, zero_us: 1500, us_per_rad: 636.62, min_us: 500, max_us: 2500}
tool: {channel: 6}
"""
    )
    assert load_calibration(path) == DEFAULT_CALIBRATION


def test_load_calibration_problems_name_the_file(tmp_path: Path) -> None:
    path = tmp_path / "cal.yaml"
    path.write_text("joints:\n  joint_1: {channel: 0, zero_us: 15OO}\n")
    with pytest.raises(CalibrationError) as info:
        load_calibration(path)
    msg = str(info.value)
    assert str(path) in msg and "joint_1.zero_us: '15OO' is not a number" in msg
    assert "joints.joint_2: missing" in msg


def test_load_calibration_missing_file(tmp_path: Path) -> None:
    path = tmp_path / "nope.yaml"
    with pytest.raises(CalibrationError, match=r"(?s)nope\.yaml.*file not found"):
        load_calibration(path)


def test_load_calibration_yaml_syntax_error(tmp_path: Path) -> None:
    path = tmp_path / "broken.yaml"
    path.write_text("joints:\n  joint_1: {channel: 0, zero_us: 1500\n")
    with pytest.raises(CalibrationError, match=r"(?s)broken\.yaml.*not valid YAML.*line"):
        load_calibration(path)


def test_load_calibration_not_a_mapping(tmp_path: Path) -> None:
    path = tmp_path / "list.yaml"
    path.write_text("- 1\n- 2\n")
    with pytest.raises(CalibrationError, match=r"(?s)list\.yaml.*expected a mapping"):
        load_calibration(path)
