"""Roll and pitch as interval states of mode full (docs/dynamic-method.md, section 3b).

:func:`build_states` evaluates every accelerometer window (:mod:`.gravity`), walks the
gyros from each window's node and over each link between the epochs
(:mod:`.kernels`), and solves the strips with the prior (the vehicle's max tilt, the
pitch from GNSS altitude, an attitude stream) and the chain (:mod:`.solve`) once per
*independence variant*: the margins of a channel read the variant built without that
channel's samples (:data:`VARIANT_OF`), the others and the smoother the full one.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from imubounds.dynamic.estimator.attitude import kernels as K
from imubounds.dynamic.estimator.attitude.gravity import GravityWindows, gravity_windows
from imubounds.dynamic.estimator.attitude.gyro_terms import GyroTerms, edge_error, gyro_terms
from imubounds.dynamic.estimator.attitude.solve import (
    AngleResult,
    HSolution,
    coefficients,
    link_terms,
    solve,
    window_terms,
)
from imubounds.interval import IntervalArray as IA

#: the (roll, pitch) variant each channel's margins read; the others read "full".
#: "nox": without accel_x's windows (accel_x measures g sin(pitch)); "noy": without
#: accel_y's; "prior": the max tilt, the pitch from GNSS altitude, an attitude stream
#: (gyro_x and gyro_y: every state walks both gyros); "prior_no_gnss": without the
#: pitch from GNSS altitude, which uses gyro_y
VARIANT_OF = {
    "accel_x": ("nox", "nox"),
    "accel_y": ("noy", "noy"),
    "gyro_x": ("prior", "prior"),
    "gyro_y": ("prior", "prior_no_gnss"),
}
#: the channels whose samples each variant uses (the notes and dynamic.json say so)
USES = {
    "full": ("accel_x", "accel_y", "gyro_x", "gyro_y", "gyro_z"),
    "nox": ("accel_y", "gyro_x", "gyro_y", "gyro_z"),
    "noy": ("accel_x", "gyro_x", "gyro_y", "gyro_z"),
    "prior": (),
    "prior_no_gnss": (),
}
#: the windows (angle of gravity.GravityWindows) each solved variant uses
SOLVED = {"full": ("pitch", "roll"), "nox": ("roll",), "noy": ("pitch",)}


@dataclass
class GyroWalk:
    """The gyro terms, gyro_z's step tables, the error coefficients, the largest sin(tilt)
    and the edge error: what :func:`.kernels.window_terms` needs for any window."""

    g: GyroTerms
    tab: np.ndarray
    coef: np.ndarray
    s_inf: float
    edge: Any


@dataclass
class AttitudeStates:
    """Node intervals at the epochs ``te`` and pieces on the links, per variant."""

    te: np.ndarray
    prior_roll: IA
    prior_pitch: IA
    roll: dict[str, AngleResult]
    pitch: dict[str, AngleResult]
    windows: dict[str, GravityWindows]
    empty: list[tuple[str, float, float]] = field(default_factory=list)
    chain_bad: dict[str, np.ndarray] = field(default_factory=dict)
    #: what walks the gyros from a node over a window (:mod:`.changes`)
    walk: Any = None

    def angle(self, axis: str, variant: str) -> AngleResult:
        return (self.roll if axis == "roll" else self.pitch)[variant]

    def pair(self, ch: str) -> tuple[AngleResult, AngleResult]:
        r, p = VARIANT_OF.get(ch, ("full", "full"))
        return self.roll[r], self.pitch[p]


def _prior(ctx: Any, te: np.ndarray, no_gnss: bool = False) -> tuple[IA, IA, IA, IA]:
    """Roll/pitch of the prior (``Aiding.tilt_range``) at the epochs and over the links."""
    ag, veh = ctx.aiding, ctx.vehicle
    saved = ag.pitch
    if no_gnss:
        ag.pitch = None
    if hasattr(ag, "_pitch_ext"):
        del ag._pitch_ext
    try:
        rl, rh, pl, ph = ag.tilt_range(te, te, veh)
        ql, qh, sl, sh = ag.tilt_range(te[:-1], te[1:], veh)
    finally:
        ag.pitch = saved
        if hasattr(ag, "_pitch_ext"):
            del ag._pitch_ext
    return IA(rl, rh), IA(pl, ph), IA(ql, qh), IA(sl, sh)


def build_states(ctx: Any, mb: Any, constraints: dict[str, Any]) -> AttitudeStates:
    """The attitude states of a run (see the module docstring). ``mb`` a margin builder
    with the prior tilt; ``constraints`` accel_x's and accel_y's true-signal constraints."""
    te = np.asarray(ctx.te, dtype=float)
    g: GyroTerms = gyro_terms(ctx)
    prior = _prior(ctx, te)
    _, pg_n, _, pg_l = _prior(ctx, te, no_gnss=True)
    m = float(max(np.max(np.abs(prior[0].lo)), np.max(np.abs(prior[0].hi)),
                  np.max(np.abs(prior[1].lo)), np.max(np.abs(prior[1].hi))))
    s_inf = math.sin(min(m, 0.5 * math.pi))
    coef = coefficients(ctx, g, s_inf)
    # a window longer than this cannot narrow the prior: its gyro bias term alone (a
    # quarter of the window on average from its node) exceeds the largest tilt
    tau_max = 4.0 * s_inf / max(float(min(coef[0], coef[8])), 1e-300)
    gw = {ax: gravity_windows(ctx, mb, ax, constraints[ch], tau_max)
          for ax, ch in (("pitch", "accel_x"), ("roll", "accel_y"))}

    def edge(t: np.ndarray) -> np.ndarray:
        return edge_error(ctx, t, math.sqrt(2.0) * s_inf)

    wt = window_terms(g, te, gw, coef, edge)
    lt = link_terms(g, te, coef, edge)
    psi = np.interp(te, g.bnd, g.C["gyro_z"])
    r_n, p_n, r_l, p_l = prior
    sols: dict[str, HSolution] = {}
    for v, use in SOLVED.items():
        if any(gw[ax].n for ax in use):
            sols[v] = solve(g, te, psi, gw, wt, lt, prior, s_inf, use)
        else:  # no window: the prior (the chain of its boxes narrows nothing)
            sols[v] = HSolution(AngleResult(r_n, r_l), AngleResult(p_n, p_l))
    st = AttitudeStates(
        te=te, prior_roll=r_l, prior_pitch=p_l,
        roll={**{v: s.roll for v, s in sols.items()}, "prior": AngleResult(r_n, r_l)},
        pitch={**{v: s.pitch for v, s in sols.items()}, "prior": AngleResult(p_n, p_l),
               "prior_no_gnss": AngleResult(pg_n, pg_l)},
        windows=gw,
        walk=GyroWalk(g, K.step_tables(g.bnd, g.y["gyro_z"]), coef, s_inf, edge),
    )
    full = sols["full"]
    for wid in np.unique(full.bad_windows):
        ax = "pitch" if wid < 1_000_000_000 else "roll"
        i = int(wid % 1_000_000_000)
        w = gw[ax]
        st.empty.append((ax, float(w.ker[i, 0]), float(w.ker[i, 3])))
    st.chain_bad["attitude"] = full.bad_nodes
    return st
