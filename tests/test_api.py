"""The Python API (``tattotronix.plan``; README, "The Python API").

* The README's example runs as written, on a generated logo (no CAD meshes needed).
* A plan made through the API is the plan the pipeline makes from the same inputs.
* Strokes land where they were sent; bad strokes, bad keywords and bad settings get one
  clear error; ``import tattotronix`` stays light.
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import tattotronix as tt
from tattotronix.config.params import compose_settings
from tattotronix.errors import ConfigError, TattotronixError
from tests.conftest import PYTHON, ROOT, small_art
from tests.test_artwork_tracked import MINE_ARGS, Clone

LOGO = """<svg xmlns="http://www.w3.org/2000/svg" width="80mm" height="30mm" viewBox="0 0 80 30">
<path fill-rule="evenodd" d="M2 2H38V28H2Z M10 9H30V21H10Z"/>
<circle cx="60" cy="15" r="12"/></svg>"""


def _readme_example() -> str:
    text = (ROOT / "README.md").read_text()
    section = text[text.index("## The Python API"):]
    match = re.search(r"```python\n(.*?)```", section, re.S)
    assert match, "README's Python API section has no python block"
    return match.group(1)


@pytest.mark.slow
def test_readme_example_runs_as_written(tmp_path: Path) -> None:
    (tmp_path / "logo.svg").write_text(LOGO)
    script = tmp_path / "example.py"
    script.write_text(_readme_example() + (
        "\nimport json\n"
        "json.dump({'stats': d.stats, 'run': run['verdict'], 'max': run['marking_max_um'],\n"
        "           'real': real['verdict'], 'arm': arm['status'], 'strokes': s.stats,\n"
        "           'draft': [p.ok, p.problem],\n"
        "           'workdir': str(d.workdir)}, open('out.json', 'w'))\n"))
    env = {k: v for k, v in os.environ.items() if k != "TATTOTRONIX_CAD_DIR"}
    env["MPLBACKEND"] = "Agg"
    proc = subprocess.run([sys.executable, str(script)], cwd=tmp_path, env=env,
                          capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, proc.stderr[-3000:]
    out = json.loads((tmp_path / "out.json").read_text())
    assert out["stats"]["entries"] >= 2 and out["stats"]["duration_s"] > 0
    assert out["stats"]["bleed_max_mm"] <= 0.1
    assert out["run"] == "ok" and out["max"] < 20  # the default controller's goal
    assert out["real"] in ("ok", "out-of-tolerance")  # hobby servos miss by millimetres
    assert out["arm"] == "done"
    assert out["strokes"]["entries"] == 2
    assert out["draft"][0] is False and "off the" in out["draft"][1]
    assert (tmp_path / "preview.png").stat().st_size > 10_000
    with np.load(tmp_path / "logo" / "trajectories" / "logo.npz", allow_pickle=False) as z:
        assert {"joints", "t", "q", "qd", "qdd", "kind", "marked", "tcp",
                "provenance"} <= set(z.files)
    work = Path(out["workdir"])
    for backend in ("mujoco", "servo"):
        assert (work / "runs" / f"logo-{backend}" / "ink.png").is_file()
        assert (work / "metrics" / "runs" / f"logo-{backend}.json").is_file()
    assert (work / "runs" / "logo-arm" / "i2c.jsonl").stat().st_size > 0


def test_plan_is_the_pipelines_plan(tmp_path: Path) -> None:
    """The API's plan and the pipeline's (``draw.py artwork.source=...``) from the same
    file and settings: the same points, times and angles, to the bit."""
    from tattotronix.app.pipeline import plan_drawing
    from tattotronix.robot.description import build_description

    art = small_art(tmp_path / "small.png")
    d = tt.plan(art, width_mm=24, workdir=tmp_path / "work")
    cfg = compose_settings([f"artwork.source={art}", "mask.width_mm=24"])
    traj = plan_drawing(cfg, art, "small", build_description(cfg.robot))
    assert d.name == "small"
    for key in ("t", "q", "qd", "kind"):
        assert np.array_equal(getattr(d.trajectory, key), getattr(traj, key)), key
    assert d.stats["entries"] == d.toolpath.metrics.entries
    saved = d.save(tmp_path / "saved")
    assert saved == tmp_path / "saved" / "trajectories" / "small.npz"
    with np.load(saved, allow_pickle=False) as z:
        assert np.array_equal(z["q"], traj.q)
        prov = json.loads(str(z["provenance"]))
    assert prov["inputs"]["ik"]["path"] == "ik/small.npz"
    assert prov["inputs"]["urdf"]["path"] == "robot/tattotronix.urdf"
    png = d.preview(tmp_path / "p" / "preview.png")
    assert png.stat().st_size > 10_000
    draft = tt.draft(art, width_mm=24)  # the same toolpath, untimed
    assert draft.ok and np.array_equal(draft.toolpath.path.uvz_mm, d.toolpath.path.uvz_mm)
    assert {k: draft.stats[k] for k in ("entries", "marked_mm", "travel_mm")} == {
        k: d.stats[k] for k in ("entries", "marked_mm", "travel_mm")}
    assert draft.preview(tmp_path / "draft.png").stat().st_size > 10_000


def test_a_draft_names_what_planning_would_refuse(tmp_path: Path) -> None:
    art = small_art(tmp_path / "small.png")
    off = tt.draft(art, width_mm=24, overrides=["mask.anchor=centre", "mask.at_mm=[95,0]"])
    assert not off.ok and off.drafted is None
    with pytest.raises(TattotronixError) as err:
        tt.plan(art, width_mm=24, overrides=["mask.anchor=centre", "mask.at_mm=[95,0]"])
    assert off.problem == str(err.value) and "off the" in off.problem
    with pytest.raises(TattotronixError, match="off the"):
        off.toolpath  # noqa: B018
    assert off.stats == {"name": "small", "ok": False, "problem": off.problem}
    with pytest.raises(ConfigError):
        tt.draft(art, overrides=["toolpath.pitch_mm=-1"])


@pytest.mark.slow
def test_a_saved_plan_is_the_stages_files_byte_for_byte(tmp_path: Path) -> None:
    """On a clone, ``dvc repro trajectory@mine`` and ``tt.plan(...).save(...)`` of the same
    file with the same overrides write the same bytes, file by file, from the artwork's
    raster to the trajectory (each records the same provenance)."""
    c = Clone(tmp_path)
    made = c.dvc("repro", "trajectory@mine")
    assert made.returncode == 0, made.stdout[-3000:] + made.stderr[-3000:]
    width = MINE_ARGS.split("mask.width_mm=")[1]
    script = ("import tattotronix as tt\n"
              f"tt.plan('art/mine.png', width_mm={width}).save('saved')\n")
    saved = c.run(PYTHON, "-c", script)
    assert saved.returncode == 0, saved.stderr[-3000:]
    files = ["artwork/mine.png", "artwork/mine-lines.npz", "mask/mine.npz",
             "toolpath/mine.npz", "robot/tattotronix.urdf", "ik/mine.npz",
             "trajectories/mine.npz"]
    for f in files:
        ours, theirs = c.root / "saved" / f, c.root / "data" / f
        assert ours.read_bytes() == theirs.read_bytes(), f


def test_strokes_land_where_sent(tmp_path: Path) -> None:
    strokes = [np.array([(-20.0, -10.0), (20.0, -10.0), (20.0, 10.0)]),
               np.array([(-30.0, 15.0), (-10.0, 25.0)])]
    d = tt.plan_strokes(strokes, workdir=tmp_path)
    assert d.stats["entries"] == 2
    uv = d.toolpath.path.uvz_mm[d.toolpath.path.kind == 1][:, :2]

    def dist(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        ab = b - a
        t = np.clip(((p - a) @ ab) / (ab @ ab), 0, 1)
        return np.linalg.norm(p - (a + t[:, None] * ab), axis=1)

    segs = [(s[i], s[i + 1]) for s in strokes for i in range(len(s) - 1)]
    near = np.min([dist(uv, a, b) for a, b in segs], axis=0)
    assert near.max() < 0.1  # on the polylines (the mask's pixel is 0.25 mm)
    marked = d.stats["marked_mm"]
    assert marked == pytest.approx(40 + 20 + np.hypot(20, 10), rel=0.03)
    assert (tmp_path / "strokes.svg").is_file()


@pytest.mark.parametrize(("strokes", "match"), [
    ([], "no strokes"),
    ([[(0.0, 0.0)]], "at least two"),
    ([[(0.0, 0.0), (float("nan"), 1.0)]], "finite"),
    ([[(0.0, 0.0), (500.0, 0.0)]], r"\(500\.0, 0\.0\) mm is off the panel"),
])
def test_bad_strokes_are_refused(strokes: list[list[tuple[float, float]]], match: str,
                                 tmp_path: Path) -> None:
    with pytest.raises(TattotronixError, match=match):
        tt.plan_strokes(strokes, workdir=tmp_path)


def test_bad_keywords_and_settings(tmp_path: Path) -> None:
    art = small_art(tmp_path / "small.png")
    with pytest.raises(TypeError, match="unexpected keyword argument 'widht_mm'"):
        tt.plan(art, widht_mm=20)
    with pytest.raises(ConfigError):
        tt.plan(art, overrides=["toolpath.pitch_mm=-1"])
    with pytest.raises(TattotronixError, match="no such file|not found|cannot"):
        tt.plan(tmp_path / "missing.png")


def test_simulate_refuses_the_servo_and_the_arm(tmp_path: Path) -> None:
    d = tt.plan_strokes([[(-5.0, 0.0), (5.0, 0.0)]], workdir=tmp_path)
    for backend in ("servo", "arm"):
        with pytest.raises(TattotronixError, match="predict|draw"):
            d.simulate(backend)


def test_import_stays_light() -> None:
    """``import tattotronix`` (every stage's first import) loads no API; ``tt.plan``
    loads it on first use."""
    code = ("import sys, tattotronix as tt; assert 'tattotronix.app' not in sys.modules; "
            "assert callable(tt.plan) and 'tattotronix.app.api' in sys.modules; "
            "assert 'plan_strokes' in dir(tt)")
    subprocess.run([sys.executable, "-c", code], check=True, cwd=ROOT)
    with pytest.raises(AttributeError):
        tt.no_such_thing  # noqa: B018


def test_no_stage_runs_the_api_but_draw() -> None:
    """Every stage imports the package, and the package offers the API lazily; only the
    stage that draws runs it (through ``app.draw``), so an edit of the API reruns that
    stage alone, not all of them (``tattotronix/__init__.py`` imports it via importlib)."""
    from tattotronix.devtools.codedeps import stage_deps

    users = {s.name for s in stage_deps(ROOT) if "tattotronix/app/api.py" in s.wanted}
    assert not users, users
    drawers = {s.name for s in stage_deps(ROOT) if "tattotronix/app/draw.py" in s.wanted}
    assert drawers == {"simulate"}, drawers
