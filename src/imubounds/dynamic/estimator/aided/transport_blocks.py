"""The kernel mean of |r| with the gyro centred on each heading gap (docs/dynamic-method.md,
section 3, **accel_x**, "per heading gap").

The IMU samples are cut into blocks at the heading epochs (each epoch snapped to the
next sample boundary). On block g the gyro's mean error is known from the heading
difference over the block: ``c_g +- rad_g``. With ``y - e_g = r + d + n`` (``e_g`` the
block's true mean error, ``d`` the deterministic deviation from it, ``n`` the noise's
deviation from its block mean) and ``z = r + d``:

* Jensen: ``E |z_k + n_k| >= |z_k|`` (``n_k`` zero-mean, ``z`` not random), so
  ``sum_k w_k |z_k| <= E F(n)`` with ``F(n) = sum_k w_k |z_k + n_k|``;
* Gaussian concentration (Tsirelson-Ibragimov-Sudakov): ``F`` is Lipschitz in the
  standard normal vector behind ``n`` with constant ``sqrt(sum w_k^2) sqrt(Lambda)``,
  ``Lambda >= ||P C P||`` (``P`` the block centring, ``C`` the noise covariance), so
  ``E F <= F(n) + sqrt(sum w^2 Lambda 2 ln(1/p))`` with probability ``>= 1 - p``;
* ``F(n) = sum w_k |y_k - e_g|`` with ``e_g`` in ``c_g +- rad_g``: a convex function of
  ``e_g``, so at most its larger value at ``c_g - rad_g`` and ``c_g + rad_g``
  (:func:`_dev_over_box`; at most ``sum w_k |y_k - c_g| + sum w_k rad_g``).

So the noise enters once (in the gyro's record) plus a concentration term: the slow
flicker components, nearly constant over a heading gap, drop out of ``P C P``.
``Lambda`` per Gauss-Markov component (:func:`gm_block_norm`, ``a = beta dt``, ``m`` the
largest block): the smallest of ``sigma^2 (1+phi)/(1-phi)`` (the whole covariance), a
Gershgorin bound of ``P C P``, ``a ||P L P||`` with ``L`` the distance matrix ``|i - j|``
(exact to first order in ``a``: the slow components, ~20x below the other two) and the
two combined in the frequency domain. The kernel weights:
``w_k <= K_max l_k``, ``sum w_k <= 1``, so ``sum w^2 <= K_max dt``.

Used only where the IMU samples are regular (every segment one period, no gap) and the
window lies inside the heading epochs; elsewhere +inf (the caller keeps its other bound).
Blocks of a few lengths are tried (the registry's ``heading_blocks_<k>`` forms,
:mod:`.form_tables`, the probability split over them): short blocks know their mean
error only to ``2 h_psi / length``, long ones keep more of the slow flicker in ``P C P``.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit

from imubounds.dynamic.estimator.aided.base import up
from imubounds.dynamic.estimator.aided.common import WindowContext
from imubounds.dynamic.estimator.aided.heading import heading_at, psi_dot_abs, r_from_psidot
from imubounds.dynamic.estimator.budget import ChannelNoise
from imubounds.dynamic.estimator.window_plan import LevelPlan
from imubounds.interval import IntervalArray as IA


@njit(cache=True)
def weighted_abs_dev(  # noqa: PLR0913 (the kernel takes its arrays one by one)
    bnd: np.ndarray,
    y: np.ndarray,
    unknown: np.ndarray,
    xmax: float,
    om: np.ndarray,
    a: np.ndarray,
    b: np.ndarray,
    c: np.ndarray,
    tf: np.ndarray,
    wf: np.ndarray,
    tl: np.ndarray,
    wl: np.ndarray,
) -> np.ndarray:
    """Upper bounds of ``int_a^b om |y - c| dt`` per window (piecewise-constant ``y`` and
    weight ``om`` on the segments ``bnd``; a segment's part starting before ``tf`` takes
    at least the weight ``wf``, one ending after ``tl`` at least ``wl``; an unknown
    segment counts ``xmax + |c|``). Plain float sums inflated by ``(n + 8) 2^-52``
    relative for rounding (each term three roundings, the sum one per term), plus 1e-300
    for the products that underflow."""
    out = np.empty(a.size)
    nseg = bnd.size - 1
    for w in range(a.size):
        lo = np.searchsorted(bnd, a[w], side="right") - 1
        if lo < 0:
            lo = 0
        acc = 0.0
        cnt = 0
        k = lo
        while k < nseg and bnd[k] < b[w]:
            s0 = bnd[k] if bnd[k] > a[w] else a[w]
            s1 = bnd[k + 1] if bnd[k + 1] < b[w] else b[w]
            if s1 > s0:
                v = xmax + abs(c[w]) if unknown[k] else abs(y[k] - c[w])
                wt = om[k]
                if s0 < tf[w] and wf[w] > wt:
                    wt = wf[w]
                if s1 > tl[w] and wl[w] > wt:
                    wt = wl[w]
                acc += wt * v * (s1 - s0)
                cnt += 1
            k += 1
        out[w] = acc * (1.0 + (cnt + 8) * 2.3e-16) + 1e-300  # (+ underflow)
    return out


@njit(cache=True)
def abs_dev_pair(
    bnd: np.ndarray,
    y: np.ndarray,
    unknown: np.ndarray,
    xmax: float,
    a: np.ndarray,
    b: np.ndarray,
    c_lo: np.ndarray,
    c_hi: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`abs_dev_integral` at two centres per window in one pass (the same sums:
    :func:`weighted_abs_dev` with unit weights and no floors, whose ``1 x v x len`` is
    ``v x len`` exactly)."""
    out_lo = np.empty(a.size)
    out_hi = np.empty(a.size)
    nseg = bnd.size - 1
    for w in range(a.size):
        lo = np.searchsorted(bnd, a[w], side="right") - 1
        if lo < 0:
            lo = 0
        acc_lo = 0.0
        acc_hi = 0.0
        cnt = 0
        k = lo
        while k < nseg and bnd[k] < b[w]:
            s0 = bnd[k] if bnd[k] > a[w] else a[w]
            s1 = bnd[k + 1] if bnd[k + 1] < b[w] else b[w]
            if s1 > s0:
                if unknown[k]:
                    v_lo = xmax + abs(c_lo[w])
                    v_hi = xmax + abs(c_hi[w])
                else:
                    v_lo = abs(y[k] - c_lo[w])
                    v_hi = abs(y[k] - c_hi[w])
                acc_lo += v_lo * (s1 - s0)
                acc_hi += v_hi * (s1 - s0)
                cnt += 1
            k += 1
        g = 1.0 + (cnt + 8) * 2.3e-16
        out_lo[w] = acc_lo * g + 1e-300  # (+ underflow)
        out_hi[w] = acc_hi * g + 1e-300
    return out_lo, out_hi


@njit(cache=True)
def abs_dev_integral(
    bnd: np.ndarray,
    y: np.ndarray,
    unknown: np.ndarray,
    xmax: float,
    a: np.ndarray,
    b: np.ndarray,
    c: np.ndarray,
) -> np.ndarray:
    """Upper bounds of ``int_a^b |y - c| dt`` per window (piecewise-constant ``y`` on the
    segments ``bnd``; an unknown segment counts ``xmax + |c|``): :func:`weighted_abs_dev`
    with unit weights and no floors (:func:`abs_dev_pair` at one centre)."""
    return abs_dev_pair(bnd, y, unknown, xmax, a, b, c, c)[0]


def centred_distance_norm(m: int) -> float:
    """``||P L P||_F = sqrt((m^2 - 1)(2 m^2 + 7)/45)`` for the ``m x m`` distance matrix
    ``L_ij = |i - j|`` and ``P = I - 11'/m`` (``tr(PLPL) = tr(L^2) - 2 |L1|^2/m +
    (1'L1)^2/m^2``, summed in closed form): an upper bound of ``||P L P||``, 4 % above it
    for large ``m`` (the centred kernel ``-|x - y|`` has eigenvalues ``~ 2 m^2/(k pi)^2``);
    nondecreasing in ``m``."""
    if m <= 1:
        return 0.0
    mf = float(m)
    return math.sqrt((mf * mf - 1.0) * (2.0 * mf * mf + 7.0) / 45.0)


#: the multipliers ``c / sinh(a)`` tried in :func:`_spectral_bound` (any ``c >= 0`` is
#: valid; at most 0.99, so the stationary point's denominator ``sqrt(A C) (1 - sqrt(c /
#: sinh a))`` keeps 0.5 % of its terms: no cancellation)
_C_GRID = np.concatenate([[0.0], np.geomspace(1e-6, 0.99, 241)])


def _spectral_bound(a: float, lam_l: float) -> float:
    """``min_c [sup_s h_c(s) + c lam_l]`` of :func:`gm_block_norm`, over :data:`_C_GRID`
    (times ``sinh a``): ``h_c(s) = (1 - phi^2)/((1 - phi)^2 + 4 phi s) - c/(2 s)`` on
    ``s`` in (0, 1] has one stationary point ``s* = B r/(sqrt(A C) - C r)`` (``r =
    sqrt(c/2)``, ``A = 1 - phi^2``, ``B = (1 - phi)^2``, ``C = 4 phi``; ``h_c' = 0`` is
    ``r (B + C s) = s sqrt(A C)``), a maximum (``h_c' > 0`` before it, ``< 0`` after),
    where the denominator is positive (else ``h_c`` increases up to ``s = 1``; ``C r =
    sqrt(A C)`` at ``c = sinh a``); the rounding of ``s*`` lowers ``h_c(s*)`` only to
    second order, and each candidate takes an absolute guard of ``1e-13`` times its
    terms' magnitude (the cancellation in ``h_c``)."""
    phi = math.exp(-a)
    A = -math.expm1(-2.0 * a)
    B = math.expm1(-a) ** 2
    C4 = 4.0 * phi
    if B <= 0.0:
        return math.inf
    c = math.sinh(a) * _C_GRID[1:]
    r = np.sqrt(0.5 * c)
    den = math.sqrt(A * C4) - C4 * r
    s = np.where(den > 0.0, B * r / np.where(den > 0.0, den, 1.0), 1.0)
    s = np.clip(s, 1e-300, 1.0)
    t1 = A / (B + C4 * s)
    t2 = c / (2.0 * s)
    v = t1 - t2 + c * lam_l + 1e-13 * (t1 + t2 + c * lam_l)
    return float(min(A / B, np.min(v)))


def gm_block_norm(a: float, m: int) -> float:
    """An upper bound of ``||P T P||`` for a unit Gauss-Markov component, ``T_ij =
    phi^|i-j|`` (``phi = exp(-a)``, ``a = beta dt``) over consecutive blocks of at most
    ``m`` samples of any lengths, ``P`` centring each block on its own mean: the smallest of

    1. ``||T|| <= (1 + phi)/(1 - phi)`` (the spectral density's peak; ``||P|| = 1``);
    2. Gershgorin on ``P T P``: an entry inside a block is at most ``2 d`` (``d = 1 -
       phi^(m-1)``), one across blocks i < j is ``(u_k - mean_i u)(v_l - mean_j v)`` with
       ``u = phi^-k``, ``v = phi^l``, at most ``d^2 phi^(start_j - end_i)``, so a row sums
       to at most ``2 m d + 2 d^2 phi^(2-m)/(1-phi)``;
    3. ``a lam_L``, ``lam_L = ||P L P||`` for the distance matrix ``L_ij = |i - j|`` over
       the whole record: a vector ``v`` in the range of ``P`` sums to zero over each block,
       so over the record, and then ``v'Tv = -v'Dv`` (``D = 1 - phi^|i-j|``) and ``v'(aL -
       D)v <= 0``: ``a|x| - 1 + e^(-a|x|) = int (1 - cos wx) a^3/(pi w^2 (a^2 + w^2)) dw``
       (from ``|x| = int (1 - cos wx)/(pi w^2) dw`` and ``e^(-a|x|) = int cos(wx) a/(pi
       (a^2 + w^2)) dw``) and ``sum v_i v_j (1 - cos w(x_i - x_j)) = -|sum v_k e^(i w
       x_k)|^2 <= 0``. Across blocks g < h, ``L_ij = (e_g - i) + (j - e_g)`` (``e_g`` the
       last sample of g) is a function of i plus one of j, removed by the centring on both
       sides, so ``P L P`` is block-diagonal and ``lam_L = max_g ||P_g L_g P_g|| <=``
       :func:`centred_distance_norm` ``(m)`` (a shorter block's norm is at most the
       longer's: pad the vector with zeros). Exact to first order in ``a``: 4 % above
       ``||PTP||`` for ``a m << 1``, where 1 and 2 are ~20x too large;
    4. the two combined in the frequency domain: with ``V(w) = sum v_k e^(i w k)``,
       ``v'Tv = int_-pi^pi f |V|^2 dw`` (``f = (1 - phi^2)/(2 pi (1 - 2 phi cos w +
       phi^2))``, AR(1)'s spectral density), ``|v|^2 = int |V|^2 dw/(2 pi)`` and, as ``v``
       sums to zero, ``-v'Lv = int g |V|^2 dw`` (``g = 1/(4 pi sin^2(w/2))``, from
       ``|k| = int (1 - cos kw) g dw``). So for every ``c >= 0``: ``v'Tv = int (f - c g)|V|^2
       + c int g |V|^2 <= sup_w 2 pi (f - c g) + c lam_L`` for a unit ``v``; with ``s =
       sin^2(w/2)``, ``2 pi (f - c g) = (1 - phi^2)/((1 - phi)^2 + 4 phi s) - c/(2 s)``
       (:func:`_spectral_bound`). ``c = 0`` gives 1 and ``c = sinh a`` gives
       ``sinh(a) lam_L``; between them it bridges ``a m ~ 1-10`` (within 6 % of the largest
       eigenvalue of ``PTP`` over six equal blocks, tests/test_block_norm.py)."""
    phi = math.exp(-a)
    q = -math.expm1(-a)
    best = (1 + phi) / q
    if a * (m + 2) < 600.0:
        d = -math.expm1(-a * max(m - 1, 0))
        best = min(best, 2 * m * d + 2 * d * d * math.exp(a * (m - 2)) / q)
    lam_l = centred_distance_norm(m)
    best = min(best, a * lam_l * (1 + 1e-12), _spectral_bound(a, lam_l))
    return max(best, 0.0)  # 4 can go negative at m = 1, where P = 0


def block_norm(cn: ChannelNoise, m: int, dt: float) -> float:
    """``Lambda``: an upper bound of ``||P C P||`` for the noise of channel ``cn`` cut in
    consecutive blocks of at most ``m`` samples of any lengths (``P`` centres each block
    on its own mean): ``N^2/dt + 4 Q^2/dt^2`` (white and quantization noise: ``||P|| =
    1``) plus ``sigma^2`` :func:`gm_block_norm` ``(beta dt, m)`` per Gauss-Markov
    component of the flicker (the norm of a sum at most the sum of the norms)."""
    lam = cn.N * cn.N / dt + 4 * cn.Q * cn.Q / (dt * dt)
    for s, b in cn.gm_terms():
        lam += s * s * gm_block_norm(b * dt, m)
    return lam * (1 + 1e-9)


def _block_edges(w: WindowContext, ch: str, k: int) -> np.ndarray | None:
    """Sample-boundary indices of the blocks: every ``k``-th heading epoch (gyro_z), every
    ``k`` seconds (gyro_y); None where the samples are not regular or have gaps."""
    sig = w.imu.sig[ch]
    ln = np.diff(sig.bnd)
    if ln.size == 0 or np.any(sig.unknown) or float(np.max(ln) - np.min(ln)) > 1e-6 * w.imu.dt:
        return None
    if ch == "gyro_z":
        ht = w.ag.head_t
        if ht.size < 2:
            return None
        sel = np.unique(np.concatenate([np.arange(0, ht.size, k), [ht.size - 1]]))
        ks = np.unique(np.clip(np.searchsorted(sig.bnd, ht[sel]), 0, sig.bnd.size - 1))
    else:
        step = max(1, int(round(k / w.imu.dt)))
        ks = np.unique(np.concatenate([np.arange(0, sig.bnd.size, step), [sig.bnd.size - 1]]))
    return ks if ks.size >= 2 else None


def pitch_rate_mean(w: WindowContext, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Bound of |mean q| over [a, b]: ``q = -theta' cos(phi) + psi' sin(phi) cos(theta)``,
    so ``|mean q| <= 2 max_tilt/L + sin(max_tilt) mean|psi'| + (1/cos(max_tilt) - 1)
    (mean|q| + mean|psi'|)`` (the last, second-order term with the magnitudes)."""
    veh = w.veh
    L = np.maximum(b - a, 1e-300)
    psid = psi_dot_abs(w, a, b, own_q=True)
    st = math.sin(veh.max_tilt)
    sec1 = 1.0 / math.cos(veh.max_tilt) - 1.0
    return up(
        2 * veh.max_tilt / L + st * psid + sec1 * (w.gyro_abs_mean("gyro_y", a, b) + psid)
    )


def _centres(w: WindowContext, ch: str, ts: np.ndarray, te: np.ndarray) -> IA:
    """The mean error of channel ``ch`` over each block: gyro_z from the heading
    difference, gyro_y from the bound of the mean pitch rate."""
    sig = w.imu.sig[ch]
    L = te - ts
    ylo, yhi = sig.integral(ts, te)
    if ch == "gyro_z":
        z = np.zeros(ts.size, dtype=np.int64)
        sup = LevelPlan(1.0, "aided", ts, ts, te, te, z, z)
        dpsi = (heading_at(w, te) - heading_at(w, ts)) / IA(L)
        return IA(ylo, yhi) / IA(L) - r_from_psidot(w, dpsi, sup, L, own_q=True)
    qb = pitch_rate_mean(w, ts, te)
    return IA(ylo, yhi) / IA(L) + IA(-qb, qb)


def _dev_over_box(
    sig: Any, a: np.ndarray, b: np.ndarray, c: np.ndarray, rad: np.ndarray
) -> np.ndarray:
    """Upper bound of ``int_a^b |y - e|`` over every ``e`` in ``[c - rad, c + rad]``: a
    convex function of ``e``, so its larger value at the two ends (at most ``int |y - c|
    + (b - a) rad``, the triangle inequality's bound, and smaller where the gyro's record
    straddles ``c``); the ends rounded outward."""
    fin = np.isfinite(rad)
    r = np.where(fin, rad, 0.0)
    lo = np.ascontiguousarray(np.nextafter(c - r, -np.inf))
    hi = np.ascontiguousarray(np.nextafter(c + r, np.inf))
    g_lo, g_hi = abs_dev_pair(sig.bnd, sig.y, sig.unknown, sig.xmax, a, b, lo, hi)
    return np.where(fin, up(np.maximum(g_lo, g_hi)), np.inf)


def block_tables(w: WindowContext, ch: str, k: int) -> dict[str, Any] | None:
    """Per block: start, end, ``G' = max over e in c_g +- rad_g of int |y - e|``
    (:func:`_dev_over_box`) and its prefix sums (also
    weighted by the block's end and start times); computed once per channel and ``k``."""
    key = f"blocks_{ch}_{k}"
    if key in w.cache:
        return w.cache[key]
    ks = _block_edges(w, ch, k)
    if ks is None:
        w.cache[key] = None
        return None
    sig = w.imu.sig[ch]
    ts, te = sig.bnd[ks[:-1]], sig.bnd[ks[1:]]
    e = _centres(w, ch, ts, te)
    fin = np.isfinite(e.lo) & np.isfinite(e.hi)
    c = np.where(fin, e.mid(), 0.0)
    rad = np.where(fin, up(e.radius()), np.inf)
    gp = _dev_over_box(sig, ts, te, c, rad)

    def cum(x: np.ndarray) -> np.ndarray:
        return np.concatenate([[0.0], np.cumsum(x)])

    m = int(np.max(ks[1:] - ks[:-1]))
    tab = {
        "ch": ch,
        "ts": ts,
        "te": te,
        "c": c,
        "rad": rad,
        "G": cum(gp),
        "tG": cum(te * gp),
        "sG": cum(ts * gp),
        "total": float(np.sum(np.abs(te * gp)) + np.sum(gp)),
        "lam": block_norm(w.ctx.noise[ch], m, w.imu.dt),
    }
    w.cache[key] = tab
    return tab


def _piece(w: WindowContext, tab: dict[str, Any], a: np.ndarray, b: np.ndarray,
           g: np.ndarray) -> np.ndarray:
    """``max over e in c_g +- rad_g of int_a^b |y - e|`` over partial pieces inside block
    ``g``."""
    sig = w.imu.sig[tab["ch"]]
    gg = np.clip(g, 0, tab["c"].size - 1)
    c = np.ascontiguousarray(tab["c"][gg])
    ok = b > a
    aa, bb = np.where(ok, a, 0.0), np.where(ok, b, 0.0)
    v = _dev_over_box(sig, aa, bb, c, tab["rad"][gg])
    return np.where(ok, v, 0.0)


def _sum_blocks(tab: dict[str, Any], i: np.ndarray, j: np.ndarray, key: str) -> np.ndarray:
    """Sum of prefix table ``key`` over blocks i..j-1 (zero where j <= i)."""
    jj = np.maximum(j, i)
    return tab[key][jj] - tab[key][i]


def block_bound(
    w: WindowContext,
    lp: LevelPlan,
    tau: np.ndarray,
    p: float,
    det_mean: np.ndarray,
    k: int,
    ch: str = "gyro_z",
) -> np.ndarray:
    """Bound of the kernel mean of |r| (``ch`` gyro_z; |q| for gyro_y) over each window
    with the gyro centred on blocks of ``k`` heading gaps (gyro_y: ``k`` seconds), holding
    with probability ``>= 1 - p`` per window (docs/dynamic-method.md, (3.9)); +inf where
    not applicable. ``det_mean`` bounds the mean of the deterministic deviation over the
    support."""
    tab = block_tables(w, ch, k)
    if tab is None or lp.a1.size == 0:
        return np.full(lp.a1.size, np.inf)
    out = _bound(w, tab, lp, tau, p, det_mean)
    return np.where(np.isfinite(out), out, np.inf)


def _bound(
    w: WindowContext,
    tab: dict[str, Any],
    lp: LevelPlan,
    tau: np.ndarray,
    p: float,
    det_mean: np.ndarray,
) -> np.ndarray:
    """:func:`block_bound` with the blocks of one table."""
    ts, te = tab["ts"], tab["te"]
    s0, s1 = lp.a1, lp.b2
    inside = (s0 >= ts[0]) & (s1 <= te[-1])
    # full blocks i..j-1 inside [s0, s1]; the pieces left over lie in blocks i-1 and j
    i = np.clip(np.searchsorted(ts, s0, side="left"), 0, ts.size)
    j = np.clip(np.searchsorted(te, s1, side="right"), 0, ts.size)
    j = np.maximum(j, i)
    trap = lp.b1 > lp.a1
    kmax = 1.0 / tau
    # boxcar: K = 1/tau on [s0, s1]
    full_box = _sum_blocks(tab, i, j, "G") * kmax
    # trapezoid: K rises on [a1, b1] (bounded at each block's end) and falls on [a2, b2]
    # (bounded at each block's start); a block across b1 takes the peak 1/tau
    L1 = np.maximum(lp.b1 - lp.a1, 1e-300)
    L2 = np.maximum(lp.b2 - lp.a2, 1e-300)
    m1 = np.clip(np.searchsorted(te, lp.b1, side="right"), i, j)  # blocks i..m1-1 in I1
    m2 = np.clip(np.searchsorted(ts, lp.b1, side="left"), m1, j)  # blocks m2..j-1 in I2
    rise = (_sum_blocks(tab, i, m1, "tG") - lp.a1 * _sum_blocks(tab, i, m1, "G")) / (L1 * tau)
    fall = (lp.b2 * _sum_blocks(tab, m2, j, "G") - _sum_blocks(tab, m2, j, "sG")) / (L2 * tau)
    mid = _sum_blocks(tab, m1, m2, "G") * kmax
    full = np.where(trap, np.maximum(rise, 0.0) + np.maximum(fall, 0.0) + mid, full_box)
    # partial pieces at both ends (and a window inside a single block)
    left_end = np.where(i < ts.size, ts[np.clip(i, 0, ts.size - 1)], s1)
    left = _piece(w, tab, s0, np.minimum(left_end, s1), i - 1)
    right_start = np.where(j > 0, te[np.clip(j - 1, 0, ts.size - 1)], s0)
    right_start = np.maximum(right_start, np.minimum(left_end, s1))
    right = _piece(w, tab, right_start, s1, j)
    parts = (left + right) * kmax
    # rounding of the prefix sums
    scale = kmax + np.where(trap, 1.0 / (L1 * tau) + 1.0 / (L2 * tau), 0.0)
    guard = (ts.size + 4) * 2.3e-16 * tab["total"] * (1.0 + np.abs(lp.a1) + np.abs(lp.b2)) * scale
    conc = np.sqrt(tab["lam"] * w.imu.dt * kmax * 2.0 * math.log(1.0 / p))
    det = det_mean * (s1 - s0) * kmax
    out = up((full + parts + guard + conc + det) * (1 + 1e-12))
    return np.where(inside, out, np.inf)
