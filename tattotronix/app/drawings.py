"""A drawing's use cases on the simulated plants: which drawing to play, and what a run writes.

What is played (:func:`resolve_drawing`):

* ``art=NAME`` (or the default artwork's name): the stored ``data/trajectories/NAME.npz``.
  If it was planned at another ``speed`` (or other trajectory settings), it is re-timed
  here from ``data/ik/NAME.npz``; a built-in artwork with no stored files is planned here.
* ``artwork.source=PATH``: the file is planned here, in memory (every stage).

What is written (:func:`score_and_write`; paths other tools rely on, README, "The stages"):
``data/runs/<name>-<backend>/log.npz`` (the sampled run), ``.../ink.png`` (what the
simulated needle drew), ``.../ink_vs_plan.png`` (both inks, coloured by agreement) and
``data/metrics/runs/<name>-<backend>.json``.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from tattotronix.app.pipeline import mask_of, plan_drawing_on, trajectory_from_path
from tattotronix.art.artwork import BUILTINS, artwork_name, check_same_source, source_label
from tattotronix.art.grid import InkMask
from tattotronix.config.schema import Config, to_dict
from tattotronix.control.drawing import ClosedLoop, Drawing, finite_json, score_ink
from tattotronix.control.verdict import length_text
from tattotronix.errors import TattotronixError
from tattotronix.io.artifacts import (
    TRAJECTORY,
    IkRecord,
    RunLogRecord,
    ToolpathRecord,
    TrajectoryRecord,
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
from tattotronix.robot.description import RobotDescription
from tattotronix.trajectory import JointPath

__all__ = ["available_drawings", "check_run_source", "resolve_drawing", "score_and_write"]

log = logging.getLogger("tattotronix.draw")
Array = NDArray[np.float64]


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
        st = TrajectoryRecord.load(stored)
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


def _ink_image(sim: NDArray[np.bool_]) -> Any:
    """The simulated ink as an image: black ink on white, one pixel per raster pixel."""
    from PIL import Image

    return Image.fromarray(np.where(sim, 0, 255).astype(np.uint8), mode="L")


def check_run_source(cfg: Config, out: Outputs) -> None:
    """A file named by its stem (``artwork.source=mine.png``, no ``artwork.name``) must not
    overwrite the run of another file of the same stem (``mine.svg``): refused, naming both
    (:func:`~tattotronix.art.artwork.check_same_source`)."""
    source = cfg.artwork.source
    if cfg.art is None and cfg.artwork.name is None and source is not None and str(
            source) not in BUILTINS:
        name = artwork_name(cfg.artwork)
        label = run_label(name, cfg.backend.name, out.sweep_suffix(_NOT_IN_LABEL))
        check_same_source(out.path("metrics", "runs", f"{label}.json"), source, name,
                          replacing=True)


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
    grid, sim_ink, plan_ink, ink = score_ink(tip, tip_ref, cfg.toolpath.panel_origin,
                                             float(cfg.draw.ink_res_mm),
                                             float(cfg.toolpath.needle_width_mm), corners)
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
           out.provenance(cfg, drawing.inputs))
    metrics = loop.metrics(err)
    artwork_file = drawing.inputs.get("artwork")
    metrics["source"] = None if artwork_file is None else source_label(artwork_file)
    metrics.update(finite_json({
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
