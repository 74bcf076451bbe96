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
* **Warm-up and drift** (:mod:`imubounds.stationary.drift`): block means of the signal
  are tested against the log's own noise (Q, N, B, K fitted to its Allan curve; their
  covariance of block means, exact for white, flicker and random-walk noise) by
  generalized least squares. A **warm-up** ``c + A·exp(−t/T)`` is flagged when
  z = Â/SE(Â) ≥ :data:`WARMUP_Z`, its end ``T·ln(1/0.05)`` ≈ 3T lies in the first half
  of the log, and ``|A| ≥`` :data:`WARMUP_SIGMA` × the Allan deviation at τ = T of
  the log after it (a settling too small to matter is not flagged, however
  significant). T is given with its 68 % interval; ``--cut-warmup`` cuts each channel
  at the end its own interval allows (``T_hi·ln 20``). A **drift** (a ramp, or a
  settling slower than half the log: thermal) is flagged when the slope of
  ``c + s·t`` has z ≥ :data:`DRIFT_Z` (described as a settling when the best
  exponential ends in the second half and fits better); the channel is then *not
  stationary*, whatever the windows say: the R (rate ramp) of its terms, and part of
  its K, are this drift, not a noise. A slope below that, z ≥ :data:`TREND_NOTE_Z`,
  is named (:meth:`Stationarity.trend_message`) when the term fit resolves R or K:
  they may then describe the trend rather than a noise, which one log cannot tell.

Units: time in s from the first sample; deviations in the signal's unit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy import special

from imubounds.errors import InputError
from imubounds.io.log import ImuLog
from imubounds.stationary import drift
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
#: ... that is, this many time constants after the start (ln 20 ≈ 3.0).
WARMUP_END = math.log(1.0 / WARMUP_FRACTION)
#: z = Â/SE(Â) of the warm-up's exponential against the noise above which it is flagged
#: (with the two other tests: no flag on 600 clean simulated channels of 2 h at 100 Hz,
#: half with a Gauss–Markov component: benchmarks/bench_drift.py).
WARMUP_Z = 4.5
#: z of a drift's slope above which the channel is not stationary (largest on 300 clean
#: simulated channels of 2 h at 100 Hz: 4.2, and 4.0 on 300 with the Gauss–Markov
#: component; with the true noise model z is standard normal: tests/test_drift.py).
DRIFT_Z = 5.5
#: A trend below :data:`DRIFT_Z` but at least this z is named when the term fit resolves
#: R or K, which may then be the trend rather than a noise (on the same clean channels
#: z ≥ 3 on 2 %, never with R or K resolved; on 38 of 42 with a thermal settling of
#: 20·B, 16 of the 23 not called drifting with R or K resolved).
TREND_NOTE_Z = 3.0


@dataclass(frozen=True)
class Warmup:
    """A detected warm-up: start and end (s from the first sample), time constant T
    (s) with its 68 % interval, amplitude A (signal unit), its z against the noise, the
    wander it was compared with, and where ``--cut-warmup`` cuts (``T_hi·ln 20``)."""

    start_s: float
    end_s: float
    time_constant_s: float
    amplitude: float
    settled_adev: float
    ratio: float
    time_constant_ci_s: tuple[float, float] = (math.nan, math.nan)
    z: float = math.nan
    cut_s: float = math.nan

    @property
    def end_ci_s(self) -> tuple[float, float]:
        k = WARMUP_END
        return (self.time_constant_ci_s[0] * k, self.time_constant_ci_s[1] * k)

    def to_dict(self) -> dict[str, Any]:
        return {
            "start_s": self.start_s,
            "end_s": self.end_s,
            "end_ci_s": list(self.end_ci_s),
            "time_constant_s": self.time_constant_s,
            "time_constant_ci_s": list(self.time_constant_ci_s),
            "amplitude": self.amplitude,
            "z": self.z,
            "settled_adev_at_T": self.settled_adev,
            "amplitude_over_adev": self.ratio,
            "cut_s": self.cut_s,
            "model": "bias = c + A*exp(-t/T) by generalized least squares of block means "
            "against the log's noise (Q, N, B, K); end when the transient is 5 % of A "
            "(t = 3.0*T); T's interval 68 %; --cut-warmup cuts at the interval's upper end "
            "times 3.0",
        }


@dataclass(frozen=True)
class Drift:
    """A change of the bias over the log beyond its noise: ``kind`` "ramp" (the slope
    of a line) or "settling" (an exponential ending in the second half: thermal),
    the slope (signal unit per s), the change over the log, z, and T for a settling."""

    kind: str
    slope: float
    change: float
    z: float
    duration_s: float
    time_constant_s: float | None = None

    def to_dict(self) -> dict[str, Any]:
        return {
            "kind": self.kind,
            "slope_per_s": self.slope,
            "change_over_log": self.change,
            "z": self.z,
            "threshold_z": DRIFT_Z,
            "time_constant_s": self.time_constant_s,
            "model": (
                "bias = c + s*t" if self.kind == "ramp" else "bias = c + A*exp(-t/T), T long"
            )
            + " by generalized least squares of block means against the log's noise "
            "(Q, N, B, K)",
        }


@dataclass(frozen=True)
class Trend:
    """The slope of the block means against the noise, flagged or not: slope (signal
    unit per s), the change over the log (slope × duration) and z."""

    slope: float
    change: float
    z: float

    def to_dict(self) -> dict[str, Any]:
        return {"slope_per_s": self.slope, "change_over_log": self.change, "z": self.z}


@dataclass
class Stationarity:
    """Time-resolved Allan deviation, stationarity test, warm-up and drift of one
    channel. ``stationary`` is the windows' test passing and no drift."""

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
    drift: Drift | None = None
    noise: dict[str, float] | None = None
    trend: Trend | None = None

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
                f"p = {P_NON_STATIONARY:g}, or with a drift (z >= {DRIFT_Z:g})"
            ),
            "warmup": self.warmup.to_dict() if self.warmup is not None else None,
            "drift": self.drift.to_dict() if self.drift is not None else None,
            "trend": self.trend.to_dict() if self.trend is not None else None,
            "noise_model": dict(self.noise) if self.noise is not None else None,
        }

    def messages(self, unit: str = "", cut: bool = False) -> list[str]:
        """Warnings for the user (``unit`` of the signal; ``cut``: the warm-up was cut)."""
        out = []
        if self.warmup is not None:
            w = self.warmup
            lo, hi = w.time_constant_ci_s
            out.append(
                f"warm-up: the bias settles from t = {w.start_s:.4g} s to {w.end_s:.4g} s "
                f"(time constant {w.time_constant_s:.3g} s, 68 % interval {lo:.3g}-{hi:.3g} s;"
                f" amplitude {w.amplitude:.3g} {unit}, z = {w.z:.3g} against the noise, "
                f"{w.ratio:.3g}x the settled Allan deviation there); "
                + (
                    f"the first {w.cut_s:.4g} s of this channel were cut before the analysis"
                    if cut
                    else f"cut it with --cut-warmup (this channel from {w.cut_s:.4g} s)"
                )
            )
        if self.drift is not None:
            d = self.drift
            what = (
                "a ramp"
                if d.kind == "ramp"
                else f"a settling slower than half the log (T ~ {d.time_constant_s:.3g} s)"
            )
            out.append(
                f"not stationary: the bias drifts by {d.change:.3g} {unit} over the "
                f"{d.duration_s:.4g} s of the log ({what}, z = {d.z:.3g} against the noise): "
                "a thermal or other deterministic drift; the terms at long tau (R, and part "
                "of K) describe this drift, not a stationary noise"
            )
        if not self.windows_stationary:
            out.append(
                f"not stationary: the Allan deviation changes between the {self.adev.shape[0]}"
                f" windows of {self.window_s:.4g} s beyond its intervals (p = {self.p_value:.2g})"
            )
        return out

    def trend_message(self, resolved: list[str], unit: str = "") -> str | None:
        """The warning for a trend below a drift's z (:data:`TREND_NOTE_Z` ≤ z <
        :data:`DRIFT_Z`) when the term fit resolves ``resolved`` (R, K): those terms may
        describe the trend rather than a stationary noise. None otherwise."""
        tr = self.trend
        if self.drift is not None or tr is None or not resolved or abs(tr.z) < TREND_NOTE_Z:
            return None
        terms = " and ".join(resolved)
        return (
            f"the bias trends by {tr.change:.3g} {unit} over the log (z = {abs(tr.z):.3g} "
            f"against the noise: below the {DRIFT_Z:g} of a drift, so the channel is not "
            f"called non-stationary); the resolved {terms} may describe this trend (a "
            "thermal or other slow drift) rather than a stationary noise: this log cannot "
            "tell them apart (a longer log, or the temperature, can)"
        )

    @property
    def windows_stationary(self) -> bool:
        """The windows' test alone."""
        return self.p_value >= P_NON_STATIONARY


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


def _settled_adev(y: NDArray[np.float64], rate_hz: float, tc: float, end: float) -> float:
    """Allan deviation at τ = T (at most a third of what is left) after ``end``."""
    settled = y[int(end * rate_hz) :]
    m = min(max(1, int(round(tc * rate_hz))), settled.size // 3)
    if m < 1:
        return math.nan
    return float(allan(settled, rate_hz, [m / rate_hz]).dev[0])


def _usable(curve: Any, duration: float) -> bool:
    """An overlapping plain curve of octaves or denser, reaching a 16th of the log."""
    return (
        curve is not None
        and curve.estimator == "overlapping"
        and not getattr(curve, "robust", False)
        and np.size(curve.tau) >= 8
        and float(np.max(curve.tau)) >= duration / 16
    )


def _warmup(y: NDArray[np.float64], rate_hz: float, tr: Any) -> Warmup | None:
    """The transient as a warm-up when it passes the three tests (module docstring)."""
    if tr is None or abs(tr.z) < WARMUP_Z:
        return None
    duration = y.size / rate_hz
    end = tr.time_constant_s * WARMUP_END
    if end > duration / 2.0:
        return None
    adev = _settled_adev(y, rate_hz, tr.time_constant_s, end)
    ratio = abs(tr.amplitude) / adev if adev > 0 else math.inf
    if ratio < WARMUP_SIGMA:
        return None
    cut = max(min(tr.time_constant_ci_s[1] * WARMUP_END, duration / 2.0), end)
    return Warmup(0.0, end, tr.time_constant_s, tr.amplitude, adev, ratio,
                  tr.time_constant_ci_s, abs(tr.z), cut)  # fmt: skip


def detect_changes(
    y: NDArray[np.float64], rate_hz: float, curve: Any = None
) -> tuple[Warmup | None, Drift | None, Any, dict[str, float] | None, Trend | None]:
    """The warm-up and the drift of one channel (None when not flagged), the blocks
    used, the noise model and the slope's trend (module docstring). ``curve``: the
    channel's Allan curve (an octave overlapping one is computed when None or sparse)."""
    n = y.size
    duration = n / rate_hz
    if n < 4 * drift.MIN_BLOCKS:
        return None, None, None, None, None
    csum = drift.centred_cumsum(y)
    blocks = drift.block_means(y, rate_hz, csum)
    if blocks.mean.size < drift.MIN_BLOCKS:
        return None, None, blocks, None, None
    if not _usable(curve, duration):
        curve = allan(y, rate_hz, "octave")
    model = drift.noise_model(curve)
    units = drift.unit_covariances(blocks)
    try:
        gls = drift.Gls(blocks, model, units)
        # the slope in time pins a ramp: the noise is refitted to the curve of the
        # samples without the part of the slope beyond its standard error (none
        # expected from the noise alone), and without R
        slope, se, _ = drift.fit_slope(gls)
        excess = math.copysign(math.sqrt(max(slope**2 - se**2, 0.0)), slope)
        model = drift.noise_model(curve, drift.detrended_variance(y, curve, excess, csum))
        gls = drift.Gls(blocks, model, units)
    except (ValueError, np.linalg.LinAlgError):
        return None, None, blocks, dict(model.terms), None
    tr = drift.fit_transient(gls)
    warm = _warmup(y, rate_hz, tr)
    slope, _, z = drift.fit_slope(gls, warm.time_constant_s if warm is not None else None)
    found = None
    trend = Trend(slope, slope * duration, z)
    if abs(z) >= DRIFT_Z:
        found = Drift("ramp", slope, slope * duration, abs(z), duration)
        slow = tr is not None and warm is None and tr.time_constant_s * WARMUP_END > duration / 2
        if slow and tr is not None and abs(tr.z) >= abs(z):  # described as the settling
            change = tr.amplitude * math.expm1(-duration / tr.time_constant_s)
            found = Drift("settling", slope, change, abs(z), duration, tr.time_constant_s)
    return warm, found, blocks, dict(model.terms), trend


def detect_warmup(y: NDArray[np.float64], rate_hz: float) -> tuple[Warmup | None, Any, Any]:
    """The warm-up of one channel (None when not flagged), and the block times and
    means used (see :func:`detect_changes`)."""
    warm, _, blocks, _, _ = detect_changes(np.asarray(y, dtype=np.float64), rate_hz)
    if blocks is None:
        return warm, np.zeros(0), np.zeros(0)
    return warm, blocks.mid_s, blocks.mean + blocks.offset


def stationarity(
    y: Any, rate_hz: float, windows: int = WINDOWS, curve: Any = None
) -> Stationarity:
    """Time-resolved Allan deviation, stationarity test, warm-up and drift of one
    channel (``curve``: its Allan curve when already computed)."""
    arr = np.asarray(y, dtype=np.float64)
    if arr.size < 3 * windows:
        raise InputError(
            f"signal of {arr.size} samples is too short for the stationarity check "
            f"({windows} windows of at least 3 samples)"
        )
    win, starts, tau, cur = sliding_adev(arr, rate_hz, windows)
    adev, edf = cur["dev"], cur["edf"]
    p_each = [_homogeneity_p(adev[:, j] ** 2, edf[:, j]) for j in range(tau.size)]
    p = min(1.0, min(p_each) * len(p_each)) if p_each else 1.0
    warm, found, blocks, noise, trend = detect_changes(arr, rate_hz, curve)
    bt = blocks.mid_s if blocks is not None else np.zeros(0)
    bm = blocks.mean + blocks.offset if blocks is not None else np.zeros(0)
    return Stationarity(
        window_s=win,
        window_start_s=starts,
        tau_s=tau,
        adev=adev,
        ci_lower=cur["ci_lower"],
        ci_upper=cur["ci_upper"],
        p_value=p,
        stationary=p >= P_NON_STATIONARY and found is None,
        warmup=warm,
        block_t=bt,
        block_mean=bm,
        drift=found,
        noise=noise,
        trend=trend,
    )


def warmup_cuts(results: dict[str, Stationarity], rate_hz: float) -> dict[str, int]:
    """Samples to drop at the start of each channel for ``--cut-warmup``: its own
    warm-up's ``cut_s`` (0 where none was flagged)."""
    out: dict[str, int] = {}
    for name, r in results.items():
        w = r.warmup
        out[name] = int(math.ceil(w.cut_s * rate_hz)) if w is not None else 0
    return out


def cut_warmup(log: ImuLog, results: dict[str, Stationarity]) -> tuple[ImuLog, float]:
    """The whole log without the latest warm-up over the channels (every channel cut
    at the same sample), and that cut (s). The pipeline cuts each channel at its own
    warm-up instead (:func:`warmup_cuts`); this is for a caller who needs one time axis."""
    cuts = warmup_cuts(results, log.rate_hz)
    k = max(cuts.values(), default=0)
    if k == 0:
        return log, 0.0
    chans = {name: np.asarray(v)[k:] for name, v in log.channels.items()}
    return replace(log, channels=chans, t=np.asarray(log.t)[k:]), k / log.rate_hz
