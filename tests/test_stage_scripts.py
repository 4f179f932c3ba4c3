"""The stage scripts and the import path: ``python stages/<name>.py`` puts ``stages/``
first on ``sys.path``, so a script named like an importable module would shadow it in
every stage; and the library never edits ``sys.path`` to undo such a thing."""

from __future__ import annotations

import ast
import json
import subprocess
from pathlib import Path

from .conftest import PYTHON, ROOT

STAGES = ROOT / "stages"


def test_no_stage_script_has_the_name_of_an_importable_module(tmp_path: Path) -> None:
    """Every ``stages/<stem>.py``: ``importlib.util.find_spec(stem)`` finds nothing when
    ``stages/`` is not on the path (run from an empty folder, as a fresh interpreter)."""
    stems = sorted(p.stem for p in STAGES.glob("*.py"))
    assert "approach" in stems and "control" not in stems
    code = ("import importlib.util, json, sys\n"
            "found = {}\n"
            "for stem in json.loads(sys.argv[1]):\n"
            "    spec = importlib.util.find_spec(stem)\n"
            "    if spec is not None:\n"
            "        found[stem] = str(spec.origin)\n"
            "print(json.dumps(found))\n")
    run = subprocess.run([PYTHON, "-c", code, json.dumps(stems)], cwd=tmp_path,
                         capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr
    assert json.loads(run.stdout) == {}, "stage scripts that shadow an importable module"


def _refers_to_sys_path(tree: ast.AST) -> list[int]:
    """Lines that name ``sys.path`` (``sys.path``, ``from sys import path``)."""
    lines = []
    for node in ast.walk(tree):
        if (isinstance(node, ast.Attribute) and node.attr == "path"
                and isinstance(node.value, ast.Name) and node.value.id == "sys"):
            lines.append(node.lineno)
        elif (isinstance(node, ast.ImportFrom) and node.module == "sys"
              and any(a.name == "path" for a in node.names)):
            lines.append(node.lineno)
    return sorted(lines)


def test_no_library_module_edits_sys_path() -> None:
    """No module of ``tattotronix`` names ``sys.path`` at all: nothing there needs to read
    it, and a name bound to it would hide an edit."""
    offenders = {}
    for path in sorted((ROOT / "tattotronix").rglob("*.py")):
        lines = _refers_to_sys_path(ast.parse(path.read_text(encoding="utf-8")))
        if lines:
            offenders[path.relative_to(ROOT).as_posix()] = lines
    assert offenders == {}


def test_the_sys_path_check_sees_an_edit() -> None:
    tree = ast.parse("import sys\nsys.path.insert(0, 'x')\nfrom sys import path\n")
    assert _refers_to_sys_path(tree) == [2, 3]


def test_a_run_by_hand_composes_its_config_once() -> None:
    """Hydra reads ``hydra.mode`` from a whole first composition before the job's; a run
    by hand answers it (``None``: the command line decides, as conf/ never sets it)
    without composing, unless an override sets ``hydra.mode``; Hydra's own comes back."""
    from hydra._internal.hydra import Hydra

    from tattotronix.stage import _one_compose

    own = Hydra.__dict__["get_mode"]
    with _one_compose(["robot.tool=none"]):
        assert Hydra.__dict__["get_mode"] is not own
        assert Hydra.get_mode(None, "config", ["no_such_key=1"]) is None  # type: ignore[arg-type]
    assert Hydra.__dict__["get_mode"] is own
    with _one_compose(["hydra.mode=MULTIRUN"]):
        assert Hydra.__dict__["get_mode"] is own
    # what the skipped composition would have read: conf/ leaves hydra.mode unset
    from hydra import compose, initialize_config_dir

    with initialize_config_dir(config_dir=str(ROOT / "conf"), version_base="1.3"):
        cfg = compose(config_name="config", return_hydra_config=True)
    assert cfg.hydra.mode is None
