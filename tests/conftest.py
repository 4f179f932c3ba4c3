"""Shared fixtures: the composed config, generated models, and the CAD directory."""

from __future__ import annotations

import os
import sys
from pathlib import Path

import pytest

from tattotronix.config.params import compose
from tattotronix.robot.description import RobotDescription, build_description
from tattotronix.robot.mjcf import to_mjcf
from tattotronix.robot.urdf import to_urdf

ROOT = Path(__file__).resolve().parents[1]
PYTHON = sys.executable


@pytest.fixture(scope="session")
def cad_dir() -> Path:
    """The CAD meshes; tests that need them skip only when TATTOTRONIX_CAD_DIR is unset."""
    value = os.environ.get("TATTOTRONIX_CAD_DIR")
    if not value:
        pytest.skip("TATTOTRONIX_CAD_DIR is unset (CI sets it to ../shared/cad/meshes)")
    path = Path(value).resolve()
    assert path.is_dir(), f"TATTOTRONIX_CAD_DIR={value} is not a directory"
    return path


def write_models(desc: RobotDescription, folder: Path) -> tuple[Path, Path]:
    """Write the URDF and MJCF of ``desc`` into ``folder``."""
    urdf, mjcf = folder / "robot.urdf", folder / "robot.xml"
    urdf.write_text(to_urdf(desc))
    mjcf.write_text(to_mjcf(desc))
    return urdf, mjcf


@pytest.fixture(scope="session")
def desc() -> RobotDescription:
    """The default description (printed masses, tattoo pen, primitive geometry)."""
    return build_description(compose().robot)


@pytest.fixture(scope="session")
def models(desc: RobotDescription, tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """URDF and MJCF files of the default description."""
    return write_models(desc, tmp_path_factory.mktemp("models"))
