"""accel_y (docs/dynamic-method.md, section 3, **accel_y**, (3.13)): ``(v(b) - v(a))/tau +
mean(r u) + g mean(sin phi cos theta)`` plus the Earth rate; the transport term ``mean(r
u)`` is bounded by the forms of the registry's table
:data:`~imubounds.dynamic.estimator.aided.form_tables.TRANSPORT_Y`, intersected:
``u0 mean(r) +- du mean|r|`` (mean(r) from the heading difference, ``du`` the half-range
of u), with velocity epochs also per heading gap (:mod:`.transport_gaps`), positions
only also over blocks of fix gaps (:mod:`.transport_fixes`) and from the gyro's shape
(:mod:`.transport_gyro`)."""

from __future__ import annotations

import numpy as np

from imubounds.dynamic.estimator.aided.base import pm
from imubounds.dynamic.estimator.aided.common import WindowContext
from imubounds.dynamic.estimator.aided.form_tables import transport_inputs, transport_y
from imubounds.dynamic.estimator.aided.horizontal import horizontal_terms
from imubounds.dynamic.estimator.aided.velocity import body_velocity
from imubounds.dynamic.estimator.window_plan import ChannelPlan, LevelPlan
from imubounds.interval import IntervalArray as IA


def accel_y(w: WindowContext, plan: ChannelPlan, lp: LevelPlan, tau: np.ndarray) -> IA:
    """``[x_W]`` of accel_y."""
    h = horizontal_terms(w, plan, lp, tau)
    ends, rng = h.ends, h.rng
    ru = transport_y(transport_inputs(w, plan, lp, tau, rng, body_velocity(w)))
    grav = w.tilt.kmean("g_sinr_cosp", lp, tau)
    x = (ends["v2"] - ends["v1"]) / IA(tau) + ru + grav + h.earth
    if w.veh.vertical_bound > 0:  # p w, |w| <= the vertical (heave) bound
        x = x + pm(rng["w_max"] * w.kernel_mag("gyro_x", lp, tau))
    return x
