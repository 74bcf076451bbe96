"""accel_y (docs/dynamic-method.md, section 3, **accel_y**): ``(v(b) - v(a))/tau +
mean(r u) + g mean(sin phi cos theta)`` plus the Earth rate, with ``mean(r u) =
u0 mean(r) + mean((u - u0) r)``: mean(r) from the heading difference, the second term by
``max|u - u0| mean|r|``; with velocity epochs also per heading gap
(:func:`transport_by_gaps`), positions only also over blocks of fix gaps
(:func:`~imubounds.dynamic.estimator.aided.transport_fixes.transport_by_fixes`), the
narrower of the two."""

from __future__ import annotations

from typing import Any

import numpy as np

from imubounds.dynamic.estimator.aided.base import pm, up
from imubounds.dynamic.estimator.aided.common import WindowContext
from imubounds.dynamic.estimator.aided.heading import heading_at, heading_mean, r_from_psidot
from imubounds.dynamic.estimator.aided.horizontal import horizontal_terms
from imubounds.dynamic.estimator.aided.transport import r_abs
from imubounds.dynamic.estimator.aided.transport_fixes import (
    _EPS,
    _rate_terms,
    _speed_part,
    transport_by_fixes,
)
from imubounds.dynamic.estimator.aided.velocity import body_velocity, vel_range
from imubounds.dynamic.estimator.aided.yaw import q_window_mean
from imubounds.dynamic.estimator.window_plan import ChannelPlan, LevelPlan
from imubounds.interval import IntervalArray as IA

#: the share of the window's gyro-deviation probability given to the bound of mean|q|
#: (its term, ``u x mean|q| x tan(max tilt)``, is small: a share of 0.1 costs it little)
Q_SHARE = 0.1
#: positions only: the share of that probability for the support's mean |r| in
#: :func:`~imubounds.dynamic.estimator.aided.transport_fixes.transport_by_fixes`
SUP_SHARE = 0.45


def mean_r_from_heading(
    w: WindowContext,
    lp: LevelPlan,
    tau: np.ndarray,
    trapezoid: bool,
    q_mean: np.ndarray | None = None,
) -> IA:
    """Kernel mean of the yaw rate r from the heading (for accel_y's transport term);
    ``q_mean`` a bound of the kernel mean of |q| (else gyro_y's magnitude)."""
    if trapezoid:
        p1 = heading_mean(w, lp.a1, lp.b1)
        p2 = heading_mean(w, lp.a2, lp.b2)
    else:
        p1 = heading_at(w, lp.a1)
        p2 = heading_at(w, lp.a2)
    dpsi = (p2 - p1) / IA(tau)
    return r_from_psidot(w, dpsi, lp, tau, own_q=True, q_mean=q_mean)


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
    w: WindowContext,
    lp: LevelPlan,
    tau: np.ndarray,
    bv: Any,
    r_mag: np.ndarray,
    q_mean: np.ndarray | None = None,
) -> IA:
    """``mean(r u)`` over boxcar windows, cut at the heading epochs inside: on gap k,
    ``u = u0_k + (u - u0_k)`` with ``u0_k`` the centre of u's range over the gap
    (:func:`~imubounds.dynamic.estimator.aided.velocity.vel_range`), so
    ``tau mean(r u) = sum_k u0_k int_k r + sum_k int_k (u - u0_k) r``. With
    ``r = psi' c - q tan(phi)`` (c within ``c0 +- cdev``): the first sum is
    ``c0 sum_k u0_k (psi_k+1 - psi_k)`` (by parts: ``sum_j psi_j w_j`` with ``w_j =
    u0_j-1 - u0_j``, so each heading box enters once, weighted by the CHANGE of u0, not
    twice by u0) plus ``max|u0| tau (rate cdev + (mean|q| + earth) tan)``
    (:func:`_rate_terms`: r relative to the navigation frame, the Earth's rates in the
    Coriolis term); the second within ``sum_k half-range_k(u) int_k |r|`` (:func:`_speed_part`)."""
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
    c0, ext, earth = _rate_terms(w, lp, tau, q_mean)
    speed = _speed_part(w, gwin, ga, gb, du, a.size, tau, r_mag, earth)
    head = (IA(cen) + pm(np.where(ok, rad, 0.0))) / IA(tau) * IA(c0)
    x = head + pm(up(umax * ext)) + pm(speed)
    return IA(np.where(ok, x.lo, -np.inf), np.where(ok, x.hi, np.inf))


def gyro_deviation_bounds(
    w: WindowContext, lp: LevelPlan, tau: np.ndarray, sup_share: float = 0.0
) -> tuple[np.ndarray, np.ndarray]:
    """The transport term's two gyro bounds, sharing the window's second bounded event
    (the first is the band's; ``full._plan_windows`` counts two per accelerometer window)
    (``Q_SHARE`` of its probability to the second, ``sup_share`` kept for the support's
    mean |r| of :func:`~imubounds.dynamic.estimator.aided.transport_fixes.transport_by_fixes`,
    the rest to the first): the kernel mean of |r| (``aided.transport.r_abs``) and
    of |q| for the tilt coupling ``q tan(phi)`` of r (``aided.yaw.q_window_mean``)."""
    p = w.p_window
    try:
        w.p_window = (1.0 - Q_SHARE - sup_share) * p
        r_mag = r_abs(w, lp, tau)
    finally:
        w.p_window = p
    return r_mag, q_window_mean(w, lp, tau, Q_SHARE * p)


def accel_y(w: WindowContext, plan: ChannelPlan, lp: LevelPlan, tau: np.ndarray) -> IA:
    """``[x_W]`` of accel_y."""
    h = horizontal_terms(w, plan, lp, tau)
    ends, rng = h.ends, h.rng
    fixes = plan.trapezoid and w.ag.has_heading and w.ag.gnss_t.size > 2
    r_mag, q_mean = gyro_deviation_bounds(w, lp, tau, SUP_SHARE if fixes else 0.0)
    mean_r = mean_r_from_heading(w, lp, tau, plan.trapezoid, q_mean)
    u0 = 0.5 * (rng["u_lo"] + rng["u_hi"])
    du = up(0.5 * (rng["u_hi"] - rng["u_lo"]))
    ru = IA(u0) * mean_r + pm(du * r_mag)
    bv = body_velocity(w)
    if not plan.trapezoid and bv is not None and w.ag.has_heading:
        # the narrower of the two enclosures of mean(r u), per window
        rg = transport_by_gaps(w, lp, tau, bv, r_mag, q_mean)
        use = (rg.hi - rg.lo) < (ru.hi - ru.lo)
        ru = IA(np.where(use, rg.lo, ru.lo), np.where(use, rg.hi, ru.hi))
    if fixes:
        rf = transport_by_fixes(w, lp, tau, r_mag, q_mean, SUP_SHARE * w.p_window)
        use = (rf.hi - rf.lo) < (ru.hi - ru.lo)
        ru = IA(np.where(use, rf.lo, ru.lo), np.where(use, rf.hi, ru.hi))
    grav = w.tilt.kmean("g_sinr_cosp", lp, tau)
    x = (ends["v2"] - ends["v1"]) / IA(tau) + ru + grav + h.earth
    if w.veh.vertical_bound > 0:  # p w, |w| <= the vertical (heave) bound
        x = x + pm(rng["w_max"] * w.kernel_mag("gyro_x", lp, tau))
    return x
