"""Where a result came from: the code version, the config, and the hashes of its inputs."""

from __future__ import annotations

import copy
import dataclasses
import enum
import hashlib
import json
import sys
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from contextvars import ContextVar
from pathlib import Path
from typing import Any

import numpy as np

from tattotronix.io.jsontypes import JsonDict
from tattotronix.io.npz import READ_ERRORS

__all__ = ["CODE_PATHS", "PROVENANCE_KEY", "code_version", "config_sha256", "file_sha256",
           "only_keys", "plain_config", "provenance_json", "recorded_keys"]

_ROOT = Path(__file__).resolve().parents[2]

#: the key every artifact stores its provenance JSON under
PROVENANCE_KEY = "provenance"


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


def provenance_json(config: Mapping[str, object], inputs: Mapping[str, str | Path],
                    code_version: str) -> str:
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
        "inputs": {k: {"path": str(p), "sha256": file_sha256(p)} for k, p in inputs.items()},
    }, sort_keys=True)
