"""The server's one job at a time: its process, its controls and its live state.

A job plays a plan on the arm in a process of its own (:mod:`~tattotronix.server.runner`)
so that the arm's stop handling (signals, in that process's main thread) works as it does
for ``draw.py``: **pause** sends SIGINT, and the arm stops at its next frame with the
needle lifted to the clearance height and every output off; **resume** starts the process
again with ``resume=true`` (the arm approaches again as its own resume does); **stop**
sends SIGTERM to a drawing job (the same lift and all-off) and ends the job, so it is not
offered to resume. The job's state is the arm's state file (the frame reached, the
status, the last pose) and the runner's result; the server reads both, so a browser that
connects mid-job, or a server restarted after a crash, finds the job where it is (a job
whose process is gone while drawing is offered to resume: the arm lifts first).
"""

from __future__ import annotations

import json
import logging
import os
import secrets
import signal
import subprocess
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, cast

import numpy as np

from tattotronix.app.arm import state_file_of
from tattotronix.errors import TattotronixError
from tattotronix.hardware.arm import ArmState
from tattotronix.io.artifacts import run_dir, run_label
from tattotronix.io.jsontypes import JsonDict
from tattotronix.kinematics import Chain
from tattotronix.server.plans import StoredPlan
from tattotronix.server.runner import JOB_FILE, LOG_FILE, RESULT_FILE, JobSpec

__all__ = ["Job", "JobConflict", "JobManager"]

log = logging.getLogger("tattotronix.server")

#: statuses of a job that has a process (or is about to)
ACTIVE = ("starting", "drawing", "pausing", "stopping")


class JobConflict(TattotronixError):
    """An action the job's state does not allow (HTTP 409): the message says why."""


@dataclass
class Job:
    """One job: a plan drawn on the arm (a dry run unless ``dry_run`` is False).

    Attributes:
        id: the job's id (its folder's name).
        folder: ``<server>/jobs/<id>``.
        spec: what the runner reads (``job.json``).
        state_file: the arm's state file the job's sessions keep.
        duration_s: the plan's duration, s (for the time remaining).
        status: ``starting``, ``drawing``, ``pausing``, ``paused``, ``stopping``,
            ``stopped``, ``done``, ``failed``, or ``resumable`` (found after a restart).
        message: the last thing said about it.
        process: the runner, while it runs (None after a restart: ``pid`` is followed).
        pid: the runner's process id.
        stop_asked: a stop (not a pause) was asked.
    """

    id: str
    folder: Path
    spec: JobSpec
    state_file: Path
    duration_s: float
    status: str = "starting"
    message: str = ""
    process: subprocess.Popen[bytes] | None = field(default=None, repr=False)
    pid: int | None = None
    stop_asked: bool = False
    started_at: float = field(default_factory=time.time)
    pid_start: str | None = None

    def save(self) -> None:
        """Write ``job.json`` (the runner's spec and the server's view of the job)."""
        doc = {**self.spec, "id": self.id, "state_file": str(self.state_file),
               "duration_s": self.duration_s, "status": self.status,
               "message": self.message, "pid": self.pid, "pid_start": self.pid_start,
               "stop_asked": self.stop_asked,
               "started_at": self.started_at}
        tmp = self.folder / f".{JOB_FILE}.tmp"
        tmp.write_text(json.dumps(doc, indent=1) + "\n", encoding="utf-8")
        tmp.replace(self.folder / JOB_FILE)


def _start_time(pid: int) -> str | None:
    """When the process ``pid`` started (Linux: field 22 of ``/proc/<pid>/stat``, in clock
    ticks since boot); None where that is not known."""
    try:
        stat_line = Path(f"/proc/{pid}/stat").read_text(encoding="ascii", errors="replace")
    except OSError:
        return None
    fields = stat_line.rpartition(")")[2].split()
    return fields[19] if len(fields) > 19 else None


def _is_runner(job: Job) -> bool:
    """Whether the job's runner still runs: its pid alive, and the same process (its start
    time unchanged: a pid the system gave to another process since is not it)."""
    if not _alive(job.pid):
        return False
    return job.pid_start is None or job.pid is None or _start_time(job.pid) in (
        None, job.pid_start)


def _alive(pid: int | None) -> bool:
    """Whether the process ``pid`` runs (a zombie, dead but not yet reaped, does not)."""
    if pid is None:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    try:  # Linux: the state letter after the command's closing parenthesis
        stat_line = Path(f"/proc/{pid}/stat").read_text(encoding="ascii", errors="replace")
    except OSError:
        return True
    return stat_line.rpartition(")")[2].split()[:1] != ["Z"]


def _last_line(file: Path) -> str:
    try:
        with file.open("rb") as f:
            f.seek(max(0, f.seek(0, os.SEEK_END) - 4096))
            lines = f.read().decode("utf-8", "replace").strip().splitlines()
    except OSError:
        return ""
    return lines[-1].split(": ", 1)[-1] if lines else ""


class JobManager:
    """The jobs of one server, under ``<folder>/jobs/``; one runs at a time."""

    def __init__(self, folder: Path, python: str = sys.executable):
        self.server = folder
        self.folder = folder / "jobs"
        self.folder.mkdir(parents=True, exist_ok=True)
        self.python = python
        self.job: Job | None = None
        self._chains: dict[str, Chain] = {}
        self._lock = threading.RLock()
        self._recover()

    # ---------------------------------------------------------------- recovery
    def _recover(self) -> None:
        """After a (re)start: the newest job, followed if its runner still runs, offered
        to resume if it stopped part-way."""
        specs = sorted(self.folder.glob(f"*/{JOB_FILE}"), key=lambda p: p.stat().st_mtime)
        if not specs:
            return
        try:
            doc = json.loads(specs[-1].read_text(encoding="utf-8"))
            job = self._job_of(doc, specs[-1].parent)
        except (OSError, ValueError, KeyError, TypeError) as exc:
            log.warning("the last job's %s is unreadable (%s): no job is offered to resume; "
                        "the arm's state file is untouched", specs[-1], exc)
            return
        self.job = job
        if job.status in ACTIVE and not _is_runner(job):
            if (job.folder / RESULT_FILE).exists():  # it ended while the server was down
                self._finish(job, -1)
            else:
                job.status, job.message = "resumable", (
                    "the server stopped while this job ran: resume it (the arm lifts the "
                    "needle first and approaches again) or stop it")
                job.save()
        self._refresh()

    @staticmethod
    def _job_of(doc: dict[str, Any], folder: Path) -> Job:
        return Job(id=str(doc["id"]), folder=folder,
                  spec=cast(JobSpec, {k: doc[k] for k in JobSpec.__annotations__
                                      if k in doc}),
                  state_file=Path(doc["state_file"]), duration_s=float(doc["duration_s"]),
                  status=str(doc["status"]), message=str(doc.get("message", "")),
                  pid=doc.get("pid"), stop_asked=bool(doc.get("stop_asked")),
                  started_at=float(doc.get("started_at", time.time())),
                  pid_start=doc.get("pid_start"))

    # ---------------------------------------------------------------- actions
    def start(self, stored: StoredPlan, *, dry_run: bool = True, realtime: bool = True,
              arm_overrides: tuple[str, ...] = ()) -> Job:
        """Start drawing ``stored`` on the arm.

        Raises:
            JobConflict: a job is drawing, pausing or stopping (or paused: stop or resume
                it first).
        """
        with self._lock:
            self._refresh()
            cur = self.job
            if cur is not None and cur.status in (*ACTIVE, "paused", "resumable"):
                raise JobConflict(
                    f"job {cur.id} ({cur.spec['name']}) is {cur.status}: "
                    + ("pause or stop it first" if cur.status in ACTIVE else
                       "resume or stop it first"))
            jid = time.strftime("%Y%m%d-%H%M%S-") + secrets.token_hex(3)
            folder = self.folder / jid
            folder.mkdir(parents=True)
            from tattotronix.app.api import settings_of
            from tattotronix.server.runner import arm_settings

            # the real arm is always paced at its frame rate; its state file (and lock) is
            # the one draw.py keeps (hardware.state_file under paths.data, from where the
            # server runs), so the two never drive the servos at once
            spec: JobSpec = {"plan": stored.id, "plan_data": str(stored.data),
                    "name": stored.plan.name, "overrides": list(stored.plan.overrides),
                    "dry_run": bool(dry_run), "realtime": bool(realtime) or not dry_run,
                    "resume": False, "park": False, "server": str(self.server),
                    "arm_overrides": list(arm_overrides)}
            cfg = settings_of(arm_settings(spec))
            data = self.server if dry_run else Path(cfg.paths.data).resolve()
            spec["data"] = str(data)
            spec["panel_origin"] = [float(c) for c in cfg.toolpath.panel_origin]
            state = state_file_of(cfg, data,
                                  run_dir(folder, run_label(stored.plan.name, "arm")))
            job = Job(jid, folder, spec, state, float(stored.plan.trajectory.duration_s))
            self._chains[jid] = Chain.from_description(stored.plan.desc)
            self.job = job
            self._launch(job, "starting: compiling the servo program, then the first lift")
            return job

    def _launch(self, job: Job, message: str) -> None:
        (job.folder / RESULT_FILE).unlink(missing_ok=True)
        job.save()
        log = (job.folder / "runner.out").open("ab")
        job.process = subprocess.Popen(
            [self.python, "-m", "tattotronix.server.runner", str(job.folder)],
            stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
        log.close()
        job.pid, job.status, job.message = job.process.pid, "starting", message
        job.pid_start = _start_time(job.pid)
        job.stop_asked = False
        job.save()

    def pause(self) -> Job:
        """Ask the drawing job to stop at its next frame with the needle lifted.

        Raises:
            JobConflict: no job is drawing.
        """
        with self._lock:
            job = self._active("pause")
            self._signal(job, signal.SIGINT)
            job.status, job.message = "pausing", (
                "pausing: the arm stops at its next frame and lifts the needle to the "
                "clearance height")
            job.save()
            return job

    def resume(self) -> Job:
        """Continue a paused (or interrupted) job from where it stopped.

        Raises:
            JobConflict: no job is paused.
        """
        with self._lock:
            self._refresh()
            job = self.job
            if job is None or job.status not in ("paused", "resumable", "failed"):
                raise JobConflict("no job to resume: " + (
                    f"job {job.id} is {job.status}" if job else "no job yet"))
            # continue only what this job drew: one stopped before its first frame starts
            # afresh (the arm's state may be another job's of the same drawing)
            poses = run_dir(job.folder, run_label(str(job.spec["name"]), "arm")) / "poses.jsonl"
            job.spec["resume"] = poses.is_file() and poses.stat().st_size > 0
            job.spec["park"] = False
            self._chains.setdefault(job.id, self._chain_of(job))
            self._launch(job, "resuming: the lift, then the approach to where it stopped")
            return job

    def stop(self) -> Job:
        """End the job: a drawing one stops at its next frame with the needle lifted and
        every output off; one whose process died (a failure, a server that stopped while
        it ran) is parked: a process lifts the needle from the last pose sent and switches
        every output off. A stopped job is not offered to resume.

        Raises:
            JobConflict: no job, or it has ended.
        """
        with self._lock:
            self._refresh()
            job = self.job
            if job is None or job.status in ("stopped", "done"):
                raise JobConflict("no job to stop: " + (
                    f"job {job.id} is {job.status}" if job else "no job yet"))
            job.stop_asked = True
            if job.status in ACTIVE:
                self._signal(job, signal.SIGTERM)
                job.status, job.message = "stopping", (
                    "stopping: the arm stops at its next frame, lifts the needle and "
                    "switches every output off")
            elif job.status in ("resumable", "failed") and job.state_file.exists():
                # its process died where it was: the needle may be in the work
                job.spec["park"], job.spec["resume"] = True, False
                self._launch(job, "stopping: lifting the needle from the last pose sent, "
                             "then switching every output off")
                job.status, job.stop_asked = "stopping", True
                job.save()
            else:
                job.status, job.message = "stopped", "stopped: " + job.message
            job.save()
            return job

    def _active(self, action: str) -> Job:
        self._refresh()
        job = self.job
        if job is None or job.status not in ("starting", "drawing"):
            raise JobConflict(f"no job to {action}: " + (
                f"job {job.id} is {job.status}" if job else "no job yet"))
        return job

    def _signal(self, job: Job, sig: signal.Signals) -> None:
        if job.pid is None or not _is_runner(job):
            return
        try:
            os.kill(job.pid, sig)
        except ProcessLookupError:
            return
        except PermissionError:
            raise JobConflict(f"the job's process ({job.pid}) is not this server's to "
                              "signal") from None

    # ---------------------------------------------------------------- state
    def _chain_of(self, job: Job) -> Chain:
        from tattotronix.app.api import settings_of
        from tattotronix.robot.description import build_description

        return Chain.from_description(build_description(settings_of(job.spec["overrides"])
                                                        .robot))

    def _refresh(self) -> None:
        """The job's status from its process and its result."""
        job = self.job
        if job is None or job.status not in ACTIVE:
            return
        code = job.process.poll() if job.process is not None else (
            None if _is_runner(job) else -1)
        if code is None:
            if job.status == "starting" and job.state_file.exists():
                state = self._arm_state(job)
                if state is not None and state.drawing == job.spec["name"] and (
                        state.status == "drawing" and state.saved_at >= job.started_at):
                    job.status, job.message = "drawing", "drawing"
            return
        self._finish(job, code)

    def _finish(self, job: Job, code: int) -> None:
        """The job's status from the result its runner left (or its exit ``code``)."""
        result = self._result(job)
        status = str(result.get("status", "failed"))
        job.message = str(result.get("message", "")) or f"the runner ended with code {code}"
        if job.spec.get("park") and status == "failed":
            job.message = "the lift failed (stop again to retry, or resume): " + job.message
        elif job.stop_asked and status in ("paused", "failed"):
            status = "stopped"
        job.status = status
        job.process = None
        job.save()

    def _result(self, job: Job) -> dict[str, Any]:
        try:
            doc = json.loads((job.folder / RESULT_FILE).read_text(encoding="utf-8"))
        except (OSError, ValueError):
            return {"status": "failed", "message": "the job's process ended without a "
                    "result: " + _last_line(job.folder / "runner.out")}
        return doc if isinstance(doc, dict) else {}

    def _arm_state(self, job: Job) -> ArmState | None:
        try:
            return ArmState.load(job.state_file, len(self._chain(job).joint_names))
        except TattotronixError:
            return None

    def _chain(self, job: Job) -> Chain:
        if job.id not in self._chains:
            self._chains[job.id] = self._chain_of(job)
        return self._chains[job.id]

    def state(self) -> JsonDict | None:
        """The job's live state (None: no job yet): ``status``, ``message``, the frame
        reached of ``frames``, ``share`` done, ``remaining_s``, the needle tip ``tip_mm``
        (panel u, v, height above the surface) and the runner's last log line."""
        with self._lock:
            self._refresh()
            job = self.job
            if job is None:
                return None
            out: JsonDict = {"id": job.id, "plan": job.spec.get("plan"),
                             "name": job.spec.get("name"), "status": job.status,
                             "message": job.message, "dry_run": job.spec.get("dry_run"),
                             "frame": 0, "frames": 0, "share": 0.0,
                             "remaining_s": job.duration_s, "tip_mm": None,
                             "log": _last_line(job.folder / LOG_FILE)}
            state = self._arm_state(job) if job.state_file.exists() else None
            if state is not None and state.drawing == job.spec.get("name"):
                share = state.frame / state.frames if state.frames else 0.0
                out.update(frame=state.frame, frames=state.frames, share=round(share, 4),
                           remaining_s=round(job.duration_s * (1.0 - share), 1),
                           arm_status=state.status, reason=state.reason)
                tcp, _ = self._chain(job).fk(np.asarray([state.q], dtype=np.float64))
                origin = np.asarray(job.spec.get("panel_origin", (0.0, 0.0, 0.0)), float)
                out["tip_mm"] = [round(float(c), 2) for c in (tcp[0] - origin) * 1e3]
            return out
