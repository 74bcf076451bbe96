"""The limit the input bounds allow for accel_x's and gyro_z's window means, computed
independently of the estimator's constraint code (docs/dynamic-method.md, section 6;
issue 24 item 4).

What it computes, per aided window of accel_x (the windows the estimator planned), as a
half-width of the true kernel mean ``[x_W]`` (gyro_z: :func:`gyro_z_limits`):

* **ends**: the spread the aiding boxes alone leave in the end velocities:
  velocity at both ends (boxcar ``[a, b]``): ``(R_a + R_b)/tau`` with ``R`` the GNSS
  velocity radius (the speed's radial uncertainty, at least that of u) or the
  body-velocity sensor's half-width; positions only (trapezoid over ``I1 = [a1, b1]``,
  ``I2 = [b1, b2]``): with the heading piecewise constant on the fix gaps (the compass
  centres), the kernel mean of u is ``sum_k c_k . P_k`` over the fixes, so the boxes
  ``+-h_k`` per axis leave ``sum_k h_k |c_k|_1`` (``c_k`` from the gap headings
  ``e_k``: ``e_a1/L1``, ``(e_k-1 - e_k)/L``, ``-(e_b1-1/L1 + e_b1/L2)``, ...; over tau);
* **transport**: ``v_max x M``, ``v_max`` the lateral bound (or the body-velocity
  sensor's ``|v_m| + h`` when smaller), ``M`` the kernel mean of ``|y_r - c|`` with
  ``y_r`` gyro_z's samples and ``c`` its mean error over the support as the heading
  gives it (``mean y_r - (psi_c(end) - psi_c(start))/L``): the gyro's record with its
  noise counted ONCE (the truth's mean |r| plus what the noise adds to it in the
  record). This is a choice, not a proof of minimality: a world where the gyro noise
  deviates from its mean by its whole high-probability bound is also consistent with
  the gyro's bounds, but not with the heading at every epoch in between;
* **gravity**: ``g_max sin(max tilt)`` (any tilt within the bound is consistent); where
  the pitch is bounded from GNSS altitude (``ctx.aiding.pitch``: the same boxes the
  estimator's input has, docs/dynamic-method.md 3a) half the kernel mean of
  ``g_max (sin(hi) - sin(lo))`` over the window (any pitch within its boxes is
  consistent), integrated here on a grid of the support;
* **Earth rate**: ``2 Omega S + S^2/R_E`` with ``S`` the largest measured speed
  (GNSS velocity, chord speed of the fixes or the body-velocity sensor) in the window;

and the limit is the smaller of their sum and what the vehicle bounds alone allow
(``max_accel + g_max sin(max tilt)``).

The terms are left out where they are smaller (the tilt conversion of u, the heading
width's second-order projection), so the limit is on the low side: the ratio
estimator / limit is if anything overstated.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

OMEGA = 7.2921159e-5
R_E = 6.371e6
G_MAX = 9.84


@dataclass
class LevelRatio:
    tau_s: float
    estimator: float  # median half-width of [E_W]
    limit: float  # median of the reference limit over the same windows
    terms: dict[str, float]

    @property
    def ratio(self) -> float:
        return self.estimator / self.limit


def _heading_centres(ag: Any, t: np.ndarray) -> np.ndarray:
    return np.interp(t, ag.head_t, ag.head_c)


def _gyro_abs_dev(sig: Any, s0: float, s1: float, weight: Any, c: float) -> float:
    """``int K |y - c|`` over [s0, s1] for the samples of a piecewise-constant signal
    (``weight(t)`` the kernel at the segment midpoints)."""
    bnd = sig.bnd
    k0 = max(int(np.searchsorted(bnd, s0, side="right")) - 1, 0)
    k1 = int(np.searchsorted(bnd, s1, side="left"))
    lo = np.maximum(bnd[k0:k1], s0)
    hi = np.minimum(bnd[k0 + 1 : k1 + 1], s1)
    ln = np.maximum(hi - lo, 0.0)
    y = sig.y[k0:k1]
    return float(np.sum(weight(0.5 * (lo + hi)) * np.abs(y - c) * ln))


def _support_centre(sig: Any, ag: Any, s0: float, s1: float) -> float:
    lo, hi = sig.integral(np.array([s0]), np.array([s1]))
    ybar = 0.5 * (float(lo[0]) + float(hi[0])) / (s1 - s0)
    p0, p1 = _heading_centres(ag, np.array([s0, s1]))
    return ybar - (p1 - p0) / (s1 - s0)


def _gap_units(ag: Any) -> tuple[np.ndarray, np.ndarray]:
    """Unit heading vectors (east, north components) at the fix-gap midpoints."""
    t = ag.gnss_t
    psi = _heading_centres(ag, 0.5 * (t[:-1] + t[1:]))
    return np.cos(psi), np.sin(psi)


def _trapezoid_fixes(ag: Any, lp: Any, w: int) -> tuple[int, int, int, float, float, float]:
    """Fix indices p, m, q of trapezoid window w (its two intervals' ends on the fixes),
    the intervals' lengths L1, L2 and tau."""
    t = ag.gnss_t
    p = int(np.searchsorted(t, lp.a1[w]))
    m = int(np.searchsorted(t, lp.b1[w]))
    q = int(np.searchsorted(t, lp.b2[w]))
    L1, L2 = t[m] - t[p], t[q] - t[m]
    tau = 0.5 * (t[q] + t[m]) - 0.5 * (t[m] + t[p])
    return p, m, q, L1, L2, tau


def _positions_ends(ag: Any, ex: np.ndarray, ny: np.ndarray, lp: Any, w: int) -> float:
    """Half-width of the kernel mean of u_h from the fix boxes (trapezoid window w)."""
    h = ag.gnss_h
    p, m, q, L1, L2, tau = _trapezoid_fixes(ag, lp, w)
    n = q - p + 1
    ce = np.zeros(n)
    cn = np.zeros(n)
    # mean_I u = (1/L) sum_k (P_k+1 - P_k).e_k; the kernel is (mean_I2 - mean_I1)/tau
    for lo, hi, sgn, L in ((p, m, -1.0, L1), (m, q, 1.0, L2)):
        for k in range(lo, hi):
            ce[k + 1 - p] += sgn * ex[k] / L
            ce[k - p] -= sgn * ex[k] / L
            cn[k + 1 - p] += sgn * ny[k] / L
            cn[k - p] -= sgn * ny[k] / L
    return float(np.sum(h[p : q + 1] * (np.abs(ce) + np.abs(cn))) / tau)


def accel_x_limits(ctx: Any, plan: Any, lp: Any) -> dict[str, np.ndarray]:
    """Per window of level ``lp``: the reference limit's terms (m/s^2)."""
    ag, veh = ctx.aiding, ctx.vehicle
    sig = ctx.imu.sig["gyro_z"]
    n = lp.a1.size
    ends = np.zeros(n)
    trans = np.zeros(n)
    earth = np.zeros(n)
    vl = veh.lateral_speed_bound_mps
    gravity = np.full(n, G_MAX * math.sin(veh.max_tilt))
    if plan.trapezoid:
        ex, ny = _gap_units(ag)
        chord = np.hypot(np.diff(ag.gnss_e), np.diff(ag.gnss_n)) / np.diff(ag.gnss_t)
    for w in range(n):
        a1, b1, a2, b2 = lp.a1[w], lp.b1[w], lp.a2[w], lp.b2[w]
        tau = 0.5 * (a2 + b2) - 0.5 * (a1 + b1)
        if plan.trapezoid:
            ends[w] = _positions_ends(ag, ex, ny, lp, w)
            i0 = int(np.searchsorted(ag.gnss_t, a1))
            i2 = int(np.searchsorted(ag.gnss_t, b2))
            speed = float(np.max(chord[i0:i2]))
            vmax = vl if vl is not None else speed

            def kern(s: np.ndarray, a1=a1, b1=b1, b2=b2, tau=tau) -> np.ndarray:
                return np.where(
                    s < b1, (s - a1) / ((b1 - a1) * tau), (b2 - s) / ((b2 - b1) * tau)
                )
        else:
            if ag.has_bvel:
                tt = ag.bvel_t
                ia, ib = int(np.searchsorted(tt, a1)), int(np.searchsorted(tt, b2))
                ends[w] = (ag.bvel_h[ia] + ag.bvel_h[ib]) / tau
                speed = float(np.max(np.abs(ag.bvel_u[ia : ib + 1])))
                vmax = vl if vl is not None else math.inf
                if ag.bvel_v is not None:
                    vm = float(np.max(np.abs(ag.bvel_v[ia : ib + 1]) + ag.bvel_h[ia : ib + 1]))
                    vmax = min(vmax, vm)
            else:
                tt = ag.gnss_t[ag.gvel_ok]
                rr = ag.gvel_hi[ag.gvel_ok]
                ia, ib = int(np.searchsorted(tt, a1)), int(np.searchsorted(tt, b2))
                ends[w] = (rr[ia] + rr[ib]) / tau
                sp = np.hypot(ag.gvel_e[ag.gvel_ok], ag.gvel_n[ag.gvel_ok])
                speed = float(np.max(sp[ia : ib + 1]))
                vmax = vl if vl is not None else speed

            def kern(s: np.ndarray, a1=a1, b1=b1, b2=b2, tau=tau) -> np.ndarray:
                return np.full(s.shape, 1.0 / tau)

        c = _support_centre(sig, ag, a1, b2)
        trans[w] = vmax * _gyro_abs_dev(sig, a1, b2, kern, c)
        earth[w] = 2 * OMEGA * speed + speed * speed / R_E
        ts = _tilt_of(ctx, "accel_x")
        if ts is not None:
            gravity[w] = _pieces_gravity(ts.bnd, ts.pitch.lo, ts.pitch.hi, a1, b2, kern)
        elif ag.pitch is not None:
            gravity[w] = _pitch_gravity(ag.pitch, a1, b2, kern)
    return {"ends": ends, "transport": trans, "gravity": gravity, "earth": earth}


def _tilt_of(ctx: Any, ch: str) -> Any:
    """The roll/pitch pieces the estimator's input gives the channel's windows: its
    attitude states' variant (docs/dynamic-method.md section 3b: built without the
    channel's samples), None without the states. With the attitude known to a
    half-width delta, the accelerometer's limit takes g delta (its kernel mean)."""
    return getattr(ctx, "tilt_for", {}).get(ch)


def _pieces_gravity(bnd: np.ndarray, lo: np.ndarray, hi: np.ndarray, a: float, b: float,
                    kern: Any, factor: float = 1.0) -> float:
    """Half the kernel mean of ``factor g_max (sin(hi) - sin(lo))`` over ``[a, b]`` for an
    angle piecewise constant on ``bnd``, on a grid of 2000 points (any angle within its
    pieces is consistent with the inputs)."""
    s = np.linspace(a, b, 2000)
    k = np.clip(np.searchsorted(bnd, s, side="right") - 1, 0, lo.size - 1)
    f = kern(s) * (np.sin(hi[k]) - np.sin(lo[k]))
    return float(0.5 * factor * G_MAX * np.sum(0.5 * (f[1:] + f[:-1]) * np.diff(s)))


def _pitch_gravity(pb: Any, a: float, b: float, kern: Any) -> float:
    """:func:`_pieces_gravity` of the pitch boxes ``pb`` (piecewise constant on ``pb.bnd``)."""
    return _pieces_gravity(pb.bnd, pb.lo, pb.hi, a, b, kern)


def _level_ratios(ctx: Any, margins: Any, ch: str, limits: Any,
                  min_tau_s: float) -> list[LevelRatio]:
    """Per aided level of an accelerometer at or above ``min_tau_s``: the estimator's
    median half-width against the median reference limit over the same windows (the
    vehicle bounds alone enclose the same mean: the limit is the smaller)."""
    plan = ctx.plans[ch]
    out: list[LevelRatio] = []
    levels = [lp for lp in plan.levels if lp.n > 0]
    for lp, lv in zip(levels, margins.levels, strict=True):
        if lp.kind != "aided" or lp.tau_s < min_tau_s:
            continue
        terms = limits(ctx, plan, lp)
        out.append(_ratio(lp, lv, terms, ctx.vehicle.max_accel + terms["gravity"]))
    return out


def accel_x_ratios(ctx: Any, margins: Any, min_tau_s: float = 0.0) -> list[LevelRatio]:
    """:func:`_level_ratios` of accel_x."""
    return _level_ratios(ctx, margins, "accel_x", accel_x_limits, min_tau_s)


def _ratio(lp: Any, lv: Any, terms: dict[str, np.ndarray], cap: Any) -> LevelRatio:
    """The level's median half-width against the median of the smaller of the terms'
    sum and ``cap`` (what the vehicle bounds alone allow)."""
    lim = np.minimum(sum(terms.values()), cap)
    est = 0.5 * (lv.e_hi - lv.e_lo)
    return LevelRatio(
        lp.tau_s,
        float(np.median(est)),
        float(np.median(lim)),
        {k: float(np.median(v)) for k, v in terms.items()},
    )


def gyro_z_limits(ctx: Any, lp: Any) -> dict[str, np.ndarray]:
    """Per window of gyro_z (boxcar between heading epochs): ``(h_a + h_b)/tau`` from the
    heading boxes, ``tan(max tilt) x`` gyro_y's window mean of ``|y_q - mean y_q|`` (the
    tilt coupling ``q tan(phi)`` with the noise counted once), and the Earth rate
    ``Omega + S/R_E`` (S the largest measured speed, or 0 without one: on the low side)."""
    ag, veh = ctx.aiding, ctx.vehicle
    sig = ctx.imu.sig["gyro_y"]
    n = lp.a1.size
    head = (ag.head_h[lp.i] + ag.head_h[lp.j]) / lp.tau
    tilt = np.zeros(n)
    ts = _tilt_of(ctx, "gyro_z")
    for w in range(n):
        a, b = lp.a1[w], lp.b2[w]
        lo, hi = sig.integral(np.array([a]), np.array([b]))
        c = 0.5 * (float(lo[0]) + float(hi[0])) / (b - a)
        tmax = math.tan(veh.max_tilt)
        if ts is not None:  # the largest |tan(roll)| of the states' pieces over the window
            k0 = max(int(np.searchsorted(ts.bnd, a, side="right")) - 1, 0)
            k1 = max(int(np.searchsorted(ts.bnd, b, side="left")), k0 + 1)
            r = np.maximum(np.abs(ts.roll.lo[k0:k1]), np.abs(ts.roll.hi[k0:k1]))
            tmax = min(tmax, math.tan(float(np.max(r))))
        tilt[w] = tmax * _gyro_abs_dev(
            sig, a, b, lambda s, L=b - a: np.full(s.shape, 1.0 / L), c
        )
    return {"heading": head, "tilt": tilt, "earth": np.full(n, OMEGA)}


def gyro_z_ratios(ctx: Any, margins: Any) -> list[LevelRatio]:
    """Per aided level of gyro_z: median half-width against the median reference limit
    (the smaller of the terms' sum and the vehicle's rate bound)."""
    plan = ctx.plans["gyro_z"]
    out: list[LevelRatio] = []
    levels = [lp for lp in plan.levels if lp.n > 0]
    for lp, lv in zip(levels, margins.levels, strict=True):
        if lp.kind != "aided":
            continue
        out.append(_ratio(lp, lv, gyro_z_limits(ctx, lp), ctx.vehicle.max_rate))
    return out


# ---------------------------------------------------------------------------- accel_y
#
# ``f_y = v' + r u - p w + g sin(phi) cos(theta)`` (+ Earth rate). Per window, the
# half-widths of what the same input bounds leave of each term's kernel mean:
#
# * **ends** (lateral velocity): boxcar: at each end the lateral projection of the
#   velocity box, ``[S_m sin(d0 - h_psi) - R, S_m sin(d0 + h_psi) + R]`` (``d0`` the
#   course minus the heading centre, ``h_psi`` the heading half-width, ``R`` the GNSS
#   velocity radius), or the body-velocity sensor's ``v_m +- h``, intersected with the
#   lateral bound; positions only: ``sum_k h_k |c_k|_1`` through the lateral unit vectors
#   of the gap headings, at most ``2 v_l`` (each interval mean of v is within the lateral
#   bound); over tau;
# * **heading** (``mean(r u)`` through the heading boxes): summation by parts of
#   ``sum_k K_k u_k (psi_k+1 - psi_k)``: ``(|u_a| h_a + |u_b| h_b + sum_k h_k |K_k u_k -
#   K_k-1 u_k-1|/K)`` for a boxcar (``u_k`` the speed data's centres at the heading gaps),
#   ``h sum_k |K_k - K_k-1| u_bar`` for a trapezoid (``u_bar`` the mean chord speed over the
#   support: the chords' own noise would only add);
# * **speed** (``mean(r u)`` through the speed boxes): boxcar: ``rho x`` the kernel mean of
#   ``|y_r - c|`` (the gyro's record centred by the heading, noise counted once, as in
#   accel_x's transport term), ``rho`` the smallest speed radius of the window's epochs;
#   positions only: with ``r`` the gyro's centred gap means ``r_k`` and the heading
#   piecewise constant, ``sum_k K_k r_k (P_k+1 - P_k).e_k`` leaves ``sum_k h_k |w_k|_1``,
#   ``w_k`` the fix weights of ``K r e`` (summation by parts, as the ends);
# * **heave** ``W x`` gyro_x's window mean of ``|y_p - mean y_p|`` (0 when W = 0);
# * **gravity** :func:`accel_y_gravity`; **Earth rate** as accel_x's;
#
# the limit the smaller of their sum and ``max_accel + gravity``. Left out (they would
# only add): the tilt conversions, u's growth between velocity epochs, the heading's
# excursion inside a gap.


def _kernel(a1: float, b1: float, a2: float, b2: float) -> Any:
    """The window's kernel (boxcar on ``[a1, a2]`` or the trapezoid's ramps)."""
    tau = 0.5 * (a2 + b2) - 0.5 * (a1 + b1)
    l1, l2 = b1 - a1, b2 - a2

    def k(s: np.ndarray) -> np.ndarray:
        up_ = np.clip((s - a1) / l1, 0, 1) if l1 > 0 else (s >= a1).astype(float)
        dn = np.clip((b2 - s) / l2, 0, 1) if l2 > 0 else (s <= b2).astype(float)
        return np.minimum(up_, dn) / tau

    return k


def accel_y_gravity(veh: Any, ctx: Any = None, w: tuple[float, ...] = ()) -> float:
    """Gravity's share of accel_y: any tilt within the bound (or within the roll pieces
    of the channel's attitude variant over the window ``w = (a1, b1, a2, b2)``, times the
    smallest cos(pitch): on the low side) is consistent with the inputs."""
    ts = _tilt_of(ctx, "accel_y") if ctx is not None else None
    if ts is None or not w:
        return G_MAX * math.sin(veh.max_tilt)
    a, b = w[0], w[3]
    k0 = max(int(np.searchsorted(ts.bnd, a, side="right")) - 1, 0)
    k1 = max(int(np.searchsorted(ts.bnd, b, side="left")), k0 + 1)
    pm = float(np.max(np.maximum(np.abs(ts.pitch.lo[k0:k1]), np.abs(ts.pitch.hi[k0:k1]))))
    return _pieces_gravity(ts.bnd, ts.roll.lo, ts.roll.hi, a, b, _kernel(*w), math.cos(pm))


def _head_half(ag: Any, t: np.ndarray) -> np.ndarray:
    """The heading's half-width at ``t``: the smaller of its neighbouring epochs' (the
    gyro's noise inside a gap counted as zero: on the low side)."""
    ht, hh = ag.head_t, ag.head_h
    j = np.clip(np.searchsorted(ht, t), 0, ht.size - 1)
    i = np.clip(j - 1, 0, ht.size - 1)
    exact = np.abs(ht[j] - t) <= 1e-9
    return np.where(exact, hh[j], np.minimum(hh[i], hh[j]))


def _lateral_half(lo: np.ndarray, hi: np.ndarray, vl: float | None) -> np.ndarray:
    """Half-width of ``[lo, hi]`` intersected with the lateral bound."""
    if vl is not None:
        lo, hi = np.maximum(lo, -vl), np.minimum(hi, vl)
    return 0.5 * np.maximum(hi - lo, 0.0)


def _boxcar_speed_data(ag: Any, vl: float | None) -> tuple[np.ndarray, ...]:
    """Per velocity epoch: time, u centre, u radius, lateral half-width (intersected
    with the lateral bound)."""
    if ag.has_bvel:
        t, u, h = ag.bvel_t, ag.bvel_u, ag.bvel_h
        if ag.bvel_v is not None:
            lat = _lateral_half(ag.bvel_v - h, ag.bvel_v + h, vl)
        else:
            lat = np.full(t.size, vl if vl is not None else math.inf)
        return t, u, h, lat
    ok = ag.gvel_ok
    t = ag.gnss_t[ok]
    ve, vn, R = ag.gvel_e[ok], ag.gvel_n[ok], ag.gvel_hi[ok]
    sm = np.hypot(ve, vn)
    psi = _heading_centres(ag, t)
    hp = _head_half(ag, t)
    d0 = np.arctan2(vn, ve) - psi
    d0 = (d0 + math.pi) % (2 * math.pi) - math.pi
    lo = sm * np.sin(np.clip(d0 - hp, -0.5 * math.pi, 0.5 * math.pi)) - R
    hi = sm * np.sin(np.clip(d0 + hp, -0.5 * math.pi, 0.5 * math.pi)) + R
    return t, sm * np.cos(d0), R, _lateral_half(lo, hi, vl)


def _fix_weights_abs(h: np.ndarray, we: np.ndarray, wn: np.ndarray) -> float:
    """``sum_k h_k |c_k|_1`` for ``sum_k (P_k+1 - P_k).(we_k, wn_k)`` over fixes 0..n."""
    ce = np.zeros(we.size + 1)
    cn = np.zeros(we.size + 1)
    ce[1:] += we
    ce[:-1] -= we
    cn[1:] += wn
    cn[:-1] -= wn
    return float(np.sum(h * (np.abs(ce) + np.abs(cn))))


def _accel_y_trapezoid(ctx: Any, lp: Any, w: int) -> tuple[float, float, float, float]:
    """ends, heading, speed half-widths and the speed bound S of trapezoid window w."""
    ag, veh = ctx.aiding, ctx.vehicle
    sig = ctx.imu.sig["gyro_z"]
    t, h = ag.gnss_t, ag.gnss_h
    p, m, q, L1, L2, tau = _trapezoid_fixes(ag, lp, w)
    mid = 0.5 * (t[p:q] + t[p + 1 : q + 1])
    psi = _heading_centres(ag, mid)
    ce, sn = np.cos(psi), np.sin(psi)
    # lateral ends: (mean_I2 v - mean_I1 v)/tau, mean_I v = (1/L) sum (P_k+1 - P_k).n_k
    wl = np.where(mid < t[m], -1.0 / L1, 1.0 / L2) / tau
    ends = _fix_weights_abs(h[p : q + 1], -sn * wl, ce * wl)
    vl = veh.lateral_speed_bound_mps
    if vl is not None:
        ends = min(ends, 2 * vl / tau)
    # kernel weight of the gap means (the kernel of the acceleration)
    K = np.where(mid < t[m], (mid - t[p]) / (L1 * tau), (t[q] - mid) / (L2 * tau))
    g = np.diff(t[p : q + 1])
    chord = np.hypot(np.diff(ag.gnss_e[p : q + 1]), np.diff(ag.gnss_n[p : q + 1]))
    ubar = float(np.sum(chord) / (t[q] - t[p]))
    hk = _head_half(ag, t[p : q + 1])
    Kx = np.concatenate([[0.0], K, [0.0]])
    head = ubar * float(np.sum(hk * np.abs(np.diff(Kx))))
    # the gyro's gap means centred by the heading over the support
    c = _support_centre(sig, ag, float(t[p]), float(t[q]))
    lo, hi = sig.integral(t[p:q], t[p + 1 : q + 1])
    rk = 0.5 * (np.asarray(lo) + np.asarray(hi)) / g - c
    # sum_k K_k r_k g_k (P_k+1 - P_k).e_k / g_k: fix weights of K r e
    speed = _fix_weights_abs(h[p : q + 1], K * rk * ce, K * rk * sn)
    return ends, head, speed, float(np.max(chord / g))


def _accel_y_boxcar(
    ctx: Any, lp: Any, w: int, data: tuple[np.ndarray, ...]
) -> tuple[float, float, float, float]:
    """ends, heading, speed half-widths and the speed bound S of boxcar window w."""
    ag = ctx.aiding
    sig = ctx.imu.sig["gyro_z"]
    tv, uc, rho, lat = data
    a, b = float(lp.a1[w]), float(lp.b2[w])
    tau = b - a
    ia, ib = int(np.searchsorted(tv, a - 1e-9)), int(np.searchsorted(tv, b - 1e-9))
    ib = min(ib, tv.size - 1)
    ends = (lat[ia] + lat[ib]) / tau
    # heading: epochs strictly inside, the ends' own half-widths
    ht = ag.head_t
    k0, k1 = int(np.searchsorted(ht, a + 1e-9)), int(np.searchsorted(ht, b - 1e-9))
    knots = np.concatenate([[a], ht[k0:k1], [b]])
    hk = np.concatenate([_head_half(ag, np.array([a])), ag.head_h[k0:k1],
                         _head_half(ag, np.array([b]))])
    um = np.interp(0.5 * (knots[:-1] + knots[1:]), tv, uc)
    ux = np.concatenate([[0.0], um, [0.0]])
    head = float(np.sum(hk * np.abs(np.diff(ux)))) / tau
    c = _support_centre(sig, ag, a, b)
    dev = _gyro_abs_dev(sig, a, b, lambda s, tau=tau: np.full(s.shape, 1.0 / tau), c)
    speed = float(np.min(rho[ia : ib + 1])) * dev
    return ends, head, speed, float(np.max(np.abs(uc[ia : ib + 1])))


def accel_y_limits(ctx: Any, plan: Any, lp: Any) -> dict[str, np.ndarray]:
    """Per window of level ``lp`` of accel_y: the reference limit's terms (m/s^2)."""
    ag, veh = ctx.aiding, ctx.vehicle
    n = lp.a1.size
    out = {k: np.zeros(n) for k in ("ends", "heading", "speed", "heave", "earth")}
    data = None if plan.trapezoid else _boxcar_speed_data(ag, veh.lateral_speed_bound_mps)
    sx = ctx.imu.sig["gyro_x"]
    for w in range(n):
        if plan.trapezoid:
            e, hd, sp, S = _accel_y_trapezoid(ctx, lp, w)
        else:
            assert data is not None
            e, hd, sp, S = _accel_y_boxcar(ctx, lp, w, data)
        out["ends"][w], out["heading"][w], out["speed"][w] = e, hd, sp
        out["earth"][w] = 2 * OMEGA * S + S * S / R_E
        if veh.vertical_bound > 0:
            a, b = float(lp.a1[w]), float(lp.b2[w])
            lo, hi = sx.integral(np.array([a]), np.array([b]))
            cx = 0.5 * (float(lo[0]) + float(hi[0])) / (b - a)
            out["heave"][w] = veh.vertical_bound * _gyro_abs_dev(
                sx, a, b, lambda s, L=b - a: np.full(s.shape, 1.0 / L), cx
            )
    out["gravity"] = np.array([
        accel_y_gravity(veh, ctx, (float(lp.a1[w]), float(lp.b1[w]), float(lp.a2[w]),
                                   float(lp.b2[w]))) for w in range(n)])
    return out


def accel_y_ratios(ctx: Any, margins: Any, min_tau_s: float = 0.0) -> list[LevelRatio]:
    """:func:`_level_ratios` of accel_y."""
    return _level_ratios(ctx, margins, "accel_y", accel_y_limits, min_tau_s)


# ---------------------------------------------------------------- attitude floor
# docs/dynamic-method.md section 3b, "What no method can do": an independent lower
# bound of the roll/pitch half-width any sound method can reach from the stated budget.
# The adversary: an alternative trajectory whose tilt differs from the true one by a
# constant e in the level frame (|e| = D/g). In the body frame e turns with the heading,
# e_b(t) = R(psi(t) - psi_0) e, and the accelerometers read g e_b(t) more: a bias wander
# of at most |e| g = D per component, which the stated drift bound D (the mean wander over
# any window of at least its window) allows; the gyros differ by at most r_max |e|
# (the yaw rate carrying the offset), which the gyros' drift bound allows when it is at
# least that. Every aiding measurement is unchanged (positions, velocities, course).
# The wander changes between adjacent windows by at most D |delta psi| (the heading change
# between them): within the change test's band wherever that is at least so.
# On a straight span the turn-on bound b_TO adds (a body-fixed constant is then also a
# level-frame one): asin((b_TO + D) / g) there.


def tilt_floor(ctx: Any, ch: str = "accel_x", jerk_slack: float | None = None) -> dict[str, float]:
    """Lower bounds (rad) of the half-width of the angle the accelerometer ``ch`` sees of
    gravity (pitch for accel_x, roll for accel_y) that any sound method reaches from the
    run's budget (``ctx.noise``) and aiding, at every epoch:

    * ``wander``: ``asin(D / g_max)`` (the constant level-frame offset above), 0 where a
      drift bound is not stated or the gyros' drift bound is below ``r_max |e|``;
    * ``straight``: ``asin((b_TO + D) / g_max)`` on a span that does not turn;
    * ``velocity``: ``sqrt(R D_eff / g_max)``: an alternative trajectory that tilts by a
      triangle wave ``e(t)`` of amplitude A and period P and accelerates by ``g e(t)``
      horizontally reads the same specific force; its velocity differs by at most
      ``g A P / 4 <= R`` (R the smallest GNSS velocity radius of the fixes) and its gyro by
      ``4 A / P <= D_eff`` (the gyros' drift bound, and the jerk slack over g:
      ``jerk_slack`` the vehicle's jerk bound minus the truth's largest, by default the
      whole bound), so ``A = sqrt(R D_eff / g)`` at the best P (positions differ by at most
      ``R P / 8``, below any fix's box here);
    * ``turning``: ``wander + velocity`` (the two adversaries add, to first order)."""
    cn = ctx.noise[ch]
    gy = [ctx.noise[g] for g in ("gyro_x", "gyro_y")]
    D = cn.drift_bound
    dg = [g.drift_bound for g in gy]
    out = {"wander": 0.0, "straight": 0.0, "velocity": 0.0, "turning": 0.0}
    if D is None or any(x is None for x in dg):
        return out
    dmin = min(float(x) for x in dg if x is not None)
    e = math.asin(min(1.0, D / G_MAX))
    if dmin >= ctx.vehicle.max_rate * e:
        b = cn.turn_on_bound(0.0) if cn.turn_on_kind == "bound" else 0.0
        out["wander"] = e
        out["straight"] = math.asin(min(1.0, (b + D) / G_MAX))
    ag = ctx.aiding
    if ag.has_gvel:
        R = float(np.min(ag.gvel_hi[ag.gvel_ok]))
        js = ctx.vehicle.max_jerk if jerk_slack is None else max(0.0, jerk_slack)
        d_eff = min(dmin, js / G_MAX)
        out["velocity"] = math.sqrt(R * d_eff / G_MAX)
    out["turning"] = out["wander"] + out["velocity"]
    return out
