"""Noise terms read off Allan-family curves: fit, read-off, selection (stationary.terms)."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from imubounds.errors import AnalysisError, InputError
from imubounds.stationary import theory
from imubounds.stationary.allan import ESTIMATORS, allan
from imubounds.stationary.terms import (
    B_FACTOR,
    EDF_MIN,
    TERMS,
    _eta_from_residuals,
    _median_small,
    analyse_curve,
    avar_terms,
    fit_slopes,
    fit_terms,
    selected_terms,
)
from imubounds.units import DEG, to_ieee

from .synthetic import five_term_signal

TRUE = {"Q": 0.02, "N": 0.1, "B": 0.01, "K": 2e-4, "R": 2e-7}
RATE = 100.0


def exact_curve(
    tau: np.ndarray,
    estimator: str = "overlapping",
    edf: float | np.ndarray = 1e6,
    rate_hz: float | None = None,
    n_samples: int | None = None,
    **terms: float,
) -> SimpleNamespace:
    """The expected curve of ``estimator`` for ``terms``, with ±1 % intervals."""
    dev = theory.sigma(terms, tau, estimator, rate_hz=rate_hz, n_samples=n_samples)
    return SimpleNamespace(
        tau=tau,
        dev=dev,
        ci_lower=dev * 0.99,
        ci_upper=dev * 1.01,
        edf=np.broadcast_to(np.asarray(edf, dtype=float), tau.shape).copy(),
        estimator=estimator,
        rate_hz=rate_hz,
        n_samples=n_samples,
    )


def octave(n: int, rate: float = RATE) -> np.ndarray:
    return 2.0 ** np.arange(int(math.log2(n // 2)) + 1) / rate


def test_characteristic_points_of_each_term() -> None:
    assert math.sqrt(avar_terms(1.0, N=0.3)) == pytest.approx(0.3)
    assert math.sqrt(avar_terms(math.sqrt(3), Q=0.3)) == pytest.approx(0.3)
    assert math.sqrt(avar_terms(3.0, K=0.3)) == pytest.approx(0.3)
    assert math.sqrt(avar_terms(math.sqrt(2), R=0.3)) == pytest.approx(0.3)
    assert math.sqrt(avar_terms(123.0, B=1.0)) == pytest.approx(0.664, abs=5e-4)
    assert pytest.approx(0.6643, abs=1e-4) == B_FACTOR


@pytest.mark.parametrize("estimator", ESTIMATORS)
def test_fit_recovers_exact_curves_of_every_estimator(estimator: str) -> None:
    """The fit uses each estimator's own factors: the exact curve gives the terms back."""
    n = 2**30
    tau = np.logspace(-2, 6, 80)
    truth = dict(TRUE) if estimator not in ("hadamard", "non-overlapping-hadamard") else {
        t: v for t, v in TRUE.items() if t != "R"
    }
    fit = fit_terms(exact_curve(tau, estimator, rate_hz=RATE, n_samples=n, **truth))
    for t, v in truth.items():
        assert fit.value(t) == pytest.approx(v, rel=1e-4), f"{estimator} {t}: {fit.value(t)}"
        assert fit.status[t] == "resolved", (estimator, t)
    if "R" not in truth:
        assert fit.status["R"] == "not_observed" and math.isnan(fit.R)


@pytest.mark.parametrize("estimator", ["modified", "hadamard", "total"])
def test_allan_factors_on_other_curves_would_be_wrong_ours_are_not(estimator: str) -> None:
    """Issue 13: N from a modified curve read with the Allan formula was 30 % low,
    B from a Hadamard curve 10-45 % low. The read-off with the estimator's factors is not."""
    n = 2**24
    tau = octave(n)
    c = exact_curve(tau, estimator, rate_hz=RATE, n_samples=n, N=0.1, B=0.01, K=2e-4)
    slope = fit_slopes(c)
    assert slope.N == pytest.approx(0.1, rel=0.02), slope.N
    naive_n = float(np.min(c.dev * np.sqrt(tau)))  # σ(τ)·√τ: the Allan read-off of N
    if estimator == "modified":
        assert naive_n < 0.75 * 0.1  # what the old code reported
    fit = fit_terms(c)
    assert fit.B == pytest.approx(0.01, rel=1e-3)
    if estimator == "hadamard":
        naive_b = float(np.min(c.dev)) / B_FACTOR
        assert abs(naive_b / 0.01 - 1) > 0.1 or abs(fit.B / 0.01 - 1) < 1e-3


def test_same_terms_whatever_the_estimator_on_synthetic_noise() -> None:
    rate, n = 100.0, 2**21
    truth = {"N": 2e-3, "B": 3e-4, "K": 2e-5}
    y = five_term_signal(n, rate, 0.0, truth["N"], truth["B"], truth["K"], 0.0, seed=3)
    got: dict[str, dict[str, float]] = {}
    for e in ESTIMATORS:
        _, _, sel = analyse_curve(allan(y, rate, "octave", e))
        got[e] = {t: sel.value(t) for t in ("N", "B")}
        assert sel.status("N") == "resolved" and sel.status("B") == "resolved", e
    for e, v in got.items():
        assert v["N"] == pytest.approx(truth["N"], rel=0.03), (e, v["N"])
        assert v["B"] == pytest.approx(truth["B"], rel=0.25), (e, v["B"])
        assert v["N"] == pytest.approx(got["overlapping"]["N"], rel=0.03), e


@pytest.mark.parametrize("factor", [0.3, 3.0])
def test_a_notch_or_a_bump_cannot_drag_the_fit(factor: float) -> None:
    tau = np.logspace(-2, 3.5, 24)
    c = exact_curve(tau, edf=np.logspace(6, 2, tau.size), rate_hz=RATE, N=0.1, B=0.01, K=2e-4)
    c.dev[9] *= factor
    c.ci_lower[9] *= factor
    c.ci_upper[9] *= factor
    fit = fit_terms(c)
    plain = fit_terms(c, robust=False)
    for t, v in {"N": 0.1, "B": 0.01, "K": 2e-4}.items():
        assert fit.value(t) == pytest.approx(v, rel=0.02), (t, fit.value(t))
    assert fit.stats["points_downweighted"] >= 1
    worst = max(abs(plain.value(t) / v - 1) for t, v in {"N": 0.1, "B": 0.01}.items())
    assert worst > 0.05, f"the plain fit is dragged by {worst:.1%}"


def test_a_notch_at_the_floor_is_not_taken_for_sigma_min() -> None:
    tau = np.logspace(-2, 3.5, 24)
    c = exact_curve(tau, edf=np.logspace(6, 2, tau.size), rate_hz=RATE, N=0.1, B=0.01, K=2e-4)
    i = int(np.argmin(c.dev))
    floor = float(c.dev[i])
    c.dev[i] *= 0.3
    fit, slope, sel = analyse_curve(c)
    assert sel.sigma_min["index"] != i
    assert sel.sigma_min["value"] == pytest.approx(floor, rel=0.1)
    assert slope.B == pytest.approx(sel.sigma_min["value"] / B_FACTOR, rel=1e-6)


def test_intervals_include_the_model_misfit() -> None:
    """A curve off the model by ±15 % with EDF 1e6 gets intervals of that size, not ±0.1 %."""
    tau = np.logspace(-2, 3.5, 30)
    c = exact_curve(tau, rate_hz=RATE, N=0.1, B=0.01, K=2e-4)
    wobble = 1.0 + 0.15 * np.sin(3.0 * np.log(tau))
    c.dev *= wobble
    fit = fit_terms(c)
    assert fit.stats["misfit_rel"] > 0.05
    assert fit.stats["chi2_dof"] < 2.0  # once the misfit is counted
    lo, hi = fit.ci["N"]
    assert (hi - lo) / fit.N > 0.01, f"N interval {lo:.4g}..{hi:.4g} ignores the misfit"
    assert lo <= 0.1 <= hi or abs(fit.N / 0.1 - 1) < 0.05


def test_hidden_white_noise_is_an_upper_bound_at_or_above_the_truth() -> None:
    """MTx-like gyro at 100 Hz: the white noise never dominates the flicker floor."""
    n = 10**6
    tau = octave(n)
    truth = {"N": 0.05 * DEG, "B": 1.0 * DEG}
    edf = 1.5 * n / (tau * RATE)
    c = exact_curve(tau, edf=edf, rate_hz=RATE, n_samples=n, **truth)
    c.ci_lower, c.ci_upper = c.dev * (1 - 2 / np.sqrt(edf)), c.dev * (1 + 2 / np.sqrt(edf))
    fit, slope, sel = analyse_curve(c)
    assert sel.status("N") == "upper_bound" and sel.terms["N"].source == "curve_ci"
    assert sel.value("N") >= truth["N"], (sel.value("N"), truth["N"])
    assert sel.value("N") < 3.0 * truth["N"]
    assert sel.status("B") == "resolved"
    assert sel.value("B") == pytest.approx(truth["B"], rel=0.01)


def test_no_selected_term_is_zero_unless_the_estimator_is_blind_to_it() -> None:
    n = 10**6
    tau = octave(n)
    c = exact_curve(tau, edf=1.5 * n / (tau * RATE), rate_hz=RATE, n_samples=n, N=0.1, B=0.01)
    _, _, sel = analyse_curve(c)
    for t in TERMS:
        assert sel.value(t) > 0, t
    assert sel.status("K") == "upper_bound" and sel.status("R") == "upper_bound"
    js = sel.to_json("gyro")
    assert js["K"]["status"] == "upper_bound" and js["K"]["value"] > 0
    assert js["K"]["ci"][0] == 0.0
    had = exact_curve(tau, "hadamard", edf=1e4, rate_hz=RATE, n_samples=n, N=0.1, B=0.01)
    _, _, sel_h = analyse_curve(had)
    assert sel_h.status("R") == "not_observed" and sel_h.value("R") == 0.0
    assert sel_h.to_json("gyro")["R"]["value"] is None


def test_upper_bounds_cover_small_true_terms() -> None:
    """A K too small to show: its upper bound from the curve is at or above it."""
    n = 10**6
    tau = octave(n)
    edf = 1.5 * n / (tau * RATE)
    c = exact_curve(tau, edf=edf, rate_hz=RATE, n_samples=n, N=0.1, B=0.01, K=1e-6)
    c.ci_upper = c.dev * (1 + 2 / np.sqrt(edf))
    _, _, sel = analyse_curve(c)
    assert sel.status("K") == "upper_bound"
    assert sel.value("K") >= 1e-6


def test_sigma_min_and_b_read_off_ignore_points_with_few_degrees_of_freedom() -> None:
    """Issue 13: the minimum was taken at τ = 1310 s with about 5 degrees of freedom."""
    n = 10**6
    tau = octave(n)
    edf = n / (tau * RATE)
    c = exact_curve(tau, edf=edf, rate_hz=RATE, n_samples=n, N=0.1, B=0.01, K=2e-5)
    low = np.flatnonzero(edf < EDF_MIN)
    assert low.size >= 2
    c.dev[low[-1]] = 0.2 * c.dev.min()  # a deep, poorly measured last point
    fit, slope, sel = analyse_curve(c)
    sm = sel.sigma_min
    assert sm["edf"] >= EDF_MIN and sm["tau_s"] < tau[low[0]]
    assert slope.B == pytest.approx(sm["value"] / B_FACTOR, rel=1e-3)
    js = sel.to_json("gyro")["sigma_min"]
    assert js["tau_s"] == sm["tau_s"] and "0.664" in js["convention"]
    assert js["datasheet"]["unit"] == "deg/s"


def test_a_floor_without_an_interior_minimum_is_resolved() -> None:
    """Issue 13: 'no minimum inside the tau range' although the curve has a clear floor."""
    n = 10**6
    tau = octave(n)
    c = exact_curve(tau, edf=1.5 * n / (tau * RATE), rate_hz=RATE, n_samples=n, N=0.1, B=0.01)
    assert np.all(np.diff(c.dev) < 0)  # monotone: the floor is reached, never left
    fit, slope, sel = analyse_curve(c)
    assert sel.status("B") == "resolved"
    assert sel.value("B") == pytest.approx(0.01, rel=1e-3)
    assert slope.status["B"] == "resolved"


def test_read_off_reports_where_each_term_was_read() -> None:
    n = 2**24
    tau = octave(n)
    c = exact_curve(tau, edf=1.5 * n / (tau * RATE), rate_hz=RATE, n_samples=n,
                    N=0.1, B=0.01, K=2e-4)  # fmt: skip
    fit, slope, sel = analyse_curve(c)
    n_tau = slope.tau_used["N"]
    k_tau = slope.tau_used["K"]
    assert n_tau < sel.sigma_min["tau_s"] < k_tau
    assert slope.info["N"]["local_slope"] == pytest.approx(-0.5, abs=0.05)
    assert slope.info["N"]["expected_slope"] == pytest.approx(-0.5, abs=1e-3)
    assert slope.info["N"]["share"] >= 0.5
    assert slope.N == pytest.approx(0.1, rel=0.01)
    # K is read where it dominates, and the read value is an upper estimate
    assert slope.K >= 2e-4 * 0.99
    js = slope.to_json("gyro")
    assert js["N"]["tau_s"] == n_tau and "local_slope" in js["N"]


def test_read_off_warns_when_the_local_slope_is_off() -> None:
    """White noise that only just dominates the first point: the N read-off says that the
    local slope is not -1/2 there, so its value is an upper estimate."""
    tau = np.logspace(-2, 3, 25)
    c = exact_curve(tau, edf=1e5, rate_hz=RATE, N=0.1, B=1.23)
    slope = fit_slopes(c)
    info = slope.info["N"]
    assert slope.tau_used["N"] == pytest.approx(0.01)
    assert info["local_slope"] > -0.4, info
    assert any("local slope" in w for w in info["warnings"])
    assert any(note.startswith("N: local slope") for note in slope.notes)
    assert slope.N >= 0.1


def test_fit_recovers_terms_from_synthetic_noise() -> None:
    rate = 10.0
    y = five_term_signal(2**23, rate, seed=1, **TRUE)
    res = allan(y, rate, taus="points:60")
    terms = fit_terms(res)
    for t in ("Q", "N", "B", "K"):
        assert terms.value(t) == pytest.approx(TRUE[t], rel=0.10), t
        lo, hi = terms.ci[t]
        assert lo * 0.9 <= TRUE[t] <= hi * 1.1, (t, lo, hi)


def test_json_has_si_ieee_and_datasheet_units() -> None:
    tau = np.logspace(-2, 4, 40)
    terms = fit_terms(exact_curve(tau, N=0.01 * DEG / 60, B=1 * DEG / 3600))
    js = terms.to_json("gyro")
    assert js["N"]["unit"] == "rad/s^0.5"
    assert js["N"]["ieee"]["unit"] == "deg/h^0.5"
    assert js["N"]["ieee"]["value"] == pytest.approx(0.01, rel=1e-6)
    assert js["N"]["datasheet"]["unit"] == "deg/s/sqrt(Hz)"
    assert js["N"]["datasheet"]["value"] == pytest.approx(0.01 / 60, rel=1e-6)
    assert js["B"]["ieee"]["value"] == pytest.approx(1.0, rel=1e-6)
    assert js["B"]["datasheet"]["value"] == pytest.approx(1.0 / 3600, rel=1e-6)
    assert to_ieee("accel", "B", 9.80665e-6) == pytest.approx((1.0, "ug"))


def test_selected_terms_from_a_noise_json_document() -> None:
    tau = np.logspace(-2, 4, 40)
    _, _, sel = analyse_curve(exact_curve(tau, rate_hz=RATE, N=0.1, B=0.01))
    doc = {"channels": {"gyro_z": {"noise": {"selected": sel.to_json("gyro")}}}}
    got = selected_terms(doc, "gyro_z")
    assert got["N"]["value"] == pytest.approx(0.1, rel=1e-3) and got["N"]["status"] == "resolved"
    assert got["K"]["status"] == "upper_bound" and got["K"]["value"] > 0
    assert got["sigma_min"]["unit"] == "rad/s"
    with pytest.raises(InputError, match="no channel"):
        selected_terms(doc, "gyro_x")
    with pytest.raises(InputError, match="re-run"):
        selected_terms({"channels": {"gyro_z": {"noise": {}}}}, "gyro_z")
    with pytest.raises(InputError, match="channels"):
        selected_terms({}, "gyro_z")


def test_too_short_curve_is_an_analysis_error() -> None:
    one = SimpleNamespace(
        tau=np.array([1.0]),
        dev=np.array([1.0]),
        ci_lower=np.array([0.9]),
        ci_upper=np.array([1.1]),
        edf=np.array([10.0]),
    )
    with pytest.raises(AnalysisError):
        fit_terms(one)
    with pytest.raises(AnalysisError):
        fit_slopes(one)


# ---- the fit's fast median and misfit are the np.median versions, bit for bit
_finite = st.floats(min_value=-1e12, max_value=1e12, allow_nan=False, allow_infinity=False)


@given(st.lists(_finite, min_size=1, max_size=60))
def test_median_small_is_np_median_bit_for_bit(values: list[float]) -> None:
    v = np.array(values)
    assert _median_small(v.copy()) == float(np.median(v))
    v[len(values) // 2] = np.nan
    assert math.isnan(_median_small(v.copy())) and math.isnan(float(np.median(v)))


def _eta_reference(lr: np.ndarray, sd: np.ndarray, w: np.ndarray) -> float:
    """The misfit as first written, with np.median (the plain reference)."""
    from scipy import stats

    keep = w > 0
    if np.count_nonzero(keep) < 3:
        return 0.0
    a = np.abs(lr[keep])
    s = sd[keep]
    target = float(stats.norm.ppf(0.75))
    if float(np.median(a / s)) <= target:
        return 0.0
    lo, hi = 0.0, float(np.max(a)) * 10.0 + 1e-12
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        if float(np.median(a / np.sqrt(s * s + mid * mid))) > target:
            lo = mid
        else:
            hi = mid
    return hi


@given(
    st.lists(
        st.tuples(st.floats(-3.0, 3.0), st.floats(0.01, 2.0), st.sampled_from([0.0, 0.5, 1.0])),
        min_size=0, max_size=40,
    )
)  # fmt: skip
def test_misfit_equals_the_np_median_reference(points: list[tuple[float, float, float]]) -> None:
    lr = np.array([p[0] for p in points], dtype=float)
    sd = np.array([p[1] for p in points], dtype=float)
    w = np.array([p[2] for p in points], dtype=float)
    assert _eta_from_residuals(lr, sd, w) == _eta_reference(lr, sd, w)
