"""The aiding sensors of the dynamic analysis (METHOD.md section 2; docs/dynamic-method.md,
section 3): each a module with the same small surface, its boxes or bounds and its checks.

* :mod:`.gnss` -- the GNSS error model (Rayleigh radius), position and velocity boxes,
  the outlier screen;
* :mod:`.heading` -- compass, magnetometer, AHRS yaw and the heading from the GNSS course:
  deviation, calibration, the check against the GNSS course, heading intervals;
* :mod:`.body_velocity` -- DVL and wheel/CAN speed intervals;
* :mod:`.attitude` -- an attitude (AHRS) stream's roll/pitch bound;
* :mod:`.clocks` -- the clock offsets between the streams and the IMU.

:func:`build_aiding` puts them together into the estimator's
:class:`~imubounds.dynamic.estimator.inputs.Aiding`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from imubounds.dynamic.estimator.inputs import Aiding
from imubounds.dynamic.sensors.attitude import attitude_bounds
from imubounds.dynamic.sensors.body_velocity import body_velocity_boxes
from imubounds.dynamic.sensors.gnss import (
    GpsBoxSpec,
    cep_to_drms,
    gnss_position_boxes,
    gnss_velocity_boxes,
    gps_box_halfwidths,
    mean_error,
    parse_gps_box,
    radius_at_probability,
)
from imubounds.dynamic.sensors.heading import (
    CompassDeviation,
    course_heading,
    fit_deviation,
    heading_boxes,
    heading_from_magnetometer,
    heading_intervals,
)
from imubounds.frames import compass_to_model, model_to_compass, wrap_pi
from imubounds.geodesy import course_over_ground, geodetic_to_enu, haversine_enu

if TYPE_CHECKING:
    from imubounds.dynamic.estimator.budget import AlphaPlan
    from imubounds.dynamic.estimator.inputs import Vehicle
    from imubounds.dynamic.estimator.options import FullOptions

__all__ = [
    "CompassDeviation",
    "GpsBoxSpec",
    "build_aiding",
    "cep_to_drms",
    "compass_to_model",
    "course_over_ground",
    "fit_deviation",
    "geodetic_to_enu",
    "gps_box_halfwidths",
    "haversine_enu",
    "heading_from_magnetometer",
    "heading_intervals",
    "mean_error",
    "model_to_compass",
    "parse_gps_box",
    "radius_at_probability",
    "wrap_pi",
]


def build_aiding(
    drive: Any,
    t0: float,
    vehicle: Vehicle,
    alpha: AlphaPlan,
    opts: FullOptions,
    heading: Any,
) -> Aiding:
    """Aiding intervals (IMU-free) with their budget rows, one builder per sensor.
    ``alpha`` must already count the GNSS fixes, GNSS velocity components and heading
    epochs."""
    st = drive.settings
    ag = Aiding(origin=None)
    g = drive.gnss
    if g is not None and opts.use_gnss:
        ok = g.usable()
        if np.any(ok):
            ok, lev = gnss_position_boxes(ag, g, ok, st, vehicle, alpha, opts, t0)
            gnss_velocity_boxes(ag, g, ok, lev, st, vehicle, alpha, opts)
    if heading is not None and heading.t.size:
        heading_boxes(ag, heading, alpha, t0)
    if heading is not None:
        ag.notes += heading.notes
    if not ag.has_heading and ag.has_gvel:
        course_heading(ag, vehicle, opts)
    body_velocity_boxes(ag, drive, st, opts, t0)
    attitude_bounds(ag, drive, st, vehicle, opts, t0)
    return ag
