"""Exact checks of the interval rules against Fraction (+ - * / sqr sqrt) and
128-bit mpmath (sin cos atan2) on random intervals.

Default run: 115 000 random cases in total (the per-op counts below); the
slow run: 1.15 million (ten times each). For + - * / sqr sqrt the check is
exact tightness: each endpoint must be the directed rounding of the exact
bound. For the libm-based functions the result must contain the exact image
and be at most ~16 ulp wider at each end (exactly +-1 at sin/cos extrema).
"""

from __future__ import annotations

import math
from fractions import Fraction

import mpmath
import numpy as np
import pytest
from _iv_exact import MAXF, ceil_double, floor_double, mp, rand_intervals, sin_image

import imubounds.interval as iv

F = Fraction

DEFAULT_N = {
    "add": 20_000, "sub": 10_000, "mul": 20_000, "div": 20_000, "sqr": 10_000,
    "sqrt": 10_000, "sin": 10_000, "cos": 5_000, "atan2": 10_000,
}


def _pairs(op: str, n: int, seed: int):
    rng = np.random.default_rng(seed)
    alo, ahi = rand_intervals(rng, n)
    blo, bhi = rand_intervals(rng, n)
    return rng, alo, ahi, blo, bhi


def check_arith(op: str, n: int, seed: int) -> int:
    _, alo, ahi, blo, bhi = _pairs(op, n, seed)
    if op == "div":  # exact tight check where 0 is not in [b]
        keep = (blo > 0) | (bhi < 0)
        alo, ahi, blo, bhi = alo[keep], ahi[keep], blo[keep], bhi[keep]
    A = iv.IntervalArray(alo, ahi)
    B = iv.IntervalArray(blo, bhi)
    R = {"add": A + B, "sub": A - B, "mul": A * B, "div": A / B}[op]
    for i in range(alo.size):
        a = (F(alo[i]), F(ahi[i]))
        b = (F(blo[i]), F(bhi[i]))
        if op == "add":
            ex_lo, ex_hi = a[0] + b[0], a[1] + b[1]
        elif op == "sub":
            ex_lo, ex_hi = a[0] - b[1], a[1] - b[0]
        else:
            vals = [x * y for x in a for y in b] if op == "mul" else [x / y for x in a for y in b]
            ex_lo, ex_hi = min(vals), max(vals)
        assert R.lo[i] == floor_double(ex_lo), (op, i, alo[i], ahi[i], blo[i], bhi[i])
        assert R.hi[i] == ceil_double(ex_hi), (op, i, alo[i], ahi[i], blo[i], bhi[i])
    return alo.size


def check_unary_exact(op: str, n: int, seed: int) -> int:
    rng = np.random.default_rng(seed)
    lo, hi = rand_intervals(rng, n)
    if op == "sqrt":
        lo, hi = np.abs(lo), np.abs(hi)
        lo, hi = np.minimum(lo, hi), np.maximum(lo, hi)
        R = iv.sqrt(iv.IntervalArray(lo, hi))
    else:
        R = iv.sqr(iv.IntervalArray(lo, hi))
    for i in range(lo.size):
        a, b = F(lo[i]), F(hi[i])
        if op == "sqr":
            ex_lo = F(0) if a <= 0 <= b else min(a * a, b * b)
            ex_hi = max(a * a, b * b)
            assert R.lo[i] == floor_double(ex_lo) and R.hi[i] == ceil_double(ex_hi), (i, a, b)
        else:
            rl, rh = F(R.lo[i]), F(R.hi[i])
            # rl = largest double with rl^2 <= a ; rh = smallest double with rh^2 >= b
            assert rl * rl <= a and F(math.nextafter(R.lo[i], math.inf)) ** 2 > a, (i, a)
            assert rh * rh >= b and (b == 0 or F(math.nextafter(R.hi[i], -math.inf)) ** 2 < b)
    return lo.size


def _ulp_slack(x: mpmath.mpf) -> mpmath.mpf:
    return abs(x) * mpmath.mpf(2) ** -48 + mpmath.mpf(2) ** -1060


def check_transcendental(op: str, n: int, seed: int) -> int:
    rng = np.random.default_rng(seed)
    if op not in ("sin", "cos"):
        return check_atan2(n, seed)
    c = rng.uniform(-60, 60, n)
    w = 10.0 ** rng.uniform(-12, 1.2, n)
    lo, hi = c, c + w
    deg = rng.random(n) < 0.05
    hi[deg] = lo[deg]
    R = {"sin": iv.sin, "cos": iv.cos}[op](iv.IntervalArray(lo, hi))
    for i in range(n):
        m, M = sin_image(lo[i], hi[i], op)
        if M == 1:
            assert R.hi[i] == 1.0
        if m == -1:
            assert R.lo[i] == -1.0
        assert mp(R.lo[i]) <= m and mp(R.hi[i]) >= M, (op, i, lo[i], hi[i])
        if m > MAXF:  # beyond the doubles: the best lower bound is the largest double
            assert R.lo[i] == MAXF
        else:
            assert mp(R.lo[i]) >= m - _ulp_slack(m), (op, i, lo[i], hi[i])
        if M <= MAXF:
            assert mp(R.hi[i]) <= M + _ulp_slack(M), (op, i, lo[i], hi[i])
    return n


def atan2_hull(ylo: float, yhi: float, xlo: float, xhi: float) -> tuple[mpmath.mpf, mpmath.mpf]:
    """Independent exact hull of atan2 over a box minus the origin."""
    pi = mpmath.pi
    cand = []
    for y in (ylo, yhi):
        for x in (xlo, xhi):
            if x == 0 and y == 0:
                continue
            if y == 0 and x < 0:
                cand.append(pi)
            else:
                cand.append(mpmath.atan2(mp(y), mp(x)))
    if ylo <= 0 <= yhi and xhi > 0:
        cand.append(mpmath.mpf(0))
    if xlo <= 0 <= xhi and yhi > 0:
        cand.append(pi / 2)
    if xlo <= 0 <= xhi and ylo < 0:
        cand.append(-pi / 2)
    if ylo <= 0 <= yhi and xlo < 0:
        cand.append(pi)
        if ylo < 0:
            cand.append(-pi)
    return min(cand), max(cand)


def check_atan2(n: int, seed: int) -> int:
    rng = np.random.default_rng(seed)
    ylo, yhi = rand_intervals(rng, n, -20, 20)
    xlo, xhi = rand_intervals(rng, n, -20, 20)
    R = iv.atan2(iv.IntervalArray(ylo, yhi), iv.IntervalArray(xlo, xhi))
    for i in range(n):
        m, M = atan2_hull(ylo[i], yhi[i], xlo[i], xhi[i])
        assert mp(R.lo[i]) <= m and mp(R.hi[i]) >= M, (i, ylo[i], yhi[i], xlo[i], xhi[i])
        assert mp(R.lo[i]) >= m - _ulp_slack(m) and mp(R.hi[i]) <= M + _ulp_slack(M), i
    return n


def run(op: str, n: int, seed: int) -> int:
    if op in ("add", "sub", "mul", "div"):
        return check_arith(op, n, seed)
    if op in ("sqr", "sqrt"):
        return check_unary_exact(op, n, seed)
    return check_transcendental(op, n, seed)


@pytest.mark.parametrize("op", list(DEFAULT_N))
def test_exact_default(op: str) -> None:
    done = run(op, DEFAULT_N[op], seed=1234 + len(op))
    assert done >= DEFAULT_N[op] * 0.4  # div keeps only boxes with 0 outside [b]


def test_default_total_is_at_least_1e5() -> None:
    assert sum(DEFAULT_N.values()) >= 100_000


@pytest.mark.slow
@pytest.mark.parametrize("op", list(DEFAULT_N))
def test_exact_slow_1e6(op: str) -> None:
    """Ten times the default counts with other seeds: 1.15e6 cases in total."""
    done = run(op, 10 * DEFAULT_N[op], seed=98765 + len(op))
    assert done >= 4 * DEFAULT_N[op]
