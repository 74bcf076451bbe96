"""Outward rounding helpers of the true-signal constraints (the physical constants are in
:mod:`imubounds.constants`)."""

from __future__ import annotations

from typing import Any

import numpy as np

from imubounds.constants import EARTH_RATE, R_EARTH
from imubounds.interval import IntervalArray as IA
from imubounds.interval.rounding import up


def pm(r: Any) -> IA:
    """The interval ``[-r, r]`` (r >= 0, rounded up)."""
    r = up(np.asarray(r, dtype=float))
    return IA(-r, r)


def earth_rates(veh: Any) -> float:
    """``Omega + S_max/R_E`` (rad/s, rounded up): the rate of the level frame in inertial
    space, which the gyros measure besides the body's rate relative to it."""
    return float(up(np.asarray(EARTH_RATE + veh.max_speed / R_EARTH)))
