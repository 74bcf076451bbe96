"""accel_y (docs/dynamic-method.md, section 3, **accel_y**): ``(v(b) - v(a))/tau +
mean(r u) + g mean(sin phi cos theta)`` plus the Earth rate, with ``mean(r u) =
u0 mean(r) + mean((u - u0) r)``: mean(r) from the heading difference, the second term by
``max|u - u0| mean|r|``; with velocity epochs also per heading gap
(:func:`transport_by_gaps`, its speed part also as one weighted mean:
:mod:`.transport_weighted`), positions only also over blocks of fix gaps
(:func:`~imubounds.dynamic.estimator.aided.transport_fixes.transport_by_fixes`) and from
the gyro's shape (:func:`~imubounds.dynamic.estimator.aided.transport_gyro.transport_by_gyro`),
the narrowest."""

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
    SPEED_LEVELS,
    _rate_terms,
    transport_by_fixes,
)
from imubounds.dynamic.estimator.aided.transport_gyro import transport_by_gyro
from imubounds.dynamic.estimator.aided.transport_weighted import gap_weights, weighted_speed
from imubounds.dynamic.estimator.aided.velocity import body_velocity, vel_range
from imubounds.dynamic.estimator.aided.yaw import q_window_mean
from imubounds.dynamic.estimator.window_plan import ChannelPlan, LevelPlan
from imubounds.interval import IntervalArray as IA

#: the share of the window's gyro-deviation probability given to the bound of mean|q|
#: (its term, ``u x mean|q| x tan(max tilt)``, is small: a share of 0.1 costs it little)
Q_SHARE = 0.1
#: boxcar windows with velocity epochs: the share of that probability for the weighted
#: speed part of :func:`transport_by_gaps` (:mod:`.transport_weighted`)
W_SHARE = 0.3
#: positions only: the share of that probability for the support's mean |r| in
#: :func:`~imubounds.dynamic.estimator.aided.transport_fixes.transport_by_fixes`
SUP_SHARE = 0.35
#: positions only: the share for the gyro-shape form
#: (:func:`~imubounds.dynamic.estimator.aided.transport_gyro.transport_by_gyro`)
GYRO_SHARE = 0.1


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




def _knot_rows(w: WindowContext, t: np.ndarray) -> np.ndarray:
    """Rows ``(m, rho, ok)`` of the heading at ``t``: centre (0 where unbounded), radius
    rounded up (inf there) and 1.0 where finite."""
    psi = heading_at(w, t)
    ok = np.isfinite(psi.lo) & np.isfinite(psi.hi)
    m = np.where(ok, psi.mid(), 0.0)
    rho = np.where(ok, up(np.maximum(psi.hi - m, m - psi.lo)), np.inf)
    return np.column_stack([m, rho, ok.astype(float)])


def _gap_rows(w: WindowContext, bv: Any, ga: np.ndarray, gb: np.ndarray) -> np.ndarray:
    """Rows ``(u0, max|u|, du)`` of u over the gaps ``[ga, gb]``: centre, magnitude and
    half-range rounded up (:func:`~imubounds.dynamic.estimator.aided.velocity.vel_range`)."""
    rng = vel_range(w, bv, ga, gb)
    ulo, uhi = rng["u_lo"], rng["u_hi"]
    u0 = 0.5 * (ulo + uhi)
    du = up(np.maximum(uhi - u0, u0 - ulo))
    return np.column_stack([u0, np.maximum(np.abs(ulo), np.abs(uhi)), du])


def _gap_terms(
    w: WindowContext, ga: np.ndarray, gb: np.ndarray, du: np.ndarray, d0: np.ndarray,
    earth: float,
) -> np.ndarray:
    """Per gap and level d0: ``(du - d0)+ int |r|``, ``int |r|`` by the gyro's magnitude on
    the gap (+ the Earth's rates), each rounded up."""
    coarse = up(up(w.gyro_abs_mean("gyro_z", ga, gb) + earth) * (gb - ga))
    return up(np.maximum(du[:, None] - d0[None, :], 0.0) * coarse[:, None])


def _speed_levels(
    dmax: np.ndarray, ex: np.ndarray, d0: np.ndarray, tau: np.ndarray, r_mag: np.ndarray,
    earth: float,
) -> np.ndarray:
    """Bound of ``(1/tau) sum_k du_k int_k |r|`` over each window's gaps (``du_k`` the
    half-range of u on gap k): for a level ``d0``, ``du_k <= d0 + (du_k - d0)+``, so the
    sum is at most ``d0 mean|r| + (1/tau) sum_k (du_k - d0)+ int_k |r|`` (``ex``, per
    level), ``mean|r| <= r_mag`` and ``int_k |r|`` by the gyro's magnitude on the gap; the
    smallest over the levels ``d0`` (quantiles of every window's gaps' ``du``) and
    ``max du x r_mag`` (``dmax``). r is relative to the navigation frame: the gyro's
    bounds plus ``earth`` (:func:`_rate_terms`)."""
    r_mag = up(r_mag + earth)
    best = up(dmax * r_mag)
    for d in range(d0.size):
        cand = up((d0[d] * r_mag + up(ex[:, d] * (1 + 1e-12)) / tau) * (1 + 1e-12))
        best = np.minimum(best, cand)
    return best


def _trip_gaps(w: WindowContext, bv: Any) -> tuple[np.ndarray, np.ndarray]:
    """The heading epochs' knot rows and the rows of the gaps between consecutive heading
    epochs (the same for every window: computed once per run)."""
    key = "accel_y_trip_gaps"
    if key not in w.cache:
        ht = w.ag.head_t
        w.cache[key] = (_knot_rows(w, ht), _gap_rows(w, bv, ht[:-1], ht[1:]))
    return w.cache[key]


def window_gaps(
    ht: np.ndarray, a: np.ndarray, b: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Windows ``[a, b]`` cut at the heading epochs ``ht``: they hold ``ht[k0 .. k1-1]``;
    the first gap is ``[a, fb]`` (``fb = ht[k0]``, ``b`` without an epoch inside), the
    last ``[la, b]`` (``la = ht[k1 - 1]``, only used where there is an epoch inside)."""
    k0 = np.searchsorted(ht, a, side="right")
    k1 = np.maximum(np.searchsorted(ht, b, side="left"), k0)
    has = k1 > k0
    last = ht.size - 1
    fb = np.where(has, ht[np.minimum(k0, last)], b)
    la = np.where(has, ht[np.clip(k1 - 1, 0, last)], a)
    return k0, k1, fb, la


def weighted_floors(
    w: WindowContext, bv: Any, a: np.ndarray, b: np.ndarray, fb: np.ndarray,
    la: np.ndarray, has: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The floors ``(fb, wf, la, wl)`` of :func:`.transport_weighted.weighted_speed`: the
    gyro-free half-ranges of u on each window's first and last gaps (``la = +inf``
    where the window holds no heading epoch: its one gap is the first)."""
    wf = gap_weights(w, bv, a, fb)
    wl = np.where(has, gap_weights(w, bv, la, b), 0.0)
    return fb, wf, np.where(has, la, np.inf), wl


def transport_by_gaps(
    w: WindowContext,
    lp: LevelPlan,
    tau: np.ndarray,
    bv: Any,
    r_mag: np.ndarray,
    q_mean: np.ndarray | None = None,
    p_weighted: float = 0.0,
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
    Coriolis term); the second within ``sum_k half-range_k(u) int_k |r|``
    (:func:`_speed_levels`), or with ``p_weighted > 0`` the smaller of that and the
    weighted bound of :func:`.transport_weighted.weighted_speed` (holding with
    probability ``>= 1 - p_weighted`` per window: the gyro centred on blocks of heading
    gaps, each sample's |r| weighted by its gap's half-range). The per-window sums:
    :func:`.gap_sums.gap_sums` (compiled; the gaps between heading epochs computed once
    per run)."""
    from imubounds.dynamic.estimator.aided.gap_sums import gap_sums

    a, b = lp.a1, lp.b2
    ht = w.ag.head_t
    n = a.size
    k0, k1, fb, la = window_gaps(ht, a, b)
    ni = k1 - k0
    knot_h, gap_g = _trip_gaps(w, bv)
    has = ni >= 1
    gap_f = _gap_rows(w, bv, a, fb)
    gap_l = _gap_rows(w, bv, la, b)
    # the levels d0: quantiles of the half-ranges of every window's gaps (as a multiset:
    # the inner gap g counts once per window holding it)
    inner = ni >= 2
    cnt = np.zeros(ht.size, dtype=np.int64)
    np.add.at(cnt, k0[inner], 1)
    np.add.at(cnt, k1[inner] - 1, -1)
    cnt = np.cumsum(cnt)[: max(ht.size - 1, 0)]
    c0, ext, earth = _rate_terms(w, lp, tau, q_mean)
    if n == 0:
        return IA(np.zeros(0), np.zeros(0))
    dus = np.concatenate([np.repeat(gap_g[:, 2], cnt), gap_f[:, 2], gap_l[has, 2]])
    d0 = np.quantile(dus, SPEED_LEVELS)
    del dus
    ex_g = _gap_terms(w, ht[:-1], ht[1:], gap_g[:, 2], d0, earth)
    ex_f = _gap_terms(w, a, fb, gap_f[:, 2], d0, earth)
    ex_l = _gap_terms(w, la, b, gap_l[:, 2], d0, earth)
    cen, rad, mag, ok, umax, dmax, ex = gap_sums(
        k0.astype(np.int64), k1.astype(np.int64), _knot_rows(w, a), _knot_rows(w, b),
        knot_h, gap_f, gap_l, gap_g, ex_f, ex_l, ex_g)
    nk = ni + 2
    rad = up((rad + (nk + 6) * _EPS * 4 * mag + 1e-300) * (1 + 1e-12))
    speed = _speed_levels(dmax, ex, d0, tau, r_mag, earth)
    if p_weighted > 0:
        floors = weighted_floors(w, bv, a, b, fb, la, has)
        speed = np.minimum(speed, weighted_speed(w, lp, tau, bv, p_weighted, floors, earth))
    head = (IA(cen) + pm(np.where(ok, rad, 0.0))) / IA(tau) * IA(c0)
    x = head + pm(up(umax * ext)) + pm(speed)
    return IA(np.where(ok, x.lo, -np.inf), np.where(ok, x.hi, np.inf))


def gyro_deviation_bounds(
    w: WindowContext, lp: LevelPlan, tau: np.ndarray, sup_share: float = 0.0
) -> tuple[np.ndarray, np.ndarray]:
    """The transport term's two gyro bounds, sharing the window's second bounded event
    (the first is the band's; ``full._plan_windows`` counts two per accelerometer window)
    (``Q_SHARE`` of its probability to the second, ``sup_share`` kept for the support's
    mean |r| of :func:`~imubounds.dynamic.estimator.aided.transport_fixes.transport_by_fixes`
    and the gyro-shape form (``SUP_SHARE + GYRO_SHARE`` with positions only), the rest to
    the first, ``sup_share`` also standing for :data:`W_SHARE` of the weighted speed part):
    the kernel mean of |r| (``aided.transport.r_abs``) and
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
    bv = body_velocity(w)
    gaps = not plan.trapezoid and bv is not None and w.ag.has_heading
    share = SUP_SHARE + GYRO_SHARE if fixes else (W_SHARE if gaps else 0.0)
    r_mag, q_mean = gyro_deviation_bounds(w, lp, tau, share)
    mean_r = mean_r_from_heading(w, lp, tau, plan.trapezoid, q_mean)
    u0 = 0.5 * (rng["u_lo"] + rng["u_hi"])
    du = up(0.5 * (rng["u_hi"] - rng["u_lo"]))
    ru = IA(u0) * mean_r + pm(du * r_mag)
    if gaps:
        # the narrower of the two enclosures of mean(r u), per window
        rg = transport_by_gaps(w, lp, tau, bv, r_mag, q_mean, W_SHARE * w.p_window)
        use = (rg.hi - rg.lo) < (ru.hi - ru.lo)
        ru = IA(np.where(use, rg.lo, ru.lo), np.where(use, rg.hi, ru.hi))
    if fixes:
        rf = transport_by_fixes(w, lp, tau, r_mag, q_mean, SUP_SHARE * w.p_window)
        use = (rf.hi - rf.lo) < (ru.hi - ru.lo)
        ru = IA(np.where(use, rf.lo, ru.lo), np.where(use, rf.hi, ru.hi))
        rg = transport_by_gyro(w, lp, tau, rng["u_lo"], rng["u_hi"], GYRO_SHARE * w.p_window)
        use = (rg.hi - rg.lo) < (ru.hi - ru.lo)
        ru = IA(np.where(use, rg.lo, ru.lo), np.where(use, rg.hi, ru.hi))
    grav = w.tilt.kmean("g_sinr_cosp", lp, tau)
    x = (ends["v2"] - ends["v1"]) / IA(tau) + ru + grav + h.earth
    if w.veh.vertical_bound > 0:  # p w, |w| <= the vertical (heave) bound
        x = x + pm(rng["w_max"] * w.kernel_mag("gyro_x", lp, tau))
    return x
