"""The paper-scenario simulator."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from imubounds.dynamic.aiding.gps import cep_to_drms
from imubounds.dynamic.scenario import (
    ScenarioConfig,
    closure_error,
    imu_halfwidths,
    model_error_bounds,
    simulate,
    write_scenario,
)
from imubounds.errors import OptionError
from imubounds.frames import model_to_compass, wrap_pi
from imubounds.units import DEG


def test_paper_trip_geometry() -> None:
    sc = simulate(ScenarioConfig())
    tr = sc.truth
    assert sc.t.size == 793 and sc.t[-1] == 792.0  # 792 s at 1 Hz
    path = np.sum(np.hypot(np.diff(tr["east"]), np.diff(tr["north"])))
    assert path == pytest.approx(9400.0, rel=2e-3)
    assert closure_error(sc) < 1e-3  # a closed trip
    assert np.mean(tr["u"]) * 3.6 < 50.0  # mean speed under 50 km/h
    assert tr["u"][0] == 0.0 and tr["u"][-1] == pytest.approx(0.0, abs=1e-9)
    # one full turn of heading
    assert tr["psi"][-1] - tr["psi"][0] == pytest.approx(2 * math.pi, abs=1e-9)
    assert np.mean(sc.hdop) == pytest.approx(0.8, abs=0.05)


def test_seeded_and_reproducible() -> None:
    a = simulate(ScenarioConfig(seed=7))
    b = simulate(ScenarioConfig(seed=7))
    c = simulate(ScenarioConfig(seed=8))
    np.testing.assert_array_equal(a.accel, b.accel)
    np.testing.assert_array_equal(a.gps_east, b.gps_east)
    assert not np.array_equal(a.accel, c.accel)


def test_step_averages_are_exact() -> None:
    sc = simulate(ScenarioConfig(truth_model="continuous"))
    tr = sc.truth
    # mean of u' over (t_{k-1}, t_k] is the velocity difference; mean r the heading difference
    np.testing.assert_allclose(tr["accel_x"][1:], np.diff(tr["u"]), atol=1e-12)
    np.testing.assert_allclose(tr["r"][1:], np.diff(tr["psi"]), atol=1e-12)
    # lateral specific force r*u peaks at v^2/R_min, R_min = L/pi for a corner of length L
    v = tr["u"].max()
    assert tr["accel_y"].max() == pytest.approx(v * v / (150.0 / math.pi), rel=0.1)


def test_bounded_noise_inside_bounds() -> None:
    sc = simulate(ScenarioConfig(bounded=True, seed=11))
    half = imu_halfwidths("mtx", 1.0, 792.0, 3.0)
    assert np.all(np.abs(sc.accel[:, 0] - sc.truth["accel_x"]) <= half["accel_x"])
    assert np.all(np.abs(sc.gyro[:, 2] - sc.truth["r"]) <= half["gyro_z"])
    drms = sc.hdop * cep_to_drms(3.0)
    bnd = drms * math.sqrt(-math.log(1e-3))
    assert np.all(np.abs(sc.gps_east - sc.truth["east"]) <= bnd)
    assert np.all(np.abs(sc.gps_north - sc.truth["north"]) <= bnd)


def test_compass_deviation_applied() -> None:
    sc = simulate(ScenarioConfig(compass_noise_deg=0.0))
    true_c = model_to_compass(sc.truth["psi"])
    err = np.asarray(wrap_pi(sc.compass - true_c))
    A, B, C = (x * DEG for x in (1.0, 2.5, -1.5))
    np.testing.assert_allclose(err, A + B * np.sin(sc.compass) + C * np.cos(sc.compass), atol=1e-9)


def test_discrete_truth_follows_model() -> None:
    for mode in ("paper", "full"):
        sc = simulate(ScenarioConfig(truth_model=mode))
        me = model_error_bounds(sc.truth, 1.0)
        if mode == "full":
            assert me["nav_accel_bound"] < 1e-9 and me["jerk_bound"] < 1e-9
    cont = simulate(ScenarioConfig()).truth
    assert model_error_bounds(cont, 1.0)["nav_accel_bound"] > 1.0


def test_outliers_and_options() -> None:
    sc = simulate(ScenarioConfig(gps_outlier_fraction=0.05, seed=1))
    assert 10 < sc.gps_outlier.sum() < 80
    d = np.hypot(sc.gps_east - sc.truth["east"], sc.gps_north - sc.truth["north"])
    assert np.all(d[sc.gps_outlier] > 20)
    sc10 = simulate(ScenarioConfig(rate_hz=10.0, duration_s=100.0, distance_m=1000.0))
    assert sc10.t.size == 1001 and sc10.gps_t.size == 101
    with pytest.raises(OptionError):
        simulate(ScenarioConfig(truth_model="paper", rate_hz=10.0))
    with pytest.raises(OptionError):
        simulate(ScenarioConfig(duration_s=30.0))


def test_write_directory(tmp_path: Path) -> None:
    sc = simulate(ScenarioConfig(duration_s=100.0, distance_m=1000.0))
    out = write_scenario(sc, tmp_path / "run")
    names = {p.name for p in out.iterdir()}
    assert names == {
        "imu.csv",
        "gps.csv",
        "compass.csv",
        "compass_cal.csv",
        "truth.csv",
        "scenario.json",
    }
    meta = json.loads((out / "scenario.json").read_text())
    assert meta["config"]["seed"] == 0 and "estimator" in meta
    # rewriting replaces the directory atomically, leaving no temporary siblings
    write_scenario(sc, out)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run"]
