"""The generic drive layout: write -> read round trip, mounts, settings errors."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from imubounds.errors import InputError
from imubounds.io.drive import Drive, GnssStream, ImuStream, VelocityStream
from imubounds.io.drive_layout import axes_matrix, parse_settings, read_layout, write_layout


def _drive(n: int = 50) -> Drive:
    rng = np.random.default_rng(1)
    t = np.arange(n) * 0.01
    return Drive(
        imu=ImuStream(t=t, accel=rng.normal(size=(n, 3)), gyro=rng.normal(size=(n, 3))),
        gnss=GnssStream(
            t=t[::10],
            lat_deg=np.full(5, 45.0),
            lon_deg=np.full(5, 7.0),
            vel_n_mps=np.ones(5),
            vel_e_mps=np.zeros(5),
        ),
        velocity=VelocityStream(t=t[::5], u_mps=np.full(10, 3.0)),
    )


def test_layout_round_trip_keeps_every_stream(tmp_path: Path) -> None:
    d = _drive()
    write_layout(d, tmp_path / "drive")
    back = read_layout(tmp_path / "drive")
    assert back.streams() == ["imu", "gnss", "velocity"]
    assert back.imu is not None and d.imu is not None
    np.testing.assert_allclose(back.imu.accel, d.imu.accel, rtol=1e-11)
    assert back.gnss is not None and back.gnss.velocity_ne() is not None
    np.testing.assert_allclose(back.gnss.velocity_ne()[0], 1.0)  # type: ignore[index]


def test_rotated_mount_is_undone_by_imu_axes(tmp_path: Path) -> None:
    d = _drive()
    assert d.imu is not None
    m = axes_matrix(["x", "-z", "y"])  # body y = -IMU z, body z = IMU y
    raw = d.imu.accel @ m  # IMU-axis readings of the body vectors
    out = tmp_path / "rot"
    out.mkdir()
    cols = {"time_s": d.imu.t}
    for i, ax in enumerate("xyz"):
        cols[f"accel_{ax}_mps2"] = raw[:, i]
        cols[f"gyro_{ax}_rads"] = (d.imu.gyro @ m)[:, i]
    import pandas as pd

    pd.DataFrame(cols).to_csv(out / "imu.csv", index=False, float_format="%.17g")
    pd.DataFrame({"time_s": [0.0], "lat_deg": [45.0], "lon_deg": [7.0]}).to_csv(
        out / "gnss.csv", index=False
    )
    (out / "drive.yaml").write_text("imu_axes: [x, -z, y]\n")
    back = read_layout(out)
    assert back.imu is not None
    np.testing.assert_allclose(back.imu.accel, d.imu.accel, rtol=1e-12, atol=1e-15)


@pytest.mark.parametrize(
    "data, message",
    [
        ({"gnss": {"cep": 3}}, "unknown key gnss.cep"),
        ({"colour": 1}, "unknown key 'colour'"),
        ({"imu_axes": ["x", "x", "z"]}, "not a rotation"),
        ({"imu_axes": ["x", "y", "w"]}, "use x, y, z"),
    ],
)
def test_settings_errors_name_the_key(data: dict[str, object], message: str) -> None:
    with pytest.raises(InputError, match=message):
        parse_settings(data)


def test_defaults_are_listed_as_assumed() -> None:
    s = parse_settings({"gnss": {"cep_m": 2.5}})
    assert s.gnss.cep_m == 2.5
    assert any("gnss.default_hdop" in a for a in s.assumed)
    assert not any("gnss.cep_m" in a for a in s.assumed)
    assert math.isclose(s.vehicle.max_speed_mps, 70.0)


def test_missing_imu_or_aiding_is_one_line_error() -> None:
    d = _drive()
    d.imu = None
    with pytest.raises(InputError, match="no IMU"):
        d.check()
    d = _drive()
    d.gnss = d.velocity = None
    with pytest.raises(InputError, match="no aiding sensor"):
        d.check()
