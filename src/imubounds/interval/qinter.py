"""Relaxed (q-relaxed) intersection of m boxes tolerating q outliers (Jaulin).

The q-relaxed intersection of sets X_1..X_m is the set of points that belong
to at least ``m - q`` of them. For boxes it is a union of boxes; this module
returns its hull:

* ``method="per_dim"`` (default, vectorised, O(m log m) per dimension): for
  each dimension separately, the hull of the points covered by at least
  ``m - q`` of the m intervals (exact in 1-D: sort the endpoints and sweep
  the coverage count). In several dimensions the product of these per-dimension
  results is a guaranteed OVER-approximation of the true q-relaxed
  intersection: a point in ``m - q`` boxes has every coordinate in
  ``m - q`` intervals, but the per-dimension inliers may be different boxes.
* ``method="exact"``: the hull of the exact set, as the hull of the
  intersections of all ``C(m, m - q)`` choices of ``m - q`` boxes. Exact but
  combinatorial; refused beyond ``max_subsets`` choices.

:func:`qinter_1d` is the compiled scalar form for one dimension (used inside the
estimators' numba loops). Empty input boxes count as outliers (they contain no point). With
``q >= m`` every point qualifies and the result is the whole space.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
from numba import njit

from imubounds.errors import OptionError
from imubounds.interval.array import IntervalArray


@njit(cache=True)
def qinter_1d(lo: np.ndarray, hi: np.ndarray, m: int, q: int) -> tuple[float, float]:
    """Hull of the points lying in at least ``m - q`` of the closed intervals ``[lo_i, hi_i]``.

    Exact in one dimension (coverage only changes at endpoints); empty intervals
    count as outliers; empty result if no point is covered often enough.
    """
    need = m - q
    if need <= 0:
        return -np.inf, np.inf
    best_lo = np.inf
    best_hi = -np.inf
    for i in range(m):
        if not (lo[i] <= hi[i]):
            continue
        c_lo = 0
        c_hi = 0
        for j in range(m):
            if lo[j] <= hi[j]:
                if lo[j] <= lo[i] <= hi[j]:
                    c_lo += 1
                if lo[j] <= hi[i] <= hi[j]:
                    c_hi += 1
        if c_lo >= need and lo[i] < best_lo:
            best_lo = lo[i]
        if c_hi >= need and hi[i] > best_hi:
            best_hi = hi[i]
    if best_lo > best_hi:
        return np.inf, -np.inf
    return best_lo, best_hi


def _per_dim_lower(lo: np.ndarray, hi: np.ndarray, need: int) -> np.ndarray:
    # lo, hi: (..., m); lowest point covered by >= need intervals; +inf if none
    valid = lo <= hi
    coords = np.concatenate([np.where(valid, lo, np.inf), np.where(valid, hi, np.inf)], axis=-1)
    delta = np.concatenate(
        [valid.astype(np.int64), -valid.astype(np.int64)], axis=-1
    )
    # sort by coordinate, openings (+1) before closings (-1) at ties (closed intervals)
    order = np.lexsort((-delta, coords), axis=-1)
    cs = np.take_along_axis(coords, order, axis=-1)
    ds = np.take_along_axis(delta, order, axis=-1)
    count = np.cumsum(ds, axis=-1)
    hit = count >= need
    any_hit = hit.any(axis=-1)
    first = np.argmax(hit, axis=-1)
    res = np.take_along_axis(cs, first[..., None], axis=-1)[..., 0]
    return np.where(any_hit, res, np.inf)


def qinter(boxes: IntervalArray, q: int, axis: int = 0, method: str = "per_dim",
           max_subsets: int = 100_000) -> IntervalArray:
    """Hull of the q-relaxed intersection of ``m`` boxes.

    Parameters
    ----------
    boxes : IntervalArray
        Shape ``(m, ...)`` with the m boxes along ``axis``; the remaining axes
        are the dimensions (and any batch axes), e.g. ``(m, n)`` or
        ``(m, T, n)``. For ``method="exact"`` the LAST axis is the box
        dimension and the other remaining axes are independent batches.
    q : int
        Number of outliers tolerated, ``0 <= q``. ``q = 0`` is the ordinary
        intersection.
    method : {"per_dim", "exact"}
        See the module docstring.

    Returns
    -------
    IntervalArray
        Shape of ``boxes`` without ``axis``; empty where fewer than ``m - q``
        boxes overlap (for ``per_dim``: in some dimension -- then the whole box
        is returned empty).
    """
    if not isinstance(boxes, IntervalArray):
        raise OptionError("qinter needs an IntervalArray of boxes")
    if q < 0 or int(q) != q:
        raise OptionError(f"q={q!r} must be a non-negative integer")
    lo = np.moveaxis(boxes.lo, axis, -1 if method == "per_dim" else 0)
    hi = np.moveaxis(boxes.hi, axis, -1 if method == "per_dim" else 0)
    m = lo.shape[-1] if method == "per_dim" else lo.shape[0]
    need = m - int(q)
    if method == "per_dim":
        out_shape = lo.shape[:-1]
        if need <= 0:
            return IntervalArray.entire(out_shape)
        rlo = _per_dim_lower(lo, hi, need)
        rhi = -_per_dim_lower(-hi, -lo, need)
        bad = ~(rlo <= rhi)
        if out_shape and lo.ndim >= 2:
            # a box is empty as soon as one of its dimensions is (last axis = dimension)
            bad = np.broadcast_to(bad.any(axis=-1, keepdims=True), bad.shape)
        rlo = np.where(bad, np.inf, rlo)
        rhi = np.where(bad, -np.inf, rhi)
        return IntervalArray._raw(np.asarray(rlo, float), np.asarray(rhi, float))
    if method != "exact":
        raise OptionError(f"unknown qinter method {method!r}; use 'per_dim' or 'exact'")
    out_shape = lo.shape[1:]
    if need <= 0:
        return IntervalArray.entire(out_shape)
    n_sub = math.comb(m, need)
    if n_sub > max_subsets:
        raise OptionError(
            f"exact q-relaxed intersection needs C({m},{need}) = {n_sub} subsets "
            f"(> max_subsets={max_subsets}); use method='per_dim'"
        )
    acc_lo = np.full(out_shape, np.inf)
    acc_hi = np.full(out_shape, -np.inf)
    for sub in itertools.combinations(range(m), need):
        idx = list(sub)
        slo = lo[idx].max(axis=0)
        shi = hi[idx].min(axis=0)
        nonempty = (slo <= shi).all(axis=-1, keepdims=True) if lo.ndim >= 2 else slo <= shi
        nonempty = np.broadcast_to(nonempty, slo.shape)
        acc_lo = np.where(nonempty, np.minimum(acc_lo, slo), acc_lo)
        acc_hi = np.where(nonempty, np.maximum(acc_hi, shi), acc_hi)
    return IntervalArray._raw(acc_lo, acc_hi)


def qinter_inliers(boxes: IntervalArray, result: IntervalArray, axis: int = 0) -> np.ndarray:
    """Boolean array over the m boxes: True where a box meets ``result`` in every dimension.

    Boxes that do not meet the relaxed intersection are the outliers it
    discarded (e.g. GPS fixes contradicting the others).
    """
    lo = np.moveaxis(boxes.lo, axis, 0)
    hi = np.moveaxis(boxes.hi, axis, 0)
    meet = (np.maximum(lo, result.lo) <= np.minimum(hi, result.hi))
    return meet.reshape(meet.shape[0], -1).all(axis=1)

