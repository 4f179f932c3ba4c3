"""``draw.py backend=arm``: stream a servo program to the PCA9685, safely, with resume.

* Nothing reaches the bus before the drawing is proven clear of collisions with the
  margin (:func:`tattotronix.app.arm.check_drawing_clear`, the collision stage's check).
* Nothing is written before the bus is known to work: the board must answer (or the
  recording bus stand in) before a log, the state file or the session lock is touched,
  so a missing device leaves the last run's files as they were. One session at a time:
  a lock beside the state file (``state.json.lock``) refuses a second one.
* The last commanded pose lives in the state file (the servos report nothing). A session
  first lifts the needle straight up if that pose has it below the clearance height,
  then ramps slowly (``hardware.ramp_rad_s``) to the start pose.
* Frames are sent at the frame rate; only the channels whose count changed are written
  (every channel on the first frame of a session). No count leaves the calibration.
* The logs are append-only, one line per frame, numbered by ``session``: ``poses.jsonl``
  (the commanded poses) and on a dry run ``i2c.jsonl`` (the I2C writes). Each frame's
  lines are flushed as it is sent, and both logs are forced to disk before every refresh
  of the state file (every ``hardware.save_every_s``), so they are never behind it.
* **Stop**: SIGINT (Ctrl-C), SIGTERM and SIGHUP (a closed terminal, a dropped SSH) only
  note the request; the frame being sent completes, the needle is lifted straight up to
  the clearance height (a further signal does not cut the lift short), the frame index is
  saved and every output is switched off. The message says where the last pose sent left
  the needle tip. A bus error saves the frame it failed on and tries all-off (no lift:
  the bus is gone). Either way ``resume=true`` continues: it lifts first if needed, ramps
  to the point above the stopped frame, comes down along the needle at the marking feed
  (a fresh approach) and streams on from there.
* **Crash**: a process that dies (SIGKILL, a power cut, out of memory) leaves the state
  ``drawing``. ``resume=true`` treats its frame as uncertain: it takes the last pose in
  ``poses.jsonl`` as the last one commanded, lifts the needle from there first, and
  restarts :data:`RESUME_MARGIN_S` of drawing before the last frame known to be sent.
* Before anything reaches the bus, the plan is printed in one block
  (:mod:`tattotronix.hardware.preview`: duration, needle entries, the inked box on the
  panel, the start and end poses); ``preview=true`` stops there and writes
  ``preview.png`` in the run's folder.
* ``dry_run=true`` runs all of it against a recording bus, under the run's folder
  (``runs/runs/<name>-arm/`` by hand), with a state file of its own there: a dry run never changes
  what the real arm's state file (``hardware.state_file``) says about the arm.
  ``realtime=false`` skips the waits.
* Tests time their stops with the environment variable :data:`TEST_HOOK_ENV`:
  ``phase:n:action[;...]`` acts after the ``n``-th frame of ``phase`` (``lift``,
  ``ramp``, ``approach``, ``draw``) sent in the session; the action is a signal the
  process sends itself (``INT``, ``TERM``, ``HUP``, ``KILL``) or ``wait`` (say so on
  stderr, then hold until a stop is asked, at most a minute).
"""

from __future__ import annotations

import fcntl
import json
import logging
import math
import os
import signal
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path
from types import FrameType
from typing import IO

import numpy as np
from numpy.typing import NDArray

from tattotronix.config.schema import HardwareConfig
from tattotronix.errors import Interrupted, TattotronixError
from tattotronix.hardware.pca9685 import PCA9685, BusError, RecordingBus, SMBusLike, open_bus
from tattotronix.hardware.program import ServoProgram
from tattotronix.hardware.servos import Calibration, load_calibration
from tattotronix.io.artifacts import run_label
from tattotronix.io.jsontypes import JsonDict
from tattotronix.kinematics import Chain, IkOptions, solve_path

__all__ = ["DRY_RUN_STATE", "PREVIEW_IMAGE", "RESUME_MARGIN_S", "TEST_HOOK_ENV", "ArmSession",
           "ArmState", "Paused", "calibration_from_config", "ramp"]

log = logging.getLogger("tattotronix.arm")
Array = NDArray[np.float64]

#: how much drawing a resume after a crash goes back before the last frame known sent, s
RESUME_MARGIN_S = 0.5
#: a dry run's state file, in its run folder (never the real arm's)
DRY_RUN_STATE = "state.json"
#: the preview image in the run's folder (``preview=true``)
PREVIEW_IMAGE = "preview.png"
#: the test hook (module docstring); unset in normal use
TEST_HOOK_ENV = "TATTOTRONIX_ARM_TEST_HOOK"
_STOP_SIGNALS = ("SIGINT", "SIGTERM", "SIGHUP")
_HOOK_WAIT_S = 60.0
_Handler = Callable[[int, FrameType | None], object] | int | signal.Handlers | None


class Paused(Interrupted):
    """The drawing stopped on request (a stop signal: its ``signum``), after the lift and
    all-off; the message says how to resume. The stage exits with 128 + ``signum`` (130
    for Ctrl-C, a double one included)."""


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
        status: ``idle``, ``drawing`` (also what a session that died leaves), ``paused``,
            ``failed`` or ``done``.
        reason: why it stopped.
        drawn: the frames known sent so far (one past the highest), over all sessions.
        session: the session that last wrote the state (``session`` in the logs).
    """

    q: list[float]
    drawing: str | None = None
    program: str | None = None
    frame: int = 0
    frames: int = 0
    status: str = "idle"
    reason: str = ""
    saved_at: float = field(default_factory=time.time)
    drawn: int = 0
    session: int = 0

    @classmethod
    def load(cls, path: Path, n: int) -> ArmState | None:
        """Read the state file; None if there is none.

        Every field is checked (:func:`_state_problem`): a frame that is not a whole
        number within the program (``0 <= drawn``, ``frame <= frames``), a session that is
        not a whole number, an unknown status, a pose that is not ``n`` finite angles. A
        resume from a wrong frame would ink again what is drawn (or skip what is not), and
        ink cannot be undone: such a file is refused, never repaired.

        Raises:
            TattotronixError: the file is unreadable or malformed (it names the file and
                the field).
        """
        if not path.exists():
            return None
        try:
            raw = json.loads(path.read_text())
        except (OSError, ValueError) as exc:
            raise _bad_state(path, f"unreadable ({one_line_of(exc)})") from None
        problem = _state_problem(raw, n)
        if problem:
            raise _bad_state(path, problem)
        assert isinstance(raw, dict)
        return cls(**raw)

    def save(self, path: Path) -> None:
        """Write atomically and durably: a crash or a power cut leaves the old file or the
        new one, never half a file."""
        path.parent.mkdir(parents=True, exist_ok=True)
        self.saved_at = time.time()
        tmp = path.with_name(path.name + ".tmp")
        with open(tmp, "w", encoding="utf-8") as fh:
            fh.write(json.dumps(asdict(self), indent=1) + "\n")
            fh.flush()
            os.fsync(fh.fileno())
        tmp.replace(path)
        _fsync_dir(path.parent)


#: what ``status`` may say
_STATUSES = ("idle", "drawing", "paused", "failed", "done")


def one_line_of(exc: BaseException) -> str:
    """An exception's message on one line."""
    return " ".join(str(exc).split()) or type(exc).__name__


def _bad_state(path: Path, problem: str) -> TattotronixError:
    return TattotronixError(
        f"arm state file {path}: {problem}. Nothing was sent. Ink cannot be undone, so a "
        "bad state is never guessed at: if the arm rests at its zero pose and nothing of "
        "this drawing is drawn, delete the file; otherwise restore it (its frame is the next "
        "one to draw), or check the last session's poses.jsonl")


def _is_int(v: object) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def _state_problem(raw: object, n: int) -> str:
    """What is wrong with a state file's content (naming the field), or ""."""
    if not isinstance(raw, dict):
        return f"not a JSON object (got {type(raw).__name__})"
    known = [f.name for f in fields(ArmState)]
    unknown = sorted(str(k) for k in raw if k not in known)
    if unknown:
        return (f"unknown field {', '.join(repr(k) for k in unknown)} (the fields: "
                f"{', '.join(known)})")
    if "q" not in raw:
        return "field 'q' (the last commanded pose) is missing"
    q = raw["q"]
    if (not isinstance(q, list) or len(q) != n
            or not all(isinstance(v, int | float) and not isinstance(v, bool)
                       and math.isfinite(v) for v in q)):
        return f"field 'q' must be {n} finite angles in rad (got {q!r})"
    for name in ("drawing", "program"):
        if raw.get(name) is not None and not isinstance(raw[name], str):
            return f"field {name!r} must be a string or null (got {raw[name]!r})"
    for name in ("status", "reason"):
        if name in raw and not isinstance(raw[name], str):
            return f"field {name!r} must be a string (got {raw[name]!r})"
    if raw.get("status", "idle") not in _STATUSES:
        return f"field 'status' must be one of {', '.join(_STATUSES)} (got {raw['status']!r})"
    saved = raw.get("saved_at", 0.0)
    if not (isinstance(saved, int | float) and not isinstance(saved, bool)
            and math.isfinite(saved)):
        return f"field 'saved_at' must be a time in seconds (got {saved!r})"
    for name in ("frames", "session"):
        v = raw.get(name, 0)
        if not (_is_int(v) and v >= 0):
            return f"field {name!r} must be a whole number >= 0 (got {v!r})"
    frames = raw.get("frames", 0)
    for name in ("frame", "drawn"):
        v = raw.get(name, 0)
        if not (_is_int(v) and 0 <= v <= frames):
            return (f"field {name!r} must be a whole number of frames from 0 to the "
                    f"program's {frames} ('frames') (got {v!r})")
    return ""


def _fsync_dir(folder: Path) -> None:
    """Make a rename in ``folder`` durable (POSIX; a no-op where directories can't sync)."""
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


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


# ----------------------------------------------------------------------------- stops


class _StopRequests:
    """The stop signals received during a session: the handlers only note them, so that
    nothing (a second Ctrl-C included) can cut a frame or a lift short."""

    def __init__(self) -> None:
        self.signals: list[int] = []
        self._previous: dict[int, _Handler] = {}

    def install(self) -> None:
        """Handle SIGINT, SIGTERM and SIGHUP (main thread only; an ignored one stays
        ignored, as under ``nohup``)."""
        if threading.current_thread() is not threading.main_thread():
            return
        for name in _STOP_SIGNALS:
            sig = getattr(signal, name, None)
            if sig is None:  # no SIGHUP off POSIX
                continue
            previous = signal.getsignal(sig)
            if previous == signal.SIG_IGN:
                continue
            signal.signal(sig, self._note)
            self._previous[sig] = previous

    def restore(self) -> None:
        """Put the previous handlers back."""
        for sig, previous in self._previous.items():
            signal.signal(sig, signal.SIG_DFL if previous is None else previous)
        self._previous = {}

    def _note(self, signum: int, frame: FrameType | None) -> None:
        self.signals.append(signum)

    @property
    def asked(self) -> bool:
        """Whether a stop was asked."""
        return bool(self.signals)

    def names(self) -> list[str]:
        """The signals received, in order (``SIGINT``, ...)."""
        return [signal.Signals(s).name for s in self.signals]


@dataclass(frozen=True)
class _HookStep:
    phase: str
    count: int
    action: str


def _hook_steps(text: str) -> list[_HookStep]:
    """Parse :data:`TEST_HOOK_ENV` (``phase:n:action[;...]``)."""
    steps = []
    for part in filter(None, (p.strip() for p in text.split(";"))):
        bits = part.split(":")
        ok = len(bits) == 3 and bits[0] in ("lift", "ramp", "approach", "draw") and (
            bits[1].isdigit() and (bits[2] == "wait" or bits[2] in ("INT", "TERM", "HUP",
                                                                   "KILL")))
        if not ok:
            raise TattotronixError(
                f"{TEST_HOOK_ENV}={text!r}: each step is phase:n:action with phase lift, "
                "ramp, approach or draw, n a frame count, action INT, TERM, HUP, KILL or "
                "wait")
        steps.append(_HookStep(bits[0], int(bits[1]), bits[2]))
    return steps


class _SessionLock:
    """An exclusive lock beside the state file, held for a session (the kernel drops it
    when the process dies, however it dies)."""

    def __init__(self, state_file: Path):
        self.path = state_file.with_name(state_file.name + ".lock")
        self.path.parent.mkdir(parents=True, exist_ok=True)
        fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            holder = os.read(fd, 32).decode(errors="replace").strip() or "?"
            os.close(fd)
            raise TattotronixError(
                f"another arm session is running (process {holder} holds {self.path}): "
                "stop it first (Ctrl-C); two sessions must never drive the servos") from None
        os.ftruncate(fd, 0)
        os.write(fd, f"{os.getpid()}\n".encode())
        self.fd = fd

    def release(self) -> None:
        """Let the next session in."""
        fcntl.flock(self.fd, fcntl.LOCK_UN)
        os.close(self.fd)


# ----------------------------------------------------------------------------- logs


@dataclass(frozen=True)
class _LogTail:
    """The end of a ``poses.jsonl``: its last session, that session's last pose and one
    past its last drawn frame (0 when it drew none)."""

    session: int = 0
    q: tuple[float, ...] | None = None
    drawn: int = 0


def _pose_record(raw: bytes, n: int) -> tuple[int, str, int | None, tuple[float, ...]] | None:
    """A ``poses.jsonl`` line as (session, phase, frame, q); None for a torn or garbled
    one (a power cut can leave one at the end)."""
    try:
        rec = json.loads(raw)
        session, phase, frame = rec["session"], rec["phase"], rec["frame"]
        q = tuple(float(v) for v in rec["q"])
    except (ValueError, KeyError, TypeError):
        return None
    if not (_is_int(session) and isinstance(phase, str)
            and (frame is None or (_is_int(frame) and frame >= 0))
            and len(q) == n and all(math.isfinite(v) for v in q)):
        return None
    return session, phase, frame, q


def _read_tail(path: Path, n: int, block: int = 1 << 16) -> _LogTail:
    """The :class:`_LogTail` of ``path``, read backwards from its end (only as far as the
    last session's last drawn frame)."""
    if not path.exists():
        return _LogTail()
    session, q = 0, None
    with open(path, "rb") as fh:
        pos = fh.seek(0, os.SEEK_END)
        rest = b""
        while pos > 0:
            step = min(block, pos)
            pos -= step
            fh.seek(pos)
            lines = (fh.read(step) + rest).split(b"\n")
            rest = lines.pop(0) if pos > 0 else b""  # may be a line cut by the block
            for raw in reversed(lines):
                rec = _pose_record(raw, n)
                if rec is None:
                    continue
                s, phase, frame, pose = rec
                if q is None:
                    session, q = s, pose
                elif s != session:
                    return _LogTail(session, q, 0)
                if phase == "draw" and frame is not None:
                    return _LogTail(session, q, frame + 1)
    return _LogTail(session, q, 0)


class _Logs:
    """The session's append-only logs: every frame's lines are flushed as it is sent;
    :meth:`sync` forces them to disk."""

    def __init__(self, folder: Path, session: int, recorder: RecordingBus | None):
        folder.mkdir(parents=True, exist_ok=True)
        self.session = session
        self.recorder = recorder
        self.poses = self._append(folder / "poses.jsonl")
        self.i2c = self._append(folder / "i2c.jsonl") if recorder is not None else None
        self._drained = 0

    @staticmethod
    def _append(path: Path) -> IO[str]:
        """Open for appending, after ending a line a crash may have left torn."""
        torn = False
        if path.exists() and path.stat().st_size > 0:
            with open(path, "rb") as fh:
                fh.seek(-1, os.SEEK_END)
                torn = fh.read(1) != b"\n"
        out = open(path, "a", encoding="utf-8")  # noqa: SIM115
        if torn:
            out.write("\n")
        return out

    def _drain(self) -> None:
        if self.recorder is None or self.i2c is None:
            return
        for w in self.recorder.writes[self._drained:]:
            self.i2c.write(json.dumps({"session": self.session, **w}) + "\n")
        self._drained = len(self.recorder.writes)

    def pose(self, phase: str, frame: int | None, q: Array, counts: dict[int, int]) -> None:
        """Log a frame just sent (its I2C writes first), and flush."""
        self._drain()
        self.poses.write(json.dumps({"session": self.session, "phase": phase, "frame": frame,
                                     "q": [round(float(v), 9) for v in q],
                                     "counts": {str(k): v for k, v in counts.items()}}) + "\n")
        self.flush()

    def flush(self) -> None:
        """Hand every line to the operating system (survives the process, not a power cut)."""
        self._drain()
        for fh in (self.poses, self.i2c):
            if fh is not None:
                fh.flush()

    def sync(self) -> None:
        """Flush and force to disk (survives a power cut)."""
        self.flush()
        for fh in (self.poses, self.i2c):
            if fh is not None:
                os.fsync(fh.fileno())

    def close(self) -> None:
        """Sync and close."""
        try:
            self.sync()
        finally:
            self.poses.close()
            if self.i2c is not None:
                self.i2c.close()


class _Stream:
    """Sends frames to the board: changed channels only, paced, logged."""

    def __init__(self, board: PCA9685, calib: Calibration, count_us: float, frame_hz: float,
                 realtime: bool, logs: _Logs, stop: _StopRequests, hook: list[_HookStep]):
        self.board = board
        self.calib = calib
        self.count_us = count_us
        self.period = 1.0 / frame_hz
        self.realtime = realtime
        self.logs = logs
        self.stop = stop
        self.hook = hook
        self.last: dict[int, int] = {}
        self.q = np.zeros(len(calib.joints))
        self.sent = 0
        self.writes = 0
        self.by_phase: dict[str, int] = {}
        self.late_s: list[float] = []  # how late each paced frame went out, s
        self._next = time.perf_counter()

    def send(self, q: Array, phase: str, frame: int | None = None,
             counts: dict[int, int] | None = None) -> None:
        counts = counts if counts is not None else self.calib.counts(q, self.count_us)
        if self.realtime:
            due = self._next
            delay = due - time.perf_counter()
            if delay > 0:
                time.sleep(delay)
            now = time.perf_counter()
            self.late_s.append(now - due)
            self._next = max(due + self.period, now - self.period)
        for ch, c in counts.items():
            if self.last.get(ch) != c:
                self.board.set_counts(ch, c)
                self.last[ch] = c
                self.writes += 1
        self.q = np.asarray(q, dtype=np.float64).copy()
        self.sent += 1
        self.logs.pose(phase, frame, self.q, counts)
        k = self.by_phase[phase] = self.by_phase.get(phase, 0) + 1
        for step in self.hook:
            if step.phase == phase and step.count == k:
                self._act(step)

    def _act(self, step: _HookStep) -> None:
        if step.action != "wait":
            noted = len(self.stop.signals)
            os.kill(os.getpid(), getattr(signal, f"SIG{step.action}"))
            deadline = time.monotonic() + 1.0  # let the handler note it before going on
            while len(self.stop.signals) == noted and time.monotonic() < deadline:
                time.sleep(0.001)
            return
        print(f"arm test hook: waiting at {step.phase} {step.count} (pid {os.getpid()})",
              file=sys.stderr, flush=True)
        deadline = time.monotonic() + _HOOK_WAIT_S
        while not self.stop.asked and time.monotonic() < deadline:
            time.sleep(0.01)


# ----------------------------------------------------------------------------- session


@dataclass(frozen=True)
class _Start:
    """Where a session starts: the first frame to send, the pose the arm was last sent,
    the frames known drawn, and whether the last session died without stopping."""

    frame: int
    q: Array
    drawn: int
    crashed: bool


@dataclass
class _SessionRun:
    """How far a session got (the parts of :meth:`ArmSession._session` share it).

    Attributes:
        start: the program frame it started drawing from.
        stage: ``start``, then ``lift`` (the first one), ``ramp`` or ``approach``,
            ``draw``, and ``stop`` (the lift after a stop request).
        stopped_in: the stage a stop request ended ("" if none did).
        lifted: frames of the last lift (the first one, or the one after a stop).
        status: ``drawing``, then ``done``, ``paused`` or ``failed``.
        error: what failed it.
        outputs_off: every output was switched off at the end.
        stream: the frame stream, once the board started.
    """

    start: int
    stage: str = "start"
    stopped_in: str = ""
    lifted: int = 0
    status: str = "drawing"
    error: TattotronixError | None = None
    outputs_off: bool = False
    stream: _Stream | None = None


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
        surface_z_m: the panel surface's height (arm frame), m.
        feed_m_s: the approach feed (the marking feed), m/s.
        ramp_rad_s: the fastest joint speed of ramps, rad/s.
        ik: IK keyword arguments for lifts and approaches (``kinematics.ik_options``).
        dry_run, realtime, resume: as configured.
        park: lift the needle from where the last session of this drawing left the arm and
            switch every output off, drawing nothing (the stop of a job whose process
            died); the state keeps where the drawing stopped, for a later resume.
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
    surface_z_m: float
    feed_m_s: float
    ramp_rad_s: float
    ik: IkOptions
    dry_run: bool = True
    realtime: bool = True
    resume: bool = False
    park: bool = False
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

    def _needle(self, q: Array) -> str:
        """Where ``q`` puts the needle tip, for a message."""
        z = float(self.chain.fk(q)[0][0, 2])
        c, s = self.clearance_z_m * 1e3, self.surface_z_m * 1e3
        if z >= self.clearance_z_m - 1e-5:
            return (f"{z * 1e3:.2f} mm, {z * 1e3 - s:.2f} mm above the surface ({s:.2f} mm): "
                    f"at or above the clearance height {c:.2f} mm")
        if z > self.surface_z_m:
            return (f"{z * 1e3:.2f} mm, {z * 1e3 - s:.2f} mm above the surface ({s:.2f} mm) "
                    f"but below the clearance height {c:.2f} mm")
        return (f"{z * 1e3:.2f} mm, {s - z * 1e3:.2f} mm INTO the work (the surface is at "
                f"{s:.2f} mm): the needle may be in it")

    def _poses_of(self, drawing: str) -> Path:
        return self.run_dir.parent / run_label(drawing, "arm") / "poses.jsonl"

    # -------------------------------------------------------------- the run

    def _begin(self, state: ArmState | None, digest: str) -> _Start:
        """Where this session starts, from the state (and after a crash, the pose log).

        Raises:
            TattotronixError: a resume with nothing to resume, or of a changed program.
        """
        n = len(self.calib.joints)
        if state is None:
            if self.park:
                raise TattotronixError(f"nothing to park for '{self.name}': no state file, so"
                                       " the arm's pose is unknown; nothing was sent")
            if self.resume:
                raise TattotronixError(f"nothing to resume for '{self.name}': no state file;"
                                       " run without resume=true to start from the beginning")
            return _Start(0, np.zeros(n), 0, crashed=False)
        q = np.asarray(state.q, dtype=np.float64)
        crashed = state.status == "drawing"
        tail = _LogTail()
        if crashed and state.drawing:
            tail = _read_tail(self._poses_of(state.drawing), n)
            if tail.session != state.session or tail.q is None:
                tail = _LogTail()  # not the log of that session: the state is all we know
            else:
                q = np.asarray(tail.q, dtype=np.float64)  # the last pose it sent
        if not (self.resume or self.park):
            return _Start(0, q, 0, crashed)
        if state.drawing != self.name or state.status not in ("paused", "failed", "drawing"):
            raise TattotronixError(
                f"nothing to resume for '{self.name}': the last drawing was "
                f"'{state.drawing}' ({state.status}); run without resume=true to start from "
                "the beginning")
        if state.program != digest:
            raise TattotronixError(
                f"the program of '{self.name}' changed since it stopped at frame "
                f"{state.frame} (trajectory, calibration or settings): resuming would "
                "draw a different picture; start again without resume=true")
        if state.frames != self.program.frames:
            raise _bad_state(self.state_file, (
                f"field 'frames' is {state.frames}, but the program of '{self.name}' it "
                f"names (program {digest}) has {self.program.frames} frames"))
        if not crashed:
            return _Start(state.frame, q, max(state.drawn, state.frame), crashed=False)
        if tail.drawn > self.program.frames:
            raise TattotronixError(
                f"{self._poses_of(self.name)} says frame {tail.drawn - 1} was drawn, past the "
                f"program's {self.program.frames} frames: not the log of this drawing; "
                "nothing was sent (restore the log, or start again without resume=true)")
        known = max(state.drawn, state.frame, tail.drawn)
        margin = int(round(RESUME_MARGIN_S * self.program.frame_hz))
        return _Start(max(0, known - margin), q, known, crashed=True)

    def run(self) -> JsonDict:
        """Lift if needed, ramp or approach, stream, and stop safely (module docstring).

        Raises:
            Paused: a stop signal (after the lift and all-off; state saved).
            TattotronixError: a bus error (state saved), a refused resume, a missing
                device, another session running.
        """
        hook = _hook_steps(os.environ.get(TEST_HOOK_ENV, ""))
        # refuse early, and touch nothing before the bus answers
        self._begin(ArmState.load(self.state_file, len(self.calib.joints)),
                    self.program.digest())
        bus: SMBusLike = RecordingBus(fail_after=self.fail_after_writes) if self.dry_run else \
            open_bus(self.calib.device, self.calib.address)
        try:
            lock = _SessionLock(self.state_file)
            try:
                return self._session(bus, hook)
            finally:
                lock.release()
        finally:
            bus.close()

    def _save(self, state: ArmState, stream: _Stream, logs: _Logs) -> None:
        """The logs to disk first, then the state: the logs are never behind it."""
        state.q = stream.q.tolist()
        logs.sync()
        state.save(self.state_file)

    def _session(self, bus: SMBusLike, hook: list[_HookStep]) -> JsonDict:
        """One session on the board: the state it starts from, the frames
        (:meth:`_play_session`), every output off whatever happened, then the state saved
        with its reason (:meth:`_reason`) and the summary (:meth:`_summary`)."""
        prog = self.program
        digest = prog.digest()
        loaded = ArmState.load(self.state_file, len(self.calib.joints))  # the lock is ours
        begin = self._begin(loaded, digest)
        state = self._open_state(loaded, begin, digest)
        logs = _Logs(self.run_dir, state.session,
                     bus if isinstance(bus, RecordingBus) else None)
        run = _SessionRun(begin.frame)
        t0 = time.perf_counter()
        board = PCA9685(bus, self.calib.address, self.calib.oscillator_hz,
                        handle_signals=False)
        stop = _StopRequests()
        stop.install()
        try:
            try:
                board.start(self.calib.frame_hz)
                run.stage = "lift"
                run.stream = _Stream(board, self.calib, prog.count_us, prog.frame_hz,
                                     self.realtime, logs, stop, hook)
                run.stream.q = begin.q.copy()
                self._save(state, run.stream, logs)
                self._play_session(run, run.stream, state, begin.q, stop, logs)
            except TattotronixError as exc:  # a bus error; an unreachable lift
                run.status, run.error = "failed", exc
            finally:
                try:
                    board.all_off()
                    run.outputs_off = True
                except BusError as exc:
                    log.error("switching the PCA9685 outputs off failed: %s", exc)
                    if run.error is None:
                        run.status, run.error = "failed", exc
        finally:
            if run.stream is not None:
                state.q = run.stream.q.tolist()
            state.status = run.status if run.status != "drawing" else "failed"
            state.reason = self._reason(run, state, stop)
            try:
                logs.close()
            finally:
                state.save(self.state_file)
                stop.restore()
        return self._summary(run, state, begin, time.perf_counter() - t0, stop)

    def _open_state(self, loaded: ArmState | None, begin: _Start, digest: str) -> ArmState:
        """The state this session starts from and keeps up to date: the saved one (or, with
        none, the arm at rest at the zero pose), now this drawing's, at ``begin``, in a new
        session."""
        prog = self.program
        n = len(self.calib.joints)
        margin = int(round(RESUME_MARGIN_S * prog.frame_hz))
        if loaded is None:
            log.warning("no arm state file (%s): assuming the arm rests at the zero pose; "
                        "the first move goes from there", self.state_file)
            state = ArmState(q=[0.0] * n)
        else:
            state = loaded
            if begin.crashed:
                log.warning(
                    "the last session (of '%s') died without stopping: taking the last pose "
                    "it sent as the arm's and lifting the needle from there first%s",
                    state.drawing, f"; {begin.drawn} frames known sent, going back "
                    f"{begin.drawn - begin.frame} (at most {margin}) to frame {begin.frame}"
                    if self.resume else "")
        session_no = max(_read_tail(self.run_dir / "poses.jsonl", n).session,
                         state.session if state.drawing == self.name else 0) + 1
        state.drawing, state.program, state.frames = self.name, digest, prog.frames
        state.session, state.frame, state.drawn = session_no, begin.frame, begin.drawn
        state.status, state.reason, state.q = "drawing", "", begin.q.tolist()
        return state

    def _play_session(self, run: _SessionRun, st: _Stream, state: ArmState, q_start: Array,
                      stop: _StopRequests, logs: _Logs) -> None:
        """Send the frames: the lift from where the arm is (never cut short), the ramp (or
        on resume the approach) to the first frame, the drawing, and after a stop request
        the lift; ``run`` says how far it got."""
        prog = self.program
        start = run.start
        save_every = max(1, int(round(self.save_every_s * prog.frame_hz)))

        def play(frames: Array, phase: str, interruptible: bool) -> bool:
            for q in frames:
                if interruptible and stop.asked:
                    return False
                st.send(q, phase)
                if st.sent % save_every == 0:
                    self._save(state, st, logs)
            return True

        # a needle left in the work (a bus failure or a crash stops without a lift) comes
        # straight up first; a stop signal waits for that lift
        lift = self._lift(q_start)
        play(lift, "lift", interruptible=False)
        run.lifted = len(lift)
        if self.park:  # nothing drawn: lifted, then every output off (the caller)
            run.status, run.stopped_in = "paused", "park"
            return
        run.stage = "approach" if self.resume else "ramp"
        lead = (self._approach(st.q, prog.q[start]) if self.resume else
                ramp(st.q, prog.q[start], self.ramp_rad_s, prog.frame_hz))
        if stop.asked:
            run.stopped_in = "lift"
        elif not play(lead, run.stage, interruptible=True):
            run.stopped_in = run.stage
        else:
            run.stage = "draw"
            for frame in range(start, prog.frames):
                if stop.asked:
                    run.stopped_in = "draw"
                    break
                st.send(prog.q[frame], "draw", frame, prog.row(frame))
                state.frame, state.drawn = frame + 1, max(state.drawn, frame + 1)
                if st.sent % save_every == 0:
                    self._save(state, st, logs)
            else:
                run.status = "done"
        if run.stopped_in and run.stopped_in != "lift":
            run.stage = "stop"
            lift = self._lift(st.q)
            play(lift, "lift", interruptible=False)
            run.lifted = len(lift)
        if run.stopped_in:
            run.status = "paused"

    def _reason(self, run: _SessionRun, state: ArmState, stop: _StopRequests) -> str:
        """Why the session ended where it did, and in what state it left the arm (the
        state file's ``reason``; "" when done)."""
        start = run.start
        where = {"start": "while starting the board, before any frame was sent",
                 "lift": f"during the first lift, before frame {start}",
                 "ramp": f"during the ramp to frame {start}",
                 "approach": f"during the approach to frame {start}",
                 "draw": f"while drawing, at frame {state.frame} of {self.program.frames}",
                 "stop": f"during the lift after a stop at frame {state.frame}"}
        needle = self._needle(np.asarray(state.q, dtype=np.float64))
        if run.status == "done":
            return ""
        if run.stopped_in == "park":
            return (f"parked at frame {state.frame} of {self.program.frames}: "
                    + (f"the needle lifted to the clearance height ({run.lifted} frames)"
                       if run.lifted else "the needle was already at the clearance height")
                    + f"; the last pose sent has the needle tip at {needle}; every output "
                    "is off")
        if run.status == "paused":
            names = stop.names()
            later = (f" (then {', '.join(names[1:])}: noted and ignored, so as never to"
                     " cut a lift short)" if len(names) > 1 else "")
            return (f"{names[0]} {where[run.stopped_in]}: "
                    + ("the lift to the clearance height completed" if run.lifted else
                       "no lift was needed")
                    + f"; the last pose sent has the needle tip at {needle}; every output "
                    f"is off{later}")
        return (f"{run.error or 'an unexpected error'}. Stopped {where[run.stage]}; the last "
                f"pose fully sent has the needle tip at {needle}; "
                + {"start": "nothing was sent", "lift": "the first lift did not complete",
                   "stop": "the lift did not complete"}.get(run.stage, "no lift was tried")
                + "; switching every output off "
                + ("went through" if run.outputs_off else
                   "failed too: the servos may still hold that pose"))

    def _summary(self, run: _SessionRun, state: ArmState, begin: _Start, wall_s: float,
                 stop: _StopRequests) -> JsonDict:
        """The session's summary when done.

        Raises:
            Paused: a stop request ended it (with the needle lifted); not a park's.
            TattotronixError: it failed (the state file says where, for ``resume=true``).
        """
        prog, stream = self.program, run.stream
        summary: JsonDict = {
            "name": self.name, "backend": "arm", "dry_run": self.dry_run,
            "status": run.status, "reason": state.reason, "frames": prog.frames,
            "start_frame": run.start,
            "stopped_at_frame": state.frame if run.status != "done" else prog.frames,
            "after_crash": begin.crashed,
            "frames_sent": stream.sent if stream else 0,
            "channel_writes": stream.writes if stream else 0,
            "session": state.session, "wall_s": wall_s, "program": state.program}
        if stream is not None and stream.late_s:  # paced: how late the frames went out
            late = np.asarray(stream.late_s) * 1e3
            summary["late_ms"] = {"median": round(float(np.median(late)), 3),
                                  "p99": round(float(np.percentile(late, 99)), 3),
                                  "worst": round(float(late.max()), 3),
                                  "over_a_frame": int((late > 1e3 * stream.period).sum())}
        if run.stopped_in == "park":
            summary["status"] = "parked"
            return summary
        if run.status == "paused":
            raise Paused(f"{state.reason}. Continue with resume=true", stop.signals[0])
        if run.status == "failed":
            raise TattotronixError(
                f"{state.reason}. The state is saved in {self.state_file}: fix the cause, "
                "then continue with resume=true (it lifts the needle first)")
        return summary
