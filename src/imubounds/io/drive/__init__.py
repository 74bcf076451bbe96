"""The drive-log model: every sensor stream of a trip in SI units, plus its settings.

Every drive reader (the generic layout of :mod:`imubounds.io.drive.layout`, VN-100,
comma2k19, ROS bags, NMEA, ULog, the simulator) produces a :class:`Drive`; the
dynamic estimator consumes nothing else.

Frames and units (see :mod:`imubounds.frames`):

* time ``t`` in s on one clock shared by every stream;
* IMU in the **vehicle body frame FLU** (x forward, y left, z up), after the
  mount rotation ``imu_axes`` of the drive's settings: ``accel`` specific force
  in m/s^2, ``gyro`` angular rate in rad/s;
* GNSS geodetic WGS-84 (degrees, m), velocities in m/s (north, east), course in
  rad clockwise from north;
* body velocity (DVL, wheel or CAN speed) in m/s along body x, y, z;
* heading in rad clockwise from north (compass convention);
* magnetometer in body FLU axes (any unit: only directions are used);
* attitude: roll (positive right side down), pitch (positive nose up), yaw
  (compass convention), rad;
* truth (optional, for simulations and post-processed references): ENU metres
  of ``truth_origin`` or geodetic degrees, heading in rad clockwise from north,
  body velocities in m/s.

Streams that a log does not have are ``None``; columns that a stream does not
have are ``None`` (never zeros). Values missing in some rows are NaN.

The package reads drives: this module holds the model (:class:`Drive`, its streams and
:class:`DriveSettings`); :mod:`.readers` has :func:`~imubounds.io.drive.readers.read_drive`,
the one entry point; :mod:`.layout` the generic folder layout; :mod:`.settings` drive.yaml;
:mod:`.validate` the checks every reader's output goes through; :mod:`.mount` the mount
rotation and time matching every reader shares. It imports none of them, so that they
can import the model from here.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from imubounds.errors import InputError

Array = np.ndarray


def _len(name: str, a: Array | None, n: int, src: str) -> None:
    if a is not None and a.shape[0] != n:
        raise InputError(f"{src}: {name} has {a.shape[0]} rows, its time column has {n}")


@dataclass
class ImuStream:
    """IMU samples in the vehicle body frame FLU: ``accel`` (n, 3) m/s^2, ``gyro`` (n, 3) rad/s.

    A column the log does not have is NaN (e.g. a yaw-rate-only gyro).
    """

    t: Array
    accel: Array
    gyro: Array
    input_units: dict[str, str] = field(default_factory=dict)

    @property
    def rate_hz(self) -> float:
        """Median sample rate in Hz."""
        return float(1.0 / np.median(np.diff(self.t)))

    def check(self, src: str) -> None:
        n = self.t.shape[0]
        for name in ("accel", "gyro"):
            a = getattr(self, name)
            if a.shape != (n, 3):
                raise InputError(f"{src}: IMU {name} must be (n, 3) matching its {n} time stamps")


@dataclass
class GnssStream:
    """GNSS fixes: position (deg, m), quality, and velocity where the receiver gives it.

    ``fix`` is False for rows without a fix (kept for counting, never used).
    ``hdop`` (dimensionless) and ``h_acc_m`` (1-sigma accuracy in m of each
    horizontal axis: u-blox ``hAcc``, PX4 ``eph``, the square root of a ROS
    NavSatFix east/north covariance) are NaN where not reported.
    ``speed_mps``/``course_rad`` (clockwise from north) and
    ``vel_n_mps``/``vel_e_mps`` are ``None`` when absent; ``vel_acc_mps`` is
    the receiver's 1-sigma accuracy of each horizontal velocity component
    (NaN or ``None`` where not reported); ``v_acc_m`` the 1-sigma accuracy of the
    altitude (u-blox ``vAcc``, PX4 ``epv``, the square root of a ROS NavSatFix up
    variance; NaN or ``None`` where not reported).
    """

    t: Array
    lat_deg: Array
    lon_deg: Array
    alt_m: Array | None = None
    hdop: Array | None = None
    h_acc_m: Array | None = None
    fix: Array | None = None
    speed_mps: Array | None = None
    course_rad: Array | None = None
    vel_n_mps: Array | None = None
    vel_e_mps: Array | None = None
    vel_acc_mps: Array | None = None
    v_acc_m: Array | None = None

    @property
    def has_velocity(self) -> bool:
        """True if the stream carries a horizontal velocity (NE components or speed+course)."""
        return (self.vel_n_mps is not None and self.vel_e_mps is not None) or (
            self.speed_mps is not None and self.course_rad is not None
        )

    def velocity_ne(self) -> tuple[Array, Array] | None:
        """(north, east) velocity in m/s from whichever form the receiver gave, or None."""
        if self.vel_n_mps is not None and self.vel_e_mps is not None:
            return self.vel_n_mps, self.vel_e_mps
        if self.speed_mps is not None and self.course_rad is not None:
            return self.speed_mps * np.cos(self.course_rad), self.speed_mps * np.sin(
                self.course_rad
            )
        return None

    def usable(self) -> Array:
        """Rows with a fix and finite latitude and longitude."""
        ok = np.isfinite(self.lat_deg) & np.isfinite(self.lon_deg)
        if self.fix is not None:
            ok &= self.fix.astype(bool)
        return np.asarray(ok, dtype=bool)

    def check(self, src: str) -> None:
        n = self.t.shape[0]
        for name in (
            "lat_deg",
            "lon_deg",
            "alt_m",
            "hdop",
            "h_acc_m",
            "fix",
            "speed_mps",
            "course_rad",
            "vel_n_mps",
            "vel_e_mps",
            "vel_acc_mps",
            "v_acc_m",
        ):
            _len(f"GNSS {name}", getattr(self, name), n, src)


@dataclass
class VelocityStream:
    """Body-frame velocity (m/s) from a Doppler velocity log, wheel or CAN speed.

    ``kind`` is ``"dvl"``, ``"wheel"``, ``"can"`` or ``"odometry"``. ``v_mps``
    and ``w_mps`` are ``None`` when the sensor gives forward speed only.
    """

    t: Array
    u_mps: Array
    v_mps: Array | None = None
    w_mps: Array | None = None
    kind: str = "dvl"

    def check(self, src: str) -> None:
        n = self.t.shape[0]
        for name in ("u_mps", "v_mps", "w_mps"):
            _len(f"velocity {name}", getattr(self, name), n, src)


@dataclass
class HeadingStream:
    """Heading (rad, clockwise from north) from a compass, dual-antenna GNSS or an AHRS.

    ``source`` says which (``"compass"``, ``"magnetometer"`` once calibrated,
    ``"gnss"``, ``"ahrs"``); an AHRS yaw uses the IMU's own gyros and is not
    independent of it. ``true_north`` is True when the heading is referred to
    true north (NMEA HDT, a GNSS heading, a ROS/PX4 orientation in a
    geographic frame); False for a magnetic heading, to which the drive's
    ``heading.declination_deg`` is added.
    """

    t: Array
    heading_rad: Array
    source: str = "compass"
    true_north: bool = False

    def check(self, src: str) -> None:
        _len("heading", self.heading_rad, self.t.shape[0], src)


@dataclass
class MagStream:
    """Raw magnetometer (n, 3) in body FLU axes; any unit (``unit`` says which)."""

    t: Array
    mag: Array
    unit: str = "unknown"

    def check(self, src: str) -> None:
        if self.mag.shape != (self.t.shape[0], 3):
            raise InputError(f"{src}: magnetometer must be (n, 3) matching its time stamps")


@dataclass
class AttitudeStream:
    """Roll and pitch (rad; roll positive right side down, pitch positive nose up) and
    optionally yaw (rad, clockwise from north) of the vehicle body."""

    t: Array
    roll_rad: Array
    pitch_rad: Array
    yaw_rad: Array | None = None
    source: str = "ahrs"

    def check(self, src: str) -> None:
        n = self.t.shape[0]
        for name in ("roll_rad", "pitch_rad", "yaw_rad"):
            _len(f"attitude {name}", getattr(self, name), n, src)


@dataclass
class Truth:
    """Reference trajectory (simulation truth or post-processed solution).

    ``east_m``/``north_m`` are ENU metres of ``origin`` (lat_deg, lon_deg, alt_m);
    readers that have geodetic truth convert it with the drive's geodesy.
    ``extra`` holds any further true quantities by name in SI (e.g.
    ``accel_x``, ``gyro_z``, ``bias_accel_x``, ``roll_rad``, ``pitch_rad``).
    """

    t: Array
    east_m: Array
    north_m: Array
    origin: tuple[float, float, float]
    heading_rad: Array | None = None
    u_mps: Array | None = None
    v_mps: Array | None = None
    extra: dict[str, Array] = field(default_factory=dict)


#: Default GPS CEP in m at HDOP 1 (the paper's receiver); the one place of this default.
DEFAULT_CEP_M = 3.0
#: HDOP used for fixes that do not carry one.
DEFAULT_HDOP = 1.0


@dataclass
class GnssSettings:
    """GNSS error model. ``cep_m``: CEP at HDOP 1 (m), used when a fix has no
    ``h_acc_m``; ``default_hdop`` when a fix has neither; ``vel_sigma_mps``:
    1-sigma per velocity component when the receiver reports none."""

    cep_m: float = DEFAULT_CEP_M
    default_hdop: float = DEFAULT_HDOP
    vel_sigma_mps: float = 0.1
    #: 1-sigma of each fix's altitude error as a multiple of its horizontal 1-sigma per
    #: axis (the pitch from GNSS altitude, docs/dynamic-method.md section 3a)
    vertical_sigma_ratio: float = 1.5
    #: clock offset of the GNSS stamps against the IMU (true time = stamp - offset, s)
    #: and a bound on what remains of it (s); the dynamic estimator applies and budgets
    #: them (docs/dynamic-method.md, timing)
    time_offset_s: float = 0.0
    time_offset_bound_s: float | None = None


@dataclass
class VelocitySettings:
    """Body-velocity sensor bound: |error| <= ``bound_mps`` + ``scale`` x |speed|."""

    bound_mps: float = 0.1
    scale: float = 0.0


@dataclass
class HeadingSettings:
    """Compass: ``deviation_deg`` bound after calibration (None: from the calibration's
    residual), ``declination_deg`` (east positive) added to magnetic headings,
    ``calibration``: the swing calibration, a CSV file of (measured, reference) pairs
    or (in memory, e.g. a simulated drive) those pairs as an (n, 2) array in degrees;
    ``noise_deg`` 1-sigma.

    ``sensor``: what ``heading.csv``'s ``heading_deg`` comes from (``"compass"``,
    ``"gnss"`` for a dual-antenna receiver, ``"ahrs"`` for a yaw that uses the
    IMU's gyros); ``reference``: ``"magnetic"`` or ``"true"``, its north.
    ``fit``: how the compass is calibrated (``"auto"``: the swing file if given,
    else an ellipse fit of the raw magnetometer, else ``deviation_deg``;
    ``"ellipse"``, ``"swing"``, ``"gnss-course"`` (explicit only: the heading
    is then not independent of the GNSS) or ``"none"``).
    ``alignment_deg``: bound on the constant heading offset that no
    self-calibration can see (magnetometer yaw misalignment, rotational soft
    iron); ``use``: which stream gives the heading (``"auto"``: an
    independent heading stream, else the magnetometer, else an AHRS yaw;
    ``"heading"``, ``"mag"``, ``"attitude"``).
    ``errors``: ``"estimate"`` (the compass error model, constant offset and harmonics 1
    and 2, estimated against the GNSS course and the terms the data detect taken off:
    ``course_check.estimate_heading_model``) or ``"stated"`` (the stated bounds only,
    checked).
    """

    deviation_deg: float | None = None
    declination_deg: float = 0.0
    calibration: str | np.ndarray | None = None
    noise_deg: float = 0.5
    sensor: str = "compass"
    reference: str = "magnetic"
    fit: str = "auto"
    alignment_deg: float = 0.0
    use: str = "auto"
    errors: str = "estimate"
    #: clock offset of the heading stamps (true time = stamp - offset, s) and its bound
    time_offset_s: float = 0.0
    time_offset_bound_s: float | None = None


@dataclass
class AttitudeSettings:
    """Bound on the attitude stream's roll/pitch error (deg)."""

    bound_deg: float = 1.0


@dataclass
class VehicleSettings:
    """What the vehicle can do (bounds used to make the model error explicit).

    ``kind``: ``"ground"``, ``"marine"`` or ``"air"``; ``lateral_speed_bound_mps``:
    non-holonomic |v| bound for wheeled vehicles (None: not assumed);
    ``vertical_speed_bound_mps``: |w| bound, the IMU's velocity along its body z axis
    (None: the kind's default, 0.5 m/s for a ground vehicle, the speed bound otherwise);
    ``max_tilt_deg``: roll/pitch bound when there is no attitude stream.
    """

    kind: str = "ground"
    max_speed_mps: float = 70.0
    max_accel_mps2: float = 10.0
    max_jerk_mps3: float = 20.0
    max_yaw_rate_dps: float = 90.0
    max_tilt_deg: float = 10.0
    lateral_speed_bound_mps: float | None = None
    vertical_speed_bound_mps: float | None = None


@dataclass
class ImuSettings:
    """The IMU's noise: a static ``noise_json``, a ``preset`` name, or datasheet figures.

    Datasheet keys and units as ``imubounds dynamic --imu-spec``: ``accel_nd``
    m/s^2/sqrt(Hz), ``accel_bs`` m/s^2 (in-run bias stability), ``gyro_nd``
    deg/s/sqrt(Hz), ``gyro_bs`` deg/s; optional turn-on bias, scale factor and
    misalignment.

    ``accel_bias_drift_mps2`` / ``gyro_bias_drift_dps`` bound the in-run bias
    wander (the bias minus its turn-on value) averaged over any window of at least
    ``bias_drift_window_s`` over the whole trip; with the turn-on bound they bound
    the bias: ``|b| <= turn_on + drift``. ``sample_time`` says which instant of its
    averaging period an IMU sample's ``time_s`` marks: ``"end"`` (the sample is the
    mean over ``[t - dt, t]``), ``"centre"`` or ``"start"``; None: not stated.
    """

    noise_json: str | None = None
    preset: str | None = None
    accel_nd: float | None = None
    accel_bs: float | None = None
    gyro_nd: float | None = None
    gyro_bs: float | None = None
    accel_turn_on_mps2: float | None = None
    gyro_turn_on_dps: float | None = None
    scale_factor: float | None = None
    misalignment_deg: float | None = None
    accel_bias_drift_mps2: float | None = None
    gyro_bias_drift_dps: float | None = None
    bias_drift_window_s: float | None = None
    sample_time: str | None = None
    #: rate random walk K: ``accel_rrw`` m/s^2/sqrt(s), ``gyro_rrw`` deg/s/sqrt(s)
    accel_rrw: float | None = None
    gyro_rrw: float | None = None


@dataclass
class DriveSettings:
    """Everything ``drive.yaml`` can say (see the docs' drive-layout page).

    ``imu_axes`` maps body axes (x forward, y left, z up) to signed IMU axes,
    e.g. ``("x", "-z", "y")``: body x is IMU x, body y is IMU -z, body z is IMU y.
    ``mag_axes`` does the same for the magnetometer when it is mounted apart
    from the IMU (None: it shares the IMU's axes and ``imu_axes``).
    ``assumed`` lists, in words, every setting that was not given and took its
    documented default; outputs repeat it. ``defaulted`` lists the same
    settings as dotted keys (``"gnss.cep_m"``), so that a writer can leave them
    out of ``drive.yaml`` and a reader lists them as assumed again.
    """

    imu_axes: tuple[str, str, str] = ("x", "y", "z")
    mag_axes: tuple[str, str, str] | None = None
    imu: ImuSettings = field(default_factory=ImuSettings)
    gnss: GnssSettings = field(default_factory=GnssSettings)
    velocity: VelocitySettings = field(default_factory=VelocitySettings)
    heading: HeadingSettings = field(default_factory=HeadingSettings)
    attitude: AttitudeSettings = field(default_factory=AttitudeSettings)
    vehicle: VehicleSettings = field(default_factory=VehicleSettings)
    lever_arm_m: tuple[float, float, float] | None = None
    assumed: list[str] = field(default_factory=list)
    defaulted: list[str] = field(default_factory=list)


@dataclass
class Drive:
    """A drive log: sensor streams in SI on one clock, and the settings that bound them.

    ``warnings`` are problems found in the input (each a one-line message, with
    its count); ``counts`` holds the same counts by key (e.g. ``gnss_no_fix``,
    ``heading_nan``) for outputs; ``notes`` are facts an output must repeat
    (the mount rotation applied, a lever arm that is ignored, where a default
    came from).
    """

    imu: ImuStream | None = None
    gnss: GnssStream | None = None
    velocity: VelocityStream | None = None
    heading: HeadingStream | None = None
    mag: MagStream | None = None
    attitude: AttitudeStream | None = None
    truth: Truth | None = None
    settings: DriveSettings = field(default_factory=DriveSettings)
    source: str = "<memory>"
    layout: str = "memory"
    warnings: list[str] = field(default_factory=list)
    meta: dict[str, Any] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    counts: dict[str, int] = field(default_factory=dict)

    def warn(self, key: str, count: int, message: str) -> None:
        """Record a counted warning: ``counts[key] += count`` and the message."""
        if count <= 0:
            return
        self.counts[key] = self.counts.get(key, 0) + int(count)
        self.warnings.append(message)

    def time_range(self, name: str) -> tuple[float, float] | None:
        """(first, last) time stamp of a stream in s, or None if it is absent or empty."""
        s = getattr(self, name)
        if s is None or s.t.size == 0:
            return None
        return float(s.t[0]), float(s.t[-1])

    def __repr__(self) -> str:
        return (
            f"Drive(source={self.source!r}, layout={self.layout!r}, streams={self.streams()}, "
            f"warnings={len(self.warnings)})"
        )

    def to_dict(self) -> dict[str, Any]:
        """A JSON-able description of the drive (not the samples): source, layout, the
        streams present with their sample count and time span (s), the IMU rate (Hz),
        warnings, notes and the settings that were assumed (the ``input`` block of
        dynamic.json, plus the spans)."""
        spans: dict[str, Any] = {}
        for name in self.streams():
            s = getattr(self, name)
            rng = self.time_range(name)
            spans[name] = {
                "samples": int(s.t.shape[0]),
                "t_first_s": None if rng is None else rng[0],
                "t_last_s": None if rng is None else rng[1],
            }
        return {
            "source": self.source,
            "layout": self.layout,
            "streams": spans,
            "imu_rate_hz": self.imu.rate_hz if self.imu is not None and self.imu.t.size > 1
            else None,
            "warnings": list(self.warnings),
            "notes": list(self.notes),
            "settings_assumed": list(self.settings.assumed),
        }

    def streams(self) -> list[str]:
        """Names of the streams present."""
        return [
            n
            for n in ("imu", "gnss", "velocity", "heading", "mag", "attitude", "truth")
            if getattr(self, n) is not None
        ]

    def check(self) -> None:
        """Shapes, finite and strictly increasing time stamps; a missing IMU or no aiding
        sensor at all is an :class:`InputError` naming what is expected."""
        src = self.source
        if self.imu is None:
            raise InputError(
                f"{src}: no IMU: the drive needs imu.csv (time_s and gyro_{{x,y,z}}_<unit>, "
                "accel_{x,y,z}_<unit> columns) or an IMU topic"
            )
        if (
            self.gnss is None
            and self.velocity is None
            and self.heading is None
            and self.mag is None
        ):
            raise InputError(
                f"{src}: no aiding sensor: give gnss.csv (time_s, lat_deg, lon_deg), "
                "velocity.csv (time_s, u_mps) or heading.csv (time_s, heading_deg or mag_x/y/z)"
            )
        for name in ("imu", "gnss", "velocity", "heading", "mag", "attitude"):
            s = getattr(self, name)
            if s is None:
                continue
            t = s.t
            if t.ndim != 1 or t.shape[0] < 1:
                raise InputError(f"{src}: the {name} stream has no samples")
            if not np.all(np.isfinite(t)):
                i = int(np.flatnonzero(~np.isfinite(t))[0])
                raise InputError(f"{src}: {name} time_s is NaN or infinite at row {i + 1}")
            bad = np.flatnonzero(np.diff(t) <= 0)
            if bad.size:
                k = int(bad[0])
                raise InputError(
                    f"{src}: {name} time_s is not strictly increasing at row {k + 2} "
                    f"(t={t[k]:.6f} then {t[k + 1]:.6f} s); sort the file or drop duplicate rows"
                )
            s.check(src)
