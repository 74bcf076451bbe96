"""Inputs of mode ``full``: the IMU as integrable sample series, and the aiding sensors as
intervals at their epochs, built without the IMU (docs/dynamic-method.md, section 3).

* :class:`ImuSeries` -- the samples of each channel as a piecewise-constant signal
  (sample ``k`` is the mean of the true signal over its period; the period is
  ``(t_k - dt_k, t_k]`` for ``stamp="end"``, the default), with rigorous integrals
  over any time span: ``integral(ch, a, b)`` returns an interval containing the
  float sum of ``y dt`` (summation error bounded by Higham's ``gamma_n``), the
  length of partially covered samples at the ends (for the sample-model error),
  and spans with no sample (gaps, NaN rows) are bounded by the vehicle's limits.
* :class:`Aiding` -- the container of the aiding intervals: GNSS position boxes and
  velocity boxes, heading intervals (compass after deviation correction), body-velocity
  intervals (DVL, wheel/CAN), roll/pitch intervals: everything at its own epochs, in the
  local ENU frame at the first fix, with the half-widths of the error budget. Each sensor
  fills its part (:mod:`imubounds.dynamic.sensors`, :func:`~imubounds.dynamic.sensors.
  build_aiding`).
* :class:`Vehicle` -- the vehicle bounds (:func:`vehicle_from`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from imubounds.constants import G_HI, ROUND_REL
from imubounds.constants import UNIT_ROUNDOFF as _U
from imubounds.dynamic.estimator import series_kernels as SK
from imubounds.dynamic.estimator.budget import CHANNELS, Term
from imubounds.errors import InputError, OptionError
from imubounds.interval import IntervalArray as IA
from imubounds.interval.rounding import down as _dn
from imubounds.interval.rounding import up as _up
from imubounds.units import DEG

if TYPE_CHECKING:
    from imubounds.dynamic.estimator.options import FullOptions



class RangeExt:
    """Range minimum / maximum queries over a fixed array: exact, ``O(n)`` memory (a
    sparse table over blocks of :data:`~.series_kernels.BLOCK` values, the partial
    blocks at a query's ends scanned; :mod:`.series_kernels`)."""

    def __init__(self, lo: np.ndarray, hi: np.ndarray | None = None) -> None:
        self.lo = np.ascontiguousarray(lo, dtype=float)
        self.hi = self.lo if hi is None else np.ascontiguousarray(hi, dtype=float)
        self._tmn = SK.block_table(self.lo, SK.BLOCK, True)
        self._tmx = SK.block_table(self.hi, SK.BLOCK, False)

    def query(self, i: np.ndarray, j: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(min lo, max hi) over inclusive index ranges ``i..j`` (``i <= j``)."""
        i = np.asarray(i, dtype=np.int64)
        j = np.asarray(j, dtype=np.int64)
        shape = np.broadcast(i, j).shape
        ii = np.ascontiguousarray(np.broadcast_to(i, shape).ravel())
        jj = np.ascontiguousarray(np.broadcast_to(j, shape).ravel())
        ii, jj = _index_rule(ii, self.lo.size), _index_rule(jj, self.lo.size)
        mn = SK.range_query(self.lo, self._tmn, SK.BLOCK, ii, jj, True)
        mx = SK.range_query(self.hi, self._tmx, SK.BLOCK, ii, jj, False)
        return mn.reshape(shape), mx.reshape(shape)


def _index_rule(k: np.ndarray, n: int) -> np.ndarray:
    """numpy's indexing rules for the compiled queries: negative from the end, else an
    ``IndexError`` outside ``0..n-1``."""
    if k.size and (k.min() < 0 or k.max() >= n):
        if k.min() < -n or k.max() >= n:
            raise IndexError(f"range query index out of bounds for size {n}")
        return np.where(k < 0, k + n, k)
    return k


# ------------------------------------------------------------------------ vehicle


#: default bound of a ground vehicle's vertical body velocity |w| (m/s): suspension heave
#: over bumps and potholes (tenths of m/s) plus the speed times the body's pitch against
#: its path as the suspension pitches under braking (about 1 deg, 0.3 m/s at 20 m/s); an
#: IMU pitched on its mount by more than about 1 deg needs the bound stated
VERTICAL_DEFAULT_MPS = 0.5


@dataclass
class Vehicle:
    """The vehicle bounds used (SI) and where they came from."""

    kind: str = "ground"
    max_speed: float = 70.0
    max_accel: float = 10.0
    max_jerk: float = 20.0
    max_rate: float = 90.0 * DEG
    max_ang_accel: float = 2.0 * math.pi
    max_tilt: float = 10.0 * DEG
    lateral_speed_bound_mps: float | None = None
    #: |w|, the IMU's velocity along its body z axis (m/s): the stated
    #: ``vertical_speed_bound_mps``, else the kind's default (:data:`VERTICAL_DEFAULT_MPS`
    #: for a ground vehicle: suspension heave over bumps; the speed bound otherwise)
    vertical_bound: float = 0.0
    sources: dict[str, str] = field(default_factory=dict)

    def signal_bound(self, ch: str) -> float:
        """|true signal| bound of a channel (for spans with no IMU sample); ``max_accel``
        bounds the horizontal acceleration including the centripetal part."""
        g = G_HI
        if ch in ("accel_x", "accel_y"):
            return self.max_accel + g * math.sin(self.max_tilt)
        if ch == "accel_z":
            return g + self.max_accel
        return self.max_rate

    def rate_of_change(self, ch: str) -> float:
        """Bound on |d/dt| of a channel's true signal (sample-model edge error)."""
        return self.max_jerk if ch.startswith("accel") else self.max_ang_accel


def vehicle_from(settings: Any, opts: FullOptions) -> tuple[Vehicle, list[str]]:
    """Vehicle bounds: options > drive.yaml (``vehicle``) > defaults (listed as assumed)."""
    vs = getattr(settings, "vehicle", None)
    assumed_in = list(getattr(settings, "assumed", []) or [])
    v = Vehicle()
    notes: list[str] = []
    table = (
        ("kind", "kind", 1.0, None),
        ("max_speed", "max_speed_mps", 1.0, "max_speed"),
        ("max_accel", "max_accel_mps2", 1.0, "max_accel"),
        ("max_jerk", "max_jerk_mps3", 1.0, "max_jerk"),
        ("max_rate", "max_yaw_rate_dps", DEG, "max_rate_dps"),
        ("max_tilt", "max_tilt_deg", DEG, "max_tilt_deg"),
        ("lateral_speed_bound_mps", "lateral_speed_bound_mps", 1.0, "lateral_speed_bound_mps"),
        ("vertical_bound", "vertical_speed_bound_mps", 1.0, "vertical_speed_bound_mps"),
    )
    for attr, key, fac, opt in table:
        if opt is not None and getattr(opts, opt) is not None:
            setattr(v, attr, float(getattr(opts, opt)) * fac)
            v.sources[attr] = "option"
            continue
        val = getattr(vs, key, None) if vs is not None else None
        if val is not None:
            setattr(v, attr, val if attr == "kind" else float(val) * fac)
            assumed = any(key.split("_")[0] in a and "vehicle" in a for a in assumed_in)
            v.sources[attr] = "default (drive.yaml silent)" if assumed else "drive.yaml"
        else:
            v.sources[attr] = "default"
    if opts.max_ang_accel_dps2 is not None:
        v.max_ang_accel = float(opts.max_ang_accel_dps2) * DEG
        v.sources["max_ang_accel"] = "option"
    else:
        v.sources["max_ang_accel"] = "default"
    if v.sources.get("vertical_bound") == "default":  # nothing stated: the kind's default
        v.vertical_bound = VERTICAL_DEFAULT_MPS if v.kind == "ground" else v.max_speed
        if v.kind != "ground":
            notes.append(
                f"vehicle kind {v.kind!r}: body vertical velocity w bounded by the speed "
                f"bound {v.max_speed:g} m/s only"
            )
    return v, notes


# --------------------------------------------------------------------------- IMU


#: bytes of queries and answers a :class:`Locator` keeps (the cache grew to GBs on long
#: trips with 10 Hz aiding when it was bounded by its number of entries only)
LOCATOR_CACHE_BYTES = 64 << 20


class Locator:
    """Segment index of times on fixed boundaries, cached by the query (several signals
    on the same segments ask for the same window ends)."""

    def __init__(self, bnd: np.ndarray) -> None:
        self.bnd = bnd
        self._cache: dict[bytes, np.ndarray] = {}
        self._bytes = 0
        self._none: np.ndarray | None = None

    def no_unknown(self) -> np.ndarray:
        """All False, one per segment: shared by the signals on these segments that have
        no unknown segment (not to be written)."""
        if self._none is None:
            self._none = np.zeros(self.bnd.size - 1, dtype=bool)
        return self._none

    def locate(self, t: np.ndarray) -> np.ndarray:
        t = np.asarray(t, dtype=float)
        key = t.tobytes() + bytes(str(t.shape), "ascii")
        hit = self._cache.get(key)
        if hit is None:
            hit = np.clip(np.searchsorted(self.bnd, t, side="right") - 1, 0, self.bnd.size - 2)
            size = len(key) + hit.nbytes
            if size <= LOCATOR_CACHE_BYTES // 4:  # the cache holds at most its byte budget
                if self._bytes + size > LOCATOR_CACHE_BYTES or len(self._cache) > 512:
                    self._cache.clear()
                    self._bytes = 0
                self._cache[key] = hit
                self._bytes += size
        return hit


class PiecewiseSignal:
    """A signal constant on segments ``[bnd[i], bnd[i+1])`` with rigorous integrals.

    ``y`` holds the value of each segment (0 where ``unknown``); an unknown segment
    contributes ``+-xmax`` per second. Prefix sums ``S`` (of ``y * length``) and
    ``Z`` (of the integral ``Y``) are kept with the bounds of their rounding errors
    (recursive summation: ``|error| <= gamma_n sum |terms|``, Higham): stored every
    :data:`~.series_kernels.CHECKPOINT` (``Z``: :data:`~.series_kernels.CHECKPOINT_Z`)
    segments and finished from there when asked, the same additions as full arrays
    (:mod:`.series_kernels`; memory: ``y`` and about 1/6 of a value per segment).
    ``y`` is the caller's array (no copy) when no segment is unknown.
    """

    def __init__(
        self,
        bnd: np.ndarray,
        y: np.ndarray,
        unknown: np.ndarray | None = None,
        xmax: float = 0.0,
        locator: Locator | None = None,
    ) -> None:
        self.bnd = np.asarray(bnd, dtype=float)
        self.locator = locator if locator is not None else Locator(self.bnd)
        self.unknown = (
            self.locator.no_unknown() if unknown is None else np.asarray(unknown)
        )
        self._any_unknown = bool(np.any(self.unknown))
        y = np.asarray(y, dtype=float)
        if y.shape != self.unknown.shape:  # a constant (broadcast, as np.where did)
            y = np.array(np.broadcast_to(y, self.unknown.shape))
        self.y = np.where(self.unknown, 0.0, y) if self._any_unknown else y
        self.xmax = float(xmax)
        self._ck = SK.checkpoints(self.bnd, self.y, SK.CHECKPOINT, SK.CHECKPOINT_Z)
        self._monotone = bool(np.all(self.bnd[1:] >= self.bnd[:-1]))
        self._UL: np.ndarray | None = None

    def _prefix(self, i: np.ndarray, want_z: bool) -> tuple[np.ndarray, ...]:
        """``S[i], A[i]`` (and ``Z[i], ZA[i]``) at segment indices ``i``."""
        i = np.asarray(i, dtype=np.int64)
        flat = np.ascontiguousarray(i.ravel())
        out = SK.prefix_at(
            self.bnd, self.y, *self._ck, SK.CHECKPOINT, SK.CHECKPOINT_Z, flat, want_z
        )
        return tuple(o.reshape(i.shape) for o in (out if want_z else out[:2]))

    @property
    def UL(self) -> np.ndarray:
        """Prefix sums of the unknown segments' lengths (computed on first use)."""
        if self._UL is None:
            ul = np.where(self.unknown, np.diff(self.bnd), 0.0)
            self._UL = np.concatenate([[0.0], np.cumsum(ul)])
        return self._UL

    @property
    def n(self) -> int:
        return int(self.bnd.size - 1)

    def locate(self, t: np.ndarray) -> np.ndarray:
        return self.locator.locate(t)

    def cum(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``Y(t) = int_{bnd[0]}^t y`` (float), its rounding-error bound, and the length by
        which ``t`` cuts a segment (min of the two parts; 0 on a boundary)."""
        t = np.clip(np.asarray(t, dtype=float), self.bnd[0], self.bnd[-1])
        i = self.locate(t)
        part = t - self.bnd[i]
        S, A = self._prefix(i, False)
        val = S + self.y[i] * part
        err = 1.01 * _U * ((i + 3) * A + 3 * np.abs(self.y[i] * part))
        return val, err, self._cut(i, part)

    def _cut(self, i: np.ndarray, part: np.ndarray) -> np.ndarray:
        ln = self.bnd[i + 1] - self.bnd[i]
        return np.where((part > 0) & (part < ln), np.minimum(part, ln - part), 0.0)

    def cut(self, t: np.ndarray) -> np.ndarray:
        """The third value of :meth:`cum` alone (no prefix sums)."""
        t = np.clip(np.asarray(t, dtype=float), self.bnd[0], self.bnd[-1])
        i = self.locate(t)
        return self._cut(i, t - self.bnd[i])

    def zcum(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``Z(t) = int_{bnd[0]}^t Y`` and its rounding-error bound."""
        t = np.clip(np.asarray(t, dtype=float), self.bnd[0], self.bnd[-1])
        i = self.locate(t)
        p = t - self.bnd[i]
        S, A, Z, ZA = self._prefix(i, True)
        inc = S * p + 0.5 * self.y[i] * p * p
        val = Z + inc
        err = 1.01 * _U * ((i + 4) * ZA + 4 * np.abs(inc) + (i + 3) * A * p)
        return val, err

    def unknown_len(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """Length without a value inside ``[a, b]`` (whole segments touched, conservative)."""
        if not self._any_unknown:
            return np.zeros(np.broadcast(np.asarray(a), np.asarray(b)).shape)
        ia, ib = self.locate(np.asarray(a, float)), self.locate(np.asarray(b, float))
        return np.maximum(self.UL[ib + 1] - self.UL[ia], 0.0)

    def integral(self, a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Interval ``(lo, hi)`` of ``int_a^b y dt`` (unknown spans: ``+-xmax``)."""
        ya, ea, _ = self.cum(a)
        yb, eb, _ = self.cum(b)
        d = yb - ya
        err = ea + eb + 2 * _U * np.abs(d) + self.unknown_len(a, b) * self.xmax
        return _dn(d - err), _up(d + err)

    def mean_cum(self, a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Interval of the float mean of ``Y`` over ``[a, b]`` (``Y(a)`` where ``b == a``),
        rounding included; unknown spans are NOT charged here (see :meth:`kernel_mean`)."""
        a = np.asarray(a, dtype=float)
        b = np.asarray(b, dtype=float)
        L = b - a
        ya, ea, _ = self.cum(a)
        if not np.any(L > 0):
            return _dn(ya - ea), _up(ya + ea)
        za, zea = self.zcum(a)
        zb, zeb = self.zcum(b)
        pos = L > 0
        if not np.any(pos):
            return _dn(ya - ea), _up(ya + ea)
        Ls = np.where(pos, L, 1.0)
        num = zb - za
        m = np.where(pos, num / Ls, ya)
        e = np.where(
            pos, (zea + zeb + 2 * _U * np.abs(num)) / Ls * (1 + 4 * _U) + 2 * _U * np.abs(m), ea
        )
        return _dn(m - e), _up(m + e)

    def kernel_mean(
        self, a1: np.ndarray, b1: np.ndarray, a2: np.ndarray, b2: np.ndarray, tau: np.ndarray
    ) -> IA:
        """Interval of the kernel mean ``(mean_{I2} Y - mean_{I1} Y) / tau`` of ``y`` (the
        kernel of a difference of two means over ``I1 = [a1, b1]``, ``I2 = [a2, b2]``;
        the boxcar on ``[a1, a2]`` when both have length 0). Unknown spans inside the
        support ``[a1, b2]`` are charged ``+-xmax * length / tau`` (the kernel is at
        most ``1/tau``)."""
        l1, h1 = self.mean_cum(a1, b1)
        l2, h2 = self.mean_cum(a2, b2)
        d = IA(l2, h2) - IA(l1, h1)
        uw = self.unknown_len(a1, b2) * self.xmax
        if np.any(uw > 0):
            d = d + IA(-uw, uw)
        return d / IA(tau)

    def abs_integral(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """Upper bound of ``int_a^b |y|`` (whole segments touched; unknown: ``xmax``)."""
        ia, ib = self.locate(np.asarray(a, float)), self.locate(np.asarray(b, float))
        if self._monotone:
            # the running sum of |y| x length is A (|y l| = |y| l: rounding is symmetric)
            Ab, Aa = self._prefix(ib + 1, False)[1], self._prefix(ia, False)[1]
        else:
            AB = np.concatenate([[0.0], np.cumsum(np.abs(self.y) * np.diff(self.bnd))])
            Ab, Aa = AB[ib + 1], AB[ia]
        return (Ab - Aa) * (1 + ROUND_REL) + self.unknown_len(a, b) * self.xmax


@dataclass
class ImuSeries:
    """The six IMU channels as :class:`PiecewiseSignal` on common sample segments.

    Times are relative to ``t0`` (s); sample ``k`` covers ``(t_k - dt_k, t_k]`` for
    ``stamp="end"`` (``[t_k, t_k + dt_k)`` for ``"start"``, centred for
    ``"centre"``); a gap longer than 1.5 periods becomes an unknown segment, bounded
    by the vehicle's signal limits, as are NaN samples.
    """

    t0: float
    bnd: np.ndarray
    dt: float
    sig: dict[str, PiecewiseSignal]
    rate_bound: dict[str, float]
    stamp: str
    n_gaps: int = 0
    available: dict[str, bool] = field(default_factory=dict)
    max_len: float = 0.0

    @property
    def n(self) -> int:
        return int(self.bnd.size - 1)

    @property
    def duration(self) -> float:
        return float(self.bnd[-1] - self.bnd[0])

    @classmethod
    def from_drive(cls, drive: Any, stamp: str, vehicle: Vehicle) -> ImuSeries:
        imu = drive.imu
        if imu is None or imu.t.size < 2:
            raise InputError(f"{drive.source}: the IMU stream needs at least 2 samples")
        if stamp not in ("end", "start", "centre"):
            raise OptionError(f"--imu-stamp must be end, start or centre, got {stamp!r}")
        t_abs = np.asarray(imu.t, dtype=float)
        t0 = float(t_abs[0])
        t = t_abs - t0  # exact for nearby doubles (Sterbenz)
        d = np.diff(t)
        dt = float(np.median(d))
        if not dt > 0:
            raise InputError(f"{drive.source}: IMU time stamps do not increase")
        big = d > 1.5 * dt
        per = np.concatenate([[dt], np.where(big, dt, d)])
        nxt = np.concatenate([np.where(big, dt, d), [dt]])
        if stamp == "end":
            start, end = t - per, t
        elif stamp == "start":
            start, end = t, t + nxt
        else:
            start, end = t - 0.5 * per, t + 0.5 * nxt
        gaps = np.flatnonzero(start[1:] > end[:-1])
        is_gap = np.zeros(t.size, dtype=bool)
        seg_start = start
        if gaps.size:
            seg_start = np.insert(start, gaps + 1, end[gaps])
            is_gap = np.insert(is_gap, gaps + 1, True)
        bnd = np.maximum.accumulate(np.concatenate([seg_start, [end[-1]]]))
        raw = {
            "accel_x": imu.accel[:, 0],
            "accel_y": imu.accel[:, 1],
            "accel_z": imu.accel[:, 2],
            "gyro_x": imu.gyro[:, 0],
            "gyro_y": imu.gyro[:, 1],
            "gyro_z": imu.gyro[:, 2],
        }
        sig: dict[str, PiecewiseSignal] = {}
        avail: dict[str, bool] = {}
        loc = Locator(bnd)
        del t, d, per, nxt, start, end, seg_start
        for ch in CHANNELS:
            vals = np.asarray(raw[ch], dtype=float)  # the drive's column: no copy
            if gaps.size:
                vals = np.insert(vals, gaps + 1, np.nan)
            bad = ~np.isfinite(vals) | is_gap
            avail[ch] = bool(np.any(~bad))
            if not np.any(bad):
                bad = loc.no_unknown()
            sig[ch] = PiecewiseSignal(bnd, vals, bad, vehicle.signal_bound(ch), locator=loc)
        ln = np.diff(bnd)
        return cls(
            t0=t0,
            bnd=bnd,
            dt=dt,
            sig=sig,
            rate_bound={ch: vehicle.rate_of_change(ch) for ch in CHANNELS},
            stamp=stamp,
            n_gaps=int(gaps.size),
            available=avail,
            max_len=float(np.max(ln[~is_gap])) if np.any(~is_gap) else dt,
        )

    def count(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """Number of segments touched by ``[a, b]``."""
        s = self.sig["accel_x"]
        return (s.locate(np.asarray(b, float)) - s.locate(np.asarray(a, float)) + 1).astype(
            np.int64
        )

    def edge(self, t: np.ndarray) -> np.ndarray:
        """Length by which ``t`` cuts a sample (sample-model error at a window end)."""
        return self.sig["accel_x"].cut(t)


# -------------------------------------------------------------------------- aiding


@dataclass
class Aiding:
    """Aiding intervals at their epochs (relative times in s, ENU m, model heading rad).

    Arrays of lo/hi have NaN where a value is absent at an epoch.
    """

    origin: tuple[float, float, float] | None
    # GNSS position
    gnss_t: np.ndarray = field(default_factory=lambda: np.zeros(0))
    gnss_e: np.ndarray = field(default_factory=lambda: np.zeros(0))
    gnss_n: np.ndarray = field(default_factory=lambda: np.zeros(0))
    gnss_h: np.ndarray = field(default_factory=lambda: np.zeros(0))  # box half-width, m
    gnss_alt: np.ndarray = field(default_factory=lambda: np.zeros(0))  # m, NaN: none
    gnss_vacc: np.ndarray = field(default_factory=lambda: np.zeros(0))  # 1-sigma m, NaN
    # GNSS velocity (nav, ENU), per-component half-width
    gvel_ok: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))
    gvel_e: np.ndarray = field(default_factory=lambda: np.zeros(0))
    gvel_n: np.ndarray = field(default_factory=lambda: np.zeros(0))
    gvel_h: float = 0.0
    gvel_hi: np.ndarray = field(default_factory=lambda: np.zeros(0))  # per fix
    # heading (model convention, CCW from east), unwrapped centres
    head_t: np.ndarray = field(default_factory=lambda: np.zeros(0))
    head_c: np.ndarray = field(default_factory=lambda: np.zeros(0))
    head_h: np.ndarray = field(default_factory=lambda: np.zeros(0))
    head_source: str = "none"
    head_independent_of_imu: bool = True
    head_from_course: bool = False  # heading derived from the GNSS course (same epochs)
    # body velocity (DVL / wheel), body frame
    bvel_t: np.ndarray = field(default_factory=lambda: np.zeros(0))
    bvel_u: np.ndarray = field(default_factory=lambda: np.zeros(0))
    bvel_v: np.ndarray | None = None
    bvel_w: np.ndarray | None = None
    bvel_h: np.ndarray = field(default_factory=lambda: np.zeros(0))
    bvel_kind: str = ""
    # attitude
    att_t: np.ndarray | None = None
    att_roll: np.ndarray | None = None
    att_pitch: np.ndarray | None = None
    att_bound: float = 0.0
    att_source: str = ""
    #: pitch intervals from GNSS altitude without an attitude stream (pitch_gnss.py)
    pitch: Any = None
    budget: dict[str, list[Term]] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    gnss_rejected: list[tuple[float, float]] = field(default_factory=list)
    #: error model of the residual checks (residual_checks.py): per-axis Gaussian sigma
    #: and deterministic bound of each GNSS fix (m), velocity (m/s) and heading (rad)
    gnss_sig: np.ndarray = field(default_factory=lambda: np.zeros(0))
    gnss_det: float = 0.0
    gvel_sig: np.ndarray = field(default_factory=lambda: np.zeros(0))
    gvel_det: float = 0.0
    head_sig: float = 0.0
    head_det: float = 0.0

    @property
    def has_gnss(self) -> bool:
        return self.gnss_t.size > 0

    @property
    def has_gvel(self) -> bool:
        return bool(self.gvel_ok.size and np.any(self.gvel_ok))

    @property
    def has_heading(self) -> bool:
        return self.head_t.size > 0

    @property
    def has_bvel(self) -> bool:
        return self.bvel_t.size > 0

    @property
    def has_attitude(self) -> bool:
        return self.att_t is not None and self.att_t.size > 0

    # -- roll / pitch intervals over any time span --------------------------------
    def tilt_range(self, s0: np.ndarray, s1: np.ndarray, vehicle: Vehicle) -> tuple[Any, ...]:
        """(roll_lo, roll_hi, pitch_lo, pitch_hi) valid at every time of ``[s0, s1]``.

        Between two attitude samples the angle lies within the chord of the two
        (each +-bound) +- ``max_ang_accel * gap^2 / 8`` (a bound on the second
        derivative); before the first and after the last sample it may move at the
        angular-rate bound; +-max_tilt without attitude.
        """
        s0 = np.asarray(s0, dtype=float)
        s1 = np.asarray(s1, dtype=float)
        if not self.has_attitude:
            m = vehicle.max_tilt
            z = np.full(s0.shape, m)
            if self.pitch is None:
                return -z, z, -z, z
            pb = self.pitch  # hull of the pieces [s0, s1] touches
            if not hasattr(self, "_pitch_ext"):
                self._pitch_ext = RangeExt(pb.lo, pb.hi)
            k = pb.lo.size - 1
            i = np.clip(np.searchsorted(pb.bnd, s0, side="right") - 1, 0, k)
            j = np.clip(np.searchsorted(pb.bnd, s1, side="left") - 1, i, k)
            pl, ph = self._pitch_ext.query(i, j)
            return -z, z, np.maximum(pl, -m), np.minimum(ph, m)
        assert self.att_t is not None and self.att_roll is not None
        assert self.att_pitch is not None
        at = self.att_t
        na = at.size
        gaps = np.diff(at) if na > 1 else np.zeros(1)
        dev = vehicle.max_ang_accel * float(np.max(gaps)) ** 2 / 8.0
        cap = vehicle.max_tilt + self.att_bound
        if not hasattr(self, "_att_ext"):
            self._att_ext = (RangeExt(self.att_roll), RangeExt(self.att_pitch))
        out = []
        t_first, t_last = float(at[0]), float(at[-1])
        # attitude samples strictly inside [s0, s1] (the chord's vertices)
        i_in = np.searchsorted(at, s0, side="right")
        j_in = np.searchsorted(at, s1, side="left") - 1
        has = j_in >= i_in
        for arr, ext in zip((self.att_roll, self.att_pitch), self._att_ext, strict=True):
            vals = []
            for s in (s0, s1):
                chord = np.interp(s, at, arr)  # clamps outside [first, last]
                far = np.maximum(t_first - s, 0.0) + np.maximum(s - t_last, 0.0)
                inside = far == 0.0
                wid = self.att_bound + np.where(inside, dev, 0.0) + vehicle.max_rate * far
                vals.append((chord - wid, chord + wid))
            lo = np.minimum(vals[0][0], vals[1][0])
            hi = np.maximum(vals[0][1], vals[1][1])
            if np.any(has):
                ii = np.clip(i_in[has], 0, na - 1)
                jj = np.clip(np.maximum(j_in[has], i_in[has]), 0, na - 1)
                mn, mx = ext.query(ii, jj)
                lo[has] = np.minimum(lo[has], mn - self.att_bound - dev)
                hi[has] = np.maximum(hi[has], mx + self.att_bound + dev)
            lo = np.maximum(lo, -cap)
            hi = np.minimum(hi, cap)
            out += [_dn(lo * (1 + ROUND_REL) - 1e-15), _up(hi * (1 + ROUND_REL) + 1e-15)]
        return out[0], out[1], out[2], out[3]

    def tilt(self, t: np.ndarray, vehicle: Vehicle) -> tuple[Any, ...]:
        """Roll/pitch intervals at times ``t`` (see :meth:`tilt_range`)."""
        t = np.asarray(t, dtype=float)
        return self.tilt_range(t, t, vehicle)


def lateral_h_bound(vehicle: Vehicle) -> float | None:
    """Bound of the horizontal lateral velocity ``|cos(roll) v - sin(roll) w|`` (m/s),
    None when no lateral bound is stated."""
    vl = vehicle.lateral_speed_bound_mps
    if vl is None:
        return None
    return float(_up(vl + math.sin(vehicle.max_tilt) * vehicle.vertical_bound))


# ------------------------------------------------------------------------ checks


def check_overlap(imu: ImuSeries, ag: Aiding, source: str) -> None:
    """The aiding must overlap the IMU in time."""
    ts = [x for x in (ag.gnss_t, ag.head_t, ag.bvel_t) if x.size]
    if not ts:
        raise InputError(
            f"{source}: no usable aiding sensor (GNSS fixes, body velocity or heading)"
        )
    lo = min(float(x[0]) for x in ts)
    hi = max(float(x[-1]) for x in ts)
    if hi < imu.bnd[0] or lo > imu.bnd[-1]:
        raise InputError(
            f"{source}: the aiding sensors ({lo + imu.t0:.3f}..{hi + imu.t0:.3f} s) do not "
            f"overlap the IMU ({imu.bnd[0] + imu.t0:.3f}..{imu.bnd[-1] + imu.t0:.3f} s); "
            "check the clocks"
        )
