"""Forward-backward contractors of the smoother (``z = x + y``, ``z = x * y``):
textbook cases, soundness on random boxes (no solution point is ever removed;
exact references), contraction, codes."""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
import pytest
from _hc4 import hc4_add, hc4_inplace, hc4_mul
from _iv_exact import ceil_double, floor_double
from hypothesis import given, settings
from hypothesis import strategies as st

import imubounds.interval as iv
from imubounds.interval import _ctc as k

INF = math.inf
OPS = ["add", "mul"]


def test_textbook_add() -> None:
    r = hc4_add(iv.I(4, 6), iv.I(1, 2), iv.I(0, 5))
    assert r.z.to_tuples() == [(4.0, 6.0)]
    assert r.a.to_tuples() == [(1.0, 2.0)]
    assert r.b.to_tuples() == [(2.0, 5.0)]
    assert int(r.code) == -1
    assert k.ctc_add(4.0, 6.0, 1.0, 2.0, 0.0, 5.0) == (4.0, 6.0, 1.0, 2.0, 2.0, 5.0, -1)


def test_mul_backward_with_zero_in_y_still_contracts() -> None:
    # z = x*y, z in [1,2], y in [0,1] (contains 0): x must be >= 1
    r = hc4_mul(iv.I(1, 2), iv.I(-10, 10), iv.I(0, 1))
    assert r.a.to_tuples() == [(1.0, 10.0)]
    assert r.b.to_tuples() == [(0.1, 1.0)] or float(r.b.lo) <= 0.1 <= float(r.b.lo) + 1e-16
    # y straddles 0: x in (-inf, -1] U [0.5, inf) intersected with [-0.9, 10]
    r = hc4_mul(iv.I(1, 2), iv.I(-0.9, 10), iv.I(-1, 2))
    assert r.a.to_tuples() == [(0.5, 10.0)]
    # both z and y contain 0: no contraction of x possible
    r = hc4_mul(iv.I(-1, 2), iv.I(-10, 10), iv.I(0, 1))
    assert r.a.to_tuples() == [(-10.0, 10.0)]


def test_inconsistency_codes_and_empty_propagation() -> None:
    r = hc4_add(iv.I(10, 11), iv.I(1, 2), iv.I(0, 5))
    assert int(r.code) == 0 and r.z.is_empty() and r.a.is_empty() and r.b.is_empty()
    r = hc4_add(iv.I(4, 6), iv.IntervalArray.empty(()), iv.I(0, 5))
    assert int(r.code) == 1
    r = hc4_mul(iv.I(1, 2), iv.I(-1, 1), iv.I(-0.5, 0.5))  # |x y| <= 1/2 < 1
    assert int(r.code) == 0


def test_modes_forward_only_and_backward_only() -> None:
    z, x, y = iv.I(0, 100), iv.I(1, 2), iv.I(0, 5)
    f = hc4_add(z, x, y, mode="f")
    assert f.z.to_tuples() == [(1.0, 7.0)] and f.b.to_tuples() == [(0.0, 5.0)]
    b = hc4_add(iv.I(4, 6), x, y, mode="b")
    assert b.z.to_tuples() == [(4.0, 6.0)] and b.b.to_tuples() == [(2.0, 5.0)]


# --- soundness on random boxes -------------------------------------------------


def _exact(op: str, x: float, y: float) -> Fraction:
    X, Y = Fraction(x), Fraction(y)
    return X + Y if op == "add" else X * Y


def _points(rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray]:
    x = rng.normal(0, 1, n) * 10.0 ** rng.uniform(-3, 3, n)
    y = rng.normal(0, 1, n) * 10.0 ** rng.uniform(-3, 3, n)
    x[rng.random(n) < 0.05] = 0.0
    y[rng.random(n) < 0.05] = 0.0
    return x, y


def _box(rng: np.random.Generator, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    n = p.size
    w = np.abs(p) * 10.0 ** rng.uniform(-12, 0.5, n) + 10.0 ** rng.uniform(-6, 1, n)
    t = rng.random(n)
    t[rng.random(n) < 0.1] = 0.0
    t[rng.random(n) < 0.1] = 1.0
    lo = p - t * w
    hi = p + (1 - t) * w
    lo = np.minimum(lo, p)
    hi = np.maximum(hi, p)
    return lo, hi


def check_soundness(op: str, n: int, seed: int) -> None:
    rng = np.random.default_rng(seed)
    x, y = _points(rng, n)
    zex = [_exact(op, float(a), float(b)) for a, b in zip(x, y, strict=True)]
    zlo = np.array([floor_double(z) for z in zex])
    zhi = np.array([ceil_double(z) for z in zex])
    zc = 0.5 * zlo + 0.5 * zhi
    wlo, whi = _box(rng, zc)
    zlo = np.minimum(zlo, wlo)
    zhi = np.maximum(zhi, whi)
    xlo, xhi = _box(rng, x)
    ylo, yhi = _box(rng, y)
    arrs = [a.copy() for a in (zlo, zhi, xlo, xhi, ylo, yhi)]
    code = hc4_inplace(op, *arrs)
    assert (code == -1).all(), (op, np.flatnonzero(code != -1)[:5])
    nz_lo, nz_hi, nx_lo, nx_hi, ny_lo, ny_hi = arrs
    assert np.all((nx_lo <= x) & (x <= nx_hi)), op
    assert np.all((ny_lo <= y) & (y <= ny_hi)), op
    for i in range(n):
        z = zex[i]
        lo_ok = nz_lo[i] == -INF or Fraction(nz_lo[i]) <= z
        hi_ok = nz_hi[i] == INF or z <= Fraction(nz_hi[i])
        assert lo_ok and hi_ok, (op, i)
    # contraction never enlarges
    assert np.all(nx_lo >= xlo) and np.all(nx_hi <= xhi) and np.all(nz_lo >= zlo)
    # and it does something on average for the tight z boxes
    # scalar == vector
    for i in range(0, n, max(1, n // 50)):
        r = getattr(k, f"ctc_{op}")(zlo[i], zhi[i], xlo[i], xhi[i], ylo[i], yhi[i])
        assert r[:6] == (nz_lo[i], nz_hi[i], nx_lo[i], nx_hi[i], ny_lo[i], ny_hi[i])


@pytest.mark.parametrize("op", OPS)
def test_contractor_soundness_random_boxes(op: str) -> None:
    check_soundness(op, 4000, seed=17 + OPS.index(op))


@pytest.mark.slow
@pytest.mark.parametrize("op", OPS)
def test_contractor_soundness_random_boxes_slow(op: str) -> None:
    check_soundness(op, 60_000, seed=1017 + OPS.index(op))


def test_contractors_shrink_something() -> None:
    rng = np.random.default_rng(5)
    n = 2000
    x = rng.normal(0, 1, n)
    y = rng.normal(0, 1, n)
    z = x + y
    zlo, zhi = z - 0.01, z + 0.01
    xlo, xhi = x - 1.0, x + 1.0
    ylo, yhi = y - 0.001, y + 0.001
    code = hc4_inplace("add", zlo, zhi, xlo, xhi, ylo, yhi)
    assert (code == -1).all()
    # x <- x & (z - y) = x +- 0.011: every x shrank from width 2 to ~0.022
    assert np.all(xhi - xlo <= 0.022 + 1e-12) and np.all((xlo <= x) & (x <= xhi))


small = st.floats(-1e6, 1e6, allow_nan=False)
width = st.floats(0.0, 1e3, allow_nan=False)


@settings(max_examples=400, deadline=None)
@given(small, small, width, width, width, width, width, width,
       st.sampled_from(OPS))
def test_binary_contractors_never_remove_a_solution(p, q, a1, a2, b1, b2, c1, c2, op) -> None:
    z = _exact(op, p, q)
    zlo = floor_double(z)
    zhi = ceil_double(z)
    r = getattr(k, f"ctc_{op}")(zlo - c1, zhi + c2, p - a1, p + a2, q - b1, q + b2)
    assert r[6] == -1
    assert r[2] <= p <= r[3] and r[4] <= q <= r[5]
    assert r[0] == -INF or Fraction(r[0]) <= z
    assert r[1] == INF or z <= Fraction(r[1])
