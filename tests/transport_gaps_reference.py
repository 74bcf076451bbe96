"""Plain reference of accel_y's transport term cut at the heading epochs
(:func:`imubounds.dynamic.estimator.aided.transport_gaps.transport_by_gaps`): the vectorised
form that materialises every window's knots (O(windows x knots) memory), kept to test
the compiled per-window sums (:mod:`imubounds.dynamic.estimator.aided.gap_sums`) bit for
bit against."""

from __future__ import annotations

from typing import Any

import numpy as np

from imubounds.dynamic.estimator.aided.base import pm, up
from imubounds.dynamic.estimator.aided.heading import heading_at
from imubounds.dynamic.estimator.aided.transport_terms import rate_terms, speed_part
from imubounds.dynamic.estimator.aided.velocity import vel_range
from imubounds.interval import IntervalArray as IA

_EPS = 2.3e-16


def _knots(ht: np.ndarray, a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, ...]:
    """Per boxcar window [a, b]: its ends and the heading epochs strictly inside, all
    windows concatenated: the knots, their window's index, their position in it, and
    each window's first knot and knot count."""
    k0 = np.searchsorted(ht, a, side="right")
    k1 = np.maximum(np.searchsorted(ht, b, side="left"), k0)
    nk = (k1 - k0) + 2
    start = np.concatenate([[0], np.cumsum(nk)[:-1]])
    win = np.repeat(np.arange(a.size), nk)
    pos = np.arange(int(np.sum(nk))) - start[win]
    last = pos == nk[win] - 1
    inner = np.clip(k0[win] + pos - 1, 0, max(ht.size - 1, 0))
    t = np.where(pos == 0, a[win], np.where(last, b[win], ht[inner] if ht.size else 0.0))
    return t, win, pos, start, nk


def transport_by_gaps(
    w: Any,
    lp: Any,
    tau: np.ndarray,
    bv: Any,
    r_mag: np.ndarray,
    q_mean: np.ndarray | None = None,
) -> IA:
    """The vectorised form of ``transport_gaps.transport_by_gaps`` (same arguments, same
    equations): every window's knots materialised."""
    a, b = lp.a1, lp.b2
    t, win, pos, start, nk = _knots(w.ag.head_t, a, b)
    psi = heading_at(w, t)
    ok_k = np.isfinite(psi.lo) & np.isfinite(psi.hi)
    m = np.where(ok_k, psi.mid(), 0.0)
    rho = np.where(ok_k, up(np.maximum(psi.hi - m, m - psi.lo)), np.inf)
    ref = m[start]
    ms = m - ref[win]  # the heading relative to the window's first knot
    # u over each gap (knot j to j + 1 of the same window)
    gap = pos < nk[win] - 1
    ga, gb = t[gap], t[1:][gap[:-1]] if t.size > 1 else t[:0]
    rng = vel_range(w, bv, ga, gb)
    ulo, uhi = rng["u_lo"], rng["u_hi"]
    u0 = 0.5 * (ulo + uhi)
    du = up(np.maximum(uhi - u0, u0 - ulo))
    # weight of knot j: u0 of the gap before it minus u0 of the gap after it
    u_after = np.zeros(t.size)
    u_after[gap] = u0
    u_before = np.zeros(t.size)
    u_before[1:][gap[:-1]] = u0
    wj = u_before - u_after
    cen = np.add.reduceat(wj * ms, start)
    rad = np.add.reduceat(np.abs(wj) * rho, start)
    mag = np.add.reduceat(np.abs(wj) * (np.abs(ms) + rho + np.abs(m) + np.abs(ref[win])), start)
    rad = up((rad + (nk + 6) * _EPS * 4 * mag + 1e-300) * (1 + 1e-12))
    ok = np.logical_and.reduceat(ok_k, start)
    gwin = win[gap]
    umax = np.zeros(a.size)
    np.maximum.at(umax, gwin, np.maximum(np.abs(ulo), np.abs(uhi)))
    c0, ext, earth = rate_terms(w, lp, tau, q_mean)
    speed = speed_part(w, gwin, ga, gb, du, a.size, tau, r_mag, earth)
    head = (IA(cen) + pm(np.where(ok, rad, 0.0))) / IA(tau) * IA(c0)
    x = head + pm(up(umax * ext)) + pm(speed)
    return IA(np.where(ok, x.lo, -np.inf), np.where(ok, x.hi, np.inf))
