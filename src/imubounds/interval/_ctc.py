"""Scalar forward-backward (HC4-revise) contractors for the primitive
constraints of the dynamic estimator's smoother.

Every contractor takes the domains of its variables as ``lo, hi`` float
pairs, output variable first, and returns the contracted pairs followed by
an int code: ``-1`` if the box stays consistent, else the position (0 = the
output ``z``, 1 = first argument, 2 = second argument) of the variable that
became empty first; in that case every returned domain is empty.

``mode`` selects the steps: 1 = forward only (``z <- z & f(x, y)``),
2 = backward only (the inverse projections onto the arguments), 3 = both
(HC4-revise of the single primitive). A contractor never removes a point
that satisfies the constraint: it relies only on the outward-rounded rules
of :mod:`imubounds.interval._core`. Nonlinear terms of the smoother's links
(rotations by an interval angle) are evaluated forward with those rules and
enter the links as the ``y`` of ``z = x + y`` or ``z = x * y``.
"""

from __future__ import annotations

import math

from numba import njit

from imubounds.interval import _core as c

_E = math.inf
_F = -math.inf

Res = tuple[float, float, float, float, float, float, int]


@njit(cache=True)
def _fail(k: int) -> Res:
    return _E, _F, _E, _F, _E, _F, k


@njit(cache=True)
def _first_empty(zlo: float, zhi: float, alo: float, ahi: float, blo: float, bhi: float) -> int:
    if not (zlo <= zhi):
        return 0
    if not (alo <= ahi):
        return 1
    if not (blo <= bhi):
        return 2
    return -1


@njit(cache=True)
def ctc_add(zlo: float, zhi: float, xlo: float, xhi: float, ylo: float, yhi: float,
            mode: int = 3) -> Res:
    """HC4-revise of ``z = x + y``."""
    k = _first_empty(zlo, zhi, xlo, xhi, ylo, yhi)
    if k >= 0:
        return _fail(k)
    if mode & 1:
        zlo, zhi = c.inter(zlo, zhi, *c.add(xlo, xhi, ylo, yhi))
        if not (zlo <= zhi):
            return _fail(0)
    if mode & 2:
        xlo, xhi = c.inter(xlo, xhi, *c.sub(zlo, zhi, ylo, yhi))
        if not (xlo <= xhi):
            return _fail(1)
        ylo, yhi = c.inter(ylo, yhi, *c.sub(zlo, zhi, xlo, xhi))
        if not (ylo <= yhi):
            return _fail(2)
    return zlo, zhi, xlo, xhi, ylo, yhi, -1


@njit(cache=True)
def ctc_mul(zlo: float, zhi: float, xlo: float, xhi: float, ylo: float, yhi: float,
            mode: int = 3) -> Res:
    """HC4-revise of ``z = x * y`` (relational division: ``y`` containing 0
    still contracts ``x`` unless ``z`` contains 0 too)."""
    k = _first_empty(zlo, zhi, xlo, xhi, ylo, yhi)
    if k >= 0:
        return _fail(k)
    if mode & 1:
        zlo, zhi = c.inter(zlo, zhi, *c.mul(xlo, xhi, ylo, yhi))
        if not (zlo <= zhi):
            return _fail(0)
    if mode & 2:
        xlo, xhi = c.inter_two(xlo, xhi, *c.div_rel(zlo, zhi, ylo, yhi))
        if not (xlo <= xhi):
            return _fail(1)
        ylo, yhi = c.inter_two(ylo, yhi, *c.div_rel(zlo, zhi, xlo, xhi))
        if not (ylo <= yhi):
            return _fail(2)
    return zlo, zhi, xlo, xhi, ylo, yhi, -1
