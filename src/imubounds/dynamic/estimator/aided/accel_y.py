"""accel_y (docs/dynamic-method.md, section 3, **accel_y**): ``(v(b) - v(a))/tau +
mean(r u) + g mean(sin phi cos theta)`` plus the Earth rate, with ``mean(r u) =
u0 mean(r) + mean((u - u0) r)``: mean(r) from the heading difference, the second term by
``max|u - u0| mean|r|``; with velocity epochs also per heading gap
(:func:`transport_by_gaps`), the narrower of the two."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from imubounds.dynamic.estimator.aided.base import EARTH_RATE, G_HI, R_EARTH, pm, up
from imubounds.dynamic.estimator.aided.common import WindowContext
from imubounds.dynamic.estimator.aided.heading import heading_at, heading_mean, r_from_psidot
from imubounds.dynamic.estimator.aided.horizontal import horizontal_terms
from imubounds.dynamic.estimator.aided.positions import body_u_mean
from imubounds.dynamic.estimator.aided.transport import r_abs
from imubounds.dynamic.estimator.aided.velocity import body_velocity, speed_max, vel_range
from imubounds.dynamic.estimator.aided.yaw import q_window_mean
from imubounds.dynamic.estimator.window_plan import ChannelPlan, LevelPlan
from imubounds.interval import IntervalArray as IA

_EPS = 2.3e-16
#: the share of the window's gyro-deviation probability given to the bound of mean|q|
#: (its term, ``u x mean|q| x tan(max tilt)``, is small: a share of 0.1 costs it little)
Q_SHARE = 0.1
#: block lengths (in fix gaps) of the positions-only transport bound (:func:`transport_by_fixes`)
FIX_BLOCKS = (4, 6, 8, 12, 16, 24)


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


def _rate_terms(
    w: WindowContext, lp: LevelPlan, tau: np.ndarray, q_mean: np.ndarray | None
) -> tuple[np.ndarray, np.ndarray, float]:
    """``c0``, the radius of ``r - c0 psi'`` and the Earth's share of the gyro's rate.

    In ``f_y = v' + r u + ...`` r is the body's rate relative to the navigation frame,
    ``psi' c - q_nb tan(phi)`` (c = cos(theta)/cos(phi) within ``c0 +- cdev``); the
    Earth's rotation and the transport rate enter through the Coriolis term of
    :func:`~imubounds.dynamic.estimator.aided.horizontal.horizontal_terms`, so unlike
    gyro_z's :func:`~imubounds.dynamic.estimator.aided.heading.r_from_psidot` no Earth
    rate is added to r here. The gyros measure the inertial rates: ``|q_nb| <= |q| +
    earth`` and ``|r_nb| <= |r| + earth``, ``earth = Omega + max_speed/R_E``."""
    veh = w.veh
    c = w.tilt.hull("cosp_over_cosr", lp.a1, lp.b2)
    c0 = c.mid()
    cdev = up(np.maximum(c.hi - c0, c0 - c.lo))
    rate = veh.max_rate / math.cos(veh.max_tilt)
    q = w.kernel_mag("gyro_y", lp, tau) if q_mean is None else q_mean
    earth = float(up(np.asarray(EARTH_RATE + veh.max_speed / R_EARTH)))
    tr = w.tilt.hull("abs_tanr", lp.a1, lp.b2).hi
    ext = up(up(rate * cdev) + up(up(q + earth) * tr))
    return c0, ext, earth


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


def _speed_part(
    w: WindowContext,
    gwin: np.ndarray,
    ga: np.ndarray,
    gb: np.ndarray,
    du: np.ndarray,
    n: int,
    tau: np.ndarray,
    r_mag: np.ndarray,
    earth: float,
) -> np.ndarray:
    """Bound of ``(1/tau) sum_k du_k int_k |r|`` over each window's gaps (``du_k`` the
    half-range of u on gap k, ``gwin`` each gap's window): for a level ``d0``,
    ``du_k <= d0 + (du_k - d0)+``, so the sum is at most ``d0 mean|r| + (1/tau) sum_k
    (du_k - d0)+ int_k |r|``, ``mean|r| <= r_mag`` and ``int_k |r|`` by the gyro's
    magnitude on the gap; the smallest over a few levels ``d0`` (quantiles of ``du``,
    its maximum included, which gives ``max du x r_mag``). r is relative to the
    navigation frame: the gyro's bounds plus ``earth`` (:func:`_rate_terms`)."""
    r_mag = up(r_mag + earth)
    dmax = np.zeros(n)
    np.maximum.at(dmax, gwin, du)
    best = up(dmax * r_mag)
    if du.size == 0:
        return best
    coarse = up(up(w.gyro_abs_mean("gyro_z", ga, gb) + earth) * (gb - ga))
    for d0 in np.quantile(du, [0.25, 0.5, 0.65, 0.75, 0.85, 0.9, 0.95, 0.97, 0.99]):
        ex = np.zeros(n)
        np.add.at(ex, gwin, up(np.maximum(du - d0, 0.0) * coarse))
        cand = up((d0 * r_mag + up(ex * (1 + 1e-12)) / tau) * (1 + 1e-12))
        best = np.minimum(best, cand)
    return best


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


def _fix_blocks(t: np.ndarray, lp: LevelPlan, mb: int) -> tuple[np.ndarray, ...]:
    """Blocks of ``mb`` fix gaps over each trapezoid window's I1 and I2 (the last of each
    shorter): their first and last fix index, their window, and whether in I1."""
    p = np.searchsorted(t, lp.a1)
    m = np.searchsorted(t, lp.b1)
    q = np.searchsorted(t, lp.b2)
    s_l: list[np.ndarray] = []
    w_l: list[np.ndarray] = []
    for k in range(p.size):
        bnd = np.concatenate([np.arange(p[k], m[k], mb), np.arange(m[k], q[k], mb), [q[k]]])
        s_l.append(bnd)
        w_l.append(np.full(bnd.size, k))
    bnd_all = np.concatenate(s_l)
    win_all = np.concatenate(w_l)
    last = np.r_[win_all[1:] != win_all[:-1], True]
    s, e, win = bnd_all[~last], bnd_all[1:][~last[:-1]], win_all[~last]
    return s, e, win, e <= m[win]


def _gap_heading_sums(w: WindowContext) -> tuple[np.ndarray, np.ndarray]:
    """Prefix sums over the fix gaps of ``g x`` the heading hull's ends (computed once)."""
    if "fix_psi_sums" not in w.cache:
        t = w.ag.gnss_t
        hm = heading_mean(w, t[:-1], t[1:])
        g = np.diff(t)
        w.cache["fix_psi_sums"] = (
            np.concatenate([[0.0], np.cumsum(hm.lo * g)]),
            np.concatenate([[0.0], np.cumsum(hm.hi * g)]),
        )
    return w.cache["fix_psi_sums"]


def _u_deviation(w: WindowContext, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Bound of ``max_t |u(t) - mean_[a,b] u|`` over [a, b] (u the body forward velocity):
    ``u' = f_x - q w + r v - g sin(theta)`` (+ the Earth's Coriolis and transport terms),
    and per sample ``|f_x| <= (|y_x| + E0)/(1 - s)`` (as
    :meth:`~imubounds.dynamic.estimator.aided.common.WindowContext.mag_mean`), so
    ``|u'| <= k + h(t)`` with the constant ``k = E0/(1 - s) + v_max (max_rate + earth)
    + W max_rate + g_max |sin theta| + 2 Omega S + S^2/R_E`` and ``h = |y_x|/(1 - s)``
    (a magnitude use of the other channels, as
    :func:`~imubounds.dynamic.estimator.aided.velocity.gap_growth`). Then
    ``|u(t) - u(s)| <= k |t - s| + int_[a,b] h``, and ``|u(t) - mean u| <= mean_s
    |u(t) - u(s)| <= k (b - a)/2 + int_[a,b] h``; also ``<= max_accel (b - a)/2``."""
    veh = w.veh
    ln = b - a
    S = speed_max(w, a, b)
    vl = veh.lateral_speed_bound_mps
    vmax = S if vl is None else np.minimum(S, vl)
    earth = EARTH_RATE + S / R_EARTH
    k = up(
        vmax * (veh.max_rate + earth)
        + G_HI * w.tilt.hull("abs_sinp", a, b).hi
        + 2 * EARTH_RATE * S + S * S / R_EARTH
        + veh.vertical_bound * veh.max_rate
    )
    if w.imu.available["accel_x"]:
        cn = w.ctx.noise["accel_x"]
        k = up(k + w.ctx.E0["accel_x"] / (1.0 - cn.scale))
        h = up(w.imu.sig["accel_x"].abs_integral(a, b) / (1.0 - cn.scale))
    else:
        k = up(k + w.imu.sig["accel_x"].xmax)
        h = np.zeros(np.shape(a))
    dev = up(up(k * ln * 0.5) + h)
    return up(np.minimum(dev, veh.max_accel * ln * 0.5) * (1 + 1e-12))


def _transport_fix_blocks(
    w: WindowContext, lp: LevelPlan, tau: np.ndarray, mb: int, r_mag: np.ndarray,
    q_mean: np.ndarray | None,
) -> IA:
    """:func:`transport_by_fixes` for blocks of ``mb`` fix gaps."""
    t = w.ag.gnss_t
    n = lp.a1.size
    s, e, win, in1 = _fix_blocks(t, lp, mb)
    ta, tb = t[s], t[e]
    ell = tb - ta
    ub = body_u_mean(w, s, e)
    fin = np.isfinite(ub.lo) & np.isfinite(ub.hi)
    cb = np.where(fin, ub.mid(), 0.0)
    du = np.where(fin, up(np.maximum(ub.hi - cb, cb - ub.lo) + _u_deviation(w, ta, tb)), np.inf)
    L1, L2 = lp.b1 - lp.a1, lp.b2 - lp.b1
    # the kernel's slope on each block, its value at each block's start
    kd = np.where(in1, 1.0 / (L1[win] * tau[win]), -1.0 / (L2[win] * tau[win]))
    k_at = np.where(in1, (ta - lp.a1[win]) / (L1[win] * tau[win]),
                    (lp.b2[win] - ta) / (L2[win] * tau[win]))
    first = np.r_[True, win[1:] != win[:-1]]
    start = np.flatnonzero(first)
    ref = heading_at(w, lp.a1).mid()
    ref = np.where(np.isfinite(ref), ref, 0.0)
    plo, phi = _gap_heading_sums(w)
    ib = IA(plo[e] - plo[s], phi[e] - phi[s]) + pm(1e-12 * (np.abs(plo[e]) + np.abs(phi[e]) + 1))
    ib = ib - IA(ell) * IA(ref[win])
    term = IA(-cb * kd) * ib
    # the jumps of C K at the inner block starts: -K(t_j) (c_j - c_j-1) psi(t_j)
    dc = np.where(first, 0.0, cb - np.r_[0.0, cb[:-1]])
    psi = heading_at(w, ta) - IA(ref[win])
    term = term + IA(-k_at * dc) * psi
    ok_t = np.isfinite(term.lo) & np.isfinite(term.hi) & fin
    lo = np.where(ok_t, term.lo, 0.0)
    hi = np.where(ok_t, term.hi, 0.0)
    mag = np.add.reduceat(np.maximum(np.abs(lo), np.abs(hi)), start)
    cnt = np.add.reduceat(np.ones(win.size), start)
    guard = up((cnt + 4) * _EPS * 4 * mag + 1e-300)
    head = IA(np.add.reduceat(lo, start) - guard, np.add.reduceat(hi, start) + guard)
    ok = np.logical_and.reduceat(ok_t, start)
    c0, ext, earth = _rate_terms(w, lp, tau, q_mean)
    kint = 0.5 * (L1 + L2) / tau  # int K (1 for the trapezoid)
    ok &= np.abs(kint - 1.0) < 1e-9
    umax = np.zeros(n)
    np.maximum.at(umax, win, np.abs(cb))
    speed = _speed_part(w, win, ta, tb, np.where(fin, du, 0.0), n, tau, r_mag, earth)
    x = head * IA(c0) + pm(up(umax * ext)) + pm(speed)
    return IA(np.where(ok, x.lo, -np.inf), np.where(ok, x.hi, np.inf))


def transport_by_fixes(
    w: WindowContext,
    lp: LevelPlan,
    tau: np.ndarray,
    r_mag: np.ndarray,
    q_mean: np.ndarray | None = None,
) -> IA:
    """``mean(r u)`` over trapezoid (positions-only) windows, the window cut into blocks
    B of a few fix gaps (I1's and I2's separately; the narrowest over
    :data:`FIX_BLOCKS`, each an enclosure). On B, u's mean ``u_B`` is known from the
    fixes (:func:`~imubounds.dynamic.estimator.aided.positions.body_u_mean`: the chords
    projected on the gap headings, the position boxes by parts), and u stays within
    ``u_B +- D_B`` (:func:`_u_deviation`); so with ``c_B``
    the centre of u_B's interval and ``du_B = rad(u_B) + D_B``, ``|u - c_B| <= du_B`` on
    B and ``int K r u = int C K r + int K r (u - C)`` (C = c_B on B). The second is within
    ``sum_B du_B int_B K|r|`` (:func:`_speed_part`, K <= 1/tau). In the first
    ``r = psi' c - q tan(phi)`` (:func:`_rate_terms`): ``c0 int C K psi' +- max|c_B|
    ext``, and by parts (C K vanishes at the window's ends) ``int C K psi' = -sum_B c_B
    K'_B int_B psi - sum_j K(t_j) (c_j - c_j-1) psi(t_j)`` over the inner block starts
    t_j, with ``int_B psi`` from the heading hull of each fix gap and psi(t_j) from the
    heading boxes (:func:`~imubounds.dynamic.estimator.aided.heading.heading_at`; all
    relative to the heading at a1, as the weights sum to zero)."""
    best: IA | None = None
    for mb in FIX_BLOCKS:
        x = _transport_fix_blocks(w, lp, tau, mb, r_mag, q_mean)
        if best is None:
            best = x
        else:
            use = (x.hi - x.lo) < (best.hi - best.lo)
            best = IA(np.where(use, x.lo, best.lo), np.where(use, x.hi, best.hi))
    assert best is not None
    return best


def gyro_deviation_bounds(
    w: WindowContext, lp: LevelPlan, tau: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The transport term's two gyro bounds, sharing the window's second bounded event
    (the first is the band's; ``full._plan_windows`` counts two per accelerometer window)
    (``Q_SHARE`` of its probability to the second, the rest to the first): the kernel
    mean of |r| (``aided.transport.r_abs``) and
    of |q| for the tilt coupling ``q tan(phi)`` of r (``aided.yaw.q_window_mean``)."""
    p = w.p_window
    try:
        w.p_window = (1.0 - Q_SHARE) * p
        r_mag = r_abs(w, lp, tau)
    finally:
        w.p_window = p
    return r_mag, q_window_mean(w, lp, tau, Q_SHARE * p)


def accel_y(w: WindowContext, plan: ChannelPlan, lp: LevelPlan, tau: np.ndarray) -> IA:
    """``[x_W]`` of accel_y."""
    h = horizontal_terms(w, plan, lp, tau)
    ends, rng = h.ends, h.rng
    r_mag, q_mean = gyro_deviation_bounds(w, lp, tau)
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
    if plan.trapezoid and w.ag.has_heading and w.ag.gnss_t.size > 2:
        rf = transport_by_fixes(w, lp, tau, r_mag, q_mean)
        use = (rf.hi - rf.lo) < (ru.hi - ru.lo)
        ru = IA(np.where(use, rf.lo, ru.lo), np.where(use, rf.hi, ru.hi))
    grav = w.tilt.kmean("g_sinr_cosp", lp, tau)
    x = (ends["v2"] - ends["v1"]) / IA(tau) + ru + grav + h.earth
    if w.veh.vertical_bound > 0:  # p w, |w| <= the vertical (heave) bound
        x = x + pm(rng["w_max"] * w.kernel_mag("gyro_x", lp, tau))
    return x
