"""Noise terms read off an Allan-family curve (METHOD.md 1.2, IEEE Std 952 Annex C).

For the Allan variance the five classical error processes add up to

    σ²(τ) = 3Q²/τ² + N²/τ + (2 ln2/π)·B² + K²·τ/3 + R²·τ²/2;

every other estimator has its own factors (:mod:`.theory`), and every
function here uses the factors of the curve's own estimator, so that the same
log gives the same Q, N, B, K, R whichever estimator drew the curve.

Three results are built from one curve:

* :func:`fit_terms` — a weighted non-negative least-squares fit of the five
  squared terms to σ²(τ), **robust** (iteratively reweighted with Tukey's
  biweight on log residuals, so that a notch or a bump of a few points
  cannot drag it) and with **honest uncertainty**: each point's standard
  error is its statistical one (from its EDF) combined with a relative model
  misfit η estimated from the residuals themselves (the median standardised
  residual is made that of a normal law), and the covariance is inflated
  for τ grids denser than one point per octave (neighbouring points share
  their data). Terms whose removal does not raise χ² by 4 (2σ) are removed
  one by one. A kept term is ``resolved`` when it dominates the
  model (half the variance; a quarter for B) at some point whose EDF is at
  least :data:`EDF_MIN`; otherwise it is an ``upper_bound``.
* :func:`fit_slopes` — the IEEE 952 read-off, done where each term lives:
  its *home* is the set of points where the fit gives it at least half of
  the variance and the EDF is adequate; the line of the term's slope is laid
  tangent to the curve inside the home (the point minimising
  ``σ²(τ)/f_j(τ)``, which is where the local slope equals the term's) and
  read at the characteristic τ. The τ used, the local slope there and the
  expected slope are reported, with a warning when they disagree (other
  terms contribute there and the value is an upper estimate). B is read
  from σ_min, the lowest point with adequate EDF: ``B = σ_min / 0.664`` on
  an Allan curve (0.546 modified, 0.598 Hadamard). The read-off counts as
  resolved only where the fit resolves the term.
* :func:`select_terms` — the terms used for bounds and ``imu.yaml``: a
  resolved term from the preferred estimate, otherwise an **upper bound**
  from the curve's confidence intervals where the term would show,
  ``min_τ σ_hi(τ)/√f_j(τ)`` at 99 % per point with EDF ≥ 10. Every other
  term only adds variance, so the true term lies below it whenever the
  intervals hold. An unresolved term is never 0.

Everything is SI: Q in rad (m/s), N in rad/s^0.5 (m/s^1.5), B in rad/s
(m/s^2), K in rad/s^1.5 (m/s^2.5), R in rad/s^2 (m/s^3).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from imubounds.errors import InputError, OptionError
from imubounds.stationary import theory
from imubounds.stationary.consistency import consistent_bound, describe_misfit, misfit_ranges
from imubounds.stationary.edf import norm_ppf
from imubounds.stationary.term_curve import EDF_MIN as EDF_MIN
from imubounds.stationary.term_curve import TERMS as TERMS
from imubounds.stationary.term_curve import (
    UPPER_BOUND_LEVEL,
    _Curve,
    _curve,
    _curve_fields,
    _grid_density,
    _log_sd,
    _nnls_weighted,
    _robust_fit,
    _term_fields,
)
from imubounds.stationary.term_curve import AllanCurve as AllanCurve
from imubounds.stationary.term_curve import _eta_from_residuals as _eta_from_residuals
from imubounds.stationary.term_curve import _median_small as _median_small
from imubounds.stationary.term_curve import curve_upper_bound as curve_upper_bound
from imubounds.stationary.term_curve import local_slopes as local_slopes
from imubounds.units import DATASHEET_UNITS, SI_UNITS, SensorKind, Term, to_datasheet, to_ieee

#: √(2 ln2 / π): the flat level of the Allan deviation of flicker noise, per unit B.
B_FACTOR = math.sqrt(2.0 * math.log(2.0) / math.pi)  # 0.6643
#: The τ (s) at which IEEE 952 reads each term's line on an Allan curve
#: (N at 1 s, K at 3 s, Q at √3 s, R at √2 s); other estimators: :func:`expected_slope`.
READ_TAU: dict[Term, float] = {"Q": math.sqrt(3.0), "N": 1.0, "K": 3.0, "R": math.sqrt(2.0)}
#: How far (in slope units) the local slope may be from the term's expected
#: slope before the read-off warns that other terms contribute there.
SLOPE_TOLERANCE = 0.15
#: Share of the model variance a term must carry somewhere (at a point with EDF ≥
#: EDF_MIN) to be resolved: it must dominate the curve there; B, which lives where
#: the N and K lines cross, needs a quarter. A term hidden under another (N under a
#: large flicker floor at the sample period) depends on how the hiding term is
#: modelled there, and is reported as an upper bound instead.
SHARE_VISIBLE: dict[str, float] = {"Q": 0.5, "N": 0.5, "B": 0.25, "K": 0.5, "R": 0.5}
#: Share of the model variance that makes a point part of a term's home for the read-off.
SHARE_MIN = 0.5
#: A term stays in the fit when removing it raises chi-squared by at least this squared.
RESOLVE_Z = 2.0

Status = Literal["resolved", "upper_bound", "not_observed"]


@dataclass(frozen=True)
class NoiseTerms:
    """Five noise coefficients in SI with confidence intervals and a status each.

    ``nan`` marks a term the method could not read; ``status`` says per term
    ``resolved``, ``upper_bound`` or ``not_observed`` (the estimator is blind to
    it); ``ci`` maps a term to ``(lower, upper)`` in SI; ``tau_used`` to the τ (s)
    of the point it was read from; ``info`` holds per-term details for the
    JSON (local slope, share of the variance, ...); ``stats`` the fit's
    statistics. ``estimator``, ``rate_hz`` and ``n_samples`` are those of the
    curve, so :meth:`avar` draws the model in the curve's own statistic.
    ``kind`` (``"gyro"`` or ``"accel"``, when known) gives the units of
    :meth:`to_dict` and :meth:`to_frame`.
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
    status: dict[str, str] = field(default_factory=dict)
    info: dict[str, dict[str, Any]] = field(default_factory=dict)
    stats: dict[str, Any] = field(default_factory=dict)
    estimator: str = "overlapping"
    rate_hz: float | None = None
    n_samples: int | None = None
    kind: SensorKind | None = None

    def value(self, term: Term | str) -> float:
        return float(getattr(self, term))

    def as_dict(self) -> dict[str, float]:
        """Term -> SI value (``nan`` where undetermined)."""
        return {t: self.value(t) for t in TERMS}

    def avar(self, tau: ArrayLike) -> NDArray[np.float64]:
        """Model variance of these terms in the curve's own statistic (nan terms count as 0)."""
        return theory.variance(
            self.as_dict(), tau, self.estimator, rate_hz=self.rate_hz, n_samples=self.n_samples
        )

    def adev(self, tau: ArrayLike) -> NDArray[np.float64]:
        """Model deviation of these terms in the curve's own statistic."""
        return np.sqrt(self.avar(tau))

    def to_json(self, kind: SensorKind) -> dict[str, Any]:
        """JSON form: per term ``{"value", "unit", "status", "ieee", "datasheet", "ci", ...}``."""
        out: dict[str, Any] = {"method": self.method, "estimator": self.estimator}
        for t in TERMS:
            v = self.value(t)
            entry = term_entry(kind, t, v if math.isfinite(v) else None, self.ci.get(t))
            if t in self.status:
                entry["status"] = self.status[t]
            if t in self.tau_used:
                entry["tau_s"] = self.tau_used[t]
            entry.update(self.info.get(t, {}))
            out[t] = entry
        if self.stats:
            out["stats"] = dict(self.stats)
        if self.notes:
            out["notes"] = list(self.notes)
        return out

    def to_dict(self) -> dict[str, Any]:
        """:meth:`to_json` in the units of ``kind`` as plain JSON types (nan -> None): the
        ``noise.fit`` or ``noise.slope`` block of noise.json."""
        from imubounds.io.outputs import to_jsonable

        out: dict[str, Any] = to_jsonable(self.to_json(_known_kind(self.kind)))
        return out

    def to_frame(self) -> Any:
        """One row per term: ``term``, ``value`` (SI), ``unit``, ``status``, ``ci_lower``,
        ``ci_upper``, ``tau_s``, ``ieee_value``, ``ieee_unit``, ``datasheet_value``,
        ``datasheet_unit`` (a :class:`pandas.DataFrame`)."""
        return _terms_frame(self.to_dict(), source=None)


def _known_kind(kind: SensorKind | None) -> SensorKind:
    if kind is None:
        raise OptionError(
            "the sensor of these terms is unknown, so are their units: use "
            "imubounds.noise_terms(curve, sensor='gyro' or 'accel')"
        )
    return kind


def _terms_frame(d: Mapping[str, Any], source: str | None) -> Any:
    """The per-term rows of a JSON terms block (``noise.fit``, ``noise.selected``)."""
    import pandas as pd

    rows = []
    for t in TERMS:
        e = d[t]
        ci = e.get("ci") or [None, None]
        row: dict[str, Any] = {
            "term": t,
            "value": e["value"],
            "unit": e["unit"],
            "status": e.get("status"),
        }
        if source is not None:
            row["source"] = e.get(source)
        row.update(
            {
                "ci_lower": ci[0],
                "ci_upper": ci[1],
                "tau_s": e.get("tau_s"),
                "ieee_value": e["ieee"]["value"],
                "ieee_unit": e["ieee"]["unit"],
                "datasheet_value": e["datasheet"]["value"],
                "datasheet_unit": e["datasheet"]["unit"],
            }
        )
        rows.append(row)
    return pd.DataFrame(rows)


def term_entry(
    kind: SensorKind, term: str, value: float | None, ci: tuple[float, float] | None = None
) -> dict[str, Any]:
    """``{"value", "unit", "ieee": {...}, "datasheet": {...}, "ci"}`` for one SI term value."""
    t: Term = term  # type: ignore[assignment]
    iv, iu = to_ieee(kind, t, value) if value is not None else (None, to_ieee(kind, t, 1.0)[1])
    dv, du = (
        to_datasheet(kind, t, value) if value is not None else (None, DATASHEET_UNITS[kind][t][0])
    )
    entry: dict[str, Any] = {
        "value": value,
        "unit": SI_UNITS[kind][t],
        "ieee": {"value": iv, "unit": iu},
        "datasheet": {"value": dv, "unit": du},
    }
    if ci is not None:
        lo, hi = float(ci[0]), float(ci[1])
        entry["ci"] = [lo, hi]
        entry["ieee"]["ci"] = [to_ieee(kind, t, lo)[0], to_ieee(kind, t, hi)[0]]
        entry["datasheet"]["ci"] = [to_datasheet(kind, t, lo)[0], to_datasheet(kind, t, hi)[0]]
    return entry


def avar_terms(
    tau: ArrayLike,
    Q: float = 0.0,
    N: float = 0.0,
    B: float = 0.0,
    K: float = 0.0,
    R: float = 0.0,
) -> NDArray[np.float64]:
    """Allan variance σ²(τ) of the five IEEE 952 terms (τ in s, terms in SI, continuous time).

    Other estimators: :func:`imubounds.stationary.theory.variance`.
    """
    t = np.asarray(tau, dtype=np.float64)
    return (
        3.0 * Q * Q / t**2 + N * N / t + (B_FACTOR * B) ** 2 + K * K * t / 3.0 + R * R * t**2 / 2.0
    )


def fit_terms(
    curve: AllanCurve,
    *,
    terms: tuple[Term, ...] = TERMS,
    confidence: float = 0.683,
    robust: bool = True,
    iterations: int = 30,
) -> NoiseTerms:
    """Robust weighted non-negative least-squares fit of the noise terms to σ²(τ).

    Minimises Σ_i w_i ((Σ_j c_j f_j(τ_i) − σ²_i)/s_i)² over c = (Q², N², B², K², R²) ≥ 0,
    with f_j the responses of the curve's estimator (:mod:`.theory`),
    s_i = model_i·√(ψ₁(edf_i/2) + η²) (ψ₁ the trigamma function: the spread
    of ln σ² for a chi-squared estimate) and w_i Tukey biweights of the
    standardised log residuals (all 1 when ``robust`` is False). η, the
    model misfit, is re-estimated at every iteration from the median
    residual.

    The weights and η of the full five-term fit are then kept fixed, and terms
    the curve does not support are removed one at a time: the one whose removal
    raises χ² least, while that rise (divided by the covariance inflation) is
    below :data:`RESOLVE_Z`² — a likelihood-ratio test at about 2σ — so that an
    unsupported R does not blur K, nor Q blur N, and two terms that can stand
    in for each other do not both vanish. A kept term is ``resolved`` when it carries at least
    its :data:`SHARE_VISIBLE` share of the model variance at some point with
    EDF ≥ :data:`EDF_MIN`; a removed or hidden one is an ``upper_bound``
    (the bound itself comes from :func:`select_terms`).

    Returns
    -------
    NoiseTerms
        ``method="fit"``; values are √c; ``stats`` holds ``chi2_dof`` (with the
        misfit), ``chi2_dof_statistical`` (without), ``misfit_rel`` (η),
        ``points_downweighted``, ``cov_inflation`` and ``removed`` terms.
    """
    c = _curve(curve)
    avar = c.avar
    obs = c.observable()
    candidates = [j for j, t in enumerate(TERMS) if t in terms and obs[j]]
    sd_stat = _log_sd(c.edf)
    z = float(norm_ppf(0.5 + confidence / 2.0))
    density = _grid_density(c.tau)
    # 1. the full model, robustly: its weights and misfit are then kept fixed
    full, w, eta = _robust_fit(c.basis[:, candidates], avar, sd_stat, robust, iterations)
    model_full = c.basis[:, candidates] @ full
    model_full = np.where(model_full > 0, model_full, avar * 1e-12)
    sd = np.sqrt(sd_stat**2 + eta**2)
    sw = np.sqrt(w) / (model_full * sd)
    kept = max(float(np.sum(w)), 1.0)
    chi2_full = float(np.sum((sw * (model_full - avar)) ** 2)) / max(kept - len(candidates), 1.0)
    inflate = density * max(1.0, chi2_full)

    def objective(cols: list[int]) -> tuple[NDArray[np.float64], float]:
        x = _nnls_weighted(c.basis[:, cols], avar, sw)
        return x, float(np.sum((sw * (c.basis[:, cols] @ x - avar)) ** 2))

    # 2. backward elimination by the rise of chi-squared when a term is dropped
    active = list(candidates)
    removed: list[int] = []
    coef, obj = objective(active)
    while len(active) > 1:
        rises = []
        for j in active:
            rest = [k for k in active if k != j]
            _, o = objective(rest)
            rises.append((o - obj) / inflate)
        k_min = int(np.argmin(rises))
        if rises[k_min] >= RESOLVE_Z**2:
            break
        removed.append(active.pop(k_min))
        coef, obj = objective(active)
    A = c.basis[:, active]
    model = A @ coef
    model = np.where(model > 0, model, avar * 1e-12)
    lr = np.log(avar / model)
    pos = coef > 0
    dof = max(kept - int(np.count_nonzero(pos)), 1.0)
    chi2 = float(np.sum(w * (lr / sd) ** 2)) / dof
    J = A * sw[:, None]
    cov = np.full((len(active), len(active)), np.nan)
    if np.any(pos):
        Ja = J[:, pos]
        idx = np.flatnonzero(pos)
        cov[np.ix_(idx, idx)] = np.linalg.pinv(Ja.T @ Ja) * inflate
    sd_c = np.sqrt(np.where(np.isfinite(np.diag(cov)), np.diag(cov), np.inf))
    chi2_stat = float(np.sum(w * (lr / sd_stat) ** 2)) / dof
    shares = _shares(c, coef, active)
    adequate = c.edf >= EDF_MIN
    values: dict[str, float] = {t: 0.0 for t in TERMS}
    ci: dict[str, tuple[float, float]] = {}
    status: dict[str, str] = {}
    info: dict[str, dict[str, Any]] = {}
    notes: list[str] = []
    for j, t in enumerate(TERMS):
        if not obs[j]:
            values[t] = math.nan
            status[t] = "not_observed"
            info[t] = {"reason": f"the {c.estimator} estimator is blind to {t}"}
            continue
        if j not in active:
            ub, tau_ub = curve_upper_bound(c, t)
            status[t] = "upper_bound"
            ci[t] = (0.0, ub)
            info[t] = {"removed": True, "upper_bound": ub, "upper_bound_tau_s": tau_ub}
            continue
        k = active.index(j)
        cj = float(coef[k])
        values[t] = math.sqrt(cj)
        share = shares[:, k]
        best = float(np.max(share[adequate])) if np.any(adequate) else 0.0
        i_best = int(np.argmax(np.where(adequate, share, -1.0)))
        sdk = float(sd_c[k])
        ci[t] = (math.sqrt(max(cj - z * sdk, 0.0)), math.sqrt(cj + z * sdk))
        status[t] = "resolved" if best >= SHARE_VISIBLE[t] else "upper_bound"
        info[t] = {
            "max_share": best,
            "tau_max_share_s": float(c.tau[i_best]),
            "rel_se": sdk / cj / 2.0 if cj > 0 else None,
        }
    down = int(np.count_nonzero(w < 0.5))
    if down:
        where = ", ".join(f"{x:.3g}" for x in c.tau[w < 0.5][:6])
        notes.append(
            f"fit: {down} point(s) disagree with the model beyond their uncertainty and were "
            f"down-weighted (tau = {where} s)"
        )
    if eta > 0.05:
        notes.append(
            f"fit: the curve departs from the five-term model by about {eta:.0%} beyond its "
            "statistical error; the term intervals include that misfit"
        )
    gone = [TERMS[j] for j in removed]
    if gone:
        notes.append(
            "fit: " + ", ".join(gone) + " not supported by the curve (removed from the fit;"
            " upper bounds from the curve are used)"
        )
    return NoiseTerms(
        method="fit",
        ci=ci,
        notes=notes,
        status=status,
        info=info,
        stats={
            "chi2_dof": chi2,
            "chi2_dof_statistical": chi2_stat,
            "misfit_rel": eta,
            "points": int(avar.size),
            "points_downweighted": down,
            "cov_inflation": inflate,
            "removed": gone,
            "point_weights": [float(v) for v in w],
            "robust": bool(robust),
            "confidence": confidence,
        },
        **_curve_fields(c),
        **_term_fields(values),
    )


def _shares(c: _Curve, coef: NDArray[np.float64], cols: list[int]) -> NDArray[np.float64]:
    """Share of the model variance of each fitted term at each point, shape (k, len(cols))."""
    parts = c.basis[:, cols] * coef[None, :]
    tot = parts.sum(axis=1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(tot > 0, parts / tot, 0.0)


def _full_shares(c: _Curve, fit: NoiseTerms) -> NDArray[np.float64]:
    vals = np.array([fit.value(t) if math.isfinite(fit.value(t)) else 0.0 for t in TERMS])
    return _shares(c, vals**2, list(range(len(TERMS))))


# --------------------------------------------------------------------------
# read-off where each term lives
# --------------------------------------------------------------------------
def expected_slope(term: str, estimator: str, tau_s: float, **kw: Any) -> float:
    """Log-log slope of the term's deviation line for this estimator at τ (numerical)."""
    t = np.array([tau_s / 1.05, tau_s * 1.05])
    r = theory.response(term, estimator, t, **kw)
    if np.any(r <= 0):
        return math.nan
    return float(0.5 * (math.log(r[1]) - math.log(r[0])) / math.log(1.05**2))


def _fit_weights(fit: NoiseTerms, size: int) -> NDArray[np.float64]:
    w = np.asarray(fit.stats.get("point_weights", np.ones(size)), dtype=np.float64)
    return w if w.shape == (size,) else np.ones(size)


def sigma_min(curve: AllanCurve | _Curve, weights: ArrayLike | None = None) -> dict[str, Any]:
    """The lowest point of the curve among points with EDF ≥ :data:`EDF_MIN`.

    ``weights`` (the robust fit's point weights) leave out points the fit set
    aside (weight < 0.5: a notch is not a bias stability). Returns
    ``{"value", "tau_s", "ci", "edf", "index"}`` (value in the unit of the
    curve). Falls back to all points when none qualifies (and says so).
    """
    c = curve if isinstance(curve, _Curve) else _curve(curve)
    ok = c.edf >= EDF_MIN
    if weights is not None:
        ok &= np.asarray(weights, dtype=np.float64) >= 0.5
    note = None
    if not np.any(ok):
        ok = np.ones(c.dev.size, dtype=bool)
        note = f"no kept point has EDF >= {EDF_MIN:g}; the minimum is taken over all points"
    idx = np.flatnonzero(ok)
    i = int(idx[np.argmin(c.dev[ok])])
    out: dict[str, Any] = {
        "value": float(c.dev[i]),
        "tau_s": float(c.tau[i]),
        "ci": [float(c.lo[i]), float(c.hi[i])],
        "edf": float(c.edf[i]),
        "index": i,
        "at_edge": bool(i == idx[0] or i == idx[-1]),
    }
    if note:
        out["note"] = note
    return out


def fit_slopes(
    curve: AllanCurve, *, fit: NoiseTerms | None = None, tolerance: float = SLOPE_TOLERANCE
) -> NoiseTerms:
    """IEEE 952 read-off of Q, N, B, K and R, each where it lives.

    The home of a term is where ``fit`` (computed when not given) gives it at
    least half of the variance, the EDF is at least :data:`EDF_MIN` and the
    robust fit kept the point (weight ≥ 0.5: a notch, a bump or a first
    sample shaped by the sensor's own filter is no place to read). Inside
    it the tangent line of the term's slope touches the curve at the point
    minimising ``σ²/f_term``; the term is ``σ/√f_term`` there (for N on an Allan
    curve: ``σ(τ)·√τ``, the line read at τ = 1 s). The CI of that point scales
    the value. B is σ_min over √f_B at σ_min's τ (0.664 for Allan). A term with
    no home is ``nan`` with status ``upper_bound`` and its curve bound in
    ``info``.
    """
    c = _curve(curve)
    if fit is None:
        fit = fit_terms(curve)
    shares = _full_shares(c, fit)
    slopes = local_slopes(c.tau, c.dev)
    weights = _fit_weights(fit, c.tau.size)
    # points the robust fit set aside (a notch, a bump, a filtered first sample) are no home
    adequate = (c.edf >= EDF_MIN) & (weights >= 0.5)
    kw = {"rate_hz": c.rate_hz, "n_samples": c.n_samples}
    values: dict[str, float] = {}
    ci: dict[str, tuple[float, float]] = {}
    tau_used: dict[str, float] = {}
    status: dict[str, str] = {}
    info: dict[str, dict[str, Any]] = {}
    notes: list[str] = []
    smin = sigma_min(c, weights)
    for j, term in enumerate(TERMS):
        f = c.basis[:, j]
        if not np.any(f > 0) or not theory.observable(term, c.estimator):
            values[term] = math.nan
            status[term] = "not_observed"
            info[term] = {"reason": f"the {c.estimator} estimator is blind to {term}"}
            continue
        if term == "B":
            i = int(smin["index"])
            home_ok = shares[i, j] >= SHARE_MIN
        else:
            home = np.flatnonzero(adequate & (shares[:, j] >= SHARE_MIN) & (f > 0))
            if home.size == 0:
                ub, tau_ub = curve_upper_bound(c, term)
                values[term] = math.nan
                status[term] = "upper_bound"
                info[term] = {"upper_bound": ub, "upper_bound_tau_s": tau_ub}
                notes.append(
                    f"{term}: dominates nowhere on the curve with EDF >= {EDF_MIN:g}; "
                    f"not read (upper bound {ub:.4g} from the curve at tau = {tau_ub:.4g} s)"
                )
                continue
            i = int(home[np.argmin(c.avar[home] / f[home])])
            home_ok = True
        scale = 1.0 / math.sqrt(float(f[i]))
        values[term] = float(c.dev[i]) * scale
        ci[term] = (float(c.lo[i]) * scale, float(c.hi[i]) * scale)
        tau_used[term] = float(c.tau[i])
        exp_slope = expected_slope(term, c.estimator, float(c.tau[i]), **kw)
        entry: dict[str, Any] = {
            "local_slope": float(slopes[i]),
            "expected_slope": exp_slope,
            "share": float(shares[i, j]),
            "edf": float(c.edf[i]),
        }
        warnings: list[str] = []
        if math.isfinite(exp_slope) and abs(slopes[i] - exp_slope) > tolerance:
            warnings.append(
                f"local slope {slopes[i]:+.2f} at tau = {c.tau[i]:.4g} s, expected "
                f"{exp_slope:+.2f}: other terms contribute there, the value is an upper estimate"
            )
        if term == "B":
            entry["sigma_min"] = smin["value"]
            entry["b_factor"] = math.sqrt(float(f[i]))
            if not home_ok:
                warnings.append(
                    f"the minimum (tau = {c.tau[i]:.4g} s) is not a flicker floor (B carries "
                    f"{shares[i, j]:.0%} of the variance there): sigma_min/{math.sqrt(f[i]):.3f}"
                    " is only an upper bound of B"
                )
            if smin["at_edge"]:
                warnings.append(
                    f"the lowest point with EDF >= {EDF_MIN:g} is at the end of the curve "
                    f"(tau = {c.tau[i]:.4g} s): the floor may lie beyond it"
                )
        resolved = home_ok and fit.status.get(term) == "resolved"
        if home_ok and not resolved:
            warnings.append(
                "the fit does not resolve this term (too uncertain): the read value is not used"
            )
        status[term] = "resolved" if resolved else "upper_bound"
        if warnings:
            entry["warnings"] = warnings
            notes.extend(f"{term}: {w}" for w in warnings)
        info[term] = entry
    return NoiseTerms(
        method="slope",
        ci=ci,
        tau_used=tau_used,
        notes=notes,
        status=status,
        info=info,
        **_curve_fields(c),
        **_term_fields(values),
    )


# --------------------------------------------------------------------------
# the terms used downstream
# --------------------------------------------------------------------------
@dataclass(frozen=True)
class SelectedTerm:
    """One term as used for bounds and imu.yaml.

    ``value`` in SI (``None`` only when ``status`` is ``not_observed``);
    ``source`` says where it came from: ``"fit"``, ``"slope"`` or
    ``"curve_ci"`` (an upper bound from the curve's intervals).
    """

    value: float | None
    status: str
    source: str
    ci: tuple[float, float] | None = None
    tau_s: float | None = None
    note: str = ""


@dataclass(frozen=True)
class Selection:
    """The selected Q, N, B, K, R and σ_min of one channel (see :func:`select_terms`).

    What :func:`imubounds.noise_terms` returns. ``terms`` maps each of Q, N, B, K,
    R to a :class:`SelectedTerm` (SI value, status, source, CI); ``sigma_min`` is
    the lowest adequate point of the curve (``value`` in the signal's unit,
    ``tau_s``, ``ci``, ``edf``). ``kind`` (``"gyro"`` or ``"accel"``) gives the units
    of :meth:`to_dict` and :meth:`to_frame`; ``fit`` and ``slope`` are the two
    estimates the selection chose from and ``curve`` the Allan curve they come from
    (set by :func:`select_terms`; used by :meth:`plot`).
    """

    terms: dict[str, SelectedTerm]
    sigma_min: dict[str, Any]
    estimator: str
    notes: list[str] = field(default_factory=list)
    kind: SensorKind | None = None
    misfit: list[dict[str, Any]] = field(default_factory=list)
    fit: NoiseTerms | None = field(default=None, compare=False, repr=False)
    slope: NoiseTerms | None = field(default=None, compare=False, repr=False)
    curve: AllanCurve | None = field(default=None, compare=False, repr=False)

    def __repr__(self) -> str:
        from imubounds.units import SI_UNITS

        parts = []
        for t in TERMS:
            s = self.terms[t]
            if s.value is None:
                parts.append(f"{t}=n/a")
                continue
            unit = f" {SI_UNITS[self.kind][t]}" if self.kind is not None else ""
            mark = "<=" if s.status == "upper_bound" else ""
            parts.append(f"{t}={mark}{s.value:.3g}{unit}")
        return f"Selection(kind={self.kind!r}, estimator={self.estimator!r}, {', '.join(parts)})"

    def to_dict(self) -> dict[str, Any]:
        """The ``noise.selected`` block of noise.json as plain JSON types (nan -> None).

        Per term ``{"value" (SI), "unit", "status", "from", "ci", "ieee", "datasheet"}``
        and ``sigma_min``.
        """
        from imubounds.io.outputs import to_jsonable

        out: dict[str, Any] = to_jsonable(self.to_json(_known_kind(self.kind)))
        return out

    def to_frame(self) -> Any:
        """One row per term: ``term``, ``value`` (SI), ``unit``, ``status``, ``source``,
        ``ci_lower``, ``ci_upper``, ``tau_s``, ``ieee_value``, ``ieee_unit``,
        ``datasheet_value``, ``datasheet_unit`` (a :class:`pandas.DataFrame`)."""
        return _terms_frame(self.to_dict(), source="from")

    def plot(self, ax: Any = None) -> Any:
        """The curve with the selected term lines (dotted where only an upper bound is
        known), the fitted sum and σ_min; gyro in deg/h, accelerometer in m/s².
        Returns the :class:`matplotlib.figure.Figure` (a new one unless ``ax`` is given)."""
        if self.curve is None or self.fit is None or self.slope is None:
            raise OptionError("these terms carry no curve to plot (made without select_terms)")
        _known_kind(self.kind)
        from imubounds.report.static_plots import plot_terms

        return plot_terms(self, ax=ax)

    def value(self, term: str) -> float:
        """SI value used downstream (0 only for a term the estimator cannot see)."""
        v = self.terms[term].value
        return 0.0 if v is None else float(v)

    def status(self, term: str) -> str:
        return self.terms[term].status

    def to_json(self, kind: SensorKind) -> dict[str, Any]:
        """The ``noise.selected`` block of noise.json."""
        from imubounds.units import si_unit_of_signal, signal_to_datasheet

        out: dict[str, Any] = {}
        for t in TERMS:
            s = self.terms[t]
            e = term_entry(kind, t, s.value, s.ci)
            e["status"] = s.status
            e["from"] = s.source
            if s.tau_s is not None:
                e["tau_s"] = s.tau_s
            if s.note:
                e["note"] = s.note
            out[t] = e
        unit = si_unit_of_signal(kind)
        n_val = self.terms["N"].value
        if n_val is not None:
            dv, du = signal_to_datasheet(kind, n_val)
            out["N"]["adev_at_1s"] = {
                "value": n_val,
                "unit": unit,
                "datasheet": {"value": dv, "unit": du},
                "convention": "Allan deviation of the white part at tau = 1 s (equals N)",
            }
        sm = self.sigma_min
        dv, du = signal_to_datasheet(kind, sm["value"])
        b_fac = math.sqrt(float(theory.B_VAR_FACTOR[theory.FAMILY[self.estimator]]))
        out["sigma_min"] = {
            "value": sm["value"],
            "unit": unit,
            "tau_s": sm["tau_s"],
            "ci": sm["ci"],
            "edf": sm["edf"],
            "datasheet": {"value": dv, "unit": du},
            "estimator": self.estimator,
            "convention": (
                f"minimum of the measured {self.estimator} deviation over points with EDF >= "
                f"{EDF_MIN:g} (the 'bias stability' most datasheets quote); "
                f"B = sigma_min/{b_fac:.3f} is the IEEE 952 bias instability "
                "(sigma_min/0.664 on an Allan curve)"
            ),
        }
        out["misfit"] = [dict(r) for r in self.misfit]
        if self.notes:
            out["notes"] = list(self.notes)
        return out


#: Terms whose resolved value must stay inside the curve's intervals everywhere
#: (stationary.consistency). N is not among them: a sensor's anti-alias filter lowers
#: the first octaves below the white-noise line (the ADIS16405 by x0.8 at 0.01 s)
#: without making N wrong where it lives; the misfit range reports it.
GATED: tuple[str, ...] = ("B", "K")


def _disjoint(a: NoiseTerms, b: NoiseTerms, t: str, ub: float) -> bool:
    """Both estimates resolved and consistent (≤ ``ub``), with disjoint CIs."""
    ca, cb = a.ci.get(t), b.ci.get(t)
    if ca is None or cb is None or b.status.get(t) != "resolved":
        return False
    vb = b.value(t)
    if not (math.isfinite(vb) and 0 < vb <= ub * (1.0 + 1e-9)):
        return False
    return bool(ca[1] < cb[0] or cb[1] < ca[0])


def _ci_text(est: NoiseTerms, t: str) -> str:
    ci = est.ci.get(t)
    return f"{ci[0]:.4g}-{ci[1]:.4g}" if ci is not None else "n/a"


def select_terms(
    curve: AllanCurve,
    fit: NoiseTerms,
    slope: NoiseTerms,
    prefer: str = "fit",
) -> Selection:
    """The terms used for bounds and imu.yaml, never 0 unless the estimator cannot see them.

    A term resolved by the preferred estimate (``"fit"`` or ``"slope"``) takes
    its value and CI; else one resolved by the other estimate; else the
    curve's upper bound (:func:`curve_upper_bound`), status ``upper_bound``,
    with a note that bounds built on it are conservative.
    """
    if prefer not in ("fit", "slope"):
        raise OptionError(f"terms_from must be 'fit' or 'slope', got {prefer!r}")
    c = _curve(curve)
    first, second = (fit, slope) if prefer == "fit" else (slope, fit)
    out: dict[str, SelectedTerm] = {}
    notes: list[str] = []
    misfit = misfit_ranges(c, {t: fit.value(t) for t in TERMS})
    notes.extend(describe_misfit(r) for r in misfit)
    for t in TERMS:
        if first.status.get(t) == "not_observed":
            out[t] = SelectedTerm(None, "not_observed", first.method, note=f"blind to {t}")
            continue
        chosen = None
        ub, tau_ub = curve_upper_bound(c, t)
        gate, tau_gate = consistent_bound(c, t)
        refused: list[str] = []
        for est in (first, second):
            v = est.value(t)
            if est.status.get(t) == "resolved" and math.isfinite(v) and v > 0:
                if t in GATED and v > gate * (1.0 + 1e-9):  # its line alone exceeds the curve
                    refused.append(f"{v:.4g} from the {est.method}")
                    continue
                chosen = est
                break
        if t == "B" and chosen is fit and misfit and _disjoint(fit, slope, t, gate):
            # the fit leaves the curve somewhere and its floor disagrees with the curve's
            # minimum: the decomposition there is not to be trusted, the read-off is
            chosen = slope
            notes.append(
                f"B: the fit's {fit.value(t):.4g} (CI {_ci_text(fit, t)}) disagrees with the "
                f"read-off {slope.value(t):.4g} (CI {_ci_text(slope, t)}) while the fitted sum "
                "leaves the curve: B from the read-off (sigma_min over its factor, an upper "
                "estimate consistent with the curve)"
            )
        why = (
            f"{t} = {' and '.join(refused)} exceeds what the curve allows ({gate:.4g}: its "
            f"{UPPER_BOUND_LEVEL:.0%} intervals at tau = {tau_gate:.4g} s); structure the five "
            "terms cannot follow was absorbed into it"
            if refused
            else ""
        )
        if why:
            notes.append(why)
        if chosen is not None:
            v = chosen.value(t)
            note = "" if chosen is first else f"{t} from the {chosen.method} estimate"
            if why:
                note = f"{note}; {why}" if note else why
            out[t] = SelectedTerm(
                v, "resolved", chosen.method, chosen.ci.get(t), chosen.tau_used.get(t), note
            )
            continue
        fv = fit.value(t)
        if refused:  # the bound the estimates broke
            ub, tau_ub = gate, tau_gate
        elif math.isfinite(fv) and fv > ub:
            ub = fv
        note = (
            f"{t} is not resolved by the curve; the upper bound {ub:.4g} (from the curve's "
            f"{UPPER_BOUND_LEVEL:.0%} intervals at tau = {tau_ub:.4g} s) is used, which is "
            "conservative"
        )
        out[t] = SelectedTerm(ub, "upper_bound", "curve_ci", (0.0, ub), tau_ub, note)
        if t in ("N", "B", "K"):
            notes.append(note)
    smin = sigma_min(c, _fit_weights(fit, c.tau.size))
    return Selection(
        terms=out,
        sigma_min=smin,
        estimator=c.estimator,
        notes=notes,
        misfit=misfit,
        fit=fit,
        slope=slope,
        curve=curve,
    )


def analyse_curve(
    curve: AllanCurve, *, prefer: str = "fit", confidence: float = 0.683, robust: bool = True
) -> tuple[NoiseTerms, NoiseTerms, Selection]:
    """Fit, read-off and selection of one curve: ``(fit, slope, selected)``."""
    fit = fit_terms(curve, confidence=confidence, robust=robust)
    slope = fit_slopes(curve, fit=fit)
    return fit, slope, select_terms(curve, fit, slope, prefer)


def selected_terms(noise_doc: Mapping[str, Any], channel: str) -> dict[str, Any]:
    """The terms used for bounds of one channel, from a loaded noise.json document.

    Returns ``noise_doc["channels"][channel]["noise"]["selected"]``: per term
    ``{"value" (SI or None), "unit", "status", "from", "ci", "ieee", "datasheet"}``
    and ``sigma_min``. :class:`~imubounds.errors.InputError` names what is
    missing (an older noise.json without ``selected``, an unknown channel).
    """
    if not isinstance(noise_doc, Mapping) or "channels" not in noise_doc:
        raise InputError("not a noise.json document from 'imubounds static' (no 'channels')")
    chans = noise_doc["channels"]
    if channel not in chans:
        raise InputError(
            f"noise.json has no channel {channel!r}; available: {', '.join(map(str, chans))}"
        )
    sel = ((chans[channel] or {}).get("noise") or {}).get("selected")
    if not isinstance(sel, Mapping):
        raise InputError(
            f"noise.json channel {channel} has no noise.selected block; re-run 'imubounds static'"
            " with this version"
        )
    for t in TERMS:
        if t not in sel or "status" not in sel[t]:
            raise InputError(f"noise.json channel {channel}: noise.selected.{t} is incomplete")
    return dict(sel)
