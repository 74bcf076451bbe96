"""Plain reference of the compiled per-window integrals of ``|y - c|`` over piecewise-
constant samples (:func:`imubounds.dynamic.estimator.aided.transport_blocks.abs_dev_integral`,
:func:`imubounds.dynamic.estimator.aided.transport_blocks.weighted_abs_dev`): every
window's overlap with every segment as one dense matrix (O(windows x segments) memory),
in exact rational arithmetic, to test the compiled loops' sums and their rounding
inflation against."""

from __future__ import annotations

from fractions import Fraction

import numpy as np


def weighted_abs_dev_exact(
    bnd: np.ndarray, y: np.ndarray, unknown: np.ndarray, xmax: float, om: np.ndarray,
    a: np.ndarray, b: np.ndarray, c: np.ndarray,
    tf: np.ndarray, wf: np.ndarray, tl: np.ndarray, wl: np.ndarray,
) -> list[Fraction]:
    """``int_a^b om |y - c| dt`` per window, exactly: on segment k the part ``[s0, s1]``
    of ``[a, b]``; its weight ``om_k``, at least ``wf`` where ``s0 < tf``, at least ``wl``
    where ``s1 > tl``; an unknown segment's value ``xmax + |c|``."""
    F = Fraction
    out = []
    for w in range(a.size):
        acc = F(0)
        for k in range(bnd.size - 1):
            s0, s1 = max(F(bnd[k]), F(a[w])), min(F(bnd[k + 1]), F(b[w]))
            if s1 <= s0:
                continue
            v = F(xmax) + abs(F(c[w])) if unknown[k] else abs(F(y[k]) - F(c[w]))
            wt = F(om[k])
            if float(s0) < tf[w]:  # the ends are floats: compared exactly
                wt = max(wt, F(wf[w]))
            if float(s1) > tl[w]:
                wt = max(wt, F(wl[w]))
            acc += wt * v * (s1 - s0)
        out.append(acc)
    return out
