"""Plain-Python references of the attitude states' compiled loops
(``imubounds.dynamic.estimator.attitude.kernels``): the window walk, the link terms,
and the template polygons cut by strips and chained, the polygons' supports by linear
programming (scipy) instead of clipping."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from scipy.optimize import linprog

ND = 16
BIG = 2.0
DIRS = np.stack([np.cos(2 * np.pi * np.arange(ND) / ND), np.sin(2 * np.pi * np.arange(ND) / ND)], 1)


def cumk(x: float, a1: float, b1: float, a2: float, b2: float) -> float:
    l1, l2 = b1 - a1, b2 - a2
    out = 0.0
    r1 = min(max(x - a1, 0.0), l1)
    if l1 > 0:
        out += r1 * r1 / (2 * l1)
    out += min(max(x - b1, 0.0), a2 - b1)
    r2 = min(max(x - a2, 0.0), l2)
    out += r2 - r2 * r2 / (2 * l2) if l2 > 0 else r2
    return out


def step(v: np.ndarray, yr: float, g: np.ndarray, ln: float) -> np.ndarray:
    """Exact solution of ``v' = yr J v + g`` over ``ln`` (the matrix exponential)."""
    a = yr * ln
    rot = np.array([[math.cos(a), math.sin(a)], [-math.sin(a), math.cos(a)]])
    if abs(a) < 1e-4:
        b1, b2 = ln * (1 - a * a / 6), ln * (a / 2 - a**3 / 24)
    else:
        b1, b2 = math.sin(a) / yr, (1 - math.cos(a)) / yr
    return rot @ v + np.array([[b1, b2], [-b2, b1]]) @ g


def err(L: float, side: float, A: tuple[float, float, float], U: float, c: np.ndarray) -> float:
    b = c[0] * L
    if L >= c[9]:
        b = min(b, c[8] * L)
    return (b + c[1] * math.sqrt(side) + c[2] * A[0] + c[3] * A[1] + c[4] * A[2]
            + c[5] * math.sqrt(L) + c[6] + c[7] * U)


def walk(bnd: np.ndarray, yp: np.ndarray, yq: np.ndarray, yr: np.ndarray, unk: np.ndarray,
         mp: np.ndarray, mq: np.ndarray, mr: np.ndarray, t_node: float, t_end: float,
         forward: bool, ker: np.ndarray, side: float, c: np.ndarray, edge: float) -> np.ndarray:
    """The six sums of ``kernels._walk`` from ``t_node`` to ``t_end``."""
    a1, b1, a2, b2, tau = (float(x) for x in ker)
    acc = np.zeros(6)
    # the pieces: IMU segments cut at the node and the end
    lo, hi = (t_node, t_end) if forward else (t_end, t_node)
    edges = np.unique(np.concatenate([[lo, hi], bnd[(bnd > lo) & (bnd < hi)]]))
    pieces = list(zip(edges[:-1], edges[1:], strict=True))
    if not forward:
        pieces = pieces[::-1]
    v = np.zeros(2)
    dpsi = 0.0
    A = np.zeros(3)
    U = 0.0
    for s0, s1 in pieces:
        ln = s1 - s0
        k = min(max(int(np.searchsorted(bnd, 0.5 * (s0 + s1))) - 1, 0), bnd.size - 2)
        g = np.array([-yq[k], yp[k]])
        w = (cumk(s1, a1, b1, a2, b2) - cumk(s0, a1, b1, a2, b2)) / tau
        L = (s1 - t_node) if forward else (t_node - s0)
        A += np.array([mq[k], mp[k], mr[k]]) * ln
        U += ln if unk[k] else 0.0
        e = err(L, side, (A[0], A[1], A[2]), U, c) + edge
        gn = abs(g[0]) + abs(g[1]) + (mq[k] + mp[k] if unk[k] else 0.0)
        ev = (abs(yr[k]) * (abs(v[0]) + abs(v[1])) * 2 + gn) * ln
        acc += w * np.array([math.cos(dpsi), math.sin(dpsi), v[0], v[1], e + ev,
                             (abs(yr[k]) + (mr[k] if unk[k] else 0.0)) * ln])
        if forward:
            v = step(v, yr[k], g, ln)
            dpsi += yr[k] * ln
        else:
            v = step(v, yr[k], g, -ln)
            dpsi -= yr[k] * ln
    return acc


def support_lp(strips: list[tuple[float, float, float, float]], d: np.ndarray) -> float:
    """max d . w over the box [-BIG, BIG]^2 cut by the strips (a, b, lo, hi); -inf if
    empty."""
    A, bb = [], []
    for a, b, lo, hi in strips:
        if math.isfinite(hi):
            A.append([a, b])
            bb.append(hi)
        if math.isfinite(lo):
            A.append([-a, -b])
            bb.append(-lo)
    res = linprog(-np.asarray(d), A_ub=np.asarray(A) if A else None,
                  b_ub=np.asarray(bb) if bb else None, bounds=[(-BIG, BIG)] * 2,
                  method="highs")
    if res.status == 2:
        return -math.inf
    return float(-res.fun)


def template_strips(u: np.ndarray) -> list[tuple[float, float, float, float]]:
    return [(float(DIRS[j, 0]), float(DIRS[j, 1]), -math.inf, float(u[j])) for j in range(ND)]


def nodes_chain(U: np.ndarray, strips: list[list[tuple[float, float, float, float]]],
                D: np.ndarray) -> np.ndarray:
    """The chain of ``kernels.nodes_chain`` with each template's cut by strips taken
    exactly (the LP support in every template direction), no outward widening."""
    U = U.copy()
    n = U.shape[0]
    for k in range(n):
        for s in strips[k]:
            cons = template_strips(U[k]) + [s]
            sup = np.array([support_lp(cons, DIRS[j]) for j in range(ND)])
            if np.all(np.isfinite(sup)):
                U[k] = np.minimum(U[k], sup)
    for direction in (0, 1):
        order = range(n - 1) if direction == 0 else range(n - 2, -1, -1)
        for k in order:
            src, dst, sg = (k, k + 1, 1.0) if direction == 0 else (k + 1, k, -1.0)
            xlo, xhi, ylo, yhi = D[k]
            if sg < 0:
                xlo, xhi, ylo, yhi = -xhi, -xlo, -yhi, -ylo
            t = U[src] + np.maximum(DIRS[:, 0] * xlo, DIRS[:, 0] * xhi) + np.maximum(
                DIRS[:, 1] * ylo, DIRS[:, 1] * yhi)
            t = np.minimum(t, U[dst])
            if support_lp(template_strips(t), DIRS[0]) > -math.inf:
                U[dst] = t
    return U


def true_mean_h(bnd: np.ndarray, yp: np.ndarray, yq: np.ndarray, yr: np.ndarray,
                h0: np.ndarray, t_node: float, ker: np.ndarray, sub: int = 40) -> Any:
    """``mean_K h`` of the exact trajectory of ``h' = r J h + (-q, p)`` through ``h0`` at
    ``t_node`` (the rates constant on each segment), by fine quadrature."""
    a1, b1, a2, b2, tau = (float(x) for x in ker)
    edges = np.unique(np.concatenate([[a1, b2, t_node], bnd[(bnd > a1) & (bnd < b2)]]))
    total = np.zeros(2)
    for side in (1, -1):
        h = h0.copy()
        pieces = [(s0, s1) for s0, s1 in zip(edges[:-1], edges[1:], strict=True)
                  if (s0 >= t_node if side > 0 else s1 <= t_node)]
        if side < 0:
            pieces = pieces[::-1]
        for s0, s1 in pieces:
            k = min(max(int(np.searchsorted(bnd, 0.5 * (s0 + s1))) - 1, 0), bnd.size - 2)
            g = np.array([-yq[k], yp[k]])
            ln = (s1 - s0) / sub
            for i in range(sub):
                # the mean over the sub-piece by Simpson's rule on the exact flow
                t_a = s0 + i * ln if side > 0 else s1 - i * ln
                h_a = h
                h_m = step(h, yr[k], g, side * ln / 2)
                h_b = step(h, yr[k], g, side * ln)
                lo_t, hi_t = (t_a, t_a + ln) if side > 0 else (t_a - ln, t_a)
                w = (cumk(hi_t, a1, b1, a2, b2) - cumk(lo_t, a1, b1, a2, b2)) / tau
                total += w * (h_a + 4 * h_m + h_b) / 6
                h = h_b
    return total
