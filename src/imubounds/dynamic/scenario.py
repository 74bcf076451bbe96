"""The paper's experiment as a simulator (METHOD.md 3.5), with truth.

A closed ground-vehicle trip (default 9.4 km in 792 s, mean speed under
50 km/h) around a rounded rectangle, sampled at ``rate_hz`` (IMU, default
1 Hz as in the paper) with GPS fixes (CEP 3 m, HDOP around 0.8) and a compass
with a hard-iron deviation. :func:`simulate` returns the data in memory;
:func:`write_scenario` writes the directory layout that
``imubounds dynamic DIR`` reads as it is.

Truth models (``truth_model``):

``continuous``
    A smooth continuous trajectory (speed ramps, raised-cosine curvature in
    the corners); the IMU reports step averages of the true specific force
    (``accel_x = u' - r v``, ``accel_y = v' + r u``) and rate. The
    estimator's discrete model then has a real discretisation error.
``paper`` / ``full``
    The true trajectory follows the estimator's own discrete recursion of
    that kinematic mode exactly (METHOD.md 3.2), driven by the step-averaged
    rates of the continuous trajectory. In ``paper`` mode the accelerometer
    reads the body-velocity derivatives (the printed model), in ``full`` the
    specific force.

``bounded=True`` draws every noise sample (IMU, GPS, compass) inside the
bounds handed to the estimator (recorded in ``scenario.json``), which is the
premise of the soundness guarantee.

Frames: ENU at the start point; body FLU; compass headings clockwise from
north; model heading counter-clockwise from east. SI units.
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from imubounds.dynamic.aiding.geodesy import enu_to_geodetic
from imubounds.dynamic.aiding.gps import GpsBoxSpec, cep_to_drms, parse_gps_box
from imubounds.errors import OptionError
from imubounds.frames import compass_to_model, model_to_compass, wrap_pi
from imubounds.presets import XSENS_MTX
from imubounds.stationary.bounds import interval_halfwidth
from imubounds.units import DEG, G0

#: Xsens MTx datasheet figures (METHOD.md 3.5), SI: N in (m/s^2)/sqrt(Hz) = m/s^1.5 and
#: rad/s/sqrt(Hz) = rad/s^0.5; B in m/s^2 and rad/s.
MTX_SPEC: dict[str, dict[str, float]] = {
    kind: {k: XSENS_MTX.kind(kind)[k] for k in ("N", "B")} for kind in ("accel", "gyro")
}
IMU_PRESETS: dict[str, dict[str, dict[str, float]]] = {"mtx": MTX_SPEC}


@dataclass
class ScenarioConfig:
    """Settings of a simulated drive (SI units unless the name says otherwise)."""

    scenario: str = "paper"
    seed: int = 0
    duration_s: float = 792.0
    distance_m: float = 9400.0
    rate_hz: float = 1.0
    gps_rate_hz: float = 1.0
    compass_rate_hz: float = 1.0
    ramp_s: float = 20.0
    corner_length_m: float = 150.0
    laps: int = 1
    aspect: float = 1.5
    origin: tuple[float, float, float] = (23.55, 87.29, 80.0)
    heading0_deg: float = 90.0  # compass heading at the start (90 = east)
    imu_preset: str = "mtx"
    noise_scale: float = 1.0
    k_sigma: float = 3.0
    gps_cep_m: float = 3.0
    hdop_mean: float = 0.8
    gps_box: str = "p=0.999"
    gps_outlier_fraction: float = 0.0
    gps_outlier_m: float = 40.0
    compass_dev_deg: tuple[float, float, float] = (1.0, 2.5, -1.5)
    compass_noise_deg: float = 0.3
    truth_model: str = "continuous"
    bounded: bool = False
    extra: dict[str, float] = field(default_factory=dict)

    def check(self) -> None:
        if self.duration_s <= 2 * self.ramp_s:
            raise OptionError("--duration must exceed twice the speed ramp (2 x 20 s)")
        for name in ("distance_m", "rate_hz", "gps_rate_hz", "compass_rate_hz", "gps_cep_m"):
            if not getattr(self, name) > 0:
                raise OptionError(f"--{name.replace('_', '-')} must be positive")
        if self.truth_model not in ("continuous", "paper", "full"):
            raise OptionError("--truth-model must be continuous, paper or full")
        if self.truth_model != "continuous" and not (
            self.gps_rate_hz == self.rate_hz == self.compass_rate_hz
        ):
            raise OptionError("a discrete truth model needs IMU, GPS and compass at the same rate")
        if self.imu_preset not in IMU_PRESETS:
            raise OptionError(f"--imu-preset must be one of {', '.join(IMU_PRESETS)}")
        if not 0.0 <= self.gps_outlier_fraction < 1.0:
            raise OptionError("--gps-outliers must lie in [0, 1)")
        if self.laps < 1:
            raise OptionError("--laps must be at least 1")
        parse_gps_box(self.gps_box)


@dataclass
class Scenario:
    """A simulated drive in memory (see :func:`simulate`)."""

    config: ScenarioConfig
    t: np.ndarray  # IMU sample times, s
    accel: np.ndarray  # (n, 3) FLU, m/s^2
    gyro: np.ndarray  # (n, 3) FLU, rad/s
    gps_t: np.ndarray
    gps_east: np.ndarray
    gps_north: np.ndarray
    hdop: np.ndarray
    gps_outlier: np.ndarray  # bool
    compass_t: np.ndarray
    compass: np.ndarray  # rad, clockwise from north
    truth: dict[str, np.ndarray]
    imu_halfwidth: dict[str, float]  # per channel, the bound handed to the estimator
    compass_halfwidth: float
    calibration: np.ndarray  # (m, 2) measured, reference compass headings in rad


def _speed_profile(cfg: ScenarioConfig) -> float:
    """Cruise speed V (m/s) so that the distance is covered in the duration."""
    return cfg.distance_m / (cfg.duration_s - cfg.ramp_s)


def _speed(t: np.ndarray, cfg: ScenarioConfig) -> tuple[np.ndarray, np.ndarray]:
    """Speed (m/s) and its derivative (m/s^2) with raised-cosine ramps."""
    V, T, D = _speed_profile(cfg), cfg.ramp_s, cfg.duration_s
    v = np.full_like(t, V)
    dv = np.zeros_like(t)
    a = t < T
    v[a] = V * 0.5 * (1 - np.cos(math.pi * t[a] / T))
    dv[a] = V * 0.5 * math.pi / T * np.sin(math.pi * t[a] / T)
    b = t > D - T
    tb = D - t[b]
    v[b] = V * 0.5 * (1 - np.cos(math.pi * tb / T))
    dv[b] = -V * 0.5 * math.pi / T * np.sin(math.pi * tb / T)
    return v, dv


def _distance(t: np.ndarray, cfg: ScenarioConfig) -> np.ndarray:
    """Arc length s(t) in m (closed form of the speed profile)."""
    V, T, D = _speed_profile(cfg), cfg.ramp_s, cfg.duration_s
    t = np.clip(t, 0.0, D)
    s = V * (t - 0.5 * T)
    a = t < T
    s[a] = V * 0.5 * (t[a] - T / math.pi * np.sin(math.pi * t[a] / T))
    b = t > D - T
    tb = D - t[b]
    s[b] = cfg.distance_m - V * 0.5 * (tb - T / math.pi * np.sin(math.pi * tb / T))
    return s


def _corners(cfg: ScenarioConfig) -> np.ndarray:
    """Arc-length start of each corner of the rounded rectangle (laps times)."""
    lap = cfg.distance_m / cfg.laps
    lc = cfg.corner_length_m
    straight = lap - 4 * lc
    if straight <= 0:
        raise OptionError("--corner-length too long for the lap length")
    l1 = straight / 2 * cfg.aspect / (1 + cfg.aspect)
    l2 = straight / 2 - l1
    starts = []
    for k in range(cfg.laps):
        base = k * lap
        # start in the middle of a long side so the speed ramps are on a straight
        s = base + l1 / 2
        for side in (l2, l1, l2, l1):
            starts.append(s)
            s += lc + side
    return np.array(starts)


def _heading(s: np.ndarray, cfg: ScenarioConfig) -> tuple[np.ndarray, np.ndarray]:
    """Model heading psi(s) (rad, CCW from east) and curvature kappa(s) (1/m)."""
    lc = cfg.corner_length_m
    psi0 = float(compass_to_model(math.radians(cfg.heading0_deg)))
    psi = np.full_like(s, psi0)
    kap = np.zeros_like(s)
    for s0 in _corners(cfg):
        x = np.clip(s - s0, 0.0, lc)
        psi += (math.pi / (2 * lc)) * (x - lc / (2 * math.pi) * np.sin(2 * math.pi * x / lc))
        inside = (s > s0) & (s < s0 + lc)
        kap[inside] += (math.pi / lc) * 0.5 * (1 - np.cos(2 * math.pi * (s[inside] - s0) / lc))
    return psi, kap


def _continuous_truth(cfg: ScenarioConfig, t: np.ndarray, sub: int) -> dict[str, np.ndarray]:
    """States at ``t`` and step averages over (t[k-1], t[k]] from a fine grid of ``sub``."""
    dt = t[1] - t[0]
    tf = np.concatenate([[t[0]], (t[:-1, None] + dt * (np.arange(1, sub + 1) / sub)).ravel()])
    s = _distance(tf, cfg)
    v, dv = _speed(tf, cfg)
    psi, kap = _heading(s, cfg)
    # positions: trapezoid on the fine grid (second order; sub >= 10)
    ce, sn = v * np.cos(psi), v * np.sin(psi)
    hf = np.diff(tf)
    east = np.concatenate([[0.0], np.cumsum(0.5 * (ce[1:] + ce[:-1]) * hf)])
    north = np.concatenate([[0.0], np.cumsum(0.5 * (sn[1:] + sn[:-1]) * hf)])
    r = kap * v
    ay = r * v  # lateral specific force (no side slip): v' + r u with v = 0
    idx = np.arange(0, tf.size, sub)
    n = t.size

    def step_mean(q: np.ndarray) -> np.ndarray:
        out = np.zeros(n)
        seg = 0.5 * (q[1:] + q[:-1])  # trapezoid per fine interval
        out[1:] = seg.reshape(n - 1, sub).mean(axis=1)
        return out

    ax_mean = np.zeros(n)
    ax_mean[1:] = np.diff(v[idx]) / dt  # exact mean of u'
    r_mean = np.zeros(n)
    r_mean[1:] = np.diff(psi[idx]) / dt  # exact mean of r
    return {
        "t": t,
        "east": east[idx],
        "north": north[idx],
        "psi": psi[idx],
        "u": v[idx],
        "v": np.zeros(n),
        "accel_x": ax_mean,
        "accel_y": step_mean(ay),
        "r": r_mean,
        "udot": ax_mean,
        "vdot": np.zeros(n),
        "speed_fine_max": np.full(n, float(v.max())),
        "accel_nav_max": np.full(n, float(np.max(np.hypot(dv, ay)))),
    }


def model_error_bounds(truth: dict[str, np.ndarray], dt: float) -> dict[str, float]:
    """Bounds that make the full-mode discrete model hold for this truth at step ``dt``.

    Returns ``nav_accel_bound`` A (m/s^2) and ``jerk_bound`` J (m/s^3) such that
    the per-step position residual is within ½·A·dt² and the velocity residual
    within J·dt² (the estimator's ``E_p`` and ``E_v``), measured on the truth
    with a 10 % margin.
    """
    x, y, u, v, psi = (truth[k] for k in ("east", "north", "u", "v", "psi"))
    a, b, r = truth["accel_x"], truth["accel_y"], truth["r"]
    c, s = np.cos(psi[1:]), np.sin(psi[1:])
    ex = np.diff(x) - (u[1:] * c - v[1:] * s) * dt
    ey = np.diff(y) - (v[1:] * c + u[1:] * s) * dt
    eu = np.diff(u) - (a[1:] + r[1:] * v[:-1]) * dt
    evv = np.diff(v) - (b[1:] - r[1:] * u[:-1]) * dt
    ep = float(max(np.max(np.abs(ex)), np.max(np.abs(ey))))
    ev = float(max(np.max(np.abs(eu)), np.max(np.abs(evv))))
    return {"nav_accel_bound": 1.1 * ep / (0.5 * dt * dt), "jerk_bound": 1.1 * ev / (dt * dt)}


def _discrete_truth(cont: dict[str, np.ndarray], mode: str, dt: float) -> dict[str, np.ndarray]:
    """Truth following the estimator's discrete recursion (METHOD.md 3.2) exactly."""
    n = cont["t"].size
    if mode == "paper":
        a = cont["udot"].copy()  # accelerometer reads u' in the printed model
        b = np.zeros(n)
    else:
        a = cont["accel_x"].copy()
        b = cont["accel_y"].copy()
    r = cont["r"].copy()
    u = np.zeros(n)
    v = np.zeros(n)
    psi = np.zeros(n)
    x = np.zeros(n)
    y = np.zeros(n)
    psi[0] = cont["psi"][0]
    for k in range(1, n):
        if mode == "paper":
            u[k] = u[k - 1] + a[k] * dt
            v[k] = v[k - 1] + b[k] * dt
        else:
            u[k] = u[k - 1] + (a[k] + r[k] * v[k - 1]) * dt
            v[k] = v[k - 1] + (b[k] - r[k] * u[k - 1]) * dt
        psi[k] = psi[k - 1] + r[k] * dt
        c, s = math.cos(psi[k]), math.sin(psi[k])
        x[k] = x[k - 1] + (u[k] * c - v[k] * s) * dt
        y[k] = y[k - 1] + (v[k] * c + u[k] * s) * dt
    out = dict(cont)
    out.update(east=x, north=y, psi=psi, u=u, v=v, accel_x=a, accel_y=b, r=r)
    return out


def _truncated_normal(
    rng: np.random.Generator, sigma: np.ndarray | float, bound: np.ndarray | float, size: int
) -> np.ndarray:
    """Normal(0, sigma) samples redrawn until |x| <= bound (elementwise)."""
    sig = np.broadcast_to(np.asarray(sigma, dtype=float), (size,))
    bnd = np.broadcast_to(np.asarray(bound, dtype=float), (size,))
    x = rng.normal(0.0, 1.0, size) * sig
    bad = np.abs(x) > bnd
    while np.any(bad):
        x[bad] = rng.normal(0.0, 1.0, int(bad.sum())) * sig[bad]
        bad = np.abs(x) > bnd
    return x


#: The noise simulator's preset for each IMU preset of the scenario.
SIM_PRESETS: dict[str, str] = {"mtx": "xsens-mtx"}


def _imu_noise(
    preset_name: str, rate_hz: float, n: int, scale: float, seed: int
) -> dict[str, np.ndarray]:
    """MTx-grade IMU noise from :mod:`~imubounds.stationary.noise_sim` (white N plus flicker B).

    Each sample is the noise of the average over its sample period, in SI.
    """
    from dataclasses import replace

    from imubounds.stationary import noise_sim

    spec = noise_sim.preset(SIM_PRESETS[preset_name])
    if scale != 1.0:
        spec = noise_sim.NoiseSpec(
            channels={
                c: replace(a, N=a.N * scale, B=a.B * scale) for c, a in spec.channels.items()
            },
            name=f"{spec.name} x {scale:g}",
        )
    log = noise_sim.simulate(spec, rate_hz=rate_hz, n_samples=n, seed=seed)
    return {c: np.asarray(v, dtype=float) for c, v in log.channels.items()}


def imu_halfwidths(
    preset: str | dict[str, dict[str, float]], dt: float, t_avg: float, k: float = 3.0
) -> dict[str, float]:
    """The estimator's per-sample half-width k·sigma_c for each channel (SI)."""
    spec = IMU_PRESETS[preset] if isinstance(preset, str) else preset
    out = {}
    for ch in ("accel_x", "accel_y", "accel_z", "gyro_x", "gyro_y", "gyro_z"):
        s = spec["accel" if ch.startswith("accel") else "gyro"]
        out[ch] = interval_halfwidth(s["N"], s["B"], dt, t_avg, k)
    return out


def simulate(cfg: ScenarioConfig) -> Scenario:
    """Simulate a drive (see the module docstring)."""
    cfg.check()
    rng = np.random.default_rng(cfg.seed)
    dt = 1.0 / cfg.rate_hz
    n = int(round(cfg.duration_s * cfg.rate_hz)) + 1
    t = np.arange(n) * dt
    sub = max(10, int(math.ceil(100.0 / cfg.rate_hz)))
    truth = _continuous_truth(cfg, t, sub)
    if cfg.truth_model != "continuous":
        truth = _discrete_truth(truth, cfg.truth_model, dt)

    # IMU (FLU): accel_z reads +g (level vehicle), gyro_x/y zero
    spec = IMU_PRESETS[cfg.imu_preset]
    half = imu_halfwidths(spec, dt, cfg.duration_s, cfg.k_sigma)
    clean = {
        "accel_x": truth["accel_x"],
        "accel_y": truth["accel_y"],
        "accel_z": np.full(n, G0),
        "gyro_x": np.zeros(n),
        "gyro_y": np.zeros(n),
        "gyro_z": truth["r"],
    }
    meas = {}
    if not cfg.bounded:
        sim_noise = _imu_noise(
            cfg.imu_preset, cfg.rate_hz, n, cfg.noise_scale, int(rng.integers(2**31))
        )
    for ch, val in clean.items():
        s = spec["accel" if ch.startswith("accel") else "gyro"]
        if cfg.bounded:
            sig = s["N"] * cfg.noise_scale / math.sqrt(dt)
            noise = _truncated_normal(rng, sig, half[ch], n)
        else:
            noise = sim_noise[ch]
        meas[ch] = val + noise
    accel = np.column_stack([meas["accel_x"], meas["accel_y"], meas["accel_z"]])
    gyro = np.column_stack([meas["gyro_x"], meas["gyro_y"], meas["gyro_z"]])

    # GPS
    g_dt = 1.0 / cfg.gps_rate_hz
    gps_t = np.arange(0.0, cfg.duration_s + 1e-9, g_dt)
    tn = truth["t"]
    ge = np.interp(gps_t, tn, truth["east"])
    gn = np.interp(gps_t, tn, truth["north"])
    m = gps_t.size
    hdop = cfg.hdop_mean + 0.1 * np.sin(2 * math.pi * gps_t / 300.0) + rng.normal(0, 0.03, m)
    hdop = np.round(np.clip(hdop, 0.5, 1.5), 2)
    drms = hdop * cep_to_drms(cfg.gps_cep_m)
    box: GpsBoxSpec = parse_gps_box(cfg.gps_box)
    gsig = drms / math.sqrt(2.0)
    if cfg.bounded:
        bnd = drms * box.factor()
        ex = _truncated_normal(rng, gsig, bnd, m)
        ey = _truncated_normal(rng, gsig, bnd, m)
    else:
        ex = rng.normal(0, 1, m) * gsig
        ey = rng.normal(0, 1, m) * gsig
    outlier = np.zeros(m, dtype=bool)
    if cfg.gps_outlier_fraction > 0:
        outlier = rng.random(m) < cfg.gps_outlier_fraction
        outlier[0] = False
        ang = rng.uniform(0, 2 * math.pi, int(outlier.sum()))
        ex[outlier] += cfg.gps_outlier_m * np.cos(ang)
        ey[outlier] += cfg.gps_outlier_m * np.sin(ang)

    # Compass: measured = true + deviation(measured) + noise (clockwise from north)
    c_dt = 1.0 / cfg.compass_rate_hz
    ct = np.arange(0.0, cfg.duration_s + 1e-9, c_dt)
    true_c = model_to_compass(np.interp(ct, tn, np.unwrap(truth["psi"])))
    A, B, C = (x * DEG for x in cfg.compass_dev_deg)
    sig_c = cfg.compass_noise_deg * DEG
    comp_half = cfg.k_sigma * sig_c
    if cfg.bounded:
        cn = _truncated_normal(rng, sig_c, comp_half, ct.size)
    else:
        cn = rng.normal(0, sig_c, ct.size)
    meas_c = true_c.copy()
    for _ in range(30):
        meas_c = true_c + A + B * np.sin(meas_c) + C * np.cos(meas_c)
    meas_c = (meas_c + cn) % (2 * math.pi)
    # an exact bench calibration (36 headings, no noise): the fit then is exact
    ref = np.radians(np.arange(0.0, 360.0, 10.0))
    cal_m = ref.copy()
    for _ in range(30):
        cal_m = ref + A + B * np.sin(cal_m) + C * np.cos(cal_m)
    calibration = np.column_stack([cal_m % (2 * math.pi), ref])

    return Scenario(
        config=cfg,
        t=t,
        accel=accel,
        gyro=gyro,
        gps_t=gps_t,
        gps_east=ge + ex,
        gps_north=gn + ey,
        hdop=hdop,
        gps_outlier=outlier,
        compass_t=ct,
        compass=meas_c,
        truth=truth,
        imu_halfwidth=half,
        compass_halfwidth=comp_half,
        calibration=calibration,
    )


def estimator_settings(sc: Scenario) -> dict[str, object]:
    """The bounds handed to the estimator, as stored in ``scenario.json``."""
    cfg = sc.config
    spec = IMU_PRESETS[cfg.imu_preset]
    return {
        "imu_spec": {
            k: {kk: vv * cfg.noise_scale for kk, vv in v.items()} for k, v in spec.items()
        },
        "k_sigma": cfg.k_sigma,
        "t_avg_s": cfg.duration_s,
        "gps_cep_m": cfg.gps_cep_m,
        "gps_box": cfg.gps_box,
        "compass_cal": "compass_cal.csv",
        "compass_mode": "corrected",
        # the deviation is evaluated at the noisy reading: widen by (1 + |B| + |C|)
        "compass_floor_rad": sc.compass_halfwidth
        * (1.0 + (abs(cfg.compass_dev_deg[1]) + abs(cfg.compass_dev_deg[2])) * DEG)
        * 1.001,
        "initial_speed_bound": 0.0,
        "mode": "full" if cfg.truth_model == "continuous" else cfg.truth_model,
        "model_error": model_error_bounds(sc.truth, 1.0 / cfg.rate_hz),
    }


def write_scenario(sc: Scenario, out_dir: str | Path) -> Path:
    """Write the simulator's files into the directory ``out_dir`` (created if needed).

    Callers that need the set to land complete or not at all write into an
    :class:`imubounds.io.outputs.OutputSet` staging directory.
    """
    tmp = Path(out_dir)
    tmp.mkdir(parents=True, exist_ok=True)
    if True:
        import pandas as pd

        cfg = sc.config
        lat, lon = enu_to_geodetic(sc.gps_east, sc.gps_north, cfg.origin)
        imu = pd.DataFrame({"t": sc.t})
        for i, ax in enumerate("xyz"):
            imu[f"accel_{ax}"] = sc.accel[:, i]
        for i, ax in enumerate("xyz"):
            imu[f"gyro_{ax}"] = sc.gyro[:, i]
        imu.to_csv(tmp / "imu.csv", index=False, float_format="%.10g")
        pd.DataFrame(
            {
                "t": sc.gps_t,
                "lat": lat,
                "lon": lon,
                "alt": np.full(sc.gps_t.size, cfg.origin[2]),
                "hdop": sc.hdop,
                "fix": np.ones(sc.gps_t.size, dtype=int),
            }
        ).to_csv(tmp / "gps.csv", index=False, float_format="%.12g")
        pd.DataFrame({"t": sc.compass_t, "heading_deg": np.degrees(sc.compass)}).to_csv(
            tmp / "compass.csv", index=False, float_format="%.10g"
        )
        pd.DataFrame(
            {
                "measured_deg": np.degrees(sc.calibration[:, 0]),
                "reference_deg": np.degrees(sc.calibration[:, 1]),
            }
        ).to_csv(tmp / "compass_cal.csv", index=False, float_format="%.12g")
        tr = sc.truth
        tlat, tlon = enu_to_geodetic(tr["east"], tr["north"], cfg.origin)
        pd.DataFrame(
            {
                "t": tr["t"],
                "lat": tlat,
                "lon": tlon,
                "east": tr["east"],
                "north": tr["north"],
                "psi": tr["psi"],
                "u": tr["u"],
                "v": tr["v"],
                "accel_x": tr["accel_x"],
                "accel_y": tr["accel_y"],
                "r": tr["r"],
            }
        ).to_csv(tmp / "truth.csv", index=False, float_format="%.12g")
        meta = {
            "generator": "imubounds.dynamic.scenario",
            "config": asdict(cfg),
            "frames": {
                "imu": "FLU body, SI (m/s^2, rad/s); accel_x/y are step averages",
                "compass": "heading_deg clockwise from north",
                "truth": "ENU at origin (m); psi rad CCW from east; u, v body m/s",
            },
            "origin": list(cfg.origin),
            "estimator": estimator_settings(sc),
            "gps_outlier_rows": np.flatnonzero(sc.gps_outlier).tolist(),
            "true_compass_deviation_deg": list(cfg.compass_dev_deg),
        }
        (tmp / "scenario.json").write_text(json.dumps(meta, indent=2))
    return tmp


def closure_error(sc: Scenario) -> float:
    """Distance in m between the true start and end points."""
    tr = sc.truth
    return float(math.hypot(tr["east"][-1] - tr["east"][0], tr["north"][-1] - tr["north"][0]))


__all__ = [
    "IMU_PRESETS",
    "MTX_SPEC",
    "Scenario",
    "ScenarioConfig",
    "closure_error",
    "estimator_settings",
    "imu_halfwidths",
    "simulate",
    "write_scenario",
    "wrap_pi",
]
