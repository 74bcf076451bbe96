"""Roll and pitch over the trip from the window strips, the prior and the chain
(docs/dynamic-method.md, section 3b, (3b.5)-(3b.7)).

* **Window strips** (3b.5): a window with node ``c`` gives ``mean_K h = M h_c + V +- E``
  (:func:`.kernels.window_terms`), so each of its accelerometer rows is a strip on the
  node's ``h_c``: accel_x's ``(C, S) . h_c in S_x - V_x -+ E'``, accel_y's ``(-S, C) .
  h_c in S_y - V_y -+ E'`` (``E' = E + 2 eps_M sin m``); in the yaw-compensated frame
  ``w_c = R(psi_c) h_c`` the strip's direction turns by ``psi_c``.
* **Prior strips**: ``h_x in sin(pitch prior)``, ``h_y in sin(roll prior) cos(pitch
  prior)`` at every node.
* **Chain** (3b.6): ``w_k+1 - w_k in R(psi_k+1) (v_k +- e_k)``
  (:func:`.kernels.link_terms`), forward and backward over the template polygons.
* **Pieces** (3b.7): over link ``k`` the node's ``h`` box turned by at most the link's
  measured turn, plus the hull of ``v`` there and the error, met with the next node's
  box widened the same way; roll and pitch from ``h``: ``theta = asin(h_x)``, ``phi =
  asin(h_y / cos(theta))``, met with the prior.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from imubounds.dynamic.estimator.attitude import kernels as K
from imubounds.dynamic.estimator.attitude.gravity import GravityWindows
from imubounds.dynamic.estimator.attitude.gyro_terms import (
    GyroTerms,
    error_coefficients,
    reflection_k,
)
from imubounds.interval import IntervalArray as IA
from imubounds.interval import atan2, cos, sin, sqr, sqrt


@dataclass
class AngleResult:
    """An angle's intervals at the epochs ``te`` (nodes) and over the links (pieces)."""

    nodes: IA
    pieces: IA
    used: int = 0


@dataclass
class HSolution:
    """The solution of one set of strips: roll and pitch, and the failed checks."""

    roll: AngleResult
    pitch: AngleResult
    bad_windows: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    bad_nodes: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))


@dataclass
class WindowTerms:
    """Unique windows (kernel rows, node) with ``M`` (C, S, eps) and ``V``, ``E``."""

    ker: np.ndarray
    node: np.ndarray
    out: np.ndarray
    #: per angle's window: the index of its unique window
    index: dict[str, np.ndarray]


def _asin(x: IA) -> IA:
    x = x & IA(np.full(x.shape, -1.0), np.full(x.shape, 1.0))
    return atan2(x, sqrt(1.0 - sqr(x)))


def window_terms(g: GyroTerms, te: np.ndarray, gw: dict[str, GravityWindows],
                 coef: np.ndarray, edge: Any) -> WindowTerms:
    """The walks of every distinct window of accel_x's and accel_y's plans."""
    rows, owner = [], {}
    for ax, w in gw.items():
        rows.append(np.concatenate([w.ker, w.node[:, None].astype(float)], 1))
        owner[ax] = w.n
    allrows = np.concatenate(rows) if rows else np.zeros((0, 6))
    uniq, inv = np.unique(allrows, axis=0, return_inverse=True)
    inv = np.asarray(inv).ravel()
    index, start = {}, 0
    for ax, n in owner.items():
        index[ax] = inv[start:start + n]
        start += n
    ker = np.ascontiguousarray(uniq[:, :5])
    node = uniq[:, 5].astype(np.int64)
    out = np.zeros((ker.shape[0], 6))
    if ker.shape[0]:
        tn = np.ascontiguousarray(te[node])
        ew = edge(tn) + np.maximum(edge(ker[:, 0]), edge(ker[:, 3]))
        tab = K.step_tables(g.bnd, g.y["gyro_z"])
        K.window_terms(g.bnd, tab, g.y["gyro_x"], g.y["gyro_y"], g.y["gyro_z"], g.unknown,
                       g.mag["gyro_x"], g.mag["gyro_y"], g.mag["gyro_z"], tn, ker, coef,
                       np.ascontiguousarray(ew), out)
    return WindowTerms(ker, node, out, index)


def _strips(wt: WindowTerms, gw: dict[str, GravityWindows], psi: np.ndarray, s_inf: float,
            use: tuple[str, ...]) -> tuple[np.ndarray, ...]:
    """Window strips in the yaw-compensated frame: (a, b, lo, hi, node, window id)."""
    parts = []
    for ax in use:
        w = gw[ax]
        if w.n == 0:
            continue
        u = wt.index[ax]
        C, S, Vx, Vy, E, eps = (wt.out[u, i] for i in range(6))
        e = np.nextafter((E + 2.0 * eps * s_inf) * (1 + 1e-9) + 1e-15, np.inf)
        if ax == "pitch":
            a_h, b_h, V = C, S, Vx
        else:
            a_h, b_h, V = -S, C, Vy
        ps = psi[w.node]
        cp, sp = np.cos(ps), np.sin(ps)
        # (a, b) . R(-psi) in w coordinates
        a = a_h * cp - b_h * sp
        b = a_h * sp + b_h * cp
        lo = w.S.lo - V - e
        hi = w.S.hi - V + e
        ok = np.isfinite(lo) & np.isfinite(hi)
        parts.append(np.stack([a[ok], b[ok], lo[ok], hi[ok], w.node[ok].astype(float),
                               np.flatnonzero(ok) + (0 if ax == "pitch" else 1_000_000_000)],
                              1))
    if not parts:
        return tuple(np.zeros(0) for _ in range(6))
    st = np.concatenate(parts)
    st = st[np.argsort(st[:, 4], kind="stable")]
    return tuple(np.ascontiguousarray(st[:, i]) for i in range(6))


def _prior_strips(psi: np.ndarray, roll: IA, pitch: IA) -> tuple[np.ndarray, ...]:
    """``h_x in sin(pitch)``, ``h_y in sin(roll) cos(pitch)`` at every node, as strips."""
    hx = sin(pitch)
    hy = sin(roll) * cos(pitch)
    cp, sp = np.cos(psi), np.sin(psi)
    n = psi.size
    idx = np.arange(n, dtype=float)
    a = np.concatenate([cp, -sp])
    b = np.concatenate([sp, cp])
    lo = np.concatenate([hx.lo, hy.lo])
    hi = np.concatenate([hx.hi, hy.hi])
    node = np.concatenate([idx, idx])
    return a, b, lo, hi, node, np.full(2 * n, -1.0)


def _chain_boxes(lt: np.ndarray, psi: np.ndarray) -> np.ndarray:
    """``w_k+1 - w_k in R(psi_k+1) (v_k +- e_k)``: box (x lo, x hi, y lo, y hi)."""
    c, s = np.cos(psi[1:]), np.sin(psi[1:])
    vx, vy, e = lt[:, 1], lt[:, 2], lt[:, 3]
    cx = c * vx - s * vy
    cy = s * vx + c * vy
    r = (np.abs(c) + np.abs(s)) * e
    r = np.nextafter(r * (1 + 1e-9) + 1e-12 * (1 + np.abs(vx) + np.abs(vy)), np.inf)
    return np.ascontiguousarray(np.stack([cx - r, cx + r, cy - r, cy + r], 1))


def solve(g: GyroTerms, te: np.ndarray, psi: np.ndarray, gw: dict[str, GravityWindows],
          wt: WindowTerms, lt: np.ndarray, prior: tuple[IA, IA, IA, IA], s_inf: float,
          use: tuple[str, ...]) -> HSolution:
    """Roll and pitch from the windows of the angles in ``use`` (see the module
    docstring); ``prior`` = (roll, pitch) at the nodes and over the links."""
    r_n, p_n, r_l, p_l = prior
    ws = _strips(wt, gw, psi, s_inf, use)
    ps = _prior_strips(psi, r_n, p_n)
    a, b, lo, hi, node, wid = (np.concatenate([x, y]) for x, y in zip(ps, ws, strict=True))
    order = np.argsort(node, kind="stable")
    a, b, lo, hi, node, wid = (np.ascontiguousarray(x[order]) for x in (a, b, lo, hi, node, wid))
    n = te.size
    U = np.full((n, K.ND), 2.0 * K.BIG)
    bad_w = np.zeros(a.size, bool)
    bad_n = np.zeros(n, bool)
    K.nodes_chain(U, a, b, lo, hi, node.astype(np.int64), _chain_boxes(lt, psi), bad_w, bad_n)
    hx = np.empty((n, 2))
    hy = np.empty((n, 2))
    K.project_all(U, np.ascontiguousarray(psi), hx, hy)
    HX, HY = IA(hx[:, 0], hx[:, 1]), IA(hy[:, 0], hy[:, 1])
    # over a link: turned by at most its measured turn, plus v's hull and the error
    mp = lt[:, 4]
    rot = np.sin(np.minimum(mp, math.pi)) * s_inf + (1.0 - np.cos(np.minimum(mp, math.pi))) * s_inf
    e = lt[:, 3]
    wx = IA(lt[:, 5] - rot - e, lt[:, 6] + rot + e)
    wy = IA(lt[:, 7] - rot - e, lt[:, 8] + rot + e)
    # from the next node: h(t) = h_k+1 - v_end + v(t) (+ the turn and the error twice)
    bx = IA(lt[:, 5] - lt[:, 1] - rot - 2 * e, lt[:, 6] - lt[:, 1] + rot + 2 * e)
    by = IA(lt[:, 7] - lt[:, 2] - rot - 2 * e, lt[:, 8] - lt[:, 2] + rot + 2 * e)
    px_ = (HX[:-1] + wx) & (HX[1:] + bx)
    py_ = (HY[:-1] + wy) & (HY[1:] + by)
    px_ = _fill(px_, HX[:-1] + wx)
    py_ = _fill(py_, HY[:-1] + wy)
    pitch_n = _meet(_asin(HX), p_n)
    roll_n = _meet(_asin(HY / cos(pitch_n)), r_n)
    pitch_l = _meet(_asin(px_), p_l)
    roll_l = _meet(_asin(py_ / cos(pitch_l)), r_l)
    bw = wid[bad_w]
    return HSolution(AngleResult(roll_n, roll_l, int(np.sum(ws[5] >= 1_000_000_000))),
                     AngleResult(pitch_n, pitch_l, int(np.sum(ws[5] < 1_000_000_000))),
                     bw[bw >= 0].astype(np.int64), bad_n)


def _fill(x: IA, alt: IA) -> IA:
    bad = ~(x.lo <= x.hi)
    return IA(np.where(bad, alt.lo, x.lo), np.where(bad, alt.hi, x.hi))


def _meet(x: IA, prior: IA) -> IA:
    lo, hi = np.maximum(x.lo, prior.lo), np.minimum(x.hi, prior.hi)
    ok = lo <= hi
    return IA(np.where(ok, lo, prior.lo), np.where(ok, hi, prior.hi))


def link_terms(g: GyroTerms, te: np.ndarray, coef: np.ndarray, edge: Any) -> np.ndarray:
    """:func:`.kernels.link_terms` of every link between the epochs."""
    out = np.zeros((max(te.size - 1, 0), 9))
    if te.size > 1:
        el = np.ascontiguousarray(edge(te[:-1]) + edge(te[1:]))
        K.link_terms(g.bnd, g.y["gyro_x"], g.y["gyro_y"], g.y["gyro_z"], g.unknown,
                     g.mag["gyro_x"], g.mag["gyro_y"], g.mag["gyro_z"],
                     np.ascontiguousarray(te), coef, el, out)
    return out


def coefficients(ctx: Any, g: GyroTerms, s_inf: float) -> np.ndarray:
    k_w, k_sg = reflection_k(ctx)
    return error_coefficients(g, math.sqrt(2.0) * s_inf, k_w, k_sg)
