"""The factory that builds a plant backend from the generated models."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from numpy.typing import ArrayLike

from tattotronix.errors import TattotronixError
from tattotronix.plants.base import Plant, PlantSettings

__all__ = ["BACKENDS", "make_plant"]

#: the simulated backends (``draw.py backend=...``)
BACKENDS = ("mujoco", "pybullet", "model")


def make_plant(backend: str, settings: PlantSettings, *, urdf: Path, mjcf: Path,
               joint_names: Sequence[str], lower: ArrayLike, upper: ArrayLike,
               viewer: bool = False) -> Plant:
    """Build a plant from the generated models.

    Args:
        backend: ``model``, ``mujoco`` or ``pybullet``.
        settings: the plant settings.
        urdf, mjcf: the generated models (``data/robot/<name>.urdf`` / ``.xml``).
        joint_names: the joints, base outward (checked against each model).
        lower, upper: joint limits, rad (the model plant's clamp).
        viewer: open the engine's viewer (needs a display; MuJoCo and PyBullet).

    Raises:
        TattotronixError: an unknown backend, or a setting the backend cannot honour.
    """
    name = str(getattr(backend, "name", backend))
    if name not in BACKENDS:
        raise TattotronixError(f"unknown backend '{name}': use one of {', '.join(BACKENDS)} "
                               "(the real arm is backend=arm)")
    plant: Plant
    if name == "model":
        from tattotronix.plants.model import ModelPlant

        plant = ModelPlant(urdf, settings, lower=lower, upper=upper)
    elif name == "mujoco":
        from tattotronix.plants.mujoco_plant import MujocoPlant

        plant = MujocoPlant(mjcf, settings, viewer=viewer)
    else:
        from tattotronix.plants.pybullet_plant import PybulletPlant

        plant = PybulletPlant(urdf, settings, viewer=viewer)
    got = tuple(getattr(plant, "joint_names", ()))
    if got != tuple(joint_names):
        plant.close()
        raise TattotronixError(f"the {name} model has joints {got}, the description "
                               f"{tuple(joint_names)}: re-run the 'robot' stage")
    return plant
