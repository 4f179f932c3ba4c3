"""Shared matplotlib helpers for the figures of reports and studies.

matplotlib only, imported when a figure is drawn (never at module import), on the
non-interactive Agg backend: figures are written to files, never shown.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from types import ModuleType
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
from numpy.typing import ArrayLike

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.lines import Line2D
    from matplotlib.text import Annotation
    from matplotlib.transforms import Bbox

__all__ = ["legend_proxy", "pin_fonts", "place_labels", "pyplot"]

_HA = Literal["left", "center", "right"]
_VA = Literal["bottom", "center", "top"]
#: where a label may go about its point, in order of preference (right, left, above,
#: below, then the diagonals): the direction and the label's alignment there
_DIRECTIONS: tuple[tuple[float, float, _HA, _VA], ...] = (
    (1.0, 0.0, "left", "center"), (-1.0, 0.0, "right", "center"),
    (0.0, 1.0, "center", "bottom"), (0.0, -1.0, "center", "top"),
    (1.0, 1.0, "left", "bottom"), (-1.0, 1.0, "right", "bottom"),
    (1.0, -1.0, "left", "top"), (-1.0, -1.0, "right", "top"))


def pyplot() -> ModuleType:
    """``matplotlib.pyplot`` on the Agg backend, with the fonts pinned (:func:`pin_fonts`)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    pin_fonts()
    return plt


_pinned: list[bool] = []


def pin_fonts() -> None:
    """Draw text with the fonts matplotlib ships, never a system font of the same name.

    matplotlib picks among fonts of one name (DejaVu Sans in its own folder and in
    ``/usr/share/fonts``) by the order of its font cache, a file shared by every
    environment of the user and rebuilt by whichever runs first: the same figure came out
    with a label a pixel apart on two machines, and ``dvc.lock`` differed. Here the
    shipped fonts go first and their system namesakes are dropped. Once per process.
    """
    if _pinned:
        return
    import matplotlib
    from matplotlib import font_manager

    folder = Path(matplotlib.get_data_path()) / "fonts" / "ttf"
    shipped = [font_manager.ttfFontProperty(font_manager.get_font(str(f)))
               for f in sorted(folder.glob("*.ttf"))]
    names = {e.name for e in shipped}
    fm = font_manager.fontManager
    fm.ttflist = shipped + [e for e in fm.ttflist if e.name not in names]
    cached = getattr(font_manager.FontManager, "_findfont_cached", None)
    if cached is not None and hasattr(cached, "cache_clear"):
        cached.cache_clear()
    _pinned.append(True)


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


def _overlap(a: Bbox, b: Bbox) -> float:
    """Area common to two display boxes (``Bbox``), px^2."""
    w = min(a.x1, b.x1) - max(a.x0, b.x0)
    h = min(a.y1, b.y1) - max(a.y0, b.y0)
    return w * h if w > 0 and h > 0 else 0.0


def place_labels(ax: Axes, xy: ArrayLike, texts: Sequence[str],
                 radii_pt: ArrayLike | float = 4.0, avoid: Sequence[ArrayLike] = (),
                 marks: Sequence[tuple[float, float, float]] = (), gap_pt: float = 3.0,
                 taken: list[Bbox] | None = None,
                 **text_kw: Any,  # Any: matplotlib's Text keyword arguments
                 ) -> list[Annotation]:
    """Label each point beside its marker, where the label covers least.

    Each label goes just outside its point's marker (radius ``radii_pt``), on the side
    (:data:`_DIRECTIONS`, in order of preference) where it covers the least of: every
    point's marker, the other ``marks``, the labels already placed, the polylines of
    ``avoid``, the axes' legend and the area outside the axes. Call it once the axes'
    limits and aspect are final.

    Args:
        ax: the axes (data coordinates).
        xy: (N, 2) the points.
        texts: (N,) the labels.
        radii_pt: each marker's radius (or one for all), points.
        avoid: polylines, each (M, 2) in data coordinates, that labels should not cross.
        marks: other markers labels should not cover: (x, y, radius in points) each.
        gap_pt: between a marker's edge and its label, points.
        taken: the display boxes of labels placed by an earlier call, avoided too; this
            call's are appended (one list shared by calls on one axes).
        **text_kw: for ``ax.annotate`` (``fontsize`` ...).

    Returns:
        The annotations.
    """
    from matplotlib.transforms import Bbox

    fig = ax.get_figure()
    assert fig is not None
    fig.canvas.draw()  # the layout (limits, aspect) the labels are placed on
    renderer = fig.canvas.get_renderer()  # type: ignore[attr-defined]
    pts = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
    radii = np.broadcast_to(np.asarray(radii_pt, dtype=np.float64), (len(pts),))
    px_per_pt = fig.dpi / 72.0
    centre = ax.transData.transform(pts)
    markers = [Bbox.from_extents(*(c - r * px_per_pt), *(c + r * px_per_pt))
               for c, r in zip(centre, radii, strict=True)]
    for x, y, r in marks:
        c = ax.transData.transform((x, y))
        markers.append(Bbox.from_extents(*(c - r * px_per_pt), *(c + r * px_per_pt)))
    lines = []
    for line in avoid:
        d = ax.transData.transform(np.asarray(line, dtype=np.float64).reshape(-1, 2))
        for a, b in zip(d[:-1], d[1:], strict=True):
            n = max(2, int(np.hypot(*(b - a)) / 2.0))
            lines.append(a + np.linspace(0.0, 1.0, n)[:, None] * (b - a))
    samples = np.concatenate(lines) if lines else np.zeros((0, 2))
    frame = ax.get_window_extent(renderer)
    legend = ax.get_legend()
    placed: list[Bbox] = [] if taken is None else taken
    if legend is not None:
        placed.append(legend.get_window_extent(renderer))
    out = []
    for i, (p, text) in enumerate(zip(pts, texts, strict=True)):
        best: tuple[float, tuple[float, float], _HA, _VA] | None = None
        ann = ax.annotate(text, tuple(p), textcoords="offset points", xytext=(0, 0),
                          **text_kw)
        for dx, dy, ha, va in _DIRECTIONS:
            norm = float(np.hypot(dx, dy))
            off = ((radii[i] + gap_pt) * dx / norm, (radii[i] + gap_pt) * dy / norm)
            ann.set_position(off)
            ann.set_horizontalalignment(ha)
            ann.set_verticalalignment(va)
            box = ann.get_window_extent(renderer).expanded(1.08, 1.15)
            cost = sum(_overlap(box, m) for j, m in enumerate(markers) if j != i)
            cost += sum(_overlap(box, q) for q in placed)
            inside = Bbox.intersection(box, frame)
            cost += 4.0 * (box.width * box.height
                           - (inside.width * inside.height if inside is not None else 0.0))
            if len(samples):
                hit = ((samples[:, 0] >= box.x0) & (samples[:, 0] <= box.x1)
                       & (samples[:, 1] >= box.y0) & (samples[:, 1] <= box.y1))
                cost += 40.0 * float(hit.sum())
            if best is None or cost < best[0] - 1e-9:
                best = (cost, off, ha, va)
        assert best is not None
        _, off, ha, va = best
        ann.set_position(off)
        ann.set_horizontalalignment(ha)
        ann.set_verticalalignment(va)
        placed.append(ann.get_window_extent(renderer).expanded(1.08, 1.15))
        out.append(ann)
    return out
