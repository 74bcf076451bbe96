"""Guaranteed interval arithmetic and forward-backward contractors.

* :class:`IntervalArray` -- vectorised closed intervals (``lo``/``hi`` float64
  arrays, empty = ``(+inf, -inf)``) with outward-rounded arithmetic and the
  functions below;
* :mod:`imubounds.interval._core` -- the same rules as scalar ``@njit``
  functions on floats returning ``(lo, hi)`` tuples, for numba loops
  (``from imubounds.interval import scalar`` gives that module);
* ``scalar_contractors`` (:mod:`._ctc`) -- HC4-revise of primitive constraints on
  float pairs, for compiled loops (the dynamic estimator's smoother is built on them);
* :func:`qinter_1d` -- q-relaxed intersection of intervals (compiled);
* :mod:`.rounding` -- the rules need the default round-to-nearest mode
  (importing ``codac`` switches the process to round-upward!); the
  vectorised entry points check it.

Units: whatever the caller uses; angles in rad.
"""

from __future__ import annotations

from imubounds.interval import _core as scalar
from imubounds.interval import _ctc as scalar_contractors
from imubounds.interval import rounding
from imubounds.interval.array import (
    I,
    IntervalArray,
    atan2,
    cos,
    hull,
    intersection,
    pi,
    sin,
    sqr,
    sqrt,
)
from imubounds.interval.qinter import qinter_1d

__all__ = [
    "I",
    "IntervalArray",
    "atan2",
    "cos",
    "hull",
    "intersection",
    "pi",
    "qinter_1d",
    "rounding",
    "scalar",
    "scalar_contractors",
    "sin",
    "sqr",
    "sqrt",
]
