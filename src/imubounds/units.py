"""Unit constants and conversions between SI and the units of IEEE Std 952.

Inside the library everything is SI: rad, rad/s, m/s, m/s^2, s. Degrees, hours
and g appear only at the edges (parsing, reports). This module is the one place
those edge conversions live.
"""

from __future__ import annotations

import math
from typing import Literal

DEG = math.pi / 180.0  #: one degree in rad
G0 = 9.80665  #: standard gravity, m/s^2
HOUR = 3600.0  #: s
SQRT_HOUR = 60.0  #: sqrt(s) per sqrt(h)

SensorKind = Literal["gyro", "accel"]
Term = Literal["Q", "N", "B", "K", "R"]

# SI unit of each noise term, for rate gyros (rad/s) and accelerometers (m/s^2).
SI_UNITS: dict[SensorKind, dict[Term, str]] = {
    "gyro": {"Q": "rad", "N": "rad/s^0.5", "B": "rad/s", "K": "rad/s^1.5", "R": "rad/s^2"},
    "accel": {"Q": "m/s", "N": "m/s^1.5", "B": "m/s^2", "K": "m/s^2.5", "R": "m/s^3"},
}

# IEEE 952-style units and the factor that converts an SI value into them.
IEEE_UNITS: dict[SensorKind, dict[Term, tuple[str, float]]] = {
    "gyro": {
        "Q": ("deg", 1.0 / DEG),
        "N": ("deg/h^0.5", SQRT_HOUR / DEG),
        "B": ("deg/h", HOUR / DEG),
        "K": ("deg/h/h^0.5", HOUR * SQRT_HOUR / DEG),
        "R": ("deg/h^2", HOUR * HOUR / DEG),
    },
    "accel": {
        "Q": ("m/s", 1.0),
        "N": ("m/s/h^0.5", SQRT_HOUR),
        "B": ("ug", 1.0e6 / G0),
        "K": ("m/s/h/h^0.5", HOUR * SQRT_HOUR),
        "R": ("m/s/h^2", HOUR * HOUR),
    },
}

# Datasheet-style units (per second and per root-hertz, as most MEMS datasheets
# print them), shown beside the IEEE 952 ones; the factor converts from SI.
DATASHEET_UNITS: dict[SensorKind, dict[Term, tuple[str, float]]] = {
    "gyro": {
        "Q": ("deg", 1.0 / DEG),
        "N": ("deg/s/sqrt(Hz)", 1.0 / DEG),
        "B": ("deg/s", 1.0 / DEG),
        "K": ("deg/s^2/sqrt(Hz)", 1.0 / DEG),
        "R": ("deg/s^2", 1.0 / DEG),
    },
    "accel": {
        "Q": ("m/s", 1.0),
        "N": ("ug/sqrt(Hz)", 1.0e6 / G0),
        "B": ("mg", 1.0e3 / G0),
        "K": ("m/s^3/sqrt(Hz)", 1.0),
        "R": ("m/s^3", 1.0),
    },
}
#: Datasheet unit of the measured signal itself, with the factor from SI.
SIGNAL_DATASHEET_UNITS: dict[SensorKind, tuple[str, float]] = {
    "gyro": ("deg/s", 1.0 / DEG),
    "accel": ("mg", 1.0e3 / G0),
}

# Measured-quantity units accepted on input, with the factor to SI.
GYRO_UNITS: dict[str, float] = {
    "rad/s": 1.0,
    "rads": 1.0,
    "deg/s": DEG,
    "dps": DEG,
    "deg/h": DEG / HOUR,
    "mrad/s": 1e-3,
}
ACCEL_UNITS: dict[str, float] = {
    "m/s^2": 1.0,
    "m/s2": 1.0,
    "mps2": 1.0,
    "g": G0,
    "mg": 1e-3 * G0,
    "ug": 1e-6 * G0,
}
TIME_UNITS: dict[str, float] = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}

# Unit spellings (lower case, spaces removed: imubounds.io.columns compacts a written unit
# to this form) -> key of GYRO_UNITS. The one table of unit spellings: the column
# recognition of every reader and the drive layout's <unit> suffixes both use it.
GYRO_UNIT_SYNONYMS: dict[str, str] = {
    "rad/s": "rad/s",
    "rads": "rad/s",
    "rad_s": "rad/s",
    "radps": "rad/s",
    "radpersec": "rad/s",
    "rad/sec": "rad/s",
    "rps": "rad/s",
    "deg/s": "deg/s",
    "degs": "deg/s",
    "deg_s": "deg/s",
    "degps": "deg/s",
    "dps": "deg/s",
    "deg/sec": "deg/s",
    "degpersec": "deg/s",
    "deg/h": "deg/h",
    "deg/hr": "deg/h",
    "degh": "deg/h",
    "deg_h": "deg/h",
    "dph": "deg/h",
    "mrad/s": "mrad/s",
    "mrads": "mrad/s",
    "mrad_s": "mrad/s",
}
# Unit spellings -> key of ACCEL_UNITS.
ACCEL_UNIT_SYNONYMS: dict[str, str] = {
    "m/s^2": "m/s^2",
    "m/s2": "m/s^2",
    "ms2": "m/s^2",
    "ms^2": "m/s^2",
    "m_s2": "m/s^2",
    "m_s_2": "m/s^2",
    "m_s^2": "m/s^2",
    "mps2": "m/s^2",
    "mpss": "m/s^2",
    "m/s/s": "m/s^2",
    "g": "g",
    "g0": "g",
    "mg": "mg",
    "ug": "ug",
}
TIME_UNIT_SYNONYMS: dict[str, str] = {
    "s": "s",
    "sec": "s",
    "secs": "s",
    "second": "s",
    "seconds": "s",
    "ms": "ms",
    "msec": "ms",
    "millisecond": "ms",
    "milliseconds": "ms",
    "us": "us",
    "usec": "us",
    "microsecond": "us",
    "microseconds": "us",
    "ns": "ns",
    "nsec": "ns",
    "nanosecond": "ns",
    "nanoseconds": "ns",
}
assert set(GYRO_UNIT_SYNONYMS.values()) <= set(GYRO_UNITS)
assert set(ACCEL_UNIT_SYNONYMS.values()) <= set(ACCEL_UNITS)
assert set(TIME_UNIT_SYNONYMS.values()) <= set(TIME_UNITS)


def unit_factors(kind: Literal["gyro", "accel", "time"]) -> dict[str, float]:
    """Every accepted spelling of a ``kind`` unit (canonical keys and their synonyms)
    -> the factor to SI."""
    si = {"gyro": GYRO_UNITS, "accel": ACCEL_UNITS, "time": TIME_UNITS}[kind]
    synonyms = {"gyro": GYRO_UNIT_SYNONYMS, "accel": ACCEL_UNIT_SYNONYMS,
                "time": TIME_UNIT_SYNONYMS}[kind]  # fmt: skip
    return {**si, **{spelling: si[key] for spelling, key in synonyms.items()}}


def sensor_kind(channel: str) -> SensorKind:
    """``'gyro'`` for gyro channels, ``'accel'`` for accelerometer channels."""
    if channel.startswith("gyro"):
        return "gyro"
    if channel.startswith("accel"):
        return "accel"
    raise ValueError(f"not an IMU channel name: {channel!r}")


def si_unit_of_signal(kind: SensorKind) -> str:
    """SI unit of the measured signal itself."""
    return "rad/s" if kind == "gyro" else "m/s^2"


def to_ieee(kind: SensorKind, term: Term, value_si: float) -> tuple[float, str]:
    """Convert a noise term from SI into IEEE 952 units; returns (value, unit)."""
    unit, factor = IEEE_UNITS[kind][term]
    return value_si * factor, unit


def to_datasheet(kind: SensorKind, term: Term, value_si: float) -> tuple[float, str]:
    """Convert a noise term from SI into datasheet units; returns (value, unit)."""
    unit, factor = DATASHEET_UNITS[kind][term]
    return value_si * factor, unit


def signal_to_datasheet(kind: SensorKind, value_si: float) -> tuple[float, str]:
    """A rate (rad/s) or acceleration (m/s^2) in datasheet units (deg/s, mg)."""
    unit, factor = SIGNAL_DATASHEET_UNITS[kind]
    return value_si * factor, unit
