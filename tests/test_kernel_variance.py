"""The compiled Gauss-Markov quadratic form of ``budget.kernel_variance``
(``series_kernels.gm_quadratic_sum``) against its plain reference: two ``lfilter``
passes per component, ``c'Phi c = sum_k c_k (f_k + g_k - c_k)``."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.signal import lfilter

from imubounds.dynamic.estimator.series_kernels import gm_quadratic_sum


def reference(c: np.ndarray, phis: np.ndarray, s2: np.ndarray) -> float:
    v = 0.0
    for phi, w in zip(phis, s2, strict=True):
        f = lfilter([1.0], [1.0, -phi], c)
        g = lfilter([1.0], [1.0, -phi], c[::-1])[::-1]
        v += w * float(np.dot(c, f + g - c))
    return v


def explicit(c: np.ndarray, phis: np.ndarray, s2: np.ndarray) -> float:
    """The matrix itself (small n): ``sum_i s2_i c' Phi_i c``."""
    idx = np.arange(c.size)
    d = np.abs(idx[:, None] - idx[None, :])
    return float(sum(w * c @ (phi**d) @ c for phi, w in zip(phis, s2, strict=True)))


@settings(max_examples=80, deadline=None)
@given(
    st.lists(st.floats(-10, 10), min_size=1, max_size=60),
    st.lists(st.floats(0.0, 20.0), min_size=1, max_size=4),
)
def test_matches_the_explicit_matrix_and_the_two_filters(c: list, betas: list) -> None:
    ca = np.array(c)
    phis = np.array([math.exp(-b) for b in betas])
    s2 = np.linspace(0.5, 2.0, phis.size)
    got = gm_quadratic_sum(ca, phis, s2)
    scale = float(np.sum(s2)) * float(np.sum(np.abs(ca))) ** 2 + 1e-300
    assert abs(got - explicit(ca, phis, s2)) <= 1e-12 * scale
    assert abs(got - reference(ca, phis, s2)) <= 1e-12 * scale


@pytest.mark.parametrize("beta_dt", [1e-7, 1e-4, 1e-2, 1.0])
def test_long_centred_ramps_match_the_filters(beta_dt: float) -> None:
    """Weights like the ramps of ``transport_gyro._ramp_noise_sd`` (sum 0, 60 000
    samples): within 1e-9 of the filters' value relative to ``c.c`` (the inflation
    ``kernel_variance`` adds is 1e-9 of the whole variance, which has ``N^2 c.c/dt``)."""
    rng = np.random.default_rng(3)
    k = np.arange(60000)
    c = np.sin(k / 700.0) * (1 + 0.1 * rng.standard_normal(k.size))
    c -= c.mean()
    phis, s2 = np.array([math.exp(-beta_dt)]), np.array([1.0])
    got = gm_quadratic_sum(c, phis, s2)
    assert abs(got - reference(c, phis, s2)) <= 1e-9 * float(np.dot(c, c))
