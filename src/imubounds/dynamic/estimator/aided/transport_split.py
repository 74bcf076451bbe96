"""The known-shape parts of accel_y's gyro-shape transport term
(:func:`~imubounds.dynamic.estimator.aided.transport_gyro.transport_by_gyro`,
docs/dynamic-method.md, section 3, **accel_y**): :func:`known_shape_terms`.

The second term there is ``T2 = int K (r - rbar)(u - U0)`` (K the trapezoid kernel,
``int K = 1``, ``U0 = u(t_c)``, t_c the support's centre). u's deviation from U0 splits
as::

    u(t) - U0 = A(t) + b (t - t_c) + delta(t),   A = C(t) - C(t_c)

with C accel_x's measured running integral (known numbers, linear between the sample
boundaries), ``b`` the accelerometer's turn-on bias (a constant: ``|b| <=`` its bound)
and ``delta`` the rest (the in-run wander, the white noise's integral, scale and
misalignment, the other terms of ``u' = f_x + r v - q w - g sin(theta)``, the samples'
model): ``|delta| <= D'`` (``transport_gyro._u_excursion``'s bound without the measured
part and the turn-on). With ``r - rbar = (y - ybar) - (e - ebar)`` (y the gyro's samples,
e = y - r their error; bars the kernel means)::

    T2 = int K (y - ybar) A - int K e (A - Abar)
       + b [int K (y - ybar)(t - t_c) - int K e (t - t_c - m)]  + int K (r - rbar) delta

(``int K (e - ebar) f = int K e (f - fbar)`` for any f, ``fbar = int K f``; ``m`` the
kernel mean of ``t - t_c``). The first and the measured half of the third are numbers
from the samples (y constant on a sample, A and K linear on the pieces between the sample
boundaries and the kernel's knots: exact by Simpson's rule; ``ybar`` within ``c +- rho``
adds ``rho int K |A|``, resp. ``rho int K |t - t_c|``; C's rounding enters delta). The
gyro's error on the known weights ``K (A - Abar)`` and ``K (t - t_c - m)``: its constant
(turn-on) part cancels up to ``|1 - int K|`` (the kernel's normalisation, within 1e-9:
``E0 |1 - int K| int K |f|``, E0 the gyro's per-sample bound); its Gaussian part (white,
quantization, flicker: the wander's changes within the window keep the flicker model, as
everywhere in section 1 of the docs) a zero-mean Gaussian, its standard deviation bounded
for the weights by :func:`batch_sd` (white and quantization exact, each Gauss-Markov
component on blocks of :data:`BLOCK` samples plus the blocks' residual; regular samples,
the sd times the ratio of the longest sample to the period as
``transport_gyro._ramp_noise_sd``), within ``k`` standard deviations; its deterministic
part (scale and misalignment on the rate bound, the rate random walk's bound, the
Earth's rates: ``|e_d| <= ed``) within ``ed int K |f - fbar|``. The weights A come from
the accelerometer's samples only and ``t - t_c`` from the clock: both independent of
the gyro's noise, so the Gaussian statement holds for them as for fixed weights (the
two Gaussians at ``p/2`` each of the caller's share).
The last term is the old form's (``transport_gyro``) with ``D'``.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.signal import lfilter

from imubounds.constants import EPS_UP as EPS
from imubounds.dynamic.estimator.aided.accel_integral import c_extremes, k_two
from imubounds.dynamic.estimator.aided.base import up
from imubounds.dynamic.estimator.aided.common import WindowContext
from imubounds.dynamic.estimator.aided.forms import share
from imubounds.dynamic.estimator.budget import ChannelNoise
from imubounds.dynamic.estimator.window_plan import LevelPlan


def _cum_table(w: WindowContext) -> tuple[np.ndarray, np.ndarray]:
    """accel_x's running integral C at every sample boundary and its rounding bound
    (computed once per run)."""
    key = "transport_split_cum"
    if key not in w.cache:
        sig = w.imu.sig["accel_x"]
        val, err, _ = sig.cum(sig.bnd)
        w.cache[key] = (val, up(err * (1 + 1e-9) + 1e-300))
    return w.cache[key]


def _err_max(w: WindowContext) -> np.ndarray:
    """The running maximum of :func:`_cum_table`'s rounding bounds (once per run)."""
    key = "transport_split_cum_errmax"
    if key not in w.cache:
        w.cache[key] = np.maximum.accumulate(_cum_table(w)[1])
    return w.cache[key]


def _simpson(h: np.ndarray, k0: np.ndarray, k1: np.ndarray, f0: np.ndarray,
             f1: np.ndarray) -> np.ndarray:
    """``int K f`` over a piece of length h where K and f are linear (ends k, f): exact
    (Simpson's rule on the quadratic K f)."""
    return h / 6.0 * (k0 * (f0 + f0 + f1) + k1 * (f0 + f1 + f1))


def known_shape_terms(
    w: WindowContext,
    lp: LevelPlan,
    tau: np.ndarray,
    sel: np.ndarray,
    c: np.ndarray,
    rho: np.ndarray,
    ed: float,
    p: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per window: ``(known, tb, a_err)``: the bound of ``|int K (y - ybar) A - int K e (A
    - Abar)|`` (module docstring), that of ``|int K (y - ybar)(t - t_c) - int K e (t - t_c
    - m)|`` (to be multiplied by the turn-on bound) and the bound of C's rounding in A (it
    goes into ``delta``). ``c +- rho`` encloses ``ybar``, ``ed`` bounds the gyro's
    deterministic error; the two Gaussians at probability ``p/2`` each. ``inf`` where a
    sample of either channel is unknown in the support, and on the windows not in ``sel``
    (a boolean mask: the caller's choice of where the terms can narrow its bound).
    Computed for the selected windows at once:
    a row per window, a column per sample of its support (the sample cut at ``b1`` into
    two pieces, at the support's ends clipped)."""
    nall = lp.a1.size
    out = (np.full(nall, np.inf), np.full(nall, np.inf), np.full(nall, np.inf))
    if not np.any(sel):
        return out
    idx = np.flatnonzero(sel)
    # chunks of windows holding at most CELLS samples together (memory: a few arrays of
    # that size)
    span = w.imu.count(lp.a1[idx], lp.b2[idx]) + 2
    step = max(1, int(CELLS // max(float(np.max(span)), 1.0)))
    for j0 in range(0, idx.size, step):
        ix = idx[j0 : j0 + step]
        res = _terms(w, lp.a1[ix], lp.b1[ix], lp.b2[ix], tau[ix], c[ix], rho[ix], ed, p)
        for o, r in zip(out, res, strict=True):
            o[ix] = r
    return out


def _terms(
    w: WindowContext, la1: np.ndarray, lb1: np.ndarray, lb2: np.ndarray, tau: np.ndarray,
    c: np.ndarray, rho: np.ndarray, ed: float, p: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`known_shape_terms` on windows ``[la1, lb2]`` (``lb1`` the kernel's apex)."""
    n = la1.size
    inf = np.full(n, np.inf)
    gy = w.imu.sig["gyro_z"]
    ax = w.imu.sig["accel_x"]
    if n == 0 or gy.bnd.size != ax.bnd.size or not np.array_equal(gy.bnd, ax.bnd):
        return inf, inf.copy(), inf.copy()
    cn = w.ctx.noise["gyro_z"]
    dt = w.imu.dt
    ratio = max(1.0, w.imu.max_len / dt)
    k_wa = k_two(share("split", "accel_weights") * p)
    k_wt = k_two(share("split", "clock_weights") * p)
    bnd = gy.bnd
    a1, b1, b2 = la1[:, None], lb1[:, None], lb2[:, None]
    r1, r2 = 1.0 / ((b1 - a1) * tau[:, None]), 1.0 / ((b2 - b1) * tau[:, None])
    tc = 0.5 * (la1 + lb2)
    ok = (gy.unknown_len(la1, lb2) == 0) & (ax.unknown_len(la1, lb2) == 0)
    i0 = gy.locate(la1)
    i1 = gy.locate(lb2)
    # a column per sample from the one holding a1, its boundaries the nodes (clipped to
    # [a1, b2]: past the sample holding b2 the pieces are empty, zero weights)
    m = int(np.max(i1 - i0)) + 1
    j = np.arange(m + 1)[None, :]
    kn = np.minimum(i0[:, None] + j, bnd.size - 1)
    z = np.clip(bnd[kn], a1, b2)
    k = np.minimum(kn[:, :-1], bnd.size - 2)
    cval, cerr = _cum_table(w)
    cc, ec, _ = ax.cum(tc)
    # C at a node: the table at a sample boundary, else (a1, b2) along its sample's slope
    kk = np.minimum(kn, i1[:, None])
    fz = cval[kk] + ax.y[kk] * (z - bnd[kk]) - cc[:, None]

    def kern(t: np.ndarray) -> np.ndarray:
        # the trapezoid (a2 = b1): the smaller of its rising and falling lines, >= 0
        return np.maximum(np.minimum((t - a1) * r1, (b2 - t) * r2), 0.0)

    kz = kern(z)
    sz = z - tc[:, None]
    h = z[:, 1:] - z[:, :-1]
    k0, k1 = kz[:, :-1], kz[:, 1:]
    wk = 0.5 * h * (k0 + k1)
    wka = _simpson(h, k0, k1, fz[:, :-1], fz[:, 1:])
    wkt = _simpson(h, k0, k1, sz[:, :-1], sz[:, 1:])
    # K is linear on each piece except on the sample holding b1: redone as two pieces
    # (A linear on the sample: its value at b1 by the sample's slope)
    rows = np.arange(n)
    jb = np.minimum(gy.locate(lb1) - i0, m - 1)
    za, zb = z[rows, jb], z[rows, jb + 1]
    zm = np.clip(lb1, za, zb)
    fa, fb = fz[rows, jb], fz[rows, jb + 1]
    ib = kk[rows, jb]
    fm = cval[ib] + ax.y[ib] * (zm - bnd[ib]) - cc
    ka, kb = kz[rows, jb], kz[rows, jb + 1]
    km = np.maximum(np.minimum((zm - la1) * r1[:, 0], (lb2 - zm) * r2[:, 0]), 0.0)
    sa, sb, sm = za - tc, zb - tc, zm - tc
    ha, hb = zm - za, zb - zm
    wk[rows, jb] = 0.5 * ha * (ka + km) + 0.5 * hb * (km + kb)
    wka[rows, jb] = _simpson(ha, ka, km, fa, fm) + _simpson(hb, km, kb, fm, fb)
    wkt[rows, jb] = _simpson(ha, ka, km, sa, sm) + _simpson(hb, km, kb, sm, sb)
    # A's extremes over the support (C linear between the samples: the range table of
    # C at the sample boundaries and the ends, rounding included, less C(t_c) +- its
    # rounding): int K |A| <= max |A|, int K |A - Abar| <= max |A - Abar| (int K = 1 up
    # to the sums' rounding, the factor 1 + 1e-9); likewise |t - t_c| <= half the support
    clo, chi, _ = c_extremes(w, la1, lb2)
    amin_f, amax_f = clo - cc - ec, chi - cc + ec
    amax = up(np.maximum(np.abs(amin_f), np.abs(amax_f)))
    abar = np.sum(wka, axis=1)
    tbar = np.sum(wkt, axis=1)
    half = 0.5 * (lb2 - la1)
    abs_ka = amax * (1 + 1e-9)
    abs_kt = half * (1 + 1e-9)
    dev_a = np.maximum(amax_f - abar, abar - amin_f) * (1 + 1e-9)
    dev_t = (half + np.abs(tbar)) * (1 + 1e-9)
    # C's rounding in A: the table's bound (its running maximum up to the support's last
    # boundary), C(t_c)'s, and the few operations forming A at a point (each within an
    # ulp of |C| + |C(t_c)| + |y_x| max_len)
    cmax = float(np.max(np.abs(cval))) + float(np.max(np.abs(ax.y))) * w.imu.max_len
    aerr = up(_err_max(w)[np.minimum(i1 + 1, bnd.size - 1)] + ec
              + 8 * EPS * (cmax + np.abs(cc)))
    yv = gy.y[k] - c[:, None]
    nz = k.shape[1] + 8
    m_a = np.sum(yv * wka, axis=1)
    m_t = np.sum(yv * wkt, axis=1)
    # the sums' rounding: within 2 n eps of the sums of magnitudes (n the pieces), |y -
    # c| <= max|y| + |c|, sum |wka| <= max|A| sum wk, sum |wkt| <= half sum wk; each
    # piece's Simpson sum within a few ulps of those
    ymax = float(np.max(np.abs(gy.y))) + np.abs(c)
    e_a = 8 * nz * EPS * (ymax + 1) * 2 * abs_ka
    e_t = 8 * nz * EPS * (ymax + 1) * 2 * abs_kt
    ca = wka - abar[:, None] * wk
    ct = wkt - tbar[:, None] * wk
    # the centred weights' rounding: |dc| <= 8 n eps (|wka| + |abar| wk) per weight, its
    # sd at most sum |dc| x one sample's sd
    one = math.sqrt(cn.N**2 / dt + 2 * cn.Q**2 / dt**2 + cn.flicker_sigma() ** 2)
    rnd_a = 8 * nz * EPS * (abs_ka + np.abs(abar)) * one * ratio
    rnd_t = 8 * nz * EPS * (abs_kt + np.abs(tbar)) * one * ratio
    sd = batch_sd(cn, np.concatenate([ca, ct]), dt) * ratio
    # the gyro's constant error: int K (e0 - e0 int K) f = e0 (1 - int K) int K f, int K
    # = (L1 + L2) / (2 tau) up to two roundings
    norm = np.abs((lb2 - la1) / (2 * tau) - 1) + 4 * EPS
    e0 = w.ctx.E0["gyro_z"] * norm
    known = (np.abs(m_a) + e_a + (rho + e0) * abs_ka + k_wa * (sd[:n] + rnd_a) + ed * dev_a)
    tb = (np.abs(m_t) + e_t + (rho + e0) * abs_kt + k_wt * (sd[n:] + rnd_t) + ed * dev_t)
    known = np.where(ok, up(known * (1 + 1e-9)), np.inf)
    tb = np.where(ok, up(tb * (1 + 1e-9)), np.inf)
    return known, tb, np.where(ok, aerr, np.inf)


#: the samples of one chunk of windows (:func:`known_shape_terms`)
CELLS = 400_000
#: samples per block of the Gauss-Markov variances (:func:`batch_sd`)
BLOCK = 32


def _gm_block_sd(sg: float, phi: float, d: np.ndarray, r2: np.ndarray) -> np.ndarray:
    """Per row, a bound of the standard deviation of ``sum_k c_k x_k`` (x a stationary
    Gauss-Markov process, variance ``sg^2``, correlation ``phi^|j-k|``) with c split on
    blocks of B = :data:`BLOCK` samples as ``c_k = d_b + r_k`` (``d_b`` the block's mean
    weight, ``sum_(k in b) r_k = 0``; ``r2`` = ``sum r_k^2``): by Minkowski, ``sd(sum_b d_b
    X_b) + sd(sum r_k x_k)`` (X_b the block sums). The first exactly: ``Var(X_b) = sg^2
    P``, ``P = sum_(u,v<B) phi^|u-v|``, and for blocks Delta >= 1 apart ``Cov = sg^2 S^2
    phi^(1-B) psi^Delta`` (``S = sum_(v<B) phi^v``, ``psi = phi^B``), so ``Var = sg^2
    ((P - S^2 phi^(1-B)) sum d^2 + S^2 phi^(1-B) d' Psi d)``, ``d' Psi d`` by the two
    exponential filters of ``psi`` (as ``budget.kernel_variance``). The second: r sums
    to zero on each block, so ``r' Phi r = r' (Phi - Phi~) r`` for ``Phi~`` constant on
    block pairs (``psi^Delta``); ``|phi^|j-k| - psi^Delta| <= 1 - phi^(B-1)`` in a block
    and ``<= phi^(B Delta - B + 1) (1 - phi^(2B-2))`` Delta >= 1 blocks apart, so each row
    of the difference sums to at most ``lam = B (1 - phi^(B-1)) + 2 B phi (1 -
    phi^(2B-2)) / (1 - psi)`` (Gershgorin: ``|r' E r| <= lam |r|^2``); also ``r' Phi r
    <= (1 + phi)/(1 - phi) |r|^2`` (Phi's row sums); the smaller."""
    B = BLOCK
    v = np.arange(B)
    S = float(np.sum(phi**v))
    uu, vv = np.meshgrid(v, v)
    P = float(np.sum(phi ** np.abs(uu - vv)))
    off = S * S * phi ** (1 - B)
    psi = phi**B
    f = lfilter([1.0], [1.0, -psi], d, axis=1)
    g = lfilter([1.0], [1.0, -psi], d[:, ::-1], axis=1)[:, ::-1]
    dd = np.sum(d * d, axis=1)
    var_d = (P - off) * dd + off * np.sum(d * (f + g - d), axis=1)
    # the rounding of the filters and sums: within 1e-9 of their magnitudes' bound
    # (|d' Psi d| <= (1 + psi)/(1 - psi) |d|^2, each term's few ulps)
    mag = (abs(P - off) + off * (1 + psi) / max(1 - psi, 1e-300)) * dd
    var_d = np.maximum(var_d, 0.0) + 1e-9 * mag
    lam = B * (1 - phi ** (B - 1)) + 2 * B * phi * (1 - phi ** (2 * B - 2)) / max(1 - psi, 1e-300)
    lam = min(lam * (1 + 1e-9), (1 + phi) / max(1 - phi, 1e-300))
    return sg * (np.sqrt(var_d) + np.sqrt(lam * r2)) * (1 + 1e-9)


def batch_sd(cn: ChannelNoise, rows: np.ndarray, dt: float) -> np.ndarray:
    """Per row ``c`` of ``rows`` (weights on consecutive samples), a bound of the standard
    deviation of ``sum_k c_k n_k``, n the channel's Gaussian noise (white, quantization,
    flicker as independent parts: their standard deviations added, a bound of the root
    of the summed variances): white ``N sqrt(sum c^2 / dt)`` and quantization ``Q
    sqrt(sum (diff c)^2) / dt`` (c padded by a zero at both ends) exactly, each of the
    flicker's Gauss-Markov components by :func:`_gm_block_sd` (the rows padded with
    zeros to whole blocks: a zero weight adds nothing)."""
    n, m = rows.shape
    nb = -(-m // BLOCK)
    c = np.zeros((n, nb * BLOCK))
    c[:, :m] = rows
    white = cn.N * np.sqrt(np.sum(c * c, axis=1) * (1 + 1e-9) / dt)
    quant = np.zeros(n)
    if cn.Q > 0:
        cq = np.zeros((n, m + 2))
        cq[:, 1:-1] = rows
        dq = np.diff(cq, axis=1)
        quant = cn.Q * np.sqrt(np.sum(dq * dq, axis=1) * (1 + 1e-9)) / dt
    cb = c.reshape(n, nb, BLOCK)
    d = np.mean(cb, axis=2)
    r = cb - d[:, :, None]
    r2 = np.sum(r * r, axis=(1, 2))
    # the block means' rounding leaves sum_b r_k within a few ulps of zero: r' Phi~ r
    # <= (sum_b |sum r|)^2 <= (4 eps sum |c|)^2, added to |r|^2 (Phi~ entries <= 1)
    r2 = r2 + (4 * 2.3e-16 * np.sum(np.abs(c), axis=1)) ** 2
    var = white * white + quant * quant
    for sg, b in cn.gm_terms():
        var = var + _gm_block_sd(sg, math.exp(-b * dt), d, r2) ** 2
    return np.asarray(up(np.sqrt(var * (1 + 1e-9)) * (1 + 1e-9)))
