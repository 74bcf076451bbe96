"""Bad input, third round (issue 25): drive layouts, the API and numbers at the edges.

One row per case of the issue (its number leads the row's name). Each row copies a
small simulated drive layout (``imubounds simulate``, 150 s, made once per module),
spoils it as a new user would, runs a command in-process and checks: the exit code;
an error is exactly one line naming the file, key or channel; a suspicious input is a
counted warning; no traceback; no file that existed before was changed or removed; a
refused command wrote no output. A hypothesis property test spoils drive.yaml and the
tables at random with the same guarantees.
"""

from __future__ import annotations

import gzip
import json
import re
import shutil
import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import imubounds as ib
from imubounds.cli import main
from imubounds.io import read_drive
from imubounds.io.table import read_frame

FAST_STATIC = ["-q", "--models", "none", "--no-plot", "--no-report"]


#: every case fails (instead of hanging the run) if it blocks for 60 s (conftest.no_hang)
pytestmark = pytest.mark.usefixtures("no_hang")


@pytest.fixture(scope="module")
def sim(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A simulated 150 s drive layout (IMU 50 Hz, GNSS 1 Hz, compass, truth)."""
    d = tmp_path_factory.mktemp("sim") / "drive"
    code = main(["simulate", "--duration", "150", "--distance", "1500", "--rate", "50",
                 "-o", str(d), "-q"])
    assert code == 0
    return d


def _copy(sim: Path, dest: Path) -> Path:
    shutil.copytree(sim, dest, ignore=shutil.ignore_patterns("run.json", "scenario.json"))
    return dest


def _snapshot(d: Path) -> dict[str, bytes | str]:
    return {
        str(p.relative_to(d)): (p.read_bytes() if p.is_file() else "dir")
        for p in sorted(d.rglob("*"))
    }


def _run(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str]:
    try:
        code = main(argv)
    except SystemExit as exc:  # argparse errors
        code = int(exc.code or 0)
    err = capsys.readouterr().err
    assert "Traceback" not in err and "internal error" not in err, err
    return code, err


def _one_error(err: str) -> str:
    lines = [ln for ln in err.splitlines() if ln.strip() and "warning:" not in ln]
    assert len(lines) == 1, f"not one line: {err}"
    return lines[0]


# ----------------------------------------------------------------------------- spoilers
def _csv(d: Path, name: str, f: Callable[[pd.DataFrame], pd.DataFrame | None]) -> None:
    df = pd.read_csv(d / name)
    out = f(df)
    (out if out is not None else df).to_csv(d / name, index=False)


def _yaml(d: Path, old: str, new: str) -> None:
    text = (d / "drive.yaml").read_text()
    assert old in text, old
    (d / "drive.yaml").write_text(text.replace(old, new))


def _yaml_value(d: Path, key: str, new: str) -> None:
    """Set ``key``'s value in drive.yaml, whatever the simulator wrote there."""
    text = (d / "drive.yaml").read_text()
    out, n = re.subn(rf"(?m)^(\s*{key}:) .*$", rf"\g<1> {new}", text)
    assert n == 1, (key, text)
    (d / "drive.yaml").write_text(out)


def _swap(d: Path) -> None:
    def f(g: pd.DataFrame) -> None:
        g["lat_deg"], g["lon_deg"] = g["lon_deg"].copy(), g["lat_deg"].copy()
    _csv(d, "gnss.csv", f)


def _drift(d: Path) -> None:
    _yaml_value(d, "gyro_bias_drift_dps", "-0.01")


def _window(d: Path) -> None:
    _yaml(d, "bias_drift_window_s: 1.0", "bias_drift_window_s: -5")


def _middle(d: Path) -> None:
    _yaml(d, "sample_time: end", "sample_time: middle")


def _lever(d: Path) -> None:
    (d / "drive.yaml").write_text((d / "drive.yaml").read_text() + "lever_arm_m: '123'\n")


def _abc(d: Path) -> None:
    _yaml_value(d, "accel_bias_drift_mps2", "abc")


def _two_imu(d: Path) -> None:
    pd.read_csv(d / "imu.csv").to_parquet(d / "imu.parquet")


def _gps(d: Path) -> None:
    (d / "gnss.csv").rename(d / "gps.csv")


def _gnss_ms(d: Path) -> None:
    def f(g: pd.DataFrame) -> None:
        g["time_s"] *= 1000.0
    _csv(d, "gnss.csv", f)


def _parquet(d: Path, f: Callable[[pd.DataFrame], None]) -> None:
    df = pd.read_csv(d / "imu.csv")
    f(df)
    df.to_parquet(d / "imu.parquet")
    (d / "imu.csv").unlink()


def _bool_gyro(d: Path) -> None:
    def f(df: pd.DataFrame) -> None:
        df["gyro_x_rads"] = df["gyro_x_rads"] > 0
    _parquet(d, f)


def _datetime_time(d: Path) -> None:
    def f(df: pd.DataFrame) -> None:
        df["time_s"] = pd.to_datetime(df["time_s"], unit="s")
    _parquet(d, f)


def _cut_gz(d: Path) -> None:
    z = gzip.compress((d / "imu.csv").read_bytes())
    (d / "imu.csv.gz").write_bytes(z[: int(0.6 * len(z))])
    (d / "imu.csv").unlink()


def _two_rows(d: Path) -> None:
    _csv(d, "imu.csv", lambda df: df.iloc[:2])


def _alias_bomb(d: Path) -> None:
    lines = ["a: &a [x, x, x, x, x, x, x, x, x]"]
    for i in range(1, 9):
        prev = "a" if i == 1 else f"b{i - 1}"
        lines.append(f"b{i}: &b{i} [{', '.join([f'*{prev}'] * 9)}]")
    lines.append("imu_axes: *b8")
    (d / "drive.yaml").write_text("\n".join(lines) + "\n")


def _nan_calibration(d: Path) -> None:
    lines = (d / "compass_cal.csv").read_text().splitlines()
    lines[3] = "nan,nan"
    (d / "compass_cal.csv").write_text("\n".join(lines) + "\n")


def _long_truth_row(d: Path) -> None:
    lines = (d / "truth.csv").read_text().splitlines()
    lines[10] += ",1,2"
    (d / "truth.csv").write_text("\n".join(lines) + "\n")


def _reversed_imu(d: Path) -> None:
    def f(df: pd.DataFrame) -> None:
        df["time_s"] = df["time_s"].to_numpy()[::-1]
    _csv(d, "imu.csv", f)


def _zero_spec(d: Path) -> None:
    text = (d / "drive.yaml").read_text()
    for k in ("accel_nd: 0.002", "accel_bs: 0.02", "gyro_nd: 0.05", "gyro_bs: 1.0"):
        text = text.replace(k, k.split(":")[0] + ": 0")
    (d / "drive.yaml").write_text(text)


def _gyros_only_noise(d: Path) -> None:
    noise = {"channels": {f"gyro_{a}": {"stationary": {"N": 1e-4, "B": 1e-5}} for a in "xyz"}}
    (d / "noise.json").write_text(json.dumps(noise))


# ----------------------------------------------------------------------------- errors
@dataclass
class Bad:
    name: str
    spoil: Callable[[Path], None]
    needles: tuple[str, ...]
    command: str = "convert"
    extra: tuple[str, ...] = ()


BAD = [
    Bad("01-lat-lon-swapped", _swap, ("gnss.csv", "swapped")),
    Bad("01-lat-lon-swapped-no-heading", lambda d: (_swap(d), (d / "heading.csv").unlink()),
        ("gnss.csv", "swapped", "no heading to say which")),
    Bad("02-negative-drift", _drift, ("drive.yaml", "imu.gyro_bias_drift_dps", ">= 0")),
    Bad("02-negative-window", _window, ("drive.yaml", "imu.bias_drift_window_s", "> 0")),
    Bad("02-sample-time-middle", _middle, ("imu.sample_time", "'middle'", "end, centre, start")),
    Bad("02-lever-arm-text", _lever, ("lever_arm_m", "three finite numbers", "'123'")),
    Bad("03-csv-and-parquet", _two_imu, ("imu.csv and imu.parquet", "keep one")),
    Bad("05-gnss-time-in-ms", _gnss_ms, ("gnss.csv", "in ms", "convert it to seconds")),
    Bad("08-boolean-gyro", _bool_gyro, ("imu.parquet", "gyro_x_rads", "booleans")),
    Bad("12-nan-compass-calibration", _nan_calibration,
        ("heading.calibration", "measured_deg", "finite")),
    Bad("12-nan-compass-cal-option", _nan_calibration, ("--compass-cal", "measured_deg"),
        command="dynamic", extra=("--compass-cal", "{d}/compass_cal.csv")),
    Bad("12-long-truth-row", _long_truth_row, ("truth.csv", "more fields than the header")),
    Bad("12-reversed-imu-time", _reversed_imu, ("imu time_s is not strictly increasing",)),
    Bad("12-all-zero-imu-spec", _zero_spec, ("drive.yaml", "imu.accel_nd", "all 0")),
    Bad("15-text-drift", _abc, ("drive.yaml", "imu.accel_bias_drift_mps2", "'abc'")),
    Bad("16-cut-gz-convert", _cut_gz, ("imu.csv.gz", "ends early")),
    Bad("16-cut-gz-dynamic", _cut_gz, ("imu.csv.gz", "ends early"), command="dynamic"),
    Bad("22-datetime-time", _datetime_time, ("imu.parquet", "time_s", "dates and times")),
    Bad("22-imu-of-two-rows", _two_rows, ("imu.csv", "2 samples", "too short")),
    Bad("23-alias-bomb", _alias_bomb, ("drive.yaml", "alias", "not allowed")),
    Bad("12-declination-1000", lambda d: None, ("--declination", "-180..180"),
        command="dynamic", extra=("--declination", "1000")),
    Bad("12-empty-imu-spec", lambda d: None, ("--imu-spec", "empty"),
        command="dynamic", extra=("--imu-spec", "")),
    Bad("12-zero-imu-spec", lambda d: None, ("--imu-spec", "every figure is 0"),
        command="dynamic",
        extra=("--imu-spec", "accel_nd=0,accel_bs=0,gyro_nd=0,gyro_bs=0")),
    Bad("12-gyros-only-noise-json", _gyros_only_noise, ("noise.json", "no accel channel"),
        command="dynamic", extra=("--static", "{d}/noise.json")),
]


@pytest.mark.parametrize("case", BAD, ids=[c.name for c in BAD])
def test_bad_drive_is_one_line_and_writes_nothing(
    case: Bad, sim: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    d = _copy(sim, tmp_path / "drive")
    case.spoil(d)
    before = _snapshot(d)
    out = tmp_path / "out"
    extra = [x.replace("{d}", str(d)) for x in case.extra]
    argv = [case.command, str(d), "-o", str(out), "-q", *extra]
    code, err = _run(argv, capsys)
    assert code == 2, f"{case.name}: exit {code}: {err}"
    line = _one_error(err)
    for needle in case.needles:
        assert needle in line, f"{case.name}: {needle!r} not in {line!r}"
    assert _snapshot(d) == before, "an input was changed"
    assert not out.exists(), "a refused command wrote its output folder"


# ----------------------------------------------------------------------------- warnings
@dataclass
class Odd:
    name: str
    spoil: Callable[[Path], None]
    key: str
    needles: tuple[str, ...]


def _spike(d: Path) -> None:
    def f(df: pd.DataFrame) -> None:
        df.loc[3000, "gyro_x_rads"] = 1e300
    _csv(d, "imu.csv", f)


def _stuck(d: Path) -> None:
    def f(df: pd.DataFrame) -> None:
        df.loc[1000:3000, "gyro_z_rads"] = 0.0
    _csv(d, "imu.csv", f)


def _one_spot(d: Path) -> None:
    def f(g: pd.DataFrame) -> None:
        g["lat_deg"] = g["lat_deg"].iloc[0]
        g["lon_deg"] = g["lon_deg"].iloc[0]
    _csv(d, "gnss.csv", f)


def _nan_yaw(d: Path) -> None:
    t = np.arange(0.0, 150.0, 1.0)
    pd.DataFrame({"time_s": t, "roll_deg": 0.0, "pitch_deg": 0.0, "yaw_deg": np.nan}).to_csv(
        d / "attitude.csv", index=False
    )


def _short_truth_row(d: Path) -> None:
    lines = (d / "truth.csv").read_text().splitlines()
    lines[20] = ",".join(lines[20].split(",")[:1])
    (d / "truth.csv").write_text("\n".join(lines) + "\n")


def _fixes_outside(d: Path) -> None:
    def f(g: pd.DataFrame) -> pd.DataFrame:
        extra = g.iloc[-3:].copy()
        extra["time_s"] = extra["time_s"] + 100.0
        return pd.concat([g, extra], ignore_index=True)
    _csv(d, "gnss.csv", f)


def _imu_col(col: str, value: float, rows: slice | int = slice(None)) -> Callable[[Path], None]:
    def spoil(d: Path) -> None:
        def f(df: pd.DataFrame) -> None:
            df.loc[rows, col] = value if not isinstance(rows, slice) else df[col] * 0 + value
        _csv(d, "imu.csv", f)
    return spoil


def _scale_cols(cols: tuple[str, ...], k: float) -> Callable[[Path], None]:
    def spoil(d: Path) -> None:
        def f(df: pd.DataFrame) -> None:
            for c in cols:
                df[c] = df[c] * k
        _csv(d, "imu.csv", f)
    return spoil


def _one_fix_inside(d: Path) -> None:
    def f(g: pd.DataFrame) -> pd.DataFrame:
        last = g.iloc[-1:].copy()
        late = last.copy()
        late["time_s"] = late["time_s"] + 100.0
        return pd.concat([last, late], ignore_index=True)
    _csv(d, "gnss.csv", f)


ODD = [
    Odd("04-gps-csv-ignored", _gps, "layout_ignored_files", ("gps.csv", "ignored")),
    Odd("12-fixes-on-one-spot", _one_spot, "gnss_one_spot", ("gnss.csv", "one spot")),
    Odd("12-nan-yaw", _nan_yaw, "attitude_yaw_nan", ("attitude.csv", "yaw")),
    Odd("12-short-truth-row", _short_truth_row, "truth_nan", ("truth.csv", "data row 20")),
    Odd("05-fixes-outside-the-imu", _fixes_outside, "gnss_outside_imu",
        ("gnss.csv", "3 of 154", "outside the IMU")),
    Odd("14-one-1e300-gyro-sample", _spike, "gyro_spikes",
        ("imu.csv", "gyro_x", "t=60.000", "2000 deg/s")),
    Odd("14-gyro-stuck-while-turning", _stuck, "gyro_stuck",
        ("imu.csv", "gyro_z", "t=20.000 to t=60.000", "turns")),
    Odd("36-accel-y-in-g", _scale_cols(("accel_y_mps2",), 1 / 9.80665), "accel_axis_units",
        ("imu.csv", "accel_y", "1/10 of accel_z", "to be in g while read as m/s^2")),
    Odd("36-one-1e300-accel-sample", _imu_col("accel_y_mps2", -1e300, 3000), "accel_spikes",
        ("imu.csv", "accel_y", "t=60.000", "400 g", "data row 3001", "corrupt")),
    Odd("36-gyro-y-converted-twice", _scale_cols(("gyro_y_rads",), np.pi / 180), "gyro_axis_units",
        ("imu.csv", "gyro_y", "of gyro_z's", "57.3x too small for rad/s (converted twice?)",
         "undo the second conversion")),
    Odd("36-accel-x-all-nan", _imu_col("accel_x_mps2", np.nan), "imu_column_empty",
        ("imu.csv", "accel_x_mps2", "no value", "accel_x is treated as absent")),
    Odd("36-two-fixes-one-in-the-imu", _one_fix_inside, "gnss_single_epoch",
        ("gnss.csv", "only one fix", "t=150.000")),
]


@pytest.mark.parametrize("case", ODD, ids=[c.name for c in ODD])
def test_suspicious_drive_is_a_counted_warning(
    case: Odd, sim: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    d = _copy(sim, tmp_path / "drive")
    case.spoil(d)
    drive = read_drive(d)
    assert drive.counts.get(case.key, 0) > 0, drive.counts
    text = "\n".join(w for w in drive.warnings if all(n in w for n in case.needles))
    assert text, f"{case.name}: no warning with {case.needles}: {drive.warnings}"
    code, err = _run(["convert", str(d), "-o", str(tmp_path / "out")], capsys)
    assert code == 0 and "imubounds: warning:" in err and case.needles[0] in err


def test_04_an_ignored_file_leaves_the_numbers_of_a_clean_run(
    sim: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    clean = _copy(sim, tmp_path / "clean")
    odd = _copy(sim, tmp_path / "odd")
    shutil.copy(odd / "gnss.csv", odd / "gps.csv")  # a stray copy beside the real table
    for d in (clean, odd):
        assert _run(["convert", str(d), "-o", str(d) + "_out", "-q"], capsys)[0] == 0
    for name in ("imu.csv", "gnss.csv", "heading.csv", "truth.csv"):
        assert (tmp_path / "odd_out" / name).read_bytes() == (
            tmp_path / "clean_out" / name).read_bytes()
    assert not (tmp_path / "odd_out" / "gps.csv").exists()


def test_07_convert_writes_a_layout_that_survives_a_move(
    sim: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    d = _copy(sim, tmp_path / "drive")
    noise = {"channels": {c: {"stationary": {"N": 1e-4, "B": 1e-5}}
                          for c in ("accel_x", "gyro_z")}}
    (d / "static.json").write_text(json.dumps(noise))
    _yaml(d, "imu:\n", "imu:\n  noise_json: static.json\n")
    for k in ("accel_nd", "accel_bs", "gyro_nd", "gyro_bs"):  # noise_json replaces them
        text = (d / "drive.yaml").read_text()
        (d / "drive.yaml").write_text(
            "\n".join(ln for ln in text.splitlines() if not ln.strip().startswith(k)) + "\n")
    out = tmp_path / "conv"
    assert _run(["convert", str(d), "-o", str(out), "-q"], capsys)[0] == 0
    text = (out / "drive.yaml").read_text()
    assert str(tmp_path) not in text, "an absolute path back into the input"
    assert "calibration: compass_cal.csv" in text and "noise_json: imu_noise.json" in text
    moved = tmp_path / "elsewhere" / "conv"
    moved.parent.mkdir()
    shutil.move(str(out), moved)
    shutil.rmtree(d)
    drive = read_drive(moved)
    assert drive.settings.heading.calibration == str(moved / "compass_cal.csv")
    assert drive.settings.imu.noise_json == str(moved / "imu_noise.json")


# ----------------------------------------------------------------------------- the API
def test_09_20_api_errors_are_imubounds_errors(sim: Path) -> None:
    x = np.random.default_rng(0).normal(0.0, 0.01, 4000)
    with pytest.raises(ib.InputError, match="signal: samples reach .*overflow"):
        ib.allan(x * 1e300, 100.0)
    with pytest.raises(ib.InputError, match="signal: every sample is below 1e-150"):
        ib.allan(x * 1e-315, 100.0)
    with pytest.raises(ib.InputError, match="complex"):
        ib.allan(x + 1j * x, 100.0)
    with pytest.raises(ib.InputError, match="gyro_z: every one of the 4000 samples is 0"):
        ib.allan(np.zeros(4000), 100.0, name="gyro_z")
    drive = read_drive(sim)
    with pytest.raises(ib.OptionError, match="noise must be a noise.json path.*got int 42"):
        ib.dynamic_margins(drive, noise=42)  # type: ignore[arg-type]
    with pytest.raises(ib.OptionError, match="imu_spec must be a preset name"):
        ib.dynamic_margins(drive, imu_spec="")
    assert ib.allan(x, 100.0).dev.size > 0  # the same signal, fine, still works
    with pytest.raises(ib.InputError, match="read_drive takes a path"):
        read_drive(42)  # type: ignore[arg-type]
    with pytest.raises(ib.InputError, match="read_log takes a file path"):
        ib.read_log(42)  # type: ignore[arg-type]
    with pytest.raises(ib.OptionError, match="seed must be a whole number"):
        ib.simulate_trip(seed="x")  # type: ignore[arg-type]


# ----------------------------------------------------------------------------- static
def _static_log(d: Path, name: str, *, scale: tuple[float, float, float] = (1, 1, 1),
                step: float = 0.01, n: int = 3000) -> Path:
    rng = np.random.default_rng(2)
    g = rng.normal(0.0, 0.01, (n, 3)) * np.asarray(scale)
    df = pd.DataFrame({"time_s": np.arange(n) * step,
                       **{f"gyro_{a}_rads": g[:, i] for i, a in enumerate("xyz")}})
    p = d / name
    df.to_csv(p, index=False)
    return p


STATIC = [
    ("10-time-in-ms-labelled-s", {"step": 10.0}, [], ("a rate no IMU log has",
                                                     "--time-unit ms", "--allow-unusual-rate")),
    ("17-log-times-1e300", {"scale": (1e300, 1e300, 1e300)}, [], ("gyro_x", "overflow")),
    ("21-one-channel-times-1e300", {"scale": (1, 1e300, 1)}, [], ("gyro_y", "overflow")),
    ("21-log-times-1e-315", {"scale": (1e-315, 1e-315, 1e-315)}, [], ("gyro_x", "underflow")),
    ("21-zeros", {"scale": (0, 1, 1)}, [], ("gyro_x", "constant")),
    ("21-zeros-out-of-core", {"scale": (0, 1, 1)}, ["--out-of-core", "--max-memory", "64KiB"],
     ("gyro_x", "constant")),
]


@pytest.mark.parametrize("case", STATIC, ids=[c[0] for c in STATIC])
def test_static_numeric_edges_name_the_channel(
    case: tuple[str, dict[str, object], list[str], tuple[str, ...]],
    tmp_path: Path, capsys: pytest.CaptureFixture[str],
) -> None:
    name, kw, extra, needles = case
    p = _static_log(tmp_path, "log.csv", **kw)  # type: ignore[arg-type]
    code, err = _run(["static", str(p), "-o", str(tmp_path / "out"), *FAST_STATIC, *extra],
                     capsys)
    assert code == 2, err
    line = _one_error(err)
    assert all(n in line for n in needles), line
    assert "log.csv" in line
    assert not (tmp_path / "out").exists()


def test_10_unusual_rates_need_confirming(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    ms = _static_log(tmp_path, "ms.csv", step=10.0)
    code, err = _run(["static", str(ms), "-o", str(tmp_path / "a"), *FAST_STATIC,
                      "--allow-unusual-rate"], capsys)
    assert code == 0 and "gives only 0.1 Hz" in err
    plain = _static_log(tmp_path, "plain.csv")
    pd.read_csv(plain).drop(columns="time_s").to_csv(tmp_path / "norate.csv", index=False)
    for rate in ("1e-9", "1e12"):
        code, err = _run(["static", str(tmp_path / "norate.csv"), "--rate", rate,
                          "-o", str(tmp_path / "b"), *FAST_STATIC], capsys)
        assert code == 2 and "a rate no IMU log has" in _one_error(err)
    with pytest.raises(ib.OptionError, match="--allow-unusual-rate"):
        read_frame({"gyro_x": np.zeros(10) + np.arange(10)}, rate_hz=1e12)


def test_11_empty_output_folder_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    p = _static_log(tmp_path, "log.csv")
    work = tmp_path / "cwd"
    work.mkdir()
    monkeypatch.chdir(work)
    for argv in (["static", str(p), "-o", "", *FAST_STATIC],
                 ["simulate", "--duration", "150", "--distance", "1500", "-o", "", "-q"]):
        code, err = _run(argv, capsys)
        assert code == 2 and "-o is empty" in _one_error(err)
    assert list(work.iterdir()) == []


def test_13_a_later_run_replaces_the_earlier_runs_report_and_figures(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    p = _static_log(tmp_path, "log.csv", n=2000)
    out = tmp_path / "out"
    out.mkdir()
    (out / "notes.md").write_text("the user's notes")
    code, err = _run(["static", str(p), "-o", str(out), "-q", "--models", "none"], capsys)
    assert code == 2 and "did not write: notes.md" in err and "--overwrite" in err
    assert _run(["static", str(p), "-o", str(out), "-q", "--models", "none", "--overwrite"],
                capsys)[0] == 0  # beside the user's notes, as they said
    first = {q.name for q in out.iterdir()}
    assert "report.html" in first and any(n.endswith(".png") for n in first)
    assert _run(["static", str(p), "-o", str(out), *FAST_STATIC, "--force"], capsys)[0] == 0
    now = {q.name for q in out.iterdir()}
    assert "report.html" not in now and not any(n.endswith((".png", ".svg")) for n in now)
    assert "noise.json" in now and (out / "notes.md").read_text() == "the user's notes"
    rec = json.loads((out / "run.json").read_text())
    assert "earlier_files" not in rec and all((out / f).is_file() for f in rec["files"])


# ----------------------------------------------------------------------------- simulate-noise
def test_12_18_simulate_noise_refuses_empty_blocks_and_binary_files(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "spec.yaml").write_text("gyro: {}\naccel:\n  N: 0.001\n")
    (tmp_path / "null.yaml").write_text("gyro:\n  N: null\n  B: null\n")
    (tmp_path / "noise.json").write_bytes(bytes(range(256)) * 8)
    for option, name, needle in (("--spec", "spec.yaml", "the gyro block is empty"),
                                 ("--spec", "null.yaml", "gyro_x.N: None is not a number"),
                                 ("--from-noise", "noise.json", "not a text file")):
        out = tmp_path / f"{name}.csv"
        code, err = _run(["simulate-noise", option, str(tmp_path / name), "--rate", "100",
                          "--duration", "10", "-o", str(out)], capsys)
        assert code == 2 and needle in _one_error(err) and name in _one_error(err)
        assert not out.exists()


# ----------------------------------------------------------------------------- issue 26
def test_26_deg_s_in_a_rads_column_is_a_counted_warning(tmp_path: Path) -> None:
    rng = np.random.default_rng(4)
    dps = 0.4 + rng.normal(0.0, 0.3, 5000)  # an ADIS16405-like gyro at rest, deg/s
    t = np.arange(dps.size) / 100.0
    df = pd.DataFrame({"time_s": t, "gyro_x_rads": dps})
    df.to_csv(tmp_path / "log.csv", index=False)
    df.to_parquet(tmp_path / "log.parquet")
    needle = "the values look like deg/s"
    for p in (tmp_path / "log.csv", tmp_path / "log.parquet"):
        assert any(needle in w and "gyro_x" in w for w in ib.read_log(p).warnings), p
    frame = pd.DataFrame({"time_s": t, "gyro_x": dps})
    assert any(needle in w for w in read_frame(frame, gyro_unit="rad/s").warnings)
    good = read_frame(frame, gyro_unit="deg/s")
    assert not any(needle in w for w in good.warnings)


# ----------------------------------------------------------------------------- property
_KEYS = [
    "imu_axes", "lever_arm_m", "imu.gyro_bias_drift_dps", "imu.sample_time", "imu.gyro_nd",
    "gnss.cep_m", "heading.declination_deg", "heading.fit", "vehicle.max_speed_mps",
    "vehicle.kind", "velocity.scale", "attitude.bound_deg", "unknown_key",
]
_VALUES = st.one_of(
    st.none(), st.booleans(), st.integers(-10**6, 10**6),
    st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=8),
    st.lists(st.one_of(st.text(max_size=3), st.floats()), max_size=4),
    st.dictionaries(st.text(max_size=4), st.integers(), max_size=2),
)
_TABLE_SPOILS = st.sampled_from([
    "none", "text-cell", "bool-column", "nan-time", "drop-time", "one-row", "huge", "dup-time",
    # issue 36
    "all-nan", "one-1e300", "swap-rows", "short-row",
])
#: What the output folder holds before the run (issue 36: only "new", "empty" and the
#: same command's results of the same input are written without --overwrite).
_OUT_STATES = st.sampled_from(["new", "empty", "user-file", "other-results", "own-results"])


def _spoil_table(d: Path, how: str, table: str) -> None:
    p = d / f"{table}.csv"
    if how == "short-row":  # a row cut after its second field
        lines = p.read_text().splitlines()
        lines[5] = ",".join(lines[5].split(",")[:2])
        p.write_text("\n".join(lines) + "\n")
        return
    df = pd.read_csv(p)
    col = df.columns[1]
    if how == "text-cell":
        df[col] = df[col].astype(object)
        df.loc[3, col] = "abc"
    elif how == "bool-column":
        df[col] = df[col] > 0
    elif how == "nan-time":
        df.loc[2, "time_s"] = np.nan
    elif how == "drop-time":
        df = df.drop(columns="time_s")
    elif how == "one-row":
        df = df.iloc[:1]
    elif how == "huge":
        df[col] = df[col] * 1e300
    elif how == "dup-time":
        df.loc[5, "time_s"] = df.loc[4, "time_s"]
    elif how == "all-nan":
        df[col] = np.nan
    elif how == "one-1e300":
        df.loc[7, col] = 1e300
    elif how == "swap-rows":
        df.iloc[[3, 4]] = df.iloc[[4, 3]].to_numpy()
    df.to_csv(p, index=False)


def _prepare_out(out: Path, state: str, d: Path, capsys: pytest.CaptureFixture[str]) -> None:
    if state == "new":
        return
    out.mkdir()
    if state == "user-file":
        (out / "mine.txt").write_text("the user's file")
    elif state == "other-results":
        (out / "noise.json").write_text("{}")
        (out / "run.json").write_text(json.dumps({"command": "imubounds static x.csv",
                                                  "command_name": "static",
                                                  "files": ["noise.json"]}))
    elif state == "own-results":  # an earlier convert of the same input
        clean = Path(str(d) + "_clean")
        _run(["convert", str(clean), "-o", str(out), "-q"], capsys)
        rec = json.loads((out / "run.json").read_text())
        rec["inputs"] = [str(d.resolve())]  # as if converted from this folder
        (out / "run.json").write_text(json.dumps(rec))


#: dynamic options that override a drive.yaml setting, with its range (issue 36)
_DYN_OPTIONS = ["--heading-deviation", "--heading-noise", "--attitude-bound", "--max-tilt",
                "--misalignment", "--scale", "--gnss-vel-sigma", "--declination"]


@settings(max_examples=40, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    edits=st.dictionaries(st.sampled_from(_KEYS), _VALUES, max_size=3),
    table=st.sampled_from(["imu", "gnss", "heading", "truth"]),
    how=_TABLE_SPOILS,
    state=_OUT_STATES,
    overwrite=st.booleans(),
)
def test_property_no_traceback_and_nothing_written_on_refusal(
    sim: Path, capsys: pytest.CaptureFixture[str],
    edits: dict[str, object], table: str, how: str, state: str, overwrite: bool,
) -> None:
    import yaml

    with tempfile.TemporaryDirectory() as tmp:
        d = _copy(sim, Path(tmp) / "drive")
        if state == "own-results":
            _copy(sim, Path(tmp) / "drive_clean")
        data = yaml.safe_load((d / "drive.yaml").read_text())
        for key, value in edits.items():
            section, _, name = key.partition(".")
            if name:
                if not isinstance(data.get(section), dict):
                    data[section] = {}
                data[section][name] = value
            else:
                data[section] = value
        (d / "drive.yaml").write_text(yaml.safe_dump(data))
        _spoil_table(d, how, table)
        out = Path(tmp) / "out"
        _prepare_out(out, state, d, capsys)
        before = _snapshot(d)
        before_out = _snapshot(out) if out.exists() else None
        argv = ["convert", str(d), "-o", str(out), "-q", *(["--overwrite"] if overwrite else [])]
        code, err = _run(argv, capsys)
        assert code in (0, 2), err
        assert _snapshot(d) == before
        if code == 2:
            line = _one_error(err)
            if str(out) in line:  # the folder, not an input, is refused: naming its files
                assert "mine.txt" in line or "noise.json" in line, line
            if before_out is None:
                assert not out.exists(), "a refused run left its output folder"
            else:
                assert _snapshot(out) == before_out, "a refused run wrote into the output folder"
        else:
            assert state not in ("user-file", "other-results") or overwrite, "not refused"
            assert (out / "drive.yaml").is_file()
            if state == "user-file":
                assert (out / "mine.txt").read_text() == "the user's file"
            for w in (ln for ln in err.splitlines() if "warning:" in ln):
                assert str(d) in w or "drive.yaml" in w, f"a warning naming no file: {w}"


@settings(max_examples=25, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(opts=st.lists(st.tuples(st.sampled_from(_DYN_OPTIONS), st.one_of(
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.sampled_from(["", "abc", "1e999", "-0", "1000", "-1", "90", "180", "0.5"]))),
    min_size=1, max_size=3))
def test_property_dynamic_options_out_of_range_are_refused_when_parsed(
    sim: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str],
    opts: list[tuple[str, str]],
) -> None:
    """Whatever the values, an option is refused at parse time naming it, or taken; the
    run is stopped at parse time by an invalid --max-windows after them, so that nothing
    is computed: exit 2, one line naming one of the options, nothing written."""
    out = tmp_path / "out"
    flat = [x for o, v in opts for x in (o, f"={v}")]
    argv = ["dynamic", str(sim), "-o", str(out), *[a + b if b.startswith("=") else a
                                                     for a, b in zip(flat[::2], flat[1::2],
                                                                     strict=True)],
            "--max-windows", "0"]
    code, err = _run(argv, capsys)
    assert code == 2, err
    line = _one_error(err)
    assert any(f"argument {o}" in line for o, _ in opts) or "argument --max-windows" in line
    assert not out.exists()


# ----------------------------------------------------------------------------- real formats
def test_12_comma2k19_gyro_with_reversed_time_is_refused(
    shared_data: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    d = tmp_path / "comma"
    shutil.copytree(shared_data / "dynamic" / "comma2k19_example1", d)
    p = d / "processed_log" / "IMU" / "gyro" / "t"
    with open(p, "rb") as fh:
        t = np.load(fh)
    with open(p, "wb") as fh:
        np.save(fh, t[::-1].copy())
    before = _snapshot(d)
    code, err = _run(["convert", str(d), "-o", str(tmp_path / "out"), "-q"], capsys)
    assert code == 2 and _snapshot(d) == before
    line = _one_error(err)
    assert "gyro/t" in line and "go backwards" in line and "sort it by time" in line


def test_12_vn100_nan_yaw_and_frozen_fixes_are_counted(
    shared_data: Path, tmp_path: Path
) -> None:
    src = shared_data / "dynamic" / "vn100_bu353_circle"
    imu, gps = tmp_path / "circle_data_0_imu.csv", tmp_path / "circle_data_0_gps.csv"
    df = pd.read_csv(src / "circle_data_0_imu.csv")
    df["raw_vnymr"] = df["raw_vnymr"].str.replace(
        r"^\$VNYMR,[+-][0-9.]+,", "$VNYMR,nan,", regex=True)
    df.to_csv(imu, index=False)
    g = pd.read_csv(src / "circle_data_0_gps.csv")
    g["latitude"], g["longitude"] = g["latitude"].iloc[0], g["longitude"].iloc[0]
    g.to_csv(gps, index=False)
    drive = read_drive([imu, gps])
    # the yaw is named and left out; the roll and pitch of every sentence are kept
    assert drive.counts["attitude_yaw_nan"] == df.shape[0] and "attitude_nan" not in drive.counts
    assert drive.attitude is not None and drive.attitude.yaw_rad is None
    assert drive.attitude.t.size == df.shape[0]
    assert any("yaw has no finite value" in w and imu.name in w for w in drive.warnings)
    assert drive.counts["gnss_one_spot"] == g.shape[0] - drive.counts.get("gnss_no_fix", 0)
    assert any("one spot" in w and gps.name in w for w in drive.warnings)


@pytest.mark.parametrize("name", ["vn100_bu353_circle", "comma2k19_example1"])
def test_a_drive_yaml_in_a_log_directory_is_read(
    name: str, shared_data: Path, tmp_path: Path
) -> None:
    """The console's advice ("state vehicle.max_tilt_deg in drive.yaml", ...) holds for
    every directory layout: a drive.yaml beside a VN-100 pair or in a comma2k19 segment
    is the user's settings, not ignored; without one every setting is a named default."""
    d = shutil.copytree(shared_data / "dynamic" / name, tmp_path / name)
    plain = read_drive(d)
    assert plain.settings.vehicle.max_tilt_deg == 10.0
    assert any("no drive.yaml" in a for a in plain.settings.assumed)
    (d / "drive.yaml").write_text("vehicle:\n  max_tilt_deg: 4\n")
    drive = read_drive(d)
    assert drive.settings.vehicle.max_tilt_deg == 4.0
    assert not any("no drive.yaml" in a for a in drive.settings.assumed)
    assert "vehicle.max_tilt_deg" not in drive.settings.defaulted


# ----------------------------------------------------------------------------- issue 36
# `imubounds dynamic` on spoiled drives, from the command line: an error names the file or
# option and the problem (exit 2, nothing written), a suspicious input is a warning naming
# it (exit 0, even with -q), dynamic.json is strict JSON (no NaN, no Infinity), and no file
# outside the run's output folder changes.
DYN = ["--mode", "full", "--no-plot", "--no-report", "-q"]


def _strict_json(p: Path) -> object:
    def refuse(name: str) -> object:
        raise AssertionError(f"{p.name} holds {name}")
    return json.loads(p.read_text(), parse_constant=refuse)


def _truth_lines(edit: Callable[[list[str]], None]) -> Callable[[Path], None]:
    def spoil(d: Path) -> None:
        lines = (d / "truth.csv").read_text().splitlines()
        edit(lines)
        (d / "truth.csv").write_text("\n".join(lines) + "\n")
    return spoil


def _swap_rows(lines: list[str]) -> None:
    lines[20], lines[21] = lines[21], lines[20]


def _repeat_row(lines: list[str]) -> None:
    lines.insert(21, lines[20])


def _cut_after_position(lines: list[str]) -> None:
    """Data row 20 cut after east_m, north_m (a short row: the rest of it empty)."""
    lines[20] = ",".join(lines[20].split(",")[:3])


def _one_fix_beside_velocity(d: Path) -> None:
    _csv(d, "gnss.csv", lambda g: g.iloc[:1])
    t = pd.read_csv(d / "truth.csv")
    pd.DataFrame({"time_s": t["time_s"], "u_mps": t["u_mps"], "v_mps": t["v_mps"]}).to_csv(
        d / "velocity.csv", index=False)


DYN_BAD = [
    Bad("36-heading-deviation-1000", lambda d: None, ("--heading-deviation", "at most 180"),
        command="dynamic", extra=("--heading-deviation", "1000")),
    Bad("36-max-tilt-100", lambda d: None, ("--max-tilt", "at most 90"),
        command="dynamic", extra=("--max-tilt", "100")),
    Bad("36-gnss-velocity-sigma-0", lambda d: None, ("--gnss-vel-sigma", "> 0"),
        command="dynamic", extra=("--gnss-vel-sigma", "0")),
    Bad("36-truth-rows-out-of-order", _truth_lines(_swap_rows),
        ("truth.csv", "not strictly increasing", "data row 21", "sort"), command="dynamic"),
    Bad("36-truth-row-repeated", _truth_lines(_repeat_row),
        ("truth.csv", "not strictly increasing", "data row 21"), command="dynamic"),
    Bad("36-one-gyro-sample-1e300", _imu_col("gyro_x_rads", 1e300, 3000),
        ("imu.csv", "gyro_x", "t=60.000", "data row 3001", "corrupt"), command="dynamic"),
    Bad("36-one-accel-sample-1e300", _imu_col("accel_y_mps2", -1e300, 3000),
        ("imu.csv", "accel_y", "400 g", "corrupt"), command="dynamic"),
    Bad("36-gyro-x-y-in-deg-s", _scale_cols(("gyro_x_rads", "gyro_y_rads"), 180 / np.pi),
        ("imu.csv", "gyro_x", "deg/s while read as rad/s", "convert gyro_x to rad/s"),
        command="dynamic"),
    Bad("36-gyro-x-in-deg-s", _scale_cols(("gyro_x_rads",), 180 / np.pi),
        ("imu.csv", "gyro_x", "deg/s"), command="dynamic"),
    Bad("36-gnss-all-nan", lambda d: _csv(d, "gnss.csv", lambda g: g.assign(lat_deg=np.nan)),
        ("gnss.csv", "lat_deg", "no finite value"), command="dynamic"),
    Bad("36-heading-stream-empty", lambda d: _csv(d, "heading.csv", lambda h: h.iloc[:0]),
        ("heading.csv", "no data rows"), command="dynamic"),
    Bad("36-drive-yaml-notes-mapping",
        lambda d: (d / "drive.yaml").write_text((d / "drive.yaml").read_text()
                                                + "notes: {a: 1}\n"),
        ("drive.yaml", "notes must be a text or a list"), command="dynamic"),
]


@pytest.mark.parametrize("case", DYN_BAD, ids=[c.name for c in DYN_BAD])
def test_36_dynamic_refuses_bad_drives_naming_file_and_problem(
    case: Bad, sim: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    d = _copy(sim, tmp_path / "drive")
    case.spoil(d)
    before = _snapshot(tmp_path)
    out = tmp_path / "out"
    code, err = _run(["dynamic", str(d), "-o", str(out), *DYN, *case.extra], capsys)
    assert code == 2, f"{case.name}: exit {code}: {err}"
    line = _one_error(err)
    for needle in case.needles:
        assert needle in line, f"{case.name}: {needle!r} not in {line!r}"
    assert _snapshot(tmp_path) == before, "a file changed, or the refused run wrote one"


@dataclass
class Warned:
    name: str
    spoil: Callable[[Path], None]
    needles: tuple[str, ...]
    check: Callable[[dict[str, object]], None] | None = None


def _heading_share_survives(doc: dict[str, object]) -> None:
    enc = doc["modes"]["full"]["enclosure"]  # type: ignore[index]
    assert enc.get("heading") is not None and enc["heading"] > 0.9, enc  # was dropped


DYN_WARNED = [
    Warned("36-gyro-z-all-nan", _imu_col("gyro_z_rads", np.nan),
           ("imu.csv", "gyro_z_rads", "no value in any of its 7501 rows", "absent")),
    Warned("36-one-gnss-fix-beside-heading-and-velocity", _one_fix_beside_velocity,
           ("gnss.csv", "only one fix", "t=0.000")),
    Warned("36-truth-short-row", _truth_lines(_cut_after_position),
           ("truth.csv", "data row 20", "heading_deg", "short row"), _heading_share_survives),
    # the neighbours: another gyro axis, an accelerometer axis, one NaN truth heading
    Warned("36-gyro-x-all-nan", _imu_col("gyro_x_rads", np.nan),
           ("imu.csv", "gyro_x_rads", "no value in any of its 7501 rows", "absent")),
    Warned("36-accel-z-all-nan", _imu_col("accel_z_mps2", np.nan),
           ("imu.csv", "accel_z_mps2", "no value in any of its 7501 rows", "absent")),
    Warned("36-truth-one-nan-heading",
           lambda d: _csv(d, "truth.csv", lambda t: t.assign(
               heading_deg=t["heading_deg"].where(t.index != 300))),
           ("truth.csv", "data row 301", "heading_deg", "left out of the truth check"),
           _heading_share_survives),
]


@pytest.mark.parametrize("case", DYN_WARNED, ids=[c.name for c in DYN_WARNED])
def test_36_dynamic_warns_naming_file_and_problem(
    case: Warned, sim: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    d = _copy(sim, tmp_path / "drive")
    case.spoil(d)
    before = _snapshot(d)
    out = tmp_path / "out"
    code, err = _run(["dynamic", str(d), "-o", str(out), *DYN], capsys)
    assert code == 0, f"{case.name}: exit {code}: {err}"
    warned = [ln for ln in err.splitlines() if ln.startswith("imubounds: warning:")]
    assert any(all(n in ln for n in case.needles) for ln in warned), (case.needles, err)
    assert _snapshot(d) == before, "an input was changed"
    doc = _strict_json(out / "dynamic.json")
    assert any(all(n in w for n in case.needles)
               for w in doc["input"]["warnings"])  # type: ignore[index]
    if case.check is not None:
        case.check(doc)  # type: ignore[arg-type]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["drive", "out"]


def test_36_vn100_log_with_nan_yaw_on_every_row_is_named_by_dynamic(
    shared_data: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    src = shared_data / "dynamic" / "vn100_bu353_circle"
    d = tmp_path / "vn"
    d.mkdir()
    df = pd.read_csv(src / "circle_data_0_imu.csv")
    df["raw_vnymr"] = df["raw_vnymr"].str.replace(
        r"^\$VNYMR,[+-][0-9.]+,", "$VNYMR,nan,", regex=True)
    df.to_csv(d / "circle_data_0_imu.csv", index=False)
    shutil.copy(src / "circle_data_0_gps.csv", d)
    before = _snapshot(d)
    code, err = _run(["dynamic", str(d), "-o", str(tmp_path / "out"), *DYN], capsys)
    assert code == 0, err
    assert any("circle_data_0_imu.csv" in ln and "yaw has no finite value in 2530 row(s)" in ln
               for ln in err.splitlines() if ln.startswith("imubounds: warning:")), err
    assert _snapshot(d) == before
    _strict_json(tmp_path / "out" / "dynamic.json")


def test_36_the_truth_check_projects_at_the_truths_altitude() -> None:
    """A truth in lat/lon/alt_m at 1,600 m and an estimator origin 2 km away at 1,610 m:
    truth_at gives the ENU the GNSS frame has (pymap3d, independently), to a millimetre.
    Projected at h = 0, as before, it was 0.5 m off at 2 km (the 49.9 % of the issue on
    a longer trip)."""
    import pymap3d

    from imubounds.dynamic.estimator.result import truth_at
    from imubounds.io.drive import Drive
    from imubounds.io.drive.layout import truth_from_table

    t = np.arange(0.0, 300.0, 1.0)
    ang = 2 * np.pi * t / 300.0
    e, n, u = 3000 * np.cos(ang), 3000 * np.sin(ang), 20 * np.sin(3 * ang)
    org = (45.0, 7.0, 1600.0)
    lat, lon, alt = pymap3d.enu2geodetic(e, n, u, *org)
    heading = np.degrees(ang) % 360
    heading[40] = np.nan  # one NaN heading row: the rest keeps its share
    df = pd.DataFrame({"time_s": t, "lat_deg": lat, "lon_deg": lon, "alt_m": alt,
                       "heading_deg": heading})
    drive = Drive(truth=truth_from_table(df, "truth.csv"))
    gnss_org = pymap3d.enu2geodetic(2000.0, 0.0, 10.0, *org)
    tr = truth_at(drive, t[5:-5] + 0.5, gnss_org)
    ee, nn, _ = pymap3d.geodetic2enu(lat, lon, alt, *gnss_org)
    assert np.max(np.abs(tr["east"] - np.interp(t[5:-5] + 0.5, t, ee))) < 1e-3
    assert np.max(np.abs(tr["north"] - np.interp(t[5:-5] + 0.5, t, nn))) < 1e-3
    psi = tr["psi"]
    assert np.isnan(psi[34]) and np.isnan(psi[35]) and np.isfinite(psi).sum() == psi.size - 2


def _truth_at_1600_m_rtk(d: Path) -> None:
    """The drive moved to 1,600 m, its truth written as lat_deg, lon_deg, alt_m and its GNSS
    replaced by 2 cm fixes of the truth (h_acc_m 0.02): boxes of about 0.1 m."""
    import pymap3d

    tr = pd.read_csv(d / "truth.csv")
    org = (float(tr["origin_lat_deg"][0]), float(tr["origin_lon_deg"][0]), 1600.0)
    lat, lon, alt = pymap3d.enu2geodetic(tr["east_m"], tr["north_m"], tr["up_m"], *org)
    out = tr.drop(columns=["east_m", "north_m", "origin_lat_deg", "origin_lon_deg",
                           "origin_alt_m", "up_m"])
    out.insert(1, "lat_deg", lat)
    out.insert(2, "lon_deg", lon)
    out.insert(3, "alt_m", alt)
    out.to_csv(d / "truth.csv", index=False)
    rng = np.random.default_rng(4)

    def f(g: pd.DataFrame) -> None:
        e = np.interp(g["time_s"], tr["time_s"], tr["east_m"]) + rng.normal(0, 0.02, len(g))
        n = np.interp(g["time_s"], tr["time_s"], tr["north_m"]) + rng.normal(0, 0.02, len(g))
        u = np.interp(g["time_s"], tr["time_s"], tr["up_m"])
        g["lat_deg"], g["lon_deg"], g["alt_m"] = pymap3d.enu2geodetic(e, n, u, *org)
        g["h_acc_m"] = 0.02
    _csv(d, "gnss.csv", f)


def test_36_the_truth_check_of_dynamic_at_1600_m(
    sim: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """From the command line: 2 cm GNSS boxes at 1,600 m, truth in lat/lon/alt_m. The check
    projected the truth at h = 0 and printed "truth inside: position 87.4%" (the boxes
    hold the truth: the check was wrong); at the truth's own height it is 100 %."""
    d = _copy(sim, tmp_path / "drive")
    _truth_at_1600_m_rtk(d)
    before = _snapshot(d)
    code, err = _run(["dynamic", str(d), "-o", str(tmp_path / "out"), *DYN], capsys)
    assert code == 0, err
    enc = _strict_json(tmp_path / "out" / "dynamic.json")["modes"]["full"]["enclosure"]  # type: ignore[index]
    assert enc["position"] == 1.0, enc
    assert _snapshot(d) == before


def test_36_drive_yaml_notes_may_be_one_text(
    sim: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """notes as one text (the docs do not forbid it) was refused; now read as one note, from
    the command line too (convert writes it back, the input untouched)."""
    import yaml

    d = _copy(sim, tmp_path / "drive")
    (d / "drive.yaml").write_text((d / "drive.yaml").read_text() + "notes: logged by Ana\n")
    assert "logged by Ana" in read_drive(d).notes
    before = _snapshot(d)
    code, err = _run(["convert", str(d), "-o", str(tmp_path / "out"), "-q"], capsys)
    assert code == 0, err
    assert "logged by Ana" in yaml.safe_load((tmp_path / "out" / "drive.yaml").read_text())[
        "notes"]
    assert _snapshot(d) == before


def test_36_the_budget_says_where_each_number_came_from(
    sim: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """GNSS velocities with the receiver's accuracy at every other fix: the budget row of
    the velocity sigma names the receiver for those and drive.yaml's 0.1 m/s for the rest
    (it said "0.1, drive.yaml" while the per-fix accuracies were used); a setting the
    drive.yaml leaves out is "default (drive.yaml silent)", never "drive.yaml"."""
    d = _copy(sim, tmp_path / "drive")
    tr = pd.read_csv(d / "truth.csv")

    def f(g: pd.DataFrame) -> None:
        g["vel_e_mps"] = np.interp(g["time_s"], tr["time_s"], tr["vel_e_mps"])
        g["vel_n_mps"] = np.interp(g["time_s"], tr["time_s"], tr["vel_n_mps"])
        g["vel_acc_mps"] = np.where(np.arange(len(g)) % 2 == 0, 0.05, np.nan)
    _csv(d, "gnss.csv", f)
    _yaml(d, "  cep_m: 3.0\n", "")
    code, err = _run(["dynamic", str(d), "-o", str(tmp_path / "out"), *DYN], capsys)
    assert code == 0, err
    doc = _strict_json(tmp_path / "out" / "dynamic.json")
    budget = doc["modes"]["full"]["aiding_budget"]  # type: ignore[index]
    rows = {t["term"]: t for t in budget["gnss_velocity"]}
    sigma = rows["velocity sigma per component"]
    n = len(pd.read_csv(d / "gnss.csv"))
    assert sigma["source"] == (f"receiver's vel_acc_mps at {(n + 1) // 2} of {n} fixes "
                               "(median); drive.yaml 0.1 m/s at the others"), sigma
    assert sigma["value"] == pytest.approx(0.05 if n % 2 else 0.075)
    cep = {t["term"]: t for t in budget["gnss_position"]}["CEP at HDOP 1"]
    assert cep["source"] == "default (drive.yaml silent)", cep


def test_36_simulate_refuses_options_that_make_an_unreadable_drive_yaml(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """--misalignment 100 (a sigma: the bound written is 334 deg) used to write a layout
    that every reader refused; now the option is named and nothing is written."""
    out = tmp_path / "sim"
    code, err = _run(["simulate", "--duration", "150", "--distance", "1500", "--rate", "20",
                      "-o", str(out), "--misalignment", "100", "-q"], capsys)
    assert code == 2
    line = _one_error(err)
    assert "--misalignment" in line and "imu.misalignment_deg must be at most 90" in line
    assert list(tmp_path.iterdir()) == []
