"""The drive-log model: IMU, GPS fixes, compass heading / magnetometer, optional truth.

Frames and units (SI throughout):

* IMU body axes are **FLU**: x forward, y left, z up. Readers convert from
  the sensor's frame (FRD on the VN-100 and the comma2k19 phone). ``accel``
  is specific force in m/s^2, ``gyro`` angular rate in rad/s; the yaw rate
  ``gyro[:, 2]`` is positive counter-clockwise seen from above, matching the
  model heading.
* GPS fixes are geodetic WGS-84 (``lat``/``lon`` in degrees, ``alt`` in m),
  with ``hdop`` (NaN when not reported) and a ``fix`` flag (False: no fix).
* ``heading`` is a compass heading in rad, **clockwise from north** (what a
  compass or a yaw output reports). ``mag`` is the magnetometer in the same
  FLU body axes (any unit; only the direction is used).
* ``truth`` (optional) holds the true trajectory in the local ENU frame of
  ``truth_origin``: ``t`` (s), ``east``/``north`` (m), ``psi`` (rad, model
  convention: counter-clockwise from east), ``u``/``v`` (m/s, body), and
  where known ``accel_x``/``accel_y`` (m/s^2, what a noiseless accelerometer
  under the log's kinematic model reads) and ``r`` (rad/s).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from imubounds.errors import InputError


@dataclass
class DriveLog:
    """A multi-sensor drive log in SI units (see the module docstring for frames)."""

    imu_t: np.ndarray
    accel: np.ndarray
    gyro: np.ndarray
    gps_t: np.ndarray
    lat: np.ndarray
    lon: np.ndarray
    alt: np.ndarray
    hdop: np.ndarray
    fix: np.ndarray
    heading_t: np.ndarray | None = None
    heading: np.ndarray | None = None
    mag_t: np.ndarray | None = None
    mag: np.ndarray | None = None
    truth: dict[str, np.ndarray] | None = None
    truth_origin: tuple[float, float, float] | None = None
    source: str = "<memory>"
    layout: str = "memory"
    frame: str = "FLU"
    settings: dict[str, object] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)

    @property
    def imu_rate_hz(self) -> float:
        """Median IMU sample rate in Hz."""
        return float(1.0 / np.median(np.diff(self.imu_t)))

    @property
    def gps_rate_hz(self) -> float:
        """Median GPS fix rate in Hz."""
        return float(1.0 / np.median(np.diff(self.gps_t)))

    def validate(self) -> None:
        """Check shapes, sorting and overlap; raise :class:`InputError` naming the problem."""
        src = self.source
        n = self.imu_t.shape[0]
        if n < 2:
            raise InputError(f"{src}: the IMU stream has {n} samples; need at least 2")
        if self.accel.shape != (n, 3) or self.gyro.shape != (n, 3):
            raise InputError(f"{src}: accel and gyro must be (n, 3) arrays matching the IMU time")
        for name, t in (
            ("IMU", self.imu_t),
            ("GPS", self.gps_t),
            ("heading", self.heading_t),
            ("magnetometer", self.mag_t),
        ):
            if t is None:
                continue
            if not np.all(np.isfinite(t)):
                raise InputError(f"{src}: the {name} time stamps contain NaN or inf")
            bad = np.flatnonzero(np.diff(t) <= 0)
            if bad.size:
                raise InputError(
                    f"{src}: {name} time stamps are not strictly increasing at sample {bad[0] + 1} "
                    f"(0-based; t={t[bad[0]]:.6f} then {t[bad[0] + 1]:.6f} s); "
                    "sort the log or drop duplicate rows"
                )
        m = self.gps_t.shape[0]
        for name, arr in (
            ("lat", self.lat),
            ("lon", self.lon),
            ("alt", self.alt),
            ("hdop", self.hdop),
            ("fix", self.fix),
        ):
            if arr.shape[0] != m:
                raise InputError(f"{src}: GPS column {name} has {arr.shape[0]} rows, time has {m}")
        good = self.fix & np.isfinite(self.lat) & np.isfinite(self.lon)
        if not np.any(good):
            raise InputError(f"{src}: no usable GPS fix (all rows missing or flagged no-fix)")
        if self.heading is None and self.mag is None:
            raise InputError(f"{src}: no compass heading and no magnetometer: cannot bound heading")
        g_t = self.gps_t[good]
        lo, hi = max(self.imu_t[0], g_t[0]), min(self.imu_t[-1], g_t[-1])
        if hi <= lo:
            raise InputError(
                f"{src}: IMU ({self.imu_t[0]:.3f}..{self.imu_t[-1]:.3f} s) and GPS "
                f"({g_t[0]:.3f}..{g_t[-1]:.3f} s) do not overlap in time; check the clocks"
            )
        ht = self.heading_t if self.heading is not None else self.mag_t
        assert ht is not None
        if min(hi, ht[-1]) <= max(lo, ht[0]):
            raise InputError(
                f"{src}: the heading source ({ht[0]:.3f}..{ht[-1]:.3f} s) does not overlap the "
                f"IMU and GPS ({lo:.3f}..{hi:.3f} s)"
            )


def to_drive(log: DriveLog) -> Any:
    """A legacy :class:`DriveLog` as a :class:`imubounds.io.drive.Drive` (transition helper).

    Truth in the legacy form (``east``/``north``/``psi`` model heading, ``u``, ``v``)
    becomes :class:`imubounds.io.drive.Truth` with a compass heading; other truth
    columns go to ``Truth.extra``.
    """
    import math

    from imubounds.frames import model_to_compass
    from imubounds.io.drive import (
        Drive,
        GnssStream,
        HeadingStream,
        ImuStream,
        MagStream,
        Truth,
    )

    d = Drive(
        imu=ImuStream(t=log.imu_t, accel=log.accel, gyro=log.gyro),
        gnss=GnssStream(
            t=log.gps_t,
            lat_deg=log.lat,
            lon_deg=log.lon,
            alt_m=log.alt,
            hdop=log.hdop,
            fix=log.fix,
        ),
        source=log.source,
        layout=log.layout,
        warnings=list(log.warnings),
        meta={"legacy_settings": log.settings},
    )
    if log.heading is not None and log.heading_t is not None:
        d.heading = HeadingStream(t=log.heading_t, heading_rad=log.heading)
    if log.mag is not None and log.mag_t is not None:
        d.mag = MagStream(t=log.mag_t, mag=log.mag)
    tr = log.truth
    if tr is not None:
        if "east" in tr:
            e, n = tr["east"], tr["north"]
            origin = log.truth_origin or (math.nan, math.nan, 0.0)
        else:
            from imubounds.dynamic.aiding.geodesy import geodetic_to_enu

            e, n, origin = geodetic_to_enu(tr["lat"], tr["lon"], None)
        used = {"t", "east", "north", "lat", "lon", "psi", "u", "v"}
        d.truth = Truth(
            t=tr["t"],
            east_m=e,
            north_m=n,
            origin=tuple(origin),  # type: ignore[arg-type]
            heading_rad=np.asarray(model_to_compass(tr["psi"])) if "psi" in tr else None,
            u_mps=tr.get("u"),
            v_mps=tr.get("v"),
            extra={k: v for k, v in tr.items() if k not in used},
        )
    return d
