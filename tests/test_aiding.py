"""Aiding-sensor models: GPS boxes, compass deviation and headings, geodesy."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from imubounds.dynamic.sensors import (
    cep_to_drms,
    compass_to_model,
    course_over_ground,
    fit_deviation,
    geodetic_to_enu,
    gps_box_halfwidths,
    heading_from_magnetometer,
    heading_intervals,
    mean_error,
    model_to_compass,
    parse_gps_box,
    radius_at_probability,
    wrap_pi,
)
from imubounds.dynamic.sensors._compass import read_calibration
from imubounds.errors import AnalysisError, InputError, OptionError
from imubounds.geodesy import enu_to_geodetic, haversine_enu


def test_paper_gps_numbers() -> None:
    drms = cep_to_drms(3.0)
    assert drms == pytest.approx(3.603, abs=1e-3)  # "approximated measure of DRMS as 3.6 m"
    assert mean_error(drms) == pytest.approx(3.193, abs=1e-3)  # the paper's 3.19 m
    h, n_def = gps_box_halfwidths(np.array([1.0, 0.8, np.nan]), 3.0, "mean")
    assert h[0] == pytest.approx(3.193, abs=1e-3)
    assert h[1] == pytest.approx(0.8 * 3.193, abs=1e-3)
    assert h[2] == pytest.approx(h[0]) and n_def == 1


def test_probability_box_contains_rayleigh_fraction() -> None:
    spec = parse_gps_box("p=0.999")
    assert spec.containment() == pytest.approx(0.999)
    assert parse_gps_box("mean").containment() == pytest.approx(1 - math.exp(-math.pi / 4))
    drms = cep_to_drms(3.0)
    d = radius_at_probability(drms, 0.5)
    assert d == pytest.approx(3.0)  # CEP is the 50 % radius
    rng = np.random.default_rng(1)
    # 2-D isotropic Gaussian with DRMS: sigma per axis = DRMS/sqrt(2)
    err = rng.normal(0, drms / math.sqrt(2), size=(200_000, 2))
    r = np.hypot(err[:, 0], err[:, 1])
    assert np.mean(r <= radius_at_probability(drms, 0.9)) == pytest.approx(0.9, abs=0.005)
    assert np.mean(r) == pytest.approx(mean_error(drms), rel=0.01)


@pytest.mark.parametrize("bad", ["p=1", "p=0", "median", "p=x"])
def test_bad_box_spec(bad: str) -> None:
    with pytest.raises(OptionError, match="gps-box"):
        parse_gps_box(bad)


def test_conventions() -> None:
    # North (compass 0) is model pi/2, east (compass 90 deg) is model 0.
    assert compass_to_model(0.0) == pytest.approx(math.pi / 2)
    assert compass_to_model(math.pi / 2) == pytest.approx(0.0)
    assert model_to_compass(math.pi) == pytest.approx(1.5 * math.pi)


@given(st.floats(-20, 20))
def test_conversion_roundtrip(a: float) -> None:
    back = model_to_compass(compass_to_model(a))
    assert abs(wrap_pi(back - a)) < 1e-9


def test_deviation_fit_recovers_coefficients() -> None:
    rng = np.random.default_rng(3)
    ref = rng.uniform(0, 2 * math.pi, 300)
    A, B, C = math.radians(2.0), math.radians(-3.0), math.radians(1.5)
    # measured = ref + err(measured): solve by fixed-point
    meas = ref.copy()
    for _ in range(50):
        meas = ref + A + B * np.sin(meas) + C * np.cos(meas)
    meas = meas % (2 * math.pi)  # wraps must not disturb the fit
    dev = fit_deviation(meas, ref)
    assert (dev.A, dev.B, dev.C) == pytest.approx((A, B, C), abs=1e-9)
    assert dev.residual_bound < 1e-9
    with pytest.raises(AnalysisError):
        fit_deviation(meas[:2], ref[:2])


def test_heading_intervals_modes_and_wrap() -> None:
    dev = fit_deviation(
        np.radians([0, 90, 180, 270, 359.0]), np.radians([358, 87, 181, 272, 357.5])
    )
    psi_c = np.radians([359.5, 0.5])
    c_p, h_p = heading_intervals(psi_c, dev, "paper")
    assert np.all(h_p >= 0)
    # both readings straddle north; model centres near +pi/2 with no 2pi jump
    assert np.all(np.abs(c_p - math.pi / 2) < 0.02)
    c_c, h_c = heading_intervals(psi_c, dev, "corrected", floor_rad=0.01)
    assert np.all(h_c == pytest.approx(max(dev.residual_bound, 0.01)))
    # corrected centre = model(psi_c - err)
    assert c_c[0] == pytest.approx(float(compass_to_model(psi_c[0] - dev.error(psi_c[0]))))
    with pytest.raises(OptionError):
        heading_intervals(psi_c, dev, "nope")


def test_calibration_file(tmp_path) -> None:
    f = tmp_path / "cal.csv"
    f.write_text("# bench\nmeasured_deg,reference_deg\n0,1\n90,92\n180,181\n270,268\n")
    dev = read_calibration(str(f))
    assert dev.n == 4 and dev.source == str(f)
    bad = tmp_path / "bad.csv"
    bad.write_text("a,b\n1,2\n")
    with pytest.raises(InputError, match="measured_deg"):
        read_calibration(str(bad))


@pytest.mark.parametrize("heading_deg", [0.0, 45.0, 90.0, 200.0, 315.0])
def test_heading_from_magnetometer(heading_deg: float) -> None:
    psi = math.radians(heading_deg)
    # Field pointing north, horizontal; in FRD body: forward cos(psi), right -sin(psi)
    fwd, right = math.cos(psi), -math.sin(psi)
    assert heading_from_magnetometer(np.array([fwd]), np.array([right]), "FRD")[0] == (
        pytest.approx(psi % (2 * math.pi))
    )
    assert heading_from_magnetometer(np.array([fwd]), np.array([-right]), "FLU")[0] == (
        pytest.approx(psi % (2 * math.pi))
    )


def test_course_over_ground() -> None:
    t = np.arange(5.0)
    e = np.array([0, 10, 20, 20.5, 30.0])
    n = np.array([0, 10, 20, 20.5, 20.0])
    tm, cog = course_over_ground(t, e, n, min_speed=3.0)
    assert np.degrees(cog[:2]) == pytest.approx([45.0, 45.0])
    assert tm.size == 3  # the 0.7 m/s pair is dropped
    assert np.degrees(cog[2]) == pytest.approx(np.degrees(math.atan2(9.5, -0.5)) % 360)


def paper_loop(lat0: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A 9.4 km closed loop (1.5 km radius circle) around (lat0, 88 E)."""
    th = np.linspace(0, 2 * np.pi, 400)
    r = 9400.0 / (2 * np.pi)
    e, n = r * np.cos(th) - r, r * np.sin(th)
    lat, lon = enu_to_geodetic(e, n, (lat0, 88.0, 0.0))
    return e, n, lat, lon


@pytest.mark.parametrize("lat0", [0.0, 23.5, 45.0, 60.0])
def test_wgs84_exact_and_haversine_close(lat0: float) -> None:
    e, n, lat, lon = paper_loop(lat0)
    e1, n1, _ = geodetic_to_enu(lat, lon, origin=(lat0, 88.0, 0.0))
    assert np.max(np.hypot(e1 - e, n1 - n)) < 1e-3  # pymap3d round trip (height 0 vs up 0)
    e2, n2, _ = geodetic_to_enu(lat, lon, origin=(lat0, 88.0, 0.0), method="haversine")
    dist = np.hypot(e, n)
    # The sphere (R = 6371 km) differs from the ellipsoid's radii of curvature by at most
    # ~0.6 %: centimetres within ~10 m of the origin, metres across the 9.4 km loop.
    assert np.all(np.hypot(e2 - e, n2 - n) <= 0.006 * dist + 1e-6)
    near = dist < 10
    assert np.all(np.hypot(e2 - e, n2 - n)[near] < 0.06)


def test_haversine_axes_are_east_north() -> None:
    # A point due east has north ~ 0 and positive east (the paper's x=S cos(alpha) is wrong).
    e, n = haversine_enu(np.array([10.0]), np.array([10.01]), 10.0, 10.0)
    assert e[0] > 1000 and abs(n[0]) < 1.0
    with pytest.raises(OptionError):
        geodetic_to_enu(np.array([1.0]), np.array([1.0]), method="flat")


@settings(max_examples=30, deadline=None)
@given(st.floats(-70, 70), st.floats(-179, 179), st.floats(0, 2 * math.pi), st.floats(1, 3000))
def test_haversine_scale(lat0: float, lon0: float, b: float, s: float) -> None:
    e, n = s * math.sin(b), s * math.cos(b)
    lat, lon = enu_to_geodetic(np.array([e]), np.array([n]), (lat0, lon0, 0.0))
    e2, n2 = haversine_enu(lat, lon, lat0, lon0)
    assert math.hypot(e2[0] - e, n2[0] - n) <= 0.0071 * s
