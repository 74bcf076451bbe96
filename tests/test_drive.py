"""Drive-log model and readers: simulator dirs, VN-100 + BU-353N, comma2k19."""

from __future__ import annotations

import math
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from imubounds.dynamic.aiding.compass import course_over_ground
from imubounds.dynamic.aiding.geodesy import geodetic_to_enu
from imubounds.dynamic.scenario import ScenarioConfig, simulate, write_scenario
from imubounds.errors import InputError
from imubounds.frames import wrap_pi
from imubounds.io.drive_readers import detect_layout, read_drive


@pytest.fixture(scope="module")
def vn100_dir(shared_data: Path) -> Path:
    return shared_data / "dynamic" / "vn100_bu353_circle"


@pytest.fixture(scope="module")
def comma_dir(shared_data: Path) -> Path:
    return shared_data / "dynamic" / "comma2k19_example1"


@pytest.fixture(scope="module")
def sim_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("sim") / "run"
    write_scenario(
        simulate(ScenarioConfig(duration_s=120, distance_m=1200, seed=4, rate_hz=1.0)), d
    )
    return d


def test_layout_detection(vn100_dir: Path, comma_dir: Path, sim_dir: Path, tmp_path: Path) -> None:
    assert detect_layout([str(sim_dir)])[0] == "sim"
    assert detect_layout([str(vn100_dir)])[0] == "vn100"
    files = sorted(str(p) for p in vn100_dir.glob("*.csv"))
    assert detect_layout(files)[0] == "vn100"
    assert detect_layout([str(comma_dir)])[0] == "comma2k19"
    with pytest.raises(InputError, match="not a known drive-log directory"):
        detect_layout([str(tmp_path)])
    with pytest.raises(InputError, match="no such file"):
        detect_layout([str(tmp_path / "nope")])


def test_vn100_conventions(vn100_dir: Path) -> None:
    log = read_drive(str(vn100_dir))
    assert log.layout == "vn100" and log.frame == "FLU"
    assert log.imu_rate_hz == pytest.approx(40, rel=0.05)
    assert log.gps_rate_hz == pytest.approx(1, rel=0.01)
    assert np.all(log.hdop > 0.9) and log.fix.all()
    # FLU: gravity reaction points up
    assert np.mean(log.accel[:, 2]) == pytest.approx(9.6, abs=0.3)
    # the unit is mounted backwards: detected and rotated
    assert log.settings["mount"] == "backward"
    assert any("mounted backwards" in w for w in log.warnings)
    # after rotation the yaw agrees with the GPS course (within the compass error)
    e, n, _ = geodetic_to_enu(log.lat, log.lon)
    tm, cog = course_over_ground(log.gps_t, e, n, 2.0)
    assert log.heading is not None and log.heading_t is not None
    yaw = np.interp(tm, log.heading_t, np.unwrap(log.heading))
    assert abs(np.median(np.asarray(wrap_pi(yaw - cog)))) < math.radians(30)
    # a left-hand circle: CCW yaw rate positive, centripetal acceleration to the left (+y)
    assert np.mean(log.gyro[:, 2]) > 0.15
    assert np.mean(log.accel[:, 1]) > 0.5
    # yaw (clockwise) rate = -gyro_z (CCW) in FLU
    rate = np.gradient(np.unwrap(log.heading), log.heading_t)
    assert np.corrcoef(rate, -log.gyro[:, 2])[0, 1] > 0.8


def test_vn100_forward_mount_option(vn100_dir: Path) -> None:
    log = read_drive(str(vn100_dir), mount="forward")
    assert log.settings["mount"] == "forward"
    assert np.mean(log.accel[:, 1]) < -0.5


def test_comma_conventions(comma_dir: Path) -> None:
    log = read_drive(str(comma_dir))
    assert log.layout == "comma2k19"
    assert log.imu_rate_hz == pytest.approx(104, rel=0.05)
    assert np.all(np.isnan(log.hdop))
    assert log.truth is not None and log.truth_origin is not None
    tr = log.truth
    # body x carries the velocity: u ~ speed, |v| small
    assert np.median(tr["u"]) > 15 and np.median(np.abs(tr["v"])) < 0.5
    # highway heading north: model psi ~ +pi/2
    assert np.median(tr["psi"]) == pytest.approx(math.pi / 2, abs=0.1)
    # the phone gyro (converted to FLU) follows the truth yaw rate
    gz = np.interp(tr["t"], log.imu_t, log.gyro[:, 2])
    assert np.corrcoef(gz, tr["r"])[0, 1] > 0.7
    assert np.mean(log.accel[:, 2]) == pytest.approx(9.66, abs=0.2)
    # u-blox fixes vs truth position: a few metres
    e, n, org = geodetic_to_enu(log.lat, log.lon, log.alt)
    te, tn, _ = geodetic_to_enu(tr["lat"], tr["lon"], None, origin=(org[0], org[1], 0.0))
    ge = np.interp(log.gps_t, tr["t"], te)
    gn = np.interp(log.gps_t, tr["t"], tn)
    assert np.median(np.hypot(e - ge, n - gn)) < 5.0


def test_sim_reader(sim_dir: Path) -> None:
    log = read_drive(str(sim_dir))
    assert log.layout == "sim" and log.truth is not None
    assert log.accel.shape == (121, 3)
    assert "estimator" in log.settings


def _copy_vn(vn100_dir: Path, tmp_path: Path) -> tuple[Path, Path]:
    d = tmp_path / "vn"
    d.mkdir()
    imu = d / "x_imu.csv"
    gps = d / "x_gps.csv"
    shutil.copy(vn100_dir / "circle_data_0_imu.csv", imu)
    shutil.copy(vn100_dir / "circle_data_0_gps.csv", gps)
    return imu, gps


def test_bad_inputs(vn100_dir: Path, tmp_path: Path) -> None:
    imu, gps = _copy_vn(vn100_dir, tmp_path)
    g = pd.read_csv(gps)
    # no overlap in time between IMU and GPS
    g2 = g.copy()
    g2["t"] = g2["t"] + 10_000
    g2.to_csv(gps, index=False)
    with pytest.raises(InputError, match="do not overlap in time"):
        read_drive([str(imu), str(gps)])
    # GPS all missing
    g3 = g.copy()
    g3["latitude"] = np.nan
    g3.to_csv(gps, index=False)
    with pytest.raises(InputError, match="no usable GPS fix"):
        read_drive([str(imu), str(gps)])
    # unsorted time
    g.to_csv(gps, index=False)
    i = pd.read_csv(imu)
    i.loc[[10, 11], "t"] = i.loc[[11, 10], "t"].to_numpy()
    i.to_csv(imu, index=False)
    with pytest.raises(InputError, match=r"not strictly increasing at sample 11 \(0-based"):
        read_drive([str(imu), str(gps)])
    # missing column
    i = i.drop(columns=["gyro_z"])
    i.to_csv(imu, index=False)
    with pytest.raises(InputError, match="missing column"):
        read_drive([str(imu), str(gps)])
