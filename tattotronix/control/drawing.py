"""A timed drawing played closed loop on a simulated plant, and its ink.

* :class:`Drawing`: a timed drawing to play (times, angles, rates, kinds);
* :class:`ClosedLoop`: a run of it on a plant, with what set it up; its tracking errors
  and verdict (the run itself is assembled from the settings by the application:
  :func:`tattotronix.app.simulate.run_closed_loop`);
* :func:`score_ink`: the simulated and the planned ink on one grid, compared;
* :class:`Progress`: a progress bar over simulated seconds.

Which drawing to play, and what a run writes, are the application's
(:mod:`tattotronix.app.drawings`).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from tattotronix.art.grid import InkMask
from tattotronix.control.analysis import LoopReport
from tattotronix.control.ink import (
    InkComparison,
    InkGrid,
    compare_ink,
    ink_grid,
    rasterise_ink,
)
from tattotronix.control.simulate import Run
from tattotronix.control.tracking import TrackingErrors, tracking_errors
from tattotronix.control.verdict import Judgement, Tolerance, judge
from tattotronix.errors import TattotronixError
from tattotronix.io.jsontypes import JsonDict
from tattotronix.kinematics import Chain

__all__ = ["MAX_TICKS", "ClosedLoop", "Drawing", "Progress", "check_tick_budget",
           "finite_json", "score_ink", "warm_up"]

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


def finite_json(values: Mapping[str, object]) -> JsonDict:
    """``values`` as plain JSON: non-finite floats become None, numpy scalars Python
    numbers, tuples lists, recursively (metrics never hold NaN)."""
    out: JsonDict = _finite(dict(values))
    return out


class Progress:
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


def warm_up() -> None:
    """Import what every closed-loop run needs (the engines, the dynamics, python-control
    for the loop analysis): once, before forking workers that each run some."""
    import mujoco  # noqa: F401
    import pinocchio  # noqa: F401

    from tattotronix.control.analysis import step_overshoot_pct

    step_overshoot_pct(False)
    step_overshoot_pct(True)


def score_ink(tip: Array, tip_ref: Array, panel_origin_m: Sequence[float], res_mm: float,
              needle_mm: float, corners: Array | None = None
              ) -> tuple[InkGrid, NDArray[np.bool_], NDArray[np.bool_], InkComparison]:
    """The simulated and the planned ink of a run on one grid, and how they compare.

    Args:
        tip, tip_ref: the simulated and the planned tip at every tick, m.
        panel_origin_m: the panel's origin in the arm frame (``toolpath.panel_origin``), m.
        res_mm: the ink pixel (``draw.ink_res_mm``), mm.
        needle_mm: the needle's width (``toolpath.needle_width_mm``), mm.
        corners: panel points the grid must also cover (the artwork's corners), mm.
    """
    origin = np.asarray(panel_origin_m, dtype=np.float64)
    res = float(res_mm)
    needle = float(needle_mm)
    grid = ink_grid([tip, tip_ref], origin, res, cover_mm=corners)
    sim_ink = rasterise_ink(tip, origin, grid, needle)
    plan_ink = rasterise_ink(tip_ref, origin, grid, needle)
    return grid, sim_ink, plan_ink, compare_ink(sim_ink, plan_ink, res)
