"""``imubounds simulate`` and ``imubounds dynamic`` end to end."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import imubounds.cli as cli


@pytest.fixture()
def main(monkeypatch: pytest.MonkeyPatch):  # type: ignore[no-untyped-def]
    mods = tuple(dict.fromkeys((*cli.COMMAND_MODULES, "dynamic", "simulate")))
    monkeypatch.setattr(cli, "COMMAND_MODULES", mods)
    return cli.main


def _check_outputs(out: Path) -> dict:
    names = {p.name for p in out.iterdir()}
    for n in (
        "dynamic.json",
        "steps.csv",
        "intervals.png",
        "intervals.svg",
        "trajectory.png",
        "comparison.png",
    ):
        assert n in names
    assert not [n for n in names if n.startswith(".")]  # no temporary leftovers
    doc = json.loads((out / "dynamic.json").read_text())
    assert set(doc["modes"]) == {"paper", "full"}
    for s in doc["modes"].values():
        assert set(s["channels"]) == {"accel_x", "accel_y", "gyro_z"}
    steps = pd.read_csv(out / "steps.csv")
    assert len(steps) == doc["modes"]["full"]["n_steps"]
    return doc


def test_simulate_then_dynamic(main, tmp_path: Path, capsys: pytest.CaptureFixture) -> None:  # type: ignore[no-untyped-def]
    sim = tmp_path / "sim"
    assert (
        main(
            [
                "simulate",
                "-o",
                str(sim),
                "--seed",
                "5",
                "--duration",
                "200",
                "--distance",
                "2000",
                "--bounded",
                "--gps-cep",
                "0.5",
                # the per-step estimator: a 1 Hz IMU without bias, as before
                "--rate",
                "1",
                "--no-bias",
            ]
        )
        == 0
    )
    out = tmp_path / "out"
    assert main(["dynamic", str(sim), "-o", str(out), "--passes", "3"]) == 0
    doc = _check_outputs(out)
    full = doc["modes"]["full"]
    assert full["enclosure"]["position_box"] > 0.9
    assert full["channels"]["gyro_z"]["enclosure"]["aided"] == 1.0
    # the simulator's model-error bound is applied on request and reported by default
    assert "with_model_error" in doc
    assert doc["with_model_error"]["summary"]["enclosure"]["position_box"] == 1.0
    err = capsys.readouterr().err
    assert "truth inside position boxes" in err
    steps = pd.read_csv(out / "steps.csv")
    assert {"accel_x_aided_lo", "gyro_z_err_hi", "truth_east", "x_ins_lo"} <= set(steps.columns)


def test_dynamic_vn100(main, shared_data: Path, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    out = tmp_path / "vn"
    d = shared_data / "dynamic" / "vn100_bu353_circle"
    assert main(["dynamic", str(d), "-o", str(out), "-q", "--gps-box", "mean"]) == 0
    doc = _check_outputs(out)
    assert doc["input"]["layout"] == "vn100"
    assert any("mounted backwards" in w for w in doc["input"]["warnings"])
    # the two CSV files work too
    files = sorted(str(p) for p in d.glob("*.csv"))
    assert main(["dynamic", *files, "-o", str(tmp_path / "vn2"), "-q", "--no-plot"]) == 0


def test_dynamic_comma(main, shared_data: Path, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    out = tmp_path / "c"
    d = shared_data / "dynamic" / "comma2k19_example1"
    assert (
        main(
            [
                "dynamic",
                str(d),
                "-o",
                str(out),
                "-q",
                "--imu-spec",
                "accel_nd=0.02,accel_bs=0.5,gyro_nd=0.5,gyro_bs=1",
            ]
        )
        == 0
    )
    doc = _check_outputs(out)
    assert doc["modes"]["full"]["enclosure"]["position_box"] >= 0.95
    assert doc["imu_bounds"]["source"] == "--imu-spec"


def test_dynamic_static_json(main, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    sim = tmp_path / "sim"
    main(
        ["simulate", "-o", str(sim), "--duration", "100", "--distance", "1000", "-q", "--rate", "1"]
    )
    noise = {
        "channels": {
            ch: {"stationary": {"N": n, "B": b}}
            for ch, n, b in (
                ("accel_x", 0.004, 0.01),
                ("accel_y", 0.005, 0.01),
                ("gyro_z", 0.001, 0.0001),
            )
        }
    }
    nj = tmp_path / "noise.json"
    nj.write_text(json.dumps(noise))
    out = tmp_path / "o"
    assert main(["dynamic", str(sim), "--static", str(nj), "-o", str(out), "-q", "--no-plot"]) == 0
    doc = json.loads((out / "dynamic.json").read_text())
    hw = doc["imu_bounds"]["halfwidth_per_step"]
    assert hw["accel_y"] > hw["accel_x"]  # per-channel N from the static run
    assert doc["modes"]["full"]["channels"]["accel_y"]["stationary_level_95"] == pytest.approx(
        1.96 * 0.005 * 60 * np.sqrt(100 / 3600), rel=1e-6
    )


def test_bad_inputs(main, shared_data: Path, tmp_path: Path, capsys: pytest.CaptureFixture) -> None:  # type: ignore[no-untyped-def]
    # an unknown directory
    assert main(["dynamic", str(tmp_path), "-o", str(tmp_path / "o")]) == 2
    assert "not a known drive-log directory" in capsys.readouterr().err
    # GPS all missing
    vn = tmp_path / "vn"
    vn.mkdir()
    src = shared_data / "dynamic" / "vn100_bu353_circle"
    shutil.copy(src / "circle_data_0_imu.csv", vn / "a_imu.csv")
    g = pd.read_csv(src / "circle_data_0_gps.csv")
    g["latitude"] = np.nan
    g.to_csv(vn / "a_gps.csv", index=False)
    assert main(["dynamic", str(vn), "-o", str(tmp_path / "o")]) == 2
    assert "no usable GPS fix" in capsys.readouterr().err
    # bad options
    sim = tmp_path / "sim"
    main(
        ["simulate", "-o", str(sim), "--duration", "100", "--distance", "1000", "-q", "--rate", "1"]
    )
    assert main(["dynamic", str(sim), "-o", str(tmp_path / "o"), "--gps-box", "p=2"]) == 2
    assert "--gps-box" in capsys.readouterr().err
    assert main(["dynamic", str(sim), "-o", str(tmp_path / "o"), "--imu-spec", "x=1"]) == 2
    assert "--imu-spec" in capsys.readouterr().err
    assert main(["dynamic", str(sim), "-o", str(tmp_path / "o"), "--step", "0.2"]) == 2
    assert "longer --step" in capsys.readouterr().err
    assert main(["dynamic", str(src), "-o", str(tmp_path / "o"), "--model-error"]) == 2
    assert "simulator directory" in capsys.readouterr().err
