"""The record of simulated inputs that fell outside their stated bounds.

Each :class:`Check` compares one error of one stream with the bound that
``drive.yaml`` states for it (METHOD.md 4.1), at a whole-trip risk ``alpha``
per stream with ``k(n) = Phi^-1(1 - alpha/(2n))`` over the ``n`` samples (or
windows) checked. The definitions (each :class:`Check` carries its own text):

IMU, per channel (error terms as in :mod:`.imu`; the IMU's k counts the six
channels together):

``white_sample``
    ``|w_k| <= k(6n) N/sqrt(dt)`` for every sample (n samples per channel).
``white_interval``
    the white noise integrated between consecutive aiding epochs (the union of
    every aiding stream's time stamps), ``|sum w_k dt| <= k(6m) N sqrt(Delta)``
    over the m intervals.
``white_window``
    the white noise averaged over the non-overlapping octave windows from one
    sample to a quarter of the trip, ``|mean w| <= k(6M) N/sqrt(tau)`` (M windows
    over all octaves).
``turn_on``
    ``|b| <=`` the stated turn-on bound.
``bias_drift``
    the bias wander averaged over the non-overlapping octave windows from the
    drift window (1 s) to a quarter of the trip ``<=`` the stated drift bound.
``scale``, ``misalignment``
    when simulated: ``|s| <=`` the stated scale bound, ``|m| <=`` the stated
    misalignment bound.

Aiding streams:

``gnss.position``
    horizontal error radius ``<= D = DRMS_i sqrt(ln(n/alpha))`` (the radius of
    probability ``1 - alpha/n``, METHOD.md 2.2 and 4.1; DRMS_i = HDOP_i CEP /
    sqrt(ln 2) = sqrt(2) ``h_acc_m``), n fixes; a box of half-width D holds whatever
    this circle holds.
``gnss.velocity``
    each component ``|e| <= k(n) vel_sigma_mps`` with n the number of fixes.
``velocity``
    each component ``|e| <= bound_mps + scale |u|`` (the stated bound).
``heading``
    ``|corrected - true| <= deviation_deg + k(n) noise_deg`` after the
    calibration of ``heading.calibration`` is applied.
``attitude``
    ``|roll error|, |pitch error| <= bound_deg``.

The k of an aiding stream counts its epochs, not its components, and uses the
whole ``alpha`` for the stream: an estimator that counts each component, or
splits ``alpha`` between streams, uses a larger k, so a clean record means every
aiding input lies within its bounds. The IMU's k counts its six channels: an
estimator must count them too (Sidak over every bounded IMU quantity) for a
clean record to imply its white-noise bounds. GNSS outliers and sensor faults are always
recorded; a record is :attr:`Record.clean` when no check has a sample outside
and there is no outlier and no fault.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

Array = np.ndarray

#: How many of the first offending samples a check lists.
FIRST = 10


@dataclass
class Check:
    """One bound check over one stream's samples."""

    name: str
    stream: str
    unit: str
    definition: str
    n: int
    k: float | None
    bound: float | None  # a constant bound, or None when it varies per sample
    count: int
    first_indices: list[int]
    first_times_s: list[float]
    worst_excess: float  # max(|error| - bound); negative: the smallest margin
    worst_time_s: float | None

    def to_dict(self) -> dict[str, Any]:
        return {
            "stream": self.stream,
            "unit": self.unit,
            "definition": self.definition,
            "n": self.n,
            "k": self.k,
            "bound": self.bound,
            "count": self.count,
            "first_indices": self.first_indices,
            "first_times_s": self.first_times_s,
            "worst_excess": self.worst_excess,
            "worst_time_s": self.worst_time_s,
        }


def check(
    name: str,
    stream: str,
    unit: str,
    definition: str,
    error: Array,
    bound: Array | float,
    times: Array,
    *,
    k: float | None = None,
    index: Array | None = None,
) -> Check:
    """Compare ``|error|`` with ``bound`` elementwise (rows of a 2-D error: any column)."""
    e = np.abs(np.asarray(error, dtype=float))
    b = np.asarray(bound, dtype=float)
    excess = e - (b if e.ndim == 1 or b.ndim == 0 else b.reshape(-1, *([1] * (e.ndim - 1))))
    if excess.ndim > 1:
        excess = excess.max(axis=tuple(range(1, excess.ndim)))
    times = np.asarray(times, dtype=float)
    idx = np.arange(excess.size) if index is None else np.asarray(index)
    bad = np.flatnonzero(excess > 0)
    w = int(np.argmax(excess)) if excess.size else 0
    return Check(
        name=name,
        stream=stream,
        unit=unit,
        definition=definition,
        n=int(excess.size),
        k=None if k is None else float(k),
        bound=float(b) if b.ndim == 0 else None,
        count=int(bad.size),
        first_indices=[int(i) for i in idx[bad[:FIRST]]],
        first_times_s=[float(x) for x in times[bad[:FIRST]]],
        worst_excess=float(excess[w]) if excess.size else -math.inf,
        worst_time_s=float(times[w]) if excess.size else None,
    )


@dataclass
class Record:
    """Every check of a simulated trip, its GNSS outliers and its sensor faults."""

    alpha: float
    checks: list[Check] = field(default_factory=list)
    outliers: dict[str, dict[str, list[float]]] = field(default_factory=dict)
    faults: list[dict[str, Any]] = field(default_factory=list)

    @property
    def clean(self) -> bool:
        """True when no input left its stated bound and there is no outlier and no fault."""
        return (
            all(c.count == 0 for c in self.checks)
            and not any(v["indices"] for v in self.outliers.values())
            and not self.faults
        )

    def out_of_bounds(self) -> list[Check]:
        """The checks with at least one sample outside its bound."""
        return [c for c in self.checks if c.count]

    def get(self, name: str) -> Check:
        for c in self.checks:
            if c.name == name:
                return c
        raise KeyError(name)

    def to_dict(self) -> dict[str, Any]:
        return {
            "clean": self.clean,
            "alpha": self.alpha,
            "rule": "k(n) = Phi^-1(1 - alpha/(2n)) per stream over its n epochs (or windows)",
            "out_of_bounds": [c.name for c in self.out_of_bounds()],
            "outliers": self.outliers,
            "faults": self.faults,
            "checks": {c.name: c.to_dict() for c in self.checks},
        }

    def summary(self) -> str:
        """One line: clean, or what fell outside."""
        if self.clean:
            return "record: clean (every input within its stated bound)"
        parts = [f"{c.name} x{c.count}" for c in self.out_of_bounds()]
        for s, v in self.outliers.items():
            if v["indices"]:
                parts.append(f"{s} outliers x{len(v['indices'])}")
        parts += [f"fault {f['label']}" for f in self.faults]
        return "record: " + ", ".join(parts)


# ----------------------------------------------------------------------------- IMU


def white_interval_sums(white: Array, dt: float, epoch_index: Array) -> tuple[Array, Array, Array]:
    """White noise integrated between consecutive epochs: (sums, durations, end indices).

    ``epoch_index`` are sample indices of the epochs (sorted, unique); sample k
    covers ``[t_k - dt, t_k]``, so the interval (e_{j-1}, e_j] holds samples
    e_{j-1}+1 .. e_j.
    """
    c = np.concatenate([[0.0], np.cumsum(white)]) * dt  # c[k+1] = sum of samples 0..k
    e = np.asarray(epoch_index)
    sums = c[e[1:] + 1] - c[e[:-1] + 1]
    return sums, (e[1:] - e[:-1]) * dt, e[1:]


def octave_windows(n: int, first: int, last_s: float, dt: float) -> list[tuple[int, int]]:
    """Non-overlapping windows of samples 1..n-1 (those inside the trip), of ``first`` samples
    doubling up to ``last_s / dt``: [(samples per window m, number of windows)]."""
    out = []
    m = max(1, first)
    avail = n - 1
    while m * dt <= last_s + 1e-9 and m <= avail:
        out.append((m, avail // m))
        m *= 2
    return out


def window_means(x: Array, wins: list[tuple[int, int]]) -> tuple[Array, Array, Array]:
    """Means of ``x`` (n,) over the windows of :func:`octave_windows`:
    (means, samples per window, index of each window's last sample)."""
    c = np.concatenate([[0.0], np.cumsum(x)])  # c[k] = sum of x[0..k-1]
    means, size, last = [], [], []
    for m, w in wins:
        starts = 1 + m * np.arange(w)
        means.append((c[starts + m] - c[starts]) / m)
        size.append(np.full(w, m))
        last.append(starts + m - 1)
    if not means:
        return np.zeros(0), np.zeros(0, dtype=int), np.zeros(0, dtype=int)
    return np.concatenate(means), np.concatenate(size), np.concatenate(last)
