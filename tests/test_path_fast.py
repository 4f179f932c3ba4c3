"""The vectorised toolpath routines give exactly what the former per-item routines gave.

Each former routine (one stroke, one outline, one greedy tour, one line at a time) is kept
here as the reference; the library's vectorised one must agree with it bit for bit on
random and on grid-aligned inputs (pixel centres, pixel edges and corners, where ties are).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from numpy.typing import NDArray

import tattotronix.path.costs as costs_mod
import tattotronix.path.order as order_mod
from tattotronix.art.grid import InkMask
from tattotronix.config.schema import MaskConfig, PanelConfig, ToolpathConfig
from tattotronix.path.costs import SAME_POINT_MM, TransitionCosts, can_drag
from tattotronix.path.inklookup import ink_at, lines_on_ink
from tattotronix.path.order import (
    _endpoints,
    _ends,
    _greedy,
    _greedy_near,
    _optimise_seams,
    _Precedence,
    _transitions,
    _two_opt,
    original_order,
)
from tattotronix.path.params import ToolpathParams
from tattotronix.path.path3d import APPROACH, MARK, TRAVEL, Path3D, build_path, build_path_flat
from tattotronix.path.plan import Toolpath, plan_toolpath
from tattotronix.path.polyline import (
    close,
    equal_chords,
    oriented,
    resample,
    resample_many,
    rotate_closed,
    smooth_closed,
)
from tattotronix.path.strokes import StrokeSet, build_drawing

from .test_toolpath_props import masks

RES = 0.25
PARAMS = ToolpathParams.from_settings(ToolpathConfig(), MaskConfig(), PanelConfig())


# ---------------------------------------------------------------- the former routines


def greedy_reference(costs: TransitionCosts, prec: _Precedence, first: int
                     ) -> tuple[NDArray[np.intp], NDArray[np.bool_]]:
    """One greedy tour, one stroke per step, as the planner did it before."""
    n = len(costs.pts) // 2
    visited = np.zeros(n, bool)
    remaining = np.bincount(prec.region[prec.outline], minlength=prec.regions)
    blocked = ~prec.outline & (remaining[prec.region] > 0) if prec.enabled else visited.copy()
    fills_of = [np.flatnonzero((prec.region == r) & ~prec.outline) for r in range(prec.regions)]
    seq, rev = np.empty(n, np.intp), np.empty(n, bool)
    cost = np.zeros((n, 2))
    i, o = divmod(first, 2)
    for k in range(n):
        if k > 0:
            cost[:] = costs.from_endpoint(2 * i + 1 - o).reshape(n, 2)
            cost[visited | blocked] = np.inf
            i, o = divmod(int(np.argmin(cost)), 2)
        seq[k], rev[k] = i, bool(o)
        visited[i] = True
        if prec.enabled and prec.outline[i]:
            r = prec.region[i]
            remaining[r] -= 1
            if remaining[r] == 0:
                blocked[fills_of[r]] = False
    return seq, rev


def seams_reference(
    drawing: StrokeSet, seq: NDArray[np.intp], rev: NDArray[np.bool_], seam: NDArray[np.intp],
    mask: InkMask, params: ToolpathParams, costs: TransitionCosts,
) -> NDArray[np.intp]:
    """Seams chosen one outline at a time, as the planner did it before."""
    seam = seam.copy()
    pts = costs.pts.copy()
    entry, exit_ = _ends(seq, rev)
    inv_mark = 1.0 / params.feed_mark_mm_s
    for k, s in enumerate(seq):
        stroke = drawing.strokes[int(s)]
        if not stroke.closed:
            continue
        ring = stroke.path_mm[:-1]
        total = np.zeros(len(ring))
        for q in ([pts[exit_[k - 1]]] if k > 0 else []) + (
            [pts[entry[k + 1]]] if k + 1 < len(seq) else []
        ):
            dist = np.linalg.norm(ring - q, axis=1)
            c = costs.lift(dist)
            near = np.flatnonzero(dist <= params.drag_max_mm)
            drag = near[can_drag(mask, np.broadcast_to(q, (len(near), 2)), ring[near],
                                 params.drag_max_mm)]
            c[drag] = dist[drag] * inv_mark
            total += c
        best = int(np.argmin(total))
        if total[best] < total[int(seam[s]) % len(ring)] - 1e-9:
            seam[s] = best
            pts[2 * s] = pts[2 * s + 1] = ring[best]
    return seam


def build_path_reference(strokes: Sequence[NDArray[np.float64]], mask: InkMask,
                         params: ToolpathParams, drag_max_mm: float | None = None) -> Path3D:
    """The 3-D path joined one stroke at a time, as the planner did it before (a drag in
    equal chords, as it is now)."""
    reach = params.drag_max_mm if drag_max_mm is None else drag_max_mm
    ends = np.array([s[-1] for s in strokes[:-1]]).reshape(-1, 2)
    starts = np.array([s[0] for s in strokes[1:]]).reshape(-1, 2)
    stay = can_drag(mask, ends, starts, reach)
    z_clear, z_app, z_mark = params.clearance_mm, params.approach_z_mm, params.mark_z_mm
    xy: list[NDArray[np.float64]] = []
    z: list[NDArray[np.float64]] = []
    kind: list[NDArray[np.int8]] = []
    idx: list[NDArray[np.int32]] = []

    def put(p: NDArray[np.float64], zz: float | NDArray[np.float64], k: int, s: int) -> None:
        p = np.atleast_2d(p)
        xy.append(p)
        z.append(np.broadcast_to(np.asarray(zz, dtype=np.float64), (len(p),)))
        kind.append(np.full(len(p), k, np.int8))
        idx.append(np.full(len(p), s, np.int32))

    for s, pts in enumerate(strokes):
        if s > 0 and stay[s - 1]:
            gap = equal_chords(ends[s - 1], pts[0], params.step_mm)[0][1:-1]
            if len(gap):
                put(gap, z_mark, MARK, s)
        else:
            if s > 0:
                put(ends[s - 1], z_clear, TRAVEL, s - 1)
            put(np.repeat(pts[:1], 2, axis=0), np.array([z_clear, z_app]), TRAVEL, s)
            put(pts[0], z_mark, APPROACH, s)
        put(pts, z_mark, MARK, s)
    put(strokes[-1][-1], z_clear, TRAVEL, len(strokes) - 1)
    uvz = np.column_stack([np.concatenate(xy), np.concatenate(z)])
    k, i = np.concatenate(kind), np.concatenate(idx)
    keep = np.concatenate([[True], np.linalg.norm(np.diff(uvz, axis=0), axis=1) > SAME_POINT_MM])
    gaps = np.linalg.norm(starts - ends, axis=1) > SAME_POINT_MM
    return Path3D(uvz[keep], k[keep], i[keep], int((stay & gaps).sum()))


# ---------------------------------------------------------------- inputs


@st.composite
def polylines(draw: st.DrawFn) -> list[NDArray[np.float64]]:
    """Polylines as the planner makes them: pixel loops smoothed and closed, fill
    segments, and odd ones (repeated vertices, a single point, grid-aligned steps)."""
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    out = []
    for _ in range(draw(st.integers(1, 12))):
        kind = int(rng.integers(5))
        n = int(rng.integers(1, 120))
        if kind == 0:
            p = rng.normal(size=(n, 2)) * rng.uniform(0.001, 50)
        elif kind == 1:
            walk = np.cumsum(rng.integers(-1, 2, size=(n, 2)), axis=0).astype(np.float64)
            p = close(smooth_closed(walk * RES))
        elif kind == 2:
            p = np.repeat(rng.normal(size=(1, 2)), n, axis=0)
        elif kind == 3:
            p = np.array([[0.0, 0.0], [float(rng.choice([0.3, 0.15, 0.45, 1.2, 1e-10])), 0.0]])
        else:
            p = np.cumsum(rng.choice([0.25, 0.5, 0.75, 0.15], size=(n, 2)), axis=0)
            p[rng.random(n) < 0.2] += 1e-10
        out.append(p)
    return out


# --- the former line-on-ink test: the reference of lines_on_ink ---------------------------

Arr = NDArray[Any]


def lines_on_ink_sampled(
    mask: InkMask, a_mm: NDArray[np.float64], b_mm: NDArray[np.float64], chunk: int = 1 << 20
) -> NDArray[np.bool_]:
    """:func:`lines_on_ink` by sampling (the former method, this file's reference).

    The nearest-pixel cells are the pixel squares, so the line is cut where it crosses a
    cell edge (x or y halfway between pixel centres); one sample inside each piece, plus
    the two ends, sees every pixel the line passes through, however small the corner it
    clips. A piece that only touches a cell corner is tested against every pixel there.

    Args:
        mask: the ink mask.
        a_mm: (n, 2) line starts, mm.
        b_mm: (n, 2) line ends, mm.
        chunk: samples evaluated at once (bounds memory).

    Returns:
        (n,) bool: every pixel the line passes through is ink.
    """
    a = np.asarray(a_mm, dtype=np.float64).reshape(-1, 2)
    b = np.asarray(b_mm, dtype=np.float64).reshape(-1, 2)
    out = np.ones(len(a), dtype=bool)
    if len(a) == 0:
        return out
    # endpoints in pixel units: u along columns, w along rows
    ua, ub = (a[:, 0] - mask.xs[0]) / mask.res_mm, (b[:, 0] - mask.xs[0]) / mask.res_mm
    wa, wb = (mask.ys[0] - a[:, 1]) / mask.res_mm, (mask.ys[0] - b[:, 1]) / mask.res_mm
    # cell edges crossed: k + 0.5 for k in [first, last]
    fu = np.ceil(np.minimum(ua, ub) - 0.5).astype(np.intp)
    nu = np.maximum(np.floor(np.maximum(ua, ub) - 0.5).astype(np.intp) - fu + 1, 0)
    fw = np.ceil(np.minimum(wa, wb) - 0.5).astype(np.intp)
    nw = np.maximum(np.floor(np.maximum(wa, wb) - 0.5).astype(np.intp) - fw + 1, 0)
    width = nu + nw + 2
    # one dense (lines x samples) array per power-of-two bucket of crossing counts
    bucket = np.ceil(np.log2(width)).astype(np.intp)
    for b_id in np.unique(bucket):
        group = np.flatnonzero(bucket == b_id)
        ku, kw = int(nu[group].max()), int(nw[group].max())
        step = max(1, chunk // (2 * (ku + kw + 2)))
        for i in range(0, len(group), step):
            g = group[i : i + step]
            out[g] = _pieces_on_ink(mask, a[g], b[g], ua[g], ub[g], wa[g], wb[g],
                                    fu[g], nu[g], fw[g], nw[g], ku, kw)
    return out


def _pieces_on_ink(mask: InkMask, a: Arr, b: Arr, ua: Arr, ub: Arr, wa: Arr, wb: Arr,
                   fu: Arr, nu: Arr, fw: Arr, nw: Arr, ku: int, kw: int) -> NDArray[np.bool_]:
    """:func:`lines_on_ink` for one block of lines with at most ku / kw edge crossings."""
    with np.errstate(divide="ignore", invalid="ignore"):
        ju = np.arange(ku)[None, :]
        tu = (fu[:, None] + ju + 0.5 - ua[:, None]) / (ub - ua)[:, None]
        tu[ju >= nu[:, None]] = np.nan
        jw = np.arange(kw)[None, :]
        tw = (fw[:, None] + jw + 0.5 - wa[:, None]) / (wb - wa)[:, None]
        tw[jw >= nw[:, None]] = np.nan
    n = len(a)
    t = np.sort(np.concatenate([np.zeros((n, 1)), np.ones((n, 1)), tu, tw], axis=1), axis=1)
    t = np.clip(t, 0.0, 1.0)
    mid = 0.5 * (t[:, 1:] + t[:, :-1])  # NaN after the last crossing
    samples = np.concatenate([t[:, :2], mid], axis=1)  # t = 0 and each piece (t = 1 in mid)
    samples = np.concatenate([samples, np.ones((n, 1))], axis=1)
    valid = ~np.isnan(samples)
    pts = a[:, None, :] + (b - a)[:, None, :] * np.where(valid, samples, 0.0)[:, :, None]
    return (ink_at(mask, pts) | ~valid).all(axis=1)


def _params(pitch: float, outlines_first: bool) -> ToolpathParams:
    return dataclasses.replace(PARAMS, pitch_mm=pitch, outlines_first=outlines_first)


def _drawing(mask: InkMask, params: ToolpathParams) -> StrokeSet | None:
    drawing = build_drawing(mask, params)
    return drawing if len(drawing.strokes) >= 2 else None


# ---------------------------------------------------------------- polylines


@settings(max_examples=80, deadline=None)
@given(polylines(), st.sampled_from([0.15, 0.05, 0.3, 0.25, 0.07, 1.0]), st.integers(0, 2**32 - 1))
def test_resample_many_is_resample(polys: list[NDArray[np.float64]], step: float,
                                   seed: int) -> None:
    rng = np.random.default_rng(seed)
    bounds = np.concatenate([[0], np.cumsum([len(p) for p in polys])]).astype(np.intp)
    closed = (rng.random(len(polys)) < 0.5) & (np.diff(bounds) >= 2)
    seam = rng.integers(0, 400, len(polys)) * (rng.random(len(polys)) < 0.7)
    rev = rng.random(len(polys)) < 0.5
    verts = np.concatenate(polys)
    out, ob = resample_many(verts[oriented(bounds, closed, seam, rev)], bounds, step)
    for i, p in enumerate(polys):
        path = rotate_closed(p, int(seam[i])) if closed[i] and seam[i] else p
        ref = resample(path[::-1] if rev[i] else path, step)
        assert np.array_equal(out[ob[i] : ob[i + 1]], ref)


# ---------------------------------------------------------------- lines on ink


def _grid_lines(mask: InkMask, rng: np.random.Generator, n: int, denominator: int
                ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Lines between points on a 1/denominator pixel lattice: through pixel centres, along
    pixel edges and through pixel corners."""
    h, w = mask.ink.shape
    lo = -2 * denominator
    ua = rng.integers(lo, w * denominator - lo, n) / denominator
    va = rng.integers(lo, h * denominator - lo, n) / denominator
    ub = ua + rng.integers(-8 * denominator, 8 * denominator, n) / denominator
    vb = va + rng.integers(-8 * denominator, 8 * denominator, n) / denominator
    a = np.column_stack([mask.xs[0] + ua * RES, mask.ys[0] - va * RES])
    b = np.column_stack([mask.xs[0] + ub * RES, mask.ys[0] - vb * RES])
    return a, b


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(masks(size=48), st.integers(0, 2**32 - 1), st.sampled_from([1, 2, 4, 16]))
def test_lines_on_ink_is_the_sampled_reading(mask: InkMask, seed: int, denominator: int
                                             ) -> None:
    rng = np.random.default_rng(seed)
    a, b = _grid_lines(mask, rng, 300, denominator)
    free_a = rng.uniform([mask.xs[0] - 1, mask.ys[-1] - 1], [mask.xs[-1] + 1, mask.ys[0] + 1],
                         (300, 2))
    free_b = free_a + rng.normal(0, 2, (300, 2))
    a, b = np.concatenate([a, free_a]), np.concatenate([b, free_b])
    assert np.array_equal(lines_on_ink(mask, a, b), lines_on_ink_sampled(mask, a, b))


def test_lines_on_ink_chunks_and_degenerate_lines() -> None:
    ink = np.zeros((20, 30), bool)
    ink[5:15, 5:25] = True
    mask = InkMask.centred(ink, RES)
    rng = np.random.default_rng(3)
    a, b = _grid_lines(mask, rng, 500, 2)
    b[:50] = a[:50]  # points
    want = lines_on_ink_sampled(mask, a, b)
    assert np.array_equal(lines_on_ink(mask, a, b), want)
    assert np.array_equal(lines_on_ink(mask, a, b, chunk=7), want)
    assert lines_on_ink(mask, np.zeros((0, 2)), np.zeros((0, 2))).shape == (0,)


# ---------------------------------------------------------------- ordering and the path


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(masks(), st.sampled_from([0.5, 1.2, 2.0]), st.booleans())
def test_ordering_steps_match_the_former_ones(mask: InkMask, pitch: float,
                                              outlines_first: bool) -> None:
    params = _params(pitch, outlines_first)
    drawing = _drawing(mask, params)
    if drawing is None:
        return
    n = len(drawing.strokes)
    seam = np.zeros(n, np.intp)
    costs = TransitionCosts(_endpoints(drawing, seam), mask, params)
    prec = _Precedence(drawing, outlines_first)
    may_start = prec.outline if prec.enabled and prec.outline.any() else np.ones(n, bool)
    ids = np.flatnonzero(np.repeat(may_start, 2))
    firsts = sorted({int(ids[0]), int(ids[-1]), int(ids[len(ids) // 2])})
    tours = _greedy(costs, prec, firsts)
    for first, (seq, rev) in zip(firsts, tours, strict=True):
        ref_seq, ref_rev = greedy_reference(costs, prec, first)
        assert np.array_equal(seq, ref_seq) and np.array_equal(rev, ref_rev)
    seq, rev, _, _ = _two_opt(costs, *tours[0], prec, 20)
    new_seam = _optimise_seams(drawing, seq, rev, seam, mask, params, costs)
    assert np.array_equal(new_seam, seams_reference(drawing, seq, rev, seam, mask, params, costs))
    # the costs after the seams moved: reusing the old ones changes nothing
    pts = _endpoints(drawing, new_seam)
    moved = np.any(pts != costs.pts, axis=1)
    fresh = TransitionCosts(pts, mask, params)
    reused = TransitionCosts(pts, mask, params, reuse=costs, moved=moved)
    for name in ("src", "dst", "key", "drag_s", "indptr"):
        assert np.array_equal(getattr(fresh, name), getattr(reused, name))
    full, again = fresh.matrix(), reused.matrix()
    if full is not None and again is not None:
        assert np.array_equal(full, again)
        assert np.array_equal(full[3], fresh.from_endpoint(3))


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(masks(), st.sampled_from([0.5, 1.2, 2.0]), st.booleans())
def test_build_path_matches_the_former_one(mask: InkMask, pitch: float, reverse: bool) -> None:
    params = _params(pitch, True)
    drawing = _drawing(mask, params)
    if drawing is None:
        return
    order = original_order(drawing)
    strokes = [s.points(params.step_mm, reverse=reverse) for s in drawing.strokes]
    for reach in (None, math.inf):
        want = build_path_reference(strokes, mask, params, reach)
        got = build_path(strokes, mask, params, reach)
        for name in ("uvz_mm", "kind", "stroke"):
            assert np.array_equal(getattr(got, name), getattr(want, name))
        assert got.drags == want.drags
    pts, bounds = order.resampled(drawing, params.step_mm)
    flat = build_path_flat(pts, bounds, mask, params)
    assert np.array_equal(flat.uvz_mm, build_path(order.points(drawing, params.step_mm), mask,
                                                  params).uvz_mm)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(masks(), st.sampled_from([0.5, 1.2]), st.booleans())
def test_large_drawing_ordering_near_the_full_one(mask: InkMask, pitch: float,
                                                  outlines_first: bool) -> None:
    """Above GREEDY_ROWS_MAX strokes the greedy finds its next stroke with a k-d tree (the
    same tours as the row-by-row greedy), and past TWO_OPT_FULL_WORK 2-opt scores the
    moves that join near endpoints (here forced on small drawings): it converges to an
    order no such move improves, never worse than the greedy's, the outlines still first.
    How close it comes to the full search is a benchmark's figure
    (benchmarks/bench_ordering.py: 0.007 % on 10,341 strokes), not a property: on a
    drawing of a few strokes the two searches can end in local optima 8 % apart."""
    params = _params(pitch, outlines_first)
    drawing = _drawing(mask, params)
    if drawing is None or len(drawing.strokes) < 2:
        return
    n = len(drawing.strokes)
    costs = TransitionCosts(_endpoints(drawing, np.zeros(n, np.intp)), mask, params)
    prec = _Precedence(drawing, outlines_first)
    may_start = prec.outline if prec.enabled and prec.outline.any() else np.ones(n, bool)
    ids = np.flatnonzero(np.repeat(may_start, 2))
    firsts = sorted({int(ids[0]), int(ids[-1])})
    for first, (seq, rev) in zip(firsts, _greedy(costs, prec, firsts), strict=True):
        near_seq, near_rev = _greedy_near(costs, prec, first)
        # the same cost (a tie between equally cheap strokes may pick another one)
        assert math.isclose(float(_transitions(costs, near_seq, near_rev).sum()),
                            float(_transitions(costs, seq, rev).sum()), rel_tol=1e-12)
        assert sorted(near_seq.tolist()) == list(range(n))
    seq, rev = _greedy(costs, prec, firsts[:1])[0]
    greedy = float(_transitions(costs, seq, rev).sum())
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(order_mod, "TWO_OPT_FULL_WORK", 0)
        near_seq, near_rev, passes, _ = _two_opt(costs, seq, rev, prec, 200)
        # converged: no move of the neighbour lists improves it any more
        assert passes < 200
        assert _two_opt(costs, near_seq, near_rev, prec, 1)[3] == 0
    near = float(_transitions(costs, near_seq, near_rev).sum())
    assert near <= greedy + 1e-9  # only improving moves are applied
    assert sorted(near_seq.tolist()) == list(range(n))
    if outlines_first:  # every fill row after all its region's outlines
        pos = np.empty(n, np.intp)
        pos[near_seq] = np.arange(n)
        for r in range(prec.regions):
            lines = np.flatnonzero(prec.outline & (prec.region == r))
            fills = np.flatnonzero(~prec.outline & (prec.region == r))
            if len(lines) and len(fills):
                assert pos[lines].max() < pos[fills].min()


def _same_plan(a: Toolpath, b: Toolpath) -> None:
    assert np.array_equal(a.order.sequence, b.order.sequence)
    assert np.array_equal(a.order.reverse, b.order.reverse)
    assert np.array_equal(a.order.seam, b.order.seam)
    assert np.array_equal(a.path.uvz_mm, b.path.uvz_mm)
    assert a.metrics == b.metrics and a.original == b.original
    assert a.metrics_dict() == b.metrics_dict()


@pytest.mark.parametrize("outlines_first", [True, False])
def test_plan_without_cost_matrices_is_the_same(monkeypatch: pytest.MonkeyPatch,
                                                outlines_first: bool) -> None:
    """Above MAX_MATRIX endpoints the costs are computed row by row: the same plan."""
    yy, xx = np.mgrid[0:160, 0:240]
    ink = np.zeros((160, 240), bool)
    for cx, cy in ((50, 50), (120, 60), (190, 110), (70, 120)):
        r = np.hypot(xx - cx, yy - cy)
        ink |= (r <= 30) & (r >= 12)
    ink[70:90, 20:220] = True
    mask = InkMask.centred(ink, RES)
    params = _params(1.2, outlines_first)
    full = plan_toolpath(mask, params)
    monkeypatch.setattr(costs_mod, "MAX_MATRIX", 0)
    _same_plan(full, plan_toolpath(mask, params))


@settings(max_examples=50, deadline=None)
@given(st.lists(st.tuples(st.floats(-50, 50), st.floats(-50, 50), st.floats(-50, 50),
                          st.floats(-50, 50)), min_size=1, max_size=8),
       st.sampled_from([0.05, 0.15, 0.6]))
def test_equal_chords_cut_each_drag_evenly(lines: list[tuple[float, float, float, float]],
                                           step: float) -> None:
    """Each line from its start to its end exactly, in ceil(length / step) chords of one
    length, none longer than the step (no remainder chord beside a corner); a line with
    no length is its one end point."""
    ab = np.array(lines, dtype=np.float64)
    a, b = ab[:, :2], ab[:, 2:]
    out, ob = equal_chords(a, b, step)
    for i in range(len(ab)):
        p = out[ob[i]:ob[i + 1]]
        d = float(np.linalg.norm(b[i] - a[i]))
        assert np.array_equal(p[-1], b[i])
        if d <= 1e-9:
            assert len(p) == 1
            continue
        chords = np.linalg.norm(np.diff(p, axis=0), axis=1)
        assert np.array_equal(p[0], a[i]) and len(chords) == math.ceil(d / step - 1e-9)
        assert chords.max() <= step + 1e-9 and np.ptp(chords) <= 1e-9
