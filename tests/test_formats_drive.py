"""Drive logs from a ROS 2 MCAP bag, a PX4 ULog and an NMEA capture + IMU CSV.

All three samples hold the same 10 s of the real VN-100/BU-353N drive
(tests/data/formats/make_formats.py), written in each format's own frames
(ROS: FLU/ENU; PX4: FRD/NED; VN-100 CSV and $VNYMR: FRD, yaw clockwise from
north). The readers must agree after their explicit conversions.
"""

from __future__ import annotations

import csv
import importlib.util
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from imubounds.errors import InputError
from imubounds.frames import enu_yaw_to_heading, quaternion_yaw_enu
from imubounds.io import Drive, read_drive
from imubounds.io.nmea import nmea_checksum, read_drive_nmea, scan_nmea, sniff_nmea
from imubounds.io.rosbag import read_drive_rosbag
from imubounds.io.ulog import quaternion_ned_heading, read_drive_ulog

FORMATS = Path(__file__).parent / "data" / "formats"
VN100 = (
    Path(__file__).resolve().parents[1].parent
    / "shared"
    / "data"
    / "dynamic"
    / ("vn100_bu353_circle")
)


def _load_make_formats() -> Any:
    spec = importlib.util.spec_from_file_location("make_formats", FORMATS / "make_formats.py")
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


MAKE = _load_make_formats()


@pytest.fixture(scope="module")
def drives() -> dict[str, Drive]:
    return {
        "mcap": read_drive(FORMATS / "vn100_drive_mcap"),
        "ulog": read_drive(FORMATS / "vn100_drive.ulg"),
        "nmea": read_drive([FORMATS / "vn100.nmea", FORMATS / "vn100_imu.csv"], imu_frame="FRD"),
    }


def _raw_imu() -> dict[str, np.ndarray]:
    with open(FORMATS / "vn100_imu.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    return {k: np.array([float(r[k]) for r in rows]) for k in rows[0]}


def test_imu_frd_to_flu(drives: dict[str, Drive]) -> None:
    raw = _raw_imu()  # VN-100 FRD
    for name, d in drives.items():
        assert d.imu is not None
        tol = 1e-6 if name == "ulog" else 0.0  # PX4 stores float32
        g, a = d.imu.gyro, d.imu.accel
        np.testing.assert_allclose(g[:, 0], raw["gyro_x"], rtol=tol, atol=tol, err_msg=name)
        np.testing.assert_allclose(g[:, 1], -raw["gyro_y"], rtol=tol, atol=tol)
        np.testing.assert_allclose(g[:, 2], -raw["gyro_z"], rtol=tol, atol=tol)
        np.testing.assert_allclose(a[:, 2], -raw["acc_z"], rtol=tol, atol=tol)
        assert np.median(a[:, 2]) > 9.0, name  # FLU: z up reads +g at rest/level


def test_gnss_agrees_and_covariance_gives_h_acc(drives: dict[str, Drive]) -> None:
    m, u, n = (drives[k].gnss for k in ("mcap", "ulog", "nmea"))
    assert m is not None and u is not None and n is not None
    np.testing.assert_allclose(m.lat_deg, n.lat_deg, rtol=0, atol=1e-12)
    np.testing.assert_allclose(u.lat_deg, n.lat_deg, rtol=0, atol=2e-7)  # PX4: int32 1e-7 deg
    np.testing.assert_allclose(m.alt_m, n.alt_m, atol=1e-9)  # type: ignore[arg-type]
    # The MCAP NavSatFix covariance was written from the real HDOP (per-axis variance
    # (HDOP x DRMS)^2 / 2): it comes back as the per-axis 1-sigma h_acc_m.
    assert n.hdop is not None and m.h_acc_m is not None and u.h_acc_m is not None
    np.testing.assert_allclose(m.h_acc_m, n.hdop * MAKE.DRMS_PER_HDOP / math.sqrt(2), rtol=1e-12)
    np.testing.assert_allclose(u.h_acc_m, n.hdop * MAKE.DRMS_PER_HDOP, rtol=1e-6)  # PX4 eph
    np.testing.assert_allclose(u.hdop, n.hdop, rtol=1e-6)  # type: ignore[arg-type]
    assert n.hdop[0] == 0.96 and n.usable().all() and m.usable().all() and u.usable().all()
    np.testing.assert_allclose(m.t, n.t, atol=1e-6)


def test_headings_clockwise_from_north_agree(drives: dict[str, Drive]) -> None:
    """ENU quaternion (ROS), NED quaternion (PX4 attitude) and HDT all give the VN-100 yaw."""
    m, n = drives["mcap"].heading, drives["nmea"].heading
    u = drives["ulog"].attitude
    assert m is not None and n is not None and u is not None and u.yaw_rad is not None
    assert m.true_north and n.true_north
    # the first VN-100 yaw of the sample is +066.172 deg (clockwise from north)
    assert math.degrees(m.heading_rad[0]) == pytest.approx(66.172, abs=1e-9)
    assert math.degrees(u.yaw_rad[0]) == pytest.approx(66.172, abs=1e-4)
    assert math.degrees(n.heading_rad[0]) == pytest.approx(66.172, abs=1e-9)
    # PX4 times are since boot (another clock): compare sample by sample (MCAP at 10 Hz).
    d = np.angle(np.exp(1j * (u.yaw_rad[::4] - m.heading_rad)))
    assert np.max(np.abs(d)) < 1e-4
    assert u.t[0] == pytest.approx(100.0) and m.t[0] > 1.7e9
    np.testing.assert_allclose(n.heading_rad, m.heading_rad, atol=1e-9)


def test_magnetometer_frames_and_units(drives: dict[str, Drive]) -> None:
    raw_first = (2.653e-05, 7.91e-06 * -1, 3.577e-05)  # FRD tesla of the first VN-100 sample
    m, u = drives["mcap"].mag, drives["ulog"].mag
    assert m is not None and u is not None
    expect = np.array(raw_first) * np.array([1.0, -1.0, -1.0])
    np.testing.assert_allclose(m.mag[0], expect, rtol=1e-12)
    np.testing.assert_allclose(u.mag[0], expect, rtol=1e-6)  # gauss float32 -> tesla


def test_drive_sources_and_velocity(drives: dict[str, Drive]) -> None:
    assert {k: d.layout for k, d in drives.items()} == {
        "mcap": "rosbag", "ulog": "ulog", "nmea": "nmea"}
    assert drives["mcap"].meta["topics"]["heading"] == "/imu/heading"
    # RMC speed and course come with the GGA fix of the same epoch (the first fix has none)
    g = drives["nmea"].gnss
    assert g is not None and g.speed_mps is not None and g.course_rad is not None
    assert np.isnan(g.speed_mps[0]) and np.isfinite(g.speed_mps[1:]).all()
    assert 0 <= np.nanmin(g.course_rad) and np.nanmax(g.course_rad) < 2 * math.pi


def test_rosbag_drive_topic_errors() -> None:
    with pytest.raises(InputError, match="no aiding sensor"):
        read_drive(FORMATS / "adis_ros2")
    with pytest.raises(InputError, match="not geometry_msgs/msg/QuaternionStamped or"):
        read_drive_rosbag(FORMATS / "vn100_drive_mcap", topics={"heading": "/gps/fix"})
    with pytest.raises(InputError, match="unknown topic role"):
        read_drive_rosbag(FORMATS / "vn100_drive_mcap", topics={"compass": "/x"})


def test_ulog_drive_without_gps() -> None:
    with pytest.raises(InputError, match="no aiding sensor"):
        read_drive(FORMATS / "adis_px4.ulg")
    assert read_drive_ulog(FORMATS / "adis_px4.ulg").gnss is None


# ----------------------------------------------------------------------------- NMEA
def test_nmea_bad_checksum_error_and_skip(tmp_path: Path) -> None:
    with pytest.raises(InputError, match=r"bad_checksum.nmea, line 2: NMEA checksum '00'"):
        scan_nmea(FORMATS / "bad_checksum.nmea")
    cap = scan_nmea(FORMATS / "bad_checksum.nmea", on_bad_checksum="skip")
    assert any(
        "1 sentence(s) with a bad checksum skipped (first at line 2)" in n for n in cap.notes
    )
    assert len(cap.sentences) == 39


def test_nmea_utc_time_without_host_stamps(tmp_path: Path) -> None:
    """Strip the host stamps: times come from GGA UTC on the RMC date (2025-11-19)."""
    p = tmp_path / "utc.nmea"
    p.write_text(
        "".join(
            line.split(",", 1)[1] + "\n"
            for line in (FORMATS / "vn100.nmea").read_text().splitlines()
        )
    )
    imu = tmp_path / "imu.csv"
    raw = _raw_imu()
    host = read_drive_nmea(FORMATS / "vn100.nmea", FORMATS / "vn100_imu.csv", imu_frame="FRD")
    # the first GGA is 22:09:32.00 UTC on 19 Nov 2025; the host clock said 1763590170.28
    utc0 = 1763590172.0
    assert host.gnss is not None
    assert host.gnss.t[0] == pytest.approx(1763590170.2813318, abs=1e-6)
    with open(imu, "w") as f:
        f.write("t,gyro_x,gyro_y,gyro_z,acc_x,acc_y,acc_z\n")
        for i in range(raw["t"].size):
            f.write(
                ",".join(
                    repr(float(raw[k][i]))
                    for k in ("t", "gyro_x", "gyro_y", "gyro_z", "acc_x", "acc_y", "acc_z")
                )
                + "\n"
            )
    d = read_drive_nmea(p, imu, imu_frame="FRD", time_offset_s=0.0)
    assert d.gnss is not None
    assert d.gnss.t[0] == pytest.approx(utc0, abs=1e-6)
    assert np.all(np.diff(d.gnss.t) == pytest.approx(1.0, abs=1e-9))
    assert d.meta["nmea_time"] == "UTC"


def test_nmea_hdg_variation(tmp_path: Path) -> None:
    lines = [
        line for line in (FORMATS / "vn100.nmea").read_text().splitlines() if "HDT" not in line
    ]
    t = float(lines[len(lines) // 2].split(",")[0])
    body = "HCHDG,100.0,,,5.0,W"
    lines.insert(1, f"{t + 0.01:.6f},${body}*{nmea_checksum(body):02X}")
    body = "HCHDG,358.0,,,4.0,E"
    lines.insert(2, f"{t + 0.5:.6f},${body}*{nmea_checksum(body):02X}")
    p = tmp_path / "hdg.nmea"
    p.write_text("\n".join(lines) + "\n")
    d = read_drive_nmea(p, FORMATS / "vn100_imu.csv", imu_frame="FRD")
    assert d.heading is not None
    np.testing.assert_allclose(np.degrees(d.heading.heading_rad), [95.0, 2.0], atol=1e-9)
    assert d.heading.true_north  # every HDG carried its variation
    assert any("heading from HDG" in n for n in d.notes)


def test_sniff_nmea() -> None:
    assert sniff_nmea(b"$GPGGA,220932.00,4220.2")
    assert sniff_nmea(b"1763590170.281332,$GPGGA,2209")
    assert not sniff_nmea(b"time_s,gyro_x_dps\n0.0,1")


@pytest.mark.skipif(not VN100.is_dir(), reason="real VN-100 data folder not beside the repo")
def test_nmea_gga_matches_the_original_gps_csv() -> None:
    g = read_drive_nmea(FORMATS / "vn100.nmea", FORMATS / "vn100_imu.csv", imu_frame="FRD").gnss
    assert g is not None
    with open(VN100 / "circle_data_0_gps.csv", newline="") as f:
        rows = list(csv.DictReader(f))[: g.t.size]
    np.testing.assert_allclose(g.lat_deg, [float(r["latitude"]) for r in rows], atol=1e-9)
    np.testing.assert_allclose(g.lon_deg, [float(r["longitude"]) for r in rows], atol=1e-9)


# ----------------------------------------------------------------------------- conversions
def test_quaternion_conventions_reference_values() -> None:
    s = math.sqrt(0.5)
    # ENU: yaw +90 deg (facing north) -> heading 0; facing east -> heading 90 deg.
    assert enu_yaw_to_heading(quaternion_yaw_enu(*np.array([[0.0], [0.0], [s], [s]])))[0] == (
        pytest.approx(0.0, abs=1e-12)
    )
    assert enu_yaw_to_heading(np.array([0.0]))[0] == pytest.approx(math.pi / 2)
    # NED: yaw +90 deg about down = facing east = heading 90 deg.
    q = np.array([[s, 0.0, 0.0, s]])
    assert quaternion_ned_heading(q)[0] == pytest.approx(math.pi / 2)
    assert quaternion_ned_heading(np.array([[s, 0.0, 0.0, -s]]))[0] == pytest.approx(
        3 * math.pi / 2
    )


@settings(max_examples=60, deadline=None)
@given(st.floats(-10.0, 10.0), st.floats(-1.2, 1.2), st.floats(-1.2, 1.2))
def test_enu_and_ned_quaternions_give_the_same_heading(
    yaw: float, pitch: float, roll: float
) -> None:
    """A NED attitude with heading h and the ENU attitude with yaw pi/2 - h agree."""
    euler_to_quat = MAKE.euler_to_quat
    q_ned = euler_to_quat(np.array([yaw]), np.array([pitch]), np.array([roll]))
    h = quaternion_ned_heading(q_ned)[0]
    assert 0.0 <= h < 2 * math.pi
    assert math.isclose(math.cos(h), math.cos(yaw), abs_tol=1e-9)
    assert math.isclose(math.sin(h), math.sin(yaw), abs_tol=1e-9)
    q_enu = euler_to_quat(np.array([math.pi / 2 - yaw]), np.zeros(1), np.zeros(1))
    h2 = enu_yaw_to_heading(quaternion_yaw_enu(q_enu[:, 1], q_enu[:, 2], q_enu[:, 3], q_enu[:, 0]))[
        0
    ]
    assert math.isclose(math.cos(h2 - h), 1.0, abs_tol=1e-9)


@pytest.mark.parametrize(
    "sources",
    [
        ["vn100_drive.ulg"],
        ["vn100_drive_mcap"],
    ],
)
def test_dynamic_cli_reads_every_drive_format(sources: list[str], tmp_path: Path) -> None:
    """``imubounds dynamic`` takes a ULog and a ROS 2/MCAP bag as they are (NMEA with an
    FRD IMU CSV needs the IMU frame: see the convert tests)."""
    import json

    from imubounds.cli import main

    base = Path(__file__).parent / "data" / "formats"
    out = tmp_path / "dyn"
    code = main(
        [
            "dynamic",
            *(str(base / s) for s in sources),
            "-o",
            str(out),
            "--quiet",
            "--no-plot",
            "--no-report",
            "--imu-spec",
            "accel_nd=0.00137,accel_bs=0.00039,gyro_nd=0.0035,gyro_bs=0.0028",
        ]
    )
    assert code == 0
    doc = json.loads((out / "dynamic.json").read_text())
    full = doc["modes"]["full"]
    assert full["smoother"]["epochs"] >= 5
    assert {"accel_x", "accel_y", "gyro_z"} <= set(full["verdict"])
    assert full["margins"]["accel_x"], "no margins for accel_x"
