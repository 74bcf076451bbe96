"""Positions only (docs/dynamic-method.md, section 3, **positions only**): the mean body
velocities over the fix intervals I1, I2 of a trapezoid window, from the position boxes,
projected on the mid-heading ``psi0`` of the heading hull over each interval (radius
``eps``): ``mean(u_h) = mean(V).e(psi0) +- (S_max (1 - cos eps) + v_l sin eps)`` (second
order in the heading width through the speed, ``v_l`` the lateral bound),
``mean(v_h) = mean(V).e_perp(psi0) +- (S_max sin eps + v_l (1 - cos eps))``; then from
the horizontal to the body frame with the tilt intervals."""

from __future__ import annotations

import math

import numpy as np

from imubounds.constants import ROUND_REL
from imubounds.dynamic.estimator.aided.base import pm, up
from imubounds.dynamic.estimator.aided.common import WindowContext
from imubounds.dynamic.estimator.aided.heading import (
    heading_at,
    heading_mean,
    psi_dot_abs,
    psi_rate_bound,
)
from imubounds.dynamic.estimator.aided.velocity import speed_max
from imubounds.dynamic.estimator.inputs import lateral_h_bound
from imubounds.dynamic.estimator.window_plan import LevelPlan
from imubounds.interval import IntervalArray as IA


def _second_order(eps: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``1 - cos eps`` and ``sin eps`` (eps >= 0), rounded up."""
    e2 = up(1.0 - np.cos(np.minimum(eps, math.pi)) + 1e-15)
    e1 = up(np.sin(np.minimum(eps, 0.5 * math.pi)) + 1e-15)
    return e2, e1


def _pos_part(v0: np.ndarray, v1: np.ndarray, ell: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``int max(0, x)`` and ``int max(0, x)^2`` of x linear from ``v0`` to ``v1`` over a
    length ``ell``."""
    hi, lo = np.maximum(v0, v1), np.minimum(v0, v1)
    both = lo >= 0
    frac = np.where(both, 1.0, np.where(hi > 0, hi / np.maximum(hi - lo, 1e-300), 0.0))
    lp = ell * frac  # length where x > 0
    lo_p = np.where(both, lo, 0.0)
    hi_p = np.maximum(hi, 0.0)
    i1 = lp * (lo_p + hi_p) / 2
    i2 = lp * (lo_p * lo_p + lo_p * hi_p + hi_p * hi_p) / 3
    return i1, i2


def _envelope_integrals(
    w: WindowContext, a: np.ndarray, b: np.ndarray, psi0: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Bounds of ``int_a^b |psi - psi0|`` and ``int_a^b (psi - psi0)^2`` over each fix gap
    from the heading at its ends, the bound I of ``int_a^b |psi'|`` (``psi_dot_abs`` x the
    gap: the MEAN |psi'| over the gap, not the rate at each time) and the rate bound
    ``int_s^t |psi'| <= Rm (t - s) + Cm`` for every ``[s, t]`` inside the gap
    (``psi_rate_bound``: the gyros' largest samples, their per-sample error bound, the
    change inside a sample, the Earth's rates and the tilt coupling; at most the
    vehicle's cap), which also gives ``I <= Rm (b - a) + Cm``: with ``x = int_a^t
    |psi'|``, ``psi(t) <= psi_hi(a) + x``, ``x <= Rm (t - a) + Cm`` and ``psi(t) <=
    psi_hi(b) + I - x``, ``I - x <= Rm (b - t) + Cm``, so ``psi`` lies under ``U =
    min(psi_hi(a) + Cm + Rm (t - a), psi_hi(b) + Cm + Rm (b - t), (psi_hi(a) + psi_hi(b) +
    I)/2)`` (concave; the two lines meet above the third term since I <= Rm (b - a) +
    2 Cm, so U is linear between its breakpoints) and over the like ``L``; ``|psi - psi0|
    <= max((U - psi0)+, (psi0 - L)+)`` and ``max(x, y)^k <= x^k + y^k``."""
    pa, pb = heading_at(w, a), heading_at(w, b)
    ok = np.isfinite(pa.lo) & np.isfinite(pa.hi) & np.isfinite(pb.lo) & np.isfinite(pb.hi)
    ok &= np.isfinite(psi0)
    if not np.any(ok):
        return np.full(a.shape, np.inf), np.full(a.shape, np.inf)
    pa = IA(np.where(ok, pa.lo, 0.0), np.where(ok, pa.hi, 0.0))
    pb = IA(np.where(ok, pb.lo, 0.0), np.where(ok, pb.hi, 0.0))
    psi0 = np.where(ok, psi0, 0.0)
    g = b - a
    rm, cm = psi_rate_bound(w, a, b)
    rm = np.maximum(rm, 1e-12)
    integral = np.minimum(up(psi_dot_abs(w, a, b) * g), up(up(rm * g) + cm))
    out1 = np.zeros(a.shape)
    out2 = np.zeros(a.shape)
    for sgn, ya, yb in ((1.0, pa.hi, pb.hi), (-1.0, -pa.lo, -pb.lo)):
        # sgn = 1: U - psi0; sgn = -1: psi0 - L (mirrored: -L is a min of lines too)
        cap = up((ya + yb + integral) / 2)
        la, lb = up(ya + cm), up(yb + cm)  # the lines' values at a and b
        t1 = np.clip(a + (cap - la) / rm, a, b)
        t2 = np.maximum(np.clip(b - (cap - lb) / rm, a, b), t1)

        def env(t: np.ndarray, la: np.ndarray = la, lb: np.ndarray = lb,
                cap: np.ndarray = cap) -> np.ndarray:
            return np.minimum(np.minimum(la + rm * (t - a), lb + rm * (b - t)), cap)

        v = [env(x) - sgn * psi0 for x in (a, t1, t2, b)]
        for v0, v1, ell in ((v[0], v[1], t1 - a), (v[1], v[2], t2 - t1), (v[2], v[3], b - t2)):
            i1, i2 = _pos_part(v0, v1, ell)
            out1 = out1 + i1
            out2 = out2 + i2
    fin = np.isfinite(out1) & np.isfinite(out2) & ok
    out1 = np.where(fin, up(out1 * (1 + 1e-9) + 1e-15), np.inf)
    out2 = np.where(fin, up(out2 * (1 + 1e-9) + 1e-15), np.inf)
    return out1, out2


def _gap_tables(w: WindowContext) -> dict[str, np.ndarray]:
    """Per gap k between fixes k and k + 1: the chord projected on the gap's mid-heading
    ``e_k`` (u and v), the second-order remainder times the gap, and, per fix, the
    weight of its position error in a sum of projected chords (summation by parts:
    ``sum (P_k+1 - P_k).e_k = P_n.e_n-1 - P_0.e_0 - sum P_k.(e_k - e_k-1)``); prefix
    sums of each (computed once)."""
    if "pos_tables" in w.cache:
        return w.cache["pos_tables"]
    ag, veh = w.ag, w.veh
    t = ag.gnss_t
    a, b = t[:-1], t[1:]
    g = b - a
    psi = heading_mean(w, a, b)
    fin = np.isfinite(psi.lo) & np.isfinite(psi.hi)
    psi0 = np.where(fin, psi.mid(), 0.0)
    eps = np.where(fin, up(psi.radius()) + 1e-12, math.pi)
    c, sn = np.cos(psi0), np.sin(psi0)
    smax = speed_max(w, a, b)
    vl_h = lateral_h_bound(veh)
    vlat = smax if vl_h is None else np.minimum(smax, vl_h)
    e2, e1 = _second_order(eps)
    # per gap: int (1 - cos d) <= int d^2/2 and int |sin d| <= int |d| (d = psi - psi0),
    # from the heading's reachable envelope, where smaller than the hull's gap x (1 - cos
    # eps), gap x sin eps
    i1, i2 = _envelope_integrals(w, a, b, psi0)
    i2 = np.where(fin, up(0.5 * i2), np.inf)
    i1 = np.where(fin, i1, np.inf)
    e2g = np.minimum(up(g * e2), i2)
    e1g = np.minimum(up(g * e1), i1)
    dE, dN = np.diff(ag.gnss_e), np.diff(ag.gnss_n)
    du = dE * c + dN * sn
    dv = dN * c - dE * sn
    # |e_k - e_k-1|_1 (the same for e_perp), times the interior fix's box half-width
    de = np.abs(np.diff(c)) + np.abs(np.diff(sn))
    h = ag.gnss_h

    def cum(x: np.ndarray) -> np.ndarray:
        return np.concatenate([[0.0], np.cumsum(x)])

    tab = {
        "du": cum(du),
        "dv": cum(dv),
        "abs": cum(np.abs(dE) + np.abs(dN)),
        "ru": cum(up(smax * e2g + vlat * e1g)),
        "rv": cum(up(smax * e1g + vlat * e2g)),
        "perr": cum(h[1:-1] * de) if t.size > 2 else np.zeros(1),
        "end": np.abs(c) + np.abs(sn),
        "smax": smax,
        "ce": c,
        "sn": sn,
    }
    w.cache["pos_tables"] = tab
    return tab


def _mean_over_parts(
    w: WindowContext, p: np.ndarray, q: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`_mean_over`'s parts (before the division by ``L = t_q - t_p``): the sums of
    the projected chords ``nu``, ``nv``, the position errors' share ``perr`` (by parts),
    and the rest of the radii of u_h and v_h (the second-order remainders and rounding)."""
    ag = w.ag
    tab = _gap_tables(w)
    t, h = ag.gnss_t, ag.gnss_h
    nu = tab["du"][q] - tab["du"][p]
    nv = tab["dv"][q] - tab["dv"][p]
    inner = tab["perr"][np.maximum(q - 1, p)] - tab["perr"][p]  # interior fixes p+1..q-1
    perr = h[p] * tab["end"][p] + h[q] * tab["end"][q - 1] + np.maximum(inner, 0.0)
    n = t.size
    guard = (n + 4) * 2.3e-16 * (tab["abs"][q] + tab["abs"][p] + 1.0) * 2.0
    ru = tab["ru"][q] - tab["ru"][p]
    rv = tab["rv"][q] - tab["rv"][p]
    gr = (n + 4) * 2.3e-16 * (tab["ru"][q] + tab["rv"][q] + tab["perr"][-1] + 1.0)
    return nu, nv, perr, up(ru + guard + gr), up(rv + guard + gr)


def _mean_over(w: WindowContext, p: np.ndarray, q: np.ndarray) -> tuple[IA, IA]:
    """Mean horizontal heading-frame velocities (u_h, v_h) over [t_p, t_q] (fix indices,
    q > p): the projected chords of every gap inside, their position errors by summation
    by parts, their second-order remainders, and a bound of the prefix sums' rounding."""
    t = w.ag.gnss_t
    nu, nv, perr, rest_u, rest_v = _mean_over_parts(w, p, q)
    wu = up((perr + rest_u) * (1 + ROUND_REL))
    wv = up((perr + rest_v) * (1 + ROUND_REL))
    dT = IA(t[q] - t[p])
    return (IA(nu) + pm(wu)) / dT, (IA(nv) + pm(wv)) / dT


def gap_units(w: WindowContext) -> tuple[np.ndarray, np.ndarray]:
    """Per fix gap, the unit vector (east, north) of its mid-heading ``e_k`` (the
    chords' projection of :func:`_mean_over`)."""
    tab = _gap_tables(w)
    return tab["ce"], tab["sn"]


def _body_u(w: WindowContext, uh: IA, a: np.ndarray, b: np.ndarray, smax: np.ndarray) -> IA:
    """The mean body forward velocity over [a, b] from that of ``u_h`` (the tilt
    conversion: ``+- (S_max (sec(pitch) - 1) + v_max |tan(roll) tan(pitch)| + W |tan(pitch)|)``)."""
    veh = w.veh
    sec_p = w.tilt.hull("sec_p_minus_1", a, b).hi
    trp = w.tilt.hull("abs_tanr_tanp", a, b).hi
    vl = veh.lateral_speed_bound_mps
    vmax = np.minimum(smax, vl) if vl is not None else smax
    u = uh + pm(smax * sec_p + vmax * trp)
    if veh.vertical_bound > 0:
        u = u + pm(veh.vertical_bound * w.tilt.hull("abs_tanp", a, b).hi)
    return u


def body_u_mean_parts(
    w: WindowContext, p: np.ndarray, q: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The mean body forward velocity over the fix interval ``[t_p, t_q]`` (fix indices,
    ``q > p``; as in :func:`position_means`) apart from its position errors: ``mean u =
    nu/L + sum_k (eps_k+1 - eps_k).e_k / L +- rest`` (eps the fixes' errors, e_k the gap
    units of :func:`gap_units`); returns ``nu/L`` and ``rest`` (the projection's
    second-order remainders, the tilt conversion and rounding)."""
    t = w.ag.gnss_t
    a, b = t[p], t[q]
    L = b - a
    nu, _, _, rest_u, _ = _mean_over_parts(w, p, q)
    c = nu / L
    u = _body_u(w, IA(c) + pm(up(up(rest_u * (1 + ROUND_REL)) / L * (1 + ROUND_REL))), a, b,
                speed_max(w, a, b))
    rest = up(np.maximum(u.hi - c, c - u.lo) * (1 + ROUND_REL) + 1e-300)
    return c, rest


def position_means(w: WindowContext, lp: LevelPlan, tau: np.ndarray) -> dict[str, IA]:
    """Mean body velocities ``u1, v1`` over I1 and ``u2, v2`` over I2 from the GNSS
    positions (trapezoid kernel)."""
    ag, veh = w.ag, w.veh
    out: dict[str, IA] = {}
    t = ag.gnss_t
    i0 = np.searchsorted(t, lp.a1)
    i1 = np.searchsorted(t, lp.b1)
    i2 = np.searchsorted(t, lp.b2)
    for key, (p, q) in (("1", (i0, i1)), ("2", (i1, i2))):
        a, b = t[p], t[q]
        uh, vh = _mean_over(w, p, q)
        smax = speed_max(w, a, b)
        sec_r = w.tilt.hull("sec_r_minus_1", a, b).hi
        u = _body_u(w, uh, a, b, smax)
        v = vh + pm(smax * sec_r)
        if veh.vertical_bound > 0:
            v = v + pm(veh.vertical_bound * w.tilt.hull("abs_tanr", a, b).hi)
        vl = veh.lateral_speed_bound_mps
        if vl is not None:  # |v| <= the lateral bound at every time, so its means too
            vc = v & pm(np.full(v.lo.shape, vl))
            keep = vc.is_empty()  # inconsistent with the bound: left as the fixes give it
            v = IA(np.where(keep, v.lo, vc.lo), np.where(keep, v.hi, vc.hi))
        out["u" + key] = u
        out["v" + key] = v
    return out
