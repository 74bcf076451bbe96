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
from typing import Any

import numpy as np

from imubounds.dynamic.estimator.budget import Term, k_two_sided
from imubounds.interval.rounding import down as _dn
from imubounds.interval.rounding import up as _up
from imubounds.units import DEG

#: spacing of the reference epochs (GNSS fixes taken as nodes), s
REF_STEP_S = 1.0
#: chord half-lengths in node steps (chords of about 4 to 128 s)
HALF_NODES = (2, 4, 8, 16, 32, 64)
#: bisection steps over [-max tilt, max tilt] (resolution 2 max_tilt / 2^steps)
BISECT = 16
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

    def narrows(self, max_tilt: float) -> bool:
        return bool(np.any(self.hi - self.lo < 2 * max_tilt * (1 - 1e-9)))


def applicable(drive: Any, vehicle: Any, opts: dict[str, Any], available: dict[str, bool]) -> bool:
    """Whether the method runs (decided before the alpha plan: its events are counted
    then): a ground vehicle with a stated lateral bound, that does not reverse, GNSS
    altitude and velocity in use, gyro_y and gyro_z, and no attitude stream in use."""
    g = drive.gnss
    if vehicle.kind != "ground" or vehicle.lateral_speed_bound_mps is None:
        return False
    if opts.get("reverses") or not opts.get("use_gnss", True):
        return False
    if not opts.get("use_gnss_velocity", True) or not opts.get("use_gnss_altitude", True):
        return False
    if drive.attitude is not None and opts.get("use_attitude", True):
        return False
    if g is None or g.alt_m is None or g.velocity_ne() is None:
        return False
    if not (available.get("gyro_y") and available.get("gyro_z")):
        return False
    return bool(np.sum(np.isfinite(np.asarray(g.alt_m, float)) & g.usable()) >= 5)


def interval_events(n_fix: int, duration_s: float) -> int:
    """Events the method adds to the ``imu_intervals`` family (an upper bound: per
    reference epoch, each chord's two halves and the two spans next to it, each a
    reflection-principle bound counted twice)."""
    n_ref = min(int(n_fix), int(duration_s / REF_STEP_S) + 2)
    return n_ref * (2 * len(HALF_NODES) + 2) * 2


def _nodes(t: np.ndarray, ok: np.ndarray) -> np.ndarray:
    """Indices of the fixes taken as nodes: the first usable one of each REF_STEP_S bin."""
    idx = np.flatnonzero(ok)
    if idx.size == 0:
        return idx
    b = np.floor((t[idx] - t[idx[0]]) / REF_STEP_S)
    first = np.concatenate([[True], np.diff(b) > 0])
    return idx[first]


def _speed_hull(
    tn: np.ndarray, s_lo: np.ndarray, s_hi: np.ndarray, amax: float, smax: float
) -> tuple[np.ndarray, np.ndarray]:
    """Bounds of the horizontal speed over each span between nodes: from both ends, the
    speed moves by at most ``max_accel`` per s (``max_accel`` bounds the horizontal
    acceleration, centripetal part included)."""
    d = np.diff(tn)
    a = max(amax, 1e-12)
    L0, L1 = s_lo[:-1], s_lo[1:]
    x = np.clip((L0 - L1 + a * d) / (2 * a), 0.0, d)
    lo = np.maximum(L0 - a * x, 0.0)
    H0, H1 = s_hi[:-1], s_hi[1:]
    y = np.clip((H1 - H0 + a * d) / (2 * a), 0.0, d)
    hi = np.minimum(H0 + a * y, smax)
    return _dn(lo), _up(np.maximum(hi, lo))


def _gyro_parts(ctx: Any, m: float) -> tuple[Any, ...]:
    """Cumulative gyro_y integral and deterministic rate-error integral at the IMU
    boundaries, the bias bound b (rad/s), white density, quantization term, edge term."""
    imu, noise, E0 = ctx.imu, ctx.noise, ctx.E0
    veh = ctx.vehicle
    bnd = imu.bnd
    dl = np.diff(bnd)

    def mag(ch: str) -> np.ndarray:
        s = imu.sig[ch]
        if not imu.available.get(ch, False):
            return np.full(dl.size, veh.max_rate)
        x = (np.abs(s.y) + E0[ch]) / (1.0 - noise[ch].scale)
        return np.where(s.unknown, veh.max_rate, x)

    qs = imu.sig["gyro_y"]
    cq = noise["gyro_y"]
    aq, ap, ar = mag("gyro_y"), mag("gyro_x"), mag("gyro_z")
    rho = (cq.scale * aq + cq.misalignment_rad * (ap + ar) + aq * (1.0 - math.cos(m))
           + ar * math.sin(m))
    # an unknown span: the gyro_y integral there is not measured (y = 0): + max rate
    rho = rho + np.where(qs.unknown, veh.max_rate, 0.0)
    C = np.concatenate([[0.0], np.cumsum(qs.y * dl)])
    P = np.concatenate([[0.0], np.cumsum(rho * dl)]) * (1 + 1e-9)
    k_to = ctx.alpha.k("imu_turn_on")
    wd = ctx.wander["gyro_y"]
    model = ctx.k_ps * cq.flicker_sigma() + wd.kr
    wander_pt = float(wd.pick(model, wd.point))
    b = cq.turn_on_bound(k_to) + wander_pt
    const = 2.0 * ctx.k_ps * cq.Q + 2.0 * veh.max_ang_accel * imu.max_len**2 + 1e-9
    return C, P, b, cq.N, const


def _rows(lo_base: np.ndarray, w: np.ndarray, ulo: np.ndarray, uhi: np.ndarray,
          m: float, theta: np.ndarray, upper: bool) -> np.ndarray:
    """Lower (``upper`` False) or upper bound of ``int u sin(theta)`` over each chord's
    spans for the candidate ``theta(t_r)`` per row."""
    x = np.clip(theta[:, None] + lo_base, -m, m)
    s = np.sin(x)
    if upper:
        v = np.where(s >= 0, uhi * s, ulo * s)
    else:
        v = np.where(s >= 0, ulo * s, uhi * s)
    return np.sum(v * w, axis=1)


def _bisect(f: Any, target: np.ndarray, m: float, n: int, sup: bool) -> tuple[np.ndarray, np.ndarray]:
    """``sup``: the least upper bound of {theta: f(theta) <= target} (f nondecreasing);
    else the greatest lower bound of {theta: f(theta) >= target}. Returns (bound, ok);
    ok False where the set is empty."""
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
    h_fix = _up(k_alt * ratio * ag.gnss_sig * (1 + 1e-12) + lev3 + dtr * vz)
    b0, b1 = float(imu.bnd[0]), float(imu.bnd[-1])
    t = ag.gnss_t
    ok = np.isfinite(ag.gnss_alt) & ag.gvel_ok & (t > b0) & (t < b1)
    nd = _nodes(t, ok)
    if nd.size < 2 * HALF_NODES[0] + 1:
        return None
    tn, an, hn = t[nd], ag.gnss_alt[nd], h_fix[nd]
    sp = np.hypot(ag.gvel_e[nd], ag.gvel_n[nd])
    s_lo, s_hi = _speed_hull(tn, sp - ag.gvel_hi[nd], sp + ag.gvel_hi[nd], veh.max_accel,
                             veh.max_speed)
    c = np.sqrt(np.maximum(s_lo**2 - vh**2, 0.0)) - E * math.sin(m)
    ulo = _dn(np.where(c >= 0, c, c / math.cos(m)) * (1 - 1e-12))
    uhi = _up((s_hi + E * math.sin(m)) / math.cos(m) * (1 + 1e-12))
    irregular = ulo < 0  # near standstill: the span's u sin(theta) taken as a slack
    umax = np.maximum(np.abs(ulo), uhi)
    dspan = np.diff(tn)
    slack_span = np.where(irregular, umax * math.sin(m) * dspan, 0.0)
    ulo_r = np.where(irregular, 0.0, ulo)
    uhi_r = np.where(irregular, 0.0, uhi)
    # gyro parts at the nodes and the hull of the gyro_y integral over each span
    C, P, b, N, const = _gyro_parts(ctx, m)
    bnd = imu.bnd
    Cn = np.interp(tn, bnd, C)
    Pn = np.interp(tn, bnd, P)
    from imubounds.dynamic.estimator.inputs import RangeExt

    i0 = np.searchsorted(bnd, tn[:-1], side="right")
    i1 = np.searchsorted(bnd, tn[1:], side="left") - 1
    has = i1 >= i0
    mn, mx = RangeExt(C).query(np.where(has, i0, 0), np.where(has, i1, 0))
    Cmin = np.minimum(np.minimum(Cn[:-1], Cn[1:]), np.where(has, mn, np.inf))
    Cmax = np.maximum(np.maximum(Cn[:-1], Cn[1:]), np.where(has, mx, -np.inf))
    tol = 1e-9 * (1.0 + np.abs(C).max())
    Cmin, Cmax = Cmin - tol, Cmax + tol
    k_w = alpha.k("imu_intervals")
    nn = tn.size
    lo_r = np.full(nn, -m)
    hi_r = np.full(nn, m)
    bad = np.zeros(nn, bool)
    for h in HALF_NODES:
        r = np.arange(h, nn - h)
        if r.size == 0:
            continue
        K = (r - h)[:, None] + np.arange(2 * h)[None, :]  # span indices of each chord
        tr = tn[r][:, None]
        right = K >= r[:, None]
        far = np.where(right, tn[K + 1], tn[K])
        Pfar = np.where(right, Pn[K + 1], Pn[K])
        half = np.maximum(tn[r] - tn[r - h], tn[r + h] - tn[r])
        delta = (np.abs(Pfar - Pn[r][:, None]) + b * np.abs(far - tr)
                 + (k_w * N * np.sqrt(half) + const)[:, None])
        Cr = Cn[r][:, None]
        base_lo = np.maximum(-(Cmax[K] - Cr) - delta, -2.0 * m)
        base_hi = np.minimum(-(Cmin[K] - Cr) + delta, 2.0 * m)
        w = dspan[K]
        ul, uh = ulo_r[K], uhi_r[K]
        dalt = an[r + h] - an[r - h]
        L = tn[r + h] - tn[r - h]
        slack = hn[r + h] + hn[r - h] + E * L + slack_span[K].sum(axis=1)
        eps = 1e-9 * (np.abs(dalt) + slack + uhi.max() * L)
        a_hi = dalt + slack + eps
        a_lo = dalt - slack - eps
        th_max, ok_max = _bisect(lambda th: _rows(base_lo, w, ul, uh, m, th, False),
                                 a_hi, m, r.size, True)
        th_min, ok_min = _bisect(lambda th: _rows(base_hi, w, ul, uh, m, th, True),
                                 a_lo, m, r.size, False)
        bad[r] |= ~(ok_max & ok_min)
        lo_r[r] = np.maximum(lo_r[r], th_min)
        hi_r[r] = np.minimum(hi_r[r], th_max)
    bad |= lo_r > hi_r
    lo_r = np.where(bad, -m, lo_r)
    hi_r = np.where(bad, m, hi_r)
    # each span: the two nodes' intervals propagated over it, intersected
    dP = Pn[1:] - Pn[:-1]
    dd = dspan
    dspan_w = k_w * N * np.sqrt(dd) + const + b * dd + dP
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
    plo = _dn(np.concatenate([[-m], plo, [-m]]) * (1 + 1e-12) - 1e-12)
    phi = _up(np.concatenate([[m], phi, [m]]) * (1 + 1e-12) + 1e-12)
    plo, phi = np.maximum(plo, -m), np.minimum(phi, m)
    hw = 0.5 * (phi - plo)
    out = PitchBoxes(pb, plo, phi, median_halfwidth=float(np.median(hw[1:-1])))
    out.infeasible = _bad_spans(tn, bad) if np.any(bad) else []
    defaulted = "gnss.vertical_sigma_ratio" in getattr(st, "defaulted", [])
    src_ratio = "default" if defaulted else "drive.yaml"
    out.budget = [
        Term("vertical sigma ratio", ratio, "x horizontal sigma per axis", src_ratio,
             "each fix's altitude error is Gaussian with 1-sigma = this x the fix's "
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
