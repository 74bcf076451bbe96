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
from pathlib import Path
from typing import Any

import numpy as np

from imubounds.errors import ImuboundsError, InputError
from imubounds.frames import FRD_TO_FLU
from imubounds.io.drive_legacy import DriveLog
from imubounds.io.log import ImuLog

from .assemble import RawChannel, RawTime, ReadOptions, assemble_logs

ULOG_MAGIC = b"ULog\x01\x12\x35"
IMU_TOPICS = ("sensor_combined", "vehicle_imu")


def sniff_ulog(head: bytes) -> bool:
    """True for the first bytes of a ULog file."""
    return head.startswith(ULOG_MAGIC)


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
    """Heading (rad, clockwise from north, [0, 2π)) of PX4 FRD->NED quaternions (w, x, y, z)."""
    w, x, y, z = (np.asarray(q[:, k], dtype=float) for k in range(4))
    yaw = np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    h = np.mod(yaw, 2.0 * math.pi)
    return np.where(h >= 2.0 * math.pi, 0.0, h)  # mod of -tiny is 2*pi


def read_drive_ulog(path: str | Path, *, gps_cep_m: float = 3.0) -> DriveLog:
    """Read a PX4 ULog as a drive log: IMU, ``vehicle_gps_position``, magnetometer, heading.

    Parameters
    ----------
    path:
        ``.ulg`` file.
    gps_cep_m:
        CEP (m) of the estimator's GPS model; used only when a fix has no
        ``hdop`` field, to turn ``eph`` (m) into an equivalent HDOP.

    Returns
    -------
    DriveLog
        IMU and magnetometer in FLU (from FRD), GPS in degrees/metres with
        ``fix`` from ``fix_type >= 2``, heading from ``vehicle_attitude``
        (NED yaw = clockwise from north) when logged.
    """
    from imubounds.dynamic.aiding.gps import cep_to_drms

    p = Path(path)
    if not p.exists():
        raise InputError(f"no such file: {p}")
    imu = read_ulog(p, ReadOptions(on_gap="ignore").validated())[0]
    gps_names = ["vehicle_gps_position", "sensor_gps"]
    ulog = _load(p, [*gps_names, "vehicle_magnetometer", "vehicle_attitude"])
    g = next((d for d in (_dataset(ulog, n) for n in gps_names) if d is not None), None)
    if g is None:
        raise InputError(f"{p}: no vehicle_gps_position (or sensor_gps) topic in the ULog")
    warnings = list(imu.warnings)
    g_t = _field(p, g, "timestamp").astype(np.float64) * 1e-6
    if "latitude_deg" in g.data:
        lat = _field(p, g, "latitude_deg").astype(float)
        lon = _field(p, g, "longitude_deg").astype(float)
        alt = _field(p, g, "altitude_msl_m").astype(float)
    else:  # older PX4: int32 1e-7 degrees and mm
        lat = _field(p, g, "lat").astype(float) * 1e-7
        lon = _field(p, g, "lon").astype(float) * 1e-7
        alt = _field(p, g, "alt").astype(float) * 1e-3
    if "hdop" in g.data:
        hdop = _field(p, g, "hdop").astype(float)
    else:
        hdop = _field(p, g, "eph").astype(float) / cep_to_drms(gps_cep_m)
        warnings.append(f"{p}: no hdop field; HDOP taken as eph / DRMS(CEP {gps_cep_m:g} m)")
    fix = _field(p, g, "fix_type").astype(int) >= 2 if "fix_type" in g.data else np.isfinite(lat)
    mag_t = mag = None
    m = _dataset(ulog, "vehicle_magnetometer")
    if m is not None:
        mag_t = _field(p, m, "timestamp").astype(np.float64) * 1e-6
        mag = np.column_stack(
            [_field(p, m, f"magnetometer_ga[{k}]") for k in range(3)]
        ).astype(float) * FRD_TO_FLU * 1e-4  # gauss -> tesla, FRD -> FLU
    head_t = head = None
    a = _dataset(ulog, "vehicle_attitude")
    if a is not None:
        head_t = _field(p, a, "timestamp").astype(np.float64) * 1e-6
        head = quaternion_ned_heading(np.column_stack([_field(p, a, f"q[{k}]") for k in range(4)]))
    log = DriveLog(
        imu_t=imu.t,
        accel=np.column_stack([imu.channels[f"accel_{c}"] for c in "xyz"]),
        gyro=np.column_stack([imu.channels[f"gyro_{c}"] for c in "xyz"]),
        gps_t=g_t, lat=lat, lon=lon, alt=alt, hdop=hdop, fix=fix,
        heading_t=head_t, heading=head, mag_t=mag_t, mag=mag,
        source=str(p), layout="ulog", frame="FLU", warnings=warnings,
        settings={"gps_topic": g.name,
                  "heading_source": "vehicle_attitude" if head is not None else "magnetometer"},
    )
    log.validate()
    return log
