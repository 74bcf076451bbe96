"""How the body forward velocity u moves within a span, from the SIGNED running integral
of accel_x (docs/dynamic-method.md, section 3, **accel_y**, positions only): shared by
the transport term's gyro-shape form (:mod:`.transport_gyro`) and its fix blocks
(:func:`~imubounds.dynamic.estimator.aided.transport_fixes.u_deviation`).

``u' = f_x + r v - q w - g sin(theta)`` + the Earth's Coriolis and transport terms (their
magnitude ``k_o``, :func:`other_rate`), and ``y_x = (1 + s) f_x + m (f_y, f_z) + b + n``,
so for ``|t - s| <= x``: ``u(t) - u(s) = C(t) - C(s) + eps`` (C accel_x's running
integral, :func:`c_extremes`) with ``|eps| <= k_o x + s int|f_x| + m x max|f_perp| +
|int b| + |int n|`` (:func:`accel_error`): ``int|f|`` from the samples' magnitudes plus
E0; the bias the turn-on bound plus the wander, ``|int d| <= D_s x`` over a span of at
least the stated drift window (the stated drift bound bounds every such mean; the model's
rule: its per-sample bound) plus the per-sample bound's excess over ``D_s`` on at most one
window's length (:class:`~imubounds.dynamic.estimator.budget.Wander`); the white noise's
running integral ``k N sqrt(x)`` (the caller's k, by Levy's inequality) and the
quantization's ``2 k_q Q`` (its value at both ends); the samples are the means of the true
signal over them plus the error, so a span's ends cutting a sample add
:func:`sample_model`.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.special import ndtri

from imubounds.constants import EARTH_RATE, G_HI, R_EARTH, ROUND_REL
from imubounds.dynamic.estimator.aided.base import up
from imubounds.dynamic.estimator.aided.common import WindowContext
from imubounds.dynamic.estimator.aided.velocity import speed_max
from imubounds.dynamic.estimator.inputs import RangeExt


def k_two(p: float) -> float:
    """``Phi^-1(1 - p/2)``: a two-sided Gaussian bound at probability ``p``."""
    return float(-ndtri(0.5 * p))


def _table(w: WindowContext) -> RangeExt:
    """Range table of accel_x's running integral ``C`` at the sample boundaries, each
    widened by its rounding bound (computed once per run)."""
    key = "accel_x_cum_ext"
    if key not in w.cache:
        sig = w.imu.sig["accel_x"]
        val, err, _ = sig.cum(sig.bnd)
        err = up(err * (1 + 1e-9) + 1e-300)
        w.cache[key] = RangeExt(np.nextafter(val - err, -np.inf), up(val + err))
    return w.cache[key]


def c_extremes(w: WindowContext, s0: np.ndarray, s1: np.ndarray) -> tuple[np.ndarray, ...]:
    """Bounds of ``min C`` and ``max C`` over each ``[s0, s1]`` (C linear between the
    samples: its extremes at the sample boundaries inside and the ends; rounding
    included) and the length of unknown samples there (where C has no value: the caller
    adds ``xmax`` per second)."""
    sig = w.imu.sig["accel_x"]
    c0, e0, _ = sig.cum(s0)
    c1, e1, _ = sig.cum(s1)
    i0 = sig.locate(s0) + 1
    i1 = np.minimum(sig.locate(s1), sig.bnd.size - 1)
    has = i1 >= i0
    mn, mx = _table(w).query(np.where(has, i0, 0), np.where(has, i1, 0))
    lo = np.minimum(c0 - e0, c1 - e1)
    hi = np.maximum(c0 + e0, c1 + e1)
    lo = np.where(has, np.minimum(lo, mn), lo)
    hi = np.where(has, np.maximum(hi, mx), hi)
    return np.nextafter(lo, -np.inf), up(hi), sig.unknown_len(s0, s1)


def other_rate(w: WindowContext, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``k_o``: the magnitude bound of ``u' - f_x`` over ``[a, b]`` (``v_max (max_rate +
    earth) + g_max |sin theta| + 2 Omega S + S^2/R_E + W max_rate``, S the speed bound,
    v_max the lateral bound)."""
    veh = w.veh
    S = speed_max(w, a, b)
    vl = veh.lateral_speed_bound_mps
    vmax = S if vl is None else np.minimum(S, vl)
    earth = EARTH_RATE + S / R_EARTH
    return up(
        vmax * (veh.max_rate + earth)
        + G_HI * w.tilt.hull("abs_sinp", a, b).hi
        + 2 * EARTH_RATE * S + S * S / R_EARTH
        + veh.vertical_bound * veh.max_rate
    )


def error_rates(w: WindowContext, turn_on: bool = True) -> tuple[float, float, float, float]:
    """``(lin, excess, window, scale)``: the error of ``int f_x`` over a span x is at most
    ``lin x + excess min(x, window) + scale int|y_x|`` + the noise (:func:`accel_error`);
    ``turn_on=False``: without the turn-on bias (``lin`` less the turn-on bound, for a
    caller that carries the turn-on as a constant times the span)."""
    ctx = w.ctx
    cn = ctx.noise["accel_x"]
    wd = ctx.wander["accel_x"]
    s = cn.scale
    model = ctx.k_ps * cn.flicker_sigma() + wd.kr
    per_sample = float(wd.pick(model, wd.point))
    mean_long = min(float(wd.pick(model, wd.stated)), per_sample)
    b_to = cn.turn_on_bound(ctx.alpha.k("imu_turn_on")) if turn_on else 0.0
    win_s = float(wd.window_s) if wd.rule != "model" else 0.0
    mis = 0.0
    if cn.misalignment_rad > 0:
        for other in ("accel_y", "accel_z"):
            o_max = (w.imu.sig[other].xmax if not w.imu.available[other]
                     else float(np.max(np.abs(w.imu.sig[other].y))) + ctx.E0[other])
            mis += cn.misalignment_rad * o_max / (1.0 - ctx.noise[other].scale)
    lin = b_to + mean_long + s * ctx.E0["accel_x"] / (1.0 - s) + mis
    return (float(up(np.asarray(lin * (1 + ROUND_REL)))), per_sample - mean_long, win_s,
            s / (1.0 - s))


def noise_amplitudes(w: WindowContext) -> tuple[float, float]:
    """accel_x's white density N (times the square root of the longest sample over the
    period) and quantization Q (times that ratio): the running integral's noise is
    ``k N sqrt(x) + 2 k_q Q``."""
    cn = w.ctx.noise["accel_x"]
    ratio = max(1.0, w.imu.max_len / w.imu.dt)
    return cn.N * math.sqrt(ratio), cn.Q * ratio


def accel_error(
    w: WindowContext, x: np.ndarray, absint: np.ndarray, kw: float, kq: np.ndarray | float,
    turn_on: bool = True,
) -> np.ndarray:
    """Bound of ``|int_s^t f_x - int_s^t y_x|`` over a span ``|t - s| <= x`` (module
    docstring; ``absint`` a bound of ``int |y_x|`` there, ``kw``, ``kq`` the caller's
    factors of the white noise and quantization); ``turn_on=False``: of that less ``b_TO
    (t - s)`` (:func:`error_rates`)."""
    lin, excess, win_s, sc = error_rates(w, turn_on)
    nw, nq = noise_amplitudes(w)
    return up((lin * x + excess * np.minimum(x, win_s) + sc * absint
               + kw * nw * np.sqrt(x) + 2.0 * np.asarray(kq) * nq + sample_model(w))
              * (1 + ROUND_REL))


def sample_model(w: WindowContext) -> float:
    """The span's ends cut a sample: ``|int_part (f - mean_sample f)| <= part x rate x
    len`` at each end (``rate`` the bound of accel_x's rate of change, len the longest
    sample): ``2 rate max_len^2``."""
    ml = w.imu.max_len
    return float(up(np.asarray(2.0 * w.imu.rate_bound["accel_x"] * ml * ml)))
