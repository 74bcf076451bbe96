"""First-order Gauss–Markov model of a static sensor signal (METHOD.md 1.3); see
:mod:`imubounds.stationary.models` for the conventions and the model choice."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

from imubounds.errors import AnalysisError, InputError, OptionError
from imubounds.stationary import theory
from imubounds.stationary.model_base import (
    FIT_SPAN_TC,
    MIN_SAMPLES,
    WHITE_FRACTION,
    ModelNotSupportedError,
    _as_signal,
    _at_tau,
    _avar_at_tau,
    _rng,
    _variance_at_tau,
    block_average,
    decimation_factor,
    sample_autocovariance,
)


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


def gm_sum_variance(
    k: ArrayLike, sigma2: float, a: float, white_var: float = 0.0
) -> NDArray[np.float64]:
    """S(k) = Var(sum of k consecutive samples) of a sampled first-order GM plus white
    noise, in closed form: R(0) = σ² + r_w, R(j) = σ²·e^{-a·j} (a = β·δt > 0).

    S(k) = k·R(0) + 2σ²·Σ_{j=1}^{k-1}(k-j)φ^j, φ = e^{-a}, and
    Σ_{j=1}^{k-1}(k-j)φ^j = φ·[k(1-φ) - (1-φ^k)]/(1-φ)². The bracket cancels
    for small k·a; there its series Σ_{n≥2} (-1)^n (k^n - k) a^n / n! is used.
    Equals :func:`imubounds.stationary.theory.sum_variance` of the same
    autocovariance to rounding, without building the lags.
    """
    kk = np.asarray(k, dtype=np.float64)
    u = -math.expm1(-a)  # 1 - φ
    ka = kk * a
    with np.errstate(over="ignore", invalid="ignore"):
        bracket = kk * u + np.expm1(-ka)
        small = ka < 0.5
        if np.any(small):
            ks = kk[small]
            ser = np.zeros(ks.size)
            for n in range(30, 1, -1):  # smallest terms first
                ser += (-1.0) ** n * (ks**n - ks) * a**n / math.factorial(n)
            bracket = bracket.copy()
            bracket[small] = ser
    phi = math.exp(-a)
    return np.asarray(kk * (sigma2 + white_var) + 2.0 * sigma2 * phi * bracket / (u * u),
                      dtype=np.float64)  # fmt: skip


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

        if theory.FAMILY.get(estimator) in ("allan", "total", "hadamard"):
            a = -log_phi

            def at_m(m: NDArray[np.int64]) -> NDArray[np.float64]:
                def sums(k: NDArray[np.int64]) -> NDArray[np.float64]:
                    return gm_sum_variance(k, sig2, a, r_white)

                return theory.variance_at_sums(sums, m, estimator)

            return _at_tau(tau, dt, at_m)

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
        from scipy import signal  # only here: its import takes a quarter of a second

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


@njit(cache=True, fastmath=False)
def _exp_fit_cost(q: float, y: NDArray[np.float64]) -> tuple[float, float]:
    """For e_j = q^j (j = 1..L): the best amplitude A = Σ e·y / Σ e² (> 0) and the
    residual sum of squares Σ (A·e - y)², in two passes without temporaries."""
    see = 0.0
    sey = 0.0
    e = 1.0
    for k in range(y.size):
        e *= q
        see += e * e
        sey += e * y[k]
    amp = sey / see if see > 0.0 else 1e-300
    amp = max(amp, 1e-300)
    cost = 0.0
    e = 1.0
    for k in range(y.size):
        e *= q
        r = amp * e - y[k]
        cost += r * r
    return amp, cost


def _fit_exponential(
    j: NDArray[np.float64], y: NDArray[np.float64], b0: float
) -> tuple[float, float]:
    """Least squares of ``A·exp(-b·j)`` to ``y`` (b in [1e-12, 50]) by variable
    projection: for a given b the best A is linear, ``Σ e·y / Σ e²`` (e = exp(-b·j)),
    so only b is searched: a grid of ln b over a factor e^±3 around ``b0``, then
    Brent's bounded search between the grid neighbours of the best point (to 1e-9 in
    ln b). A search of b alone cannot run off to the empty fit (A → 0, b large) that
    a joint search may fall into. Returns (A, b); A > 0."""

    if not np.array_equal(j, np.arange(1, j.size + 1, dtype=np.float64)):
        raise ValueError("the exponential fit takes the lags 1..L")
    yc = np.ascontiguousarray(y, dtype=np.float64)

    def amp_and_cost(lb: float) -> tuple[float, float]:
        amp, cost = _exp_fit_cost(math.exp(-math.exp(lb)), yc)
        return float(amp), float(cost)

    lo, hi = math.log(1e-12), math.log(50.0)
    lb0 = min(max(math.log(max(b0, 1e-12)), lo), hi)
    grid = np.clip(lb0 + np.linspace(-3.0, 3.0, 13), lo, hi)
    costs = [amp_and_cost(float(v))[1] for v in grid]
    k = int(np.argmin(costs))
    a_lo, a_hi = float(grid[max(k - 1, 0)]), float(grid[min(k + 1, grid.size - 1)])
    lb = a_lo
    if a_hi > a_lo:
        from scipy import optimize  # here: a half-second import

        sol = optimize.minimize_scalar(
            lambda v: amp_and_cost(v)[1],
            bounds=(a_lo, a_hi),
            method="bounded",
            options={"xatol": 1e-9},
        )
        lb = float(sol.x)
    amp, _ = amp_and_cost(lb)
    return amp, math.exp(lb)


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
        amp_s, b = _fit_exponential(jj, yy / scale, b)
        amp = amp_s * scale
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
