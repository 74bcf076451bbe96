"""The scalar interval rules the estimator uses, from :mod:`imubounds.interval`.

One import point, so the estimator follows wherever the interval subpackage
exposes its compiled scalar rules (functions on floats returning ``(lo, hi)``,
outward rounded, empty = ``(+inf, -inf)``).
"""

from __future__ import annotations

from imubounds.interval import scalar as _scalar

add = _scalar.add
cos = _scalar.cos
div = _scalar.div
div_rel = _scalar.div_rel
hull = _scalar.hull
inter = _scalar.inter
inter_two = _scalar.inter_two
is_empty = _scalar.is_empty
mul = _scalar.mul
next_down = _scalar.next_down
next_up = _scalar.next_up
sin = _scalar.sin
sub = _scalar.sub

__all__ = [
    "add",
    "cos",
    "div",
    "div_rel",
    "hull",
    "inter",
    "inter_two",
    "is_empty",
    "mul",
    "next_down",
    "next_up",
    "sin",
    "sub",
]
