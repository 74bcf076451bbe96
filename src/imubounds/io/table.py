"""Readers for delimited text tables (CSV/TSV/TXT, optionally gzip) and Parquet.

Text tables: the delimiter (tab, comma, semicolon, pipe, else whitespace) is
detected from the header and the first data row. Lines starting with ``#``
are comments; if the first non-comment line is numeric, the last comment line
is the header (EuRoC: ``#timestamp [ns],w_RS_S_x [rad s^-1],...``).

Fast path: ``pyarrow.csv`` (multi-threaded). If it fails for any reason the
file is re-read by a slow line-by-line parser that either finds the exact
line and column at fault (and raises :class:`InputError`) or succeeds (for
instance with comment lines inside the data).
"""

from __future__ import annotations

import csv
import gzip
import io
import re
import zlib
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.csv as pacsv

from imubounds.errors import InputError
from imubounds.io.log import ImuLog

from .assemble import RawChannel, RawTime, ReadOptions, assemble_logs
from .columns import ColumnPlan, plan_columns

GZIP_MAGIC = b"\x1f\x8b"
PARQUET_MAGIC = b"PAR1"
_HEAD_BYTES = 1 << 18
_DELIMITERS = ("\t", ",", ";", "|")


def _is_gzip(path: Path) -> bool:
    with open(path, "rb") as f:
        return f.read(2) == GZIP_MAGIC


def _open_text(path: Path, gz: bool) -> io.TextIOBase:
    if gz:
        return io.TextIOWrapper(gzip.open(path, "rb"), encoding="utf-8-sig", newline="")
    return open(path, encoding="utf-8-sig", newline="")  # noqa: SIM115


def _gzip_error(path: Path, err: BaseException) -> InputError:
    return InputError(
        f"{path}: the gzip data is truncated or corrupt ({type(err).__name__}); "
        "copy the file again or decompress what is left with zcat and fix its end"
    )


def _read_head(path: Path, gz: bool) -> str:
    try:
        with _open_text(path, gz) as f:
            return f.read(_HEAD_BYTES)
    except (EOFError, OSError, zlib.error) as err:
        if gz:
            raise _gzip_error(path, err) from err
        raise InputError(f"{path}: cannot read the file ({err})") from err
    except UnicodeDecodeError as err:
        raise InputError(
            f"{path}: not a text table (byte {err.start} is not UTF-8); give a CSV/TSV/TXT "
            "or Parquet file"
        ) from err


class _Layout:
    """Where the header is and how fields are separated."""

    def __init__(self, header: list[str], delimiter: str | None, skip_lines: int,
                 header_line: int, quoted: bool, first_row: list[str] | None = None) -> None:
        self.header = header
        self.first_row = first_row or []  # fields of the first data row, if any
        self.delimiter = delimiter  # None: runs of whitespace
        self.skip_lines = skip_lines  # physical lines before the first data line
        self.header_line = header_line  # 1-based line number of the header
        self.quoted = quoted


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _split(line: str, delimiter: str | None) -> list[str]:
    if delimiter is None:
        return line.split()
    return next(csv.reader([line], delimiter=delimiter))


def _detect_layout(path: Path, head: str) -> _Layout:
    lines = re.split(r"\r\n|\r|\n", head)
    if lines and lines[-1] == "":
        lines.pop()
    if not head.endswith(("\n", "\r")) and len(head) >= _HEAD_BYTES and lines:
        lines = lines[:-1]  # last line may be cut by the head size
    comments: list[tuple[int, str]] = []
    first = None
    for i, line in enumerate(lines):
        s = line.strip()
        if not s:
            continue
        if s.startswith("#"):
            comments.append((i, s.lstrip("#").strip()))
            continue
        first = i
        break
    if first is None:
        if comments:
            raise InputError(
                f"{path} holds only comment lines and no table; give a file with a header "
                "and data rows"
            )
        raise InputError(f"{path} is empty; give a file with a header line and data rows")
    first_line = lines[first]
    nxt = next((j for j in range(first + 1, len(lines)) if lines[j].strip()
                and not lines[j].lstrip().startswith("#")), None)

    def fields_consistent(a: str, b: str | None, d: str | None) -> bool:
        fa = _split(a, d)
        if len(fa) < 2:
            return False
        return b is None or len(_split(b, d)) == len(fa)

    first_is_data = all(_is_number(f) for f in _split(first_line, _guess_delim(first_line)) if f)
    if first_is_data:
        if not comments:
            raise InputError(
                f"{path}: line {first + 1} is data but there is no header line; add one naming "
                "the columns (e.g. time_s,gyro_x_dps,...,accel_z_g)"
            )
        h_idx, h_text = comments[-1]
        header_text, data_text, header_line, skip = h_text, first_line, h_idx + 1, first
    else:
        header_text, data_text, header_line, skip = first_line, (
            lines[nxt] if nxt is not None else None), first + 1, first + 1

    delim: str | None = None
    for d in _DELIMITERS:
        if d in header_text and fields_consistent(header_text, data_text, d):
            delim = d
            break
    else:
        if len(header_text.split()) >= 2 and fields_consistent(header_text, data_text, None):
            delim = None
        elif len(header_text.split()) == 1 and (data_text is None or len(data_text.split()) == 1):
            delim = ","  # a single column
        elif data_text is not None:
            d0 = _guess_delim(header_text)
            raise InputError(
                f"{path}: line {header_line} (header) has {len(_split(header_text, d0))} field(s) "
                f"but the first data row has {len(_split(data_text, d0))}; make them agree"
            )
        else:
            delim = _guess_delim(header_text)
    header = [h.strip() for h in _split(header_text, delim)]
    first_row = [] if data_text is None else [c.strip() for c in _split(data_text, delim)]
    return _Layout(header, delim, skip, header_line, '"' in head, first_row)


def _guess_delim(line: str) -> str | None:
    counts = {d: line.count(d) for d in _DELIMITERS}
    best = max(counts, key=lambda d: counts[d])
    return best if counts[best] else None


def _raw_from_arrays(
    plan: ColumnPlan, arrays: dict[int, np.ndarray]
) -> tuple[RawTime | None, dict[str, RawChannel]]:
    time = None
    if plan.time is not None:
        tspec = plan.time
        time = RawTime(arrays[tspec.index], tspec.unit, tspec.source, tspec.layout)
    chans = {
        name: RawChannel(arrays[spec.index], spec.unit, spec.source)
        for name, spec in plan.channels.items()
    }
    # Kalibr: omega/alpha columns imply a ns "timestamp" column.
    if time is not None and time.unit is None and time.source.lower() == "timestamp" and any(
        spec.layout == "kalibr" for spec in plan.channels.values()
    ):
        time.layout = "kalibr"
    return time, chans


def _line_finder(path: Path, gz: bool, layout: _Layout) -> Callable[[int], str]:
    """Row label that finds the physical line of a data row on demand."""

    def label(i: int) -> str:
        try:
            with _open_text(path, gz) as f:
                reader = _records(f, layout)
                for k, (line_no, _rec) in enumerate(reader):
                    if k == i:
                        return f"line {line_no} (data row {i + 1})"
        except (EOFError, OSError, zlib.error, InputError):
            pass
        return f"data row {i + 1}"

    return label


def _records(f: io.TextIOBase, layout: _Layout) -> Iterator[tuple[int, list[str]]]:
    """Yield (line number, fields) for each data record, skipping blanks and comments."""
    for _ in range(layout.skip_lines):
        f.readline()
    if layout.delimiter is None:
        for k, line in enumerate(f, start=layout.skip_lines + 1):
            s = line.strip()
            if not s or s.startswith("#"):
                continue
            yield k, s.split()
        return
    reader = csv.reader(f, delimiter=layout.delimiter)
    prev = layout.skip_lines
    for rec in reader:
        line_no = prev + 1
        prev = layout.skip_lines + reader.line_num
        if not rec or (len(rec) == 1 and not rec[0].strip()):
            continue
        if rec[0].lstrip().startswith("#"):
            continue
        yield line_no, rec


def _slow_parse(path: Path, gz: bool, layout: _Layout, plan: ColumnPlan) -> dict[int, np.ndarray]:
    """Line-by-line parse of the needed columns; raises at the first bad cell."""
    idx = plan.indices()
    names = {i: layout.header[i] for i in idx}
    cols: dict[int, list[float]] = {i: [] for i in idx}
    is_int = {i: True for i in idx}
    time_index = -1 if plan.time is None else plan.time.index
    ncol = len(layout.header)
    try:
        with _open_text(path, gz) as f:
            for line_no, rec in _records(f, layout):
                if len(rec) != ncol:
                    raise InputError(
                        f"{path}, line {line_no}: {len(rec)} field(s) but the header has {ncol} "
                        "(a truncated or malformed row?); repair or delete that line"
                    )
                for i in idx:
                    cell = rec[i].strip()
                    if not cell:
                        raise InputError(
                            f"{path}, line {line_no}, column {names[i]!r}: the cell is empty; "
                            "fill it or delete the row"
                        )
                    try:
                        v: float = int(cell)
                    except ValueError:
                        try:
                            v = float(cell)
                        except ValueError:
                            if i == time_index and (ns := _parse_datetime_ns(cell)) is not None:
                                cols[i].append(ns)
                                continue
                            raise InputError(
                                f"{path}, line {line_no}, column {names[i]!r}: {cell[:40]!r} is "
                                "not a number; fix or delete that row"
                            ) from None
                        is_int[i] = False
                    cols[i].append(v)
    except (EOFError, zlib.error) as err:
        raise _gzip_error(path, err) from err
    except OSError as err:
        if gz:
            raise _gzip_error(path, err) from err
        raise InputError(f"{path}: cannot read the file ({err})") from err
    except UnicodeDecodeError as err:
        raise InputError(f"{path}: not a UTF-8 text table ({err.reason})") from err
    out: dict[int, np.ndarray] = {}
    for i in idx:
        if is_int[i] and cols[i]:
            try:
                out[i] = np.asarray(cols[i], dtype=np.int64)
                continue
            except OverflowError:
                pass
        out[i] = np.asarray(cols[i], dtype=np.float64)
    return out


def _fast_parse(path: Path, gz: bool, layout: _Layout, plan: ColumnPlan) -> dict[int, np.ndarray]:
    """pyarrow CSV parse of the needed columns (raises pyarrow errors)."""
    if layout.delimiter is None:
        return _whitespace_parse(path, gz, layout, plan)
    names = [f"c{i}" for i in range(len(layout.header))]
    idx = plan.indices()
    types: dict[str, pa.DataType] = {f"c{spec.index}": pa.float64()
                                     for spec in plan.channels.values()}
    ropts = pacsv.ReadOptions(column_names=names, skip_rows=layout.skip_lines,
                              block_size=1 << 22)
    popts = pacsv.ParseOptions(delimiter=layout.delimiter, newlines_in_values=layout.quoted)
    copts = pacsv.ConvertOptions(include_columns=[f"c{i}" for i in idx], column_types=types,
                                 null_values=[""], strings_can_be_null=False)
    stream = pa.input_stream(str(path), compression="gzip" if gz else None)
    try:
        table = pacsv.read_csv(stream, read_options=ropts, parse_options=popts,
                               convert_options=copts)
    finally:
        stream.close()
    out: dict[int, np.ndarray] = {}
    for i in idx:
        col = table.column(f"c{i}")
        if col.null_count:
            raise ValueError("nulls")
        if plan.time is not None and i == plan.time.index and pa.types.is_timestamp(col.type):
            # ISO 8601 date-times: integer ns since the epoch (naive stamps read as UTC)
            out[i] = col.cast(pa.timestamp("ns", tz=col.type.tz)).cast(pa.int64()).to_numpy()
            continue
        if not (pa.types.is_integer(col.type) or pa.types.is_floating(col.type)):
            raise ValueError("not numeric")
        out[i] = col.to_numpy()
    return out


def _whitespace_parse(path: Path, gz: bool, layout: _Layout,
                      plan: ColumnPlan) -> dict[int, np.ndarray]:
    import pandas as pd

    idx = plan.indices()
    df = pd.read_csv(path, sep=r"\s+", header=None, skiprows=layout.skip_lines, usecols=idx,
                     comment="#", compression="gzip" if gz else None, engine="c",
                     skip_blank_lines=True)
    out = {}
    for i in idx:
        arr = df[i].to_numpy()
        if arr.dtype.kind not in "fiu" or (arr.dtype.kind == "f" and np.isnan(arr).any()):
            raise ValueError("not numeric")
        out[i] = arr
    return out


def _is_datetime_text(layout: _Layout, plan: ColumnPlan) -> bool:
    """Whether the time column holds ISO date-times (converted to epoch ns)."""
    if plan.time is None or plan.time.index >= len(layout.first_row):
        return False
    cell = layout.first_row[plan.time.index]
    return bool(cell) and not _is_number(cell) and _parse_datetime_ns(cell) is not None


def _parse_datetime_ns(cell: str) -> int | None:
    """ISO 8601 date-time text -> integer ns since the epoch, else ``None``."""
    try:
        return int(np.datetime64(cell.rstrip("Z"), "ns").astype(np.int64))
    except ValueError:
        return None


def read_text_table(path: Path, opts: ReadOptions) -> list[ImuLog]:
    """Read a CSV/TSV/TXT table (optionally gzip-compressed) into log segments.

    Parameters
    ----------
    path:
        The file.
    opts:
        Validated :class:`ReadOptions`.

    Returns
    -------
    list of ImuLog
        See :func:`imubounds.io.assemble.assemble_logs`.
    """
    gz = _is_gzip(path)
    head = _read_head(path, gz)
    layout = _detect_layout(path, head)
    plan = plan_columns(layout.header, str(path), columns=opts.columns, channels=opts.channels)
    label = _line_finder(path, gz, layout)
    try:
        arrays = _fast_parse(path, gz, layout, plan)
    except (pa.ArrowException, ValueError, OSError, EOFError, zlib.error, KeyError,
            IndexError, UnicodeDecodeError):
        arrays = _slow_parse(path, gz, layout, plan)
    time, chans = _raw_from_arrays(plan, arrays)
    if time is not None and time.values.dtype.kind == "i" and _is_datetime_text(layout, plan):
        if opts.time_unit is None:
            time.unit = "ns"
    return assemble_logs(str(path), time, chans, opts, row_label=label, notes=plan.notes)


def read_parquet(path: Path, opts: ReadOptions) -> list[ImuLog]:
    """Read a Parquet file into log segments (see :func:`read_text_table`)."""
    import pyarrow.parquet as pq

    try:
        pf = pq.ParquetFile(path)
        header = list(pf.schema_arrow.names)
    except (pa.ArrowException, OSError) as err:
        raise InputError(
            f"{path}: not a readable Parquet file ({str(err).splitlines()[0][:120]}); "
            "check that it was written completely"
        ) from err
    plan = plan_columns(header, str(path), columns=opts.columns, channels=opts.channels)
    idx = plan.indices()
    try:
        table = pf.read(columns=[header[i] for i in idx])
    except (pa.ArrowException, OSError) as err:
        raise InputError(
            f"{path}: the Parquet data cannot be read ({str(err).splitlines()[0][:120]}); "
            "the file is probably corrupt or truncated"
        ) from err
    arrays: dict[int, np.ndarray] = {}
    for k, i in enumerate(idx):
        col = table.column(k)
        name = header[i]
        if col.null_count:
            first = int(np.argmax(np.asarray(col.is_null())))
            raise InputError(
                f"{path}, data row {first + 1}, column {name!r}: the value is missing (null); "
                "fill it or delete the row"
            )
        typ = col.type
        if pa.types.is_timestamp(typ) or pa.types.is_duration(typ):
            unit = typ.unit
            arr = col.cast(pa.int64()).to_numpy()
            if plan.time is not None and i == plan.time.index:
                plan = ColumnPlan(
                    type(plan.time)(plan.time.index, plan.time.source, unit, plan.time.layout),
                    plan.channels,
                    plan.notes,
                )
            arrays[i] = arr
        elif pa.types.is_integer(typ) or pa.types.is_floating(typ):
            arrays[i] = col.to_numpy()
        else:
            raise InputError(
                f"{path}, column {name!r}: type {typ} is not numeric; store numbers in it"
            )
    time, chans = _raw_from_arrays(plan, arrays)
    return assemble_logs(str(path), time, chans, opts, notes=plan.notes)
