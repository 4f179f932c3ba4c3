"""Runs by hand never write where ``dvc repro`` writes (README, "Hand runs").

A run by hand (``python stages/...``, a ``-m`` sweep, a notebook's ``Outputs``) reads the
pipeline's data but writes under ``runs/`` beside it, unless ``paths.out`` says otherwise
or its ``paths.data`` is a folder of its own. Inside a DVC stage it writes to
``paths.data``.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from tattotronix.io.outputs import HAND_RUNS, PIPELINE_DATA, PROJECT_ROOT, Outputs, write_root

from .conftest import ROOT

PYTHON = sys.executable


def test_write_root_follows_the_rules(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    pipeline = PROJECT_ROOT / PIPELINE_DATA
    monkeypatch.delenv("DVC_STAGE", raising=False)
    assert write_root(pipeline) == PROJECT_ROOT / HAND_RUNS  # by hand: beside it
    assert write_root(pipeline, out="somewhere") == Path("somewhere")  # the explicit choice
    assert write_root(pipeline, out=str(pipeline)) == pipeline  # ... even the pipeline's
    assert write_root(tmp_path / "mine") == tmp_path / "mine"  # a scratch pipeline
    monkeypatch.setenv("DVC_STAGE", "simulate@emblem")
    assert write_root(pipeline) == pipeline  # dvc repro owns it


def test_a_notebooks_outputs_read_the_pipeline_and_write_beside_it(
        monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("DVC_STAGE", raising=False)
    monkeypatch.chdir(PROJECT_ROOT)
    # a hand-runs folder no run wrote (the checkout's own runs/ may hold a robot a user
    # made by hand, which a notebook would rightly read first)
    fresh = f"{HAND_RUNS}-{os.getpid()}-never-written"
    monkeypatch.setattr("tattotronix.io.outputs.HAND_RUNS", fresh)
    out = Outputs(PIPELINE_DATA)
    assert out.by_hand and out.input("robot") == Path(PIPELINE_DATA, "robot")
    assert out.path("metrics", "x.json") == Path(fresh, "metrics", "x.json")
    assert not (PROJECT_ROOT / fresh).exists()


def _tree(folder: Path) -> dict[str, str]:
    return {p.relative_to(folder).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file()}


@pytest.fixture()
def project(tmp_path: Path) -> Path:
    """A copy of the project's code and config, with an empty pipeline data folder."""
    root = tmp_path / "project"
    root.mkdir()
    for name in ("conf", "stages", "tattotronix", "hydra_plugins"):
        shutil.copytree(ROOT / name, root / name,
                        ignore=shutil.ignore_patterns("__pycache__"))
    for name in ("params.yaml", "pyproject.toml", "dvc.yaml"):
        shutil.copy2(ROOT / name, root / name)
    (root / PIPELINE_DATA).mkdir()
    return root


def _run(root: Path, *args: str) -> subprocess.CompletedProcess[str]:
    env = {k: v for k, v in os.environ.items() if k != "DVC_STAGE"}
    env["PYTHONPATH"] = str(root)  # the copy's own code: its PROJECT_ROOT is the copy
    return subprocess.run([PYTHON, *args], cwd=root, env=env, capture_output=True,
                          text=True, timeout=600)


def test_hand_runs_and_sweeps_leave_the_pipeline_alone(project: Path) -> None:
    """The pipeline's stage outputs, made as DVC makes them, then the README's hand runs
    on top: a stage by hand and a ``-m`` sweep. The pipeline's folder is unchanged, the
    runs land under runs/, and each run says where it wrote."""
    env_dvc = {"DVC_STAGE": "robot"}
    made = subprocess.run([PYTHON, "stages/robot.py"], cwd=project, capture_output=True,
                          text=True, timeout=600,
                          env={**os.environ, **env_dvc, "PYTHONPATH": str(project)})
    assert made.returncode == 0, made.stderr
    before = _tree(project / PIPELINE_DATA)
    assert "robot/tattotronix.urdf" in before

    one = _run(project, "stages/robot.py", "robot.mass_model=box")
    assert one.returncode == 0, one.stderr
    said = one.stdout + one.stderr
    assert "robot: wrote runs/robot/tattotronix.urdf" in said, said
    assert "the pipeline's data/ is untouched" in said, said
    sweep = _run(project, "stages/robot.py", "-m", "robot.mass_model=box,printed")
    assert sweep.returncode == 0, sweep.stderr

    assert _tree(project / PIPELINE_DATA) == before
    runs = _tree(project / HAND_RUNS)
    assert "robot/tattotronix.urdf" in runs and "metrics/robot.json" in runs
    assert any(k.startswith("multirun/") for k in runs), sorted(runs)  # Hydra's own record
    assert not (project / ".hydra").exists()

    mine = _run(project, "stages/robot.py", "paths.out=data", "robot.mass_model=box")
    assert mine.returncode == 0, mine.stderr
    assert _tree(project / PIPELINE_DATA) != before  # the explicit choice does write there


def test_inputs_come_from_the_runs_by_hand_first(tmp_path: Path,
                                                 caplog: pytest.LogCaptureFixture) -> None:
    """A sweep job reads its own folder's file, then the runs' folder's, then paths.data's,
    and says once which file a run by hand wrote."""
    data, runs = tmp_path / "data", tmp_path / "runs"
    job = runs / "sweeps" / "mask.res_mm=0.1"
    for folder in (data, runs, job):
        (folder / "mask").mkdir(parents=True)
        (folder / "mask" / "a.npz").write_text(folder.name)
    (data / "mask" / "b.npz").write_text("data")
    (runs / "mask" / "b.npz").write_text("runs")
    (data / "mask" / "c.npz").write_text("data")
    out = Outputs(data, ["mask.res_mm=0.1"], root=runs)
    with caplog.at_level("INFO", logger="tattotronix"):
        assert out.input("mask", "a.npz") == job / "mask" / "a.npz"
        assert out.input("mask/a.npz") == job / "mask" / "a.npz"
        assert out.input("mask", "b.npz") == runs / "mask" / "b.npz"
        assert out.input("mask", "c.npz") == data / "mask" / "c.npz"
        assert out.input_root("mask", "b.npz") == runs
        assert out.input("mask", "d.npz") == data / "mask" / "d.npz"  # none: paths.data's
    said = [r.getMessage() for r in caplog.records]
    assert sum("a.npz, which a run by hand wrote" in m for m in said) == 1, said
    assert sum("b.npz, which a run by hand wrote" in m for m in said) == 1, said
    assert not any("c.npz" in m for m in said), said
    # inside a DVC stage the run writes where it reads: paths.data only
    dvc = Outputs(data, root=data)
    assert dvc.input("mask", "b.npz") == data / "mask" / "b.npz"


def test_stages_run_by_hand_chain(project: Path, tmp_path: Path) -> None:
    """artwork -> mask -> toolpath by hand on a PNG of the user's own: each reads what the
    one before wrote under runs/, says so, and data/ stays empty."""
    from .conftest import small_art

    png = small_art(tmp_path / "my.png")
    args = (f"artwork.source={png}", "mask.width_mm=24")
    for stage in ("artwork", "mask", "toolpath"):
        run = _run(project, f"stages/{stage}.py", *args)
        assert run.returncode == 0, run.stderr
        said = run.stdout + run.stderr
        if stage == "mask":
            assert "reading runs/artwork/my.png, which a run by hand wrote" in said, said
        if stage == "toolpath":
            assert "reading runs/mask/my.npz, which a run by hand wrote" in said, said
    runs = _tree(project / HAND_RUNS)
    for made in ("artwork/my.png", "mask/my.npz", "toolpath/my.npz",
                 "metrics/toolpath/my.json"):
        assert made in runs, sorted(runs)
    assert _tree(project / PIPELINE_DATA) == {}


def test_a_missing_input_names_the_command_that_makes_it(project: Path,
                                                         tmp_path: Path) -> None:
    """The mask stage without its artwork names the artwork command with the run's own
    overrides; that command writes the input it lacked."""
    import shlex

    from .conftest import small_art

    png = small_art(tmp_path / "my logo.png")  # a space: the command quotes it
    args = (f"artwork.source={png}", "mask.width_mm=24")
    missing = _run(project, "stages/mask.py", *args)
    assert missing.returncode == 2, missing.stdout + missing.stderr
    command = "python stages/artwork.py " + " ".join(shlex.quote(a) for a in args)
    line = missing.stderr.strip().splitlines()[-1]
    assert line == (f"mask: error: missing input data/artwork/my logo.png (nor runs/artwork/my "
                    f"logo.png, where runs by hand write): run the 'artwork' stage first: "
                    f"{command} (or dvc repro)"), line
    fix = shlex.split(command)  # the command as a shell splits it: the artwork run's own
    assert fix[1:] == ["stages/artwork.py", *args]
    assert _run(project, *fix[1:]).returncode == 0
    assert (project / HAND_RUNS / "artwork" / "my logo.png").is_file()


def test_two_files_with_one_stem_never_overwrite_or_mix(project: Path, tmp_path: Path) -> None:
    """mine.png and mine.svg are both 'mine': the second artwork run by hand was written
    over the first without a word, and a mask run for the SVG read the PNG's raster. Now
    the second is refused in one line that names artwork.name, nothing written; with a
    name of its own it runs; a mask run reads only the artwork made from its own file."""
    from .conftest import small_art

    png = small_art(tmp_path / "mine.png")
    svg = tmp_path / "mine.svg"
    svg.write_text('<svg xmlns="http://www.w3.org/2000/svg" width="24mm" height="12mm" '
                   'viewBox="0 0 24 12"><rect x="2" y="2" width="20" height="8"/></svg>')
    assert _run(project, "stages/artwork.py", f"artwork.source={png}",
                "mask.width_mm=24").returncode == 0
    before = _tree(project / HAND_RUNS)
    for stage in ("artwork", "mask"):
        run = _run(project, f"stages/{stage}.py", f"artwork.source={svg}")
        assert run.returncode == 2, run.stdout + run.stderr
        line = run.stderr.strip().splitlines()
        assert len(line) == 1 and "artwork.name=mine-svg" in line[0], run.stderr
        assert "Traceback" not in run.stdout + run.stderr
        assert _tree(project / HAND_RUNS) == before
    for stage in ("artwork", "mask"):
        run = _run(project, f"stages/{stage}.py", f"artwork.source={svg}",
                   "artwork.name=mine-svg")
        assert run.returncode == 0, run.stderr
    # a name given on purpose takes a new file (a new version of a logo)
    again = _run(project, "stages/artwork.py", f"artwork.source={svg}", "artwork.name=mine")
    assert again.returncode == 0, again.stderr


def test_same_source_compares_files_not_spellings(tmp_path: Path,
                                                  monkeypatch: pytest.MonkeyPatch) -> None:
    import json

    from tattotronix.art.artwork import check_same_source
    from tattotronix.errors import TattotronixError

    monkeypatch.chdir(tmp_path)
    (tmp_path / "a.png").write_bytes(b"x")
    (tmp_path / "a.svg").write_text("<svg/>")
    rec = tmp_path / "rec.json"
    rec.write_text(json.dumps({"source": "a.png"}))
    check_same_source(rec, str(tmp_path / "a.png"), "a", replacing=True)  # same file
    check_same_source(rec, "./a.png", "a", replacing=False)
    with pytest.raises(TattotronixError, match=r"artwork.name=a-svg"):
        check_same_source(rec, "a.svg", "a", replacing=True)
    with pytest.raises(TattotronixError, match=r"was made from a.png .*not a.svg"):
        check_same_source(rec, "a.svg", "a", replacing=False)
    rec.write_text(json.dumps({"source": "builtin:emblem"}))
    check_same_source(rec, "emblem", "emblem", replacing=False)
    check_same_source(rec, None, "emblem", replacing=False)  # the default is the emblem
    with pytest.raises(TattotronixError):
        check_same_source(rec, "lineart", "emblem", replacing=False)
    for text in ("{", "[]", json.dumps({"res_mm": 0.1})):  # nothing recorded: no check
        rec.write_text(text)
        check_same_source(rec, "a.svg", "a", replacing=True)
    check_same_source(tmp_path / "none.json", "a.svg", "a", replacing=True)
