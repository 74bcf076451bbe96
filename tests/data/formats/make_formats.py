"""Write the small real-data sample files of tests/data/formats/ (ROS, ULog, NMEA, HDF5).

Every file is written FROM real recordings with the libraries users have
(rosbags for ROS 1/ROS 2/MCAP, h5py for HDF5; a minimal ULog writer below,
because pyulog can only re-write a ULog it has parsed, not create one):

* ``adis_*``: the first rows of the bundled ADIS16405 static extract
  (``src/imubounds/data/adis16405_imu1_extract.csv.gz``; CC BY-NC-SA 4.0,
  University of Calgary via SMAC-Group/imudata).
* ``vn100_*``: the first seconds of ``../shared/data/dynamic/vn100_bu353_circle``
  (VectorNav VN-100 + BU-353N GPS in a car; MIT, Kiran1510/Automotive-Dead-Reckoning).

Run from the repository root (deterministic output):

    .venv/bin/python tests/data/formats/make_formats.py
"""

from __future__ import annotations

import csv
import gzip
import math
import shutil
import struct
from pathlib import Path

import h5py  # before anything that may import codac
import numpy as np

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[2]
BUNDLED = REPO / "src" / "imubounds" / "data" / "adis16405_imu1_extract.csv.gz"
VN100 = REPO.parent / "shared" / "data" / "dynamic" / "vn100_bu353_circle"
DEG = math.pi / 180.0
G0 = 9.80665
N_ADIS = 600  # samples (6 s at 100 Hz) in the ADIS files
N_ADIS_ROS1 = 600  # the ROS 1 bag
ROS_EPOCH_NS = 1_700_000_000 * 1_000_000_000  # header stamp of the first ADIS sample
ULOG_T0_US = 5_000_000  # PX4 time since boot of the first sample
VN_SECONDS = 10.0  # seconds of the VN-100 drive in the drive samples


# --------------------------------------------------------------------------- data
def adis_rows(n: int) -> list[list[str]]:
    """The first ``n`` data rows of the bundled extract, as text fields."""
    with gzip.open(BUNDLED, "rt", newline="") as f:
        r = csv.reader(f)
        next(r)
        return [row for _, row in zip(range(n), r, strict=False)]


def adis_si(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(sample index, gyro rad/s (n,3), accel m/s^2 (n,3)), FLU as the CSV path treats it.

    Converted exactly as the CSV reader converts (value * DEG, value * G0), so
    a reader that returns these doubles reproduces the CSV path bit for bit.
    """
    rows = adis_rows(n)
    v = np.array([[float(x) for x in row[1:7]] for row in rows])
    return np.arange(n), v[:, 0:3] * DEG, v[:, 3:6] * G0


def vn100() -> tuple[dict[str, np.ndarray], dict[str, np.ndarray], list[str], list[str]]:
    """IMU and GPS columns of the first VN_SECONDS of the VN-100 drive, and raw sentences."""
    with open(VN100 / "circle_data_0_imu.csv", newline="") as f:
        imu_rows = list(csv.DictReader(f))
    with open(VN100 / "circle_data_0_gps.csv", newline="") as f:
        gps_rows = list(csv.DictReader(f))
    t0 = float(gps_rows[0]["t"])
    imu_rows = [r for r in imu_rows if t0 <= float(r["t"]) < t0 + VN_SECONDS]
    gps_rows = [r for r in gps_rows if t0 <= float(r["t"]) < t0 + VN_SECONDS + 0.5]
    imu = {k: np.array([float(r[k]) for r in imu_rows]) for k in (
        "t", "gyro_x", "gyro_y", "gyro_z", "acc_x", "acc_y", "acc_z", "mag_x", "mag_y", "mag_z")}
    ymr = [r["raw_vnymr"].strip() for r in imu_rows]
    imu["yaw_deg"] = np.array([float(s.split(",")[1]) for s in ymr])
    imu["pitch_deg"] = np.array([float(s.split(",")[2]) for s in ymr])
    imu["roll_deg"] = np.array([float(s.split(",")[3]) for s in ymr])
    gps = {k: np.array([float(r[k]) for r in gps_rows]) for k in (
        "t", "latitude", "longitude", "altitude", "hdop")}
    gga = [r["raw_gpgga"].strip() for r in gps_rows]
    return imu, gps, ymr, gga


def euler_to_quat(yaw: np.ndarray, pitch: np.ndarray, roll: np.ndarray) -> np.ndarray:
    """ZYX Euler angles (rad) -> quaternions (w, x, y, z)."""
    cy, sy = np.cos(yaw / 2), np.sin(yaw / 2)
    cp, sp = np.cos(pitch / 2), np.sin(pitch / 2)
    cr, sr = np.cos(roll / 2), np.sin(roll / 2)
    return np.column_stack([
        cr * cp * cy + sr * sp * sy,
        sr * cp * cy - cr * sp * sy,
        cr * sp * cy + sr * cp * sy,
        cr * cp * sy - sr * sp * cy,
    ])


# --------------------------------------------------------------------------- ROS
def _ros_msgs(ts):  # type: ignore[no-untyped-def]
    T = ts.types
    return (T["sensor_msgs/msg/Imu"], T["std_msgs/msg/Header"],
            T["builtin_interfaces/msg/Time"], T["geometry_msgs/msg/Vector3"],
            T["geometry_msgs/msg/Quaternion"])


def _stamp(Time, ns: int):  # type: ignore[no-untyped-def]
    return Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def imu_msg(ts, ns: int, frame: str, w: np.ndarray, a: np.ndarray,  # type: ignore[no-untyped-def]
            seq: int | None = None):
    Imu, Header, Time, V3, Q = _ros_msgs(ts)
    hdr = {"seq": seq} if seq is not None else {}
    cov = np.zeros(9)
    ocov = np.zeros(9)
    ocov[0] = -1.0  # REP-145: no orientation
    return Imu(
        header=Header(stamp=_stamp(Time, ns), frame_id=frame, **hdr),
        orientation=Q(x=0.0, y=0.0, z=0.0, w=1.0), orientation_covariance=ocov,
        angular_velocity=V3(x=float(w[0]), y=float(w[1]), z=float(w[2])),
        angular_velocity_covariance=cov,
        linear_acceleration=V3(x=float(a[0]), y=float(a[1]), z=float(a[2])),
        linear_acceleration_covariance=cov,
    )


def write_adis_ros2(path: Path, n: int) -> None:
    from rosbags.rosbag2 import Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS2_HUMBLE)
    k, gyro, acc = adis_si(n)
    if path.exists():
        shutil.rmtree(path)
    with Writer(path, version=8) as w:
        conn = w.add_connection("/imu/data", "sensor_msgs/msg/Imu", typestore=ts)
        # A second, empty-ish topic so topic selection by type is exercised.
        other = w.add_connection("/status", "std_msgs/msg/String", typestore=ts)
        w.write(other, ROS_EPOCH_NS, ts.serialize_cdr(
            ts.types["std_msgs/msg/String"](data="adis16405 at rest"), "std_msgs/msg/String"))
        for i in k:
            ns = ROS_EPOCH_NS + int(i) * 10_000_000
            msg = imu_msg(ts, ns, "imu_link", gyro[i], acc[i])
            w.write(conn, ns + 150_000, ts.serialize_cdr(msg, "sensor_msgs/msg/Imu"))


def write_adis_ros1(path: Path, n: int) -> None:
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS1_NOETIC)
    k, gyro, acc = adis_si(n)
    path.unlink(missing_ok=True)
    w = Writer(path)
    w.set_compression(Writer.CompressionFormat.BZ2)
    with w:
        conn = w.add_connection("/imu", "sensor_msgs/msg/Imu", typestore=ts)
        for i in k:
            ns = ROS_EPOCH_NS + int(i) * 10_000_000
            msg = imu_msg(ts, ns, "imu_link", gyro[i], acc[i], seq=int(i))
            w.write(conn, ns + 150_000, ts.serialize_ros1(msg, "sensor_msgs/msg/Imu"))


from imubounds.frames import FRD_TO_FLU  # noqa: E402

DRMS_PER_HDOP = 1.2011224087864498 * 3.0  # CEP 3 m -> DRMS (m), HDOP 1


def write_vn100_mcap(path: Path) -> None:
    """The VN-100 drive as a ROS 2 MCAP bag: Imu + MagneticField (FLU), NavSatFix, heading."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS2_HUMBLE)
    T = ts.types
    imu, gps, _, _ = vn100()
    if path.exists():
        shutil.rmtree(path)
    Header, Time, V3, Q = (T["std_msgs/msg/Header"], T["builtin_interfaces/msg/Time"],
                           T["geometry_msgs/msg/Vector3"], T["geometry_msgs/msg/Quaternion"])
    events: list[tuple[int, str, object, str]] = []
    gyro = np.column_stack([imu["gyro_x"], imu["gyro_y"], imu["gyro_z"]]) * FRD_TO_FLU
    acc = np.column_stack([imu["acc_x"], imu["acc_y"], imu["acc_z"]]) * FRD_TO_FLU
    mag = np.column_stack([imu["mag_x"], imu["mag_y"], imu["mag_z"]]) * FRD_TO_FLU
    # VN-100 yaw: degrees clockwise from north (NED). ENU yaw = pi/2 - heading.
    yaw_enu = 0.5 * math.pi - np.radians(imu["yaw_deg"])
    q = euler_to_quat(yaw_enu, np.zeros_like(yaw_enu), np.zeros_like(yaw_enu))
    for i, t in enumerate(imu["t"]):
        ns = round(t * 1e9)
        st = _stamp(Time, ns)
        events.append((ns, "/imu/data", imu_msg(ts, ns, "imu_link", gyro[i], acc[i]),
                       "sensor_msgs/msg/Imu"))
        events.append((ns, "/imu/mag", T["sensor_msgs/msg/MagneticField"](
            header=Header(stamp=st, frame_id="imu_link"),
            magnetic_field=V3(x=float(mag[i, 0]), y=float(mag[i, 1]), z=float(mag[i, 2])),
            magnetic_field_covariance=np.zeros(9)), "sensor_msgs/msg/MagneticField"))
        if i % 4 == 0:  # heading at 10 Hz
            events.append((ns, "/imu/heading", T["geometry_msgs/msg/QuaternionStamped"](
                header=Header(stamp=st, frame_id="enu"),
                quaternion=Q(w=float(q[i, 0]), x=float(q[i, 1]), y=float(q[i, 2]),
                             z=float(q[i, 3]))), "geometry_msgs/msg/QuaternionStamped"))
    for i, t in enumerate(gps["t"]):
        ns = round(t * 1e9)
        var = (gps["hdop"][i] * DRMS_PER_HDOP) ** 2 / 2.0  # per axis, DRMS = HDOP * DRMS(CEP)
        cov = np.diag([var, var, 4 * var]).ravel()
        events.append((ns, "/gps/fix", T["sensor_msgs/msg/NavSatFix"](
            header=Header(stamp=_stamp(Time, ns), frame_id="gps"),
            status=T["sensor_msgs/msg/NavSatStatus"](status=0, service=1),
            latitude=float(gps["latitude"][i]), longitude=float(gps["longitude"][i]),
            altitude=float(gps["altitude"][i]), position_covariance=cov,
            position_covariance_type=2), "sensor_msgs/msg/NavSatFix"))
    events.sort(key=lambda e: e[0])
    with Writer(path, version=8, storage_plugin=StoragePlugin.MCAP) as w:
        conns = {}
        for topic, typ in (("/imu/data", "sensor_msgs/msg/Imu"),
                           ("/imu/mag", "sensor_msgs/msg/MagneticField"),
                           ("/imu/heading", "geometry_msgs/msg/QuaternionStamped"),
                           ("/gps/fix", "sensor_msgs/msg/NavSatFix")):
            conns[topic] = w.add_connection(topic, typ, typestore=ts)
        for ns, topic, msg, typ in events:
            w.write(conns[topic], ns, ts.serialize_cdr(msg, typ))


# --------------------------------------------------------------------------- ULog
_ULOG_TYPES = {"uint64_t": "Q", "int64_t": "q", "uint32_t": "I", "int32_t": "i",
               "uint16_t": "H", "int16_t": "h", "uint8_t": "B", "int8_t": "b",
               "float": "f", "double": "d", "bool": "?", "char": "c"}


class ULogWriter:
    """A minimal ULog (version 1) writer following the PX4 file format spec.

    File header (16 bytes: magic ``ULog\\x01\\x12\\x35``, version, start time
    in µs), a flag-bits message ``B``, format definitions ``F``, info ``I``,
    then ``A`` (add logged message, assigning a msg_id to a topic) and ``D``
    (data: msg_id + the packed little-endian fields, no padding). Each message
    starts with ``uint16 msg_size`` (payload bytes) and ``uint8 msg_type``.
    """

    def __init__(self, path: Path, t0_us: int = 0) -> None:
        self.f = open(path, "wb")  # noqa: SIM115
        self.f.write(b"ULog\x01\x12\x35" + bytes([1]) + struct.pack("<Q", t0_us))
        self._msg(b"B", bytes(16) + struct.pack("<3Q", 0, 0, 0))
        self.formats: dict[str, list[tuple[str, str, int]]] = {}
        self.ids: dict[str, int] = {}

    def _msg(self, kind: bytes, payload: bytes) -> None:
        self.f.write(struct.pack("<HB", len(payload), kind[0]) + payload)

    def info(self, key: str, value: str) -> None:
        k = f"char[{len(value)}] {key}".encode()
        self._msg(b"I", bytes([len(k)]) + k + value.encode())

    def format(self, name: str, fields: list[tuple[str, str]]) -> None:
        """``fields``: (type, name) pairs, type like ``float[3]`` or ``uint64_t``."""
        text = name + ":" + "".join(f"{t} {n};" for t, n in fields)
        self._msg(b"F", text.encode())
        parsed = []
        for t, n in fields:
            base, _, cnt = t.partition("[")
            parsed.append((_ULOG_TYPES[base], n, int(cnt.rstrip("]")) if cnt else 1))
        self.formats[name] = parsed

    def add_logged(self, name: str, multi_id: int = 0) -> int:
        msg_id = len(self.ids)
        self.ids[name] = msg_id
        self._msg(b"A", struct.pack("<BH", multi_id, msg_id) + name.encode())
        return msg_id

    def data(self, name: str, values: dict[str, object]) -> None:
        out = [struct.pack("<H", self.ids[name])]
        for code, n, cnt in self.formats[name]:
            v = values[n]
            if cnt == 1:
                out.append(struct.pack("<" + code, v))
            else:
                out.append(struct.pack(f"<{cnt}{code}", *list(v)))  # type: ignore[call-overload]
        self._msg(b"D", b"".join(out))

    def close(self) -> None:
        self.f.close()


SENSOR_COMBINED = [
    ("uint64_t", "timestamp"), ("float[3]", "gyro_rad"), ("uint32_t", "gyro_integral_dt"),
    ("int32_t", "accelerometer_timestamp_relative"), ("float[3]", "accelerometer_m_s2"),
    ("uint32_t", "accelerometer_integral_dt"), ("uint8_t", "accelerometer_clipping"),
    ("uint8_t", "gyro_clipping"), ("uint8_t", "accel_calibration_count"),
    ("uint8_t", "gyro_calibration_count"),
]


def _sc(t_us: int, g: np.ndarray, a: np.ndarray, dt_us: int) -> dict[str, object]:
    return {"timestamp": t_us, "gyro_rad": g.tolist(), "gyro_integral_dt": dt_us,
            "accelerometer_timestamp_relative": 0, "accelerometer_m_s2": a.tolist(),
            "accelerometer_integral_dt": dt_us, "accelerometer_clipping": 0,
            "gyro_clipping": 0, "accel_calibration_count": 1, "gyro_calibration_count": 1}


def write_adis_ulog(path: Path, n: int) -> None:
    """The ADIS extract as PX4 ``sensor_combined`` (float32, FRD: y and z negated from FLU)."""
    k, gyro, acc = adis_si(n)
    w = ULogWriter(path, ULOG_T0_US)
    w.info("sys_name", "PX4")
    w.info("ver_hw", "ADIS16405_EXTRACT")
    w.format("sensor_combined", SENSOR_COMBINED)
    w.add_logged("sensor_combined")
    for i in k:
        w.data("sensor_combined", _sc(ULOG_T0_US + int(i) * 10_000, gyro[i] * FRD_TO_FLU,
                                      acc[i] * FRD_TO_FLU, 10_000))
    w.close()


def write_vn100_ulog(path: Path) -> None:
    """The VN-100 drive as a PX4 log: sensor_combined, vehicle_gps_position, magnetometer, attitude.

    The VN-100 axes are FRD already (like PX4); its yaw/pitch/roll are NED Euler angles.
    """
    imu, gps, _, _ = vn100()
    t0 = imu["t"][0] - 100.0  # boot 100 s before the first sample
    w = ULogWriter(path, 0)
    w.info("sys_name", "PX4")
    w.format("sensor_combined", SENSOR_COMBINED)
    w.format("vehicle_gps_position", [
        ("uint64_t", "timestamp"), ("int32_t", "lat"), ("int32_t", "lon"), ("int32_t", "alt"),
        ("float", "eph"), ("float", "epv"), ("float", "hdop"), ("float", "vdop"),
        ("uint8_t", "fix_type"), ("uint8_t", "satellites_used"),
    ])
    w.format("vehicle_magnetometer", [("uint64_t", "timestamp"), ("float[3]", "magnetometer_ga")])
    w.format("vehicle_attitude", [("uint64_t", "timestamp"), ("float[4]", "q")])
    for name in ("sensor_combined", "vehicle_gps_position", "vehicle_magnetometer",
                 "vehicle_attitude"):
        w.add_logged(name)
    q = euler_to_quat(np.radians(imu["yaw_deg"]), np.radians(imu["pitch_deg"]),
                      np.radians(imu["roll_deg"]))
    events: list[tuple[int, str, dict[str, object]]] = []
    for i, t in enumerate(imu["t"]):
        us = round((t - t0) * 1e6)
        g = np.array([imu["gyro_x"][i], imu["gyro_y"][i], imu["gyro_z"][i]])
        a = np.array([imu["acc_x"][i], imu["acc_y"][i], imu["acc_z"][i]])
        events.append((us, "sensor_combined", _sc(us, g, a, 25_000)))
        m = np.array([imu["mag_x"][i], imu["mag_y"][i], imu["mag_z"][i]]) * 1e4  # T -> gauss
        events.append(
            (us, "vehicle_magnetometer", {"timestamp": us, "magnetometer_ga": m.tolist()})
        )
        events.append((us, "vehicle_attitude", {"timestamp": us, "q": q[i].tolist()}))
    for i, t in enumerate(gps["t"]):
        us = round((t - t0) * 1e6)
        events.append((us, "vehicle_gps_position", {
            "timestamp": us, "lat": round(gps["latitude"][i] * 1e7),
            "lon": round(gps["longitude"][i] * 1e7), "alt": round(gps["altitude"][i] * 1e3),
            "eph": float(gps["hdop"][i] * DRMS_PER_HDOP), "epv": 5.0,
            "hdop": float(gps["hdop"][i]), "vdop": 1.5, "fix_type": 3, "satellites_used": 11}))
    events.sort(key=lambda e: e[0])
    for _, name, vals in events:
        w.data(name, vals)
    w.close()


def write_ulog_without_imu(path: Path) -> None:
    """A valid ULog holding only GPS (from the VN-100 drive): no IMU topic."""
    _, gps, _, _ = vn100()
    w = ULogWriter(path, 0)
    w.format("vehicle_gps_position", [
        ("uint64_t", "timestamp"), ("int32_t", "lat"), ("int32_t", "lon"), ("int32_t", "alt"),
        ("float", "hdop"), ("uint8_t", "fix_type"),
    ])
    w.add_logged("vehicle_gps_position")
    for i in range(len(gps["t"])):
        w.data("vehicle_gps_position", {
            "timestamp": 1_000_000 + i * 1_000_000, "lat": round(gps["latitude"][i] * 1e7),
            "lon": round(gps["longitude"][i] * 1e7), "alt": round(gps["altitude"][i] * 1e3),
            "hdop": float(gps["hdop"][i]), "fix_type": 3})
    w.close()


# --------------------------------------------------------------------------- NMEA
def _cs(body: str) -> str:
    c = 0
    for ch in body:
        c ^= ord(ch)
    return f"${body}*{c:02X}"


def write_vn100_nmea(nmea: Path, imu_csv: Path, bad: Path) -> None:
    """Host-stamped capture: the real $GPGGA and $VNYMR sentences, HDT from the VN-100 yaw,
    RMC with the course over ground between consecutive fixes; and the IMU as CSV."""
    from imubounds.geodesy import geodetic_to_enu

    imu, gps, ymr, gga = vn100()
    lines: list[tuple[float, str]] = [(t, s) for t, s in zip(gps["t"], gga, strict=True)]
    e, n, _ = geodetic_to_enu(gps["latitude"], gps["longitude"])
    for i in range(1, len(gps["t"])):
        cog = math.degrees(math.atan2(e[i] - e[i - 1], n[i] - n[i - 1])) % 360.0
        spd = math.hypot(e[i] - e[i - 1], n[i] - n[i - 1]) / (gps["t"][i] - gps["t"][i - 1])
        f = gga[i].split(",")
        body = (f"GPRMC,{f[1]},A,{f[2]},{f[3]},{f[4]},{f[5]},{spd / 0.514444:.2f},{cog:.1f},"
                "191125,,,D")
        lines.append((gps["t"][i] + 0.001, _cs(body)))
    for i, t in enumerate(imu["t"]):
        lines.append((t, ymr[i]))
        if i % 4 == 0:
            lines.append((t + 0.0001, _cs(f"HEHDT,{imu['yaw_deg'][i] % 360.0:.3f},T")))
    lines.sort(key=lambda x: x[0])
    text = "".join(f"{t:.6f},{s}\n" for t, s in lines)
    nmea.write_text(text)
    with open(imu_csv, "w", newline="") as f:
        wr = csv.writer(f)
        wr.writerow(["t", "gyro_x", "gyro_y", "gyro_z", "acc_x", "acc_y", "acc_z"])
        for i in range(len(imu["t"])):
            wr.writerow([repr(float(imu["t"][i]))] + [repr(float(imu[k][i])) for k in (
                "gyro_x", "gyro_y", "gyro_z", "acc_x", "acc_y", "acc_z")])
    # Bad-checksum capture: the first 40 lines, with one GGA checksum altered.
    out = []
    for line in text.splitlines()[:40]:
        if "GPGGA" in line and not any("GPGGA" in o for o in out[1:]) and out:
            line = line[:-2] + ("00" if line[-2:] != "00" else "01")
        out.append(line)
    bad.write_text("\n".join(out) + "\n")


# --------------------------------------------------------------------------- HDF5
def write_adis_hdf5(path: Path, n: int, bad: Path) -> None:
    """Two tables: /imu0 a group of 1-D datasets (time_s, gyro_*_dps, accel_*_g, exact
    values of the CSV), /imu1 the same as a compound dataset with a unit attribute style.
    And a file with no IMU table at all (only an attribute and a 3-D image)."""
    rows = adis_rows(n)
    names = ["time_s", "gyro_x_dps", "gyro_y_dps", "gyro_z_dps", "accel_x_g", "accel_y_g",
             "accel_z_g"]
    v = np.array([[float(x) for x in row] for row in rows])
    with h5py.File(path, "w", track_order=True) as f:
        f.attrs["source"] = "ADIS16405 static extract, University of Calgary (CC BY-NC-SA 4.0)"
        g = f.create_group("imu0")
        for j, name in enumerate(names):
            g.create_dataset(name, data=v[:, j])
        rec = np.zeros(n, dtype=[("t", "<i8")] + [(nm, "<f8") for nm in (
            "gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z")])
        rec["t"] = np.arange(n, dtype=np.int64) * 10_000_000
        for j, nm in enumerate(("gyro_x", "gyro_y", "gyro_z")):
            rec[nm] = v[:, 1 + j] * DEG
        for j, nm in enumerate(("accel_x", "accel_y", "accel_z")):
            rec[nm] = v[:, 4 + j] * G0
        f.create_dataset("imu1", data=rec[:200])
    with h5py.File(bad, "w") as f:
        f.attrs["note"] = "no IMU table in this file"
        f.create_dataset("camera/frames", data=np.zeros((2, 4, 4), dtype=np.uint8))


def main() -> None:
    out = HERE
    write_adis_ros2(out / "adis_ros2", N_ADIS)
    write_adis_ros1(out / "adis_ros1.bag", N_ADIS_ROS1)
    write_adis_ulog(out / "adis_px4.ulg", N_ADIS)
    write_adis_hdf5(out / "adis.h5", N_ADIS, out / "no_imu_table.h5")
    write_vn100_mcap(out / "vn100_drive_mcap")
    write_vn100_ulog(out / "vn100_drive.ulg")
    write_ulog_without_imu(out / "gps_only.ulg")
    write_vn100_nmea(out / "vn100.nmea", out / "vn100_imu.csv", out / "bad_checksum.nmea")
    total = sum(p.stat().st_size for p in out.rglob("*") if p.is_file())
    print(f"wrote {out} ({total / 1024:.0f} KiB)")


if __name__ == "__main__":
    main()
