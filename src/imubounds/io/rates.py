"""Changes of the sample rate inside one log (part of the validation layer of
:mod:`imubounds.io.validate`).

A log spliced from two recordings at different rates (100 Hz, then 50 Hz) has steps
of two sizes. Taken as one rate it is wrong everywhere: the median step makes the
whole log the faster rate (a 2 h log read as 1.5 h), and the second part's steps
are either gaps or "jitter" of 70 % that no clock has. :func:`find_rate_changes`
finds them: the steps are cut into blocks of :func:`block_size` steps, each block's
nominal step is the mean of its steps within [½, 1½] × its median (quantised stamps
alternating between two values average out; a gap's long step is left out), and a
run of at least :data:`MIN_RUN_BLOCKS` blocks whose nominal step differs from the
run before by more than :data:`RATE_CHANGE_REL` (and :data:`JITTER_SIGMAS` standard
errors of a block's mean step, for jittery stamps) is a new rate. The change is placed
at the step that best separates the two rates (least sum of |ln(step/nominal)| on
each side). Readers refuse a log with a rate change, or split it there with
``--on-gap split`` (each part with its own rate); it is never analysed as one rate.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Relative difference of the nominal step between two runs that makes a rate change
#: (sample clocks differ by well under 1 %; the mean of a block of jittered steps by
#: the jitter / √(block)).
RATE_CHANGE_REL = 0.05
#: A new rate must hold for this many consecutive blocks.
MIN_RUN_BLOCKS = 2
#: ... and differ by more than this many standard errors of a block's nominal step
#: (the steps' robust spread within the blocks / √steps per block), for jittery stamps.
JITTER_SIGMAS = 5.0


@dataclass(frozen=True)
class RateChange:
    """A change of the nominal step between rows ``row`` − 1 and ``row`` (0-based
    index of the first sample at the new rate), from ``before_s`` to ``after_s``."""

    row: int
    before_s: float
    after_s: float

    @property
    def rates_hz(self) -> tuple[float, float]:
        return 1.0 / self.before_s, 1.0 / self.after_s


def block_size(n_steps: int) -> int:
    """Steps per block: 256, fewer for short logs (at least 16), so that a log has
    a few dozen blocks."""
    return int(min(256, max(16, n_steps // 32)))


def nominal_step(block: np.ndarray) -> float:
    """The mean of the positive steps within [½, 1½] × their median (nan: none)."""
    pos = block[block > 0]
    if pos.size == 0:
        return float("nan")
    med = float(np.median(pos))
    keep = pos[(pos >= 0.5 * med) & (pos <= 1.5 * med)]
    return float(np.mean(keep)) if keep.size else med


def _spread(block: np.ndarray) -> float:
    """Robust relative spread of a block's positive steps (IQR / 1.349 / median)."""
    pos = block[block > 0]
    if pos.size < 4:
        return 0.0
    q25, med, q75 = np.percentile(pos, [25.0, 50.0, 75.0])
    return float((q75 - q25) / 1.349 / med) if med > 0 else 0.0


def _runs(nominal: np.ndarray, tol: float) -> list[tuple[int, int, float]]:
    """Runs of blocks of one nominal step (within ``tol``): (first block, end, step)."""
    runs: list[tuple[int, int, float]] = []
    start = 0
    for k in range(1, nominal.size + 1):
        if k < nominal.size and np.isfinite(nominal[k]):
            ref = float(np.median(nominal[start:k]))
            if abs(nominal[k] / ref - 1.0) <= tol:
                continue
        runs.append((start, k, float(np.median(nominal[start:k]))))
        start = k
    merged: list[tuple[int, int, float]] = []
    for a, b, step in runs:  # a short run (a transition, a burst) joins the run before
        same = bool(merged) and abs(step / merged[-1][2] - 1.0) <= tol
        if merged and (b - a < MIN_RUN_BLOCKS or same):
            pa, _, pstep = merged[-1]
            merged[-1] = (pa, b, pstep)
        else:
            merged.append((a, b, step))
    if len(merged) > 1 and merged[0][1] - merged[0][0] < MIN_RUN_BLOCKS:  # a short start
        merged[:2] = [(0, merged[1][1], merged[1][2])]
    return merged


def _split_at(dt: np.ndarray, lo: int, hi: int, before: float, after: float) -> int:
    """The step index in [lo, hi) from which the steps are at ``after``."""
    seg = dt[lo:hi]
    pos = np.where(seg > 0, seg, before)
    cost_a = np.abs(np.log(pos / before))
    cost_b = np.abs(np.log(pos / after))
    # split k: steps lo..lo+k-1 at `before`, lo+k..hi-1 at `after`
    left = np.concatenate(([0.0], np.cumsum(cost_a)))
    right = np.concatenate((np.cumsum(cost_b[::-1])[::-1], [0.0]))
    return lo + int(np.argmin(left + right))


def find_rate_changes(dt: np.ndarray) -> list[RateChange]:
    """The rate changes of steps ``dt`` (s, between consecutive rows), in order."""
    d = np.asarray(dt, dtype=np.float64)
    size = block_size(d.size)
    nb = d.size // size
    if nb < 2 * MIN_RUN_BLOCKS:
        return []
    blocks = [d[k * size : (k + 1) * size] for k in range(nb)]
    nominal = np.array([nominal_step(b) for b in blocks])
    jitter = float(np.median([_spread(b) for b in blocks]))
    runs = _runs(nominal, max(RATE_CHANGE_REL, JITTER_SIGMAS * jitter / np.sqrt(size)))
    out: list[RateChange] = []
    for (_, b0, s0), (a1, _, s1) in zip(runs, runs[1:], strict=False):
        lo, hi = max(0, (b0 - 1) * size), min(d.size, (a1 + 1) * size)
        step = _split_at(d, lo, hi, s0, s1)
        out.append(RateChange(step + 1, s0, s1))
    return out


def describe(source: str, change: RateChange, row_label: str, t_s: float) -> str:
    """One line naming the change."""
    r0, r1 = change.rates_hz
    return (
        f"{source}: the sample rate changes at {row_label} (t = {t_s:.6g} s) from "
        f"{r0:.4g} Hz to {r1:.4g} Hz (median steps {change.before_s:.4g} s and "
        f"{change.after_s:.4g} s): a log spliced from two rates cannot be analysed as one"
    )
