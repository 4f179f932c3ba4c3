"""Property tests of the toolpath on random masks (unions of discs and rectangles)."""

from __future__ import annotations

import dataclasses

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy import ndimage

from tattotronix.art.grid import InkMask
from tattotronix.config.schema import MaskConfig, PanelConfig, ToolpathConfig
from tattotronix.path.params import ToolpathParams
from tattotronix.path.plan import Toolpath, plan_toolpath
from tattotronix.path.strokes import StrokeKind

RES = 0.25
SIZE = 96  # grid pixels per side (24 mm)
PARAMS = dataclasses.replace(  # the original's strokes (compensated: tests/test_inset.py)
    ToolpathParams.from_settings(ToolpathConfig(), MaskConfig(), PanelConfig()), compensate=False)

@st.composite
def masks(draw: st.DrawFn, size: int = SIZE) -> InkMask:
    """Unions of discs, rectangles and rings, with cuts, on a ``size`` x ``size`` grid."""
    shape = st.tuples(
        st.sampled_from(["disc", "rect", "ring", "cut"]),
        st.integers(0, size - 1), st.integers(0, size - 1),  # centre (row, col)
        st.integers(5, 30), st.integers(2, 30),  # radius / half sizes, px
    )
    yy, xx = np.mgrid[0:size, 0:size]
    ink = np.zeros((size, size), bool)
    for kind, r0, c0, a, b in draw(st.lists(shape, min_size=1, max_size=7)):
        if kind == "disc":
            ink |= np.hypot(yy - r0, xx - c0) <= a
        elif kind == "rect":
            ink |= (np.abs(yy - r0) <= a) & (np.abs(xx - c0) <= b)
        elif kind == "ring":
            r = np.hypot(yy - r0, xx - c0)
            ink |= (r <= a) & (r > min(b, a - 2))
        else:  # cut a hole (or a notch) into what is there
            ink &= np.hypot(yy - r0, xx - c0) > a / 2
    ink[0, 0] = True  # a one-pixel speck: always dropped
    return InkMask.centred(ink, RES)


def nearest_ink(mask: InkMask, pts: np.ndarray) -> np.ndarray:
    """Independent nearest-pixel lookup (argmin over the grid coordinates)."""
    col = np.abs(pts[:, None, 0] - mask.xs[None, :]).argmin(axis=1)
    row = np.abs(pts[:, None, 1] - mask.ys[None, :]).argmin(axis=1)
    return mask.ink[row, col]


def arc_positions(path: np.ndarray, pts: np.ndarray, step: float) -> np.ndarray:
    """Arc length along ``path`` of each point of ``pts`` (taken in order along it).

    Where the path runs over itself (the two sides of a one-pixel spur), a point lies on
    it at several arc lengths; the one nearest to a step after the previous point is
    taken, so a point off its stroke or a wrong step still shows.
    """
    a, b = path[:-1], path[1:]
    seg = b - a
    length = np.linalg.norm(seg, axis=1)
    s0 = np.concatenate([[0.0], np.cumsum(length)])
    out, last = [], -step
    for p in pts:
        t = np.clip(((p - a) * seg).sum(axis=1) / np.maximum(length**2, 1e-30), 0, 1)
        dist = np.linalg.norm(a + t[:, None] * seg - p, axis=1)
        cand = (s0[:-1] + t * length)[dist < 1e-7]
        assert len(cand), "a resampled point is off its stroke"
        last = float(cand[np.argmin(np.abs(cand - (last + step)))])
        out.append(last)
    return np.array(out)


def plan(mask: InkMask, pitch: float, outlines_first: bool) -> Toolpath | None:
    params = dataclasses.replace(PARAMS, pitch_mm=pitch, outlines_first=outlines_first)
    labels, n = ndimage.label(mask.ink, structure=np.ones((3, 3)))
    if not (np.bincount(labels.ravel())[1:] * RES**2 >= params.min_region_mm2).any():
        return None
    return plan_toolpath(mask, params, max_passes=20)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(masks(), st.sampled_from([0.5, 0.625, 1.2, 1.125, 2.0]), st.booleans())
def test_toolpath_properties(mask: InkMask, pitch: float, outlines_first: bool) -> None:
    tp = plan(mask, pitch, outlines_first)
    if tp is None:
        return
    params = dataclasses.replace(PARAMS, pitch_mm=pitch)
    strokes = tp.drawing.strokes

    # every hatch segment lies on ink
    t = np.linspace(0.0, 1.0, 64)[:, None]
    for s in strokes:
        if s.kind == StrokeKind.FILL:
            a, b = s.path_mm
            assert nearest_ink(mask, a + t * (b - a)).all()

    # every region gets an outline
    labels, _ = ndimage.label(mask.ink, structure=np.ones((3, 3)))
    big = int((np.bincount(labels.ravel())[1:] * RES**2 >= params.min_region_mm2).sum())
    assert tp.drawing.regions == big
    outer = {s.region for s in strokes if s.kind == StrokeKind.OUTER}
    assert outer == set(range(big))

    # every stroke once; with outlines_first, a region's outlines before its fill
    seq = tp.order.sequence
    assert np.array_equal(np.sort(seq), np.arange(len(strokes)))
    if outlines_first:
        kinds, regions = tp.drawing.kinds[seq], tp.drawing.region_of[seq]
        for r in range(tp.drawing.regions):
            outline = np.flatnonzero((regions == r) & (kinds != StrokeKind.FILL))
            fill = np.flatnonzero((regions == r) & (kinds == StrokeKind.FILL))
            if len(outline) and len(fill):
                assert outline.max() < fill.min()

    # no marking point above the surface
    uvz, kind = tp.path.uvz_mm, tp.path.kind
    assert np.all(uvz[kind == 1, 2] <= 0)
    assert np.all(uvz[kind == 2, 2] <= 0)

    # resampled steps are step_mm along each stroke, except its last (0, step]
    pts = tp.order.points(tp.drawing, params.step_mm)
    for pos, (sid, rev, seam) in enumerate(
        zip(tp.order.sequence, tp.order.reverse, tp.order.seam, strict=True)
    ):
        stroke, p = strokes[sid], pts[pos]
        chord = np.linalg.norm(np.diff(p, axis=0), axis=1)
        assert np.all(chord <= params.step_mm + 1e-9) and chord[-1] > 0
        if stroke.kind == StrokeKind.FILL:
            steps = chord
        else:  # closed loops end on their start point
            assert np.array_equal(p[0], p[-1])
            ring = stroke.path_mm[:-1]
            dense = np.vstack([ring[seam:], ring[: seam + 1]])
            steps = np.diff(arc_positions(dense[::-1] if rev else dense, p, params.step_mm))
        assert np.allclose(steps[:-1], params.step_mm, atol=1e-6)
        assert 0 < steps[-1] <= params.step_mm + 1e-6

    # the path draws exactly those points, stroke after stroke, except a hatch run that a
    # round turn trims (tattotronix/path/turns.py): its points lie on the run and reach to
    # within a turn radius (half a pitch) of each end
    for k, p in enumerate(pts):
        sub = uvz[(tp.path.stroke == k) & (kind != 0), :2]
        tail = sub[len(sub) - len(p) + 1 :]
        if len(tail) == len(p) - 1 and np.allclose(tail, p[1:]):
            assert len(sub) < len(p) or np.allclose(sub[len(sub) - len(p)], p[0])
            continue
        assert strokes[tp.order.sequence[k]].kind == StrokeKind.FILL
        a, b = p[0], p[-1]
        length = float(np.linalg.norm(b - a))
        d = (b - a) / length
        rel = sub - a
        along = (rel @ d)[np.abs(rel[:, 0] * d[1] - rel[:, 1] * d[0]) <= 1e-6]
        # (a straight drag into the run along its own line lies on it too, before its start)
        assert len(along) and along.max() <= length + 1e-6
        assert along.max() >= length - params.pitch_mm / 2 - 1e-6

    # the needle stays down between strokes only along a straight line on ink
    lifted = {int(tp.path.stroke[i]) for i in np.flatnonzero(kind == 2)}
    for k in range(1, len(pts)):
        if k not in lifted:
            a, b = pts[k - 1][-1], pts[k][0]
            assert nearest_ink(mask, a + t * (b - a)).all() or np.allclose(a, b)
