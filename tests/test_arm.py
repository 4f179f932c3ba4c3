"""The real-arm backend: servo program, dry-run draws, faults, pause and resume."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from tattotronix.app.arm import state_file_of
from tattotronix.config.params import compose_settings
from tattotronix.errors import TattotronixError
from tattotronix.hardware import (
    PCA9685,
    RecordingBus,
    default_calibration,
    default_calibration_mapping,
)
from tattotronix.hardware.arm import (
    DRY_RUN_STATE,
    RESUME_MARGIN_S,
    TEST_HOOK_ENV,
    ArmState,
    ramp,
)
from tattotronix.hardware.program import compile_program, count_period_us
from tattotronix.hardware.pulse import hold_pulses
from tattotronix.kinematics import Chain
from tattotronix.robot.description import RobotDescription

from .conftest import ROOT, default_signals

SMALL = ["mask.width_mm=24", "mask.min_region_mm2=0.5"]
ALL_OFF = {"addr": 64, "reg": 0xFA, "data": [0, 0, 0, 0x10]}
MARGIN = round(RESUME_MARGIN_S * 50)  # frames a resume after a crash goes back


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
    with pytest.raises(TattotronixError, match="state.json: unreadable"):
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


@dataclass(frozen=True)
class Geometry:
    """The needle's heights (arm frame, m) and the kinematics that put it there."""

    chain: Chain
    clearance: float
    surface: float

    def tip(self, q: object) -> np.ndarray:
        """(N, 3) tip positions of the poses ``q``, m."""
        return self.chain.fk(np.atleast_2d(np.asarray(q, dtype=float)))[0]


@pytest.fixture(scope="module")
def geo() -> Geometry:
    from tattotronix.robot.description import build_description

    cfg = compose_settings()
    surface = float(cfg.toolpath.panel_origin[2])
    return Geometry(Chain.from_description(build_description(cfg.robot)),
                    surface + cfg.toolpath.clearance_m, surface)


def _env(hook: str | None = None) -> dict[str, str]:
    env = dict(os.environ)
    env.pop(TEST_HOOK_ENV, None)
    if hook:
        env[TEST_HOOK_ENV] = hook
    return env


def _arm_cmd(data: Path, *extra: str) -> list[str]:
    return [sys.executable, "stages/draw.py", f"paths.data={data}", "backend=arm",
            f"artwork.source={data.parent / 'small.png'}", *SMALL, *extra]


def _arm(data: Path, *extra: str, hook: str | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run(_arm_cmd(data, "dry_run=true", "realtime=false", *extra), cwd=ROOT,
                          env=_env(hook), capture_output=True, text=True, timeout=600,
                          preexec_fn=default_signals)


def _log(data: Path, name: str) -> list[dict]:
    return [json.loads(x) for x in (data / "runs" / "small-arm" / name).open()]


def _transcript(data: Path, session: int | None = None) -> list[dict]:
    """The I2C writes (of one session), without their session number."""
    return [{k: v for k, v in w.items() if k != "session"} for w in _log(data, "i2c.jsonl")
            if session is None or w["session"] == session]


def _poses(data: Path, session: int | None = None) -> list[dict]:
    return [p for p in _log(data, "poses.jsonl") if session is None or p["session"] == session]


def _state_file(data: Path) -> Path:
    """A dry run's state file: in its run folder, never the real arm's (data/arm/)."""
    return data / "runs" / "small-arm" / DRY_RUN_STATE


def _state(data: Path) -> dict:
    return json.loads(_state_file(data).read_text())


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


def _assert_stopped_safely(data: Path, r: subprocess.CompletedProcess[str], geo: Geometry,
                           signame: str) -> None:
    """A stop signal: the needle ends at or above the clearance height in the last pose
    sent (forward kinematics of the logged angles), every output off after it, the state
    paused at the next frame to draw, and a message that says all of it truthfully, in
    one line, with the exit code of an interrupt (128 + the signal: 130 for Ctrl-C)."""
    assert r.returncode == 128 + signal.Signals[signame], r.stderr
    assert r.stderr.strip().splitlines()[-1].startswith(f"draw: interrupted: {signame} ")
    assert "Traceback" not in r.stderr and "resume=true" in r.stderr
    state = _state(data)
    assert state["status"] == "paused"
    poses = _poses(data, state["session"])
    z = geo.tip(poses[-1]["q"])[0, 2]
    assert z >= geo.clearance - 1e-5
    assert _transcript(data, state["session"])[-1] == ALL_OFF
    err = " ".join(r.stderr.split())
    assert f"interrupted: {signame} " in err
    assert f"the last pose sent has the needle tip at {z * 1e3:.2f} mm" in err
    assert "every output is off" in err
    moving = [p for p in poses if p["phase"] != "lift"]
    z_stop = geo.tip(moving[-1]["q"])[0, 2] if moving else z
    if z_stop < geo.clearance - 1e-5:  # stopped in the work: the lift is in the log, done
        assert poses[-1]["phase"] == "lift" and "the lift to the clearance height completed" in err
    else:
        assert "no lift was needed" in err
    draws = [p["frame"] for p in poses if p["phase"] == "draw"]
    if draws:
        assert state["frame"] == draws[-1] + 1


def _assert_resume_lifts_first(data: Path, geo: Geometry, killed: int) -> None:
    """After SIGKILL: the next session starts from the last pose the killed one sent (no
    jump) and, if that left the needle below the clearance height, first lifts it
    straight up there."""
    last = np.array(_poses(data, killed)[-1]["q"])
    nxt = _poses(data, killed + 1)
    assert np.abs(np.array(nxt[0]["q"]) - last).max() < 0.02  # within one small step
    tip = geo.tip(last)[0]
    phases = [p["phase"] for p in nxt]
    if tip[2] >= geo.clearance - 1e-5:
        assert phases[0] != "lift"
        return
    n_lift = next((i for i, p in enumerate(phases) if p != "lift"), len(phases))
    assert n_lift > 0
    lift = geo.tip([p["q"] for p in nxt[:n_lift]])
    assert np.abs(lift[:, :2] - tip[:2]).max() < 1e-4  # straight up
    assert np.all(np.diff(np.concatenate([[tip[2]], lift[:, 2]])) > 0)
    if n_lift < len(phases):  # (unless that session was killed in the lift too)
        assert lift[-1, 2] == pytest.approx(geo.clearance, abs=1e-5)


def _assert_drawn_once(data: Path, after_crash: set[int]) -> None:
    """Every frame drawn; a session re-draws nothing, except after a crash (the sessions
    in ``after_crash``) at most the margin plus the one frame that may have gone out
    unlogged."""
    frames = _state(data)["frames"]
    before: set[int] = set()
    for s in sorted({p["session"] for p in _poses(data)}):
        drawn = [p["frame"] for p in _poses(data, s) if p["phase"] == "draw"]
        assert drawn == list(range(drawn[0], drawn[0] + len(drawn)) if drawn else [])
        again = before & set(drawn)
        assert len(again) <= (MARGIN + 1 if s in after_crash else 0), (s, sorted(again))
        before |= set(drawn)
    assert before == set(range(frames))


@pytest.mark.slow
def test_dry_run_draw_is_deterministic_appends_and_survives_a_missing_bus(data: Path) -> None:
    first = _arm(data)
    assert first.returncode == 0, first.stderr
    logs = [data / "runs" / "small-arm" / f for f in ("i2c.jsonl", "poses.jsonl")]
    kept = {p: p.read_bytes() for p in [*logs, _state_file(data)]}
    assert not (data / "arm").exists()  # the real arm's state is not the dry run's
    # a real run without the device: refused before anything is opened for writing
    r = subprocess.run(_arm_cmd(data, "hardware.servos.device=/dev/i2c-77"), cwd=ROOT,
                       env=_env(), capture_output=True, text=True, timeout=600)
    assert r.returncode == 2 and "/dev/i2c-77" in r.stderr and "Traceback" not in r.stderr
    assert {p: p.read_bytes() for p in kept} == kept
    _state_file(data).unlink()  # start again from the same (zero) pose
    second = _arm(data)
    assert second.returncode == 0, second.stderr
    for p in logs:  # the second session appends: the first one's logs are kept
        assert p.read_bytes().startswith(kept[p]) and len(p.read_bytes()) > len(kept[p])
    assert _transcript(data, 2) == _transcript(data, 1)
    writes = _transcript(data, 2)
    assert writes[:5] == [{"addr": 64, "reg": 0, "data": [16]},
                          {"addr": 64, "reg": 254, "data": [121]},
                          {"addr": 64, "reg": 1, "data": [4]},
                          {"addr": 64, "reg": 0, "data": [32]}, ALL_OFF]
    assert writes[-1] == ALL_OFF
    _counts_within_limits(writes)
    state = _state(data)
    m = json.loads((data / "metrics" / "runs" / "small-arm.json").read_text())
    assert state["status"] == "done" and state["frame"] == m["frames"]
    draws = [p["frame"] for p in _poses(data, 2) if p["phase"] == "draw"]
    assert draws == list(range(m["frames"]))


@pytest.mark.slow
def test_bus_error_half_way_then_resume_completes_with_a_fresh_approach(
        data: Path, geo: Geometry) -> None:
    # (write 301 falls mid-stroke, frame 582 of 1515, the needle 1.5 mm in the work)
    failed = _arm(data, "hardware.fail_after_writes=300")
    assert failed.returncode == 2
    assert "0x40" in failed.stderr and "resume=true" in failed.stderr
    assert "no lift was tried" in failed.stderr and "went through" in failed.stderr
    assert "Traceback" not in failed.stderr
    state = _state(data)
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
    _assert_drawn_once(data, after_crash=set())
    second = _poses(data, 2)
    phases = [p["phase"] for p in second]
    assert phases[0] == "lift"  # the needle was left in the work: up first
    assert "approach" in phases and phases.index("approach") < phases.index("draw")
    # the approach comes down the needle axis onto the stopped frame from clearance
    appr = np.array([p["q"] for p in second if p["phase"] == "approach"])
    z = geo.tip(appr)[:, 2]
    assert z.max() == pytest.approx(geo.clearance, abs=1e-5)
    assert np.all(np.diff(z[int(np.argmax(z)):]) <= 1e-9)  # then only down
    assert _state(data)["status"] == "done"


SIGNALS = ["SIGINT", "SIGTERM", "SIGHUP", "double SIGINT", "SIGKILL"]


def _hook(sig: str, point: str) -> str:
    """The test hook that delivers ``sig`` at ``point`` (``phase:n``); a double SIGINT
    sends its second one a frame into the lift, or at once where nothing needs lifting."""
    if sig == "double SIGINT":
        second = point if point.startswith("ramp") else "lift:1"
        return f"{point}:INT;{second}:INT"
    return f"{point}:{sig.removeprefix('SIG')}"


@pytest.mark.slow
@pytest.mark.parametrize("sig", SIGNALS)
def test_every_stop_leaves_the_needle_up_and_resume_draws_every_frame(
        data: Path, geo: Geometry, sig: str) -> None:
    """The acceptance test: the signal at each kill point (the ramp, while drawing, the
    approach of a resume, the lift after a stop; with SIGKILL also the first lift of the
    resume after it), each stop checked from the poses sent, then resumed to the end."""
    state_file = _state_file(data)
    state_file.parent.mkdir(parents=True)
    state_file.write_text(json.dumps({"q": [0.3, 0.0, 0.0, 0.0, 0.0], "status": "done"}))
    kill = sig == "SIGKILL"
    points = [("ramp", "ramp:20"), ("draw", "draw:200"),
              *([("first lift", "lift:3")] if kill else []),
              ("approach", "approach:60"), ("lift", "draw:100:INT;lift:3")]
    after_crash: set[int] = set()
    for session, (where, point) in enumerate(points, start=1):
        r = _arm(data, *(["resume=true"] if session > 1 else []), hook=_hook(sig, point))
        poses = _poses(data, session)
        assert poses and poses[0]["session"] == session, (where, r.stderr)
        if where == "approach":  # the hook stopped it on the way down, in the work
            appr = [p["q"] for p in poses if p["phase"] == "approach"]
            assert geo.tip(appr[-1])[0, 2] < geo.clearance - 1e-3
        if where == "lift" and not kill:
            assert f"then {'SIGINT' if sig == 'double SIGINT' else sig}" in r.stderr
        if session in after_crash:
            _assert_resume_lifts_first(data, geo, session - 1)
        if kill:
            assert r.returncode == -signal.SIGKILL, (where, r.stderr)
            state = _state(data)
            assert state["status"] == "drawing"
            draws = [p["frame"] for p in poses if p["phase"] == "draw"]
            assert not draws or state["frame"] <= draws[-1] + 1  # the log is never behind
            after_crash.add(session + 1)
        else:
            _assert_stopped_safely(data, r, geo, "SIGINT" if "INT" in sig or where == "lift"
                                   else sig)
    done = _arm(data, "resume=true")
    assert done.returncode == 0, done.stderr
    if kill:
        _assert_resume_lifts_first(data, geo, len(points))
    assert _state(data)["status"] == "done"
    _assert_drawn_once(data, after_crash)
    _counts_within_limits(_transcript(data))


def _until_hook_waits(proc: subprocess.Popen[str]) -> None:
    assert proc.stderr is not None
    for line in proc.stderr:
        if line.startswith("arm test hook: waiting"):
            return
    raise AssertionError(f"the session ended before its hook: {proc.communicate()}")


@pytest.mark.slow
def test_hang_up_and_a_double_ctrl_c_from_outside_in_real_time(data: Path, geo: Geometry
                                                                ) -> None:
    """Signals from another process while the frames go out at 50 Hz: ``kill -HUP`` a
    second into drawing (a closed terminal), then on the resume two SIGINTs 30 ms apart
    while its approach has the needle below the clearance height (so the first one's
    lift is under way when the second comes), while a second session is refused."""
    proc = subprocess.Popen(_arm_cmd(data, "dry_run=true", "realtime=true"), cwd=ROOT,
                            env=_env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, preexec_fn=default_signals)
    poses = data / "runs" / "small-arm" / "poses.jsonl"
    deadline = time.time() + 120
    while time.time() < deadline:  # wait until it draws
        if poses.exists() and '"phase": "draw"' in poses.read_text():
            break
        time.sleep(0.1)
    time.sleep(1.0)
    os.kill(proc.pid, signal.SIGHUP)
    out, err = proc.communicate(timeout=120)
    _assert_stopped_safely(data, subprocess.CompletedProcess(proc.args, proc.returncode, out,
                                                             err), geo, "SIGHUP")
    assert "while drawing" in err and "completed" in err

    proc = subprocess.Popen(_arm_cmd(data, "dry_run=true", "realtime=true", "resume=true"),
                            cwd=ROOT, env=_env("approach:60:wait"), stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, preexec_fn=default_signals)
    _until_hook_waits(proc)
    other = _arm(data, "resume=true")
    assert other.returncode == 2 and "another arm session is running" in other.stderr
    os.kill(proc.pid, signal.SIGINT)
    time.sleep(0.03)
    os.kill(proc.pid, signal.SIGINT)
    out, err = proc.communicate(timeout=120)
    r = subprocess.CompletedProcess(proc.args, proc.returncode, out, err)
    _assert_stopped_safely(data, r, geo, "SIGINT")
    assert "then SIGINT: noted and ignored" in " ".join(err.split())
    done = _arm(data, "resume=true")
    assert done.returncode == 0, done.stderr
    _assert_drawn_once(data, after_crash=set())


def test_the_pose_log_tail_skips_a_torn_line(tmp_path: Path) -> None:
    from tattotronix.hardware.arm import _Logs, _LogTail, _read_tail

    log = tmp_path / "poses.jsonl"
    lines = [{"session": 1, "phase": "draw", "frame": i, "q": [0.0] * 5} for i in range(9)]
    lines += [{"session": 2, "phase": p, "frame": f, "q": [0.1 * k] * 5}
              for k, (p, f) in enumerate([("lift", None), ("approach", None), ("draw", 4),
                                          ("draw", 5), ("lift", None)])]
    log.write_text("".join(json.dumps(x) + "\n" for x in lines) + '{"session": 2, "pha')
    tail = _read_tail(log, 5, block=7)  # blocks shorter than a line
    assert (tail.session, tail.drawn) == (2, 6) and tail.q == pytest.approx([0.4] * 5)
    logs = _Logs(tmp_path, 3, None)  # the next session ends the torn line first
    logs.pose("lift", None, np.full(5, 0.7), {})
    logs.close()
    assert log.read_text().endswith('{"session": 2, "pha\n' + json.dumps(
        {"session": 3, "phase": "lift", "frame": None, "q": [0.7] * 5, "counts": {}}) + "\n")
    assert _read_tail(log, 5) == _LogTail(3, (0.7,) * 5, 0)
    log.write_text("".join(json.dumps(x) + "\n" for x in lines[:11]))
    assert _read_tail(log, 5).drawn == 0  # session 2 drew nothing yet
    assert _read_tail(tmp_path / "none.jsonl", 5).session == 0


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


@pytest.mark.parametrize("how", ["override", "file"])
def test_calibration_beyond_a_hobby_servo_is_refused(data: Path, tmp_path: Path, how: str
                                                     ) -> None:
    if how == "override":
        r = _arm(data, "hardware.servos.joints.joint_1.max_us=9000")
        key = "joint_1.max_us: 9000 us is above 2600 us"
    else:
        cal = default_calibration_mapping()
        cal["joints"]["joint_4"]["min_us"] = 100
        path = tmp_path / "cal.yaml"
        path.write_text(json.dumps(cal))  # JSON is YAML
        r = _arm(data, f"hardware.calibration_file={path}")
        key = "joint_4.min_us: 100 us is below 400 us"
    assert r.returncode == 2 and key in r.stderr and "Traceback" not in r.stderr
    assert not (data / "runs").exists() and not (data / "arm").exists()


def test_the_arm_refuses_a_colliding_drawing_before_the_bus(desc: RobotDescription) -> None:
    """draw.py backend=arm checks whatever it is about to play (check_drawing_clear runs
    before the program is compiled or the bus opened): a sweep of the shoulder that folds
    the arm into the bench is refused, naming the pair; a small move near home is not."""
    from tattotronix.app.arm import check_drawing_clear
    from tattotronix.collision.check import CollisionRefused
    from tattotronix.config.params import compose_settings

    cfg = compose_settings()
    t = np.linspace(0.0, 2.0, 21)
    fold = np.zeros((21, 5))
    fold[:, 1] = np.linspace(0.0, 1.57, 21)
    with pytest.raises(CollisionRefused, match=r"and bench collide at t = [0-9.]+ s"):
        check_drawing_clear(cfg, desc, t, fold)
    near_home = np.zeros((21, 5))
    near_home[:, 0] = np.linspace(0.0, 0.3, 21)
    check_drawing_clear(cfg, desc, t, near_home)


def test_a_dry_run_keeps_its_own_state_file(tmp_path: Path) -> None:
    """The real arm's last commanded pose is hardware.state_file under paths.data; a dry
    run's is in its run folder, so a rehearsal never changes what the arm believes."""
    folder = tmp_path / "runs" / "x-arm"
    real = compose_settings(["dry_run=false"])
    assert state_file_of(real, tmp_path, folder) == tmp_path / "arm" / "state.json"
    dry = compose_settings(["dry_run=true"])
    assert state_file_of(dry, tmp_path, folder) == folder / DRY_RUN_STATE


def test_preview_prints_the_plan_and_sends_nothing(data: Path) -> None:
    """The plan comes first, in one block; preview=true stops there with an image, even
    without the device, and touches no log or state file."""
    folder = data / "runs" / "small-arm"
    before = {p: p.read_bytes() for p in folder.glob("*")} if folder.is_dir() else {}
    r = subprocess.run(_arm_cmd(data, "preview=true", "hardware.servos.device=/dev/i2c-77"),
                       cwd=ROOT, env=_env(), capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    said = r.stdout + r.stderr
    block = said[said.index("plan for the arm: small"):]
    for line in ("duration", "needle entries", "inked box", "on the panel", "start pose",
                 "end pose"):
        assert line in block, block
    assert "nothing sent" in said
    image = folder / "preview.png"
    assert image.read_bytes().startswith(b"\x89PNG")
    after = {p: p.read_bytes() for p in folder.glob("*") if p != image}
    assert after == before  # no log, no state: nothing reached a bus
    assert not (data / "arm").exists()
