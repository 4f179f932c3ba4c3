"""Planned travel: the joint moves, a planned drawing, the way home, lifts and refusals.

Stated tolerances:

* :func:`joint_move`: joint rates and accelerations inside their limits to ``1e-9``
  relative (the profile is built on exactly these quantities); on the straight joint line
  to ``1e-12`` rad; the end pose to ``1e-15`` rad (``q0 + 1.0 (q1 - q0)`` rounds); the
  duration equals the rest-to-rest bound to ``1e-9`` relative when every joint has the
  same limits.
* Clearance: a planned move's tip may be 10 um under the clearance height (IK lands
  within 1 um); a tip below the clearance height outside the ink is on the vertical line
  over an ink point: the same panel point to ``1e-9`` mm, and the FK tips within 2 um
  (two IK solutions, each within 1 um of its target).
* The trajectory's limits: ``1e-6`` relative.
* The way home never lowers the pen: its lowest point is non-decreasing to ``1e-9`` m.
"""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, example, given, settings
from hypothesis import strategies as st

from tattotronix.app.pipeline import plan_drawing, travel_planner
from tattotronix.collision.model import CollisionModel
from tattotronix.config.params import compose_settings
from tattotronix.errors import TattotronixError
from tattotronix.kinematics import Chain, ik_options, solve_path
from tattotronix.robot.description import RobotDescription, build_description
from tattotronix.trajectory import (
    JointLimits,
    JointMove,
    JointPath,
    Trajectory,
    TrajectoryParams,
    TravelPlanner,
    joint_move,
    plan_trajectory,
    way_home,
)

from .conftest import small_art

SMALL = ["mask.width_mm=24", "mask.min_region_mm2=0.5"]  # the small drawing, 24 mm wide
JOINTS = ("joint_1", "joint_2", "joint_3", "joint_4", "joint_5")
CLEAR_TOL = 1e-5  # m: a planned move may dip 10 um under the clearance height
IK_TOL = 2e-6  # m: two IK tips, each within 1 um of its target
LOWEST_TOL = 1e-9  # m: "never lowers the pen"
REL = 1e-9
HOME = np.zeros(5)
# the needle tilted 0.2 rad towards +x: hops between clearance points can dip (test below)
TILTED = (math.sin(0.2), 0.0, -math.cos(0.2))


# ----------------------------------------------------------------- helpers and fixtures

def _rest_to_rest_s(d: float, v: float, a: float) -> float:
    """The textbook least time to cover ``d`` from rest to rest under ``v`` and ``a``."""
    d = abs(d)
    if d <= v * v / a:
        return 2.0 * math.sqrt(d / a)  # a triangle: never reaches v
    return d / v + v / a


def _limits(v: Any, a: Any) -> JointLimits:
    return JointLimits(JOINTS, np.broadcast_to(np.asarray(v, float), (5,)).copy(),
                       np.broadcast_to(np.asarray(a, float), (5,)).copy())


def _dense(move: JointMove) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(t, q, qd, qdd) on 4001 uniform times plus the profile's switching times."""
    big_t = move.duration_s
    t_acc = min(move.vel / move.acc, big_t)
    t = np.unique(np.concatenate((np.linspace(0.0, big_t, 4001), [t_acc, big_t - t_acc])))
    return (t, *move.at(t))


def _clearance_z(cfg: Any) -> float:
    """Panel top plus ``toolpath.clearance_mm``, arm frame, m."""
    p = cfg.robot.panel
    return float(p.centre[2]) + float(p.size[2]) / 2 + cfg.toolpath.clearance_m


def _ik(chain: Chain, cfg: Any, xyz: Any, **over: Any) -> np.ndarray:
    """IK of one tip target (needle down unless ``needle_axis`` is given); must succeed."""
    kw = {**ik_options(cfg.ik), **over}
    res = solve_path(chain, np.asarray(xyz, float)[None, :], seed=list(cfg.ik.seed), **kw)
    assert res.ok, f"{xyz} is out of reach"
    return np.asarray(res.q[0], dtype=np.float64)


def _panel_grid(cfg: Any, z: float, inset: float = 0.005) -> np.ndarray:
    """6 x 5 tip targets over the panel (``robot.panel``), ``inset`` m in from its edges."""
    c, s = np.asarray(cfg.robot.panel.centre, float), np.asarray(cfg.robot.panel.size, float)
    xs = c[0] + np.linspace(-(s[0] / 2 - inset), s[0] / 2 - inset, 6)
    ys = c[1] + np.linspace(-(s[1] / 2 - inset), s[1] / 2 - inset, 5)
    return np.array([[x, y, z] for x in xs for y in ys])


@pytest.fixture(scope="module")
def chain(desc: RobotDescription) -> Chain:
    return Chain.from_description(desc)


@pytest.fixture(scope="module")
def art(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return small_art(tmp_path_factory.mktemp("travel_art") / "small.png")


@pytest.fixture(scope="module")
def planned(art: Path, desc: RobotDescription) -> Trajectory:
    """The small drawing, planned travel (the default)."""
    cfg = compose_settings(SMALL)
    assert cfg.trajectory.travel == "planned"
    return plan_drawing(cfg, art, "small", desc)


@pytest.fixture(scope="module")
def straight(art: Path, desc: RobotDescription) -> Trajectory:
    """The small drawing, the original's straight travel."""
    cfg = compose_settings([*SMALL, "trajectory.travel=straight"])
    return plan_drawing(cfg, art, "small", desc)


def _move_windows(traj: Trajectory) -> list[np.ndarray]:
    """The sample indices of each planned move (both its end points included)."""
    eps = 1e-9
    return [np.flatnonzero((traj.t >= m.start_s - eps) & (traj.t <= m.start_s + m.duration_s
                                                          + eps)) for m in traj.moves]


# ----------------------------------------------------------------- joint_move

POSE = st.lists(st.floats(-1.57, 1.57, allow_subnormal=False), min_size=5, max_size=5)
VEL = st.lists(st.floats(0.05, 20.0), min_size=5, max_size=5)
ACC = st.lists(st.floats(0.1, 100.0), min_size=5, max_size=5)


def _check_profile(move: JointMove, q0: np.ndarray, q1: np.ndarray, lim: JointLimits) -> None:
    """Rest to rest at the exact poses, on the straight line, inside the limits, and as
    fast as the binding joint allows."""
    d = q1 - q0
    t, q, qd, qdd = _dense(move)
    # starts and ends at rest at the poses
    assert np.array_equal(q[0], q0) and np.all(qd[0] == 0.0)
    np.testing.assert_allclose(q[-1], q1, rtol=0, atol=1e-15)
    assert np.all(qd[-1] == 0.0)
    # on the straight segment q0 -> q1, progressing monotonically
    u = (q - q0) @ d / (d @ d)
    assert np.abs(q - q0 - u[:, None] * d).max() <= 1e-12
    assert u.min() >= -1e-12 and u.max() <= 1 + 1e-12 and np.diff(u).min() >= -1e-12
    assert np.all(qd * np.sign(d) >= 0.0)  # never backwards on any joint
    # inside the limits, densely and between the samples
    assert np.all(np.abs(qd) <= lim.velocity * (1 + REL))
    assert np.all(np.abs(qdd) <= lim.acceleration * (1 + REL))
    dt = np.diff(t)[:, None]
    # a switching time a hair from a sampled one leaves a step of 1e-16 s, over which qd
    # (~6 rad/s) can differ by its own rounding: a few units in its last place
    ulps = 4 * np.spacing(np.abs(qd).max(axis=0))
    assert np.all(np.abs(np.diff(qd, axis=0)) <= lim.acceleration * dt * (1 + REL) + ulps)
    # qd is the rate of q: the switching times are samples, so the trapezoid rule is exact
    np.testing.assert_allclose(np.diff(q, axis=0), 0.5 * dt * (qd[:-1] + qd[1:]), rtol=0,
                               atol=1e-14)
    # the binding joint accelerates at its limit, and cruises at it unless a triangle
    ratio_a = np.abs(qdd) / lim.acceleration
    assert ratio_a.max() == pytest.approx(1.0, rel=REL)
    if move.vel * move.vel / move.acc < 1.0 - 1e-12:  # reaches a cruise
        assert (np.abs(qd) / lim.velocity).max() == pytest.approx(1.0, rel=REL)
    # the bound is max_j of each joint's own rest-to-rest time; no move beats it
    bound = max(_rest_to_rest_s(dj, vj, aj)
                for dj, vj, aj in zip(d, lim.velocity, lim.acceleration, strict=True))
    assert move.lower_bound_s == pytest.approx(bound, rel=1e-12)
    assert move.duration_s >= bound * (1 - 1e-12)


# a still joint's 1e-310 rad step overflows its own ratio (the move is still right)
@pytest.mark.filterwarnings("ignore:overflow encountered:RuntimeWarning")
@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.filter_too_much])
@given(q0=POSE, q1=POSE, v=VEL, a=ACC)
@example(q0=[0.0, 0.3, -1.57, 1.0, 0.2], q1=[0.0, 0.3, 1.57, 1.0, -0.2],
         v=[1.5] * 5, a=[10.0] * 5)  # two joints still: the moving mask
@example(q0=[0.0] * 5, q1=[1e-9, 0.0, 0.0, 0.0, 0.0], v=[1.5] * 5, a=[10.0] * 5)
def test_joint_move_is_a_synchronised_rest_to_rest_line(q0: list[float], q1: list[float],
                                                        v: list[float], a: list[float]) -> None:
    a0, a1 = np.array(q0), np.array(q1)
    # below ~1e-300 rad the time arithmetic overflows: see the xfail test below
    assume(np.abs(a1 - a0).max() >= 1e-12)
    lim = _limits(v, a)
    _check_profile(joint_move(a0, a1, lim), a0, a1, lim)


@pytest.mark.filterwarnings("ignore:overflow encountered:RuntimeWarning")
@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.filter_too_much])
@given(q0=POSE, q1=POSE, v=st.floats(0.05, 20.0), a=st.floats(0.1, 100.0))
def test_joint_move_reaches_the_bound_when_every_joint_has_the_same_limits(
        q0: list[float], q1: list[float], v: float, a: float) -> None:
    a0, a1 = np.array(q0), np.array(q1)
    assume(np.abs(a1 - a0).max() >= 1e-12)
    lim = _limits(v, a)
    move = joint_move(a0, a1, lim)
    assert move.duration_s == pytest.approx(move.lower_bound_s, rel=REL)
    assert move.duration_s == pytest.approx(_rest_to_rest_s(np.abs(a1 - a0).max(), v, a),
                                            rel=REL)


def test_joint_move_textbook_numbers() -> None:
    """1.5 rad/s, 10 rad/s^2: 1 rad is a trapezoid (0.15 s ramps, 0.81667 s), 0.1 rad a
    triangle (0.2 s, peaking at 1 rad/s)."""
    lim = _limits(1.5, 10.0)
    long = joint_move(np.zeros(5), [1.0, 0.5, 0.0, 0.0, 0.0], lim)
    assert long.duration_s == pytest.approx(1.0 / 1.5 + 0.15, rel=1e-12)
    t = np.array([0.0, 0.15, 0.5, long.duration_s - 0.15, long.duration_s])
    q, qd, _ = long.at(t)
    np.testing.assert_allclose(qd[:, 0], [0.0, 1.5, 1.5, 1.5, 0.0], atol=1e-12)
    np.testing.assert_allclose(qd[:, 1], 0.5 * qd[:, 0], atol=1e-12)  # synchronised
    assert q[1, 0] == pytest.approx(0.5 * 10.0 * 0.15**2, rel=1e-12)
    short = joint_move(np.zeros(5), [0.0, 0.0, -0.1, 0.0, 0.0], lim)
    assert short.duration_s == pytest.approx(0.2, rel=1e-12)
    _, qd, qdd = short.at(np.array([0.05, 0.1, 0.15]))
    np.testing.assert_allclose(qd[:, 2], [-0.5, -1.0, -0.5], atol=1e-12)
    np.testing.assert_allclose(qdd[[0, 2], 2], [-10.0, 10.0], atol=1e-12)
    # times outside the move are clipped to its ends
    q, qd, _ = short.at(np.array([-1.0, 5.0]))
    np.testing.assert_allclose(q[:, 2], [0.0, -0.1], atol=1e-15)
    assert np.all(qd == 0.0)


def test_zero_move_takes_no_time() -> None:
    q = np.array([0.1, -0.4, 0.9, 0.0, -1.2])
    move = joint_move(q, q.copy(), _limits(1.5, 10.0))
    assert move.duration_s == 0.0 and move.lower_bound_s == 0.0
    pos, qd, qdd = move.at(np.array([0.0, 1.0]))
    assert np.array_equal(pos, [q, q]) and np.all(qd == 0.0) and np.all(qdd == 0.0)


@pytest.mark.parametrize(("q0", "q1"), [
    ([0.0] * 4, [0.0] * 5),
    ([0.0] * 5, [0.0] * 6),
    ([[0.0] * 5], [0.0] * 5),
    ([0.0] * 5, [0.0, math.nan, 0.0, 0.0, 0.0]),
    ([0.0, 0.0, math.inf, 0.0, 0.0], [0.0] * 5),
    ([0.0, 0.0, math.inf, 0.0, 0.0], [0.0, 0.0, math.inf, 0.0, 0.0]),
])
@pytest.mark.filterwarnings("ignore:invalid value encountered:RuntimeWarning")  # inf - inf
def test_joint_move_refuses_bad_poses(q0: Any, q1: Any) -> None:
    with pytest.raises(TattotronixError, match="a move needs two poses of 5 finite angles"):
        joint_move(q0, q1, _limits(1.5, 10.0))


@pytest.mark.parametrize("d", [1e-13, 1e-308, 5e-324])
def test_a_vanishing_displacement_is_no_move(d: float) -> None:
    """Below 1e-12 rad (every joint) the poses are the same: no move, no overflow (the
    progress rates are the limits over the displacement)."""
    move = joint_move(np.zeros(5), [d, 0.0, 0.0, 0.0, 0.0], _limits(1.5, 10.0))
    assert move.duration_s == 0.0 and move.lower_bound_s == 0.0
    tiny = joint_move(np.zeros(5), [1e-9, 0.0, 0.0, 0.0, 0.0], _limits(1.5, 10.0))
    assert tiny.duration_s == pytest.approx(2.0 * math.sqrt(1e-9 / 10.0), rel=1e-9)


# ----------------------------------------------------------------- a planned drawing

def test_planned_moves_stay_above_the_clearance_height(planned: Trajectory) -> None:
    cfg = compose_settings(SMALL)
    clear = _clearance_z(cfg)
    assert clear == pytest.approx(0.013, abs=1e-12)
    kinds = [m.kind for m in planned.moves]
    # home, a hop between each two ink pieces, home again; nothing here needs a lift
    assert kinds == ["from_home"] + ["hop"] * (planned.entries - 1) + ["to_home"]
    # three ink pieces; with compensation the ring's hatch needs one entry more (the
    # original's strokes take 3: issue 30's "at most as many entries" is open here)
    assert planned.entries == 4
    windows = _move_windows(planned)
    step = planned.params.max_step_m
    for m, idx in zip(planned.moves, windows, strict=True):
        assert planned.t[idx[0]] == pytest.approx(m.start_s, abs=1e-12)
        assert planned.t[idx[-1]] == pytest.approx(m.start_s + m.duration_s, abs=1e-12)
        assert np.all(planned.kind[idx] == 0), m.kind
        assert planned.tcp[idx, 2].min() >= clear - CLEAR_TOL, m.kind
        if m.kind == "hop":  # blended: it moves on through both ends, up the needle
            assert np.all(np.abs(planned.qd[idx[[0, -1]]]).max(axis=1) > 0), m.kind
            for a, b in ((idx[0], idx[0] + 1), (idx[-1], idx[-1] - 1)):
                d = planned.tcp[b] - planned.tcp[a]
                assert np.linalg.norm(d[:2]) <= 0.1 * d[2], m.kind  # within 6 deg of up
        tip_steps = np.linalg.norm(np.diff(planned.tcp[idx], axis=0), axis=1)
        assert tip_steps.max() <= step + 1e-12, m.kind
        if m.kind == "hop":  # clearance point to clearance point
            np.testing.assert_allclose(planned.tcp[idx[[0, -1]], 2], clear, atol=IK_TOL)
            assert m.straight_m == pytest.approx(
                float(np.linalg.norm(planned.tcp[idx[-1]] - planned.tcp[idx[0]])), abs=1e-12)
    # the moves are apart: ink pieces run between them
    for a, b in zip(windows[:-1], windows[1:], strict=True):
        assert b[0] > a[-1] + 1
        assert np.any(planned.kind[a[-1]:b[0]] != 0)


def test_the_needle_is_below_clearance_only_over_ink(planned: Trajectory) -> None:
    clear = _clearance_z(compose_settings(SMALL))
    ink = planned.kind != 0
    low = planned.tcp[:, 2] < clear - CLEAR_TOL
    vertical = np.flatnonzero(low & ~ink)
    assert len(vertical) > 0  # the plunges and retracts
    in_move = np.zeros(len(planned.t), bool)
    for idx in _move_windows(planned):
        in_move[idx] = True
    assert not np.any(in_move[vertical])
    ink_uv, ink_xy = planned.uvz_mm[ink, :2], planned.tcp[ink, :2]
    for i in vertical:  # directly above an ink point
        assert np.linalg.norm(ink_uv - planned.uvz_mm[i, :2], axis=1).min() <= 1e-9, i
        assert np.linalg.norm(ink_xy - planned.tcp[i, :2], axis=1).min() <= IK_TOL, i


def test_planned_drawing_keeps_the_limits_from_home_to_home(planned: Trajectory,
                                                             desc: RobotDescription,
                                                             chain: Chain) -> None:
    lower = np.array([j.lower for j in desc.joints])
    upper = np.array([j.upper for j in desc.joints])
    vel = np.array([j.velocity for j in desc.joints])
    assert np.all(planned.q >= lower) and np.all(planned.q <= upper)
    assert np.all(np.abs(planned.qd) <= vel * (1 + 1e-6))
    acc = planned.limits.acceleration
    np.testing.assert_allclose(acc, 10.0)  # trajectory.accel_rad_s2
    assert np.all(np.abs(planned.qdd_ends) <= acc * (1 + 1e-6))
    assert np.all(np.abs(planned.qdd) <= acc * (1 + 1e-6))
    assert planned.qdd_ends.shape == (len(planned.t) - 1, 2, 5)
    assert planned.t[0] == 0.0 and np.all(np.diff(planned.t) > 0)
    # home to home, at rest
    np.testing.assert_allclose(planned.q[[0, -1]], [HOME, HOME], rtol=0, atol=1e-15)
    assert np.all(planned.qd[[0, -1]] == 0.0)
    home_tip, _ = chain.fk(HOME[None, :])
    np.testing.assert_allclose(planned.tcp[[0, -1]], np.vstack([home_tip, home_tip]),
                               atol=1e-12)


def test_planned_drawing_is_one_continuous_jerk_limited_motion(planned: Trajectory) -> None:
    jerk = planned.params.jerk_rad_s3
    assert jerk is not None  # the default limits one
    dt = np.diff(planned.t)
    step = np.abs(np.diff(planned.qd, axis=0)) / dt[:, None]
    assert np.all(step <= planned.limits.acceleration * (1 + 1e-6))  # velocity continuous
    jk = np.abs(np.diff(planned.qdd, axis=0)) / dt[:, None]
    assert jk.max() <= jerk * (1 + 1e-6)
    # at rest only at home, where the needle leaves the ink and where an approach begins
    rest = np.flatnonzero(np.abs(planned.qd).max(axis=1) == 0.0)
    travel = planned.segment_kinds() == 0
    changes = set((np.flatnonzero(travel[:-1] != travel[1:]) + 1).tolist())
    assert set(rest.tolist()) <= changes | {0, len(planned.t) - 1}


def test_straight_travel_marks_the_same(planned: Trajectory, straight: Trajectory) -> None:
    assert straight.moves == ()
    assert straight.entries == planned.entries
    assert straight.marked_m == planned.marked_m
    m = straight.metrics()
    assert m["travel"] == "straight" and m["moves"] == 0 and m["travel_saved_s"] == 0.0
    # the same marking poses, in the same order; the approach's samples lie on the time
    # law after the travel before them, so they agree to rounding (8e-8 rad measured)
    assert np.array_equal(straight.q[straight.kind == 1], planned.q[planned.kind == 1])
    np.testing.assert_allclose(straight.q[straight.kind == 2], planned.q[planned.kind == 2],
                               rtol=0, atol=1e-6)
    # straight travel starts at the first clearance point, not at home
    assert not np.allclose(straight.q[0], HOME)


def test_planned_travel_needs_a_planner(chain: Chain, desc: RobotDescription) -> None:
    cfg = compose_settings()
    params = TrajectoryParams.from_settings(cfg.trajectory, cfg.toolpath, cfg.speed)
    assert params.travel == "planned"
    q = np.array([_ik(chain, cfg, [0.20, 0.0, 0.013]), _ik(chain, cfg, [0.22, 0.0, 0.013])])
    tcp, _ = chain.fk(q)
    path = JointPath.from_arrays(chain.joint_names, q, tcp, [0, 0])
    limits = JointLimits.from_description(desc, params.accel_rad_s2)
    with pytest.raises(TattotronixError, match="planned travel needs a TravelPlanner"):
        plan_trajectory(path, chain, limits, params)


# ----------------------------------------------------------------- the way home

@pytest.mark.parametrize("geometry", ["k-DOP", pytest.param("mesh hulls", marks=pytest.mark.cad)])
def test_way_home_never_lowers_the_pen(geometry: str, request: pytest.FixtureRequest) -> None:
    """From the needle plunged anywhere on a 6 x 5 grid over the panel (5 mm in from its
    edges), up the needle to clearance and home: the pen's lowest point only rises."""
    overrides = []
    if geometry == "mesh hulls":
        overrides.append(f"robot.cad_dir={request.getfixturevalue('cad_dir')}")
    cfg = compose_settings(overrides)
    desc = build_description(cfg.robot)
    chain = Chain.from_description(desc)
    params = TrajectoryParams.from_settings(cfg.trajectory, cfg.toolpath, cfg.speed)
    limits = JointLimits.from_description(desc, params.accel_rad_s2)
    planner = travel_planner(cfg, desc, chain, limits)
    model = planner.collision
    assert isinstance(model, CollisionModel) and model.geometry == geometry
    clear = _clearance_z(cfg)
    assert planner.clearance_z_m == pytest.approx(clear, abs=1e-12)
    surface = clear - cfg.toolpath.clearance_m
    depth = cfg.toolpath.plunge_m
    home = np.asarray(params.home, dtype=np.float64)
    targets = _panel_grid(cfg, surface - depth)
    sols = [solve_path(chain, p[None, :], seed=list(cfg.ik.seed), **ik_options(cfg.ik))
            for p in targets]
    unreachable = [tuple(p) for p, r in zip(targets, sols, strict=True) if not r.ok]
    assert not unreachable, f"grid points out of reach: {unreachable}"
    for p, res in zip(targets, sols, strict=True):
        q = np.asarray(res.q[0], dtype=np.float64)
        tip, axis = chain.fk(q[None, :])
        assert np.linalg.norm(tip[0] - p) <= 1e-6 and axis[0] @ [0, 0, -1] > 1 - 1e-9
        moves = way_home(planner, q, home)
        assert [m.kind for m in moves] == ["lift", "to_home"], p
        lift = moves[0]
        assert np.array_equal(lift.q[0], q)
        np.testing.assert_allclose(lift.tcp[-1], [p[0], p[1], clear], atol=IK_TOL)
        for a, b in zip(moves[:-1], moves[1:], strict=True):  # end to end (to rounding)
            np.testing.assert_allclose(a.q[-1], b.q[0], rtol=0, atol=1e-15)
        q_all = np.concatenate([m.q for m in moves])
        lowest = model.pen_lowest_z(q_all)
        assert lowest[0] == pytest.approx(surface - depth, abs=1e-6)  # the tip, in the panel
        assert np.diff(lowest).min() >= -LOWEST_TOL, f"the way home from {p} lowers the pen"
        np.testing.assert_allclose(q_all[-1], home, rtol=0, atol=1e-15)
        assert np.all(moves[-1].qd[-1] == 0.0)


def test_way_home_from_clearance_needs_no_lift(chain: Chain, desc: RobotDescription) -> None:
    cfg = compose_settings()
    planner = travel_planner(cfg, desc, chain, JointLimits.from_description(desc, 10.0))
    q = _ik(chain, cfg, [0.21, 0.03, _clearance_z(cfg)])
    moves = way_home(planner, q, HOME)
    assert [m.kind for m in moves] == ["to_home"]
    assert np.array_equal(moves[0].q[0], q)
    np.testing.assert_allclose(moves[0].q[-1], HOME, rtol=0, atol=1e-15)


# ----------------------------------------------------------------- refusals and lifts

@pytest.mark.parametrize("kind", ["hop", "from_home", "to_home"])
def test_a_move_no_lift_saves_is_refused_naming_it(kind: str, chain: Chain,
                                                   desc: RobotDescription) -> None:
    """A 0.5 m margin: every pose is inside it, however high the needle goes."""
    cfg = compose_settings()
    clear = _clearance_z(cfg)
    planner = TravelPlanner(chain, JointLimits.from_description(desc, 10.0),
                            CollisionModel(desc), margin_m=0.5, resolution_m=1e-4,
                            clearance_z_m=clear, lifts_m=[0.01, 0.02, 0.04, 0.08],
                            max_step_m=5e-4, ik=ik_options(cfg.ik))
    qa = _ik(chain, cfg, [0.18, -0.03, clear])
    qb = _ik(chain, cfg, [0.25, 0.04, clear])
    ends = {"hop": (qa, qb), "from_home": (HOME, qa), "to_home": (qb, HOME)}[kind]
    where = f"the {kind} under test"
    with pytest.raises(TattotronixError) as err:
        planner.plan(*ends, kind, where)
    text = str(err.value)
    assert text.startswith(f"no safe travel for {where}: ")
    assert "come within the margin" in text and "margin 500 mm" in text
    assert "lifts of 10, 20, 40, 80 mm did not help" in text


def _tilted_hop(chain: Chain, desc: RobotDescription, lifts_m: list[float]
                ) -> tuple[TravelPlanner, np.ndarray, np.ndarray, float]:
    """A planner without collision model for a needle tilted 0.2 rad towards +x, and two
    clearance poses 120 mm apart in y whose joint line dips below the clearance height."""
    cfg = compose_settings()
    clear = _clearance_z(cfg)
    ik = {**ik_options(cfg.ik), "needle_axis": list(TILTED)}
    planner = TravelPlanner(chain, JointLimits.from_description(desc, 10.0), None,
                            margin_m=0.001, resolution_m=1e-4, clearance_z_m=clear,
                            lifts_m=lifts_m, max_step_m=5e-4, ik=ik)
    qa = _ik(chain, cfg, [0.165, -0.06, clear], needle_axis=list(TILTED))
    qb = _ik(chain, cfg, [0.165, 0.06, clear], needle_axis=list(TILTED))
    return planner, qa, qb, clear


def test_a_hop_that_dips_below_clearance_is_lifted(chain: Chain,
                                                   desc: RobotDescription) -> None:
    planner, qa, qb, clear = _tilted_hop(chain, desc, [0.01, 0.02, 0.04, 0.08])
    direct = planner.sample(joint_move(qa, qb, planner.limits), "hop")
    dip = clear - float(direct.tcp[:, 2].min())
    assert dip > 0.1e-3  # 0.24 mm: far more than the 10 um allowed
    assert planner.problems(direct) == (f"the needle dips {1000 * dip:.3f} mm below the "
                                        "clearance height")
    moves = planner.plan(qa, qb, "hop", "the tilted hop")
    assert [m.kind for m in moves] == ["lift", "hop", "lift"]
    assert np.array_equal(moves[0].q[0], qa)
    np.testing.assert_allclose(moves[-1].q[-1], qb, rtol=0, atol=1e-15)
    for a, b in zip(moves[:-1], moves[1:], strict=True):
        np.testing.assert_allclose(a.q[-1], b.q[0], rtol=0, atol=1e-15)
    for m in moves:
        assert planner.problems(m) == ""
        assert m.tcp[:, 2].min() >= clear - CLEAR_TOL
        assert np.all(m.qd[[0, -1]] == 0.0)
    hop = moves[1]
    tip_a, _ = chain.fk(qa[None, :])
    tip_b, _ = chain.fk(qb[None, :])
    # the first lift (10 mm) is enough; the needle keeps its tilt up there
    np.testing.assert_allclose(hop.tcp[[0, -1]], np.vstack([tip_a, tip_b]) + [0, 0, 0.01],
                               atol=IK_TOL)
    _, axis = chain.fk(hop.q[[0, -1]])
    np.testing.assert_allclose(axis, [TILTED, TILTED], atol=1e-6)
    assert hop.tcp[:, 2].min() >= clear + 0.01 - dip - 1e-6
    assert hop.straight_m == pytest.approx(float(np.linalg.norm(tip_b - tip_a)), abs=IK_TOL)


def test_a_dipping_hop_without_a_reachable_lift_is_refused(chain: Chain,
                                                           desc: RobotDescription) -> None:
    planner, qa, qb, _ = _tilted_hop(chain, desc, [1.0])  # 1 m up: out of reach
    with pytest.raises(TattotronixError, match=re.escape(
            "no safe travel for the tilted hop: the needle dips 0.2")) as err:
        planner.plan(qa, qb, "hop", "the tilted hop")
    assert "lifts of 1000 mm did not help" in str(err.value)


def test_with_the_needle_down_no_hop_over_the_panel_dips(chain: Chain,
                                                         desc: RobotDescription) -> None:
    """Every hop between two points of the 6 x 5 grid at clearance is one move."""
    cfg = compose_settings()
    clear = _clearance_z(cfg)
    planner = TravelPlanner(chain, JointLimits.from_description(desc, 10.0), None,
                            margin_m=0.001, resolution_m=1e-4, clearance_z_m=clear,
                            lifts_m=[0.01], max_step_m=5e-4, ik=ik_options(cfg.ik))
    poses = [_ik(chain, cfg, p) for p in _panel_grid(cfg, clear)]
    for i, qa in enumerate(poses):
        for j, qb in enumerate(poses):
            if i != j:
                moves = planner.plan(qa, qb, "hop", f"hop {i} -> {j}")
                assert len(moves) == 1 and moves[0].tcp[:, 2].min() >= clear - CLEAR_TOL


def test_the_tip_never_leaves_the_marking_path(planned: Trajectory, chain: Chain) -> None:
    """While marking, the samples are the IK path's own points (at the marking depth) and
    the reference between two of them (the controller's C1 Hermite in joint space, at
    the time law's rates) keeps the tip near the chord between them: within a micrometre
    on most chords (on a curved stroke the reference follows the curve the points lie on,
    a sagitta off the chord), and within a tenth of the point step where the path turns a
    corner at a point (the Hermite's tangent there is the three-point slope of the two
    chords, so it rounds the corner a little; measured up to 12 um at 0.15 mm steps, with
    each drag cut into equal chords: 25.7 um when a drag ended in a 9 um remainder)."""
    from scipy.interpolate import CubicHermiteSpline

    step = compose_settings(SMALL).toolpath.step_mm / 1000  # the toolpath's point step, m
    mark = np.flatnonzero(planned.marked)  # samples ending a marking segment
    assert len(mark) > 100
    depth = planned.tcp[planned.kind == 1, 2]
    assert np.ptp(depth) <= IK_TOL  # one marking depth
    spline = CubicHermiteSpline(planned.t, planned.q, planned.qd, axis=0)
    a, b = planned.tcp[mark - 1], planned.tcp[mark]
    for frac in (0.25, 0.5, 0.75):
        tm = planned.t[mark - 1] + frac * (planned.t[mark] - planned.t[mark - 1])
        tip, _ = chain.fk(spline(tm))
        d = b - a
        u = np.clip(np.einsum("ij,ij->i", tip - a, d) / np.einsum("ij,ij->i", d, d), 0, 1)
        off = np.linalg.norm(tip - (a + u[:, None] * d), axis=1)
        assert np.median(off) <= 1e-6, frac
        assert off.max() <= 0.1 * step, (frac, float(off.max()))
