"""Carrying the documents' figures over to new metrics (tattotronix/devtools/docfigures.py):
a figure follows the source that traced it, at its written precision; a still-traced
figure, a quoted document and an ambiguous figure are left alone."""

from __future__ import annotations

import json
from pathlib import Path

from tattotronix.devtools.certify import extract_figures, load_sources
from tattotronix.devtools.docfigures import carry_over, written_as


def _metrics(root: Path, values: dict[str, float]) -> None:
    path = root / "data" / "metrics" / "runs" / "x.json"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(values))


def test_a_figure_follows_its_source_and_the_rest_are_left(tmp_path: Path) -> None:
    old, new = tmp_path / "old", tmp_path / "new"
    _metrics(old, {"marking_max_um": 16.22, "peak_torque_nm": 0.358, "a_um": 3.04,
                   "b_um": 3.04, "fixed_mm": 1.5})
    _metrics(new, {"marking_max_um": 18.748, "peak_torque_nm": 0.3531, "a_um": 4.0,
                   "b_um": 5.0, "fixed_mm": 1.5})
    readme = ("Worst 16.22 µm, torque 0.358 N m, plunge 1.5 mm, either 3.04 µm.\n"
              "Unknown 7.7 mm.\n")
    (new / "README.md").write_text(readme)
    (new / "docs").mkdir()
    (new / "docs" / "original.md").write_text("The original: 16.22 µm.\n")
    before, _ = load_sources(old)
    after, _ = load_sources(new)
    changes, unsettled = carry_over(new, before, after)
    assert [(c.before, c.after) for c in changes] == [("16.22", "18.75"), ("0.358", "0.353")]
    assert (new / "README.md").read_text() == readme.replace("16.22", "18.75").replace(
        "0.358", "0.353")
    assert (new / "docs" / "original.md").read_text() == "The original: 16.22 µm.\n"
    why = {u.text: u.why for u in unsettled}
    assert why == {"3.04 µm": "its sources now disagree: 4.00, 5.00",
                   "7.7 mm": "traced to nothing before"}


def test_written_as_keeps_the_figures_form() -> None:
    fig = extract_figures("a 1,234.5 mm b\n")[0]
    assert written_as(12345.67, fig) == "12,345.7"
    fig = extract_figures("at -9.44 mm\n")[0]
    assert written_as(-9.4449, fig) == "-9.44"
    fig = extract_figures("IoU 99.6 %\n")[0]
    assert written_as(0.9981, fig, 100) == "99.8"
