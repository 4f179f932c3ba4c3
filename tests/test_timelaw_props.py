"""Property tests of the time law (:func:`time_parameterise`) on random jagged paths.

The paths are synthetic: a random planar tip polyline (m, z constant) of short steps and
sharp turns with straight runs between, mapped to five joints by a fixed smooth nonlinear
map (no robot model), with marking intervals at the feed (6 mm/s) under a tip
acceleration limit and travel intervals at 0.2 m/s without one.

What is tested:

* Limits: joint velocity, acceleration and (with a jerk limit) jerk at every sample,
  and the tip's acceleration on the marking points, within ``1e-6`` of the limit; the
  path speed within its cap (the feed).
* Rest to rest: the law starts at ``t = 0``, its clock strictly increases and it starts
  and ends at rest, exactly.
* Feed: on a 20 mm straight run between jagged stretches the law reaches the feed.
* Monotone: without a jerk limit a laxer tip limit, and no jerk limit instead of one,
  never make the law longer (2 %). With a jerk limit neither a laxer tip limit nor a
  laxer jerk limit is monotone: not asserted (the examples are below).
* Existence: a law is found on every path without a jerk limit, and a laxer jerk limit
  never fails where a stricter one succeeds.

Each case hypothesis once found failing (shrunk by hand) is pinned with ``@example``:
the feed exceeded next to travel, a last speed of -6e-18, a stall from a tip-limit
coefficient of 1e-13 where it is 0, and a laxer jerk limit refused.
* Bad input: a non-positive or NaN jerk limit is refused.
* Rests split the law: the whole path's law on each stretch between rests is the
  stretch's own, to the bit; the jerk filter of several laws at once is each alone's.
* The jerk filter's timing: each point's filtered time puts the window's mean position at
  the point (against a Gauss-Legendre quadrature of the unfiltered law), on random laws
  with rests and near-rest crawls and windows from 5 ms to 0.5 s.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, example, given, settings
from hypothesis import strategies as st
from numpy.typing import NDArray

from tattotronix.errors import TattotronixError
from tattotronix.trajectory import path_derivatives
from tattotronix.trajectory.timelaw import JointLimits, TimeLaw, TipLimit, time_parameterise

Array = NDArray[np.float64]
REL = 1e-6  # relative tolerance on every limit
FEED, TRAVEL = 0.006, 0.2  # m/s: the marking and the travel caps
LIMITS = JointLimits(tuple("abcde"), np.full(5, 1.5), np.full(5, 10.0))
TIPS = (0.1, 0.2, 0.4)  # m/s^2
JERKS = (None, 200.0, 500.0, 2000.0)  # rad/s^3
MAX_PTS = 200
_RNG = np.random.default_rng(20240611)
_LIN = _RNG.normal(size=(5, 3)) * 5.0  # rad/m: about 30 rad/m, 0.2 rad/s at the feed
_WAVE = _RNG.normal(size=(5, 3)) * 60.0  # 1/m: a wave of some 5 cm along the path
SLOW = settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])

Segment = tuple[float, float, int, bool]  # turn (deg), step (mm), steps, marking


def joints(p: Array) -> Array:
    """(N, 5) joint angles (rad) of tip points ``p`` (N, 3) in m: smooth, nonlinear."""
    return np.asarray(p @ _LIN.T + 0.2 * np.sin(p @ _WAVE.T))


@dataclass(frozen=True)
class Path:
    """A tip polyline, its arc length and its marking intervals."""

    p: Array  # (N, 3) m
    s: Array  # (N,) m
    on: NDArray[np.bool_]  # (N-1,)

    @classmethod
    def build(cls, segments: list[Segment], *, marking_only: bool = False,
              min_pts: int = 20, max_pts: int = MAX_PTS) -> Path:
        """Each segment turns by its angle, then takes its steps straight on."""
        pts, on, heading = [np.zeros(3)], [], 0.0
        for turn, step_mm, count, flag in segments:
            heading += math.radians(turn)
            d = step_mm * 1e-3 * np.array([math.cos(heading), math.sin(heading), 0.0])
            for _ in range(count):
                pts.append(pts[-1] + d)
                on.append(flag or marking_only)
        while len(pts) < min_pts:  # too short: a straight run on at the last step
            pts.append(2 * pts[-1] - pts[-2])
            on.append(on[-1])
        p = np.array(pts[:max_pts])
        s = np.concatenate(([0.0], np.cumsum(np.linalg.norm(np.diff(p, axis=0), axis=1))))
        return cls(p, s, np.array(on[:len(p) - 1], bool))


def plan(path: Path, tip_m_s2: float, jerk: float | None) -> tuple[TimeLaw, TipLimit]:
    """The time law of ``path`` at the feed (travel faster), and its tip limit."""
    dq, d2q = path_derivatives(joints(path.p), path.s)
    dp, d2p = path_derivatives(path.p, path.s)
    tip = TipLimit(dp, d2p, tip_m_s2, path.on)
    cap = np.where(tip.points(), FEED, TRAVEL)
    law = time_parameterise(path.s, dq, d2q, cap, LIMITS, tip=tip, jerk_rad_s3=jerk)
    return law, tip


def cap_of(path: Path) -> Array:
    """(N,) the path-speed cap :func:`plan` gives, m/s."""
    pts = np.zeros(len(path.s), bool)
    pts[:-1] |= path.on
    pts[1:] |= path.on
    return np.where(pts, FEED, TRAVEL)


# a turn (deg), then steps straight on (mm, mostly one, some long runs), marking or travel
runs = st.sampled_from((1, 1, 1, 1, 1, 1, 1, 1, 2, 3, 5, 10, 40))
segments = st.tuples(st.floats(-170.0, 170.0), st.floats(0.05, 0.5), runs, st.booleans())


@st.composite
def paths(draw: st.DrawFn) -> Path:
    """Random jagged paths of 20 to 200 points: all marking, or marking and travel."""
    segs = draw(st.lists(segments, min_size=19, max_size=MAX_PTS - 1))
    return Path.build(segs, marking_only=draw(st.booleans()))


def tip_accel_ends(law: TimeLaw, tip: TipLimit) -> Array:
    """(N-1,) the tip's largest acceleration magnitude at the two ends of each interval
    (the law without a jerk limit: constant path acceleration per interval)."""
    x = law.sdot**2
    u = np.diff(x) / (2.0 * np.diff(law.s))
    start = tip.d2p[:-1] * x[:-1, None] + tip.dp[:-1] * u[:, None]
    end = tip.d2p[1:] * x[1:, None] + tip.dp[1:] * u[:, None]
    return np.asarray(np.maximum(np.linalg.norm(start, axis=1), np.linalg.norm(end, axis=1)))


def plan_or_reject(path: Path, tip_m_s2: float, jerk: float | None) -> tuple[TimeLaw,
                                                                               TipLimit]:
    """:func:`plan`, where a refusal rejects the example: whether a law is found is the
    existence tests' property (below), not the one of the tests that use this."""
    try:
        return plan(path, tip_m_s2, jerk)
    except TattotronixError:
        assume(False)
        raise


# ----------------------------------------------------------------- limits


@SLOW
@given(path=paths(), tip_m_s2=st.sampled_from(TIPS), jerk=st.sampled_from(JERKS))
def test_every_limit_holds_at_every_sample(path: Path, tip_m_s2: float,
                                           jerk: float | None) -> None:
    law, tip = plan_or_reject(path, tip_m_s2, jerk)
    v, a = LIMITS.velocity * (1 + REL), LIMITS.acceleration * (1 + REL)
    assert np.all(np.abs(law.qd) <= v), np.abs(law.qd).max(axis=0)
    assert np.all(np.abs(law.qdd) <= a), np.abs(law.qdd).max(axis=0)
    assert np.all(np.abs(law.qdd_ends) <= a), np.abs(law.qdd_ends).max(axis=(0, 1))
    if jerk is not None:
        jk = np.abs(np.diff(law.qdd, axis=0) / np.diff(law.t)[:, None])
        assert np.all(jk <= jerk * (1 + REL)), jk.max(axis=0)
        marked = law.tip_accel[tip.points()]
    else:
        marked = tip_accel_ends(law, tip)[path.on]
    assert np.all(marked <= tip_m_s2 * (1 + REL)), marked.max()


# found by hypothesis (shrunk by hand): 0.5 mm of marking, then 1 mm of travel; at 0.2
# m/s^2 and 200 rad/s^3 the filter runs the marking point at 8.9 mm/s, the feed 6 mm/s
_FEED_AT_TRAVEL = Path.build([(0.0, 0.5, 1, True), (0.0, 0.5, 2, False)], min_pts=3)


@SLOW
@given(path=paths(), tip_m_s2=st.sampled_from(TIPS), jerk=st.sampled_from(JERKS))
@example(path=_FEED_AT_TRAVEL, tip_m_s2=0.2, jerk=200.0)
def test_the_feed_holds_at_every_sample(path: Path, tip_m_s2: float,
                                        jerk: float | None) -> None:
    law, _ = plan_or_reject(path, tip_m_s2, jerk)
    over = law.sdot / cap_of(path)
    assert np.all(over <= 1 + REL), (over.max(), int(over.argmax()))


# ----------------------------------------------------------------- rest to rest


@SLOW
@given(path=paths(), tip_m_s2=st.sampled_from(TIPS), jerk=st.sampled_from(JERKS))
def test_rest_to_rest(path: Path, tip_m_s2: float, jerk: float | None) -> None:
    law, _ = plan_or_reject(path, tip_m_s2, jerk)
    assert law.t[0] == 0.0 and np.all(np.isfinite(law.t)) and np.all(np.diff(law.t) > 0)
    assert law.sdot[0] == 0.0 and law.sdot[-1] == 0.0
    assert np.all(law.sdot >= 0.0)


# found by hypothesis: a 20-point straight line of 0.40625 mm steps, all travel; with a
# jerk limit the filter's last speed is -6.3e-18 m/s (rounding in the window's mean)
_ENDS_BELOW_REST = Path.build([(0.0, 0.40625, 1, False)])


@SLOW
@given(path=paths(), tip_m_s2=st.sampled_from(TIPS), jerk=st.sampled_from(JERKS[1:]))
@example(path=_ENDS_BELOW_REST, tip_m_s2=0.2, jerk=200.0)
def test_rest_to_rest_exactly(path: Path, tip_m_s2: float, jerk: float | None) -> None:
    law, _ = plan_or_reject(path, tip_m_s2, jerk)
    assert law.sdot[0] == 0.0 and law.sdot[-1] == 0.0, law.sdot[[0, -1]]
    assert np.all(law.sdot >= 0.0)


# ----------------------------------------------------------------- the feed


jagged = st.lists(st.tuples(st.floats(-170.0, 170.0), st.floats(0.05, 0.5), st.just(1),
                           st.just(True)), min_size=2, max_size=30)


@SLOW
@given(before=jagged, after=jagged, turn=st.floats(-170.0, 170.0),
       step_mm=st.floats(0.05, 0.5), tip_m_s2=st.sampled_from(TIPS),
       jerk=st.sampled_from(JERKS))
def test_marking_reaches_the_feed_on_a_straight_run(
        before: list[Segment], after: list[Segment], turn: float, step_mm: float,
        tip_m_s2: float, jerk: float | None) -> None:
    """A straight run of at least 20 mm between two jagged stretches: the law reaches
    the feed in its middle third, whatever the tip and jerk limits."""
    count = math.ceil(20.0 / step_mm)  # the run's steps
    k0, k1 = len(before), len(before) + count  # its first and last points
    path = Path.build([*before, (turn, step_mm, count, True), *after], min_pts=2,
                      max_pts=10**6)
    assert np.allclose(np.diff(path.s[k0:k1 + 1]), step_mm * 1e-3)
    assert path.s[k1] - path.s[k0] >= 0.02 * (1 - 1e-9)
    law, _ = plan_or_reject(path, tip_m_s2, jerk)
    middle = law.sdot[k0 + count // 3:k1 - count // 3 + 1]
    assert np.any(np.abs(middle - FEED) <= REL * FEED), (middle.max(), FEED)


# ----------------------------------------------------------------- rests split the path


@SLOW
@given(path=paths(), tip_m_s2=st.sampled_from(TIPS), jerk=st.sampled_from(JERKS),
       picks=st.lists(st.floats(0.05, 0.95), min_size=1, max_size=4))
def test_a_rest_splits_the_law_into_the_laws_of_its_stretches(
        path: Path, tip_m_s2: float, jerk: float | None, picks: list[float]) -> None:
    """Rests decouple the law: the whole path's law, on each stretch between rests, is
    that stretch's own law (timed alone, from rest to rest), to the bit in speed and
    acceleration. The jerk filter relies on it: it solves the whole path once, and
    filters and repairs every stretch in one batch."""
    n = len(path.s)
    rests = np.unique([int(round(p * (n - 1))) for p in picks])
    rests = rests[(rests > 1) & (rests < n - 2)]
    assume(rests.size and np.all(np.diff(rests) > 2))
    dq, d2q = path_derivatives(joints(path.p), path.s)
    dp, d2p = path_derivatives(path.p, path.s)
    tip = TipLimit(dp, d2p, tip_m_s2, path.on)
    cap = np.where(tip.points(), FEED, TRAVEL)
    try:
        whole = time_parameterise(path.s, dq, d2q, cap, LIMITS, tip=tip, jerk_rad_s3=jerk,
                                  rests=rests)
    except TattotronixError:
        assume(False)
        raise
    bounds = np.concatenate(([0], rests, [n - 1]))
    for lo, hi in zip(bounds[:-1], bounds[1:], strict=True):
        part = slice(int(lo), int(hi) + 1)
        alone = time_parameterise(path.s[part], dq[part], d2q[part], cap[part], LIMITS,
                                  tip=tip.slice(part), jerk_rad_s3=jerk)
        assert np.array_equal(whole.sdot[part], alone.sdot)
        inner = slice(int(lo) + 1, int(hi))  # a rest's acceleration joins two stretches
        assert np.array_equal(whole.sddot[inner], alone.sddot[1:-1])
        assert np.allclose(whole.t[part] - whole.t[lo], alone.t, rtol=1e-12, atol=1e-15)


@given(seed=st.integers(0, 2**32 - 1), count=st.integers(1, 6))
@settings(max_examples=30, deadline=None)
def test_the_batched_filter_is_each_filter_alone(seed: int, count: int) -> None:
    """The jerk filter of several laws at once (what the repairs run) is, law by law, the
    filter of each alone, bit for bit, each with its own window."""
    from tattotronix.trajectory.timelaw import _box_filter_law, _box_filter_laws

    rng = np.random.default_rng(seed)
    laws, windows = [], []
    for _ in range(count):
        n = int(rng.integers(3, 60))
        x = np.concatenate(([0.0], rng.uniform(1e-6, 0.04, n - 2) ** 2, [0.0]))
        h = rng.uniform(1e-5, 5e-3, n - 1)
        s = float(rng.uniform(0.0, 0.5)) + np.concatenate(([0.0], np.cumsum(h)))
        v = np.sqrt(x)
        t = np.concatenate(([0.0], np.cumsum(2 * h / (v[:-1] + v[1:]))))
        laws.append((t, s, v, np.diff(x) / (2 * h)))
        windows.append(float(rng.choice((0.005, 0.05, 0.5))))
    batched = _box_filter_laws(laws, windows)
    for law, window, got in zip(laws, windows, batched, strict=True):
        for a, b in zip(_box_filter_law(*law, window), got, strict=True):
            assert np.array_equal(a, b)


# ----------------------------------------------------------------- monotone in the limits
#
# Not asserted, because not true (examples on this file's paths; durations in s):
#
# * With a jerk limit, a laxer tip limit can make the law longer: the filter's window
#   grows with the law's own largest path acceleration, which the tip limit bounds. A
#   0.95 mm straight line of 0.05 mm steps, all marking, jerk 200:
#   ``Path.build([(0.0, 0.05, 19, True)])`` takes 0.2427, 0.2352, 0.2591 at a tip limit
#   of 0.1, 0.2, 0.4 m/s^2 (0.4 is 10 % slower than 0.2).
# * A laxer jerk limit can make the law longer: the 3 mm straight line
#   ``Path.build([(0.0, 0.5, 2, False), (0.0, 0.5, 4, True)], min_pts=3)`` (1 mm travel,
#   2 mm marking) at tip 0.2 takes 0.6192, 0.6713, 0.6764 at jerk 200, 500, 1000 (8 %
#   slower at 500 than at 200). On one random 104-point path (18 % marking) at tip 0.1,
#   jerk 2000 took 166 s against 2.5 s at 500: 52 repairs lowered the caps towards 0.


@SLOW
@given(path=paths())
def test_a_laxer_tip_limit_is_never_slower_without_a_jerk_limit(path: Path) -> None:
    durations = [plan_or_reject(path, a, None)[0].duration_s for a in TIPS]
    for strict, lax in zip(durations, durations[1:], strict=False):
        assert lax <= strict * 1.02, durations


@SLOW
@given(path=paths(), tip_m_s2=st.sampled_from(TIPS), jerk=st.sampled_from(JERKS[1:]))
def test_no_jerk_limit_is_never_slower_than_one(path: Path, tip_m_s2: float,
                                                jerk: float) -> None:
    limited = plan_or_reject(path, tip_m_s2, jerk)[0].duration_s
    free = plan_or_reject(path, tip_m_s2, None)[0].duration_s
    assert free <= limited * 1.02, (free, limited)


# ----------------------------------------------------------------- existence

# found by hypothesis (shrunk by hand): 0.07 mm of travel, a right angle, 0.07 mm and
# 0.35 mm of marking, tip 0.1. Point 1 sits at the speed cap set by the tip channel
# normal to the path (theta = pi/2), whose coefficient of x_{i+1} is c cos(pi/2) / 2h,
# about 1e-13, not 0: the forward bound divides by it, cancels to -3e-5 and finds nothing
# reachable; the backward pass sets point 1 to rest, and the repeated passes keep it there.
# (Zeroing that coefficient in TipLimit.channels mends this example.)
_STALL = Path.build([(0.0, 0.07, 1, False), (90.0, 0.07, 1, True), (0.0, 0.35, 1, True)],
                    min_pts=3)


@SLOW
@given(path=paths(), tip_m_s2=st.sampled_from(TIPS))
@example(path=_STALL, tip_m_s2=0.1)
def test_a_law_exists_without_a_jerk_limit(path: Path, tip_m_s2: float) -> None:
    plan(path, tip_m_s2, None)


# found by hypothesis (shrunk by hand): a 3 mm straight line, 1 mm travel then marking, tip
# 0.1: jerk 200, 500 and 1000 are met, 2000 is refused after 60 repairs (the first marking
# point keeps 1.33 times the tip limit: the travel speed before it is never lowered)
_LAX_JERK_REFUSED = Path.build([(0.0, 0.5, 2, False), (0.0, 0.5, 4, True)], min_pts=3)


@SLOW
@given(path=paths(), tip_m_s2=st.sampled_from(TIPS))
@example(path=_LAX_JERK_REFUSED, tip_m_s2=0.1)
def test_a_laxer_jerk_limit_never_fails_where_a_stricter_one_succeeds(
        path: Path, tip_m_s2: float) -> None:
    met: list[float] = []
    for jerk in JERKS[1:]:
        try:
            plan(path, tip_m_s2, jerk)
            met.append(jerk)
        except TattotronixError as err:
            assert not met, f"jerk {jerk:g} refused, {met} met: {err}"


# ----------------------------------------------------------------- bad input


@settings(max_examples=25, deadline=None)
@given(jerk=st.one_of(st.floats(max_value=0.0), st.just(math.nan)))
def test_a_non_positive_or_nan_jerk_limit_is_refused(jerk: float) -> None:
    path = Path.build([(0.0, 0.3, 30, True)])
    with pytest.raises(TattotronixError, match="jerk limit must be a positive number"):
        plan(path, 0.2, jerk)


@given(seed=st.integers(0, 2**32 - 1), window=st.sampled_from((0.005, 0.05, 0.5)))
@settings(max_examples=40, deadline=None)
def test_the_filter_puts_each_point_where_the_window_averages_it(seed: int,
                                                                 window: float) -> None:
    """The jerk filter's timing (Halley's method with a bisection guard): at each point's
    filtered time the window's mean position is the point's own, against an independent
    quadrature; its times strictly increase; its speed is the window's mean speed."""
    from tattotronix.trajectory.timelaw import _box_filter_law

    rng = np.random.default_rng(seed)
    n = int(rng.integers(3, 60))
    x = np.concatenate(([0.0], rng.uniform(1e-6, 0.04, n - 2) ** 2, [0.0]))  # sdot^2
    if rng.random() < 0.5:
        x[1:-1] = np.maximum(x[1:-1], 1e-4)
    h = rng.uniform(1e-5, 5e-3, n - 1)
    s = np.concatenate(([0.0], np.cumsum(h)))
    v = np.sqrt(x)
    u = np.diff(x) / (2 * h)
    t = np.concatenate(([0.0], np.cumsum(2 * h / (v[:-1] + v[1:]))))
    tf, sdot_f, _ = _box_filter_law(t, s, v, u, window)
    assert np.all(np.diff(tf) > 0)
    assert tf[0] == 0.0 and tf[-1] == pytest.approx(t[-1] + window, abs=1e-12)

    def pos(tq: Array) -> Array:  # the unfiltered law, at rest outside [0, t_end]
        k = np.clip(np.searchsorted(t, tq, side="right") - 1, 0, n - 2)
        tau = np.clip(tq, 0.0, t[-1]) - t[k]
        return np.asarray(s[k] + v[k] * tau + u[k] * tau**2 / 2)

    # Gauss-Legendre on every piece the window meets: exact for the law's quadratics
    nodes, weights = np.polynomial.legendre.leggauss(3)
    for i in range(1, n - 1):
        a, b = tf[i] - window, tf[i]
        cuts = np.unique(np.concatenate(([a, b], t[(t > a) & (t < b)])))
        lo, hi = cuts[:-1, None], cuts[1:, None]
        pts = (lo + hi) / 2 + (hi - lo) / 2 * nodes
        mean = float(np.sum((hi - lo) / 2 * weights * pos(pts))) / window
        assert mean == pytest.approx(s[i], abs=1e-12 + 1e-9 * s[-1])
        assert sdot_f[i] == pytest.approx((pos(np.array([b]))[0] - pos(np.array([a]))[0])
                                          / window, rel=1e-9, abs=1e-12)
