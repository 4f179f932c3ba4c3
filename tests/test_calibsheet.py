"""The calibration sheet and identification from its photo (issue 34, item 4;
tattotronix/hardware/calibsheet.py, tattotronix/app/identify.py, stages/calibrate.py):
the sheet's markers and pattern, a synthetic photo read back onto the panel, photos that
are refused, the servo-figures file, and the identification round trip."""

from __future__ import annotations

import math
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np
import pytest

from tattotronix.config.params import compose_settings
from tattotronix.control.ink import compare_ink
from tattotronix.errors import TattotronixError
from tattotronix.hardware.calibsheet import (
    MARKERS,
    pattern_strokes,
    read_photo,
    sheet_grid,
    sheet_image,
    synthetic_photo,
)
from tattotronix.hardware.servo_model import joint_servos, load_servo_figures
from tattotronix.hardware.servos import default_calibration
from tattotronix.path.fidelity import rasterise_runs
from tattotronix.robot.description import RobotDescription

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def drawn() -> np.ndarray:
    """The pattern's ink at the needle's width on the sheet's grid."""
    return rasterise_runs(pattern_strokes(), sheet_grid(), 0.3)


def test_the_pattern_lies_on_the_panel_between_the_markers() -> None:
    cfg = compose_settings()
    half_w, half_h = (s / 2 for s in cfg.robot.panel.size_mm)
    pts = np.concatenate(pattern_strokes())
    inner = min(abs(m.u_mm) - m.side_mm for m in MARKERS), min(abs(m.v_mm) - m.side_mm
                                                              for m in MARKERS)
    assert np.all(np.abs(pts[:, 0]) < inner[0]) and np.all(np.abs(pts[:, 1]) < inner[1])
    for m in MARKERS:
        assert abs(m.u_mm) + m.side_mm / 2 < half_w and abs(m.v_mm) + m.side_mm / 2 < half_h


def test_the_printed_sheets_markers_are_found_where_they_are() -> None:
    """The sheet as printed, photographed square on: every marker found, its corners
    where the sheet puts them (to a tenth of a pixel)."""
    img = sheet_image()
    det = cv2.aruco.ArucoDetector(cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_4X4_50),
                                  cv2.aruco.DetectorParameters())
    corners, ids, _ = det.detectMarkers(img)
    assert sorted(ids.ravel().tolist()) == [m.id for m in MARKERS]
    from tattotronix.hardware.calibsheet import _marker_px

    for c, i in zip(corners, ids.ravel(), strict=True):
        want = _marker_px(next(m for m in MARKERS if m.id == i), sheet_grid())
        np.testing.assert_allclose(c.reshape(4, 2), want, atol=0.6)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_photo_is_read_back_onto_the_panel(drawn: np.ndarray, seed: int) -> None:
    """In perspective, blurred, unevenly lit, noisy: the ink read back lies within 1.5
    pixels (0.15 mm) of the drawn ink, and overlaps it by 85 % or more."""
    grid = sheet_grid()
    photo = synthetic_photo(drawn, grid, np.random.default_rng(seed))
    got = read_photo(photo, grid)
    ink = compare_ink(got, drawn, grid.res_mm)
    assert ink.max_dev_mm is not None and ink.max_dev_mm <= 0.15 + 1e-9
    assert ink.iou is not None and ink.iou >= 0.85


def test_a_photo_missing_a_marker_is_refused_naming_it(drawn: np.ndarray) -> None:
    grid = sheet_grid()
    photo = synthetic_photo(drawn, grid, np.random.default_rng(4), tilt=0.0)
    h, w = photo.shape
    photo[: h // 3, w * 2 // 3:] = 200  # the top-right corner, marker 1, covered
    with pytest.raises(TattotronixError) as err:
        read_photo(photo, grid, "photo=p.jpg")
    text = str(err.value)
    assert "\n" not in text and "markers 1 are not found" in text and "found: 0, 2, 3" in text


def test_an_unreadable_photo_is_one_line(tmp_path: Path) -> None:
    bad = tmp_path / "photo.jpg"
    bad.write_bytes(b"not a jpeg")
    with pytest.raises(TattotronixError, match="not a readable image"):
        read_photo(bad)
    with pytest.raises(TattotronixError, match="not a readable image"):
        read_photo(tmp_path / "missing.png")
    with pytest.raises(TattotronixError, match="markers 0, 1, 2, 3 are not found"):
        read_photo(np.full((300, 400), 255, np.uint8))


def test_identified_figures_replace_the_catalogues(tmp_path: Path,
                                                  desc: RobotDescription) -> None:
    cfg = compose_settings()
    f = tmp_path / "figures.yaml"
    f.write_text("joints:\n  joint_1: {backlash_deg: 1.5, deadband_deg: 0.2, note: 3}\n"
                 "residual_mm: 0.1\n")
    figures = load_servo_figures(f, desc.joint_names)
    assert figures == {"joint_1": {"backlash_deg": 1.5, "deadband_deg": 0.2}}
    calib = default_calibration()
    cat = joint_servos(cfg.robot, desc.joint_names, calib, cfg.servo)
    own = joint_servos(cfg.robot, desc.joint_names, calib, cfg.servo, figures)
    assert own[0].backlash_rad == pytest.approx(math.radians(1.5))
    assert own[0].deadband_rad == pytest.approx(math.radians(0.2))
    assert own[1:] == cat[1:] and replace(own[0], backlash_rad=cat[0].backlash_rad,
                                          deadband_rad=cat[0].deadband_rad) == cat[0]
    # the plant's switch still rules: backlash off is off
    off = compose_settings(["servo.backlash=false"]).servo
    assert joint_servos(cfg.robot, desc.joint_names, calib, off, figures)[0].backlash_rad == 0


@pytest.mark.parametrize("text, says", [
    ("joints:\n  joint_9: {backlash_deg: 1}\n", "joints.joint_9: not a joint"),
    ("joints:\n  joint_1: {backlash_deg: -1}\n", "joints.joint_1.backlash_deg"),
    ("joints:\n  joint_1: {deadband_deg: .nan}\n", "joints.joint_1.deadband_deg"),
    ("joints: [1, 2]\n", "no 'joints' mapping"),
    ("{{{", "cannot read it"),
])
def test_a_bad_figures_file_is_refused_naming_the_key(tmp_path: Path, desc: RobotDescription,
                                                      text: str, says: str) -> None:
    f = tmp_path / "figures.yaml"
    f.write_text(text)
    with pytest.raises(TattotronixError, match="servo_figures_file") as err:
        load_servo_figures(f, desc.joint_names)
    assert says in str(err.value)


def test_the_stage_writes_the_sheet_and_refuses_a_bad_photo(tmp_path: Path) -> None:
    script = str(ROOT / "stages" / "calibrate.py")
    sheet = tmp_path / "sheet.png"
    ok = subprocess.run([sys.executable, script, f"sheet={sheet}"], capture_output=True,
                        text=True, cwd=tmp_path, timeout=300)
    assert ok.returncode == 0, ok.stderr
    assert cv2.imread(str(sheet), cv2.IMREAD_GRAYSCALE).shape == sheet_grid().shape
    blank = tmp_path / "blank.png"
    cv2.imwrite(str(blank), np.full((300, 400), 255, np.uint8))
    bad = subprocess.run([sys.executable, script, f"photo={blank}", "out=f.yaml"],
                         capture_output=True, text=True, cwd=tmp_path, timeout=600)
    assert bad.returncode == 2
    assert bad.stderr.strip().splitlines()[-1].startswith("calibrate: error: photo=")
    assert not (tmp_path / "f.yaml").exists()


@pytest.mark.slow
def test_identification_recovers_the_backlash_from_a_synthetic_photo(
        tmp_path: Path, models_data: Path) -> None:
    """A hidden arm whose backlash differs from the catalogue by -30 to +40 % draws part of
    the pattern (the ladder and the circles) on the servo plant; from a synthetic photo
    of its ink, each moving joint's backlash is recovered within 15 %."""
    from tattotronix.app.identify import SheetModel, calibration_plan, identify

    strokes = pattern_strokes()
    plan = calibration_plan(workdir=tmp_path, strokes=[strokes[4], strokes[5], strokes[6]])
    model = SheetModel.of_plan(plan)
    cat = model.catalogue()
    truth = list(cat)
    for j, f in zip(model.moving_joints(), (1.4, 0.7, 1.3, 0.8), strict=False):
        truth[j] = replace(cat[j], backlash_rad=cat[j].backlash_rad * f)
    photo = synthetic_photo(model.ink(tuple(truth)), model.grid, np.random.default_rng(7))
    found = identify(read_photo(photo, model.grid), model)
    assert found.residual_mm < found.residual_before_mm
    for name, factor in found.factors["backlash_rad"].items():
        j = plan.desc.joint_names.index(name)
        want = truth[j].backlash_rad / cat[j].backlash_rad
        assert factor == pytest.approx(want, rel=0.15), name
