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
from collections.abc import Callable, Iterable, Iterator, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pyarrow as pa
import pyarrow.csv as pacsv

from imubounds.errors import InputError
from imubounds.io.log import ImuLog

from .assemble import OnGap, RawChannel, RawTime, ReadOptions, assemble_logs
from .columns import ColumnPlan, plan_columns, recognise
from .magic import file_is_gzip

if TYPE_CHECKING:
    import pandas as pd
    from numpy.typing import ArrayLike

_HEAD_BYTES = 1 << 18
_DELIMITERS = ("\t", ",", ";", "|")


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
                 header_line: int, quoted: bool, first_row: list[str] | None = None,
                 decimal: str = ".", units_line: int | None = None) -> None:
        self.header = header
        self.first_row = first_row or []  # fields of the first data row, if any
        self.delimiter = delimiter  # None: runs of whitespace
        self.skip_lines = skip_lines  # physical lines before the first data line
        self.header_line = header_line  # 1-based line number of the header
        self.quoted = quoted
        self.decimal = decimal  # "," for decimal commas (with ; or tab delimiters)
        self.units_line = units_line  # 1-based line of a units row under the header
        self.notes: list[str] = []  # what the reader must say about the layout (warnings)


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


_DECIMAL_COMMA = re.compile(r"^\s*[-+]?\d*,\d+(?:[eE][-+]?\d+)?\s*$")


def _uses_decimal_comma(cells: list[str]) -> bool:
    """True when the numbers of a row are written with a decimal comma (``0,013``)."""
    commas = sum(bool(_DECIMAL_COMMA.match(c)) for c in cells)
    points = sum("." in c and _is_number(c) for c in cells)
    return commas > 0 and points == 0


def _units_row(header: list[str], cells: list[str]) -> list[str | None] | None:
    """The units of a row of units under the header (``s, deg/s, g``), else ``None``."""
    from .columns import normalise_unit

    if len(cells) != len(header) or not cells:
        return None
    if any(c.strip() and _is_number(c.strip().replace(",", ".")) for c in cells):
        return None
    units: list[str | None] = []
    known = 0
    for c in cells:
        text = c.strip().strip("[]()")
        units.append(text or None)
        if text and any(normalise_unit(text, k) is not None for k in ("gyro", "accel", "time")):
            known += 1
    return units if known else None


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
    units_line = None
    units = _units_row(header, first_row) if not first_is_data and nxt is not None else None
    if units is not None and nxt is not None:
        # A row of units under the header: fold each unit into its column name
        # ("gyro_x [deg/s]") unless the name states one, and skip the row.
        from .columns import recognise, split_bracket_unit

        for i, u in enumerate(units):
            rec = recognise(header[i])
            if u and split_bracket_unit(header[i])[1] is None and (rec is None or rec.unit is None):
                header[i] = f"{header[i]} [{u}]"
        units_line = nxt + 1
        skip = nxt + 1
        after = next((j for j in range(nxt + 1, len(lines)) if lines[j].strip()
                      and not lines[j].lstrip().startswith("#")), None)
        first_row = [] if after is None else [c.strip() for c in _split(lines[after], delim)]
    decimal = "," if delim not in (",", None) and _uses_decimal_comma(first_row) else "."
    layout = _Layout(header, delim, skip, header_line, '"' in head, first_row, decimal,
                     units_line)
    if units is not None and units_line is not None:
        shown = ", ".join(u or "-" for u in units)
        layout.notes.append(
            f"{path}: line {units_line} under the header is a row of units ({shown}): read "
            "as the columns' units (where a name states none), not as data"
        )
    return layout


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


def _cell_value(cell: str, decimal: str) -> float | int | None:
    """A cell as int or float (``None`` if it is not a number)."""
    try:
        return int(cell)
    except ValueError:
        pass
    try:
        return float(cell.replace(",", ".") if decimal == "," else cell)
    except ValueError:
        return None


def _field_count_problem(rec: list[str], ncol: int, layout: _Layout) -> str:
    """Why a record has the wrong number of fields, with what to do."""
    delimiter = layout.delimiter
    text = (delimiter or " ").join(rec)
    other = [d for d in _DELIMITERS if d != delimiter and d in text and d != ","]
    if delimiter != "," and layout.decimal != "," and "," in text:
        other.append(",")
    if len(rec) < ncol and other:
        return (
            f"{len(rec)} field(s) but the header has {ncol}: the row seems separated by "
            f"{other[0]!r}, the header by {delimiter or 'spaces'!r}; use one separator "
            "throughout"
        )
    return (
        f"{len(rec)} field(s) but the header has {ncol} (a truncated or malformed row?); "
        "repair or delete that line"
    )


def _slow_blocks(
    path: Path, gz: bool, layout: _Layout, plan: ColumnPlan, rows: int, skip_records: int = 0
) -> Iterator[dict[int, np.ndarray]]:
    """Line-by-line parse of the needed columns in blocks of ``rows`` records.

    Raises :class:`InputError` at the first bad record (naming its line and
    column). ``skip_records`` data records are passed over first (already read).
    """
    idx = plan.indices()
    names = {i: layout.header[i] for i in idx}
    time_index = -1 if plan.time is None else plan.time.index
    ncol = len(layout.header)

    def block(cols: dict[int, list[float]], is_int: dict[int, bool]) -> dict[int, np.ndarray]:
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

    cols: dict[int, list[float]] = {i: [] for i in idx}
    is_int = dict.fromkeys(idx, True)
    count = 0
    try:
        with _open_text(path, gz) as f:
            for k, (line_no, rec) in enumerate(_records(f, layout)):
                if k < skip_records:
                    continue
                if len(rec) != ncol:
                    raise InputError(
                        f"{path}, line {line_no}: {_field_count_problem(rec, ncol, layout)}"
                    )
                for i in idx:
                    cell = rec[i].strip()
                    if not cell:
                        raise InputError(
                            f"{path}, line {line_no}, column {names[i]!r}: the cell is empty; "
                            "fill it or delete the row"
                        )
                    v = _cell_value(cell, layout.decimal)
                    if v is None:
                        if i == time_index and (ns := _parse_datetime_ns(cell)) is not None:
                            cols[i].append(ns)
                            continue
                        raise InputError(
                            f"{path}, line {line_no}, column {names[i]!r}: {cell[:40]!r} is "
                            "not a number; fix or delete that row"
                        )
                    if isinstance(v, float):
                        is_int[i] = False
                    cols[i].append(v)
                count += 1
                if count == rows:
                    yield block(cols, is_int)
                    cols = {i: [] for i in idx}
                    is_int = dict.fromkeys(idx, True)
                    count = 0
    except (EOFError, zlib.error) as err:
        raise _gzip_error(path, err) from err
    except OSError as err:
        if gz:
            raise _gzip_error(path, err) from err
        raise InputError(f"{path}: cannot read the file ({err})") from err
    except UnicodeDecodeError as err:
        raise InputError(f"{path}: not a UTF-8 text table ({err.reason})") from err
    except csv.Error as err:
        raise InputError(f"{path}: malformed text ({err}); repair the file") from err
    if count or not skip_records:
        yield block(cols, is_int)


def _slow_parse(path: Path, gz: bool, layout: _Layout, plan: ColumnPlan) -> dict[int, np.ndarray]:
    """Line-by-line parse of the whole file; raises at the first bad cell."""
    blocks = list(_slow_blocks(path, gz, layout, plan, rows=1 << 20))
    out: dict[int, np.ndarray] = {}
    for i in plan.indices():
        parts = [b[i] for b in blocks if b[i].size] or [blocks[0][i]]
        out[i] = parts[0] if len(parts) == 1 else np.concatenate(parts)
    return out


def _arrow_options(layout: _Layout, plan: ColumnPlan) -> tuple[Any, Any, Any]:
    names = [f"c{i}" for i in range(len(layout.header))]
    idx = plan.indices()
    types: dict[str, pa.DataType] = {f"c{spec.index}": pa.float64()
                                     for spec in plan.channels.values()}
    ropts = pacsv.ReadOptions(column_names=names, skip_rows=layout.skip_lines,
                              block_size=1 << 22)
    popts = pacsv.ParseOptions(delimiter=layout.delimiter, newlines_in_values=layout.quoted)
    copts = pacsv.ConvertOptions(include_columns=[f"c{i}" for i in idx], column_types=types,
                                 null_values=[""], strings_can_be_null=False,
                                 decimal_point=layout.decimal)
    return ropts, popts, copts


def _arrow_arrays(table: Any, plan: ColumnPlan) -> dict[int, np.ndarray]:
    """Numpy arrays of the needed columns of a pyarrow table or record batch."""
    out: dict[int, np.ndarray] = {}
    for i in plan.indices():
        col = table.column(f"c{i}")
        if col.null_count:
            raise ValueError("nulls")
        if plan.time is not None and i == plan.time.index and pa.types.is_timestamp(col.type):
            # ISO 8601 date-times: integer ns since the epoch (naive stamps read as UTC)
            out[i] = col.cast(pa.timestamp("ns", tz=col.type.tz)).cast(pa.int64()).to_numpy()
            continue
        if not (pa.types.is_integer(col.type) or pa.types.is_floating(col.type)):
            raise ValueError("not numeric")
        out[i] = _numeric_to_numpy(col)
    return out


def _numeric_to_numpy(col: Any) -> np.ndarray:
    """A null-free integer or float pyarrow column as a new (writable) numpy array.

    Read from the value buffers: pyarrow's ``to_numpy`` imports pandas (about 0.3 s
    of every CSV read), the values are the same.
    """
    dtype = np.dtype(col.type.to_pandas_dtype())
    parts = [
        np.frombuffer(c.buffers()[1], dtype=dtype)[c.offset : c.offset + len(c)]
        for c in getattr(col, "chunks", [col])
    ]
    return np.concatenate(parts) if parts else np.empty(0, dtype=dtype)


_FAST_ERRORS = (pa.ArrowException, ValueError, OSError, EOFError, zlib.error, KeyError,
                IndexError, UnicodeDecodeError)


def iter_text_blocks(
    path: Path, gz: bool, layout: _Layout, plan: ColumnPlan, rows: int
) -> Iterator[dict[int, np.ndarray]]:
    """The needed columns in blocks of at most ``rows`` rows (out-of-core reading).

    pyarrow's streaming CSV reader (the parser of the in-memory fast path, so
    values are identical); from the first block it cannot parse, the
    line-by-line parser takes over, which either reads on (comment lines in
    the data) or raises :class:`InputError` naming the bad line.
    """
    rows = max(1, int(rows))
    done = 0
    try:
        if layout.delimiter is None:
            import pandas as pd

            reader = pd.read_csv(
                path, sep=r"\s+", header=None, skiprows=layout.skip_lines,
                usecols=plan.indices(), comment="#", compression="gzip" if gz else None,
                engine="c", skip_blank_lines=True, chunksize=rows,
                decimal=layout.decimal,
            )
            for df in reader:
                arrs = {i: df[i].to_numpy() for i in plan.indices()}
                if any(a.dtype.kind not in "fiu" or (a.dtype.kind == "f" and np.isnan(a).any())
                       for a in arrs.values()):
                    raise ValueError("not numeric")
                yield arrs
                done += len(df)
            return
        # the time column's type is inferred from the first block (int ns, float s or
        # ISO date-times); a later row that does not fit goes to the line parser
        ropts, popts, copts = _arrow_options(layout, plan)
        ropts.block_size = max(1 << 20, min(1 << 26, rows * 16 * max(1, len(layout.header))))
        stream = pa.input_stream(str(path), compression="gzip" if gz else None)
        try:
            reader = pacsv.open_csv(stream, read_options=ropts, parse_options=popts,
                                    convert_options=copts)
            for batch in reader:
                arrs = _arrow_arrays(batch, plan)
                m = batch.num_rows
                for a in range(0, m, rows):
                    yield {i: v[a : a + rows] for i, v in arrs.items()}
                done += m
        finally:
            stream.close()
        return
    except _FAST_ERRORS:
        pass
    yield from _slow_blocks(path, gz, layout, plan, rows, skip_records=done)


def _fast_parse(path: Path, gz: bool, layout: _Layout, plan: ColumnPlan) -> dict[int, np.ndarray]:
    """pyarrow CSV parse of the needed columns (raises pyarrow errors)."""
    if layout.delimiter is None:
        return _whitespace_parse(path, gz, layout, plan)
    ropts, popts, copts = _arrow_options(layout, plan)
    stream = pa.input_stream(str(path), compression="gzip" if gz else None)
    try:
        table = pacsv.read_csv(stream, read_options=ropts, parse_options=popts,
                               convert_options=copts)
    finally:
        stream.close()
    return _arrow_arrays(table, plan)


def _whitespace_parse(path: Path, gz: bool, layout: _Layout,
                      plan: ColumnPlan) -> dict[int, np.ndarray]:
    import pandas as pd

    idx = plan.indices()
    df = pd.read_csv(path, sep=r"\s+", header=None, skiprows=layout.skip_lines, usecols=idx,
                     comment="#", compression="gzip" if gz else None, engine="c",
                     skip_blank_lines=True, decimal=layout.decimal)
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
    gz = file_is_gzip(path)
    head = _read_head(path, gz)
    layout = _detect_layout(path, head)
    plan = plan_columns(layout.header, str(path), columns=opts.columns, channels=opts.channels)
    label = _line_finder(path, gz, layout)
    try:
        arrays = _fast_parse(path, gz, layout, plan)
    except _FAST_ERRORS:
        arrays = _slow_parse(path, gz, layout, plan)
    time, chans = _raw_from_arrays(plan, arrays)
    if time is not None and time.values.dtype.kind == "i" and _is_datetime_text(layout, plan):
        if opts.time_unit is None:
            time.unit = "ns"
    return assemble_logs(str(path), time, chans, opts, row_label=label,
                         notes=[*layout.notes, *plan.notes])


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


def read_frame(
    data: pd.DataFrame | Mapping[str, ArrayLike],
    *,
    rate_hz: float | None = None,
    columns: Mapping[str, str] | None = None,
    gyro_unit: str | None = None,
    accel_unit: str | None = None,
    time_unit: str | None = None,
    gap_tolerance: float | None = None,
    on_gap: OnGap = "refuse",
    channels: Iterable[str] | None = None,
    source: str = "<DataFrame>",
    unusual_rate: bool = False,
) -> ImuLog:
    """An :class:`ImuLog` from a :class:`pandas.DataFrame` or a mapping of columns,
    with the recognition, unit conversion and checks of a file read.

    Columns are recognised by name as in a CSV file (``time_s``, ``gyro_x_dps``,
    ``accel_z_g``, ...; a bare ``gyro_x`` is rad/s and ``accel_x`` m/s^2, with a
    warning in ``ImuLog.warnings``). A :class:`pandas.DatetimeIndex` or
    :class:`pandas.TimedeltaIndex` is the time, and so is an index whose name is
    recognised as time (``time_s``); otherwise give a time column or ``rate_hz``.
    The other parameters are those of :func:`imubounds.io.read_imu`; with gaps and
    ``on_gap="split"`` the longest segment is returned, with a warning.

    Raises
    ------
    InputError
        Not a table, no IMU column, non-numeric or missing values, bad time stamps.
    OptionError
        Invalid options (no time and no ``rate_hz``, an unknown unit, ...).
    """
    import pandas as pd

    opts = ReadOptions(
        rate_hz=rate_hz,
        columns=columns,
        gyro_unit=gyro_unit,
        accel_unit=accel_unit,
        time_unit=time_unit,
        gap_tolerance=gap_tolerance,
        on_gap=on_gap,
        channels=None if channels is None else tuple(channels),
        unusual_rate=bool(unusual_rate),
    ).validated()
    if isinstance(data, pd.DataFrame):
        df = data
    elif isinstance(data, Mapping):
        try:
            df = pd.DataFrame({str(k): np.asarray(v) for k, v in data.items()})
        except ValueError as err:
            raise InputError(f"{source}: the columns cannot form a table ({err})") from err
    else:
        raise InputError(
            f"{source}: expected a pandas DataFrame or a mapping of column name -> samples, "
            f"got {type(data).__name__}"
        )
    idx = df.index
    if isinstance(idx, pd.DatetimeIndex | pd.TimedeltaIndex):
        ns = idx.asi8 if isinstance(idx, pd.TimedeltaIndex) else idx.as_unit("ns").asi8
        df = df.reset_index(drop=True)
        df.insert(0, "timestamp_ns", np.asarray(ns, dtype=np.int64))
    elif idx.name is not None and recognise(str(idx.name)) is not None:
        df = df.reset_index()
    header = [str(c) for c in df.columns]
    if len(set(header)) != len(header):
        raise InputError(f"{source}: column names repeat; give each column its own name")
    plan = plan_columns(header, source, columns=opts.columns, channels=opts.channels)
    arrays: dict[int, np.ndarray] = {}
    for i in plan.indices():
        col = df.iloc[:, i]
        if col.isna().any():
            first = int(np.flatnonzero(col.isna().to_numpy())[0])
            raise InputError(
                f"{source}, position {first}, column {header[i]!r}: the value is missing "
                "(NaN/None); fill it or drop the row"
            )
        values = col.to_numpy()
        if values.dtype.kind not in "iuf":
            raise InputError(
                f"{source}, column {header[i]!r}: type {values.dtype} is not numeric; "
                "store numbers in it"
            )
        arrays[i] = values
    time, chans = _raw_from_arrays(plan, arrays)
    logs = assemble_logs(
        source, time, chans, opts, row_label=lambda i: f"position {i}", notes=plan.notes
    )
    if len(logs) == 1:
        return logs[0]
    k = max(range(len(logs)), key=lambda i: logs[i].n_samples)
    best = logs[k]
    best.warnings.insert(
        0,
        f"{source}: {len(logs)} contiguous segments found; using segment {k + 1} "
        f"(the longest, {best.n_samples} samples from t={best.t[0]:.6g} s)",
    )
    return best
