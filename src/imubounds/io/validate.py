"""The one validation layer for IMU sample streams, used by every reader.

Every static reader (CSV/TSV/Parquet, HDF5, ROS bags, ULog, NMEA, in memory
through :func:`imubounds.io.assemble.assemble_logs` and out of core through
:mod:`imubounds.io.chunked`) checks its input with these functions, so every
format gives the same errors and warnings. Each problem is either a one-line
:class:`~imubounds.errors.InputError` / :class:`~imubounds.errors.UnitsError`
naming the file, the row (or line, or message) and what to do, or a counted
warning (a string the reader appends to ``ImuLog.warnings``).

Public API
----------
:func:`check_input_path`
    Refuse, *before opening*, a path that is missing, a directory (unless
    allowed), a named pipe, a device, a socket or unreadable. Reading a pipe
    could block forever; every file option goes through this.
:func:`check_finite`
    NaN or infinite values: an error naming the first one (NaN samples are
    named as such, never as a gap).
:func:`check_time_order`
    Time stamps that repeat or go backwards. A repeated stamp with the same
    values in every channel is a *duplicated row*: an error with
    ``on_gap="refuse"``, otherwise dropped with a counted warning. A repeated
    stamp with different values, or a small step backwards (rows out of
    order), is always an error. A step backwards of more than
    :data:`RESTART_STEPS` sample periods is a *restart* (a second recording
    appended): an error unless ``on_gap="split"``, which splits there.
:func:`resolve_time_unit`
    The unit of a time column: the one given, the one its name states, or
    inferred from the spacing; a stated unit that gives an impossible rate
    (a ``time_us`` column holding seconds) is a :class:`UnitsError`.
:func:`gap_threshold`, :func:`find_gaps`, :func:`gap_summary`
    Steps longer than a multiple of the nominal period, and the one-line
    summary every reader uses.
:func:`unit_warnings`
    Magnitude checks per channel and unit: deg/s values in a rad/s column
    (beyond the range of any MEMS gyro), an accelerometer whose median
    magnitude is not near 1 g in the unit it claims.
:func:`spike_warnings`
    Isolated one-sample spikes (more than :data:`SPIKE_SIGMAS` robust
    standard deviations of the sample-to-sample difference, against both
    neighbours).
:class:`StreamChecker`
    The same checks for a log read in blocks (out of core): finiteness, time
    order, duplicates, restarts, gaps and spikes across block boundaries.

Thresholds are module constants, documented where they are defined.
"""

from __future__ import annotations

import math
import os
import re
import stat
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from imubounds.errors import InputError, OptionError, UnitsError
from imubounds.units import ACCEL_UNITS, DEG, G0, GYRO_UNITS, TIME_UNITS

__all__ = [
    "GYRO_MAX_RADS",
    "IMPOSSIBLE_RATE_HZ",
    "PLAUSIBLE_RATE_HZ",
    "RESTART_STEPS",
    "SPIKE_SIGMAS",
    "StreamChecker",
    "TimeOrder",
    "check_finite",
    "check_input_path",
    "check_on_gap",
    "check_time_order",
    "default_row_label",
    "find_gaps",
    "gap_summary",
    "gap_threshold",
    "rate_from_step",
    "resolve_time_unit",
    "spike_warnings",
    "unit_warnings",
]

RowLabel = Callable[[int], str]

#: Plausible IMU sample rates (Hz), used to infer a time unit the column does not state.
PLAUSIBLE_RATE_HZ = (0.5, 1.0e5)
#: Rates (Hz) outside which a *stated* time unit is refused: no IMU samples faster than
#: 50 kHz, and a log with less than one sample per 3 h is not an IMU log. Between
#: 1e-4 Hz and the plausible range a stated unit only gives a warning.
IMPOSSIBLE_RATE_HZ = (1.0e-4, 5.0e4)
#: A step backwards larger than this many nominal periods is a restart of the
#: recording (a second log appended), not rows out of order.
RESTART_STEPS = 100
#: Largest plausible gyro reading, rad/s: 40 rad/s is about 2300 deg/s, above the
#: +-2000 deg/s full scale of common MEMS gyros.
GYRO_MAX_RADS = 40.0
#: At rest, a gyro's median |value| (its bias, plus the Earth's rate) beyond 20 deg/s, or
#: a sample-to-sample noise (1-sigma) beyond 5.7 deg/s, fits no MEMS gyro read in rad/s
#: but fits deg/s values read as rad/s (57x): the unit-warning thresholds, rad/s.
GYRO_REST_MAX_RADS = 0.35
GYRO_NOISE_MAX_RADS = 0.1
#: A median accelerometer magnitude outside [0.5 g, 2 g] does not fit any IMU on Earth.
ACCEL_NORM_RANGE_G = (0.5, 2.0)
#: A one-sample spike: a jump of more than this many robust standard deviations of
#: the sample-to-sample difference to and back from one sample.
SPIKE_SIGMAS = 30.0
#: Samples used to estimate the robust spread for the spike check (at most, and at least
#: when a log is read in blocks and is that long).
SPIKE_ESTIMATE_SAMPLES = 200_000
SPIKE_MIN_SAMPLES = 1024
#: Smallest gap tolerance (in nominal periods) of the automatic rule.
MIN_GAP_FACTOR = 1.5
#: Multiple of the relative robust jitter added by the automatic gap rule.
JITTER_GAP_FACTOR = 4.0


def default_row_label(i: int) -> str:
    """``"data row N"`` (1 = first data row) for a 0-based row index."""
    return f"data row {i + 1}"


def _fmt(x: float) -> str:
    return f"{x:.6g}"


def _num(x: object) -> str:
    """A numpy scalar as plain text (``nan``, ``1403636579758555392``, ``0.01``)."""
    if isinstance(x, np.integer | int):
        return str(int(x))
    return repr(float(x))  # type: ignore[arg-type]


# ----------------------------------------------------------------------------- paths
_URL = re.compile(r"^[A-Za-z][A-Za-z0-9+.-]*://")


def is_url(source: str | os.PathLike[str]) -> bool:
    """Whether ``source`` is an fsspec URL (``s3://``, ``gs://``, ``https://``, ``memory://``,
    ``file://`` ...) rather than a local path."""
    return isinstance(source, str) and bool(_URL.match(source))


def check_input_path(
    path: str | os.PathLike[str],
    *,
    what: str = "IMU log",
    option: str | None = None,
    allow_dir: bool = False,
    need_dir: bool = False,
) -> Path:
    """Check an input path *without opening it*; return it as a :class:`Path`.

    Parameters
    ----------
    path:
        The path as given.
    what:
        What the file should be, for messages (``"IMU log"``, ``"noise.json"``).
    option:
        The option that named it (``"--from-noise"``), for messages.
    allow_dir:
        Accept a directory (a ROS 2 bag, a run directory).
    need_dir:
        Require a directory (a drive-layout folder).

    Raises
    ------
    InputError
        Missing, a directory (unless ``allow_dir``), a named pipe, a device, a
        socket, or not readable; also over-long or looping paths.
    """
    p = Path(path)
    who = f"{option} {p}" if option else str(p)
    if not os.fspath(path):
        raise InputError(f"{option or 'the ' + what + ' path'} is empty; give a file name")
    missing = f"{who}: cannot read it: no such file" if option else f"no such file: {p}"
    try:
        st = os.stat(p)
    except FileNotFoundError:
        if is_url(path):  # Path() has folded its "//": name it as given
            raise InputError(
                f"{path}: a URL; this command reads local files (imubounds fleet reads "
                "fsspec URLs: s3://, gs://, https://): download it first"
            ) from None
        raise InputError(f"{missing}; check the path") from None
    except NotADirectoryError:
        raise InputError(f"{missing} (a folder in that path is a file); check the path") from None
    except PermissionError:
        raise InputError(f"{who}: permission denied; check the file's permissions") from None
    except OSError as err:  # ENAMETOOLONG, ELOOP, EIO ...
        raise InputError(f"{who}: cannot be read ({err.strerror or err}); check the path") from None
    mode = st.st_mode
    if stat.S_ISDIR(mode):
        if allow_dir or need_dir:
            return p
        raise InputError(f"{who} is a directory; give the {what} file inside it")
    if need_dir:
        raise InputError(f"{who}: not a directory; give the {what} folder")
    kind = None
    if stat.S_ISFIFO(mode):
        kind = "a named pipe (FIFO)"
    elif stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        kind = "a device"
    elif stat.S_ISSOCK(mode):
        kind = "a socket"
    elif not stat.S_ISREG(mode):
        kind = "not a regular file"
    if kind is not None:
        raise InputError(
            f"{who} is {kind}, not a regular file; imubounds reads the {what} from a file "
            "(reading a stream could block forever): save it to a file first"
        )
    if not os.access(p, os.R_OK):
        raise InputError(f"{who}: permission denied; check the file's permissions")
    return p


# ----------------------------------------------------------------------------- values
def check_finite(
    values: np.ndarray,
    *,
    source: str,
    column: str,
    row_label: RowLabel = default_row_label,
    what: str = "value",
    offset: int = 0,
) -> None:
    """Raise :class:`InputError` at the first NaN or infinite value.

    ``offset`` is added to the index given to ``row_label`` (for blocks).
    """
    v = np.asarray(values)
    if v.dtype.kind not in "fc":
        return
    bad = ~np.isfinite(v)
    if not bad.any():
        return
    i = int(np.argmax(bad))
    count = int(np.count_nonzero(bad))
    x = float(v[i])
    kind = "NaN (not a number)" if math.isnan(x) else ("+inf" if x > 0 else "-inf")
    more = f" ({count} non-finite values in this column in all)" if count > 1 else ""
    raise InputError(
        f"{source}, {row_label(offset + i)}, column {column!r}: {what} is {kind}{more}; "
        "a non-finite sample is not a gap and is never interpolated: remove or repair that row"
    )


# ----------------------------------------------------------------------------- time order
@dataclass
class TimeOrder:
    """What :func:`check_time_order` found and kept.

    Attributes
    ----------
    keep:
        Boolean mask of the rows kept (``None``: all); duplicated rows are dropped.
    restarts:
        Indices (into the kept rows) where a new recording starts (``on_gap="split"``).
    notes:
        Counted warnings for the user.
    """

    keep: np.ndarray | None = None
    restarts: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    notes: list[str] = field(default_factory=list)


def _median_positive_step(d: np.ndarray) -> float:
    pos = d[d > 0]
    return float(np.median(pos)) if pos.size else 0.0


def _rows_equal(values: Sequence[np.ndarray], a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Element-wise: do rows ``a`` and ``b`` hold the same value in every channel?"""
    same = np.ones(a.shape[0], dtype=bool)
    for v in values:
        same &= np.asarray(v)[a] == np.asarray(v)[b]
    return same


def check_time_order(
    tv: np.ndarray,
    *,
    source: str,
    column: str,
    values: Sequence[np.ndarray] | None = (),
    on_gap: str = "refuse",
    row_label: RowLabel = default_row_label,
    median_step: float | None = None,
    offset: int = 0,
    can_split: bool = True,
) -> TimeOrder:
    """Check that time stamps increase strictly (see the module docstring for the rules).

    Parameters
    ----------
    tv:
        Time stamps in their native unit and dtype (integer ns stay exact).
    values:
        The channels' values, row-aligned with ``tv``, to recognise duplicated rows;
        ``None`` when they are not at hand (repeated stamps are then not judged).
    on_gap:
        ``"refuse"``, ``"split"`` or ``"ignore"`` (as :func:`imubounds.io.read_imu`).
    median_step:
        Nominal step in the native unit (default: median of the positive steps).
    offset:
        Added to row indices in messages (for blocks).
    can_split:
        False when the reader cannot split at a restart (out of core).

    Raises
    ------
    InputError
        Rows out of order, one stamp with two different samples, a duplicated
        row with ``on_gap="refuse"``, a restart unless ``on_gap="split"``.
    """
    tv = np.asarray(tv)
    if tv.size < 2:
        return TimeOrder()
    d = np.diff(tv)
    nonpos = np.flatnonzero(d <= 0)
    if nonpos.size == 0:
        return TimeOrder()
    step = median_step if median_step is not None else _median_positive_step(d)
    k = nonpos + 1  # the later row of each offending pair
    zero = d[nonpos] == 0
    if values is None:  # repeats are judged later, with the values
        keep_rows = ~zero
        nonpos, k, zero = nonpos[keep_rows], k[keep_rows], zero[keep_rows]
        values = ()
    dup = np.zeros(nonpos.size, dtype=bool)
    if values and zero.any():
        dup[zero] = _rows_equal(values, nonpos[zero], k[zero])
    conflict = zero & ~dup
    back = ~zero
    restart = np.zeros(nonpos.size, dtype=bool)
    if back.any() and step > 0:
        restart[back] = -d[nonpos[back]].astype(np.float64) > RESTART_STEPS * float(step)
    disorder = back & ~restart

    def at(j: int) -> tuple[str, str, str]:
        r = int(k[j])
        return row_label(offset + r), _num(tv[r]), _num(tv[r - 1])

    if disorder.any():
        j = int(np.argmax(disorder))
        where, now, prev = at(j)
        raise InputError(
            f"{source}, {where}, column {column!r}: time stamp {now} goes backwards (previous "
            f"{prev}); time must increase strictly: sort the rows"
        )
    if conflict.any():
        j = int(np.argmax(conflict))
        where, now, _ = at(j)
        raise InputError(
            f"{source}, {where}, column {column!r}: time stamp {now} repeats with different "
            "values (two samples at one time); time must increase strictly: remove one of them"
        )
    out = TimeOrder()
    if dup.any():
        first, count = int(np.argmax(dup)), int(np.count_nonzero(dup))
        where, now, _ = at(first)
        if on_gap == "refuse":
            raise InputError(
                f"{source}, {where}, column {column!r}: time stamp {now} repeats: a duplicated "
                f"row ({count} in all); remove them, or pass --on-gap ignore or split to drop "
                "duplicated rows with a warning"
            )
        keep = np.ones(tv.size, dtype=bool)
        keep[k[dup]] = False
        out.keep = keep
        out.notes.append(
            f"{source}: {count} duplicated row(s) (same time stamp and values as the row "
            f"before) dropped; first at {where}"
        )
    if restart.any():
        first, count = int(np.argmax(restart)), int(np.count_nonzero(restart))
        where, now, prev = at(first)
        if on_gap != "split" or not can_split:
            advice = (
                "split the file, or pass --on-gap split to analyse each recording"
                if can_split
                else "split the file (a log read out of core cannot be split)"
            )
            raise InputError(
                f"{source}, {where}, column {column!r}: time restarts (from {prev} back to "
                f"{now}): the file holds at least {count + 1} recordings; {advice}"
            )
        rows = k[restart]
        if out.keep is not None:  # index into the kept rows
            rows = np.cumsum(out.keep)[rows] - 1
        out.restarts = rows.astype(np.int64)
        out.notes.append(
            f"{source}: the time restarts {count} time(s) (first at {where}, from {prev} back "
            f"to {now}); split into {count + 1} recordings"
        )
    return out


# ----------------------------------------------------------------------------- time unit
def resolve_time_unit(
    median_step: float,
    *,
    source: str,
    column: str,
    stated: str | None = None,
    override: str | None = None,
    warnings: list[str] | None = None,
    unusual_rate: bool = False,
) -> str:
    """The unit of a time column (a key of :data:`imubounds.units.TIME_UNITS`).

    ``override`` (``--time-unit``) wins, then ``stated`` (from the column name
    or the format), else the unit in which the median step gives a plausible
    rate (:data:`PLAUSIBLE_RATE_HZ`; s if none does), with a warning.

    Raises
    ------
    UnitsError
        The given or stated unit makes the rate one no IMU log has (outside
        :data:`PLAUSIBLE_RATE_HZ`, e.g. a time column in ms labelled s), unless
        ``unusual_rate`` (``--allow-unusual-rate``) confirms it; outside
        :data:`IMPOSSIBLE_RATE_HZ` always. The message says which unit fits.
    """
    notes = warnings if warnings is not None else []
    step = float(median_step)
    if not step > 0 or not math.isfinite(step):
        return override or stated or "s"

    def rate(unit: str) -> float:
        return 1.0 / (step * TIME_UNITS[unit])

    def fitting() -> str | None:
        lo, hi = PLAUSIBLE_RATE_HZ
        return next((u for u in ("s", "ms", "us", "ns") if lo <= rate(u) <= hi), None)

    given = override or stated
    if given is not None:
        r = rate(given)
        lo, hi = IMPOSSIBLE_RATE_HZ
        whose = f"--time-unit {given}" if override else f"column {column!r} states {given}, but"
        if not lo <= r <= hi:
            alt = fitting()
            hint = (
                f"the stamps look like {alt} ({_fmt(rate(alt))} Hz): pass --time-unit {alt}"
                if alt is not None and alt != given
                else "check the time column"
            )
            raise UnitsError(
                f"{source}: {whose} its median step {_fmt(step)} {given} means "
                f"{_fmt(r)} Hz, impossible for an IMU; {hint}"
            )
        plo, phi = PLAUSIBLE_RATE_HZ
        if not plo <= r <= phi and not unusual_rate:
            alt = fitting()
            hint = (
                f"the stamps look like {alt} ({_fmt(rate(alt))} Hz): pass --time-unit {alt}"
                if alt is not None and alt != given
                else "check the time column"
            )
            raise UnitsError(
                f"{source}: {whose} its median step {_fmt(step)} {given} means "
                f"{_fmt(r)} Hz, a rate no IMU log has ({_fmt(plo)} Hz to {_fmt(phi)} Hz); "
                f"{hint}, or confirm the rate with --allow-unusual-rate"
            )
        if r < PLAUSIBLE_RATE_HZ[0]:
            alt = fitting()
            notes.append(
                f"{source}: column {column!r} in {given} gives only {_fmt(r)} Hz"
                + (f"; if the stamps are in {alt} give --time-unit {alt}" if alt else "")
            )
        return given
    unit = fitting() or "s"
    if fitting() is None and not unusual_rate:
        raise UnitsError(
            f"{source}: time column {column!r} states no unit and its median step "
            f"{_fmt(step)} gives a rate no IMU log has in s, ms, us or ns; state the unit "
            "(--time-unit) or confirm the rate with --allow-unusual-rate"
        )
    if unit != "s":
        notes.append(
            f"time column {column!r} states no unit; its spacing ({_fmt(step)}) only makes "
            f"sense in {unit}, so {unit} was assumed (use --time-unit to override)"
        )
    return unit


# ----------------------------------------------------------------------------- gaps
def gap_threshold(dt: np.ndarray, tolerance: float | None = None) -> tuple[float, float]:
    """``(median step, gap factor)`` of positive steps ``dt`` (s).

    The factor is ``tolerance`` if given, else ``max(1.5, 1 + 4 * jitter)``
    with jitter the inter-quartile range of the steps / 1.349 / median step.
    """
    pos = dt[dt > 0]
    if pos.size == 0:
        return 0.0, MIN_GAP_FACTOR if tolerance is None else float(tolerance)
    med = float(np.median(pos))
    if tolerance is not None:
        return med, float(tolerance)
    q25, q75 = np.percentile(pos, [25.0, 75.0])
    jitter = float((q75 - q25) / 1.349 / med)
    return med, max(MIN_GAP_FACTOR, 1.0 + JITTER_GAP_FACTOR * jitter)


def find_gaps(dt: np.ndarray, median_step: float, factor: float) -> np.ndarray:
    """Indices ``i`` of steps ``dt[i]`` (between rows i and i+1) longer than a gap."""
    return np.flatnonzero(dt > factor * median_step)


def gap_summary(
    source: str,
    *,
    count: int,
    factor: float,
    median_step: float,
    first_row: int,
    first_t: float,
    first_step: float,
    longest: float,
    row_label: RowLabel = default_row_label,
    complete: bool = True,
) -> str:
    """One line describing the gaps (all of them, or the first when ``complete`` is False)."""
    missing = max(round(first_step / median_step) - 1, 1)
    what = f"{count} gap(s)" if complete else "a gap"
    tail = f"; longest {_fmt(longest)} s" if complete else ""
    return (
        f"{source} has {what} in the time stamps longer than {factor:.3g} x the "
        f"{_fmt(median_step)} s sample period (first just before {row_label(first_row)}, "
        f"t={_fmt(first_t)} s: a {_fmt(first_step)} s step, about {missing} missing "
        f"sample(s){tail})"
    )


#: Relative tolerance when a time column and ``rate_hz`` are both given.
RATE_TOLERANCE = 0.01


def rate_from_step(
    median_step_s: float, rate_hz: float | None, *, source: str, column: str
) -> float:
    """The nominal rate (Hz): ``1 / median step`` to 9 digits, or ``rate_hz`` if it agrees.

    Raises
    ------
    OptionError
        ``rate_hz`` differs from the time stamps by more than 1 %.
    """
    rate = float(f"{1.0 / median_step_s:.9g}")
    if rate_hz is None:
        return rate
    if abs(median_step_s * rate_hz - 1.0) > RATE_TOLERANCE:
        raise OptionError(
            f"--rate {_fmt(rate_hz)} Hz disagrees with the time stamps of {source} "
            f"(column {column!r}: median step {_fmt(median_step_s)} s = {_fmt(rate)} Hz); "
            "drop --rate or fix it"
        )
    return float(rate_hz)


GAP_ADVICE = (
    "; choose --on-gap split (analyse contiguous segments) or --on-gap ignore "
    "(treat as contiguous), or raise --gap-tolerance"
)


# ----------------------------------------------------------------------------- plausibility
def unit_warnings(
    si: Mapping[str, np.ndarray],
    units: Mapping[str, str],
    *,
    source: str,
    assumed: Sequence[str] = (),
) -> list[str]:
    """Warnings when channel magnitudes do not fit the unit they were read in.

    ``si`` holds the values already converted to SI with ``units`` (channel ->
    unit key); ``assumed`` lists channels whose unit was assumed, not stated.
    """
    out: list[str] = []
    for c, v in si.items():
        if not c.startswith("gyro") or v.size == 0:
            continue
        peak = float(np.max(np.abs(v)))
        if peak > GYRO_MAX_RADS:
            unit = units.get(c, "rad/s")
            how = "assumed" if c in assumed else "stated"
            advice = (
                "no unit explains values this large: the channel is corrupt or scaled wrongly"
                if peak > 1e8  # beyond deg/h named rad/s
                else "the values look like deg/s (use --gyro-unit deg/s)"
                if GYRO_UNITS.get(unit) == 1.0
                else "check the unit (--gyro-unit)"
            )
            out.append(
                f"{source}: {c} reaches {peak:.3g} rad/s ({peak / DEG:.3g} deg/s) read as "
                f"{unit} ({how}), beyond the +-2000 deg/s range of MEMS gyros: {advice}"
            )
        elif GYRO_UNITS.get(units.get(c, "rad/s")) == 1.0 and v.size >= 16:
            # deg/s read as rad/s at rest: a bias or a sample-to-sample noise 57x too large
            level = float(np.median(np.abs(v)))
            noise = _robust_step_sigma(np.asarray(v, dtype=np.float64))
            if level > GYRO_REST_MAX_RADS or noise > GYRO_NOISE_MAX_RADS:
                how = "assumed" if c in assumed else "stated"
                what = (
                    f"a median of {level:.3g} rad/s ({level / DEG:.3g} deg/s)"
                    if level > GYRO_REST_MAX_RADS
                    else f"a sample-to-sample noise of {noise:.3g} rad/s ({noise / DEG:.3g} deg/s)"
                )
                out.append(
                    f"{source}: {c} read as rad/s ({how}) has {what}, beyond any MEMS gyro at "
                    "rest: the values look like deg/s (name the column "
                    f"{c}_dps or use --gyro-unit deg/s); the noise terms would be 57x too large"
                )
    acc = [f"accel_{a}" for a in "xyz"]
    if all(c in si and si[c].size for c in acc):
        x, y, z = (np.asarray(si[c], dtype=np.float64) for c in acc)
        norm = np.hypot(np.hypot(x, y), z)  # no overflow for huge values
        med_g = float(np.median(norm)) / G0
        lo, hi = ACCEL_NORM_RANGE_G
        if med_g > 0 and not lo <= med_g <= hi:
            used = {units.get(c, "m/s^2") for c in acc}
            u_used = used.pop() if len(used) == 1 else None
            guess = ""
            if u_used is not None:
                f_used = ACCEL_UNITS[u_used]
                # if the true unit is u, the median magnitude read as u_used is f_used/f_u g
                best = min(
                    ACCEL_UNITS, key=lambda u: abs(math.log(med_g * ACCEL_UNITS[u] / f_used))
                )
                if best != u_used and ACCEL_UNITS[best] != f_used:
                    guess = f"; the values look like {best} (use --accel-unit {best})"
            how = "assumed" if any(c in assumed for c in acc) else "stated"
            out.append(
                f"{source}: the median accelerometer magnitude is {med_g:.3g} g read as "
                f"{u_used or 'the stated units'} ({how}), but an IMU on Earth measures about "
                f"1 g{guess or '; check the unit (--accel-unit)'}"
            )
    return out


def _robust_step_sigma(v: np.ndarray) -> float:
    d = np.diff(np.asarray(v[: SPIKE_ESTIMATE_SAMPLES + 1], dtype=np.float64))
    if d.size < 16:
        return 0.0
    mad = float(np.median(np.abs(d - np.median(d))))
    return 1.4826 * mad


def _spike_index(v: np.ndarray, sigma: float, k: float) -> np.ndarray:
    """Indices i (1..n-2) of isolated one-sample spikes of ``v``."""
    if v.size < 3 or not sigma > 0:
        return np.zeros(0, dtype=np.int64)
    d = np.diff(v)
    big = np.abs(d) > k * sigma
    i = np.flatnonzero(big[:-1] & big[1:])  # both steps large: the other tests on those only
    up, down = d[i], d[i + 1]
    hit = (np.sign(up) != np.sign(down)) & (
        np.abs(v[i + 2] - v[i]) < 0.5 * np.minimum(np.abs(up), np.abs(down))
    )
    return i[hit] + 1


def _spike_note(
    source: str, column: str, count: int, first: str, value: float, sigma: float, k: float
) -> str:
    unit = "rad/s" if column.startswith("gyro") else "m/s^2"
    return (
        f"{source}: {column} has {count} isolated one-sample spike(s) larger than {k:g} "
        f"robust standard deviations of the sample-to-sample change (first at {first}: "
        f"{_fmt(value)} {unit}, typical change {_fmt(sigma)} {unit}); they inflate the "
        "white-noise estimate: check the logger or remove those rows"
    )


def spike_warnings(
    si: Mapping[str, np.ndarray],
    *,
    source: str,
    t: np.ndarray | None = None,
    row_label: RowLabel = default_row_label,
    sigmas: float = SPIKE_SIGMAS,
) -> list[str]:
    """One counted warning per channel with isolated one-sample spikes."""
    out: list[str] = []
    for c, v in si.items():
        v = np.asarray(v, dtype=np.float64)
        sigma = _robust_step_sigma(v)
        idx = _spike_index(v, sigma, sigmas)
        if idx.size:
            i = int(idx[0])
            where = row_label(i) + (f", t={_fmt(float(t[i]))} s" if t is not None else "")
            out.append(_spike_note(source, c, int(idx.size), where, float(v[i]), sigma, sigmas))
    return out


# ----------------------------------------------------------------------------- streaming
class StreamChecker:
    """The checks of this module for a log read in consecutive blocks.

    Parameters
    ----------
    source:
        File name for messages.
    column:
        Name of the time column (``None``: no time column, stamps from the rate).
    time_factor:
        Factor from the native time unit to s.
    median_step:
        Nominal step in the native unit (from the first rows).
    gap_factor:
        A step longer than ``gap_factor * median_step`` is a gap.
    on_gap:
        ``"refuse"`` (raise at the first gap), ``"ignore"`` (count, warn at the
        end); ``"split"`` is not possible out of core and raises at the first gap.
    row_label:
        Formats a global 0-based data row index.

    :meth:`feed` takes each block (time in the native unit, channels in SI) and
    returns a mask of the rows to keep (``None``: all); :meth:`finish` returns
    the counted warnings.
    """

    def __init__(
        self,
        source: str,
        *,
        column: str | None,
        time_factor: float = 1.0,
        median_step: float = 0.0,
        gap_factor: float = MIN_GAP_FACTOR,
        on_gap: str = "refuse",
        row_label: RowLabel = default_row_label,
    ) -> None:
        self.source = source
        self.column = column
        self.time_factor = float(time_factor)
        self.median_step = float(median_step)
        self.gap_factor = float(gap_factor)
        self.on_gap = on_gap
        self.row_label = row_label
        self.rows = 0  # rows fed so far (before dropping)
        self._last_t: np.ndarray | None = None
        self._last_v: dict[str, np.ndarray] = {}
        self._tail: dict[str, tuple[np.ndarray, np.ndarray]] = {}  # last two kept samples, rows
        self._pending: dict[str, tuple[np.ndarray, np.ndarray]] = {}  # before the spread is known
        self._sigma: dict[str, float] = {}
        self._spikes: dict[str, tuple[int, int, float]] = {}  # count, first row, its value
        self._dups = 0
        self._first_dup: str | None = None
        self._gaps = 0
        self._first_gap: tuple[int, float, float] | None = None
        self._longest = 0.0

    def feed(self, t: np.ndarray | None, values: Mapping[str, np.ndarray]) -> np.ndarray | None:
        """Check one block; return the mask of rows to keep (``None``: all)."""
        n = len(next(iter(values.values()))) if values else (0 if t is None else len(t))
        row0 = self.rows
        for c, v in values.items():
            check_finite(v, source=self.source, column=c, row_label=self.row_label, offset=row0)
        keep = None
        if t is not None and self.column is not None and n:
            t = np.asarray(t)
            check_finite(t, source=self.source, column=self.column, row_label=self.row_label,
                         what="time", offset=row0)
            keep = self._time(t, values, row0)
        self.rows += n
        self._spike_block(values, keep, row0)
        return keep

    def _time(
        self, t: np.ndarray, values: Mapping[str, np.ndarray], row0: int
    ) -> np.ndarray | None:
        has_prev = self._last_t is not None
        tt: np.ndarray = t
        vv = [np.asarray(v) for v in values.values()]
        off = row0
        if self._last_t is not None:
            tt = np.concatenate((self._last_t, t))
            vv = [np.concatenate((self._last_v[c], np.asarray(v))) for c, v in values.items()]
            off = row0 - 1
        order = check_time_order(tt, source=self.source, column=str(self.column), values=vv,
                                 on_gap=self.on_gap, row_label=self.row_label,
                                 median_step=self.median_step or None, offset=off,
                                 can_split=False)
        keep_all = order.keep
        if order.notes:
            dropped = int(np.count_nonzero(~keep_all)) if keep_all is not None else 0
            if self._first_dup is None and keep_all is not None:
                self._first_dup = self.row_label(off + int(np.argmax(~keep_all)))
            self._dups += dropped
        kept_t = tt if keep_all is None else tt[keep_all]
        rows = np.arange(off, off + tt.size) if keep_all is None else np.flatnonzero(keep_all) + off
        dt = np.diff(kept_t).astype(np.float64) * self.time_factor
        if self.median_step > 0:
            med = self.median_step * self.time_factor
            self._rate_change(dt, med, rows, kept_t)
            gaps = find_gaps(dt, med, self.gap_factor)
            if gaps.size:
                g = int(gaps[0])
                first = (int(rows[g + 1]), float(kept_t[g + 1]) * self.time_factor, float(dt[g]))
                if self.on_gap != "ignore":
                    msg = gap_summary(self.source, count=1, factor=self.gap_factor,
                                      median_step=med, first_row=first[0], first_t=first[1],
                                      first_step=first[2], longest=first[2],
                                      row_label=self.row_label, complete=False)
                    if self.on_gap == "split":
                        raise InputError(
                            msg + "; --on-gap split is not available for a log read out of "
                            "core: use --on-gap ignore, raise --gap-tolerance, or split the file"
                        )
                    raise InputError(msg + GAP_ADVICE)
                if self._first_gap is None:
                    self._first_gap = first
                self._gaps += int(gaps.size)
                self._longest = max(self._longest, float(dt[gaps].max()))
        self._last_t = t[-1:].copy()
        self._last_v = {c: np.asarray(v)[-1:].copy() for c, v in values.items()}
        if keep_all is None:
            return None
        return keep_all[1:] if has_prev else keep_all

    def _rate_change(self, dt: np.ndarray, med: float, rows: np.ndarray, t: np.ndarray) -> None:
        """Refuse a change of the sample rate (:mod:`imubounds.io.rates`): inside this
        block, or between the first rows' step and this block's."""
        from imubounds.io import rates

        changes = rates.find_rate_changes(dt)
        if not changes and dt.size >= rates.MIN_RUN_BLOCKS * 16:
            nom = rates.nominal_step(dt)
            if abs(nom / med - 1.0) > rates.RATE_CHANGE_REL:
                changes = [rates.RateChange(0, med, nom)]
        if changes:
            c = changes[0]
            raise InputError(
                rates.describe(self.source, c, self.row_label(int(rows[c.row])),
                               float(t[c.row]) * self.time_factor)  # fmt: skip
                + "; a log read out of core cannot be split: split the file at the change"
            )

    def _spike_block(
        self, values: Mapping[str, np.ndarray], keep: np.ndarray | None, row0: int
    ) -> None:
        for c, v in values.items():
            v = np.asarray(v, dtype=np.float64)
            rows = np.arange(row0, row0 + v.size)
            if keep is not None:
                v, rows = v[keep], rows[keep]
            if c not in self._sigma:  # gather enough samples for the robust spread first
                pv, pr = self._pending.get(c, (np.zeros(0), np.zeros(0, dtype=np.int64)))
                pv, pr = np.concatenate((pv, v)), np.concatenate((pr, rows))
                if pv.size < SPIKE_MIN_SAMPLES:
                    self._pending[c] = (pv, pr)
                    continue
                self._pending.pop(c, None)
                self._sigma[c] = _robust_step_sigma(pv)
                v, rows = pv, pr
            self._spikes_in(c, v, rows)

    def _spikes_in(self, c: str, v: np.ndarray, rows: np.ndarray) -> None:
        tail_v, tail_r = self._tail.get(c, (np.zeros(0), np.zeros(0, dtype=np.int64)))
        vv = np.concatenate((tail_v, v))
        rr = np.concatenate((tail_r, rows))
        idx = _spike_index(vv, self._sigma[c], SPIKE_SIGMAS)
        if idx.size:
            count, row, value = self._spikes.get(c, (0, int(rr[idx[0]]), float(vv[idx[0]])))
            self._spikes[c] = (count + int(idx.size), row, value)
        self._tail[c] = (vv[-2:].copy(), rr[-2:].copy())

    def finish(self) -> list[str]:
        """Counted warnings: duplicated rows dropped, gaps ignored, spikes."""
        for c, (pv, pr) in list(self._pending.items()):  # a log shorter than the estimate
            self._sigma[c] = _robust_step_sigma(pv)
            self._spikes_in(c, pv, pr)
        self._pending.clear()
        out: list[str] = []
        if self._dups:
            out.append(
                f"{self.source}: {self._dups} duplicated row(s) (same time stamp and values as "
                f"the row before) dropped; first at {self._first_dup}"
            )
        if self._gaps and self._first_gap is not None:
            r, t0, step = self._first_gap
            out.append(
                gap_summary(self.source, count=self._gaps, factor=self.gap_factor,
                            median_step=self.median_step * self.time_factor, first_row=r,
                            first_t=t0, first_step=step, longest=self._longest,
                            row_label=self.row_label)
                + "; ignored (--on-gap ignore): treated as contiguous"
            )
        for c, (count, row, value) in self._spikes.items():
            out.append(_spike_note(self.source, c, count, self.row_label(row), value,
                                   self._sigma[c], SPIKE_SIGMAS))
        return out


def check_on_gap(on_gap: str) -> None:
    """Raise :class:`OptionError` for an unknown ``on_gap`` policy."""
    if on_gap not in ("refuse", "split", "ignore"):
        raise OptionError(f"--on-gap must be one of refuse, split, ignore, got {on_gap!r}")
