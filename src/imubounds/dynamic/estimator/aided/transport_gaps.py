"""accel_y's transport term ``mean(r u)`` over boxcar windows with velocity epochs, cut at
the heading epochs inside (docs/dynamic-method.md, section 3, **accel_y**, (3.16)–(3.18)):
:func:`gap_parts` (the heading and rate part, and the speed part's inputs), the speed
part's two forms :func:`speed_levels` and
:func:`~imubounds.dynamic.estimator.aided.transport_weighted.weighted_speed` (the
registry's ``accel_y.gap_speed`` table, :mod:`.form_tables`), and
:func:`transport_by_gaps`, the form with the smaller of the two.

On gap k, ``u = u0_k + (u - u0_k)`` with ``u0_k`` the centre of u's range over the gap
(:func:`~imubounds.dynamic.estimator.aided.velocity.vel_range`), so ``tau mean(r u) =
sum_k u0_k int_k r + sum_k int_k (u - u0_k) r``. With ``r = psi' c - q tan(phi)`` (c
within ``c0 +- cdev``): the first sum is ``c0 sum_k u0_k (psi_k+1 - psi_k)`` (by parts:
``sum_j psi_j w_j`` with ``w_j = u0_j-1 - u0_j``, so each heading box enters once,
weighted by the CHANGE of u0, not twice by u0) plus ``max|u0| tau (rate cdev + (mean|q| +
earth) tan)`` (:func:`~.transport_terms.rate_terms`: r relative to the navigation frame,
the Earth's rates in the Coriolis term); the second within ``sum_k half-range_k(u) int_k
|r|`` (the speed part). The per-window sums: :func:`.gap_sums.gap_sums` (compiled; the
gaps between heading epochs computed once per run).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from imubounds.constants import EPS_UP as EPS
from imubounds.dynamic.estimator.aided.base import pm, up
from imubounds.dynamic.estimator.aided.common import WindowContext
from imubounds.dynamic.estimator.aided.gap_sums import gap_sums
from imubounds.dynamic.estimator.aided.heading import heading_at
from imubounds.dynamic.estimator.aided.transport_terms import SPEED_LEVELS, rate_terms
from imubounds.dynamic.estimator.aided.transport_weighted import gap_weights, weighted_speed
from imubounds.dynamic.estimator.aided.velocity import vel_range
from imubounds.dynamic.estimator.window_plan import LevelPlan
from imubounds.interval import IntervalArray as IA


def _knot_rows(w: WindowContext, t: np.ndarray) -> np.ndarray:
    """Rows ``(m, rho, ok)`` of the heading at ``t``: centre (0 where unbounded), radius
    rounded up (inf there) and 1.0 where finite."""
    psi = heading_at(w, t)
    ok = np.isfinite(psi.lo) & np.isfinite(psi.hi)
    m = np.where(ok, psi.mid(), 0.0)
    rho = np.where(ok, up(np.maximum(psi.hi - m, m - psi.lo)), np.inf)
    return np.column_stack([m, rho, ok.astype(float)])


def gap_rows(w: WindowContext, bv: Any, ga: np.ndarray, gb: np.ndarray) -> np.ndarray:
    """Rows ``(u0, max|u|, du)`` of u over the gaps ``[ga, gb]``: centre, magnitude and
    half-range rounded up (:func:`~imubounds.dynamic.estimator.aided.velocity.vel_range`)."""
    rng = vel_range(w, bv, ga, gb)
    ulo, uhi = rng["u_lo"], rng["u_hi"]
    u0 = 0.5 * (ulo + uhi)
    du = up(np.maximum(uhi - u0, u0 - ulo))
    return np.column_stack([u0, np.maximum(np.abs(ulo), np.abs(uhi)), du])


def _gap_terms(
    w: WindowContext, ga: np.ndarray, gb: np.ndarray, du: np.ndarray, d0: np.ndarray,
    earth: float,
) -> np.ndarray:
    """Per gap and level d0: ``(du - d0)+ int |r|``, ``int |r|`` by the gyro's magnitude on
    the gap (+ the Earth's rates), each rounded up."""
    coarse = up(up(w.gyro_abs_mean("gyro_z", ga, gb) + earth) * (gb - ga))
    return up(np.maximum(du[:, None] - d0[None, :], 0.0) * coarse[:, None])


def speed_levels_bound(
    dmax: np.ndarray, ex: np.ndarray, d0: np.ndarray, tau: np.ndarray, r_mag: np.ndarray,
    earth: float,
) -> np.ndarray:
    """Bound of ``(1/tau) sum_k du_k int_k |r|`` over each window's gaps (``du_k`` the
    half-range of u on gap k): for a level ``d0``, ``du_k <= d0 + (du_k - d0)+``, so the
    sum is at most ``d0 mean|r| + (1/tau) sum_k (du_k - d0)+ int_k |r|`` (``ex``, per
    level), ``mean|r| <= r_mag`` and ``int_k |r|`` by the gyro's magnitude on the gap; the
    smallest over the levels ``d0`` (quantiles of every window's gaps' ``du``) and
    ``max du x r_mag`` (``dmax``). r is relative to the navigation frame: the gyro's
    bounds plus ``earth`` (:func:`rate_terms`)."""
    r_mag = up(r_mag + earth)
    best = up(dmax * r_mag)
    for d in range(d0.size):
        cand = up((d0[d] * r_mag + up(ex[:, d] * (1 + 1e-12)) / tau) * (1 + 1e-12))
        best = np.minimum(best, cand)
    return best


def _trip_gaps(w: WindowContext, bv: Any) -> tuple[np.ndarray, np.ndarray]:
    """The heading epochs' knot rows and the rows of the gaps between consecutive heading
    epochs (the same for every window: computed once per run)."""
    key = "accel_y_trip_gaps"
    if key not in w.cache:
        ht = w.ag.head_t
        w.cache[key] = (_knot_rows(w, ht), gap_rows(w, bv, ht[:-1], ht[1:]))
    return w.cache[key]


def window_gaps(
    ht: np.ndarray, a: np.ndarray, b: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Windows ``[a, b]`` cut at the heading epochs ``ht``: they hold ``ht[k0 .. k1-1]``;
    the first gap is ``[a, fb]`` (``fb = ht[k0]``, ``b`` without an epoch inside), the
    last ``[la, b]`` (``la = ht[k1 - 1]``, only used where there is an epoch inside)."""
    k0 = np.searchsorted(ht, a, side="right")
    k1 = np.maximum(np.searchsorted(ht, b, side="left"), k0)
    has = k1 > k0
    last = ht.size - 1
    fb = np.where(has, ht[np.minimum(k0, last)], b)
    la = np.where(has, ht[np.clip(k1 - 1, 0, last)], a)
    return k0, k1, fb, la


def weighted_floors(
    w: WindowContext, bv: Any, a: np.ndarray, b: np.ndarray, fb: np.ndarray,
    la: np.ndarray, has: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The floors ``(fb, wf, la, wl)`` of :func:`.transport_weighted.weighted_speed`: the
    gyro-free half-ranges of u on each window's first and last gaps (``la = +inf``
    where the window holds no heading epoch: its one gap is the first)."""
    wf = gap_weights(w, bv, a, fb)
    wl = np.where(has, gap_weights(w, bv, la, b), 0.0)
    return fb, wf, np.where(has, la, np.inf), wl


@dataclass
class GapParts:
    """What :func:`gap_parts` leaves to the speed part: the heading and rate part
    ``head`` (an enclosure, +-inf where a heading box is unbounded), the speed part's
    ``dmax``, ``ex`` and levels ``d0`` (:func:`speed_levels_bound`), each window's first
    gap's end ``fb``, last gap's start ``la`` and whether it holds a heading epoch (for
    the weighted form's floors, :meth:`floors`) and the Earth's rates."""

    head: IA
    ok: np.ndarray
    dmax: np.ndarray
    ex: np.ndarray
    d0: np.ndarray
    fb: np.ndarray
    la: np.ndarray
    has: np.ndarray
    earth: float

    def floors(
        self, w: WindowContext, bv: Any, lp: LevelPlan
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """:func:`weighted_floors` of the windows."""
        return weighted_floors(w, bv, lp.a1, lp.b2, self.fb, self.la, self.has)

    def enclosure(self, speed: np.ndarray) -> IA:
        """``head +- speed``, unbounded where a heading box is."""
        x = self.head + pm(speed)
        return IA(np.where(self.ok, x.lo, -np.inf), np.where(self.ok, x.hi, np.inf))


def gap_parts(
    w: WindowContext,
    lp: LevelPlan,
    tau: np.ndarray,
    bv: Any,
    q_mean: np.ndarray | None = None,
) -> GapParts:
    """The per-heading-gap decomposition of ``mean(r u)`` (module docstring) but the speed
    part: the heading sums by parts, ``max|u0| ext`` and the speed part's inputs."""
    a, b = lp.a1, lp.b2
    ht = w.ag.head_t
    k0, k1, fb, la = window_gaps(ht, a, b)
    ni = k1 - k0
    knot_h, gap_g = _trip_gaps(w, bv)
    has = ni >= 1
    gap_f = gap_rows(w, bv, a, fb)
    gap_l = gap_rows(w, bv, la, b)
    # the levels d0: quantiles of the half-ranges of every window's gaps (as a multiset:
    # the inner gap g counts once per window holding it)
    inner = ni >= 2
    cnt = np.zeros(ht.size, dtype=np.int64)
    np.add.at(cnt, k0[inner], 1)
    np.add.at(cnt, k1[inner] - 1, -1)
    cnt = np.cumsum(cnt)[: max(ht.size - 1, 0)]
    c0, ext, earth = rate_terms(w, lp, tau, q_mean)
    dus = np.concatenate([np.repeat(gap_g[:, 2], cnt), gap_f[:, 2], gap_l[has, 2]])
    d0 = np.quantile(dus, SPEED_LEVELS)
    del dus
    ex_g = _gap_terms(w, ht[:-1], ht[1:], gap_g[:, 2], d0, earth)
    ex_f = _gap_terms(w, a, fb, gap_f[:, 2], d0, earth)
    ex_l = _gap_terms(w, la, b, gap_l[:, 2], d0, earth)
    cen, rad, mag, ok, umax, dmax, ex = gap_sums(
        k0.astype(np.int64), k1.astype(np.int64), _knot_rows(w, a), _knot_rows(w, b),
        knot_h, gap_f, gap_l, gap_g, ex_f, ex_l, ex_g)
    nk = ni + 2
    rad = up((rad + (nk + 6) * EPS * 4 * mag + 1e-300) * (1 + 1e-12))
    head = (IA(cen) + pm(np.where(ok, rad, 0.0))) / IA(tau) * IA(c0) + pm(up(umax * ext))
    return GapParts(head, ok, dmax, ex, d0, fb, la, has, earth)


def speed_levels(parts: GapParts, tau: np.ndarray, r_mag: np.ndarray) -> np.ndarray:
    """The speed part by levels (:func:`speed_levels_bound`) of :func:`gap_parts`'s
    decomposition: no probability of its own (``r_mag`` holds at its own)."""
    return speed_levels_bound(parts.dmax, parts.ex, parts.d0, tau, r_mag, parts.earth)


def transport_by_gaps(
    w: WindowContext,
    lp: LevelPlan,
    tau: np.ndarray,
    bv: Any,
    r_mag: np.ndarray,
    q_mean: np.ndarray | None = None,
    p_weighted: float = 0.0,
) -> IA:
    """``mean(r u)`` over boxcar windows, cut at the heading epochs inside (module
    docstring): the speed part by levels (:func:`speed_levels`), or with ``p_weighted >
    0`` the smaller of that and the weighted bound of
    :func:`.transport_weighted.weighted_speed` (holding with probability ``>= 1 -
    p_weighted`` per window: the gyro centred on blocks of heading gaps, each sample's
    |r| weighted by its gap's half-range)."""
    if lp.a1.size == 0:
        return IA(np.zeros(0), np.zeros(0))
    parts = gap_parts(w, lp, tau, bv, q_mean)
    speed = speed_levels(parts, tau, r_mag)
    if p_weighted > 0:
        floors = parts.floors(w, bv, lp)
        ws = weighted_speed(w, lp, tau, bv, p_weighted, floors, parts.earth)
        speed = np.minimum(speed, ws)
    return parts.enclosure(speed)
