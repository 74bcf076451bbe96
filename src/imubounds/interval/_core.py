"""Scalar interval rules: the one set of rules, compiled with numba.

Every function here works on plain floats and returns a tuple ``(lo, hi)``
(or several such pairs), so it can be called from other ``@njit`` code, e.g.
the per-time-step loop of the dynamic estimator. The vectorised
:class:`~imubounds.interval.IntervalArray` calls exactly these functions in
compiled loops, so scalar and array results are identical bit for bit.

Conventions
-----------
* An interval is a closed set ``[lo, hi]`` of real numbers with
  ``lo <= hi``, ``lo < +inf`` and ``hi > -inf``; infinite endpoints mean
  unbounded.
* The empty set is ``(+inf, -inf)`` (:data:`EMPTY_LO`, :data:`EMPTY_HI`).
  Every operation returns exactly this pair when its result is empty, and
  treats any input with ``not (lo <= hi)`` as empty, so empty propagates and
  no NaN is ever produced as an endpoint.
* Rounding is outward and as tight as cheaply possible: ``+ - * /`` and
  ``sqrt`` use error-free transformations (TwoSum, FMA) to find the sign of
  the rounding error, so exact results stay exact and inexact ones move by
  exactly one ulp (the directed-rounding result). Near underflow/overflow,
  where the error-free transformations are not exact, the result is widened
  by one ulp on both sides. The libm functions (sin, cos, asin,
  atan2) are widened by a relative margin of
  ``1.25 * 2**-50`` (4.5 to 10 ulp, above the 4 ulp error bound of common libms)
  plus ``2**-1069`` absolute, except at a few exact points (sin 0 = 0,
  cos 0 = 1, atan2(0, x>0) = 0) and at the extrema of
  sin/cos, which are exactly +-1.
* The rules assume the default round-to-nearest mode (see
  :mod:`imubounds.interval.rounding`; the vectorised entry points check it,
  code calling these scalar functions from numba must not change it).
* All values are SI: angles in radians.
"""

from __future__ import annotations

import math
from typing import Any

from llvmlite import ir
from numba import njit, types
from numba.extending import intrinsic

INF = math.inf
EMPTY_LO = math.inf  #: lower endpoint of the empty interval
EMPTY_HI = -math.inf  #: upper endpoint of the empty interval
MAXF = 1.7976931348623157e308  #: largest finite double

PI_LO = float.fromhex("0x1.921fb54442d18p+1")  #: largest double below pi
PI_HI = float.fromhex("0x1.921fb54442d19p+1")  #: smallest double above pi
HALF_PI_LO = PI_LO / 2.0
HALF_PI_HI = PI_HI / 2.0
TWO_PI_LO = PI_LO * 2.0
TWO_PI_HI = PI_HI * 2.0

_REL = 2.0**-50 + 2.0**-52  # relative margin for libm results (>= 4.5 ulp)
_ABS = 2.0**-1069  # absolute margin for libm results (subnormal range)
_EFT_MIN = 2.0**-967  # below this an error-free transformation may be inexact
_EFT_MAX = 2.0**1020
_BIG_ARG = 2.0**40  # beyond this |x|, sin/cos/tan return their full range


@intrinsic
def _fma_ii(typingctx, a, b, c):  # pragma: no cover - compiled
    sig = types.float64(types.float64, types.float64, types.float64)

    def codegen(context, builder, signature, args):
        return builder.fma(*args)

    return sig, codegen


@intrinsic
def _f2i_ii(typingctx, x):  # pragma: no cover - compiled
    sig = types.int64(types.float64)

    def codegen(context, builder, signature, args):
        return builder.bitcast(args[0], ir.IntType(64))

    return sig, codegen


@intrinsic
def _i2f_ii(typingctx, i):  # pragma: no cover - compiled
    sig = types.float64(types.int64)

    def codegen(context, builder, signature, args):
        return builder.bitcast(args[0], ir.DoubleType())

    return sig, codegen


# typed as plain callables (numba calls the intrinsics with the value arguments only)
_fma: Any = _fma_ii
_f2i: Any = _f2i_ii
_i2f: Any = _i2f_ii


# ---------------------------------------------------------------------------
# directed rounding helpers
# ---------------------------------------------------------------------------


@njit(cache=True)
def next_up(x: float) -> float:
    """Smallest double above ``x`` (``+inf`` and NaN unchanged); bit arithmetic,
    same results as ``np.nextafter(x, inf)``."""
    if x != x or x == INF:
        return x
    if x == 0.0:
        return 5e-324
    i = _f2i(x)
    return _i2f(i + 1) if x > 0.0 else _i2f(i - 1)


@njit(cache=True)
def next_down(x: float) -> float:
    """Largest double below ``x`` (``-inf`` and NaN unchanged)."""
    return -next_up(-x)


@njit(cache=True)
def _adj_dn(v: float, d: bool) -> float:
    # one ulp down if d, branch-free; v finite and nonzero (or d False)
    i = _f2i(v)
    return _i2f(i - d * (1 + 2 * (i >> 63)))


@njit(cache=True)
def _adj_up(v: float, d: bool) -> float:
    # one ulp up if d, branch-free; v finite and nonzero (or d False)
    i = _f2i(v)
    return _i2f(i + d * (1 + 2 * (i >> 63)))


@njit(cache=True)
def _twosum_err(a: float, b: float, s: float) -> float:
    # Knuth's TwoSum: exact error (a + b) - s, for |a|, |b| <= 2**1020 and s finite
    bp = s - a
    ap = s - bp
    return (a - ap) + (b - bp)


@njit(cache=True)
def add_dn(a: float, b: float) -> float:
    """``a + b`` rounded toward -inf (exact results stay exact)."""
    s = a + b
    if not (abs(s) < INF) or abs(a) > _EFT_MAX or abs(b) > _EFT_MAX:
        if math.isinf(a) or math.isinf(b):
            return s
        if s == INF:
            return MAXF
        return next_down(s)
    return _adj_dn(s, _twosum_err(a, b, s) < 0.0)


@njit(cache=True)
def add_up(a: float, b: float) -> float:
    """``a + b`` rounded toward +inf (exact results stay exact)."""
    s = a + b
    if not (abs(s) < INF) or abs(a) > _EFT_MAX or abs(b) > _EFT_MAX:
        if math.isinf(a) or math.isinf(b):
            return s
        if s == -INF:
            return -MAXF
        return next_up(s)
    return _adj_up(s, _twosum_err(a, b, s) > 0.0)


@njit(cache=True)
def sub_dn(a: float, b: float) -> float:
    """``a - b`` rounded toward -inf."""
    return add_dn(a, -b)


@njit(cache=True)
def sub_up(a: float, b: float) -> float:
    """``a - b`` rounded toward +inf."""
    return add_up(a, -b)


@njit(cache=True)
def mul_dn(a: float, b: float) -> float:
    """``a * b`` rounded toward -inf, with ``0 * inf = 0``."""
    if a == 0.0 or b == 0.0:
        return 0.0
    p = a * b
    ap = abs(p)
    if not (ap < INF) or ap < _EFT_MIN:
        if math.isinf(a) or math.isinf(b):
            return p
        if p == INF:
            return MAXF
        return next_down(p)
    return _adj_dn(p, _fma(a, b, -p) < 0.0)


@njit(cache=True)
def mul_up(a: float, b: float) -> float:
    """``a * b`` rounded toward +inf, with ``0 * inf = 0``."""
    if a == 0.0 or b == 0.0:
        return 0.0
    p = a * b
    ap = abs(p)
    if not (ap < INF) or ap < _EFT_MIN:
        if math.isinf(a) or math.isinf(b):
            return p
        if p == -INF:
            return -MAXF
        return next_up(p)
    return _adj_up(p, _fma(a, b, -p) > 0.0)


@njit(cache=True)
def div_dn(a: float, b: float) -> float:
    """``a / b`` rounded toward -inf (``b != 0``; not both infinite)."""
    if a == 0.0:
        return 0.0
    q = a / b
    if math.isinf(a) or math.isinf(b):
        return q
    aq = abs(q)
    aa = abs(a)
    if not (aq < INF) or aq < _EFT_MIN or aa < _EFT_MIN or aa > _EFT_MAX:
        if q == INF:
            return MAXF
        return next_down(q)
    r = _fma(-q, b, a)  # exact remainder: a/b - q = r/b
    return _adj_dn(q, ((r < 0.0) ^ (b < 0.0)) & (r != 0.0))


@njit(cache=True)
def div_up(a: float, b: float) -> float:
    """``a / b`` rounded toward +inf (``b != 0``; not both infinite)."""
    if a == 0.0:
        return 0.0
    q = a / b
    if math.isinf(a) or math.isinf(b):
        return q
    aq = abs(q)
    aa = abs(a)
    if not (aq < INF) or aq < _EFT_MIN or aa < _EFT_MIN or aa > _EFT_MAX:
        if q == -INF:
            return -MAXF
        return next_up(q)
    r = _fma(-q, b, a)
    return _adj_up(q, ((r > 0.0) ^ (b < 0.0)) & (r != 0.0))


@njit(cache=True)
def sqrt_dn(a: float) -> float:
    """``sqrt(a)`` rounded toward -inf (``a >= 0``)."""
    s = math.sqrt(a)
    if a == 0.0 or a == INF:
        return s
    if a < _EFT_MIN:
        r = next_down(s)
        return r if r > 0.0 else 0.0
    return _adj_dn(s, _fma(-s, s, a) < 0.0)


@njit(cache=True)
def sqrt_up(a: float) -> float:
    """``sqrt(a)`` rounded toward +inf (``a >= 0``)."""
    s = math.sqrt(a)
    if a == 0.0 or a == INF:
        return s
    if a < _EFT_MIN:
        return next_up(s)
    return _adj_up(s, _fma(-s, s, a) > 0.0)


@njit(cache=True)
def lib_dn(y: float) -> float:
    """Lower bound for a true value within a few ulp of the libm result ``y``."""
    if y == INF:
        return MAXF
    if y == -INF:
        return -INF
    return y - (abs(y) * _REL + _ABS)


@njit(cache=True)
def lib_up(y: float) -> float:
    """Upper bound for a true value within a few ulp of the libm result ``y``."""
    if y == -INF:
        return -MAXF
    if y == INF:
        return INF
    return y + (abs(y) * _REL + _ABS)


# ---------------------------------------------------------------------------
# set operations and predicates
# ---------------------------------------------------------------------------


@njit(cache=True)
def empty() -> tuple[float, float]:
    """The empty interval ``(+inf, -inf)``."""
    return EMPTY_LO, EMPTY_HI


@njit(cache=True)
def is_empty(lo: float, hi: float) -> bool:
    """True for the empty set (any pair with ``not lo <= hi``)."""
    return not (lo <= hi)


@njit(cache=True)
def inter(alo: float, ahi: float, blo: float, bhi: float) -> tuple[float, float]:
    """Intersection of two intervals."""
    if not (alo <= ahi) or not (blo <= bhi):
        return EMPTY_LO, EMPTY_HI
    lo = alo if alo > blo else blo
    hi = ahi if ahi < bhi else bhi
    if lo > hi:
        return EMPTY_LO, EMPTY_HI
    return lo, hi


@njit(cache=True)
def hull(alo: float, ahi: float, blo: float, bhi: float) -> tuple[float, float]:
    """Smallest interval containing both (empty is the neutral element)."""
    if not (alo <= ahi):
        if not (blo <= bhi):
            return EMPTY_LO, EMPTY_HI
        return blo, bhi
    if not (blo <= bhi):
        return alo, ahi
    return (alo if alo < blo else blo), (ahi if ahi > bhi else bhi)


@njit(cache=True)
def width(lo: float, hi: float) -> float:
    """Width ``hi - lo`` rounded up; NaN for the empty set."""
    if not (lo <= hi):
        return math.nan
    return sub_up(hi, lo)


@njit(cache=True)
def mid(lo: float, hi: float) -> float:
    """A midpoint inside the interval (0 for the entire line; +-MAXF for
    half-lines); NaN for the empty set."""
    if not (lo <= hi):
        return math.nan
    if lo == -INF:
        if hi == INF:
            return 0.0
        return -MAXF
    if hi == INF:
        return MAXF
    m = 0.5 * lo + 0.5 * hi
    if m < lo:
        return lo
    if m > hi:
        return hi
    return m


@njit(cache=True)
def radius(lo: float, hi: float) -> float:
    """Smallest ``r`` with ``[lo, hi]`` inside ``[mid - r, mid + r]``; NaN if empty."""
    if not (lo <= hi):
        return math.nan
    m = mid(lo, hi)
    r1 = sub_up(m, lo)
    r2 = sub_up(hi, m)
    return r1 if r1 > r2 else r2


@njit(cache=True)
def contains(lo: float, hi: float, x: float) -> bool:
    """True if the real number ``x`` lies in ``[lo, hi]``."""
    return lo <= x and x <= hi


@njit(cache=True)
def subset(alo: float, ahi: float, blo: float, bhi: float) -> bool:
    """True if ``[a]`` is a subset of ``[b]`` (the empty set is a subset of all)."""
    if not (alo <= ahi):
        return True
    if not (blo <= bhi):
        return False
    return blo <= alo and ahi <= bhi


# ---------------------------------------------------------------------------
# arithmetic
# ---------------------------------------------------------------------------


@njit(cache=True)
def neg(lo: float, hi: float) -> tuple[float, float]:
    """``-[x]``."""
    if not (lo <= hi):
        return EMPTY_LO, EMPTY_HI
    return -hi, -lo


@njit(cache=True)
def add(alo: float, ahi: float, blo: float, bhi: float) -> tuple[float, float]:
    """``[a] + [b]``."""
    if not (alo <= ahi) or not (blo <= bhi):
        return EMPTY_LO, EMPTY_HI
    return add_dn(alo, blo), add_up(ahi, bhi)


@njit(cache=True)
def sub(alo: float, ahi: float, blo: float, bhi: float) -> tuple[float, float]:
    """``[a] - [b]``."""
    if not (alo <= ahi) or not (blo <= bhi):
        return EMPTY_LO, EMPTY_HI
    return sub_dn(alo, bhi), sub_up(ahi, blo)


@njit(cache=True)
def mul(alo: float, ahi: float, blo: float, bhi: float) -> tuple[float, float]:
    """``[a] * [b]`` (``0 * inf`` counts as 0: an infinite endpoint means unbounded)."""
    if not (alo <= ahi) or not (blo <= bhi):
        return EMPTY_LO, EMPTY_HI
    if alo >= 0.0:
        if blo >= 0.0:
            return mul_dn(alo, blo), mul_up(ahi, bhi)
        if bhi <= 0.0:
            return mul_dn(ahi, blo), mul_up(alo, bhi)
        return mul_dn(ahi, blo), mul_up(ahi, bhi)
    if ahi <= 0.0:
        if blo >= 0.0:
            return mul_dn(alo, bhi), mul_up(ahi, blo)
        if bhi <= 0.0:
            return mul_dn(ahi, bhi), mul_up(alo, blo)
        return mul_dn(alo, bhi), mul_up(alo, blo)
    # alo < 0 < ahi
    if blo >= 0.0:
        return mul_dn(alo, bhi), mul_up(ahi, bhi)
    if bhi <= 0.0:
        return mul_dn(ahi, blo), mul_up(alo, blo)
    l1 = mul_dn(alo, bhi)
    l2 = mul_dn(ahi, blo)
    h1 = mul_up(alo, blo)
    h2 = mul_up(ahi, bhi)
    return (l1 if l1 < l2 else l2), (h1 if h1 > h2 else h2)


@njit(cache=True)
def div(alo: float, ahi: float, blo: float, bhi: float) -> tuple[float, float]:
    """``[a] / [b]`` = hull of ``{a/b : a in [a], b in [b], b != 0}``.

    Division by ``[0, 0]`` is empty; by an interval with 0 strictly inside it
    is the whole line (unless ``[a] = [0, 0]``); by ``[0, h]`` or ``[l, 0]``
    it is a half-line or the whole line. Never NaN.
    """
    if not (alo <= ahi) or not (blo <= bhi):
        return EMPTY_LO, EMPTY_HI
    if blo > 0.0:
        if alo >= 0.0:
            return div_dn(alo, bhi), div_up(ahi, blo)
        if ahi <= 0.0:
            return div_dn(alo, blo), div_up(ahi, bhi)
        return div_dn(alo, blo), div_up(ahi, blo)
    if bhi < 0.0:
        if alo >= 0.0:
            return div_dn(ahi, bhi), div_up(alo, blo)
        if ahi <= 0.0:
            return div_dn(ahi, blo), div_up(alo, bhi)
        return div_dn(ahi, bhi), div_up(alo, bhi)
    # 0 in [b]
    if blo == 0.0 and bhi == 0.0:
        return EMPTY_LO, EMPTY_HI
    if alo == 0.0 and ahi == 0.0:
        return 0.0, 0.0
    if blo < 0.0 and bhi > 0.0:
        return -INF, INF
    if blo == 0.0:  # b in (0, bhi]
        if alo > 0.0:
            return div_dn(alo, bhi), INF
        if ahi < 0.0:
            return -INF, div_up(ahi, bhi)
        if alo == 0.0:
            return 0.0, INF
        if ahi == 0.0:
            return -INF, 0.0
        return -INF, INF
    # b in [blo, 0)
    if alo > 0.0:
        return -INF, div_up(alo, blo)
    if ahi < 0.0:
        return div_dn(ahi, blo), INF
    if alo == 0.0:
        return -INF, 0.0
    if ahi == 0.0:
        return 0.0, INF
    return -INF, INF


@njit(cache=True)
def div_rel(
    zlo: float, zhi: float, ylo: float, yhi: float
) -> tuple[float, float, float, float]:
    """Relational division: ``{x : x*y = z for some y in [y], z in [z]}``.

    Returns two intervals ``(lo1, hi1, lo2, hi2)`` whose union is that set
    (the second is empty unless 0 is strictly inside ``[y]``). Unlike
    :func:`div`, if both ``[y]`` and ``[z]`` contain 0 every ``x`` qualifies.
    """
    if not (zlo <= zhi) or not (ylo <= yhi):
        return EMPTY_LO, EMPTY_HI, EMPTY_LO, EMPTY_HI
    if zlo <= 0.0 and zhi >= 0.0 and ylo <= 0.0 and yhi >= 0.0:
        return -INF, INF, EMPTY_LO, EMPTY_HI
    if ylo < 0.0 and yhi > 0.0:  # 0 not in [z]
        if zlo > 0.0:
            return -INF, div_up(zlo, ylo), div_dn(zlo, yhi), INF
        return -INF, div_up(zhi, yhi), div_dn(zhi, ylo), INF
    lo, hi = div(zlo, zhi, ylo, yhi)
    return lo, hi, EMPTY_LO, EMPTY_HI


@njit(cache=True)
def inter_two(
    xlo: float, xhi: float, p1lo: float, p1hi: float, p2lo: float, p2hi: float
) -> tuple[float, float]:
    """Hull of ``[x] & ([p1] | [p2])``: the tightest interval for a union."""
    alo, ahi = inter(xlo, xhi, p1lo, p1hi)
    blo, bhi = inter(xlo, xhi, p2lo, p2hi)
    return hull(alo, ahi, blo, bhi)


@njit(cache=True)
def absval(lo: float, hi: float) -> tuple[float, float]:
    """``|[x]|``."""
    if not (lo <= hi):
        return EMPTY_LO, EMPTY_HI
    if lo >= 0.0:
        return lo, hi
    if hi <= 0.0:
        return -hi, -lo
    return 0.0, (-lo if -lo > hi else hi)


@njit(cache=True)
def sqr(lo: float, hi: float) -> tuple[float, float]:
    """``[x]**2`` (tight: the image of ``[-1, 2]`` is ``[0, 4]``)."""
    if not (lo <= hi):
        return EMPTY_LO, EMPTY_HI
    if lo >= 0.0:
        return mul_dn(lo, lo), mul_up(hi, hi)
    if hi <= 0.0:
        return mul_dn(hi, hi), mul_up(lo, lo)
    a = mul_up(lo, lo)
    b = mul_up(hi, hi)
    return 0.0, (a if a > b else b)


@njit(cache=True)
def sqrt(lo: float, hi: float) -> tuple[float, float]:
    """``sqrt([x] & [0, inf))``; empty if ``hi < 0``."""
    if not (lo <= hi) or hi < 0.0:
        return EMPTY_LO, EMPTY_HI
    return sqrt_dn(lo if lo > 0.0 else 0.0), sqrt_up(hi)


@njit(cache=True)
def _crit_range(lo: float, hi: float, offset: float, period: float) -> tuple[int, int]:
    # integers k with offset + k*period possibly in [lo, hi]: [kmin, kmax]
    # (conservative by a relative margin; empty if kmin > kmax)
    inv = 1.0 / period  # constant-folded for the constant periods used here
    tl = (lo - offset) * inv
    th = (hi - offset) * inv
    el = abs(tl) * 2.0**-46 + 2.0**-46
    eh = abs(th) * 2.0**-46 + 2.0**-46
    return math.ceil(tl - el), math.floor(th + eh)


@njit(cache=True)
def _extrema(lo: float, hi: float, offset: float) -> tuple[bool, bool]:
    # critical points offset + k*pi, maxima for even k and minima for odd k
    # (sin: offset pi/2; cos: offset 0): which kinds may lie in [lo, hi]
    kmin, kmax = _crit_range(lo, hi, offset, PI_LO)
    if kmax < kmin:
        return False, False
    if kmax > kmin:
        return True, True
    even = kmin % 2 == 0
    return even, not even


@njit(cache=True)
def sin(lo: float, hi: float) -> tuple[float, float]:
    """``sin([x])``, exactly +-1 where a maximum/minimum lies in ``[x]``.

    For ``max(|lo|, |hi|) > 2**40`` or width >= 2 pi the result is ``[-1, 1]``.
    """
    if not (lo <= hi):
        return EMPTY_LO, EMPTY_HI
    if abs(lo) > _BIG_ARG or abs(hi) > _BIG_ARG or hi - lo >= TWO_PI_LO:
        return -1.0, 1.0
    has_max, has_min = _extrema(lo, hi, HALF_PI_LO)
    if has_max and has_min:
        return -1.0, 1.0
    # one libm call per endpoint; sin(0) = 0.0 exactly
    fl = 0.0 if lo == 0.0 else math.sin(lo)
    fh = 0.0 if hi == 0.0 else math.sin(hi)
    if has_max:
        rhi = 1.0
    else:
        a = fl if lo == 0.0 else lib_up(fl)
        b = fh if hi == 0.0 else lib_up(fh)
        rhi = a if a > b else b
        rhi = rhi if rhi < 1.0 else 1.0
    if has_min:
        rlo = -1.0
    else:
        a = fl if lo == 0.0 else lib_dn(fl)
        b = fh if hi == 0.0 else lib_dn(fh)
        rlo = a if a < b else b
        rlo = rlo if rlo > -1.0 else -1.0
    return rlo, rhi


@njit(cache=True)
def cos(lo: float, hi: float) -> tuple[float, float]:
    """``cos([x])``, exactly +-1 where a maximum/minimum lies in ``[x]``."""
    if not (lo <= hi):
        return EMPTY_LO, EMPTY_HI
    if abs(lo) > _BIG_ARG or abs(hi) > _BIG_ARG or hi - lo >= TWO_PI_LO:
        return -1.0, 1.0
    has_max, has_min = _extrema(lo, hi, 0.0)
    if has_max and has_min:
        return -1.0, 1.0
    # one libm call per endpoint; cos(0) = 1.0 exactly
    fl = 1.0 if lo == 0.0 else math.cos(lo)
    fh = 1.0 if hi == 0.0 else math.cos(hi)
    if has_max:
        rhi = 1.0
    else:
        a = fl if lo == 0.0 else lib_up(fl)
        b = fh if hi == 0.0 else lib_up(fh)
        rhi = a if a > b else b
        rhi = rhi if rhi < 1.0 else 1.0
    if has_min:
        rlo = -1.0
    else:
        a = fl if lo == 0.0 else lib_dn(fl)
        b = fh if hi == 0.0 else lib_dn(fh)
        rlo = a if a < b else b
        rlo = rlo if rlo > -1.0 else -1.0
    return rlo, rhi


@njit(cache=True)
def asin(lo: float, hi: float) -> tuple[float, float]:
    """``asin([x] & [-1, 1])``."""
    if not (lo <= hi) or hi < -1.0 or lo > 1.0:
        return EMPTY_LO, EMPTY_HI
    lo = lo if lo > -1.0 else -1.0
    hi = hi if hi < 1.0 else 1.0
    rlo = 0.0 if lo == 0.0 else lib_dn(math.asin(lo))
    rhi = 0.0 if hi == 0.0 else lib_up(math.asin(hi))
    rlo = rlo if rlo > -HALF_PI_HI else -HALF_PI_HI
    rhi = rhi if rhi < HALF_PI_HI else HALF_PI_HI
    return rlo, rhi


@njit(cache=True)
def _at2(y: float, x: float, up: bool) -> float:
    # outward-rounded atan2 at one point; exact 0 on the positive x axis
    if y == 0.0 and x > 0.0:
        return 0.0
    v = math.atan2(y, x)
    return lib_up(v) if up else lib_dn(v)


@njit(cache=True)
def _at2c(
    y: float, x: float, ylo: float, yhi: float, xlo: float, xhi: float, up: bool
) -> float:
    # atan2 at a corner of the piece [ylo, yhi] x [xlo, xhi]; if that corner is
    # the origin the piece is a segment on an axis and its other end is used
    if y == 0.0 and x == 0.0:
        y = yhi if y == ylo else ylo
        x = xhi if x == xlo else xlo
    return _at2(y, x, up)


@njit(cache=True)
def atan2(ylo: float, yhi: float, xlo: float, xhi: float) -> tuple[float, float]:
    """``atan2([y], [x])`` in ``[-pi, pi]``: hull over the box minus the origin.

    ``atan2(0, 0)`` is undefined and excluded (the box ``[0,0] x [0,0]`` gives
    the empty set). The result is the hull over the closed quadrant pieces of
    the box; a box reaching the negative x axis from below (y < 0) and from
    above/on it gives ``[-pi, pi]``; a caller with a course near +-pi rotates the box by
    pi first and shifts the result back (as the estimator's course bound does).
    """
    if not (ylo <= yhi) or not (xlo <= xhi):
        return EMPTY_LO, EMPTY_HI
    ylo = ylo + 0.0  # turn -0.0 into +0.0
    yhi = yhi + 0.0
    xlo = xlo + 0.0
    xhi = xhi + 0.0
    if ylo == 0.0 and yhi == 0.0 and xlo == 0.0 and xhi == 0.0:
        return EMPTY_LO, EMPTY_HI
    rlo = INF
    rhi = -INF
    # Q1: x >= 0, y >= 0: min at (x2, y1), max at (x1, y2)
    if xhi >= 0.0 and yhi >= 0.0:
        x1 = xlo if xlo > 0.0 else 0.0
        y1 = ylo if ylo > 0.0 else 0.0
        if not (x1 == 0.0 and xhi == 0.0 and y1 == 0.0 and yhi == 0.0):
            rlo = min(rlo, _at2c(y1, xhi, y1, yhi, x1, xhi, False))
            rhi = max(rhi, _at2c(yhi, x1, y1, yhi, x1, xhi, True))
    # Q2: x <= 0, y >= 0: min at (x2, y2), max at (x1, y1)
    if xlo < 0.0 and yhi >= 0.0:
        x2 = xhi if xhi < 0.0 else 0.0
        y1 = ylo if ylo > 0.0 else 0.0
        rlo = min(rlo, _at2c(yhi, x2, y1, yhi, xlo, x2, False))
        rhi = max(rhi, _at2c(y1, xlo, y1, yhi, xlo, x2, True))
    # Q3: x < 0, y < 0 (closure reaches -pi as y -> 0-): min at (x1, y2), max at (x2, y1)
    if xlo < 0.0 and ylo < 0.0:
        x2 = xhi if xhi < 0.0 else 0.0
        y2 = yhi if yhi < 0.0 else -0.0
        rlo = min(rlo, _at2(y2, xlo, False))
        rhi = max(rhi, _at2(ylo, x2, True))
    # Q4: x >= 0, y < 0: min at (x1, y1), max at (x2, y2)
    if xhi >= 0.0 and ylo < 0.0:
        x1 = xlo if xlo > 0.0 else 0.0
        y2 = yhi if yhi < 0.0 else 0.0
        rlo = min(rlo, _at2(ylo, x1, False))
        rhi = max(rhi, _at2c(y2, xhi, ylo, y2, x1, xhi, True))
    if rlo > rhi:
        return EMPTY_LO, EMPTY_HI
    rlo = rlo if rlo > -PI_HI else -PI_HI
    rhi = rhi if rhi < PI_HI else PI_HI
    return rlo, rhi
