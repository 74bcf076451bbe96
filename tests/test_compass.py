"""Compass without GPS: hard/soft-iron ellipse calibration of the raw magnetometer, swing
calibration, the explicit GNSS-course fit, and the one function the estimator calls."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from imubounds.dynamic.sensors._compass import (
    UNCALIBRATED_DEVIATION_DEG,
    CompassHeading,
    compass_heading,
    harmonic_fit,
    k_sigma,
)
from imubounds.dynamic.sensors._magcal import fit_magnetometer
from imubounds.errors import AnalysisError, OptionError
from imubounds.frames import rpy_to_matrix, wrap_pi
from imubounds.io import Drive, read_drive
from imubounds.io.drive import (
    AttitudeStream,
    GnssStream,
    HeadingStream,
    ImuStream,
    MagStream,
)

SOFT = np.array([[1.12, 0.06, 0.02], [0.06, 0.91, -0.03], [0.02, -0.03, 1.0]])
HARD_UT = np.array([18.0, -9.0, 31.0])
H_UT, V_UT = 21.0, -44.0  # horizontal and vertical (up) field, northern hemisphere


def sim_mag(
    seed: int,
    *,
    turns: float = 2.0,
    tilt_deg: float = 3.0,
    noise_ut: float = 0.3,
    outliers: float = 0.0,
    n: int = 3000,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(t, true heading rad cw from north, roll, pitch, raw mag in uT (body FLU)): a vehicle
    turning ``turns`` times with a slowly varying tilt, hard and soft iron, Gaussian noise
    and a fraction of outliers (5 uT disturbances in random directions)."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 300.0, n)
    heading = np.mod(2 * math.pi * turns * t / t[-1] + 0.3 * np.sin(t / 17.0), 2 * math.pi)
    roll = np.radians(tilt_deg) * np.sin(t / 23.0 + 1.0)
    pitch = np.radians(tilt_deg) * np.sin(t / 31.0)
    field_enu = np.array([0.0, H_UT, V_UT])  # magnetic north = ENU north
    c_nb = rpy_to_matrix(roll, pitch, heading)
    body = np.einsum("nji,j->ni", c_nb, field_enu)
    raw = body @ SOFT.T + HARD_UT + noise_ut * rng.standard_normal((n, 3))
    k = rng.random(n) < outliers
    d = rng.standard_normal((int(k.sum()), 3))
    raw[k] += 5.0 * d / np.linalg.norm(d, axis=1, keepdims=True)
    return t, heading, roll, pitch, raw


def _drive(t: np.ndarray, roll: np.ndarray | None, pitch: np.ndarray | None,
           raw_ut: np.ndarray, heading: np.ndarray) -> Drive:
    """A drive with the magnetometer, the attitude, and a gyro z that turns with the
    heading (only used to check that the drive turns enough for a calibration)."""
    n = t.size
    gyro = np.zeros((n, 3))
    gyro[:, 2] = -np.gradient(np.unwrap(heading), t)
    d = Drive(imu=ImuStream(t=t, accel=np.zeros((n, 3)), gyro=gyro),
              mag=MagStream(t=t, mag=raw_ut * 1e-6, unit="T"))
    if roll is not None and pitch is not None:
        d.attitude = AttitudeStream(t=t, roll_rad=roll, pitch_rad=pitch)
    return d


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("tilt_deg", [0.0, 3.0, 15.0])
def test_ellipse_calibration_error_within_its_bound(seed: int, tilt_deg: float) -> None:
    """Simulated hard and soft iron (3-D, with couplings), tilt compensated with the
    attitude, Gaussian noise: every corrected heading lies within deviation_bound + k *
    noise_sigma (k for the drive's samples at alpha = 1 %), and the hard iron is found."""
    t, truth, roll, pitch, raw = sim_mag(seed, tilt_deg=tilt_deg)
    ch = compass_heading(_drive(t, roll, pitch, raw, truth))
    assert ch.calibration == "ellipse" and ch.source == "magnetometer"
    assert ch.independent_of_gnss and ch.independent_of_imu
    tr = np.interp(ch.t, t, np.unwrap(truth))
    err = np.degrees(np.abs(np.asarray(wrap_pi(ch.heading_rad - tr))))
    bound = math.degrees(ch.halfwidth_rad(k_sigma(0.01, t.size)))
    assert err.max() <= bound, f"max error {err.max():.3f} deg > bound {bound:.3f} deg"
    # noise-limited: 0.3 uT on a 21 uT horizontal field is 0.82 deg rms
    assert np.sqrt(np.mean(err**2)) < 1.0, np.sqrt(np.mean(err**2))
    assert bound < 5.0, bound
    detail = ch.detail["ellipse"]
    hard = np.asarray(detail["hard_iron"]) * 1e6
    if tilt_deg > 0:  # level, the soft iron's vertical coupling looks like hard iron
        assert np.allclose(hard[:2], HARD_UT[:2], atol=0.5), hard
        # the vertical hard iron shows only when the vehicle tilts
        assert hard[2] == pytest.approx(HARD_UT[2], abs=12.0 if tilt_deg < 5 else 2.0)
        assert detail["vertical_ratio"] == pytest.approx(V_UT / H_UT, rel=0.05)


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_outliers_break_only_their_own_samples(seed: int) -> None:
    """1 % outliers (5 uT, random directions): the calibration still holds, most outliers
    are seen (radial residual) and dropped, and every sample outside its bound is an
    injected outlier (a purely sideways disturbance cannot be seen in the field's size)."""
    t, truth, roll, pitch, raw = sim_mag(seed, outliers=0.01)
    clean_t, _, _, _, clean = sim_mag(seed, outliers=0.0)
    injected = np.any(raw != clean, axis=1)
    ch = compass_heading(_drive(t, roll, pitch, raw, truth))
    idx = np.searchsorted(t, ch.t)
    err = np.degrees(np.abs(np.asarray(wrap_pi(ch.heading_rad - truth[idx]))))
    bound = math.degrees(ch.halfwidth_rad(k_sigma(0.01, t.size)))
    outside = err > bound
    assert not np.any(outside & ~injected[idx]), "a clean sample is outside its bound"
    dropped = ch.detail["ellipse"]["disturbed_samples"]
    assert dropped >= 0.6 * injected.sum(), (dropped, int(injected.sum()))


def test_uncalibrated_heading_is_far_off_and_the_fit_brings_it_back() -> None:
    """Without the calibration the same samples are tens of degrees off (the test has teeth)."""
    from imubounds.dynamic.sensors._compass import heading_from_magnetometer

    t, truth, roll, pitch, raw = sim_mag(3)
    rawh = heading_from_magnetometer(raw[:, 0], raw[:, 1], "FLU")
    assert np.degrees(np.abs(np.asarray(wrap_pi(rawh - truth)))).max() > 30.0
    ch = compass_heading(_drive(t, roll, pitch, raw, truth))
    assert np.degrees(np.abs(np.asarray(wrap_pi(ch.heading_rad - truth)))).max() < 4.0


def test_level_vehicle_without_attitude() -> None:
    t, truth, roll, pitch, raw = sim_mag(4, tilt_deg=0.0)
    ch = compass_heading(_drive(t, None, None, raw, truth))
    tr = np.interp(ch.t, t, np.unwrap(truth))
    err = np.degrees(np.abs(np.asarray(wrap_pi(ch.heading_rad - tr))))
    assert err.max() <= math.degrees(ch.halfwidth_rad(k_sigma(0.01, t.size)))
    assert any("level" in n for n in ch.notes)


def test_large_tilts_of_a_tumbling_vehicle() -> None:
    """Tilts of +-40 deg (a drone, a boat in waves): the levelled fit still holds."""
    t, truth, roll, pitch, raw = sim_mag(5, tilt_deg=40.0)
    cal = fit_magnetometer(raw, roll, pitch)
    err = np.degrees(np.abs(np.asarray(wrap_pi(cal.heading(raw, roll, pitch) - truth))))
    assert err.max() < 4.0, err.max()
    assert np.allclose(cal.hard_iron, HARD_UT, atol=1.0), cal.hard_iron


def test_a_short_arc_is_refused() -> None:
    t, truth, roll, pitch, raw = sim_mag(6, turns=0.2)
    with pytest.raises(AnalysisError, match=r"turns through 7\d deg of heading only"):
        compass_heading(_drive(t, roll, pitch, raw, truth))


def test_vn100_raw_magnetometer_against_its_own_yaw(shared_data: Path) -> None:
    """The VN-100 drive: the ellipse-calibrated, tilt-compensated heading of the raw
    magnetometer against the unit's own VNYMR yaw. Apart from a constant offset (the
    alignment that no self-calibration sees, stated as an assumption: 7.1 deg here), every
    sample is within the bound the calibration reports."""
    d = read_drive(shared_data / "dynamic" / "vn100_bu353_circle")
    ch = compass_heading(d)
    assert ch.calibration == "ellipse" and ch.detail["ellipse"]["levelled"]
    assert any("alignment_deg = 0" in a for a in ch.assumed)
    a = d.attitude
    assert a is not None and a.yaw_rad is not None
    yaw = np.interp(ch.t, a.t, np.unwrap(a.yaw_rad))
    diff = np.degrees(np.asarray(wrap_pi(ch.heading_rad - yaw)))
    offset = float(np.median(diff))
    assert abs(offset) < 10.0, offset
    bound = math.degrees(ch.halfwidth_rad(k_sigma(0.01, ch.t.size)))
    worst = float(np.max(np.abs(diff - offset)))
    assert worst <= bound, f"worst {worst:.2f} deg > bound {bound:.2f} deg"
    assert bound < 15.0, bound  # informative, not a blanket


def _heading_drive(t: np.ndarray, measured: np.ndarray, true_north: bool = False) -> Drive:
    n = t.size
    return Drive(imu=ImuStream(t=t, accel=np.zeros((n, 3)), gyro=np.zeros((n, 3))),
                 heading=HeadingStream(t=t, heading_rad=measured, true_north=true_north))


def test_swing_calibration_of_a_compass(tmp_path: Path) -> None:
    rng = np.random.default_rng(7)
    dev = (math.radians(2.0), math.radians(4.0), math.radians(-3.0))

    def err(h: np.ndarray) -> np.ndarray:
        return dev[0] + dev[1] * np.sin(h) + dev[2] * np.cos(h)

    ref = np.radians(np.arange(0.0, 360.0, 15.0))
    meas = ref + err(ref)  # first order: the deviation at the measured heading
    for _ in range(3):
        meas = ref + err(meas)
    cal = tmp_path / "swing.csv"
    cal.write_text("measured_deg,reference_deg\n" + "".join(
        f"{math.degrees(m) % 360:.4f},{math.degrees(r):.4f}\n" for m, r in zip(meas, ref,
                                                                               strict=True)))
    t = np.arange(0.0, 100.0, 0.1)
    truth = np.mod(0.05 * t, 2 * math.pi)
    m = truth.copy()
    for _ in range(4):
        m = truth + err(m)
    m = np.mod(m + np.radians(0.5) * rng.standard_normal(t.size), 2 * math.pi)
    ch = compass_heading(_heading_drive(t, m), calibration=cal)
    assert ch.calibration == "swing" and ch.independent_of_gnss
    e = np.degrees(np.abs(np.asarray(wrap_pi(ch.heading_rad - truth))))
    assert e.max() <= math.degrees(ch.halfwidth_rad(k_sigma(0.01, t.size)))
    raw_e = np.degrees(np.abs(np.asarray(wrap_pi(m - truth))))
    assert raw_e.max() > 6.0 and e.max() < 2.5


def test_gnss_course_fit_is_explicit_and_says_it_is_not_independent() -> None:
    t = np.arange(0.0, 200.0, 1.0)
    truth = np.mod(0.04 * t, 2 * math.pi)
    meas = np.mod(truth + math.radians(5.0) + math.radians(3.0) * np.sin(truth), 2 * math.pi)
    d = _heading_drive(t, meas)
    lat = 45.0 + 0.001 * np.cos(0.04 * t)
    d.gnss = GnssStream(t=t, lat_deg=lat, lon_deg=np.full(t.size, 7.0), speed_mps=np.full(
        t.size, 8.0), course_rad=truth)
    auto = compass_heading(d)
    assert auto.calibration == "none" and auto.independent_of_gnss
    assert auto.deviation_bound_rad == pytest.approx(math.radians(UNCALIBRATED_DEVIATION_DEG))
    assert any("uncalibrated heading" in a for a in auto.assumed)
    fitted = compass_heading(d, fit="gnss-course")
    assert not fitted.independent_of_gnss and fitted.calibration == "gnss-course"
    assert any("NOT independent of the GNSS" in n for n in fitted.notes)
    e = np.degrees(np.abs(np.asarray(wrap_pi(fitted.heading_rad - truth))))
    assert e.max() < 0.5


def test_declination_goes_to_magnetic_headings_only() -> None:
    t = np.arange(0.0, 10.0, 1.0)
    h = np.full(t.size, math.radians(100.0))
    mag = compass_heading(_heading_drive(t, h), declination_deg=-14.0, deviation_deg=2.0)
    true = compass_heading(_heading_drive(t, h, true_north=True), declination_deg=-14.0,
                           deviation_deg=2.0)
    assert np.degrees(mag.heading_rad[0]) == pytest.approx(86.0)
    assert np.degrees(true.heading_rad[0]) == pytest.approx(100.0)
    assert mag.deviation_bound_rad == pytest.approx(math.radians(2.0))


def test_source_choice_and_ahrs_is_not_independent_of_the_imu(shared_data: Path) -> None:
    d = read_drive(shared_data / "dynamic" / "vn100_bu353_circle")
    ahrs = compass_heading(d, use="attitude")
    assert ahrs.source == "ahrs" and not ahrs.independent_of_imu
    assert isinstance(ahrs, CompassHeading) and ahrs.to_dict()["n"] == ahrs.t.size
    with pytest.raises(OptionError, match="an ellipse fit calibrates a raw magnetometer"):
        compass_heading(d, use="attitude", fit="ellipse")
    with pytest.raises(OptionError, match="compass fit 'magic'"):
        compass_heading(d, fit="magic")


def test_comma2k19_highway_cannot_self_calibrate(shared_data: Path) -> None:
    """A straight highway drive turns too little for an ellipse fit: a clear error, and the
    GNSS-course fit is there when asked for."""
    d = read_drive(shared_data / "dynamic" / "comma2k19_example1")
    with pytest.raises(AnalysisError, match="turns through"):
        compass_heading(d)
    with pytest.raises(AnalysisError, match="turns through"):
        compass_heading(d, fit="ellipse")
    ch = compass_heading(d, fit="gnss-course")
    assert not ch.independent_of_gnss


# ----------------------------------------------------------- harmonics of the deviation


def _rectangle_headings(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Compass headings (rad) and yaw rates (rad/s) of a rectangle driven clockwise at
    1 Hz: 60 s straights at 0, 90, 180, 270 deg, 9 s corners at 10 deg/s (the paper trip's
    shape: a two-cycle deviation peaks in the corners only)."""
    psi, rate = [], []
    for c in range(4):
        psi += [c * math.pi / 2] * 60
        rate += [0.0] * 60
        psi += list(c * math.pi / 2 + np.radians(10.0) * np.arange(1, 10))
        rate += [math.radians(10.0)] * 9
    psi_a = np.mod(np.array(psi) + rng.normal(0.0, math.radians(0.3), len(psi)), 2 * math.pi)
    return psi_a, np.array(rate)


def _rectangle_setup(rng: np.random.Generator) -> tuple[np.ndarray, ...]:
    """The rectangle's headings and yaw rates, the d noise variance (0.6 deg) and the
    bound (1 deg) of the harmonic tests."""
    psi, rate = _rectangle_headings(rng)
    sig2 = np.full(psi.size, math.radians(0.6) ** 2)
    return psi, rate, sig2, np.full(psi.size, math.radians(1.0))


def harmonic_test(*args: Any, **kw: Any) -> list[dict[str, Any]]:
    """The check's harmonics: :func:`harmonic_fit`'s coefficients of cycle >= 1."""
    return [c for c in harmonic_fit(*args, **kw) if c["cycle"]]


def test_harmonic_test_is_sound_under_its_assumptions() -> None:
    """|e_i| <= bound_i of any sign (here the worst: the sign of each coefficient's weight)
    and Gaussian noise: a coefficient beyond its limit at no more than the Gaussian tail's
    rate; a constant offset and a clock offset (offset x yaw rate) leave the harmonics."""
    from scipy.stats import norm

    rng = np.random.default_rng(3)
    psi, rate, sig2, bound = _rectangle_setup(rng)
    k = float(norm.isf(0.01 / 2))
    zero = harmonic_test(psi, np.zeros_like(psi), sig2, bound, k, rate)
    assert [(c["cycle"], c["term"]) for c in zero] == [(1, "cos"), (1, "sin"), (2, "cos"),
                                                       (2, "sin")]
    wm = _weights(psi, sig2, rate)
    for j, c in enumerate(zero):  # the deterministic part is sum |W_j| bound
        assert c["det"] == pytest.approx(float(np.abs(wm[j + 1]) @ bound))
    fails = 0
    for trial in range(200):
        j = trial % 4
        e = bound * np.sign(wm[j + 1])  # the worst error for coefficient j
        d = e + rng.normal(0.0, np.sqrt(sig2)) + math.radians(5.0) + 0.1 * rate
        c = harmonic_test(psi, d, sig2, bound, k, rate)[j]
        assert c["coef"] == pytest.approx(c["det"] + float(wm[j + 1] @ (d - e)), abs=1e-12)
        fails += abs(c["coef"]) > c["limit"]
    assert fails <= 6  # 0.5 % per trial (one-sided at the worst e): binomial 99.9 % is 5


def _weights(psi: np.ndarray, sig2: np.ndarray, rate: np.ndarray) -> np.ndarray:
    a = np.column_stack([np.ones_like(psi), np.cos(psi), np.sin(psi), np.cos(2 * psi),
                         np.sin(2 * psi), rate])
    w = 1.0 / sig2
    return np.linalg.solve(a.T @ (a * w[:, None]), (a * w[:, None]).T)


@pytest.mark.parametrize("amp_deg", [3.0, 4.0])
def test_harmonic_test_sees_a_two_cycle_deviation_in_the_corners(amp_deg: float) -> None:
    """A two-cycle deviation amp x sin(2 psi) held only in the corners of a rectangle:
    the per-bin means hold few epochs at 45 deg; the sin 2psi coefficient pools them."""
    from scipy.stats import norm

    rng = np.random.default_rng(5)
    psi, rate, sig2, bound = _rectangle_setup(rng)
    k = float(norm.isf(0.0025 / 36))
    d = math.radians(amp_deg) * np.sin(2 * psi) + rng.normal(0.0, np.sqrt(sig2))
    res = {(c["cycle"], c["term"]): c for c in harmonic_test(psi, d, sig2, bound, k, rate)}
    s2 = res[(2, "sin")]
    assert s2["coef"] == pytest.approx(math.radians(amp_deg), abs=math.radians(0.6))
    assert abs(s2["coef"]) > s2["limit"]
    assert all(abs(c["coef"]) <= c["limit"] for key, c in res.items() if key != (2, "sin"))


def test_harmonic_test_refuses_a_singular_design() -> None:
    """Headings that are not spread (a straight line): no harmonic test."""
    psi = np.full(50, 0.3)
    one = np.ones(50)
    assert harmonic_test(psi, 0.01 * one, one * 1e-4, one * 1e-2, 3.0) == []


def test_harmonic_test_budgets_the_weights_moved_by_the_heading_noise() -> None:
    """The weights W are taken at the measured heading: with ``psi_var`` the bound gains
    ``psi_var x sum_i |dW_ji/dpsi_i|``, the derivative of each column checked against
    finite differences."""
    rng = np.random.default_rng(1)
    n = 120
    psi = rng.uniform(0.0, 2 * math.pi, n)
    rate = rng.normal(0.0, 0.1, n)
    sig2 = rng.uniform(1e-5, 1e-4, n)
    zero = np.zeros(n)
    base = harmonic_test(psi, zero, sig2, zero, 0.0, rate)
    moved = harmonic_test(psi, zero, sig2, zero, 0.0, rate, psi_var=1.0)
    num = np.zeros((6, n))
    for i in range(n):
        p = psi.copy()
        p[i] += 1e-6
        num[:, i] = (_weights(p, sig2, rate)[:, i] - _weights(psi, sig2, rate)[:, i]) / 1e-6
    for j in range(4):
        assert base[j]["det"] == 0.0
        assert moved[j]["det"] == pytest.approx(float(np.abs(num[j + 1]).sum()), rel=1e-5)


# ------------------------------------------------- the compass error model (issue 27, 2)


def test_harmonic_fit_holds_the_model_and_its_coefficients_intervals() -> None:
    """harmonic_fit (the one least squares behind harmonic_test and the error model): the
    constant first, then the harmonics harmonic_test returns unchanged; an offset, a
    one- and a two-cycle deviation and a clock offset (x yaw rate) with a bounded error of
    the worst sign and Gaussian noise: every coefficient's interval holds its true value
    at the Gaussian tail's rate at most."""
    from scipy.stats import norm

    from imubounds.dynamic.sensors._course_check import harmonic_basis

    rng = np.random.default_rng(11)
    psi, rate, sig2, bound = _rectangle_setup(rng)
    k = float(norm.isf(0.01 / 2))
    fit0 = harmonic_fit(psi, np.zeros_like(psi), sig2, bound, k, rate)
    assert [(c["cycle"], c["term"]) for c in fit0][0] == (0, "const")
    assert fit0[1:5] == harmonic_test(psi, np.zeros_like(psi), sig2, bound, k, rate)
    assert fit0[5]["term"] == "rate" and fit0[5]["cycle"] is None
    wm = _weights(psi, sig2, rate)
    true = np.radians([3.0, -1.0, 0.5, 0.0, 2.0])
    model = sum(true[j] * harmonic_basis(j, psi) for j in range(5))
    misses = 0
    for trial in range(200):
        j = trial % 5
        e = bound * np.sign(wm[j])
        d = model + e + rng.normal(0.0, np.sqrt(sig2)) + 0.1 * rate
        c = harmonic_fit(psi, d, sig2, bound, k, rate)
        misses += abs(c[j]["coef"] - true[j]) > c[j]["limit"]
        assert all(abs(ci["coef"] - ti) <= ci["limit"] + 5 * ci["sd"]
                   for ci, ti in zip(c[:5], true, strict=True))
    assert misses <= 6  # 0.5 % per trial at the worst error: binomial 99.9 % is 5


def test_model_adequacy_is_silent_on_the_model_and_sees_three_cycles() -> None:
    """model_adequacy: the bins' means of the fit's residual within their bound whatever
    the model's coefficients (an 8 deg offset, a 4 deg two-cycle deviation, a clock
    offset) on headings spread round the circle; a three-cycle deviation of 4 deg fails
    it."""
    from scipy.stats import norm

    from imubounds.dynamic.sensors._course_check import model_adequacy

    rng = np.random.default_rng(2)
    n = 400
    psi = np.mod(np.linspace(0.0, 4 * math.pi, n) + rng.normal(0, 0.05, n), 2 * math.pi)
    rate = np.full(n, 0.05) + rng.normal(0.0, 0.02, n)
    sig2 = np.full(n, math.radians(0.6) ** 2)
    bound = np.full(n, math.radians(0.5))
    k = float(norm.isf(0.0025 / 36))
    fails = 0
    for _ in range(50):
        e = bound * rng.choice([-1.0, 1.0]) * np.sign(np.sin(psi))  # a bounded shape
        d = (math.radians(8.0) + math.radians(4.0) * np.sin(2 * psi) + 0.2 * rate + e
             + rng.normal(0.0, np.sqrt(sig2)))
        fails += bool(model_adequacy(psi, d, sig2, bound, k, rate))
    assert fails <= 1
    d = math.radians(4.0) * np.sin(3 * psi) + rng.normal(0.0, np.sqrt(sig2))
    bad = model_adequacy(psi, d, sig2, bound, k, rate)
    assert bad and all(abs(b["mean_deg"]) > b["limit_deg"] for b in bad)
    assert model_adequacy(np.full(50, 0.3), np.zeros(50), np.ones(50), np.ones(50), k) is None


def _offset_trip(seed: int, off: float, lag: float = 0.0) -> Drive:
    from imubounds.dynamic.scenario import faults as F
    from imubounds.dynamic.scenario import make_trip

    drive = make_trip("paper", seed=seed, duration_s=240.0, distance_m=2800.0, rate_hz=50.0,
                      aiding=("gnss", "gnss-vel", "compass")).drive
    if lag:
        drive = F.heading_lag(drive, lag)
    return F.heading_offset(drive, off) if off else drive


@pytest.mark.parametrize("off", [3.0, -3.0, 8.0])
def test_compass_offset_is_estimated_applied_and_the_check_runs_after(off: float) -> None:
    """compass_heading: a constant offset is estimated against the GNSS course (its
    interval holding it), taken off the headings (their mean error against the true
    heading well inside the new deviation bound), the bound replaced by the interval's
    half-width, the heading flagged as not independent of the GNSS, and the check of the
    corrected heading passes; estimate_errors=False keeps today's check, which fails."""
    drive = _offset_trip(7, off)
    ch = compass_heading(drive)
    model = ch.detail["heading_model"]
    c0 = model["coefficients"][0]
    assert c0["applied"] is True and c0["interval_deg"][0] <= off <= c0["interval_deg"][1]
    assert not any(c["applied"] for c in model["coefficients"][1:])
    assert ch.deviation_bound_rad == pytest.approx(math.radians(c0["half_width_deg"]))
    assert ch.independent_of_gnss is False and ch.detail["gnss_course_check"]["passed"]
    tr = drive.truth
    true_c = np.interp(ch.t, tr.t, np.unwrap(np.asarray(tr.heading_rad, float)))
    err = np.degrees(np.asarray(wrap_pi(ch.heading_rad - true_c)))
    assert abs(float(np.median(err))) < 0.5 * c0["half_width_deg"]
    plain = compass_heading(drive, estimate_errors=False)
    assert "heading_model" not in plain.detail and plain.independent_of_gnss is True
    assert plain.detail["gnss_course_check"]["passed"] is False


def test_clean_compass_is_not_corrected() -> None:
    """Clean trips (three seeds): no coefficient's interval excludes 0, nothing applied,
    the headings and the stated bound unchanged, the check silent."""
    for seed in (1, 7, 11):
        drive = _offset_trip(seed, 0.0)
        ch = compass_heading(drive)
        plain = compass_heading(drive, estimate_errors=False)
        assert ch.detail["heading_model"]["applied"] is False
        assert np.array_equal(ch.heading_rad, plain.heading_rad)
        assert ch.deviation_bound_rad == plain.deviation_bound_rad
        assert ch.independent_of_gnss and ch.detail["gnss_course_check"]["passed"] is True


@pytest.mark.parametrize("seed", [3, 7, 11])
def test_turn_test_budgets_the_heading_clock_allowance(seed: int) -> None:
    """The turn test of the check against the GNSS course budgets half the stated heading
    clock allowance (0.1 s by default; course_check.CLOCK_TEST_SHARE) x the mean turn
    rate: a compass 0.1 s late (within the allowance; 1.38 deg against a limit of 1.36
    before) passes; a 0.3 s lag still fails it."""
    from imubounds.dynamic.sensors._course_check import CLOCK_TEST_SHARE
    from imubounds.dynamic.sensors._timing import DEFAULT_HEADING_CLOCK_BOUND_S as B

    ok = compass_heading(_offset_trip(seed, 0.0, lag=0.1)).detail["gnss_course_check"]
    tu = ok["turns"]
    assert tu["clock_allowance_deg"] == pytest.approx(
        CLOCK_TEST_SHARE * B * tu["mean_rate_dps"])
    assert abs(tu["mean_diff_deg"]) <= tu["limit_deg"] and ok["passed"] is True
    late = compass_heading(_offset_trip(seed, 0.0, lag=0.3)).detail["gnss_course_check"]
    assert late["turns"]["mean_diff_deg"] > late["turns"]["limit_deg"]
    assert late["passed"] is False


def test_drive_yaml_heading_errors_stated_turns_the_model_off(tmp_path: Path) -> None:
    """drive.yaml ``heading.errors``: ``estimate`` (default) or ``stated`` (the compass
    error model off: the stated bound only, checked); any other value is refused."""
    import dataclasses

    from imubounds.errors import InputError
    from imubounds.io.drive.settings import parse_settings

    drive = _offset_trip(7, 3.0)
    assert drive.settings.heading.errors == "estimate"
    assert compass_heading(drive).detail["heading_model"]["applied"] is True
    hs = dataclasses.replace(drive.settings.heading, errors="stated")
    stated = dataclasses.replace(drive, settings=dataclasses.replace(drive.settings, heading=hs))
    ch = compass_heading(stated)
    assert "heading_model" not in ch.detail
    assert ch.detail["gnss_course_check"]["passed"] is False
    assert parse_settings({"heading": {"errors": "stated"}}).heading.errors == "stated"
    with pytest.raises(InputError, match="heading.errors"):
        parse_settings({"heading": {"errors": "off"}})
