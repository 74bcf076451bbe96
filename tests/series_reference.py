"""Plain references of :mod:`imubounds.dynamic.estimator.series_kernels` (for tests).

The sample series as they were before the checkpoints (issue 27): the four prefix sums
of a :class:`~imubounds.dynamic.estimator.inputs.PiecewiseSignal` as full arrays of
``np.cumsum``, and the range extrema from the full sparse table (``O(n log n)``
memory). The compiled kernels must agree bit for bit.
"""

from __future__ import annotations

import numpy as np


def prefix_arrays(
    bnd: np.ndarray, y: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``S, A, Z, ZA`` (length ``n + 1``) as the signal computed them."""
    ln = np.diff(bnd)
    x = y * ln
    S = np.concatenate([[0.0], np.cumsum(x)])
    A = np.concatenate([[0.0], np.cumsum(np.abs(x))])
    inc = S[:-1] * ln + 0.5 * y * ln * ln
    Z = np.concatenate([[0.0], np.cumsum(inc)])
    ZA = np.concatenate([[0.0], np.cumsum(np.abs(inc))])
    return S, A, Z, ZA


class SparseTable:
    """Range minimum / maximum queries over a fixed array (sparse tables, O(1) query)."""

    def __init__(self, lo: np.ndarray, hi: np.ndarray | None = None) -> None:
        hi = lo if hi is None else hi
        self.mn = [np.asarray(lo, dtype=float)]
        self.mx = [np.asarray(hi, dtype=float)]
        k = 1
        while (1 << k) <= self.mn[0].size:
            h = 1 << (k - 1)
            self.mn.append(np.minimum(self.mn[-1][:-h], self.mn[-1][h:]))
            self.mx.append(np.maximum(self.mx[-1][:-h], self.mx[-1][h:]))
            k += 1

    def query(self, i: np.ndarray, j: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(min lo, max hi) over inclusive index ranges ``i..j`` (``i <= j``)."""
        i = np.asarray(i, dtype=np.int64)
        j = np.asarray(j, dtype=np.int64)
        n = np.maximum(j - i + 1, 1)
        k = np.floor(np.log2(n)).astype(np.int64)
        out_mn = np.empty(i.shape)
        out_mx = np.empty(i.shape)
        for kk in np.unique(k):
            s = k == kk
            a, b = i[s], j[s] - (1 << kk) + 1
            out_mn[s] = np.minimum(self.mn[kk][a], self.mn[kk][b])
            out_mx[s] = np.maximum(self.mx[kk][a], self.mx[kk][b])
        return out_mn, out_mx
