"""The flicker (bias-instability) noise model as a sum of Gauss–Markov processes.

Bias instability ``B`` is flicker noise: a flat Allan deviation ``0.664·B`` (Allan
variance ``(2 ln2/π)·B²``) over a τ range. It is represented by first-order
Gauss–Markov processes whose correlation times are log-spaced (2 per decade) from
τ_lo/6 to 1.5·τ_hi, weights by non-negative least squares so that the sum of the GM
Allan variances is flat to ~0.1 % over [τ_lo, τ_hi] and equal to (2 ln2/π)·B² there;
outside the range the curve falls off (τ below: like a random walk, above: like white
noise).

One model for both users: the noise simulator generates these processes
(:mod:`imubounds.stationary.noise_sim`) and the dynamic error budget bounds them
(:mod:`imubounds.dynamic.estimator.budget`, ``d_F``).
"""

from __future__ import annotations

import math

import numpy as np

from imubounds.errors import OptionError
from imubounds.stationary.gauss_markov import GaussMarkovModel, gm_avar_continuous

__all__ = ["B_FACTOR2", "DEFAULT_BIAS_TAU_RANGE", "flicker_gm_terms"]

#: Allan variance of flicker noise per B²: 2 ln2 / π (deviation 0.664 B).
B_FACTOR2 = 2.0 * math.log(2.0) / math.pi
#: Default τ range (s) over which bias instability is flicker noise.
DEFAULT_BIAS_TAU_RANGE: tuple[float, float] = (1.0, 1000.0)


def flicker_gm_terms(
    B: float, tau_range_s: tuple[float, float] = DEFAULT_BIAS_TAU_RANGE, per_decade: int = 2
) -> tuple[GaussMarkovModel, ...]:
    """Gauss–Markov processes whose summed Allan variance is (2 ln2/π)·B²
    over ``tau_range_s`` (flat to about 0.1 %).

    Parameters
    ----------
    B:
        Bias instability in signal units (rad/s or m/s²).
    tau_range_s:
        (τ_lo, τ_hi) in s where the Allan deviation is flat at 0.664·B.
    per_decade:
        Correlation times per decade.
    """
    lo, hi = float(tau_range_s[0]), float(tau_range_s[1])
    if not (0 < lo < hi and math.isfinite(hi)):
        raise OptionError(f"bias tau range must be 0 < lo < hi seconds, got {tau_range_s}")
    if B <= 0:
        return ()
    a, b = lo / 6.0, hi * 1.5
    k = int(math.ceil(math.log10(b / a) * per_decade)) + 1
    tcs = np.logspace(math.log10(a), math.log10(b), k)
    tau = np.logspace(math.log10(lo), math.log10(hi), 20 * k)
    mat = np.stack([gm_avar_continuous(tau, 1.0, 1.0 / tc) for tc in tcs], axis=1)
    from scipy.optimize import nnls  # here: a half-second import

    w, _ = nnls(mat, np.ones(tau.size))
    level = B_FACTOR2 * B * B
    return tuple(
        GaussMarkovModel(beta=1.0 / tc, sigma=math.sqrt(wi * level), method="flicker_approx")
        for tc, wi in zip(tcs, w, strict=True)
        if wi > 0
    )
