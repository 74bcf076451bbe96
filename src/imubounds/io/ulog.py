"""PX4 ULog files via ``pyulog``.

Only the topics needed are decoded (``pyulog``'s message filter), so a large
flight log costs the memory of its IMU topic, not of the whole file.

IMU topics, in order of preference (or by option ``topic``):

``sensor_combined``
    ``gyro_rad[3]`` (rad/s) and ``accelerometer_m_s2[3]`` (m/s^2) at
    ``timestamp`` (µs).
``vehicle_imu``
    ``delta_angle[3]`` (rad) over ``delta_angle_dt`` (µs) and
    ``delta_velocity[3]`` (m/s) over ``delta_velocity_dt`` (µs); rates are
    delta / dt.

Frames: PX4 body axes are **FRD** (x forward, y right, z down) and the local
frame is NED. The readers convert explicitly to the log model's FLU body
frame: (x, y, z)_FLU = (x, −y, −z)_FRD. A NED yaw (``vehicle_attitude``
quaternion) is already a heading clockwise from north.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from imubounds.errors import ImuboundsError, InputError
from imubounds.frames import FRD_TO_FLU, ned_quaternion_to_rpy
from imubounds.io.drive import (
    AttitudeStream,
    Drive,
    DriveSettings,
    GnssStream,
    HeadingStream,
    ImuStream,
    MagStream,
)
from imubounds.io.log import ImuLog

from .assemble import RawChannel, RawTime, ReadOptions, assemble_logs

IMU_TOPICS = ("sensor_combined", "vehicle_imu")


def truncation_note(path: Path) -> str | None:
    """A warning if the ULog ends inside a message (a cut or truncated file), else ``None``.

    Walks the message headers (2-byte size, 1-byte type) from the end of the
    16-byte file header; the last message must end exactly at the end of the file.
    """
    import mmap
    import struct

    try:
        with open(path, "rb") as f, mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ) as m:
            size = len(m)
            pos = 16
            unpack = struct.Struct("<H").unpack_from
            while pos + 3 <= size:
                pos += 3 + unpack(m, pos)[0]
    except (OSError, ValueError):
        return None
    if pos == size or size <= 16:
        return None
    return (
        f"{path}: the ULog is truncated (it ends inside a message, {size} bytes); the "
        "samples before the cut are used: copy the log again if the end matters"
    )


def _load(path: Path, topics: list[str]) -> Any:
    import contextlib
    import io

    from pyulog import ULog

    try:
        # pyulog prints diagnostics on stdout; the library prints nothing
        with contextlib.redirect_stdout(io.StringIO()):
            ulog = ULog(str(path), message_name_filter_list=topics)
    except ImuboundsError:
        raise
    except Exception as err:  # pyulog raises bare exceptions / struct errors on bad files
        text = " ".join(str(err).split())[:160] or type(err).__name__
        raise InputError(
            f"{path}: not a readable ULog file ({type(err).__name__}: {text}); "
            "check that it is a PX4 .ulg log and not truncated"
        ) from err
    return ulog


def _topic_names(path: Path) -> list[str]:
    import contextlib
    import io

    from pyulog import ULog

    try:
        with contextlib.redirect_stdout(io.StringIO()):
            ulog = ULog(str(path), parse_header_only=True)
    except Exception:  # noqa: BLE001 - only used to list topics in an error message
        return []
    return sorted({f.name for f in ulog.message_formats.values()}) if hasattr(
        ulog, "message_formats"
    ) else []


def _dataset(ulog: Any, name: str) -> Any | None:
    for d in ulog.data_list:
        if d.name == name and d.multi_id == 0:
            return d
    for d in ulog.data_list:
        if d.name == name:
            return d
    return None


def _field(path: Path, ds: Any, name: str) -> np.ndarray:
    if name not in ds.data:
        raise InputError(
            f"{path}: topic {ds.name!r} has no field {name!r}; fields are "
            f"{', '.join(sorted(ds.data))}"
        )
    return np.asarray(ds.data[name])


def read_ulog(path: Path, opts: ReadOptions) -> list[ImuLog]:
    """Read the IMU of a PX4 ULog into SI :class:`ImuLog` segment(s), FLU body frame.

    Parameters
    ----------
    path:
        ``.ulg`` file.
    opts:
        Reader options; ``opts.extra["topic"]`` is ``sensor_combined`` or
        ``vehicle_imu`` (default: the first of them present).
    """
    wanted = opts.extra.get("topic")
    if wanted is not None and wanted not in IMU_TOPICS:
        raise InputError(f"{path}: --topic {wanted!r} is not an IMU topic; use one of "
                         f"{', '.join(IMU_TOPICS)}")
    topics = [str(wanted)] if wanted is not None else list(IMU_TOPICS)
    ulog = _load(path, topics)
    ds = None
    for name in topics:
        ds = _dataset(ulog, name)
        if ds is not None:
            break
    if ds is None:
        have = _topic_names(path)
        cut = " (the file is truncated)" if truncation_note(path) else ""
        raise InputError(
            f"{path}: no IMU topic ({' or '.join(topics)}) in the ULog{cut}; it holds "
            f"{', '.join(have) if have else 'no logged topics'}; log sensor_combined in PX4 "
            "(SDLOG_PROFILE) or give --topic"
        )
    t_us = _field(path, ds, "timestamp").astype(np.int64)
    if ds.name == "sensor_combined":
        gyro = np.column_stack([_field(path, ds, f"gyro_rad[{k}]") for k in range(3)])
        acc = np.column_stack([_field(path, ds, f"accelerometer_m_s2[{k}]") for k in range(3)])
        src_g, src_a = "gyro_rad", "accelerometer_m_s2"
    else:
        da = np.column_stack([_field(path, ds, f"delta_angle[{k}]") for k in range(3)])
        dv = np.column_stack([_field(path, ds, f"delta_velocity[{k}]") for k in range(3)])
        dta = _field(path, ds, "delta_angle_dt").astype(np.float64) * 1e-6
        dtv = _field(path, ds, "delta_velocity_dt").astype(np.float64) * 1e-6
        bad = np.flatnonzero((dta <= 0) | (dtv <= 0))
        if bad.size:
            raise InputError(f"{path}: vehicle_imu message {bad[0] + 1} has a zero delta time")
        gyro = da.astype(np.float64) / dta[:, None]
        acc = dv.astype(np.float64) / dtv[:, None]
        src_g, src_a = "delta_angle/delta_angle_dt", "delta_velocity/delta_velocity_dt"
    # Explicit FRD -> FLU: negate y and z.
    gyro = gyro.astype(np.float64) * FRD_TO_FLU
    acc = acc.astype(np.float64) * FRD_TO_FLU
    channels: dict[str, RawChannel] = {}
    for k, a in enumerate("xyz"):
        for name, arr, unit, src in (
            (f"gyro_{a}", gyro, "rad/s", src_g),
            (f"accel_{a}", acc, "m/s^2", src_a),
        ):
            if opts.channels is None or name in opts.channels:
                channels[name] = RawChannel(arr[:, k], unit, f"{ds.name}.{src}[{k}]")
    order = {c: i for i, c in enumerate(("gyro_x", "gyro_y", "gyro_z",
                                         "accel_x", "accel_y", "accel_z"))}
    channels = dict(sorted(channels.items(), key=lambda kv: order[kv[0]]))
    notes = [f"{path}: PX4 FRD body axes converted to FLU (y and z negated)"]
    truncated = truncation_note(path)
    if truncated is not None:
        notes.append(truncated)
    elif getattr(ulog, "file_corruption", False):
        notes.append(f"{path}: pyulog found corrupt data in the ULog and skipped it")
    dropouts = getattr(ulog, "dropouts", None) or []
    if dropouts:
        total_ms = sum(int(getattr(d, "duration", 0)) for d in dropouts)
        notes.append(
            f"{path}: the PX4 logger dropped messages {len(dropouts)} time(s) "
            f"({total_ms} ms in all); the gap check below says where the IMU lost samples"
        )
    return assemble_logs(
        f"{path}:{ds.name}",
        RawTime(t_us, "us", f"{ds.name}.timestamp"),
        channels,
        opts,
        row_label=lambda i: f"{ds.name} message {i + 1}",
        notes=notes,
        frame="FLU",
    )


def quaternion_ned_heading(q: np.ndarray) -> np.ndarray:
    """Heading (rad, clockwise from north, [0, 2pi)) of PX4 FRD->NED quaternions (w, x, y, z)."""
    return ned_quaternion_to_rpy(q)[2]


GPS_TOPICS = ("vehicle_gps_position", "sensor_gps")


def drive_from_files(
    files: Mapping[str, Any], settings: DriveSettings, options: Mapping[str, Any]
) -> Drive:
    """The drive reader registered for the ``ulog`` format (see
    :data:`imubounds.io.registry.DriveReaderFunc`)."""
    return read_drive_ulog(files["path"], settings=settings)


def read_drive_ulog(path: str | Path, *, settings: DriveSettings | None = None) -> Drive:
    """Read a PX4 ULog as a drive: IMU, GNSS (position, velocity, accuracy, dual-antenna
    heading), magnetometer and attitude.

    * ``sensor_combined`` (or ``vehicle_imu``) -> the IMU, FRD -> FLU;
    * ``vehicle_gps_position`` (or ``sensor_gps``) -> GNSS: ``latitude_deg``/
      ``longitude_deg`` (or ``lat``/``lon`` in 1e-7 deg), ``fix_type >= 2`` as
      the fix, ``hdop``, ``eph`` as ``h_acc_m``, ``vel_n_m_s``/``vel_e_m_s``
      (where ``vel_ned_valid``), ``s_variance_m_s`` as the velocity accuracy,
      and a finite ``heading`` (dual antenna, true north) as a heading stream;
    * ``vehicle_magnetometer`` -> magnetometer (gauss -> tesla, FRD -> FLU);
    * ``vehicle_attitude`` -> attitude (roll, pitch, yaw of the FRD/NED
      quaternion: an EKF that uses the IMU, not an independent heading).

    Times are PX4's time since boot (µs -> s) for every topic.
    """
    p = Path(path)
    if not p.exists():
        raise InputError(f"no such file: {p}")
    s = settings if settings is not None else DriveSettings()
    drive = Drive(settings=s, source=str(p), layout="ulog")
    imu = read_ulog(p, ReadOptions(on_gap="ignore").validated())[0]
    drive.warnings.extend(imu.warnings)
    nan = np.full(imu.t.size, np.nan)
    drive.imu = ImuStream(
        t=imu.t,
        accel=np.column_stack([imu.channels.get(f"accel_{c}", nan) for c in "xyz"]),
        gyro=np.column_stack([imu.channels.get(f"gyro_{c}", nan) for c in "xyz"]),
        input_units={"gyro": "rad/s", "accel": "m/s^2"},
    )
    ulog = _load(p, [*GPS_TOPICS, "vehicle_magnetometer", "vehicle_attitude"])
    files = {"imu": f"{p}:{imu.source.rsplit(':', 1)[-1]}"}
    g = next((d for d in (_dataset(ulog, n) for n in GPS_TOPICS) if d is not None), None)
    if g is not None:
        drive.gnss, heading = _gnss(p, g)
        files["gnss"] = f"{p}:{g.name}"
        if heading is not None:
            drive.heading = heading
            files["heading"] = f"{p}:{g.name}.heading"
    m = _dataset(ulog, "vehicle_magnetometer")
    if m is not None:
        mt = _field(p, m, "timestamp").astype(np.float64) * 1e-6
        mv = np.column_stack([_field(p, m, f"magnetometer_ga[{k}]") for k in range(3)])
        drive.mag = MagStream(t=mt, mag=mv.astype(float) * FRD_TO_FLU * 1e-4, unit="T")
        files.setdefault("heading", f"{p}:vehicle_magnetometer")
    a = _dataset(ulog, "vehicle_attitude")
    if a is not None:
        at = _field(p, a, "timestamp").astype(np.float64) * 1e-6
        q = np.column_stack([_field(p, a, f"q[{k}]") for k in range(4)]).astype(float)
        r, pt, y = ned_quaternion_to_rpy(q)
        drive.attitude = AttitudeStream(t=at, roll_rad=r, pitch_rad=pt, yaw_rad=y, source="ahrs")
        files["attitude"] = f"{p}:vehicle_attitude"
    drive.meta["files"] = files
    from imubounds.io.drive.mount import apply_mount

    apply_mount(drive)
    return drive


def _gnss(p: Path, g: Any) -> tuple[GnssStream, HeadingStream | None]:
    t = _field(p, g, "timestamp").astype(np.float64) * 1e-6
    if "latitude_deg" in g.data:
        lat = _field(p, g, "latitude_deg").astype(float)
        lon = _field(p, g, "longitude_deg").astype(float)
        alt = _field(p, g, "altitude_msl_m").astype(float) if "altitude_msl_m" in g.data else None
    else:  # older PX4: int32 1e-7 degrees and mm
        lat = _field(p, g, "lat").astype(float) * 1e-7
        lon = _field(p, g, "lon").astype(float) * 1e-7
        alt = _field(p, g, "alt").astype(float) * 1e-3 if "alt" in g.data else None

    def opt(name: str) -> np.ndarray | None:
        return _field(p, g, name).astype(float) if name in g.data else None

    fix = _field(p, g, "fix_type").astype(int) >= 2 if "fix_type" in g.data else None
    vn, ve = opt("vel_n_m_s"), opt("vel_e_m_s")
    if vn is not None and ve is not None and "vel_ned_valid" in g.data:
        valid = _field(p, g, "vel_ned_valid").astype(bool)
        vn, ve = np.where(valid, vn, np.nan), np.where(valid, ve, np.nan)
    gs = GnssStream(
        t=t, lat_deg=lat, lon_deg=lon, alt_m=alt, hdop=opt("hdop"), h_acc_m=opt("eph"), fix=fix,
        vel_n_mps=vn if ve is not None else None, vel_e_mps=ve if vn is not None else None,
        vel_acc_mps=opt("s_variance_m_s") if vn is not None and ve is not None else None,
        v_acc_m=opt("epv"),
    )
    head = opt("heading")
    hs = None
    if head is not None:
        ok = np.isfinite(head)
        if ok.any():
            hs = HeadingStream(t=t[ok], heading_rad=np.mod(head[ok], 2 * math.pi), source="gnss",
                               true_north=True)
    return gs, hs
