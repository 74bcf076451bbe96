"""Equivalent degrees of freedom of the Allan-family estimators (the confidence intervals
of :mod:`imubounds.stationary.allan`).

* Greenhall's algorithm (C. A. Greenhall and W. J. Riley, "Uncertainty of stability
  variances based on finite differences", PTTI 2003) for the overlapping,
  non-overlapping, modified and Hadamard estimators (the same algorithm as
  ``allantools.ci.edf_greenhall``);
* NIST SP 1065 Table 7 (``edf = b*(N+1)/m - c``) for TOTDEV.
"""

from __future__ import annotations

import functools
import math
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy import special


# --------------------------------------------------------------------------
# chi-squared and normal quantiles without importing scipy.stats
# --------------------------------------------------------------------------
def chi2_ppf(q: Any, df: Any) -> NDArray[np.float64]:
    """``scipy.stats.chi2.ppf(q, df)`` for ``0 < q < 1`` (the same formula,
    ``2·gammaincinv(df/2, q)``, NaN where ``df <= 0``), without importing
    ``scipy.stats`` (about a quarter of a second of every command)."""
    q = np.asarray(q, dtype=np.float64)
    df = np.asarray(df, dtype=np.float64)
    with np.errstate(invalid="ignore"):
        out = 2.0 * special.gammaincinv(df / 2.0, q)
    return np.asarray(np.where(df > 0, out, np.nan), dtype=np.float64)


def norm_ppf(q: Any) -> Any:
    """``scipy.stats.norm.ppf`` (``special.ndtri``)."""
    return special.ndtri(q)


def norm_cdf(x: Any) -> Any:
    """``scipy.stats.norm.cdf`` (``special.ndtr``); ``norm_cdf(-x)`` is the survival."""
    return special.ndtr(x)


def norm_pdf(x: Any) -> Any:
    """``scipy.stats.norm.pdf``, the same expression."""
    return np.exp(-np.asarray(x, dtype=np.float64) ** 2 / 2.0) / np.sqrt(2 * np.pi)


# --------------------------------------------------------------------------
# equivalent degrees of freedom
# --------------------------------------------------------------------------
def _sw(t: float, alpha: int) -> float:
    a = abs(t)
    if alpha == 2:
        return -a
    if alpha == 0:
        return a**3
    if alpha == -2:
        return a**5
    if alpha == -4:
        return a**7
    if a == 0.0:
        return 0.0
    p = {1: 2, -1: 4, -3: 6}[alpha]
    return t**p * math.log(a)


def _sx(t: float, f: float, alpha: int) -> float:
    if math.isinf(f):
        return _sw(t, alpha + 2)
    return f * f * (2.0 * _sw(t, alpha) - _sw(t - 1.0 / f, alpha) - _sw(t + 1.0 / f, alpha))


def _sz(t: float, f: float, alpha: int, d: int) -> float:
    return float(
        sum(
            (-1) ** abs(k) * math.comb(2 * d, d + k) * _sx(t + k, f, alpha)
            for k in range(-d, d + 1)
        )
    )


def _basic_sum(j_: float, m_: float, s_: float, f: float, alpha: int, d: int) -> float:
    total = _sz(0.0, f, alpha, d) ** 2 + (1.0 - j_ / m_) * _sz(j_ / s_, f, alpha, d) ** 2
    for j in range(1, int(j_)):
        total += 2.0 * (1.0 - j / m_) * _sz(j / s_, f, alpha, d) ** 2
    return total


# Greenhall & Riley 2003, Tables 1-3: (a0, a1) per (alpha, d).
_G_TABLE1 = {
    (2, 1): (2 / 3, 1 / 3), (2, 2): (7 / 9, 1 / 2), (2, 3): (22 / 25, 2 / 3),
    (1, 1): (0.840, 0.345), (1, 2): (0.997, 0.616), (1, 3): (1.141, 0.843),
    (0, 1): (1.079, 0.368), (0, 2): (1.033, 0.607), (0, 3): (1.184, 0.848),
    (-1, 2): (1.048, 0.534), (-1, 3): (1.180, 0.816),
    (-2, 2): (1.302, 0.535), (-2, 3): (1.175, 0.777),
    (-3, 3): (1.194, 0.703), (-4, 3): (1.489, 0.702),
}  # fmt: skip
_G_TABLE2 = {
    (2, 1): (3 / 2, 1 / 2), (2, 2): (35 / 18, 1.0), (2, 3): (231 / 100, 3 / 2),
    (1, 1): (78.6, 25.2), (1, 2): (790.0, 410.0), (1, 3): (9950.0, 6520.0),
    (0, 1): (2 / 3, 1 / 6), (0, 2): (2 / 3, 1 / 3), (0, 3): (7 / 9, 1 / 2),
    (-1, 2): (0.852, 0.375), (-1, 3): (0.997, 0.617),
    (-2, 2): (1.079, 0.368), (-2, 3): (1.033, 0.607),
    (-3, 3): (1.053, 0.553), (-4, 3): (1.302, 0.535),
}  # fmt: skip
_G_TABLE3 = {1: (6.0, 4.0), 2: (15.23, 12.0), 3: (47.8, 40.0)}
_J_MAX = 100


@functools.lru_cache(maxsize=4096)
def edf_greenhall(
    alpha: int, d: int, m: int, n_phase: int, overlapping: bool, modified: bool
) -> float:
    """Equivalent degrees of freedom by Greenhall's algorithm.

    Memoised: a pure function of its six integers, asked again for every channel
    of a log (same ``m`` and ``n_phase``) and every unit of a fleet of equal logs.

    Parameters
    ----------
    alpha : int
        Noise exponent of ``S_y(f) ~ f^alpha``, -4..2, with ``alpha + 2d > 1``.
    d : int
        Difference order: 2 Allan, 3 Hadamard (1 first-difference variance).
    m : int
        Cluster size.
    n_phase : int
        Number of phase points (N + 1 for N rate samples).
    overlapping : bool
        Overlapped estimator (stride 1) instead of stride m.
    modified : bool
        Modified variance (MDEV family).

    Returns
    -------
    float
        The EDF (dimensionless, > 0).
    """
    alpha = int(alpha)
    if alpha + 2 * d <= 1:
        raise ValueError(f"Greenhall EDF needs alpha + 2d > 1 (alpha={alpha}, d={d})")
    f = 1.0 if modified else float(m)
    s = float(m) if overlapping else 1.0
    length = m / f + m * d
    m_big = 1.0 + math.floor(s * (n_phase - length) / m)
    j_ = min(m_big, (d + 1) * s)
    r = m_big / s
    if modified:
        if j_ <= _J_MAX:
            inv = _basic_sum(j_, m_big, s, 1.0, alpha, d) / (_sz(0.0, 1.0, alpha, d) ** 2 * m_big)
        elif r > d + 1:
            a0, a1 = _G_TABLE1[(alpha, d)]
            inv = (a0 - a1 / r) / r
        else:
            mp = _J_MAX / r
            inv = _basic_sum(_J_MAX, _J_MAX, mp, 1.0, alpha, d) / (
                _sz(0.0, 1.0, alpha, d) ** 2 * _J_MAX
            )
        return 1.0 / inv
    if alpha <= 0:
        if j_ <= _J_MAX:
            fp = float(m) if m * (d + 1) <= _J_MAX else math.inf
            inv = _basic_sum(j_, m_big, s, fp, alpha, d) / (_sz(0.0, fp, alpha, d) ** 2 * m_big)
        elif r > d + 1:
            a0, a1 = _G_TABLE2[(alpha, d)]
            inv = (a0 - a1 / r) / r
        else:
            mp = _J_MAX / r
            inv = _basic_sum(_J_MAX, _J_MAX, mp, math.inf, alpha, d) / (
                _sz(0.0, math.inf, alpha, d) ** 2 * _J_MAX
            )
        return 1.0 / inv
    if alpha == 1:
        if j_ <= _J_MAX:
            inv = _basic_sum(j_, m_big, s, float(m), 1, d) / (_sz(0.0, float(m), 1, d) ** 2 * m_big)
        elif r > d + 1:
            a0, a1 = _G_TABLE2[(1, d)]
            b0, b1 = _G_TABLE3[d]
            inv = (a0 - a1 / r) / ((b0 + b1 * math.log(m)) ** 2 * r)
        else:
            mp = _J_MAX / r
            b0, b1 = _G_TABLE3[d]
            inv = _basic_sum(_J_MAX, _J_MAX, mp, mp, 1, d) / ((b0 + b1 * math.log(m)) ** 2 * _J_MAX)
        return 1.0 / inv
    # alpha == 2, unmodified
    k = math.ceil(r)
    if k <= d:
        # too few terms for the asymptotic form: evaluate the basic sum exactly
        inv = _basic_sum(j_, m_big, s, float(m), 2, d) / (_sz(0.0, float(m), 2, d) ** 2 * m_big)
        return 1.0 / inv
    a0 = math.comb(4 * d, 2 * d) / math.comb(2 * d, d) ** 2
    a1 = d / 2.0
    return 1.0 / ((a0 - a1 / r) / m_big)


def edf_totdev(n_phase: int, m: int, alpha: int) -> float:
    """EDF of the total deviation, NIST SP 1065 Table 7 (``b*T/tau - c``).

    For alpha outside {0, -1, -2} the overlapping-ADEV Greenhall EDF is used.
    """
    table7 = {0: (1.50, 0.0), -1: (1.17, 0.22), -2: (0.93, 0.36)}
    if alpha in table7:
        b, c = table7[alpha]
        return b * (n_phase / m) - c
    return edf_greenhall(alpha, 2, m, n_phase, overlapping=True, modified=False)
