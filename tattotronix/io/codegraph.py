"""The code a stage runs, found from the imports themselves, and its stamp.

A stage's code is the set of project files its entry point executes: the script
(``python stages/<name>.py``) or module (``python -m tattotronix.config.params``), every
project module it imports (at module level or inside a function; imports under
``if TYPE_CHECKING:`` never run and do not count), the ``__init__.py`` of every package on
the way, the package data a module names (``assets``, ``kdop.json``), and, when anything
imports Hydra, the plugins under ``hydra_plugins/`` that Hydra imports at start-up.

Its **stamp** is one line per file, ``<sha256>  <path>`` (``sha256sum``'s format, sorted
by path, folders expanded to their files), and its **code version** is ``sha256:`` and the
hash of the stamp's bytes. Both are functions of the source alone: not of which modules a
process happened to import (lazily, in a worker or not), of the folder the project sits
in, or of the commit. DVC reruns a stage when its stamp changes
(:mod:`tattotronix.devtools.codedeps`), and every output the stage writes records the same
code version (:func:`tattotronix.io.provenance.code_version`).
"""

from __future__ import annotations

import ast
import functools
import hashlib
import json
import os
import shlex
import sys
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path

__all__ = ["PACKAGES", "CodeGraph", "entry_of", "stamp_text", "version_of_stamp",
           "write_stamp_folder"]

ROOT = Path(__file__).resolve().parents[2]
#: importable project packages (their files are code when executed)
PACKAGES = ("tattotronix", "hydra_plugins")
#: top-level import names that make Hydra import every plugin module at start-up
PLUGIN_HOSTS = ("hydra",)
SKIP = ("__pycache__",)


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


def _imports_of(tree: ast.AST, package: str) -> tuple[set[str], set[str]]:
    """The dotted names a module imports at run time (relative ones resolved against
    ``package``) and its string constants."""
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
    return found, strings


def _cache_folder() -> Path | None:
    """Where parsed imports are kept between processes (None: nowhere): the user's cache
    (``$XDG_CACHE_HOME`` or ``~/.cache``), per Python version (its ``ast`` reads the
    source); ``TATTOTRONIX_CODEGRAPH_CACHE=0`` turns it off."""
    if os.environ.get("TATTOTRONIX_CODEGRAPH_CACHE", "1") == "0":
        return None
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "tattotronix" / f"codegraph-py{sys.version_info[0]}{sys.version_info[1]}"


def _file_name_like(text: str) -> bool:
    """A string constant that could name a file beside the module (what
    :meth:`CodeGraph._package_data` looks for): no path separator, no line break."""
    return 0 < len(text) <= 255 and "/" not in text and "\n" not in text


@functools.cache
def _parser_key() -> bytes:
    """The hash of this module's own source: an edit to how imports are read makes every
    kept entry a miss."""
    return hashlib.sha256(Path(__file__).read_bytes()).digest()


def _parsed_imports(source: bytes, package: str, filename: str) -> tuple[set[str], set[str]]:
    """:func:`_imports_of` the source (its file-name-like strings only), parsed once per
    content: a file's imports are a function of its bytes, its package and this module's
    code, so they are kept in :func:`_cache_folder` under the hash of the three, and a
    start-up that would parse every module of the closure again (a second or two) reads
    them back instead."""
    folder = _cache_folder()
    key = hashlib.sha256(_parser_key() + package.encode() + b"\0" + source).hexdigest()
    entry = folder / f"{key}.json" if folder is not None else None
    if entry is not None:
        try:
            found, strings = json.loads(entry.read_text(encoding="utf-8"))
            return set(found), set(strings)
        except (OSError, ValueError, TypeError):
            pass
    tree = ast.parse(source, filename=filename)
    found, strings = _imports_of(tree, package)
    strings = {t for t in strings if _file_name_like(t)}
    if entry is not None:
        try:
            entry.parent.mkdir(parents=True, exist_ok=True)
            tmp = entry.with_name(f".{entry.name}.{os.getpid()}.tmp")
            tmp.write_text(json.dumps([sorted(found), sorted(strings)]), encoding="utf-8")
            os.replace(tmp, entry)
        except OSError:
            pass  # a read-only home: parsed each time, as before
    return found, strings


@dataclass(frozen=True)
class _Module:
    name: str
    path: Path
    is_package: bool
    imports: frozenset[str]  # dotted names as written (resolved when relative)
    strings: frozenset[str]  # string constants (to find the package data a module names)


class CodeGraph:
    """The project's modules and what each one imports, read from the source (each
    module parsed the first time a closure reaches it)."""

    def __init__(self, root: Path = ROOT):
        self.root = root
        self.paths: dict[str, tuple[Path, bool]] = {}
        self._parsed: dict[str, _Module] = {}
        for package in PACKAGES:
            for path in sorted((root / package).rglob("*.py")):
                if any(part in SKIP for part in path.parts):
                    continue
                parts = list(path.relative_to(root).with_suffix("").parts)
                is_pkg = parts[-1] == "__init__"
                if is_pkg:
                    parts = parts[:-1]
                self.paths[".".join(parts)] = (path, is_pkg)

    def module(self, name: str) -> _Module:
        """The parsed module ``name`` (a key of :attr:`paths`)."""
        mod = self._parsed.get(name)
        if mod is None:
            path, is_pkg = self.paths[name]
            package = name if is_pkg else name.rpartition(".")[0]
            found, strings = _parsed_imports(path.read_bytes(), package, str(path))
            mod = self._parsed[name] = _Module(name, path, is_pkg, frozenset(found),
                                               frozenset(strings))
        return mod

    def _executed(self, dotted: str) -> list[str]:
        """The project modules that ``import dotted`` runs: every package on the way."""
        parts = dotted.split(".")
        return [m for i in range(1, len(parts) + 1)
                if (m := ".".join(parts[:i])) in self.paths]

    def _package_data(self, module: _Module) -> set[Path]:
        """Non-Python files and folders beside ``module`` that it names in a string."""
        folder = module.path.parent
        return {p for p in folder.iterdir()
                if p.name in module.strings and p.suffix != ".py" and p.name not in SKIP
                and not (p.is_dir() and any(p.rglob("*.py")))}

    def closure(self, entry: Path, entry_imports: Iterable[str] = ()) -> set[Path]:
        """Every project file (or package-data folder) that running ``entry`` executes
        (``entry`` included)."""
        files = {entry}
        todo: list[str] = list(entry_imports)
        if entry.suffix == ".py" and entry.is_file():
            found, _ = _parsed_imports(entry.read_bytes(), "", str(entry))
            todo.extend(d for d in found if d)  # a script's relative imports resolve nowhere
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
                mod = self.module(name)
                files.add(mod.path)
                files.update(self._package_data(mod))
                todo.extend(mod.imports)
            if plugins and not any(m.startswith("hydra_plugins.") for m in seen):
                todo.extend(m for m in self.paths if m.startswith("hydra_plugins."))
        return files

    def modules_closure(self, modules: Iterable[str]) -> set[Path]:
        """Every project file that importing ``modules`` executes."""
        files: set[Path] = set()
        for name in modules:
            if name in self.paths:
                files |= self.closure(self.paths[name][0], [name])
        return files

    def all_files(self, folder: Path) -> set[Path]:
        """Every file under ``folder`` that can be code (no caches)."""
        return {p for p in folder.rglob("*")
                if p.is_file() and not any(part in SKIP for part in p.parts)}

    def expand(self, paths: Iterable[Path]) -> list[Path]:
        """``paths`` with each folder replaced by its files, sorted."""
        out: set[Path] = set()
        for p in paths:
            out |= self.all_files(p) if p.is_dir() else {p}
        return sorted(out)


def entry_of(cmd: str, root: Path = ROOT) -> tuple[Path, list[str]] | None:
    """The file a stage command runs, and the module it names when run with ``-m``
    (None: not a ``python`` command)."""
    argv = shlex.split(cmd)
    if len(argv) < 2 or Path(argv[0]).name not in ("python", "python3"):
        return None
    if argv[1] == "-m":
        module = argv[2]
        base = root.joinpath(*module.split("."))
        path = base / "__init__.py" if base.is_dir() else base.with_suffix(".py")
        return path, [module]
    return root / argv[1], []


def stamp_text(root: Path, files: Iterable[Path]) -> str:
    """``<sha256>  <path>`` per file (``sha256sum``'s format), sorted by path, relative to
    ``root`` with ``/``."""
    lines = []
    for path in sorted(files, key=lambda p: p.relative_to(root).as_posix()):
        digest = hashlib.sha256(path.read_bytes()).hexdigest()
        lines.append(f"{digest}  {path.relative_to(root).as_posix()}\n")
    return "".join(lines)


def version_of_stamp(stamp: str | bytes) -> str:
    """The code version a stamp stands for: ``sha256:`` and the hash of its bytes."""
    data = stamp.encode("utf-8") if isinstance(stamp, str) else stamp
    return "sha256:" + hashlib.sha256(data).hexdigest()


def write_stamp_folder(folder: Path, stamps: Mapping[str, str], suffix: str) -> list[str]:
    """Write ``stamps`` (stage -> text) into ``folder`` as ``<stage><suffix>``: atomically,
    leaving a file whose text is unchanged alone (DVC then sees nothing new) and removing
    the stamps of stages that are gone; the stages whose stamp changed."""
    folder.mkdir(parents=True, exist_ok=True)
    changed = []
    for name, text in stamps.items():
        path = folder / f"{name}{suffix}"
        if path.is_file() and path.read_text(encoding="utf-8") == text:
            continue
        tmp = path.with_name(f".{path.name}.tmp{os.getpid()}")
        tmp.write_text(text, encoding="utf-8")
        os.replace(tmp, path)
        changed.append(name)
    for old in folder.glob(f"*{suffix}"):
        if old.name[: -len(suffix)] not in stamps:
            old.unlink()
    return changed
