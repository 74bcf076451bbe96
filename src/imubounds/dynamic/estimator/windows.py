"""Window-mean margins per averaging time, and the verdicts (docs/dynamic-method.md,
sections 3 and 4).

For a window ``W`` with kernel ``K_W`` (``>= 0``, integral 1) the guaranteed interval of
the kernel-weighted mean of the IMU error of channel ``c`` is::

    [E_W] = [y_W] - [x_W]

``[y_W]``: the same kernel applied to the samples (rigorous float sums);
``[x_W]``: the kernel mean of the TRUE signal, built from the aiding sensors and the
vehicle bounds only (never from channel ``c``), by the constraint of the channel: one
module of :mod:`imubounds.dynamic.estimator.aided` each (:data:`CONSTRAINTS`). The
windows are planned in :mod:`~imubounds.dynamic.estimator.window_plan`, the stationary
band is :mod:`~imubounds.dynamic.estimator.band`, the verdicts
:mod:`~imubounds.dynamic.estimator.verdicts`.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from imubounds.dynamic.estimator.aided.accel_x import accel_x
from imubounds.dynamic.estimator.aided.accel_y import accel_y
from imubounds.dynamic.estimator.aided.attitude import accel_z, gyro_x, gyro_y
from imubounds.dynamic.estimator.aided.common import WindowContext
from imubounds.dynamic.estimator.aided.forms import FormRecord, side_labels
from imubounds.dynamic.estimator.aided.tilt import TiltSignals, build_tilt
from imubounds.dynamic.estimator.aided.vehicle import GRAVITY_OF, vehicle_only
from imubounds.dynamic.estimator.aided.velocity import body_velocity
from imubounds.dynamic.estimator.aided.yaw import gyro_z
from imubounds.dynamic.estimator.attitude.changes import pair_change
from imubounds.dynamic.estimator.band import change_band, level_band
from imubounds.dynamic.estimator.budget import UNITS, k_two_sided
from imubounds.dynamic.estimator.vehicle_bounds import (
    dominant_default,
    dominant_transport,
    heave_note,
)
from imubounds.dynamic.estimator.verdicts import (
    HOW_TO_REFERENCE,
    NO_REFERENCE,
    ChannelMargins,
    LevelResult,
    band_reference,
    fragility,
    verdict_of,
)
from imubounds.dynamic.estimator.window_plan import ChannelPlan, LevelPlan, plan_channel, tau_grid
from imubounds.interval import IntervalArray as IA

Constraint = Callable[[WindowContext, ChannelPlan, LevelPlan, np.ndarray], IA]

#: the true-signal constraint of each channel at the levels at or above its aiding period
CONSTRAINTS: dict[str, Constraint] = {
    "accel_x": accel_x,
    "accel_y": accel_y,
    "accel_z": accel_z,
    "gyro_x": gyro_x,
    "gyro_y": gyro_y,
    "gyro_z": gyro_z,
}

#: the term whose forms name each window's bound (margins.csv ``bound_by``), per channel
#: (the others have one form: ``AIDED``)
BOUND_TERM = {
    "accel_x": "accel_x.mean_abs_r",
    "accel_y": "accel_y.transport",
    "gyro_z": "gyro_z.mean_abs_q",
}
#: ``bound_by`` of an end from the vehicle-only enclosure, and of a channel's one form
VEHICLE, AIDED = "vehicle", "aided"


def bound_labels(
    forms: FormRecord, ch: str, n: int, veh_lo: np.ndarray, veh_hi: np.ndarray
) -> np.ndarray:
    """Per window the forms giving its two ends (:func:`~.aided.forms.side_labels`): those
    of the channel's :data:`BOUND_TERM`, ``VEHICLE`` where the vehicle-only enclosure was
    narrower on that side."""
    lo, hi = forms.sides(BOUND_TERM.get(ch, ""))
    if lo.size != n:
        lo, hi = np.full(n, AIDED, dtype=object), np.full(n, AIDED, dtype=object)
    lo = np.where(veh_lo, VEHICLE, lo)
    hi = np.where(veh_hi, VEHICLE, hi)
    return side_labels(lo, hi)


__all__ = [
    "CONSTRAINTS",
    "ChannelMargins",
    "ChannelPlan",
    "MarginBuilder",
    "TiltSignals",
    "build_tilt",
    "plan_channel",
    "tau_grid",
]


class MarginBuilder(WindowContext):
    """Evaluates the windows of every channel (see the module docstring)."""

    bound_by: np.ndarray = np.zeros(0, dtype=object)

    def body_velocity(self) -> Any:
        """Body velocity at the velocity epochs (:func:`~imubounds.dynamic.estimator.aided.
        velocity.body_velocity`)."""
        return body_velocity(self)

    def aided(self, ch: str, plan: ChannelPlan, lp: LevelPlan, tau: np.ndarray) -> IA:
        """``[x_W]`` of the level's windows; which forms gave each window's ends in
        ``self.bound_by`` (:func:`bound_labels`)."""
        self.forms.clear()
        veh = vehicle_only(self, ch, lp, tau)
        if lp.kind == "vehicle":
            self.bound_by = np.full(lp.n, VEHICLE, dtype=object)
            return veh
        # both enclose the same kernel mean: the tighter of the two at every window (the
        # aided one where they contradict each other)
        kin = self.kin_cache.get((ch, id(lp)))
        own = getattr(plan, "constraint", None)  # a plan with its own constraint
        if kin is not None:  # accel_x, accel_y: the kinematic part of the attitude pass
            x = kin + self.tilt.kmean(GRAVITY_OF[ch], lp, tau)
        elif own is not None:
            x = own(self, lp, tau)
        else:
            x = CONSTRAINTS[ch](self, plan, lp, tau)
        lo, hi = np.maximum(x.lo, veh.lo), np.minimum(x.hi, veh.hi)
        ok = lo <= hi
        self.bound_by = bound_labels(self.forms, ch, lp.n, ok & (veh.lo > x.lo),
                                     ok & (veh.hi < x.hi))
        return IA(np.where(ok, lo, x.lo), np.where(ok, hi, x.hi))

    def evaluate(self, plan: ChannelPlan) -> ChannelMargins:
        """Every level of a channel: ``[x_W]``, ``[y_W]``, the bands; then the verdict
        (with the tilt functions and window ends of the channel's attitude variant)."""
        saved = self.tilt, self.ends
        self.tilt = getattr(self.ctx, "tilt_for", {}).get(plan.channel, self.ctx.tilt)
        self.ends = getattr(self.ctx, "ends_for", {}).get(plan.channel)
        try:
            return self._evaluate(plan)
        finally:
            self.tilt, self.ends = saved

    def _evaluate(self, plan: ChannelPlan) -> ChannelMargins:
        ch = plan.channel
        levels: list[LevelResult] = []
        fam = "imu_windows"
        for li, lp in enumerate(plan.levels):
            if lp.n == 0:
                continue
            tau = lp.tau
            gi = self.ctx.level_index[(ch, li)]
            k = self.ctx.alpha.k_level(fam, gi)
            self.p_window = self.ctx.alpha.p_level(fam, gi)
            if ch == "gyro_z" and lp.kind == "aided":
                # the window's probability is shared by the band and gyro_y's window
                # bound of the tilt coupling (aided.yaw.gyro_z)
                k = k_two_sided(self.p_window, 2)
            x = self.aided(ch, plan, lp, tau)
            y = self.imu_mean(ch, lp, tau)
            band, band_nto = level_band(self, ch, lp, tau, k)
            xl = np.where(np.isfinite(x.lo), x.lo, -np.inf)
            xh = np.where(np.isfinite(x.hi), x.hi, np.inf)
            c_band = np.zeros(0)
            c_k = 0.0
            dx = None
            if lp.n_pairs and lp.kind == "aided":
                gc = self.ctx.level_index_changes[(ch, li)]
                c_k = self.ctx.alpha.k_level("imu_changes", gc)
                c_band = change_band(self, ch, lp, tau, c_k)
                kin = self.kin_cache.get((ch, id(lp)))
                if kin is not None:  # the tilt change from the gyros (attitude/changes.py)
                    dx = pair_change(self, ch, lp, tau, kin)
            levels.append(
                LevelResult(
                    tau_s=lp.tau_s,
                    kind=lp.kind,
                    t_start=lp.a1,
                    tau=tau,
                    x_lo=xl,
                    x_hi=xh,
                    y_lo=y.lo,
                    y_hi=y.hi,
                    band=band,
                    band_nto=band_nto,
                    k=k,
                    p1=lp.p1 if c_band.size else np.zeros(0, np.int64),
                    p2=lp.p2 if c_band.size else np.zeros(0, np.int64),
                    c_band=c_band,
                    c_k=c_k,
                    **({} if dx is None else {"dx_lo": dx.lo, "dx_hi": dx.hi}),
                    bound_by=self.bound_by,
                )
            )
        verdict, reason, exc, n_exc = verdict_of(levels)
        if plan.reason and not levels:
            verdict, reason = "undecided", plan.reason
        raw = verdict
        if levels and band_reference(self.ctx.noise[ch]) is None:
            verdict = NO_REFERENCE
            reason = (
                "no noise figures for this IMU: the stationary band shown is a default "
                f"preset's, not a reference to judge against; {HOW_TO_REFERENCE}"
            )
        out = ChannelMargins(
            ch, UNITS[ch], plan.source, levels, verdict, reason, exc, n_exc, raw_verdict=raw,
            fragile=fragility(levels, verdict) if levels and verdict != NO_REFERENCE else {},
        )
        aided = [lv for lv in levels if lv.kind == "aided"]
        if aided:
            last = aided[-1].summary()
            pb = self.ctx.aiding.pitch
            note = dominant_default(ch, self.veh, last["halfwidth_median"], last["tau_s"],
                                    None if pb is None else pb.median_halfwidth)
            if note:
                out.notes.append(note)
            gz = self.ctx.imu.sig["gyro_z"]
            abs_int = float(np.sum(np.abs(gz.y) * np.diff(gz.bnd)))  # int |r| dt
            mean_r = abs_int / max(self.ctx.imu.duration, 1e-300)
            note = dominant_transport(
                ch, self.veh, last["halfwidth_median"], last["tau_s"], mean_r
            )
            if note:
                out.notes.append(note)
            note = heave_note(ch, self.veh, levels)
            if note:
                out.notes.append(note)
        acc = getattr(plan, "accel", "")
        if acc and aided:  # gyro_x / gyro_y from an accelerometer's window pairs
            out.notes.append(
                f"{ch} is judged from {acc}'s window changes (docs/dynamic-method.md section "
                f"3b, (3b.8)) with {acc}'s change band as stated: a bias step of {acc} reads "
                f"as an error of {ch}, so `exceeds` here names {ch} or {acc} (the change "
                f"test of {acc}, (3b.9), tells them apart where it decides)"
            )
        return out
