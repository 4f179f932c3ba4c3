"""Round turns between hatch runs (tattotronix/path/turns.py): inside the drag area, of
bounded curvature, and joined into the 3-D path by build_path_flat."""

from __future__ import annotations

import math

import numpy as np

from tattotronix.art.grid import InkMask
from tattotronix.config.schema import MaskConfig, PanelConfig, ToolpathConfig
from tattotronix.path.inklookup import lines_on_ink
from tattotronix.path.params import ToolpathParams
from tattotronix.path.path3d import MARK, build_path_flat
from tattotronix.path.polyline import resample
from tattotronix.path.turns import round_turns
from tattotronix.trajectory import path_derivatives
from tattotronix.trajectory.timelaw import JointLimits, TipLimit, time_parameterise

PARAMS = ToolpathParams.from_settings(ToolpathConfig(), MaskConfig(), PanelConfig())
STEP, PITCH = PARAMS.step_mm, PARAMS.pitch_mm


def _mask(half_w: float = 6.0, half_h: float = 4.0, res: float = 0.05) -> InkMask:
    """A rectangle of ink, ``2 half_w`` x ``2 half_h`` mm, in a 1 mm margin."""
    xs = np.arange(-half_w - 1, half_w + 1 + 1e-9, res)
    ys = np.arange(half_h + 1, -half_h - 1 - 1e-9, -res)
    ink = (np.abs(xs)[None, :] <= half_w) & (np.abs(ys)[:, None] <= half_h)
    return InkMask(ink, res, xs, ys)


def _hatch(rows: int, x0: float, x1: float, stagger: float = 0.0
           ) -> tuple[np.ndarray, np.ndarray]:
    """Boustrophedon runs one pitch apart, resampled, laid out one after the other."""
    runs = []
    for i in range(rows):
        y = 3.0 - i * PITCH
        a, b = np.array([x0 + stagger * i, y]), np.array([x1 - stagger * i, y])
        runs.append(resample(np.stack([a, b] if i % 2 == 0 else [b, a]), STEP))
    bounds = np.concatenate([[0], np.cumsum([len(r) for r in runs])]).astype(np.intp)
    return np.concatenate(runs), bounds


def _curvature(p: np.ndarray) -> np.ndarray:
    """Circumradius-based curvature at each inner point of a polyline, 1/mm."""
    a, b, c = p[:-2], p[1:-1], p[2:]
    ab, bc, ca = (np.linalg.norm(b - a, axis=1), np.linalg.norm(c - b, axis=1),
                  np.linalg.norm(a - c, axis=1))
    cross = np.abs((b - a)[:, 0] * (c - a)[:, 1] - (b - a)[:, 1] * (c - a)[:, 0])
    return 2.0 * cross / (ab * bc * ca)


def test_turns_stay_on_the_drag_area_and_bound_the_curvature() -> None:
    mask = _mask()
    for stagger in (0.0, 0.3):
        pts, bounds = _hatch(5, -5.0, 5.0, stagger)
        turns = round_turns(pts, bounds, np.ones(4, bool), mask, STEP, PITCH / 2)
        assert turns is not None
        assert sorted(turns.arcs) == [0, 1, 2, 3]
        for k, arc in turns.arcs.items():
            # the whole turn, from run k's new end to run k + 1's new start
            turn = np.concatenate([turns.points[turns.bounds[k + 1] - 1][None], arc,
                                   turns.points[turns.bounds[k + 1]][None]])
            assert lines_on_ink(mask, turn[:-1], turn[1:]).all()
            # with the runs' last and first steps: the curvature is at most 1 / r
            whole = np.concatenate([turns.points[turns.bounds[k + 1] - 2][None], turn,
                                    turns.points[turns.bounds[k + 1] + 1][None]])
            r = PITCH / 2 if stagger == 0.0 else STEP
            assert _curvature(whole).max() <= 1.0 / r * 1.01
            if stagger == 0.0:  # aligned runs: a half circle of radius pitch / 2
                assert _curvature(whole).max() <= 1.0 / (PITCH / 2) * 1.01
                assert math.isclose(float(np.linalg.norm(turn[-1] - turn[0])), PITCH,
                                    rel_tol=1e-9)


def test_staggered_ends_keep_their_jog_when_asked() -> None:
    mask = _mask()
    pts, bounds = _hatch(3, -5.0, 5.0, stagger=0.3)
    assert round_turns(pts, bounds, np.ones(2, bool), mask, STEP, PITCH / 2, 0.15) is None
    turns = round_turns(pts, bounds, np.ones(2, bool), mask, STEP, PITCH / 2, 0.5)
    assert turns is not None and sorted(turns.arcs) == [0, 1]


def test_no_turn_leaves_the_area() -> None:
    """Runs ending at the ink's edge: a turn that would leave the ink is refused."""
    mask = _mask(half_w=5.0)
    pts, bounds = _hatch(3, -5.0, 5.0)
    # the jog itself is on the edge column; the turn stays inside the corner, so it is kept
    turns = round_turns(pts, bounds, np.ones(2, bool), mask, STEP, PITCH / 2)
    assert turns is not None
    # with no ink between the rows (two strips), nothing is turned
    strips = mask.ink.copy()
    strips[np.abs(np.abs(mask.ys) - 2.4) > 0.3] = False
    gap = InkMask(strips, mask.res_mm, mask.xs, mask.ys)
    pts2, bounds2 = _hatch(2, -4.0, 4.0)
    pts2[:, 1] -= 0.6  # rows at y = 2.4 (on the strip) and 1.2 (off the ink)
    assert round_turns(pts2, bounds2, np.ones(1, bool), gap, STEP, PITCH / 2) is None


def test_build_path_marks_through_the_turns() -> None:
    mask = _mask()
    pts, bounds = _hatch(4, -5.0, 5.0)
    straight = build_path_flat(pts, bounds, mask, PARAMS)
    turned = build_path_flat(pts, bounds, mask, PARAMS, turnable=np.ones(3, bool))
    # one plunge, no lifts between the runs, either way
    assert (straight.kind != MARK).sum() == (turned.kind != MARK).sum() == 4
    assert turned.drags == straight.drags == 3
    mark = turned.uvz_mm[turned.kind == MARK, :2]
    steps = np.linalg.norm(np.diff(mark, axis=0), axis=1)
    assert steps.max() <= STEP + 1e-9
    # no corner tighter than the half-pitch turn (the straight jogs have right angles)
    assert _curvature(mark).max() <= 1.0 / (PITCH / 2) * 1.01
    assert _curvature(straight.uvz_mm[straight.kind == MARK, :2]).max() > 5.0


def _law(path_mm: np.ndarray, jerk: float | None) -> tuple[np.ndarray, float]:
    """The time law of a marking polyline (mm) at the 6 mm/s feed under a 100 mm/s^2 tip
    limit, through joints that are a gentle smooth map of the tip (no joint limit binds):
    the speed at each point (m/s) and the duration over the marking-only time."""
    p = np.column_stack([path_mm * 1e-3, np.zeros(len(path_mm))])
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(p, axis=0), axis=1))])
    lin = np.array([[2.0, 0.5, 0.0], [-0.5, 2.0, 0.0], [1.0, 1.0, 1.0]])
    q = p @ lin.T + 0.01 * np.sin(50.0 * p @ lin.T)
    dq, d2q = path_derivatives(q, s)
    dp, d2p = path_derivatives(p, s)
    limits = JointLimits(("a", "b", "c"), np.full(3, 10.0), np.full(3, 100.0))
    tip = TipLimit(dp, d2p, 0.1, np.ones(len(s) - 1, bool))
    law = time_parameterise(s, dq, d2q, np.full(len(s), 0.006), limits, tip=tip,
                            jerk_rad_s3=jerk)
    return law.sdot, float(law.t[-1] / (s[-1] / 0.006))


def test_the_feed_holds_through_a_turn_and_the_cycle_drops() -> None:
    mask = _mask()
    pts, bounds = _hatch(4, -5.0, 5.0)
    rows = np.array([3.0 - i * PITCH for i in range(4)])
    for jerk in (None, 500.0):
        cycles = []
        for turnable in (None, np.ones(3, bool)):
            path = build_path_flat(pts, bounds, mask, PARAMS, turnable=turnable)
            mark = path.uvz_mm[path.kind == MARK, :2]
            speed, cycle = _law(mark, jerk)
            cycles.append(cycle)
            # away from the path's ends (rest to rest): at the feed through every turn
            along = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(mark, axis=0),
                                                                    axis=1))])
            inner = (along > 2.0) & (along < along[-1] - 2.0)
            off = np.abs(mark[:, 1, None] - rows[None, :]).min(axis=1) > 1e-6
            if turnable is None:
                assert speed[inner].min() < 0.5 * 0.006  # the straight jogs' corners
            else:
                assert (off & inner).sum() >= 3 * 10  # the turns' points
                assert speed[inner].min() >= 0.95 * 0.006
        assert cycles[1] < cycles[0] - 0.02
