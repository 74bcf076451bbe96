"""accel_y's transport term ``mean(r u)`` (docs/dynamic-method.md, section 3,
**accel_y**): the tilt and rate terms of r and the speed part shared by the per-heading-gap
form (:func:`~imubounds.dynamic.estimator.aided.accel_y.transport_by_gaps`), and the
positions-only form over blocks of fix gaps (:func:`transport_by_fixes`)."""

from __future__ import annotations

import math

import numpy as np

from imubounds.dynamic.estimator.aided.base import EARTH_RATE, G_HI, R_EARTH, pm, up
from imubounds.dynamic.estimator.aided.common import WindowContext
from imubounds.dynamic.estimator.aided.heading import heading_at, heading_mean
from imubounds.dynamic.estimator.aided.positions import body_u_mean_parts, gap_units
from imubounds.dynamic.estimator.aided.velocity import speed_max
from imubounds.dynamic.estimator.window_plan import LevelPlan
from imubounds.interval import IntervalArray as IA

_EPS = 2.3e-16
#: block lengths (in fix gaps) of the positions-only transport bound (:func:`transport_by_fixes`)
FIX_BLOCKS = (4, 6, 8, 12, 16, 24)


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


def _block_rate_means(
    w: WindowContext, lp: LevelPlan, win: np.ndarray, ta: np.ndarray, tb: np.ndarray,
    kd: np.ndarray, k_a: np.ndarray, k_b: np.ndarray, ref: np.ndarray,
) -> tuple[IA, IA, IA]:
    """Per block B = [ta, tb] (window ``win``, kernel slope ``kd``, kernel ``k_a``, ``k_b``
    at its ends): ``int_B psi``, psi(ta) (both relative to the window's ``ref``) and
    ``rho_B = (1/len) int_B K r`` with ``r = psi' c - q tan(phi)``: ``int_B K psi' =
    K(tb) psi(tb) - K(ta) psi(ta) - K'_B int_B psi`` (``int_B psi`` from the heading hull
    of each fix gap), times ``c0``, ``+- (rate cdev + (mean_B|q| + earth) tan) max_B K
    len`` (gyro_y's magnitude on the block)."""
    veh = w.veh
    t = w.ag.gnss_t
    s = np.searchsorted(t, ta)
    e = np.searchsorted(t, tb)
    ell = tb - ta
    plo, phi = _gap_heading_sums(w)
    ib = IA(plo[e] - plo[s], phi[e] - phi[s]) + pm(1e-12 * (np.abs(plo[e]) + np.abs(phi[e]) + 1))
    ib = ib - IA(ell) * IA(ref[win])
    pa = heading_at(w, ta) - IA(ref[win])
    pb = heading_at(w, tb) - IA(ref[win])
    c = w.tilt.hull("cosp_over_cosr", lp.a1, lp.b2)
    c0 = c.mid()
    cdev = up(np.maximum(c.hi - c0, c0 - c.lo))
    rate = veh.max_rate / math.cos(veh.max_tilt)
    earth = float(up(np.asarray(EARTH_RATE + veh.max_speed / R_EARTH)))
    tr = w.tilt.hull("abs_tanr", lp.a1, lp.b2).hi
    kmax = np.maximum(k_a, k_b)
    ext = up(
        up(up(rate * cdev[win]) + up(up(w.gyro_abs_mean("gyro_y", ta, tb) + earth) * tr[win]))
        * kmax * ell * (1 + 1e-12)
    )
    intk = IA(k_b) * pb - IA(k_a) * pa - IA(kd) * ib
    rho = (intk * IA(c0[win]) + pm(ext)) / IA(ell)
    return ib, pa, rho


def _position_error_share(
    w: WindowContext, s: np.ndarray, e: np.ndarray, win: np.ndarray, rho: IA, n: int
) -> np.ndarray:
    """Bound of ``sum_B rho_B sum_{k in B} (eps_k+1 - eps_k).e_k`` per window (eps the
    fixes' errors, ``|eps| <= h`` per axis, e_k the gaps' units): by parts, ``sum_j
    eps_j.X_j`` with ``X_j = rho_(j-1) e_j-1 - rho_j e_j`` (rho of the gap's block, 0
    outside the window), so within ``sum_j h_j |X_j|_1``: only a change of rho (or a
    turn) between gaps lets the position boxes in."""
    ce, sn = gap_units(w)
    h = w.ag.gnss_h
    cnt = e - s
    blk = np.repeat(np.arange(s.size), cnt)
    bstart = np.concatenate([[0], np.cumsum(cnt)[:-1]])
    gk = s[blk] + (np.arange(int(np.sum(cnt))) - bstart[blk])
    gw = win[blk]
    r = IA(rho.lo[blk], rho.hi[blk])
    ax, ay = r * IA(ce[gk]), r * IA(sn[gk])
    same = np.r_[False, gw[1:] == gw[:-1]]
    zero = np.zeros(gk.size)
    px = IA(np.where(same, np.r_[0.0, ax.lo[:-1]], zero), np.where(same, np.r_[0.0, ax.hi[:-1]], zero))
    py = IA(np.where(same, np.r_[0.0, ay.lo[:-1]], zero), np.where(same, np.r_[0.0, ay.hi[:-1]], zero))
    xx, xy = px - ax, py - ay
    mag = up(up(np.maximum(np.abs(xx.lo), np.abs(xx.hi))) + up(np.maximum(np.abs(xy.lo), np.abs(xy.hi))))
    out = np.zeros(n)
    np.add.at(out, gw, up(h[gk] * mag))
    # each window's last fix: X = rho_last e_last
    last = np.r_[gw[1:] != gw[:-1], True]
    lm = up(up(np.maximum(np.abs(ax.lo), np.abs(ax.hi))) + up(np.maximum(np.abs(ay.lo), np.abs(ay.hi))))
    np.add.at(out, gw[last], up(h[gk[last] + 1] * lm[last]))
    return up(out * (1 + 1e-9) * (1 + 4 * _EPS * (gk.size + 4)) + 1e-300)


def _transport_fix_blocks(
    w: WindowContext, lp: LevelPlan, tau: np.ndarray, mb: int, r_mag: np.ndarray,
    q_mean: np.ndarray | None,
) -> IA:
    """:func:`transport_by_fixes` for blocks of ``mb`` fix gaps."""
    t = w.ag.gnss_t
    n = lp.a1.size
    s, e, win, in1 = _fix_blocks(t, lp, mb)
    ta, tb = t[s], t[e]
    cb, rest = body_u_mean_parts(w, s, e)
    fin = np.isfinite(cb) & np.isfinite(rest)
    cb = np.where(fin, cb, 0.0)
    du = np.where(fin, up(rest + _u_deviation(w, ta, tb)), np.inf)
    L1, L2 = lp.b1 - lp.a1, lp.b2 - lp.b1
    # the kernel's slope on each block, its values at the block's ends
    kd = np.where(in1, 1.0 / (L1[win] * tau[win]), -1.0 / (L2[win] * tau[win]))
    k_a = np.where(in1, (ta - lp.a1[win]) / (L1[win] * tau[win]),
                   (lp.b2[win] - ta) / (L2[win] * tau[win]))
    k_b = np.where(in1, (tb - lp.a1[win]) / (L1[win] * tau[win]),
                   (lp.b2[win] - tb) / (L2[win] * tau[win]))
    first = np.r_[True, win[1:] != win[:-1]]
    start = np.flatnonzero(first)
    ref = heading_at(w, lp.a1).mid()
    ref = np.where(np.isfinite(ref), ref, 0.0)
    ib, psi, rho = _block_rate_means(w, lp, win, ta, tb, kd, k_a, k_b, ref)
    term = IA(-cb * kd) * ib
    # the jumps of C K at the inner block starts: -K(t_j) (c_j - c_j-1) psi(t_j)
    dc = np.where(first, 0.0, cb - np.r_[0.0, cb[:-1]])
    term = term + IA(-k_a * dc) * psi
    ok_t = np.isfinite(term.lo) & np.isfinite(term.hi) & fin
    ok_t &= np.isfinite(rho.lo) & np.isfinite(rho.hi)
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
    rho = IA(np.where(ok_t, rho.lo, 0.0), np.where(ok_t, rho.hi, 0.0))
    perr = _position_error_share(w, s, e, win, rho, n)
    speed = _speed_part(w, win, ta, tb, np.where(fin, du, 0.0), n, tau, r_mag, earth)
    x = head * IA(c0) + pm(up(umax * ext)) + pm(perr) + pm(speed)
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
    fixes (:func:`~imubounds.dynamic.estimator.aided.positions.body_u_mean_parts`:
    ``u_B = c_B + sum_{k in B} (eps_k+1 - eps_k).e_k/len_B +- rest_B``, c_B the chords
    projected on the gap headings, eps the fixes' errors), and u stays within ``u_B +-
    D_B`` (:func:`_u_deviation`). So ``int K r u = int C K r + sum_B (u_B - c_B) int_B K r
    + sum_B int_B K r (u - u_B)`` (C = c_B on B). The third with the rest is within
    ``sum_B (D_B + rest_B) int_B K|r|`` (:func:`_speed_part`, K <= 1/tau); the second's
    position errors, ``sum_B rho_B sum_{k in B} (eps_k+1 - eps_k).e_k`` (``rho_B`` the
    block mean of K r from the heading, :func:`_block_rate_means`), by parts
    (:func:`_position_error_share`). In the first
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
