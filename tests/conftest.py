"""Shared fixtures: the composed config, generated models, and the CAD directory."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from tattotronix.config.params import compose_settings
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
    return build_description(compose_settings().robot)


def small_art(path: Path) -> Path:
    """A 240 x 120 px drawing: a ring, a filled square and a dot (24 mm wide at
    ``mask.width_mm=24``)."""
    from PIL import Image, ImageDraw

    im = Image.new("L", (240, 120), 255)
    d = ImageDraw.Draw(im)
    d.ellipse((10, 10, 110, 110), outline=0, width=12)
    d.rectangle((140, 30, 200, 90), fill=0)
    d.ellipse((215, 55, 227, 67), fill=0)
    im.save(path)
    return path


@pytest.fixture()
def draw_data(tmp_path: Path, desc: RobotDescription) -> Path:
    """A data folder holding the generated models (what the robot stage writes), with
    the small artwork beside it (``small.png``)."""
    robot = tmp_path / "data" / "robot"
    robot.mkdir(parents=True)
    (robot / f"{desc.name}.urdf").write_text(to_urdf(desc))
    (robot / f"{desc.name}.xml").write_text(to_mjcf(desc))
    small_art(tmp_path / "small.png")
    return tmp_path / "data"


@pytest.fixture(scope="session")
def models_data(desc: RobotDescription, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A data folder holding only the generated models (what the robot stage writes), so
    a drawing is planned in memory (a clean clone has no DVC data). Shared by the tests
    that read it; none writes into it."""
    data = tmp_path_factory.mktemp("models_data") / "data"
    (data / "robot").mkdir(parents=True)
    (data / "robot" / f"{desc.name}.urdf").write_text(to_urdf(desc))
    (data / "robot" / f"{desc.name}.xml").write_text(to_mjcf(desc))
    return data


@pytest.fixture(scope="session")
def models(desc: RobotDescription, tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """URDF and MJCF files of the default description."""
    return write_models(desc, tmp_path_factory.mktemp("models"))


def stage_env() -> dict[str, str]:
    """The environment of a stage run by hand (not by DVC), with one-line errors."""
    env = dict(os.environ)
    env.pop("DVC_STAGE", None)
    env["HYDRA_FULL_ERROR"] = "0"
    return env


def run_side_by_side(stage: str, folders: dict[str, Path], *overrides: str
                     ) -> dict[str, tuple[subprocess.CompletedProcess[str], Path]]:
    """``python stages/<stage>.py paths.data=<folder> [overrides]`` for every folder, run
    at the same time; key -> (the finished run, its data folder)."""
    procs = {key: subprocess.Popen(
        [PYTHON, f"stages/{stage}.py", f"paths.data={d}", *overrides], cwd=ROOT,
        env=stage_env(), text=True, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
        for key, d in folders.items()}
    out = {}
    for key, proc in procs.items():
        stdout, stderr = proc.communicate(timeout=300)
        out[key] = (subprocess.CompletedProcess(proc.args, proc.returncode, stdout, stderr),
                    folders[key])
    return out


def default_signals() -> None:
    """``preexec_fn`` of a child whose test stops it with a signal: SIGINT, SIGTERM and
    SIGHUP at their defaults in the child, whatever this run inherited (a background job
    or ``nohup`` starts pytest with SIGINT or SIGHUP ignored, and a child inherits an
    ignored signal across exec)."""
    import signal

    for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
        signal.signal(sig, signal.SIG_DFL)


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """The slow tests first, and the longest (it runs the whole pipeline) first of all:
    ``--dist load`` (pyproject.toml) deals the first tests to the workers in turn, so the
    long one starts at once and the short ones fill in beside it, instead of it starting
    last alone."""
    def rank(item: pytest.Item) -> int:
        if item.name in LONGEST:
            return 0
        return 1 if item.get_closest_marker("slow") is not None else 2
    items.sort(key=rank)  # stable: the order within each rank is the collection's


#: the tests that run the whole pipeline (minutes each)
LONGEST = ("test_dvc_repro_on_a_clean_clone",
           "test_the_readme_experiments_rerun_only_what_they_change")


def small_pipeline(clone: Path, keep: tuple[str, ...], env: dict[str, str],
                   artworks: tuple[str, ...] | None = None) -> None:
    """The clone's pipeline cut to the stages ``keep`` (and, given ``artworks``, its
    drawings to those), their code stamps re-declared, with no lock yet: the project's
    own commands and stages, at a size that reruns in seconds or a minute.

    A test of DVC's workflow on it (the lock, experiments) runs the real stages; the
    whole pipeline's reproduction is tests/test_config.py::test_dvc_repro_on_a_clean_clone.
    """
    import yaml

    doc = yaml.safe_load((clone / "dvc.yaml").read_text())
    doc["stages"] = {k: v for k, v in doc["stages"].items() if k in keep}
    doc.pop("plots", None)
    if artworks is not None:
        for var in doc["vars"]:
            if isinstance(var, dict) and "artworks" in var:
                var["artworks"] = {k: v for k, v in var["artworks"].items() if k in artworks}
    (clone / "dvc.yaml").write_text(yaml.safe_dump(doc, sort_keys=False))
    (clone / "dvc.lock").unlink()
    wrote = subprocess.run([PYTHON, "-m", "tattotronix.devtools.codedeps", "--write"],
                           cwd=clone, env=env, capture_output=True, text=True)
    assert wrote.returncode == 0, wrote.stderr
