"""Guaranteed interval arithmetic and forward-backward contractors.

* :class:`IntervalArray` -- vectorised closed intervals (``lo``/``hi`` float64
  arrays, empty = ``(+inf, -inf)``) with outward-rounded arithmetic and the
  functions below;
* :mod:`imubounds.interval._core` -- the same rules as scalar ``@njit``
  functions on floats returning ``(lo, hi)`` tuples, for numba loops
  (``from imubounds.interval import scalar`` gives that module);
* :mod:`.contractors` -- HC4-revise of primitive constraints, vectorised
  (:func:`hc4`) and scalar (:mod:`._ctc`);
* :class:`Network` -- constraint networks contracted by one forward-backward
  pass or by Waltz propagation, with inconsistency returned as data;
* :mod:`.angles` -- angle intervals modulo 2 pi;
* :func:`qinter` -- q-relaxed intersection of boxes;
* :mod:`.rounding` -- the rules need the default round-to-nearest mode
  (importing ``codac`` switches the process to round-upward!); the
  vectorised entry points check it.

Units: whatever the caller uses; angles in rad.
"""

from __future__ import annotations

from imubounds.interval import _core as scalar
from imubounds.interval import _ctc as scalar_contractors
from imubounds.interval import angles, rounding
from imubounds.interval.array import (
    I,
    IntervalArray,
    absolute,
    acos,
    asin,
    atan2,
    cos,
    exp,
    from_decimal,
    half_pi,
    hull,
    intersection,
    log,
    maximum,
    minimum,
    pi,
    sin,
    sqr,
    sqrt,
    tan,
    two_pi,
)
from imubounds.interval.contractors import (
    HC4Result,
    hc4,
    hc4_add,
    hc4_atan2,
    hc4_cos,
    hc4_div,
    hc4_inplace,
    hc4_mul,
    hc4_sin,
    hc4_sqr,
    hc4_sqrt,
    hc4_sub,
)
from imubounds.interval.network import ContractResult, Network, Primitive
from imubounds.interval.qinter import qinter, qinter_inliers

__all__ = [
    "ContractResult",
    "HC4Result",
    "I",
    "IntervalArray",
    "Network",
    "Primitive",
    "absolute",
    "acos",
    "angles",
    "asin",
    "atan2",
    "cos",
    "exp",
    "from_decimal",
    "half_pi",
    "hc4",
    "hc4_add",
    "hc4_atan2",
    "hc4_cos",
    "hc4_div",
    "hc4_inplace",
    "hc4_mul",
    "hc4_sin",
    "hc4_sqr",
    "hc4_sqrt",
    "hc4_sub",
    "hull",
    "intersection",
    "log",
    "maximum",
    "minimum",
    "pi",
    "qinter",
    "qinter_inliers",
    "rounding",
    "scalar",
    "scalar_contractors",
    "sin",
    "sqr",
    "sqrt",
    "tan",
    "two_pi",
]
