"""Exact reference helpers for the interval tests (Fraction and mpmath)."""

from __future__ import annotations

import math
from fractions import Fraction

import mpmath
import numpy as np

mpmath.mp.prec = 128  # >= 100 bits for the transcendental references
MAXF = 1.7976931348623157e308


def floor_double(q: Fraction | mpmath.mpf) -> float:
    """Largest double <= q."""
    try:
        d = float(q)
    except OverflowError:
        return MAXF if q > 0 else -math.inf
    if math.isinf(d):
        return MAXF if d > 0 else -math.inf
    if (Fraction(d) if isinstance(q, Fraction) else mpmath.mpf(d)) > q:
        d = math.nextafter(d, -math.inf)
    return d


def ceil_double(q: Fraction | mpmath.mpf) -> float:
    """Smallest double >= q."""
    return -floor_double(-q)


def rand_intervals(rng: np.random.Generator, n: int, emin: int = -40, emax: int = 40,
                   specials: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """Random finite intervals with mixed signs and magnitudes (and some
    degenerate ones, zero endpoints and short/long widths)."""

    def num(k: int) -> np.ndarray:
        m = rng.uniform(1.0, 2.0, k)
        e = rng.integers(emin, emax + 1, k)
        s = rng.choice([-1.0, 1.0], k)
        return s * np.ldexp(m, e)

    a = num(n)
    b = num(n)
    # a third of the intervals short around a
    short = rng.random(n) < 0.33
    b[short] = a[short] + a[short] * rng.uniform(-1e-6, 1e-6, short.sum())
    lo = np.minimum(a, b)
    hi = np.maximum(a, b)
    if specials:
        k = rng.random(n)
        lo[k < 0.04] = 0.0
        hi[(k >= 0.04) & (k < 0.08)] = 0.0
        deg = (k >= 0.08) & (k < 0.12)
        hi[deg] = lo[deg]
        lo, hi = np.minimum(lo, hi), np.maximum(lo, hi)
    return lo, hi


def mp(x: float) -> mpmath.mpf:
    return mpmath.mpf(x)


def sin_image(a: float, b: float, fn: str = "sin") -> tuple[mpmath.mpf, mpmath.mpf]:
    """Exact (128-bit) image of [a, b] under sin or cos (via critical points)."""
    f = mpmath.sin if fn == "sin" else mpmath.cos
    A, B = mp(a), mp(b)
    vals = [f(A), f(B)]
    if B - A >= 2 * mpmath.pi:
        return mpmath.mpf(-1), mpmath.mpf(1)
    off = mpmath.pi / 2 if fn == "sin" else mpmath.mpf(0)
    k0 = int(mpmath.ceil((A - off) / mpmath.pi))
    k1 = int(mpmath.floor((B - off) / mpmath.pi))
    for kk in range(k0, k1 + 1):
        # sin: +1 at pi/2 + 2k pi (kk even), -1 at kk odd; cos: +1 at 2k pi (kk even)
        vals.append(mpmath.mpf(1) if kk % 2 == 0 else mpmath.mpf(-1))
    return min(vals), max(vals)
