"""Physical and numerical constants of the analysis, each once, with its unit.

Unit factors (one degree in rad, standard gravity, an hour) are in :mod:`imubounds.units`.
The values are those the method was written with (docs/dynamic-method.md, section 3);
changing one changes the bounds.
"""

from __future__ import annotations

# ------------------------------------------------------------------------- the Earth

#: the Earth's rotation rate against inertial space (WGS84), rad/s
EARTH_RATE = 7.2921159e-5
#: the Earth's mean radius, m: the transport rate ``v / R`` of the local level frame in
#: mode full's constraints, and the sphere of the haversine geodesy (the paper's value)
R_EARTH = 6.371e6
#: a lower bound of the Earth's radius, m (below the polar radius 6.357e6 m): the rate of
#: the local level frame against inertial space is at most ``EARTH_RATE + v / R_EARTH_MIN``
#: (the pitch from GNSS altitude, where an upper bound is needed)
R_EARTH_MIN = 6.35e6
#: the range of the local gravity magnitude, m/s^2 (latitude and height of a vehicle on
#: the ground: 9.78 at the equator to 9.83 at the poles, less with height)
G_LO = 9.76
G_HI = 9.84

# ------------------------------------------------------------------ floating point

#: the unit roundoff of IEEE double precision (round to nearest), dimensionless
UNIT_ROUNDOFF = 2.0**-53
#: an upper bound of the machine epsilon 2**-52 = 2.22e-16 used in error bounds of sums,
#: dimensionless
EPS_UP = 2.3e-16
#: the relative inflation of a bound computed in floating point, ``x * (1 + ROUND_REL)``
#: (covers the rounding of its few operations with a wide margin), dimensionless
ROUND_REL = 1e-12
