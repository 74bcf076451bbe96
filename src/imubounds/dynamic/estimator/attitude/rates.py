"""gyro_x and gyro_y from pairs of accelerometer windows (docs/dynamic-method.md,
section 3b, (3b.8)): with ``h = (sin theta, sin phi cos theta)`` (what accel_x and
accel_y measure of gravity, over g) and ``h' = r J h + (-q, p) u_z``,

    p = (h_y' + r h_x) / u_z,     q = (r h_y - h_x') / u_z,

so over the triangle kernel ``K`` of two adjacent windows ``W1 = [a, b]``, ``W2 = [b, c]``
of the accelerometer's plan (``tau`` = the distance of their midpoints)::

    int K h' = (mean_W2 h - mean_W1 h) / tau
             = ((y_W2 - y_W1) - (k_W2 - k_W1) -+ chg) / (g tau),

``y`` the accelerometer's window means, ``k`` their kinematic parts (the margins'),
``chg`` the change band of the pair (the turn-on bias cancels: no absolute tilt, no
gyro). The coupling ``int K r h_other`` is ``c0 [y_r]_K +- (rad(H) mean_K|y_r| + max|H|
E0_r)`` with ``H`` the other component's hull over the support from the channel's
variant (the prior: never this gyro), and ``1/u_z - 1`` (the tilt's cosines) times the
gyro's own magnitude bound (a second-order term); plus the Earth's rates. The gyro
judged never enters but through that second-order term."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from imubounds.constants import EARTH_RATE, G_HI, G_LO, R_EARTH
from imubounds.dynamic.estimator.aided.base import pm, up
from imubounds.dynamic.estimator.band import change_band
from imubounds.dynamic.estimator.window_plan import ChannelPlan, LevelPlan
from imubounds.interval import IntervalArray as IA

#: the triangle windows are used where gyro_z's per-sample error bound is at most this
#: (rad/s): above it the coupling ``r h`` over the triangle's support (twice the
#: kernel's 1/tau) is wider than the boxcar windows' between the states' nodes
MAX_E0_R = 0.02
#: the accelerometer whose windows judge each gyro, and the sign of int K h' in it
ACCEL_OF = {"gyro_x": ("accel_y", 1.0, "sinp"), "gyro_y": ("accel_x", -1.0, "sinr_cosp")}


@dataclass
class PairPlan(ChannelPlan):
    """A gyro's windows: the triangles of its accelerometer's adjacent window pairs."""

    accel: str = ""
    #: per level: (accelerometer level index, its level plan)
    pairs: dict[int, tuple[int, LevelPlan]] = field(default_factory=dict)

    def constraint(self, w: Any, lp: LevelPlan, tau: np.ndarray) -> IA:
        return gyro_from_pairs(w, self, lp, tau)


def pair_plan(plans: dict[str, ChannelPlan], ch: str, e0_r: float) -> PairPlan | None:
    """The triangle windows of ``ch`` (gyro_x or gyro_y) from its accelerometer's boxcar
    levels with adjacent pairs; None when there are none or gyro_z's per-sample bound
    ``e0_r`` exceeds :data:`MAX_E0_R`."""
    if e0_r > MAX_E0_R:
        return None
    acc = ACCEL_OF[ch][0]
    plan = plans.get(acc)
    if plan is None or plan.trapezoid or not plan.levels:
        return None
    out = PairPlan(ch, f"{acc} window pairs (attitude states)", plan.epochs, True, accel=acc)
    for li, lp in enumerate(plan.levels):
        if lp.kind != "aided" or lp.n_pairs == 0:
            continue
        p1, p2 = lp.p1, lp.p2
        new = LevelPlan(lp.tau_s, "aided", lp.a1[p1], lp.a2[p1], lp.a1[p2], lp.a2[p2],
                        lp.i[p1], lp.j[p2])
        out.pairs[id(new)] = (li, lp)
        out.levels.append(new)
    return out if out.levels else None


def gyro_from_pairs(w: Any, plan: PairPlan, lp: LevelPlan, tau: np.ndarray) -> IA:
    """``[x_W]`` of gyro_x or gyro_y over the triangle windows (module docstring)."""
    ch = plan.channel
    acc, sign, other = ACCEL_OF[ch]
    li, la = plan.pairs[id(lp)]
    ctx = w.ctx
    kin = w.kin_cache.get((acc, id(la)))
    if kin is None:  # the accelerometer's margins have not been built: no constraint
        return pm(np.full(lp.n, w.veh.max_rate))
    y = w.imu_mean(acc, la, la.tau)
    gc = ctx.level_index_changes[(acc, li)]
    chg = change_band(w, acc, la, la.tau, ctx.alpha.k_level("imu_changes", gc))
    p1, p2 = la.p1, la.p2
    d = (y[p2] - kin[p2]) - (y[p1] - kin[p1]) + pm(chg)
    main = d / IA(G_LO, G_HI) / IA(tau)
    # the coupling r h_other, h_other within the channel variant's hull
    H = w.tilt.hull(other, lp.a1, lp.b2)
    c0 = H.mid()
    rad = up(0.5 * (H.hi - H.lo))
    hmax = np.maximum(np.abs(H.lo), np.abs(H.hi))
    yr = w.imu_mean("gyro_z", lp, tau)
    coup = IA(c0) * yr + pm(rad * w.kernel_mag("gyro_z", lp, tau) + hmax * ctx.E0["gyro_z"])
    # 1 / u_z - 1 with u_z = cos(phi) cos(theta) over the support
    cr = w.tilt.hull("cosr", lp.a1, lp.b2).lo
    sec = 1.0 + w.tilt.hull("sec_p_minus_1", lp.a1, lp.b2).hi
    f = up(sec / np.maximum(cr, 1e-9) - 1.0)
    slack = up(f * w.kernel_mag(ch, lp, tau))
    earth = EARTH_RATE + w.veh.max_speed / R_EARTH
    x = IA(sign) * main + coup + pm(slack + earth)
    # the same kernel mean from the variant's angles: mean_W in the hull over W
    alt = _from_angles(w, ch, lp, tau) + pm(earth)
    lo, hi = np.maximum(x.lo, alt.lo), np.minimum(x.hi, alt.hi)
    ok = lo <= hi
    return IA(np.where(ok, lo, x.lo), np.where(ok, hi, x.hi))


def _from_angles(w: Any, ch: str, lp: LevelPlan, tau: np.ndarray) -> IA:
    """``int K p = (mean_W2 phi - mean_W1 phi) / tau + int K psi' sin(theta)`` and
    ``int K q = -int K theta' cos(phi) + int K psi' cos(theta) sin(phi)`` with each mean
    in the angle's hull over its window (the channel's variant) and ``|psi'|`` from the
    other gyros' magnitudes (``aided.heading.psi_dot_abs``, without this one's)."""
    from imubounds.dynamic.estimator.aided.heading import psi_dot_abs

    supp = lp.b2 - lp.a1
    own_q = ch != "gyro_y"
    psid = up(psi_dot_abs(w, lp.a1, lp.b2, own_q=own_q) * supp / tau)
    if ch == "gyro_x":
        r1, r2 = w.tilt.hull("roll", lp.a1, lp.b1), w.tilt.hull("roll", lp.a2, lp.b2)
        f = w.tilt.hull("abs_sinp", lp.a1, lp.b2).hi
        return (r2 - r1) / IA(tau) + pm(psid * f)
    p1, p2 = w.tilt.hull("pitch", lp.a1, lp.b1), w.tilt.hull("pitch", lp.a2, lp.b2)
    c = w.tilt.hull("cosr", lp.a1, lp.b2)
    c0 = c.mid()
    cdev = up(np.maximum(c.hi - c0, c0 - c.lo))
    rate = up(w.veh.max_rate * supp / tau)
    f = w.tilt.hull("abs_sinr", lp.a1, lp.b2).hi
    return (p1 - p2) / IA(tau) * IA(c0) + pm(rate * cdev + psid * f)
