"""The change of an accelerometer's true mean between adjacent windows with the tilt
change from the gyros (docs/dynamic-method.md, section 3b, "Changes", (3b.9)).

The change test of section 4 judges ``[E_W2] - [E_W1]`` against the change band (the
turn-on bias cancels). Taken window by window, each ``[E_W]`` holds the whole tilt
uncertainty ``g delta`` of its window, so a bias step smaller than ``2 g delta`` passes
unseen -- and moves the attitude states, which read the accelerometer's windows, with it.
The tilt *change* between the two windows is known far better: from their common
boundary ``b`` (an epoch) the gyros carry ``h`` to every time of both windows (3b.3),

    mean_K2 h - mean_K1 h in (M_2 - M_1) h_b + (V_2 - V_1) +- (E'_1 + E'_2),

with ``h_b`` in the node of the channel's own variant (built without its samples: accel_x
reads pitch and roll without accel_x's windows), so

    [x_W2 - x_W1] = ([k_W2] - [k_W1]) + [g] (row of the difference above)        (3b.9)

(``k`` the kinematic parts of the margins, ``[g] = [G_LO, G_HI]``). The change of the
channel's error is then ``[y_W2 - y_W1] - [x_W2 - x_W1]``, intersected with the
window-by-window difference (both enclose it). On a straight span ``M_2 - M_1`` is
near 0 and the interval is the velocity ends' ``4R/tau`` plus the transport terms. On the
hilly GNSS-only industrial trip a 0.6 m/s^2 accel_x step is judged `exceeds`; a 0.3 m/s^2
one is not (the joint change at the step is +-0.37 m/s^2 at tau = 10 s, 0.22 of it the
velocity ends; docs section 4, "Which channel").
"""

from __future__ import annotations

from typing import Any

import numpy as np

from imubounds.constants import G_HI, G_LO
from imubounds.dynamic.estimator.attitude import kernels as K
from imubounds.dynamic.estimator.window_plan import LevelPlan
from imubounds.interval import IntervalArray as IA
from imubounds.interval import cos, sin

#: the accelerometers with a change from the gyros, and the row of h they measure
ROW = {"accel_x": 0, "accel_y": 1}
#: pairs are used at levels of at least this many aiding periods (below, the velocity
#: ends' 4R/tau exceed what the joint tilt saves), thinned to boundaries at least half a
#: window apart: at most about one pair per epoch and channel over the levels, each
#: counted as one window of the states (``EVENTS_PER_WINDOW``: both walks start at the
#: common boundary, one to each side; attitude.interval_events)
MIN_PERIODS = 4.0


def _thin(b: np.ndarray, tau_s: float) -> np.ndarray:
    """Indices of boundaries ``b`` (sorted) at least ``tau_s / 2`` apart (greedy)."""
    keep, last = [], -np.inf
    for i in np.argsort(b, kind="stable"):
        if b[i] - last >= 0.5 * tau_s * (1 - 1e-9):
            keep.append(i)
            last = b[i]
    return np.asarray(keep, dtype=np.int64)


def pair_change(w: Any, ch: str, lp: LevelPlan, tau: np.ndarray, kin: IA) -> IA | None:
    """``[x_W2 - x_W1]`` over the level's adjacent pairs ``(lp.p1, lp.p2)`` by (3b.9), or
    None (no attitude states, not an accelerometer with a gyro walk, no pairs)."""
    ctx = w.ctx
    st = getattr(ctx, "attitude", None)
    walk = getattr(st, "walk", None)
    if st is None or walk is None or ch not in ROW or lp.n_pairs == 0 or lp.kind != "aided":
        return None
    plan = ctx.plans.get(ch)
    ep = plan.epochs if plan is not None else np.zeros(0)
    gap = float(np.median(np.diff(ep))) if ep.size > 1 else np.inf
    if not lp.tau_s >= MIN_PERIODS * gap * (1 - 1e-9):
        return None
    p1, p2 = lp.p1, lp.p2
    te = st.te
    b = lp.b2[p1]  # W1 ends where W2 starts (window_plan.LevelPlan)
    kb = np.searchsorted(te, b)
    on = (kb < te.size) & (np.abs(te[np.minimum(kb, te.size - 1)] - b) <= 1e-9 * (1 + abs(b)))
    on &= np.abs(lp.a1[p2] - b) <= 1e-9 * (1 + np.abs(b))
    out_lo = np.full(p1.size, -np.inf)
    out_hi = np.full(p1.size, np.inf)
    sel = np.flatnonzero(on)
    sel = sel[_thin(b[sel], lp.tau_s)] if sel.size else sel
    if sel.size == 0:
        return None
    kb = np.minimum(kb[sel], te.size - 1)
    tn = te[kb]
    rows = []
    for p in (p1[sel], p2[sel]):
        rows.append(np.stack([lp.a1[p], lp.b1[p], lp.a2[p], lp.b2[p], tau[p]], -1))
    ker = np.ascontiguousarray(np.concatenate(rows))
    tn2 = np.ascontiguousarray(np.concatenate([tn, tn]))
    res = np.zeros((ker.shape[0], 6))
    ew = walk.edge(tn2) + np.maximum(walk.edge(ker[:, 0]), walk.edge(ker[:, 3]))
    g = walk.g
    K.window_terms(g.bnd, walk.tab, g.y["gyro_x"], g.y["gyro_y"], g.y["gyro_z"], g.unknown,
                   g.mag["gyro_x"], g.mag["gyro_y"], g.mag["gyro_z"], tn2, ker, walk.coef,
                   np.ascontiguousarray(ew), res)
    n = sel.size
    C, S, Vx, Vy, E, eps = (res[:, i] for i in range(6))
    e = np.nextafter((E + 2.0 * eps * walk.s_inf) * (1 + 1e-9) + 1e-15, np.inf)
    dC, dS = C[n:] - C[:n], S[n:] - S[:n]
    # h at the boundary from the channel's own variant (without its samples)
    roll, pitch = st.pair(ch)
    pn, rn = pitch.nodes[kb], roll.nodes[kb]
    hx = sin(pn)
    hy = sin(rn) * cos(pn)
    if ROW[ch] == 0:  # (C, S) . h_b + V_x
        d = IA(dC) * hx + IA(dS) * hy + IA(Vx[n:] - Vx[:n])
    else:  # (-S, C) . h_b + V_y
        d = IA(-dS) * hx + IA(dC) * hy + IA(Vy[n:] - Vy[:n])
    rad = np.nextafter((e[:n] + e[n:]) * (1 + 1e-9) + 1e-12 * (1 + np.abs(dC) + np.abs(dS)),
                       np.inf)
    d = d + IA(-rad, rad)
    dx = (kin[p2[sel]] - kin[p1[sel]]) + IA(G_LO, G_HI) * d
    ok = np.isfinite(dx.lo) & np.isfinite(dx.hi)
    out_lo[sel] = np.where(ok, dx.lo, -np.inf)
    out_hi[sel] = np.where(ok, dx.hi, np.inf)
    return IA(out_lo, out_hi)
