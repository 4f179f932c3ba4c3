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
    out = Outputs(PIPELINE_DATA)
    assert out.by_hand and out.input("robot") == Path(PIPELINE_DATA, "robot")
    assert out.path("metrics", "x.json") == Path(HAND_RUNS, "metrics", "x.json")


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
