"""Bad drive inputs: a one-line error (exit 2) or a counted warning, never a traceback.

Table-driven: each case edits a clean synthetic drive (the layout of a car on a
50 m circle at 10 m/s for 60 s: IMU 100 Hz, GNSS 1 Hz with speed and course,
compass, wheel speed), runs ``imubounds convert``, and checks the exit code
and the message. Plus property-based fuzzing of the drive CSV and NMEA readers.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from imubounds.cli import main
from imubounds.errors import ImuboundsError, InputError
from imubounds.io import read_drive

LAT0, LON0 = 37.4, -122.1  # a drive near Palo Alto (|lon| > 90: swapped coordinates show)
R_M, V_MPS = 50.0, 10.0


def make_drive(d: Path, lat0: float = LAT0, lon0: float = LON0) -> Path:
    """A consistent drive layout: counter-clockwise circle, FLU IMU, compass clockwise."""
    d.mkdir(parents=True, exist_ok=True)
    w = V_MPS / R_M
    t = np.arange(0.0, 60.0, 0.01)
    rng = np.random.default_rng(0)
    imu = pd.DataFrame({
        "time_s": t,
        "gyro_x_rads": 1e-3 * rng.standard_normal(t.size),
        "gyro_y_rads": 1e-3 * rng.standard_normal(t.size),
        "gyro_z_rads": w + 1e-3 * rng.standard_normal(t.size),
        "accel_x_mps2": 0.02 * rng.standard_normal(t.size),
        "accel_y_mps2": V_MPS * w + 0.02 * rng.standard_normal(t.size),
        "accel_z_mps2": 9.81 + 0.02 * rng.standard_normal(t.size),
    })
    imu.to_csv(d / "imu.csv", index=False)
    tg = np.arange(0.0, 60.0, 1.0)
    psi = w * tg  # model heading (CCW from east); start heading east
    east = R_M * np.sin(psi)
    north = R_M * (1 - np.cos(psi))
    lat = lat0 + np.degrees(north / 6_371_000.0)
    lon = lon0 + np.degrees(east / (6_371_000.0 * math.cos(math.radians(lat0))))
    course = np.mod(90.0 - np.degrees(psi), 360.0)
    pd.DataFrame({
        "time_s": tg, "lat_deg": lat, "lon_deg": lon, "alt_m": 10.0, "hdop": 0.9, "fix": 1,
        "speed_mps": V_MPS, "course_deg": course,
    }).to_csv(d / "gnss.csv", index=False)
    th = np.arange(0.0, 60.0, 0.1)
    pd.DataFrame({"time_s": th, "heading_deg": np.mod(90.0 - np.degrees(w * th), 360.0)}).to_csv(
        d / "heading.csv", index=False)
    pd.DataFrame({"time_s": th, "u_mps": V_MPS, "kind": "wheel"}).to_csv(
        d / "velocity.csv", index=False)
    return d


def _edit(name: str, fn: Callable[[pd.DataFrame], pd.DataFrame | None]) -> Callable[[Path], None]:
    def apply(d: Path) -> None:
        df = pd.read_csv(d / name)
        out = fn(df)
        (out if out is not None else df).to_csv(d / name, index=False)

    return apply


def _set(name: str, col: str, rows: slice | list[int], value: object) -> Callable[[Path], None]:
    def fn(df: pd.DataFrame) -> None:
        df[col] = df[col].astype(object)
        df.loc[df.index[rows], col] = value

    return _edit(name, fn)


def _text(path: str, text: str) -> Callable[[Path], None]:
    def apply(d: Path) -> None:
        (d / path).write_text(text)

    return apply


def _remove(name: str) -> Callable[[Path], None]:
    def apply(d: Path) -> None:
        (d / name).unlink()

    return apply


def _swap(df: pd.DataFrame) -> pd.DataFrame:
    return df.rename(columns={"lat_deg": "lon_deg", "lon_deg": "lat_deg"})


def _rename(name: str, cols: dict[str, str], scale: float = 1.0) -> Callable[[Path], None]:
    def fn(df: pd.DataFrame) -> pd.DataFrame:
        for c in cols:
            df[c] = df[c] * scale
        return df.rename(columns=cols)

    return _edit(name, fn)


def _shift_gnss(df: pd.DataFrame) -> None:
    df["time_s"] = df["time_s"] + 1000.0


def _e7(df: pd.DataFrame) -> None:
    df["lat_deg"] = (df["lat_deg"] * 1e7).round().astype(np.int64)
    df["lon_deg"] = (df["lon_deg"] * 1e7).round().astype(np.int64)


def _radians(df: pd.DataFrame) -> None:
    df["lat_deg"] = np.radians(df["lat_deg"])
    df["lon_deg"] = np.radians(df["lon_deg"])


def _course_radians(df: pd.DataFrame) -> None:
    df["course_deg"] = np.radians(df["course_deg"])


def _frd_gyro(df: pd.DataFrame) -> None:
    df["gyro_z_rads"] = -df["gyro_z_rads"]
    df["gyro_y_rads"] = -df["gyro_y_rads"]


def _fix_rows(df: pd.DataFrame) -> None:
    df.loc[df.index[[3, 4, 9]], "fix"] = 0


def _hdops(df: pd.DataFrame) -> None:
    df["hdop"] = df["hdop"].astype(float)
    df.loc[df.index[[1, 2, 3]], "hdop"] = [0.0, np.nan, -1.0]


def _speed_spikes(df: pd.DataFrame) -> None:
    df.loc[df.index[[5, 6]], "speed_mps"] = 250.0


def _unsorted(df: pd.DataFrame) -> None:
    df.loc[[10, 11], "time_s"] = df.loc[[11, 10], "time_s"].to_numpy()


# (id, edit of the clean drive, extra convert args, exit code, message (regex))
CASES: list[tuple[str, Callable[[Path], None] | None, list[str], int, str]] = [
    ("clean", None, [], 0, r"-> "),
    ("text-in-a-cell", _set("imu.csv", "gyro_x_rads", [4], "abc"), [], 2,
     r"imu.csv: column gyro_x_rads, data row 5: 'abc' is not a number"),
    ("header-only-compass", _text("heading.csv", "time_s,heading_deg\n"), [], 2,
     r"heading.csv: no data rows \(only a header\)"),
    ("all-nan-latitudes", _set("gnss.csv", "lat_deg", slice(None), np.nan), [], 2,
     r"gnss.csv: lat_deg/lon_deg have no finite value in 60 row\(s\): no usable GPS fix"),
    ("inf-gyro", _set("imu.csv", "gyro_z_rads", [250], "inf"), [], 2,
     r"imu.csv: gyro_z \(body axes\) is inf at data row 251 \(t=2.500 s\)"),
    ("nan-heading", _set("heading.csv", "heading_deg", [7, 8], np.nan), [], 0,
     r"warning: .*heading.csv: 2 row\(s\) with NaN heading_deg skipped"),
    ("lat-e7-integers", _edit("gnss.csv", _e7), [], 2, r"degrees x 1e7.*divide lat/lon by 1e7"),
    ("lat-lon-swapped-range", _edit("gnss.csv", _swap), [], 2,
     r"lat_deg is -122.* while every lon_deg is within \+-90: latitude and longitude are swapped"),
    ("lat-lon-radians", _edit("gnss.csv", _radians), [], 2,
     r"the fixes move \d+x slower than the measured speed: lat/lon are in radians"),
    ("course-radians", _edit("gnss.csv", _course_radians), [], 2,
     r"course_deg stays within 0..6.3 .* the course is in radians"),
    ("heading-radians", _edit("heading.csv", lambda df: df.assign(
        heading_deg=np.radians(df["heading_deg"]))), [], 2,
     r"heading.csv: heading_deg stays within \+-6.3 .* the heading is in radians"),
    ("attitude-pitch-beyond-90",
     _text("attitude.csv", "time_s,roll_deg,pitch_deg\n0,1,2\n1,1,95\n"), [], 2,
     r"attitude.csv: pitch 95 deg at data row 2 \(t=1.000 s\) is beyond \+-90 deg"),
    ("fix-no-rows", _edit("gnss.csv", _fix_rows), [], 0,
     r"warning: .*gnss.csv: 3 of 60 row\(s\) without a fix \(fix = 0\) skipped"),
    ("hdop-0-nan-minus1", _edit("gnss.csv", _hdops), [], 0,
     r"warning: .*gnss.csv: 3 fix\(es\) with HDOP <= 0 or missing \(first 0 at data row 2"),
    ("speeds-beyond-max", _edit("gnss.csv", _speed_spikes), [], 0,
     r"2 GNSS speed\(s\) negative or beyond the vehicle's maximum 70 m/s \(first 250 m/s"),
    ("speeds-beyond-max-speed-option", None, ["--max-speed", "9"], 2,
     r"velocity.csv: u_mps has no usable value in 600 row\(s\) \(600 beyond the maximum "
     r"speed 9 m/s\)"),
    ("no-overlap", _edit("gnss.csv", _shift_gnss), [], 2,
     r"gnss.csv: the gnss stream \(1000.000..1059.000 s\) does not overlap the IMU "
     r"\(0.000..59.990 s\)"),
    ("gyro-dps-named-rads", _edit("imu.csv", lambda df: df.assign(
        **{f"gyro_{a}_rads": np.degrees(df[f"gyro_{a}_rads"]) for a in "xyz"})), [], 2,
     r"gyro_z turns 57x faster than the heading .* are in deg/s; name them gyro_\*_dps"),
    ("gyro-rads-named-dps", _rename("imu.csv", {f"gyro_{a}_rads": f"gyro_{a}_dps" for a in "xyz"}),
     [], 2, r"gyro_z turns 57x slower than the heading .* are in rad/s"),
    ("accel-g-named-mps2", _edit("imu.csv", lambda df: df.assign(
        **{f"accel_{a}_mps2": df[f"accel_{a}_mps2"] / 9.81 for a in "xyz"})), [], 2,
     r"median \|acceleration\| is 1.0\d .* the columns are in g"),
    ("gyro-upside-down", _edit("imu.csv", _frd_gyro), [], 2,
     r"gyro_z turns against the heading .* fix the mount with imu_axes"),
    ("imu-unsorted", _edit("imu.csv", _unsorted), [], 2,
     r"imu time_s is not strictly increasing at row 12 \(t=0.110000 then 0.100000 s\)"),
    ("no-imu", _remove("imu.csv"), [], 2,
     r"not a known drive-log directory.*found gnss.csv, velocity.csv, heading.csv but no imu"),
    ("no-aiding", lambda d: [_remove(n)(d) for n in ("gnss.csv", "heading.csv", "velocity.csv")],
     [], 2, r"no aiding sensor: give gnss.csv \(time_s, lat_deg, lon_deg\), velocity.csv"),
    ("imu-without-columns", _text("imu.csv", "time_s,temp_c\n0,20\n1,21\n"), [], 2,
     r"imu.csv: no IMU columns; expected gyro_\{x,y,z\}_<unit>"),
    ("unknown-yaml-key", _text("drive.yaml", "gnss:\n  cep: 3\n"), [], 2,
     r"drive.yaml: unknown key gnss.cep; known in gnss: cep_m"),
    ("yaml-negative-bound", _text("drive.yaml", "velocity:\n  bound_mps: -1\n"), [], 2,
     r"velocity.bound_mps must be a finite number >= 0, got -1"),
    ("yaml-missing-noise-json", _text("drive.yaml", "imu:\n  noise_json: nope.json\n"), [], 2,
     r"imu.noise_json: no such file: .*nope.json"),
    ("unknown-unit", _rename("imu.csv", {"gyro_x_rads": "gyro_x_furlong"}), [], 2,
     r"column gyro_x_furlong: unknown unit 'furlong'"),
]


@pytest.fixture(scope="module")
def clean(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return make_drive(tmp_path_factory.mktemp("clean") / "drive")


@pytest.mark.parametrize("case", CASES, ids=[c[0] for c in CASES])
def test_bad_drive_input(
    case: tuple[str, Callable[[Path], None] | None, list[str], int, str],
    clean: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str],
) -> None:
    import shutil

    name, edit, extra, code, message = case
    d = tmp_path / "in"
    shutil.copytree(clean, d)
    if edit is not None:
        edit(d)
    out = tmp_path / "out"
    got = main(["convert", str(d), "-o", str(out), *extra])
    captured = capsys.readouterr()
    err = captured.err
    assert got == code, err
    assert len([x for x in err.splitlines() if x.startswith("imubounds: error")]) == (code != 0)
    import re

    # the summary ("-> OUT") is on stdout, warnings and errors on stderr
    assert re.search(message, captured.out + err), err
    if code:
        assert not out.exists()  # nothing half written


def _fifo(path: Path) -> Path:
    if not hasattr(os, "mkfifo"):
        pytest.skip("no named pipes on this platform")
    os.mkfifo(path)
    return path


def test_pipes_are_refused_before_reading(
    clean: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A named pipe as the input, as a table of the layout, or as --compass-cal never blocks."""
    import shutil

    pipe = _fifo(tmp_path / "log.csv")
    assert main(["convert", str(pipe), "-o", str(tmp_path / "o")]) == 2
    assert "log.csv is a named pipe" in capsys.readouterr().err
    d = tmp_path / "d"
    shutil.copytree(clean, d)
    (d / "heading.csv").unlink()
    _fifo(d / "heading.csv")
    assert main(["convert", str(d), "-o", str(tmp_path / "o")]) == 2
    assert "heading.csv is a named pipe" in capsys.readouterr().err
    from imubounds.dynamic.sensors._compass import read_calibration

    cal = _fifo(tmp_path / "cal.csv")
    with pytest.raises(InputError, match="cal.csv is a named pipe"):
        read_calibration(str(cal))
    with pytest.raises(InputError, match="settings.yaml is a named pipe"):
        read_drive(clean, settings=_fifo(tmp_path / "settings.yaml"))


def test_compass_cal_pipe_in_the_dynamic_command(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    sim = tmp_path / "sim"
    assert main(["simulate", "-o", str(sim), "--duration", "100", "--distance", "1000", "-q"]) == 0
    cal = _fifo(tmp_path / "cal.csv")
    assert main(["dynamic", str(sim), "--compass-cal", str(cal), "-o", str(tmp_path / "o"),
                 "-q", "--no-plot", "--no-report"]) == 2
    assert "cal.csv is a named pipe" in capsys.readouterr().err


def test_header_only_and_short_compass_calibration_files(tmp_path: Path) -> None:
    from imubounds.dynamic.sensors._compass import read_calibration

    p = tmp_path / "c.csv"
    p.write_text("measured_deg,reference_deg\n")
    with pytest.raises(InputError, match="0 complete .* at least 3 are needed"):
        read_calibration(str(p))
    p.write_text("")
    with pytest.raises(InputError, match="the compass calibration file is empty"):
        read_calibration(str(p))
    p.write_text("measured_deg,reference_deg\n1,2\nx,3\n")
    with pytest.raises(InputError, match="column measured_deg, data row 2: 'x' is not a number"):
        read_calibration(str(p))


def test_warnings_are_counted(clean: Path, tmp_path: Path) -> None:
    import shutil

    d = tmp_path / "d"
    shutil.copytree(clean, d)
    _edit("gnss.csv", _fix_rows)(d)
    _edit("gnss.csv", _hdops)(d)
    drive = read_drive(d)
    assert drive.counts == {"gnss_no_fix": 3, "gnss_hdop_invalid": 2}  # row 3 has no fix
    assert drive.gnss is not None and drive.gnss.hdop is not None
    assert np.isnan(drive.gnss.hdop[[1, 2]]).all()  # neutralised, the default applies


# ----------------------------------------------------------------------------- fuzzing

CELLS = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.text(alphabet="0123456789.-+eEnaNif ,;\"x", max_size=8),
    st.integers(-(10**12), 10**12).map(str),
    st.just(""),
)


@settings(max_examples=40, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(table=st.sampled_from(["imu.csv", "gnss.csv", "heading.csv", "velocity.csv"]),
       row=st.integers(0, 30), col=st.integers(0, 7), cell=CELLS)
def test_fuzz_drive_tables(table: str, row: int, col: int, cell: str,
                           clean: Path, tmp_path_factory: pytest.TempPathFactory) -> None:
    """A random cell anywhere in a drive table: a Drive or an ImuboundsError, nothing else."""
    import shutil

    d = tmp_path_factory.mktemp("fz") / "d"
    shutil.copytree(clean, d)
    lines = (d / table).read_text().splitlines()
    cells = lines[1 + row].split(",")
    cells[col % len(cells)] = cell
    lines[1 + row] = ",".join(cells)
    (d / table).write_text("\n".join(lines) + "\n")
    try:
        read_drive(d)
    except ImuboundsError as err:
        assert "\n" not in str(err)


@settings(max_examples=40, deadline=None)
@given(lines=st.lists(st.sampled_from([
    "1.0,$GPGGA,220932.00,4220.23175,N,07105.38033,W,2,11,0.96,9.1,M,-33.2,M,,0000",
    "1.5,$GPVTG,260.2,T,,M,6.349,N,11.758,K,D",
    "2.0,$GPRMC,220933.00,A,4220.23145,N,07105.38267,W,6.4,242.5,191125,,,D",
    "2.1,$HEHDT,123.4,T",
    "2.2,$HCHDG,100.0,,,5.0,W",
    "2.3,$VNYMR,+066.172,+003.948,+002.132,+00.2653,-00.0791,+00.3577,+00.558,+00.250,"
    "-10.355,+00.037773,+00.029186,-00.272747",
    "garbage line", "", "3.0,$GPGGA,,,,,,0,,,,,,,,", "3.1,$GPVTG,,,,,,,,,N",
    "x,$GPGGA,1,2,3", "4.0,$HCHDG,abc,,,,",
]), max_size=12))
def test_fuzz_nmea_drive_reader(lines: list[str], tmp_path_factory: pytest.TempPathFactory) -> None:
    """Any mix of valid, empty and broken sentences: a Drive or an ImuboundsError."""
    p = tmp_path_factory.mktemp("nm") / "c.nmea"
    p.write_text("\n".join(lines) + "\n")
    try:
        read_drive(p)
    except ImuboundsError as err:
        assert "\n" not in str(err)


def test_gnss_jumps_allow_for_the_fixes_own_errors(tmp_path: Path) -> None:
    """A noisy 1 Hz GNSS at 12 m/s (CEP 3 m) gives no jump warning; a 60 m outlier does
    (twice: the jump there and the one back)."""
    from imubounds.dynamic.scenario import make_trip
    from imubounds.io.drive.layout import write_layout

    sim = make_trip("gnss-pos", seed=3, duration_s=120.0, distance_m=1300.0)
    write_layout(sim.drive, tmp_path / "clean")
    clean = read_drive(tmp_path / "clean")
    assert "gnss_position_jumps" not in clean.counts, clean.warnings
    gnss = pd.read_csv(tmp_path / "clean" / "gnss.csv")
    gnss.loc[60, "lat_deg"] += 60.0 / 111_000.0  # 60 m north
    gnss.to_csv(tmp_path / "clean" / "gnss.csv", index=False)
    bad = read_drive(tmp_path / "clean")
    assert bad.counts.get("gnss_position_jumps") == 2, bad.warnings
