"""Ink comparisons as figures a person can read: the planned ink against the artwork
(``artwork_ink.png``, ``ink_vs_artwork.png``) and the simulated ink against the planned
ink (``ink_vs_plan.png``).

The two rasters being compared (``draw.ink_res_mm`` or ``toolpath.ink_res_mm`` pixels)
differ mostly by single pixels, far too small to see at the scale of the whole drawing.
The overview (panel millimetres, a scale bar) therefore grows every differing pixel to a
spot a few screen pixels across, drawn over the ink; the zoom beside it shows the worst
spot (:func:`worst_spot`) at the raster's own pixels, nothing grown. Nothing here is
measured: the figures draw the masks they are given.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from tattotronix.path.fidelity import ArtworkFidelity, InkGrid, distance_at
from tattotronix.plotting import pyplot

__all__ = ["InkLayer", "artwork_ink_figure", "ink_figure", "plan_ink_figure", "worst_spot"]

Mask = NDArray[np.bool_]

#: figure size, inches, and resolution, dots per inch
FIGSIZE = (14.0, 6.8)
DPI = 130
#: the overview and the zoom, figure fractions (left, bottom, width, height)
_MAIN = (0.055, 0.1, 0.63, 0.76)
_ZOOM = (0.735, 0.36, 0.245, 0.5)
#: a grown difference is about this many screen pixels across on the overview
_SPOT_PX = 4.0
#: ink colours (the same as the rasters these figures replaced)
INK_BOTH = "#282828"
PLAN_ONLY = "#1e5ae6"
SIM_ONLY = "#dc1e1e"
ART_UNINKED = "#c8c8c8"
BLEED = "#e61e1e"


@dataclass(frozen=True)
class InkLayer:
    """One kind of pixel of a comparison.

    Attributes:
        pixels: where it is (the grid's shape).
        colour: its colour (matplotlib).
        label: the legend's words.
        grow: a difference: grown on the overview so that it shows, drawn over the rest.
    """

    pixels: Mask
    colour: str
    label: str
    grow: bool = False


def worst_spot(far_px: NDArray[np.float32], where: Mask, window_px: int
               ) -> tuple[int, int] | None:
    """The (row, col) of the pixel of ``where`` with the largest ``far_px``; among equals,
    the one with the most pixels of ``where`` within ``window_px`` (the densest cluster
    of the worst). None when ``where`` is empty."""
    if not where.any():
        return None
    top = float(far_px[where].max())
    candidates = where & (far_px >= top - 1e-6)
    k = max(1, int(window_px)) | 1
    density = cv2.boxFilter(where.astype(np.float32), -1, (k, k), normalize=False,
                            borderType=cv2.BORDER_CONSTANT)
    score = np.where(candidates, density, -1.0)
    r, c = np.unravel_index(int(np.argmax(score)), score.shape)
    return int(r), int(c)


def _pool(img: Mask, f: int) -> Mask:
    """Max-pool a mask by ``f`` (any pixel of a block inked inks the block)."""
    if f <= 1:
        return img
    rows, cols = img.shape
    pr, pc = -rows % f, -cols % f
    padded = np.pad(img, ((0, pr), (0, pc)))
    return np.asarray(padded.reshape((rows + pr) // f, f, (cols + pc) // f, f).any(axis=(1, 3)),
                      dtype=bool)


def _grow(img: Mask, radius_px: int) -> Mask:
    if radius_px < 1 or not img.any():
        return img
    disc = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * radius_px + 1,) * 2)
    return cv2.dilate(img.astype(np.uint8), disc).astype(bool)


def _compose(layers: Sequence[tuple[Mask, str]], shape: tuple[int, int]) -> NDArray[np.uint8]:
    """An RGB image: white, then each layer's pixels in its colour, in order."""
    from matplotlib.colors import to_rgb

    rgb = np.full(shape + (3,), 255, dtype=np.uint8)
    for pixels, colour in layers:
        rgb[pixels] = np.round(np.asarray(to_rgb(colour)) * 255).astype(np.uint8)
    return rgb


def _scale_bar(ax: Any, length_mm: float, label: str, loc: str = "lower left") -> None:
    from matplotlib.font_manager import FontProperties
    from mpl_toolkits.axes_grid1.anchored_artists import AnchoredSizeBar

    ax.add_artist(AnchoredSizeBar(ax.transData, length_mm, label, loc, pad=0.5,
                                  borderpad=0.6, sep=3, color="black", frameon=True,
                                  size_vertical=length_mm / 25,
                                  fontproperties=FontProperties(size=8)))


def _nice(x: float) -> float:
    """The largest of 1, 2, 5 x 10^k not above ``x``."""
    if x <= 0:
        return 1.0
    k = 10.0 ** np.floor(np.log10(x))
    return float(max(m * k for m in (1.0, 2.0, 5.0) if m * k <= x))


def ink_figure(layers: Sequence[InkLayer], grid: InkGrid, path: Path, *, title: str,
               worst: tuple[int, int] | None, worst_words: str, zoom_mm: float = 3.0) -> None:
    """Draw a comparison of rasters on ``grid`` and write it as a PNG.

    Left, the whole raster in panel millimetres, with a scale bar; the ``grow`` layers
    grown to spots that show and drawn over the rest. Right, the ``zoom_mm`` square about
    ``worst`` (row, col) at the raster's own pixels (the worst pixel ringed), framed on
    the overview; below it, the legend.

    Args:
        layers: the kinds of pixel, drawn in order (later ones over earlier ones).
        grid: the raster's grid (panel mm).
        path: the PNG to write.
        title: the figure's title (one or two lines).
        worst: the pixel the zoom is centred on, or None (no zoom: nothing differs).
        worst_words: what the worst pixel is (the zoom's title).
        zoom_mm: the zoom's side, mm.
    """
    from matplotlib.patches import Circle, Patch

    plt = pyplot()
    res = grid.res_mm
    rows, cols = grid.shape
    fig = plt.figure(figsize=FIGSIZE, dpi=DPI)
    ax = fig.add_axes(_MAIN)
    # raster pixels per screen pixel on the overview (the axes are width- or height-bound)
    aspect_box = _MAIN[2] * FIGSIZE[0] / (_MAIN[3] * FIGSIZE[1])
    screen_px = (_MAIN[2] * FIGSIZE[0] * DPI if cols / rows >= aspect_box
                 else _MAIN[3] * FIGSIZE[1] * DPI * cols / rows)
    f = max(1, int(round(cols / screen_px)))
    grow_px = max(1, int(round(_SPOT_PX * f / 2)))
    spot_mm = (2 * grow_px + 1) * res
    over = [(_pool(_grow(ly.pixels, grow_px) if ly.grow else ly.pixels, f), ly.colour)
            for ly in sorted(layers, key=lambda ly: ly.grow)]
    img = _compose(over, over[0][0].shape if over else (rows, cols))
    u_lo, v_hi = grid.u0_mm - res / 2, grid.v0_mm + res / 2
    extent = (u_lo, u_lo + img.shape[1] * f * res, v_hi - img.shape[0] * f * res, v_hi)
    ax.imshow(img, extent=extent, origin="upper", interpolation="nearest")
    ax.set_xlim(u_lo, u_lo + cols * res)
    ax.set_ylim(v_hi - rows * res * 1.12, v_hi)  # white below the raster: the scale bar
    ax.set_aspect("equal")
    ax.set_anchor("W")
    ax.set_xlabel("panel u (mm)")
    ax.set_ylabel("panel v (mm)")
    ax.tick_params(labelsize=8)
    bar = _nice(cols * res / 6)
    _scale_bar(ax, bar, f"{bar:g} mm")

    handles = [Patch(facecolor=ly.colour, edgecolor="0.3", lw=0.5,
                     label=f"{ly.label}: {int(ly.pixels.sum()):,} px"
                           + (f"\n(grown to {spot_mm:.2f} mm spots on the left)"
                              if ly.grow else ""))
               for ly in layers]
    if worst is not None:
        r, c = worst
        uc, vc = grid.to_mm(c, r)
        half = zoom_mm / 2
        az = fig.add_axes(_ZOOM)
        r0, r1 = max(0, int(r - half / res)), min(rows, int(r + half / res) + 1)
        c0, c1 = max(0, int(c - half / res)), min(cols, int(c + half / res) + 1)
        crop = _compose([(ly.pixels[r0:r1, c0:c1], ly.colour) for ly in layers],
                        (r1 - r0, c1 - c0))
        (left, bottom), (right, top) = grid.to_mm(c0 - 0.5, r1 - 0.5), grid.to_mm(c1 - 0.5,
                                                                                 r0 - 0.5)
        az.imshow(crop, origin="upper", interpolation="nearest",
                  extent=(left, right, bottom, top))
        az.set_xlim(uc - half, uc + half)
        az.set_ylim(vc - half, vc + half)
        az.set_aspect("equal")
        az.add_patch(Circle((uc, vc), 4 * res, fill=False, ec="#f08c00", lw=1.6, zorder=3))
        handles.append(plt.Line2D([], [], marker="o", ls="none", mfc="none", mec="#f08c00",
                                  mew=1.6, ms=9, label=f"the worst pixel ({worst_words})"))
        az.set_title(f"zoom on the worst spot ({zoom_mm:g} mm square),\n"
                     f"true pixels of {res:g} mm, nothing grown", fontsize=9)
        az.tick_params(labelsize=7)
        az.set_xlabel("panel u (mm)", fontsize=8)
        az.set_ylabel("panel v (mm)", fontsize=8)
        zbar = _nice(zoom_mm / 4)
        _scale_bar(az, zbar, f"{zbar:g} mm")
        ax.indicate_inset_zoom(az, edgecolor="#f08c00", alpha=1.0, linewidth=1.2)
    else:
        fig.text(_ZOOM[0] + _ZOOM[2] / 2, _ZOOM[1] + _ZOOM[3] / 2, "no pixel differs:\nno zoom",
                 ha="center", va="center", fontsize=10)
    fig.legend(handles=handles, loc="upper left", fontsize=8, frameon=True,
               bbox_to_anchor=(_ZOOM[0] - 0.02, _ZOOM[1] - 0.06))
    fig.suptitle(title, fontsize=11)
    fig.savefig(path, format="png", dpi=DPI)
    plt.close(fig)


def plan_ink_figure(sim: Mask, plan: Mask, grid: InkGrid, path: Path, title: str) -> None:
    """The simulated ink against the planned ink (grey both, blue plan only, red
    simulation only); the zoom on the pixel farthest from the other ink (the one that
    sets the worst deviation), in its densest cluster."""
    sim_only, plan_only = sim & ~plan, plan & ~sim
    far = np.zeros(sim.shape, dtype=np.float32)
    if sim_only.any():
        far[sim_only] = distance_at(plan, sim_only)
    if plan_only.any():
        far[plan_only] = distance_at(sim, plan_only)
    worst = worst_spot(far, sim_only | plan_only, int(round(1.0 / grid.res_mm)))
    words = "" if worst is None else f"{far[worst] * grid.res_mm:.2f} mm from the other ink"
    ink_figure([InkLayer(sim & plan, INK_BOTH, "inked in both"),
                InkLayer(plan_only, PLAN_ONLY, "plan only", grow=True),
                InkLayer(sim_only, SIM_ONLY, "simulation only", grow=True)],
               grid, path, title=title, worst=worst, worst_words=words)


def artwork_ink_figure(art: Mask, ink: Mask, grid: InkGrid, path: Path, head: str,
                       fidelity: ArtworkFidelity | str) -> None:
    """Ink against the artwork (dark grey ink on the artwork, light grey artwork left
    uninked, red ink outside the artwork); the zoom on the ink pixel farthest outside
    the artwork, in its densest cluster. The title is ``head`` and a line of
    ``fidelity``'s numbers (or, for ink that is not scored, the reason why)."""
    f = fidelity
    title = (f"{head}\n{f}" if isinstance(f, str) else
             f"{head}\nink outside the artwork: {100 * f.bleed_share:.2f} % of the ink, at "
             f"most {f.bleed_max_mm:.2f} mm out;  artwork inked: {100 * f.coverage:.1f} %;  "
             f"edge error {f.edge_mean_mm:.3f} mm mean, {f.edge_max_mm:.2f} mm worst")
    bleed = ink & ~art
    far = np.zeros(art.shape, dtype=np.float32)
    if bleed.any():
        far[bleed] = distance_at(art, bleed)
    worst = worst_spot(far, bleed, int(round(1.0 / grid.res_mm)))
    words = "" if worst is None else f"{far[worst] * grid.res_mm:.2f} mm outside the artwork"
    ink_figure([InkLayer(art & ~ink, ART_UNINKED, "artwork left uninked"),
                InkLayer(art & ink, INK_BOTH, "ink on the artwork"),
                InkLayer(bleed, BLEED, "ink outside the artwork", grow=True)],
               grid, path, title=title, worst=worst, worst_words=words)
