"""How long to record: the CI width of N, B and K against the recording length.

The intervals of the fitted terms (:func:`~imubounds.stationary.terms.fit_terms`)
come from each point's equivalent degrees of freedom (EDF): ln σ² of a point
spreads as ψ₁(EDF/2). For a log of length T the expected curve is the fitted
five-term model at the octave τ grid the log allows, each point's EDF follows
from T (Greenhall's algorithm, :func:`~imubounds.stationary.allan.estimator_edf`)
for the noise type of the term that dominates the model there (Q: white phase,
N: white rate, B: flicker rate, K and R: random-walk rate), and the fit of that
expected curve gives the intervals a log of length T would get. The relative misfit
η of this log's fit (structure the five terms do not follow) is assumed to persist:
each EDF is lowered so that ψ₁(EDF/2) includes η², as the fit's own intervals do.

:func:`record_length` tabulates the predicted relative CI width
``(hi − lo)/value`` of N, B and K at :data:`HOURS` and, for a target width, the
length needed (log-log interpolation between the tabulated lengths; beyond the
last one, extrapolated with the slope of the last two). Units: hours, relative
widths (dimensionless).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray
from scipy import special

from imubounds.stationary import theory
from imubounds.stationary.allan import estimator_edf, max_cluster_size
from imubounds.stationary.term_curve import TERMS, AllanCurve

if TYPE_CHECKING:
    from imubounds.stationary.terms import NoiseTerms, Selection

#: Recording lengths (h) of the table.
HOURS: tuple[float, ...] = (0.5, 1.0, 2.0, 4.0, 8.0, 24.0)
#: Default target: a relative CI width of 20 % (about ±10 %).
TARGET_REL_WIDTH = 0.2
#: Power-law noise exponent α (S_y ~ f^α) of each term's rate noise.
ALPHA: dict[str, int] = {"Q": 2, "N": 0, "B": -1, "K": -2, "R": -2}
PREDICTED: tuple[str, ...] = ("N", "B", "K")
#: Shortest log (s) a plan is predicted from: shorter, its fit has no τ where B or K
#: shows, and the block says so instead of a length.
MIN_PLAN_S = 60.0


@dataclass(frozen=True)
class ExpectedCurve:
    """The curve a log of ``n_samples`` at ``rate_hz`` is expected to give (for the fit)."""

    tau: NDArray[np.float64]
    dev: NDArray[np.float64]
    ci_lower: NDArray[np.float64]
    ci_upper: NDArray[np.float64]
    edf: NDArray[np.float64]
    estimator: str
    rate_hz: float
    n_samples: int


def _edf_with_misfit(edf: NDArray[np.float64], eta: float) -> NDArray[np.float64]:
    """The EDF whose spread of ln σ², ψ₁(EDF/2), includes a relative misfit η:
    ψ₁(x) = ψ₁(EDF/2) + η², solved for x by Newton's method (ψ₁ is convex, falling)."""
    if eta <= 0:
        return edf
    # ψ₁(x) = ζ(2, x) and ψ₂(x) = −2 ζ(3, x): scipy's polygamma(n, x) is the product
    # (−1)^(n+1) n! ζ(n+1, x) with n! exactly 1 and 2, so the values are its own bit
    # for bit, without its wrapper (60 calls per curve, a third of their time)
    target = special.zeta(2.0, edf / 2.0) + eta**2
    x = 1.0 / target + 0.5  # ψ₁(x) ≈ 1/x + 1/(2x²)
    for _ in range(30):
        step = (special.zeta(2.0, x) - target) / (-2.0 * special.zeta(3.0, x))
        x = np.maximum(x - step, x / 10.0)
    return np.asarray(2.0 * x, dtype=np.float64)


def expected_curve(
    values: Mapping[str, float],
    estimator: str,
    rate_hz: float,
    n_samples: int,
    misfit: float = 0.0,
) -> ExpectedCurve:
    """The five-term model with ``values`` (SI) on the octave grid of a log of
    ``n_samples`` at ``rate_hz``, with each point's EDF for the dominant term's noise
    (lowered to include a relative ``misfit`` η, as the fit's intervals do)."""
    m_max = max_cluster_size(n_samples, estimator)
    ms = 2 ** np.arange(int(math.floor(math.log2(max(m_max, 1)))) + 1)
    tau = ms / rate_hz
    basis = theory.basis(tau, estimator, rate_hz=rate_hz, n_samples=n_samples)
    v2 = np.array([float(values.get(t, 0.0) or 0.0) ** 2 for t in TERMS])
    v2 = np.where(np.isfinite(v2), v2, 0.0)
    parts = basis * v2
    avar = parts.sum(axis=1)
    dominant = np.argmax(parts, axis=1)
    edf = np.array(
        [
            estimator_edf(estimator, ALPHA[TERMS[int(j)]], int(m), n_samples)
            for j, m in zip(dominant, ms, strict=True)
        ]
    )
    edf = _edf_with_misfit(edf, misfit)
    dev = np.sqrt(np.maximum(avar, 1e-300))
    return ExpectedCurve(tau, dev, dev, dev, edf, estimator, float(rate_hz), int(n_samples))


def predicted_widths(
    values: Mapping[str, float],
    estimator: str,
    rate_hz: float,
    hours: Sequence[float] = HOURS,
    confidence: float = 0.683,
    misfit: float = 0.0,
) -> dict[str, list[float | None]]:
    """Predicted relative CI width of N, B and K for each length in ``hours``
    (``None`` where the fit of the expected curve does not resolve the term)."""
    from imubounds.stationary.terms import fit_terms

    out: dict[str, list[float | None]] = {t: [] for t in PREDICTED}
    for h in hours:
        n = int(round(h * 3600.0 * rate_hz))
        curve = expected_curve(values, estimator, rate_hz, n, misfit)
        fit = fit_terms(curve, confidence=confidence, robust=False, iterations=3)
        for t in PREDICTED:
            ci = fit.ci.get(t)
            v = fit.value(t)
            ok = fit.status.get(t) == "resolved" and ci is not None and v > 0
            out[t].append(float((ci[1] - ci[0]) / v) if ok and ci is not None else None)
    return out


def hours_for_width(
    hours: Sequence[float], widths: Sequence[float | None], target: float
) -> float | None:
    """Shortest length (h) whose predicted width is at most ``target``: log-log
    interpolation, or extrapolation beyond the table (slope of its last two
    resolved lengths); ``None`` when fewer than two lengths resolve the term."""
    pts = [(h, w) for h, w in zip(hours, widths, strict=True) if w is not None and w > 0]
    if not pts:
        return None
    for k, (h, w) in enumerate(pts):
        if w <= target:
            if k == 0:  # already there at the shortest length: back along its slope
                return _interp(pts[0], pts[1], target) if len(pts) > 1 else float(h)
            return _interp(pts[k - 1], pts[k], target)
    if len(pts) < 2:
        return None
    return _interp(pts[-2], pts[-1], target)


def _interp(a: tuple[float, float], b: tuple[float, float], target: float) -> float:
    (h1, w1), (h2, w2) = a, b
    if h1 == h2 or w1 == w2:
        return float(h2)
    slope = math.log(w2 / w1) / math.log(h2 / h1)
    if slope >= -0.05:  # the width no longer shrinks (a misfit floor): never
        return math.inf if w2 > target else float(h1)
    return float(h1 * math.exp(math.log(target / w1) / slope))


def record_length(
    values: Mapping[str, float],
    estimator: str,
    rate_hz: float,
    *,
    recorded_hours: float,
    misfit: float = 0.0,
    target: float = TARGET_REL_WIDTH,
    confidence: float = 0.683,
    hours: Sequence[float] = HOURS,
) -> dict[str, Any]:
    """The ``record_length`` block of noise.json for one channel (see the module)."""
    hrs = sorted({*hours, round(recorded_hours, 6)})
    widths = predicted_widths(values, estimator, rate_hz, hrs, confidence, misfit)
    found = {t: hours_for_width(hrs, widths[t], target) for t in PREDICTED}
    need = {t: (None if h is None or math.isinf(h) else h) for t, h in found.items()}
    never = [t for t, h in found.items() if h is not None and math.isinf(h)]
    return {
        "hours": hrs,
        "recorded_hours": recorded_hours,
        "rel_ci_width": widths,
        "target_rel_width": target,
        "hours_needed": need,
        "never_reached": never,
        "confidence": confidence,
        "misfit_rel": misfit,
        "method": (
            "the fitted five-term model on the octave grid of each length, EDF per point "
            "(Greenhall) for the dominant term's noise, lowered to include this log's relative "
            "misfit, refitted"
        ),
    }


def channel_record_length(
    curve: AllanCurve, fit: NoiseTerms, sel: Selection, hours: float, confidence: float = 0.683
) -> dict[str, Any]:
    """The ``record_length`` block of one channel: N, B, K as selected (an upper bound
    where not resolved), Q and R as fitted, this log's misfit η assumed to persist.
    A log shorter than :data:`MIN_PLAN_S` gets no plan: ``predicted`` false and the
    reason (no length, never "0 min")."""
    if not hours * 3600.0 >= MIN_PLAN_S:
        return {
            "predicted": False,
            "reason": f"the log ({hours * 3600.0:.3g} s) is shorter than the "
            f"{MIN_PLAN_S:.0f} s a plan is predicted from",
            "recorded_hours": hours,
            "target_rel_width": TARGET_REL_WIDTH,
            "hours_needed": {t: None for t in PREDICTED},
            "never_reached": [],
            "term_status": {t: sel.status(t) for t in PREDICTED},
        }
    values = {t: fit.value(t) for t in ("Q", "R")}
    values.update({t: sel.value(t) for t in PREDICTED})
    block = record_length(
        values,
        str(getattr(curve, "estimator", "overlapping")),
        float(getattr(curve, "rate_hz", 0.0) or 0.0),
        recorded_hours=hours,
        misfit=float(fit.stats.get("misfit_rel", 0.0) or 0.0),
        confidence=confidence,
    )
    block["term_status"] = {t: sel.status(t) for t in PREDICTED}
    return block


def describe(name: str, block: Mapping[str, Any]) -> str:
    """One console line: the length each term needs for the target width."""
    target = float(block["target_rel_width"])
    head = f"{name}: " if name else ""
    if block.get("predicted") is False:
        return f"{head}recording length: not predicted ({block.get('reason', '')})"
    parts = []
    for t in PREDICTED:
        h = block["hours_needed"].get(t)
        if t in block.get("never_reached", []):
            parts.append(f"{t} never (the misfit keeps the width above the target)")
        elif h is None:
            parts.append(f"{t} not resolvable")
        else:
            parts.append(f"{t} {_hours_text(h)}")
    return (
        f"{head}recording length for a {target:.0%} CI width (predicted from the EDFs): "
        + ", ".join(parts)
        + f" (this log: {float(block['recorded_hours']):.3g} h)"
    )


def _hours_text(h: float) -> str:
    if h * 60 < 0.5:
        return "under 1 min"
    return f"{h * 60:.0f} min" if h < 1 else f"{h:.3g} h"
