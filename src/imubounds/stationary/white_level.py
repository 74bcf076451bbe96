"""Is the white-noise level the same at every τ where N dominates? (docs/static-method.md,
section 1.2, white level across τ)

The fit and the IEEE 952 read-off estimate N differently: the read-off takes the
lowest N line that touches the curve where N dominates (the point minimising
``σ²/f_N``); the fit weighs every point. On a curve of the five terms both find the
same N. When they disagree beyond their intervals (a contaminated Xsens MTi-G gyro
log: the fit 27 % above the read-off), the white level itself changes with τ:
a filter in the sensor lowers the first octaves, and a correlated process with a
correlation time T inside N's range (a Gauss–Markov component) adds nothing below T
and a white-like ``2σ²T`` above it. The five terms cannot follow that, the read-off
finds the level of the shortest τ and the fit a compromise across the range.

:func:`white_level` makes it visible: at each point of N's home (the points the
read-off may use) the level the curve implies once the other fitted terms are taken
out, ``N(τ) = √((σ² − Σ_{t≠N} t²·f_t)/f_N)`` with the interval of σ, and whether
those levels agree within their intervals and :data:`WHITE_LEVEL_TOLERANCE`. When
they do not (or the fit and the read-off disagree by more than that), the message
says which to believe: noise at a time scale τ follows the level read at τ — the
lowest (the read-off) for the noise of single samples and short intervals, the one
at the longest τ of the range for a random walk over longer times — and by how much
the selected N (σ_c, the random-walk growth, imu.yaml) may be low there.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy import special

from imubounds.stationary.term_curve import EDF_MIN, AllanCurve, _curve
from imubounds.stationary.terms import (
    SHARE_MIN,
    TERMS,
    NoiseTerms,
    _fit_weights,
    _full_shares,
)

#: Levels (and the fit against the read-off) differing by more than this beyond
#: their intervals are reported.
WHITE_LEVEL_TOLERANCE = 0.10
#: Confidence of each point's interval in the test of a constant level (and of the
#: "up to x % below" of the message): 99 % per point, with the other terms' intervals
#: taken out at their ends. With the curve's own 68 % intervals and the other terms
#: fixed, one point of ~15 strayed often enough to warn on 10 of 108 clean simulated
#: 0.5-1 h logs whose N was right to 0.7 %.
TEST_CONFIDENCE = 0.99


@dataclass(frozen=True)
class WhiteLevel:
    """The white-noise level N implied by the curve at each τ of N's home (SI, the
    unit of N), with its interval, and the fit's and the read-off's N."""

    tau_s: NDArray[np.float64]
    level: NDArray[np.float64]
    ci_lower: NDArray[np.float64]
    ci_upper: NDArray[np.float64]
    fit: float
    fit_ci: tuple[float, float] | None
    read_off: float
    read_off_ci: tuple[float, float] | None
    read_off_tau_s: float | None
    selected: float
    test_lower: NDArray[np.float64] | None = None
    test_upper: NDArray[np.float64] | None = None

    @property
    def _test(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        if self.test_lower is None or self.test_upper is None:
            return self.ci_lower, self.ci_upper
        return self.test_lower, self.test_upper

    @property
    def spread(self) -> float:
        """How far apart the levels are beyond their test intervals
        (:data:`TEST_CONFIDENCE`): max lower end over min upper end, minus 1 (≤ 0 when
        all intervals share a value)."""
        lo, hi = self._test
        up = hi[hi > 0]  # 0: the other terms fill the curve there
        if up.size == 0:
            return 0.0
        return float(np.max(lo) / np.min(up)) - 1.0

    @property
    def highest_lower(self) -> float:
        """The highest level the curve supports at :data:`TEST_CONFIDENCE` (the largest
        lower end of the test intervals)."""
        return float(np.max(self._test[0]))

    @property
    def estimates_gap(self) -> float:
        """The same for the fit's and the read-off's intervals (0 without both)."""
        if self.fit_ci is None or self.read_off_ci is None:
            return 0.0
        lo = max(self.fit_ci[0], self.read_off_ci[0])
        hi = min(self.fit_ci[1], self.read_off_ci[1])
        return lo / hi - 1.0 if hi > 0 else 0.0

    @property
    def constant(self) -> bool:
        """The levels agree, and so do the fit and the read-off (within their intervals
        and :data:`WHITE_LEVEL_TOLERANCE`)."""
        return self.spread <= WHITE_LEVEL_TOLERANCE and self.estimates_gap <= WHITE_LEVEL_TOLERANCE

    def _at(self, k: int) -> dict[str, float]:
        return {"value": float(self.level[k]), "tau_s": float(self.tau_s[k])}

    @property
    def low(self) -> dict[str, float]:
        return self._at(int(np.argmin(self.level)))

    @property
    def high(self) -> dict[str, float]:
        return self._at(int(np.argmax(self.level)))

    def to_dict(self) -> dict[str, Any]:
        return {
            "tau_s": [float(v) for v in self.tau_s],
            "level": [float(v) for v in self.level],
            "ci_lower": [float(v) for v in self.ci_lower],
            "ci_upper": [float(v) for v in self.ci_upper],
            "fit": self.fit,
            "read_off": self.read_off,
            "read_off_tau_s": self.read_off_tau_s,
            "selected": self.selected,
            "low": self.low,
            "high": self.high,
            "at_longest_tau": self._at(self.tau_s.size - 1),
            "test_lower": [float(v) for v in self._test[0]],
            "test_upper": [float(v) for v in self._test[1]],
            "test_confidence": TEST_CONFIDENCE,
            "spread": self.spread,
            "estimates_gap": self.estimates_gap,
            "tolerance": WHITE_LEVEL_TOLERANCE,
            "constant": self.constant,
            "method": "N(tau) = sqrt((avar - other fitted terms)/f_N) at each point where N "
            "carries >= half the variance (EDF >= 10, kept by the robust fit)",
            "use": self.advice(),
        }

    def advice(self) -> str:
        """Which N to believe, in one sentence."""
        if self.constant:
            return (
                "the white level is the same at every tau where N dominates: the fit and "
                "the read-off agree; use the selected N"
            )
        first, last = self._at(0), self._at(self.tau_s.size - 1)
        return (
            "believe the level at the time scale of use (noise.white_level): "
            f"{first['value']:.4g} at tau = {first['tau_s']:.3g} s for single samples and "
            f"short intervals, {last['value']:.4g} at tau = {last['tau_s']:.3g} s for a "
            "random walk over longer times"
        )

    def message(self, name: str, unit: str = "") -> str | None:
        """A warning for the user, or None when the level is constant."""
        if self.constant:
            return None
        lo, hi = self.low, self.high
        ro = (
            f"the read-off ({self.read_off:.4g} at tau = {self.read_off_tau_s:.3g} s)"
            if math.isfinite(self.read_off) and self.read_off_tau_s is not None
            else "the read-off (none)"
        )
        low_by = max(0.0, self.highest_lower / self.selected - 1.0) if self.selected > 0 else 0.0
        return (
            f"{name}: N from the fit ({self.fit:.4g} {unit}) and {ro} differ because the "
            f"white level changes with tau where N dominates ({lo['value']:.4g} to "
            f"{hi['value']:.4g} over tau = {self.tau_s[0]:.3g}-{self.tau_s[-1]:.3g} s: a "
            "filter or a correlated process the five terms cannot follow); "
            + self.advice()
            + (
                f"; the selected N {self.selected:.4g} (sigma_c, random-walk growth, imu.yaml)"
                f" is at least {low_by:.0%} below the highest level ({TEST_CONFIDENCE:.0%} "
                "per point)"
                if low_by > 0.005
                else ""
            )
        )


def white_level(
    curve: AllanCurve, fit: NoiseTerms, slope: NoiseTerms, selected: float | None = None
) -> WhiteLevel | None:
    """The white level across N's home (see the module docstring); None when N has no
    home with two points or the fit does not resolve it."""
    if fit.status.get("N") != "resolved" or not math.isfinite(fit.value("N")):
        return None
    c = _curve(curve)
    j = TERMS.index("N")
    f = c.basis[:, j]
    shares = _full_shares(c, fit)
    weights = _fit_weights(fit, c.tau.size)
    home = np.flatnonzero(
        (c.edf >= EDF_MIN) & (weights >= 0.5) & (shares[:, j] >= SHARE_MIN) & (f > 0)
    )
    if home.size < 2:
        return None
    vals = np.array([fit.value(t) if math.isfinite(fit.value(t)) else 0.0 for t in TERMS])
    other = (c.basis @ vals**2 - f * vals[j] ** 2)[home]
    fh = f[home]

    def level(v: NDArray[np.float64], oth: NDArray[np.float64] = other) -> NDArray[np.float64]:
        return np.asarray(np.sqrt(np.clip(v**2 - oth, 0.0, None) / fh), dtype=np.float64)

    ends = [fit.ci.get(t) or (vals[i], vals[i]) for i, t in enumerate(TERMS)]
    lo_t = np.array([0.0 if i == j else max(0.0, float(e[0])) for i, e in enumerate(ends)])
    hi_t = np.array([0.0 if i == j else float(e[1]) for i, e in enumerate(ends)])
    p = 1.0 - TEST_CONFIDENCE
    dev, edf = c.dev[home], np.maximum(c.edf[home], 1.0)
    t_lo = level(dev * np.sqrt(edf / special.chdtri(edf, p / 2.0)), (c.basis @ hi_t**2)[home])
    t_hi = level(dev * np.sqrt(edf / special.chdtri(edf, 1.0 - p / 2.0)),
                 (c.basis @ lo_t**2)[home])  # fmt: skip

    ro = slope.value("N")
    ro_ok = slope.status.get("N") == "resolved" and math.isfinite(ro)
    return WhiteLevel(
        tau_s=c.tau[home],
        level=level(c.dev[home]),
        ci_lower=level(c.lo[home]),
        ci_upper=level(c.hi[home]),
        fit=fit.value("N"),
        fit_ci=fit.ci.get("N"),
        read_off=ro if ro_ok else math.nan,
        read_off_ci=slope.ci.get("N") if ro_ok else None,
        read_off_tau_s=slope.tau_used.get("N") if ro_ok else None,
        selected=float(selected) if selected is not None else fit.value("N"),
        test_lower=t_lo,
        test_upper=t_hi,
    )
