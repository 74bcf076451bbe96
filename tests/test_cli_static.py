"""End-to-end tests of ``imubounds static`` on the real ADIS16405 log and on bad input."""

from __future__ import annotations

import gzip
import json
import math
import re
import subprocess
import sys
from pathlib import Path
from typing import Any

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
        assert ch["sigma_c"] > 0 and "bound_3sigma" not in ch
        assert ch["bound"]["k"] == 3.0
        assert ch["bound"]["value"] == pytest.approx(3 * ch["sigma_c"])
        assert ch["bound"]["unit"] == ch["unit"]
        sel = ch["noise"]["selected"]
        for term in ("Q", "N", "B", "K", "R"):
            assert sel[term]["status"] in ("resolved", "upper_bound", "not_observed")
            assert {"value", "unit", "ieee", "datasheet", "from"} <= set(sel[term])
        assert sel["N"]["value"] == ch["stationary"]["N"]
        assert sel["B"]["value"] == ch["stationary"]["B"]
        assert sel["sigma_min"]["tau_s"] > 0 and sel["sigma_min"]["unit"] == ch["unit"]
        assert sel["N"]["adev_at_1s"]["value"] == sel["N"]["value"]
        # the random-walk growth is an angle (rad) or a velocity (m/s), not a rate
        rw = ch["random_walk_95"]
        assert rw["unit"] == ("rad" if name.startswith("gyro") else "m/s")
        assert rw["datasheet"]["unit"] == ("deg" if name.startswith("gyro") else "m/s")
        assert "level_95" not in ch
        assert len(a["noise_type"]) == len(a["tau_s"])
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
    data = json.loads((real_run / "noise.json").read_text())
    for key, kind, term in (
        ("gyroscope_noise_density", "gyro", "N"),
        ("gyroscope_random_walk", "gyro", "K"),
        ("accelerometer_noise_density", "accel", "N"),
        ("accelerometer_random_walk", "accel", "K"),
    ):
        assert y[key] > 0, key
        # imu.yaml carries the selected terms: the largest axis of the sensor
        selected = [
            ch["noise"]["selected"][term]["value"]
            for name, ch in data["channels"].items()
            if name.startswith(kind)
        ]
        assert y[key] == pytest.approx(max(selected), rel=1e-6), key
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
            "points:20",
        ],
        capture_output=True,
        text=True,
        check=False,
    )
    assert proc.returncode == 0, proc.stderr
    summary = json.loads(proc.stdout)
    assert list(summary) == ["gyro_z"]
    assert summary["gyro_z"]["N"]["ieee"]["unit"] == "deg/h^0.5"
    assert summary["gyro_z"]["N"]["datasheet"]["unit"] == "deg/s/sqrt(Hz)"
    assert summary["gyro_z"]["N"]["status"] == "resolved"
    assert summary["gyro_z"]["bound"]["k"] == 3.0
    assert summary["gyro_z"]["sigma_min"]["tau_s"] > 1.0


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
    proc = run_cli("static", str(path), "-o", str(tmp_path / "out"), "--tau", "1,1000s", "--quiet")
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


# ---------------------------------------------------------------------------
# every estimator on the bundled ADIS16405 log gives the same N and B
# ---------------------------------------------------------------------------
def _selected_by_estimator(path: Path) -> dict[str, dict[str, Any]]:
    from imubounds.io import read_imu
    from imubounds.stationary.allan import ESTIMATORS
    from imubounds.stationary.pipeline import StaticSettings, analyse_static

    log = read_imu(path)
    return {
        est: analyse_static(log, StaticSettings(estimator=est)).channels for est in ESTIMATORS
    }


@pytest.mark.slow  # six estimators on 10^6 samples x 6 channels: ~20 s
def test_adis_log_same_n_and_b_whatever_the_estimator(adis_log_path: Path) -> None:
    res = _selected_by_estimator(adis_log_path)
    ref = res["overlapping"]
    bad = []
    for est, chans in res.items():
        for name, ch in chans.items():
            r = ref[name].selected
            for t, tol in (("N", 0.10), ("B", 0.25)):
                assert ch.selected.status(t) == "resolved", (est, name, t)
                ratio = ch.selected.value(t) / r.value(t)
                if abs(ratio - 1) > tol:
                    bad.append(f"{est} {name} {t}: x{ratio:.3f} of the overlapping value")
    assert not bad, "\n".join(bad)


@pytest.mark.slow  # six estimators on the 45-min extract: ~8 s
def test_bundled_extract_same_n_and_consistent_b() -> None:
    """The 45-minute extract resolves N on every axis; B only where the floor shows: a
    resolved B agrees within 25 % across estimators and an upper bound does not fall
    below a resolved value (less 25 %)."""
    from imubounds.io.registry import bundled_static_log

    res = _selected_by_estimator(bundled_static_log())
    bad = []
    for name in res["overlapping"]:
        n_vals = [res[e][name].selected.value("N") for e in res]
        if max(n_vals) / min(n_vals) > 1.10:
            bad.append(f"{name} N spread x{max(n_vals) / min(n_vals):.3f}")
        b = [(res[e][name].selected.value("B"), res[e][name].selected.status("B")) for e in res]
        resolved = [v for v, s in b if s == "resolved"]
        if resolved and max(resolved) / min(resolved) > 1.25 / 0.75:
            bad.append(f"{name} resolved B spread x{max(resolved) / min(resolved):.3f}")
        if resolved:
            low = min(v for v, s in b if s == "upper_bound") if any(
                s == "upper_bound" for _, s in b
            ) else None
            if low is not None and low < 0.75 * min(resolved):
                bad.append(f"{name} B upper bound {low:.3g} below resolved {min(resolved):.3g}")
    assert not bad, "\n".join(bad)


# ---------------------------------------------------------------------------
# command line: grammar, option ranges, help, table
# ---------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("argv", "needle"),
    [
        (["--tau", "60"], "ambiguous"),
        (["--tau", "fortnightly"], "unknown tau grid"),
        (["--confidence", "1.5"], "between 0 and 1"),
        (["--k-sigma", "-1"], "must be > 0"),
        (["--avg-time", "0"], "must be > 0"),
        (["--ar-max-order", "0"], "at least 1"),
        (["--spike-threshold", "nan"], "finite"),
    ],
)
def test_bad_options_are_one_line_errors(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], argv: list[str], needle: str
) -> None:
    path = _write_csv(tmp_path / "ok.csv", _good_rows(2000))
    try:
        code = main(["static", str(path), "-o", str(tmp_path / "out"), "--quiet", *argv])
    except SystemExit as exc:  # argparse refuses the value while parsing
        code = int(exc.code or 0)
    assert code == 2
    err = capsys.readouterr().err
    # argparse prints its usage first; the cause is one line, the last
    last = err.strip().splitlines()[-1]
    assert needle in last and "error" in last, err
    assert not (tmp_path / "out" / "noise.json").exists()


def test_help_is_clean() -> None:
    proc = run_cli("static", "--help")
    assert proc.returncode == 0
    assert "%%" not in proc.stdout
    for needle in ("points:K", "1,10,100s", "--ar-max-order", "--robust"):
        assert needle in proc.stdout, needle


def test_terminal_table_columns_are_separated(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = _write_csv(tmp_path / "ok.csv", _good_rows(8000))
    code = main(["static", str(path), "-o", str(tmp_path / "out"), "--no-plot", "--no-report",
                 "--models", "none"])  # fmt: skip
    assert code == 0
    out = capsys.readouterr().out
    rows = [ln for ln in out.splitlines() if ln.startswith(("gyro", "accel"))]
    # the answer: a header and a row per sensor kind, N B K in datasheet and SI units;
    # then the IEEE 952 units with sigma_min and the bounds
    assert len(rows) == 8, out
    for header, row, n in ((rows[0], rows[1], 7), (rows[2], rows[3], 7),
                           (rows[4], rows[5], 7), (rows[6], rows[7], 7)):  # fmt: skip
        cells_h = re.split(r"\s{2,}", header.strip())
        cells_r = re.split(r"\s{2,}", row.strip())
        assert len(cells_h) == len(cells_r) == n, (cells_h, cells_r)
        assert len(header) == len(row)
    assert "deg/s/sqrt(Hz)" in rows[0] and "rad/s^0.5" in rows[0]
    assert "ug/sqrt(Hz)" in rows[2] and "m/s^1.5" in rows[2]
    assert "deg/h^0.5" in rows[4]


def test_robust_needs_the_in_memory_path(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = _write_csv(tmp_path / "ok.csv", _good_rows(2000))
    code = main(["static", str(path), "-o", str(tmp_path / "out"), "--quiet", "--robust",
                 "--out-of-core"])  # fmt: skip
    assert code == 2
    err = capsys.readouterr().err
    assert "--robust" in err and len(err.strip().splitlines()) == 1
