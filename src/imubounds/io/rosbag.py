"""ROS 1 bags, ROS 2 bags (sqlite3 or MCAP storage) and MCAP files, via ``rosbags``.

No ROS installation is needed: :class:`rosbags.highlevel.AnyReader` reads all
three containers and deserialises the standard message types. Messages are
streamed (one at a time), so large bags are not loaded into memory; only the
selected topics are decoded.

Frames (REP-103 / REP-105): ``sensor_msgs/Imu`` is in the body frame of its
``frame_id``, which REP-103 fixes as **FLU** (x forward, y left, z up), so no
axis change is applied. ``sensor_msgs/NavSatFix`` position covariance is in
ENU (m^2). Orientations (``geometry_msgs`` quaternions) are in ENU: the yaw
ψ is counter-clockwise from east, so the compass heading clockwise from north
is ``π/2 − ψ``.

Time: the message header stamp (sensor time) is used; when every header stamp
is zero the bag's receive time is used instead, with a warning.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from imubounds.errors import ImuboundsError, InputError
from imubounds.frames import enu_yaw_to_heading, quaternion_to_rpy, quaternion_yaw_enu
from imubounds.io.drive import (
    AttitudeStream,
    Drive,
    DriveSettings,
    GnssStream,
    HeadingStream,
    ImuStream,
    MagStream,
    VelocityStream,
)
from imubounds.io.log import ImuLog

from .assemble import RawChannel, RawTime, ReadOptions, assemble_logs

IMU_TYPE = "sensor_msgs/msg/Imu"
NAVSAT_TYPE = "sensor_msgs/msg/NavSatFix"
MAG_TYPE = "sensor_msgs/msg/MagneticField"
#: Heading topic types accepted (an orientation in a geographic ENU frame).
HEADING_TYPES = (
    "geometry_msgs/msg/QuaternionStamped",
    "geometry_msgs/msg/PoseStamped",
    "geometry_msgs/msg/PoseWithCovarianceStamped",
    "nav_msgs/msg/Odometry",
)
#: Velocity topic types: a twist (body frame, or ENU for a GNSS receiver's velocity).
TWIST_TYPES = ("geometry_msgs/msg/TwistWithCovarianceStamped", "geometry_msgs/msg/TwistStamped")
ODOM_TYPE = "nav_msgs/msg/Odometry"
#: Header frame ids taken as a geographic (ENU) frame; anything else is a body frame.
GEOGRAPHIC_FRAMES = ("enu", "map", "world", "earth", "utm", "gps", "gnss", "navsat", "ublox")


def _bag_error(path: Path, err: BaseException) -> InputError:
    text = " ".join(str(err).split()) or type(err).__name__
    if len(text) > 160:
        text = text[:157] + "..."
    return InputError(
        f"{path}: not a readable ROS bag ({type(err).__name__}: {text}); the file may be "
        "truncated or corrupt: re-copy it or reindex it (rosbag reindex / ros2 bag reindex)"
    )


class _Bag:
    """An open bag: topics by type, and streaming of one topic's messages."""

    def __init__(self, path: Path) -> None:
        from rosbags.highlevel import AnyReader
        from rosbags.typesys import Stores, get_typestore

        self.path = path
        paths = [path]
        if path.is_file() and path.suffix.lower() == ".db3" and (
            path.parent / "metadata.yaml"
        ).is_file():
            paths = [path.parent]
        try:
            self.reader = AnyReader(paths, default_typestore=get_typestore(Stores.ROS2_HUMBLE))
            self.reader.open()
        except ImuboundsError:
            raise
        except Exception as err:  # rosbags/sqlite/struct raise many types on bad files
            raise _bag_error(path, err) from err

    def close(self) -> None:
        try:
            self.reader.close()
        except Exception:  # noqa: BLE001 - closing a broken bag must not hide the real error
            pass

    def __enter__(self) -> _Bag:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def topics(self) -> dict[str, tuple[str, int]]:
        """Topic -> (message type, message count)."""
        out: dict[str, tuple[str, int]] = {}
        for c in self.reader.connections:
            typ, n = out.get(c.topic, (c.msgtype, 0))
            out[c.topic] = (typ, n + int(c.msgcount))
        return out

    def pick(
        self, wanted: str | None, types: tuple[str, ...], what: str, option: str,
        required: bool = True,
    ) -> str | None:
        """The topic to read: ``wanted`` if given (checked), else the busiest topic of ``types``."""
        topics = self.topics()
        if wanted is not None:
            if wanted not in topics:
                have = ", ".join(f"{t} ({ty})" for t, (ty, _) in sorted(topics.items()))
                raise InputError(f"{self.path}: no topic {wanted!r}; topics are: {have or 'none'}")
            if topics[wanted][0] not in types:
                raise InputError(
                    f"{self.path}: topic {wanted!r} is {topics[wanted][0]}, not "
                    f"{' or '.join(types)}; give another {option}"
                )
            return wanted
        cands = sorted(
            (t for t, (ty, _) in topics.items() if ty in types), key=lambda t: -topics[t][1]
        )
        if not cands:
            if not required:
                return None
            have = ", ".join(f"{t} ({ty})" for t, (ty, _) in sorted(topics.items()))
            raise InputError(
                f"{self.path}: no {what} topic ({' or '.join(types)}) in the bag; topics are: "
                f"{have or 'none'}"
            )
        return cands[0]

    def messages(self, topic: str) -> Iterator[tuple[int, Any]]:
        """Stream (bag receive time in ns, deserialised message) of one topic."""
        conns = [c for c in self.reader.connections if c.topic == topic]
        try:
            for conn, t_ns, raw in self.reader.messages(connections=conns):
                yield int(t_ns), self.reader.deserialize(raw, conn.msgtype)
        except ImuboundsError:
            raise
        except Exception as err:  # truncated chunks, bad CDR, ...
            raise _bag_error(self.path, err) from err


def _stamp_ns(msg: Any) -> int:
    st = msg.header.stamp
    return int(st.sec) * 1_000_000_000 + int(st.nanosec)


def _times(path: Path, topic: str, stamps: list[int], recv: list[int],
           warnings: list[str]) -> np.ndarray:
    """Header stamps in ns, or receive times if every header stamp is zero."""
    st = np.asarray(stamps, dtype=np.int64)
    if st.size and not np.any(st):
        warnings.append(
            f"{path}: topic {topic!r} has no header stamps (all zero); the bag receive time is used"
        )
        return np.asarray(recv, dtype=np.int64)
    return st


def read_rosbag(path: Path, opts: ReadOptions) -> list[ImuLog]:
    """Read the ``sensor_msgs/Imu`` topic of a bag into SI :class:`ImuLog` segment(s).

    Parameters
    ----------
    path:
        ROS 1 ``.bag``, ROS 2 bag directory (or its ``.db3``), or ``.mcap`` file.
    opts:
        Reader options; ``opts.extra["topic"]`` selects the IMU topic
        (default: the ``sensor_msgs/Imu`` topic with most messages).

    Returns
    -------
    list of ImuLog
        Gyro in rad/s and accelerometer in m/s^2 (the message units), FLU
        body frame (REP-103), time from the header stamps in s.
    """
    wanted = opts.extra.get("topic")
    notes: list[str] = []
    with _Bag(path) as bag:
        topic = bag.pick(None if wanted is None else str(wanted), (IMU_TYPE,), "IMU", "--topic")
        assert topic is not None
        n_imu = sum(1 for ty, _ in bag.topics().values() if ty == IMU_TYPE)
        if wanted is None and n_imu > 1:
            notes.append(
                f"{path}: {n_imu} sensor_msgs/Imu topics; read {topic!r} (the most messages); "
                "choose another with --topic"
            )
        stamps: list[int] = []
        recv: list[int] = []
        vals: list[tuple[float, ...]] = []
        gyro_ok = accel_ok = True
        for t_ns, msg in bag.messages(topic):
            stamps.append(_stamp_ns(msg))
            recv.append(t_ns)
            w, a = msg.angular_velocity, msg.linear_acceleration
            vals.append((w.x, w.y, w.z, a.x, a.y, a.z))
            # REP-145: a covariance starting with -1 means "this field is not provided".
            gyro_ok = gyro_ok and msg.angular_velocity_covariance[0] != -1
            accel_ok = accel_ok and msg.linear_acceleration_covariance[0] != -1
    if not vals:
        raise InputError(f"{path}: topic {topic!r} holds no messages")
    arr = np.asarray(vals, dtype=np.float64)
    t = _times(path, topic, stamps, recv, notes)
    names = ("gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z")
    fields = ("angular_velocity.x", "angular_velocity.y", "angular_velocity.z",
              "linear_acceleration.x", "linear_acceleration.y", "linear_acceleration.z")
    channels: dict[str, RawChannel] = {}
    for k, (name, fld) in enumerate(zip(names, fields, strict=True)):
        if (name.startswith("gyro") and not gyro_ok) or (name.startswith("accel") and not accel_ok):
            continue
        if opts.channels is not None and name not in opts.channels:
            continue
        unit = "rad/s" if name.startswith("gyro") else "m/s^2"
        channels[name] = RawChannel(arr[:, k], unit, f"{topic}/{fld}")
    if not channels:
        raise InputError(f"{path}: topic {topic!r} marks both rates and accelerations as absent")
    return assemble_logs(
        f"{path}:{topic}",
        RawTime(t, "ns", f"{topic}/header.stamp"),
        channels,
        opts,
        row_label=lambda i: f"message {i + 1}",
        notes=notes,
        frame="FLU",
    )


def _geographic(frame_id: str) -> bool:
    f = frame_id.strip().lstrip("/").lower()
    return any(f == g or f.startswith(g + "_") or f.endswith("_" + g) for g in GEOGRAPHIC_FRAMES)


def _twist(msg: Any) -> Any:
    tw = msg.twist
    return tw.twist if hasattr(tw, "twist") else tw


def drive_from_files(
    files: Mapping[str, Any], settings: DriveSettings, options: Mapping[str, Any]
) -> Drive:
    """The drive reader registered for the ``rosbag`` format (see
    :data:`imubounds.io.registry.DriveReaderFunc`)."""
    return read_drive_rosbag(files["path"], settings=settings, topics=options.get("topics"))


def read_drive_rosbag(
    path: str | Path,
    *,
    settings: DriveSettings | None = None,
    topics: dict[str, str] | Any | None = None,
) -> Drive:
    """Read a drive from a ROS 1 bag, a ROS 2 bag (directory or ``.db3``) or an MCAP file.

    Topics are auto-detected (the busiest of each type) unless ``topics``
    names them (keys ``imu``, ``gnss``, ``mag``, ``heading``, ``velocity``,
    ``gnss_velocity``, ``attitude``):

    * ``sensor_msgs/Imu`` -> the IMU (FLU per REP-103, SI); its orientation,
      when given (covariance[0] != -1), -> the attitude stream (an AHRS of the
      same unit: not independent of the IMU);
    * ``sensor_msgs/NavSatFix`` -> GNSS (fix from ``status.status >= 0``,
      ``h_acc_m`` from the east/north position covariance);
    * ``sensor_msgs/MagneticField`` -> magnetometer (tesla, IMU axes);
    * ``TwistWithCovarianceStamped``/``TwistStamped`` in a geographic frame
      (``enu``, ``map``, ``gps``, ... see :data:`GEOGRAPHIC_FRAMES`) -> GNSS
      velocity (east, north) at the fixes; in any other frame -> body velocity;
    * ``nav_msgs/Odometry`` twist -> body velocity (``kind`` odometry); its
      orientation -> heading when its frame is geographic;
    * ``QuaternionStamped``/``PoseStamped``/``PoseWithCovarianceStamped`` ->
      heading (ENU orientation, true north).

    Time: header stamps (the bag's receive time when every stamp is zero).
    """
    p = Path(path)
    if not p.exists():
        raise InputError(f"no such file or directory: {p}")
    tp = dict(topics or {})
    unknown = sorted(set(tp) - {"imu", "gnss", "mag", "heading", "velocity", "gnss_velocity",
                                "attitude"})
    if unknown:
        raise InputError(
            f"{p}: unknown topic role(s) {', '.join(unknown)}; use imu, gnss, mag, heading, "
            "velocity, gnss_velocity, attitude"
        )
    s = settings if settings is not None else DriveSettings()
    drive = Drive(settings=s, source=str(p), layout="rosbag")
    opts = ReadOptions(on_gap="ignore", extra={"topic": tp.get("imu")}).validated()
    imu = read_rosbag(p, opts)[0]
    drive.warnings.extend(imu.warnings)
    nan = np.full(imu.t.size, np.nan)
    drive.imu = ImuStream(
        t=imu.t,
        accel=np.column_stack([imu.channels.get(f"accel_{a}", nan) for a in "xyz"]),
        gyro=np.column_stack([imu.channels.get(f"gyro_{a}", nan) for a in "xyz"]),
        input_units={"gyro": "rad/s", "accel": "m/s^2"},
    )
    imu_topic = imu.source.rsplit(":", 1)[-1]
    used: dict[str, str | None] = {"imu": imu_topic}
    with _Bag(p) as bag:
        g_topic = bag.pick(tp.get("gnss"), (NAVSAT_TYPE,), "GNSS", "--topic gnss=...",
                           required=False)
        m_topic = bag.pick(tp.get("mag"), (MAG_TYPE,), "magnetometer", "--topic mag=...",
                           required=False)
        h_topic = bag.pick(tp.get("heading"), HEADING_TYPES, "heading", "--topic heading=...",
                           required=False)
        if h_topic is not None and tp.get("heading") is None and bag.topics()[h_topic][0] == (
            ODOM_TYPE
        ):
            h_topic = None  # odometry is a velocity source; its orientation only if geographic
        used.update(gnss=g_topic, mag=m_topic, heading=h_topic)
        if g_topic is not None:
            drive.gnss = _navsat(bag, p, g_topic, drive.warnings)
        if m_topic is not None:
            t, v = _vectors(bag, p, m_topic, lambda m: m.magnetic_field, drive.warnings)
            if t.size:
                drive.mag = MagStream(t=t, mag=v, unit="T")
        if h_topic is not None:
            t, q = _quats(bag, p, h_topic, drive.warnings)
            if t.size:
                drive.heading = HeadingStream(
                    t=t, heading_rad=enu_yaw_to_heading(quaternion_yaw_enu(*q.T)),
                    source="compass", true_north=True,
                )
        _imu_orientation(bag, p, imu_topic, drive)
        _velocities(bag, p, tp, drive, used)
        att = tp.get("attitude")
        if att is not None:
            t, q = _quats(bag, p, bag.pick(att, (*HEADING_TYPES, IMU_TYPE), "attitude",
                                           "--topic attitude=...") or att, drive.warnings)
            r, pt, y = quaternion_to_rpy(q[:, [3, 0, 1, 2]])
            drive.attitude = AttitudeStream(t=t, roll_rad=r, pitch_rad=pt, yaw_rad=y)
            used["attitude"] = att
    drive.meta["topics"] = {k: v for k, v in used.items() if v is not None}
    drive.meta["files"] = {k: f"{p}:{v}" for k, v in drive.meta["topics"].items()}
    from imubounds.io.drive.mount import apply_mount

    apply_mount(drive, attitude_of_sensor=drive.meta.get("attitude_from") == "imu")
    return drive


def _collect(bag: _Bag, topic: str, get: Any, path: Path,
             warnings: list[str]) -> tuple[np.ndarray, list[Any]]:
    st: list[int] = []
    rc: list[int] = []
    vals: list[Any] = []
    for t_ns, msg in bag.messages(topic):
        st.append(_stamp_ns(msg))
        rc.append(t_ns)
        vals.append(get(msg))
    if not vals:
        return np.zeros(0), []
    t = _times(path, topic, st, rc, warnings) * 1e-9
    order = np.argsort(t, kind="stable")
    keep = np.concatenate(([True], np.diff(t[order]) > 0))
    idx = order[keep]
    return t[idx], [vals[i] for i in idx]


def _vectors(bag: _Bag, path: Path, topic: str, get: Any,
             warnings: list[str]) -> tuple[np.ndarray, np.ndarray]:
    t, vals = _collect(bag, topic, get, path, warnings)
    return t, np.asarray([(v.x, v.y, v.z) for v in vals], dtype=float).reshape(-1, 3)


def _quats(bag: _Bag, path: Path, topic: str,
           warnings: list[str]) -> tuple[np.ndarray, np.ndarray]:
    t, vals = _collect(bag, topic, _orientation, path, warnings)
    return t, np.asarray([(q.x, q.y, q.z, q.w) for q in vals], dtype=float).reshape(-1, 4)


def _navsat(bag: _Bag, path: Path, topic: str, warnings: list[str]) -> GnssStream:
    def row(msg: Any) -> tuple[float, ...]:
        cov = msg.position_covariance
        known = int(msg.position_covariance_type) > 0
        return (msg.latitude, msg.longitude, msg.altitude, float(msg.status.status),
                cov[0] if known else math.nan, cov[4] if known else math.nan,
                cov[8] if known else math.nan)

    t, rows = _collect(bag, topic, row, path, warnings)
    if not rows:
        raise InputError(f"{path}: GNSS topic {topic!r} holds no messages")
    g = np.asarray(rows, dtype=float)
    var = 0.5 * (g[:, 4] + g[:, 5])
    h_acc = np.where(np.isfinite(var) & (var > 0), np.sqrt(np.abs(var)), np.nan)
    if np.all(np.isnan(h_acc)):
        warnings.append(f"{path}: {topic!r} carries no position covariance; the default HDOP "
                        "and CEP are used")
    v_acc = np.where(np.isfinite(g[:, 6]) & (g[:, 6] > 0), np.sqrt(np.abs(g[:, 6])), np.nan)
    return GnssStream(t=t, lat_deg=g[:, 0], lon_deg=g[:, 1], alt_m=g[:, 2],
                      fix=g[:, 3] >= 0, h_acc_m=h_acc, v_acc_m=v_acc)


def _imu_orientation(bag: _Bag, path: Path, topic: str, drive: Drive) -> None:
    def get(msg: Any) -> tuple[float, ...]:
        q = msg.orientation
        given = msg.orientation_covariance[0] != -1 and (q.x, q.y, q.z, q.w) != (0, 0, 0, 0)
        return (q.w, q.x, q.y, q.z, 1.0 if given else 0.0)

    t, vals = _collect(bag, topic, get, path, [])
    a = np.asarray(vals, dtype=float).reshape(-1, 5)
    ok = a[:, 4] > 0
    if t.size and ok.all():
        r, pt, y = quaternion_to_rpy(a[:, :4])
        drive.attitude = AttitudeStream(t=t, roll_rad=r, pitch_rad=pt, yaw_rad=y, source="ahrs")
        drive.meta["attitude_from"] = "imu"


def _velocities(bag: _Bag, path: Path, tp: dict[str, Any], drive: Drive,
                used: dict[str, str | None]) -> None:
    topics = bag.topics()
    twists = [tn for tn, (ty, _) in topics.items() if ty in TWIST_TYPES]
    odoms = [tn for tn, (ty, _) in topics.items() if ty == ODOM_TYPE]
    frames: dict[str, str] = {}
    for tn in twists + odoms:
        for _, msg in bag.messages(tn):
            frames[tn] = str(msg.header.frame_id)
            break
    gv = tp.get("gnss_velocity")
    if gv is None:
        geo = [tn for tn in twists if _geographic(frames.get(tn, ""))]
        gv = max(geo, key=lambda tn: topics[tn][1]) if geo else None
    else:
        bag.pick(gv, TWIST_TYPES, "GNSS velocity", "--topic gnss_velocity=...")
    bv = tp.get("velocity")
    if bv is None:
        body = odoms + [tn for tn in twists if not _geographic(frames.get(tn, "")) and tn != gv]
        bv = max(body, key=lambda tn: topics[tn][1]) if body else None
    else:
        bag.pick(bv, (*TWIST_TYPES, ODOM_TYPE), "velocity", "--topic velocity=...")
    if gv is not None and drive.gnss is not None:
        t, v = _vectors(bag, path, gv, lambda m: _twist(m).linear, drive.warnings)
        if t.size:
            from imubounds.io.drive.mount import match_times

            g = drive.gnss
            k, near = match_times(t, g.t)
            g.vel_e_mps = np.where(near, v[k, 0], np.nan)
            g.vel_n_mps = np.where(near, v[k, 1], np.nan)
            used["gnss_velocity"] = gv
    elif gv is not None:
        drive.warnings.append(f"{path}: GNSS velocity topic {gv!r} ignored: no NavSatFix topic")
    if bv is not None:
        t, v = _vectors(bag, path, bv, lambda m: _twist(m).linear, drive.warnings)
        if t.size:
            drive.velocity = VelocityStream(t=t, u_mps=v[:, 0], v_mps=v[:, 1], w_mps=v[:, 2],
                                            kind="odometry")
            used["velocity"] = bv
        if topics[bv][0] == ODOM_TYPE and drive.heading is None:
            if _geographic(frames.get(bv, "")):
                t, q = _quats(bag, path, bv, drive.warnings)
                drive.heading = HeadingStream(
                    t=t, heading_rad=enu_yaw_to_heading(quaternion_yaw_enu(*q.T)),
                    source="compass", true_north=True,
                )
                used["heading"] = bv
            else:
                drive.notes.append(
                    f"{bv}: odometry orientation in frame {frames.get(bv, '')!r} (not "
                    "geographic) is not used as a heading"
                )


def _orientation(msg: Any) -> Any:
    if hasattr(msg, "quaternion"):
        return msg.quaternion
    if hasattr(msg, "orientation"):
        return msg.orientation
    pose = msg.pose
    if hasattr(pose, "pose"):  # PoseWithCovariance / Odometry
        pose = pose.pose
    return pose.orientation
