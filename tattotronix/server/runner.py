"""A job's process: play a saved plan on the arm (``python -m tattotronix.server.runner
JOB_FOLDER``).

The server starts one per job, and again to resume it. ``JOB_FOLDER/job.json`` says what
to draw: the plan's stages' files (``plan_data``, :meth:`tattotronix.app.api.Plan.save`),
its name and settings (``overrides``), and ``dry_run``, ``realtime`` and ``resume``. The
arm's own stop handling does the rest: SIGINT or SIGTERM stop it at the next frame with
the needle lifted to the clearance height and every output off, and the state file keeps
where it stopped for a resume (:class:`tattotronix.hardware.arm.ArmSession`).

At exit it writes ``JOB_FOLDER/result.json``: ``status`` (``done``, ``paused`` or
``failed``; ``stopped`` after a park) and ``message``; its log is ``JOB_FOLDER/runner.log``.
"""

from __future__ import annotations

import json
import logging
import signal
import sys
from pathlib import Path
from typing import TypedDict

from tattotronix.errors import Interrupted, TattotronixError
from tattotronix.io.jsontypes import JsonDict

__all__ = ["JOB_FILE", "RESULT_FILE", "JobSpec", "main", "run_job"]

JOB_FILE = "job.json"
RESULT_FILE = "result.json"
LOG_FILE = "runner.log"

log = logging.getLogger("tattotronix.server.runner")


class JobSpec(TypedDict, total=False):
    """What a job draws and how (``job.json``, written by the server).

    Attributes:
        plan: the plan's id; plan_data: its stages' files; name: the drawing's name.
        overrides: the plan's settings; arm_overrides: further ``hardware.*`` settings.
        dry_run, realtime, resume: as ``draw.py backend=arm`` takes them.
        park: only lift the needle from where the job's last process left the arm and
            switch every output off (the stop of a job whose process died).
        server: the server's folder; data: where the arm's state file lives.
        panel_origin: the panel's origin in the arm's frame, m (for the live tip).
    """

    plan: str
    plan_data: str
    name: str
    overrides: list[str]
    arm_overrides: list[str]
    dry_run: bool
    realtime: bool
    resume: bool
    park: bool
    server: str
    data: str
    panel_origin: list[float]


def arm_settings(job: JobSpec) -> list[str]:
    """The settings a job draws with: the plan's, then the arm's."""
    return [*job["overrides"], "backend=arm",
            f"dry_run={str(bool(job['dry_run'])).lower()}",
            f"realtime={str(bool(job['realtime'])).lower()}",
            f"resume={str(bool(job['resume'])).lower()}",
            *job.get("arm_overrides", [])]


def run_job(folder: Path) -> JsonDict:
    """Draw the job in ``folder`` on the arm; its result (also ``result.json``)."""
    from tattotronix.app.api import settings_of
    from tattotronix.app.arm import play_on_arm
    from tattotronix.app.draw import play
    from tattotronix.control.drawing import Drawing
    from tattotronix.io.artifacts import TrajectoryRecord
    from tattotronix.io.outputs import Outputs
    from tattotronix.robot.description import build_description

    job: JobSpec = json.loads((folder / JOB_FILE).read_text(encoding="utf-8"))
    name = str(job["name"])
    result: JsonDict
    try:
        cfg = settings_of(arm_settings(job))
        desc = build_description(cfg.robot)
        stored = TrajectoryRecord.path(job["plan_data"], name=name)
        tr = TrajectoryRecord.load(stored)
        drawing = Drawing(name, tr.t, tr.q, tr.qd, tr.kind, "stored", {"trajectory": stored})
        # the arm's state where the job says (draw.py's for the real arm), its logs here
        with Outputs(Path(job.get("data", job["server"])), root=folder).transaction() as out:
            if job.get("park"):
                summary = play_on_arm(cfg, out, desc, drawing, park=True)
            else:
                summary = play(cfg, out, desc, drawing)
        result = ({"status": "stopped", "message": f"stopped: {summary['reason']}",
                   "summary": summary} if job.get("park") else
                  {"status": "done", "message": "drawn to the end", "summary": summary})
    except Interrupted as exc:  # a stop request: the needle lifted, every output off
        result = {"status": "paused", "message": str(exc)}
    except KeyboardInterrupt:  # before the session took over its signals, or after
        if _state_status(job, folder) == "done":
            result = {"status": "done", "message": "drawn to the end (a stop request came "
                      "as it finished)"}
        else:
            result = {"status": "paused", "message": "stopped before the first frame: "
                      "nothing was sent"}
    except TattotronixError as exc:
        result = {"status": "failed", "message": str(exc)}
    (folder / RESULT_FILE).write_text(json.dumps(result, indent=1, default=str) + "\n",
                                      encoding="utf-8")
    log.info("job %s: %s: %s", folder.name, result["status"], result["message"])
    return result


def _state_status(job: JobSpec, folder: Path) -> str | None:
    """The status in the job's arm state file, if it is this drawing's."""
    from tattotronix.app.api import settings_of
    from tattotronix.app.arm import state_file_of
    from tattotronix.io.artifacts import run_dir, run_label

    try:
        cfg = settings_of(arm_settings(job))
        state = state_file_of(cfg, Path(job.get("data", job["server"])),
                              run_dir(folder, run_label(str(job["name"]), "arm")))
        doc = json.loads(state.read_text(encoding="utf-8"))
    except (OSError, ValueError, TattotronixError):
        return None
    return str(doc.get("status")) if doc.get("drawing") == job["name"] else None


def main(argv: list[str] | None = None) -> int:
    """Run the job of the folder ``argv[0]``: 0 done (or stopped by a park), 3 paused,
    1 failed."""
    args = sys.argv[1:] if argv is None else argv
    if len(args) != 1:
        print("usage: python -m tattotronix.server.runner JOB_FOLDER", file=sys.stderr)
        return 2
    folder = Path(args[0])
    # the server pauses this process with SIGINT and stops it with SIGTERM; a server whose
    # process ignores SIGINT (started in a script's background, where the shell ignores it,
    # and not under uvicorn's own handlers: embedded, or in a thread) passes that on, and
    # a pause would go unheard while the arm drew on. Both get their defaults back; the
    # arm's session takes them over (hardware.arm)
    signal.signal(signal.SIGINT, signal.default_int_handler)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    logging.basicConfig(filename=folder / LOG_FILE, level=logging.INFO,
                        format="%(asctime)s %(name)s: %(message)s")
    result = run_job(folder)
    return {"done": 0, "stopped": 0, "paused": 3}.get(str(result["status"]), 1)


if __name__ == "__main__":
    raise SystemExit(main())
