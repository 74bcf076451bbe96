""":func:`simulate`: a trip with truth, as a :class:`~imubounds.io.drive.Drive` plus its record."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from imubounds.dynamic.scenario.aiding import AidingOutput, SampledTruth, simulate_aiding
from imubounds.dynamic.scenario.config import ScenarioConfig
from imubounds.dynamic.scenario.imu import CHANNELS, ImuErrors, imu_checks, simulate_errors
from imubounds.dynamic.scenario.record import Record
from imubounds.dynamic.scenario.trajectory import Trajectory
from imubounds.frames import model_to_compass
from imubounds.io.drive import (
    DEFAULT_HDOP,
    AttitudeSettings,
    Drive,
    DriveSettings,
    GnssSettings,
    HeadingSettings,
    ImuSettings,
    ImuStream,
    Truth,
    VehicleSettings,
    VelocitySettings,
)
from imubounds.units import DEG

Array = np.ndarray

#: Independent random streams, one per part of the simulation (adding a stream or
#: changing one part leaves the others' draws unchanged).
SEED_STREAMS: tuple[str, ...] = (
    "trajectory",
    "imu_white",
    "imu_drift",
    "imu_static",
    "gnss",
    "compass",
    "mag",
    "velocity",
    "attitude",
)

#: How the simulator stamps and frames its data (repeated in scenario.json).
CONVENTIONS: dict[str, str] = {
    "frames": "navigation ENU at the origin; body FLU (x forward, y left, z up); model heading "
    "CCW from east, compass heading clockwise from north; roll positive right side down, pitch "
    "positive nose up; body->ENU R = Rz(yaw) Ry(-pitch) Rx(roll)",
    "imu": "sample k at time_s = k/rate is the mean of the true specific force (body rate) over "
    "[time_s - 1/rate, time_s] plus its errors (drive.yaml imu.sample_time = end); gravity "
    "9.80665 m/s^2, specific force f = R^T (a - g_nav)",
    "aiding": "every aiding sample is of the truth at its time_s (instantaneous, no lever arm)",
    "truth": "truth.csv rows are instants; accel_*/gyro_* are the noiseless IMU sample stamped "
    "there (its period mean); bias_* the IMU bias (turn-on + drift) at that sample",
}


@dataclass
class SimResult:
    """A simulated trip: the :class:`Drive`, the :class:`Record` of inputs outside their stated
    bounds, and every true value.

    ``truth`` holds arrays at the IMU sample times (SI): ``t, east, north, up, vel_enu, acc_enu,
    roll, pitch, yaw`` (model heading, continuous), ``speed, accel_mean, gyro_mean`` (what a
    noiseless IMU reads) and ``bias`` (n, 6).
    """

    config: ScenarioConfig
    drive: Drive
    record: Record
    truth: dict[str, Array]
    imu_errors: ImuErrors
    aiding: AidingOutput
    trajectory: Trajectory

    @property
    def clean(self) -> bool:
        """True when every input lies within its stated bound (see :class:`Record`)."""
        return self.record.clean

    def closure_error_m(self) -> float:
        """Horizontal distance (m) between the true start and end points."""
        tr = self.truth
        return float(math.hypot(tr["east"][-1] - tr["east"][0], tr["north"][-1] - tr["north"][0]))

    def true_values(self) -> dict[str, Any]:
        """Every simulated error term (SI), for ``scenario.json``."""
        fig = self.imu_errors.figures
        return {
            "imu": {
                "figures": fig.to_dict(),
                "channels": self.imu_errors.summary(),
                "notes": self.imu_errors.notes,
            },
            "aiding": self.aiding.true_errors,
            "trajectory": {
                "cruise_speed_mps": self.trajectory.cruise_mps,
                "corner_speed_mps": self.trajectory.corner_mps,
                "path_length_m": self.trajectory.path.total,
                "closure_error_m": self.closure_error_m(),
                "hill_phases_rad": [float(x) for x in self.trajectory.terrain.hill_phase],
                "bank_phases_rad": [float(x) for x in self.trajectory.terrain.bank_phase],
            },
        }

    def to_json(self) -> dict[str, Any]:
        """The content of ``scenario.json``."""
        cfg = self.config
        return {
            "generator": "imubounds.dynamic.scenario",
            "schema_version": 2,
            "variant": cfg.variant,
            "seed": cfg.seed,
            "config": cfg.to_dict(),
            "conventions": CONVENTIONS,
            "origin": list(cfg.origin),
            "streams": self.drive.streams(),
            "true_values": self.true_values(),
            "record": self.record.to_dict(),
            # legacy: the per-step estimator's tests read the outlier rows here
            "gps_outlier_rows": self.record.outliers.get("gnss", {}).get("indices", []),
        }


def _round_up(x: float, margin: float = 1.1, floor: float = 0.0) -> float:
    """``margin * x`` rounded up to two significant digits (at least ``floor``)."""
    v = max(margin * x, floor)
    if v <= 0:
        return 0.0
    e = math.floor(math.log10(v)) - 1
    return math.ceil(v / 10**e) * 10**e


def _vehicle(cfg: ScenarioConfig, tru: dict[str, Array], dt: float) -> VehicleSettings:
    acc = tru["acc_enu"]
    jerk = np.linalg.norm(np.diff(acc, axis=0), axis=1) / dt
    return VehicleSettings(
        kind=cfg.vehicle_kind,
        max_speed_mps=_round_up(float(tru["speed"].max())),
        max_accel_mps2=_round_up(float(np.linalg.norm(acc, axis=1).max())),
        max_jerk_mps3=_round_up(float(jerk.max())),
        max_yaw_rate_dps=_round_up(float(np.abs(tru["gyro"][:, 2]).max()) / DEG),
        max_tilt_deg=_round_up(
            float(max(np.abs(tru["roll"]).max(), np.abs(tru["pitch"]).max())) / DEG, floor=0.1
        ),
        lateral_speed_bound_mps=cfg.lateral_speed_bound_mps,
        # the truth's |w| (0 without road bumps: the velocity is along the path)
        vertical_speed_bound_mps=_round_up(float(np.abs(tru["body_vel"][:, 2]).max())),
    )


def _settings(
    cfg: ScenarioConfig, err: ImuErrors, aid: AidingOutput, tru: dict[str, Array]
) -> DriveSettings:
    fig = err.figures
    st = aid.stated
    # with a noise.json the estimator reads each axis's terms from it (copied beside as
    # imu_noise.json); else the preset's figures, one per sensor kind
    by_json = cfg.imu_noise is not None and cfg.noise_scale == 1.0
    imu = ImuSettings(
        noise_json=str(cfg.imu_noise) if by_json else None,
        accel_nd=None if by_json else fig.N["accel"],
        accel_bs=None if by_json else fig.B["accel"],
        gyro_nd=None if by_json else fig.N["gyro"] / DEG,
        gyro_bs=None if by_json else fig.B["gyro"] / DEG,
        accel_turn_on_mps2=fig.turn_on_bound["accel"],
        gyro_turn_on_dps=fig.turn_on_bound["gyro"] / DEG,
        scale_factor=fig.scale_bound,
        # the simulator states every bound it drew against: no misalignment simulated
        # is a bound of 0 (not the estimator's 0.5 deg default for an unknown IMU)
        misalignment_deg=(
            0.0 if fig.misalignment_bound_rad is None else fig.misalignment_bound_rad / DEG
        ),
        accel_bias_drift_mps2=fig.drift_bound["accel"],
        gyro_bias_drift_dps=fig.drift_bound["gyro"] / DEG,
        bias_drift_window_s=fig.drift_window_s,
        sample_time="end",
    )
    vel = st.get("velocity")
    head = st.get("heading")
    return DriveSettings(
        imu_axes=("x", "y", "z"),
        imu=imu,
        gnss=GnssSettings(
            cep_m=cfg.gps_cep_m, default_hdop=DEFAULT_HDOP, vel_sigma_mps=cfg.gps_vel_sigma_mps,
            vertical_sigma_ratio=1.5,  # the altitude error model (aiding.py)
        ),
        velocity=(
            VelocitySettings(bound_mps=vel["bound_mps"], scale=vel["scale"])
            if vel
            else VelocitySettings()
        ),
        heading=(
            HeadingSettings(
                deviation_deg=head["deviation_deg"],
                declination_deg=0.0,
                calibration=head["calibration"],
                noise_deg=head["noise_deg"],
            )
            if head
            else HeadingSettings(noise_deg=cfg.compass_noise_deg)
        ),
        attitude=AttitudeSettings(
            bound_deg=st["attitude"]["bound_deg"] if "attitude" in st else 1.0
        ),
        vehicle=_vehicle(cfg, tru, 1.0 / cfg.rate_hz),
    )


def _truth_stream(cfg: ScenarioConfig, tru: dict[str, Array], bias: Array) -> Truth:
    step = max(1, int(round(cfg.rate_hz / cfg.truth_rate_hz)))
    i = np.arange(0, tru["t"].size, step)
    extra: dict[str, Array] = {
        "up_m": tru["up"][i],
        "w_mps": np.zeros(i.size),
        "roll_rad": tru["roll"][i],
        "pitch_rad": tru["pitch"][i],
        "vel_e_mps": tru["vel_enu"][i, 0],
        "vel_n_mps": tru["vel_enu"][i, 1],
        "vel_u_mps": tru["vel_enu"][i, 2],
    }
    for j, ch in enumerate(CHANNELS):
        src = tru["accel_mean"] if j < 3 else tru["gyro_mean"]
        extra[ch] = src[i, j % 3]
    for j, ch in enumerate(CHANNELS):
        extra[f"bias_{ch}"] = bias[i, j]
    return Truth(
        t=tru["t"][i],
        east_m=tru["east"][i],
        north_m=tru["north"][i],
        origin=(cfg.origin[0], cfg.origin[1], cfg.origin[2]),
        heading_rad=np.asarray(model_to_compass(tru["yaw"][i])),
        u_mps=tru["body_vel"][i, 0],
        v_mps=tru.get("lateral", np.zeros_like(tru["speed"]))[i],
        extra=extra,
    )


def simulate(cfg: ScenarioConfig | None = None) -> SimResult:
    """Simulate a trip (see :mod:`imubounds.dynamic.scenario`)."""
    cfg = cfg or ScenarioConfig()
    cfg.check()
    seeds = dict(
        zip(SEED_STREAMS, np.random.SeedSequence(cfg.seed).spawn(len(SEED_STREAMS)), strict=True)
    )
    traj = Trajectory(cfg, np.random.default_rng(seeds["trajectory"]))
    dt = 1.0 / cfg.rate_hz
    n = int(round(cfg.duration_s * cfg.rate_hz)) + 1
    tru = traj.imu_truth(n, dt)
    mean = np.column_stack([tru["accel_mean"], tru["gyro_mean"]])
    aid = simulate_aiding(cfg, SampledTruth(tru, cfg.rate_hz), seeds)
    ep = aid.epoch_times()
    t = tru["t"]
    meas, err = simulate_errors(cfg, t, mean, seeds, ep)
    tru["bias"] = err.bias()
    record = Record(alpha=cfg.alpha)
    record.checks += imu_checks(cfg, t, err, ep)
    record.checks += aid.checks
    record.outliers = aid.outliers
    for f in cfg.faults:
        hit = np.flatnonzero(t > f.t0_s)
        record.faults.append(
            {
                "label": f.label(),
                "channel": f.channel,
                "kind": f.kind,
                "value": f.value,
                "t0_s": f.t0_s,
                "first_index": int(hit[0]) if hit.size else None,
            }
        )
    if cfg.velocity_lag_s > 0 and aid.velocity is not None:
        # an unstated timing error: the record is not clean
        record.faults.append(
            {
                "label": f"velocity:lag={cfg.velocity_lag_s:g}",
                "channel": "velocity",
                "kind": "lag",
                "value": cfg.velocity_lag_s,
                "t0_s": 0.0,
                "first_index": 0,
            }
        )
    drive = Drive(
        imu=ImuStream(
            t=t, accel=meas[:, :3], gyro=meas[:, 3:], input_units={"gyro": "rads", "accel": "mps2"}
        ),
        gnss=aid.gnss,
        velocity=aid.velocity,
        heading=aid.heading,
        mag=aid.mag,
        attitude=aid.attitude,
        truth=_truth_stream(cfg, tru, err.bias()),
        settings=_settings(cfg, err, aid, tru),
        source=f"simulated: {cfg.variant}, seed {cfg.seed}",
        layout="simulated",
        meta={"variant": cfg.variant, "seed": cfg.seed, "record_clean": record.clean},
    )
    drive.check()
    return SimResult(cfg, drive, record, tru, err, aid, traj)
