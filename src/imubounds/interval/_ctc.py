"""Scalar forward-backward (HC4-revise) contractors for primitive constraints.

Every contractor takes the domains of its variables as ``lo, hi`` float
pairs, output variable first, and returns the contracted pairs followed by
an int code: ``-1`` if the box stays consistent, else the position (0 = the
output ``z``, 1 = first argument, 2 = second argument) of the variable that
became empty first; in that case every returned domain is empty.

``mode`` selects the steps: 1 = forward only (``z <- z & f(x, y)``),
2 = backward only (the inverse projections onto the arguments), 3 = both
(HC4-revise of the single primitive). A contractor never removes a point
that satisfies the constraint: it relies only on the outward-rounded rules
of :mod:`imubounds.interval._core`.

Operation codes (used by the constraint network)::

    OP_ADD  z = x + y        OP_SQR   z = x**2        OP_NEG  z = -x
    OP_SUB  z = x - y        OP_SQRT  z = sqrt(x)     OP_EXP  z = exp(x)
    OP_MUL  z = x * y        OP_SIN   z = sin(x)      OP_LOG  z = log(x)
    OP_DIV  z = x / y        OP_COS   z = cos(x)      OP_EQ   z = x
    OP_ATAN2 z = atan2(y, x)  (arguments in the order y, x)
"""

from __future__ import annotations

import math

from numba import njit

from imubounds.interval import _core as c

OP_ADD = 0
OP_SUB = 1
OP_MUL = 2
OP_DIV = 3
OP_SQR = 4
OP_SQRT = 5
OP_SIN = 6
OP_COS = 7
OP_ATAN2 = 8
OP_NEG = 9
OP_EXP = 10
OP_LOG = 11
OP_EQ = 12

#: number of arguments (besides the output) of each operation code
OP_ARITY = (2, 2, 2, 2, 1, 1, 1, 1, 2, 1, 1, 1, 1)
#: name of each operation code
OP_NAMES = ("add", "sub", "mul", "div", "sqr", "sqrt", "sin", "cos", "atan2", "neg", "exp",
            "log", "eq")

_E = math.inf
_F = -math.inf
INF = math.inf
_INV_TWO_PI = 1.0 / (2.0 * math.pi)  # only for first guesses, checked rigorously

Res = tuple[float, float, float, float, float, float, int]


@njit(cache=True)
def _fail(k: int) -> Res:
    return _E, _F, _E, _F, _E, _F, k


@njit(cache=True)
def _first_empty(zlo: float, zhi: float, alo: float, ahi: float, blo: float, bhi: float) -> int:
    if not (zlo <= zhi):
        return 0
    if not (alo <= ahi):
        return 1
    if not (blo <= bhi):
        return 2
    return -1


@njit(cache=True)
def _piece(j: int, p1lo: float, p1hi: float, p2lo: float, p2hi: float) -> tuple[float, float]:
    # piece number j of the periodic solution set: P1 + 2k pi (j = 2k), P2 + 2k pi
    # (j = 2k + 1), outward rounded
    kk = float(j >> 1)
    if kk >= 0.0:
        slo = c.mul_dn(kk, c.TWO_PI_LO)
        shi = c.mul_up(kk, c.TWO_PI_HI)
    else:
        slo = c.mul_dn(kk, c.TWO_PI_HI)
        shi = c.mul_up(kk, c.TWO_PI_LO)
    if j & 1:
        return c.add(p2lo, p2hi, slo, shi)
    return c.add(p1lo, p1hi, slo, shi)


@njit(cache=True)
def _periodic_bwd(
    xlo: float, xhi: float, p1lo: float, p1hi: float, p2lo: float, p2hi: float
) -> tuple[float, float]:
    """Contract ``[x]`` to the hull of ``[x] & U_k (P1 + 2k pi  U  P2 + 2k pi)``.

    ``P1 <= P2`` are the two solution pieces inside one period (outward
    rounded, each narrower than pi, ``P2`` starting less than 2 pi after
    ``P1``), so the pieces ``..., P1+2k pi, P2+2k pi, P1+2(k+1)pi, ...``
    are increasing. The first/last piece meeting ``[x]`` is found from a
    floating-point guess ``ceil((xlo - P.hi) / 2 pi)``; when that guess is
    within a relative 2**-44 of an integer (where rounding could make it one
    piece late) the previous pieces are checked in interval arithmetic, so no
    solution is lost.
    """
    if not (p1lo <= p1hi) or not (p2lo <= p2hi):
        return _E, _F
    if abs(xlo) > 2.0**40 or abs(xhi) > 2.0**40:
        return xlo, xhi
    # lower end: first piece whose upper end reaches xlo
    t1 = (xlo - p1hi) * _INV_TWO_PI
    t2 = (xlo - p2hi) * _INV_TWO_PI
    e1 = abs(t1) * 2.0**-44 + 2.0**-44
    e2 = abs(t2) * 2.0**-44 + 2.0**-44
    k1 = math.ceil(t1)
    k2 = math.ceil(t2)
    j = min(2 * k1, 2 * k2 + 1)
    if math.ceil(t1 - e1) != math.ceil(t1 + e1) or math.ceil(t2 - e2) != math.ceil(t2 + e2):
        # the guess may be one piece late: move back while the previous piece
        # may still reach xlo (checked in interval arithmetic)
        for _ in range(8):
            a, b = _piece(j - 1, p1lo, p1hi, p2lo, p2hi)
            if b < xlo:
                break
            j -= 1
    nlo = _E
    for _ in range(8):
        a, b = _piece(j, p1lo, p1hi, p2lo, p2hi)
        if b < xlo:
            j += 1
            continue
        if a > xhi:
            return _E, _F
        nlo = a if a > xlo else xlo
        break
    if nlo == _E:  # not reached (pieces are < 2 pi apart); stay safe
        return xlo, xhi
    # upper end: last piece whose lower end reaches down to xhi
    t1 = (xhi - p1lo) * _INV_TWO_PI
    t2 = (xhi - p2lo) * _INV_TWO_PI
    e1 = abs(t1) * 2.0**-44 + 2.0**-44
    e2 = abs(t2) * 2.0**-44 + 2.0**-44
    k1 = math.floor(t1)
    k2 = math.floor(t2)
    j = max(2 * k1, 2 * k2 + 1)
    if math.floor(t1 - e1) != math.floor(t1 + e1) or math.floor(t2 - e2) != math.floor(t2 + e2):
        for _ in range(8):
            a, b = _piece(j + 1, p1lo, p1hi, p2lo, p2hi)
            if a > xhi:
                break
            j += 1
    for _ in range(8):
        a, b = _piece(j, p1lo, p1hi, p2lo, p2hi)
        if a > xhi:
            j -= 1
            continue
        return nlo, (b if b < xhi else xhi)
    return nlo, xhi


@njit(cache=True)
def ctc_add(zlo: float, zhi: float, xlo: float, xhi: float, ylo: float, yhi: float,
            mode: int = 3) -> Res:
    """HC4-revise of ``z = x + y``."""
    k = _first_empty(zlo, zhi, xlo, xhi, ylo, yhi)
    if k >= 0:
        return _fail(k)
    if mode & 1:
        zlo, zhi = c.inter(zlo, zhi, *c.add(xlo, xhi, ylo, yhi))
        if not (zlo <= zhi):
            return _fail(0)
    if mode & 2:
        xlo, xhi = c.inter(xlo, xhi, *c.sub(zlo, zhi, ylo, yhi))
        if not (xlo <= xhi):
            return _fail(1)
        ylo, yhi = c.inter(ylo, yhi, *c.sub(zlo, zhi, xlo, xhi))
        if not (ylo <= yhi):
            return _fail(2)
    return zlo, zhi, xlo, xhi, ylo, yhi, -1


@njit(cache=True)
def ctc_sub(zlo: float, zhi: float, xlo: float, xhi: float, ylo: float, yhi: float,
            mode: int = 3) -> Res:
    """HC4-revise of ``z = x - y``."""
    k = _first_empty(zlo, zhi, xlo, xhi, ylo, yhi)
    if k >= 0:
        return _fail(k)
    if mode & 1:
        zlo, zhi = c.inter(zlo, zhi, *c.sub(xlo, xhi, ylo, yhi))
        if not (zlo <= zhi):
            return _fail(0)
    if mode & 2:
        xlo, xhi = c.inter(xlo, xhi, *c.add(zlo, zhi, ylo, yhi))
        if not (xlo <= xhi):
            return _fail(1)
        ylo, yhi = c.inter(ylo, yhi, *c.sub(xlo, xhi, zlo, zhi))
        if not (ylo <= yhi):
            return _fail(2)
    return zlo, zhi, xlo, xhi, ylo, yhi, -1


@njit(cache=True)
def ctc_mul(zlo: float, zhi: float, xlo: float, xhi: float, ylo: float, yhi: float,
            mode: int = 3) -> Res:
    """HC4-revise of ``z = x * y`` (relational division: ``y`` containing 0
    still contracts ``x`` unless ``z`` contains 0 too)."""
    k = _first_empty(zlo, zhi, xlo, xhi, ylo, yhi)
    if k >= 0:
        return _fail(k)
    if mode & 1:
        zlo, zhi = c.inter(zlo, zhi, *c.mul(xlo, xhi, ylo, yhi))
        if not (zlo <= zhi):
            return _fail(0)
    if mode & 2:
        xlo, xhi = c.inter_two(xlo, xhi, *c.div_rel(zlo, zhi, ylo, yhi))
        if not (xlo <= xhi):
            return _fail(1)
        ylo, yhi = c.inter_two(ylo, yhi, *c.div_rel(zlo, zhi, xlo, xhi))
        if not (ylo <= yhi):
            return _fail(2)
    return zlo, zhi, xlo, xhi, ylo, yhi, -1


@njit(cache=True)
def ctc_div(zlo: float, zhi: float, xlo: float, xhi: float, ylo: float, yhi: float,
            mode: int = 3) -> Res:
    """HC4-revise of ``z = x / y`` (``y != 0``)."""
    k = _first_empty(zlo, zhi, xlo, xhi, ylo, yhi)
    if k >= 0:
        return _fail(k)
    if mode & 1:
        zlo, zhi = c.inter(zlo, zhi, *c.div(xlo, xhi, ylo, yhi))
        if not (zlo <= zhi):
            return _fail(0)
    if mode & 2:
        xlo, xhi = c.inter(xlo, xhi, *c.mul(zlo, zhi, ylo, yhi))
        if not (xlo <= xhi):
            return _fail(1)
        ylo, yhi = c.inter_two(ylo, yhi, *c.div_rel(xlo, xhi, zlo, zhi))
        if not (ylo <= yhi):
            return _fail(2)
    return zlo, zhi, xlo, xhi, ylo, yhi, -1


@njit(cache=True)
def ctc_sqr(zlo: float, zhi: float, xlo: float, xhi: float, mode: int = 3) -> Res:
    """HC4-revise of ``z = x**2`` (backward: ``x in +-sqrt(z)``, two pieces hulled
    after intersecting each with ``x``)."""
    k = _first_empty(zlo, zhi, xlo, xhi, 0.0, 0.0)
    if k >= 0:
        return _fail(k)
    if mode & 1:
        zlo, zhi = c.inter(zlo, zhi, *c.sqr(xlo, xhi))
        if not (zlo <= zhi):
            return _fail(0)
    if mode & 2:
        slo, shi = c.sqrt(zlo, zhi)
        if not (slo <= shi):
            return _fail(0)
        xlo, xhi = c.inter_two(xlo, xhi, -shi, -slo, slo, shi)
        if not (xlo <= xhi):
            return _fail(1)
    return zlo, zhi, xlo, xhi, 0.0, 0.0, -1


@njit(cache=True)
def ctc_sqrt(zlo: float, zhi: float, xlo: float, xhi: float, mode: int = 3) -> Res:
    """HC4-revise of ``z = sqrt(x)`` (``x >= 0``, ``z >= 0``)."""
    k = _first_empty(zlo, zhi, xlo, xhi, 0.0, 0.0)
    if k >= 0:
        return _fail(k)
    zlo, zhi = c.inter(zlo, zhi, 0.0, INF)
    if not (zlo <= zhi):
        return _fail(0)
    if mode & 1:
        zlo, zhi = c.inter(zlo, zhi, *c.sqrt(xlo, xhi))
        if not (zlo <= zhi):
            return _fail(0)
    if mode & 2:
        slo, shi = c.sqr(zlo, zhi)
        xlo, xhi = c.inter(xlo, xhi, slo, shi)
        if not (xlo <= xhi):
            return _fail(1)
    return zlo, zhi, xlo, xhi, 0.0, 0.0, -1


@njit(cache=True)
def ctc_neg(zlo: float, zhi: float, xlo: float, xhi: float, mode: int = 3) -> Res:
    """HC4-revise of ``z = -x``."""
    k = _first_empty(zlo, zhi, xlo, xhi, 0.0, 0.0)
    if k >= 0:
        return _fail(k)
    if mode & 1:
        zlo, zhi = c.inter(zlo, zhi, -xhi, -xlo)
        if not (zlo <= zhi):
            return _fail(0)
    if mode & 2:
        xlo, xhi = c.inter(xlo, xhi, -zhi, -zlo)
        if not (xlo <= xhi):
            return _fail(1)
    return zlo, zhi, xlo, xhi, 0.0, 0.0, -1


@njit(cache=True)
def ctc_eq(zlo: float, zhi: float, xlo: float, xhi: float, mode: int = 3) -> Res:
    """Contractor of ``z = x`` (both become the intersection)."""
    k = _first_empty(zlo, zhi, xlo, xhi, 0.0, 0.0)
    if k >= 0:
        return _fail(k)
    if mode & 1:
        zlo, zhi = c.inter(zlo, zhi, xlo, xhi)
        if not (zlo <= zhi):
            return _fail(0)
    if mode & 2:
        xlo, xhi = c.inter(xlo, xhi, zlo, zhi)
        if not (xlo <= xhi):
            return _fail(1)
    return zlo, zhi, xlo, xhi, 0.0, 0.0, -1


@njit(cache=True)
def ctc_exp(zlo: float, zhi: float, xlo: float, xhi: float, mode: int = 3) -> Res:
    """HC4-revise of ``z = exp(x)``."""
    k = _first_empty(zlo, zhi, xlo, xhi, 0.0, 0.0)
    if k >= 0:
        return _fail(k)
    if mode & 1:
        zlo, zhi = c.inter(zlo, zhi, *c.exp(xlo, xhi))
        if not (zlo <= zhi):
            return _fail(0)
    if mode & 2:
        xlo, xhi = c.inter(xlo, xhi, *c.log(zlo, zhi))
        if not (xlo <= xhi):
            return _fail(1)
    return zlo, zhi, xlo, xhi, 0.0, 0.0, -1


@njit(cache=True)
def ctc_log(zlo: float, zhi: float, xlo: float, xhi: float, mode: int = 3) -> Res:
    """HC4-revise of ``z = log(x)`` (``x > 0``)."""
    k = _first_empty(zlo, zhi, xlo, xhi, 0.0, 0.0)
    if k >= 0:
        return _fail(k)
    if mode & 1:
        zlo, zhi = c.inter(zlo, zhi, *c.log(xlo, xhi))
        if not (zlo <= zhi):
            return _fail(0)
    if mode & 2:
        xlo, xhi = c.inter(xlo, xhi, *c.exp(zlo, zhi))
        if not (xlo <= xhi):
            return _fail(1)
    return zlo, zhi, xlo, xhi, 0.0, 0.0, -1


@njit(cache=True)
def ctc_sin(zlo: float, zhi: float, xlo: float, xhi: float, mode: int = 3) -> Res:
    """HC4-revise of ``z = sin(x)``; backward over all periods met by ``x``."""
    k = _first_empty(zlo, zhi, xlo, xhi, 0.0, 0.0)
    if k >= 0:
        return _fail(k)
    if mode & 1:
        zlo, zhi = c.inter(zlo, zhi, *c.sin(xlo, xhi))
        if not (zlo <= zhi):
            return _fail(0)
    if mode & 2:
        alo, ahi = c.asin(zlo, zhi)
        if not (alo <= ahi):
            return _fail(0)
        blo, bhi = c.sub(c.PI_LO, c.PI_HI, alo, ahi)
        xlo, xhi = _periodic_bwd(xlo, xhi, alo, ahi, blo, bhi)
        if not (xlo <= xhi):
            return _fail(1)
    return zlo, zhi, xlo, xhi, 0.0, 0.0, -1


@njit(cache=True)
def ctc_cos(zlo: float, zhi: float, xlo: float, xhi: float, mode: int = 3) -> Res:
    """HC4-revise of ``z = cos(x)``; backward over all periods met by ``x``."""
    k = _first_empty(zlo, zhi, xlo, xhi, 0.0, 0.0)
    if k >= 0:
        return _fail(k)
    if mode & 1:
        zlo, zhi = c.inter(zlo, zhi, *c.cos(xlo, xhi))
        if not (zlo <= zhi):
            return _fail(0)
    if mode & 2:
        alo, ahi = c.acos(zlo, zhi)
        if not (alo <= ahi):
            return _fail(0)
        xlo, xhi = _periodic_bwd(xlo, xhi, -ahi, -alo, alo, ahi)
        if not (xlo <= xhi):
            return _fail(1)
    return zlo, zhi, xlo, xhi, 0.0, 0.0, -1


@njit(cache=True)
def _tan_dn(x: float) -> float:
    return 0.0 if x == 0.0 else c.lib_dn(math.tan(x))


@njit(cache=True)
def _tan_up(x: float) -> float:
    return 0.0 if x == 0.0 else c.lib_up(math.tan(x))


@njit(cache=True)
def _cot_dn(x: float) -> float:
    return c.lib_dn(c.lib_dn(math.cos(x) / math.sin(x)))


@njit(cache=True)
def _cot_up(x: float) -> float:
    return c.lib_up(c.lib_up(math.cos(x) / math.sin(x)))


@njit(cache=True)
def _atan2_quadrant(
    q: int, zlo: float, zhi: float, ylo: float, yhi: float, xlo: float, xhi: float
) -> tuple[float, float, float, float]:
    """Contract the part of the box in quadrant ``q`` (1..4) with angle in ``[z]``.

    Inside one closed quadrant ``y = x tan(z)`` and ``x = y cot(z)`` hold for
    every point (the origin included), with ``tan`` and ``cot`` monotone;
    bounds at the quadrant's edges are taken as 0 or infinite, outward.
    """
    PI_LO = c.PI_LO
    cvalid = True
    H_LO = c.HALF_PI_LO
    H_HI = c.HALF_PI_HI
    if q == 1:  # angles [0, pi/2], x >= 0, y >= 0
        a, b = c.inter(zlo, zhi, 0.0, H_HI)
        ylo, yhi = c.inter(ylo, yhi, 0.0, INF)
        xlo, xhi = c.inter(xlo, xhi, 0.0, INF)
        if not (a <= b) or not (ylo <= yhi) or not (xlo <= xhi):
            return _E, _F, _E, _F
        tlo = 0.0 if a <= 0.0 else _tan_dn(a)
        thi = INF if b >= H_LO else _tan_up(b)
        if b <= 0.0:  # only the angle 0, where cot is undefined
            cvalid = False
            clo = 0.0
        else:
            clo = 0.0 if b >= H_LO else _cot_dn(b)
        chi = INF if a <= 0.0 else _cot_up(a)
    elif q == 2:  # angles [pi/2, pi], x <= 0, y >= 0
        a, b = c.inter(zlo, zhi, H_LO, c.PI_HI)
        ylo, yhi = c.inter(ylo, yhi, 0.0, INF)
        xlo, xhi = c.inter(xlo, xhi, -INF, 0.0)
        if not (a <= b) or not (ylo <= yhi) or not (xlo <= xhi):
            return _E, _F, _E, _F
        tlo = -INF if a <= H_HI else _tan_dn(a)
        thi = 0.0 if b >= PI_LO else _tan_up(b)
        clo = -INF if b >= PI_LO else _cot_dn(b)
        chi = 0.0 if a <= H_HI else _cot_up(a)
    elif q == 3:  # angles [-pi, -pi/2], x <= 0, y <= 0
        a, b = c.inter(zlo, zhi, -c.PI_HI, -H_LO)
        ylo, yhi = c.inter(ylo, yhi, -INF, 0.0)
        xlo, xhi = c.inter(xlo, xhi, -INF, 0.0)
        if not (a <= b) or not (ylo <= yhi) or not (xlo <= xhi):
            return _E, _F, _E, _F
        tlo = 0.0 if a <= -PI_LO else _tan_dn(a)
        thi = INF if b >= -H_HI else _tan_up(b)
        clo = 0.0 if b >= -H_HI else _cot_dn(b)
        chi = INF if a <= -PI_LO else _cot_up(a)
    else:  # angles [-pi/2, 0], x >= 0, y <= 0
        a, b = c.inter(zlo, zhi, -H_HI, 0.0)
        ylo, yhi = c.inter(ylo, yhi, -INF, 0.0)
        xlo, xhi = c.inter(xlo, xhi, 0.0, INF)
        if not (a <= b) or not (ylo <= yhi) or not (xlo <= xhi):
            return _E, _F, _E, _F
        tlo = -INF if a <= -H_LO else _tan_dn(a)
        thi = 0.0 if b >= 0.0 else _tan_up(b)
        clo = -INF if b >= 0.0 else _cot_dn(b)
        if a >= 0.0:  # only the angle 0, where cot is undefined
            cvalid = False
            chi = 0.0
        else:
            chi = 0.0 if a <= -H_LO else _cot_up(a)
    # y = x tan z fails where tan is infinite (angle +-pi/2, x = 0), so the
    # product step needs a bounded tan; the division step is safe (its
    # closure contains 0). Likewise for x = y cot z at angles 0, pi.
    if tlo > -INF and thi < INF:
        ylo, yhi = c.inter(ylo, yhi, *c.mul(xlo, xhi, tlo, thi))
        if not (ylo <= yhi):
            return _E, _F, _E, _F
    xlo, xhi = c.inter_two(xlo, xhi, *c.div_rel(ylo, yhi, tlo, thi))
    if not (xlo <= xhi):
        return _E, _F, _E, _F
    if cvalid:
        if clo > -INF and chi < INF:
            xlo, xhi = c.inter(xlo, xhi, *c.mul(ylo, yhi, clo, chi))
            if not (xlo <= xhi):
                return _E, _F, _E, _F
        ylo, yhi = c.inter_two(ylo, yhi, *c.div_rel(xlo, xhi, clo, chi))
        if not (ylo <= yhi):
            return _E, _F, _E, _F
    return ylo, yhi, xlo, xhi


@njit(cache=True)
def ctc_atan2(zlo: float, zhi: float, ylo: float, yhi: float, xlo: float, xhi: float,
              mode: int = 3) -> Res:
    """HC4-revise of ``z = atan2(y, x)`` (arguments in the order ``y, x``).

    Backward: the box is split into its four closed quadrants; in each, the
    part whose angle can lie in ``[z]`` is contracted with ``y = x tan z`` and
    ``x = y cot z`` (monotone there), and the results are hulled.
    """
    k = _first_empty(zlo, zhi, ylo, yhi, xlo, xhi)
    if k >= 0:
        return _fail(k)
    zlo, zhi = c.inter(zlo, zhi, -c.PI_HI, c.PI_HI)
    if not (zlo <= zhi):
        return _fail(0)
    if mode & 1:
        zlo, zhi = c.inter(zlo, zhi, *c.atan2(ylo, yhi, xlo, xhi))
        if not (zlo <= zhi):
            return _fail(0)
    if mode & 2:
        nylo = _E
        nyhi = _F
        nxlo = _E
        nxhi = _F
        for q in range(1, 5):
            a, b, d, e = _atan2_quadrant(q, zlo, zhi, ylo, yhi, xlo, xhi)
            if a <= b and d <= e:
                nylo, nyhi = c.hull(nylo, nyhi, a, b)
                nxlo, nxhi = c.hull(nxlo, nxhi, d, e)
        if not (nylo <= nyhi):
            return _fail(1)
        ylo, yhi, xlo, xhi = nylo, nyhi, nxlo, nxhi
    return zlo, zhi, ylo, yhi, xlo, xhi, -1


@njit(cache=True)
def revise(op: int, zlo: float, zhi: float, alo: float, ahi: float, blo: float, bhi: float,
           mode: int) -> Res:
    """Dispatch on an operation code (see module docstring); unary operations
    ignore ``b`` and return it unchanged (also on failure)."""
    if op == OP_ADD:
        return ctc_add(zlo, zhi, alo, ahi, blo, bhi, mode)
    if op == OP_SUB:
        return ctc_sub(zlo, zhi, alo, ahi, blo, bhi, mode)
    if op == OP_MUL:
        return ctc_mul(zlo, zhi, alo, ahi, blo, bhi, mode)
    if op == OP_DIV:
        return ctc_div(zlo, zhi, alo, ahi, blo, bhi, mode)
    if op == OP_ATAN2:
        return ctc_atan2(zlo, zhi, alo, ahi, blo, bhi, mode)
    if op == OP_SQR:
        r = ctc_sqr(zlo, zhi, alo, ahi, mode)
    elif op == OP_SQRT:
        r = ctc_sqrt(zlo, zhi, alo, ahi, mode)
    elif op == OP_SIN:
        r = ctc_sin(zlo, zhi, alo, ahi, mode)
    elif op == OP_COS:
        r = ctc_cos(zlo, zhi, alo, ahi, mode)
    elif op == OP_NEG:
        r = ctc_neg(zlo, zhi, alo, ahi, mode)
    elif op == OP_EXP:
        r = ctc_exp(zlo, zhi, alo, ahi, mode)
    elif op == OP_LOG:
        r = ctc_log(zlo, zhi, alo, ahi, mode)
    else:
        r = ctc_eq(zlo, zhi, alo, ahi, mode)
    if r[6] >= 0:
        return _E, _F, _E, _F, blo, bhi, r[6]
    return r[0], r[1], r[2], r[3], blo, bhi, -1
