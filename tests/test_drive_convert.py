"""``imubounds convert`` end to end on every supported drive input, and the round trip:
reading the converted directory gives the same Drive as reading the source directly."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from imubounds.cli import main
from imubounds.io import Drive, read_drive
from imubounds.io.drive.layout import settings_to_dict

HERE = Path(__file__).parent
FORMATS = HERE / "data" / "formats"
DRIVES = HERE / "data" / "drive"
WIDE_MAP = (
    "time_ms=Time [ms],gyro_x_dps=GyroX,gyro_y_dps=GyroY,gyro_z_dps=GyroZ,accel_x_g=AccX,"
    "accel_y_g=AccY,accel_z_g=AccZ,lat_deg=Lat,lon_deg=Lon,speed_mps=Speed"
)

# (id, inputs (relative to tests/ or shared data), convert options, streams expected)
CASES: list[tuple[str, list[str], list[str], set[str]]] = [
    ("vn100-shared", ["@shared/dynamic/vn100_bu353_circle"], [],
     {"imu", "gnss", "mag", "attitude"}),
    ("vn100-bundled-files", ["@bundled/circle_data_0_imu.csv", "@bundled/circle_data_0_gps.csv"],
     ["--format", "parquet"], {"imu", "gnss", "mag", "attitude"}),
    ("comma2k19", ["@shared/dynamic/comma2k19_example1"], ["--format", "csv.gz"],
     {"imu", "gnss", "velocity", "mag", "truth"}),
    ("ros1", ["data/drive/vn100_drive_ros1.bag"], [],
     {"imu", "gnss", "velocity", "mag", "attitude"}),
    ("ros2", ["data/drive/vn100_drive_ros2"], ["--topic", "velocity=/wheel/twist"],
     {"imu", "gnss", "velocity", "heading"}),
    ("mcap", ["data/formats/vn100_drive_mcap"], [], {"imu", "gnss", "heading", "mag"}),
    ("ulog", ["data/formats/vn100_drive.ulg"], [], {"imu", "gnss", "mag", "attitude"}),
    ("ulog-velocity", ["data/drive/vn100_drive_vel.ulg"], [], {"imu", "gnss", "attitude"}),
    ("nmea+imu", ["data/formats/vn100.nmea", "data/formats/vn100_imu.csv"],
     ["--imu-frame", "FRD"], {"imu", "gnss", "heading"}),
    ("nmea-vnymr", ["data/drive/vn100_vnymr.nmea"], [],
     {"imu", "gnss", "heading", "mag", "attitude"}),
    ("wide-csv", ["data/drive/wide_log.csv"], ["--columns", WIDE_MAP, "--imu-axes", "x,-y,-z"],
     {"imu", "gnss"}),
]


def _inputs(items: list[str], shared: Path) -> list[str]:
    from imubounds.io.drive.readers import bundled_drive_log

    out = []
    for s in items:
        if s.startswith("@shared/"):
            out.append(str(shared / s[len("@shared/"):]))
        elif s.startswith("@bundled/"):
            out.append(str(bundled_drive_log() / s[len("@bundled/"):]))
        else:
            out.append(str(HERE / s))
    return out


def _read_kwargs(opts: list[str]) -> dict[str, Any]:
    """The read_drive arguments equal to the convert options of a case."""
    from imubounds.cli._common import parse_topics
    from imubounds.io.drive.readers import parse_drive_columns

    kw: dict[str, Any] = {}
    it = iter(opts)
    for o in it:
        v = next(it)
        if o == "--columns":
            kw["columns"] = parse_drive_columns(v)
        elif o == "--imu-axes":
            kw["imu_axes"] = v.split(",")
        elif o == "--imu-frame":
            kw["imu_frame"] = v
        elif o == "--topic":
            kw["topics"] = parse_topics([v])
    return kw


def _angles_equal(a: np.ndarray, b: np.ndarray, what: str) -> None:
    d = np.angle(np.exp(1j * (np.asarray(a) - np.asarray(b))))
    ok = np.isfinite(a) == np.isfinite(b)
    assert ok.all(), what
    assert np.nanmax(np.abs(d), initial=0.0) < 1e-12, f"{what}: {np.nanmax(np.abs(d))}"


def assert_same_drive(a: Drive, b: Drive) -> None:
    """Same streams, same samples (to 1e-12 for angles written in degrees), same settings
    (but the mount, which the written IMU already carries), same defaults."""
    assert a.streams() == b.streams()
    for name in a.streams():
        sa, sb = getattr(a, name), getattr(b, name)
        np.testing.assert_array_equal(sa.t, sb.t, err_msg=f"{name}.t")
        for f in vars(sa):
            va, vb = getattr(sa, f), getattr(sb, f)
            label = f"{name}.{f}"
            if f in ("t", "input_units") or isinstance(va, str | bool | tuple):
                if f in ("kind", "source", "true_north", "unit", "origin"):
                    assert va == vb or (f == "origin" and np.allclose(va, vb, equal_nan=True)), (
                        label, va, vb)
                continue
            if isinstance(va, dict):
                assert va.keys() == vb.keys(), label
                for k in va:
                    np.testing.assert_array_equal(va[k], vb[k], err_msg=f"{label}.{k}")
                continue
            assert (va is None) == (vb is None), label
            if va is None:
                continue
            if f.endswith("_rad"):
                _angles_equal(va, vb, label)
            else:
                np.testing.assert_allclose(va, vb, rtol=1e-13, atol=0, err_msg=label)
    da = settings_to_dict(a.settings, keep_defaults=True)
    db = settings_to_dict(b.settings, keep_defaults=True)
    da.pop("imu_axes", None)
    db.pop("imu_axes", None)
    assert da == db
    assert set(a.settings.defaulted) == set(b.settings.defaulted)
    assert b.settings.imu_axes == ("x", "y", "z")


@pytest.mark.parametrize("case", CASES, ids=[c[0] for c in CASES])
def test_convert_end_to_end_and_round_trip(
    case: tuple[str, list[str], list[str], set[str]], shared_data: Path, tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    name, items, opts, streams = case
    inputs = _inputs(items, shared_data)
    out = tmp_path / "layout"
    assert main(["convert", *inputs, "-o", str(out), *opts]) == 0
    summary = capsys.readouterr().out  # the summary is on stdout
    assert f"-> {out}" in summary
    run = json.loads((out / "run.json").read_text())
    assert run["complete"] and "drive.yaml" in run["files"]
    direct = read_drive(inputs, **_read_kwargs(opts))
    assert set(direct.streams()) == streams
    back = read_drive(out)
    assert back.layout == "generic" and back.meta["converted_from"] == direct.source
    assert_same_drive(direct, back)
    # the mount applied by the reader stays visible after the conversion
    for n in direct.notes:
        assert n in back.notes


def test_converted_vn100_keeps_the_mount_note(shared_data: Path, tmp_path: Path) -> None:
    out = tmp_path / "vn"
    assert main(["convert", str(shared_data / "dynamic/vn100_bu353_circle"), "-o", str(out),
                 "-q"]) == 0
    back = read_drive(out)
    assert any("mounted backwards" in n for n in back.notes)
    assert back.settings.imu.preset == "vn100"
    text = (out / "drive.yaml").read_text()
    assert "preset: vn100" in text and "cep_m" not in text  # defaults stay out (assumed)
    assert any("gnss.cep_m = 3.0 (default)" in x for x in back.settings.assumed)


def test_convert_refuses_to_overwrite_and_writes_nothing_on_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "o"
    out.mkdir()
    (out / "imu.csv").write_text("mine\n")
    src = str(DRIVES / "vn100_drive_ros2")
    assert main(["convert", src, "-o", str(out)]) == 2
    assert "imubounds did not write: imu.csv" in capsys.readouterr().err
    assert (out / "imu.csv").read_text() == "mine\n"
    assert main(["convert", src, "-o", str(out), "--force", "-q"]) == 0
    assert (out / "imu.csv").read_text().startswith("time_s,")
    # an input error leaves a new target absent
    bad = tmp_path / "bad"
    assert main(["convert", str(FORMATS / "adis_ros2"), "-o", str(bad)]) == 2
    assert not bad.exists()


def test_round_trip_keeps_headings_true_and_magnetic(tmp_path: Path) -> None:
    d = read_drive(DRIVES / "vn100_drive_ros2")
    assert d.heading is not None and d.heading.true_north
    from imubounds.io import write_layout

    write_layout(d, tmp_path / "x")
    back = read_drive(tmp_path / "x")
    assert back.heading is not None and back.heading.true_north
    assert "reference: 'true'" in (tmp_path / "x" / "drive.yaml").read_text() or (
        "reference: true" in (tmp_path / "x" / "drive.yaml").read_text()
    )
    assert math.isclose(float(back.heading.heading_rad[0]), float(d.heading.heading_rad[0]),
                        rel_tol=1e-13)


@pytest.mark.parametrize(
    "args, message",
    [
        (["--imu-axes", "x,x,z"], "is not a rotation"),
        (["--imu-axes", "x,y,w"], "use x, y, z with an optional sign"),
        (["--max-speed", "-5"], "argument --max-speed: must be > 0"),
        (["--max-speed", "nan"], "is not a finite number"),
        (["--time-offset", "inf"], "is not a finite number"),
        (["--topic", "compass=/x"], "unknown role 'compass'"),
        (["--topic", "gnss="], "names no topic"),
        (["--columns", "lat=Lat"], "--columns key 'lat' is not a drive-layout column"),
        (["--columns", "time_s"], "write LAYOUT_COLUMN=SOURCE_COLUMN"),
        (["--format", "xlsx"], "argument --format: invalid choice"),
    ],
)
def test_bad_convert_options(args: list[str], message: str, tmp_path: Path,
                             capsys: pytest.CaptureFixture[str]) -> None:
    src = str(DRIVES / "vn100_drive_ros2")
    try:
        code = main(["convert", src, "-o", str(tmp_path / "o"), *args])
    except SystemExit as exc:  # argparse rejects the option while parsing
        code = int(exc.code or 0)
    assert code == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_options_that_do_not_apply_are_errors(tmp_path: Path,
                                              capsys: pytest.CaptureFixture[str]) -> None:
    ulog = str(FORMATS / "vn100_drive.ulg")
    assert main(["convert", ulog, "-o", str(tmp_path / "a"), "--topic", "gnss=/x"]) == 2
    assert "--topic applies to ROS bags only" in capsys.readouterr().err
    assert main(["convert", ulog, "-o", str(tmp_path / "b"), "--columns", "lat_deg=x"]) == 2
    assert "--columns applies to CSV logs only" in capsys.readouterr().err
    bag = str(DRIVES / "vn100_drive_ros1.bag")
    assert main(["convert", bag, "-o", str(tmp_path / "c"), "--topic", "heading=/gps/fix"]) == 2
    assert "is sensor_msgs/msg/NavSatFix, not geometry_msgs" in capsys.readouterr().err
