"""The robustness study (docs/servos.md, "Robustness"): what each servo correction still
buys when the servos are not the catalogue's.

The servo catalogue's figures are partly assumed (docs/servos.md), and the corrections
(``hardware.compensate``) are sized from them. This study draws ``study.robustness.draws``
arms whose every servo differs from its catalogue entry by up to
``study.robustness.spread`` (:func:`~tattotronix.hardware.servo_model.spread_servos`:
uniform, each figure of each joint on its own, from ``study.robustness.seed``) and plays
the study artwork's busiest window (``study.window_s``) on each, on the servo plant, under
each condition of :data:`CONDITIONS`: no correction, each correction alone, and all of
them. The corrections are sized from the catalogue, as a program compiled for the
catalogue's servo is; the pulse-map fit is measured on the drawn servo, as a user measures
their own. Every condition meets the same arms (paired), so what a correction buys is
read arm by arm: the mean marking deviation without it minus with it.

Writes ``data/metrics/robustness/<name>.json``: the settings, the catalogue arm's figures
per condition and, over the drawn arms, the quantiles of the mean and worst marking
deviation and of what each condition buys against none (mm); and the figure
``data/figures/<name>/robustness.png``, drawn from those metrics alone
(:func:`robustness_figure`). Stage ``robustness`` (``stages/robustness.py``).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from scipy.interpolate import CubicHermiteSpline

from tattotronix.app.drawings import resolve_drawing
from tattotronix.app.servos import run_servo_loop
from tattotronix.art.artwork import artwork_name
from tattotronix.config.params import with_overrides
from tattotronix.config.schema import Config
from tattotronix.control.drawing import Drawing, warm_up
from tattotronix.control.reference import resolve_window
from tattotronix.errors import TattotronixError
from tattotronix.hardware.arm import calibration_from_config
from tattotronix.hardware.servo_model import SPREAD_FIELDS, joint_servos, spread_servos
from tattotronix.io.jsontypes import JsonDict, JsonValue
from tattotronix.io.workers import usable_cores, worker_signals
from tattotronix.kinematics import Chain
from tattotronix.plants.servo_plant import ServoSpec
from tattotronix.plotting import pyplot
from tattotronix.robot.description import RobotDescription, build_description
from tattotronix.studies.servo import COMPENSATIONS

__all__ = ["CONDITIONS", "QUANTILES", "crop_drawing", "robustness_figure", "run_robustness"]

log = logging.getLogger("tattotronix.studies")

#: the study's conditions: no correction, each alone, all of them
CONDITIONS = ("none", *COMPENSATIONS, "all")
#: the quantiles stored of every distribution (percent), and what the figure's boxes are
QUANTILES = (5, 25, 50, 75, 95)
#: program before the window and after it: the program's own state (the rate clamp, the
#: dead band's rest, the backlash's look-ahead, the lead) settles before the window starts
_MARGIN_S = 1.0


def crop_drawing(drawing: Drawing, start: float, end: float, frame_hz: float,
                 margin_s: float = _MARGIN_S) -> tuple[Drawing, tuple[float, float]]:
    """The stretch of ``drawing`` around ``[start, end]`` s, as a drawing of its own.

    It starts ``margin_s`` before ``start``, on a servo frame of the whole drawing (so its
    frames fall where the whole program's do), with the point the whole drawing's cubic
    Hermite curve passes there: the same curve on the stretch, which begins at time 0. It
    ends at the first point ``margin_s`` after ``end`` (or the drawing's end).

    Returns:
        The stretch, and ``[start, end]`` in its own time.
    """
    t = drawing.t
    t0 = max(0.0, math.floor((start - margin_s) * frame_hz + 1e-9) / frame_hz)
    first = int(np.searchsorted(t, t0, side="right"))
    last = min(len(t) - 1, int(np.searchsorted(t, end + margin_s, side="left")))
    if first > last:
        raise TattotronixError(f"the stretch {start:.3f}..{end:.3f} s holds no point")
    curve = CubicHermiteSpline(t, drawing.q, drawing.qd, axis=0)
    q0 = curve(t0)[None]
    qd0 = curve(t0, 1)[None]
    part = Drawing(
        name=drawing.name, t=np.concatenate(([0.0], t[first:last + 1] - t0)),
        q=np.concatenate((q0, drawing.q[first:last + 1])),
        qd=np.concatenate((qd0, drawing.qd[first:last + 1])),
        kind=np.concatenate((drawing.kind[first - 1:first], drawing.kind[first:last + 1])),
        origin=drawing.origin, inputs=dict(drawing.inputs), mask=drawing.mask)
    return part, (start - t0, min(end, float(t[last])) - t0)


def _condition_overrides(condition: str) -> list[str]:
    """The overrides of a condition: which corrections are on."""
    on = set(COMPENSATIONS) if condition == "all" else {condition}
    return ["backend=servo", *(f"hardware.compensate.{c}={str(c in on).lower()}"
                               for c in COMPENSATIONS)]


@dataclass(frozen=True)
class _Arms:
    """What every arm's runs share (sent to the workers once, by the fork)."""

    configs: tuple[Config, ...]  # one per condition
    data: Path
    desc: RobotDescription
    drawing: Drawing
    window: tuple[float, float]
    settle_periods: float


_SHARED: _Arms | None = None


def _play_arm(truth: Sequence[ServoSpec] | None) -> NDArray[np.float64]:
    """(conditions, 2) one arm's mean and worst marking deviation, mm, per condition (NaN
    where a run was not scored: it diverged)."""
    assert _SHARED is not None
    s = _SHARED
    chain = Chain.from_description(s.desc)
    out = np.full((len(s.configs), 2), np.nan)
    for i, cfg in enumerate(s.configs):
        start, end = s.window
        loop = run_servo_loop(cfg, s.data, s.desc, s.drawing, window=[start, end - start],
                              truth=truth)
        m = loop.metrics(loop.errors(chain, s.settle_periods))
        for j, key in enumerate(("marking_mean_um", "marking_max_um")):
            value = m.get(key)
            if isinstance(value, int | float):
                out[i, j] = float(value) / 1e3
    return out


def _play_all(arms: Sequence[Sequence[ServoSpec] | None], workers: int
              ) -> list[NDArray[np.float64]]:
    """:func:`_play_arm` on every arm, in a pool of forked workers."""
    if workers <= 1 or len(arms) <= 1:
        done = []
        for k, a in enumerate(arms):
            done.append(_play_arm(a))
            log.info("robustness: arm %d of %d", k + 1, len(arms))
        return done
    import multiprocessing

    warm_up()
    results: list[NDArray[np.float64]] = []
    with multiprocessing.get_context("fork").Pool(workers, worker_signals) as pool:
        for k, r in enumerate(pool.imap(_play_arm, arms, chunksize=1)):
            results.append(r)
            if (k + 1) % 8 == 0 or k + 1 == len(arms):
                log.info("robustness: %d of %d arms", k + 1, len(arms))
    return results


def _quantiles(values: NDArray[np.float64]) -> JsonDict:
    """The stored quantiles of ``values`` (NaN dropped), mm, and the worst."""
    v = values[np.isfinite(values)]
    if not len(v):
        return {"scored": 0}
    q = np.percentile(v, QUANTILES)
    out: JsonDict = {f"p{p}": round(float(x), 4) for p, x in zip(QUANTILES, q, strict=True)}
    out["worst"] = round(float(v.max()), 4)
    out["best"] = round(float(v.min()), 4)
    out["scored"] = int(len(v))
    return out


def run_robustness(cfg: Config, data: Path, workers: int | None = None) -> JsonDict:
    """The study (module docstring) on ``cfg``'s artwork; its metrics.

    Raises:
        TattotronixError: the drawing, the models or a servo the catalogue lacks.
    """
    study = cfg.study.robustness
    desc = build_description(cfg.robot)
    drawing = resolve_drawing(cfg, data, desc)
    calib = calibration_from_config(cfg.hardware, desc.joint_names)
    start, end = resolve_window("busiest", drawing.t, drawing.kind, float(cfg.study.window_s))
    part, window = crop_drawing(drawing, start, end, float(calib.frame_hz))
    catalogue = joint_servos(cfg.robot, desc.joint_names, calib, cfg.servo)
    rng = np.random.default_rng(int(study.seed))
    drawn = [spread_servos(catalogue, study.spread, rng) for _ in range(int(study.draws))]
    global _SHARED
    _SHARED = _Arms(tuple(with_overrides(cfg, _condition_overrides(c)) for c in CONDITIONS),
                    data, desc, part, window, float(cfg.draw.settle_periods))
    try:
        n = usable_cores() if workers is None else int(workers)
        log.info("robustness: %d arms x %d conditions, %.1f s each (%.1f..%.1f s of %s)",
                 len(drawn), len(CONDITIONS), end - start, start, end, drawing.name)
        results = _play_all([None, *drawn], max(1, n))
    finally:
        _SHARED = None
    nominal, arms = results[0], np.stack(results[1:])  # (draws, conditions, 2)
    # the stretch's program against the whole drawing's: the catalogue's servos, every
    # correction, the same window
    every = with_overrides(cfg, _condition_overrides("all"))
    whole = run_servo_loop(every, data, desc, drawing, window=[start, end - start])
    check = whole.metrics(whole.errors(Chain.from_description(desc),
                                       float(cfg.draw.settle_periods)))
    whole_mean = check.get("marking_mean_um")
    conditions: dict[str, JsonValue] = {}
    for i, c in enumerate(CONDITIONS):
        conditions[c] = {
            "catalogue_mean_mm": _round(nominal[i, 0]),
            "catalogue_max_mm": _round(nominal[i, 1]),
            "mean_mm": _quantiles(arms[:, i, 0]),
            "max_mm": _quantiles(arms[:, i, 1]),
            # paired, arm by arm: what the condition buys against no correction
            "buys_mm": _quantiles(arms[:, 0, 0] - arms[:, i, 0]),
            "helps_share": _round(float(np.mean(arms[:, i, 0] < arms[:, 0, 0])), 4),
        }
    return {
        "study": "robustness", "name": artwork_name(cfg.artwork),
        "servos": [s.type for s in catalogue],
        "draws": int(study.draws), "seed": int(study.seed),
        "spread_pct": {k: float(getattr(study.spread, f"{k}_pct")) for k in SPREAD_FIELDS},
        "window_s": [round(start, 4), round(end, 4)],
        # the catalogue's servos with every correction, on the whole drawing's program
        "whole_program_all_mean_mm": (_round(float(whole_mean) / 1e3)
                                      if isinstance(whole_mean, int | float) else None),
        "conditions": conditions,
    }


def _round(x: float, digits: int = 4) -> float | None:
    return round(float(x), digits) if math.isfinite(float(x)) else None


def _section(obj: Mapping[str, JsonValue], key: str) -> Mapping[str, JsonValue]:
    """A section of the study's metrics (refused where it is not one: a file from
    elsewhere)."""
    value = obj.get(key)
    if not isinstance(value, Mapping):
        raise TattotronixError(f"the robustness metrics have no section '{key}': re-run "
                               "the 'robustness' stage")
    return value


def _box(section: Mapping[str, JsonValue], label: str) -> dict[str, float | str]:
    """A box of the figure from stored quantiles (:data:`QUANTILES`)."""
    def q(p: int) -> float:
        v = section.get(f"p{p}")
        return float(v) if isinstance(v, int | float) else math.nan

    return {"med": q(50), "q1": q(25), "q3": q(75), "whislo": q(5), "whishi": q(95),
            "label": label}


def robustness_figure(metrics: Mapping[str, JsonValue], path: Path) -> None:
    """The study's figure, from its metrics alone: per condition, the spread of the mean
    marking deviation over the drawn arms (box: 25 to 75 %, whiskers 5 to 95 %, the
    median line) and the catalogue arm's (a diamond); beside it, what each condition buys
    against no correction, arm by arm."""
    plt = pyplot()
    conds = _section(metrics, "conditions")
    names = [c for c in CONDITIONS if c in conds]
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(11, 4.4))
    ax.bxp([_box(_section(_section(conds, c), "mean_mm"), c) for c in names],
           showfliers=False)
    nominal = [(i + 1, v) for i, c in enumerate(names)
               if isinstance(v := _section(conds, c).get("catalogue_mean_mm"), int | float)]
    ax.plot([i for i, _ in nominal], [v for _, v in nominal], "D", color="#c0392b",
            label="the catalogue's servos")
    ax.set_yscale("log")
    ax.set_ylabel("mean marking deviation, mm (log)")
    ax.set_title("each arm drawn from the spread", fontsize=10)
    ax.legend(fontsize=8)
    bx.bxp([_box(_section(_section(conds, c), "buys_mm"), c) for c in names[1:]],
           showfliers=False)
    bx.axhline(0.0, color="0.4", lw=0.8)
    bx.set_yscale("symlog", linthresh=1.0)  # the small corrections, and where they hurt
    bx.set_ylabel("without - with, mm (linear within 1)")
    bx.set_title("what each condition buys, arm by arm", fontsize=10)
    from matplotlib.ticker import FuncFormatter

    for a in (ax, bx):
        a.yaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
        a.yaxis.set_minor_formatter(FuncFormatter(
            lambda v, _: f"{v:g}" if f"{v:g}"[0] in "235" else ""))
        a.grid(True, axis="y", alpha=0.3)
        a.tick_params(axis="x", labelrotation=30)
    window = metrics.get("window_s")
    span = "busiest window"
    if isinstance(window, list) and len(window) == 2 and all(
            isinstance(w, int | float) for w in window):
        span = f"its busiest {float(window[1]) - float(window[0]):.0f} s"
    fig.suptitle(f"Robustness study: {metrics.get('draws')} arms, their servos within the "
                 f"catalogue's spread ({metrics.get('name')}, {span})")
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    plt.close(fig)
