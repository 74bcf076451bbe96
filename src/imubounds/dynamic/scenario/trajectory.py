"""3-D rigid-body truth of a ground vehicle: position, velocity, attitude, rate, specific force.

Conventions (:mod:`imubounds.frames`): navigation frame ENU at the trip's origin,
body frame FLU (x forward, y left, z up), model heading ``psi`` counter-clockwise
from east, roll ``phi`` positive right side down, pitch ``theta`` positive nose up.
The body-to-ENU rotation is ``R = Rz(psi) Ry(-theta) Rx(phi)`` (the attitude a
quaternion ``qw, qx, qy, qz`` body->ENU of the drive layout describes).

The path is laid out by its horizontal arc length ``s``: straights and
right-angle left corners of a rounded rectangle (raised-cosine curvature, so
heading, curvature and its slope are continuous), altitude ``h(s)`` and road
bank from sums of sinusoids with whole periods per trip (the trip closes), and
a speed profile ``s(t)`` of constant-speed pieces joined by raised-cosine ramps
(speed and acceleration continuous). The vehicle does not slip: its velocity is
along body x, so body velocity is ``(V, 0, 0)``, pitch is the path's climb
angle ``atan(dh/ds)`` and roll is the road bank plus a body roll proportional
to the lateral acceleration.

From these closed forms, with ``V`` the 3-D speed,

* body rate ``w = (phi' + psi' sin(theta), -theta' cos(phi) + psi' cos(theta) sin(phi),
  theta' sin(phi) + psi' cos(theta) cos(phi))`` (from ``R^T R' = [w]x``);
* specific force ``f = R^T (a_nav - g_nav) = (V', V w_z, -V w_y)
  + g (sin(theta), cos(theta) sin(phi), cos(theta) cos(phi))`` with ``g_nav = (0, 0, -g)``,
  ``g`` = :data:`imubounds.units.G0`.

So ``f_x = u' - r v + g sin(theta)`` and ``f_y = v' + r u + g sin(phi) cos(theta)``
(METHOD.md 4.3) with ``v = 0``. Positions are exact up to the corner integrals,
evaluated by Gauss-Legendre quadrature (error below 1e-9 m).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from imubounds.dynamic.scenario.config import ScenarioConfig
from imubounds.errors import OptionError
from imubounds.frames import compass_to_model
from imubounds.units import DEG, G0

Array = np.ndarray

_GL_CORNER = np.polynomial.legendre.leggauss(24)  # positions inside a corner
_GL_PIECE = np.polynomial.legendre.leggauss(64)  # the displacement of a whole corner


# ----------------------------------------------------------------------------- path


@dataclass(frozen=True)
class _Pieces:
    s0: Array  # start arc length of each piece, m
    length: Array
    corner: Array  # bool
    psi0: Array  # model heading at the start, rad
    e0: Array
    n0: Array


def _layout(cfg: ScenarioConfig) -> tuple[list[float], list[bool]]:
    """Piece lengths along the path (straights and corners) of the rounded rectangle."""
    lap = cfg.distance_m / cfg.laps
    lc = cfg.corner_length_m
    straight = lap - 4 * lc
    if straight <= 0:
        raise OptionError(
            f"--corner-length ({lc:g} m) too long: four corners do not fit in a lap of {lap:g} m"
        )
    l1 = straight / 2 * cfg.aspect / (1 + cfg.aspect)
    l2 = straight / 2 - l1
    lengths: list[float] = []
    corner: list[bool] = []

    def add(length: float, is_corner: bool) -> None:
        if not is_corner and lengths and not corner[-1]:
            lengths[-1] += length
        else:
            lengths.append(length)
            corner.append(is_corner)

    for _ in range(cfg.laps):
        # start in the middle of a long side so the speed ramps are on a straight
        add(l1 / 2, False)
        for side in (l2, l1, l2):
            add(lc, True)
            add(side, False)
        add(lc, True)
        add(l1 / 2, False)
    return lengths, corner


class Path:
    """Horizontal geometry by arc length: heading, curvature and position (ENU, m)."""

    def __init__(self, cfg: ScenarioConfig) -> None:
        lengths, corner = _layout(cfg)
        self.lc = cfg.corner_length_m
        self.total = float(sum(lengths))
        psi = float(compass_to_model(math.radians(cfg.heading0_deg)))
        s0, psi0, e0, n0 = [], [], [], []
        s = e = n = 0.0
        for L, c in zip(lengths, corner, strict=True):
            s0.append(s)
            psi0.append(psi)
            e0.append(e)
            n0.append(n)
            if c:
                x, w = _GL_PIECE
                xs = 0.5 * L * (x + 1.0)
                ps = psi + self._turn(xs)
                e += 0.5 * L * float(np.dot(w, np.cos(ps)))
                n += 0.5 * L * float(np.dot(w, np.sin(ps)))
                psi += 0.5 * math.pi
            else:
                e += L * math.cos(psi)
                n += L * math.sin(psi)
            s += L
        self.p = _Pieces(
            np.array(s0),
            np.array(lengths),
            np.array(corner),
            np.array(psi0),
            np.array(e0),
            np.array(n0),
        )

    def _turn(self, x: Array) -> Array:
        """Heading gained ``x`` metres into a corner (raised-cosine curvature, pi/2 in total)."""
        L = self.lc
        return (math.pi / (2 * L)) * (x - L / (2 * math.pi) * np.sin(2 * math.pi * x / L))

    def _where(self, s: Array) -> tuple[Array, Array]:
        i = np.clip(np.searchsorted(self.p.s0, s, side="right") - 1, 0, self.p.s0.size - 1)
        x = np.clip(s - self.p.s0[i], 0.0, self.p.length[i])
        return i, x

    def heading(self, s: Array) -> tuple[Array, Array, Array]:
        """Model heading psi (rad, CCW from east, continuous), curvature (1/m) and its
        derivative by arc length (1/m^2)."""
        i, x = self._where(s)
        c = self.p.corner[i]
        L = self.lc
        xc = np.where(c, x, 0.0)
        psi = self.p.psi0[i] + np.where(c, self._turn(xc), 0.0)
        kap = np.where(c, (math.pi / (2 * L)) * (1.0 - np.cos(2 * math.pi * xc / L)), 0.0)
        dkap = np.where(c, (math.pi / L) ** 2 * np.sin(2 * math.pi * xc / L), 0.0)
        return psi, kap, dkap

    def position(self, s: Array) -> tuple[Array, Array]:
        """East and north (m) of the point at arc length ``s``."""
        i, x = self._where(s)
        psi0 = self.p.psi0[i]
        e = self.p.e0[i] + x * np.cos(psi0)
        n = self.p.n0[i] + x * np.sin(psi0)
        c = self.p.corner[i]
        if np.any(c):
            xc = x[c]
            g, w = _GL_CORNER
            nodes = 0.5 * xc[:, None] * (g[None, :] + 1.0)
            ps = psi0[c][:, None] + self._turn(nodes)
            e[c] = self.p.e0[i][c] + 0.5 * xc * np.einsum("qj,j->q", np.cos(ps), w)
            n[c] = self.p.n0[i][c] + 0.5 * xc * np.einsum("qj,j->q", np.sin(ps), w)
        return e, n


# ----------------------------------------------------------------------------- speed


class SpeedProfile:
    """Arc length s(t), speed s'(t) and acceleration s''(t) along the horizontal path.

    Pieces of constant speed joined by raised-cosine ramps; at rest before 0 and
    after the end.
    """

    def __init__(self, t0: Array, T: Array, s0: Array, va: Array, vb: Array) -> None:
        self.t0, self.T, self.s0, self.va, self.vb = t0, T, s0, va, vb
        self.t_end = float(t0[-1] + T[-1])
        self.s_end = float(s0[-1] + 0.5 * (va[-1] + vb[-1]) * T[-1])

    def eval(self, t: Array) -> tuple[Array, Array, Array]:
        t = np.asarray(t, dtype=float)
        i = np.clip(np.searchsorted(self.t0, t, side="right") - 1, 0, self.t0.size - 1)
        T = self.T[i]
        tau = np.clip(t - self.t0[i], 0.0, T)
        x = tau / T
        va, dv = self.va[i], self.vb[i] - self.va[i]
        s = self.s0[i] + va * tau + 0.5 * dv * (tau - T / math.pi * np.sin(math.pi * x))
        sd = va + 0.5 * dv * (1.0 - np.cos(math.pi * x))
        sdd = dv * math.pi / (2 * T) * np.sin(math.pi * x)
        before = t < self.t0[0]
        after = t > self.t_end
        s = np.where(before, 0.0, np.where(after, self.s_end, s))
        sd = np.where(before | after, 0.0, sd)
        sdd = np.where(before | after, 0.0, sdd)
        return s, sd, sdd


def _speed_plan(
    cfg: ScenarioConfig, lengths: Array, corner: Array
) -> tuple[SpeedProfile, float, float]:
    """The speed profile covering the path in ``duration_s``: (profile, cruise, corner speed).

    When the corners need no slowing, the speed ramps up over ``ramp_s``, cruises and ramps
    down (corners may fall in a ramp); otherwise the vehicle slows before each corner to
    keep the lateral acceleration under ``max_lateral_accel_mps2`` (ramps on the straights).
    """
    kpeak = math.pi / cfg.corner_length_m
    vc_max = math.sqrt(cfg.max_lateral_accel_mps2 / kpeak)
    a_long = cfg.max_long_accel_mps2
    Tr = cfg.ramp_s
    npiece = lengths.size
    total_length = float(np.sum(lengths))

    def plan(V: float) -> list[tuple[float, float, float]] | None:
        """[(duration, v_start, v_end)] for each segment, None if it does not fit."""
        if V <= vc_max:  # no corner needs slowing: ramp up, cruise, ramp down (anywhere)
            cruise = total_length - V * Tr
            if cruise < 0:
                return None
            return [(Tr, 0.0, V), (cruise / V, V, V), (Tr, V, 0.0)]
        vc = vc_max
        segs: list[tuple[float, float, float]] = []
        for k in range(npiece):
            L = float(lengths[k])
            if corner[k]:
                segs.append((L / vc, vc, vc))
                continue
            vin = 0.0 if k == 0 else vc
            vout = 0.0 if k == npiece - 1 else vc
            tin = Tr if vin == 0.0 else math.pi * (V - vin) / (2 * a_long)
            tout = Tr if vout == 0.0 else math.pi * (V - vout) / (2 * a_long)
            lin = 0.5 * (vin + V) * tin
            lout = 0.5 * (vout + V) * tout
            cruise = L - lin - lout
            if cruise < 0:
                return None
            if tin > 0:
                segs.append((tin, vin, V))
            if cruise > 0:
                segs.append((cruise / V, V, V))
            if tout > 0:
                segs.append((tout, V, vout))
        return segs

    def total(V: float) -> float:
        segs = plan(V)
        return math.inf if segs is None else sum(s[0] for s in segs)

    D = cfg.duration_s
    lo = float(np.sum(lengths)) / D
    if plan(lo) is None:
        raise OptionError(
            "the straights are too short for the speed ramps; lengthen --distance or "
            "--duration, or shorten --corner-length"
        )
    # the fastest cruise whose ramps still fit on the straights
    hi = lo
    while plan(hi * 2.0) is not None and hi < 1e4:
        hi *= 2.0
    top = hi * 2.0
    for _ in range(100):
        mid = 0.5 * (hi + top)
        if plan(mid) is None:
            top = mid
        else:
            hi = mid
    if total(hi) > D:
        raise OptionError(
            f"cannot cover {cfg.distance_m:g} m in {D:g} s with speed ramps on the straights "
            "and slow corners; lengthen --duration, or --distance, or --corner-length"
        )
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if total(mid) > D:
            lo = mid
        else:
            hi = mid
        if hi - lo < 1e-13 * hi:
            break
    V = 0.5 * (lo + hi)
    segs = plan(V)
    assert segs is not None
    dur = np.array([s[0] for s in segs])
    va = np.array([s[1] for s in segs])
    vb = np.array([s[2] for s in segs])
    t0 = np.concatenate([[0.0], np.cumsum(dur)[:-1]])
    lens = 0.5 * (va + vb) * dur
    s0 = np.concatenate([[0.0], np.cumsum(lens)[:-1]])
    return SpeedProfile(t0, dur, s0, va, vb), V, min(V, vc_max)


# ----------------------------------------------------------------------------- terrain


class Terrain:
    """Altitude h(s) (m) and road bank (rad) from sinusoids with whole periods per trip."""

    HILLS = ((1.0, 5), (0.27, 23))  # (relative amplitude, periods per trip)
    BANK = ((0.7, 7), (0.3, 17))

    def __init__(self, cfg: ScenarioConfig, total_s: float, rng: np.random.Generator) -> None:
        self.S = total_s
        self.amp = cfg.hill_amplitude_m
        self.bank = cfg.bank_deg * DEG
        self.hill_phase = rng.uniform(0, 2 * math.pi, len(self.HILLS))
        self.bank_phase = rng.uniform(0, 2 * math.pi, len(self.BANK))

    def altitude(self, s: Array) -> tuple[Array, Array, Array]:
        """h, dh/ds, d2h/ds2."""
        h = np.zeros_like(s)
        h1 = np.zeros_like(s)
        h2 = np.zeros_like(s)
        if self.amp:
            for (a, m), p in zip(self.HILLS, self.hill_phase, strict=True):
                k = 2 * math.pi * m / self.S
                A = a * self.amp
                h += A * (np.sin(k * s + p) - math.sin(p))
                h1 += A * k * np.cos(k * s + p)
                h2 -= A * k * k * np.sin(k * s + p)
        return h, h1, h2

    def road_bank(self, s: Array) -> tuple[Array, Array]:
        """Bank angle (rad, positive right side down) and its derivative by arc length."""
        b = np.zeros_like(s)
        db = np.zeros_like(s)
        if self.bank:
            for (a, m), p in zip(self.BANK, self.bank_phase, strict=True):
                k = 2 * math.pi * m / self.S
                b += a * self.bank * np.sin(k * s + p)
                db += a * self.bank * k * np.cos(k * s + p)
        return b, db


class Bumps:
    """Heave of the body over road bumps: ``z = H sin^4(pi x)``, ``x = (t - t_k)/D`` in
    [0, 1] for bumps starting at ``t_k = (k + 1/2) every``; z and its first three
    derivatives vanish at both ends (the vertical jerk is bounded)."""

    def __init__(self, cfg: ScenarioConfig) -> None:
        self.H = cfg.bump_height_m
        self.D = cfg.bump_duration_s
        self.every = cfg.bump_every_s

    def heave(self, t: Array) -> tuple[Array, Array, Array]:
        """z (m), dz/dt (m/s), d2z/dt2 (m/s^2) at the instants ``t``."""
        z = np.zeros_like(t)
        if not self.H:
            return z, z.copy(), z.copy()
        x = (t - 0.5 * self.every) / self.every
        x = (x - np.floor(x)) * self.every / self.D  # time into the current bump / D
        on = (t >= 0.5 * self.every) & (x < 1.0)
        w = math.pi / self.D
        s, c = np.sin(math.pi * x), np.cos(math.pi * x)
        z = np.where(on, self.H * s**4, 0.0)
        zd = np.where(on, 4 * self.H * w * s**3 * c, 0.0)
        zdd = np.where(on, self.H * w * w * (12 * s * s * c * c - 4 * s**4), 0.0)
        return z, zd, zdd


# ----------------------------------------------------------------------------- trajectory


class Trajectory:
    """The continuous truth of a trip (see the module docstring)."""

    def __init__(self, cfg: ScenarioConfig, rng: np.random.Generator) -> None:
        self.path = Path(cfg)
        p = self.path.p
        self.speed, self.cruise_mps, self.corner_mps = _speed_plan(cfg, p.length, p.corner)
        self.terrain = Terrain(cfg, self.path.total, rng)
        self.roll_gain = cfg.roll_gain_deg_per_mps2 * DEG
        self.bumps = Bumps(cfg)
        self.g = G0

    def kinematics(self, t: Array, positions: bool = True) -> dict[str, Array]:
        """Every true quantity at the instants ``t`` (s), SI, ENU / FLU.

        Keys: ``east, north, up`` (m), ``vel_enu`` (n, 3) and ``acc_enu`` (n, 3),
        ``roll, pitch, yaw`` (rad; yaw is the model heading, continuous),
        ``speed`` (3-D path speed, m/s), ``body_vel`` (n, 3: the path speed along x
        plus the heave of road bumps), ``s`` (horizontal arc length), ``gyro`` (n, 3) body
        rate and ``accel`` (n, 3) specific force, ``lat_acc`` (m/s^2, horizontal).
        """
        t = np.asarray(t, dtype=float)
        s, sd, sdd = self.speed.eval(t)
        psi, kap, dkap = self.path.heading(s)
        east, north = self.path.position(s) if positions else (s * np.nan, s * np.nan)
        h, h1, h2 = self.terrain.altitude(s)
        bank, dbank = self.terrain.road_bank(s)
        q = np.sqrt(1.0 + h1 * h1)
        ct, st = 1.0 / q, h1 / q
        thd = h2 * sd / (q * q)
        psd = kap * sd
        lat = sd * sd * kap
        roll = self.roll_gain * lat + bank
        rolld = self.roll_gain * (2 * sd * sdd * kap + sd**3 * dkap) + dbank * sd
        V = sd * q
        Vd = sdd * q + sd * sd * h1 * h2 / q
        cp, sp = np.cos(roll), np.sin(roll)
        wx = rolld + psd * st
        wy = -thd * cp + psd * ct * sp
        wz = thd * sp + psd * ct * cp
        g = self.g
        fx = Vd + g * st
        fy = V * wz + g * ct * sp
        fz = -V * wy + g * ct * cp
        cps, sps = np.cos(psi), np.sin(psi)
        z, zd, zdd = self.bumps.heave(t)
        # heave along ENU up: R^T e_up = (sin theta, cos theta sin phi, cos theta cos phi)
        up_b = np.column_stack([st, ct * sp, ct * cp])
        fx = fx + zdd * up_b[:, 0]
        fy = fy + zdd * up_b[:, 1]
        fz = fz + zdd * up_b[:, 2]
        vel = np.column_stack([sd * cps, sd * sps, sd * h1 + zd])
        acc = np.column_stack(
            [sdd * cps - lat * sps, sdd * sps + lat * cps, sdd * h1 + sd * sd * h2 + zdd]
        )
        body = zd[:, None] * up_b
        body[:, 0] += V
        return {
            "t": t,
            "s": s,
            "east": east,
            "north": north,
            "up": h + z,
            "vel_enu": vel,
            "acc_enu": acc,
            "roll": roll,
            "pitch": np.arctan(h1),
            "yaw": psi,
            "speed": V,
            "body_vel": body,
            "lat_acc": lat,
            "gyro": np.column_stack([wx, wy, wz]),
            "accel": np.column_stack([fx, fy, fz]),
        }

    def imu_truth(self, n: int, dt: float) -> dict[str, Array]:
        """The truth at the IMU sample times ``t_k = k dt`` (k < n) and what a noiseless IMU
        reads there: the means of the specific force and body rate over ``[t_k - dt, t_k]``
        (each sample is stamped at the end of its averaging period).

        One evaluation on the half-period grid serves both: Simpson's rule per period
        (error below 1e-9 in SI units where the motion is smooth), the forward
        acceleration V' exactly as the speed difference. Returns :meth:`kinematics`
        at the samples with ``accel_mean`` and ``gyro_mean`` (n, 3) added.
        """
        th = (np.arange(2 * n + 1) - 2) * (0.5 * dt)  # -dt, -dt/2, 0, dt/2, ...
        k = self.kinematics(th, positions=False)
        even = slice(2, None, 2)

        def simpson(a: Array) -> Array:
            return (a[0:-2:2] + 4.0 * a[1:-1:2] + a[2::2]) / 6.0

        acc = simpson(k["accel"])
        gyr = simpson(k["gyro"])
        sp = k["speed"]
        acc[:, 0] = (sp[2::2] - sp[0:-2:2]) / dt + self.g * simpson(np.sin(k["pitch"]))
        if self.bumps.H:
            # the heave's share d2z/dt2 (sin theta, cos theta sin phi, cos theta cos phi):
            # its mean over the period as (dz/dt(t_k) - dz/dt(t_k - dt))/dt exactly
            # times the mean direction (Simpson's rule is off by 1e-5 m/s^2 on a bump)
            _, zd, zdd = self.bumps.heave(th)
            pt, rl = k["pitch"], k["roll"]
            up_b = np.column_stack(
                [np.sin(pt), np.cos(pt) * np.sin(rl), np.cos(pt) * np.cos(rl)]
            )
            exact = (zd[2::2] - zd[0:-2:2]) / dt
            acc[:, 0] += simpson(zdd * up_b[:, 0])
            acc += (exact - simpson(zdd))[:, None] * simpson(up_b)
        out = {name: v[even] for name, v in k.items()}
        out["east"], out["north"] = self.path.position(out["s"])
        out["accel_mean"] = acc
        out["gyro_mean"] = gyr
        return out


def body_from_enu(v: Array, roll: Array, pitch: Array, yaw: Array) -> Array:
    """ENU vectors (n, 3) in body FLU axes: ``R^T v`` with ``R = Rz(yaw) Ry(-pitch) Rx(roll)``."""
    cy, sy = np.cos(yaw), np.sin(yaw)
    x = cy * v[:, 0] + sy * v[:, 1]  # Rz^T
    y = -sy * v[:, 0] + cy * v[:, 1]
    z = v[:, 2]
    cp, sp = np.cos(pitch), np.sin(pitch)
    x, z = cp * x + sp * z, -sp * x + cp * z  # Ry(-pitch)^T
    cr, sr = np.cos(roll), np.sin(roll)
    y, z = cr * y + sr * z, -sr * y + cr * z  # Rx^T
    return np.column_stack([x, y, z])
