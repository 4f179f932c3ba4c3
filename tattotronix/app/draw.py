"""``draw.py``: a drawing on the configured backend, dispatched here and nowhere else.

:func:`draw` is the stage's (find or plan the drawing, then play it); :func:`play` plays a
drawing already in hand (the stage's, or a plan made through the Python API,
:mod:`tattotronix.app.api`) on the one backend the settings name:

* ``mujoco``, ``pybullet``, ``model``: the simulated plants, closed loop;
* ``servo``: the servo program played by the modelled hobby servos;
* ``arm``: the real arm, or a dry run on a recording bus
  (:func:`~tattotronix.app.arm.play_on_arm`).
"""

from __future__ import annotations

import logging

from tattotronix.app.arm import play_on_arm
from tattotronix.app.drawings import check_run_source, resolve_drawing, score_and_write
from tattotronix.app.servos import run_servo_loop
from tattotronix.app.simulate import run_closed_loop
from tattotronix.config.schema import Config, SurfaceKind
from tattotronix.control.drawing import Drawing
from tattotronix.errors import TattotronixError
from tattotronix.hardware.arm import calibration_from_config
from tattotronix.io.jsontypes import JsonDict
from tattotronix.io.outputs import Outputs
from tattotronix.plants import BACKENDS as PLANTS
from tattotronix.robot.description import RobotDescription, build_description

__all__ = ["BACKENDS", "check_backend", "check_panel", "draw", "play"]

log = logging.getLogger("tattotronix.draw")

#: every backend ``draw.py`` takes: the simulated plants (a new plant is added there, in
#: ``tattotronix.plants.factory``, and nowhere else), the servo plant, the real arm
BACKENDS = (*PLANTS, "servo", "arm")


def draw(cfg: Config, out: Outputs) -> JsonDict:
    """``draw.py``: find or plan the configured drawing and draw it on ``cfg.backend``
    (:func:`play`); its summary (the run metrics).

    Raises:
        TattotronixError: an unknown backend, a curved surface (``stages/surface.py``
            draws there), or whatever the backend refuses.
    """
    check_backend(cfg)
    check_panel(cfg, "draw.py")
    desc = build_description(cfg.robot)
    if cfg.backend.name == "arm":  # a bad calibration fails before any planning
        calibration_from_config(cfg.hardware, desc.joint_names)
    else:
        check_run_source(cfg, out)
    return play(cfg, out, desc, resolve_drawing(cfg, out.data, desc))


def check_panel(cfg: Config, what: str) -> None:
    """Refuse a curved surface where only the panel is drawn on (``draw.py``, the Python
    API's plans), instead of drawing on the panel regardless.

    Raises:
        TattotronixError: naming the stage that draws on the skin.
    """
    if cfg.surface.kind is not SurfaceKind.panel:
        kind = cfg.surface.kind.value
        raise TattotronixError(
            f"surface={kind}: {what} draws on the panel; a drawing on a curved surface is "
            "planned, simulated (backend=mujoco, pybullet or model) and scored by "
            f"stages/surface.py surface={kind} ...")


def check_backend(cfg: Config) -> None:
    """Refuse an unknown backend, and a window on the arm (it draws whole drawings).

    Raises:
        TattotronixError: naming what to give instead.
    """
    backend = cfg.backend.name
    if backend not in BACKENDS:
        raise TattotronixError(f"unknown backend '{backend}': use one of {', '.join(BACKENDS)}")
    if backend == "arm" and cfg.window is not None:
        raise TattotronixError("window= is for simulated backends; the arm draws the "
                               "whole drawing (resume=true continues a stopped one)")


def play(cfg: Config, out: Outputs, desc: RobotDescription, drawing: Drawing) -> JsonDict:
    """Draw ``drawing`` on ``cfg.backend``, the one place a backend is chosen:

    * ``mujoco``, ``pybullet``, ``model``: closed loop on the simulated plant
      (:func:`~tattotronix.app.simulate.run_closed_loop`), scored and written
      (:func:`~tattotronix.app.drawings.score_and_write`);
    * ``servo``: the servo program on the modelled servos
      (:func:`~tattotronix.app.servos.run_servo_loop`), scored and written alike;
    * ``arm``: compiled and streamed to the arm (:func:`~tattotronix.app.arm.play_on_arm`).

    Returns:
        The run metrics (also written to ``metrics/runs/<name>-<backend>.json``), or the
        arm's summary.
    """
    check_backend(cfg)
    backend = cfg.backend.name
    if backend == "arm":
        return play_on_arm(cfg, out, desc, drawing)
    if backend == "servo":
        if cfg.viewer:
            log.warning("viewer=true: the servo plant has no viewer (it plays whole stretches "
                        "in C); running without one")
        loop = run_servo_loop(cfg, out.data, desc, drawing, window=cfg.window,
                              progress=bool(cfg.draw.progress))
    else:  # one of the plants (check_backend)
        loop = run_closed_loop(cfg, out.data, desc, drawing, window=cfg.window,
                               progress=bool(cfg.draw.progress), viewer=bool(cfg.viewer))
    return score_and_write(cfg, out, loop, desc)
