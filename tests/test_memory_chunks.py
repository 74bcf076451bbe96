"""Chunked passes over per-sample arrays (issue 27: a 24 h trip within 2 GiB) give the
numbers of one pass over the whole trip, bit for bit."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from imubounds.dynamic.estimator import dynamic_margins
from imubounds.dynamic.scenario import make_trip


@pytest.fixture(scope="module")
def analysed() -> Any:
    drive = make_trip("paper", seed=3, duration_s=300.0, distance_m=3510.0, rate_hz=50.0,
                      aiding=("gnss", "gnss-vel", "compass")).drive
    return drive, dynamic_margins(drive)


def test_imu_trapezoid_chunks_equal_one_pass(analysed: Any, monkeypatch: Any) -> None:
    """residual_checks.imu_trapezoid in chunks of 97 sub-segments (cut at fixes) equals
    one pass over all of them."""
    from imubounds.dynamic.estimator import residual_checks as RC

    _, r = analysed
    ctx, sm = r.full.ctx, r.full.smoother
    t = ctx.aiding.gnss_t
    monkeypatch.setattr(RC, "_TRAP_CHUNK", 1 << 40)
    one = RC.imu_trapezoid(ctx, sm, t)
    monkeypatch.setattr(RC, "_TRAP_CHUNK", 97)
    many = RC.imu_trapezoid(ctx, sm, t)
    assert float(np.max(np.abs(one[0]))) > 0.01  # a real correction, not zeros
    for a, b in zip(one, many, strict=True):
        np.testing.assert_array_equal(a, b)


def _old_integral(t: np.ndarray, rate: np.ndarray) -> np.ndarray:
    dt = np.diff(t)
    d0 = float(np.median(dt)) if dt.size else 0.0
    return np.asarray(np.cumsum(np.nan_to_num(rate) * np.concatenate([[d0], dt])))


def _old_rate_allowance(tq: np.ndarray, it: np.ndarray, rate: np.ndarray, bound_s: float,
                        err: float, rmax: float, scale: float) -> np.ndarray:
    """timing.rate_allowance as it was (filters over every IMU sample)."""
    import math

    from scipy.ndimage import maximum_filter1d, minimum_filter1d

    cap = bound_s * rmax
    dt = float(np.median(np.diff(it)))
    half = int(math.ceil(bound_s / max(dt, 1e-9))) + 1
    r = np.nan_to_num(rate, nan=0.0)
    G = np.cumsum(r * np.concatenate([[dt], np.diff(it)]))
    gmax = maximum_filter1d(G, size=2 * half + 1, mode="nearest")
    gmin = minimum_filter1d(G, size=2 * half + 1, mode="nearest")
    i = np.searchsorted(it, tq).clip(0, it.size - 1)
    j = (i - 1).clip(0, it.size - 1)
    g = np.interp(tq, it, G)
    swing = np.maximum(np.maximum(gmax[i], gmax[j]) - g, g - np.minimum(gmin[i], gmin[j]))
    out = np.minimum((1.0 + scale) * swing + err, cap)
    bad = (tq < it[0]) | (tq > it[-1])
    if not np.isfinite(rate).all():
        fin = maximum_filter1d((~np.isfinite(rate)).astype(float), size=2 * half + 1)
        bad |= (fin[i] > 0) | (fin[j] > 0)
    return np.asarray(np.where(bad, cap, out))


@pytest.mark.parametrize("with_nan", [False, True])
def test_timing_chunked_passes_equal_one_pass(monkeypatch: Any, with_nan: bool) -> None:
    """sensors._timing: the chunked integral, the rate allowance from windows at the
    queried samples only, and the reference variance's in-place reversed sums equal
    the one-pass formulas they replaced, bit for bit (chunks of 1000 samples)."""
    from imubounds.dynamic.estimator.budget import ChannelNoise, kernel_variance
    from imubounds.dynamic.sensors import _timing as TM

    monkeypatch.setattr(TM, "CHUNK", 1000)
    rng = np.random.default_rng(4)
    n = 12345
    it = np.cumsum(rng.uniform(0.009, 0.011, n))
    rate = rng.normal(0.0, 0.2, n)
    ok = rng.uniform(size=n) > 0.01
    if with_nan:
        rate[rng.integers(0, n, 30)] = np.nan
    np.testing.assert_array_equal(TM._integral(it, rate), _old_integral(it, rate))
    np.testing.assert_array_equal(TM._integral(it, rate, ok),
                                  _old_integral(it, np.where(ok, rate, 0.0)))
    tq = np.sort(rng.uniform(it[0] - 1.0, it[-1] + 1.0, 700))
    np.testing.assert_array_equal(
        TM.rate_allowance(tq, it, rate, 0.1, 1e-3, 0.5, 0.01),
        _old_rate_allowance(tq, it, rate, 0.1, 1e-3, 0.5, 0.01))
    cn = ChannelNoise("gyro_z", N=1e-3, Q=1e-5, B=1e-4, turn_on=1e-3)
    wj = rng.normal(size=tq.size)
    gain = np.where(ok, rng.uniform(0.05, 0.3, n), np.nan)
    dt = float(np.median(np.diff(it)))
    idx = np.searchsorted(it, tq, side="right")
    A = np.bincount(idx, weights=wj, minlength=it.size + 1)
    R = np.cumsum(A[::-1])[::-1][1:]
    old = float(kernel_variance(cn, R * np.nan_to_num(gain) * dt, dt, True))
    assert TM._reference_variance(tq, wj, it, cn, gain) == old
