"""A readable pure-Python reference of the single-pass estimator (for tests).

Written directly from METHOD.md 3.2-3.3 with a small interval class whose
operators call the same scalar rules as the compiled loop, so the two must
agree bit for bit. It is slow (about 10^4 steps/s) and only covers a single
forward-backward pass per step (``passes == 1``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from imubounds.dynamic.estimator import _rules as R
from imubounds.dynamic.estimator.paper_kernel import (
    F_AX_EMPTY,
    F_AY_EMPTY,
    F_GPS_EMPTY,
    F_GPS_MISSING,
    F_HEAD_EMPTY,
    F_HEAD_MISSING,
    F_R_EMPTY,
    F_U_EMPTY,
    F_V_EMPTY,
    heading_interval,
)


@dataclass(frozen=True)
class Iv:
    """A closed interval [lo, hi]; empty is (+inf, -inf)."""

    lo: float
    hi: float

    @staticmethod
    def pt(x: float) -> Iv:
        return Iv(x, x)

    def empty(self) -> bool:
        return not (self.lo <= self.hi)

    def __add__(self, o: Iv) -> Iv:
        return Iv(*R.add(self.lo, self.hi, o.lo, o.hi))

    def __sub__(self, o: Iv) -> Iv:
        return Iv(*R.sub(self.lo, self.hi, o.lo, o.hi))

    def __mul__(self, o: Iv) -> Iv:
        return Iv(*R.mul(self.lo, self.hi, o.lo, o.hi))

    def __truediv__(self, o: Iv) -> Iv:
        return Iv(*R.div(self.lo, self.hi, o.lo, o.hi))

    def __and__(self, o: Iv) -> Iv:
        return Iv(*R.inter(self.lo, self.hi, o.lo, o.hi))


def icos(x: Iv) -> Iv:
    return Iv(*R.cos(x.lo, x.hi))


def isin(x: Iv) -> Iv:
    return Iv(*R.sin(x.lo, x.hi))


def run_reference(
    S0: np.ndarray,
    M: np.ndarray,
    G: np.ndarray,
    C: np.ndarray,
    dt: float,
    ep: float = 0.0,
    ev: float = 0.0,
    mode: str = "full",
    veldiff: str = "contracted",
    fallback: str = "reset",
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Single-pass estimator; returns (S, D, A, flags) like the compiled kernel."""
    n = M.shape[0]
    S = np.empty((n, 10))
    S[0] = S0
    P = np.empty((n, 10))
    P[0] = S0
    D = M.copy()
    A = np.full((n, 6), np.nan)
    flags = np.zeros(n, dtype=np.int64)
    T = Iv.pt(dt)
    Ep, Ev = Iv(-ep, ep), Iv(-ev, ev)

    def st(k: int, i: int, arr: np.ndarray = S) -> Iv:
        return Iv(arr[k, 2 * i], arr[k, 2 * i + 1])

    for k in range(1, n):
        x, y, u, v, psi = (st(k - 1, i) for i in range(5))
        a, b, r = (Iv(M[k, 2 * i], M[k, 2 * i + 1]) for i in range(3))
        # forward (METHOD.md 3.2): the t+1 values on the right
        if mode == "paper":
            u_p = u + (a * T + Ev)
            v_p = v + (b * T + Ev)
        else:
            u_p = u + ((a + r * v) * T + Ev)
            v_p = v + ((b - r * u) * T + Ev)
        psi_p = psi + r * T
        c, s = icos(psi_p), isin(psi_p)
        x_p = (x + (u_p * c - v_p * s) * T) + Ep
        y_p = (y + (v_p * c + u_p * s) * T) + Ep
        P[k] = [x_p.lo, x_p.hi, y_p.lo, y_p.hi, u_p.lo, u_p.hi, v_p.lo, v_p.hi, psi_p.lo, psi_p.hi]
        # contraction (METHOD.md 3.3)
        if math.isnan(G[k, 0]):
            flags[k] |= F_GPS_MISSING
            x_h, y_h = x_p, y_p
        else:
            gx, gy = Iv(G[k, 0], G[k, 1]), Iv(G[k, 2], G[k, 3])
            x_h, y_h = x_p & gx, y_p & gy
            if x_h.empty() or y_h.empty():
                flags[k] |= F_GPS_EMPTY
                x_h, y_h = (x_p, y_p) if fallback == "keep" else (gx, gy)
        if math.isnan(C[k, 0]):
            flags[k] |= F_HEAD_MISSING
            psi_h = psi_p
        else:
            ref = 0.5 * (psi_p.lo + psi_p.hi)
            if not (math.isfinite(psi_p.lo) and math.isfinite(psi_p.hi)):
                ref = psi.lo
            if not math.isfinite(ref):
                ref = C[k, 0]
            comp = Iv(*heading_interval(C[k, 0], C[k, 1], ref))
            psi_h = psi_p & comp
            if psi_h.empty():
                flags[k] |= F_HEAD_EMPTY
                psi_h = psi_p if fallback == "keep" else comp
        # backward: nav velocity, then body velocity R(-psi)
        ox, oy = (st(k - 1, 0, P), st(k - 1, 1, P)) if veldiff == "ins" else (x, y)
        xd = ((x_h - ox) - Ep) / T
        yd = ((y_h - oy) - Ep) / T
        c, s = icos(psi_h), isin(psi_h)
        U = c * xd + s * yd
        V = c * yd - s * xd
        u_h = u_p & U
        if u_h.empty():
            flags[k] |= F_U_EMPTY
            u_h = u_p
        v_h = v_p & V
        if v_h.empty():
            flags[k] |= F_V_EMPTY
            v_h = v_p
        S[k] = [x_h.lo, x_h.hi, y_h.lo, y_h.hi, u_h.lo, u_h.hi, v_h.lo, v_h.hi, psi_h.lo, psi_h.hi]
        r_aid = (psi_h - psi) / T
        r_h = r & r_aid
        if not r_h.empty():
            D[k, 4], D[k, 5] = r_h.lo, r_h.hi
    # aided projections from the final states, then the estimates
    for k in range(1, n):
        u0, u1 = st(k - 1, 2), st(k, 2)
        v0, v1 = st(k - 1, 3), st(k, 3)
        r_d = Iv(D[k, 4], D[k, 5])
        R_a = (st(k, 4) - st(k - 1, 4)) / T
        A_a = ((u1 - u0) - Ev) / T
        B_a = ((v1 - v0) - Ev) / T
        if mode == "full":
            A_a = A_a - r_d * v0
            B_a = B_a + r_d * u0
        A[k] = [A_a.lo, A_a.hi, B_a.lo, B_a.hi, R_a.lo, R_a.hi]
        for i, (aid, bit) in enumerate(((A_a, F_AX_EMPTY), (B_a, F_AY_EMPTY), (R_a, F_R_EMPTY))):
            e = Iv(D[k, 2 * i], D[k, 2 * i + 1]) & aid
            if e.empty():
                flags[k] |= bit
            else:
                D[k, 2 * i], D[k, 2 * i + 1] = e.lo, e.hi
    return S, D, A, flags
