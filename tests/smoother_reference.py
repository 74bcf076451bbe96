"""Readable pure-Python references of the smoother's compiled hot paths (for tests).

Written from the equations of :mod:`imubounds.dynamic.estimator.smoother` with the
small interval class of the paper reference, whose operators call the same scalar
rules of :mod:`imubounds.interval`; the compiled functions must agree bit for bit.
Slow (pure Python): for short trips only.
"""

from __future__ import annotations

import math

import numpy as np

from imubounds.interval import scalar as R
from imubounds.interval import scalar_contractors as K
from tests.paper_reference import Iv, icos, isin

E, N, VE, VN, PSI, UH, VH = range(7)
ENTIRE = Iv(-math.inf, math.inf)


def rot(c: Iv, s: Iv, x: Iv, y: Iv) -> tuple[Iv, Iv]:
    """R(psi) (x, y)."""
    return c * x - s * y, s * x + c * y


def irot(c: Iv, s: Iv, x: Iv, y: Iv) -> tuple[Iv, Iv]:
    """R(-psi) (x, y)."""
    return c * x + s * y, c * y - s * x


def preintegrate_reference(
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
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Same outputs as :func:`~imubounds.dynamic.estimator.smoother.preintegrate`."""
    n = te.size - 1
    YR = np.empty((n, 2))
    FH = np.empty((n, 2, 2))
    QH = np.empty((n, 2, 2))
    AA = np.empty((n, 2))
    for j in range(n):
        t0, t1 = float(te[j]), float(te[j + 1])
        F = [Iv(0.0, 0.0), Iv(0.0, 0.0)]
        Q = [Iv(0.0, 0.0), Iv(0.0, 0.0)]
        Y = Iv(0.0, 0.0)
        aabs = rabs = 0.0
        phi = 0.0
        for k in range(bnd.size - 1):
            s0, s1 = max(bnd[k], t0), min(bnd[k + 1], t1)
            ln = s1 - s0
            if not ln > 0.0:
                continue
            L = Iv.pt(s1) - Iv.pt(s0)
            grm = 0.5 * (gr[k, 0] + gr[k, 1]) - beta_r_mid
            ph_mid = phi + grm * 0.5 * ln
            phi = phi + grm * ln
            roll, pitch = Iv(rl[k], rh[k]), Iv(pl[k], ph[k])
            cr, sr, cp, sp = icos(roll), isin(roll), icos(pitch), isin(pitch)
            ax, ay, az = Iv(*fx[k]), Iv(*fy[k]), Iv(*fz[k])
            a_fwd = cp * ax - (sr * sp) * ay - (cr * sp) * az
            a_left = cr * ay - sr * az
            c, s = icos(Iv.pt(ph_mid)), isin(Iv.pt(ph_mid))
            r0, r1 = rot(c, s, a_fwd, a_left)
            F[0] = F[0] + r0 * L
            F[1] = F[1] + r1 * L
            mid = 0.5 * (s0 + s1)
            w = (Iv.pt(t1) - Iv.pt(mid)) * L
            e = abs(t1) * 2.3e-16 * ln
            w = w + Iv(-e, e)
            Q[0] = Q[0] + r0 * w
            Q[1] = Q[1] + r1 * w
            Y = Y + Iv(*gr[k]) * L
            amax = max(abs(a_fwd.lo), abs(a_fwd.hi), abs(a_left.lo), abs(a_left.hi))
            aabs += amax * ln * 1.4142135623730951
            rabs += max(abs(gr[k, 0]), abs(gr[k, 1])) * ln
        YR[j] = Y.lo, Y.hi
        FH[j, 0], FH[j, 1] = (F[0].lo, F[0].hi), (F[1].lo, F[1].hi)
        QH[j, 0], QH[j, 1] = (Q[0].lo, Q[0].hi), (Q[1].lo, Q[1].hi)
        AA[j] = aabs * (1.0 + 1e-12), rabs * (1.0 + 1e-12)
    return YR, FH, QH, AA


def _hc4_add(z: Iv, x: Iv, y: Iv) -> tuple[Iv, Iv, Iv] | None:
    r = K.ctc_add(z.lo, z.hi, x.lo, x.hi, y.lo, y.hi, 3)
    if r[6] >= 0:
        return None
    return Iv(r[0], r[1]), Iv(r[2], r[3]), Iv(r[4], r[5])


def link_reference(
    xa: list[Iv], xb: list[Iv], yr: Iv, fh: list[Iv], qh: list[Iv], d: float, beta: list[Iv],
    contract_beta: bool,
) -> bool:
    """The three constraints of one link, contracted in place on ``xa``, ``xb``, ``beta``
    (lists of Iv); False if something became empty. Mirrors ``constrain_link``."""
    D = Iv.pt(d)
    phi = yr - D * beta[2]
    r = _hc4_add(xb[PSI], xa[PSI], phi)
    if r is None:
        return False
    xb[PSI], xa[PSI], phi = r
    if contract_beta:
        beta[2] = beta[2] & ((yr - phi) / D)
        if beta[2].empty():
            return False
    hd = Iv.pt(d) * Iv.pt(0.5)
    d2 = hd * D
    f = [fh[a] - D * beta[a] for a in range(2)]
    q = [qh[a] - d2 * beta[a] for a in range(2)]
    c, s = icos(xa[PSI]), isin(xa[PSI])
    we, wn = rot(c, s, f[0], f[1])
    r = _hc4_add(xb[VE], xa[VE], we)
    if r is None:
        return False
    xb[VE], xa[VE], we = r
    r = _hc4_add(xb[VN], xa[VN], wn)
    if r is None:
        return False
    xb[VN], xa[VN], wn = r
    if contract_beta:
        g0, g1 = irot(c, s, we, wn)
        for a, g in ((0, g0), (1, g1)):
            fa = f[a] & g
            beta[a] = beta[a] & ((fh[a] - fa) / D)
            if beta[a].empty():
                return False
    qe, qn = rot(c, s, q[0], q[1])
    for pv, vv, qq in ((E, VE, qe), (N, VN, qn)):
        vd = xa[vv] * D
        dd = vd + qq
        r = _hc4_add(xb[pv], xa[pv], dd)
        if r is None:
            return False
        xb[pv], xa[pv], dd = r
        r2 = K.ctc_add(dd.lo, dd.hi, vd.lo, vd.hi, qq.lo, qq.hi, 3)
        if r2[6] >= 0:
            return False
        r3 = K.ctc_mul(r2[2], r2[3], xa[vv].lo, xa[vv].hi, d, d, 3)
        if r3[6] >= 0:
            return False
        xa[vv] = Iv(r3[2], r3[3])
    return True


def couple_reference(x: list[Iv], vlat: float) -> bool:
    """Mirror of ``couple`` (rotation nav <-> heading frame, heading from the course)."""
    if vlat < math.inf:
        x[VH] = x[VH] & Iv(-vlat, vlat)
        if x[VH].empty():
            return False
    for _ in range(2):
        c, s = icos(x[PSI]), isin(x[PSI])
        u, v = irot(c, s, x[VE], x[VN])
        x[UH], x[VH] = x[UH] & u, x[VH] & v
        if x[UH].empty() or x[VH].empty():
            return False
        e, n = rot(c, s, x[UH], x[VH])
        x[VE], x[VN] = x[VE] & e, x[VN] & n
        if x[VE].empty() or x[VN].empty():
            return False
        sq = Iv(*R.sqr(x[VE].lo, x[VE].hi)) + Iv(*R.sqr(x[VN].lo, x[VN].hi))
        sp = Iv(*R.sqrt(sq.lo, sq.hi))
        av = max(abs(x[VH].lo), abs(x[VH].hi))
        if sp.lo > av and (x[UH].lo > 0.0 or x[UH].hi < 0.0) and math.isfinite(sp.hi):
            chi = Iv(*R.atan2(x[VN].lo, x[VN].hi, x[VE].lo, x[VE].hi))
            b = Iv(*R.atan2(-x[VN].hi, -x[VN].lo, -x[VE].hi, -x[VE].lo))
            b = b + Iv(R.PI_LO, R.PI_HI)
            if b.hi - b.lo < chi.hi - chi.lo:
                chi = b
            if chi.hi - chi.lo < math.pi:
                q = x[VH] / sp
                dlt = Iv(*R.asin(q.lo, q.hi))
                if x[UH].hi < 0.0:
                    dlt = Iv(R.PI_LO, R.PI_HI) - dlt
                p = chi - dlt
                if math.isfinite(x[PSI].lo) and math.isfinite(x[PSI].hi):
                    dm = 0.5 * (x[PSI].lo + x[PSI].hi) - 0.5 * (p.lo + p.hi)
                    m = float(math.floor(dm / (2 * math.pi) + 0.5))
                    p = p + Iv(R.TWO_PI_LO, R.TWO_PI_HI) * Iv(m, m)
                    x[PSI] = x[PSI] & p
                    if x[PSI].empty():
                        return False
    return True


def sweep_reference(
    X: np.ndarray,
    link: np.ndarray,
    YR: np.ndarray,
    FH: np.ndarray,
    QH: np.ndarray,
    DT: np.ndarray,
    beta: np.ndarray,
    vlat: float,
    contract_beta: bool,
) -> bool:
    """One forward and one backward sweep (as ``sweep``), in place; False on empty."""
    n = X.shape[0]
    st = [[Iv(*X[j, i]) for i in range(7)] for j in range(n)]
    b = [Iv(*beta[i]) for i in range(3)]
    ok = True
    for direction in range(2):
        for step in range(n - 1):
            j = step if direction == 0 else n - 2 - step
            if not link[j]:
                continue
            tgt = j + 1 if direction == 0 else j
            if not link_reference(
                st[j],
                st[j + 1],
                Iv(*YR[j]),
                [Iv(*FH[j, 0]), Iv(*FH[j, 1])],
                [Iv(*QH[j, 0]), Iv(*QH[j, 1])],
                float(DT[j]),
                b,
                contract_beta,
            ):
                ok = False
                break
            if not couple_reference(st[tgt], vlat):
                ok = False
                break
        if not ok:
            break
    for j in range(n):
        for i in range(7):
            X[j, i] = st[j][i].lo, st[j][i].hi
    for i in range(3):
        beta[i] = b[i].lo, b[i].hi
    return ok
