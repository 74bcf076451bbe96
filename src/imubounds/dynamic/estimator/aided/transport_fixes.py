"""accel_y's transport term ``mean(r u)`` over trapezoid (positions-only) windows, the
window cut into blocks B of a few fix gaps (docs/dynamic-method.md, section 3,
**accel_y**, (3.20)): :func:`fix_block_form`, one block length each (the registry's
``fix_blocks_<n>`` forms, :mod:`.form_tables`).

I1 and I2 are cut separately. On B, u's mean ``u_B`` is known from the fixes
(:func:`~imubounds.dynamic.estimator.aided.positions.body_u_mean_parts`: ``u_B = c_B +
sum_{k in B} (eps_k+1 - eps_k).e_k/len_B +- rest_B``, c_B the chords projected on the gap
headings, eps the fixes' errors), and u stays within ``u_B +- D_B`` (:func:`u_deviation`).
So ``int K r u = int C K r + sum_B (u_B - c_B) int_B K r + sum_B int_B K r (u - u_B)``
(C = c_B on B). The third with the rest is within ``sum_B (D_B + rest_B) int_B K|r|``
(:func:`~.transport_terms.speed_part`, K <= 1/tau); the second's position errors, ``sum_B
rho_B sum_{k in B} (eps_k+1 - eps_k).e_k`` (``rho_B`` the block mean of K r from the
heading), by parts (:func:`_position_error_share`). In the first ``r = psi' c - q
tan(phi)`` (:func:`~.transport_terms.rate_terms`): ``c0 int C K psi' +- max|c_B| ext``,
and by parts (C K vanishes at the window's ends) ``int C K psi' = -sum_B c_B K'_B int_B
psi - sum_j K(t_j) (c_j - c_j-1) psi(t_j)`` over the inner block starts t_j, with ``int_B
psi`` from the heading hull of each fix gap and psi(t_j) from the heading boxes (all
relative to the heading at a1, as the weights sum to zero).
"""

from __future__ import annotations

import math

import numpy as np

from imubounds.constants import EPS_UP as EPS
from imubounds.dynamic.estimator.aided.accel_integral import (
    c_extremes,
    error_rates,
    k_two,
    noise_amplitudes,
    other_rate,
    sample_model,
)
from imubounds.dynamic.estimator.aided.base import earth_rates, pm, up
from imubounds.dynamic.estimator.aided.common import WindowContext
from imubounds.dynamic.estimator.aided.forms import share
from imubounds.dynamic.estimator.aided.heading import heading_at_epochs, heading_at_fixes
from imubounds.dynamic.estimator.aided.positions import body_u_mean_parts, gap_units
from imubounds.dynamic.estimator.aided.transport_terms import by_parts, rate_terms, speed_part
from imubounds.dynamic.estimator.window_plan import LevelPlan
from imubounds.interval import IntervalArray as IA


def _fix_blocks(t: np.ndarray, lp: LevelPlan, mb: int) -> tuple[np.ndarray, ...]:
    """Blocks of ``mb`` fix gaps over each trapezoid window's I1 and I2 (the last of each
    shorter): their first and last fix index, their window, and whether in I1."""
    p = np.searchsorted(t, lp.a1)
    m = np.searchsorted(t, lp.b1)
    q = np.searchsorted(t, lp.b2)
    # per window the block starts p, p + mb, .. (< m), m, m + mb, .. (< q), then q
    c1 = -(-(m - p) // mb)
    c2 = -(-(q - m) // mb)
    cnt = c1 + c2 + 1
    win_all = np.repeat(np.arange(p.size), cnt)
    pos = np.arange(int(np.sum(cnt))) - np.repeat(np.cumsum(cnt) - cnt, cnt)
    r1, r2 = np.repeat(c1, cnt), np.repeat(c1 + c2, cnt)
    bnd_all = np.where(pos < r1, p[win_all] + mb * pos,
                       np.where(pos < r2, m[win_all] + mb * (pos - r1), q[win_all]))
    last = np.r_[win_all[1:] != win_all[:-1], True]
    s, e, win = bnd_all[~last], bnd_all[1:][~last[:-1]], win_all[~last]
    return s, e, win, e <= m[win]


def u_deviation(
    w: WindowContext, a: np.ndarray, b: np.ndarray, kw: float | None = None,
    kq: float = 0.0,
) -> np.ndarray:
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
    ko = other_rate(w, a, b)
    if w.imu.available["accel_x"]:
        cn = w.ctx.noise["accel_x"]
        k = up(ko + w.ctx.E0["accel_x"] / (1.0 - cn.scale))
        absint = w.imu.sig["accel_x"].abs_integral(a, b)
        h = up(absint / (1.0 - cn.scale))
    else:
        k = up(ko + w.imu.sig["accel_x"].xmax)
        h = np.zeros(np.shape(a))
    dev = up(up(k * ln * 0.5) + h)
    if kw is not None and w.imu.available["accel_x"]:
        lo, hi, unk = c_extremes(w, a, b)
        sig = w.imu.sig["accel_x"]
        lin, excess, win_s, sc = error_rates(w)
        nw, nq = noise_amplitudes(w)
        signed = up(
            up(hi - lo) + unk * sig.xmax + up((lin + ko) * ln * 0.5)
            + excess * np.minimum(ln * 0.5, win_s) + sc * absint
            + 2.0 * kw * nw * np.sqrt(ln) + 2.0 * kq * nq + sample_model(w)
        )
        dev = np.minimum(dev, up(signed * (1 + 1e-12)))
    return up(np.minimum(dev, veh.max_accel * ln * 0.5) * (1 + 1e-12))



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

    def prev(x: np.ndarray) -> np.ndarray:
        return np.where(same, np.r_[0.0, x[:-1]], 0.0)

    def absmax(x: IA) -> np.ndarray:
        return np.maximum(np.abs(x.lo), np.abs(x.hi))

    xx = IA(prev(ax.lo), prev(ax.hi)) - ax
    xy = IA(prev(ay.lo), prev(ay.hi)) - ay
    out = np.zeros(n)
    np.add.at(out, gw, up(h[gk] * up(up(absmax(xx)) + up(absmax(xy)))))
    # each window's last fix: X = rho_last e_last
    last = np.r_[gw[1:] != gw[:-1], True]
    lm = up(absmax(ax) + absmax(ay))
    np.add.at(out, gw[last], up(h[gk[last] + 1] * lm[last]))
    return up(out * (1 + 1e-9) * (1 + 4 * EPS * (gk.size + 4)) + 1e-300)


def psi_variation(w: WindowContext, lp: LevelPlan, r_sup: np.ndarray) -> np.ndarray:
    """Bound of ``int |psi'|`` over each window's support: ``psi' = (r + q sin(phi))/
    cos(theta)``, with ``r_sup`` a bound of the mean |r| over the support (a boxcar over
    it, :func:`~imubounds.dynamic.estimator.aided.form_tables.mean_abs_r`) plus the
    Earth's rates, gyro_y's magnitude for |q|; at most the rate bound times the support."""
    veh = w.veh
    s0, s1 = lp.a1, lp.b2
    L = s1 - s0
    earth = earth_rates(veh)
    sr = w.tilt.hull("abs_sinr", s0, s1).hi
    sec = 1.0 + w.tilt.hull("sec_p_minus_1", s0, s1).hi
    q = w.gyro_abs_mean("gyro_y", s0, s1)
    m = up(up(r_sup + earth + up(up(q + earth) * sr)) * sec)
    m = np.minimum(m, veh.max_rate / math.cos(veh.max_tilt))
    return up(m * L * (1 + 1e-12))


def _gap_rows(
    t: np.ndarray, lp: LevelPlan, tau: np.ndarray, s: np.ndarray, e: np.ndarray,
    win: np.ndarray, in1: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per fix gap of the blocks: its block, first fix, window and the kernel's mean on it
    (K linear on the gap: its value at the gap's midpoint)."""
    L1, L2 = lp.b1 - lp.a1, lp.b2 - lp.b1
    cnt = e - s
    gb = np.repeat(np.arange(s.size), cnt)
    bstart = np.concatenate([[0], np.cumsum(cnt)[:-1]])
    gk = s[gb] + (np.arange(int(np.sum(cnt))) - bstart[gb])
    gw = win[gb]
    mid = 0.5 * (t[gk] + t[gk + 1])
    kbar = np.where(in1[gb], (mid - lp.a1[gw]) / (L1[gw] * tau[gw]),
                    (lp.b2[gw] - mid) / (L2[gw] * tau[gw]))
    return gb, gk, gw, kbar


def _kernel_on_fixes(t: np.ndarray, lp: LevelPlan, tau: np.ndarray) -> np.ndarray:
    """Windows whose kernel integrates to 1 and has its corners on fix epochs."""
    kint = 0.5 * ((lp.b1 - lp.a1) + (lp.b2 - lp.b1)) / tau  # int K (1 for the trapezoid)
    ok = np.abs(kint - 1.0) < 1e-9
    for x_t in (lp.a1, lp.b1, lp.b2):
        k = np.clip(np.searchsorted(t, x_t), 0, t.size - 1)
        ok &= np.abs(t[k] - x_t) <= 1e-9
    return ok


def _accel_noise_k(
    w: WindowContext, win: np.ndarray, ta: np.ndarray, tb: np.ndarray, p_acc: float
) -> tuple[float | None, float]:
    """The k of accel_x's white noise (Levy, 4 tails per block, over the most blocks of a
    window) and of its quantization (a union bound over the samples of the longest
    block) at ``p_acc`` (``SHARES["accel_noise"]`` where it has a quantization part)."""
    if not (p_acc > 0 and ta.size):
        return None, 0.0
    nb = int(np.max(np.bincount(win)))
    q = w.ctx.noise["accel_x"].Q > 0
    pw = share("accel_noise", "white") * p_acc if q else p_acc
    kw = k_two(pw / (2.0 * nb))
    kq = 0.0
    if q:
        mm = int(np.max(w.imu.count(ta, tb)))
        kq = k_two(share("accel_noise", "quantization") * p_acc / (nb * (mm + 1.0)))
    return kw, kq


def _turn_factor(w: WindowContext, s: np.ndarray, win: np.ndarray, gb: np.ndarray,
                 gk: np.ndarray, ell: np.ndarray, n: int) -> np.ndarray:
    """Per window ``max_B (2 sqrt 2 + turn_B)/len_B``: where the unknown part of rho meets
    the position boxes (the blocks' ends, ``|e|_1 <= sqrt 2`` each side, and the turns
    inside a block)."""
    ce, sn = gap_units(w)
    first_g = np.r_[True, gb[1:] != gb[:-1]]
    de = np.where(first_g, 0.0, np.abs(ce[gk] - ce[np.maximum(gk - 1, 0)])
                  + np.abs(sn[gk] - sn[np.maximum(gk - 1, 0)]))
    turn = np.zeros(s.size)
    np.add.at(turn, gb, de)
    fac = np.zeros(n)
    np.maximum.at(fac, win, up((2 * math.sqrt(2) + turn) / ell))
    return fac


def fix_block_form(
    w: WindowContext, lp: LevelPlan, tau: np.ndarray, mb: int, r_mag: np.ndarray,
    q_mean: np.ndarray | None, psi_var: np.ndarray, p_acc: float = 0.0,
    within: IA | None = None,
) -> IA:
    """``mean(r u)`` over trapezoid (positions-only) windows, the window cut into blocks
    B of ``mb`` fix gaps (docs/dynamic-method.md, (3.20); ``psi_var`` from
    :func:`psi_variation`; ``p_acc`` > 0: u's deviation also from accel_x's signed
    integral, one event at that probability per window over its blocks: Levy's
    inequality for the white noise, 4 tails per block, and the quantization over the
    samples of the longest block, a union bound).

    ``within`` (the intersection of the forms before it, :func:`~.forms.combine`): the
    form is ``head + [-R, R]`` with ``R >= max|c_B| Delta + h_max max_B((2 sqrt 2 +
    turn_B)/len_B) Delta``; where ``head +-`` that already contains ``within`` at every
    window of the level (or the window has no bound), the form cannot narrow the
    intersection and its costly parts (u's deviation, the position errors, the speed
    part) are skipped: ``(-inf, inf)``."""
    t = w.ag.gnss_t
    h = w.ag.gnss_h
    n = lp.a1.size
    s, e, win, in1 = _fix_blocks(t, lp, mb)
    ta, tb = t[s], t[e]
    ell = tb - ta
    cb, rest = body_u_mean_parts(w, s, e)
    fin = np.isfinite(cb) & np.isfinite(rest)
    cb = np.where(fin, cb, 0.0)
    gb, gk, gw, kbar = _gap_rows(t, lp, tau, s, e, win, in1)
    ref = heading_at_epochs(w, lp.a1).mid()
    ref = np.where(np.isfinite(ref), ref, 0.0)
    ps = heading_at_fixes(w, gk) - IA(ref[gw])
    pe = heading_at_fixes(w, gk + 1) - IA(ref[gw])
    c0, ext, _ = rate_terms(w, lp, tau, q_mean)
    # the first sum: c0 sum_g c_B Kbar_g dpsi_g by parts over the window's fixes
    head = by_parts(cb[gb] * kbar, gw, gk, ps, pe, gw) * IA(c0)
    # what the gaps leave: c0 K' int_g (t - t_mid) psi' and int K |r - c0 psi'|
    gmax = np.zeros(n)
    np.maximum.at(gmax, gw, t[gk + 1] - t[gk])
    kslope = np.maximum(1.0 / ((lp.b1 - lp.a1) * tau), 1.0 / ((lp.b2 - lp.b1) * tau))
    delta = up(up(c0 * kslope * 0.5 * gmax * psi_var) + ext)
    delta = up(delta * (1 + 1e-9))
    ok = np.ones(n, dtype=bool)
    np.logical_and.at(ok, win, fin)
    ok &= np.isfinite(head.lo) & np.isfinite(head.hi) & _kernel_on_fixes(t, lp, tau)
    umax = np.zeros(n)
    np.maximum.at(umax, win, np.abs(cb))
    inner = head + pm(up(umax * delta))
    fac = _turn_factor(w, s, win, gb, gk, ell, n)
    hmax = np.zeros(n)
    np.maximum.at(hmax, gw, np.maximum(h[gk], h[gk + 1]))
    pturn = up(hmax * fac * delta) * (1 + 1e-9)
    none = IA(np.full(n, -np.inf), np.full(n, np.inf))
    if within is not None:
        g2 = inner + pm(pturn)
        if np.all(~ok | ((g2.lo <= within.lo) & (g2.hi >= within.hi))):
            return none
    kw, kq = _accel_noise_k(w, win, ta, tb, p_acc)
    du = np.where(fin, up(rest + u_deviation(w, ta, tb, kw, kq)), np.inf)
    # rho_B's known part: (c0/len_B) sum_{g in B} Kbar_g dpsi_g, by parts in the block
    rho0 = by_parts(kbar, gw, gk, ps, pe, gb) * IA(c0[win]) / IA(ell)
    ok_b = np.isfinite(rho0.lo) & np.isfinite(rho0.hi)
    np.logical_and.at(ok, win, ok_b)
    rho0 = IA(np.where(fin & ok_b, rho0.lo, 0.0), np.where(fin & ok_b, rho0.hi, 0.0))
    perr = _position_error_share(w, s, e, win, rho0, n)
    # the unknown part of rho: sum_B len_B |delta_B| <= delta
    perr = up(perr + pturn)
    speed = speed_part(w, win, ta, tb, np.where(fin, du, 0.0), n, tau, r_mag, earth_rates(w.veh))
    x = inner + pm(perr) + pm(speed)
    return IA(np.where(ok, x.lo, -np.inf), np.where(ok, x.hi, np.inf))
