"""N from the fit against the read-off: the white level across τ (issue 28, item 1, the
contaminated MTi-G gyro log whose fitted N was 27 % above the read-off).

A correlated process with a correlation time inside N's range (here a Gauss–Markov
component of 0.3 s, like a sensor's internal filtering or a slow vibration) adds no
variance below that time and a white-like level above it: the read-off finds the
level of the shortest τ, the fit a compromise. The outputs must say so, and which
to believe, never disagree silently.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from imubounds.io.log import ImuLog
from imubounds.stationary.allan import allan
from imubounds.stationary.gauss_markov import GaussMarkovModel
from imubounds.stationary.noise_sim import AxisNoise, NoiseSpec, simulate
from imubounds.stationary.pipeline import StaticSettings, analyse_static
from imubounds.stationary.terms import analyse_curve
from imubounds.stationary.white_level import WHITE_LEVEL_TOLERANCE, white_level

RATE = 100.0
TRUTH = {"N": 2e-3, "B": 3e-4, "K": 2e-5}


def _log(extra: tuple[GaussMarkovModel, ...] = (), seed: int = 3, hours: float = 1.5) -> ImuLog:
    ax = AxisNoise(**TRUTH, bias_tau_range_s=(0.05, 2e4), gauss_markov=extra)
    return simulate(NoiseSpec(channels={"gyro_x": ax}), RATE, hours * 3600.0, seed=seed)


def _contaminated(kind: str) -> ImuLog:
    if kind.startswith("gm"):
        tc, sigma = {"gm_fast": (0.05, 5e-3), "gm_mid": (0.3, 2e-3), "gm_slow": (1.0, 1e-3)}[kind]
        return _log((GaussMarkovModel(beta=1.0 / tc, sigma=sigma),))
    log = _log()
    y = np.asarray(log.channels["gyro_x"]).copy()
    rng = np.random.default_rng(5)
    if kind == "spikes":
        pos = rng.choice(y.size, 200, replace=False)
        y[pos] += rng.choice([-1.0, 1.0], pos.size) * 50 * TRUTH["N"] * math.sqrt(RATE)
    elif kind == "quantised":
        q = 2 * TRUTH["N"] * math.sqrt(RATE)
        y = np.round(y / q) * q
    elif kind == "filtered":  # a sensor's moving-average filter
        y = np.convolve(y, np.ones(5) / 5, mode="same")
    return ImuLog(t=log.t, channels={"gyro_x": y}, rate_hz=log.rate_hz, source=kind)


@pytest.fixture(scope="module")
def gm_result() -> tuple[object, ...]:
    log = _contaminated("gm_mid")
    curve = allan(np.asarray(log.channels["gyro_x"]), RATE, "octave")
    fit, slope, sel = analyse_curve(curve)
    return curve, fit, slope, sel


def test_a_correlated_component_makes_fit_and_read_off_disagree(gm_result: tuple) -> None:
    """The MTi-G phenomenon reproduced: a 0.3 s Gauss-Markov component puts the fitted N
    above the read-off, which reads the white level of the shortest τ."""
    curve, fit, slope, _ = gm_result
    assert fit.value("N") > 1.05 * slope.value("N")
    assert slope.value("N") == pytest.approx(TRUTH["N"], rel=0.05)
    wl = white_level(curve, fit, slope)
    assert wl is not None and not wl.constant
    # the level rises with tau: at the shortest tau the white part, at the longest more
    assert wl.level[0] == pytest.approx(TRUTH["N"], rel=0.05)
    assert wl.high["value"] > (1 + WHITE_LEVEL_TOLERANCE) * wl.low["value"]
    assert wl.high["tau_s"] > 1.0 > wl.tau_s[0]  # above the 0.3 s correlation time
    # the fit is a compromise between the two
    assert wl.low["value"] < fit.value("N") < wl.high["value"]
    d = wl.to_dict()
    assert d["constant"] is False and "random walk" in d["use"] and "single samples" in d["use"]


def test_clean_log_has_a_constant_white_level() -> None:
    log = _log(seed=4)
    curve = allan(np.asarray(log.channels["gyro_x"]), RATE, "octave")
    fit, slope, _ = analyse_curve(curve)
    wl = white_level(curve, fit, slope)
    assert wl is not None and wl.constant, (wl.spread, wl.estimates_gap)
    assert wl.message("gyro_x") is None
    assert np.all(np.abs(wl.level[:8] / TRUTH["N"] - 1.0) < 0.05)  # tau <= 1.28 s: EDF high
    assert np.all((0.9 * wl.ci_lower <= TRUTH["N"]) & (TRUTH["N"] <= 1.1 * wl.ci_upper))


@pytest.mark.slow  # six simulated 1.5 h logs through analyse_static: ~20 s
@pytest.mark.parametrize(
    "kind", ["gm_fast", "gm_mid", "gm_slow", "spikes", "quantised", "filtered", "clean"]
)
def test_fit_and_read_off_never_disagree_silently(kind: str) -> None:
    """Whenever the fit's N and the read-off's differ beyond their intervals by more than
    the tolerance, noise.json carries the white level (constant: false) and the channel a
    warning naming both values; when noise.json says constant, they agree."""
    log = _log(seed=6) if kind == "clean" else _contaminated(kind)
    res = analyse_static(log, StaticSettings(models=()))
    ch = res.channels["gyro_x"]
    js = ch.to_json()
    noise = js["noise"]
    fit, ro = noise["fit"]["N"], noise["slope"]["N"]
    assert "white_level" in noise
    wl = noise["white_level"]
    gap = max(fit["ci"][0], ro["ci"][0]) / min(fit["ci"][1], ro["ci"][1]) - 1.0
    warned = [w for w in js.get("warnings", []) if "white level changes with tau" in w]
    if gap > WHITE_LEVEL_TOLERANCE:
        assert wl["constant"] is False
    if not wl["constant"]:
        assert len(warned) == 1
        assert f"{fit['value']:.4g}" in warned[0] and f"{ro['value']:.4g}" in warned[0]
        assert "believe the level at the time scale of use" in warned[0]
    else:
        assert not warned
        assert abs(fit["value"] / ro["value"] - 1.0) <= WHITE_LEVEL_TOLERANCE + 0.05
    if kind == "clean":
        assert wl["constant"] is True
    if kind == "gm_mid":
        assert wl["constant"] is False
