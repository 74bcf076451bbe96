"""Relaxed (q-relaxed) intersection of m intervals tolerating q outliers (Jaulin).

The q-relaxed intersection of sets X_1..X_m is the set of points that belong
to at least ``m - q`` of them. :func:`qinter_1d` returns its hull for m intervals,
exactly (coverage only changes at endpoints), compiled so that the estimators' numba
loops call it. Empty intervals count as outliers (they contain no point); with
``q >= m`` every point qualifies and the result is the whole line.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def qinter_1d(lo: np.ndarray, hi: np.ndarray, m: int, q: int) -> tuple[float, float]:
    """Hull of the points lying in at least ``m - q`` of the closed intervals ``[lo_i, hi_i]``.

    Exact in one dimension (coverage only changes at endpoints); empty intervals
    count as outliers; empty result if no point is covered often enough.
    """
    need = m - q
    if need <= 0:
        return -np.inf, np.inf
    best_lo = np.inf
    best_hi = -np.inf
    for i in range(m):
        if not (lo[i] <= hi[i]):
            continue
        c_lo = 0
        c_hi = 0
        for j in range(m):
            if lo[j] <= hi[j]:
                if lo[j] <= lo[i] <= hi[j]:
                    c_lo += 1
                if lo[j] <= hi[i] <= hi[j]:
                    c_hi += 1
        if c_lo >= need and lo[i] < best_lo:
            best_lo = lo[i]
        if c_hi >= need and hi[i] > best_hi:
            best_hi = hi[i]
    if best_lo > best_hi:
        return np.inf, -np.inf
    return best_lo, best_hi
