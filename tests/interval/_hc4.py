"""Test harness: the scalar HC4-revise contractors of ``imubounds.interval._ctc``
(``ctc_add``, ``ctc_mul``, what the estimator's smoother uses) run over arrays of
boxes in compiled loops, with an :class:`IntervalArray` front end.

A box that the constraint proves inconsistent comes back with every domain
empty and a code saying which variable was emptied first (0 = ``z``,
1 = first argument, 2 = second argument); ``-1`` means consistent.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
from numba import njit

from imubounds.interval import _ctc as k
from imubounds.interval.array import IntervalArray
from imubounds.interval.rounding import check_rounding

OPS = ("add", "mul")
_MODES = {"f": 1, "b": 2, "fb": 3}


class HC4Result(NamedTuple):
    """Contracted domains and the per-box emptiness code."""

    z: IntervalArray
    a: IntervalArray
    b: IntervalArray
    code: np.ndarray  #: int8: -1 consistent, else 0/1/2 = variable emptied first


@njit(cache=True)
def v_revise(op: int, zlo: np.ndarray, zhi: np.ndarray, alo: np.ndarray, ahi: np.ndarray,
             blo: np.ndarray, bhi: np.ndarray, mode: int, code: np.ndarray) -> None:
    """In place over every box: op 0 = ``z = a + b``, 1 = ``z = a * b``."""
    for i in range(zlo.size):
        if op == 0:
            r = k.ctc_add(zlo[i], zhi[i], alo[i], ahi[i], blo[i], bhi[i], mode)
        else:
            r = k.ctc_mul(zlo[i], zhi[i], alo[i], ahi[i], blo[i], bhi[i], mode)
        zlo[i], zhi[i], alo[i], ahi[i], blo[i], bhi[i] = r[0], r[1], r[2], r[3], r[4], r[5]
        code[i] = r[6]


def hc4_inplace(op: str, zlo: np.ndarray, zhi: np.ndarray, alo: np.ndarray, ahi: np.ndarray,
                blo: np.ndarray, bhi: np.ndarray, mode: str = "fb") -> np.ndarray:
    """Contract 1-D float64 endpoint arrays in place; returns the int8 codes."""
    check_rounding()
    code = np.empty(zlo.size, dtype=np.int8)
    v_revise(OPS.index(op), zlo, zhi, alo, ahi, blo, bhi, _MODES[mode], code)
    return code


def hc4(op: str, z: Any, a: Any, b: Any, mode: str = "fb") -> HC4Result:
    """HC4-revise of one primitive on broadcast interval arrays (inputs untouched)."""
    zz, aa, bb = (IntervalArray.coerce(x) for x in (z, a, b))
    parts = np.broadcast_arrays(zz.lo, zz.hi, aa.lo, aa.hi, bb.lo, bb.hi)
    shape = parts[0].shape
    flat = [np.array(p, dtype=np.float64).reshape(-1) for p in parts]
    code = hc4_inplace(op, *flat, mode=mode)

    def mk(i: int) -> IntervalArray:
        return IntervalArray._raw(flat[i].reshape(shape), flat[i + 1].reshape(shape))

    return HC4Result(mk(0), mk(2), mk(4), code.reshape(shape))


def hc4_add(z: Any, x: Any, y: Any, mode: str = "fb") -> HC4Result:
    """HC4-revise of ``z = x + y``."""
    return hc4("add", z, x, y, mode)


def hc4_mul(z: Any, x: Any, y: Any, mode: str = "fb") -> HC4Result:
    """HC4-revise of ``z = x * y``."""
    return hc4("mul", z, x, y, mode)
