"""The control study (docs/control.md, "The control study: whole drawing and busiest
window"; the original's: docs/original.md, "5.6 Published control results"): the four
controller structures at wn 20, and ``pid_g`` across the bandwidths, each over the whole
drawing and its busiest window.

Cases: ``study.control.cases`` (name -> structure and wn); a case sweeps
``controller.structure`` and ``controller.wn`` and is named ``pid_g-wn40``. Stage
``control`` (``stages/control_study.py``); the machinery is
:class:`tattotronix.studies.base.ClosedLoopStudy`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

from tattotronix.config.schema import Config, StudyConfig
from tattotronix.io.jsontypes import JsonDict
from tattotronix.plotting import pyplot
from tattotronix.studies.base import (
    VERDICT_COLOUR,
    WINDOWS,
    Cases,
    ClosedLoopStudy,
    StudyCase,
    finish_figure,
    setting,
    window_value,
)

if TYPE_CHECKING:
    from matplotlib.axes import Axes

__all__ = ["STUDY", "ControlStudy"]

_STRUCTURES = ("pid", "pid_g", "pid_g_v", "computed_torque")


def _ok(c: StudyCase) -> bool:
    return c.section("whole").get("verdict") == "ok"


def _worst(c: StudyCase) -> float:
    return window_value(c, "whole", "marking_max_um")


def _structure(c: StudyCase) -> str:
    return c.text("settings", "controller.structure")


def _log_log_wn(ax: Axes, ylabel: str, title: str) -> None:
    """A log-log panel against the bandwidth, with its legend and grid."""
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("wn, rad/s")
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.legend(fontsize=8)
    ax.grid(True, which="both", alpha=0.3)


def _verdicts(ax: Axes, sweep: list[tuple[float, StudyCase]],
              value: Callable[[StudyCase], float]) -> None:
    """Name the verdict of every whole-drawing run whose loop failed (saturated or
    diverged), left of its point (where it has one). An out-of-tolerance run's loop held:
    the tip-error panel's tolerance line shows it."""
    for w, c in sweep:
        verdict = c.text("whole", "verdict")
        y = value(c)
        if verdict in ("saturated", "diverged") and math.isfinite(y):
            ax.annotate(verdict, (w, y), xytext=(-8, 0), textcoords="offset points",
                        fontsize=8, color=VERDICT_COLOUR.get(verdict, "k"), ha="right",
                        va="center")


def _tolerance(ax: Axes, cases: Cases) -> None:
    """The drawing's marking tolerance (where the cases state one), in the legend: a worst
    marking error above it is ``out-of-tolerance``."""
    tol = {t for t in (c.number("whole", "tolerance_um") for c in cases.values())
           if math.isfinite(t)}
    if len(tol) == 1:
        t = tol.pop()
        ax.axhline(t, color=VERDICT_COLOUR["out-of-tolerance"], lw=1.0, ls="--",
                   label=f"tolerance, {t:g} µm: worst marking above is out-of-tolerance")


class ControlStudy(ClosedLoopStudy):
    """Controller structure x bandwidth, over the whole drawing and its busiest window."""

    name = "control"
    keys = ("controller.structure", "controller.wn")
    windows = (None, "busiest")

    def cases(self, study: StudyConfig) -> dict[str, list[str]]:
        return {key: [f"controller.structure={case.structure.name}",
                      f"controller.wn={case.wn}"]
                for key, case in study.control.cases.items()}

    def case_name(self, cfg: Config) -> str:
        return f"{setting(cfg, 'controller.structure')}-wn{float(cfg.controller.wn):g}"

    def cost(self, cfg: Config) -> float:
        # computed torque runs the Python loop (the model every tick); the rest, the engine
        return 4.0 if setting(cfg, "controller.structure") == "computed_torque" else 1.0

    def figure(self, cases: Cases, path: Path, title: str = "") -> None:
        """Structures at wn 20 (bars); the pid_g bandwidth sweep (lines): tip errors, peak
        torque and travel error, each on its own axes."""
        plt = pyplot()
        fig, axes = plt.subplots(2, 2, figsize=(13, 9))
        at20 = [(s, cases[f"{s}-wn20"]) for s in _STRUCTURES if f"{s}-wn20" in cases]
        ax = axes[0, 0]
        width = 0.2
        for i, (key, label, hatch) in enumerate((("settled_mean_um", "settled mean", ""),
                                                  ("marking_max_um", "worst marking", "//"))):
            for j, (win, wlabel, _) in enumerate(WINDOWS):
                xs = [k + (2 * i + j - 1.5) * width for k in range(len(at20))]
                ys = [window_value(c, win, key) for _, c in at20]
                ax.bar(xs, ys, width, label=f"{label}, {wlabel}", hatch=hatch,
                       color=("#3b6fb6", "#9cbbe3")[j], edgecolor="k", linewidth=0.4)
        ax.set_xticks(range(len(at20)), [s for s, _ in at20])
        ax.set_yscale("log")
        # room above the bars for the legend (the bars end below 70 % of the height)
        lo, hi = ax.get_ylim()
        ax.set_ylim(lo, lo * (hi / lo) ** (1 / 0.7))
        ax.set_xlabel("controller structure")
        ax.set_ylabel("tip error, µm")
        ax.set_title("structures at wn = 20 rad/s")
        ax.legend(fontsize=8, ncol=2, loc="upper center")
        ax.grid(True, axis="y", which="both", alpha=0.3)

        sweep = sorted(((c.setting("controller.wn"), c) for c in cases.values()
                        if _structure(c) == "pid_g"),
                       key=lambda x: x[0])
        wns = [w for w, _ in sweep]
        ax = axes[0, 1]
        for win, wlabel, ls in WINDOWS:
            ax.plot(wns, [window_value(c, win, "settled_mean_um") for _, c in sweep],
                    "o" + ls, color="#3b6fb6", label=f"settled mean, {wlabel}")
            ax.plot(wns, [window_value(c, win, "marking_max_um") for _, c in sweep],
                    "s" + ls, color="#c0392b", label=f"worst marking, {wlabel}")
        ax.axhline(300, color="0.5", lw=0.8, ls=":")
        ax.text(wns[0] if wns else 10, 300, " 0.3 mm line", fontsize=8, va="bottom",
                color="0.35")
        ax.axhline(20, color="0.5", lw=0.8, ls="-.")
        ax.text(wns[0] if wns else 10, 20, " 20 µm goal", fontsize=8, va="bottom",
                color="0.35")
        _tolerance(ax, cases)
        _log_log_wn(ax, "tip error, µm", "pid_g across the bandwidth: tip error")

        ax = axes[1, 0]
        for win, wlabel, ls in WINDOWS:
            ax.plot(wns, [window_value(c, win, "peak_torque_nm") for _, c in sweep],
                    "o" + ls, color="#6a4c93", label=f"peak torque, {wlabel}")
        _verdicts(ax, sweep, lambda c: window_value(c, "whole", "peak_torque_nm"))
        _log_log_wn(ax, "peak joint torque, N m", "pid_g across the bandwidth: peak torque")

        ax = axes[1, 1]
        for win, wlabel, ls in WINDOWS:
            ax.plot(wns, [window_value(c, win, "travel_mean_um") / 1000.0 for _, c in sweep],
                    "^" + ls, color="#e08a1e", label=f"travel mean, {wlabel}")
        _verdicts(ax, sweep, lambda c: window_value(c, "whole", "travel_mean_um") / 1000.0)
        _log_log_wn(ax, "mean tip error in travel, mm",
                    "pid_g across the bandwidth: travel error")
        finish_figure(fig, path, "Control", title, "MuJoCo, 1 kHz loop")

    def summary(self, cases: Cases) -> JsonDict:
        """The best structure at wn 20 and the best pid_g bandwidth (lowest worst marking
        error over the whole drawing among the runs that stayed ok)."""
        at20 = {k: c for k, c in cases.items() if c.setting("controller.wn") == 20}
        sweep = {k: c for k, c in cases.items() if _structure(c) == "pid_g" and _ok(c)}
        best_pid_g = min(sweep.values(), key=_worst) if sweep else None
        return {
            "cases": len(cases),
            "best_at_wn20": min(at20, key=lambda k: _worst(at20[k])) if at20 else None,
            "best_pid_g_wn": best_pid_g.setting("controller.wn") if best_pid_g is not None
                             else None,
            "not_ok": sorted(k for k, c in cases.items() if not _ok(c)),
        }


#: the control study
STUDY = ControlStudy()
