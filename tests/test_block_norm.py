"""``transport_blocks.block_norm``: the bound ``Lambda >= ||P C P||`` of the gyro noise
centred on blocks (docs/dynamic-method.md section 3, accel_x "per heading gap"), checked
against the largest eigenvalue of ``P C P`` computed with numpy on explicit matrices
(equal and unequal blocks, one or several), its tightness, and the parts it keeps."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from imubounds.dynamic.estimator.aided.transport_blocks import (
    block_norm,
    centred_distance_norm,
    gm_block_norm,
)
from imubounds.dynamic.estimator.budget import ChannelNoise


def _centring(sizes: list[int]) -> np.ndarray:
    n = sum(sizes)
    P = np.zeros((n, n))
    k = 0
    for s in sizes:
        P[k:k + s, k:k + s] = np.eye(s) - 1.0 / s
        k += s
    return P


def _gm(a: float, n: int) -> np.ndarray:
    idx = np.arange(n)
    return np.exp(-a * np.abs(np.subtract.outer(idx, idx)))


def _exact(C: np.ndarray, sizes: list[int]) -> float:
    P = _centring(sizes)
    return float(np.linalg.eigvalsh(P @ C @ P)[-1])


def _exact_gm(a: float, sizes: list[int]) -> float:
    """||PTP|| for T_ij = exp(-a|i - j|) as ||P D P||, D = 1 - T = -expm1(-a|i - j|)
    (P removes the constant exactly; no cancellation of entries near 1 at small a)."""
    idx = np.arange(sum(sizes))
    D = -np.expm1(-a * np.abs(np.subtract.outer(idx, idx)))
    P = _centring(sizes)
    return float(np.linalg.eigvalsh(-(P @ D @ P))[-1])


def _previous(a: float, m: int) -> float:
    """The bound before the distance-matrix terms: Toeplitz and Gershgorin."""
    phi, q = math.exp(-a), -math.expm1(-a)
    best = (1 + phi) / q
    if a * (m + 2) < 600.0:
        d = -math.expm1(-a * max(m - 1, 0))
        best = min(best, 2 * m * d + 2 * d * d * math.exp(a * (m - 2)) / q)
    return best


@settings(max_examples=150, deadline=None)
@given(
    log_a=st.floats(-9.0, 1.5),
    sizes=st.lists(st.integers(1, 120), min_size=1, max_size=6),
)
def test_gm_bound_encloses_the_exact_norm(log_a: float, sizes: list[int]) -> None:
    """Any a, any block lengths (unequal, one or several): the bound >= the largest
    eigenvalue of PTP, never above the previous bound, and within 1.6x of the exact value
    (within 1.1x with equal blocks, below)."""
    a = 10.0**log_a
    m = max(sizes)
    ex = _exact_gm(a, sizes)
    bound = gm_block_norm(a, m)
    assert bound >= ex * (1 - 1e-9) - 1e-12, (a, sizes, bound, ex)
    assert bound <= _previous(a, m) * (1 + 1e-12)
    if ex > 1e-9:
        assert bound <= 1.6 * ex, (a, sizes, bound, ex)


@pytest.mark.parametrize("m", [2, 3, 10, 50, 200])
@pytest.mark.parametrize("a", [1e-7, 1e-4, 1e-3, 1e-2, 0.03, 0.1, 0.3, 1.0, 3.0])
def test_gm_bound_is_tight_with_equal_blocks(a: float, m: int) -> None:
    """Four equal blocks: within 1.1x of ||PTP|| at every a (the old bound was up to 20x
    above it for a m << 1), and above it."""
    sizes = [m] * 4
    ex = _exact_gm(a, sizes)
    bound = gm_block_norm(a, m)
    assert ex * (1 - 1e-9) <= bound <= 1.1 * ex, (bound, ex)


def test_small_a_is_first_order_exact() -> None:
    """a m << 1: ||PTP|| ~ a ||PLP|| ~ 2 a m^2/pi^2; the bound a ||PLP||_F, 4 % above."""
    m, a = 300, 1e-6
    ex = _exact_gm(a, [m, m])
    assert gm_block_norm(a, m) == pytest.approx(a * centred_distance_norm(m), rel=1e-9)
    assert 1.0 < gm_block_norm(a, m) / ex < 1.05
    assert ex == pytest.approx(2 * a * m * m / math.pi**2, rel=0.01)


@pytest.mark.parametrize("m", [1, 2, 3, 7, 40, 333])
def test_centred_distance_norm_is_the_frobenius_norm(m: int) -> None:
    idx = np.arange(m)
    L = np.abs(np.subtract.outer(idx, idx)).astype(float)
    P = np.eye(m) - 1.0 / m
    M = P @ L @ P
    assert centred_distance_norm(m) == pytest.approx(np.linalg.norm(M), rel=1e-12, abs=1e-12)
    assert centred_distance_norm(m) >= np.max(np.abs(np.linalg.eigvalsh(M))) * (1 - 1e-12)


def test_white_and_quantization_parts_unchanged() -> None:
    """No flicker: Lambda = N^2/dt + 4 Q^2/dt^2 (times the 1e-9 guard), at every m."""
    cn = ChannelNoise("gyro_z", N=1e-3, Q=2e-5)
    dt = 0.01
    for m in (1, 10, 400):
        assert block_norm(cn, m, dt) == pytest.approx(
            (cn.N**2 / dt + 4 * cn.Q**2 / dt**2) * (1 + 1e-9), rel=1e-15
        )


@pytest.mark.parametrize(
    "sizes,factor",
    [([100] * 6, 1.1), ([100, 37, 100, 5, 81, 100], 1.25), ([100], 1.4)],
)
def test_channel_bound_against_the_exact_norm(sizes: list[int], factor: float) -> None:
    """A gyro with white noise and flicker (its Gauss-Markov components, 0.17-1500 s)
    at 100 Hz in 1 s blocks: Lambda >= the largest eigenvalue of P C P with the whole
    covariance, and within ``factor`` of it: 1.04x with six equal blocks, 1.2x with
    unequal ones, 1.35x with a single block (the bound holds for any number of blocks, so
    it keeps the cross-block terms a single block lacks); the previous bound was 5-7x
    above."""
    dt = 0.01
    cn = ChannelNoise("gyro_z", N=math.radians(0.05), B=math.radians(1.0))
    n = sum(sizes)
    C = np.eye(n) * (cn.N**2 / dt)
    prev = cn.N**2 / dt
    for s, b in cn.gm_terms():
        C += s * s * _gm(b * dt, n)
        prev += s * s * _previous(b * dt, max(sizes))
    ex = _exact(C, sizes)
    lam = block_norm(cn, max(sizes), dt)
    assert ex <= lam <= factor * ex, (lam, ex)
    assert lam < prev / 4
