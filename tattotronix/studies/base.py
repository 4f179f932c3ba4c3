"""What a closed-loop study is, and what every closed-loop study shares.

A closed-loop study (control, approach, resample, rate: the original's, docs/original.md,
"2.11 The resample study" and "5.5 Tracking error" to "5.8 The rate study") is a sweep over
ordinary config keys, one *case* per run of its stage
(``python stages/<script>.py [overrides]``, or ``-m KEY=a,b,c`` for a sweep). Each study
is one module of this package holding one :class:`ClosedLoopStudy`, ``STUDY``, which
states:

* ``name``: its stage, and its folders under ``data/metrics`` and ``data/studies``;
* ``keys``: the swept config keys (dotted), recorded as each case's ``settings``;
* ``windows``: the stretches each case runs: ``None`` (the whole drawing) and/or
  ``"busiest"`` (the busiest ``study.window_s`` window, where the original reported);
* :meth:`~ClosedLoopStudy.cases`: the configured cases (``conf/study``), name ->
  overrides, as dvc.yaml's ``foreach``/``matrix`` runs them;
* :meth:`~ClosedLoopStudy.case_name`: a case's name from the swept values (dvc.yaml names
  the outputs the same way);
* :meth:`~ClosedLoopStudy.plant_dt_s`, :meth:`~ClosedLoopStudy.window_metrics` and
  :meth:`~ClosedLoopStudy.case_metrics`: what the study changes or adds to a case;
* :meth:`~ClosedLoopStudy.figure` and :meth:`~ClosedLoopStudy.summary`: its figure and
  its conclusions, from the stored cases (the ``studies`` stage).

The machinery lives here, once: :meth:`ClosedLoopStudy.run_case` plays the drawing closed
loop (:func:`tattotronix.control.drawing.run_closed_loop`, the plant of ``backend``) over
each window, scores it as the original did (docs/original.md, "5.5 Tracking error"), and
writes ``data/metrics/<study>/<name>/<case>.json`` (settings, drawing figures, the tracking
metrics of each window, the loop analysis; no wall times, so ``dvc metrics diff`` shows
only what changed) and ``data/studies/<study>/<name>/<case>.npz`` (the sampled error
series of each window, ``<window>_t``, ``<window>_error_um``, ``<window>_down`` and
``<window>_settled``, with the provenance:
:class:`~tattotronix.io.artifacts.StudySeriesRecord`). In a ``-m`` sweep, any
override that is not a swept key is added to the case name
(:meth:`tattotronix.io.outputs.Outputs.sweep_suffix`), so no two jobs write the same file.
:meth:`ClosedLoopStudy.stage_body` is the whole of a study's stage script.

A drawing whose path settings differ from the stored trajectory's (approach, step) is
re-planned in memory from the artwork (:func:`~tattotronix.control.drawing.resolve_drawing`).

Adding a study: its module here (a subclass, and ``STUDY``), its line in
:mod:`tattotronix.studies.registry` (for the ``studies`` stage), its settings in
``conf/study`` (and their fields in ``StudyConfig``, ``tattotronix/config/schema.py``),
a three-line ``stages/<script>.py``, and its stage in ``dvc.yaml``.
"""

from __future__ import annotations

import json
import logging
import math
from abc import ABC, abstractmethod
from collections.abc import Mapping
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from tattotronix.art.artwork import artwork_name
from tattotronix.config.schema import Config, StudyConfig
from tattotronix.control.drawing import ClosedLoop, Drawing, resolve_drawing, run_closed_loop
from tattotronix.control.tracking import entry_times
from tattotronix.io.artifacts import StudySeriesRecord, make_provenance
from tattotronix.io.outputs import Outputs
from tattotronix.kinematics import Chain
from tattotronix.robot.description import RobotDescription, build_description

__all__ = ["VERDICT_COLOUR", "WINDOWS", "Cases", "ClosedLoopStudy", "int_label",
           "load_cases", "log_axes_with_twin", "setting", "sorted_by", "window_value"]

log = logging.getLogger("tattotronix.studies")

#: a study's stored cases on one artwork: case name -> metrics
Cases = Mapping[str, Mapping[str, Any]]

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
        that run it (dvc.yaml runs the same values)."""

    @abstractmethod
    def case_name(self, cfg: Config) -> str:
        """The case's name, from the swept values (as dvc.yaml's ``foreach``/``matrix``
        names the outputs)."""

    def plant_dt_s(self, cfg: Config) -> float | None:
        """The plant's step for this study's runs; None: ``plant.dt_s``."""
        return None

    def window_metrics(self, loop: ClosedLoop) -> dict[str, Any]:
        """Metrics added to each window's (empty by default)."""
        return {}

    def case_metrics(self, cfg: Config, name: str,
                     windows: Mapping[str, Mapping[str, Any]]) -> dict[str, Any]:
        """Metrics added to the case's, given each window's (label -> metrics; empty by
        default)."""
        return {}

    @abstractmethod
    def figure(self, cases: Cases, path: Path, title: str = "") -> None:
        """Draw the study's figure from its cases on one artwork; save it as a PNG."""

    @abstractmethod
    def summary(self, cases: Cases) -> dict[str, Any]:
        """What the study concludes from its cases on one artwork (JSON-ready)."""

    # --- the shared machinery ---------------------------------------------------------

    def run_case(self, cfg: Config, out: Outputs) -> dict[str, Any]:
        """Run the case ``cfg`` describes; write its metrics and series.

        Returns:
            The case metrics (also written to ``data/metrics/<study>/<name>/<case>.json``).

        Raises:
            TattotronixError: whatever the drawing or run refuses.
        """
        name = artwork_name(cfg.artwork)
        # a by-hand sweep over other keys (``-m plant.damping=0,0.01``) names them too
        case = self.case_name(cfg) + out.sweep_suffix((*self.keys, *_NOT_A_CASE))
        desc: RobotDescription = build_description(cfg.robot)
        chain = Chain.from_description(desc)
        drawing = resolve_drawing(cfg, out.data, desc)
        plant_dt = self.plant_dt_s(cfg)
        settle = float(cfg.draw.settle_periods)
        windows: dict[str, Any] = {}
        series: dict[str, NDArray[Any]] = {}
        analysis: dict[str, Any] = {}
        controller: dict[str, Any] = {}
        for window in self.windows:
            label = "whole" if window is None else str(window)
            loop = run_closed_loop(cfg, out.data, desc, drawing, window=window,
                                   plant_dt_s=plant_dt, progress=bool(cfg.draw.progress))
            m, s = _window_metrics(loop, chain, settle)
            m.update(self.window_metrics(loop))
            windows[label] = m
            series.update({f"{label}_{k}": v for k, v in s.items()})
            if not analysis:  # the loop facts of the first window (the whole drawing)
                analysis, controller = loop.analysis, loop.controller.summary()
            log.info("%s %s %s (%s): %s; settled %s / marking max %s um, peak %.3f N m",
                     self.name, name, case, label, m["verdict"], _fmt(m["settled_mean_um"]),
                     _fmt(m["marking_max_um"]), m["peak_torque_nm"])
        metrics: dict[str, Any] = {
            "study": self.name, "name": name, "case": case,
            "backend": str(setting(cfg, "backend")),
            "settings": {k: setting(cfg, k) for k in self.keys},
            "plant_dt_s": plant_dt if plant_dt is not None else float(cfg.plant.dt_s),
            "drawing": _drawing_figures(drawing),
            "controller": controller, "loop": analysis, **windows,
        }
        metrics.update(self.case_metrics(cfg, name, windows))
        metrics = _json_ready(metrics)
        out.write_json(out.path("metrics", self.name, name, f"{case}.json"), metrics)
        StudySeriesRecord(series).save(
            out.tmp_path(StudySeriesRecord.path(out.data, self.name, name, case)),
            make_provenance(cfg, drawing.inputs))
        return metrics

    def stage_body(self, cfg: Config, out: Outputs) -> None:
        """The study's stage: run the case the config describes. A study's script is
        ``run_stage(STUDY.name, STUDY.stage_body)`` (:func:`tattotronix.stage.run_stage`)."""
        self.run_case(cfg, out)

    def load_cases(self, data: Path, name: str) -> dict[str, dict[str, Any]]:
        """Every stored case of this study on one artwork: case name -> metrics."""
        return load_cases(data, self.name, name)


def load_cases(data: Path, study: str, name: str) -> dict[str, dict[str, Any]]:
    """Every stored case of a study on one artwork: case name -> metrics."""
    folder = data / "metrics" / study / name
    return {p.stem: json.loads(p.read_text()) for p in sorted(folder.glob("*.json"))}


# --- config values -----------------------------------------------------------------------

def setting(cfg: Any, dotted: str) -> Any:
    """The config value at a dotted key (an enum as its name)."""
    node = cfg
    for part in dotted.split("."):
        node = getattr(node, part)
    return getattr(node, "name", node)


def int_label(v: float) -> str:
    """``500`` for 500.0, ``0.5`` for 0.5 (case names)."""
    return str(int(v)) if float(v).is_integer() else f"{v:g}"


# --- one case ----------------------------------------------------------------------------

def _drawing_figures(d: Drawing) -> dict[str, Any]:
    return {"points": int(len(d.t)), "duration_s": float(d.t[-1]),
            "entries": int(len(entry_times(d.t, d.kind))), "origin": d.origin}


def _window_metrics(loop: ClosedLoop, chain: Chain, settle_periods: float
                    ) -> tuple[dict[str, Any], dict[str, NDArray[Any]]]:
    err = loop.errors(chain, settle_periods)
    m = loop.metrics(err)
    for k in (*_WALL_KEYS, "loop", "controller", "name", "backend", "drawing"):
        m.pop(k, None)
    series: dict[str, NDArray[Any]] = {
        "t": err.t, "error_um": (err.error_m * 1e6).astype(np.float32),
        "down": err.down, "settled": err.settled}
    return m, series


def _json_ready(obj: Any) -> Any:
    if isinstance(obj, dict):
        return {str(k): _json_ready(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_json_ready(v) for v in obj]
    if isinstance(obj, np.generic):
        return _json_ready(obj.item())
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    return obj


def _fmt(v: float | None) -> str:
    return "-" if v is None else f"{v:.2f}"


# --- what the figures share ----------------------------------------------------------------

#: the windows of a case: key, legend label, line style
WINDOWS = (("whole", "whole drawing", "-"), ("busiest", "busiest window", "--"))
#: a run's verdict -> its colour
VERDICT_COLOUR = {"ok": "#2a9d55", "saturated": "#e08a1e", "diverged": "#c0392b"}


def window_value(case: Mapping[str, Any], window: str, key: str) -> float:
    """A window's metric of a case (NaN where the window or the metric is missing)."""
    w = case.get(window) or {}
    val = w.get(key)
    return float("nan") if val is None else float(val)


def sorted_by(cases: Cases, key: str) -> list[tuple[float, Mapping[str, Any]]]:
    """(setting, case) pairs, ascending in one swept setting."""
    return sorted(((float(c["settings"][key]), c) for c in cases.values()),
                  key=lambda x: x[0])


def log_axes_with_twin(ax: Any, xlabel: str, ylabel: str, x: list[float],
                       twin_y: list[float], twin_label: str, twin_ylabel: str,
                       legend_loc: str) -> None:
    """Log-scale errors on ``ax``, a dotted cost curve on a twin axis, one legend."""
    ax.set_yscale("log")
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.grid(True, which="both", alpha=0.3)
    ax2 = ax.twinx()
    ax2.plot(x, twin_y, "d:", color="0.3", label=twin_label)
    ax2.set_ylabel(twin_ylabel)
    h1, l1 = ax.get_legend_handles_labels()
    h2, l2 = ax2.get_legend_handles_labels()
    ax.legend(h1 + h2, l1 + l2, fontsize=8, loc=legend_loc)
