"""The windows of every averaging time (docs/dynamic-method.md, section 3, "Windows").

For a channel whose aided means come from a set of aiding epochs: octave tau levels from
one IMU sample to a quarter of the trip; at each level windows start every tau/2 (at most
``cap``). Levels shorter than the aiding period get windows judged by the vehicle bounds
only; boxcar levels keep adjacent pairs for the change test.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np


@dataclass
class LevelPlan:
    """The windows of one averaging time (relative times, s)."""

    tau_s: float
    kind: str  # "aided" or "vehicle"
    a1: np.ndarray
    b1: np.ndarray
    a2: np.ndarray
    b2: np.ndarray
    i: np.ndarray  # epoch index of the window start (aided)
    j: np.ndarray  # epoch index of the window end (aided)
    #: adjacent pairs (window p1[q] ends where window p2[q] starts) for the change test
    p1: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    p2: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))

    @property
    def n(self) -> int:
        return int(self.a1.size)

    @property
    def n_pairs(self) -> int:
        return int(self.p1.size)

    @property
    def tau(self) -> np.ndarray:
        return 0.5 * (self.a2 + self.b2) - 0.5 * (self.a1 + self.b1)


@dataclass
class ChannelPlan:
    channel: str
    source: str  # which aiding builds [x_W]
    epochs: np.ndarray  # aiding epochs of the windows
    trapezoid: bool
    levels: list[LevelPlan] = field(default_factory=list)
    reason: str = ""


def tau_grid(dt: float, duration: float) -> list[float]:
    """Octave grid from one IMU sample to a quarter of the trip."""
    out = []
    tau = dt
    while tau <= duration / 4.0 * (1 + 1e-9):
        out.append(tau)
        tau *= 2.0
    return out


def _subsample(idx: np.ndarray, cap: int) -> np.ndarray:
    if idx.size <= cap:
        return idx
    pick = np.unique(np.round(np.linspace(0, idx.size - 1, cap)).astype(np.int64))
    return idx[pick]


def plan_channel(
    channel: str,
    source: str,
    epochs: np.ndarray,
    trapezoid: bool,
    bnd: np.ndarray,
    dt: float,
    cap: int,
) -> ChannelPlan:
    """Windows of every tau level for a channel whose aided means come from ``epochs``."""
    plan = ChannelPlan(channel, source, epochs, trapezoid)
    duration = float(bnd[-1] - bnd[0])
    if epochs.size < 2:
        plan.reason = f"fewer than two {source} epochs"
    gap = float(np.median(np.diff(epochs))) if epochs.size >= 2 else math.inf
    n_imu = bnd.size - 1
    for tau in tau_grid(dt, duration):
        if tau < 0.999 * gap or epochs.size < 2:
            # shorter than the aiding period: only the vehicle's bounds (gross faults);
            # fewer windows are enough
            m = max(1, int(round(tau / dt)))
            starts = np.arange(0, n_imu - m + 1, max(1, m // 2))
            starts = _subsample(starts, min(cap, 256))
            a = bnd[starts]
            b = bnd[starts + m]
            z = np.zeros(a.size, dtype=np.int64)
            plan.levels.append(LevelPlan(tau, "vehicle", a, a, b, b, z, z))
            continue
        m = max(1, int(round(tau / gap)))
        last = epochs.size - 1 - (2 * m if trapezoid else m)
        if last < 0:
            continue
        if trapezoid:
            starts = _subsample(np.arange(0, last + 1, max(1, m // 2)), cap)
        else:
            step = max(1, m // 2)
            while m % step:  # a divisor of m: window s + m is a start too (change test)
                step -= 1
            starts = _subsample_pairs(np.arange(0, last + 1, step), m, last, cap)
        if trapezoid:
            a1, b1 = epochs[starts], epochs[starts + m]
            a2, b2 = epochs[starts + m], epochs[starts + 2 * m]
            j = starts + 2 * m
        else:
            a1 = b1 = epochs[starts]
            a2 = b2 = epochs[starts + m]
            j = starts + m
        lp = LevelPlan(tau, "aided", a1, b1, a2, b2, starts, j)
        if not trapezoid:
            q = np.searchsorted(starts, j)
            ok = q < starts.size
            ok[ok] = starts[q[ok]] == j[ok]
            lp.p1 = np.flatnonzero(ok).astype(np.int64)
            lp.p2 = q[ok].astype(np.int64)
        plan.levels.append(lp)
    return plan


def _subsample_pairs(idx: np.ndarray, m: int, last: int, cap: int) -> np.ndarray:
    """Like :func:`_subsample`, but the kept starts come in adjacent pairs (s, s + m)
    so that the change test has windows to compare."""
    if idx.size <= cap:
        return idx
    first = idx[idx + m <= last]
    pick = _subsample(first, max(1, cap // 2))
    return np.unique(np.concatenate([pick, pick + m]))


def epochs_near(t: np.ndarray, t_head: np.ndarray) -> np.ndarray | None:
    """Indices of the epochs ``t`` nearest each epoch of a sparser heading ``t_head``
    (within half of ``t``'s median gap), when the heading's median gap exceeds 1.5 x
    ``t``'s; else None. accel_y's windows end there: its transport term takes the
    heading at the window ends, which between heading epochs is widened by the gyro's
    magnitude x the distance (docs/dynamic-method.md, section 3, **accel_y**)."""
    if t.size < 2 or t_head.size < 2:
        return None
    gap = float(np.median(np.diff(t)))
    if float(np.median(np.diff(t_head))) <= 1.5 * gap:
        return None
    j = np.clip(np.searchsorted(t, t_head), 1, t.size - 1)
    near = np.where(np.abs(t[j - 1] - t_head) <= np.abs(t[j] - t_head), j - 1, j)
    near = near[np.abs(t[near] - t_head) <= 0.5 * gap]
    sel = np.unique(near)
    return sel if sel.size >= 2 else None


def plan_on_subset(
    channel: str,
    source: str,
    epochs: np.ndarray,
    sel: np.ndarray,
    bnd: np.ndarray,
    dt: float,
    cap: int,
) -> ChannelPlan:
    """:func:`plan_channel` (boxcar) on the epochs ``epochs[sel]``, with the windows'
    epoch indices ``i``, ``j`` pointing into ``epochs``."""
    plan = plan_channel(channel, source, epochs[sel], False, bnd, dt, cap)
    for lp in plan.levels:
        if lp.kind == "aided":
            lp.i = sel[lp.i]
            lp.j = sel[lp.j]
    return plan
