"""The time-law study (docs/timelaw.md): the tip's acceleration limit x the joints' jerk
limit, over the whole drawing, against the cycle time.

Cases: ``study.timelaw_tip_mm_s2`` x ``study.timelaw_jerk_rad_s3``; a case sets
``trajectory.tip_accel_mm_s2`` and ``trajectory.jerk_rad_s3``, is named
``tip100-jerk500``, re-times the drawing from its IK path with those limits and runs it
closed loop (the default controller: MuJoCo, pid_g_v at wn 160 and 1 kHz) over the whole
drawing. Stage ``timelaw`` (``stages/timelaw.py``); the machinery is
:class:`tattotronix.studies.base.ClosedLoopStudy`. The defaults of ``TrajectoryConfig``
are the fastest case that meets the accuracy goals (:func:`meets_goals`).
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

from tattotronix.config.schema import Config, StudyConfig
from tattotronix.io.artifacts import IkRecord
from tattotronix.io.jsontypes import JsonDict, JsonValue
from tattotronix.plotting import place_labels, pyplot
from tattotronix.studies.base import Cases, ClosedLoopStudy, StudyCase, finish_figure, int_label
from tattotronix.trajectory.path import JointPath

__all__ = ["GOALS", "STUDY", "TimeLawStudy", "meets_goals"]

#: the accuracy goals over the whole drawing (issue "A time law that respects the arm"):
#: metric -> the largest value that meets it
GOALS = {"marking_max_um": 20.0, "settled_mean_um": 2.0, "travel_mean_um": 20.0}


def meets_goals(case: StudyCase) -> bool:
    """Whether a case's whole-drawing run meets every accuracy goal (:data:`GOALS`)."""
    return case.text("whole", "verdict") == "ok" and all(
        case.number("whole", k) < v if k != "settled_mean_um" else
        case.number("whole", k) <= v for k, v in GOALS.items())


class TimeLawStudy(ClosedLoopStudy):
    """Tip acceleration x jerk limit: tracking against cycle time."""

    name = "timelaw"
    keys = ("trajectory.tip_accel_mm_s2", "trajectory.jerk_rad_s3")

    def cases(self, study: StudyConfig) -> dict[str, list[str]]:
        return {f"tip{int_label(a)}-jerk{int_label(j)}": [
            f"trajectory.tip_accel_mm_s2={a}", f"trajectory.jerk_rad_s3={j}"]
            for a in study.timelaw_tip_mm_s2 for j in study.timelaw_jerk_rad_s3}

    def case_name(self, cfg: Config) -> str:
        tr = cfg.trajectory
        tip = "off" if tr.tip_accel_mm_s2 is None else int_label(float(tr.tip_accel_mm_s2))
        jerk = "off" if tr.jerk_rad_s3 is None else int_label(float(tr.jerk_rad_s3))
        return f"tip{tip}-jerk{jerk}"

    def case_metrics(self, cfg: Config, name: str,
                     windows: Mapping[str, Mapping[str, JsonValue]]) -> JsonDict:
        """``cycle``: the run's length over the marking-only time (the marked length of the
        IK path at the marking feed)."""
        path = JointPath.from_npz(IkRecord.path(Path(cfg.paths.data), name=name))
        marking_only = path.marked_length_m() / (cfg.toolpath.feed_mark_m_s * float(cfg.speed))
        whole = windows["whole"]
        duration = float(whole["sim_s"])  # type: ignore[arg-type]
        return {"cycle": {"marking_only_s": marking_only, "cycle_s": duration,
                          "cycle_over_marking": duration / marking_only}}

    def figure(self, cases: Cases, path: Path, title: str = "") -> None:
        """Worst marking error, settled mean and travel mean against the cycle, one point
        per case, each named beside its marker."""
        plt = pyplot()
        fig, axes = plt.subplots(1, 3, figsize=(16, 5.4))
        jerks = sorted({c.setting("trajectory.jerk_rad_s3") for c in cases.values()})
        markers = dict(zip(jerks, "osD^v", strict=False))
        xs = [c.number("cycle", "cycle_over_marking") for c in cases.values()]
        panels = ((axes[0], "marking_max_um", "worst marking error, µm"),
                  (axes[1], "settled_mean_um", "settled mean, µm"),
                  (axes[2], "travel_mean_um", "travel mean error, µm"))
        goals = []
        for ax, key, label in panels:
            goal = GOALS[key]
            for x, c in zip(xs, cases.values(), strict=True):
                ax.scatter(x, c.number("whole", key),
                           marker=markers.get(c.setting("trajectory.jerk_rad_s3"), "o"), s=60,
                           color="tab:green" if meets_goals(c) else "tab:red", edgecolor="k",
                           zorder=3)
            ax.axhline(goal, color="k", ls="--", lw=1)
            ax.set_xlabel("cycle over marking-only time")
            ax.set_ylabel(label)
            ax.grid(True, alpha=0.3)
            # room for the names beside the points, and the goal well inside the axes
            ax.margins(x=0.2, y=0.12)
            lo, hi = ax.get_ylim()
            pad = 0.1 * (hi - lo)
            ax.set_ylim(min(lo, goal - pad), max(hi, goal + pad))
            goals.append(ax.annotate(f"goal {goal:g} µm", (0.99, goal),
                                     xycoords=("axes fraction", "data"), xytext=(0, 3),
                                     textcoords="offset points", ha="right", va="bottom",
                                     fontsize=8))
        for j, m in markers.items():
            axes[0].scatter([], [], marker=m, color="0.6", edgecolor="k",
                            label=f"jerk limit {j:g} rad/s³")
        axes[0].scatter([], [], color="tab:green", label="meets every goal")
        axes[0].scatter([], [], color="tab:red", label="misses one")
        fig.legend(*axes[0].get_legend_handles_labels(), loc="lower center", ncol=5,
                   fontsize=9, frameon=False)

        def names() -> None:
            renderer = fig.canvas.get_renderer()
            for (ax, key, _), text in zip(panels, goals, strict=True):
                place_labels(ax, [(x, c.number("whole", key)) for x, c in
                                  zip(xs, cases.values(), strict=True)], list(cases), 5.0,
                             avoid=[[(x, GOALS[key]) for x in ax.get_xlim()]],
                             taken=[text.get_window_extent(renderer)], fontsize=7.5)

        finish_figure(fig, path, "Time law", title,
                      "tip acceleration × jerk limit; MuJoCo, pid_g_v, wn 160 rad/s, 1 kHz",
                      bottom=0.07, then=names)

    def summary(self, cases: Cases) -> JsonDict:
        """The fastest case that meets every goal (``None`` when none does)."""
        good = {k: c for k, c in cases.items() if meets_goals(c)}
        best = min(good, key=lambda k: good[k].number("cycle", "cycle_over_marking"), default=None)
        return {"cases": len(cases), "meet_goals": len(good), "fastest_meeting_goals": best,
                "fastest_cycle_over_marking": good[best].number("cycle", "cycle_over_marking")
                if best is not None else None}


#: the time-law study
STUDY = TimeLawStudy()
