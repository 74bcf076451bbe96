"""IMU errors of a simulated trip and the bounds stated for them.

Sample model (METHOD.md 4.1, one channel ``c`` of the six)::

    y_c = x_c + s_c x_c + sum_j m_cj x_j + b_c + d_c(t) + w_c + fault_c(t)

``x`` the true mean of the specific force (or body rate) over the sample's
period, ``s`` a scale-factor error, ``m`` a cross-axis misalignment (within the
accelerometer triad or the gyro triad), ``b`` the turn-on bias, ``d(t)`` the
in-run bias wander (flicker noise of level B, plus rate random walk K when the
preset has one), ``w`` white noise of density N (per-sample deviation N/sqrt(dt)).
Every term is a Gaussian (or flicker) draw: nothing is bounded unless
``bounded=True``. White noise and bias wander come from
:func:`imubounds.stationary.noise_sim.simulate_axis`.

The bounds stated for them (``drive.yaml``: imu, and the record), at a whole-trip
risk ``alpha`` per stream with ``k(n) = Phi^-1(1 - alpha/(2n))``:

* white noise per sample: ``k(6 n) N / sqrt(dt)`` over the n samples of the six
  channels (the estimator derives it from ``accel_nd``/``gyro_nd``);
* turn-on bias: ``k(6) sigma_turn_on`` (``accel_turn_on_mps2``, ``gyro_turn_on_dps``);
* bias drift: the wander averaged over any window of at least ``tau_lo`` (the
  lower end of the flicker range, 1 s) stays within
  ``k(6 T / tau_lo) sqrt(sigma_d(tau_lo)^2 + K^2 T)`` with ``sigma_d(tau)`` the
  deviation of the wander's ``tau``-mean (``accel_bias_drift_mps2``,
  ``gyro_bias_drift_dps``);
* scale factor ``k(6) sigma_s`` and misalignment ``k(12) sigma_m`` when simulated.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from functools import lru_cache

import numpy as np
from scipy.stats import norm

from imubounds.dynamic.scenario.config import ScenarioConfig
from imubounds.dynamic.scenario.imu_noise import load_imu_noise, preset_noise
from imubounds.dynamic.scenario.record import (
    Check,
    check,
    octave_windows,
    white_interval_sums,
    window_means,
)
from imubounds.presets import get_preset
from imubounds.stationary import noise_sim
from imubounds.stationary.models import GaussMarkovModel

Array = np.ndarray

#: Channel order of the IMU arrays: accelerometer x, y, z then gyro x, y, z (FLU).
CHANNELS: tuple[str, ...] = ("accel_x", "accel_y", "accel_z", "gyro_x", "gyro_y", "gyro_z")
#: Rate at which the slow bias wander is generated and then interpolated.
WANDER_RATE_HZ = 10.0


def k_level(alpha: float, n: float) -> float:
    """``Phi^-1(1 - alpha/(2n))``: the two-sided Sidak/Bonferroni factor for ``n`` samples."""
    return float(norm.isf(alpha / (2.0 * max(n, 1.0))))


def truncated_normal(
    rng: np.random.Generator,
    sigma: Array | float,
    bound: Array | float,
    shape: int | tuple[int, ...],
) -> Array:
    """Normal(0, sigma) draws redrawn until ``|x| <= bound`` (elementwise)."""
    size = shape if isinstance(shape, tuple) else (shape,)
    sig = np.broadcast_to(np.asarray(sigma, dtype=float), size)
    bnd = np.broadcast_to(np.asarray(bound, dtype=float), size)
    x = rng.standard_normal(size) * sig
    bad = np.abs(x) > bnd
    while np.any(bad):
        x[bad] = rng.standard_normal(int(bad.sum())) * sig[bad]
        bad = np.abs(x) > bnd
    return x


@lru_cache(maxsize=32)
def _flicker(B: float, lo: float, hi: float) -> tuple[GaussMarkovModel, ...]:
    return noise_sim.flicker_gm_terms(B, (lo, hi))


def _window_mean_factor(beta: float, tau: float) -> float:
    """Variance of the tau-mean of a unit Gauss-Markov process of rate ``beta``."""
    x = beta * tau
    if x < 1e-6:
        return 1.0
    return 2.0 * (x - 1.0 + math.exp(-x)) / (x * x)


@dataclass
class ImuFigures:
    """The simulated noise and the stated bounds, SI.

    ``axes`` holds each channel's simulated noise (:class:`~imubounds.stationary.noise_sim.
    AxisNoise`: N, Q, B, K, R); ``N``, ``B``, ``K`` and the bounds are per sensor kind
    (``accel``, ``gyro``), the largest over its three axes (what ``drive.yaml`` states)."""

    N: dict[str, float]
    B: dict[str, float]
    K: dict[str, float]
    turn_on_sigma: dict[str, float]
    turn_on_bound: dict[str, float]
    drift_sigma: dict[str, float]  # deviation of the wander's tau_lo-mean (with K^2 T)
    drift_bound: dict[str, float]
    drift_window_s: float
    scale_bound: float | None
    misalignment_bound_rad: float | None
    preset: str
    axes: dict[str, noise_sim.AxisNoise] = field(default_factory=dict)
    source: str = ""
    notes: tuple[str, ...] = ()

    def white_sigma(self, ch: str, tau: Array | float, dt: float) -> Array:
        """Deviation of the white part (N, and Q: differences of a white angle/velocity
        error) averaged over ``tau`` (>= one sample ``dt``): ``sqrt(N^2/tau + 2Q^2/tau^2)``;
        times ``tau`` it is the deviation of its integral."""
        ax = self.axes[ch]
        t = np.maximum(np.asarray(tau, dtype=float), dt)
        return np.asarray(np.sqrt(ax.N**2 / t + 2.0 * ax.Q**2 / t**2))

    def to_dict(self) -> dict[str, object]:
        return {
            "preset": self.preset,
            "noise_source": self.source,
            "N": self.N,
            "B": self.B,
            "K": self.K,
            "axes": {
                ch: {t: getattr(ax, t) for t in noise_sim.TERMS} for ch, ax in self.axes.items()
            },
            "noise_notes": list(self.notes),
            "turn_on_sigma": self.turn_on_sigma,
            "turn_on_bound": self.turn_on_bound,
            "drift_sigma": self.drift_sigma,
            "drift_bound": self.drift_bound,
            "drift_window_s": self.drift_window_s,
            "scale_bound": self.scale_bound,
            "misalignment_bound_rad": self.misalignment_bound_rad,
            "units": "SI: N m/s^1.5 | rad/s^0.5; Q m/s | rad; K m/s^2.5 | rad/s^1.5; R m/s^3 | "
            "rad/s^2; B, bounds m/s^2 | rad/s",
        }


def _scaled_axes(cfg: ScenarioConfig) -> tuple[dict[str, noise_sim.AxisNoise], str, list[str]]:
    """Each channel's noise (preset or noise.json) scaled by ``noise_scale``, without bias
    terms when ``imu_bias`` is off; the source and notes."""
    src = load_imu_noise(cfg) if cfg.imu_noise is not None else preset_noise(cfg)
    s = cfg.noise_scale
    notes = list(src.notes)
    axes = {}
    for ch, ax in src.axes.items():
        on = s if cfg.imu_bias else 0.0
        q = 0.0 if cfg.bounded else ax.Q * s
        if cfg.bounded and ax.Q > 0:
            notes.append(f"{ch} Q: not simulated with --bounded (white noise drawn truncated)")
        axes[ch] = replace(ax, N=ax.N * s, Q=q, B=ax.B * on, K=ax.K * on, R=ax.R * on)
    return axes, src.source, notes


def imu_figures(cfg: ScenarioConfig) -> ImuFigures:
    """The simulated noise (preset or noise.json, scaled by ``noise_scale``) and the bounds
    stated for it."""
    axes, source, notes = _scaled_axes(cfg)
    pre = get_preset(cfg.imu_preset).kind if cfg.imu_noise is None else None
    T = cfg.duration_s
    lo = cfg.bias_tau_range_s[0]
    k_d = k_level(cfg.alpha, 6 * max(1.0, T / lo))
    N, B, K, to_s, to_b, d_s, d_b = ({} for _ in range(7))
    for kind in ("accel", "gyro"):
        mine = [ax for ch, ax in axes.items() if ch.startswith(kind)]
        N[kind] = max(ax.N for ax in mine)
        B[kind] = max(ax.B for ax in mine)
        K[kind] = max(ax.K for ax in mine)
        base = pre(kind).get("turn_on_bias") if pre is not None else None
        if base is None:
            to_s[kind] = B[kind] * cfg.turn_on_scale
        else:
            to_s[kind] = base * cfg.turn_on_scale * cfg.noise_scale if cfg.imu_bias else 0.0
        to_b[kind] = k_level(cfg.alpha, 6) * to_s[kind]
        sig = []
        for ax in mine:
            var = sum(
                g.sigma**2 * _window_mean_factor(g.beta, lo)
                for g in _flicker(ax.B, *cfg.bias_tau_range_s)
            )
            sig.append((math.sqrt(var + ax.K**2 * T), ax.R * T))
        d_s[kind] = max(x for x, _ in sig)
        d_b[kind] = max(k_d * x + r for x, r in sig)
    return ImuFigures(
        N=N,
        B=B,
        K=K,
        turn_on_sigma=to_s,
        turn_on_bound=to_b,
        drift_sigma=d_s,
        drift_bound=d_b,
        drift_window_s=lo,
        scale_bound=k_level(cfg.alpha, 6) * cfg.scale_error if cfg.scale_error else None,
        misalignment_bound_rad=(
            k_level(cfg.alpha, 12) * math.radians(cfg.misalignment_deg)
            if cfg.misalignment_deg
            else None
        ),
        preset=get_preset(cfg.imu_preset).key if cfg.imu_noise is None else "noise.json",
        axes=axes,
        source=source,
        notes=tuple(notes),
    )


def drift_process(
    B: float,
    K: float,
    tau_range_s: tuple[float, float],
    n: int,
    rate_hz: float,
    seed: np.random.SeedSequence,
) -> Array:
    """``n`` samples at ``rate_hz`` of the in-run bias drift: flicker noise of level ``B``
    over ``tau_range_s`` as the noise simulator builds it (a sum of Gauss-Markov processes,
    :func:`imubounds.stationary.noise_sim.flicker_gm_terms`) plus a rate random walk ``K``."""
    gms = _flicker(B, *tau_range_s) if B > 0 else ()
    subs = seed.spawn(len(gms) + 1)
    d = np.zeros(n)
    for g, s in zip(gms, subs, strict=False):
        d += g.simulate(n, rate_hz, np.random.default_rng(s))
    if K > 0:
        steps = np.random.default_rng(subs[-1]).standard_normal(n) * (K / math.sqrt(rate_hz))
        steps[0] = 0.0
        d += np.cumsum(steps)
    return d


@dataclass
class ImuErrors:
    """Every error term of the simulated IMU, (n, 6) in :data:`CHANNELS` order, SI."""

    white: Array
    turn_on: Array  # (6,)
    drift: Array  # (n, 6) bias wander
    scale: Array  # (6,)
    misalignment: Array  # (2, 3, 3): accel and gyro triads, zero diagonal
    fault: Array  # (n, 6)
    figures: ImuFigures
    notes: list[str] = field(default_factory=list)

    def bias(self) -> Array:
        """Turn-on bias plus drift, (n, 6)."""
        return self.turn_on[None, :] + self.drift

    def summary(self) -> dict[str, object]:
        """The true values of every term, for ``scenario.json`` (SI)."""
        out: dict[str, object] = {}
        for j, ch in enumerate(CHANNELS):
            d = self.drift[:, j]
            tri = 0 if j < 3 else 1
            out[ch] = {
                "turn_on_bias": float(self.turn_on[j]),
                "bias_drift_mean": float(d.mean()),
                "bias_drift_min": float(d.min()),
                "bias_drift_max": float(d.max()),
                "bias_drift_std": float(d.std()),
                "white_std": float(self.white[:, j].std()),
                "scale_error": float(self.scale[j]),
                "misalignment_row": [float(x) for x in self.misalignment[tri, j % 3]],
            }
        return out


def simulate_errors(
    cfg: ScenarioConfig,
    t: Array,
    truth_mean: Array,
    seeds: dict[str, np.random.SeedSequence],
    epoch_times: Array | None = None,
) -> tuple[Array, ImuErrors]:
    """The measured IMU (n, 6) for true period means ``truth_mean`` (n, 6) at stamps ``t``."""
    n = t.size
    dt = 1.0 / cfg.rate_hz
    fig = imu_figures(cfg)
    kinds = ["accel"] * 3 + ["gyro"] * 3
    white = np.zeros((n, 6))
    drift = np.zeros((n, 6))
    rng = np.random.default_rng(seeds["imu_static"])
    wseeds = seeds["imu_white"].spawn(6)
    dseeds = seeds["imu_drift"].spawn(6)
    kw = k_level(cfg.alpha, 6 * n)
    for j, ch in enumerate(CHANNELS):
        ax = fig.axes[ch]
        N = ax.N
        if cfg.bounded:
            white[:, j] = truncated_normal(
                np.random.default_rng(wseeds[j]), N / math.sqrt(dt), kw * N / math.sqrt(dt), n
            )
        elif N > 0 or ax.Q > 0:
            white[:, j] = noise_sim.simulate_axis(
                noise_sim.AxisNoise(N=N, Q=ax.Q), n, cfg.rate_hz, wseeds[j]
            )
        if ax.B > 0 or ax.K > 0:
            slow = min(cfg.rate_hz, WANDER_RATE_HZ)
            m = int(math.ceil(cfg.duration_s * slow)) + 2
            d = drift_process(ax.B, ax.K, cfg.bias_tau_range_s, m, slow, dseeds[j])
            drift[:, j] = np.interp(t, np.arange(m) / slow, d)
        if ax.R > 0:  # the rate ramp of the noise simulator: R t from the first sample
            drift[:, j] += ax.R * (t - t[0])
    sig_to = np.array([fig.turn_on_sigma[k] for k in kinds])
    if cfg.bounded:
        turn_on = truncated_normal(rng, sig_to, np.array([fig.turn_on_bound[k] for k in kinds]), 6)
    else:
        turn_on = rng.standard_normal(6) * sig_to
    scale = np.zeros(6)
    if cfg.scale_error:
        assert fig.scale_bound is not None
        scale = (
            truncated_normal(rng, cfg.scale_error, fig.scale_bound, 6)
            if cfg.bounded
            else rng.standard_normal(6) * cfg.scale_error
        )
    mis = np.zeros((2, 3, 3))
    if cfg.misalignment_deg:
        assert fig.misalignment_bound_rad is not None
        sm = math.radians(cfg.misalignment_deg)
        vals = (
            truncated_normal(rng, sm, fig.misalignment_bound_rad, 12)
            if cfg.bounded
            else rng.standard_normal(12) * sm
        )
        off = ~np.eye(3, dtype=bool)
        mis[0][off] = vals[:6]
        mis[1][off] = vals[6:]
    notes: list[str] = list(fig.notes)
    if cfg.bounded:
        notes += _bound_drift(cfg, t, drift, fig, kinds)
        if epoch_times is not None:
            notes += bound_white(cfg, t, white, fig, epoch_times)
    fault = np.zeros((n, 6))
    for f in cfg.faults:
        j = CHANNELS.index(f.channel)
        frac = np.clip((t - f.t0_s) / dt, 0.0, 1.0)  # share of [t - dt, t] after t0
        fault[:, j] += f.value * frac * (1.0 if f.kind == "bias" else truth_mean[:, j])
    meas = truth_mean.copy()
    if np.any(scale):
        meas += scale[None, :] * truth_mean
    if np.any(mis):  # einsum, not a BLAS call: no thread pool for 3x3 products
        meas[:, :3] += np.einsum("ij,nj->ni", mis[0], truth_mean[:, :3])
        meas[:, 3:] += np.einsum("ij,nj->ni", mis[1], truth_mean[:, 3:])
    meas += turn_on[None, :] + drift + white + fault
    return meas, ImuErrors(white, turn_on, drift, scale, mis, fault, fig, notes)


def _bound_drift(
    cfg: ScenarioConfig, t: Array, drift: Array, fig: ImuFigures, kinds: list[str]
) -> list[str]:
    """``bounded``: shrink a channel's drift whose window means leave the drift bound."""
    notes = []
    dt = 1.0 / cfg.rate_hz
    wins = octave_windows(t.size, int(round(fig.drift_window_s / dt)), cfg.duration_s / 4, dt)
    for j, kind in enumerate(kinds):
        means = window_means(drift[:, j], wins)[0]
        worst = float(np.abs(means).max()) if means.size else 0.0
        bound = fig.drift_bound[kind]
        if worst > bound > 0:
            drift[:, j] *= 0.999 * bound / worst
            notes.append(f"bounded: {CHANNELS[j]} drift scaled by {0.999 * bound / worst:.3f}")
    return notes


def epoch_indices(t: Array, epoch_times: Array) -> Array:
    """Sample indices of the aiding epochs inside the IMU's span (sorted, unique)."""
    dt = float(t[1] - t[0])
    i = np.unique(np.rint((np.asarray(epoch_times) - t[0]) / dt).astype(np.int64))
    return i[(i >= 0) & (i < t.size)]


def imu_checks(cfg: ScenarioConfig, t: Array, err: ImuErrors, epoch_times: Array) -> list[Check]:
    """The IMU part of the record (see :mod:`.record` for the definitions)."""
    n = t.size
    dt = 1.0 / cfg.rate_hz
    fig = err.figures
    a = cfg.alpha
    # k over the six channels' samples: one level for the whole IMU stream
    k_s = k_level(a, 6 * n)
    eidx = epoch_indices(t, epoch_times)
    wins = octave_windows(n, 1, cfg.duration_s / 4, dt)
    k_w = k_level(a, 6 * sum(w for _, w in wins))
    dwins = octave_windows(n, int(round(fig.drift_window_s / dt)), cfg.duration_s / 4, dt)
    out: list[Check] = []
    for j, ch in enumerate(CHANNELS):
        kind = "accel" if j < 3 else "gyro"
        unit = "m/s^2" if j < 3 else "rad/s"
        w = err.white[:, j]
        out.append(
            check(
                f"imu.{ch}.white_sample",
                "imu",
                unit,
                "|white noise| <= k(n) N/sqrt(dt) per sample (with Q: k(n) sqrt(N^2/dt + "
                "2Q^2/dt^2))",
                w,
                k_s * float(fig.white_sigma(ch, dt, dt)),
                t,
                k=k_s,
            )
        )
        if eidx.size >= 2:
            sums, dur, ends = white_interval_sums(w, dt, eidx)
            k_m = k_level(a, 6 * sums.size)
            out.append(
                check(
                    f"imu.{ch}.white_interval",
                    "imu",
                    "m/s" if j < 3 else "rad",
                    "|white noise integrated between consecutive aiding epochs| <= "
                    "k(m) N sqrt(interval) (with Q: k(m) sqrt(N^2 interval + 2Q^2))",
                    sums,
                    k_m * dur * fig.white_sigma(ch, dur, dt),
                    t[ends],
                    k=k_m,
                    index=ends,
                )
            )
        if wins:
            means, size, ends = window_means(w, wins)
            out.append(
                check(
                    f"imu.{ch}.white_window",
                    "imu",
                    unit,
                    "|white noise averaged over an octave window tau| <= k(M) N/sqrt(tau), "
                    "M windows of one sample to T/4 (with Q: k(M) sqrt(N^2/tau + 2Q^2/tau^2))",
                    means,
                    k_w * fig.white_sigma(ch, size * dt, dt),
                    t[ends],
                    k=k_w,
                    index=ends,
                )
            )
        out.append(
            check(
                f"imu.{ch}.turn_on",
                "imu",
                unit,
                "|turn-on bias| <= the stated turn-on bound",
                err.turn_on[j : j + 1],
                fig.turn_on_bound[kind],
                t[:1],
                k=k_level(a, 6),
            )
        )
        if dwins:
            means, _, ends = window_means(err.drift[:, j], dwins)
            out.append(
                check(
                    f"imu.{ch}.bias_drift",
                    "imu",
                    unit,
                    f"|bias drift averaged over an octave window of {fig.drift_window_s:g} s "
                    "to T/4| <= the stated drift bound",
                    means,
                    fig.drift_bound[kind],
                    t[ends],
                    k=k_level(a, 6 * max(1.0, cfg.duration_s / fig.drift_window_s)),
                    index=ends,
                )
            )
        if fig.scale_bound is not None:
            out.append(
                check(
                    f"imu.{ch}.scale",
                    "imu",
                    "1",
                    "|scale-factor error| <= the stated bound",
                    err.scale[j : j + 1],
                    fig.scale_bound,
                    t[:1],
                    k=k_level(a, 6),
                )
            )
        if fig.misalignment_bound_rad is not None:
            row = err.misalignment[0 if j < 3 else 1, j % 3]
            out.append(
                check(
                    f"imu.{ch}.misalignment",
                    "imu",
                    "rad",
                    "|misalignment of this axis towards the other two| <= the stated bound",
                    row[None, :],
                    fig.misalignment_bound_rad,
                    t[:1],
                    k=k_level(a, 12),
                )
            )
    return out


def bound_white(
    cfg: ScenarioConfig, t: Array, white: Array, fig: ImuFigures, epoch_times: Array
) -> list[str]:
    """``bounded``: shrink a channel's white noise until its interval and window sums stay
    inside their bounds (per-sample draws are already truncated)."""
    notes = []
    dummy = ImuErrors(
        white,
        np.zeros(6),
        np.zeros_like(white),
        np.zeros(6),
        np.zeros((2, 3, 3)),
        np.zeros_like(white),
        fig,
    )
    for _ in range(50):
        bad = {
            c.name.split(".")[1]
            for c in imu_checks(cfg, t, dummy, epoch_times)
            if c.count and (c.name.endswith("white_interval") or c.name.endswith("white_window"))
        }
        if not bad:
            break
        for ch in bad:
            white[:, CHANNELS.index(ch)] *= 0.95
        notes.append(f"bounded: white noise of {', '.join(sorted(bad))} scaled by 0.95")
    return notes
