"""The servo study (docs/servos.md, "The servo study"): what the real arm will draw, on
which servos, with which corrections.

Every case plays the whole drawing on the servo plant (``backend=servo``), as ``deploy``
would compile it. The cases (``study.servo.cases``) sweep:

* the servos: as mounted (MG996R, the wrist an SG90), SG90 on every joint, or serial bus
  servos (STS3215) on every joint (``servo.type``);
* the corrections (``hardware.compensate``: the measured pulse-map fit, backlash, dead
  band, sag, lead) one at a time and all together;
* the speed, for the cycle time it costs;
* each imperfection of the as-mounted servos alone (``only``), which splits the error by
  its source: quantisation, dead band, backlash, the pulse map's bend, lag; and each alone
  with every correction (``built-only-<part>-all``): what the corrections leave of it.

Each case reports, over the whole drawing: the worst ink deviation (the symmetric
Hausdorff distance of the simulated ink from the planned ink, mm), the mean and worst tip
deviation while marking (mm), the line width (inked area over the planned marking length,
mm; the planned ink's, the same way, is the reference: overlapping strokes make both
narrower than the needle), the cycle time, and the verdict against the drawing's tolerance
(:mod:`tattotronix.control.verdict`; a run that saturated or diverged has no ink scores:
null, with ``ink_reason``). Stage ``servo`` (``stages/servo_study.py``);
the machinery is :class:`tattotronix.studies.base.ClosedLoopStudy`.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from tattotronix.config.schema import Config, StudyConfig
from tattotronix.control.drawing import ClosedLoop, score_ink
from tattotronix.io.jsontypes import JsonDict
from tattotronix.kinematics import Chain
from tattotronix.plotting import pyplot
from tattotronix.studies.base import (
    VERDICT_COLOUR,
    Cases,
    ClosedLoopStudy,
    StudyCase,
    finish_figure,
)

if TYPE_CHECKING:
    from matplotlib.axes import Axes

__all__ = ["COMPENSATIONS", "IMPERFECTIONS", "STUDY", "ServoStudy"]

#: the servo plant's imperfections (``servo.<name>``), in the order the figure shows them
IMPERFECTIONS = ("quantise", "deadband", "backlash", "nonlinearity", "lag")
#: the corrections (``hardware.compensate.<name>``)
COMPENSATIONS = ("fit", "backlash", "deadband", "sag", "lead")
_BASE = "built"  # the as-mounted servos' case name


class ServoStudy(ClosedLoopStudy):
    """Servos and corrections against the ink deviation, the line width and the cycle."""

    name = "servo"
    keys = ("servo.type", *(f"hardware.compensate.{c}" for c in COMPENSATIONS), "speed",
            *(f"servo.{k}" for k in IMPERFECTIONS))

    def cases(self, study: StudyConfig) -> dict[str, list[str]]:
        out: dict[str, list[str]] = {}
        for name, c in study.servo.cases.items():
            only = None if c.only is None else str(c.only)
            out[str(name)] = [
                "backend=servo",
                f"servo.type={'null' if c.type is None else c.type}",
                *(f"hardware.compensate.{k}={str(bool(getattr(c, k))).lower()}"
                  for k in COMPENSATIONS),
                f"speed={float(c.speed)}",
                *(f"servo.{k}={str(only is None or k == only).lower()}"
                  for k in IMPERFECTIONS)]
        return out

    def case_name(self, cfg: Config) -> str:
        kind = _BASE if cfg.servo.type is None else str(cfg.servo.type).lower()
        parts = [kind]
        on = [k for k in IMPERFECTIONS if getattr(cfg.servo, k)]
        if len(on) == 1:
            parts.append(f"only-{on[0]}")
        elif len(on) < len(IMPERFECTIONS):
            parts.append("ideal" if not on else "without-" + "-".join(
                k for k in IMPERFECTIONS if k not in on))
        comp = [k for k in COMPENSATIONS if getattr(cfg.hardware.compensate, k)]
        if len(comp) == len(COMPENSATIONS):
            parts.append("all")
        elif comp:
            parts.append("-".join(comp))
        if float(cfg.speed) != 1.0:  # no dot: case names are config keys
            parts.append(f"speed{round(100 * float(cfg.speed))}pct")
        return "-".join(parts)

    def cost(self, cfg: Config) -> float:
        return 1.0 / float(cfg.speed)

    def window_metrics(self, cfg: Config, loop: ClosedLoop, chain: Chain) -> JsonDict:
        """The ink: its worst deviation from the plan's, the line width, the cycle time (the
        ink's scores null, with ``ink_reason``, where the run saturated or diverged)."""
        run = loop.run
        tip, _ = chain.fk(run.q)
        tip_ref, _ = chain.fk(run.ref.q[:len(run.q)])
        _, sim_ink, plan_ink, ink = score_ink(tip, tip_ref, cfg.toolpath.panel_origin,
                                               float(cfg.draw.ink_res_mm),
                                               float(cfg.toolpath.needle_width_mm))
        unscored = loop.judge(loop.errors(chain, float(cfg.draw.settle_periods))).unscored_ink()
        if unscored:
            ink = ink.unscored(unscored)
        res = float(cfg.draw.ink_res_mm)
        origin = np.asarray(cfg.toolpath.panel_origin, dtype=np.float64)
        below = (tip_ref[:, 2] - origin[2]) < 0.0
        seg = np.linalg.norm(np.diff(tip_ref[:, :2], axis=0), axis=1) * 1e3
        length = float(seg[below[1:] & below[:-1]].sum())
        px = res * res / length if length > 0 else math.nan
        return {"ink_max_dev_mm": ink.max_dev_mm, "ink_iou": ink.iou, "ink_reason": ink.reason,
                "line_width_mm": None if unscored else float(sim_ink.sum()) * px,
                "plan_line_width_mm": float(plan_ink.sum()) * px,
                "marking_length_mm": length,
                "cycle_s": float(loop.drawing.t[-1])}

    def figure(self, cases: Cases, path: Path, title: str = "") -> None:
        """Left: each case's worst ink deviation and mean marking deviation (mm), labelled
        with its cycle time and line width (and its verdict, where the run saturated or
        diverged and its ink has no score), against the drawing's tolerance. Right: each
        imperfection alone, on the as-mounted servos."""
        plt = pyplot()
        table = [(name, c) for name, c in cases.items() if "-only-" not in name]
        fig, (ax, src) = plt.subplots(1, 2, figsize=(13, 0.9 + 0.42 * max(6, len(table))),
                                      gridspec_kw={"width_ratios": [1.3, 1.0]})
        y = np.arange(len(table))
        worst = [c.number("whole", "ink_max_dev_mm") for _, c in table]
        mean = [c.number("whole", "marking_mean_um") / 1e3 for _, c in table]
        ax.barh(y - 0.2, worst, 0.4, color="#c0392b", label="worst ink deviation")
        ax.barh(y + 0.2, mean, 0.4, color="#3b6fb6", label="mean marking deviation")
        unscored = False
        for k, (_, c) in enumerate(table):
            verdict = c.text("whole", "verdict")
            cycle = f"{c.number('whole', 'cycle_s'):.0f} s"
            if verdict in ("ok", "out-of-tolerance"):  # the ink has scores
                text, colour = f"{cycle}, line {c.number('whole', 'line_width_mm'):.2f} mm", \
                    "#444444"
            else:
                text, colour = f"{verdict}: ink not scored; {cycle}", VERDICT_COLOUR.get(
                    verdict, "k")
                unscored = True
            ax.annotate(text, (_largest(worst[k], mean[k]), k), textcoords="offset points",
                        xytext=(4, -3), fontsize=7.5, color=colour)
        _tolerance(ax, table)
        ax.set_yticks(y, [name for name, _ in table])
        ax.invert_yaxis()
        ax.set_xlim(0, (1.55 if unscored else 1.3) * _largest(*worst, *mean, 1e-3))
        ax.set_xlabel("mm over the whole drawing (labels: cycle time, line width)")
        ax.legend(loc="lower right", fontsize=8)
        ax.grid(True, axis="x", alpha=0.3)
        only, fixed = _alone(cases)
        names = [k for k in IMPERFECTIONS if k in only]
        y = np.arange(len(names))
        worst = [only[k].number("whole", "ink_max_dev_mm") for k in names]
        mean = [only[k].number("whole", "marking_mean_um") / 1e3 for k in names]
        src.barh(y - 0.27, worst, 0.27, color="#c0392b", label="worst ink deviation")
        src.barh(y, mean, 0.27, color="#3b6fb6", label="mean marking deviation")
        left = [fixed[k].number("whole", "marking_mean_um") / 1e3 if k in fixed else math.nan
                for k in names]
        src.barh(y + 0.27, left, 0.27, color="#2f9e44",
                 label="mean, with every correction")
        for k, v in enumerate(left):
            if math.isfinite(v):
                src.annotate(f"{v:.3f} mm" if v < 0.01 else f"{v:.2f} mm", (v, k + 0.27),
                             textcoords="offset points", xytext=(4, -3), fontsize=7.5,
                             color="#2f9e44")
        _tolerance(src, list(only.items()))
        src.set_yticks(y, [_SOURCE_LABEL[k] for k in names])
        src.invert_yaxis()
        src.set_xlabel("mm, the as-mounted servos with this imperfection alone")
        src.legend(loc="lower right", fontsize=8)
        src.grid(True, axis="x", alpha=0.3)
        finish_figure(fig, path, "Servo", title,
                      "whole drawing on the servo plant; docs/servos.md")

    def summary(self, cases: Cases) -> JsonDict:
        """Per case the worst and mean deviation, line width and cycle time (mm, s), and per
        correction what it buys on the as-mounted servos (mm, the mean and the worst)."""
        table = {name: _row(c) for name, c in cases.items()}
        base = table.get(_BASE)
        gains: dict[str, JsonDict] = {}
        if base is not None:
            for name, row in table.items():
                rest = name[len(_BASE) + 1:] if name.startswith(_BASE + "-") else ""
                if rest and "only" not in rest and "speed" not in rest:
                    gains[rest] = {
                        "mean_mm": _diff(base["mean_mm"], row["mean_mm"]),
                        "worst_mm": _diff(base["worst_mm"], row["worst_mm"])}
        left = {k: {"mean_mm": _row(c)["mean_mm"], "worst_mm": _row(c)["worst_mm"]}
                for k, c in _alone(cases)[1].items()}
        return {"cases": table, "compensation_gain_mm": gains,
                "left_by_imperfection_mm": left}


def _alone(cases: Cases) -> tuple[Cases, Cases]:
    """The cases of each imperfection alone on the as-mounted servos (``built-only-<k>``)
    and of each alone with every correction (``built-only-<k>-all``), by imperfection."""
    alone = {k: cases[f"{_BASE}-only-{k}"] for k in IMPERFECTIONS
             if f"{_BASE}-only-{k}" in cases}
    fixed = {k: cases[f"{_BASE}-only-{k}-all"] for k in IMPERFECTIONS
             if f"{_BASE}-only-{k}-all" in cases}
    return alone, fixed


_SOURCE_LABEL = {"quantise": "quantisation\n(PCA9685 counts)", "deadband": "dead band",
                 "backlash": "backlash", "nonlinearity": "pulse-map bend\n(linear calibration)",
                 "lag": "lag (frame, latency,\nspeed, torque)"}


def _largest(*values: float) -> float:
    """The largest of ``values`` that is a number (0 where none is)."""
    finite = [v for v in values if math.isfinite(v)]
    return max(finite, default=0.0)


def _tolerance(ax: Axes, cases: list[tuple[str, StudyCase]]) -> None:
    """The drawing's marking tolerance, a dotted line (where the cases state it)."""
    tol = {c.number("whole", "tolerance_um") for _, c in cases}
    tol = {t for t in tol if math.isfinite(t)}
    if len(tol) == 1:
        t = tol.pop() / 1e3
        ax.axvline(t, color="k", ls=":", lw=1)
        ax.annotate(f" tolerance {t:g} mm", (t, 1.0), xycoords=("data", "axes fraction"),
                    va="top", fontsize=7.5)


def _colour(name: str) -> str:
    return {"built": "#3b6fb6", "sg90": "#e08a1e", "sts3215": "#2e8b57"}.get(
        name.split("-")[0], "#555555")


def _row(c: StudyCase) -> JsonDict:
    return {"verdict": c.text("whole", "verdict"),
            "worst_mm": _num(c.number("whole", "ink_max_dev_mm")),
            "mean_mm": _num(c.number("whole", "marking_mean_um") / 1e3),
            "marking_max_mm": _num(c.number("whole", "marking_max_um") / 1e3),
            "line_width_mm": _num(c.number("whole", "line_width_mm")),
            "cycle_s": _num(c.number("whole", "cycle_s"))}


def _num(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None


def _diff(a: object, b: object) -> float | None:
    return float(a) - float(b) if isinstance(a, int | float) and isinstance(b, int | float) \
        else None


#: the servo study
STUDY = ServoStudy()
