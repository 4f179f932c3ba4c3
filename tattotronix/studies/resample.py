"""The resample study (docs/toolpath.md, "The resample study: why 0.15 mm"; the original's:
docs/original.md, "2.11 The resample study"): the toolpath's point step.

Cases: ``study.step_mm``; a case sweeps ``toolpath.step_mm`` (the drawing is re-planned in
memory) and is named ``0.15mm``; it runs over the whole drawing, and adds the chord error
of the resampled outlines (:func:`chord_error_mm`). Stage ``resample``
(``stages/resample.py``); the machinery is :class:`tattotronix.studies.base.ClosedLoopStudy`.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from tattotronix.config.schema import Config, StudyConfig
from tattotronix.io.jsontypes import JsonDict, JsonValue
from tattotronix.path.params import ToolpathParams
from tattotronix.path.strokes import build_drawing
from tattotronix.plotting import pyplot
from tattotronix.studies.base import (
    Cases,
    ClosedLoopStudy,
    finish_figure,
    log_axes_with_twin,
    sorted_by,
    window_value,
)

__all__ = ["STUDY", "ResampleStudy", "chord_error_mm"]


def chord_error_mm(dense: NDArray[np.float64], step_mm: float) -> float:
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


def _chord_error(cfg: Config, name: str) -> JsonDict:
    """The resampling's chord error over the drawing's outlines (fill rows are straight)."""
    from tattotronix.app.pipeline import mask_of

    source = cfg.artwork.source if cfg.artwork.source is not None else name
    mask = mask_of(cfg, source, name)
    params = ToolpathParams.from_settings(cfg.toolpath, cfg.mask, cfg.robot.panel)
    drawing = build_drawing(mask, params)
    step = float(cfg.toolpath.step_mm)
    errs = [chord_error_mm(s.path_mm, step) for s in drawing.strokes if s.is_outline]
    return {"chord_error_um": max(errs) * 1000.0 if errs else 0.0,
            "outlines": len(errs), "mask_res_mm": float(cfg.mask.res_mm)}


class ResampleStudy(ClosedLoopStudy):
    """Point step against the chord error, the tracking and the point count."""

    name = "resample"
    keys = ("toolpath.step_mm",)

    def cases(self, study: StudyConfig) -> dict[str, list[str]]:
        return {f"{v}mm": [f"toolpath.step_mm={v}"] for v in study.step_mm}

    def case_name(self, cfg: Config) -> str:
        return f"{float(cfg.toolpath.step_mm)}mm"

    def case_metrics(self, cfg: Config, name: str,
                     windows: Mapping[str, Mapping[str, JsonValue]]) -> JsonDict:
        return {"chord": _chord_error(cfg, name)}

    def figure(self, cases: Cases, path: Path, title: str = "") -> None:
        """Chord error and tracking (µm), and the point count, against the point step."""
        plt = pyplot()
        rows = sorted_by(cases, "toolpath.step_mm")
        h = [x for x, _ in rows]
        fig, ax = plt.subplots(figsize=(8, 4.8))
        ax.plot(h, [c.number("chord", "chord_error_um") for _, c in rows], "o-",
                color="#2a9d55", label="chord error (outlines)")
        ax.plot(h, [window_value(c, "whole", "marking_max_um") for _, c in rows], "s--",
                color="#c0392b", label="worst marking")
        ax.plot(h, [window_value(c, "whole", "settled_mean_um") for _, c in rows], "^-",
                color="#3b6fb6", label="settled mean")
        if rows:
            res_um = rows[0][1].number("chord", "mask_res_mm") * 1000.0
            ax.axhline(res_um, color="0.5", lw=0.8, ls=":")
            # at the right end: the point count's first marker is at the left, up here
            ax.text(h[-1], res_um, f"mask pixel {res_um:g} µm ", fontsize=8, va="bottom",
                    ha="right", color="0.35")
        log_axes_with_twin(ax, "point step, mm", "error, µm", h,
                           [c.number("drawing", "points") for _, c in rows],
                           "trajectory points", "trajectory points")
        finish_figure(fig, path, "Resample", title, "whole drawing")

    def summary(self, cases: Cases) -> JsonDict:
        """The chord error, the worst marking and the point count of each step."""
        return {f"{step:g}mm": {"chord_error_um": c.number("chord", "chord_error_um"),
                                "marking_max_um": window_value(c, "whole", "marking_max_um"),
                                "points": int(c.number("drawing", "points"))}
                for step, c in sorted_by(cases, "toolpath.step_mm")}


#: the resample study
STUDY = ResampleStudy()
