"""Roll and pitch over the trip as piecewise-constant interval functions, and the
functions of them the windows need (docs/dynamic-method.md, section 3: gravity and the
tilt terms of every constraint)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from imubounds.constants import G_HI, G_LO
from imubounds.dynamic.estimator.inputs import Locator, PiecewiseSignal, RangeExt
from imubounds.dynamic.estimator.window_plan import LevelPlan
from imubounds.interval import IntervalArray as IA
from imubounds.interval import cos, sin


@dataclass
class TiltSignals:
    """Piecewise-constant interval functions of roll and pitch over the trip."""

    bnd: np.ndarray
    roll: IA
    pitch: IA
    sig: dict[str, tuple[Any, Any]] = field(default_factory=dict)
    ext: dict[str, RangeExt] = field(default_factory=dict)
    funcs: dict[str, Any] = field(default_factory=dict)

    def add(self, name: str, val: IA) -> None:
        lo = np.where(np.isfinite(val.lo), val.lo, -1e300)
        hi = np.where(np.isfinite(val.hi), val.hi, 1e300)
        if not hasattr(self, "_loc"):
            self._loc = Locator(self.bnd)
        self.sig[name] = (
            PiecewiseSignal(self.bnd, lo, locator=self._loc),
            PiecewiseSignal(self.bnd, hi, locator=self._loc),
        )
        self.ext[name] = RangeExt(lo, hi)

    def _get(self, name: str) -> tuple[Any, Any]:
        if name not in self.sig:
            self.add(name, self.funcs[name]())
        return self.sig[name]

    def kmean(self, name: str, lp: LevelPlan, tau: np.ndarray) -> IA:
        lo_s, hi_s = self._get(name)
        lo = lo_s.kernel_mean(lp.a1, lp.b1, lp.a2, lp.b2, tau).lo
        hi = hi_s.kernel_mean(lp.a1, lp.b1, lp.a2, lp.b2, tau).hi
        return IA(lo, hi)

    def hull(self, name: str, a: np.ndarray, b: np.ndarray) -> IA:
        lo_s, _ = self._get(name)
        i, j = lo_s.locate(a), lo_s.locate(b)
        mn, mx = self.ext[name].query(i, j)
        return IA(mn, mx)


def build_tilt(ctx: Any) -> TiltSignals:
    """Roll/pitch interval functions on a grid covering the IMU span, and the derived
    functions the windows need (sin/cos products)."""
    ag, veh = ctx.aiding, ctx.vehicle
    b0, b1 = float(ctx.imu.bnd[0]), float(ctx.imu.bnd[-1])
    if ag.has_attitude:
        at = ag.att_t
        inner = at[(at > b0) & (at < b1)]
        bnd = np.concatenate([[b0], inner, [b1]])
        rl, rh, pl, ph = ag.tilt_range(bnd[:-1], bnd[1:], veh)
    elif ag.pitch is not None:
        # pitch from GNSS altitude (pitch_gnss.py): its pieces; roll +-max tilt
        bnd = ag.pitch.bnd
        rl, rh, pl, ph = ag.tilt_range(bnd[:-1], bnd[1:], veh)
    else:
        bnd = np.array([b0, b1])
        m = veh.max_tilt
        rl, rh, pl, ph = (np.array([x]) for x in (-m, m, -m, m))
    roll, pitch = IA(rl, rh), IA(pl, ph)
    ts = TiltSignals(bnd, roll, pitch)
    g = IA(G_LO, G_HI)
    sr, cr, sp, cp = sin(roll), cos(roll), sin(pitch), cos(pitch)
    ts.funcs = {
        "g_sinp": lambda: g * sp,
        "g_sinr_cosp": lambda: g * sr * cp,
        "g_cosr_cosp": lambda: g * cr * cp,
        "cosp_over_cosr": lambda: cp / cr,
        "abs_tanr": lambda: abs(sr / cr),
        "abs_sinr": lambda: abs(sr),
        "abs_sinp": lambda: abs(sp),
        "sinp": lambda: sp,
        "sinr_cosp": lambda: sr * cp,
        "cosr": lambda: cr,
        "sec_p_minus_1": lambda: 1.0 / cp - 1.0,
        "sec_r_minus_1": lambda: 1.0 / cr - 1.0,
        "abs_tanr_tanp": lambda: abs(sr * sp / (cr * cp)),
        "abs_tanp": lambda: abs(sp / cp),
    }
    return ts
