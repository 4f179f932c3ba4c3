"""Vector input for line art: the stroked paths of an SVG, flattened, on the mask's grid.

With ``artwork.vector=true`` an SVG's stroked, unfilled paths are taken from its geometry
(parsed by svgelements, every transform applied: groups, ``<use>``, rotate, skew, matrix,
the viewBox) instead of from the rasterised mask, so a line is drawn where it was designed,
not where the mask's pixels put it. Each subpath
becomes a polyline: straight segments as they are, curves sampled at most ``step_mm``
apart (a chord error under a micrometre for a 2 mm radius at 0.15 mm). Coordinates are
panel millimetres in the mask's frame: the SVG's intrinsic size is mapped onto the raster
exactly as the renderer maps it (:func:`tattotronix.art.artwork.grid_shape`). Filled
shapes, and strokes as wide as the line threshold or wider, stay with the mask; so does a
stroke the geometry would draw other than the renderer (dashed, clipped, masked,
filtered, translucent; see :func:`svg_lines`), which the log names.
"""

from __future__ import annotations

import io
import logging
import math
import re
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from tattotronix.art.place import Placement
from tattotronix.errors import TattotronixError
from tattotronix.io.npz import READ_ERRORS, save_npz

__all__ = ["VectorLines", "artwork_lines", "svg_lines"]

log = logging.getLogger(__name__)


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

    def placed(self, place: Placement) -> VectorLines:
        """The lines where :class:`~tattotronix.art.place.Placement` puts the drawing (the
        mask's :attr:`~tattotronix.art.grid.InkMask.place`)."""
        if place.identity:
            return self
        return VectorLines(tuple(place.apply(p) for p in self.paths), self.widths_mm)

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


FALLBACK_ATTR = "data-tattotronix-fallback"
"""Marks, before svgelements parses, an element whose rendering the geometry cannot
reproduce (clipped, masked, filtered, translucent); svgelements passes unknown attributes
down to the element's descendants (and through ``<use>``), so they fall back too."""

MAX_WIDTH_SPREAD = 2.0
"""A subpath whose stroke width varies more than this (max / min) along it, under a
non-uniform transform (a strong skew or unequal scale), is left to the mask: one width per
polyline could not describe it."""

_SHOWN_FALLBACKS = 5  # elements named in the fallback log line
_CSS_DECL = re.compile(r"([\w-]+)\s*:\s*([^;]+)")


def _style(el: ET.Element) -> dict[str, str]:
    """An XML element's presentation attributes, its ``style`` declarations over them."""
    props = {k: v for k, v in el.attrib.items() if not k.startswith("{")}
    props.update((m.group(1).strip(), m.group(2).strip())
                 for m in _CSS_DECL.finditer(el.get("style", "")))
    return props


def _mark_fallbacks(text: str) -> str:
    """The SVG text with :data:`FALLBACK_ATTR` on every element the renderer draws other
    than its geometry says: a ``clip-path``, ``mask`` or ``filter``, or ``opacity`` below
    1 (not inherited in CSS, so svgelements does not pass them down by itself)."""
    root = ET.fromstring(text)
    marked = False
    for el in root.iter():
        props = _style(el)
        why = [k for k in ("clip-path", "mask", "filter")
               if props.get(k, "none").strip() not in ("", "none")]
        try:
            if float(props.get("opacity", "1").strip().rstrip("%")) < (
                    100.0 if props.get("opacity", "").strip().endswith("%") else 1.0):
                why.append("opacity")
        except ValueError:
            pass
        if why:
            el.set(FALLBACK_ATTR, "+".join(why))
            marked = True
    if not marked:
        return text
    ET.register_namespace("", "http://www.w3.org/2000/svg")
    ET.register_namespace("xlink", "http://www.w3.org/1999/xlink")
    return ET.tostring(root, encoding="unicode")


def _fallback_reason(el: Any) -> str | None:
    """Why a stroked shape is left to the mask (None: it is taken as a vector)."""
    values = el.values
    if values.get(FALLBACK_ATTR):
        return f"{values[FALLBACK_ATTR]} on it or a group around it"
    for key in ("clip-path", "mask", "filter"):  # set by a CSS rule on the element
        if str(values.get(key, "none")).strip() not in ("", "none"):
            return key
    dash = str(values.get("stroke-dasharray", "none")).strip()
    if dash not in ("", "none") and any(float(v) > 0 for v in re.split(r"[\s,]+", dash)
                                        if re.fullmatch(r"[\d.eE+-]+", v)):
        return "a dashed stroke (the vector line would be solid)"
    if str(values.get("vector-effect", "none")).strip() not in ("", "none"):
        return f"vector-effect={values['vector-effect']}"
    if el.stroke.alpha < 255:
        return "a translucent stroke"
    return None


def _label(el: Any) -> str:
    tag = el.values.get("tag", type(el).__name__.lower())
    return f"<{tag} id={el.id}>" if el.id else f"<{tag}>"


def svg_lines(path: Path, size_px: tuple[float, float], shape: tuple[int, int], res_mm: float,
              step_mm: float) -> VectorLines:
    """The stroked, unfilled subpaths of an SVG as polylines on the mask's grid.

    Every transform is applied (``matrix``, ``rotate``, ``skewX/Y``, ``scale``, nested
    groups, ``<use>``, the ``viewBox``), and the stroke width is the width the transform
    gives it across each segment (a skew or an unequal scale makes it depend on the
    direction; a subpath takes its length-weighted mean). A stroked shape whose rendering
    the geometry does not give (dashed, clipped, masked, filtered, translucent,
    ``vector-effect``, a stroke width that varies more than :data:`MAX_WIDTH_SPREAD` along
    it, or geometry svgelements cannot flatten) is not taken: the mask draws it, as without
    ``artwork.vector``, and the log names it and says why.

    Args:
        path: the SVG file.
        size_px: its intrinsic (width, height) in CSS px, as the renderer sizes it.
        shape: (H, W) of the raster it was rendered to (the mask grid).
        res_mm: the grid's pixel, mm.
        step_mm: the longest chord a curve is flattened to, mm.

    Returns:
        The polylines and their widths (in mm on the drawing).

    Raises:
        TattotronixError: the file cannot be read or is not XML (as the loader says).
    """
    from svgelements import SVG, Close, Line, Move, Shape
    from svgelements import Path as SvgPath

    from tattotronix.art.artwork import read_svg

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
    fallbacks: list[str] = []
    label = f"artwork {path}"
    text = _mark_fallbacks(read_svg(path, label))
    # reify=False: each shape keeps its whole transform (groups, <use>, viewBox) in
    # .transform, so the stroke width across a segment can be read from it
    svg = SVG.parse(io.StringIO(text), reify=False)
    for el in svg.elements():
        if not isinstance(el, Shape) or el.stroke is None or el.stroke.value is None:
            continue
        if el.fill is not None and el.fill.value is not None and el.fill.alpha > 0:
            continue  # a filled shape: the mask draws it
        if str(el.values.get("visibility", "visible")).strip() in ("hidden", "collapse"):
            continue  # not drawn at all
        width_user = float(el.stroke_width or 0.0)
        if width_user <= 0 or el.stroke.alpha == 0:
            continue
        why = _fallback_reason(el)
        taken: list[tuple[NDArray[np.float64], float]] = []
        if why is None:
            try:
                # flattened in the shape's own coordinates and then transformed here:
                # svgelements' transformed arcs are wrong under a skew or unequal scale
                # (the endpoints right, the ellipse between them not the circle's image)
                local = SvgPath(el)
                m = local.transform
                a2 = np.array([[m.a, m.c], [m.b, m.d]], dtype=np.float64)
                t2 = np.array([m.e, m.f], dtype=np.float64)
                adj = np.array([[m.d, -m.c], [-m.b, m.a]], dtype=np.float64)
                local_step = step_px / max(float(np.linalg.norm(a2, 2)), 1e-12)
                for sub in local.as_subpaths():
                    pts: list[tuple[float, float]] = []
                    for seg in sub:
                        if isinstance(seg, Move):
                            pts = [(seg.end.x, seg.end.y)]
                        elif isinstance(seg, Line | Close):
                            pts.append((seg.end.x, seg.end.y))
                        else:
                            n = max(2, math.ceil(float(seg.length()) / local_step) + 1)
                            for p in seg.npoint(np.linspace(0.0, 1.0, n))[1:]:
                                pts.append((float(p[0]), float(p[1])))
                    if len(pts) < 2:
                        continue
                    xy = np.asarray(pts, dtype=np.float64) @ a2.T + t2
                    if not np.isfinite(xy).all():
                        raise ValueError("non-finite coordinates")
                    d = np.diff(xy, axis=0)
                    seg_len = np.hypot(d[:, 0], d[:, 1])
                    keep = seg_len > 0
                    if not keep.any():
                        continue
                    # the stroke's width across each segment: w |adj(A) v|, v its unit
                    # direction on the page (w |det A| / |A u| for u its direction in
                    # user space)
                    across = width_user * np.hypot(
                        *(adj @ (d[keep] / seg_len[keep, None]).T))
                    if across.max() > MAX_WIDTH_SPREAD * across.min():
                        raise _WidthSpreadError(float(across.max() / across.min()))
                    width_px = float(np.average(across, weights=seg_len[keep]))
                    taken.append((to_mm(xy), width_px * sx * res_mm))
            except _WidthSpreadError as exc:
                why = (f"its stroke width varies {exc.args[0]:.1f}x along it "
                       "(a non-uniform transform)")
            except Exception as exc:  # noqa: BLE001 - svgelements raises anything
                why = f"svgelements cannot flatten it ({type(exc).__name__}: {exc})"
        if why is not None:
            fallbacks.append(f"{_label(el)} ({why})")
            continue
        for xy_mm, width_mm in taken:
            paths.append(xy_mm)
            widths.append(width_mm)
    if fallbacks:
        shown = "; ".join(fallbacks[:_SHOWN_FALLBACKS]) + (
            f"; and {len(fallbacks) - _SHOWN_FALLBACKS} more"
            if len(fallbacks) > _SHOWN_FALLBACKS else "")
        log.info("%s: %d stroked element(s) drawn from the mask, not as vector lines "
                 "(artwork.vector): %s", label, len(fallbacks), shown)
    return VectorLines(tuple(paths), np.asarray(widths, dtype=np.float64))


class _WidthSpreadError(Exception):
    """A subpath's stroke width varies too much along it (see :data:`MAX_WIDTH_SPREAD`)."""


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
