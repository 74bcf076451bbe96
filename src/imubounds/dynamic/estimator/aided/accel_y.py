"""accel_y (docs/dynamic-method.md, section 3, **accel_y**): ``(v(b) - v(a))/tau +
mean(r u) + g mean(sin phi cos theta)`` plus the Earth rate, with ``mean(r u) =
u0 mean(r) + mean((u - u0) r)``: mean(r) from the heading difference, the second term by
``max|u - u0| mean|r|``."""

from __future__ import annotations

import numpy as np

from imubounds.dynamic.estimator.aided.base import pm, up
from imubounds.dynamic.estimator.aided.common import WindowContext
from imubounds.dynamic.estimator.aided.heading import heading_at, heading_mean, r_from_psidot
from imubounds.dynamic.estimator.aided.horizontal import horizontal_terms
from imubounds.dynamic.estimator.aided.transport import r_abs
from imubounds.dynamic.estimator.window_plan import ChannelPlan, LevelPlan
from imubounds.interval import IntervalArray as IA


def mean_r_from_heading(
    w: WindowContext, lp: LevelPlan, tau: np.ndarray, trapezoid: bool
) -> IA:
    """Kernel mean of the yaw rate r from the heading (for accel_y's transport term)."""
    if trapezoid:
        p1 = heading_mean(w, lp.a1, lp.b1)
        p2 = heading_mean(w, lp.a2, lp.b2)
    else:
        p1 = heading_at(w, lp.a1)
        p2 = heading_at(w, lp.a2)
    dpsi = (p2 - p1) / IA(tau)
    return r_from_psidot(w, dpsi, lp, tau, own_q=True)


def accel_y(w: WindowContext, plan: ChannelPlan, lp: LevelPlan, tau: np.ndarray) -> IA:
    """``[x_W]`` of accel_y."""
    h = horizontal_terms(w, plan, lp, tau)
    ends, rng = h.ends, h.rng
    r_mag = r_abs(w, lp, tau)
    mean_r = mean_r_from_heading(w, lp, tau, plan.trapezoid)
    u0 = 0.5 * (rng["u_lo"] + rng["u_hi"])
    du = up(0.5 * (rng["u_hi"] - rng["u_lo"]))
    ru = IA(u0) * mean_r + pm(du * r_mag)
    grav = w.tilt.kmean("g_sinr_cosp", lp, tau)
    x = (ends["v2"] - ends["v1"]) / IA(tau) + ru + grav + h.earth
    if w.veh.vertical_bound > 0:  # p w, |w| <= the vertical (heave) bound
        x = x + pm(rng["w_max"] * w.kernel_mag("gyro_x", lp, tau))
    return x
