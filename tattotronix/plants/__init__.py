"""Interchangeable simulated arms: Pinocchio's ABA, MuJoCo and PyBullet behind one interface.

Every plant resets to a state, holds a torque (N m) over ``step(n)`` integration steps of
``dt`` (semi-implicit Euler in all three), and reports ``q``, ``qd`` and the tip pose. All
three are built from the generated models of the one robot description; none has joint
friction unless ``plant.damping`` is set, and the panel never resists the needle.
"""

from __future__ import annotations

from tattotronix.plants.base import Plant, PlantSettings, Workpiece
from tattotronix.plants.factory import BACKENDS, make_plant

__all__ = ["BACKENDS", "Plant", "PlantSettings", "Workpiece", "make_plant"]
