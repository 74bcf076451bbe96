"""Terms consistent with their curve (issue 28 item 1): a resolved term never
contradicts the data, structure the five terms cannot follow is reported."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from imubounds.stationary.allan import allan
from imubounds.stationary.consistency import consistent_bound, misfit_ranges
from imubounds.stationary.gauss_markov import simulate_gm
from imubounds.stationary.terms import analyse_curve, curve_upper_bound

from .synthetic import five_term_signal

ADIS = "src/imubounds/data/adis16405_imu1_extract.csv.gz"


def bumped_log(seed: int, rate: float, n: int, b: float, k: float, tc: float, gain: float):
    """White + flicker + random walk with a Gauss-Markov bump (correlation time tc s,
    standard deviation gain·B) on top: structure the five terms cannot follow."""
    y = five_term_signal(n, rate, 0.0, 1e-3, b, k, 0.0, seed)
    phi = math.exp(-1.0 / (tc * rate))
    sig = gain * b
    y += simulate_gm(n, phi, sig * math.sqrt(1 - phi**2), sig, np.random.default_rng(seed + 1))
    return y


@settings(max_examples=12)
@given(
    seed=st.integers(0, 10_000),
    rate=st.sampled_from([1.0, 2.0, 5.0]),
    b=st.floats(5e-5, 3e-4),
    k=st.floats(0.0, 2e-6),
    log_tc=st.floats(1.5, 3.0),
    gain=st.floats(1.0, 4.0),
)
def test_no_resolved_b_above_the_curves_bound_with_a_gm_bump(
    seed: int, rate: float, b: float, k: float, log_tc: float, gain: float
) -> None:
    y = bumped_log(seed, rate, 30_000, b, k, 10**log_tc, gain)
    curve = allan(y, rate)
    _, _, sel = analyse_curve(curve)
    bound, _ = consistent_bound(curve, "B")
    if sel.status("B") == "resolved":
        assert sel.value("B") <= bound * (1 + 1e-9)
    else:  # an upper bound is never below what the curve allows
        assert sel.value("B") >= min(bound, curve_upper_bound(curve, "B")[0]) * (1 - 1e-9)


def test_a_bump_absorbed_into_b_is_refused_and_said() -> None:
    # seed 34 of a scan: the fit's B runs above the curve's intervals at the floor
    rng = np.random.default_rng(34)
    rate = float(rng.choice([1.0, 2.0, 5.0]))
    n = int(rng.integers(20000, 60000))
    b, k = float(rng.uniform(0.5e-4, 3e-4)), float(rng.uniform(0, 2e-6))
    tc, gain = float(10 ** rng.uniform(1.5, 3)), float(rng.uniform(1, 4))
    y = bumped_log(34, rate, n, b, k, tc, gain)
    curve = allan(y, rate)
    fit, slope, sel = analyse_curve(curve)
    bound, _ = consistent_bound(curve, "B")
    assert fit.status["B"] == "resolved" and fit.value("B") > bound  # the fit alone contradicts
    assert sel.value("B") <= bound
    assert any("exceeds what the curve allows" in n for n in sel.notes)
    assert sel.misfit, "the bump is reported as a misfit range"
    assert all(r["tau_range_s"][0] <= r["tau_range_s"][1] for r in sel.misfit)


def test_clean_logs_have_no_misfit_and_keep_the_fit() -> None:
    rate, n = 2.0, 40_000
    y = five_term_signal(n, rate, 0.0, 1e-3, 1.5e-4, 1e-6, 0.0, 7)
    curve = allan(y, rate)
    fit, _, sel = analyse_curve(curve)
    assert misfit_ranges(curve, {t: fit.value(t) for t in "QNBKR"}) == []
    assert sel.terms["B"].source == "fit" and sel.status("B") == "resolved"


def test_adis_accelerometer_b_lies_within_its_read_off_band() -> None:
    from imubounds.io.registry import read_imu
    from imubounds.stationary.pipeline import StaticSettings, analyse_static

    log = read_imu(ADIS)
    res = analyse_static(log, StaticSettings(models=()), channels=["accel_x", "accel_y", "accel_z"])
    for name, ch in res.channels.items():
        sm = ch.selected.sigma_min
        lo, hi = (v / 0.6643 for v in sm["ci"])
        b = ch.selected.value("B")
        assert ch.selected.status("B") == "resolved", name
        assert lo * 0.999 <= b <= hi * 1.001, f"{name}: B {b} outside the read-off band {lo}..{hi}"
    bound, _ = consistent_bound(res.channels["accel_x"].allan, "B")
    assert res.channels["accel_x"].selected.value("B") <= bound
    noise = res.to_json()["channels"]["accel_y"]["noise"]["selected"]
    assert isinstance(noise["misfit"], list) and noise["misfit"]


@pytest.mark.parametrize("term", ["N", "K"])
def test_consistent_bound_is_at_least_the_curve_bound(term: str) -> None:
    y = five_term_signal(20_000, 5.0, 0.0, 1e-3, 1e-4, 1e-6, 0.0, 3)
    curve = allan(y, 5.0)
    # capped EDFs widen the intervals: the gate never refuses what the bound allows
    assert consistent_bound(curve, term)[0] >= curve_upper_bound(curve, term)[0] * (1 - 1e-12)
