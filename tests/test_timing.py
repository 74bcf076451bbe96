"""Irregular sampling (issue 28 item 5): jittered or gapped stamps are never
silently taken for a constant rate."""

from __future__ import annotations

import math

import numpy as np
import pytest

from imubounds.io.log import ImuLog
from imubounds.stationary.pipeline import StaticSettings, analyse_static
from imubounds.stationary.timing import timing_check

RATE = 50.0
N = 60_000


def _log(t: np.ndarray) -> ImuLog:
    y = np.random.default_rng(0).standard_normal(t.size) * 1e-3
    return ImuLog(channels={"gyro_z": y}, rate_hz=RATE, t=t)


def test_regular_stamps_give_a_zero_bound_and_no_warning() -> None:
    res = analyse_static(_log(np.arange(N) / RATE), StaticSettings())
    ch = res.channels["gyro_z"]
    assert ch.timing is not None and ch.timing["jitter_rel"] < 1e-9  # float stamps
    assert ch.timing["bound_rel_max"] < 1e-9 and ch.timing["gaps"] == 0
    assert not any("jitter" in w or "gap" in w for w in ch.warnings)
    assert "timing" in res.to_json()["channels"]["gyro_z"]


def test_jittered_stamps_are_measured_bounded_and_said() -> None:
    jitter = 0.05  # 5 % of the step, independent steps
    steps = (1.0 + jitter * np.random.default_rng(1).standard_normal(N - 1)) / RATE
    t = np.concatenate(([0.0], np.cumsum(steps)))
    res = analyse_static(_log(t), StaticSettings())
    tm = res.channels["gyro_z"].timing
    assert tm is not None and tm["jitter_rel"] == pytest.approx(jitter, rel=0.1)
    # white rate noise: slope -1/2, so b = 0.5*0.05/sqrt(m) + 0.05^2/2 at each tau
    m = np.rint(np.asarray(tm["tau_s"]) * RATE)
    expect = 0.5 * jitter / np.sqrt(m[0]) + jitter**2 / 2
    assert tm["bound_rel"][0] == pytest.approx(expect, rel=0.3)
    assert tm["bound_rel_max"] == tm["bound_rel"][0] and tm["bound_rel"][-1] < expect / 10
    assert any("jitter" in w and "constant rate" in w for w in res.channels["gyro_z"].warnings)


def test_gaps_left_in_are_counted_and_the_long_tau_named() -> None:
    t = np.arange(N) / RATE
    for k in (10_000, 30_000, 50_000):
        t[k:] += 2.0  # three 2-s holes
    block = timing_check(t, [0.02, 1.0, 100.0, 200.0], [1e-3, 1e-4, 1e-5, 1e-5], [0.9e-3] * 4,
                         [1.1e-3] * 4)  # fmt: skip
    assert block["gaps"] == 3 and block["missing_s"] == pytest.approx(6.0, abs=0.1)
    assert block["unreliable_tau_s"] == [100.0, 200.0]  # 3*2*m/n > 10 % from m = 1000


# --------------------------------------------------------------- clock offsets (issue 27)
# The aiding streams' clock offsets against the IMU (dynamic/aiding/timing.py): estimated
# from the data on the simulator's paper trip (5 min, MTx-grade IMU at 50 Hz, GNSS
# position + velocity at 1 Hz, compass), the stamps of one stream moved late.

LAG_TRIP = {"duration_s": 300.0, "distance_m": 3510.0, "rate_hz": 50.0}


def _estimates(drive: object) -> dict[str, object]:
    from imubounds.dynamic.aiding import speed_clock as SC
    from imubounds.dynamic.aiding import timing as TM
    from imubounds.dynamic.estimator.budget import k_two_sided, resolve_noise
    from imubounds.dynamic.estimator.full import check_options
    from imubounds.dynamic.estimator.heading_input import heading_input

    o = check_options({})
    noise, _ = resolve_noise(drive.settings, None, o)  # type: ignore[attr-defined]
    out = {
        "gnss": TM.estimate_gnss(drive, "end", noise),
        "heading": TM.estimate_heading(drive, "end", heading_input(drive, o), noise),
        "velocity": SC.estimate_velocity(drive, "end", noise),
    }
    timing = {k: v for k, v in out.items() if v is not None}
    # finalize with the k of a stream's family on the paper trip (about 300 epochs)
    TM.apply_offsets(drive, timing, lambda s, n: k_two_sided(0.01 / 9, 300 + n))
    return out


def test_level_offset_recovers_a_synthetic_lag() -> None:
    """A synthetic yaw rate (raised-cosine turns) with a wandering bias, a stream of
    headings 0.23 s late with white noise: estimated within 0.02 s, inside its interval."""
    from imubounds.dynamic.aiding.timing import level_offset

    rng = np.random.default_rng(4)
    dt = 0.02
    it = np.arange(0, 400, dt)
    rate = np.zeros(it.size)
    for c in (60.0, 140.0, 220.0, 300.0):
        s = np.abs(it - c) < 6
        rate[s] = 0.25 * np.cos(np.pi * (it[s] - c) / 12) ** 2
    bias = 0.002 * np.cumsum(rng.standard_normal(it.size)) * math.sqrt(dt)
    psi = np.cumsum(rate) * dt
    th = np.arange(2, 398, 1.0)
    lag = 0.23
    y = np.interp(th - lag, it, psi) + rng.normal(0, 0.005, th.size)
    est = level_offset(th, y, 0.005, it, rate + bias, "synthetic")
    assert est is not None
    est.finalize(3.6, 0.1)
    assert abs(est.offset_s - lag) < 0.02 and est.lo <= lag <= est.hi, est
    assert est.applied  # outside the allowance of 0.1 s: applied, half-width budgeted
    assert est.remainder_s == pytest.approx(max(est.hi - est.offset_s, est.offset_s - est.lo))


@pytest.mark.slow
@pytest.mark.parametrize("seed", [1, 2, 3])
def test_injected_lags_are_estimated_within_50_ms(seed: int) -> None:
    """GNSS and compass stamps 0.1-0.5 s late: estimated within 0.05 s with the lag in
    the interval; the clean trip's intervals hold 0; a GNSS lag of 0.3 s or more is
    applied, the GNSS of the clean trip is not (its stamps stay exact, the data agree)."""
    from imubounds.dynamic.scenario import faults as F
    from imubounds.dynamic.scenario import make_trip

    drive = make_trip("paper", seed=seed, aiding=("gnss", "gnss-vel", "compass"),
                      **LAG_TRIP).drive  # fmt: skip
    clean = _estimates(drive)
    for name in ("gnss", "heading"):
        e = clean[name]
        assert e is not None and e.lo <= 0.0 <= e.hi, (name, e)  # type: ignore[attr-defined]
    assert clean["gnss"].applied is False  # type: ignore[attr-defined]
    for lag in (0.1, 0.3, 0.5):
        for name, fn in (("gnss", F.gnss_lag), ("heading", F.heading_lag)):
            e = _estimates(fn(drive, lag))[name]
            assert e is not None, (name, lag)
            assert abs(e.offset_s - lag) <= 0.05, (name, lag, e)  # type: ignore[attr-defined]
            assert e.lo <= lag <= e.hi, (name, lag, e)  # type: ignore[attr-defined]
            if name == "gnss" and lag >= 0.3:
                assert e.applied  # type: ignore[attr-defined]


@pytest.mark.slow
def test_body_velocity_offset_is_reported_not_applied() -> None:
    """A wheel speed 0.3 s late: its offset is estimated and reported, never applied
    (the forward-acceleration reference is not good enough on an MTx-grade IMU)."""
    from imubounds.dynamic.scenario import faults as F
    from imubounds.dynamic.scenario import make_trip

    drive = make_trip("paper", seed=1, aiding=("gnss", "gnss-vel", "compass", "wheel"),
                      **LAG_TRIP).drive  # fmt: skip
    e = _estimates(F.velocity_lag(drive, 0.3))["velocity"]
    assert e is not None and e.applied is False and "not applied" in e.reason  # type: ignore[attr-defined]
    assert e.to_dict()["offset_s"] == 0.0  # type: ignore[attr-defined]


@pytest.mark.slow
def test_a_pinned_heading_clock_shrinks_the_allowance(monkeypatch: pytest.MonkeyPatch) -> None:
    """A VN-100-grade gyro pins the compass's clock: the estimate is applied with a
    remainder below the default 0.1 s, and the clean trip's heading half-width in the
    turns shrinks against the default allowance (the same trip without the estimate)."""
    from imubounds.dynamic.aiding import timing as TM
    from imubounds.dynamic.aiding.timing import DEFAULT_HEADING_CLOCK_BOUND_S as B
    from imubounds.dynamic.estimator import dynamic_margins
    from imubounds.dynamic.scenario import make_trip

    drive = make_trip("paper", seed=1, aiding=("gnss", "gnss-vel", "compass"),
                      imu_preset="vn100", **LAG_TRIP).drive  # fmt: skip
    r = dynamic_margins(drive)
    tm = r.to_dict()["timing"]["heading"]
    assert tm["applied"] is True and tm["remainder_s"] < B, tm
    assert tm["interval_s"][0] <= 0.0 <= tm["interval_s"][1]
    monkeypatch.setattr(TM, "estimate_heading", lambda *a, **k: None)
    r0 = dynamic_margins(drive)
    assert any(a.startswith("heading clock: ") and "+-0.1 s" in a
               for a in r0.to_dict()["assumptions"])
    # in the turns (the allowance is b x the turn rate there); on the straights the
    # compass noise dominates and the clock family's share of alpha costs ~0.2 %
    h, h0 = r.full.ctx.aiding.head_h, r0.full.ctx.aiding.head_h
    assert np.percentile(h, 95) < 0.8 * np.percentile(h0, 95), (np.percentile(h, 95),
                                                                np.percentile(h0, 95))
    assert np.median(h) < 1.01 * np.median(h0)
