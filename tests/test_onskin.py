"""A design-plane needle path carried onto a curved surface (issue 33): the marking depth
and the clearance along the normal, the needle along the inward normal, strokes at equal
arc length on the surface, and no straight step that cuts into the skin or loses its
clearance."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tattotronix.errors import TattotronixError
from tattotronix.path.kinds import APPROACH, MARK, TRAVEL
from tattotronix.path.onskin import carry_path
from tattotronix.surface.cone import EllipticCone

CLEAR, PLUNGE, APPROACH_MM = 8.0, 1.5, 2.0


def _strokes_path(strokes: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """The panel's plunge, stroke and retract pattern (docs/toolpath.md, "The 3-D path")
    for each stroke, in the design plane."""
    pts: list[list[float]] = []
    kinds: list[int] = []
    for s in strokes:
        u, v = s[0]
        pts += [[u, v, CLEAR], [u, v, -PLUNGE + APPROACH_MM], [u, v, -PLUNGE]]
        kinds += [TRAVEL, TRAVEL, APPROACH]
        pts += [[a, b, -PLUNGE] for a, b in s[1:]]
        kinds += [MARK] * (len(s) - 1)
        pts.append([s[-1][0], s[-1][1], CLEAR])
        kinds.append(TRAVEL)
    return np.array(pts), np.array(kinds, np.int8)


def _line(rng: np.random.Generator, half: float, step: float = 0.3) -> np.ndarray:
    """A straight stroke sampled unevenly (steps of 0.5 to 1.5 ``step``)."""
    a, b = rng.uniform(-half, half, (2, 2))
    gaps = rng.uniform(0.5, 1.5, max(2, int(np.linalg.norm(b - a) / step)))
    t = np.concatenate(([0.0], np.cumsum(gaps) / gaps.sum()))
    return a + (b - a) * t[:, None]


def _heights(cone: EllipticCone, p: np.ndarray) -> np.ndarray:
    """Signed distances of limb-frame points ``p`` (N, 3) from the phantom's side (out:
    +): the foot of each on the surface by Newton's method on ``|X(x, theta) - p|^2``
    (with the surface's second derivatives: Gauss-Newton alone stalls a radius of
    curvature out)."""
    a, b = cone.semi_axes(p[:, 0])
    q = np.column_stack([p[:, 0], np.arctan2(p[:, 2] / b, p[:, 1] / a)])
    r, c = cone.depth_ratio, cone.slope
    for _ in range(60):
        x, th = q[:, 0], q[:, 1]
        a, b = cone.semi_axes(x)
        cos, sin = np.cos(th), np.sin(th)
        res = cone.point(x, th) - p
        jx = np.column_stack([np.ones_like(x), c * cos, r * c * sin])
        jt = np.column_stack([np.zeros_like(x), -a * sin, b * cos])
        xt = np.column_stack([np.zeros_like(x), -c * sin, r * c * cos])
        tt = np.column_stack([np.zeros_like(x), -a * cos, -b * sin])
        grad = np.column_stack([(jx * res).sum(1), (jt * res).sum(1)])
        hess = np.empty((len(x), 2, 2))
        hess[:, 0, 0] = (jx * jx).sum(1)
        hess[:, 0, 1] = hess[:, 1, 0] = (jx * jt).sum(1) + (xt * res).sum(1)
        hess[:, 1, 1] = (jt * jt).sum(1) + (tt * res).sum(1)
        q = q - np.linalg.solve(hess, grad[..., None])[..., 0]
    foot = cone.point(q[:, 0], q[:, 1])
    n = cone.normal(q[:, 0], q[:, 1])
    d = p - foot
    return np.linalg.norm(d, axis=1) * np.sign((d * n).sum(axis=1))


@settings(max_examples=12, deadline=None)
@given(elbow=st.floats(60, 100), taper=st.floats(0.6, 1.0), ratio=st.floats(0.6, 1.0),
       theta=st.floats(45, 135), rot=st.floats(-90, 90), seed=st.integers(0, 10_000))
def test_a_carried_path_keeps_depth_clearance_and_the_normal(
        elbow: float, taper: float, ratio: float, theta: float, rot: float,
        seed: int) -> None:
    cone = EllipticCone(220.0, elbow, elbow * taper, ratio)
    chart = cone.chart(110.0, theta, rot)
    rng = np.random.default_rng(seed)
    uvz, kind = _strokes_path([_line(rng, 14.0) for _ in range(3)])
    sk = carry_path(uvz, kind, chart, sag_mm=0.01)
    assert len(sk.xyz_mm) >= len(uvz)
    assert np.allclose(np.linalg.norm(sk.axis, axis=1), 1.0)
    # every point at its height along the normal: the marking depth in the skin, the
    # clearance over it (checked against the surface itself, not the chart)
    assert np.allclose(_heights(cone, sk.xyz_mm), sk.uvz_mm[:, 2], atol=1e-6)
    # the straight moves between points neither dig in nor lose clearance
    travel = np.flatnonzero((sk.kind[1:] == TRAVEL) & (sk.uvz_mm[1:, 2] == CLEAR)
                            & (sk.uvz_mm[:-1, 2] == CLEAR))
    assert len(travel) > 0
    mid = 0.5 * (sk.xyz_mm[travel] + sk.xyz_mm[travel + 1])
    assert (_heights(cone, mid) >= CLEAR - 0.011).all()
    # a stroke's steps are equal on the surface (the design's were uneven)
    marks = np.flatnonzero(sk.kind == MARK)
    runs = np.split(marks, np.flatnonzero(np.diff(marks) > 1) + 1)
    for run in runs:
        run = np.concatenate(([run[0] - 1], run))
        steps = np.linalg.norm(np.diff(sk.xyz_mm[run], axis=0), axis=1)
        assert steps.std() <= 1e-3 * steps.mean() + 1e-9
    # the needle's axis is the inward normal there
    out = sk.xyz_mm - 0.5 * sk.axis
    assert np.allclose(_heights(cone, out), sk.uvz_mm[:, 2] + 0.5, atol=1e-6)


def test_on_a_flat_chart_nothing_moves() -> None:
    """A cylinder's chart along its axis is straight: a path along the axis is carried
    rigidly, and no step needs splitting."""
    cone = EllipticCone(220.0, 80.0, 80.0, 1.0)
    chart = cone.chart(110.0, 90.0)
    line = np.column_stack([np.linspace(-20, 20, 101), np.zeros(101)])
    uvz, kind = _strokes_path([line])
    sk = carry_path(uvz, kind, chart)
    assert len(sk.xyz_mm) == len(uvz)
    assert np.allclose(sk.xyz_mm[:, 0], 110.0 + uvz[:, 0])
    assert np.allclose(sk.xyz_mm[:, 2], 40.0 + uvz[:, 2])
    assert np.allclose(sk.axis, [0.0, 0.0, -1.0])


def test_bad_paths_are_refused() -> None:
    chart = EllipticCone(220.0, 80.0, 55.0, 0.75).chart(200.0, 90.0)
    with pytest.raises(TattotronixError, match="N >= 2"):
        carry_path(np.zeros((1, 3)), np.zeros(1, np.int8), chart)
    with pytest.raises(TattotronixError, match="sag_mm"):
        carry_path(np.zeros((2, 3)), np.zeros(2, np.int8), chart, sag_mm=0.0)
    with pytest.raises(TattotronixError, match="falls"):  # past the wrist end
        carry_path(np.array([[0.0, 0.0, 8.0], [40.0, 0.0, 8.0]]), np.zeros(2, np.int8), chart)
