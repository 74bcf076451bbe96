"""Allan-variance family of a stationary rate signal (METHOD.md section 1.1).

Input is a rate signal ``y`` (gyro in rad/s, accelerometer in m/s^2; the
module is unit-agnostic and returns deviations in the unit of ``y``) sampled
at ``rate_hz``. With ``t0 = 1/rate_hz``, cluster size ``m`` and averaging time
``tau = m*t0``, the integrated signal (phase) is
``x[0] = 0, x[k] = t0 * sum_{i<k} (y[i] - mean(y))`` (length ``N + 1``) and

========================  ==================================================================
``overlapping``           ``1/(2 tau^2 (N-2m+1)) sum_{k=0}^{N-2m} (x[k+2m] - 2x[k+m] + x[k])^2``
                          (IEEE Std 952/1554, NIST SP 1065 eq. 11; allantools ``oadev``)
``non-overlapping``       ``K = N//m`` cluster means, ``1/(2(K-1)) sum (ybar[j+1]-ybar[j])^2``
                          (the paper's cluster form; allantools ``adev``)
``modified``              NIST SP 1065 eq. 14 (allantools ``mdev``)
``hadamard``              overlapping Hadamard, NIST SP 1065 eq. 20 (allantools ``ohdev``)
``non-overlapping-        ``K = N//m`` cluster means,
hadamard``                ``1/(6(K-2)) sum (ybar[j+2]-2ybar[j+1]+ybar[j])^2``
                          (NIST SP 1065 eq. 18; allantools ``hdev``, Stable32 HDEV)
``total``                 TOTDEV with odd reflection at both ends, NIST SP 1065 eq. 25
                          (allantools ``totdev``)
========================  ==================================================================

Removing the mean changes none of them (second/third differences of ``x``
annihilate a linear phase trend, and the TOTDEV reflection preserves it).

Confidence intervals
--------------------
Each point gets a chi-squared interval (NIST SP 1065 eq. 45)
``[dev*sqrt(edf/chi2_{1-p/2}), dev*sqrt(edf/chi2_{p/2})]`` with ``p = 1 -
confidence`` and equivalent degrees of freedom ``edf`` from

* Greenhall's algorithm (C. A. Greenhall and W. J. Riley, "Uncertainty of
  stability variances based on finite differences", PTTI 2003) for the
  overlapping, non-overlapping, modified and Hadamard estimators (the same
  algorithm as ``allantools.ci.edf_greenhall``);
* NIST SP 1065 Table 7 (``edf = b*(N+1)/m - c``) for TOTDEV with white, flicker
  or random-walk FM; for other noise types TOTDEV uses the overlapping-ADEV EDF.

The EDF depends on the power-law noise type ``S_y(f) ~ f^alpha`` (alpha = 2
white PM / quantization, 1 flicker PM, 0 white FM = angle/velocity random
walk, -1 flicker FM = bias instability, -2 random-walk FM = rate random walk).
``noise="auto"`` (default) identifies alpha at each tau with the lag-1
autocorrelation method (W. J. Riley and C. A. Greenhall, "Power law noise
identification using the lag 1 autocorrelation", EFTF 2004) applied to the
cluster means (at most :data:`NOISE_ID_MAX_POINTS` of them); where fewer than
30 cluster means exist the alpha of the previous tau is kept. An integer
``noise`` forces one alpha for every tau.

Robust (outlier-resistant) variant
----------------------------------
``allan(..., robust=True)`` first replaces the samples flagged as spikes by
:func:`imubounds.stationary.contamination.detect_spikes` with a linear
interpolation between their clean neighbours (a spike averaged into long
clusters acts like extra white noise that no scale estimate can tell from
the real one), then replaces the mean of the squared terms ``d_k``
(the second, third or averaged differences above) by a clipped mean (Huber's
proposal 2 for a scale): with ``s = 1.4826·median|d_k|`` (a scale a spike does
not move), each ``d_k²`` is capped at ``(c·s)²``, ``c`` = :data:`ROBUST_CLIP`
(3), and the mean of the capped squares is divided by its expectation for a
standard normal term, ``E[min(Z², c²)]`` = 0.9950. For Gaussian terms the
estimate has the same expectation as the plain one and about the same
variance; a spike contributes at most ``(c·s)²`` to each of the few terms it
touches instead of its full square. Unlike a plain median, the clipped mean
stays unbiased at long τ where the terms are few and strongly correlated.
The EDF of each point is multiplied by :data:`ROBUST_EFFICIENCY` (a margin for
the estimated clipping scale). Points with fewer than :data:`ROBUST_MIN_TERMS`
terms keep the plain estimate. A rate ramp (terms of non-zero mean) is not
represented faithfully by the robust estimate. It is computed in memory only.

Note: the R package ``avar`` (SMAC-Group), which produced the reference curve
of the ADIS16405 log, reports a symmetric interval
``adev * (1 +- 2/sqrt(2*(N/m - 1)))`` (a normal approximation, about 95 %,
with K - 1 = N/m - 1 degrees of freedom whatever the noise); its estimator also
drops the last overlapping term (sums N-2m terms, divides by N-2m+1).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from imubounds.errors import AnalysisError, InputError, OptionError
from imubounds.stationary import _allan_kernels as _k
from imubounds.stationary.allan_grammar import ESTIMATORS as ESTIMATORS
from imubounds.stationary.allan_grammar import TAU_GRAMMAR as TAU_GRAMMAR
from imubounds.stationary.allan_grammar import parse_tau_spec as parse_tau_spec
from imubounds.stationary.edf import chi2_ppf, edf_greenhall, edf_totdev, norm_cdf, norm_pdf

__all__ = [
    "ESTIMATORS",
    "HADAMARD_ESTIMATORS",
    "NOISE_ID_MAX_POINTS",
    "NOISE_NAMES",
    "ROBUST_EFFICIENCY",
    "AllanResult",
    "allan",
    "allan_channels",
    "confidence_interval",
    "edf_greenhall",
    "edf_totdev",
    "estimator_edf",
    "max_cluster_size",
    "noise_id_lag1",
    "parse_tau_spec",
    "tau_grid",
]

#: The Hadamard family (third differences of the phase; blind to a linear rate drift).
HADAMARD_ESTIMATORS: tuple[str, ...] = ("hadamard", "non-overlapping-hadamard")

#: Clipping point of the robust estimate, in robust standard deviations of the terms.
ROBUST_CLIP: float = 3.0
#: E[min(Z², c²)] for a standard normal Z and c = ROBUST_CLIP (consistency factor).
ROBUST_CONSISTENCY: float = float(
    (2 * norm_cdf(ROBUST_CLIP) - 1)
    - 2 * ROBUST_CLIP * norm_pdf(ROBUST_CLIP)
    + 2 * ROBUST_CLIP**2 * norm_cdf(-ROBUST_CLIP)
)
#: EDF factor of the robust estimate (its variance at the normal law is within a few
#: per cent of the plain one; the factor leaves a margin for the estimated scale).
ROBUST_EFFICIENCY: float = 0.9
#: Fewer terms than this at one tau: the robust estimate keeps the plain value.
ROBUST_MIN_TERMS: int = 30
#: 1/Φ⁻¹(3/4): scale of the median absolute value of a zero-mean normal variable.
MAD_SCALE: float = 1.482602218505602

#: Largest number of cluster means used by the lag-1 noise identification.
NOISE_ID_MAX_POINTS: int = 1 << 13

#: Name of each power-law noise exponent alpha (S_y(f) ~ f^alpha) in IMU terms.
NOISE_NAMES: dict[int, str] = {
    2: "white PM (quantization)",
    1: "flicker PM",
    0: "white FM (angle/velocity random walk)",
    -1: "flicker FM (bias instability)",
    -2: "random-walk FM (rate random walk)",
    -3: "flicker walk FM",
    -4: "random run FM (rate ramp-like)",
}

_ALPHA_NAMES = {
    "white_pm": 2,
    "quantization": 2,
    "flicker_pm": 1,
    "white_fm": 0,
    "random_walk": 0,
    "flicker_fm": -1,
    "bias_instability": -1,
    "random_walk_fm": -2,
    "rate_random_walk": -2,
}


# --------------------------------------------------------------------------
# result
# --------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class AllanResult:
    """One Allan-family curve.

    Attributes
    ----------
    tau : ndarray of float
        Averaging times in s (``m / rate_hz``).
    m : ndarray of int
        Cluster sizes in samples.
    dev : ndarray of float
        Deviation, in the unit of the input signal.
    ci_lower, ci_upper : ndarray of float
        Chi-squared confidence interval of ``dev`` at level ``confidence``.
    edf : ndarray of float
        Equivalent degrees of freedom used for the interval.
    n_terms : ndarray of int
        Number of squared terms averaged at each point.
    alpha : ndarray of int
        Power-law exponent of ``S_y(f)`` assumed for the EDF at each point.
    estimator : str
        One of :data:`ESTIMATORS`.
    n_samples : int
        Length of the input signal.
    rate_hz : float
        Sample rate in Hz.
    confidence : float
        Confidence level of the interval (0.683 = 1 sigma).
    robust : bool
        Whether ``dev`` is the outlier-resistant estimate (see the module notes).
    unit : str or None
        Unit of ``dev`` (that of the input signal: ``"rad/s"`` for a gyro,
        ``"m/s^2"`` for an accelerometer), or None when the caller did not say.
    """

    tau: np.ndarray
    m: np.ndarray
    dev: np.ndarray
    ci_lower: np.ndarray
    ci_upper: np.ndarray
    edf: np.ndarray
    n_terms: np.ndarray
    alpha: np.ndarray
    estimator: str
    n_samples: int
    rate_hz: float
    confidence: float
    robust: bool = False
    unit: str | None = None

    def __repr__(self) -> str:
        span = f"{self.tau[0]:.3g}..{self.tau[-1]:.3g} s" if self.tau.size else "none"
        return (
            f"AllanResult(estimator={self.estimator!r}, points={self.tau.size}, tau={span}, "
            f"unit={self.unit!r}, rate_hz={self.rate_hz:g}, n_samples={self.n_samples}"
            f"{', robust' if self.robust else ''})"
        )

    @property
    def var(self) -> np.ndarray:
        """The variance ``dev**2`` (unit of the input, squared)."""
        return self.dev**2

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict: arrays become lists of floats/ints (``unit`` only when known).

        ``noise.json`` holds the same keys under ``channels.<ch>.allan`` with ``tau``
        named ``tau_s`` and ``dev`` named ``adev``.
        """
        out = {
            "estimator": self.estimator,
            "n_samples": int(self.n_samples),
            "rate_hz": float(self.rate_hz),
            "confidence": float(self.confidence),
            "tau": [float(v) for v in self.tau],
            "m": [int(v) for v in self.m],
            "dev": [float(v) for v in self.dev],
            "ci_lower": [float(v) for v in self.ci_lower],
            "ci_upper": [float(v) for v in self.ci_upper],
            "edf": [float(v) for v in self.edf],
            "n_terms": [int(v) for v in self.n_terms],
            "alpha": [int(v) for v in self.alpha],
            "noise_type": [NOISE_NAMES.get(int(v), f"alpha={int(v)}") for v in self.alpha],
            "robust": bool(self.robust),
        }
        if self.unit is not None:
            out["unit"] = self.unit
        return out

    def to_frame(self) -> Any:
        """The curve as a :class:`pandas.DataFrame`, one row per averaging time.

        Columns: ``tau_s``, ``m``, ``dev``, ``ci_lower``, ``ci_upper`` (in ``unit``),
        ``edf``, ``n_terms``, ``alpha``, ``noise_type`` and ``unit`` (the unit of the
        deviation, ``"unit of the input"`` when unknown).
        """
        import pandas as pd

        d = self.to_dict()
        return pd.DataFrame(
            {
                "tau_s": d["tau"],
                "m": d["m"],
                "dev": d["dev"],
                "ci_lower": d["ci_lower"],
                "ci_upper": d["ci_upper"],
                "edf": d["edf"],
                "n_terms": d["n_terms"],
                "alpha": d["alpha"],
                "noise_type": d["noise_type"],
                "unit": self.unit or "unit of the input",
            }
        )

    def plot(self, ax: Any = None) -> Any:
        """Deviation against τ on log-log axes with the confidence bars.

        Parameters
        ----------
        ax : matplotlib.axes.Axes, optional
            Draw there; by default a new :class:`matplotlib.figure.Figure` is made
            (no pyplot, the backend is left alone).

        Returns
        -------
        matplotlib.figure.Figure
            The figure drawn on.
        """
        from imubounds.report.static_plots import plot_allan

        return plot_allan(self, ax=ax)


# --------------------------------------------------------------------------
# tau grid
# --------------------------------------------------------------------------
def _check_estimator(estimator: str) -> str:
    if estimator not in ESTIMATORS:
        raise OptionError(
            f"unknown Allan estimator {estimator!r}: use one of {', '.join(ESTIMATORS)}"
        )
    return estimator


def max_cluster_size(n_samples: int, estimator: str = "overlapping") -> int:
    """Largest cluster size ``m`` the estimator supports for ``n_samples`` samples.

    overlapping ``(N-1)//2`` (>= 2 terms), non-overlapping ``N//2`` (K >= 2
    clusters), modified ``N//3`` (>= 2 terms), hadamard ``(N-1)//3`` (>= 2 terms),
    non-overlapping-hadamard ``N//3`` (K >= 3 clusters), total ``N//2`` (tau up
    to half the record, NIST SP 1065).
    """
    _check_estimator(estimator)
    n = int(n_samples)
    return {
        "overlapping": (n - 1) // 2,
        "non-overlapping": n // 2,
        "modified": n // 3,
        "hadamard": (n - 1) // 3,
        "non-overlapping-hadamard": n // 3,
        "total": n // 2,
    }[estimator]


#: ``"all"`` is refused when it would sum more than this many squared terms
#: (every m from 1 to the maximum costs about N per m); use ``points:K`` instead.
ALL_TAU_MAX_WORK: float = 2e10
def tau_grid(
    n_samples: int,
    rate_hz: float,
    spec: str | int | Sequence[float] | np.ndarray = "octave",
    estimator: str = "overlapping",
) -> tuple[np.ndarray, np.ndarray]:
    """Cluster sizes and averaging times for a tau specification.

    Parameters
    ----------
    n_samples : int
        Signal length N.
    rate_hz : float
        Sample rate in Hz.
    spec : str or int or sequence of float
        ``"octave"``: m = 1, 2, 4, ...; ``"decade"``: m = 1, 2, 5, 10, 20, 50,
        ...; ``"all"``: every m (refused when that would cost more than
        :data:`ALL_TAU_MAX_WORK` terms); an int K: K log-spaced m from 1 to the
        maximum (duplicates after rounding removed, so possibly fewer); a
        sequence: averaging times in s, each rounded to the nearest whole
        number of samples. Any other string is read by :func:`parse_tau_spec`
        (``"points:60"``, ``"1,10,100s"``).
    estimator : str
        Sets the largest usable m (:func:`max_cluster_size`).

    Returns
    -------
    m : ndarray of int64
        Sorted unique cluster sizes.
    tau : ndarray of float
        ``m / rate_hz`` in s.
    """
    _check_estimator(estimator)
    rate = _check_rate(rate_hz)
    m_max = max_cluster_size(n_samples, estimator)
    if m_max < 1:
        raise AnalysisError(
            f"signal of {n_samples} samples is too short for the {estimator} Allan estimator"
            f" (needs at least {_min_samples(estimator)} samples)"
        )
    if isinstance(spec, str) and spec not in ("octave", "decade", "all"):
        spec = parse_tau_spec(spec)
    if isinstance(spec, str):
        if spec == "octave":
            m = 2 ** np.arange(int(math.floor(math.log2(m_max))) + 1, dtype=np.int64)
        elif spec == "decade":
            vals = [
                b * 10**e for e in range(int(math.floor(math.log10(m_max))) + 1) for b in (1, 2, 5)
            ]
            m = np.array([v for v in vals if v <= m_max], dtype=np.int64)
        else:  # "all"
            work = float(m_max) * float(n_samples)
            if work > ALL_TAU_MAX_WORK:
                raise OptionError(
                    f"tau grid 'all' on {n_samples} samples means {m_max} points (about"
                    f" {work:.2g} squared terms); use points:K (e.g. points:200) instead"
                )
            m = np.arange(1, m_max + 1, dtype=np.int64)
    elif isinstance(spec, (int, np.integer)) and not isinstance(spec, bool):
        if spec < 1:
            raise OptionError(f"tau grid: number of points must be >= 1, got {spec}")
        m = np.unique(np.rint(np.logspace(0.0, math.log10(m_max), int(spec))).astype(np.int64))
    else:
        try:
            taus = np.asarray(spec, dtype=np.float64).ravel()
        except (TypeError, ValueError) as exc:
            raise OptionError(f"tau grid: cannot read {spec!r} as a list of tau in s") from exc
        if taus.size == 0 or not np.all(np.isfinite(taus)):
            raise OptionError("tau grid: give at least one finite tau in s")
        m_f = np.rint(taus * rate)
        bad = np.flatnonzero(m_f < 1)
        if bad.size:
            raise OptionError(
                f"tau = {taus[bad[0]]:g} s is shorter than one sample ({1.0 / rate:g} s at"
                f" {rate:g} Hz)"
            )
        big = np.flatnonzero(m_f > m_max)
        if big.size:
            raise AnalysisError(
                f"tau = {taus[big[0]]:g} s is too long for {n_samples} samples at {rate:g} Hz:"
                f" the largest tau of the {estimator} estimator is {m_max / rate:g} s"
            )
        m = np.unique(m_f.astype(np.int64))
    m = m[(m >= 1) & (m <= m_max)]
    return m, m / rate


def _min_samples(estimator: str) -> int:
    n = 1
    while max_cluster_size(n, estimator) < 1:
        n += 1
    return n


def _check_rate(rate_hz: float) -> float:
    try:
        rate = float(rate_hz)
    except (TypeError, ValueError) as exc:
        raise OptionError(f"sample rate must be a number in Hz, got {rate_hz!r}") from exc
    if not math.isfinite(rate) or rate <= 0:
        raise OptionError(f"sample rate must be a positive number of Hz, got {rate_hz!r}")
    return rate


# equivalent degrees of freedom: imubounds.stationary.edf (re-exported here)

def estimator_edf(estimator: str, alpha: int, m: int, n_samples: int) -> float:
    """EDF of one point of ``estimator`` (cluster size ``m``, ``n_samples`` rate samples)
    for power-law noise ``alpha``: Greenhall's algorithm, or NIST SP 1065 Table 7 for
    the total deviation (:func:`edf_greenhall`, :func:`edf_totdev`)."""
    _check_estimator(estimator)
    n_phase = n_samples + 1
    if estimator == "overlapping":
        return edf_greenhall(alpha, 2, m, n_phase, True, False)
    if estimator == "non-overlapping":
        return edf_greenhall(alpha, 2, m, n_phase, False, False)
    if estimator == "modified":
        return edf_greenhall(alpha, 2, m, n_phase, True, True)
    if estimator == "hadamard":
        return edf_greenhall(alpha, 3, m, n_phase, True, False)
    if estimator == "non-overlapping-hadamard":
        return edf_greenhall(alpha, 3, m, n_phase, False, False)
    return edf_totdev(n_phase, m, alpha)


def _alpha_limits(estimator: str) -> tuple[int, int]:
    return (-4, 2) if estimator in HADAMARD_ESTIMATORS else (-2, 2)


# --------------------------------------------------------------------------
# noise identification
# --------------------------------------------------------------------------
def _lag1(z: np.ndarray) -> float:
    zc = z - z.mean()
    den = float(np.dot(zc, zc))
    if den == 0.0:
        return 0.0
    return float(np.dot(zc[:-1], zc[1:])) / den


def noise_id_lag1(ybar: np.ndarray, dmax: int = 2) -> int | None:
    """Power-law exponent alpha of cluster means by the lag-1 autocorrelation method.

    Parameters
    ----------
    ybar : ndarray
        Cluster means of the rate signal (any unit), at least 30 of them.
    dmax : int
        Maximum number of differencing steps (2 for Allan, 3 for Hadamard).

    Returns
    -------
    int or None
        alpha in -2*dmax .. 2 (``S_y(f) ~ f^alpha``), or None when fewer than 30
        points are given.
    """
    z = np.asarray(ybar, dtype=np.float64)
    if z.size < 30:
        return None
    t = np.arange(z.size, dtype=np.float64)
    t -= t.mean()
    zc = z - z.mean()
    tt = float(np.dot(t, t))
    z = zc - (float(np.dot(t, zc)) / tt) * t if tt > 0 else zc  # remove linear drift
    d = 0
    while True:
        r1 = _lag1(z)
        rho = r1 / (1.0 + r1) if r1 > -1.0 else -math.inf
        if rho < 0.25 or d >= dmax:
            if not math.isfinite(rho):
                return 2
            return int(-round(2.0 * rho) - 2 * d)
        z = np.diff(z)
        d += 1


def _identify_alphas(x: np.ndarray, ms: np.ndarray, t0: float, estimator: str) -> np.ndarray:
    lo, hi = _alpha_limits(estimator)
    dmax = 3 if estimator in HADAMARD_ESTIMATORS else 2
    out = np.zeros(ms.size, dtype=np.int64)
    prev = 0
    n = x.shape[0] - 1
    for i, m in enumerate(ms):
        k = min(n // int(m), NOISE_ID_MAX_POINTS)
        a = None
        if k >= 30:
            xs = np.asarray(x[: k * int(m) + 1 : int(m)])
            a = noise_id_lag1(np.diff(xs) / (m * t0), dmax=dmax)
        if a is None:
            a = prev
        a = min(max(a, lo), hi)
        out[i] = a
        prev = a
    return out


# --------------------------------------------------------------------------
# main entry points
# --------------------------------------------------------------------------
_NORM_FACTOR = {
    "overlapping": 2.0,
    "non-overlapping": 2.0,
    "modified": 2.0,
    "hadamard": 6.0,
    "non-overlapping-hadamard": 6.0,
    "total": 2.0,
}


#: Largest |sample| the estimators square without overflow (the sums of squares of
#: 1e150 stay below the float64 maximum 1.8e308 for any log length).
SIGNAL_MAX_ABS = 1e150
#: Smallest largest-|sample| whose squares do not underflow to zero (denormals below).
SIGNAL_MIN_ABS = 1e-150


def _check_signal(y: Any, name: str) -> np.ndarray:
    if np.iscomplexobj(y) or (
        isinstance(y, np.ndarray | list | tuple) and np.iscomplexobj(np.asarray(y))
    ):
        raise InputError(
            f"{name}: samples are complex numbers; pass the real signal (e.g. x.real) "
            "explicitly"
        )
    try:
        arr = np.asarray(y, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{name}: samples are not numbers ({exc})") from exc
    if arr.ndim != 1:
        raise InputError(f"{name}: expected a 1-D array of samples, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        bad = int(np.flatnonzero(~np.isfinite(arr))[0])
        raise InputError(
            f"{name}: sample {bad} is {arr[bad]} (NaN/inf); remove or interpolate"
            " non-finite samples first"
        )
    check_magnitude(arr, name)
    return arr


def check_magnitude(arr: np.ndarray, name: str) -> None:
    """The numeric edges of a channel, named: every sample equal (no noise to measure),
    samples so large that their squares overflow, or so small that they underflow."""
    if arr.size == 0:
        return
    top = float(np.max(np.abs(arr)))
    if top > SIGNAL_MAX_ABS:
        raise InputError(
            f"{name}: samples reach {top:.3g}, beyond {SIGNAL_MAX_ABS:.0e} where their squares "
            "overflow double precision: the channel is corrupt or scaled wrongly; check its "
            "unit and scale"
        )
    if arr.size > 1 and float(np.ptp(arr)) == 0.0:
        raise InputError(
            f"{name}: every one of the {arr.size} samples is {arr[0]:g}: the channel is constant "
            "(stuck or not recorded), there is no noise to measure; check the channel"
        )
    if top < SIGNAL_MIN_ABS:
        raise InputError(
            f"{name}: every sample is below {SIGNAL_MIN_ABS:.0e} in magnitude (largest "
            f"{top:.3g}), where their squares underflow to zero: the channel is scaled "
            "wrongly; check its unit and scale"
        )


def _parse_noise(noise: str | int, estimator: str) -> int | None:
    if isinstance(noise, str):
        if noise == "auto":
            return None
        if noise in _ALPHA_NAMES:
            alpha = _ALPHA_NAMES[noise]
        else:
            raise OptionError(
                f"unknown noise type {noise!r}: use 'auto', an integer alpha -4..2 or one of"
                f" {', '.join(_ALPHA_NAMES)}"
            )
    elif isinstance(noise, (int, np.integer)) and not isinstance(noise, bool):
        alpha = int(noise)
    else:
        raise OptionError(f"noise must be 'auto', a name or an integer alpha, got {noise!r}")
    lo, hi = _alpha_limits(estimator)
    if not lo <= alpha <= hi:
        raise OptionError(
            f"noise alpha={alpha} is outside {lo}..{hi} for the {estimator} estimator"
        )
    return alpha


def warm_kernels() -> None:
    """Make numba's first call (its CPU target: type registries and lowering, ~0.2 s)
    on one sample, e.g. in a thread while a log is read; the kernels' machine code
    then comes from numba's cache as at any first call."""
    _k.phase_from_rate(np.zeros(1), 1.0)


def allan(
    y: np.ndarray | Sequence[float],
    rate_hz: float,
    taus: str | int | Sequence[float] | np.ndarray = "octave",
    estimator: str = "overlapping",
    confidence: float = 0.683,
    noise: str | int = "auto",
    *,
    name: str = "signal",
    robust: bool = False,
) -> AllanResult:
    """Allan-family deviation of a rate signal with chi-squared confidence intervals.

    Parameters
    ----------
    y : array_like, shape (N,)
        Rate samples (e.g. rad/s or m/s^2), finite.
    rate_hz : float
        Sample rate in Hz.
    taus : see :func:`tau_grid`
        ``"octave"`` (default), ``"decade"``, a number of log-spaced points or
        explicit averaging times in s.
    estimator : str
        ``"overlapping"`` (default), ``"non-overlapping"``, ``"modified"``,
        ``"hadamard"`` or ``"total"``.
    confidence : float
        Two-sided confidence level of the interval, in (0, 1); 0.683 = 1 sigma.
    noise : "auto", int or name
        Noise exponent alpha used for the EDF: ``"auto"`` identifies it per tau
        (lag-1 autocorrelation); an int -4..2 or a name such as ``"white_fm"``
        (= angle/velocity random walk) forces it.
    name : str
        Name used in error messages (a channel or column).
    robust : bool
        Outlier-resistant estimate (median of the absolute terms instead of
        the mean of their squares; see the module notes).

    Returns
    -------
    AllanResult
        Deviations in the unit of ``y``.
    """
    _check_estimator(estimator)
    rate = _check_rate(rate_hz)
    if robust:
        from imubounds.stationary.contamination import despike, detect_spikes

        y = despike(y, detect_spikes(_check_signal(y, name), rate, name=name))
    try:
        conf = float(confidence)
    except (TypeError, ValueError) as exc:
        raise OptionError(f"confidence must be a number in (0, 1), got {confidence!r}") from exc
    if not 0.0 < conf < 1.0:
        raise OptionError(f"confidence must be in (0, 1), got {confidence!r}")
    fixed_alpha = _parse_noise(noise, estimator)
    arr = _check_signal(y, name)
    n = arr.shape[0]
    ms, tau = tau_grid(n, rate, taus, estimator)
    t0 = 1.0 / rate
    x = _k.phase_from_rate(arr, t0)
    sums = _k.sumsq_tasks(x, estimator, ms)
    if fixed_alpha is None:
        alphas = _identify_alphas(x, ms, t0, estimator)
    else:
        alphas = np.full(ms.size, fixed_alpha, dtype=np.int64)
    res = result_from_sums(sums, ms, tau, alphas, estimator, n, rate, conf)
    if not robust:
        return res
    return _robust_result(res, x, sums)


def _robust_result(res: AllanResult, x: np.ndarray, sums: np.ndarray) -> AllanResult:
    """Replace the mean of squared terms by their clipped mean where there are enough terms."""
    dev = res.dev.copy()
    edf = res.edf.copy()
    for i, m in enumerate(res.m):
        nt = int(res.n_terms[i])
        if nt < ROBUST_MIN_TERMS or sums[i] <= 0:
            continue
        d = _k.terms_ref(x, res.estimator, int(m))
        cap = (ROBUST_CLIP * MAD_SCALE * float(np.median(np.abs(d)))) ** 2
        if cap <= 0:
            continue
        robust_ms = float(np.mean(np.minimum(d * d, cap))) / ROBUST_CONSISTENCY
        dev[i] = res.dev[i] * math.sqrt(robust_ms / (sums[i] / nt))
        edf[i] = res.edf[i] * ROBUST_EFFICIENCY
    lo, hi = confidence_interval(dev, edf, res.confidence)
    return AllanResult(
        tau=res.tau,
        m=res.m,
        dev=dev,
        ci_lower=lo,
        ci_upper=hi,
        edf=edf,
        n_terms=res.n_terms,
        alpha=res.alpha,
        estimator=res.estimator,
        n_samples=res.n_samples,
        rate_hz=res.rate_hz,
        confidence=res.confidence,
        robust=True,
    )


def result_from_sums(
    sums: np.ndarray,
    ms: np.ndarray,
    tau: np.ndarray,
    alphas: np.ndarray,
    estimator: str,
    n: int,
    rate: float,
    conf: float,
) -> AllanResult:
    """Finish a curve from its per-τ sums of squares: normalise, EDF, CI.

    Shared by the in-memory path (:func:`allan`) and the out-of-core path
    (:mod:`imubounds.stationary.stream`), so both give the same numbers by construction.
    """
    nt = np.array([_k.n_terms(estimator, n, int(m)) for m in ms], dtype=np.int64)
    var = sums / (_NORM_FACTOR[estimator] * tau**2 * nt)
    if estimator == "modified":
        var = var / ms.astype(np.float64) ** 2
    dev = np.sqrt(var)
    edf = np.array(
        [estimator_edf(estimator, int(a), int(m), n) for a, m in zip(alphas, ms, strict=True)],
        dtype=np.float64,
    )
    lo, hi = confidence_interval(dev, edf, conf)
    return AllanResult(
        tau=tau,
        m=ms,
        dev=dev,
        ci_lower=lo,
        ci_upper=hi,
        edf=edf,
        n_terms=nt,
        alpha=alphas,
        estimator=estimator,
        n_samples=n,
        rate_hz=rate,
        confidence=conf,
    )


def confidence_interval(
    dev: np.ndarray, edf: np.ndarray, confidence: float = 0.683
) -> tuple[np.ndarray, np.ndarray]:
    """Chi-squared interval of a deviation (NIST SP 1065 eq. 45).

    Returns ``(dev*sqrt(edf/chi2.ppf(1-p/2, edf)), dev*sqrt(edf/chi2.ppf(p/2, edf)))``
    with ``p = 1 - confidence``; same unit as ``dev``.
    """
    dev = np.asarray(dev, dtype=np.float64)
    edf = np.asarray(edf, dtype=np.float64)
    p = 1.0 - confidence
    lo = dev * np.sqrt(edf / chi2_ppf(1.0 - p / 2.0, edf))
    hi = dev * np.sqrt(edf / chi2_ppf(p / 2.0, edf))
    return lo, hi


def allan_channels(
    channels: Mapping[str, np.ndarray],
    rate_hz: float,
    taus: str | int | Sequence[float] | np.ndarray = "octave",
    estimator: str = "overlapping",
    confidence: float = 0.683,
    noise: str | int = "auto",
    progress: Callable[[int, int], None] | None = None,
    robust: bool = False,
) -> dict[str, AllanResult]:
    """:func:`allan` for every channel of a log.

    Parameters
    ----------
    channels : mapping of name -> 1-D array
        E.g. ``ImuLog.channels`` (SI units).
    progress : callable(done, total), optional
        Called after each channel (``done`` = channels finished so far).

    Other parameters are those of :func:`allan`.

    Returns
    -------
    dict of name -> AllanResult, in the order of ``channels``.
    """
    out: dict[str, AllanResult] = {}
    total = len(channels)
    if progress is not None:
        progress(0, total)
    for i, (key, values) in enumerate(channels.items()):
        out[key] = allan(
            values, rate_hz, taus, estimator, confidence, noise, name=key, robust=robust
        )
        if progress is not None:
            progress(i + 1, total)
    return out
