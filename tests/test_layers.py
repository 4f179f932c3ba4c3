"""The application layer's boundary (issue 31): below ``tattotronix.app`` no library
function takes the root ``Config``. Each domain takes its own settings (a config group's
dataclass, ``ToolpathConfig``, ``DrawConfig``, ...) or plain values; the application reads
the root settings and hands each domain its part. The ``config`` package itself (the
schema and the composition of the settings) is where the root lives.
"""

from __future__ import annotations

import ast
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "tattotronix"


def _layers() -> list[list[str]]:
    contract = next(c for c in tomllib.loads((ROOT / "pyproject.toml").read_text())[
        "tool"]["importlinter"]["contracts"] if c["id"] == "layers")
    return [[p.strip() for p in layer.split("|")] for layer in contract["layers"]]


def _below_app() -> list[str]:
    layers = _layers()
    at = next(i for i, layer in enumerate(layers) if "app" in layer)
    return [p for layer in layers[at + 1:] for p in layer if p != "config"]


def _root_config_params(path: Path) -> list[str]:
    found = []
    for node in ast.walk(ast.parse(path.read_text())):
        if not isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            continue
        args = node.args
        for arg in [*args.posonlyargs, *args.args, *args.kwonlyargs]:
            ann = ast.unparse(arg.annotation) if arg.annotation is not None else ""
            if ann.strip("'\"") in ("Config", "Config | None", "DictConfig"):
                found.append(f"{path.relative_to(ROOT)}:{node.lineno} {node.name}({arg.arg})")
    return found


def test_the_layers_name_the_app_between_the_domains_and_the_stages() -> None:
    names = [p for layer in _layers() for p in layer]
    assert names.index("app") < names.index("hardware") < names.index("control")
    assert names.index("studies") < names.index("app") and names.index("stage") < names.index(
        "app")
    assert "pipeline" not in names  # the pipeline in one process is a use case: app's


def test_no_function_below_the_app_takes_the_root_config() -> None:
    below = _below_app()
    assert {"hardware", "control", "plants", "trajectory", "path", "kinematics"} <= set(below)
    offenders = [hit for pkg in below
                 for path in sorted((PACKAGE / pkg).rglob("*.py")) if (PACKAGE / pkg).is_dir()
                 for hit in _root_config_params(path)]
    offenders += [hit for pkg in below if (PACKAGE / f"{pkg}.py").is_file()
                  for hit in _root_config_params(PACKAGE / f"{pkg}.py")]
    assert not offenders, ("functions below the application layer that take the root "
                           "Config (give them their own settings):\n" + "\n".join(offenders))


def test_the_scan_finds_a_root_config_parameter(tmp_path: Path) -> None:
    probe = PACKAGE / "app" / "simulate.py"  # the app takes it, by design
    assert any("run_closed_loop(cfg)" in hit for hit in _root_config_params(probe))
