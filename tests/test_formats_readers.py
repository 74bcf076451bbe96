"""Readers of ROS 1/ROS 2/MCAP bags, PX4 ULog, NMEA and HDF5 on real sample files.

The samples in tests/data/formats/ are written from real recordings by
tests/data/formats/make_formats.py (the bundled ADIS16405 static extract and the
VN-100/BU-353N drive). Round trips: bag/ULog/HDF5 -> ``imubounds static`` ->
the same noise.json numbers as the CSV of the same samples.
"""

from __future__ import annotations

import gzip
import importlib.util
import json
import math
import shutil
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from imubounds.cli import main as cli_main
from imubounds.errors import InputError
from imubounds.io import bundled_static_log, find_reader, read_imu
from imubounds.units import DEG, G0

FORMATS = Path(__file__).parent / "data" / "formats"
N_ADIS = 600
CHANNELS = ("gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z")


def _make_formats_module() -> Any:
    spec = importlib.util.spec_from_file_location("make_formats", FORMATS / "make_formats.py")
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


@pytest.fixture(scope="module")
def adis_csv(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The first N_ADIS rows of the bundled extract, as the original CSV text."""
    out = tmp_path_factory.mktemp("csv") / "adis_first.csv"
    with gzip.open(bundled_static_log(), "rt") as f:
        lines = [next(f) for _ in range(N_ADIS + 1)]
    out.write_text("".join(lines))
    return out


@pytest.fixture(scope="module")
def adis_ref(adis_csv: Path) -> Any:
    return read_imu(adis_csv)


def _static(path: Path | str, out: Path, *extra: str) -> dict[str, Any]:
    code = cli_main(["static", str(path), "-o", str(out), "--models", "none", "--no-plot",
                     "--no-report", "-q", *extra])
    assert code == 0
    return json.loads((out / "noise.json").read_text())  # type: ignore[no-any-return]


def _noise_numbers(js: dict[str, Any]) -> dict[str, float]:
    out: dict[str, float] = {}
    for ch, c in js["channels"].items():
        for method in ("slope", "fit"):
            for term, e in c["noise"][method].items():
                if isinstance(e, dict) and isinstance(e.get("value"), int | float):
                    out[f"{ch}.{method}.{term}"] = float(e["value"])
        out[f"{ch}.sigma_c"] = float(c["sigma_c"])
        out[f"{ch}.random_walk_95"] = float(c["random_walk_95"]["value"])
        for k, v in enumerate(c["allan"]["adev"]):
            out[f"{ch}.adev{k}"] = float(v)
    return out


def _assert_same_noise(a: dict[str, Any], b: dict[str, Any], rtol: float) -> None:
    na, nb = _noise_numbers(a), _noise_numbers(b)
    assert na.keys() == nb.keys()
    assert len(na) > 6 * 10
    for k in na:
        assert na[k] == pytest.approx(nb[k], rel=rtol, abs=1e-300), k


# ----------------------------------------------------------------------------- dispatch
@pytest.mark.parametrize(
    ("name", "fmt"),
    [("adis_ros2", "rosbag"), ("adis_ros2/adis_ros2.db3", "rosbag"), ("adis_ros1.bag", "rosbag"),
     ("vn100_drive_mcap", "rosbag"), ("vn100_drive_mcap/vn100_drive_mcap.mcap", "rosbag"),
     ("adis_px4.ulg", "ulog"), ("adis.h5", "hdf5"), ("vn100.nmea", "nmea")],
)
def test_find_reader_by_suffix_and_directory(name: str, fmt: str) -> None:
    assert find_reader(FORMATS / name).name == fmt


@pytest.mark.parametrize(
    ("name", "fmt"),
    [("adis_ros1.bag", "rosbag"), ("adis_px4.ulg", "ulog"), ("adis.h5", "hdf5"),
     ("vn100_drive_mcap/vn100_drive_mcap.mcap", "rosbag")],
)
def test_find_reader_by_magic_bytes(tmp_path: Path, name: str, fmt: str) -> None:
    dst = tmp_path / "renamed.bin"
    shutil.copy(FORMATS / name, dst)
    assert find_reader(dst).name == fmt


# ----------------------------------------------------------------------------- values
@pytest.mark.parametrize("name", ["adis_ros2", "adis_ros1.bag", "adis.h5"])
def test_float64_formats_equal_the_csv_exactly(name: str, adis_ref: Any) -> None:
    opts = {"dataset": "/imu0"} if name.endswith(".h5") else None
    log = read_imu(FORMATS / name, format_options=opts)
    n = log.n_samples
    assert n in (N_ADIS, 600)
    for c in CHANNELS:
        np.testing.assert_array_equal(log.channels[c], adis_ref.channels[c][:n])
    assert log.rate_hz == 100.0
    np.testing.assert_allclose(np.diff(log.t), 0.01, atol=5e-7)  # epoch stamps: float64 s


def test_rosbag_stamps_topic_and_frame() -> None:
    log = read_imu(FORMATS / "adis_ros2")
    assert log.frame == "FLU"
    assert log.source.endswith(":/imu/data")  # found by type, not the /status topic
    assert log.t[0] == 1_700_000_000.0  # header stamp, not the (later) receive time
    assert log.input_units["gyro_x"] == "rad/s" and log.input_units["accel_z"] == "m/s^2"


def test_rosbag_topic_option() -> None:
    log = read_imu(FORMATS / "adis_ros2", format_options={"topic": "/imu/data"})
    assert log.n_samples == N_ADIS
    with pytest.raises(InputError, match=r"no topic '/nope'.*/imu/data \(sensor_msgs/msg/Imu\)"):
        read_imu(FORMATS / "adis_ros2", format_options={"topic": "/nope"})
    with pytest.raises(InputError, match="is std_msgs/msg/String, not sensor_msgs/msg/Imu"):
        read_imu(FORMATS / "adis_ros2", format_options={"topic": "/status"})


def test_ulog_frd_to_flu_and_float32(adis_ref: Any) -> None:
    """sensor_combined is FRD float32: y and z come back negated twice = as in the CSV."""
    log = read_imu(FORMATS / "adis_px4.ulg")
    assert log.frame == "FLU"
    assert any("FRD body axes converted to FLU" in w for w in log.warnings)
    for c in CHANNELS:
        ref = adis_ref.channels[c][:N_ADIS]
        np.testing.assert_array_equal(log.channels[c], ref.astype(np.float32).astype(np.float64))
    # The sign matters: the ADIS z axis reads about -1 g in the CSV, and so here.
    ref_z = float(np.median(adis_ref.channels["accel_z"][:N_ADIS]))
    assert ref_z < -9.5
    assert np.median(log.channels["accel_z"]) == pytest.approx(ref_z, rel=1e-6)
    assert log.t[0] == pytest.approx(5.0) and log.rate_hz == 100.0


def test_ulog_vehicle_imu_deltas(tmp_path: Path) -> None:
    """vehicle_imu: rates are delta_angle / delta_angle_dt (µs), FRD -> FLU."""
    mf = _make_formats_module()
    log_csv = read_imu(FORMATS / "adis_px4.ulg")
    path = tmp_path / "vehicle_imu.ulg"
    w = mf.ULogWriter(path, 0)
    w.format("vehicle_imu", [("uint64_t", "timestamp"), ("float[3]", "delta_angle"),
                             ("float[3]", "delta_velocity"), ("uint16_t", "delta_angle_dt"),
                             ("uint16_t", "delta_velocity_dt")])
    w.add_logged("vehicle_imu")
    frd = np.array([1.0, -1.0, -1.0])
    for i in range(200):
        g = np.array([log_csv.channels[f"gyro_{a}"][i] for a in "xyz"]) * frd
        a = np.array([log_csv.channels[f"accel_{a}"][i] for a in "xyz"]) * frd
        w.data("vehicle_imu", {"timestamp": 1_000_000 + 4000 * i,
                               "delta_angle": (g * 0.004).tolist(),
                               "delta_velocity": (a * 0.004).tolist(), "delta_angle_dt": 4000,
                               "delta_velocity_dt": 4000})
    w.close()
    log = read_imu(path)
    assert log.rate_hz == 250.0 and log.n_samples == 200
    for c in CHANNELS:
        np.testing.assert_allclose(log.channels[c], log_csv.channels[c][:200], rtol=2e-7,
                                   atol=1e-9)


def test_hdf5_dataset_option_compound_and_units() -> None:
    log = read_imu(FORMATS / "adis.h5", format_options={"dataset": "imu1"})
    assert log.n_samples == 200
    assert any("ns was assumed" in w for w in log.warnings)
    ref = read_imu(FORMATS / "adis.h5", format_options={"dataset": "/imu0"})
    for c in CHANNELS:
        np.testing.assert_array_equal(log.channels[c], ref.channels[c][:200])


def test_hdf5_unit_attribute(tmp_path: Path) -> None:
    import h5py

    p = tmp_path / "attr.h5"
    ref = read_imu(FORMATS / "adis.h5", format_options={"dataset": "/imu0"})
    with h5py.File(p, "w") as f:
        g = f.create_group("sensors/imu")
        g["t"] = ref.t
        g["t"].attrs["unit"] = "s"
        for c in CHANNELS:
            g[c] = ref.channels[c] / (DEG if c.startswith("gyro") else G0)
            g[c].attrs["unit"] = "deg/s" if c.startswith("gyro") else "g"
    log = read_imu(p)
    for c in CHANNELS:
        np.testing.assert_allclose(log.channels[c], ref.channels[c], rtol=1e-15, atol=1e-18)
    assert log.input_units["gyro_x"] == "deg/s" and log.input_units["accel_x"] == "g"


def test_nmea_vnymr_imu_frd_to_flu() -> None:
    """$VNYMR accel/gyro are FRD; the VN-100 at the start of the drive reads about +g up in FLU."""
    log = read_imu(FORMATS / "vn100.nmea")
    assert log.frame == "FLU"
    raw = (FORMATS / "vn100.nmea").read_text().splitlines()
    first = next(line for line in raw if "$VNYMR" in line)
    f = first.split("*")[0].split(",")
    # fields after the host stamp: $VNYMR, yaw, pitch, roll, mag xyz, accel xyz, gyro xyz
    assert log.channels["accel_x"][0] == float(f[8])
    assert log.channels["accel_z"][0] == -float(f[10])
    assert log.channels["gyro_y"][0] == -float(f[12])
    assert log.channels["gyro_z"][0] == -float(f[13])
    assert np.median(log.channels["accel_z"]) > 9.0


# ----------------------------------------------------------------------------- round trips
@pytest.mark.parametrize(("name", "extra"), [
    ("adis_ros2", ()), ("adis_ros1.bag", ()), ("adis.h5", ("--dataset", "/imu0")),
])
def test_round_trip_static_equals_csv(tmp_path: Path, adis_csv: Path, name: str,
                                      extra: tuple[str, ...]) -> None:
    ref = _static(adis_csv, tmp_path / "csv")
    got = _static(FORMATS / name, tmp_path / "fmt", *extra)
    _assert_same_noise(got, ref, 1e-9)
    assert got["input"]["frame"] in ("FLU", "unknown")


def test_round_trip_ulog_static_equals_csv_of_same_float32(tmp_path: Path, adis_ref: Any) -> None:
    """PX4 stores float32: the CSV of the same float32 values gives the same noise.json;
    against the original float64 CSV the terms agree to float32 precision."""
    csv = tmp_path / "f32.csv"
    cols = np.column_stack([adis_ref.t[:N_ADIS]] + [
        adis_ref.channels[c][:N_ADIS].astype(np.float32).astype(np.float64) for c in CHANNELS])
    head = "time_s,gyro_x_rads,gyro_y_rads,gyro_z_rads,accel_x_mps2,accel_y_mps2,accel_z_mps2"
    np.savetxt(csv, cols, delimiter=",", header=head, comments="", fmt="%.17g")
    ref32 = _static(csv, tmp_path / "csv32")
    got = _static(FORMATS / "adis_px4.ulg", tmp_path / "ulog")
    _assert_same_noise(got, ref32, 1e-9)
    orig = tmp_path / "orig.csv"
    np.savetxt(orig, np.column_stack([adis_ref.t[:N_ADIS]] + [
        adis_ref.channels[c][:N_ADIS] for c in CHANNELS]), delimiter=",", header=head,
        comments="", fmt="%.17g")
    _assert_same_noise(got, _static(orig, tmp_path / "csv64"), 1e-5)


# ----------------------------------------------------------------------------- bad files
def _cli_error(capsys: pytest.CaptureFixture[str], argv: list[str]) -> str:
    code = cli_main(argv)
    err = capsys.readouterr().err.strip()
    assert code == 2, err
    lines = err.splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("imubounds: error: ")
    assert "Traceback" not in err
    return lines[0]


def test_truncated_ros1_bag(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    src = (FORMATS / "adis_ros1.bag").read_bytes()
    bad = tmp_path / "truncated.bag"
    bad.write_bytes(src[: len(src) // 2])
    msg = _cli_error(capsys, ["static", str(bad), "-o", str(tmp_path / "o"), "-q"])
    assert "truncated.bag" in msg and "not a readable ROS bag" in msg


def test_truncated_ros2_bag(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    d = tmp_path / "bag2"
    shutil.copytree(FORMATS / "adis_ros2", d)
    db = d / "adis_ros2.db3"
    db.write_bytes(db.read_bytes()[:20000])
    msg = _cli_error(capsys, ["static", str(d), "-o", str(tmp_path / "o"), "-q"])
    assert "not a readable ROS bag" in msg


def test_truncated_mcap(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    src = (FORMATS / "vn100_drive_mcap" / "vn100_drive_mcap.mcap").read_bytes()
    bad = tmp_path / "cut.mcap"
    bad.write_bytes(src[: len(src) // 3])
    msg = _cli_error(capsys, ["static", str(bad), "-o", str(tmp_path / "o"), "-q"])
    assert "cut.mcap" in msg


def test_ulog_without_imu_topic(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    msg = _cli_error(capsys, ["static", str(FORMATS / "gps_only.ulg"), "-o", str(tmp_path), "-q"])
    assert "no IMU topic" in msg and "vehicle_gps_position" in msg


def test_truncated_ulog(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "cut.ulg"
    bad.write_bytes((FORMATS / "adis_px4.ulg").read_bytes()[:9])
    msg = _cli_error(capsys, ["static", str(bad), "-o", str(tmp_path / "o"), "-q"])
    assert "cut.ulg" in msg


def test_nmea_bad_checksum(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    msg = _cli_error(capsys, ["static", str(FORMATS / "bad_checksum.nmea"), "-o",
                              str(tmp_path), "-q"])
    assert "bad_checksum.nmea, line 2: NMEA checksum" in msg


def test_nmea_without_imu_sentences(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    p = tmp_path / "gps_only.nmea"
    p.write_text("".join(line + "\n" for line in (FORMATS / "vn100.nmea").read_text()
                         .splitlines() if "VNYMR" not in line))
    msg = _cli_error(capsys, ["static", str(p), "-o", str(tmp_path / "o"), "-q"])
    assert "no IMU sentences" in msg and "imubounds dynamic" in msg


def test_hdf5_without_the_dataset(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    msg = _cli_error(capsys, ["static", str(FORMATS / "adis.h5"), "--dataset", "/imu9", "-o",
                              str(tmp_path), "-q"])
    assert "no dataset or group '/imu9'" in msg and "/imu0" in msg
    msg = _cli_error(capsys, ["static", str(FORMATS / "no_imu_table.h5"), "-o",
                              str(tmp_path), "-q"])
    assert "no IMU table found" in msg
    msg = _cli_error(capsys, ["static", str(FORMATS / "adis.h5"), "-o", str(tmp_path), "-q"])
    assert "several tables (/imu0, /imu1)" in msg


def test_truncated_hdf5(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "cut.h5"
    bad.write_bytes((FORMATS / "adis.h5").read_bytes()[:3000])
    msg = _cli_error(capsys, ["static", str(bad), "-o", str(tmp_path / "o"), "-q"])
    assert "cut.h5" in msg


def test_topic_option_on_the_cli(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    msg = _cli_error(capsys, ["static", str(FORMATS / "adis_ros1.bag"), "--topic", "/gps", "-o",
                              str(tmp_path), "-q"])
    assert "no topic '/gps'" in msg and "/imu (sensor_msgs/msg/Imu)" in msg


def test_units_constants_used_by_the_samples() -> None:
    assert math.isclose(DEG, math.pi / 180.0)


def test_lone_mcap_file_equals_its_bag_directory() -> None:
    a = read_imu(FORMATS / "vn100_drive_mcap")
    b = read_imu(FORMATS / "vn100_drive_mcap" / "vn100_drive_mcap.mcap")
    assert a.n_samples == b.n_samples > 250
    for c in CHANNELS:
        np.testing.assert_array_equal(a.channels[c], b.channels[c])
