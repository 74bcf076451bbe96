"""The forms of the bound of the kernel mean of |q| (true pitch rate) besides gyro_y's
magnitude (docs/dynamic-method.md, section 3, **gyro_z**, (3.10); the registry's
``mean_abs_q`` table, :mod:`.form_tables`): gyro_y centred on its window mean
(:func:`q_centred_window`) and on blocks of seconds
(:func:`~imubounds.dynamic.estimator.aided.transport_blocks.block_bound`).

Centred on the window mean ``c`` of gyro_y's samples: its true mean error is ``c - mean
q``, ``|mean q|`` bounded by
:func:`~imubounds.dynamic.estimator.aided.transport_blocks.pitch_rate_mean`; the noise's
deviation from its window mean enters once (Jensen) plus the Gaussian concentration term
``sqrt(Lambda dt/tau 2 ln(1/p))`` (one block).
"""

from __future__ import annotations

import math

import numpy as np

from imubounds.dynamic.estimator.aided.base import up
from imubounds.dynamic.estimator.aided.common import WindowContext
from imubounds.dynamic.estimator.aided.transport_blocks import (
    abs_dev_integral,
    block_norm,
    pitch_rate_mean,
)
from imubounds.dynamic.estimator.window_plan import LevelPlan


def q_centred_applies(w: WindowContext) -> bool:
    """gyro_y recorded on regular samples without gaps."""
    if not w.imu.available["gyro_y"]:
        return False
    sig = w.imu.sig["gyro_y"]
    ln = np.diff(sig.bnd)
    return not (np.any(sig.unknown) or float(np.max(ln) - np.min(ln)) > 1e-6 * w.imu.dt)


def q_det(w: WindowContext, s0: np.ndarray, s1: np.ndarray) -> np.ndarray:
    """Bound of the mean over ``[s0, s1]`` of gyro_y's error's deterministic deviation
    from its own mean (as :func:`~.transport.det_mean` for gyro_z)."""
    cn = w.ctx.noise["gyro_y"]
    det = 2 * w.ctx.D_KR["gyro_y"] + 2 * cn.scale * w.mag_mean("gyro_y", s0, s1)
    for other in ("gyro_x", "gyro_z"):
        det = det + 2 * cn.misalignment_rad * w.mag_mean(other, s0, s1)
    return det


def q_centred_window(
    w: WindowContext, lp: LevelPlan, tau: np.ndarray, p: float, det: np.ndarray
) -> np.ndarray:
    """gyro_y centred on its window mean (module docstring), holding with probability
    ``>= 1 - p`` per window; +inf where not finite."""
    sig = w.imu.sig["gyro_y"]
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
    conc = np.sqrt(lam * w.imu.dt / tau * 2.0 * math.log(1.0 / p))
    whole = up(((dev + crad + pitch_rate_mean(w, s0, s1) + det) * L / tau + conc) * (1 + 1e-12))
    return np.where(np.isfinite(whole), whole, np.inf)
