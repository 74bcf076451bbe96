"""Residual checks of the aiding against the smoothed states (docs/dynamic-method.md,
section 5b).

After the smoother, every aiding measurement ``z_i`` (a GNSS fix's east and north, a
GNSS velocity's components, a compass heading) is compared with the centre ``c_i`` of
the smoothed interval of the same state, of half-width ``w_i``. If every assumption
holds the truth ``x_i`` lies in the interval, so the residual ``r_i = z_i - c_i`` is the
measurement's error ``e_i`` plus at most ``w_i``: ``|r_i - e_i| <= w_i``. The error is
a deterministic part ``|d_i| <= D`` (lever arm, compass deviation bound) plus white
Gaussian noise of the stated sigma ``s_i`` (the GNSS model: isotropic Gaussian, per-axis
sigma DRMS / sqrt 2; the compass: its noise sigma). Two tests follow, each sound under
the assumptions (a false alarm only with the stated probability):

* **runs**: over every run of ``m`` consecutive measurements (m = 1, 4, 16, 64; runs
  overlapping by half), ``|mean r| <= mean w + D + k sqrt(sum s_i^2) / m``, k two-sided
  with Bonferroni over every run and axis. A step that the IMU sees (multipath moving a
  run of fixes, a clock lag shifting the fixes along the track or the heading in the
  turns) moves the mean of the run while the IMU holds the smoothed interval.
* **tails**: the number of measurements with ``max(|r_i| - w_i - D, 0) > 3.5 s_i`` is
  at most its binomial quantile under the Gaussian model (P = 4.65e-4 per axis): heavy-
  tailed errors (Student-t) exceed it.

Each check's level is its share of the checks' level (``alpha`` of the run, split
equally over the families run): a clean trip raises a false violation with probability
at most that. The smallest step of each run length that the runs test would flag is
reported (``steps_unnoticed``): a smaller one goes unnoticed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from imubounds.dynamic.estimator import smoother as SM
from imubounds.dynamic.estimator.violations import Violation
from imubounds.units import G0

RUN_LENGTHS = (1, 4, 16, 64)
STEP_LENGTHS = (4, 8, 16, 32)
TAIL_K = 3.5
TEST_RUNS = "residuals of runs of measurements against the smoothed states"
TEST_TAILS = "tails of the residuals (Gaussian error model)"
TEST_STEP = "GNSS position step against the integrated GNSS velocity"
TEST_FIX = "GNSS fix against its neighbours and the integrated GNSS velocity"
TEST_VEL_LAG = "GNSS velocity against its positions (latency)"
VEL_LAG_RULE = (
    "least squares of the pairs' dq = (p_l+1 - p_l) - (IMU-corrected trapezoid of v) on "
    "dv = v_l+1 - v_l (east and north): a velocity L s late gives dq = L dv; the sum of "
    "dv^2 less the velocity noise's share, sd exact for the stated Gaussian errors (+ the "
    "second-order noise products), deterministic the trapezoid's bound x |dv| and "
    "L^2/2 x jerk dt; interval +-(k sd + det), k of the step test's family (one test more)"
)
#: neighbours on each side of a fix in the single-fix test
NB = 4
#: the largest latency (s) of the GNSS velocity against its positions the lag estimate's
#: second-order noise term allows for (:func:`velocity_lag`)
MAX_VEL_LAG_S = 1.0


@dataclass
class Family:
    """One measured quantity's residuals: ``r`` (n, axes), ``w`` (n, axes), ``s`` (n,)."""

    stream: str
    unit: str
    t: np.ndarray
    r: np.ndarray
    w: np.ndarray
    s: np.ndarray
    det: float
    scale: float = 1.0  # for messages (deg for headings)
    out_unit: str = ""
    summary: dict[str, Any] = field(default_factory=dict)


def _windows(n: int) -> list[tuple[int, np.ndarray]]:
    out = []
    for m in RUN_LENGTHS:
        if m > n:
            break
        step = max(1, m // 2)
        starts = np.arange(0, n - m + 1, step)
        out.append((m, starts))
    return out


def _families(ctx: Any, sm: Any) -> list[Family]:
    ag = ctx.aiding
    te, X = sm.te, sm.X
    fams: list[Family] = []

    def at(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        i = np.searchsorted(te, t).clip(0, te.size - 1)
        return i, te[i] == t

    def centre_half(i: np.ndarray, v: int) -> tuple[np.ndarray, np.ndarray]:
        lo, hi = X[i, v, 0], X[i, v, 1]
        with np.errstate(invalid="ignore"):  # unbounded intervals: dropped below
            return 0.5 * (lo + hi), 0.5 * (hi - lo)

    if ag.has_gnss and ag.gnss_sig.size == ag.gnss_t.size:
        i, ok = at(ag.gnss_t)
        ce, we = centre_half(i, SM.E)
        cn, wn = centre_half(i, SM.N)
        r = np.stack([ag.gnss_e - ce, ag.gnss_n - cn], -1)
        w = np.stack([we, wn], -1)
        ok &= np.all(np.isfinite(w), axis=1)
        fams.append(
            Family("gnss position", "m", ag.gnss_t[ok], r[ok], w[ok], ag.gnss_sig[ok],
                   ag.gnss_det, 1.0, "m")
        )
        if ag.has_gvel and ag.gvel_sig.size == ag.gnss_t.size:
            okv = ag.gvel_ok & ok
            ce, we = centre_half(i, SM.VE)
            cn, wn = centre_half(i, SM.VN)
            r = np.stack([ag.gvel_e - ce, ag.gvel_n - cn], -1)
            w = np.stack([we, wn], -1)
            okv &= np.all(np.isfinite(w), axis=1)
            fams.append(
                Family("gnss velocity", "m/s", ag.gnss_t[okv], r[okv], w[okv],
                       ag.gvel_sig[okv], ag.gvel_det, 1.0, "m/s")
            )
    if ag.has_heading and not ag.head_from_course and ag.head_sig > 0:
        i, ok = at(ag.head_t)
        c, w = centre_half(i, SM.PSI)
        r = np.mod(ag.head_c - c + math.pi, 2 * math.pi) - math.pi
        ok &= np.isfinite(w)
        fams.append(
            Family("heading", "rad", ag.head_t[ok], r[ok, None], w[ok, None],
                   np.full(int(ok.sum()), ag.head_sig), ag.head_det, 180 / math.pi, "deg")
        )
    return [f for f in fams if f.t.size >= 2]


def _vel_var(
    i: np.ndarray, m: int, d: np.ndarray, sv: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """(exact variance (m^2) of the velocity part of the step statistic ``D`` at the
    splits ``i``, ``sum_l w_l d_l^3`` (s^3) for its trapezoid error) with ``m`` fixes
    before and after: ``mean_A P - mean_B P`` weights the trapezoid pair ``l`` by ``w =
    (m + 1 + o) / m`` for ``o = l - i`` in ``[-m, -1]`` and ``(m - 1 - o) / m`` in
    ``[0, m - 1]`` (0 elsewhere; the weights sum to m), so the velocity ``v_j`` has the
    coefficient ``(d_{j-1} w_{j-1} + d_j w_j) / 2``: the variance is
    ``sum_j c_j^2 sigma_j^2`` (a triangle, about ``2 m / 3 (sigma d)^2``) and the
    trapezoid error is at most ``jerk sum_l w_l d_l^3 / 12``."""
    o = np.arange(-m - 1, m + 1)  # pair offsets -m-1 .. m
    w = np.where(o < 0, (m + 1 + o) / m, (m - 1 - o) / m)
    w[(o < -m) | (o > m - 1)] = 0.0
    L = (i[:, None] + o[None, :])  # pair indices
    dl = np.where((L >= 0) & (L < d.size), d[L.clip(0, d.size - 1)], 0.0)
    u = 0.5 * dl * w[None, :]  # (splits, 2m + 2): pair l's weight on v_l and v_{l+1}
    c = u[:, 1:] + u[:, :-1]  # v_j for j = i - m .. i + m
    J = (i[:, None] + o[None, 1:]).clip(0, sv.size - 1)
    var = np.sum((c * sv[J]) ** 2, axis=1)
    return np.asarray(var), np.asarray(2.0 * np.sum(u * dl * dl, axis=1))


#: gyro noise over a fix interval taken as at most this many sigma in the heading error
#: of the IMU's trapezoid correction (its share of the deterministic bound)
GYRO_K = 5.0


def imu_trapezoid(
    ctx: Any, sm: Any, t: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The IMU's correction of the trapezoid rule between consecutive fixes ``t``.

    Between fixes ``t_l`` and ``t_{l+1}`` (``dt``, mid ``t_m``) the true velocity's
    integral is ``dt (v_l + v_{l+1}) / 2 - c_l`` with ``c_l = int (t - t_m) a(t) dt``
    (by parts; ``a`` the ENU acceleration). The IMU measures it:
    ``c^_l = sum_k (s_k - t_m) R(psi_k) (f_k - b^) len_k`` over the IMU segments ``k``
    in the pair (``s_k`` their mid, ``f_k`` = accel x, y, ``psi_k`` = the centre of the
    smoothed heading at ``t_l`` + the gyro z integrated from ``t_l``, less the centre of
    the smoothed yaw-rate bias; ``b^`` the centre of the smoothed accel bias). Returns
    per pair (``c^`` (n-1, 2); the variance of its noise error per axis, the larger of
    accel x's and y's for the weights ``c_k = (s_k - t_m) len_k``: white ``N^2 sum
    (s_k - t_m)^2 len_k``, quantization ``Q^2 sum (diff c)^2 / h^2``, and the slow
    processes (flicker ``sum sigma_i^2`` of its Gauss-Markov terms, rate random walk
    ``K^2 dt / 2``) at most ``(sum |c_k|)^2`` times their variance; the turn-on bias is
    in the bias term below; pairs are taken as independent: each kernel has zero mean);
    a bound ``det`` of the rest):

    * heading error ``Delta(t) = d0 + e (t - t_l) + GYRO_K N_g sqrt(dt) + (s_g + m_g)
      int |gyro z|`` (``d0`` the smoothed heading's half-width at ``t_l``, ``e`` the
      yaw-rate bias's, ``s_g, m_g`` the gyro's scale and misalignment bounds): at most
      ``d0 C + e (A2 + dt C / 2) + Delta^2 A1 / 2`` with ``C = jerk dt^3 / 12`` (the
      bound of ``|c_l|``), ``A1 = sum |s_k - t_m| |f|_k len_k``, ``A2 = sum (s_k - t_m)^2
      |f|_k len_k``, ``|f|_k = |f_k| + sqrt 2 b_w`` (``b_w`` the accel bias half-width);
    * scale, misalignment and tilt (``cos``): ``(s + m + 1 - cos tilt) A1``; gravity
      through a tilt that varies within the pair: ``2 g sin(tilt) dt^2 / 4``;
    * the accel bias left (``sqrt 2 b_w``) turned by the yaw within the pair:
      ``sqrt 2 b_w r_max dt^3 / 12``; a segment's mean against its samples:
      ``jerk sum len_k^3 / 12``.

    Pairs with unknown IMU segments, no smoothed heading at ``t_l``, or a declared
    antenna lever arm (``gnss_det > 0``: the antenna's acceleration is not the IMU's)
    keep the trapezoid's own bound (``c^ = 0``, variance 0, ``det = jerk dt^3 / 12``),
    as does every pair where that bound is the smaller."""
    n = t.size
    dt = np.diff(t)
    jerk = ctx.vehicle.max_jerk
    cb = jerk * dt**3 / 12.0
    chat = np.zeros((max(n - 1, 0), 2))
    var = np.zeros(max(n - 1, 0))
    det = cb.copy()
    imu = getattr(ctx, "imu", None)
    if imu is None or sm is None or ctx.aiding.gnss_det > 0 or n < 2:
        return chat, var, det
    sx, sy, sg = imu.sig["accel_x"], imu.sig["accel_y"], imu.sig["gyro_z"]
    bnd = imu.bnd
    unk = sx.unknown | sy.unknown | sg.unknown
    beta = np.asarray(sm.beta, float)
    bx, by, bg = (0.5 * (beta[i, 0] + beta[i, 1]) for i in range(3))
    bw = float(max(0.5 * (beta[0, 1] - beta[0, 0]), 0.5 * (beta[1, 1] - beta[1, 0])))
    eps = float(0.5 * (beta[2, 1] - beta[2, 0]))
    nx, ny = ctx.noise["accel_x"], ctx.noise["accel_y"]
    ng = ctx.noise["gyro_z"].N
    sgz = ctx.noise["gyro_z"].scale + ctx.noise["gyro_z"].misalignment_rad
    sc = max(ctx.noise["accel_x"].scale, ctx.noise["accel_y"].scale)
    mis = max(ctx.noise["accel_x"].misalignment_rad, ctx.noise["accel_y"].misalignment_rad)
    tilt = ctx.vehicle.max_tilt
    rmax = ctx.vehicle.max_rate
    g = G0
    if not (np.all(np.isfinite(beta)) and math.isfinite(bw + eps)):
        return chat, var, det
    ie = np.searchsorted(sm.te, t).clip(0, sm.te.size - 1)
    psi = sm.X[ie, SM.PSI]
    has = (sm.te[ie] == t) & np.all(np.isfinite(psi), axis=1)
    psi = np.where(has[:, None], psi, 0.0)
    # sub-segments: the IMU segments cut at the fixes; j = their pair, k = their segment
    inner = t[(t > bnd[0]) & (t < bnd[-1])]
    cuts = np.union1d(bnd, inner)
    npair = n - 1
    sums = np.zeros((_TRAP_SUMS, npair))
    lns: list[np.ndarray] = []
    carry = 0.0
    # in chunks of sub-segments that start at fixes (a pair's sub-segments in one chunk:
    # the per-pair sums and the running sum of gz ln are those of one pass, bit for bit)
    at_fix = np.searchsorted(cuts, inner)  # the cuts at fixes
    starts = np.zeros(1, dtype=np.int64)
    if at_fix.size:
        want = np.arange(_TRAP_CHUNK, cuts.size - 1, _TRAP_CHUNK)
        pick = np.searchsorted(at_fix, want).clip(0, at_fix.size - 1)
        starts = np.unique(np.r_[starts, at_fix[pick]])
    ends = np.r_[starts[1:], cuts.size - 1]
    for c0, c1 in zip(starts, ends, strict=True):
        if c1 <= c0:
            continue
        carry = _trap_chunk(cuts[c0 : c1 + 1], t, bnd, unk, sg, sx, sy, psi, bx, by, bg, bw,
                            carry, sums, lns)
    (covered, badsum, ch_e, ch_n, A1, A2, turn, cube, u2, c1s, dq) = sums
    bad = badsum > 0
    ok = has[:-1] & ~bad & (np.abs(covered - dt) <= 1e-9 * np.maximum(dt, 1.0))
    ln = np.concatenate(lns) if lns else np.zeros(0)
    del lns
    h = float(np.median(ln, overwrite_input=True)) if ln.size else 1.0
    del ln
    c1 = c1s

    def noise_var(cn_: Any) -> np.ndarray:
        slow = sum(sg_ * sg_ for sg_, _ in cn_.gm_terms()) + 0.5 * cn_.K**2 * dt
        return np.asarray(cn_.N**2 * u2 + cn_.Q**2 * dq / h**2 + c1**2 * slow)

    D = (0.5 * (psi[:-1, 1] - psi[:-1, 0]) + eps * dt + GYRO_K * ng * np.sqrt(dt)
         + sgz * turn)  # fmt: skip
    d0 = 0.5 * (psi[:-1, 1] - psi[:-1, 0])
    dj = (
        d0 * cb + eps * (A2 + 0.5 * dt * cb) + 0.5 * D * D * A1
        + (sc + mis + 1.0 - math.cos(tilt)) * A1 + 0.5 * g * math.sin(tilt) * dt**2
        + math.sqrt(2.0) * bw * rmax * dt**3 / 12.0 + jerk * cube / 12.0
    )  # fmt: skip
    use = ok & np.isfinite(dj) & (dj < cb)
    chat[use, 0], chat[use, 1] = ch_e[use], ch_n[use]
    var[use] = np.maximum(noise_var(nx), noise_var(ny))[use]
    det[use] = dj[use]
    return chat, var, det


#: sub-segments per chunk of :func:`imu_trapezoid` (its memory: ~30 arrays of this size)
_TRAP_CHUNK = 1 << 19
#: the per-pair sums of :func:`_trap_chunk`
_TRAP_SUMS = 11


def _trap_chunk(
    cuts: np.ndarray, t: np.ndarray, bnd: np.ndarray, unk: np.ndarray, sg: Any, sx: Any,
    sy: Any, psi: np.ndarray, bx: float, by: float, bg: float, bw: float, carry: float,
    sums: np.ndarray, lns: list[np.ndarray],
) -> float:
    """:func:`imu_trapezoid`'s per-pair sums over the sub-segments between ``cuts``
    (starting at a fix, or at the first cut) added to ``sums``; the selected
    sub-segments' lengths appended to ``lns``; returns the running sum of ``gz ln``
    (``carry`` its value before the chunk)."""
    n = t.size
    s0, s1 = cuts[:-1], cuts[1:]
    mid_s = 0.5 * (s0 + s1)
    j = np.searchsorted(t, mid_s, side="right") - 1
    k = (np.searchsorted(bnd, mid_s, side="right") - 1).clip(0, bnd.size - 2)
    sel = (j >= 0) & (j < n - 1) & (s1 > s0)
    j, k, s0, s1, mid_s = j[sel], k[sel], s0[sel], s1[sel], mid_s[sel]
    if j.size == 0:
        return carry
    ln = s1 - s0
    lns.append(ln)
    j0 = int(j[0])
    m = int(j[-1]) - j0 + 1
    jl = j - j0
    out = sums[:, j0 : j0 + m]
    out[0] += np.bincount(jl, ln, m)
    out[1] += np.bincount(jl, unk[k].astype(float), m)
    gz = sg.y[k] - bg
    x = gz * ln
    x[0] += carry
    cg = np.cumsum(x)
    del x
    first = np.r_[True, j[1:] != j[:-1]]
    base = np.maximum.accumulate(np.where(first, np.arange(j.size), 0))
    ph = (0.5 * (psi[j, 0] + psi[j, 1]) + cg - (cg[base] - gz[base] * ln[base])
          - 0.5 * gz * ln)  # fmt: skip
    carry = float(cg[-1])
    del cg, base
    fx, fy = sx.y[k] - bx, sy.y[k] - by
    u = mid_s - 0.5 * (t[j] + t[j + 1])
    ce, cn = np.cos(ph), np.sin(ph)
    del ph
    cu = u * ln
    out[2] += np.bincount(jl, cu * (ce * fx - cn * fy), m)
    out[3] += np.bincount(jl, cu * (cn * fx + ce * fy), m)
    del ce, cn
    fa = np.hypot(fx, fy) + math.sqrt(2.0) * bw
    out[4] += np.bincount(jl, np.abs(cu) * fa, m)
    out[5] += np.bincount(jl, u * cu * fa, m)
    out[6] += np.bincount(jl, np.abs(sg.y[k]) * ln, m)
    out[7] += np.bincount(jl, ln**3, m)
    out[8] += np.bincount(jl, u * cu, m)
    out[9] += np.bincount(jl, np.abs(cu), m)
    last = np.r_[j[1:] != j[:-1], True]
    dc = np.where(first, cu, cu - np.r_[0.0, cu[:-1]])
    out[10] += np.bincount(jl, dc**2 + np.where(last, cu**2, 0.0), m)
    return carry


def _pair_sums(i: np.ndarray, m: int, x: np.ndarray, power: int) -> np.ndarray:
    """``sum_l w_l^power x_l`` over the pairs of the step statistic at the splits ``i``
    (the triangular weights of :func:`_vel_var`)."""
    o = np.arange(-m - 1, m + 1)
    w = np.where(o < 0, (m + 1 + o) / m, (m - 1 - o) / m)
    w[(o < -m) | (o > m - 1)] = 0.0
    L = i[:, None] + o[None, :]
    xl = np.where((L >= 0) & (L < x.size), x[L.clip(0, max(x.size - 1, 0))], 0.0)
    return np.asarray(np.sum(w[None, :] ** power * xl, axis=1))


@dataclass
class _LagSums:
    """Sums of the GNSS velocity's lag against its positions (:func:`velocity_lag`)."""

    s: float = 0.0  # sum x dq
    d: float = 0.0  # sum x^2 less the noise's share (attenuation)
    var: float = 0.0  # variance of s given x
    var2: float = 0.0  # the noise products' variance (second order) and x's own noise
    det: float = 0.0  # sum |x| x the pair's deterministic bound
    ax: float = 0.0  # sum |x| x jerk dt (the second-order term's factor)
    n: int = 0

    def add(self, dq: np.ndarray, x: np.ndarray, d: np.ndarray, sp: np.ndarray,
            sv: np.ndarray, pv: np.ndarray, pd: np.ndarray, jerk: float) -> None:
        xe = np.r_[0.0, x, 0.0]
        de = np.r_[0.0, d, 0.0]
        nv = sv[:-1] ** 2 + sv[1:] ** 2  # the variance of x's own noise
        self.s += float(np.sum(x * dq))
        self.d += float(np.sum(x * x - nv))
        self.var += float(np.sum(sp**2 * (xe[:-1] - xe[1:]) ** 2)
                          + np.sum(sv**2 * (de[:-1] * xe[:-1] + de[1:] * xe[1:]) ** 2) / 4
                          + np.sum(x * x * pv))
        self.var2 += float(np.sum(nv * (sp[:-1] ** 2 + sp[1:] ** 2 + d * d * nv / 4 + pv))
                           + np.sum(x * x * nv) * MAX_VEL_LAG_S**2)
        self.det += float(np.sum(np.abs(x) * pd))
        self.ax += float(np.sum(np.abs(x) * jerk * d))
        self.n += int(x.size)

    def estimate(self, k: float) -> dict[str, Any] | None:
        """``{offset_s, interval_s, sd_s, deterministic_s, pairs}``: the velocity's lag L
        (velocity stamp = true time of the velocity + L) or None without information."""
        if self.n < 8 or self.d <= 0:
            return None
        lag = self.s / self.d
        sd = math.sqrt(self.var + self.var2) / self.d
        lb = abs(lag) + k * sd
        det = (self.det + 0.5 * lb * lb * self.ax) / self.d
        half = k * sd + det
        return {"offset_s": lag, "interval_s": [lag - half, lag + half], "sd_s": sd,
                "deterministic_s": det, "pairs": self.n, "k": k}


def step_check(
    ctx: Any, a_fam: float, t_span: tuple[float, float], sm: Any = None
) -> tuple[list[Violation], dict[str, Any]]:
    """A step in the GNSS positions (multipath moving a run of fixes) against the GNSS
    velocity integrated by the trapezoid rule: ``q_i = p_i - P_i`` (P the integral) is
    constant but for noise, so the difference of the means of ``q`` over ``m`` fixes
    before and after each split must stay within ``det + k sigma``: ``det`` the
    trapezoid's error bound (max jerk x dt^3 / 12 per pair, weighted by the pair's
    triangular weight in ``D``), sigma from the positions' and the velocities' stated
    Gaussian errors (exact for those weights, :func:`_vel_var`). With the smoother's
    result ``sm``, the IMU corrects the trapezoid (:func:`imu_trapezoid`): its centre
    enters ``q``, its white noise sigma and its bound replace the jerk bound pair by
    pair. Runs of consecutive fixes only (gaps > 2.5 x the median interval split
    them)."""
    from scipy.stats import norm

    ag = ctx.aiding
    if not (ag.has_gnss and ag.has_gvel) or ag.gvel_sig.size != ag.gnss_t.size:
        return [], {}
    t = ag.gnss_t
    okv = ag.gvel_ok
    dt = np.diff(t)
    if dt.size < 8:
        return [], {}
    med = float(np.median(dt))
    # segments of consecutive fixes with velocities
    brk = np.flatnonzero((dt > 2.5 * med) | ~okv[1:] | ~okv[:-1])
    bounds = np.concatenate([[0], brk + 1, [t.size]])
    steps: dict[str, list[float]] = {str(m): [] for m in STEP_LENGTHS}
    chat, cvar, cdet = imu_trapezoid(ctx, sm, t)
    cand = []
    lag = _LagSums()
    single: list[tuple[np.ndarray, int, np.ndarray, np.ndarray, np.ndarray]] = []
    for a, b in zip(bounds[:-1], bounds[1:], strict=True):
        n = b - a
        if n < 2 * STEP_LENGTHS[0]:
            continue
        tt = t[a:b]
        d = np.diff(tt)
        pd_, pv_ = cdet[a:b - 1], cvar[a:b - 1]
        for ax, (p, v) in enumerate(((ag.gnss_e, ag.gvel_e), (ag.gnss_n, ag.gvel_n))):
            pp, vv = p[a:b], v[a:b]
            P = np.concatenate([[0.0], np.cumsum(0.5 * (vv[1:] + vv[:-1]) * d - chat[a:b - 1, ax])])
            q = pp - P
            lag.add(np.diff(q), np.diff(vv), d, ag.gnss_sig[a:b], ag.gvel_sig[a:b], pv_, pd_,
                    ctx.vehicle.max_jerk)
            cq = np.concatenate([[0.0], np.cumsum(q)])
            cs = np.concatenate([[0.0], np.cumsum(ag.gnss_sig[a:b] ** 2)])
            cv = np.concatenate([[0.0], np.cumsum((ag.gvel_sig[a:b] * np.r_[d, d[-1]]) ** 2)])
            cv = cv + np.concatenate([[0.0], np.cumsum(np.r_[pv_, 0.0])])
            cd = np.concatenate([[0.0], np.cumsum(pd_)])
            for m in STEP_LENGTHS:
                if 2 * m > n:
                    break
                i = np.arange(m, n - m + 1, max(1, m // 2))
                D = (cq[i + m] - cq[i]) / m - (cq[i] - cq[i - m]) / m
                vv2, _ = _vel_var(i, m, d, ag.gvel_sig[a:b])
                var = (cs[i + m] - cs[i - m]) / m**2 + vv2 + _pair_sums(i, m, pv_, 2)
                det = _pair_sums(i, m, pd_, 1)
                cand.append((a, ax, m, i, D, var, det))
            # each fix against the mean of its NB neighbours on each side
            M = NB
            if n >= 2 * M + 1:
                jn = np.arange(M, n - M)
                r = q[jn] - (cq[jn + M + 1] - cq[jn - M] - q[jn]) / (2 * M)
                sj2 = ag.gnss_sig[a:b][jn] ** 2
                var = sj2 + (cs[jn + M + 1] - cs[jn - M] - sj2) / (2 * M) ** 2 + (
                    cv[jn + M + 1] - cv[jn - M]
                )
                det = cd[jn + M] - cd[jn - M]
                single.append((a + jn, ax, r, np.sqrt(var), det))
    n_tests = sum(c[3].size for c in cand)
    if not n_tests:
        return [], {}
    a_fam = a_fam / 3  # steps (+ the velocity's lag), single fixes, tails
    k = float(norm.isf(a_fam / (2 * (n_tests + 1))))
    vlag = lag.estimate(k)
    worst: tuple[float, int, int, int, float, float] | None = None
    for a, ax, m, i, D, var, det in cand:
        lim = det + k * np.sqrt(var)
        steps[str(m)].extend(lim.tolist())
        ex = np.abs(D) - lim
        j = int(np.argmax(ex))
        if ex[j] > 0 and (worst is None or ex[j] / lim[j] > worst[0]):
            worst = (float(ex[j] / lim[j]), a + int(i[j]), m, ax, float(D[j]), float(lim[j]))
    t0 = ctx.imu.t0
    summary = {
        "unit": "m",
        "level": a_fam,
        "k": k,
        "steps_unnoticed": {m: float(np.median(v)) for m, v in steps.items() if v},
        "steps_rule": "median over the splits of det + k sigma for m fixes before and after "
        "a split: a position step of a run at least m fixes long and smaller than this "
        "goes unnoticed by this test",
    }
    viol = []
    cause = "multipath or a position step"
    if vlag is not None:
        vlag["rule"] = VEL_LAG_RULE
        summary["velocity_lag"] = vlag
        lo, hi = vlag["interval_s"]
        if lo > 0 or hi < 0:
            cause = (f"or the GNSS velocity {vlag['offset_s']:+.3f} s late against its "
                     "positions, found by the velocity lag test")
            viol.append(Violation(
                "gnss velocity", *t_span, TEST_VEL_LAG,
                f"the receiver's velocity is {vlag['offset_s']:+.3f} s [{lo:+.3f}, {hi:+.3f}] "
                "late against its own positions (a latency of the receiver's velocity "
                "solution, or its stamps): the velocity intervals and the integrated "
                "velocity of the step tests assume both at the same instant; the GNSS clock "
                "offset from the receiver's course (timing.gnss) is the velocity's",
                (float(t[0] + ctx.imu.t0), float(t[-1] + ctx.imu.t0))))
    if single:
        from scipy.stats import binom

        idx = np.concatenate([x[0] for x in single])
        r = np.concatenate([x[2] for x in single])
        sd = np.concatenate([x[3] for x in single])
        det = np.concatenate([x[4] for x in single])
        k1 = float(norm.isf(a_fam / (2 * r.size)))
        ex = np.abs(r) - det - k1 * sd
        j = int(np.argmax(ex))
        summary["single_fix_unnoticed_m"] = float(np.median(det + k1 * sd))
        if ex[j] > 0:
            tj = float(t[idx[j]] + t0)
            viol.append(
                Violation(
                    "gnss position",
                    *t_span,
                    TEST_FIX,
                    f"the fix at t = {tj:.2f} s is {r[j]:+.3g} m off the mean of its "
                    f"{2 * NB} neighbours (relative to the integrated GNSS velocity), beyond "
                    f"the {float(det[j] + k1 * sd[j]):.3g} m the error model allows",
                    (tj, tj),
                )
            )
        p_tail = 2 * float(norm.sf(TAIL_K))
        n_tail = int(np.sum(np.maximum(np.abs(r) - det, 0.0) / sd > TAIL_K))
        q_tail = int(binom.isf(a_fam, r.size, p_tail))
        summary["tail_count"], summary["tail_limit"] = n_tail, q_tail
        if n_tail > q_tail:
            viol.append(
                Violation(
                    "gnss position",
                    *t_span,
                    TEST_TAILS,
                    f"{n_tail} of {r.size} fix residual(s) against their neighbours beyond "
                    f"{TAIL_K:g} sigma, more than the {q_tail} the Gaussian error model "
                    "allows: the GNSS errors have heavier tails than stated",
                    (float(t[0] + t0), float(t[-1] + t0)),
                )
            )
    if worst is not None:
        _, i0, m, ax, D, lim = worst
        ta, tb = float(t[i0 - m] + t0), float(t[min(i0 + m - 1, t.size - 1)] + t0)
        viol.append(
            Violation(
                "gnss position",
                *t_span,
                TEST_STEP,
                f"at t = {t[i0] + t0:.2f} s the mean position of the {m} fixes after moves "
                f"{D:+.3g} m {['east', 'north'][ax]} against the {m} before, relative to the "
                f"integrated GNSS velocity, beyond the {lim:.3g} m the error model allows "
                f"({cause})",
                (ta, tb),
            )
        )
    return viol, summary


def residual_checks(
    ctx: Any, sm: Any, alpha: float, t_span: tuple[float, float]
) -> tuple[list[Violation], dict[str, Any]]:
    """Violations of the residual checks and their summary (dynamic.json
    ``residual_checks``)."""
    from scipy.stats import binom, norm

    fams = _families(ctx, sm)
    t0 = ctx.imu.t0
    viol: list[Violation] = []
    summary: dict[str, Any] = {}
    if not fams:
        return viol, summary
    has_step = ctx.aiding.has_gnss and ctx.aiding.has_gvel
    a_fam = alpha / (2 * len(fams) + int(has_step))  # runs and tails of every family
    if has_step:
        sv, ss = step_check(ctx, a_fam, t_span, sm)
        viol += sv
        if ss:
            summary["gnss position step"] = ss
    for f in fams:
        n, axes = f.r.shape
        wins = _windows(n)
        n_tests = sum(st.size for _, st in wins) * axes
        k = float(norm.isf(a_fam / (2 * max(n_tests, 1))))
        cr = np.vstack([np.zeros((1, axes)), np.cumsum(f.r, 0)])
        cw = np.vstack([np.zeros((1, axes)), np.cumsum(f.w, 0)])
        cs = np.concatenate([[0.0], np.cumsum(f.s**2)])
        worst: tuple[float, int, int, int] | None = None  # excess, m, start, axis
        steps: dict[str, float] = {}
        for m, st in wins:
            mr = (cr[st + m] - cr[st]) / m
            mw = (cw[st + m] - cw[st]) / m
            lim = mw + f.det + (k * np.sqrt(cs[st + m] - cs[st]) / m)[:, None]
            ex = np.abs(mr) - lim
            steps[str(m)] = float(np.median(lim)) * f.scale
            j = np.unravel_index(int(np.argmax(ex)), ex.shape)
            if ex[j] > 0 and (worst is None or ex[j] / lim[j] > worst[0]):
                worst = (float(ex[j] / lim[j]), m, int(st[j[0]]), int(j[1]))
        # tails
        p_tail = 2 * float(norm.sf(TAIL_K))
        z = np.maximum(np.abs(f.r) - f.w - f.det, 0.0) / f.s[:, None]
        n_tail = int(np.sum(z > TAIL_K))
        q_tail = int(binom.isf(a_fam, n * axes, p_tail)) if n * axes else 0
        summary[f.stream] = {
            "unit": f.out_unit,
            "n": n,
            "level": 2 * a_fam,
            "runs_k": k,
            "steps_unnoticed": steps,
            "steps_rule": "median over the runs of m measurements of mean half-width + "
            "deterministic bound + k sigma / sqrt(m): a step of a run this long and "
            "smaller goes unnoticed",
            "tail_count": n_tail,
            "tail_limit": q_tail,
        }
        if worst is not None:
            _, m, s0, ax = worst
            ta, tb = float(f.t[s0] + t0), float(f.t[s0 + m - 1] + t0)
            mr = float((cr[s0 + m, ax] - cr[s0, ax]) / m)
            mw = float((cw[s0 + m, ax] - cw[s0, ax]) / m)
            lim = mw + f.det + k * math.sqrt(cs[s0 + m] - cs[s0]) / m
            axis = ["east", "north"][ax] if axes == 2 else ""
            viol.append(
                Violation(
                    f.stream,
                    *t_span,
                    TEST_RUNS,
                    f"{m} measurement(s) at {ta:.2f}..{tb:.2f} s: mean residual "
                    f"{axis + ' ' if axis else ''}{mr * f.scale:+.3g} {f.out_unit} against the "
                    f"smoothed states, beyond the {lim * f.scale:.3g} {f.out_unit} the "
                    "assumptions allow (a step, a clock lag or an error larger than stated)",
                    (ta, tb),
                )
            )
        if n_tail > q_tail:
            viol.append(
                Violation(
                    f.stream,
                    *t_span,
                    TEST_TAILS,
                    f"{n_tail} of {n} residual(s) beyond {TAIL_K:g} sigma outside the smoothed "
                    f"interval, more than the {q_tail} the Gaussian error model allows: the "
                    "errors have heavier tails than stated",
                    (float(f.t[0] + t0), float(f.t[-1] + t0)),
                )
            )
    return viol, summary
