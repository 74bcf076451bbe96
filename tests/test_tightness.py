"""Issue 24 item 4: the accel_x margins against the limit the same input bounds allow,
computed independently of the estimator's constraint code (tests/tightness_reference.py,
docs/dynamic-method.md section 6), per aiding set of the simulator; and the soundness of
the transport term's per-heading-gap bound against the simulated truth."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest

from imubounds.dynamic.estimator.aided.form_tables import (
    SUPPORT_MEAN_ABS_R,
    TRANSPORT_Y,
    mean_abs_q,
    mean_abs_r,
    shared_bounds,
    transport_by_fixes,
)
from imubounds.dynamic.estimator.aided.forms import allot, share
from imubounds.dynamic.estimator.aided.transport import support_plan
from imubounds.dynamic.estimator.aided.transport_fixes import fix_block_form, psi_variation
from imubounds.dynamic.estimator.aided.transport_gaps import (
    gap_rows,
    transport_by_gaps,
    weighted_floors,
    window_gaps,
)
from imubounds.dynamic.estimator.aided.transport_gyro import mean_r_by_gaps, transport_by_gyro
from imubounds.dynamic.estimator.aided.transport_weighted import weighted_speed
from imubounds.dynamic.estimator.aided.velocity import body_velocity, ranges, speed_max
from imubounds.dynamic.estimator.full import build_context
from imubounds.dynamic.estimator.inputs import PiecewiseSignal
from imubounds.dynamic.estimator.window_plan import LevelPlan
from imubounds.dynamic.estimator.windows import MarginBuilder
from imubounds.dynamic.scenario import Fault, make_trip
from imubounds.dynamic.scenario.imu import CHANNELS as IMU_CHANNELS
from imubounds.interval.rounding import nearest
from tests.tightness_reference import accel_x_ratios, accel_y_ratios, gyro_z_ratios

#: the simulator's aiding sets (issue 24 item 4)
AIDING_SETS = {
    "positions+compass": ("gnss", "compass"),
    "gnss-pos+vel+compass": ("gnss", "gnss-vel", "compass"),
    "course-heading": ("gnss", "gnss-vel"),
    "dvl+compass": ("dvl", "compass"),
    "wheel+gnss+compass": ("wheel", "gnss", "compass"),
    "wheel+compass": ("wheel", "compass"),
}
TARGET = 1.5

#: accel_y's median half-width / reference limit (paper trip, seed 30, tau >= 1.28 s,
#: the heading's period): 1.5 with a DVL or wheel speed (wheel at 82 s: 1.22), with GNSS
#: position + velocity and the course (1.43 at 82 s) and with GNSS position + velocity +
#: compass (1.38 at 82 s, was 1.52 and 1.81 before: the speed part of the transport term,
#: ``sum_k half-range_k(u) int_k |r|``, now also as one weighted mean,
#: ``aided.transport_weighted.weighted_speed``, each gap's |r| weighted by u's half-range
#: on it instead of the largest half-range times the bound of mean|r|), and the ceiling
#: positions only is held to while it misses it (issue 24 item 4; docs/dynamic-method.md
#: section 6): 1.41 1.10 1.07 1.32 1.94 1.81 1.49 1.48 (1.12 1.44 at 5 and 10 s before
#: the split of u - U0 into accel_x's measured integral, the turn-on's constant and the
#: rest, ``aided.transport_split``; 3.04 3.40 2.83 2.41 2.13 2.02 1.70 1.65 before
#: ``aided.transport_gyro.transport_by_gyro`` and u's block deviation from accel_x's
#: signed integral, 4-10x before the fix blocks): up to 10 s the
#: gyro-shape form, its width at 1.28 s the heading boxes' share of ``rbar`` (0.027 rad
#: over 1 s) times u's range from the vehicle bound (14 m/s) plus the gyro flicker's ramp
#: noise; from 20 s ``aided.form_tables.transport_by_fixes`` (the gyro form's u
#: excursion grows as the accelerometer's bias bound, 0.23 m/s^2, x tau; the split takes
#: out only the turn-on's 0.063 and the measured integral: the stated drift bound, 0.17,
#: bounds window means, not a constant, and stays with k_o = 0.08 in the rest, whose
#: K-norm times the gyro noise's, 0.115 rad/s, is 0.28 m/s^2 at 20 s): the position
#: boxes (+-10.6 m) where the block means of K r change between blocks (0.18 m/s^2 at
#: 20 s), and u's deviation from its block mean (bias bound x half the block) times the
#: bound of mean|r| (0.06 rad/s where the truth's is about 0.01).
ACCEL_Y_CEILING = {
    "positions+compass": 2.0,
    "gnss-pos+vel+compass": TARGET,
    "course-heading": TARGET,
    "dvl+compass": TARGET,
    "wheel+gnss+compass": TARGET,
    "wheel+compass": TARGET,
}


def _context(
    aiding: tuple[str, ...], seed: int, trip: str = "paper", **kw: Any
) -> tuple[Any, Any, MarginBuilder]:
    res = make_trip(trip, seed=seed, aiding=aiding, **kw)
    ctx = build_context(res.drive, None, {})
    return res, ctx, MarginBuilder(ctx)


@pytest.mark.parametrize("name", sorted(AIDING_SETS))
def test_within_1p5_of_the_limit(name: str) -> None:
    """accel_x and gyro_z: median half-width <= 1.5 x the reference limit at every
    tau >= the aiding period (paper trip, seed 30), and never below the limit by more
    than the reference's own approximations (a sanity check of the reference)."""
    with nearest():
        _, ctx, mb = _context(AIDING_SETS[name], 30)
        gz = mb.evaluate(ctx.plans["gyro_z"])
        mb.fine_r = gz.raw_verdict != "exceeds"
        m = mb.evaluate(ctx.plans["accel_x"])
    # at every tau the tighter of the aided and the vehicle-only enclosure: no level is
    # wider than the vehicle bounds alone (no spike where the aided level takes over)
    veh = ctx.vehicle
    for res_ch, bound in (
        (m, veh.max_accel + 9.84 * np.sin(veh.max_tilt)),
        (gz, veh.max_rate),
    ):
        for lv in res_ch.levels:
            assert np.all(lv.halfwidth <= bound * (1 + 1e-6) + 1e-6), (res_ch.channel, lv.tau_s)
    for ch, rows in (("accel_x", accel_x_ratios(ctx, m)), ("gyro_z", gyro_z_ratios(ctx, gz))):
        assert rows, f"{ch}: no aided level"
        table = ", ".join(f"{r.tau_s:.3g} s: {r.ratio:.2f}" for r in rows)
        assert all(r.ratio <= TARGET for r in rows), f"{name} {ch}: {table}"
        assert all(r.ratio >= 0.9 for r in rows), f"{name} {ch}: below the limit: {table}"


def test_within_1p5_of_the_limit_with_the_pitch_from_gnss() -> None:
    """A hilly trip (+-19 m, industrial IMU, GNSS position + velocity, compass): accel_x's
    gravity term follows the pitch from GNSS altitude in the estimator and in the
    reference alike (the same boxes, ``ctx.aiding.pitch``); the ratio stays within 1.5
    at every tau, and the reference's gravity term is below g sin(max tilt)."""
    res = make_trip("hills", seed=2, duration_s=792.0, distance_m=9400.0,
                    hill_amplitude_m=19.0, imu_preset="industrial",
                    aiding=("gnss", "gnss-vel", "compass"))
    with nearest():
        ctx = build_context(res.drive, None, {})
        assert ctx.aiding.pitch is not None
        mb = MarginBuilder(ctx)
        gz = mb.evaluate(ctx.plans["gyro_z"])
        mb.fine_r = gz.raw_verdict != "exceeds"
        m = mb.evaluate(ctx.plans["accel_x"])
    rows = accel_x_ratios(ctx, m)
    assert rows
    table = ", ".join(f"{r.tau_s:.3g} s: {r.ratio:.2f}" for r in rows)
    assert all(0.9 <= r.ratio <= TARGET for r in rows), table
    full_tilt = 9.84 * np.sin(ctx.vehicle.max_tilt)
    assert all(r.terms["gravity"] < 0.7 * full_tilt for r in rows), table


def _accel_y_rows(name: str) -> list[Any]:
    with nearest():
        _, ctx, mb = _context(AIDING_SETS[name], 30)
        gz = mb.evaluate(ctx.plans["gyro_z"])
        mb.fine_r = gz.raw_verdict != "exceeds"
        m = mb.evaluate(ctx.plans["accel_y"])
    period = float(np.median(np.diff(ctx.aiding.head_t)))
    return accel_y_ratios(ctx, m, min_tau_s=period)


@pytest.mark.parametrize("name", sorted(AIDING_SETS))
def test_accel_y_against_the_limit(name: str) -> None:
    """accel_y: never below the reference limit by more than its approximations (>= 0.9),
    and within :data:`ACCEL_Y_CEILING` at every tau >= the heading's period: the issue's
    1.5 target with a DVL or wheel speed and a compass, with the course heading and with
    GNSS position + velocity + compass; positions only misses it (held to its measured
    ceiling, the reasons beside it)."""
    rows = _accel_y_rows(name)
    assert rows, f"{name} accel_y: no aided level"
    table = ", ".join(f"{r.tau_s:.3g} s: {r.ratio:.2f}" for r in rows)
    assert all(r.ratio >= 0.9 for r in rows), f"{name} accel_y: below the limit: {table}"
    assert all(r.ratio <= ACCEL_Y_CEILING[name] for r in rows), f"{name} accel_y: {table}"


def _aided_levels(ctx: Any, mb: MarginBuilder, ch: str) -> Iterator[Any]:
    """The aided levels of channel ``ch`` with windows, ``mb.p_window`` set to each
    level's per-window probability (as ``MarginBuilder.evaluate`` does)."""
    for li, lp in enumerate(ctx.plans[ch].levels):
        if lp.kind != "aided" or lp.n == 0:
            continue
        mb.p_window = ctx.alpha.p_level("imu_windows", ctx.level_index[(ch, li)])
        yield lp


def _true_ru(res: Any, ctx: Any) -> PiecewiseSignal:
    """The simulator's true r u (yaw rate x forward velocity) on the IMU's stamps."""
    tr = res.drive.truth
    r = np.asarray(tr.extra["gyro_z"], dtype=float)
    u = np.asarray(tr.u_mps, dtype=float)
    assert r.size == ctx.imu.n and u.size == ctx.imu.n
    return PiecewiseSignal(ctx.imu.bnd, r * u)


@pytest.mark.parametrize(
    "aiding,seed,kw",
    [
        (("gnss", "gnss-vel", "compass"), 46, {}),
        (("dvl", "compass"), 47, {"turn_on_scale": 3.0}),
        (("gnss", "gnss-vel"), 48, {"corner_length_m": 20.0, "laps": 3}),
    ],
    ids=["posvel", "dvl-turn-on", "course-corners"],
)
def test_accel_y_transport_by_gaps_encloses_the_true_mean(
    aiding: tuple, seed: int, kw: dict
) -> None:
    """accel_y's transport term cut at the heading epochs
    (``aided.transport_gaps.transport_by_gaps``) contains the true kernel mean of r u (the
    simulator's yaw rate and forward velocity on the IMU's stamps) at every window of
    every aided boxcar level."""
    with nearest():
        res, ctx, mb = _context(aiding, seed, truth_rate_hz=100.0, **kw)
        sig = _true_ru(res, ctx)
        bv = body_velocity(mb)
        n = 0
        for lp in _aided_levels(ctx, mb, "accel_y"):
            box = transport_by_gaps(mb, lp, lp.tau, bv, mean_abs_r(mb, lp, lp.tau, mb.p_window))
            true = sig.kernel_mean(lp.a1, lp.b1, lp.a2, lp.b2, lp.tau)
            bad = (true.lo > box.hi) | (true.hi < box.lo)
            assert not bad.any(), (lp.tau_s, int(bad.sum()))
            n += lp.n
        assert n > 100


def _true_weighted_speed(
    mb: MarginBuilder, bv: Any, r_abs_sig: PiecewiseSignal, lp: Any, idx: np.ndarray
) -> np.ndarray:
    """``(1/tau) sum_k du_k int_k |r|`` over the windows ``idx``: ``du_k`` the half-range
    of u that ``transport_by_gaps`` gives gap k (the window cut at the heading epochs
    inside it), ``|r|`` the simulator's on the IMU's stamps."""
    ht = mb.ag.head_t
    out = np.empty(idx.size)
    for m, i in enumerate(idx):
        a, b = lp.a1[i], lp.b2[i]
        knots = np.concatenate([[a], ht[(ht > a) & (ht < b)], [b]])
        du = gap_rows(mb, bv, knots[:-1], knots[1:])[:, 2]
        lo, hi = r_abs_sig.integral(knots[:-1], knots[1:])
        out[m] = float(np.sum(du * hi)) / lp.tau[i]
    return out


@pytest.mark.parametrize(
    "aiding,seed,kw",
    [
        (("gnss", "gnss-vel", "compass"), 60, {}),
        (("gnss", "gnss-vel", "compass"), 61, {"turn_on_scale": 3.0}),
        (("gnss", "gnss-vel", "compass"), 62, {"corner_length_m": 20.0, "laps": 3}),
        (("wheel", "compass"), 63, {"corner_length_m": 20.0, "laps": 3,
                                    "turn_on_scale": 3.0}),
        (("gnss", "gnss-vel"), 64, {"corner_length_m": 20.0, "laps": 3,
                                    "turn_on_scale": 3.0}),
        # GNSS velocity at 10 Hz, the compass at 1 Hz: most velocity epochs between
        # heading epochs (the weights' heading carried by the vehicle's rate cap)
        (("gnss", "gnss-vel", "compass"), 65, {"trip": "gnss10", "duration_s": 300.0,
                                               "distance_m": 3600.0, "turn_on_scale": 3.0}),
    ],
    ids=["posvel", "posvel-turn-on", "posvel-corners", "wheel-corners-turn-on",
         "course-corners-turn-on", "gnss10-turn-on"],
)
def test_accel_y_weighted_speed_encloses_the_truth(aiding: tuple, seed: int, kw: dict) -> None:
    """The weighted speed part of accel_y's transport term
    (``aided.transport_weighted.weighted_speed``) lies over ``(1/tau) sum_k du_k int_k |r|``
    with the simulator's |r| at every window of every aided boxcar level (a turn-on gyro
    bias at 3 sigma, sharp corners where the vehicle slows); ``transport_by_gaps`` with
    it contains the true kernel mean of r u; and it is narrower than the form without
    it at some tau (the test exercises the weighted bound)."""
    with nearest():
        res, ctx, mb = _context(aiding, seed, truth_rate_hz=100.0, **kw)
        sig = _true_ru(res, ctx)
        r_true = np.abs(np.asarray(res.drive.truth.extra["gyro_z"], dtype=float))
        r_sig = PiecewiseSignal(ctx.imu.bnd, r_true)
        bv = body_velocity(mb)
        ht = mb.ag.head_t
        n, gain = 0, []
        for lp in _aided_levels(ctx, mb, "accel_y"):
            if np.any(lp.b1 > lp.a1):
                continue  # boxcar levels only (the trapezoid ones have no heading gaps)
            r_mag, q_mean = shared_bounds(mb, lp, lp.tau, ["weighted_speed"], mb.p_window)
            p_w = share("accel_y.transport", "weighted_speed") * mb.p_window
            box = transport_by_gaps(mb, lp, lp.tau, bv, r_mag, q_mean, p_w)
            true = sig.kernel_mean(lp.a1, lp.b1, lp.a2, lp.b2, lp.tau)
            bad = (true.lo > box.hi) | (true.hi < box.lo)
            assert not bad.any(), (lp.tau_s, int(bad.sum()))
            # the level's windows (on the heading epochs) and the same shifted by 0.37 of
            # a sample (the first and last gaps partial, a block reaching into them)
            for shift in (0.0, 0.37 * ctx.imu.dt):
                sl = LevelPlan(lp.tau_s, lp.kind, lp.a1 + shift, lp.b1 + shift,
                               lp.a2 + shift, lp.b2 + shift, lp.i, lp.j)
                k0, k1, fb, la = window_gaps(ht, sl.a1, sl.b2)
                floors = weighted_floors(mb, bv, sl.a1, sl.b2, fb, la, k1 > k0)
                ws = weighted_speed(mb, sl, sl.tau, bv, p_w, floors, 0.0)
                idx = np.arange(0, sl.n, max(1, sl.n // 400))
                tw = _true_weighted_speed(mb, bv, r_sig, sl, idx)
                fin = np.isfinite(ws[idx])
                assert np.all(tw[fin] <= ws[idx][fin]), (sl.tau_s, shift)
                # larger floors (the first and last gaps' weights above the blocks'
                # table weights there) never narrow it
                up_f = (floors[0], floors[1] + 0.5, floors[2], floors[3] + 0.5)
                ws2 = weighted_speed(mb, sl, sl.tau, bv, p_w, up_f, 0.0)
                assert np.all(ws2[np.isfinite(ws)] >= ws[np.isfinite(ws)]), (sl.tau_s, shift)
                n += int(np.sum(fin))
            old = transport_by_gaps(mb, lp, lp.tau, bv, r_mag, q_mean)
            gain.append(float(np.median(box.hi - box.lo) / np.median(old.hi - old.lo)))
        assert n > 100
        assert min(gain) < 0.97, gain


#: the block lengths of the registry's fix-block forms
FIX_BLOCKS = tuple(int(f.name.rsplit("_", 1)[1]) for f in TRANSPORT_Y if f.family == "fix_blocks")

#: the positions-only trips the transport forms are checked on (seed offset, settings)
POSITIONS_TRIPS = {
    "paper": (0, {}),
    "corners": (1, {"corner_length_m": 20.0, "laps": 3}),
    "turn-on": (2, {"turn_on_scale": 3.0}),
    "corners-turn-on": (3, {"corner_length_m": 20.0, "laps": 3, "turn_on_scale": 3.0}),
    "scale-misalignment": (4, {"scale_error": 0.002, "misalignment_deg": 0.1}),
}


def _positions_trips(first_seed: int, **more: tuple[int, dict]) -> Any:
    """``pytest.mark.parametrize`` of ``seed, kw`` over :data:`POSITIONS_TRIPS` (seeds
    from ``first_seed``) and ``more``."""
    cases = {**POSITIONS_TRIPS, **more}
    return pytest.mark.parametrize(
        "seed,kw", [(first_seed + i, kw) for i, kw in cases.values()], ids=list(cases))


@_positions_trips(50)
def test_accel_y_transport_by_fixes_encloses_the_true_mean(seed: int, kw: dict) -> None:
    """Positions + compass: accel_y's transport term over blocks of fix gaps
    (``aided.form_tables.transport_by_fixes``, each block length of ``FIX_BLOCKS`` on its
    own, u's block deviation also from accel_x's signed integral) contains the true
    trapezoid kernel mean of r u (the simulator's yaw rate and forward velocity on the
    IMU's stamps) at every window of every aided level, on the sharp-corners trip (the
    vehicle slows in the corners), with a turn-on gyro bias at 3 sigma and with scale
    and misalignment errors; and it is narrower than the chord-speed form ``S_max x
    mean|r|`` at some tau (by half at the longest on the paper trip; in the corners,
    where the vehicle slows, at the middle ones)."""
    with nearest():
        res, ctx, mb = _context(("gnss", "compass"), seed, truth_rate_hz=100.0, **kw)
        sig = _true_ru(res, ctx)
        plan = ctx.plans["accel_y"]
        assert plan.trapezoid
        n = 0
        gain = []
        for lp in _aided_levels(ctx, mb, "accel_y"):
            r_mag, q_mean = shared_bounds(mb, lp, lp.tau, ["fix_blocks"], mb.p_window)
            p_fix = share("accel_y.transport", "fix_blocks") * mb.p_window
            true = sig.kernel_mean(lp.a1, lp.b1, lp.a2, lp.b2, lp.tau)
            sup, L = support_plan(lp)
            p_sup = allot(p_fix, "fix_blocks", ["accel_noise"])["psi_variation"]
            psi_var = psi_variation(mb, lp, mean_abs_r(mb, sup, L, p_sup, table=SUPPORT_MEAN_ABS_R))
            p_acc = share("fix_blocks", "accel_noise") * p_fix / len(FIX_BLOCKS)
            for blk in FIX_BLOCKS:
                box = fix_block_form(mb, lp, lp.tau, blk, r_mag, q_mean, psi_var, p_acc)
                bad = (true.lo > box.hi) | (true.hi < box.lo)
                assert not bad.any(), (lp.tau_s, blk, int(bad.sum()))
            box = transport_by_fixes(mb, lp, lp.tau, r_mag, q_mean, mb.p_window)
            assert np.all(np.isfinite(box.lo) & np.isfinite(box.hi))
            old = speed_max(mb, lp.a1, lp.b2) * r_mag  # the chord-speed form's radius
            gain.append(float(np.median(0.5 * (box.hi - box.lo)) / np.median(old)))
            n += lp.n
        assert n > 100
        # the paper trip by a third or more; the corners (slower) less since the sharper
        # Lambda also narrowed the chord-speed form's mean|r| (0.78-0.82 at the middle tau)
        assert min(gain) < (0.9 if kw.get("corner_length_m") else 0.7), gain


@pytest.mark.parametrize(
    "seed,kw",
    [
        (65, {"corner_length_m": 20.0, "laps": 3}),
        (66, {"turn_on_scale": 3.0, "scale_error": 0.002, "misalignment_deg": 0.1}),
    ],
    ids=["corners", "turn-on-scale-misalignment"],
)
def test_u_deviation_from_the_signed_accel_integral_encloses_the_truth(
    seed: int, kw: dict
) -> None:
    """``transport_fixes.u_deviation`` with accel_x's signed integral (the white noise's
    factor given) bounds the true ``max |u(t) - mean_B u|`` over blocks of 4-32 fix gaps
    (the vehicle slows in the corners), and is below the per-sample form on most blocks."""
    from imubounds.dynamic.estimator.aided.transport_fixes import u_deviation

    with nearest():
        res, ctx, mb = _context(("gnss", "compass"), seed, truth_rate_hz=100.0, **kw)
        u = np.asarray(res.drive.truth.u_mps, dtype=float)
        assert u.size == ctx.imu.n
        t = ctx.aiding.gnss_t
        mid = 0.5 * (ctx.imu.bnd[:-1] + ctx.imu.bnd[1:])
        sig_u = PiecewiseSignal(ctx.imu.bnd, u)
        narrower = []
        for blk in FIX_BLOCKS:
            a, b = t[:-blk:blk], t[blk::blk]
            new = u_deviation(mb, a, b, 6.0)  # k of the white noise: p about 1e-9
            old = u_deviation(mb, a, b)
            lo, hi = sig_u.integral(a, b)
            mean = 0.5 * (lo + hi) / (b - a)
            k0, k1 = np.searchsorted(mid, a), np.searchsorted(mid, b)
            true = np.array([np.max(np.abs(u[i:j] - m))
                             for i, j, m in zip(k0, k1, mean, strict=True)])
            assert np.all(true <= new), (blk, float(np.max(true - new)))
            narrower.append(float(np.mean(new < old)))
        assert min(narrower) > 0.5, narrower


@_positions_trips(
    60,
    **{"biases-at-bound": (7, {"biases_at_bound": True}),
       "corners-biases-at-bound": (8, {"corner_length_m": 20.0, "laps": 3,
                                       "biases_at_bound": True})},
)
def test_accel_y_transport_by_gyro_encloses_the_true_mean(seed: int, kw: dict) -> None:
    """Positions + compass: the gyro-shape form of accel_y's transport term
    (``aided.transport_gyro.transport_by_gyro``) contains the true trapezoid kernel mean
    of r u, and its ``rbar`` (``mean_r_by_gaps``) the true kernel mean of r (within the
    Earth's rate, which the truth's inertial rate adds), at every window of every aided
    level: straight legs, sharp corners where the vehicle slows, a turn-on gyro bias at
    3 sigma, scale and misalignment errors, accel_x's and gyro_z's turn-on biases at 97 %
    of their stated bounds (opposite signs; the split's ``b_TO (t - t_c)`` term); and it
    is at most half the fix-block form at the shortest aided level (the accelerometer
    moves u little within a window)."""
    with nearest():
        res, ctx, mb = _biased_context(seed, kw)
        sig = _true_ru(res, ctx)
        r = np.asarray(res.drive.truth.extra["gyro_z"], dtype=float)
        sig_r = PiecewiseSignal(ctx.imu.bnd, r)
        bv = body_velocity(mb)
        n = 0
        ratios = []
        for lp in _aided_levels(ctx, mb, "accel_y"):
            rng = ranges(mb, lp, bv)
            p = 0.1 * mb.p_window
            box = transport_by_gyro(mb, lp, lp.tau, rng["u_lo"], rng["u_hi"], p)
            true = sig.kernel_mean(lp.a1, lp.b1, lp.a2, lp.b2, lp.tau)
            bad = (true.lo > box.hi) | (true.hi < box.lo)
            assert not bad.any(), (lp.tau_s, int(bad.sum()))
            rb = mean_r_by_gaps(mb, lp, lp.tau, 0.04 * mb.p_window)
            tr = sig_r.kernel_mean(lp.a1, lp.b1, lp.a2, lp.b2, lp.tau)
            earth = 7.3e-5 + ctx.vehicle.max_speed / 6.37e6
            bad = (tr.lo - earth > rb.hi) | (tr.hi + earth < rb.lo)
            assert not bad.any(), (lp.tau_s, int(bad.sum()))
            if not ratios:
                r_mag, q_mean = shared_bounds(mb, lp, lp.tau, ["fix_blocks"], mb.p_window)
                fx = transport_by_fixes(mb, lp, lp.tau, r_mag, q_mean, mb.p_window)
                ratios.append(float(np.median(box.radius()) / np.median(fx.radius())))
            n += lp.n
        assert n > 100
        assert ratios[0] < 0.5, ratios


def _biased_context(seed: int, kw: dict) -> tuple[Any, Any, MarginBuilder]:
    """Positions + compass at 100 Hz truth; with ``biases_at_bound`` accel_x's turn-on
    bias at +97 % of its stated bound and gyro_z's at -97 % (a constant fault from t = 0
    added to the drawn turn-on: the total within the bound the drive states)."""
    kw = dict(kw)
    if not kw.pop("biases_at_bound", False):
        return _context(("gnss", "compass"), seed, truth_rate_hz=100.0, **kw)
    res, _, _ = _context(("gnss", "compass"), seed, truth_rate_hz=100.0, **kw)
    err = res.imu_errors
    faults = []
    for ch, kind, sign in (("accel_x", "accel", 1.0), ("gyro_z", "gyro", -1.0)):
        j = IMU_CHANNELS.index(ch)
        bound = err.figures.turn_on_bound[kind]
        faults.append(Fault(ch, "bias", sign * 0.97 * bound - float(err.turn_on[j]), 0.0))
    return _context(("gnss", "compass"), seed, truth_rate_hz=100.0, faults=tuple(faults), **kw)


def test_u_split_known_shape_terms_bound_the_true_projections() -> None:
    """:func:`.transport_split.known_shape_terms` (the split of u - U0 in accel_y's
    gyro-shape form) bounds ``|int K (r - rbar) A|`` and ``|int K (r - rbar)(t - t_c)|``
    with the true yaw rate r (the simulator's sample means, rbar its kernel mean) and A
    the measured ``C(t) - C(t_c)`` (accel_x's running integral), both computed here on a
    fine grid (20 points per sample, the trapezoid rule), at every window of the levels
    where it is computed, with gyro_z's turn-on at 97 % of its bound (it cancels); and
    the split narrows the form at some level (its second term without the split, all
    windows, against with it)."""
    import imubounds.dynamic.estimator.aided.transport_gyro as TG
    from imubounds.dynamic.estimator.aided.transport_split import known_shape_terms

    with nearest():
        res, ctx, mb = _biased_context(69, {"corner_length_m": 20.0, "laps": 3,
                                            "biases_at_bound": True})
        r = np.asarray(res.drive.truth.extra["gyro_z"], dtype=float)
        bnd = ctx.imu.bnd
        ya = np.asarray(mb.imu.sig["accel_x"].y, dtype=float)
        cb = np.concatenate([[0.0], np.cumsum(ya * np.diff(bnd))])
        sig_y = mb.imu.sig["gyro_z"]
        bv = body_velocity(mb)
        checked = 0
        narrower = []
        for lp in _aided_levels(ctx, mb, "accel_y"):
            sel = np.zeros(lp.n, dtype=bool)
            sel[:: max(1, lp.n // 12)] = True
            yb = sig_y.kernel_mean(lp.a1, lp.b1, lp.a2, lp.b2, lp.tau)
            c = yb.mid()
            rho = yb.radius() * (1 + 1e-6)
            cn = ctx.noise["gyro_z"]
            rate = ctx.vehicle.max_rate + 7.3e-5 + ctx.vehicle.max_speed / 6.37e6
            ed = (ctx.D_KR["gyro_z"] + cn.scale * rate / (1 - cn.scale)
                  + 2 * cn.misalignment_rad * rate + 7.3e-5 + ctx.vehicle.max_speed / 6.37e6)
            known, tb, _ = known_shape_terms(mb, lp, lp.tau, sel, c, rho, ed, 1e-9)
            for i in np.flatnonzero(sel):
                a1, b1, b2 = lp.a1[i], lp.b1[i], lp.b2[i]
                tau = lp.tau[i]
                t = np.linspace(a1, b2, 20 * int(round((b2 - a1) / ctx.imu.dt)) + 1)
                k = np.where(t <= b1, (t - a1) / ((b1 - a1) * tau), (b2 - t) / ((b2 - b1) * tau))
                tc = 0.5 * (a1 + b2)
                a = np.interp(t, bnd, cb) - np.interp(tc, bnd, cb)
                idx = np.clip(np.searchsorted(bnd, t, side="right") - 1, 0, r.size - 1)
                rt = r[idx]
                rbar = np.trapezoid(k * rt, t)
                ta = np.trapezoid(k * (rt - rbar) * a, t)
                tt = np.trapezoid(k * (rt - rbar) * (t - tc), t)
                assert abs(ta) <= known[i] + 1e-9, (lp.tau_s, i, ta, known[i])
                assert abs(tt) <= tb[i] + 1e-9, (lp.tau_s, i, tt, tb[i])
                checked += 1
            rng = ranges(mb, lp, bv)
            p = 0.1 * mb.p_window
            with_split = transport_by_gyro(mb, lp, lp.tau, rng["u_lo"], rng["u_hi"], p)
            saved = TG.SPLIT_GAIN
            try:
                TG.SPLIT_GAIN = np.inf
                without = transport_by_gyro(mb, lp, lp.tau, rng["u_lo"], rng["u_hi"], p)
            finally:
                TG.SPLIT_GAIN = saved
            w1, w0 = with_split.hi - with_split.lo, without.hi - without.lo
            fin = np.isfinite(w0)
            assert np.all(w1[fin] <= w0[fin] * (1 + 1e-12))
            narrower.append(float(np.median(w1[fin] / w0[fin])) if fin.any() else 1.0)
        assert checked > 50
        assert min(narrower) < 0.95, narrower


@pytest.mark.parametrize(
    "aiding,seed,kw",
    [
        (("gnss", "gnss-vel", "compass"), 41, {}),
        (("gnss", "compass"), 42, {"scale_error": 0.002, "misalignment_deg": 0.1}),
        (("dvl", "compass"), 43, {"turn_on_scale": 3.0}),
        (("gnss", "gnss-vel"), 44, {"corner_length_m": 20.0, "laps": 3}),
    ],
    ids=["posvel", "pos-scale", "dvl-turn-on", "course-corners"],
)
def test_transport_bound_encloses_true_mean_abs_r(aiding: tuple, seed: int, kw: dict) -> None:
    """The kernel mean of the true |r| (of its sample means) lies under the transport term's bound
    (``aided.form_tables.mean_abs_r``, whose per-heading-gap part counts the gyro noise once)
    at every window of every aided accel_x level, biased noise included; likewise the
    true |q| under gyro_y's window bound in gyro_z's tilt coupling
    (``aided.form_tables.mean_abs_q``), which is tighter than the per-sample bound."""
    with nearest():
        res, ctx, mb = _context(aiding, seed, truth_rate_hz=100.0, **kw)
        # the true yaw rate's means over the IMU samples (truth on the IMU's stamps)
        x = np.asarray(res.drive.truth.extra["gyro_z"], dtype=float)
        assert x.size == ctx.imu.n
        sig = PiecewiseSignal(ctx.imu.bnd, np.abs(x))
        n = 0
        for lp in _aided_levels(ctx, mb, "accel_x"):
            bound = mean_abs_r(mb, lp, lp.tau, mb.p_window)
            true = sig.kernel_mean(lp.a1, lp.b1, lp.a2, lp.b2, lp.tau)
            bad = true.lo > bound
            assert not bad.any(), (lp.tau_s, float(np.max(true.lo[bad] - bound[bad])))
            n += lp.n
        assert n > 100
        # the tilt coupling of gyro_z: gyro_y's window bound of the mean |q|
        xq = np.asarray(res.drive.truth.extra["gyro_y"], dtype=float)
        sq = PiecewiseSignal(ctx.imu.bnd, np.abs(xq))
        for lp in _aided_levels(ctx, mb, "gyro_z"):
            bound = mean_abs_q(mb, lp, lp.tau, 0.5 * mb.p_window)
            true = sq.kernel_mean(lp.a1, lp.b1, lp.a2, lp.b2, lp.tau)
            assert not (true.lo > bound).any(), lp.tau_s
            assert np.median(bound) < np.median(mb.kernel_mag("gyro_y", lp, lp.tau))


def test_heading_envelope_encloses_the_true_heading() -> None:
    """Positions only: per fix gap, the integrals of |psi - psi0| and (psi - psi0)^2 that
    bound the projection remainder (``aided.positions._envelope_integrals``) are at least
    those of the true heading (sharp corners, 100 Hz truth)."""
    from imubounds.dynamic.estimator.aided import positions as P

    with nearest():
        res, ctx, mb = _context(
            ("gnss", "compass"), 45, truth_rate_hz=100.0, corner_length_m=20.0, laps=3
        )
        ag = ctx.aiding
        t = ag.gnss_t
        a, b = t[:-1], t[1:]
        psi0 = P.heading_mean(mb, a, b).mid()
        i1, i2 = P._envelope_integrals(mb, a, b, psi0)
    tr = res.drive.truth
    tt = np.asarray(tr.t, dtype=float) - float(np.asarray(res.drive.imu.t)[0])
    # truth: compass heading (clockwise from north); the model's is pi/2 - it, on the
    # branch of the unwrapped compass centres
    psi = np.unwrap(0.5 * np.pi - np.asarray(tr.heading_rad, dtype=float))
    psi = psi - 2 * np.pi * np.round((np.interp(a[0], tt, psi) - psi0[0]) / (2 * np.pi))
    checked = 0
    for k in range(0, a.size, 7):
        sel = (tt >= a[k]) & (tt <= b[k])
        if sel.sum() < 10:
            continue
        d = psi[sel] - psi0[k]
        dt = np.gradient(tt[sel])
        assert np.sum(np.abs(d) * dt) <= i1[k] * 1.05 + 1e-6, k
        assert np.sum(d * d * dt) <= i2[k] * 1.05 + 1e-9, k
        checked += 1
    assert checked > 50


def test_weights_are_not_gyro_free_with_an_ahrs_heading_or_attitude() -> None:
    """The weighted speed part needs weights independent of the gyro's noise
    (``aided.transport_weighted``): an AHRS yaw used as heading, or an AHRS attitude
    stream, follows the gyros, so ``velocity.gyro_free_u`` gives None there (the
    weighted form is then not used) and a box otherwise."""
    from imubounds.dynamic.estimator.aided.velocity import gyro_free_u

    with nearest():
        _, ctx, mb = _context(("gnss", "gnss-vel", "compass"), 30)
        bv = body_velocity(mb)
        assert gyro_free_u(mb, bv) is not None
        mb.cache.pop("bodyvel_gyro_free")
        ctx.aiding.head_independent_of_imu = False
        assert gyro_free_u(mb, bv) is None
