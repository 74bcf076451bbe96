"""Aiding streams of a simulated trip, with their true errors and bound checks.

Every stream's epochs fall on IMU sample times; each measurement is of the
truth at its time stamp (instantaneous, no lever arm: every sensor sits at the
body origin).

* GNSS position: per-axis Gaussian error of deviation DRMS_i/sqrt(2), DRMS_i =
  HDOP_i CEP/sqrt(ln 2) (METHOD.md 2.2); ``h_acc_m`` = DRMS_i/sqrt(2), the 1-sigma of each
  horizontal axis (as :class:`imubounds.io.drive.GnssStream` defines it); outliers add a
  jump of ``gps_outlier_m`` in a random direction. Altitude error 1.5 x the
  horizontal per-axis deviation (not bounded).
* GNSS velocity (``gnss-vel``): north and east, Gaussian per component.
* Compass: ``measured = true + n + dev(measured)`` with the one-cycle deviation
  ``dev(h) = A + B sin h + C cos h`` (clockwise from north) and noise ``n``, so
  correcting with the swing calibration gives ``true + n``; the calibration file
  is exact (36 headings, no noise).
* Magnetometer: the earth field (north, inclined down) in body axes through a
  soft-iron matrix, plus a hard-iron offset and noise, in tesla.
* Attitude: roll and pitch with Gaussian noise.
* DVL: body u, v, w with Gaussian noise; wheel speed: body u with a scale error
  and Gaussian noise.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from imubounds.dynamic.scenario.config import ScenarioConfig
from imubounds.dynamic.scenario.imu import k_level, truncated_normal
from imubounds.dynamic.scenario.record import Check, check
from imubounds.dynamic.scenario.trajectory import body_from_enu
from imubounds.dynamic.sensors.gnss import cep_to_drms, drms_to_sigma, rayleigh_factor
from imubounds.frames import model_to_compass, wrap_pi
from imubounds.io.drive import (
    AttitudeStream,
    GnssStream,
    HeadingStream,
    MagStream,
    VelocityStream,
)
from imubounds.units import DEG

Array = np.ndarray


def epochs(cfg: ScenarioConfig, rate_hz: float) -> Array:
    """Time stamps (s) of a stream at ``rate_hz`` over the trip, on the IMU grid."""
    step = int(round(cfg.rate_hz / rate_hz))
    n_imu = int(round(cfg.duration_s * cfg.rate_hz)) + 1
    return np.arange(0, n_imu, step) / cfg.rate_hz


@dataclass
class AidingOutput:
    """The streams, the bounds they were stated with, the true error terms, the checks."""

    gnss: GnssStream | None = None
    velocity: VelocityStream | None = None
    heading: HeadingStream | None = None
    mag: MagStream | None = None
    attitude: AttitudeStream | None = None
    calibration: Array | None = None  # (36, 2) measured, reference compass headings, rad
    stated: dict[str, Any] = field(default_factory=dict)
    true_errors: dict[str, Any] = field(default_factory=dict)
    checks: list[Check] = field(default_factory=list)
    outliers: dict[str, dict[str, list[float]]] = field(default_factory=dict)

    def epoch_times(self) -> Array:
        """The union of every stream's time stamps (for the IMU interval checks)."""
        ts = [s.t for s in (self.gnss, self.velocity, self.heading, self.mag, self.attitude) if s]
        return np.unique(np.concatenate(ts)) if ts else np.zeros(0)


class SampledTruth:
    """The truth at IMU sample times, looked up for stream epochs (which fall on them)."""

    def __init__(self, truth: dict[str, Array], rate_hz: float) -> None:
        self.truth = truth
        self.rate_hz = rate_hz

    def kinematics(self, t: Array, positions: bool = True) -> dict[str, Array]:
        i = np.rint(np.asarray(t) * self.rate_hz).astype(np.int64)
        return {k: v[i] for k, v in self.truth.items() if isinstance(v, np.ndarray)}


def _normal(
    rng: np.random.Generator, sigma: Array | float, bound: Array | float, shape: Any, bounded: bool
) -> Array:
    if bounded:
        return truncated_normal(rng, sigma, 0.999 * np.asarray(bound), shape)
    size = shape if isinstance(shape, tuple) else (shape,)
    return rng.standard_normal(size) * np.broadcast_to(np.asarray(sigma, dtype=float), size)


def simulate_aiding(
    cfg: ScenarioConfig, traj: SampledTruth, seeds: dict[str, np.random.SeedSequence]
) -> AidingOutput:
    """Every aiding stream of ``cfg.aiding`` (see the module docstring)."""
    out = AidingOutput()
    a = cfg.alpha
    if "gnss" in cfg.aiding:
        _gnss(cfg, traj, np.random.default_rng(seeds["gnss"]), out)
    if "compass" in cfg.aiding:
        _compass(cfg, traj, np.random.default_rng(seeds["compass"]), out)
    if "mag" in cfg.aiding:
        _mag(cfg, traj, np.random.default_rng(seeds["mag"]), out)
    if "attitude" in cfg.aiding:
        _attitude(cfg, traj, np.random.default_rng(seeds["attitude"]), out)
    if "dvl" in cfg.aiding or "wheel" in cfg.aiding:
        _velocity(cfg, traj, np.random.default_rng(seeds["velocity"]), out)
    out.stated["alpha"] = a
    return out


def _gnss(
    cfg: ScenarioConfig, traj: SampledTruth, rng: np.random.Generator, out: AidingOutput
) -> None:
    from imubounds.geodesy import enu_to_geodetic_3d

    t = epochs(cfg, cfg.gps_rate_hz)
    m = t.size
    k = traj.kinematics(t)
    hdop = cfg.hdop_mean + 0.1 * np.sin(2 * math.pi * t / 300.0) + rng.normal(0, 0.03, m)
    hdop = np.asarray(np.round(np.clip(hdop, 0.5, 1.5), 2), dtype=float)
    drms = hdop * cep_to_drms(cfg.gps_cep_m)
    sig = drms_to_sigma(drms)
    radius = drms * rayleigh_factor(one_in=m / cfg.alpha)
    ex = rng.standard_normal(m) * sig
    ey = rng.standard_normal(m) * sig
    if cfg.bounded:
        bad = np.hypot(ex, ey) > 0.999 * radius
        while np.any(bad):
            ex[bad] = rng.standard_normal(int(bad.sum())) * sig[bad]
            ey[bad] = rng.standard_normal(int(bad.sum())) * sig[bad]
            bad = np.hypot(ex, ey) > 0.999 * radius
    ez = rng.standard_normal(m) * 1.5 * sig
    orng = np.random.default_rng(rng.integers(2**63))
    outlier = np.zeros(m, dtype=bool)
    if cfg.gps_outlier_fraction > 0:
        outlier = orng.random(m) < cfg.gps_outlier_fraction
        outlier[0] = False  # the first fix is clean (many estimators start from it)
        ang = orng.uniform(0, 2 * math.pi, int(outlier.sum()))
        ex[outlier] += cfg.gps_outlier_m * np.cos(ang)
        ey[outlier] += cfg.gps_outlier_m * np.sin(ang)
    lat, lon, alt = enu_to_geodetic_3d(k["east"] + ex, k["north"] + ey, k["up"] + ez, cfg.origin)
    g = GnssStream(
        t=t,
        lat_deg=np.asarray(lat, dtype=float),
        lon_deg=np.asarray(lon, dtype=float),
        alt_m=np.asarray(alt, dtype=float),
        hdop=hdop,
        h_acc_m=sig.copy() if cfg.gps_h_acc else None,  # 1-sigma per axis (io.drive)
        fix=np.ones(m, dtype=bool),
    )
    out.checks.append(
        check(
            "gnss.position",
            "gnss",
            "m",
            "horizontal error radius <= DRMS_i sqrt(ln(n/alpha)) (probability 1 - alpha/n)",
            np.hypot(ex, ey),
            radius,
            t,
            k=math.sqrt(math.log(m / cfg.alpha)),
        )
    )
    out.true_errors["gnss"] = {
        "east_m": _stats(ex),
        "north_m": _stats(ey),
        "up_m": _stats(ez),
        "hdop_mean": float(hdop.mean()),
    }
    out.outliers["gnss"] = {
        "indices": [int(i) for i in np.flatnonzero(outlier)],
        "times_s": [float(x) for x in t[outlier]],
    }
    if "gnss-vel" in cfg.aiding:
        sv = cfg.gps_vel_sigma_mps
        kv = k_level(cfg.alpha, m)
        ev = _normal(rng, sv, kv * sv, (m, 2), cfg.bounded)
        g.vel_e_mps = k["vel_enu"][:, 0] + ev[:, 0]
        g.vel_n_mps = k["vel_enu"][:, 1] + ev[:, 1]
        out.checks.append(
            check(
                "gnss.velocity",
                "gnss",
                "m/s",
                "north and east velocity error <= k(n) vel_sigma_mps",
                ev,
                kv * sv,
                t,
                k=kv,
            )
        )
        out.true_errors["gnss_velocity"] = {
            "east_mps": _stats(ev[:, 0]),
            "north_mps": _stats(ev[:, 1]),
        }
    out.gnss = g
    out.stated["gnss"] = {"cep_m": cfg.gps_cep_m, "vel_sigma_mps": cfg.gps_vel_sigma_mps}


def deviation(h: Array, abc_rad: tuple[float, float, float]) -> Array:
    """One-cycle compass deviation ``A + B sin h + C cos h`` (rad) at heading ``h``."""
    A, B, C = abc_rad
    return A + B * np.sin(h) + C * np.cos(h)


def _solve_measured(target: Array, abc: tuple[float, float, float]) -> Array:
    """``m`` with ``m - dev(m) = target`` (fixed point; |dev'| <= |B| + |C| < 1)."""
    m = target.copy()
    for _ in range(60):
        m_new = target + deviation(m, abc)
        if np.max(np.abs(m_new - m)) < 1e-15:
            m = m_new
            break
        m = m_new
    return m


def _compass(
    cfg: ScenarioConfig, traj: SampledTruth, rng: np.random.Generator, out: AidingOutput
) -> None:
    t = epochs(cfg, cfg.compass_rate_hz)
    k = traj.kinematics(t, positions=False)
    true_c = np.asarray(model_to_compass(k["yaw"]))
    abc = tuple(x * DEG for x in cfg.compass_dev_deg)
    if abs(abc[1]) + abs(abc[2]) >= 0.5:
        from imubounds.errors import OptionError

        raise OptionError("compass deviation |B| + |C| must stay under 0.5 rad")
    sc = cfg.compass_noise_deg * DEG
    kc = k_level(cfg.alpha, t.size)
    noise = _normal(rng, sc, kc * sc, t.size, cfg.bounded)
    meas = _solve_measured(true_c + noise, abc) % (2 * math.pi)  # type: ignore[arg-type]
    out.heading = HeadingStream(t=t, heading_rad=meas, source="compass")
    ref = np.radians(np.arange(0.0, 360.0, 10.0))
    out.calibration = np.column_stack(
        [_solve_measured(ref, abc) % (2 * math.pi), ref]  # type: ignore[arg-type]
    )
    corrected = meas - deviation(meas, abc)  # type: ignore[arg-type]
    err = np.asarray(wrap_pi(corrected - true_c))
    out.checks.append(
        check(
            "heading",
            "heading",
            "deg",
            "|heading corrected by the calibration - true| <= deviation_deg + k(n) noise_deg",
            np.degrees(err),
            kc * cfg.compass_noise_deg,
            t,
            k=kc,
        )
    )
    out.true_errors["compass"] = {
        "deviation_deg": {
            "A": cfg.compass_dev_deg[0],
            "B": cfg.compass_dev_deg[1],
            "C": cfg.compass_dev_deg[2],
        },
        "noise_deg": _stats(np.degrees(noise)),
    }
    out.stated["heading"] = {
        "deviation_deg": 0.0,
        "noise_deg": cfg.compass_noise_deg,
        # the swing pairs, measured and reference, in degrees (written by write_layout)
        "calibration": None if out.calibration is None else np.degrees(out.calibration),
    }


def _mag(
    cfg: ScenarioConfig, traj: SampledTruth, rng: np.random.Generator, out: AidingOutput
) -> None:
    t = epochs(cfg, cfg.compass_rate_hz)
    k = traj.kinematics(t, positions=False)
    F, inc = cfg.mag_field_uT, math.radians(cfg.mag_inclination_deg)
    field_enu = np.tile([0.0, F * math.cos(inc), -F * math.sin(inc)], (t.size, 1))
    body = body_from_enu(field_enu, k["roll"], k["pitch"], k["yaw"])
    hard = rng.standard_normal(3) * cfg.mag_hard_iron_uT
    e = rng.standard_normal((3, 3)) * cfg.mag_soft_iron
    soft = np.eye(3) + 0.5 * (e + e.T)
    mag = (
        np.einsum("ij,nj->ni", soft, body)
        + hard
        + rng.standard_normal((t.size, 3)) * cfg.mag_noise_uT
    )
    out.mag = MagStream(t=t, mag=mag * 1e-6, unit="ut")
    out.true_errors["magnetometer"] = {
        "field_uT": F,
        "inclination_deg": cfg.mag_inclination_deg,
        "declination_deg": 0.0,
        "hard_iron_uT": [float(x) for x in hard],
        "soft_iron": [[float(x) for x in row] for row in soft],
        "noise_uT": cfg.mag_noise_uT,
        "model": "mag = soft_iron @ (R^T field_enu) + hard_iron + noise, body FLU",
    }


def _attitude(
    cfg: ScenarioConfig, traj: SampledTruth, rng: np.random.Generator, out: AidingOutput
) -> None:
    t = epochs(cfg, cfg.attitude_rate_hz)
    k = traj.kinematics(t, positions=False)
    sa = cfg.attitude_sigma_deg * DEG
    bound = k_level(cfg.alpha, 2 * t.size) * sa
    err = _normal(rng, sa, bound, (t.size, 2), cfg.bounded)
    out.attitude = AttitudeStream(
        t=t, roll_rad=k["roll"] + err[:, 0], pitch_rad=k["pitch"] + err[:, 1], source="ahrs"
    )
    if cfg.attitude_yaw_sigma_deg > 0:
        # the AHRS yaw (compass convention), Gaussian; the heading of a drive without a
        # compass (the estimator flags it as not independent of the gyro)
        sy = cfg.attitude_yaw_sigma_deg * DEG
        ky = k_level(cfg.alpha, t.size)
        ey = _normal(rng, sy, ky * sy, t.size, cfg.bounded)
        out.attitude.yaw_rad = np.mod(np.asarray(model_to_compass(k["yaw"])) + ey, 2 * math.pi)
        out.checks.append(
            check("attitude.yaw", "heading", "deg", "|yaw error| <= k(n) noise_deg",
                  np.degrees(ey), ky * cfg.attitude_yaw_sigma_deg, t, k=ky)
        )
        out.true_errors["attitude"] = {"yaw_deg": _stats(np.degrees(ey))}
        if "heading" not in out.stated:
            out.stated["heading"] = {
                "deviation_deg": 0.0, "noise_deg": cfg.attitude_yaw_sigma_deg, "calibration": None,
            }
    out.checks.append(
        check(
            "attitude",
            "attitude",
            "deg",
            "|roll error|, |pitch error| <= bound_deg",
            np.degrees(err),
            math.degrees(bound),
            t,
            k=k_level(cfg.alpha, 2 * t.size),
        )
    )
    out.true_errors.setdefault("attitude", {}).update({
        "roll_deg": _stats(np.degrees(err[:, 0])),
        "pitch_deg": _stats(np.degrees(err[:, 1])),
    })
    out.stated["attitude"] = {"bound_deg": math.degrees(bound)}


def _velocity(
    cfg: ScenarioConfig, traj: SampledTruth, rng: np.random.Generator, out: AidingOutput
) -> None:
    t = epochs(cfg, cfg.velocity_rate_hz)
    k = traj.kinematics(t, positions=False)
    bv = k["body_vel"]  # (speed, 0, 0) plus the heave of road bumps
    u = bv[:, 0]
    m = t.size
    if "dvl" in cfg.aiding:
        s = cfg.dvl_sigma_mps
        bound = k_level(cfg.alpha, 3 * m) * s
        err = _normal(rng, s, bound, (m, 3), cfg.bounded)
        out.velocity = VelocityStream(
            t=t, u_mps=u + err[:, 0], v_mps=bv[:, 1] + err[:, 1], w_mps=bv[:, 2] + err[:, 2],
            kind="dvl",
        )
        scale, scale_err = 0.0, 0.0
        comp = err
        out.true_errors["velocity"] = {
            "kind": "dvl",
            "u_mps": _stats(err[:, 0]),
            "v_mps": _stats(err[:, 1]),
            "w_mps": _stats(err[:, 2]),
        }
    else:
        s = cfg.wheel_sigma_mps
        bound = k_level(cfg.alpha, m) * s
        scale = k_level(cfg.alpha, 1) * cfg.wheel_scale_sigma
        scale_err = float(
            _normal(rng, cfg.wheel_scale_sigma, max(scale, 1e-300), 1, cfg.bounded)[0]
        )
        noise = _normal(rng, s, bound, m, cfg.bounded)
        comp = (scale_err * u + noise)[:, None]
        out.velocity = VelocityStream(t=t, u_mps=u + comp[:, 0], kind="wheel")
        out.true_errors["velocity"] = {
            "kind": "wheel",
            "scale_error": scale_err,
            "noise_mps": _stats(noise),
        }
    out.checks.append(
        check(
            "velocity",
            "velocity",
            "m/s",
            "body velocity error (each component) <= bound_mps + scale |u|",
            comp,
            bound + scale * np.abs(u),
            t,
            k=k_level(cfg.alpha, 3 * m if "dvl" in cfg.aiding else m),
        )
    )
    if cfg.velocity_lag_s > 0:
        # the stream reports the velocity at t with the stamp t + lag (a lagging odometry)
        out.velocity.t = t + cfg.velocity_lag_s
        out.true_errors["velocity"]["lag_s"] = cfg.velocity_lag_s
    out.stated["velocity"] = {"bound_mps": bound, "scale": scale}


def _stats(x: Array) -> dict[str, float]:
    x = np.asarray(x, dtype=float)
    return {
        "mean": float(x.mean()),
        "std": float(x.std()),
        "max_abs": float(np.abs(x).max()) if x.size else 0.0,
    }
