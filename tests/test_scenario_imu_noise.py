"""``imubounds simulate --imu-noise NOISE_JSON`` / ``simulate_trip(imu_noise=...)``: a trip
whose IMU has the noise ``imubounds static`` measured, per axis (issue 26 item 3)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import yaml

import imubounds as ib
from imubounds.cli import main
from imubounds.dynamic.scenario import write_scenario
from imubounds.dynamic.scenario.imu import CHANNELS
from imubounds.io import bundled_static_log
from imubounds.io.outputs import to_jsonable
from imubounds.stationary.allan import allan
from imubounds.stationary.noise_sim import NoiseSpec

SHORT = {"duration_s": 400.0, "distance_m": 4000.0}


@pytest.fixture(scope="module")
def noise_json(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The bundled ADIS16405 log characterised (terms only: about a second)."""
    doc = ib.characterize(bundled_static_log(), models=()).to_dict()
    p = tmp_path_factory.mktemp("static") / "noise.json"
    p.write_text(json.dumps(to_jsonable(doc), allow_nan=False))
    return p


def test_trip_imu_error_has_the_allan_deviation_of_the_noise_json(noise_json: Path) -> None:
    doc = json.loads(noise_json.read_text())
    spec = NoiseSpec.from_noise_json(noise_json)  # the model simulate-noise --from-noise uses
    res = ib.simulate_trip("paper", seed=0, imu_noise=noise_json, **SHORT)
    fig = res.imu_errors.figures
    err = res.imu_errors.white + res.imu_errors.drift  # the truth the simulator stores
    n_checks = 0
    for j, ch in enumerate(CHANNELS):
        c = doc["channels"][ch]
        assert fig.axes[ch].N == pytest.approx(c["noise"]["fit"]["N"]["value"], rel=1e-12)
        assert fig.axes[ch].B == pytest.approx(c["noise"]["fit"]["B"]["value"], rel=1e-12)
        cur = c["allan"]
        tau = np.asarray(cur["tau_s"])
        idx = [int(np.argmin(np.abs(np.log(tau / t)))) for t in (0.16, 1.28, 10.24)]
        sim = allan(err[:, j], 100.0, taus=list(tau[idx]), confidence=0.999)
        model = spec.channels[ch].adev(tau[idx], 100.0)
        # the fit's five terms follow the curve up to its stated relative misfit
        mis = c["record_length"]["misfit_rel"]
        for k, i in enumerate(idx):
            assert sim.tau[k] == pytest.approx(tau[i])
            # the simulated IMU realises the noise.json's model ...
            assert sim.ci_lower[k] <= model[k] <= sim.ci_upper[k], (ch, tau[i])
            # ... and so the measured curve: the intervals meet
            lo = max(sim.ci_lower[k], cur["ci_lower"][i] * (1 - mis))
            hi = min(sim.ci_upper[k], cur["ci_upper"][i] * (1 + mis))
            assert lo <= hi, (ch, tau[i], sim.dev[k], cur["adev"][i])
            n_checks += 1
    assert n_checks == 18
    # the per-axis figures differ: the trip is not one figure per sensor kind
    assert len({fig.axes[ch].N for ch in CHANNELS[3:]}) == 3


def test_upper_bound_terms_are_named_and_the_layout_names_the_noise(
    noise_json: Path, tmp_path: Path
) -> None:
    doc = json.loads(noise_json.read_text())
    res = ib.simulate_trip("paper", seed=1, imu_noise=str(noise_json), **SHORT)
    fig = res.imu_errors.figures
    upper = [
        (ch, t)
        for ch in CHANNELS
        for t in ("Q", "N", "B", "K", "R")
        if doc["channels"][ch]["noise"]["selected"][t]["status"] == "upper_bound"
    ]
    assert upper  # the bundled log leaves some terms unresolved
    for ch, t in upper:
        fit = doc["channels"][ch]["noise"]["fit"][t]["value"] or 0.0
        assert getattr(fig.axes[ch], t) == pytest.approx(fit)  # the fit's value, or none
        assert any(n.startswith(f"{ch} {t}: ") and "upper bound" in n for n in fig.notes)
    out = write_scenario(res, tmp_path / "trip")
    drive = yaml.safe_load((out / "drive.yaml").read_text())
    assert drive["imu"]["noise_json"] == "imu_noise.json"
    assert "gyro_nd" not in drive["imu"]  # the noise.json gives each axis its figures
    assert (out / "imu_noise.json").read_bytes() == noise_json.read_bytes()
    scen = json.loads((out / "scenario.json").read_text())
    assert scen["config"]["imu_noise"] == str(noise_json)
    assert scen["true_values"]["imu"]["notes"] == list(fig.notes)
    back = ib.read_drive(out)
    assert Path(back.settings.imu.noise_json).name == "imu_noise.json"
    # the IMU's errors lie within the bounds drive.yaml states for them (risk 1 % each)
    assert [c.name for c in res.record.checks if c.name.startswith("imu.") and c.count] == []


def test_cli_imu_noise(
    noise_json: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "sim"
    argv = ["simulate", "--imu-noise", str(noise_json), "--duration", "200", "--distance",
            "2000", "-o", str(out), "-q"]  # fmt: skip
    assert main(argv) == 0
    assert yaml.safe_load((out / "drive.yaml").read_text())["imu"]["noise_json"] == (
        "imu_noise.json"
    )
    assert main([*argv[:-3], "-o", str(tmp_path / "b"), "--imu-preset", "mtx"]) == 2
    assert "--imu-preset or --imu-noise, not both" in capsys.readouterr().err
    bad = tmp_path / "bad.json"
    bad.write_text("{}")
    assert main(["simulate", "--imu-noise", str(bad), "-o", str(tmp_path / "c")]) == 2
    assert str(bad) in capsys.readouterr().err
