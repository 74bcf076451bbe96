"""Drive readers into the Drive model: VN-100 + BU-353N, comma2k19, the old simulator
directory, format detection, the mount check against the truth."""

from __future__ import annotations

import math
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from imubounds.dynamic.scenario import ScenarioConfig, simulate, write_scenario
from imubounds.errors import InputError
from imubounds.frames import axes_matrix, wrap_pi
from imubounds.geodesy import course_over_ground, geodetic_to_enu
from imubounds.io import Drive, read_drive
from imubounds.io.drive.mount import mount_check
from imubounds.io.drive.readers import detect_layout


@pytest.fixture(scope="module")
def vn100_dir(shared_data: Path) -> Path:
    return shared_data / "dynamic" / "vn100_bu353_circle"


@pytest.fixture(scope="module")
def comma_dir(shared_data: Path) -> Path:
    return shared_data / "dynamic" / "comma2k19_example1"


@pytest.fixture(scope="module")
def comma(comma_dir: Path) -> Drive:
    return read_drive(comma_dir)


@pytest.fixture(scope="module")
def sim_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("sim") / "run"
    write_scenario(
        simulate(ScenarioConfig(duration_s=120, distance_m=1200, seed=4, rate_hz=1.0)), d
    )
    return d


def test_layout_detection(vn100_dir: Path, comma_dir: Path, sim_dir: Path, tmp_path: Path) -> None:
    # the simulator writes the generic drive layout (with its scenario.json beside it)
    assert detect_layout([str(sim_dir)])[0] == "generic"
    assert detect_layout([str(vn100_dir)])[0] == "vn100"
    files = sorted(str(p) for p in vn100_dir.glob("*.csv"))
    assert detect_layout(files)[0] == "vn100"
    assert detect_layout([str(comma_dir)])[0] == "comma2k19"
    fmt = Path(__file__).parent / "data" / "formats"
    assert detect_layout([fmt / "adis_ros1.bag"])[0] == "rosbag"
    assert detect_layout([fmt / "adis_ros2"])[0] == "rosbag"
    assert detect_layout([fmt / "vn100_drive.ulg"])[0] == "ulog"
    assert detect_layout([fmt / "vn100.nmea", fmt / "vn100_imu.csv"])[0] == "nmea"
    assert detect_layout([fmt / "vn100_imu.csv"])[0] == "csv"
    with pytest.raises(InputError, match="not a known drive-log directory"):
        detect_layout([str(tmp_path)])
    with pytest.raises(InputError, match="no such file"):
        detect_layout([str(tmp_path / "nope")])


def test_vn100_conventions(vn100_dir: Path) -> None:
    d = read_drive(vn100_dir)
    assert d.layout == "vn100" and d.imu is not None and d.gnss is not None
    assert d.imu.rate_hz == pytest.approx(40, rel=0.05)
    assert np.all(d.gnss.hdop > 0.9) and d.gnss.usable().all()  # type: ignore[operator]
    assert d.mag is not None and d.mag.unit == "T" and d.heading is None
    # FLU: gravity reaction points up
    assert np.mean(d.imu.accel[:, 2]) == pytest.approx(9.6, abs=0.3)
    # the unit is mounted backwards: detected, rotated through imu_axes, said
    assert d.settings.imu_axes == ("-x", "-y", "z") and "imu_axes" not in d.settings.defaulted
    assert any("mounted backwards" in w for w in d.warnings)
    assert any("imu_axes ['-x', '-y', 'z'] applied" in n for n in d.notes)
    assert d.settings.imu.preset == "vn100"
    # after rotation the attitude yaw agrees with the GPS course (within the compass error)
    a = d.attitude
    assert a is not None and a.yaw_rad is not None and a.source == "ahrs"
    e, n, _ = geodetic_to_enu(d.gnss.lat_deg, d.gnss.lon_deg)
    tm, cog = course_over_ground(d.gnss.t, e, n, 2.0)
    yaw = np.interp(tm, a.t, np.unwrap(a.yaw_rad))
    assert abs(np.median(np.asarray(wrap_pi(yaw - cog)))) < math.radians(30)
    # the rotated unit: roll and pitch change sign (the unit's pitch is about +3.5 deg)
    assert np.median(np.degrees(a.pitch_rad)) == pytest.approx(-3.5, abs=1.0)
    # a left-hand circle: CCW yaw rate positive, centripetal acceleration to the left (+y)
    assert np.mean(d.imu.gyro[:, 2]) > 0.15
    assert np.mean(d.imu.accel[:, 1]) > 0.5
    # yaw (clockwise) rate = -gyro_z (CCW) in FLU
    rate = np.gradient(np.unwrap(a.yaw_rad), a.t)
    assert np.corrcoef(rate, -np.interp(a.t, d.imu.t, d.imu.gyro[:, 2]))[0, 1] > 0.8


def test_vn100_forward_mount_option_and_explicit_axes(vn100_dir: Path) -> None:
    d = read_drive(vn100_dir, mount="forward")
    assert d.settings.imu_axes == ("x", "y", "z")
    assert d.imu is not None and np.mean(d.imu.accel[:, 1]) < -0.5
    # the same rotation given as imu_axes (the mount option is then not needed)
    d2 = read_drive(vn100_dir, imu_axes=["-x", "-y", "z"])
    back = read_drive(vn100_dir)
    assert d2.imu is not None and back.imu is not None
    np.testing.assert_array_equal(d2.imu.gyro, back.imu.gyro)


def test_comma_conventions(comma: Drive) -> None:
    d = comma
    assert d.layout == "comma2k19" and d.imu is not None and d.gnss is not None
    assert d.imu.rate_hz == pytest.approx(104, rel=0.05)
    assert d.gnss.hdop is None and d.gnss.h_acc_m is None
    # every u-blox fix (about 10 Hz), with speed and bearing
    assert d.gnss.t.size == 579 and np.median(np.diff(d.gnss.t)) == pytest.approx(0.1, abs=0.01)
    assert d.gnss.has_velocity
    tr = d.truth
    assert tr is not None and tr.u_mps is not None and tr.v_mps is not None
    assert tr.heading_rad is not None
    # body x carries the velocity: u ~ speed, |v| small
    assert np.median(tr.u_mps) > 15 and np.median(np.abs(tr.v_mps)) < 0.5
    # highway heading north: compass heading near 0
    assert abs(np.median(np.asarray(wrap_pi(tr.heading_rad)))) < 0.1
    # the phone gyro (converted to FLU) follows the truth yaw rate
    gz = np.interp(tr.t, d.imu.t, d.imu.gyro[:, 2])
    assert np.corrcoef(gz, tr.extra["r"])[0, 1] > 0.7
    assert np.mean(d.imu.accel[:, 2]) == pytest.approx(9.66, abs=0.2)
    # u-blox fixes vs truth position: a few metres
    e, n, _ = geodetic_to_enu(d.gnss.lat_deg, d.gnss.lon_deg, None, origin=tr.origin)
    ge = np.interp(d.gnss.t, tr.t, tr.east_m)
    gn = np.interp(d.gnss.t, tr.t, tr.north_m)
    assert np.median(np.hypot(e - ge, n - gn)) < 5.0


def test_comma_gnss_velocity_and_can_speed_agree_with_truth(comma: Drive) -> None:
    """The u-blox speed/bearing (deg clockwise from true north) and the CAN speed against the
    post-processed truth: speed within 0.3 m/s median, course within 2 deg median."""
    g, tr, v = comma.gnss, comma.truth, comma.velocity
    assert g is not None and tr is not None and v is not None and v.kind == "can"
    assert tr.u_mps is not None and tr.heading_rad is not None
    assert g.speed_mps is not None and g.course_rad is not None
    u = np.interp(g.t, tr.t, tr.u_mps)
    assert np.median(np.abs(g.speed_mps - u)) < 0.3, np.median(np.abs(g.speed_mps - u))
    h = np.interp(g.t, tr.t, np.unwrap(tr.heading_rad))
    dc = np.degrees(np.abs(np.asarray(wrap_pi(g.course_rad - h))))
    assert np.median(dc) < 2.0, np.median(dc)
    uc = np.interp(v.t, tr.t, tr.u_mps)
    assert np.median(np.abs(v.u_mps - uc)) < 0.5, np.median(np.abs(v.u_mps - uc))


def test_comma_mount_is_checked_against_the_truth(comma: Drive) -> None:
    """The phone axes fit the truth (score close to 3) and a wrongly rotated IMU is caught."""
    chk = comma.meta["mount_check"]
    assert chk["best_axes"] == ["x", "y", "z"] and chk["score"] > 2.5, chk
    assert "mount_mismatch" not in comma.counts
    wrong = Drive(imu=comma.imu, truth=comma.truth)
    assert comma.imu is not None
    m = axes_matrix(["-y", "x", "z"])  # the phone turned 90 deg in its holder
    wrong.imu = type(comma.imu)(t=comma.imu.t, accel=comma.imu.accel @ m.T,
                                gyro=comma.imu.gyro @ m.T)
    res = mount_check(wrong)
    assert res is not None
    assert res["best_score"] > res["score"] + 0.5, res
    # rotating back by the mapping found restores the phone axes
    np.testing.assert_allclose(axes_matrix(res["best_axes"]) @ m, np.eye(3), atol=0)


def _copy_vn(vn100_dir: Path, tmp_path: Path) -> tuple[Path, Path]:
    d = tmp_path / "vn"
    d.mkdir()
    imu = d / "x_imu.csv"
    gps = d / "x_gps.csv"
    shutil.copy(vn100_dir / "circle_data_0_imu.csv", imu)
    shutil.copy(vn100_dir / "circle_data_0_gps.csv", gps)
    return imu, gps


def test_bad_vn100_inputs(vn100_dir: Path, tmp_path: Path) -> None:
    imu, gps = _copy_vn(vn100_dir, tmp_path)
    g = pd.read_csv(gps)
    g2 = g.copy()
    g2["t"] = g2["t"] + 10_000
    g2.to_csv(gps, index=False)
    with pytest.raises(InputError, match="does not overlap the IMU"):
        read_drive([imu, gps])
    g3 = g.copy()
    g3["latitude"] = np.nan
    g3.to_csv(gps, index=False)
    with pytest.raises(InputError, match="no usable GPS fix"):
        read_drive([imu, gps])
    g.to_csv(gps, index=False)
    i = pd.read_csv(imu)
    i.loc[[10, 11], "t"] = i.loc[[11, 10], "t"].to_numpy()
    i.to_csv(imu, index=False)
    with pytest.raises(InputError, match=r"imu time_s is not strictly increasing at row 12"):
        read_drive([imu, gps])
    i = i.drop(columns=["gyro_z"])
    i.to_csv(imu, index=False)
    with pytest.raises(InputError, match="missing column"):
        read_drive([imu, gps])
