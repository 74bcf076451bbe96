"""Compiled element-wise loops over the scalar rules of :mod:`._core`.

Generated text (one loop per rule, so each caches separately); arrays must be
1-D, C-contiguous float64 of equal length. The public, broadcasting API is
:class:`imubounds.interval.IntervalArray`.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from imubounds.interval import _core as c
from imubounds.interval import _ctc as k


@njit(cache=True)
def v_neg(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    n = lo.size
    olo = np.empty(n)
    ohi = np.empty(n)
    for i in range(n):
        olo[i], ohi[i] = c.neg(lo[i], hi[i])
    return olo, ohi


@njit(cache=True)
def v_absval(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    n = lo.size
    olo = np.empty(n)
    ohi = np.empty(n)
    for i in range(n):
        olo[i], ohi[i] = c.absval(lo[i], hi[i])
    return olo, ohi


@njit(cache=True)
def v_sqr(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    n = lo.size
    olo = np.empty(n)
    ohi = np.empty(n)
    for i in range(n):
        olo[i], ohi[i] = c.sqr(lo[i], hi[i])
    return olo, ohi


@njit(cache=True)
def v_sqrt(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    n = lo.size
    olo = np.empty(n)
    ohi = np.empty(n)
    for i in range(n):
        olo[i], ohi[i] = c.sqrt(lo[i], hi[i])
    return olo, ohi


@njit(cache=True)
def v_exp(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    n = lo.size
    olo = np.empty(n)
    ohi = np.empty(n)
    for i in range(n):
        olo[i], ohi[i] = c.exp(lo[i], hi[i])
    return olo, ohi


@njit(cache=True)
def v_log(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    n = lo.size
    olo = np.empty(n)
    ohi = np.empty(n)
    for i in range(n):
        olo[i], ohi[i] = c.log(lo[i], hi[i])
    return olo, ohi


@njit(cache=True)
def v_sin(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    n = lo.size
    olo = np.empty(n)
    ohi = np.empty(n)
    for i in range(n):
        olo[i], ohi[i] = c.sin(lo[i], hi[i])
    return olo, ohi


@njit(cache=True)
def v_cos(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    n = lo.size
    olo = np.empty(n)
    ohi = np.empty(n)
    for i in range(n):
        olo[i], ohi[i] = c.cos(lo[i], hi[i])
    return olo, ohi


@njit(cache=True)
def v_tan(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    n = lo.size
    olo = np.empty(n)
    ohi = np.empty(n)
    for i in range(n):
        olo[i], ohi[i] = c.tan(lo[i], hi[i])
    return olo, ohi


@njit(cache=True)
def v_asin(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    n = lo.size
    olo = np.empty(n)
    ohi = np.empty(n)
    for i in range(n):
        olo[i], ohi[i] = c.asin(lo[i], hi[i])
    return olo, ohi


@njit(cache=True)
def v_acos(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    n = lo.size
    olo = np.empty(n)
    ohi = np.empty(n)
    for i in range(n):
        olo[i], ohi[i] = c.acos(lo[i], hi[i])
    return olo, ohi


@njit(cache=True)
def v_add(
    alo: np.ndarray, ahi: np.ndarray, blo: np.ndarray, bhi: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    n = alo.size
    olo = np.empty(n)
    ohi = np.empty(n)
    for i in range(n):
        olo[i], ohi[i] = c.add(alo[i], ahi[i], blo[i], bhi[i])
    return olo, ohi


@njit(cache=True)
def v_sub(
    alo: np.ndarray, ahi: np.ndarray, blo: np.ndarray, bhi: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    n = alo.size
    olo = np.empty(n)
    ohi = np.empty(n)
    for i in range(n):
        olo[i], ohi[i] = c.sub(alo[i], ahi[i], blo[i], bhi[i])
    return olo, ohi


@njit(cache=True)
def v_mul(
    alo: np.ndarray, ahi: np.ndarray, blo: np.ndarray, bhi: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    n = alo.size
    olo = np.empty(n)
    ohi = np.empty(n)
    for i in range(n):
        olo[i], ohi[i] = c.mul(alo[i], ahi[i], blo[i], bhi[i])
    return olo, ohi


@njit(cache=True)
def v_div(
    alo: np.ndarray, ahi: np.ndarray, blo: np.ndarray, bhi: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    n = alo.size
    olo = np.empty(n)
    ohi = np.empty(n)
    for i in range(n):
        olo[i], ohi[i] = c.div(alo[i], ahi[i], blo[i], bhi[i])
    return olo, ohi


@njit(cache=True)
def v_atan2(
    alo: np.ndarray, ahi: np.ndarray, blo: np.ndarray, bhi: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    n = alo.size
    olo = np.empty(n)
    ohi = np.empty(n)
    for i in range(n):
        olo[i], ohi[i] = c.atan2(alo[i], ahi[i], blo[i], bhi[i])
    return olo, ohi


@njit(cache=True)
def v_imin(
    alo: np.ndarray, ahi: np.ndarray, blo: np.ndarray, bhi: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    n = alo.size
    olo = np.empty(n)
    ohi = np.empty(n)
    for i in range(n):
        olo[i], ohi[i] = c.imin(alo[i], ahi[i], blo[i], bhi[i])
    return olo, ohi


@njit(cache=True)
def v_imax(
    alo: np.ndarray, ahi: np.ndarray, blo: np.ndarray, bhi: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    n = alo.size
    olo = np.empty(n)
    ohi = np.empty(n)
    for i in range(n):
        olo[i], ohi[i] = c.imax(alo[i], ahi[i], blo[i], bhi[i])
    return olo, ohi


@njit(cache=True)
def v_inter(
    alo: np.ndarray, ahi: np.ndarray, blo: np.ndarray, bhi: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    n = alo.size
    olo = np.empty(n)
    ohi = np.empty(n)
    for i in range(n):
        olo[i], ohi[i] = c.inter(alo[i], ahi[i], blo[i], bhi[i])
    return olo, ohi


@njit(cache=True)
def v_hull(
    alo: np.ndarray, ahi: np.ndarray, blo: np.ndarray, bhi: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    n = alo.size
    olo = np.empty(n)
    ohi = np.empty(n)
    for i in range(n):
        olo[i], ohi[i] = c.hull(alo[i], ahi[i], blo[i], bhi[i])
    return olo, ohi


@njit(cache=True)
def v_width(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    n = lo.size
    out = np.empty(n)
    for i in range(n):
        out[i] = c.width(lo[i], hi[i])
    return out


@njit(cache=True)
def v_mid(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    n = lo.size
    out = np.empty(n)
    for i in range(n):
        out[i] = c.mid(lo[i], hi[i])
    return out


@njit(cache=True)
def v_radius(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    n = lo.size
    out = np.empty(n)
    for i in range(n):
        out[i] = c.radius(lo[i], hi[i])
    return out


@njit(cache=True)
def v_revise(
    op: int,
    zlo: np.ndarray,
    zhi: np.ndarray,
    alo: np.ndarray,
    ahi: np.ndarray,
    blo: np.ndarray,
    bhi: np.ndarray,
    mode: int,
    code: np.ndarray,
) -> None:
    """In place: HC4-revise of primitive ``op`` on every box; ``code[i]`` gets
    the position of the variable emptied first (-1 if consistent). The
    dispatch on ``op`` is outside the loops (one loop per primitive)."""
    n = zlo.size
    if op == k.OP_ADD:
        for i in range(n):
            r = k.ctc_add(zlo[i], zhi[i], alo[i], ahi[i], blo[i], bhi[i], mode)
            zlo[i], zhi[i], alo[i], ahi[i], blo[i], bhi[i] = r[0], r[1], r[2], r[3], r[4], r[5]
            code[i] = r[6]
    elif op == k.OP_SUB:
        for i in range(n):
            r = k.ctc_sub(zlo[i], zhi[i], alo[i], ahi[i], blo[i], bhi[i], mode)
            zlo[i], zhi[i], alo[i], ahi[i], blo[i], bhi[i] = r[0], r[1], r[2], r[3], r[4], r[5]
            code[i] = r[6]
    elif op == k.OP_MUL:
        for i in range(n):
            r = k.ctc_mul(zlo[i], zhi[i], alo[i], ahi[i], blo[i], bhi[i], mode)
            zlo[i], zhi[i], alo[i], ahi[i], blo[i], bhi[i] = r[0], r[1], r[2], r[3], r[4], r[5]
            code[i] = r[6]
    elif op == k.OP_DIV:
        for i in range(n):
            r = k.ctc_div(zlo[i], zhi[i], alo[i], ahi[i], blo[i], bhi[i], mode)
            zlo[i], zhi[i], alo[i], ahi[i], blo[i], bhi[i] = r[0], r[1], r[2], r[3], r[4], r[5]
            code[i] = r[6]
    elif op == k.OP_ATAN2:
        for i in range(n):
            r = k.ctc_atan2(zlo[i], zhi[i], alo[i], ahi[i], blo[i], bhi[i], mode)
            zlo[i], zhi[i], alo[i], ahi[i], blo[i], bhi[i] = r[0], r[1], r[2], r[3], r[4], r[5]
            code[i] = r[6]
    elif op == k.OP_SQR:
        for i in range(n):
            r = k.ctc_sqr(zlo[i], zhi[i], alo[i], ahi[i], mode)
            zlo[i], zhi[i], alo[i], ahi[i] = r[0], r[1], r[2], r[3]
            code[i] = r[6]
    elif op == k.OP_SQRT:
        for i in range(n):
            r = k.ctc_sqrt(zlo[i], zhi[i], alo[i], ahi[i], mode)
            zlo[i], zhi[i], alo[i], ahi[i] = r[0], r[1], r[2], r[3]
            code[i] = r[6]
    elif op == k.OP_SIN:
        for i in range(n):
            r = k.ctc_sin(zlo[i], zhi[i], alo[i], ahi[i], mode)
            zlo[i], zhi[i], alo[i], ahi[i] = r[0], r[1], r[2], r[3]
            code[i] = r[6]
    elif op == k.OP_COS:
        for i in range(n):
            r = k.ctc_cos(zlo[i], zhi[i], alo[i], ahi[i], mode)
            zlo[i], zhi[i], alo[i], ahi[i] = r[0], r[1], r[2], r[3]
            code[i] = r[6]
    elif op == k.OP_NEG:
        for i in range(n):
            r = k.ctc_neg(zlo[i], zhi[i], alo[i], ahi[i], mode)
            zlo[i], zhi[i], alo[i], ahi[i] = r[0], r[1], r[2], r[3]
            code[i] = r[6]
    elif op == k.OP_EXP:
        for i in range(n):
            r = k.ctc_exp(zlo[i], zhi[i], alo[i], ahi[i], mode)
            zlo[i], zhi[i], alo[i], ahi[i] = r[0], r[1], r[2], r[3]
            code[i] = r[6]
    elif op == k.OP_LOG:
        for i in range(n):
            r = k.ctc_log(zlo[i], zhi[i], alo[i], ahi[i], mode)
            zlo[i], zhi[i], alo[i], ahi[i] = r[0], r[1], r[2], r[3]
            code[i] = r[6]
    elif op == k.OP_EQ:
        for i in range(n):
            r = k.ctc_eq(zlo[i], zhi[i], alo[i], ahi[i], mode)
            zlo[i], zhi[i], alo[i], ahi[i] = r[0], r[1], r[2], r[3]
            code[i] = r[6]
    else:
        raise ValueError("unknown operation code")
