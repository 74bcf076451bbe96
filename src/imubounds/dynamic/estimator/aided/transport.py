"""The forms of the bound of the kernel mean of |r| in the accelerometers' transport terms
(docs/dynamic-method.md, section 3, **accel_x**: ``mean_W|r|``; the registry's
``mean_abs_r`` table, :mod:`.form_tables`).

Besides the gyro's magnitude (the per-sample bound), two forms, each at its share of
the window's probability:

* the gyro's magnitude centred on its own mean error over the window (known from the
  heading): ``mean|y_r - c| + |e - c| + sqrt(S^2) + 2D + 2s mean|x|``, ``S^2`` a bound of
  the mean square deviation of the gyro noise from its mean
  (:func:`~imubounds.dynamic.estimator.budget.centered_ms_bound`);
* the gyro centred on each heading gap (:mod:`.transport_blocks`): the noise counted once
  (Jensen) plus a Gaussian concentration term that the per-gap centring keeps small.
"""

from __future__ import annotations

import numpy as np

from imubounds.dynamic.estimator.aided.base import up
from imubounds.dynamic.estimator.aided.common import WindowContext
from imubounds.dynamic.estimator.aided.heading import heading_at, r_from_psidot
from imubounds.dynamic.estimator.aided.transport_blocks import abs_dev_integral
from imubounds.dynamic.estimator.budget import centered_ms_bound
from imubounds.dynamic.estimator.window_plan import LevelPlan
from imubounds.interval import IntervalArray as IA

__all__ = ["abs_dev_integral", "centred_applies", "centred_window", "det_mean", "support_plan"]


def det_mean(w: WindowContext, s0: np.ndarray, s1: np.ndarray) -> np.ndarray:
    """Bound of the mean over ``[s0, s1]`` of the gyro_z error's deterministic deviation
    from its own mean: ``2 D + 2 s mean|r| + 2 m (mean|p| + mean|q|)`` (``D`` the
    channel's deterministic bound, ``s`` its scale and ``m`` its misalignment bound)."""
    cn = w.ctx.noise["gyro_z"]
    det = 2 * w.ctx.D_KR["gyro_z"] + 2 * cn.scale * w.mag_mean("gyro_z", s0, s1)
    for other in ("gyro_x", "gyro_y"):
        det = det + 2 * cn.misalignment_rad * w.mag_mean(other, s0, s1)
    return det


def centred_applies(w: WindowContext) -> bool:
    """Whether the gyro-centred forms of mean |r| apply: a heading, gyro_z recorded and
    not judged faulty (``w.fine_r``)."""
    return bool(w.fine_r and w.ag.has_heading and w.imu.available["gyro_z"])


def support_plan(lp: LevelPlan) -> tuple[LevelPlan, np.ndarray]:
    """A boxcar over each window's support ``[a1, b2]`` and its length."""
    s0, s1 = lp.a1, lp.b2
    L = s1 - s0
    return LevelPlan(float(np.median(L)), "aided", s0, s0, s1, s1, lp.i, lp.j), L


def centred_window(
    w: WindowContext, lp: LevelPlan, tau: np.ndarray, p: float, det: np.ndarray
) -> np.ndarray:
    """Bound of the kernel mean of |r| (true yaw rate) over each window (docs/dynamic-
    method.md, (3.8)), holding with probability ``>= 1 - p``: the gyro's magnitude
    centred on its own mean error over the window's support (known from the heading),
    plus a bound of the noise's deviation from its mean (Gaussian quadratic form) and
    the deterministic deviation ``det`` (:func:`det_mean` over the support); +inf where
    not finite."""
    s0, s1 = lp.a1, lp.b2
    sup, L = support_plan(lp)
    sig = w.imu.sig["gyro_z"]
    ylo, yhi = sig.integral(s0, s1)
    ybox = IA(ylo, yhi) / IA(L)
    p0, p1 = heading_at(w, s0), heading_at(w, s1)
    xbox = r_from_psidot(w, (p1 - p0) / IA(L), sup, L, own_q=True)
    e = ybox - xbox
    fin = np.isfinite(e.lo) & np.isfinite(e.hi)
    c0 = np.where(fin, e.mid(), 0.0)
    rad = np.where(fin, e.radius(), np.inf)
    dev = abs_dev_integral(
        sig.bnd, sig.y, sig.unknown, sig.xmax, s0, s1, np.ascontiguousarray(c0)
    ) / L
    cn = w.ctx.noise["gyro_z"]
    m = w.imu.count(s0, s1)
    uc, inv = np.unique(m, return_inverse=True)
    ms = np.array([centered_ms_bound(cn, int(mm), w.imu.dt, p) for mm in uc])[inv]
    ratio = max(1.0, w.imu.max_len / w.imu.dt)
    fine = dev + rad + np.sqrt(ms) * ratio + det
    fine = up(fine * L / tau)
    return np.where(np.isfinite(fine), fine, np.inf)
