"""Angle intervals across the +-pi wrap, and the q-relaxed intersection."""

from __future__ import annotations

import math

import mpmath
import numpy as np
import pytest
from _iv_exact import mp
from hypothesis import given, settings
from hypothesis import strategies as st

import imubounds.interval as iv
from imubounds.errors import OptionError
from imubounds.interval import angles

INF = math.inf
TWO_PI = 2 * math.pi


def test_intersection_across_the_wrap() -> None:
    # [-3.2, -3.0] is [2 pi - 3.2, 2 pi - 3.0] = [3.0832, 3.2832] in the first
    # one's branch, which lies inside [3.0, 3.3]
    lo, hi = angles.angle_inter(3.0, 3.3, -3.2, -3.0)
    assert mp(lo) <= 2 * mpmath.pi - 3.2 and mp(hi) >= 2 * mpmath.pi - 3.0
    assert lo > 3.0831853 and hi < 3.2831854
    # and in the other branch
    lo, hi = angles.angle_inter(-3.2, -3.0, 3.0, 3.3)
    assert (lo, hi) == (-3.2, -3.0)
    # partial overlap across the cut: [3.0, 3.3] & [-3.1, 0] -> [2 pi - 3.1, 3.3]
    lo, hi = angles.angle_inter(3.0, 3.3, -3.1, 0.0)
    assert mp(lo) <= 2 * mpmath.pi - 3.1 and lo > 3.183 and hi == 3.3
    # really disjoint arcs
    assert angles.angle_inter(0.0, 1.0, 2.0, 3.0) == (INF, -INF)


def test_two_pieces_and_full_circle() -> None:
    # [-3, 3] and [2.9, 3.5]: overlap near +3 and (3.5 - 2 pi) near -3
    l1, h1, l2, h2 = angles.angle_inter_pieces(-3.0, 3.0, 2.9, 3.5)
    pieces = sorted([(l1, h1), (l2, h2)])
    assert pieces[0][0] == -3.0 and abs(pieces[0][1] - (3.5 - TWO_PI)) < 1e-15
    assert pieces[1] == (2.9, 3.0)
    assert angles.angle_inter(-3.0, 3.0, 2.9, 3.5) == (-3.0, 3.0)  # hull in a's branch
    full = (-4.0, 4.0)
    assert angles.angle_inter(*full, 1.0, 2.0) == (1.0, 2.0)
    assert angles.angle_inter(1.0, 2.0, *full) == (1.0, 2.0)
    assert angles.is_full(0.0, 7.0) and not angles.is_full(0.0, 6.0)


def test_wrap_and_contains() -> None:
    lo, hi = angles.wrap(7.0, 7.5)
    assert mp(lo) <= 7 - 2 * mpmath.pi and mp(hi) >= 7.5 - 2 * mpmath.pi and hi - lo < 0.5 + 1e-14
    assert angles.wrap(-1.0, 1.0) == (-1.0, 1.0)
    assert angles.wrap(0.0, 10.0) == (-iv.scalar.PI_HI, iv.scalar.PI_HI)
    assert angles.angle_contains(3.0, 3.3, -3.1)  # -3.1 + 2 pi = 3.18
    assert not angles.angle_contains(3.0, 3.3, 0.0)
    a = iv.IntervalArray([3.0, 0.0], [3.3, 1.0])
    assert angles.contains(a, [-3.1, 7.0]).tolist() == [True, True]  # 7 - 2 pi = 0.717


@settings(max_examples=300, deadline=None)
@given(st.floats(-20, 20), st.floats(0, 6), st.floats(-20, 20), st.floats(0, 6),
       st.floats(0, 1), st.integers(-3, 3))
def test_angle_intersection_keeps_every_common_angle(a, wa, b, wb, t, k) -> None:
    # a point of [a] that also lies in [b] + 2k pi must be in the result
    th = a + t * wa
    lo, hi = angles.angle_inter(a, a + wa, b, b + wb)
    shifted = mp(th) - 2 * k * mpmath.pi
    if mp(b) <= shifted <= mp(b + wb):
        assert lo <= th <= hi
    l1, h1, l2, h2 = angles.angle_inter_pieces(a, a + wa, b, b + wb)
    if mp(b) <= shifted <= mp(b + wb):
        assert (l1 <= th <= h1) or (l2 <= th <= h2)


def test_vectorised_angle_functions_match_scalar() -> None:
    rng = np.random.default_rng(1)
    alo = rng.uniform(-10, 10, 300)
    ahi = alo + rng.uniform(0, 7, 300)
    blo = rng.uniform(-10, 10, 300)
    bhi = blo + rng.uniform(0, 7, 300)
    r = angles.intersect(iv.IntervalArray(alo, ahi), iv.IntervalArray(blo, bhi))
    p1, p2 = angles.intersect_pieces(iv.IntervalArray(alo, ahi), iv.IntervalArray(blo, bhi))
    w = angles.wrap_array(iv.IntervalArray(alo, ahi))
    for i in range(300):
        assert angles.angle_inter(alo[i], ahi[i], blo[i], bhi[i]) == (r.lo[i], r.hi[i])
        assert angles.angle_inter_pieces(alo[i], ahi[i], blo[i], bhi[i]) == (
            p1.lo[i], p1.hi[i], p2.lo[i], p2.hi[i])
        assert angles.wrap(alo[i], ahi[i]) == (w.lo[i], w.hi[i])


# --- q-relaxed intersection -------------------------------------------------------


def _brute_1d(lo: np.ndarray, hi: np.ndarray, need: int) -> tuple[float, float]:
    pts = np.unique(np.r_[lo[lo <= hi], hi[lo <= hi]])
    cover = [int(((lo <= p) & (p <= hi)).sum()) for p in pts]
    ok = [p for p, cnt in zip(pts, cover, strict=True) if cnt >= need]
    return (min(ok), max(ok)) if ok else (INF, -INF)


@pytest.mark.parametrize("seed", range(30))
def test_qinter_1d_matches_brute_force(seed: int) -> None:
    rng = np.random.default_rng(seed)
    m = int(rng.integers(1, 9))
    lo = np.round(rng.uniform(0, 10, m), 1)
    hi = lo + np.round(rng.uniform(0, 4, m), 1)
    hi[rng.random(m) < 0.1] = -INF  # some empty boxes
    lo[hi == -INF] = INF
    for q in range(m + 1):
        r = iv.qinter(iv.IntervalArray(lo[:, None], hi[:, None]), q)
        exp = _brute_1d(lo, hi, m - q) if m - q > 0 else (-INF, INF)
        assert (float(r.lo[0]), float(r.hi[0])) == exp, (q, lo, hi)


def test_qinter_q0_is_intersection_and_q_ge_m_is_everything() -> None:
    b = iv.IntervalArray(np.array([[0.0, 0.0], [1.0, -1.0], [0.5, 0.2]]),
                         np.array([[2.0, 1.0], [3.0, 0.5], [2.5, 0.4]]))
    r = iv.qinter(b, 0)
    assert r.to_tuples() == [(1.0, 2.0), (0.2, 0.4)]
    assert iv.qinter(b, 3).to_tuples() == [(-INF, INF), (-INF, INF)]


def test_gps_outlier_is_tolerated() -> None:
    # four consistent position boxes and one outlier far away (x, y in m)
    lo = np.array([[0.0, 0.0], [1.0, 0.5], [0.5, 1.0], [0.2, 0.2], [50.0, 50.0]])
    hi = lo + 3.0
    boxes = iv.IntervalArray(lo, hi)
    assert iv.qinter(boxes, 0).is_empty().all()
    r = iv.qinter(boxes, 1)
    assert r.to_tuples() == [(1.0, 3.0), (1.0, 3.0)]
    assert iv.qinter(boxes, 1, method="exact").to_tuples() == [(1.0, 3.0), (1.0, 3.0)]
    assert iv.qinter_inliers(boxes, r).tolist() == [True, True, True, True, False]


@pytest.mark.parametrize("seed", range(20))
def test_qinter_exact_inside_per_dim_and_contains_all_qualifying_points(seed: int) -> None:
    rng = np.random.default_rng(100 + seed)
    m, n = int(rng.integers(2, 7)), 2
    lo = rng.uniform(0, 6, (m, n))
    hi = lo + rng.uniform(0.5, 4, (m, n))
    boxes = iv.IntervalArray(lo, hi)
    q = int(rng.integers(0, m))
    per = iv.qinter(boxes, q)
    ex = iv.qinter(boxes, q, method="exact")
    assert ex.subset(per).all()
    pts = rng.uniform(-1, 11, (4000, n))
    inside = ((lo[None] <= pts[:, None]) & (pts[:, None] <= hi[None])).all(axis=2)
    good = pts[inside.sum(axis=1) >= m - q]
    assert ((ex.lo <= good) & (good <= ex.hi)).all()
    assert ((per.lo <= good) & (good <= per.hi)).all()


def test_qinter_batched_and_errors() -> None:
    rng = np.random.default_rng(7)
    lo = rng.uniform(0, 5, (4, 10, 2))  # m=4 boxes, 10 time steps, 2 dims
    hi = lo + 3
    r = iv.qinter(iv.IntervalArray(lo, hi), 1)
    assert r.shape == (10, 2)
    for t in range(10):
        rt = iv.qinter(iv.IntervalArray(lo[:, t], hi[:, t]), 1)
        assert r[t] == rt
    re = iv.qinter(iv.IntervalArray(lo, hi), 1, method="exact")
    assert re.shape == (10, 2) and re.subset(r).all()
    with pytest.raises(OptionError):
        iv.qinter(iv.IntervalArray(lo, hi), -1)
    with pytest.raises(OptionError):
        iv.qinter(iv.IntervalArray(lo, hi), 1, method="magic")
    with pytest.raises(OptionError):
        iv.qinter(iv.IntervalArray(np.zeros((40, 1)), np.ones((40, 1))), 20, method="exact",
                  max_subsets=1000)
