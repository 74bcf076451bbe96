"""Clock offset of a body-velocity stream (wheel speed, DVL) against the IMU, by a score
test inverted over the offsets (docs/dynamic-method.md, section 5b "Clock offsets").

A speed stream late by ``L`` (stamp = true time + L) reads ``y_i = (1 + kappa) u(t_i -
L) + e_i``; the IMU's forward acceleration integrates to ``Y(t) = u(t) + B(t) + N(t)``
(``B`` the integrated bias, its drift and the gravity of a slow pitch; ``N`` the
integrated noise). As in :func:`~imubounds.dynamic.sensors._timing.level_offset`, the model
is ``y_i = s Y(t_i - L) + c(t_i) + e_i`` with ``c`` a cubic spline (knots every
:data:`~imubounds.dynamic.sensors._timing.KNOT_S`) and the scale ``s`` eliminated
(Frisch-Waugh). The information on ``L`` is in the speed changes shorter than the knot
spacing (braking for corners, stop-and-go); on a trip whose only speed changes are two
slow ramps the spline takes almost all of it, and the least-squares estimate moves by
several tenths of a second with where the knots fall, far beyond its linearised standard
deviation. So the interval is not ``estimate +- k sd`` but the set of offsets that a
score test does not reject, each tested on its own (exact for a linear statistic of
Gaussian noise, however curved the cost is):

    r(L) = P y - s(L) P Y(t - L)                       (residual at the offset L)
    J(L) = s(L) P rho_h(t - L), orthogonalised to P Y(t - L)  (rho_h: a_x over +-0.5 s)
    S(L) = sum_i w_i J_i r_i
    Var S(L) = max(1, chi2_red) sum w J^2 + s0^2 Var(sum_i w_i J_i N(t_i - L))

(``P`` the weighted spline residual, ``w = 1/sigma^2``; ``S = <J, e> - s0 <J, N>`` at the
true offset whatever the fitted scale, ``s0`` the true scale ratio, at most
``max(|s|, (1 + speed scale bound) / (1 - accel_x scale bound))``; the second variance term the
stated IMU noise through the kernel, :func:`~imubounds.dynamic.sensors._timing.
_reference_variance`; without a stated noise a Bartlett HAC estimate over one knot span).
``L`` is accepted when ``|S(L)| <= k sd(L)`` (:func:`~imubounds.dynamic.sensors._timing.
score_interval`, k of the stream's share of alpha). The IMU noise's share of ``Var S``
varies slowly with ``L``: it is computed every :data:`ANCHOR_S` and the larger of the two
around ``L`` taken. The grid: every
:data:`~imubounds.dynamic.sensors._timing.COARSE_STEP_S` over ``[-MAX_OFFSET_S,
MAX_OFFSET_S]``, refined down to :data:`~imubounds.dynamic.sensors._timing.GRID_STEP_S` in
the cells where ``S`` changes sign or ``|S| / sd`` crosses the range of k (:data:`K_RANGE`)
in steps larger than :data:`Z_STEP`. The point estimate is the zero of ``S`` next to the
smallest residual sum of squares.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from imubounds.dynamic.sensors import _timing as TM

#: the range of k (the stream's share of alpha) whose acceptance boundary the grid
#: resolves to :data:`~imubounds.dynamic.sensors._timing.GRID_STEP_S`
K_RANGE = (2.5, 7.0)
#: spacing (s) of the offsets at which the stated IMU noise's share of Var S is computed
ANCHOR_S = 0.2
#: a coarse cell is refined when ``|S| / sd`` changes by more than this across it
Z_STEP = 0.5


class _Score:
    """``L -> (SSE, S, variance of S from the speed noise, scale)`` and ``L -> variance of
    S from the stated IMU noise`` (module docstring)."""

    def __init__(self, t: np.ndarray, y: np.ndarray, w: np.ndarray, it: np.ndarray,
                 Y: np.ndarray, knot_s: float, noise: Any, s_max: float) -> None:
        self.t, self.w, self.it, self.Y, self.noise = t, w, it, Y, noise
        self.s_max = s_max
        self.P = TM._Detrend(t, w, knot_s)
        self.dof = t.size - self.P.p - 2
        self.yt = self.P(y)
        self.band = max(1, int(round(knot_s / max(float(np.median(np.diff(t))), 1e-9))))

    def _parts(self, L: float) -> tuple[np.ndarray, np.ndarray, float] | None:
        """(J, r, scale) at the offset ``L``; None when the reference is flat."""
        t, w, it, Y, P = self.t, self.w, self.it, self.Y, self.P
        Yt = P(np.interp(t - L, it, Y))
        b = float(np.sum(w * Yt * Yt))
        if not b > 0:
            return None
        sc = float(np.sum(w * self.yt * Yt)) / b
        r = self.yt - sc * Yt
        h = TM.DERIV_HALF_S
        J = sc * P((np.interp(t - L + h, it, Y) - np.interp(t - L - h, it, Y)) / (2 * h))
        J -= float(np.sum(w * J * Yt)) / b * Yt
        return J, r, sc

    def __call__(self, L: float) -> tuple[float, float, float, float]:
        p = self._parts(L)
        if p is None:
            return math.inf, 0.0, math.inf, 0.0
        J, r, sc = p
        w = self.w
        sse = float(np.sum(w * r * r))
        var = max(1.0, sse / max(self.dof, 1)) * float(np.sum(w * J * J))
        if self.noise is None:
            # no stated IMU noise: a HAC estimate (Bartlett over one knot span)
            u = w * J * r
            hac = float(np.sum(u * u))
            for lag in range(1, min(self.band, u.size - 1) + 1):
                hac += 2.0 * (1.0 - lag / (self.band + 1)) * float(np.sum(u[lag:] * u[:-lag]))
            var = max(var, hac)
        return sse, float(np.sum(w * J * r)), var, sc

    def reference(self, L: float) -> float:
        """The variance of ``S(L)`` from the stated IMU noise (0 without one)."""
        p = self._parts(L) if self.noise is not None else None
        if p is None:
            return 0.0
        J, _, sc = p
        # S = <J, e> - s0 <J, N(t - L)> whatever the fitted scale (J is orthogonal to
        # P Y): the IMU noise enters with the true scale s0, at most s_max
        return TM._reference_variance(self.t - L, self.w * J, self.it, self.noise,
                                      max(abs(sc), self.s_max))


def _refine(Lc: np.ndarray, Sc: np.ndarray, dc: np.ndarray) -> list[float]:
    """The offsets to add inside the coarse cells (:data:`K_RANGE`, :data:`Z_STEP`)."""
    z = np.abs(Sc) / np.maximum(dc, 1e-300)
    out: list[float] = []
    per_cell = int(round(TM.COARSE_STEP_S / TM.GRID_STEP_S))
    for a in range(Lc.size - 1):
        za, zb = z[a], z[a + 1]
        sign = Sc[a] * Sc[a + 1] < 0
        span = min(za, zb) <= K_RANGE[1] and max(za, zb) >= K_RANGE[0]
        dz = abs(Sc[a] / dc[a] - Sc[a + 1] / dc[a + 1])
        if not (sign or span) or dz <= Z_STEP:
            continue
        n = min(per_cell, int(math.ceil(dz / Z_STEP)))
        out.extend(float(x) for x in np.linspace(Lc[a], Lc[a + 1], n + 1)[1:-1])
    return out


def speed_offset(
    t: np.ndarray,
    y: np.ndarray,
    sigma: float,
    imu_t: np.ndarray,
    accel: np.ndarray,
    method: str,
    noise: Any = None,
    max_abs: float = TM.MAX_OFFSET_S,
    knot_s: float = TM.KNOT_S,
    s_max: float = 1.0,
) -> TM.OffsetEstimate | None:
    """The clock offset of a forward-speed stream ``y`` at ``t`` (m/s, sigma) against the
    IMU's forward acceleration ``accel`` at ``imu_t`` (the sample ends), by the score test
    of the module docstring. ``noise`` the stated noise of accel_x (a
    :class:`~imubounds.dynamic.estimator.budget.ChannelNoise`), ``s_max`` the largest
    true ratio of the speed's scale to the IMU's (stated scale bounds). None when too few epochs
    (a fitted scale far from 1 does not void the test: the interval is then wide)."""
    prep = TM._prepare(t, y, sigma, 0.0, imu_t, accel, None, max_abs)
    if prep is None:
        return None
    t, y, sig, _, it, Y = prep
    score = _Score(t, y, 1.0 / sig**2, it, Y, knot_s, noise, s_max)
    if score.dof < 10:
        return None
    Lc = np.arange(-max_abs, max_abs + TM.COARSE_STEP_S / 2, TM.COARSE_STEP_S)
    # the IMU noise's variance at anchors every ANCHOR_S (smooth in L); between two, the
    # larger of theirs
    La = np.linspace(-max_abs, max_abs, int(round(2 * max_abs / ANCHOR_S)) + 1)
    va = np.array([score.reference(float(x)) for x in La])

    def at(x: float) -> tuple[float, float, float, float]:
        sse, S, var, sc = score(x)
        i = int(np.clip(np.searchsorted(La, x), 1, La.size - 1))
        return sse, S, math.sqrt(var + max(va[i - 1], va[i])), sc

    res = {float(x): at(float(x)) for x in Lc}
    Sc = np.array([res[float(x)][1] for x in Lc])
    dc = np.array([res[float(x)][2] for x in Lc])
    for x in _refine(Lc, Sc, dc):
        res[x] = at(x)
    L = np.array(sorted(res))
    sse, S, sd = (np.array([res[float(x)][i] for x in L]) for i in range(3))
    j = int(np.argmin(sse))
    est, slope = float(L[j]), 0.0
    for a in (j - 1, j):  # the zero of S in a cell next to the smallest SSE
        if 0 <= a < L.size - 1 and S[a] * S[a + 1] <= 0 and S[a] != S[a + 1]:
            est = float(L[a] + (L[a + 1] - L[a]) * S[a] / (S[a] - S[a + 1]))
            slope = float((S[a + 1] - S[a]) / (L[a + 1] - L[a]))
            break
    sd_L = float(np.interp(est, L, sd)) / abs(slope) if slope else max_abs
    out = TM.OffsetEstimate(est, min(sd_L, max_abs), method, False, int(t.size), 0.0)
    out.score = (L, S, sd, np.zeros(L.size))
    return out


def level_acceleration(
    drive: Any, te: np.ndarray, cn: Any
) -> tuple[np.ndarray, Any, bool]:
    """(forward acceleration less the gravity of the pitch, the accel_x noise with the
    attitude's error added, whether the pitch was taken off). The accelerometer reads
    ``a_x = du/dt + g sin(theta)``: with an attitude stream, ``g sin(theta)`` at its
    pitch (interpolated to the IMU samples) is taken off and its error (sigma a third of
    ``attitude.bound_deg``) joins the white noise as ``g sigma sqrt(attitude step)``;
    without one the pitch stays in (level ground is then an assumption of the estimate,
    which is reported only: :func:`estimate_velocity`)."""
    import dataclasses

    from imubounds.units import G0

    acc = np.asarray(drive.imu.accel[:, 0], float)
    att = drive.attitude
    if att is None or att.t.size < 2 or not np.isfinite(att.pitch_rad).all():
        return acc, cn, False
    th = np.interp(te, np.asarray(att.t, float), np.asarray(att.pitch_rad, float))
    acc = acc - G0 * np.sin(th)
    if cn is not None:
        sd = math.radians(float(drive.settings.attitude.bound_deg)) / 3.0
        step = TM._median_step(np.asarray(att.t, float))
        cn = dataclasses.replace(cn, N=math.hypot(cn.N, G0 * sd * math.sqrt(step)))
    return acc, cn, True


#: why a body-velocity offset without an attitude stream is reported, not applied
NO_PITCH = ("reported, not applied: no attitude stream, so the forward acceleration "
            "holds the gravity of the pitch, which the spline takes only where it changes "
            "slowly (on hills with sharp corners the estimate is off by up to 0.2 s); the "
            "stamps are taken as exact (an assumption)")


def estimate_velocity(
    drive: Any, stamp: str, noise: dict[str, Any] | None = None
) -> TM.OffsetEstimate | None:
    """The body-velocity stream's (wheel, DVL) clock offset against the IMU: its forward
    speed against the integrated forward acceleration (:func:`speed_offset`), less the
    gravity of the attitude stream's pitch (:func:`level_acceleration`; the IMU's bias
    drift taken by the spline), sigma a third of the stated bound. Without an attitude
    stream it is reported only (:data:`NO_PITCH`)."""
    bv, imu = drive.velocity, drive.imu
    if bv is None or imu is None or getattr(imu, "accel", None) is None:
        return None
    te, _ = TM._sample_ends(imu.t, stamp)
    sig = float(drive.settings.velocity.bound_mps)
    sig = sig / 3.0 if sig > 0 else 0.05
    cn = None if noise is None else noise.get("accel_x")
    # the true scale of the speed against the integrated acceleration: at most this
    s_max = (1.0 + float(drive.settings.velocity.scale)) / max(
        1.0 - (0.0 if cn is None else float(cn.scale)), 0.5)
    acc, cn, level = level_acceleration(drive, te, cn)
    how = "less the gravity of the attitude's pitch" if level else "(level ground assumed)"
    est = speed_offset(np.asarray(bv.t, float), np.asarray(bv.u_mps, float), sig, te, acc,
                       f"{bv.kind} speed against the integrated forward acceleration {how} "
                       "(score test inverted over the offsets)", noise=cn, s_max=s_max)
    if est is not None and not level:
        est.report_why = NO_PITCH
    return est
