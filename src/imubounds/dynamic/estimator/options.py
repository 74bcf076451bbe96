"""The options of mode ``full``, typed (docs/dynamic-method.md; ``imubounds dynamic --help``).

:class:`FullOptions` is built once at the boundary -- by
:func:`imubounds.dynamic_margins` from its keywords and by the command line from its
arguments -- through :func:`check_options`, which refuses unknown names and bad values
(:class:`~imubounds.errors.OptionError`, naming the option). Every figure left ``None`` is
taken from drive.yaml, then from a default (each listed as assumed in dynamic.json).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any

from imubounds.errors import OptionError

#: the whole-trip probability that some stated probabilistic bound fails, by default
DEFAULT_ALPHA = 0.01
#: where in its period an IMU sample may be time-stamped
IMU_STAMPS = ("end", "start", "centre")


@dataclass(frozen=True)
class FullOptions:
    """The options of mode ``full`` (SI unless the name says otherwise; ``None``: the figure
    of drive.yaml, else the default, listed as assumed).

    Probability and IMU figures:

    * ``alpha`` -- whole-trip probability that some stated probabilistic bound fails, in
      (0, 1) (:data:`DEFAULT_ALPHA`);
    * ``imu_stamp`` -- where in its period an IMU sample is time-stamped: ``end``,
      ``start`` or ``centre`` (not given: drive.yaml ``imu.sample_time``, else ``end``;
      :func:`check_options`);
    * ``imu_spec`` -- a preset name (``mtx``, ``vn100``) or
      ``accel_nd=..,accel_bs=..,gyro_nd=..,gyro_bs=..`` when no noise.json is given;
    * ``accel_turn_on`` -- turn-on bias bound of the accelerometers, m/s^2, >= 0;
    * ``gyro_turn_on`` -- turn-on bias bound of the gyros, rad/s, >= 0;
    * ``scale`` -- scale-factor error bound, a fraction (0.005 = 0.5 %) in [0, 0.5);
    * ``misalignment_deg`` -- axis misalignment bound, deg, >= 0;
    * ``flicker_tau_range_s`` -- (low, high) averaging times of the flicker band, s.

    Vehicle bounds (drive.yaml ``vehicle``):

    * ``max_speed`` (m/s), ``max_accel`` (horizontal, centripetal included, m/s^2),
      ``max_jerk`` (m/s^3), ``max_rate_dps`` (deg/s), ``max_ang_accel_dps2`` (deg/s^2):
      each > 0;
    * ``max_tilt_deg`` -- roll/pitch bound without an attitude stream, deg, >= 0;
    * ``lateral_speed_bound_mps`` -- non-holonomic |lateral velocity| bound of a wheeled
      vehicle, m/s, >= 0;
    * ``vertical_speed_bound_mps`` -- |vertical body velocity| bound, m/s, >= 0;
    * ``reverses`` -- the vehicle may drive backwards (no heading from the GNSS course).

    Aiding sensors (drive.yaml ``gnss``, ``velocity``, ``attitude``, ``heading``):

    * ``gnss_cep_m`` -- CEP at HDOP 1, m, > 0; ``default_hdop`` -- HDOP of a fix that
      reports none, > 0; ``gnss_vel_sigma`` -- GNSS velocity 1-sigma per component, m/s,
      >= 0;
    * ``velocity_bound`` -- body-velocity sensor error per component, m/s, >= 0;
    * ``attitude_bound_deg`` -- attitude stream roll/pitch error bound, deg, >= 0;
    * ``heading_noise_deg`` -- heading noise 1-sigma, deg, >= 0;
      ``heading_deviation_deg`` -- heading deviation bound after correction, deg, >= 0;
      ``declination_deg`` -- magnetic declination, deg east;
    * ``compass_cal`` -- a swing calibration file; ``compass_fit`` -- ``auto``,
      ``ellipse``, ``swing``, ``gnss-course`` or ``none``;
    * ``geodesy`` -- the ENU conversion of the fixes (``wgs84``);
    * ``use_gnss``, ``use_gnss_velocity``, ``use_velocity``, ``use_attitude``,
      ``use_gnss_altitude`` -- use that stream (all True).

    The smoother and the windows:

    * ``tol`` -- the smoother's convergence tolerance (relative), > 0;
    * ``max_sweeps`` -- the smoother's sweeps at most, >= 1;
    * ``max_windows`` -- windows per averaging time at most, >= 1.
    """

    alpha: float = DEFAULT_ALPHA
    imu_stamp: str = "end"
    imu_spec: str | None = None
    accel_turn_on: float | None = None
    gyro_turn_on: float | None = None
    scale: float | None = None
    misalignment_deg: float | None = None
    flicker_tau_range_s: tuple[float, float] | None = None
    max_speed: float | None = None
    max_accel: float | None = None
    max_jerk: float | None = None
    max_rate_dps: float | None = None
    max_tilt_deg: float | None = None
    max_ang_accel_dps2: float | None = None
    lateral_speed_bound_mps: float | None = None
    vertical_speed_bound_mps: float | None = None
    gnss_cep_m: float | None = None
    default_hdop: float | None = None
    gnss_vel_sigma: float | None = None
    velocity_bound: float | None = None
    attitude_bound_deg: float | None = None
    heading_noise_deg: float | None = None
    heading_deviation_deg: float | None = None
    declination_deg: float | None = None
    compass_cal: str | Path | None = None
    compass_fit: str | None = None
    geodesy: str = "wgs84"
    use_gnss: bool = True
    use_gnss_velocity: bool = True
    use_velocity: bool = True
    use_attitude: bool = True
    use_gnss_altitude: bool = True
    reverses: bool = False
    tol: float = 1e-3
    max_sweeps: int = 200
    max_windows: int = 2048

    def __post_init__(self) -> None:
        # None stands for the default of a field that has one (as in a keyword call)
        for f in fields(self):
            if getattr(self, f.name) is None and f.default is not None:
                object.__setattr__(self, f.name, f.default)
        _validate(self)


#: the options that must be positive, and those that must be non-negative (when given)
_POSITIVE = ("max_speed", "max_accel", "max_jerk", "max_rate_dps", "max_ang_accel_dps2",
             "gnss_cep_m", "default_hdop", "tol")
_NON_NEGATIVE = ("accel_turn_on", "gyro_turn_on", "scale", "misalignment_deg", "max_tilt_deg",
                 "lateral_speed_bound_mps", "vertical_speed_bound_mps", "gnss_vel_sigma",
                 "velocity_bound", "attitude_bound_deg", "heading_noise_deg",
                 "heading_deviation_deg")


def _validate(o: FullOptions) -> None:
    """Bad values refused (:class:`OptionError`, naming the option as on the command line)."""
    a = o.alpha
    if not (isinstance(a, int | float) and 0 < a < 1):
        raise OptionError(f"--alpha must lie in (0, 1), got {a!r}")
    for name in _POSITIVE:
        v = getattr(o, name)
        if v is not None and not (math.isfinite(float(v)) and float(v) > 0):
            raise OptionError(f"--{name.replace('_', '-')} must be positive, got {v!r}")
    for name in _NON_NEGATIVE:
        v = getattr(o, name)
        if v is not None and not (math.isfinite(float(v)) and float(v) >= 0):
            raise OptionError(f"--{name.replace('_', '-')} must be >= 0, got {v!r}")
    if o.scale is not None and o.scale >= 0.5:
        raise OptionError("--scale is a fraction (0.01 = 1 %) below 0.5")
    if o.imu_stamp not in IMU_STAMPS:
        raise OptionError(f"--imu-stamp must be end, start or centre, got {o.imu_stamp!r}")
    if int(o.max_windows) < 1 or int(o.max_sweeps) < 1:
        raise OptionError("max_windows and max_sweeps must be >= 1")


#: the names of the options of mode full
FULL_OPTION_NAMES = tuple(f.name for f in fields(FullOptions))


def check_options(opts: Mapping[str, Any] | FullOptions, settings: Any = None) -> FullOptions:
    """The options of mode full from keywords (``None``: the default), unknown names and
    bad values refused (:class:`OptionError`); a :class:`FullOptions` is returned as is.
    With a drive's ``settings`` (:class:`~imubounds.io.drive.DriveSettings`), an
    ``imu_stamp`` not given is drive.yaml's ``imu.sample_time`` when it states one."""
    if isinstance(opts, FullOptions):
        return opts
    unknown = set(opts) - set(FULL_OPTION_NAMES)
    if unknown:
        raise OptionError(
            f"unknown option(s) for mode full: {', '.join(sorted(unknown))}; "
            f"known: {', '.join(sorted(FULL_OPTION_NAMES))}"
        )
    given = {k: v for k, v in opts.items() if v is not None}
    sample_time = getattr(getattr(settings, "imu", None), "sample_time", None)
    if "imu_stamp" not in opts and sample_time in IMU_STAMPS:
        given["imu_stamp"] = sample_time
    return FullOptions(**given)
