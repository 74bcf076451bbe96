"""Real-sensor faults injected into a simulated drive (the fault suite of
tests/test_dynamic_faults.py and benchmarks/sweep_faults.py; docs/dynamic-method.md,
section 5b).

Each function returns a copy of the :class:`~imubounds.io.drive.Drive` with one stream
perturbed the way a real sensor is, as if its file had been edited (``time_s`` shifted,
``heading_deg`` offset, fixes moved): the drive's truth and settings are unchanged, so
the perturbation breaks one stated assumption and the estimator must either still
enclose the truth or withdraw its guarantee. :data:`FAULTS` names them for the tests.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Callable
from typing import Any

import numpy as np

from imubounds.dynamic.sensors.gnss import cep_to_sigma


def _copy(drive: Any) -> Any:
    return copy.deepcopy(drive)


def gnss_lag(drive: Any, lag_s: float) -> Any:
    """GNSS time stamps ``lag_s`` late (stamp = true time + lag)."""
    d = _copy(drive)
    d.gnss.t = d.gnss.t + lag_s
    return d


def heading_lag(drive: Any, lag_s: float) -> Any:
    """Compass time stamps ``lag_s`` late."""
    d = _copy(drive)
    d.heading.t = d.heading.t + lag_s
    return d


def velocity_lag(drive: Any, lag_s: float) -> Any:
    """Body-velocity (wheel speed, DVL) time stamps ``lag_s`` late."""
    d = _copy(drive)
    d.velocity.t = d.velocity.t + lag_s
    return d


def no_gnss_velocity(drive: Any) -> Any:
    """A receiver that logs positions only (no velocity, speed or course)."""
    d = _copy(drive)
    g = d.gnss
    g.vel_n_mps = g.vel_e_mps = g.vel_acc_mps = g.speed_mps = g.course_rad = None
    return d


def heading_lag_positions_only(drive: Any, lag_s: float) -> Any:
    """Compass time stamps ``lag_s`` late on a trip with GNSS positions only: the course
    comes from chords of fixes, too noisy for the turn test to see the lag."""
    return heading_lag(no_gnss_velocity(drive), lag_s)


def _true_velocity_ne(drive: Any, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The truth's (north, east) velocity (m/s) at ``t``, by central differences of its
    positions (the simulator's truth at 10 Hz)."""
    tr = drive.truth
    tt = np.asarray(tr.t, float)
    vn = np.gradient(np.asarray(tr.north_m, float), tt)
    ve = np.gradient(np.asarray(tr.east_m, float), tt)
    return np.interp(t, tt, vn), np.interp(t, tt, ve)


def gnss_velocity_lag(drive: Any, lag_s: float) -> Any:
    """The receiver's velocity ``lag_s`` late against its own positions (a velocity
    filtered or computed over the past, stamped with the fix): each reported velocity
    keeps its error but is the true velocity of ``lag_s`` earlier."""
    d = _copy(drive)
    g = d.gnss
    ne = g.velocity_ne()
    if ne is None:
        raise ValueError("gnss_velocity_lag: the drive has no GNSS velocity")
    vn0, ve0 = _true_velocity_ne(d, g.t)
    vn1, ve1 = _true_velocity_ne(d, g.t - lag_s)
    g.vel_n_mps = np.asarray(ne[0], float) + (vn1 - vn0)
    g.vel_e_mps = np.asarray(ne[1], float) + (ve1 - ve0)
    g.speed_mps = g.course_rad = None
    return d


def heading_offset(drive: Any, offset_deg: float) -> Any:
    """A constant compass offset (mount, declination) of ``offset_deg``."""
    d = _copy(drive)
    d.heading.heading_rad = np.mod(d.heading.heading_rad + math.radians(offset_deg), 2 * math.pi)
    return d


def heading_two_cycle(drive: Any, amplitude_deg: float, cycles: int = 2) -> Any:
    """A two-cycle compass deviation ``amplitude_deg * sin(2 heading)`` (``cycles``
    another number of cycles)."""
    d = _copy(drive)
    h = d.heading.heading_rad
    d.heading.heading_rad = np.mod(
        h + math.radians(amplitude_deg) * np.sin(cycles * h), 2 * math.pi)
    return d


def heading_three_cycle(drive: Any, amplitude_deg: float) -> Any:
    """A three-cycle compass deviation ``amplitude_deg * sin(3 heading)``: a shape the
    compass error model (constant, harmonics 1 and 2) does not take."""
    return heading_two_cycle(drive, amplitude_deg, cycles=3)


def _shift_fixes(d: Any, sel: np.ndarray, de: np.ndarray, dn: np.ndarray) -> None:
    lat = np.radians(d.gnss.lat_deg[sel])
    r = 6378137.0
    d.gnss.lat_deg[sel] = d.gnss.lat_deg[sel] + np.degrees(dn / r)
    d.gnss.lon_deg[sel] = d.gnss.lon_deg[sel] + np.degrees(de / (r * np.cos(lat)))


def multipath(drive: Any, step_m: float, t0_s: float, duration_s: float = 60.0) -> Any:
    """GNSS fixes between ``t0_s`` and ``t0_s + duration_s`` moved ``step_m`` east."""
    d = _copy(drive)
    d.gnss.lat_deg = d.gnss.lat_deg.copy()
    d.gnss.lon_deg = d.gnss.lon_deg.copy()
    sel = (d.gnss.t >= t0_s) & (d.gnss.t < t0_s + duration_s)
    _shift_fixes(d, sel, np.full(int(sel.sum()), step_m), np.zeros(int(sel.sum())))
    return d


def student_t(drive: Any, dof: float = 3.0, seed: int = 0) -> Any:
    """Heavy-tailed GNSS position errors: Student-t noise of ``dof`` degrees of freedom
    scaled to the stated per-axis sigma, added to the fixes."""
    d = _copy(drive)
    rng = np.random.default_rng(seed)
    n = d.gnss.t.size
    s = cep_to_sigma(d.settings.gnss.cep_m)
    scale = s * math.sqrt((dof - 2) / dof) if dof > 2 else s
    d.gnss.lat_deg = d.gnss.lat_deg.copy()
    d.gnss.lon_deg = d.gnss.lon_deg.copy()
    _shift_fixes(
        d, np.ones(n, bool), scale * rng.standard_t(dof, n), scale * rng.standard_t(dof, n)
    )
    return d


def lever_arm(drive: Any, length_m: float = 1.5) -> Any:
    """An undeclared antenna lever arm of ``length_m`` forward of the IMU: the fixes
    move by ``length_m`` along the true heading."""
    d = _copy(drive)
    tr = d.truth
    hd = np.interp(d.gnss.t, tr.t, np.unwrap(np.asarray(tr.heading_rad, float)))
    d.gnss.lat_deg = d.gnss.lat_deg.copy()
    d.gnss.lon_deg = d.gnss.lon_deg.copy()
    _shift_fixes(d, np.ones(d.gnss.t.size, bool), length_m * np.sin(hd), length_m * np.cos(hd))
    return d


def imu_stamp_start(drive: Any) -> Any:
    """IMU stamps at the start of the sample period while drive.yaml says the end."""
    d = _copy(drive)
    dt = float(np.median(np.diff(d.imu.t)))
    d.imu.t = d.imu.t - dt
    return d


#: name -> (function, keyword arguments) of the fault suite's cases
FAULTS: dict[str, tuple[Callable[..., Any], dict[str, Any]]] = {
    "gnss_lag_0.1": (gnss_lag, {"lag_s": 0.1}),
    "gnss_lag_0.3": (gnss_lag, {"lag_s": 0.3}),
    "gnss_lag_0.5": (gnss_lag, {"lag_s": 0.5}),
    "compass_lag_0.1": (heading_lag, {"lag_s": 0.1}),
    "compass_lag_0.15": (heading_lag, {"lag_s": 0.15}),
    "compass_lag_0.2": (heading_lag, {"lag_s": 0.2}),
    "compass_lag_0.3": (heading_lag, {"lag_s": 0.3}),
    "compass_lag_0.5": (heading_lag, {"lag_s": 0.5}),
    "wheel_lag_0.3": (velocity_lag, {"lag_s": 0.3}),
    "dvl_lag_0.3": (velocity_lag, {"lag_s": 0.3}),
    "compass_offset_3": (heading_offset, {"offset_deg": 3.0}),
    "compass_offset_-3": (heading_offset, {"offset_deg": -3.0}),
    "compass_offset_8": (heading_offset, {"offset_deg": 8.0}),
    "compass_two_cycle_2": (heading_two_cycle, {"amplitude_deg": 2.0}),
    "compass_two_cycle_3": (heading_two_cycle, {"amplitude_deg": 3.0}),
    "compass_two_cycle_4": (heading_two_cycle, {"amplitude_deg": 4.0}),
    "compass_three_cycle_3": (heading_three_cycle, {"amplitude_deg": 3.0}),
    "compass_three_cycle_4": (heading_three_cycle, {"amplitude_deg": 4.0}),
    "multipath_5m": (multipath, {"step_m": 5.0, "t0_s": 100.0}),
    "multipath_8m": (multipath, {"step_m": 8.0, "t0_s": 100.0}),
    "multipath_12m": (multipath, {"step_m": 12.0, "t0_s": 100.0}),
    "student_t": (student_t, {"dof": 3.0}),
    "lever_arm_1.5": (lever_arm, {"length_m": 1.5}),
    "imu_stamp_start": (imu_stamp_start, {}),
    "positions_only": (no_gnss_velocity, {}),
    "positions_only_compass_lag_0.2": (heading_lag_positions_only, {"lag_s": 0.2}),
    "positions_only_compass_lag_0.3": (heading_lag_positions_only, {"lag_s": 0.3}),
    "gnss_velocity_lag_0.12": (gnss_velocity_lag, {"lag_s": 0.12}),
    "gnss_velocity_lag_0.3": (gnss_velocity_lag, {"lag_s": 0.3}),
}
