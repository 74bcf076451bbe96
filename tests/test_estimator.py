"""Mode paper: the paper's per-step estimator on a Drive (compiled loop vs reference, the
paper's numbers, its rules for empty intersections). Not guaranteed, and says so."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from imubounds.dynamic.estimator import dynamic_margins
from imubounds.dynamic.estimator.paper import config_for_drive, prepare_steps, run
from imubounds.dynamic.estimator.paper_kernel import F_GPS_MISSING
from imubounds.errors import AnalysisError, InputError
from imubounds.interval.qinter import qinter_1d
from imubounds.io.drive import Drive, GnssStream, HeadingStream, ImuStream
from imubounds.stationary import bounds
from tests.paper_reference import run_reference
from tests.trips import make_trip

SHORT = {"duration_s": 200.0, "distance_m": 2000.0, "corner_m": 80.0, "imu_hz": 10.0}


def test_paper_worked_numbers() -> None:
    assert bounds.level_95(0.108, 0.22) == pytest.approx(0.099, abs=5e-4)
    assert bounds.level_95(0.12, 0.22) == pytest.approx(0.11, abs=5e-4)
    assert bounds.level_95(6.0, 0.22) == pytest.approx(5.52, abs=5e-3)
    assert bounds.level_95_si(0.002, 0.22 * 3600) == pytest.approx(0.11, abs=5e-4)


@pytest.mark.parametrize("kinematics", ["paper", "full"])
@pytest.mark.parametrize("veldiff", ["contracted", "ins"])
@pytest.mark.parametrize("fallback", ["keep", "reset"])
def test_kernel_equals_reference(kinematics: str, veldiff: str, fallback: str) -> None:
    drive, _ = make_trip("outliers", 5, outlier_fraction=0.05, **SHORT)
    cfg = config_for_drive(
        drive,
        kinematics=kinematics,
        veldiff=veldiff,
        fallback=fallback,
        nav_accel_bound=0.5,
        jerk_bound=0.01,
    )
    steps = prepare_steps(drive, cfg)
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
        kinematics,
        veldiff,
        fallback,
    )
    np.testing.assert_array_equal(S, res.S)
    np.testing.assert_array_equal(D[1:], res.D[1:])
    np.testing.assert_array_equal(A[1:], res.A[1:])
    np.testing.assert_array_equal(flags, res.flags)
    assert np.all(res.flags[50:53] & F_GPS_MISSING)


def test_paper_mode_block_says_not_guaranteed() -> None:
    drive, _ = make_trip("paper", 2, **SHORT)
    r = dynamic_margins(drive, mode="paper")
    d = r.to_dict()
    assert d["guaranteed"] is False and d["statement"].startswith("not guaranteed")
    for ch in ("accel_x", "accel_y", "gyro_z"):
        (row,) = d["margins"][ch]
        assert row["tau_s"] == 1.0
        # the paper's 1.96 N sqrt(T) stays in its own unit (m/s or rad), labelled so
        assert row["stationary_unit"] == ("m/s" if ch.startswith("accel") else "rad")
        # known on this trip: the per-step margins are tens of times the paper's
        # stationary level, so they are supersets of it (the paper's finding for
        # accelerations): ``exceeds``
        assert row["halfwidth_median"] > 10 * row["stationary"], (ch, row)
        assert d["verdict"][ch] == "exceeds", (ch, d["verdict"])
        assert d["budget"][ch][0]["term"] == "white noise density N"
    assert set(d["enclosure"]) >= {"position", "heading", "u", "v"}


def test_paper_kinematics_lose_the_lateral_velocity() -> None:
    """The printed model reads the centripetal r*u as v': its lateral velocity leaves the
    truth in the turns (the issue's 52-95 % for v); the full kinematics keep it."""
    drive, _ = make_trip("paper", 1)
    paper = dynamic_margins(drive, mode="paper", kinematics="paper", gps_box="p=0.999")
    full = dynamic_margins(drive, mode="paper", kinematics="full", gps_box="p=0.999")
    vp = paper.to_dict()["enclosure"]["v"]
    vf = full.to_dict()["enclosure"]["v"]
    assert vp < 0.7, f"paper kinematics keep v inside at {vp:.2f} of the steps"
    assert vf > vp, f"full kinematics {vf:.2f} vs paper {vp:.2f}"


def _straight_north(heading_deg: np.ndarray) -> Drive:
    n = heading_deg.size
    t = np.arange(n, dtype=float)
    lat = 23.5 + 10.0 * t / 111_000.0
    return Drive(
        imu=ImuStream(t=t, accel=np.zeros((n, 3)), gyro=np.zeros((n, 3))),
        gnss=GnssStream(t=t, lat_deg=lat, lon_deg=np.full(n, 88.0), hdop=np.full(n, 0.8)),
        heading=HeadingStream(t=t, heading_rad=np.radians(heading_deg)),
    )


def test_heading_wrap_north() -> None:
    """Driving north with compass readings alternating 359.9 / 0.1 deg: no 2 pi blow-up."""
    from imubounds.dynamic.sensors._compass import ZERO_DEVIATION

    n = 61
    drive = _straight_north(np.where(np.arange(n) % 2 == 0, 359.9, 0.1))
    cfg = config_for_drive(drive, deviation=ZERO_DEVIATION, initial_speed_bound=15.0)
    res = run(drive, cfg)
    w = res.S[:, 9] - res.S[:, 8]
    assert np.all(w < math.radians(1.1))
    mid = 0.5 * (res.S[:, 8] + res.S[:, 9])
    assert np.all(np.abs(mid - math.pi / 2) < math.radians(1.0))
    assert res.summary["flags"]["heading_empty"]["count"] == 0


def test_step_shorter_than_imu_period() -> None:
    drive, _ = make_trip("paper", 0, **{**SHORT, "imu_hz": 1.0})
    with pytest.raises(AnalysisError, match="longer --step"):
        prepare_steps(drive, config_for_drive(drive, step_s=0.5))


def test_longer_step_averages() -> None:
    drive, _ = make_trip("paper", 0, **SHORT)
    cfg = config_for_drive(drive, step_s=1.0)
    steps = prepare_steps(drive, cfg)
    k = 57
    t_imu = drive.imu.t  # type: ignore[union-attr]
    sel = (t_imu > steps.t[k - 1]) & (t_imu <= steps.t[k] + 1e-9)
    assert sel.sum() == 10
    assert steps.meas[k, 0] == pytest.approx(np.mean(drive.imu.accel[sel, 0]))  # type: ignore[union-attr]
    N, B = cfg.imu.accel["N"], cfg.imu.accel["B"]
    T = float(steps.t[-1] - steps.t[0])
    assert steps.half[0] == pytest.approx(bounds.interval_halfwidth(N, B, 1.0, T, 3.0))


def test_paper_needs_gnss_and_heading() -> None:
    drive = _straight_north(np.zeros(20))
    drive.heading = None
    with pytest.raises(InputError, match="compass heading or a magnetometer"):
        dynamic_margins(drive, mode="paper")


@settings(max_examples=60, deadline=None)
@given(
    st.lists(st.tuples(st.floats(-10, 10), st.floats(0, 5)), min_size=1, max_size=7),
    st.integers(0, 3),
)
def test_qinter_1d_matches_brute_force(ivs: list[tuple[float, float]], q: int) -> None:
    lo = np.array([a for a, _ in ivs])
    hi = np.array([a + w for a, w in ivs])
    m = lo.size
    got = qinter_1d(lo, hi, m, q)
    pts = np.concatenate([lo, hi])
    cover = np.array([np.sum((lo <= p) & (p <= hi)) for p in pts])
    ok = pts[cover >= m - q]
    if m - q <= 0:
        assert got == (-np.inf, np.inf)
    elif ok.size == 0:
        assert not (got[0] <= got[1])
    else:
        assert got == (ok.min(), ok.max())


def test_qrelax_rule_tolerates_outliers() -> None:
    """GPS outliers: the q-relaxed rule (q = 1 over a 10-step window) keeps the truth in the
    position boxes at more steps than 'reset' to the outlier box."""
    drive, _ = make_trip("outliers", 3, outlier_fraction=0.03)
    enc = {}
    for rule in ("reset", "qrelax"):
        cfg = config_for_drive(drive, fallback=rule, kinematics="full")
        s = run(drive, cfg).summary
        enc[rule] = s["enclosure"]["position_box"]
    assert enc["qrelax"] >= enc["reset"], enc


def test_comma2k19_paper_mode(shared_data: Path) -> None:
    from imubounds.cli.dynamic import load_drive

    drive = load_drive([str(shared_data / "dynamic" / "comma2k19_example1")])
    d = dynamic_margins(drive, mode="paper", kinematics="full").to_dict()
    assert d["enclosure"]["steps"] == 60
    assert d["enclosure"]["position"] >= 0.95, d["enclosure"]
