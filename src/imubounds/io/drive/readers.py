"""Read any supported drive log into a :class:`~imubounds.io.drive.Drive`: one entry point.

:func:`read_drive` detects the input (see :func:`detect_layout`), reads it,
applies the mount rotation (``imu_axes``) to the IMU before anything else, and
validates every stream (:func:`imubounds.io.drive.validate.validate_drive`):

``generic``
    The documented drive layout (``imu.csv``, ``gnss.csv``, ``velocity.csv``,
    ``heading.csv``, ``attitude.csv``, ``truth.csv``, ``drive.yaml``; CSV,
    CSV.gz or Parquet), :mod:`imubounds.io.drive.layout`.
``vn100``
    The VN-100 + BU-353N layout: ``*_imu.csv`` (t Unix s, ``gyro_*`` rad/s,
    ``acc_*`` m/s^2, ``mag_*`` T, raw ``$VNYMR`` with yaw/pitch/roll in degrees;
    FRD axes) and ``*_gps.csv`` (t, latitude, longitude, altitude, hdop, raw
    ``$GPGGA``). A directory holding both, or the two files.
``comma2k19``
    A comma2k19 segment directory: ``processed_log/IMU/{accelerometer,gyro,
    magnetometer}``, ``processed_log/GNSS/live_gnss_ublox`` (every fix, with
    speed and bearing), ``processed_log/CAN/speed`` and ``global_pose`` (truth).
``rosbag``
    ROS 1 ``.bag``, ROS 2 bag directory or ``.db3``, MCAP
    (:func:`imubounds.io.rosbag.read_drive_rosbag`).
``ulog``
    PX4 ``.ulg`` (:func:`imubounds.io.ulog.read_drive_ulog`).
``nmea``
    An NMEA capture (GGA, RMC, VTG, HDT/HDG) with an IMU log, or alone when it
    carries VectorNav ``$VNYMR`` IMU sentences
    (:func:`imubounds.io.nmea.read_drive_nmea`).
``csv``
    CSV/Parquet logs of other tools through a column map (``columns``:
    layout column -> source column), or a wide table already using the
    layout's column names.

What was verified against the data (the sign conventions):

* VN-100: axes are FRD (``acc_z`` ~ -9.8 at rest, the VNYMR yaw rate equals
  +``gyro_z`` so yaw is clockwise). In ``vn100_bu353_circle`` the yaw is
  about 180 deg from the GPS course over ground and the lateral acceleration
  points out of the turn in sensor axes: the unit is mounted facing
  backwards. With ``mount="auto"`` the reader detects this (median |yaw -
  course| > 90 deg) and sets ``imu_axes: [-x, -y, z]``, saying so in
  ``warnings``.
* comma2k19: ``frame_orientations`` are (w, x, y, z) quaternions of an FRD
  body frame in ECEF (the body x axis carries the velocity, body z points
  down); the phone IMU axes agree with it once read as FRD (``gyro_z`` ~ -yaw
  rate, ``accel_x`` follows the forward acceleration, ``accel_z`` ~ -9.7),
  which :func:`~imubounds.io.drive.mount.mount_check` confirms against the truth on every read. The
  u-blox bearing is degrees clockwise from true north (agrees with the truth's
  heading to about a degree on the highway). There is no HDOP.
"""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from imubounds.errors import InputError, OptionError
from imubounds.frames import (
    axes_matrix,
    frd_to_flu,
    is_identity_axes,
    matrix_to_rpy,
    wrap_pi,
)
from imubounds.io.drive import (
    AttitudeStream,
    Drive,
    DriveSettings,
    GnssStream,
    ImuStream,
    MagStream,
    Truth,
    VelocityStream,
)
from imubounds.io.drive.layout import (
    FILES,
    TABLE_COLUMNS,
    drive_from_tables,
    is_layout,
    read_layout,
    release_freed_memory,
)
from imubounds.io.drive.mount import apply_mount, warn_mount
from imubounds.io.drive.settings import (
    SETTINGS_FILE,
    load_settings_yaml,
    parse_settings,
    read_settings_with_info,
)
from imubounds.io.drive.validate import validate_drive
from imubounds.io.magic import is_bag, is_ulog
from imubounds.io.registry import reader_entry
from imubounds.io.validate import check_input_path

_BAG_SUFFIXES = (".bag", ".mcap", ".db3")
_NMEA_SUFFIXES = (".nmea", ".nma", ".gps")
_TABLE_SUFFIXES = (".csv", ".csv.gz", ".tsv", ".txt", ".parquet")


# ----------------------------------------------------------------------------- detection


def _head(p: Path, n: int = 64) -> bytes:
    try:
        with open(p, "rb") as f:
            return f.read(n)
    except OSError as err:
        raise InputError(f"{p}: cannot read ({err.strerror})") from err


def _is_nmea(p: Path) -> bool:
    from imubounds.io.nmea import sniff_nmea

    return p.suffix.lower() in _NMEA_SUFFIXES or sniff_nmea(_head(p, 256))


def detect_layout(paths: Sequence[str | Path]) -> tuple[str, dict[str, Any]]:
    """Work out which input ``paths`` are; return (layout, files).

    Every path is checked first: a missing path or a special file (a named
    pipe, a device) is an :class:`InputError` before anything is opened.
    """
    if not paths:
        raise InputError(
            "no drive log given: pass a drive-layout directory, a VN-100 directory or its two "
            "CSV files, a comma2k19 segment, a ROS bag, a ULog, an NMEA capture or a CSV log"
        )
    ps = [check_input_path(p, what="drive log", allow_dir=True) for p in paths]
    files = [p for p in ps if p.is_file()]
    dirs = [p for p in ps if p.is_dir()]
    if len(ps) == 1 and dirs:
        return _detect_dir(dirs[0])
    if dirs:
        raise InputError(
            f"{' '.join(map(str, ps))}: give one directory alone, or files only"
        )
    if len(ps) == 1:
        p = ps[0]
        name = p.name.lower()
        head = _head(p)
        if name.endswith(_BAG_SUFFIXES) or is_bag(head):
            return "rosbag", {"path": p}
        if name.endswith(".ulg") or is_ulog(head):
            return "ulog", {"path": p}
        if _is_nmea(p):
            return "nmea", {"nmea": p, "imu": None}
        if name.endswith(_TABLE_SUFFIXES):
            return "csv", {"paths": [p]}
    if len(files) == 2:
        imu = [p for p in files if p.name.endswith("_imu.csv")]
        gps = [p for p in files if p.name.endswith("_gps.csv")]
        if len(imu) == 1 and len(gps) == 1:
            return "vn100", {"imu": imu[0], "gps": gps[0]}
        nmea = [p for p in files if _is_nmea(p)]
        if len(nmea) == 1:
            other = files[1] if files[0] == nmea[0] else files[0]
            return "nmea", {"nmea": nmea[0], "imu": other}
    if files and all(p.name.lower().endswith(_TABLE_SUFFIXES) for p in files):
        return "csv", {"paths": files}
    raise InputError(
        f"{' '.join(map(str, ps))}: not a known drive log: give one drive-layout directory, a "
        "ROS bag / MCAP / ULog file, the two VN-100 files (*_imu.csv and *_gps.csv), an NMEA "
        "capture (with an IMU log unless it holds $VNYMR), or CSV files with a column map"
    )


def _detect_dir(d: Path) -> tuple[str, dict[str, Any]]:
    if (d / "metadata.yaml").is_file():
        return "rosbag", {"path": d}
    if (d / "processed_log").is_dir():
        return "comma2k19", {"dir": d}
    imu = sorted(d.glob("*_imu.csv"))
    gps = sorted(d.glob("*_gps.csv"))
    vn_pair = len(imu) == 1 and len(gps) == 1
    # a drive.yaml beside a VN-100 pair is that drive's settings (load_drive reads it)
    if is_layout(d) and not (vn_pair and not any(d.glob("imu.*"))):
        return "generic", {"dir": d}
    if vn_pair:
        return "vn100", {"imu": imu[0], "gps": gps[0]}
    present = [f"{s}.csv" for s in FILES if any(d.glob(f"{s}.*"))]
    raise InputError(
        f"{d}: not a known drive-log directory: expected the drive layout (imu.csv with "
        "time_s, gyro_{x,y,z}_<unit>, accel_{x,y,z}_<unit>, plus gnss.csv, velocity.csv or "
        "heading.csv, and drive.yaml), a comma2k19 segment (processed_log/), a ROS 2 bag "
        "(metadata.yaml) or one *_imu.csv with one *_gps.csv"
        + (f"; found {', '.join(present)} but no imu table" if present else "")
    )


# ----------------------------------------------------------------------------- settings


def _settings(
    settings: DriveSettings | str | Path | None, where: str
) -> tuple[DriveSettings, dict[str, Any]]:
    if isinstance(settings, DriveSettings):
        return dataclasses.replace(settings, assumed=list(settings.assumed),
                                   defaulted=list(settings.defaulted)), {}
    if settings is None:
        s = parse_settings({}, where)
        s.assumed.insert(0, f"{where}: no drive.yaml: every setting is its documented default")
        return s, {}
    p = check_input_path(settings, what="drive settings (drive.yaml)")
    data = load_settings_yaml(p)
    info = {}
    if isinstance(data, dict):
        for k in ("converted_from", "notes"):
            if k in data:
                info[k] = data.pop(k)
    return parse_settings(data, str(p), base_dir=p.parent), info


def _given(s: DriveSettings, key: str, value: Any, where: str) -> None:
    """Set a dotted setting that a reader knows (no longer assumed)."""
    section, _, name = key.partition(".")
    if key not in s.defaulted:
        return  # the user's drive.yaml said it: the user wins
    if name:
        setattr(getattr(s, section), name, value)
    else:
        setattr(s, section, value)
    s.defaulted.remove(key)
    s.assumed[:] = [a for a in s.assumed if not a.startswith(f"{key} =")]
    s.assumed.append(f"{key} = {value!r} ({where})")


def _override_axes(s: DriveSettings, imu_axes: Sequence[str] | None) -> bool:
    if imu_axes is None:
        return False
    axes = tuple(str(a).strip() for a in imu_axes)
    axes_matrix(axes)
    s.imu_axes = axes  # type: ignore[assignment]
    if "imu_axes" in s.defaulted:
        s.defaulted.remove("imu_axes")
    s.assumed[:] = [a for a in s.assumed if not a.startswith("imu_axes")]
    return True


# ----------------------------------------------------------------------------- helpers


# ----------------------------------------------------------------------------- VN-100


def _vn_csv(path: Path) -> pd.DataFrame:
    check_input_path(path, what="VN-100 log")
    try:
        df = pd.read_csv(path)
    except (OSError, ValueError, pd.errors.ParserError) as err:
        first = (str(err).splitlines() or [type(err).__name__])[0]
        raise InputError(f"{path}: cannot read CSV ({first})") from err
    if df.shape[0] == 0:
        raise InputError(f"{path}: no data rows (only a header)")
    return df


def _need(df: pd.DataFrame, cols: list[str], path: Path) -> None:
    missing = [c for c in cols if c not in df.columns]
    if missing:
        raise InputError(
            f"{path}: missing column(s) {', '.join(missing)} (found: {', '.join(df.columns[:12])})"
        )


def _num(df: pd.DataFrame, col: str, path: Path) -> np.ndarray:
    raw = df[col]
    v = pd.to_numeric(raw, errors="coerce")
    bad = v.isna() & raw.notna()
    if bad.any():
        i = int(np.flatnonzero(bad.to_numpy())[0])
        raise InputError(f"{path}: column {col}, data row {i + 1}: {raw.iloc[i]!r} is not a number")
    return v.to_numpy(float)


def _nmea_field(raw: pd.Series, index: int) -> np.ndarray:
    parts = raw.astype(str).str.strip().str.split(",")
    return pd.to_numeric(parts.str[index], errors="coerce").to_numpy(float)


def read_vn100(
    imu_path: Path, gps_path: Path, settings: DriveSettings, mount: str = "auto"
) -> Drive:
    """Read the VN-100 IMU CSV and BU-353N GPS CSV (FRD axes -> FLU, then ``imu_axes``).

    The VNYMR yaw/pitch/roll become the attitude stream (an AHRS of the same
    unit: its yaw is magnetic and uses the unit's gyros, so it is not a heading
    independent of the IMU); the raw magnetometer is kept for the compass
    calibration. ``mount``: ``"auto"`` (a backwards unit is detected from the
    yaw against the GPS course), ``"forward"`` or ``"backward"``; ignored when
    ``imu_axes`` was given.
    """
    if mount not in ("auto", "forward", "backward"):
        raise OptionError(f"--mount must be auto, forward or backward, got {mount!r}")
    imu = _vn_csv(imu_path)
    _need(imu, ["t", "gyro_x", "gyro_y", "gyro_z", "acc_x", "acc_y", "acc_z"], imu_path)
    gps = _vn_csv(gps_path)
    _need(gps, ["t", "latitude", "longitude"], gps_path)
    t = _num(imu, "t", imu_path)
    drive = Drive(settings=settings, source=str(imu_path.parent), layout="vn100")
    drive.meta["files"] = {"imu": str(imu_path), "gnss": str(gps_path),
                           "heading": str(imu_path), "attitude": str(imu_path)}
    drive.imu = ImuStream(
        t=t,
        accel=frd_to_flu(np.column_stack([_num(imu, f"acc_{a}", imu_path) for a in "xyz"])),
        gyro=frd_to_flu(np.column_stack([_num(imu, f"gyro_{a}", imu_path) for a in "xyz"])),
        input_units={"gyro": "rad/s", "accel": "m/s^2"},
    )
    if all(c in imu.columns for c in ("mag_x", "mag_y", "mag_z")):
        m = frd_to_flu(np.column_stack([_num(imu, f"mag_{a}", imu_path) for a in "xyz"]))
        drive.mag = MagStream(t=t, mag=m, unit="T")
    if "raw_vnymr" in imu.columns:
        ypr = [np.radians(_nmea_field(imu["raw_vnymr"], k)) for k in (1, 2, 3)]
        ok = np.isfinite(ypr[1]) & np.isfinite(ypr[2])
        lost = int((~ok).sum())
        if lost:
            drive.warn("attitude_nan", lost, f"{imu_path}: {lost} of {t.size} $VNYMR "
                       "sentence(s) without a finite pitch and roll: no attitude there")
        if ok.any():  # a NaN yaw: validate_drive drops it (counted, named)
            drive.attitude = AttitudeStream(
                t=t[ok], roll_rad=ypr[2][ok], pitch_rad=ypr[1][ok],
                yaw_rad=np.mod(ypr[0][ok], 2 * math.pi), source="ahrs",
            )
    g_t = _num(gps, "t", gps_path)
    lat, lon = _num(gps, "latitude", gps_path), _num(gps, "longitude", gps_path)
    hdop = _num(gps, "hdop", gps_path) if "hdop" in gps.columns else None
    fix = np.ones(g_t.size, bool)
    if "raw_gpgga" in gps.columns:
        q = _nmea_field(gps["raw_gpgga"], 6)
        fix = ~(np.isfinite(q) & (q == 0))
        if hdop is None:
            hdop = _nmea_field(gps["raw_gpgga"], 8)
    if hdop is None:
        drive.warnings.append(f"{gps_path}: no HDOP column; the default HDOP is used for every fix")
    drive.gnss = GnssStream(
        t=g_t, lat_deg=lat, lon_deg=lon,
        alt_m=_num(gps, "altitude", gps_path) if "altitude" in gps.columns else None,
        hdop=hdop, fix=fix,
    )
    _given(settings, "imu.preset", "vn100", "the VN-100 reader: datasheet of the unit")
    user_axes = "imu_axes" not in settings.defaulted
    if not user_axes:
        if mount == "auto":
            mount = _detect_backwards(drive)
        if mount == "backward":
            _given(settings, "imu_axes", ("-x", "-y", "z"), "the VN-100 reader: mounted backwards")
            drive.warnings.append(
                f"{imu_path}: the VN-100 yaw is ~180 deg from the GPS course over ground: the "
                "unit is mounted backwards; body axes rotated 180 deg about z (imu_axes [-x, -y, "
                "z]; use --mount forward to disable)"
            )
    apply_mount(drive, attitude_of_sensor=True)
    drive.meta["mount"] = "backward" if settings.imu_axes == ("-x", "-y", "z") else (
        "forward" if is_identity_axes(settings.imu_axes) else "imu_axes")
    return drive


def _detect_backwards(drive: Drive) -> str:
    from imubounds.geodesy import course_over_ground, geodetic_to_enu

    g, a = drive.gnss, drive.attitude
    if g is None or a is None or a.yaw_rad is None:
        return "forward"
    good = g.usable()
    if good.sum() < 3:
        return "forward"
    e, n, _ = geodetic_to_enu(g.lat_deg[good], g.lon_deg[good])
    tm, cog = course_over_ground(g.t[good], e, n, min_speed=2.0)
    if tm.size < 3:
        return "forward"
    yaw = np.interp(tm, a.t, np.unwrap(a.yaw_rad))
    diff = np.abs(np.asarray(wrap_pi(yaw - cog)))
    return "backward" if np.median(diff) > math.pi / 2 else "forward"


# ----------------------------------------------------------------------------- comma2k19


def _load(d: Path, rel: str) -> np.ndarray:
    p = d / rel
    check_input_path(p, what="comma2k19 signal")
    try:
        with open(p, "rb") as fh:
            a = np.load(fh, allow_pickle=False)
    except (OSError, ValueError, EOFError) as err:
        raise InputError(f"{p}: cannot load numpy array ({err})") from err
    try:
        out = np.asarray(a, dtype=float)
    except (TypeError, ValueError) as err:
        raise InputError(f"{p}: not an array of numbers ({a.dtype})") from err
    if rel.endswith("/t") and out.ndim == 1 and out.size > 1:
        back = np.flatnonzero(np.diff(out) < 0)
        if back.size:
            k = int(back[0])
            raise InputError(
                f"{p}: the time stamps go backwards at row {k + 2} ({out[k]:.6f} then "
                f"{out[k + 1]:.6f} s; {back.size} step(s) back): the signal is reversed or "
                "unsorted; sort it by time"
            )
    return out


#: lateral speed bound the comma2k19 reader states for its road cars (m/s)
COMMA_LATERAL_BOUND_MPS = 0.5
#: vertical body-velocity bound the comma2k19 reader states (m/s): the phone sits pitched
#: about 4 deg against the car's velocity (|w| up to 1.41 m/s at 20 m/s in global_pose on
#: the bundled segment); 4 deg at 33 m/s plus suspension heave
COMMA_VERTICAL_BOUND_MPS = 2.5


def read_comma2k19(d: Path, settings: DriveSettings) -> Drive:
    """Read a comma2k19 segment: phone IMU (read as FRD, then ``imu_axes``), every u-blox
    fix with its speed and bearing as GNSS velocity, the CAN speed as body velocity, the
    (OS-calibrated) magnetometer, and ``global_pose`` as truth."""
    drive = Drive(settings=settings, source=str(d), layout="comma2k19")
    # comma2k19 is driven by road cars: the side-slip velocity at the phone is a few
    # tenths of a m/s at most (0.37 m/s in global_pose on the bundled segment)
    _given(settings, "vehicle.lateral_speed_bound_mps", COMMA_LATERAL_BOUND_MPS,
           "the comma2k19 reader: a road car")
    _given(settings, "vehicle.vertical_speed_bound_mps", COMMA_VERTICAL_BOUND_MPS,
           "the comma2k19 reader: a phone pitched on its mount")
    base = "processed_log/"
    drive.meta["files"] = {
        "imu": str(d / base / "IMU"), "gnss": str(d / base / "GNSS/live_gnss_ublox"),
        "velocity": str(d / base / "CAN/speed"), "heading": str(d / base / "IMU/magnetometer"),
    }
    a_t = _load(d, base + "IMU/accelerometer/t")
    acc = _load(d, base + "IMU/accelerometer/value")
    g_t = _load(d, base + "IMU/gyro/t")
    gyr = _load(d, base + "IMU/gyro/value")
    if acc.ndim != 2 or acc.shape[1] != 3 or gyr.ndim != 2 or gyr.shape[1] != 3:
        raise InputError(f"{d}: accelerometer and gyro values must be (n, 3) arrays")
    if acc.shape[0] != a_t.shape[0] or gyr.shape[0] != g_t.shape[0]:
        raise InputError(f"{d}: an IMU signal has a different number of times and values")
    if g_t.shape != a_t.shape or not np.allclose(g_t, a_t):
        gyr = np.column_stack([np.interp(a_t, g_t, gyr[:, k]) for k in range(3)])
        drive.warnings.append(f"{d}: gyro resampled onto the accelerometer time stamps")
    drive.imu = ImuStream(t=a_t, accel=frd_to_flu(acc), gyro=frd_to_flu(gyr),
                          input_units={"gyro": "rad/s", "accel": "m/s^2"})
    gn_t = _load(d, base + "GNSS/live_gnss_ublox/t")
    gn = _load(d, base + "GNSS/live_gnss_ublox/value")
    if gn.ndim != 2 or gn.shape[1] < 5 or gn.shape[0] != gn_t.shape[0]:
        raise InputError(
            f"{d}: live_gnss_ublox/value must have columns lat, lon, speed, utc, alt[, bearing]"
        )
    lat, lon = gn[:, 0], gn[:, 1]
    bearing = gn[:, 5] if gn.shape[1] > 5 else None
    drive.gnss = GnssStream(
        t=gn_t, lat_deg=lat, lon_deg=lon, alt_m=gn[:, 4],
        fix=np.isfinite(lat) & np.isfinite(lon) & (np.abs(lat) + np.abs(lon) > 0),
        speed_mps=gn[:, 2] if bearing is not None else None,
        course_rad=None if bearing is None else np.mod(np.radians(bearing), 2 * math.pi),
    )
    drive.warnings.append(f"{d}: u-blox fixes carry no HDOP or accuracy; the defaults are used")
    if (d / base / "CAN/speed/t").is_file():
        st = _load(d, base + "CAN/speed/t")
        sv = _load(d, base + "CAN/speed/value").reshape(st.shape[0], -1)[:, 0]
        drive.velocity = VelocityStream(t=st, u_mps=sv, kind="can")
    if (d / base / "IMU/magnetometer/t").is_file():
        mt = _load(d, base + "IMU/magnetometer/t")
        mv = _load(d, base + "IMU/magnetometer/value")
        drive.mag = MagStream(t=mt, mag=frd_to_flu(mv) * 1e-6, unit="T")  # uT -> T
    gp = d / "global_pose"
    if gp.is_dir():
        assert drive.gnss.fix is not None
        ok = np.flatnonzero(drive.gnss.fix)
        if ok.size == 0:
            raise InputError(f"{d}: no u-blox fix: no origin for the truth")
        origin = (float(lat[ok[0]]), float(lon[ok[0]]), float(gn[ok[0], 4]))
        drive.truth = _comma_truth(d, origin)
    else:
        drive.warnings.append(f"{d}: no global_pose/ folder: no ground truth")
    apply_mount(drive)
    warn_mount(drive)
    return drive


def _comma_truth(d: Path, origin: tuple[float, float, float]) -> Truth:
    from scipy.spatial.transform import Rotation

    from imubounds.geodesy import ecef_to_enu

    ft = _load(d, "global_pose/frame_times")
    pos = _load(d, "global_pose/frame_positions")
    vel = _load(d, "global_pose/frame_velocities")
    quat = _load(d, "global_pose/frame_orientations")
    c_eb = Rotation.from_quat(quat[:, [1, 2, 3, 0]]).as_matrix()  # FRD body -> ECEF
    lat0, lon0 = math.radians(origin[0]), math.radians(origin[1])
    sl, cl, so, co = math.sin(lat0), math.cos(lat0), math.sin(lon0), math.cos(lon0)
    c_ne = np.array([[-so, co, 0.0], [-sl * co, -sl * so, cl], [cl * co, cl * so, sl]])
    c_nb = c_ne @ c_eb @ np.diag([1.0, -1.0, -1.0])  # FLU body -> ENU
    roll, pitch, heading = matrix_to_rpy(c_nb)
    e, n, u = ecef_to_enu(pos[:, 0], pos[:, 1], pos[:, 2], origin)
    vb = np.einsum("nji,nj->ni", c_eb, vel) * np.array([1.0, -1.0, -1.0])  # body FLU
    psi = np.unwrap(0.5 * math.pi - heading)
    r = np.gradient(psi, ft)
    return Truth(
        t=ft, east_m=np.asarray(e), north_m=np.asarray(n), origin=origin,
        heading_rad=heading, u_mps=vb[:, 0], v_mps=vb[:, 1],
        extra={
            "up_m": np.asarray(u), "w_mps": vb[:, 2], "roll_rad": roll, "pitch_rad": pitch,
            "r": r, "accel_x": np.gradient(vb[:, 0], ft) - r * vb[:, 1],
            "accel_y": np.gradient(vb[:, 1], ft) + r * vb[:, 0],
        },
    )


# ----------------------------------------------------------------------------- CSV maps

_TIME_TARGETS = {"time_s": 1.0, "time_ms": 1e-3, "time_us": 1e-6, "time_ns": 1e-9}


def parse_drive_columns(text: str) -> dict[str, str]:
    """``"time_s=stamp,gyro_z_dps=yaw_rate,lat_deg=Lat"`` -> {layout column: source column}.

    Keys are the layout's column names (``gyro_x_dps``, ``lat_deg``,
    ``u_mps``, ``heading_deg``, ``mag_x_uT``, ``roll_deg`` ...; ``time_s``,
    ``time_ms``, ``time_us`` or ``time_ns`` for the time), optionally with the
    table in front (``truth.u_mps``); values are the source columns.
    """
    if not text or not text.strip():
        raise OptionError("--columns is empty; give e.g. --columns time_s=stamp,lat_deg=Lat")
    out: dict[str, str] = {}
    for item in text.split(","):
        item = item.strip()
        if not item or "=" not in item:
            raise OptionError(
                f"--columns item {item!r}: write LAYOUT_COLUMN=SOURCE_COLUMN, e.g. lat_deg=Lat"
            )
        key, _, src = (x.strip() for x in item.partition("="))
        if not src:
            raise OptionError(f"--columns item {item!r} names no source column after '='")
        _table_of(key, option=True)
        if key in out:
            raise OptionError(f"--columns gives {key} twice; give each key once")
        out[key] = src
    return out


def _table_of(key: str, option: bool = False) -> str | None:
    """The layout table a (possibly ``table.``-prefixed) column belongs to, None for time."""
    table, dot, col = key.partition(".")
    if not dot:
        table, col = "", key
    if col in _TIME_TARGETS:
        return None
    cands = [t for t in FILES if any(
        col.lower().startswith(p[:-1]) if p.endswith("*") else col == p
        for p in TABLE_COLUMNS[t])]
    if table:
        if table not in FILES or table not in cands:
            if option:
                raise OptionError(f"--columns key {key!r}: {col!r} is not a column of {table!r}")
            return None
        return table
    cands = [t for t in cands if t != "truth"]
    if not cands:
        if option:
            raise OptionError(
                f"--columns key {key!r} is not a drive-layout column; use names like time_s, "
                "gyro_z_dps, accel_x_mps2, lat_deg, lon_deg, speed_mps, u_mps, heading_deg, "
                "mag_x_uT, roll_deg (see docs/drive-layout.md)"
            )
        return None
    return cands[0]


def _read_any_table(p: Path) -> pd.DataFrame:
    try:
        if p.name.lower().endswith(".parquet"):
            df = pd.read_parquet(p)
        else:
            df = pd.read_csv(p, sep=None, engine="python", comment="#")
    except (OSError, ValueError, ImportError, pd.errors.ParserError) as err:
        first = (str(err).splitlines() or [type(err).__name__])[0]
        raise InputError(f"{p}: cannot read as a table ({first})") from err
    df.columns = [str(c).strip() for c in df.columns]
    if df.shape[0] == 0:
        raise InputError(f"{p}: no data rows (only a header)")
    return df


def read_mapped_csv(
    paths: Sequence[Path], columns: Mapping[str, str] | None, settings: DriveSettings
) -> Drive:
    """CSV/Parquet logs of other tools -> :class:`Drive` through a column map.

    Columns already named as in the layout are used as they are; ``columns``
    maps further ones (``{layout column: source column}``). Each file needs a
    time column; a wide log whose rows mix sensors (GNSS columns empty between
    fixes) is split by table, each keeping the rows that carry its values.
    """
    cmap = dict(columns or {})
    tables: dict[str, tuple[pd.DataFrame, str]] = {}
    used: set[str] = set()
    for p in paths:
        check_input_path(p, what="CSV log")
        df = _read_any_table(p)
        rename = {src: key for key, src in cmap.items() if src in df.columns}
        used |= set(rename.values())
        mapped = df.rename(columns=rename)
        tcols = [c for c in mapped.columns if c.partition(".")[2] in _TIME_TARGETS
                 or c in _TIME_TARGETS]
        if not tcols:
            raise InputError(
                f"{p}: no time column; map one with --columns time_s=SOURCE (or time_ms, "
                f"time_us, time_ns); columns are {', '.join(df.columns[:12])}"
            )
        if len(tcols) > 1:
            raise InputError(f"{p}: several time columns ({', '.join(tcols)}); map one")
        tkey = tcols[0].rpartition(".")[2]
        tvals = pd.to_numeric(mapped[tcols[0]], errors="coerce")
        if tvals.isna().any():
            i = int(np.flatnonzero(tvals.isna().to_numpy())[0])
            raise InputError(
                f"{p}: time column {tcols[0]!r}, data row {i + 1}: "
                f"{mapped[tcols[0]].iloc[i]!r} is not a number"
            )
        by_table: dict[str, list[str]] = {}
        for c in mapped.columns:
            if c in tcols:
                continue
            t = _table_of(c)
            if t is not None:
                by_table.setdefault(t, []).append(c)
        for t, cols in by_table.items():
            if t in tables:
                raise InputError(
                    f"{p}: {t} columns also in {tables[t][1]}; give each sensor in one file"
                )
            sub = mapped[cols].copy()
            sub.columns = [c.partition(".")[2] if "." in c else c for c in cols]
            sub.insert(0, "time_s", tvals.to_numpy(float) * _TIME_TARGETS[tkey])
            tables[t] = (sub, str(p))
    unused = sorted(set(cmap) - used)
    if unused:
        raise InputError(
            f"--columns: source column(s) {', '.join(repr(cmap[k]) for k in unused)} not found "
            f"in {', '.join(map(str, paths))}"
        )
    if "imu" not in tables:
        raise InputError(
            f"{', '.join(map(str, paths))}: no IMU columns; map them with --columns, e.g. "
            "time_s=stamp,gyro_x_dps=wx,...,accel_z_g=az (layout names: docs/drive-layout.md)"
        )
    return drive_from_tables(tables, settings, source=", ".join(map(str, paths)), layout="csv",
                             wide=True)


# ----------------------------------------------------------------------------- entry point


def read_drive(
    paths: Sequence[str | Path] | str | Path,
    *,
    settings: DriveSettings | str | Path | None = None,
    imu_axes: Sequence[str] | None = None,
    mount: str = "auto",
    topics: Mapping[str, str] | None = None,
    columns: Mapping[str, str] | None = None,
    imu_frame: str = "FLU",
    date_utc: str | None = None,
    time_offset_s: float = 0.0,
    on_bad_checksum: str = "error",
    max_speed_mps: float | None = None,
    validate: bool = True,
) -> Drive:
    """Read a drive log from any supported input into a validated :class:`Drive`.

    Parameters
    ----------
    paths:
        A directory (drive layout, VN-100, comma2k19, ROS 2 bag, the old
        simulator output) or files (a bag, MCAP, ULog, NMEA capture [+ IMU
        log], the two VN-100 CSVs, CSV logs with ``columns``).
    settings:
        A ``drive.yaml`` path or :class:`DriveSettings`; replaces the layout's
        own ``drive.yaml``; for other formats it gives the bounds they lack.
    imu_axes:
        The mount (body axes as signed sensor axes, e.g. ``["x", "-z", "y"]``),
        overriding the settings; applied to the IMU and magnetometer before
        anything else, after the format's own axes were converted to FLU.
    mount:
        VN-100 only: ``"auto"``, ``"forward"`` or ``"backward"``.
    topics:
        ROS bags: ``{"imu"|"gnss"|"mag"|"heading"|"velocity"|"gnss_velocity"|
        "attitude": topic}``; by default the busiest topic of each type.
    columns:
        CSV logs: ``{layout column: source column}`` (:func:`parse_drive_columns`).
    imu_frame, date_utc, time_offset_s, on_bad_checksum:
        NMEA captures (:func:`imubounds.io.nmea.read_drive_nmea`).
    max_speed_mps:
        Speeds beyond it are dropped and counted (default
        ``vehicle.max_speed_mps`` of the settings).
    validate:
        Run :func:`~imubounds.io.drive.validate.validate_drive` (default).
    """
    if isinstance(paths, str | os.PathLike):
        ps: list[str | Path] = [paths]
    elif isinstance(paths, list | tuple) and paths and all(
        isinstance(p, str | os.PathLike) for p in paths
    ):
        ps = list(paths)
    else:
        raise InputError(
            "read_drive takes a path (str or Path) or a list of paths, got "
            f"{type(paths).__name__} {paths!r:.40}"
        )
    layout, files = detect_layout(ps)
    if layout == "generic":
        d = files["dir"]
        if settings is None:
            s, info = read_settings_with_info(d)
        else:
            s, info = _settings(settings, str(d / SETTINGS_FILE))
        _override_axes(s, imu_axes)
        drive = read_layout(d, s)
        if info.get("notes"):
            drive.notes[:0] = [str(n) for n in info["notes"]]
        if info.get("converted_from"):
            drive.meta["converted_from"] = str(info["converted_from"])
    else:
        where = f"{ps[0]}" if len(ps) == 1 else ", ".join(map(str, ps))
        own = Path(ps[0]) / SETTINGS_FILE if len(ps) == 1 else None
        if settings is None and own is not None and own.is_file():
            # a drive.yaml beside a VN-100 pair, in a comma2k19 segment or a bag folder
            # is the user's, as in the drive layout
            settings = own
        s, info = _settings(settings, f"settings of {where}")
        _override_axes(s, imu_axes)
        if layout == "vn100":
            drive = read_vn100(files["imu"], files["gps"], s, mount=mount)
        elif layout == "comma2k19":
            drive = read_comma2k19(files["dir"], s)
        elif layout in ("rosbag", "ulog", "nmea"):  # formats that register a drive reader
            options = {"topics": topics, "imu_frame": imu_frame, "date_utc": date_utc,
                       "time_offset_s": time_offset_s, "on_bad_checksum": on_bad_checksum}
            drive = reader_entry(layout).load_drive()(files, s, options)
        else:
            drive = read_mapped_csv(files["paths"], columns, s)
        _settings_from_streams(drive)
        if info.get("notes"):
            drive.notes[:0] = [str(n) for n in info["notes"]]
    if columns and layout != "csv":
        raise OptionError("--columns applies to CSV logs only")
    if validate:
        validate_drive(drive, max_speed_mps=max_speed_mps)
    release_freed_memory()
    return drive



def _settings_from_streams(drive: Drive) -> None:
    """What a reader knows about its heading stream goes into the settings (unless the
    user's drive.yaml said otherwise), so that a converted drive.yaml says it too."""
    h = drive.heading
    if h is None:
        return
    where = f"the {drive.layout} reader"
    sensor = h.source if h.source in ("compass", "gnss", "ahrs") else "compass"
    if sensor != "compass":
        _given(drive.settings, "heading.sensor", sensor, where)
    if h.true_north:
        _given(drive.settings, "heading.reference", "true", where)


def bundled_drive_log() -> Path:
    """Directory of the bundled VN-100 + BU-353N drive log (demo data, MIT licence)."""
    from importlib import resources

    path = Path(str(resources.files("imubounds") / "data" / "vn100_bu353_circle"))
    if not (path / "circle_data_0_imu.csv").is_file():
        raise InputError(f"the bundled drive log {path} is missing; reinstall imubounds")
    return path
