"""The factory that builds a plant backend from the generated models."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

from numpy.typing import ArrayLike

from tattotronix.errors import TattotronixError
from tattotronix.plants.base import Plant, PlantSettings, Workpiece

__all__ = ["BACKENDS", "make_plant"]


@dataclass(frozen=True)
class _Models:
    """What a backend may build from: the generated models and the joint limits."""

    urdf: Path
    mjcf: Path
    lower: ArrayLike
    upper: ArrayLike
    viewer: bool
    workpiece: Workpiece | None = None


def _model(m: _Models, settings: PlantSettings) -> Plant:
    from tattotronix.plants.model import ModelPlant

    return ModelPlant(m.urdf, settings, lower=m.lower, upper=m.upper)


def _mujoco(m: _Models, settings: PlantSettings) -> Plant:
    from tattotronix.plants.mujoco_plant import MujocoPlant

    return MujocoPlant(m.mjcf, settings, viewer=m.viewer, workpiece=m.workpiece)


def _pybullet(m: _Models, settings: PlantSettings) -> Plant:
    from tattotronix.plants.pybullet_plant import PybulletPlant

    return PybulletPlant(m.urdf, settings, viewer=m.viewer, workpiece=m.workpiece)


#: backend name -> builder (the engine is imported only when its backend is asked for).
#: A new backend is its module, one line here and its name in ``config.schema.Backend``.
_BUILDERS: dict[str, Callable[[_Models, PlantSettings], Plant]] = {
    "mujoco": _mujoco,
    "pybullet": _pybullet,
    "model": _model,
}

#: the simulated backends (``draw.py backend=...``)
BACKENDS = tuple(_BUILDERS)


def make_plant(backend: str, settings: PlantSettings, *, urdf: Path, mjcf: Path,
               joint_names: Sequence[str], lower: ArrayLike, upper: ArrayLike,
               viewer: bool = False, workpiece: Workpiece | None = None) -> Plant:
    """Build a plant from the generated models.

    Args:
        backend: one of :data:`BACKENDS` (``mujoco``, ``pybullet``, ``model``).
        settings: the plant settings.
        urdf, mjcf: the generated models (``data/robot/<name>.urdf`` / ``.xml``).
        joint_names: the joints, base outward (checked against each model).
        lower, upper: joint limits, rad (the model plant's clamp).
        viewer: open the engine's viewer (needs a display; MuJoCo and PyBullet).
        workpiece: what the needle draws on in the panel's place (a limb), shown by
            MuJoCo and PyBullet, in the viewer and the renderings, and never collided
            with; the model plant has no geometry to show it in.

    Raises:
        TattotronixError: an unknown backend, or a setting the backend cannot honour.
    """
    name = str(getattr(backend, "name", backend))
    build = _BUILDERS.get(name)
    if build is None:
        raise TattotronixError(f"unknown backend '{name}': use one of {', '.join(BACKENDS)} "
                               "(the real arm is backend=arm)")
    plant = build(_Models(urdf, mjcf, lower, upper, viewer, workpiece), settings)
    got = tuple(getattr(plant, "joint_names", ()))
    if got != tuple(joint_names):
        plant.close()
        raise TattotronixError(f"the {name} model has joints {got}, the description "
                               f"{tuple(joint_names)}: re-run the 'robot' stage")
    return plant
