"""Code deps by construction: every stage reruns exactly when the files it runs change.

The code a stage runs comes from the imports (``tattotronix.io.codegraph``); each stage
depends on its stamp, which the ``code`` stage writes (``tattotronix.devtools.codedeps``).
These tests hold dvc.yaml to that, hold the committed stamps and dvc.lock to the
committed code, and show on a clean clone that editing a module makes DVC call the
stages that import it stale, and no other stage.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from tattotronix.devtools.codedeps import (
    CODE_STAGE,
    CodeGraph,
    check,
    code_deps,
    stage_deps,
    stale,
    stamps,
)
from tattotronix.io.codegraph import version_of_stamp
from tattotronix.io.provenance import _entry_version

from .conftest import ROOT

PYTHON = sys.executable


def test_every_stage_depends_on_its_stamp_and_on_no_code_file() -> None:
    problems = check(ROOT)
    assert not problems, ("\n".join(problems)
                          + "\nfix: python -m tattotronix.devtools.codedeps --write")


def test_the_committed_stamps_are_the_code_as_committed() -> None:
    """data/code/<stage>.txt is what the code stage writes from this very code (so a
    clean clone's dvc repro finds the code stage up to date)."""
    assert not stale(ROOT / "data" / "code", ROOT), (
        "stale stamps: run dvc repro (the code stage) and commit data/code")
    assert sorted(p.stem for p in (ROOT / "data" / "code").glob("*.txt")) == sorted(stamps(ROOT))


def test_a_stamp_lists_every_file_the_stage_runs_and_is_its_code_version() -> None:
    fresh = stamps(ROOT)
    draw = fresh["simulate"].splitlines()
    paths = [line.split("  ", 1)[1] for line in draw]
    assert paths == sorted(paths) and "stages/draw.py" in paths
    assert "tattotronix/plants/mujoco_plant.py" in paths and "stages/robot.py" not in paths
    assert all(len(line.split("  ", 1)[0]) == 64 for line in draw)  # sha256sum's format
    # the code version every output of the stage records is the stamp's hash
    assert _entry_version(ROOT, ROOT / "stages" / "draw.py", None) == version_of_stamp(
        fresh["simulate"])
    assert version_of_stamp(fresh["simulate"]) != version_of_stamp(fresh["robot"])


def test_every_stage_that_builds_the_robot_depends_on_its_settings() -> None:
    """The robot stage publishes the robot settings (data/robot/config.json); every other
    stage that builds the description depends on that file (or, for the robot and mass
    stages, on the `robot` params), so a robot change reruns it."""
    import yaml

    stages = yaml.safe_load((ROOT / "dvc.yaml").read_text())["stages"]
    builders = []
    for s in stage_deps(ROOT):
        if not any(d in ("tattotronix/robot/description.py", "tattotronix/robot")
                   for d in s.wanted):
            continue
        builders.append(s.name)
        body = stages[s.name].get("do", stages[s.name])
        if s.name in ("robot", "mass"):
            assert "robot" in body.get("meta", {}).get("params", []), s.name
        else:
            assert "${paths.data}/robot/config.json" in s.deps, s.name
            # held once, in that file
            assert "robot" not in body.get("meta", {}).get("params", []), s.name
    assert {"ik", "trajectory", "simulate", "control"} <= set(builders), builders
    assert "${paths.data}/robot/config.json" in stages["robot"]["outs"]


def test_every_package_data_file_is_a_dep_of_some_stage() -> None:
    """Non-Python files the library reads (the built-in artwork, the k-DOP table) count as
    code: a change to them must rerun the stages whose modules name them. A subpackage no
    stage runs (the job server's page) is no stage's code."""
    covered = {d for s in stage_deps(ROOT) for d in s.wanted}
    data = [p.relative_to(ROOT).as_posix() for p in (ROOT / "tattotronix").rglob("*")
            if p.is_file() and p.suffix not in (".py", ".pyc") and "__pycache__" not in p.parts]
    assert data, "no package data found: the scan is broken"
    for f in data:
        package = "/".join(f.split("/")[:2]) + "/"  # tattotronix/<subpackage>/
        if not any(d.startswith(package) for d in covered):
            assert f.startswith("tattotronix/server/"), f"{f}: no stage runs {package}"
            continue
        assert any(f == d or f.startswith(d + "/") for d in covered), f


def _tree(root: Path, files: dict[str, str]) -> None:
    for rel, text in files.items():
        path = root / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(textwrap.dedent(text))


def test_closure_follows_every_runtime_import_and_nothing_else(tmp_path: Path) -> None:
    _tree(tmp_path, {
        "stages/s.py": """
            from tattotronix.a import f
            def main():
                import tattotronix.lazy
        """,
        "tattotronix/__init__.py": "",
        "tattotronix/a.py": """
            from typing import TYPE_CHECKING
            from .sub import helper
            if TYPE_CHECKING:
                from tattotronix.typing_only import T
            def f():
                from tattotronix.sub.deep import g
            DATA = "table.json"
        """,
        "tattotronix/table.json": "{}",
        "tattotronix/unused.py": "",
        "tattotronix/lazy.py": "",
        "tattotronix/typing_only.py": "",
        "tattotronix/sub/__init__.py": "",
        "tattotronix/sub/helper.py": "",
        "tattotronix/sub/deep.py": "import hydra\n",
        "hydra_plugins/p/__init__.py": "from tattotronix.sub import helper\n",
    })
    deps = code_deps("python stages/s.py x=1", CodeGraph(tmp_path))
    assert deps == ["hydra_plugins", "stages/s.py", "tattotronix/__init__.py",
                    "tattotronix/a.py", "tattotronix/lazy.py", "tattotronix/sub",
                    "tattotronix/table.json"]
    # -m runs the module and the packages above it
    assert code_deps("python -m tattotronix.lazy", CodeGraph(tmp_path)) == [
        "tattotronix/__init__.py", "tattotronix/lazy.py"]


def _run(clone: Path, *argv: str) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "DVC_NO_ANALYTICS": "1", "PYTHONPATH": str(clone)}
    env.pop("DVC_STAGE", None)
    return subprocess.run([PYTHON, *argv], cwd=clone, env=env, capture_output=True,
                          text=True, timeout=300)


def _dvc_status(clone: Path) -> dict[str, set[str]]:
    """stage -> the deps `dvc status` calls modified (missing data is ignored: a clean
    clone has no outputs)."""
    run = _run(clone, "-m", "dvc", "status", "--json")
    assert run.returncode == 0, run.stderr
    changed: dict[str, set[str]] = {}
    for stage, entries in json.loads(run.stdout or "{}").items():
        for entry in entries:
            if isinstance(entry, dict):
                for path, state in entry.get("changed deps", {}).items():
                    if state == "modified":
                        changed.setdefault(stage, set()).add(path)
    return changed


@pytest.fixture(scope="module")
def clone(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("codedeps") / "clone"
    subprocess.run(["git", "clone", "-q", str(ROOT), str(path)], check=True)
    return path


def test_committed_lock_was_made_by_the_committed_code(clone: Path) -> None:
    """Cached results never belong to older code: on a clean clone the code stage's
    folders are as dvc.lock recorded them, and no stage's stamp differs (run `dvc repro`
    and commit dvc.lock and data/code)."""
    changed = _dvc_status(clone)
    assert CODE_STAGE not in changed, changed.get(CODE_STAGE)
    stamped = {s: p for s, p in changed.items() if any("/code/" in d for d in p)}
    assert not stamped, "dvc.lock is older than the code: " + "; ".join(
        f"{s}: {', '.join(sorted(p))}" for s, p in sorted(stamped.items()))


@pytest.mark.parametrize("module", ["tattotronix/app/pipeline.py", "tattotronix/path/order.py",
                                    "tattotronix/robot/urdf.py"])
def test_editing_a_module_makes_exactly_its_importers_stale(clone: Path, module: str) -> None:
    target = clone / module
    before = target.read_text()
    importers = {s.name for s in stage_deps(clone)
                 if any(module == d or module.startswith(d + "/") for d in s.wanted)}
    assert importers, module
    try:
        target.write_text(before + "\n# an edit\n")
        # DVC sees the code folders changed: the code stage reruns first
        assert CODE_STAGE in _dvc_status(clone)
        # which restamps exactly the importers, and DVC then calls exactly those stale
        said = _run(clone, "-m", "tattotronix.devtools.codedeps", "--status")
        assert said.returncode == 0, said.stderr
        named = set(said.stdout.split("code changed for ", 1)[1].split(" (")[0].split(", "))
        assert named == importers
        assert _run(clone, "-m", "tattotronix.devtools.codedeps", "--stamp",
                    "data/code").returncode == 0
        stale_now = {s for s, paths in _dvc_status(clone).items()
                     if any(p.startswith("data/code/") for p in paths)}
    finally:
        target.write_text(before)
        _run(clone, "-m", "tattotronix.devtools.codedeps", "--stamp", "data/code")
    # dvc names foreach stages name@key: compare on the stage part
    assert {s.split("@")[0] for s in stale_now} == importers
    # the edit undone and restamped: no stamp is stale any more (a clone without the
    # pipeline's outputs has other changed deps: data/figures, partly in git)
    assert not {s: p for s, p in _dvc_status(clone).items()
                if s == CODE_STAGE or any(d.startswith("data/code/") for d in p)}
    if module == "tattotronix/app/pipeline.py":
        assert any(s.startswith("ik@") for s in stale_now)
