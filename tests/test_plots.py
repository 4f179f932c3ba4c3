"""``dvc plots``: the plots declared in dvc.yaml render from the tables the figures and
studies stages write (README, "Plots"), and the tables keep every worst value."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from tattotronix.report.figures import plot_tables

from .conftest import ROOT

PYTHON = sys.executable
ENV = {**{k: v for k, v in os.environ.items() if k != "DVC_STAGE"}, "DVC_NO_ANALYTICS": "1"}


def _declared() -> list[str]:
    doc = yaml.safe_load((ROOT / "dvc.yaml").read_text())
    return [next(iter(p)) for p in doc["plots"]]


def test_every_declared_plot_renders(tmp_path: Path) -> None:
    names = _declared()
    assert len(names) >= 8  # the drawing's three and each study's curve
    if not (ROOT / "data" / "plots").is_dir():
        pytest.skip("the plot tables are not checked out (data/plots)")
    shown = subprocess.run([PYTHON, "-m", "dvc", "plots", "show", "--json"], cwd=ROOT,
                           env=ENV, capture_output=True, text=True, timeout=300)
    assert shown.returncode == 0, shown.stderr
    doc = json.loads(shown.stdout)
    assert not doc.get("errors"), doc.get("errors")
    for name in names:
        (plot,) = doc["data"][name]
        values = plot["content"]["data"]["values"]
        assert values, f"{name}: no data"
    html = subprocess.run([PYTHON, "-m", "dvc", "plots", "show", "-o", str(tmp_path)],
                          cwd=ROOT, env=ENV, capture_output=True, text=True, timeout=300)
    assert html.returncode == 0, html.stderr
    page = (tmp_path / "index.html").read_text()
    assert all(name in page for name in names)


def test_the_tables_keep_the_worst_value_and_the_limits() -> None:
    t = np.linspace(0.0, 100.0, 10_001)
    err = np.full_like(t, 1e-6)
    err[4321] = 55e-6  # one spike among 10 001 samples
    q = np.column_stack([np.sin(t), np.zeros_like(t)])
    qd = np.column_stack([np.cos(t), np.zeros_like(t)])
    qd[777, 1] = 2.0  # a single fast sample on the second joint
    tables = plot_tables(t, q, qd, ["a", "b"], [-1.0, -1.0], [1.0, 1.0], [2.0, 4.0],
                         t, err, t > 50, rows=100)
    track = tables["tracking.csv"]
    assert len(track) == 100
    assert max(r["error_um"] for r in track) == pytest.approx(55.0)
    assert {r["needle_down"] for r in track} == {0, 1}
    pos = tables["joints.csv"]
    assert all(0.0 <= r["a_pct"] <= 100.0 for r in pos) and pos[0]["b_pct"] == 50.0
    speed = tables["joint_speed.csv"]
    assert max(r["b_pct"] for r in speed) == pytest.approx(50.0)  # 2 of its 4 rad/s
    assert max(r["a_pct"] for r in speed) == pytest.approx(50.0, abs=0.01)
