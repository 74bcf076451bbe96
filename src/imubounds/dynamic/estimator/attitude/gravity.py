"""Vector matching over a window (docs/dynamic-method.md, section 3b, (3b.1)-(3b.2)):
the kernel mean of the gravity components ``g sin(theta)`` (accel_x) and ``g sin(phi)
cos(theta)`` (accel_y) from the accelerometer against the aiding::

    g mean_K sin(theta)           in  [y_W(accel_x)] - [k_W(accel_x)] -+ band_W(accel_x)
    g mean_K sin(phi) cos(theta)  in  [y_W(accel_y)] - [k_W(accel_y)] -+ band_W(accel_y)

``[k_W]`` the kinematic part of the channel's true-signal constraint (every term of
``aided.accel_x`` / ``aided.accel_y`` but gravity: the velocity ends, transport, the
Earth's rates, ``q w`` / ``p w``), built with the prior tilt, and ``band_W`` the
stationary band: the bound of the window's mean error when the channel's budget holds.
These are the constraint of each window of the channel's plan turned round: the same
windows, the same events (no new probability), and the margins of accel_x and accel_y
reuse the kinematic parts computed here (:attr:`GravityWindows.kin`)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from imubounds.constants import G_HI, G_LO
from imubounds.dynamic.estimator.aided.base import pm
from imubounds.dynamic.estimator.aided.tilt import TiltSignals
from imubounds.dynamic.estimator.band import level_band
from imubounds.interval import IntervalArray as IA

#: the channel of each angle's windows and the gravity function that channel measures
CHANNEL_OF = {"pitch": "accel_x", "roll": "accel_y"}
GRAVITY_KEYS = ("g_sinp", "g_sinr_cosp")
#: windows shorter than this many aiding periods are not used (their kinematic part,
#: about 2 R / tau, is wider than any tilt bound)
MIN_PERIODS = 4
#: at most this many windows of a level, at least half their length apart
CAP = 2048


def _thin(a1: np.ndarray, tau: float, cap: int) -> np.ndarray:
    """Indices of windows (starts ``a1``, sorted) at least ``tau / 2`` apart, at most
    ``cap`` of them spread over the trip."""
    keep = []
    last = -np.inf
    for i in np.argsort(a1, kind="stable"):
        if a1[i] >= last + 0.5 * tau * (1 - 1e-9):
            keep.append(i)
            last = a1[i]
    idx = np.asarray(keep, dtype=np.int64)
    if idx.size > cap:
        idx = idx[np.unique(np.round(np.linspace(0, idx.size - 1, cap)).astype(np.int64))]
    return idx


@dataclass
class GravityWindows:
    """The windows of one angle: the kernel mean ``S`` of the gravity function over g,
    the kernel (``ker`` rows a1, b1, a2, b2, tau) and the links and node on the epochs
    ``te`` (``k0 <= k < k1``; the node at the kernel's centre)."""

    axis: str
    S: IA
    ker: np.ndarray
    node: np.ndarray
    k0: np.ndarray
    k1: np.ndarray
    level: np.ndarray
    #: per (channel, id(level plan)): the kinematic part of every window of the level
    kin: dict[tuple[str, int], IA] = field(default_factory=dict)

    @property
    def n(self) -> int:
        return int(self.node.size)


def no_gravity(ts: TiltSignals) -> TiltSignals:
    """A view of ``ts`` whose gravity functions of accel_x and accel_y are 0 (the other
    tilt functions, second-order factors of the kinematic part, unchanged)."""
    out = TiltSignals(ts.bnd, ts.roll, ts.pitch)
    out.funcs = dict(ts.funcs)
    n = ts.roll.shape[0]
    for key in GRAVITY_KEYS:
        out.funcs[key] = lambda n=n: IA(np.zeros(n), np.zeros(n))
    out.sig = {k: v for k, v in ts.sig.items() if k not in GRAVITY_KEYS}
    out.ext = {k: v for k, v in ts.ext.items() if k not in GRAVITY_KEYS}
    return out


def _on_epochs(te: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Indices of ``t`` among the epochs ``te`` and whether each is one of them."""
    i = np.clip(np.searchsorted(te, t), 0, te.size - 1)
    return i, np.abs(te[i] - t) <= 1e-9 * (1.0 + np.abs(t))


def gravity_windows(ctx: Any, mb: Any, axis: str, constraint: Any,
                    tau_max: float = np.inf) -> GravityWindows:
    """The windows of ``axis`` from its channel's plan (the aided levels of at least
    :data:`MIN_PERIODS` aiding periods and at most ``tau_max``, thinned by
    :func:`_thin`), evaluated with ``mb`` (a margin builder whose tilt is the prior);
    ``constraint`` the channel's true-signal constraint. The kinematic part of every
    aided level is kept for the margins (:attr:`GravityWindows.kin`)."""
    ch = CHANNEL_OF[axis]
    plan = ctx.plans.get(ch)
    te = ctx.te
    parts: dict[str, list[Any]] = {k: [] for k in ("lo", "hi", "ker", "node", "k0", "k1", "lv")}
    out = GravityWindows(axis, IA(np.zeros(0)), np.zeros((0, 5)), *(np.zeros(0, np.int64),) * 4)
    if plan is None or not plan.levels:
        return out
    gap = float(np.median(np.diff(plan.epochs))) if plan.epochs.size > 1 else np.inf
    prior = mb.tilt
    mb.tilt = no_gravity(prior)
    alpha = ctx.alpha
    try:
        for li, lp in enumerate(plan.levels):
            if lp.kind != "aided" or lp.n == 0:
                continue
            tau = lp.tau
            gi = ctx.level_index[(ch, li)]
            mb.p_window = alpha.p_level("imu_windows", gi)
            kin = constraint(mb, plan, lp, tau)
            acc = pm(np.full(lp.n, ctx.vehicle.max_accel))
            lo, hi = np.maximum(kin.lo, acc.lo), np.minimum(kin.hi, acc.hi)
            ok = lo <= hi
            kin = IA(np.where(ok, lo, kin.lo), np.where(ok, hi, kin.hi))
            out.kin[(ch, id(lp))] = kin
            if lp.tau_s < MIN_PERIODS * gap * (1 - 1e-9) or lp.tau_s > tau_max:
                continue
            y = mb.imu_mean(ch, lp, tau)
            band, _ = level_band(mb, ch, lp, tau, alpha.k_level("imu_windows", gi))
            S = (y - kin + pm(band)) / IA(G_LO, G_HI)
            sel = np.zeros(lp.n, bool)
            sel[_thin(lp.a1, lp.tau_s, CAP)] = True
            ia, ok1 = _on_epochs(te, lp.a1)
            ib, ok2 = _on_epochs(te, lp.b1)
            ic, ok3 = _on_epochs(te, lp.a2)
            iz, ok4 = _on_epochs(te, lp.b2)
            good = sel & ok1 & ok2 & ok3 & ok4 & np.isfinite(S.lo) & np.isfinite(S.hi) & (iz > ia)
            if plan.trapezoid:
                node = ib
            else:
                mid = 0.5 * (lp.a1 + lp.a2)
                node = np.clip(np.searchsorted(te, mid), ia, iz)
                prev = np.maximum(node - 1, ia)
                node = np.where(np.abs(te[prev] - mid) < np.abs(te[node] - mid), prev, node)
            parts["lo"].append(S.lo[good])
            parts["hi"].append(S.hi[good])
            parts["ker"].append(np.stack([lp.a1, lp.b1, lp.a2, lp.b2, tau], -1)[good])
            parts["node"].append(node[good])
            parts["k0"].append(ia[good])
            parts["k1"].append(iz[good])
            parts["lv"].append(np.full(int(good.sum()), li))
    finally:
        mb.tilt = prior
    if parts["lo"]:
        out.S = IA(np.concatenate(parts["lo"]), np.concatenate(parts["hi"]))
        out.ker = np.ascontiguousarray(np.concatenate(parts["ker"]))
        out.node = np.concatenate(parts["node"]).astype(np.int64)
        out.k0 = np.concatenate(parts["k0"]).astype(np.int64)
        out.k1 = np.concatenate(parts["k1"]).astype(np.int64)
        out.level = np.concatenate(parts["lv"]).astype(np.int64)
    return out
