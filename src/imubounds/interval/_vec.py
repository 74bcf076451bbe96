"""Compiled element-wise loops over the scalar rules of :mod:`._core`.

Generated text (one loop per rule, so each caches separately); arrays must be
1-D, C-contiguous float64 of equal length. The public, broadcasting API is
:class:`imubounds.interval.IntervalArray`.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from imubounds.interval import _core as c


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
