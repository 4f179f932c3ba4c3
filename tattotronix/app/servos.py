"""A drawing on the servo plant (``backend=servo``; docs/servos.md): the servo program the
``deploy`` stage would send, played by the arm's hobby servos, scored like every other
backend's run.

Steps:

1. the calibration (``hardware``), each joint's servo
   (:func:`~tattotronix.hardware.servo_model.joint_servos`: as mounted or ``servo.type``),
   and, with ``hardware.compensate.fit``, each servo measured and fitted first (the
   ``servo_pulse`` procedure, simulated);
2. the program, as ``deploy`` compiles it (:func:`tattotronix.app.arm.build_program`,
   with the corrections ``hardware.compensate`` switches on);
3. what each servo turns to every frame: its count's width through the servo's own
   pulse map (``servo.quantise=false``: the exact width; a bus servo: the angle rounded to
   its encoder step);
4. the servo arm plays those frames (:class:`~tattotronix.plants.servo_plant.ServoArm`);
   the links' angles at every plant step are the run, against the drawing's reference
   at the same steps.

The verdict is every backend's (:mod:`tattotronix.control.verdict`): the marking error
against the drawing's tolerance (``draw.tolerance_needle_widths`` of the needle), so a
servo arm that would miss the drawing by millimetres ends ``out-of-tolerance``, with a
``WARNING:`` line that says by how much the real arm will miss; ``saturated`` where a
servo reached its stall torque (with ``servo.lag``), ``diverged`` where a joint left its
reference by ``plant.abort_error_rad``.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, fields, replace
from pathlib import Path

import numpy as np

from tattotronix.app.arm import build_program
from tattotronix.config.schema import Config
from tattotronix.control.drawing import ClosedLoop, Drawing, Progress
from tattotronix.control.reference import reference_at_ticks, resolve_window
from tattotronix.control.simulate import Run, saturation
from tattotronix.control.verdict import Tolerance
from tattotronix.errors import StageInputMissing, TattotronixError
from tattotronix.hardware.arm import calibration_from_config
from tattotronix.hardware.program import ServoProgram
from tattotronix.hardware.servo_model import joint_servos, servo_figures, with_measured_fits
from tattotronix.hardware.servos import Calibration
from tattotronix.io.jsontypes import JsonDict
from tattotronix.plants.base import Array, PlantSettings
from tattotronix.plants.servo_plant import ServoSpec
from tattotronix.robot.description import RobotDescription

__all__ = ["ServoSetup", "run_servo_loop", "servo_commands", "servo_setup"]

log = logging.getLogger("tattotronix.draw")


@dataclass(frozen=True)
class ServoSetup:
    """The servos and the program a servo-plant run plays.

    Attributes:
        specs: each joint's servo.
        calib: the calibration the program was compiled with (measured fits included).
        program: the servo program.
        command: (F, n) the angle each servo turns to for its frame's command, rad.
    """

    specs: tuple[ServoSpec, ...]
    calib: Calibration
    program: ServoProgram
    command: Array


def servo_commands(program: ServoProgram, calib: Calibration, specs: tuple[ServoSpec, ...],
                   quantise: bool) -> Array:
    """(F, n) the angle each servo turns to for each frame (servo A of each joint), rad."""
    assert program.q_sent is not None
    out = np.empty_like(program.q_sent)
    col = {ch: i for i, ch in enumerate(program.channels)}
    for i, (j, s) in enumerate(zip(calib.joints, specs, strict=True)):
        sent = program.q_sent[:, i]
        if s.bus:  # positions in encoder steps (the PCA9685's counts play no part)
            out[:, i] = np.round(sent / s.step_rad) * s.step_rad if quantise else sent
            continue
        if quantise:
            width = program.counts[:, col[j.a.channel]].astype(np.float64) * program.count_us
        else:
            width = np.array([j.a.pulse_us(float(x)) for x in sent])
        out[:, i] = s.true_angle(j.a, width)
    return out


def servo_setup(cfg: Config, desc: RobotDescription, drawing: Drawing,
                truth: Sequence[ServoSpec] | None = None) -> ServoSetup:
    """The servos, the (possibly measured) calibration and the program of ``drawing``.

    Args:
        truth: the servos as built, where they differ from the catalogue's (the
            robustness study's draws). The corrections are sized from the catalogue (the
            program cannot know better); the pulse-map fit is measured on ``truth`` (the
            user measures their own servos); the plant plays ``truth``.
    """
    calib = calibration_from_config(cfg.hardware, desc.joint_names)
    specs = joint_servos(cfg.robot, desc.joint_names, calib, cfg.servo,
                         servo_figures(cfg.hardware, desc.joint_names))
    built = specs if truth is None else tuple(truth)
    if len(built) != len(specs):
        raise TattotronixError(f"{len(built)} servos given for {len(specs)} joints")
    if cfg.hardware.compensate.fit:
        calib = with_measured_fits(calib, built, cfg.servo)
    program, calib = build_program(cfg, desc, drawing.t, drawing.q, drawing.qd, calib, specs)
    return ServoSetup(built, calib, program,
                      servo_commands(program, calib, built, bool(cfg.servo.quantise)))


def _summary(setup: ServoSetup, cfg: Config) -> JsonDict:
    """The servos' figures (the run's ``controller`` and ``loop`` sections)."""
    s = cfg.servo
    comp = cfg.hardware.compensate
    return {
        "structure": "servo", "frame_hz": setup.program.frame_hz,
        "servos": [sp.type for sp in setup.specs],
        "imperfections": {k: bool(getattr(s, k)) for k in
                          ("quantise", "deadband", "backlash", "nonlinearity", "lag")},
        "compensate": {f.name: bool(getattr(comp, f.name)) for f in fields(comp)},
        "deadband_deg": [math.degrees(sp.deadband_rad) for sp in setup.specs],
        "backlash_deg": [math.degrees(sp.backlash_rad) for sp in setup.specs],
        "latency_ms": [sp.latency_s * 1e3 for sp in setup.specs],
    }


def run_servo_loop(cfg: Config, data: Path, desc: RobotDescription, drawing: Drawing, *,
                   window: object = None, progress: bool = False,
                   plant_dt_s: float | None = None,
                   truth: Sequence[ServoSpec] | None = None) -> ClosedLoop:
    """Play ``drawing`` on the servo plant (module docstring); ``truth``: the servos as
    built, where they differ from the catalogue (:func:`servo_setup`).

    Raises:
        TattotronixError: missing models, a bad window, or a servo the catalogue lacks.
    """
    from tattotronix.plants.servo_plant import ServoArm

    mjcf = data / "robot" / f"{desc.name}.xml"
    if not mjcf.exists():
        raise StageInputMissing(mjcf, "robot")
    start, end = resolve_window(window, drawing.t, drawing.kind, float(cfg.study.window_s))
    setup = servo_setup(cfg, desc, drawing, truth)
    prog = setup.program
    first = int(math.floor(start * prog.frame_hz + 1e-9))
    last = min(prog.frames - 1, int(math.ceil(end * prog.frame_hz - 1e-9)))
    if last - first < 1:
        raise TattotronixError(f"the stretch {start:.3f}..{end:.3f} s is shorter than two "
                               f"servo frames ({1 / prog.frame_hz * 1e3:g} ms)")
    settings = PlantSettings.from_settings(cfg.plant, desc.gravity, desc.tip_frame)
    if plant_dt_s is not None:
        settings = replace(settings, dt_s=float(plant_dt_s))
    command = setup.command[first:last + 1]
    t0 = first / prog.frame_hz
    q0 = command[0]
    label = f"{drawing.name} on servo"
    log.info("draw %s: %s drawing, %.1f..%.1f s, %d frames at %g Hz, servos %s, plant %g Hz",
             label, drawing.origin, t0, last / prog.frame_hz, len(command), prog.frame_hz,
             "/".join(dict.fromkeys(s.type for s in setup.specs)), 1.0 / settings.dt_s)
    bar = Progress((len(command) - 1) / prog.frame_hz, label, progress)
    wall0 = time.perf_counter()
    try:
        arm = ServoArm(mjcf, settings, setup.specs, lag=bool(cfg.servo.lag),
                       ideal_wn=float(cfg.servo.ideal_wn), q0=q0)
        played = arm.run(command, prog.frame_hz, q0,
                         progress=lambda s: bar(s, time.perf_counter() - wall0))
    finally:
        bar.close()
    wall = time.perf_counter() - wall0
    ref = reference_at_ticks(drawing.t, drawing.q, drawing.qd, settings.dt_s, t0,
                             min(float(drawing.t[-1]), last / prog.frame_hz))
    k = min(ref.ticks, len(played.t))
    q = played.q[:k]
    sample_every = max(1, round(float(cfg.draw.sample_s) / settings.dt_s))
    err = np.max(np.abs(q - ref.q[:k]), axis=1) if k else np.zeros(0)
    bad = np.flatnonzero(err > float(cfg.plant.abort_error_rad))
    reason = ""
    if not played.healthy:
        reason = "the plant's state is not finite (the engine reported instability)"
    elif len(bad):
        reason = (f"a joint left its reference by more than plant.abort_error_rad="
                  f"{float(cfg.plant.abort_error_rad):g} rad at {ref.t[bad[0]]:.3f} s")
    stall = np.array([s.stall_nm for s in setup.specs])
    verdict = "diverged" if reason else "ok"
    if not reason and cfg.servo.lag:  # without lag the servos are stiff: no torque limit
        reason = saturation(played.tau[:k], stall, ref.t[:k], desc.joint_names,
                            "its servo's stall torque")
        verdict = "saturated" if reason else "ok"
    run = Run(backend="servo", t=ref.t[:k].copy(), q=q, qd_samples=played.qd[:k:sample_every],
              sample_every=sample_every, tau=played.tau[:k], ref=ref,
              completed=verdict != "diverged", verdict=verdict, reason=reason, wall_s=wall,
              substeps=1, loop="engine")
    wn = _servo_wn(setup.specs, bool(cfg.servo.lag), float(cfg.servo.ideal_wn))
    summary = _summary(setup, cfg)
    return ClosedLoop(drawing, run, {**summary, "wn": wn}, None,
                      (t0, t0 + (k - 1) * settings.dt_s), sample_every, "servo",
                      settings.dt_s, wn, settings.dt_s,
                      Tolerance.from_settings(cfg.draw, cfg.toolpath))


def _servo_wn(specs: tuple[ServoSpec, ...], lag: bool, ideal_wn: float) -> float:
    """The slowest servo's corner, rad/s: its loop's pole ``kp / back_emf`` (the stiff
    loop's ``ideal_wn`` without lag); "settled" waits ``settle_periods`` of it."""
    if not lag:
        return ideal_wn
    return float(min(s.kp / s.back_emf for s in specs))
