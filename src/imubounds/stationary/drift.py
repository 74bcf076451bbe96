"""Deterministic bias changes against the noise: warm-up and drift (docs/static-method.md, 1.2).

A bias that settles after power-on (a warm-up ``c + A·exp(−t/T)``) or drifts over the
log (a ramp, a thermal settling slower than the log) is a deterministic change of the
mean. Whether the block means of a log show one cannot be judged against white noise:
the flicker and random-walk wander of the bias make distant blocks differ, and an
exponential or a line fitted by ordinary least squares to that wander looks
significant (and its T lands anywhere). Here the change is tested against the noise
the log itself has:

* **Block means.** The samples are averaged over :func:`block_edges` (narrow blocks at
  the start, where a warm-up lives, widening geometrically to
  :data:`UNIFORM_BLOCKS` equal blocks over the rest), a few hundred in all.
* **The noise model** (:func:`noise_model`): a weighted non-negative least-squares
  fit of Q, N, B, K and R to the Allan curve of the *second half* of the log (a
  warm-up is over by then; a ramp goes into R). The stationary noise is Q, N, B, K;
  R is left out of it (a ramp is what is tested for).
* **Its covariance of block means** (:meth:`NoiseModel.covariance`), exact for
  blocks of any widths: ``Cov(b_i, b_j) = [G(a_i+w_i−a_j) − G(a_i−a_j) −
  G(a_i+w_i−a_j−w_j) + G(a_i−a_j−w_j)]/(w_i·w_j)`` with ``G'' `` the (generalized)
  covariance of the rate: white ``N²·δ(h)`` (G = N²|h|/2), flicker ``−(B²/π)·ln|h|``
  (G = −(B²/π)(h² ln|h|/2 − 3h²/4); its structure function of equal blocks is
  (B²/π)[(k+1)² ln(k+1) + (k−1)² ln(k−1) − 2k² ln k], 2·(2 ln2/π)B² at k = 1), rate
  random walk ``−K²|h|/2`` (G = −K²|h|³/12), and the white angle noise Q on the block
  edges. Flicker and random walk have no variance, only stationary increments, so the
  fits use the differences of consecutive block means, whose covariance is proper.
* **Generalized least squares** on those differences (:class:`Gls`): for each T of a
  log grid the fit of ``c + A·exp(−t/T)`` (the constant drops out of the
  differences), T refined where the residual is least; z = Â/SE(Â), the standard
  error scaled up by the residual's reduced χ² when above 1 (a noise model too low
  makes nothing significant). The interval of T is where the residual is within 1
  of its minimum (68 %). A drift is the slope of ``c + s·t`` (with the warm-up's
  exponential when one is flagged), its z the same way.

Units: time in s from the first sample, the signal's unit for means and amplitudes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from imubounds.stationary import theory

#: Equal blocks over the part of the log after the narrow blocks of the start.
UNIFORM_BLOCKS = 200
#: The first block is this fraction of the log (at least one sample).
FIRST_BLOCK_FRACTION = 1.0 / 5000.0
#: Growth of the block width from the first block to the uniform width.
BLOCK_GROWTH = 1.06
#: Fewer blocks than this: no test (a log too short to show a change of its mean).
MIN_BLOCKS = 20
#: Time constants tried for an exponential (log grid), from 3 first blocks to half the log.
T_GRID = 96

TERMS = ("Q", "N", "B", "K", "R")
NULL_TERMS = ("Q", "N", "B", "K")


def block_edges(n: int, rate_hz: float) -> NDArray[np.int64]:
    """Sample indices of the block edges (first 0, last n): widths growing from
    ``n·FIRST_BLOCK_FRACTION`` by :data:`BLOCK_GROWTH` to ``n/UNIFORM_BLOCKS``."""
    wide = max(1.0, n / UNIFORM_BLOCKS)
    w = max(1.0, n * FIRST_BLOCK_FRACTION)
    edges = [0]
    pos = 0.0
    while pos < n:
        pos = min(float(n), pos + w)
        e = int(round(pos))
        if e > edges[-1]:
            edges.append(e)
        w = min(wide, w * BLOCK_GROWTH)
    if edges[-1] != n:
        edges.append(n)
    out = np.asarray(edges, dtype=np.int64)
    if out.size >= 3 and out[-1] - out[-2] < 0.5 * wide:  # no sliver at the end
        out = np.delete(out, -2)
    return out


@dataclass(frozen=True)
class Blocks:
    """Block means of a channel: start and width (s), mean (the signal's unit, the
    log's mean removed: ``offset`` added back gives the signal)."""

    start_s: NDArray[np.float64]
    width_s: NDArray[np.float64]
    mean: NDArray[np.float64]
    offset: float

    @property
    def mid_s(self) -> NDArray[np.float64]:
        return np.asarray(self.start_s + self.width_s / 2.0)

    @property
    def duration_s(self) -> float:
        return float(self.start_s[-1] + self.width_s[-1])

    def average(self, fn: str, tc: float = 0.0) -> NDArray[np.float64]:
        """The block averages of ``t`` (``fn="t"``) or ``exp(−t/tc)`` (``"exp"``)."""
        a, w = self.start_s, self.width_s
        if fn == "t":
            return np.asarray(a + w / 2.0)
        return np.asarray(tc * np.exp(-a / tc) * -np.expm1(-w / tc) / w)


def centred_cumsum(y: NDArray[np.float64]) -> NDArray[np.float64]:
    """``[0, cumsum(y − mean(y))]`` (length n + 1), shared by the block means and the
    detrended curve."""
    return np.concatenate(([0.0], np.cumsum(y - float(np.mean(y)))))


def block_means(
    y: NDArray[np.float64], rate_hz: float, csum: NDArray[np.float64] | None = None
) -> Blocks:
    """The block means of ``y`` over :func:`block_edges` (``csum``: its
    :func:`centred_cumsum` when already computed)."""
    n = y.size
    edges = block_edges(n, rate_hz)
    c = centred_cumsum(y) if csum is None else csum
    cnt = np.diff(edges).astype(np.float64)
    mean = (c[edges[1:]] - c[edges[:-1]]) / cnt
    return Blocks(edges[:-1] / rate_hz, cnt / rate_hz, np.asarray(mean), float(np.mean(y)))


def _g_white(x: NDArray[np.float64]) -> NDArray[np.float64]:
    return np.asarray(np.abs(x) / 2.0)


def _g_flicker(x: NDArray[np.float64]) -> NDArray[np.float64]:
    ax = np.abs(x)
    sq = ax * ax
    with np.errstate(divide="ignore", invalid="ignore"):
        lg = np.log(np.where(ax > 0, ax, 1.0))
    return np.asarray(-(sq * lg / 2.0 - 0.75 * sq) / math.pi)


def _g_rw(x: NDArray[np.float64]) -> NDArray[np.float64]:
    ax = np.abs(x)
    return np.asarray(-(ax * ax * ax) / 12.0)


def _pair_integral(g: Any, edges: NDArray[np.float64]) -> NDArray[np.float64]:
    """(1/(w_i w_j)) ∫∫ C(u − v) over blocks i, j (edges e_i, e_{i+1}), for C = G'':
    [G(e_{i+1} − e_j) − G(e_i − e_j) − G(e_{i+1} − e_{j+1}) + G(e_i − e_{j+1})]/(w_i w_j),
    G evaluated once on the differences of the edges."""
    m = g(edges[:, None] - edges[None, :])
    s = m[1:, :-1] - m[:-1, :-1] - m[1:, 1:] + m[:-1, 1:]
    w = np.diff(edges)
    return np.asarray(s / (w[:, None] * w[None, :]))


def unit_covariances(blocks: Blocks) -> dict[str, NDArray[np.float64]]:
    """The covariance of the differences of consecutive block means for each stationary
    term at unit value (Q, N, B, K = 1 in SI): any model's is their sum weighted by the
    squared terms. Time in units of the log's length for the arithmetic (a constant of
    the flicker's ln|h| then drops out of the differences)."""
    scale = max(blocks.duration_s, 1e-300)
    edges = np.concatenate((blocks.start_s, [blocks.duration_s])) / scale
    ws = blocks.width_s
    q = np.diag(2.0 / ws**2) - np.diag(1.0 / (ws[:-1] * ws[1:]), 1)
    q = q + np.triu(q, 1).T  # white angle noise on the edges: (θ(end) − θ(start))/w
    raw = {
        "Q": q,
        "N": _pair_integral(_g_white, edges) / scale,
        "B": _pair_integral(_g_flicker, edges),
        "K": _pair_integral(_g_rw, edges) * scale,
    }
    out = {}
    for t, c in raw.items():
        d = np.diff(np.diff(c, axis=0), axis=1)  # Cov(b_{i+1} − b_i, b_{j+1} − b_j)
        out[t] = np.asarray((d + d.T) / 2.0)
    return out


@dataclass(frozen=True)
class NoiseModel:
    """The stationary noise of a channel (Q, N, B, K in SI, IEEE 952) fitted to the Allan
    curve of ``part`` (the τ range ``tau_s``), and the ramp R fitted beside it (not part
    of the noise)."""

    terms: dict[str, float]
    tau_s: tuple[float, float]
    part: str

    def covariance(self, blocks: Blocks) -> NDArray[np.float64]:
        """The (generalized) covariance of the block means under the stationary noise
        (flicker and random walk have none, only stationary increments: defined up to a
        constant, which no contrast sees)."""
        scale = max(blocks.duration_s, 1e-300)
        edges = np.concatenate((blocks.start_s, [blocks.duration_s])) / scale
        q, n_, b, k = (self.terms.get(t, 0.0) for t in NULL_TERMS)
        cov = n_**2 / scale * _pair_integral(_g_white, edges)
        if b > 0:
            cov = cov + b**2 * _pair_integral(_g_flicker, edges)
        if k > 0:
            cov = cov + k**2 * scale * _pair_integral(_g_rw, edges)
        if q > 0:  # white angle noise on the block edges: (θ(end) − θ(start))/w
            ws = blocks.width_s
            off = -(q**2) / (ws[:-1] * ws[1:])
            cov = cov + np.diag(2.0 * q**2 / ws**2) + np.diag(off, 1) + np.diag(off, -1)
        return np.asarray(cov)

    def difference_covariance(
        self, units: dict[str, NDArray[np.float64]]
    ) -> NDArray[np.float64]:
        """The covariance of the differences of consecutive block means, from
        :func:`unit_covariances` of the blocks."""
        return np.asarray(sum(self.terms.get(t, 0.0) ** 2 * units[t] for t in NULL_TERMS))


def noise_model(curve: Any, var: NDArray[np.float64] | None = None,
                part: str = "whole log") -> NoiseModel:  # fmt: skip
    """Weighted NNLS of the terms on an Allan-family curve (an
    :class:`~imubounds.stationary.allan.AllanResult`), each point weighted by
    √(EDF/2)/σ² (the inverse spread of a χ² estimate of σ²), with the estimator's own
    responses (:func:`imubounds.stationary.theory.basis`).

    Without ``var``: Q, N, B, K and R, R then left out of the stationary noise (a ramp
    must not inflate K). With ``var``, the variances of the curve with a ramp taken out
    of the samples (:func:`detrended_variance`): Q, N, B, K alone — on the long-τ
    points K and R are nearly collinear, and the slope in time pins the ramp far better
    than the curve's few last points do."""
    from scipy.optimize import nnls

    dev = np.asarray(curve.dev, dtype=np.float64)
    edf = np.asarray(curve.edf, dtype=np.float64)
    ok = np.isfinite(dev) & (dev > 0) & np.isfinite(edf) & (edf >= 2.0)
    tau, v0 = np.asarray(curve.tau, dtype=np.float64)[ok], dev[ok] ** 2
    if tau.size < 2:
        return NoiseModel({t: 0.0 for t in TERMS}, (math.nan, math.nan), part)
    f = theory.basis(tau, curve.estimator, rate_hz=curve.rate_hz,
                     n_samples=curve.n_samples, terms=TERMS)  # fmt: skip
    target = v0 if var is None else np.asarray(var, dtype=np.float64)[ok]
    # the spread of each point is that of the curve's own estimate (σ²·√(2/EDF)), not
    # of the detrended value: weighted by the detrended value, a long-τ point the
    # ramp's removal brings near 0 would pin the fit there (B and K to 0 under a
    # Gauss–Markov bump, then a false drift at z = 13)
    wgt = np.sqrt(edf[ok] / 2.0) / v0
    cols = list(range(len(TERMS))) if var is None else [TERMS.index(t) for t in NULL_TERMS]
    design = f[:, cols] * wgt[:, None]
    norm = np.linalg.norm(design, axis=0)
    norm[~(norm > 0)] = 1.0  # a term the estimator is blind to (R on a Hadamard curve)
    x, _ = nnls(design / norm, target * wgt, maxiter=50 * len(cols))
    x = x / norm
    terms = {t: 0.0 for t in TERMS}
    terms.update({TERMS[j]: float(math.sqrt(max(v, 0.0))) for j, v in zip(cols, x, strict=True)})
    return NoiseModel(terms, (float(tau[0]), float(tau[-1])), part)


def detrended_variance(
    y: NDArray[np.float64], curve: Any, slope: float, csum: NDArray[np.float64] | None = None
) -> NDArray[np.float64]:
    """The overlapping Allan variances of ``curve`` (of ``y``) for ``y − slope·t``,
    exactly: each second difference of the phase loses ``slope·τ²``, so
    σ²' = σ² − (slope/M)·Σ_k Δ²θ_k + slope²·τ²/2 with M = N − 2m + 1 terms; the sums
    Σ_k θ_{k+j} from one cumulative sum of the phase (``csum``: :func:`centred_cumsum`
    of ``y`` when already computed)."""
    var = np.asarray(curve.dev, dtype=np.float64) ** 2
    if slope == 0.0:
        return var
    t0 = 1.0 / float(curve.rate_hz)
    theta = (centred_cumsum(y) if csum is None else csum) * t0
    big = np.concatenate(([0.0], np.cumsum(theta)))  # big[j] = Σ_{i<j} θ_i
    m = np.asarray(curve.m, dtype=np.int64)
    n = int(y.size)
    terms = n - 2 * m + 1
    ok = terms >= 1
    mm, tt = np.where(ok, m, 0), np.where(ok, terms, 1)

    def window(j0: NDArray[np.int64]) -> NDArray[np.float64]:
        return np.asarray(big[j0 + tt] - big[j0])

    total = window(2 * mm) - 2.0 * window(mm) + window(np.zeros_like(mm))
    tau = np.asarray(curve.tau, dtype=np.float64)
    out = var - slope * total / tt + slope**2 * tau**2 / 2.0
    return np.asarray(np.where(ok, out, np.nan))


class Gls:
    """Generalized least squares of block means on regressors, under a noise model:
    on the differences of consecutive means (the constant drops out; the covariance
    of differences is proper for flicker and random walk)."""

    def __init__(
        self,
        blocks: Blocks,
        model: NoiseModel,
        units: dict[str, NDArray[np.float64]] | None = None,
    ) -> None:
        units = units if units is not None else unit_covariances(blocks)
        sd = model.difference_covariance(units)
        top = float(np.max(np.abs(np.diag(sd)))) if sd.size else 0.0
        if not top > 0:
            raise ValueError("the noise model has no variance")
        self.chol = np.linalg.cholesky(sd + 1e-12 * top * np.eye(sd.shape[0]))
        self.blocks = blocks
        self.y = self.whiten(blocks.mean)

    def whiten(self, v: NDArray[np.float64]) -> NDArray[np.float64]:
        """L⁻¹·diff(v) (v: block averages, one column or several)."""
        from scipy.linalg import solve_triangular

        out = solve_triangular(self.chol, np.diff(v, axis=0), lower=True, check_finite=False)
        return np.asarray(out, dtype=np.float64)

    @property
    def dof(self) -> int:
        return int(self.y.size)

    def fit(self, cols: NDArray[np.float64]) -> Fit:
        """The fit of whitened regressors ``cols`` (columns; the constant implied)."""
        x = np.asarray(cols, dtype=np.float64).reshape(self.y.size, -1)
        coef, *_ = np.linalg.lstsq(x, self.y, rcond=None)
        r = self.y - x @ coef
        cost = float(r @ r)
        cov = np.linalg.pinv(x.T @ x)
        scale = max(1.0, cost / max(self.dof - x.shape[1], 1))
        f64 = np.float64
        return Fit(np.asarray(coef, dtype=f64), np.asarray(cov, dtype=f64), cost, scale)


@dataclass(frozen=True)
class Fit:
    """Coefficients, their covariance (unit noise), the residual sum of squares and the
    variance scale ``max(1, reduced χ²)`` applied to the standard errors."""

    coef: NDArray[np.float64]
    cov: NDArray[np.float64]
    cost: float
    scale: float

    def z(self, k: int) -> float:
        v = float(self.cov[k, k]) * self.scale
        return float(self.coef[k]) / math.sqrt(v) if v > 0 else math.inf


@dataclass(frozen=True)
class Transient:
    """The exponential ``A·exp(−t/T)`` that lowers the residual of the block means most
    (T on a log grid from three first blocks to half the log, refined): T (s) with its
    68 % interval (where the residual is within the variance scale of its minimum, open
    at the grid's ends), A (signal unit) and z = Â/SE(Â)."""

    time_constant_s: float
    time_constant_ci_s: tuple[float, float]
    amplitude: float
    z: float


def _crossing(lg: NDArray[np.float64], c: NDArray[np.float64], k: int, level: float,
              step: int) -> float:  # fmt: skip
    """ln T where the profile ``c`` first rises above ``level`` from index ``k`` going
    ``step`` (±1), interpolated; the grid's end if it never does."""
    j = k
    while 0 <= j + step < c.size and c[j + step] <= level:
        j += step
    if not 0 <= j + step < c.size:
        return float(lg[j])
    a, b = c[j], c[j + step]
    frac = (level - a) / (b - a) if b != a else 0.0
    return float(lg[j] + frac * (lg[j + step] - lg[j]))


def fit_transient(gls: Gls) -> Transient | None:
    """The best exponential of the block means (see :class:`Transient`); None when the
    log is too short for the grid."""
    from scipy.optimize import minimize_scalar

    bl = gls.blocks
    lo_t, hi_t = 3.0 * float(bl.width_s[0]), bl.duration_s / 2.0
    if not hi_t > lo_t:
        return None
    lg = np.linspace(math.log(lo_t), math.log(hi_t), T_GRID)
    x = gls.whiten(np.column_stack([bl.average("exp", math.exp(v)) for v in lg]))
    xx, xy = np.einsum("ij,ij->j", x, x), x.T @ gls.y
    cost = float(gls.y @ gls.y) - xy**2 / xx
    k = int(np.argmin(cost))

    def one(v: float) -> float:
        e = gls.whiten(bl.average("exp", math.exp(v))[:, None])[:, 0]
        return float(gls.y @ gls.y) - float(e @ gls.y) ** 2 / float(e @ e)

    lt = float(lg[k])
    if 0 < k < lg.size - 1:
        lt = float(minimize_scalar(one, bounds=(lg[k - 1], lg[k + 1]), method="bounded",
                                   options={"xatol": 1e-3}).x)  # fmt: skip
    best = gls.fit(gls.whiten(bl.average("exp", math.exp(lt))[:, None]))
    level = best.cost + best.scale
    ci = (
        math.exp(min(_crossing(lg, cost, k, level, -1), lt)),
        math.exp(max(_crossing(lg, cost, k, level, +1), lt)),
    )
    return Transient(math.exp(lt), ci, float(best.coef[0]), best.z(0))


def fit_slope(gls: Gls, time_constant_s: float | None = None) -> tuple[float, float, float]:
    """(slope per s, its standard error, z) of ``c + s·t`` (with ``A·exp(−t/T)``
    beside it when a warm-up's T is given)."""
    bl = gls.blocks
    cols = [bl.average("t")]
    if time_constant_s is not None:
        cols.append(bl.average("exp", time_constant_s))
    fit = gls.fit(gls.whiten(np.column_stack(cols)))
    se = math.sqrt(max(float(fit.cov[0, 0]) * fit.scale, 0.0))
    return float(fit.coef[0]), se, fit.z(0)
