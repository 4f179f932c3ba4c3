"""The closed-loop studies: control, approach, resample and rate (reference sections
2.11 and 5.5 to 5.8), one *case* per run.

Each study is a sweep over ordinary config keys; one run of ``stages/<study>.py`` is one
case, named from the swept values:

========== ===================================== ============================ ==========
study      swept keys                            case name                    windows
========== ===================================== ============================ ==========
control    ``controller.structure``, ``.wn``     ``pid_g-wn40``               whole,
                                                                              busiest
approach   ``toolpath.approach_mm``              ``4.0mm``                    whole
resample   ``toolpath.step_mm``                  ``0.15mm``                   whole
rate       ``controller.rate_hz``, ``.wn``;      ``500hz-wn80``               whole,
           the plant at ``study.rate_plant_dt_s``                             busiest
========== ===================================== ============================ ==========

A case plays the drawing closed loop (:func:`tattotronix.control.drawing.run_closed_loop`,
the plant of ``backend``) over the whole drawing and, where the original reported that
way, over its busiest ``study.window_s`` window, and scores it as section 5.5 does. It
writes ``data/metrics/<study>/<name>/<case>.json`` (settings, drawing figures, the
tracking metrics of each window, the loop analysis; no wall times, so ``dvc metrics
diff`` shows only what changed) and ``data/studies/<study>/<name>/<case>.npz`` (the
sampled error series of each window, for the figures).

A drawing whose path settings differ from the stored trajectory's (approach, step) is
re-planned in memory from the artwork (:func:`~tattotronix.control.drawing.resolve_drawing`).
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from tattotronix.art.artwork import artwork_name
from tattotronix.control.drawing import ClosedLoop, Drawing, resolve_drawing, run_closed_loop
from tattotronix.control.tracking import entry_times
from tattotronix.errors import TattotronixError
from tattotronix.io.outputs import Outputs
from tattotronix.kinematics import Chain
from tattotronix.path.params import ToolpathParams
from tattotronix.path.strokes import build_drawing
from tattotronix.robot.description import RobotDescription, build_description

__all__ = ["STUDIES", "StudySpec", "case_name", "chord_error_mm", "load_cases",
           "rate_verdict_check", "run_case"]

log = logging.getLogger("tattotronix.studies")
Array = NDArray[np.float64]

#: metrics of a run that depend on the machine, not on the physics (left out of studies)
_WALL_KEYS = ("wall_s", "realtime_factor")


@dataclass(frozen=True)
class StudySpec:
    """What a closed-loop study sweeps and how it scores.

    Attributes:
        name: the study (its stage, and its folders under ``data/metrics`` and
            ``data/studies``).
        windows: the stretches each case runs: ``None`` (whole drawing) and/or
            ``"busiest"``.
        keys: the swept config keys (dotted), recorded as the case's settings.
    """

    name: str
    windows: tuple[str | None, ...]
    keys: tuple[str, ...]


STUDIES: dict[str, StudySpec] = {
    "control": StudySpec("control", (None, "busiest"),
                         ("controller.structure", "controller.wn")),
    "approach": StudySpec("approach", (None,), ("toolpath.approach_mm",)),
    "resample": StudySpec("resample", (None,), ("toolpath.step_mm",)),
    "rate": StudySpec("rate", (None, "busiest"), ("controller.rate_hz", "controller.wn")),
}


def _get(cfg: Any, dotted: str) -> Any:
    node = cfg
    for part in dotted.split("."):
        node = getattr(node, part)
    return getattr(node, "name", node)  # enums -> their name


def _int_label(v: float) -> str:
    return str(int(v)) if float(v).is_integer() else f"{v:g}"


def case_name(study: str, cfg: Any) -> str:
    """The case's name, from the swept values (as dvc.yaml's ``foreach``/``matrix`` names
    the outputs: ``pid_g-wn40``, ``4.0mm``, ``0.15mm``, ``500hz-wn80``)."""
    if study == "control":
        return f"{_get(cfg, 'controller.structure')}-wn{float(cfg.controller.wn):g}"
    if study == "approach":
        return f"{float(cfg.toolpath.approach_mm)}mm"
    if study == "resample":
        return f"{float(cfg.toolpath.step_mm)}mm"
    if study == "rate":
        return (f"{_int_label(float(cfg.controller.rate_hz))}hz-"
                f"wn{_int_label(float(cfg.controller.wn))}")
    raise TattotronixError(f"unknown study '{study}': one of {', '.join(STUDIES)}")


def chord_error_mm(dense: Array, step_mm: float) -> float:
    """The worst distance from a dense polyline to the chords of its resampling.

    The resampled points lie on the polyline at arc-length stations ``0, h, 2h, ..``
    (:func:`tattotronix.path.polyline.resample`); each dense vertex is measured against
    the chord that spans its arc length (about ``h^2 / 8R`` on a curve of radius R).

    Args:
        dense: (n, 2) polyline vertices, mm (the smoothed traced contour).
        step_mm: the resampling step, mm.
    """
    from tattotronix.path.polyline import resample, stations

    p = np.asarray(dense, dtype=np.float64)
    seg = np.linalg.norm(np.diff(p, axis=0), axis=1)
    if len(p) < 3 or seg.sum() <= 0:
        return 0.0
    s = np.concatenate([[0.0], np.cumsum(seg)])
    r = resample(p, step_mm)
    st = stations(float(s[-1]), step_mm)  # chord j spans arc length [st_j, st_j+1]
    if len(st) != len(r) or len(r) < 2:
        return 0.0
    j = np.clip(np.searchsorted(st, s, side="right") - 1, 0, len(r) - 2)
    a, b = r[j], r[j + 1]
    ab = b - a
    L2 = np.einsum("ij,ij->i", ab, ab)
    u = np.where(L2 > 0, np.einsum("ij,ij->i", p - a, ab) / np.where(L2 > 0, L2, 1.0), 0.0)
    u = np.clip(u, 0.0, 1.0)
    d = np.linalg.norm(p - (a + u[:, None] * ab), axis=1)
    return float(d.max())


def _chord_error(cfg: Any, name: str) -> dict[str, Any]:
    """The resampling's chord error over the drawing's outlines (fill rows are straight)."""
    from tattotronix.pipeline import mask_of

    source = cfg.artwork.source if cfg.artwork.source is not None else name
    mask = mask_of(cfg, source, name)
    params = ToolpathParams.from_config(cfg.toolpath, cfg.mask, cfg.robot.panel)
    drawing = build_drawing(mask, params)
    step = float(cfg.toolpath.step_mm)
    errs = [chord_error_mm(s.path_mm, step) for s in drawing.strokes if s.is_outline]
    return {"chord_error_um": max(errs) * 1000.0 if errs else 0.0,
            "outlines": len(errs), "mask_res_mm": float(cfg.mask.res_mm)}


def _drawing_figures(d: Drawing) -> dict[str, Any]:
    return {"points": int(len(d.t)), "duration_s": float(d.t[-1]),
            "entries": int(len(entry_times(d.t, d.kind))), "origin": d.origin}


def rate_verdict_check(loop: ClosedLoop) -> dict[str, Any]:
    """The run's verdict beside the computed sampled-loop boundary (reference section 5.8).

    ``boundary_wnT`` is 2/(3 lambda_max) (exact hold), ``boundary_numeric_wnT`` the same
    loop with the plant's Euler sub-steps; ``predicted`` is ``ok`` below the latter.
    """
    a = loop.analysis
    predicted = "ok" if a["wnT"] < a["sampled_boundary_numeric_wnT"] else "fail"
    return {"wnT": a["wnT"], "boundary_wnT": a["sampled_boundary_wnT"],
            "boundary_numeric_wnT": a["sampled_boundary_numeric_wnT"],
            "lambda_max": a["modal_gain"][0], "substeps": loop.run.substeps,
            "predicted": predicted, "verdict": loop.run.verdict,
            "agrees": (loop.run.verdict == "ok") == (predicted == "ok")}


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


def run_case(study: str, cfg: Any, out: Outputs) -> dict[str, Any]:
    """Run one case of a closed-loop study; write its metrics and series.

    Returns:
        The case metrics (also written to ``data/metrics/<study>/<name>/<case>.json``).

    Raises:
        TattotronixError: an unknown study, or whatever the drawing or run refuses.
    """
    if study not in STUDIES:
        raise TattotronixError(f"unknown study '{study}': one of {', '.join(STUDIES)}")
    spec = STUDIES[study]
    name = artwork_name(cfg.artwork)
    # a by-hand sweep over other keys (``-m plant.damping=0,0.01``) names them too
    case = case_name(study, cfg) + out.sweep_suffix(
        (*spec.keys, "artwork.name", "artwork.source", "draw.progress"))
    desc: RobotDescription = build_description(cfg.robot)
    chain = Chain.from_description(desc)
    drawing = resolve_drawing(cfg, out.data, desc)
    plant_dt = float(cfg.study.rate_plant_dt_s) if study == "rate" else None
    settle = float(cfg.draw.settle_periods)
    windows: dict[str, Any] = {}
    series: dict[str, NDArray[Any]] = {}
    analysis: dict[str, Any] = {}
    controller: dict[str, Any] = {}
    check: dict[str, Any] = {}
    for window in spec.windows:
        label = "whole" if window is None else str(window)
        loop = run_closed_loop(cfg, out.data, desc, drawing, window=window,
                               plant_dt_s=plant_dt, progress=bool(cfg.draw.progress))
        m, s = _window_metrics(loop, chain, settle)
        if study == "rate":
            m["boundary"] = rate_verdict_check(loop)
            check = check or m["boundary"]
        windows[label] = m
        series.update({f"{label}_{k}": v for k, v in s.items()})
        if not analysis:  # the loop facts of the first window (the whole drawing)
            analysis, controller = loop.analysis, loop.controller.summary()
        log.info("%s %s %s (%s): %s; settled %s / marking max %s um, peak %.3f N m", study,
                 name, case, label, m["verdict"], _fmt(m["settled_mean_um"]),
                 _fmt(m["marking_max_um"]), m["peak_torque_nm"])
    metrics: dict[str, Any] = {
        "study": study, "name": name, "case": case, "backend": str(_get(cfg, "backend")),
        "settings": {k: _get(cfg, k) for k in spec.keys},
        "plant_dt_s": plant_dt if plant_dt is not None else float(cfg.plant.dt_s),
        "drawing": _drawing_figures(drawing),
        "controller": controller, "loop": analysis, **windows,
    }
    if study == "rate":
        metrics["verdict_check"] = check
    if study == "resample":
        metrics["chord"] = _chord_error(cfg, name)
    metrics = _json_ready(metrics)
    out.write_json(out.path("metrics", study, name, f"{case}.json"), metrics)
    np.savez_compressed(out.tmp_path(out.path("studies", study, name, f"{case}.npz")),
                        **series)  # type: ignore[arg-type]
    return metrics


def load_cases(data: Path, study: str, name: str) -> dict[str, dict[str, Any]]:
    """Every stored case of a study on one artwork: case name -> metrics."""
    import json

    folder = data / "metrics" / study / name
    return {p.stem: json.loads(p.read_text()) for p in sorted(folder.glob("*.json"))}


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
