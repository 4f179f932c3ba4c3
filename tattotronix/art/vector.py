"""Vector input for line art: the stroked paths of an SVG, flattened, on the mask's grid.

With ``artwork.vector=true`` an SVG's stroked, unfilled paths are taken from its geometry
(parsed by svgelements, transforms applied) instead of from the rasterised mask, so a
line is drawn where it was designed, not where the mask's pixels put it. Each subpath
becomes a polyline: straight segments as they are, curves sampled at most ``step_mm``
apart (a chord error under a micrometre for a 2 mm radius at 0.15 mm). Coordinates are
panel millimetres in the mask's frame: the SVG's intrinsic size is mapped onto the raster
exactly as the renderer maps it (:func:`tattotronix.art.artwork.grid_shape`). Filled
shapes, and strokes as wide as the line threshold or wider, stay with the mask.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from tattotronix.errors import TattotronixError
from tattotronix.io.npz import READ_ERRORS, save_npz

__all__ = ["VectorLines", "artwork_lines", "svg_lines"]


@dataclass(frozen=True)
class VectorLines:
    """Stroked polylines in panel mm (the mask's frame) and their stroke widths.

    Attributes:
        paths: each (n, 2) mm; a closed subpath repeats its first vertex.
        widths_mm: (len(paths),) stroke width of each, mm.
    """

    paths: tuple[NDArray[np.float64], ...]
    widths_mm: NDArray[np.float64]

    @classmethod
    def empty(cls) -> VectorLines:
        """No vector line (raster input, or ``artwork.vector=false``)."""
        return cls((), np.zeros(0))

    def save(self, path: Path) -> None:
        """Write as an npz: the vertices end to end, the bounds and the widths."""
        sizes = [len(p) for p in self.paths]
        save_npz(path, {
            "vertices": np.concatenate(self.paths) if self.paths else np.zeros((0, 2)),
            "bounds": np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64),
            "widths_mm": np.asarray(self.widths_mm, dtype=np.float64)})

    @classmethod
    def load(cls, path: Path) -> VectorLines:
        """Read what :meth:`save` wrote.

        Raises:
            TattotronixError: unreadable, or not a lines file; the message names it.
        """
        try:
            with np.load(path, allow_pickle=False) as z:
                v, b, w = z["vertices"], z["bounds"], z["widths_mm"]
        except READ_ERRORS as exc:
            raise TattotronixError(f"cannot read {path} ({exc}): re-run the 'artwork' stage"
                                   ) from None
        if len(b) != len(w) + 1 or (len(b) and b[-1] != len(v)):
            raise TattotronixError(f"{path} is not a lines file: re-run the 'artwork' stage")
        return cls(tuple(v[b[i]:b[i + 1]] for i in range(len(w))), w)


def svg_lines(path: Path, size_px: tuple[float, float], shape: tuple[int, int], res_mm: float,
              step_mm: float) -> VectorLines:
    """The stroked, unfilled subpaths of an SVG as polylines on the mask's grid.

    Args:
        path: the SVG file.
        size_px: its intrinsic (width, height) in CSS px, as the renderer sizes it.
        shape: (H, W) of the raster it was rendered to (the mask grid).
        res_mm: the grid's pixel, mm.
        step_mm: the longest chord a curve is flattened to, mm.

    Returns:
        The polylines and their widths (in mm on the drawing).
    """
    from svgelements import SVG, Close, Line, Move, Shape
    from svgelements import Path as SvgPath

    h, w = shape
    sx, sy = w / size_px[0], h / size_px[1]  # raster px per CSS px
    x0 = -w / 2 * res_mm
    y0 = (h - 1 - h / 2) * res_mm

    def to_mm(pts: NDArray[np.float64]) -> NDArray[np.float64]:
        col = pts[:, 0] * sx - 0.5
        row = pts[:, 1] * sy - 0.5
        return np.column_stack([x0 + col * res_mm, y0 - row * res_mm])

    step_px = step_mm / res_mm / max(sx, sy)
    paths: list[NDArray[np.float64]] = []
    widths: list[float] = []
    svg = SVG.parse(str(path), reify=True)
    for el in svg.elements():
        if not isinstance(el, Shape) or el.stroke is None or el.stroke.value is None:
            continue
        if el.fill is not None and el.fill.value is not None and el.fill.alpha > 0:
            continue  # a filled shape: the mask draws it
        width_px = float(el.implicit_stroke_width or 0.0)
        if width_px <= 0:
            continue
        width_mm = width_px * sx * res_mm
        for sub in SvgPath(el).as_subpaths():
            pts: list[tuple[float, float]] = []
            for seg in sub:
                if isinstance(seg, Move):
                    pts = [(seg.end.x, seg.end.y)]
                elif isinstance(seg, Line | Close):
                    pts.append((seg.end.x, seg.end.y))
                else:
                    n = max(2, math.ceil(float(seg.length()) / step_px) + 1)
                    for p in seg.npoint(np.linspace(0.0, 1.0, n))[1:]:
                        pts.append((float(p[0]), float(p[1])))
            if len(pts) >= 2:
                paths.append(to_mm(np.asarray(pts, dtype=np.float64)))
                widths.append(width_mm)
    return VectorLines(tuple(paths), np.asarray(widths, dtype=np.float64))


def artwork_lines(source: str | Path | None, shape: tuple[int, int], res_mm: float,
                  step_mm: float) -> VectorLines:
    """The vector lines of an artwork (:func:`svg_lines`); none for a raster image.

    Args:
        source: the artwork source (a path or a built-in name, as ``artwork.source``).
        shape: (H, W) of its raster on the mask grid.
        res_mm: the grid's pixel, mm.
        step_mm: the longest chord a curve is flattened to, mm.
    """
    from tattotronix.art.artwork import read_svg, resolve_source, svg_intrinsic_size

    path = resolve_source(source)
    if path.suffix.lower() != ".svg":
        return VectorLines.empty()
    size = svg_intrinsic_size(read_svg(path))
    return svg_lines(path, size, shape, res_mm, step_mm)
