"""Put a drive log on one step, run the interval estimator, summarise (METHOD.md 3.2-3.4).

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
from typing import Any

import numpy as np

from imubounds.dynamic.aiding.compass import (
    ZERO_DEVIATION,
    CompassDeviation,
    course_over_ground,
    fit_deviation,
    heading_from_magnetometer,
    heading_intervals,
)
from imubounds.dynamic.aiding.geodesy import geodetic_to_enu
from imubounds.dynamic.aiding.gps import gps_box_halfwidths, parse_gps_box
from imubounds.dynamic.estimator import kernel as K
from imubounds.errors import AnalysisError, OptionError
from imubounds.io.drive_legacy import DriveLog
from imubounds.stationary.bounds import interval_halfwidth, level_95_si

CHANNELS: tuple[str, ...] = ("accel_x", "accel_y", "gyro_z")
CHANNEL_UNITS = {"accel_x": "m/s^2", "accel_y": "m/s^2", "gyro_z": "rad/s"}
MODES = {"paper": 0, "full": 1}
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
    mode: str = "full"
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
    gps_cep_m: float = 3.0
    gps_box: str = "p=0.999"
    default_hdop: float = 1.0
    geodesy: str = "wgs84"
    compass_mode: str = "corrected"
    compass_floor_rad: float = 0.5 * math.pi / 180.0
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
        if self.mode not in MODES:
            raise OptionError(f"--mode must be paper or full, got {self.mode!r}")
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
    gps_centre: np.ndarray  # (n, 2)
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


def prepare_steps(log: DriveLog, cfg: EstimatorConfig) -> StepData:
    """Put ``log`` on the estimator's step (see the module docstring)."""
    cfg.check()
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
    truth = _truth_at_steps(log, t, origin, cfg) if log.truth is not None else None
    return StepData(
        t=t,
        dt=dt,
        meas=meas,
        half=half,
        gps=gps,
        gps_centre=cen[:, :2],
        heading=heading,
        origin=origin,
        deviation=dev,
        truth=truth,
        counts=counts,
        warnings=warnings + [f"heading source: {h_src}"],
    )


def _truth_at_steps(
    log: DriveLog, t: np.ndarray, origin: tuple[float, float, float], cfg: EstimatorConfig
) -> dict[str, np.ndarray]:
    tr = log.truth
    assert tr is not None
    tt = tr["t"]
    out: dict[str, np.ndarray] = {}
    if "lat" in tr:
        e, n, _ = geodetic_to_enu(
            tr["lat"], tr["lon"], None, origin=(origin[0], origin[1], 0.0), method=cfg.geodesy
        )
    else:
        e, n = tr["east"], tr["north"]
    inside = (t >= tt[0] - 1e-9) & (t <= tt[-1] + 1e-9)
    for name, vals in (
        ("east", e),
        ("north", n),
        ("psi", np.unwrap(tr["psi"])),
        ("u", tr["u"]),
        ("v", tr["v"]),
    ):
        out[name] = np.where(inside, np.interp(t, tt, vals), np.nan)
    for name in ("accel_x", "accel_y", "r"):
        if name not in tr:
            continue
        on_rows = np.all([np.any(np.abs(tt - tk) < 1e-6) for tk in t[1:]])
        if on_rows and np.allclose(np.diff(tt), t[1] - t[0], rtol=1e-6):
            out[name] = np.where(inside, np.interp(t, tt, tr[name]), np.nan)
        else:
            out[name] = _step_average(tt, tr[name], t)
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


def run(log_or_steps: DriveLog | StepData, cfg: EstimatorConfig) -> EstimatorResult:
    """Run the estimator (compiled loop) on a drive log or prepared steps."""
    steps = log_or_steps if isinstance(log_or_steps, StepData) else prepare_steps(log_or_steps, cfg)
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
        MODES[cfg.mode],
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
            "heading": float(np.mean(_psi_contains(res.S[ok, 8], res.S[ok, 9], tr["psi"][ok]))),
            "u": float(np.mean(((res.S[:, 4] <= tr["u"]) & (tr["u"] <= res.S[:, 5]))[ok])),
            "v": float(np.mean(((res.S[:, 6] <= tr["v"]) & (tr["v"] <= res.S[:, 7]))[ok])),
            "steps": int(ok.sum()),
        }
        h_ok = ok & np.isfinite(st.heading[:, 0])
        if h_ok.any():
            hc, hh = st.heading[h_ok, 0], st.heading[h_ok, 1]
            enc["compass_interval"] = float(
                np.mean(_psi_contains(hc - hh, hc + hh, tr["psi"][h_ok]))
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


def config_for_log(log: DriveLog, imu: ImuSpec | None = None, **overrides: Any) -> EstimatorConfig:
    """Estimator settings for ``log``: a simulator directory supplies its own bounds.

    For a ``sim`` log the IMU spec, averaging time, GPS CEP/box, compass
    calibration (``compass_cal.csv``) and floor, and the zero initial speed
    come from ``scenario.json``; ``overrides`` (non-None values) win.
    """
    from pathlib import Path

    from imubounds.dynamic.aiding.compass import read_calibration
    from imubounds.presets import XSENS_MTX

    MTX_SPEC = {k: {t: XSENS_MTX.kind(k)[t] for t in ('N', 'B')} for k in ('accel', 'gyro')}

    base: dict[str, Any] = {}
    if log.layout == "sim":
        est = log.settings.get("estimator", {})
        assert isinstance(est, dict)
        spec = est.get("imu_spec", MTX_SPEC)
        base.update(
            imu=ImuSpec(accel=dict(spec["accel"]), gyro=dict(spec["gyro"]), source="scenario.json"),
            k_sigma=est.get("k_sigma", 3.0),
            t_avg_s=est.get("t_avg_s"),
            gps_cep_m=est.get("gps_cep_m", 3.0),
            gps_box=est.get("gps_box", "p=0.999"),
            compass_mode=est.get("compass_mode", "corrected"),
            compass_floor_rad=est.get("compass_floor_rad", 0.5 * math.pi / 180),
            initial_speed_bound=est.get("initial_speed_bound"),
        )
        cal = Path(log.source) / str(est.get("compass_cal", "compass_cal.csv"))
        if cal.is_file():
            base["deviation"] = read_calibration(str(cal))
    if imu is not None:
        base["imu"] = imu
    if "imu" not in base:
        base["imu"] = ImuSpec(
            accel=dict(MTX_SPEC["accel"]), gyro=dict(MTX_SPEC["gyro"]), source="mtx datasheet"
        )
    base.update({k: v for k, v in overrides.items() if v is not None})
    return EstimatorConfig(**base)


def scenario_model_error(log: DriveLog) -> dict[str, float]:
    """The model-error bounds a simulator directory recorded (zeros otherwise)."""
    est = log.settings.get("estimator", {}) if log.layout == "sim" else {}
    me = est.get("model_error", {}) if isinstance(est, dict) else {}
    return {
        "nav_accel_bound": float(me.get("nav_accel_bound", 0.0)),
        "jerk_bound": float(me.get("jerk_bound", 0.0)),
    }


def config_dict(cfg: EstimatorConfig) -> dict[str, Any]:
    d = asdict(cfg)
    d["deviation"] = cfg.deviation.to_dict() if cfg.deviation is not None else None
    return d
