"""Compiled kernels of the sample series of mode ``full`` (:mod:`.inputs`), written so
that long trips fit in memory (docs/dynamic-method.md, section 2: a 24 h trip at 100 Hz
is 8.64 M samples).

* Prefix sums by checkpoints: :class:`~imubounds.dynamic.estimator.inputs.PiecewiseSignal`
  keeps its four running sums (``S`` of ``y l``, ``A`` of ``|y l|``, ``Z`` of the
  integral's increments, ``ZA`` of their magnitudes; ``l`` a segment's length) only
  every :data:`CHECKPOINT` segments (``Z``, ``ZA``: :data:`CHECKPOINT_Z`) and finishes
  a sum from the checkpoint before it when asked. The additions are those of
  ``np.cumsum``, in the same order (numpy's accumulate is sequential), so every value
  is bit for bit the one a full array gives.
* Range minimum / maximum by blocks: a sparse table over blocks of :data:`BLOCK`
  values and the two partial blocks at a query's ends scanned: exact (min and max do
  not round), ``O(n)`` memory where the full sparse table took ``O(n log n)``.

Plain references: ``tests/series_reference.py`` (the full arrays and the full sparse
table); the tests compare them bit for bit.
"""

from __future__ import annotations

import numpy as np
from numba import njit

#: segments between two stored checkpoints of the sums S and A (most queries)
CHECKPOINT = 16
#: segments between two stored checkpoints of Z and ZA (a multiple of CHECKPOINT)
CHECKPOINT_Z = 64
#: values per block of the range-extremum table
BLOCK = 64


@njit(cache=True, fastmath=False)
def checkpoints(
    bnd: np.ndarray, y: np.ndarray, every: int, every_z: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``S, A`` at segment indices ``0, every, 2 every, ...`` and ``Z, ZA`` at ``0,
    every_z, ...`` (each array's last value: the sum over all ``n`` segments): the
    running sums of ``x = y l``, ``|x|``, ``inc = S l + 0.5 y l l`` and ``|inc|`` (``l =
    bnd[k+1] - bnd[k]``), in the order of ``np.cumsum``."""
    n = y.size
    cS = np.empty(n // every + 2)
    cA = np.empty(n // every + 2)
    cZ = np.empty(n // every_z + 2)
    cZA = np.empty(n // every_z + 2)
    s = 0.0
    a = 0.0
    z = 0.0
    za = 0.0
    cS[0] = 0.0
    cA[0] = 0.0
    cZ[0] = 0.0
    cZA[0] = 0.0
    for k in range(n):
        ln = bnd[k + 1] - bnd[k]
        x = y[k] * ln
        inc = s * ln + 0.5 * y[k] * ln * ln
        if k == 0:  # np.cumsum starts from the first term, not 0 + it (signed zeros)
            s, a, z, za = x, abs(x), inc, abs(inc)
        else:
            s, a, z, za = s + x, a + abs(x), z + inc, za + abs(inc)
        if (k + 1) % every == 0:
            cS[(k + 1) // every] = s
            cA[(k + 1) // every] = a
        if (k + 1) % every_z == 0:
            cZ[(k + 1) // every_z] = z
            cZA[(k + 1) // every_z] = za
    cS[-1] = s
    cA[-1] = a
    cZ[-1] = z
    cZA[-1] = za
    return cS, cA, cZ, cZA


@njit(cache=True, fastmath=False)
def prefix_at(
    bnd: np.ndarray,
    y: np.ndarray,
    cS: np.ndarray,
    cA: np.ndarray,
    cZ: np.ndarray,
    cZA: np.ndarray,
    every: int,
    every_z: int,
    idx: np.ndarray,
    want_z: bool,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``S[i], A[i]`` (and ``Z[i], ZA[i]`` when ``want_z``) at the indices ``idx``
    (``0 <= i <= n``), finished from the checkpoint before each."""
    q = idx.size
    oS = np.empty(q)
    oA = np.empty(q)
    oZ = np.empty(q if want_z else 0)
    oZA = np.empty(q if want_z else 0)
    n = y.size
    for r in range(q):
        i = idx[r]
        if i == n:
            oS[r] = cS[-1]
            oA[r] = cA[-1]
            if want_z:
                oZ[r] = cZ[-1]
                oZA[r] = cZA[-1]
            continue
        if want_z:
            c = i // every_z
            k0 = c * every_z
            z = cZ[c]
            za = cZA[c]
        else:
            k0 = (i // every) * every
            z = 0.0
            za = 0.0
        s = cS[k0 // every]
        a = cA[k0 // every]
        for k in range(k0, i):
            ln = bnd[k + 1] - bnd[k]
            x = y[k] * ln
            if want_z:
                inc = s * ln + 0.5 * y[k] * ln * ln
                z = inc if k == 0 else z + inc
                za = abs(inc) if k == 0 else za + abs(inc)
            s = x if k == 0 else s + x
            a = abs(x) if k == 0 else a + abs(x)
        oS[r] = s
        oA[r] = a
        if want_z:
            oZ[r] = z
            oZA[r] = za
    return oS, oA, oZ, oZA


@njit(cache=True, fastmath=False)
def _mn(a: float, b: float) -> float:
    # np.minimum: NaN wins
    if b < a or b != b:
        return b
    return a


@njit(cache=True, fastmath=False)
def _mx(a: float, b: float) -> float:
    if b > a or b != b:
        return b
    return a


@njit(cache=True, fastmath=False)
def block_table(v: np.ndarray, block: int, is_min: bool) -> np.ndarray:
    """Sparse table of the blocks' extrema: row ``k`` holds the extremum of blocks
    ``b .. b + 2**k - 1`` at column ``b``."""
    n = v.size
    nb = (n + block - 1) // block
    levels = 1
    while (1 << levels) <= nb:
        levels += 1
    tab = np.empty((levels, max(nb, 1)))
    for b in range(nb):
        e = v[b * block]
        for k in range(b * block + 1, min(n, (b + 1) * block)):
            e = _mn(e, v[k]) if is_min else _mx(e, v[k])
        tab[0, b] = e
    for lv in range(1, levels):
        h = 1 << (lv - 1)
        for b in range(nb - (1 << lv) + 1):
            x = tab[lv - 1, b]
            y = tab[lv - 1, b + h]
            tab[lv, b] = _mn(x, y) if is_min else _mx(x, y)
    return tab


@njit(cache=True, fastmath=False)
def range_query(
    v: np.ndarray, tab: np.ndarray, block: int, i: np.ndarray, j: np.ndarray, is_min: bool
) -> np.ndarray:
    """Extremum of ``v[i..j]`` (inclusive) per query; ``j < i`` gives the extremum of
    ``v[i]`` and ``v[j]`` (as the full sparse table did)."""
    q = i.size
    out = np.empty(q)
    for r in range(q):
        a = i[r]
        b = j[r]
        if b <= a:
            e = v[a]
            e = _mn(e, v[b]) if is_min else _mx(e, v[b])
            out[r] = e
            continue
        ba = a // block
        bb = b // block
        e = v[a]
        if ba == bb:
            for k in range(a + 1, b + 1):
                e = _mn(e, v[k]) if is_min else _mx(e, v[k])
            out[r] = e
            continue
        for k in range(a + 1, (ba + 1) * block):
            e = _mn(e, v[k]) if is_min else _mx(e, v[k])
        for k in range(bb * block, b + 1):
            e = _mn(e, v[k]) if is_min else _mx(e, v[k])
        nmid = bb - ba - 1
        if nmid > 0:
            lv = 0
            while (2 << lv) <= nmid:
                lv += 1
            x = tab[lv, ba + 1]
            y = tab[lv, bb - (1 << lv)]
            e = _mn(e, x) if is_min else _mx(e, x)
            e = _mn(e, y) if is_min else _mx(e, y)
        out[r] = e
    return out


@njit(cache=True)
def gm_quadratic_sum(c: np.ndarray, phis: np.ndarray, s2: np.ndarray) -> float:
    """``sum_i s2_i c' Phi_i c`` with ``Phi_i[j, k] = phis_i^|j-k|``: per component one
    pass of the one-sided filter ``f_k = c_k + phi f_(k-1)``, ``c' Phi c = 2 c.f - c.c``
    (the two-sided filter's sum in one pass; the plain reference, two ``lfilter`` passes,
    is tests/test_kernel_variance.py; used by
    :func:`~imubounds.dynamic.estimator.budget.kernel_variance`)."""
    cc = 0.0
    for k in range(c.size):
        cc += c[k] * c[k]
    v = 0.0
    for i in range(phis.size):
        phi = phis[i]
        f = 0.0
        acc = 0.0
        for k in range(c.size):
            f = c[k] + phi * f
            acc += c[k] * f
        v += s2[i] * (2.0 * acc - cc)
    return v
