"""Collision safety: derived allowed pairs, mesh hulls and k-DOPs, pose reports, the swept
trajectory check, the margin and plunge refusals, the stage's pose CLI, and the deploy gate.

Tests marked ``cad`` need the CAD meshes (``TATTOTRONIX_CAD_DIR``, e.g.
``/work/shared/cad/meshes``); the rest run on the committed k-DOP table.
"""

from __future__ import annotations

import json
import re
import subprocess
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from numpy.typing import NDArray
from scipy.optimize import least_squares

from tattotronix.collision import shapes
from tattotronix.collision.check import CollisionRefused, TrajectoryClearance, check_trajectory
from tattotronix.collision.model import CollisionModel, parse_pose
from tattotronix.collision.pairs import body_pairs
from tattotronix.config.params import compose_settings
from tattotronix.devtools import tables
from tattotronix.errors import TattotronixError
from tattotronix.hardware.gate import require_checked
from tattotronix.io.provenance import file_sha256
from tattotronix.report.robot import collision_pairs_report, zero_pose_report
from tattotronix.robot.description import RobotDescription, build_description
from tattotronix.robot.stl import mesh_dir_files

from .conftest import PYTHON, ROOT, small_art, stage_env

Array = NDArray[np.float64]

HOME = (0.0, 0.0, 0.0, 0.0, 0.0)
INTO_BENCH = (0.0, 1.57, 0.0, 0.0, 0.0)  # the arm folded forward into the bench
THROUGH_SHOULDER = (0.0, 1.5, 1.5, 0.0, 0.0)  # the wrist folded back through the shoulder
# docs/original.md, "Allowed collision pairs": the 6 allowed of the 21 link pairs, and why
ALLOWED_LINK_PAIRS = {
    ("base_link", "shoulder_link"): "joint_1",
    ("shoulder_link", "upper_arm_link"): "joint_2",
    ("upper_arm_link", "forearm_link"): "joint_3",
    ("forearm_link", "wrist_link"): "joint_4",
    ("wrist_link", "tool_mount_link"): "joint_5",
    ("tool_mount_link", "tattoo_pen_link"): "rigidly attached",
}
# A joint_5 sweep that swings the pen down through the bench and up again: the pen grazes
# the bench between 62 % and 86 % of the way, while both ends and the midpoint are clear.
GRAZE_ARM = (0.91, 0.29, 0.97, -0.91)
GRAZE_Q5 = (-1.5, 0.9)
PEN_BENCH = "tattoo_pen_link|bench"
MARGIN_M = 1e-3  # collision.margin_mm (CollisionConfig)
PLUNGE_M = 1.5e-3  # toolpath.plunge_mm (ToolpathConfig)
# coal's GJK stops at 1e-6 m and warm-starts from the last query, so one pose's clearance
# can differ by about a micrometre between calls
GJK_M = 2e-6


@pytest.fixture(scope="module")
def kdop(desc: RobotDescription) -> CollisionModel:
    """The collision model of the default description: committed k-DOPs, no meshes."""
    return CollisionModel(desc)


@pytest.fixture(scope="module")
def mesh_desc(cad_dir: Path) -> RobotDescription:
    return build_description(compose_settings([f"robot.cad_dir={cad_dir}"]).robot)


@pytest.fixture(scope="module")
def mesh(mesh_desc: RobotDescription) -> CollisionModel:
    """The collision model on the convex hulls of the CAD meshes."""
    return CollisionModel(mesh_desc)


def _graze_pose(q5: float) -> Array:
    return np.array([*GRAZE_ARM, q5])


def _pose_with_tip(model: CollisionModel, xyz: tuple[float, float, float]) -> Array:
    """A pose with the tip at ``xyz`` (m) and the pen pointing straight down."""
    target = np.asarray(xyz)

    def residual(q: Array) -> Array:
        tcp, _, axis = model.frames(q)
        return np.concatenate([tcp[0] - target, axis[0] - (0.0, 0.0, -1.0)])

    d = model.desc
    res = least_squares(residual, np.array([0.0, 0.5, 0.5, 0.0, 0.5]), bounds=(d.lower, d.upper),
                        xtol=1e-15, ftol=1e-15, gtol=1e-15)
    assert np.abs(res.fun).max() < 1e-9, "the test pose is unreachable"
    return np.asarray(res.x, dtype=np.float64)


def _check(model: CollisionModel, t: Any, q: Any, margin_m: float = MARGIN_M,
           plunge_m: float = PLUNGE_M) -> TrajectoryClearance:
    return check_trajectory(model, np.asarray(t, dtype=np.float64),
                            np.asarray(q, dtype=np.float64), margin_m=margin_m,
                            plunge_m=plunge_m)


# ----------------------------------------------------------------------------- allowed pairs


def test_allowed_link_pairs_are_the_six_hinges_and_the_pen_mount(desc: RobotDescription
                                                                 ) -> None:
    pairs = body_pairs(desc)
    links = [p for p in pairs if not p.environment]
    assert len(links) == 21
    allowed = {(p.a, p.b): p for p in links if not p.checked}
    assert set(allowed) == set(ALLOWED_LINK_PAIRS)
    for key, why in ALLOWED_LINK_PAIRS.items():
        assert why in allowed[key].reason, (key, allowed[key].reason)
        assert allowed[key].joints == (() if why == "rigidly attached" else (why,))
    # the environment: only the base, bolted to the bench, may touch the bench and the panel
    env_allowed = {p.name: p.reason for p in pairs if p.environment and not p.checked}
    assert set(env_allowed) == {"base_link|bench", "base_link|panel"}
    assert all(r.startswith("rigidly attached") for r in env_allowed.values())
    # every checked pair has a movable joint between its bodies, and no reason
    assert all(p.joints and not p.reason for p in pairs if p.checked)
    assert sum(p.checked for p in pairs) == 15 + 12


@pytest.mark.parametrize(("override", "link_pairs", "allowed", "checked_too"), [
    # no pen: one link fewer, and no pen mount to allow
    ("robot.tool=none", 15,
     {k for k in ALLOWED_LINK_PAIRS if "tattoo_pen_link" not in k}, set()),
    # the pen hung off the wrist: the wrist holds it rigidly, the bracket no longer does
    ("robot.tool0.parent=wrist_link", 21,
     {k for k in ALLOWED_LINK_PAIRS if k != ("tool_mount_link", "tattoo_pen_link")}
     | {("wrist_link", "tattoo_pen_link")}, {"tool_mount_link|tattoo_pen_link"}),
])
def test_allowed_pairs_follow_the_tree(override: str, link_pairs: int,
                                       allowed: set[tuple[str, str]], checked_too: set[str]
                                       ) -> None:
    d = build_description(compose_settings([override]).robot)
    links = [p for p in body_pairs(d) if not p.environment]
    assert len(links) == link_pairs
    assert {(p.a, p.b) for p in links if not p.checked} == allowed
    assert checked_too <= {p.name for p in links if p.checked}
    report = collision_pairs_report(d)
    assert (report["link_pairs"], report["allowed_link_pairs"]) == (link_pairs, len(allowed))


def test_robot_report_lists_the_derived_pairs(desc: RobotDescription,
                                              models: tuple[Path, Path]) -> None:
    pairs = body_pairs(desc)
    report = collision_pairs_report(desc)
    assert report["link_pairs"] == 21
    assert report["allowed_link_pairs"] == 6
    assert report["checked_pairs"] == sum(p.checked for p in pairs) == 27
    assert report["allowed"] == [{"pair": [p.a, p.b], "reason": p.reason}
                                 for p in pairs if not p.checked]
    assert "needle" in report["needle"] and "plunge_mm" in report["needle"]
    # what the robot stage writes into data/metrics/robot.json
    assert zero_pose_report(desc, *models, poses=1)["collision_pairs"] == report


def test_model_checks_exactly_the_checked_pairs(kdop: CollisionModel) -> None:
    assert kdop.pair_names == [p.name for p in body_pairs(kdop.desc) if p.checked]
    assert kdop.clearance(np.zeros(5)).shape == (27,)
    assert kdop.clearance(np.zeros((3, 5))).shape == (3, 27)
    assert np.all(np.isfinite(kdop.clearance(np.zeros(5))))


# ----------------------------------------------------------------------------- poses


@pytest.mark.cad
def test_mesh_hull_poses(mesh: CollisionModel) -> None:
    assert mesh.geometry == "mesh hulls"
    home = mesh.pose_report(HOME)
    assert home.collisions == []
    assert home.min_clearance_m * 1000 == pytest.approx(3.457, abs=0.01)
    assert home.worst_pair == ["upper_arm_link", "wrist_link"]
    assert home.within_limits

    bench = mesh.pose_report(INTO_BENCH)
    assert ["wrist_link", "bench"] in bench.collisions
    assert bench.worst_pair == ["tattoo_pen_link", "bench"]
    assert bench.min_clearance_m < -0.1  # the pen is 137 mm deep in the bench

    folded = mesh.pose_report(THROUGH_SHOULDER)
    assert folded.worst_pair == ["shoulder_link", "wrist_link"]
    assert ["shoulder_link", "wrist_link"] in folded.collisions
    assert folded.min_clearance_m == folded.clearance_m["shoulder_link|wrist_link"] < 0
    assert all(folded.clearance_m["|".join(p)] <= 0 for p in folded.collisions)
    assert all(c > 0 for n, c in folded.clearance_m.items()
               if n.split("|") not in folded.collisions)


def test_kdop_poses(kdop: CollisionModel) -> None:
    assert kdop.geometry == "k-DOP"
    home = kdop.pose_report(HOME)
    assert home.collisions == []
    assert home.min_clearance_m * 1000 == pytest.approx(1.997, abs=0.01)
    assert home.worst_pair == ["upper_arm_link", "wrist_link"]

    bench = kdop.pose_report(INTO_BENCH)
    assert ["wrist_link", "bench"] in bench.collisions
    assert bench.worst_pair == ["tattoo_pen_link", "bench"]
    assert bench.collisions == [p.split("|") for p, c in bench.clearance_m.items() if c <= 0]

    folded = kdop.pose_report(THROUGH_SHOULDER)
    assert folded.worst_pair == ["shoulder_link", "wrist_link"]


def test_kdops_are_tighter_than_the_bounding_boxes(desc: RobotDescription,
                                                   kdop: CollisionModel) -> None:
    # the boxes of the upper arm and the wrist overlap at the zero pose (shapes docstring)
    boxes = CollisionModel(desc, kdops={}).pose_report(HOME)
    assert boxes.collisions == [["upper_arm_link", "wrist_link"]]
    assert boxes.min_clearance_m * 1000 == pytest.approx(-2.1, abs=0.01)
    assert kdop.pose_report(HOME).clearance_m["upper_arm_link|wrist_link"] > 0.0019


def test_pen_bench_clearance_is_the_pen_lowest_point(kdop: CollisionModel,
                                                     desc: RobotDescription) -> None:
    rng = np.random.default_rng(20261121)
    q = rng.uniform(desc.lower, desc.upper, size=(600, 5))
    z = kdop.pen_lowest_z(q)
    tcp, tool0, _ = kdop.frames(q)
    half = np.asarray(desc.bench_size[:2]) / 2 - 0.02  # well inside the bench top
    over = (z > 0) & np.all(np.abs(tcp[:, :2]) < half, axis=1) & np.all(
        np.abs(tool0[:, :2]) < half, axis=1)
    assert over.sum() > 100
    c = kdop.clearance(q[over])[:, kdop.pair_names.index(PEN_BENCH)]
    assert np.abs(c - z[over]).max() < GJK_M
    # at the zero pose the pen lies level, its underside one radius under tool0
    radius = float(desc.geometry["tattoo_pen_link"][0].size[0])
    assert kdop.pen_lowest_z(np.zeros(5))[0] == pytest.approx(0.2455775 - radius, abs=1e-7)


def test_motion_bound_bounds_the_change_of_clearance(kdop: CollisionModel,
                                                     desc: RobotDescription) -> None:
    rng = np.random.default_rng(7)
    q0 = rng.uniform(desc.lower, desc.upper, size=(300, 5))
    q1 = np.clip(q0 + rng.normal(0.0, 0.3, size=q0.shape), desc.lower, desc.upper)
    bound = kdop.motion_bound_m(q0, q1)
    assert bound.shape == (300, 27)
    assert np.all(np.abs(kdop.clearance(q1) - kdop.clearance(q0)) <= bound + GJK_M)
    # along the line too, from one end to each of its interior points
    s = np.linspace(0.0, 1.0, 11)
    for a, b in zip(q0[:20], q1[:20], strict=True):
        line = a + s[:, None] * (b - a)
        change = np.abs(kdop.clearance(line) - kdop.clearance(a))
        assert np.all(change <= kdop.motion_bound_m(np.tile(a, (11, 1)), line) + GJK_M)
    # no motion, no bound; only joint_1 moves the shoulder relative to the bench
    assert np.all(kdop.motion_bound_m(q0[:1], q0[:1]) == 0)
    reach = bound[:, kdop.pair_names.index("shoulder_link|bench")] / np.abs(q1 - q0)[:, 0]
    assert np.allclose(reach, reach[0]) and 0.1 < reach[0] < 0.15  # m, the shoulder's size


def test_bad_poses_are_refused(kdop: CollisionModel, desc: RobotDescription) -> None:
    for bad in ([0.0] * 4, [[0.0] * 6], [0.0, np.nan, 0.0, 0.0, 0.0]):
        with pytest.raises(TattotronixError, match="5 finite joint angles"):
            kdop.clearance(bad)
    assert parse_pose([0, 1, 0, 0, 0], desc).tolist() == [0.0, 1.0, 0.0, 0.0, 0.0]
    with pytest.raises(TattotronixError, match="joint_1, joint_2, joint_3, joint_4, joint_5"):
        parse_pose([0, 1], desc)
    with pytest.raises(TattotronixError, match="give 5 finite"):
        parse_pose([0, 0, float("inf"), 0, 0], desc)
    with pytest.raises(TattotronixError, match=r"pose=\[0,0,0,0,0\]"):
        parse_pose(3.0, desc)


def test_pose_report_is_strict_json_with_the_tip_off_the_panel(kdop: CollisionModel) -> None:
    report = kdop.pose_report([1.0, 0.0, 0.0, 0.0, 0.0])  # yawed: the tip is off the panel
    doc = json.loads(json.dumps(report.to_json(MARGIN_M, kdop.geometry), allow_nan=False))
    assert doc["needle_depth_mm"] is None


# ----------------------------------------------------------------------------- k-DOP table


@pytest.mark.cad
def test_every_mesh_vertex_lies_inside_its_kdop(cad_dir: Path,
                                                mesh_desc: RobotDescription) -> None:
    table = shapes.load_kdops()
    files = mesh_dir_files(cad_dir, list(table))
    assert set(table) == set(files) == set(mesh_desc.links) - {"tattoo_pen_link"}
    d = shapes.directions(shapes.KDOP_DIRECTIONS)
    for link, stl in files.items():
        off = table[link]
        assert off.shape == (shapes.KDOP_DIRECTIONS,)
        pts = shapes.mesh_vertices(stl, mesh_desc.geometry[link][0].size)
        assert len(pts) > 1000
        assert np.all(pts @ d.T <= off + 1e-12), link
        # and tightly: every plane touches the mesh to within the 0.01 mm rounding
        assert np.all(off - (pts @ d.T).max(axis=0) <= 1e-5 + 1e-12), link
        # the polytope's corners satisfy every plane, and enclose the mesh's extent
        corners = shapes.kdop_vertices(off)
        assert np.all(corners @ d.T <= off + 1e-9), link
        assert np.all(corners.min(axis=0) <= pts.min(axis=0) + 1e-9)
        assert np.all(corners.max(axis=0) >= pts.max(axis=0) - 1e-9)


@pytest.mark.cad
def test_committed_kdop_table_matches_the_meshes(cad_dir: Path,
                                                 monkeypatch: pytest.MonkeyPatch,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    run = subprocess.run([PYTHON, "-m", "tattotronix.devtools.tables", "kdops", "--cad-dir",
                          str(cad_dir)], cwd=ROOT, env=stage_env(), text=True,
                         capture_output=True, timeout=120)
    assert run.returncode == 0, run.stdout + run.stderr
    assert "largest difference from the meshes: 0.0000 mm" in run.stdout
    # the comparison is real: a table 0.02 mm off on one plane fails it
    stale = shapes.load_kdops()
    stale["wrist_link"] = stale["wrist_link"].copy()
    stale["wrist_link"][17] += 2e-5
    monkeypatch.setattr(shapes, "load_kdops", lambda: stale)
    assert tables.main(["kdops", "--cad-dir", str(cad_dir)]) == 1
    assert "0.0200 mm" in capsys.readouterr().out


@pytest.mark.cad
def test_kdop_clearance_is_conservative(kdop: CollisionModel, mesh: CollisionModel,
                                        desc: RobotDescription) -> None:
    """k-DOPs enclose the hulls, so every pair is at most as clear as on the meshes."""
    assert kdop.pair_names == mesh.pair_names
    rng = np.random.default_rng(11)
    q = np.vstack([rng.uniform(desc.lower, desc.upper, size=(150, 5)),
                   HOME, INTO_BENCH, THROUGH_SHOULDER])
    ck, cm = kdop.clearance(q), mesh.clearance(q)
    assert np.all(ck <= cm + GJK_M), kdop.pair_names[int(np.argmax((ck - cm).max(axis=0)))]
    # strictly for the links' own pairs (the pen and the world are the same shapes in both)
    links = [i for i, n in enumerate(kdop.pair_names)
             if "tattoo_pen_link" not in n and "bench" not in n and "panel" not in n]
    assert np.all((ck - cm)[:, links].max(axis=0) < 0)
    home = kdop.pair_names.index("upper_arm_link|wrist_link")
    assert (cm[150, home] - ck[150, home]) * 1000 == pytest.approx(1.46, abs=0.05)


@pytest.mark.parametrize(("text", "match"), [
    ("{", "is not a k-DOP table"),
    ('{"links": {}}', "is not a k-DOP table: 'directions'"),
    ('{"directions": "x", "links": {}}', "is not a k-DOP table"),
    ('{"directions": 4, "links": {"wrist_link": "abcd"}}', "is not a k-DOP table"),
    ('{"directions": 4, "links": {"wrist_link": [1, 2, 3]}}', "wrist_link needs 4 finite"),
    ('{"directions": 4, "links": {"wrist_link": [1, 2, NaN, 4]}}', "wrist_link needs 4 finite"),
    ('{"directions": 4, "links": [1, 2, 3, 4]}', "is not a k-DOP table"),
])
def test_bad_kdop_table_is_refused(tmp_path: Path, text: str, match: str) -> None:
    table = tmp_path / "kdop.json"
    table.write_text(text)
    with pytest.raises(TattotronixError, match=match):
        shapes.load_kdops(table)


def test_kdop_table_helpers(tmp_path: Path) -> None:
    assert shapes.load_kdops(tmp_path / "absent.json") == {}
    with pytest.raises(TattotronixError, match="at least 4 directions"):
        shapes.directions(3)
    d = shapes.directions(64)
    assert np.allclose(np.linalg.norm(d, axis=1), 1.0)
    assert np.abs(d.mean(axis=0)).max() < 0.02  # spread over the whole sphere
    with pytest.raises(TattotronixError, match="bound no solid"):
        shapes.kdop_vertices(-np.ones(64))
    cube = shapes.kdop_offsets(np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1)
                                         for z in (-1, 1)], dtype=np.float64) * 0.01, 64)
    corners = shapes.kdop_vertices(cube)
    assert np.all(corners @ d.T <= cube + 1e-12)
    assert np.abs(corners).max() <= 0.01 * 3**0.5 + 1e-5


# ----------------------------------------------------------------------------- trajectories


def test_swept_check_catches_a_graze_between_clear_samples(kdop: CollisionModel) -> None:
    q0, q1 = _graze_pose(GRAZE_Q5[0]), _graze_pose(GRAZE_Q5[1])
    p = kdop.pair_names.index(PEN_BENCH)
    ends = kdop.clearance(np.array([q0, q1, (q0 + q1) / 2]))
    assert ends.min() > 2 * MARGIN_M  # both samples, and even their midpoint, are clear
    s = np.linspace(0.0, 1.0, 2401)
    dense = kdop.clearance(q0 + s[:, None] * (q1 - q0))[:, p]
    assert dense.min() < -1e-3  # ... but the pen dips ~2 mm into the bench in between
    below = s[dense < MARGIN_M]

    t0, t1 = 2.0, 3.0
    rep = _check(kdop, [t0, t1], [q0, q1])
    assert not rep.ok
    assert rep.collisions == 1
    assert [e["pair"] for e in rep.events] == [PEN_BENCH]
    event = rep.events[0]
    assert t0 < event["time_s"] < t1
    assert t0 + below.min() - 1e-3 <= event["time_s"] <= t0 + below.max() + 1e-3
    # the event's pose is on the joint line at its time, and really is under the margin
    frac = (event["time_s"] - t0) / (t1 - t0)
    assert np.allclose(event["pose"], q0 + frac * (q1 - q0), atol=1e-12)
    assert kdop.clearance(np.array(event["pose"]))[p] < MARGIN_M
    # the least clearance found is a real one, within half the resolution of the truth
    assert kdop.clearance(rep.at_pose[p])[p] == pytest.approx(rep.min_clearance_m[p], abs=GJK_M)
    assert t0 < rep.at_time_s[p] < t1
    assert dense.min() - GJK_M <= rep.min_clearance_m[p] <= dense.min() + rep.resolution_m / 2
    assert event["clearance_mm"] == pytest.approx(rep.min_clearance_m[p] * 1000)
    assert rep.samples > 2 and rep.bisected > 0
    # the message names the pair, the time and the pose
    msg = rep.message()
    assert re.match(rf"tattoo_pen_link and bench collides? at t = {event['time_s']:.3f} s ", msg)
    assert f"{event['clearance_mm']:.2f} mm" in msg
    assert "pose [" + ", ".join(f"{v:.4f}" for v in event["pose"]) + "] rad" in msg
    assert str(CollisionRefused(rep)) == f"trajectory refused: {msg}"
    assert rep.metrics()["worst_pair"] == ["tattoo_pen_link", "bench"]
    assert rep.metrics()["below_margin"] == 1


def test_swept_check_passes_a_clear_sweep(kdop: CollisionModel) -> None:
    # the same sweep, stopped before the pen reaches down to the bench
    q0, q1 = _graze_pose(-1.5), _graze_pose(-0.3)
    rep = _check(kdop, [0.0, 1.0], [q0, q1])
    assert rep.ok and rep.events == [] and rep.message() == ""
    s = np.linspace(0.0, 1.0, 601)
    dense = kdop.clearance(q0 + s[:, None] * (q1 - q0)).min(axis=0)
    # the proof holds: the true least clearance of every pair is above the margin; the
    # reported one is a sampled clearance, so it is never below the truth
    assert dense.min() > MARGIN_M
    assert np.all(rep.min_clearance_m >= dense - GJK_M)


def test_event_is_the_first_moment_under_the_margin(kdop: CollisionModel) -> None:
    q5 = (-0.899, -0.256, 0.639)
    t = np.arange(3.0)
    rep = _check(kdop, t, [_graze_pose(v) for v in q5])
    s = np.linspace(0.0, 2.0, 8001)
    dense = kdop.clearance([_graze_pose(v) for v in np.interp(s, t, q5)])
    first = s[dense[:, kdop.pair_names.index(PEN_BENCH)] < MARGIN_M].min()  # 1.265 s
    assert [e["pair"] for e in rep.events] == [PEN_BENCH]
    assert rep.events[0]["time_s"] == pytest.approx(first, abs=0.005)  # reported: 1.5 s


def test_near_miss_within_the_margin_is_refused(kdop: CollisionModel) -> None:
    # the tip 1.5 mm over the bench, beside the panel
    q = _pose_with_tip(kdop, (0.21, -0.1, 0.0015))
    pose = kdop.pose_report(q)
    assert pose.clearance_m[PEN_BENCH] == pytest.approx(0.0015, abs=GJK_M)
    assert pose.worst_pair == ["tattoo_pen_link", "bench"] and pose.collisions == []
    assert pose.needle_depth_m == -np.inf  # not over the panel

    rep = _check(kdop, [4.0], [q], margin_m=2e-3)
    assert not rep.ok and rep.collisions == 0
    assert [e["pair"] for e in rep.events] == [PEN_BENCH]
    assert rep.events[0]["time_s"] == 4.0
    assert rep.events[0]["clearance_mm"] == pytest.approx(1.5, abs=1e-3)
    assert re.match(r"tattoo_pen_link and bench comes? within the margin at t = 4\.000 s "
                    r"\(least clearance 1\.50 mm, margin 2 mm\)", rep.message())
    assert "within the margin" in str(CollisionRefused(rep))
    assert pose.to_json(2e-3, kdop.geometry)["within_margin"] == [["tattoo_pen_link", "bench"]]
    # the same pose passes the configured 1 mm
    assert _check(kdop, [4.0], [q], margin_m=MARGIN_M).ok


def test_needle_deeper_than_the_plunge_is_refused(kdop: CollisionModel,
                                                   desc: RobotDescription) -> None:
    top = float(desc.panel_centre[2] + desc.panel_size[2] / 2)
    q = _pose_with_tip(kdop, (float(desc.panel_centre[0]), float(desc.panel_centre[1]),
                              top - 0.003))
    pose = kdop.pose_report(q)
    assert pose.needle_depth_m == pytest.approx(0.003, abs=1e-7)
    # the needle may be in the panel (its shape pair is not checked); the barrel may not
    assert pose.collisions == []
    barrel = float(desc.pen_barrel_length)
    pen_len = float(desc.geometry["tattoo_pen_link"][0].size[1])
    assert pose.clearance_m["tattoo_pen_link|panel"] == pytest.approx(
        pen_len - barrel - 0.003, abs=GJK_M)

    rep = _check(kdop, [0.0, 1.0], [q, q], plunge_m=PLUNGE_M)
    assert rep.events == [] and not rep.ok
    assert rep.needle_depth_max_m == pytest.approx(0.003, abs=1e-7)
    assert rep.message() == ("the needle goes 3.000 mm into the panel, deeper than the "
                             "plunge (1.5 mm)")
    assert rep.metrics()["needle_depth_max_mm"] == pytest.approx(3.0, abs=1e-4)
    assert _check(kdop, [0.0, 1.0], [q, q], plunge_m=0.003).ok


def test_check_of_colliding_samples(kdop: CollisionModel) -> None:
    rep = _check(kdop, [0.0, 0.5, 1.0], [HOME, HOME, INTO_BENCH])
    assert not rep.ok
    assert {e["pair"] for e in rep.events} >= {"wrist_link|bench", PEN_BENCH}
    bench = next(e for e in rep.events if e["pair"] == "wrist_link|bench")
    assert 0.5 < bench["time_s"] <= 1.0  # found on the way down, at or before the last sample
    assert rep.series_m.shape == (3, 27)
    assert rep.metrics()["pairs_checked"] == 27
    assert rep.metrics()["collisions"] == rep.collisions >= 4


def test_check_trajectory_refuses_bad_arguments(kdop: CollisionModel) -> None:
    q = np.zeros((2, 5))
    for t, qq in (([0.0], q), ([0.0, 1.0], np.zeros(5)), ([], np.zeros((0, 5)))):
        with pytest.raises(TattotronixError, match="need"):
            _check(kdop, t, qq)
    with pytest.raises(TattotronixError, match="margin"):
        _check(kdop, [0.0, 1.0], q, margin_m=-1e-3)
    with pytest.raises(TattotronixError, match="resolution"):
        check_trajectory(kdop, np.array([0.0, 1.0]), q, margin_m=MARGIN_M,
                         plunge_m=PLUNGE_M, resolution_m=0.0)
    with pytest.raises(TattotronixError, match="finite"):
        _check(kdop, [0.0, 1.0], [HOME, (0.0, np.nan, 0.0, 0.0, 0.0)])


# ----------------------------------------------------------------------------- deploy gate


def _verdict(folder: Path, **metrics: Any) -> tuple[Path, Path]:
    traj = folder / "emblem.npz"
    traj.write_bytes(b"a trajectory file")
    out = folder / "emblem.json"
    out.write_text(json.dumps({"trajectory_sha256": file_sha256(traj), "collisions": 0,
                               "below_margin": 0, "min_clearance_mm": 3.46, **metrics}))
    return out, traj


def test_require_checked(tmp_path: Path) -> None:
    metrics, traj = _verdict(tmp_path)
    assert require_checked(metrics, traj) == json.loads(metrics.read_text())

    with pytest.raises(TattotronixError, match="has no collision check .* run the "
                                               "'collision' stage first"):
        require_checked(tmp_path / "absent.json", traj)

    traj.write_bytes(b"a trajectory file, planned again")
    with pytest.raises(TattotronixError, match="checked another version"):
        require_checked(metrics, traj)

    for bad in ({"collisions": 2}, {"below_margin": 1}):
        metrics, traj = _verdict(tmp_path, **bad)
        with pytest.raises(TattotronixError, match="is not collision-free"):
            require_checked(metrics, traj)


# ----------------------------------------------------------------------------- the stage CLI


def _pose_cli(*overrides: str) -> subprocess.Popen[str]:
    return subprocess.Popen([PYTHON, "stages/collision.py", *overrides], cwd=ROOT,
                            env=stage_env(), text=True, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE)


def _finish(proc: subprocess.Popen[str]) -> subprocess.CompletedProcess[str]:
    out, err = proc.communicate(timeout=120)
    return subprocess.CompletedProcess(proc.args, proc.returncode, out, err)


@pytest.fixture(scope="module")
def cli_runs() -> dict[str, subprocess.CompletedProcess[str]]:
    """``collision.py pose=...`` on a clear, a colliding and a bad pose, side by side."""
    procs = {"home": _pose_cli("pose=[0,0,0,0,0]"), "bench": _pose_cli("pose=[0,1.57,0,0,0]"),
             "bad": _pose_cli("pose=[0,1]")}
    return {key: _finish(proc) for key, proc in procs.items()}


def _one_json_object(run: subprocess.CompletedProcess[str]) -> dict[str, Any]:
    assert run.returncode == 0, run.stderr
    assert run.stdout.endswith("}\n") and run.stdout.count("\n") == 1  # one line, nothing else
    doc = json.loads(run.stdout)
    assert isinstance(doc, dict)
    return doc


def test_cli_pose_prints_one_json_object(cli_runs: dict[str, subprocess.CompletedProcess[str]]
                                         ) -> None:
    home = _one_json_object(cli_runs["home"])
    assert home["collisions"] == []
    assert home["min_clearance_mm"] == pytest.approx(1.997, abs=0.01)
    assert home["worst_pair"] == ["upper_arm_link", "wrist_link"]
    assert home["geometry"] == "k-DOP" and home["margin_mm"] == 1.0
    assert home["pose"] == [0.0] * 5 and home["within_limits"] is True
    assert len(home["clearance_mm"]) == 27
    assert min(home["clearance_mm"].values()) == home["min_clearance_mm"]


def test_cli_pose_names_the_colliding_pairs(
        cli_runs: dict[str, subprocess.CompletedProcess[str]]) -> None:
    bench = _one_json_object(cli_runs["bench"])
    assert ["wrist_link", "bench"] in bench["collisions"]
    assert bench["worst_pair"] == ["tattoo_pen_link", "bench"]
    assert bench["min_clearance_mm"] < -100
    assert all(bench["clearance_mm"]["|".join(p)] <= 0 for p in bench["collisions"])


def test_cli_bad_pose_is_a_one_line_error(cli_runs: dict[str, subprocess.CompletedProcess[str]]
                                          ) -> None:
    bad = cli_runs["bad"]
    assert bad.returncode == 2
    assert bad.stdout == ""
    lines = bad.stderr.strip().splitlines()
    assert len(lines) == 1, bad.stderr
    assert lines[0].startswith("collision: error: pose=[0.0, 1.0]: give 5 finite joint angles")
    assert "joint_1, joint_2, joint_3, joint_4, joint_5" in lines[0]


@pytest.mark.cad
def test_cli_pose_on_the_meshes(cad_dir: Path) -> None:
    home = _one_json_object(_finish(_pose_cli("pose=[0,0,0,0,0]", f"robot.cad_dir={cad_dir}")))
    assert home["geometry"] == "mesh hulls"
    assert home["collisions"] == []
    assert home["min_clearance_mm"] == pytest.approx(3.46, abs=0.05)
    assert home["worst_pair"] == ["upper_arm_link", "wrist_link"]


# ----------------------------------------------------------------------------- a whole drawing


@pytest.mark.slow
@pytest.mark.cad
def test_small_drawing_is_proven_clear_on_the_meshes(tmp_path: Path, cad_dir: Path) -> None:
    from tattotronix.app.pipeline import plan_drawing

    art = small_art(tmp_path / "small.png")
    cfg = compose_settings([f"artwork.source={art}", "mask.width_mm=24", "mask.min_region_mm2=0.5",
                   f"robot.cad_dir={cad_dir}"])
    desc = build_description(cfg.robot)
    traj = plan_drawing(cfg, art, "small", desc)
    model = CollisionModel(desc)
    margin = cfg.collision.margin_m
    plunge = cfg.toolpath.plunge_m
    rep = check_trajectory(model, traj.t, traj.q, margin_m=margin, plunge_m=plunge,
                           resolution_m=cfg.collision.resolution_m)
    assert rep.ok, rep.message()
    assert rep.events == [] and rep.collisions == 0
    assert rep.min_clearance_m.min() > margin
    m = rep.metrics()
    assert model.geometry == "mesh hulls"
    assert m["worst_pair"] == ["upper_arm_link", "wrist_link"]
    assert m["min_clearance_mm"] == pytest.approx(3.457, abs=0.01)  # at home, where it starts
    assert m["poses_checked"] >= len(traj.t) > 1000
    assert m["pairs_checked"] == 27
    # the needle marks: it reaches the plunge depth, no deeper
    assert plunge - 1e-5 <= rep.needle_depth_max_m <= plunge + 1e-5


@pytest.mark.slow
@pytest.mark.cad
def test_the_built_in_drawing_is_clear_with_the_meshes(cad_dir: Path) -> None:
    """The emblem, planned in memory with the CAD meshes (planned travel from home and
    back), is collision-free with the margin: every sample and the motion between them.
    Its least clearance is reported, and the proven lower bound lies under it."""
    from tattotronix.app.pipeline import plan_drawing

    cfg = compose_settings([f"robot.cad_dir={cad_dir}"])
    desc = build_description(cfg.robot)
    traj = plan_drawing(cfg, "emblem", "emblem", desc)
    assert [m.kind for m in traj.moves][:1] == ["from_home"]
    model = CollisionModel(desc)
    assert model.geometry == "mesh hulls"
    rep = check_trajectory(model, traj.t, traj.q, margin_m=cfg.collision.margin_m,
                           plunge_m=cfg.toolpath.plunge_m,
                           resolution_m=cfg.collision.resolution_m)
    assert rep.ok, rep.message()
    m = rep.metrics()
    assert m["collisions"] == 0 and m["below_margin"] == 0
    assert m["min_clearance_mm"] > float(cfg.collision.margin_mm)
    assert m["worst_pair"] == ["upper_arm_link", "wrist_link"]
    assert np.all(rep.lower_bound_m <= rep.min_clearance_m + 1e-12)
    assert m["min_clearance_bound_mm"] >= float(cfg.collision.margin_mm)
    assert m["needle_depth_max_mm"] == pytest.approx(float(cfg.toolpath.plunge_mm), abs=0.01)
