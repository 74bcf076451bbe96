"""gyro_x, gyro_y and accel_z from an attitude stream (docs/dynamic-method.md, section 3,
**gyro_x, gyro_y, accel_z**): boxcar between attitude epochs, from the roll/pitch
differences, with the other axes' magnitudes in second-order terms.

* gyro_x: ``p = phi' + psi' sin(theta)``;
* gyro_y: ``q = -theta' cos(phi) + psi' cos(theta) sin(phi)`` (FLU, pitch nose up);
* accel_z: ``f_z = w' + p v - q u + g cos(phi) cos(theta)``; the mean of ``w'`` over the
  boxcar is ``(w(a2) - w(a1))/tau``, within ``+-2 W/tau`` for a ground vehicle (``W`` the
  vertical body-velocity bound), ``+-max_accel`` otherwise.
"""

from __future__ import annotations

import numpy as np

from imubounds.constants import EARTH_RATE, R_EARTH
from imubounds.dynamic.estimator.aided.base import pm, up
from imubounds.dynamic.estimator.aided.common import WindowContext
from imubounds.dynamic.estimator.aided.heading import heading_at, psi_dot_abs
from imubounds.dynamic.estimator.aided.velocity import body_velocity, ranges
from imubounds.dynamic.estimator.window_plan import ChannelPlan, LevelPlan
from imubounds.interval import IntervalArray as IA


def _ends(w: WindowContext, lp: LevelPlan) -> tuple[IA, IA, IA, IA]:
    """Roll and pitch intervals at the window's two attitude epochs."""
    ag = w.ag
    assert ag.att_roll is not None and ag.att_pitch is not None
    h = ag.att_bound
    r1 = IA(ag.att_roll[lp.i] - h, ag.att_roll[lp.i] + h)
    r2 = IA(ag.att_roll[lp.j] - h, ag.att_roll[lp.j] + h)
    p1 = IA(ag.att_pitch[lp.i] - h, ag.att_pitch[lp.i] + h)
    p2 = IA(ag.att_pitch[lp.j] - h, ag.att_pitch[lp.j] + h)
    return r1, r2, p1, p2


def _earth_rate(w: WindowContext) -> IA:
    return pm(EARTH_RATE + w.veh.max_speed / R_EARTH)


def q_mean(w: WindowContext, lp: LevelPlan, tau: np.ndarray, p1: IA, p2: IA) -> IA:
    """Kernel mean of q = -pitch' cos(roll) + psi' cos(pitch) sin(roll) (FLU body, pitch
    positive nose up: a nose-up pitch rate is a negative rate about body y)."""
    c = w.tilt.hull("cosr", lp.a1, lp.b2)
    c0 = c.mid()
    cdev = up(np.maximum(c.hi - c0, c0 - c.lo))
    supp = lp.b2 - lp.a1
    rate = up(w.veh.max_rate * supp / tau)
    psid = up(psi_dot_abs(w, lp.a1, lp.b2, own_q=False) * supp / tau)
    coupling = _psidot_times(w, lp, tau, psid, "sinr_cosp", own_q=False)
    return (p1 - p2) / IA(tau) * IA(c0) + pm(rate * cdev) + coupling


def _psidot_times(
    w: WindowContext, lp: LevelPlan, tau: np.ndarray, psid: np.ndarray, f: str, own_q: bool
) -> IA:
    """Kernel mean of ``psi' f`` (boxcar ``[a1, a2]``, ``f`` a tilt function: ``sinp`` or
    ``sinr_cosp``): ``+- mean|psi'| max|f|``, intersected where there is a heading with
    ``f0 (psi(a2) - psi(a1))/tau +- mean|psi'| max|f - f0|`` (``f0`` the middle of f over
    the window): the yaw rate's mean from the heading, only f's variation times |psi'|.
    ``own_q`` False: the heading between its epochs without gyro_y's magnitude."""
    h = w.tilt.hull(f, lp.a1, lp.b2)
    out = pm(psid * up(np.maximum(np.abs(h.lo), np.abs(h.hi))))
    if not w.ag.has_heading:
        return out
    f0 = h.mid()
    df = up(np.maximum(h.hi - f0, f0 - h.lo))
    mean_psid = (heading_at(w, lp.a2, own_q) - heading_at(w, lp.a1, own_q)) / IA(tau)
    alt = mean_psid * IA(f0) + pm(psid * df)
    lo = np.maximum(out.lo, alt.lo)
    hi = np.minimum(out.hi, alt.hi)
    ok = np.isfinite(lo) & np.isfinite(hi) & (lo <= hi)
    return IA(np.where(ok, lo, out.lo), np.where(ok, hi, out.hi))


def gyro_x(w: WindowContext, plan: ChannelPlan, lp: LevelPlan, tau: np.ndarray) -> IA:
    """``[x_W]`` of gyro_x: ``p = roll' + psi' sin(pitch)``."""
    r1, r2, _, _ = _ends(w, lp)
    supp = lp.b2 - lp.a1
    psid = up(psi_dot_abs(w, lp.a1, lp.b2) * supp / tau)
    coupling = _psidot_times(w, lp, tau, psid, "sinp", own_q=True)
    return (r2 - r1) / IA(tau) + coupling + _earth_rate(w)


def gyro_y(w: WindowContext, plan: ChannelPlan, lp: LevelPlan, tau: np.ndarray) -> IA:
    """``[x_W]`` of gyro_y: :func:`q_mean` plus the Earth rate."""
    _, _, p1, p2 = _ends(w, lp)
    return q_mean(w, lp, tau, p1, p2) + _earth_rate(w)


def accel_z(w: WindowContext, plan: ChannelPlan, lp: LevelPlan, tau: np.ndarray) -> IA:
    """``[x_W]`` of accel_z: ``w' + p v - q u + g cos(roll) cos(pitch)``."""
    veh = w.veh
    _, _, p1, p2 = _ends(w, lp)
    q = q_mean(w, lp, tau, p1, p2)
    supp = lp.b2 - lp.a1
    rng = ranges(w, lp, body_velocity(w))
    u0 = 0.5 * (rng["u_lo"] + rng["u_hi"])
    du = up(0.5 * (rng["u_hi"] - rng["u_lo"]))
    qu = IA(u0) * q + pm(du * w.kernel_mag("gyro_y", lp, tau))
    pv = pm(rng["v_max"] * w.kernel_mag("gyro_x", lp, tau))
    grav = w.tilt.kmean("g_cosr_cosp", lp, tau)
    x = pv - qu + grav + pm(2 * EARTH_RATE * veh.max_speed)
    if veh.kind != "ground":
        x = x + pm(veh.max_accel * supp / tau)
    elif veh.vertical_bound > 0:
        # the boxcar mean of w' is (w(a2) - w(a1))/tau: heave over bumps (|w| <= W)
        x = x + pm(up(2.0 * veh.vertical_bound / tau))
    return x
