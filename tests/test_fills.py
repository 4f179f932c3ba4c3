"""The fill styles side by side (tattotronix/path/fillstyles.py, stage ``fills``): each
case is the toolpath stage's own plan with its style, the densest square is the densest,
and bad cases are refused."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from PIL import Image

from tattotronix.config.schema import MaskConfig, PanelConfig, ToolpathConfig
from tattotronix.errors import TattotronixError
from tattotronix.path.fillstyles import compare_fill_styles, densest_square, fills_figure
from tattotronix.path.params import ToolpathParams
from tattotronix.path.plan import plan_toolpath

from .test_fidelity import _disc_and_bar

NEEDLE, RES = 0.3, 0.05
CASES = {"hatch": ("hatch", 0.0), "hatch-30": ("hatch", 30.0), "cross": ("cross", 0.0),
         "concentric": ("concentric", 0.0), "solid": ("solid", 0.0)}


def _params(**over: object) -> ToolpathParams:
    params = ToolpathParams.from_settings(ToolpathConfig(compensate=True), MaskConfig(),
                                        PanelConfig())
    return dataclasses.replace(params, **over)


@pytest.fixture(scope="module")
def comparison():
    return compare_fill_styles(_disc_and_bar(), _params(), CASES, NEEDLE, RES, "disc")


def test_each_case_is_the_toolpath_stages_plan_with_its_style(comparison) -> None:
    mask = _disc_and_bar()
    assert [c.name for c in comparison.cases] == list(CASES)
    for case in comparison.cases:
        style, angle = CASES[case.name]
        tp = plan_toolpath(mask, _params(fill_style=style, fill_angle_deg=angle))
        assert case.time_s == tp.metrics.time_s and case.entries == tp.metrics.entries
        assert case.ink.fidelity == tp.ink(mask, NEEDLE, RES).fidelity
        assert case.ink.fidelity.bleed_max_mm <= 0.05  # compensated: the ink stays inside


def test_the_metrics_give_each_style_its_time_against_the_first(comparison) -> None:
    m = comparison.metrics()
    assert m["reference"] == "hatch" and list(m["cases"]) == list(CASES)
    by = m["cases"]
    assert by["hatch"]["time_ratio"] == 1.0
    for name, case in zip(CASES, comparison.cases, strict=True):
        assert by[name]["time_ratio"] == pytest.approx(case.time_s / comparison.cases[0].time_s)
        assert by[name]["artwork"]["coverage"] == case.ink.fidelity.coverage
        assert by[name]["fill_style"] == CASES[name][0]
    # density costs time: solid inks the most and takes the longest
    cover = {k: v["artwork"]["coverage"] for k, v in by.items()}
    assert max(cover, key=cover.get) == "solid" == max(by, key=lambda k: by[k]["time_s"])
    assert cover["cross"] > cover["hatch"]


def test_bad_cases_are_refused() -> None:
    mask = _disc_and_bar()
    with pytest.raises(TattotronixError, match="no cases"):
        compare_fill_styles(mask, _params(), {}, NEEDLE, RES, "disc")
    with pytest.raises(TattotronixError, match="compensate=true"):
        compare_fill_styles(mask, _params(compensate=False), {"r": ("concentric", 0.0)},
                            NEEDLE, RES, "disc")


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(1, 9))
def test_the_densest_square_holds_the_most_artwork(seed: int, side: int) -> None:
    art = np.random.default_rng(seed).random((13, 11)) < 0.4
    r, c = densest_square(art, side)
    best = max(art[i:i + side, j:j + side].sum()
               for i in range(14 - side) for j in range(12 - side))
    assert 0 <= r <= 13 - side and 0 <= c <= 11 - side
    assert art[r:r + side, c:c + side].sum() == best


def test_the_figure_shows_every_style(comparison, tmp_path: Path) -> None:
    path = tmp_path / "fills.png"
    fills_figure(comparison, 12.0, path)
    with Image.open(path) as im:
        w, h = im.size
        rgb = np.asarray(im.convert("RGB"))
    assert w > 1000 and h > 800  # five crops and the scatter, three to a row
    # every crop shows ink on the artwork (dark grey) and artwork left uninked
    assert np.any(np.all(rgb == (40, 40, 40), axis=2))
    assert np.any(np.all(rgb == (200, 200, 200), axis=2))
