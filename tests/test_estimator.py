"""The interval estimator: compiled loop vs reference, soundness, model error, modes."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from imubounds.dynamic.estimator import config_for_log, prepare_steps, run, scenario_model_error
from imubounds.dynamic.estimator.kernel import F_GPS_EMPTY, F_GPS_MISSING
from imubounds.dynamic.estimator.reference import run_reference
from imubounds.dynamic.scenario import ScenarioConfig, simulate, write_scenario
from imubounds.errors import AnalysisError
from imubounds.io.drive_legacy import DriveLog
from imubounds.io.drive_legacy import read_drive_log as read_drive
from imubounds.stationary import bounds

# the per-step estimator's tests: a 1 Hz IMU without turn-on bias, and without bias drift
# when the draws are bounded, at a constant speed in the corners, as before
LEGACY = {"rate_hz": 1.0, "turn_on_scale": 0.0, "max_lateral_accel_mps2": 100.0}


def legacy_config(**kw: object) -> ScenarioConfig:
    imu_bias = {"imu_bias": False} if kw.get("bounded") else {}
    return ScenarioConfig(**{**LEGACY, **imu_bias, **kw})  # type: ignore[arg-type]


def sim_log(tmp: Path, **kw: object) -> DriveLog:
    cfg = legacy_config(**kw)
    d = tmp / f"s{abs(hash(tuple(sorted(kw.items())))) % 10**8}"
    write_scenario(simulate(cfg), d)
    return read_drive(str(d))


SHORT = {"duration_s": 200.0, "distance_m": 2000.0, "corner_length_m": 80.0}


def _all_enclosed(s: dict) -> bool:
    enc = s["enclosure"]
    ok = all(enc[k] == 1.0 for k in ("position_box", "heading", "u", "v"))
    for ch in s["channels"].values():
        ok &= ch["enclosure"]["aided"] == 1.0 and ch["enclosure"]["estimate"] == 1.0
    return bool(ok)


# ------------------------------------------------------------------ the paper's numbers


def test_paper_worked_numbers() -> None:
    assert bounds.level_95(0.108, 0.22) == pytest.approx(0.099, abs=5e-4)
    assert bounds.level_95(0.12, 0.22) == pytest.approx(0.11, abs=5e-4)
    assert bounds.level_95(6.0, 0.22) == pytest.approx(5.52, abs=5e-3)
    # the MTx accelerometer density 0.002 m/s^2/sqrt(Hz) is RW 0.12 (m/s)/sqrt(h):
    assert bounds.level_95_si(0.002, 0.22 * 3600) == pytest.approx(0.11, abs=5e-4)


# ------------------------------------------------------------- compiled == reference


@pytest.mark.parametrize("mode", ["paper", "full"])
@pytest.mark.parametrize("veldiff", ["contracted", "ins"])
@pytest.mark.parametrize("fallback", ["keep", "reset"])
def test_kernel_equals_reference(tmp_path: Path, mode: str, veldiff: str, fallback: str) -> None:
    log = sim_log(tmp_path, seed=5, gps_outlier_fraction=0.05, **SHORT)
    cfg = config_for_log(
        log, mode=mode, veldiff=veldiff, fallback=fallback, nav_accel_bound=0.5, jerk_bound=0.01
    )
    steps = prepare_steps(log, cfg)
    steps.gps[50:53] = np.nan  # a GPS dropout
    steps.heading[80] = np.nan  # a compass dropout
    res = run(steps, cfg)
    dt = steps.dt
    S, D, A, flags = run_reference(
        res.S[0],
        res.M,
        steps.gps,
        steps.heading,
        dt,
        0.5 * 0.5 * dt * dt,
        0.01 * dt * dt,
        mode,
        veldiff,
        fallback,
    )
    np.testing.assert_array_equal(S, res.S)
    np.testing.assert_array_equal(D[1:], res.D[1:])
    np.testing.assert_array_equal(A[1:], res.A[1:])
    np.testing.assert_array_equal(flags, res.flags)
    assert np.all(res.flags[50:53] & F_GPS_MISSING)
    assert np.count_nonzero(res.flags & F_GPS_EMPTY) > 0  # the outliers are caught


# ------------------------------------------------------------------------- soundness


def _soundness(tmp_path: Path, seeds: range, duration: float, passes: int) -> list[str]:
    failures = []
    for seed in seeds:
        for mode in ("paper", "full"):
            kw = dict(seed=seed, truth_model=mode, bounded=True)
            if duration < 792:
                kw.update(duration_s=duration, distance_m=duration * 10.0, corner_length_m=80.0)
            cfg_s = legacy_config(**kw)
            d = tmp_path / f"{mode}{seed}"
            write_scenario(simulate(cfg_s), d)
            log = read_drive(str(d))
            res = run(log, config_for_log(log, mode=mode, passes=passes, window=8))
            s = res.summary
            n_empty = sum(v["count"] for v in s["flags"].values())
            if not _all_enclosed(s) or n_empty:
                failures.append(f"seed {seed} mode {mode}: {s['enclosure']} flags {n_empty}")
    return failures


def test_soundness_few_seeds(tmp_path: Path) -> None:
    assert _soundness(tmp_path, range(6), 150.0, 1) == []
    assert _soundness(tmp_path, range(100, 103), 150.0, 4) == []


@pytest.mark.slow
def test_soundness_200_seeds(tmp_path: Path) -> None:
    """>= 200 seeds x both modes over the full 792 s paper trip, single pass;
    plus 20 seeds with Waltz sweeps over a window."""
    assert _soundness(tmp_path, range(200), 792.0, 1) == []
    assert _soundness(tmp_path, range(1000, 1020), 792.0, 3) == []


@settings(max_examples=12, deadline=None)
@given(
    seed=st.integers(0, 10**6),
    cep=st.floats(0.3, 5.0),
    corner=st.floats(30.0, 200.0),
    mode=st.sampled_from(["paper", "full"]),
)
def test_soundness_property(
    tmp_path_factory: pytest.TempPathFactory, seed: int, cep: float, corner: float, mode: str
) -> None:
    cfg = legacy_config(
        seed=seed,
        truth_model=mode,
        bounded=True,
        duration_s=120.0,
        distance_m=1000.0,
        corner_length_m=corner,
        gps_cep_m=cep,
    )
    d = tmp_path_factory.mktemp("prop") / "s"
    write_scenario(simulate(cfg), d)
    log = read_drive(str(d))
    s = run(log, config_for_log(log, mode=mode)).summary
    assert _all_enclosed(s), s["enclosure"]


def test_waltz_only_contracts(tmp_path: Path) -> None:
    log = sim_log(tmp_path, seed=9, truth_model="full", bounded=True, **SHORT)
    one = run(log, config_for_log(log, mode="full"))
    many = run(log, config_for_log(log, mode="full", passes=6, window=10))
    assert many.sweeps > 0
    w1 = one.S[:, 1::2] - one.S[:, 0::2]
    w2 = many.S[:, 1::2] - many.S[:, 0::2]
    assert np.all(w2 <= w1 + 1e-9)
    assert np.sum(w2) < np.sum(w1)  # it does contract something
    assert _all_enclosed(many.summary)


# -------------------------------------------------------------------------- model error


def test_model_error_restores_enclosure(tmp_path: Path) -> None:
    """Continuous trajectory, precise GPS: the discretisation error is visible without the
    bound and gone with it (the rates are reported in dynamic.json the same way)."""
    log = sim_log(tmp_path, seed=2, bounded=True, gps_cep_m=0.3, compass_noise_deg=0.05)
    me = scenario_model_error(log)
    assert me["nav_accel_bound"] > 1.0  # the corners: ~ v^2 / R
    without = run(log, config_for_log(log, mode="full")).summary
    with_me = run(log, config_for_log(log, mode="full", **me)).summary
    assert without["enclosure"]["position_box"] < 1.0
    assert sum(v["count"] for v in without["flags"].values()) > 0
    assert _all_enclosed(with_me)
    assert sum(v["count"] for v in with_me["flags"].values()) == 0


# ------------------------------------------------------------------------- paper vs full


def test_paper_vs_full_on_turns(tmp_path: Path) -> None:
    """The truth turns with the full kinematics: the printed model treats the centripetal
    specific force r*u as v' and loses the lateral velocity; the full model does not."""
    log = sim_log(tmp_path, seed=1, truth_model="full", bounded=True)
    paper = run(log, config_for_log(log, mode="paper")).summary
    full = run(log, config_for_log(log, mode="full")).summary
    assert _all_enclosed(full)
    assert paper["enclosure"]["v"] < 0.5
    assert paper["flags"]["gps_empty"]["count"] > 100
    # on a straight-only stretch the two agree: the first 100 s have no corner
    # (corners start later), so the paper model's v stays enclosed there
    res = run(log, config_for_log(log, mode="paper"))
    tv = res.steps.truth["v"][:100]  # type: ignore[index]
    assert np.all((res.S[:100, 6] <= tv) & (tv <= res.S[:100, 7]))


# ------------------------------------------------------------------------ empty and bad


def test_outliers_counted_and_located(tmp_path: Path) -> None:
    log = sim_log(
        tmp_path, seed=3, gps_outlier_fraction=0.03, gps_outlier_m=60.0, bounded=True, **SHORT
    )
    rows = set(log.settings["gps_outlier_rows"])  # type: ignore[arg-type]
    assert len(rows) >= 2
    keep = run(log, config_for_log(log, fallback="keep")).summary
    g = keep["flags"]["gps_empty"]
    # keep the prediction: exactly the outlier fixes are flagged, located in time
    assert {round(t) for t in g["first_times_s"]} == rows
    assert keep["enclosure"]["position_box"] == 1.0
    assert keep["empty_rule"] == "keep the prediction"
    reset = run(log, config_for_log(log, fallback="reset"))
    # reset to the GPS box: every outlier is caught, but resetting onto an outlier box
    # also corrupts the next steps (more flags than outliers): 'keep' is the rule for outliers
    got = set(np.flatnonzero(reset.flags & F_GPS_EMPTY).tolist())
    assert rows <= got
    assert len(got) > len(rows)


def test_heading_wrap_north(tmp_path: Path) -> None:
    """Driving north with compass readings alternating 359.9 / 0.1 deg: no 2 pi blow-up."""
    n = 61
    t = np.arange(n, dtype=float)
    lat0 = 23.5
    north = 10.0 * t
    lat = lat0 + north / 111_000.0
    heading = np.radians(np.where(np.arange(n) % 2 == 0, 359.9, 0.1))
    log = DriveLog(
        imu_t=t,
        accel=np.zeros((n, 3)),
        gyro=np.zeros((n, 3)),
        gps_t=t,
        lat=lat,
        lon=np.full(n, 88.0),
        alt=np.zeros(n),
        hdop=np.full(n, 0.8),
        fix=np.ones(n, bool),
        heading_t=t,
        heading=heading,
    )
    log.validate()
    from imubounds.dynamic.aiding.compass import ZERO_DEVIATION

    cfg = config_for_log(log, deviation=ZERO_DEVIATION, initial_speed_bound=15.0)
    res = run(log, cfg)
    w = res.S[:, 9] - res.S[:, 8]
    assert np.all(w < math.radians(1.1))
    mid = 0.5 * (res.S[:, 8] + res.S[:, 9])
    assert np.all(np.abs(mid - math.pi / 2) < math.radians(1.0))
    assert res.summary["flags"]["heading_empty"]["count"] == 0


def test_step_shorter_than_imu_period(tmp_path: Path) -> None:
    log = sim_log(tmp_path, seed=0, **SHORT)
    with pytest.raises(AnalysisError, match="longer --step"):
        prepare_steps(log, config_for_log(log, step_s=0.5))


def test_longer_step_averages(tmp_path: Path) -> None:
    log = sim_log(tmp_path, seed=0, rate_hz=10.0, truth_model="continuous", bounded=True, **SHORT)
    cfg = config_for_log(log, step_s=1.0)
    steps = prepare_steps(log, cfg)
    assert steps.t.size == 201
    k = 57
    sel = (log.imu_t > steps.t[k - 1]) & (log.imu_t <= steps.t[k] + 1e-9)
    assert sel.sum() == 10
    assert steps.meas[k, 0] == pytest.approx(np.mean(log.accel[sel, 0]))
    # bound scaled to the 1 s average: N/sqrt(1 s) instead of N/sqrt(0.1 s)
    cfg10 = config_for_log(log, step_s=0.1)
    s10 = prepare_steps(log, cfg10)
    N, B = cfg.imu.accel["N"], cfg.imu.accel["B"]
    k = cfg.k_sigma
    assert steps.half[0] == pytest.approx(bounds.interval_halfwidth(N, B, 1.0, 200.0, k))
    assert s10.half[0] == pytest.approx(bounds.interval_halfwidth(N, B, 0.1, 200.0, k))
    res = run(steps, cfg)
    assert res.summary["enclosure"]["position_box"] == 1.0


def test_comma2k19_position_enclosure(shared_data: Path) -> None:
    """Ground truth inside the contracted boxes on comma2k19 (60 steps of 1 s).

    Threshold 0.95: the boxes are p = 0.999 GPS boxes (u-blox, CEP 3 m, HDOP 1 by
    default) intersected with the INS prediction; the measured share is 1.0 in
    full mode. The IMU bound (MTx datasheet) is far too tight for this phone IMU,
    so the velocity can be pushed off the truth by the accelerometer bias; 0.95
    leaves room for up to 3 such steps.
    """
    log = read_drive(str(shared_data / "dynamic" / "comma2k19_example1"))
    s = run(log, config_for_log(log, mode="full")).summary
    assert s["enclosure"]["steps"] == 60
    assert s["enclosure"]["position_box"] >= 0.95
    assert s["enclosure"]["gps_box"] >= 0.95


@settings(max_examples=60, deadline=None)
@given(
    st.lists(st.tuples(st.floats(-10, 10), st.floats(0, 5)), min_size=1, max_size=7),
    st.integers(0, 3),
)
def test_qrelaxed_1d_matches_brute_force(ivs: list[tuple[float, float]], q: int) -> None:
    from imubounds.dynamic.estimator.kernel import qrelaxed_1d

    lo = np.array([a for a, _ in ivs])
    hi = np.array([a + w for a, w in ivs])
    m = lo.size
    got = qrelaxed_1d(lo, hi, m, q)
    pts = np.concatenate([lo, hi])
    cover = np.array([np.sum((lo <= p) & (p <= hi)) for p in pts])
    ok = pts[cover >= m - q]
    if m - q <= 0:
        assert got == (-np.inf, np.inf)
    elif ok.size == 0:
        assert not (got[0] <= got[1])
    else:
        assert got == (ok.min(), ok.max())


def test_qrelax_rule_tolerates_outliers(tmp_path: Path) -> None:
    """GPS outliers with bounded noise otherwise: the q-relaxed rule (q = 1 over a 10-step
    window) keeps the truth in the boxes at far more steps than 'keep' or 'reset'."""
    log = sim_log(tmp_path, seed=3, gps_outlier_fraction=0.03, gps_outlier_m=60.0, bounded=True)
    enc = {}
    for rule in ("keep", "reset", "qrelax"):
        s = run(log, config_for_log(log, fallback=rule)).summary
        enc[rule] = s["enclosure"]["position_box"]
        if rule == "qrelax":
            assert s["empty_rule"].startswith("q-relaxed")
    # With the 3-D simulator's draws (bounded at the whole-trip level, not 3 sigma) the
    # per-step rule no longer beats 'keep' reliably (seeds 0-5: 0.82-1.0 vs 0.86-1.0);
    # it still beats 'reset' clearly.
    assert enc["qrelax"] > 0.9
    assert enc["qrelax"] > enc["reset"] + 0.05


def test_bias_margin_widens_bounds_by_B_and_reduces_inconsistency(tmp_path: Path) -> None:
    # The simulated MTx has a bias instability (1 deg/s gyro, 0.02 m/s^2 accel) far
    # above the paper's k*sigma_c: its bounds are violated and intersections go empty.
    log = sim_log(tmp_path, duration_s=300.0, distance_m=3500.0)
    base = config_for_log(log)
    wide = config_for_log(log, bias_margin=1.0)
    s0, s1 = prepare_steps(log, base), prepare_steps(log, wide)
    for i, ch in enumerate(("accel_x", "accel_y", "gyro_z")):
        assert s1.half[i] - s0.half[i] == pytest.approx(base.imu.coeffs(ch)["B"], rel=1e-12)
    r0, r1 = run(log, base), run(log, wide)

    def n_empty(res: object) -> int:
        s = res.summary  # type: ignore[attr-defined]
        return sum(v["count"] for k, v in s["flags"].items() if "empty" in k)

    assert n_empty(r1) < n_empty(r0)
