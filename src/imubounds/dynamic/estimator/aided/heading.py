"""gyro_z from the heading (docs/dynamic-method.md, section 3, **gyro_z**).

Boxcar between heading epochs: ``r = psi' cos(theta)/cos(phi) - q tan(phi)``, so the
kernel mean of the yaw rate is ``c0 (psi(b) - psi(a))/tau +- rate |c - c0| +- mean|q|
tan(phi)`` with ``c = cos(theta)/cos(phi)`` over the window, plus the Earth rate. Also the
heading between its epochs (:func:`heading_at`, :func:`heading_mean`) and the bounds of
its rate (:func:`psi_dot_abs` of the mean, :func:`psi_rate_bound` at each time), which
the accelerometer constraints use.
"""

from __future__ import annotations

import math

import numpy as np

from imubounds.constants import EARTH_RATE, R_EARTH, ROUND_REL
from imubounds.dynamic.estimator.aided.base import pm, up
from imubounds.dynamic.estimator.aided.common import WindowContext
from imubounds.dynamic.estimator.inputs import RangeExt
from imubounds.dynamic.estimator.window_plan import LevelPlan
from imubounds.interval import IntervalArray as IA


def _earth(w: WindowContext) -> float:
    """``Omega + S_max/R_E``: the rate of the level frame in inertial space, which the
    gyros measure besides the body's rate relative to it."""
    return float(up(np.asarray(EARTH_RATE + w.veh.max_speed / R_EARTH)))


#: :func:`psi_dot_abs` tries the rate bound of :func:`psi_rate_bound` on spans of at
#: most this many (longest) sample periods
SHORT_SPAN_SAMPLES = 8


def psi_dot_abs(
    w: WindowContext, a: np.ndarray, b: np.ndarray, own_q: bool = True
) -> np.ndarray:
    """Bound of mean |d psi/dt| over [a, b] from the gyro magnitudes (other channels):
    ``|psi'| <= (|r| + |q| |sin(phi)|)/cos(theta)`` with r, q the body's rates relative to
    the level frame, each at most the gyro's (inertial) rate plus ``Omega + S_max/R_E``;
    at most the vehicle's rate cap ``max_rate/cos(max_tilt)``, and at most ``Rm + Cm/(b -
    a)`` (:func:`psi_rate_bound`: ``int_a^b |psi'| <= Rm (b - a) + Cm``; smaller on spans
    that cut samples, whose magnitudes count whole here)."""
    veh = w.veh
    earth = _earth(w)
    r = w.gyro_abs_mean("gyro_z", a, b)
    q = w.gyro_abs_mean("gyro_y", a, b) if own_q else np.full(r.shape, veh.max_rate)
    sr = w.tilt.hull("abs_sinr", a, b).hi
    sec = 1.0 + w.tilt.hull("sec_p_minus_1", a, b).hi
    m = up(up(r + earth + up(up(q + earth) * sr)) * sec)
    m = np.minimum(m, veh.max_rate / math.cos(veh.max_tilt))
    # only spans of a few samples can gain (the magnitudes above count every sample the
    # span touches whole; over longer spans the mean is below the maximum): skipping the
    # others is sound (a minimum of two bounds) and saves the range queries
    a, b, m = np.broadcast_arrays(np.asarray(a, dtype=float), np.asarray(b, dtype=float), m)
    span = b - a
    few = (span > 0) & (span <= SHORT_SPAN_SAMPLES * w.imu.max_len)
    if np.any(few):
        m = m.copy()
        rm, cm = psi_rate_bound(w, a[few], b[few], own_q=own_q)
        m[few] = np.minimum(m[few], up(rm + cm / span[few]))
    return m


def _abs_rate(
    w: WindowContext, ch: str, a: np.ndarray, b: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """``(M, C)`` with ``int_s^t |x| <= M (t - s) + C`` for EVERY ``[s, t]`` inside
    ``[a, b]`` (x the true signal of gyro ``ch``: a bound at each time, not of the mean
    over ``[a, b]`` only). The sample model: sample k is the mean ``mu_k`` of x over its
    period (length ``L_k <= L``, the longest), ``|mu_k| <= m_k = (|y_k| + E0)/(1 - s)``
    (E0 the per-sample error bound, s the scale error, as
    :meth:`~imubounds.dynamic.estimator.aided.common.WindowContext.mag_mean`), and
    ``|x'| <= D`` (the vehicle's angular-acceleration bound). With ``M = max(max_k m_k,
    D L/2)`` over the samples ``[a, b]`` touches (a range-maximum table of |y|, once per
    run): a whole period gives ``int |x| = |L_k mu_k| <= L_k M`` where x keeps its sign,
    else ``x(z) = 0`` inside and ``int |x| <= D int |t - z| <= D L_k^2/2 <= L_k M``; a
    part of length l of one period gives, where x keeps its sign, ``|l mu_k + int_part (x
    - mu_k)| <= l m_k + D int |H| <= l m_k + D l (L_k - l)/2`` (by parts: ``int_part (x -
    mu_k) = -int x' H``, H the running integral of ``1_part - l/L_k`` over the period, zero
    at both ends: ``int |H| = (p^2 + p'^2) l/(2 (L_k - l))``, p and p' the lengths before
    and after the part), else ``D int_part |t - z| <= D l (L_k - l/2) <= l M + D l (L_k -
    l)/2``: at most ``l M + D L^2/8``; ``[s, t]`` has at most two parts, ``C = D L^2/4``.
    Spans with an unknown sample or outside the samples: ``(xmax, 0)``, the vehicle's
    signal bound at each time."""
    sig = w.imu.sig[ch]
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    shape = np.broadcast(a, b).shape
    xmax = np.full(shape, sig.xmax)
    if not w.imu.available[ch]:
        return xmax, np.zeros(shape)
    key = "abs_y_ext_" + ch
    if key not in w.cache:
        w.cache[key] = RangeExt(np.abs(sig.y))
    _, ymax = w.cache[key].query(sig.locate(a), sig.locate(b))
    cn = w.ctx.noise[ch]
    d, ell = w.imu.rate_bound[ch], w.imu.max_len
    m = np.maximum(up(up(ymax + w.ctx.E0[ch]) / (1.0 - cn.scale)), up(d * ell * 0.5))
    c = float(up(np.asarray(d * ell * ell * 0.25)))
    bad = (sig.unknown_len(a, b) > 0) | (a < w.imu.bnd[0]) | (b > w.imu.bnd[-1])
    bad |= m >= sig.xmax
    return np.where(bad, xmax, m), np.where(bad, 0.0, c)


def psi_rate_bound(
    w: WindowContext, a: np.ndarray, b: np.ndarray, own_q: bool = True
) -> tuple[np.ndarray, np.ndarray]:
    """``(Rm, Cm)`` with ``int_s^t |psi'| <= Rm (t - s) + Cm`` for every ``[s, t]`` inside
    ``[a, b]`` (the rate at each time, to a constant: not the mean over ``[a, b]`` alone):
    ``psi' = (r cos(phi) + q sin(phi))/cos(theta)``, r and q the body's rates relative to
    the level frame, each within ``Omega + S_max/R_E`` of the gyro's, so ``|psi'| <= (|r_g|
    + E + (|q_g| + E) max|sin(phi)|) max sec(theta)`` over the span (E = ``Omega +
    S_max/R_E``) and, with :func:`_abs_rate` of gyro_z and gyro_y (``own_q`` False: the
    vehicle's rate bound for |q|), ``Rm = sec (M_r + E + (M_q + E) sr)``, ``Cm = sec (C_r +
    C_q sr)``; the vehicle's cap ``max_rate/cos(max_tilt)`` (with ``Cm = 0``) where it is
    smaller."""
    veh = w.veh
    earth = _earth(w)
    r, cr = _abs_rate(w, "gyro_z", a, b)
    if own_q:
        q, cq = _abs_rate(w, "gyro_y", a, b)
    else:
        q, cq = np.full(r.shape, veh.max_rate), np.zeros(r.shape)
    sr = w.tilt.hull("abs_sinr", a, b).hi
    sec = 1.0 + w.tilt.hull("sec_p_minus_1", a, b).hi
    rm = up(up(r + earth + up(up(q + earth) * sr)) * sec)
    cm = up(up(cr + up(cq * sr)) * sec)
    cap = veh.max_rate / math.cos(veh.max_tilt)
    use_cap = rm >= cap
    return np.where(use_cap, cap, rm), np.where(use_cap, 0.0, cm)


def heading_at(w: WindowContext, t: np.ndarray, own_q: bool = True) -> IA:
    """Heading (model convention, unwrapped branch of the compass centres) at ``t``,
    interpolated from the nearest heading epochs; the change over the gap is bounded
    by the gyro magnitudes (a magnitude bound, never the gyro's value). ``own_q`` False:
    without gyro_y's magnitude (the vehicle's rate bound for |q|), for the constraints
    of gyro_y itself."""
    ag = w.ag
    t = np.asarray(t, dtype=float)
    if not ag.has_heading:
        return IA(np.full(t.shape, -np.inf), np.full(t.shape, np.inf))
    ht, hc, hh = ag.head_t, ag.head_c, ag.head_h
    j = np.searchsorted(ht, t)
    lo = np.full(t.shape, -np.inf)
    hi = np.full(t.shape, np.inf)
    for e in (j - 1, j):
        ok = (e >= 0) & (e < ht.size)
        ee = np.clip(e, 0, ht.size - 1)
        te = ht[ee]
        a, b = np.minimum(t, te), np.maximum(t, te)
        exact = np.abs(t - te) <= 1e-9
        g = np.where(exact, 0.0, psi_dot_abs(w, a, b, own_q=own_q) * (b - a))
        g = up(g)
        c_lo = np.nextafter(hc[ee] - hh[ee] - g, -np.inf)
        c_hi = up(hc[ee] + hh[ee] + g)
        lo = np.where(ok, np.maximum(lo, c_lo), lo)
        hi = np.where(ok, np.minimum(hi, c_hi), hi)
    bad = lo > hi
    if np.any(bad):  # inconsistent neighbours: keep their hull (reported by the smoother)
        lo = np.where(bad, np.minimum(lo, hi), lo)
        hi = np.where(bad, np.maximum(lo, hi), hi)
    return IA(lo, hi)


def heading_at_fixes(w: WindowContext, k: np.ndarray) -> IA:
    """:func:`heading_at` at the GNSS fixes ``gnss_t[k]``: computed once per run for every
    fix (elementwise, so the same values as at the fixes asked for alone)."""
    key = "heading_at_fixes"
    if key not in w.cache:
        w.cache[key] = heading_at(w, w.ag.gnss_t)
    h = w.cache[key]
    return IA(h.lo[k], h.hi[k])


def heading_at_epochs(w: WindowContext, t: np.ndarray) -> IA:
    """:func:`heading_at` at ``t``, from :func:`heading_at_fixes` where ``t`` is a GNSS fix
    (exactly), computed elsewhere."""
    ft = w.ag.gnss_t
    t = np.asarray(t, dtype=float)
    if ft.size == 0:
        return heading_at(w, t)
    k = np.clip(np.searchsorted(ft, t), 0, ft.size - 1)
    on = ft[k] == t
    if np.all(on):
        return heading_at_fixes(w, k)
    out = heading_at_fixes(w, k)
    off = heading_at(w, t[~on])
    lo, hi = out.lo.copy(), out.hi.copy()
    lo[~on], hi[~on] = off.lo, off.hi
    return IA(lo, hi)


def heading_mean(w: WindowContext, a: np.ndarray, b: np.ndarray) -> IA:
    """Interval containing the mean heading over [a, b] (hull of the heading there)."""
    ag = w.ag
    lo = heading_at(w, a)
    hi = heading_at(w, b)
    ht = ag.head_t
    out_lo = np.minimum(lo.lo, hi.lo)
    out_hi = np.maximum(lo.hi, hi.hi)
    if ht.size:
        i = np.searchsorted(ht, a)
        j = np.searchsorted(ht, b, side="right") - 1
        has = j >= i
        ext = RangeExt(ag.head_c - ag.head_h, ag.head_c + ag.head_h)
        ii = np.clip(i, 0, ht.size - 1)
        jj = np.clip(np.maximum(j, i), 0, ht.size - 1)
        mn, mx = ext.query(ii, jj)
        out_lo = np.where(has, np.minimum(out_lo, mn), out_lo)
        out_hi = np.where(has, np.maximum(out_hi, mx), out_hi)
        # between two knots (a, the heading epochs inside, b) the heading leaves the
        # hull of its two ends by at most (int |psi'| - |psi(t2) - psi(t1)|)/2 there:
        # psi_dot_abs bounds the MEAN |psi'| over its own span, so each gap's integral
        # is taken over that gap (the gaps between heading epochs once per run)
        t_in = np.where(has, ht[ii], b)
        t_out = np.where(has, ht[jj], b)
        g = np.maximum(_half_integral(w, a, t_in), _half_integral(w, t_out, b))
        if ht.size > 1:
            ge = _gap_excursions(w)
            inner = has & (j > i)
            lo_k = np.clip(ii, 0, ge.size - 1)
            hi_k = np.clip(np.maximum(jj - 1, ii), 0, ge.size - 1)
            _, gm = w.cache["gap_exc_ext"].query(lo_k, hi_k)
            g = np.where(inner, np.maximum(g, gm), g)
        g = up(g)
        out_lo, out_hi = out_lo - g, out_hi + g
    return IA(np.nextafter(out_lo, -np.inf), up(out_hi))


def _half_integral(w: WindowContext, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``int_a^b |psi'| / 2`` bounded (``psi_dot_abs`` x the span), 0 on empty spans."""
    span = np.maximum(b - a, 0.0)
    return np.where(span > 0, up(psi_dot_abs(w, a, np.maximum(a, b)) * span / 2), 0.0)


def _gap_excursions(w: WindowContext) -> np.ndarray:
    """Per gap between consecutive heading epochs: how far the heading can leave the hull
    of its two ends inside it, ``(int |psi'| - max(0, |c2 - c1| - h1 - h2))/2`` (the
    integral bounded over the gap; the true change at least the centres' minus the two
    boxes); computed once per run, with its range-maximum table."""
    if "gap_exc" not in w.cache:
        ag = w.ag
        ht, hc, hh = ag.head_t, ag.head_c, ag.head_h
        a, b = ht[:-1], ht[1:]
        integral = up(psi_dot_abs(w, a, b) * (b - a))
        change = np.maximum(np.nextafter(np.abs(hc[1:] - hc[:-1]) - hh[1:] - hh[:-1],
                                         -np.inf), 0.0)
        ge = up(np.maximum(integral - change, 0.0) * (0.5 * (1 + ROUND_REL)) + 1e-300)
        w.cache["gap_exc"] = ge
        w.cache["gap_exc_ext"] = RangeExt(ge)
    return w.cache["gap_exc"]


def r_from_psidot(
    w: WindowContext,
    dpsi: IA,
    lp: LevelPlan,
    tau: np.ndarray,
    own_q: bool,
    q_mean: np.ndarray | None = None,
) -> IA:
    """r = psi' cos(p)/cos(r) - q tan(roll): from the mean heading rate, with the tilt
    terms bounded (|psi'| by the vehicle's rate bound, |q| by gyro_y's magnitude or,
    when given, ``q_mean``: a bound of the kernel mean of |q|)."""
    veh = w.veh
    c = w.tilt.hull("cosp_over_cosr", lp.a1, lp.b2)
    c0 = c.mid()
    cdev = up(np.maximum(c.hi - c0, c0 - c.lo))
    rate = veh.max_rate / math.cos(veh.max_tilt)
    if q_mean is not None:
        q = q_mean
    elif own_q:
        q = w.kernel_mag("gyro_y", lp, tau)
    else:
        q = up(veh.max_rate * (lp.b2 - lp.a1) / tau)
    tr = w.tilt.hull("abs_tanr", lp.a1, lp.b2).hi
    earth = pm(EARTH_RATE + veh.max_speed / R_EARTH)
    return dpsi * IA(c0) + pm(rate * cdev) + pm(q * tr) + earth
