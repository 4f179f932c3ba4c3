"""Toolpaths: outlines, hatch fill, lifts, resampling, ordering, panel mapping."""

from __future__ import annotations
