"""Mode ``paper``: the paper's per-step interval estimator (METHOD.md 3.2-3.4), kept to
reproduce the paper. NOT guaranteed: every output of this mode says so.

Put a drive on one step, run the interval estimator, summarise.

Steps: ``t_k = t_0 + k·step``. The IMU is averaged over (t_{k-1}, t_k] and its
per-sample bound is taken for that averaging period (``k·sigma_c(N, B,
step, t_avg)``); GPS and heading are taken at ``t_k`` (linear interpolation
between bracketing fixes, the box enlarged by the interpolation error bound
``½·A·Δ1·Δ2`` for a bound A on the acceleration, zero when a fix falls on
the step).

Channels estimated: ``accel_x`` (a, m/s^2, forward), ``accel_y`` (b, m/s^2,
left), ``gyro_z`` (r, rad/s, CCW). Per step and channel the result holds the
measured value, its interval, the *aided* interval (the projection of the
kinematic constraints from the contracted states, excluding the channel's
own measurement), the *estimate* (measured interval ∩ aided) and the
dynamic error interval ``[e] = [aided] - measured``.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from imubounds.dynamic.estimator import paper_kernel as K
from imubounds.dynamic.sensors.gnss import gps_box_halfwidths, parse_gps_box
from imubounds.dynamic.sensors.heading import (
    ZERO_DEVIATION,
    CompassDeviation,
    fit_deviation,
    heading_from_magnetometer,
    heading_intervals,
)
from imubounds.errors import AnalysisError, InputError, OptionError
from imubounds.geodesy import course_over_ground, geodetic_to_enu
from imubounds.io.drive import DEFAULT_CEP_M, DEFAULT_HDOP  # the GNSS defaults, defined once
from imubounds.stationary.bounds import interval_halfwidth, level_95_si
from imubounds.units import DEG

CHANNELS: tuple[str, ...] = ("accel_x", "accel_y", "gyro_z")
CHANNEL_UNITS = {"accel_x": "m/s^2", "accel_y": "m/s^2", "gyro_z": "rad/s"}
KINEMATICS = {"paper": 0, "full": 1}
VELDIFF = {"contracted": 0, "ins": 1}
FALLBACKS = {"keep": 0, "reset": 1, "qrelax": 2}


@dataclass
class ImuSpec:
    """Noise coefficients per sensor kind, SI: N (rad/s^0.5, m/s^1.5) and B (rad/s, m/s^2).

    ``per_channel`` overrides per channel name (from a static noise.json).
    """

    accel: dict[str, float]
    gyro: dict[str, float]
    per_channel: dict[str, dict[str, float]] = field(default_factory=dict)
    source: str = "datasheet"
    t_static_s: float | None = None

    def coeffs(self, channel: str) -> dict[str, float]:
        if channel in self.per_channel:
            return self.per_channel[channel]
        return self.accel if channel.startswith("accel") else self.gyro


@dataclass
class EstimatorConfig:
    """Settings of one estimator run (SI units)."""

    imu: ImuSpec
    step_s: float = 1.0
    kinematics: str = "paper"
    veldiff: str = "contracted"
    passes: int = 1
    window: int = 10
    tol: float = 0.01
    fallback: str = "reset"
    q_outliers: int = 1
    k_sigma: float = 3.0
    t_avg_s: float | None = None  # averaging time of sigma_c; the drive length if None
    # Extra half-width of the IMU intervals, in units of the bias-instability
    # coefficient B: 0 is the paper's k*sigma_c alone; 1 adds B, so that a
    # sensor whose bias wanders by its bias stability stays inside its bounds.
    bias_margin: float = 0.0
    gps_cep_m: float = DEFAULT_CEP_M
    gps_box: str = "p=0.999"
    default_hdop: float = DEFAULT_HDOP
    geodesy: str = "wgs84"
    compass_mode: str = "corrected"
    compass_floor_rad: float = 0.5 * DEG
    compass_margin: float = 1.0
    deviation: CompassDeviation | None = None
    declination_rad: float = 0.0
    cog_min_speed: float = 3.0
    initial_speed_bound: float | None = None
    max_speed: float = 70.0
    nav_accel_bound: float = 0.0  # m/s^2: position model error ½·A·dt^2 per step
    jerk_bound: float = 0.0  # m/s^3: velocity model error J·dt^2 per step
    interp_accel_bound: float = 10.0  # m/s^2, for GPS interpolation between fixes
    interp_rate_accel_bound: float = 1.0  # rad/s^2, for heading interpolation

    def check(self) -> None:
        if not (self.step_s > 0 and math.isfinite(self.step_s)):
            raise OptionError(f"--step must be a positive number of seconds, got {self.step_s!r}")
        if self.kinematics not in KINEMATICS:
            raise OptionError(f"--kinematics must be paper or full, got {self.kinematics!r}")
        if self.veldiff not in VELDIFF:
            raise OptionError(
                f"--velocity-difference must be contracted or ins, got {self.veldiff!r}"
            )
        if self.fallback not in FALLBACKS:
            raise OptionError(f"--on-empty must be keep, reset or qrelax, got {self.fallback!r}")
        if self.q_outliers < 0:
            raise OptionError("--q must be >= 0")
        if self.passes < 1 or self.window < 1:
            raise OptionError("--passes and --window must be at least 1")
        for name in ("nav_accel_bound", "jerk_bound", "k_sigma", "bias_margin"):
            if not getattr(self, name) >= 0:
                raise OptionError(f"--{name.replace('_', '-')} must be non-negative")
        parse_gps_box(self.gps_box)


@dataclass
class StepData:
    """A drive log on one time step (arrays of length n)."""

    t: np.ndarray
    dt: float
    meas: np.ndarray  # (n, 3) measured a, b, r (step averages)
    half: np.ndarray  # (3,) bound half-widths per channel
    gps: np.ndarray  # (n, 4) box, NaN = none
    heading: np.ndarray  # (n, 2) centre (model), half-width; NaN = none
    origin: tuple[float, float, float]
    deviation: CompassDeviation
    truth: dict[str, np.ndarray] | None
    counts: dict[str, int]
    warnings: list[str]


@dataclass
class EstimatorResult:
    """Everything one run produced (see :mod:`imubounds.dynamic.estimator.kernel` for layouts)."""

    config: EstimatorConfig
    steps: StepData
    S: np.ndarray
    P: np.ndarray
    M: np.ndarray
    D: np.ndarray
    A: np.ndarray
    flags: np.ndarray
    sweeps: int
    summary: dict[str, Any]


def _interp_at(
    t_src: np.ndarray, values: np.ndarray, t: np.ndarray, max_gap: float
) -> tuple[np.ndarray, np.ndarray]:
    """Linear interpolation at ``t``; returns (values, Δ1·Δ2) with NaN where not bracketed.

    A fix within 1e-6 s of ``t`` is taken as it is (Δ1·Δ2 = 0).
    """
    idx = np.searchsorted(t_src, t, side="left")
    out = np.full((t.size,) + values.shape[1:], np.nan)
    prod = np.full(t.size, np.nan)
    for i, (tk, j) in enumerate(zip(t, idx, strict=True)):
        if j < t_src.size and abs(t_src[j] - tk) < 1e-6:
            out[i] = values[j]
            prod[i] = 0.0
            continue
        if j > 0 and j < t_src.size and abs(t_src[j - 1] - tk) < 1e-6:
            out[i] = values[j - 1]
            prod[i] = 0.0
            continue
        if 0 < j < t_src.size and t_src[j] - t_src[j - 1] <= max_gap:
            d1, d2 = tk - t_src[j - 1], t_src[j] - tk
            w = d1 / (d1 + d2)
            out[i] = (1 - w) * values[j - 1] + w * values[j]
            prod[i] = d1 * d2
    return out, prod


def _step_average(t_src: np.ndarray, values: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Mean of the samples in (t[k-1], t[k]] for k >= 1 (NaN if none; row 0 NaN)."""
    edges = np.searchsorted(t_src, t, side="right")
    csum = np.concatenate([np.zeros((1,) + values.shape[1:]), np.cumsum(values, axis=0)])
    out = np.full((t.size,) + values.shape[1:], np.nan)
    cnt = edges[1:] - edges[:-1]
    s = csum[edges[1:]] - csum[edges[:-1]]
    with np.errstate(invalid="ignore", divide="ignore"):
        out[1:] = s / cnt.reshape((-1,) + (1,) * (values.ndim - 1))
    out[1:][cnt == 0] = np.nan
    return out


def _arrays(drive: Any) -> Any:
    """The drive's streams as the flat arrays this estimator works on."""
    from types import SimpleNamespace

    if drive.imu is None:
        raise InputError(f"{drive.source}: no IMU stream")
    g = drive.gnss
    if g is None or not np.any(g.usable()):
        raise InputError(
            f"{drive.source}: mode paper needs GNSS fixes (no usable GPS fix in the drive)"
        )
    n = g.t.size
    nan = np.full(n, np.nan)
    ns = SimpleNamespace(
        imu_t=drive.imu.t,
        accel=drive.imu.accel,
        gyro=drive.imu.gyro,
        gps_t=g.t,
        lat=g.lat_deg,
        lon=g.lon_deg,
        alt=g.alt_m if g.alt_m is not None else np.zeros(n),
        hdop=g.hdop if g.hdop is not None else nan,
        fix=g.usable(),
        heading_t=drive.heading.t if drive.heading is not None else None,
        heading=drive.heading.heading_rad if drive.heading is not None else None,
        mag_t=drive.mag.t if drive.mag is not None else None,
        mag=drive.mag.mag if drive.mag is not None else None,
        source=drive.source,
        warnings=list(drive.warnings),
    )
    if ns.heading is None and ns.mag is None:
        raise InputError(
            f"{drive.source}: mode paper needs a compass heading or a magnetometer"
        )
    return ns


def prepare_steps(drive: Any, cfg: EstimatorConfig) -> StepData:
    """Put a drive on the estimator's step (see the module docstring)."""
    cfg.check()
    log = _arrays(drive)
    warnings: list[str] = list(log.warnings)
    counts: dict[str, int] = {}
    good = log.fix & np.isfinite(log.lat) & np.isfinite(log.lon)
    counts["gps_rows"] = int(log.gps_t.size)
    counts["gps_no_fix_skipped"] = int((~good).sum())
    g_t = log.gps_t[good]
    e, n, origin = geodetic_to_enu(log.lat[good], log.lon[good], log.alt[good], method=cfg.geodesy)
    half_g, n_def = gps_box_halfwidths(log.hdop[good], cfg.gps_cep_m, cfg.gps_box, cfg.default_hdop)
    counts["gps_default_hdop"] = n_def
    # heading source
    if log.heading is not None and log.heading_t is not None:
        h_t, h_c, h_src = log.heading_t, log.heading, "compass"
    else:
        assert log.mag is not None and log.mag_t is not None
        h_t = log.mag_t
        h_c = heading_from_magnetometer(log.mag[:, 0], log.mag[:, 1], "FLU", cfg.declination_rad)
        h_src = "magnetometer"
    # steps
    dt = cfg.step_s
    t0 = max(log.imu_t[0], g_t[0], h_t[0])
    t_end = min(log.imu_t[-1], g_t[-1] + 0.5 * dt, h_t[-1] + 0.5 * dt)
    nstep = int(math.floor((t_end - t0) / dt + 1e-9)) + 1
    if nstep < 3:
        raise AnalysisError(
            f"{log.source}: IMU, GPS and heading overlap for {t_end - t0:.2f} s only; "
            f"need at least 2 steps of {dt:g} s"
        )
    t = t0 + dt * np.arange(nstep)
    # deviation
    dev = cfg.deviation
    if dev is None:
        tm, cog = course_over_ground(g_t, e, n, cfg.cog_min_speed)
        if tm.size >= 10:
            meas_at = np.interp(tm, h_t, np.unwrap(h_c))
            dev = fit_deviation(meas_at % (2 * math.pi), cog, source="gps-course")
            warnings.append(
                f"no compass calibration file: deviation fitted against the GPS course over "
                f"ground ({dev.n} pairs at >= {cfg.cog_min_speed:g} m/s; residual bound "
                f"{math.degrees(dev.residual_bound):.2f} deg)"
            )
        else:
            dev = ZERO_DEVIATION
            warnings.append(
                "no compass calibration and too few GPS course pairs: no deviation "
                "correction; the heading half-width is the floor only"
            )
    # IMU step averages (FLU: a forward, b left, r yaw CCW)
    raw = np.column_stack([log.accel[:, 0], log.accel[:, 1], log.gyro[:, 2]])
    meas = _step_average(log.imu_t, raw, t)
    no_imu = ~np.isfinite(meas[1:, 0])
    if np.any(no_imu):
        k = int(np.flatnonzero(no_imu)[0]) + 1
        raise AnalysisError(
            f"{log.source}: no IMU sample between t={t[k - 1]:.3f} and {t[k]:.3f} s: the step "
            f"({dt:g} s) is shorter than the IMU period or the IMU has a gap; use a longer --step"
        )
    meas[0] = meas[1]
    duration = float(t[-1] - t[0])
    t_avg = cfg.t_avg_s if cfg.t_avg_s else max(duration, dt)
    half = np.array(
        [
            (
                interval_halfwidth(
                    cfg.imu.coeffs(ch)["N"], cfg.imu.coeffs(ch)["B"], dt, t_avg, cfg.k_sigma
                )
                if cfg.k_sigma > 0
                else 0.0
            )
            + cfg.bias_margin * cfg.imu.coeffs(ch)["B"]
            for ch in CHANNELS
        ]
    )
    # GPS at steps
    cen, prod = _interp_at(g_t, np.column_stack([e, n, half_g]), t, 1.5 * max(dt, 1.0))
    grow = 0.5 * cfg.interp_accel_bound * np.nan_to_num(prod, nan=0.0)
    hw = cen[:, 2] + grow
    gps = np.column_stack([cen[:, 0] - hw, cen[:, 0] + hw, cen[:, 1] - hw, cen[:, 1] + hw])
    counts["steps_without_gps"] = int(np.isnan(gps[:, 0]).sum())
    # heading at steps (compass convention, unwrapped for interpolation)
    hc, hprod = _interp_at(h_t, np.unwrap(h_c)[:, None], t, 1.5 * max(dt, 1.0))
    hc = hc[:, 0] % (2 * math.pi)
    centre, hh = heading_intervals(
        np.nan_to_num(hc), dev, cfg.compass_mode, cfg.compass_floor_rad, cfg.compass_margin
    )
    hh = hh + 0.5 * cfg.interp_rate_accel_bound * np.nan_to_num(hprod, nan=0.0)
    heading = np.column_stack([np.where(np.isfinite(hc), centre, np.nan), hh])
    counts["steps_without_heading"] = int(np.isnan(heading[:, 0]).sum())
    if np.isnan(gps[0, 0]):
        raise AnalysisError(f"{log.source}: no GPS fix at the first step t={t[0]:.3f} s")
    truth = _truth_at_steps(drive, t, origin) if drive.truth is not None else None
    return StepData(
        t=t,
        dt=dt,
        meas=meas,
        half=half,
        gps=gps,
        heading=heading,
        origin=origin,
        deviation=dev,
        truth=truth,
        counts=counts,
        warnings=warnings + [f"heading source: {h_src}"],
    )


def _truth_at_steps(
    drive: Any, t: np.ndarray, origin: tuple[float, float, float]
) -> dict[str, np.ndarray]:
    from imubounds.dynamic.estimator.result import truth_at

    tr = truth_at(drive, t, origin)
    out: dict[str, np.ndarray] = {"east": tr["east"], "north": tr["north"]}
    for k in ("psi", "u", "v"):
        if tr.get(k) is not None:
            out[k] = tr[k]
    ex = drive.truth.extra
    tt = np.asarray(drive.truth.t, dtype=float)
    for name, keys in (
        ("accel_x", ("true_accel_x", "accel_x")),
        ("accel_y", ("true_accel_y", "accel_y")),
        ("r", ("true_gyro_z", "r")),
    ):
        for key in keys:
            if key in ex:
                vals = np.asarray(ex[key], dtype=float)
                per_sample = drive.imu is not None and vals.size == drive.imu.t.size
                if key.startswith("true_") and per_sample:
                    out[name] = _step_average(np.asarray(drive.imu.t, float), vals, t)
                else:
                    out[name] = np.interp(t, tt, vals)
                break
    return out


def initial_state(steps: StepData, cfg: EstimatorConfig) -> np.ndarray:
    """State at step 0: GPS box, speed bound, heading interval (entire if unknown)."""
    s0 = np.empty(10)
    s0[0:4] = steps.gps[0]
    vb = cfg.initial_speed_bound if cfg.initial_speed_bound is not None else cfg.max_speed
    s0[4:6] = (-vb, vb)
    s0[6:8] = (-vb, vb)
    c, h = steps.heading[0]
    if math.isfinite(c):
        s0[8:10] = K.heading_interval(float(c), float(h), float(c))
    else:
        s0[8:10] = (-math.pi, math.pi)
    return s0


def run(drive_or_steps: Any, cfg: EstimatorConfig) -> EstimatorResult:
    """Run the estimator (compiled loop) on a drive or prepared steps."""
    steps = (
        drive_or_steps
        if isinstance(drive_or_steps, StepData)
        else prepare_steps(drive_or_steps, cfg)
    )
    cfg.check()
    n = steps.t.size
    M = np.empty((n, 6))
    for c in range(3):
        M[:, 2 * c] = steps.meas[:, c] - steps.half[c]
        M[:, 2 * c + 1] = steps.meas[:, c] + steps.half[c]
    # outward: one ulp each side for the float subtraction / addition above
    M[:, 0::2] = np.nextafter(M[:, 0::2], -np.inf)
    M[:, 1::2] = np.nextafter(M[:, 1::2], np.inf)
    S = np.empty((n, 10))
    S[0] = initial_state(steps, cfg)
    P = np.empty((n, 10))
    D = np.empty((n, 6))
    A = np.empty((n, 6))
    flags = np.zeros(n, dtype=np.int64)
    dt = steps.dt
    ep = 0.5 * cfg.nav_accel_bound * dt * dt
    ev = cfg.jerk_bound * dt * dt
    sweeps = K.run_kernel(
        S,
        P,
        M,
        D,
        A,
        np.ascontiguousarray(steps.gps),
        np.ascontiguousarray(steps.heading),
        flags,
        dt,
        ep,
        ev,
        KINEMATICS[cfg.kinematics],
        VELDIFF[cfg.veldiff],
        FALLBACKS[cfg.fallback],
        cfg.window,
        cfg.passes,
        cfg.tol,
        cfg.q_outliers,
    )
    res = EstimatorResult(cfg, steps, S, P, M, D, A, flags, int(sweeps), {})
    res.summary = summarize(res)
    return res


# ----------------------------------------------------------------------------- summary


def _psi_contains(lo: np.ndarray, hi: np.ndarray, x: np.ndarray) -> np.ndarray:
    m = np.round((0.5 * (lo + hi) - x) / (2 * math.pi))
    xx = x + 2 * math.pi * m
    return (lo <= xx) & (xx <= hi)


def stationary_level_95(cfg: EstimatorConfig, channel: str, T_s: float) -> float:
    """The paper's 95 % stationary level 1.96·N·sqrt(T) for a channel (SI)."""
    return level_95_si(cfg.imu.coeffs(channel)["N"], T_s)


def summarize(res: EstimatorResult) -> dict[str, Any]:
    """Per-channel summary, enclosure against truth, and empty-intersection report."""
    st, cfg = res.steps, res.config
    n = st.t.size
    sl = slice(1, n)
    T = float(st.t[-1] - st.t[0])
    out: dict[str, Any] = {"n_steps": n, "step_s": st.dt, "duration_s": T, "channels": {}}
    for c, ch in enumerate(CHANNELS):
        meas = st.meas[sl, c]
        alo, ahi = res.A[sl, 2 * c], res.A[sl, 2 * c + 1]
        dlo, dhi = res.D[sl, 2 * c], res.D[sl, 2 * c + 1]
        fin = np.isfinite(alo) & np.isfinite(ahi)
        elo, ehi = alo - meas, ahi - meas
        L95 = stationary_level_95(cfg, ch, T)
        mlo = float(np.mean(elo[fin])) if fin.any() else float("nan")
        mhi = float(np.mean(ehi[fin])) if fin.any() else float("nan")
        if not fin.any():
            verdict = "undetermined (no finite aided interval)"
        elif mlo <= -L95 and mhi >= L95:
            verdict = "superset of the stationary 95% level"
        elif mlo >= -L95 and mhi <= L95:
            verdict = "sharper than the stationary 95% level"
        else:
            verdict = "overlaps the stationary 95% level"
        ch_out: dict[str, Any] = {
            "unit": CHANNEL_UNITS[ch],
            "bound_halfwidth": float(st.half[c]),
            "steps_finite": int(fin.sum()),
            "dynamic_error_mean_interval": [mlo, mhi],
            "dynamic_error_mean_midpoint": float(np.mean(0.5 * (elo + ehi)[fin]))
            if fin.any()
            else float("nan"),
            "aided_mean_width": float(np.mean((ahi - alo)[fin])) if fin.any() else float("nan"),
            "aided_median_width": float(np.median((ahi - alo)[fin])) if fin.any() else float("nan"),
            "estimate_mean_width": float(np.mean(dhi - dlo)),
            "measurement_inside_aided": float(np.mean((alo <= meas) & (meas <= ahi))),
            "stationary_level_95": L95,
            "ratio_to_stationary_95": (max(-mlo, mhi) / L95)
            if (L95 > 0 and fin.any())
            else float("nan"),
            "verdict": verdict,
        }
        if ch == "gyro_z":
            ch_out["in_deg_per_s"] = {
                "dynamic_error_mean_interval": [math.degrees(mlo), math.degrees(mhi)],
                "stationary_level_95": math.degrees(L95),
            }
        if st.truth is not None:
            key = {"accel_x": "accel_x", "accel_y": "accel_y", "gyro_z": "r"}[ch]
            if key in st.truth:
                tv = st.truth[key][sl]
                ok = np.isfinite(tv)
                if ok.any():
                    ch_out["enclosure"] = {
                        "aided": float(np.mean(((alo <= tv) & (tv <= ahi))[ok])),
                        "estimate": float(np.mean(((dlo <= tv) & (tv <= dhi))[ok])),
                        "measurement_interval": float(
                            np.mean(((res.M[sl, 2 * c] <= tv) & (tv <= res.M[sl, 2 * c + 1]))[ok])
                        ),
                        "steps": int(ok.sum()),
                    }
        out["channels"][ch] = ch_out
    if st.truth is not None:
        tr = st.truth
        ok = np.isfinite(tr["east"])
        inside = (
            (res.S[:, 0] <= tr["east"])
            & (tr["east"] <= res.S[:, 1])
            & (res.S[:, 2] <= tr["north"])
            & (tr["north"] <= res.S[:, 3])
        )
        g_ok = ok & np.isfinite(st.gps[:, 0])
        g_in = (
            (st.gps[:, 0] <= tr["east"])
            & (tr["east"] <= st.gps[:, 1])
            & (st.gps[:, 2] <= tr["north"])
            & (tr["north"] <= st.gps[:, 3])
        )
        enc: dict[str, Any] = {
            "position_box": float(np.mean(inside[ok])),
            "gps_box": float(np.mean(g_in[g_ok])) if g_ok.any() else float("nan"),
            "steps": int(ok.sum()),
        }
        if "psi" in tr:
            pk = ok & np.isfinite(tr["psi"])
            enc["heading"] = float(
                np.mean(_psi_contains(res.S[pk, 8], res.S[pk, 9], tr["psi"][pk]))
            )
            h_ok = pk & np.isfinite(st.heading[:, 0])
            if h_ok.any():
                hc, hh = st.heading[h_ok, 0], st.heading[h_ok, 1]
                enc["compass_interval"] = float(
                    np.mean(_psi_contains(hc - hh, hc + hh, tr["psi"][h_ok]))
                )
        for q, i in (("u", 4), ("v", 6)):
            if q in tr:
                qk = ok & np.isfinite(tr[q])
                enc[q] = float(
                    np.mean(((res.S[:, i] <= tr[q]) & (tr[q] <= res.S[:, i + 1]))[qk])
                )
        out["enclosure"] = enc
    # empty intersections
    empties: dict[str, Any] = {}
    for bit, name in K.FLAG_NAMES.items():
        hit = np.flatnonzero(res.flags & bit)
        empties[name] = {
            "count": int(hit.size),
            "first_times_s": [float(st.t[i] - st.t[0]) for i in hit[:100]],
        }
    out["flags"] = empties
    out["empty_rule"] = {
        "keep": "keep the prediction",
        "reset": "reset to the aiding measurement",
        "qrelax": f"q-relaxed intersection (q={cfg.q_outliers}) of the prediction and the "
        f"aiding intervals of the last {cfg.window} steps carried forward",
    }[cfg.fallback]
    w = res.S[:, 1] - res.S[:, 0]
    out["position_box_mean_width_m"] = [
        float(np.mean(w[np.isfinite(w)])),
        float(np.mean((res.S[:, 3] - res.S[:, 2])[np.isfinite(w)])),
    ]
    out["gps_box_mean_width_m"] = float(np.nanmean(st.gps[:, 1] - st.gps[:, 0]))
    out["counts"] = st.counts
    out["waltz_sweeps"] = res.sweeps
    return out


def config_for_drive(drive: Any, imu: ImuSpec | None = None, **overrides: Any) -> EstimatorConfig:
    """Settings of the paper estimator for a drive: ``drive.settings`` (drive.yaml) gives
    the GNSS CEP, default HDOP and the compass calibration; ``overrides`` (non-None
    values) win; the IMU spec defaults to the MTx datasheet."""
    from imubounds.dynamic.sensors.heading import swing_deviation
    from imubounds.presets import XSENS_MTX

    st = drive.settings
    base: dict[str, Any] = {
        "gps_cep_m": st.gnss.cep_m,
        "default_hdop": st.gnss.default_hdop,
        "declination_rad": math.radians(st.heading.declination_deg),
    }
    cal = st.heading.calibration
    if isinstance(cal, np.ndarray):
        base["deviation"] = swing_deviation(cal)
    elif cal:
        p = Path(cal)
        if not p.is_absolute():
            p = Path(str(drive.source)) / p
        base["deviation"] = swing_deviation(p)
    base["imu"] = imu or ImuSpec(
        accel={t: XSENS_MTX.accel[t] for t in ("N", "B")},
        gyro={t: XSENS_MTX.gyro[t] for t in ("N", "B")},
        source="mtx datasheet",
    )
    base.update({k: v for k, v in overrides.items() if v is not None})
    return EstimatorConfig(**base)


def config_dict(cfg: EstimatorConfig) -> dict[str, Any]:
    d = asdict(cfg)
    d["deviation"] = cfg.deviation.to_dict() if cfg.deviation is not None else None
    return d


# --------------------------------------------------------------------- mode block


def imu_spec_from(drive: Any, noise: Any, imu_spec: str | None) -> ImuSpec:
    """N and B per channel: --imu-spec > noise.json > drive.yaml > MTx datasheet (the
    noise.json reader is :func:`imubounds.dynamic.estimator.budget.read_noise_json`)."""
    from imubounds.dynamic.estimator.budget import resolve_noise

    terms, _ = resolve_noise(drive.settings, noise, {"imu_spec": imu_spec}, None)
    per = {ch: {"N": terms[ch].N, "B": terms[ch].B} for ch in CHANNELS}
    src = {terms[ch].sources["N"] for ch in CHANNELS}
    return ImuSpec(
        accel=per["accel_x"], gyro=per["gyro_z"], per_channel=per, source=", ".join(sorted(src))
    )


def run_paper(drive: Any, noise: Any = None, **options: Any) -> Any:
    """Mode paper on a drive: the per-step estimator and its dynamic.json block."""
    from imubounds.dynamic.estimator.result import NOT_GUARANTEED, DynamicResult

    imu_spec = options.pop("imu_spec", None)
    known = set(EstimatorConfig.__dataclass_fields__) - {"imu"}
    unknown = set(options) - known
    if unknown:
        raise OptionError(
            f"unknown option(s) for mode paper: {', '.join(sorted(unknown))}; "
            f"known: {', '.join(sorted(known))}"
        )
    cfg = config_for_drive(drive, imu_spec_from(drive, noise, imu_spec), **options)
    res = run(drive, cfg)
    return DynamicResult("paper", paper_block(res, NOT_GUARANTEED), paper=res)


def paper_block(res: EstimatorResult, statement: str) -> dict[str, Any]:
    """The schema block of mode paper (margins at tau = the step, the paper's level)."""
    s = res.summary
    cfg = res.config
    st = res.steps
    T = s["duration_s"]
    out: dict[str, Any] = {
        "mode": "paper",
        "guaranteed": False,
        "statement": statement,
        "kinematics": cfg.kinematics,
        "margins": {},
        "verdict": {},
        "budget": {},
    }
    sl = slice(1, st.t.size)
    for c, ch in enumerate(CHANNELS):
        co = s["channels"][ch]
        alo, ahi = res.A[sl, 2 * c], res.A[sl, 2 * c + 1]
        fin = np.isfinite(alo) & np.isfinite(ahi)
        hw = 0.5 * (ahi - alo)[fin]
        L95 = co["stationary_level_95"]
        meas = st.meas[sl, c][fin]
        elo, ehi = alo[fin] - meas, ahi[fin] - meas
        own = "m/s" if ch.startswith("accel") else "rad"
        out["margins"][ch] = [
            {
                "tau_s": float(st.dt),
                "halfwidth_max": float(np.max(hw)) if hw.size else None,
                "halfwidth_median": float(np.median(hw)) if hw.size else None,
                "stationary": L95,
                "stationary_unit": own,
                "exceeds_fraction": float(np.mean((elo > L95) | (ehi < -L95)))
                if hw.size
                else 0.0,
                "unit": CHANNEL_UNITS[ch],
                "note": "the paper compares 1.96 N sqrt(T) (unit "
                + own
                + ") with margins in "
                + CHANNEL_UNITS[ch]
                + "; not unit-correct, kept to reproduce the paper",
            }
        ]
        v = co["verdict"]
        out["verdict"][ch] = (
            "exceeds" if v.startswith("superset") else "consistent" if v.startswith("sharper")
            else "undecided"
        )
        N = cfg.imu.coeffs(ch)["N"]
        B = cfg.imu.coeffs(ch)["B"]
        out["budget"][ch] = [
            {"term": "white noise density N", "value": N, "unit": own + "/s^0.5",
             "source": cfg.imu.source, "assumption": "the paper's sigma_c"},
            {"term": "bias instability B", "value": B, "unit": CHANNEL_UNITS[ch],
             "source": cfg.imu.source, "assumption": "divided by sqrt(t/dt) (the paper)"},
            {"term": "k", "value": cfg.k_sigma, "unit": "", "source": "option",
             "assumption": "one k per step (not over the trip)"},
            {"term": "per-step half-width k sigma_c", "value": float(st.half[c]),
             "unit": CHANNEL_UNITS[ch], "source": "computed", "assumption": statement},
            {"term": "stationary 95 % level 1.96 N sqrt(T)", "value": L95, "unit": own,
             "source": "computed", "assumption": f"T = {T:.1f} s"},
        ]
    if "enclosure" in s:
        e = s["enclosure"]
        out["enclosure"] = {
            "position": e.get("position_box"),
            "heading": e.get("heading"),
            "u": e.get("u"),
            "v": e.get("v"),
            "gps_box": e.get("gps_box"),
            "steps": e.get("steps"),
        }
        for ch, co in s["channels"].items():
            if "enclosure" in co:
                out["enclosure"][f"aided_{ch}"] = co["enclosure"]["aided"]
    n_empty = sum(v["count"] for k, v in s["flags"].items() if "empty" in k)
    out["empty_intersections"] = {
        "count": n_empty,
        "rule": s["empty_rule"],
        "by_flag": {k: v["count"] for k, v in s["flags"].items() if v["count"]},
    }
    out["settings"] = config_dict(cfg)
    out["details"] = s
    return out
