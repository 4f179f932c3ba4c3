"""README numbers equal the metrics files they come from."""

from __future__ import annotations

import json
import re

import pytest

from .conftest import ROOT

README = (ROOT / "README.md").read_text()


def _row(label: str) -> list[float]:
    m = re.search(rf"^\| {re.escape(label)} \| (.+?) \|$", README, re.M)
    assert m, f"README has no row {label!r}"
    return [float(v) for v in re.findall(r"-?\d+(?:\.\d+)?(?:e-?\d+)?", m.group(1))]


@pytest.fixture(scope="module")
def robot() -> dict:
    return json.loads((ROOT / "data" / "metrics" / "robot.json").read_text())


def test_readme_zero_pose_figures_equal_the_robot_metrics(robot: dict) -> None:
    assert _row("`tattoo_tcp`") == robot["tcp_zero_mm"]
    assert _row("`tool0`") == robot["tool0_zero_mm"]
    assert _row("wrist axis height") == [robot["wrist_axis_mm"]]
    assert _row("gravity torques") == robot["gravity_zero_nm"]
    assert _row("arm mass / moving mass (with the pen)") == [
        robot["arm_mass_kg"], robot["moving_mass_kg"]]


def test_readme_opens_with_the_two_fresh_machine_commands() -> None:
    blocks = re.findall(r"```bash\n(.+?)\n```", README, re.S)
    assert "pip install -c constraints.txt -e" in blocks[0] and "dvc repro" in blocks[0]
    assert "pytest" in blocks[1]
    assert "python -m pytest" in (ROOT / ".ci" / "run").read_text()


def test_readme_toolpath_table_equals_the_toolpath_metrics() -> None:
    m = json.loads((ROOT / "data" / "metrics" / "toolpath" / "emblem.json").read_text())
    for label, d in (("ours", m), ("the original's rule", m["original_order"])):
        want = [d["points"], round(d["marked_mm"]), round(d["travel_mm"]), d["entries"],
                round(d["time_s"])]
        assert _row(label) == want, label


def test_readme_ik_table_equals_the_ik_metrics() -> None:
    m = json.loads((ROOT / "data" / "metrics" / "ik" / "emblem.json").read_text())
    assert _row("points") == [m["points"]]
    assert _row("converged") == [m["converged_pct"]]
    assert _row("condition number along the path") == [round(v, 1) for v in m["cond"]]


def test_readme_trajectory_table_equals_the_trajectory_metrics() -> None:
    m = json.loads((ROOT / "data" / "metrics" / "trajectory" / "emblem.json").read_text())
    assert _row("duration") == [round(m["duration_s"], 1)]
    assert _row("marking-only time (marked length / feed)") == [round(m["marking_only_s"], 1)]
    assert _row("cycle over marking") == [round(m["cycle_over_marking"], 3)]
    assert _row("fastest speed") == [round(m["fastest_speed"], 2)]
    k = json.loads((ROOT / "data" / "metrics" / "kinematics" / "emblem.json").read_text())
    assert f"{k['reachability']['reachable_pct']:.3f} %" in README


def test_readme_simulation_table_equals_the_run_metrics() -> None:
    m = json.loads((ROOT / "data" / "metrics" / "runs" / "emblem-mujoco.json").read_text())
    assert _row("settled mean / max") == [round(m["settled_mean_um"], 2),
                                          round(m["settled_max_um"], 1)]
    assert _row("marking max") == [round(m["marking_max_um"], 1)]
    assert _row("travel mean") == [round(m["travel_mean_um"], 1)]
    assert _row("peak torque") == [round(m["peak_torque_nm"], 3)]
    assert _row("ink IoU against the plan") == [round(m["ink_iou"], 3)]


def test_readme_servo_program_table_equals_the_deploy_metrics() -> None:
    m = json.loads((ROOT / "data" / "metrics" / "deploy" / "emblem.json").read_text())
    assert _row("frames") == [m["frames"]]
    assert _row("worst quantisation of a joint") == [
        round(max(m["quantisation_deg"].values()), 3)]
    assert _row("tip error from quantisation, worst / mean") == [
        round(m["quantisation_tip_mm_max"], 2), round(m["quantisation_tip_mm_mean"], 2)]
