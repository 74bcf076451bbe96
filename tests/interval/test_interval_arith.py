"""Interval arithmetic: special values, empty propagation, division by zero,
scalar == vector, inclusion property (hypothesis, exact), constructors."""

from __future__ import annotations

import itertools
import math
from fractions import Fraction

import mpmath
import numpy as np
import pytest
from _hc4 import hc4_add
from _iv_exact import MAXF, mp
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from numba import njit

import imubounds.interval as iv
from imubounds.errors import OptionError
from imubounds.interval import _core as c
from imubounds.interval import _vec as v

INF = math.inf
TINY = 5e-324
SPECIAL = [-INF, -MAXF, -1e300, -3.0, -1.0, -1e-300, -TINY, -0.0, 0.0, TINY, 1e-300, 0.5,
           1.0, math.pi, 1e300, MAXF, INF]
SPECIAL_IV = [(a, b) for a, b in itertools.combinations_with_replacement(SPECIAL, 2)
              if a <= b and not (a == b and math.isinf(a))] + [(INF, -INF)]

UNARY = ["neg", "absval", "sqr", "sqrt", "sin", "cos"]
BINARY = ["add", "sub", "mul", "div", "atan2", "inter", "hull"]


def _grid_binary():
    pairs = list(itertools.product(SPECIAL_IV, SPECIAL_IV))
    a = np.array([p[0] for p in pairs])
    b = np.array([p[1] for p in pairs])
    return a[:, 0].copy(), a[:, 1].copy(), b[:, 0].copy(), b[:, 1].copy()


def _wellformed(lo: np.ndarray, hi: np.ndarray) -> None:
    assert not np.isnan(lo).any() and not np.isnan(hi).any()
    empty = ~(lo <= hi)
    assert np.all(lo[empty] == INF) and np.all(hi[empty] == -INF)
    ok = ~empty
    assert not np.any((lo[ok] == INF) | (hi[ok] == -INF))


@pytest.mark.parametrize("op", BINARY)
def test_binary_special_values_wellformed_and_scalar_equals_vector(op: str) -> None:
    alo, ahi, blo, bhi = _grid_binary()
    lo, hi = getattr(v, f"v_{op}")(alo, ahi, blo, bhi)
    _wellformed(lo, hi)
    f = getattr(c, op)
    for i in range(0, alo.size, 7):
        s = f(alo[i], ahi[i], blo[i], bhi[i])
        assert (s[0], s[1]) == (lo[i], hi[i]) or (math.isnan(s[0]) and math.isnan(lo[i]))
    # empty in -> empty out (hull: the other operand)
    e = (alo == INF) | (blo == INF)
    if op == "hull":
        both = (alo == INF) & (blo == INF)
        assert np.all(lo[both] == INF)
    else:
        assert np.all(lo[e] == INF) and np.all(hi[e] == -INF)


@pytest.mark.parametrize("op", UNARY)
def test_unary_special_values_wellformed_and_scalar_equals_vector(op: str) -> None:
    lo0 = np.array([p[0] for p in SPECIAL_IV])
    hi0 = np.array([p[1] for p in SPECIAL_IV])
    lo, hi = getattr(v, f"v_{op}")(lo0, hi0)
    _wellformed(lo, hi)
    f = getattr(c, op)
    for i in range(lo0.size):
        assert f(lo0[i], hi0[i]) == (lo[i], hi[i])
    e = lo0 == INF
    assert np.all(lo[e] == INF) and np.all(hi[e] == -INF)


def _finite_points(lo: float, hi: float) -> list[float]:
    lo, hi = float(lo), float(hi)
    pts = [x for x in (lo, hi) if math.isfinite(x)]
    if math.isinf(lo) and math.isinf(hi):
        pts += [-1e200, 0.0, 2.5]
    elif math.isinf(lo):
        pts += [hi - abs(hi) - 1.0, hi * 2 if hi < 0 else -1e200]
    elif math.isinf(hi):
        pts += [lo + abs(lo) + 1.0, 1e200 if lo < 1e200 else MAXF]
    else:
        pts.append(0.5 * lo + 0.5 * hi)
    return [p for p in pts if lo <= p <= hi and math.isfinite(p)]


@pytest.mark.parametrize("op", ["add", "sub", "mul", "div"])
def test_special_values_contain_exact_point_results(op: str) -> None:
    alo, ahi, blo, bhi = _grid_binary()
    lo, hi = getattr(v, f"v_{op}")(alo, ahi, blo, bhi)
    for i in range(alo.size):
        if alo[i] == INF or blo[i] == INF:
            continue
        for x in _finite_points(alo[i], ahi[i]):
            for y in _finite_points(blo[i], bhi[i]):
                X, Y = Fraction(x), Fraction(y)
                if op == "div" and Y == 0:
                    continue
                r = {"add": X + Y, "sub": X - Y, "mul": X * Y}.get(op) if op != "div" else X / Y
                assert (lo[i] == -INF or Fraction(lo[i]) <= r), (op, alo[i], ahi[i], blo[i], bhi[i])
                assert (hi[i] == INF or Fraction(hi[i]) >= r), (op, alo[i], ahi[i], blo[i], bhi[i])


@pytest.mark.parametrize(
    ("a", "b", "expected"),
    [
        ((1.0, 2.0), (0.0, 0.0), (INF, -INF)),  # division by {0}: empty
        ((0.0, 0.0), (0.0, 0.0), (INF, -INF)),
        ((0.0, 0.0), (-1.0, 1.0), (0.0, 0.0)),
        ((1.0, 2.0), (-1.0, 1.0), (-INF, INF)),  # hull of two half-lines
        ((1.0, 2.0), (0.0, 4.0), (0.25, INF)),
        ((1.0, 2.0), (-4.0, 0.0), (-INF, -0.25)),
        ((-2.0, -1.0), (0.0, 4.0), (-INF, -0.25)),
        ((-2.0, -1.0), (-4.0, 0.0), (0.25, INF)),
        ((0.0, 2.0), (0.0, 4.0), (0.0, INF)),
        ((-2.0, 0.0), (0.0, 4.0), (-INF, 0.0)),
        ((-2.0, 3.0), (0.0, 4.0), (-INF, INF)),
        ((1.0, 1.0), (3.0, 3.0), (float.fromhex("0x1.5555555555555p-2"),
                                  float.fromhex("0x1.5555555555556p-2"))),
        ((1.0, 2.0), (-INF, -1.0), (-2.0, -0.0)),
        ((-INF, INF), (1.0, 2.0), (-INF, INF)),
    ],
)
def test_division_cases(a, b, expected) -> None:
    r = c.div(a[0], a[1], b[0], b[1])
    assert r == expected
    R = iv.IntervalArray(*a) / iv.IntervalArray(*b)
    assert (float(R.lo), float(R.hi)) == expected


def test_relational_division_two_pieces() -> None:
    # {x : x*y in [1,2], y in [-1, 2]} = (-inf, -1] U [0.5, inf)
    assert c.div_rel(1.0, 2.0, -1.0, 2.0) == (-INF, -1.0, 0.5, INF)
    # y and z both contain 0: any x
    assert c.div_rel(-1.0, 2.0, 0.0, 0.0) == (-INF, INF, INF, -INF)
    assert c.div_rel(1.0, 2.0, 0.0, 0.0) == (INF, -INF, INF, -INF)


def test_textbook_sin_and_cos_extrema_are_exact() -> None:
    assert c.sin(0.0, c.PI_LO) == (0.0, 1.0)
    assert c.sin(0.0, c.PI_HI)[1] == 1.0 and c.sin(0.0, c.PI_HI)[0] < 0  # sin(pi_hi) < 0
    assert c.cos(-1.0, 1.0)[1] == 1.0
    assert c.cos(3.0, 3.5)[0] == -1.0
    assert c.sin(-1e20, -1e20 + 1e5) == (-1.0, 1.0)  # huge arguments: honest full range
    lo, hi = c.sin(1.0, 1.0)
    assert lo < hi and mp(lo) <= mpmath.sin(1) <= mp(hi)


def test_exact_results_stay_exact() -> None:
    assert c.add(1.0, 2.0, 3.0, 4.0) == (4.0, 6.0)
    assert c.mul(1.5, 2.0, 2.0, 4.0) == (3.0, 8.0)
    assert c.div(1.0, 2.0, 4.0, 8.0) == (0.125, 0.5)
    assert c.sqrt(4.0, 9.0) == (2.0, 3.0)
    assert c.atan2(0.0, 0.0, 1.0, 2.0) == (0.0, 0.0)


def test_domains_of_partial_functions() -> None:
    assert c.sqrt(-2.0, -1.0) == (INF, -INF)
    assert c.sqrt(-2.0, 4.0) == (0.0, 2.0)
    assert c.asin(2.0, 3.0) == (INF, -INF)
    assert c.atan2(0.0, 0.0, 0.0, 0.0) == (INF, -INF)  # atan2(0, 0) undefined


def test_atan2_branch_cases() -> None:
    lo, hi = c.atan2(-1.0, 1.0, -2.0, -1.0)  # crosses the negative x axis
    assert lo == -c.PI_HI and hi == c.PI_HI
    lo, hi = c.atan2(0.0, 1.0, -2.0, -1.0)  # touches it from above only
    assert mp(lo) <= 3 * mpmath.pi / 4 and lo > 2.356 and hi == c.PI_HI
    lo, hi = c.atan2(0.0, 0.0, -1.0, 1.0)  # y = 0, x in [-1, 1]: {0, pi}
    assert lo == 0.0 and hi == c.PI_HI
    lo, hi = c.atan2(0.0, 1.0, 0.0, 1.0)
    assert lo == 0.0 and mp(hi) >= mpmath.pi / 2 and hi < 1.5707963267949


def test_set_operations_and_predicates() -> None:
    a = iv.IntervalArray([1.0, 0.0, INF], [2.0, 1.0, -INF])
    b = iv.IntervalArray([1.5, 2.0, 0.0], [3.0, 3.0, 1.0])
    r = a & b
    assert r.to_tuples() == [(1.5, 2.0), (INF, -INF), (INF, -INF)]
    h = a | b
    assert h.to_tuples() == [(1.0, 3.0), (0.0, 3.0), (0.0, 1.0)]
    assert a.is_empty().tolist() == [False, False, True]
    w = a.width()
    assert w[0] == 1.0 and w[1] == 1.0 and math.isnan(w[2])
    assert a.mid()[0] == 1.5 and math.isnan(a.mid()[2])
    assert a.radius()[0] == 0.5
    assert a.contains(1.0).tolist() == [True, True, False]
    assert a.subset(b).tolist() == [False, False, True]  # empty is a subset of everything
    e = iv.IntervalArray.entire(())
    assert float(e.mid()) == 0.0
    assert abs(iv.I(-3, 2)).to_tuples() == [(0.0, 3.0)]
    assert (iv.I(-1, 2) ** 2).to_tuples() == [(0.0, 4.0)]


def test_constructor_rejects_bad_input() -> None:
    with pytest.raises(OptionError):
        iv.IntervalArray(2.0, 1.0)
    with pytest.raises(OptionError):
        iv.IntervalArray(float("nan"), 1.0)
    with pytest.raises(OptionError):
        iv.IntervalArray(INF, INF)
    assert iv.IntervalArray(INF, -INF).is_empty()


def test_pi_encloses_pi() -> None:
    p = iv.pi()
    assert mp(float(p.lo)) < mpmath.pi < mp(float(p.hi))
    assert float(p.hi) == math.nextafter(float(p.lo), INF)


def test_scalar_rules_run_inside_numba_and_match_arrays() -> None:
    @njit
    def integrate(rate_lo, rate_hi, dt):  # heading += rate * dt, rate an interval
        lo = 0.0
        hi = 0.0
        for i in range(rate_lo.size):
            dlo, dhi = c.mul(rate_lo[i], rate_hi[i], dt, dt)
            lo, hi = c.add(lo, hi, dlo, dhi)
        return lo, hi

    rng = np.random.default_rng(0)
    r = rng.normal(0.0, 0.1, 1000)
    lo, hi = integrate(r - 0.01, r + 0.01, 0.1)
    acc = iv.IntervalArray(0.0)
    R = iv.IntervalArray(r - 0.01, r + 0.01) * 0.1
    for i in range(r.size):
        acc = acc + R[i]
    assert (lo, hi) == (float(acc.lo), float(acc.hi))
    exact = sum(Fraction(x) for x in (r * 0.1).tolist())
    assert Fraction(lo) <= exact <= Fraction(hi)


# --- inclusion property with hypothesis (exact references) ---------------------

finite = st.floats(min_value=-1e12, max_value=1e12, allow_nan=False, allow_infinity=False)


@st.composite
def interval_and_point(draw, lo_min=-1e12, hi_max=1e12):
    a = draw(st.floats(min_value=lo_min, max_value=hi_max))
    b = draw(st.floats(min_value=lo_min, max_value=hi_max))
    lo, hi = min(a, b), max(a, b)
    t = draw(st.floats(min_value=0.0, max_value=1.0))
    p = lo + t * (hi - lo)
    p = min(max(p, lo), hi)
    return lo, hi, p


def _inside(lo: float, hi: float, exact) -> bool:
    return (lo == -INF or mp(lo) <= exact) and (hi == INF or exact <= mp(hi))


@settings(max_examples=300, deadline=None)
@given(interval_and_point(), interval_and_point(), st.sampled_from(["add", "sub", "mul", "div"]))
def test_inclusion_arith(x, y, op) -> None:
    xl, xh, p = x
    yl, yh, q = y
    lo, hi = getattr(c, op)(xl, xh, yl, yh)
    P, Q = Fraction(p), Fraction(q)
    if op == "div" and Q == 0:
        return
    r = {"add": lambda: P + Q, "sub": lambda: P - Q, "mul": lambda: P * Q,
         "div": lambda: P / Q}[op]()
    assert (lo == -INF or Fraction(lo) <= r) and (hi == INF or r <= Fraction(hi))


@settings(max_examples=300, deadline=None)
@given(interval_and_point(-800.0, 800.0),
       st.sampled_from(["sqr", "sqrt", "sin", "cos", "absval", "neg"]))
def test_inclusion_unary(x, op) -> None:
    lo0, hi0, p = x
    if op == "sqrt":
        assume(p >= 0)
    lo, hi = getattr(c, op)(lo0, hi0)
    P = mp(p)
    f = {"sqr": lambda t: t * t, "sqrt": mpmath.sqrt, "sin": mpmath.sin, "cos": mpmath.cos,
         "absval": abs, "neg": lambda t: -t}[op]
    assert _inside(lo, hi, f(P)), (op, lo0, hi0, p, lo, hi)


@settings(max_examples=300, deadline=None)
@given(interval_and_point(-1.5, 1.5))
def test_inclusion_asin(x) -> None:
    lo0, hi0, p = x
    assume(-1.0 <= p <= 1.0)
    lo, hi = c.asin(lo0, hi0)
    assert _inside(lo, hi, mpmath.asin(mp(p))), (lo0, hi0, p, lo, hi)


@settings(max_examples=300, deadline=None)
@given(interval_and_point(-10.0, 10.0), interval_and_point(-10.0, 10.0))
def test_inclusion_atan2(y, x) -> None:
    yl, yh, p = y
    xl, xh, q = x
    assume(not (p == 0 and q == 0))
    lo, hi = c.atan2(yl, yh, xl, xh)
    ex = mpmath.pi if (p == 0 and q < 0) else mpmath.atan2(mp(p), mp(q))
    assert _inside(lo, hi, ex)


def test_bit_level_next_up_down_match_numpy() -> None:
    rng = np.random.default_rng(9)
    xs = SPECIAL + list(np.ldexp(rng.uniform(-2, 2, 2000), rng.integers(-1074, 1024, 2000)))
    with np.errstate(over="ignore"):
        for x in xs:
            assert c.next_up(x) == np.nextafter(x, INF)
            assert c.next_down(x) == np.nextafter(x, -INF)
    assert c.next_up(-INF) == -MAXF and c.next_down(INF) == MAXF
    assert c.next_up(-TINY) == 0.0 and c.next_down(TINY) == 0.0


def test_wrong_rounding_mode_is_refused_not_silently_wrong() -> None:
    from imubounds.errors import AnalysisError
    from imubounds.interval.rounding import rounding, rounding_mode

    upward = 0x800 if rounding_mode() == 0 else rounding_mode()  # x86-64 FE_UPWARD
    with rounding(upward):
        with pytest.raises(AnalysisError):
            _ = iv.I(1, 2) + iv.I(3, 4)
        with pytest.raises(AnalysisError):
            hc4_add(iv.I(4, 6), iv.I(1, 2), iv.I(0, 5))
    assert rounding_mode() == 0
    assert (iv.I(1, 2) + iv.I(3, 4)).to_tuples() == [(4.0, 6.0)]
