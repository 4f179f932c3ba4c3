"""The routes: every action the page takes is one of these, documented as OpenAPI
(``/docs``, ``/openapi.json``), so a script or another front end can plan, preview,
start and follow a job as the page does.

* ``POST /api/plans`` (an upload and its placement), ``POST /api/plans/strokes``;
  ``GET /api/plans/{id}``, ``/preview.png``, ``/path``; ``POST /api/plans/{id}/predict``
  and ``GET /api/plans/{id}/servo/{image}`` (the ink the servos would draw): plans;
* ``POST /api/jobs``; ``GET /api/jobs/current``; ``POST /api/jobs/current/pause``,
  ``/resume``, ``/stop``: the one job;
* ``WS /api/ws``: the job's live state, pushed twice a second;
* ``GET /``: the page.

Bad input gets one message, as ``{"detail": "..."}``: 400 (a bad request), 404 (no such
plan or job), 409 (the job's state does not allow it: a second start, a pause with
nothing drawing), 413 (an upload too large), 415 (not a PNG, JPEG or SVG), 422 (what the
artwork checks or planning refuse, or a value out of range). Served beyond this machine,
every route but the page needs the token (:mod:`~tattotronix.server.auth`): 401 without
it, 403 with a wrong one.
"""

from __future__ import annotations

import asyncio
import json
import logging
from collections.abc import Sequence
from importlib import resources
from pathlib import Path
from typing import Annotated, Any
from urllib.parse import urlsplit

from fastapi import (
    Depends,
    FastAPI,
    File,
    Form,
    HTTPException,
    Request,
    UploadFile,
    WebSocket,
    WebSocketDisconnect,
)
from fastapi.responses import FileResponse, HTMLResponse, JSONResponse
from pydantic import BaseModel, Field
from starlette.middleware.trustedhost import TrustedHostMiddleware

from tattotronix.errors import ConfigError, TattotronixError
from tattotronix.server.auth import token_matches
from tattotronix.server.jobs import JobConflict, JobManager
from tattotronix.server.plans import PlanRequest, PlanStore, UploadRefused

__all__ = ["create_app"]

log = logging.getLogger("tattotronix.server")

#: seconds between two pushes of the live state
PUSH_EVERY_S = 0.5


class StrokesIn(BaseModel):
    """Strokes in panel mm: each a polyline of ``[u, v]`` points (u right, v up, the
    panel's centre at 0, 0)."""

    strokes: list[list[tuple[float, float]]] = Field(
        ..., description="polylines in panel mm", examples=[[[[-20, -10], [20, -10]]]])
    width_mm: float | None = Field(None, gt=0, description="stroke width (the needle's)")
    name: str | None = Field(None, description="names the drawing's files")


class PredictIn(BaseModel):
    """The servos to predict with."""

    servos: str | None = Field(None, description="a catalogue type for every joint "
                               "(mg996r, sg90, sts3215); none: as mounted")
    compensate: bool = Field(True, description="every correction the servo program makes")


class JobIn(BaseModel):
    """A job: the plan to draw, and on what."""

    plan: str = Field(..., description="the plan's id (POST /api/plans)")
    real: bool = Field(False, description="the real arm (else a dry run: a recording bus)")
    confirm: bool = Field(False, description="required with real=true: the arm moves")
    realtime: bool = Field(True, description="a dry run paced at the servo frame rate")


def create_app(folder: Path, *, token: str | None = None,
               max_upload_bytes: int | None = None, python: str | None = None,
               hosts: Sequence[str] | None = None) -> FastAPI:
    """The server's application.

    Args:
        folder: the server's own folder (plans, jobs, dry runs' arm state, the token).
        token: required on every route but the page (None: none, on a loopback bind).
        max_upload_bytes: the largest upload taken.
        python: the interpreter that runs jobs (this one if None).
        hosts: the only ``Host`` names taken (a loopback bind's: a page elsewhere cannot
            reach it by DNS rebinding); None: any. A request whose ``Origin`` is not its
            own host is refused on every action and the WebSocket (no other site's page
            can start, pause or resume the arm from a visitor's browser).
    """
    from tattotronix.app.api import settings_of

    settings_of([])  # Hydra's compose once, before any thread can race to it
    open_docs = token is None  # behind a token, the description is /api/openapi.json
    app = FastAPI(title="TATTOTRONIX", version="0.1.0",
                  description="Plan a drawing, preview it, and draw it on the arm.",
                  docs_url="/docs" if open_docs else None,
                  redoc_url="/redoc" if open_docs else None,
                  openapi_url="/openapi.json" if open_docs else None)
    if hosts is not None:
        app.add_middleware(TrustedHostMiddleware, allowed_hosts=list(hosts))

    @app.middleware("http")
    async def same_origin(request: Request, call_next: Any) -> Any:
        if request.method not in ("GET", "HEAD", "OPTIONS") and not _same_origin(
                request.headers):
            return JSONResponse({"detail": "refused: a request from another site's page"},
                                status_code=403)
        return await call_next(request)
    plans = PlanStore(folder, **({"max_upload_bytes": max_upload_bytes}
                                 if max_upload_bytes else {}))
    jobs = JobManager(folder, **({"python": python} if python else {}))
    app.state.plans, app.state.jobs = plans, jobs

    def given_token(request: Request) -> str | None:
        auth = request.headers.get("authorization", "")
        if auth.lower().startswith("bearer "):
            return auth[7:].strip()
        return request.query_params.get("token")

    def check_token(request: Request) -> None:
        if token is None:
            return
        given = given_token(request)
        if given is None:
            raise HTTPException(401, "this server needs its token: Authorization: Bearer "
                                "<token>, or ?token=<token> (printed when it was made)")
        if not token_matches(given, token):
            raise HTTPException(403, "wrong token")

    Auth = Depends(check_token)

    @app.exception_handler(TattotronixError)
    async def refused(_: Request, exc: TattotronixError) -> JSONResponse:
        status = (exc.status if isinstance(exc, UploadRefused) else
                  409 if isinstance(exc, JobConflict) else 422)
        return JSONResponse({"detail": str(exc)}, status_code=status)

    @app.exception_handler(ConfigError)
    async def bad_setting(_: Request, exc: ConfigError) -> JSONResponse:
        return JSONResponse({"detail": str(exc)}, status_code=422)

    @app.get("/", response_class=HTMLResponse, include_in_schema=False)
    def page() -> str:
        return resources.files("tattotronix.server").joinpath("static/index.html").read_text(
            encoding="utf-8")

    @app.get("/api/health", dependencies=[Auth])
    def health() -> dict[str, Any]:
        """The server is up; whether a job exists."""
        return {"ok": True, "job": jobs.state() is not None}

    @app.post("/api/plans", status_code=201, dependencies=[Auth])
    async def create_plan(
        file: Annotated[UploadFile, File(description="a PNG, JPEG or SVG")],
        req: Annotated[PlanRequest, Depends(_placement)],
    ) -> dict[str, Any]:
        """Plan an uploaded artwork placed on the panel: its width, turn and centre
        ``(u_mm, v_mm)`` (both or neither), fill style and vector mode; the plan's id and
        stats (entries, marked and travel length, duration, bleed, coverage)."""
        data = await _read_limited(file, plans)
        stored = await asyncio.to_thread(plans.create, data, file.filename, req)
        return stored.info

    @app.post("/api/drafts", dependencies=[Auth])
    async def create_draft(
        file: Annotated[UploadFile, File(description="a PNG, JPEG or SVG")],
        req: Annotated[PlanRequest, Depends(_placement)],
    ) -> dict[str, Any]:
        """Check a placement at once, before planning (the fields of ``POST /api/plans``):
        ``stats.ok``, ``stats.problem`` (off the panel, out of reach, no ink, ...: what
        planning would refuse), and with a toolpath its entries, marked and travel length
        and its path (``uv``, ``kind``, as ``GET /api/plans/{pid}/path``). Nothing is kept
        and nothing is timed: a fraction of a plan's time."""
        data = await _read_limited(file, plans)
        return dict(await asyncio.to_thread(plans.draft, data, file.filename, req))

    @app.post("/api/plans/strokes", status_code=201, dependencies=[Auth])
    async def create_strokes(body: StrokesIn) -> dict[str, Any]:
        """Plan strokes sent as polylines (a canvas drawn with a finger or a stylus)."""
        stored = await asyncio.to_thread(plans.create_strokes, body.strokes, body.width_mm,
                                         body.name)
        return stored.info

    def _plan(pid: str) -> Any:
        stored = plans.get(pid)
        if stored is None:
            raise HTTPException(404, f"no plan {pid!r}")
        return stored

    @app.get("/api/plans/{pid}", dependencies=[Auth])
    def get_plan(pid: str) -> dict[str, Any]:
        """A plan's id, name and stats."""
        return dict(_plan(pid).info)

    @app.get("/api/plans/{pid}/preview.png", response_class=FileResponse,
             dependencies=[Auth])
    async def preview(pid: str) -> FileResponse:
        """The plan's toolpath on the panel (marking by kind, travel, entries)."""
        _plan(pid)
        png = await asyncio.to_thread(plans.preview, pid)
        if png is None:
            raise HTTPException(404, f"no plan {pid!r}")
        return FileResponse(png, media_type="image/png")

    @app.get("/api/plans/{pid}/path", dependencies=[Auth])
    def path(pid: str) -> dict[str, Any]:
        """The plan's path in panel mm (thinned), each point's kind (0 travel, 1 mark,
        2 approach): what the page draws the plan and the live tip over."""
        _plan(pid)
        return plans.path(pid) or {}

    @app.post("/api/plans/{pid}/predict", dependencies=[Auth])
    async def predict(pid: str, body: PredictIn) -> dict[str, Any]:
        """The plan drawn by the modelled servos (the arm as built): the run's metrics
        (the marking deviation, the verdict) and its images
        (``GET /api/plans/{pid}/servo/{image}``: the predicted ink, and it against the
        planned ink, the ideal)."""
        _plan(pid)
        return await asyncio.to_thread(plans.predict, pid, body.servos,
                                       body.compensate) or {}

    @app.get("/api/plans/{pid}/servo/{image}", response_class=FileResponse,
             dependencies=[Auth])
    def servo_image(pid: str, image: str) -> FileResponse:
        """An image of the plan's last servo prediction (``ink.png``, ``ink_vs_plan.png``,
        ``ink_vs_artwork.png``)."""
        _plan(pid)
        png = plans.run_image(pid, "servo", image)
        if png is None:
            raise HTTPException(404, f"no {image!r} for plan {pid!r}: predict it first "
                                "(POST /api/plans/{id}/predict)")
        return FileResponse(png, media_type="image/png")

    @app.post("/api/jobs", status_code=201, dependencies=[Auth])
    async def start_job(body: JobIn) -> dict[str, Any]:
        """Start drawing a plan: a dry run unless ``real`` and ``confirm``; 409 while
        another job is drawing or paused."""
        stored = _plan(body.plan)
        if body.real and not body.confirm:
            raise HTTPException(400, "the real arm moves: send confirm=true with real=true")
        await asyncio.to_thread(jobs.start, stored, dry_run=not body.real,
                                realtime=body.realtime)
        return jobs.state() or {}

    @app.get("/api/jobs/current", dependencies=[Auth])
    def current() -> dict[str, Any]:
        """The job's live state (404: no job yet)."""
        state = jobs.state()
        if state is None:
            raise HTTPException(404, "no job yet")
        return state

    @app.post("/api/jobs/current/pause", dependencies=[Auth])
    def pause() -> dict[str, Any]:
        """Pause at the arm's next frame, with the needle lifted to the clearance height."""
        jobs.pause()
        return jobs.state() or {}

    @app.post("/api/jobs/current/resume", dependencies=[Auth])
    async def resume() -> dict[str, Any]:
        """Resume a paused job: the arm approaches again and draws from where it stopped."""
        await asyncio.to_thread(jobs.resume)
        return jobs.state() or {}

    @app.post("/api/jobs/current/stop", dependencies=[Auth])
    def stop() -> dict[str, Any]:
        """Stop the job: the needle lifted, every output off; it is not offered to resume."""
        jobs.stop()
        return jobs.state() or {}

    if token is not None:  # the API's description, behind the token too
        @app.get("/api/openapi.json", dependencies=[Auth], include_in_schema=False)
        def openapi() -> dict[str, Any]:
            return app.openapi()

    @app.websocket("/api/ws")
    async def live(ws: WebSocket) -> None:
        """The job's live state (as ``GET /api/jobs/current``, ``{"status": "none"}``
        before any job), pushed every half second."""
        if not _same_origin(ws.headers):
            await ws.close(code=1008, reason="refused: a connection from another site's page")
            return
        if token is not None and not token_matches(ws.query_params.get("token"), token):
            await ws.close(code=1008, reason="this server needs its token: ?token=<token>")
            return
        await ws.accept()
        try:
            while True:
                state = await asyncio.to_thread(jobs.state)
                await ws.send_text(json.dumps(state or {"status": "none"}))
                await asyncio.sleep(PUSH_EVERY_S)
        except WebSocketDisconnect:
            return

    return app


def _placement(
    width_mm: Annotated[float | None, Form(gt=0, description="its width, mm")] = None,
    rotate_deg: Annotated[float | None, Form(description="its turn, degrees")] = None,
    u_mm: Annotated[float | None, Form(description="its centre's u, mm")] = None,
    v_mm: Annotated[float | None, Form(description="its centre's v, mm")] = None,
    fill: Annotated[str | None, Form(description="the fill style")] = None,
    vector: Annotated[bool | None, Form(description="an SVG's paths as lines")] = None,
    name: Annotated[str | None, Form(description="names its files")] = None,
) -> PlanRequest:
    """A placement from a form's fields (the centre as both ``u_mm`` and ``v_mm``, or
    neither)."""
    if (u_mm is None) != (v_mm is None):
        raise HTTPException(400, "give the centre as both u_mm and v_mm, or neither")
    return PlanRequest(width_mm=width_mm, rotate_deg=rotate_deg,
                       at_mm=None if u_mm is None or v_mm is None else (u_mm, v_mm),
                       fill=fill, vector=vector, name=name)


def _same_origin(headers: Any) -> bool:
    """Whether the request has no ``Origin`` (not a browser's cross-site request) or one
    whose host is the request's own ``Host``."""
    origin = headers.get("origin")
    if not origin:  # a script, curl, the test client: no page of another site
        return True
    return urlsplit(origin).netloc == headers.get("host", "")  # "null": refused


async def _read_limited(file: UploadFile, plans: PlanStore) -> bytes:
    """The upload's bytes, refused (413) as soon as it passes the limit."""
    chunks, size = [], 0
    while chunk := await file.read(1 << 16):
        size += len(chunk)
        plans.check_size(size)
        chunks.append(chunk)
    return b"".join(chunks)
