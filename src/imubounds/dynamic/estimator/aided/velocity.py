"""The body velocity at the velocity epochs and its range over a window (docs/dynamic-
method.md, section 3, **accel_x**: "u, v at the epochs" and "max_W|v|").

u, v at the epochs: a DVL/wheel measures them; GNSS velocity gives them as
``S cos(chi - psi)``, ``S sin(chi - psi)`` with the heading, converted from the
horizontal to the body frame with the roll/pitch intervals and intersected with the
lateral speed bound. Over a window: the hull of the epoch values plus how far the
velocity can leave it between epochs; without velocity epochs, the speed bound from the
GNSS chords.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from imubounds.constants import G_HI, ROUND_REL
from imubounds.dynamic.estimator.aided.base import pm, up
from imubounds.dynamic.estimator.aided.common import WindowContext
from imubounds.dynamic.estimator.aided.heading import heading_at
from imubounds.dynamic.estimator.inputs import RangeExt, lateral_h_bound
from imubounds.dynamic.estimator.window_plan import LevelPlan
from imubounds.frames import TWO_PI
from imubounds.interval import IntervalArray as IA
from imubounds.interval import atan2, cos, sin, sqr, sqrt
from imubounds.interval import pi as ipi


def growth(w: WindowContext, gaps: np.ndarray) -> np.ndarray:
    """How far a velocity can leave the hull of its epoch values between epochs."""
    v = w.veh
    return up(np.minimum(v.max_accel * gaps / 2.0, v.max_jerk * gaps * gaps / 8.0))


def course(ve: IA, vn: IA) -> IA:
    """Course (CCW from east) of velocity boxes, without the jump at +-pi: the narrower of
    ``atan2(vn, ve)`` and ``atan2(-vn, -ve) + pi`` (equal modulo 2 pi)."""
    a = atan2(vn, ve)
    b = atan2(-vn, -ve) + ipi()
    use_b = (b.hi - b.lo) < (a.hi - a.lo)
    return IA(np.where(use_b, b.lo, a.lo), np.where(use_b, b.hi, a.hi))


def _from_body_sensor(w: WindowContext) -> tuple[np.ndarray, IA, IA, IA, str]:
    """u, v, w at the epochs of a body-velocity sensor (DVL, wheel speed)."""
    ag, veh = w.ag, w.veh
    vl = veh.lateral_speed_bound_mps
    t = ag.bvel_t
    h = ag.bvel_h
    u = IA(ag.bvel_u - h, ag.bvel_u + h)
    if ag.bvel_v is not None and np.all(np.isfinite(ag.bvel_v)):
        v = IA(ag.bvel_v - h, ag.bvel_v + h)
    else:
        vb = vl if vl is not None else veh.max_speed
        v = pm(np.full(t.size, vb))
    if ag.bvel_w is not None and np.all(np.isfinite(ag.bvel_w)):
        wz = IA(ag.bvel_w - h, ag.bvel_w + h)
    else:
        wz = pm(np.full(t.size, veh.vertical_bound))
    return t, u, v, wz, f"body velocity ({ag.bvel_kind})"


def _course_minus_heading(
    w: WindowContext, t: np.ndarray, S: IA, psi: IA | None = None
) -> IA:
    """``chi - psi`` at the GNSS velocity epochs ``t`` (speed interval ``S``); ``psi`` the
    heading there (else :func:`~.heading.heading_at`)."""
    ag, veh = w.ag, w.veh
    ok = ag.gvel_ok
    R = ag.gvel_hi[ok]
    vem, vnm = IA(ag.gvel_e[ok]), IA(ag.gvel_n[ok])
    if ag.head_from_course:
        # heading from this very course (no reversing): |psi - chi| <= asin(vh/S)
        vhm = lateral_h_bound(veh)
        assert vhm is not None
        slo = S.lo
        dm = np.where(
            slo > vhm,
            up(np.arcsin(np.minimum(1.0, vhm / np.maximum(slo, 1e-300))) * (1 + 1e-9)),
            0.5 * math.pi * (1 + 1e-9),
        )
        return pm(dm)
    smf = np.sqrt(ag.gvel_e[ok] ** 2 + ag.gvel_n[ok] ** 2)
    fast = smf * (1 - 1e-9) > R
    e_chi = np.where(
        fast,
        up(np.arcsin(np.minimum(1.0, R / np.maximum(smf * (1 - 1e-9), 1e-300)))
           * (1 + 1e-9) + 1e-15),
        np.inf,
    )
    chi = course(vem, vnm) + pm(np.where(fast, e_chi, 0.0))
    chi = IA(np.where(fast, chi.lo, -np.inf), np.where(fast, chi.hi, np.inf))
    if psi is None:
        psi = heading_at(w, t)
    fin = np.isfinite(psi.lo) & np.isfinite(psi.hi) & fast
    kk = np.where(fin, np.round((chi.mid() - np.where(fin, psi.mid(), 0.0)) / TWO_PI), 0)
    psi = psi + IA(TWO_PI * kk) * IA(1.0 - 2**-50, 1.0 + 2**-50)
    return chi - psi


def _heading_gyro_free(w: WindowContext, t: np.ndarray) -> IA:
    """The heading at ``t`` without the gyros: each neighbouring heading epoch's box
    widened by the vehicle's heading-rate cap (``max_rate / cos(max_tilt)``) times the
    distance to it, the two intersected (the compass box itself at a heading epoch)."""
    ag, veh = w.ag, w.veh
    ht = ag.head_t
    lo = np.full(t.shape, -np.inf)
    hi = np.full(t.shape, np.inf)
    if ht.size == 0:
        return IA(lo, hi)
    rate = up(np.asarray(veh.max_rate / math.cos(veh.max_tilt) * (1 + ROUND_REL)))
    j = np.searchsorted(ht, t)
    for e in (j - 1, j):
        ok = (e >= 0) & (e < ht.size)
        ee = np.clip(e, 0, ht.size - 1)
        dist = np.abs(t - ht[ee])
        g = np.where(dist <= 1e-9, 0.0, up(rate * dist))
        c_lo = np.nextafter(ag.head_c[ee] - ag.head_h[ee] - g, -np.inf)
        c_hi = up(ag.head_c[ee] + ag.head_h[ee] + g)
        lo = np.where(ok, np.maximum(lo, c_lo), lo)
        hi = np.where(ok, np.minimum(hi, c_hi), hi)
    bad = lo > hi  # inconsistent neighbours: their hull
    return IA(np.where(bad, np.minimum(lo, hi), lo), np.where(bad, np.maximum(lo, hi), hi))


def _from_gnss_velocity(
    w: WindowContext, gyro_free: bool = False
) -> tuple[np.ndarray, IA, IA, IA, str]:
    """u, v, w at the GNSS velocity epochs: the velocity rotated by the heading, then to
    the body frame with the roll/pitch intervals. ``gyro_free``: the heading from the
    compass boxes carried by the vehicle's rate cap (:func:`_heading_gyro_free`, not by
    the gyro's magnitude), and without an attitude stream the tilt within +-max tilt
    (not the pitch from GNSS altitude, which follows the gyros)."""
    ag, veh = w.ag, w.veh
    vl = veh.lateral_speed_bound_mps
    ok = ag.gvel_ok
    t = ag.gnss_t[ok]
    R = ag.gvel_hi[ok]
    vem, vnm = IA(ag.gvel_e[ok]), IA(ag.gvel_n[ok])
    # the radial bound R: ||V| - |Vm|| <= R and |chi - chi_m| <= asin(R / |Vm|)
    sm = sqrt(sqr(vem) + sqr(vnm))
    S = (sm + pm(R)) & IA(np.zeros(t.size), np.full(t.size, np.inf))
    psi = _heading_gyro_free(w, t) if gyro_free else None
    d = _course_minus_heading(w, t, S, psi)
    uh, vh = S * cos(d), S * sin(d)
    if gyro_free and not ag.has_attitude:  # not the pitch from GNSS altitude (gyros)
        z = np.full(t.size, veh.max_tilt)
        rl, rh, pl, ph = -z, z, -z, z
    else:
        rl, rh, pl, ph = ag.tilt(t, veh)
    roll, pitch = IA(rl, rh), IA(pl, ph)
    sr, cr, sp, cp = sin(roll), cos(roll), sin(pitch), cos(pitch)
    wz = pm(np.full(t.size, veh.vertical_bound))
    v = (vh + sr * wz) / cr
    if vl is not None:
        v = v & pm(np.full(t.size, vl))
    u = (uh + sr * sp * v + cr * sp * wz) / cp
    return t, u, v, wz, "GNSS velocity rotated by the heading"


def body_velocity(w: WindowContext) -> Any:
    """Body velocity (u, v, w) intervals at the velocity epochs (DVL preferred), with the
    range tables of :func:`vel_range`; None without velocity aiding. Computed once."""
    if w.cache.get("bodyvel") is not None:
        return w.cache["bodyvel"]
    ag, veh = w.ag, w.veh
    vl = veh.lateral_speed_bound_mps
    if ag.has_bvel:
        t, u, v, wz, src = _from_body_sensor(w)
    elif ag.has_gvel:
        t, u, v, wz, src = _from_gnss_velocity(w)
    else:
        w.cache["bodyvel"] = None
        return None
    u = u & pm(np.full(t.size, veh.max_speed))
    if vl is not None:
        v = v & pm(np.full(t.size, vl))
    bad = u.is_empty() | v.is_empty()
    if np.any(bad):  # an aiding epoch contradicts the vehicle bounds: drop it
        keep = ~bad
        t, u, v, wz = t[keep], u[keep], v[keep], wz[keep]
    gaps = np.diff(t) if t.size > 1 else np.zeros(0)
    gu, gv = gap_growth(w, t, u, v)
    w.cache["bodyvel"] = {
        "t": t,
        "u": u,
        "v": v,
        "w": wz,
        "src": src,
        "uext": RangeExt(u.lo, u.hi),
        "vabs": RangeExt(abs(v).hi),
        "wabs": RangeExt(abs(wz).hi),
        "gaps": RangeExt(gaps if gaps.size else np.zeros(1)),
        "gu": RangeExt(gu if gu.size else np.zeros(1)),
        "gv": RangeExt(gv if gv.size else np.zeros(1)),
        "dropped": int(np.sum(bad)),
    }
    return w.cache["bodyvel"]


def gyro_free_u(w: WindowContext, bv: Any) -> Any:
    """``bv`` with u at the epochs from the aiding alone (no gyro magnitude: the GNSS
    velocity rotated by the compass boxes carried by the vehicle's rate cap, the course
    heading's bound as it is, the tilt within +-max tilt without an attitude stream; a
    DVL/wheel's u as it is), for weights that
    must not depend on the gyro's noise (:mod:`.transport_weighted`); each ``u`` of
    ``bv`` lies in its box (the same construction with narrower boxes: heading_at's
    gyro magnitude is capped by the vehicle's rate, the GNSS pitch lies in the max
    tilt; checked, else None). None where an epoch was dropped (the gaps would
    differ), and None when the heading or the attitude stream is an AHRS output of this
    IMU (it follows the gyros). Computed once."""
    key = "bodyvel_gyro_free"
    if key in w.cache:
        return w.cache[key]
    ag, veh = w.ag, w.veh
    out = None
    ahrs = not ag.head_independent_of_imu or (
        ag.has_attitude and ag.att_source == "ahrs")
    if bv is not None and bv["dropped"] == 0 and not ahrs:
        if ag.has_bvel:
            u = bv["u"]
        else:
            t, u, _, _, _ = _from_gnss_velocity(w, gyro_free=True)
            u = u & pm(np.full(t.size, veh.max_speed))
            if t.size != bv["t"].size or np.any(u.is_empty()):
                u = None
            elif np.any((u.lo > bv["u"].lo) | (u.hi < bv["u"].hi)):
                u = None  # (rounding of the 2 pi unwrap) not a box around bv's u
        if u is not None:
            out = dict(bv)
            out["u"] = u
            out["uext"] = RangeExt(u.lo, u.hi)
    w.cache[key] = out
    return out


def vel_range(
    w: WindowContext, bv: Any, a: np.ndarray, b: np.ndarray, tv: bool = True
) -> dict[str, np.ndarray]:
    """Over the support [a, b]: hull of u, max |v|, max |w| (epochs inside, plus the
    growth between epochs), in m/s. ``tv`` False: the growth from the vehicle's bounds
    only (not the IMU magnitudes' total variation of :func:`gap_growth`)."""
    t = bv["t"]
    i = np.clip(np.searchsorted(t, a, side="right") - 1, 0, t.size - 1)
    j = np.clip(np.searchsorted(t, b, side="left"), 0, t.size - 1)
    j = np.maximum(j, i)
    ulo, uhi = bv["uext"].query(i, j)
    _, vmax = bv["vabs"].query(i, j)
    _, wmax = bv["wabs"].query(i, j)
    gi = np.clip(i, 0, max(0, t.size - 2))
    gj = np.clip(j - 1, 0, max(0, t.size - 2))
    _, gmax = bv["gaps"].query(gi, np.maximum(gj, gi))
    _, gu = bv["gu"].query(gi, np.maximum(gj, gi))
    _, gv = bv["gv"].query(gi, np.maximum(gj, gi))
    # outside the epoch span the growth is over the distance to the nearest epoch
    ext = np.maximum(t[i] - a, 0.0) + np.maximum(b - t[j], 0.0)
    g = growth(w, np.maximum(gmax, 2 * ext))
    single = (t.size < 2) or not tv
    g_u = np.where((ext > 0) | single, g, np.minimum(g, gu))
    g_v = np.where((ext > 0) | single, g, np.minimum(g, gv))
    vl = w.veh.lateral_speed_bound_mps
    vmax = vmax + g_v
    if vl is not None:
        vmax = np.minimum(vmax, vl)
    wm = up(wmax + g)
    if w.veh.kind == "ground":  # |w| <= the vertical bound (heave) at every time
        wm = np.minimum(wm, w.veh.vertical_bound)
    return {
        "u_lo": ulo - g_u,
        "u_hi": uhi + g_u,
        "v_max": up(vmax),
        "w_max": wm,
    }


def gap_growth(
    w: WindowContext, t: np.ndarray, u: IA, v: IA
) -> tuple[np.ndarray, np.ndarray]:
    """How far u and v can leave the hull of their values at two consecutive velocity
    epochs: half their total variation over the gap, bounded with the magnitudes of
    the other IMU channels (|u'| <= |f_x| + |r| |v| + |q| |w| + g |sin pitch|, |v'| <=
    |f_y| + |r| |u| + |p| |w| + g |sin roll|; a magnitude use in a second-order term), and the
    vehicle's acceleration and jerk bounds."""
    if t.size < 2:
        return np.zeros(0), np.zeros(0)
    veh = w.veh
    a, b = t[:-1], t[1:]
    g = b - a
    r_int = w.mag_mean("gyro_z", a, b) * g
    fx_int = w.mag_mean("accel_x", a, b) * g
    fy_int = w.mag_mean("accel_y", a, b) * g
    sp = w.tilt.hull("abs_sinp", a, b).hi
    sr = w.tilt.hull("abs_sinr", a, b).hi
    vmax = np.maximum(abs(v).hi[:-1], abs(v).hi[1:])
    umax = np.maximum(abs(u).hi[:-1], abs(u).hi[1:])
    vl = veh.lateral_speed_bound_mps
    vcap = vl if vl is not None else veh.max_speed
    base = growth(w, g)
    tv_u = fx_int + np.minimum(vmax + base, vcap) * r_int + G_HI * sp * g
    tv_v = fy_int + np.minimum(umax + base, veh.max_speed) * r_int + G_HI * sr * g
    if veh.vertical_bound > 0:  # q w in u', p w in v' (|w| <= the vertical bound)
        tv_u = tv_u + veh.vertical_bound * w.mag_mean("gyro_y", a, b) * g
        tv_v = tv_v + veh.vertical_bound * w.mag_mean("gyro_x", a, b) * g
    return up(np.minimum(base, tv_u / 2)), up(np.minimum(base, tv_v / 2))


def speed_max(w: WindowContext, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Bound on the horizontal speed over [a, b] from the GNSS positions (chord speeds
    of the fix pairs inside plus the growth between fixes), capped by max_speed."""
    ag, veh = w.ag, w.veh
    if "chord" not in w.cache:
        t = ag.gnss_t
        if t.size < 2:
            w.cache["chord"] = None
        else:
            d = np.hypot(np.diff(ag.gnss_e), np.diff(ag.gnss_n))
            hh = ag.gnss_h[1:] + ag.gnss_h[:-1]
            g = np.diff(t)
            sp = (d + math.sqrt(2) * hh) / g + veh.max_accel * g / 2
            w.cache["chord"] = RangeExt(sp)
    chord = w.cache["chord"]
    if chord is None:
        return np.full(np.shape(a), veh.max_speed)
    t = ag.gnss_t
    i = np.clip(np.searchsorted(t, a, side="right") - 1, 0, t.size - 2)
    j = np.clip(np.searchsorted(t, b) - 1, 0, t.size - 2)
    _, mx = chord.query(i, np.maximum(i, j))
    return np.minimum(up(mx), veh.max_speed)


def ranges(w: WindowContext, lp: LevelPlan, bv: Any) -> dict[str, np.ndarray]:
    """Velocity ranges over each window's support: from the velocity epochs, else from
    the speed bound of the GNSS chords."""
    if bv is not None:
        return vel_range(w, bv, lp.a1, lp.b2)
    s = speed_max(w, lp.a1, lp.b2)
    vl = w.veh.lateral_speed_bound_mps
    return {
        "u_lo": -s,
        "u_hi": s,
        "v_max": np.minimum(s, vl) if vl is not None else s,
        "w_max": np.full(s.shape, w.veh.vertical_bound) if w.veh.kind == "ground" else s,
    }
