"""The speed part of accel_y's transport term over the heading gaps, with the gyro centred
on blocks of heading gaps (docs/dynamic-method.md, section 3, **accel_y**).

:func:`~imubounds.dynamic.estimator.aided.transport_gaps.transport_by_gaps` bounds ``(1/tau)
sum_k int_k (u - u0_k) r`` by ``(1/tau) sum_k du_k int_k |r|`` (``du_k`` u's half-range
on heading gap k). Bounding ``int_k |r|`` by the window's mean |r| times the largest
``du_k`` loses where the half-ranges differ; here the sum is bounded as one weighted
mean: with per-sample weights ``om_i >= du_k`` of every gap k that sample i meets, it is
at most ``(1/tau) sum_i om_i int_i |r|``, bounded as in
:func:`~imubounds.dynamic.estimator.aided.transport_blocks.block_bound` with the kernel
weights ``w_i`` multiplied by ``om_i``:

With ``y_i - e_g = z_i + n_i`` on block g (``e_g`` the block's true mean error, ``z =
r + d``, ``d`` the deterministic deviation from it, ``n`` the noise's deviation from its
block mean) and ``w_i`` the kernel's weight of sample i (its overlap with the window
over tau):

* ``sum_i om_i w_i |z_i| <= E F(n)``, ``F(n) = sum_i om_i w_i |z_i + n_i|`` (Jensen,
  ``n`` zero-mean; the weights must not depend on the noise: ``om`` comes from the
  aiding and the vehicle's bounds alone, :func:`~.velocity.gyro_free_u` and the growth
  without the IMU's magnitudes);
* ``F`` is Lipschitz in the standard normal vector behind ``n`` with constant
  ``sqrt(sum (om_i w_i)^2) sqrt(Lambda)`` (``Lambda >= ||P C P||``,
  :func:`~.transport_blocks.block_norm`), and ``w_i <= l_max/tau`` gives ``sum (om_i
  w_i)^2 <= (l_max/tau^2) sum om_i^2 x overlap_i``: at most the sum of ``om_i^2 l_i``
  over every sample the window touches plus each floor squared over its span and a
  sample; so ``E F <= F(n) + sqrt(that Lambda 2 ln(1/p))`` with probability ``>= 1 - p``
  (Gaussian concentration);
* ``F(n) = sum_i om_i w_i |y_i - e_g|`` is convex in each block's ``e_g`` (in ``c_g +-
  rad_g`` from the heading): at most the sum over the blocks of its larger value at
  the two ends of the block's box;
* ``|r| <= |z| + |d|`` adds ``om_max`` times the bound of the mean |d| (``det_mean``),
  and ``|r_nb| <= |r| + earth`` ``om_max earth``.

The samples in the window's first and last partial gaps take the larger of their table
weight and those gaps' half-ranges (the floors ``wf``, ``wl``): in the pieces at the
window's ends directly, in a full block reaching into such a gap through the excess
``(floor - min om)+`` (:func:`_floor_excess`).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from imubounds.dynamic.estimator.aided.base import up
from imubounds.dynamic.estimator.aided.common import WindowContext
from imubounds.dynamic.estimator.aided.transport import det_mean
from imubounds.dynamic.estimator.aided.transport_blocks import block_tables, weighted_abs_dev
from imubounds.dynamic.estimator.aided.velocity import gyro_free_u, vel_range
from imubounds.dynamic.estimator.inputs import RangeExt
from imubounds.dynamic.estimator.window_plan import LevelPlan

#: the block lengths (in heading gaps) tried here, the probability split over them
WEIGHTED_BLOCKS = (4,)


def gap_weights(w: WindowContext, bv: Any, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Half-ranges of u over ``[a, b]`` from the gyro-free u at the epochs and the
    vehicle's growth (:func:`~.velocity.vel_range` with ``tv`` False), rounded up: at
    least the half-range :func:`~.accel_y._gap_rows` gives (a wider hull at the epochs,
    the growth without the IMU's smaller total variation); +inf without a gyro-free u."""
    bf = gyro_free_u(w, bv)
    if bf is None:
        return np.full(np.shape(a), np.inf)
    rng = vel_range(w, bf, a, b, tv=False)
    ulo, uhi = rng["u_lo"], rng["u_hi"]
    u0 = 0.5 * (ulo + uhi)
    return up(np.maximum(uhi - u0, u0 - ulo))


def _sample_weights(w: WindowContext, bv: Any) -> tuple[np.ndarray, Any, np.ndarray] | None:
    """Per gyro_z sample, the largest :func:`gap_weights` of the heading gaps it meets (0
    outside the heading epochs: the floors cover the window's partial gaps there), a
    range table of them and the prefix sums of ``om^2 l`` (each rounded up); None
    without finite weights. Computed once."""
    key = "accel_y_weights"
    if key in w.cache:
        return w.cache[key]
    ht = w.ag.head_t
    out = None
    if ht.size >= 2:
        dg = gap_weights(w, bv, ht[:-1], ht[1:])
        if np.all(np.isfinite(dg)):
            bnd = w.imu.sig["gyro_z"].bnd
            ng = dg.size
            g0 = np.searchsorted(ht, bnd[:-1], side="right") - 1
            g1 = np.searchsorted(ht, bnd[1:], side="left") - 1
            ok0 = (g0 >= 0) & (g0 < ng)
            ok1 = (g1 >= 0) & (g1 < ng)
            om = np.maximum(np.where(ok0, dg[np.clip(g0, 0, ng - 1)], 0.0),
                            np.where(ok1, dg[np.clip(g1, 0, ng - 1)], 0.0))
            # a sample spanning several gaps (longer than a gap): the largest of them
            span = (g1 - g0 > 1) & ok0 & ok1
            if np.any(span):
                rt = RangeExt(dg)
                _, mx = rt.query(np.clip(g0[span], 0, ng - 1), np.clip(g1[span], 0, ng - 1))
                om[span] = np.maximum(om[span], mx)
            ln = np.diff(bnd)
            sq = np.concatenate([[0.0], np.cumsum(up(up(om * om) * ln))])
            out = (np.ascontiguousarray(om), RangeExt(om), sq)
    w.cache[key] = out
    return out


def _weighted_table(w: WindowContext, om: np.ndarray, k: int) -> dict[str, Any] | None:
    """Per block of ``k`` heading gaps (:func:`.transport_blocks.block_tables`): the larger of
    ``int om |y - e|`` at the ends of its mean-error box, and prefix sums. Once per run."""
    key = f"wblocks_{k}"
    if key in w.cache:
        return w.cache[key]
    tab = block_tables(w, "gyro_z", k)
    out = None
    if tab is not None:
        ts, te = tab["ts"], tab["te"]
        zero = np.zeros(ts.size)
        none = (np.full(ts.size, -np.inf), zero, np.full(ts.size, np.inf), zero)
        gp = _over_box(w, om, ts, te, tab["c"], tab["rad"], none)
        out = dict(tab)
        out["G"] = np.concatenate([[0.0], np.cumsum(gp)])
        out["total"] = float(np.sum(gp))
    w.cache[key] = out
    return out


def _over_box(
    w: WindowContext, om: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray,
    rad: np.ndarray, floors: tuple[np.ndarray, ...],
) -> np.ndarray:
    """Upper bound of ``int_a^b om |y - e|`` over every ``e`` in ``[c - rad, c + rad]``
    (convex in ``e``: the larger of its two ends, rounded outward); ``floors`` =
    ``(tf, wf, tl, wl)`` of :func:`weighted_abs_dev`."""
    sig = w.imu.sig["gyro_z"]
    fin = np.isfinite(rad)
    r = np.where(fin, rad, 0.0)
    lo = np.ascontiguousarray(np.nextafter(c - r, -np.inf))
    hi = np.ascontiguousarray(np.nextafter(c + r, np.inf))
    tf, wf, tl, wl = (np.ascontiguousarray(x, dtype=float) for x in floors)
    a, b = np.ascontiguousarray(a, dtype=float), np.ascontiguousarray(b, dtype=float)
    g_lo = weighted_abs_dev(sig.bnd, sig.y, sig.unknown, sig.xmax, om, a, b, lo, tf, wf, tl, wl)
    g_hi = weighted_abs_dev(sig.bnd, sig.y, sig.unknown, sig.xmax, om, a, b, hi, tf, wf, tl, wl)
    return np.where(fin, up(np.maximum(g_lo, g_hi)), np.inf)


def _floor_excess(
    w: WindowContext, tab: dict[str, Any], i: np.ndarray, j: np.ndarray,
    floors: tuple[np.ndarray, ...], rt: Any,
) -> np.ndarray:
    """Where a full block (``i .. j-1``, table weights without floors) reaches into the
    window's first partial gap ``[s0, fb)`` (the block starts at the end of the sample
    holding ``s0``, before ``fb``) or its last ``(la, s1]``: ``max(om, floor) <= om +
    (floor - min om)+`` over that stretch (the smallest table weight of its samples,
    ``rt``), so the excess times ``int |y - e|`` at the ends of the block's box (zero
    where the window starts and ends on heading epochs: the floor is then the gap's own
    weight)."""
    fb, wf, la, wl = floors
    n = fb.size
    ts, te = tab["ts"], tab["te"]
    bnd = w.imu.sig["gyro_z"].bnd
    has = j > i
    ii = np.clip(i, 0, ts.size - 1)
    jj = np.clip(j - 1, 0, ts.size - 1)
    zero = np.zeros(bnd.size - 1)
    inf = np.full(n, np.inf)
    out = np.zeros(n)
    for a, b, g, fl in (
        (ts[ii], np.minimum(fb, te[ii]), ii, wf),
        (np.maximum(np.where(np.isfinite(la), la, te[jj]), ts[jj]), te[jj], jj, wl),
    ):
        ok = has & (b > a)
        if not np.any(ok):
            continue
        k0 = np.clip(np.searchsorted(bnd, a, side="right") - 1, 0, zero.size - 1)
        k1 = np.clip(np.searchsorted(bnd, b, side="left") - 1, k0, zero.size - 1)
        mn, _ = rt.query(k0, k1)
        ex = np.where(ok & (fl > mn), up(fl - mn), 0.0)
        ok &= ex > 0
        if np.any(ok):
            v = _over_box(w, zero, np.where(ok, a, 0.0), np.where(ok, b, 0.0),
                          tab["c"][g], tab["rad"][g], (inf, ex, inf, np.zeros(n)))
            out = out + np.where(ok, v, 0.0)
    return out


def weighted_speed(
    w: WindowContext,
    lp: LevelPlan,
    tau: np.ndarray,
    bv: Any,
    p: float,
    floors: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    earth: float,
) -> np.ndarray:
    """Bound of ``(1/tau) sum_k du_k int_k |r_nb|`` over boxcar windows (probability
    ``>= 1 - p`` per window, split over :data:`WEIGHTED_BLOCKS`), +inf where it does not
    apply (no gyro-free weights, irregular samples, the window outside the blocks).
    ``floors = (fb, wf, la, wl)``: the window's first partial gap ends at ``fb`` with
    weight ``wf``, its last starts at ``la`` with ``wl`` (``la = +inf``: none). ``r_nb
    = r`` minus the Earth's rates: ``|r_nb| <= |r| + earth``, adding ``earth om_max``."""
    n = lp.a1.size
    out = np.full(n, np.inf)
    sw = _sample_weights(w, bv) if w.imu.available["gyro_z"] else None
    if sw is None or n == 0 or not w.ag.has_heading:
        return out
    om, rt, sq = sw
    s0, s1 = lp.a1, lp.b2
    fb, wf, la, wl = floors
    bnd = w.imu.sig["gyro_z"].bnd
    lmax = max(w.imu.dt, float(np.max(np.diff(bnd)))) if bnd.size > 1 else w.imu.dt
    # the samples the window touches: i0 .. i1 - 1
    i0 = np.clip(np.searchsorted(bnd, s0, side="right") - 1, 0, bnd.size - 1)
    i1 = np.clip(np.searchsorted(bnd, s1, side="left"), i0, bnd.size - 1)
    # the largest weight a sample of the window can take: theirs and the floors
    _, mx = rt.query(np.minimum(i0, om.size - 1), np.clip(i1 - 1, i0, om.size - 1))
    om_max = np.maximum(np.maximum(mx, wf), np.where(np.isfinite(la), wl, 0.0))
    det = det_mean(w, s0, s1) * (s1 - s0) / tau
    kmax = 1.0 / tau
    # sum om^2 x overlap <= sum om^2 l over the samples the window touches, plus each
    # floor^2 over its span (the samples a floor reaches overlap it by at most a sample)
    sum_sq = (sq[i1] - sq[i0]) * (1 + 1e-12)
    sum_sq = sum_sq + wf * wf * (fb - s0 + lmax)
    last = np.isfinite(la)
    sum_sq = sum_sq + np.where(last, wl * wl * (s1 - np.where(last, la, s1) + lmax), 0.0)
    sum_w2 = up(up(sum_sq * (1 + 1e-12)) * lmax * kmax * kmax)
    for k in WEIGHTED_BLOCKS:
        tab = _weighted_table(w, om, k)
        if tab is None:
            continue
        ts, te = tab["ts"], tab["te"]
        inside = (s0 >= ts[0]) & (s1 <= te[-1])
        i = np.clip(np.searchsorted(ts, s0, side="left"), 0, ts.size)
        j = np.maximum(np.clip(np.searchsorted(te, s1, side="right"), 0, ts.size), i)
        full = (tab["G"][j] - tab["G"][i]) * kmax
        left_end = np.where(i < ts.size, ts[np.clip(i, 0, ts.size - 1)], s1)
        l_b = np.minimum(left_end, s1)
        right_start = np.where(j > 0, te[np.clip(j - 1, 0, ts.size - 1)], s0)
        right_start = np.maximum(right_start, l_b)
        parts = np.zeros(n)
        for pa, pb, g in ((s0, l_b, i - 1), (right_start, s1, j)):
            gg = np.clip(g, 0, ts.size - 1)
            ok = pb > pa
            v = _over_box(w, om, np.where(ok, pa, 0.0), np.where(ok, pb, 0.0),
                          tab["c"][gg], tab["rad"][gg], (fb, wf, la, wl))
            parts = parts + np.where(ok, v, 0.0)
        parts = parts + _floor_excess(w, tab, i, j, floors, rt)
        guard = (ts.size + 4) * 2.3e-16 * tab["total"] * kmax
        conc = np.sqrt(tab["lam"] * sum_w2 * 2.0 * math.log(len(WEIGHTED_BLOCKS) / p))
        val = up((full + parts * kmax + guard + conc + om_max * (det + earth)) * (1 + 1e-12))
        out = np.minimum(out, np.where(inside, val, np.inf))
    return out
