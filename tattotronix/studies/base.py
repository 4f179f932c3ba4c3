"""What a closed-loop study is, and what every closed-loop study shares.

A closed-loop study (control, approach, resample, rate: the original's, docs/original.md,
"2.11 The resample study" and "5.5 Tracking error" to "5.8 The rate study") is a sweep over
ordinary config keys. Its stage runs every configured *case* at once
(``study.all_cases=true``, what dvc.yaml runs: :meth:`ClosedLoopStudy.run_all`, in a pool
of one forked process per core); by hand, ``python stages/<script>.py [overrides]`` runs
the one case the settings describe, and ``-m KEY=a,b,c`` a sweep. Each study
is one module of this package holding one :class:`ClosedLoopStudy`, ``STUDY``, which
states:

* ``name``: its stage, and its folders under ``data/metrics`` and ``data/studies``;
* ``keys``: the swept config keys (dotted), recorded as each case's ``settings``;
* ``windows``: the stretches each case runs: ``None`` (the whole drawing) and/or
  ``"busiest"`` (the busiest ``study.window_s`` window, where the original reported);
* :meth:`~ClosedLoopStudy.cases`: the configured cases (``conf/study``), name ->
  overrides;
* :meth:`~ClosedLoopStudy.case_name`: a case's name from the swept values (it must equal
  the configured name: the stage refuses otherwise);
* :meth:`~ClosedLoopStudy.cost`: how long a case runs against the others (the pool starts
  the longest first);
* :meth:`~ClosedLoopStudy.plant_dt_s`, :meth:`~ClosedLoopStudy.window_metrics` and
  :meth:`~ClosedLoopStudy.case_metrics`: what the study changes or adds to a case;
* :meth:`~ClosedLoopStudy.figure` and :meth:`~ClosedLoopStudy.summary`: its figure and
  its conclusions, from the stored cases (the ``studies`` stage), each read back as a
  :class:`StudyCase`.

The machinery lives here, once: :meth:`ClosedLoopStudy.compute_case` plays the drawing closed
loop (:func:`tattotronix.app.simulate.run_closed_loop`, the plant of ``backend``) over
each window, scores it as the original did (docs/original.md, "5.5 Tracking error"), and
writes ``data/metrics/<study>/<name>/<case>.json`` (settings, drawing figures, the tracking
metrics of each window, the loop analysis; no wall times, so ``dvc metrics diff`` shows
only what changed) and ``data/studies/<study>/<name>/<case>.npz`` (the sampled error
series of each window, ``<window>_t``, ``<window>_error_um``, ``<window>_down`` and
``<window>_settled``, with the provenance:
:class:`~tattotronix.io.artifacts.StudySeriesRecord`), which :meth:`ClosedLoopStudy.write_case`
writes. In a ``-m`` sweep, any
override that is not a swept key is added to the case name
(:meth:`tattotronix.io.outputs.Outputs.sweep_suffix`), so no two jobs write the same file.
:meth:`ClosedLoopStudy.stage_body` is the whole of a study's stage script.

A drawing whose path settings differ from the stored trajectory's (approach, step) is
re-planned in memory from the artwork (:func:`~tattotronix.app.drawings.resolve_drawing`).

Adding a study: its module here (a subclass, and ``STUDY``), its line in
:mod:`tattotronix.studies.registry` (for the ``studies`` stage), its settings in
``conf/study`` (and their fields in ``StudyConfig``, ``tattotronix/config/schema.py``),
a three-line ``stages/<script>.py``, and its stage in ``dvc.yaml`` (one stage, with the
study's two folders as its outputs).
"""

from __future__ import annotations

import json
import logging
import math
from abc import ABC, abstractmethod
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, ClassVar

import numpy as np
from numpy.typing import NDArray

from tattotronix.app.drawings import resolve_drawing
from tattotronix.app.servos import run_servo_loop
from tattotronix.app.simulate import run_closed_loop
from tattotronix.art.artwork import artwork_name
from tattotronix.config.params import with_overrides
from tattotronix.config.schema import Config, StudyConfig
from tattotronix.control.drawing import ClosedLoop, Drawing, warm_up
from tattotronix.control.tracking import entry_times
from tattotronix.control.verdict import length_text
from tattotronix.errors import ConfigError, TattotronixError
from tattotronix.io.artifacts import StudySeriesRecord, make_provenance
from tattotronix.io.jsontypes import JsonDict, JsonValue
from tattotronix.io.outputs import Outputs
from tattotronix.io.workers import usable_cores, worker_signals
from tattotronix.kinematics import Chain
from tattotronix.plotting import pyplot
from tattotronix.robot.description import RobotDescription, build_description

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

__all__ = ["VERDICT_COLOUR", "WINDOWS", "CaseResult", "Cases", "ClosedLoopStudy", "StudyCase",
           "finish_figure", "int_label", "load_cases", "log_axes_with_twin", "setting",
           "sorted_by", "window_value"]

log = logging.getLogger("tattotronix.studies")


@dataclass(frozen=True)
class CaseResult:
    """A case that ran, before it is written (:meth:`ClosedLoopStudy.compute_case`).

    Attributes:
        name: the artwork. case: the case's name.
        metrics: the case file's JSON. series: the sampled error series of each window.
        provenance: the series file's provenance JSON.
    """

    name: str
    case: str
    metrics: JsonDict
    series: dict[str, NDArray[np.generic]]
    provenance: str


@dataclass(frozen=True, eq=False)  # equal as mappings are
class StudyCase(Mapping[str, JsonValue]):
    """One stored case of a study, as read back from its metrics file
    (``data/metrics/<study>/<name>/<case>.json``, what :meth:`ClosedLoopStudy.run_case`
    writes): a read-only mapping of the file's JSON, with typed accessors.

    The file holds ``study``, ``name``, ``case``, ``backend``, ``plant_dt_s`` and the
    sections ``settings`` (swept key -> value), ``drawing``, ``controller``, ``loop``, one
    section per window run (``whole``, ``busiest``: the tracking metrics) and those a
    study adds (``chord``, ``verdict_check``).
    """

    #: the parsed JSON of the case file
    metrics: Mapping[str, JsonValue]

    @classmethod
    def load(cls, path: Path, study: str | None = None) -> StudyCase:
        """Read a case file (``metrics/<study>/<name>/<case>.json``).

        Raises:
            TattotronixError: the file is unreadable, not JSON, or does not hold a JSON
                object; the message names it and the stage to re-run (``study``, by
                default the name of the file's study folder).
        """
        stage = study or path.parent.parent.name
        try:
            obj = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, ValueError) as exc:
            raise TattotronixError(f"cannot read {path} ({type(exc).__name__}: {exc}): "
                                   f"re-run the '{stage}' stage") from None
        if not isinstance(obj, dict):
            raise TattotronixError(f"cannot read {path}: a study case file holds a JSON "
                                   f"object, not {type(obj).__name__}: re-run the '{stage}' "
                                   "stage")
        return cls(obj)

    def __getitem__(self, key: str) -> JsonValue:
        return self.metrics[key]

    def __iter__(self) -> Iterator[str]:
        return iter(self.metrics)

    def __len__(self) -> int:
        return len(self.metrics)

    def section(self, key: str) -> Mapping[str, JsonValue]:
        """A section of the case (``whole``, ``busiest``, ``settings``, ``drawing``,
        ``controller``, ``chord``, ``verdict_check``, ...); empty where it is missing or
        null (a window that did not run)."""
        value = self.metrics.get(key)
        return value if isinstance(value, Mapping) else {}

    def number(self, section: str, key: str) -> float:
        """A number of a section (NaN where the section or the number is missing or null,
        as a metric that had none is stored).

        Raises:
            ValueError: the value is not a number.
        """
        return _as_float(self.section(section).get(key), f"{section}.{key}", math.nan)

    def text(self, section: str, key: str, default: str = "?") -> str:
        """A value of a section as text (``default`` where it is missing or null)."""
        value = self.section(section).get(key)
        return default if value is None else str(value)

    def setting(self, key: str) -> float:
        """A swept setting of the case, as a number (``controller.wn``: 40.0).

        Raises:
            ValueError: the case has no such setting, or it is not a number.
        """
        return _as_float(self.section("settings").get(key), f"settings.{key}")


#: a study's stored cases on one artwork: case name -> the case
Cases = Mapping[str, StudyCase]

#: metrics of a run that depend on the machine, not on the physics (left out of studies)
_WALL_KEYS = ("wall_s", "realtime_factor")
#: overrides that never name a case: the artwork (its own folder) and the progress bar
_NOT_A_CASE = ("artwork.name", "artwork.source", "draw.progress")


class ClosedLoopStudy(ABC):
    """One closed-loop study: its cases, how one is named and run, its figure and summary.

    Subclasses set the class attributes and implement the abstract methods; the hooks
    with defaults (:meth:`plant_dt_s`, :meth:`window_metrics`, :meth:`case_metrics`) are
    overridden only by a study that changes or adds something.
    """

    #: the study: its stage, and its folders under data/metrics and data/studies
    name: ClassVar[str]
    #: the swept config keys (dotted), recorded as the case's settings
    keys: ClassVar[tuple[str, ...]]
    #: the stretches each case runs: None (whole drawing) and/or "busiest"
    windows: ClassVar[tuple[str | None, ...]] = (None,)

    # --- what the study states --------------------------------------------------------

    @abstractmethod
    def cases(self, study: StudyConfig) -> dict[str, list[str]]:
        """The configured cases (``study``: ``conf/study``): case name -> the overrides
        that run it."""

    @abstractmethod
    def case_name(self, cfg: Config) -> str:
        """The case's name, from the swept values (names its files)."""

    def plant_dt_s(self, cfg: Config) -> float | None:
        """The plant's step for this study's runs; None: ``plant.dt_s``."""
        return None

    def cost(self, cfg: Config) -> float:
        """How long the case runs, relative to the study's others (1 by default): the pool
        starts the longest first, so no long case is left alone at the end."""
        return 1.0

    def window_metrics(self, cfg: Config, loop: ClosedLoop, chain: Chain) -> JsonDict:
        """Metrics added to each window's (empty by default); ``chain`` is the arm's."""
        return {}

    def case_metrics(self, cfg: Config, name: str,
                     windows: Mapping[str, Mapping[str, JsonValue]]) -> JsonDict:
        """Metrics added to the case's, given each window's (label -> metrics; empty by
        default)."""
        return {}

    @abstractmethod
    def figure(self, cases: Cases, path: Path, title: str = "") -> None:
        """Draw the study's figure from its cases on one artwork; save it as a PNG."""

    @abstractmethod
    def summary(self, cases: Cases) -> JsonDict:
        """What the study concludes from its cases on one artwork (JSON-ready)."""

    def curve(self, cases: Cases) -> list[dict[str, JsonValue]]:
        """The study's curve for ``dvc plots`` (``data/plots/studies/<study>.csv``): one row
        per case, in the order of its swept settings, with the case's name, its settings
        (by their last name: ``wn``, ``rate_hz``) and the whole drawing's worst and mean
        marking error and cycle time, and its verdict (the plot marks a case that is not
        ``ok``)."""
        rows: list[dict[str, JsonValue]] = []
        for case, c in cases.items():
            row: dict[str, JsonValue] = {"case": case}
            for key in self.keys:
                row[key.rsplit(".", 1)[-1]] = c.section("settings").get(key)
            for key in ("marking_max_um", "marking_mean_um", "sim_s"):
                value = c.number("whole", key)
                row[key] = round(value, 3) if math.isfinite(value) else None
            row["verdict"] = c.text("whole", "verdict", "")
            rows.append(row)

        def order(row: dict[str, JsonValue]) -> tuple[tuple[float, str], ...]:
            return tuple((float(v), "") if isinstance(v, int | float) else (math.inf, str(v))
                         for v in (row[k.rsplit(".", 1)[-1]] for k in self.keys))
        return sorted(rows, key=order)

    # --- the shared machinery ---------------------------------------------------------

    def compute_case(self, cfg: Config, data: Path, suffix: str = "") -> CaseResult:
        """Run the case ``cfg`` describes (nothing written).

        Args:
            cfg: the case's settings.
            data: the data folder (the stored drawing and models).
            suffix: added to the case's name (a by-hand sweep's other overrides).

        Raises:
            TattotronixError: whatever the drawing or run refuses.
        """
        name = artwork_name(cfg.artwork)
        case = self.case_name(cfg) + suffix
        desc: RobotDescription = build_description(cfg.robot)
        chain = Chain.from_description(desc)
        drawing = resolve_drawing(cfg, data, desc)
        plant_dt = self.plant_dt_s(cfg)
        settle = float(cfg.draw.settle_periods)
        windows: dict[str, JsonDict] = {}
        series: dict[str, NDArray[np.generic]] = {}
        analysis: Mapping[str, object] = {}  # the loop facts (a LoopReport)
        controller: JsonDict = {}
        for window in self.windows:
            label = "whole" if window is None else str(window)
            if cfg.backend.name == "servo":  # the servos close their own loops
                loop = run_servo_loop(cfg, data, desc, drawing, window=window,
                                      plant_dt_s=plant_dt, progress=bool(cfg.draw.progress))
            else:
                loop = run_closed_loop(cfg, data, desc, drawing, window=window,
                                       plant_dt_s=plant_dt,
                                       progress=bool(cfg.draw.progress))
            m, s = _window_metrics(loop, chain, settle)
            m.update(self.window_metrics(cfg, loop, chain))
            windows[label] = m
            series.update({f"{label}_{k}": v for k, v in s.items()})
            if not controller:  # the loop facts of the first window (the whole drawing)
                analysis, controller = loop.analysis or {}, loop.controller
            log.info("%s %s %s (%s): %s; settled %s / marking max %s, peak %.3f N m "
                     "(%s loop, %.0fx real time)", self.name, name, case, label,
                     m["verdict"], _fmt(m["settled_mean_um"]), _fmt(m["marking_max_um"]),
                     m["peak_torque_nm"], loop.run.loop, loop.run.realtime_factor)
        record: dict[str, object] = {
            "study": self.name, "name": name, "case": case,
            "backend": str(setting(cfg, "backend")),
            "settings": {k: setting(cfg, k) for k in self.keys},
            "plant_dt_s": plant_dt if plant_dt is not None else float(cfg.plant.dt_s),
            "drawing": _drawing_figures(drawing),
            "controller": controller, "loop": analysis, **windows,
        }
        record.update(self.case_metrics(cfg, name, windows))
        return CaseResult(name, case, _json_dict(record), series,
                          make_provenance(cfg, drawing.inputs, roots=(data,)))

    def write_case(self, out: Outputs, result: CaseResult) -> None:
        """Write a case's metrics (``data/metrics/<study>/<name>/<case>.json``) and series
        (``data/studies/<study>/<name>/<case>.npz``)."""
        out.write_json(out.path("metrics", self.name, result.name, f"{result.case}.json"),
                       result.metrics)
        StudySeriesRecord(result.series).save(
            out.tmp_path(StudySeriesRecord.path(out.root, self.name, result.name,
                                                result.case)),
            result.provenance)

    def run_case(self, cfg: Config, out: Outputs) -> JsonDict:
        """Run the case ``cfg`` describes; write its metrics and series.

        Returns:
            The case metrics (also written to ``data/metrics/<study>/<name>/<case>.json``).

        Raises:
            TattotronixError: whatever the drawing or run refuses.
        """
        # a by-hand sweep over other keys (``-m plant.damping=0,0.01``) names them too
        result = self.compute_case(cfg, out.data,
                                   out.sweep_suffix((*self.keys, *_NOT_A_CASE)))
        self.write_case(out, result)
        return result.metrics

    def run_all(self, cfg: Config, out: Outputs, workers: int | None = None) -> list[str]:
        """Run every configured case (:meth:`cases`) concurrently, one process per core
        (forked, so nothing is imported again), and write them all; the study's folders
        then hold exactly these cases (any other file there is removed).

        Returns:
            The case names, as configured.

        Raises:
            TattotronixError: a case refused (the message names it); nothing is written.
            ConfigError: no case is configured, or one is named other than its settings
                name it.
        """
        configs = {case: with_overrides(cfg, overrides)
                   for case, overrides in self.cases(cfg.study).items()}
        if not configs:
            raise ConfigError(f"the {self.name} study has no cases configured (conf/study)")
        for case, c in configs.items():
            if self.case_name(c) != case:
                raise ConfigError(f"the {self.name} case '{case}' runs as "
                                  f"'{self.case_name(c)}': name it so in conf/study")
        longest_first = dict(sorted(configs.items(), key=lambda kv: -self.cost(kv[1])))
        done = {r.case: r for r in run_parallel(self.compute_case, longest_first, out.data,
                                                 workers)}
        results = [done[case] for case in configs]
        name = artwork_name(cfg.artwork)
        first = next(iter(configs))
        folders = (out.path("metrics", self.name, name),
                   StudySeriesRecord.path(out.root, self.name, name, first).parent)
        for folder, suffix in zip(folders, (".json", ".npz"), strict=True):
            for stale in sorted(folder.glob(f"*{suffix}")) if folder.is_dir() else []:
                if stale.stem not in configs:  # a hand run's case: not this stage's
                    out.remove(stale)
        for result in results:
            self.write_case(out, result)
        return list(configs)

    def stage_body(self, cfg: Config, out: Outputs) -> None:
        """The study's stage: every configured case with ``study.all_cases=true`` (what
        dvc.yaml runs), else the case the config describes. A study's script is
        ``run_stage(STUDY.name, STUDY.stage_body)`` (:func:`tattotronix.stage.run_stage`)."""
        if cfg.study.all_cases:
            self.run_all(cfg, out)
        else:
            self.run_case(cfg, out)

    def load_cases(self, data: Path, name: str) -> dict[str, StudyCase]:
        """Every stored case of this study on one artwork: case name -> metrics."""
        return load_cases(data, self.name, name)


def load_cases(data: Path, study: str, name: str) -> dict[str, StudyCase]:
    """Every stored case of a study on one artwork: case name -> the case."""
    folder = data / "metrics" / study / name
    return {p.stem: StudyCase.load(p, study) for p in sorted(folder.glob("*.json"))}


# --- cases in parallel -------------------------------------------------------------------

#: a case's run: (settings, data folder) -> the result
CaseRun = Callable[[Config, Path], CaseResult]


def _one(run: CaseRun, cfg: Config, data: Path) -> CaseResult | str:
    """Run one case in a worker: its result, or the message of what it refused (our
    errors carry their own arguments, so they travel back as text)."""
    try:
        return run(cfg, data)
    except (TattotronixError, ConfigError) as exc:
        return str(exc)


def run_parallel(run: CaseRun, cases: Mapping[str, Config], data: Path,
                 workers: int | None = None) -> list[CaseResult]:
    """``run`` on every case's config, in a pool of ``workers`` forked processes (default: one
    per core this process may use), in order.

    The pool forks after the imports the cases share (:func:`warm_up`), so no worker
    imports them again.

    Raises:
        TattotronixError: a case refused; the message names it (the first, in order).
    """
    if workers is None:
        workers = usable_cores()
    configs = list(cases.values())
    workers = max(1, min(len(configs), workers))
    if workers == 1:
        outcomes: list[CaseResult | str] = [_one(run, c, data) for c in configs]
    else:
        import multiprocessing

        warm_up()  # the shared imports, once, before the fork
        # a Pool, not a ProcessPoolExecutor: leaving the block terminates the workers, so a
        # Ctrl-C stops every case at once instead of running the queued ones first
        with multiprocessing.get_context("fork").Pool(workers, worker_signals) as pool:
            outcomes = pool.starmap(_one, [(run, c, data) for c in configs], chunksize=1)
    for case, outcome in zip(cases, outcomes, strict=True):
        if isinstance(outcome, str):
            raise TattotronixError(f"case '{case}': {outcome}")
    return [o for o in outcomes if not isinstance(o, str)]


# --- config values -----------------------------------------------------------------------

def setting(cfg: Config, dotted: str) -> str | float | bool | None:
    """The config value at a dotted key (an enum as its name).

    Raises:
        ConfigError: the key names a section or a list, not one value.
    """
    node: object = cfg
    for part in dotted.split("."):
        node = getattr(node, part)
    value = getattr(node, "name", node)
    if value is None or isinstance(value, str | int | float | bool):
        return value
    raise ConfigError(f"{dotted} is not one value (a {type(value).__name__}): a study "
                      "records single settings")


def int_label(v: float) -> str:
    """``500`` for 500.0, ``0.5`` for 0.5 (case names)."""
    return str(int(v)) if float(v).is_integer() else f"{v:g}"


# --- one case ----------------------------------------------------------------------------

def _drawing_figures(d: Drawing) -> JsonDict:
    return {"points": int(len(d.t)), "duration_s": float(d.t[-1]),
            "entries": int(len(entry_times(d.t, d.kind))), "origin": d.origin}


def _window_metrics(loop: ClosedLoop, chain: Chain, settle_periods: float
                    ) -> tuple[JsonDict, dict[str, NDArray[np.generic]]]:
    err = loop.errors(chain, settle_periods)
    m = loop.metrics(err)
    for k in (*_WALL_KEYS, "loop", "controller", "name", "backend", "drawing"):
        m.pop(k, None)
    series: dict[str, NDArray[np.generic]] = {
        "t": err.t, "error_um": (err.error_m * 1e6).astype(np.float32),
        "down": err.down, "settled": err.settled}
    return m, series


def _json_dict(obj: Mapping[str, object]) -> JsonDict:
    return {str(k): _json_ready(v) for k, v in obj.items()}


def _json_ready(obj: object) -> JsonValue:
    """``obj`` as plain JSON: string keys, lists, Python numbers, non-finite floats as
    None."""
    if isinstance(obj, dict):
        return _json_dict(obj)
    if isinstance(obj, list | tuple):
        return [_json_ready(v) for v in obj]
    if isinstance(obj, np.generic):
        return _json_ready(obj.item())
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    if obj is None or isinstance(obj, str | int | float):
        return obj
    raise TypeError(f"not a JSON value: {obj!r}")


def _as_float(value: JsonValue, what: str, missing: float | None = None) -> float:
    """A stored number as a float (``missing`` where it is null or absent; None: refuse)."""
    if value is None and missing is not None:
        return missing
    if isinstance(value, int | float | str):
        return float(value)
    raise ValueError(f"{what}: {value!r} is not a number")


def _fmt(um: object) -> str:
    """A metric in µm, in µm or (from a millimetre up) in mm; ``-`` where it is None."""
    return length_text(float(um) if isinstance(um, int | float) else None)


# --- what the figures share ----------------------------------------------------------------

#: the windows of a case: key, legend label, line style
WINDOWS = (("whole", "whole drawing", "-"), ("busiest", "busiest window", "--"))
#: a run's verdict -> its colour (every verdict of :data:`tattotronix.control.verdict.VERDICTS`)
VERDICT_COLOUR = {"ok": "#2a9d55", "out-of-tolerance": "#7b5ea7", "saturated": "#e08a1e",
                  "diverged": "#c0392b"}


def window_value(case: StudyCase, window: str, key: str) -> float:
    """A window's metric of a case (NaN where the window or the metric is missing)."""
    return case.number(window, key)


def sorted_by(cases: Cases, key: str) -> list[tuple[float, StudyCase]]:
    """(setting, case) pairs, ascending in one swept setting."""
    return sorted(((c.setting(key), c) for c in cases.values()), key=lambda x: x[0])


def finish_figure(fig: Figure, path: Path, study: str, title: str, about: str,
                  bottom: float = 0.0, then: Callable[[], object] | None = None) -> None:
    """Title a study figure ("<Study> study: <title> (<about>)"), lay it out, write it to
    ``path`` and close it.

    Args:
        bottom: the share of the height kept free below the axes (a figure legend).
        then: run once the layout is final, before the figure is written (labels placed
            where they cover least need the final layout).
    """
    plt = pyplot()
    fig.suptitle(f"{study} study{': ' + title if title else ''} ({about})")
    fig.tight_layout(rect=(0.0, bottom, 1.0, 1.0))
    if then is not None:
        then()
    fig.savefig(path, dpi=130)
    plt.close(fig)


def log_axes_with_twin(ax: Axes, xlabel: str, ylabel: str, x: list[float],
                       twin_y: list[float], twin_label: str, twin_ylabel: str) -> None:
    """Log-scale errors on ``ax``, a dotted cost curve on a twin axis, one legend (below
    the axes, where it covers no curve)."""
    ax.set_yscale("log")
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.grid(True, which="both", alpha=0.3)
    ax2 = ax.twinx()
    ax2.plot(x, twin_y, "d:", color="0.3", label=twin_label)
    ax2.set_ylabel(twin_ylabel)
    h1, l1 = ax.get_legend_handles_labels()
    h2, l2 = ax2.get_legend_handles_labels()
    ax.legend(h1 + h2, l1 + l2, fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.13),
              ncol=min(4, len(h1 + h2)), frameon=False)
