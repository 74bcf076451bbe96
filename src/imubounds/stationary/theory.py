"""What each Allan-family estimator expects from each noise term and model (METHOD.md 1.2).

The IEEE 952 formula ``σ²(τ) = 3Q²/τ² + N²/τ + (2 ln2/π)·B² + K²·τ/3 + R²·τ²/2``
holds for the Allan variance only. The modified, Hadamard and total variances
respond to the same noise with other factors (a white rate noise gives a
modified variance of ``N²/(2τ)``, a flicker floor a Hadamard deviation of
``0.598·B`` instead of ``0.664·B``). Reading N or B off a modified or Hadamard
curve with the Allan factors gives numbers 30-45 % off. This module is the one
place those responses live; the read-off, the fit (:mod:`.terms`), the model
curves and the dynamic side all take them from here, so the same log gives
the same terms whatever the estimator.

:func:`response` returns the expected variance of one estimator per unit
squared term, at τ = m·t0 for a log of ``n_samples`` samples at ``rate_hz``:

================  ======================  ====================  ===========================
term              Allan (overlapping and  modified              Hadamard (overlapping and
                  non-overlapping)                              non-overlapping)
================  ======================  ====================  ===========================
Q (white angle)   3/τ²                    3/(m·τ²)              10/(3τ²)
N (white rate)    1/τ                     (1 + 1/m²)/(2τ)       1/τ
B (flicker rate)  2 ln2/π  (m → ∞)        (2/π)(27/16·ln3 −     (8 ln2 − 3 ln3)/(2π)
                                          2 ln2)  (m → ∞)       (m → ∞)
K (rate RW)       τ/3 + t0²/(6τ)          τ·(11/40 + 1/(8m²)    τ/6 + t0²/(6τ)
                                          + 1/(10m⁴))
R (rate ramp)     τ²/2                    τ²/2                  0 (blind to a drift)
================  ======================  ====================  ===========================

* Q, N, K and R are exact for the sampled processes the IEEE 952 model
  describes (white angle noise differenced, white rate samples of variance
  N²/t0, a rate random walk with steps of variance K²·t0, a ramp): they are
  sums of squared filter weights, worked out in closed form and checked in
  the tests against the estimators applied to unit impulses.
* B is a flicker (1/f) rate noise; its response depends on m at small m
  (the sampled 1/f spectrum up to the Nyquist frequency): computed by the
  exact spectral integral ``(1/π)∫_0^{1/2} |H_m(u)|²/u du`` for m ≤
  :data:`FLICKER_EXACT_M`, and the continuous constant beyond (within 2e-5).
  The continuous constants are those of NIST SP 1065 (Riley 2008), Table 3
  (Allan: 2 ln2·h₋₁) and section 5.2.5 (modified: ``2(27/16·ln3 − 2 ln2)·h₋₁``,
  i.e. ``R(n) = 0.674``); the Hadamard one is the transfer-function integral
  ``(8/3)∫ h₋₁/f · sin⁶(πfτ)/(πfτ)² df = (8/3)·h₋₁·(3/16)(8 ln2 − 3 ln3)``
  (expanding sin⁶ in cosines), here with the one-sided PSD ``h₋₁/f`` and
  ``h₋₁ = B²/π`` of IEEE 952's B: ``(8 ln2 − 3 ln3)/(2π)·B²``.
* The total variance has the Allan variance's expectation up to its
  reflection bias ``1 − a·τ/T`` (T the record length; NIST SP 1065 section
  5.2.11: a = 0 white FM, 1/(3 ln2) flicker FM, 0.75 random-walk FM) for B and
  K; for Q, N and R its expectation is computed exactly, edge terms included.

Stationary models (Gauss-Markov, AR) have an autocovariance; the expected
value of every estimator follows exactly from the variance ``S(k)`` of a sum
of k samples (:func:`variance_from_sums`, :func:`stationary_variance`), in
O(1) per τ after O(L) prefix sums. The total variance of a stationary model
is taken as its Allan variance (the reflection bias of a stationary process
is of order τ/T and not modelled).

Everything is SI: τ in s, terms in SI (rad/s^0.5 ...), variances in the
signal's unit squared.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from functools import lru_cache
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from imubounds.errors import OptionError

__all__ = [
    "B_VAR_FACTOR",
    "FAMILY",
    "FLICKER_EXACT_M",
    "TERMS",
    "TOTVAR_BIAS",
    "basis",
    "b_dev_factor",
    "observable",
    "response",
    "sigma",
    "stationary_variance",
    "sum_variance",
    "variance",
    "variance_from_sums",
]

TERMS: tuple[str, ...] = ("Q", "N", "B", "K", "R")

#: Estimator -> the family whose expectation it has.
FAMILY: dict[str, str] = {
    "overlapping": "allan",
    "non-overlapping": "allan",
    "modified": "modified",
    "hadamard": "hadamard",
    "non-overlapping-hadamard": "hadamard",
    "total": "total",
}

#: Continuous-limit variance of a flicker floor per unit B² (one-sided PSD B²/(π f)).
B_VAR_FACTOR: dict[str, float] = {
    "allan": 2.0 * math.log(2.0) / math.pi,  # 0.4413 (dev 0.6643)
    "modified": 2.0 * (27.0 / 16.0 * math.log(3.0) - 2.0 * math.log(2.0)) / math.pi,  # 0.2977
    "hadamard": (8.0 * math.log(2.0) - 3.0 * math.log(3.0)) / (2.0 * math.pi),  # 0.3580
}
B_VAR_FACTOR["total"] = B_VAR_FACTOR["allan"]

#: Total-variance bias coefficient a in ``E[Totvar] = Avar·(1 − a·τ/T)`` (NIST SP 1065 5.2.11).
TOTVAR_BIAS: dict[str, float] = {"N": 0.0, "B": 1.0 / (3.0 * math.log(2.0)), "K": 0.75}

#: Up to this cluster size the flicker response is the exact sampled-spectrum integral.
FLICKER_EXACT_M = 256


def _family(estimator: str) -> str:
    try:
        return FAMILY[estimator]
    except KeyError:
        raise OptionError(
            f"unknown Allan estimator {estimator!r}: use one of {', '.join(FAMILY)}"
        ) from None


def observable(term: str, estimator: str) -> bool:
    """Whether the estimator sees the term at all (the Hadamard family is blind to R)."""
    return not (term == "R" and _family(estimator) == "hadamard")


# --------------------------------------------------------------------------
# filter weights (on rate samples) of one term of each estimator
# --------------------------------------------------------------------------
def filter_weights(estimator: str, m: int) -> NDArray[np.float64]:
    """Weights w with ``E[σ²_est(m)] = E[(Σ_k w_k y_k)²]`` for a stationary rate y.

    Allan ``(ȳ₂ − ȳ₁)/√2``, Hadamard ``(ȳ₃ − 2ȳ₂ + ȳ₁)/√6`` (cluster means of m
    samples), modified: the m-sample average of Allan terms (NIST SP 1065 eq. 14).
    The total variance uses the Allan weights. Dimensionless.
    """
    fam = _family(estimator)
    m = int(m)
    if m < 1:
        raise OptionError(f"cluster size must be >= 1, got {m}")
    box = np.full(m, 1.0 / m)
    if fam in ("allan", "total"):
        return np.concatenate((-box, box)) / math.sqrt(2.0)
    if fam == "hadamard":
        return np.concatenate((box, -2.0 * box, box)) / math.sqrt(6.0)
    c = np.convolve(np.ones(m), np.concatenate((-np.ones(m), np.ones(m))))
    return c / (math.sqrt(2.0) * m * m)


@lru_cache(maxsize=4096)
def _flicker_exact(fam: str, m: int) -> float:
    """Exact sampled-flicker response at the integer cluster size m (≤ FLICKER_EXACT_M)."""
    est = {"allan": "overlapping", "modified": "modified", "hadamard": "hadamard"}[fam]
    w = filter_weights(est, m)
    pad = 1 << max(12, int(math.ceil(math.log2(128 * max(m, 1) * 3))))
    h2 = np.abs(np.fft.rfft(w, pad)) ** 2
    u = np.arange(h2.size, dtype=np.float64) / pad
    g = np.zeros_like(h2)
    g[1:] = h2[1:] / u[1:]
    return float(np.trapezoid(g, u)) / math.pi


def _flicker(fam: str, m: NDArray[np.float64]) -> NDArray[np.float64]:
    """Flicker response per unit B²: exact (log-linear between the integer cluster
    sizes around m, each computed once when first needed) below FLICKER_EXACT_M."""
    base = "allan" if fam == "total" else fam
    out = np.full(m.shape, B_VAR_FACTOR[base])
    small = np.isfinite(m) & (m < FLICKER_EXACT_M)
    if np.any(small):
        mm = np.clip(m[small], 1.0, float(FLICKER_EXACT_M))
        lo = np.floor(mm).astype(np.int64)
        hi = np.minimum(lo + 1, FLICKER_EXACT_M)
        vals = {int(k): _flicker_exact(base, int(k)) for k in np.unique(np.concatenate((lo, hi)))}
        f_lo = np.array([vals[int(k)] for k in lo])
        f_hi = np.array([vals[int(k)] for k in hi])
        x_lo, x_hi = np.log(lo.astype(np.float64)), np.log(hi.astype(np.float64))
        span = np.where(hi > lo, x_hi - x_lo, 1.0)
        frac = np.where(hi > lo, (np.log(mm) - x_lo) / span, 0.0)
        out[small] = f_lo + frac * (f_hi - f_lo)
    return out


# --------------------------------------------------------------------------
# total variance: exact expectations of Q, N and R with the reflected edges
# --------------------------------------------------------------------------
def _tot_edge_white_rate(m: NDArray[np.float64]) -> NDArray[np.float64]:
    """Σ_{k=1}^{m-1} v_k, v_k = 6k (k ≤ m/2), 4m − 2k (k > m/2): edge terms of white rate noise."""
    h = np.floor(m / 2.0)
    first = 3.0 * h * (h + 1.0)  # Σ_{k=1}^{h} 6k
    cnt = np.maximum(m - 1.0 - h, 0.0)  # k = h+1 .. m-1
    ksum = (h + 1.0 + (m - 1.0)) * cnt / 2.0
    return first + 4.0 * m * cnt - 2.0 * ksum


def _tot_edge_ramp(m: NDArray[np.float64]) -> NDArray[np.float64]:
    """Σ_{k=1}^{m-1} (4km − 2k²)²: edge terms of a rate ramp (phase a·k², per a²)."""
    j = m - 1.0
    s2 = j * (j + 1) * (2 * j + 1) / 6.0
    s3 = (j * (j + 1) / 2.0) ** 2
    s4 = j * (j + 1) * (2 * j + 1) * (3 * j * j + 3 * j - 1) / 30.0
    return 16.0 * m * m * s2 - 16.0 * m * s3 + 4.0 * s4


def _total(term: str, m: NDArray[np.float64], t0: float, n: float) -> NDArray[np.float64]:
    """Exact E[Totvar] per unit term² (Q, N, R) for integer-like m ≤ n/2."""
    tau = m * t0
    inner = n - 2.0 * m + 1.0
    if term == "N":
        s = 2.0 * m * inner + 2.0 * _tot_edge_white_rate(m)
        return t0 * s / (2.0 * tau**2 * (n - 1.0))
    if term == "Q":
        even = (np.round(m) % 2 == 0).astype(np.float64)
        s = 6.0 * inner + 2.0 * (10.0 * (m - 1.0) + 4.0 * even)
        return np.asarray(s / (2.0 * tau**2 * (n - 1.0)), dtype=np.float64)
    # R: phase x_k = a k² (+ linear), a = R t0²/2
    a2 = (t0 * t0 / 2.0) ** 2
    s = 4.0 * m**4 * inner + 2.0 * _tot_edge_ramp(m)
    return a2 * s / (2.0 * tau**2 * (n - 1.0))


# --------------------------------------------------------------------------
# the responses
# --------------------------------------------------------------------------
def response(
    term: str,
    estimator: str,
    tau_s: ArrayLike,
    *,
    rate_hz: float | None = None,
    n_samples: int | None = None,
) -> NDArray[np.float64]:
    """Expected variance of ``estimator`` at ``tau_s`` per unit squared ``term``.

    Parameters
    ----------
    term : {"Q", "N", "B", "K", "R"}
    estimator : str
        One of :data:`FAMILY` (the names of :mod:`.allan`).
    tau_s : array_like
        Averaging times in s.
    rate_hz : float, optional
        Sample rate. With it the exact sampled responses are used (m = τ·rate);
        without it the continuous limits (m → ∞). The modified variance of Q
        needs it.
    n_samples : int, optional
        Log length; sets T = n/rate for the total variance's reflection bias
        and edge terms (ignored by the other estimators). Without it T = ∞.

    Returns
    -------
    ndarray
        ``E[σ²(τ)] / term²``: multiply by the squared term (SI) to get the
        variance in the signal's unit squared.
    """
    if term not in TERMS:
        raise OptionError(f"unknown noise term {term!r}: use one of {', '.join(TERMS)}")
    fam = _family(estimator)
    tau = np.asarray(tau_s, dtype=np.float64)
    if rate_hz is not None:
        if not (math.isfinite(rate_hz) and rate_hz > 0):
            raise OptionError(f"sample rate must be a positive number of Hz, got {rate_hz!r}")
        t0 = 1.0 / float(rate_hz)
        m = tau / t0
    else:
        t0 = 0.0
        m = np.full(tau.shape, np.inf)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv_m2 = np.where(np.isfinite(m), 1.0 / m**2, 0.0)
        if fam == "total":
            if n_samples is not None and rate_hz is not None and term in ("Q", "N", "R"):
                n = float(n_samples)
                return np.asarray(_total(term, np.maximum(m, 1.0), t0, n), dtype=np.float64)
            base = response(term, "overlapping", tau, rate_hz=rate_hz)
            if n_samples is not None and rate_hz is not None and term in TOTVAR_BIAS:
                big_t = float(n_samples) * t0
                return np.asarray(base * (1.0 - TOTVAR_BIAS[term] * tau / big_t))
            return base
        if term == "Q":
            if fam == "allan":
                return 3.0 / tau**2
            if fam == "hadamard":
                return 10.0 / (3.0 * tau**2)
            if rate_hz is None:
                raise OptionError(
                    "the modified variance of quantization noise depends on the sample rate;"
                    " give rate_hz"
                )
            return 3.0 / (m * tau**2)
        if term == "N":
            if fam == "modified":
                return (1.0 + inv_m2) / (2.0 * tau)
            return 1.0 / tau
        if term == "B":
            return _flicker(fam, m)
        if term == "K":
            if fam == "allan":
                return tau / 3.0 + tau * inv_m2 / 6.0
            if fam == "hadamard":
                return tau / 6.0 + tau * inv_m2 / 6.0
            return tau * (11.0 / 40.0 + inv_m2 / 8.0 + inv_m2**2 / 10.0)
        # R
        if fam == "hadamard":
            return np.zeros_like(tau)
        return tau**2 / 2.0


def basis(
    tau_s: ArrayLike,
    estimator: str,
    *,
    rate_hz: float | None = None,
    n_samples: int | None = None,
    terms: tuple[str, ...] = TERMS,
) -> NDArray[np.float64]:
    """Columns ``f_j(τ)`` with ``E[σ²(τ)] = Σ_j term_j² · f_j(τ)`` (shape (len(τ), len(terms)))."""
    return np.column_stack(
        [response(t, estimator, tau_s, rate_hz=rate_hz, n_samples=n_samples) for t in terms]
    )


def _term_values(terms: Mapping[str, Any] | Any) -> dict[str, float]:
    out: dict[str, float] = {}
    for t in TERMS:
        if isinstance(terms, Mapping):
            v = terms.get(t)
            if isinstance(v, Mapping):  # a noise.json entry {"value": ...}
                v = v.get("value")
        else:
            v = getattr(terms, t, None)
        try:
            x = float(v) if v is not None else 0.0
        except (TypeError, ValueError):
            raise OptionError(f"noise term {t} must be a number, got {v!r}") from None
        if math.isnan(x):
            x = 0.0
        if not (math.isfinite(x) and x >= 0):
            raise OptionError(f"noise term {t} must be finite and >= 0, got {v!r}")
        out[t] = x
    return out


def variance(
    terms: Mapping[str, Any] | Any,
    tau_s: ArrayLike,
    estimator: str = "overlapping",
    *,
    rate_hz: float | None = None,
    n_samples: int | None = None,
) -> NDArray[np.float64]:
    """Expected variance (signal unit²) of ``estimator`` for the given terms at ``tau_s``.

    ``terms`` maps Q, N, B, K, R to SI values (missing, None or NaN count as
    0), or is an object with those attributes (:class:`~.terms.NoiseTerms`), or
    a noise.json ``selected`` block (``{"N": {"value": ...}, ...}``).
    """
    vals = _term_values(terms)
    tau = np.asarray(tau_s, dtype=np.float64)
    out = np.zeros(tau.shape)
    for t in TERMS:
        if vals[t] > 0:
            out = out + vals[t] ** 2 * response(
                t, estimator, tau, rate_hz=rate_hz, n_samples=n_samples
            )
    return out


def sigma(
    terms: Mapping[str, Any] | Any,
    tau_s: ArrayLike,
    estimator: str = "overlapping",
    *,
    rate_hz: float | None = None,
    n_samples: int | None = None,
) -> NDArray[np.float64]:
    """Expected deviation of ``estimator`` at ``tau_s`` (s) for noise terms in SI.

    The stationary prediction of an IMU channel: for example
    ``sigma(selected, [1.0], "overlapping")`` is the Allan deviation at
    τ = 1 s (rad/s for a gyro, m/s² for an accelerometer). See :func:`variance`
    for ``terms`` and :func:`response` for ``rate_hz`` and ``n_samples``.
    """
    return np.sqrt(variance(terms, tau_s, estimator, rate_hz=rate_hz, n_samples=n_samples))


def b_dev_factor(estimator: str, tau_s: ArrayLike | None = None, **kw: Any) -> NDArray[np.float64]:
    """Deviation of a flicker floor per unit B (0.664 for Allan, 0.546 modified, 0.598 Hadamard).

    Without ``tau_s`` the continuous constant; with it the exact sampled value
    (pass ``rate_hz`` and, for the total deviation, ``n_samples``).
    """
    if tau_s is None:
        return np.asarray(math.sqrt(B_VAR_FACTOR[_family(estimator)]))
    return np.sqrt(response("B", estimator, tau_s, **kw))


# --------------------------------------------------------------------------
# stationary processes with a known autocovariance (GM, AR)
# --------------------------------------------------------------------------
def sum_variance(acov: NDArray[np.float64]) -> NDArray[np.float64]:
    """S(k) = Var(sum of k consecutive samples) for k = 0..len(acov), from R(0..L-1)."""
    r = np.asarray(acov, dtype=np.float64)
    kmax = r.size
    j = np.arange(kmax, dtype=np.float64)
    # S(k) = k R0 + 2 Σ_{j=1}^{k-1} (k-j) R(j) = k R0 + 2(k c1[k] - c2[k])
    c1 = np.concatenate(([0.0, 0.0], np.cumsum(r[1:])))  # c1[k] = Σ_{j=1}^{k-1} R(j)
    c2 = np.concatenate(([0.0, 0.0], np.cumsum(j[1:] * r[1:])))
    k = np.arange(kmax + 1, dtype=np.float64)
    return np.asarray(k * r[0] + 2.0 * (k * c1[: kmax + 1] - c2[: kmax + 1]), dtype=np.float64)


def variance_from_sums(s: NDArray[np.float64], m: ArrayLike, estimator: str) -> NDArray[np.float64]:
    """Expected variance of ``estimator`` at integer cluster sizes ``m`` of a sequence
    with stationary increments of its partial sums: ``s[k] = Var(sum of k samples)``,
    k = 0..≥3·max(m).

    Allan ``(4S(m) − S(2m))/(2m²)``; Hadamard ``(15S(m) − 6S(2m) + S(3m))/(6m²)``;
    modified ``−Σ_δ c_δ·T(δ)/(4m⁴)`` with ``c = 6, −4, −4, 1, 1`` at
    ``δ = 0, ±m, ±2m`` and ``T(δ) = Σ_{|h|<m} (m − |h|)·S(|h + δ|)`` (the
    variance of a sum of m overlapping second differences of the partial
    sums, written with the structure function S); total: as Allan.
    """
    fam = _family(estimator)
    mm = np.atleast_1d(np.asarray(m, dtype=np.int64))
    sv = np.asarray(s, dtype=np.float64)
    if mm.size and np.any(mm < 1):
        raise OptionError("cluster sizes must be >= 1")
    need = (3 if fam in ("hadamard", "modified") else 2) * int(mm.max(initial=1))
    if sv.size <= need:
        raise ValueError(f"need S(k) up to k = {need}, have {sv.size - 1}")
    mf = mm.astype(np.float64)
    if fam in ("allan", "total"):
        return np.asarray((4.0 * sv[mm] - sv[2 * mm]) / (2.0 * mf * mf), dtype=np.float64)
    if fam == "hadamard":
        return np.asarray(
            (15.0 * sv[mm] - 6.0 * sv[2 * mm] + sv[3 * mm]) / (6.0 * mf * mf), dtype=np.float64
        )
    u = np.arange(sv.size, dtype=np.float64)
    p0 = np.concatenate(([0.0], np.cumsum(sv)))  # p0[k] = Σ_{u<k} S(u)
    p1 = np.concatenate(([0.0], np.cumsum(u * sv)))

    def wsum(alpha: NDArray[np.float64], a: NDArray[np.int64], b: NDArray[np.int64]) -> Any:
        """Σ_{u=a}^{b} (alpha + u)·S(u) (zero where b < a)."""
        out = alpha * (p0[b + 1] - p0[a]) + (p1[b + 1] - p1[a])
        return np.where(b >= a, out, 0.0)

    # T(0) = 2 Σ_{u=1}^{m-1} (m - u) S(u)   (S(0) = 0)
    t_zero = 2.0 * (mf * (p0[mm] - p0[1]) - (p1[mm] - p1[1]))

    def t_shift(d: NDArray[np.int64]) -> Any:
        # δ ≥ m: Σ_{u=δ-m+1}^{δ} (m - δ + u) S(u) + Σ_{u=δ+1}^{δ+m-1} (m + δ - u) S(u)
        df = d.astype(np.float64)
        rise = wsum(mf - df, d - mm + 1, d)
        fall = (mf + df) * (p0[d + mm] - p0[d + 1]) - (p1[d + mm] - p1[d + 1])
        return rise + fall

    var_sum = -0.5 * (6.0 * t_zero - 8.0 * t_shift(mm) + 2.0 * t_shift(2 * mm))
    return np.asarray(var_sum / (2.0 * mf**4), dtype=np.float64)


def variance_at_sums(
    sums: Callable[[NDArray[np.int64]], NDArray[np.float64]], m: ArrayLike, estimator: str
) -> NDArray[np.float64]:
    """:func:`variance_from_sums` for the Allan and Hadamard families from
    ``sums(k) = S(k)`` evaluated only at the cluster sizes needed (m, 2m, 3m): for a
    process whose S(k) has a closed form
    (:func:`~imubounds.stationary.gauss_markov.gm_sum_variance`)."""
    fam = _family(estimator)
    if fam not in ("allan", "total", "hadamard"):
        raise OptionError(
            f"variance_at_sums covers the Allan and Hadamard families, not {estimator!r}"
        )
    mm = np.atleast_1d(np.asarray(m, dtype=np.int64))
    if mm.size and np.any(mm < 1):
        raise OptionError("cluster sizes must be >= 1")
    mf = mm.astype(np.float64)
    s1, s2 = sums(mm), sums(2 * mm)
    if fam == "hadamard":
        s3 = sums(3 * mm)
        return np.asarray((15.0 * s1 - 6.0 * s2 + s3) / (6.0 * mf * mf), dtype=np.float64)
    return np.asarray((4.0 * s1 - s2) / (2.0 * mf * mf), dtype=np.float64)


def stationary_variance(
    acov: Callable[[int], NDArray[np.float64]], m: ArrayLike, estimator: str
) -> NDArray[np.float64]:
    """Exact expected variance of ``estimator`` at integer cluster sizes ``m`` for a
    stationary sequence with autocovariance ``acov(nlags) -> R[0..nlags-1]``
    (see :func:`variance_from_sums`). Units: the signal's squared."""
    mm = np.atleast_1d(np.asarray(m, dtype=np.int64))
    if mm.size == 0:
        return np.zeros(0)
    if np.any(mm < 1):
        raise OptionError("cluster sizes must be >= 1")
    return variance_from_sums(sum_variance(acov(3 * int(mm.max()) + 1)), mm, estimator)
