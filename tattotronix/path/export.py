"""The toolpath as an SVG in millimetres, for vpype, Inkscape and plotter tools.

The page is the panel: ``width``/``height`` in mm and a ``viewBox`` in mm, so a user unit
is a millimetre and the file opens at the panel's physical size. The panel frame is y-up
(``v``), SVG is y-down: a panel point (u, v) is drawn at (u - u_min, v_max - v), so the
panel's top-left corner is the page's top-left corner.

Every piece of the path is a ``<polyline>`` in a top-level Inkscape layer
(``<g inkscape:groupmode="layer">``), one layer per kind of move (:data:`LAYERS`). vpype
``read`` makes a layer of each top-level group and takes its ID from the digits of its
``inkscape:label`` (then of its ``id``): each label starts with its layer number and each
id is ``layer<number>``, so both give the same ID. ``vpype read --attr stroke`` sorts by
stroke colour instead: each layer has its own colour, so that gives the same layers.

* The marking strokes, by their kind (``ToolpathRecord.stroke_kind``,
  :class:`~tattotronix.path.strokes.StrokeKind`): outer outlines, hole outlines, fill rows,
  lines along a centreline, concentric rings. A polyline is one stroke's run of points with
  the needle in the skin (every point whose kind is not travel), the plan's own points; a
  stroke of one point (a dot) is a polyline of that point twice.
* Drags: where the needle stays down across a gap between two strokes, the straight line
  from where one stroke ends to where the next starts.
* Travel: the moves with the needle up, from where one stroke ends to where the next
  starts (as seen from above: the lift and the plunge are vertical). First in the file, so
  Inkscape draws it under the ink; hide it (or ``vpype ... ldelete 7``) to see the ink only.

Each layer is drawn at the needle's width with round caps and joins. Coordinates are
rounded to 1 µm (3 decimals) and nothing depends on the time or the machine, so equal
plans give byte-identical files.
"""

from __future__ import annotations

from dataclasses import dataclass
from xml.sax.saxutils import escape, quoteattr

import numpy as np
from numpy.typing import NDArray

from tattotronix.path.kinds import TRAVEL
from tattotronix.path.order import Order
from tattotronix.path.path3d import Path3D
from tattotronix.path.plan import Toolpath
from tattotronix.path.polyline import oriented
from tattotronix.path.strokes import StrokeKind, StrokeSet

__all__ = ["DRAG_LAYER", "LAYERS", "LAYER_OF_KIND", "TRAVEL_LAYER", "Layer", "panel_extent_mm",
           "path_svg", "stroke_directions", "stroke_starts", "toolpath_svg"]

SVG_NS = "http://www.w3.org/2000/svg"
INKSCAPE_NS = "http://www.inkscape.org/namespaces/inkscape"

#: a drawn stroke's start is found among its points within this distance, mm (the path
#: holds the stroke's start vertex itself; the drag's points before it are a step away)
_START_TOL_MM = 1e-6


@dataclass(frozen=True)
class Layer:
    """One layer of the SVG.

    Attributes:
        number: the vpype layer ID (the digits of the label and of ``id``).
        name: what it holds (the rest of the label).
        colour: its stroke colour, ``#rrggbb`` (one per layer).
    """

    number: int
    name: str
    colour: str

    @property
    def label(self) -> str:
        """The ``inkscape:label``: the number, then the name (no other digits)."""
        return f"{self.number} {self.name}"


#: the layers, by number: the stroke kinds first (number = kind + 1), then drags, travel
LAYERS: tuple[Layer, ...] = (
    Layer(1, "outer outline", "#000000"),
    Layer(2, "hole outline", "#1971c2"),
    Layer(3, "fill row", "#862e9c"),
    Layer(4, "line", "#2f9e44"),
    Layer(5, "ring", "#c2255c"),
    Layer(6, "drag", "#f08c00"),
    Layer(7, "travel", "#adb5bd"),
)
#: the layer of each stroke kind
LAYER_OF_KIND: dict[StrokeKind, Layer] = {k: LAYERS[int(k)] for k in StrokeKind}
DRAG_LAYER = LAYERS[5]
TRAVEL_LAYER = LAYERS[6]


def panel_extent_mm(panel_size_mm: tuple[float, float]) -> tuple[float, float, float, float]:
    """(u_min, u_max, v_min, v_max) of a panel of (width, height) mm centred on the origin."""
    pw, ph = (float(s) for s in panel_size_mm)
    return (-pw / 2, pw / 2, -ph / 2, ph / 2)


def _oriented_vertex(drawing: StrokeSet, order: Order, nth: int) -> NDArray[np.float64]:
    """(n, 2) each drawn stroke's ``nth`` vertex as the planner orients it (its last, for
    a stroke with fewer), in drawing order."""
    seq = np.asarray(order.sequence, dtype=np.intp)
    if not len(seq):
        return np.zeros((0, 2))
    vb = drawing.bounds
    sizes = (vb[1:] - vb[:-1])[seq]
    fb = np.concatenate([[0], np.cumsum(sizes)]).astype(np.intp)
    src = np.repeat(vb[seq] - fb[:-1], sizes) + np.arange(int(fb[-1]))
    idx = oriented(fb, drawing.closed[seq], np.asarray(order.seam, dtype=np.intp),
                   np.asarray(order.reverse, dtype=bool))
    out: NDArray[np.float64] = drawing.vertices[src[idx[fb[:-1] + np.minimum(nth, sizes - 1)]]]
    return out


def stroke_starts(drawing: StrokeSet, order: Order) -> NDArray[np.float64]:
    """(n, 2) where each drawn stroke starts, in drawing order, panel mm: its vertex at the
    seam (a loop) or its first vertex as drawn (reversed or not), as the planner orients it
    (:func:`~tattotronix.path.polyline.oriented`)."""
    return _oriented_vertex(drawing, order, 0)


def stroke_directions(drawing: StrokeSet, order: Order) -> NDArray[np.float64]:
    """(n, 2) the unit direction of each drawn stroke's first segment (zero for a single
    point): a round turn (:mod:`tattotronix.path.turns`) trims a hatch run along it, so the
    run then starts on that line, past :func:`stroke_starts`."""
    d = _oriented_vertex(drawing, order, 1) - stroke_starts(drawing, order)
    n = np.hypot(d[:, 0], d[:, 1])
    out: NDArray[np.float64] = np.where(n[:, None] > 0, d / np.where(n > 0, n, 1.0)[:, None], 0.0)
    return out


def toolpath_svg(tp: Toolpath, needle_width_mm: float,
                 extent_mm: tuple[float, float, float, float], title: str = "") -> str:
    """The planned toolpath as an SVG document (see the module's docstring).

    Args:
        tp: the planned toolpath.
        needle_width_mm: the needle's width, the stroke width of every layer, mm.
        extent_mm: (u_min, u_max, v_min, v_max), the page in the panel frame, mm (the
            toolpath stage gives the panel: :func:`panel_extent_mm`).
        title: the document's ``<title>`` (e.g. the artwork's name); none when empty.

    Returns:
        The SVG text (UTF-8, a trailing newline).

    Raises:
        ValueError: an empty extent or a needle width that is not positive.
    """
    seq = tp.order.sequence
    return path_svg(tp.path, tp.drawing.kinds[seq], stroke_starts(tp.drawing, tp.order),
                    needle_width_mm, extent_mm, title,
                    stroke_directions(tp.drawing, tp.order))


def path_svg(path: Path3D, stroke_kind: NDArray[np.integer],
             stroke_start_mm: NDArray[np.float64], needle_width_mm: float,
             extent_mm: tuple[float, float, float, float], title: str = "",
             stroke_dir: NDArray[np.float64] | None = None) -> str:
    """:func:`toolpath_svg` of a path and its drawn strokes.

    Args:
        path: the 3-D path in the panel frame (its points, kinds and strokes).
        stroke_kind: (n,) the kind of each drawn stroke (drawing order).
        stroke_start_mm: (n, 2) where each drawn stroke starts (:func:`stroke_starts`):
            the points of a stroke reached with the needle down that come before it are
            the drag's.
        needle_width_mm: as for :func:`toolpath_svg`.
        extent_mm: as for :func:`toolpath_svg`.
        title: as for :func:`toolpath_svg`.
        stroke_dir: (n, 2) each stroke's first direction (:func:`stroke_directions`): a
            stroke reached by a round turn starts where its path first lies on that line,
            at or past its start; None: only at its start.

    Returns:
        The SVG text.

    Raises:
        ValueError: an empty extent or a needle width that is not positive.
    """
    u0, u1, v0, v1 = (float(e) for e in extent_mm)
    if not (u1 > u0 and v1 > v0):
        raise ValueError(f"empty SVG extent {extent_mm} (u_min, u_max, v_min, v_max)")
    if not needle_width_mm > 0:
        raise ValueError(f"needle width must be > 0 mm (got {needle_width_mm})")
    starts = np.asarray(stroke_start_mm, np.float64)
    dirs = np.zeros_like(starts) if stroke_dir is None else np.asarray(stroke_dir, np.float64)
    pieces = _pieces(path, np.asarray(stroke_kind), starts, dirs)
    uv = path.uvz_mm[:, :2]
    xs = (np.round(uv[:, 0] - u0, 3) + 0.0).tolist()  # + 0.0: no "-0.000"
    ys = (np.round(v1 - uv[:, 1], 3) + 0.0).tolist()
    width, height = _num(u1 - u0), _num(v1 - v0)
    lines = [
        '<?xml version="1.0" encoding="UTF-8" standalone="no"?>',
        f'<svg xmlns="{SVG_NS}" xmlns:inkscape="{INKSCAPE_NS}" version="1.1" '
        f'width="{width}mm" height="{height}mm" viewBox="0 0 {width} {height}">',
    ]
    if title:
        lines.append(f"<title>{escape(title)}</title>")
    lines.append(
        f"<desc>Toolpath, panel mm: x = u - u_min, y = v_max - v (u_min {_num(u0)}, v_max "
        f"{_num(v1)}). Layers: "
        + ", ".join(layer.label for layer in LAYERS) + f". Needle {_num(needle_width_mm)} mm."
        "</desc>")
    stroke_width = _num(needle_width_mm)
    for layer in (TRAVEL_LAYER, *LAYERS[:-1]):  # travel first: under the ink
        lines.append(
            f'<g id="layer{layer.number}" inkscape:groupmode="layer" '
            f"inkscape:label={quoteattr(layer.label)} fill=\"none\" stroke=\"{layer.colour}\" "
            f'stroke-width="{stroke_width}" stroke-linecap="round" stroke-linejoin="round">')
        for rows in pieces[layer.number]:
            points = [f"{xs[i]:.3f},{ys[i]:.3f}" for i in rows]
            if layer is TRAVEL_LAYER:  # the vertical moves are one point seen from above
                points = [p for j, p in enumerate(points) if j == 0 or p != points[j - 1]]
                if len(points) < 2:
                    continue
            lines.append(f'<polyline points="{" ".join(points)}"/>')
        lines.append("</g>")
    lines.append("</svg>")
    return "\n".join(lines) + "\n"


def _num(x: float) -> str:
    """A length for the header: at most 3 decimals, no trailing zeros."""
    text = f"{round(float(x), 3) + 0.0:.3f}".rstrip("0").rstrip(".")
    return text if text != "-0" else "0"


def _pieces(path: Path3D, stroke_kind: NDArray[np.integer], starts: NDArray[np.float64],
            dirs: NDArray[np.float64]) -> dict[int, list[list[int]]]:
    """The path's points in pieces, per layer number: each piece the row indices of one
    polyline, in path order."""
    uv = path.uvz_mm[:, :2]
    stroke = np.asarray(path.stroke, dtype=np.intp)
    n = len(uv)
    out: dict[int, list[list[int]]] = {layer.number: [] for layer in LAYERS}
    if n == 0:
        return out
    down = np.asarray(path.kind) != TRAVEL
    ink = down[:-1] & down[1:]  # segment i (point i to i + 1) is drawn in the skin
    # drags: entering a stroke with the needle down, the segments up to its start
    drag = np.zeros(n - 1, dtype=bool)
    for i in np.flatnonzero(ink & (stroke[1:] != stroke[:-1])).tolist():
        k = int(stroke[i + 1])
        end = int(np.searchsorted(stroke, k, side="right"))  # strokes never go back
        d = uv[i + 1:end] - starts[k]
        along = d @ dirs[k]  # 0 for a stroke with no direction: its start only
        across = np.hypot(d[:, 0] - along[:, None][:, 0] * dirs[k][0],
                          d[:, 1] - along * dirs[k][1])
        at = np.flatnonzero((across <= _START_TOL_MM) & (along >= -_START_TOL_MM))
        if len(at):  # else the stroke starts where the last ended: no drag at all
            drag[i:i + 1 + int(at[0])] = True
    kind_layer = np.array([LAYER_OF_KIND[StrokeKind(int(k))].number for k in stroke_kind]
                          + [0], dtype=np.intp)  # + [0]: an empty drawing indexes nothing
    layer = np.where(drag, DRAG_LAYER.number, kind_layer[stroke[1:]])
    # marking pieces: runs of drawn segments of one layer and one stroke
    seg = np.flatnonzero(ink)
    if len(seg):
        new = np.ones(len(seg), dtype=bool)
        new[1:] = ((seg[1:] != seg[:-1] + 1) | (layer[seg[1:]] != layer[seg[:-1]])
                   | (stroke[seg[1:] + 1] != stroke[seg[:-1] + 1]))
        first = seg[new]
        last = seg[np.concatenate([np.flatnonzero(new)[1:] - 1, [len(seg) - 1]])]
        for a, b in zip(first.tolist(), last.tolist(), strict=True):
            out[int(layer[a])].append(list(range(a, b + 2)))
    # dots: a point in the skin with no drawn segment on either side
    touched = np.zeros(n, dtype=bool)
    touched[:-1] |= ink
    touched[1:] |= ink
    for i in np.flatnonzero(down & ~touched).tolist():
        out[int(kind_layer[stroke[i]])].append([i, i])
    for pieces in out.values():
        pieces.sort(key=lambda rows: rows[0])
    # travel: runs of segments not in the skin
    up = np.flatnonzero(~ink)
    if len(up):
        new = np.ones(len(up), dtype=bool)
        new[1:] = up[1:] != up[:-1] + 1
        first = up[new]
        last = up[np.concatenate([np.flatnonzero(new)[1:] - 1, [len(up) - 1]])]
        out[TRAVEL_LAYER.number] = [list(range(a, b + 2))
                                    for a, b in zip(first.tolist(), last.tolist(), strict=True)]
    return out
