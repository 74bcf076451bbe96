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
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from imubounds.errors import ImuboundsError, InputError
from imubounds.frames import enu_yaw_to_heading, quaternion_yaw_enu
from imubounds.io.drive_legacy import DriveLog
from imubounds.io.log import ImuLog

from .assemble import RawChannel, RawTime, ReadOptions, assemble_logs

IMU_TYPE = "sensor_msgs/msg/Imu"
NAVSAT_TYPE = "sensor_msgs/msg/NavSatFix"
MAG_TYPE = "sensor_msgs/msg/MagneticField"
#: Heading topic types accepted (orientation in ENU, or a yaw/heading number).
HEADING_TYPES = (
    "geometry_msgs/msg/QuaternionStamped",
    "geometry_msgs/msg/PoseStamped",
    "geometry_msgs/msg/PoseWithCovarianceStamped",
    "nav_msgs/msg/Odometry",
)
ROS1_MAGIC = b"#ROSBAG V2.0"
MCAP_MAGIC = b"\x89MCAP"
SQLITE_MAGIC = b"SQLite format 3\x00"


def sniff_bag(head: bytes) -> bool:
    """True for the first bytes of a ROS 1 bag, an MCAP file or a ROS 2 sqlite3 file."""
    return head.startswith((ROS1_MAGIC, MCAP_MAGIC, SQLITE_MAGIC))


def sniff_bag_dir(path: Path) -> bool:
    """True for a ROS 2 bag directory (``metadata.yaml`` beside ``.db3``/``.mcap`` files)."""
    return (path / "metadata.yaml").is_file()


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


def covariance_hdop(cov_en: np.ndarray, gps_cep_m: float) -> np.ndarray:
    """HDOP equivalent of an ENU position covariance, for the CEP-based GPS model.

    The estimator's box half-width is ``HDOP · DRMS(CEP) · factor``; with
    ``HDOP = sqrt(var_e + var_n) / DRMS(CEP)`` it becomes the covariance's
    own DRMS times the same factor. NaN where the covariance is unknown.
    """
    from imubounds.dynamic.aiding.gps import cep_to_drms

    cov = np.asarray(cov_en, dtype=float)
    drms = np.sqrt(cov[:, 0] + cov[:, 1])
    out = drms / cep_to_drms(gps_cep_m)
    out[~np.isfinite(out) | (out <= 0)] = np.nan
    return out


def read_drive_rosbag(
    path: str | Path,
    *,
    imu_topic: str | None = None,
    gps_topic: str | None = None,
    mag_topic: str | None = None,
    heading_topic: str | None = None,
    gps_cep_m: float = 3.0,
) -> DriveLog:
    """Read a drive log (IMU, NavSatFix, MagneticField and/or heading) from a bag.

    Parameters
    ----------
    path:
        ROS 1 bag, ROS 2 bag directory or MCAP file.
    imu_topic, gps_topic, mag_topic, heading_topic:
        Topics; by default the busiest topic of each type. A heading topic is
        ``geometry_msgs/QuaternionStamped``, ``PoseStamped``,
        ``PoseWithCovarianceStamped`` or ``nav_msgs/Odometry`` (ENU orientation).
    gps_cep_m:
        CEP (m) of the estimator's GPS model, used to turn each fix's ENU
        position covariance into an equivalent HDOP (see :func:`covariance_hdop`).

    Returns
    -------
    DriveLog
        IMU in FLU (REP-103, unchanged), GPS geodetic with ``fix`` from
        ``status.status >= 0``, heading clockwise from north in rad, the
        magnetometer in FLU (tesla).
    """
    p = Path(path)
    if not p.exists():
        raise InputError(f"no such file or directory: {p}")
    warnings: list[str] = []
    imu = read_rosbag(p, ReadOptions(on_gap="ignore", extra={"topic": imu_topic}).validated())[0]
    warnings += imu.warnings
    with _Bag(p) as bag:
        g_topic = bag.pick(gps_topic, (NAVSAT_TYPE,), "GPS", "--gps-topic")
        assert g_topic is not None
        m_topic = bag.pick(mag_topic, (MAG_TYPE,), "magnetometer", "--mag-topic", required=False)
        h_topic = bag.pick(heading_topic, HEADING_TYPES, "heading", "--heading-topic",
                           required=False)
        st: list[int] = []
        rc: list[int] = []
        rows: list[tuple[float, ...]] = []
        for t_ns, msg in bag.messages(g_topic):
            st.append(_stamp_ns(msg))
            rc.append(t_ns)
            cov = msg.position_covariance
            known = int(msg.position_covariance_type) > 0
            rows.append((msg.latitude, msg.longitude, msg.altitude, float(msg.status.status),
                         cov[0] if known else math.nan, cov[4] if known else math.nan))
        if not rows:
            raise InputError(f"{p}: GPS topic {g_topic!r} holds no messages")
        g = np.asarray(rows, dtype=float)
        g_t = _times(p, g_topic, st, rc, warnings) * 1e-9
        mag_t = mag = None
        if m_topic is not None:
            st, rc, mv = [], [], []
            for t_ns, msg in bag.messages(m_topic):
                st.append(_stamp_ns(msg))
                rc.append(t_ns)
                f = msg.magnetic_field
                mv.append((f.x, f.y, f.z))
            if mv:
                mag_t = _times(p, m_topic, st, rc, warnings) * 1e-9
                mag = np.asarray(mv, dtype=float)
        head_t = head = None
        if h_topic is not None:
            st, rc, qv = [], [], []
            for t_ns, msg in bag.messages(h_topic):
                st.append(_stamp_ns(msg))
                rc.append(t_ns)
                q = _orientation(msg)
                qv.append((q.x, q.y, q.z, q.w))
            if qv:
                qa = np.asarray(qv, dtype=float)
                head_t = _times(p, h_topic, st, rc, warnings) * 1e-9
                head = enu_yaw_to_heading(quaternion_yaw_enu(*qa.T))
    hdop = covariance_hdop(g[:, 4:6], gps_cep_m)
    if np.all(np.isnan(hdop)):
        warnings.append(
            f"{p}: {g_topic!r} carries no position covariance; the default HDOP is used"
        )
    log = DriveLog(
        imu_t=imu.t,
        accel=np.column_stack([imu.channels[f"accel_{a}"] for a in "xyz"]),
        gyro=np.column_stack([imu.channels[f"gyro_{a}"] for a in "xyz"]),
        gps_t=g_t, lat=g[:, 0], lon=g[:, 1], alt=g[:, 2], hdop=hdop,
        fix=(g[:, 3] >= 0) & np.isfinite(g[:, 0]) & np.isfinite(g[:, 1]),
        heading_t=head_t, heading=head, mag_t=mag_t, mag=mag,
        source=str(p), layout="rosbag", frame="FLU", warnings=warnings,
        settings={
            "imu_topic": imu.source.rsplit(":", 1)[-1], "gps_topic": g_topic,
            "mag_topic": m_topic, "heading_topic": h_topic,
            "heading_source": "heading-topic" if head is not None else "magnetometer",
            "hdop_from_covariance_cep_m": gps_cep_m,
        },
    )
    log.validate()
    return log


def _orientation(msg: Any) -> Any:
    if hasattr(msg, "quaternion"):
        return msg.quaternion
    pose = msg.pose
    if hasattr(pose, "pose"):  # PoseWithCovariance / Odometry
        pose = pose.pose
    return pose.orientation
