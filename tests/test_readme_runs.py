"""README commands that no other test ran, run here at a test's size (README, "Calibrating
the servos", "CAD meshes", "Development"; the list is tests/test_readme_commands.py).

Each writes only into a scratch folder: a ``paths.data`` of its own, or a copy of the
project.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from .conftest import ROOT, stage_env

PYTHON = sys.executable


def test_servo_pulse_holds_the_widths_typed_and_ends_off() -> None:
    """``python stages/servo_pulse.py channel=0 width_us=1500``, as a dry run: it holds the
    width, takes the widths typed after it, and an empty line switches the channel off."""
    r = subprocess.run([PYTHON, "stages/servo_pulse.py", "channel=0", "width_us=1500",
                        "dry_run=true"], cwd=ROOT, env=stage_env(), input="1600\n\n",
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    writes = [json.loads(line) for line in r.stdout.splitlines() if line.startswith("{")]
    assert writes and all(w["addr"] == 0x40 for w in writes)
    channel_0 = [w["data"] for w in writes if w["reg"] == 0x06]  # LED0_ON_L and on
    held = [d for d in channel_0 if d[3] & 0x10 == 0]
    assert len(held) == 2 and held[0] != held[1], channel_0  # 1500, then 1600 us
    assert channel_0[-1][3] & 0x10  # the channel switched fully off
    assert writes[-1]["reg"] == 0xFA and writes[-1]["data"][3] & 0x10  # then all off


def test_servo_pulse_records_the_angles_read_and_says_how_well_they_fit(
        tmp_path: Path) -> None:
    """``... joint=joint_1 record=FILE``: each width typed with the angle read at the one
    held adds a pair to FILE, and from the second on the command says how far the fit
    passes from them."""
    import yaml

    file = tmp_path / "calibration.yaml"
    r = subprocess.run([PYTHON, "stages/servo_pulse.py", "channel=0", "width_us=1500",
                        "dry_run=true", "joint=joint_1", f"record={file}"], cwd=ROOT,
                       env=stage_env(), input="1600 0.2\n1700 9.3\n1800 18.1\n\n",
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    points = yaml.safe_load(file.read_text())["joints"]["joint_1"]["points"]
    # each width as sent, the nearest count (4.88 us at 50 Hz), with the angle read there
    assert [a for _, a in points] == [0.2, 9.3, 18.1]
    assert all(abs(w - want) < 4.9 for (w, _), want in zip(points, (1500, 1600, 1700),
                                                             strict=True))
    said = [line for line in r.stdout.splitlines() if line.startswith("joint_1:")]
    assert said == [
        "joint_1: 2 widths measured; the order-1 fit passes within 0.00 deg of their angles",
        "joint_1: 3 widths measured; the order-2 fit passes within 0.00 deg of their angles"]


@pytest.mark.cad
def test_the_cad_commands_run_on_the_meshes(cad_dir: Path, tmp_path: Path) -> None:
    """``python stages/robot.py robot.cad_dir=DIR`` and ``python stages/mass.py
    robot.cad_dir=DIR``, in a scratch data folder."""
    for stage in ("robot", "mass"):
        r = subprocess.run([PYTHON, f"stages/{stage}.py", f"paths.data={tmp_path}",
                            f"robot.cad_dir={cad_dir}"], cwd=ROOT, env=stage_env(),
                           capture_output=True, text=True, timeout=300)
        assert r.returncode == 0, r.stderr
    robot = json.loads((tmp_path / "metrics" / "robot.json").read_text())
    assert robot["geometry"] == "mesh"
    mass = json.loads((tmp_path / "metrics" / "mass.json").read_text())
    assert mass["source"] == "meshes" and mass["committed_table"]["up_to_date"] is True


def test_codedeps_write_restores_a_dropped_code_dep(tmp_path: Path) -> None:
    """``python -m tattotronix.devtools.codedeps --write`` in a copy of the project whose
    dvc.yaml lost one stage's code stamp: it puts it back, and dvc.yaml is the checkout's again."""
    listed = subprocess.run(["git", "ls-files", "-z", "--cached", "--others",
                             "--exclude-standard"], cwd=ROOT, capture_output=True, check=True)
    copy = tmp_path / "project"
    for name in listed.stdout.decode().split("\0"):
        src = ROOT / name
        if name and src.is_file() and not name.startswith("data/"):
            (copy / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src, copy / name)
    dvc_yaml = (ROOT / "dvc.yaml").read_text(encoding="utf-8")
    lines = dvc_yaml.splitlines(keepends=True)
    drop = next(i for i, line in enumerate(lines)
                if re.fullmatch(r"\s+- \$\{paths\.data\}/code/\w+\.txt\n", line)
                and "cache" not in lines[i + 1])  # a stage's stamp dep, not an out
    (copy / "dvc.yaml").write_text("".join(lines[:drop] + lines[drop + 1:]), encoding="utf-8")
    env = {**os.environ, "PYTHONPATH": str(copy)}  # the copy's own code
    r = subprocess.run([PYTHON, "-m", "tattotronix.devtools.codedeps", "--write"], cwd=copy,
                       env=env, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert "1 stage(s) rewritten in dvc.yaml" in r.stdout, r.stdout
    assert (copy / "dvc.yaml").read_text(encoding="utf-8") == dvc_yaml
