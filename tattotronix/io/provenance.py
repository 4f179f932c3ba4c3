"""Where a result came from: the code version, the config, and the hashes of its inputs."""

from __future__ import annotations

import hashlib
import json
import subprocess
from collections.abc import Mapping
from pathlib import Path

__all__ = ["code_version", "file_sha256", "provenance_json"]

_ROOT = Path(__file__).resolve().parents[2]


def code_version(root: Path | None = None) -> str:
    """The git commit of the code (with ``-dirty`` when the tree has changes), or unknown."""
    root = root or _ROOT
    try:
        rev = subprocess.run(
            ["git", "rev-parse", "HEAD"], cwd=root, capture_output=True, text=True, check=True
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=no"],
            cwd=root, capture_output=True, text=True, check=True,
        ).stdout.strip()
        return rev + ("-dirty" if dirty else "")
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def file_sha256(file: str | Path) -> str:
    """Hex SHA-256 of a file's bytes."""
    h = hashlib.sha256()
    with open(file, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def provenance_json(config: Mapping[str, object], inputs: Mapping[str, str | Path],
                    code_version: str) -> str:
    """The provenance string: the resolved config, the code version, input file hashes.

    Args:
        config: the composed config as plain containers (``OmegaConf.to_container(cfg,
            resolve=True, enum_to_str=True)``).
        inputs: role -> file (``{"ik": ..., "urdf": ...}``).
        code_version: :func:`code_version`.
    """
    return json.dumps({
        "config": dict(config),
        "code_version": code_version,
        "inputs": {k: {"path": str(p), "sha256": file_sha256(p)} for k, p in inputs.items()},
    }, sort_keys=True)
