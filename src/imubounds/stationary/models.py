"""Stochastic error models of a static sensor signal (METHOD.md 1.3).

Two models are fitted to a rate signal (gyro rad/s or accelerometer m/s², SI):

* **First-order Gauss–Markov (GM)**, optionally on top of white noise
  (white + GM is an ARMA(1,1) process).  The exact discrete form used for
  simulation is ``x[k+1] = exp(-β δt)·x[k] + σ·sqrt(1 - exp(-2β δt))·w[k]``,
  β = 1/correlation time, σ the stationary standard deviation.  β and σ come
  from a least-squares fit of ``A·exp(-β|τ|)`` to the sample autocovariance
  at lags ≥ 1 (lag 0 holds the white noise, so it is skipped), so a white
  floor does not ruin the correlation time; the white variance is what lag 0
  has in excess of the GM.  The paper's 1/e read-off of the normalised
  autocorrelation is offered as ``method="paper"``.
* **AR(p) by Burg's method** with order selection (AIC, BIC, HQIC, FPE or a
  fixed order).  Convention (METHOD.md):
  ``y[n] = -Σ_{k=1..p} a_k·y[n-k] + e[n]``, ``var(e) = noise_variance``.
  ``coefficients`` are these ``a_k``.  Statsmodels' ``burg`` returns
  ``rho = -a`` (``y[n] = Σ rho_k·y[n-k] + e[n]``).

Long logs are decimated by **block averaging** before fitting (default
``decimate_to_hz="auto"``: down to about 1 Hz while keeping at least 20 000
samples), so the models describe the long-term behaviour and fitting a
10⁶-sample log takes well under a second per channel.  Block averaging keeps
the Allan variance: the Allan variance of the averaged series at cluster
``m`` equals that of the raw series at cluster ``m·D``; the GM fit corrects
its amplitude for the averaging exactly.  Every fitted model can simulate
noise and give its theoretical Allan deviation, so a measured curve can be
compared with each model.

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
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import optimize, signal

from imubounds.errors import AnalysisError, InputError, OptionError

CRITERIA: tuple[str, ...] = ("aic", "bic", "hqic", "fpe")
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


# ----------------------------------------------------------------------------
# helpers


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


# ----------------------------------------------------------------------------
# Gauss–Markov


def gm_avar_continuous(tau: ArrayLike, sigma: float, beta: float) -> NDArray[np.float64]:
    """Allan variance of a continuous first-order Gauss–Markov rate process.

    σ²(T) = (q_c² T_c² / T)·[1 − (T_c/2T)(3 − 4e^{−T/T_c} + e^{−2T/T_c})],
    q_c² = 2σ²/T_c, T_c = 1/β (IEEE Std 952; El-Sheimy et al. 2008).  τ in s,
    σ in signal units, β in 1/s; result in signal units squared.  Evaluated
    with a series for T ≪ T_c to avoid cancellation.
    """
    t = np.asarray(tau, dtype=np.float64)
    tc = 1.0 / beta
    x = t / tc
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        bracket = 1.0 - (3.0 - 4.0 * np.exp(-x) + np.exp(-2.0 * x)) / (2.0 * x)
        # for x < 1 the closed form cancels; its Taylor series has no cancellation:
        # bracket = -Σ_{n≥3} (-1)^n (2^n - 4) x^{n-1} / (2·n!) = x²/3 - x³/4 + ...
        xs = np.minimum(x, 1.0)
        series = np.zeros_like(xs)
        for n in range(25, 2, -1):  # smallest terms first
            series += -((-1.0) ** n) * (2.0**n - 4.0) / (2.0 * math.factorial(n)) * xs ** (n - 1)
        bracket = np.where(x < 1.0, series, bracket)
        out = 2.0 * sigma**2 * tc / t * bracket
    return np.asarray(out, dtype=np.float64)


@dataclass(frozen=True)
class GaussMarkovModel:
    """First-order Gauss–Markov process, optionally plus white noise.

    Attributes
    ----------
    beta:
        1/correlation time, 1/s.
    sigma:
        Stationary standard deviation of the GM part, signal units (rad/s or m/s²).
    white_density:
        Density N of the added white noise, signal units·√s (rad/s^0.5,
        m/s^1.5); the per-sample std at rate f is N·√f.  0 for a pure GM.
    method, fit, fitted_rate_hz, decimation, unit:
        How it was fitted (see :func:`fit_gauss_markov`).
    """

    beta: float
    sigma: float
    white_density: float = 0.0
    method: str = "given"
    fit: dict[str, Any] = field(default_factory=dict)
    fitted_rate_hz: float | None = None
    decimation: int = 1
    unit: str | None = None

    @property
    def correlation_time_s(self) -> float:
        return 1.0 / self.beta

    @property
    def variant(self) -> str:
        return "white+gm" if self.white_density > 0 else "gm"

    def white_sigma(self, rate_hz: float) -> float:
        """Per-sample std of the white part at ``rate_hz``."""
        return self.white_density * math.sqrt(rate_hz)

    def simulate(
        self, n: int, rate_hz: float, rng: np.random.Generator | int | None = None
    ) -> NDArray[np.float64]:
        """``n`` samples at ``rate_hz`` of the exact discrete GM (started in its
        stationary distribution) plus the white part."""
        g = _rng(rng)
        dt = 1.0 / rate_hz
        phi = math.exp(-self.beta * dt)
        s = self.sigma * math.sqrt(-math.expm1(-2.0 * self.beta * dt))
        x = simulate_gm(n, phi, s, self.sigma, g)
        if self.white_density > 0:
            x += g.standard_normal(n) * self.white_sigma(rate_hz)
        return x

    def avar(self, tau: ArrayLike, rate_hz: float | None = None) -> NDArray[np.float64]:
        """Theoretical Allan variance at τ (s).

        ``rate_hz=None``: continuous-time GM (its closed form) plus N²/τ, the
        curve of a sensor that averages over each sample period.  With
        ``rate_hz``: exact expectation of the overlapping estimator for point
        samples of the discrete process at that rate (NaN for τ < 1/rate).
        """
        t = np.asarray(tau, dtype=np.float64)
        if rate_hz is None:
            return gm_avar_continuous(t, self.sigma, self.beta) + self.white_density**2 / t
        dt = 1.0 / rate_hz
        r_white = self.white_density**2 * rate_hz
        log_phi = -self.beta * dt

        def gamma(nlag: int) -> NDArray[np.float64]:
            j = np.arange(nlag, dtype=np.float64)
            g = -(self.sigma**2) * np.expm1(j * log_phi) + r_white
            g[0] = 0.0
            return g

        return _avar_at_tau(t, dt, gamma)

    def adev(self, tau: ArrayLike, rate_hz: float | None = None) -> NDArray[np.float64]:
        """Theoretical Allan deviation at τ (s), signal units (see :meth:`avar`)."""
        return np.sqrt(self.avar(tau, rate_hz))

    @property
    def valid_from_tau_s(self) -> float:
        """Shortest τ the model describes: the sample period of the series it was fitted to."""
        return 1.0 / self.fitted_rate_hz if self.fitted_rate_hz else 0.0

    def variance(
        self, tau: ArrayLike, estimator: str = "overlapping", rate_hz: float | None = None
    ) -> NDArray[np.float64]:
        """Expected variance of any Allan-family ``estimator`` at τ (s), signal units².

        Exact for the point-sampled process at ``rate_hz`` (default: the rate of
        the log the model was fitted to, ``fitted_rate_hz·decimation``); NaN for
        τ below one sample. See :mod:`imubounds.stationary.theory`.
        """
        rate = rate_hz or (
            (self.fitted_rate_hz or 0.0) * self.decimation if self.fitted_rate_hz else None
        )
        if rate is None:
            raise OptionError("give rate_hz: this Gauss-Markov model has no fit rate")
        dt = 1.0 / rate
        r_white = self.white_density**2 * rate
        log_phi = -self.beta * dt
        sig2 = self.sigma**2

        def acov(nlag: int) -> NDArray[np.float64]:
            r = sig2 * np.exp(np.arange(nlag, dtype=np.float64) * log_phi)
            r[0] += r_white
            return r

        return _variance_at_tau(tau, dt, acov, estimator)

    def to_dict(self) -> dict[str, Any]:
        d: dict[str, Any] = {
            "model": "gauss_markov",
            "variant": self.variant,
            "beta": self.beta,
            "beta_unit": "1/s",
            "correlation_time_s": self.correlation_time_s,
            "sigma": self.sigma,
            "white_density": self.white_density,
            "unit": self.unit,
            "white_density_unit": f"({self.unit})*s^0.5" if self.unit else "signal*s^0.5",
            "method": self.method,
            "fitted_rate_hz": self.fitted_rate_hz,
            "decimation": self.decimation,
            "discrete_form": "x[k+1] = exp(-beta*dt)*x[k] + sigma*sqrt(1-exp(-2*beta*dt))*w[k]",
        }
        if self.fitted_rate_hz:
            d["white_sigma"] = self.white_sigma(self.fitted_rate_hz)
            d["valid_from_tau_s"] = 1.0 / self.fitted_rate_hz
        if self.fit:
            d["fit"] = dict(self.fit)
        return d

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> GaussMarkovModel:
        """Rebuild from :meth:`to_dict` output (e.g. a ``noise.json`` entry)."""
        try:
            beta = float(d["beta"]) if "beta" in d else 1.0 / float(d["correlation_time_s"])
            sigma = float(d["sigma"])
        except (KeyError, TypeError, ValueError, ZeroDivisionError) as err:
            raise InputError(f"gauss_markov model entry lacks a valid beta/sigma: {err}") from err
        if not (beta > 0 and math.isfinite(beta) and sigma >= 0 and math.isfinite(sigma)):
            raise InputError(f"gauss_markov model entry has beta={beta}, sigma={sigma}")
        return cls(
            beta=beta,
            sigma=sigma,
            white_density=float(d.get("white_density") or 0.0),
            method=str(d.get("method", "given")),
            fitted_rate_hz=d.get("fitted_rate_hz"),
            decimation=int(d.get("decimation", 1) or 1),
            unit=d.get("unit"),
        )


def simulate_gm(
    n: int, phi: float, innovation_std: float, sigma: float, rng: np.random.Generator
) -> NDArray[np.float64]:
    """``x[0] ~ N(0, σ²)``, ``x[k] = φ x[k-1] + s·w[k]`` (vectorised by lfilter)."""
    w = rng.standard_normal(n)
    if n == 0:
        return w
    x0 = sigma * w[0]
    out = np.empty(n)
    out[0] = x0
    if n > 1:
        out[1:], _ = signal.lfilter([innovation_std], [1.0, -phi], w[1:], zi=[phi * x0])
    return out


def _gm_block_factors(beta: float, dt: float, d: int) -> tuple[float, float]:
    """For a point-sampled GM (φ = e^{-β dt}) averaged in blocks of ``d``:
    (c, v) with cov at block lag j ≥ 1 = σ²·c·φ^{jd} and block variance σ²·v."""
    if d == 1:
        return 1.0, 1.0
    phi = math.exp(-beta * dt)
    k = np.arange(1, d, dtype=np.float64)
    v = (d + 2.0 * np.sum((d - k) * phi**k)) / d**2
    s_plus = np.sum(phi ** np.arange(d, dtype=np.float64))
    s_minus = np.sum(phi ** (-np.arange(d, dtype=np.float64)))
    return float(s_plus * s_minus / d**2), float(v)


def fit_gauss_markov(
    y: ArrayLike,
    rate_hz: float,
    *,
    decimate_to_hz: float | Literal["auto"] | None = "auto",
    max_lag_s: float | None = None,
    method: Literal["acf_ls", "paper"] = "acf_ls",
    white: bool | None = None,
    name: str = "signal",
    unit: str | None = None,
    notes: list[str] | None = None,
) -> GaussMarkovModel:
    """Fit a first-order Gauss–Markov model (plus white noise where present).

    Parameters
    ----------
    y:
        Rate samples in SI (rad/s or m/s²).
    rate_hz:
        Sample rate, Hz.
    decimate_to_hz:
        Block-average down to this rate before fitting (see
        :func:`decimation_factor`).
    max_lag_s:
        Largest autocovariance lag used, s (default: a quarter of the log; the
        fit then uses lags up to 3 correlation times, iterated).
    method:
        ``"acf_ls"``: least squares of A·e^{-βτ} on lags ≥ 1 (white + GM);
        ``"paper"``: the lag where the autocorrelation normalised by lag 0
        falls to 1/e, σ² = variance, no white part (ruined by a white floor).
    white:
        Keep a white part: ``None`` decides from the data (kept when it carries
        ≥ 5 % of the variance at the fit rate), True/False forces it.
    name, unit:
        Channel name (for messages) and signal unit (recorded in the model).
    notes:
        A list that receives human-readable remarks.

    Returns
    -------
    GaussMarkovModel

    Raises
    ------
    InputError, OptionError, AnalysisError, ModelNotSupportedError
    """
    notes = notes if notes is not None else []
    arr = _as_signal(y, rate_hz, name)
    if method not in ("acf_ls", "paper"):
        raise OptionError(f"GM fit method must be 'acf_ls' or 'paper', got {method!r}")
    d = decimation_factor(arr.size, rate_hz, decimate_to_hz)
    x = block_average(arr, d)
    h = d / rate_hz
    n = x.size
    if n < MIN_SAMPLES:
        raise AnalysisError(
            f"{name}: only {n} samples remain after block averaging to {1 / h:g} Hz; "
            f"a Gauss-Markov fit needs at least {MIN_SAMPLES} (raise decimate_to_hz)"
        )
    if max_lag_s is not None:
        lmax = int(math.floor(max_lag_s / h + 1e-9))
        if lmax < 2:
            raise OptionError(
                f"{name}: max_lag_s={max_lag_s:g} s is below two fit sample periods ({2 * h:g} s)"
            )
        if lmax > n // 2:
            raise AnalysisError(
                f"{name}: the log ({n * h:g} s) is too short for max_lag_s={max_lag_s:g} s; "
                f"use at most {n // 2 * h:g} s"
            )
    else:
        lmax = max(2, n // 4)
    acov = sample_autocovariance(x, lmax)
    r0 = float(acov[0])
    if r0 <= 0:
        raise AnalysisError(f"{name}: the signal has no variance after block averaging")
    if acov[1] <= 0:
        raise ModelNotSupportedError(
            f"{name}: no positive autocorrelation at lag {h:g} s "
            f"(rho1 = {acov[1] / r0:.3g}); the signal is not Gauss-Markov at this rate"
        )
    below = np.nonzero(acov[1:] < acov[1] / math.e)[0]
    tail_limited = below.size == 0
    j_e = int(below[0]) + 1 if below.size else lmax
    dt = 1.0 / rate_hz

    if method == "paper":
        rho = acov / r0
        idx = np.nonzero(rho[1:] < 1.0 / math.e)[0]
        if idx.size == 0:
            raise ModelNotSupportedError(
                f"{name}: the autocorrelation does not fall to 1/e within {lmax * h:g} s"
            )
        j = int(idx[0]) + 1
        # linear interpolation of the crossing between lags j-1 and j
        frac = (rho[j - 1] - 1.0 / math.e) / (rho[j - 1] - rho[j])
        tc = (j - 1 + frac) * h
        paper_info = {"lag_1_over_e_s": tc, "rho1": float(rho[1])}
        notes.append("Gauss-Markov by the paper's 1/e read-off (a white-noise floor biases it)")
        return GaussMarkovModel(
            beta=1.0 / tc,
            sigma=math.sqrt(r0),
            white_density=0.0,
            method="paper_1_over_e",
            fit=paper_info,
            fitted_rate_hz=1.0 / h,
            decimation=d,
            unit=unit,
        )

    # acf_ls: A·exp(-b j), j = 1..L, L ≈ 3 Tc, iterated
    b = 1.0 / max(j_e, 1)
    amp = float(acov[1]) * math.exp(b)
    lags_used = 0
    for _ in range(6):
        span = int(math.ceil(FIT_SPAN_TC / b)) if b > 0 else lmax
        big_l = int(min(max(span, 3), lmax))
        if big_l == lags_used:
            break
        lags_used = big_l
        jj = np.arange(1, big_l + 1, dtype=np.float64)
        yy = acov[1 : big_l + 1]
        scale = float(acov[1])

        def resid(
            p: NDArray[np.float64],
            jj: NDArray[np.float64] = jj,
            yy: NDArray[np.float64] = yy,
            scale: float = scale,
        ) -> NDArray[np.float64]:
            return np.asarray((np.exp(p[0] - p[1] * jj) - yy / scale), dtype=np.float64)

        p0 = np.array([math.log(amp / scale), b])
        sol = optimize.least_squares(
            resid, p0, bounds=([-np.inf, 1e-12], [np.inf, 50.0]), x_scale="jac"
        )
        amp = float(math.exp(sol.x[0]) * scale)
        b = float(sol.x[1])
    jj = np.arange(1, lags_used + 1, dtype=np.float64)
    yy = acov[1 : lags_used + 1]
    model_vals = amp * np.exp(-b * jj)
    ss_res = float(np.sum((yy - model_vals) ** 2))
    ss_tot = float(np.sum((yy - yy.mean()) ** 2))
    beta = b / h
    c_d, v_d = _gm_block_factors(beta, dt, d)
    sigma2 = amp / c_d
    white_var_fit = r0 - sigma2 * v_d  # white variance at the fit rate
    white_frac = white_var_fit / r0
    keep_white = (white_frac >= WHITE_FRACTION) if white is None else bool(white)
    white_density = math.sqrt(max(white_var_fit, 0.0) * h) if keep_white else 0.0
    tc = 1.0 / beta
    fit_info: dict[str, Any] = {
        "lag_range_s": [h, lags_used * h],
        "n_lags": lags_used,
        "r2": 1.0 - ss_res / ss_tot if ss_tot > 0 else float("nan"),
        "rmse_rel": math.sqrt(ss_res / lags_used) / float(acov[1]),
        "white_variance_fraction": white_frac,
        "log_over_tc": n * h / tc,
    }
    # ARMA(1,1) representation at the fit rate: (1 - φB) y = (1 + θB) e
    phi_h = math.exp(-b)
    q = sigma2 * c_d * (1 - phi_h**2)  # approx. innovation of the decimated GM part
    r_w = max(white_var_fit, 0.0) if keep_white else 0.0
    g0 = q + r_w * (1 + phi_h**2)
    g1 = -phi_h * r_w
    rho1 = g1 / g0 if g0 > 0 else 0.0
    theta = 0.0 if rho1 == 0 else (1 - math.sqrt(max(1 - 4 * rho1**2, 0.0))) / (2 * rho1)
    fit_info["arma11"] = {
        "phi": phi_h,
        "theta": theta,
        "innovation_variance": g1 / theta if theta != 0 else g0,
        "rate_hz": 1.0 / h,
        "convention": "y[n] - phi*y[n-1] = e[n] + theta*e[n-1]",
    }
    if tail_limited or lags_used >= lmax:
        notes.append(
            f"the autocorrelation has not decayed within the lag range "
            f"({lmax * h:g} s); the correlation time {tc:.4g} s is poorly determined"
        )
    if lags_used <= 3:
        notes.append(
            f"correlation time {tc:.3g} s is short compared with the fit sample "
            f"period {h:g} s; fit at a higher rate (decimate_to_hz) to resolve it"
        )
    if n * h < 10 * tc:
        notes.append(f"the log is only {n * h / tc:.3g} correlation times long; beta is uncertain")
    if white is None and not keep_white and white_frac > 0:
        notes.append(
            f"white part ({100 * white_frac:.2g} % of the variance) dropped; pure Gauss-Markov"
        )
    return GaussMarkovModel(
        beta=beta,
        sigma=math.sqrt(sigma2),
        white_density=white_density,
        method="acf_ls_white_gm" if keep_white else "acf_ls_gm",
        fit=fit_info,
        fitted_rate_hz=1.0 / h,
        decimation=d,
        unit=unit,
    )


# ----------------------------------------------------------------------------
# AR(p), Burg


def ar_autocovariance(
    coefficients: ArrayLike, noise_variance: float, nlags: int
) -> NDArray[np.float64]:
    """Exact autocovariance R(0..nlags-1) of the stationary AR(p)
    ``y[n] = -Σ a_k y[n-k] + e[n]``, var(e) = noise_variance.

    R(0..p) solve the Yule–Walker system ``R(k) + Σ_i a_i R(|k-i|) = σ_e² δ_k``;
    later lags follow ``R(j) = -Σ a_i R(j-i)`` (run by ``scipy.signal.lfilter``).
    """
    a = np.asarray(coefficients, dtype=np.float64)
    p = a.size
    if nlags <= 0:
        return np.zeros(0)
    if p == 0:
        out = np.zeros(nlags)
        out[0] = noise_variance
        return out
    m = np.zeros((p + 1, p + 1))
    for k in range(p + 1):
        m[k, k] += 1.0
        for i in range(1, p + 1):
            m[k, abs(k - i)] += a[i - 1]
    rhs = np.zeros(p + 1)
    rhs[0] = noise_variance
    r = np.asarray(np.linalg.solve(m, rhs), dtype=np.float64)
    if nlags <= p + 1:
        return r[:nlags]
    den = np.concatenate(([1.0], a))
    zi = signal.lfiltic([1.0], den, r[::-1][:p])  # past outputs y[-1]=R(p), y[-2]=R(p-1)...
    tail, _ = signal.lfilter([1.0], den, np.zeros(nlags - p - 1), zi=zi)
    return np.concatenate((r, tail))


@dataclass(frozen=True)
class ArModel:
    """AR(p) process at a fixed rate.

    ``y[n] = -Σ_{k=1..p} a_k·y[n-k] + e[n]``, ``var(e) = noise_variance``
    (signal units squared), sampled at ``rate_hz`` (the effective rate after
    any block averaging: the model describes ``decimation``-sample means of
    the raw signal).
    """

    coefficients: tuple[float, ...]
    noise_variance: float
    rate_hz: float
    decimation: int = 1
    criterion: str = "bic"
    orders: tuple[int, ...] = ()
    criteria: dict[str, list[float]] = field(default_factory=dict)
    mean: float = 0.0
    unit: str | None = None
    method: str = "burg"

    @property
    def order(self) -> int:
        return len(self.coefficients)

    def autocovariance(self, nlags: int) -> NDArray[np.float64]:
        """Exact R(0..nlags-1), signal units squared."""
        return ar_autocovariance(self.coefficients, self.noise_variance, nlags)

    def simulate(
        self, n: int, rate_hz: float | None = None, rng: np.random.Generator | int | None = None
    ) -> NDArray[np.float64]:
        """``n`` samples of the zero-mean process, started in its stationary distribution.

        ``rate_hz`` must be the model's own rate (an AR model is tied to it).
        """
        if rate_hz is not None and not math.isclose(rate_hz, self.rate_hz, rel_tol=1e-9):
            raise OptionError(
                f"this AR({self.order}) model was fitted at {self.rate_hz:g} Hz and can only "
                f"simulate at that rate, not {rate_hz:g} Hz (use rate {self.rate_hz:g} Hz)"
            )
        g = _rng(rng)
        p = self.order
        e = g.standard_normal(n) * math.sqrt(self.noise_variance)
        if p == 0:
            return e
        r = self.autocovariance(p)
        cov = r[np.abs(np.subtract.outer(np.arange(p), np.arange(p)))]
        past = np.linalg.cholesky(cov + 1e-300 * np.eye(p)) @ g.standard_normal(p)
        den = np.concatenate(([1.0], np.asarray(self.coefficients)))
        zi = signal.lfiltic([1.0], den, past)  # past[0] = y[-1], past[1] = y[-2], ...
        out, _ = signal.lfilter([1.0], den, e, zi=zi)
        return np.asarray(out, dtype=np.float64)

    def avar(self, tau: ArrayLike) -> NDArray[np.float64]:
        """Theoretical Allan variance at τ (s), for τ ≥ 1/rate_hz (NaN below);
        log-log interpolated between integer cluster sizes."""
        dt = 1.0 / self.rate_hz

        def gamma(nlag: int) -> NDArray[np.float64]:
            r = self.autocovariance(nlag)
            g = np.asarray(r[0] - r, dtype=np.float64)
            g[0] = 0.0
            return g

        return _avar_at_tau(tau, dt, gamma)

    def adev(self, tau: ArrayLike, rate_hz: float | None = None) -> NDArray[np.float64]:
        """Theoretical Allan deviation at τ (s), signal units.  ``rate_hz`` is
        accepted for symmetry with :class:`GaussMarkovModel` and ignored."""
        return np.sqrt(self.avar(tau))

    @property
    def valid_from_tau_s(self) -> float:
        """Shortest τ the model describes: its own sample period."""
        return 1.0 / self.rate_hz

    def variance(
        self, tau: ArrayLike, estimator: str = "overlapping", rate_hz: float | None = None
    ) -> NDArray[np.float64]:
        """Expected variance of any Allan-family ``estimator`` at τ (s), signal units².

        Computed at the model's own rate (it describes ``decimation``-sample
        means of the raw log: exact for the Allan and Hadamard families, whose
        statistics of block means at m equal those of the raw series at
        m·decimation; for the modified variance the phase is averaged over
        block means, a difference of order 1/m²). NaN below one model sample.
        ``rate_hz`` is ignored.
        """
        return _variance_at_tau(tau, 1.0 / self.rate_hz, self.autocovariance, estimator)

    def to_dict(self) -> dict[str, Any]:
        return {
            "model": "ar",
            "method": self.method,
            "order": self.order,
            "coefficients": [float(c) for c in self.coefficients],
            "convention": "y[n] = -sum_{k=1..p} a_k*y[n-k] + e[n], var(e) = noise_variance",
            "noise_variance": self.noise_variance,
            "noise_variance_unit": f"({self.unit})^2" if self.unit else "signal^2",
            "unit": self.unit,
            "rate_hz": self.rate_hz,
            "decimation": self.decimation,
            "valid_from_tau_s": 1.0 / self.rate_hz,
            "mean": self.mean,
            "criterion": self.criterion,
            "orders": list(self.orders),
            "criteria": {k: list(v) for k, v in self.criteria.items()},
        }

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> ArModel:
        """Rebuild from :meth:`to_dict` output (e.g. a ``noise.json`` entry)."""
        try:
            coefs = tuple(float(c) for c in d["coefficients"])
            var = float(d["noise_variance"])
            rate = float(d["rate_hz"])
        except (KeyError, TypeError, ValueError) as err:
            raise InputError(
                f"ar model entry lacks coefficients/noise_variance/rate_hz: {err}"
            ) from err
        if not (var >= 0 and rate > 0):
            raise InputError(f"ar model entry has noise_variance={var}, rate_hz={rate}")
        return cls(
            coefficients=coefs,
            noise_variance=var,
            rate_hz=rate,
            decimation=int(d.get("decimation", 1) or 1),
            criterion=str(d.get("criterion", "given")),
            mean=float(d.get("mean", 0.0) or 0.0),
            unit=d.get("unit"),
        )


def burg_path(x: ArrayLike, order_max: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Burg reflection coefficients and residual variances for orders 0..order_max.

    Thin wrapper of ``statsmodels.tsa.stattools.pacf_burg`` (O(n·p), one
    pass for all orders) on the demeaned series.  Returns ``(pacf, sigma2)``,
    ``pacf[0] = 1``.
    """
    from statsmodels.tsa.stattools import pacf_burg

    arr = np.asarray(x, dtype=np.float64)
    res = pacf_burg(arr - arr.mean(), nlags=order_max, demean=False)
    return np.asarray(res.pacf), np.asarray(res.sigma2)


def ar_from_pacf(pacf: ArrayLike) -> NDArray[np.float64]:
    """AR coefficients ``a_k`` (METHOD sign, ``y = -Σ a y + e``) from reflection
    coefficients ``pacf[1..p]`` (Levinson–Durbin step-up)."""
    k = np.asarray(pacf, dtype=np.float64)[1:]
    a = np.zeros(0)
    for kk in k:
        # statsmodels' pacf is the partial autocorrelation (rho convention): the
        # new rho_p = kk, rho_i -= kk * rho_{p-i}; in a = -rho this is a_i -= kk*a_{p-i}
        a = np.concatenate((a - kk * a[::-1], [-kk]))
    return a


def information_criteria(sigma2: ArrayLike, n: int) -> dict[str, NDArray[np.float64]]:
    """AIC, BIC, HQIC (n·ln σ²_p + penalty) and FPE for orders 0..len-1."""
    s2 = np.asarray(sigma2, dtype=np.float64)
    p = np.arange(s2.size, dtype=np.float64)
    with np.errstate(divide="ignore"):
        ln = n * np.log(s2)
    return {
        "aic": ln + 2.0 * p,
        "bic": ln + p * math.log(n),
        "hqic": ln + 2.0 * p * math.log(math.log(n)),
        "fpe": s2 * (n + p + 1.0) / np.maximum(n - p - 1.0, 1.0),
    }


def fit_ar_burg(
    y: ArrayLike,
    rate_hz: float,
    *,
    order_max: int = 20,
    criterion: str = "bic",
    order: int | None = None,
    decimate_to_hz: float | Literal["auto"] | None = "auto",
    name: str = "signal",
    unit: str | None = None,
    notes: list[str] | None = None,
) -> ArModel:
    """Fit AR(p) by Burg's method, choosing p ≤ ``order_max`` by ``criterion``.

    Parameters
    ----------
    y:
        Rate samples in SI.
    rate_hz:
        Sample rate, Hz.
    order_max:
        Largest order tried (all orders 0..order_max are scored).
    criterion:
        ``"aic"``, ``"bic"``, ``"hqic"`` or ``"fpe"``.
    order:
        Fixed order (skips selection; criteria still reported up to it).
    decimate_to_hz:
        Block-average first (see :func:`decimation_factor`).
    name, unit, notes:
        As in :func:`fit_gauss_markov`.

    Returns
    -------
    ArModel, coefficients in the METHOD sign convention.
    """
    notes = notes if notes is not None else []
    arr = _as_signal(y, rate_hz, name)
    if criterion not in CRITERIA:
        raise OptionError(
            f"AR order criterion must be one of {', '.join(CRITERIA)}; got {criterion!r}"
        )
    pmax = int(order) if order is not None else int(order_max)
    if pmax < 0 or (order is None and pmax < 1):
        raise OptionError(f"AR order must be >= {0 if order is not None else 1}, got {pmax}")
    d = decimation_factor(arr.size, rate_hz, decimate_to_hz)
    x = block_average(arr, d)
    n = x.size
    need = max(MIN_SAMPLES, 10 * (pmax + 1))
    if n < need:
        raise AnalysisError(
            f"{name}: {n} samples (at {rate_hz / d:g} Hz after block averaging) are too few "
            f"for AR order {pmax}; need at least {need} (lower the order or decimate less)"
        )
    if pmax == 0:
        pacf, s2 = np.array([1.0]), np.array([float(np.var(x))])
    else:
        pacf, s2 = burg_path(x, pmax)
    crit = information_criteria(s2, n)
    if order is not None:
        p = pmax
    else:
        p = int(np.argmin(crit[criterion]))
        if p == pmax:
            notes.append(
                f"{criterion.upper()} picked the largest order tried ({pmax}); "
                "consider a larger order_max"
            )
    a = ar_from_pacf(pacf[: p + 1])
    return ArModel(
        coefficients=tuple(float(v) for v in a),
        noise_variance=float(s2[p]),
        rate_hz=rate_hz / d,
        decimation=d,
        criterion=criterion if order is None else f"fixed order {order}",
        orders=tuple(range(pmax + 1)),
        criteria={k: [float(v) for v in vals] for k, vals in crit.items()},
        mean=float(x.mean()),
        unit=unit,
    )


# ----------------------------------------------------------------------------
# both


# ----------------------------------------------------------------------------
# adequacy: does the model's curve follow the measured one?

#: A model fits when its curve lies inside the measured 95 % interval (from each
#: point's EDF) widened by this relative tolerance at no fewer than
#: ADEQUACY_FRACTION of the points where it is valid, and is off by no more than
#: ADEQUACY_MAX_RATIO at any of those points with EDF >= ADEQUACY_EDF_MIN.
ADEQUACY_TOLERANCE = 0.10
ADEQUACY_FRACTION = 0.9
ADEQUACY_MAX_RATIO = 1.5
ADEQUACY_EDF_MIN = 10.0
#: Fit rates (Hz) tried besides the automatic one when a curve is given: a
#: lower rate lets a low-order model follow the long-term part of the curve.
CANDIDATE_RATES_HZ: tuple[float, ...] = (10.0, 1.0, 0.5, 0.2, 0.1)
#: Fewest samples a candidate fit rate must leave.
CANDIDATE_MIN_SAMPLES = 500
#: AR orders tried above the criterion's choice (up to the maximum order).
AR_ORDER_LADDER: tuple[int, ...] = (1, 2, 3, 4, 5, 6, 8, 10, 12, 15, 20, 25, 30, 40, 50, 60, 80)


def adequacy(model: GaussMarkovModel | ArModel, curve: Any) -> dict[str, Any]:
    """How well ``model`` follows a measured Allan-family ``curve`` where it is valid.

    ``curve`` is an :class:`~imubounds.stationary.allan.AllanResult` (its
    estimator is used for the model's curve). Over the points with
    τ ≥ ``model.valid_from_tau_s``: z = ln(model/measured) over the spread of
    ln σ² for the point's EDF (ψ₁(edf/2), halved for the deviation) combined
    with :data:`ADEQUACY_TOLERANCE`; the fraction with |z| ≤ 2 (a 95 %
    interval), the worst ratio model/measured at points with enough EDF and
    its τ, and ``chi2_dof`` (mean z²). ``adequate`` applies
    :data:`ADEQUACY_FRACTION` and :data:`ADEQUACY_MAX_RATIO`.
    """
    from scipy import special

    tau = np.asarray(curve.tau, dtype=np.float64)
    dev = np.asarray(curve.dev, dtype=np.float64)
    edf = np.asarray(curve.edf, dtype=np.float64)
    estimator = str(getattr(curve, "estimator", "overlapping"))
    rate = getattr(curve, "rate_hz", None)
    valid = (tau >= model.valid_from_tau_s * (1 - 1e-9)) & (dev > 0)
    out: dict[str, Any] = {
        "estimator": estimator,
        "valid_from_tau_s": model.valid_from_tau_s,
        "criterion": (
            f"inside the curve's 95 % interval widened by {ADEQUACY_TOLERANCE:.0%} at >= "
            f"{ADEQUACY_FRACTION:.0%} of the points with tau >= valid_from_tau_s, and off by "
            f"no more than x{ADEQUACY_MAX_RATIO:g} where the EDF is >= {ADEQUACY_EDF_MIN:g}"
        ),
    }
    if np.count_nonzero(valid) < 3:
        out.update(points=int(np.count_nonzero(valid)), adequate=False,
                   reason="fewer than 3 points of the curve where the model is valid")  # fmt: skip
        return out
    pred = np.sqrt(model.variance(tau[valid], estimator, rate_hz=rate))
    t, d, e = tau[valid], dev[valid], np.maximum(edf[valid], 0.5)
    lr = np.log(pred / d)
    sd = np.sqrt(special.polygamma(1, e / 2.0) / 4.0 + math.log(1.0 + ADEQUACY_TOLERANCE) ** 2)
    zz = lr / sd
    inside = np.abs(zz) <= 2.0
    strong = e >= ADEQUACY_EDF_MIN
    pool = np.flatnonzero(strong) if np.any(strong) else np.arange(t.size)
    worst = int(pool[np.argmax(np.abs(lr[pool]))])
    frac = float(np.mean(inside))
    ratio = float(np.exp(lr[worst]))
    out.update(
        tau_range_s=[float(t[0]), float(t[-1])],
        points=int(t.size),
        inside_fraction=frac,
        worst_ratio=ratio,
        worst_tau_s=float(t[worst]),
        chi2_dof=float(np.mean(zz**2)),
        adequate=bool(
            frac >= ADEQUACY_FRACTION and abs(math.log(ratio)) <= math.log(ADEQUACY_MAX_RATIO)
        ),
    )
    return out


def _score(adq: dict[str, Any]) -> tuple[int, float]:
    return (0 if adq.get("adequate") else 1, float(adq.get("chi2_dof", math.inf)))


def candidate_factors(
    n: int, rate_hz: float, decimate_to_hz: float | Literal["auto"] | None
) -> list[int]:
    """Block-averaging factors to try: the asked one first, then those of
    :data:`CANDIDATE_RATES_HZ` that leave at least :data:`CANDIDATE_MIN_SAMPLES`."""
    first = decimation_factor(n, rate_hz, decimate_to_hz)
    out = [first]
    for target in CANDIDATE_RATES_HZ:
        d = decimation_factor(n, rate_hz, target)
        if d not in out and n // d >= CANDIDATE_MIN_SAMPLES:
            out.append(d)
    return out


def _describe_misfit(kind: str, adq: dict[str, Any], tried: str) -> str:
    if "worst_ratio" not in adq:
        return f"no {kind} model could be checked against the curve ({adq.get('reason', '')})"
    return (
        f"no {kind} model fits the curve within its intervals (tried {tried}); the best "
        f"follows {adq['inside_fraction']:.0%} of the points from tau = "
        f"{adq['valid_from_tau_s']:.3g} s and is off by x{adq['worst_ratio']:.3g} at tau = "
        f"{adq['worst_tau_s']:.3g} s: do not use it to predict the curve there"
    )


def _best_gm(
    arr: NDArray[np.float64],
    rate_hz: float,
    factors: list[int],
    curve: Any,
    notes: list[str],
    **kw: Any,
) -> tuple[GaussMarkovModel | None, dict[str, Any] | None]:
    best: tuple[tuple[int, float], GaussMarkovModel, dict[str, Any], list[str]] | None = None
    errors: list[str] = []
    for d in factors:
        local: list[str] = []
        try:
            gm = fit_gauss_markov(arr, rate_hz, decimate_to_hz=rate_hz / d, notes=local, **kw)
        except ModelNotSupportedError as err:
            errors.append(str(err))
            continue
        adq = adequacy(gm, curve)
        key = (_score(adq)[0], d if adq.get("adequate") else _score(adq)[1])
        if best is None or key < best[0]:
            best = (key, gm, adq, local)
    if best is None:
        notes.append("Gauss-Markov model not fitted: " + (errors[0] if errors else "no rate"))
        return None, None
    _, gm, adq, local = best
    notes.extend(local)
    tried = ", ".join(f"{rate_hz / d:g} Hz" for d in factors)
    if not adq.get("adequate"):
        notes.append(_describe_misfit("Gauss-Markov (+ white)", adq, tried))
    return gm, adq


def _best_ar(
    arr: NDArray[np.float64],
    rate_hz: float,
    factors: list[int],
    curve: Any,
    order_max: int,
    criterion: str,
    notes: list[str],
    unit: str | None,
) -> tuple[ArModel | None, dict[str, Any] | None]:
    best: tuple[tuple[int, float], ArModel, dict[str, Any]] | None = None
    for d in factors:
        x = block_average(arr, d)
        n = x.size
        pmax = min(int(order_max), n // 10 - 1)
        if pmax < 1:
            continue
        pacf, s2 = burg_path(x, pmax)
        crit = information_criteria(s2, n)
        p0 = max(int(np.argmin(crit[criterion])), 1)
        orders = [p0] + [p for p in (*AR_ORDER_LADDER, pmax) if p0 < p <= pmax]
        local_best: tuple[tuple[int, float], ArModel, dict[str, Any]] | None = None
        for p in sorted(set(orders)):
            model = _ar_model(pacf, s2, p, rate_hz / d, d, criterion, pmax, crit, x, unit)
            adq = adequacy(model, curve)
            key = _score(adq)
            if local_best is None or key < local_best[0]:
                local_best = (key, model, adq)
            if adq.get("adequate"):
                break
        if local_best is None:
            continue
        key = (local_best[0][0], d if local_best[2].get("adequate") else local_best[0][1])
        if best is None or key < best[0]:
            best = (key, local_best[1], local_best[2])
    if best is None:
        notes.append("AR model not fitted: too few samples at every fit rate tried")
        return None, None
    _, model, adq = best
    tried = ", ".join(f"{rate_hz / d:g} Hz" for d in factors) + f", orders up to {order_max}"
    if not adq.get("adequate"):
        notes.append(_describe_misfit("AR", adq, tried))
    elif model.order == order_max:
        notes.append(f"the AR model needs the largest order tried ({order_max}); a larger"
                     " --ar-max-order may give a simpler fit elsewhere")  # fmt: skip
    return model, adq


def _ar_model(
    pacf: NDArray[np.float64],
    s2: NDArray[np.float64],
    p: int,
    rate: float,
    d: int,
    criterion: str,
    pmax: int,
    crit: dict[str, NDArray[np.float64]],
    x: NDArray[np.float64],
    unit: str | None,
) -> ArModel:
    a = ar_from_pacf(pacf[: p + 1])
    return ArModel(
        coefficients=tuple(float(v) for v in a),
        noise_variance=float(s2[p]),
        rate_hz=rate,
        decimation=d,
        criterion=criterion,
        orders=tuple(range(pmax + 1)),
        criteria={k: [float(v) for v in vals] for k, vals in crit.items()},
        mean=float(x.mean()),
        unit=unit,
    )


@dataclass
class ModelsResult:
    """The models fitted to one channel (either may be ``None``: see ``notes``)."""

    gauss_markov: GaussMarkovModel | None
    ar: ArModel | None
    rate_hz: float
    decimation: int
    n_samples: int
    unit: str | None = None
    notes: list[str] = field(default_factory=list)
    adequacy: dict[str, dict[str, Any]] = field(default_factory=dict)

    @property
    def effective_rate_hz(self) -> float:
        return self.rate_hz / self.decimation

    @property
    def models(self) -> dict[str, GaussMarkovModel | ArModel]:
        """The fitted models by name (``"gauss_markov"``, ``"ar"``)."""
        out: dict[str, GaussMarkovModel | ArModel] = {}
        if self.gauss_markov is not None:
            out["gauss_markov"] = self.gauss_markov
        if self.ar is not None:
            out["ar"] = self.ar
        return out

    def adev(self, tau: ArrayLike) -> dict[str, NDArray[np.float64]]:
        """Each model's theoretical Allan deviation at τ (s), for plotting."""
        return {k: m.adev(tau) for k, m in self.models.items()}

    def to_dict(self) -> dict[str, Any]:
        return {
            "input_rate_hz": self.rate_hz,
            "n_samples": self.n_samples,
            "decimation": self.decimation,
            "effective_rate_hz": self.effective_rate_hz,
            "decimation_method": "block average",
            "gauss_markov": _with_adequacy(self.gauss_markov, self.adequacy.get("gauss_markov")),
            "ar": _with_adequacy(self.ar, self.adequacy.get("ar")),
            "notes": list(self.notes),
        }


def _with_adequacy(
    model: GaussMarkovModel | ArModel | None, adq: dict[str, Any] | None
) -> dict[str, Any] | None:
    if model is None:
        return None
    d = model.to_dict()
    if adq is not None:
        d["adequacy"] = adq
    return d


def parse_kinds(kinds: str | Sequence[str]) -> tuple[str, ...]:
    """``"gm,ar"`` or a sequence → validated tuple of model kinds."""
    items = kinds.split(",") if isinstance(kinds, str) else list(kinds)
    alias = {"gauss_markov": "gm", "gm": "gm", "ar": "ar", "burg": "ar"}
    out: list[str] = []
    for k in items:
        key = alias.get(str(k).strip().lower())
        if key is None:
            raise OptionError(f"unknown model {k!r}; choose from gm, ar")
        if key not in out:
            out.append(key)
    return tuple(out)


def fit_models(
    y: ArrayLike,
    rate_hz: float,
    kinds: str | Sequence[str] = ("gm", "ar"),
    *,
    ar_order_max: int = 20,
    criterion: str = "bic",
    ar_order: int | None = None,
    decimate_to_hz: float | Literal["auto"] | None = "auto",
    max_lag_s: float | None = None,
    gm_method: Literal["acf_ls", "paper"] = "acf_ls",
    name: str = "signal",
    unit: str | None = None,
    curve: Any = None,
) -> ModelsResult:
    """Fit the asked stochastic models to one channel.

    Both fits share one block-averaged series (``decimate_to_hz``; default
    ``"auto"``: ~1 Hz, ≥ 20 000 samples kept).  Invalid input (NaN, constant,
    too short) raises; a model the data do not support (e.g. no positive
    autocorrelation for GM) is left ``None`` and explained in ``notes``.

    With ``curve`` (the channel's measured Allan-family curve) every model is
    checked against it (:func:`adequacy`): the fit is repeated at the fit rates
    of :func:`candidate_factors` and, for AR, at increasing orders from the
    criterion's choice up to ``ar_order_max``, and the first adequate model
    (widest valid range, lowest order) is kept; when none is adequate the
    closest one is kept and a note says plainly that no model of that family
    fits. ``adequacy`` of the result holds the check of each kept model.

    Other parameters are those of :func:`fit_gauss_markov` and :func:`fit_ar_burg`.
    """
    ks = parse_kinds(kinds)
    arr = _as_signal(y, rate_hz, name)
    d = decimation_factor(arr.size, rate_hz, decimate_to_hz)
    notes: list[str] = []
    if d > 1:
        dropped = arr.size % d
        notes.append(
            f"decimated by block averaging from {rate_hz:g} Hz to {rate_hz / d:g} Hz "
            f"(factor {d}) before the model fits"
            + (f"; last {dropped} samples dropped" if dropped else "")
        )
    fixed = float(rate_hz / d) if d > 1 else None
    gm: GaussMarkovModel | None = None
    ar: ArModel | None = None
    if curve is not None and ar_order is None:
        if criterion not in CRITERIA:
            raise OptionError(
                f"AR order criterion must be one of {', '.join(CRITERIA)}; got {criterion!r}"
            )
        if int(ar_order_max) < 1:
            raise OptionError(f"AR order must be >= 1, got {ar_order_max}")
        factors = candidate_factors(arr.size, rate_hz, decimate_to_hz)
        adq: dict[str, dict[str, Any]] = {}
        if "gm" in ks:
            gm, a_gm = _best_gm(arr, rate_hz, factors, curve, notes, max_lag_s=max_lag_s,
                                method=gm_method, name=name, unit=unit)  # fmt: skip
            if a_gm is not None:
                adq["gauss_markov"] = a_gm
        if "ar" in ks:
            ar, a_ar = _best_ar(arr, rate_hz, factors, curve, ar_order_max, criterion, notes, unit)
            if a_ar is not None:
                adq["ar"] = a_ar
    else:
        gm, ar = _fit_plain(arr, rate_hz, ks, fixed, notes, max_lag_s=max_lag_s,
                            gm_method=gm_method, ar_order_max=ar_order_max, criterion=criterion,
                            ar_order=ar_order, name=name, unit=unit)  # fmt: skip
        adq = {}
    return ModelsResult(
        gauss_markov=gm,
        ar=ar,
        rate_hz=float(rate_hz),
        decimation=d,
        n_samples=int(arr.size),
        unit=unit,
        notes=notes,
        adequacy=adq,
    )


def _fit_plain(
    arr: NDArray[np.float64],
    rate_hz: float,
    ks: tuple[str, ...],
    fixed: float | None,
    notes: list[str],
    *,
    max_lag_s: float | None,
    gm_method: Literal["acf_ls", "paper"],
    ar_order_max: int,
    criterion: str,
    ar_order: int | None,
    name: str,
    unit: str | None,
) -> tuple[GaussMarkovModel | None, ArModel | None]:
    """The models at one fit rate, without checking them against a curve."""
    gm: GaussMarkovModel | None = None
    ar: ArModel | None = None
    if "gm" in ks:
        try:
            gm = fit_gauss_markov(
                arr,
                rate_hz,
                decimate_to_hz=fixed,
                max_lag_s=max_lag_s,
                method=gm_method,
                name=name,
                unit=unit,
                notes=notes,
            )
        except ModelNotSupportedError as err:
            notes.append(f"Gauss-Markov model not fitted: {err}")
    if "ar" in ks:
        ar = fit_ar_burg(
            arr,
            rate_hz,
            order_max=ar_order_max,
            criterion=criterion,
            order=ar_order,
            decimate_to_hz=fixed,
            name=name,
            unit=unit,
            notes=notes,
        )
    return gm, ar
