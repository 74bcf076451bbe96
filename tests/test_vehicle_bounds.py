"""Vehicle bounds from the aiding sensors' own intervals (issue 24, item 1): an attitude
beyond a default cap never stops the run, the speed bound comes from the GNSS, and the
defaults left are named."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from imubounds.dynamic.estimator import dynamic_margins
from imubounds.dynamic.scenario import make_trip
from imubounds.errors import InputError
from imubounds.units import DEG

#: a short hilly trip: pitch up to about 13 deg (quadrotor-like), attitude stream at 10 Hz
STEEP = {"hill_amplitude_m": 8.0, "duration_s": 200.0, "distance_m": 2400.0, "rate_hz": 50.0}


def _steep(max_tilt_deg: float | None) -> tuple[object, float, float]:
    res = make_trip("hills", seed=5, **STEEP)
    drive = res.drive
    veh = dataclasses.replace(
        drive.settings.vehicle, max_tilt_deg=max_tilt_deg, max_speed_mps=None
    )
    drive.settings = dataclasses.replace(drive.settings, vehicle=veh)
    tr = res.truth
    pitch = float(np.max(np.abs(tr["pitch"]))) / DEG
    speed = float(np.max(np.hypot(tr["vel_enu"][:, 0], tr["vel_enu"][:, 1])))
    return drive, pitch, speed


def test_attitude_beyond_the_default_tilt_runs_with_finite_margins() -> None:
    drive, pitch, speed = _steep(None)
    assert pitch > 10.0  # beyond the 10 deg default
    d = dynamic_margins(drive).to_dict()
    veh = d["vehicle"]
    assert veh["sources"]["max_tilt"] == "data: attitude stream"
    assert pitch <= veh["max_tilt_deg"] <= pitch + 2.0
    # the speed bound is the GNSS's, not the 70 m/s default, and holds
    assert veh["sources"]["max_speed"].startswith("data: GNSS")
    assert speed <= veh["max_speed_mps"] < 40.0  # positions at 1 Hz, 3 m CEP
    for ch, rows in d["margins"].items():
        aided = [r for r in rows if r["aided_from"] == "aiding"]
        assert aided, ch
        assert all(math.isfinite(r["halfwidth_median"]) for r in aided), ch
    assert any("taken from the defaults" in n and "angular acceleration" in n for n in d["notes"])


def test_stated_tilt_contradicted_by_the_attitude_is_replaced_and_said() -> None:
    drive, pitch, _ = _steep(5.0)
    d = dynamic_margins(drive).to_dict()
    assert d["vehicle"]["max_tilt_deg"] >= pitch
    assert any("exceeds the stated maximum tilt" in n for n in d["notes"])


def test_a_dominant_assumed_tilt_is_named() -> None:
    """No attitude stream and no stated tilt: the 10 deg default bounds gravity's part of
    accel_x (g sin 10 deg = 1.71 m/s^2) and the channel's notes say it dominates."""
    res = make_trip("gnss-posvel", seed=6, duration_s=200.0, distance_m=2400.0, rate_hz=50.0)
    drive = res.drive
    veh = dataclasses.replace(drive.settings.vehicle, max_tilt_deg=None)
    drive.settings = dataclasses.replace(drive.settings, vehicle=veh)
    d = dynamic_margins(drive).to_dict()
    assert d["vehicle"]["sources"]["max_tilt"].startswith("default")
    notes = d["verdict_detail"]["accel_x"]["notes"]
    assert any("default maximum tilt" in n and "dominates" in n for n in notes), notes
    assert d["margins"]["accel_x"][-1]["halfwidth_median"] >= 9.76 * math.sin(10 * DEG)


def test_an_attitude_on_its_side_is_a_user_error_naming_the_mount() -> None:
    """Roll 89.5 deg (an IMU on its side read as the body frame): an InputError naming
    imu_axes, never an internal interval error."""
    drive, _, _ = _steep(None)
    att = drive.attitude
    att.roll_rad = np.full_like(np.asarray(att.roll_rad, dtype=float), math.radians(89.5))
    with pytest.raises(InputError, match="imu_axes"):
        dynamic_margins(drive)


def test_transport_without_a_lateral_bound_is_named() -> None:
    """accel_x's transport term through the speed bound (no lateral-velocity bound) is
    named when it is at least half the interval, and only then."""
    from imubounds.dynamic.estimator.inputs import Vehicle
    from imubounds.dynamic.estimator.vehicle_bounds import dominant_transport

    veh = Vehicle(max_speed=36.6, lateral_speed_bound_mps=None)
    note = dominant_transport("accel_x", veh, 10.2, 12.6, 0.31)
    assert note is not None and "lateral_speed_bound_mps" in note and "11.3" in note
    assert dominant_transport("accel_x", veh, 30.0, 12.6, 0.31) is None
    assert dominant_transport("accel_y", veh, 10.2, 12.6, 0.31) is None
    veh.lateral_speed_bound_mps = 0.5
    assert dominant_transport("accel_x", veh, 10.2, 12.6, 0.31) is None
