"""Is the log stationary? Time-resolved Allan deviation and warm-up detection.

* :func:`sliding_adev` — the Allan deviation at four τ (octaves from one sample to
  a tenth of a window) in consecutive windows of the log, each with its CI and EDF.
* The **stationarity test** of a channel compares, at each of those τ, the
  windows' ln σ² (each spreads as ψ₁(EDF/2) for a chi-squared estimate): under
  stationarity ``Σ (ln σ²_i − mean)²/ψ₁(EDF_i/2)`` is χ² with k − 1 degrees of
  freedom; the smallest p-value over the τ, times their number (Bonferroni), is
  the channel's p-value, and below :data:`P_NON_STATIONARY` the channel is flagged
  (each spread widened by :data:`STATIONARITY_TOLERANCE`: changes of σ² below 10 %
  are not flagged, however significant).
* **Warm-up**: the bias of a sensor just powered on settles, roughly as
  ``c + A·exp(−t/T)``. Block means of the signal are fitted by that curve (T on a
  grid, c and A linear); a warm-up is flagged when the settling is large against the
  sensor's own wander at that time scale — ``|A| ≥`` :data:`WARMUP_SIGMA` × the
  Allan deviation at τ = T of the log after the warm-up — and ends in the first half
  of the log. It starts at the first sample and ends when the transient has fallen
  to :data:`WARMUP_FRACTION` of its amplitude, ``T·ln(1/0.05)`` ≈ 3T later.

Units: time in s from the first sample; deviations in the signal's unit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy import special

from imubounds.io.log import ImuLog
from imubounds.stationary._allan_kernels import window_sums
from imubounds.stationary.allan import allan, estimator_edf

#: Windows of the time-resolved Allan deviation.
WINDOWS = 8
#: τ per window of the time-resolved Allan deviation.
SLIDING_TAUS = 4
#: Channel flagged non-stationary below this (Bonferroni-corrected) p-value.
P_NON_STATIONARY = 1e-3
#: Relative change of σ² between windows below which no change is flagged (added in
#: quadrature to each window's ln σ² spread): with 10⁴ degrees of freedom per window
#: a 1 % change of the white noise is significant, and of no use to a filter.
STATIONARITY_TOLERANCE = 0.1
#: A warm-up is flagged when its amplitude is at least this many Allan deviations
#: (at τ = its time constant) of the settled log.
WARMUP_SIGMA = 5.0
#: The warm-up ends when the transient has fallen to this fraction of its amplitude.
WARMUP_FRACTION = 0.05
#: Block means used for the warm-up fit.
WARMUP_BLOCKS = 2000


@dataclass(frozen=True)
class Warmup:
    """A detected warm-up: start and end (s from the first sample), time constant T
    (s), amplitude A (signal unit), and the wander it was compared with."""

    start_s: float
    end_s: float
    time_constant_s: float
    amplitude: float
    settled_adev: float
    ratio: float

    def to_dict(self) -> dict[str, Any]:
        return {
            "start_s": self.start_s,
            "end_s": self.end_s,
            "time_constant_s": self.time_constant_s,
            "amplitude": self.amplitude,
            "settled_adev_at_T": self.settled_adev,
            "amplitude_over_adev": self.ratio,
            "model": "bias = c + A*exp(-t/T); end when the transient is 5 % of A (t = 3.0*T)",
        }


@dataclass
class Stationarity:
    """Time-resolved Allan deviation, stationarity test and warm-up of one channel."""

    window_s: float
    window_start_s: NDArray[np.float64]
    tau_s: NDArray[np.float64]
    adev: NDArray[np.float64]  # (windows, tau)
    ci_lower: NDArray[np.float64]
    ci_upper: NDArray[np.float64]
    p_value: float
    stationary: bool
    warmup: Warmup | None
    block_t: NDArray[np.float64] = field(repr=False, default_factory=lambda: np.zeros(0))
    block_mean: NDArray[np.float64] = field(repr=False, default_factory=lambda: np.zeros(0))

    def to_dict(self) -> dict[str, Any]:
        return {
            "window_s": self.window_s,
            "window_start_s": [float(v) for v in self.window_start_s],
            "tau_s": [float(v) for v in self.tau_s],
            "adev": [[float(v) for v in row] for row in self.adev],
            "ci_lower": [[float(v) for v in row] for row in self.ci_lower],
            "ci_upper": [[float(v) for v in row] for row in self.ci_upper],
            "p_value": self.p_value,
            "stationary": self.stationary,
            "test": (
                "chi-squared homogeneity of the windows' ln(avar) at each tau (spread "
                "psi1(edf/2)), Bonferroni over tau; non-stationary below "
                f"p = {P_NON_STATIONARY:g}"
            ),
            "warmup": self.warmup.to_dict() if self.warmup is not None else None,
        }

    def messages(self, unit: str = "", cut: bool = False) -> list[str]:
        """Warnings for the user (``unit`` of the signal; ``cut``: the warm-up was cut)."""
        out = []
        if self.warmup is not None:
            w = self.warmup
            out.append(
                f"warm-up: the bias settles from t = {w.start_s:.4g} s to {w.end_s:.4g} s "
                f"(time constant {w.time_constant_s:.3g} s, amplitude {w.amplitude:.3g} {unit}, "
                f"{w.ratio:.3g}x the settled Allan deviation there); "
                + ("cut before the analysis" if cut else "cut it with --cut-warmup")
            )
        if not self.stationary:
            out.append(
                f"not stationary: the Allan deviation changes between the {self.adev.shape[0]}"
                f" windows of {self.window_s:.4g} s beyond its intervals (p = {self.p_value:.2g})"
            )
        return out


def _homogeneity_p(avar: NDArray[np.float64], edf: NDArray[np.float64]) -> float:
    ok = (avar > 0) & np.isfinite(avar) & (edf > 0)
    if np.count_nonzero(ok) < 2:
        return 1.0
    lv = np.log(avar[ok])
    var = special.polygamma(1, edf[ok] / 2.0) + STATIONARITY_TOLERANCE**2
    w = 1.0 / var
    mean = float(np.sum(w * lv) / np.sum(w))
    stat = float(np.sum(w * (lv - mean) ** 2))
    return float(special.chdtrc(np.count_nonzero(ok) - 1, stat))


def sliding_adev(
    y: NDArray[np.float64], rate_hz: float, windows: int = WINDOWS, confidence: float = 0.683
) -> tuple[float, NDArray[np.float64], NDArray[np.float64], dict[str, NDArray[np.float64]]]:
    """Overlapping Allan deviation of ``windows`` consecutive windows at
    :data:`SLIDING_TAUS` octaves spread evenly from one sample to a tenth of a window.

    From one cumulative sum of the whole channel: the window's second differences of
    the phase are those of the whole log inside it (each τ is a pass over the log,
    :func:`~imubounds.stationary._allan_kernels.window_sums`);
    the noise type of each τ (for the EDF, Greenhall) is identified on the first
    window (:func:`~imubounds.stationary.allan.allan`). Returns (window length s,
    window starts s, τ s, {"dev", "edf", "ci_lower", "ci_upper"} arrays (window, τ)).
    """
    n = y.size // windows
    top = int(math.log2(max(n // 10, 1)))
    octaves = sorted({int(round(k * top / (SLIDING_TAUS - 1))) for k in range(SLIDING_TAUS)})
    ms = [2**k for k in octaves]
    alphas = allan(y[:n], rate_hz, [m / rate_hz for m in ms]).alpha
    x = np.concatenate(([0.0], np.cumsum(y - float(np.mean(y)))))
    dev = np.empty((windows, len(ms)))
    edf = np.empty_like(dev)
    for j, m in enumerate(ms):
        c0, c1 = window_sums(x, m, n, windows)  # np.cumsum's values at the window ends
        terms = n - 2 * m + 1
        for k in range(windows):
            dev[k, j] = math.sqrt((float(c1[k]) - float(c0[k])) / (2.0 * terms))
            edf[k, j] = estimator_edf("overlapping", int(alphas[j]), m, n)
    p = 1.0 - confidence
    lo = dev * np.sqrt(edf / special.chdtri(edf, p / 2.0))
    hi = dev * np.sqrt(edf / special.chdtri(edf, 1.0 - p / 2.0))
    starts = np.arange(windows) * n / rate_hz
    tau = np.asarray(ms, dtype=np.float64) / rate_hz
    return n / rate_hz, starts, tau, {"dev": dev, "edf": edf, "ci_lower": lo, "ci_upper": hi}


def _fit_warmup(
    t: NDArray[np.float64], b: NDArray[np.float64], duration: float
) -> tuple[float, float, float, float]:
    """Least squares of c + A·exp(−t/T) over a log grid of T: (T, A, c, cost)."""
    from scipy.optimize import minimize_scalar

    def solve(tc: float) -> tuple[float, float, float]:
        X = np.column_stack((np.ones_like(t), np.exp(-t / tc)))
        coef, *_ = np.linalg.lstsq(X, b, rcond=None)
        return float(coef[1]), float(coef[0]), float(np.sum((X @ coef - b) ** 2))

    grid = np.geomspace(max(t[1] - t[0], 1.0) * 3, duration / 6.0, 40)
    costs = [solve(float(tc))[2] for tc in grid]
    k = int(np.argmin(costs))
    if costs[k] >= float(np.sum((b - b.mean()) ** 2)):
        return math.nan, 0.0, float(np.mean(b)), costs[k]
    lo, hi = math.log(grid[max(k - 1, 0)]), math.log(grid[min(k + 1, grid.size - 1)])
    lt = math.log(grid[k])
    if hi > lo:
        lt = float(minimize_scalar(lambda v: solve(math.exp(v))[2], bounds=(lo, hi),
                                   method="bounded").x)  # fmt: skip
    amp, c, cost = solve(math.exp(lt))
    return math.exp(lt), amp, c, cost


def detect_warmup(y: NDArray[np.float64], rate_hz: float) -> tuple[Warmup | None, Any, Any]:
    """The warm-up of one channel (None when not flagged), and the block means used."""
    n = y.size
    size = max(1, n // WARMUP_BLOCKS)
    nb = n // size
    b = np.asarray(y[: nb * size].reshape(nb, size).mean(axis=1), dtype=np.float64)
    t = np.asarray((np.arange(nb) + 0.5) * size / rate_hz, dtype=np.float64)
    duration = n / rate_hz
    if nb < 20:
        return None, t, b
    tc, amp, _, _ = _fit_warmup(t, b, duration)
    if not math.isfinite(tc):
        return None, t, b
    end = tc * math.log(1.0 / WARMUP_FRACTION)
    if end > duration / 2.0:
        return None, t, b
    settled = y[int(end * rate_hz) :]
    m = max(1, int(round(tc * rate_hz)))
    if settled.size < 4 * m:
        return None, t, b
    adev = float(allan(settled, rate_hz, [m / rate_hz]).dev[0])
    ratio = abs(amp) / adev if adev > 0 else math.inf
    if ratio < WARMUP_SIGMA:
        return None, t, b
    return Warmup(0.0, end, tc, amp, adev, ratio), t, b


def stationarity(y: Any, rate_hz: float, windows: int = WINDOWS) -> Stationarity:
    """Time-resolved Allan deviation, stationarity test and warm-up of one channel."""
    arr = np.asarray(y, dtype=np.float64)
    win, starts, tau, cur = sliding_adev(arr, rate_hz, windows)
    adev, edf = cur["dev"], cur["edf"]
    p_each = [_homogeneity_p(adev[:, j] ** 2, edf[:, j]) for j in range(tau.size)]
    p = min(1.0, min(p_each) * len(p_each)) if p_each else 1.0
    warm, bt, bm = detect_warmup(arr, rate_hz)
    return Stationarity(
        window_s=win,
        window_start_s=starts,
        tau_s=tau,
        adev=adev,
        ci_lower=cur["ci_lower"],
        ci_upper=cur["ci_upper"],
        p_value=p,
        stationary=p >= P_NON_STATIONARY,
        warmup=warm,
        block_t=bt,
        block_mean=bm,
    )


def cut_warmup(log: ImuLog, results: dict[str, Stationarity]) -> tuple[ImuLog, float]:
    """The log without its warm-up (the latest end over the channels), and the cut (s)."""
    ends = [r.warmup.end_s for r in results.values() if r.warmup is not None]
    if not ends:
        return log, 0.0
    cut = max(ends)
    k = int(math.ceil(cut * log.rate_hz))
    chans = {name: np.asarray(v)[k:] for name, v in log.channels.items()}
    return replace(log, channels=chans, t=np.asarray(log.t)[k:]), k / log.rate_hz
