"""Reading real ADIS16405 data in every supported layout, the registry and options."""

from __future__ import annotations

import gzip
from pathlib import Path

import numpy as np
import pytest

from imubounds.errors import InputError, UnitsError
from imubounds.io import (
    ReadOptions,
    bundled_static_log,
    find_reader,
    read_imu,
    read_imu_segments,
    register_reader,
    registered_readers,
    unregister_reader,
)
from imubounds.io.log import IMU_CHANNELS, ImuLog
from imubounds.units import DEG, G0

DATA = Path(__file__).parent / "data"
START_ROW = 100_000  # the samples start at this row of the real log (make_samples.py)


@pytest.fixture(scope="module")
def reference() -> dict[str, np.ndarray]:
    """The original text of the sample rows, parsed independently, in SI."""
    lines = (DATA / "adis_plain_ns.csv").read_text().splitlines()[1:]
    vals = np.array([[float(x) for x in line.split(",")] for line in lines])
    out = {"t": vals[:, 0] * 1e-9}
    for k, c in enumerate(IMU_CHANNELS):
        out[c] = vals[:, k + 1] * (DEG if c.startswith("gyro") else G0)
    return out


def _check(log: ImuLog, ref: dict[str, np.ndarray], rtol: float = 0.0) -> None:
    n = min(log.n_samples, ref["t"].size)
    assert log.channel_names() == list(IMU_CHANNELS)
    assert log.rate_hz == pytest.approx(100.0, rel=1e-9)
    for c in IMU_CHANNELS:
        np.testing.assert_allclose(log.channels[c][:n], ref[c][:n], rtol=rtol, atol=0)
        assert log.channels[c].dtype == np.float64


def test_plain_ns(reference: dict[str, np.ndarray]) -> None:
    log = read_imu(DATA / "adis_plain_ns.csv")
    _check(log, reference)
    np.testing.assert_allclose(log.t, reference["t"], rtol=0, atol=1e-12)
    assert log.t[0] == 1000.0
    assert log.input_units == {**dict.fromkeys(IMU_CHANNELS[:3], "deg/s"),
                               **dict.fromkeys(IMU_CHANNELS[3:], "g")}
    assert log.warnings == []


def test_euroc(reference: dict[str, np.ndarray]) -> None:
    log = read_imu(DATA / "adis_euroc.csv")
    assert log.n_samples == 1000
    _check(log, reference, rtol=1e-15)
    assert log.input_units["gyro_x"] == "rad/s" and log.input_units["accel_x"] == "m/s^2"
    assert log.warnings == []
    # absolute ns stamps: steps stay exact to float64 resolution of ~1.4e9 s
    assert log.t[0] == pytest.approx(1_403_636_579.758555392, abs=1e-6)
    np.testing.assert_allclose(np.diff(log.t), 0.01, atol=1e-6)


def test_kalibr(reference: dict[str, np.ndarray]) -> None:
    log = read_imu(DATA / "adis_kalibr.csv.gz")
    assert log.n_samples == 2000
    _check(log, reference, rtol=1e-15)
    assert log.t[0] == pytest.approx(1000.0)
    assert not any("assumed" in w for w in log.warnings)
    assert any("Kalibr" in w and "ns" in w for w in log.warnings)


def test_parquet(reference: dict[str, np.ndarray]) -> None:
    log = read_imu(DATA / "adis.parquet")
    assert log.n_samples == 2000
    _check(log, reference)
    assert log.t[0] == 1000.0


def test_whitespace_txt_with_comments(reference: dict[str, np.ndarray]) -> None:
    log = read_imu(DATA / "adis_spaces.txt")
    assert log.n_samples == 500
    _check(log, reference)
    assert log.t[1] == pytest.approx(1000.01)


def test_tsv_semicolon_and_comments_inside(tmp_path: Path,
                                           reference: dict[str, np.ndarray]) -> None:
    lines = (DATA / "adis_plain_ns.csv").read_text().splitlines()
    tsv = tmp_path / "log.tsv"
    tsv.write_text("\n".join(line.replace(",", "\t") for line in lines[:200]) + "\n")
    _check(read_imu(tsv), reference)
    semi = tmp_path / "log.txt"
    body = [line.replace(",", ";") for line in lines[:200]]
    body.insert(50, "# operator touched the table here")
    body.insert(80, "")
    semi.write_text("\n".join(body) + "\n")
    log = read_imu(semi)
    assert log.n_samples == 199
    _check(log, reference)


def test_quoted_multiline_field(tmp_path: Path) -> None:
    text = 't,gyro_x,acc_x,raw\n0.0,0.1,9.8,"$VNYMR,1,2\n"\n0.025,0.2,9.7,"$VNYMR,3\n"\n'
    p = tmp_path / "vn.csv"
    p.write_text(text)
    log = read_imu(p)
    np.testing.assert_array_equal(log.channels["gyro_x"], [0.1, 0.2])
    np.testing.assert_array_equal(log.channels["accel_x"], [9.8, 9.7])
    assert log.rate_hz == pytest.approx(40.0)


def test_real_dynamic_vn100(shared_data: Path) -> None:
    """A real jittery 40 Hz log with text columns and quoted multi-line cells."""
    log = read_imu(shared_data / "dynamic/vn100_bu353_circle/circle_data_0_imu.csv")
    assert log.channel_names() == list(IMU_CHANNELS)
    assert log.rate_hz == pytest.approx(40.0, rel=0.05)
    assert np.median(log.channels["accel_z"]) == pytest.approx(-9.8, abs=0.5)
    assert any("assumed rad/s" in w for w in log.warnings)


def test_full_real_log(adis_log_path: Path) -> None:
    log = read_imu(adis_log_path)
    assert log.n_samples == 1_000_000
    assert log.rate_hz == 100.0
    assert log.duration_s == pytest.approx(10_000.0)
    assert log.t[0] == 0.0 and log.t[-1] == pytest.approx(9999.99)
    assert log.input_units["gyro_z"] == "deg/s" and log.input_units["accel_z"] == "g"
    # first row of the file: 0.00,-0.05,-0.3,0.7,-0.00666,0,-1.01565
    assert log.channels["gyro_x"][0] == -0.05 * DEG
    assert log.channels["gyro_z"][0] == 0.7 * DEG
    assert log.channels["accel_z"][0] == -1.01565 * G0
    # last row: 9999.99,0.35,-0.2,-0.45,-0.00666,-0.00333,-1.01898
    assert log.channels["accel_y"][-1] == -0.00333 * G0
    assert np.mean(log.channels["accel_z"]) == pytest.approx(-G0, rel=0.05)
    assert log.warnings == []  # the real log passes every plausibility check


def test_bundled_extract() -> None:
    p = bundled_static_log()
    assert p.is_file() and p.name == "adis16405_imu1_extract.csv.gz"
    assert p.stat().st_size < 2_500_000
    assert (p.parent / "LICENSE_CC-BY-NC-SA-4.0.txt").is_file()
    assert "CC BY-NC-SA 4.0" in (p.parent / "README.md").read_text()
    with gzip.open(p, "rt") as f:
        head = [f.readline() for _ in range(3)]
    assert head[0] == "time_s,gyro_x_dps,gyro_y_dps,gyro_z_dps,accel_x_g,accel_y_g,accel_z_g\n"
    assert head[1] == "0.00,-0.05,-0.3,0.7,-0.00666,0,-1.01565\n"
    log = read_imu(p)
    assert log.n_samples == 270_000 and log.duration_s == pytest.approx(2700.0)


def test_bundled_extract_matches_real_log(adis_log_path: Path) -> None:
    with gzip.open(adis_log_path, "rb") as f:
        original = b"".join(f.readline() for _ in range(270_001))
    assert gzip.decompress(bundled_static_log().read_bytes()) == original


def test_units_override_and_assumed(tmp_path: Path) -> None:
    p = tmp_path / "log.csv"
    p.write_text("t,gyro_x,gyro_y,accel_x,accel_y,accel_z\n0,1,2,0,0,1\n0.01,1,2,0,0,1\n")
    log = read_imu(p)
    assert log.channels["gyro_x"][0] == 1.0
    assert any("assumed rad/s" in w for w in log.warnings)
    assert any("look like g (use --accel-unit g)" in w for w in log.warnings)
    log = read_imu(p, gyro_unit="deg/s", accel_unit="g")
    assert log.channels["gyro_y"][0] == pytest.approx(2 * DEG)
    assert log.channels["accel_z"][0] == G0
    assert log.input_units["gyro_x"] == "deg/s" and log.input_units["accel_z"] == "g"
    assert not any("assumed" in w for w in log.warnings)
    log = read_imu(p, gyro_unit="°/s", accel_unit="mg")
    assert log.channels["accel_z"][0] == pytest.approx(1e-3 * G0)


def test_override_conflicting_suffix_warns(tmp_path: Path) -> None:
    p = tmp_path / "log.csv"
    p.write_text("t,gyro_x_dps\n0,1\n0.01,1\n")
    log = read_imu(p, gyro_unit="rad/s")
    assert log.channels["gyro_x"][0] == 1.0
    assert any("says deg/s" in w for w in log.warnings)


@pytest.mark.parametrize(
    ("name", "values", "expected_dt"),
    [
        ("time_ns", ["0", "5000000", "10000000"], 0.005),
        ("timestamp_us", ["100", "5100", "10100"], 0.005),
        ("t_ms", ["0", "5", "10"], 0.005),
        ("#timestamp [ns]", ["0", "5000000", "10000000"], 0.005),
        ("time [s]", ["0", "0.005", "0.010"], 0.005),
        ("stamp", ["0", "0.005", "0.010"], 0.005),
        ("%time", ["1700000000000000000", "1700000000005000000", "1700000000010000000"],
         0.005),
    ],
)
def test_time_units(tmp_path: Path, name: str, values: list[str], expected_dt: float) -> None:
    p = tmp_path / "log.csv"
    p.write_text(f"{name},gyro_x\n" + "".join(f"{v},0.5\n" for v in values))
    log = read_imu(p)
    assert log.rate_hz == pytest.approx(1.0 / expected_dt)
    # epoch stamps (1.7e9 s) have float64 resolution 2.4e-7 s
    np.testing.assert_allclose(np.diff(log.t), expected_dt, rtol=0, atol=3e-7)


def test_time_unit_inferred_and_override(tmp_path: Path) -> None:
    p = tmp_path / "log.csv"
    p.write_text("timestamp,gyro_x\n" + "".join(f"{k * 5_000_000},0.5\n" for k in range(10)))
    log = read_imu(p)
    assert log.rate_hz == pytest.approx(200.0)
    assert any("ns was assumed" in w for w in log.warnings)
    with pytest.raises(UnitsError, match="0.2 Hz, a rate no IMU log has.*--allow-unusual-rate"):
        read_imu(p, time_unit="us")  # a rate no IMU log has: confirmed explicitly only
    log = read_imu(p, time_unit="us", unusual_rate=True)
    assert log.rate_hz == pytest.approx(0.2)


def test_rate_without_time(tmp_path: Path) -> None:
    p = tmp_path / "log.csv"
    p.write_text("gyro_x_dps,accel_z_g\n" + "1,1\n" * 10)
    log = read_imu(p, rate_hz=250.0)
    assert log.rate_hz == 250.0 and log.n_samples == 10
    np.testing.assert_allclose(log.t, np.arange(10) / 250.0)


def test_channels_subset_and_columns(tmp_path: Path) -> None:
    p = tmp_path / "log.csv"
    p.write_text("stamp_ns,wx,wy,wz,acc_x_mps2\n0,1,2,3,4\n10000000,1,2,3,4\n")
    log = read_imu(p, columns={"gyro_z": "wz", "gyro_x": "wx"}, gyro_unit="dps")
    assert log.channel_names() == ["gyro_x", "gyro_z", "accel_x"]
    assert log.channels["gyro_z"][0] == pytest.approx(3 * DEG)
    assert log.rate_hz == pytest.approx(100.0)
    log = read_imu(p, channels=["accel_x"])
    assert log.channel_names() == ["accel_x"]
    log = read_imu(p, columns={"time": "stamp_ns", "gyro_y": "wy"})
    assert log.t[1] == pytest.approx(0.01)


def test_mapped_source_with_bracket_unit(tmp_path: Path) -> None:
    p = tmp_path / "log.csv"
    p.write_text("t,Wx (deg/s)\n0,1\n0.01,1\n")
    log = read_imu(p, columns={"gyro_x": "Wx (deg/s)"})
    assert log.input_units["gyro_x"] == "deg/s"


def test_parquet_timestamp_column(tmp_path: Path) -> None:
    import pyarrow as pa
    import pyarrow.parquet as pq

    ts = pa.array(np.arange(5, dtype=np.int64) * 2_000_000, type=pa.timestamp("ns"))
    pq.write_table(pa.table({"time": ts, "gyro_x_dps": np.ones(5)}), tmp_path / "t.parquet")
    log = read_imu(tmp_path / "t.parquet")
    assert log.rate_hz == pytest.approx(500.0)


def test_registry_dispatch(tmp_path: Path) -> None:
    names = [e.name for e in registered_readers()]
    assert {"table", "parquet"} <= set(names)
    assert find_reader(DATA / "adis_kalibr.csv.gz").name == "table"
    assert find_reader(DATA / "adis.parquet").name == "parquet"

    calls: list[ReadOptions] = []

    def fake(path: Path, opts: ReadOptions) -> list[ImuLog]:
        calls.append(opts)
        t = np.arange(3) / 10.0
        return [ImuLog({"gyro_x": np.zeros(3)}, 10.0, t, str(path))]

    register_reader("fake-test", fake, suffixes=(".fake",), replace=True)
    try:
        p = tmp_path / "x.FAKE"
        p.write_bytes(b"\x00binary")
        log = read_imu(p, rate_hz=10.0, gyro_unit="dps")
        assert log.rate_hz == 10.0
        assert calls[-1].rate_hz == 10.0 and calls[-1].gyro_unit == "deg/s"
        with pytest.raises(ValueError, match="already registered"):
            register_reader("fake-test", fake)
    finally:
        unregister_reader("fake-test")
    with pytest.raises(InputError, match="unknown file type"):
        read_imu(p)


def test_registry_lazy_string(tmp_path: Path) -> None:
    register_reader("lazy-test", "imubounds.io.table:read_text_table",
                    suffixes=(".lazycsv",), replace=True)
    try:
        p = tmp_path / "x.lazycsv"
        p.write_text("t,gyro_x\n0,1\n0.5,1\n")
        assert find_reader(p).name == "lazy-test"
        assert read_imu(p).rate_hz == 2.0
    finally:
        unregister_reader("lazy-test")


def test_segments_without_gaps_is_one() -> None:
    segs = read_imu_segments(DATA / "adis_plain_ns.csv")
    assert len(segs) == 1 and segs[0].n_samples == 1500


def test_real_log_gap_split(tmp_path: Path) -> None:
    """Real sample rows with a block removed: split gives the two real pieces."""
    lines = (DATA / "adis_plain_ns.csv").read_text().splitlines(keepends=True)
    p = tmp_path / "cut.csv"
    p.write_text("".join(lines[:701] + lines[801:]))
    with pytest.raises(InputError, match="1 gap"):
        read_imu(p)
    a, b = read_imu_segments(p)
    assert (a.n_samples, b.n_samples) == (700, 700)
    assert b.t[0] - a.t[-1] == pytest.approx(1.01)


@pytest.mark.parametrize("comment_inside", [False, True])  # fast path / line-by-line path
def test_iso_datetime_time_column(tmp_path: Path, comment_inside: bool) -> None:
    rows = [f"2024-05-01T12:00:{k * 0.01:05.2f},{k}\n" for k in range(50)]
    if comment_inside:
        rows.insert(10, "# paused logging display\n")
    p = tmp_path / "iso.csv"
    p.write_text("time,gyro_x_dps\n" + "".join(rows))
    log = read_imu(p)
    assert log.n_samples == 50 and log.rate_hz == pytest.approx(100.0)
    epoch = (np.datetime64("2024-05-01T12:00:00", "s") - np.datetime64(0, "s")).astype(int)
    assert log.t[0] == float(epoch)
    np.testing.assert_allclose(np.diff(log.t), 0.01, atol=3e-7)


def test_single_column_with_rate(tmp_path: Path) -> None:
    p = tmp_path / "z.txt"
    p.write_text("gyro_z_dps\n" + "0.05\n" * 20 + "-0.05\n")
    log = read_imu(p, rate_hz=100.0)
    assert log.channel_names() == ["gyro_z"] and log.n_samples == 21
    assert log.channels["gyro_z"][-1] == pytest.approx(-0.05 * DEG)
