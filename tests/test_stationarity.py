"""Stationarity and warm-up (issue 28 item 3)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from imubounds.io.log import ImuLog
from imubounds.stationary.pipeline import StaticSettings, analyse_static
from imubounds.stationary.stationarity import WARMUP_FRACTION, stationarity

from .synthetic import five_term_signal

RATE = 10.0
N = int(2 * 3600 * RATE)  # 2 h
WARMUP_END_S = 600.0  # the bias settles (to 5 % of its step) over the first 10 min
TC = WARMUP_END_S / np.log(1.0 / WARMUP_FRACTION)


def gyro(seed: int, warm: bool) -> np.ndarray:
    y = five_term_signal(N, RATE, 0.0, 1e-3, 5e-5, 1e-6, 0.0, seed)
    if warm:
        y = y + 6e-3 * np.exp(-np.arange(N) / RATE / TC)  # rad/s
    return y


@pytest.mark.parametrize("seed", range(4))
def test_a_settling_bias_is_flagged_with_its_start_and_end(seed: int) -> None:
    st = stationarity(gyro(seed, warm=True), RATE)
    assert st.warmup is not None
    assert abs(st.warmup.start_s) <= 0.2 * WARMUP_END_S
    assert st.warmup.end_s == pytest.approx(WARMUP_END_S, rel=0.2)


@pytest.mark.parametrize("seed", range(4))
def test_clean_logs_are_not_flagged(seed: int) -> None:
    st = stationarity(gyro(seed, warm=False), RATE)
    assert st.warmup is None and st.stationary
    assert st.adev.shape == (8, st.tau_s.size) and np.all(st.ci_lower <= st.adev)
    assert json.loads(json.dumps(st.to_dict(), allow_nan=False))["warmup"] is None


def test_a_noise_level_change_fails_the_stationarity_test() -> None:
    y = gyro(5, warm=False)
    y[N // 2 :] *= 1.5  # the white noise grows by half in the second hour
    st = stationarity(y, RATE)
    assert not st.stationary and st.p_value < 1e-3
    assert any("not stationary" in m for m in st.messages("rad/s"))


def test_cut_warmup_cuts_each_channel_at_its_own_warmup() -> None:
    t = np.arange(N) / RATE
    log = ImuLog(channels={"gyro_x": gyro(1, True), "gyro_y": gyro(2, False)}, rate_hz=RATE, t=t)
    kept = analyse_static(log, StaticSettings())
    cut = analyse_static(log, StaticSettings(cut_warmup=True))
    assert any("warm-up" in w for w in kept.channels["gyro_x"].warnings)
    w = kept.channels["gyro_x"].stationarity.warmup
    assert w.end_s <= w.cut_s <= N / RATE / 2
    gx, gy = cut.channels["gyro_x"], cut.channels["gyro_y"]
    assert gx.allan.n_samples == N - int(np.ceil(w.cut_s * RATE))
    assert gx.start_s == pytest.approx(w.cut_s, abs=1.0 / RATE)
    assert gy.allan.n_samples == N and gy.start_s == 0.0  # no warm-up there: nothing cut
    assert gx.run_hours == pytest.approx((N / RATE - gx.start_s) / 3600.0)
    assert any("were cut before the analysis of this channel" in n for n in gx.notes)
    assert any("no warm-up found on this channel; nothing cut" in n for n in gy.notes)
    doc = cut.to_json()
    assert doc["settings"]["cut_warmup"] is True
    assert doc["input"]["n_samples"] == N  # the log as read
    assert doc["channels"]["gyro_x"]["analysed"]["start_s"] == gx.start_s
    assert doc["channels"]["gyro_x"]["stationarity"]["warmup"]["cut_s"] == w.cut_s
