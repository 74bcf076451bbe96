"""Static logs with known drift, warm-up and rate changes, for tests and benchmarks only.

Independent of :mod:`imubounds.stationary.noise_sim` on purpose (numpy alone): white
rate noise, flicker by 1/f spectral shaping, an exact first-order Gauss–Markov
process (AR(1) with its stationary start), a rate random walk, and the deterministic
disturbances the stationarity checks must find: a bias settling exponentially after
power-on (warm-up), a linear ramp, a slow thermal exponential, and a log spliced
from two sample rates.

Noise parameters follow IEEE 952: Allan variance N²/τ + (2 ln2/π)·B² + K²·τ/3 (+ the
Gauss–Markov's own curve). Units: SI (rad/s or m/s²), time in s.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: A MEMS-grade gyro (rad/s): N ≈ 1 °/√h, B ≈ 10 °/h, K large enough to show in 2 h.
GYRO = {"N": 3e-4, "B": 5e-5, "K": 1e-6}
#: A MEMS-grade accelerometer (m/s²).
ACCEL = {"N": 1e-3, "B": 1e-4, "K": 2e-6}
CHANNELS = ("gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z")


@dataclass(frozen=True)
class Axis:
    """The stochastic terms of one channel (SI): white N, flicker B, random walk K, and
    an optional Gauss–Markov component (σ, correlation time τc in s)."""

    N: float
    B: float
    K: float
    gm_sigma: float = 0.0
    gm_tau_s: float = 0.0


def axis(
    name: str, gm_sigma_over_b: float = 0.0, gm_tau_s: float = 300.0, k_scale: float = 1.0
) -> Axis:
    """The terms of channel ``name`` (:data:`GYRO` or :data:`ACCEL`, K times ``k_scale``)."""
    p = GYRO if name.startswith("gyro") else ACCEL
    return Axis(p["N"], p["B"], p["K"] * k_scale, gm_sigma_over_b * p["B"], gm_tau_s)


def flicker(n: int, rate_hz: float, b: float, rng: np.random.Generator) -> np.ndarray:
    """Flicker rate noise of one-sided PSD B²/(2πf) (Allan deviation 0.664·B), by shaping
    white noise of twice the length in frequency (the first half kept)."""
    if b <= 0:
        return np.zeros(n)
    nf = 2 * n
    dt = 1.0 / rate_hz
    f = np.fft.rfftfreq(nf, dt)
    psd = np.zeros_like(f)
    psd[1:] = b**2 / (2.0 * np.pi * f[1:])
    amp = np.sqrt(psd * nf / (2.0 * dt))
    spec = amp * (rng.standard_normal(f.size) + 1j * rng.standard_normal(f.size))
    return np.fft.irfft(spec, nf)[:n]


def gauss_markov(
    n: int, rate_hz: float, sigma: float, tau_s: float, rng: np.random.Generator
) -> np.ndarray:
    """Exact discrete first-order Gauss–Markov samples, started from its stationary law:
    x_k = φ·x_{k−1} + σ·√(1 − φ²)·w_k, φ = exp(−δt/τc)."""
    if sigma <= 0:
        return np.zeros(n)
    from scipy.signal import lfilter

    phi = np.exp(-1.0 / (rate_hz * tau_s))
    w = rng.standard_normal(n) * sigma * np.sqrt(1.0 - phi**2)
    x0 = rng.standard_normal() * sigma
    out: np.ndarray = lfilter([1.0], [1.0, -phi], w, zi=[phi * x0])[0]
    return out


def noise(ax: Axis, n: int, rate_hz: float, rng: np.random.Generator) -> np.ndarray:
    """White + flicker + random walk (+ Gauss–Markov) rate samples of one channel."""
    dt = 1.0 / rate_hz
    y = rng.standard_normal(n) * ax.N / np.sqrt(dt)
    y += flicker(n, rate_hz, ax.B, rng)
    y += np.cumsum(rng.standard_normal(n)) * ax.K * np.sqrt(dt)
    y += gauss_markov(n, rate_hz, ax.gm_sigma, ax.gm_tau_s, rng)
    return y


@dataclass(frozen=True)
class Disturbance:
    """Deterministic bias changes added to a channel, in units of its B:
    ``warmup_amp`` · B · exp(−t/``warmup_tau_s``), a ramp of ``ramp_total`` · B from the
    first to the last sample, and a thermal settling ``thermal_amp`` · B ·
    (1 − exp(−t/``thermal_tau_s``))."""

    warmup_amp: float = 0.0
    warmup_tau_s: float = 180.0
    ramp_total: float = 0.0
    thermal_amp: float = 0.0
    thermal_tau_s: float = 3600.0

    def signal(self, t: np.ndarray, b: float) -> np.ndarray:
        out = np.zeros_like(t)
        if self.warmup_amp:
            out += self.warmup_amp * b * np.exp(-t / self.warmup_tau_s)
        if self.ramp_total:
            out += self.ramp_total * b * (t - t[0]) / max(t[-1] - t[0], 1e-300)
        if self.thermal_amp:
            out += self.thermal_amp * b * (1.0 - np.exp(-t / self.thermal_tau_s))
        return out


def static_log(
    seed: int,
    *,
    rate_hz: float = 100.0,
    hours: float = 2.0,
    channels: tuple[str, ...] = CHANNELS,
    disturbance: Disturbance | None = None,
    gm_sigma_over_b: float = 0.0,
    gm_tau_s: float = 300.0,
    k_scale: float = 1.0,
) -> dict[str, np.ndarray]:
    """``{"time_s": t, channel: samples}`` of a static log (SI), each channel with its
    own noise (K scaled by ``k_scale``); the disturbance (if any) added to every
    channel in its own B."""
    rng = np.random.default_rng(seed)
    n = int(round(hours * 3600.0 * rate_hz))
    t = np.arange(n) / rate_hz
    out: dict[str, np.ndarray] = {"time_s": t}
    for name in channels:
        ax = axis(name, gm_sigma_over_b, gm_tau_s, k_scale)
        y = noise(ax, n, rate_hz, rng)
        if disturbance is not None:
            y = y + disturbance.signal(t, ax.B)
        if name == "accel_z":
            y = y + 9.80665
        out[name] = y
    return out


def spliced_log(
    seed: int,
    *,
    rate_hz: float = 100.0,
    hours: tuple[float, float] = (1.0, 1.0),
    channels: tuple[str, ...] = CHANNELS,
) -> dict[str, np.ndarray]:
    """A log recorded at ``rate_hz`` for ``hours[0]``, then at half that rate for
    ``hours[1]`` (pairs of samples averaged: the same sensor, its noise continuing
    across the change), the time stamps continuing at the new step."""
    n1 = int(round(hours[0] * 3600.0 * rate_hz))
    n2 = 2 * int(round(hours[1] * 3600.0 * rate_hz / 2.0))
    full = static_log(seed, rate_hz=rate_hz, hours=(n1 + n2) / rate_hz / 3600.0,
                      channels=channels)  # fmt: skip
    t1 = np.arange(n1) / rate_hz
    t2 = n1 / rate_hz + np.arange(n2 // 2) * 2.0 / rate_hz
    out: dict[str, np.ndarray] = {"time_s": np.concatenate((t1, t2))}
    for name in channels:
        y = full[name]
        out[name] = np.concatenate((y[:n1], y[n1 : n1 + n2].reshape(-1, 2).mean(axis=1)))
    return out


def write_csv(path: object, cols: dict[str, np.ndarray]) -> None:
    """The columns as a CSV with SI unit suffixes the readers recognise."""
    names = list(cols)
    header = ",".join(
        n if n == "time_s" else f"{n}_{'rads' if n.startswith('gyro') else 'mps2'}" for n in names
    )
    data = np.column_stack([cols[n] for n in names])
    np.savetxt(str(path), data, delimiter=",", header=header, comments="", fmt="%.10g")
