"""The gyros' running integrals and error bounds that carry roll and pitch between two
times (docs/dynamic-method.md, section 3b, equations (3b.3)-(3b.5)).

For each gyro ``c`` at the IMU boundaries: the signed running integral ``C_c`` of the
samples, the running integral ``M_c`` of a bound of the true rate's magnitude
``|x_c| <= (|y_c| + m_c |x_perp| + b_c + sigma_c sqrt(2/pi) + quantization)/(1 - s_c)``
(the white part by its mean absolute value, its deviation added per span), and the
unknown spans' running length ``U`` (no sample: the vehicle's rate bound). The error of
the signed integral over a span of length ``L`` is within::

    |int e_c| <= b_c L + k_w N_c sqrt(L) + s_c int|x_c| + m_c int|x_perp| + 2 k_ps Q_c
                 + edge + 2 max_rate (unknown length)

``b_c`` the turn-on bound plus the per-sample wander bound (``budget.Wander``) plus the
Earth and transport rates the gyros also measure; the white part by the reflection
principle (``k_w`` of the ``imu_intervals`` family, two events per bound: it holds at
every time of the span at once).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from imubounds.constants import EARTH_RATE

GYROS = ("gyro_x", "gyro_y", "gyro_z")
#: a lower bound of the Earth's radius (m): the local level frame turns at most at
#: Omega + v / R against inertial space
EARTH_RADIUS_M = 6.35e6
_U = 2.0**-53


def reflection_k(ctx: Any) -> tuple[float, float]:
    """``k_w`` (the reflection principle, ``imu_intervals``) and the sub-Gaussian factor
    ``k_sg = sqrt(2 ln(1/p))`` of the magnitudes' white part at that family's share."""
    alpha = ctx.alpha
    k_w = alpha.k("imu_intervals")
    p_int = alpha.share() / max(1, alpha.counts.get("imu_intervals", 1))
    return k_w, math.sqrt(2.0 * math.log(1.0 / p_int))


def bias_bound(ctx: Any, ch: str) -> float:
    """A channel's turn-on bound plus its per-sample wander bound (the model's flicker and
    K, R, or the stated drift bound's point bound; ``budget.Wander``)."""
    cn, wd = ctx.noise[ch], ctx.wander[ch]
    model = ctx.k_ps * cn.flicker_sigma() + wd.kr
    return float(cn.turn_on_bound(ctx.alpha.k("imu_turn_on")) + wd.pick(model, wd.point))


@dataclass
class GyroTerms:
    """Running integrals of the three gyros at the IMU boundaries and their budgets."""

    bnd: np.ndarray
    C: dict[str, np.ndarray]
    M: dict[str, np.ndarray]
    U: np.ndarray
    bias: dict[str, float]
    N: dict[str, float]
    scale: dict[str, float]
    mis: dict[str, float]
    #: sigma of the white part of a magnitude sum per sqrt(s) (its deviation, k_sg x this)
    sig_a: dict[str, float]
    const: float
    max_rate: float
    tol: float
    #: per IMU segment: the samples (0 where unknown), the unknown mask and the magnitude
    #: bounds of the true rates (rad/s), for the compiled walks
    y: dict[str, np.ndarray] = field(default_factory=dict)
    mag: dict[str, np.ndarray] = field(default_factory=dict)
    unknown: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))
    Q: dict[str, float] = field(default_factory=dict)
    k_ps: float = 0.0
    max_ang_accel: float = 0.0
    max_len: float = 0.0
    #: the bias bound of a mean over spans of at least ``long_span`` s (a stated drift
    #: bound's window: turn-on + D_s + Earth), where smaller than ``bias``
    bias_long: dict[str, float] = field(default_factory=dict)
    long_span: float = math.inf

    def at(self, name: str, ch: str, t: np.ndarray) -> np.ndarray:
        """``C`` or ``M`` of a gyro at times ``t`` (linear inside a sample)."""
        arr = self.C[ch] if name == "C" else self.M[ch]
        return np.interp(t, self.bnd, arr)

    def unknown_at(self, t: np.ndarray) -> np.ndarray:
        return np.interp(t, self.bnd, self.U)

    def hull_C(self, ch: str, t0: np.ndarray, t1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Hull of ``C`` over each ``[t0, t1]``: its values at the ends and at the IMU
        boundaries inside (``C`` is linear between them), widened by its rounding."""
        from imubounds.dynamic.estimator.inputs import RangeExt

        C = self.C[ch]
        c0, c1 = np.interp(t0, self.bnd, C), np.interp(t1, self.bnd, C)
        i0 = np.searchsorted(self.bnd, t0, side="right")
        i1 = np.searchsorted(self.bnd, t1, side="left") - 1
        has = i1 >= i0
        ext = self._ext.get(ch)
        if ext is None:
            ext = self._ext[ch] = RangeExt(C)
        mn, mx = ext.query(np.where(has, i0, 0), np.where(has, i1, 0))
        lo = np.minimum(np.minimum(c0, c1), np.where(has, mn, np.inf))
        hi = np.maximum(np.maximum(c0, c1), np.where(has, mx, -np.inf))
        return lo - self.tol, hi + self.tol

    def __post_init__(self) -> None:
        self._ext: dict[str, Any] = {}


def gyro_terms(ctx: Any) -> GyroTerms:
    """:class:`GyroTerms` of a run (the budget's sample model, as the smoother's links)."""
    imu, noise, veh = ctx.imu, ctx.noise, ctx.vehicle
    dl = np.diff(imu.bnd)
    dt = imu.dt
    earth = EARTH_RATE + veh.max_speed / EARTH_RADIUS_M
    C: dict[str, np.ndarray] = {}
    M: dict[str, np.ndarray] = {}
    bias: dict[str, float] = {}
    sig_a: dict[str, float] = {}
    unknown = np.zeros(dl.size, bool)
    absy = {}
    mags: dict[str, np.ndarray] = {}
    long_b: dict[str, float] = {}
    span = math.inf
    for ch in GYROS:
        if imu.available.get(ch, False):
            s = imu.sig[ch]
            unknown |= s.unknown
            absy[ch] = np.abs(s.y)
        bias[ch] = bias_bound(ctx, ch) + earth
        wd = ctx.wander[ch]
        if wd.rule != "model":
            to = noise[ch].turn_on_bound(ctx.alpha.k("imu_turn_on"))
            long_b[ch] = min(bias[ch], to + wd.stated + earth)
            span = min(span, wd.window_s)
        else:
            long_b[ch] = bias[ch]
    total = 0.0
    for ch in GYROS:
        cn = noise[ch]
        sig_w = cn.N / math.sqrt(dt)
        if not imu.available.get(ch, False):
            mags[ch] = np.full(dl.size, veh.max_rate)
            C[ch] = np.zeros(dl.size + 1)
            M[ch] = np.concatenate([[0.0], np.cumsum(np.full(dl.size, veh.max_rate) * dl)])
            sig_a[ch] = 0.0
            continue
        s = imu.sig[ch]
        perp = sum(absy[o] for o in GYROS if o != ch and o in absy)
        quant = ctx.k_ps * math.sqrt(2.0) * cn.Q / dt
        x = (np.abs(s.y) + cn.misalignment_rad * (perp + sum(
            ctx.E0[o] for o in GYROS if o != ch and o in absy)) + bias[ch]
             + sig_w * math.sqrt(2.0 / math.pi) + quant) / (1.0 - cn.scale)
        x = np.where(unknown, veh.max_rate, x)
        mags[ch] = np.ascontiguousarray(x * (1 + 1e-12))
        C[ch] = np.concatenate([[0.0], np.cumsum(s.y * dl)])
        M[ch] = np.concatenate([[0.0], np.cumsum(x * dl)]) * (1 + 1e-9)
        sig_a[ch] = sig_w / (1.0 - cn.scale) * math.sqrt(dt)
        total = max(total, float(np.sum(np.abs(s.y) * dl)))
    U = np.concatenate([[0.0], np.cumsum(np.where(unknown, dl, 0.0))])
    n = dl.size
    # recursive summation: |error| <= gamma_n sum |terms| (Higham), for C and its hull
    tol = 1.01 * (n + 2) * _U * total + 1e-15
    const = 2.0 * ctx.k_ps * max(noise[c].Q for c in GYROS) + 2.0 * veh.max_ang_accel * (
        imu.max_len**2) + 1e-12
    return GyroTerms(
        bnd=imu.bnd, C=C, M=M, U=U, bias=bias,
        N={c: noise[c].N / (1.0 - noise[c].scale) for c in GYROS},
        scale={c: noise[c].scale for c in GYROS},
        mis={c: noise[c].misalignment_rad for c in GYROS},
        sig_a=sig_a, const=const, max_rate=veh.max_rate, tol=tol,
        y={c: np.ascontiguousarray(imu.sig[c].y if imu.available.get(c, False)
                                   else np.zeros(dl.size)) for c in GYROS},
        mag=mags, unknown=np.ascontiguousarray(unknown),
        Q={c: noise[c].Q for c in GYROS}, k_ps=ctx.k_ps, max_ang_accel=veh.max_ang_accel,
        max_len=imu.max_len, bias_long=long_b,
        long_span=span if all(ctx.wander[c].rule != "model" for c in GYROS) else math.inf,
    )


def error_coefficients(g: GyroTerms, h_max: float, k_w: float, k_sg: float) -> np.ndarray:
    """The coefficients of ``kernels._err`` (3b.4) for tilts with ``|h|_2 <= h_max``:
    (bias, white, a_q, a_p, a_r, dev, const, unk). Per component of ``h``:

    * gyro_y and gyro_x errors, rotated: ``sqrt(b_q^2 + b_p^2) L``, ``k_w max(N_q, N_p)
      sqrt(L)`` (a rotated white noise has at most the larger variance), their scale and
      misalignment on the magnitude integrals;
    * ``u_z = cos(phi) cos(theta) >= 1 - h_max^2``: ``(1 - u_z) (int|q| + int|p|)``;
    * the sample model (the rates move inside a sample): ``max_ang_accel dt^2 / 2`` on
      the same integrals;
    * gyro_z's error turns ``h`` by its angle: ``h_max`` times its bias, white noise,
      scale and misalignment terms;
    * quantization and the two edges (``const``), an unknown span (``unk`` per s)."""
    uz = 1.0 - h_max * h_max
    rot = g.max_ang_accel * g.max_len**2 / 2.0
    bq, bp, br = g.bias["gyro_y"], g.bias["gyro_x"], g.bias["gyro_z"]
    sq, sp, sr = g.scale["gyro_y"], g.scale["gyro_x"], g.scale["gyro_z"]
    mq, mp, mr = g.mis["gyro_y"], g.mis["gyro_x"], g.mis["gyro_z"]
    a_q = sq + mp + (1.0 - uz) + rot + h_max * mr
    a_p = sp + mq + (1.0 - uz) + rot + h_max * mr
    a_r = mq + mp + h_max * sr
    dev = k_sg * (a_q * g.sig_a["gyro_y"] + a_p * g.sig_a["gyro_x"] + a_r * g.sig_a["gyro_z"])
    const = (2.0 * g.k_ps * (g.Q["gyro_y"] + g.Q["gyro_x"] + h_max * g.Q["gyro_z"])
             + g.tol * (2.0 + h_max))
    lq, lp, lr = g.bias_long["gyro_y"], g.bias_long["gyro_x"], g.bias_long["gyro_z"]
    c = np.array([
        math.hypot(bq, bp) + h_max * br,
        k_w * (max(g.N["gyro_y"], g.N["gyro_x"]) + h_max * g.N["gyro_z"]),
        a_q, a_p, a_r, dev, const, g.max_rate * (2.0 + h_max),
        math.hypot(lq, lp) + h_max * lr,
    ])
    c = np.append(np.nextafter(c * (1 + 1e-9) + 1e-300, np.inf), g.long_span)
    return c


def edge_error(ctx: Any, t: np.ndarray, h_max: float) -> np.ndarray:
    """The sample-model error where a time cuts a sample (the true rates move inside it:
    at most the vehicle's angular acceleration x the sample x the cut length, on the
    three gyros' terms)."""
    imu = ctx.imu
    cut = imu.edge(np.asarray(t, dtype=float))
    out = ctx.vehicle.max_ang_accel * imu.max_len * cut * (2.0 + h_max) * (1 + 1e-9)
    return np.ascontiguousarray(np.nextafter(out, np.inf))
