"""``draw.py``: a drawing on the configured backend, dispatched here and nowhere else.

:func:`draw` is the stage's (find or plan the drawing, then play it); :func:`play` plays a
drawing already in hand (the stage's, or a plan made through the Python API,
:mod:`tattotronix.app.api`) on the one backend the settings name:

* ``mujoco``, ``pybullet``, ``model``: the simulated plants, closed loop;
* ``servo``: the servo program played by the modelled hobby servos;
* ``arm``: the real arm, or a dry run on a recording bus (:func:`play_on_arm`).
"""

from __future__ import annotations

import logging

import numpy as np

from tattotronix.app.drawings import check_run_source, resolve_drawing, score_and_write
from tattotronix.config.schema import Config
from tattotronix.control.drawing import Drawing, run_closed_loop
from tattotronix.errors import TattotronixError
from tattotronix.hardware.arm import (
    PREVIEW_IMAGE,
    ArmSession,
    build_program,
    calibration_from_config,
    check_drawing_clear,
    state_file_of,
)
from tattotronix.hardware.preview import preview_of
from tattotronix.hardware.servo_loop import run_servo_loop
from tattotronix.io.artifacts import run_dir, run_label
from tattotronix.io.jsontypes import JsonDict
from tattotronix.io.outputs import Outputs
from tattotronix.kinematics import Chain
from tattotronix.pipeline import ik_settings
from tattotronix.robot.description import RobotDescription, build_description

__all__ = ["BACKENDS", "draw", "play", "play_on_arm"]

log = logging.getLogger("tattotronix.draw")

#: every backend ``draw.py`` takes: the simulated plants, the servo plant, the real arm
BACKENDS = ("mujoco", "pybullet", "model", "servo", "arm")


def draw(cfg: Config, out: Outputs) -> JsonDict:
    """``draw.py``: find or plan the configured drawing and draw it on ``cfg.backend``
    (:func:`play`); its summary (the run metrics).

    Raises:
        TattotronixError: an unknown backend, or whatever the backend refuses.
    """
    backend = cfg.backend.name
    if backend not in BACKENDS:
        raise TattotronixError(f"unknown backend '{backend}': use one of {', '.join(BACKENDS)}")
    desc = build_description(cfg.robot)
    if backend == "arm":  # what the arm refuses, it refuses before any planning
        if cfg.window is not None:
            raise TattotronixError("window= is for simulated backends; the arm draws the "
                                   "whole drawing (resume=true continues a stopped one)")
        calibration_from_config(cfg.hardware, desc.joint_names)
    else:
        check_run_source(cfg, out)
    return play(cfg, out, desc, resolve_drawing(cfg, out.data, desc))


def play(cfg: Config, out: Outputs, desc: RobotDescription, drawing: Drawing) -> JsonDict:
    """Draw ``drawing`` on ``cfg.backend``, the one place a backend is chosen:

    * ``mujoco``, ``pybullet``, ``model``: closed loop on the simulated plant
      (:func:`~tattotronix.control.drawing.run_closed_loop`), scored and written
      (:func:`~tattotronix.app.drawings.score_and_write`);
    * ``servo``: the servo program on the modelled servos
      (:func:`~tattotronix.hardware.servo_loop.run_servo_loop`), scored and written alike;
    * ``arm``: compiled and streamed to the arm (:func:`play_on_arm`).

    Returns:
        The run metrics (also written to ``metrics/runs/<name>-<backend>.json``), or the
        arm's summary.
    """
    backend = cfg.backend.name
    if backend == "arm":
        return play_on_arm(cfg, out, desc, drawing)
    if backend == "servo":
        if cfg.viewer:
            log.warning("viewer=true: the servo plant has no viewer (it plays whole stretches "
                        "in C); running without one")
        loop = run_servo_loop(cfg, out.data, desc, drawing, window=cfg.window,
                              progress=bool(cfg.draw.progress))
    elif backend in BACKENDS:
        loop = run_closed_loop(cfg, out.data, desc, drawing, window=cfg.window,
                               progress=bool(cfg.draw.progress), viewer=bool(cfg.viewer))
    else:
        raise TattotronixError(f"unknown backend '{backend}': use one of {', '.join(BACKENDS)}")
    return score_and_write(cfg, out, loop, desc)


def play_on_arm(cfg: Config, out: Outputs, desc: RobotDescription, drawing: Drawing
                ) -> JsonDict:
    """``draw.py backend=arm``: compile the drawing and stream it.

    Prints the plan first (:mod:`tattotronix.hardware.preview`); ``preview=true`` stops
    there with ``preview.png``. Appends to ``runs/<name>-arm/{i2c.jsonl (dry run),
    poses.jsonl}`` under the write root (``runs/`` by hand: ``io.outputs.write_root``),
    writes the arm state file, and on completion ``metrics/runs/<name>-arm.json``.

    Raises:
        TattotronixError: a bad calibration, a drawing not clear of the bench, a bad ramp.
    """
    calibration_from_config(cfg.hardware, desc.joint_names)
    check_drawing_clear(cfg, desc, drawing.t, drawing.q)
    program, calib = build_program(cfg, desc, drawing.t, drawing.q, drawing.qd)
    folder = run_dir(out.root, run_label(drawing.name, "arm"))
    chain = Chain.from_description(desc)
    preview = preview_of(drawing.name, drawing.t, drawing.q, drawing.kind, program.frames,
                         program.frame_hz, chain, np.asarray(cfg.toolpath.panel_origin),
                         np.asarray(cfg.robot.panel.centre), np.asarray(cfg.robot.panel.size))
    log.info("%s", preview.text())  # before anything reaches the bus
    if cfg.preview:
        image = preview.figure(out.tmp_path(folder / PREVIEW_IMAGE))
        log.info("arm %s: preview only (preview=true): nothing sent, no state touched",
                 drawing.name)
        return {"status": "preview", "duration_s": preview.duration_s,
                "entries": preview.entries, "box_mm": list(preview.box_mm),
                "fits": preview.fits, "image": str(image)}
    surface = float(cfg.toolpath.panel_origin[2])
    clearance = surface + cfg.toolpath.clearance_m
    speed = float(cfg.hardware.ramp_rad_s)
    if not (np.isfinite(speed) and speed > 0):
        raise TattotronixError(f"hardware.ramp_rad_s={speed}: give a positive speed in rad/s")
    session = ArmSession(
        name=drawing.name, program=program, calib=calib, chain=chain,
        run_dir=folder, state_file=state_file_of(cfg, out.data, folder),
        clearance_z_m=clearance, surface_z_m=surface, feed_m_s=cfg.toolpath.feed_mark_m_s,
        ramp_rad_s=speed, ik=ik_settings(cfg.ik), dry_run=bool(cfg.dry_run),
        realtime=bool(cfg.realtime), resume=bool(cfg.resume),
        fail_after_writes=cfg.hardware.fail_after_writes,
        save_every_s=float(cfg.hardware.save_every_s))
    log.info("arm %s: %d frames at %g Hz (%.1f s), %s%s", drawing.name, program.frames,
             program.frame_hz, program.frames / program.frame_hz,
             "dry run" if session.dry_run else f"{calib.device} at 0x{calib.address:02x}",
             ", resuming" if session.resume else "")
    summary = session.run()
    summary["program_metrics"] = program.metrics(calib, session.chain)
    out.write_json(out.path("metrics", "runs", f"{drawing.name}-arm.json"), summary)
    log.info("arm %s: %s, %d frames sent, %d channel writes, %.1f s", drawing.name,
             summary["status"], summary["frames_sent"], summary["channel_writes"],
             summary["wall_s"])
    return summary
