"""Vectorised interval arrays over the compiled scalar rules.

:class:`IntervalArray` holds two float64 arrays ``lo`` and ``hi`` of the same
shape. All arithmetic broadcasts like numpy and runs the scalar rules of
:mod:`imubounds.interval._core` in compiled loops, so an element of an array
result is bit-for-bit the scalar result. The empty interval is stored as
``lo = +inf, hi = -inf`` and propagates through every operation.

Plain floats and ints mixed into the arithmetic are taken as exact binary
values (``0.1`` means the double nearest to 0.1); a caller that means a
decimal number widens it itself (the estimator widens its inputs by their
stated bounds, which dwarf one ulp).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from imubounds.errors import OptionError
from imubounds.interval import _core as c
from imubounds.interval import _vec as v
from imubounds.interval.rounding import check_rounding


def _flat(a: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=np.float64).reshape(-1)


class IntervalArray:
    """An array of closed real intervals ``[lo, hi]`` (empty = ``(+inf, -inf)``).

    Parameters
    ----------
    lo, hi : array_like
        Lower and upper endpoints (any common unit; the library uses SI).
        ``hi`` defaults to ``lo`` (degenerate intervals). Pairs with
        ``lo = +inf, hi = -inf`` are empty intervals.

    Raises
    ------
    OptionError
        If an endpoint is NaN, if ``lo > hi`` (other than the empty pair), or
        if an interval is ``[+inf, +inf]`` or ``[-inf, -inf]``.
    """

    __slots__ = ("lo", "hi")
    __array_priority__ = 1000  # numpy scalars/arrays defer to our operators

    lo: np.ndarray
    hi: np.ndarray

    def __init__(self, lo: ArrayLike, hi: ArrayLike | None = None) -> None:
        lo_a = np.asarray(lo, dtype=np.float64)
        hi_a = lo_a if hi is None else np.asarray(hi, dtype=np.float64)
        lo_a, hi_a = np.broadcast_arrays(lo_a, hi_a)
        lo_a = np.array(lo_a, dtype=np.float64)
        hi_a = np.array(hi_a, dtype=np.float64)
        if np.isnan(lo_a).any() or np.isnan(hi_a).any():
            raise OptionError("interval endpoints must not be NaN; use IntervalArray.empty()")
        is_e = (lo_a == np.inf) & (hi_a == -np.inf)
        bad = ~is_e & ((lo_a > hi_a) | (lo_a == np.inf) | (hi_a == -np.inf))
        if bad.any():
            i = int(np.flatnonzero(bad.reshape(-1))[0])
            raise OptionError(
                f"interval {i} has lo={lo_a.reshape(-1)[i]!r} > hi={hi_a.reshape(-1)[i]!r} "
                "or an infinite degenerate bound; give lo <= hi (empty: lo=+inf, hi=-inf)"
            )
        self.lo = lo_a
        self.hi = hi_a

    # -- construction -----------------------------------------------------
    @classmethod
    def _raw(cls, lo: np.ndarray, hi: np.ndarray) -> IntervalArray:
        obj = cls.__new__(cls)
        obj.lo = lo
        obj.hi = hi
        return obj

    @classmethod
    def empty(cls, shape: int | tuple[int, ...] = ()) -> IntervalArray:
        """Array of empty intervals."""
        return cls._raw(np.full(shape, np.inf), np.full(shape, -np.inf))

    @classmethod
    def entire(cls, shape: int | tuple[int, ...] = ()) -> IntervalArray:
        """Array of ``(-inf, +inf)``."""
        return cls._raw(np.full(shape, -np.inf), np.full(shape, np.inf))

    @classmethod
    def coerce(cls, x: Any) -> IntervalArray:
        """An :class:`IntervalArray` as is; numbers/arrays as degenerate intervals."""
        if isinstance(x, IntervalArray):
            return x
        return cls(x)

    # -- container protocol ------------------------------------------------
    @property
    def shape(self) -> tuple[int, ...]:
        return self.lo.shape

    @property
    def size(self) -> int:
        return int(self.lo.size)

    @property
    def ndim(self) -> int:
        return self.lo.ndim

    def __len__(self) -> int:
        return len(self.lo)

    def __getitem__(self, idx: Any) -> IntervalArray:
        return IntervalArray._raw(np.asarray(self.lo[idx]), np.asarray(self.hi[idx]))

    def __setitem__(self, idx: Any, value: Any) -> None:
        o = IntervalArray.coerce(value)
        self.lo[idx] = o.lo
        self.hi[idx] = o.hi

    def reshape(self, *shape: Any) -> IntervalArray:
        return IntervalArray._raw(self.lo.reshape(*shape), self.hi.reshape(*shape))

    def copy(self) -> IntervalArray:
        return IntervalArray._raw(self.lo.copy(), self.hi.copy())

    def __iter__(self) -> Iterator[IntervalArray]:
        for i in range(len(self)):
            yield self[i]

    def __repr__(self) -> str:
        if self.ndim == 0:
            if self.is_empty():
                return "IntervalArray(empty)"
            return f"IntervalArray([{float(self.lo)!r}, {float(self.hi)!r}])"
        return f"IntervalArray(lo={self.lo!r}, hi={self.hi!r})"

    def __eq__(self, other: object) -> bool:
        """True if all intervals are identical sets (all empties compare equal)."""
        if not isinstance(other, IntervalArray) or other.shape != self.shape:
            return False
        e1 = self.is_empty()
        e2 = other.is_empty()
        same = (self.lo == other.lo) & (self.hi == other.hi)
        return bool(np.all((e1 & e2) | (~e1 & ~e2 & same)))

    __hash__ = None  # type: ignore[assignment]

    def to_tuples(self) -> list[tuple[float, float]]:
        """List of ``(lo, hi)`` pairs in C order."""
        return list(zip(self.lo.reshape(-1).tolist(), self.hi.reshape(-1).tolist(), strict=True))

    # -- element-wise machinery ------------------------------------------
    def _unary(self, f: Callable[..., tuple[np.ndarray, np.ndarray]]) -> IntervalArray:
        check_rounding()
        lo, hi = f(_flat(self.lo), _flat(self.hi))
        return IntervalArray._raw(lo.reshape(self.shape), hi.reshape(self.shape))

    def _binary(
        self, other: Any, f: Callable[..., tuple[np.ndarray, np.ndarray]], swap: bool = False
    ) -> IntervalArray:
        check_rounding()
        o = IntervalArray.coerce(other)
        a, b = (o, self) if swap else (self, o)
        shape = np.broadcast_shapes(a.lo.shape, b.lo.shape)

        def flat(x: np.ndarray) -> np.ndarray:
            # broadcast_to (a read-only view, copied by _flat) where the shape differs:
            # numba warns on the views np.broadcast_arrays returns
            return _flat(x if x.shape == shape else np.broadcast_to(x, shape))

        lo, hi = f(flat(a.lo), flat(a.hi), flat(b.lo), flat(b.hi))
        return IntervalArray._raw(lo.reshape(shape), hi.reshape(shape))

    # -- arithmetic ---------------------------------------------------------
    def __add__(self, o: Any) -> IntervalArray:
        return self._binary(o, v.v_add)

    def __radd__(self, o: Any) -> IntervalArray:
        return self._binary(o, v.v_add, swap=True)

    def __sub__(self, o: Any) -> IntervalArray:
        return self._binary(o, v.v_sub)

    def __rsub__(self, o: Any) -> IntervalArray:
        return self._binary(o, v.v_sub, swap=True)

    def __mul__(self, o: Any) -> IntervalArray:
        return self._binary(o, v.v_mul)

    def __rmul__(self, o: Any) -> IntervalArray:
        return self._binary(o, v.v_mul, swap=True)

    def __truediv__(self, o: Any) -> IntervalArray:
        return self._binary(o, v.v_div)

    def __rtruediv__(self, o: Any) -> IntervalArray:
        return self._binary(o, v.v_div, swap=True)

    def __neg__(self) -> IntervalArray:
        return self._unary(v.v_neg)

    def __pos__(self) -> IntervalArray:
        return self

    def __abs__(self) -> IntervalArray:
        return self._unary(v.v_absval)

    def __pow__(self, p: int) -> IntervalArray:
        """Only ``**2`` (tight square) and ``**0.5`` (square root) are supported."""
        if p == 2:
            return self._unary(v.v_sqr)
        if p == 0.5:
            return self._unary(v.v_sqrt)
        raise OptionError(f"interval power {p!r} is not supported; use **2 or **0.5")

    def __and__(self, o: Any) -> IntervalArray:
        """Intersection."""
        return self._binary(o, v.v_inter)

    __rand__ = __and__

    def __or__(self, o: Any) -> IntervalArray:
        """Hull (smallest interval containing both)."""
        return self._binary(o, v.v_hull)

    __ror__ = __or__

    # -- set functions ------------------------------------------------------
    def intersection(self, o: Any) -> IntervalArray:
        """Intersection with ``o``."""
        return self & o

    def hull(self, o: Any) -> IntervalArray:
        """Hull with ``o``."""
        return self | o

    def is_empty(self) -> np.ndarray:
        """Boolean array: True where the interval is empty."""
        return ~(self.lo <= self.hi)

    def width(self) -> np.ndarray:
        """``hi - lo`` rounded up; NaN where empty."""
        return v.v_width(_flat(self.lo), _flat(self.hi)).reshape(self.shape)

    def mid(self) -> np.ndarray:
        """A midpoint inside each interval; NaN where empty."""
        return v.v_mid(_flat(self.lo), _flat(self.hi)).reshape(self.shape)

    def radius(self) -> np.ndarray:
        """Radius about :meth:`mid`, rounded up; NaN where empty."""
        return v.v_radius(_flat(self.lo), _flat(self.hi)).reshape(self.shape)

    def contains(self, x: ArrayLike) -> np.ndarray:
        """Boolean array: True where the number ``x`` lies in the interval."""
        xa = np.asarray(x, dtype=np.float64)
        return (self.lo <= xa) & (xa <= self.hi)

    def subset(self, o: Any) -> np.ndarray:
        """Boolean array: True where ``self`` is a subset of ``o`` (empty is a subset)."""
        other = IntervalArray.coerce(o)
        e = self.is_empty()
        return e | ((other.lo <= self.lo) & (self.hi <= other.hi))


# -- module-level functions ---------------------------------------------------


def _u(x: Any, f: Callable[..., tuple[np.ndarray, np.ndarray]]) -> IntervalArray:
    return IntervalArray.coerce(x)._unary(f)


def sqr(x: Any) -> IntervalArray:
    """``x**2`` (tight on intervals containing 0)."""
    return _u(x, v.v_sqr)


def sqrt(x: Any) -> IntervalArray:
    """``sqrt(x & [0, inf))``; empty where ``x < 0``."""
    return _u(x, v.v_sqrt)


def sin(x: Any) -> IntervalArray:
    """``sin(x)`` of an angle in rad; exactly +-1 at interior extrema."""
    return _u(x, v.v_sin)


def cos(x: Any) -> IntervalArray:
    """``cos(x)`` of an angle in rad; exactly +-1 at interior extrema."""
    return _u(x, v.v_cos)


def atan2(y: Any, x: Any) -> IntervalArray:
    """``atan2(y, x)`` in rad, within ``[-pi, pi]`` (origin excluded)."""
    return IntervalArray.coerce(y)._binary(x, v.v_atan2)


def intersection(a: Any, b: Any) -> IntervalArray:
    """Element-wise intersection."""
    return IntervalArray.coerce(a) & b


def hull(a: Any, b: Any) -> IntervalArray:
    """Element-wise hull."""
    return IntervalArray.coerce(a) | b


def I(lo: Any, hi: Any = None) -> IntervalArray:  # noqa: E743 - conventional name
    """Convenience constructor: ``I(1, 2)``; ``I(x)`` is the point ``[x, x]``.

    Numbers are exact binary values (``0.1`` is the double nearest to 0.1).
    """
    a = IntervalArray.coerce(lo)
    if hi is None:
        return a
    b = IntervalArray.coerce(hi)
    if float(b.hi) < float(a.lo):
        raise OptionError(f"I({lo!r}, {hi!r}): lower end is above the upper end")
    return IntervalArray._raw(np.asarray(a.lo), np.asarray(b.hi))


def pi() -> IntervalArray:
    """``[pi]``: the two doubles around pi."""
    return IntervalArray._raw(np.asarray(c.PI_LO), np.asarray(c.PI_HI))
