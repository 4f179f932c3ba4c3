"""The fill styles side by side (docs/toolpath.md, "Fill styles"): density against time.

Each case plans the same mask again with its ``toolpath.fill_style`` and
``toolpath.fill_angle_deg`` (:func:`~tattotronix.path.plan.plan_toolpath`: the same
regions, ordering and timing as the ``toolpath`` stage) and scores its planned ink against
the artwork (:meth:`~tattotronix.path.plan.Toolpath.ink`). :func:`fills_figure` shows a
square of each style's ink where the artwork is densest, and the share of the artwork
inked against the planned time; :meth:`FillComparison.metrics` is the metrics file (the
time of each style relative to the first case's).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, replace
from pathlib import Path

import cv2
import numpy as np
from numpy.typing import NDArray

from tattotronix.art.grid import InkMask
from tattotronix.art.vector import VectorLines
from tattotronix.errors import TattotronixError
from tattotronix.io.jsontypes import JsonDict
from tattotronix.path.fidelity import PlannedInk, fidelity_image
from tattotronix.path.params import ToolpathParams
from tattotronix.path.plan import plan_toolpath
from tattotronix.plotting import legend_proxy, pyplot

__all__ = ["FillCaseResult", "FillComparison", "compare_fill_styles", "densest_square",
           "fills_figure"]


@dataclass(frozen=True)
class FillCaseResult:
    """One style, planned.

    Attributes:
        name: the case. style, angle_deg: what it plans with.
        time_s: the planned drawing time, s. entries: needle entries.
        marked_mm: ink path length, mm. ink: the planned ink against the artwork.
    """

    name: str
    style: str
    angle_deg: float
    time_s: float
    entries: int
    marked_mm: float
    ink: PlannedInk

    def label(self) -> str:
        """``hatch``, or ``hatch at 45°`` when the hatch is turned."""
        return self.style if self.angle_deg == 0.0 else f"{self.style} at {self.angle_deg:g}°"


@dataclass(frozen=True)
class FillComparison:
    """Every style of one artwork; the first is the reference for the time ratios."""

    name: str
    cases: tuple[FillCaseResult, ...]

    def metrics(self) -> JsonDict:
        """The metrics file: per case its settings, planned time (and its ratio to the
        first case's), entries, marked length and the ink against the artwork."""
        ref = self.cases[0].time_s
        return {"name": self.name, "reference": self.cases[0].name, "cases": {
            c.name: {"fill_style": c.style, "fill_angle_deg": c.angle_deg,
                     "time_s": c.time_s, "time_ratio": c.time_s / ref if ref else None,
                     "entries": c.entries, "marked_mm": c.marked_mm,
                     "artwork": c.ink.fidelity.metrics()}
            for c in self.cases}}


def compare_fill_styles(mask: InkMask, params: ToolpathParams,
                        cases: Mapping[str, tuple[str, float]], needle_mm: float,
                        res_mm: float, name: str, vector: VectorLines | None = None
                        ) -> FillComparison:
    """Plan ``mask`` once per case and score each plan's ink against the artwork.

    Args:
        mask: the artwork's ink mask.
        params: the toolpath settings every case starts from.
        cases: case name -> ``(fill_style, fill_angle_deg)``, in order (the first is the
            reference for the time ratios).
        needle_mm: the needle's line width. res_mm: the ink grid's pixel.
        name: the artwork.
        vector: the artwork's own lines (``artwork.vector``), if any.

    Raises:
        TattotronixError: no cases, or a style the settings refuse (``concentric`` without
            ``toolpath.compensate``).
    """
    if not cases:
        raise TattotronixError("the fill-styles comparison has no cases (study.fills.cases)")
    out = []
    for case, (style, angle) in cases.items():
        tp = plan_toolpath(mask, replace(params, fill_style=style, fill_angle_deg=angle),
                           vector=vector)
        out.append(FillCaseResult(case, style, float(angle), float(tp.metrics.time_s),
                                  int(tp.metrics.entries), float(tp.metrics.marked_mm),
                                  tp.ink(mask, needle_mm, res_mm)))
    return FillComparison(name, tuple(out))


def densest_square(art: NDArray[np.bool_], side_px: int) -> tuple[int, int]:
    """The (row, col) of the top-left corner of the ``side_px`` square holding the most
    artwork (the first such, scanning rows then columns), inside the image."""
    rows, cols = art.shape
    side = max(1, min(side_px, rows, cols))
    summed = cv2.integral(art.astype(np.uint8))  # (rows + 1, cols + 1)
    inside = (summed[side:, side:] - summed[:-side, side:] - summed[side:, :-side]
              + summed[:-side, :-side])
    r, c = np.unravel_index(int(np.argmax(inside)), inside.shape)
    return int(r), int(c)


def fills_figure(comparison: FillComparison, zoom_mm: float, path: Path) -> None:
    """Each style's ink over the artwork in the same ``zoom_mm`` square (where the
    first case's artwork is densest; ink dark grey, artwork left uninked light grey,
    bleed red), and the share of the artwork inked against the planned time."""
    plt = pyplot()
    cases = comparison.cases
    n = len(cases)
    cols = min(3, n + 1)
    rows = -(-(n + 1) // cols)
    fig, axes = plt.subplots(rows, cols, figsize=(4.2 * cols, 4.3 * rows), squeeze=False)
    first = cases[0].ink
    res = first.grid.res_mm
    r0, c0 = densest_square(first.art, round(zoom_mm / res))
    # the square in panel mm (the grids may differ from case to case)
    u0, v0 = first.grid.to_mm(c0, r0)
    ref = cases[0].time_s
    for ax, c in zip(axes.flat, cases, strict=False):
        g = c.ink.grid
        r = round((g.v0_mm - v0) / g.res_mm)
        k = round((u0 - g.u0_mm) / g.res_mm)
        side = round(zoom_mm / g.res_mm)
        rgb = fidelity_image(c.ink.art, c.ink.ink)[max(r, 0):r + side, max(k, 0):k + side]
        ax.imshow(rgb, extent=(0.0, zoom_mm, 0.0, zoom_mm), interpolation="nearest")
        f = c.ink.fidelity
        ax.set_title(f"{c.label()}\n{100 * f.coverage:.0f} % of the artwork inked, "
                     f"{c.time_s / ref:.2f} × the time", fontsize=10)
        ax.set_xlabel("mm")
        ax.set_ylabel("mm")
    ax = axes.flat[n]
    markers = "osD^vP*X"
    # one hollow marker each, named in the legend: two cases at the same place both show
    for i, c in enumerate(cases):
        ax.plot(c.time_s, 100 * c.ink.fidelity.coverage, markers[i % len(markers)], ms=9,
                mfc="none", mew=1.8, color=f"C{i}", label=c.label())
    ax.legend(fontsize=9, loc="lower right")
    ax.set_xlabel("planned drawing time, s")
    ax.set_ylabel("share of the artwork inked, %")
    ax.set_title("density against time", fontsize=10)
    ax.grid(True, alpha=0.3)
    ax.margins(x=0.25, y=0.15)
    for extra in axes.flat[n + 1:]:
        extra.axis("off")
    fig.legend(handles=[legend_proxy("s", "#282828", "ink on the artwork", ms=9),
                        legend_proxy("s", "#c8c8c8", "artwork left uninked", ms=9),
                        legend_proxy("s", "#e61e1e", "ink outside the artwork", ms=9)],
               loc="lower center", ncol=3, fontsize=9, frameon=False)
    fig.suptitle(f"Fill styles on {comparison.name}: the same {zoom_mm:g} mm square of each "
                 f"plan ({first.grid.res_mm:g} mm grid)")
    fig.tight_layout(rect=(0, 0.04, 1, 1))
    fig.savefig(path, dpi=110)
    plt.close(fig)
