"""Windows shorter than the aiding period (docs/dynamic-method.md, section 3, **windows
shorter than the aiding period**): the vehicle bounds only (``kind`` "vehicle"): the
angular-rate bound for a gyro; the horizontal acceleration bound (centripetal part
included) plus gravity through the tilt for an accelerometer."""

from __future__ import annotations

import numpy as np

from imubounds.dynamic.estimator.aided.base import pm
from imubounds.dynamic.estimator.aided.common import WindowContext
from imubounds.dynamic.estimator.window_plan import LevelPlan
from imubounds.interval import IntervalArray as IA

#: the tilt function giving gravity's part of each accelerometer
GRAVITY_OF = {"accel_x": "g_sinp", "accel_y": "g_sinr_cosp", "accel_z": "g_cosr_cosp"}


def vehicle_only(w: WindowContext, ch: str, lp: LevelPlan, tau: np.ndarray) -> IA:
    """``[x_W]`` from the vehicle's bounds alone."""
    veh = w.veh
    n = tau.size
    if ch.startswith("gyro"):
        return pm(np.full(n, veh.max_rate))
    # |horizontal acceleration in the heading frame| <= max_accel (centripetal included)
    acc = pm(np.full(n, veh.max_accel))
    return acc + w.tilt.kmean(GRAVITY_OF[ch], lp, tau)
