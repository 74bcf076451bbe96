"""Pitch intervals without an attitude stream: GNSS altitude chords, the non-holonomic
bounds of a ground vehicle and the gyros (docs/dynamic-method.md, section 3a, "Pitch from
GNSS altitude").

With ``n = sin(roll) v + cos(roll) w`` (the IMU's velocity off its x axis in the vertical
plane of the heading, ``|n| <= E = sin(max tilt) V + W``), the up velocity is
``u sin(theta) + n cos(theta)``, so over fixes ``i < j``::

    alt_j - alt_i = int u sin(theta) + int n cos(theta) + e_j - e_i,

``|e| <= h`` (each fix's vertical bound: ``gnss.vertical_sigma_ratio`` x the horizontal
1-sigma per axis, ``k`` of the ``gnss_position`` family, + the lever arm, + the GNSS clock
remainder x the vertical speed bound). The pitch between epochs follows the gyros,
``theta' = -q cos(roll) + r sin(roll)``::

    theta(t) = theta(t_r) - int_{t_r}^t y_q  +- Delta(t),
    Delta = int [s|q| + m(|p| + |r|) + |q|(1 - cos phi_m) + |r| sin phi_m]
            + b |t - t_r| + k_w N sqrt(half chord) + 2 k_ps Q + edge,

``b`` the gyro_y turn-on bound plus its per-sample wander bound (:class:`budget.Wander`),
the white part by the reflection principle (``k_w`` of the ``imu_intervals`` family, two
events per bound). Per reference epoch ``t_r`` (GNSS nodes about :data:`REF_STEP_S`
apart) and per chord of ``2 h`` node steps centred on it (:data:`HALF_NODES`), the
``theta(t_r)`` for which the altitude change is reachable form an interval (``int u
sin(theta)`` is monotone in ``theta(t_r)``: bisection, all chords at once); the chords'
intervals are intersected, and each span between two nodes gets the intersection of
the two nodes' intervals propagated over it. A chord with no feasible pitch withdraws
nothing silently: it is a violation (``pitch from GNSS altitude``) and the span keeps
``+-max tilt``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from imubounds.constants import EARTH_RATE, R_EARTH_MIN, ROUND_REL
from imubounds.dynamic.estimator.budget import Term, k_two_sided
from imubounds.interval.rounding import down as _dn
from imubounds.interval.rounding import up as _up
from imubounds.units import DEG

if TYPE_CHECKING:
    from imubounds.dynamic.estimator.options import FullOptions

#: spacing of the reference epochs (GNSS fixes taken as nodes), s
REF_STEP_S = 1.0
#: chord half-lengths in node steps (chords of about 4 to 128 s)
HALF_NODES = (2, 4, 8, 16, 32, 64)
#: integration cells per span between two nodes (the speed hull's resolution)
SPLIT = 2
#: bisection steps over [-max tilt, max tilt] (resolution 2 max_tilt / 2^steps)
BISECT = 12
#: name of the failed check (violations)
TEST_PITCH = "pitch from GNSS altitude (altitude chords against the gyro-propagated pitch)"


@dataclass
class PitchBoxes:
    """Piecewise-constant pitch intervals on ``bnd`` (relative s), with their budget."""

    bnd: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    budget: list[Term] = field(default_factory=list)
    infeasible: list[tuple[float, float]] = field(default_factory=list)
    median_halfwidth: float = math.inf
    #: the reference epochs (relative s) and their intervals (before the spans)
    nodes: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None

    def narrows(self, max_tilt: float) -> bool:
        return bool(np.any(self.hi - self.lo < 2 * max_tilt * (1 - 1e-9)))


#: the method runs only when gyro_y's bias (a settings-only estimate: the turn-on bound
#: or 5 sigma, plus the stated drift bound or 5 flicker sigmas) moves the pitch by less
#: than this fraction of the max tilt over the shortest chord's half
USEFUL_FRACTION = 0.5


def applicable(drive: Any, vehicle: Any, opts: FullOptions, available: dict[str, bool],
               noise: dict[str, Any]) -> bool:
    """Whether the method runs, decided from the settings alone before the alpha plan
    (its events are counted then, whatever the data): a ground vehicle with a stated
    lateral bound, that does not reverse, GNSS altitude and velocity in use, gyro_y and
    gyro_z, no attitude stream in use, and a gyro_y whose bias can leave the pitch
    narrower than the max tilt (:data:`USEFUL_FRACTION`)."""
    cq = noise["gyro_y"]
    drift = cq.drift_bound if cq.drift_bound is not None else 5.0 * cq.flicker_sigma()
    b_est = cq.turn_on_bound(5.0) + drift
    if b_est * HALF_NODES[0] * REF_STEP_S >= USEFUL_FRACTION * vehicle.max_tilt:
        return False
    g = drive.gnss
    if vehicle.kind != "ground" or vehicle.lateral_speed_bound_mps is None:
        return False
    if opts.reverses or not opts.use_gnss:
        return False
    if not opts.use_gnss_velocity or not opts.use_gnss_altitude:
        return False
    if drive.attitude is not None and opts.use_attitude:
        return False
    if g is None or g.alt_m is None or g.velocity_ne() is None:
        return False
    if not (available.get("gyro_y") and available.get("gyro_z")):
        return False
    return bool(np.sum(np.isfinite(np.asarray(g.alt_m, float)) & g.usable()) >= 5)


def interval_events(n_fix: int, duration_s: float) -> int:
    """Events the method adds to the ``imu_intervals`` family (an upper bound: per
    reference epoch, each chord's two halves and the two spans next to it, each a
    reflection-principle bound of the white noise counted twice, and the deviation of the
    rate-error magnitudes once)."""
    n_ref = min(int(n_fix), int(duration_s / REF_STEP_S) + 2)
    return n_ref * (2 * len(HALF_NODES) + 2) * 3


def _nodes(t: np.ndarray, ok: np.ndarray) -> np.ndarray:
    """Indices of the fixes taken as nodes: the first usable one of each REF_STEP_S bin."""
    idx = np.flatnonzero(ok)
    if idx.size == 0:
        return idx
    b = np.floor((t[idx] - t[idx[0]]) / REF_STEP_S)
    first = np.concatenate([[True], np.diff(b) > 0])
    return idx[first]


def _cells(tn: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Boundaries of the integration cells (each span between nodes cut in :data:`SPLIT`
    equal parts) and each cell's span."""
    d = np.diff(tn)
    frac = np.arange(SPLIT) / SPLIT
    tc = np.concatenate([(tn[:-1, None] + d[:, None] * frac[None, :]).ravel(), tn[-1:]])
    return tc, np.repeat(np.arange(d.size), SPLIT)


def _speed_hull(
    tn: np.ndarray, tc: np.ndarray, span: np.ndarray, s_lo: np.ndarray, s_hi: np.ndarray,
    amax: float, smax: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Bounds of the horizontal speed over each cell ``[tc[c], tc[c + 1]]`` of a span
    between two nodes: from both ends the speed moves by at most ``max_accel`` per s
    (``max_accel`` bounds the horizontal acceleration, centripetal part included)."""
    a = max(amax, 1e-12)
    t0, t1 = tn[span], tn[span + 1]
    d = t1 - t0
    xa, xb = tc[:-1] - t0, tc[1:] - t0
    L0, L1 = s_lo[span], s_lo[span + 1]
    x = np.clip((L0 - L1 + a * d) / (2 * a), xa, xb)
    lo = np.maximum(np.maximum(L0 - a * x, L1 - a * (d - x)), 0.0)
    H0, H1 = s_hi[span], s_hi[span + 1]
    y = np.clip((H1 - H0 + a * d) / (2 * a), xa, xb)
    hi = np.minimum(np.minimum(H0 + a * y, H1 + a * (d - y)), smax)
    return _dn(lo * (1 - ROUND_REL)), _up(np.maximum(hi, lo) * (1 + ROUND_REL))


def _bias_bound(ctx: Any, ch: str) -> float:
    """A channel's turn-on bound plus its per-sample wander bound (:class:`budget.Wander`:
    the model's flicker and K, R, or the stated drift bound's point bound)."""
    cn, wd = ctx.noise[ch], ctx.wander[ch]
    model = ctx.k_ps * cn.flicker_sigma() + wd.kr
    return float(cn.turn_on_bound(ctx.alpha.k("imu_turn_on")) + wd.pick(model, wd.point))


def _gyro_parts(ctx: Any, m: float) -> tuple[Any, ...]:
    """At the IMU boundaries: the cumulative gyro_y integral ``C`` and the integral ``P`` of
    the rate error's deterministic part ``sum_c a_c |x_c|`` (``a_q = s + 1 - cos(phi_m)``,
    ``a_p = m_q``, ``a_r = m_q + sin(phi_m)``; ``|x_c| <= (|y_c| + m_c |x_perp| + b_c +
    sigma_c sqrt(2/pi) + quantization) / (1 - s_c)``, the white part's mean absolute value
    with its deviation ``sigma_a`` left to the caller; + the Earth and transport rates
    ``Omega + v_max / R``); the gyro_y bias bound, white
    density, ``sigma_a`` (rad/s per sqrt(sample count)) and the constant terms."""
    imu, noise, E0 = ctx.imu, ctx.noise, ctx.E0
    veh = ctx.vehicle
    dl = np.diff(imu.bnd)
    dt = imu.dt
    cq = noise["gyro_y"]
    coef = {"gyro_y": cq.scale + 1.0 - math.cos(m), "gyro_x": cq.misalignment_rad,
            "gyro_z": cq.misalignment_rad + math.sin(m)}
    rho = np.zeros(dl.size)
    var = 0.0
    unknown = np.zeros(dl.size, bool)
    for ch, a in coef.items():
        cn = noise[ch]
        if not imu.available.get(ch, False):
            rho += a * veh.max_rate
            continue
        s = imu.sig[ch]
        unknown |= s.unknown
        perp = sum(np.abs(imu.sig[o].y) + E0[o] for o in coef if o != ch
                   and imu.available.get(o, False))
        sig_w = cn.N / math.sqrt(dt)
        quant = ctx.k_ps * math.sqrt(2.0) * cn.Q / dt
        x = (np.abs(s.y) + cn.misalignment_rad * perp + _bias_bound(ctx, ch)
             + sig_w * math.sqrt(2.0 / math.pi) + quant) / (1.0 - cn.scale)
        rho += a * x
        var += (a * sig_w / (1.0 - cn.scale)) ** 2
    # an unknown span: the rates there are not measured (y = 0 there): + the rate bound
    rho = np.where(unknown, rho + veh.max_rate * (1.0 + sum(coef.values())), rho)
    # the gyros measure the Earth rate and the transport rate too (the level frame turns)
    rho = rho + EARTH_RATE + veh.max_speed / R_EARTH_MIN
    # magnitudes from the sample means, as the smoother's links bound int |x| (full.py,
    # _link_errors: int |y| + E0 D over 1 - s): the sample model of the budget
    qs = imu.sig["gyro_y"]
    C = np.concatenate([[0.0], np.cumsum(qs.y * dl)])
    P = np.concatenate([[0.0], np.cumsum(rho * dl)]) * (1 + 1e-9)
    b = _bias_bound(ctx, "gyro_y")
    const = 2.0 * ctx.k_ps * cq.Q + 2.0 * veh.max_ang_accel * imu.max_len**2 + 1e-9
    # the deviation of sum_k dt a |w_k| over n samples from its mean: sub-Gaussian with
    # variance proxy n dt^2 sum a^2 sigma^2, i.e. sigma_a sqrt(dt T) over T s
    return C, P, b, cq.N, const, math.sqrt(var)


def _rows(cb: np.ndarray, sb: np.ndarray, wlo: np.ndarray, whi: np.ndarray,
          m: float, theta: np.ndarray, upper: bool) -> np.ndarray:
    """Lower (``upper`` False) or upper bound of ``int u sin(theta)`` over each chord's
    cells for the candidate ``theta(t_r)`` per row (``wlo``, ``whi``: the cells' speed
    bounds times their lengths): ``sin(clip(theta_r + base, -m, m))`` as
    ``clip(sin(theta_r) cos(base) + cos(theta_r) sin(base), -sin m, sin m)`` (base within
    +-2m, m < 30 deg: sin is monotone there), rounding widened outward."""
    sm = math.sin(m)
    s = np.sin(theta)[:, None] * cb + np.cos(theta)[:, None] * sb
    s = np.clip(s + (4e-16 if upper else -4e-16), -sm, sm)
    if upper:
        v = np.where(s >= 0, whi, wlo) * s
    else:
        v = np.where(s >= 0, wlo, whi) * s
    return np.asarray(v.sum(axis=1))


def _bisect(rows: tuple[np.ndarray, ...], target: np.ndarray, m: float,
            sup: bool) -> tuple[np.ndarray, np.ndarray]:
    """``sup``: the least upper bound of {theta: Lo(theta) <= target}; else the greatest
    lower bound of {theta: Hi(theta) >= target} (Lo, Hi of :func:`_rows` over ``rows``,
    both nondecreasing). Returns (bound, ok); ok False where the set is empty."""
    n = target.size

    def f(theta: np.ndarray) -> np.ndarray:
        cb, sb, wlo, whi = rows
        return _rows(cb, sb, wlo, whi, m, theta, not sup)

    lo = np.full(n, -m)
    hi = np.full(n, m)
    if sup:
        ok = f(lo) <= target
        full = f(hi) <= target
    else:
        ok = f(hi) >= target
        full = f(lo) >= target
    for _ in range(BISECT):
        mid = 0.5 * (lo + hi)
        good = f(mid) <= target if sup else f(mid) >= target
        if sup:
            lo = np.where(good, mid, lo)
            hi = np.where(good, hi, mid)
        else:
            hi = np.where(good, mid, hi)
            lo = np.where(good, lo, mid)
    if sup:
        return np.where(full, m, hi), ok
    return np.where(full, -m, lo), ok


def _c_hull(
    bnd: np.ndarray, C: np.ndarray, P: np.ndarray, tc: np.ndarray
) -> tuple[np.ndarray, ...]:
    """``C`` and ``P`` at the cell boundaries (linear inside a sample, as the sample
    model) and the hull of ``C`` over each cell (its values at the IMU boundaries inside
    and at the cell's ends), widened by its rounding."""
    from imubounds.dynamic.estimator.inputs import RangeExt

    Cc = np.interp(tc, bnd, C)
    Pc = np.interp(tc, bnd, P)
    i0 = np.searchsorted(bnd, tc[:-1], side="right")
    i1 = np.searchsorted(bnd, tc[1:], side="left") - 1
    has = i1 >= i0
    mn, mx = RangeExt(C).query(np.where(has, i0, 0), np.where(has, i1, 0))
    Cmin = np.minimum(np.minimum(Cc[:-1], Cc[1:]), np.where(has, mn, np.inf))
    Cmax = np.maximum(np.maximum(Cc[:-1], Cc[1:]), np.where(has, mx, -np.inf))
    tol = 1e-9 * (1.0 + float(np.abs(C).max()))
    return Cc, Pc, Cmin - tol, Cmax + tol


def pitch_boxes(ctx: Any) -> PitchBoxes | None:
    """The pitch intervals of the module docstring, or None when the drive has no nodes."""
    ag, veh, imu, alpha = ctx.aiding, ctx.vehicle, ctx.imu, ctx.alpha
    m = veh.max_tilt
    if m >= 30 * DEG or ag.gnss_alt.size != ag.gnss_t.size or not ag.has_gvel:
        return None
    V = float(veh.lateral_speed_bound_mps)
    W = veh.vertical_bound
    E = _up(math.sin(m) * V + W)
    vh = _up(V + math.sin(m) * W)
    st = ctx.drive.settings
    ratio = float(st.gnss.vertical_sigma_ratio)
    k_alt = k_two_sided(alpha.share(), alpha.counts.get("gnss_position", 0))
    lever = getattr(st, "lever_arm_m", None)
    lev3 = float(np.linalg.norm(lever)) if lever is not None else 0.0
    tm = ctx.timing.get("gnss")
    dtr = float(tm.remainder_s) if tm is not None and tm.applied else 0.0
    vz = veh.max_speed * math.sin(m) + E
    # the receiver's vertical accuracy where it gives one, else the ratio x horizontal
    va = ag.gnss_vacc if ag.gnss_vacc.size == ag.gnss_t.size else np.full(ag.gnss_t.size, np.nan)
    has_va = np.isfinite(va) & (va > 0)
    sig_v = np.where(has_va, va, ratio * ag.gnss_sig)
    h_fix = _up(k_alt * sig_v * (1 + ROUND_REL) + lev3 + dtr * vz)
    b0, b1 = float(imu.bnd[0]), float(imu.bnd[-1])
    t = ag.gnss_t
    ok = np.isfinite(ag.gnss_alt) & ag.gvel_ok & (t > b0) & (t < b1)
    nd = _nodes(t, ok)
    if nd.size < 2 * HALF_NODES[0] + 1:
        return None
    tn, an, hn = t[nd], ag.gnss_alt[nd], h_fix[nd]
    tc, span = _cells(tn)
    sp = np.hypot(ag.gvel_e[nd], ag.gvel_n[nd])
    s_lo, s_hi = _speed_hull(tn, tc, span, sp - ag.gvel_hi[nd], sp + ag.gvel_hi[nd],
                             veh.max_accel, veh.max_speed)
    c = np.sqrt(np.maximum(s_lo**2 - vh**2, 0.0)) - E * math.sin(m)
    c = np.where(c >= 0, c, c / math.cos(m))
    ulo = _dn(c - np.abs(c) * ROUND_REL)
    uhi = _up((s_hi + E * math.sin(m)) / math.cos(m) * (1 + ROUND_REL))
    irregular = ulo < 0  # near standstill: the cell's u sin(theta) taken as a slack
    dcell = np.diff(tc)
    slack_cell = np.where(irregular, np.maximum(-ulo, uhi) * math.sin(m) * dcell, 0.0)
    ulo_r = np.where(irregular, 0.0, ulo)
    uhi_r = np.where(irregular, 0.0, uhi)
    C, P, b, N, const, sig_a = _gyro_parts(ctx, m)
    Cc, Pc, Cmin, Cmax = _c_hull(imu.bnd, C, P, tc)
    k_w = alpha.k("imu_intervals")
    # the sub-Gaussian deviation of the rate-error magnitudes' white part (Doob's maximal
    # inequality for its exponential martingale): P <= exp(-k^2/2) at the family's share
    p_int = alpha.share() / max(1, alpha.counts.get("imu_intervals", 1))
    k_sg = math.sqrt(2.0 * math.log(1.0 / p_int))
    kn = k_w * N + k_sg * sig_a * math.sqrt(ctx.imu.dt)
    nn = tn.size
    lo_r = np.full(nn, -m)
    hi_r = np.full(nn, m)
    bad = np.zeros(nn, bool)
    for h in HALF_NODES:
        r = np.arange(h, nn - h)
        if r.size == 0:
            continue
        rc = r * SPLIT  # the reference's cell boundary
        K = (rc - h * SPLIT)[:, None] + np.arange(2 * h * SPLIT)[None, :]
        right = K >= rc[:, None]
        far = np.where(right, K + 1, K)
        half = np.maximum(tn[r] - tn[r - h], tn[r + h] - tn[r])
        delta = (np.abs(Pc[far] - Pc[rc][:, None]) + b * np.abs(tc[far] - tn[r][:, None])
                 + (kn * np.sqrt(half) + const)[:, None])
        Cr = Cc[rc][:, None]
        base_lo = np.maximum(-(Cmax[K] - Cr) - delta, -2.0 * m)
        base_hi = np.minimum(-(Cmin[K] - Cr) + delta, 2.0 * m)
        w = dcell[K]
        ul, uh = ulo_r[K], uhi_r[K]
        dalt = an[r + h] - an[r - h]
        L = tn[r + h] - tn[r - h]
        slack = hn[r + h] + hn[r - h] + E * L + slack_cell[K].sum(axis=1)
        eps = 1e-9 * (np.abs(dalt) + slack + uhi.max() * L)
        wlo, whi = _dn(ul * w), _up(uh * w)
        th_max, ok_max = _bisect((np.cos(base_lo), np.sin(base_lo), wlo, whi),
                                 dalt + slack + eps, m, True)
        th_min, ok_min = _bisect((np.cos(base_hi), np.sin(base_hi), wlo, whi),
                                 dalt - slack - eps, m, False)
        bad[r] |= ~(ok_max & ok_min)
        lo_r[r] = np.maximum(lo_r[r], th_min)
        hi_r[r] = np.minimum(hi_r[r], th_max)
    bad |= lo_r > hi_r
    lo_r = np.where(bad, -m, lo_r)
    hi_r = np.where(bad, m, hi_r)
    # span hulls of the gyro_y integral and the rate-error integral
    Cn, Pn = Cc[::SPLIT], Pc[::SPLIT]
    Cmin = np.minimum.reduceat(Cmin, np.arange(0, Cmin.size, SPLIT))
    Cmax = np.maximum.reduceat(Cmax, np.arange(0, Cmax.size, SPLIT))
    dspan = np.diff(tn)
    # each span: the two nodes' intervals propagated over it, intersected
    dspan_w = kn * np.sqrt(dspan) + const + b * dspan + (Pn[1:] - Pn[:-1])
    f_lo = lo_r[:-1] - (Cmax - Cn[:-1]) - dspan_w
    f_hi = hi_r[:-1] - (Cmin - Cn[:-1]) + dspan_w
    g_lo = lo_r[1:] - (Cmax - Cn[1:]) - dspan_w
    g_hi = hi_r[1:] - (Cmin - Cn[1:]) + dspan_w
    plo = np.clip(np.maximum(f_lo, g_lo), -m, m)
    phi = np.clip(np.minimum(f_hi, g_hi), -m, m)
    empty = plo > phi
    plo = np.where(empty, -m, plo)
    phi = np.where(empty, m, phi)
    pb = np.concatenate([[b0], tn, [b1]])
    plo = _dn(np.concatenate([[-m], plo, [-m]]) * (1 + ROUND_REL) - 1e-12)
    phi = _up(np.concatenate([[m], phi, [m]]) * (1 + ROUND_REL) + 1e-12)
    plo, phi = np.maximum(plo, -m), np.minimum(phi, m)
    hw = 0.5 * (phi - plo)
    out = PitchBoxes(pb, plo, phi, median_halfwidth=float(np.median(hw[1:-1])),
                     nodes=(tn, lo_r, hi_r))
    out.infeasible = _bad_spans(tn, bad) if np.any(bad) else []
    defaulted = "gnss.vertical_sigma_ratio" in getattr(st, "defaulted", [])
    src_ratio = "default" if defaulted else "drive.yaml"
    out.budget = [
        Term("vertical sigma ratio", ratio, "x horizontal sigma per axis", src_ratio,
             "each fix's altitude error is Gaussian with 1-sigma = the receiver's v_acc_m "
             f"(given at {int(has_va.sum())} of {has_va.size} fixes), else this x the fix's "
             "horizontal 1-sigma per axis"),
        Term("altitude bound (median)", float(np.median(hn)), "m", "computed",
             f"k = {k_alt:.3g} (gnss_position family, the altitude of each fix counted) x "
             "sigma + lever arm + GNSS clock remainder x vertical speed bound"),
        Term("off-axis velocity bound E", E, "m/s", "vehicle",
             "sin(max tilt) x lateral bound + vertical bound"),
        Term("gyro_y bias bound", b, "rad/s", "budget",
             "turn-on bound + per-sample wander bound of gyro_y"),
        Term("white noise factor", k_w, "x N sqrt(s)", "alpha plan",
             "reflection principle over each chord half (imu_intervals family)"),
        Term("median pitch half-width", out.median_halfwidth / DEG, "deg", "computed",
             f"{nn} nodes, chords of {2 * HALF_NODES[0]}..{2 * HALF_NODES[-1]} node steps"),
    ]
    return out


def _bad_spans(tn: np.ndarray, bad: np.ndarray) -> list[tuple[float, float]]:
    """Runs of reference epochs with no feasible pitch, as (start, end) relative s."""
    idx = np.flatnonzero(bad)
    out: list[tuple[float, float]] = []
    start = prev = int(idx[0])
    for i in idx[1:]:
        if i != prev + 1:
            out.append((float(tn[start]), float(tn[prev])))
            start = int(i)
        prev = int(i)
    out.append((float(tn[start]), float(tn[prev])))
    return out
