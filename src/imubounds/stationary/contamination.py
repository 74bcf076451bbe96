"""Spikes and contaminated samples in a static log (METHOD.md 1.1;
docs/static-method.md, section 1.1).

A spike (one wild sample, or a short burst of them, as MEMS logs show after
a bus error or a shock) adds its squared size to every Allan term that
contains it: ten 50-sigma spikes in a million samples raise the Allan
variance at the sample period by 2.5 % and bias N accordingly, and nothing
in the curve says why. This module finds them.

Detection works on the local second difference of the rate samples,
``d_k = y_k − (y_{k−1} + y_{k+1})/2``: white noise gives d a standard
deviation of √1.5 times the sample noise, every slower process (flicker,
random walk, drift) is nearly cancelled, and a spike of size A gives
``|d| = A`` at its sample. The scale of d is estimated robustly
(1.4826 × median absolute deviation, so the spikes do not inflate it; on
quantised samples, where that underestimates, the RMS of the central 99.9 %
of the differences), and a
sample is flagged when ``|d| > threshold × scale`` (default 8: a Gaussian log
of 10⁹ samples has about one false alarm in a million such logs).
Neighbouring flagged samples form one event; the count of events, their
times, the largest robust z and the share of the sample-period Allan
variance they carry are reported. The robust Allan variance
(``allan(..., robust=True)``, ``imubounds static --robust``) is the remedy to
compare with.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from imubounds.errors import InputError, OptionError

__all__ = ["DEFAULT_THRESHOLD", "SpikeReport", "despike", "detect_spikes"]

#: Robust z above which a sample counts as a spike.
DEFAULT_THRESHOLD = 8.0
#: The RMS of the differences below this quantile bounds the robust scale from below.
TRIM_QUANTILE = 0.999
#: How many event positions a report lists.
MAX_LISTED = 20


@dataclass(frozen=True)
class SpikeReport:
    """Spikes found in one channel.

    ``events`` counts groups of neighbouring flagged samples (one spike gives
    one event), ``samples`` the flagged samples; ``first_index`` /
    ``first_time_s`` list up to :data:`MAX_LISTED` events (the sample with the
    largest z of each); ``max_z`` is the largest robust z; ``variance_share``
    the share of Σd² carried by the flagged samples (≈ their share of the Allan
    variance at the sample period). ``scale`` is the robust standard deviation
    of d, in the signal's unit.
    """

    channel: str
    n_samples: int
    threshold: float
    events: int
    samples: int
    max_z: float
    variance_share: float
    scale: float
    first_index: list[int] = field(default_factory=list)
    first_time_s: list[float] = field(default_factory=list)
    flagged: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64), repr=False)

    @property
    def found(self) -> bool:
        return self.events > 0

    def warning(self, robust: bool = False) -> str | None:
        """One line for the user, or None when the log is clean (``robust``: the
        robust curve is in use and sets the spikes aside)."""
        if not self.found:
            return None
        where = ", ".join(f"{t:.6g}" for t in self.first_time_s[:3])
        return (
            f"{self.channel}: {self.events} spike(s) beyond {self.threshold:g} robust sigma "
            f"({self.samples} sample(s), largest z = {self.max_z:.3g}) at t = {where}"
            f"{' ...' if self.events > 3 else ''} s (row {self.first_index[0]}); they carry "
            f"{self.variance_share:.2%} of the sample-period Allan variance"
            + (
                "; the robust curve interpolates them (the plain one is kept for comparison)"
                if robust
                else " and inflate N; compare with --robust"
            )
        )

    def to_dict(self) -> dict[str, Any]:
        return {
            "method": "robust z of the local second difference y[k] - (y[k-1]+y[k+1])/2",
            "threshold_sigma": self.threshold,
            "events": self.events,
            "samples": self.samples,
            "fraction": self.samples / self.n_samples if self.n_samples else 0.0,
            "max_z": self.max_z,
            "variance_share": self.variance_share,
            "scale": self.scale,
            "first_index": list(self.first_index),
            "first_time_s": list(self.first_time_s),
        }


def order_statistics(a: np.ndarray, ranks: list[int]) -> dict[int, float]:
    """The values of rank ``ranks`` (0-based) of a finite 1-d array, exactly as in
    ``np.sort(a)``, by one partition per rank at a single index, each of what is
    right of the previous rank: numpy partitions around one index with its
    vectorised selection (x86-simd-sort) and around several with introselect,
    several times slower (a median of an even count takes two indices)."""
    out: dict[int, float] = {}
    ks = sorted(set(ranks))
    if not ks:
        return out
    buf = np.partition(a, ks[0])
    out[ks[0]] = float(buf[ks[0]])
    start = ks[0] + 1
    for k in ks[1:]:
        view = buf[start:]  # every value here is >= those of the ranks before
        view.partition(k - start)
        out[k] = float(buf[k])
        start = k + 1
    return out


def median(a: np.ndarray) -> float:
    """``np.median(a)`` of a finite 1-d array, bit for bit (the middle value, or the
    ``np.mean`` of the two middle values), from :func:`order_statistics`."""
    n = a.size
    half = n // 2
    mid = [half - 1, half] if n % 2 == 0 else [half]
    v = order_statistics(a, mid)
    return float(np.mean(np.array([v[k] for k in mid])))


def median_and_quantile(a: np.ndarray, q: float) -> tuple[float, float]:
    """``np.median(a)`` and ``np.quantile(a, q)`` (linear method) of a finite 1-d
    array, bit for bit, from the same partitions (:func:`order_statistics`; numpy's
    formulas: the mean of the two middle values; ``_lerp`` of the neighbours of
    ``(n - 1) q``)."""
    n = a.size
    half = n // 2
    mid = [half - 1, half] if n % 2 == 0 else [half]
    virtual = (n - 1) * q
    lo = int(math.floor(virtual))
    hi = min(lo + 1, n - 1)
    v = order_statistics(a, [*mid, lo, hi])
    med = float(np.mean(np.array([v[k] for k in mid])))
    x0, x1 = v[lo], v[hi]
    gamma = virtual - lo
    diff = x1 - x0
    quant = x1 - diff * (1.0 - gamma) if gamma >= 0.5 else x0 + diff * gamma
    return med, quant


def detect_spikes(
    y: ArrayLike,
    rate_hz: float,
    *,
    threshold: float = DEFAULT_THRESHOLD,
    name: str = "signal",
    t: ArrayLike | None = None,
) -> SpikeReport:
    """Find spikes in a rate signal (see the module docstring).

    Parameters
    ----------
    y : array_like
        Rate samples (any unit), finite.
    rate_hz : float
        Sample rate (for the event times when ``t`` is not given).
    threshold : float
        Robust z above which a sample is flagged (> 0).
    name : str
        Channel name for the report and messages.
    t : array_like, optional
        Time stamps in s (default: sample index / rate).
    """
    if not (math.isfinite(threshold) and threshold > 0):
        raise OptionError(f"spike threshold must be a positive number of sigmas, got {threshold}")
    if not (math.isfinite(rate_hz) and rate_hz > 0):
        raise OptionError(f"rate must be a positive number of Hz, got {rate_hz}")
    arr = np.asarray(y, dtype=np.float64)
    if arr.ndim != 1:
        raise InputError(f"{name}: expected a 1-D signal, got shape {arr.shape}")
    n = arr.size
    empty = SpikeReport(name, n, float(threshold), 0, 0, 0.0, 0.0, 0.0)
    if n < 5 or not np.all(np.isfinite(arr)):
        return empty
    # the same operations as arr[1:-1] - 0.5 * (arr[:-2] + arr[2:]) and
    # abs(d - med), in place: fewer arrays of the log's length to allocate and fault in
    d = np.add(arr[:-2], arr[2:])
    np.multiply(0.5, d, out=d)
    np.subtract(arr[1:-1], d, out=d)
    med = median(d)
    a = np.subtract(d, med)
    np.abs(a, out=a)
    mad, cut = median_and_quantile(a, TRIM_QUANTILE)
    scale = 1.482602218505602 * mad
    # On quantised samples the median absolute deviation underestimates the spread
    # (most differences are 0 or one step); the RMS of the central 99.9 % does not,
    # and spikes rarer than 1 in 1000 samples do not enter it.
    central = a[a <= cut]
    if central.size:
        np.multiply(central, central, out=central)
        scale = max(scale, float(np.sqrt(np.mean(central))))
    if scale == 0.0:
        return empty
    z = a / scale
    flag = z > threshold
    if not np.any(flag):
        return SpikeReport(name, n, float(threshold), 0, 0, float(z.max()), 0.0, scale)
    idx = np.flatnonzero(flag)
    # events: runs of flagged samples no more than 2 apart (a spike flags k-1, k, k+1)
    breaks = np.flatnonzero(np.diff(idx) > 2)
    starts = np.concatenate(([0], breaks + 1))
    stops = np.concatenate((breaks + 1, [idx.size]))
    peaks = [
        int(idx[a + int(np.argmax(z[idx[a:b]]))]) + 1 for a, b in zip(starts, stops, strict=True)
    ]
    times = np.asarray(t, dtype=np.float64) if t is not None else None
    listed = peaks[:MAX_LISTED]
    first_t = [float(times[i]) if times is not None else i / rate_hz for i in listed]
    dd = d * d
    share = float(dd[flag].sum() / dd.sum()) if dd.sum() > 0 else 0.0
    return SpikeReport(
        channel=name,
        n_samples=n,
        threshold=float(threshold),
        events=len(peaks),
        samples=int(idx.size),
        max_z=float(z.max()),
        variance_share=share,
        scale=scale,
        first_index=listed,
        first_time_s=first_t,
        flagged=idx + 1,
    )


def despike(y: ArrayLike, report: SpikeReport) -> np.ndarray:
    """A copy of ``y`` with the flagged samples replaced by linear interpolation
    between the nearest clean samples (the first step of the robust Allan variance)."""
    arr = np.array(y, dtype=np.float64, copy=True)
    if report.samples == 0 or arr.size == 0:
        return arr
    bad = np.zeros(arr.size, dtype=bool)
    bad[report.flagged] = True
    good = np.flatnonzero(~bad)
    if good.size == 0:
        return arr
    arr[bad] = np.interp(np.flatnonzero(bad), good, arr[good])
    return arr
