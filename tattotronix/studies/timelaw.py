"""The time-law study (docs/timelaw.md): the tip's acceleration limit x the joints' jerk
limit, over the whole drawing, against the cycle time.

Cases: ``study.timelaw_tip_mm_s2`` x ``study.timelaw_jerk_rad_s3``; a case sets
``trajectory.tip_accel_mm_s2`` and ``trajectory.jerk_rad_s3``, is named
``tip100-jerk500``, re-times the drawing from its IK path with those limits and runs it
closed loop (the default controller: MuJoCo, pid_g_v at wn 160 and 1 kHz) over the whole
drawing. Stage ``timelaw`` (``stages/timelaw.py``); the machinery is
:class:`tattotronix.studies.base.ClosedLoopStudy`. The defaults in ``conf/trajectory``
are the fastest case that meets the accuracy goals (:func:`meets_goals`).
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

from tattotronix.config.schema import Config, StudyConfig
from tattotronix.io.artifacts import IkRecord
from tattotronix.io.jsontypes import JsonDict, JsonValue
from tattotronix.plotting import pyplot
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
        """Worst marking error and settled mean against the cycle, one point per case."""
        plt = pyplot()
        fig, axes = plt.subplots(1, 3, figsize=(16, 4.8))
        jerks = sorted({c.setting("trajectory.jerk_rad_s3") for c in cases.values()})
        markers = dict(zip(jerks, "osD^v", strict=False))
        for ax, key, goal, label in (
                (axes[0], "marking_max_um", GOALS["marking_max_um"], "worst marking error, um"),
                (axes[1], "settled_mean_um", GOALS["settled_mean_um"], "settled mean, um"),
                (axes[2], "travel_mean_um", GOALS["travel_mean_um"], "travel mean error, um")):
            for case, c in cases.items():
                x = c.number("cycle", "cycle_over_marking")
                y = c.number("whole", key)
                ax.scatter(x, y, marker=markers.get(c.setting("trajectory.jerk_rad_s3"), "o"),
                           s=60, color="tab:green" if meets_goals(c) else "tab:red",
                           edgecolor="k", zorder=3)
                ax.annotate(case, (x, y), fontsize=7, xytext=(4, 3),
                            textcoords="offset points")
            ax.axhline(goal, color="k", ls="--", lw=1)
            ax.text(ax.get_xlim()[0], goal, " goal", va="bottom", fontsize=8)
            ax.set_xlabel("cycle over marking-only time")
            ax.set_ylabel(label)
            ax.grid(True, alpha=0.3)
        for j, m in markers.items():
            axes[0].scatter([], [], marker=m, color="0.6", edgecolor="k",
                            label=f"jerk {j:g} rad/s^3")
        axes[0].scatter([], [], color="tab:green", label="meets every goal")
        axes[0].scatter([], [], color="tab:red", label="misses one")
        axes[0].legend(fontsize=8)
        finish_figure(fig, path, "Time law", title,
                      "tip acceleration x jerk limit; MuJoCo, pid_g_v, wn 160, 1 kHz")

    def summary(self, cases: Cases) -> JsonDict:
        """The fastest case that meets every goal (``None`` when none does)."""
        good = {k: c for k, c in cases.items() if meets_goals(c)}
        best = min(good, key=lambda k: good[k].number("cycle", "cycle_over_marking"), default=None)
        return {"cases": len(cases), "meet_goals": len(good), "fastest_meeting_goals": best,
                "fastest_cycle_over_marking": good[best].number("cycle", "cycle_over_marking")
                if best is not None else None}


#: the time-law study
STUDY = TimeLawStudy()
