"""Error models of the aiding sensors (METHOD.md section 2): GPS, compass, geodesy."""

from imubounds.dynamic.aiding.compass import (
    CompassDeviation,
    course_over_ground,
    fit_deviation,
    heading_from_magnetometer,
    heading_intervals,
)
from imubounds.dynamic.aiding.gps import (
    GpsBoxSpec,
    cep_to_drms,
    gps_box_halfwidths,
    mean_error,
    parse_gps_box,
    radius_at_probability,
)
from imubounds.frames import compass_to_model, model_to_compass, wrap_pi
from imubounds.geodesy import geodetic_to_enu, haversine_enu

__all__ = [
    "CompassDeviation",
    "GpsBoxSpec",
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
