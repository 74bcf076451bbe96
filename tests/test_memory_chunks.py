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
