"""The pieces accel_y's transport forms share (docs/dynamic-method.md, section 3,
**accel_y**): the tilt and rate terms of r (:func:`rate_terms`), the speed part over
gaps or blocks (:func:`speed_part`) and the heading sums by parts (:func:`by_parts`)."""

from __future__ import annotations

import math

import numpy as np

from imubounds.constants import EPS_UP as EPS
from imubounds.dynamic.estimator.aided.base import earth_rates, up
from imubounds.dynamic.estimator.aided.common import WindowContext
from imubounds.dynamic.estimator.window_plan import LevelPlan
from imubounds.interval import IntervalArray as IA

#: the levels d0 of the speed part: quantiles of the gaps' half-ranges of u
SPEED_LEVELS = (0.25, 0.5, 0.65, 0.75, 0.85, 0.9, 0.95, 0.97, 0.99)


def rate_terms(
    w: WindowContext, lp: LevelPlan, tau: np.ndarray, q_mean: np.ndarray | None
) -> tuple[np.ndarray, np.ndarray, float]:
    """``c0``, the radius of ``r - c0 psi'`` and the Earth's share of the gyro's rate.

    In ``f_y = v' + r u + ...`` r is the body's rate relative to the navigation frame,
    ``psi' c - q_nb tan(phi)`` (c = cos(theta)/cos(phi) within ``c0 +- cdev``); the
    Earth's rotation and the transport rate enter through the Coriolis term of
    :func:`~imubounds.dynamic.estimator.aided.horizontal.horizontal_terms`, so unlike
    gyro_z's :func:`~imubounds.dynamic.estimator.aided.heading.r_from_psidot` no Earth
    rate is added to r here. The gyros measure the inertial rates: ``|q_nb| <= |q| +
    earth`` and ``|r_nb| <= |r| + earth``, ``earth = Omega + max_speed/R_E``."""
    veh = w.veh
    c = w.tilt.hull("cosp_over_cosr", lp.a1, lp.b2)
    c0 = c.mid()
    cdev = up(np.maximum(c.hi - c0, c0 - c.lo))
    rate = veh.max_rate / math.cos(veh.max_tilt)
    q = w.kernel_mag("gyro_y", lp, tau) if q_mean is None else q_mean
    earth = earth_rates(veh)
    tr = w.tilt.hull("abs_tanr", lp.a1, lp.b2).hi
    ext = up(up(rate * cdev) + up(up(q + earth) * tr))
    return c0, ext, earth

def speed_part(
    w: WindowContext,
    gwin: np.ndarray,
    ga: np.ndarray,
    gb: np.ndarray,
    du: np.ndarray,
    n: int,
    tau: np.ndarray,
    r_mag: np.ndarray,
    earth: float,
) -> np.ndarray:
    """Bound of ``(1/tau) sum_k du_k int_k |r|`` over each window's gaps (``du_k`` the
    half-range of u on gap k, ``gwin`` each gap's window): for a level ``d0``,
    ``du_k <= d0 + (du_k - d0)+``, so the sum is at most ``d0 mean|r| + (1/tau) sum_k
    (du_k - d0)+ int_k |r|``, ``mean|r| <= r_mag`` and ``int_k |r|`` by the gyro's
    magnitude on the gap; the smallest over a few levels ``d0`` (quantiles of ``du``,
    its maximum included, which gives ``max du x r_mag``). r is relative to the
    navigation frame: the gyro's bounds plus ``earth`` (:func:`rate_terms`)."""
    r_mag = up(r_mag + earth)
    dmax = np.zeros(n)
    np.maximum.at(dmax, gwin, du)
    best = up(dmax * r_mag)
    if du.size == 0:
        return best
    coarse = up(up(w.gyro_abs_mean("gyro_z", ga, gb) + earth) * (gb - ga))
    for d0 in np.quantile(du, SPEED_LEVELS):
        ex = np.zeros(n)
        np.add.at(ex, gwin, up(np.maximum(du - d0, 0.0) * coarse))
        cand = up((d0 * r_mag + up(ex * (1 + 1e-12)) / tau) * (1 + 1e-12))
        best = np.minimum(best, cand)
    return best

def by_parts(
    coef: np.ndarray, gw: np.ndarray, gk: np.ndarray, psi_start: IA, psi_end: IA,
    group: np.ndarray,
) -> IA:
    """``sum_k coef_k (psi_k+1 - psi_k)`` per group of consecutive gaps (``group`` the
    gap's group, ascending), each heading box once: ``sum_j psi_j (coef_j-1 - coef_j)``
    plus the group's last fix with ``coef_last``. ``psi_start`` the heading at each gap's
    first fix, ``psi_end`` at each gap's last."""
    same = np.r_[False, group[1:] == group[:-1]]
    prev = np.where(same, np.r_[0.0, coef[:-1]], 0.0)
    term = IA(prev - coef) * psi_start
    last = np.r_[group[1:] != group[:-1], True]
    term = term + IA(np.where(last, coef, 0.0)) * psi_end
    start = np.flatnonzero(np.r_[True, group[1:] != group[:-1]])
    lo = np.add.reduceat(term.lo, start)
    hi = np.add.reduceat(term.hi, start)
    mag = np.add.reduceat(np.maximum(np.abs(term.lo), np.abs(term.hi)), start)
    cnt = np.add.reduceat(np.ones(group.size), start)
    guard = up((cnt + 4) * EPS * 4 * mag + 1e-300)
    return IA(lo - guard, hi + guard)
