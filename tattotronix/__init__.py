"""TATTOTRONIX: a config-driven pipeline for a 5-DOF tattoo and drawing arm."""

from __future__ import annotations

import sys
from pathlib import Path

__version__ = "0.1.0"


def _unshadow_stages() -> None:
    """Take the project's ``stages/`` folder off ``sys.path``.

    ``python stages/<name>.py`` puts the script's folder first on the import path, and
    ``stages/control.py`` (the control study) would then shadow python-control's
    ``control`` package in every stage. The stages import nothing from their own folder.
    """
    script = getattr(sys.modules.get("__main__"), "__file__", None)
    if not script:
        return
    folder = Path(script).resolve().parent
    if folder.name == "stages" and (folder / "control.py").is_file():
        sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != folder]
        cached = sys.modules.get("control")
        if cached is not None and Path(getattr(cached, "__file__", "") or "").parent == folder:
            del sys.modules["control"]


_unshadow_stages()
