"""accel_y's transport term ``mean_K(r u)`` over trapezoid windows from the gyro's shape
(docs/dynamic-method.md, section 3, **accel_y**): :func:`transport_by_gyro`.

For a constant ``U0`` and ``rbar = int K r`` (K the window's kernel, ``int K = 1``)::

    int K r u = rbar int K u + int K (r - rbar)(u - U0)

(expand the second integral: ``int K r u - rbar int K u - U0 (int K r - rbar)``). The
first term: ``rbar`` from the heading, cut at the heading epochs with the gyro's shape
inside each gap (:func:`mean_r_by_gaps`), times the range of u. The second: ``r - rbar
= (y - ybar) - (e - ebar)`` (y the gyro's samples, e = y - r its error, bars the kernel
means), so with ``U0 = u(t_c)`` (t_c the support's centre) it is at most
``sum_p D_p int_p K |y - ybar| + ||e - ebar||_K ||u - U0||_K`` over pieces p of the
support (``D_p`` a bound of ``|u - u(t_c)|`` on piece p, :func:`_u_excursion`; the
second product by Cauchy-Schwarz in the measure ``K dt``). Neither needs u's level
(the positions' +-10.6 m at short tau): only how u moves within the window, from the
SIGNED integral of accel_x (its error: the bias bound times the length plus the white
noise's integral, :mod:`.accel_integral`). Where the measured integral and the turn-on's
known shape carry most of u's excursion, they leave it (:mod:`.transport_split`).
"""

from __future__ import annotations

import math

import numpy as np

from imubounds.constants import EARTH_RATE, R_EARTH
from imubounds.constants import EPS_UP as EPS
from imubounds.dynamic.estimator.aided.accel_integral import (
    accel_error,
    c_extremes,
    k_two,
    other_rate,
)
from imubounds.dynamic.estimator.aided.base import pm, up
from imubounds.dynamic.estimator.aided.common import WindowContext
from imubounds.dynamic.estimator.aided.forms import share
from imubounds.dynamic.estimator.aided.heading import heading_at
from imubounds.dynamic.estimator.aided.transport_blocks import abs_dev_integral
from imubounds.dynamic.estimator.aided.transport_split import known_shape_terms
from imubounds.dynamic.estimator.aided.transport_terms import by_parts, rate_terms
from imubounds.dynamic.estimator.budget import ChannelNoise, centered_ms_bound, kernel_variance
from imubounds.dynamic.estimator.window_plan import LevelPlan
from imubounds.interval import IntervalArray as IA

#: pieces of each of the trapezoid's two intervals (the kernel's bound on a piece)
PIECES = 8
#: the split of u - U0 (:mod:`.transport_split`) is computed where it could narrow the
#: form by at least this share of its width
SPLIT_GAIN = 0.03


def _kernel_ok(w: WindowContext, lp: LevelPlan, tau: np.ndarray) -> np.ndarray:
    """The windows whose kernel is the trapezoid ``(t - a1)/(L1 tau)`` on I1, ``(b2 -
    t)/(L2 tau)`` on I2 with ``int K = 1`` (I2 starting where I1 ends)."""
    L1, L2 = lp.b1 - lp.a1, lp.b2 - lp.b1
    ok = (L1 > 0) & (L2 > 0) & (np.abs(lp.a2 - lp.b1) <= 1e-12)
    return ok & (np.abs(0.5 * (L1 + L2) / tau - 1.0) < 1e-9)


def _kernel_at(lp: LevelPlan, tau: np.ndarray, t: np.ndarray, win: np.ndarray) -> np.ndarray:
    """The trapezoid kernel at ``t`` (window ``win``); 0 outside the support."""
    a1, b1, b2 = lp.a1[win], lp.b1[win], lp.b2[win]
    k1 = (t - a1) / ((b1 - a1) * tau[win])
    k2 = (b2 - t) / ((b2 - b1) * tau[win])
    return np.clip(np.where(t <= b1, k1, k2), 0.0, None)


def _pieces(lp: LevelPlan, tau: np.ndarray) -> tuple[np.ndarray, ...]:
    """``PIECES`` equal pieces of I1 and of I2 per window (rows): their ends ``s0, s1``,
    the kernel's largest value and its integral on each (K linear on a piece)."""
    f = np.arange(PIECES + 1) / PIECES
    e1 = lp.a1[:, None] + (lp.b1 - lp.a1)[:, None] * f[None, :]
    e2 = lp.b1[:, None] + (lp.b2 - lp.b1)[:, None] * f[None, :]
    e1[:, -1] = lp.b1
    e2[:, -1] = lp.b2
    s0 = np.concatenate([e1[:, :-1], e2[:, :-1]], axis=1)
    s1 = np.concatenate([e1[:, 1:], e2[:, 1:]], axis=1)
    win = np.broadcast_to(np.arange(lp.a1.size)[:, None], s0.shape)
    k0 = _kernel_at(lp, tau, s0, win)
    k1 = _kernel_at(lp, tau, s1, win)
    kmax = up(np.maximum(k0, k1) * (1 + 1e-12))
    kint = up(0.5 * (k0 + k1) * (s1 - s0) * (1 + 1e-12))
    return s0, s1, kmax, kint


def _u_excursion(
    w: WindowContext, lp: LevelPlan, s0: np.ndarray, s1: np.ndarray, p: float
) -> tuple[np.ndarray, np.ndarray]:
    """Per piece ``[s0, s1]``: a bound of ``|u(t) - u(t_c)|`` over it (t_c the support's
    centre): ``max |C(t) - C(t_c)|`` over the piece (C accel_x's running integral, linear
    between samples: its extremes at the sample boundaries and the piece's ends; an
    unknown span counts ``xmax`` per second) plus
    :func:`~imubounds.dynamic.estimator.aided.accel_integral.accel_error` and the other
    terms' ``k_o |t - t_c|`` (:func:`.accel_integral.other_rate`) at the piece's farthest
    point (the white noise by Levy's inequality on each side of t_c, a union bound over
    the ``PIECES`` nested spans of a side; the quantization over the support's samples);
    at most ``max_accel`` times that distance. Second: the bound ``D'`` of ``delta = u - U0
    - A - b_TO (t - t_c)`` (:mod:`.transport_split`: A the measured ``C - C(t_c)``, b_TO
    the turn-on bias), the same terms without the measured part and the turn-on (the
    same white-noise event; inf where accel_x is missing; the caller adds A's rounding)."""
    veh = w.veh
    tc = 0.5 * (lp.a1 + lp.b2)
    n = lp.a1.size
    tcp = np.broadcast_to(tc[:, None], s0.shape)
    x = up(np.maximum(np.abs(s0 - tcp), np.abs(s1 - tcp)))
    cap = up(veh.max_accel * x)
    if not w.imu.available["accel_x"]:
        return cap, np.full(s0.shape, np.inf)
    sig = w.imu.sig["accel_x"]
    P2 = s0.shape[1]
    f0, f1 = s0.ravel(), s1.ravel()
    tcf = np.repeat(tc, P2)
    lo, hi, _ = c_extremes(w, f0, f1)
    cc, ec, _ = sig.cum(tc)
    cc, ec = np.repeat(cc, P2), np.repeat(ec, P2)
    dev = np.maximum(hi - (cc - ec), (cc + ec) - lo)
    unk = sig.unknown_len(np.minimum(f0, tcf), np.maximum(f1, tcf)) * sig.xmax
    dev = up(up(dev * (1 + 1e-12)) + unk).reshape(s0.shape)
    absint = sig.abs_integral(lp.a1, lp.b2)
    # the white noise: Levy's inequality on each side of t_c, PIECES nested spans per side
    # (a union bound); the quantization at the support's m samples
    pw = share("accel_noise", "white") * p if w.ctx.noise["accel_x"].Q > 0 else p
    kw = k_two(pw / (4.0 * PIECES))
    m = w.imu.count(lp.a1, lp.b2)
    pq = share("accel_noise", "quantization") * p
    kq = (np.array([k_two(pq / (k + 1.0)) for k in m])[:, None]
          if w.ctx.noise["accel_x"].Q > 0 else 0.0)
    err = accel_error(w, x, absint[:, None], kw, kq)
    ko = up(other_rate(w, lp.a1, lp.b2)[:, None] * x)
    out = up(dev + err + ko)
    assert out.shape == (n, s0.shape[1])
    rest = up(accel_error(w, x, absint[:, None], kw, kq, turn_on=False) + ko)
    return np.minimum(out, cap), rest


def _ramp_noise_sd(
    w: WindowContext, cn: ChannelNoise, s0: np.ndarray, s1: np.ndarray, slope: np.ndarray,
    gw: np.ndarray, n: int,
) -> np.ndarray:
    """Per window, the standard deviation of ``sum_j slope_j int_j (t - m_j) n dt`` (the
    gaps ``[s0, s1]`` of window ``gw``, n the gyro's Gaussian noise): the weight of each
    sample is ``sum_j slope_j int_(sample & gap j) (t - m_j) dt``, exact from the sample
    boundaries; the variance by ``budget.kernel_variance`` (regular samples: the caller
    multiplies by the ratio of the longest sample to the period), computed once per
    distinct weight vector (on a regular grid, once per distinct placement of the knots,
    the others within the bound of the weights' differences)."""
    bnd = w.imu.bnd
    sig = w.imu.sig["gyro_z"]
    dt = w.imu.dt
    one = _one_sd(cn, dt)
    out = np.zeros(n)
    if gw.size == 0:
        return out
    cache: dict[bytes, float] = {}
    start = np.flatnonzero(np.r_[True, gw[1:] != gw[:-1]])
    stop = np.r_[start[1:], gw.size]
    first = sig.locate(s0[start])

    def exact(a: int, b: int, i0: int) -> float:
        k0, k1, sl = s0[a:b], s1[a:b], slope[a:b]
        i1 = int(sig.locate(np.array([k1[-1]]))[0])
        inner = bnd[i0 + 1 : i1 + 1]
        z = np.unique(np.concatenate([k0, k1[-1:], inner[(inner > k0[0]) & (inner < k1[-1])]]))
        za, zb = z[:-1], z[1:]
        zm = 0.5 * (za + zb)
        j = np.clip(np.searchsorted(k0, zm, side="right") - 1, 0, k0.size - 1)
        mid = 0.5 * (k0[j] + k1[j])
        part = sl[j] * 0.5 * ((zb - mid) ** 2 - (za - mid) ** 2)
        i = np.clip(np.searchsorted(bnd, zm, side="right") - 1 - i0, 0, i1 - i0)
        c = np.bincount(i, weights=part, minlength=i1 - i0 + 1)
        scale = float(np.max(np.abs(c))) if c.size else 0.0
        if scale == 0.0:
            return 0.0
        key = np.round(c / scale, 9).tobytes()
        if key not in cache:
            cache[key] = math.sqrt(kernel_variance(cn, c / scale, dt, False))
        # the key's rounding: at most 1e-9 of the scale per weight (sd <= sum |dc| x one sd)
        return float(up(scale * (cache[key] + 1e-9 * c.size * one)))

    dev = float(np.max(np.abs(np.diff(bnd) - dt))) if bnd.size > 1 else 0.0
    if not (dev <= 1e-9 * dt and w.imu.n_gaps == 0):
        for a, b, i0 in zip(start, stop, first, strict=True):
            out[gw[a]] = exact(int(a), int(b), int(i0))
        return out
    # a regular sample grid: windows whose knots sit alike on it (offsets from their
    # first sample within 1e-6 dt, slopes equal in single precision) share the weights
    # up to sum |dc| <= 2 (delta + shift) sum |slope| g + 2^-23 sum |slope| g^2/4
    # (delta the offsets' rounding, shift the grid's drift from k dt over the window)
    cnt = stop - start
    mg = int(np.max(cnt))
    rows = np.full((start.size, 2 * mg + 2), -1e300)
    rows[:, 0] = cnt
    col = np.arange(gw.size) - np.repeat(start, cnt)
    wi = np.repeat(np.arange(start.size), cnt)
    base = bnd[first][wi]
    rows[wi, 1 + col] = np.round((s0 - base) / dt, 6)
    rows[wi, 1 + mg + col] = slope.astype(np.float32)
    rows[:, -1] = np.round((s1[stop - 1] - bnd[first]) / dt, 6)
    _, rep, inv = np.unique(rows, axis=0, return_index=True, return_inverse=True)
    inv = np.ravel(inv)
    sd_rep = np.array([exact(int(start[r]), int(stop[r]), int(first[r])) for r in rep])
    g = s1 - s0
    span = s1[stop - 1] - s0[start]
    shift = dev * (span / dt + 2)
    terms = np.abs(slope) * (2 * (0.5e-6 * dt + shift[wi]) * g + 2.0**-23 * g * g / 4)
    extra = one * np.bincount(wi, weights=terms, minlength=start.size)
    res = up(sd_rep[inv] + up(extra * (1 + 1e-9)))
    res[rep] = sd_rep  # the representatives' own weights
    out[gw[start]] = res
    return out


def _one_sd(cn: ChannelNoise, dt: float) -> float:
    """One sample's standard deviation of the Gaussian noise (white, quantization,
    flicker)."""
    return math.sqrt(cn.N**2 / dt + 2 * cn.Q**2 / dt**2 + cn.flicker_sigma() ** 2)


def _gap_knots(w: WindowContext, lp: LevelPlan) -> tuple[np.ndarray, np.ndarray]:
    """Per window the knots ``a1``, the heading epochs inside, ``b1`` and ``b2`` (sorted,
    unique): the flattened knots and their window."""
    ht = w.ag.head_t
    n = lp.a1.size
    k0 = np.searchsorted(ht, lp.a1, side="right")
    k1 = np.maximum(np.searchsorted(ht, lp.b2, side="left"), k0)
    cnt = k1 - k0
    win_e = np.repeat(np.arange(n), cnt)
    start = np.repeat(np.cumsum(cnt) - cnt, cnt)
    idx = np.repeat(k0, cnt) + (np.arange(int(np.sum(cnt))) - start)
    t = np.concatenate([lp.a1, lp.b1, lp.b2, ht[idx]])
    win = np.concatenate([np.arange(n), np.arange(n), np.arange(n), win_e])
    order = np.lexsort((t, win))
    t, win = t[order], win[order]
    keep = np.r_[True, (win[1:] != win[:-1]) | (t[1:] != t[:-1])]
    return t[keep], win[keep]


def mean_r_by_gaps(w: WindowContext, lp: LevelPlan, tau: np.ndarray, p: float) -> IA:
    """``rbar = int K r`` (r the yaw rate relative to the navigation frame, K the
    trapezoid kernel) cut at the heading epochs (and at b1): on each gap j, with ``Kbar_j``
    K's mean there and K linear, ``int_j K r = Kbar_j int_j r + slope_j int_j (t - m_j)
    r``. The first: ``r = c0 psi' + (r - c0 psi')`` (:func:`.transport_fixes.rate_terms`:
    ``int K |r - c0 psi'| <= ext``), so ``c0 sum_j Kbar_j (psi_j+1 - psi_j)``, by parts
    (each heading box once, weighted by the change of Kbar: ``by_parts``). The second:
    ``r = y - e``; the y part exact from the samples' running integrals (``int_j (t -
    m_j) y = g_j (Y_0 + Y_1)/2 - (Z_1 - Z_0)``, Y, Z the first and second integrals, their
    rounding bounds added); the e part: its turn-on constant drops out (``int_j (t - m_j)
    = 0``), the Gaussian noise (white, quantization, flicker) within k standard
    deviations of the sum over the gaps (:func:`_ramp_noise_sd`), the deterministic
    part (the rate random walk's bound, scale and misalignment on the vehicle's rate
    bound, the Earth's rates) within ``2 max|e_d| int_j |t - m_j|``, the samples' model
    (each sample the true rate's mean over it; the rest inside a sample within its
    rate-of-change bound times the sample) by the samples' lengths and the knots' cuts. One event at
    probability ``p`` per window."""
    n = lp.a1.size
    bad = IA(np.full(n, -np.inf), np.full(n, np.inf))
    if n == 0 or not w.ag.has_heading or not w.imu.available["gyro_z"] or not w.fine_r:
        return bad
    ctx = w.ctx
    kn, kw = _gap_knots(w, lp)
    same = kw[1:] == kw[:-1]
    s0, s1, gw = kn[:-1][same], kn[1:][same], kw[:-1][same]
    g = s1 - s0
    k0 = _kernel_at(lp, tau, s0, gw)
    k1 = _kernel_at(lp, tau, s1, gw)
    kbar = 0.5 * (k0 + k1)
    slope = (k1 - k0) / g
    ref = heading_at(w, lp.a1).mid()
    ref = np.where(np.isfinite(ref), ref, 0.0)
    ku, kinv = np.unique(kn, return_inverse=True)  # windows share most knots
    hu = heading_at(w, ku)
    hk = IA(hu.lo[kinv], hu.hi[kinv])
    ps = IA(hk.lo[:-1][same], hk.hi[:-1][same]) - IA(ref[gw])
    pe = IA(hk.lo[1:][same], hk.hi[1:][same]) - IA(ref[gw])
    c0, ext, earth = rate_terms(w, lp, tau, None)
    head = by_parts(kbar, gw, gw, ps, pe, gw)
    # the known part of the y ramps: sum_j slope_j (g_j (Y0 + Y1)/2 - (Z1 - Z0))
    sig = w.imu.sig["gyro_z"]
    y0, ey0, _ = sig.cum(s0)
    y1, ey1, _ = sig.cum(s1)
    z0, ez0 = sig.zcum(s0)
    z1, ez1 = sig.zcum(s1)
    ramp = 0.5 * g * (y0 + y1) - (z1 - z0)
    rerr = (0.5 * g * (ey0 + ey1) + ez0 + ez1
            + 4 * EPS * (np.abs(0.5 * g * (y0 + y1)) + np.abs(z1) + np.abs(z0))
            + sig.unknown_len(s0, s1) * sig.xmax * 0.5 * g)
    term = slope * ramp
    terr = up(np.abs(slope) * up(rerr) + 4 * EPS * np.abs(term))
    yk = np.zeros(n)
    np.add.at(yk, gw, term)
    yk_err = np.zeros(n)
    np.add.at(yk_err, gw, terr)
    tmag = np.zeros(n)
    np.add.at(tmag, gw, np.abs(term))
    cnt = np.bincount(gw, minlength=n)
    yk_err = up(yk_err + (cnt + 4) * EPS * tmag + 1e-300)
    # the gyro's Gaussian noise on the ramps: one Gaussian per window, its weights on
    # the samples exact (the samples' pieces between the knots)
    cn = ctx.noise["gyro_z"]
    ratio = max(1.0, w.imu.max_len / w.imu.dt)
    sd = _ramp_noise_sd(w, cn, s0, s1, slope, gw, n) * ratio
    noise = up(k_two(p) * sd * (1 + 1e-9))
    # the error's deterministic part: |e_d| <= D_KR + s R + 2 m R + earth (R the rate bound)
    R = w.veh.max_rate + earth
    ed = ctx.D_KR["gyro_z"] + cn.scale * R / (1 - cn.scale) + 2 * cn.misalignment_rad * R + earth
    dsum = np.zeros(n)
    np.add.at(dsum, gw, up(np.abs(slope) * g * g / 4))
    det = up(2 * ed * dsum * (1 + 1e-9))
    # the samples are the true rate's means over them plus the error: a sample inside a
    # gap, |int (phi - phi(t_i)) (rmean - r)| <= |slope| (len/2) (rate len/2) len (phi =
    # slope (t - m), rate the bound of gyro_z's rate of change); a sample a knot cuts (by
    # ``cut``, the smaller part): |phi(knot)| cut rate len + |slope| rate len^3 per side
    ml = w.imu.max_len
    cuts = sig.cut(s0) + sig.cut(s1)
    sm = up(np.abs(slope) * (g * ml * ml / 4 + 0.5 * g * ml * cuts + 2 * ml**3))
    sl = np.zeros(n)
    np.add.at(sl, gw, sm)
    det = up(det + up(w.imu.rate_bound["gyro_z"] * sl * (1 + 1e-9)))
    out = head * IA(c0) + IA(yk) + pm(yk_err + noise + det + ext)
    ok = np.isfinite(out.lo) & np.isfinite(out.hi) & _kernel_ok(w, lp, tau)
    ok &= sig.unknown_len(lp.a1, lp.b2) == 0
    return IA(np.where(ok, out.lo, -np.inf), np.where(ok, out.hi, np.inf))


def transport_by_gyro(
    w: WindowContext,
    lp: LevelPlan,
    tau: np.ndarray,
    u_lo: np.ndarray,
    u_hi: np.ndarray,
    p: float,
) -> IA:
    """``mean_K(r u)`` over trapezoid windows (module docstring): ``rbar x [u_lo, u_hi]``
    (``rbar`` from :func:`mean_r_by_gaps`, u's range over the support) plus ``+-(sum_p
    D_p K_p (int_p |y - c| + rho len_p) + (sigma_n + 2 max|e_d|) sqrt(sum_p W_p D_p^2))``
    over the pieces p (``K_p`` the kernel's largest value on p, ``W_p`` its integral,
    ``D_p`` :func:`_u_excursion`; ``ybar`` within ``c +- rho``). ``||e - ebar||_K``:
    ``ebar`` minimises ``int K (e - x)^2`` over x, so it is at most that about the
    equal-weight mean of the support's m samples, ``<= K_max max_len m MS`` with ``MS``
    the bound of the noise's mean square deviation from its mean
    (:func:`~imubounds.dynamic.estimator.budget.centered_ms_bound`, the noise's white,
    quantization and flicker parts, as ``aided.transport.centred_window``; ``K_max = 1/tau``),
    plus the deterministic part (Minkowski); each sample is the true rate's mean over it
    plus the error, the rest inside a sample (its rate-of-change bound times the sample)
    added against ``K (u - U0)``'s slope. Also ``U0`` the centre of ``[u_lo, u_hi]``:
    ``|u - U0| <= (u_hi - u_lo)/2`` everywhere; and the split of ``u - U0`` into accel_x's
    measured integral A, the turn-on's ``b_TO (t - t_c)`` and the rest (:mod:`.transport_split`:
    the known shapes' terms, ``b_TO``'s bound times its term, plus the first form with the
    rest's bound ``D'`` for ``D``; computed where the known terms being 0 would narrow the
    form by at least :data:`SPLIT_GAIN` of its width); the narrowest. The probability
    ``p`` of the window's event is split over the ramp noise of ``rbar``, accel_x's
    white noise (one event for D and D'), ``MS`` and the split's two Gaussians as
    :data:`~.forms.SHARES` ``["gyro_shape"]`` says."""
    n = lp.a1.size
    bad = IA(np.full(n, -np.inf), np.full(n, np.inf))
    if n == 0 or not w.ag.has_heading or not w.imu.available["gyro_z"] or not w.fine_r:
        return bad
    ctx = w.ctx
    rbar = mean_r_by_gaps(w, lp, tau, share("gyro_shape", "mean_r") * p)
    first = rbar * IA(u_lo, u_hi)
    s0, s1, kmax, kint = _pieces(lp, tau)
    D, Dr = _u_excursion(w, lp, s0, s1, share("gyro_shape", "accel_noise") * p)
    sig = w.imu.sig["gyro_z"]
    yb = sig.kernel_mean(lp.a1, lp.b1, lp.a2, lp.b2, tau)
    fin = np.isfinite(yb.lo) & np.isfinite(yb.hi)
    c = np.where(fin, yb.mid(), 0.0)
    rho = np.where(fin, up(yb.radius()), np.inf)
    P2 = s0.shape[1]
    ad = abs_dev_integral(sig.bnd, sig.y, sig.unknown, sig.xmax, np.ascontiguousarray(s0.ravel()),
                          np.ascontiguousarray(s1.ravel()),
                          np.ascontiguousarray(np.repeat(c, P2))).reshape(s0.shape)
    ad = up(ad + rho[:, None] * (s1 - s0))
    ypart = np.sum(up(D * up(kmax * ad)), axis=1)
    # ||e - ebar||_K: the noise (Gaussian quadratic form) and the deterministic part
    cn = ctx.noise["gyro_z"]
    m = w.imu.count(lp.a1, lp.b2)
    uc, inv = np.unique(m, return_inverse=True)
    p_ms = share("gyro_shape", "gyro_ms") * p
    ms = np.array([centered_ms_bound(cn, int(mm), w.imu.dt, p_ms) for mm in uc])[inv]
    sig_n = np.sqrt(up(w.imu.max_len * m * ms / tau * (1 + 1e-9)))
    earth = EARTH_RATE + w.veh.max_speed / R_EARTH
    R = w.veh.max_rate + earth
    ed = ctx.D_KR["gyro_z"] + cn.scale * R / (1 - cn.scale) + 2 * cn.misalignment_rad * R + earth
    enorm = up(up(sig_n * (1 + 1e-9)) + 2 * ed)
    unorm = np.sqrt(up(np.sum(up(kint * up(D * D)), axis=1) * (1 + 1e-9)))
    unorm = up(unorm * (1 + 1e-9))
    # the same with U0 the centre of [u_lo, u_hi]: |u - U0| <= (u_hi - u_lo)/2 on the
    # support (int K = 1, the kernel's pieces' integrals sum to at most 1 + rounding)
    half = up(0.5 * (u_hi - u_lo))
    alt = up(half * up(np.sum(up(kmax * ad), axis=1) + enorm))
    # the samples are the true rate's means over them plus the error: the part of e
    # inside a sample, e_s = rmean_i - r, against phi = K (u - U0) (|phi'| <= K' D + K
    # max_accel): sum_i int_i |phi - phi(t_i)| |e_s| <= sup|phi'| 2 tau rate len^2/4
    # (rate gyro_z's rate-of-change bound), its kernel mean likewise with K' times int K
    # |u - U0| <= D; together (2 D/L + max_accel) rate len^2/2, doubled for the samples
    # the support's ends cut (where K = 0)
    lmin = np.minimum(lp.b1 - lp.a1, lp.b2 - lp.b1)
    ml = w.imu.max_len
    rb = w.imu.rate_bound["gyro_z"]
    dmax = np.max(D, axis=1)
    samp = up((2 * dmax / lmin + w.veh.max_accel) * rb * ml * ml * (1 + 1e-9))
    samp_alt = up((2 * half / lmin + w.veh.max_accel) * rb * ml * ml * (1 + 1e-9))
    second = np.minimum(up(ypart + up(enorm * unorm) + samp), up(alt + samp_alt))
    # the split of u - U0 into the measured A, the turn-on's b_TO (t - t_c) and delta
    # (:mod:`.transport_split`): the known shapes' terms plus the old form with D'
    # computed where the known shapes' terms being 0 would narrow the form by at least
    # SPLIT_GAIN of its width (its cost is a row of the support's samples per window)
    want = fin & np.all(np.isfinite(Dr), axis=1) & np.isfinite(second)
    want &= np.isfinite(rbar.lo) & np.isfinite(rbar.hi)
    if np.any(want):
        dr = np.where(want[:, None], Dr, 0.0)
        lb = np.sum(dr * kmax * ad, axis=1) + enorm * np.sqrt(np.sum(kint * dr * dr, axis=1))
        width = np.where(want, rbar.hi - rbar.lo, 0.0) * np.maximum(np.abs(u_lo), np.abs(u_hi))
        want &= second - (lb + samp) > SPLIT_GAIN * (width + second)
    known, tb, aerr = known_shape_terms(w, lp, tau, want, c, rho, ed,
                                         share("gyro_shape", "split") * p)
    want &= np.isfinite(known) & np.isfinite(tb) & np.isfinite(aerr)
    if np.any(want):
        turn_on = ctx.noise["accel_x"].turn_on_bound(ctx.alpha.k("imu_turn_on"))
        Dp = up(Dr[want] + aerr[want, None])
        ypart2 = np.sum(up(Dp * up(kmax[want] * ad[want])), axis=1)
        unorm2 = np.sqrt(up(np.sum(up(kint[want] * up(Dp * Dp)), axis=1) * (1 + 1e-9)))
        split = up(known[want] + up(turn_on * tb[want]) + ypart2
                   + up(enorm[want] * up(unorm2 * (1 + 1e-9))) + samp[want])
        second[want] = np.minimum(second[want], split)
    out = first + pm(up(second * (1 + 1e-9)))
    ok = np.isfinite(out.lo) & np.isfinite(out.hi) & _kernel_ok(w, lp, tau)
    return IA(np.where(ok, out.lo, -np.inf), np.where(ok, out.hi, np.inf))
