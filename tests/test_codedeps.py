"""Code deps by construction: every stage depends on exactly the project files it runs.

The deps come from the imports (``tattotronix.devtools.codedeps``); these tests hold
dvc.yaml to them, hold the committed dvc.lock to the committed code, and show on a
clean clone that editing a module makes DVC call the stages that import it stale, and
no other stage.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from tattotronix.devtools.codedeps import CODE_PREFIXES, CodeGraph, check, code_deps, stage_deps

from .conftest import ROOT

PYTHON = sys.executable


def test_dvc_yaml_code_deps_are_the_imports_of_each_stage() -> None:
    problems = check(ROOT)
    assert not problems, ("\n".join(problems)
                          + "\nfix: python -m tattotronix.devtools.codedeps --write")


def test_every_stage_that_builds_the_robot_depends_on_its_settings() -> None:
    """The robot stage publishes the robot settings (data/robot/config.json); every other
    stage that builds the description depends on that file (or, for the robot and mass
    stages, on the `robot` params), so a robot change reruns it."""
    import yaml

    stages = yaml.safe_load((ROOT / "dvc.yaml").read_text())["stages"]
    builders = []
    for name, stage in stages.items():
        body = stage.get("do", stage)
        deps = body.get("deps", [])
        if "tattotronix/robot/description.py" not in deps and "tattotronix/robot" not in deps:
            continue
        builders.append(name)
        if name in ("robot", "mass"):
            assert "robot" in body.get("params", []), name
        else:
            assert "${paths.data}/robot/config.json" in deps, name
            assert "robot" not in body.get("params", []), name  # held once, in that file
    assert {"ik", "trajectory", "simulate", "control"} <= set(builders), builders
    assert "${paths.data}/robot/config.json" in stages["robot"]["outs"]


def test_every_package_data_file_is_a_dep_of_some_stage() -> None:
    """Non-Python files the library reads (the built-in artwork, the k-DOP table) count as
    code: a change to them must rerun the stages whose modules name them."""
    covered = {d for s in stage_deps(ROOT) for d in s.wanted}
    data = [p.relative_to(ROOT).as_posix() for p in (ROOT / "tattotronix").rglob("*")
            if p.is_file() and p.suffix not in (".py", ".pyc") and "__pycache__" not in p.parts]
    assert data, "no package data found: the scan is broken"
    for f in data:
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


def _dvc_status(clone: Path) -> dict[str, set[str]]:
    """stage -> the code deps `dvc status` calls changed (missing data is ignored: a
    clean clone has no outputs)."""
    env = {**os.environ, "DVC_NO_ANALYTICS": "1", "PYTHONPATH": str(clone)}
    env.pop("DVC_STAGE", None)
    run = subprocess.run([PYTHON, "-m", "dvc", "status", "--json"], cwd=clone, env=env,
                         capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr
    changed: dict[str, set[str]] = {}
    for stage, entries in json.loads(run.stdout or "{}").items():
        for entry in entries:
            if isinstance(entry, dict):
                for path, state in entry.get("changed deps", {}).items():
                    if path.startswith(CODE_PREFIXES) and state == "modified":
                        changed.setdefault(stage, set()).add(path)
    return changed


@pytest.fixture(scope="module")
def clone(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("codedeps") / "clone"
    subprocess.run(["git", "clone", "-q", str(ROOT), str(path)], check=True)
    return path


def test_committed_lock_was_made_by_the_committed_code(clone: Path) -> None:
    """Cached results never belong to older code: on a clean clone no stage's code dep
    differs from what dvc.lock recorded (run `dvc repro` and commit dvc.lock)."""
    stale = _dvc_status(clone)
    assert not stale, "dvc.lock is older than the code: " + "; ".join(
        f"{s}: {', '.join(sorted(p))}" for s, p in sorted(stale.items()))


@pytest.mark.parametrize("module", ["tattotronix/pipeline.py", "tattotronix/path/order.py",
                                    "tattotronix/robot/urdf.py"])
def test_editing_a_module_makes_exactly_its_importers_stale(clone: Path, module: str) -> None:
    target = clone / module
    before = target.read_text()
    try:
        target.write_text(before + "\n# an edit\n")
        stale = {s for s, paths in _dvc_status(clone).items()
                 if any(module == p or module.startswith(p + "/") for p in paths)}
    finally:
        target.write_text(before)
    importers = {s.name for s in stage_deps(clone)
                 if any(module == d or module.startswith(d + "/") for d in s.wanted)}
    assert importers, module
    # dvc names foreach stages name@key: compare on the stage part
    assert {s.split("@")[0] for s in stale} == importers
    if module == "tattotronix/pipeline.py":
        assert any(s.startswith("ik@") for s in stale)
