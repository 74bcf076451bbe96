"""The filter exports rebuild from a known noise.json with the conversions written out.

The noise.json below is made by hand (known N, K, B per axis, one K unresolved), so
each exported number is checked against its definition: continuous-time densities
for Kalibr/OpenVINS/GTSAM, per-sample figures for VINS and ROS (sqrt of the rate).
Here each file is loaded with yaml.safe_load; tests/test_export_parsers.py reads them with
the consumers' own parsers (OpenCV FileStorage, GTSAM, rosbags) and propagates the
consumers' covariances.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import pytest
import yaml

import imubounds as ib
from imubounds.cli import main
from imubounds.errors import InputError, OptionError
from imubounds.export import FORMATS

RATE = 200.0  # Hz

# per axis: N (rad/s^0.5 | m/s^1.5), K (rad/s^1.5 | m/s^2.5), B (rad/s | m/s^2)
TRUE = {
    "gyro_x": (1.0e-4, 2.0e-6, 3.0e-5, "resolved"),
    "gyro_y": (3.0e-4, 1.0e-6, 2.0e-5, "resolved"),
    "gyro_z": (2.0e-4, 5.0e-6, 1.0e-5, "upper_bound"),  # K not resolved: its upper bound
    "accel_x": (2.0e-3, 4.0e-5, 1.0e-3, "resolved"),
    "accel_y": (1.0e-3, 9.0e-5, 2.0e-3, "resolved"),
    "accel_z": (4.0e-3, 3.0e-5, 3.0e-3, "resolved"),
}


def _term(value: float, unit: str, status: str = "resolved") -> dict[str, Any]:
    return {"value": value, "unit": unit, "status": status, "from": "fit", "ci": [value, value]}


def known_noise() -> dict[str, Any]:
    chans = {}
    for ch, (n, k, b, k_status) in TRUE.items():
        u = "rad/s" if ch.startswith("gyro") else "m/s^2"
        chans[ch] = {
            "unit": u,
            "noise": {
                "selected": {
                    "N": _term(n, f"{u}^0.5"),
                    "K": _term(k, "x", k_status),
                    "B": _term(b, u),
                }
            },
        }
    return {
        "format": "imubounds.stationary.terms/1",
        "input": {"path": "known.csv", "sample_rate_hz": RATE},
        "channels": chans,
    }


def explained(text: str, key: str) -> str:
    """The comment lines just before ``key`` (its unit and conversion) and the key's line."""
    lines = text.splitlines()
    i = next(j for j, ln in enumerate(lines) if ln.strip().startswith(f"{key}:"))
    j = i
    while j > 0 and lines[j - 1].strip().startswith("#"):
        j -= 1
    return "\n".join(lines[j : i + 1])


def test_no_comment_inside_a_value() -> None:
    """Comments on their own lines: OpenCV reads an unquoted text value to the end of its
    line (a comment beside 'rostopic: /imu0' became part of the topic)."""
    for fmt in FORMATS:
        for motion in (None, {"format": "imubounds.motion/1", "channels": {"gyro_y": {"F": 2.0}}}):
            text = ib.export_noise(known_noise(), fmt, motion=motion)
            for ln in text.splitlines():
                if not ln.strip().startswith("#"):
                    assert "#" not in ln, (fmt, ln)


def _kind(kind: str, i: int) -> list[float]:
    return [TRUE[f"{kind}_{a}"][i] for a in "xyz"]


def test_kalibr_and_openvins_are_continuous_time_densities_of_the_worst_axis() -> None:
    doc = known_noise()
    kal = yaml.safe_load(ib.export_noise(doc, "kalibr"))
    # continuous time: sigma = N, sigma_b = K, no rate factor; one value: the largest axis
    assert kal["gyroscope_noise_density"] == pytest.approx(max(_kind("gyro", 0)), rel=1e-6)
    assert kal["gyroscope_random_walk"] == pytest.approx(max(_kind("gyro", 1)), rel=1e-6)
    assert kal["accelerometer_noise_density"] == pytest.approx(max(_kind("accel", 0)), rel=1e-6)
    assert kal["accelerometer_random_walk"] == pytest.approx(max(_kind("accel", 1)), rel=1e-6)
    assert kal["update_rate"] == RATE
    ov = yaml.safe_load(ib.export_noise(doc, "openvins"))["imu0"]
    keys = ("gyroscope_noise_density", "gyroscope_random_walk",
            "accelerometer_noise_density", "accelerometer_random_walk", "update_rate")
    for key in keys:
        assert ov[key] == kal[key], key
    assert ov["model"] == "kalibr"


def test_the_unresolved_random_walk_is_its_upper_bound_flagged() -> None:
    text = ib.export_noise(known_noise(), "kalibr")
    line = explained(text, "gyroscope_random_walk")
    assert "gyro_z" in line and "UPPER BOUND" in line
    # discrete form written beside it: sigma_bd = sigma_b / sqrt(f)
    assert f"{5.0e-6 / math.sqrt(RATE):.6e}" in line
    # B is not exported as a parameter, only named in a comment
    assert "bias instability" in text and "B gyro_x" in text


def test_vins_is_per_sample_sigma_with_its_mid_point_factor() -> None:
    v = yaml.safe_load(ib.export_noise(known_noise(), "vins"))
    sq = math.sqrt(RATE)  # acc_n = sqrt(2) N sqrt(f) (its mid-point rule); acc_w = K sqrt(f)
    assert v["acc_n"] == pytest.approx(math.sqrt(2) * 4.0e-3 * sq, rel=1e-6)
    assert v["gyr_n"] == pytest.approx(math.sqrt(2) * 3.0e-4 * sq, rel=1e-6)
    assert v["acc_w"] == pytest.approx(9.0e-5 * sq, rel=1e-6)
    assert v["gyr_w"] == pytest.approx(5.0e-6 * sq, rel=1e-6)


def test_gtsam_is_continuous_covariance_per_axis() -> None:
    g = yaml.safe_load(ib.export_noise(known_noise(), "gtsam"))
    spec = (("accelerometerCovariance", "accel", 0), ("gyroscopeCovariance", "gyro", 0),
            ("biasAccCovariance", "accel", 1), ("biasOmegaCovariance", "gyro", 1))
    for key, kind, i in spec:
        m = g[key]
        want = [v**2 for v in _kind(kind, i)]  # (units/sqrt(Hz))^2, no rate factor
        for r in range(3):
            for c in range(3):
                assert m[r][c] == pytest.approx(want[r] if r == c else 0.0, rel=1e-6), (key, r, c)


def test_ros_is_per_sample_variance_at_the_log_rate() -> None:
    imu = yaml.safe_load(ib.export_noise(known_noise(), "ros"))["imu"]
    for key, kind in (("angular_velocity_covariance", "gyro"),
                      ("linear_acceleration_covariance", "accel")):  # fmt: skip
        cov = imu[key]
        assert len(cov) == 9
        want = [n**2 * RATE for n in _kind(kind, 0)]  # sigma_d^2 = (N sqrt(f))^2
        assert [cov[0], cov[4], cov[8]] == pytest.approx(want, rel=1e-6)
        assert [cov[i] for i in (1, 2, 3, 5, 6, 7)] == [0.0] * 6
    assert imu["orientation_covariance"][0] == -1.0


def test_motion_factor_multiplies_n_and_k() -> None:
    motion = {"format": "imubounds.motion/1",
              "channels": {"gyro_y": {"F": 3.0}, "accel_z": {"F": None}}}  # fmt: skip
    kal = yaml.safe_load(ib.export_noise(known_noise(), "kalibr", motion=motion))
    assert kal["gyroscope_noise_density"] == pytest.approx(3.0 * 3.0e-4, rel=1e-6)
    text = ib.export_noise(known_noise(), "kalibr", motion=motion)
    assert "IN MOTION" in text and "accel_z: the trip did not resolve" in text
    # the worst axis has no in-motion factor: its line says so (it is no in-motion bound)
    unanalysed = {"format": "imubounds.motion/1", "channels": {"gyro_x": {"F": 2.0}}}
    text = ib.export_noise(known_noise(), "kalibr", motion=unanalysed)
    line = explained(text, "gyroscope_noise_density")
    assert "of axis gyro_y" in line and "NO FACTOR for gyro_y" in line, line
    # in-motion figures of another noise model are refused, naming the channel
    other = {"format": "imubounds.motion/1",
             "channels": {"gyro_y": {"F": 3.0, "N_static": 1.0e-3}}}  # fmt: skip
    with pytest.raises(InputError, match="gyro_y: its in-motion figures were computed"):
        ib.export_noise(known_noise(), "kalibr", motion=other)
    same = {"format": "imubounds.motion/1",
            "channels": {"gyro_y": {"F": 3.0, "N_static": 3.0e-4}}}  # fmt: skip
    assert "IN MOTION" in ib.export_noise(known_noise(), "kalibr", motion=same)


def test_cli_export_writes_the_file_and_a_summary(tmp_path: Path, capsys: Any) -> None:
    nj = tmp_path / "noise.json"
    nj.write_text(json.dumps(known_noise()), encoding="utf-8")
    out = tmp_path / "imu.yaml"
    assert main(["export", str(tmp_path), "--format", "kalibr", "-o", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "wrote" in printed
    # the values it wrote, each with its unit
    assert "gyroscope_noise_density: 3.000000e-04  [rad/s/sqrt(Hz)]" in printed
    assert "update_rate: 200  [Hz]" in printed
    assert yaml.safe_load(out.read_text())["update_rate"] == RATE
    assert main(["export", str(nj), "--format", "bogus"]) == 2
    assert main(["export", str(tmp_path / "nothing"), "--format", "ros"]) == 2
    assert "not found" in capsys.readouterr().err


def test_errors_name_the_problem() -> None:
    with pytest.raises(OptionError, match="unknown export format"):
        ib.export_noise(known_noise(), "rovio")  # type: ignore[arg-type]
    doc = known_noise()
    for a in "xyz":
        doc["channels"][f"gyro_{a}"]["noise"]["selected"]["N"]["value"] = None
    with pytest.raises(InputError, match="gyroscope_noise_density"):
        ib.export_noise(doc, "kalibr")


def test_report_marks_in_motion_figures_without_a_factor() -> None:
    """The report's filter table: an in-motion figure that is the stationary one (the worst
    axis was not analysed in motion) is marked, one with a factor is not."""
    from imubounds.report.html import _filter_block

    motion = {"format": "imubounds.motion/1", "channels": {"gyro_x": {"F": 2.0}}}
    rows = {r.split("</td>")[0].split(">")[-1]: r
            for r in _filter_block(known_noise(), motion).split("<tr>")[2:]}  # fmt: skip
    assert "no in-motion factor" in rows["gyroscope_noise_density"]
    motion = {"format": "imubounds.motion/1", "channels": {"gyro_y": {"F": 2.0}}}
    rows = {r.split("</td>")[0].split(">")[-1]: r
            for r in _filter_block(known_noise(), motion).split("<tr>")[2:]}  # fmt: skip
    assert "no in-motion factor" not in rows["gyroscope_noise_density"]
