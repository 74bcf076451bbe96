"""Angle intervals that survive the wrap at +-pi.

An angle interval is stored as an ordinary real interval ``[lo, hi]`` (rad)
-- its *branch* -- and means the set ``{theta + 2 k pi : theta in [lo, hi],
k integer}`` on the circle. Any width ``>= 2 pi`` is the full circle.
Arithmetic (adding a rate times a time step, say) is ordinary interval
arithmetic on the branch; only comparisons between angles (intersection,
membership) need the modulo, and those are here.

* :func:`angle_inter` returns ``[a] & ([b] + 2 pi Z)`` expressed in the
  branch of ``[a]``. The true set can be two pieces (when the two arcs
  overlap at both ends); the scalar form returns both pieces, the hull form
  returns their hull in ``[a]``'s branch (always a superset, documented).
* :func:`wrap` moves a branch so that its midpoint lies in ``[-pi, pi]``.

The shifts by ``2 k pi`` are done in interval arithmetic (pi enclosed by two
doubles), so results are guaranteed supersets.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit

from imubounds.interval import _core as c
from imubounds.interval.array import IntervalArray
from imubounds.interval.rounding import check_rounding

_E = math.inf
_F = -math.inf


@njit(cache=True)
def _shift(lo: float, hi: float, k: float) -> tuple[float, float]:
    slo, shi = c.mul(k, k, c.TWO_PI_LO, c.TWO_PI_HI)
    return c.add(lo, hi, slo, shi)


@njit(cache=True)
def is_full(lo: float, hi: float) -> bool:
    """True if the angle interval covers the whole circle (width >= 2 pi)."""
    return lo <= hi and c.sub_up(hi, lo) >= c.TWO_PI_LO


@njit(cache=True)
def wrap(lo: float, hi: float) -> tuple[float, float]:
    """Same angle set with the branch's midpoint in ``[-pi, pi]``
    (full circle -> ``[-pi, pi]``, outward)."""
    if not (lo <= hi):
        return _E, _F
    if is_full(lo, hi) or math.isinf(lo) or math.isinf(hi):
        return -c.PI_HI, c.PI_HI
    m = 0.5 * lo + 0.5 * hi
    k = -math.floor((m + c.PI_LO) / c.TWO_PI_LO)
    if k == 0.0:
        return lo, hi
    return _shift(lo, hi, k)


@njit(cache=True)
def angle_inter_pieces(
    alo: float, ahi: float, blo: float, bhi: float
) -> tuple[float, float, float, float]:
    """``[a] & ([b] + 2 pi Z)`` in the branch of ``[a]``, as up to two pieces.

    Returns ``(lo1, hi1, lo2, hi2)``; an unused piece is empty. If ``[a]`` is
    the full circle the result is ``[b]`` (in ``[b]``'s branch, one piece); if
    ``[b]`` is the full circle it is ``[a]``.
    """
    if not (alo <= ahi) or not (blo <= bhi):
        return _E, _F, _E, _F
    if is_full(blo, bhi):
        return alo, ahi, _E, _F
    if is_full(alo, ahi):
        return blo, bhi, _E, _F
    ma = 0.5 * alo + 0.5 * ahi
    mb = 0.5 * blo + 0.5 * bhi
    k0 = math.floor((ma - mb) / c.TWO_PI_LO + 0.5)
    r1lo = _E
    r1hi = _F
    r2lo = _E
    r2hi = _F
    for j in range(5):
        k = k0 + (j - 2)
        slo, shi = _shift(blo, bhi, k)
        plo, phi = c.inter(alo, ahi, slo, shi)
        if not (plo <= phi):
            continue
        if not (r1lo <= r1hi):
            r1lo, r1hi = plo, phi
        elif not (r2lo <= r2hi):
            r2lo, r2hi = plo, phi
        else:  # a third sliver (only through outward rounding): merge into piece 2
            r2lo, r2hi = c.hull(r2lo, r2hi, plo, phi)
    return r1lo, r1hi, r2lo, r2hi


@njit(cache=True)
def angle_inter(alo: float, ahi: float, blo: float, bhi: float) -> tuple[float, float]:
    """Hull (in ``[a]``'s branch) of ``[a] & ([b] + 2 pi Z)``; empty if disjoint."""
    l1, h1, l2, h2 = angle_inter_pieces(alo, ahi, blo, bhi)
    return c.hull(l1, h1, l2, h2)


@njit(cache=True)
def angle_contains(lo: float, hi: float, theta: float) -> bool:
    """True if the angle ``theta`` (rad, any branch) is in the angle interval."""
    l1, h1, l2, h2 = angle_inter_pieces(lo, hi, theta, theta)
    return (l1 <= h1) or (l2 <= h2)


@njit(cache=True)
def _v_inter(alo, ahi, blo, bhi, pieces):  # type: ignore[no-untyped-def]
    n = alo.size
    out = np.empty((4, n))
    for i in range(n):
        l1, h1, l2, h2 = angle_inter_pieces(alo[i], ahi[i], blo[i], bhi[i])
        if pieces:
            out[0, i], out[1, i], out[2, i], out[3, i] = l1, h1, l2, h2
        else:
            out[0, i], out[1, i] = c.hull(l1, h1, l2, h2)
            out[2, i] = _E
            out[3, i] = _F
    return out


@njit(cache=True)
def _v_wrap(lo, hi):  # type: ignore[no-untyped-def]
    n = lo.size
    olo = np.empty(n)
    ohi = np.empty(n)
    for i in range(n):
        olo[i], ohi[i] = wrap(lo[i], hi[i])
    return olo, ohi


def _prep(a: Any, b: Any) -> tuple[tuple[int, ...], list[np.ndarray]]:
    check_rounding()
    aa = IntervalArray.coerce(a)
    bb = IntervalArray.coerce(b)
    parts = np.broadcast_arrays(aa.lo, aa.hi, bb.lo, bb.hi)
    return parts[0].shape, [np.ascontiguousarray(p, dtype=np.float64).reshape(-1) for p in parts]


def intersect(a: Any, b: Any) -> IntervalArray:
    """Vectorised :func:`angle_inter`: hull, in ``a``'s branch, of ``a & (b + 2 pi Z)``."""
    shape, f = _prep(a, b)
    out = _v_inter(f[0], f[1], f[2], f[3], False)
    return IntervalArray._raw(out[0].reshape(shape), out[1].reshape(shape))


def intersect_pieces(a: Any, b: Any) -> tuple[IntervalArray, IntervalArray]:
    """Vectorised :func:`angle_inter_pieces`: the (up to) two pieces in ``a``'s branch."""
    shape, f = _prep(a, b)
    out = _v_inter(f[0], f[1], f[2], f[3], True)
    return (IntervalArray._raw(out[0].reshape(shape), out[1].reshape(shape)),
            IntervalArray._raw(out[2].reshape(shape), out[3].reshape(shape)))


def wrap_array(a: Any) -> IntervalArray:
    """Vectorised :func:`wrap`."""
    check_rounding()
    aa = IntervalArray.coerce(a)
    lo, hi = _v_wrap(np.ascontiguousarray(aa.lo, float).reshape(-1),
                     np.ascontiguousarray(aa.hi, float).reshape(-1))
    return IntervalArray._raw(lo.reshape(aa.shape), hi.reshape(aa.shape))


def contains(a: Any, theta: Any) -> np.ndarray:
    """Vectorised :func:`angle_contains`."""
    shape, f = _prep(a, theta)
    out = _v_inter(f[0], f[1], f[2], f[3], True)
    return ((out[0] <= out[1]) | (out[2] <= out[3])).reshape(shape)
