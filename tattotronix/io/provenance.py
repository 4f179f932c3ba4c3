"""Where a result came from: the code version, the config, and the hashes of its inputs."""

from __future__ import annotations

import copy
import dataclasses
import enum
import functools
import hashlib
import json
import os
import sys
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from contextvars import ContextVar
from pathlib import Path
from typing import Any

import numpy as np

from tattotronix.io.codegraph import PACKAGES, CodeGraph, stamp_text, version_of_stamp
from tattotronix.io.jsontypes import JsonDict
from tattotronix.io.npz import READ_ERRORS

__all__ = ["CODE_VERSION_ENV", "PROVENANCE_KEY", "code_version", "config_sha256", "file_sha256",
           "fixed_code_version", "only_keys", "plain_config", "provenance_json", "recorded_keys",
           "script_version", "stamp_version"]

_ROOT = Path(__file__).resolve().parents[2]

#: the key every artifact stores its provenance JSON under
PROVENANCE_KEY = "provenance"


#: the environment variable that carries a run's code version to its worker processes
CODE_VERSION_ENV = "TATTOTRONIX_CODE_VERSION"


def code_version(root: Path | None = None) -> str:
    """The version of the code that made a result: ``sha256:`` and the hash of the stamp
    of the code the process's entry point runs (:mod:`tattotronix.io.codegraph`: the
    script or ``-m`` module and its static import closure, read from the source).

    What the code *is*, not the commit it sits in, nor which modules a process happened
    to import: two clean clones, anywhere on disk, with any number of workers, write the
    same bytes. The stage runner fixes it once per run in :data:`CODE_VERSION_ENV` (under
    DVC: the hash of the stage's stamp in ``<paths.data>/code/``, the dep DVC reruns the
    stage on), so every worker records the same. A process with no project entry point
    (a notebook, the tests) records the closure of the project modules it has imported.
    """
    fixed = os.environ.get(CODE_VERSION_ENV)
    if fixed:
        return fixed
    root = (root or _ROOT).resolve()
    main = sys.modules.get("__main__")
    file = getattr(main, "__file__", None)
    spec = getattr(main, "__spec__", None)
    entry = Path(file).resolve() if file else None
    if entry is not None and entry.is_relative_to(root) and entry.suffix == ".py":
        return _entry_version(root, entry, getattr(spec, "name", None))
    imported = tuple(sorted(name for name in sys.modules
                            if name.split(".")[0] in PACKAGES))
    return _imports_version(root, imported)


@contextmanager
def fixed_code_version(version: str | None = None) -> Iterator[str]:
    """Within the block, every :func:`code_version` of this process and of the processes
    it starts is ``version`` (:func:`code_version` as computed now, if None)."""
    old = os.environ.get(CODE_VERSION_ENV)
    os.environ[CODE_VERSION_ENV] = value = version or code_version()
    try:
        yield value
    finally:
        if old is None:
            os.environ.pop(CODE_VERSION_ENV, None)
        else:
            os.environ[CODE_VERSION_ENV] = old


def stamp_version(stamp: Path) -> str | None:
    """The code version a stage's stamp file stands for (None: no such file)."""
    try:
        return version_of_stamp(stamp.read_bytes())
    except FileNotFoundError:
        return None


def script_version(script: Path, root: Path | None = None) -> str:
    """The code version a run of the project's script ``script`` records (:func:`code_version`
    with that script as the entry point): what its stamp in ``<paths.data>/code/`` stands for
    while the stamp is current."""
    return _entry_version((root or _ROOT).resolve(), script.resolve(), None)


@functools.cache
def _entry_version(root: Path, entry: Path, module: str | None) -> str:
    graph = CodeGraph(root)
    files = graph.closure(entry, [module] if module and module != "__main__" else [])
    return version_of_stamp(stamp_text(root, graph.expand(files)))


@functools.cache
def _imports_version(root: Path, modules: tuple[str, ...]) -> str:
    graph = CodeGraph(root)
    files = graph.modules_closure(modules)
    if not files:
        return "unknown"
    return version_of_stamp(stamp_text(root, graph.expand(files)))


def file_sha256(file: str | Path) -> str:
    """Hex SHA-256 of a file's bytes."""
    h = hashlib.sha256()
    with open(file, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def _plain(value: Any) -> Any:
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: _plain(getattr(value, f.name)) for f in dataclasses.fields(value)}
    if isinstance(value, enum.Enum):
        return value.name
    if isinstance(value, Mapping):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_plain(v) for v in value]
    return value


def plain_config(cfg: object) -> JsonDict:
    """The resolved config as plain containers (enums by name), from an OmegaConf
    ``DictConfig``, a config dataclass (``tattotronix.config.schema.Config``) or a mapping.
    """
    from omegaconf import DictConfig, OmegaConf

    if isinstance(cfg, DictConfig):
        cfg = OmegaConf.to_container(cfg, resolve=True, enum_to_str=True)
    plain = _plain(cfg)
    if not isinstance(plain, dict):
        raise TypeError(f"a config is a mapping or a dataclass, not {type(cfg).__name__}")
    return plain


def config_sha256(config: Mapping[str, object]) -> str:
    """Hex SHA-256 of the resolved config's JSON (sorted keys, compact)."""
    text = json.dumps(config, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


#: the config keys a provenance records; None: the whole config (:func:`recorded_keys`)
_RECORDED: ContextVar[tuple[str, ...] | None] = ContextVar("recorded_keys", default=None)


@contextmanager
def recorded_keys(keys: Sequence[str] | None) -> Iterator[None]:
    """Within the block, every provenance records only the config keys ``keys`` (dotted:
    ``toolpath`` is the section, ``toolpath.pitch_mm`` one value); None records it all.

    The stage runner sets it under DVC to the params DVC tracks for the stage
    (:func:`tattotronix.config.tracked.tracked_params`), so that an output's bytes move
    exactly when DVC reruns the stage that writes it.
    """
    token = _RECORDED.set(None if keys is None else tuple(keys))
    try:
        yield
    finally:
        _RECORDED.reset(token)


def only_keys(config: Mapping[str, object], keys: Sequence[str]) -> dict[str, object]:
    """The part of a plain config holding ``keys`` (dotted paths; absent ones skipped)."""
    out: dict[str, Any] = {}
    for key in keys:
        *parents, last = key.split(".")
        src: Any = config
        for part in parents:
            src = src.get(part) if isinstance(src, Mapping) else None
        if not isinstance(src, Mapping) or last not in src:
            continue
        dst = out
        for part in parents:
            dst = dst.setdefault(part, {})
        # a section named whole (before or after one of its keys) is the whole of it
        dst[last] = copy.deepcopy(src[last])
    return out


def _recorded_config(file: str | Path) -> Mapping[str, Any] | None:
    """The config an input artifact's provenance records (None: not an npz with one)."""
    if Path(file).suffix != ".npz":
        return None
    try:
        with np.load(file, allow_pickle=False) as z:
            if PROVENANCE_KEY not in z.files:
                return None
            prov = json.loads(str(z[PROVENANCE_KEY]))
    except READ_ERRORS:
        return None
    config = prov.get("config") if isinstance(prov, dict) else None
    return config if isinstance(config, Mapping) else None


def _fill(into: dict[str, Any], more: Mapping[str, Any]) -> None:
    """Add to ``into`` the keys of ``more`` it lacks, at any depth."""
    for key, value in more.items():
        if key not in into:
            into[key] = copy.deepcopy(value)
        elif isinstance(into[key], dict) and isinstance(value, Mapping):
            _fill(into[key], value)


def _label(file: str | Path, roots: Sequence[str | Path]) -> str:
    """``file`` relative to the first of ``roots`` it lies under (``/``-separated), else
    as given."""
    path = Path(file).resolve()
    for root in roots:
        base = Path(root).resolve()
        if path.is_relative_to(base):
            return path.relative_to(base).as_posix()
    return str(file)


def provenance_json(config: Mapping[str, object], inputs: Mapping[str, str | Path],
                    code_version: str, roots: Sequence[str | Path] = ()) -> str:
    """The provenance string: the resolved config and its hash (:func:`config_sha256`),
    the code version, input file hashes.

    Inside :func:`recorded_keys` (a stage run by DVC) the config is only those keys, the
    params DVC reruns the stage on, completed by the config each input artifact records
    (its own provenance, so the settings upstream stages ran with reach every artifact
    downstream): the bytes then depend only on what DVC tracks for the stage.

    Args:
        config: the composed config as plain containers (``OmegaConf.to_container(cfg,
            resolve=True, enum_to_str=True)``).
        inputs: role -> file (``{"ik": ..., "urdf": ...}``).
        code_version: :func:`code_version`.
        roots: the data folders the inputs were read from: an input under one is recorded
            by its path relative to it (``ik/emblem.npz``), so that the same files in
            another folder (a plan the Python API saved) record the same bytes.
    """
    keys = _RECORDED.get()
    if keys is not None:
        recorded = only_keys(config, keys)
        for file in inputs.values():
            upstream = _recorded_config(file)
            if upstream is not None:
                _fill(recorded, upstream)
        config = recorded
    return json.dumps({
        "config": dict(config),
        "config_sha256": config_sha256(config),
        "code_version": code_version,
        "inputs": {k: {"path": _label(p, roots), "sha256": file_sha256(p)}
                   for k, p in inputs.items()},
    }, sort_keys=True)
