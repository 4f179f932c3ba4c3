"""``dvc plots``: the plots declared in dvc.yaml render from the tables the figures and
studies stages write (README, "Plots"), offline (the page inlines Vega), the errors by case
on a log scale with the cases that are not ok marked, and the tables keep every worst
value."""

from __future__ import annotations

import configparser
import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from tattotronix.report.figures import plot_tables
from tattotronix.report.plotpage import PLACEHOLDERS, page_html
from tattotronix.studies.base import StudyCase
from tattotronix.studies.rate import STUDY as RATE

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
    # offline: the configured page, Vega inlined, no script from anywhere else
    assert "window.vegaEmbed" in page
    assert not re.search(r"<script[^>]*\bsrc=", page), "a script loaded from elsewhere"
    assert "cdn.jsdelivr" not in page


def test_the_page_template_is_the_plots_page_stages_and_inlines_vega() -> None:
    config = configparser.ConfigParser()
    config.read(ROOT / ".dvc" / "config")
    template = (ROOT / ".dvc" / config["plots"]["html_template"]).resolve()
    assert template == ROOT / "data" / "plots" / "page.html"
    stages = yaml.safe_load((ROOT / "dvc.yaml").read_text())["stages"]
    assert stages["plots_page"]["outs"] == [{"${paths.data}/plots/page.html": {"cache": False}}]
    page = page_html()
    assert page == page_html()  # the same bytes every time (a git-tracked output)
    assert all(p in page for p in PLACEHOLDERS) and "{scripts}" not in page  # no CDN tags
    assert "window.vegaEmbed" in page and not re.search(r"<script[^>]*\bsrc=", page)
    if template.is_file():  # the committed page is the installed package's
        assert template.read_text(encoding="utf-8") == page, (
            "data/plots/page.html is not what vl-convert-python writes now: "
            "dvc repro plots_page")


def test_the_errors_by_case_are_on_a_log_scale_and_mark_what_is_not_ok() -> None:
    plots = {next(iter(p)): next(iter(p.values()))
             for p in yaml.safe_load((ROOT / "dvc.yaml").read_text())["plots"]}
    log_plots = [n for n, p in plots.items() if p.get("template") == "error_bars_log"]
    assert {n.split(",")[0] for n in log_plots} == {
        "control study", "rate study", "servo study"}
    template = json.loads((ROOT / ".dvc" / "plots" / "error_bars_log.json").read_text())
    assert template["encoding"]["x"]["scale"] == {"type": "log"}
    assert "verdict" in json.dumps(template["transform"])
    # the study tables carry each case's verdict for it
    cases = {"200hz-wn80": StudyCase({"settings": {"controller.rate_hz": 200,
                                                   "controller.wn": 80},
                                      "whole": {"verdict": "diverged", "sim_s": 0.1}}),
             "1000hz-wn160": StudyCase({"settings": {"controller.rate_hz": 1000,
                                                     "controller.wn": 160},
                                        "whole": {"verdict": "ok", "marking_max_um": 20.7,
                                                  "marking_mean_um": 1.3, "sim_s": 650.4}})}
    rows = {r["case"]: r for r in RATE.curve(cases)}
    assert rows["200hz-wn80"]["verdict"] == "diverged"
    assert rows["200hz-wn80"]["marking_max_um"] is None
    assert rows["1000hz-wn160"]["verdict"] == "ok"


@pytest.mark.skipif(shutil.which("chromium") is None, reason="no chromium (apt: chromium)")
def test_the_page_renders_offline_in_a_browser(tmp_path: Path) -> None:
    """Headless Chromium, background networking off, opens the page `dvc plots show`
    writes: every plot is drawn (Vega puts its marks, an svg or a canvas, in each plot's
    div)."""
    if not (ROOT / "data" / "plots").is_dir():
        pytest.skip("the plot tables are not checked out (data/plots)")
    out = tmp_path / "plots"
    html = subprocess.run([PYTHON, "-m", "dvc", "plots", "show", "-o", str(out)], cwd=ROOT,
                          env=ENV, capture_output=True, text=True, timeout=300)
    assert html.returncode == 0, html.stderr
    dom = subprocess.run(
        ["chromium", "--headless", "--no-sandbox", "--disable-gpu",
         "--disable-background-networking", "--virtual-time-budget=10000", "--dump-dom",
         (out / "index.html").as_uri()],
        capture_output=True, text=True, timeout=300)
    assert dom.returncode == 0, dom.stderr[-2000:]
    drawn = re.findall(r'<(?:svg|canvas)[^>]*class="marks"', dom.stdout)
    assert len(drawn) == len(_declared()), dom.stdout[-2000:]


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
