"""What reads the attitude states (docs/dynamic-method.md, section 3b, "Consumers"):
the tilt functions of every channel's windows (one variant per channel, ``states.
VARIANT_OF``), the roll/pitch over any span for the smoother's links and epochs
(:class:`TiltBoxes`, through ``Aiding.tilt_range``), the window ends of gyro_x,
gyro_y and accel_z without an attitude stream (:func:`ends_provider`)."""

from __future__ import annotations

from typing import Any

import numpy as np

from imubounds.dynamic.estimator.aided.tilt import TiltSignals, signals_of
from imubounds.dynamic.estimator.attitude.states import VARIANT_OF, AttitudeStates
from imubounds.dynamic.estimator.window_plan import LevelPlan
from imubounds.interval import IntervalArray as IA


def _meet(a: IA, b: IA, use: np.ndarray) -> IA:
    lo = np.where(use, np.maximum(a.lo, b.lo), a.lo)
    hi = np.where(use, np.minimum(a.hi, b.hi), a.hi)
    ok = lo <= hi
    return IA(np.where(ok, lo, a.lo), np.where(ok, hi, a.hi))


def variant_signals(ctx: Any, st: AttitudeStates, rv: str, pv: str,
                    prior: TiltSignals) -> TiltSignals:
    """Roll (variant ``rv``) and pitch (``pv``) as tilt functions: on the union of the
    prior's pieces and the states' links, the prior's hull there (``Aiding.tilt_range``;
    without the pitch from GNSS altitude for ``prior_no_gnss``) met with the states'
    piece of the link."""
    ag, veh, te = ctx.aiding, ctx.vehicle, st.te
    b0, b1 = float(ctx.imu.bnd[0]), float(ctx.imu.bnd[-1])
    bnd = np.union1d(prior.bnd, te[(te > b0) & (te < b1)])
    s0, s1 = bnd[:-1], bnd[1:]
    saved = ag.pitch, getattr(ag, "tilt_boxes", None)
    ag.tilt_boxes = None
    if pv == "prior_no_gnss":
        ag.pitch = None
    try:
        if hasattr(ag, "_pitch_ext"):
            del ag._pitch_ext
        rl, rh, pl, ph = ag.tilt_range(s0, s1, veh)
    finally:
        ag.pitch, ag.tilt_boxes = saved
        if hasattr(ag, "_pitch_ext"):
            del ag._pitch_ext
    mid = 0.5 * (s0 + s1)
    k = np.searchsorted(te, mid) - 1
    inside = (k >= 0) & (k < te.size - 1)
    kk = np.clip(k, 0, max(te.size - 2, 0))
    roll = _meet(IA(rl, rh), st.roll[rv].pieces[kk], inside)
    pitch = _meet(IA(pl, ph), st.pitch[pv].pieces[kk], inside)
    return signals_of(bnd, roll, pitch)


class TiltBoxes:
    """The full variant's pieces on the links of ``te``: :meth:`narrow` meets a prior
    roll/pitch over spans ``[s0, s1]`` with the hull of the links the span touches."""

    def __init__(self, te: np.ndarray, roll: IA, pitch: IA) -> None:
        from imubounds.dynamic.estimator.inputs import RangeExt

        self.te = te
        self._r = RangeExt(roll.lo, roll.hi)
        self._p = RangeExt(pitch.lo, pitch.hi)

    def narrow(self, s0: np.ndarray, s1: np.ndarray, rl: Any, rh: Any, pl: Any,
               ph: Any) -> tuple[Any, ...]:
        te = self.te
        nl = te.size - 1
        i = np.searchsorted(te, s0, side="right") - 1
        j = np.searchsorted(te, s1, side="left") - 1
        inside = (i >= 0) & (np.maximum(j, i) < nl) & (s1 <= te[-1])
        ii = np.clip(i, 0, nl - 1)
        jj = np.clip(np.maximum(j, i), 0, nl - 1)
        out = []
        for (lo, hi), ext in (((rl, rh), self._r), ((pl, ph), self._p)):
            mn, mx = ext.query(ii, jj)
            a = IA(np.asarray(lo, float), np.asarray(hi, float))
            m = _meet(a, IA(mn, mx), inside)
            out += [m.lo, m.hi]
        return out[0], out[1], out[2], out[3]


def ends_provider(st: AttitudeStates, ch: str) -> Any:
    """The roll/pitch intervals at the two ends of each window (epoch indices ``lp.i``,
    ``lp.j`` into ``te``) of the variant channel ``ch`` reads."""
    r, p = st.pair(ch)

    def ends(lp: LevelPlan) -> tuple[IA, IA, IA, IA]:
        return r.nodes[lp.i], r.nodes[lp.j], p.nodes[lp.i], p.nodes[lp.j]

    return ends


def attach(ctx: Any, mb: Any, constraints: dict[str, Any]) -> AttitudeStates:
    """Build the states and hand them to their readers (see the module docstring)."""
    from imubounds.dynamic.estimator.attitude.states import build_states

    prior = ctx.tilt
    st = build_states(ctx, mb, constraints)
    kin: dict[tuple[str, int], IA] = {}
    for gw in st.windows.values():
        kin.update(gw.kin)
    mb.kin_cache = kin
    full = variant_signals(ctx, st, "full", "full", prior)
    ctx.tilt_for = {ch: variant_signals(ctx, st, *VARIANT_OF[ch], prior) for ch in VARIANT_OF}
    ctx.tilt = full
    mb.tilt = full
    ctx.aiding.tilt_boxes = TiltBoxes(st.te, st.roll["full"].pieces, st.pitch["full"].pieces)
    ctx.attitude = st
    if not ctx.aiding.has_attitude:
        ctx.ends_for = {ch: ends_provider(st, ch) for ch in ("gyro_x", "gyro_y", "accel_z")}
    return st
