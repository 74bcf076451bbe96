"""The IMU's pitch against its path from the data (docs/dynamic-method.md, section 3b,
"Mount"): the mount's pitch on the vehicle plus the suspension's, which the
non-holonomic bounds take as bounded (``|w| <= W``: ``|delta| <= asin(W / u)`` at speed
u), checked here against the attitude states and GNSS altitude.

With ``delta = theta - gamma`` (``theta`` the IMU's pitch, ``gamma`` the elevation of
its velocity) constant over a chord of GNSS fixes ``i < j``::

    alt_j - alt_i = int V sin(theta - delta) dt + e_j - e_i,

``V`` the 3-D speed (within ``[S - R, (S + R) / cos(max tilt)]`` from the GNSS speed
``S`` and its radius ``R``, moving by at most ``max_accel`` per s between fixes),
``theta`` within the states' pieces, ``|e| <=`` each fix's vertical bound (the model of
``pitch_gnss``: ``gnss.vertical_sigma_ratio`` x the horizontal 1-sigma, ``k`` of the
``gnss_position`` family). The right side is decreasing in ``delta``, so each chord's
``delta`` is an interval (bisection); their intersection is the data's constant
``delta``. Where the non-holonomic bound at the chord's speed excludes it, the vertical
bound is contradicted: a failed check (a stated default is a claim, not a licence).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from imubounds.dynamic.estimator.budget import k_two_sided
from imubounds.units import DEG

#: chord lengths (s) and the spacing of their starts (s)
CHORDS_S = (60.0, 120.0, 240.0)
STEP_S = 10.0
#: bisection steps over [-2 max_tilt, 2 max_tilt]: 0.35 rad / 2**16 = 5e-6 rad (0.0003 deg); the
#: ends kept are the outer ones, so fewer steps only widen (30 steps cost 24 s of 131 s
#: on the 1 h, 10 Hz GNSS benchmark under load)
BISECT = 16
TEST_MOUNT = "attitude: the IMU's pitch against its path within the vertical bound"


def _chord_rows(te: np.ndarray, L: float) -> tuple[np.ndarray, np.ndarray]:
    starts = np.arange(te[0], te[-1] - L, STEP_S)
    i = np.searchsorted(te, starts)
    j = np.searchsorted(te, te[np.minimum(i, te.size - 1)] + L)
    ok = j < te.size
    return i[ok], j[ok]


def pitch_against_path(ctx: Any) -> dict[str, Any] | None:
    """The data's ``delta`` (see the module docstring), or None without GNSS altitude
    and velocity."""
    st = ctx.attitude
    ag, veh = ctx.aiding, ctx.vehicle
    if st is None or not ag.has_gvel or ag.gnss_alt.size != ag.gnss_t.size:
        return None
    te = st.te
    ig = np.searchsorted(ag.gnss_t, te)
    on = (ig < ag.gnss_t.size) & (ag.gnss_t[np.minimum(ig, ag.gnss_t.size - 1)] == te)
    ig = np.minimum(ig, ag.gnss_t.size - 1)
    good = on & ag.gvel_ok[ig] & np.isfinite(ag.gnss_alt[ig])
    if good.sum() < 10:
        return None
    tn = te[good]
    g = ig[good]
    alt = ag.gnss_alt[g]
    k = k_two_sided(ctx.alpha.share(), ctx.alpha.counts.get("gnss_position", 0) + g.size)
    ratio = float(ctx.drive.settings.gnss.vertical_sigma_ratio)
    va = ag.gnss_vacc[g] if ag.gnss_vacc.size == ag.gnss_t.size else np.full(g.size, np.nan)
    sig = np.where(np.isfinite(va) & (va > 0), va, ratio * ag.gnss_sig[g])
    h = k * sig
    S = np.hypot(ag.gvel_e[g], ag.gvel_n[g])
    R = ag.gvel_hi[g]
    d = np.diff(tn)
    m = veh.max_tilt
    v_lo = np.maximum(np.minimum(S[:-1] - R[:-1], S[1:] - R[1:]) - veh.max_accel * d / 2, 0.0)
    v_hi = (np.maximum(S[:-1] + R[:-1], S[1:] + R[1:]) + veh.max_accel * d / 2) / math.cos(m)
    # the states' pitch over each span between the nodes used
    pitch = st.angle("pitch", "full").pieces
    kk = np.searchsorted(te, tn[:-1])
    last = np.searchsorted(te, tn[1:]) - 1
    from imubounds.dynamic.estimator.inputs import RangeExt

    ext = RangeExt(pitch.lo, pitch.hi)
    th_lo, th_hi = ext.query(kk, np.maximum(last, kk))
    rows: list[tuple[float, float, float, float, float]] = []
    for L in CHORDS_S:
        i, j = _chord_rows(tn, L)
        if i.size == 0:
            continue
        dh = alt[j] - alt[i]
        e = h[i] + h[j]
        lo = np.full(i.size, -2 * m)
        hi = np.full(i.size, 2 * m)

        nl = int(np.max(j - i))
        K = i[:, None] + np.arange(nl)[None, :]
        inside = K < j[:, None]
        K = np.minimum(K, d.size - 1)
        tl, th, vl, vh = th_lo[K], th_hi[K], v_lo[K], v_hi[K]
        dd = np.where(inside, d[K], 0.0)

        def F(delta: np.ndarray, upper: bool, tl: np.ndarray = tl, th: np.ndarray = th,
              vl: np.ndarray = vl, vh: np.ndarray = vh, dd: np.ndarray = dd) -> np.ndarray:
            a = (th if upper else tl) - delta[:, None]
            s = np.sin(np.clip(a, -0.5 * math.pi, 0.5 * math.pi))
            v = np.where(s >= 0, vh if upper else vl, vl if upper else vh)
            return np.asarray(np.sum(v * s * dd, axis=1))

        # delta_max: F_hi(delta) >= dh - e (F decreasing); delta_min: F_lo <= dh + e
        a_lo, a_hi = lo.copy(), hi.copy()
        b_lo, b_hi = lo.copy(), hi.copy()
        for _ in range(BISECT):
            mid = 0.5 * (a_lo + a_hi)
            ok = F(mid, True) >= dh - e - 1e-9
            a_lo, a_hi = np.where(ok, mid, a_lo), np.where(ok, a_hi, mid)
            mid = 0.5 * (b_lo + b_hi)
            ok = F(mid, False) <= dh + e + 1e-9
            b_lo, b_hi = np.where(ok, b_lo, mid), np.where(ok, mid, b_hi)
        speed = np.array([float(np.median(S[a:b + 1])) for a, b in zip(i, j, strict=True)])
        for q in range(i.size):
            rows.append((float(tn[i[q]]), float(tn[j[q]]), float(b_lo[q]), float(a_hi[q]),
                         float(speed[q])))
    if not rows:
        return None
    arr = np.array(rows)
    lo_all, hi_all = float(np.max(arr[:, 2])), float(np.min(arr[:, 3]))
    return {"chords": arr, "delta": (lo_all, hi_all), "constant": lo_all <= hi_all}


def mount_checks(ctx: Any) -> dict[str, Any] | None:
    """``attitude.mount`` of dynamic.json, and a violation where the data's pitch against
    the path contradicts the vertical bound (at a chord's median speed)."""
    from imubounds.dynamic.estimator import violations as V

    res = pitch_against_path(ctx)
    if res is None:
        return None
    veh = ctx.vehicle
    arr = res["chords"]
    t0 = float(ctx.imu.t0)
    W = veh.vertical_bound
    src = veh.sources.get("vertical_bound", "default")
    allowed = np.arcsin(np.minimum(1.0, W / np.maximum(arr[:, 4], 1e-9)))
    bad = (arr[:, 2] > allowed) | (arr[:, 3] < -allowed)
    fast = arr[:, 4] > 3.0
    for a, b in arr[bad & fast][:, :2]:
        ctx.violations.append(V.Violation(
            "imu", a + t0, b + t0, TEST_MOUNT,
            f"the IMU's pitch against its path over this chord (from the attitude states and "
            f"GNSS altitude) lies beyond asin(W / speed) for the vertical bound W = {W:g} m/s "
            f"({src}): the IMU is pitched on its mount (or the altitude or tilt budget "
            "fails); state vehicle.vertical_speed_bound_mps for the mount",
        ))
    lo, hi = res["delta"]
    out = {
        "pitch_against_path_deg": [lo / DEG, hi / DEG] if res["constant"] else None,
        "chord_hull_deg": [float(np.min(arr[:, 2])) / DEG, float(np.max(arr[:, 3])) / DEG],
        "chords": int(arr.shape[0]),
        "contradicts_vertical_bound": int(np.sum(bad & fast)),
        "roll": None,
        "yaw": None,
        "note": "the IMU's pitch against the elevation of its velocity (mount + suspension), "
        "constant over each chord of 60-240 s; roll and yaw on the vehicle are not observable "
        "from the accelerometers and GNSS (a roll turns the off-axis velocity about the "
        "path, a yaw needs a heading independent of the course)",
    }
    return out
