"""The per-window sums of accel_y's transport term cut at the heading epochs
(:func:`~imubounds.dynamic.estimator.aided.transport_gaps.transport_by_gaps`), compiled.

A window ``[a, b]`` holds the heading epochs ``ht[k0 .. k1-1]`` (``k1 - k0 = ni``); its
knots are ``a``, those epochs and ``b``, and its gaps the ``ni + 1`` spans between them:
the first ``[a, ht[k0]]`` (``[a, b]`` when ``ni = 0``), the inner ones the spans between
consecutive heading epochs, the same for every window (computed once per trip), and the
last ``[ht[k1-1], b]``. The kernel walks each window's knots and gaps in order and adds
sequentially; the vectorised form (``tests/transport_gaps_reference.py``, which
materialised every window's knots: O(windows x knots) memory, 1.1 GB more on a 24 h
trip, 3x the time on a 4 h one) sums pairwise, so the two differ in the last bits; the
caller's radius carries the rounding of any order (``(nk + 6) 4 eps`` x the sum of the
terms' magnitudes).
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def _maximum(x: float, y: float) -> float:
    """``np.maximum`` of two floats (NaN propagates)."""
    if x != x or y != y:
        return np.nan
    return x if x >= y else y


@njit(cache=True)
def gap_sums(  # noqa: PLR0913 (the kernel takes its arrays one by one)
    k0: np.ndarray,
    k1: np.ndarray,
    knot_a: np.ndarray,
    knot_b: np.ndarray,
    knot_h: np.ndarray,
    gap_f: np.ndarray,
    gap_l: np.ndarray,
    gap_g: np.ndarray,
    ex_f: np.ndarray,
    ex_l: np.ndarray,
    ex_g: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per window: ``cen = sum_j w_j (m_j - m_0)``, ``rad = sum_j |w_j| rho_j``, ``mag =
    sum_j |w_j| (|m_j - m_0| + rho_j + |m_j| + |m_0|)``, ``ok`` (every knot's heading
    finite), the largest ``|u|`` and half-range of u over its gaps, and per level d0 the
    sum of the gaps' terms ``ex``. Knots: rows ``(m, rho, ok)`` of ``knot_a`` / ``knot_b``
    (the window's ends) and ``knot_h`` (the heading epochs); gaps: rows ``(u0, umax,
    du)`` of ``gap_f`` / ``gap_l`` (the window's first and last) and ``gap_g`` (between
    consecutive heading epochs), with their ``ex`` rows. ``w_j`` = u0 of the gap before
    knot j minus u0 of the gap after it (0 outside the window)."""
    n = k0.size
    nd = ex_g.shape[1]
    cen = np.empty(n)
    rad = np.empty(n)
    mag = np.empty(n)
    ok = np.empty(n, dtype=np.bool_)
    umax = np.zeros(n)
    dmax = np.zeros(n)
    ex = np.zeros((n, nd))
    for i in range(n):
        ni = k1[i] - k0[i]
        ref = knot_a[i, 0]
        prev_u0 = 0.0  # u0 of the gap before the current knot
        for j in range(ni + 2):
            if j == 0:
                m, rho, okk = knot_a[i, 0], knot_a[i, 1], knot_a[i, 2]
            elif j <= ni:
                h = k0[i] + j - 1
                m, rho, okk = knot_h[h, 0], knot_h[h, 1], knot_h[h, 2]
            else:
                m, rho, okk = knot_b[i, 0], knot_b[i, 1], knot_b[i, 2]
            # the gap after knot j (none after the last)
            if j == ni + 1:
                u_after = 0.0
            elif j == 0:
                u_after = gap_f[i, 0]
            elif j == ni:
                u_after = gap_l[i, 0]
            else:
                u_after = gap_g[k0[i] + j - 1, 0]
            wj = prev_u0 - u_after
            ms = m - ref
            aw = abs(wj)
            t1 = wj * ms
            t2 = aw * rho
            t3 = aw * (((abs(ms) + rho) + abs(m)) + abs(ref))
            if j == 0:
                cen[i], rad[i], mag[i], ok[i] = t1, t2, t3, okk != 0.0
            else:
                cen[i] += t1
                rad[i] += t2
                mag[i] += t3
                ok[i] = ok[i] and okk != 0.0
            prev_u0 = u_after
        for p in range(ni + 1):
            if p == 0:
                um, du = gap_f[i, 1], gap_f[i, 2]
                for d in range(nd):
                    ex[i, d] += ex_f[i, d]
            elif p == ni:
                um, du = gap_l[i, 1], gap_l[i, 2]
                for d in range(nd):
                    ex[i, d] += ex_l[i, d]
            else:
                g = k0[i] + p - 1
                um, du = gap_g[g, 1], gap_g[g, 2]
                for d in range(nd):
                    ex[i, d] += ex_g[g, d]
            umax[i] = _maximum(umax[i], um)
            dmax[i] = _maximum(dmax[i], du)
    return cen, rad, mag, ok, umax, dmax, ex
