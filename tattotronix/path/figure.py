"""The toolpath figure: ink, travel moves and needle entries over the panel (matplotlib Agg)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from tattotronix.path.path3d import MARK, TRAVEL
from tattotronix.path.plan import Toolpath
from tattotronix.plotting import pyplot

__all__ = ["toolpath_figure"]


def _runs(uv: np.ndarray, on: np.ndarray) -> list[np.ndarray]:
    """The polylines of consecutive segments ``on`` (segment ``i`` joins points ``i`` and
    ``i + 1``): one path each, not one per segment (a drawing has thousands)."""
    edges = np.diff(np.concatenate(([0], on.astype(np.int8), [0])))
    starts, stops = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    return [uv[a:b + 1] for a, b in zip(starts, stops, strict=True)]


def toolpath_figure(tp: Toolpath, panel_size_mm: tuple[float, float], path: Path,
                    title: str = "") -> None:
    """Draw the toolpath over the panel and save it as a PNG.

    Ink segments (both ends marking) are solid; travel moves at clearance are thin dashed
    lines between the retract and the next plunge; needle entries are dots.

    Args:
        tp: the planned toolpath.
        panel_size_mm: (width, height) of the panel, mm (centred at the origin).
        path: where to write the PNG.
        title: first title line (e.g. the artwork's name).
    """
    uv, z, kind = tp.path.uvz_mm[:, :2], tp.path.uvz_mm[:, 2], tp.path.kind
    seg = np.stack([uv[:-1], uv[1:]], axis=1)
    ink = (kind[:-1] == MARK) & (kind[1:] == MARK)
    horizontal = np.linalg.norm(seg[:, 1] - seg[:, 0], axis=1) > 1e-9
    travel = ~ink & horizontal & (z[:-1] > 0) & (z[1:] > 0)
    entry = np.flatnonzero((kind[:-1] == TRAVEL) & (kind[1:] != TRAVEL)) + 1
    if len(kind) and kind[0] != TRAVEL:
        entry = np.concatenate([[0], entry])

    pw, ph = panel_size_mm
    plt = pyplot()
    from matplotlib.collections import LineCollection
    from matplotlib.patches import Rectangle

    # a fixed layout in inches (matplotlib's tight_layout measured every label first: 40 %
    # of the preview's time): the title's two lines above, the labels and the legend below
    fig_h = 10 * ph / pw + 0.9
    fig, ax = plt.subplots(figsize=(10, fig_h), dpi=150)
    fig.subplots_adjust(left=0.75 / 10, right=1 - 0.15 / 10, top=1 - 0.5 / fig_h,
                        bottom=0.85 / fig_h)
    ax.add_patch(Rectangle((-pw / 2, -ph / 2), pw, ph, facecolor="#f4efe6",
                           edgecolor="#8a7f70", lw=1.2, zorder=0))
    ax.add_collection(LineCollection(_runs(uv, travel), colors="#d9480f", linewidths=0.5,
                                     linestyles=(0, (3, 2)), alpha=0.8, zorder=1,
                                     label="travel at clearance"))
    ax.add_collection(LineCollection(_runs(uv, ink), colors="#1b1b1b", linewidths=0.6,
                                     zorder=2, label="ink (needle down)"))
    ax.plot(uv[entry, 0], uv[entry, 1], "o", ms=3.5, mfc="#1971c2", mec="white", mew=0.5,
            zorder=3, label="needle entry")
    m, o = tp.metrics, tp.original
    ax.set_title(
        f"{title + ': ' if title else ''}{m.points} points, {m.marked_mm:.0f} mm ink, "
        f"{m.travel_mm:.0f} mm travel, {m.entries} entries, {m.time_s:.0f} s\n"
        f"original order: {o.travel_mm:.0f} mm travel, {o.entries} entries, {o.time_s:.0f} s"
        f"   |   {tp.drawing.regions} regions, {tp.drawing.holes} holes, "
        f"{len(tp.drawing.strokes)} strokes",
        fontsize=9,
    )
    ax.set_xlim(-pw / 2 - 5, pw / 2 + 5)
    ax.set_ylim(-ph / 2 - 5, ph / 2 + 5)
    ax.set_aspect("equal")
    ax.set_xlabel("panel u (mm)")
    ax.set_ylabel("panel v (mm)")
    # below the axes: inside, it would cover the panel's edge or the drawing
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.07), ncol=3, fontsize=8,
              frameon=False)
    fig.savefig(path, format="png", pil_kwargs={"compress_level": 1})  # 3x faster, 1.2x larger
    plt.close(fig)
