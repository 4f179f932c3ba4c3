"""The approach study (docs/toolpath.md, "The approach study: why 2 mm"; the original's:
docs/original.md, "5.7 The approach study"): the slow last stretch of every plunge.

Cases: ``study.approach_mm``; a case sweeps ``toolpath.approach_mm`` (the drawing is
re-planned in memory) and is named ``4.0mm``; it runs over the whole drawing. Stage
``approach`` (``stages/approach.py``); the machinery is
:class:`tattotronix.studies.base.ClosedLoopStudy`.
"""

from __future__ import annotations

from pathlib import Path

from tattotronix.config.schema import Config, StudyConfig
from tattotronix.io.jsontypes import JsonDict
from tattotronix.plotting import pyplot
from tattotronix.studies.base import (
    Cases,
    ClosedLoopStudy,
    finish_figure,
    log_axes_with_twin,
    sorted_by,
    window_value,
)

__all__ = ["STUDY", "ApproachStudy"]


class ApproachStudy(ClosedLoopStudy):
    """Approach length against the entry error and the cycle time."""

    name = "approach"
    keys = ("toolpath.approach_mm",)

    def cases(self, study: StudyConfig) -> dict[str, list[str]]:
        return {f"{v}mm": [f"toolpath.approach_mm={v}"] for v in study.approach_mm}

    def case_name(self, cfg: Config) -> str:
        return f"{float(cfg.toolpath.approach_mm)}mm"

    def figure(self, cases: Cases, path: Path, title: str = "") -> None:
        """Worst entry error, worst marking and settled mean (µm), and the cycle time (s),
        against the approach length."""
        plt = pyplot()
        rows = sorted_by(cases, "toolpath.approach_mm")
        a = [x for x, _ in rows]
        fig, ax = plt.subplots(figsize=(8, 4.8))
        ax.plot(a, [window_value(c, "whole", "entry_max_um") for _, c in rows], "o-",
                color="#c0392b", label="worst entry (within 4/wn of an entry)")
        ax.plot(a, [window_value(c, "whole", "marking_max_um") for _, c in rows], "s--",
                color="#e08a1e", label="worst marking")
        ax.plot(a, [window_value(c, "whole", "settled_mean_um") for _, c in rows], "^-",
                color="#3b6fb6", label="settled mean")
        log_axes_with_twin(ax, "approach length (last stretch of each plunge at the "
                           "marking feed), mm", "tip error, µm", a,
                           [c.number("drawing", "duration_s") for _, c in rows],
                           "cycle time", "cycle time, s")
        ctl = next(iter(cases.values())).section("controller") if cases else {}
        finish_figure(fig, path, "Approach", title,
                      f"whole drawing, {ctl.get('structure', '?')} at wn "
                      f"{ctl.get('wn', '?')} rad/s")

    def summary(self, cases: Cases) -> JsonDict:
        """The shortest approach whose worst entry error is within 10 % of the best."""
        rows = sorted_by(cases, "toolpath.approach_mm")
        best = min(window_value(c, "whole", "entry_max_um") for _, c in rows)
        enough = next(a for a, c in rows
                      if window_value(c, "whole", "entry_max_um") <= 1.1 * best)
        return {"cases": len(cases), "best_entry_max_um": best,
                "shortest_within_10pct_mm": enough}


#: the approach study
STUDY = ApproachStudy()
