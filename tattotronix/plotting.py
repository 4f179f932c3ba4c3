"""Shared matplotlib helpers for the figures of reports and studies.

matplotlib only, imported when a figure is drawn (never at module import), on the
non-interactive Agg backend: figures are written to files, never shown.
"""

from __future__ import annotations

from types import ModuleType
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from matplotlib.lines import Line2D

__all__ = ["legend_proxy", "pyplot"]


def pyplot() -> ModuleType:
    """``matplotlib.pyplot`` on the Agg backend."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def legend_proxy(marker: str, colour: str, label: str, ms: float = 6, ls: str = "none",
                 lw: float = 0.0, mec: str | None = None) -> Line2D:
    """A legend entry that draws nothing on the axes (a ``Line2D`` proxy artist).

    Args:
        marker: the marker (``""`` for a line only).
        colour: line and marker face colour.
        label: the legend text.
        ms: marker size, points.
        ls, lw: line style and width (``"none"``: marker only).
        mec: marker edge colour (default ``colour``).
    """
    from matplotlib.lines import Line2D

    return Line2D([], [], marker=marker, color=colour, ls=ls, lw=lw, ms=ms, label=label,
                  mec=mec or colour)
