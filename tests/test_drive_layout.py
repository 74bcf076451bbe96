"""The generic drive layout: write -> read round trip, mounts, settings errors."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from imubounds.errors import InputError
from imubounds.io.drive import Drive, GnssStream, ImuStream, VelocityStream
from imubounds.io.drive.layout import axes_matrix, parse_settings, read_layout, write_layout


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


# ----------------------------------------------------------------------------- the docs

DOC = Path(__file__).resolve().parents[1] / "docs" / "drive-layout.md"


def _doc_example(dest: Path) -> Path:
    import re

    text = DOC.read_text(encoding="utf-8")
    blocks = re.findall(r"\*\*`([a-z_.]+)`\*\*\n\n```\w*\n(.*?)```", text, flags=re.S)
    assert {name for name, _ in blocks} == {
        "imu.csv", "gnss.csv", "velocity.csv", "heading.csv", "attitude.csv", "truth.csv",
        "drive.yaml"}
    dest.mkdir()
    for name, body in blocks:
        (dest / name).write_text(body)
    return dest


def test_the_documented_example_reads(tmp_path: Path) -> None:
    """The complete example of docs/drive-layout.md is a valid drive: every stream, the
    mount applied (gravity from the IMU's +y onto body z), settings given and assumed."""
    from imubounds.io import read_drive

    d = read_drive(_doc_example(tmp_path / "ex"))
    assert d.streams() == ["imu", "gnss", "velocity", "heading", "mag", "attitude", "truth"]
    assert d.imu is not None and d.mag is not None and d.velocity is not None
    np.testing.assert_allclose(d.imu.accel[0], [0.11, -0.02, 9.81])
    assert d.imu.gyro[0, 2] == pytest.approx(math.radians(0.01))  # body z = IMU y
    np.testing.assert_allclose(d.mag.mag[0], [21.3e-6, -0.9e-6, -44.0e-6])
    assert d.velocity.kind == "wheel"
    s = d.settings
    assert s.imu_axes == ("x", "-z", "y") and s.imu.preset == "xsens-mtx"
    assert s.gnss.cep_m == 2.5 and s.velocity.scale == 0.01 and s.vehicle.max_speed_mps == 50
    assert any("gnss.default_hdop = 1.0 (default)" in a for a in s.assumed)
    assert any("lever arm [0.0, 0.0, 1.2] m" in n and "ignored" in n for n in d.notes)
    assert any("imu_axes ['x', '-z', 'y'] applied" in n for n in d.notes)
    assert d.warnings == []


@pytest.mark.parametrize("fmt", ["csv", "csv.gz", "parquet"])
def test_every_table_format_reads_the_same(fmt: str, tmp_path: Path) -> None:
    from imubounds.io import read_drive

    src = read_drive(_doc_example(tmp_path / "ex"))
    write_layout(src, tmp_path / fmt, fmt=fmt)
    suffix = {"csv": ".csv", "csv.gz": ".csv.gz", "parquet": ".parquet"}[fmt]
    assert (tmp_path / fmt / f"imu{suffix}").is_file()
    back = read_drive(tmp_path / fmt)
    assert back.imu is not None and src.imu is not None
    np.testing.assert_array_equal(back.imu.accel, src.imu.accel)
    assert back.settings.imu_axes == ("x", "y", "z")  # written in body axes
    assert back.settings.gnss.cep_m == 2.5 and "gnss.default_hdop" in back.settings.defaulted


def test_every_mount_reads_to_the_same_body_imu(tmp_path: Path) -> None:
    """The same drive written with the IMU (and magnetometer) in each of the 24 possible
    orientations, with the matching imu_axes, reads to the same body-frame samples; and the
    readers' validation (gyro against the heading, gravity) passes for each."""
    import shutil

    from imubounds.io import read_drive
    from imubounds.io.drive.mount import proper_axes

    sys_path = Path(__file__).parent
    import sys

    sys.path.insert(0, str(sys_path))
    try:
        from test_drive_validate import make_drive
    finally:
        sys.path.remove(str(sys_path))
    base = make_drive(tmp_path / "base")
    ref = read_drive(base)
    assert ref.imu is not None
    imu = pd.read_csv(base / "imu.csv")
    axes_all = proper_axes()
    assert len(axes_all) == 24
    for k, axes in enumerate(axes_all):
        m = axes_matrix(list(axes))
        d = tmp_path / f"m{k}"
        shutil.copytree(base, d)
        out = {"time_s": imu["time_s"]}
        for kind, unit in (("gyro", "rads"), ("accel", "mps2")):
            body = imu[[f"{kind}_{a}_{unit}" for a in "xyz"]].to_numpy()
            sensor = body @ m  # v_sensor = R^T v_body
            for i, a in enumerate("xyz"):
                out[f"{kind}_{a}_{unit}"] = sensor[:, i]
        pd.DataFrame(out).to_csv(d / "imu.csv", index=False)
        (d / "drive.yaml").write_text(f"imu_axes: [{', '.join(axes)}]\n")
        got = read_drive(d)
        assert got.imu is not None
        np.testing.assert_allclose(got.imu.gyro, ref.imu.gyro, rtol=0, atol=1e-15,
                                   err_msg=str(axes))
        np.testing.assert_allclose(got.imu.accel, ref.imu.accel, rtol=0, atol=1e-15)
        # the same file without the mount is refused or read differently, never silently equal
        if axes != ("x", "y", "z"):
            (d / "drive.yaml").unlink()
            try:
                wrong = read_drive(d)
            except InputError:
                continue
            assert wrong.imu is not None
            assert not np.allclose(wrong.imu.accel, ref.imu.accel)


def test_noise_json_is_relative_to_the_yaml_and_presets_are_checked(tmp_path: Path) -> None:
    (tmp_path / "noise.json").write_text('{"channels": {"accel_x": {}, "gyro_z": {}}}')
    s = parse_settings({"imu": {"noise_json": "noise.json"}}, "x/drive.yaml", base_dir=tmp_path)
    assert s.imu.noise_json == str(tmp_path / "noise.json")
    with pytest.raises(InputError, match="imu.preset: unknown IMU preset 'nope'"):
        parse_settings({"imu": {"preset": "nope"}})
    with pytest.raises(InputError, match="give imu.noise_json or imu.preset, not both"):
        parse_settings({"imu": {"preset": "mtx", "noise_json": "noise.json"}}, base_dir=tmp_path)
    with pytest.raises(InputError, match="heading.fit is 'magic'; use one of auto, ellipse"):
        parse_settings({"heading": {"fit": "magic"}})
    with pytest.raises(InputError, match="gnss.cep_m must be a number, got 'three'"):
        parse_settings({"gnss": {"cep_m": "three"}})
    with pytest.raises(InputError, match="gnss.cep_m must be a finite number > 0, got 0"):
        parse_settings({"gnss": {"cep_m": 0}})
