"""The robustness study (tattotronix/studies/robustness.py; docs/servos.md, "Robustness"):
arms drawn within the catalogue's spread, the stretch of a drawing the study plays, and a
small study end to end, its figure drawn from its metrics."""

from __future__ import annotations

import json
import math
from dataclasses import fields, replace
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.interpolate import CubicHermiteSpline

from tattotronix.app.drawings import resolve_drawing
from tattotronix.app.servos import run_servo_loop
from tattotronix.config.params import compose_settings
from tattotronix.config.schema import ServoSpreadConfig
from tattotronix.control.drawing import Drawing
from tattotronix.hardware.servo_model import SPREAD_FIELDS, joint_servos, spread_servos
from tattotronix.hardware.servos import default_calibration
from tattotronix.kinematics import Chain
from tattotronix.plants.servo_plant import ServoSpec
from tattotronix.robot.description import RobotDescription
from tattotronix.studies.robustness import (
    CONDITIONS,
    QUANTILES,
    crop_drawing,
    robustness_figure,
    run_robustness,
)


@pytest.fixture(scope="module")
def mounted(desc: RobotDescription) -> tuple[ServoSpec, ...]:
    """The mounted servos' catalogue figures, every imperfection on (the defaults)."""
    cfg = compose_settings()
    return joint_servos(cfg.robot, desc.joint_names, default_calibration(), cfg.servo)


def test_no_spread_is_the_catalogue(mounted: tuple[ServoSpec, ...]) -> None:
    zero = ServoSpreadConfig(**{f"{k}_pct": 0.0 for k in SPREAD_FIELDS})
    assert spread_servos(mounted, zero, np.random.default_rng(3)) == mounted


@given(seed=st.integers(0, 2**32 - 1), pct=st.floats(0.0, 90.0))
@settings(max_examples=40, deadline=None)
def test_every_drawn_figure_is_within_its_spread(seed: int, pct: float) -> None:
    """Each figure within +-pct of the catalogue's, zero figures and a bus servo's dead band
    (its encoder step) untouched, and the same seed the same arm."""
    pwm = ServoSpec("MG996R", False, 0.004, 1.079, 6.98, 0.05, 0.017, 0.035, 0.0022, 0.0115,
                    0.0)
    bus = ServoSpec("STS3215", True, 0.003, 2.94, 4.72, 0.035, 0.017, 0.0, 0.009, 0.002,
                    0.0015)
    spread = ServoSpreadConfig(**{f"{k}_pct": pct for k in SPREAD_FIELDS})
    arm = spread_servos((pwm, bus), spread, np.random.default_rng(seed))
    assert arm == spread_servos((pwm, bus), spread, np.random.default_rng(seed))
    for cat, drawn in zip((pwm, bus), arm, strict=True):
        for f in fields(ServoSpec):
            a, b = getattr(cat, f.name), getattr(drawn, f.name)
            if not isinstance(a, float) or isinstance(a, bool):
                assert a == b
            elif a == 0.0 or (cat.bus and f.name == "deadband_rad") or f.name == "step_rad":
                assert b == a
            else:
                assert abs(b - a) <= pct / 100 * abs(a) * (1 + 1e-12)
                assert b > 0


def test_each_figure_draws_from_its_own_spread(mounted: tuple[ServoSpec, ...]) -> None:
    """Only the backlash spread: only the backlash moves, and over many arms it fills
    +-50 % of the catalogue's (uniform: both ends reached within a few %)."""
    only = ServoSpreadConfig(**{f"{k}_pct": (50.0 if k == "backlash" else 0.0)
                                for k in SPREAD_FIELDS})
    rng = np.random.default_rng(0)
    ratios = []
    for _ in range(400):
        arm = spread_servos(mounted, only, rng)
        for cat, drawn in zip(mounted, arm, strict=True):
            assert replace(drawn, backlash_rad=cat.backlash_rad) == cat
            ratios.append(drawn.backlash_rad / cat.backlash_rad)
    assert min(ratios) < 0.53 and max(ratios) > 1.47
    assert abs(float(np.mean(ratios)) - 1.0) < 0.03


def test_the_stretch_is_the_whole_drawings_curve() -> None:
    """The cropped drawing's Hermite curve, shifted back, is the whole one's; it starts on a
    frame of the whole program, a margin before the window."""
    rng = np.random.default_rng(1)
    t = np.cumsum(rng.uniform(0.005, 0.05, 2000))
    t -= t[0]
    q = np.cumsum(rng.normal(0, 0.01, (len(t), 5)), axis=0)
    qd = rng.normal(0, 0.2, (len(t), 5))
    kind = rng.integers(0, 3, len(t)).astype(np.int8)
    whole = Drawing("random", t, q, qd, kind, "planned")
    start, end = 17.31, 21.0
    part, (a, b) = crop_drawing(whole, start, end, 50.0, margin_s=1.0)
    t0 = start - a
    assert t0 == pytest.approx(16.30)  # 50 Hz frames: the frame at or before start - 1 s
    assert b - a == pytest.approx(end - start)
    assert part.t[0] == 0.0 and part.t[-1] >= b + 1.0 - 1e-9
    s = np.linspace(0.0, float(part.t[-1]), 3001)
    mine = CubicHermiteSpline(part.t, part.q, part.qd, axis=0)(s)
    theirs = CubicHermiteSpline(t, q, qd, axis=0)(s + t0)
    np.testing.assert_allclose(mine, theirs, atol=1e-9)
    np.testing.assert_array_equal(part.kind[1:], kind[(t > t0) & (t <= part.t[-1] + t0 + 1e-12)])


def test_a_small_study_end_to_end(models_data: Path, desc: RobotDescription,
                                  tmp_path: Path) -> None:
    """Three arms over a 3 s window: every condition scored; the catalogue arm with every
    correction is the servo plant's own run of that window (the program compiled on the
    stretch, not the whole drawing: within 2 %); the corrections all together beat none on
    every arm; the figure is drawn from the metrics file."""
    overrides = ["study.robustness.draws=3", "study.window_s=3"]
    cfg = compose_settings(overrides)
    m = run_robustness(cfg, models_data, workers=1)
    assert m["draws"] == 3 and set(m["conditions"]) == set(CONDITIONS)  # type: ignore[arg-type]
    conds: dict = m["conditions"]  # type: ignore[assignment]
    for c in CONDITIONS:
        for key in ("mean_mm", "max_mm", "buys_mm"):
            q = conds[c][key]
            assert q["scored"] == 3
            values = [q[f"p{p}"] for p in QUANTILES]
            assert values == sorted(values) and q["best"] <= values[0] <= values[-1] <= q["worst"]
    assert conds["none"]["buys_mm"]["worst"] == 0.0
    assert conds["all"]["buys_mm"]["best"] > 0 and conds["all"]["helps_share"] == 1.0
    # the catalogue arm, against the servo plant on the whole drawing's program
    every = compose_settings(["backend=servo", *overrides,
                              *(f"hardware.compensate.{k}=true" for k in
                                ("fit", "backlash", "deadband", "sag", "lead"))])
    drawing = resolve_drawing(every, models_data, desc)
    loop = run_servo_loop(every, models_data, desc, drawing, window="busiest")
    own = loop.metrics(loop.errors(Chain.from_description(desc),
                                   float(every.draw.settle_periods)))
    assert conds["all"]["catalogue_mean_mm"] == pytest.approx(
        float(own["marking_mean_um"]) / 1e3, rel=0.02)
    assert m["whole_program_all_mean_mm"] == pytest.approx(
        float(own["marking_mean_um"]) / 1e3, abs=1e-4)
    # the figure: from the file's JSON alone
    path = tmp_path / "metrics.json"
    path.write_text(json.dumps(m))
    png = tmp_path / "robustness.png"
    robustness_figure(json.loads(path.read_text()), png)
    assert png.stat().st_size > 10_000
    assert math.isfinite(float(conds["all"]["mean_mm"]["p50"]))
