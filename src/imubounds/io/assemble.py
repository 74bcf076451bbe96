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

OnGap = Literal["refuse", "split", "ignore"]
ON_GAP_CHOICES: tuple[str, ...] = ("refuse", "split", "ignore")
#: Relative tolerance when a time column and ``rate_hz`` are both given.
RATE_TOLERANCE = 0.01
#: Smallest gap tolerance (in nominal sample periods) used by the automatic rule.
MIN_GAP_FACTOR = 1.5
#: Multiple of the relative robust jitter added by the automatic rule.
JITTER_GAP_FACTOR = 4.0
#: Plausible IMU sample rates used to infer an unstated time unit, Hz.
PLAUSIBLE_RATE_HZ = (0.5, 1.0e5)


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
        if self.on_gap not in ON_GAP_CHOICES:
            raise OptionError(
                f"--on-gap must be one of {', '.join(ON_GAP_CHOICES)}, got {self.on_gap!r}"
            )
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


def _first_nonfinite(values: np.ndarray) -> int | None:
    bad = ~np.isfinite(values)
    if not bad.any():
        return None
    return int(np.argmax(bad))


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
    InputError, OptionError
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
        bad = _first_nonfinite(vals)
        if bad is not None:
            raise InputError(
                f"{source}, {row_label(bad)}, column {raw.source!r}: value "
                f"{_num(vals[bad])} is not a finite number; remove or repair that row"
            )
        out[name] = np.ascontiguousarray(vals * table[unit], dtype=np.float64)
        input_units[name] = unit
    if assumed:
        warnings.append(
            f"units not stated for {', '.join(assumed)}: assumed rad/s (gyro) and m/s^2 (accel); "
            "use a unit suffix (_dps, _g) or --gyro-unit/--accel-unit if that is wrong"
        )
        _plausibility(out, assumed, warnings)

    # --- time ---------------------------------------------------------------
    if time is None:
        if opts.rate_hz is None:
            raise InputError(
                f"{source} has no time column (looked for time, time_s, t, timestamp, ...); "
                "give the sample rate with --rate HZ or map one with --columns time=NAME"
            )
        rate = opts.rate_hz
        t = np.arange(n, dtype=np.float64) / rate
        log = ImuLog(out, rate, t, source, input_units, frame, warnings)
        return [log]

    tv = np.asarray(time.values)
    if tv.dtype.kind not in "fiu":
        raise InputError(f"time column {time.source!r} of {source} is not numeric")
    if tv.dtype.kind == "f":
        bad = _first_nonfinite(tv)
        if bad is not None:
            raise InputError(
                f"{source}, {row_label(bad)}, column {time.source!r}: time {_num(tv[bad])} is not "
                "a finite number; remove or repair that row"
            )
    if n < 2 and opts.rate_hz is None:
        raise InputError(
            f"{source} has only {n} data row; at least 2 are needed to find the sample rate"
        )
    # Differences in the native dtype (exact for integer ns stamps).
    if tv.dtype.kind in "iu":
        tv = tv.astype(np.int64)
        d_native = np.diff(tv)
    else:
        d_native = np.diff(tv.astype(np.float64))
    if d_native.size:
        nonpos = d_native <= 0
        if nonpos.any():
            k = int(np.argmax(nonpos)) + 1
            what = "repeats" if d_native[k - 1] == 0 else "goes backwards"
            raise InputError(
                f"{source}, {row_label(k)}, column {time.source!r}: time stamp {_num(tv[k])} "
                f"{what} (previous {_num(tv[k - 1])}); time must increase strictly: sort the "
                "rows or remove duplicates"
            )

    unit = opts.time_unit or time.unit
    if unit is None and time.layout == "kalibr":
        unit = "ns"
        warnings.append(f"time column {time.source!r}: Kalibr layout, time stamps taken as ns")
    if unit is None:
        unit = "s"
        if d_native.size:
            med = float(np.median(d_native))
            lo, hi = PLAUSIBLE_RATE_HZ
            if not lo <= 1.0 / med <= hi:
                for cand in ("ms", "us", "ns"):
                    if lo <= 1.0 / (med * TIME_UNITS[cand]) <= hi:
                        unit = cand
                        break
            if unit != "s":
                warnings.append(
                    f"time column {time.source!r} states no unit; its spacing ({_fmt(med)}) only "
                    f"makes sense in {unit}, so {unit} was assumed (use --time-unit to override)"
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
    med_dt = float(np.median(dt))
    rate_from_t = float(f"{1.0 / med_dt:.9g}")
    if opts.rate_hz is not None:
        if abs(med_dt * opts.rate_hz - 1.0) > RATE_TOLERANCE:
            raise OptionError(
                f"--rate {_fmt(opts.rate_hz)} Hz disagrees with the time stamps of {source} "
                f"(column {time.source!r}: median step {_fmt(med_dt)} s = {_fmt(rate_from_t)} Hz); "
                "drop --rate or fix it"
            )
        rate = float(opts.rate_hz)
    else:
        rate = rate_from_t

    # --- gaps ---------------------------------------------------------------
    if opts.gap_tolerance is not None:
        gap_factor = opts.gap_tolerance
    else:
        q25, q75 = np.percentile(dt, [25.0, 75.0])
        jitter = float((q75 - q25) / 1.349 / med_dt)
        gap_factor = max(MIN_GAP_FACTOR, 1.0 + JITTER_GAP_FACTOR * jitter)
    gaps = np.flatnonzero(dt > gap_factor * med_dt)
    if gaps.size == 0:
        return [ImuLog(out, rate, t, source, input_units, frame, warnings)]

    first = int(gaps[0])
    longest = float(dt[gaps].max())
    summary = (
        f"{source} has {gaps.size} gap(s) in the time stamps longer than "
        f"{gap_factor:.3g} x the {_fmt(med_dt)} s sample period "
        f"(first just before {row_label(first + 1)}, t={_fmt(float(t[first + 1]))} s: "
        f"a {_fmt(float(dt[first]))} s step, about "
        f"{max(round(float(dt[first]) / med_dt) - 1, 1)} missing sample(s); longest "
        f"{_fmt(longest)} s)"
    )
    if opts.on_gap == "refuse":
        raise InputError(
            summary + "; choose --on-gap split (analyse contiguous segments) or --on-gap ignore "
            "(treat as contiguous), or raise --gap-tolerance"
        )
    if opts.on_gap == "ignore":
        warnings.append(summary + "; ignored (--on-gap ignore): treated as contiguous")
        return [ImuLog(out, rate, t, source, input_units, frame, warnings)]
    bounds = np.concatenate(([0], gaps + 1, [n]))
    logs = []
    for k in range(bounds.size - 1):
        a, b = int(bounds[k]), int(bounds[k + 1])
        seg_warn = [
            *warnings,
            f"segment {k + 1} of {bounds.size - 1} (data rows {a + 1}..{b}); {summary}",
        ]
        logs.append(
            ImuLog(
                {c: v[a:b].copy() for c, v in out.items()},
                rate,
                t[a:b].copy(),
                f"{source} [segment {k + 1}/{bounds.size - 1}]",
                dict(input_units),
                frame,
                seg_warn,
            )
        )
    return logs


def _plausibility(out: dict[str, np.ndarray], assumed: list[str], warnings: list[str]) -> None:
    """Warn when assumed SI units look wrong (e.g. an accelerometer in g)."""
    acc = [f"accel_{a}" for a in "xyz"]
    if all(c in out and c in assumed for c in acc):
        norm = float(np.median(np.sqrt(sum(out[c] ** 2 for c in acc))))
        if 0.5 < norm < 1.5:
            warnings.append(
                f"median |accel| is {norm:.3g} m/s^2 if the unit is m/s^2, but near 1: "
                "the accelerometer is probably in g (use --accel-unit g)"
            )
    for c in [c for c in assumed if c.startswith("gyro")]:
        peak = float(np.max(np.abs(out[c]))) if out[c].size else 0.0
        if peak > 50.0:
            warnings.append(
                f"{c} reaches {peak:.3g} rad/s if the unit is rad/s, beyond any MEMS gyro range: "
                "it is probably in deg/s (use --gyro-unit deg/s)"
            )
