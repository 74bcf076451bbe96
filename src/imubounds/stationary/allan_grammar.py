"""The command-line grammar of the Allan-family options (estimator names, τ grids).

Light on purpose (no numpy, scipy or numba): the command line builds its parser and
reads ``--tau`` with it while the analysis modules are imported in another thread.
:mod:`imubounds.stationary.allan` re-exports every name.
"""

from __future__ import annotations

import math

from imubounds.errors import OptionError

#: Estimator names accepted by :func:`allan`.
ESTIMATORS: tuple[str, ...] = (
    "overlapping",
    "non-overlapping",
    "modified",
    "hadamard",
    "non-overlapping-hadamard",
    "total",
)
#: The τ grid of a characterisation (``imubounds static``, ``fleet``, ``characterize``):
#: 40 log-spaced points. On the bundled ADIS16405 extract it resolves gyro_z's B (25.1 deg/h;
#: the fit of the whole 2.78 h log gives 25.7-27.8 deg/h) where the octave grid leaves an
#: upper bound of 63.8 deg/h; the other terms agree within a few per cent, at the same CPU
#: time (docs/static-method.md, "The τ grid").
DEFAULT_TAU_POINTS = 40
DEFAULT_TAU_GRID = f"points:{DEFAULT_TAU_POINTS}"
TAU_GRAMMAR = (
    "'octave' (m = 1, 2, 4, ...), 'decade' (m = 1, 2, 5, 10, ...), 'all' (every m), "
    "'points:K' (K log-spaced points) or averaging times in seconds ending in 's', "
    "e.g. '1,10,100s'"
)


def parse_tau_spec(text: str) -> str | int | list[float]:
    """Read a τ-grid specification in the command-line grammar.

    ``octave`` | ``decade`` | ``all`` | ``points:K`` (K log-spaced points) |
    ``1,10,100s`` (averaging times in s; the list ends in ``s``). A bare number
    is refused because it is ambiguous (a count or seconds?).

    Returns what :func:`tau_grid` takes: the keyword, an int (points) or a
    list of τ in s.
    """
    raw = str(text)
    t = raw.strip().lower()
    if t in ("octave", "decade", "all"):
        return t
    if t.startswith("points:"):
        body = t[len("points:") :].strip()
        if not body.isdigit() or int(body) < 2:
            raise OptionError(f"tau grid {raw!r}: points:K needs a whole number K >= 2")
        return int(body)
    seconds = t.endswith("s")
    items = [v.strip() for v in (t[:-1] if seconds else t).split(",")]
    try:
        values = [float(v) for v in items]
    except ValueError:
        if seconds:
            raise OptionError(
                f"tau grid {raw!r}: cannot read the seconds; write e.g. '1,10,100s'"
            ) from None
        raise OptionError(f"unknown tau grid {raw!r}: use {TAU_GRAMMAR}") from None
    if not values or any(not (math.isfinite(v) and v > 0) for v in values):
        raise OptionError(
            f"tau grid {raw!r}: every tau must be a positive, finite number of seconds"
        )
    if seconds:
        return values
    raise OptionError(
        f"tau grid {raw!r} is ambiguous: write points:K for K log-spaced points (K >= 2) or "
        f"{t}s for averaging times in seconds"
    )
