"""One figure per closed-loop study, drawn from the cases' metrics
(:func:`tattotronix.studies.sweeps.load_cases`).

* :func:`control_figure`: the four structures at wn 20, and pid_g across the bandwidths,
  over the whole drawing and its busiest window.
* :func:`approach_figure`: the worst entry error, the settled mean and the cycle time
  against the approach length.
* :func:`resample_figure`: the chord error and the tracking against the point step.
* :func:`rate_figure`: each rate x bandwidth run's verdict against the computed
  sampled-loop boundary.
"""

from __future__ import annotations

import textwrap
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from tattotronix.studies.kinematics import _pyplot

__all__ = ["approach_figure", "control_figure", "rate_figure", "resample_figure",
           "study_figures", "study_summary"]

Cases = Mapping[str, Mapping[str, Any]]
_WINDOWS = (("whole", "whole drawing", "-"), ("busiest", "busiest window", "--"))
_VERDICT_COLOUR = {"ok": "#2a9d55", "saturated": "#e08a1e", "diverged": "#c0392b"}


def _v(case: Mapping[str, Any], window: str, key: str) -> float:
    w = case.get(window) or {}
    val = w.get(key)
    return float("nan") if val is None else float(val)


def control_figure(cases: Cases, path: Path, title: str = "") -> None:
    """Structures at wn 20 (bars) and the pid_g bandwidth sweep (lines); saved as a PNG."""
    plt = _pyplot()
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.8))
    structs = ["pid", "pid_g", "pid_g_v", "computed_torque"]
    at20 = [(s, cases[f"{s}-wn20"]) for s in structs if f"{s}-wn20" in cases]
    ax = axes[0]
    width = 0.2
    for i, (key, label, hatch) in enumerate((("settled_mean_um", "settled mean", ""),
                                              ("marking_max_um", "worst marking", "//"))):
        for j, (win, wlabel, _) in enumerate(_WINDOWS):
            xs = [k + (2 * i + j - 1.5) * width for k in range(len(at20))]
            ys = [_v(c, win, key) for _, c in at20]
            ax.bar(xs, ys, width, label=f"{label}, {wlabel}", hatch=hatch,
                   color=("#3b6fb6", "#9cbbe3")[j], edgecolor="k", linewidth=0.4)
    ax.set_xticks(range(len(at20)), [s for s, _ in at20], rotation=15)
    ax.set_yscale("log")
    ax.set_ylabel("tip error, um")
    ax.set_title("structures at wn = 20 rad/s")
    ax.legend(fontsize=7)
    ax.grid(True, axis="y", which="both", alpha=0.3)

    sweep = sorted(((float(c["settings"]["controller.wn"]), c) for n, c in cases.items()
                    if c["settings"]["controller.structure"] == "pid_g"), key=lambda x: x[0])
    wns = [w for w, _ in sweep]
    ax = axes[1]
    for win, wlabel, ls in _WINDOWS:
        ax.plot(wns, [_v(c, win, "settled_mean_um") for _, c in sweep], "o" + ls,
                color="#3b6fb6", label=f"settled mean, {wlabel}")
        ax.plot(wns, [_v(c, win, "marking_max_um") for _, c in sweep], "s" + ls,
                color="#c0392b", label=f"worst marking, {wlabel}")
    ax.axhline(300, color="0.5", lw=0.8, ls=":")
    ax.text(wns[0] if wns else 10, 300, " 0.3 mm line", fontsize=7, va="bottom", color="0.4")
    ax.axhline(20, color="0.5", lw=0.8, ls="-.")
    ax.text(wns[0] if wns else 10, 20, " 20 um goal", fontsize=7, va="bottom", color="0.4")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("wn, rad/s")
    ax.set_ylabel("tip error, um")
    ax.set_title("pid_g across the bandwidth")
    ax.legend(fontsize=7)
    ax.grid(True, which="both", alpha=0.3)

    ax = axes[2]
    for win, wlabel, ls in _WINDOWS:
        ax.plot(wns, [_v(c, win, "peak_torque_nm") for _, c in sweep], "o" + ls,
                color="#6a4c93", label=f"peak torque, {wlabel}")
        ax.plot(wns, [_v(c, win, "travel_mean_um") / 1000.0 for _, c in sweep], "^" + ls,
                color="#e08a1e", label=f"travel mean (mm), {wlabel}")
    for w, c in sweep:
        verdict = (c.get("whole") or {}).get("verdict", "?")
        if verdict != "ok":
            ax.annotate(f"{verdict} ", (w, _v(c, "whole", "peak_torque_nm")), fontsize=7,
                        color=_VERDICT_COLOUR.get(verdict, "k"), ha="right", va="center")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("wn, rad/s")
    ax.set_ylabel("N m  /  mm")
    ax.set_title("pid_g: peak torque and travel error")
    ax.legend(fontsize=7)
    ax.grid(True, which="both", alpha=0.3)
    fig.suptitle(f"Control study{': ' + title if title else ''} (section 5.6; MuJoCo, "
                 "1 kHz loop)")
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    plt.close(fig)


def _sorted_by(cases: Cases, key: str) -> list[tuple[float, Mapping[str, Any]]]:
    return sorted(((float(c["settings"][key]), c) for c in cases.values()),
                  key=lambda x: x[0])


def _log_axes_with_twin(ax: Any, xlabel: str, ylabel: str, x: list[float],
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


def approach_figure(cases: Cases, path: Path, title: str = "") -> None:
    """Worst entry error, worst marking and settled mean (um), and the cycle time (s),
    against the approach length; saved as a PNG."""
    plt = _pyplot()
    rows = _sorted_by(cases, "toolpath.approach_mm")
    a = [x for x, _ in rows]
    fig, ax = plt.subplots(figsize=(8, 4.8))
    ax.plot(a, [_v(c, "whole", "entry_max_um") for _, c in rows], "o-", color="#c0392b",
            label="worst entry (within 4/wn of an entry)")
    ax.plot(a, [_v(c, "whole", "marking_max_um") for _, c in rows], "s--", color="#e08a1e",
            label="worst marking")
    ax.plot(a, [_v(c, "whole", "settled_mean_um") for _, c in rows], "^-", color="#3b6fb6",
            label="settled mean")
    _log_axes_with_twin(ax, "approach length (last stretch of each plunge at the marking "
                        "feed), mm", "tip error, um", a,
                        [float(c["drawing"]["duration_s"]) for _, c in rows], "cycle time",
                        "cycle time, s", "upper center")
    ctl = next(iter(cases.values()))["controller"] if cases else {}
    fig.suptitle(f"Approach study{': ' + title if title else ''} (section 5.7; whole "
                 f"drawing, {ctl.get('structure', '?')} at wn {ctl.get('wn', '?')} rad/s)")
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    plt.close(fig)


def resample_figure(cases: Cases, path: Path, title: str = "") -> None:
    """Chord error and tracking (um), and the point count, against the point step;
    saved as a PNG."""
    plt = _pyplot()
    rows = _sorted_by(cases, "toolpath.step_mm")
    h = [x for x, _ in rows]
    fig, ax = plt.subplots(figsize=(8, 4.8))
    ax.plot(h, [float(c["chord"]["chord_error_um"]) for _, c in rows], "o-",
            color="#2a9d55", label="chord error (outlines)")
    ax.plot(h, [_v(c, "whole", "marking_max_um") for _, c in rows], "s--", color="#c0392b",
            label="worst marking")
    ax.plot(h, [_v(c, "whole", "settled_mean_um") for _, c in rows], "^-", color="#3b6fb6",
            label="settled mean")
    if rows:
        res_um = float(rows[0][1]["chord"]["mask_res_mm"]) * 1000.0
        ax.axhline(res_um, color="0.5", lw=0.8, ls=":")
        ax.text(h[0], res_um, f" mask pixel {res_um:g} um", fontsize=7, va="bottom")
    _log_axes_with_twin(ax, "point step, mm", "um", h,
                        [float(c["drawing"]["points"]) for _, c in rows],
                        "trajectory points", "points", "center right")
    fig.suptitle(f"Resample study{': ' + title if title else ''} (section 2.11; whole "
                 "drawing)")
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    plt.close(fig)


def rate_figure(cases: Cases, path: Path, title: str = "") -> None:
    """The rate x bandwidth grid coloured by verdict, and each run's wn T against the
    computed boundary; saved as a PNG."""
    plt = _pyplot()
    rates = sorted({float(c["settings"]["controller.rate_hz"]) for c in cases.values()})
    wns = sorted({float(c["settings"]["controller.wn"]) for c in cases.values()})
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(14, 5),
                                 gridspec_kw={"width_ratios": [1.1, 1]})
    for c in cases.values():
        i = rates.index(float(c["settings"]["controller.rate_hz"]))
        j = wns.index(float(c["settings"]["controller.wn"]))
        chk = c["verdict_check"]
        verdict = chk["verdict"]
        ax.add_patch(plt.Rectangle((j - 0.5, i - 0.5), 1, 1,
                                   color=_VERDICT_COLOUR.get(verdict, "0.7"), alpha=0.75))
        w = c.get("whole") or {}
        if verdict == "ok":
            body = (f"settled {w.get('settled_mean_um', float('nan')):.2f} um\n"
                    f"worst {w.get('marking_max_um', float('nan')):.1f} um\n"
                    f"peak {w.get('peak_torque_nm', float('nan')):.3f} N m")
        else:
            body = textwrap.fill(str(w.get("reason", "")).split(" (")[0], 30)
        ax.text(j, i, f"{verdict}  (wn T {chk['wnT']:.2f})\n{body}", ha="center",
                va="center", fontsize=7)
    ax.set_xlim(-0.5, len(wns) - 0.5)
    ax.set_ylim(-0.5, len(rates) - 0.5)
    ax.set_xticks(range(len(wns)), [f"{w:g}" for w in wns])
    ax.set_yticks(range(len(rates)), [f"{r:g}" for r in rates])
    ax.set_xlabel("wn, rad/s")
    ax.set_ylabel("loop rate, Hz")
    ax.set_title("whole drawing, plant at 4 kHz")

    for c in cases.values():
        chk = c["verdict_check"]
        r = float(c["settings"]["controller.rate_hz"])
        bx.scatter(chk["wnT"], r, s=80, color=_VERDICT_COLOUR.get(chk["verdict"], "0.5"),
                   edgecolor="k", zorder=3)
        bx.plot([chk["boundary_numeric_wnT"]] * 2, [r * 0.85, r * 1.15], color="k", lw=2)
    if cases:
        b = next(iter(cases.values()))["verdict_check"]["boundary_wnT"]
        bx.axvline(b, color="0.3", ls="--", lw=1)
        bx.text(b, rates[0] * 0.72, f" exact hold: 2/(3 lambda_max) = {b:.3f}", fontsize=8)
    for v, col in _VERDICT_COLOUR.items():
        bx.scatter([], [], color=col, edgecolor="k", label=v)
    bx.plot([], [], color="k", lw=2, label="boundary with the plant's Euler sub-steps")
    from matplotlib.ticker import NullFormatter

    bx.set_yscale("log")
    bx.set_xscale("log")
    bx.set_ylim(rates[0] * 0.6, rates[-1] * 1.4) if rates else None
    bx.set_yticks(rates, [f"{r:g}" for r in rates])
    bx.yaxis.set_minor_formatter(NullFormatter())
    ticks = sorted({round(float(c["verdict_check"]["wnT"]), 2) for c in cases.values()})
    bx.set_xticks(ticks, [f"{t:g}" for t in ticks])
    bx.xaxis.set_minor_formatter(NullFormatter())
    bx.set_xlabel("wn T")
    bx.set_ylabel("loop rate, Hz")
    bx.set_title("verdict against the computed sampled-loop boundary")
    bx.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    bx.grid(True, which="both", alpha=0.3)
    fig.suptitle(f"Rate study{': ' + title if title else ''} (section 5.8; pid_g_v)")
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    plt.close(fig)


def study_figures(data: Path, name: str, folder: Path,
                  tmp: Any = None) -> dict[str, Path]:
    """Draw every closed-loop study's figure that has cases on ``name``.

    Args:
        data: the data folder.
        name: the artwork.
        folder: where the PNGs go (``<study>.png``).
        tmp: maps a target path to the path to write (``Outputs.tmp_path``); default:
            write the target itself.

    Returns:
        study -> the target path written.
    """
    from tattotronix.studies.sweeps import load_cases

    draw = {"control": control_figure, "approach": approach_figure,
            "resample": resample_figure, "rate": rate_figure}
    written: dict[str, Path] = {}
    for study, fn in draw.items():
        cases = load_cases(data, study, name)
        if not cases:
            continue
        target = folder / f"{study}.png"
        fn(cases, tmp(target) if tmp is not None else target, name)
        written[study] = target
    return written


def study_summary(data: Path, name: str) -> dict[str, Any]:
    """What each closed-loop study concludes, from its cases (JSON-ready).

    * control: the best structure at wn 20 and the best pid_g bandwidth (lowest worst
      marking error over the whole drawing among the runs that stayed ok);
    * approach: the shortest approach whose worst entry error is within 10 % of the best;
    * resample: the chord error and tracking of each step;
    * rate: how many verdicts agree with the computed boundary.
    """
    from tattotronix.studies.sweeps import load_cases

    out: dict[str, Any] = {}

    def ok(c: Mapping[str, Any]) -> bool:
        return (c.get("whole") or {}).get("verdict") == "ok"

    def worst(c: Mapping[str, Any]) -> float:
        return _v(c, "whole", "marking_max_um")

    control = load_cases(data, "control", name)
    if control:
        at20 = {k: c for k, c in control.items() if float(c["settings"]["controller.wn"]) == 20}
        sweep = {k: c for k, c in control.items()
                 if c["settings"]["controller.structure"] == "pid_g" and ok(c)}
        out["control"] = {
            "cases": len(control),
            "best_at_wn20": min(at20, key=lambda k: worst(at20[k])) if at20 else None,
            "best_pid_g_wn": float(sweep[min(sweep, key=lambda k: worst(sweep[k]))]
                                   ["settings"]["controller.wn"]) if sweep else None,
            "not_ok": sorted(k for k, c in control.items() if not ok(c)),
        }
    approach = load_cases(data, "approach", name)
    if approach:
        rows = _sorted_by(approach, "toolpath.approach_mm")
        best = min(_v(c, "whole", "entry_max_um") for _, c in rows)
        enough = next(a for a, c in rows if _v(c, "whole", "entry_max_um") <= 1.1 * best)
        out["approach"] = {"cases": len(approach), "best_entry_max_um": best,
                           "shortest_within_10pct_mm": enough}
    resample = load_cases(data, "resample", name)
    if resample:
        out["resample"] = {
            f"{step:g}mm": {"chord_error_um": float(c["chord"]["chord_error_um"]),
                            "marking_max_um": _v(c, "whole", "marking_max_um"),
                            "points": int(c["drawing"]["points"])}
            for step, c in _sorted_by(resample, "toolpath.step_mm")}
    rate = load_cases(data, "rate", name)
    if rate:
        checks = [c["verdict_check"] for c in rate.values()]
        out["rate"] = {"cases": len(rate), "agree": sum(bool(k["agrees"]) for k in checks),
                       "ok": sum(k["verdict"] == "ok" for k in checks),
                       "boundary_wnT": checks[0]["boundary_wnT"]}
    return out
