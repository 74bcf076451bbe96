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

from imubounds.dynamic.estimator.aided.accel_integral import k_two
from imubounds.dynamic.estimator.aided.base import up
from imubounds.dynamic.estimator.aided.common import WindowContext
from imubounds.dynamic.estimator.budget import kernel_variance
from imubounds.dynamic.estimator.window_plan import LevelPlan

_EPS = 2.3e-16


def _nodes(
    bnd: np.ndarray, a1: float, b1: float, b2: float, i0: int, i1: int
) -> np.ndarray:
    """The support's pieces: its knots and the sample boundaries inside (sorted)."""
    inner = bnd[i0 + 1 : i1 + 1]
    inner = inner[(inner > a1) & (inner < b2)]
    return np.unique(np.concatenate([[a1, b1, b2], inner]))


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
    sample of either channel is unknown in the support."""
    n = lp.a1.size
    known = np.full(n, np.inf)
    tb = np.full(n, np.inf)
    aerr = np.full(n, np.inf)
    gy = w.imu.sig["gyro_z"]
    ax = w.imu.sig["accel_x"]
    if n == 0:
        return known, tb, aerr
    cn = w.ctx.noise["gyro_z"]
    dt = w.imu.dt
    ratio = max(1.0, w.imu.max_len / dt)
    kg = k_two(0.5 * p)
    bnd = gy.bnd
    tc_all = 0.5 * (lp.a1 + lp.b2)
    ok = (gy.unknown_len(lp.a1, lp.b2) == 0) & (ax.unknown_len(lp.a1, lp.b2) == 0)
    i0s = gy.locate(lp.a1)
    i1s = gy.locate(lp.b2)
    cc, ec, _ = ax.cum(tc_all)
    for i in range(n):
        if not ok[i]:
            continue
        a1, b1, b2, tc = float(lp.a1[i]), float(lp.b1[i]), float(lp.b2[i]), float(tc_all[i])
        z = _nodes(bnd, a1, b1, b2, int(i0s[i]), int(i1s[i]))
        t0, t1 = z[:-1], z[1:]
        h = t1 - t0
        L1, L2, ta = b1 - a1, b2 - b1, float(tau[i])
        kz = np.clip(np.where(z <= b1, (z - a1) / (L1 * ta), (b2 - z) / (L2 * ta)), 0.0, None)
        k0, k1 = kz[:-1], kz[1:]
        cv, ce, _ = ax.cum(z)
        az = cv - cc[i]
        a_e = float(up(np.max(ce) + ec[i] + 4 * _EPS * (np.max(np.abs(cv)) + abs(cc[i]))))
        a0, a1v = az[:-1], az[1:]
        wk = 0.5 * h * (k0 + k1)
        wka = h / 6.0 * (2 * k0 * a0 + k0 * a1v + k1 * a0 + 2 * k1 * a1v)
        s0, s1 = t0 - tc, t1 - tc
        wkt = h / 6.0 * (2 * k0 * s0 + k0 * s1 + k1 * s0 + 2 * k1 * s1)
        seg = gy.locate(0.5 * (t0 + t1))
        yv = gy.y[seg] - c[i]
        # the measured parts; their rounding: each product and sum within a few ulps of
        # the sum of magnitudes (2 n eps relative, n the pieces)
        m_a = float(np.dot(yv, wka))
        m_t = float(np.dot(yv, wkt))
        nz = z.size + 8
        abs_ka = float(np.sum(wk * np.maximum(np.abs(a0), np.abs(a1v))))
        abs_kt = float(np.sum(wk * np.maximum(np.abs(s0), np.abs(s1))))
        e_a = 4 * nz * _EPS * float(np.dot(np.abs(yv), np.abs(wka)) + abs_ka)
        e_t = 4 * nz * _EPS * float(np.dot(np.abs(yv), np.abs(wkt)) + abs_kt)
        # the gyro's error on the centred weights K (A - Abar), K (t - t_c - m)
        abar = float(np.sum(wka))
        tbar = float(np.sum(wkt))
        j = seg - seg[0]
        ca = np.bincount(j, weights=wka - abar * wk)
        ct = np.bincount(j, weights=wkt - tbar * wk)
        sda = math.sqrt(kernel_variance(cn, ca, dt, False)) * ratio
        sdt = math.sqrt(kernel_variance(cn, ct, dt, False)) * ratio
        # int K |f - fbar| <= sum_piece int K x max over the piece's ends (f linear there)
        dev_a = float(np.sum(wk * np.maximum(np.abs(a0 - abar), np.abs(a1v - abar))))
        dev_t = float(np.sum(wk * np.maximum(np.abs(s0 - tbar), np.abs(s1 - tbar))))
        # the rounding of the centred weights: |d c| <= 4 n eps (|wka| + |abar| wk)
        rnd_a = 4 * nz * _EPS * (float(np.sum(np.abs(wka))) + abs(abar))
        rnd_t = 4 * nz * _EPS * (float(np.sum(np.abs(wkt))) + abs(tbar))
        one = math.sqrt(cn.N**2 / dt + 2 * cn.Q**2 / dt**2 + cn.flicker_sigma() ** 2)
        known[i] = (abs(m_a) + e_a + float(rho[i]) * abs_ka + kg * (sda + rnd_a * one * ratio)
                    + ed * dev_a)
        tb[i] = (abs(m_t) + e_t + float(rho[i]) * abs_kt + kg * (sdt + rnd_t * one * ratio)
                 + ed * dev_t)
        aerr[i] = a_e
    return (up(known * (1 + 1e-9)), up(tb * (1 + 1e-9)), aerr)
