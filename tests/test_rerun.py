"""Metrics that only move when the physics moves.

Two clean clones, set up alike for a small drawing and one case per study (one of them a
commit later, with the same code), run every stage that writes metrics at the same time
(``dvc repro``). Every output, and so ``dvc.lock``, must be byte-identical between them
(no absolute path, time of day or commit reaches a file): no wall time, rate or other
machine noise may reach a metrics file (those go to ``data/timings/``). Then a no-change
``dvc repro`` runs nothing and ``dvc metrics diff`` shows nothing.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from .conftest import ROOT, small_art

PYTHON = sys.executable
ENV = {**{k: v for k, v in os.environ.items() if k != "DVC_STAGE"}, "DVC_NO_ANALYTICS": "1",
       "HYDRA_FULL_ERROR": "0", "GIT_AUTHOR_NAME": "t", "GIT_AUTHOR_EMAIL": "t@t",
       "GIT_COMMITTER_NAME": "t", "GIT_COMMITTER_EMAIL": "t@t"}


def _env(clone: Path) -> dict[str, str]:
    """Run the clone's own code, not the checkout the tests were started from."""
    return {**ENV, "PYTHONPATH": str(clone)}


def _yaml_edit(path: Path, **changes: object) -> None:
    doc = yaml.safe_load(path.read_text())
    doc.update(changes)
    path.write_text(yaml.safe_dump(doc, sort_keys=False))


def _small_pipeline(clone: Path) -> None:
    """The pipeline of ``clone`` on a 24 mm drawing, with one case per study."""
    small_art(clone / "small.png")
    _yaml_edit(clone / "conf" / "artwork" / "default.yaml", source="small.png")
    _yaml_edit(clone / "conf" / "mask" / "default.yaml", width_mm=24.0, min_region_mm2=0.5)
    study = clone / "conf" / "study" / "default.yaml"
    doc = yaml.safe_load(study.read_text())
    doc["control"]["cases"] = {"pid_g-wn40": {"structure": "pid_g", "wn": 40.0}}
    doc.update(approach_mm=[2.0], step_mm=[0.3], rate_hz=[1000], rate_wn=[40])
    doc["kinematics"].update(reach_nx=7, reach_ny=5, workspace_samples=2000,
                             placement_widths_mm=[24.0], placement_offsets_mm=[0.0])
    study.write_text(yaml.safe_dump(doc, sort_keys=False))
    dvc = clone / "dvc.yaml"
    text = dvc.read_text()
    assert "emblem: artwork.source=emblem" in text and "study_artwork: emblem" in text
    dvc.write_text(text.replace("emblem: artwork.source=emblem", "small: artwork.source=small.png")
                   .replace("study_artwork: emblem", "study_artwork: small"))
    run = subprocess.run([PYTHON, "-m", "tattotronix.config.params"], cwd=clone,
                         env=_env(clone),
                         capture_output=True, text=True)
    assert run.returncode == 0, run.stderr


def _metrics_stages(clone: Path) -> list[str]:
    """Every stage that writes metrics from the data, so not ``certify`` (its metric is the
    documents' agreement with the emblem's metrics, which the small pipeline replaces)."""
    code = ("from dvc.repo import Repo\n"
            "print('\\n'.join(s.addressing for s in Repo('.').index.stages if s.metrics))")
    run = subprocess.run([PYTHON, "-c", code], cwd=clone, env=_env(clone),
                         capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr
    return [s for s in run.stdout.split() if s != "certify"]


def _files(folder: Path) -> dict[str, bytes]:
    return {p.relative_to(folder).as_posix(): p.read_bytes()
            for p in sorted(folder.rglob("*.json"))}


@pytest.mark.slow
def test_every_stage_writes_the_same_metrics_twice(tmp_path: Path) -> None:
    a, b = tmp_path / "a", tmp_path / "b"
    subprocess.run(["git", "clone", "-q", str(ROOT), str(a)], check=True)
    _small_pipeline(a)
    subprocess.run(["git", "add", "-A"], cwd=a, check=True, env=ENV)
    subprocess.run(["git", "commit", "-qm", "small pipeline"], cwd=a, check=True, env=ENV)
    shutil.copytree(a, b, symlinks=True)
    # b sits at another commit with the same code (as a clean clone of a later commit
    # that touched only documents does): no output may record which commit it ran at
    (b / "README.md").write_text((b / "README.md").read_text() + "\nA later edit.\n")
    subprocess.run(["git", "commit", "-qam", "a document edit"], cwd=b, check=True, env=ENV)
    stages = _metrics_stages(a)
    assert {"ik@small", "trajectory@small", "toolpath@small", "simulate@small",
            "studies"} <= set(stages), stages

    procs = [subprocess.Popen([PYTHON, "-m", "dvc", "repro", *stages], cwd=c, env=_env(c),
                              text=True, stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
             for c in (a, b)]
    for proc in procs:
        out, _ = proc.communicate(timeout=1800)
        assert proc.returncode == 0, out[-4000:]

    ma, mb = _files(a / "data" / "metrics"), _files(b / "data" / "metrics")
    assert sorted(ma) == sorted(mb)
    # every stage that writes metrics wrote here (the emblem's files were replaced)
    assert any(k.startswith("ik/small") for k in ma) and any("small" in k for k in ma)
    differ = [k for k in ma if ma[k] != mb[k]]
    assert not differ, f"metrics differ between two runs of the same inputs: {differ}"
    # the wall times went somewhere else
    assert (a / "data" / "timings" / "ik" / "small.json").is_file()
    # and every output, not only the metrics, is byte-identical: dvc.lock holds the hash
    # of each (the npz with their provenance, the figures, the animation)
    lock_a, lock_b = ((c / "dvc.lock").read_text() for c in (a, b))
    assert lock_a == lock_b, "dvc.lock differs between two clones of the same code"

    subprocess.run(["git", "add", "-A"], cwd=a, check=True, env=ENV)
    subprocess.run(["git", "commit", "-qm", "results"], cwd=a, check=True, env=ENV)
    again = subprocess.run([PYTHON, "-m", "dvc", "repro", *stages], cwd=a, env=_env(a),
                           capture_output=True, text=True, timeout=600)
    assert again.returncode == 0 and "Running stage" not in again.stdout, again.stdout
    diff = subprocess.run([PYTHON, "-m", "dvc", "metrics", "diff"], cwd=a, env=_env(a),
                          capture_output=True, text=True, timeout=300)
    assert diff.returncode == 0 and diff.stdout.strip() == "", diff.stdout
