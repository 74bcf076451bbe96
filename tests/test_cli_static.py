"""End-to-end tests of ``imubounds static`` on the real ADIS16405 log and on bad input."""

from __future__ import annotations

import gzip
import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from imubounds.cli import main
from imubounds.units import DEG, G0

CHANNELS = ("gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z")


@pytest.fixture(scope="module")
def real_run(tmp_path_factory: pytest.TempPathFactory, adis_log_path: Path) -> Path:
    out = tmp_path_factory.mktemp("static_real")
    code = main(["static", str(adis_log_path), "-o", str(out), "--quiet"])
    assert code == 0
    return out


def test_real_log_outputs_exist_and_are_consistent(real_run: Path) -> None:
    data = json.loads((real_run / "noise.json").read_text())
    assert data["input"]["sample_rate_hz"] == pytest.approx(100.0)
    assert data["input"]["duration_s"] == pytest.approx(10000.0, rel=1e-3)
    assert set(data["channels"]) == set(CHANNELS)
    for name in CHANNELS:
        ch = data["channels"][name]
        assert ch["unit"] == ("rad/s" if name.startswith("gyro") else "m/s^2")
        a = ch["allan"]
        assert len(a["tau_s"]) == len(a["adev"]) == len(a["ci_lower"]) == len(a["ci_upper"])
        assert all(
            lo <= d <= hi for lo, d, hi in zip(a["ci_lower"], a["adev"], a["ci_upper"], strict=True)
        )
        for method in ("slope", "fit"):
            for term in ("Q", "N", "B", "K", "R"):
                entry = ch["noise"][method][term]
                assert {"value", "unit", "ieee"} <= set(entry)
        n = ch["noise"]["fit"]["N"]["value"]
        assert n > 0
        assert ch["sigma_c"] > 0 and ch["bound_3sigma"] == pytest.approx(3 * ch["sigma_c"])
    assert (real_run / "allan.png").stat().st_size > 10_000
    assert (real_run / "allan.svg").stat().st_size > 10_000


def test_real_log_noise_density_matches_datasheet_order(real_run: Path) -> None:
    # ADIS16405 datasheet: gyro noise density 0.05 deg/s/sqrt(Hz) (= 3 deg/sqrt(h));
    # accel 0.5 mg/sqrt(Hz) ~ 0.29 m/s/sqrt(h). The recorded unit ought to be near them.
    data = json.loads((real_run / "noise.json").read_text())
    gyro_n = data["channels"]["gyro_x"]["noise"]["fit"]["N"]["ieee"]["value"]
    accel_n = data["channels"]["accel_x"]["noise"]["fit"]["N"]["ieee"]["value"]
    assert 0.5 < gyro_n < 10.0, gyro_n
    assert 0.02 < accel_n < 1.0, accel_n


def test_real_log_kalibr_yaml(real_run: Path) -> None:
    y = yaml.safe_load((real_run / "imu.yaml").read_text())
    for key in (
        "gyroscope_noise_density",
        "gyroscope_random_walk",
        "accelerometer_noise_density",
        "accelerometer_random_walk",
    ):
        assert y[key] > 0, key
    assert y["update_rate"] == pytest.approx(100.0)
    text = (real_run / "imu.yaml").read_text()
    assert "axis gyro_" in text and "axis accel_" in text


def test_json_summary_on_stdout(adis_log_path: Path, tmp_path: Path) -> None:
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "imubounds",
            "static",
            str(adis_log_path),
            "-o",
            str(tmp_path),
            "--json",
            "--quiet",
            "--no-plot",
            "--channels",
            "gyro_z",
            "--tau",
            "20",
        ],
        capture_output=True,
        text=True,
        check=False,
    )
    assert proc.returncode == 0, proc.stderr
    summary = json.loads(proc.stdout)
    assert list(summary) == ["gyro_z"]
    assert summary["gyro_z"]["N"]["ieee"]["unit"] == "deg/h^0.5"


def _write_csv(path: Path, rows: list[str]) -> Path:
    path.write_text("\n".join(rows) + "\n")
    return path


def run_cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "imubounds", *args], capture_output=True, text=True, check=False
    )


def _good_rows(n: int = 4000, rate: float = 100.0) -> list[str]:
    rng = np.random.default_rng(0)
    rows = ["time_s,gyro_x_dps,accel_x_g"]
    for i in range(n):
        rows.append(f"{i / rate:.4f},{rng.normal(0, 0.1):.6f},{rng.normal(0, 0.01):.6f}")
    return rows


@pytest.mark.parametrize(
    ("name", "mutate", "needle"),
    [
        ("empty", lambda rows: [], "empty"),
        ("nonnumeric", lambda rows: rows[:10] + ["0.1,abc,0.0"] + rows[11:], "abc"),
        ("nan", lambda rows: rows[:10] + ["0.09,nan,0.0"] + rows[11:], "row"),
        ("unsorted", lambda rows: rows[:10] + [rows[12], rows[11]] + rows[13:], "time"),
        ("nocols", lambda rows: ["time_s,foo,bar", "0,1,2", "0.01,1,2"], "--columns"),
    ],
)
def test_bad_input_one_line_error_exit_2(tmp_path: Path, name: str, mutate, needle: str) -> None:
    path = _write_csv(tmp_path / f"{name}.csv", mutate(_good_rows(200)))
    proc = run_cli("static", str(path), "-o", str(tmp_path / "out"), "--quiet")
    assert proc.returncode == 2, proc.stderr
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1, proc.stderr
    assert "Traceback" not in proc.stderr
    assert needle.lower() in lines[0].lower()
    assert not (tmp_path / "out" / "noise.json").exists()


def test_truncated_gzip_is_a_clear_error(tmp_path: Path) -> None:
    raw = gzip.compress(("\n".join(_good_rows(5000)) + "\n").encode())
    path = tmp_path / "cut.csv.gz"
    path.write_bytes(raw[: len(raw) // 2])
    proc = run_cli("static", str(path), "-o", str(tmp_path / "out"), "--quiet")
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr and str(path.name) in proc.stderr


def test_log_too_short_for_requested_tau(tmp_path: Path) -> None:
    path = _write_csv(tmp_path / "short.csv", _good_rows(300))
    proc = run_cli("static", str(path), "-o", str(tmp_path / "out"), "--tau", "1,1000", "--quiet")
    assert proc.returncode == 2
    assert "tau" in proc.stderr.lower() and "Traceback" not in proc.stderr


def test_inconsistent_rate_option(tmp_path: Path) -> None:
    path = _write_csv(tmp_path / "ok.csv", _good_rows(500))
    proc = run_cli("static", str(path), "-o", str(tmp_path / "out"), "--rate", "50", "--quiet")
    assert proc.returncode == 2
    assert "rate" in proc.stderr.lower()


def test_units_are_converted_to_si(tmp_path: Path) -> None:
    path = _write_csv(tmp_path / "ok.csv", _good_rows(4000))
    out = tmp_path / "out"
    assert main(["static", str(path), "-o", str(out), "--quiet", "--no-plot"]) == 0
    data = json.loads((out / "noise.json").read_text())
    # White noise of std 0.1 deg/s at 100 Hz: N = 0.1 deg/s * sqrt(0.01 s) in rad/sqrt(s).
    n = data["channels"]["gyro_x"]["noise"]["fit"]["N"]["value"]
    assert n == pytest.approx(0.1 * DEG * math.sqrt(0.01), rel=0.1)
    na = data["channels"]["accel_x"]["noise"]["fit"]["N"]["value"]
    assert na == pytest.approx(0.01 * G0 * math.sqrt(0.01), rel=0.1)
