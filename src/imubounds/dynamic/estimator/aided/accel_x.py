"""accel_x (docs/dynamic-method.md, section 3, **accel_x**): ``(u(b) - u(a))/tau -
mean(r v) + g mean(sin theta)`` plus the Earth rate, the transport term bounded by
``max_W|v| mean_W|r|`` (never computed from the gyro; ``mean_W|r|`` the registry's
``mean_abs_r`` forms, :mod:`.form_tables`), and ``q w`` by ``max|w| mean|q|``
(|w| within the vertical bound: heave for a ground vehicle)."""

from __future__ import annotations

import numpy as np

from imubounds.dynamic.estimator.aided.base import pm
from imubounds.dynamic.estimator.aided.common import WindowContext
from imubounds.dynamic.estimator.aided.form_tables import mean_abs_r
from imubounds.dynamic.estimator.aided.forms import allot
from imubounds.dynamic.estimator.aided.horizontal import horizontal_terms
from imubounds.dynamic.estimator.window_plan import ChannelPlan, LevelPlan
from imubounds.interval import IntervalArray as IA


def accel_x(w: WindowContext, plan: ChannelPlan, lp: LevelPlan, tau: np.ndarray) -> IA:
    """``[x_W]`` of accel_x."""
    h = horizontal_terms(w, plan, lp, tau)
    ends, rng = h.ends, h.rng
    p_r = allot(w.p_window, "accel_x.transport", [])["mean_abs_r"]
    r_mag = mean_abs_r(w, lp, tau, p_r, term="accel_x.mean_abs_r")
    transport = pm(rng["v_max"] * r_mag)
    grav = w.tilt.kmean("g_sinp", lp, tau)
    x = (ends["u2"] - ends["u1"]) / IA(tau) - transport + grav + h.earth
    if w.veh.vertical_bound > 0:  # q w, |w| <= the vertical (heave) bound
        x = x + pm(rng["w_max"] * w.kernel_mag("gyro_y", lp, tau))
    return x
