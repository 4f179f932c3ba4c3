"""Artwork input and ink masks."""

from __future__ import annotations
