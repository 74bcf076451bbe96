"""AR(p) model of a static sensor signal by Burg's method (METHOD.md 1.3); see
:mod:`imubounds.stationary.models` for the conventions and the model choice."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

from imubounds.errors import AnalysisError, InputError, OptionError
from imubounds.stationary.model_base import (
    MIN_SAMPLES,
    _as_signal,
    _avar_at_tau,
    _rng,
    _variance_at_tau,
    block_average,
    decimation_factor,
)

CRITERIA: tuple[str, ...] = ("aic", "bic", "hqic", "fpe")


def ar_autocovariance(
    coefficients: ArrayLike, noise_variance: float, nlags: int
) -> NDArray[np.float64]:
    """Exact autocovariance R(0..nlags-1) of the stationary AR(p)
    ``y[n] = -Σ a_k y[n-k] + e[n]``, var(e) = noise_variance.

    R(0..p) solve the Yule–Walker system ``R(k) + Σ_i a_i R(|k-i|) = σ_e² δ_k``;
    later lags follow ``R(j) = -Σ a_i R(j-i)`` (:func:`_ar_tail`).
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
    out = np.empty(nlags)
    out[: p + 1] = r
    _ar_tail(np.ascontiguousarray(a), out, p + 1)
    return out


@njit(cache=True, fastmath=False)
def _ar_tail(a: NDArray[np.float64], r: NDArray[np.float64], start: int) -> None:
    """``r[j] = -Σ_i a_i r[j-i]`` for ``j >= start``, in place, summed from the
    oldest term to the newest as ``scipy.signal.lfilter`` does (the values it gave
    before; without importing ``scipy.signal``, a quarter of a second)."""
    p = a.size
    for j in range(start, r.size):
        acc = 0.0
        for i in range(p, 0, -1):
            acc -= a[i - 1] * r[j - i]
        r[j] = acc


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
        from scipy import signal

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

    The recursion of ``statsmodels.tsa.stattools.pacf_burg`` (Brockwell & Davis
    2016, O(n·p), one pass for all orders) on the demeaned series, compiled
    (:func:`_burg_kernel`). Returns ``(pacf, sigma2)``, ``pacf[0] = 1``.
    """
    arr = np.asarray(x, dtype=np.float64)
    p = max(int(order_max), 1)
    if p > arr.size - 1:
        raise ValueError("order_max must be smaller than the number of samples - 1")
    pacf, d = _burg_kernel(np.ascontiguousarray(arr - arr.mean()), p)
    sigma2 = (1.0 - pacf**2) * d / (2.0 * (arr.size - np.arange(p + 1)))
    pacf[0] = 1.0
    return np.asarray(pacf), np.asarray(sigma2)


@njit(cache=True, fastmath=False)
def _burg_kernel(x: NDArray[np.float64], p: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Burg's recursion: reflection coefficients ``pacf[1..p]`` and the forward plus
    backward prediction error energies ``d[0..p]`` (u, v: backward/forward errors of
    the reversed series, updated in place)."""
    n = x.size
    u = x[::-1].copy()
    v = x[::-1].copy()
    d = np.zeros(p + 1)
    pacf = np.zeros(p + 1)
    d[0] = 2.0 * np.dot(x, x)
    d[1] = np.dot(u[:-1], u[:-1]) + np.dot(v[1:], v[1:])
    pacf[1] = 2.0 / d[1] * np.dot(v[1:], u[:-1])
    for i in range(1, p):
        k = pacf[i]
        prev_u = u[0]
        for t in range(1, n):  # u[t] = u[t-1] - k v[t], v[t] = v[t] - k u[t-1] (old values)
            ut = u[t]
            u[t] = prev_u - k * v[t]
            v[t] = v[t] - k * prev_u
            prev_u = ut
        d[i + 1] = (1.0 - k * k) * d[i] - v[i] ** 2 - u[n - 1] ** 2
        acc = 0.0
        for t in range(i + 1, n):
            acc += v[t] * u[t - 1]
        pacf[i + 1] = 2.0 / d[i + 1] * acc
    return pacf, d


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
