"""``draw.py`` on a simulated plant: pick the drawing, run it closed loop, score it.

What is played:

* ``art=NAME`` (or the default artwork's name): the stored ``data/trajectories/NAME.npz``.
  If it was planned at another ``speed`` (or other trajectory settings), it is re-timed
  here from ``data/ik/NAME.npz``; a built-in artwork with no stored files is planned here.
* ``artwork.source=PATH``: the file is planned here, in memory (every stage).

What is written (paths other tools rely on; README, "The stages"):
``data/runs/<name>-<backend>/log.npz`` (the sampled run), ``.../ink.png`` (what the
simulated needle drew), ``.../ink_vs_plan.png`` (both inks, coloured by agreement) and
``data/metrics/runs/<name>-<backend>.json``.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from tattotronix.art.artwork import BUILTINS, artwork_name, check_same_source, source_label
from tattotronix.art.grid import InkMask
from tattotronix.config.schema import Config, to_dict
from tattotronix.control.analysis import LoopReport, loop_report
from tattotronix.control.controller import Controller, Gains
from tattotronix.control.dynamics import Dynamics
from tattotronix.control.ink import (
    InkComparison,
    InkGrid,
    compare_ink,
    ink_grid,
    rasterise_ink,
)
from tattotronix.control.reference import reference_at_ticks, resolve_window
from tattotronix.control.simulate import Loop, Run, simulate, substeps_per_tick
from tattotronix.control.tracking import TrackingErrors, tracking_errors
from tattotronix.control.verdict import Judgement, Tolerance, judge, length_text
from tattotronix.errors import StageInputMissing, TattotronixError
from tattotronix.io.artifacts import (
    TRAJECTORY,
    IkRecord,
    RunLogRecord,
    ToolpathRecord,
    TrajectoryRecord,
    make_provenance,
    run_dir,
    run_label,
)
from tattotronix.io.jsontypes import JsonDict
from tattotronix.io.outputs import Outputs
from tattotronix.kinematics import Chain
from tattotronix.path.fidelity import (
    artwork_fidelity,
    artwork_on,
    line_runs,
    line_width,
)
from tattotronix.path.inkfigure import artwork_ink_figure, plan_ink_figure
from tattotronix.plants import PlantSettings, make_plant
from tattotronix.robot.description import RobotDescription, build_description
from tattotronix.trajectory import JointPath, load_trajectory

__all__ = ["MAX_TICKS", "ClosedLoop", "Drawing", "available_drawings", "check_tick_budget",
           "draw_simulated", "resolve_drawing", "run_closed_loop", "score_and_write",
           "score_ink", "warm_up"]

log = logging.getLogger("tattotronix.draw")
Array = NDArray[np.float64]


@dataclass(frozen=True)
class Drawing:
    """A timed drawing to play.

    Attributes:
        name: names the outputs.
        t, q, qd: point times (s), angles (rad), rates (rad/s).
        kind: point kinds (0 travel, 1 mark, 2 approach).
        origin: ``stored``, ``retimed`` or ``planned``.
        inputs: files it came from (role -> path), for the provenance.
        mask: the ink mask a drawing planned here was planned on (its ink is scored
            against it); None for a stored or re-timed one (the mask stage's file).
    """

    name: str
    t: Array
    q: Array
    qd: Array
    kind: NDArray[np.int8]
    origin: str
    inputs: dict[str, Path] = field(default_factory=dict)
    mask: InkMask | None = None


def available_drawings(data: Path) -> list[str]:
    """Stored trajectories and built-in artworks, by name."""
    stored = sorted(p.stem for p in TRAJECTORY.find(data))
    return stored + [b for b in BUILTINS if b not in stored]


#: toolpath keys that only time the path: a change re-times the stored IK path
_TIMING_KEYS = ("feed_mark_mm_s", "feed_travel_mm_s", "lift_s")


def _plain(cfg: Config | Mapping[str, Any]) -> dict[str, Any]:
    """The settings as plain values (a stored provenance's config is already plain)."""
    c: Mapping[str, Any] = to_dict(cfg) if isinstance(cfg, Config) else cfg
    return {str(k): v for k, v in c.items()}


def _path_settings(cfg: Config | Mapping[str, Any]) -> dict[str, Any]:
    """The settings that shape the joint path (mask, toolpath geometry, IK)."""
    c = _plain(cfg)
    return {"mask": c.get("mask"), "ik": c.get("ik"),
            "toolpath": {k: v for k, v in (c.get("toolpath") or {}).items()
                         if k not in _TIMING_KEYS}}


def _timing_settings(cfg: Config | Mapping[str, Any]) -> dict[str, Any]:
    """The settings that time the path (speed, the time law, the marking feed, the planned
    travel's collision margin)."""
    c = _plain(cfg)
    return {"speed": float(c["speed"]), "trajectory": c["trajectory"],
            "feed_mark_mm_s": float(c["toolpath"]["feed_mark_mm_s"]),
            "collision": c.get("collision")}


def _differ(want: dict[str, Any], have: dict[str, Any] | None) -> list[str]:
    return sorted(k for k in want if have is None or have.get(k) != want[k])


def resolve_drawing(cfg: Config, data: Path, desc: RobotDescription) -> Drawing:
    """Find or plan the drawing ``cfg`` asks for (see the module docstring).

    A stored trajectory is played as is when it was planned with this config's path and
    timing settings; re-timed from the stored IK path when only the timing differs
    (``speed``, ``trajectory.*``, the marking feed); re-planned from the artwork, in
    memory, when the path itself differs (``mask.*``, ``toolpath.*``, ``ik.*``).

    Raises:
        TattotronixError: an unknown ``art`` (the message lists those available), or
            whatever planning refuses.
    """
    from tattotronix.pipeline import plan_drawing_on, trajectory_from_path

    def planned(source: str | Path, inputs: dict[str, Path]) -> Drawing:
        traj, mask = plan_drawing_on(cfg, source, name, desc)
        return Drawing(name, traj.t, traj.q, traj.qd, traj.kind, "planned", inputs, mask)

    source = cfg.artwork.source
    art = cfg.art
    if art is None and source is not None and str(source) not in BUILTINS:
        name = artwork_name(cfg.artwork)
        return planned(source, {"artwork": Path(str(source))})
    name = str(art) if art is not None else artwork_name(cfg.artwork)
    stored = TrajectoryRecord.path(data, name=name)
    ik_file = IkRecord.path(data, name=name)
    same_path = True
    planned_from: object = None
    if stored.exists():
        st = load_trajectory(stored)
        config = st.provenance.get("config")
        have = config if isinstance(config, Mapping) else None
        path_diff = _differ(_path_settings(cfg), _path_settings(have) if have else None)
        time_diff = _differ(_timing_settings(cfg), _timing_settings(have) if have else None)
        if not path_diff and not time_diff:
            return Drawing(name, st.t, st.q, st.qd, st.kind, "stored", {"trajectory": stored})
        same_path = not path_diff
        artwork = (have or {}).get("artwork")
        planned_from = artwork.get("source") if isinstance(artwork, Mapping) else None
        log.info("draw %s: the stored trajectory was planned with other %s: %s", name,
                 ", ".join(path_diff + time_diff), "re-timing" if same_path else "re-planning")
    if same_path and ik_file.exists():
        traj = trajectory_from_path(cfg, JointPath.from_npz(ik_file), desc)
        return Drawing(name, traj.t, traj.q, traj.qd, traj.kind, "retimed", {"ik": ik_file})
    if name in BUILTINS:
        return planned(name, {})
    if not same_path and planned_from is not None and Path(str(planned_from)).is_file():
        return planned(str(planned_from), {"artwork": Path(str(planned_from))})
    if not same_path:
        raise TattotronixError(
            f"the drawing '{name}' was planned with other path settings and is not a "
            "built-in artwork: give artwork.source=PATH to re-plan it")
    raise TattotronixError(
        f"no drawing named '{name}': available are {', '.join(available_drawings(data))} "
        "(or give artwork.source=PATH to plan a new one)")


def _finite(obj: Any) -> Any:
    """Replace non-finite floats by None, recursively (metrics never hold NaN)."""
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: _finite(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_finite(v) for v in obj]
    if isinstance(obj, np.floating | np.integer):
        return _finite(obj.item())
    return obj


class _Progress:
    """tqdm bar over simulated seconds, showing the real-time factor."""

    def __init__(self, total_s: float, label: str, enabled: bool):
        self.bar = None
        if enabled:
            from tqdm import tqdm

            self.bar = tqdm(total=round(total_s, 2), unit="s", desc=label, leave=True,
                            bar_format="{desc}: {n:.1f}/{total:.1f} s simulated "
                                       "[{elapsed}<{remaining}{postfix}]")
        self.done = 0.0

    def __call__(self, sim_s: float, wall_s: float) -> None:
        if self.bar is None:
            return
        self.bar.update(round(sim_s - self.done, 2))
        self.done = sim_s
        self.bar.set_postfix_str(f"{sim_s / max(wall_s, 1e-9):.0f}x real time", refresh=False)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


def _ink_image(sim: NDArray[np.bool_]) -> Any:
    """The simulated ink as an image: black ink on white, one pixel per raster pixel."""
    from PIL import Image

    return Image.fromarray(np.where(sim, 0, 255).astype(np.uint8), mode="L")


@dataclass(frozen=True)
class ClosedLoop:
    """A closed-loop run of a drawing, with what set it up.

    Attributes:
        drawing: what was played.
        run: the run (ticks, torques, verdict).
        controller: what closed the loop (``Controller.summary()``, or the servos').
        analysis: the loop analysis at the tuning pose (:func:`loop_report`); None on the
            servo plant (its servos' figures are in ``controller``).
        window: ``(start_s, end_s)`` of the stretch that ran.
        sample_every: ticks between error samples.
        backend: the plant.
        plant_dt_s: the plant's integration step, s.
        wn: the loop's bandwidth, rad/s ("settled" drops ``settle_periods / wn`` after
            each needle entry).
        period_s: the tick, s.
        tolerance: the drawing's marking tolerance (:mod:`tattotronix.control.verdict`).
    """

    drawing: Drawing
    run: Run
    controller: JsonDict
    analysis: LoopReport | None
    window: tuple[float, float]
    sample_every: int
    backend: str
    plant_dt_s: float
    wn: float
    period_s: float
    tolerance: Tolerance

    def samples(self) -> NDArray[np.intp]:
        """Tick indices of the error samples."""
        return np.arange(0, len(self.run.t), self.sample_every)

    def errors(self, chain: Chain, settle_periods: float,
               tips: tuple[Array, Array] | None = None) -> TrackingErrors:
        """The sampled tracking errors (docs/original.md, "5.5 Tracking error").

        Args:
            chain: the kinematic chain (FK of the tip).
            settle_periods: "settled" drops ``settle_periods / wn`` after each entry.
            tips: the simulated and reference tips at every tick, if already computed.
        """
        idx = self.samples()
        if tips is None:
            tip = chain.fk(self.run.q[idx])[0] if len(idx) else np.zeros((0, 3))
            tip_ref = chain.fk(self.run.ref.q[idx])[0] if len(idx) else np.zeros((0, 3))
        else:
            tip, tip_ref = tips[0][idx], tips[1][idx]
        return tracking_errors(self.run.t[idx], tip, tip_ref, self.drawing.t,
                               self.drawing.kind, self.wn, settle_periods)

    def judge(self, err: TrackingErrors) -> Judgement:
        """The run's verdict: the loop's, and the marking error against the tolerance
        (:func:`tattotronix.control.verdict.judge`)."""
        worst = err.metrics()["marking_max_um"]
        return judge(self.run.verdict, self.run.reason,
                     float(worst) if isinstance(worst, int | float) else None, self.tolerance)

    def metrics(self, err: TrackingErrors) -> JsonDict:
        """Tracking, verdict, controller, plant and loop analysis: plain JSON values. A run
        that diverged has no error statistics (None, ``tracking_reason`` says why)."""
        verdict = self.judge(err)
        errors = err.metrics() if verdict.stable else err.unscored(
            f"not scored: the run diverged; {self.run.reason}; the errors of the "
            f"{self.run.sim_s:.3f} s that ran are in its log and say nothing of the drawing")
        return _finite({
            "name": self.drawing.name, "backend": self.backend,
            "drawing": self.drawing.origin,
            "window_s": [self.window[0], self.window[1] - self.window[0]],
            **errors,
            **self.run.summary(),  # peak torque, real-time factor, wall/sim time
            **verdict.metrics(),  # the verdict and its reason, stable, within tolerance
            "controller": self.controller,
            "loop": self.analysis if self.analysis is not None else {},
            "sample_s": self.sample_every * self.period_s,
        })


#: most controller ticks one run logs (~300 bytes each: measured angles, torques, the
#: reference, the tip); the built-in emblem is 0.6 million at 1 kHz
MAX_TICKS = 10_000_000
_TICK_BYTES = 300


def check_tick_budget(duration_s: float, rate_hz: float) -> None:
    """Refuse a run of more than :data:`MAX_TICKS` controller ticks, before simulating.

    Raises:
        TattotronixError: over budget; the message gives the estimate and what to change.
    """
    ticks = duration_s * rate_hz
    if ticks > MAX_TICKS:
        raise TattotronixError(
            f"the run is {duration_s:.4g} s at controller.rate_hz={rate_hz:g}: {ticks:.3g} "
            f"controller ticks, over the budget of {MAX_TICKS:.3g} (~"
            f"{ticks * _TICK_BYTES / 2**30:.1f} GiB of logs): run a window "
            "(window=[start_s, length_s]), lower controller.rate_hz, or plan a faster "
            "drawing (speed, toolpath.feed_mark_mm_s)")


def run_closed_loop(cfg: Config, data: Path, desc: RobotDescription, drawing: Drawing, *,
                    window: object = None, plant_dt_s: float | None = None,
                    progress: bool = False, viewer: bool = False,
                    loop: Loop = "auto") -> ClosedLoop:
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

    Raises:
        TattotronixError: missing models, a bad rate, tuning pose or window.
    """
    backend = cfg.backend.name
    if backend == "servo":
        raise TattotronixError("the servo plant plays the servo program, not this loop: "
                               "use tattotronix.hardware.servo_loop.run_servo_loop")
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
    settings = PlantSettings.from_config(cfg.plant, desc.gravity, desc.tip_frame)
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
    bar = _Progress(ref.duration_s, label, progress)
    try:
        with make_plant(backend, settings, urdf=urdf, mjcf=mjcf,
                        joint_names=desc.joint_names, lower=desc.lower, upper=desc.upper,
                        viewer=viewer) as plant:
            run = simulate(plant, controller, ref, sample_every=sample_every,
                           abort_error_rad=float(cfg.plant.abort_error_rad), progress=bar,
                           viewer=viewer, loop=loop)
    finally:
        bar.close()
    return ClosedLoop(drawing, run, controller.summary(), analysis, (start, end),
                      sample_every, backend, settings.dt_s, gains.wn, controller.period_s,
                      Tolerance.from_config(cfg))


def warm_up() -> None:
    """Import what every closed-loop run needs (the engines, the dynamics, python-control
    for the loop analysis): once, before forking workers that each run some."""
    import mujoco  # noqa: F401
    import pinocchio  # noqa: F401

    from tattotronix.control.analysis import step_overshoot_pct

    step_overshoot_pct(False)
    step_overshoot_pct(True)


def draw_simulated(cfg: Config, out: Outputs) -> JsonDict:
    """Run the configured drawing on the configured simulated backend; write its outputs.

    Returns:
        The run metrics (also written to ``data/metrics/runs/<name>-<backend>.json``).
    """
    source = cfg.artwork.source
    if cfg.art is None and cfg.artwork.name is None and source is not None and str(
            source) not in BUILTINS:  # a file named by its stem: mine.png and mine.svg
        name = artwork_name(cfg.artwork)
        label = run_label(name, cfg.backend.name, out.sweep_suffix(_NOT_IN_LABEL))
        check_same_source(out.path("metrics", "runs", f"{label}.json"), source, name,
                          replacing=True)
    desc = build_description(cfg.robot)
    drawing = resolve_drawing(cfg, out.data, desc)
    loop = run_closed_loop(cfg, out.data, desc, drawing, window=cfg.window,
                           progress=bool(cfg.draw.progress), viewer=bool(cfg.viewer))
    return score_and_write(cfg, out, loop, desc)


#: overrides a run's folder name never carries (the name and backend say them, or they
#: change nothing drawn)
_NOT_IN_LABEL = ("backend", "art", "artwork.name", "artwork.source", "draw.progress", "viewer")


def score_and_write(cfg: Config, out: Outputs, loop: ClosedLoop,
                    desc: RobotDescription) -> JsonDict:
    run, drawing, backend = loop.run, loop.drawing, loop.backend
    # the jobs of a multirun (draw.py -m controller.wn=40,80) each get their own outputs
    label = run_label(drawing.name, backend, out.sweep_suffix(_NOT_IN_LABEL))
    chain = Chain.from_description(desc)
    k = len(run.t)
    tip, _ = chain.fk(run.q) if k else (np.zeros((0, 3)), None)
    tip_ref, _ = chain.fk(run.ref.q[:k]) if k else (np.zeros((0, 3)), None)
    idx = loop.samples()
    err = loop.errors(chain, float(cfg.draw.settle_periods), (tip, tip_ref))
    res = float(cfg.draw.ink_res_mm)
    mask = _artwork_mask(cfg, out.data, drawing)
    corners = None if mask is None else np.array([[mask.xs[0], mask.ys[0]],
                                                  [mask.xs[-1], mask.ys[-1]]])
    grid, sim_ink, plan_ink, ink = score_ink(cfg, tip, tip_ref, corners)
    verdict = loop.judge(err)
    unscored = verdict.unscored_ink()  # a run that saturated or diverged: no ink scores
    if unscored:
        ink = ink.unscored(unscored)
    against_art: dict[str, Any] = {"artwork": None, "artwork_plan": None, "artwork_reason":
                                   "no artwork to compare the ink with (no stored mask)"}
    art = None if mask is None else artwork_on(mask, grid)
    sim_art = None
    if art is not None:
        lines = _planned_lines(out.data, drawing)
        sim_lw, plan_lw = ((line_width(sim_ink, grid, *lines), line_width(plan_ink, grid, *lines))
                           if lines else (None, None))
        sim_art = None if unscored else artwork_fidelity(art, sim_ink, res, lines=sim_lw)
        # the plan's ink is the whole plan's only where the run ran to the end
        plan_art = (artwork_fidelity(art, plan_ink, res, lines=plan_lw).metrics()
                    if run.completed else None)
        against_art = {"artwork": None if sim_art is None else sim_art.metrics(),
                       "artwork_plan": plan_art, "artwork_reason": unscored}

    run_folder = run_dir(out.root, label)
    dpi = 25.4 / res
    _ink_image(sim_ink).save(out.tmp_path(run_folder / "ink.png"), format="PNG", dpi=(dpi, dpi))
    needle = float(cfg.toolpath.needle_width_mm)
    pixels = ("" if ink.max_dev_mm is None else
              f" ({ink.max_dev_mm / res:.3g} × the {res:g} mm pixel)")
    plan_ink_figure(
        sim_ink, plan_ink, grid, out.tmp_path(run_folder / "ink_vs_plan.png"),
        f"{drawing.name} on {backend}: the simulated ink against the planned ink (needle "
        f"{needle:g} mm wide)\n{ink.text()}{pixels}")
    if art is not None:
        artwork_ink_figure(
            art, sim_ink, grid, out.tmp_path(run_folder / "ink_vs_artwork.png"),
            f"{drawing.name} on {backend}: the simulated ink against the artwork (needle "
            f"{needle:g} mm wide)", sim_art if sim_art is not None else f"ink {unscored}")
    RunLogRecord(
        joints=desc.joint_names, t=run.t[idx], q=run.q[idx], qd=run.qd_samples,
        tau=run.tau[idx], q_ref=run.ref.q[idx], qd_ref=run.ref.qd[idx], tip=tip[idx],
        tip_ref=tip_ref[idx], error_m=err.error_m, down=err.down, settled=err.settled,
    ).save(out.tmp_path(RunLogRecord.path(out.root, label=label)),
           make_provenance(cfg, drawing.inputs))
    metrics = loop.metrics(err)
    artwork_file = drawing.inputs.get("artwork")
    metrics["source"] = None if artwork_file is None else source_label(artwork_file)
    metrics.update(_finite({
        **ink.metrics(), **against_art,
        "plant": {"dt_s": loop.plant_dt_s, "substeps": run.substeps,
                  "damping": float(cfg.plant.damping),
                  "joint_limits": bool(cfg.plant.joint_limits),
                  "contacts": bool(cfg.plant.contacts)},
    }))
    out.write_json(out.path("metrics", "runs", f"{label}.json"), metrics)
    out.write_timings("runs", label, run.timings())
    iou = "-" if ink.iou is None else f"{ink.iou:.3f}"
    log.info("draw %s on %s: %s; settled %s / %s (mean / max), marking max %s, peak %.3f N m, "
             "ink IoU %s, %.0fx real time (%.1f s, the %s loop)",
             drawing.name, backend, verdict.verdict, _length(metrics["settled_mean_um"]),
             _length(metrics["settled_max_um"]), _length(metrics["marking_max_um"]),
             run.peak_torque_nm, iou, run.realtime_factor, run.wall_s, run.loop)
    warning = verdict.warning(f"{drawing.name} on {backend}", real_arm=backend == "servo")
    if warning:
        log.warning("%s", warning)
    return metrics


def score_ink(cfg: Config, tip: Array, tip_ref: Array, corners: Array | None = None
              ) -> tuple[InkGrid, NDArray[np.bool_], NDArray[np.bool_], InkComparison]:
    """The simulated and the planned ink of a run on one grid, and how they compare.

    Args:
        cfg: the settings (the panel's origin, the needle's width, the ink pixel).
        tip, tip_ref: the simulated and the planned tip at every tick, m.
        corners: panel points the grid must also cover (the artwork's corners), mm.
    """
    origin = np.asarray(cfg.toolpath.panel_origin, dtype=np.float64)
    res = float(cfg.draw.ink_res_mm)
    needle = float(cfg.toolpath.needle_width_mm)
    grid = ink_grid([tip, tip_ref], origin, res, cover_mm=corners)
    sim_ink = rasterise_ink(tip, origin, grid, needle)
    plan_ink = rasterise_ink(tip_ref, origin, grid, needle)
    return grid, sim_ink, plan_ink, compare_ink(sim_ink, plan_ink, res)


def _planned_lines(data: Path, drawing: Drawing) -> tuple[list[Array], list[float]] | None:
    """The line art's centrelines and designed widths from the toolpath the drawing was
    planned from (a stored or re-timed drawing); None where there is none."""
    stored = ToolpathRecord.path(data, name=drawing.name)
    if drawing.origin == "planned" or not stored.exists():
        return None
    rec = ToolpathRecord.load(stored)
    runs, widths = line_runs(rec.uvz_mm, rec.stroke, rec.stroke_width_mm)
    return (runs, widths) if runs else None


def _artwork_mask(cfg: Config, data: Path, drawing: Drawing) -> InkMask | None:
    """The ink mask the drawing was planned from: the mask stage's file for a stored or
    re-timed drawing, else the one it was planned on, or the artwork's, made here; None
    where there is none to make."""
    from tattotronix.pipeline import mask_of

    if drawing.mask is not None:
        return drawing.mask
    stored = data / "mask" / f"{drawing.name}.npz"
    if drawing.origin != "planned" and stored.exists():
        return InkMask.load(stored)
    source = drawing.inputs.get("artwork")
    if source is None and drawing.name in BUILTINS:
        return mask_of(cfg, drawing.name, drawing.name)
    if source is None:
        log.info("draw %s: no artwork to compare the ink with (no stored mask)", drawing.name)
        return None
    return mask_of(cfg, source, drawing.name)


def _length(um: object) -> str:
    """A metric in µm, in µm or (from a millimetre up) in mm; ``-`` where it is None."""
    return length_text(float(um) if isinstance(um, int | float) else None)
