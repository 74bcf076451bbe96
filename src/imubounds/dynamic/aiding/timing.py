"""Clock offsets of the aiding streams against the IMU, estimated from the data.

A stream whose time stamps are late by ``L`` (stamp = true time + L) shows the vehicle's
turns ``L`` late. Over consecutive epochs ``t_i, t_{i+1}`` the stream's angle increment
(compass heading, GNSS course; counter-clockwise, rad) equals the integrated IMU yaw rate
over ``[t_i - L, t_{i+1} - L]`` plus a constant-rate term (the gyro's bias and the
declination drift, fitted) plus noise:

    da_i = b dt_i + G(t_{i+1} - L) - G(t_i - L) + e_i,     G(t) = int_0^t r dt'

:func:`estimate_offset` takes the ``L`` of least squares on a grid of 50 ms over
``[-max_abs, max_abs]``, then of 2.5 ms within 0.06 s of its minimum (refined by a
parabola; streams faster than 1 Hz thinned to 1 s steps), and its standard deviation from the
linearised variance ``s^2 / sum J_i^2`` (``J_i = dG_i/dL``, ``s^2`` the larger of the
stated and the fitted residual variance, doubled for the correlation of adjacent
increments) or, when larger, from a delete-a-block jackknife over 8 blocks of the trip
(the IMU's coloured errors; the blocks' minima are searched within the fine window, so
a wider spread is clipped and the sd is then a lower bound); the interval is
``offset +- (k sd + det + grid step)``, det the effect of the stream's bounded
deterministic error (sideslip, compass deviation). True time = stamp - ``offset_s``.
An estimate is reported, not applied (:meth:`OffsetEstimate.finalize`); an offset
stated in drive.yaml is applied and its bound budgeted.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

GRID_STEP_S = 0.0025
MAX_OFFSET_S = 1.0
JACKKNIFE_BLOCKS = 8
COARSE_STEP_S = 0.05
FINE_HALF_S = 0.06
#: a faster stream is thinned to epochs this far apart (s)
MIN_STEP_S = 1.0


@dataclass
class OffsetEstimate:
    """A stream's clock offset against the IMU (s): true time = stamp - ``offset_s``;
    ``sd`` its standard deviation, ``[lo, hi]`` its interval once :meth:`finalize` has
    the k of the timing family."""

    offset_s: float
    sd: float
    method: str
    applied: bool
    n: int
    det_s: float = 0.0
    lo: float = float("nan")
    hi: float = float("nan")
    reason: str = ""

    def finalize(self, k: float) -> None:
        """The interval ``offset +- (k sd + det_s + grid step)``. An estimate is a
        diagnostic: it is not applied (the clock stays an assumption), because the
        coloured errors of a MEMS gyro make its spread larger than ``sd`` says on trips
        with few turns (measured: 0.02-0.2 s off on the simulator's clean 5-min trips)."""
        half = k * self.sd + self.det_s + GRID_STEP_S
        self.lo, self.hi = self.offset_s - half, self.offset_s + half
        self.applied = False
        self.reason = (
            "estimated from the data, not applied (a diagnostic): state "
            "<stream>.time_offset_s and <stream>.time_offset_bound_s in drive.yaml to apply "
            "and budget an offset"
        )

    @classmethod
    def stated(cls, offset_s: float, bound_s: float) -> OffsetEstimate:
        """An offset stated in drive.yaml (applied; the bound budgeted)."""
        return cls(offset_s, 0.0, "drive.yaml", True, 0, 0.0, offset_s - bound_s,
                   offset_s + bound_s, "stated in drive.yaml: applied, the bound budgeted")

    @property
    def remainder_s(self) -> float:
        """The offset left after applying ``offset_s`` that the budget carries (s): the
        stated bound; 0 for an estimate that is not applied (the clock is assumed)."""
        if not self.applied:
            return 0.0
        return max(self.hi - self.offset_s, self.offset_s - self.lo)

    def to_dict(self) -> dict[str, Any]:
        return {
            "offset_s": self.offset_s if self.applied else 0.0,
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


def imu_yaw_angle(
    imu_t: np.ndarray, gyro_z: np.ndarray, stamp: str
) -> tuple[np.ndarray, np.ndarray]:
    """(t, G(t)): the integrated yaw rate at the sample ends (rad)."""
    t = np.asarray(imu_t, dtype=float)
    dt = np.diff(t)
    d0 = float(np.median(dt)) if dt.size else 0.0
    shift = {"end": 0.0, "centre": 0.5 * d0, "start": d0}.get(stamp, 0.0)
    te = t + shift
    g = np.nan_to_num(np.asarray(gyro_z, dtype=float))
    steps = np.concatenate([[d0], dt])
    return te, np.cumsum(g * steps)


def estimate_offset(
    t: np.ndarray,
    angle: np.ndarray,
    sigma: np.ndarray,
    imu_t: np.ndarray,
    imu_angle: np.ndarray,
    method: str,
    max_abs: float = MAX_OFFSET_S,
    det: np.ndarray | None = None,
) -> OffsetEstimate | None:
    """The clock offset of an angle stream (see the module docstring); None when the
    stream has too few increments or the IMU does not turn enough to tell."""
    t = np.asarray(t, dtype=float)
    a = np.unwrap(np.asarray(angle, dtype=float))
    sig = np.broadcast_to(np.asarray(sigma, dtype=float), t.shape)
    dd = np.zeros(t.shape) if det is None else np.broadcast_to(np.asarray(det, float), t.shape)
    inside = (t - max_abs > imu_t[0]) & (t + max_abs < imu_t[-1]) & np.isfinite(a)
    t, a, sig, dd = t[inside], a[inside], sig[inside], dd[inside]
    if t.size < 10:
        return None
    med = float(np.median(np.diff(t)))
    if med < MIN_STEP_S:
        # a fast stream: epochs MIN_STEP_S apart (the increments' noise does not shrink
        # with the step, their signal does: longer steps tell the offset better)
        keep = np.arange(0, t.size, int(round(MIN_STEP_S / med)))
        t, a, sig, dd = t[keep], a[keep], sig[keep], dd[keep]
        if t.size < 10:
            return None
    dt = np.diff(t)
    med = float(np.median(dt))
    ok = (dt > 0) & (dt <= 2.5 * med)
    da = np.diff(a)[ok]
    t1, t2, dt = t[:-1][ok], t[1:][ok], dt[ok]
    s2 = (sig[:-1] ** 2 + sig[1:] ** 2)[ok]
    d1 = np.maximum(dd[:-1], dd[1:])[ok]
    if da.size < 8:
        return None
    # second differences of the residual increments: a gyro bias that wanders slowly
    # (flicker) cancels with the constant one; adjacent pairs only
    adj = np.flatnonzero(np.abs(t1[1:] - t2[:-1]) < 1e-9)
    if adj.size < 8:
        return None
    w = 1.0 / (s2[adj] + s2[adj + 1])

    def resid(L: float) -> np.ndarray:
        g = np.interp(t2 - L, imu_t, imu_angle) - np.interp(t1 - L, imu_t, imu_angle)
        y = da - g
        return np.asarray(y[adj + 1] - y[adj])

    def sse_all(lag: np.ndarray) -> np.ndarray:
        return np.array([w * resid(float(L)) ** 2 for L in lag])

    def sse(lag: np.ndarray) -> np.ndarray:
        return np.asarray(sse_all(lag).sum(axis=1))

    def argmin(cost: np.ndarray) -> float:
        j = int(np.argmin(cost))
        L = float(grid[j])
        if 0 < j < grid.size - 1:
            c0, c1, c2 = cost[j - 1], cost[j], cost[j + 1]
            den = c0 - 2 * c1 + c2
            if den > 0:
                L += 0.5 * GRID_STEP_S * (c0 - c2) / den
        return L

    # coarse grid over +-max_abs, then the fine grid around its minimum
    coarse = np.arange(-max_abs, max_abs + COARSE_STEP_S / 2, COARSE_STEP_S)
    c0 = float(coarse[int(np.argmin(sse(coarse)))])
    grid = np.arange(c0 - FINE_HALF_S, c0 + FINE_HALF_S + GRID_STEP_S / 2, GRID_STEP_S)
    terms = sse_all(grid)  # (grid, pairs)
    L = argmin(terms.sum(axis=1))
    # delete-a-block jackknife: the IMU's errors are coloured (flicker), which the
    # least-squares variance does not see
    nb = JACKKNIFE_BLOCKS
    edges = np.linspace(0, adj.size, nb + 1).astype(int)
    Lb = np.array(
        [argmin(terms.sum(axis=1) - terms[:, edges[b] : edges[b + 1]].sum(axis=1))
         for b in range(nb)]
    )
    sd_jk = math.sqrt((nb - 1) / nb * float(np.sum((Lb - Lb.mean()) ** 2)))
    # linearised variance: dz/dL = (r(t2-L) - r(t1-L)) differenced
    rate = np.gradient(imu_angle, imu_t)
    J1 = np.interp(t2 - L, imu_t, rate) - np.interp(t1 - L, imu_t, rate)
    J = J1[adj + 1] - J1[adj]
    info = float(np.sum(w * J * J))
    if not info > 0:
        return None
    chi2_red = float(sse(np.array([L]))[0]) / max(adj.size - 1, 1)
    # adjacent second differences share a measurement: the variance is doubled
    var = 2.0 * max(1.0, chi2_red) / info
    sd = max(math.sqrt(var), sd_jk)
    # a bounded deterministic error |d_i| <= det_i moves each second difference by at
    # most 4 max det: the estimate by at most sum w |J| 4 det / sum w J^2
    det_s = float(np.sum(w * np.abs(J) * 4 * np.maximum(d1[adj], d1[adj + 1])) / info)
    return OffsetEstimate(L, sd, method, False, int(da.size), det_s)


def _imu_angle(drive: Any, stamp: str) -> tuple[np.ndarray, np.ndarray] | None:
    imu = drive.imu
    if imu is None or imu.t.size < 10 or not np.isfinite(imu.gyro[:, 2]).all():
        return None
    return imu_yaw_angle(imu.t, imu.gyro[:, 2], stamp)


def estimate_gnss(drive: Any, stamp: str) -> OffsetEstimate | None:
    """The GNSS's clock offset against the IMU's gyro z: its course (from the receiver's
    velocity, else from consecutive fixes) at speeds of at least
    :data:`~imubounds.dynamic.aiding.compass.COURSE_CHECK_MIN_SPEED`; the sideslip
    (bounded by asin(lateral bound / speed)) is the deterministic error. None without a
    lateral speed bound (the sideslip is then unbounded) or too few turns."""
    from imubounds.dynamic.aiding.compass import COURSE_CHECK_MIN_SPEED, course_noise

    ia = _imu_angle(drive, stamp)
    lat = drive.settings.vehicle.lateral_speed_bound_mps
    if ia is None or drive.gnss is None or lat is None:
        return None
    gc = course_noise(drive, COURSE_CHECK_MIN_SPEED)
    if gc is None:
        return None
    tc, course, sc, v_lo = gc
    slip = np.arcsin(np.minimum(1.0, lat / np.maximum(v_lo, 1e-9)))
    how = "velocity" if drive.gnss.velocity_ne() is not None else "consecutive fixes"
    return estimate_offset(tc, -course, sc, ia[0], ia[1],
                           f"GNSS course ({how}) increments against the integrated gyro z",
                           det=slip)


def estimate_heading(drive: Any, stamp: str, heading: Any) -> OffsetEstimate | None:
    """The heading sensor's clock offset against the IMU's gyro z, from the corrected
    heading (a :class:`~imubounds.dynamic.estimator.heading_input.HeadingInput`); its deviation
    bound is the deterministic error. None for an AHRS yaw (it uses the same gyro)."""
    ia = _imu_angle(drive, stamp)
    h = heading
    if ia is None or h is None or not h.independent_of_imu or h.t.size < 10:
        return None
    sig = float(h.noise_sigma_rad) * float(h.noise_gain)
    return estimate_offset(h.t, -np.asarray(h.heading_rad, float), np.full(h.t.size, sig),
                           ia[0], ia[1], "heading increments against the integrated gyro z",
                           det=np.full(h.t.size, float(h.deviation_bound_rad)))


def shifted(obj: Any, name: str | None, est: OffsetEstimate) -> Any:
    """A shallow copy of ``obj`` (a drive with stream ``name``, or a stream when ``name``
    is None) with an applied offset taken off the time stamps (true time = stamp -
    offset)."""
    import dataclasses

    if not est.applied:
        return obj
    if name is None:
        return dataclasses.replace(obj, t=obj.t - est.offset_s)
    stream = getattr(obj, name)
    return dataclasses.replace(obj, **{name: shifted(stream, None, est)})


#: the stated bound (s) on an undeclared clock offset of the heading stream against the
#: IMU (drive.yaml heading.time_offset_s / time_offset_bound_s replace it); a larger
#: offset is what the check against the GNSS course in the turns tests
DEFAULT_HEADING_CLOCK_BOUND_S = 0.1
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
    from scipy.ndimage import maximum_filter1d, minimum_filter1d

    it = np.asarray(imu_t, dtype=float)
    tq = np.asarray(tq, dtype=float)
    cap = bound_s * rate_max
    if it.size < 2 or tq.size == 0 or bound_s <= 0:
        return np.zeros(tq.shape)
    dt = float(np.median(np.diff(it)))
    half = int(math.ceil(bound_s / max(dt, 1e-9))) + 1
    r = np.nan_to_num(np.asarray(rate, dtype=float), nan=0.0)
    G = np.cumsum(r * np.concatenate([[dt], np.diff(it)]))
    gmax = maximum_filter1d(G, size=2 * half + 1, mode="nearest")
    gmin = minimum_filter1d(G, size=2 * half + 1, mode="nearest")
    i = np.searchsorted(it, tq).clip(0, it.size - 1)
    j = (i - 1).clip(0, it.size - 1)
    g = np.interp(tq, it, G)
    swing = np.maximum(np.maximum(gmax[i], gmax[j]) - g, g - np.minimum(gmin[i], gmin[j]))
    out = np.minimum((1.0 + scale) * swing + err_rad, cap)
    # outside the IMU's span or where the rate is not finite: the vehicle's bound
    bad = (tq < it[0]) | (tq > it[-1])
    if not np.isfinite(rate).all():
        fin = maximum_filter1d((~np.isfinite(rate)).astype(float), size=2 * half + 1)
        bad |= (fin[i] > 0) | (fin[j] > 0)
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
    dt = float(np.median(np.diff(it)))
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
