"""Do the five terms agree with the curve they come from?

Structure the five-term model cannot follow — a bump of a Gauss–Markov process
between its correlation time and ten times it, a periodic term — is absorbed by
the nearest terms: a bump at 100–1000 s raises the fitted flicker floor B above
what the curve allows, and the fitted sum then runs above the data where the bump
is not. Two checks catch this (used by :func:`imubounds.stationary.terms.select_terms`):

* :func:`misfit_ranges` — the τ ranges where the fitted sum lies outside the
  curve's per-point intervals (99 %, from each point's EDF, widened by
  :data:`MISFIT_TOLERANCE`) at two or more
  consecutive points with EDF ≥ :data:`~imubounds.stationary.term_curve.EDF_MIN`,
  with the side (model above or below the curve), the worst ratio and the terms
  that carry the model there;
* a term (B and K: :data:`~imubounds.stationary.terms.GATED`) is *consistent*
  when its own line stays inside the curve's upper intervals everywhere:
  ``value ≤ consistent_bound`` (for B on an Allan curve,
  ``B ≤ σ_hi(τ_min)/0.664``: the flicker floor alone cannot exceed the curve at
  its minimum). A resolved term above it is not used: the other estimate takes
  its place when it is consistent, else the curve's bound, as an upper bound.

Units: τ in s; values in the curve's SI units.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy import special

from imubounds.stationary.term_curve import (
    EDF_MIN,
    TERMS,
    UPPER_BOUND_LEVEL,
    AllanCurve,
    _Curve,
    _curve,
    _upper_points,
)

#: Consecutive points outside their intervals that make a misfit range (one point
#: outside its 99 % interval happens by chance on a 20-point curve one time in five).
MISFIT_MIN_POINTS = 2
#: Relative widening of the intervals before a point counts as misfit: a departure of
#: a few per cent (a simulator's or a sensor filter's detail at the shortest τ, where
#: the EDF is huge) is no structure a filter needs to know about.
MISFIT_TOLERANCE = 0.05


def capped(curve: AllanCurve | _Curve) -> _Curve:
    """The curve with each point's EDF capped at 1.5·n/m, about that of white rate
    noise on the overlapping curve (n samples, cluster size m): a long-τ point whose
    noise was identified as white phase (α = 1, 2) gets an EDF tens of times too large
    from a handful of clusters, and an interval too narrow to judge a model by."""
    c = curve if isinstance(curve, _Curve) else _curve(curve)
    if not c.n_samples or not c.rate_hz:
        return c
    m = np.maximum(np.rint(c.tau * c.rate_hz), 1.0)
    return dataclasses.replace(c, edf=np.minimum(c.edf, 1.5 * c.n_samples / m))


def consistent_bound(curve: AllanCurve | _Curve, term: str) -> tuple[float, float]:
    """The largest value of ``term`` whose line alone stays inside the curve's upper
    intervals (99 %, EDF capped by :func:`capped`) at every point with EDF ≥ EDF_MIN,
    and the τ (s) that sets it; ``(inf, nan)`` when no point can judge it."""
    c = capped(curve)
    j = TERMS.index(term)
    f = c.basis[:, j]
    ok = (f > 0) & (c.edf >= EDF_MIN)
    if not np.any(ok):
        return math.inf, math.nan
    cand = _upper_points(c)[ok] / np.sqrt(f[ok])
    i = int(np.argmin(cand))
    return float(cand[i]), float(c.tau[ok][i])


def _intervals(c: _Curve, level: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Per-point lower and upper ends of σ at ``level`` (two-sided), from each EDF."""
    p = 1.0 - level
    edf = np.maximum(c.edf, 0.5)
    lo = c.dev * np.sqrt(edf / special.chdtri(edf, p / 2.0))
    hi = c.dev * np.sqrt(edf / special.chdtri(edf, 1.0 - p / 2.0))
    return np.asarray(lo, dtype=np.float64), np.asarray(hi, dtype=np.float64)


def model_dev(curve: AllanCurve | _Curve, values: Mapping[str, float]) -> NDArray[np.float64]:
    """The deviation of the five-term model with ``values`` (SI) at the curve's τ,
    with the factors of the curve's own estimator."""
    c = curve if isinstance(curve, _Curve) else _curve(curve)
    v2 = np.array([float(values.get(t, 0.0) or 0.0) ** 2 for t in TERMS])
    v2 = np.where(np.isfinite(v2), v2, 0.0)
    return np.asarray(np.sqrt(c.basis @ v2), dtype=np.float64)


def misfit_ranges(
    curve: AllanCurve | _Curve,
    values: Mapping[str, float],
    level: float = UPPER_BOUND_LEVEL,
) -> list[dict[str, Any]]:
    """τ ranges where the five-term model with ``values`` leaves the curve's intervals.

    Each range: ``tau_range_s`` [first, last point], ``side`` (``"model above the
    curve"`` or ``"model below the curve"``), ``worst_ratio`` (model/measured at the
    worst point), ``points`` and ``terms`` (those carrying at least a quarter of the
    model variance somewhere in the range). Only points with EDF ≥ EDF_MIN count;
    a range needs :data:`MISFIT_MIN_POINTS` consecutive points on the same side.
    """
    c = capped(curve)
    model = model_dev(c, values)
    lo, hi = _intervals(c, level)
    ok = (c.edf >= EDF_MIN) & (c.dev > 0) & (model > 0)
    side = np.zeros(c.tau.size, dtype=np.int64)
    side[ok & (model > hi * (1.0 + MISFIT_TOLERANCE))] = 1
    side[ok & (model < lo / (1.0 + MISFIT_TOLERANCE))] = -1
    v2 = np.array([float(values.get(t, 0.0) or 0.0) ** 2 for t in TERMS])
    v2 = np.where(np.isfinite(v2), v2, 0.0)
    parts = c.basis * v2
    total = np.maximum(parts.sum(axis=1), 1e-300)
    out: list[dict[str, Any]] = []
    k = 0
    while k < side.size:
        if side[k] == 0:
            k += 1
            continue
        end = k
        while end + 1 < side.size and side[end + 1] == side[k]:
            end += 1
        if end - k + 1 >= MISFIT_MIN_POINTS:
            idx = np.arange(k, end + 1)
            ratio = model[idx] / c.dev[idx]
            worst = int(idx[np.argmax(np.abs(np.log(ratio)))])
            share = parts[idx] / total[idx, None]
            out.append(
                {
                    "tau_range_s": [float(c.tau[k]), float(c.tau[end])],
                    "side": "model above the curve" if side[k] > 0 else "model below the curve",
                    "worst_ratio": float(model[worst] / c.dev[worst]),
                    "worst_tau_s": float(c.tau[worst]),
                    "points": int(end - k + 1),
                    "terms": [t for j, t in enumerate(TERMS) if np.any(share[:, j] >= 0.25)],
                    "level": level,
                }
            )
        k = end + 1
    return out


def describe_misfit(r: Mapping[str, Any]) -> str:
    """One line for a misfit range (console and notes)."""
    a, b = r["tau_range_s"]
    return (
        f"the five-term model leaves the curve's {r['level']:.0%} intervals from tau = {a:.3g}"
        f" to {b:.3g} s ({r['side']}, x{r['worst_ratio']:.3g} at {r['worst_tau_s']:.3g} s;"
        f" terms there: {', '.join(r['terms']) or 'none'}): structure the five terms cannot"
        " follow (a Gauss-Markov bump, a periodic term); the terms there are upper bounds"
        " at best"
    )
