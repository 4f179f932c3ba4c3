"""``stages/draw.py`` end to end on a small artwork: outputs, ink, refusals."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from .conftest import ROOT

SMALL = ["mask.width_mm=24", "mask.min_region_mm2=0.5"]


def _draw(data: Path, *overrides: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "stages/draw.py", f"paths.data={data}",
                           "draw.progress=false", *overrides],
                          cwd=ROOT, capture_output=True, text=True, timeout=600)


@pytest.fixture()
def data(draw_data: Path) -> Path:
    return draw_data


@pytest.mark.slow
@pytest.mark.parametrize("backend", ["mujoco", "pybullet", "model"])
def test_draw_writes_log_metrics_and_ink_on_every_backend(data: Path, backend: str) -> None:
    art = data.parent / "small.png"
    r = _draw(data, f"backend={backend}", f"artwork.source={art}", *SMALL)
    assert r.returncode == 0, r.stderr
    m = json.loads((data / "metrics" / "runs" / f"small-{backend}.json").read_text())
    for key in ("settled_mean_um", "settled_max_um", "marking_mean_um", "marking_max_um",
                "travel_mean_um", "peak_torque_nm", "ink_iou", "ink_max_dev_mm"):
        assert isinstance(m[key], float), key
    # wall times vary from run to run: they go to the timings file, never the metrics
    assert "wall_s" not in m and "realtime_factor" not in m
    timings = json.loads((data / "timings" / "runs" / f"small-{backend}.json").read_text())
    for key in ("realtime_factor", "wall_s"):
        assert isinstance(timings[key], float), key
    assert m["verdict"] == "ok" and m["completed"] and m["drawing"] == "planned"
    assert m["stable"] and m["within_tolerance"] and m["reason"] == ""
    assert m["marking_max_um"] <= m["tolerance_um"] == 150.0  # half the 0.3 mm needle
    assert m["ink_iou"] > 0.95 and m["ink_reason"] == "" and m["tracking_reason"] == ""
    assert m["marking_max_um"] < 100.0 and m["peak_torque_nm"] < 20.0
    run = data / "runs" / f"small-{backend}"
    with np.load(run / "log.npz", allow_pickle=False) as z:
        assert {"t", "q", "qd", "tau", "q_ref", "tip", "tip_ref", "error_m", "down",
                "provenance"} <= set(z.files)
        assert len(z["t"]) == m["samples"] and np.all(np.isfinite(z["q"]))
        assert json.loads(str(z["provenance"]))["config"]["backend"] == backend
    with Image.open(run / "ink.png") as im:
        ink = np.asarray(im.convert("L")) < 128
    assert ink.any() and ink.mean() < 0.9
    assert (run / "ink_vs_plan.png").exists()
    # against the artwork (the small drawing's mask, made here): the simulated ink and the
    # reference's, side by side
    sim, plan = m["artwork"], m["artwork_plan"]
    assert 0.3 < sim["coverage"] <= 1.0 and 0.0 <= sim["bleed_share"] < 0.5
    assert sim["bleed_max_mm"] < 1.0 and 0 < sim["edge_mean_mm"] <= sim["edge_max_mm"]
    assert abs(sim["coverage"] - plan["coverage"]) < 0.05
    with Image.open(run / "ink_vs_artwork.png") as im:
        assert im.size[0] > 100


@pytest.mark.slow
def test_unstable_controller_is_reported_not_crashed(data: Path) -> None:
    """200 Hz at wn = 160 is past the sampled boundary: the run says so, the metrics
    hold no NaN, and the stage still writes everything."""
    art = data.parent / "small.png"
    r = _draw(data, "backend=model", f"artwork.source={art}", *SMALL, "controller.rate_hz=200",
              "window=[0,3]")
    assert r.returncode == 0, r.stderr
    text = (data / "metrics" / "runs" / "small-model.json").read_text()
    assert "NaN" not in text and "Infinity" not in text
    m = json.loads(text)
    assert m["verdict"] in ("saturated", "diverged") and m["reason"]
    # never ok, and never scored: the ink's scores are null, with the reason
    assert m["ink_iou"] is None and m["ink_max_dev_mm"] is None and m["artwork"] is None
    assert m["ink_reason"] == f"not scored: the run {m['verdict']}; {m['reason']}"
    assert f"WARNING: draw small on model {m['verdict'].upper()}: " in r.stdout + r.stderr
    assert m["loop"]["wnT"] == pytest.approx(0.8)
    assert m["loop"]["margin"] < 1.0


def test_unknown_art_lists_those_available(data: Path) -> None:
    r = _draw(data, "art=nosuchthing")
    assert r.returncode == 2
    assert "no drawing named 'nosuchthing'" in r.stderr and "emblem" in r.stderr
    assert "Traceback" not in r.stderr


def test_missing_models_name_the_robot_stage(tmp_path: Path) -> None:
    r = _draw(tmp_path / "empty", "art=emblem")
    assert r.returncode == 2 and "run the 'robot' stage first" in r.stderr


def test_bad_window_and_backend_are_refused(data: Path) -> None:
    r = _draw(data, "window=[1,2,3]")
    assert r.returncode == 2 and "window" in r.stderr
    r = _draw(data, "backend=gazebo")
    assert r.returncode != 0 and "gazebo" in r.stderr and "mujoco" in r.stderr
