"""The deploy gate: only a trajectory the collision stage checked, and found clean, is
compiled for the servos (``stages/deploy.py``)."""

from __future__ import annotations

import json
from pathlib import Path

from tattotronix.errors import TattotronixError
from tattotronix.io.jsontypes import JsonDict
from tattotronix.io.provenance import file_sha256

__all__ = ["require_checked"]


def require_checked(metrics_file: str | Path, trajectory_file: str | Path) -> JsonDict:
    """The collision stage's verdict on a trajectory file, or a refusal.

    Raises:
        TattotronixError: no verdict, a verdict on another trajectory (its SHA-256
            differs), or a trajectory that was not clean.
    """
    mf = Path(metrics_file)
    if not mf.is_file():
        raise TattotronixError(f"{trajectory_file} has no collision check ({mf} is missing): "
                               "run the 'collision' stage first")
    try:
        m = json.loads(mf.read_text())
    except (OSError, ValueError) as exc:
        raise TattotronixError(f"{mf} is not a collision verdict ({exc}): re-run the "
                               "'collision' stage") from None
    if not isinstance(m, dict) or m.get("trajectory_sha256") != file_sha256(trajectory_file):
        raise TattotronixError(f"{mf} checked another version of {trajectory_file}: re-run "
                               "the 'collision' stage")
    if m.get("collisions") != 0 or m.get("below_margin") != 0:
        raise TattotronixError(f"{trajectory_file} is not collision-free ({mf})")
    return dict(m)
