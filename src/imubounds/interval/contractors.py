"""Vectorised forward-backward (HC4-revise) contractors on interval arrays.

Each primitive constraint (``z = x + y``, ``x - y``, ``x * y``, ``x / y``,
``x**2``, ``sqrt(x)``, ``sin(x)``, ``cos(x)``, ``atan2(y, x)``, ``-x``,
``exp(x)``, ``log(x)``, ``z = x``) has a contractor that, for every box,
applies the forward step ``[z] <- [z] & f([x], [y])`` and the backward
(inverse-projection) steps ``[x] <- [x] & ...``. They run the scalar rules of
:mod:`imubounds.interval._ctc` in a compiled loop; the scalar versions
(``_ctc.ctc_add`` ...) are callable from numba code directly.

A box that the constraint proves inconsistent comes back with every domain
empty and a code saying which variable was emptied first (0 = ``z``,
1 = first argument, 2 = second argument); ``-1`` means consistent.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

from imubounds.errors import OptionError
from imubounds.interval import _ctc as k
from imubounds.interval import _vec as v
from imubounds.interval.array import IntervalArray
from imubounds.interval.rounding import check_rounding

OPS: dict[str, int] = {name: i for i, name in enumerate(k.OP_NAMES)}
_MODES = {"f": 1, "forward": 1, "b": 2, "backward": 2, "fb": 3, "both": 3}


class HC4Result(NamedTuple):
    """Contracted domains and the per-box emptiness code."""

    z: IntervalArray
    a: IntervalArray
    b: IntervalArray | None
    code: np.ndarray  #: int8: -1 consistent, else 0/1/2 = variable emptied first

    @property
    def consistent(self) -> np.ndarray:
        """Boolean array: True where the box survived."""
        return self.code < 0


def op_code(op: str | int) -> int:
    """Operation code for a name (``"add"``, ``"sin"``, ...) or a code."""
    if isinstance(op, int | np.integer):
        if 0 <= int(op) < len(k.OP_NAMES):
            return int(op)
    elif op in OPS:
        return OPS[op]
    raise OptionError(f"unknown primitive {op!r}; use one of {', '.join(k.OP_NAMES)}")


def mode_code(mode: str | int) -> int:
    """1 forward, 2 backward, 3 both, from ``"f"``, ``"b"``, ``"fb"`` or the int."""
    if isinstance(mode, int) and mode in (1, 2, 3):
        return mode
    if isinstance(mode, str) and mode in _MODES:
        return _MODES[mode]
    raise OptionError(f"unknown contractor mode {mode!r}; use 'f', 'b' or 'fb'")


def hc4_inplace(
    op: str | int,
    zlo: np.ndarray,
    zhi: np.ndarray,
    alo: np.ndarray,
    ahi: np.ndarray,
    blo: np.ndarray | None = None,
    bhi: np.ndarray | None = None,
    mode: str | int = "fb",
) -> np.ndarray:
    """Contract raw 1-D contiguous float64 endpoint arrays in place (fast path).

    Returns the int8 code array (see module docstring). For unary primitives
    ``blo``/``bhi`` may be None.
    """
    check_rounding()
    opc = op_code(op)
    n = zlo.size
    arrays = [zlo, zhi, alo, ahi]
    if k.OP_ARITY[opc] == 2:
        if blo is None or bhi is None:
            raise OptionError(f"primitive {k.OP_NAMES[opc]!r} needs two arguments")
        arrays += [blo, bhi]
    for arr in arrays:
        if arr.dtype != np.float64 or arr.ndim != 1 or arr.size != n or not arr.flags.c_contiguous:
            raise OptionError("hc4_inplace needs 1-D C-contiguous float64 arrays of one length")
    if blo is None or bhi is None:
        blo = np.zeros(n)
        bhi = np.zeros(n)
    code = np.empty(n, dtype=np.int8)
    v.v_revise(opc, zlo, zhi, alo, ahi, blo, bhi, mode_code(mode), code)
    return code


def hc4(op: str | int, z: Any, a: Any, b: Any = None, mode: str | int = "fb") -> HC4Result:
    """HC4-revise of one primitive on broadcast interval arrays.

    Parameters
    ----------
    op : str or int
        ``"add"``, ``"sub"``, ``"mul"``, ``"div"``, ``"sqr"``, ``"sqrt"``,
        ``"sin"``, ``"cos"``, ``"atan2"`` (``z = atan2(a, b)``: ``a`` is y),
        ``"neg"``, ``"exp"``, ``"log"``, ``"eq"``.
    z, a, b : IntervalArray or array_like
        Domains of the output and the arguments (numbers = degenerate).
    mode : {"fb", "f", "b"}
        Forward and backward, forward only, or backward only.

    Returns
    -------
    HC4Result
        New arrays (inputs are not modified) and the emptiness code.
    """
    check_rounding()
    opc = op_code(op)
    binary = k.OP_ARITY[opc] == 2
    if binary and b is None:
        raise OptionError(f"primitive {k.OP_NAMES[opc]!r} needs two arguments")
    zz = IntervalArray.coerce(z)
    aa = IntervalArray.coerce(a)
    bb = IntervalArray.coerce(b) if binary else IntervalArray(0.0)
    parts = np.broadcast_arrays(zz.lo, zz.hi, aa.lo, aa.hi, bb.lo, bb.hi)
    shape = parts[0].shape
    flat = [np.array(p, dtype=np.float64).reshape(-1) for p in parts]
    code = np.empty(flat[0].size, dtype=np.int8)
    v.v_revise(opc, *flat, mode_code(mode), code)

    def mk(i: int) -> IntervalArray:
        return IntervalArray._raw(flat[i].reshape(shape), flat[i + 1].reshape(shape))

    return HC4Result(mk(0), mk(2), mk(4) if binary else None, code.reshape(shape))


def hc4_add(z: Any, x: Any, y: Any, mode: str | int = "fb") -> HC4Result:
    """Contract ``z = x + y``."""
    return hc4("add", z, x, y, mode)


def hc4_sub(z: Any, x: Any, y: Any, mode: str | int = "fb") -> HC4Result:
    """Contract ``z = x - y``."""
    return hc4("sub", z, x, y, mode)


def hc4_mul(z: Any, x: Any, y: Any, mode: str | int = "fb") -> HC4Result:
    """Contract ``z = x * y``."""
    return hc4("mul", z, x, y, mode)


def hc4_div(z: Any, x: Any, y: Any, mode: str | int = "fb") -> HC4Result:
    """Contract ``z = x / y``."""
    return hc4("div", z, x, y, mode)


def hc4_sqr(z: Any, x: Any, mode: str | int = "fb") -> HC4Result:
    """Contract ``z = x**2``."""
    return hc4("sqr", z, x, None, mode)


def hc4_sqrt(z: Any, x: Any, mode: str | int = "fb") -> HC4Result:
    """Contract ``z = sqrt(x)``."""
    return hc4("sqrt", z, x, None, mode)


def hc4_sin(z: Any, x: Any, mode: str | int = "fb") -> HC4Result:
    """Contract ``z = sin(x)`` (x in rad)."""
    return hc4("sin", z, x, None, mode)


def hc4_cos(z: Any, x: Any, mode: str | int = "fb") -> HC4Result:
    """Contract ``z = cos(x)`` (x in rad)."""
    return hc4("cos", z, x, None, mode)


def hc4_atan2(z: Any, y: Any, x: Any, mode: str | int = "fb") -> HC4Result:
    """Contract ``z = atan2(y, x)`` (z in rad); the result's ``a`` is y, ``b`` is x."""
    return hc4("atan2", z, y, x, mode)
