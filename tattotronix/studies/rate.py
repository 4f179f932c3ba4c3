"""The rate study (docs/control.md, "The rate study: the loop rate is the ceiling"; the
original's: docs/original.md, "5.8 The rate study"): loop rate x bandwidth, the plant at
4 kHz.

Cases: ``study.rate_hz`` x ``study.rate_wn``; a case sweeps ``controller.rate_hz`` and
``controller.wn`` with the plant at ``study.rate_plant_dt_s``, is named ``500hz-wn80``,
runs over the whole drawing and its busiest window, and sets each run's stability beside the
computed sampled-loop boundary (:func:`rate_verdict_check`), with its verdict (which also
judges accuracy: a stable loop can still miss the drawing's tolerance). Stage ``rate``
(``stages/rate.py``); the machinery is :class:`tattotronix.studies.base.ClosedLoopStudy`.
"""

from __future__ import annotations

import textwrap
from collections.abc import Mapping
from pathlib import Path

from tattotronix.config.schema import Config, StudyConfig
from tattotronix.control.drawing import ClosedLoop
from tattotronix.control.verdict import length_text
from tattotronix.errors import TattotronixError
from tattotronix.io.jsontypes import JsonDict, JsonValue
from tattotronix.kinematics import Chain
from tattotronix.plotting import pyplot
from tattotronix.studies.base import (
    VERDICT_COLOUR,
    Cases,
    ClosedLoopStudy,
    finish_figure,
    int_label,
)

__all__ = ["STUDY", "RateStudy", "rate_verdict_check"]


def rate_verdict_check(loop: ClosedLoop) -> JsonDict:
    """The run's stability beside the computed sampled-loop boundary (docs/original.md,
    "5.4 Loop facts" and "5.8 The rate study").

    ``boundary_wnT`` is 2/(3 lambda_max) (exact hold), ``boundary_numeric_wnT`` the same
    loop with the plant's Euler sub-steps; ``predicted`` is ``ok`` below the latter.
    ``simulated`` is what the run showed, in the same terms: ``ok`` where the loop stayed
    bounded and under its torque limit, ``fail`` where it diverged or saturated (a
    saturated loop is no longer the linear loop the boundary is computed for, so it counts
    on the failing side, as the original's did); ``agrees`` compares the two. Accuracy
    plays no part: the case's ``verdict`` (:meth:`RateStudy.case_metrics`) adds it.
    """
    a = loop.analysis
    if a is None:
        raise TattotronixError(f"the rate study needs our controller's loop: backend="
                               f"{loop.backend} closes its own")
    predicted = "ok" if a["wnT"] < a["sampled_boundary_numeric_wnT"] else "fail"
    # the loop's own verdict: ok is bounded and unsaturated, whatever the accuracy
    simulated = "ok" if loop.run.verdict == "ok" else "fail"
    return {"wnT": a["wnT"], "boundary_wnT": a["sampled_boundary_wnT"],
            "boundary_numeric_wnT": a["sampled_boundary_numeric_wnT"],
            "lambda_max": a["modal_gain"][0], "substeps": loop.run.substeps,
            "predicted": predicted, "simulated": simulated, "agrees": simulated == predicted}


class RateStudy(ClosedLoopStudy):
    """Loop rate x bandwidth: each verdict against the computed boundary."""

    name = "rate"
    keys = ("controller.rate_hz", "controller.wn")
    windows = (None, "busiest")

    def cases(self, study: StudyConfig) -> dict[str, list[str]]:
        return {f"{r}hz-wn{w}": [f"controller.rate_hz={r}", f"controller.wn={w}"]
                for r in study.rate_hz for w in study.rate_wn}

    def case_name(self, cfg: Config) -> str:
        return (f"{int_label(float(cfg.controller.rate_hz))}hz-"
                f"wn{int_label(float(cfg.controller.wn))}")

    def plant_dt_s(self, cfg: Config) -> float | None:
        return float(cfg.study.rate_plant_dt_s)

    def cost(self, cfg: Config) -> float:
        # the plant's steps are the same in every case; the controller ticks in Python
        return float(cfg.controller.rate_hz)

    def window_metrics(self, cfg: Config, loop: ClosedLoop, chain: Chain) -> JsonDict:
        return {"boundary": rate_verdict_check(loop)}

    def case_metrics(self, cfg: Config, name: str,
                     windows: Mapping[str, Mapping[str, JsonValue]]) -> JsonDict:
        """``verdict_check``: the first window's (the whole drawing) loop against the
        boundary (:func:`rate_verdict_check`), and the run's verdict."""
        first = next(iter(windows.values()))
        check = first["boundary"]
        assert isinstance(check, Mapping)
        return {"verdict_check": {**check, "verdict": first["verdict"]}}

    def figure(self, cases: Cases, path: Path, title: str = "") -> None:
        """The rate x bandwidth grid coloured by verdict, and each run's wn T against the
        computed boundary."""
        plt = pyplot()
        rates = sorted({c.setting("controller.rate_hz") for c in cases.values()})
        wns = sorted({c.setting("controller.wn") for c in cases.values()})
        fig, (ax, bx) = plt.subplots(1, 2, figsize=(14, 5),
                                     gridspec_kw={"width_ratios": [1.1, 1]})
        for c in cases.values():
            i = rates.index(c.setting("controller.rate_hz"))
            j = wns.index(c.setting("controller.wn"))
            verdict = c.text("verdict_check", "verdict")
            ax.add_patch(plt.Rectangle((j - 0.5, i - 0.5), 1, 1,
                                       color=VERDICT_COLOUR.get(verdict, "0.7"), alpha=0.75))
            if verdict in ("ok", "out-of-tolerance"):
                body = (f"settled {_length(c.number('whole', 'settled_mean_um'))}\n"
                        f"worst {_length(c.number('whole', 'marking_max_um'))}\n"
                        f"peak {c.number('whole', 'peak_torque_nm'):.3f} N m")
            else:
                body = textwrap.fill(c.text("whole", "reason", "").split(" (")[0], 30)
            ax.text(j, i, f"{verdict}  (wn T {c.number('verdict_check', 'wnT'):.2f})\n{body}",
                    ha="center", va="center", fontsize=7)
        ax.set_xlim(-0.5, len(wns) - 0.5)
        ax.set_ylim(-0.5, len(rates) - 0.5)
        ax.set_xticks(range(len(wns)), [f"{w:g}" for w in wns])
        ax.set_yticks(range(len(rates)), [f"{r:g}" for r in rates])
        ax.set_xlabel("wn, rad/s")
        ax.set_ylabel("loop rate, Hz")
        ax.set_title("whole drawing, plant at 4 kHz")

        for c in cases.values():
            r = c.setting("controller.rate_hz")
            bx.scatter(c.number("verdict_check", "wnT"), r, s=80,
                       color=VERDICT_COLOUR.get(c.text("verdict_check", "verdict"), "0.5"),
                       edgecolor="k", zorder=3)
            bx.plot([c.number("verdict_check", "boundary_numeric_wnT")] * 2,
                    [r * 0.85, r * 1.15], color="k", lw=2)
        if cases:
            b = next(iter(cases.values())).number("verdict_check", "boundary_wnT")
            bx.axvline(b, color="0.3", ls="--", lw=1)
            bx.text(b, rates[0] * 0.72, f" exact hold: 2 / (3 $\\lambda_{{max}}$) = {b:.3f}",
                    fontsize=8)
        for v, col in VERDICT_COLOUR.items():
            bx.scatter([], [], color=col, edgecolor="k", label=v)
        bx.plot([], [], color="k", lw=2, label="boundary with the plant's Euler sub-steps")
        from matplotlib.ticker import NullFormatter

        bx.set_yscale("log")
        bx.set_xscale("log")
        bx.set_ylim(rates[0] * 0.6, rates[-1] * 1.4) if rates else None
        bx.set_yticks(rates, [f"{r:g}" for r in rates])
        bx.yaxis.set_minor_formatter(NullFormatter())
        ticks = sorted({round(c.number("verdict_check", "wnT"), 2) for c in cases.values()})
        # every case's wn T, slanted: neighbours on the log axis are close
        bx.set_xticks(ticks, [f"{t:g}" for t in ticks], rotation=45, ha="right",
                      rotation_mode="anchor")
        bx.xaxis.set_minor_formatter(NullFormatter())
        bx.set_xlabel("wn T")
        bx.set_ylabel("loop rate, Hz")
        bx.set_title("verdict against the computed sampled-loop boundary")
        bx.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
        bx.grid(True, which="both", alpha=0.3)
        finish_figure(fig, path, "Rate", title, "pid_g_v")

    def summary(self, cases: Cases) -> JsonDict:
        """How many simulated loops agree with the computed boundary, how many held
        (bounded and unsaturated: ``simulated_ok``), and how many runs are ok (held, and
        within the drawing's tolerance)."""
        checks = [c.section("verdict_check") for c in cases.values()]
        return {"cases": len(cases), "agree": sum(bool(k["agrees"]) for k in checks),
                "simulated_ok": sum(k.get("simulated") == "ok" for k in checks),
                "ok": sum(k["verdict"] == "ok" for k in checks),
                "boundary_wnT": checks[0]["boundary_wnT"]}


def _length(um: float) -> str:
    return length_text(um if um == um else None, "µm")  # NaN: a metric the run lacks


#: the rate study
STUDY = RateStudy()
