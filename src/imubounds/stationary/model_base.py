"""Shared pieces of the stochastic models (:mod:`imubounds.stationary.models`).

Theoretical Allan variance from an autocovariance
-------------------------------------------------
For a stationary sequence with autocovariance ``R(j)`` and variogram
``γ(j) = R(0) - R(j)``, the expected overlapping Allan variance at cluster
size ``m`` (τ = m·δt) is (derivation in :func:`avar_from_variogram`)::

    σ²(m) = [G(2m) - 4·G(m)] / m²,   G(k) = Σ_{j=1}^{k-1} (k - j)·γ(j).

Equivalently σ²(m) = [4·S(m) - S(2m)] / (2m²) with ``S(k) = Var(Σ of k
samples) = k·R(0) + 2·Σ_{j=1}^{k-1}(k-j)·R(j)``; the variogram form cancels
R(0) analytically.  White noise (γ(j) = R(0)) gives R(0)/m.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Callable
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from imubounds.errors import AnalysisError, InputError, OptionError

#: Minimum samples (after decimation) for any model fit.
MIN_SAMPLES = 32
#: Auto decimation: target effective rate (Hz) and minimum samples kept.
AUTO_TARGET_HZ = 1.0
AUTO_MIN_SAMPLES = 20_000
#: The white part of a white+GM fit is kept when it carries at least this
#: fraction of the variance of the (decimated) signal.
WHITE_FRACTION = 0.05
#: The GM fit uses lags up to this many correlation times (2: a compromise between
#: the scatter of β and how far the exponential is checked).
FIT_SPAN_TC = 2.0


class ModelNotSupportedError(AnalysisError):
    """The data are valid but do not show the structure the model needs
    (e.g. no positive autocorrelation for a Gauss–Markov fit)."""


def _as_signal(y: ArrayLike, rate_hz: float, name: str) -> NDArray[np.float64]:
    """Validate a 1-D finite, non-constant signal and a positive rate."""
    if not (isinstance(rate_hz, numbers.Real) and math.isfinite(rate_hz) and rate_hz > 0):
        raise OptionError(f"rate_hz must be a positive number of Hz, got {rate_hz!r}")
    arr = np.asarray(y, dtype=np.float64)
    if arr.ndim != 1:
        raise InputError(f"{name}: expected a 1-D signal, got shape {arr.shape}")
    bad = ~np.isfinite(arr)
    if bad.any():
        first = int(np.argmax(bad))
        raise InputError(
            f"{name}: {int(bad.sum())} non-finite value(s) (NaN/inf), first at sample {first}; "
            "remove or interpolate them before fitting models"
        )
    if arr.size < MIN_SAMPLES:
        raise AnalysisError(
            f"{name}: {arr.size} samples are too few for a stochastic model fit "
            f"(need at least {MIN_SAMPLES})"
        )
    if np.ptp(arr) == 0.0:
        raise AnalysisError(
            f"{name}: the signal is constant ({arr[0]:g}); there is no noise to model"
        )
    return arr


def decimation_factor(
    n: int, rate_hz: float, decimate_to_hz: float | Literal["auto"] | None
) -> int:
    """Block-averaging factor D for ``n`` samples at ``rate_hz``.

    ``None`` → 1 (no decimation); a number → ``floor(rate_hz / decimate_to_hz)``
    (at least 1); ``"auto"`` → down to about :data:`AUTO_TARGET_HZ` while
    keeping at least :data:`AUTO_MIN_SAMPLES` samples.
    """
    if decimate_to_hz is None:
        return 1
    if decimate_to_hz == "auto":
        by_rate = int(math.floor(rate_hz / AUTO_TARGET_HZ + 1e-9))
        by_count = n // AUTO_MIN_SAMPLES
        return max(1, min(by_rate, by_count))
    if not (
        isinstance(decimate_to_hz, numbers.Real)
        and math.isfinite(decimate_to_hz)
        and decimate_to_hz > 0
    ):
        raise OptionError(
            f"decimate_to_hz must be a positive rate in Hz, 'auto' or None, got {decimate_to_hz!r}"
        )
    return max(1, int(math.floor(rate_hz / float(decimate_to_hz) + 1e-9)))


def block_average(y: ArrayLike, factor: int) -> NDArray[np.float64]:
    """Means of consecutive blocks of ``factor`` samples (a trailing partial block is dropped)."""
    arr = np.asarray(y, dtype=np.float64)
    if factor <= 1:
        return arr.copy()
    n = (arr.size // factor) * factor
    return np.asarray(arr[:n].reshape(-1, factor).mean(axis=1), dtype=np.float64)


def sample_autocovariance(
    x: ArrayLike, max_lag: int, *, unbiased: bool = True
) -> NDArray[np.float64]:
    """Autocovariance of a (demeaned inside) series at lags 0..max_lag, by FFT.

    ``unbiased`` divides lag j by ``n - j`` (else by ``n``).
    """
    arr = np.asarray(x, dtype=np.float64)
    arr = arr - arr.mean()
    n = arr.size
    max_lag = min(int(max_lag), n - 1)
    nfft = 1 << int(math.ceil(math.log2(2 * n)))
    f = np.fft.rfft(arr, nfft)
    acov = np.fft.irfft(f * np.conj(f), nfft)[: max_lag + 1]
    denom = (n - np.arange(max_lag + 1)) if unbiased else np.full(max_lag + 1, float(n))
    return np.asarray(acov / denom, dtype=np.float64)


def avar_from_variogram(gamma: NDArray[np.float64], m: ArrayLike) -> NDArray[np.float64]:
    """Expected overlapping Allan variance at integer cluster sizes ``m``.

    Parameters
    ----------
    gamma:
        Variogram ``γ(j) = R(0) - R(j)`` of the stationary sequence at lags
        ``j = 0..L`` (``gamma[0] = 0``), with ``L >= 2·max(m) - 1``; units of
        the signal squared.
    m:
        Cluster sizes (integers ≥ 1).

    Returns
    -------
    σ²(m) in signal units squared.

    Notes
    -----
    With cluster means ȳ₁, ȳ₂ of m consecutive samples each, adjacent,
    σ²(m) = ½E[(ȳ₂ - ȳ₁)²].  Writing ``A₁, A₂`` for the cluster sums and
    ``S(k) = Var(sum of k samples)``, ``Var(A₂ - A₁) = 4S(m) - S(2m)``, hence
    σ²(m) = (4S(m) - S(2m))/(2m²).  Substituting ``R(j) = R(0) - γ(j)`` into
    ``S(k) = k·R(0) + 2Σ_{j<k}(k-j)R(j)`` gives
    ``S(k) = k²R(0) - 2G(k)`` with ``G(k) = Σ_{j=1}^{k-1}(k-j)γ(j)`` and
    σ²(m) = (G(2m) - 4G(m))/m².  This is the expectation of the overlapping
    estimator (every overlapping term has the same expectation).
    """
    mm = np.asarray(m, dtype=np.int64)
    g = np.asarray(gamma, dtype=np.float64)
    kmax = int(2 * mm.max())
    if g.size < kmax:
        raise ValueError(f"variogram needs lags up to {kmax - 1}, has {g.size - 1}")
    j = np.arange(g.size, dtype=np.float64)
    # c1[k] = Σ_{j=1}^{k-1} γ(j), c2[k] = Σ_{j=1}^{k-1} j γ(j)
    c1 = np.concatenate(([0.0], np.cumsum(g)))  # c1[k] = Σ_{j=0}^{k-1} γ(j), γ(0)=0
    c2 = np.concatenate(([0.0], np.cumsum(j * g)))

    def big_g(k: NDArray[np.int64]) -> NDArray[np.float64]:
        return np.asarray(k * c1[k] - c2[k], dtype=np.float64)

    mf = mm.astype(np.float64)
    return np.asarray((big_g(2 * mm) - 4.0 * big_g(mm)) / (mf * mf), dtype=np.float64)


def _at_tau(
    tau: ArrayLike, dt: float, at_m: Callable[[NDArray[np.int64]], NDArray[np.float64]]
) -> NDArray[np.float64]:
    """A variance known at integer cluster sizes, at arbitrary τ ≥ dt: log-log
    interpolation between the cluster sizes around τ/dt; NaN below dt."""
    t = np.atleast_1d(np.asarray(tau, dtype=np.float64))
    out = np.full(t.shape, np.nan)
    mreal = t / dt
    ok = np.isfinite(mreal) & (mreal >= 1.0 - 1e-9)
    if not ok.any():
        return out
    mr = np.maximum(mreal[ok], 1.0)
    lo = np.floor(mr + 1e-9).astype(np.int64)
    hi = np.maximum(lo, np.ceil(mr - 1e-9).astype(np.int64))
    grid = np.unique(np.concatenate((lo, hi)))
    vals = at_m(grid)
    v_lo = vals[np.searchsorted(grid, lo)]
    v_hi = vals[np.searchsorted(grid, hi)]
    same = hi == lo
    w = np.where(same, 0.0, (np.log(mr) - np.log(lo)) / np.where(same, 1.0, np.log(hi / lo)))
    with np.errstate(divide="ignore", invalid="ignore"):
        val = np.exp((1 - w) * np.log(v_lo) + w * np.log(v_hi))
    out[ok] = np.where(same, v_lo, val)
    return out


def _avar_at_tau(
    tau: ArrayLike, dt: float, gamma_fn: Callable[[int], NDArray[np.float64]]
) -> NDArray[np.float64]:
    """σ²(τ) (overlapping Allan) of a sampled process from its variogram (see :func:`_at_tau`)."""

    def at_m(m: NDArray[np.int64]) -> NDArray[np.float64]:
        return avar_from_variogram(gamma_fn(int(2 * m.max())), m)

    return _at_tau(tau, dt, at_m)


def _variance_at_tau(
    tau: ArrayLike, dt: float, acov: Callable[[int], NDArray[np.float64]], estimator: str
) -> NDArray[np.float64]:
    """Expected variance of ``estimator`` at τ for a stationary sequence sampled every
    ``dt`` from its autocovariance (see :func:`_at_tau`)."""
    from imubounds.stationary.theory import stationary_variance

    return _at_tau(tau, dt, lambda m: stationary_variance(acov, m, estimator))


def _rng(rng: np.random.Generator | int | None) -> np.random.Generator:
    return rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
