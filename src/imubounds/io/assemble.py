"""Format-independent part of reading: options, checks, units, gaps, segments.

Every format reader (CSV, Parquet, and later ROS bags, ULog, HDF5, NMEA)
extracts raw numbers and hands them to :func:`assemble_logs`, which converts
to SI, checks the time stamps, finds gaps and applies the ``on_gap`` policy.
That way every format gives the same errors and warnings.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from imubounds.errors import InputError, OptionError
from imubounds.io.log import IMU_CHANNELS, ImuLog
from imubounds.units import ACCEL_UNITS, GYRO_UNITS, TIME_UNITS

from .columns import MAP_KEYS, normalise_unit
from .rates import describe as describe_rate_change
from .rates import find_rate_changes
from .validate import (
    GAP_ADVICE,
    JITTER_GAP_FACTOR,
    MIN_GAP_FACTOR,
    PLAUSIBLE_RATE_HZ,
    RATE_TOLERANCE,
    check_finite,
    check_on_gap,
    check_time_order,
    default_row_label,
    find_gaps,
    gap_summary,
    gap_threshold,
    rate_from_step,
    resolve_time_unit,
    spike_warnings,
    unit_warnings,
)

OnGap = Literal["refuse", "split", "ignore"]
ON_GAP_CHOICES: tuple[str, ...] = ("refuse", "split", "ignore")
__all__ = [
    "JITTER_GAP_FACTOR",
    "MIN_GAP_FACTOR",
    "ON_GAP_CHOICES",
    "PLAUSIBLE_RATE_HZ",
    "RATE_TOLERANCE",
    "RawChannel",
    "RawTime",
    "ReadOptions",
    "assemble_logs",
    "default_row_label",
]


@dataclass(frozen=True)
class ReadOptions:
    """Options shared by every reader (see :func:`imubounds.io.read_imu`).

    Attributes
    ----------
    rate_hz:
        Sample rate in Hz when the file has no time column (or to check it).
    columns:
        ``{canonical: source_column}`` overriding name recognition.
    gyro_unit, accel_unit, time_unit:
        Unit overrides (keys or synonyms of ``units.GYRO_UNITS`` etc.).
    gap_tolerance:
        A time step longer than ``gap_tolerance`` x the nominal period is a
        gap. ``None``: automatic, ``max(1.5, 1 + 4 * jitter)`` where jitter is
        the inter-quartile range of the steps / 1.349 / median step.
    on_gap:
        ``"refuse"`` (raise), ``"split"`` (segments) or ``"ignore"`` (warn).
    channels:
        Restrict to these canonical channels.
    unusual_rate:
        Accept a sample rate outside :data:`~imubounds.io.validate.PLAUSIBLE_RATE_HZ`
        (0.5 Hz to 100 kHz; ``--allow-unusual-rate``). Without it such a rate (a time
        column in ms or us labelled s) is an error.
    """

    rate_hz: float | None = None
    columns: Mapping[str, str] | None = None
    gyro_unit: str | None = None
    accel_unit: str | None = None
    time_unit: str | None = None
    gap_tolerance: float | None = None
    on_gap: OnGap = "refuse"
    channels: tuple[str, ...] | None = None
    extra: dict[str, object] = field(default_factory=dict)
    unusual_rate: bool = False

    def validated(self) -> ReadOptions:
        """Check every option; returns a copy with units normalised.

        Raises
        ------
        OptionError
            For any invalid option value.
        """
        if self.rate_hz is not None:
            r = float(self.rate_hz)
            if not np.isfinite(r) or r <= 0:
                raise OptionError(f"--rate must be a positive number of Hz, got {self.rate_hz!r}")
            lo, hi = PLAUSIBLE_RATE_HZ
            if not lo <= r <= hi and not self.unusual_rate:
                raise OptionError(
                    f"--rate {r:g} Hz is a rate no IMU log has ({lo:g} Hz to {hi:g} Hz); if it "
                    "is right, confirm it with --allow-unusual-rate (unusual_rate=True)"
                )
        check_on_gap(self.on_gap)
        if self.gap_tolerance is not None:
            g = float(self.gap_tolerance)
            if not np.isfinite(g) or g <= 1.0:
                raise OptionError(
                    "--gap-tolerance is a multiple of the sample period and must be > 1, "
                    f"got {self.gap_tolerance!r}"
                )
        units: dict[str, str | None] = {}
        for name, kind, table in (
            ("gyro_unit", "gyro", GYRO_UNITS),
            ("accel_unit", "accel", ACCEL_UNITS),
            ("time_unit", "time", TIME_UNITS),
        ):
            value = getattr(self, name)
            if value is None:
                units[name] = None
                continue
            key = normalise_unit(str(value), kind)
            if key is None:
                raise OptionError(
                    f"--{name.replace('_', '-')} {value!r} is not known; use one of "
                    f"{', '.join(table)}"
                )
            units[name] = key
        channels = None
        if self.channels is not None:
            channels = tuple(self.channels)
            bad = [c for c in channels if c not in IMU_CHANNELS]
            if bad or not channels:
                raise OptionError(
                    f"unknown channel(s) {', '.join(map(repr, bad)) or '(none given)'}; "
                    f"use names from {', '.join(IMU_CHANNELS)}"
                )
        columns = None
        if self.columns is not None:
            columns = dict(self.columns)
            bad = [k for k in columns if k not in MAP_KEYS]
            if bad:
                raise OptionError(
                    f"columns key(s) {', '.join(map(repr, bad))} not known; "
                    f"use {', '.join(MAP_KEYS)}"
                )
        return ReadOptions(
            rate_hz=None if self.rate_hz is None else float(self.rate_hz),
            columns=columns,
            gyro_unit=units["gyro_unit"],
            accel_unit=units["accel_unit"],
            time_unit=units["time_unit"],
            gap_tolerance=None if self.gap_tolerance is None else float(self.gap_tolerance),
            on_gap=self.on_gap,
            channels=channels,
            extra=dict(self.extra),
            unusual_rate=bool(self.unusual_rate),
        )


@dataclass
class RawChannel:
    """A channel as read: values in the input unit and the unit the name stated."""

    values: np.ndarray
    unit: str | None
    source: str


@dataclass
class RawTime:
    """A time column as read (numeric, any dtype) and the unit its name stated."""

    values: np.ndarray
    unit: str | None
    source: str
    layout: str = "generic"


def _fmt(x: float) -> str:
    return f"{x:.6g}"


def assemble_logs(
    source: str,
    time: RawTime | None,
    channels: Mapping[str, RawChannel],
    opts: ReadOptions,
    *,
    row_label: Callable[[int], str] = default_row_label,
    notes: Sequence[str] = (),
    frame: str = "unknown",
) -> list[ImuLog]:
    """Turn raw columns into SI :class:`ImuLog` segments, with all checks.

    The checks are those of :mod:`imubounds.io.validate`: finite values, time
    order (duplicated rows, restarts), time unit, gaps and the ``on_gap``
    policy, unit plausibility and spikes (warnings).

    Parameters
    ----------
    source:
        File name for messages and ``ImuLog.source``.
    time:
        The time column or ``None`` (then ``opts.rate_hz`` is required).
    channels:
        Canonical channel name -> raw values in the input unit.
    opts:
        Validated options.
    row_label:
        Formats a 0-based data row index for messages (e.g. a file line).
    notes:
        Warnings from the format reader to pass on.
    frame:
        Body frame convention if the format knows it.

    Returns
    -------
    list of ImuLog
        One log, or one per contiguous segment when ``opts.on_gap == "split"``.

    Raises
    ------
    InputError, UnitsError, OptionError
        Bad values, bad time stamps, gaps (``on_gap="refuse"``), inconsistent rate.
    """
    warnings: list[str] = list(notes)
    if not channels:
        raise InputError(f"no IMU channel in {source}")
    n = len(next(iter(channels.values())).values)
    if n == 0:
        raise InputError(f"{source} has a header but no data rows; give a file with samples")

    # --- units and values -------------------------------------------------
    out: dict[str, np.ndarray] = {}
    input_units: dict[str, str] = {}
    assumed: list[str] = []
    for name in [c for c in IMU_CHANNELS if c in channels]:
        raw = channels[name]
        kind = name.split("_")[0]
        table = GYRO_UNITS if kind == "gyro" else ACCEL_UNITS
        override = opts.gyro_unit if kind == "gyro" else opts.accel_unit
        if override is not None:
            unit = override
            if raw.unit is not None and raw.unit != override:
                warnings.append(
                    f"column {raw.source!r} says {raw.unit} but --{kind}-unit {override} was used"
                )
        elif raw.unit is not None:
            unit = raw.unit
        else:
            unit = "rad/s" if kind == "gyro" else "m/s^2"
            assumed.append(name)
        vals = np.asarray(raw.values)
        if vals.dtype.kind not in "fiu":
            raise InputError(f"column {raw.source!r} of {source} is not numeric")
        vals = vals.astype(np.float64, copy=False)
        check_finite(vals, source=source, column=raw.source, row_label=row_label)
        out[name] = np.ascontiguousarray(vals * table[unit], dtype=np.float64)
        input_units[name] = unit
    if assumed:
        warnings.append(
            f"units not stated for {', '.join(assumed)}: assumed rad/s (gyro) and m/s^2 (accel); "
            "use a unit suffix (_dps, _g) or --gyro-unit/--accel-unit if that is wrong"
        )
    warnings += unit_warnings(out, input_units, source=source, assumed=assumed)

    # --- time ---------------------------------------------------------------
    if time is None:
        if opts.rate_hz is None:
            raise InputError(
                f"{source} has no time column (looked for time, time_s, t, timestamp, ...); "
                "give the sample rate with --rate HZ (rate_hz= in Python) or map one with "
                "--columns time=NAME"
            )
        rate = opts.rate_hz
        t = np.arange(n, dtype=np.float64) / rate
        warnings += spike_warnings(out, source=source, t=t, row_label=row_label)
        return [ImuLog(out, rate, t, source, input_units, frame, warnings)]

    tv = np.asarray(time.values)
    if tv.dtype.kind not in "fiu":
        raise InputError(f"time column {time.source!r} of {source} is not numeric")
    check_finite(tv, source=source, column=time.source, row_label=row_label, what="time")
    if n < 2 and opts.rate_hz is None:
        raise InputError(
            f"{source} has only {n} data row; at least 2 are needed to find the sample rate"
        )
    # Differences in the native dtype (exact for integer ns stamps).
    tv = tv.astype(np.int64) if tv.dtype.kind in "iu" else tv.astype(np.float64)
    order = check_time_order(
        tv, source=source, column=time.source, values=list(out.values()), on_gap=opts.on_gap,
        row_label=row_label,
    )
    warnings += order.notes
    label = row_label
    kept: np.ndarray | None = None
    if order.keep is not None:
        kept = np.flatnonzero(order.keep)
        tv = tv[kept]
        out = {c: np.ascontiguousarray(v[kept]) for c, v in out.items()}
        n = int(tv.size)

        def label(i: int) -> str:
            return row_label(int(kept[i]))

        if n < 2 and opts.rate_hz is None:
            raise InputError(
                f"{source} has only {n} distinct data row; at least 2 are needed to find the "
                "sample rate"
            )
    d_native = np.diff(tv)
    pos = d_native[d_native > 0]
    med_native = float(np.median(pos)) if pos.size else 0.0

    stated = time.unit
    if stated is None and time.layout == "kalibr":
        stated = "ns"
        warnings.append(f"time column {time.source!r}: Kalibr layout, time stamps taken as ns")
    unit = resolve_time_unit(
        med_native, source=source, column=time.source, stated=stated,
        override=opts.time_unit, warnings=warnings, unusual_rate=opts.unusual_rate,
    )
    factor = TIME_UNITS[unit]
    if tv.dtype.kind == "i":
        # Exact integer split, so 1000000000000 ns is exactly 1000.0 s and large
        # epoch stamps keep full float64 resolution.
        per_s = round(1.0 / factor)
        whole, frac = np.divmod(tv, per_s)
        t = whole.astype(np.float64) + frac.astype(np.float64) / per_s
    else:
        t = tv.astype(np.float64) * factor
    dt = d_native.astype(np.float64) * factor

    if dt.size == 0:
        rate = float(opts.rate_hz)  # type: ignore[arg-type]
        return [ImuLog(out, rate, t, source, input_units, frame, warnings)]
    changes = find_rate_changes(dt)
    if changes and opts.on_gap != "split":
        c = changes[0]
        more = f" ({len(changes)} changes in all)" if len(changes) > 1 else ""
        raise InputError(
            describe_rate_change(source, c, label(c.row), float(t[c.row])) + more
            + "; --on-gap split analyses each part at its own rate"
            + ("" if opts.on_gap == "refuse" else " (--on-gap ignore does not apply to it)")
        )  # fmt: skip
    warnings += spike_warnings(out, source=source, t=t, row_label=label)
    edges = [0, *[c.row for c in changes], n]
    why = ""
    if changes:
        c = changes[0]
        why = describe_rate_change(source, c, label(c.row), float(t[c.row])) + (
            f" ({len(changes)} changes in all); split there (--on-gap split)"
            if len(changes) > 1 else "; split there (--on-gap split)"
        )  # fmt: skip
    ranges: list[tuple[int, int, float, str]] = []
    for a, b in zip(edges, edges[1:], strict=False):
        part = _gap_ranges(source, time.source, (a, b), t, dt, order.restarts, opts, label,
                           warnings, why)  # fmt: skip
        if part is None:  # one contiguous part, gaps ignored: the log as it is
            return [ImuLog(out, _part_rate(dt, opts, source, time.source), t, source,
                           input_units, frame, warnings)]  # fmt: skip
        ranges += part
    if len(ranges) == 1:
        a, b, rate, _ = ranges[0]
        return [ImuLog(out, rate, t, source, input_units, frame, warnings)]
    logs = []
    for k, (a, b, rate, reason) in enumerate(ranges):
        first, last = (a, b - 1) if kept is None else (int(kept[a]), int(kept[b - 1]))
        seg_warn = [
            *warnings,
            f"segment {k + 1} of {len(ranges)} (data rows {first + 1}..{last + 1}); {reason}",
        ]
        logs.append(
            ImuLog(
                {c: v[a:b].copy() for c, v in out.items()},
                rate,
                t[a:b].copy(),
                f"{source} [segment {k + 1}/{len(ranges)}]",
                dict(input_units),
                frame,
                seg_warn,
            )
        )
    return logs


def _part_rate(dt: np.ndarray, opts: ReadOptions, source: str, column: str) -> float:
    med, _ = gap_threshold(dt, opts.gap_tolerance)
    return rate_from_step(med, opts.rate_hz, source=source, column=column)


def _gap_ranges(
    source: str,
    column: str,
    rows: tuple[int, int],
    t: np.ndarray,
    dt: np.ndarray,
    restarts: np.ndarray,
    opts: ReadOptions,
    label: Callable[[int], str],
    warnings: list[str],
    why: str,
) -> list[tuple[int, int, float, str]] | None:
    """Rows [a, b) of one rate cut at its gaps and restarts: (start, end, rate, reason)
    per contiguous range; None when the part is one range with its gaps ignored (the
    caller keeps the log whole). Raises for a gap with ``on_gap="refuse"``."""
    a, b = rows
    d = dt[a : b - 1]
    if d.size == 0:
        rate = float(opts.rate_hz) if opts.rate_hz else 1.0 / float(np.median(dt[dt > 0]))
        return [(a, b, rate, why)]
    med_dt, gap_factor = gap_threshold(d, opts.gap_tolerance)
    rate = rate_from_step(med_dt, opts.rate_hz, source=source, column=column)
    gaps = find_gaps(d, med_dt, gap_factor) + a
    rs = restarts[(restarts > a) & (restarts < b)]
    if gaps.size == 0 and rs.size == 0:
        return [(a, b, rate, why)]
    summary = ""
    if gaps.size:
        first = int(gaps[0])
        summary = gap_summary(
            source, count=int(gaps.size), factor=gap_factor, median_step=med_dt,
            first_row=first + 1, first_t=float(t[first + 1]), first_step=float(dt[first]),
            longest=float(dt[gaps].max()), row_label=label,
        )  # fmt: skip
        if opts.on_gap == "refuse":
            raise InputError(summary + GAP_ADVICE)
        if opts.on_gap == "ignore":
            warnings.append(summary + "; ignored (--on-gap ignore): treated as contiguous")
            return None
    cuts = np.union1d(gaps + 1, rs)
    bounds = np.concatenate(([a], cuts, [b])).astype(np.int64)
    reason = "; ".join(r for r in (why, summary or "the time restarts") if r)
    return [(int(x), int(y), rate, reason) for x, y in zip(bounds, bounds[1:], strict=False)]
