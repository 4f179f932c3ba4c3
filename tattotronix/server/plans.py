"""Uploads checked and stored, and the plans the server makes of them.

An upload is refused before any work when it is too large, empty or not a PNG, JPEG or
SVG by its first bytes (whatever its name says); what the artwork loader refuses (a
decompression bomb, an SVG's external reference, a corrupt file) and what planning
refuses (off the panel, out of reach, a setting out of range) comes back as one message.
Everything is stored under the server's folder (``plans/<id>/``), never where the
pipeline writes; a refused upload is not kept. Plans outlive the server: a restarted one
plans a stored plan again on its first use.

A plan is :func:`tattotronix.plan` of the stored file with the placement asked for; its
stages' files are saved (:meth:`tattotronix.app.api.Plan.save`) under ``plans/<id>/data``
for the job that draws it. One plan is made at a time (planning composes settings with
Hydra, which is not thread-safe, and uses both cores).
"""

from __future__ import annotations

import json
import logging
import re
import secrets
import shutil
import threading
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from tattotronix.app.api import Plan, draft, plan, plan_strokes
from tattotronix.config.schema import FillStyle
from tattotronix.errors import ConfigError, TattotronixError
from tattotronix.io.artifacts import run_dir, run_label
from tattotronix.io.jsontypes import JsonDict
from tattotronix.path.plan import Toolpath

__all__ = ["MAX_UPLOAD_BYTES", "PlanRefused", "PlanRequest", "PlanStore", "UploadRefused",
           "sniff_kind"]

log = logging.getLogger("tattotronix.server")

#: the largest upload taken, bytes (``tattotronix serve --max-upload-mb``)
MAX_UPLOAD_BYTES = 8 * 1024 * 1024
#: points of a plan's path sent to the page (every one would be megabytes)
PATH_POINTS = 4000
_NAME = re.compile(r"[^A-Za-z0-9_-]+")
_PID = re.compile(r"[0-9a-f]{12}")  # secrets.token_hex(6)
#: what a plan's folder says of it (its id, name, kind, stats and settings)
PLAN_FILE = "plan.json"
#: the images a run writes: its ink, against the plan's, against the artwork
RUN_IMAGES = ("ink.png", "ink_vs_plan.png", "ink_vs_artwork.png")
_FILLS = tuple(f.value for f in FillStyle)  # toolpath.fill_style


class UploadRefused(TattotronixError):
    """An upload refused before any planning; ``status`` is the HTTP status it gets."""

    def __init__(self, message: str, status: int):
        super().__init__(message)
        self.status = status


class PlanRefused(TattotronixError):
    """What planning refused (the artwork, the placement, a setting): HTTP 422."""


def sniff_kind(data: bytes) -> str:
    """``png``, ``jpg`` or ``svg`` by the file's first bytes.

    Raises:
        UploadRefused: empty (400), or none of the three (415).
    """
    if not data:
        raise UploadRefused("the upload is empty", 400)
    if data.startswith(b"\x89PNG\r\n\x1a\n"):
        return "png"
    if data.startswith(b"\xff\xd8\xff"):
        return "jpg"
    head = data[:4096].lstrip(b"\xef\xbb\xbf \t\r\n").lower()
    if head.startswith((b"<?xml", b"<svg", b"<!--", b"<!doctype svg")) and b"<svg" in (
            data[:65536].lower()):
        return "svg"
    raise UploadRefused("not a PNG, JPEG or SVG file (by its first bytes): upload one of "
                        "those", 415)


def safe_name(text: str | None, fallback: str = "drawing") -> str:
    """A name for a drawing's files: letters, digits, ``-`` and ``_`` (at most 40)."""
    stem = Path(text or "").stem
    name = _NAME.sub("-", stem).strip("-_")[:40]
    return name or fallback


@dataclass(frozen=True)
class PlanRequest:
    """Where and how to draw an artwork (each None: the settings').

    Attributes:
        width_mm: its width on the panel, mm.
        rotate_deg: its turn, degrees (counter-clockwise).
        at_mm: ``(u, v)`` of its centre on the panel, mm (the panel's centre is (0, 0)).
        fill: the fill style (``toolpath.fill_style``).
        vector: draw an SVG's stroked paths along their geometry (``artwork.vector``).
        name: names its files (the upload's stem otherwise).
    """

    width_mm: float | None = None
    rotate_deg: float | None = None
    at_mm: tuple[float, float] | None = None
    fill: str | None = None
    vector: bool | None = None
    name: str | None = None

    def overrides(self) -> list[str]:
        """The placement's settings beyond :func:`tattotronix.plan`'s keywords."""
        if self.at_mm is None:
            return []
        u, v = (float(c) for c in self.at_mm)
        return ["mask.anchor=centre", f"mask.at_mm=[{u!r},{v!r}]"]


@dataclass
class StoredPlan:
    """A plan the server made: its id, the plan, and where its files are."""

    id: str
    plan: Plan
    folder: Path
    kind: str
    info: JsonDict = field(default_factory=dict)

    @property
    def data(self) -> Path:
        """The plan's stages' files (``data/``'s layout), what a job draws."""
        return self.folder / "data"


class PlanStore:
    """The plans of one server, under ``<folder>/plans/``."""

    def __init__(self, folder: Path, max_upload_bytes: int = MAX_UPLOAD_BYTES):
        self.folder = folder / "plans"
        self.folder.mkdir(parents=True, exist_ok=True)
        self.max_upload_bytes = max_upload_bytes
        self._plans: dict[str, StoredPlan] = {}
        self._lock = threading.Lock()

    def check_size(self, size: int) -> None:
        """Refuse an upload over the limit (413)."""
        if size > self.max_upload_bytes:
            raise UploadRefused(
                f"the upload is {size / 1e6:.1f} MB; the server takes at most "
                f"{self.max_upload_bytes / 1e6:.1f} MB (tattotronix serve --max-upload-mb)",
                413)

    def _checked(self, data: bytes, req: PlanRequest) -> str:
        self.check_size(len(data))
        kind = sniff_kind(data)
        if req.fill is not None and req.fill not in _FILLS:
            raise PlanRefused(f"fill '{req.fill}': use one of {', '.join(_FILLS)}")
        return kind

    def draft(self, data: bytes, filename: str | None, req: PlanRequest) -> JsonDict:
        """An uploaded artwork placed as asked, drafted (:func:`tattotronix.draft`: the
        toolpath, no timing) and not kept: ``ok``, the ``problem`` planning would refuse
        (off the panel, out of reach, ...), and with a toolpath its stats and path (as
        :meth:`path`). What a page shows as the placement changes, at once.

        Raises:
            UploadRefused: too large, empty, or not a PNG, JPEG or SVG.
            PlanRefused: a fill style or setting out of range.
        """
        kind = self._checked(data, req)
        name = safe_name(req.name or filename)
        folder = self.folder.parent / "drafts" / secrets.token_hex(6)
        folder.mkdir(parents=True)
        source = folder / f"{name}.{kind}"
        source.write_bytes(data)
        try:
            with self._lock:
                made = draft(source, width_mm=req.width_mm, rotate_deg=req.rotate_deg,
                             fill=req.fill, vector=req.vector, name=name,
                             overrides=req.overrides())
        except ConfigError as exc:
            raise PlanRefused(str(exc)) from None
        finally:
            source.unlink(missing_ok=True)
            folder.rmdir()
        out: JsonDict = {"stats": made.stats,
                         "panel_mm": [float(x) for x in made.cfg.robot.panel.size_mm[:2]]}
        if made.drafted is not None:
            out.update(path_for_page(made.toolpath))
        return out

    def create(self, data: bytes, filename: str | None, req: PlanRequest) -> StoredPlan:
        """Store an uploaded artwork and plan it.

        Raises:
            UploadRefused: too large, empty, or not a PNG, JPEG or SVG.
            PlanRefused: what the artwork loader or planning refuses, in one message.
        """
        kind = self._checked(data, req)
        name = safe_name(req.name or filename)
        pid, folder = self._new_folder()
        source = folder / f"{name}.{kind}"
        source.write_bytes(data)
        return self._make(pid, folder, kind, lambda: plan(
            source, width_mm=req.width_mm, rotate_deg=req.rotate_deg, fill=req.fill,
            vector=req.vector, name=name, overrides=req.overrides(), workdir=folder / "runs"))

    def create_strokes(self, strokes: Sequence[Sequence[Sequence[float]]],
                       width_mm: float | None, name: str | None) -> StoredPlan:
        """Plan polylines in panel mm (:func:`tattotronix.plan_strokes`).

        Raises:
            PlanRefused: no strokes, a stroke of fewer than two points, a point off the
                panel or out of reach.
        """
        pid, folder = self._new_folder()
        arrays = [np.asarray(s, dtype=np.float64) for s in strokes]
        label = safe_name(name, "strokes")
        return self._make(pid, folder, "strokes", lambda: plan_strokes(
            arrays, name=label, width_mm=width_mm, workdir=folder))

    def _new_folder(self) -> tuple[str, Path]:
        pid = secrets.token_hex(6)
        folder = self.folder / pid
        folder.mkdir(parents=True)
        return pid, folder

    def _make(self, pid: str, folder: Path, kind: str, make: Any, *,
              keep_on_refusal: bool = False) -> StoredPlan:
        with self._lock:
            try:
                made: Plan = make()
                made.save(folder / "data")
            except (TattotronixError, ConfigError) as exc:
                log.info("plan %s refused: %s", pid, exc)
                if not keep_on_refusal:  # a new upload's: nothing of it is kept
                    shutil.rmtree(folder, ignore_errors=True)
                raise PlanRefused(str(exc)) from None
        stored = StoredPlan(pid, made, folder, kind)
        stored.info = {"id": pid, "name": made.name, "kind": kind, "stats": made.stats,
                       "panel_mm": [float(x) for x in made.cfg.robot.panel.size_mm[:2]],
                       "overrides": list(made.overrides)}
        (folder / PLAN_FILE).write_text(json.dumps(stored.info, indent=1) + "\n")
        self._plans[pid] = stored
        log.info("plan %s: %s, %s", pid, made.name, made.stats)
        return stored

    def get(self, pid: str) -> StoredPlan | None:
        """The plan ``pid`` (None: no such plan). One made before the server (re)started
        is planned again from its stored artwork and settings, once, on first use, and its
        files saved again (the same files, unless the code changed)."""
        stored = self._plans.get(pid)
        if stored is None and _PID.fullmatch(pid) and (self.folder / pid / PLAN_FILE).is_file():
            stored = self._reload(pid)
        return stored

    def _reload(self, pid: str) -> StoredPlan | None:
        folder = self.folder / pid
        try:
            info = json.loads((folder / PLAN_FILE).read_text(encoding="utf-8"))
            items = [str(x) for x in info["overrides"]]
            source = next(x.split("=", 1)[1] for x in items
                          if x.startswith("artwork.source="))
            rest = [x for x in items if not x.startswith(("artwork.source=", "artwork.name="))]
            kind, name = str(info["kind"]), str(info["name"])
        except (OSError, ValueError, KeyError, TypeError, StopIteration) as exc:
            log.warning("plan %s: its %s is unreadable (%s)", pid, PLAN_FILE, exc)
            return None
        if not Path(source).is_file():
            log.warning("plan %s: its artwork %s is gone", pid, source)
            return None
        workdir = folder if kind == "strokes" else folder / "runs"
        try:
            return self._make(pid, folder, kind, lambda: plan(
                source, name=name, overrides=rest, workdir=workdir), keep_on_refusal=True)
        except PlanRefused as exc:
            log.warning("plan %s: planned again, it is refused: %s", pid, exc)
            return None

    def preview(self, pid: str) -> Path | None:
        """The plan's toolpath on the panel as a PNG (made once); None: no such plan."""
        stored = self.get(pid)
        if stored is None:
            return None
        png = stored.folder / "preview.png"
        if not png.exists():
            with self._lock:  # matplotlib's pyplot is not thread-safe
                stored.plan.preview(png)
        return png

    def predict(self, pid: str, servos: str | None, compensate: bool) -> JsonDict | None:
        """What the arm as built would draw: the plan on the servo plant
        (:meth:`tattotronix.app.api.Plan.predict`); the run's metrics and its images'
        names (:data:`RUN_IMAGES` that it wrote); None: no such plan.

        Raises:
            PlanRefused: an unknown servo type, or what the run refuses.
        """
        stored = self.get(pid)
        if stored is None:
            return None
        with self._lock:
            try:
                metrics = stored.plan.predict(servos=servos, compensate=compensate)
            except (TattotronixError, ConfigError) as exc:
                raise PlanRefused(str(exc)) from None
        folder = self.run_folder(stored, "servo")
        return {"metrics": metrics,
                "images": [f for f in RUN_IMAGES if (folder / f).is_file()]}

    @staticmethod
    def run_folder(stored: StoredPlan, backend: str) -> Path:
        """Where a run of the plan on ``backend`` wrote its images."""
        return run_dir(stored.plan.workdir, run_label(stored.plan.name, backend))

    def run_image(self, pid: str, backend: str, image: str) -> Path | None:
        """One of :data:`RUN_IMAGES` of the plan's last run on ``backend`` (None: none)."""
        stored = self.get(pid)
        if stored is None or image not in RUN_IMAGES:
            return None
        file = self.run_folder(stored, backend) / image
        return file if file.is_file() else None

    def path(self, pid: str) -> JsonDict | None:
        """The plan's path for the page: panel ``(u, v)`` mm and each point's kind (0
        travel, 1 mark, 2 approach), thinned to about :data:`PATH_POINTS` points (every
        needle entry and lift kept); None: no such plan."""
        stored = self.get(pid)
        if stored is None:
            return None
        return {"id": pid, **path_for_page(stored.plan.toolpath)}


def path_for_page(toolpath: Toolpath) -> JsonDict:
    """A toolpath for the page: ``uv``, panel ``(u, v)`` mm, and each point's ``kind`` (0
    travel, 1 mark, 2 approach), thinned to about :data:`PATH_POINTS` points (every needle
    entry and lift kept)."""
    p = toolpath.path
    kind = np.asarray(p.kind)
    keep = np.zeros(len(kind), bool)
    keep[:: max(1, len(kind) // PATH_POINTS)] = True
    keep[[0, -1]] = True
    keep[1:] |= kind[1:] != kind[:-1]  # where the kind changes
    keep[:-1] |= kind[1:] != kind[:-1]
    uv = np.round(np.asarray(p.uvz_mm)[keep, :2], 3)
    return {"uv": uv.tolist(), "kind": kind[keep].astype(int).tolist()}
