"""The floating-point rounding mode the interval rules rely on.

Every rule in :mod:`imubounds.interval._core` assumes the IEEE default
rounding mode, round-to-nearest: the error-free transformations (TwoSum,
FMA remainders) that give exact one-ulp directed rounding are only exact
there. Some libraries change the mode of the whole process: importing
``codac`` (2.1.2) switches it to round-upward and leaves it so (its own
rules need that). The vectorised entry points of this package therefore
check the mode (one cheap libm call) and refuse to compute in any other;
:func:`round_to_nearest` restores it, :func:`rounding_mode` and the context
manager :func:`rounding` let a caller switch temporarily (e.g. around Codac
calls in a cross-check).
"""

from __future__ import annotations

import ctypes
import ctypes.util
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import numpy as np

from imubounds.errors import AnalysisError

FE_TONEAREST = 0  #: glibc/x86-64 and aarch64 value of FE_TONEAREST

_fegetround: Any
_fesetround: Any
try:
    _libm = ctypes.CDLL(ctypes.util.find_library("m") or "libm.so.6")
    _fegetround = _libm.fegetround
    _fesetround = _libm.fesetround
    _fegetround.restype = ctypes.c_int
    _fesetround.argtypes = [ctypes.c_int]
    _fesetround.restype = ctypes.c_int
except (OSError, AttributeError):  # pragma: no cover - no C99 libm: cannot check
    _fegetround = None
    _fesetround = None


def rounding_mode() -> int:
    """Current C ``fegetround()`` value (``FE_TONEAREST`` = 0 is what we need)."""
    return FE_TONEAREST if _fegetround is None else int(_fegetround())


def round_to_nearest() -> None:
    """Set the process rounding mode back to round-to-nearest."""
    if _fesetround is not None:
        _fesetround(FE_TONEAREST)


@contextmanager
def rounding(mode: int) -> Iterator[None]:
    """Run a block in rounding ``mode`` and restore the previous mode after it."""
    old = rounding_mode()
    if _fesetround is not None:
        _fesetround(mode)
    try:
        yield
    finally:
        if _fesetround is not None:
            _fesetround(old)


@contextmanager
def nearest() -> Iterator[None]:
    """Run a block in round-to-nearest (what every interval rule needs) and restore the
    caller's rounding mode afterwards, whatever it was (e.g. round-upward after
    ``import codac``). The interval kernels of the estimator run inside it."""
    old = rounding_mode()
    if _fesetround is not None and old != FE_TONEAREST:
        _fesetround(FE_TONEAREST)
    try:
        yield
    finally:
        if _fesetround is not None and rounding_mode() != old:
            _fesetround(old)


def check_rounding() -> None:
    """Raise :class:`AnalysisError` unless the rounding mode is round-to-nearest."""
    if _fegetround is not None and _fegetround() != FE_TONEAREST:
        raise AnalysisError(
            f"floating-point rounding mode is {int(_fegetround()):#x}, not round-to-nearest "
            "(importing codac sets round-upward); call "
            "imubounds.interval.rounding.round_to_nearest() first"
        )


def up(x: Any) -> Any:
    """``x`` (floats) rounded up by one ulp: the outward rounding of an upper bound
    computed in round-to-nearest."""
    return np.nextafter(np.asarray(x, dtype=float), np.inf)


def down(x: Any) -> Any:
    """``x`` (floats) rounded down by one ulp: the outward rounding of a lower bound."""
    return np.nextafter(np.asarray(x, dtype=float), -np.inf)
