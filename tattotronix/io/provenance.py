"""Where a result came from: the code version, the config, and the hashes of its inputs."""

from __future__ import annotations

import dataclasses
import enum
import hashlib
import json
import sys
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from tattotronix.io.jsontypes import JsonDict

__all__ = ["CODE_PATHS", "code_version", "config_sha256", "file_sha256", "plain_config",
           "provenance_json"]

_ROOT = Path(__file__).resolve().parents[2]


#: where "the code" lives: a change elsewhere (dvc.lock, metrics, documents, tests) is
#: not a change of the code, and DVC rewrites some of those while a pipeline runs
CODE_PATHS = ("tattotronix", "stages", "hydra_plugins")


def code_version(root: Path | None = None) -> str:
    """The version of the code that made a result: ``sha256:`` and a hash of the path and
    bytes of every project file this process has imported (the stage script, and the
    modules under :data:`CODE_PATHS`).

    What the code *is*, not the commit it sits in. Those files are the stage's code deps in
    dvc.yaml (``tattotronix.devtools.codedeps`` finds the same imports), so the version
    moves exactly when DVC reruns the stage, and two clean clones, anywhere on disk, write
    the same bytes. A git revision would move with every commit, documents and metrics
    included, and a run on uncommitted code could only say ``-dirty``.
    """
    root = (root or _ROOT).resolve()
    dirs = tuple(root / name for name in CODE_PATHS)
    files: set[str] = set()
    for module in list(sys.modules.values()):
        file = getattr(module, "__file__", None)
        if not file:
            continue
        path = Path(file).resolve()
        if path.suffix == ".py" and any(path.is_relative_to(d) for d in dirs):
            files.add(path.relative_to(root).as_posix())
    if not files:
        return "unknown"
    h = hashlib.sha256()
    for name in sorted(files):
        h.update(name.encode("utf-8") + b"\0")
        h.update(hashlib.sha256((root / name).read_bytes()).digest())
    return "sha256:" + h.hexdigest()


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


def provenance_json(config: Mapping[str, object], inputs: Mapping[str, str | Path],
                    code_version: str) -> str:
    """The provenance string: the resolved config and its hash (:func:`config_sha256`),
    the code version, input file hashes.

    Args:
        config: the composed config as plain containers (``OmegaConf.to_container(cfg,
            resolve=True, enum_to_str=True)``).
        inputs: role -> file (``{"ik": ..., "urdf": ...}``).
        code_version: :func:`code_version`.
    """
    return json.dumps({
        "config": dict(config),
        "config_sha256": config_sha256(config),
        "code_version": code_version,
        "inputs": {k: {"path": str(p), "sha256": file_sha256(p)} for k, p in inputs.items()},
    }, sort_keys=True)
