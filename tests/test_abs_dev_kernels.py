"""The compiled integrals of ``om |y - c|`` per window (``transport_blocks.abs_dev_integral``,
``transport_blocks.weighted_abs_dev``) against their plain exact reference
(tests/abs_dev_reference.py): never below the exact value (they are upper bounds used in
guaranteed intervals) and above it by no more than their stated rounding inflation."""

from __future__ import annotations

from fractions import Fraction

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from imubounds.dynamic.estimator.aided.transport_blocks import (
    abs_dev_integral,
    abs_dev_pair,
    weighted_abs_dev,
)
from tests.abs_dev_reference import weighted_abs_dev_exact

_F = st.floats(-50.0, 50.0, allow_nan=False, allow_subnormal=False)


@st.composite
def _case(draw: st.DrawFn) -> tuple[np.ndarray, ...]:
    n = draw(st.integers(1, 12))
    steps = np.array(draw(st.lists(st.floats(1e-3, 2.0), min_size=n, max_size=n)))
    bnd = np.concatenate([[draw(st.floats(-5.0, 5.0))], steps]).cumsum()
    y = np.array(draw(st.lists(_F, min_size=n, max_size=n)))
    unknown = np.array(draw(st.lists(st.booleans(), min_size=n, max_size=n)))
    om = np.array(draw(st.lists(st.floats(0.0, 10.0), min_size=n, max_size=n)))
    m = draw(st.integers(1, 5))
    lo, hi = float(bnd[0]) - 1.0, float(bnd[-1]) + 1.0
    ends = np.sort(np.array(draw(st.lists(st.floats(lo, hi), min_size=2 * m,
                                          max_size=2 * m))).reshape(m, 2), axis=1)
    a, b = ends[:, 0].copy(), ends[:, 1].copy()
    c = np.array(draw(st.lists(_F, min_size=m, max_size=m)))
    tf = a + np.array(draw(st.lists(st.floats(0.0, 3.0), min_size=m, max_size=m)))
    tl = b - np.array(draw(st.lists(st.floats(0.0, 3.0), min_size=m, max_size=m)))
    wf = np.array(draw(st.lists(st.floats(0.0, 10.0), min_size=m, max_size=m)))
    wl = np.array(draw(st.lists(st.floats(0.0, 10.0), min_size=m, max_size=m)))
    return bnd, y, unknown, om, a, b, c, tf, wf, tl, wl


def _close_above(got: np.ndarray, exact: list[Fraction], n_seg: int) -> None:
    for g, e in zip(got, exact, strict=True):
        assert Fraction(float(g)) >= e, (g, float(e))
        # at most the stated inflation (n + 8) 2^-52 plus the sum's own roundings
        assert float(g) <= float(e) * (1 + (3 * n_seg + 16) * 2.3e-16) + 1e-300, (g, float(e))


@settings(max_examples=200, deadline=None)
@given(_case())
def test_weighted_abs_dev_against_the_exact_reference(case: tuple[np.ndarray, ...]) -> None:
    bnd, y, unknown, om, a, b, c, tf, wf, tl, wl = case
    xmax = 7.0
    got = weighted_abs_dev(bnd, y, unknown, xmax, om, a, b, c, tf, wf, tl, wl)
    _close_above(got, weighted_abs_dev_exact(bnd, y, unknown, xmax, om, a, b, c,
                                             tf, wf, tl, wl), y.size)


@settings(max_examples=200, deadline=None)
@given(_case())
def test_abs_dev_integral_against_the_exact_reference(case: tuple[np.ndarray, ...]) -> None:
    bnd, y, unknown, _, a, b, c, *_ = case
    xmax = 7.0
    ones = np.ones(y.size)
    none_lo, none_hi = np.full(a.size, -np.inf), np.full(a.size, np.inf)
    zero = np.zeros(a.size)
    got = abs_dev_integral(bnd, y, unknown, xmax, a, b, c)
    _close_above(got, weighted_abs_dev_exact(bnd, y, unknown, xmax, ones, a, b, c,
                                             none_lo, zero, none_hi, zero), y.size)


@settings(max_examples=100, deadline=None)
@given(_case())
def test_abs_dev_pair_is_the_unit_weight_kernel_at_both_centres(
    case: tuple[np.ndarray, ...]
) -> None:
    """One pass at two centres: bit for bit the weighted kernel with unit weights (the
    form the pair replaced) at each, and above the exact reference."""
    bnd, y, unknown, _, a, b, c, *_ = case
    ones = np.ones(y.size)
    none_lo, none_hi = np.full(a.size, -np.inf), np.full(a.size, np.inf)
    zero = np.zeros(a.size)
    c2 = c + 0.75
    lo, hi = abs_dev_pair(bnd, y, unknown, 7.0, a, b, c, c2)
    for got, cc in ((lo, c), (hi, c2)):
        ref = weighted_abs_dev(bnd, y, unknown, 7.0, ones, a, b, cc, none_lo, zero, none_hi,
                               zero)
        assert np.array_equal(got, ref)
        _close_above(got, weighted_abs_dev_exact(bnd, y, unknown, 7.0, ones, a, b, cc,
                                                 none_lo, zero, none_hi, zero), y.size)


def test_products_that_underflow_still_give_an_upper_bound() -> None:
    """Hypothesis found it: a weight times a deviation times a length below the smallest
    subnormal rounds to 0, under the exact value; the kernel adds 1e-300."""
    bnd = np.arange(6.0)
    y = np.array([6.5e-200, 0.0, 0.0, 0.0, 0.0])
    unknown = np.zeros(5, dtype=bool)
    a, b = np.array([0.0]), np.array([1.75e-180])
    lo, hi, zero = np.array([-np.inf]), np.array([np.inf]), np.zeros(1)
    for om in (np.ones(5), np.array([1.0, 0.0, 0.0, 0.0, 0.0])):
        got = weighted_abs_dev(bnd, y, unknown, 7.0, om, a, b, zero, lo, zero, hi, zero)
        exact = weighted_abs_dev_exact(bnd, y, unknown, 7.0, om, a, b, zero, lo, zero, hi,
                                       zero)
        assert exact[0] > 0 and Fraction(float(got[0])) >= exact[0]
    assert abs_dev_integral(bnd, y, unknown, 7.0, a, b, zero)[0] > 0
