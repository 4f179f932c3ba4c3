"""The arm's use case: a timed drawing compiled into servo frames and streamed to the
PCA9685 (``draw.py backend=arm``, and the ``deploy`` stage's program), from the settings.

* :func:`build_program`: the program, with the corrections ``hardware.compensate`` switches
  on (:mod:`tattotronix.hardware.program`, :mod:`tattotronix.hardware.servo_model`);
* :func:`check_drawing_clear`: the collision stage's check, on whatever the arm will play;
* :func:`play_on_arm`: the plan printed, then the session (:class:`~tattotronix.hardware.
  arm.ArmSession`: pause, stop, resume, the state file);
* :func:`state_file_of`: where the arm's state lives (the real arm's, or a dry run's own).
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from tattotronix.config.schema import Config
from tattotronix.control.drawing import Drawing
from tattotronix.errors import TattotronixError
from tattotronix.hardware.arm import (
    DRY_RUN_STATE,
    PREVIEW_IMAGE,
    ArmSession,
    calibration_from_config,
)
from tattotronix.hardware.preview import preview_of
from tattotronix.hardware.program import ServoProgram
from tattotronix.hardware.servos import Calibration
from tattotronix.io.artifacts import run_dir, run_label
from tattotronix.io.jsontypes import JsonDict
from tattotronix.io.outputs import Outputs
from tattotronix.kinematics import Chain, ik_options
from tattotronix.plants.servo_plant import ServoSpec
from tattotronix.robot.description import RobotDescription

__all__ = ["build_program", "check_drawing_clear", "play_on_arm", "state_file_of"]

log = logging.getLogger("tattotronix.arm")
Array = NDArray[np.float64]


def build_program(cfg: Config, desc: RobotDescription, t: Array, q: Array, qd: Array,
                  calib: Calibration | None = None,
                  servos: Sequence[ServoSpec] | None = None
                  ) -> tuple[ServoProgram, Calibration]:
    """The program of a timed drawing, with the servo corrections ``hardware.compensate``
    switches on.

    Args:
        cfg: the settings.
        desc: the robot description (joint ranges and velocity limits).
        t, q, qd: the drawing.
        calib: the calibration (default: from the config).
        servos: the servos the corrections are sized for (default: as mounted, from the
            catalogue, :func:`~tattotronix.hardware.servo_model.joint_servos`, with the
            figures ``hardware.servo_figures_file`` identified).
    """
    from tattotronix.config.schema import ServoPlantConfig
    from tattotronix.hardware.program import compile_program
    from tattotronix.hardware.servo_model import (
        compensate,
        joint_servos,
        servo_figures,
        servo_lead_s,
    )

    if calib is None:
        calib = calibration_from_config(cfg.hardware, desc.joint_names)
    comp = cfg.hardware.compensate
    adjust = None
    lead = None
    if comp.backlash or comp.deadband or comp.sag or comp.lead:
        specs = tuple(servos) if servos is not None else joint_servos(
            cfg.robot, desc.joint_names, calib, ServoPlantConfig(),
            servo_figures(cfg.hardware, desc.joint_names))
        if comp.lead:
            lead = servo_lead_s(specs, float(calib.frame_hz))
        frame_s = 1.0 / float(calib.frame_hz)

        def adjust(qf: Array) -> Array:
            torque = needed_torque(desc, qf, frame_s) if comp.sag else None
            return compensate(qf, specs, comp, torque)
    program = compile_program(t, q, qd, calib, desc.lower, desc.upper,
                              [j.velocity for j in desc.joints], adjust, lead)
    return program, calib


def needed_torque(desc: RobotDescription, qf: Array, frame_s: float) -> Array:
    """(F, n) the torque each joint needs along frames ``qf`` (F, n) ``frame_s`` apart,
    N m: inverse dynamics (Pinocchio's RNEA on the description's URDF: gravity, and the
    motion's inertia and velocity terms, from the frames' central differences)."""
    import pinocchio as pin

    from tattotronix.robot.loaders import pinocchio_model
    from tattotronix.robot.urdf import to_urdf

    model = pinocchio_model(to_urdf(desc), desc.gravity)
    data = model.createData()
    qa = np.ascontiguousarray(qf, dtype=np.float64)
    if len(qa) < 3:
        vel = np.zeros_like(qa)
        acc = np.zeros_like(qa)
    else:
        vel = np.gradient(qa, frame_s, axis=0)
        acc = np.gradient(vel, frame_s, axis=0)
    return np.array([pin.rnea(model, data, qa[k], vel[k], acc[k]) for k in range(len(qa))])


def check_drawing_clear(cfg: Config, desc: RobotDescription, t: Array, q: Array) -> None:
    """Refuse, before anything reaches the bus, a drawing that collides or comes within
    ``collision.margin_mm`` (samples and the motion between them; the collision stage's
    check, run here on whatever drawing the arm is about to play).

    Raises:
        CollisionRefused: naming the time, the pose and the pair.
    """
    from tattotronix.collision.check import CollisionRefused, check_trajectory
    from tattotronix.collision.model import CollisionModel

    rep = check_trajectory(CollisionModel(desc), t, q,
                           margin_m=cfg.collision.margin_m, plunge_m=cfg.toolpath.plunge_m,
                           resolution_m=cfg.collision.resolution_m)
    if not rep.ok:
        raise CollisionRefused(rep)
    log.info("arm: the drawing is clear of collisions (least clearance %.2f mm, %s)",
             rep.min_clearance_m[rep.worst] * 1e3, rep.pair_names[rep.worst])


def state_file_of(cfg: Config, data: Path, folder: Path) -> Path:
    """Where a session keeps the arm's last commanded pose: ``hardware.state_file`` under
    ``paths.data`` for the real arm, the run's own folder on a dry run (whose recording
    bus moves no arm)."""
    if cfg.dry_run:
        return folder / DRY_RUN_STATE
    return Path(data).joinpath(*Path(str(cfg.hardware.state_file)).parts)


def play_on_arm(cfg: Config, out: Outputs, desc: RobotDescription, drawing: Drawing, *,
                park: bool = False) -> JsonDict:
    """``draw.py backend=arm``: compile the drawing and stream it.

    Prints the plan first (:mod:`tattotronix.hardware.preview`); ``preview=true`` stops
    there with ``preview.png``. Appends to ``runs/<name>-arm/{i2c.jsonl (dry run),
    poses.jsonl}`` under the write root (``runs/`` by hand: ``io.outputs.write_root``),
    writes the arm state file, and on completion ``metrics/runs/<name>-arm.json``.
    ``park``: only lift the needle from where the last session of this drawing left the
    arm and switch every output off (:attr:`~tattotronix.hardware.arm.ArmSession.park`).

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
        ramp_rad_s=speed, ik=ik_options(cfg.ik), dry_run=bool(cfg.dry_run),
        realtime=bool(cfg.realtime), resume=bool(cfg.resume), park=park,
        fail_after_writes=cfg.hardware.fail_after_writes,
        save_every_s=float(cfg.hardware.save_every_s))
    log.info("arm %s: %d frames at %g Hz (%.1f s), %s%s", drawing.name, program.frames,
             program.frame_hz, program.frames / program.frame_hz,
             "dry run" if session.dry_run else f"{calib.device} at 0x{calib.address:02x}",
             ", parking" if park else ", resuming" if session.resume else "")
    summary = session.run()
    summary["program_metrics"] = program.metrics(calib, session.chain)
    out.write_json(out.path("metrics", "runs", f"{drawing.name}-arm.json"), summary)
    log.info("arm %s: %s, %d frames sent, %d channel writes, %.1f s", drawing.name,
             summary["status"], summary["frames_sent"], summary["channel_writes"],
             summary["wall_s"])
    return summary
