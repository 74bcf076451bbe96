"""Numba kernels (and plain-numpy references) for the Allan-variance family.

Everything here works on the *phase* array ``x`` (length ``N + 1``) of a rate
signal ``y`` (length ``N``) sampled every ``t0`` seconds::

    x[0] = 0,   x[k] = t0 * sum_{i<k} (y[i] - mean(y))

The units of ``x`` are those of ``y`` times seconds (rad for a gyro in rad/s,
m/s for an accelerometer in m/s^2). Removing the mean keeps ``|x|`` small; it
changes none of the statistics (they are built from second or third
differences of ``x``, which annihilate a linear phase trend).

Exactness
---------
* :func:`phase_from_rate` is a compensated running sum (Knuth's branch-free
  TwoSum, i.e. Kahan-Babuska/Neumaier summation): every ``x[k]`` is the
  correctly rounded value of the exact partial sum up to a few ulp,
  independent of ``N``. A naive running sum would
  instead accumulate ``O(k * eps * max|x|)`` error; for ``N = 1e9`` samples
  that is the difference between 1e-16 and ~1e-7 relative on ``x``.
* The sum-of-squares kernels accumulate over *chunks* of at most
  :data:`CHUNK` terms with four interleaved accumulators (partial sums of
  <= CHUNK/4 terms each); the per-chunk partial sums are added with
  ``math.fsum`` in :func:`reduce_partials`. The rounding error of the sum is
  thus bounded by about ``(CHUNK/4) * eps`` relative instead of ``N * eps``.
* Kernels are compiled without fast-math, except that the three
  sum-of-squares loops allow *reassociation* only (``_REDUCE_FLAGS``) so that
  LLVM vectorises the reduction; results do not depend on the number of
  threads, because every chunk is a fixed task whose partial sum is stored
  separately and reduced in a fixed order.

Out-of-core use
---------------
Every ``*_sumsq`` kernel takes the phase array (a ``numpy.memmap`` works) and a
half-open range ``[k0, k1)`` of *term indices* and returns the partial sum of
squares over that range. A chunked driver can call them on successive ranges
(reading the needed ``x`` window, which extends ``2m``, ``3m`` or ``m`` samples
beyond the range) and add the partial sums; the term counts and normalisations
are given by :func:`n_terms` and the ``allan`` module.

Term index conventions (``Np = N + 1`` phase points):

========================  ===========================================  =================
estimator                 term ``k``                                    valid ``k``
========================  ===========================================  =================
overlapping ADEV          ``x[k+2m] - 2x[k+m] + x[k]``                  ``0 .. N-2m``
non-overlapping ADEV      same, with ``k = j*m``; the *range* is in j   ``j = 0 .. N//m-2``
overlapping HDEV          ``x[k+3m] - 3x[k+2m] + 3x[k+m] - x[k]``       ``0 .. N-3m``
non-overlapping HDEV      same, with ``k = j*m``; the *range* is in j   ``j = 0 .. N//m-3``
modified ADEV             ``sum_{i=k}^{k+m-1} (x[i+2m]-2x[i+m]+x[i])``  ``0 .. N-3m+1``
total deviation           ``x*[k-m] - 2x[k] + x*[k+m]`` (x* reflected)  ``1 .. N-1``
========================  ===========================================  =================
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numba import njit, prange

__all__ = [
    "CHUNK",
    "ESTIMATOR_CODES",
    "adev_sumsq",
    "hdev_sumsq",
    "mdev_sumsq",
    "n_terms",
    "phase_from_rate",
    "phase_from_rate_ref",
    "reduce_partials",
    "sumsq_ref",
    "sumsq_tasks",
    "term_range",
    "terms_ref",
    "totdev_sumsq",
]

#: Maximum number of terms summed by one kernel call inside :func:`sumsq_tasks`.
CHUNK: int = 1 << 16

#: Below this many terms in all (a log of 1e6 samples has about 2e7 over the octave
#: grid) :func:`sumsq_tasks` runs its tasks one after the other from Python: the work
#: takes milliseconds, while the threads of a parallel region keep spinning after it
#: (OpenMP's wait policy), which cost ``imubounds static`` a third of a CPU second.
SERIAL_MAX_TERMS: int = 1 << 26

#: LLVM fast-math flags of the sum-of-squares kernels: *only* reassociation, so
#: that the compiler may split the sum into SIMD lanes (4x faster on AVX2).
#: No ``nnan``/``ninf``/``arcp``/``afn``: every term is an IEEE double; the
#: order of additions (lanes, then chunks, then ``fsum``) is fixed for a given
#: build and independent of the thread count.
_REDUCE_FLAGS: set[str] = {"reassoc"}

#: Integer codes of the estimators, as used by :func:`sumsq_tasks`.
ESTIMATOR_CODES: dict[str, int] = {
    "overlapping": 0,
    "non-overlapping": 1,
    "hadamard": 2,
    "modified": 3,
    "total": 4,
    "non-overlapping-hadamard": 5,
}


# --------------------------------------------------------------------------
# phase (integrated signal)
# --------------------------------------------------------------------------
@njit(cache=True, fastmath=False)
def _phase_kernel(y: np.ndarray, mean: float, t0: float, out: np.ndarray) -> None:
    s = 0.0
    c = 0.0
    out[0] = 0.0
    for i in range(y.shape[0]):
        v = y[i] - mean
        t = s + v
        bp = t - s
        c += (s - (t - bp)) + (v - bp)  # Knuth TwoSum: exact error of s + v
        s = t
        out[i + 1] = (s + c) * t0


def phase_from_rate(y: np.ndarray, t0: float, out: np.ndarray | None = None) -> np.ndarray:
    """Compensated integral of the mean-removed rate signal.

    Parameters
    ----------
    y : ndarray, shape (N,)
        Rate samples (any unit U, e.g. rad/s), float64, finite.
    t0 : float
        Sample period in s.
    out : ndarray, shape (N + 1,), optional
        Where to write the result (may be a writable ``np.memmap``).

    Returns
    -------
    ndarray, shape (N + 1,)
        ``x[0] = 0``, ``x[k] = t0 * sum_{i<k} (y[i] - mean(y))`` in U*s, each
        value within a few ulp of the exact partial sum (compensated summation).
    """
    y = np.ascontiguousarray(y, dtype=np.float64)
    if out is None:
        out = np.empty(y.shape[0] + 1, dtype=np.float64)
    mean = float(np.mean(y)) if y.shape[0] else 0.0
    _phase_kernel(y, mean, float(t0), out)
    return out


def phase_from_rate_ref(y: np.ndarray, t0: float) -> np.ndarray:
    """Plain-numpy reference of :func:`phase_from_rate` (``np.cumsum``)."""
    y = np.asarray(y, dtype=np.float64)
    return np.concatenate(([0.0], np.cumsum(y - np.mean(y)) * t0))


@njit(cache=True, fastmath=False, boundscheck=False)
def _window_sums_kernel(
    x: np.ndarray, m: int, n: int, windows: int, lo: np.ndarray, hi: np.ndarray
) -> None:
    terms = n - 2 * m + 1
    last = (windows - 1) * n + terms  # the last index of the running sum needed
    c = 0.0  # sum of d[j]**2 for j < i, added in order (np.cumsum's order)
    for i in range(last + 1):
        if i % n == 0 and i // n < windows:
            lo[i // n] = c
        if i >= terms and (i - terms) % n == 0:
            hi[(i - terms) // n] = c
        if i < last:
            d = (x[i + 2 * m] - 2.0 * x[i + m] + x[i]) / m
            c += d * d


def window_sums(
    x: np.ndarray, m: int, n: int, windows: int
) -> tuple[np.ndarray, np.ndarray]:
    """The running sum ``c`` of the squared overlapping second differences
    ``d[i] = (x[i+2m] - 2 x[i+m] + x[i]) / m`` at the ends of each window of ``n``
    samples: ``lo[k] = c[k n]`` and ``hi[k] = c[k n + n - 2m + 1]`` (the window's
    sum is ``hi - lo``), each value bit for bit that of
    :func:`window_sums_ref` (the same additions in the same order, no
    reassociation), without the two arrays of the log's length."""
    x = np.ascontiguousarray(x, dtype=np.float64)
    if windows < 1 or n < 2 * m or x.shape[0] < windows * n + 1:
        raise ValueError("window_sums: windows of n samples need n >= 2m and x of windows*n+1")
    lo = np.empty(windows, dtype=np.float64)
    hi = np.empty(windows, dtype=np.float64)
    _window_sums_kernel(x, int(m), int(n), int(windows), lo, hi)
    return lo, hi


def window_sums_ref(
    x: np.ndarray, m: int, n: int, windows: int
) -> tuple[np.ndarray, np.ndarray]:
    """Plain-numpy reference of :func:`window_sums` (``np.cumsum``)."""
    d = (x[2 * m :] - 2.0 * x[m:-m] + x[: -2 * m]) / m
    c = np.concatenate(([0.0], np.cumsum(d * d)))
    starts = np.arange(windows) * n
    return c[starts], c[starts + n - 2 * m + 1]


# --------------------------------------------------------------------------
# term counts and ranges
# --------------------------------------------------------------------------
def term_range(estimator: str, n_samples: int, m: int) -> tuple[int, int]:
    """Half-open range ``[k_start, k_stop)`` of term indices for one ``m``.

    For ``non-overlapping`` the index is the cluster-pair index ``j``.
    The range is empty (``k_stop <= k_start``) when ``m`` is too large.
    """
    n = int(n_samples)
    if estimator == "overlapping":
        return 0, n - 2 * m + 1
    if estimator == "non-overlapping":
        return 0, n // m - 1
    if estimator == "hadamard":
        return 0, n - 3 * m + 1
    if estimator == "non-overlapping-hadamard":
        return 0, n // m - 2
    if estimator == "modified":
        return 0, n - 3 * m + 2
    if estimator == "total":
        return 1, n
    raise ValueError(f"unknown estimator {estimator!r}")


def n_terms(estimator: str, n_samples: int, m: int) -> int:
    """Number of squared terms averaged for cluster size ``m`` (may be <= 0)."""
    a, b = term_range(estimator, n_samples, m)
    return b - a


# --------------------------------------------------------------------------
# sum-of-squares kernels over a range of term indices
# --------------------------------------------------------------------------
@njit(cache=True, fastmath=_REDUCE_FLAGS, boundscheck=False)
def adev_sumsq(x: np.ndarray, m: int, k0: int, k1: int, stride: int) -> float:
    """Sum of ``(x[k+2m] - 2x[k+m] + x[k])**2`` for ``k = k0, k0+stride, ... < k1``.

    ``stride=1``, ``k`` in ``[0, N-2m+1)`` gives the overlapping Allan variance
    numerator; ``stride=m`` with ``k = j*m`` the non-overlapping one. The caller
    guarantees ``k1 - 1 + 2m < len(x)``. Units: (U*s)^2.
    """
    s0 = 0.0
    m2 = 2 * m
    if stride == 1:
        if k1 <= k0:
            return 0.0
        a = x[k0:k1]
        b = x[k0 + m : k1 + m]
        c = x[k0 + m2 : k1 + m2]
        for i in range(a.shape[0]):
            d0 = c[i] - 2.0 * b[i] + a[i]
            s0 += d0 * d0
    else:
        for k in range(k0, k1, stride):
            d0 = x[k + m2] - 2.0 * x[k + m] + x[k]
            s0 += d0 * d0
    return s0


@njit(cache=True, fastmath=_REDUCE_FLAGS, boundscheck=False)
def hdev_sumsq(x: np.ndarray, m: int, k0: int, k1: int, stride: int) -> float:
    """Sum of ``(x[k+3m] - 3x[k+2m] + 3x[k+m] - x[k])**2`` over ``k = k0, k0+stride, ... < k1``.

    Overlapping Hadamard variance numerator for ``stride=1``; ``stride=m`` with
    ``k = j*m`` the non-overlapping one. The caller
    guarantees ``k1 - 1 + 3m < len(x)``. Units: (U*s)^2.
    """
    s0 = 0.0
    m2 = 2 * m
    m3 = 3 * m
    if stride == 1:
        if k1 <= k0:
            return 0.0
        a = x[k0:k1]
        b = x[k0 + m : k1 + m]
        c = x[k0 + m2 : k1 + m2]
        e = x[k0 + m3 : k1 + m3]
        for i in range(a.shape[0]):
            d0 = e[i] - 3.0 * c[i] + 3.0 * b[i] - a[i]
            s0 += d0 * d0
    else:
        for k in range(k0, k1, stride):
            d0 = x[k + m3] - 3.0 * x[k + m2] + 3.0 * x[k + m] - x[k]
            s0 += d0 * d0
    return s0


@njit(cache=True, fastmath=False, boundscheck=False)
def mdev_sumsq(x: np.ndarray, m: int, k0: int, k1: int) -> float:
    """Modified Allan variance numerator over outer indices ``k0 <= j < k1``.

    Sum over ``j`` of ``S_j**2`` with
    ``S_j = sum_{i=j}^{j+m-1} (x[i+2m] - 2x[i+m] + x[i])``. ``S_{k0}`` is
    summed directly (m terms); later ``S_j`` are updated by the sliding-window
    increment ``S_j - S_{j-1} = x[j-1+3m] - 3x[j-1+2m] + 3x[j-1+m] - x[j-1]``
    (computed in vectorised blocks), the rounding error of the running sum is
    carried in a TwoSum compensation term, and the window is re-summed
    directly every ``max(16m, 4096)`` steps. The caller
    guarantees ``k1 - 2 + 3m < len(x)``. Units: (U*s)^2.
    """
    if k1 <= k0:
        return 0.0
    m2 = 2 * m
    resync = max(16 * m, 4096)
    nbuf = 2048
    buf = np.empty(nbuf, dtype=np.float64)
    total = 0.0
    j = k0
    while j < k1:
        # direct window sum at j
        s = 0.0
        c = 0.0
        for i in range(j, j + m):
            v = x[i + m2] - 2.0 * x[i + m] + x[i]
            t = s + v
            bp = t - s
            c += (s - (t - bp)) + (v - bp)
            s = t
        w = s + c
        total += w * w
        jstop = min(k1, j + resync)
        j += 1
        while j < jstop:
            nb = min(nbuf, jstop - j)
            # window increments S_j - S_{j-1} = d_{j+m-1} - d_{j-1}
            #   = x[j-1+3m] - 3x[j-1+2m] + 3x[j-1+m] - x[j-1]  (vectorisable loop)
            p0 = x[j - 1 : j - 1 + nb]
            p1 = x[j - 1 + m : j - 1 + m + nb]
            p2 = x[j - 1 + m2 : j - 1 + m2 + nb]
            p3 = x[j - 1 + m2 + m : j - 1 + m2 + m + nb]
            for q in range(nb):
                buf[q] = p3[q] - 3.0 * p2[q] + 3.0 * p1[q] - p0[q]
            for q in range(nb):
                v = buf[q]
                t = s + v
                bp = t - s
                c += (s - (t - bp)) + (v - bp)
                s = t
                w = s + c
                total += w * w
            j += nb
    return total


@njit(cache=True, fastmath=False, boundscheck=False)
def _refl(x: np.ndarray, idx: int) -> float:
    last = x.shape[0] - 1
    if idx < 0:
        return 2.0 * x[0] - x[-idx]
    if idx > last:
        return 2.0 * x[last] - x[2 * last - idx]
    return x[idx]


@njit(cache=True, fastmath=_REDUCE_FLAGS, boundscheck=False)
def totdev_sumsq(x: np.ndarray, m: int, k0: int, k1: int) -> float:
    """Total-variance numerator over centres ``k0 <= k < k1`` (valid 1 .. N-1).

    Sum of ``(x*[k-m] - 2x[k] + x*[k+m])**2`` where ``x*`` is ``x`` extended by
    odd reflection at both ends (NIST SP 1065 eq. 25):
    ``x*[-j] = 2x[0] - x[j]``, ``x*[N+j] = 2x[N] - x[N-j]``. Needs ``m <= N``.
    Units: (U*s)^2.
    """
    last = x.shape[0] - 1
    s0 = 0.0
    s1 = 0.0
    # interior where no reflection is needed: m <= k <= last - m
    a = max(k0, m)
    b = min(k1, last - m + 1)
    if 2 * m > last:  # reflections on both sides possible: generic scalar path
        for k in range(k0, k1):
            d = _refl(x, k - m) - 2.0 * x[k] + _refl(x, k + m)
            s0 += d * d
        return s0
    # left edge k0 <= k < min(k1, a): x*[k-m] = 2x[0] - x[m-k]
    lo = k0
    hi = min(k1, a)
    if hi > lo:
        x0 = x[0]
        xr = x[m - hi + 1 : m - lo + 1][::-1]  # xr[q] = x[m - (lo + q)]
        xc = x[lo:hi]
        xp = x[lo + m : hi + m]
        for q in range(hi - lo):
            d = (2.0 * x0 - xr[q]) - 2.0 * xc[q] + xp[q]
            s0 += d * d
    if a < b:
        # interior terms are overlapping-ADEV terms shifted by m (vectorised)
        s0 += adev_sumsq(x, m, a - m, b - m, 1)
    # right edge max(k0, b, a) <= k < k1: x*[k+m] = 2x[last] - x[2 last - k - m]
    lo = max(k0, b, a)
    hi = k1
    if hi > lo:
        xl = x[last]
        xr = x[2 * last - m - hi + 1 : 2 * last - m - lo + 1][::-1]
        xm = x[lo - m : hi - m]
        xc = x[lo:hi]
        for q in range(hi - lo):
            d = xm[q] - 2.0 * xc[q] + (2.0 * xl - xr[q])
            s1 += d * d
    return s0 + s1


# --------------------------------------------------------------------------
# parallel task driver
# --------------------------------------------------------------------------
@njit(cache=True, fastmath=False, parallel=True)
def _run_tasks(
    x: np.ndarray, code: int, ms: np.ndarray, k0: np.ndarray, k1: np.ndarray
) -> np.ndarray:
    out = np.empty(k0.shape[0], dtype=np.float64)
    for t in prange(k0.shape[0]):
        m = ms[t]
        if code == 0:
            out[t] = adev_sumsq(x, m, k0[t], k1[t], 1)
        elif code == 1:
            out[t] = adev_sumsq(x, m, k0[t] * m, k1[t] * m, m)
        elif code == 2:
            out[t] = hdev_sumsq(x, m, k0[t], k1[t], 1)
        elif code == 3:
            out[t] = mdev_sumsq(x, m, k0[t], k1[t])
        elif code == 5:
            out[t] = hdev_sumsq(x, m, k0[t] * m, k1[t] * m, m)
        else:
            out[t] = totdev_sumsq(x, m, k0[t], k1[t])
    return out


def _make_tasks(
    estimator: str, n_samples: int, ms: np.ndarray, chunk: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Split every ``m`` into chunks of term indices, chunk-major order.

    Chunk-major order (all ``m`` for chunk 0, then chunk 1, ...) makes
    consecutive tasks read the same region of ``x`` (cache blocking) and the
    static ``prange`` schedule gives each thread a contiguous region.
    """
    ranges = [term_range(estimator, n_samples, int(m)) for m in ms]
    lens = [max(0, b - a) for a, b in ranges]
    if estimator == "modified":
        # each chunk re-sums an m-long window first: keep that overhead small
        csize = [max(chunk, 16 * int(m)) for m in ms]
    else:
        csize = [chunk] * len(ms)
    nch = [max(1, -(-n // c)) for n, c in zip(lens, csize, strict=True)]
    idx, m_t, a_t, b_t = [], [], [], []
    for c in range(max(nch) if nch else 0):
        for i, m in enumerate(ms):
            if c >= nch[i]:
                continue
            a = ranges[i][0] + c * csize[i]
            b = min(ranges[i][0] + lens[i], a + csize[i])
            idx.append(i)
            m_t.append(int(m))
            a_t.append(a)
            b_t.append(max(a, b))
    return (
        np.asarray(idx, dtype=np.int64),
        np.asarray(m_t, dtype=np.int64),
        np.asarray(a_t, dtype=np.int64),
        np.asarray(b_t, dtype=np.int64),
    )


def _task_sum(x: np.ndarray, code: int, m: int, a: int, b: int) -> float:
    """One task of :func:`_run_tasks`, called from Python: the same kernel call on
    the same range, hence the same partial sum."""
    if code == 0:
        return float(adev_sumsq(x, m, a, b, 1))
    if code == 1:
        return float(adev_sumsq(x, m, a * m, b * m, m))
    if code == 2:
        return float(hdev_sumsq(x, m, a, b, 1))
    if code == 3:
        return float(mdev_sumsq(x, m, a, b))
    if code == 5:
        return float(hdev_sumsq(x, m, a * m, b * m, m))
    return float(totdev_sumsq(x, m, a, b))


def reduce_partials(idx: np.ndarray, partial: np.ndarray, n_out: int) -> np.ndarray:
    """Add per-task partial sums into one sum per ``m`` with ``math.fsum``."""
    out = np.zeros(n_out, dtype=np.float64)
    order = np.argsort(idx, kind="stable")
    idx_s = idx[order]
    part_s = partial[order]
    bounds = np.searchsorted(idx_s, np.arange(n_out + 1))
    for i in range(n_out):
        out[i] = math.fsum(part_s[bounds[i] : bounds[i + 1]].tolist())
    return out


def sumsq_tasks(
    x: np.ndarray,
    estimator: str,
    ms: np.ndarray,
    chunk: int = CHUNK,
    parallel: bool | None = None,
) -> np.ndarray:
    """Sums of squared terms for every cluster size in ``ms`` (numba; tasks run in
    parallel when there are more than :data:`SERIAL_MAX_TERMS` terms).

    The tasks and their reduction are the same either way, so the sums are too;
    ``parallel`` forces the choice (tests).

    Parameters
    ----------
    x : ndarray, shape (N + 1,)
        Phase array from :func:`phase_from_rate` (U*s).
    estimator : str
        One of :data:`ESTIMATOR_CODES`.
    ms : ndarray of int
        Cluster sizes, each within the estimator's limit.
    chunk : int
        Maximum number of terms per task.

    Returns
    -------
    ndarray, shape (len(ms),)
        Sum of squared terms for each ``m`` in (U*s)^2; divide by the
        normalisation of the estimator to get the variance.
    """
    ms = np.asarray(ms, dtype=np.int64)
    n_samples = x.shape[0] - 1
    idx, m_t, a_t, b_t = _make_tasks(estimator, n_samples, ms, int(chunk))
    if idx.size == 0:
        return np.zeros(ms.shape[0])
    code = ESTIMATOR_CODES[estimator]
    if parallel is None:
        parallel = int(np.sum(b_t - a_t)) > SERIAL_MAX_TERMS
    if parallel:
        partial = _run_tasks(x, code, m_t, a_t, b_t)
    else:
        partial = np.array([_task_sum(x, code, int(m), int(a), int(b))
                            for m, a, b in zip(m_t, a_t, b_t, strict=True)])  # fmt: skip
    return reduce_partials(idx, partial, ms.shape[0])


def num_threads() -> int:
    """Number of threads numba uses for :func:`sumsq_tasks`."""
    return int(numba.get_num_threads())


# --------------------------------------------------------------------------
# plain-numpy references (tests compare the kernels against these)
# --------------------------------------------------------------------------
def terms_ref(x: np.ndarray, estimator: str, m: int) -> np.ndarray:
    """Plain-numpy array of the squared-term *bases* d_k for one ``m`` (U*s).

    The estimator's numerator is ``sum(d**2)``; the robust Allan variance takes
    a median of ``|d|`` instead. Uses O(N) temporaries.
    """
    x = np.asarray(x, dtype=np.float64)
    n = x.shape[0] - 1
    m = int(m)
    if estimator == "overlapping":
        return x[2 * m :] - 2.0 * x[m:-m] + x[: -2 * m]
    if estimator == "non-overlapping":
        k = n // m
        xs = x[: k * m + 1 : m]
        return xs[2:] - 2.0 * xs[1:-1] + xs[:-2]
    if estimator == "non-overlapping-hadamard":
        k = n // m
        xs = x[: k * m + 1 : m]
        return xs[3:] - 3.0 * xs[2:-1] + 3.0 * xs[1:-2] - xs[:-3]
    if estimator == "hadamard":
        return (
            x[3 * m :]
            - 3.0 * x[2 * m : n + 1 - m]
            + 3.0 * x[m : n + 1 - 2 * m]
            - x[: n + 1 - 3 * m]
        )
    if estimator == "modified":
        d2 = x[2 * m :] - 2.0 * x[m:-m] + x[: -2 * m]
        c = np.concatenate(([0.0], np.cumsum(d2)))
        return c[m:] - c[:-m]
    if estimator == "total":
        left = 2.0 * x[0] - x[n - 1 : 0 : -1]  # x*[-(n-1)] .. x*[-1]
        right = 2.0 * x[n] - x[n - 1 : 0 : -1]  # x*[n+1] .. x*[2n-1]
        ext = np.concatenate((left, x, right))
        off = n - 1  # ext[off + k] = x*[k]
        k = np.arange(1, n)
        return ext[off + k - m] - 2.0 * ext[off + k] + ext[off + k + m]
    raise ValueError(f"unknown estimator {estimator!r}")


def sumsq_ref(x: np.ndarray, estimator: str, m: int) -> float:
    """Plain-numpy sum of squared terms for one ``m`` (reference, uses temporaries)."""
    x = np.asarray(x, dtype=np.float64)
    if estimator == "modified":
        d2 = x[2 * m :] - 2.0 * x[m:-m] + x[: -2 * m]
        d = np.lib.stride_tricks.sliding_window_view(d2, int(m)).sum(axis=1)
        return float(np.sum(d * d))
    d = terms_ref(x, estimator, m)
    return float(np.sum(d * d))
