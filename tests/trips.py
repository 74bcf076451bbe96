"""A compact 3-D trip generator for the estimator's tests: ``make_trip(variant, seed)``.

The paper's trip (METHOD.md 3.5: closed 9.4 km in 792 s, rounded rectangle) driven by a
ground vehicle with no side slip, with truth in 3-D (hills: altitude, pitch and roll
profiles), an MTx-grade IMU at 100 Hz whose samples are the means of the true specific
force and body rate over each period plus REALISTIC errors (turn-on bias drawn
Gaussian with sigma = B, white noise N and flicker B from the noise simulator, scale
and misalignment inside their bounds), GNSS positions with Rayleigh errors (and 2 %
gross outliers in the ``outliers`` variant), GNSS velocity, a deviation-corrected
compass, roll/pitch and a DVL, each with Gaussian errors.

It returns a :class:`~imubounds.io.drive.Drive` whose ``drive.yaml``-style settings
state the figures the data were drawn with, and a :class:`TripErrors` with the true
errors, so that a test can tell which inputs fell outside the estimator's stated
bounds (:func:`record`). The soundness test runs on this generator; the simulator of
``imubounds simulate`` can replace it (same signature).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.special import ndtri

from imubounds.dynamic.estimator.budget import ChannelNoise, box_sum_variance
from imubounds.geodesy import enu_to_geodetic
from imubounds.io.drive import (
    AttitudeStream,
    Drive,
    DriveSettings,
    GnssStream,
    HeadingStream,
    ImuStream,
    Truth,
    VelocityStream,
)
from imubounds.presets import XSENS_MTX
from imubounds.stationary.noise_sim import AxisNoise, simulate_axis
from imubounds.units import DEG

G = 9.80665
VARIANTS = ("paper", "hills", "sharp", "gnss10", "pos_only", "pos_vel", "dvl", "outliers")
CHANS = ("accel_x", "accel_y", "accel_z", "gyro_x", "gyro_y", "gyro_z")


@dataclass
class TripConfig:
    duration_s: float = 792.0
    distance_m: float = 9400.0
    ramp_s: float = 20.0
    corner_m: float = 150.0
    aspect: float = 1.5
    imu_hz: float = 100.0
    gnss_hz: float = 1.0
    compass_hz: float = 1.0
    attitude_hz: float = 100.0
    dvl_hz: float = 5.0
    hills: bool = False
    gnss_pos: bool = True
    gnss_vel: bool = True
    compass: bool = True
    attitude: bool = True
    dvl: bool = False
    outlier_fraction: float = 0.0
    cep_m: float = 3.0
    hdop: float = 0.8
    vel_sigma: float = 0.1
    compass_noise_deg: float = 0.3
    compass_residual_deg: float = 0.3
    compass_bound_deg: float = 0.4
    attitude_noise_deg: float = 0.02
    attitude_bound_deg: float = 0.1
    dvl_sigma: float = 0.02
    dvl_bound: float = 0.1
    lateral_speed_bound_mps: float | None = 0.3
    state_drift: bool = False
    scale_bound: float = 0.002
    imu_noise_scale: float = 1.0
    faults: list[tuple[str, float, float]] = field(default_factory=list)  # (ch, bias, t0)
    origin: tuple[float, float, float] = (23.55, 87.29, 80.0)


def variant_config(variant: str, **kw: Any) -> TripConfig:
    if variant not in VARIANTS:
        raise ValueError(f"unknown variant {variant!r}; choose from {VARIANTS}")
    cfg = TripConfig()
    if variant == "hills":
        cfg.hills = True
    elif variant == "sharp":
        cfg.corner_m = 60.0
    elif variant == "gnss10":
        cfg.gnss_hz = 10.0
    elif variant == "pos_only":
        cfg.gnss_vel = False
    elif variant == "dvl":
        cfg.gnss_pos = cfg.gnss_vel = False
        cfg.dvl = True
    elif variant == "outliers":
        cfg.outlier_fraction = 0.02
    for k, v in kw.items():
        setattr(cfg, k, v)
    return cfg


@dataclass
class TripErrors:
    """True errors and figures of a trip (for the out-of-bound record)."""

    turn_on: dict[str, float]
    imu_error: dict[str, np.ndarray]  # y - x - (scale/misalignment part), per sample
    gnss_pos_err: np.ndarray | None  # (m, 2) east, north
    gnss_outlier: np.ndarray | None
    gnss_vel_err: np.ndarray | None
    heading_err: np.ndarray | None  # rad
    attitude_err: np.ndarray | None  # (m, 2) rad
    dvl_err: np.ndarray | None  # (m, 3)
    faults: list[tuple[str, float, float]]
    truth_mean: dict[str, np.ndarray]  # true sample means per channel


# ----------------------------------------------------------------------- geometry


def _speed(t: np.ndarray, V: float, T: float, D: float) -> tuple[np.ndarray, np.ndarray]:
    v = np.full_like(t, V)
    a = np.zeros_like(t)
    s1 = t < T
    v[s1] = V * 0.5 * (1 - np.cos(math.pi * t[s1] / T))
    a[s1] = V * 0.5 * math.pi / T * np.sin(math.pi * t[s1] / T)
    s2 = t > D - T
    tb = D - t[s2]
    v[s2] = V * 0.5 * (1 - np.cos(math.pi * tb / T))
    a[s2] = -V * 0.5 * math.pi / T * np.sin(math.pi * tb / T)
    return v, a


def _dist(t: np.ndarray, V: float, T: float, D: float, total: float) -> np.ndarray:
    t = np.clip(t, 0.0, D)
    s = V * (t - 0.5 * T)
    s1 = t < T
    s[s1] = V * 0.5 * (t[s1] - T / math.pi * np.sin(math.pi * t[s1] / T))
    s2 = t > D - T
    tb = D - t[s2]
    s[s2] = total - V * 0.5 * (tb - T / math.pi * np.sin(math.pi * tb / T))
    return s


def _corners(cfg: TripConfig) -> np.ndarray:
    lap = cfg.distance_m
    lc = cfg.corner_m
    straight = lap - 4 * lc
    l1 = straight / 2 * cfg.aspect / (1 + cfg.aspect)
    l2 = straight / 2 - l1
    s = l1 / 2
    out = []
    for side in (l2, l1, l2, l1):
        out.append(s)
        s += lc + side
    return np.array(out)


def _heading(s: np.ndarray, cfg: TripConfig) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """psi (CCW from east), curvature kappa and dkappa/ds vs horizontal distance."""
    lc = cfg.corner_m
    psi = np.zeros_like(s)
    kap = np.zeros_like(s)
    dk = np.zeros_like(s)
    for s0 in _corners(cfg):
        x = np.clip(s - s0, 0.0, lc)
        psi += (math.pi / (2 * lc)) * (x - lc / (2 * math.pi) * np.sin(2 * math.pi * x / lc))
        inside = (s > s0) & (s < s0 + lc)
        ph = 2 * math.pi * (s[inside] - s0) / lc
        kap[inside] += (math.pi / lc) * 0.5 * (1 - np.cos(ph))
        dk[inside] += (math.pi / lc) * 0.5 * np.sin(ph) * 2 * math.pi / lc
    return psi, kap, dk


def _truth(cfg: TripConfig, tf: np.ndarray) -> dict[str, np.ndarray]:
    """Truth on the fine grid ``tf``: positions, attitude, body specific force and rate.

    Body FLU, ENU nav, R = Rz(psi) Ry(-pitch) Rx(roll) (pitch nose up, roll right side
    down); body rates from the Euler rates: p = roll' + psi' sin(pitch),
    q = -pitch' cos(roll) + psi' sin(roll) cos(pitch),
    r = pitch' sin(roll) + psi' cos(roll) cos(pitch).
    """
    T, D = cfg.ramp_s, cfg.duration_s
    V = cfg.distance_m / (D - T)
    vh, ah = _speed(tf, V, T, D)
    sig = _dist(tf, V, T, D, cfg.distance_m)
    psi, kap, _ = _heading(sig, cfg)
    if cfg.hills:
        A, lam = 15.0, 1500.0
        kk = 2 * math.pi / lam
        tanth = A * kk * np.cos(kk * sig)
        dtan = -A * kk * kk * np.sin(kk * sig)  # d tan(pitch) / d sigma
        lr = 900.0
        roll = 2.0 * DEG * np.sin(2 * math.pi * sig / lr)
        droll = 2.0 * DEG * (2 * math.pi / lr) * np.cos(2 * math.pi * sig / lr)
    else:
        tanth = np.zeros_like(sig)
        dtan = np.zeros_like(sig)
        roll = np.zeros_like(sig)
        droll = np.zeros_like(sig)
    th = np.arctan(tanth)
    dt = np.diff(tf)
    cps, sps = np.cos(psi), np.sin(psi)
    ce, sn = vh * cps, vh * sps
    east = np.concatenate([[0.0], np.cumsum(0.5 * (ce[1:] + ce[:-1]) * dt)])
    north = np.concatenate([[0.0], np.cumsum(0.5 * (sn[1:] + sn[:-1]) * dt)])
    an = (
        ah * cps - vh * vh * kap * sps,
        ah * sps + vh * vh * kap * cps,
        ah * tanth + vh * vh * dtan + G,
    )
    ct, st = np.cos(th), np.sin(th)
    cp, sp = np.cos(roll), np.sin(roll)
    xb = (ct * cps, ct * sps, st)
    yb = (-st * sp * cps - cp * sps, -st * sp * sps + cp * cps, ct * sp)
    zb = (-st * cp * cps + sp * sps, -st * cp * sps - sp * cps, ct * cp)
    f = np.stack([b[0] * an[0] + b[1] * an[1] + b[2] * an[2] for b in (xb, yb, zb)], -1)
    psid = kap * vh
    thd = dtan * vh / (1.0 + tanth * tanth)
    rold = droll * vh
    w = np.stack([rold + psid * st, -thd * cp + psid * sp * ct, thd * sp + psid * cp * ct], -1)
    return {
        "t": tf,
        "east": east,
        "north": north,
        "psi": psi,
        "pitch": th,
        "roll": roll,
        "u": vh / ct,
        "f": f,
        "w": w,
    }


# -------------------------------------------------------------------------- trip


def make_trip(variant: str = "paper", seed: int = 0, **kw: Any) -> tuple[Drive, TripErrors]:
    """A simulated trip (see the module docstring) and its true errors."""
    cfg = variant_config(variant, **kw)
    rng = np.random.default_rng(seed)
    sub = 4
    dti = 1.0 / cfg.imu_hz
    n = int(round(cfg.duration_s * cfg.imu_hz))
    tf = np.arange(n * sub + 1) * (dti / sub)
    tr = _truth(cfg, tf)
    # IMU sample k covers (t_k - dt, t_k], t_k = (k + 1) dt: means over the fine grid
    f, w = tr["f"], tr["w"]
    fm = 0.5 * (f[1:] + f[:-1]).reshape(n, sub, 3).mean(axis=1)
    om = 0.5 * (w[1:] + w[:-1]).reshape(n, sub, 3).mean(axis=1)
    t_imu = (np.arange(n) + 1) * dti
    truth_mean = {
        "accel_x": fm[:, 0],
        "accel_y": fm[:, 1],
        "accel_z": fm[:, 2],
        "gyro_x": om[:, 0],
        "gyro_y": om[:, 1],
        "gyro_z": om[:, 2],
    }
    # IMU errors: scale, misalignment (inside the stated bounds), turn-on, white+flicker
    ss = np.random.SeedSequence(seed)
    streams = ss.spawn(8)
    out: dict[str, np.ndarray] = {}
    turn_on: dict[str, float] = {}
    err: dict[str, np.ndarray] = {}
    biases: dict[str, np.ndarray] = {}
    mis = XSENS_MTX.accel["misalignment_rad"]
    for kind, cols in (("accel", (0, 1, 2)), ("gyro", (3, 4, 5))):
        p = XSENS_MTX.kind(kind)
        x = np.stack([truth_mean[CHANS[c]] for c in cols], -1)
        S = np.diag(1.0 + rng.uniform(-0.9, 0.9, 3) * cfg.scale_bound)
        a = rng.uniform(-0.45, 0.45, 3) * mis  # small rotation, each axis within the bound
        Mx = np.array([[1.0, -a[2], a[1]], [a[2], 1.0, -a[0]], [-a[1], a[0], 1.0]])
        y = x @ (S @ Mx).T
        for i, c in enumerate(cols):
            ch = CHANS[c]
            sc = cfg.imu_noise_scale
            s_w, s_f = streams[c].spawn(2)
            white = simulate_axis(AxisNoise(N=p["N"] * sc), n, cfg.imu_hz, seed=s_w)
            flick = simulate_axis(AxisNoise(B=p["B"] * sc), n, cfg.imu_hz, seed=s_f)
            b0 = float(rng.normal(0.0, p["B"] * sc))
            turn_on[ch] = b0
            bias = b0 + flick
            for fch, fb, t0 in cfg.faults:
                if fch == ch:
                    bias = bias + np.where(t_imu > t0, fb, 0.0)
            biases[ch] = bias
            err[ch] = bias + white
            out[ch] = y[:, i] + err[ch]
    accel = np.stack([out["accel_x"], out["accel_y"], out["accel_z"]], -1)
    gyro = np.stack([out["gyro_x"], out["gyro_y"], out["gyro_z"]], -1)
    imu = ImuStream(t=t_imu, accel=accel, gyro=gyro)

    def at(tt: np.ndarray, key: str) -> np.ndarray:
        return np.interp(tt, tf, tr[key])

    settings = DriveSettings()
    settings.imu.preset = "mtx"
    # stated like the simulator: turn-on bound k(6) sigma, drift bound over 1 s windows
    k6 = float(-ndtri(0.01 / 12))
    settings.imu.accel_turn_on_mps2 = k6 * XSENS_MTX.accel["B"] * cfg.imu_noise_scale
    settings.imu.gyro_turn_on_dps = k6 * XSENS_MTX.gyro["B"] / DEG * cfg.imu_noise_scale
    if cfg.state_drift:
        kd = float(-ndtri(0.01 / (2 * 6 * cfg.duration_s)))
        for kind, key in (("accel", "accel_bias_drift_mps2"), ("gyro", "gyro_bias_drift_dps")):
            cn = ChannelNoise(kind + "_x", B=XSENS_MTX.kind(kind)["B"] * cfg.imu_noise_scale)
            sd = math.sqrt(box_sum_variance(cn, 1, 1.0)) / 1.0  # the flicker's 1 s mean
            setattr(settings.imu, key, kd * sd / (DEG if kind == "gyro" else 1.0))
        settings.imu.bias_drift_window_s = 1.0
    settings.imu.scale_factor = cfg.scale_bound
    settings.imu.misalignment_deg = mis / DEG
    settings.gnss.cep_m = cfg.cep_m
    settings.gnss.vel_sigma_mps = cfg.vel_sigma
    settings.heading.deviation_deg = cfg.compass_bound_deg
    settings.heading.noise_deg = cfg.compass_noise_deg
    settings.attitude.bound_deg = cfg.attitude_bound_deg
    settings.velocity.bound_mps = cfg.dvl_bound
    settings.vehicle.max_speed_mps = 40.0
    settings.vehicle.max_accel_mps2 = 10.0
    settings.vehicle.max_jerk_mps3 = 20.0
    settings.vehicle.max_yaw_rate_dps = 90.0
    settings.vehicle.max_tilt_deg = 10.0
    settings.vehicle.lateral_speed_bound_mps = cfg.lateral_speed_bound_mps
    settings.vehicle.vertical_speed_bound_mps = 0.0  # no slip: the velocity is along body x
    drive = Drive(imu=imu, settings=settings, source=f"<trip {variant} seed {seed}>")
    pos_err = vel_err = outl = None
    if cfg.gnss_pos:
        tg = np.arange(1, int(cfg.duration_s * cfg.gnss_hz) + 1) / cfg.gnss_hz
        tg = tg[tg <= t_imu[-1]]
        m = tg.size
        hd = np.round(np.clip(cfg.hdop + 0.05 * np.sin(tg / 60.0), 0.5, 2.0), 2)
        drms = hd * cfg.cep_m / math.sqrt(math.log(2.0))
        pos_err = rng.normal(0.0, 1.0, (m, 2)) * (drms / math.sqrt(2))[:, None]
        outl = np.zeros(m, dtype=bool)
        if cfg.outlier_fraction > 0:
            outl = rng.random(m) < cfg.outlier_fraction
            outl[0] = False
            ang = rng.uniform(0, 2 * math.pi, int(outl.sum()))
            mag = rng.uniform(30.0, 80.0, int(outl.sum()))
            pos_err[outl] += np.stack([mag * np.cos(ang), mag * np.sin(ang)], -1)
        e = at(tg, "east") + pos_err[:, 0]
        nn = at(tg, "north") + pos_err[:, 1]
        lat, lon = enu_to_geodetic(e, nn, cfg.origin)
        ve = vn = None
        if cfg.gnss_vel:
            vh = at(tg, "u") * np.cos(at(tg, "pitch"))
            ps = at(tg, "psi")
            vel_err = rng.normal(0.0, cfg.vel_sigma, (m, 2))
            ve = vh * np.cos(ps) + vel_err[:, 0]
            vn = vh * np.sin(ps) + vel_err[:, 1]
        drive.gnss = GnssStream(
            t=tg,
            lat_deg=lat,
            lon_deg=lon,
            alt_m=np.full(m, cfg.origin[2]),
            hdop=hd,
            fix=np.ones(m, dtype=bool),
            vel_n_mps=vn,
            vel_e_mps=ve,
        )
    head_err = None
    if cfg.compass:
        th_ = np.arange(1, int(cfg.duration_s * cfg.compass_hz) + 1) / cfg.compass_hz
        th_ = th_[th_ <= t_imu[-1]]
        psi = at(th_, "psi")
        comp = (0.5 * math.pi - psi) % (2 * math.pi)
        resid = cfg.compass_residual_deg * DEG * np.sin(comp + 0.7)
        noise = rng.normal(0.0, cfg.compass_noise_deg * DEG, th_.size)
        head_err = resid + noise
        drive.heading = HeadingStream(t=th_, heading_rad=(comp + head_err) % (2 * math.pi))
    att_err = None
    if cfg.attitude:
        ta = np.arange(1, int(cfg.duration_s * cfg.attitude_hz) + 1) / cfg.attitude_hz
        ta = ta[ta <= t_imu[-1]]
        att_err = rng.normal(0.0, cfg.attitude_noise_deg * DEG, (ta.size, 2))
        drive.attitude = AttitudeStream(
            t=ta,
            roll_rad=at(ta, "roll") + att_err[:, 0],
            pitch_rad=at(ta, "pitch") + att_err[:, 1],
            source="reference",
        )
    dvl_err = None
    if cfg.dvl:
        td = np.arange(1, int(cfg.duration_s * cfg.dvl_hz) + 1) / cfg.dvl_hz
        td = td[td <= t_imu[-1]]
        dvl_err = rng.normal(0.0, cfg.dvl_sigma, (td.size, 3))
        drive.velocity = VelocityStream(
            t=td,
            u_mps=at(td, "u") + dvl_err[:, 0],
            v_mps=dvl_err[:, 1],
            w_mps=dvl_err[:, 2],
            kind="dvl",
        )
    # truth at the IMU rate (and the biases the IMU had)
    extra = {
        "roll_rad": at(t_imu, "roll"),
        "pitch_rad": at(t_imu, "pitch"),
    }
    for ch in CHANS:
        extra[f"bias_{ch}"] = biases[ch]
        extra[f"true_{ch}"] = truth_mean[ch]
    drive.truth = Truth(
        t=t_imu,
        east_m=at(t_imu, "east"),
        north_m=at(t_imu, "north"),
        origin=cfg.origin,
        heading_rad=(0.5 * math.pi - at(t_imu, "psi")) % (2 * math.pi),
        u_mps=at(t_imu, "u"),
        v_mps=np.zeros(t_imu.size),
        extra=extra,
    )
    errs = TripErrors(
        turn_on=turn_on,
        imu_error=err,
        gnss_pos_err=pos_err,
        gnss_outlier=outl,
        gnss_vel_err=vel_err,
        heading_err=head_err,
        attitude_err=att_err,
        dvl_err=dvl_err,
        faults=list(cfg.faults),
        truth_mean=truth_mean,
    )
    return drive, errs


def record(result: Any, errs: TripErrors) -> dict[str, int]:
    """Which inputs fell outside the bounds the estimator stated (counts per stream).

    Aiding samples against their half-widths, the turn-on biases against the bias-state
    prior, each IMU sample's total error against the per-sample bound; outliers and
    faults are always recorded.
    """
    rec: dict[str, int] = {}
    ctx = result.full.ctx
    ag = ctx.aiding
    if errs.gnss_pos_err is not None and ag.has_gnss:
        h = ag.gnss_h
        m = min(h.size, errs.gnss_pos_err.shape[0])
        rec["gnss_position"] = int(np.sum(np.any(np.abs(errs.gnss_pos_err[:m]) > h[:m, None], 1)))
    if errs.gnss_outlier is not None:
        rec["gnss_outliers"] = int(np.sum(errs.gnss_outlier))
    if errs.gnss_vel_err is not None and ag.has_gvel:
        rec["gnss_velocity"] = int(np.sum(np.abs(errs.gnss_vel_err) > ag.gvel_h))
    if errs.heading_err is not None and ag.has_heading:
        rec["heading"] = int(np.sum(np.abs(errs.heading_err) > ag.head_h[: errs.heading_err.size]))
    if errs.attitude_err is not None and ag.has_attitude:
        rec["attitude"] = int(np.sum(np.abs(errs.attitude_err) > ag.att_bound))
    if errs.dvl_err is not None and ag.has_bvel:
        rec["velocity"] = int(np.sum(np.abs(errs.dvl_err) > ag.bvel_h[:, None]))
    k_to = ctx.alpha.k("imu_turn_on")
    rec["imu_turn_on"] = int(
        sum(abs(errs.turn_on[ch]) > ctx.noise[ch].turn_on_bound(k_to) for ch in CHANS)
    )
    rec["imu_samples"] = int(
        sum(np.sum(np.abs(errs.imu_error[ch]) > ctx.E0[ch]) for ch in CHANS)
    )
    rec["faults"] = len(errs.faults)
    return rec
