"""The Python API: plan a drawing, look at it, try it on the simulated arm and on the
modelled servos, and draw it, from a notebook or a script::

    import tattotronix as tt

    d = tt.plan("logo.svg", width_mm=80, fill="cross")  # or tt.plan_strokes([[(u, v), ...]])
    d.stats                        # entries, marked and travel length, duration, bleed, ...
    d.preview("preview.png")       # the toolpath on the panel
    run = d.simulate("mujoco")     # tracking errors, the ink, the ink against the artwork
    real = d.predict(servos="mg996r", compensate=True)  # the servo plant
    d.draw(tt.Arm(dry_run=True))   # the arm: a dry run records its I2C writes
    d.save("logo")                 # the stages' files, as dvc repro writes them

Every step runs the library calls the stages run, with the same settings (``conf/`` plus
``overrides``, Hydra's ``key=value`` strings, checked as a stage checks them), so a plan
made here and one made by ``dvc repro`` from the same inputs have the same points and
times, and :meth:`Plan.save` writes the same files, byte for byte (tests hold both). What
a run
writes (its metrics, ink images, logs) goes under the plan's ``workdir`` (a temporary
folder unless given), laid out as ``runs/`` is by hand (README, "Hand runs").
"""

from __future__ import annotations

import contextlib
import functools
import logging
import math
import tempfile
from collections.abc import Iterable, Sequence
from contextlib import AbstractContextManager
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from tattotronix.app.draw import check_panel, play
from tattotronix.app.pipeline import (
    DraftedDrawing,
    PlannedDrawing,
    draft_drawing,
    plan_drawing_all,
)
from tattotronix.app.records import (
    save_artwork,
    save_ik,
    save_mask,
    save_toolpath,
    save_trajectory,
    toolpath_record,
)
from tattotronix.art.artwork import artwork_name, resolve_source
from tattotronix.art.grid import InkMask
from tattotronix.art.vector import VectorLines
from tattotronix.config.params import (
    CONF_DIR,
    PROJECT_ROOT,
    compose_settings,
    with_overrides,
)
from tattotronix.config.schema import Config
from tattotronix.config.tracked import DVC_FILE, as_stage, definition_params
from tattotronix.control.drawing import Drawing
from tattotronix.errors import TattotronixError
from tattotronix.io.jsontypes import JsonDict
from tattotronix.io.outputs import Outputs
from tattotronix.io.provenance import plain_config, script_version
from tattotronix.path.figure import toolpath_figure
from tattotronix.path.plan import Toolpath
from tattotronix.robot.description import RobotDescription, build_description
from tattotronix.robot.mjcf import to_mjcf
from tattotronix.robot.urdf import to_urdf
from tattotronix.trajectory import JointPath, Trajectory

__all__ = ["Arm", "Draft", "Plan", "draft", "plan", "plan_strokes", "settings_of", "strokes_svg"]

log = logging.getLogger("tattotronix.api")
Array = NDArray[np.float64]

#: the settings :func:`plan`'s keyword arguments stand for
_KEYWORDS = {"width_mm": "mask.width_mm", "height_mm": "mask.height_mm",
             "fill": "toolpath.fill_style", "vector": "artwork.vector",
             "rotate_deg": "mask.rotate_deg"}


@dataclass(frozen=True)
class Arm:
    """The arm to draw on (:meth:`Plan.draw`).

    Attributes:
        dry_run: record every I2C write instead of opening the bus (no arm moves).
        realtime: a dry run paced at the servo frame rate (False: as fast as it can).
        resume: continue a stopped drawing from the arm's state file.
        overrides: further ``hardware.*`` settings (``hardware.calibration_file=...``).
    """

    dry_run: bool = True
    realtime: bool = False
    resume: bool = False
    overrides: tuple[str, ...] = ()

    def settings(self) -> list[str]:
        """The ``draw.py`` overrides of this arm."""
        return ["backend=arm", f"dry_run={str(self.dry_run).lower()}",
                f"realtime={str(self.realtime).lower()}", f"resume={str(self.resume).lower()}",
                *self.overrides]


@dataclass
class Plan:
    """A planned drawing: every step's result, and the settings and robot they were planned
    with.

    Attributes:
        name: names the outputs (the artwork's stem unless given).
        cfg: the settings (``conf/`` plus the overrides).
        overrides: the overrides the settings were made with (``key=value``).
        desc: the robot description.
        planned: the artwork, ink mask, toolpath, IK solution and path, and trajectory.
        source: the artwork file (strokes sent in memory are written to one first).
        workdir: where runs write.
    """

    name: str
    cfg: Config
    overrides: tuple[str, ...]
    desc: RobotDescription
    planned: PlannedDrawing
    source: Path
    workdir: Path
    _stats: JsonDict | None = field(default=None, repr=False)

    @property
    def mask(self) -> InkMask:
        """The ink mask the drawing was planned on (the artwork on the panel)."""
        return self.planned.mask

    @property
    def toolpath(self) -> Toolpath:
        """The planned toolpath (panel mm)."""
        return self.planned.toolpath

    @property
    def path(self) -> JointPath:
        """The IK path (joint angles at every point)."""
        return self.planned.path

    @property
    def trajectory(self) -> Trajectory:
        """The timed trajectory."""
        return self.planned.trajectory

    # ------------------------------------------------------------------ figures
    @property
    def stats(self) -> JsonDict:
        """The plan's figures (:meth:`figures`), computed once."""
        if self._stats is None:
            self._stats = self.figures()
        return dict(self._stats)

    def figures(self) -> JsonDict:
        """``entries``, ``drags``, ``marked_mm``, ``travel_mm``, ``points``,
        ``duration_s``, ``cycle_over_marking``, and the planned ink against the artwork at
        the needle's width (``toolpath.ink_res_mm``): ``bleed_max_mm``, ``bleed_share``
        and ``coverage``."""
        m, tr = self.toolpath.metrics, self.trajectory
        needle = float(self.cfg.toolpath.needle_width_mm)
        fid = self.toolpath.ink(self.mask, needle, float(self.cfg.toolpath.ink_res_mm)).fidelity
        return {
            "name": self.name, "entries": int(m.entries), "drags": int(m.drags),
            "marked_mm": round(float(m.marked_mm), 3),
            "travel_mm": round(float(m.travel_mm), 3),
            "points": int(len(tr.t)),
            "duration_s": round(float(tr.duration_s), 3),
            "cycle_over_marking": round(tr.duration_s / tr.marking_only_s, 4)
            if tr.marking_only_s > 0 else None,
            "bleed_max_mm": round(float(fid.bleed_max_mm), 4),
            "bleed_share": round(float(fid.bleed_share), 5),
            "coverage": round(float(fid.coverage), 5),
        }

    def preview(self, path: str | Path) -> Path:
        """Draw the toolpath on the panel (marking by kind, travel, needle entries) to a
        PNG at ``path``, as the toolpath stage's ``toolpath.png``; the path."""
        return _preview(self.cfg, self.toolpath, self.name, path)

    def save(self, folder: str | Path) -> Path:
        """Write the files the stages from ``artwork`` to ``trajectory`` write, laid out as
        under ``data/``: ``artwork/<name>.png`` and ``-lines.npz``, ``mask/<name>.npz``,
        ``toolpath/<name>.npz``, ``robot/<robot>.urdf``, ``ik/<name>.npz`` and
        ``trajectories/<name>.npz`` (the trajectory stage's format: README, "The stages");
        the trajectory's path.

        Each file records the provenance its stage would. In the project's checkout
        (beside ``dvc.yaml``) that is what ``dvc repro`` records, so the files are byte for
        byte those of the stages for the same artwork and settings (an entry of ``vars:
        artworks`` with the same overrides); elsewhere, the whole config and the code
        imported.
        """
        root = Path(folder)
        pl, name = self.planned, self.name
        # one transaction a step: each file is in place before the next step hashes it
        with self._as_stage("artwork"), Outputs(root, root=root).transaction() as out:
            png, lines = save_artwork(out, name, pl.artwork, pl.lines or VectorLines.empty())
        with self._as_stage("mask"), Outputs(root, root=root).transaction() as out:
            mask = save_mask(out, self.cfg, name, pl.mask, png)
        inputs = {"mask": mask} if pl.lines is None else {"mask": mask, "lines": lines}
        with self._as_stage("toolpath"), Outputs(root, root=root).transaction() as out:
            tp = save_toolpath(out, self.cfg, name, pl.toolpath, inputs)
        urdf, _ = _robot_models(self.desc, root)
        with self._as_stage("ik"), Outputs(root, root=root).transaction() as out:
            ik = save_ik(out, self.cfg, name, self.desc.joint_names, pl.ik.q, pl.path.tcp,
                         pl.ik.residual, toolpath_record(pl.toolpath),
                         {"toolpath": tp, "urdf": urdf})
        with self._as_stage("trajectory"), Outputs(root, root=root).transaction() as out:
            return save_trajectory(out, self.cfg, name, pl.trajectory,
                                   {"ik": ik, "urdf": urdf})

    def _as_stage(self, stage: str) -> AbstractContextManager[None]:
        """The provenance rules of ``stage`` under DVC (its tracked params, this plan's
        overrides and its script's code version), in the project's checkout; else none
        (the whole config is recorded)."""
        if not (PROJECT_ROOT / DVC_FILE).is_file():
            return contextlib.nullcontext()
        keys = definition_params(stage, PROJECT_ROOT, plain_config(self.cfg))
        version = script_version(PROJECT_ROOT / "stages" / f"{stage}.py", PROJECT_ROOT)
        return as_stage(keys, self.overrides, version)

    # ------------------------------------------------------------------ runs
    def _drawing(self) -> Drawing:
        tr = self.trajectory
        return Drawing(self.name, tr.t, tr.q, tr.qd, tr.kind, "planned",
                       {"artwork": self.source}, self.mask)

    def _play(self, overrides: Sequence[str]) -> JsonDict:
        cfg = with_overrides(self.cfg, list(overrides))
        _robot_models(self.desc, self.workdir)
        with Outputs(self.workdir, root=self.workdir).transaction() as out:
            return play(cfg, out, self.desc, self._drawing())

    def simulate(self, backend: str = "mujoco", *, window: Sequence[float] | str | None = None,
                 overrides: Sequence[str] = ()) -> JsonDict:
        """Draw on a simulated plant (``mujoco``, ``pybullet`` or ``model``), closed loop with
        the configured controller; the run's metrics (tracking errors, verdict, the ink
        against the plan and the artwork). Its ink images and log are under
        ``workdir/runs/<name>-<backend>/``.

        Args:
            backend: the plant.
            window: ``[start_s, length_s]`` or ``"busiest"``; None draws it all.
            overrides: further settings (``controller.wn=80``).

        Raises:
            TattotronixError: an unknown backend, or whatever the run refuses.
        """
        if backend in ("servo", "arm"):
            raise TattotronixError(f"simulate('{backend}'): use predict() for the servo plant "
                                   "and draw() for the arm")
        return self._play([f"backend={backend}", *_window(window), *overrides])

    def predict(self, servos: str | None = None, *, compensate: bool = True,
                window: Sequence[float] | str | None = None,
                overrides: Sequence[str] = ()) -> JsonDict:
        """What the arm as built would draw: the servo program played by the modelled hobby
        servos (``backend=servo``, docs/servos.md); the run's metrics.

        Args:
            servos: a servo type from the catalogue for every joint (``mg996r``, ``sg90``,
                ``sts3215``); None: the servos as mounted.
            compensate: every correction the servo program can make (the pulse-map fit,
                the backlash lead, the dead-band push).
            window, overrides: as :meth:`simulate`.
        """
        flag = str(bool(compensate)).lower()
        settings = [f"hardware.compensate.{k}={flag}" for k in ("fit", "backlash", "deadband")]
        if servos is not None:  # the catalogue's own spelling: "mg996r" is MG996R
            known = {str(k).lower(): str(k) for k in self.cfg.robot.servos}
            settings.append(f"servo.type={known.get(str(servos).lower(), servos)}")
        return self._play(["backend=servo", *settings, *_window(window), *overrides])

    def draw(self, arm: Arm | None = None) -> JsonDict:
        """Draw on the arm (a dry run unless ``arm`` says otherwise): the plan is printed,
        checked clear of collisions, compiled into servo frames and streamed, as
        ``draw.py backend=arm`` does (README, "The real arm": a signal stops it with the
        needle lifted and every output off; ``Arm(resume=True)`` continues); the
        session's summary."""
        return self._play((arm or Arm()).settings())


def _preview(cfg: Config, toolpath: Toolpath, name: str, path: str | Path) -> Path:
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    size = (float(cfg.robot.panel.size_mm[0]), float(cfg.robot.panel.size_mm[1]))
    toolpath_figure(toolpath, size, out, name)
    return out


@dataclass(frozen=True)
class Draft:
    """An artwork placed and turned into a toolpath, not yet timed (:func:`draft`), or what
    is wrong with the placement.

    Attributes:
        name: names the outputs.
        cfg: the settings; overrides: the overrides that made them.
        problem: why it cannot be planned (off the panel, out of reach, no ink, a needle
            too wide, unreadable art), in the words :func:`plan` would raise; None: none.
        drafted: the artwork, mask and toolpath (None when there is a problem).
    """

    name: str
    cfg: Config
    overrides: tuple[str, ...]
    problem: str | None
    drafted: DraftedDrawing | None

    @property
    def ok(self) -> bool:
        """It can be planned as placed."""
        return self.problem is None

    @property
    def toolpath(self) -> Toolpath:
        """The toolpath (panel mm).

        Raises:
            TattotronixError: the draft's problem, if it has one.
        """
        if self.drafted is None:
            raise TattotronixError(self.problem or "no toolpath")
        return self.drafted.toolpath

    @property
    def stats(self) -> JsonDict:
        """``ok``, ``problem``, and with a toolpath its ``entries``, ``drags``,
        ``marked_mm``, ``travel_mm`` and ``points`` (as :attr:`Plan.stats`; the timing
        comes with the plan)."""
        out: JsonDict = {"name": self.name, "ok": self.ok, "problem": self.problem}
        if self.drafted is not None:
            m = self.drafted.toolpath.metrics
            out.update(entries=int(m.entries), drags=int(m.drags),
                       marked_mm=round(float(m.marked_mm), 3),
                       travel_mm=round(float(m.travel_mm), 3),
                       points=int(len(self.drafted.toolpath.path.kind)))
        return out

    def preview(self, path: str | Path) -> Path:
        """The toolpath on the panel as a PNG (:meth:`Plan.preview`).

        Raises:
            TattotronixError: the draft's problem, if it has one.
        """
        return _preview(self.cfg, self.toolpath, self.name, path)


def draft(source: str | Path, *, width_mm: float | None = None,
          height_mm: float | None = None, rotate_deg: float | None = None,
          fill: str | None = None, vector: bool | None = None, name: str | None = None,
          overrides: Sequence[str] = ()) -> Draft:
    """The toolpath of an artwork as placed, in a fraction of :func:`plan`'s time (no joint
    angles, no timing): for a page that shows the placement's problems (off the panel, out
    of reach) and the toolpath at once, while the plan is made. Takes :func:`plan`'s
    arguments; what planning would refuse is the draft's ``problem``, not an exception.

    Raises:
        ConfigError: an unknown setting or a value out of range.
    """
    keywords: dict[str, object] = {"width_mm": width_mm, "height_mm": height_mm,
                                   "rotate_deg": rotate_deg, "fill": fill, "vector": vector}
    cfg, items = _settings(source, name, keywords, overrides)
    label = artwork_name(cfg.artwork)
    try:
        drafted: DraftedDrawing | None = draft_drawing(cfg, source, label,
                                                       build_description(cfg.robot))
        problem = None
    except TattotronixError as exc:
        drafted, problem = None, str(exc)
    return Draft(label, cfg, tuple(items), problem, drafted)


def _window(window: Sequence[float] | str | None) -> list[str]:
    if window is None:
        return []
    if isinstance(window, str):
        return [f"window={window}"]
    return [f"window=[{','.join(repr(float(w)) for w in window)}]"]


def _robot_models(desc: RobotDescription, workdir: Path) -> tuple[Path, Path]:
    """The URDF and MJCF the plants load, under ``workdir/robot/`` (as the robot stage
    writes them under ``data/robot/``), rewritten when ``desc`` differs; their paths."""
    folder = workdir / "robot"
    folder.mkdir(parents=True, exist_ok=True)
    files = []
    for suffix, model in ((".urdf", to_urdf), (".xml", to_mjcf)):
        f = folder / f"{desc.name}{suffix}"
        text = model(desc)
        if not f.exists() or f.read_text() != text:
            f.write_text(text)
        files.append(f)
    return files[0], files[1]


def _settings(source: str | Path, name: str | None, keywords: dict[str, object],
              overrides: Iterable[str]) -> tuple[Config, list[str]]:
    """The settings of a plan and the overrides that make them, ``artwork.name`` always
    among them (as in each stage's command in ``dvc.yaml``)."""
    items = [f"artwork.source={source}"]
    if name is not None:
        items.append(f"artwork.name={name}")
    for key, value in keywords.items():
        if value is not None:
            text = str(value).lower() if isinstance(value, bool) else str(value)
            items.append(f"{_KEYWORDS[key]}={text}")
    items += overrides
    cfg = settings_of(items)
    check_panel(cfg, "tattotronix.plan")
    if cfg.artwork.name is None:
        named = f"artwork.name={artwork_name(cfg.artwork)}"
        cfg = with_overrides(cfg, [named])
        items.insert(1, named)
    return cfg, items


@functools.lru_cache(maxsize=1)
def _defaults() -> Config:
    """``conf/`` composed once per process (Hydra's compose takes about a second)."""
    return compose_settings()


def settings_of(overrides: Sequence[str]) -> Config:
    """``conf/`` plus ``overrides``, as a stage composes them: dotted ``key=value``
    settings on the defaults composed once (milliseconds; checked as a stage checks
    them), and Hydra's compose for anything else (a config group, ``+key``, ``~key``).

    Raises:
        ConfigError: an unknown key, or a value of the wrong type or out of range.
    """
    items = list(overrides)
    if any(_needs_hydra(item) for item in items):
        return compose_settings(items)
    return with_overrides(_defaults(), items)


def _needs_hydra(item: str) -> bool:
    key = item.partition("=")[0]
    return (key.startswith(("+", "~")) or "/" in key or "=" not in item
            or (CONF_DIR / key).is_dir())


def plan(source: str | Path, *, width_mm: float | None = None, height_mm: float | None = None,
         rotate_deg: float | None = None, fill: str | None = None, vector: bool | None = None,
         name: str | None = None, overrides: Sequence[str] = (),
         workdir: str | Path | None = None) -> Plan:
    """Plan an artwork (a PNG, JPG or SVG file, or a built-in's name) into a drawing, as
    the stages from ``artwork`` to ``trajectory`` do.

    Args:
        source: the artwork.
        width_mm, height_mm, rotate_deg: its size and turn on the panel (``mask.*``;
            None: the settings', e.g. an SVG's own size).
        fill: the fill style (``toolpath.fill_style``: ``hatch``, ``cross``, ...).
        vector: draw an SVG's stroked paths along their geometry (``artwork.vector``).
        name: names the outputs (default: the file's stem).
        overrides: any setting, as the stage scripts take them (``"toolpath.pitch_mm=0.8"``).
        workdir: where runs write (default: a new temporary folder).

    Raises:
        TattotronixError: whatever a stage would refuse (unreadable art, no ink, a drawing
            off the panel or out of reach, a needle that cannot draw it).
        ConfigError: an unknown setting or a value out of range.
    """
    keywords: dict[str, object] = {"width_mm": width_mm, "height_mm": height_mm,
                                   "rotate_deg": rotate_deg, "fill": fill, "vector": vector}
    cfg, items = _settings(source, name, keywords, overrides)
    label = artwork_name(cfg.artwork)
    desc = build_description(cfg.robot)
    planned = plan_drawing_all(cfg, source, label, desc)
    folder = Path(workdir) if workdir is not None else Path(
        tempfile.mkdtemp(prefix=f"tattotronix-{label}-"))
    return Plan(label, cfg, tuple(items), desc, planned, Path(resolve_source(source)), folder)


def strokes_svg(strokes: Sequence[ArrayLike], panel_size_mm: Sequence[float],
                width_mm: float) -> str:
    """An SVG of ``strokes`` (polylines in panel mm: ``u`` right, ``v`` up, the origin at
    the panel's centre) drawn ``width_mm`` wide, on a document the panel's size."""
    w, h = float(panel_size_mm[0]), float(panel_size_mm[1])
    paths = []
    for i, s in enumerate(strokes):
        p = np.asarray(s, dtype=np.float64)
        if p.ndim != 2 or p.shape[1] != 2 or len(p) < 2:
            raise TattotronixError(f"stroke {i}: give at least two (u, v) points in mm, "
                                   f"not an array of shape {p.shape}")
        if not np.isfinite(p).all():
            raise TattotronixError(f"stroke {i}: a point is not a finite number")
        out = p[(np.abs(p[:, 0]) > w / 2) | (np.abs(p[:, 1]) > h / 2)]
        if len(out):
            raise TattotronixError(
                f"stroke {i}: the point ({out[0, 0]:.1f}, {out[0, 1]:.1f}) mm is off the "
                f"panel ({w:g} x {h:g} mm, centred at (0, 0); u right, v up)")
        xy = " ".join(f"{u + w / 2:.4f},{h / 2 - v:.4f}" for u, v in p)
        paths.append(f'<polyline points="{xy}"/>')
    if not paths:
        raise TattotronixError("no strokes to draw: give at least one polyline")
    return (f'<svg xmlns="http://www.w3.org/2000/svg" width="{w:g}mm" height="{h:g}mm" '
            f'viewBox="0 0 {w:g} {h:g}"><g fill="none" stroke="#000" '
            f'stroke-width="{width_mm:g}" stroke-linecap="round" stroke-linejoin="round">'
            + "".join(paths) + "</g></svg>")


def plan_strokes(strokes: Sequence[ArrayLike], *, name: str = "strokes",
                 width_mm: float | None = None, overrides: Sequence[str] = (),
                 workdir: str | Path | None = None) -> Plan:
    """Plan polylines sent as strokes (a tablet's, or a vpype pipeline's): each ``(n, 2)``
    in panel mm (``u`` right, ``v`` up, the origin at the panel's centre), drawn along its
    geometry at the needle's width (or ``width_mm``), checked against the panel and the
    reach, ordered, timed and collision-checked like any plan (:func:`plan`; the strokes
    are written as a millimetre SVG, ``workdir/<name>.svg``, and planned as vector art).

    Raises:
        TattotronixError: an empty list, a stroke of fewer than two points, a point off
            the panel or out of reach.
    """
    cfg = settings_of(overrides)
    size = [float(x) for x in cfg.robot.panel.size_mm[:2]]
    needle = float(cfg.toolpath.needle_width_mm)
    width = needle if width_mm is None else float(width_mm)
    if not (math.isfinite(width) and width > 0):
        raise TattotronixError(f"width_mm={width_mm}: give a positive stroke width in mm")
    folder = Path(workdir) if workdir is not None else Path(
        tempfile.mkdtemp(prefix=f"tattotronix-{name}-"))
    folder.mkdir(parents=True, exist_ok=True)
    svg = folder / f"{name}.svg"
    svg.write_text(strokes_svg(strokes, size, width))
    # the document is the panel: placed 1:1, the panel's centre at the document's; every
    # stroke was sent on purpose, so none is too small to draw (mask.min_region_mm2)
    place = [f"mask.width_mm={size[0]:g}", "mask.height_mm=null", "mask.anchor=centre",
             "mask.at_mm=[0,0]", "mask.rotate_deg=0", "mask.min_region_mm2=0",
             "artwork.vector=true"]
    return plan(svg, name=name, overrides=[*place, *overrides], workdir=folder)
