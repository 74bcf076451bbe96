"""Clock offsets of the aiding streams against the IMU, estimated from the data.

A stream whose time stamps are late by ``L`` (stamp = true time + L) shows the vehicle's
motion ``L`` late. Its levels ``y_i`` (an angle: compass heading, GNSS course,
counter-clockwise, rad; or a speed, m/s) are compared with an IMU reference ``Y(t) =
int_0^t rho dt'`` (``rho`` the yaw rate, from the gyro z or from the lateral
acceleration over the speed ``a_y / u``; or the forward acceleration ``a_x``, whose
interval is a score test inverted over the offsets:
:mod:`~imubounds.dynamic.sensors._speed_clock`):

    y_i = s Y(t_i - L) + c(t_i) + d_i + e_i

``c`` a cubic spline with knots every :data:`KNOT_S` (the integrated bias of the
reference and its drift, the stream's constant offset), ``s`` a scale near 1, ``d_i``
the stream's bounded deterministic error (sideslip, compass deviation), ``e_i`` white
noise of the stated sigma. :func:`level_offset` profiles the weighted least squares over
``L`` (a grid of :data:`COARSE_STEP_S` over ``[-max_abs, max_abs]``, then of
:data:`GRID_STEP_S` within :data:`FINE_HALF_S` of its minimum, refined by a parabola;
``c`` and ``s`` eliminated exactly for each ``L``: Frisch-Waugh, the spline projection
does not depend on ``L``). Its standard deviation is the larger of the linearised one
``sqrt(max(1, chi2_red) / sum w J^2)`` (``J`` the detrended ``s rho(t_i - L)``, rho
averaged over +-:data:`DERIV_HALF_S`) and a
heteroscedasticity-and-autocorrelation-consistent one (Bartlett weights over one knot
span: the reference's coloured errors that the spline leaves); the deterministic error
moves the estimate by at most ``2 sum w |J| D_i / sum w J^2``. The interval is
``offset +- (k sd + det + grid step)`` (:meth:`OffsetEstimate.finalize`). True time =
stamp - ``offset_s``.

The lateral acceleration over the speed is the better yaw-rate reference on the
simulator's MTx-grade IMU (its integral is about ten times closer to the true heading
change over 1-10 s than the gyro's, whose bias wanders by 1 deg/s): for the GNSS course
it is exact kinematics (the course turns at ``a_perp / |v|``); for a compass heading the
sideslip enters as a level error within ``asin(v_lat / u)`` (the deterministic part).
Each stream takes the reference whose interval is narrower.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from imubounds.dynamic.sensors import _course_check as CC

GRID_STEP_S = 0.0025
MAX_OFFSET_S = 1.0
COARSE_STEP_S = 0.05
FINE_HALF_S = 0.05
#: knot spacing (s) of the spline that takes the reference's integrated bias and drift
KNOT_S = 10.0
#: at most this many epochs of a stream enter the fit (a faster stream is thinned)
MAX_EPOCHS = 20000
#: at most this many epochs enter the coarse grid (it finds the basin only)
COARSE_EPOCHS = 4000
#: the lateral-acceleration yaw rate ``a_y / u`` is used at speeds of at least this (m/s)
MIN_SPEED_MPS = 3.0
#: the reference's rate in dy/dL is its mean over +-this (s)
DERIV_HALF_S = 0.5
#: a fitted scale outside this range: the reference does not describe the stream
SCALE_RANGE = (0.5, 1.5)


@dataclass
class OffsetEstimate:
    """A stream's clock offset against the IMU (s): true time = stamp - ``offset_s``;
    ``sd`` its standard deviation, ``[lo, hi]`` its interval once :meth:`finalize` has
    the k of the timing family, ``allowance_s`` the offset the budget assumes when the
    estimate is not applied (0: the stamps taken as exact)."""

    offset_s: float
    sd: float
    method: str
    applied: bool
    n: int
    det_s: float = 0.0
    lo: float = float("nan")
    hi: float = float("nan")
    reason: str = ""
    allowance_s: float = 0.0
    #: the offset taken off the stamps when applied (the estimate, or 0 when the
    #: interval holds 0 within the allowance: the bound alone is applied)
    applied_s: float = 0.0
    #: the estimates against the other references (their intervals intersected)
    parts: list[OffsetEstimate] = field(default_factory=list)
    #: a score test inverted over a grid of offsets (``speed_clock.speed_offset``):
    #: ``(L, S, sd, det)`` sorted by ``L``; the interval is then the offsets not rejected
    #: (``|S| <= k sd + det``), widened to the next rejected grid point on each side
    score: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None = None
    #: not empty: the estimate rests on an assumption the data do not check, so it is
    #: reported, never applied, with this note
    report_why: str = ""
    #: not empty: the stated allowance is not tested by any other check (the heading's
    #: default clock bound where the turn test against the GNSS course lacks the power:
    #: ``clocks.allowance_untested``), so an interval that holds it is applied as a bound
    #: (its farthest end budgeted) instead of keeping the allowance
    untested_why: str = ""

    @property
    def half_s(self) -> float:
        return 0.5 * (self.hi - self.lo)

    def finalize(self, k: float, allowance_s: float | None = 0.0) -> None:
        """The interval ``offset +- (k sd + det_s + grid step)`` and whether to apply it:
        applied when it is narrower than the stated allowance ``allowance_s`` (the
        default heading clock bound; 0 for the GNSS and body velocity, whose stamps are
        otherwise taken as exact) or when it excludes the allowance (the data contradict
        it): the stamps are then shifted by ``offset_s`` and the half-width budgeted.
        Otherwise the allowance stays (the estimate is reported). ``allowance_s`` None:
        a diagnostic, never applied (the stamps taken as exact)."""
        report_only = allowance_s is None or bool(self.report_why)
        allowance_s = 0.0 if allowance_s is None else allowance_s
        half = k * self.sd + self.det_s + GRID_STEP_S
        self.lo, self.hi = self.offset_s - half, self.offset_s + half
        if self.score is not None:
            self.lo, self.hi = score_interval(self.score, k)
        for p in self.parts:
            ph = k * p.sd + p.det_s + GRID_STEP_S
            self.lo, self.hi = max(self.lo, p.offset_s - ph), min(self.hi, p.offset_s + ph)
        self.allowance_s = allowance_s
        if not self.lo <= self.offset_s <= self.hi:
            # the references disagree (beyond their intervals): keep the allowance
            self.lo = min(self.lo, self.offset_s)
            self.hi = max(self.hi, self.offset_s)
            self.applied = False
            self.reason = ("not applied: the references' intervals do not overlap at the "
                           "estimate; the allowance stays")
            return
        half = max(self.hi - self.offset_s, self.offset_s - self.lo)
        b = allowance_s
        if report_only:
            self.applied = False
            self.reason = self.report_why or ("reported, not applied: the stamps are taken "
                                              "as exact (an assumption)")
        elif self.at_edge:
            self.applied = False
            what = (f"the allowance (+-{b:g} s) stays" if b > 0
                    else "the stamps are taken as exact (an assumption)")
            self.reason = (f"not applied: the data do not bound the offset within the "
                           f"offsets tried (+-{MAX_OFFSET_S:g} s: too few speed changes); "
                           f"{what}")
        elif max(-self.lo, self.hi) < b and self.lo <= 0.0 <= self.hi:
            # the data bound the offset within the allowance and hold 0: the stamps
            # stay (shifting them would split the epochs shared with other streams),
            # the bound shrinks to the interval's farthest end
            self.applied, self.applied_s = True, 0.0
            self.reason = (f"applied as a bound: the interval holds 0 and lies within "
                           f"+-{max(-self.lo, self.hi):.3f} s, inside the stated allowance "
                           f"(+-{b:g} s); the stamps stay, that bound is budgeted")
        elif half < b:
            self.applied, self.applied_s = True, self.offset_s
            self.reason = (f"applied: the interval (+-{half:.3f} s) is narrower than the "
                           f"stated allowance (+-{b:g} s); its half-width is budgeted")
        elif self.lo > b or self.hi < -b:
            self.applied, self.applied_s = True, self.offset_s
            self.reason = (f"applied: the data put the offset outside the stated allowance "
                           f"(+-{b:g} s); the interval's half-width (+-{half:.3f} s) is "
                           "budgeted")
        elif self.untested_why and max(-self.lo, self.hi) <= MAX_OFFSET_S:
            # the allowance is an assumption nothing else tests: the data's bound replaces it
            self.applied, self.applied_s = True, 0.0
            self.reason = (f"applied as a bound: the interval [{self.lo:+.3f}, {self.hi:+.3f}] s "
                           f"holds the stated allowance (+-{b:g} s), which {self.untested_why}; "
                           f"the stamps stay, +-{max(-self.lo, self.hi):.3f} s is budgeted")
        else:
            self.applied = False
            what = (f"the allowance (+-{b:g} s) stays" if b > 0
                    else "the stamps are taken as exact (an assumption)")
            self.reason = (f"not applied: the interval (+-{half:.3f} s) holds the stated "
                           f"allowance (+-{b:g} s); {what}")
            if self.untested_why:
                self.reason += (f", which {self.untested_why}, and the data do not bound the "
                                f"offset within +-{MAX_OFFSET_S:g} s: the guarantee is withdrawn")

    @property
    def at_edge(self) -> bool:
        """A score-test interval that reaches the end of the offsets tried (+-
        :data:`MAX_OFFSET_S`): the data do not bound the offset there."""
        return self.score is not None and (self.lo <= float(self.score[0][0])
                                           or self.hi >= float(self.score[0][-1]))

    @classmethod
    def stated(cls, offset_s: float, bound_s: float) -> OffsetEstimate:
        """An offset stated in drive.yaml (applied; the bound budgeted)."""
        return cls(offset_s, 0.0, "drive.yaml", True, 0, 0.0, offset_s - bound_s,
                   offset_s + bound_s, "stated in drive.yaml: applied, the bound budgeted",
                   bound_s, offset_s)

    @property
    def remainder_s(self) -> float:
        """The offset the budget carries (s): the interval's half-width once applied; the
        allowance otherwise."""
        if not self.applied:
            return self.allowance_s
        return max(self.hi - self.applied_s, self.applied_s - self.lo)

    def to_dict(self) -> dict[str, Any]:
        return {
            "offset_s": self.applied_s if self.applied else 0.0,
            "estimate_s": self.offset_s,
            "interval_s": [self.lo, self.hi],
            "method": self.method,
            "applied": self.applied,
            "remainder_s": self.remainder_s,
            "sd_s": self.sd,
            "deterministic_s": self.det_s,
            "epochs": self.n,
            "note": self.reason,
        }


def score_interval(
    score: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray], k: float
) -> tuple[float, float]:
    """The offsets a score test does not reject at ``k``: ``|S(L)| <= k sd(L) + det(L)``
    on the grid ``L``; the interval runs from the last rejected grid point below the
    first accepted one to the first rejected one above the last accepted one (the ends
    of the grid when none: the offset is not bounded within them). None accepted: the
    whole grid (the reference does not describe the stream at any offset)."""
    L, S, sd, det = score
    ok = np.abs(S) <= k * sd + det
    if not ok.any():
        return float(L[0]), float(L[-1])
    i = np.flatnonzero(ok)
    return float(L[max(int(i[0]) - 1, 0)]), float(L[min(int(i[-1]) + 1, L.size - 1)])


def imu_yaw_angle(
    imu_t: np.ndarray, gyro_z: np.ndarray, stamp: str
) -> tuple[np.ndarray, np.ndarray]:
    """(t, G(t)): the integrated yaw rate at the sample ends (rad)."""
    te, _ = _sample_ends(imu_t, stamp)
    return te, _integral(imu_t, gyro_z)


def _sample_ends(imu_t: np.ndarray, stamp: str) -> tuple[np.ndarray, float]:
    t = np.asarray(imu_t, dtype=float)
    d0 = _median_step(t)
    shift = {"end": 0.0, "centre": 0.5 * d0, "start": d0}.get(stamp, 0.0)
    return (t + shift if shift else t), d0


#: samples per chunk of the passes over the IMU (:func:`_integral` and its kin): their
#: temporaries stay small on a long trip (a 24 h trip at 100 Hz is 8.64 M samples)
CHUNK = 1 << 18


def _median_step(t: np.ndarray) -> float:
    """The median of ``diff(t)`` (0 for fewer than two samples)."""
    if t.size < 2:
        return 0.0
    return float(np.median(np.diff(t), overwrite_input=True))


def _integral(
    imu_t: np.ndarray, rate: np.ndarray, ok: np.ndarray | None = None
) -> np.ndarray:
    """``cumsum(nan_to_num(rate) x [d0, diff(t)])`` (``d0`` the median step; the rate
    taken as 0 where ``ok`` is False): chunk by chunk into one array, the additions in
    the order of one pass (the values are those of one pass, bit for bit)."""
    t = np.asarray(imu_t, dtype=float)
    r = np.asarray(rate, dtype=float)
    n = t.size
    d0 = _median_step(t)
    out = np.empty(n)
    carry = 0.0
    for a in range(0, n, CHUNK):
        b = min(n, a + CHUNK)
        g = np.nan_to_num(r[a:b] if ok is None else np.where(ok[a:b], r[a:b], 0.0))
        seg = out[a:b]
        if a == 0:
            seg[0] = d0
            np.subtract(t[1:b], t[: b - 1], out=seg[1:])
        else:
            np.subtract(t[a:b], t[a - 1 : b - 1], out=seg)
        seg *= g
        seg[0] += carry
        np.cumsum(seg, out=seg)
        carry = float(seg[-1])
    return out


def _window_max(
    x: np.ndarray, idx: np.ndarray, half: int, chunk: int = 4096
) -> tuple[np.ndarray, np.ndarray]:
    """(max, min) of ``x`` over ``[i - half, i + half]`` (clipped to the array: the
    ``maximum_filter1d`` / ``minimum_filter1d`` of size ``2 half + 1``, mode nearest) at
    the indices ``idx`` only."""
    hi = np.empty(idx.shape)
    lo = np.empty(idx.shape)
    offs = np.arange(-half, half + 1)
    for a in range(0, idx.size, chunk):
        w = x[(idx[a : a + chunk, None] + offs[None, :]).clip(0, x.size - 1)]
        hi[a : a + chunk] = w.max(axis=1)
        lo[a : a + chunk] = w.min(axis=1)
    return hi, lo


class _Detrend:
    """The weighted least-squares residual of a cubic spline with knots every
    :data:`KNOT_S` at fixed epochs (knots on epochs, so every span holds data): the
    design matrix and the banded Cholesky factor of its normal matrix once, then O(n)
    per residual."""

    def __init__(self, t: np.ndarray, w: np.ndarray, knot_s: float) -> None:
        from scipy.interpolate import BSpline
        from scipy.linalg import cholesky_banded

        self.w = w
        grid = np.arange(t[0] + knot_s, t[-1] - 0.5 * knot_s, knot_s)
        idx = np.unique(np.searchsorted(t, grid))
        keep: list[int] = []
        last = 0
        for i in idx:  # at least 5 epochs between knots (Schoenberg-Whitney)
            if i - last >= 5 and t.size - 1 - i >= 5:
                keep.append(int(i))
                last = int(i)
        inner = t[keep]
        knots = np.r_[[t[0]] * 4, inner, [t[-1]] * 4]
        self.B = BSpline.design_matrix(t, knots, 3).tocsr()
        self.p = int(self.B.shape[1])
        N = (self.B.T.multiply(w) @ self.B).tocoo()
        ab = np.zeros((4, self.p))
        up = N.col >= N.row
        ab[3 + N.row[up] - N.col[up], N.col[up]] = N.data[up]
        self.cb = cholesky_banded(ab, lower=False)

    def __call__(self, z: np.ndarray) -> np.ndarray:
        from scipy.linalg import cho_solve_banded

        coef = cho_solve_banded((self.cb, False), self.B.T @ (self.w * z))
        return np.asarray(z - self.B @ coef)


def level_offset(
    t: np.ndarray,
    y: np.ndarray,
    sigma: np.ndarray | float,
    imu_t: np.ndarray,
    rho: np.ndarray,
    method: str,
    det: np.ndarray | float = 0.0,
    valid: np.ndarray | None = None,
    max_abs: float = MAX_OFFSET_S,
    knot_s: float = KNOT_S,
    noise: Any = None,
    gain: np.ndarray | float = 1.0,
) -> OffsetEstimate | None:
    """The clock offset of a stream of levels ``y`` at ``t`` (sigma, deterministic bound
    ``det`` per epoch) against the IMU rate ``rho`` at ``imu_t`` (the sample ends): see
    the module docstring. None when too few epochs or the reference does not move enough
    (or its fitted scale is outside :data:`SCALE_RANGE`) to tell. ``noise`` (a
    :class:`~imubounds.dynamic.estimator.budget.ChannelNoise`) is the stated noise of the
    IMU channel whose samples times ``gain`` make ``rho``: the estimate's variance then
    includes what that noise does to it (:func:`_reference_variance`)."""
    prep = _prepare(t, y, sigma, det, imu_t, rho, valid, max_abs)
    if prep is None:
        return None
    t, y, sig, dd, it, Y = prep
    w = 1.0 / sig**2
    P = _Detrend(t, w, knot_s)
    if t.size - P.p - 1 < 10:
        return None
    fit = _profile(t, y, w, it, Y, P)
    # the coarse grid on at most COARSE_EPOCHS epochs (the basin), the fine one on all
    sub = np.unique(np.linspace(0, t.size - 1, min(t.size, COARSE_EPOCHS)).astype(int))
    cfit = fit if sub.size == t.size else _profile(
        t[sub], y[sub], w[sub], it, Y, _Detrend(t[sub], w[sub], knot_s))
    coarse = np.arange(-max_abs, max_abs + COARSE_STEP_S / 2, COARSE_STEP_S)
    c0 = float(coarse[int(np.argmin([cfit(float(L))[0] for L in coarse]))])
    for _ in range(4):  # re-centred while the minimum sits on the fine grid's edge
        grid = np.arange(c0 - FINE_HALF_S, c0 + FINE_HALF_S + GRID_STEP_S / 2, GRID_STEP_S)
        cost = np.array([fit(float(L))[0] for L in grid])
        j = int(np.argmin(cost))
        if 0 < j < grid.size - 1 or abs(float(grid[j])) >= max_abs:
            break
        c0 = float(grid[j])
    L = float(grid[j])
    if 0 < j < grid.size - 1:
        den = cost[j - 1] - 2 * cost[j] + cost[j + 1]
        if den > 0:
            L += 0.5 * GRID_STEP_S * (cost[j - 1] - cost[j + 1]) / den
    sse, sc, e = fit(L)
    if not SCALE_RANGE[0] <= sc <= SCALE_RANGE[1]:
        return None
    # dy/dL from the reference averaged over +-DERIV_HALF_S (its noise would otherwise
    # add to sum w J^2 information that the timing does not have)
    h = DERIV_HALF_S
    J = sc * P((np.interp(t - L + h, it, Y) - np.interp(t - L - h, it, Y)) / (2 * h))
    info = float(np.sum(w * J * J))
    if not info > 0:
        return None
    chi2_red = sse / max(t.size - P.p - 1, 1)
    var = max(1.0, chi2_red) / info
    # HAC (Bartlett over one knot span): the reference's coloured errors
    u = w * J * e
    band = max(1, int(round(knot_s / max(float(np.median(np.diff(t))), 1e-9))))
    S = float(np.sum(u * u))
    for lag in range(1, min(band, u.size - 1) + 1):
        S += 2.0 * (1.0 - lag / (band + 1)) * float(np.sum(u[lag:] * u[:-lag]))
    var = max(var, S / info**2)
    if noise is not None:
        # the stated noise of both sides: the stream's (white, stated sigma) and the
        # reference's through the estimate's kernel on the IMU samples
        ref_var = _reference_variance(t - L, w * J * sc, it, noise, gain)
        var = max(var, 1.0 / info + ref_var / info**2)
    # J is orthogonal to the spline: <J, P d> = <J, d>, so |dL| <= sum w |J| D / info
    det_s = float(np.sum(w * np.abs(J) * dd)) / info
    return OffsetEstimate(L, math.sqrt(var), method, False, int(t.size), det_s)


def _prepare(
    t: np.ndarray, y: np.ndarray, sigma: np.ndarray | float, det: np.ndarray | float,
    imu_t: np.ndarray, rho: np.ndarray, valid: np.ndarray | None, max_abs: float,
) -> tuple[np.ndarray, ...] | None:
    """The epochs of a stream that enter the fit, ``(t, y, sigma, det, imu_t, Y)`` with
    ``Y`` the integrated rate: finite, ``valid``, their reference window (+-``max_abs``)
    inside the IMU and its finite rate, at most :data:`MAX_EPOCHS` (a faster stream is
    thinned); None when fewer than 20 or not increasing."""
    t = np.asarray(t, dtype=float)
    y = np.asarray(y, dtype=float)
    sig = np.broadcast_to(np.asarray(sigma, dtype=float), t.shape)
    dd = np.broadcast_to(np.asarray(det, dtype=float), t.shape)
    it = np.asarray(imu_t, dtype=float)
    r = np.asarray(rho, dtype=float)
    ok = np.isfinite(r)
    if it.size < 10 or ok.sum() < 10:
        return None
    Y = _integral(it, r, ok)
    # epochs whose reference window (+-max_abs) lies inside the IMU and its finite rate
    bad = np.flatnonzero(~ok)  # the count of bad samples before i: searchsorted(bad, i)
    del ok
    lo_i = np.searchsorted(it, t - max_abs - 1e-9)
    hi_i = np.searchsorted(it, t + max_abs + 1e-9)
    inside = (t - max_abs > it[0]) & (t + max_abs < it[-1])
    inside &= (np.searchsorted(bad, hi_i.clip(0, it.size))
               - np.searchsorted(bad, lo_i.clip(0, it.size))) == 0
    del bad
    m = inside & np.isfinite(y) & np.isfinite(sig) & (sig > 0)
    if valid is not None:
        m &= np.asarray(valid, dtype=bool)
    t, y, sig, dd = t[m], y[m], sig[m], dd[m]
    if t.size > MAX_EPOCHS:
        keep = np.linspace(0, t.size - 1, MAX_EPOCHS).astype(int)
        t, y, sig, dd = t[keep], y[keep], sig[keep], dd[keep]
    if t.size < 20 or np.any(np.diff(t) <= 0):
        return None
    return t, y, sig, dd, it, Y


def _profile(
    t: np.ndarray, y: np.ndarray, w: np.ndarray, it: np.ndarray, Y: np.ndarray, P: _Detrend
) -> Callable[[float], tuple[float, float, np.ndarray]]:
    """``L -> (weighted SSE, scale, residual)`` of ``y`` against ``s Y(t - L)`` with the
    spline and the scale eliminated (Frisch-Waugh)."""
    yt = P(y)

    def fit(L: float) -> tuple[float, float, np.ndarray]:
        Yt = P(np.interp(t - L, it, Y))
        a, b = float(np.sum(w * yt * Yt)), float(np.sum(w * Yt * Yt))
        sc = a / b if b > 0 else 0.0
        e = yt - sc * Yt
        return float(np.sum(w * e * e)), sc, e

    return fit


def _reference_variance(
    tq: np.ndarray, wj: np.ndarray, it: np.ndarray, noise: Any, gain: np.ndarray | float
) -> float:
    """Variance of ``sum_i wj_i dY(tq_i)``, ``dY(t) = sum_{t_k <= t} gain_k n_k dt`` the
    integrated noise of the reference (stated budget, :func:`~imubounds.dynamic.
    estimator.budget.kernel_variance`; a constant bias cancels: ``sum wj = 0``)."""
    from imubounds.dynamic.estimator.budget import kernel_variance

    dt = _median_step(it)
    idx = np.searchsorted(it, tq, side="right")
    A: np.ndarray = np.asarray(np.bincount(idx, weights=wj, minlength=it.size + 1), float)
    # R = the reversed cumulative sum of A without its first (the sum over the epochs
    # after sample k), times gain x dt: in place, chunk by chunk from the end
    g = np.broadcast_to(np.asarray(gain, float), it.shape)
    carry = 0.0
    n = A.size
    for b in range(n, 0, -CHUNK):
        a = max(0, b - CHUNK)
        seg = A[a:b][::-1]
        seg[0] += carry
        np.cumsum(seg, out=seg)
        carry = float(seg[-1])
    R = A[1:]
    for a in range(0, R.size, CHUNK):
        seg = R[a : a + CHUNK]
        seg *= np.nan_to_num(g[a : a + CHUNK])
        seg *= dt
    return float(kernel_variance(noise, R, dt, True))


def _speed(drive: Any) -> tuple[np.ndarray, np.ndarray] | None:
    """(t, speed m/s) of the vehicle from the GNSS velocity, else the body velocity."""
    g = drive.gnss
    v = g.velocity_ne() if g is not None else None
    if v is not None:
        sp = np.hypot(v[0], v[1])
        ok = np.isfinite(sp)
        if ok.sum() >= 10:
            return np.asarray(g.t, float)[ok], sp[ok]
    bv = drive.velocity
    if bv is not None:
        u = np.abs(np.asarray(bv.u_mps, float))
        ok = np.isfinite(u)
        if ok.sum() >= 10:
            return np.asarray(bv.t, float)[ok], u[ok]
    return None


@dataclass
class _Reference:
    """An IMU rate reference: ``rho = gain x channel`` at the sample ends ``t``."""

    name: str
    t: np.ndarray
    rho: np.ndarray
    channel: str
    gain: np.ndarray | float = 1.0


def yaw_references(drive: Any, stamp: str) -> list[_Reference]:
    """The IMU yaw-rate references: the gyro z, and the lateral acceleration over the
    speed (NaN below :data:`MIN_SPEED_MPS`) where a speed exists."""
    imu = drive.imu
    if imu is None or imu.t.size < 10:
        return []
    te, _ = _sample_ends(imu.t, stamp)
    out: list[_Reference] = []
    gz = np.asarray(imu.gyro[:, 2], float)
    if np.isfinite(gz).all():
        out.append(_Reference("gyro z", te, gz, "gyro_z"))
    sp = _speed(drive)
    acc = getattr(imu, "accel", None)
    if sp is not None and acc is not None:
        gain = np.interp(te, sp[0], sp[1], left=np.nan, right=np.nan)  # the speed
        slow = ~(gain >= MIN_SPEED_MPS)
        with np.errstate(invalid="ignore", divide="ignore"):
            np.divide(1.0, gain, out=gain)
        gain[slow] = np.nan
        del slow
        rho = np.asarray(acc[:, 1], float) * gain
        out.append(_Reference("lateral acceleration / speed", te, rho, "accel_y", gain))
    return out


def _fit_refs(
    refs: list[_Reference], noise: dict[str, Any] | None, what: str, t: np.ndarray,
    y: np.ndarray, sig: np.ndarray | float, det_of: Any,
) -> OffsetEstimate | None:
    """The offset against each reference (``det_of(ref)`` its deterministic bound, None
    to skip it), combined by :func:`combine`."""
    ests: list[OffsetEstimate] = []
    for ref in refs:
        det = det_of(ref)
        if det is None:
            continue
        cn = None if noise is None else noise.get(ref.channel)
        e = level_offset(t, y, sig, ref.t, ref.rho, f"{what} against the integrated "
                         f"{ref.name}", det=det, noise=cn, gain=ref.gain)
        if e is not None:
            ests.append(e)
    return combine(ests)


def combine(ests: list[OffsetEstimate]) -> OffsetEstimate | None:
    """One estimate from several references: the point of the most precise (smallest
    sd), the interval the intersection of theirs (:meth:`OffsetEstimate.finalize`, with
    the timing family's k counting every reference)."""
    if not ests:
        return None
    best = min(ests, key=lambda e: e.sd)
    out = OffsetEstimate(best.offset_s, best.sd, best.method, False, best.n, best.det_s)
    out.parts = [e for e in ests if e is not best]
    return out


def estimate_gnss(
    drive: Any, stamp: str, noise: dict[str, Any] | None = None
) -> OffsetEstimate | None:
    """The GNSS's clock offset against the IMU: its course (from the receiver's
    velocity, else from chords of fixes) at speeds of at least
    :data:`~imubounds.dynamic.sensors._compass.COURSE_CHECK_MIN_SPEED`, against the
    lateral acceleration over the speed (exact kinematics: no deterministic term) and
    the gyro z (the sideslip, bounded by asin(lateral bound / speed), its deterministic
    error; not without a lateral bound)."""
    from imubounds.dynamic.sensors._course_check import COURSE_CHECK_MIN_SPEED, course_noise

    if drive.gnss is None:
        return None
    gc = course_noise(drive, COURSE_CHECK_MIN_SPEED)
    if gc is None:
        return None
    tc, course, sc, v_lo = gc
    lat = drive.settings.vehicle.lateral_speed_bound_mps
    how = "velocity" if drive.gnss.velocity_ne() is not None else "chords of fixes"

    def det_of(ref: _Reference) -> Any:
        if ref.channel != "gyro_z":
            return 0.0
        if lat is None:
            return None
        return np.arcsin(np.minimum(1.0, lat / np.maximum(v_lo, 1e-9)))

    return _fit_refs(yaw_references(drive, stamp), noise, f"GNSS course ({how})", tc,
                     np.unwrap(-np.asarray(course, float)), sc, det_of)


def estimate_heading(
    drive: Any, stamp: str, heading: Any, noise: dict[str, Any] | None = None
) -> OffsetEstimate | None:
    """The heading sensor's clock offset against the IMU, from the corrected heading (a
    :class:`~imubounds.dynamic.sensors.heading.HeadingInput`), against the
    gyro z (its deviation bound the deterministic error) and the lateral acceleration
    over the speed (+ the sideslip bound asin(lateral bound / speed), a level error that
    turns with the vehicle; not without a lateral bound). None for an AHRS yaw."""
    h = heading
    if h is None or not h.independent_of_imu or h.t.size < 20:
        return None
    sig = float(h.noise_sigma_rad) * float(h.noise_gain)
    dev = float(h.deviation_bound_rad)
    lat = drive.settings.vehicle.lateral_speed_bound_mps
    sp = _speed(drive)

    def det_of(ref: _Reference) -> Any:
        if ref.channel == "gyro_z":
            return dev
        if lat is None or sp is None:
            return None
        u = np.interp(h.t, sp[0], sp[1])
        return dev + np.arcsin(np.minimum(1.0, lat / np.maximum(u, 1e-9)))

    return _fit_refs(yaw_references(drive, stamp), noise, "heading", h.t,
                     np.unwrap(-np.asarray(h.heading_rad, float)), sig, det_of)


def shifted(obj: Any, name: str | None, est: OffsetEstimate) -> Any:
    """A shallow copy of ``obj`` (a drive with stream ``name``, or a stream when ``name``
    is None) with an applied offset taken off the time stamps (true time = stamp -
    offset)."""
    import dataclasses

    if not est.applied:
        return obj
    if name is None:
        return dataclasses.replace(obj, t=obj.t - est.applied_s)
    stream = getattr(obj, name)
    return dataclasses.replace(obj, **{name: shifted(stream, None, est)})


#: the alpha plan's family whose Bonferroni count an applied offset's intervals join
#: (the bound it rests on fails with them); the body velocity's bound is stated, not
#: drawn from the plan: its offset joins the IMU intervals (the test's variance is
#: mostly the integrated accel_x noise)
ALPHA_FAMILY: dict[str, str | None] = {"gnss": "gnss_position", "heading": "heading",
                                       "velocity": "imu_intervals"}


def apply_offsets(
    drive: Any, timing: dict[str, OffsetEstimate], k_of: Callable[[str, int], float]
) -> tuple[Any, bool]:
    """Finalize the estimated offsets (``k_of(stream, n_intervals)`` their k; the heading
    against the default clock allowance, the GNSS and the body velocity against exact
    stamps: applied when their interval excludes 0 and is bounded) and take the applied
    ones off the drive's stamps (the heading: its compass and magnetometer streams):
    (drive, whether any stream moved)."""
    allowance = {"gnss": 0.0, "heading": DEFAULT_HEADING_CLOCK_BOUND_S, "velocity": 0.0}
    moved = False
    for name, est in timing.items():
        if est.method == "drive.yaml" or name not in allowance:
            continue
        est.finalize(k_of(name, 1 + len(est.parts)), allowance[name])
        if not est.applied or est.applied_s == 0.0:
            continue
        moved = True
        for stream in ("heading", "mag") if name == "heading" else (name,):
            if getattr(drive, stream, None) is not None:
                drive = shifted(drive, stream, est)
    return drive, moved


def heading_clock_bound_s(timing: dict[str, OffsetEstimate]) -> float:
    """The heading clock bound the turn allowance budgets: the remainder of an applied
    estimate, else :data:`DEFAULT_HEADING_CLOCK_BOUND_S`."""
    h = timing.get("heading")
    if h is not None and h.method != "drive.yaml" and h.applied:
        return h.remainder_s
    return DEFAULT_HEADING_CLOCK_BOUND_S


def heading_clock_assumption(timing: dict[str, OffsetEstimate]) -> str:
    """The ``assumptions`` line of the heading clock (estimate applied or the default)."""
    h = timing.get("heading")
    how = ("budgeted as the largest turn the gyro z measures within that bound of each "
           "epoch (+ the bound of its error)")
    if h is not None and h.method != "drive.yaml" and h.applied:
        return (f"heading clock: offset {h.offset_s:+.3f} s estimated from the data "
                f"({h.method}), {h.applied_s:+.3f} s taken off the stamps; the true offset within "
                f"[{h.lo:+.3f}, {h.hi:+.3f}] s, the remainder +-{h.remainder_s:.3f} s {how}")
    return (f"heading clock: the heading stream's stamps within "
            f"+-{DEFAULT_HEADING_CLOCK_BOUND_S:g} s of the IMU's (default; "
            f"heading.time_offset_s / time_offset_bound_s state it), {how}; a larger "
            "offset is tested by the check against the GNSS course in the turns")


def budget_timing(ag: Any, veh: Any, timing: dict[str, OffsetEstimate]) -> None:
    """What remains of an applied clock offset, times the stream's rate bound, added to
    its intervals: GNSS position + v_max dt, velocity + a_max dt (and a heading from the
    GNSS course + r_max dt), a stated heading offset + r_max dt, body velocity + a_max
    dt. An estimated heading offset: its remainder is the turn allowance's bound
    (:func:`heading_clock_bound_s`)."""
    g = timing.get("gnss")
    if g is not None and g.applied and g.remainder_s > 0 and ag.has_gnss:
        dtr = g.remainder_s
        ag.gnss_h = ag.gnss_h + dtr * veh.max_speed
        ag.gnss_det += dtr * veh.max_speed
        if ag.has_gvel:
            ag.gvel_hi = ag.gvel_hi + dtr * veh.max_accel
            ag.gvel_h += dtr * veh.max_accel
            ag.gvel_det += dtr * veh.max_accel
        if ag.has_heading and ag.head_from_course:
            # the heading from the GNSS course turns with the vehicle: + r_max dt
            ag.head_h = ag.head_h + dtr * veh.max_rate
    h = timing.get("heading")
    if (h is not None and h.method == "drive.yaml" and h.remainder_s > 0
            and ag.has_heading):
        ag.head_h = ag.head_h + h.remainder_s * veh.max_rate
        ag.head_det += h.remainder_s * veh.max_rate
    v = timing.get("velocity")
    if v is not None and v.applied and v.remainder_s > 0 and ag.has_bvel:
        ag.bvel_h = ag.bvel_h + v.remainder_s * veh.max_accel


#: the stated bound (s) on an undeclared clock offset of the heading stream against the
#: IMU (drive.yaml heading.time_offset_s / time_offset_bound_s replace it); a larger
#: offset is what the check against the GNSS course in the turns tests
DEFAULT_HEADING_CLOCK_BOUND_S = CC.DEFAULT_HEADING_CLOCK_BOUND_S
#: half-length (s) of the window around each heading epoch over which the gyro z bias is
#: taken from the heading stream itself (:func:`local_swing`)
LOCAL_BIAS_HALF_S = 10.0


def rate_allowance(
    tq: np.ndarray,
    imu_t: np.ndarray,
    rate: np.ndarray,
    bound_s: float,
    err_rad: float,
    rate_max: float,
    scale: float = 0.0,
) -> np.ndarray:
    """The change of an angle over a clock offset ``|L| <= bound_s`` at the times ``tq``
    (rad): ``(1 + scale) max |G(s) - G(t)| + err_rad`` over the IMU samples ``s`` within
    ``bound_s`` (and one sample) of ``t``, ``G`` the integrated measured rate, ``err_rad``
    the bound of the integral's error over ``bound_s`` (bias x bound + k white noise);
    at most ``bound_s x rate_max``. Only the turns are widened: the gyro measures the
    turn around each epoch."""
    it = np.asarray(imu_t, dtype=float)
    tq = np.asarray(tq, dtype=float)
    cap = bound_s * rate_max
    if it.size < 2 or tq.size == 0 or bound_s <= 0:
        return np.zeros(tq.shape)
    dt = _median_step(it)
    half = int(math.ceil(bound_s / max(dt, 1e-9))) + 1
    r = np.asarray(rate, dtype=float)
    G = _integral(it, r)  # cumsum(nan_to_num(rate) x [dt, diff(t)])
    i = np.searchsorted(it, tq).clip(0, it.size - 1)
    j = (i - 1).clip(0, it.size - 1)
    # the running max / min of G over +-half samples, at i and j only
    gmax_i, gmin_i = _window_max(G, i, half)
    gmax_j, gmin_j = _window_max(G, j, half)
    g = np.interp(tq, it, G)
    del G
    swing = np.maximum(np.maximum(gmax_i, gmax_j) - g, g - np.minimum(gmin_i, gmin_j))
    out = np.minimum((1.0 + scale) * swing + err_rad, cap)
    # outside the IMU's span or where the rate is not finite: the vehicle's bound
    bad = (tq < it[0]) | (tq > it[-1])
    nonfin = np.flatnonzero(~np.isfinite(r))
    if nonfin.size:
        # a non-finite rate within +-half samples of i or j
        for q in (i, j):
            bad |= (np.searchsorted(nonfin, q + half, side="right")
                    - np.searchsorted(nonfin, q - half)) > 0
    return np.asarray(np.where(bad, cap, out))


def local_windows(th: np.ndarray, half_s: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For each heading epoch, the heading epochs ``(ja, jb)`` that end a window of about
    ``2 half_s`` holding it (shifted inside the stream at its ends), and whether the
    window is usable: its length within 10 % of ``2 half_s`` (no gap)."""
    th = np.asarray(th, dtype=float)
    n = th.size
    if n < 2 or th[-1] - th[0] < 2 * half_s:
        z = np.zeros(n, dtype=int)
        return z, z, np.zeros(n, dtype=bool)
    start = np.clip(th - half_s, th[0], th[-1] - 2 * half_s)
    ja = np.searchsorted(th, start).clip(0, n - 1)
    jb = np.searchsorted(th, start + 2 * half_s).clip(0, n - 1)
    T = th[jb] - th[ja]
    ok = np.abs(T - 2 * half_s) <= 0.2 * half_s
    return ja, jb, ok


def local_swing(
    th: np.ndarray,
    hc: np.ndarray,
    hh: np.ndarray,
    imu_t: np.ndarray,
    G: np.ndarray,
    bound_s: float,
    half_s: float,
    rate_max: float,
    scale: float,
    chunk: int = 20000,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(largest turn within ``bound_s`` of each heading epoch, bias error x bound_s,
    usable) with the gyro z bias taken from the heading stream over a window of about
    ``2 half_s`` around the epoch (:func:`local_windows`): ``b = (dG - dh) / T`` over the
    window's ends, ``G`` the integrated measured rate (rad, at ``imu_t``), ``hc`` the
    heading (rad, counter-clockwise, unwrapped) of half-width ``hh``. The turn is
    ``(1 + scale) max |G(s) - G(t) - b (s - t)|`` over the IMU samples within
    ``bound_s`` (and one sample) of ``t``; the bias error ``(hh_a + hh_b + 2 bound_s
    rate_max + scale |dG|) / T`` covers the heading's errors at the window's ends (its
    clock offset included) and the gyro's scale; the gyro's noise within the window is
    the caller's (a kernel whose turn-on part cancels)."""
    th = np.asarray(th, dtype=float)
    it = np.asarray(imu_t, dtype=float)
    n = th.size
    turn = np.zeros(n)
    berr = np.zeros(n)
    ja, jb, ok = local_windows(th, half_s)
    if not ok.any() or it.size < 2:
        return turn, berr, ok
    dt = _median_step(it)
    h = int(math.ceil(bound_s / max(dt, 1e-9))) + 1
    Ga, Gb = np.interp(th[ja], it, G), np.interp(th[jb], it, G)
    T = np.maximum(th[jb] - th[ja], 1e-9)
    dG = Gb - Ga
    b = (dG - (hc[jb] - hc[ja])) / T
    berr = bound_s * (hh[ja] + hh[jb] + 2 * bound_s * rate_max + scale * np.abs(dG)) / T
    offs = np.arange(-h, h + 1)
    for a in range(0, n, chunk):
        sl = slice(a, min(n, a + chunk))
        i0 = np.searchsorted(it, th[sl])
        idx = (i0[:, None] + offs[None, :]).clip(0, it.size - 1)
        g0 = np.interp(th[sl], it, G)
        dev = G[idx] - g0[:, None] - b[sl, None] * (it[idx] - th[sl, None])
        turn[sl] = (1.0 + scale) * np.max(np.abs(dev), axis=1)
    return turn, berr, ok
