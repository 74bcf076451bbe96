"""Geodetic coordinates <-> a local East-North-Up frame (METHOD.md 2.3).

The one module that calls pymap3d; io, dynamic and the simulator convert through it.

* ``wgs84`` (default): exact WGS-84 geodetic -> ENU with pymap3d.
* ``haversine`` (the paper): great-circle distance S and initial bearing
  alpha (clockwise from north) from the origin on a sphere of radius R;
  ``east = S sin(alpha)``, ``north = S cos(alpha)``. The sphere ignores the
  ellipsoid's two radii of curvature, so the scale differs from WGS-84 by up
  to about 0.5 % depending on latitude and direction.
"""

from __future__ import annotations

import math

import numpy as np
import pymap3d

from imubounds.constants import R_EARTH
from imubounds.errors import OptionError
from imubounds.frames import TWO_PI

GEODESY_METHODS = ("wgs84", "haversine")


def haversine_enu(
    lat_deg: np.ndarray,
    lon_deg: np.ndarray,
    lat0_deg: float,
    lon0_deg: float,
    radius_m: float = R_EARTH,
) -> tuple[np.ndarray, np.ndarray]:
    """East and north in m of points from an origin, by haversine distance and bearing."""
    p1, l1 = math.radians(lat0_deg), math.radians(lon0_deg)
    p2 = np.radians(np.asarray(lat_deg, dtype=float))
    dl = np.radians(np.asarray(lon_deg, dtype=float)) - l1
    dp = p2 - p1
    a = np.sin(dp / 2) ** 2 + math.cos(p1) * np.cos(p2) * np.sin(dl / 2) ** 2
    s = 2.0 * radius_m * np.arctan2(np.sqrt(a), np.sqrt(np.clip(1.0 - a, 0.0, None)))
    alpha = np.arctan2(
        np.sin(dl) * np.cos(p2), math.cos(p1) * np.sin(p2) - math.sin(p1) * np.cos(p2) * np.cos(dl)
    )
    return s * np.sin(alpha), s * np.cos(alpha)


def geodetic_to_enu(
    lat_deg: np.ndarray,
    lon_deg: np.ndarray,
    alt_m: np.ndarray | None = None,
    origin: tuple[float, float, float] | None = None,
    method: str = "wgs84",
) -> tuple[np.ndarray, np.ndarray, tuple[float, float, float]]:
    """Local east and north (m) of geodetic points.

    Parameters
    ----------
    lat_deg, lon_deg:
        Latitude and longitude in degrees (WGS-84).
    alt_m:
        Ellipsoidal height in m (zeros if None). Only used by ``wgs84``.
    origin:
        (lat_deg, lon_deg, alt_m) of the ENU origin; the first point if None.
    method:
        ``"wgs84"`` or ``"haversine"``.

    Returns
    -------
    (east, north, origin)
    """
    lat = np.asarray(lat_deg, dtype=float)
    lon = np.asarray(lon_deg, dtype=float)
    alt = np.zeros_like(lat) if alt_m is None else np.asarray(alt_m, dtype=float)
    if origin is None:
        origin = (float(lat[0]), float(lon[0]), float(alt[0]))
    if method == "wgs84":
        # Project onto the origin's height so vertical noise does not leak into E/N.
        e, n, _ = pymap3d.geodetic2enu(lat, lon, alt, origin[0], origin[1], origin[2])
        return np.asarray(e, dtype=float), np.asarray(n, dtype=float), origin
    if method == "haversine":
        e, n = haversine_enu(lat, lon, origin[0], origin[1])
        return e, n, origin
    raise OptionError(f"method must be one of {', '.join(GEODESY_METHODS)}, got {method!r}")


def enu_to_geodetic(
    east: np.ndarray, north: np.ndarray, origin: tuple[float, float, float]
) -> tuple[np.ndarray, np.ndarray]:
    """Inverse of the ``wgs84`` conversion at zero up: (lat_deg, lon_deg)."""
    lat, lon, _ = pymap3d.enu2geodetic(
        np.asarray(east, dtype=float),
        np.asarray(north, dtype=float),
        np.zeros_like(np.asarray(east, dtype=float)),
        origin[0],
        origin[1],
        origin[2],
    )
    return np.asarray(lat, dtype=float), np.asarray(lon, dtype=float)


def enu_to_geodetic_3d(
    east: np.ndarray,
    north: np.ndarray,
    up: np.ndarray,
    origin: tuple[float, float, float],
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """WGS-84 (lat_deg, lon_deg, alt_m) of local ENU points (m) from ``origin``
    (lat_deg, lon_deg, alt_m)."""
    lat, lon, alt = pymap3d.enu2geodetic(east, north, up, *origin)
    return (np.asarray(lat, dtype=float), np.asarray(lon, dtype=float),
            np.asarray(alt, dtype=float))  # fmt: skip


def ecef_to_enu(
    x_m: np.ndarray, y_m: np.ndarray, z_m: np.ndarray, origin: tuple[float, float, float]
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Local (east, north, up) in m of WGS-84 ECEF points (m) from ``origin``
    (lat_deg, lon_deg, alt_m)."""
    e, n, u = pymap3d.ecef2enu(x_m, y_m, z_m, *origin)
    return np.asarray(e, dtype=float), np.asarray(n, dtype=float), np.asarray(u, dtype=float)


def course_over_ground(
    t: np.ndarray, east: np.ndarray, north: np.ndarray, min_speed: float = 3.0
) -> tuple[np.ndarray, np.ndarray]:
    """Course over ground (rad, clockwise from north) from consecutive ENU fixes.

    Returns ``(t_mid, course)`` at the midpoints of fix pairs whose speed is at
    least ``min_speed`` m/s (slower pairs give unreliable courses and are dropped).
    """
    t = np.asarray(t, dtype=float)
    de, dn, dt = np.diff(east), np.diff(north), np.diff(t)
    with np.errstate(divide="ignore", invalid="ignore"):
        speed = np.hypot(de, dn) / dt
    ok = np.isfinite(speed) & (speed >= min_speed)
    return 0.5 * (t[1:] + t[:-1])[ok], np.arctan2(de, dn)[ok] % TWO_PI
