"""Window-mean margins per averaging time, and the verdicts (docs/dynamic-method.md, section 4).

For a window ``W`` with kernel ``K_W`` (``>= 0``, integral 1) the guaranteed interval of
the kernel-weighted mean of the IMU error of channel ``c`` is::

    [E_W] = [y_W] - [x_W]

``[y_W]``: the same kernel applied to the samples (rigorous float sums);
``[x_W]``: the kernel mean of the TRUE signal, built from the aiding sensors and the
vehicle bounds only (never from channel ``c``; other gyros enter the accelerometer
and gyro channels only as magnitude bounds in second-order terms). Kernels: the
boxcar between two epochs with a velocity (``x_W(f_x) = (u(b) - u(a))/tau - mean(r v)
+ g mean(sin theta)``), the trapezoid of a difference of two mean velocities over fix
intervals (positions only), the boxcar between heading epochs (yaw rate) or attitude
epochs (roll/pitch rates, vertical specific force).

The stationary band of the window (what the IMU error may be when the sensor behaves
as its budget says) is ``k_W sigma_W + D_KR + s mean|x| + m mean|x_perp| + edge``,
``sigma_W`` the standard deviation of the kernel mean of white noise, quantization,
flicker and turn-on bias (:func:`~imubounds.dynamic.estimator.budget.box_sum_variance`,
:func:`~imubounds.dynamic.estimator.budget.kernel_variance`), ``k_W`` at the level of the
windows family split over the tau levels.

Verdict per channel: ``exceeds`` if some window's ``[E_W]`` lies entirely outside the
band; ``consistent`` if there is a decidable window (``[x_W]`` not wider than the band)
and none exceeds; ``undecided`` otherwise.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numba import njit

from imubounds.dynamic.estimator.budget import (
    box_sum_variance,
    centered_ms_bound,
    kernel_variance,
)
from imubounds.dynamic.estimator.inputs import PiecewiseSignal, RangeExt, lateral_h_bound
from imubounds.interval import IntervalArray as IA
from imubounds.interval import atan2, cos, sin, sqr, sqrt

G_LO, G_HI = 9.76, 9.84  #: local gravity magnitude range, m/s^2 (latitude, height)
R_EARTH = 6.371e6
EARTH_RATE = 7.2921159e-5
TWO_PI = 2.0 * math.pi


def _up(x: Any) -> Any:
    return np.nextafter(np.asarray(x, dtype=float), np.inf)


def pm(r: Any) -> IA:
    """The interval ``[-r, r]`` (r >= 0, rounded up)."""
    r = _up(np.asarray(r, dtype=float))
    return IA(-r, r)


# --------------------------------------------------------------------------- planning


@dataclass
class LevelPlan:
    """The windows of one averaging time (relative times, s)."""

    tau_s: float
    kind: str  # "aided" or "vehicle"
    a1: np.ndarray
    b1: np.ndarray
    a2: np.ndarray
    b2: np.ndarray
    i: np.ndarray  # epoch index of the window start (aided)
    j: np.ndarray  # epoch index of the window end (aided)
    #: adjacent pairs (window p1[q] ends where window p2[q] starts) for the change test
    p1: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    p2: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))

    @property
    def n(self) -> int:
        return int(self.a1.size)

    @property
    def n_pairs(self) -> int:
        return int(self.p1.size)

    @property
    def tau(self) -> np.ndarray:
        return 0.5 * (self.a2 + self.b2) - 0.5 * (self.a1 + self.b1)


@dataclass
class ChannelPlan:
    channel: str
    source: str  # which aiding builds [x_W]
    epochs: np.ndarray  # aiding epochs of the windows
    trapezoid: bool
    levels: list[LevelPlan] = field(default_factory=list)
    reason: str = ""


def tau_grid(dt: float, duration: float) -> list[float]:
    """Octave grid from one IMU sample to a quarter of the trip."""
    out = []
    tau = dt
    while tau <= duration / 4.0 * (1 + 1e-9):
        out.append(tau)
        tau *= 2.0
    return out


def _subsample(idx: np.ndarray, cap: int) -> np.ndarray:
    if idx.size <= cap:
        return idx
    pick = np.unique(np.round(np.linspace(0, idx.size - 1, cap)).astype(np.int64))
    return idx[pick]


def plan_channel(
    channel: str,
    source: str,
    epochs: np.ndarray,
    trapezoid: bool,
    bnd: np.ndarray,
    dt: float,
    cap: int,
) -> ChannelPlan:
    """Windows of every tau level for a channel whose aided means come from ``epochs``."""
    plan = ChannelPlan(channel, source, epochs, trapezoid)
    duration = float(bnd[-1] - bnd[0])
    if epochs.size < 2:
        plan.reason = f"fewer than two {source} epochs"
    gap = float(np.median(np.diff(epochs))) if epochs.size >= 2 else math.inf
    n_imu = bnd.size - 1
    for tau in tau_grid(dt, duration):
        if tau < 0.999 * gap or epochs.size < 2:
            # shorter than the aiding period: only the vehicle's bounds (gross faults);
            # fewer windows are enough
            m = max(1, int(round(tau / dt)))
            starts = np.arange(0, n_imu - m + 1, max(1, m // 2))
            starts = _subsample(starts, min(cap, 256))
            a = bnd[starts]
            b = bnd[starts + m]
            z = np.zeros(a.size, dtype=np.int64)
            plan.levels.append(LevelPlan(tau, "vehicle", a, a, b, b, z, z))
            continue
        m = max(1, int(round(tau / gap)))
        last = epochs.size - 1 - (2 * m if trapezoid else m)
        if last < 0:
            continue
        if trapezoid:
            starts = _subsample(np.arange(0, last + 1, max(1, m // 2)), cap)
        else:
            step = max(1, m // 2)
            while m % step:  # a divisor of m: window s + m is a start too (change test)
                step -= 1
            starts = _subsample_pairs(np.arange(0, last + 1, step), m, last, cap)
        if trapezoid:
            a1, b1 = epochs[starts], epochs[starts + m]
            a2, b2 = epochs[starts + m], epochs[starts + 2 * m]
            j = starts + 2 * m
        else:
            a1 = b1 = epochs[starts]
            a2 = b2 = epochs[starts + m]
            j = starts + m
        lp = LevelPlan(tau, "aided", a1, b1, a2, b2, starts, j)
        if not trapezoid:
            q = np.searchsorted(starts, j)
            ok = q < starts.size
            ok[ok] = starts[q[ok]] == j[ok]
            lp.p1 = np.flatnonzero(ok).astype(np.int64)
            lp.p2 = q[ok].astype(np.int64)
        plan.levels.append(lp)
    return plan


def _subsample_pairs(idx: np.ndarray, m: int, last: int, cap: int) -> np.ndarray:
    """Like :func:`_subsample`, but the kept starts come in adjacent pairs (s, s + m)
    so that the change test has windows to compare."""
    if idx.size <= cap:
        return idx
    first = idx[idx + m <= last]
    pick = _subsample(first, max(1, cap // 2))
    return np.unique(np.concatenate([pick, pick + m]))


# ------------------------------------------------------------------------- evaluation


@dataclass
class LevelResult:
    """Windows of one tau level evaluated (arrays over windows)."""

    tau_s: float
    kind: str
    t_start: np.ndarray
    tau: np.ndarray
    x_lo: np.ndarray
    x_hi: np.ndarray
    y_lo: np.ndarray
    y_hi: np.ndarray
    band: np.ndarray
    band_nto: np.ndarray
    k: float
    #: change test: adjacent pairs (window indices), the stationary band of the change
    #: of the window means (turn-on bias cancels), its k
    p1: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    p2: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    c_band: np.ndarray = field(default_factory=lambda: np.zeros(0))
    c_k: float = 0.0

    @property
    def d_lo(self) -> np.ndarray:
        """Lower end of ``[E_W2] - [E_W1]`` over the adjacent pairs."""
        return np.nextafter(self.e_lo[self.p2] - self.e_hi[self.p1], -np.inf)

    @property
    def d_hi(self) -> np.ndarray:
        return np.nextafter(self.e_hi[self.p2] - self.e_lo[self.p1], np.inf)

    @property
    def c_exceeds(self) -> np.ndarray:
        return (self.d_lo > self.c_band) | (self.d_hi < -self.c_band)

    @property
    def c_decidable(self) -> np.ndarray:
        xw = 0.5 * (self.x_hi - self.x_lo)
        return xw[self.p1] + xw[self.p2] <= self.c_band

    @property
    def e_lo(self) -> np.ndarray:
        return np.nextafter(self.y_lo - self.x_hi, -np.inf)

    @property
    def e_hi(self) -> np.ndarray:
        return np.nextafter(self.y_hi - self.x_lo, np.inf)

    @property
    def halfwidth(self) -> np.ndarray:
        return 0.5 * (self.e_hi - self.e_lo)

    @property
    def decidable(self) -> np.ndarray:
        return 0.5 * (self.x_hi - self.x_lo) <= self.band

    @property
    def exceeds(self) -> np.ndarray:
        return (self.e_lo > self.band) | (self.e_hi < -self.band)

    def summary(self) -> dict[str, Any]:
        hw = self.halfwidth
        fin = np.isfinite(hw)
        return {
            "tau_s": self.tau_s,
            "halfwidth_max": float(np.max(hw[fin])) if fin.any() else None,
            "halfwidth_median": float(np.median(hw[fin])) if fin.any() else None,
            "stationary": float(np.median(self.band)) if self.band.size else None,
            "stationary_max": float(np.max(self.band)) if self.band.size else None,
            "exceeds_fraction": float(np.mean(self.exceeds)) if self.band.size else 0.0,
            "decidable_fraction": float(np.mean(self.decidable)) if self.band.size else 0.0,
            "n_windows": int(self.band.size),
            "k": self.k,
            "aided_from": "vehicle bounds" if self.kind == "vehicle" else "aiding",
            **self._change_summary(),
        }

    def _change_summary(self) -> dict[str, Any]:
        if self.p1.size == 0:
            return {"n_changes": 0}
        hw = 0.5 * (self.d_hi - self.d_lo)
        fin = np.isfinite(hw)
        return {
            "n_changes": int(self.p1.size),
            "change_halfwidth_median": float(np.median(hw[fin])) if fin.any() else None,
            "change_stationary": float(np.median(self.c_band)),
            "change_exceeds_fraction": float(np.mean(self.c_exceeds)),
            "change_k": self.c_k,
        }


@dataclass
class ChannelMargins:
    channel: str
    unit: str
    source: str
    levels: list[LevelResult]
    verdict: str
    reason: str
    exceeding: list[dict[str, Any]]
    n_exceeding: int
    notes: list[str] = field(default_factory=list)

    def table(self) -> list[dict[str, Any]]:
        return [lv.summary() for lv in self.levels]

    def to_dict(self) -> dict[str, Any]:
        return {
            "unit": self.unit,
            "aided_from": self.source,
            "verdict": self.verdict,
            "reason": self.reason,
            "exceeding_windows": self.exceeding,
            "n_exceeding_windows": self.n_exceeding,
            "notes": self.notes,
        }


def verdict_of(levels: list[LevelResult], max_list: int = 50) -> tuple[str, str, list[Any], int]:
    """The channel verdict from its evaluated levels."""
    exc: list[dict[str, Any]] = []
    n_exc = 0
    any_dec = False
    n_lev = n_chg = 0
    for lv in levels:
        ex = lv.exceeds
        any_dec |= bool(np.any(lv.decidable))
        for w in np.flatnonzero(ex):
            n_lev += 1
            if len(exc) < max_list:
                exc.append(
                    {
                        "test": "level",
                        "t_start_s": float(lv.t_start[w]),
                        "tau_s": float(lv.tau[w]),
                        "interval": [float(lv.e_lo[w]), float(lv.e_hi[w])],
                        "stationary": float(lv.band[w]),
                    }
                )
    for lv in levels:
        if lv.p1.size == 0:
            continue
        any_dec |= bool(np.any(lv.c_decidable))
        cex = lv.c_exceeds
        d_lo, d_hi = lv.d_lo, lv.d_hi
        for q in np.flatnonzero(cex):
            n_chg += 1
            if len(exc) < max_list:
                w1, w2 = int(lv.p1[q]), int(lv.p2[q])
                exc.append(
                    {
                        "test": "change",
                        "t_start_s": float(lv.t_start[w1]),
                        "t_change_s": float(lv.t_start[w2]),
                        "tau_s": float(lv.tau[w1]),
                        "interval": [float(d_lo[q]), float(d_hi[q])],
                        "stationary": float(lv.c_band[q]),
                    }
                )
    n_exc = n_lev + n_chg
    if n_exc:
        parts = []
        if n_lev:
            f = next(e for e in exc if e["test"] == "level") if any(
                e["test"] == "level" for e in exc
            ) else None
            parts.append(
                f"{n_lev} window(s) lie entirely outside the stationary band"
                + (f" (first at t = {f['t_start_s']:.1f} s, tau = {f['tau_s']:.3g} s)" if f else "")
            )
        if n_chg:
            f = next((e for e in exc if e["test"] == "change"), None)
            parts.append(
                f"{n_chg} change(s) between adjacent windows lie entirely outside the "
                "stationary band of changes"
                + (f" (first at t = {f['t_change_s']:.1f} s, tau = {f['tau_s']:.3g} s)"
                   if f else "")
            )
        return "exceeds", "; ".join(parts), exc, n_exc
    if any_dec:
        return (
            "consistent",
            "every decidable window, and every change between adjacent windows, lies "
            "within its stationary band",
            exc,
            0,
        )
    return (
        "undecided",
        "the aided interval is wider than the stationary band at every tau",
        exc,
        0,
    )


# ----------------------------------------------------------------- tilt functions


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
            from imubounds.dynamic.estimator.inputs import Locator

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
        "cosr": lambda: cr,
        "sec_p_minus_1": lambda: 1.0 / cp - 1.0,
        "sec_r_minus_1": lambda: 1.0 / cr - 1.0,
        "abs_tanr_tanp": lambda: abs(sr * sp / (cr * cp)),
        "abs_tanp": lambda: abs(sp / cp),
    }
    return ts


# -------------------------------------------------------------------------- margins


class MarginBuilder:
    """Evaluates the windows of every channel (see the module docstring)."""

    def __init__(self, ctx: Any) -> None:
        self.ctx = ctx
        self.imu = ctx.imu
        self.veh = ctx.vehicle
        self.ag = ctx.aiding
        self.tilt: TiltSignals = ctx.tilt
        self._bodyvel: Any = None
        self.fine_r = True  # False once the gyro_z verdict is 'exceeds'
        self.p_window = 1e-6  # per-window probability of the current level

    # -- IMU-side helpers ----------------------------------------------------------
    def mag_mean(self, ch: str, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """Upper bound of the mean of |true signal| of channel ``ch`` over ``[a, b]``
        (magnitude of the measured samples plus the per-sample error bound)."""
        if not self.imu.available[ch]:
            return np.full(np.shape(a), self.imu.sig[ch].xmax)
        ln = np.maximum(np.asarray(b) - np.asarray(a), 1e-300)
        cn = self.ctx.noise[ch]
        m = (self.imu.sig[ch].abs_integral(a, b) / ln + self.ctx.E0[ch]) / (1.0 - cn.scale)
        return np.minimum(_up(m), self.imu.sig[ch].xmax)

    def kernel_mag(self, ch: str, lp: LevelPlan, tau: np.ndarray) -> np.ndarray:
        """Upper bound of the kernel mean of |true signal| (kernel <= 1/tau on its support)."""
        supp = lp.b2 - lp.a1
        return _up(self.mag_mean(ch, lp.a1, lp.b2) * supp / tau)

    def imu_mean(self, ch: str, lp: LevelPlan, tau: np.ndarray) -> IA:
        return self.imu.sig[ch].kernel_mean(lp.a1, lp.b1, lp.a2, lp.b2, tau)

    def band(self, ch: str, lp: LevelPlan, tau: np.ndarray, k: float) -> tuple[Any, Any]:
        """Stationary band per window, with and without the turn-on bias."""
        cn = self.ctx.noise[ch]
        imu = self.imu
        dt = imu.dt
        ratio = max(1.0, imu.max_len / dt)
        boxcar = bool((lp.a1 == lp.b1).all())
        if boxcar:
            cnt = imu.count(lp.a1, lp.a2)
            uc, inv = np.unique(cnt, return_inverse=True)
            v_to = np.array([box_sum_variance(cn, int(m), dt, True) for m in uc])[inv]
            v_no = np.array([box_sum_variance(cn, int(m), dt, False) for m in uc])[inv]
            sd_to = np.sqrt(v_to) * ratio / tau
            sd_no = np.sqrt(v_no) * ratio / tau
            noise_to, noise_no = k * sd_to, k * sd_no
            if cn.drift_bound is not None:
                # the stated drift bound replaces the flicker model for windows as long as
                # its window (where it is the smaller)
                w_to = np.array([box_sum_variance(cn, int(m), dt, True, False) for m in uc])[inv]
                w_no = np.array([box_sum_variance(cn, int(m), dt, False, False) for m in uc])[inv]
                long_ = tau >= cn.drift_window_s
                alt_to = k * np.sqrt(w_to) * ratio / tau + cn.drift_bound
                alt_no = k * np.sqrt(w_no) * ratio / tau + cn.drift_bound
                noise_to = np.where(long_, np.minimum(noise_to, alt_to), noise_to)
                noise_no = np.where(long_, np.minimum(noise_no, alt_no), noise_no)
        else:
            c = _trapezoid_weights(lp, tau, dt)
            sd_to = math.sqrt(kernel_variance(cn, c, dt, True)) * 1.01 * ratio
            sd_no = math.sqrt(kernel_variance(cn, c, dt, False)) * 1.01 * ratio
            noise_to = np.full(tau.shape, k * sd_to)
            noise_no = np.full(tau.shape, k * sd_no)
        det = self.ctx.D_KR[ch]
        det = det + cn.scale * self.kernel_mag(ch, lp, tau)
        for other in _perp(ch):
            det = det + cn.misalignment_rad * self.kernel_mag(other, lp, tau)
        edge = (imu.edge(lp.a1) + imu.edge(lp.b2)) * imu.rate_bound[ch] * imu.max_len / tau
        det = det + edge
        return _up(noise_to + det + cn.turn_on_det()), _up(noise_no + det)

    def _pair_noise_sd(
        self, ch: str, m1: np.ndarray, m2: np.ndarray, t1: np.ndarray, t2: np.ndarray,
        flicker: bool,
    ) -> np.ndarray:
        """Standard deviation of ``mean_W2 - mean_W1`` of the noise (white, quantization,
        flicker; the turn-on bias cancels) over adjacent windows of ``m1``, ``m2`` samples:
        ``V1/t1^2 + V2/t2^2 - 2 C/(t1 t2)`` with the covariance from the variance of the
        joined box, ``2 C = V12 - V1 - V2`` (stationary model, exact). Inflated by
        ``1 + 2/min(m)`` for the samples the window ends cut."""
        cn = self.ctx.noise[ch]
        dt = self.imu.dt
        keys = np.stack([m1, m2], 1)
        uk, inv = np.unique(keys, axis=0, return_inverse=True)
        inv = np.asarray(inv).reshape(-1)
        v1 = np.empty(len(uk))
        v2 = np.empty(len(uk))
        v12 = np.empty(len(uk))
        for q, (a, b) in enumerate(uk):
            v1[q] = box_sum_variance(cn, int(a), dt, False, flicker)
            v2[q] = box_sum_variance(cn, int(b), dt, False, flicker)
            v12[q] = box_sum_variance(cn, int(a + b), dt, False, flicker)
        V1, V2, V12 = v1[inv], v2[inv], v12[inv]
        var = V1 / (t1 * t1) + V2 / (t2 * t2) - (V12 - V1 - V2) / (t1 * t2)
        # the joined-box identity is exact; guard the rounding of the subtraction
        var = np.maximum(var, 0.0) + 1e-9 * (V1 / (t1 * t1) + V2 / (t2 * t2))
        ratio = max(1.0, self.imu.max_len / dt)
        infl = 1.0 + 2.0 / np.maximum(np.minimum(m1, m2), 1)
        return np.sqrt(var) * ratio * infl

    def _dtrue_bound(
        self, o: str, lp: LevelPlan, tau: np.ndarray, w1: np.ndarray, w2: np.ndarray,
        k: float,
    ) -> np.ndarray:
        """Bound of ``|mean_W2 x_o - mean_W1 x_o|`` (true signal of another axis, for the
        misalignment term of the change band): the measured change plus the change of
        the other axis' error (its change band without its own misalignment term),
        never above the sum of the two magnitudes."""
        cn = self.ctx.noise[o]
        crude = self.kernel_mag(o, lp, tau)
        crude = crude[w1] + crude[w2]
        if not self.imu.available[o]:
            return crude
        y = self.imu_mean(o, lp, tau)
        dy = abs(y[w2] - y[w1]).hi
        m = self.imu.count(lp.a1, lp.a2)
        sd = self._pair_noise_sd(o, m[w1], m[w2], tau[w1], tau[w2], True)
        mag = self.kernel_mag(o, lp, tau)
        err = k * sd + 2 * self.ctx.D_KR[o] + cn.scale * (mag[w1] + mag[w2])
        for oo in _perp(o):
            mm = self.kernel_mag(oo, lp, tau)
            err = err + cn.misalignment_rad * (mm[w1] + mm[w2])
        return np.minimum(crude, _up(dy + err))

    def change_band(self, ch: str, lp: LevelPlan, tau: np.ndarray, k: float) -> np.ndarray:
        """Stationary band of ``[E_W2] - [E_W1]`` for the adjacent pairs of a level: the
        turn-on bias cancels and the flicker enters through its change between the two
        windows (the Allan statistic: about ``sqrt(2) 0.664 B`` per k); a stated drift
        bound gives the alternative ``2 x drift``; plus rate random walk, scale and
        misalignment terms and the window-end edges."""
        w1, w2 = lp.p1, lp.p2
        if w1.size == 0:
            return np.zeros(0)
        cn = self.ctx.noise[ch]
        imu = self.imu
        m = imu.count(lp.a1, lp.a2)
        t1, t2 = tau[w1], tau[w2]
        noise = k * self._pair_noise_sd(ch, m[w1], m[w2], t1, t2, True)
        if cn.drift_bound is not None:
            long_ = np.minimum(t1, t2) >= cn.drift_window_s
            alt = k * self._pair_noise_sd(ch, m[w1], m[w2], t1, t2, False) + 2 * cn.drift_bound
            noise = np.where(long_, np.minimum(noise, alt), noise)
        mag = self.kernel_mag(ch, lp, tau)
        det = 2 * self.ctx.D_KR[ch] + cn.scale * (mag[w1] + mag[w2])
        for other in _perp(ch):
            det = det + cn.misalignment_rad * self._dtrue_bound(other, lp, tau, w1, w2, k)
        e = imu.edge(lp.a1) + imu.edge(lp.b2)
        edge = (e[w1] / t1 + e[w2] / t2) * imu.rate_bound[ch] * imu.max_len
        return _up(noise + det + edge)

    # -- aiding helpers ------------------------------------------------------------
    def gyro_abs_mean(self, ch: str, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        return np.minimum(self.mag_mean(ch, a, b), self.veh.max_rate)

    def psi_dot_abs(self, a: np.ndarray, b: np.ndarray, own_q: bool = True) -> np.ndarray:
        """Bound of mean |d psi/dt| over [a, b] from the gyro magnitudes (other channels)."""
        r = self.gyro_abs_mean("gyro_z", a, b)
        q = self.gyro_abs_mean("gyro_y", a, b) if own_q else np.full(r.shape, self.veh.max_rate)
        sr = self.tilt.hull("abs_sinr", a, b).hi
        sec = 1.0 + self.tilt.hull("sec_p_minus_1", a, b).hi
        return np.minimum(_up((r + q * sr) * sec), self.veh.max_rate / math.cos(self.veh.max_tilt))

    def heading_at(self, t: np.ndarray) -> IA:
        """Heading (model convention, unwrapped branch of the compass centres) at ``t``,
        interpolated from the nearest heading epochs; the change over the gap is bounded
        by the gyro magnitudes (a magnitude bound, never the gyro's value)."""
        ag = self.ag
        t = np.asarray(t, dtype=float)
        if not ag.has_heading:
            return IA(np.full(t.shape, -np.inf), np.full(t.shape, np.inf))
        ht, hc, hh = ag.head_t, ag.head_c, ag.head_h
        j = np.searchsorted(ht, t)
        lo = np.full(t.shape, -np.inf)
        hi = np.full(t.shape, np.inf)
        for e in (j - 1, j):
            ok = (e >= 0) & (e < ht.size)
            ee = np.clip(e, 0, ht.size - 1)
            te = ht[ee]
            a, b = np.minimum(t, te), np.maximum(t, te)
            exact = np.abs(t - te) <= 1e-9
            w = np.where(exact, 0.0, self.psi_dot_abs(a, b) * (b - a))
            w = _up(w)
            c_lo = np.nextafter(hc[ee] - hh[ee] - w, -np.inf)
            c_hi = _up(hc[ee] + hh[ee] + w)
            lo = np.where(ok, np.maximum(lo, c_lo), lo)
            hi = np.where(ok, np.minimum(hi, c_hi), hi)
        bad = lo > hi
        if np.any(bad):  # inconsistent neighbours: keep their hull (reported by the smoother)
            lo = np.where(bad, np.minimum(lo, hi), lo)
            hi = np.where(bad, np.maximum(lo, hi), hi)
        return IA(lo, hi)

    def growth(self, gaps: np.ndarray) -> np.ndarray:
        """How far a velocity can leave the hull of its epoch values between epochs."""
        v = self.veh
        return _up(np.minimum(v.max_accel * gaps / 2.0, v.max_jerk * gaps * gaps / 8.0))

    def body_velocity(self) -> Any:
        """Body velocity (u, v, w) intervals at the velocity epochs (DVL preferred)."""
        if self._bodyvel is not None:
            return self._bodyvel
        ag, veh = self.ag, self.veh
        vl = veh.lateral_bound
        if ag.has_bvel:
            t = ag.bvel_t
            h = ag.bvel_h
            u = IA(ag.bvel_u - h, ag.bvel_u + h)
            if ag.bvel_v is not None and np.all(np.isfinite(ag.bvel_v)):
                v = IA(ag.bvel_v - h, ag.bvel_v + h)
            else:
                vb = vl if vl is not None else veh.max_speed
                v = pm(np.full(t.size, vb))
            if ag.bvel_w is not None and np.all(np.isfinite(ag.bvel_w)):
                w = IA(ag.bvel_w - h, ag.bvel_w + h)
            else:
                w = pm(np.full(t.size, veh.vertical_bound))
            src = f"body velocity ({ag.bvel_kind})"
        elif ag.has_gvel:
            ok = ag.gvel_ok
            t = ag.gnss_t[ok]
            R = ag.gvel_hi[ok]
            vem, vnm = IA(ag.gvel_e[ok]), IA(ag.gvel_n[ok])
            # the radial bound R: ||V| - |Vm|| <= R and |chi - chi_m| <= asin(R / |Vm|)
            sm = sqrt(sqr(vem) + sqr(vnm))
            S = (sm + pm(R)) & IA(np.zeros(t.size), np.full(t.size, np.inf))
            if ag.head_from_course:
                # heading from this very course (no reversing): |psi - chi| <= asin(vh/S)
                vhm = lateral_h_bound(veh)
                assert vhm is not None
                slo = S.lo
                dm = np.where(
                    slo > vhm,
                    _up(np.arcsin(np.minimum(1.0, vhm / np.maximum(slo, 1e-300))) * (1 + 1e-9)),
                    0.5 * math.pi * (1 + 1e-9),
                )
                d = pm(dm)
            else:
                smf = np.sqrt(ag.gvel_e[ok] ** 2 + ag.gvel_n[ok] ** 2)
                fast = smf * (1 - 1e-9) > R
                e_chi = np.where(
                    fast,
                    _up(np.arcsin(np.minimum(1.0, R / np.maximum(smf * (1 - 1e-9), 1e-300)))
                        * (1 + 1e-9) + 1e-15),
                    np.inf,
                )
                chi = course(vem, vnm) + pm(np.where(fast, e_chi, 0.0))
                chi = IA(np.where(fast, chi.lo, -np.inf), np.where(fast, chi.hi, np.inf))
                psi = self.heading_at(t)
                fin = np.isfinite(psi.lo) & np.isfinite(psi.hi) & fast
                kk = np.where(
                    fin, np.round((chi.mid() - np.where(fin, psi.mid(), 0.0)) / TWO_PI), 0
                )
                psi = psi + IA(TWO_PI * kk) * IA(1.0 - 2**-50, 1.0 + 2**-50)
                d = chi - psi
            uh, vh = S * cos(d), S * sin(d)
            rl, rh, pl, ph = ag.tilt(t, veh)
            roll, pitch = IA(rl, rh), IA(pl, ph)
            sr, cr, sp, cp = sin(roll), cos(roll), sin(pitch), cos(pitch)
            w = pm(np.full(t.size, veh.vertical_bound))
            v = (vh + sr * w) / cr
            if vl is not None:
                v = v & pm(np.full(t.size, vl))
            u = (uh + sr * sp * v + cr * sp * w) / cp
            src = "GNSS velocity rotated by the heading"
        else:
            self._bodyvel = None
            return None
        u = u & pm(np.full(t.size, veh.max_speed))
        if vl is not None:
            v = v & pm(np.full(t.size, vl))
        bad = u.is_empty() | v.is_empty()
        if np.any(bad):  # an aiding epoch contradicts the vehicle bounds: drop it
            keep = ~bad
            t, u, v, w = t[keep], u[keep], v[keep], w[keep]
        gaps = np.diff(t) if t.size > 1 else np.zeros(0)
        gu, gv = self._gap_growth(t, u, v)
        self._bodyvel = {
            "t": t,
            "u": u,
            "v": v,
            "w": w,
            "src": src,
            "uext": RangeExt(u.lo, u.hi),
            "vabs": RangeExt(abs(v).hi),
            "wabs": RangeExt(abs(w).hi),
            "gaps": RangeExt(gaps if gaps.size else np.zeros(1)),
            "gu": RangeExt(gu if gu.size else np.zeros(1)),
            "gv": RangeExt(gv if gv.size else np.zeros(1)),
            "dropped": int(np.sum(bad)),
        }
        return self._bodyvel

    def _vel_range(self, bv: Any, a: np.ndarray, b: np.ndarray) -> dict[str, np.ndarray]:
        """Over the support [a, b]: hull of u, max |v|, max |w| (epochs inside, plus the
        growth between epochs), in m/s."""
        t = bv["t"]
        i = np.clip(np.searchsorted(t, a, side="right") - 1, 0, t.size - 1)
        j = np.clip(np.searchsorted(t, b, side="left"), 0, t.size - 1)
        j = np.maximum(j, i)
        ulo, uhi = bv["uext"].query(i, j)
        _, vmax = bv["vabs"].query(i, j)
        _, wmax = bv["wabs"].query(i, j)
        gi = np.clip(i, 0, max(0, t.size - 2))
        gj = np.clip(j - 1, 0, max(0, t.size - 2))
        _, gmax = bv["gaps"].query(gi, np.maximum(gj, gi))
        _, gu = bv["gu"].query(gi, np.maximum(gj, gi))
        _, gv = bv["gv"].query(gi, np.maximum(gj, gi))
        # outside the epoch span the growth is over the distance to the nearest epoch
        ext = np.maximum(t[i] - a, 0.0) + np.maximum(b - t[j], 0.0)
        g = self.growth(np.maximum(gmax, 2 * ext))
        single = t.size < 2
        g_u = np.where((ext > 0) | single, g, np.minimum(g, gu))
        g_v = np.where((ext > 0) | single, g, np.minimum(g, gv))
        vl = self.veh.lateral_bound
        vmax = vmax + g_v
        if vl is not None:
            vmax = np.minimum(vmax, vl)
        return {
            "u_lo": ulo - g_u,
            "u_hi": uhi + g_u,
            "v_max": _up(vmax),
            "w_max": _up(wmax + g) if self.veh.kind != "ground" else np.zeros(a.shape),
        }

    def _gap_growth(self, t: np.ndarray, u: IA, v: IA) -> tuple[np.ndarray, np.ndarray]:
        """How far u and v can leave the hull of their values at two consecutive velocity
        epochs: half their total variation over the gap, bounded with the magnitudes of
        the other IMU channels (|u'| <= |f_x| + |r| |v| + g |sin pitch|, |v'| <= |f_y| +
        |r| |u| + g |sin roll|; a magnitude use in a second-order term), and the
        vehicle's acceleration and jerk bounds."""
        if t.size < 2:
            return np.zeros(0), np.zeros(0)
        veh = self.veh
        a, b = t[:-1], t[1:]
        g = b - a
        r_int = self.mag_mean("gyro_z", a, b) * g
        fx_int = self.mag_mean("accel_x", a, b) * g
        fy_int = self.mag_mean("accel_y", a, b) * g
        sp = self.tilt.hull("abs_sinp", a, b).hi
        sr = self.tilt.hull("abs_sinr", a, b).hi
        vmax = np.maximum(abs(v).hi[:-1], abs(v).hi[1:])
        umax = np.maximum(abs(u).hi[:-1], abs(u).hi[1:])
        vl = veh.lateral_bound
        vcap = vl if vl is not None else veh.max_speed
        base = self.growth(g)
        tv_u = fx_int + np.minimum(vmax + base, vcap) * r_int + G_HI * sp * g
        tv_v = fy_int + np.minimum(umax + base, veh.max_speed) * r_int + G_HI * sr * g
        return _up(np.minimum(base, tv_u / 2)), _up(np.minimum(base, tv_v / 2))

    def r_abs(self, lp: LevelPlan, tau: np.ndarray) -> np.ndarray:
        """Bound of the kernel mean of |r| (true yaw rate) over each window: the gyro's
        magnitude centred on its own mean error over the window's support (known from
        the heading), plus a bound of the noise's deviation from its mean (Gaussian
        quadratic form); the per-sample bound if the gyro is judged faulty or there is
        no heading. Used only in second-order (transport) terms of the accelerometers."""
        coarse = self.kernel_mag("gyro_z", lp, tau)
        if not self.fine_r or not self.ag.has_heading or not self.imu.available["gyro_z"]:
            return coarse
        s0, s1 = lp.a1, lp.b2
        L = s1 - s0
        sup = LevelPlan(float(np.median(L)), "aided", s0, s0, s1, s1, lp.i, lp.j)
        sig = self.imu.sig["gyro_z"]
        ylo, yhi = sig.integral(s0, s1)
        ybox = IA(ylo, yhi) / IA(L)
        p0, p1 = self.heading_at(s0), self.heading_at(s1)
        xbox = self._r_from_psidot((p1 - p0) / IA(L), sup, L, own_q=True)
        e = ybox - xbox
        fin = np.isfinite(e.lo) & np.isfinite(e.hi)
        c0 = np.where(fin, e.mid(), 0.0)
        rad = np.where(fin, e.radius(), np.inf)
        dev = abs_dev_integral(
            sig.bnd, sig.y, sig.unknown, sig.xmax, s0, s1, np.ascontiguousarray(c0)
        ) / L
        cn = self.ctx.noise["gyro_z"]
        m = self.imu.count(s0, s1)
        uc, inv = np.unique(m, return_inverse=True)
        p = self.p_window
        ms = np.array([centered_ms_bound(cn, int(mm), self.imu.dt, p) for mm in uc])[inv]
        ratio = max(1.0, self.imu.max_len / self.imu.dt)
        det = 2 * self.ctx.D_KR["gyro_z"] + 2 * cn.scale * self.mag_mean("gyro_z", s0, s1)
        for other in ("gyro_x", "gyro_y"):
            det = det + 2 * cn.misalignment_rad * self.mag_mean(other, s0, s1)
        fine = dev + rad + np.sqrt(ms) * ratio + det
        fine = _up(fine * L / tau)
        return np.minimum(coarse, np.where(np.isfinite(fine), fine, coarse))

    # -- channels ------------------------------------------------------------------
    def aided(self, ch: str, plan: ChannelPlan, lp: LevelPlan, tau: np.ndarray) -> IA:
        veh = self.veh
        if lp.kind == "vehicle":
            return self._vehicle_bound(ch, lp, tau)
        if ch == "gyro_z":
            return self._gyro_z(lp, tau)
        if ch in ("gyro_x", "gyro_y", "accel_z"):
            return self._three_d(ch, lp, tau)
        bv = self.body_velocity()
        rng = self._ranges(lp, bv)
        smax = np.maximum(np.abs(rng["u_lo"]), np.abs(rng["u_hi"])) + rng["v_max"]
        smax = np.minimum(smax, veh.max_speed)
        # Coriolis and transport rate of the Earth frame, at the window's speed bound
        earth = pm(2 * EARTH_RATE * smax + smax * smax / R_EARTH)
        if plan.trapezoid:
            ends = self._position_means(lp, tau)
        else:
            ends = {
                "u1": bv["u"][lp.i],
                "u2": bv["u"][lp.j],
                "v1": bv["v"][lp.i],
                "v2": bv["v"][lp.j],
            }
        if ch == "accel_x":
            r_mag = self.r_abs(lp, tau)
            transport = pm(rng["v_max"] * r_mag)
            grav = self.tilt.kmean("g_sinp", lp, tau)
            x = (ends["u2"] - ends["u1"]) / IA(tau) - transport + grav + earth
            if veh.kind != "ground":
                x = x + pm(rng["w_max"] * self.kernel_mag("gyro_y", lp, tau))
            return x
        # accel_y: (v2 - v1)/tau + mean(r u) + g mean(sin(roll) cos(pitch))
        r_mag = self.r_abs(lp, tau)
        mean_r = self._mean_r_from_heading(lp, tau, plan.trapezoid)
        u0 = 0.5 * (rng["u_lo"] + rng["u_hi"])
        du = _up(0.5 * (rng["u_hi"] - rng["u_lo"]))
        ru = IA(u0) * mean_r + pm(du * r_mag)
        grav = self.tilt.kmean("g_sinr_cosp", lp, tau)
        x = (ends["v2"] - ends["v1"]) / IA(tau) + ru + grav + earth
        if veh.kind != "ground":
            x = x + pm(rng["w_max"] * self.kernel_mag("gyro_x", lp, tau))
        return x

    def _ranges(self, lp: LevelPlan, bv: Any) -> dict[str, np.ndarray]:
        if bv is not None:
            return self._vel_range(bv, lp.a1, lp.b2)
        s = self._speed_max(lp.a1, lp.b2)
        vl = self.veh.lateral_bound
        return {
            "u_lo": -s,
            "u_hi": s,
            "v_max": np.minimum(s, vl) if vl is not None else s,
            "w_max": np.zeros(s.shape) if self.veh.kind == "ground" else s,
        }

    def _mean_r_from_heading(self, lp: LevelPlan, tau: np.ndarray, trapezoid: bool) -> IA:
        """Kernel mean of the yaw rate r from the heading (for accel_y's transport term)."""
        if trapezoid:
            p1 = self._heading_mean(lp.a1, lp.b1)
            p2 = self._heading_mean(lp.a2, lp.b2)
        else:
            p1 = self.heading_at(lp.a1)
            p2 = self.heading_at(lp.a2)
        dpsi = (p2 - p1) / IA(tau)
        return self._r_from_psidot(dpsi, lp, tau, own_q=True)

    def _r_from_psidot(self, dpsi: IA, lp: LevelPlan, tau: np.ndarray, own_q: bool) -> IA:
        """r = psi' cos(p)/cos(r) - q tan(roll): from the mean heading rate, with the tilt
        terms bounded (|psi'| by the vehicle's rate bound, |q| by gyro_y's magnitude)."""
        c = self.tilt.hull("cosp_over_cosr", lp.a1, lp.b2)
        c0 = c.mid()
        cdev = _up(np.maximum(c.hi - c0, c0 - c.lo))
        rate = self.veh.max_rate / math.cos(self.veh.max_tilt)
        q = (
            self.kernel_mag("gyro_y", lp, tau)
            if own_q
            else _up(self.veh.max_rate * (lp.b2 - lp.a1) / tau)
        )
        tr = self.tilt.hull("abs_tanr", lp.a1, lp.b2).hi
        earth = pm(EARTH_RATE + self.veh.max_speed / R_EARTH)
        return dpsi * IA(c0) + pm(rate * cdev) + pm(q * tr) + earth

    def _gyro_z(self, lp: LevelPlan, tau: np.ndarray) -> IA:
        ag = self.ag
        p1 = IA(ag.head_c[lp.i] - ag.head_h[lp.i], ag.head_c[lp.i] + ag.head_h[lp.i])
        p2 = IA(ag.head_c[lp.j] - ag.head_h[lp.j], ag.head_c[lp.j] + ag.head_h[lp.j])
        return self._r_from_psidot((p2 - p1) / IA(tau), lp, tau, own_q=True)

    def _heading_mean(self, a: np.ndarray, b: np.ndarray) -> IA:
        """Interval containing the mean heading over [a, b] (hull of the heading there)."""
        ag = self.ag
        lo = self.heading_at(a)
        hi = self.heading_at(b)
        ht = ag.head_t
        out_lo = np.minimum(lo.lo, hi.lo)
        out_hi = np.maximum(lo.hi, hi.hi)
        if ht.size:
            i = np.searchsorted(ht, a)
            j = np.searchsorted(ht, b, side="right") - 1
            has = j >= i
            ext = RangeExt(ag.head_c - ag.head_h, ag.head_c + ag.head_h)
            ii = np.clip(i, 0, ht.size - 1)
            jj = np.clip(np.maximum(j, i), 0, ht.size - 1)
            mn, mx = ext.query(ii, jj)
            out_lo = np.where(has, np.minimum(out_lo, mn), out_lo)
            out_hi = np.where(has, np.maximum(out_hi, mx), out_hi)
            # between heading epochs the heading moves by at most the rate bound x gap
            gaps = np.diff(ht) if ht.size > 1 else np.zeros(1)
            gext = RangeExt(gaps)
            _, gm = gext.query(np.clip(ii, 0, gaps.size - 1), np.clip(jj, 0, gaps.size - 1))
            w = _up(self.psi_dot_abs(a, b) * gm / 2)
            out_lo, out_hi = out_lo - w, out_hi + w
        return IA(np.nextafter(out_lo, -np.inf), _up(out_hi))

    def _speed_max(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """Bound on the horizontal speed over [a, b] from the GNSS positions (chord speeds
        of the fix pairs inside plus the growth between fixes), capped by max_speed."""
        ag, veh = self.ag, self.veh
        if not hasattr(self, "_chord"):
            t = ag.gnss_t
            if t.size < 2:
                self._chord = None
            else:
                d = np.hypot(np.diff(ag.gnss_e), np.diff(ag.gnss_n))
                hh = ag.gnss_h[1:] + ag.gnss_h[:-1]
                g = np.diff(t)
                sp = (d + math.sqrt(2) * hh) / g + veh.max_accel * g / 2
                self._chord = RangeExt(sp)
        if self._chord is None:
            return np.full(np.shape(a), veh.max_speed)
        t = ag.gnss_t
        i = np.clip(np.searchsorted(t, a, side="right") - 1, 0, t.size - 2)
        j = np.clip(np.searchsorted(t, b) - 1, 0, t.size - 2)
        _, mx = self._chord.query(i, np.maximum(i, j))
        return np.minimum(_up(mx), veh.max_speed)

    def _position_means(self, lp: LevelPlan, tau: np.ndarray) -> dict[str, IA]:
        """Mean body velocities over I1 and I2 from the GNSS positions (trapezoid kernel)."""
        ag, veh = self.ag, self.veh
        out: dict[str, IA] = {}
        t = ag.gnss_t
        i0 = np.searchsorted(t, lp.a1)
        i1 = np.searchsorted(t, lp.b1)
        i2 = np.searchsorted(t, lp.b2)
        E = IA(ag.gnss_e - ag.gnss_h, ag.gnss_e + ag.gnss_h)
        N = IA(ag.gnss_n - ag.gnss_h, ag.gnss_n + ag.gnss_h)
        for key, (p, q) in (("1", (i0, i1)), ("2", (i1, i2))):
            a, b = t[p], t[q]
            dT = IA(b - a)
            ve = (E[q] - E[p]) / dT
            vn = (N[q] - N[p]) / dT
            psi = self._heading_mean(a, b)
            fin = np.isfinite(psi.lo) & np.isfinite(psi.hi)
            mid = np.where(fin, psi.mid(), 0.0)
            eps = np.where(fin, _up(psi.radius()), math.pi)
            smax = self._speed_max(a, b)
            cm, sm = cos(IA(mid)), sin(IA(mid))
            uh = ve * cm + vn * sm + pm(smax * eps)
            vh = vn * cm - ve * sm + pm(smax * eps)
            sec_p = self.tilt.hull("sec_p_minus_1", a, b).hi
            sec_r = self.tilt.hull("sec_r_minus_1", a, b).hi
            trp = self.tilt.hull("abs_tanr_tanp", a, b).hi
            vl = veh.lateral_bound
            vmax = np.minimum(smax, vl) if vl is not None else smax
            u = uh + pm(smax * sec_p + vmax * trp)
            v = vh + pm(smax * sec_r)
            if veh.kind != "ground":
                wv = veh.vertical_bound
                u = u + pm(wv * self.tilt.hull("abs_tanp", a, b).hi)
                v = v + pm(wv * self.tilt.hull("abs_tanr", a, b).hi)
            out["u" + key] = u
            out["v" + key] = v
        return out

    def _three_d(self, ch: str, lp: LevelPlan, tau: np.ndarray) -> IA:
        ag, veh = self.ag, self.veh
        assert ag.att_roll is not None and ag.att_pitch is not None
        h = ag.att_bound
        earth = pm(EARTH_RATE + veh.max_speed / R_EARTH)
        r1 = IA(ag.att_roll[lp.i] - h, ag.att_roll[lp.i] + h)
        r2 = IA(ag.att_roll[lp.j] - h, ag.att_roll[lp.j] + h)
        p1 = IA(ag.att_pitch[lp.i] - h, ag.att_pitch[lp.i] + h)
        p2 = IA(ag.att_pitch[lp.j] - h, ag.att_pitch[lp.j] + h)
        supp = lp.b2 - lp.a1
        if ch == "gyro_x":
            # p = roll' + psi' sin(pitch)
            psid = _up(self.psi_dot_abs(lp.a1, lp.b2) * supp / tau)
            sp = self.tilt.hull("abs_sinp", lp.a1, lp.b2).hi
            return (r2 - r1) / IA(tau) + pm(psid * sp) + earth
        q = self._q_mean(lp, tau, p1, p2)
        if ch == "gyro_y":
            return q + earth
        # accel_z = p v - q u + g cos(roll) cos(pitch)   (ground: w = 0)
        bv = self.body_velocity()
        rng = self._ranges(lp, bv)
        u0 = 0.5 * (rng["u_lo"] + rng["u_hi"])
        du = _up(0.5 * (rng["u_hi"] - rng["u_lo"]))
        qu = IA(u0) * q + pm(du * self.kernel_mag("gyro_y", lp, tau))
        pv = pm(rng["v_max"] * self.kernel_mag("gyro_x", lp, tau))
        grav = self.tilt.kmean("g_cosr_cosp", lp, tau)
        x = pv - qu + grav + pm(2 * EARTH_RATE * veh.max_speed)
        if veh.kind != "ground":
            x = x + pm(veh.max_accel * supp / tau)
        return x

    def _q_mean(self, lp: LevelPlan, tau: np.ndarray, p1: IA, p2: IA) -> IA:
        """Kernel mean of q = -pitch' cos(roll) + psi' cos(pitch) sin(roll) (FLU body, pitch
        positive nose up: a nose-up pitch rate is a negative rate about body y)."""
        c = self.tilt.hull("cosr", lp.a1, lp.b2)
        c0 = c.mid()
        cdev = _up(np.maximum(c.hi - c0, c0 - c.lo))
        supp = lp.b2 - lp.a1
        rate = _up(self.veh.max_rate * supp / tau)
        psid = _up(self.psi_dot_abs(lp.a1, lp.b2, own_q=False) * supp / tau)
        sr = self.tilt.hull("abs_sinr", lp.a1, lp.b2).hi
        return (p1 - p2) / IA(tau) * IA(c0) + pm(rate * cdev) + pm(psid * sr)

    def _vehicle_bound(self, ch: str, lp: LevelPlan, tau: np.ndarray) -> IA:
        """Windows shorter than the aiding period: only the vehicle's bounds."""
        veh = self.veh
        n = tau.size
        if ch.startswith("gyro"):
            return pm(np.full(n, veh.max_rate))
        # |horizontal acceleration in the heading frame| <= max_accel (centripetal included)
        acc = pm(np.full(n, veh.max_accel))
        name = {"accel_x": "g_sinp", "accel_y": "g_sinr_cosp"}.get(ch, "g_cosr_cosp")
        return acc + self.tilt.kmean(name, lp, tau)

    # -- evaluation ----------------------------------------------------------------
    def evaluate(self, plan: ChannelPlan) -> ChannelMargins:
        from imubounds.dynamic.estimator.budget import UNITS

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
            x = self.aided(ch, plan, lp, tau)
            y = self.imu_mean(ch, lp, tau)
            band, band_nto = self.band(ch, lp, tau, k)
            xl = np.where(np.isfinite(x.lo), x.lo, -np.inf)
            xh = np.where(np.isfinite(x.hi), x.hi, np.inf)
            c_band = np.zeros(0)
            c_k = 0.0
            if lp.n_pairs and lp.kind == "aided":
                gc = self.ctx.level_index_changes[(ch, li)]
                c_k = self.ctx.alpha.k_level("imu_changes", gc)
                c_band = self.change_band(ch, lp, tau, c_k)
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
                )
            )
        verdict, reason, exc, n_exc = verdict_of(levels)
        if plan.reason and not levels:
            verdict, reason = "undecided", plan.reason
        return ChannelMargins(ch, UNITS[ch], plan.source, levels, verdict, reason, exc, n_exc)


@njit(cache=True)
def abs_dev_integral(
    bnd: np.ndarray,
    y: np.ndarray,
    unknown: np.ndarray,
    xmax: float,
    a: np.ndarray,
    b: np.ndarray,
    c: np.ndarray,
) -> np.ndarray:
    """Upper bounds of ``int_a^b |y - c| dt`` per window (piecewise-constant ``y`` on the
    segments ``bnd``; an unknown segment counts ``xmax + |c|``). Plain float sums
    inflated by ``(n + 2) * 2^-52`` relative for rounding."""
    out = np.empty(a.size)
    nseg = bnd.size - 1
    for w in range(a.size):
        lo = np.searchsorted(bnd, a[w], side="right") - 1
        if lo < 0:
            lo = 0
        acc = 0.0
        cnt = 0
        k = lo
        while k < nseg and bnd[k] < b[w]:
            s0 = bnd[k] if bnd[k] > a[w] else a[w]
            s1 = bnd[k + 1] if bnd[k + 1] < b[w] else b[w]
            if s1 > s0:
                v = xmax + abs(c[w]) if unknown[k] else abs(y[k] - c[w])
                acc += v * (s1 - s0)
                cnt += 1
            k += 1
        out[w] = acc * (1.0 + (cnt + 4) * 2.3e-16)
    return out


def course(ve: IA, vn: IA) -> IA:
    """Course (CCW from east) of velocity boxes, without the jump at +-pi: the narrower of
    ``atan2(vn, ve)`` and ``atan2(-vn, -ve) + pi`` (equal modulo 2 pi)."""
    from imubounds.interval import pi as ipi

    a = atan2(vn, ve)
    b = atan2(-vn, -ve) + ipi()
    use_b = (b.hi - b.lo) < (a.hi - a.lo)
    return IA(np.where(use_b, b.lo, a.lo), np.where(use_b, b.hi, a.hi))


def _perp(ch: str) -> tuple[str, str]:
    axes = ("x", "y", "z")
    kind, ax = ch.split("_")
    return tuple(f"{kind}_{a}" for a in axes if a != ax)  # type: ignore[return-value]


def _trapezoid_weights(lp: LevelPlan, tau: np.ndarray, dt: float) -> np.ndarray:
    """Sample weights of the level's shortest trapezoid kernel on a regular grid."""
    w = int(np.argmin(tau))
    a1, b1, a2, b2 = (float(x[w]) for x in (lp.a1, lp.b1, lp.a2, lp.b2))
    t_s = float(tau[w])
    n = int(math.ceil((b2 - a1) / dt)) + 2
    edges = a1 - dt + dt * np.arange(n + 1)

    def cumk(x: np.ndarray) -> np.ndarray:
        # integral of the kernel k (<= 1) from -inf to x
        l1, l2 = b1 - a1, b2 - a2
        out = np.zeros_like(x)
        r1 = np.clip(x - a1, 0, l1)
        if l1 > 0:
            out += r1 * r1 / (2 * l1)
        out += np.clip(x - b1, 0, a2 - b1)
        r2 = np.clip(x - a2, 0, l2)
        out += r2 - r2 * r2 / (2 * l2) if l2 > 0 else r2
        return out

    c = np.diff(cumk(edges)) / t_s
    return c[c > 0]
