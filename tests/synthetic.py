"""Synthetic rate signals with known IEEE 952 noise terms, for tests only.

Independent of :mod:`imubounds.stationary.noise_sim` on purpose: the fit is checked against a
generator that does not share code with the library.
"""

from __future__ import annotations

import numpy as np


def five_term_signal(
    n: int, rate_hz: float, Q: float, N: float, B: float, K: float, R: float, seed: int
) -> np.ndarray:
    """Rate samples whose Allan variance is 3Q²/τ² + N²/τ + 0.4413B² + K²τ/3 + R²τ²/2.

    Q: white angle noise of std Q, differenced; N: white rate noise of density
    N; B: flicker rate noise with one-sided PSD B²/(2πf), made by spectral
    shaping; K: random walk of the rate; R: a deterministic ramp R·t.
    """
    rng = np.random.default_rng(seed)
    t0 = 1.0 / rate_hz
    y = np.diff(rng.standard_normal(n + 1) * Q) / t0
    y += rng.standard_normal(n) * N / np.sqrt(t0)
    if B > 0:
        nf = 2 * n
        f = np.fft.rfftfreq(nf, t0)
        psd = np.zeros_like(f)
        psd[1:] = B**2 / (2 * np.pi * f[1:])
        amp = np.sqrt(psd * nf / (2 * t0))
        spec = amp * (rng.standard_normal(f.size) + 1j * rng.standard_normal(f.size))
        y += np.fft.irfft(spec, nf)[:n]
    y += np.cumsum(rng.standard_normal(n)) * K * np.sqrt(t0)
    y += R * np.arange(n) * t0
    return y
