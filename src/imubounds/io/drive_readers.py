"""Readers of multi-sensor drive logs -> :class:`imubounds.io.drive_legacy.DriveLog`.

Layouts recognised by :func:`read_drive` (see :func:`detect_layout`):

``sim``
    A directory written by ``imubounds simulate``: ``scenario.json`` with the
    generic drive layout (``drive.yaml``, ``imu.csv``, ``gnss.csv``,
    ``heading.csv``, ``truth.csv``; read by
    :func:`imubounds.io.drive_layout.read_layout`), or the older layout:
    ``imu.csv`` (t, accel_x..z, gyro_x..z; FLU, SI), ``gps.csv`` (t, lat, lon,
    alt, hdop, fix), ``compass.csv`` (t, heading_deg clockwise from north),
    optional ``truth.csv`` (t, lat, lon, east, north, psi, u, v, accel_x,
    accel_y, r).
``vn100``
    The VN-100 + BU-353N layout: ``*_imu.csv`` (t Unix s, gyro_* rad/s,
    acc_* m/s^2, mag_* T, raw ``$VNYMR`` with yaw/pitch/roll in degrees; FRD
    axes) and ``*_gps.csv`` (t, latitude, longitude, altitude, hdop, raw
    ``$GPGGA``). A directory holding both, or the two files.
``comma2k19``
    A comma2k19 segment directory: ``processed_log/IMU/{accelerometer,gyro,
    magnetometer}``, ``processed_log/GNSS/live_gnss_ublox`` and
    ``global_pose`` (ground truth, ECEF), numpy arrays without extension.

What was verified against the data (the sign conventions):

* VN-100: axes are FRD (``acc_z`` ≈ -9.8 at rest, the VNYMR yaw rate equals
  +``gyro_z`` so yaw is clockwise). In ``vn100_bu353_circle`` the yaw is
  about 180° from the GPS course over ground and the lateral acceleration
  points out of the turn in sensor axes: the unit is mounted facing
  backwards. The reader detects this (median |yaw - course| > 90°), rotates
  the body axes by 180° about z and says so in ``warnings``.
* comma2k19: ``frame_orientations`` are (w, x, y, z) quaternions of an FRD
  body frame in ECEF (the body x axis carries the velocity, body z points
  down); the phone IMU axes agree with it (``gyro_z`` ≈ -yaw rate,
  ``accel_x`` correlates with the forward acceleration, ``accel_z`` ≈ -9.7).
  The u-blox bearing is degrees clockwise from north (agrees with the
  truth's course to ~1°). There is no HDOP: fixes use the default HDOP.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pandas as pd

from imubounds.errors import InputError
from imubounds.frames import frd_to_flu
from imubounds.io.drive_legacy import DriveLog


def detect_layout(paths: list[str]) -> tuple[str, dict[str, Path]]:
    """Work out which layout ``paths`` (a directory or files) is; return (layout, files)."""
    if not paths:
        raise InputError(
            "no drive log given: pass a simulator directory, a VN-100 directory or "
            "its two CSV files, or a comma2k19 segment directory"
        )
    ps = [Path(p) for p in paths]
    for p in ps:
        if not p.exists():
            raise InputError(f"{p}: no such file or directory")
    if len(ps) == 1 and ps[0].is_file():
        suffix = ps[0].suffix.lower()
        if suffix in (".bag", ".mcap", ".db3"):
            return "rosbag", {"path": ps[0]}
        if suffix == ".ulg":
            return "ulog", {"path": ps[0]}
    if len(ps) == 1 and ps[0].is_dir() and (ps[0] / "metadata.yaml").is_file():
        return "rosbag", {"path": ps[0]}
    if len(ps) == 2 and all(p.is_file() for p in ps):
        nmea = [p for p in ps if p.suffix.lower() in (".nmea", ".nma")]
        if len(nmea) == 1:
            other = ps[1] if ps[0] == nmea[0] else ps[0]
            return "nmea", {"nmea": nmea[0], "imu": other}
    if len(ps) == 1 and ps[0].is_dir():
        d = ps[0]
        if (d / "scenario.json").is_file() and (d / "imu.csv").is_file():
            return "sim", {"dir": d}
        if (d / "processed_log").is_dir() and (d / "global_pose").is_dir():
            return "comma2k19", {"dir": d}
        if (d / "processed_log").is_dir():
            return "comma2k19", {"dir": d}
        imu = sorted(d.glob("*_imu.csv"))
        gps = sorted(d.glob("*_gps.csv"))
        if len(imu) == 1 and len(gps) == 1:
            return "vn100", {"imu": imu[0], "gps": gps[0]}
        raise InputError(
            f"{d}: not a known drive-log directory (expected scenario.json+imu.csv, "
            "processed_log/ and global_pose/, or one *_imu.csv with one *_gps.csv)"
        )
    if all(p.is_file() for p in ps) and len(ps) == 2:
        imu = [p for p in ps if p.name.endswith("_imu.csv")]
        gps = [p for p in ps if p.name.endswith("_gps.csv")]
        if len(imu) == 1 and len(gps) == 1:
            return "vn100", {"imu": imu[0], "gps": gps[0]}
    raise InputError(
        f"{' '.join(map(str, ps))}: give one log directory, a ROS bag / MCAP / ULog file, "
        "the two VN-100 files (*_imu.csv and *_gps.csv), or an .nmea file with an IMU log"
    )


def _need(df: pd.DataFrame, cols: list[str], path: Path) -> None:
    missing = [c for c in cols if c not in df.columns]
    if missing:
        raise InputError(f"{path}: missing column(s) {', '.join(missing)}")


def _numeric(df: pd.DataFrame, col: str, path: Path) -> np.ndarray:
    vals = pd.to_numeric(df[col], errors="coerce").to_numpy(float)
    return vals


def _read_csv(path: Path) -> pd.DataFrame:
    try:
        return pd.read_csv(path, comment=None)
    except (OSError, ValueError, pd.errors.ParserError) as err:
        raise InputError(f"{path}: cannot read CSV ({err})") from err


def read_sim(d: Path) -> DriveLog:
    """Read a simulator output directory (the generic drive layout with ``scenario.json``,
    or the older layout with ``gps.csv`` and ``compass.csv``)."""
    try:
        settings = json.loads((d / "scenario.json").read_text())
    except (OSError, ValueError) as err:
        raise InputError(f"{d / 'scenario.json'}: cannot read ({err})") from err
    if (d / "drive.yaml").is_file():
        return _sim_layout_to_log(d, settings)
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
        truth = {c: tr[c].to_numpy(float) for c in tr.columns}
    return DriveLog(
        imu_t=imu["t"].to_numpy(float),
        accel=imu[["accel_x", "accel_y", "accel_z"]].to_numpy(float),
        gyro=imu[["gyro_x", "gyro_y", "gyro_z"]].to_numpy(float),
        gps_t=gps["t"].to_numpy(float),
        lat=_numeric(gps, "lat", d / "gps.csv"),
        lon=_numeric(gps, "lon", d / "gps.csv"),
        alt=_numeric(gps, "alt", d / "gps.csv"),
        hdop=_numeric(gps, "hdop", d / "gps.csv"),
        fix=gps["fix"].to_numpy().astype(bool),
        heading_t=comp["t"].to_numpy(float),
        heading=np.radians(comp["heading_deg"].to_numpy(float)),
        truth=truth,
        source=str(d),
        layout="sim",
        settings=settings,
    )


def _sim_layout_to_log(d: Path, settings: dict[str, object]) -> DriveLog:
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


def _nmea_field(raw: pd.Series, index: int) -> np.ndarray:
    parts = raw.astype(str).str.strip().str.split(",")
    return pd.to_numeric(parts.str[index], errors="coerce").to_numpy(float)


def read_vn100(imu_path: Path, gps_path: Path, mount: str = "auto") -> DriveLog:
    """Read the VN-100 IMU CSV and BU-353N GPS CSV.

    Parameters
    ----------
    mount:
        ``"auto"`` (detect a backwards-mounted unit from yaw vs GPS course),
        ``"forward"`` or ``"backward"`` (rotate the body axes 180° about z).
    """
    imu = _read_csv(imu_path)
    _need(imu, ["t", "gyro_x", "gyro_y", "gyro_z", "acc_x", "acc_y", "acc_z"], imu_path)
    gps = _read_csv(gps_path)
    _need(gps, ["t", "latitude", "longitude", "altitude"], gps_path)
    warnings: list[str] = []
    t = _numeric(imu, "t", imu_path)
    accel = frd_to_flu(imu[["acc_x", "acc_y", "acc_z"]].to_numpy(float))
    gyro = frd_to_flu(imu[["gyro_x", "gyro_y", "gyro_z"]].to_numpy(float))
    mag = None
    if all(c in imu.columns for c in ("mag_x", "mag_y", "mag_z")):
        mag = frd_to_flu(imu[["mag_x", "mag_y", "mag_z"]].to_numpy(float))
    heading = None
    if "raw_vnymr" in imu.columns:
        yaw_deg = _nmea_field(imu["raw_vnymr"], 1)
        if np.any(np.isfinite(yaw_deg)):
            heading = np.radians(yaw_deg) % (2 * math.pi)
    hdop = _numeric(gps, "hdop", gps_path) if "hdop" in gps.columns else None
    fixq = None
    if "raw_gpgga" in gps.columns:
        fixq = _nmea_field(gps["raw_gpgga"], 6)
        if hdop is None:
            hdop = _nmea_field(gps["raw_gpgga"], 8)
    g_t = _numeric(gps, "t", gps_path)
    lat = _numeric(gps, "latitude", gps_path)
    lon = _numeric(gps, "longitude", gps_path)
    fix = np.isfinite(lat) & np.isfinite(lon)
    if fixq is not None:
        fix &= ~(np.isfinite(fixq) & (fixq == 0))
    if hdop is None:
        hdop = np.full(g_t.shape, np.nan)
        warnings.append(f"{gps_path}: no HDOP column; the default HDOP is used for every fix")
    log = DriveLog(
        imu_t=t,
        accel=accel,
        gyro=gyro,
        gps_t=g_t,
        lat=lat,
        lon=lon,
        alt=_numeric(gps, "altitude", gps_path),
        hdop=hdop,
        fix=fix,
        heading_t=t if heading is not None else None,
        heading=heading,
        mag_t=t if mag is not None else None,
        mag=mag,
        source=f"{imu_path.parent}",
        layout="vn100",
        warnings=warnings,
        settings={"heading_source": "vnymr-yaw" if heading is not None else "magnetometer"},
    )
    if mount not in ("auto", "forward", "backward"):
        raise InputError(f"--mount must be auto, forward or backward, got {mount!r}")
    if mount == "auto" and heading is not None:
        mount = _detect_backwards(log)
    if mount == "backward":
        _rotate_180(log)
        log.warnings.append(
            f"{imu_path}: the VN-100 yaw is ~180° from the GPS course over ground; the unit is "
            "mounted backwards: body axes rotated 180° about z (use --mount forward to disable)"
        )
    log.settings["mount"] = mount if mount != "auto" else "forward"
    return log


def _detect_backwards(log: DriveLog) -> str:
    from imubounds.dynamic.aiding.compass import course_over_ground
    from imubounds.dynamic.aiding.geodesy import geodetic_to_enu
    from imubounds.frames import wrap_pi

    good = log.fix & np.isfinite(log.lat)
    if good.sum() < 3 or log.heading is None or log.heading_t is None:
        return "forward"
    e, n, _ = geodetic_to_enu(log.lat[good], log.lon[good])
    tm, cog = course_over_ground(log.gps_t[good], e, n, min_speed=2.0)
    if tm.size < 3:
        return "forward"
    yaw = np.interp(tm, log.heading_t, np.unwrap(log.heading))
    diff = np.abs(np.asarray(wrap_pi(yaw - cog)))
    return "backward" if np.median(diff) > math.pi / 2 else "forward"


def _rotate_180(log: DriveLog) -> None:
    flip = np.array([-1.0, -1.0, 1.0])
    log.accel = log.accel * flip
    log.gyro = log.gyro * flip
    if log.mag is not None:
        log.mag = log.mag * flip
    if log.heading is not None:
        log.heading = (log.heading + math.pi) % (2 * math.pi)


def _load(d: Path, rel: str) -> np.ndarray:
    p = d / rel
    try:
        with open(p, "rb") as fh:
            return np.load(fh, allow_pickle=False)
    except (OSError, ValueError) as err:
        raise InputError(f"{p}: cannot load numpy array ({err})") from err


def read_comma2k19(d: Path) -> DriveLog:
    """Read a comma2k19 segment directory (phone IMU, u-blox GNSS, magnetometer, pose truth)."""
    import pymap3d
    from scipy.spatial.transform import Rotation

    warnings: list[str] = []
    a_t = _load(d, "processed_log/IMU/accelerometer/t")
    acc = _load(d, "processed_log/IMU/accelerometer/value")
    g_t = _load(d, "processed_log/IMU/gyro/t")
    gyr = _load(d, "processed_log/IMU/gyro/value")
    if acc.ndim != 2 or acc.shape[1] != 3 or gyr.ndim != 2 or gyr.shape[1] != 3:
        raise InputError(f"{d}: accelerometer and gyro values must be (n, 3) arrays")
    if g_t.shape != a_t.shape or not np.allclose(g_t, a_t):
        gyr = np.column_stack([np.interp(a_t, g_t, gyr[:, k]) for k in range(3)])
        warnings.append(f"{d}: gyro resampled onto the accelerometer time stamps")
    gn_t = _load(d, "processed_log/GNSS/live_gnss_ublox/t")
    gn = _load(d, "processed_log/GNSS/live_gnss_ublox/value")
    if gn.ndim != 2 or gn.shape[1] < 5:
        raise InputError(f"{d}: live_gnss_ublox/value must have columns lat, lon, speed, utc, alt")
    mag_t = mag = None
    if (d / "processed_log/IMU/magnetometer/t").is_file():
        mag_t = _load(d, "processed_log/IMU/magnetometer/t")
        mag = frd_to_flu(_load(d, "processed_log/IMU/magnetometer/value"))
    lat, lon, alt = gn[:, 0], gn[:, 1], gn[:, 4]
    fix = np.isfinite(lat) & np.isfinite(lon) & (np.abs(lat) > 0)
    truth = None
    origin = None
    gp = d / "global_pose"
    if gp.is_dir():
        ft = _load(d, "global_pose/frame_times")
        pos = _load(d, "global_pose/frame_positions")
        vel = _load(d, "global_pose/frame_velocities")
        quat = _load(d, "global_pose/frame_orientations")
        rot = Rotation.from_quat(quat[:, [1, 2, 3, 0]])  # stored as (w, x, y, z)
        tl, tn, th = pymap3d.ecef2geodetic(pos[:, 0], pos[:, 1], pos[:, 2])
        ok = np.flatnonzero(fix)
        origin = (float(lat[ok[0]]), float(lon[ok[0]]), float(alt[ok[0]]))
        xb = rot.apply([1.0, 0.0, 0.0])
        e, n, _ = pymap3d.ecef2enuv(xb[:, 0], xb[:, 1], xb[:, 2], origin[0], origin[1])
        psi = np.unwrap(np.arctan2(n, e))
        vb = frd_to_flu(rot.inv().apply(vel))
        u, v = vb[:, 0], vb[:, 1]
        r = np.gradient(psi, ft)
        truth = {
            "t": ft,
            "lat": np.asarray(tl),
            "lon": np.asarray(tn),
            "alt": np.asarray(th),
            "psi": psi,
            "u": u,
            "v": v,
            "r": r,
            "accel_x": np.gradient(u, ft) - r * v,
            "accel_y": np.gradient(v, ft) + r * u,
        }
    else:
        warnings.append(f"{d}: no global_pose/ folder: no ground truth")
    heading_t = heading = None  # no compass: the magnetometer gives the heading
    if mag is None:
        raise InputError(f"{d}: no processed_log/IMU/magnetometer: no heading source")
    return DriveLog(
        imu_t=a_t,
        accel=frd_to_flu(acc),
        gyro=frd_to_flu(gyr),
        gps_t=gn_t,
        lat=lat,
        lon=lon,
        alt=alt,
        hdop=np.full(gn_t.shape, np.nan),
        fix=fix,
        heading_t=heading_t,
        heading=heading,
        mag_t=mag_t,
        mag=mag,
        truth=truth,
        truth_origin=origin,
        source=str(d),
        layout="comma2k19",
        warnings=warnings + [f"{d}: u-blox fixes carry no HDOP; the default HDOP is used"],
        settings={"heading_source": "magnetometer"},
    )


def read_drive(paths: list[str] | str, mount: str = "auto") -> DriveLog:
    """Read a drive log from any supported layout and validate it."""
    if isinstance(paths, str):
        paths = [paths]
    layout, files = detect_layout(list(paths))
    if layout == "sim":
        log = read_sim(files["dir"])
    elif layout == "vn100":
        log = read_vn100(files["imu"], files["gps"], mount=mount)
    elif layout == "rosbag":
        from imubounds.io.rosbag import read_drive_rosbag

        log = read_drive_rosbag(files["path"])
    elif layout == "ulog":
        from imubounds.io.ulog import read_drive_ulog

        log = read_drive_ulog(files["path"])
    elif layout == "nmea":
        from imubounds.io.nmea import read_drive_nmea

        log = read_drive_nmea(files["nmea"], files["imu"])
    else:
        log = read_comma2k19(files["dir"])
    log.validate()
    return log


def bundled_drive_log() -> Path:
    """Directory of the bundled VN-100 + BU-353N drive log (demo data, MIT licence)."""
    from importlib import resources

    path = Path(str(resources.files("imubounds") / "data" / "vn100_bu353_circle"))
    if not (path / "circle_data_0_imu.csv").is_file():
        raise InputError(f"the bundled drive log {path} is missing; reinstall imubounds")
    return path
