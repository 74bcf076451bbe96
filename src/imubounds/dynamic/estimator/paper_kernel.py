"""The compiled interval estimator loop (METHOD.md 3.2-3.3) on the scalar interval rules.

Array layout (all float64, intervals as lo/hi column pairs, empty = (+inf, -inf)):

``S`` (n, 10)
    Contracted state per step: x, y (m, ENU), u, v (m/s, body), psi (rad, CCW
    from east, unwrapped); lower ends in columns ``SX, SY, SU, SV, SPSI``.
``P`` (n, 10)
    The INS prediction of the same state before contraction (forward pass).
``M`` (n, 6)
    Measured-input intervals per step: a = accel_x, b = accel_y (m/s^2), r (rad/s);
    lower ends in columns ``IN_A, IN_B, IN_R`` (also of ``D`` and ``A``).
``D`` (n, 6)
    Contracted input domains (subsets of ``M``).
``G`` (n, 4)
    GPS box x lo/hi, y lo/hi (m); NaN in column 0 = no fix at this step.
``C`` (n, 2)
    Heading interval centre and half-width (rad, model convention); NaN centre = none.
``A`` (n, 6)
    The *aided* interval of each input: its projection from the contracted
    neighbouring states through the kinematic constraint, without its own
    measurement.

Discrete model for step k (linking k-1 and k), ``E_p = [-ep, ep]``, ``E_v = [-ev, ev]``
(model-error terms, zero for the paper):

* paper: ``u_k = u_{k-1} + a_k dt + E_v``;  ``v_k = v_{k-1} + b_k dt + E_v``
* full:  ``u_k = u_{k-1} + (a_k + r_k v_{k-1}) dt + E_v``;
  ``v_k = v_{k-1} + (b_k - r_k u_{k-1}) dt + E_v``
* ``psi_k = psi_{k-1} + r_k dt``
* ``x_k = x_{k-1} + (u_k cos psi_k - v_k sin psi_k) dt + E_p``
* ``y_k = y_{k-1} + (v_k cos psi_k + u_k sin psi_k) dt + E_p``
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from imubounds.dynamic.estimator._rules import (
    add,
    cos,
    div,
    div_rel,
    inter,
    inter_two,
    mul,
    next_down,
    next_up,
    sin,
    sub,
)
from imubounds.dynamic.estimator.rotation import irot, rot
from imubounds.interval.qinter import qinter_1d as qrelaxed_1d

# column of the lower end of each quantity (the upper end is the next column)
#: ``S``, ``P`` (state): east x, north y (m), body velocity u, v (m/s), heading psi (rad)
SX, SY, SU, SV, SPSI = 0, 2, 4, 6, 8
#: ``M``, ``D``, ``A`` (inputs): accel_x a, accel_y b (m/s^2), yaw rate r (rad/s)
IN_A, IN_B, IN_R = 0, 2, 4
#: ``G`` (GNSS box): x, y
GX, GY = 0, 2
#: ``C`` (heading): centre and half-width
HC, HH = 0, 1

# flag bits
F_GPS_MISSING = 1
F_GPS_EMPTY = 2
F_HEAD_MISSING = 4
F_HEAD_EMPTY = 8
F_U_EMPTY = 16
F_V_EMPTY = 32
F_R_EMPTY = 64
F_AX_EMPTY = 128
F_AY_EMPTY = 256
F_WINDOW_EMPTY = 512
FLAG_NAMES = {
    F_GPS_MISSING: "gps_missing",
    F_GPS_EMPTY: "gps_empty",
    F_HEAD_MISSING: "heading_missing",
    F_HEAD_EMPTY: "heading_empty",
    F_U_EMPTY: "u_empty",
    F_V_EMPTY: "v_empty",
    F_R_EMPTY: "r_empty",
    F_AX_EMPTY: "accel_x_empty",
    F_AY_EMPTY: "accel_y_empty",
    F_WINDOW_EMPTY: "window_empty",
}

TWO_PI = 2.0 * math.pi


@njit(cache=True)
def _emp(lo: float, hi: float) -> bool:
    return not (lo <= hi)


@njit(cache=True)
def heading_interval(centre: float, half: float, ref: float) -> tuple[float, float]:
    """Heading interval ``centre ± half`` moved by a multiple of 2 pi next to ``ref``.

    The shift is done in floating point, so the result is widened by one ulp on
    each side per operation (outward).
    """
    m = math.floor((ref - centre) / TWO_PI + 0.5)
    c = centre + m * TWO_PI
    lo = next_down(next_down(c - half))
    hi = next_up(next_up(c + half))
    return lo, hi


@njit(cache=True)
def qrelaxed_position(
    k: int,
    S: np.ndarray,
    G: np.ndarray,
    pred: np.ndarray,
    dt: float,
    ep: float,
    window: int,
    q: int,
) -> tuple[float, float, float, float]:
    """q-relaxed intersection of the INS prediction and the GPS boxes of the window.

    Each earlier fix ``G[k-j]`` is carried to step k by the INS displacement
    (``(u cos psi - v sin psi) dt + E_p`` of the contracted states, the
    prediction at k). ``pred`` = (x lo, x hi, y lo, y hi, u.., v.., psi..) at k.
    """
    m_max = window + 2
    xl = np.empty(m_max)
    xh = np.empty(m_max)
    yl = np.empty(m_max)
    yh = np.empty(m_max)
    xl[0], xh[0], yl[0], yh[0] = pred[0], pred[1], pred[2], pred[3]
    m = 1
    # cumulative displacement from step k-j to k
    dxl, dxh, dyl, dyh = 0.0, 0.0, 0.0, 0.0
    for j in range(0, window + 1):
        i = k - j
        if i < 0:
            break
        if G[i, GX] == G[i, GX]:
            a1, a2 = add(G[i, GX], G[i, GX + 1], dxl, dxh)
            b1, b2 = add(G[i, GY], G[i, GY + 1], dyl, dyh)
            xl[m], xh[m], yl[m], yh[m] = a1, a2, b1, b2
            m += 1
        if i == 0:
            break
        # displacement of step i (from i-1 to i)
        st = pred if j == 0 else S[i]
        cl, ch = cos(st[SPSI], st[SPSI + 1])
        sl, sh = sin(st[SPSI], st[SPSI + 1])
        el, eh, nl, nh = rot(cl, ch, sl, sh, st[SU], st[SU + 1], st[SV], st[SV + 1])
        el, eh = mul(el, eh, dt, dt)
        el, eh = add(el, eh, -ep, ep)
        dxl, dxh = add(dxl, dxh, el, eh)
        nl, nh = mul(nl, nh, dt, dt)
        nl, nh = add(nl, nh, -ep, ep)
        dyl, dyh = add(dyl, dyh, nl, nh)
    a1, a2 = qrelaxed_1d(xl, xh, m, q)
    b1, b2 = qrelaxed_1d(yl, yh, m, q)
    return a1, a2, b1, b2


@njit(cache=True)
def qrelaxed_heading(
    k: int,
    S: np.ndarray,
    C: np.ndarray,
    M: np.ndarray,
    ppl: float,
    pph: float,
    dt: float,
    window: int,
    q: int,
) -> tuple[float, float]:
    """q-relaxed intersection of the predicted heading and the window's compass intervals,
    each carried to step k by the measured rate intervals."""
    m_max = window + 2
    lo = np.empty(m_max)
    hi = np.empty(m_max)
    lo[0], hi[0] = ppl, pph
    m = 1
    ref = 0.5 * (ppl + pph)
    dl, dh = 0.0, 0.0
    for j in range(0, window + 1):
        i = k - j
        if i < 0:
            break
        if C[i, HC] == C[i, HC]:
            cl, ch = heading_interval(C[i, HC], C[i, HH], ref - 0.5 * (dl + dh))
            lo[m], hi[m] = add(cl, ch, dl, dh)
            m += 1
        if i == 0:
            break
        tl, th = mul(M[i, IN_R], M[i, IN_R + 1], dt, dt)
        dl, dh = add(dl, dh, tl, th)
    return qrelaxed_1d(lo, hi, m, q)


@njit(cache=True)
def forward_backward_step(
    k: int,
    S: np.ndarray,
    P: np.ndarray,
    M: np.ndarray,
    G: np.ndarray,
    C: np.ndarray,
    dt: float,
    ep: float,
    ev: float,
    mode: int,
    veldiff: int,
    fallback: int,
    window: int = 10,
    q: int = 1,
) -> int:
    """One forward-backward pass for step ``k`` (METHOD.md 3.2-3.3); returns the flags.

    ``fallback`` on an empty intersection: 0 keep the prediction, 1 reset to the
    aiding interval, 2 q-relaxed intersection over the window (prediction plus
    the aiding intervals of the last ``window`` steps carried to step k,
    tolerating ``q`` outliers; the prediction if even that is empty).
    """
    flags = 0
    xl, xh = S[k - 1, SX], S[k - 1, SX + 1]
    yl, yh = S[k - 1, SY], S[k - 1, SY + 1]
    ul, uh = S[k - 1, SU], S[k - 1, SU + 1]
    vl, vh = S[k - 1, SV], S[k - 1, SV + 1]
    pl, ph = S[k - 1, SPSI], S[k - 1, SPSI + 1]
    al, ah = M[k, IN_A], M[k, IN_A + 1]
    bl, bh = M[k, IN_B], M[k, IN_B + 1]
    rl, rh = M[k, IN_R], M[k, IN_R + 1]
    # ---- forward (prediction) ----
    if mode == 0:
        dul, duh = mul(al, ah, dt, dt)
        dvl, dvh = mul(bl, bh, dt, dt)
    else:
        ql, qh = mul(rl, rh, vl, vh)
        wl, wh = add(al, ah, ql, qh)
        dul, duh = mul(wl, wh, dt, dt)
        ql, qh = mul(rl, rh, ul, uh)
        wl, wh = sub(bl, bh, ql, qh)
        dvl, dvh = mul(wl, wh, dt, dt)
    dul, duh = add(dul, duh, -ev, ev)
    dvl, dvh = add(dvl, dvh, -ev, ev)
    upl, uph = add(ul, uh, dul, duh)
    vpl, vph = add(vl, vh, dvl, dvh)
    tl, th = mul(rl, rh, dt, dt)
    ppl, pph = add(pl, ph, tl, th)
    cl, ch = cos(ppl, pph)
    sl, sh = sin(ppl, pph)
    xdl, xdh, ydl, ydh = rot(cl, ch, sl, sh, upl, uph, vpl, vph)
    t1l, t1h = mul(xdl, xdh, dt, dt)
    xpl, xph = add(xl, xh, t1l, t1h)
    xpl, xph = add(xpl, xph, -ep, ep)
    t1l, t1h = mul(ydl, ydh, dt, dt)
    ypl, yph = add(yl, yh, t1l, t1h)
    ypl, yph = add(ypl, yph, -ep, ep)
    P[k, SX], P[k, SX + 1], P[k, SY], P[k, SY + 1] = xpl, xph, ypl, yph
    P[k, SU], P[k, SU + 1], P[k, SV], P[k, SV + 1] = upl, uph, vpl, vph
    P[k, SPSI], P[k, SPSI + 1] = ppl, pph
    # ---- contraction with the aiding sensors ----
    if G[k, GX] != G[k, GX]:
        flags |= F_GPS_MISSING
        nxl, nxh, nyl, nyh = xpl, xph, ypl, yph
    else:
        nxl, nxh = inter(xpl, xph, G[k, GX], G[k, GX + 1])
        nyl, nyh = inter(ypl, yph, G[k, GY], G[k, GY + 1])
        if _emp(nxl, nxh) or _emp(nyl, nyh):
            flags |= F_GPS_EMPTY
            if fallback == 0:
                nxl, nxh, nyl, nyh = xpl, xph, ypl, yph
            elif fallback == 1:
                nxl, nxh, nyl, nyh = G[k, GX], G[k, GX + 1], G[k, GY], G[k, GY + 1]
            else:
                nxl, nxh, nyl, nyh = qrelaxed_position(k, S, G, P[k], dt, ep, window, q)
                if _emp(nxl, nxh) or _emp(nyl, nyh):
                    nxl, nxh, nyl, nyh = xpl, xph, ypl, yph
    if C[k, HC] != C[k, HC]:
        flags |= F_HEAD_MISSING
        npl, nph = ppl, pph
    else:
        ref = 0.5 * (ppl + pph) if (math.isfinite(ppl) and math.isfinite(pph)) else pl
        if not math.isfinite(ref):
            ref = C[k, HC]
        cil, cih = heading_interval(C[k, HC], C[k, HH], ref)
        npl, nph = inter(ppl, pph, cil, cih)
        if _emp(npl, nph):
            flags |= F_HEAD_EMPTY
            if fallback == 0:
                npl, nph = ppl, pph
            elif fallback == 1:
                npl, nph = cil, cih
            else:
                npl, nph = qrelaxed_heading(k, S, C, M, ppl, pph, dt, window, q)
                if _emp(npl, nph):
                    npl, nph = ppl, pph
    # ---- backward: nav velocity, body velocity ----
    if veldiff == 1:
        oxl, oxh, oyl, oyh = P[k - 1, SX], P[k - 1, SX + 1], P[k - 1, SY], P[k - 1, SY + 1]
    else:
        oxl, oxh, oyl, oyh = xl, xh, yl, yh
    t1l, t1h = sub(nxl, nxh, oxl, oxh)
    t1l, t1h = sub(t1l, t1h, -ep, ep)
    vxl, vxh = div(t1l, t1h, dt, dt)
    t1l, t1h = sub(nyl, nyh, oyl, oyh)
    t1l, t1h = sub(t1l, t1h, -ep, ep)
    vyl, vyh = div(t1l, t1h, dt, dt)
    if npl != ppl or nph != pph:  # else cos/sin of the prediction still hold
        cl, ch = cos(npl, nph)
        sl, sh = sin(npl, nph)
    Ul, Uh, Vl, Vh = irot(cl, ch, sl, sh, vxl, vxh, vyl, vyh)
    nul, nuh = inter(upl, uph, Ul, Uh)
    if _emp(nul, nuh):
        flags |= F_U_EMPTY
        nul, nuh = upl, uph
    nvl, nvh = inter(vpl, vph, Vl, Vh)
    if _emp(nvl, nvh):
        flags |= F_V_EMPTY
        nvl, nvh = vpl, vph
    S[k, SX], S[k, SX + 1], S[k, SY], S[k, SY + 1] = nxl, nxh, nyl, nyh
    S[k, SU], S[k, SU + 1], S[k, SV], S[k, SV + 1] = nul, nuh, nvl, nvh
    S[k, SPSI], S[k, SPSI + 1] = npl, nph
    return flags


@njit(cache=True)
def aided_inputs(
    k: int, S: np.ndarray, Dr_lo: float, Dr_hi: float, dt: float, ev: float, mode: int
) -> tuple[float, float, float, float, float, float]:
    """Projection of the kinematic constraints of step ``k`` onto a, b and r."""
    t1l, t1h = sub(S[k, SPSI], S[k, SPSI + 1], S[k - 1, SPSI], S[k - 1, SPSI + 1])
    Rl, Rh = div(t1l, t1h, dt, dt)
    t1l, t1h = sub(S[k, SU], S[k, SU + 1], S[k - 1, SU], S[k - 1, SU + 1])
    t1l, t1h = sub(t1l, t1h, -ev, ev)
    Al, Ah = div(t1l, t1h, dt, dt)
    t1l, t1h = sub(S[k, SV], S[k, SV + 1], S[k - 1, SV], S[k - 1, SV + 1])
    t1l, t1h = sub(t1l, t1h, -ev, ev)
    Bl, Bh = div(t1l, t1h, dt, dt)
    if mode == 1:
        ql, qh = mul(Dr_lo, Dr_hi, S[k - 1, SV], S[k - 1, SV + 1])
        Al, Ah = sub(Al, Ah, ql, qh)
        ql, qh = mul(Dr_lo, Dr_hi, S[k - 1, SU], S[k - 1, SU + 1])
        Bl, Bh = add(Bl, Bh, ql, qh)
    return Al, Ah, Bl, Bh, Rl, Rh


@njit(cache=True)
def revise_step(
    j: int, S: np.ndarray, D: np.ndarray, dt: float, ep: float, ev: float, mode: int
) -> bool:
    """HC4-revise of all constraints of step ``j`` (linking j-1 and j), in place.

    Contracts the states at j-1 and j and the input domains ``D[j]``. Returns
    False if a domain became empty (the arrays may then be partly updated).
    """
    # --- heading: psi_j = psi_{j-1} + r dt
    P_, R_ = SPSI, IN_R
    rl, rh = D[j, R_], D[j, R_ + 1]
    tl, th = mul(rl, rh, dt, dt)
    a1, a2 = add(S[j - 1, P_], S[j - 1, P_ + 1], tl, th)
    S[j, P_], S[j, P_ + 1] = inter(S[j, P_], S[j, P_ + 1], a1, a2)
    a1, a2 = sub(S[j, P_], S[j, P_ + 1], tl, th)
    S[j - 1, P_], S[j - 1, P_ + 1] = inter(S[j - 1, P_], S[j - 1, P_ + 1], a1, a2)
    a1, a2 = sub(S[j, P_], S[j, P_ + 1], S[j - 1, P_], S[j - 1, P_ + 1])
    a1, a2 = div(a1, a2, dt, dt)
    D[j, R_], D[j, R_ + 1] = inter(rl, rh, a1, a2)
    if _emp(S[j, P_], S[j, P_ + 1]) or _emp(S[j - 1, P_], S[j - 1, P_ + 1]) or _emp(
        D[j, R_], D[j, R_ + 1]
    ):
        return False
    rl, rh = D[j, R_], D[j, R_ + 1]
    # --- velocities
    for comp in range(2):
        ci = SU if comp == 0 else SV  # u or v at j
        oi = SV if comp == 0 else SU  # the other component at j-1 (transport term)
        di = IN_A if comp == 0 else IN_B  # a or b
        il, ih = D[j, di], D[j, di + 1]
        if mode == 1:
            ql, qh = mul(rl, rh, S[j - 1, oi], S[j - 1, oi + 1])
            if comp == 0:
                wl, wh = add(il, ih, ql, qh)
            else:
                wl, wh = sub(il, ih, ql, qh)
        else:
            ql, qh = 0.0, 0.0
            wl, wh = il, ih
        ml, mh = mul(wl, wh, dt, dt)
        ml, mh = add(ml, mh, -ev, ev)
        a1, a2 = add(S[j - 1, ci], S[j - 1, ci + 1], ml, mh)
        S[j, ci], S[j, ci + 1] = inter(S[j, ci], S[j, ci + 1], a1, a2)
        a1, a2 = sub(S[j, ci], S[j, ci + 1], ml, mh)
        S[j - 1, ci], S[j - 1, ci + 1] = inter(S[j - 1, ci], S[j - 1, ci + 1], a1, a2)
        a1, a2 = sub(S[j, ci], S[j, ci + 1], S[j - 1, ci], S[j - 1, ci + 1])
        a1, a2 = sub(a1, a2, -ev, ev)
        a1, a2 = div(a1, a2, dt, dt)
        wl, wh = inter(wl, wh, a1, a2)
        if _emp(wl, wh) or _emp(S[j, ci], S[j, ci + 1]) or _emp(S[j - 1, ci], S[j - 1, ci + 1]):
            return False
        if mode == 1:
            if comp == 0:  # w = i + q
                a1, a2 = sub(wl, wh, ql, qh)
                il, ih = inter(il, ih, a1, a2)
                a1, a2 = sub(wl, wh, il, ih)
            else:  # w = i - q
                a1, a2 = add(wl, wh, ql, qh)
                il, ih = inter(il, ih, a1, a2)
                a1, a2 = sub(il, ih, wl, wh)
            ql, qh = inter(ql, qh, a1, a2)
            l1, h1, l2, h2 = div_rel(ql, qh, S[j - 1, oi], S[j - 1, oi + 1])
            rl, rh = inter_two(rl, rh, l1, h1, l2, h2)
            l1, h1, l2, h2 = div_rel(ql, qh, rl, rh)
            S[j - 1, oi], S[j - 1, oi + 1] = inter_two(
                S[j - 1, oi], S[j - 1, oi + 1], l1, h1, l2, h2
            )
            if _emp(rl, rh) or _emp(S[j - 1, oi], S[j - 1, oi + 1]):
                return False
        else:
            il, ih = inter(il, ih, wl, wh)
        D[j, di], D[j, di + 1] = il, ih
        if _emp(il, ih):
            return False
    D[j, IN_R], D[j, IN_R + 1] = rl, rh
    # --- positions: HC4-revise of the rotation x' = u c - v s, y' = v c + u s
    # (the contractor of :func:`~imubounds.dynamic.estimator.rotation.rot`)
    cl, ch = cos(S[j, SPSI], S[j, SPSI + 1])
    sl, sh = sin(S[j, SPSI], S[j, SPSI + 1])
    for comp in range(2):
        pi_ = SX if comp == 0 else SY
        # x: p1 = u c, p2 = v s, d = p1 - p2 ; y: p1 = v c, p2 = u s, d = p1 + p2
        f1 = SU if comp == 0 else SV
        f2 = SV if comp == 0 else SU
        p1l, p1h = mul(S[j, f1], S[j, f1 + 1], cl, ch)
        p2l, p2h = mul(S[j, f2], S[j, f2 + 1], sl, sh)
        if comp == 0:
            dl, dh = sub(p1l, p1h, p2l, p2h)
        else:
            dl, dh = add(p1l, p1h, p2l, p2h)
        ml, mh = mul(dl, dh, dt, dt)
        ml, mh = add(ml, mh, -ep, ep)
        a1, a2 = add(S[j - 1, pi_], S[j - 1, pi_ + 1], ml, mh)
        S[j, pi_], S[j, pi_ + 1] = inter(S[j, pi_], S[j, pi_ + 1], a1, a2)
        a1, a2 = sub(S[j, pi_], S[j, pi_ + 1], ml, mh)
        S[j - 1, pi_], S[j - 1, pi_ + 1] = inter(S[j - 1, pi_], S[j - 1, pi_ + 1], a1, a2)
        if _emp(S[j, pi_], S[j, pi_ + 1]) or _emp(S[j - 1, pi_], S[j - 1, pi_ + 1]):
            return False
        a1, a2 = sub(S[j, pi_], S[j, pi_ + 1], S[j - 1, pi_], S[j - 1, pi_ + 1])
        a1, a2 = sub(a1, a2, -ep, ep)
        a1, a2 = div(a1, a2, dt, dt)
        dl, dh = inter(dl, dh, a1, a2)
        if _emp(dl, dh):
            return False
        if comp == 0:
            a1, a2 = add(dl, dh, p2l, p2h)
            p1l, p1h = inter(p1l, p1h, a1, a2)
            a1, a2 = sub(p1l, p1h, dl, dh)
        else:
            a1, a2 = sub(dl, dh, p2l, p2h)
            p1l, p1h = inter(p1l, p1h, a1, a2)
            a1, a2 = sub(dl, dh, p1l, p1h)
        p2l, p2h = inter(p2l, p2h, a1, a2)
        l1, h1, l2, h2 = div_rel(p1l, p1h, cl, ch)
        S[j, f1], S[j, f1 + 1] = inter_two(S[j, f1], S[j, f1 + 1], l1, h1, l2, h2)
        l1, h1, l2, h2 = div_rel(p2l, p2h, sl, sh)
        S[j, f2], S[j, f2 + 1] = inter_two(S[j, f2], S[j, f2 + 1], l1, h1, l2, h2)
        if _emp(S[j, f1], S[j, f1 + 1]) or _emp(S[j, f2], S[j, f2 + 1]):
            return False
    return True


@njit(cache=True)
def _total_width(S: np.ndarray, D: np.ndarray, lo: int, hi: int) -> float:
    w = 0.0
    for j in range(lo, hi + 1):
        for c in range(0, 10, 2):
            d = S[j, c + 1] - S[j, c]
            if math.isfinite(d):
                w += d
        for c in range(0, 6, 2):
            d = D[j, c + 1] - D[j, c]
            if math.isfinite(d):
                w += d
    return w


@njit(cache=True)
def run_kernel(
    S: np.ndarray,
    P: np.ndarray,
    M: np.ndarray,
    D: np.ndarray,
    A: np.ndarray,
    G: np.ndarray,
    C: np.ndarray,
    flags: np.ndarray,
    dt: float,
    ep: float,
    ev: float,
    mode: int,
    veldiff: int,
    fallback: int,
    window: int,
    passes: int,
    tol: float,
    q: int = 1,
) -> int:
    """Run the estimator over all steps in place; ``S[0]`` holds the initial state.

    Returns the number of Waltz sweeps done in total (0 for a single pass).
    """
    n = S.shape[0]
    sweeps = 0
    P[0, :] = S[0, :]
    for c in range(6):
        D[0, c] = M[0, c]
    waltz = passes > 1 and window > 1
    Sb = np.empty((window + 1, 10))
    Db = np.empty((window + 1, 6))
    for k in range(1, n):
        flags[k] |= forward_backward_step(
            k, S, P, M, G, C, dt, ep, ev, mode, veldiff, fallback, window, q
        )
        for c in range(6):
            D[k, c] = M[k, c]
        if waltz:
            # the Waltz sweeps need the contracted rate of step k as a domain
            t1l, t1h = sub(S[k, SPSI], S[k, SPSI + 1], S[k - 1, SPSI], S[k - 1, SPSI + 1])
            r1, r2 = div(t1l, t1h, dt, dt)
            rl, rh = inter(M[k, IN_R], M[k, IN_R + 1], r1, r2)
            if not _emp(rl, rh):
                D[k, IN_R], D[k, IN_R + 1] = rl, rh
            lo = k - window + 1
            if lo < 1:
                lo = 1
            for j in range(lo - 1, k + 1):
                Sb[j - lo + 1, :] = S[j, :]
                Db[j - lo + 1, :] = D[j, :]
            ok = True
            before = _total_width(S, D, lo - 1, k)
            for _p in range(passes - 1):
                sweeps += 1
                for j in range(k, lo - 1, -1):
                    if not revise_step(j, S, D, dt, ep, ev, mode):
                        ok = False
                        break
                if ok:
                    for j in range(lo, k + 1):
                        if not revise_step(j, S, D, dt, ep, ev, mode):
                            ok = False
                            break
                if not ok:
                    break
                after = _total_width(S, D, lo - 1, k)
                if not (before - after > tol * before):
                    break
                before = after
            if not ok:
                flags[k] |= F_WINDOW_EMPTY
                for j in range(lo - 1, k + 1):
                    S[j, :] = Sb[j - lo + 1, :]
                    D[j, :] = Db[j - lo + 1, :]
        else:
            # single pass: states k-1 and k are final, finish step k now (one memory pass)
            finish_step(k, S, D, A, flags, dt, ev, mode)
    for c in range(6):
        A[0, c] = -np.inf if c % 2 == 0 else np.inf
    if waltz:
        # aided projections and the final contracted inputs, from the final states
        for k in range(1, n):
            finish_step(k, S, D, A, flags, dt, ev, mode)
    return sweeps


@njit(cache=True)
def finish_step(
    k: int,
    S: np.ndarray,
    D: np.ndarray,
    A: np.ndarray,
    flags: np.ndarray,
    dt: float,
    ev: float,
    mode: int,
) -> None:
    """Aided projections of step k and the final contracted inputs (D ∩ aided)."""
    # the rate first: the full mode's transport terms use the contracted rate
    t1l, t1h = sub(S[k, SPSI], S[k, SPSI + 1], S[k - 1, SPSI], S[k - 1, SPSI + 1])
    r1, r2 = div(t1l, t1h, dt, dt)
    l, h = inter(D[k, IN_R], D[k, IN_R + 1], r1, r2)
    if not _emp(l, h):
        D[k, IN_R], D[k, IN_R + 1] = l, h
    a1, a2, b1, b2, r1, r2 = aided_inputs(k, S, D[k, IN_R], D[k, IN_R + 1], dt, ev, mode)
    A[k, IN_A], A[k, IN_A + 1], A[k, IN_B], A[k, IN_B + 1] = a1, a2, b1, b2
    A[k, IN_R], A[k, IN_R + 1] = r1, r2
    for col, (lo, hi), flag in (
        (IN_A, (a1, a2), F_AX_EMPTY),
        (IN_B, (b1, b2), F_AY_EMPTY),
        (IN_R, (r1, r2), F_R_EMPTY),
    ):
        l, h = inter(D[k, col], D[k, col + 1], lo, hi)
        if _emp(l, h):
            flags[k] |= flag
        else:
            D[k, col], D[k, col + 1] = l, h
