"""A verdict resting on a margin within 5 % of its band is marked fragile, not presented as
decided (docs/dynamic-method.md, section 4): the verdict against the band scaled by 0.95
and 1.05, and the windows whose own test turns within that 5 %."""

from __future__ import annotations

import numpy as np

from imubounds.dynamic.estimator.verdicts import (
    FRAGILE_SHARE,
    ChannelMargins,
    LevelResult,
    fragility,
    verdict_of,
)


def level(x_half: list[float], e_mid: list[float], band: float = 1.0) -> LevelResult:
    """Windows whose aided interval has half-width ``x_half`` (the IMU's mean is exact),
    so that [E_W] = e_mid -+ x_half."""
    xh = np.asarray(x_half, dtype=float)
    mid = np.asarray(e_mid, dtype=float)
    n = xh.size
    zero = np.zeros(n)
    return LevelResult(tau_s=10.0, kind="aided", t_start=np.arange(n) * 10.0,
                       tau=np.full(n, 10.0), x_lo=-mid - xh, x_hi=-mid + xh, y_lo=zero,
                       y_hi=zero, band=np.full(n, band), band_nto=np.full(n, band), k=3.0)


def test_decidable_by_less_than_five_percent_is_fragile() -> None:
    lv = level([0.98, 3.0], [0.0, 0.0])  # one window decidable by 2 % of the band
    assert verdict_of([lv])[0] == "consistent"
    assert fragility([lv], "consistent") == {"0.95": "undecided"}
    assert lv.fragile.tolist() == [True, False]
    assert lv.summary()["fragile_fraction"] == 0.5


def test_outside_by_less_than_five_percent_is_fragile() -> None:
    # decidable (half-width 0.1), its interval 0.03 band beyond the band: exceeds, barely
    lv = level([0.1, 0.1], [1.13, 0.0])
    assert verdict_of([lv])[0] == "exceeds"
    assert fragility([lv], "exceeds") == {"1.05": "consistent"}
    assert lv.fragile.tolist() == [True, False]


def test_a_clear_verdict_is_not_fragile_and_the_share_is_what_it_says() -> None:
    lv = level([0.5, 0.2], [0.0, 2.0])  # decidable by half the band; outside by 0.8 band
    assert verdict_of([lv])[0] == "exceeds" and fragility([lv], "exceeds") == {}
    assert not lv.fragile.any()
    # just beyond the share: not fragile; just within it: fragile
    margin = 1.0 - FRAGILE_SHARE
    assert fragility([level([margin - 1e-9], [0.0])], "consistent") == {}
    assert fragility([level([margin + 1e-9], [0.0])], "consistent") == {"0.95": "undecided"}


def test_the_result_says_fragile_and_not_decided() -> None:
    lv = level([0.98], [0.0])
    flips = fragility([lv], "consistent")
    m = ChannelMargins("accel_y", "m/s^2", "aiding", [lv], "consistent", "r", [], 0,
                       fragile=flips)  # fmt: skip
    d = m.to_dict()
    assert d["fragile"] is True and d["verdict_if_band_scaled"] == {"0.95": "undecided"}
    assert d["fragile_detail"].startswith("FRAGILE: 'consistent' rests on a margin within 5 %")
    assert "not decided" in d["fragile_detail"]
    assert ChannelMargins("gyro_z", "rad/s", "aiding", [lv], "consistent", "r", [],
                          0).to_dict()["fragile"] is False  # fmt: skip
