"""The response of every Allan-family estimator to each noise term (stationary.theory)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from imubounds.errors import OptionError
from imubounds.stationary import theory
from imubounds.stationary.allan import ESTIMATORS, allan, max_cluster_size
from imubounds.stationary.ar_model import ArModel, ar_autocovariance
from imubounds.stationary.gauss_markov import GaussMarkovModel
from imubounds.stationary.terms import NoiseTerms

from .synthetic import five_term_signal

N_SMALL = 64
RATE = 10.0


def _expected(estimator: str, ms: list[int], vectors: list[np.ndarray], scale: float) -> np.ndarray:
    """E[σ²] of a quadratic statistic = Σ over the basis of the noise of the statistic."""
    tau = np.array(ms) / RATE
    acc = np.zeros(len(ms))
    for v in vectors:
        acc += allan(v, RATE, taus=tau, estimator=estimator, noise=0).dev ** 2
    return acc * scale


def _ms(estimator: str) -> list[int]:
    top = max_cluster_size(N_SMALL, estimator)
    return sorted({m for m in (1, 2, 3, 4, 5, 7, 8, 10, 16, top) if m <= top})


@pytest.mark.parametrize("estimator", ESTIMATORS)
def test_white_rate_quantization_and_ramp_responses_are_exact(estimator: str) -> None:
    """N, Q and R: the closed forms equal the estimator applied to every unit impulse."""
    t0 = 1.0 / RATE
    ms = _ms(estimator)
    tau = np.array(ms) / RATE
    eye = np.eye(N_SMALL)
    kw = {"rate_hz": RATE, "n_samples": N_SMALL}
    # white rate samples of variance N²/t0, N = 1
    want_n = _expected(estimator, ms, list(eye), 1.0 / t0)
    got_n = theory.response("N", estimator, tau, **kw)
    np.testing.assert_allclose(got_n, want_n, rtol=1e-9, err_msg=f"N on {estimator}")
    # white angle noise of std Q = 1, differenced: y = Δe / t0
    diffs = [np.diff(np.eye(N_SMALL + 1)[i]) / t0 for i in range(N_SMALL + 1)]
    got_q = theory.response("Q", estimator, tau, **kw)
    np.testing.assert_allclose(got_q, _expected(estimator, ms, diffs, 1.0), rtol=1e-9)
    # a unit ramp: deterministic, the Hadamard family is blind to it
    ramp = _expected(estimator, ms, [t0 * np.arange(N_SMALL)], 1.0)
    got_r = theory.response("R", estimator, tau, **kw)
    if estimator in ("hadamard", "non-overlapping-hadamard"):
        assert np.all(got_r == 0) and np.all(ramp < 1e-20)
        assert not theory.observable("R", estimator)
    else:
        np.testing.assert_allclose(got_r, ramp, rtol=1e-9)


@pytest.mark.parametrize("estimator", ESTIMATORS)
def test_rate_random_walk_response(estimator: str) -> None:
    """K: exact for all but the total deviation, whose NIST bias factor is within 2 % at N=64."""
    t0 = 1.0 / RATE
    ms = _ms(estimator)
    tau = np.array(ms) / RATE
    steps = [(np.arange(N_SMALL) >= k).astype(float) for k in range(1, N_SMALL)]
    want = _expected(estimator, ms, steps, t0)  # step variance K² t0, K = 1
    got = theory.response("K", estimator, tau, rate_hz=RATE, n_samples=N_SMALL)
    rtol = 0.02 if estimator == "total" else 1e-9
    np.testing.assert_allclose(got, want, rtol=rtol, err_msg=f"K on {estimator}")


def test_continuous_limits_are_the_textbook_factors() -> None:
    tau = np.array([1.0, 10.0])
    assert theory.response("N", "modified", tau) == pytest.approx(1.0 / (2.0 * tau))
    assert theory.response("K", "hadamard", tau) == pytest.approx(tau / 6.0)
    assert theory.response("K", "modified", tau) == pytest.approx(11.0 / 40.0 * tau)
    # flicker floors: 0.6643 B (Allan), 0.5456 B (modified), 0.5983 B (Hadamard)
    assert math.sqrt(theory.B_VAR_FACTOR["allan"]) == pytest.approx(0.6643, abs=1e-4)
    assert math.sqrt(theory.B_VAR_FACTOR["modified"]) == pytest.approx(0.5456, abs=1e-4)
    assert math.sqrt(theory.B_VAR_FACTOR["hadamard"]) == pytest.approx(0.5983, abs=1e-4)
    # the modified/Allan ratio for flicker FM is NIST SP 1065's R(n) = 0.674
    ratio = theory.B_VAR_FACTOR["modified"] / theory.B_VAR_FACTOR["allan"]
    assert ratio == pytest.approx(0.674, abs=1e-3)
    with pytest.raises(OptionError, match="rate"):
        theory.response("Q", "modified", tau)


@pytest.mark.parametrize("family", ["allan", "modified", "hadamard"])
def test_sampled_flicker_tends_to_the_continuous_constant(family: str) -> None:
    table = np.array(
        [theory._flicker_exact(family, m) for m in range(1, theory.FLICKER_EXACT_M + 1)]
    )
    last = table[-1]
    assert last == pytest.approx(theory.B_VAR_FACTOR[family], rel=5e-5)
    # m = 1: the modified variance is the Allan variance
    assert theory._flicker_exact("modified", 1) == pytest.approx(theory._flicker_exact("allan", 1))
    assert np.all(np.diff(table[3:]) < 1e-5)  # falls towards the constant (quadrature ~3e-6)


def test_flicker_response_matches_simulated_flicker() -> None:
    """Averaged over realisations of a 1/f rate noise, every estimator meets its theory."""
    rate, n = 100.0, 2**19
    acc: dict[str, list[np.ndarray]] = {e: [] for e in ESTIMATORS}
    for seed in range(4):
        y = five_term_signal(n, rate, 0.0, 0.0, 1.0, 0.0, 0.0, seed)
        for e in ESTIMATORS:
            r = allan(y, rate, "octave", e)
            th = theory.response("B", e, r.tau, rate_hz=rate, n_samples=n)
            acc[e].append(r.dev[:10] ** 2 / th[:10])
    for e, vals in acc.items():
        ratio = np.mean(vals, axis=0)
        # tau = 0.01 .. 5 s: statistical scatter of the 4-run mean below 2 %
        assert np.all(np.abs(ratio - 1.0) < 0.03), f"{e}: {np.round(ratio, 3)}"


@pytest.mark.parametrize("estimator", ESTIMATORS)
def test_stationary_variance_equals_the_quadratic_form(estimator: str) -> None:
    a, var = [-1.2, 0.5], 1.0

    def acov(nlags: int) -> np.ndarray:
        return ar_autocovariance(a, var, nlags)

    ms = np.array([1, 2, 3, 5, 8, 13, 40])
    r = acov(200)
    brute = []
    for m in ms:
        fam = "overlapping" if estimator in ("total", "non-overlapping") else estimator
        fam = "hadamard" if fam == "non-overlapping-hadamard" else fam
        w = theory.filter_weights(fam, int(m))
        cov = r[np.abs(np.subtract.outer(np.arange(w.size), np.arange(w.size)))]
        brute.append(w @ cov @ w)
    got = theory.stationary_variance(acov, ms, estimator)
    np.testing.assert_allclose(got, brute, rtol=1e-12)


def test_white_noise_through_the_stationary_route_is_the_N_response() -> None:
    def acov(nlags: int) -> np.ndarray:
        out = np.zeros(nlags)
        out[0] = 1.0
        return out

    ms = np.array([1, 4, 16, 64])
    for e in ("overlapping", "modified", "hadamard"):
        want = theory.response("N", e, ms / 1.0, rate_hz=1.0)  # N² / t0 = 1
        np.testing.assert_allclose(theory.stationary_variance(acov, ms, e), want, rtol=1e-12)


@pytest.mark.parametrize("estimator", ["modified", "hadamard", "total"])
def test_model_curves_for_other_estimators_follow_simulations(estimator: str) -> None:
    gm = GaussMarkovModel(beta=1 / 5.0, sigma=1.0, white_density=0.2, fitted_rate_hz=10.0)
    ar = ArModel(coefficients=(-0.9,), noise_variance=0.19, rate_hz=10.0)
    for model in (gm, ar):
        acc = []
        taus = np.array([0.2, 1.0, 5.0, 20.0])
        for seed in range(6):
            y = model.simulate(200_000, 10.0, rng=seed)
            acc.append(allan(y, 10.0, taus=taus, estimator=estimator).dev ** 2)
        meas = np.mean(acc, axis=0)
        th = model.variance(taus, estimator, rate_hz=10.0)
        assert np.all(np.abs(meas / th - 1.0) < 0.06), (type(model).__name__, meas / th)


def test_sigma_is_the_public_stationary_prediction() -> None:
    terms = {"N": 0.002, "B": 3e-4, "K": 2e-5}
    tau = np.array([1.0, 100.0])
    allan_dev = theory.sigma(terms, tau, "overlapping")
    want = np.sqrt(0.002**2 / tau + 0.4413 * 9e-8 + 4e-10 * tau / 3)
    np.testing.assert_allclose(allan_dev, want, rtol=2e-4)
    # the same through a NoiseTerms, and through a noise.json 'selected' block
    nt = NoiseTerms(N=0.002, B=3e-4, K=2e-5)
    np.testing.assert_allclose(theory.sigma(nt, tau), allan_dev)
    sel = {t: {"value": v, "status": "resolved"} for t, v in terms.items()}
    sel["Q"] = {"value": None, "status": "not_observed"}
    np.testing.assert_allclose(theory.sigma(sel, tau), allan_dev)
    assert np.all(theory.sigma(terms, tau, "modified", rate_hz=100.0) < allan_dev)
    with pytest.raises(OptionError, match="estimator"):
        theory.sigma(terms, tau, "fancy")
    with pytest.raises(OptionError, match=">= 0"):
        theory.sigma({"N": -1.0}, tau)
