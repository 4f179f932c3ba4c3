"""The trajectory stage: npz invariants, joint limits, continuity, feed, speed and refusal.

Stated tolerances:

* Limits: the time law keeps every sampled joint velocity and acceleration (at both ends
  of every interval, and the interval mean ``(qd[i+1] - qd[i]) / dt``) inside its limit
  to rounding: ``1e-9`` relative. There is no discretisation slack in these: the
  constraints are imposed on exactly the quantities tested.
* Continuity: between consecutive samples the joint velocity steps by at most
  ``a_max * dt`` (the acceleration limit times the sample interval), everywhere and in
  particular at stroke starts and ends; nothing steps from rest to the feed.
* Consistency with q(t): on smooth stretches, ``(q[i+1] - q[i]) / dt`` equals the mean
  of ``qd`` at the two samples within 1 % of the peak joint rate (finite differences on
  0.15 to 0.5 mm steps; at corners the sampled path is not smooth and the two differ).
* Feed: away from ramps and corners the tip speed ``|J qd|`` is within 1 % of the feed
  (the central-difference tangent against the chord).
"""

from __future__ import annotations

import json
import math
import re
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from tattotronix.config.params import compose_settings
from tattotronix.errors import TattotronixError
from tattotronix.io.artifacts import TrajectoryRecord
from tattotronix.io.provenance import file_sha256, provenance_json
from tattotronix.kinematics import Chain, solve_path
from tattotronix.kinematics.synthetic import logo_like_strokes, raster_strokes, stroke_path
from tattotronix.robot.description import RobotDescription
from tattotronix.robot.urdf import to_urdf
from tattotronix.trajectory import (
    NPZ_KEYS,
    JointLimits,
    JointPath,
    SpeedRefused,
    Trajectory,
    TrajectoryParams,
    corner_points,
    densify,
    path_derivatives,
    plan_trajectory,
    time_parameterise,
)

ROOT = Path(__file__).resolve().parents[1]
EMBLEM_IK = ROOT / "data" / "ik" / "emblem.npz"
# m (docs/original.md, "2.6 The 3-D path" and "2.7 Panel to arm frame, timing")
SURFACE, PLUNGE, CLEARANCE = 0.005, 0.0015, 0.008
REL = 1e-9
FASTEST = re.compile(r"the fastest this drawing can go is speed=(\d+\.\d\d)$")


# ----------------------------------------------------------------- fixtures and helpers

@pytest.fixture(scope="module")
def chain(desc: RobotDescription) -> Chain:
    return Chain.from_description(desc)


@pytest.fixture(scope="module")
def params() -> TrajectoryParams:
    """The config's settings with straight travel and the acceleration-limited law (no
    jerk or tip limit): these tests are about the discrete time-optimal law along the
    whole path (planned travel and the default limits are tested in test_travel.py, the
    jerk and tip limits in test_timelaw_props.py)."""
    return replace(_default_params(), travel="straight",
                   jerk_rad_s3=None, tip_accel_m_s2=None)


def _default_params() -> TrajectoryParams:
    """The trajectory settings of ``conf/``."""
    cfg = compose_settings()
    return TrajectoryParams.from_settings(cfg.trajectory, cfg.toolpath, cfg.speed)


def _limits(desc: RobotDescription, params: TrajectoryParams) -> JointLimits:
    return JointLimits.from_description(desc, params.accel_rad_s2)


def _solved(chain: Chain, xyz_m: np.ndarray, kind: np.ndarray,
            uvz_mm: np.ndarray) -> JointPath:
    res = solve_path(chain, xyz_m)
    assert res.ok
    tcp, _ = chain.fk(res.q)
    return JointPath.from_arrays(chain.joint_names, res.q, tcp, kind, uvz_mm)


@pytest.fixture(scope="module")
def drawing(chain: Chain) -> JointPath:
    """The built-in artwork's IK path, or a logo-like synthetic one without data/."""
    if EMBLEM_IK.exists():
        return JointPath.from_npz(EMBLEM_IK)
    sp = stroke_path(logo_like_strokes())
    return _solved(chain, sp.xyz_m, sp.kind, sp.uvz_mm)


@pytest.fixture(scope="module")
def traj(drawing: JointPath, chain: Chain, desc: RobotDescription,
         params: TrajectoryParams) -> Trajectory:
    return plan_trajectory(drawing, chain, _limits(desc, params), params)


@pytest.fixture(scope="module")
def npz(traj: Trajectory, tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("traj")
    ik = folder / "ik.npz"
    ik.write_bytes(b"stand-in input")
    file = folder / "drawing.npz"
    traj.save(file, provenance_json({"speed": 1.0}, {"ik": ik}, "abc123"))
    return file


@pytest.fixture(scope="module")
def line(chain: Chain) -> JointPath:
    """A straight 40 mm marking line at depth, every point a mark point (no travel)."""
    u = np.arange(-20.0, 20.0 + 1e-9, 0.15)
    uvz = np.column_stack((u, np.full_like(u, 10.0), np.full_like(u, -1.5)))
    xyz = np.array([0.21, 0.0, SURFACE]) + uvz / 1000.0
    return _solved(chain, xyz, np.ones(len(u), np.int8), uvz)


# ------------------------------------ npz (docs/original.md, "4.1 The trajectory file")

def test_npz_holds_the_shipped_trajectory_invariants(npz: Path,
                                                     desc: RobotDescription) -> None:
    with np.load(npz, allow_pickle=False) as z:
        assert set(NPZ_KEYS) <= set(z.files)
        arrays = {k: z[k] for k in z.files}
    n = len(arrays["t"])
    assert tuple(arrays["joints"]) == desc.joint_names and arrays["joints"].dtype.kind == "U"
    for key, shape in (("t", (n,)), ("q", (n, 5)), ("qd", (n, 5)), ("qdd", (n, 5)),
                       ("tcp", (n, 3))):
        assert arrays[key].shape == shape and arrays[key].dtype == np.float64
    assert arrays["kind"].dtype == np.int8 and arrays["kind"].shape == (n,)
    assert arrays["marked"].dtype == np.bool_ and arrays["marked"].shape == (n,)
    t, q, kind, marked, tcp = (arrays[k] for k in ("t", "q", "kind", "marked", "tcp"))
    assert t[0] == 0.0 and np.all(np.diff(t) > 0)
    assert np.all(np.abs(q) <= 1.57)
    for key in ("t", "q", "qd", "qdd", "tcp"):
        assert np.all(np.isfinite(arrays[key])), key
    z_tip = tcp[:, 2]
    assert z_tip.min() >= SURFACE - PLUNGE - 1e-4 and z_tip.max() <= SURFACE + CLEARANCE + 1e-4
    assert np.all(z_tip[marked] <= SURFACE + 1e-4)
    assert set(np.unique(kind)) <= {0, 1, 2}
    assert not marked[0] and np.array_equal(marked[1:], (kind[:-1] == 1) & (kind[1:] == 1))
    prov = json.loads(str(arrays["provenance"]))
    assert {"config", "code_version", "inputs"} <= set(prov)
    assert prov["inputs"]["ik"]["sha256"] == file_sha256(npz.parent / "ik.npz")


def test_tcp_is_the_fk_tip_and_the_drawing_is_kept(traj: Trajectory, drawing: JointPath,
                                                  chain: Chain) -> None:
    tip, _ = chain.fk(traj.q)
    assert np.abs(tip - traj.tcp).max() < 1e-12
    kept = traj.source >= 0
    assert np.array_equal(traj.source[kept], np.arange(len(drawing)))
    assert np.array_equal(traj.q[kept], drawing.q)  # the IK stage's q, untouched
    assert traj.entries == drawing.entries()
    assert math.isclose(traj.marked_m, drawing.marked_length_m(), rel_tol=1e-12)


def test_load_trajectory_round_trip(npz: Path, traj: Trajectory) -> None:
    back = TrajectoryRecord.load(npz)
    assert back.joints == traj.joints and np.array_equal(back.t, traj.t)
    assert np.array_equal(back.qd, traj.qd) and back.provenance["code_version"] == "abc123"


# ----------------------------------------------------------------- limits and continuity

def test_velocity_and_acceleration_inside_the_limits(traj: Trajectory) -> None:
    v, a = traj.limits.velocity, traj.limits.acceleration
    assert np.all(np.abs(traj.qd) <= v * (1 + REL))
    assert np.all(np.abs(traj.qdd) <= a * (1 + REL))
    assert np.all(np.abs(traj.law.qdd_ends) <= a * (1 + REL))
    step = np.abs(np.diff(traj.qd, axis=0)) / np.diff(traj.t)[:, None]
    assert np.all(step <= a * (1 + REL))
    # travel uses the limits: some joint reaches each (the law is not timid)
    assert np.abs(traj.qd).max() >= 0.99 * v.max()
    assert np.abs(traj.law.qdd_ends).max() >= 0.99 * a.max()
    m = traj.metrics()
    assert m["peak_rate_rad_s_max"] <= v.max() * (1 + REL)
    assert m["peak_accel_rad_s2_max"] <= a.max() * (1 + REL)


def test_velocity_is_continuous_at_stroke_starts_and_ends(traj: Trajectory) -> None:
    k = traj.kind
    dt = np.diff(traj.t)
    step = np.abs(np.diff(traj.qd, axis=0))
    a = traj.limits.acceleration
    starts = np.flatnonzero((k[:-1] == 0) & (k[1:] != 0))  # last travel point
    firsts = np.flatnonzero((k[:-1] != 1) & (k[1:] == 1))  # into the first mark point
    ends = np.flatnonzero((k[:-1] == 1) & (k[1:] == 0))  # last mark point
    assert len(starts) == traj.entries and len(ends) >= 1
    for idx in (starts, firsts, ends):
        w = np.unique(np.clip(np.concatenate([idx + o for o in (-2, -1, 0, 1)]), 0,
                              len(dt) - 1))
        assert np.all(step[w] <= a * dt[w, None] * (1 + REL))
    # nothing steps from rest to the feed: the path starts and ends at rest, and the
    # first marking sample is already moving at (a ramp towards) the feed
    assert np.all(traj.qd[0] == 0) and np.all(traj.qd[-1] == 0)
    assert np.all(traj.law.sdot[1:-1] > 0)


def test_joint_rates_agree_with_q_of_t(traj: Trajectory) -> None:
    dt = np.diff(traj.t)
    chord = np.diff(traj.q, axis=0) / dt[:, None]
    mean = 0.5 * (traj.qd[:-1] + traj.qd[1:])
    corner = corner_points(traj.tcp, traj.params.corner_radius_m)
    smooth = ~corner[:-1] & ~corner[1:]
    assert smooth.mean() > 0.85  # most of the drawing (the fill's row turns are corners)
    err = np.abs(chord - mean)[smooth].max()
    assert err <= 0.01 * np.abs(traj.qd).max()
    assert np.allclose(np.diff(traj.law.s) / dt, 0.5 * (traj.law.sdot[:-1] +
                                                         traj.law.sdot[1:]), rtol=1e-9)


# ----------------------------------------------------------------- feeds and timing

def test_marking_runs_at_the_feed(traj: Trajectory, chain: Chain) -> None:
    feed = traj.params.feed_mark_m_s
    seg = traj.segment_kinds()
    on_mark = np.zeros(len(traj.t), bool)
    on_mark[1:-1] = (seg[:-1] == 1) & (seg[1:] == 1)
    at_feed = on_mark & (np.abs(traj.law.sdot - feed) <= 1e-12)
    held = at_feed & ~corner_points(traj.tcp, traj.params.corner_radius_m)
    assert held.sum() > 0.9 * on_mark.sum()
    jac = chain.jacobian(traj.q[held])[:, :3, :]
    tip = np.linalg.norm(np.einsum("nij,nj->ni", jac, traj.qd[held]), axis=1)
    assert np.abs(tip / feed - 1).max() < 0.01
    m = traj.metrics()
    assert m["marking_below_feed_pct"] < 1.0
    assert math.isclose(m["marking_s"], m["marking_only_s"], rel_tol=0.01)
    # approach at the marking feed, travel capped by the travel feed
    assert traj.law.sdot[np.r_[seg == 2, False] | np.r_[False, seg == 2]].max() <= feed * (
        1 + REL)
    assert traj.law.sdot.max() <= traj.params.travel_feed_m_s * (1 + REL)


def test_metrics_add_up(traj: Trajectory) -> None:
    m = traj.metrics()
    assert math.isclose(m["marking_s"] + m["approach_s"] + m["travel_s"], m["duration_s"],
                        rel_tol=1e-9)
    assert m["entries"] == traj.entries and m["speed"] == 1.0
    assert math.isclose(m["cycle_over_marking"], m["duration_s"] / m["marking_only_s"])
    # within the limits, and still no slower than 5 % over the original's timing of the
    # same path (constant feeds, travel at 60 mm/s, velocity steps, no limits at all)
    k = traj.kind
    seg = np.linalg.norm(np.diff(traj.uvz_mm, axis=0), axis=1) / 1000.0
    slow = ((k[:-1] == 1) & (k[1:] == 1)) | (k[:-1] == 2) | (k[1:] == 2)
    original = float((seg / np.where(slow, traj.params.feed_mark_m_s, 0.060)).sum())
    assert m["duration_s"] <= 1.05 * original
    assert set(m["peak_rate_rad_s"]) == set(traj.joints)
    json.dumps(m)  # JSON-ready


def test_speed_two_halves_the_duration_where_limits_allow(line: JointPath, chain: Chain,
                                                          desc: RobotDescription,
                                                          params: TrajectoryParams) -> None:
    lim = _limits(desc, params)
    one = plan_trajectory(line, chain, lim, params)
    two = plan_trajectory(line, chain, lim, replace(params, speed=2.0))
    assert math.isclose(two.duration_s, one.duration_s / 2, rel_tol=0.01)
    assert math.isclose(two.marking_only_s, one.marking_only_s / 2)
    assert np.all(np.abs(two.qd) <= lim.velocity * (1 + REL))


def test_speed_scales_the_marking_of_the_drawing(traj: Trajectory, drawing: JointPath,
                                                 chain: Chain, desc: RobotDescription,
                                                 params: TrajectoryParams) -> None:
    two = plan_trajectory(drawing, chain, _limits(desc, params), replace(params, speed=2.0))
    m1, m2 = traj.metrics(), two.metrics()
    assert math.isclose(m2["marking_only_s"], m1["marking_only_s"] / 2)
    assert math.isclose(m2["marking_s"], m1["marking_s"] / 2, rel_tol=0.03)
    assert m2["duration_s"] < m1["duration_s"]


# ----------------------------------------------------------------- refusal

def test_too_fast_is_refused_naming_joint_and_fastest_speed(traj: Trajectory,
                                                            drawing: JointPath, chain: Chain,
                                                            desc: RobotDescription,
                                                            params: TrajectoryParams) -> None:
    fastest = traj.speed.fastest
    assert traj.speed.ok and 1.0 <= fastest < 100
    too_fast = replace(params, speed=round(fastest * 1.5 + 0.5, 1))
    with pytest.raises(SpeedRefused) as err:
        plan_trajectory(drawing, chain, _limits(desc, params), too_fast)
    msg = str(err.value)
    assert re.search(r"joint_\d would need \d+\.\d\d rad/s(\^2)? against its "
                     r"[\d.]+ rad/s(\^2)? limit", msg)
    found = FASTEST.search(msg)
    assert found and float(found.group(1)) == fastest
    assert fastest == math.floor(100 * err.value.limit.exact) / 100
    ok = plan_trajectory(drawing, chain, _limits(desc, params), replace(params, speed=fastest))
    assert ok.speed.ok and ok.metrics()["speed"] == fastest
    assert np.all(np.abs(ok.qd) <= ok.limits.velocity * (1 + REL))
    assert np.all(np.abs(ok.law.qdd_ends) <= ok.limits.acceleration * (1 + REL))


def test_velocity_refusal_reads_like_the_original(line: JointPath, chain: Chain,
                                                  desc: RobotDescription,
                                                  params: TrajectoryParams) -> None:
    lim = _limits(desc, params)
    s_max = plan_trajectory(line, chain, lim, params).speed
    assert s_max.quantity == "velocity"  # a straight line: the rate binds, not a bend
    with pytest.raises(SpeedRefused) as err:
        plan_trajectory(line, chain, lim, replace(params, speed=s_max.exact * 1.4))
    msg = str(err.value)
    need = 1.4 * 1.5  # the binding joint needs 1.4 x its limit
    assert f"{s_max.joint} would need {need:.2f} rad/s against its 1.5 rad/s limit; " in msg
    found = FASTEST.search(msg)
    assert found and float(found.group(1)) == math.floor(100 * s_max.exact) / 100
    plan_trajectory(line, chain, lim, replace(params, speed=float(found.group(1))))


@pytest.mark.parametrize(("change", "needle"), [
    ({"speed": 0.0}, "speed=0"),
    ({"speed": -1.0}, "speed=-1"),
    ({"accel_rad_s2": 0.0}, "trajectory.accel_rad_s2=0"),
    ({"travel_feed_m_s": float("nan")}, "trajectory.travel_feed_mm_s=nan"),
    ({"jerk_rad_s3": -1.0}, "jerk limit must be a positive number or null"),
    ({"tip_accel_m_s2": 0.0}, "tip acceleration limit must be a positive number or null"),
])
def test_bad_settings_are_refused(line: JointPath, chain: Chain, desc: RobotDescription,
                                  params: TrajectoryParams, change: dict[str, float],
                                  needle: str) -> None:
    with pytest.raises(TattotronixError, match=re.escape(needle)):
        plan_trajectory(line, chain, _limits(desc, params), replace(params, **change))


# ----------------------------------------------------------------- pieces

def test_densify_puts_points_on_the_straight_tip_line(drawing: JointPath, chain: Chain,
                                                      traj: Trajectory) -> None:
    new = traj.source < 0
    assert new.sum() > 0
    assert np.diff(traj.law.s).max() <= traj.params.max_step_m + 2e-6  # IK lands within 1 um
    # each inserted point is on the chord between the original points around it
    kept = np.flatnonzero(~new)
    at = np.searchsorted(kept, np.flatnonzero(new))
    a, b, p = traj.tcp[kept[at - 1]], traj.tcp[kept[at]], traj.tcp[new]
    d = (b - a) / np.linalg.norm(b - a, axis=1)[:, None]
    assert np.linalg.norm(np.cross(p - a, d), axis=1).max() < 2e-6
    _, axis = chain.fk(traj.q[new])
    assert np.abs(axis - [0.0, 0.0, -1.0]).max() < 2e-6  # the needle stays vertical
    same = JointPath.from_arrays(traj.joints, traj.q, traj.tcp, traj.kind)
    assert densify(same, chain, 1.0) is same  # nothing longer than 1 m


def test_time_law_matches_the_trapezoid_on_a_straight_joint_line() -> None:
    """One joint moving linearly in s: the time-optimal law is the textbook trapezoid."""
    length, k = 0.1, np.array([10.0, 0, 0, 0, 0])  # m; rad/m
    s = np.linspace(0.0, length, 2001)
    lim = JointLimits(("a", "b", "c", "d", "e"), np.full(5, 1.5), np.full(5, 7.5))
    dq = np.tile(k, (len(s), 1))
    law = time_parameterise(s, dq, np.zeros_like(dq), np.full(len(s), 1.0), lim)
    v, a = 1.5 / 10, 7.5 / 10  # path speed and acceleration limits, m/s, m/s^2
    expect = length / v + v / a
    assert math.isclose(law.duration_s, expect, rel_tol=1e-3)
    assert math.isclose(law.sdot.max(), v, rel_tol=1e-9)
    law.check(lim)
    # a lower feed cap wins
    slow = time_parameterise(s, dq, np.zeros_like(dq), np.full(len(s), 0.05), lim)
    assert math.isclose(slow.duration_s, length / 0.05 + 0.05 / a, rel_tol=1e-3)


def test_corners_slow_the_law_within_the_limits() -> None:
    """A right-angle corner in joint space: the path speed dips there, limits hold."""
    n = 401
    s = np.linspace(0.0, 0.04, n)
    q = np.zeros((n, 5))
    half = n // 2
    q[:half + 1, 0] = 10.0 * s[:half + 1]
    q[half:, 0] = q[half, 0]
    q[half:, 1] = 10.0 * (s[half:] - s[half])
    dq, d2q = path_derivatives(q, s)
    lim = JointLimits(tuple("abcde"), np.full(5, 1.5), np.full(5, 7.5))
    law = time_parameterise(s, dq, d2q, np.full(n, 1.0), lim)
    law.check(lim)
    assert law.sdot[half] < 0.2 * law.sdot.max()
    step = np.abs(np.diff(law.qd, axis=0)) / np.diff(law.t)[:, None]
    assert step.max() <= 7.5 * (1 + REL)


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(3, 300),
       cap=st.floats(0.001, 1.0), accel=st.floats(0.5, 50.0))
# found by hypothesis: the forward pass met a point it could not leave, and stalled there
@example(seed=984225, n=45, cap=1.0, accel=1.0)
def test_time_law_respects_limits_on_random_paths(seed: int, n: int, cap: float,
                                                  accel: float) -> None:
    rng = np.random.default_rng(seed)
    h = rng.uniform(1e-5, 2e-3, n - 1)
    s = np.concatenate(([0.0], np.cumsum(h)))
    q = np.cumsum(rng.normal(0, 1, (n, 5)) * h.mean() * 10, axis=0)
    dq, d2q = path_derivatives(q, s)
    lim = JointLimits(tuple("abcde"), rng.uniform(0.5, 2.0, 5), np.full(5, accel))
    law = time_parameterise(s, dq, d2q, np.full(n, cap), lim)
    law.check(lim, rel_tol=1e-9)
    assert law.t[0] == 0 and np.all(np.diff(law.t) > 0) and np.all(np.isfinite(law.t))
    assert law.sdot.max() <= cap * (1 + 1e-9)
    step = np.abs(np.diff(law.qd, axis=0)) / np.diff(law.t)[:, None]
    assert np.all(step <= lim.acceleration * (1 + 1e-9))


def test_path_helpers(traj: Trajectory) -> None:
    p = JointPath.from_arrays(traj.joints, traj.q[:50], traj.tcp[:50], traj.kind[:50])
    assert p.marked()[0] == np.False_ and len(p.segment_kinds()) == 49
    with pytest.raises(TattotronixError, match="unknown point kinds"):
        JointPath.from_arrays(traj.joints, traj.q[:5], traj.tcp[:5], [0, 1, 3, 1, 0])
    with pytest.raises(TattotronixError, match="at least 3 points"):
        time_parameterise(np.array([0.0, 1.0]), np.ones((2, 5)), np.zeros((2, 5)),
                          np.ones(2), JointLimits(tuple("abcde"), np.ones(5), np.ones(5)))


# ----------------------------------------------------------------- the stage

def _stage(data: Path, *overrides: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "stages/trajectory.py", f"paths.data={data}",
                           "artwork.name=tiny", *overrides],
                          cwd=ROOT, capture_output=True, text=True, timeout=300)


def _tiny_inputs(data: Path, chain: Chain, desc: RobotDescription) -> None:
    sp = stroke_path(raster_strokes((-20.0, 20.0), (-10.0, 10.0), rows=3), step_mm=0.5)
    res = solve_path(chain, sp.xyz_m)
    tcp, _ = chain.fk(res.q)
    (data / "ik").mkdir(parents=True)
    np.savez_compressed(data / "ik" / "tiny.npz", joints=np.array(chain.joint_names),
                        q=res.q, tcp=tcp, residual=res.residual, uvz_mm=sp.uvz_mm,
                        xyz_m=sp.xyz_m, kind=sp.kind,
                        stroke=np.zeros(len(sp.kind), np.int32), provenance=np.array("{}"))
    (data / "robot").mkdir()
    (data / "robot" / f"{desc.name}.urdf").write_text(to_urdf(desc))


def test_stage_end_to_end(tmp_path: Path, chain: Chain, desc: RobotDescription) -> None:
    _tiny_inputs(tmp_path, chain, desc)
    res = _stage(tmp_path)
    assert res.returncode == 0, res.stderr
    back = TrajectoryRecord.load(tmp_path / "trajectories" / "tiny.npz")
    assert np.all(np.diff(back.t) > 0) and back.joints == desc.joint_names
    assert back.provenance["config"]["speed"] == 1.0
    assert back.provenance["config"]["robot"]["mass_model"] == "printed"
    inputs = back.provenance["inputs"]
    assert inputs["ik"]["sha256"] == file_sha256(tmp_path / "ik" / "tiny.npz")
    assert inputs["urdf"]["sha256"] == file_sha256(tmp_path / "robot" / f"{desc.name}.urdf")
    m = json.loads((tmp_path / "metrics" / "trajectory" / "tiny.json").read_text())
    for key in ("duration_s", "marking_only_s", "cycle_over_marking", "peak_rate_rad_s",
                "peak_rate_rad_s_max", "peak_accel_rad_s2", "entries", "speed", "travel_s",
                "marking_s", "approach_s", "fastest_speed"):
        assert key in m, key
    assert m["entries"] == 3 and m["points"] == len(back.t)
    assert not [p for p in tmp_path.rglob("*") if ".tmp" in p.name]
    # too fast: refused with the fastest speed, nothing written
    (tmp_path / "trajectories" / "tiny.npz").unlink()
    res = _stage(tmp_path, "speed=500")
    assert res.returncode == 2 and len(res.stderr.strip().splitlines()) == 1
    found = FASTEST.search(res.stderr.strip())
    assert found and float(found.group(1)) == m["fastest_speed"]
    assert not (tmp_path / "trajectories" / "tiny.npz").exists()


def test_stage_missing_ik_names_the_ik_stage(tmp_path: Path) -> None:
    res = _stage(tmp_path)
    assert res.returncode == 2
    assert "'ik' stage" in res.stderr and len(res.stderr.strip().splitlines()) == 1
    assert not list(tmp_path.rglob("*.npz"))


def test_the_tip_comes_to_rest_where_it_turns_back_while_marking(
        chain: Chain, desc: RobotDescription) -> None:
    """A stroke joined to the next by a short drag the other way is a cusp: the jerk-
    limited law stops there, so the controller's reference turns back from rest (passed
    at speed, one on the built-in line art went at 3 mm/s and left the line by 20.8 um;
    stopped, 14.9 um)."""
    from tattotronix.trajectory.path import cusp_points

    # as on the line art: a line coming in at 20 degrees, a 0.05 mm drag back to the start
    # of a hatch run, and the run going out the way the drag came in
    k = np.arange(40, 0, -1)[:, None] * 0.15
    come = k * np.array([np.cos(np.radians(20.0)), np.sin(np.radians(20.0))])
    run = np.column_stack([-0.05 + np.arange(0.0, 6.0, 0.15), np.zeros(40)])
    uv = np.vstack([come, [[0.0, 0.0]], run])
    u, v = uv[:, 0], uv[:, 1]
    turn = len(come) + 1  # the drag's end, where the run begins
    uvz = np.column_stack((u, v, np.full_like(u, -1.5)))
    xyz = np.array([0.21, 0.0, SURFACE]) + uvz / 1000.0
    path = _solved(chain, xyz, np.ones(len(u), np.int8), uvz)
    on = np.ones(len(u) - 1, bool)
    assert cusp_points(path.tcp, on).tolist() == [turn]  # the turn into the drag is not one
    assert cusp_points(path.tcp, ~on).size == 0  # only while marking
    params = replace(_default_params(), travel="straight")
    assert params.jerk_rad_s3 is not None  # the default law: jerk-limited
    traj = plan_trajectory(path, chain, _limits(desc, params), params)
    tip_speed = np.linalg.norm(np.gradient(traj.tcp, traj.t, axis=0), axis=1)
    at = int(np.argmin(np.linalg.norm(traj.tcp - path.tcp[turn], axis=1)))
    assert tip_speed[at] < 0.02 * params.feed_mark_m_s


@settings(max_examples=60, deadline=None)
@given(halves=st.integers(1, 12), amp=st.floats(2e-4, 1.0), wobble=st.floats(0.0, 4.9e-5),
       n=st.integers(200, 600))
def test_marking_reversals_counts_each_turn_back_once(halves: int, amp: float, wobble: float,
                                                      n: int) -> None:
    """A joint swinging through ``halves`` half-periods while marking turns back
    ``halves - 1`` times; a wobble under the hysteresis adds none; a still joint none; and
    a turn across travel (the needle out) is not a reversal while marking."""
    from tattotronix.trajectory.path import REVERSAL_MIN_RAD, marking_reversals

    u = np.linspace(0.0, 1.0, n)
    swing = amp * (1 - np.cos(math.pi * halves * u)) / 2  # rests at both ends
    jitter = wobble * np.sin(2 * math.pi * 97 * u)
    q = np.column_stack([swing, 0.3 + jitter, np.full(n, -0.2), u, swing + jitter])
    kind = np.ones(n, np.int8)
    got = marking_reversals(q, kind)
    assert got[0] == halves - 1 and got[1] == 0 and got[2] == 0 and got[3] == 0
    assert got[4] == halves - 1  # the wobble rides on the swing without a turn of its own
    assert 2 * wobble < REVERSAL_MIN_RAD  # its back-moves are under the hysteresis
    # the same path with the needle out over every turn: nothing reverses while marking
    turns = np.round(np.arange(1, halves) * (n - 1) / halves).astype(int)
    out = kind.copy()
    out[turns] = 0
    assert marking_reversals(q, out)[0] == 0
