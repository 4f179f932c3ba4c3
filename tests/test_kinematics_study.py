"""The kinematics study (docs/kinematics.md; docs/original.md, "1.3 Zero pose" and "3.4
Conditioning, reachability, placement") and its stage."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import numpy as np
import pytest

from tattotronix.kinematics import Chain, PinocchioTip, solve_path
from tattotronix.kinematics.synthetic import SyntheticPath, logo_like_strokes, stroke_path
from tattotronix.robot.description import RobotDescription
from tattotronix.studies.kinematics import (
    Reachability,
    axis_distance_m,
    panel_reachability,
    path_conditioning,
    place_path,
    placement_sweep,
    workspace_samples,
    zero_pose_frames,
)

from .conftest import run_side_by_side

ORIGIN_M = np.array([0.21, 0.0, 0.005])
#: the original's reachability, 747 of 759 cells (docs/original.md, "3.4 Conditioning,
#: reachability, placement")
REACH_PCT = 98.419
FIGURES = ("manipulability.png", "reachability.png", "workspace.png", "placement.png")


@pytest.fixture(scope="module")
def chain(desc: RobotDescription) -> Chain:
    return Chain.from_description(desc)


@pytest.fixture(scope="module")
def reach(chain: Chain, desc: RobotDescription) -> Reachability:
    return panel_reachability(chain, desc)


@pytest.fixture(scope="module")
def logo() -> SyntheticPath:
    """The ROS-logo-like drawing (rings reaching the +x edge at v = 0), 0.5 mm steps."""
    return stroke_path(logo_like_strokes(), step_mm=0.5)


# --- zero pose, workspace ------------------------------------------------------------------

def test_zero_pose_frames_are_the_published_ones(desc: RobotDescription) -> None:
    zp = zero_pose_frames(desc)
    np.testing.assert_allclose(zp.tcp_mm, (258.96, -9.444, 245.5775), atol=0.01)
    np.testing.assert_allclose(zp.frames_mm["tool0"], (213.96, -9.444, 245.5775), atol=0.01)
    np.testing.assert_allclose(zp.tool_axis, (1.0, 0.0, 0.0), atol=1e-12)  # horizontal, +x
    assert zp.wrist_axis_mm == pytest.approx(242.0885, abs=1e-3)
    assert zp.chain_tcp_error_mm < 1e-9
    assert set(desc.joint_names).isdisjoint(zp.frames_mm)  # frames, not joints
    assert json.dumps(zp.summary())


def test_workspace_samples_are_seeded_and_inside_the_joint_box(chain: Chain) -> None:
    a, b = workspace_samples(chain, 500, seed=0), workspace_samples(chain, 500, seed=0)
    np.testing.assert_array_equal(a.q, b.q)
    assert a.tip_m.shape == (500, 3) and a.axis.shape == (500, 3)
    assert np.all(a.q >= chain.lower) and np.all(a.q <= chain.upper)
    np.testing.assert_allclose(np.linalg.norm(a.axis, axis=1), 1.0, atol=1e-12)
    assert not np.array_equal(a.q, workspace_samples(chain, 500, seed=1).q)


# --- reachability --------------------------------------------------------------------------

def test_panel_reachability_is_the_originals(reach: Reachability) -> None:
    pct = reach.percent
    assert abs(pct - REACH_PCT) <= 1.0, f"panel reachability {pct:.3f} %"
    assert reach.reachable.shape == (23, 33)
    assert reach.z_m == pytest.approx(0.005)
    assert reach.x_m[0] == pytest.approx(0.11) and reach.x_m[-1] == pytest.approx(0.31)
    assert reach.y_m[0] == pytest.approx(-0.07) and reach.y_m[-1] == pytest.approx(0.07)


def test_panel_reachability_fails_only_on_the_outer_x_edge(reach: Reachability) -> None:
    failing = reach.failing
    assert failing, "the original fails at the far panel corners"
    assert reach.failures_on_outer_x_edge
    assert all(x == pytest.approx(310.0) for x, _, _ in failing)
    # the far corners fail, the far edge's middle does not (it is nearest the base)
    assert not reach.reachable[0, -1] and not reach.reachable[-1, -1]
    assert reach.reachable[len(reach.y_m) // 2, -1]
    ok = reach.reachable
    assert np.all(np.isfinite(reach.sigma5[ok])) and np.all(np.isnan(reach.sigma5[~ok]))
    assert np.all(np.isnan(reach.q[~ok]))
    s = reach.summary()
    assert s["reachable"] == int(ok.sum()) and s["failures_on_outer_x_edge"]
    assert json.dumps(s)


# --- conditioning along the path -----------------------------------------------------------

def test_path_conditioning_is_ordered_and_worst_at_the_drawings_plus_x(
    chain: Chain, logo: SyntheticPath
) -> None:
    res = solve_path(chain, logo.xyz_m)
    assert res.ok
    pc = path_conditioning(chain, res.q, logo.uvz_mm)
    assert np.all(pc.sigma1 >= pc.sigma5) and np.all(pc.sigma5 > 0)
    assert np.all(np.diff(pc.cond.sigma, axis=1) <= 1e-12)  # sigma_1 >= ... >= sigma_5
    drawn = logo.kind != 0
    u_max = logo.uvz_mm[drawn, 0].max()
    assert pc.worst_point_mm[0] >= u_max - 2.0, (pc.worst_point_mm, u_max)
    assert np.linalg.norm(pc.weakest_direction) == pytest.approx(1.0)
    # the original's weakest direction: elbow against shoulder and wrist pitch, no yaw or roll
    d = pc.weakest_direction
    assert abs(d[0]) < 0.05 and abs(d[3]) < 0.01 and d[2] > 0.7 and d[1] < 0 and d[4] < 0
    s = pc.summary()
    assert s["cond"][1] == pytest.approx(s["worst_cond"])
    assert json.dumps(s)


def test_sigma5_depends_only_on_the_distance_from_the_base_axis(chain: Chain) -> None:
    """Rotating a target about the joint_1 axis leaves the task Jacobian's singular values
    unchanged (needle vertical): the law behind the placement finding."""
    ang = np.radians([-20.0, -7.0, 0.0, 12.0, 25.0])
    for r in (0.20, 0.29):
        x = np.column_stack((r * np.cos(ang), r * np.sin(ang), np.full(len(ang), 0.0035)))
        res = solve_path(chain, x, anchor_spacing_m=1e-9)
        assert res.ok
        pc = path_conditioning(chain, res.q, (x - ORIGIN_M) * 1000)
        # equal to the IK tolerance (1e-6 on the task error); 1 mm more reach moves
        # sigma_5 by ~1 % out there
        np.testing.assert_allclose(pc.cond.sigma, np.broadcast_to(pc.cond.sigma[0], (len(x), 5)),
                                   rtol=1e-4)
        np.testing.assert_allclose(axis_distance_m(chain, x), r, rtol=1e-12)


# --- placement ---------------------------------------------------------------------------

def test_place_path_scales_and_shifts_the_drawing(logo: SyntheticPath) -> None:
    out = place_path(logo.uvz_mm, logo.kind, 120.0, 15.0)
    drawn = logo.kind != 0
    u = out[drawn, 0]
    assert u.max() == pytest.approx(75.0) and u.max() - u.min() == pytest.approx(120.0)
    np.testing.assert_array_equal(out[:, 2], logo.uvz_mm[:, 2])  # depths kept
    v = out[drawn, 1]
    assert v.max() == pytest.approx(-v.min())  # centred in v
    with pytest.raises(Exception, match="width"):
        place_path(logo.uvz_mm, logo.kind, 0.0, 0.0)


def test_placement_sweep_sigma5_falls_with_reach_and_equal_reach_agrees(
    chain: Chain, logo: SyntheticPath
) -> None:
    widths = (120.0, 150.0, 120.0, 100.0, 150.0, 120.0)
    offsets = (0.0, 0.0, 15.0, 30.0, 15.0, 30.0)
    sweep = placement_sweep(chain, logo.uvz_mm, logo.kind, widths, offsets, origin_m=ORIGIN_M)
    rows = sweep.rows
    assert [p.reach_mm for p in rows] == [60.0, 75.0, 75.0, 80.0, 90.0, 90.0]
    assert all(p.converged_pct == 100.0 for p in rows)
    by_reach: dict[float, list[float]] = {}
    for p in rows:
        by_reach.setdefault(p.reach_mm, []).append(p.sigma5_min)
        assert p.cond_max > 1.0 and p.sigma5_min > 0
    reaches = sorted(by_reach)
    means = [float(np.mean(by_reach[r])) for r in reaches]
    assert all(a > b for a, b in zip(means, means[1:], strict=False)), means
    spreads = sweep.equal_reach_spread_pct()
    assert set(spreads) == {"75", "90"}
    assert all(s < 1.0 for s in spreads.values()), spreads
    # the original's table (logo, 16 656 points), to a few per cent
    ref = {60.0: 0.05897, 75.0: 0.04832, 80.0: 0.04407, 90.0: 0.03325}
    for r, v in ref.items():
        assert float(np.mean(by_reach[r])) == pytest.approx(v, rel=0.03)
    assert json.dumps(sweep.summary())


def test_placement_sweep_pairs_widths_and_offsets(chain: Chain, logo: SyntheticPath) -> None:
    with pytest.raises(Exception, match="same length"):
        placement_sweep(chain, logo.uvz_mm, logo.kind, (120.0, 150.0), (0.0,))


# --- the stage ---------------------------------------------------------------------------

def _write_ik(data: Path, desc: RobotDescription, chain: Chain) -> None:
    """A synthetic ``data/ik/test.npz`` as the ik stage writes it (a small logo)."""
    path = stroke_path(logo_like_strokes(width_mm=100.0), step_mm=1.0)
    res = solve_path(chain, path.xyz_m)
    assert res.ok
    tcp, _ = chain.fk(res.q)
    (data / "ik").mkdir(parents=True)
    np.savez_compressed(data / "ik" / "test.npz", joints=np.array(desc.joint_names), q=res.q,
                        tcp=tcp, residual=res.residual, uvz_mm=path.uvz_mm, xyz_m=path.xyz_m,
                        kind=path.kind, stroke=np.zeros(len(path), np.int32),
                        provenance=np.array("{}"))


@pytest.fixture(scope="module")
def stage_runs(tmp_path_factory: pytest.TempPathFactory, desc: RobotDescription,
               chain: Chain) -> dict[str, tuple[subprocess.CompletedProcess[str], Path]]:
    """The stage on a synthetic ik file, and on an empty data folder, run side by side."""
    base = tmp_path_factory.mktemp("kinematics_stage")
    good, empty = base / "good", base / "empty"
    _write_ik(good, desc, chain)
    empty.mkdir()
    return run_side_by_side("kinematics", {"good": good, "empty": empty}, "artwork.name=test")


def test_stage_writes_metrics_and_figures(stage_runs) -> None:
    run, data = stage_runs["good"]
    assert run.returncode == 0, run.stderr
    metrics = json.loads((data / "metrics" / "kinematics" / "test.json").read_text())
    assert metrics["name"] == "test"
    assert {"zero_pose", "path", "reachability", "placement", "workspace"} <= set(metrics)
    assert abs(metrics["reachability"]["reachable_pct"] - REACH_PCT) <= 1.0
    p = metrics["path"]
    assert p["sigma1"][0] >= p["sigma5"][1] > 0 and p["cond"][0] >= 1.0
    assert len(p["weakest_direction"]) == 5 and len(p["worst_point_mm"]) == 3
    rows = metrics["placement"]["rows"]
    assert set(rows) == {"120x0", "150x0", "120x15", "100x30", "150x15", "120x30", "150x30",
                         "150x45"}
    assert rows["150x45"]["converged_pct"] < 100.0 <= rows["150x0"]["converged_pct"]
    assert metrics["workspace"]["samples"] == 60_000
    np.testing.assert_allclose(metrics["panel_origin_m"], ORIGIN_M, atol=1e-12)
    for name in FIGURES:
        png = data / "figures" / "test" / name
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", name
    leftovers = [f for f in data.rglob("*") if ".tmp" in f.name]
    assert not leftovers


def test_stage_without_ik_names_the_ik_stage(stage_runs) -> None:
    run, data = stage_runs["empty"]
    assert run.returncode == 2
    assert "'ik' stage" in run.stderr and "test.npz" in run.stderr
    assert "Traceback" not in run.stderr
    assert not (data / "metrics").exists() and not (data / "figures").exists()


def test_pinocchio_reference_is_optional(chain: Chain, desc: RobotDescription) -> None:
    """A 2 x 2 grid with a given Pinocchio model: the panel corners, as the full grid."""
    ref = PinocchioTip.from_description(desc)
    small = panel_reachability(chain, desc, 2, 2, ref=ref)
    assert small.reachable.tolist() == [[True, False], [True, False]]
