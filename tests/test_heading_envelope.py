"""The heading between its epochs (aided/positions._envelope_integrals,
aided/heading.heading_mean): psi_dot_abs bounds the MEAN |psi'| over a span, not the
rate at each time, so an envelope with that slope misses a heading that turns early and
comes back late within one gap. Both are checked against headings built here: a
plateau (rise, hold, return within one fix gap: twice the old envelope's integral) and
hypothesis-drawn piecewise-linear headings within the rate cap, their integral of |psi'|
and their end boxes. The envelope's rate bound from the gyros' samples
(aided/heading.psi_rate_bound) against a turn at the angular-acceleration bound with the
gyro errors at their bound, with a check that a rate below the truth's fails, and
against the simulator's truth at sharp corners."""

from __future__ import annotations

import math
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import imubounds.dynamic.estimator.aided.heading as H
import imubounds.dynamic.estimator.aided.positions as P
from imubounds.interval import IntervalArray as IA

MAX_RATE = math.radians(90.0)
TILT = math.radians(10.0)
CAP = MAX_RATE / math.cos(TILT)


def _profile(knots_t: np.ndarray, knots_psi: np.ndarray, n: int = 20001) -> tuple[Any, ...]:
    """A piecewise-linear heading on [0, 1]: fine samples, its integral of |psi'|."""
    t = np.linspace(0.0, 1.0, n)
    psi = np.interp(t, knots_t, knots_psi)
    return t, psi, float(np.sum(np.abs(np.diff(knots_psi))))


def _stub(monkeypatch: Any, module: Any, t_end: float, psi_a: IA, psi_b: IA,
          integral: float) -> Any:
    """w with the vehicle's rate cap (psi_rate_bound: CAP, no offset); heading_at gives
    the end boxes, psi_dot_abs the MEAN |psi'| over [a, b] (integral / length: what it
    bounds)."""
    def heading_at(w: Any, t: np.ndarray, own_q: bool = True) -> IA:
        t = np.asarray(t, float)
        lo = np.where(t <= 0.0, psi_a.lo, psi_b.lo)
        hi = np.where(t <= 0.0, psi_a.hi, psi_b.hi)
        return IA(lo, hi)

    def psi_dot_abs(w: Any, a: np.ndarray, b: np.ndarray, own_q: bool = True) -> np.ndarray:
        a, b = np.asarray(a, float), np.asarray(b, float)
        return np.full(a.shape, integral * (1 + 1e-12) / max(t_end, 1e-300))

    def psi_rate_bound(w: Any, a: np.ndarray, b: np.ndarray,
                       own_q: bool = True) -> tuple[np.ndarray, np.ndarray]:
        a = np.asarray(a, float)
        return np.full(a.shape, CAP), np.zeros(a.shape)

    monkeypatch.setattr(module, "heading_at", heading_at)
    monkeypatch.setattr(module, "psi_dot_abs", psi_dot_abs)
    if hasattr(module, "psi_rate_bound"):
        monkeypatch.setattr(module, "psi_rate_bound", psi_rate_bound)
    return SimpleNamespace(veh=SimpleNamespace(max_rate=MAX_RATE, max_tilt=TILT), cache={})


def _check(kt: np.ndarray, kp: np.ndarray, h: float, psi0: float) -> None:
    t, psi, integral = _profile(kt, kp)
    pa = IA(np.array([psi[0] - h]), np.array([psi[0] + h]))
    pb = IA(np.array([psi[-1] - h]), np.array([psi[-1] + h]))
    with pytest.MonkeyPatch.context() as mp:
        w = _stub(mp, P, 1.0, pa, pb, integral)
        i1, i2 = P._envelope_integrals(w, np.array([0.0]), np.array([1.0]),
                                       np.array([psi0]))
    dev = psi - psi0
    true1 = float(np.trapezoid(np.abs(dev), t))
    true2 = float(np.trapezoid(dev * dev, t))
    assert true1 <= i1[0] * (1 + 1e-6) + 1e-9, (true1, i1[0])
    assert true2 <= i2[0] * (1 + 1e-6) + 1e-9, (true2, i2[0])


def test_plateau_within_one_gap_is_enclosed() -> None:
    """Rise to 0.1 rad at the rate cap, hold, return at the end of the gap: the integral
    of |psi - 0| is 0.094 rad s, where an envelope of slope mean|psi'| (0.2 rad/s) gives
    0.05; the envelope with the rate cap and the integral's cap encloses it."""
    rise = 0.1 / CAP
    kt = np.array([0.0, rise, 1.0 - rise, 1.0])
    kp = np.array([0.0, 0.1, 0.1, 0.0])
    t, psi, _ = _profile(kt, kp)
    assert float(np.trapezoid(psi, t)) > 0.09  # twice the old envelope's 0.05
    _check(kt, kp, 0.0, 0.0)


@settings(max_examples=200, deadline=None)
@given(
    st.lists(st.floats(-0.3, 0.3), min_size=2, max_size=7),
    st.floats(0.0, 0.05),
    st.floats(-0.2, 0.2),
    st.randoms(use_true_random=False),
)
def test_envelope_encloses_any_heading_within_its_bounds(
    values: list[float], h: float, psi0: float, rnd: Any
) -> None:
    """Piecewise-linear headings whose slopes stay within the rate cap (the knots'
    times spaced to keep every slope <= CAP), any end boxes of half-width h."""
    kp = np.array(values)
    need = np.abs(np.diff(kp)) / CAP  # the least time each piece takes at the cap
    if need.sum() > 1.0:
        kp = kp * (0.99 / need.sum())
        need = np.abs(np.diff(kp)) / CAP
    spare = 1.0 - need.sum()
    cuts = np.array([rnd.random() for _ in range(need.size)])
    dur = need + spare * cuts / max(cuts.sum(), 1e-12)
    kt = np.concatenate([[0.0], np.cumsum(dur)])
    kt[-1] = 1.0
    _check(kt, kp, h, psi0)


def test_heading_mean_holds_an_excursion_between_heading_epochs(monkeypatch: Any) -> None:
    """heading_mean over [0, 10] with heading epochs at 0, 1, ..., 10 (boxes +-0.01 about
    0): a 0.1 rad plateau inside one gap ([4, 5]) while the heading is still elsewhere:
    the hull must reach 0.1 although the mean |psi'| over the window is 0.02 rad/s."""
    ht = np.arange(0.0, 11.0)
    integ = {(4.0, 5.0): 0.2}

    def psi_dot_abs(w: Any, a: np.ndarray, b: np.ndarray, own_q: bool = True) -> np.ndarray:
        a, b = np.asarray(a, float), np.asarray(b, float)
        out = np.zeros(a.shape)
        for (s0, s1), v in integ.items():  # the integral of |psi'| that falls in [a, b]
            out += v * np.clip((np.minimum(b, s1) - np.maximum(a, s0)) / (s1 - s0), 0, 1)
        return out * (1 + 1e-12) / np.maximum(b - a, 1e-300)

    def heading_at(w: Any, t: np.ndarray, own_q: bool = True) -> IA:
        t = np.asarray(t, float)
        return IA(np.full(t.shape, -0.01), np.full(t.shape, 0.01))

    monkeypatch.setattr(H, "psi_dot_abs", psi_dot_abs)
    monkeypatch.setattr(H, "heading_at", heading_at)
    ag = SimpleNamespace(head_t=ht, head_c=np.zeros(ht.size), head_h=np.full(ht.size, 0.01))
    w = SimpleNamespace(ag=ag, cache={}, veh=SimpleNamespace(max_rate=MAX_RATE,
                                                             max_tilt=TILT))
    hull = H.heading_mean(w, np.array([0.0, 0.0]), np.array([10.0, 3.0]))
    assert hull.hi[0] >= 0.1 - 1e-12 and hull.lo[0] <= -0.01  # the window holding [4, 5]
    assert hull.hi[1] < 0.02  # a window without the excursion stays tight


# ---------------------------------------------------------------- the rate from the gyros

DT = 0.025  # a 40 Hz IMU
D_ANG = 20.0  # the stated angular-acceleration bound, rad/s^2 (the turn ramps at it)
E0 = 0.02  # the gyros' per-sample error bound, rad/s
SCALE = 0.01  # the scale-error bound
R_PEAK = 1.2  # the turn's rate, rad/s (below the vehicle's cap CAP = 1.59)
TILT_B = math.radians(5.0)  # the tilt bound the windows see (the truth is level)


def _turn_rate(t: np.ndarray) -> np.ndarray:
    """True yaw rate on [0, 3] s: inside the fix gap [1, 2] a left turn from its start
    and a right turn back at its end, each ramping at the angular-acceleration bound to
    R_PEAK and holding it: the heading rises 0.41 rad early and returns late."""
    r = np.zeros_like(t)
    ramp = R_PEAK / D_ANG
    for t0, t1, sgn in ((1.0, 1.4, 1.0), (1.6, 2.0, -1.0)):
        rise = np.clip((t - t0) / ramp, 0.0, 1.0)
        fall = np.clip((t1 - t) / ramp, 0.0, 1.0)
        r += sgn * R_PEAK * np.minimum(rise, fall)
    return r


def _gyro_turn(bias: float, seed: int, against: bool = False) -> tuple[Any, ...]:
    """The truth on a fine grid (t, psi, psi') and a window context over real
    PiecewiseSignal samples: each gyro sample the period mean of the true rate, shrunk
    by the scale error's bound, plus biased Gaussian noise clipped to +-E0 (so at its
    bound on many samples; ``against``: gyro_z's error E0 against the rate on every
    sample, the lowest samples the bounds allow); heading epochs at 0, 1, 2, 3 s with
    +-0.01 rad boxes."""
    from imubounds.dynamic.estimator.aided.common import WindowContext
    from imubounds.dynamic.estimator.inputs import PiecewiseSignal, Vehicle

    tf = np.linspace(0.0, 3.0, 300001)
    rf = _turn_rate(tf)
    psi = np.concatenate([[0.0], np.cumsum(0.5 * (rf[1:] + rf[:-1]) * np.diff(tf))])
    bnd = np.linspace(0.0, 3.0, 121)
    mu = np.diff(np.interp(bnd, tf, psi)) / DT  # the true period means
    rng = np.random.default_rng(seed)
    err = np.clip(bias + 0.4 * E0 * rng.standard_normal((2, mu.size)), -E0, E0)
    assert np.mean(np.abs(err) >= E0) > 0.05  # the error at its bound on many samples
    if against:
        err[0] = -E0 * np.sign(mu)
    y = {"gyro_z": (1.0 - SCALE) * mu + err[0], "gyro_y": err[1]}  # true q = 0
    sig = {ch: PiecewiseSignal(bnd, v, xmax=MAX_RATE) for ch, v in y.items()}
    imu = SimpleNamespace(sig=sig, bnd=bnd, max_len=DT,
                          available={ch: True for ch in y},
                          rate_bound={ch: D_ANG for ch in y})
    veh = Vehicle(max_rate=MAX_RATE, max_tilt=TILT, max_ang_accel=D_ANG, max_speed=30.0)
    ht = np.array([0.0, 1.0, 2.0, 3.0])
    ag = SimpleNamespace(head_t=ht, head_c=np.interp(ht, tf, psi),
                         head_h=np.full(ht.size, 0.01), has_heading=True)
    hull = {"abs_sinr": math.sin(TILT_B), "sec_p_minus_1": 1.0 / math.cos(TILT_B) - 1.0}

    def tilt_hull(name: str, a: np.ndarray, b: np.ndarray) -> IA:
        shape = np.broadcast(np.asarray(a), np.asarray(b)).shape
        return IA(np.zeros(shape), np.full(shape, hull[name]))

    ctx = SimpleNamespace(imu=imu, vehicle=veh, aiding=ag,
                          tilt=SimpleNamespace(hull=tilt_hull),
                          noise={ch: SimpleNamespace(scale=SCALE) for ch in y},
                          E0={ch: E0 for ch in y})
    return tf, psi, rf, WindowContext(ctx)


def _worst_excess(tf: np.ndarray, rf: np.ndarray, a: float, b: float, rm: float) -> float:
    """``max over a <= s < t <= b of int_s^t |psi'| - rm (t - s)`` on the fine grid (the
    largest gain of the running integral over the line of slope rm)."""
    sel = (tf >= a) & (tf <= b)
    t, x = tf[sel], np.abs(rf[sel])
    y = np.concatenate([[0.0], np.cumsum(0.5 * (x[1:] + x[:-1]) * np.diff(t))]) - rm * t
    return float(np.max(y - np.minimum.accumulate(y)))


SPANS = [(1.0, 2.0), (0.0, 3.0), (1.0, 1.3), (1.13, 1.42), (1.3, 1.32), (1.95, 2.7)]


@pytest.mark.parametrize("bias,seed", [(-0.8 * E0, 3), (0.8 * E0, 4), (-0.5 * E0, 5)])
def test_rate_bound_holds_a_sharp_turn_with_the_gyro_error_at_its_bound(
    bias: float, seed: int
) -> None:
    """psi_rate_bound from the gyro samples (errors at their bound, the scale error
    shrinking them, the rate ramping at the angular-acceleration bound): on every span,
    ``int_s^t |psi'| <= Rm (t - s) + Cm`` for all [s, t] inside, and Rm >= the truth's
    largest rate where the span holds the turn; Rm far below the vehicle's cap; the
    envelope of the fix gap [1, 2] encloses the true heading's integrals."""
    tf, psi, rf, w = _gyro_turn(bias, seed)
    a = np.array([s[0] for s in SPANS])
    b = np.array([s[1] for s in SPANS])
    rm, cm = H.psi_rate_bound(w, a, b)
    for k, (s0, s1) in enumerate(SPANS):
        assert _worst_excess(tf, rf, s0, s1, rm[k]) <= cm[k] + 1e-9, (SPANS[k], rm[k], cm[k])
        true_max = float(np.max(np.abs(rf[(tf >= s0) & (tf <= s1)])))
        if true_max >= R_PEAK:  # the span holds a plateau of the turn
            assert rm[k] >= true_max, (SPANS[k], rm[k], true_max)
    assert rm[0] < 1.1 * R_PEAK < CAP  # the data's bound, not the vehicle's cap
    for psi0 in (0.0, 0.2, 0.41, float(np.mean(psi[(tf >= 1.0) & (tf <= 2.0)]))):
        i1, i2 = P._envelope_integrals(w, np.array([1.0]), np.array([2.0]),
                                       np.array([psi0]))
        sel = (tf >= 1.0) & (tf <= 2.0)
        dev = psi[sel] - psi0
        assert float(np.trapezoid(np.abs(dev), tf[sel])) <= i1[0], psi0
        assert float(np.trapezoid(dev * dev, tf[sel])) <= i2[0], psi0


def test_a_rate_bound_below_the_true_rate_fails_the_check() -> None:
    """The check above has teeth: with gyro_z's error E0 against the rate on every sample
    (the lowest samples the bounds allow) Rm still reaches the truth's largest rate
    R_PEAK, and a rate 3 % below R_PEAK breaks ``int_s^t |psi'| <= Rm (t - s) + Cm`` over
    the turn's plateau (by more than twice Cm)."""
    tf, _, rf, w = _gyro_turn(-0.8 * E0, 3, against=True)
    rm, cm = H.psi_rate_bound(w, np.array([1.0]), np.array([2.0]))
    assert rm[0] >= R_PEAK
    assert _worst_excess(tf, rf, 1.0, 2.0, rm[0]) <= cm[0] + 1e-9
    assert _worst_excess(tf, rf, 1.0, 2.0, 0.97 * R_PEAK) > 2 * cm[0]


def test_rate_bound_holds_the_simulated_truth_at_sharp_corners() -> None:
    """A simulated trip (20 m corners, 100 Hz truth on the IMU's stamps, the simulator's
    biased Gaussian gyro errors): per fix gap, the true heading's running variation
    (the sum of |d psi| on the truth's grid, at most int |psi'|) never gains more than
    Cm over the line of slope Rm, on any sub-span; Rm stays within the vehicle's cap
    and below it on most gaps (the data's bound is the one used)."""
    from imubounds.dynamic.estimator.full import build_context
    from imubounds.dynamic.estimator.windows import MarginBuilder
    from imubounds.dynamic.scenario import make_trip
    from imubounds.interval.rounding import nearest

    res = make_trip("paper", seed=45, aiding=("gnss", "compass"), truth_rate_hz=100.0,
                    corner_length_m=20.0, laps=3)
    with nearest():
        ctx = build_context(res.drive, None, {})
        mb = MarginBuilder(ctx)
        t = ctx.aiding.gnss_t
        a, b = t[:-1], t[1:]
        rm, cm = H.psi_rate_bound(mb, a, b)
    veh = ctx.vehicle
    cap = veh.max_rate / math.cos(veh.max_tilt)
    assert np.all(rm <= cap)
    assert np.median(rm) < 0.5 * cap
    tr = res.drive.truth
    tt = np.asarray(tr.t, dtype=float) - float(np.asarray(res.drive.imu.t)[0])
    psi = np.unwrap(0.5 * np.pi - np.asarray(tr.heading_rad, dtype=float))
    var = np.concatenate([[0.0], np.cumsum(np.abs(np.diff(psi)))])
    turning = 0
    for k in range(a.size):
        sel = (tt >= a[k]) & (tt <= b[k])
        if sel.sum() < 10:
            continue
        y = var[sel] - rm[k] * tt[sel]
        assert float(np.max(y - np.minimum.accumulate(y))) <= cm[k] + 1e-9, k
        turning += int(var[sel][-1] - var[sel][0] > 0.2)
    assert turning > 20  # gaps inside the corners were checked
