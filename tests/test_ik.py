"""Whole-path IK: the batched chain against Pinocchio, the solver against the reference."""

from __future__ import annotations

import os
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tattotronix.config.params import compose_settings
from tattotronix.errors import TattotronixError
from tattotronix.kinematics import (
    Chain,
    IkFailure,
    IkVerificationError,
    PinocchioTip,
    conditioning,
    solve_path,
    solve_path_sequential,
    solve_point,
    task_jacobian,
    verify,
)
from tattotronix.kinematics.synthetic import logo_like_strokes, raster_strokes, stroke_path
from tattotronix.robot.description import RobotDescription, build_description
from tattotronix.robot.urdf import to_urdf

DOWN = np.array([0.0, 0.0, -1.0])
TCP_ZERO_MM = (258.96, -9.444, 245.5775)  # docs/original.md, "1.3 Zero pose"


@pytest.fixture(scope="module")
def chain(desc: RobotDescription) -> Chain:
    return Chain.from_description(desc)


@pytest.fixture(scope="module")
def ref(desc: RobotDescription) -> PinocchioTip:
    return PinocchioTip.from_description(desc)


@pytest.fixture(scope="module")
def raster():
    """A few hundred points: rows over x 0.14 ... 0.28 m, y -0.06 ... 0.06 m at the
    marking depth (z = 0.0035 m), with plunges and lifts to clearance (z = 0.013 m)."""
    return stroke_path(raster_strokes((-70.0, 70.0), (-60.0, 60.0), rows=7), step_mm=2.5)


def _pin_frame_jacobian(ref: PinocchioTip, q: np.ndarray) -> tuple[np.ndarray, ...]:
    import pinocchio as pin

    data = ref.model.createData()
    jac = pin.computeFrameJacobian(ref.model, data, q, ref.frame_id, pin.LOCAL_WORLD_ALIGNED)
    m = data.oMf[ref.frame_id]
    return m.translation.copy(), m.rotation.copy(), jac


# --- the chain -----------------------------------------------------------------------------

def test_chain_zero_pose_is_the_published_tcp(chain: Chain) -> None:
    p, z = chain.fk(np.zeros(5))
    assert np.allclose(p[0] * 1000, TCP_ZERO_MM, atol=1e-6)
    assert np.allclose(z[0], [1.0, 0.0, 0.0], atol=1e-12)  # the tool axis is horizontal, +x


def test_chain_fk_and_jacobian_equal_pinocchio(desc: RobotDescription, chain: Chain,
                                               ref: PinocchioTip) -> None:
    q = np.random.default_rng(7).uniform(desc.lower, desc.upper, size=(60, 5))
    state = chain.state(q)
    p, z = chain.fk(q)
    jac = chain.jacobian(q)
    assert state.p.shape == (60, 3) and state.jacobian.shape == (60, 6, 5)
    for k, qk in enumerate(q):
        pp, rr, jj = _pin_frame_jacobian(ref, qk)
        assert np.abs(state.p[k] - pp).max() < 1e-12
        assert np.abs(state.rotation[k] - rr).max() < 1e-12
        assert np.abs(state.jacobian[k] - jj).max() < 1e-12
        assert np.abs(p[k] - pp).max() < 1e-12 and np.abs(z[k] - rr[:, 2]).max() < 1e-12
        assert np.abs(jac[k] - jj).max() < 1e-12


def test_chain_other_tip_and_bad_tip(desc: RobotDescription, ref: PinocchioTip) -> None:
    tool0 = Chain.from_description(desc, tip="tool0")
    ref0 = PinocchioTip.from_description(desc, tip="tool0")
    q = np.random.default_rng(3).uniform(desc.lower, desc.upper, size=(10, 5))
    p, z = tool0.fk(q)
    pp, zz = ref0.fk(q)
    assert np.abs(p - pp).max() < 1e-12 and np.abs(z - zz).max() < 1e-12
    with pytest.raises(TattotronixError, match="does not hang from"):
        Chain.from_description(desc, tip="shoulder_link")
    with pytest.raises(ValueError, match=r"\(N, 5\)"):
        tool0.fk(np.zeros((3, 4)))


def test_chain_is_immutable(chain: Chain) -> None:
    with pytest.raises(ValueError):
        chain.lower[0] = 0.0
    with pytest.raises(AttributeError):
        chain.tip_frame = "tool0"  # type: ignore[misc]


# --- single point --------------------------------------------------------------------------

def test_panel_centre_from_zero_pose(chain: Chain, ref: PinocchioTip) -> None:
    target = np.array([0.21, 0.0, 0.005])
    r = solve_point(ref, target, needle_axis=DOWN, q0=np.zeros(5))
    assert r.converged and r.reason == "" and r.residual < 1e-6
    assert np.all(np.abs(r.q) <= 1.57)
    p, z = ref.fk(r.q)
    assert np.linalg.norm(p[0] - target) < 1e-6  # the acceptance asks 0.1 mm
    assert np.linalg.norm(z[0] - DOWN) < 2e-6
    b = solve_path(chain, target[None], seed=np.zeros(5))
    assert b.ok and b.iterations[0] == r.iterations
    assert np.abs(b.q[0] - r.q).max() < 1e-12


# --- the path solver against the reference -------------------------------------------------

def test_batched_equals_reference_on_a_raster(chain: Chain, ref: PinocchioTip, raster) -> None:
    x = raster.xyz_m
    assert 300 <= len(x) <= 600
    assert np.isclose(x[:, 2].min(), 0.0035) and np.isclose(x[:, 2].max(), 0.013)
    seen: list[tuple[int, int]] = []
    b = solve_path(chain, x, progress=lambda done, total: seen.append((done, total)))
    s = solve_path_sequential(ref, x)
    assert s.ok and b.ok
    assert np.array_equal(b.converged, s.converged)
    assert np.abs(b.q - s.q).max() < 1e-4  # the same solutions, to the tolerance's slack
    assert b.worst_residual < 1e-6 and b.residual.max() < 1e-6
    p, z = ref.fk(b.q)
    assert np.linalg.norm(p - x, axis=1).max() < 1e-6
    assert np.linalg.norm(z - DOWN, axis=1).max() < 2e-6
    assert np.abs(b.q[:, 3]).max() < 1e-6  # joint_4 stays at zero: flat panel, vertical needle
    assert np.all(np.abs(b.q) <= 1.57)
    assert seen[-1] == (len(x), len(x)) and all(d <= t for d, t in seen)
    check = verify(ref, b, x)
    assert check.ok and check.checked == len(x) and check.max_position_error_m < 1e-6
    summary = b.summary()
    assert summary["converged_pct"] == 100.0 and summary["points"] == len(x)


def test_first_point_and_warm_start_follow_the_path(chain: Chain, ref: PinocchioTip,
                                                    raster) -> None:
    """Seeded from the predecessor's reference solution, the batch repeats the reference
    iteration for iteration (same arithmetic, in lockstep)."""
    from tattotronix.kinematics.ik import SEED, _solve_lockstep

    x = raster.xyz_m[:120]
    s = solve_path_sequential(ref, x)
    seeds = np.vstack([SEED, s.q[:-1]]).T.copy()
    b = _solve_lockstep(chain, np.ascontiguousarray(x.T), None, (0.0, 0.0, -1.0), seeds,
                        dls_lambda=1e-3, max_iter=200, tol=1e-6)
    assert np.array_equal(b.iterations, s.iterations)
    assert np.abs(b.q.T - s.q).max() < 1e-12
    assert np.abs(b.residual - s.residual).max() < 1e-15


def test_strict_settling_reproduces_the_sequential_solve(chain: Chain, ref: PinocchioTip,
                                                         raster) -> None:
    """With one anchor and no joint step tolerated, every point is re-solved from its
    predecessor until nothing moves: the sequential warm-started solve, to rounding."""
    x = raster.xyz_m[:80]
    b = solve_path(chain, x, anchor_spacing_m=1.0, branch_tol_rad=1e-9)
    s = solve_path_sequential(ref, x)
    assert b.stats["resolved"] >= len(x) - 1
    assert np.abs(b.q - s.q).max() < 1e-10
    assert np.array_equal(b.iterations, s.iterations)


def test_blocks_give_the_same_answer(chain: Chain, raster,
                                     monkeypatch: pytest.MonkeyPatch) -> None:
    import tattotronix.kinematics.ik as ik

    whole = solve_path(chain, raster.xyz_m)
    monkeypatch.setattr(ik, "BLOCK", 37)
    seen: list[int] = []
    blocks = solve_path(chain, raster.xyz_m, progress=lambda d, t: seen.append(d))
    assert np.array_equal(whole.q, blocks.q) and np.array_equal(whole.iterations,
                                                                 blocks.iterations)
    assert seen == sorted(seen) and seen[-1] == len(raster.xyz_m)


def test_per_point_axes_and_empty_path(chain: Chain, ref: PinocchioTip) -> None:
    x = np.array([[0.20, 0.01, 0.005], [0.22, -0.02, 0.008]])
    axes = np.array([[0.0, 0.0, -1.0], [0.1, 0.0, -1.0]])
    b = solve_path(chain, x, needle_axis=axes)
    assert b.ok
    _, z = ref.fk(b.q)
    unit = axes / np.linalg.norm(axes, axis=1, keepdims=True)
    assert np.linalg.norm(z - unit, axis=1).max() < 2e-6
    assert verify(ref, b, x, needle_axis=axes).ok
    empty = solve_path(chain, np.zeros((0, 3)))
    assert empty.ok and empty.points == 0
    with pytest.raises(TattotronixError, match="finite"):
        solve_path(chain, [[np.nan, 0.0, 0.0]])


@settings(max_examples=25, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.lists(st.tuples(st.floats(-70.0, 70.0), st.floats(-60.0, 60.0),
                          st.floats(-1.5, 8.0)), min_size=1, max_size=12))
def test_random_panel_points_converge_onto_target(chain: Chain, ref: PinocchioTip,
                                                  pts: list[tuple[float, float, float]]) -> None:
    x = np.array([0.21, 0.0, 0.005]) + np.array(pts) / 1000.0
    b = solve_path(chain, x)
    assert b.ok
    p, z = ref.fk(b.q)
    assert np.linalg.norm(p - x, axis=1).max() < 1e-6
    ang = np.arccos(np.clip(z @ DOWN, -1.0, 1.0))
    assert ang.max() < 1e-6 + 1e-7
    assert np.all(np.abs(b.q) <= 1.57)


@settings(max_examples=40, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.lists(st.floats(-1.2, 1.2), min_size=5, max_size=5))
def test_converged_means_on_target_for_any_pose(chain: Chain, ref: PinocchioTip,
                                                q: list[float]) -> None:
    """Targets made by FK of a configuration, needle along its own axis: a converged
    solve puts Pinocchio's tip and needle there; a failed one says why."""
    p, z = ref.fk(np.array(q))
    b = solve_path(chain, p, needle_axis=z[0])
    if b.ok:
        pp, zz = ref.fk(b.q)
        assert np.linalg.norm(pp - p) < 1e-6 and np.linalg.norm(zz - z) < 2e-6
        assert b.residual[0] < 1e-6
    else:
        assert b.reason[0] in ("joint limit", "unreachable") and b.residual[0] > 0


# --- refusal -------------------------------------------------------------------------------

def test_unreachable_point_is_refused_with_its_position(chain: Chain, ref: PinocchioTip,
                                                        raster) -> None:
    x = raster.xyz_m[:40].copy()
    uvz = raster.uvz_mm[:40].copy()
    x[25] = (0.40, 0.0, 0.005)
    uvz[25] = (190.0, 0.0, 0.0)
    b = solve_path(chain, x)
    s = solve_path_sequential(ref, x)
    assert not b.ok and list(b.failed) == [25]
    assert b.converged_pct == pytest.approx(100 * 39 / 40)
    # the first failure is the reference's, warm-started from the point before it
    assert s.failed[0] == 25 and b.reason[25] == s.reason[25]
    assert b.residual[25] == pytest.approx(s.residual[25], rel=1e-9)
    # the reference stays stuck in the clamped corner after it; the batch does not
    assert np.array_equal(b.converged[:25], s.converged[:25]) and s.failed.size >= 1
    with pytest.raises(IkFailure) as exc:
        b.raise_if_failed(uvz)
    msg = str(exc.value)
    assert "1 of 40" in msg and "point 25" in msg
    assert "(190.00, 0.00, 0.00) mm" in msg
    assert f"residual {b.residual[25]:.3g}" in msg and str(b.reason[25]) in msg
    with pytest.raises(IkFailure, match=r"arm frame \(400\.00, 0\.00, 5\.00\) mm"):
        b.raise_if_failed(targets_m=x)
    # alone, from the seed, nothing clamps: the arm is stretched out and short of it
    alone = solve_path(chain, x[25:26])
    assert alone.reason[0] == "unreachable" and alone.residual[0] > 0.09


def test_joint_limit_is_named(chain: Chain, ref: PinocchioTip) -> None:
    target = np.array([0.35, 0.0, 0.005])  # needs joint_2 past +1.57
    r = solve_point(ref, target)
    b = solve_path(chain, target[None])
    assert not r.converged and r.reason == "joint limit" and r.at_limit[1]
    assert b.reason[0] == "joint limit" and b.residual[0] == pytest.approx(r.residual, rel=1e-9)
    with pytest.raises(IkFailure, match=r"joint limit \(joint_2\)"):
        b.raise_if_failed(np.array([[140.0, 0.0, 0.0]]))


def test_ok_result_does_not_raise(chain: Chain) -> None:
    solve_path(chain, [[0.21, 0.0, 0.005]]).raise_if_failed()


def test_verify_catches_a_model_mismatch(desc: RobotDescription, chain: Chain,
                                         ref: PinocchioTip, raster) -> None:
    frames = tuple(replace(f, xyz=f.xyz + np.array([0.0, 0.0, 1e-5]))
                   if f.name == "tattoo_tcp" else f for f in desc.frames)
    wrong = Chain.from_description(replace(desc, frames=frames))
    x = raster.xyz_m[:30]
    b = solve_path(wrong, x)
    assert b.ok
    with pytest.raises(IkVerificationError, match="disagree"):
        verify(ref, b, x)
    out = verify(ref, b, x, raise_on_failure=False)
    assert not out.ok and out.max_position_error_m > 5e-6


# --- conditioning --------------------------------------------------------------------------

def test_task_jacobian_is_the_literal_construction(desc: RobotDescription, chain: Chain,
                                                   ref: PinocchioTip) -> None:
    q = np.random.default_rng(11).uniform(desc.lower, desc.upper, size=(20, 5))
    jt = task_jacobian(chain, q)
    for k, qk in enumerate(q):
        _, rot, jac = _pin_frame_jacobian(ref, qk)
        z = rot[:, 2]
        a = np.array([1.0, 0, 0]) if abs(z[0]) <= 0.9 else np.array([0, 1.0, 0])
        u = np.cross(z, a)
        u /= np.linalg.norm(u)
        v = np.cross(z, u)
        wz = np.cross(jac[3:].T, z)
        expect = np.vstack((jac[:3], wz @ u, wz @ v))
        assert np.abs(jt[k] - expect).max() < 1e-12


def test_singular_values_are_ordered(chain: Chain, raster) -> None:
    b = solve_path(chain, raster.xyz_m)
    c = conditioning(chain, b.q)
    assert np.all(np.diff(c.sigma, axis=1) <= 0)
    assert np.all(c.sigma[:, 0] >= c.sigma[:, -1]) and np.all(c.sigma[:, -1] > 0)
    assert np.allclose(c.cond, c.sigma[:, 0] / c.sigma[:, -1])
    jt = task_jacobian(chain, b.q)
    det = np.linalg.det(jt @ np.swapaxes(jt, 1, 2))
    assert np.allclose(c.manipulability, np.sqrt(np.maximum(det, 0)), rtol=1e-9)
    s = c.summary()
    assert s["cond"][0] <= s["worst_cond"] == s["cond"][1]
    assert s["sigma1"][0] <= s["sigma1"][1] and s["sigma5"][1] > 0
    w = np.array(s["worst_weakest_direction"])
    assert np.isclose(np.linalg.norm(w), 1.0) and w[np.abs(w).argmax()] > 0
    # the weakest direction moves the task by sigma_5 only
    assert np.isclose(np.linalg.norm(jt[c.worst] @ w), c.sigma[c.worst, -1])


@pytest.mark.slow
def test_logo_like_path_matches_reference_and_original_ranges(chain: Chain,
                                                              ref: PinocchioTip) -> None:
    path = stroke_path(logo_like_strokes())
    b = solve_path(chain, path.xyz_m)
    assert b.ok and b.worst_residual < 1e-6
    verify(ref, b, path.xyz_m)
    s = solve_path_sequential(ref, path.xyz_m)
    assert s.ok and np.abs(b.q - s.q).max() < 1e-4
    c = conditioning(chain, b.q).summary()
    # the same kind of numbers as the original's logo (docs/original.md, "3.4 Conditioning,
    # reachability, placement"): sigma_1 ~ 1.75
    assert 1.7 < c["sigma1"][0] <= c["sigma1"][1] < 1.8
    assert 0.03 < c["sigma5"][0] and c["cond"][1] < 60


def _ik_stage(data: Path, *overrides: str) -> subprocess.CompletedProcess[str]:
    root = Path(__file__).resolve().parents[1]
    env = {k: v for k, v in os.environ.items() if not k.startswith("DVC_")}
    return subprocess.run([sys.executable, str(root / "stages" / "ik.py"), f"paths.data={data}",
                           "artwork.name=t", *overrides],
                          cwd=data, env=env, capture_output=True, text=True)


def _toolpath_rest(n: int) -> dict[str, np.ndarray]:
    """The toolpath keys the ik stage does not use, and a provenance."""
    return {"t_s": np.arange(n, dtype=float), "stroke_kind": np.ones(1, np.int8),
            "stroke_region": np.zeros(1, np.int32),
            "stroke_width_mm": np.full(1, np.nan), "provenance": np.array("{}")}


def test_ik_stage_refuses_an_unreachable_placement_and_writes_nothing(tmp_path: Path) -> None:
    desc = build_description(compose_settings().robot)
    (tmp_path / "robot").mkdir()
    (tmp_path / "robot" / "tattotronix.urdf").write_text(to_urdf(desc))
    (tmp_path / "toolpath").mkdir()
    uvz = np.array([[0.0, 0.0, -1.5], [10.0, 0.0, -1.5], [190.0, 0.0, -1.5], [0.0, 5.0, -1.5]])
    xyz = np.array([0.21, 0.0, 0.005]) + uvz / 1000.0
    np.savez(tmp_path / "toolpath" / "t.npz", uvz_mm=uvz, xyz_m=xyz,
             kind=np.array([2, 1, 1, 1], dtype=np.int8), stroke=np.zeros(4, dtype=np.int32),
             **_toolpath_rest(4))
    run = _ik_stage(tmp_path)
    assert run.returncode == 2, run.stderr
    assert "190.00" in run.stderr and "residual" in run.stderr
    assert not (tmp_path / "ik").exists() and not (tmp_path / "metrics").exists()
    # the same path without the unreachable point is solved and written
    keep = [0, 1, 3]
    np.savez(tmp_path / "toolpath" / "t.npz", uvz_mm=uvz[keep], xyz_m=xyz[keep],
             kind=np.array([2, 1, 1], dtype=np.int8), stroke=np.zeros(3, dtype=np.int32),
             **_toolpath_rest(3))
    run = _ik_stage(tmp_path)
    assert run.returncode == 0, run.stderr
    with np.load(tmp_path / "ik" / "t.npz", allow_pickle=False) as z:
        assert z["q"].shape == (3, 5) and list(z["joints"]) == list(desc.joint_names)


def test_ik_stage_names_the_missing_stage(tmp_path: Path) -> None:
    run = _ik_stage(tmp_path)
    assert run.returncode == 2 and "'robot' stage" in run.stderr


def test_independent_points_each_from_its_own_seed(chain: Chain) -> None:
    """``solve_points``: poses from random reachable configurations, each solved from a
    seed near its own, land on their targets with their own (tilted) needle axes; bad
    seeds are refused in one line."""
    from tattotronix.kinematics.ik import solve_points

    rng = np.random.default_rng(7)
    q_true = np.array([0.0, 0.6, -0.9, 0.0, -1.2]) + rng.uniform(-0.3, 0.3, (40, 5))
    tip, axis = chain.fk(q_true)
    q, ok = solve_points(chain, tip, q_true + rng.uniform(-0.05, 0.05, q_true.shape),
                         needle_axis=axis)
    assert ok.all()
    got_tip, got_axis = chain.fk(q)
    assert np.abs(got_tip - tip).max() < 1e-5 and np.abs(got_axis - axis).max() < 1e-5
    with pytest.raises(TattotronixError, match=r"IK seeds must be \(40, 5\)"):
        solve_points(chain, tip, q_true[:3], needle_axis=axis)


def test_a_path_starting_far_from_the_seed_is_solved_backwards_from_its_first_solution(
        chain: Chain) -> None:
    """The first point of a drawing on a limb: the needle 31 deg from vertical along the
    skin's normal, where a solve from the default seed fails although the arm reaches it.
    Every later point has a neighbour to start from; the first is solved again from the
    point after it (five generated artworks on the forearm phantom were refused for this
    one point alone)."""
    from tattotronix.kinematics.ik import SEED, solve_points

    a, za = np.array([0.210142, 0.023865, 0.055246]), np.array([-0.046776, -0.515982,
                                                                 -0.855322])
    b = np.array([0.21, 0.0, 0.03])
    w = np.linspace(0.0, 1.0, 60)[:, None]
    x = (1 - w) * a + w * b
    z = (1 - w) * za + w * DOWN
    z /= np.linalg.norm(z, axis=1, keepdims=True)
    _, from_seed = solve_points(chain, x[:1], np.array([SEED]), needle_axis=z[:1])
    assert not from_seed[0]  # the situation: the seed alone does not get there
    res = solve_path(chain, x, needle_axis=z)
    assert res.ok and res.stats["head_resolved"] == 1, res.stats
    tip, axis = chain.fk(res.q)
    assert np.abs(tip - x).max() < 1e-5 and np.abs(axis - z).max() < 1e-5
