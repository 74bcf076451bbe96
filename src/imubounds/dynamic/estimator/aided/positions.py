"""Positions only (docs/dynamic-method.md, section 3, **positions only**): the mean body
velocities over the fix intervals I1, I2 of a trapezoid window, from the position boxes,
projected with the heading hull over each interval (``+- S_max eps``), then from the
horizontal to the body frame with the tilt intervals."""

from __future__ import annotations

import math

import numpy as np

from imubounds.dynamic.estimator.aided.base import pm, up
from imubounds.dynamic.estimator.aided.common import WindowContext
from imubounds.dynamic.estimator.aided.heading import heading_mean
from imubounds.dynamic.estimator.aided.velocity import speed_max
from imubounds.dynamic.estimator.window_plan import LevelPlan
from imubounds.interval import IntervalArray as IA
from imubounds.interval import cos, sin


def position_means(w: WindowContext, lp: LevelPlan, tau: np.ndarray) -> dict[str, IA]:
    """Mean body velocities ``u1, v1`` over I1 and ``u2, v2`` over I2 from the GNSS
    positions (trapezoid kernel)."""
    ag, veh = w.ag, w.veh
    out: dict[str, IA] = {}
    t = ag.gnss_t
    i0 = np.searchsorted(t, lp.a1)
    i1 = np.searchsorted(t, lp.b1)
    i2 = np.searchsorted(t, lp.b2)
    E = IA(ag.gnss_e - ag.gnss_h, ag.gnss_e + ag.gnss_h)
    N = IA(ag.gnss_n - ag.gnss_h, ag.gnss_n + ag.gnss_h)
    for key, (p, q) in (("1", (i0, i1)), ("2", (i1, i2))):
        a, b = t[p], t[q]
        dT = IA(b - a)
        ve = (E[q] - E[p]) / dT
        vn = (N[q] - N[p]) / dT
        psi = heading_mean(w, a, b)
        fin = np.isfinite(psi.lo) & np.isfinite(psi.hi)
        mid = np.where(fin, psi.mid(), 0.0)
        eps = np.where(fin, up(psi.radius()), math.pi)
        smax = speed_max(w, a, b)
        cm, sm = cos(IA(mid)), sin(IA(mid))
        uh = ve * cm + vn * sm + pm(smax * eps)
        vh = vn * cm - ve * sm + pm(smax * eps)
        sec_p = w.tilt.hull("sec_p_minus_1", a, b).hi
        sec_r = w.tilt.hull("sec_r_minus_1", a, b).hi
        trp = w.tilt.hull("abs_tanr_tanp", a, b).hi
        vl = veh.lateral_bound
        vmax = np.minimum(smax, vl) if vl is not None else smax
        u = uh + pm(smax * sec_p + vmax * trp)
        v = vh + pm(smax * sec_r)
        if veh.kind != "ground":
            wv = veh.vertical_bound
            u = u + pm(wv * w.tilt.hull("abs_tanp", a, b).hi)
            v = v + pm(wv * w.tilt.hull("abs_tanr", a, b).hi)
        out["u" + key] = u
        out["v" + key] = v
    return out
