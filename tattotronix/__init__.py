"""TATTOTRONIX: a config-driven pipeline for a 5-DOF tattoo and drawing arm."""

from __future__ import annotations

__version__ = "0.1.0"
