import math
from types import SimpleNamespace

import numpy as np
import pytest

from imubounds.errors import AnalysisError
from imubounds.stationary.terms import B_FACTOR, TERMS, avar_terms, fit_slopes, fit_terms
from imubounds.units import DEG, to_ieee

from .synthetic import five_term_signal

TRUE = {"Q": 0.02, "N": 0.1, "B": 0.01, "K": 2e-4, "R": 2e-7}


def exact_curve(tau: np.ndarray, edf: float = 1e6, **terms: float) -> SimpleNamespace:
    dev = np.sqrt(avar_terms(tau, **terms))
    return SimpleNamespace(
        tau=tau, dev=dev, ci_lower=dev * 0.99, ci_upper=dev * 1.01, edf=np.full(tau.shape, edf)
    )


def test_characteristic_points_of_each_term() -> None:
    assert math.sqrt(avar_terms(1.0, N=0.3)) == pytest.approx(0.3)
    assert math.sqrt(avar_terms(math.sqrt(3), Q=0.3)) == pytest.approx(0.3)
    assert math.sqrt(avar_terms(3.0, K=0.3)) == pytest.approx(0.3)
    assert math.sqrt(avar_terms(math.sqrt(2), R=0.3)) == pytest.approx(0.3)
    assert math.sqrt(avar_terms(123.0, B=1.0)) == pytest.approx(0.664, abs=5e-4)
    assert pytest.approx(0.6643, abs=1e-4) == B_FACTOR


@pytest.mark.parametrize("term", ["Q", "N", "K", "R"])
def test_slope_readoff_exact_on_single_term_curves(term: str) -> None:
    tau = np.logspace(-2, 4, 40)
    curve = exact_curve(tau, **{term: 0.05})
    terms = fit_slopes(curve)
    assert terms.value(term) == pytest.approx(0.05, rel=1e-9)
    lo, hi = terms.ci[term]
    assert lo < terms.value(term) < hi


def test_slope_readoff_bias_instability_is_minimum_over_0664() -> None:
    tau = np.logspace(-2, 5, 60)
    curve = exact_curve(tau, N=0.1, B=0.01, K=1e-4)
    terms = fit_slopes(curve)
    assert terms.B == pytest.approx(curve.dev.min() / B_FACTOR)
    # The minimum of a curve with N and K lies above the flat B level.
    assert terms.B > 0.01
    # N and K are read where their slopes dominate.
    assert terms.N == pytest.approx(0.1, rel=0.05)
    assert terms.K == pytest.approx(1e-4, rel=0.1)


def test_slope_readoff_reports_unobserved_terms() -> None:
    tau = np.logspace(0, 3, 20)
    terms = fit_slopes(exact_curve(tau, N=0.1))
    assert math.isnan(terms.K) and math.isnan(terms.Q) and math.isnan(terms.R)
    assert math.isnan(terms.B)  # no minimum inside the range: a monotone curve
    assert any(note.startswith("K:") for note in terms.notes)


def test_fit_recovers_exact_curve() -> None:
    tau = np.logspace(-2, 5, 80)
    terms = fit_terms(exact_curve(tau, **TRUE))
    for t in TERMS:
        assert terms.value(t) == pytest.approx(TRUE[t], rel=1e-6), t


def test_fit_pins_absent_terms_at_zero() -> None:
    tau = np.logspace(-1, 3, 40)
    terms = fit_terms(exact_curve(tau, N=0.1, K=1e-3))
    assert terms.N == pytest.approx(0.1, rel=1e-6)
    assert terms.Q < 1e-6 * terms.N and terms.R < 1e-6 * terms.K
    assert terms.B < 1e-6 * terms.N and terms.ci["B"][0] == 0.0


def test_fit_recovers_terms_from_synthetic_noise() -> None:
    from imubounds.stationary.allan import allan

    rate = 10.0
    y = five_term_signal(2**23, rate, seed=1, **TRUE)
    res = allan(y, rate, taus=60)
    terms = fit_terms(res)
    for t in TERMS:
        assert terms.value(t) == pytest.approx(TRUE[t], rel=0.10), t
    # Each true value lies inside (or within 10 % of) the fit's 68 % interval.
    for t in ("Q", "N", "B"):
        lo, hi = terms.ci[t]
        assert lo * 0.9 <= TRUE[t] <= hi * 1.1, t


def test_json_has_si_and_ieee_units() -> None:
    tau = np.logspace(-2, 4, 40)
    terms = fit_terms(exact_curve(tau, N=0.01 * DEG / 60, B=1 * DEG / 3600))
    js = terms.to_json("gyro")
    assert js["N"]["unit"] == "rad/s^0.5"
    assert js["N"]["ieee"]["unit"] == "deg/h^0.5"
    assert js["N"]["ieee"]["value"] == pytest.approx(0.01, rel=1e-6)
    assert js["B"]["ieee"]["value"] == pytest.approx(1.0, rel=1e-6)
    assert to_ieee("accel", "B", 9.80665e-6) == pytest.approx((1.0, "ug"))


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
