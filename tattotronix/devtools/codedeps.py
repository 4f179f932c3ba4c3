"""The code each DVC stage runs, found from the imports themselves.

A stage's code deps in ``dvc.yaml`` are the project files its entry point executes: the
script (``python stages/<name>.py``) or module (``python -m tattotronix.config.params``),
every project module it imports (at module level or inside a function; imports under
``if TYPE_CHECKING:`` never run and do not count), the ``__init__.py`` of every package on
the way, the package data a module names (``assets``, ``kdop.json``), and, when anything
imports Hydra, the plugins under ``hydra_plugins/`` that Hydra imports at start-up. The
list is exact: a change to a file reruns the stages that execute it and no other. Where
every file under a folder is in the list, the folder stands for them.

    python -m tattotronix.devtools.codedeps --check   # exit 1, naming the stage and files
    python -m tattotronix.devtools.codedeps --write   # rewrite the code deps in dvc.yaml

Data deps (``${paths.data}/...``, ``conf``, ``README.md``, ...) are left as they are.
"""

from __future__ import annotations

import argparse
import ast
import shlex
import sys
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

__all__ = ["CodeGraph", "StageDeps", "check", "code_deps", "stage_deps", "write"]

ROOT = Path(__file__).resolve().parents[2]
#: importable project packages (their files are code deps when executed)
PACKAGES = ("tattotronix", "hydra_plugins")
#: a dep that starts with one of these is code, owned by this tool
CODE_PREFIXES = ("stages/", "tattotronix", "hydra_plugins")
#: top-level import names that make Hydra import every plugin module at start-up
PLUGIN_HOSTS = ("hydra",)
_SKIP = ("__pycache__",)


def _is_type_checking(test: ast.expr) -> bool:
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING")


def _runtime_nodes(tree: ast.AST) -> Iterator[ast.AST]:
    """Every node of ``tree`` except the bodies of ``if TYPE_CHECKING:``."""
    stack = [tree]
    while stack:
        node = stack.pop()
        yield node
        if isinstance(node, ast.If) and _is_type_checking(node.test):
            stack.extend(node.orelse)
            continue
        stack.extend(ast.iter_child_nodes(node))


@dataclass(frozen=True)
class _Module:
    name: str
    path: Path
    is_package: bool
    imports: frozenset[str]  # dotted names as written (resolved when relative)
    strings: frozenset[str]  # string constants (to find the package data a module names)


class CodeGraph:
    """The project's modules and what each one imports, read from the source."""

    def __init__(self, root: Path = ROOT):
        self.root = root
        self.modules: dict[str, _Module] = {}
        for package in PACKAGES:
            for path in sorted((root / package).rglob("*.py")):
                if any(part in _SKIP for part in path.parts):
                    continue
                rel = path.relative_to(root).with_suffix("")
                parts = list(rel.parts)
                is_pkg = parts[-1] == "__init__"
                if is_pkg:
                    parts = parts[:-1]
                name = ".".join(parts)
                self.modules[name] = self._read(name, path, is_pkg)

    def _read(self, name: str, path: Path, is_pkg: bool) -> _Module:
        tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
        package = name if is_pkg else name.rpartition(".")[0]
        found: set[str] = set()
        strings: set[str] = set()
        for node in _runtime_nodes(tree):
            if isinstance(node, ast.Import):
                found.update(alias.name for alias in node.names)
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    anchor = package.split(".")
                    anchor = anchor[: len(anchor) - node.level + 1]
                    base = ".".join([*anchor, base] if base else anchor)
                found.add(base)
                found.update(f"{base}.{alias.name}" for alias in node.names)
            elif isinstance(node, ast.Constant) and isinstance(node.value, str):
                strings.add(node.value)
        return _Module(name, path, is_pkg, frozenset(found), frozenset(strings))

    def _executed(self, dotted: str) -> list[str]:
        """The project modules that ``import dotted`` runs: every package on the way."""
        parts = dotted.split(".")
        return [m for i in range(1, len(parts) + 1)
                if (m := ".".join(parts[:i])) in self.modules]

    def _package_data(self, module: _Module) -> set[Path]:
        """Non-Python files and folders beside ``module`` that it names in a string."""
        folder = module.path.parent
        return {p for p in folder.iterdir()
                if p.name in module.strings and p.suffix != ".py" and p.name not in _SKIP
                and not (p.is_dir() and any(p.rglob("*.py")))}

    def closure(self, entry: Path, entry_imports: Iterable[str] = ()) -> set[Path]:
        """Every project file that running ``entry`` executes (``entry`` included)."""
        files = {entry}
        todo: list[str] = []
        if entry.suffix == ".py" and entry.is_file():
            tree = ast.parse(entry.read_text(encoding="utf-8"), filename=str(entry))
            for node in _runtime_nodes(tree):
                if isinstance(node, ast.Import):
                    todo.extend(alias.name for alias in node.names)
                elif isinstance(node, ast.ImportFrom) and node.module and not node.level:
                    todo.append(node.module)
                    todo.extend(f"{node.module}.{alias.name}" for alias in node.names)
        todo.extend(entry_imports)
        seen: set[str] = set()
        plugins = False
        while todo:
            dotted = todo.pop()
            if dotted.split(".")[0] in PLUGIN_HOSTS:
                plugins = True
            for name in self._executed(dotted):
                if name in seen:
                    continue
                seen.add(name)
                mod = self.modules[name]
                files.add(mod.path)
                files.update(self._package_data(mod))
                todo.extend(mod.imports)
            if plugins and not any(m.startswith("hydra_plugins.") for m in seen):
                todo.extend(m for m in self.modules if m.startswith("hydra_plugins."))
        return files

    def all_files(self, folder: Path) -> set[Path]:
        """Every file under ``folder`` that can be a code dep (no caches)."""
        return {p for p in folder.rglob("*")
                if p.is_file() and not any(part in _SKIP for part in p.parts)}


def _collapse(root: Path, graph: CodeGraph, files: set[Path]) -> list[str]:
    """``files`` as dvc.yaml paths, with a folder standing for all of its files."""
    out: list[str] = []
    remaining = set(files)
    folders = sorted({p.parent for p in files if root in p.parents}
                     | {q for p in files for q in p.parents if root in q.parents},
                     key=lambda p: len(p.parts))
    for folder in folders:
        if folder.parent == root and folder.name == "stages":
            continue  # stages/ holds one entry point per stage: never all of them
        inside = graph.all_files(folder)
        if inside and inside <= remaining:
            out.append(folder.relative_to(root).as_posix())
            remaining -= inside
    out.extend(p.relative_to(root).as_posix() for p in remaining)
    return sorted(out)


def entry_of(cmd: str, root: Path = ROOT) -> tuple[Path, list[str]] | None:
    """The file a stage command runs, and the module it names when run with ``-m``."""
    argv = shlex.split(cmd)
    if len(argv) < 2 or Path(argv[0]).name not in ("python", "python3"):
        return None
    if argv[1] == "-m":
        module = argv[2]
        base = root.joinpath(*module.split("."))
        path = base / "__init__.py" if base.is_dir() else base.with_suffix(".py")
        return path, [module]
    return root / argv[1], []


def code_deps(cmd: str, graph: CodeGraph) -> list[str] | None:
    """The code deps of a stage command, as dvc.yaml paths (None: not a Python command)."""
    entry = entry_of(cmd, graph.root)
    if entry is None:
        return None
    path, modules = entry
    if not path.is_file():
        raise SystemExit(f"codedeps: {cmd!r} runs {path}, which does not exist")
    return _collapse(graph.root, graph, graph.closure(path, modules))


@dataclass
class StageDeps:
    """One stage of dvc.yaml: its code deps as written and as its imports say."""

    name: str
    written: list[str]
    wanted: list[str]

    @property
    def missing(self) -> list[str]:
        return [d for d in self.wanted if d not in self.written]

    @property
    def extra(self) -> list[str]:
        return [d for d in self.written if d not in self.wanted]


def _is_code(dep: object) -> bool:
    return isinstance(dep, str) and dep.startswith(CODE_PREFIXES)


def _stage_bodies(doc: dict[str, Any]) -> Iterator[tuple[str, dict[str, Any]]]:
    for name, stage in doc["stages"].items():
        yield name, (stage["do"] if "do" in stage else stage)


def stage_deps(root: Path = ROOT) -> list[StageDeps]:
    """Every stage of ``root/dvc.yaml`` that runs Python, with written and wanted deps."""
    from ruamel.yaml import YAML

    doc = YAML().load((root / "dvc.yaml").read_text(encoding="utf-8"))
    graph = CodeGraph(root)
    out = []
    for name, body in _stage_bodies(doc):
        wanted = code_deps(str(body["cmd"]), graph)
        if wanted is None:
            continue
        written = [str(d) for d in body.get("deps", []) if _is_code(d)]
        out.append(StageDeps(name, written, wanted))
    return out


def check(root: Path = ROOT) -> list[str]:
    """One line per stage whose code deps in dvc.yaml differ from its imports."""
    problems = []
    for s in stage_deps(root):
        parts = []
        if s.missing:
            parts.append("missing " + ", ".join(s.missing))
        if s.extra:
            parts.append("not executed " + ", ".join(s.extra))
        if parts:
            problems.append(f"stage '{s.name}': " + "; ".join(parts))
    return problems


def write(root: Path = ROOT) -> int:
    """Rewrite the code deps of every Python stage in ``root/dvc.yaml``; the count changed."""
    from ruamel.yaml import YAML

    yaml = YAML()
    yaml.indent(mapping=2, sequence=4, offset=2)
    yaml.width = 4096
    path = root / "dvc.yaml"
    doc = yaml.load(path.read_text(encoding="utf-8"))
    graph = CodeGraph(root)
    changed = 0
    for _, body in _stage_bodies(doc):
        wanted = code_deps(str(body["cmd"]), graph)
        if wanted is None:
            continue
        deps = body.get("deps")
        data = [d for d in deps if not _is_code(d)] if deps is not None else []
        written = [str(d) for d in deps if _is_code(d)] if deps is not None else []
        if written == wanted:
            continue
        changed += 1
        if deps is None:
            body["deps"] = wanted
            continue
        deps.clear()
        deps.extend([*data, *wanted])
    if changed:
        with path.open("w", encoding="utf-8") as fh:
            yaml.dump(doc, fh)
    return changed


def main(argv: list[str] | None = None) -> int:
    """``--check`` (exit 1 on any difference) or ``--write``."""
    ap = argparse.ArgumentParser(prog="python -m tattotronix.devtools.codedeps",
                                 description=__doc__.split("\n\n")[0])
    mode = ap.add_mutually_exclusive_group(required=True)
    mode.add_argument("--check", action="store_true", help="compare dvc.yaml with the imports")
    mode.add_argument("--write", action="store_true", help="rewrite the code deps in dvc.yaml")
    args = ap.parse_args(argv)
    if args.write:
        n = write()
        print(f"codedeps: {n} stage(s) rewritten in dvc.yaml" if n else
              "codedeps: dvc.yaml is up to date")
        return 0
    problems = check()
    for line in problems:
        print(line, file=sys.stderr)
    if problems:
        print("codedeps: run python -m tattotronix.devtools.codedeps --write", file=sys.stderr)
        return 1
    print("codedeps: every stage's code deps match its imports")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
