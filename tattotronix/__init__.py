"""TATTOTRONIX: a config-driven pipeline for a 5-DOF tattoo and drawing arm.

The library is layered: a module imports only from its own layer's package and the layers
below it, ``a | b`` share a layer and never import each other, and no imports form a cycle
at any depth (``lint-imports``, with the contracts in ``pyproject.toml``). Top to bottom:

* ``devtools``: tools run on the project (the stages' code deps, the certification of the
  documents' figures, the tables derived from the CAD meshes); nothing below imports them.
* ``stage``: the runner of ``stages/<name>.py``, above the library it calls; only they import it.
* ``server``: the job server (``tattotronix serve``): the page, the routes and the one job,
  a thin shell over ``app``.
* ``report``: figures, the animation and the robot report present the results of every layer.
* ``studies``: design studies, which run the pipeline, the control loop and the servo model.
* ``app``: the use cases, once each (plan, preview, simulate, predict on the servos, draw on
  the arm), the one backend dispatch, the pipeline in one process (artwork to trajectory)
  and the Python API (``tattotronix.plan``).
* ``hardware``: servo board, program and deploy gate, for drawings control and collision clear.
* ``control``: the joint controller, and a timed drawing played closed loop on a plant.
* ``plants``: the simulated arms, built from the robot models, that control drives.
* ``trajectory``: times the IK'd path; its travel moves are checked by collision.
* ``collision``: the collision model, its pairs and the trajectory check, on the robot.
* ``kinematics``: the chain and the IK, which solve the toolpath's points (and read their kinds).
* ``path``: the artwork's ink mask to a toolpath on the panel.
* ``robot | art | surface``: the independent inputs: the robot description and models, the
  artwork, and a work surface beyond the panel (a design's chart on it).
* ``config``: the Hydra config and its typed schema, read by every layer above.
* ``io | plotting``: independent leaf utilities: output files and provenance, matplotlib helpers.
* ``errors``: the exceptions every layer raises; imports nothing of the project.

A stage script (``stages/<name>.py``) imports this package before any library (its first
import), and while it imports the rest (seconds: NumPy, SciPy, Pinocchio, MuJoCo, ...) a
Ctrl-C ends it at once with one line, ``<stage>: interrupted (Ctrl-C): stopped, nothing
written``, and exit code 130, as during the run (``tattotronix.stage.run_stage``, which
takes over), instead of a ``KeyboardInterrupt`` traceback from inside some import. Any
other process that imports the package (a test, a notebook) keeps its own Ctrl-C.
"""

from __future__ import annotations

import signal
import sys
import threading
from pathlib import Path
from types import FrameType
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # the API's names, typed, for a type checker (loaded on first use)
    from tattotronix.app.api import Arm, Draft, Plan, draft, plan, plan_strokes  # noqa: F401

__version__ = "0.1.0"

#: the Python API (:mod:`tattotronix.app.api`), imported on first use, so that importing
#: the package (every stage does, first) stays light
_API = ("Arm", "Draft", "Plan", "draft", "plan", "plan_strokes")


def __getattr__(name: str) -> object:
    if name in _API:
        # importlib, not an import statement: a stage's code stamp follows the import
        # statements of what it runs (tattotronix.io.codegraph), every stage imports this
        # package, and none uses the API; one that did would import tattotronix.app.api
        import importlib

        return getattr(importlib.import_module("tattotronix.app.api"), name)
    raise AttributeError(f"module 'tattotronix' has no attribute '{name}'")


def __dir__() -> list[str]:
    return sorted([*globals(), *_API])

#: the folder a stage script lives in (``stages/`` beside this package, or a copy's)
_STAGES = "stages"


def _ctrl_c_while_importing(signum: int, frame: FrameType | None) -> None:
    """SIGINT before the stage runs: nothing is written yet, so stop here, in one line."""
    stage = Path(sys.argv[0]).stem if sys.argv and sys.argv[0] else "stage"
    print(f"{stage}: interrupted (Ctrl-C): stopped, nothing written", file=sys.stderr)
    raise SystemExit(128 + signum)


def _is_stage_script() -> bool:
    """Whether this process runs a stage script (``python stages/<name>.py``)."""
    main = sys.modules.get("__main__")
    file = getattr(main, "__file__", None)
    if not isinstance(file, str) or getattr(main, "__name__", "") != "__main__":
        return False
    return Path(file).resolve().parent.name == _STAGES


def end_import_guard() -> None:
    """Ctrl-C raises ``KeyboardInterrupt`` again (the stage runner cleans up after it)."""
    if (threading.current_thread() is threading.main_thread()
            and signal.getsignal(signal.SIGINT) is _ctrl_c_while_importing):
        signal.signal(signal.SIGINT, signal.default_int_handler)


if (threading.current_thread() is threading.main_thread() and _is_stage_script()
        and signal.getsignal(signal.SIGINT) is signal.default_int_handler):
    signal.signal(signal.SIGINT, _ctrl_c_while_importing)

