"""A drawing simulated closed loop: the configured controller, tuned at the drawing's own
pose, and the configured plant (MuJoCo, PyBullet or the model), assembled from the
settings (:func:`run_closed_loop`; the servo plant's is :mod:`tattotronix.app.servos`).
"""

from __future__ import annotations

import logging
import math
from dataclasses import replace
from pathlib import Path

import numpy as np

from tattotronix.config.schema import Config
from tattotronix.control.analysis import loop_report
from tattotronix.control.controller import Controller, Gains
from tattotronix.control.drawing import ClosedLoop, Drawing, Progress, check_tick_budget
from tattotronix.control.dynamics import Dynamics
from tattotronix.control.reference import reference_at_ticks, resolve_window
from tattotronix.control.simulate import Loop, simulate, substeps_per_tick
from tattotronix.control.verdict import Tolerance
from tattotronix.errors import StageInputMissing, TattotronixError
from tattotronix.plants import PlantSettings, Workpiece, make_plant
from tattotronix.robot.description import RobotDescription

__all__ = ["run_closed_loop"]

log = logging.getLogger("tattotronix.draw")


def run_closed_loop(cfg: Config, data: Path, desc: RobotDescription, drawing: Drawing, *,
                    window: object = None, plant_dt_s: float | None = None,
                    progress: bool = False, viewer: bool = False,
                    loop: Loop = "auto", workpiece: Workpiece | None = None) -> ClosedLoop:
    """Run ``drawing`` closed loop on the configured backend and controller.

    Args:
        cfg: the settings (``backend``, ``controller``, ``plant``, ``draw``).
        data: the data folder (the generated URDF and MJCF).
        desc: the robot description.
        drawing: what to play.
        window: ``None`` (all), ``[start_s, length_s]`` or ``"busiest"``
            (``study.window_s`` long).
        plant_dt_s: the plant step, s (default ``plant.dt_s``).
        progress: show a progress bar.
        viewer: watch the run where a display exists.
        loop: which path runs the controller (:func:`~tattotronix.control.simulate.simulate`;
            ``auto``: the engine wherever it can).
        workpiece: what the needle draws on in the panel's place (a limb): shown by the
            plant, never collided with.

    Raises:
        TattotronixError: missing models, a bad rate, tuning pose or window.
    """
    backend = cfg.backend.name
    if backend == "servo":
        raise TattotronixError("the servo plant plays the servo program, not this loop: "
                               "use tattotronix.app.servos.run_servo_loop")
    urdf = data / "robot" / f"{desc.name}.urdf"
    mjcf = data / "robot" / f"{desc.name}.xml"
    for f in (urdf, mjcf):
        if not f.exists():
            raise StageInputMissing(f, "robot")
    start, end = resolve_window(window, drawing.t, drawing.kind, float(cfg.study.window_s))
    ctl = cfg.controller
    rate = float(ctl.rate_hz)
    if not (math.isfinite(rate) and rate > 0):
        raise TattotronixError(f"controller.rate_hz={rate}: give a positive rate in Hz")
    check_tick_budget(end - start, rate)
    ref = reference_at_ticks(drawing.t, drawing.q, drawing.qd, 1.0 / rate, start, end)
    dyn = Dynamics(urdf, desc.gravity)
    tune_q = np.asarray(ctl.tune_q if ctl.tune_q is not None else ref.middle_pose(),
                        dtype=np.float64)
    if tune_q.shape != (dyn.n,):
        raise TattotronixError(f"controller.tune_q has {tune_q.size} values: give {dyn.n} "
                               "joint angles in rad, or null")
    gains = Gains.tuned_at(dyn, tune_q, float(ctl.wn))
    effort = np.array([j.effort for j in desc.joints])
    limit = effort if ctl.torque_limit_nm is None else float(ctl.torque_limit_nm)
    controller = Controller(dyn, gains, ctl.structure, rate, limit)
    settings = PlantSettings.from_settings(cfg.plant, desc.gravity, desc.tip_frame)
    if plant_dt_s is not None:
        settings = replace(settings, dt_s=float(plant_dt_s))
    sub = substeps_per_tick(controller.period_s, settings.dt_s)
    analysis = loop_report(dyn.mass_matrix(tune_q), gains.j_eff, gains.wn, rate, sub)
    sample_every = max(1, round(float(cfg.draw.sample_s) * rate))
    label = f"{drawing.name} on {backend}"
    log.info("draw %s: %s drawing, %.1f..%.1f s, %s at wn %g rad/s, %g Hz, plant %g Hz "
             "(wn T %.3f, sampled boundary %.3f)", label, drawing.origin, start, end,
             controller.structure.name, gains.wn, rate, 1.0 / settings.dt_s,
             analysis["wnT"], analysis["sampled_boundary_numeric_wnT"])
    bar = Progress(ref.duration_s, label, progress)
    try:
        with make_plant(backend, settings, urdf=urdf, mjcf=mjcf,
                        joint_names=desc.joint_names, lower=desc.lower, upper=desc.upper,
                        viewer=viewer, workpiece=workpiece) as plant:
            run = simulate(plant, controller, ref, sample_every=sample_every,
                           abort_error_rad=float(cfg.plant.abort_error_rad), progress=bar,
                           viewer=viewer, loop=loop)
    finally:
        bar.close()
    return ClosedLoop(drawing, run, controller.summary(), analysis, (start, end),
                      sample_every, backend, settings.dt_s, gains.wn, controller.period_s,
                      Tolerance.from_settings(cfg.draw, cfg.toolpath))
