"""The code version an output records is a function of the source alone: the same for
any number of workers, any order they finish in, and any module a worker happened to
import lazily (issue: a fresh clone's servo study differed from the committed one)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from tattotronix.devtools.codedeps import stamps
from tattotronix.io.codegraph import version_of_stamp
from tattotronix.io.provenance import CODE_VERSION_ENV, code_version, fixed_code_version

from .conftest import ROOT, stage_env

PYTHON = sys.executable
SMALL = ["mask.width_mm=24", "mask.min_region_mm2=0.5"]


def _files(folder: Path) -> dict[str, bytes]:
    return {p.relative_to(folder).as_posix(): p.read_bytes()
            for p in sorted(folder.rglob("*")) if p.is_file()}


def _study(data: Path, out: Path, cpus: set[int] | None) -> subprocess.CompletedProcess[str]:
    """The approach study's cases at once (a pool of one worker per CPU it may use)."""
    def pin() -> None:
        if cpus is not None:
            os.sched_setaffinity(0, cpus)

    argv = [PYTHON, "stages/approach.py", f"paths.data={data}", f"paths.out={out}",
            f"artwork.source={data.parent / 'small.png'}", "draw.progress=false",
            "study.all_cases=true", "study.approach_mm=[0.0,2.0,4.0]", *SMALL]
    env = stage_env()
    env.pop(CODE_VERSION_ENV, None)
    return subprocess.run(argv, cwd=ROOT, env=env, capture_output=True, text=True,
                          timeout=900, preexec_fn=pin)


@pytest.mark.slow
@pytest.mark.skipif(not hasattr(os, "sched_setaffinity") or len(os.sched_getaffinity(0)) < 2,
                    reason="needs two CPUs to compare one worker with two")
def test_study_outputs_are_identical_for_any_worker_count(draw_data: Path, tmp_path: Path
                                                         ) -> None:
    out = tmp_path / "out"  # one folder for both: a run by hand records where it wrote
    one = _study(draw_data, out, {min(os.sched_getaffinity(0))})
    assert one.returncode == 0, one.stderr[-3000:]
    out.rename(tmp_path / "one")
    two = _study(draw_data, out, None)
    assert two.returncode == 0, two.stderr[-3000:]
    a, b = _files(tmp_path / "one"), _files(out)
    assert sorted(a) == sorted(b) and len(a) >= 6, sorted(a)
    differ = [name for name in a if a[name] != b[name]]
    assert not differ, differ
    # and what they record is the stamp of the stage's code
    case = next(p for p in (tmp_path / "one").rglob("*.npz"))
    with np.load(case) as z:
        prov = json.loads(str(z["provenance"]))
    assert prov["code_version"] == version_of_stamp(stamps(ROOT)["approach"])


def test_code_version_is_fixed_for_the_run_and_its_workers() -> None:
    with fixed_code_version("sha256:feed") as version:
        assert version == code_version() == "sha256:feed"
        out = subprocess.run([PYTHON, "-c", "from tattotronix.io.provenance import "
                              "code_version; print(code_version())"],
                             capture_output=True, text=True, check=True)
        assert out.stdout.strip() == "sha256:feed"  # a child process records the same
    assert code_version() != "sha256:feed"


def test_a_lazy_import_does_not_move_the_code_version_of_an_entry_point() -> None:
    """Run as a stage does (a script under stages/), the version is the stamp of the
    script's static closure, however many project modules the process has imported."""
    script = ("import runpy, sys; sys.argv = ['stages/robot.py']; "
              "from tattotronix.io.provenance import code_version as v; "
              "import __main__; __main__.__file__ = 'stages/robot.py'; a = v(); "
              "import tattotronix.plants.mujoco_plant; v.__globals__['_entry_version']"
              ".cache_clear(); print(a == v(), a)")
    env = {k: v for k, v in os.environ.items() if k != CODE_VERSION_ENV}
    out = subprocess.run([PYTHON, "-c", script], cwd=ROOT, env=env, capture_output=True,
                         text=True, check=True)
    same, version = out.stdout.split()
    assert same == "True"
    assert version == version_of_stamp(stamps(ROOT)["robot"])


def test_parsed_imports_are_kept_between_processes_and_a_bad_entry_is_read_again(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The closure read through the cache of parsed imports is the closure parsed from the
    source: filled, read back, with a corrupt entry, and with no cache at all."""
    from tattotronix.io import codegraph

    root = Path(__file__).resolve().parents[1]
    entry = root / "stages" / "draw.py"
    monkeypatch.setenv("TATTOTRONIX_CODEGRAPH_CACHE", "0")
    parsed = codegraph.CodeGraph(root).closure(entry)
    monkeypatch.setenv("TATTOTRONIX_CODEGRAPH_CACHE", "1")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    assert codegraph.CodeGraph(root).closure(entry) == parsed  # filled
    kept = sorted((tmp_path / "tattotronix").rglob("*.json"))
    assert len(kept) >= len([p for p in parsed if p.suffix == ".py"])
    assert codegraph.CodeGraph(root).closure(entry) == parsed  # read back
    for p in kept:
        p.write_text("not json")
    assert codegraph.CodeGraph(root).closure(entry) == parsed  # parsed again
    assert json.loads(kept[0].read_text())  # and kept again
    blocked = tmp_path / "a-file"
    blocked.write_text("")
    monkeypatch.setenv("XDG_CACHE_HOME", str(blocked))  # no cache can be made there
    assert codegraph.CodeGraph(root).closure(entry) == parsed
