"""Write the small drive samples of tests/data/drive/ (ROS 1, ROS 2, ULog, NMEA, CSV).

Every file holds the same first 10 s of the real VN-100 + BU-353N drive
(``../shared/data/dynamic/vn100_bu353_circle``; MIT, Kiran1510/Automotive-
Dead-Reckoning), written with the libraries users have (``rosbags``; the
minimal ULog writer of ``tests/data/formats/make_formats.py``), in each
format's own frames, with the sensors the drive readers must pick up:

* ``vn100_drive_ros1.bag`` (ROS 1): ``/imu/data`` Imu with an orientation
  (the VN-100 AHRS attitude), ``/imu/mag`` MagneticField, ``/gps/fix``
  NavSatFix with covariance, ``/gps/vel`` TwistWithCovarianceStamped in frame
  ``gps`` (ENU: the GNSS velocity), ``/odom`` Odometry (frame ``odom``, body
  twist: the wheel speed).
* ``vn100_drive_ros2/`` (ROS 2, sqlite3): Imu (no orientation), NavSatFix,
  ``/wheel/twist`` TwistWithCovarianceStamped in ``base_link`` (body
  velocity), ``/heading`` PoseStamped in ``map`` (ENU heading).
* ``vn100_drive_vel.ulg`` (PX4): sensor_combined, vehicle_gps_position with
  ``latitude_deg``, velocity NED and its accuracy, vehicle_attitude.
* ``vn100_vnymr.nmea``: host-stamped ``$GPGGA``, ``$GPVTG`` (course, speed),
  ``$HCHDG`` with variation, and the ``$VNYMR`` IMU sentences: one file.
* ``wide_log.csv``: a CSV of "another tool": time in ms, gyro in deg/s, accel
  in g with its own names, GNSS columns filled only at the fixes.

The body velocity is the speed between consecutive fixes (the car drives
forward); the GNSS velocity the ENU difference of the fixes.

Run from the repository root (deterministic output):

    .venv/bin/python tests/data/drive/make_drives.py
"""

from __future__ import annotations

import importlib.util
import math
import shutil
from pathlib import Path
from typing import Any

import numpy as np

HERE = Path(__file__).resolve().parent
FORMATS = HERE.parent / "formats"


def _make_formats() -> Any:
    spec = importlib.util.spec_from_file_location("make_formats", FORMATS / "make_formats.py")
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


MF = _make_formats()
FRD_TO_FLU = np.array([1.0, -1.0, -1.0])


def gps_velocity(gps: dict[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(east, north, speed) m/s at each fix: the difference to the next fix (last: previous)."""
    from imubounds.geodesy import geodetic_to_enu

    e, n, _ = geodetic_to_enu(gps["latitude"], gps["longitude"])
    dt = np.diff(gps["t"])
    ve = np.append(np.diff(e) / dt, np.diff(e)[-1] / dt[-1])
    vn = np.append(np.diff(n) / dt, np.diff(n)[-1] / dt[-1])
    return ve, vn, np.hypot(ve, vn)


def _ros_events(ts: Any, ros1: bool) -> tuple[list[tuple[int, str, Any, str]], list[tuple[str,
                                                                                             str]]]:
    T = ts.types
    imu, gps, _, _ = MF.vn100()
    Header, Time, V3, Q = (T["std_msgs/msg/Header"], T["builtin_interfaces/msg/Time"],
                           T["geometry_msgs/msg/Vector3"], T["geometry_msgs/msg/Quaternion"])
    hdr_kw = {"seq": 0} if ros1 else {}

    def header(ns: int, frame: str) -> Any:
        return Header(stamp=MF._stamp(Time, ns), frame_id=frame, **hdr_kw)

    gyro = np.column_stack([imu["gyro_x"], imu["gyro_y"], imu["gyro_z"]]) * FRD_TO_FLU
    acc = np.column_stack([imu["acc_x"], imu["acc_y"], imu["acc_z"]]) * FRD_TO_FLU
    mag = np.column_stack([imu["mag_x"], imu["mag_y"], imu["mag_z"]]) * FRD_TO_FLU
    # the VN-100 AHRS attitude as an ENU (FLU body) quaternion: roll/pitch keep their sign
    # convention, ENU yaw = pi/2 - heading; nose up is a negative rotation about FLU y.
    from scipy.spatial.transform import Rotation

    yaw_enu = 0.5 * math.pi - np.radians(imu["yaw_deg"])
    r = Rotation.from_euler("ZYX", np.column_stack(
        [yaw_enu, -np.radians(imu["pitch_deg"]), np.radians(imu["roll_deg"])]))
    qx, qy, qz, qw = r.as_quat().T
    ve, vn, speed = gps_velocity(gps)
    events: list[tuple[int, str, Any, str]] = []
    imu_t = "sensor_msgs/msg/Imu"
    for i, t in enumerate(imu["t"]):
        ns = round(t * 1e9)
        msg = MF.imu_msg(ts, ns, "imu_link", gyro[i], acc[i], seq=0 if ros1 else None)
        if ros1:
            msg.orientation.x, msg.orientation.y = float(qx[i]), float(qy[i])
            msg.orientation.z, msg.orientation.w = float(qz[i]), float(qw[i])
            msg.orientation_covariance[0] = 1e-4
        events.append((ns, "/imu/data", msg, imu_t))
        if ros1:
            events.append((ns, "/imu/mag", T["sensor_msgs/msg/MagneticField"](
                header=header(ns, "imu_link"),
                magnetic_field=V3(x=float(mag[i, 0]), y=float(mag[i, 1]), z=float(mag[i, 2])),
                magnetic_field_covariance=np.zeros(9)), "sensor_msgs/msg/MagneticField"))
    TwC = T["geometry_msgs/msg/TwistWithCovarianceStamped"]
    Tw, TwCov = T["geometry_msgs/msg/Twist"], T["geometry_msgs/msg/TwistWithCovariance"]
    for i, t in enumerate(gps["t"]):
        ns = round(t * 1e9)
        var = (gps["hdop"][i] * MF.DRMS_PER_HDOP) ** 2 / 2.0
        events.append((ns, "/gps/fix", T["sensor_msgs/msg/NavSatFix"](
            header=header(ns, "gps"),
            status=T["sensor_msgs/msg/NavSatStatus"](status=0, service=1),
            latitude=float(gps["latitude"][i]), longitude=float(gps["longitude"][i]),
            altitude=float(gps["altitude"][i]),
            position_covariance=np.diag([var, var, 4 * var]).ravel(),
            position_covariance_type=2), "sensor_msgs/msg/NavSatFix"))
        if ros1:
            events.append((ns, "/gps/vel", TwC(header=header(ns, "gps"), twist=TwCov(
                twist=Tw(linear=V3(x=float(ve[i]), y=float(vn[i]), z=0.0),
                         angular=V3(x=0.0, y=0.0, z=0.0)), covariance=np.zeros(36))),
                "geometry_msgs/msg/TwistWithCovarianceStamped"))
    # body velocity (10 Hz) and, for ROS 2, a heading in the map frame
    t10 = np.arange(imu["t"][0], imu["t"][-1], 0.1)
    u = np.interp(t10, gps["t"], speed)
    hq = np.interp(t10, imu["t"], np.unwrap(yaw_enu))
    for k, t in enumerate(t10):
        ns = round(t * 1e9)
        twist = Tw(linear=V3(x=float(u[k]), y=0.0, z=0.0), angular=V3(x=0.0, y=0.0, z=0.0))
        if ros1:
            pose = T["geometry_msgs/msg/PoseWithCovariance"](
                pose=T["geometry_msgs/msg/Pose"](
                    position=T["geometry_msgs/msg/Point"](x=0.0, y=0.0, z=0.0),
                    orientation=Q(x=0.0, y=0.0, z=math.sin(hq[k] / 2), w=math.cos(hq[k] / 2))),
                covariance=np.zeros(36))
            events.append((ns, "/odom", T["nav_msgs/msg/Odometry"](
                header=header(ns, "odom"), child_frame_id="base_link", pose=pose,
                twist=TwCov(twist=twist, covariance=np.zeros(36))), "nav_msgs/msg/Odometry"))
        else:
            events.append((ns, "/wheel/twist", TwC(header=header(ns, "base_link"), twist=TwCov(
                twist=twist, covariance=np.zeros(36))),
                "geometry_msgs/msg/TwistWithCovarianceStamped"))
            events.append((ns, "/heading", T["geometry_msgs/msg/PoseStamped"](
                header=header(ns, "map"), pose=T["geometry_msgs/msg/Pose"](
                    position=T["geometry_msgs/msg/Point"](x=0.0, y=0.0, z=0.0),
                    orientation=Q(x=0.0, y=0.0, z=math.sin(hq[k] / 2),
                                  w=math.cos(hq[k] / 2)))), "geometry_msgs/msg/PoseStamped"))
    events.sort(key=lambda e: e[0])
    topics = sorted({(e[1], e[3]) for e in events})
    return events, topics


def write_ros1(path: Path) -> None:
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS1_NOETIC)
    events, topics = _ros_events(ts, ros1=True)
    path.unlink(missing_ok=True)
    with Writer(path) as w:
        conns = {t: w.add_connection(t, ty, typestore=ts) for t, ty in topics}
        for ns, topic, msg, typ in events:
            w.write(conns[topic], ns, ts.serialize_ros1(msg, typ))


def write_ros2(path: Path) -> None:
    from rosbags.rosbag2 import Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS2_HUMBLE)
    events, topics = _ros_events(ts, ros1=False)
    if path.exists():
        shutil.rmtree(path)
    with Writer(path, version=8) as w:
        conns = {t: w.add_connection(t, ty, typestore=ts) for t, ty in topics}
        for ns, topic, msg, typ in events:
            w.write(conns[topic], ns, ts.serialize_cdr(msg, typ))


def write_ulog(path: Path) -> None:
    """sensor_combined (FRD), vehicle_gps_position with degrees, NED velocity and accuracy,
    vehicle_attitude (FRD/NED quaternion)."""
    imu, gps, _, _ = MF.vn100()
    t0 = imu["t"][0] - 100.0
    w = MF.ULogWriter(path, 0)
    w.info("sys_name", "PX4")
    w.format("sensor_combined", MF.SENSOR_COMBINED)
    w.format("vehicle_gps_position", [
        ("uint64_t", "timestamp"), ("double", "latitude_deg"), ("double", "longitude_deg"),
        ("double", "altitude_msl_m"), ("float", "s_variance_m_s"), ("float", "eph"),
        ("float", "hdop"), ("float", "vel_n_m_s"), ("float", "vel_e_m_s"),
        ("float", "vel_d_m_s"), ("bool", "vel_ned_valid"), ("float", "heading"),
        ("uint8_t", "fix_type"),
    ])
    w.format("vehicle_attitude", [("uint64_t", "timestamp"), ("float[4]", "q")])
    for name in ("sensor_combined", "vehicle_gps_position", "vehicle_attitude"):
        w.add_logged(name)
    q = MF.euler_to_quat(np.radians(imu["yaw_deg"]), np.radians(imu["pitch_deg"]),
                         np.radians(imu["roll_deg"]))
    ve, vn, _ = gps_velocity(gps)
    events: list[tuple[int, str, dict[str, object]]] = []
    for i, t in enumerate(imu["t"]):
        us = round((t - t0) * 1e6)
        g = np.array([imu["gyro_x"][i], imu["gyro_y"][i], imu["gyro_z"][i]])
        a = np.array([imu["acc_x"][i], imu["acc_y"][i], imu["acc_z"][i]])
        events.append((us, "sensor_combined", MF._sc(us, g, a, 25_000)))
        events.append((us, "vehicle_attitude", {"timestamp": us, "q": q[i].tolist()}))
    for i, t in enumerate(gps["t"]):
        us = round((t - t0) * 1e6)
        events.append((us, "vehicle_gps_position", {
            "timestamp": us, "latitude_deg": float(gps["latitude"][i]),
            "longitude_deg": float(gps["longitude"][i]),
            "altitude_msl_m": float(gps["altitude"][i]), "s_variance_m_s": 0.3,
            "eph": float(gps["hdop"][i] * MF.DRMS_PER_HDOP), "hdop": float(gps["hdop"][i]),
            "vel_n_m_s": float(vn[i]), "vel_e_m_s": float(ve[i]), "vel_d_m_s": 0.0,
            "vel_ned_valid": i != 3, "heading": float("nan"), "fix_type": 3 if i != 5 else 0}))
    events.sort(key=lambda e: e[0])
    for _, name, vals in events:
        w.data(name, vals)
    w.close()


def write_nmea(path: Path) -> None:
    """GGA, VTG (course and speed of the fix epoch), HDG with variation, VNYMR: one file."""
    imu, gps, ymr, gga = MF.vn100()
    ve, vn, speed = gps_velocity(gps)
    lines: list[tuple[float, str]] = []
    for i, t in enumerate(gps["t"]):
        lines.append((t, gga[i]))
        cog = math.degrees(math.atan2(ve[i], vn[i])) % 360.0
        lines.append((t + 0.002, MF._cs(
            f"GPVTG,{cog:.1f},T,,M,{speed[i] / 0.514444:.3f},N,{speed[i] * 3.6:.3f},K,D")))
    for i, t in enumerate(imu["t"]):
        lines.append((t, ymr[i]))
        if i % 4 == 0:
            lines.append((t + 0.0001, MF._cs(
                f"HCHDG,{(imu['yaw_deg'][i] + 14.0) % 360.0:.2f},,,14.0,W")))
    lines.sort(key=lambda x: x[0])
    path.write_text("".join(f"{t:.6f},{s}\n" for t, s in lines))


def write_wide_csv(path: Path) -> None:
    """One table, one row per IMU sample: time in ms, gyro deg/s and accel g (FRD, own
    names), Lat/Lon/Speed only on the rows of a fix."""
    imu, gps, _, _ = MF.vn100()
    ve, vn, speed = gps_velocity(gps)
    t0 = imu["t"][0]
    rows = ["Time [ms],GyroX,GyroY,GyroZ,AccX,AccY,AccZ,Lat,Lon,Speed"]
    fix_at = {int(np.argmin(np.abs(imu["t"] - tg))): k for k, tg in enumerate(gps["t"])
              if imu["t"][0] <= tg <= imu["t"][-1]}
    for i, t in enumerate(imu["t"]):
        g = [imu[f"gyro_{a}"][i] * 180.0 / math.pi for a in "xyz"]
        a = [imu[f"acc_{a}"][i] / 9.80665 for a in "xyz"]
        k = fix_at.get(i)
        gn = ["", "", ""] if k is None else [repr(float(gps["latitude"][k])),
                                             repr(float(gps["longitude"][k])),
                                             f"{speed[k]:.3f}"]
        rows.append(",".join([f"{(t - t0) * 1000:.3f}", *(repr(float(x)) for x in g),
                              *(repr(float(x)) for x in a), *gn]))
    path.write_text("\n".join(rows) + "\n")


def main() -> None:
    write_ros1(HERE / "vn100_drive_ros1.bag")
    write_ros2(HERE / "vn100_drive_ros2")
    write_ulog(HERE / "vn100_drive_vel.ulg")
    write_nmea(HERE / "vn100_vnymr.nmea")
    write_wide_csv(HERE / "wide_log.csv")
    total = sum(p.stat().st_size for p in HERE.rglob("*") if p.is_file())
    print(f"wrote {HERE} ({total / 1024:.0f} KiB)")


if __name__ == "__main__":
    main()
