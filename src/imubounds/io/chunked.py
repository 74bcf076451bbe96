"""Chunked (out-of-core) access to large IMU logs, in SI units.

:func:`open_chunked` opens a log without loading it and returns a
:class:`ChunkedLog` whose :meth:`~ChunkedLog.iter_chunks` yields blocks of rows
as ``{canonical channel: float64 array in SI}`` (rad/s, m/s^2). Column names are
recognised by :func:`imubounds.io.columns.plan_columns` exactly as for the
in-memory readers, and units are converted with the same tables.

Formats
-------
===========================  ==================================================================
CSV/TSV/TXT (optionally .gz)  read with pandas in blocks of rows (one header line, a delimiter
                              among ``, ; tab`` or whitespace); *not* re-readable cheaply
Parquet                       one record batch at a time (row groups)
``.npy``                      memory-mapped: a structured array (field names are the column
                              names), a 1-D array (one channel, give ``channels``) or a 2-D
                              ``(N, C)`` array (``C`` channels named by ``channels``, default
                              ``gyro_x .. accel_z`` when ``C == 6``)
raw binary                    ``.f64``/``.bin``/``.raw`` little-endian float64, ``.f32``
                              float32; ``C`` interleaved channels as for a 2-D ``.npy``
HDF5 (``.h5``, ``.hdf5``)     1-D datasets named like columns (``gyro_x``, ``acc_z_g``, ``time``)
                              anywhere in the file, or one compound dataset with such fields
===========================  ==================================================================

Binary formats have no time column: give ``rate_hz``. Units default to rad/s
and m/s^2 unless the name states one or ``gyro_unit``/``accel_unit`` is given.
Text tables are laid out exactly as for the in-memory reader
(:mod:`imubounds.io.table`: comments, delimiter, quoting, a units row under the
header, decimal commas, ISO 8601 time stamps), and values are parsed by the same
parser. Time stamps, when present, give the rate (median step of the first
100000 rows). Every block goes through :class:`imubounds.io.validate.StreamChecker`:
the finiteness, time order (duplicates, restarts), gap and spike checks of the
in-memory readers, across block boundaries. ``on_gap="split"`` is not possible
out of core (a gap is then an error naming it).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from imubounds.errors import InputError, OptionError
from imubounds.io.log import IMU_CHANNELS
from imubounds.units import ACCEL_UNITS, GYRO_UNITS, TIME_UNITS

from .assemble import ReadOptions
from .columns import plan_columns
from .validate import (
    PLAUSIBLE_RATE_HZ,
    StreamChecker,
    check_finite,
    check_input_path,
    check_time_order,
    default_row_label,
    gap_threshold,
    rate_from_step,
    resolve_time_unit,
    unit_warnings,
)

__all__ = ["CHUNKED_SUFFIXES", "PLAUSIBLE_RATE_HZ", "ChunkedLog", "open_chunked"]

#: File endings :func:`open_chunked` understands, longest first where they overlap.
CHUNKED_SUFFIXES: tuple[str, ...] = (
    ".csv.gz", ".tsv.gz", ".txt.gz", ".dat.gz", ".csv", ".tsv", ".txt", ".dat",
    ".parquet", ".pq", ".parq", ".npy", ".f64", ".bin", ".raw", ".f32", ".h5", ".hdf5",
)  # fmt: skip

#: Rows of the time column read when the log is opened, to find the rate and unit
#: (fewer for text, which has to be parsed).
HEAD_ROWS = 100_000
HEAD_TEXT_ROWS = 10_000

RawBlock = tuple[np.ndarray | None, dict[str, np.ndarray]]


@dataclass
class TimeInfo:
    """The time column of a chunked log, as found in its first rows."""

    column: str
    factor: float  # native unit -> s
    median_step: float  # native unit
    gap_factor: float


@dataclass
class ChunkedLog:
    """A log opened for chunked reading (nothing loaded yet).

    Attributes
    ----------
    path : Path
        The file.
    fmt : str
        ``"text"``, ``"parquet"``, ``"npy"``, ``"raw"`` or ``"hdf5"``.
    channels : list of str
        Canonical channel names, in canonical order.
    rate_hz : float
        Nominal sample rate in Hz.
    n_samples : int or None
        Number of rows when known without reading (binary formats, Parquet).
    input_units : dict
        Channel -> unit of the input.
    factors : dict
        Channel -> factor to SI.
    rereadable : bool
        True when a second pass over the file is cheap (binary formats).
    warnings : list of str
        Things a user should see (the checks of a complete pass are added at its end).
    on_gap : str
        ``"refuse"`` or ``"ignore"`` (``"split"`` raises at the first gap).
    """

    path: Path
    fmt: str
    channels: list[str]
    rate_hz: float
    n_samples: int | None
    input_units: dict[str, str]
    factors: dict[str, float]
    rereadable: bool
    warnings: list[str] = field(default_factory=list)
    _sources: dict[str, Any] = field(default_factory=dict, repr=False)
    _extra: dict[str, Any] = field(default_factory=dict, repr=False)
    on_gap: str = "refuse"
    time: TimeInfo | None = None
    _checked: bool = field(default=False, repr=False)

    @property
    def source(self) -> str:
        return str(self.path)

    def bytes_in_memory(self) -> int:
        """Rough bytes the *in-memory* path needs for this log.

        Channels and time as float64, the phase and kernel temporaries, and
        (for text) the parser's own copies: about ``4 * 8`` bytes per value.
        When the row count is unknown (text) it is estimated from the file
        size (x3 for gzip).
        """
        n = self.n_samples
        ncol = len(self.channels) + 1
        if n is None:
            size = self.path.stat().st_size * (3 if self._extra.get("gz") else 1)
            n = max(1, size // max(8, 12 * ncol))
        return int(n) * ncol * 8 * 4

    # ------------------------------------------------------------------
    def iter_chunks(self, rows: int) -> Iterator[dict[str, np.ndarray]]:
        """Blocks of at most ``rows`` rows: ``{channel: float64 SI array}``.

        Every block is checked (:class:`~imubounds.io.validate.StreamChecker`);
        duplicated rows are dropped when ``on_gap`` allows it. At the end of
        the first complete pass the counted warnings join :attr:`warnings`.

        Raises
        ------
        InputError
            Unreadable data, a non-finite value, time out of order, a gap
            (``on_gap="refuse"``), naming file, row and column.
        """
        rows = max(1, int(rows))
        label: Callable[[int], str] = self._extra.get("row_label") or default_row_label
        tinfo = self.time
        checker = StreamChecker(
            self.source,
            column=None if tinfo is None else tinfo.column,
            time_factor=1.0 if tinfo is None else tinfo.factor,
            median_step=0.0 if tinfo is None else tinfo.median_step,
            gap_factor=1.5 if tinfo is None else tinfo.gap_factor,
            on_gap=self.on_gap,
            row_label=label,
        )
        first = True
        for t, raw in self._raw_blocks(rows):
            si = {c: _si(np.asarray(v, dtype=np.float64), self.factors[c]) for c, v in raw.items()}
            keep = checker.feed(t, si)
            if keep is not None:
                si = {c: v[keep] for c, v in si.items()}
            if first and not self._checked:
                self.warnings.extend(unit_warnings(si, self.input_units, source=self.source))
                first = False
            if si and next(iter(si.values())).size:
                yield si
        if not self._checked:
            self.warnings.extend(checker.finish())
            self._checked = True

    def _raw_blocks(self, rows: int) -> Iterator[RawBlock]:
        if self.fmt == "text":
            return self._iter_text(rows)
        if self.fmt == "parquet":
            return self._iter_parquet(rows)
        if self.fmt in ("npy", "raw"):
            return self._iter_binary(rows)
        if self.fmt == "hdf5":
            return self._iter_hdf5(rows)
        raise ValueError(self.fmt)  # pragma: no cover - guarded by open_chunked

    def _iter_binary(self, rows: int) -> Iterator[RawBlock]:
        # plain reads, not the memory map: pages of a map would count in RSS
        arr = self._sources["array"]
        tsrc = self._sources.get("time")
        n = int(arr.shape[0])
        row_dtype = arr.dtype if arr.ndim == 1 else np.dtype((arr.dtype, arr.shape[1:]))
        offset = int(arr.offset) if isinstance(arr, np.memmap) else 0
        with open(self.path, "rb") as f:
            for a in range(0, n, rows):
                k = min(rows, n - a)
                f.seek(offset + a * row_dtype.itemsize)
                block = np.fromfile(
                    f, dtype=arr.dtype, count=k * (row_dtype.itemsize // arr.dtype.itemsize)
                )
                if arr.ndim == 2:
                    block = block.reshape(-1, arr.shape[1])
                if block.shape[0] != k:
                    raise InputError(f"{self.path}: the file ends early (row {a + block.shape[0]})")
                out = {}
                for c, src in self._sources["columns"].items():
                    if isinstance(src, str):
                        v = block[src]
                    elif block.ndim == 2:
                        v = block[:, src]
                    else:
                        v = block
                    out[c] = np.ascontiguousarray(v)
                yield (None if tsrc is None else np.asarray(block[tsrc])), out

    def _iter_text(self, rows: int) -> Iterator[RawBlock]:
        from .table import iter_text_blocks

        ex = self._extra
        plan = ex["plan"]
        names = {spec.index: c for c, spec in plan.channels.items()}
        tidx = None if plan.time is None else plan.time.index
        for arrs in iter_text_blocks(self.path, ex["gz"], ex["layout"], plan, rows):
            yield (None if tidx is None else arrs[tidx]), {c: arrs[i] for i, c in names.items()}

    def _iter_parquet(self, rows: int) -> Iterator[RawBlock]:
        import pyarrow as pa
        import pyarrow.parquet as pq

        cols: dict[str, str] = self._sources["columns"]
        tsrc: str | None = self._sources.get("time")
        wanted = list(cols.values()) + ([tsrc] if tsrc is not None else [])
        try:
            pf = pq.ParquetFile(self.path)
            for batch in pf.iter_batches(batch_size=rows, columns=wanted):
                t = None
                if tsrc is not None:
                    tc = batch.column(tsrc)
                    t = (tc.cast(pa.int64()) if pa.types.is_timestamp(tc.type) else tc).to_numpy(
                        zero_copy_only=False
                    )
                yield t, {
                    c: batch.column(src).to_numpy(zero_copy_only=False) for c, src in cols.items()
                }
        except (pa.ArrowException, OSError) as err:
            raise InputError(
                f"{self.path}: the Parquet data cannot be read ({str(err).splitlines()[0][:120]})"
            ) from err

    def _iter_hdf5(self, rows: int) -> Iterator[RawBlock]:
        import h5py

        cols: dict[str, tuple[str, str | None]] = self._sources["columns"]
        tsrc: tuple[str, str | None] | None = self._sources.get("time")
        n = int(self.n_samples or 0)

        def read(f: Any, src: tuple[str, str | None], a: int) -> np.ndarray:
            dset, fld = src
            d = f[dset]
            return np.asarray(d[a : a + rows] if fld is None else d[a : a + rows][fld])

        try:
            with h5py.File(self.path, "r") as f:
                for a in range(0, n, rows):
                    t = None if tsrc is None else read(f, tsrc, a)
                    yield t, {c: read(f, src, a) for c, src in cols.items()}
        except OSError as err:
            raise InputError(f"{self.path}: the HDF5 data cannot be read ({err})") from err


def _si(v: np.ndarray, factor: float) -> np.ndarray:
    return v if factor == 1.0 else v * factor


# ----------------------------------------------------------------------
def _suffix(path: Path) -> str:
    lower = path.name.lower()
    for s in CHUNKED_SUFFIXES:
        if lower.endswith(s):
            return s
    raise InputError(
        f"{path}: unknown file type for chunked reading; use one of {', '.join(CHUNKED_SUFFIXES)}"
    )


def _unit_factor(
    channel: str, stated: str | None, opts: ReadOptions, warnings: list[str], source: str
) -> tuple[str, float]:
    kind = channel.split("_")[0]
    override = opts.gyro_unit if kind == "gyro" else opts.accel_unit
    table = GYRO_UNITS if kind == "gyro" else ACCEL_UNITS
    if override is not None:
        return override, table[override]
    if stated is not None:
        return stated, table[stated]
    default = "rad/s" if kind == "gyro" else "m/s^2"
    warnings.append(f"{source}: no unit stated for {channel}; assumed {default}")
    return default, table[default]


def _time_info(
    t: np.ndarray,
    stated: str | None,
    opts: ReadOptions,
    source: str,
    column: str,
    warnings: list[str],
    row_label: Callable[[int], str] = default_row_label,
) -> tuple[float, TimeInfo]:
    """Rate and time unit from the first rows, as :func:`assemble_logs` finds them."""
    t = np.asarray(t)
    if t.dtype.kind not in "fiu":
        raise InputError(f"time column {column!r} of {source} is not numeric")
    check_finite(t, source=source, column=column, row_label=row_label, what="time")
    if t.size == 0:
        raise InputError(f"{source} has a header but no data rows; give a file with samples")
    if t.size < 2:
        raise InputError(f"{source}: fewer than 2 rows; cannot find the sample rate")
    t = t.astype(np.int64) if t.dtype.kind in "iu" else t.astype(np.float64)
    order = check_time_order(t, source=source, column=column, values=None, on_gap=opts.on_gap,
                             row_label=row_label, can_split=False)
    if order.keep is not None:
        t = t[order.keep]
    d = np.diff(t)
    pos = d[d > 0]
    if pos.size == 0:
        raise InputError(f"{source}: time stamps do not increase; check the time column")
    med = float(np.median(pos))
    unit = resolve_time_unit(med, source=source, column=column, stated=stated,
                             override=opts.time_unit, warnings=warnings,
                             unusual_rate=opts.unusual_rate)
    factor = TIME_UNITS[unit]
    med_dt, gap_factor = gap_threshold(pos.astype(np.float64) * factor, opts.gap_tolerance)
    rate = rate_from_step(med_dt, opts.rate_hz, source=source, column=column)
    return rate, TimeInfo(column, factor, med, gap_factor)


def _check_rate(rate_hz: float | None, source: str) -> float:
    if rate_hz is None:
        raise OptionError(f"{source} has no time column; give the sample rate with --rate HZ")
    r = float(rate_hz)
    if not (math.isfinite(r) and r > 0):
        raise OptionError(f"--rate must be a positive number of Hz, got {rate_hz!r}")
    return r


def open_chunked(
    path: str | Path,
    *,
    rate_hz: float | None = None,
    columns: Mapping[str, str] | None = None,
    channels: Sequence[str] | None = None,
    gyro_unit: str | None = None,
    accel_unit: str | None = None,
    time_unit: str | None = None,
    on_gap: str = "refuse",
    gap_tolerance: float | None = None,
    unusual_rate: bool = False,
) -> ChunkedLog:
    """Open a (possibly huge) IMU log for chunked reading.

    Parameters are those of :func:`imubounds.io.read_imu`; for binary
    arrays without names ``channels`` names the columns in order.

    Raises
    ------
    InputError, OptionError
        Unreadable file, no IMU column, missing rate, bad option.
    """
    opts = ReadOptions(
        rate_hz=rate_hz, columns=columns, gyro_unit=gyro_unit, accel_unit=accel_unit,
        time_unit=time_unit, gap_tolerance=gap_tolerance, on_gap=on_gap,  # type: ignore[arg-type]
        unusual_rate=unusual_rate,
    ).validated()
    p = check_input_path(path)
    if p.stat().st_size == 0:
        raise InputError(f"{p} is empty; give a file with data")
    suf = _suffix(p)
    o = _Opening(p, opts, dict(opts.columns) if opts.columns else None,
                 None if channels is None else tuple(channels), [])  # fmt: skip
    if suf.endswith((".csv", ".tsv", ".txt", ".dat", ".gz")):
        return _open_text(o)
    if suf in (".parquet", ".pq", ".parq"):
        return _open_parquet(o)
    if suf in (".npy", ".f64", ".bin", ".raw", ".f32"):
        return _open_array(o, suf)
    return _open_hdf5(o)


@dataclass
class _Opening:
    """What :func:`open_chunked` knows before it reads a format: the file, the
    validated options, the column map and channel names, the warnings so far."""

    path: Path
    opts: ReadOptions
    cols: dict[str, str] | None
    chans: tuple[str, ...] | None
    warnings: list[str]

    @property
    def src(self) -> str:
        return str(self.path)

    def finish(
        self,
        fmt: str,
        plan_ch: dict[str, Any],
        stated: dict[str, str | None],
        rate: float,
        n: int | None,
        rereadable: bool,
        sources: dict[str, Any],
        extra: dict[str, Any] | None = None,
        time: TimeInfo | None = None,
    ) -> ChunkedLog:
        units, factors = {}, {}
        for c in plan_ch:
            units[c], factors[c] = _unit_factor(
                c, stated.get(c), self.opts, self.warnings, self.src
            )
        return ChunkedLog(
            self.path, fmt, list(plan_ch), rate, n, units, factors, rereadable, self.warnings,
            sources, extra or {}, on_gap=self.opts.on_gap, time=time,
        )


def _open_text(o: _Opening) -> ChunkedLog:
    """A CSV/TSV/TXT/DAT log, optionally gzip."""
    p, opts, src, cols, chans, warnings = o.path, o.opts, o.src, o.cols, o.chans, o.warnings
    finish = o.finish
    from .magic import file_is_gzip
    from .table import _detect_layout, _line_finder, _read_head, iter_text_blocks

    try:
        gz = file_is_gzip(p)
    except OSError as err:
        raise InputError(f"{p}: cannot read the file ({err.strerror or err})") from err
    layout = _detect_layout(p, _read_head(p, gz))
    warnings.extend(layout.notes)
    plan = plan_columns(layout.header, src, columns=cols, channels=chans)
    label = _line_finder(p, gz, layout)
    tinfo = None
    if plan.time is not None:
        head = next(iter_text_blocks(p, gz, layout, plan, HEAD_TEXT_ROWS), None)
        if head is None:
            raise InputError(f"{p} has a header but no data rows; give a file with samples")
        t = head[plan.time.index]
        stated = plan.time.unit
        if stated is None and t.dtype.kind == "i" and layout.first_row and not _numeric(
            layout.first_row[plan.time.index]
        ):
            stated = "ns"  # ISO 8601 date-times, read as epoch ns
        if stated is None and plan.time.source.lower() == "timestamp" and any(
            s.layout == "kalibr" for s in plan.channels.values()
        ):
            stated = "ns"
        rate, tinfo = _time_info(t, stated, opts, src, plan.time.source, warnings, label)
    else:
        rate = _check_rate(opts.rate_hz, src)
    return finish(
        "text", dict(plan.channels), {c: s.unit for c, s in plan.channels.items()}, rate,
        None, False, {}, {"plan": plan, "gz": gz, "layout": layout, "row_label": label},
        tinfo,
    )


def _open_parquet(o: _Opening) -> ChunkedLog:
    """A Parquet log."""
    p, opts, src, cols, chans, warnings = o.path, o.opts, o.src, o.cols, o.chans, o.warnings
    finish = o.finish
    import pyarrow as pa
    import pyarrow.parquet as pq

    try:
        pf = pq.ParquetFile(p)
        header = list(pf.schema_arrow.names)
        n = int(pf.metadata.num_rows)
    except (pa.ArrowException, OSError) as err:
        raise InputError(f"{p}: not a readable Parquet file ({str(err)[:120]})") from err
    plan = plan_columns(header, src, columns=cols, channels=chans)
    tinfo = None
    tsrc = None
    if plan.time is not None:
        tsrc = plan.time.source
        try:
            first = pf.read_row_group(0, columns=[tsrc]).column(0)
        except (pa.ArrowException, OSError) as err:
            raise InputError(
                f"{p}: the Parquet data cannot be read ({str(err)[:120]})"
            ) from err
        is_ts = pa.types.is_timestamp(first.type)
        t = (first.cast(pa.int64()) if is_ts else first).to_numpy(zero_copy_only=False)
        unit = first.type.unit if is_ts else plan.time.unit
        rate, tinfo = _time_info(np.asarray(t[:HEAD_ROWS]), unit, opts, src, tsrc, warnings)
    else:
        rate = _check_rate(opts.rate_hz, src)
    names_pq = {c: s.source for c, s in plan.channels.items()}
    return finish(
        "parquet", dict(plan.channels), {c: s.unit for c, s in plan.channels.items()}, rate,
        n, True, {"columns": names_pq, "time": tsrc}, time=tinfo,
    )


def _open_array(o: _Opening, suf: str) -> ChunkedLog:
    """A NumPy ``.npy`` array or a raw little-endian float file."""
    p, opts, src, cols, chans, warnings = o.path, o.opts, o.src, o.cols, o.chans, o.warnings
    finish = o.finish
    if suf == ".npy":
        try:
            arr = np.load(p, mmap_mode="r")
        except (ValueError, OSError, EOFError) as err:
            raise InputError(f"{p}: not a readable .npy file ({err})") from err
    else:
        dt = np.dtype("<f4") if suf == ".f32" else np.dtype("<f8")
        if p.stat().st_size % dt.itemsize:
            raise InputError(
                f"{p}: {p.stat().st_size} bytes are not a whole number of "
                f"{dt.itemsize}-byte values; the file is truncated or not raw {dt}"
            )
        arr = np.memmap(p, dtype=dt, mode="r")
    if arr.dtype.names:
        header = list(arr.dtype.names)
        plan = plan_columns(header, src, columns=cols, channels=chans)
        tinfo = None
        tsrc = None
        if plan.time is not None:
            tsrc = plan.time.source
            t = np.asarray(arr[tsrc][:HEAD_ROWS])
            rate, tinfo = _time_info(t, plan.time.unit, opts, src, tsrc, warnings)
        else:
            rate = _check_rate(opts.rate_hz, src)
        fields = {c: s.source for c, s in plan.channels.items()}
        return finish(
            "npy", dict(plan.channels), {c: s.unit for c, s in plan.channels.items()}, rate,
            int(arr.shape[0]), True, {"array": arr, "columns": fields, "time": tsrc},
            time=tinfo,
        )
    names = list(chans) if chans else None
    ncol = 1 if arr.ndim == 1 else int(arr.shape[1])
    if suf != ".npy":
        ncol = len(names) if names else 6
        if arr.shape[0] % ncol:
            raise InputError(
                f"{p}: {arr.shape[0]} values are not a whole number of rows of "
                f"{ncol} channels; give the channels with --channels"
            )
        arr = arr.reshape(-1, ncol) if ncol > 1 else arr
    if arr.ndim not in (1, 2):
        raise InputError(f"{p}: array of shape {arr.shape}; expected (N,) or (N, C)")
    if arr.dtype.kind not in "fiu":
        raise InputError(f"{p}: array of type {arr.dtype} is not numeric")
    if names is None:
        if ncol != 6:
            raise OptionError(
                f"{p}: an unnamed array with {ncol} column(s); name them with "
                "channels=(...) / --channels gyro_z,..."
            )
        names = list(IMU_CHANNELS)
    if len(names) != ncol or any(c not in IMU_CHANNELS for c in names):
        raise OptionError(
            f"{p}: has {ncol} column(s); give as many channel names from "
            f"{', '.join(IMU_CHANNELS)}"
        )
    rate = _check_rate(opts.rate_hz, src)
    index = {c: (i if arr.ndim == 2 else 0) for i, c in enumerate(names)}
    order = {c: index[c] for c in IMU_CHANNELS if c in index}
    return finish(
        "npy" if suf == ".npy" else "raw", dict.fromkeys(order), {}, rate,
        int(arr.shape[0]), True, {"array": arr, "columns": order},
    )


def _open_hdf5(o: _Opening) -> ChunkedLog:
    """An HDF5 file: its 1-D datasets (or fields of compound ones) as columns."""
    p, opts, src, cols, chans, warnings = o.path, o.opts, o.src, o.cols, o.chans, o.warnings
    finish = o.finish
    import h5py

    try:
        f = h5py.File(p, "r")
    except OSError as err:
        raise InputError(f"{p}: not a readable HDF5 file ({err})") from err
    with f:
        found: list[tuple[str, str, str | None, int]] = []  # (header name, dset, field, len)

        def visit(name: str, obj: Any) -> None:
            if isinstance(obj, h5py.Dataset) and obj.ndim == 1:
                if obj.dtype.names:
                    for fld in obj.dtype.names:
                        found.append((fld, name, fld, int(obj.shape[0])))
                else:
                    found.append((name.rsplit("/", 1)[-1], name, None, int(obj.shape[0])))

        f.visititems(visit)
        header = [h for h, _, _, _ in found]
        plan = plan_columns(header, src, columns=cols, channels=chans)
        used = [found[s.index] for s in plan.channels.values()]
        if plan.time is not None:
            used.append(found[plan.time.index])
        lengths = {n for _, _, _, n in used}
        if len(lengths) != 1:
            raise InputError(f"{p}: the channel datasets have different lengths {sorted(lengths)}")
        n = lengths.pop()
        tinfo = None
        tsrc5 = None
        if plan.time is not None:
            _, dset, fld, _ = found[plan.time.index]
            tsrc5 = (dset, fld)
            d = f[dset]
            t = np.asarray(d[:HEAD_ROWS] if fld is None else d[:HEAD_ROWS][fld])
            rate, tinfo = _time_info(t, plan.time.unit, opts, src, plan.time.source, warnings)
        else:
            rate = _check_rate(opts.rate_hz, src)
        dsets = {c: (found[s.index][1], found[s.index][2]) for c, s in plan.channels.items()}
    return finish(
        "hdf5", dict(plan.channels), {c: s.unit for c, s in plan.channels.items()}, rate, n,
        True, {"columns": dsets, "time": tsrc5}, time=tinfo,
    )

def _numeric(text: str) -> bool:
    try:
        float(text.replace(",", "."))
    except ValueError:
        return False
    return True


def text_bytes_bound(path: Path) -> int | None:
    """An upper bound of :meth:`ChunkedLog.bytes_in_memory` for a text log (CSV, TSV,
    TXT, DAT, optionally gzip), from its size alone; ``None`` for another format.

    The row estimate there is size / (12 bytes per value), so the column count
    cancels: routing a small file needs no header or time read."""
    if not path.name.lower().endswith((".csv", ".tsv", ".txt", ".dat", ".gz")):
        return None
    from .magic import file_is_gzip

    gz = file_is_gzip(path)
    size = path.stat().st_size * (3 if gz else 1)
    return (size // 12 + 1) * 8 * 4 + 8 * 4 * 1024  # n >= 1 row of up to 1024 columns
