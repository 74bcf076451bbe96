"""Physical constants and outward rounding helpers of the true-signal constraints."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from imubounds.interval import IntervalArray as IA
from imubounds.interval.rounding import up

G_LO, G_HI = 9.76, 9.84  #: local gravity magnitude range, m/s^2 (latitude, height)
R_EARTH = 6.371e6  #: Earth radius, m
EARTH_RATE = 7.2921159e-5  #: Earth rotation rate, rad/s
TWO_PI = 2.0 * math.pi
#: a bound of the unit roundoff (2^-52 = 2.22e-16, rounded up) in the rounding guards
EPS = 2.3e-16


def earth_rates(veh: Any) -> float:
    """``Omega + S_max/R_E`` (rad/s, rounded up): the rate of the level frame in inertial
    space, which the gyros measure besides the body's rate relative to it."""
    return float(up(np.asarray(EARTH_RATE + veh.max_speed / R_EARTH)))


def pm(r: Any) -> IA:
    """The interval ``[-r, r]`` (r >= 0, rounded up)."""
    r = up(np.asarray(r, dtype=float))
    return IA(-r, r)
