"""Identification from a drawn sheet (issue 34, item 4; docs/servos.md, "Identification
from a drawn sheet"): the arm draws the calibration pattern on the sheet, the user
photographs it, and the servos' figures that the photo can tell are fitted so that the
servo plant draws what the photo shows.

* :func:`calibration_plan`: the pattern (:func:`~tattotronix.hardware.calibsheet.
  pattern_strokes`) planned as strokes on the panel, like any plan;
* :class:`SheetModel`: that drawing on the servo plant, as the settings compile it (the
  corrections they switch on included), with any servos: its ink on the sheet's grid and
  its marking tips;
* :func:`identify`: the backlash and the dead band (``FIGURES``) of each joint the
  pattern moves, as scale factors on the catalogue's, by nonlinear least squares
  (:func:`scipy.optimize.least_squares`, finite differences in the factors' logarithms):
  the residuals are the distance from each simulated marking tip to the photographed
  ink, plus a weak pull of each factor towards the catalogue (a figure the photo cannot
  tell stays the catalogue's).

The pulse map's bend is measured apart, with a protractor (``servo_pulse.py``, the
``fit`` correction): the pattern is drawn after it. The latency and the proportional band
move the ink by less than the photo resolves (docs/servos.md), so they are not fitted.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from tattotronix.app.servos import run_servo_loop
from tattotronix.config.params import with_overrides
from tattotronix.config.schema import Config
from tattotronix.control.drawing import Drawing
from tattotronix.control.tracking import down_at
from tattotronix.errors import TattotronixError
from tattotronix.hardware.arm import calibration_from_config
from tattotronix.hardware.calibsheet import pattern_strokes, sheet_grid
from tattotronix.hardware.servo_model import joint_servos
from tattotronix.kinematics import Chain
from tattotronix.path.fidelity import InkGrid, below_runs, distance_to, rasterise_runs
from tattotronix.plants.servo_plant import ServoSpec
from tattotronix.robot.description import RobotDescription

__all__ = ["DEFAULT_FIGURES", "FIGURES", "Identified", "SheetModel", "calibration_plan",
           "identify"]

if TYPE_CHECKING:
    from tattotronix.app.api import Plan

log = logging.getLogger("tattotronix.identify")

Array = NDArray[np.float64]
Mask = NDArray[np.bool_]

#: the servo figures the sheet can be asked for
FIGURES = ("backlash_rad", "deadband_rad")
#: those identified by default: the backlash. The dead band is a play on the command
#: side, the backlash one on the link's: on this pattern both leave the same ink (fitted
#: together, they trade off at the same residual: docs/servos.md), so the dead band stays
#: the catalogue's
DEFAULT_FIGURES = ("backlash_rad",)
#: a joint the pattern turns by less than this is not identified (its ink says nothing)
_MOVES_RAD = math.radians(2.0)
#: the pull of each factor's logarithm towards the catalogue, mm per unit
_PRIOR_MM = 0.02
#: every how many plant steps a marking tip is a residual
_EVERY = 5


def calibration_plan(overrides: Sequence[str] = (), workdir: str | Path | None = None,
                     strokes: Sequence[Array] | None = None) -> Plan:
    """The calibration pattern (or ``strokes`` of it) planned on the panel."""
    from tattotronix.app.api import plan_strokes

    return plan_strokes(pattern_strokes() if strokes is None else list(strokes),
                        name="calibration", overrides=overrides, workdir=workdir)


@dataclass(frozen=True)
class SheetModel:
    """The calibration drawing on the servo plant.

    Attributes:
        cfg: the settings (``backend=servo``; the corrections as the user compiles them).
        data: the folder holding the generated models (``robot/<name>.xml``).
        desc: the robot. drawing: the calibration drawing.
        grid: the sheet's grid.
    """

    cfg: Config
    data: Path
    desc: RobotDescription
    drawing: Drawing
    grid: InkGrid

    @classmethod
    def of(cls, cfg: Config, data: Path, desc: RobotDescription, drawing: Drawing,
           grid: InkGrid | None = None) -> SheetModel:
        return cls(with_overrides(cfg, ["backend=servo"]), data, desc, drawing,
                   grid or sheet_grid())

    @classmethod
    def of_plan(cls, plan: Plan) -> SheetModel:
        """The calibration drawing of ``plan`` (:func:`calibration_plan`), its models
        written into the plan's working folder."""
        from tattotronix.app.api import _robot_models

        _robot_models(plan.desc, plan.workdir)
        return cls.of(plan.cfg, plan.workdir, plan.desc, plan._drawing())

    def catalogue(self) -> tuple[ServoSpec, ...]:
        """The servos as the catalogue gives them (every imperfection the settings keep)."""
        calib = calibration_from_config(self.cfg.hardware, self.desc.joint_names)
        return joint_servos(self.cfg.robot, self.desc.joint_names, calib, self.cfg.servo)

    def tips_mm(self, specs: Sequence[ServoSpec]) -> tuple[Array, Array]:
        """The simulated tip at every plant step: the steps' times (K,), s, and the tips
        (K, 3), panel mm (z < 0: in the sheet)."""
        loop = run_servo_loop(self.cfg, self.data, self.desc, self.drawing, truth=specs)
        if loop.run.verdict == "diverged":
            raise TattotronixError(f"the calibration drawing diverged: {loop.run.reason}")
        tip = Chain.from_description(self.desc).fk(loop.run.q)[0]
        origin = np.asarray(self.cfg.toolpath.panel_origin, dtype=np.float64)
        return np.asarray(loop.run.t), np.asarray((tip - origin) * 1e3)

    def ink(self, specs: Sequence[ServoSpec]) -> Mask:
        """The ink the servo plant draws with ``specs``, on the sheet's grid."""
        return rasterise_runs(below_runs(self.tips_mm(specs)[1]), self.grid,
                              float(self.cfg.toolpath.needle_width_mm))

    def moving_joints(self) -> list[int]:
        """The joints the pattern turns by :data:`_MOVES_RAD` or more."""
        q = np.asarray(self.drawing.q)
        return [j for j in range(q.shape[1]) if float(np.ptp(q[:, j])) >= _MOVES_RAD]


@dataclass(frozen=True)
class Identified:
    """What the photo told.

    Attributes:
        specs: the servos: the catalogue's, with the fitted figures.
        factors: figure -> joint name -> fitted / catalogue (the joints identified).
        residual_mm: the mean distance from a simulated marking tip to the middle of the
            photographed lines, with the fitted figures (and with the catalogue's:
            ``residual_before_mm``).
        runs: servo-plant runs the fit took.
    """

    specs: tuple[ServoSpec, ...]
    factors: dict[str, dict[str, float]]
    residual_mm: float
    residual_before_mm: float
    runs: int


def _bilinear(field: NDArray[np.float32], grid: InkGrid, uv: Array) -> Array:
    """``field`` (on ``grid``) at panel points ``uv``, bilinear; off the grid: its edge."""
    px = grid.to_px(uv)
    rows, cols = field.shape
    c = np.clip(px[:, 0], 0, cols - 1.000001)
    r = np.clip(px[:, 1], 0, rows - 1.000001)
    c0, r0 = np.floor(c).astype(int), np.floor(r).astype(int)
    fc, fr = c - c0, r - r0
    f = field.astype(np.float64)
    return ((f[r0, c0] * (1 - fc) + f[r0, c0 + 1] * fc) * (1 - fr)
            + (f[r0 + 1, c0] * (1 - fc) + f[r0 + 1, c0 + 1] * fc) * fr)


def _off_centreline(ink: Mask, res_mm: float) -> NDArray[np.float32]:
    """How far each pixel is from the middle of the ink's lines, mm: outside the ink, the
    distance to it plus the lines' half-width; inside, the half-width less the depth (0
    on the middle of a line). The half-width is the ink's deepest (99th percentile of the
    depth): one line width, the needle's."""
    import cv2

    depth = np.asarray(cv2.distanceTransform(ink.astype(np.uint8), cv2.DIST_L2,
                                             cv2.DIST_MASK_PRECISE), dtype=np.float32)
    half = float(np.percentile(depth[ink], 99))
    out = distance_to(ink)
    field = np.where(ink, np.maximum(half - depth, 0.0), half + out)
    return (field * np.float32(res_mm)).astype(np.float32)


def identify(photo_ink: Mask, model: SheetModel, figures: Sequence[str] = DEFAULT_FIGURES,
             max_runs: int = 120) -> Identified:
    """Fit ``figures`` of each joint the pattern moves to the photographed ink (module
    docstring).

    Args:
        photo_ink: the photographed ink on ``model.grid``
            (:func:`~tattotronix.hardware.calibsheet.read_photo`).
        model: the calibration drawing on the servo plant.
        figures: the :class:`ServoSpec` figures to fit (of :data:`FIGURES`; by default
            :data:`DEFAULT_FIGURES`).
        max_runs: the most servo-plant runs the fit may take.

    Raises:
        TattotronixError: no ink in the photo, an unknown figure, or a drawing the plant
            cannot play.
    """
    from scipy.optimize import least_squares

    if not photo_ink.any():
        raise TattotronixError("the photo shows no ink on the sheet: draw the calibration "
                               "pattern, then photograph it")
    unknown = [f for f in figures if f not in FIGURES]
    if unknown:
        raise TattotronixError(f"cannot identify {', '.join(unknown)}: the sheet tells "
                               f"{', '.join(FIGURES)}")
    catalogue = model.catalogue()
    free = [(f, j) for f in figures for j in model.moving_joints()
            if float(getattr(catalogue[j], f)) > 0]
    if not free:
        raise TattotronixError(f"the calibration drawing turns no joint with a "
                               f"{' or '.join(figures)} to fit by 2 deg or more: draw the "
                               "built-in pattern")
    to_line = _off_centreline(photo_ink, model.grid.res_mm)
    runs = 0
    marking: NDArray[np.intp] | None = None  # the steps the plan marks (fixed: the plan's)

    def specs_of(x: Array) -> tuple[ServoSpec, ...]:
        out = list(catalogue)
        for (f, j), v in zip(free, x, strict=True):
            value = float(getattr(catalogue[j], f)) * math.exp(v)
            out[j] = replace(out[j], **{f: value})  # type: ignore[arg-type]
        return tuple(out)

    def residuals(x: Array) -> Array:
        nonlocal runs, marking
        runs += 1
        t, tips = model.tips_mm(specs_of(x))
        if marking is None:
            down = down_at(model.drawing.t, model.drawing.kind, t)
            marking = np.flatnonzero(down)[::_EVERY]
        return np.concatenate([_bilinear(to_line, model.grid, tips[marking, :2]),
                               _PRIOR_MM * x])

    x0 = np.zeros(len(free))
    before = residuals(x0)
    n_tips = len(before) - len(free)
    # a factor to 0.5 % is finer than the photo tells; each iteration costs a run per factor
    fit = least_squares(residuals, x0, diff_step=0.05, xtol=5e-3, ftol=1e-4, x_scale=1.0,
                        max_nfev=max(1, max_runs // (len(free) + 1)), method="trf")
    after = residuals(fit.x)
    names = model.desc.joint_names
    factors: dict[str, dict[str, float]] = {}
    for (f, j), v in zip(free, fit.x, strict=True):
        factors.setdefault(f, {})[names[j]] = float(math.exp(v))
    log.info("identified %s in %d servo-plant runs: residual %.3f -> %.3f mm", factors, runs,
             float(np.mean(before[:n_tips])), float(np.mean(after[:n_tips])))
    return Identified(specs_of(fit.x), factors, float(np.mean(after[:n_tips])),
                      float(np.mean(before[:n_tips])), runs)
