"""Noise terms read off an Allan-deviation curve (METHOD.md 1.2, IEEE Std 952 Annex C).

The Allan variance of the five classical error processes adds up to

    σ²(τ) = 3Q²/τ² + N²/τ + (2 ln2/π)·B² + K²·τ/3 + R²·τ²/2

Two estimators are offered:

* :func:`fit_slopes` — the paper's (and IEEE 952's) read-off: a line of the
  term's slope is laid through the point of the curve whose local slope is
  closest to it, and read at the characteristic τ (N at τ = 1 s, K at τ = 3 s,
  Q at τ = √3 s, R at τ = √2 s; B = σ_min / 0.664). A term whose slope is not
  seen on the curve is reported as not observed (``nan``) with the reason.
* :func:`fit_terms` — a weighted non-negative least-squares fit of all five
  coefficients to σ²(τ) over the whole curve, weighted by the statistical
  uncertainty of each Allan-variance point (from its equivalent degrees of
  freedom), iteratively re-weighted with the model.

Everything is SI: Q in rad (m/s), N in rad/s^0.5 (m/s^1.5), B in rad/s
(m/s^2), K in rad/s^1.5 (m/s^2.5), R in rad/s^2 (m/s^3).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import nnls
from scipy.stats import norm

from imubounds.errors import AnalysisError
from imubounds.units import SI_UNITS, SensorKind, Term, to_ieee

TERMS: tuple[Term, ...] = ("Q", "N", "B", "K", "R")
#: √(2 ln2 / π): the flat level of the Allan deviation of flicker noise, per unit B.
B_FACTOR = math.sqrt(2.0 * math.log(2.0) / math.pi)  # 0.6643
#: log-log slope of σ(τ) for each term, and the τ (s) at which the line is read.
SLOPES: dict[Term, float] = {"Q": -1.0, "N": -0.5, "B": 0.0, "K": 0.5, "R": 1.0}
READ_TAU: dict[Term, float] = {"Q": math.sqrt(3.0), "N": 1.0, "K": 3.0, "R": math.sqrt(2.0)}
#: How far (in slope units) the local slope may be from a term's slope for the
#: term to count as observed by the read-off.
SLOPE_TOLERANCE = 0.15


class AllanCurve(Protocol):
    """What the fits need from an Allan result (:class:`~imubounds.stationary.allan.AllanResult`).
    """

    tau: NDArray[np.float64]
    dev: NDArray[np.float64]
    ci_lower: NDArray[np.float64]
    ci_upper: NDArray[np.float64]
    edf: NDArray[np.float64]


@dataclass(frozen=True)
class NoiseTerms:
    """Five noise coefficients in SI with optional confidence intervals.

    ``nan`` marks a term the method could not determine; ``notes`` says why.
    ``ci`` maps a term to ``(lower, upper)`` in SI; ``tau_used`` maps a term
    to the τ (s) of the point it was read from (slope method only).
    """

    Q: float = 0.0
    N: float = 0.0
    B: float = 0.0
    K: float = 0.0
    R: float = 0.0
    method: str = ""
    ci: dict[str, tuple[float, float]] = field(default_factory=dict)
    tau_used: dict[str, float] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)

    def value(self, term: Term) -> float:
        return float(getattr(self, term))

    def as_dict(self) -> dict[str, float]:
        """Term -> SI value (``nan`` where undetermined)."""
        return {t: self.value(t) for t in TERMS}

    def avar(self, tau: ArrayLike) -> NDArray[np.float64]:
        """Model Allan variance of these terms (undetermined terms count as 0)."""
        vals = {t: (v if math.isfinite(v) else 0.0) for t, v in self.as_dict().items()}
        return avar_terms(tau, **vals)

    def adev(self, tau: ArrayLike) -> NDArray[np.float64]:
        """Model Allan deviation of these terms."""
        return np.sqrt(self.avar(tau))

    def to_json(self, kind: SensorKind) -> dict[str, Any]:
        """JSON form: per term ``{"value", "unit", "ieee": {"value", "unit"}, "ci", ...}``."""
        out: dict[str, Any] = {"method": self.method}
        for t in TERMS:
            v = self.value(t)
            finite = math.isfinite(v)
            iv, iu = to_ieee(kind, t, v) if finite else (None, to_ieee(kind, t, 1.0)[1])
            entry: dict[str, Any] = {
                "value": v if finite else None,
                "unit": SI_UNITS[kind][t],
                "ieee": {"value": iv, "unit": iu},
            }
            if t in self.ci:
                lo, hi = self.ci[t]
                entry["ci"] = [lo, hi]
                entry["ieee"]["ci"] = [to_ieee(kind, t, lo)[0], to_ieee(kind, t, hi)[0]]
            if t in self.tau_used:
                entry["tau_s"] = self.tau_used[t]
            out[t] = entry
        if self.notes:
            out["notes"] = list(self.notes)
        return out


def avar_terms(
    tau: ArrayLike,
    Q: float = 0.0,
    N: float = 0.0,
    B: float = 0.0,
    K: float = 0.0,
    R: float = 0.0,
) -> NDArray[np.float64]:
    """Allan variance σ²(τ) of the five IEEE 952 terms (τ in s, terms in SI)."""
    t = np.asarray(tau, dtype=np.float64)
    return (
        3.0 * Q * Q / t**2 + N * N / t + (B_FACTOR * B) ** 2 + K * K * t / 3.0 + R * R * t**2 / 2.0
    )


def _basis(tau: NDArray[np.float64]) -> NDArray[np.float64]:
    """Columns f_j(τ) with σ² = Σ c_j f_j, c = (Q², N², B², K², R²)."""
    return np.column_stack(
        [3.0 / tau**2, 1.0 / tau, np.full_like(tau, B_FACTOR**2), tau / 3.0, tau**2 / 2.0]
    )


def _curve_arrays(curve: AllanCurve) -> tuple[NDArray[np.float64], ...]:
    tau = np.asarray(curve.tau, dtype=np.float64)
    dev = np.asarray(curve.dev, dtype=np.float64)
    lo = np.asarray(curve.ci_lower, dtype=np.float64)
    hi = np.asarray(curve.ci_upper, dtype=np.float64)
    edf = np.asarray(curve.edf, dtype=np.float64)
    ok = np.isfinite(tau) & np.isfinite(dev) & (dev > 0) & (tau > 0)
    if np.count_nonzero(ok) < 2:
        raise AnalysisError(
            "the Allan curve has fewer than 2 usable points; use a longer log or a denser tau grid"
        )
    return tau[ok], dev[ok], lo[ok], hi[ok], edf[ok]


def local_slopes(tau: ArrayLike, dev: ArrayLike) -> NDArray[np.float64]:
    """Local log-log slope d log σ / d log τ at each point (central differences)."""
    lt = np.log(np.asarray(tau, dtype=np.float64))
    ld = np.log(np.asarray(dev, dtype=np.float64))
    if lt.size < 2:
        return np.zeros_like(lt)
    return np.gradient(ld, lt)


def fit_slopes(curve: AllanCurve, *, tolerance: float = SLOPE_TOLERANCE) -> NoiseTerms:
    """IEEE 952 slope read-off of Q, N, B, K and R.

    For a term of slope s, the point of the curve whose local slope is closest
    to s is taken; if it is within ``tolerance`` of s, the line of slope s
    through it is read at the term's characteristic τ. The confidence interval
    of that point scales the read value. B is the minimum of the curve divided
    by 0.664, with the CI of that point. A term whose slope does not appear on
    the curve is ``nan`` with a note.
    """
    tau, dev, lo, hi, _ = _curve_arrays(curve)
    slopes = local_slopes(tau, dev)
    values: dict[str, float] = {}
    ci: dict[str, tuple[float, float]] = {}
    tau_used: dict[str, float] = {}
    notes: list[str] = []
    for term in TERMS:
        if term == "B":
            i = int(np.argmin(dev))
            interior = 0 < i < tau.size - 1 or abs(slopes[i]) <= tolerance
            if not interior:
                values[term] = math.nan
                notes.append(
                    f"B: the curve has no minimum inside the tau range (lowest point at "
                    f"tau={tau[i]:.4g} s, slope {slopes[i]:+.2f}); extend the log or the tau grid"
                )
                continue
            values[term] = dev[i] / B_FACTOR
            ci[term] = (lo[i] / B_FACTOR, hi[i] / B_FACTOR)
            tau_used[term] = float(tau[i])
            continue
        s = SLOPES[term]
        i = int(np.argmin(np.abs(slopes - s)))
        if abs(slopes[i] - s) > tolerance:
            values[term] = math.nan
            notes.append(
                f"{term}: no part of the curve has slope {s:+.1f} (closest {slopes[i]:+.2f} at "
                f"tau={tau[i]:.4g} s); term not observed"
            )
            continue
        scale = (READ_TAU[term] / tau[i]) ** s
        values[term] = dev[i] * scale
        ci[term] = (lo[i] * scale, hi[i] * scale)
        tau_used[term] = float(tau[i])
    return NoiseTerms(
        method="slope", ci=ci, tau_used=tau_used, notes=notes, **{t: values[t] for t in TERMS}
    )


#: Smallest relative standard deviation given to any Allan-variance point in
#: the fit. Real curves deviate from the five-term model by more than the
#: statistical error of their short-τ points (edf in the millions); without a
#: floor those points dictate the fit and the mid-range is missed by 2-3x.
REL_FLOOR = 0.1
#: Reduced chi-squared above which the floor is applied (the model misfits).
CHI2_MISFIT = 4.0


def _avar_sigma(
    avar: NDArray[np.float64], edf: NDArray[np.float64], rel_floor: float = REL_FLOOR
) -> NDArray[np.float64]:
    """Standard deviation of an Allan-variance estimate: σ²·max(√(2/edf), floor)."""
    e = np.where(np.isfinite(edf) & (edf > 0), edf, 1.0)
    return avar * np.maximum(np.sqrt(2.0 / e), rel_floor)


def _irls(
    A_full: NDArray[np.float64],
    avar: NDArray[np.float64],
    edf: NDArray[np.float64],
    rel_floor: float,
    iterations: int,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Iteratively re-weighted NNLS; returns coefficients and the final point sigmas."""
    sigma = _avar_sigma(avar, edf, rel_floor)
    coef = np.zeros(A_full.shape[1])
    for _ in range(max(1, iterations)):
        A = A_full / sigma[:, None]
        b = avar / sigma
        scale = np.linalg.norm(A, axis=0)
        scale[scale == 0] = 1.0
        x, _ = nnls(A / scale, b, maxiter=50 * A_full.shape[1])
        coef = x / scale
        model = A_full @ coef
        if not np.all(np.isfinite(model)) or np.any(model <= 0):
            break
        sigma = _avar_sigma(model, edf, rel_floor)
    return coef, sigma


def fit_terms(
    curve: AllanCurve,
    *,
    terms: tuple[Term, ...] = TERMS,
    iterations: int = 4,
    confidence: float = 0.683,
    rel_floor: float = REL_FLOOR,
) -> NoiseTerms:
    """Weighted non-negative least-squares fit of the noise terms to σ²(τ).

    Minimises Σ_i ((σ²_model(τ_i) − σ²_i)/s_i)² over c = (Q², N², B², K², R²) ≥ 0,
    where s_i = σ²·max(√(2/edf_i), ``rel_floor``) is the standard deviation of
    the i-th Allan variance estimate. When the curve departs from the
    five-term model by more than its statistical error (reduced χ² above
    :data:`CHI2_MISFIT`, typical of real sensors whose short-τ points have
    edf in the millions), the fit is repeated with s_i floored at
    ``rel_floor`` relative, so that no handful of points dictates the fit;
    a note says so. The weights are first taken from the measured curve
    and then re-computed from the model (iteratively re-weighted), which avoids
    the downward bias of weighting by the data themselves.

    Confidence intervals come from the covariance of the weighted fit on the
    active (non-zero) coefficients, mapped through c ↦ √c; a coefficient
    pinned at zero gets the interval ``(0, upper)`` from a one-sided bound.
    """
    tau, dev, _, _, edf = _curve_arrays(curve)
    avar = dev**2
    cols = [TERMS.index(t) for t in terms]
    A_full = _basis(tau)[:, cols]
    notes: list[str] = []
    coef, sigma = _irls(A_full, avar, edf, 0.0, iterations)
    dof = max(tau.size - int(np.count_nonzero(coef)), 1)
    chi2 = float(np.sum(((A_full @ coef - avar) / sigma) ** 2)) / dof
    if rel_floor > 0 and chi2 > CHI2_MISFIT:
        coef, sigma = _irls(A_full, avar, edf, rel_floor, iterations)
        notes.append(
            f"fit: the curve departs from the five-term model beyond its statistical error "
            f"(chi2/dof = {chi2:.3g}); point weights floored at {rel_floor:.0%} relative"
        )
    A = A_full / sigma[:, None]
    # Inflate the covariance by the final reduced chi-squared when the model misfits.
    chi2_final = float(np.sum(((A_full @ coef - avar) / sigma) ** 2)) / dof
    inflate = max(1.0, chi2_final)
    z = float(norm.ppf(0.5 + confidence / 2.0))
    values = {t: 0.0 for t in TERMS}
    ci: dict[str, tuple[float, float]] = {}
    active = coef > 0
    cov = np.full((len(cols), len(cols)), np.nan)
    if np.any(active):
        Aa = A[:, active]
        try:
            cov_a = np.linalg.inv(Aa.T @ Aa) * inflate
            idx = np.flatnonzero(active)
            cov[np.ix_(idx, idx)] = cov_a
        except np.linalg.LinAlgError:
            pass
    for j, t in enumerate(terms):
        c = float(coef[j])
        values[t] = math.sqrt(c)
        var_c = cov[j, j]
        if active[j] and math.isfinite(var_c) and var_c >= 0:
            sd = math.sqrt(var_c)
            ci[t] = (math.sqrt(max(c - z * sd, 0.0)), math.sqrt(c + z * sd))
        else:
            # Pinned at zero: a one-sided upper bound from the column's own information.
            col = A[:, j]
            info = float(col @ col)
            if info > 0:
                ci[t] = (0.0, math.sqrt(z / math.sqrt(info)))
    pinned = [t for j, t in enumerate(terms) if not active[j]]
    if pinned:
        notes.append("fit: " + ", ".join(pinned) + " not supported by the curve (fitted as 0)")
    return NoiseTerms(method="fit", ci=ci, notes=notes, **values)
