"""Verdicts that mean what they say (tattotronix/control/verdict.py; docs/control.md,
"Verdicts"): ``ok`` only within the drawing's tolerance, a saturated or diverged run never
``ok`` and never scored, an empty ink never a perfect match, errors from a millimetre up
in mm; and the three runs that said ``ok`` (or scored perfectly) when they were not."""

from __future__ import annotations

import json
import logging
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from tattotronix.app.drawings import resolve_drawing, score_and_write
from tattotronix.app.servos import run_servo_loop
from tattotronix.app.simulate import run_closed_loop
from tattotronix.config.params import compose_settings
from tattotronix.config.schema import Config
from tattotronix.control.drawing import Drawing
from tattotronix.control.ink import compare_ink
from tattotronix.control.tracking import ERROR_KEYS, tracking_errors
from tattotronix.control.verdict import VERDICTS, Tolerance, judge, length_text
from tattotronix.io.outputs import Outputs
from tattotronix.robot.description import RobotDescription
from tattotronix.studies.base import VERDICT_COLOUR, StudyCase, load_cases
from tattotronix.studies.registry import STUDIES

from .conftest import ROOT

#: the default tolerance: half of the 0.3 mm needle
TOL = Tolerance(0.5, 0.3)


# --- the rule ----------------------------------------------------------------------------

def test_the_tolerance_is_a_stated_fraction_of_the_needle_width() -> None:
    assert _tolerance(compose_settings()).um == pytest.approx(150.0)
    cfg = compose_settings(["draw.tolerance_needle_widths=1", "toolpath.needle_width_mm=0.5"])
    tol = _tolerance(cfg)
    assert tol.um == pytest.approx(500.0)
    assert tol.text() == "500 um (draw.tolerance_needle_widths=1 of the 0.5 mm needle)"


@pytest.mark.parametrize("loop, worst_um, verdict, stable, within", [
    ("ok", 18.75, "ok", True, True),
    ("ok", 150.0, "ok", True, True),  # at the tolerance: within
    ("ok", 150.01, "out-of-tolerance", True, False),
    ("ok", 18551.72, "out-of-tolerance", True, False),  # the servo plant's emblem
    ("ok", None, "ok", True, None),  # nothing marked: nothing off
    ("saturated", 18.33, "saturated", True, True),  # accurate, but never ok
    ("saturated", 5000.0, "saturated", True, False),
    ("diverged", 0.0, "diverged", False, None),  # a 0 um error before a blow-up is none
    ("diverged", None, "diverged", False, None),
])
def test_ok_only_within_the_tolerance_and_never_saturated_or_diverged(
        loop: str, worst_um: float | None, verdict: str, stable: bool,
        within: bool | None) -> None:
    j = judge(loop, "" if loop == "ok" else f"why it {loop}", worst_um, TOL)
    assert (j.verdict, j.stable, j.within_tolerance) == (verdict, stable, within)
    assert (j.reason == "") == (verdict == "ok")
    assert j.scores_ink == (verdict in ("ok", "out-of-tolerance"))
    assert (j.unscored_ink() == "") == j.scores_ink
    m = j.metrics()
    assert m["verdict"] == verdict and m["tolerance_um"] == pytest.approx(150.0)
    assert (j.warning("art on mujoco") == "") == (verdict == "ok")


def _tolerance(cfg: Config) -> Tolerance:
    return Tolerance.from_settings(cfg.draw, cfg.toolpath)


def test_an_out_of_tolerance_servo_run_warns_that_the_real_arm_will_miss() -> None:
    j = judge("ok", "", 18551.72, TOL)
    assert j.reason == ("the marking error reaches 18.55 mm, over the tolerance of 150 um "
                        "(draw.tolerance_needle_widths=0.5 of the 0.3 mm needle)")
    assert j.warning("emblem on servo", real_arm=True) == (
        "WARNING: draw emblem on servo is OUT OF TOLERANCE: the real arm will miss the "
        "drawing by up to 18.55 mm while marking, over the tolerance of 150 um "
        "(draw.tolerance_needle_widths=0.5 of the 0.3 mm needle)")
    assert "the simulated arm misses" in j.warning("emblem on mujoco")
    sat = judge("saturated", "the torque of joint_1 reached its limit (20 N m) at t = 0.291 s",
                18.33, TOL)
    assert sat.warning("lineart on mujoco") == (
        "WARNING: draw lineart on mujoco SATURATED: the torque of joint_1 reached its limit "
        "(20 N m) at t = 0.291 s")
    with pytest.raises(ValueError, match="not a loop verdict"):
        judge("out-of-tolerance", "", 1.0, TOL)


@pytest.mark.parametrize("um, text", [
    (18.747, "18.75 um"), (999.99, "999.99 um"), (1000.0, "1.00 mm"),
    (14115.99, "14.12 mm"), (18551.72, "18.55 mm"), (None, "-")])
def test_errors_from_a_millimetre_up_print_in_mm(um: float | None, text: str) -> None:
    assert length_text(um) == text
    assert length_text(um, "µm") == text.replace("um", "µm")


def test_every_verdict_has_a_study_colour() -> None:
    assert set(VERDICT_COLOUR) == set(VERDICTS)


# --- scores that cannot be given -----------------------------------------------------------

def test_an_empty_ink_never_scores_a_perfect_match() -> None:
    empty = np.zeros((20, 20), dtype=bool)
    line = empty.copy()
    line[10, 2:18] = True
    both = compare_ink(empty, empty, 0.05)  # the wn 10000 run's engine path, before
    assert both.iou is None and both.max_dev_mm is None
    assert both.metrics()["ink_reason"] == (
        "not scored: neither the run nor the plan inked anything")
    nothing_drawn = compare_ink(empty, line, 0.05)
    assert nothing_drawn.iou == 0.0 and nothing_drawn.max_dev_mm is None
    assert nothing_drawn.reason == "no worst deviation: the run inked nothing"
    off_plan = compare_ink(line, empty, 0.05)  # its Python path, before: IoU 0, no deviation
    assert off_plan.iou == 0.0 and off_plan.max_dev_mm is None
    assert off_plan.reason == "no worst deviation: the plan inks nothing here"
    same = compare_ink(line, line, 0.05)
    assert (same.iou, same.max_dev_mm, same.reason) == (1.0, 0.0, "")
    unscored = same.unscored("not scored: the run saturated; why")
    assert unscored.metrics() == {"ink_iou": None, "ink_max_dev_mm": None,
                                  "ink_reason": "not scored: the run saturated; why",
                                  "ink_px": 16, "plan_ink_px": 16}


def test_a_statistic_without_samples_is_null_with_its_reason() -> None:
    t = np.arange(5) * 0.02
    tips = np.zeros((5, 3))
    off = tips + [1e-5, 0.0, 0.0]  # 10 um off
    travel_only = tracking_errors(t, off, tips, np.array([0.0, 1.0]),
                                  np.zeros(2, dtype=np.int8), 160.0).metrics()
    assert travel_only["marking_max_um"] is None and travel_only["travel_mean_um"] == 10.0
    assert travel_only["tracking_reason"] == (
        "settled_mean_um, settled_max_um: no settled marking sample; marking_mean_um, "
        "marking_max_um, marking_worst_at_s: no marking sample; entry_max_um: no marking "
        "sample within the settling time after an entry")
    marking = tracking_errors(t, off, tips, np.array([0.0, 1.0]),
                              np.ones(2, dtype=np.int8), 160.0)
    assert marking.metrics()["marking_max_um"] == pytest.approx(10.0)
    gone = marking.unscored("not scored: the run diverged; why")
    assert all(gone[k] is None for k in ERROR_KEYS)
    assert gone["tracking_reason"] == "not scored: the run diverged; why"
    assert gone["samples"] == 5


# --- the studies read the verdicts ---------------------------------------------------------

def _rejudged(case: StudyCase, verdict: str) -> StudyCase:
    """A stored case with its whole-drawing run given ``verdict`` (its scores as a run with
    that verdict keeps them)."""
    m: dict[str, Any] = json.loads(json.dumps(dict(case)))
    whole = m["whole"]
    whole.update(verdict=verdict, reason="" if verdict == "ok" else f"why {verdict}",
                 stable=verdict != "diverged", tolerance_um=150.0)
    if verdict in ("saturated", "diverged"):
        whole.update(ink_iou=None, ink_max_dev_mm=None, line_width_mm=None)
    if verdict == "diverged":
        whole.update(dict.fromkeys(ERROR_KEYS))
    if "verdict_check" in m:
        m["verdict_check"].update(verdict=verdict, simulated="ok" if verdict in (
            "ok", "out-of-tolerance") else "fail")
    return StudyCase(m)


@pytest.mark.parametrize("study", ["control", "rate", "servo", "timelaw"])
def test_study_figures_and_summaries_take_every_verdict(study: str, tmp_path: Path) -> None:
    """Each study that reads verdicts draws its figure and concludes with cases of every
    verdict, their scores null where a run that ends so has none."""
    stored = load_cases(ROOT / "data", study, "emblem")
    if not stored:
        pytest.skip(f"no stored {study} metrics (run dvc repro)")
    names = sorted(stored)
    cases = {n: _rejudged(stored[n], VERDICTS[i % len(VERDICTS)]) for i, n in enumerate(names)}
    STUDIES[study].figure(cases, tmp_path / f"{study}.png")
    assert (tmp_path / f"{study}.png").stat().st_size > 10_000
    summary = STUDIES[study].summary(cases)
    assert json.loads(json.dumps(summary)) == summary  # plain JSON, no NaN
    if study == "rate":
        assert summary["ok"] == sum(c["whole"]["verdict"] == "ok" for c in cases.values())
        assert summary["simulated_ok"] == sum(c["whole"]["verdict"] in (
            "ok", "out-of-tolerance") for c in cases.values())
    if study == "control":
        assert set(summary["not_ok"]) == {n for n, c in cases.items()
                                          if c["whole"]["verdict"] != "ok"}
    if study == "servo":
        for name, row in summary["cases"].items():
            assert row["verdict"] == cases[name]["whole"]["verdict"]
            if row["verdict"] in ("saturated", "diverged"):
                assert row["worst_mm"] is None


# --- the three runs of the issue -----------------------------------------------------------

@pytest.fixture(scope="module")
def emblem(desc: RobotDescription, models_data: Path) -> Drawing:
    """The built-in emblem, planned at the defaults (as the pipeline plans it)."""
    return resolve_drawing(compose_settings(), models_data, desc)


#: the pipeline's lineart-vector (dvc.yaml, ``artworks``), planned in memory as "lineart"
LINEART_VECTOR = ["art=lineart", "artwork.source=lineart", "artwork.vector=true",
                  "mask.res_mm=0.1", "toolpath.compensate=true"]


def _scored(cfg: Any, data: Path, desc: RobotDescription, loop: Any, tmp: Path,
            caplog: pytest.LogCaptureFixture) -> tuple[dict[str, Any], list[str]]:
    """Score and write a run under ``tmp``: its metrics, and the lines it logged."""
    out = Outputs(data, root=tmp)
    caplog.clear()
    with caplog.at_level(logging.INFO, logger="tattotronix"), out.transaction():
        metrics = score_and_write(cfg, out, loop, desc)
    text = json.dumps(metrics)
    assert "NaN" not in text and "Infinity" not in text
    return metrics, [r.getMessage() for r in caplog.records]


@pytest.mark.slow
def test_the_servo_emblem_is_out_of_tolerance_and_says_the_arm_will_miss_in_mm(
        desc: RobotDescription, models_data: Path, emblem: Drawing, tmp_path: Path,
        caplog: pytest.LogCaptureFixture) -> None:
    """Before: ``ok; settled 14115.99 / 18551.72 um ... ink IoU 0.073``. The defaults
    correct the sag and lead the lag (``hardware.compensate``), not the pulse map's bend:
    still about 12 mm off."""
    cfg = compose_settings(["backend=servo"])
    loop = run_servo_loop(cfg, models_data, desc, emblem)
    m, said = _scored(cfg, models_data, desc, loop, tmp_path, caplog)
    assert m["verdict"] == "out-of-tolerance" and m["stable"] and m["completed"]
    assert m["within_tolerance"] is False and m["tolerance_um"] == pytest.approx(150.0)
    assert 11_000 < m["settled_mean_um"] < 13_500 and 15_000 < m["marking_max_um"] < 18_000
    assert m["ink_iou"] < 0.1 and m["ink_reason"] == ""  # scored: it shows how far off
    worst = length_text(m["marking_max_um"])
    assert worst.endswith(" mm")
    summary = [s for s in said if s.startswith("draw emblem on servo: out-of-tolerance;")]
    assert len(summary) == 1
    assert (f"settled {length_text(m['settled_mean_um'])} / "
            f"{length_text(m['settled_max_um'])} (mean / max), marking max {worst}"
            in summary[0])
    warned = [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING]
    assert warned == [
        f"WARNING: draw emblem on servo is OUT OF TOLERANCE: the real arm will miss the "
        f"drawing by up to {worst} while marking, over the tolerance of 150 um "
        "(draw.tolerance_needle_widths=0.5 of the 0.3 mm needle)"]


@pytest.mark.slow
def test_a_saturated_run_is_never_ok_and_its_ink_is_not_scored(
        desc: RobotDescription, models_data: Path, tmp_path: Path,
        caplog: pytest.LogCaptureFixture) -> None:
    """The pipeline's lineart-vector on MuJoCo, with a torque limit 0.3 % under the peak
    it needs (the gravity hold of joint 2 at its farthest pose): it saturates, and holds
    the drawing within tolerance. Before, such a run (then: the 20 N m limit on the move
    from home) said ``ok`` and its ink scored IoU 0.998."""
    drawing = resolve_drawing(compose_settings(LINEART_VECTOR), models_data, desc)
    free, _ = _scored(compose_settings(LINEART_VECTOR), models_data, desc,
                      run_closed_loop(compose_settings(LINEART_VECTOR), models_data, desc,
                                      drawing), tmp_path / "free", caplog)
    assert free["verdict"] == "ok"
    limit = round(0.997 * free["peak_torque_nm"], 4)
    cfg = compose_settings([*LINEART_VECTOR, f"controller.torque_limit_nm={limit}"])
    loop = run_closed_loop(cfg, models_data, desc, drawing)
    m, said = _scored(cfg, models_data, desc, loop, tmp_path, caplog)
    assert m["verdict"] == "saturated" and m["stable"] and m["completed"]
    assert m["peak_torque_nm"] == pytest.approx(limit)
    assert m["reason"].startswith("the torque of joint_")
    assert f"({limit:.3g} N m) at t = " in m["reason"]
    # accurate while marking (so within tolerance), but saturated: never ok, never scored
    assert m["within_tolerance"] is True and m["marking_max_um"] < 150.0
    assert m["ink_iou"] is None and m["ink_max_dev_mm"] is None and m["artwork"] is None
    assert m["ink_reason"] == f"not scored: the run saturated; {m['reason']}"
    assert m["artwork_reason"] == m["ink_reason"]
    assert m["ink_px"] > 0 and m["artwork_plan"] is not None  # the plan's ink is whole
    assert f"WARNING: draw lineart on mujoco SATURATED: {m['reason']}" in said
    assert any("ink IoU -," in s for s in said)


@pytest.mark.slow
@pytest.mark.parametrize("structure, loop_path", [("pid_g_v", "engine"),
                                                  ("computed_torque", "python")])
def test_a_diverged_run_scores_nothing(
        desc: RobotDescription, models_data: Path, emblem: Drawing, tmp_path: Path,
        caplog: pytest.LogCaptureFixture, structure: str, loop_path: str) -> None:
    """``controller.wn=10000`` diverges in the first ticks; before, its metrics said
    ``ink_iou 1.0`` (no ink against no plan; the engine path) or ``worst_um 0.0`` (the
    Python path, one sample at the start)."""
    cfg = compose_settings(["controller.wn=10000", f"controller.structure={structure}"])
    loop = run_closed_loop(cfg, models_data, desc, emblem)
    m, said = _scored(cfg, models_data, desc, loop, tmp_path, caplog)
    assert m["loop_path"] == loop_path
    assert m["verdict"] == "diverged" and not m["stable"] and not m["completed"]
    assert m["within_tolerance"] is None and m["sim_s"] <= 1.0
    assert all(m[k] is None for k in ERROR_KEYS)
    assert m["tracking_reason"].startswith(f"not scored: the run diverged; {m['reason']}")
    assert m["ink_iou"] is None and m["ink_max_dev_mm"] is None
    assert m["ink_reason"] == f"not scored: the run diverged; {m['reason']}"
    assert m["artwork"] is None and m["artwork_plan"] is None
    assert m["samples"] >= 1  # the counts of what ran stay
    assert f"WARNING: draw emblem on mujoco DIVERGED: {m['reason']}" in said
    assert not any(math.isclose(v, 1.0) for k, v in m.items()
                   if k.startswith("ink_") and isinstance(v, float))
