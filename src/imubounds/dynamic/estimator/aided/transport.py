"""The bound of the kernel mean of |r| in the accelerometers' transport terms (docs/dynamic-
method.md, section 3, **accel_x**: ``mean_W|r|``, ``r_abs``).

The smaller of two bounds, each at half the window's probability:

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
from imubounds.dynamic.estimator.aided.transport_blocks import abs_dev_integral, block_r_abs
from imubounds.dynamic.estimator.budget import centered_ms_bound
from imubounds.dynamic.estimator.window_plan import LevelPlan
from imubounds.interval import IntervalArray as IA

__all__ = ["abs_dev_integral", "det_mean", "r_abs"]


def det_mean(w: WindowContext, s0: np.ndarray, s1: np.ndarray) -> np.ndarray:
    """Bound of the mean over ``[s0, s1]`` of the gyro_z error's deterministic deviation
    from its own mean: ``2 D + 2 s mean|r| + 2 m (mean|p| + mean|q|)`` (``D`` the
    channel's deterministic bound, ``s`` its scale and ``m`` its misalignment bound)."""
    cn = w.ctx.noise["gyro_z"]
    det = 2 * w.ctx.D_KR["gyro_z"] + 2 * cn.scale * w.mag_mean("gyro_z", s0, s1)
    for other in ("gyro_x", "gyro_y"):
        det = det + 2 * cn.misalignment_rad * w.mag_mean(other, s0, s1)
    return det


def r_abs(w: WindowContext, lp: LevelPlan, tau: np.ndarray) -> np.ndarray:
    """Bound of the kernel mean of |r| (true yaw rate) over each window: the gyro's
    magnitude centred on its own mean error over the window's support (known from
    the heading), plus a bound of the noise's deviation from its mean (Gaussian
    quadratic form); the per-sample bound if the gyro is judged faulty or there is
    no heading. Used only in second-order (transport) terms of the accelerometers."""
    coarse = w.kernel_mag("gyro_z", lp, tau)
    if not w.fine_r or not w.ag.has_heading or not w.imu.available["gyro_z"]:
        return coarse
    s0, s1 = lp.a1, lp.b2
    L = s1 - s0
    sup = LevelPlan(float(np.median(L)), "aided", s0, s0, s1, s1, lp.i, lp.j)
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
    p = w.p_window
    # half the window's probability here, half for the per-gap bound (the smaller of the
    # two is used)
    ms = np.array([centered_ms_bound(cn, int(mm), w.imu.dt, 0.5 * p) for mm in uc])[inv]
    ratio = max(1.0, w.imu.max_len / w.imu.dt)
    det = det_mean(w, s0, s1)
    fine = dev + rad + np.sqrt(ms) * ratio + det
    fine = up(fine * L / tau)
    out = np.minimum(coarse, np.where(np.isfinite(fine), fine, coarse))
    blk = block_r_abs(w, lp, tau, 0.5 * p, det)
    return np.minimum(out, np.where(np.isfinite(blk), blk, out))
