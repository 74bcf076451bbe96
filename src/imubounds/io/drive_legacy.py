"""The legacy drive-log model (``DriveLog``) of the per-step estimator: a transition module.

Every reader now produces a :class:`imubounds.io.drive.Drive`
(:func:`imubounds.io.read_drive`). This module keeps what the per-step
estimator on ``main`` still consumes until it reads a ``Drive``:
:func:`read_drive_log` (a ``Drive`` converted by :func:`from_drive`), the
simulator's old directory (``scenario.json`` + ``imu.csv``/``gps.csv``/
``compass.csv``, :func:`read_sim`) and :func:`to_drive` (DriveLog -> Drive,
which passes a ``Drive`` through unchanged). Delete it when nothing uses it.

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

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
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


def to_drive(log: Any) -> Any:
    """A legacy :class:`DriveLog` as a :class:`imubounds.io.drive.Drive` (transition helper).

    Truth in the legacy form (``east``/``north``/``psi`` model heading, ``u``, ``v``)
    becomes :class:`imubounds.io.drive.Truth` with a compass heading; other truth
    columns go to ``Truth.extra``. A ``Drive`` is returned unchanged, so that
    ``to_drive(read_drive(...))`` works before and after the readers switched.
    """
    from imubounds.frames import model_to_compass
    from imubounds.io.drive import Drive as _Drive

    if isinstance(log, _Drive):
        return log
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
        meta={"legacy_settings": log.settings, "files": _legacy_files(log)},
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
            origin=tuple(origin),
            heading_rad=np.asarray(model_to_compass(tr["psi"])) if "psi" in tr else None,
            u_mps=tr.get("u"),
            v_mps=tr.get("v"),
            extra={k: v for k, v in tr.items() if k not in used},
        )
    return d


def _legacy_files(log: DriveLog) -> dict[str, str]:
    if log.layout != "sim":
        return {}
    d = Path(log.source)
    return {"imu": str(d / "imu.csv"), "gnss": str(d / "gps.csv"),
            "heading": str(d / "compass.csv")}


def _need(df: Any, cols: list[str], path: Path) -> None:
    missing = [c for c in cols if c not in df.columns]
    if missing:
        raise InputError(f"{path}: missing column(s) {', '.join(missing)}")


def _read_csv(path: Path) -> Any:
    import pandas as pd

    from imubounds.io.drive_validate import check_input_path

    check_input_path(path, "simulator table", directory=False)
    try:
        return pd.read_csv(path)
    except (OSError, ValueError, pd.errors.ParserError) as err:
        raise InputError(f"{path}: cannot read CSV ({err})") from err


def _numeric(df: Any, col: str, path: Path) -> np.ndarray:
    import pandas as pd

    v = pd.to_numeric(df[col], errors="coerce")
    bad = v.isna() & df[col].notna()
    if bad.any():
        i = int(np.flatnonzero(bad.to_numpy())[0])
        raise InputError(f"{path}: column {col}, data row {i + 1}: {df[col].iloc[i]!r} "
                         "is not a number")
    return v.to_numpy(float)


def read_sim(d: Path) -> DriveLog:
    """Read the simulator's old output directory (``scenario.json``, ``imu.csv`` with ``t``)."""
    try:
        settings = json.loads((d / "scenario.json").read_text())
    except (OSError, ValueError) as err:
        raise InputError(f"{d / 'scenario.json'}: cannot read ({err})") from err
    imu = _read_csv(d / "imu.csv")
    cols = ["t", "accel_x", "accel_y", "accel_z", "gyro_x", "gyro_y", "gyro_z"]
    _need(imu, cols, d / "imu.csv")
    gps = _read_csv(d / "gps.csv")
    _need(gps, ["t", "lat", "lon", "alt", "hdop", "fix"], d / "gps.csv")
    comp = _read_csv(d / "compass.csv")
    _need(comp, ["t", "heading_deg"], d / "compass.csv")
    truth = None
    if (d / "truth.csv").is_file():
        tr = _read_csv(d / "truth.csv")
        truth = {c: _numeric(tr, c, d / "truth.csv") for c in tr.columns}
    ip, gp, cp = d / "imu.csv", d / "gps.csv", d / "compass.csv"
    return DriveLog(
        imu_t=_numeric(imu, "t", ip),
        accel=np.column_stack([_numeric(imu, c, ip) for c in cols[1:4]]),
        gyro=np.column_stack([_numeric(imu, c, ip) for c in cols[4:7]]),
        gps_t=_numeric(gps, "t", gp),
        lat=_numeric(gps, "lat", gp),
        lon=_numeric(gps, "lon", gp),
        alt=_numeric(gps, "alt", gp),
        hdop=_numeric(gps, "hdop", gp),
        fix=np.nan_to_num(_numeric(gps, "fix", gp), nan=0.0) != 0,
        heading_t=_numeric(comp, "t", cp),
        heading=np.radians(_numeric(comp, "heading_deg", cp)),
        truth=truth,
        source=str(d),
        layout="sim",
        settings=settings,
    )


def read_sim_layout(d: Path, settings: dict[str, object]) -> DriveLog:
    """A simulator directory in the generic drive layout as a legacy :class:`DriveLog`
    (transition helper until the per-step estimator reads a Drive)."""
    from imubounds.frames import compass_to_model
    from imubounds.io.drive_layout import read_layout

    drive = read_layout(d)
    if drive.imu is None or drive.gnss is None:
        raise InputError(f"{d}: the per-step estimator needs imu.csv and gnss.csv")
    g = drive.gnss
    m = g.t.size
    truth = None
    tr = drive.truth
    if tr is not None:
        import pymap3d

        # geodetic truth: the per-step estimator puts it in its own frame (first fix)
        up = tr.extra.get("up_m", np.zeros(tr.t.size))
        lat, lon, _ = pymap3d.enu2geodetic(tr.east_m, tr.north_m, up, *tr.origin)
        truth = {"t": tr.t, "east": tr.east_m, "north": tr.north_m, "lat": lat, "lon": lon}
        if tr.heading_rad is not None:
            truth["psi"] = np.unwrap(np.asarray(compass_to_model(tr.heading_rad)))
        truth["u"] = tr.u_mps if tr.u_mps is not None else np.zeros(tr.t.size)
        truth["v"] = tr.v_mps if tr.v_mps is not None else np.zeros(tr.t.size)
        for name, key in (("accel_x", "accel_x"), ("accel_y", "accel_y"), ("r", "gyro_z")):
            if key in tr.extra:
                truth[name] = tr.extra[key]
    h = drive.heading
    mag = drive.mag
    return DriveLog(
        imu_t=drive.imu.t,
        accel=drive.imu.accel,
        gyro=drive.imu.gyro,
        gps_t=g.t,
        lat=g.lat_deg,
        lon=g.lon_deg,
        alt=g.alt_m if g.alt_m is not None else np.zeros(m),
        hdop=g.hdop if g.hdop is not None else np.full(m, np.nan),
        fix=g.fix if g.fix is not None else np.ones(m, dtype=bool),
        heading_t=None if h is None else h.t,
        heading=None if h is None else h.heading_rad,
        mag_t=None if mag is None else mag.t,
        mag=None if mag is None else mag.mag,
        truth=truth,
        truth_origin=None if tr is None else tr.origin,
        source=str(d),
        layout="sim",
        settings=settings,
    )


def is_sim_dir(d: Path) -> bool:
    """True for the simulator's old output directory."""
    return d.is_dir() and (d / "scenario.json").is_file() and (d / "gps.csv").is_file()


def from_drive(drive: Any) -> DriveLog:
    """A :class:`~imubounds.io.drive.Drive` as a legacy :class:`DriveLog` (for the per-step
    estimator until it reads a Drive).

    The heading is the drive's heading stream, else its attitude yaw (an AHRS),
    else none (the estimator then levels the magnetometer). A GNSS ``h_acc_m``
    becomes the HDOP that gives the same DRMS under the drive's CEP.
    """
    from imubounds.dynamic.aiding.geodesy import enu_to_geodetic
    from imubounds.dynamic.aiding.gps import cep_to_drms
    from imubounds.frames import compass_to_model

    if drive.imu is None or drive.gnss is None:
        missing = "an IMU" if drive.imu is None else "GPS fixes"
        raise InputError(f"{drive.source}: the per-step estimator needs {missing}")
    g = drive.gnss
    n = g.t.size
    hdop = np.full(n, np.nan) if g.hdop is None else np.asarray(g.hdop, float).copy()
    if g.h_acc_m is not None:
        eq = math.sqrt(2.0) * g.h_acc_m / cep_to_drms(drive.settings.gnss.cep_m)
        hdop = np.where(np.isfinite(hdop), hdop, eq)
    heading_t = heading = None
    if drive.heading is not None:
        heading_t, heading = drive.heading.t, drive.heading.heading_rad
    elif drive.attitude is not None and drive.attitude.yaw_rad is not None:
        heading_t, heading = drive.attitude.t, drive.attitude.yaw_rad
    truth = truth_origin = None
    tr = drive.truth
    if tr is not None:
        truth = {"t": tr.t, "east": tr.east_m, "north": tr.north_m}
        if all(math.isfinite(x) for x in tr.origin[:2]):
            truth["lat"], truth["lon"] = enu_to_geodetic(tr.east_m, tr.north_m, tr.origin)
            truth_origin = tr.origin
        if tr.heading_rad is not None:
            truth["psi"] = np.unwrap(np.asarray(compass_to_model(tr.heading_rad)))
        if tr.u_mps is not None:
            truth["u"] = tr.u_mps
        if tr.v_mps is not None:
            truth["v"] = tr.v_mps
        truth.update(tr.extra)
        if not {"psi", "u", "v"} <= set(truth):
            truth = None  # the per-step estimator compares all three
    return DriveLog(
        imu_t=drive.imu.t,
        accel=drive.imu.accel,
        gyro=drive.imu.gyro,
        gps_t=g.t,
        lat=g.lat_deg,
        lon=g.lon_deg,
        alt=np.full(n, np.nan) if g.alt_m is None else g.alt_m,
        hdop=hdop,
        fix=g.usable(),
        heading_t=heading_t,
        heading=heading,
        mag_t=None if drive.mag is None else drive.mag.t,
        mag=None if drive.mag is None else drive.mag.mag,
        truth=truth,
        truth_origin=truth_origin,
        source=drive.source,
        layout=drive.layout,
        frame="FLU",
        settings={"imu_axes": list(drive.settings.imu_axes)},
        warnings=[*drive.warnings, *drive.notes],
    )


def read_drive_log(paths: list[str] | str, mount: str = "auto", **options: Any) -> DriveLog:
    """The per-step estimator's reader: any drive input as a validated :class:`DriveLog`.

    The simulator's old directory is read as it is; everything else goes
    through :func:`imubounds.io.read_drive` and :func:`from_drive`.
    """
    from imubounds.io.drive_readers import read_drive

    ps = [paths] if isinstance(paths, str) else list(paths)
    if len(ps) == 1 and is_sim_dir(Path(ps[0])):
        log = read_sim(Path(ps[0]))
    elif len(ps) == 1 and (Path(ps[0]) / "scenario.json").is_file():
        # the simulator's directory in the generic layout, with its estimator settings
        sd = Path(ps[0])
        try:
            settings = json.loads((sd / "scenario.json").read_text())
        except (OSError, ValueError) as err:
            raise InputError(f"{sd / 'scenario.json'}: cannot read ({err})") from err
        log = read_sim_layout(sd, settings)
    else:
        log = from_drive(read_drive(ps, mount=mount, **options))
    log.validate()
    return log
