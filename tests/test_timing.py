"""Irregular sampling (issue 28 item 5): jittered or gapped stamps are never
silently taken for a constant rate."""

from __future__ import annotations

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
