"""``draw.py backend=arm``: stream a servo program to the PCA9685, safely, with resume.

* Nothing reaches the bus before the drawing is proven clear of collisions with the
  margin (:func:`check_drawing_clear`, the collision stage's check).
* The last commanded pose lives in a state file (the servos report nothing). A session
  first ramps slowly (``hardware.ramp_rad_s``) from that pose to the start pose.
* Frames are sent at the frame rate; only the channels whose count changed are written
  (every channel on the first frame of a session). No count leaves the calibration.
* **Pause**: Ctrl-C (or SIGTERM) lifts the needle straight up to the clearance height,
  saves the frame index and switches every output off. A bus error saves the frame index
  of the last frame fully sent and tries all-off. Either way ``resume=true`` continues:
  it ramps to the point above the stopped frame, comes down along the needle at the
  marking feed (a fresh approach) and streams on from there.
* ``dry_run=true`` runs all of it against a recording bus, appending the I2C transcript
  (``i2c.jsonl``: one ``{"addr", "reg", "data"}`` per write) and the commanded poses
  (``poses.jsonl``) under ``data/runs/<name>-arm/``; ``realtime=false`` skips the waits.
"""

from __future__ import annotations

import json
import logging
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from tattotronix.config.schema import Config, HardwareConfig
from tattotronix.errors import TattotronixError
from tattotronix.hardware.pca9685 import PCA9685, BusError, RecordingBus, SMBusLike, open_bus
from tattotronix.hardware.program import ServoProgram
from tattotronix.hardware.servos import Calibration, load_calibration
from tattotronix.io.artifacts import run_dir, run_label
from tattotronix.io.jsontypes import JsonDict
from tattotronix.io.outputs import Outputs
from tattotronix.kinematics import Chain, IkOptions, solve_path
from tattotronix.robot.description import RobotDescription, build_description

__all__ = ["ArmSession", "ArmState", "Paused", "calibration_from_config", "check_drawing_clear",
           "ramp"]

log = logging.getLogger("tattotronix.arm")
Array = NDArray[np.float64]


def _sigterm_as_interrupt() -> Any:
    """Make SIGTERM stop the drawing like Ctrl-C (main thread only); returns the old one."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        return None

    def handler(signum: int, frame: Any) -> None:
        raise KeyboardInterrupt(f"signal {signum}")

    return signal.signal(signal.SIGTERM, handler)


def _restore_sigterm(previous: Any) -> None:
    import signal

    if previous is not None:
        signal.signal(signal.SIGTERM, previous)


class Paused(TattotronixError):
    """The drawing stopped on request (Ctrl-C / SIGTERM); the message says how to resume."""


def calibration_from_config(hw: HardwareConfig, joint_names: tuple[str, ...]) -> Calibration:
    """The calibration: ``hardware.calibration_file`` if set, else ``hardware.servos``."""
    if hw.calibration_file:
        return load_calibration(Path(str(hw.calibration_file)), joint_names)
    return Calibration.from_mapping(hw.servos, joint_names, source="conf/hardware servos")


@dataclass
class ArmState:
    """What the state file holds.

    Attributes:
        q: the last commanded pose, rad.
        drawing: the drawing in progress (None when none is).
        program: its program digest.
        frame: the next frame to send.
        frames: the program's length.
        status: ``idle``, ``drawing``, ``paused``, ``failed`` or ``done``.
        reason: why it stopped.
    """

    q: list[float]
    drawing: str | None = None
    program: str | None = None
    frame: int = 0
    frames: int = 0
    status: str = "idle"
    reason: str = ""
    saved_at: float = field(default_factory=time.time)

    @classmethod
    def load(cls, path: Path, n: int) -> ArmState | None:
        """Read the state file; None if there is none.

        Raises:
            TattotronixError: the file is unreadable or malformed (it names the file).
        """
        if not path.exists():
            return None
        try:
            raw = json.loads(path.read_text())
            state = cls(**raw)
            if len(state.q) != n or not all(np.isfinite(state.q)):
                raise ValueError(f"q must be {n} finite angles")
        except (OSError, ValueError, TypeError) as exc:
            raise TattotronixError(
                f"arm state file {path} is unreadable ({exc}): if the arm is at its zero "
                "pose, delete the file; otherwise fix it, since the arm would jump") from None
        return state

    def save(self, path: Path) -> None:
        """Write atomically (a crash never leaves half a file)."""
        path.parent.mkdir(parents=True, exist_ok=True)
        self.saved_at = time.time()
        tmp = path.with_name(path.name + ".tmp")
        tmp.write_text(json.dumps(asdict(self), indent=1) + "\n")
        tmp.replace(path)


def ramp(q0: Array, q1: Array, speed_rad_s: float, frame_hz: float) -> Array:
    """Frames from ``q0`` to ``q1`` (excluded start, included end), a cosine profile whose
    fastest joint peaks at ``speed_rad_s``."""
    dist = float(np.max(np.abs(q1 - q0)))
    if dist < 1e-12:
        return np.zeros((0, len(q0)))
    duration = (np.pi / 2) * dist / speed_rad_s  # peak of the cosine profile = speed
    n = max(1, int(np.ceil(duration * frame_hz)))
    s = 0.5 - 0.5 * np.cos(np.pi * np.arange(1, n + 1) / n)
    return q0 + s[:, None] * (q1 - q0)


class _Stream:
    """Sends frames to the board: changed channels only, paced, logged."""

    def __init__(self, board: PCA9685, calib: Calibration, count_us: float, frame_hz: float,
                 realtime: bool, poses: Any, session: int):
        self.board = board
        self.calib = calib
        self.count_us = count_us
        self.period = 1.0 / frame_hz
        self.realtime = realtime
        self.poses = poses
        self.session = session
        self.last: dict[int, int] = {}
        self.q = np.zeros(len(calib.joints))
        self.sent = 0
        self.writes = 0
        self._next = time.perf_counter()

    def send(self, q: Array, phase: str, frame: int | None = None,
             counts: dict[int, int] | None = None) -> None:
        counts = counts if counts is not None else self.calib.counts(q, self.count_us)
        if self.realtime:
            delay = self._next - time.perf_counter()
            if delay > 0:
                time.sleep(delay)
            self._next = max(self._next + self.period, time.perf_counter() - self.period)
        for ch, c in counts.items():
            if self.last.get(ch) != c:
                self.board.set_counts(ch, c)
                self.last[ch] = c
                self.writes += 1
        self.q = np.asarray(q, dtype=np.float64).copy()
        self.sent += 1
        self.poses.write(json.dumps({"session": self.session, "phase": phase, "frame": frame,
                                     "q": [round(float(v), 9) for v in self.q],
                                     "counts": {str(k): v for k, v in counts.items()}}) + "\n")


@dataclass
class ArmSession:
    """One ``draw.py backend=arm`` run.

    Attributes:
        name: the drawing.
        program: its servo program.
        calib: the calibration.
        chain: the kinematics (lifts and approaches).
        run_dir: ``data/runs/<name>-arm``.
        state_file: the arm state file.
        clearance_z_m: the needle's clearance height (arm frame), m.
        feed_m_s: the approach feed (the marking feed), m/s.
        ramp_rad_s: the fastest joint speed of ramps, rad/s.
        ik: IK keyword arguments for lifts and approaches (``pipeline.ik_settings``).
        dry_run, realtime, resume: as configured.
        fail_after_writes: dry-run fault injection.
        save_every_s: refresh the state file this often (of program time).
    """

    name: str
    program: ServoProgram
    calib: Calibration
    chain: Chain
    run_dir: Path
    state_file: Path
    clearance_z_m: float
    feed_m_s: float
    ramp_rad_s: float
    ik: IkOptions
    dry_run: bool = True
    realtime: bool = True
    resume: bool = False
    fail_after_writes: int | None = None
    save_every_s: float = HardwareConfig().save_every_s

    # -------------------------------------------------------------- geometry helpers

    def _ik(self, targets: Array, seed: Array) -> Array:
        res = solve_path(self.chain, targets, seed=[float(v) for v in seed], **self.ik)
        res.raise_if_failed(targets_m=targets)
        return res.q

    def _lift(self, q: Array) -> Array:
        """Frames that raise the needle straight up from ``q`` to the clearance height."""
        tip, _ = self.chain.fk(q)
        z0 = float(tip[0, 2])
        if z0 >= self.clearance_z_m - 1e-6:
            return np.zeros((0, len(q)))
        n = max(2, int(np.ceil((self.clearance_z_m - z0) / (self.feed_m_s / 50.0))))
        z = np.linspace(z0, self.clearance_z_m, n + 1)[1:]
        pts = np.column_stack([np.full(n, tip[0, 0]), np.full(n, tip[0, 1]), z])
        return self._ik(pts, q)

    def _approach(self, q_here: Array, q_target: Array) -> Array:
        """Frames from ``q_here`` to above ``q_target`` (ramp), then down the needle axis to
        it at the approach feed: a fresh approach."""
        tip, _ = self.chain.fk(q_target)
        z1 = float(tip[0, 2])
        if z1 >= self.clearance_z_m - 1e-6:
            return ramp(q_here, q_target, self.ramp_rad_s, self.program.frame_hz)
        step = self.feed_m_s / self.program.frame_hz
        n = max(2, int(np.ceil((self.clearance_z_m - z1) / step)))
        z = np.linspace(self.clearance_z_m, z1, n + 1)
        pts = np.column_stack([np.full(n + 1, tip[0, 0]), np.full(n + 1, tip[0, 1]), z])
        down = self._ik(pts, q_target)
        down[-1] = q_target
        return np.concatenate([ramp(q_here, down[0], self.ramp_rad_s, self.program.frame_hz),
                               down[1:]])

    # -------------------------------------------------------------- the run

    def run(self) -> JsonDict:
        """Ramp, stream, and stop safely (see the module docstring).

        Raises:
            Paused: Ctrl-C / SIGTERM (after the lift and all-off; state saved).
            TattotronixError: a bus error (state saved), a refused resume, a missing device.
        """
        prog = self.program
        n = len(self.calib.joints)
        state = ArmState.load(self.state_file, n)
        digest = prog.digest()
        start = 0
        if self.resume:
            if state is None or state.drawing != self.name or state.status not in (
                    "paused", "failed"):
                what = "no state file" if state is None else (
                    f"the last drawing was '{state.drawing}' ({state.status})")
                raise TattotronixError(f"nothing to resume for '{self.name}': {what}; run "
                                       "without resume=true to start from the beginning")
            if state.program != digest:
                raise TattotronixError(
                    f"the program of '{self.name}' changed since it stopped at frame "
                    f"{state.frame} (trajectory, calibration or settings): resuming would "
                    "draw a different picture; start again without resume=true")
            start = state.frame
        if state is None:
            log.warning("no arm state file (%s): assuming the arm rests at the zero pose; "
                        "the first move goes from there", self.state_file)
            state = ArmState(q=[0.0] * n)
        q_last = np.asarray(state.q, dtype=np.float64)
        session_no = self._next_session(fresh=not self.resume)
        self.run_dir.mkdir(parents=True, exist_ok=True)
        mode = "a" if self.resume else "w"  # a resume appends to the drawing's logs
        poses_fh = open(self.run_dir / "poses.jsonl", mode, encoding="utf-8")  # noqa: SIM115
        i2c_path = self.run_dir / "i2c.jsonl"
        bus: SMBusLike = RecordingBus(fail_after=self.fail_after_writes) if self.dry_run else \
            open_bus(self.calib.device, self.calib.address)
        frame = start
        status, reason = "drawing", ""
        stream: _Stream | None = None
        t0 = time.perf_counter()
        previous_term = _sigterm_as_interrupt()
        try:
            # Signals are ours, not the driver's: a stop first lifts the needle, then the
            # context switches every output off (also on any exception).
            with PCA9685(bus, self.calib.address, self.calib.oscillator_hz,
                         handle_signals=False) as board:
                board.start(self.calib.frame_hz)
                stream = _Stream(board, self.calib, prog.count_us, prog.frame_hz,
                                 self.realtime, poses_fh, session_no)
                stream.q = q_last
                state.drawing, state.program, state.frames = self.name, digest, prog.frames
                state.frame, state.status = frame, "drawing"
                # a needle left in the panel (a bus failure stops without lifting) comes
                # straight up first; then the ramp, or on resume a fresh approach
                lift = self._lift(q_last)
                for q in lift:
                    stream.send(q, "lift")
                q_up = lift[-1] if len(lift) else q_last
                lead = (self._approach(q_up, prog.q[start]) if self.resume else
                        ramp(q_up, prog.q[start], self.ramp_rad_s, prog.frame_hz))
                for q in lead:
                    stream.send(q, "approach" if self.resume else "ramp")
                save_every = max(1, int(round(self.save_every_s * prog.frame_hz)))
                try:
                    for frame in range(start, prog.frames):
                        stream.send(prog.q[frame], "draw", frame, prog.row(frame))
                        if (frame - start) % save_every == 0:
                            state.q, state.frame = stream.q.tolist(), frame + 1
                            state.save(self.state_file)
                    frame = prog.frames
                    status = "done"
                except KeyboardInterrupt:
                    reason = f"paused at frame {frame} of {prog.frames}"
                    for q in self._lift(stream.q):
                        stream.send(q, "lift")
                    status = "paused"
        except KeyboardInterrupt:  # a second Ctrl-C during the lift: outputs are off
            status, reason = "paused", f"stopped during the lift at frame {frame}"
        except BusError as exc:
            status, reason = "failed", str(exc)
        finally:
            _restore_sigterm(previous_term)
            poses_fh.close()
            if isinstance(bus, RecordingBus):
                with open(i2c_path, mode, encoding="utf-8") as fh:
                    fh.write(bus.transcript())
            if stream is not None:
                state.q = stream.q.tolist()
            state.frame = frame if status != "done" else prog.frames
            state.status = status if status != "drawing" else "failed"
            state.reason = reason
            state.save(self.state_file)
        wall = time.perf_counter() - t0
        summary: JsonDict = {"name": self.name, "backend": "arm", "dry_run": self.dry_run,
                   "status": status, "reason": reason, "frames": prog.frames,
                   "start_frame": start, "stopped_at_frame": frame,
                   "frames_sent": stream.sent if stream else 0,
                   "channel_writes": stream.writes if stream else 0,
                   "session": session_no, "wall_s": wall, "program": digest}
        if status == "paused":
            raise Paused(f"{reason}: the needle is up and every output is off; continue "
                         "with resume=true")
        if status == "failed":
            raise TattotronixError(
                f"{reason}. Stopped at frame {frame} of {prog.frames}; every output was "
                f"switched off (if the board still answers) and the state is saved in "
                f"{self.state_file}: fix the bus, then continue with resume=true")
        return summary

    def _next_session(self, fresh: bool) -> int:
        path = self.run_dir / "poses.jsonl"
        if fresh or not path.exists():
            return 1
        last = 0
        with open(path, encoding="utf-8") as fh:
            for line in fh:
                last = max(last, int(json.loads(line).get("session", 0)))
        return last + 1


def build_program(cfg: Config, desc: RobotDescription, t: Array, q: Array, qd: Array
                  ) -> tuple[ServoProgram, Calibration]:
    """The calibration from the config and the program of a timed drawing."""
    from tattotronix.hardware.program import compile_program

    calib = calibration_from_config(cfg.hardware, desc.joint_names)
    program = compile_program(t, q, qd, calib, desc.lower, desc.upper,
                              [j.velocity for j in desc.joints])
    return program, calib


def check_drawing_clear(cfg: Config, desc: RobotDescription, t: Array, q: Array) -> None:
    """Refuse, before anything reaches the bus, a drawing that collides or comes within
    ``collision.margin_mm`` (samples and the motion between them; the collision stage's
    check, run here on whatever drawing the arm is about to play).

    Raises:
        CollisionRefused: naming the time, the pose and the pair.
    """
    from tattotronix.collision.check import CollisionRefused, check_trajectory
    from tattotronix.collision.model import CollisionModel

    rep = check_trajectory(CollisionModel(desc), t, q,
                           margin_m=cfg.collision.margin_m, plunge_m=cfg.toolpath.plunge_m,
                           resolution_m=cfg.collision.resolution_m)
    if not rep.ok:
        raise CollisionRefused(rep)
    log.info("arm: the drawing is clear of collisions (least clearance %.2f mm, %s)",
             rep.min_clearance_m[rep.worst] * 1e3, rep.pair_names[rep.worst])


def draw_on_arm(cfg: Config, out: Outputs) -> JsonDict:
    """``draw.py backend=arm``: compile the drawing and stream it (see the module docstring).

    Writes ``data/runs/<name>-arm/{i2c.jsonl (dry run), poses.jsonl}``, the arm state file,
    and on completion ``data/metrics/runs/<name>-arm.json``.
    """
    from tattotronix.control.drawing import resolve_drawing
    from tattotronix.pipeline import ik_settings

    desc = build_description(cfg.robot)
    if cfg.window is not None:
        raise TattotronixError("window= is for simulated backends; the arm draws the whole "
                               "drawing (resume=true continues a stopped one)")
    drawing = resolve_drawing(cfg, out.data, desc)
    check_drawing_clear(cfg, desc, drawing.t, drawing.q)
    program, calib = build_program(cfg, desc, drawing.t, drawing.q, drawing.qd)
    clearance = float(cfg.toolpath.panel_origin[2]) + cfg.toolpath.clearance_m
    speed = float(cfg.hardware.ramp_rad_s)
    if not (np.isfinite(speed) and speed > 0):
        raise TattotronixError(f"hardware.ramp_rad_s={speed}: give a positive speed in rad/s")
    session = ArmSession(
        name=drawing.name, program=program, calib=calib, chain=Chain.from_description(desc),
        run_dir=run_dir(out.data, run_label(drawing.name, "arm")),
        state_file=out.path(*Path(str(cfg.hardware.state_file)).parts),
        clearance_z_m=clearance, feed_m_s=cfg.toolpath.feed_mark_m_s,
        ramp_rad_s=speed, ik=ik_settings(cfg.ik), dry_run=bool(cfg.dry_run),
        realtime=bool(cfg.realtime), resume=bool(cfg.resume),
        fail_after_writes=cfg.hardware.fail_after_writes,
        save_every_s=float(cfg.hardware.save_every_s))
    log.info("arm %s: %d frames at %g Hz (%.1f s), %s%s", drawing.name, program.frames,
             program.frame_hz, program.frames / program.frame_hz,
             "dry run" if session.dry_run else f"{calib.device} at 0x{calib.address:02x}",
             ", resuming" if session.resume else "")
    summary = session.run()
    summary["program_metrics"] = program.metrics(calib, session.chain)
    out.write_json(out.path("metrics", "runs", f"{drawing.name}-arm.json"), summary)
    log.info("arm %s: %s, %d frames sent, %d channel writes, %.1f s", drawing.name,
             summary["status"], summary["frames_sent"], summary["channel_writes"],
             summary["wall_s"])
    return summary
