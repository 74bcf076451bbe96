"""The interval rotation between the navigation (east, north) and heading frames.

``R(psi) (x, y) = (c x - s y, s x + c y)`` and its inverse ``R(-psi)``, for intervals
``c = cos psi``, ``s = sin psi`` (scalar interval rules, outward rounded): the one
implementation the paper kernel and the smoother use.
"""

from __future__ import annotations

from numba import njit

from imubounds.interval import scalar as c


@njit(cache=True)
def rot(
    clo: float, chi: float, slo: float, shi: float, xlo: float, xhi: float, ylo: float, yhi: float
) -> tuple[float, float, float, float]:
    """``R(psi) (x, y) = (c x - s y, s x + c y)`` for intervals c = cos psi, s = sin psi."""
    a = c.mul(clo, chi, xlo, xhi)
    b = c.mul(slo, shi, ylo, yhi)
    e = c.sub(a[0], a[1], b[0], b[1])
    a = c.mul(slo, shi, xlo, xhi)
    b = c.mul(clo, chi, ylo, yhi)
    n = c.add(a[0], a[1], b[0], b[1])
    return e[0], e[1], n[0], n[1]


@njit(cache=True)
def irot(
    clo: float, chi: float, slo: float, shi: float, xlo: float, xhi: float, ylo: float, yhi: float
) -> tuple[float, float, float, float]:
    """``R(-psi) (x, y) = (c x + s y, c y - s x)``."""
    a = c.mul(clo, chi, xlo, xhi)
    b = c.mul(slo, shi, ylo, yhi)
    f = c.add(a[0], a[1], b[0], b[1])
    a = c.mul(clo, chi, ylo, yhi)
    b = c.mul(slo, shi, xlo, xhi)
    l_ = c.sub(a[0], a[1], b[0], b[1])
    return f[0], f[1], l_[0], l_[1]
