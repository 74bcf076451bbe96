"""Settings of a simulated trip: :class:`ScenarioConfig`, the named variants and sensor faults.

Every figure is SI unless its name says otherwise (``_deg``, ``_uT``). The
defaults are the paper's experiment (METHOD.md 3.5): a closed, flat 9.4 km trip
in 792 s around a rounded rectangle, an Xsens MTx-grade IMU at 100 Hz with
turn-on bias, in-run bias instability and white noise, GNSS (CEP 3 m, HDOP about
0.8) at 1 Hz and a compass with a one-cycle deviation at 1 Hz.
"""

from __future__ import annotations

import dataclasses
import math
import re
from dataclasses import dataclass, field
from typing import Any

from imubounds.errors import OptionError
from imubounds.io.log import IMU_CHANNELS
from imubounds.presets import preset_names

#: Aiding streams the simulator can produce (``--aiding``).
AIDING_STREAMS: tuple[str, ...] = (
    "gnss",
    "gnss-vel",
    "compass",
    "mag",
    "attitude",
    "dvl",
    "wheel",
)
#: The paper's sensors: GNSS positions and a compass.
DEFAULT_AIDING: tuple[str, ...] = ("gnss", "compass")

#: Named variants: the fields each one sets on top of the paper trip, and what it is.
VARIANTS: dict[str, tuple[dict[str, Any], str]] = {
    "paper": ({}, "the paper's flat closed trip: GNSS positions at 1 Hz and a compass"),
    "hills": (
        {
            "hill_amplitude_m": 15.0,
            "bank_deg": 2.0,
            "roll_gain_deg_per_mps2": 0.5,
            "aiding": ("gnss", "compass", "attitude"),
        },
        "hills (altitude +-19 m, pitch up to about 6 deg), road bank and body roll in the "
        "corners; an attitude (roll/pitch) stream is added",
    ),
    "corners": (
        {"corner_length_m": 20.0, "laps": 3},
        "sharp corners: 12 right-angle turns of 20 m arc, the vehicle slows to keep the "
        "lateral acceleration under 4 m/s^2 (yaw rate up to about 45 deg/s)",
    ),
    "gnss10": ({"gps_rate_hz": 10.0}, "GNSS at 10 Hz"),
    "gnss-pos": ({"aiding": ("gnss",)}, "GNSS positions only (no heading, no velocity)"),
    "gnss-posvel": (
        {"aiding": ("gnss", "gnss-vel")},
        "GNSS position and velocity only (no heading)",
    ),
    "dvl-heading": (
        {"aiding": ("dvl", "compass")},
        "no GNSS: body velocity from a Doppler velocity log and a compass",
    ),
    "outliers": ({"gps_outlier_fraction": 0.02}, "2 % of the GNSS fixes are gross outliers"),
}

_FAULT = re.compile(
    r"^\s*(?P<ch>[a-z_]+)\s*:\s*(?P<kind>bias|scale)\s*=\s*(?P<val>[^@]+?)\s*"
    r"(?:@\s*(?P<t0>.+?))?\s*$"
)


@dataclass(frozen=True)
class Fault:
    """A sensor fault from ``t0_s`` on: ``bias`` adds ``value`` (m/s^2 or rad/s) to the
    channel, ``scale`` multiplies its true signal by ``1 + value``."""

    channel: str
    kind: str
    value: float
    t0_s: float = 0.0

    def __post_init__(self) -> None:
        if self.channel not in IMU_CHANNELS:
            raise OptionError(
                f"fault channel {self.channel!r}: use one of {', '.join(IMU_CHANNELS)}"
            )
        if self.kind not in ("bias", "scale"):
            raise OptionError(f"fault kind {self.kind!r}: use bias or scale")
        if not math.isfinite(self.value):
            raise OptionError(f"fault value must be a finite number, got {self.value!r}")
        if not (math.isfinite(self.t0_s) and self.t0_s >= 0):
            raise OptionError(f"fault start must be a time >= 0 s, got {self.t0_s!r}")

    def label(self) -> str:
        return f"{self.channel}:{self.kind}={self.value:g}@{self.t0_s:g}"


def parse_fault(text: str) -> Fault:
    """``CHANNEL:bias=VALUE[@T0]`` or ``CHANNEL:scale=VALUE[@T0]`` -> :class:`Fault`.

    VALUE in SI (m/s^2 or rad/s for a bias, a fraction for a scale error); T0 in s
    from the start of the trip (0 if left out).
    """
    m = _FAULT.match(text.lower())
    if not m:
        raise OptionError(
            f"--fault {text!r}: write CHANNEL:bias=VALUE[@T0] or CHANNEL:scale=VALUE[@T0], "
            "e.g. accel_x:bias=0.3@396"
        )
    ch = m.group("ch")
    if ch not in IMU_CHANNELS:
        raise OptionError(
            f"--fault {text!r}: unknown channel {ch!r}; use one of {', '.join(IMU_CHANNELS)}"
        )
    try:
        val = float(m.group("val"))
        t0 = float(m.group("t0")) if m.group("t0") is not None else 0.0
    except ValueError:
        raise OptionError(
            f"--fault {text!r}: VALUE and T0 must be numbers (SI units, T0 in s)"
        ) from None
    if not math.isfinite(val):
        raise OptionError(f"--fault {text!r}: VALUE must be a finite number")
    if not (math.isfinite(t0) and t0 >= 0):
        raise OptionError(f"--fault {text!r}: T0 must be a time >= 0 s")
    return Fault(ch, m.group("kind"), val, t0)


@dataclass
class ScenarioConfig:
    """Settings of a simulated trip (SI units unless the name says otherwise).

    Use :meth:`for_variant` for a named variant (see :data:`VARIANTS`).
    """

    scenario: str = "paper"
    variant: str = "paper"
    seed: int = 0
    # trip
    duration_s: float = 792.0
    distance_m: float = 9400.0  # horizontal path length
    ramp_s: float = 20.0  # start and stop speed ramps
    corner_length_m: float = 150.0  # arc length of each right-angle corner
    laps: int = 1
    aspect: float = 1.5  # long side / short side of the rounded rectangle
    origin: tuple[float, float, float] = (23.55, 87.29, 80.0)  # lat_deg, lon_deg, alt_m
    heading0_deg: float = 90.0  # compass heading at the start (90 = east)
    max_lateral_accel_mps2: float = 4.0  # the vehicle slows in corners to stay under this
    max_long_accel_mps2: float = 2.0  # peak acceleration of the corner speed ramps
    hill_amplitude_m: float = 0.0  # 0: flat
    bank_deg: float = 0.0  # road bank (roll) amplitude
    roll_gain_deg_per_mps2: float = 0.0  # body roll per m/s^2 of lateral acceleration
    #: road bumps: the body heaves by ``H sin^4(pi x)`` (x from 0 to 1 over
    #: ``bump_duration_s``) every ``bump_every_s``, its attitude kept (the suspension's
    #: heave); 0: none. The body velocity gains ``dz/dt (sin theta, cos theta sin phi,
    #: cos theta cos phi)``.
    bump_height_m: float = 0.0
    bump_duration_s: float = 0.4
    bump_every_s: float = 10.0
    # rates
    rate_hz: float = 100.0  # IMU
    gps_rate_hz: float = 1.0
    compass_rate_hz: float = 1.0
    velocity_rate_hz: float = 10.0
    attitude_rate_hz: float = 10.0
    truth_rate_hz: float = 10.0
    aiding: tuple[str, ...] = DEFAULT_AIDING
    # IMU
    imu_preset: str = "mtx"
    #: a noise.json of ``imubounds static``: the IMU's noise per axis (N, B as flicker over
    #: ``bias_tau_range_s``, K, and Q/R where the fit resolved them) instead of the preset's
    imu_noise: str | None = None
    noise_scale: float = 1.0  # multiplies N, B, K and the turn-on bias (0: noiseless IMU)
    imu_bias: bool = True  # turn-on bias and in-run bias instability
    turn_on_scale: float = 1.0  # turn-on sigma = this x (preset turn-on bias, else B)
    bias_tau_range_s: tuple[float, float] = (1.0, 1000.0)  # flicker range of B
    scale_error: float = 0.0  # 1-sigma scale-factor error (fraction), per channel
    misalignment_deg: float = 0.0  # 1-sigma cross-axis misalignment, per axis pair
    faults: tuple[Fault, ...] = ()
    # GNSS
    gps_cep_m: float = 3.0
    hdop_mean: float = 0.8
    gps_vel_sigma_mps: float = 0.1
    gps_h_acc: bool = True  # write h_acc_m (= DRMS of the fix)
    gps_outlier_fraction: float = 0.0
    gps_outlier_m: float = 40.0
    # compass and magnetometer
    compass_dev_deg: tuple[float, float, float] = (1.0, 2.5, -1.5)  # A, B, C
    compass_noise_deg: float = 0.3
    mag_field_uT: float = 48.0
    mag_inclination_deg: float = 40.0
    mag_hard_iron_uT: float = 10.0  # 1-sigma per axis
    mag_soft_iron: float = 0.03  # 1-sigma of the symmetric soft-iron matrix - identity
    mag_noise_uT: float = 0.05
    # body velocity
    dvl_sigma_mps: float = 0.02
    wheel_sigma_mps: float = 0.05
    wheel_scale_sigma: float = 0.003
    lateral_speed_bound_mps: float = 0.2
    #: the wheel/DVL time stamps are this late (s): the stream reports the velocity of
    #: ``lag`` seconds before its stamp (a lagging odometry), not stated in drive.yaml
    velocity_lag_s: float = 0.0
    # attitude
    attitude_sigma_deg: float = 0.1
    #: > 0: the attitude stream carries an AHRS yaw with this error sigma (deg), used as
    #: the heading when there is no compass
    attitude_yaw_sigma_deg: float = 0.0
    # the IMU's mount: imu_axes[i] names the sensor axis along body axis i (drive.yaml
    # imu_axes); the written imu.csv is in the sensor's axes (the in-memory drive keeps
    # the body axes)
    imu_axes: tuple[str, str, str] = ("x", "y", "z")
    #: vehicle.kind written to drive.yaml (ground, air, marine): a vehicle other than
    #: ground is not held to w = 0 by the estimator
    vehicle_kind: str = "ground"
    # probability level of every stated bound (whole trip, per stream)
    alpha: float = 0.01
    # every error drawn inside its stated bound
    bounded: bool = False
    extra: dict[str, float] = field(default_factory=dict)

    @classmethod
    def for_variant(cls, name: str, **overrides: Any) -> ScenarioConfig:
        """The paper trip with variant ``name``'s settings, then ``overrides``."""
        if name not in VARIANTS:
            raise OptionError(f"unknown variant {name!r}; use one of {', '.join(VARIANTS)}")
        kw: dict[str, Any] = dict(VARIANTS[name][0])
        kw.update(overrides)
        kw["variant"] = name
        return cls(**kw)

    def to_dict(self) -> dict[str, Any]:
        d = dataclasses.asdict(self)
        d["faults"] = [f.label() for f in self.faults]
        d["aiding"] = list(self.aiding)
        d["imu_axes"] = list(self.imu_axes)
        return d

    def _check_mount(self) -> None:
        """The vehicle kind and the IMU mount (``imu_axes`` a proper rotation)."""
        from imubounds.errors import InputError
        from imubounds.frames import axes_matrix

        if self.vehicle_kind not in ("ground", "air", "marine"):
            raise OptionError(f"vehicle kind {self.vehicle_kind!r}: use ground, air or marine")
        try:
            axes_matrix(self.imu_axes)
        except InputError as err:
            raise OptionError(f"--imu-axes: {err}") from None

    def check(self) -> None:
        """Raise :class:`OptionError` naming the first inconsistent setting."""
        if self.scenario != "paper":
            raise OptionError(f"--scenario {self.scenario!r}: the only base scenario is paper")
        if self.variant not in VARIANTS:
            raise OptionError(f"unknown variant {self.variant!r}; use one of {', '.join(VARIANTS)}")
        for name in (
            "duration_s",
            "distance_m",
            "rate_hz",
            "gps_rate_hz",
            "compass_rate_hz",
            "velocity_rate_hz",
            "attitude_rate_hz",
            "truth_rate_hz",
            "gps_cep_m",
            "hdop_mean",
            "corner_length_m",
            "aspect",
            "max_lateral_accel_mps2",
            "max_long_accel_mps2",
            "ramp_s",
            "bump_duration_s",
            "bump_every_s",
        ):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise OptionError(f"--{name.replace('_', '-')} must be a positive number, got {v}")
        for name in (
            "noise_scale",
            "hill_amplitude_m",
            "bank_deg",
            "roll_gain_deg_per_mps2",
            "turn_on_scale",
            "scale_error",
            "misalignment_deg",
            "gps_vel_sigma_mps",
            "gps_outlier_m",
            "compass_noise_deg",
            "mag_hard_iron_uT",
            "mag_soft_iron",
            "mag_noise_uT",
            "dvl_sigma_mps",
            "wheel_sigma_mps",
            "wheel_scale_sigma",
            "lateral_speed_bound_mps",
            "attitude_sigma_deg",
            "velocity_lag_s",
            "attitude_yaw_sigma_deg",
            "bump_height_m",
        ):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise OptionError(f"{name} must be a number >= 0, got {v}")
        if self.duration_s <= 2 * self.ramp_s:
            raise OptionError(
                f"--duration ({self.duration_s:g} s) must exceed twice the speed ramp "
                f"(2 x {self.ramp_s:g} s)"
            )
        if self.bump_every_s < self.bump_duration_s:
            raise OptionError(
                f"bump_every_s ({self.bump_every_s:g}) must be at least bump_duration_s "
                f"({self.bump_duration_s:g}): one bump at a time"
            )
        if not 0.0 <= self.gps_outlier_fraction < 1.0:
            raise OptionError(f"--gps-outliers must lie in [0, 1), got {self.gps_outlier_fraction}")
        if not 0.0 < self.alpha < 1.0:
            raise OptionError(f"alpha must lie in (0, 1), got {self.alpha}")
        self._check_mount()
        if self.laps < 1:
            raise OptionError(f"--laps must be at least 1, got {self.laps}")
        if self.imu_noise is not None:
            from imubounds.dynamic.scenario.imu_noise import load_imu_noise

            load_imu_noise(self)  # names the file and what is wrong with it
        elif self.imu_preset.lower() not in preset_names():
            raise OptionError(
                f"unknown IMU preset {self.imu_preset!r}; available: {', '.join(preset_names())}"
            )
        unknown = [a for a in self.aiding if a not in AIDING_STREAMS]
        if unknown:
            raise OptionError(
                f"--aiding: unknown stream {unknown[0]!r}; use any of {', '.join(AIDING_STREAMS)}"
            )
        if not self.aiding:
            raise OptionError("--aiding: give at least one aiding stream")
        if "dvl" in self.aiding and "wheel" in self.aiding:
            raise OptionError(
                "--aiding: dvl and wheel both give the drive's one body-velocity stream; choose one"
            )
        if "gnss-vel" in self.aiding and "gnss" not in self.aiding:
            raise OptionError("--aiding: gnss-vel needs gnss (velocity rides on the fixes)")
        lo, hi = self.bias_tau_range_s
        if not (0 < lo < hi and math.isfinite(hi)):
            raise OptionError(f"bias_tau_range_s must be 0 < lo < hi, got {self.bias_tau_range_s}")
        for f in self.faults:
            if not isinstance(f, Fault):
                raise OptionError(f"faults must be Fault objects, got {f!r}")
            if f.t0_s > self.duration_s:
                raise OptionError(
                    f"--fault {f.label()}: starts after the end of the trip ({self.duration_s:g} s)"
                )
        # every stream's epochs fall on the IMU sample grid
        used = {
            "gps_rate_hz": "gnss" in self.aiding,
            "compass_rate_hz": "compass" in self.aiding or "mag" in self.aiding,
            "velocity_rate_hz": "dvl" in self.aiding or "wheel" in self.aiding,
            "attitude_rate_hz": "attitude" in self.aiding,
            "truth_rate_hz": self.truth_rate_hz < self.rate_hz,
        }
        for name, in_use in used.items():
            if not in_use:
                continue
            r = getattr(self, name)
            ratio = self.rate_hz / r
            if ratio < 1 - 1e-9 or abs(ratio - round(ratio)) > 1e-6:
                raise OptionError(
                    f"--{name.replace('_hz', '').replace('_', '-')} ({r:g} Hz) must divide the "
                    f"IMU rate ({self.rate_hz:g} Hz) so its epochs fall on IMU samples"
                )
