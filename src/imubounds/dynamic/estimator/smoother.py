"""The whole-trip interval smoother of mode ``full`` (docs/dynamic-method.md, section 5).

A contractor network over the epochs ``t_0 < ... < t_{n-1}`` (every aiding epoch).
State per epoch, in an ``(n, 7, 2)`` array of intervals (lo, hi)::

    0 E, 1 N          position, ENU m (relative to the first fix)
    2 VE, 3 VN        horizontal velocity, m/s
    4 psi             heading, rad, counter-clockwise from east, unwrapped
    5 u_h, 6 v_h      horizontal velocity in the heading frame (forward, left), m/s

Constraints between epochs ``j`` and ``j+1`` (``D = t_{j+1} - t_j``), from the IMU
integrated at its own rate between the epochs (:func:`preintegrate`)::

    psi_{j+1} = psi_j + Phi_j,          Phi_j = [YR_j] - D beta_r
    V_{j+1}   = V_j + R(psi_j) F_j,     F_j   = [FH_j] - D beta_a
    P_{j+1}   = P_j + D V_j + R(psi_j) Q_j,   Q_j = [QH_j] - D^2/2 beta_a

``[YR]``, ``[FH]``, ``[QH]`` hold the measured increments (heading-frame specific force
rotated by the gyro's own increment from ``t_j``, gravity removed through the roll/pitch
intervals and the measured vertical specific force) widened by every error of the
budget but the bias ``beta`` (a state: ``beta_a`` accel x/y, ``beta_r`` yaw rate, each a
single interval for the whole trip, contracted). At each epoch
``u_h = VE cos psi + VN sin psi``, ``v_h = VN cos psi - VE sin psi`` (and the inverse),
and, when the lateral velocity is bounded and the speed exceeds it, the heading from
the course ``psi = atan2(VN, VE) - asin(v_h / |V|)``. Each constraint is contracted by
HC4-revise with the scalar contractors of :mod:`imubounds.interval` (``ctc_add``,
``ctc_mul``); sweeps forward and backward repeat until no interval shrinks by more
than ``tol`` of its width (the fixpoint).

Outliers (:func:`screen`): a forward filter and a backward filter (each epoch's state
from the past or from the future only) give, at every epoch, two predictions that do
not use that epoch's measurements; a measurement missing both (which agree) is
dropped; where the two predictions disagree the IMU link on the odd side is dropped.
This is the q-relaxed intersection (q = 1) of the epoch's measurement and the two
predictions. Every drop is recorded (time, sensor, miss). The fixpoint then runs on
what is kept; an empty intersection there drops the measurement (or link) at that
epoch the same way and the screening restarts.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numba import njit

from imubounds.constants import ROUND_REL
from imubounds.dynamic.estimator.rotation import irot as _irot
from imubounds.dynamic.estimator.rotation import rot as _rot
from imubounds.interval import scalar as c
from imubounds.interval import scalar_contractors as k

NV = 7
E, N, VE, VN, PSI, UH, VH = range(7)
G_POS, G_VEL, G_HEAD, G_BODY = range(4)
GROUP_VARS = ((E, N), (VE, VN), (PSI,), (UH, VH))
GROUP_NAMES = ("gnss position", "gnss velocity", "heading", "body velocity")
GROUP_UNITS = ("m", "m/s", "rad", "m/s")
INF = math.inf


# ----------------------------------------------------------------------- helpers


@njit(cache=True)
def _set(x: np.ndarray, i: int, lo: float, hi: float) -> bool:
    """x[i] <- x[i] & [lo, hi]; False if empty."""
    a, b = c.inter(x[i, 0], x[i, 1], lo, hi)
    x[i, 0] = a
    x[i, 1] = b
    return a <= b


@njit(cache=True)
def _empty7(x: np.ndarray) -> int:
    for i in range(NV):
        if not (x[i, 0] <= x[i, 1]):
            return i
    return -1


# ---------------------------------------------------------------------- coupling


@njit(cache=True)
def couple(x: np.ndarray, vlat: float) -> bool:
    """Contract one epoch's (VE, VN, psi, u_h, v_h) with the rotation between the nav and
    heading frames, |v_h| <= vlat, and the heading from the course when |V| > |v_h|."""
    if vlat < INF:
        if not _set(x, VH, -vlat, vlat):
            return False
    for _ in range(2):
        cl, ch = c.cos(x[PSI, 0], x[PSI, 1])
        sl, sh = c.sin(x[PSI, 0], x[PSI, 1])
        ul, uh, vl, vh = _irot(cl, ch, sl, sh, x[VE, 0], x[VE, 1], x[VN, 0], x[VN, 1])
        if not _set(x, UH, ul, uh) or not _set(x, VH, vl, vh):
            return False
        el, eh, nl, nh = _rot(cl, ch, sl, sh, x[UH, 0], x[UH, 1], x[VH, 0], x[VH, 1])
        if not _set(x, VE, el, eh) or not _set(x, VN, nl, nh):
            return False
        # heading from the course: v_h = |V| sin(chi - psi), u_h = |V| cos(chi - psi)
        s2 = c.add(*c.sqr(x[VE, 0], x[VE, 1]), *c.sqr(x[VN, 0], x[VN, 1]))
        sp = c.sqrt(s2[0], s2[1])
        av = max(abs(x[VH, 0]), abs(x[VH, 1]))
        if sp[0] > av and (x[UH, 0] > 0.0 or x[UH, 1] < 0.0) and math.isfinite(sp[1]):
            chl, chh = c.atan2(x[VN, 0], x[VN, 1], x[VE, 0], x[VE, 1])
            bl, bh = c.atan2(-x[VN, 1], -x[VN, 0], -x[VE, 1], -x[VE, 0])
            bl, bh = c.add(bl, bh, c.PI_LO, c.PI_HI)
            if bh - bl < chh - chl:
                chl, chh = bl, bh
            if chh - chl < math.pi:
                q = c.div(x[VH, 0], x[VH, 1], sp[0], sp[1])
                dl, dh = c.asin(q[0], q[1])
                if x[UH, 1] < 0.0:  # moving backwards: chi - psi = pi - asin(.)
                    dl, dh = c.sub(c.PI_LO, c.PI_HI, dl, dh)
                pl, ph = c.sub(chl, chh, dl, dh)
                # the branch of the state (psi is unwrapped)
                if math.isfinite(x[PSI, 0]) and math.isfinite(x[PSI, 1]):
                    dm = 0.5 * (x[PSI, 0] + x[PSI, 1]) - 0.5 * (pl + ph)
                    m = math.floor(dm / (2 * math.pi) + 0.5)
                    sh2 = c.mul(c.TWO_PI_LO, c.TWO_PI_HI, float(m), float(m))
                    pl, ph = c.add(pl, ph, sh2[0], sh2[1])
                    if not _set(x, PSI, pl, ph):
                        return False
    return True


# -------------------------------------------------------------------- constraints


@njit(cache=True)
def _phi(j: int, YR: np.ndarray, DT: np.ndarray, beta: np.ndarray) -> tuple[float, float]:
    t = c.mul(DT[j], DT[j], beta[2, 0], beta[2, 1])
    return c.sub(YR[j, 0], YR[j, 1], t[0], t[1])


@njit(cache=True)
def _fq(
    j: int, FH: np.ndarray, QH: np.ndarray, DT: np.ndarray, beta: np.ndarray
) -> tuple[float, float, float, float, float, float, float, float]:
    d = DT[j]
    h = c.mul(d, d, 0.5, 0.5)
    d2 = c.mul(h[0], h[1], d, d)
    out = np.empty(8)
    for a in range(2):
        t = c.mul(d, d, beta[a, 0], beta[a, 1])
        f = c.sub(FH[j, a, 0], FH[j, a, 1], t[0], t[1])
        out[2 * a] = f[0]
        out[2 * a + 1] = f[1]
        t = c.mul(d2[0], d2[1], beta[a, 0], beta[a, 1])
        q = c.sub(QH[j, a, 0], QH[j, a, 1], t[0], t[1])
        out[4 + 2 * a] = q[0]
        out[4 + 2 * a + 1] = q[1]
    return out[0], out[1], out[2], out[3], out[4], out[5], out[6], out[7]


@njit(cache=True)
def predict_forward(
    xa: np.ndarray,
    j: int,
    YR: np.ndarray,
    FH: np.ndarray,
    QH: np.ndarray,
    DT: np.ndarray,
    beta: np.ndarray,
    out: np.ndarray,
) -> None:
    """State at ``j+1`` from the state ``xa`` at ``j`` through the IMU link (no
    measurement of ``j+1`` used); u_h, v_h are left entire."""
    for i in range(NV):
        out[i, 0] = -INF
        out[i, 1] = INF
    ph = _phi(j, YR, DT, beta)
    p = c.add(xa[PSI, 0], xa[PSI, 1], ph[0], ph[1])
    out[PSI, 0], out[PSI, 1] = p
    fx0, fx1, fy0, fy1, qx0, qx1, qy0, qy1 = _fq(j, FH, QH, DT, beta)
    cl, ch = c.cos(xa[PSI, 0], xa[PSI, 1])
    sl, sh = c.sin(xa[PSI, 0], xa[PSI, 1])
    we0, we1, wn0, wn1 = _rot(cl, ch, sl, sh, fx0, fx1, fy0, fy1)
    out[VE, 0], out[VE, 1] = c.add(xa[VE, 0], xa[VE, 1], we0, we1)
    out[VN, 0], out[VN, 1] = c.add(xa[VN, 0], xa[VN, 1], wn0, wn1)
    qe0, qe1, qn0, qn1 = _rot(cl, ch, sl, sh, qx0, qx1, qy0, qy1)
    d = DT[j]
    t = c.mul(xa[VE, 0], xa[VE, 1], d, d)
    t = c.add(t[0], t[1], qe0, qe1)
    out[E, 0], out[E, 1] = c.add(xa[E, 0], xa[E, 1], t[0], t[1])
    t = c.mul(xa[VN, 0], xa[VN, 1], d, d)
    t = c.add(t[0], t[1], qn0, qn1)
    out[N, 0], out[N, 1] = c.add(xa[N, 0], xa[N, 1], t[0], t[1])


@njit(cache=True)
def predict_backward(
    xb: np.ndarray,
    j: int,
    YR: np.ndarray,
    FH: np.ndarray,
    QH: np.ndarray,
    DT: np.ndarray,
    beta: np.ndarray,
    out: np.ndarray,
) -> None:
    """State at ``j`` from the state ``xb`` at ``j+1`` (no measurement of ``j`` used)."""
    for i in range(NV):
        out[i, 0] = -INF
        out[i, 1] = INF
    ph = _phi(j, YR, DT, beta)
    p = c.sub(xb[PSI, 0], xb[PSI, 1], ph[0], ph[1])
    out[PSI, 0], out[PSI, 1] = p
    fx0, fx1, fy0, fy1, qx0, qx1, qy0, qy1 = _fq(j, FH, QH, DT, beta)
    cl, ch = c.cos(p[0], p[1])
    sl, sh = c.sin(p[0], p[1])
    we0, we1, wn0, wn1 = _rot(cl, ch, sl, sh, fx0, fx1, fy0, fy1)
    ve = c.sub(xb[VE, 0], xb[VE, 1], we0, we1)
    vn = c.sub(xb[VN, 0], xb[VN, 1], wn0, wn1)
    out[VE, 0], out[VE, 1] = ve
    out[VN, 0], out[VN, 1] = vn
    qe0, qe1, qn0, qn1 = _rot(cl, ch, sl, sh, qx0, qx1, qy0, qy1)
    d = DT[j]
    t = c.mul(ve[0], ve[1], d, d)
    t = c.add(t[0], t[1], qe0, qe1)
    out[E, 0], out[E, 1] = c.sub(xb[E, 0], xb[E, 1], t[0], t[1])
    t = c.mul(vn[0], vn[1], d, d)
    t = c.add(t[0], t[1], qn0, qn1)
    out[N, 0], out[N, 1] = c.sub(xb[N, 0], xb[N, 1], t[0], t[1])


@njit(cache=True)
def constrain_link(
    xa: np.ndarray,
    xb: np.ndarray,
    j: int,
    YR: np.ndarray,
    FH: np.ndarray,
    QH: np.ndarray,
    DT: np.ndarray,
    beta: np.ndarray,
    contract_beta: bool,
) -> int:
    """HC4-revise of the three constraints of link ``j`` on (xa, xb, beta).

    Returns -1 if consistent, else 0 (xa), 1 (xb) or 2 (beta) became empty.
    """
    d = DT[j]
    # heading: psi_b = psi_a + Phi,  Phi = YR - d beta_r
    ph = _phi(j, YR, DT, beta)
    r = k.ctc_add(xb[PSI, 0], xb[PSI, 1], xa[PSI, 0], xa[PSI, 1], ph[0], ph[1], 3)
    if r[6] >= 0:
        return 1 if r[6] == 0 else 0 if r[6] == 1 else 2
    xb[PSI, 0], xb[PSI, 1], xa[PSI, 0], xa[PSI, 1] = r[0], r[1], r[2], r[3]
    if contract_beta:
        # d beta_r = YR - Phi
        t = c.sub(YR[j, 0], YR[j, 1], r[4], r[5])
        t = c.div(t[0], t[1], d, d)
        if not _set(beta, 2, t[0], t[1]):
            return 2
    # velocity: V_b = V_a + R(psi_a) F
    fx0, fx1, fy0, fy1, qx0, qx1, qy0, qy1 = _fq(j, FH, QH, DT, beta)
    cl, ch = c.cos(xa[PSI, 0], xa[PSI, 1])
    sl, sh = c.sin(xa[PSI, 0], xa[PSI, 1])
    we0, we1, wn0, wn1 = _rot(cl, ch, sl, sh, fx0, fx1, fy0, fy1)
    r = k.ctc_add(xb[VE, 0], xb[VE, 1], xa[VE, 0], xa[VE, 1], we0, we1, 3)
    if r[6] >= 0:
        return 1 if r[6] == 0 else 0 if r[6] == 1 else 2
    xb[VE, 0], xb[VE, 1], xa[VE, 0], xa[VE, 1], we0, we1 = r[0], r[1], r[2], r[3], r[4], r[5]
    r = k.ctc_add(xb[VN, 0], xb[VN, 1], xa[VN, 0], xa[VN, 1], wn0, wn1, 3)
    if r[6] >= 0:
        return 1 if r[6] == 0 else 0 if r[6] == 1 else 2
    xb[VN, 0], xb[VN, 1], xa[VN, 0], xa[VN, 1], wn0, wn1 = r[0], r[1], r[2], r[3], r[4], r[5]
    if contract_beta:
        # F = R(-psi) W; d beta_a = FH - F
        f0, f1, g0, g1 = _irot(cl, ch, sl, sh, we0, we1, wn0, wn1)
        fx = c.inter(fx0, fx1, f0, f1)
        fy = c.inter(fy0, fy1, g0, g1)
        for a, ff in ((0, fx), (1, fy)):
            t = c.sub(FH[j, a, 0], FH[j, a, 1], ff[0], ff[1])
            t = c.div(t[0], t[1], d, d)
            if not _set(beta, a, t[0], t[1]):
                return 2
    # position: P_b = P_a + d V_a + R(psi_a) Q
    qe0, qe1, qn0, qn1 = _rot(cl, ch, sl, sh, qx0, qx1, qy0, qy1)
    for pv, vv, q0, q1 in ((E, VE, qe0, qe1), (N, VN, qn0, qn1)):
        vd = c.mul(xa[vv, 0], xa[vv, 1], d, d)
        dd = c.add(vd[0], vd[1], q0, q1)
        r = k.ctc_add(xb[pv, 0], xb[pv, 1], xa[pv, 0], xa[pv, 1], dd[0], dd[1], 3)
        if r[6] >= 0:
            return 1 if r[6] == 0 else 0 if r[6] == 1 else 0
        xb[pv, 0], xb[pv, 1], xa[pv, 0], xa[pv, 1] = r[0], r[1], r[2], r[3]
        # back to the velocity: d V_a = D - R Q
        r2 = k.ctc_add(r[4], r[5], vd[0], vd[1], q0, q1, 3)
        if r2[6] >= 0:
            return 0
        r3 = k.ctc_mul(r2[2], r2[3], xa[vv, 0], xa[vv, 1], d, d, 3)
        if r3[6] >= 0:
            return 0
        xa[vv, 0], xa[vv, 1] = r3[2], r3[3]
    return -1


# ------------------------------------------------------------------------ filters


@njit(cache=True)
def _combine(pred: np.ndarray, meas: np.ndarray, out: np.ndarray, conflict: np.ndarray) -> None:
    """Per group: out = pred & meas, or their hull (q = 1 of 2) when they do not meet."""
    for g in range(4):
        if g == 0:
            vs = (E, N)
        elif g == 1:
            vs = (VE, VN)
        elif g == 2:
            vs = (PSI, PSI)
        else:
            vs = (UH, VH)
        ok = True
        for v in vs:
            a, b = c.inter(pred[v, 0], pred[v, 1], meas[v, 0], meas[v, 1])
            if not (a <= b):
                ok = False
        for v in vs:
            if ok:
                out[v, 0], out[v, 1] = c.inter(pred[v, 0], pred[v, 1], meas[v, 0], meas[v, 1])
            else:
                out[v, 0], out[v, 1] = c.hull(pred[v, 0], pred[v, 1], meas[v, 0], meas[v, 1])
        if not ok:
            conflict[g] = 1


@njit(cache=True)
def run_filters(
    X0: np.ndarray,
    link: np.ndarray,
    YR: np.ndarray,
    FH: np.ndarray,
    QH: np.ndarray,
    DT: np.ndarray,
    beta: np.ndarray,
    vlat: float,
    PF: np.ndarray,
    PB: np.ndarray,
    XF: np.ndarray,
    XB: np.ndarray,
    CF: np.ndarray,
    CB: np.ndarray,
) -> None:
    """Forward and backward filters over the epochs.

    ``X0``: priors & measurements per epoch. ``PF[j]``/``PB[j]``: the predictions of
    epoch ``j`` from the past / the future only (entire where the link is dropped);
    ``XF``/``XB`` the filtered states; ``CF``/``CB`` (n, 5) conflicts per group (4:
    coupling).
    """
    n = X0.shape[0]
    pred = np.empty((NV, 2))
    tmp = np.empty((NV, 2))
    for i in range(NV):
        PF[0, i, 0] = -INF
        PF[0, i, 1] = INF
        PB[n - 1, i, 0] = -INF
        PB[n - 1, i, 1] = INF
    XF[0] = X0[0]
    if not couple(XF[0], vlat):
        XF[0] = X0[0]
        CF[0, 4] = 1
    for j in range(n - 1):
        if link[j]:
            predict_forward(XF[j], j, YR, FH, QH, DT, beta, pred)
        else:
            for i in range(NV):
                pred[i, 0] = -INF
                pred[i, 1] = INF
        PF[j + 1] = pred
        _combine(pred, X0[j + 1], XF[j + 1], CF[j + 1])
        tmp[:] = XF[j + 1]
        if not couple(XF[j + 1], vlat):
            XF[j + 1] = tmp
            CF[j + 1, 4] = 1
    XB[n - 1] = X0[n - 1]
    if not couple(XB[n - 1], vlat):
        XB[n - 1] = X0[n - 1]
        CB[n - 1, 4] = 1
    for j in range(n - 2, -1, -1):
        if link[j]:
            predict_backward(XB[j + 1], j, YR, FH, QH, DT, beta, pred)
        else:
            for i in range(NV):
                pred[i, 0] = -INF
                pred[i, 1] = INF
        PB[j] = pred
        _combine(pred, X0[j], XB[j], CB[j])
        tmp[:] = XB[j]
        if not couple(XB[j], vlat):
            XB[j] = tmp
            CB[j, 4] = 1


# ------------------------------------------------------------------------ fixpoint


@njit(cache=True)
def sweep(
    X: np.ndarray,
    link: np.ndarray,
    YR: np.ndarray,
    FH: np.ndarray,
    QH: np.ndarray,
    DT: np.ndarray,
    beta: np.ndarray,
    vlat: float,
    contract_beta: bool,
    tol: float,
) -> tuple[int, int, int, float]:
    """One forward and one backward sweep of every link and epoch coupling.

    Returns (status, epoch, what, max_shrink): status 0 ok, 1 empty at ``epoch``
    (``what``: the variable, or -1 for the coupling, -2 for beta); ``max_shrink`` the
    largest width reduction relative to ``tol * max(width, 1)`` seen (< 1: converged).
    """
    n = X.shape[0]
    old = np.empty((NV, 2))
    worst = 0.0
    for direction in range(2):
        for step in range(n - 1):
            j = step if direction == 0 else n - 2 - step
            if not link[j]:
                continue
            tgt = j + 1 if direction == 0 else j
            old[:] = X[tgt]
            code = constrain_link(X[j], X[j + 1], j, YR, FH, QH, DT, beta, contract_beta)
            if code == 2:
                return 1, j, -2, worst
            if code >= 0:
                e = j + code
                return 1, e, _empty7(X[e]), worst
            if not couple(X[tgt], vlat):
                return 1, tgt, -1, worst
            for i in range(NV):
                w0 = old[i, 1] - old[i, 0]
                w1 = X[tgt, i, 1] - X[tgt, i, 0]
                if math.isfinite(w0):
                    s = (w0 - w1) / (tol * max(w0, 1.0))
                    if s > worst:
                        worst = s
                elif math.isfinite(w1):
                    worst = max(worst, 2.0)
    return 0, -1, 0, worst


@njit(cache=True)
def fixpoint(
    X: np.ndarray,
    link: np.ndarray,
    YR: np.ndarray,
    FH: np.ndarray,
    QH: np.ndarray,
    DT: np.ndarray,
    beta: np.ndarray,
    vlat: float,
    contract_beta: bool,
    tol: float,
    max_sweeps: int,
) -> tuple[int, int, int, int]:
    """Sweeps until converged; (status, epoch, what, sweeps) as :func:`sweep`."""
    for s in range(max_sweeps):
        st, ep, what, worst = sweep(X, link, YR, FH, QH, DT, beta, vlat, contract_beta, tol)
        if st != 0:
            return st, ep, what, s + 1
        if worst < 1.0:
            return 0, -1, 0, s + 1
    return 0, -1, 0, max_sweeps


# ------------------------------------------------------------------ preintegration


@njit(cache=True)
def preintegrate(
    te: np.ndarray,
    bnd: np.ndarray,
    fx: np.ndarray,
    fy: np.ndarray,
    fz: np.ndarray,
    gr: np.ndarray,
    rl: np.ndarray,
    rh: np.ndarray,
    pl: np.ndarray,
    ph: np.ndarray,
    beta_r_mid: float,
    YR: np.ndarray,
    FH: np.ndarray,
    QH: np.ndarray,
    AA: np.ndarray,
) -> None:
    """Measured increments of every link, integrated over the IMU segments.

    Per segment ``k`` (``[bnd[k], bnd[k+1])``) the samples ``fx, fy, fz`` (intervals,
    (n, 2): unknown samples are wide), the yaw rate ``gr`` (n, 2) and the roll/pitch
    intervals ``rl..ph``; for link ``j`` (``te[j]..te[j+1]``) and each overlap of
    length ``l``:

    * heading-frame specific force a = (cos p fx - sin r sin p fy - cos r sin p fz,
      cos r fy - sin r fz), rotated by the gyro's own increment from ``te[j]`` at the
      segment's middle (nominal, bias ``beta_r_mid`` removed; its error is in the
      budget); ``FH += a l``, ``QH += a l (te[j+1] - mid)``;
    * ``YR += gr l``; ``AA[j] = (int |a|, int |gr|)`` upper bounds.
    """
    n_links = te.size - 1
    k0 = 0
    nseg = bnd.size - 1
    for j in range(n_links):
        t0 = te[j]
        t1 = te[j + 1]
        f0l = 0.0
        f0h = 0.0
        f1l = 0.0
        f1h = 0.0
        q0l = 0.0
        q0h = 0.0
        q1l = 0.0
        q1h = 0.0
        yl = 0.0
        yh = 0.0
        aabs = 0.0
        rabs = 0.0
        phi = 0.0  # nominal heading change since t0 (point)
        while k0 < nseg - 1 and bnd[k0 + 1] <= t0:
            k0 += 1
        kk = k0
        while kk < nseg and bnd[kk] < t1:
            s0 = max(bnd[kk], t0)
            s1 = min(bnd[kk + 1], t1)
            ln = s1 - s0
            if ln > 0.0:
                ln_i = c.sub(s1, s1, s0, s0)  # exact length enclosure
                grm = 0.5 * (gr[kk, 0] + gr[kk, 1]) - beta_r_mid
                ph_mid = phi + grm * 0.5 * ln
                phi = phi + grm * ln
                crl, crh = c.cos(rl[kk], rh[kk])
                srl, srh = c.sin(rl[kk], rh[kk])
                cpl, cph = c.cos(pl[kk], ph[kk])
                spl, sph = c.sin(pl[kk], ph[kk])
                t = c.mul(cpl, cph, fx[kk, 0], fx[kk, 1])
                u = c.mul(srl, srh, spl, sph)
                u = c.mul(u[0], u[1], fy[kk, 0], fy[kk, 1])
                t = c.sub(t[0], t[1], u[0], u[1])
                u = c.mul(crl, crh, spl, sph)
                u = c.mul(u[0], u[1], fz[kk, 0], fz[kk, 1])
                af = c.sub(t[0], t[1], u[0], u[1])
                t = c.mul(crl, crh, fy[kk, 0], fy[kk, 1])
                u = c.mul(srl, srh, fz[kk, 0], fz[kk, 1])
                al = c.sub(t[0], t[1], u[0], u[1])
                cl_, ch_ = c.cos(ph_mid, ph_mid)
                sl_, sh_ = c.sin(ph_mid, ph_mid)
                ax0, ax1, ay0, ay1 = _rot(cl_, ch_, sl_, sh_, af[0], af[1], al[0], al[1])
                t = c.mul(ax0, ax1, ln_i[0], ln_i[1])
                f0l, f0h = c.add(f0l, f0h, t[0], t[1])
                t = c.mul(ay0, ay1, ln_i[0], ln_i[1])
                f1l, f1h = c.add(f1l, f1h, t[0], t[1])
                w = c.sub(t1, t1, 0.5 * (s0 + s1), 0.5 * (s0 + s1))
                w = c.mul(w[0], w[1], ln_i[0], ln_i[1])
                # the midpoint 0.5 (s0 + s1) is rounded: widen the weight by one ulp of t1
                w = c.add(w[0], w[1], -abs(t1) * 2.3e-16 * ln, abs(t1) * 2.3e-16 * ln)
                t = c.mul(ax0, ax1, w[0], w[1])
                q0l, q0h = c.add(q0l, q0h, t[0], t[1])
                t = c.mul(ay0, ay1, w[0], w[1])
                q1l, q1h = c.add(q1l, q1h, t[0], t[1])
                t = c.mul(gr[kk, 0], gr[kk, 1], ln_i[0], ln_i[1])
                yl, yh = c.add(yl, yh, t[0], t[1])
                amax = max(abs(af[0]), abs(af[1]), abs(al[0]), abs(al[1]))
                aabs += amax * ln * 1.4142135623730951
                rabs += max(abs(gr[kk, 0]), abs(gr[kk, 1])) * ln
            kk += 1
        YR[j, 0], YR[j, 1] = yl, yh
        FH[j, 0, 0], FH[j, 0, 1] = f0l, f0h
        FH[j, 1, 0], FH[j, 1, 1] = f1l, f1h
        QH[j, 0, 0], QH[j, 0, 1] = q0l, q0h
        QH[j, 1, 0], QH[j, 1, 1] = q1l, q1h
        AA[j, 0] = aabs * (1.0 + ROUND_REL)
        AA[j, 1] = rabs * (1.0 + ROUND_REL)


# ------------------------------------------------------------------------ driver


@dataclass
class Dropped:
    """A measurement (or IMU link) left out by the q-relaxed intersection."""

    t_s: float
    sensor: str
    miss: float
    unit: str
    reason: str

    def to_dict(self) -> dict[str, Any]:
        return {
            "t_s": self.t_s,
            "sensor": self.sensor,
            "miss": self.miss,
            "unit": self.unit,
            "reason": self.reason,
        }


@dataclass
class SmootherResult:
    te: np.ndarray
    X: np.ndarray
    beta: np.ndarray
    dropped: list[Dropped]
    rounds: int
    sweeps: int
    beta_note: str = ""
    link: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))


def _gap(m: np.ndarray, L: np.ndarray) -> float:
    """Distance between intervals m and L (0 if they meet)."""
    return float(max(m[0] - L[1], L[0] - m[1], 0.0))


def smooth(
    te: np.ndarray,
    prior: np.ndarray,
    meas: np.ndarray,
    has: np.ndarray,
    YR: np.ndarray,
    FH: np.ndarray,
    QH: np.ndarray,
    beta0: np.ndarray,
    vlat: float,
    tol: float = 1e-3,
    max_sweeps: int = 200,
    max_rounds: int = 30,
    t_offset: float = 0.0,
) -> SmootherResult:
    """Screen outliers, then contract the network to its fixpoint.

    ``prior`` (n, 7, 2): what holds without measurements (vehicle bounds, entire);
    ``meas`` (n, 7, 2): the measurement boxes (entire where absent); ``has`` (n, 4):
    which groups have a measurement at each epoch. ``beta0`` (3, 2): bias intervals
    (accel x, accel y, yaw rate) before the smoother. Times ``te`` relative; reported
    times add ``t_offset``.
    """
    n = te.size
    DT = np.diff(te)
    link = np.ones(max(n - 1, 0), dtype=np.bool_)
    drop = np.zeros((n, 4), dtype=bool)
    dropped: list[Dropped] = []
    rounds = 0
    sweeps = 0
    beta_note = ""

    def cur_x0() -> np.ndarray:
        x = prior.copy()
        for g, vs in enumerate(GROUP_VARS):
            sel = has[:, g] & ~drop[:, g]
            for v in vs:
                x[sel, v, 0] = np.maximum(prior[sel, v, 0], meas[sel, v, 0])
                x[sel, v, 1] = np.minimum(prior[sel, v, 1], meas[sel, v, 1])
        return x

    while True:
        rounds += 1
        x0 = cur_x0()
        PF = np.empty_like(x0)
        PB = np.empty_like(x0)
        XF = np.empty_like(x0)
        XB = np.empty_like(x0)
        CF = np.zeros((n, 5), dtype=np.int64)
        CB = np.zeros((n, 5), dtype=np.int64)
        run_filters(x0, link, YR, FH, QH, DT, beta0, vlat, PF, PB, XF, XB, CF, CB)
        del CF, CB
        new = _screen(te, x0, has & ~drop, PF, PB, link, drop, dropped, t_offset)
        del PF, PB  # the predictions serve the screening only (n x 7 x 2 each)
        if new and rounds < max_rounds:
            continue
        # X = the filters' intersection where it is not empty, x0 elsewhere (in place)
        X = _intersect(XF, XB)
        ok = np.all(X[..., 0] <= X[..., 1], axis=1)
        X[~ok] = x0[~ok]
        del x0, ok
        start = X.copy()
        beta = beta0.copy()
        st, ep, what, sw = fixpoint(X, link, YR, FH, QH, DT, beta, vlat, True, tol, max_sweeps)
        sweeps += sw
        if st != 0 and what == -2:
            beta_note = (
                "the per-link constraints on the biases were inconsistent over the trip "
                f"(first at t = {te[max(ep, 0)] + t_offset:.2f} s): the biases are not "
                "contracted by the smoother"
            )
            X = start.copy()
            beta = beta0.copy()
            st, ep, what, sw = fixpoint(X, link, YR, FH, QH, DT, beta, vlat, False, tol, max_sweeps)
            sweeps += sw
        if st == 0:
            return SmootherResult(te, X, beta, dropped, rounds, sweeps, beta_note, link)
        if rounds >= max_rounds:
            hull = np.stack(
                [np.minimum(XF[..., 0], XB[..., 0]), np.maximum(XF[..., 1], XB[..., 1])], -1
            )
            note = beta_note + (
                f" the fixpoint still met an empty intersection after {rounds} rounds of "
                "dropping; the states are the hull of the forward and backward filters"
            )
            return SmootherResult(
                te, hull, beta0.copy(), dropped, rounds, sweeps, note.strip(), link
            )
        # an empty intersection the screening did not catch: drop at that epoch
        g = _group_of(what)
        done = False
        for gg in [g] if g >= 0 else [0, 1, 2, 3]:
            if has[ep, gg] and not drop[ep, gg]:
                drop[ep, gg] = True
                dropped.append(
                    Dropped(
                        float(te[ep] + t_offset),
                        GROUP_NAMES[gg],
                        float("nan"),
                        GROUP_UNITS[gg],
                        "empty intersection in the fixpoint at this epoch",
                    )
                )
                done = True
                break
        if not done and n > 1:
            jl = min(max(ep - 1, 0), n - 2)
            for jj in (jl, min(jl + 1, n - 2)):
                if link[jj]:
                    link[jj] = False
                    dropped.append(
                        Dropped(
                            float(te[jj] + t_offset),
                            "imu link",
                            float("nan"),
                            "",
                            "empty intersection in the fixpoint; the IMU constraint over "
                            f"[{te[jj] + t_offset:.3f}, {te[jj + 1] + t_offset:.3f}] s "
                            "is dropped",
                        )
                    )
                    done = True
                    break
        if not done:
            rounds = max_rounds - 1  # nothing left to drop here: finish with the filters


def _intersect(X: np.ndarray, x0: np.ndarray) -> np.ndarray:
    out = np.empty(np.broadcast_shapes(X.shape, x0.shape))
    np.maximum(X[..., 0], x0[..., 0], out=out[..., 0])
    np.minimum(X[..., 1], x0[..., 1], out=out[..., 1])
    return out


def _group_of(var: int) -> int:
    for g, vs in enumerate(GROUP_VARS):
        if var in vs:
            return g
    return -1


def _screen(
    te: np.ndarray,
    x0: np.ndarray,
    has: np.ndarray,
    PF: np.ndarray,
    PB: np.ndarray,
    link: np.ndarray,
    drop: np.ndarray,
    dropped: list[Dropped],
    t_offset: float,
) -> bool:
    """The two-sided check of every kept measurement (q-relaxed intersection of the
    measurement and the predictions from the past and from the future)."""
    new = False
    for g, vs in enumerate(GROUP_VARS):
        vs_ = list(vs)
        m_lo, m_hi = x0[:, vs_, 0], x0[:, vs_, 1]
        # the predictions' intersection, for this group's variables only
        L_lo = np.maximum(PF[:, vs_, 0], PB[:, vs_, 0])
        L_hi = np.minimum(PF[:, vs_, 1], PB[:, vs_, 1])
        preds_meet = np.all(L_lo <= L_hi, axis=1)
        miss = np.any((m_lo > L_hi) | (m_hi < L_lo), axis=1)
        if g == G_POS:
            # a GNSS fix is a disc (its box circumscribes it): test the disc
            with np.errstate(invalid="ignore", over="ignore"):
                c = 0.5 * (m_lo + m_hi)
                rad = 0.5 * np.max(m_hi - m_lo, axis=1)
                gap = np.maximum(np.maximum(L_lo - c, c - L_hi), 0.0)
                dist = np.hypot(gap[:, 0], gap[:, 1])
            miss = miss | (np.isfinite(dist) & (dist > rad * (1 + 1e-9)))
        bad = has[:, g] & preds_meet & miss
        for e in np.flatnonzero(bad):
            gap = max(_gap(np.array([m_lo[e, i], m_hi[e, i]]), np.array([L_lo[e, i], L_hi[e, i]]))
                      for i in range(len(vs_)))
            drop[e, g] = True
            new = True
            dropped.append(
                Dropped(
                    float(te[e] + t_offset),
                    GROUP_NAMES[g],
                    gap,
                    GROUP_UNITS[g],
                    "misses the predictions from both sides (which agree)",
                )
            )
        # predictions disagree: the side the measurement does not meet is the odd one
        conflict = has[:, g] & ~preds_meet
        for e in np.flatnonzero(conflict):
            mf = np.all(
                np.maximum(m_lo[e], PF[e, vs_, 0]) <= np.minimum(m_hi[e], PF[e, vs_, 1])
            )
            mb = np.all(
                np.maximum(m_lo[e], PB[e, vs_, 0]) <= np.minimum(m_hi[e], PB[e, vs_, 1])
            )
            if mb and not mf and e >= 1 and link[e - 1]:
                link[e - 1] = False
                new = True
                gap = max(
                    _gap(np.array([m_lo[e, i], m_hi[e, i]]), PF[e, vs_[i]]) for i in range(len(vs_))
                )
                dropped.append(
                    Dropped(
                        float(te[e - 1] + t_offset),
                        "imu link",
                        gap,
                        GROUP_UNITS[g],
                        f"the IMU prediction over [{te[e - 1] + t_offset:.3f}, "
                        f"{te[e] + t_offset:.3f}] s misses the {GROUP_NAMES[g]} and the "
                        "prediction from the future",
                    )
                )
            elif mf and not mb and e + 1 < te.size and link[e]:
                link[e] = False
                new = True
                gap = max(
                    _gap(np.array([m_lo[e, i], m_hi[e, i]]), PB[e, vs_[i]]) for i in range(len(vs_))
                )
                dropped.append(
                    Dropped(
                        float(te[e] + t_offset),
                        "imu link",
                        gap,
                        GROUP_UNITS[g],
                        f"the IMU prediction over [{te[e] + t_offset:.3f}, "
                        f"{te[e + 1] + t_offset:.3f}] s (backwards) misses the "
                        f"{GROUP_NAMES[g]} and the prediction from the past",
                    )
                )
            elif not mf and not mb:
                drop[e, g] = True
                new = True
                dropped.append(
                    Dropped(
                        float(te[e] + t_offset),
                        GROUP_NAMES[g],
                        float("nan"),
                        GROUP_UNITS[g],
                        "misses both predictions, which disagree too",
                    )
                )
    return new
