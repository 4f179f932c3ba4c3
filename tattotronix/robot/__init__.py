"""The robot: one description, generated URDF/MJCF, loaders, mass properties."""

from __future__ import annotations
