"""The real-arm backend: servo program, dry-run draws, faults, pause and resume."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from tattotronix.config.params import compose_settings
from tattotronix.errors import TattotronixError
from tattotronix.hardware import PCA9685, RecordingBus, default_calibration
from tattotronix.hardware.arm import ArmState, ramp
from tattotronix.hardware.program import compile_program, count_period_us
from tattotronix.hardware.pulse import hold_pulses
from tattotronix.kinematics import Chain
from tattotronix.robot.description import RobotDescription

from .conftest import ROOT

SMALL = ["mask.width_mm=24", "mask.min_region_mm2=0.5"]
ALL_OFF = {"addr": 64, "reg": 0xFA, "data": [0, 0, 0, 0x10]}


def _velocity(desc: RobotDescription) -> list[float]:
    return [j.velocity for j in desc.joints]


# ----------------------------------------------------------------------------- program


def test_pulse_mapping_and_mirrored_shoulder(desc: RobotDescription) -> None:
    cal = default_calibration()
    cu = count_period_us(50.0, 25e6)
    assert cu == pytest.approx(4.88)
    assert cal.counts([0.0] * 5, cu) == {ch: 307 for ch in range(6)}  # 1500 us -> 307
    for q in (-0.7, -0.1, 0.05, 0.4, 1.2):
        c = cal.counts([0.0, q, 0.0, 0.0, 0.0], cu)
        assert c[2] == round((1500 - 636.62 * q) / 4.88)  # the twin turns the other way
        assert c[1] == round((1500 + 636.62 * q) / 4.88)


def test_a_command_past_the_range_is_clamped(desc: RobotDescription) -> None:
    cal = default_calibration()
    t = np.array([0.0, 1.0, 2.0])
    q = np.zeros((3, 5))
    q[1:, 0] = 3.0  # 3 rad on joint_1: beyond its 1.57 range
    prog = compile_program(t, q, np.zeros_like(q), cal, desc.lower, desc.upper,
                           [100.0] * 5)
    assert prog.range_clamped > 0 and prog.q[:, 0].max() == pytest.approx(desc.upper[0])
    c0 = prog.counts[:, prog.channels.index(0)]
    assert c0.max() == round((1500 + 636.62 * 1.57) / 4.88)
    assert np.all(c0 * prog.count_us <= 2500.0) and np.all(c0 * prog.count_us >= 500.0)


def test_rate_clamp_keeps_every_joint_within_its_velocity(desc: RobotDescription) -> None:
    cal = default_calibration()
    t = np.array([0.0, 0.1, 3.0])
    q = np.zeros((3, 5))
    q[1:, 1] = 1.0  # 10 rad/s asked
    prog = compile_program(t, q, np.zeros_like(q), cal, desc.lower, desc.upper,
                           _velocity(desc))
    step = np.abs(np.diff(prog.q, axis=0)).max(axis=0)
    assert np.all(step <= np.array(_velocity(desc)) / 50.0 + 1e-12)
    assert prog.rate_clamped > 0 and prog.q[-1, 1] == pytest.approx(1.0)


def test_program_metrics_quantisation_is_half_a_count(desc: RobotDescription) -> None:
    cal = default_calibration()
    t = np.linspace(0.0, 4.0, 50)
    q = np.column_stack([0.2 * np.sin(t + k) for k in range(5)])
    qd = np.column_stack([0.2 * np.cos(t + k) for k in range(5)])
    prog = compile_program(t, q, qd, cal, desc.lower, desc.upper, _velocity(desc))
    m = prog.metrics(cal, Chain.from_description(desc))
    half_count_deg = np.degrees(0.5 * 4.88 / 636.62)
    assert m["frames"] == 201 and m["count_us"] == pytest.approx(4.88)
    assert max(m["quantisation_deg"].values()) <= half_count_deg + 1e-9
    assert 0 < m["quantisation_tip_mm_mean"] <= m["quantisation_tip_mm_max"] < 5.0


def test_ramp_peaks_at_the_ramp_speed() -> None:
    q0, q1 = np.zeros(5), np.array([0.5, -0.2, 0.1, 0.0, 0.3])
    frames = ramp(q0, q1, 0.25, 50.0)
    assert np.allclose(frames[-1], q1)
    assert np.abs(np.diff(np.vstack([q0, frames]), axis=0)).max() * 50 <= 0.25 + 1e-3


def test_state_file_problems_are_named(tmp_path: Path) -> None:
    bad = tmp_path / "state.json"
    bad.write_text("{not json")
    with pytest.raises(TattotronixError, match="state.json is unreadable"):
        ArmState.load(bad, 5)
    bad.write_text(json.dumps({"q": [0.0, 0.1]}))
    with pytest.raises(TattotronixError, match="5 finite angles"):
        ArmState.load(bad, 5)
    assert ArmState.load(tmp_path / "none.json", 5) is None


def test_servo_pulse_holds_widths_and_ends_off() -> None:
    bus = RecordingBus()
    said: list[str] = []
    with PCA9685(bus, handle_signals=False) as board:
        board.start(50.0)
        sent = hold_pulses(board, 3, "1500", ["1600\n", "oops\n", "3000\n", "\n", "1700\n"],
                           said.append)
    assert sent == [307, 328]
    assert any("ignored" in s for s in said) and said[-1] == "channel 3: off"
    writes = [(w["reg"], w["data"]) for w in bus.writes]
    assert writes[-2] == (0x12, [0, 0, 0, 0x10])  # the channel off, then all off on exit
    with pytest.raises(TattotronixError, match="outside 400..2600"):
        hold_pulses(board, 3, 300.0, [])


# ----------------------------------------------------------------------------- stage runs


@pytest.fixture()
def data(draw_data: Path) -> Path:
    return draw_data


def _arm_cmd(data: Path, *extra: str) -> list[str]:
    return [sys.executable, "stages/draw.py", f"paths.data={data}", "backend=arm",
            f"artwork.source={data.parent / 'small.png'}", *SMALL, *extra]


def _arm(data: Path, *extra: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(_arm_cmd(data, "dry_run=true", "realtime=false", *extra), cwd=ROOT,
                          capture_output=True, text=True, timeout=600)


def _transcript(data: Path) -> list[dict]:
    return [json.loads(x) for x in (data / "runs" / "small-arm" / "i2c.jsonl").open()]


def _poses(data: Path) -> list[dict]:
    return [json.loads(x) for x in (data / "runs" / "small-arm" / "poses.jsonl").open()]


def _counts_within_limits(writes: list[dict]) -> None:
    cal = default_calibration()
    lim = {s.channel: (s.min_us, s.max_us) for j in cal.joints for s in j.servos()}
    for w in writes:
        reg, d = w["reg"], w["data"]
        if 0x06 <= reg < 0x46 and not d[3] & 0x10:  # a channel's pulse (not full-off)
            ch, counts = (reg - 0x06) // 4, d[2] | (d[3] << 8)
            lo, hi = lim[ch]
            assert lo <= counts * 4.88 <= hi, (ch, counts)
            assert ch != cal.tool_channel


@pytest.mark.slow
def test_dry_run_draw_is_deterministic_and_within_limits(data: Path) -> None:
    first = _arm(data)
    assert first.returncode == 0, first.stderr
    t1 = (data / "runs" / "small-arm" / "i2c.jsonl").read_text()
    (data / "arm" / "state.json").unlink()  # start again from the same (zero) pose
    second = _arm(data)
    assert second.returncode == 0, second.stderr
    assert (data / "runs" / "small-arm" / "i2c.jsonl").read_text() == t1
    writes = _transcript(data)
    assert writes[:5] == [{"addr": 64, "reg": 0, "data": [16]},
                          {"addr": 64, "reg": 254, "data": [121]},
                          {"addr": 64, "reg": 1, "data": [4]},
                          {"addr": 64, "reg": 0, "data": [32]}, ALL_OFF]
    assert writes[-1] == ALL_OFF
    _counts_within_limits(writes)
    state = json.loads((data / "arm" / "state.json").read_text())
    m = json.loads((data / "metrics" / "runs" / "small-arm.json").read_text())
    assert state["status"] == "done" and state["frame"] == m["frames"]
    draws = [p["frame"] for p in _poses(data) if p["phase"] == "draw"]
    assert draws == list(range(m["frames"]))


@pytest.mark.slow
def test_bus_error_half_way_then_resume_completes_with_a_fresh_approach(data: Path) -> None:
    failed = _arm(data, "hardware.fail_after_writes=400")
    assert failed.returncode == 2
    assert "0x40" in failed.stderr and "resume=true" in failed.stderr
    assert "Traceback" not in failed.stderr
    state = json.loads((data / "arm" / "state.json").read_text())
    assert state["status"] == "failed" and 0 < state["frame"] < state["frames"]
    before = _transcript(data)
    assert before[-1] == ALL_OFF  # the attempt at all-off went through
    drawn = [p["frame"] for p in _poses(data) if p["phase"] == "draw"]
    assert drawn == list(range(state["frame"]))  # nothing lost, nothing skipped

    resumed = _arm(data, "resume=true")
    assert resumed.returncode == 0, resumed.stderr
    after = _transcript(data)
    assert after[:len(before)] == before  # the first session's transcript is kept
    _counts_within_limits(after)
    poses = _poses(data)
    drawn = [p["frame"] for p in poses if p["phase"] == "draw"]
    assert drawn == list(range(state["frames"]))
    second = [p for p in poses if p["session"] == 2]
    phases = [p["phase"] for p in second]
    assert "approach" in phases and phases.index("approach") < phases.index("draw")
    # the approach comes down the needle axis onto the stopped frame from clearance
    cfg = compose_settings()
    from tattotronix.robot.description import build_description

    chain = Chain.from_description(build_description(cfg.robot))
    appr = np.array([p["q"] for p in second if p["phase"] == "approach"])
    z = chain.fk(appr)[0][:, 2]
    clearance = cfg.toolpath.panel_origin[2] + cfg.toolpath.clearance_m
    assert z.max() == pytest.approx(clearance, abs=1e-5)
    assert np.all(np.diff(z[int(np.argmax(z)):]) <= 1e-9)  # then only down
    assert json.loads((data / "arm" / "state.json").read_text())["status"] == "done"


@pytest.mark.slow
def test_ctrl_c_lifts_the_needle_saves_and_switches_off(data: Path) -> None:
    proc = subprocess.Popen(_arm_cmd(data, "dry_run=true", "realtime=true"), cwd=ROOT,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.time() + 120
    poses = data / "runs" / "small-arm" / "poses.jsonl"
    while time.time() < deadline:  # wait until it draws
        if poses.exists() and '"phase": "draw"' in poses.read_text():
            break
        time.sleep(0.2)
    time.sleep(1.0)
    os.kill(proc.pid, signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 2 and "paused at frame" in err and "resume=true" in err
    state = json.loads((data / "arm" / "state.json").read_text())
    assert state["status"] == "paused" and 0 < state["frame"] < state["frames"]
    assert _transcript(data)[-1] == ALL_OFF
    last = _poses(data)[-1]
    cfg = compose_settings()
    from tattotronix.robot.description import build_description

    chain = Chain.from_description(build_description(cfg.robot))
    z = chain.fk(np.array([last["q"]]))[0][0, 2]
    clearance = cfg.toolpath.panel_origin[2] + cfg.toolpath.clearance_m
    assert z >= clearance - 1e-5  # the needle is up
    resumed = _arm(data, "resume=true")
    assert resumed.returncode == 0, resumed.stderr


def test_resume_without_a_stopped_drawing_is_refused(data: Path) -> None:
    r = _arm(data, "resume=true")
    assert r.returncode == 2 and "nothing to resume" in r.stderr


def test_missing_i2c_device_is_a_clear_error(data: Path) -> None:
    r = subprocess.run(_arm_cmd(data, "hardware.servos.device=/dev/i2c-77"), cwd=ROOT,
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 2 and "/dev/i2c-77" in r.stderr and "Traceback" not in r.stderr


def test_bad_calibration_file_names_joint_and_key(data: Path, tmp_path: Path) -> None:
    bad = tmp_path / "cal.yaml"
    bad.write_text("joints:\n  joint_1: {channel: 0, zero_us: 15OO, us_per_rad: 636.62, "
                   "min_us: 500, max_us: 2500}\n")
    r = _arm(data, f"hardware.calibration_file={bad}")
    assert r.returncode == 2 and "joint_1" in r.stderr and "zero_us" in r.stderr


def test_the_arm_refuses_a_colliding_drawing_before_the_bus(desc: RobotDescription) -> None:
    """draw.py backend=arm checks whatever it is about to play (check_drawing_clear runs
    before the program is compiled or the bus opened): a sweep of the shoulder that folds
    the arm into the bench is refused, naming the pair; a small move near home is not."""
    from tattotronix.collision.check import CollisionRefused
    from tattotronix.config.params import compose_settings
    from tattotronix.hardware.arm import check_drawing_clear

    cfg = compose_settings()
    t = np.linspace(0.0, 2.0, 21)
    fold = np.zeros((21, 5))
    fold[:, 1] = np.linspace(0.0, 1.57, 21)
    with pytest.raises(CollisionRefused, match=r"and bench collide at t = [0-9.]+ s"):
        check_drawing_clear(cfg, desc, t, fold)
    near_home = np.zeros((21, 5))
    near_home[:, 0] = np.linspace(0.0, 0.3, 21)
    check_drawing_clear(cfg, desc, t, near_home)
