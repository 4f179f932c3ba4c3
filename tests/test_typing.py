"""Typed settings at the library's boundary.

* No public signature of the library (a function, method, class attribute or type alias
  whose name has no leading underscore, in ``tattotronix/``) uses ``typing.Any``, unless
  a third-party type forces it and the line says so with an allow-comment ``# Any: why``.
* The stage runner's settings (``tattotronix.config.params.to_settings``) are typed,
  frozen and equal to the composed config.
"""

from __future__ import annotations

import ast
import dataclasses
from collections.abc import Iterator
from pathlib import Path

import pytest
from omegaconf import OmegaConf

from tattotronix.config.params import compose, compose_settings, to_settings
from tattotronix.config.schema import CollisionConfig, Config, IkConfig, to_dict

PACKAGE = Path(__file__).resolve().parents[1] / "tattotronix"
ALLOW = "# Any:"  # the allow-comment, on a line of the annotation: "# Any: <the reason>"


def _public(name: str) -> bool:
    return not name.startswith("_") or (name.startswith("__") and name.endswith("__"))


def _uses_any(node: ast.expr | None) -> bool:
    if node is None:
        return False
    for n in ast.walk(node):
        if isinstance(n, ast.Name) and n.id == "Any":
            return True
        if isinstance(n, ast.Attribute) and n.attr == "Any":
            return True
        if isinstance(n, ast.Constant) and isinstance(n.value, str):  # a string annotation
            try:
                if _uses_any(ast.parse(n.value, mode="eval").body):
                    return True
            except SyntaxError:
                continue
    return False


def _signatures(tree: ast.Module) -> Iterator[tuple[str, ast.expr]]:
    """(what, annotation) of every public signature: parameters and returns of public
    functions and methods, annotated attributes of public classes, public module-level
    annotations and type aliases."""

    def body(stmts: list[ast.stmt], owner: str) -> Iterator[tuple[str, ast.expr]]:
        for st in stmts:
            if isinstance(st, ast.FunctionDef | ast.AsyncFunctionDef) and _public(st.name):
                name = f"{owner}{st.name}"
                a = st.args
                for arg in (*a.posonlyargs, *a.args, *a.kwonlyargs, a.vararg, a.kwarg):
                    if arg is not None and arg.annotation is not None:
                        yield f"{name}({arg.arg})", arg.annotation
                if st.returns is not None:
                    yield f"{name} -> return", st.returns
            elif isinstance(st, ast.ClassDef) and _public(st.name):
                yield from body(st.body, f"{owner}{st.name}.")
            elif (isinstance(st, ast.AnnAssign) and isinstance(st.target, ast.Name)
                  and _public(st.target.id)):
                yield f"{owner}{st.target.id}", st.annotation
                if st.value is not None and "TypeAlias" in ast.unparse(st.annotation):
                    yield f"{owner}{st.target.id} (alias)", st.value
            elif (not owner and isinstance(st, ast.Assign) and len(st.targets) == 1
                  and isinstance(st.targets[0], ast.Name) and _public(st.targets[0].id)
                  and isinstance(st.value, ast.Subscript | ast.BinOp)):
                yield f"{st.targets[0].id} (alias)", st.value  # Cases = Mapping[str, Any]

    yield from body(tree.body, "")


def any_in_public_signatures(root: Path = PACKAGE) -> list[str]:
    """``path:line what`` for every public signature using ``Any`` with no allow-comment."""
    found = []
    for path in sorted(root.rglob("*.py")):
        text = path.read_text(encoding="utf-8")
        lines = text.splitlines()
        for what, node in _signatures(ast.parse(text)):
            if not _uses_any(node):
                continue
            span = lines[node.lineno - 1:(node.end_lineno or node.lineno)]
            if not any(ALLOW in line for line in span):
                found.append(f"{path.relative_to(root.parent)}:{node.lineno} {what}")
    return found


def test_no_any_in_public_signatures() -> None:
    found = any_in_public_signatures()
    assert not found, (
        "public signatures using typing.Any (type them; only a third-party type that "
        f"forces Any may stay, with '{ALLOW} <which type>' on the line):\n  "
        + "\n  ".join(found))


def test_the_scan_finds_any_and_honours_the_allow_comment(tmp_path: Path) -> None:
    pkg = tmp_path / "tattotronix"
    pkg.mkdir()
    (pkg / "m.py").write_text(
        "from typing import Any\n"
        "Alias = dict[str, Any]\n"
        "def f(x: Any, y: int) -> int: ...\n"
        "def g() -> 'list[Any]': ...\n"
        "def h() -> Any:  # Any: foo.Bar (foo ships no stubs)\n    ...\n"
        "def _private(x: Any) -> Any: ...\n"
        "class C:\n"
        "    a: Any\n"
        "    _b: Any\n"
        "    def m(self, *args: Any, **kw: int) -> None:\n"
        "        def inner(z: Any) -> Any: ...\n")
    assert [s.split(" ", 1)[1] for s in any_in_public_signatures(pkg)] == [
        "Alias (alias)", "f(x)", "g -> return", "C.a", "C.m(args)"]


# ------------------------------------------------------------------------ the settings


def test_settings_are_typed_frozen_and_equal_the_composition() -> None:
    cfg = compose(["ik.dls_lambda=0.002", "collision.margin_mm=2.5"])
    s = to_settings(cfg)
    assert isinstance(s, Config) and isinstance(s.ik, IkConfig)
    assert s.ik.dls_lambda == 0.002 and s.collision.margin_m == 2.5 / 1000
    with pytest.raises(dataclasses.FrozenInstanceError):
        s.ik.dls_lambda = 1.0  # type: ignore[misc]
    with pytest.raises(dataclasses.FrozenInstanceError):
        s.speed = 2.0  # type: ignore[misc]
    # provenance from the settings is what it was from the DictConfig
    assert to_dict(s) == OmegaConf.to_container(cfg, resolve=True, enum_to_str=True)
    assert dataclasses.replace(s.ik, dls_lambda=0.5).dls_lambda == 0.5  # a changed copy


def test_units_are_converted_once_in_the_settings() -> None:
    s = compose_settings()
    assert CollisionConfig(margin_mm=1.5, resolution_mm=0.2).margin_m == 1.5 / 1000
    assert s.collision.resolution_m == s.collision.resolution_mm / 1000
    assert s.toolpath.clearance_m == s.toolpath.clearance_mm / 1000
    assert s.trajectory.lifts_m == [h / 1000 for h in s.trajectory.lifts_mm]
    assert s.robot.panel.size_mm == (s.robot.panel.size[0] * 1e3, s.robot.panel.size[1] * 1e3)


def test_the_ik_lambda_is_not_called_damping() -> None:
    """``ik.dls_lambda`` (the IK's lambda) and ``plant.damping`` (joint friction) are two
    keys with two names."""
    s = compose_settings()
    assert not hasattr(s.ik, "damping") and s.ik.dls_lambda == 1e-3
    assert s.plant.damping == 0.0
