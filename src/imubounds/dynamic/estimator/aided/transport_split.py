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
gyro's error on the known weights ``K (A - Abar)`` and ``K (t - t_c - m)``: its Gaussian
part (white, quantization, flicker) a zero-mean Gaussian whose variance is exact for the
weights (``budget.kernel_variance``; the weights sum to zero, so the turn-on drops out;
regular samples, the sd times the ratio of the longest sample to the period as
``transport_gyro._ramp_noise_sd``), within ``k`` standard deviations; its deterministic
part (scale and misalignment on the rate bound, the rate random walk's bound, the
Earth's rates: ``|e_d| <= ed``) within ``ed int K |f - fbar|``. The weights A come from
the accelerometer's samples only and ``t - t_c`` from the clock: both independent of
the gyro's noise, so the Gaussian statement holds for them as for fixed weights.
The last term is the old form's (``transport_gyro``) with ``D'``.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.signal import lfilter

from imubounds.dynamic.estimator.aided.accel_integral import k_two
from imubounds.dynamic.estimator.aided.base import up
from imubounds.dynamic.estimator.aided.common import WindowContext
from imubounds.dynamic.estimator.budget import ChannelNoise
from imubounds.dynamic.estimator.window_plan import LevelPlan

_EPS = 2.3e-16


def _cum_table(w: WindowContext) -> tuple[np.ndarray, np.ndarray]:
    """accel_x's running integral C at every sample boundary and its rounding bound
    (computed once per run)."""
    key = "transport_split_cum"
    if key not in w.cache:
        sig = w.imu.sig["accel_x"]
        val, err, _ = sig.cum(sig.bnd)
        w.cache[key] = (val, up(err * (1 + 1e-9) + 1e-300))
    return w.cache[key]


def _simpson(h: np.ndarray, k0: np.ndarray, k1: np.ndarray, f0: np.ndarray,
             f1: np.ndarray) -> np.ndarray:
    """``int K f`` over a piece of length h where K and f are linear (ends k, f): exact
    (Simpson's rule on the quadratic K f)."""
    return h / 6.0 * (2 * k0 * f0 + k0 * f1 + k1 * f0 + 2 * k1 * f1)


def known_shape_terms(
    w: WindowContext,
    lp: LevelPlan,
    tau: np.ndarray,
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
    sample of either channel is unknown in the support. Computed for all windows at once:
    a row per window, a column per sample of its support (the sample cut at ``b1`` into
    two pieces, at the support's ends clipped)."""
    n = lp.a1.size
    inf = np.full(n, np.inf)
    gy = w.imu.sig["gyro_z"]
    ax = w.imu.sig["accel_x"]
    if n == 0 or gy.bnd.size != ax.bnd.size or not np.array_equal(gy.bnd, ax.bnd):
        return inf, inf.copy(), inf.copy()
    cn = w.ctx.noise["gyro_z"]
    dt = w.imu.dt
    ratio = max(1.0, w.imu.max_len / dt)
    kg = k_two(0.5 * p)
    bnd = gy.bnd
    a1, b1, b2 = lp.a1[:, None], lp.b1[:, None], lp.b2[:, None]
    ta = tau[:, None]
    tc = 0.5 * (lp.a1 + lp.b2)
    ok = (gy.unknown_len(lp.a1, lp.b2) == 0) & (ax.unknown_len(lp.a1, lp.b2) == 0)
    i0 = gy.locate(lp.a1)
    cnt = gy.locate(lp.b2) - i0 + 1
    k = i0[:, None] + np.arange(int(np.max(cnt)))[None, :]
    valid = np.arange(k.shape[1])[None, :] < cnt[:, None]
    k = np.minimum(k, bnd.size - 2)
    lo = np.where(valid, np.maximum(bnd[k], a1), 0.0)
    hi = np.where(valid, np.minimum(bnd[k + 1], b2), 0.0)
    hi = np.maximum(hi, lo)
    cval, cerr = _cum_table(w)
    ya = ax.y[k]
    cc, ec, _ = ax.cum(tc)
    L1, L2 = b1 - a1, b2 - b1

    def kern(t: np.ndarray, right: bool) -> np.ndarray:
        return np.clip((b2 - t) / (L2 * ta) if right else (t - a1) / (L1 * ta), 0.0, None)

    wk = np.zeros(k.shape)
    wka = np.zeros(k.shape)
    wkt = np.zeros(k.shape)
    abs_a = np.zeros(k.shape)
    abs_t = np.zeros(k.shape)
    pieces = []
    for right in (False, True):  # the sample's part before b1 (I1), after it (I2)
        z0 = np.maximum(lo, b1) if right else lo
        z1 = hi if right else np.minimum(hi, b1)
        h = np.maximum(z1 - z0, 0.0)
        z1 = z0 + h
        k0, k1 = kern(z0, right), kern(z1, right)
        # A = C - C(t_c), C linear on the sample: C(bnd_k) + y_k (z - bnd_k)
        f0 = cval[k] + ya * (z0 - bnd[k]) - cc[:, None]
        f1 = cval[k] + ya * (z1 - bnd[k]) - cc[:, None]
        s0, s1 = z0 - tc[:, None], z1 - tc[:, None]
        wk += 0.5 * h * (k0 + k1)
        wka += _simpson(h, k0, k1, f0, f1)
        wkt += _simpson(h, k0, k1, s0, s1)
        pieces.append((h, k0, k1, f0, f1, s0, s1))
    kw = np.array([0.5 * pc[0] * (pc[1] + pc[2]) for pc in pieces])  # int K per piece
    for j, (_, _, _, f0, f1, s0, s1) in enumerate(pieces):
        abs_a += kw[j] * np.maximum(np.abs(f0), np.abs(f1))
        abs_t += kw[j] * np.maximum(np.abs(s0), np.abs(s1))
    abs_ka, abs_kt = np.sum(abs_a, axis=1), np.sum(abs_t, axis=1)
    # C's rounding in A: the table's bound, the products' and the difference's
    amag = np.max(np.where(valid, np.abs(cval[k]) + np.abs(ya) * (bnd[k + 1] - bnd[k]), 0.0),
                  axis=1)
    aerr = up(np.max(np.where(valid, cerr[k], 0.0), axis=1) + ec
              + 8 * _EPS * (amag + np.abs(cc)))
    yv = np.where(valid, gy.y[k] - c[:, None], 0.0)
    nz = 2 * k.shape[1] + 8
    m_a = np.sum(yv * wka, axis=1)
    m_t = np.sum(yv * wkt, axis=1)
    # the sums' rounding: within 2 n eps of the sums of magnitudes (n the pieces), the
    # pieces' Simpson sums likewise (the abs bounds dominate the products' magnitudes)
    e_a = 8 * nz * _EPS * (np.sum(np.abs(yv) * abs_a, axis=1) + abs_ka)
    e_t = 8 * nz * _EPS * (np.sum(np.abs(yv) * abs_t, axis=1) + abs_kt)
    abar = np.sum(wka, axis=1)
    tbar = np.sum(wkt, axis=1)
    ca = wka - abar[:, None] * wk
    ct = wkt - tbar[:, None] * wk
    # int K |f - fbar| <= sum_piece int K x max over the piece's ends (f linear there)
    dev_a = np.zeros(n)
    dev_t = np.zeros(n)
    for j, (_, _, _, f0, f1, s0, s1) in enumerate(pieces):
        dev_a += np.sum(kw[j] * np.maximum(np.abs(f0 - abar[:, None]), np.abs(f1 - abar[:, None])),
                        axis=1)
        dev_t += np.sum(kw[j] * np.maximum(np.abs(s0 - tbar[:, None]), np.abs(s1 - tbar[:, None])),
                        axis=1)
    # the centred weights' rounding: |dc| <= 8 n eps (|wka| + |abar| wk) per weight, its
    # sd at most sum |dc| x one sample's sd
    one = math.sqrt(cn.N**2 / dt + 2 * cn.Q**2 / dt**2 + cn.flicker_sigma() ** 2)
    rnd_a = 8 * nz * _EPS * (np.sum(np.abs(wka), axis=1) + np.abs(abar)) * one * ratio
    rnd_t = 8 * nz * _EPS * (np.sum(np.abs(wkt), axis=1) + np.abs(tbar)) * one * ratio
    sd = np.sqrt(batch_variance(cn, np.concatenate([ca, ct]), dt)) * ratio
    known = (np.abs(m_a) + e_a + rho * abs_ka + kg * (sd[:n] + rnd_a) + ed * dev_a)
    tb = (np.abs(m_t) + e_t + rho * abs_kt + kg * (sd[n:] + rnd_t) + ed * dev_t)
    known = np.where(ok, up(known * (1 + 1e-9)), np.inf)
    tb = np.where(ok, up(tb * (1 + 1e-9)), np.inf)
    return known, tb, np.where(ok, aerr, np.inf)


def batch_variance(cn: ChannelNoise, rows: np.ndarray, dt: float) -> np.ndarray:
    """``budget.kernel_variance(cn, c, dt, False)`` for each row ``c`` of ``rows`` at
    once (the same formula: white ``N^2 sum c^2 / dt``, quantization ``Q^2 sum (diff
    c)^2 / dt^2`` with c padded by a zero at both ends, each Gauss-Markov component
    ``sigma^2 c' Phi c`` by the two exponential filters); a row's trailing zeros add
    nothing to any of the sums (the backward filter runs through zeros only until the
    row's last weight). Inflated by 1e-9 relative for rounding, as there."""
    c = np.zeros((rows.shape[0], rows.shape[1] + 2))
    c[:, 1:-1] = rows
    v = cn.N * cn.N * np.sum(c * c, axis=1) / dt
    if cn.Q > 0:
        d = np.diff(c, axis=1)
        v += cn.Q * cn.Q * np.sum(d * d, axis=1) / (dt * dt)
    for sg, b in cn.gm_terms():
        phi = math.exp(-b * dt)
        f = lfilter([1.0], [1.0, -phi], c, axis=1)
        g = lfilter([1.0], [1.0, -phi], c[:, ::-1], axis=1)[:, ::-1]
        v += sg * sg * np.sum(c * (f + g - c), axis=1)
    return np.asarray(np.maximum(v, 0.0) * (1.0 + 1e-9))
