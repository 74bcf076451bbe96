"""gyro_z from the heading (docs/dynamic-method.md, section 3, **gyro_z**): the yaw rate's
kernel mean ``c0 (psi(b) - psi(a))/tau +- rate |c - c0| +- mean|q| tan(phi)``
(:func:`~imubounds.dynamic.estimator.aided.heading.r_from_psidot`), with the tilt
coupling's ``mean|q|`` from gyro_y's window means (:func:`q_window_mean`)."""

from __future__ import annotations

import math

import numpy as np

from imubounds.constants import ROUND_REL
from imubounds.dynamic.estimator.aided.base import up
from imubounds.dynamic.estimator.aided.common import WindowContext
from imubounds.dynamic.estimator.aided.heading import r_from_psidot
from imubounds.dynamic.estimator.aided.transport_blocks import (
    abs_dev_integral,
    block_norm,
    block_r_abs,
    pitch_rate_mean,
)
from imubounds.dynamic.estimator.window_plan import ChannelPlan, LevelPlan
from imubounds.interval import IntervalArray as IA


def q_window_mean(w: WindowContext, lp: LevelPlan, tau: np.ndarray, p: float) -> np.ndarray:
    """Bound of the kernel mean of |q| (true pitch rate) over each window, holding with
    probability ``>= 1 - p`` per window: the smallest of gyro_y's magnitude plus its
    per-sample bound (:meth:`WindowContext.kernel_mag`), gyro_y centred on its window
    mean, and gyro_y centred on blocks (:func:`~imubounds.dynamic.estimator.aided.
    transport_blocks.block_r_abs`), the last two at ``p/2`` each.

    Centred on the window mean ``c`` of gyro_y's samples: its true mean error is
    ``c - mean q``, ``|mean q|`` bounded by
    :func:`~imubounds.dynamic.estimator.aided.transport_blocks.pitch_rate_mean`; the
    noise's deviation from its window mean enters once (Jensen) plus the Gaussian
    concentration term ``sqrt(Lambda dt/tau 2 ln(1/p))`` (one block)."""
    coarse = w.kernel_mag("gyro_y", lp, tau)
    if not w.imu.available["gyro_y"] or lp.a1.size == 0:
        return coarse
    sig = w.imu.sig["gyro_y"]
    ln = np.diff(sig.bnd)
    if np.any(sig.unknown) or float(np.max(ln) - np.min(ln)) > 1e-6 * w.imu.dt:
        return coarse
    s0, s1 = lp.a1, lp.b2
    L = s1 - s0
    ylo, yhi = sig.integral(s0, s1)
    c = np.ascontiguousarray(0.5 * (ylo + yhi) / L)
    crad = up(0.5 * (yhi - ylo) / L)
    dev = abs_dev_integral(sig.bnd, sig.y, sig.unknown, sig.xmax, s0, s1, c) / L
    cn = w.ctx.noise["gyro_y"]
    m = w.imu.count(s0, s1)
    uc, inv = np.unique(m, return_inverse=True)
    lam = np.array([block_norm(cn, int(mm), w.imu.dt) for mm in uc])[inv]
    conc = np.sqrt(lam * w.imu.dt / tau * 2.0 * math.log(2.0 / p))
    det = 2 * w.ctx.D_KR["gyro_y"] + 2 * cn.scale * w.mag_mean("gyro_y", s0, s1)
    for other in ("gyro_x", "gyro_z"):
        det = det + 2 * cn.misalignment_rad * w.mag_mean(other, s0, s1)
    whole = up(((dev + crad + pitch_rate_mean(w, s0, s1) + det) * L / tau + conc) * (1 + ROUND_REL))
    blocks = block_r_abs(w, lp, tau, 0.5 * p, det, ch="gyro_y")
    fine = np.minimum(whole, blocks)
    return np.minimum(coarse, np.where(np.isfinite(fine), fine, coarse))


def gyro_z(w: WindowContext, plan: ChannelPlan, lp: LevelPlan, tau: np.ndarray) -> IA:
    """``[x_W]`` of gyro_z: the yaw rate from the heading at the window ends; the tilt
    coupling ``q tan(phi)`` with gyro_y's window mean of |q| (:func:`q_window_mean`) at
    half the window's probability (the band takes the other half,
    ``windows.MarginBuilder.evaluate``)."""
    ag = w.ag
    p1 = IA(ag.head_c[lp.i] - ag.head_h[lp.i], ag.head_c[lp.i] + ag.head_h[lp.i])
    p2 = IA(ag.head_c[lp.j] - ag.head_h[lp.j], ag.head_c[lp.j] + ag.head_h[lp.j])
    q = q_window_mean(w, lp, tau, 0.5 * w.p_window)
    return r_from_psidot(w, (p2 - p1) / IA(tau), lp, tau, own_q=True, q_mean=q)
