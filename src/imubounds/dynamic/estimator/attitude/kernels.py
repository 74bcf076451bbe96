"""Compiled loops of the attitude states (docs/dynamic-method.md, section 3b). Plain
references: ``tests/attitude_reference.py``.

The state is the horizontal part ``h = (sin theta, sin phi cos theta)`` of the up
direction in the body frame (what accel_x and accel_y measure of gravity, over g). With
``p, q, r`` the body rates against the local level frame (FLU),

    h' = r J h + (-q, p) u_z,   J = [[0, 1], [-1, 0]],   u_z = cos phi cos theta,

so from a node ``c`` (3b.3): ``h(t) = R(-dpsi(t)) h_c + v(t)``, ``dpsi = int_c^t r``,
``v' = r J v + (-q, p)``, ``v(c) = 0`` (``R(-a) = [[cos a, sin a], [-sin a, cos a]]``),
integrated exactly sample by sample with the measured rates (:func:`_step`); the
errors (gyro budgets, ``u_z < 1``, the sample model) are bounded per component by
:func:`_err`. In the yaw-compensated frame ``w = R(psi_m) h`` (``psi_m`` the measured
running integral of gyro_z) a node's uncertainty does not turn with the vehicle:
``w_k+1 = w_k + R(psi_m,k+1) v_k``, so the chain adds, and each node holds a polygon
given by its support in :data:`ND` fixed directions (a template polyhedron), cut by the
strips of its windows and its prior (:func:`add_strip`).

Floats, not intervals, inside the loops: every result is widened afterwards by a bound
of its rounding (:data:`REL`, :data:`ABS`: a few ulps per operation over at most
``1e7`` operations, far below them).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

#: directions of a node's template polygon (over the full circle)
ND = 16
#: relative and absolute widening of every computed bound (rounding, see the docstring)
REL = 1e-9
ABS = 1e-12
#: the box every polygon starts in (|h| <= 1)
BIG = 2.0


@njit(cache=True)
def _cumk(x: float, a1: float, b1: float, a2: float, b2: float) -> float:
    """Integral of ``tau K`` from ``a1`` to ``x`` (ramps on ``[a1, b1]``, ``[a2, b2]``)."""
    l1 = b1 - a1
    l2 = b2 - a2
    out = 0.0
    r1 = min(max(x - a1, 0.0), l1)
    if l1 > 0.0:
        out += r1 * r1 / (2.0 * l1)
    out += min(max(x - b1, 0.0), a2 - b1)
    r2 = min(max(x - a2, 0.0), l2)
    if l2 > 0.0:
        out += r2 - r2 * r2 / (2.0 * l2)
    else:
        out += r2
    return out


@njit(cache=True)
def _step(vx: float, vy: float, yr: float, gx: float, gy: float, ln: float
          ) -> tuple[float, float]:
    """``v`` after ``ln`` s of ``v' = yr J v + g`` (constant ``yr``, ``g``), exact."""
    a = yr * ln
    ca, sa = math.cos(a), math.sin(a)
    if abs(a) < 1e-4:
        b1 = ln * (1.0 - a * a / 6.0)
        b2 = ln * (a / 2.0 - a * a * a / 24.0)
    else:
        b1 = sa / yr
        b2 = (1.0 - ca) / yr
    # R(-a) v + B g, B = [[b1, b2], [-b2, b1]]
    nx = ca * vx + sa * vy + b1 * gx + b2 * gy
    ny = -sa * vx + ca * vy - b2 * gx + b1 * gy
    return nx, ny


@njit(cache=True)
def _err(L: float, side: float, Aq: float, Ap: float, Ar: float, U: float,
         c: np.ndarray) -> float:
    """Error bound of each component of ``h(t) - R(-dpsi) h_c - v(t)`` at ``L`` s from the
    node (3b.4): ``c`` = (bias, white, a_q, a_p, a_r, dev, const, unk, bias over spans of
    at least c[9] s, c[9]) coefficients of ``L``, ``sqrt(side)``, the magnitude integrals
    ``A_q, A_p, A_r``, ``sqrt(L)``, 1 and the unknown length ``U``: the bias term is
    ``c[8] L`` where ``L >= c[9]`` (a stated drift bound bounds means over spans that
    long) if smaller."""
    b = c[0] * L
    if L >= c[9]:
        b = min(b, c[8] * L)
    return (b + c[1] * math.sqrt(side) + c[2] * Aq + c[3] * Ap + c[4] * Ar
            + c[5] * math.sqrt(L) + c[6] + c[7] * U)


@njit(cache=True)
def _coef(yr: float, ln: float) -> tuple[float, float, float, float]:
    """cos a, sin a, b1, b2 of a step of ``ln`` s at the rate ``yr`` (a = yr ln)."""
    a = yr * ln
    ca, sa = math.cos(a), math.sin(a)
    if abs(a) < 1e-4:
        return ca, sa, ln * (1.0 - a * a / 6.0), ln * (a / 2.0 - a * a * a / 24.0)
    return ca, sa, sa / yr, (1.0 - ca) / yr


def step_tables(bnd: np.ndarray, yr: np.ndarray) -> np.ndarray:
    """Per IMU segment: (cos a, sin a, b1, b2) of its whole length (``_coef``)."""
    dl = np.diff(bnd)
    a = yr * dl
    ca, sa = np.cos(a), np.sin(a)
    small = np.abs(a) < 1e-4
    ys = np.where(small, 1.0, yr)
    b1 = np.where(small, dl * (1.0 - a * a / 6.0), sa / ys)
    b2 = np.where(small, dl * (a / 2.0 - a**3 / 24.0), (1.0 - ca) / ys)
    return np.ascontiguousarray(np.stack([ca, sa, b1, b2], 1))


@njit(cache=True)
def _walk(bnd: np.ndarray, tab: np.ndarray, yp: np.ndarray, yq: np.ndarray, yr: np.ndarray,
          unk: np.ndarray, mp: np.ndarray, mq: np.ndarray, mr: np.ndarray,
          t_node: float, t_end: float, forward: bool, ker: np.ndarray, side: float,
          c: np.ndarray, edge: float, acc: np.ndarray) -> None:
    """Walk the IMU segments from ``t_node`` to ``t_end`` accumulating, with the kernel
    weights of ``ker`` (a1, b1, a2, b2, tau), ``acc`` += (sum w cos dpsi, sum w sin
    dpsi, sum w v_x, sum w v_y, sum w err, sum w eps_M), each piece's values at its
    start, their change over the piece bounded in ``err`` and ``eps_M``."""
    n = bnd.size - 1
    a1, b1, a2, b2, tau = ker[0], ker[1], ker[2], ker[3], ker[4]
    box = a1 == b1 and a2 == b2
    if forward:
        k = int(np.searchsorted(bnd, t_node, side="right")) - 1
    else:
        k = int(np.searchsorted(bnd, t_node, side="left")) - 1
    k = min(max(k, 0), n - 1)
    t = t_node
    cs = 1.0
    sn = 0.0
    vx = 0.0
    vy = 0.0
    Aq = 0.0
    Ap = 0.0
    Ar = 0.0
    U = 0.0
    while 0 <= k < n:
        if forward:
            s0 = t
            s1 = min(bnd[k + 1], t_end)
        else:
            s1 = t
            s0 = max(bnd[k], t_end)
        ln = s1 - s0
        if ln <= 0.0:
            if (forward and bnd[k + 1] >= t_end) or (not forward and bnd[k] <= t_end):
                break
            k += 1 if forward else -1
            continue
        r = yr[k]
        gx = -yq[k]
        gy = yp[k]
        if box:
            w = ln / tau
        else:
            w = (_cumk(s1, a1, b1, a2, b2) - _cumk(s0, a1, b1, a2, b2)) / tau
        L = (s1 - t_node) if forward else (t_node - s0)
        Aq += mq[k] * ln
        Ap += mp[k] * ln
        Ar += mr[k] * ln
        if unk[k]:
            U += ln
        e = _err(L, side, Aq, Ap, Ar, U, c) + edge
        u = unk[k]
        gn = abs(gx) + abs(gy) + (mq[k] + mp[k] if u else 0.0)
        ev = (abs(r) * (abs(vx) + abs(vy)) * 2.0 + gn) * ln
        acc[0] += w * cs
        acc[1] += w * sn
        acc[2] += w * vx
        acc[3] += w * vy
        acc[4] += w * (e + ev)
        acc[5] += w * (abs(r) + (mr[k] if u else 0.0)) * ln
        if ln == bnd[k + 1] - bnd[k]:
            ca, sa, c1, c2 = tab[k, 0], tab[k, 1], tab[k, 2], tab[k, 3]
        else:
            ca, sa, c1, c2 = _coef(r, ln)
        px = c1 * gx + c2 * gy
        py = -c2 * gx + c1 * gy
        if forward:
            # v <- R(-a) v + B g;  dpsi <- dpsi + a
            vx, vy = ca * vx + sa * vy + px, -sa * vx + ca * vy + py
            cs, sn = cs * ca - sn * sa, sn * ca + cs * sa
            t = s1
            k += 1
        else:
            # v <- R(a) (v - B g);  dpsi <- dpsi - a
            ux, uy = vx - px, vy - py
            vx, vy = ca * ux - sa * uy, sa * ux + ca * uy
            cs, sn = cs * ca + sn * sa, sn * ca - cs * sa
            t = s0
            k -= 1


@njit(cache=True)
def window_terms(bnd: np.ndarray, tab: np.ndarray, yp: np.ndarray, yq: np.ndarray,
                 yr: np.ndarray,
                 unk: np.ndarray, mp: np.ndarray, mq: np.ndarray, mr: np.ndarray,
                 t_node: np.ndarray, ker: np.ndarray, c: np.ndarray, edge: np.ndarray,
                 out: np.ndarray) -> None:
    """Per window: ``out[w] = (C, S, V_x, V_y, E, eps_M)`` with ``mean_K h = M h_c +
    V +- E`` per component, ``M = [[C, S], [-S, C]] +- eps_M`` (3b.3); ``edge[w]`` the
    sample-model error where the node or an end cuts a sample."""
    acc = np.zeros(6)
    for w in range(t_node.size):
        acc[:] = 0.0
        kw = ker[w]
        _walk(bnd, tab, yp, yq, yr, unk, mp, mq, mr, t_node[w], kw[3], True, kw,
              kw[3] - t_node[w], c, edge[w], acc)
        _walk(bnd, tab, yp, yq, yr, unk, mp, mq, mr, t_node[w], kw[0], False, kw,
              t_node[w] - kw[0], c, edge[w], acc)
        for i in range(6):
            out[w, i] = acc[i]


@njit(cache=True)
def link_terms(bnd: np.ndarray, yp: np.ndarray, yq: np.ndarray, yr: np.ndarray,
               unk: np.ndarray, mp: np.ndarray, mq: np.ndarray, mr: np.ndarray,
               te: np.ndarray, c: np.ndarray, edge: np.ndarray, out: np.ndarray) -> None:
    """Per link ``[te_k, te_k+1]``: ``out[k] = (dpsi, v_x, v_y, err, max |dpsi|, v_x
    lo, v_x hi, v_y lo, v_y hi)``: the measured turn and ``v`` at the link's end, the
    error there (3b.4), and the hull of the turn and of ``v`` over the link."""
    n = bnd.size - 1
    k = 0
    for j in range(te.size - 1):
        t0 = te[j]
        t1 = te[j + 1]
        while k < n - 1 and bnd[k + 1] <= t0:
            k += 1
        kk = k
        t = t0
        dpsi = 0.0
        vx = 0.0
        vy = 0.0
        Aq = 0.0
        Ap = 0.0
        Ar = 0.0
        U = 0.0
        mpsi = 0.0
        xlo = 0.0
        xhi = 0.0
        ylo = 0.0
        yhi = 0.0
        while kk < n and bnd[kk] < t1:
            s1 = min(bnd[kk + 1], t1)
            ln = s1 - t
            if ln > 0.0:
                r = yr[kk]
                gx = -yq[kk]
                gy = yp[kk]
                gn = (abs(gx) + abs(gy) + (mq[kk] + mp[kk] if unk[kk] else 0.0)
                      + abs(r) * (abs(vx) + abs(vy))) * ln
                vx, vy = _step(vx, vy, r, gx, gy, ln)
                gn += abs(r) * (abs(vx) + abs(vy)) * ln
                dpsi += r * ln
                Aq += mq[kk] * ln
                Ap += mp[kk] * ln
                Ar += mr[kk] * ln
                if unk[kk]:
                    U += ln
                # inside the piece v stays within gn of its ends
                xlo = min(xlo, vx - gn)
                xhi = max(xhi, vx + gn)
                ylo = min(ylo, vy - gn)
                yhi = max(yhi, vy + gn)
                mpsi = max(mpsi, abs(dpsi) + abs(r) * ln + (mr[kk] * ln if unk[kk] else 0.0))
                t = s1
            kk += 1
        e = _err(t1 - t0, t1 - t0, Aq, Ap, Ar, U, c) + edge[j]
        out[j, 0] = dpsi
        out[j, 1] = vx
        out[j, 2] = vy
        out[j, 3] = e
        out[j, 4] = mpsi
        out[j, 5] = xlo
        out[j, 6] = xhi
        out[j, 7] = ylo
        out[j, 8] = yhi


# ------------------------------------------------------------------ template polygons

#: the template's directions (unit vectors at 2 pi j / ND)
DIRS = np.stack([np.cos(2 * np.pi * np.arange(ND) / ND),
                 np.sin(2 * np.pi * np.arange(ND) / ND)], 1)
#: vertices a polygon can have: the start box's 4, one more per cut
CAP = 4 + ND + 4


@njit(cache=True)
def _clip(px: np.ndarray, py: np.ndarray, n: int, a: float, b: float, cc: float,
          qx: np.ndarray, qy: np.ndarray) -> int:
    """Sutherland-Hodgman: the polygon ``p`` (n vertices) cut by ``a x + b y <= cc``,
    into ``q``; returns the vertex count."""
    m = 0
    for i in range(n):
        j = i + 1 if i + 1 < n else 0
        fi = a * px[i] + b * py[i] - cc
        fj = a * px[j] + b * py[j] - cc
        if fi <= 0.0:
            qx[m] = px[i]
            qy[m] = py[i]
            m += 1
        if (fi < 0.0 < fj) or (fj < 0.0 < fi):
            s = fi / (fi - fj)
            qx[m] = px[i] + s * (px[j] - px[i])
            qy[m] = py[i] + s * (py[j] - py[i])
            m += 1
    return m


@njit(cache=True)
def _polygon(u: np.ndarray, d: np.ndarray, px: np.ndarray, py: np.ndarray,
             qx: np.ndarray, qy: np.ndarray) -> int:
    """Vertices of the template polygon ``d_j . x <= u_j`` into ``px, py``."""
    px[0], py[0] = -BIG, -BIG
    px[1], py[1] = BIG, -BIG
    px[2], py[2] = BIG, BIG
    px[3], py[3] = -BIG, BIG
    n = 4
    for j in range(ND):
        # a cut that leaves every vertex inside changes nothing
        inside = True
        for i in range(n):
            if d[j, 0] * px[i] + d[j, 1] * py[i] > u[j]:
                inside = False
                break
        if inside:
            continue
        n = _clip(px, py, n, d[j, 0], d[j, 1], u[j], qx, qy)
        if n == 0:
            return 0
        for i in range(n):
            px[i] = qx[i]
            py[i] = qy[i]
    return n


@njit(cache=True)
def _support(px: np.ndarray, py: np.ndarray, n: int, a: float, b: float) -> float:
    m = -np.inf
    for i in range(n):
        v = a * px[i] + b * py[i]
        if v > m:
            m = v
    return m


@njit(cache=True)
def _strip(u: np.ndarray, d: np.ndarray, a: float, b: float, lo: float, hi: float,
           px: np.ndarray, py: np.ndarray, qx: np.ndarray, qy: np.ndarray) -> bool:
    n = _polygon(u, d, px, py, qx, qy)
    if n == 0:
        return False
    n = _clip(px, py, n, a, b, hi, qx, qy)
    if n == 0:
        return False
    n = _clip(qx, qy, n, -a, -b, -lo, px, py)
    if n == 0:
        return False
    for j in range(ND):
        s = _support(px, py, n, d[j, 0], d[j, 1])
        v = s + REL * abs(s) + ABS
        if v < u[j]:
            u[j] = v
    return True


@njit(cache=True)
def add_strip(u: np.ndarray, a: float, b: float, lo: float, hi: float) -> bool:
    """The template ``u`` cut by the strip ``lo <= a x + b y <= hi`` (in place, its
    support recomputed and widened outward); False if the cut is empty (``u`` kept)."""
    px = np.empty(CAP)
    py = np.empty(CAP)
    qx = np.empty(CAP)
    qy = np.empty(CAP)
    return _strip(u, DIRS, a, b, lo, hi, px, py, qx, qy)


@njit(cache=True)
def project(u: np.ndarray, a: float, b: float) -> tuple[float, float]:
    """(min, max) of ``a x + b y`` over the template polygon (empty: (inf, -inf))."""
    px = np.empty(CAP)
    py = np.empty(CAP)
    qx = np.empty(CAP)
    qy = np.empty(CAP)
    n = _polygon(u, DIRS, px, py, qx, qy)
    if n == 0:
        return np.inf, -np.inf
    hi = _support(px, py, n, a, b)
    lo = -_support(px, py, n, -a, -b)
    return lo - REL * abs(lo) - ABS, hi + REL * abs(hi) + ABS


@njit(cache=True)
def project_all(U: np.ndarray, psi: np.ndarray, hx: np.ndarray, hy: np.ndarray) -> None:
    """Per node ``k``: ``h_x = (cos psi, sin psi) . w``, ``h_y = (-sin psi, cos psi) . w``
    over its polygon, as (lo, hi) rows of ``hx``, ``hy`` (empty: inf, -inf)."""
    px = np.empty(CAP)
    py = np.empty(CAP)
    qx = np.empty(CAP)
    qy = np.empty(CAP)
    for k in range(U.shape[0]):
        c, s = math.cos(psi[k]), math.sin(psi[k])
        n = _polygon(U[k], DIRS, px, py, qx, qy)
        if n == 0:
            hx[k, 0], hx[k, 1], hy[k, 0], hy[k, 1] = np.inf, -np.inf, np.inf, -np.inf
            continue
        for row, (a, b) in ((0, (c, s)), (1, (-s, c))):
            hi = _support(px, py, n, a, b)
            lo = -_support(px, py, n, -a, -b)
            lo = lo - REL * abs(lo) - ABS
            hi = hi + REL * abs(hi) + ABS
            if row == 0:
                hx[k, 0], hx[k, 1] = lo, hi
            else:
                hy[k, 0], hy[k, 1] = lo, hi


@njit(cache=True)
def translate(u: np.ndarray, xlo: float, xhi: float, ylo: float, yhi: float,
              sign: float, out: np.ndarray) -> None:
    """``out`` = the template of ``u + sign [x] x [y]`` (the Minkowski sum's support)."""
    if sign < 0:
        xlo, xhi = -xhi, -xlo
        ylo, yhi = -yhi, -ylo
    for j in range(ND):
        dx = DIRS[j, 0]
        dy = DIRS[j, 1]
        s = max(dx * xlo, dx * xhi) + max(dy * ylo, dy * yhi)
        v = u[j] + s
        out[j] = v + REL * abs(v) + ABS


@njit(cache=True)
def nodes_chain(U: np.ndarray, sa: np.ndarray, sb: np.ndarray, slo: np.ndarray,
                shi: np.ndarray, snode: np.ndarray, D: np.ndarray, bad_w: np.ndarray,
                bad_n: np.ndarray) -> None:
    """Every node's template ``U[k]`` cut by its strips (``snode`` sorted; strip ``s``:
    ``slo <= sa x + sb y <= shi``; an empty cut marks ``bad_w[s]`` and is not made), then
    the chain forward and backward (``D[k]`` = x lo, x hi, y lo, y hi of ``w_k+1 -
    w_k``): ``U[k+1] &= U[k] + D[k]``, ``U[k] &= U[k+1] - D[k]``; an empty meet marks
    ``bad_n`` and keeps the node's own."""
    n = U.shape[0]
    px = np.empty(CAP)
    py = np.empty(CAP)
    qx = np.empty(CAP)
    qy = np.empty(CAP)
    for s in range(snode.size):
        k = snode[s]
        if not _strip(U[k], DIRS, sa[s], sb[s], slo[s], shi[s], px, py, qx, qy):
            bad_w[s] = True
    tmp = np.empty(ND)
    for direction in range(2):
        for step in range(n - 1):
            if direction == 0:
                src, dst, sgn, k = step, step + 1, 1.0, step
            else:
                src, dst, sgn, k = n - 1 - step, n - 2 - step, -1.0, n - 2 - step
            translate(U[src], D[k, 0], D[k, 1], D[k, 2], D[k, 3], sgn, tmp)
            tighter = False
            for j in range(ND):
                if tmp[j] < U[dst, j]:
                    tighter = True
                else:
                    tmp[j] = U[dst, j]
            if not tighter:
                continue
            if _polygon(tmp, DIRS, px, py, qx, qy) == 0:
                bad_n[dst] = True
                continue
            for j in range(ND):
                U[dst, j] = tmp[j]
