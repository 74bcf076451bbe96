"""What accel_x and accel_y share (docs/dynamic-method.md, section 3, **accel_x**,
**accel_y**, **positions only**): the body velocity at the window ends (velocity epochs)
or its means over the fix intervals (positions only), its range over the window, and the
Earth's Coriolis and transport rate at the window's speed bound."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from imubounds.constants import EARTH_RATE, R_EARTH
from imubounds.dynamic.estimator.aided.base import pm
from imubounds.dynamic.estimator.aided.common import WindowContext
from imubounds.dynamic.estimator.aided.positions import position_means
from imubounds.dynamic.estimator.aided.velocity import body_velocity, ranges
from imubounds.dynamic.estimator.window_plan import ChannelPlan, LevelPlan
from imubounds.interval import IntervalArray as IA


@dataclass
class HorizontalTerms:
    """Per window: the velocity ends ``u1, u2, v1, v2`` (m/s), the velocity ranges over
    the support (:func:`~imubounds.dynamic.estimator.aided.velocity.ranges`) and the
    Earth-rate term (m/s^2)."""

    ends: dict[str, IA]
    rng: dict[str, np.ndarray]
    earth: IA


def horizontal_terms(
    w: WindowContext, plan: ChannelPlan, lp: LevelPlan, tau: np.ndarray
) -> HorizontalTerms:
    """The ends of a boxcar (velocity epochs) or trapezoid (position means) window."""
    veh = w.veh
    bv = body_velocity(w)
    rng = ranges(w, lp, bv)
    smax = np.maximum(np.abs(rng["u_lo"]), np.abs(rng["u_hi"])) + rng["v_max"]
    smax = np.minimum(smax, veh.max_speed)
    # Coriolis and transport rate of the Earth frame, at the window's speed bound
    earth = pm(2 * EARTH_RATE * smax + smax * smax / R_EARTH)
    if plan.trapezoid:
        ends = position_means(w, lp, tau)
    else:
        ends = {
            "u1": bv["u"][lp.i],
            "u2": bv["u"][lp.j],
            "v1": bv["v"][lp.i],
            "v2": bv["v"][lp.j],
        }
    return HorizontalTerms(ends, rng, earth)
