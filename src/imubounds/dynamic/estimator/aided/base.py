"""Outward rounding helpers of the true-signal constraints (the physical constants are in
:mod:`imubounds.constants`)."""

from __future__ import annotations

from typing import Any

import numpy as np

from imubounds.interval import IntervalArray as IA
from imubounds.interval.rounding import up


def pm(r: Any) -> IA:
    """The interval ``[-r, r]`` (r >= 0, rounded up)."""
    r = up(np.asarray(r, dtype=float))
    return IA(-r, r)
