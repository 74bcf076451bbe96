"""The curve as the term fits see it (:mod:`imubounds.stationary.terms`): each
point's response to the five terms (the estimator's basis), local slopes, the
per-point spread of ln σ² from the EDF, the curve's upper bound of a term, and the
robust weighted NNLS of the squared terms with its misfit η."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import special

from imubounds.errors import AnalysisError
from imubounds.stationary import theory
from imubounds.stationary.edf import chi2_ppf, norm_ppf
from imubounds.units import Term

TERMS: tuple[Term, ...] = ("Q", "N", "B", "K", "R")

#: Smallest EDF of a point used to locate a term, σ_min or a read-off.
EDF_MIN = 10.0
#: Two-sided level of the per-point intervals behind an upper bound (0.99:
#: each point's upper end is its 99.5 % one-sided bound).
UPPER_BOUND_LEVEL = 0.99
#: Tukey biweight tuning constant (95 % efficiency at the normal law).
TUKEY_C = 4.685


class AllanCurve(Protocol):
    """What the fits need from an Allan result (:class:`~imubounds.stationary.allan.AllanResult`).

    ``estimator``, ``rate_hz`` and ``n_samples`` are read when present
    (defaults: overlapping, continuous-time factors, no record-length bias).
    """

    @property
    def tau(self) -> NDArray[np.float64]: ...
    @property
    def dev(self) -> NDArray[np.float64]: ...
    @property
    def ci_lower(self) -> NDArray[np.float64]: ...
    @property
    def ci_upper(self) -> NDArray[np.float64]: ...
    @property
    def edf(self) -> NDArray[np.float64]: ...


# --------------------------------------------------------------------------
# the curve
# --------------------------------------------------------------------------
@dataclass(frozen=True)
class _Curve:
    tau: NDArray[np.float64]
    dev: NDArray[np.float64]
    lo: NDArray[np.float64]
    hi: NDArray[np.float64]
    edf: NDArray[np.float64]
    estimator: str
    rate_hz: float | None
    n_samples: int | None
    basis: NDArray[np.float64]  # (k, 5) responses per unit term²

    @property
    def avar(self) -> NDArray[np.float64]:
        return self.dev**2

    def observable(self) -> list[bool]:
        return [theory.observable(t, self.estimator) and bool(np.any(self.basis[:, j] > 0))
                for j, t in enumerate(TERMS)]  # fmt: skip


def _curve(curve: AllanCurve) -> _Curve:
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
    estimator = str(getattr(curve, "estimator", "overlapping"))
    rate = getattr(curve, "rate_hz", None)
    n = getattr(curve, "n_samples", None)
    rate_f = float(rate) if rate is not None else None
    n_i = int(n) if n is not None else None
    tau = tau[ok]
    return _Curve(
        tau=tau,
        dev=dev[ok],
        lo=lo[ok],
        hi=hi[ok],
        edf=np.where(np.isfinite(edf[ok]) & (edf[ok] > 0), edf[ok], 1.0),
        estimator=estimator,
        rate_hz=rate_f,
        n_samples=n_i,
        basis=theory.basis(tau, estimator, rate_hz=rate_f, n_samples=n_i),
    )


def _curve_fields(c: _Curve) -> dict[str, Any]:
    return {"estimator": c.estimator, "rate_hz": c.rate_hz, "n_samples": c.n_samples}


def _term_fields(values: Mapping[str, float]) -> dict[str, Any]:
    return {t: float(values[t]) for t in TERMS}


def local_slopes(tau: ArrayLike, dev: ArrayLike) -> NDArray[np.float64]:
    """Local log-log slope d log σ / d log τ at each point (central differences)."""
    lt = np.log(np.asarray(tau, dtype=np.float64))
    ld = np.log(np.asarray(dev, dtype=np.float64))
    if lt.size < 2:
        return np.zeros_like(lt)
    return np.gradient(ld, lt)


def _log_sd(edf: NDArray[np.float64]) -> NDArray[np.float64]:
    """Standard deviation of ln(σ²_est) for a chi-squared estimate with ``edf`` dof."""
    return np.sqrt(np.asarray(special.polygamma(1, np.maximum(edf, 0.5) / 2.0), dtype=np.float64))


def _upper_points(c: _Curve, level: float = UPPER_BOUND_LEVEL) -> NDArray[np.float64]:
    """Per-point upper ends of σ at ``level`` (two-sided) from each point's EDF."""
    p = 1.0 - level
    return np.asarray(c.dev * np.sqrt(c.edf / chi2_ppf(p / 2.0, c.edf)), dtype=np.float64)


def curve_upper_bound(curve: AllanCurve | _Curve, term: str) -> tuple[float, float]:
    """Upper bound of one term from the curve's intervals, and the τ (s) that sets it.

    ``min_τ σ_hi(τ)/√f_term(τ)`` over the points with EDF ≥ :data:`EDF_MIN`
    (all points when none has it), σ_hi the 99 % upper end
    (:data:`UPPER_BOUND_LEVEL`): every other term only adds variance, so the
    term cannot exceed this wherever the interval holds. Points with fewer
    degrees of freedom are left out: their chi-squared intervals are too
    uncertain to bound anything (a two-term point can sit at 3 % of its
    expectation). ``(inf, nan)`` when the estimator is blind to the term.
    """
    c = curve if isinstance(curve, _Curve) else _curve(curve)
    j = TERMS.index(term)
    f = c.basis[:, j]
    if not np.any(f > 0):
        return math.inf, math.nan
    ok = (f > 0) & (c.edf >= EDF_MIN)
    if not np.any(ok):  # a very short log: every point, however few its dof
        ok = f > 0
    up = _upper_points(c)
    cand = up[ok] / np.sqrt(f[ok])
    i = int(np.argmin(cand))
    return float(cand[i]), float(c.tau[ok][i])


# --------------------------------------------------------------------------
# robust weighted fit
# --------------------------------------------------------------------------
def _nnls_weighted(
    A: NDArray[np.float64], b: NDArray[np.float64], sw: NDArray[np.float64]
) -> NDArray[np.float64]:
    """NNLS of ``(A x - b)·sw`` with column scaling; returns x ≥ 0."""
    # imported here: scipy.optimize takes half a second, which `imubounds static`
    # spends while the log is read (cli/static.py)
    from scipy.optimize import nnls

    Aw = A * sw[:, None]
    bw = b * sw
    scale = np.linalg.norm(Aw, axis=0)
    scale[scale == 0] = 1.0
    x, _ = nnls(Aw / scale, bw, maxiter=50 * A.shape[1])
    return np.asarray(x / scale, dtype=np.float64)


def _tukey(r: NDArray[np.float64]) -> NDArray[np.float64]:
    u = r / TUKEY_C
    return np.where(np.abs(u) < 1.0, (1.0 - u * u) ** 2, 0.0)


def _eta_from_residuals(
    lr: NDArray[np.float64], sd: NDArray[np.float64], w: NDArray[np.float64]
) -> float:
    """Relative misfit η with median |lr/√(sd² + η²)| = 0.6745 over the kept points."""
    keep = w > 0
    if np.count_nonzero(keep) < 3:
        return 0.0
    a = np.abs(lr[keep])
    s = sd[keep]
    if _median_small(a / s) <= _Q75:
        return 0.0
    s2 = s * s
    lo, hi = 0.0, float(np.max(a)) * 10.0 + 1e-12
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        if _median_small(a / np.sqrt(s2 + mid * mid)) > _Q75:
            lo = mid
        else:
            hi = mid
    return hi


#: The upper quartile of the standard normal (median |z| of a Gaussian).
_Q75 = float(norm_ppf(0.75))


def _median_small(v: NDArray[np.float64]) -> float:
    """``np.median`` of a short finite 1-d array, bit for bit, without its overhead
    (a sort in place: the mean of the two middle values, or the middle one). The
    bisection above calls it 80 times per fit iteration: with ``np.median`` it was a
    third of a static unit's time."""
    v.sort()
    n = v.size
    if n == 0 or np.isnan(v[-1]):  # NaN sorts last; np.median gives NaN
        return math.nan
    h = n // 2
    return float(v[h]) if n % 2 else float((v[h - 1] + v[h]) / 2.0)


def _grid_density(tau: NDArray[np.float64]) -> float:
    """Points per octave of the τ grid (neighbouring points share data beyond one)."""
    if tau.size < 2:
        return 1.0
    octaves = math.log2(float(tau[-1] / tau[0]))
    return max(1.0, (tau.size - 1) / octaves) if octaves > 0 else 1.0


#: At most this fraction of the points may be rejected by the robust weights; when
#: more disagree with the model, the misfit is global and η grows instead.
MAX_REJECTED = 0.25


def _smoothed(avar: NDArray[np.float64]) -> NDArray[np.float64]:
    """Three-point running median of a curve (ends kept): a start that one notch cannot move."""
    if avar.size < 3:
        return avar
    mid = np.median(np.stack((avar[:-2], avar[1:-1], avar[2:])), axis=0)
    return np.concatenate(([avar[0]], mid, [avar[-1]]))


def _robust_fit(
    A: NDArray[np.float64],
    avar: NDArray[np.float64],
    sd_stat: NDArray[np.float64],
    robust: bool,
    iterations: int,
) -> tuple[NDArray[np.float64], NDArray[np.float64], float]:
    """Iteratively reweighted NNLS: coefficients, robust weights and the misfit η.

    Starts from weights of a smoothed curve, iterates model-based weights
    (plain IRLS), then Tukey weights; never rejects more than
    :data:`MAX_REJECTED` of the points (η grows instead).
    """
    coef = _nnls_weighted(A, avar, 1.0 / (_smoothed(avar) * sd_stat))
    w = np.ones(avar.size)
    eta = 0.0
    n_iter = max(1, iterations)
    for it in range(n_iter):
        model = A @ coef
        model = np.where(np.isfinite(model) & (model > 0), model, avar * 1e-12)
        lr = np.log(avar / model)
        use_robust = robust and it >= n_iter // 3
        eta = _eta_from_residuals(lr, sd_stat, w if use_robust else np.ones_like(w))
        if use_robust:
            cap = int(MAX_REJECTED * avar.size)
            a = np.sort(np.abs(lr) / TUKEY_C)[::-1]  # |lr| / c per point, largest first
            if cap < a.size and a[cap] > 0:
                # the (cap+1)-th largest residual must stay inside the Tukey window
                need = a[cap] ** 2 - float(np.min(sd_stat)) ** 2
                eta = max(eta, math.sqrt(need) if need > 0 else 0.0)
        sd = np.sqrt(sd_stat**2 + eta**2)
        w = _tukey(lr / sd) if use_robust else np.ones(avar.size)
        if np.count_nonzero(w > 0) < A.shape[1] + 1:
            w = np.ones(avar.size)
        new = _nnls_weighted(A, avar, np.sqrt(w) / (model * sd))
        done = it >= n_iter // 3 and np.allclose(new, coef, rtol=1e-7, atol=1e-300)
        coef = new
        if done:
            break
    return coef, w, eta
