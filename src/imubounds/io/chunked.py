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
Time stamps, when present, give the rate (median step of the first block); gaps
are *not* checked out-of-core (the in-memory reader does that).
"""

from __future__ import annotations

import gzip
import math
import warnings
import zlib
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from imubounds.errors import InputError, OptionError
from imubounds.io.log import IMU_CHANNELS
from imubounds.units import ACCEL_UNITS, GYRO_UNITS, TIME_UNITS

from .assemble import PLAUSIBLE_RATE_HZ
from .columns import ColumnPlan, normalise_unit, plan_columns

__all__ = ["CHUNKED_SUFFIXES", "ChunkedLog", "open_chunked"]

#: File endings :func:`open_chunked` understands, longest first where they overlap.
CHUNKED_SUFFIXES: tuple[str, ...] = (
    ".csv.gz", ".tsv.gz", ".txt.gz", ".dat.gz", ".csv", ".tsv", ".txt", ".dat",
    ".parquet", ".pq", ".parq", ".npy", ".f64", ".bin", ".raw", ".f32", ".h5", ".hdf5",
)  # fmt: skip


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
        Things a user should see.
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

        Raises
        ------
        InputError
            Unreadable data (naming file, row and column).
        """
        rows = max(1, int(rows))
        if self.fmt == "text":
            yield from self._iter_text(rows)
        elif self.fmt == "parquet":
            yield from self._iter_parquet(rows)
        elif self.fmt in ("npy", "raw"):
            yield from self._iter_binary(rows)
        elif self.fmt == "hdf5":
            yield from self._iter_hdf5(rows)
        else:  # pragma: no cover - guarded by open_chunked
            raise ValueError(self.fmt)

    def _iter_binary(self, rows: int) -> Iterator[dict[str, np.ndarray]]:
        # plain reads, not the memory map: pages of a map would count in RSS
        arr = self._sources["array"]
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
                    block = block.reshape(k, arr.shape[1])
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
                    out[c] = _si(np.ascontiguousarray(v, dtype=np.float64), self.factors[c])
                yield out

    def _iter_text(self, rows: int) -> Iterator[dict[str, np.ndarray]]:
        import pandas as pd

        plan: ColumnPlan = self._extra["plan"]
        names = {spec.index: c for c, spec in plan.channels.items()}
        opener = gzip.open if self._extra["gz"] else open
        row0 = 0
        try:
            with opener(self.path, "rb") as f:  # type: ignore[operator]
                with warnings.catch_warnings():
                    # round_trip parsing is what makes the values bit-identical to the
                    # in-memory reader; pandas 3 deprecates the option but honours it
                    warnings.simplefilter("ignore")
                    reader = pd.read_csv(
                        f,
                        sep=self._extra["sep"],
                        usecols=sorted(names),
                        header=0,
                        chunksize=rows,
                        dtype=np.float64,
                        engine="c",
                        float_precision="round_trip",
                        skipinitialspace=True,
                    )
                for df in reader:
                    out: dict[str, np.ndarray] = {}
                    for i, c in names.items():
                        v = df.iloc[:, sorted(names).index(i)].to_numpy(np.float64)
                        out[c] = _si(v, self.factors[c])
                    row0 += len(df)
                    yield out
        except (ValueError, EOFError, OSError, zlib.error) as err:
            raise InputError(
                f"{self.path}: cannot read the rows after data row {row0} "
                f"({str(err).splitlines()[0][:120]}); fix or remove the bad row"
            ) from err

    def _iter_parquet(self, rows: int) -> Iterator[dict[str, np.ndarray]]:
        import pyarrow as pa
        import pyarrow.parquet as pq

        cols: dict[str, str] = self._sources["columns"]
        try:
            pf = pq.ParquetFile(self.path)
            for batch in pf.iter_batches(batch_size=rows, columns=list(cols.values())):
                yield {
                    c: _si(
                        batch.column(src).to_numpy(zero_copy_only=False).astype(np.float64),
                        self.factors[c],
                    )
                    for c, src in cols.items()
                }
        except (pa.ArrowException, OSError) as err:
            raise InputError(
                f"{self.path}: the Parquet data cannot be read ({str(err).splitlines()[0][:120]})"
            ) from err

    def _iter_hdf5(self, rows: int) -> Iterator[dict[str, np.ndarray]]:
        import h5py

        cols: dict[str, tuple[str, str | None]] = self._sources["columns"]
        n = int(self.n_samples or 0)
        with h5py.File(self.path, "r") as f:
            for a in range(0, n, rows):
                out = {}
                for c, (dset, fld) in cols.items():
                    d = f[dset]
                    block = d[a : a + rows] if fld is None else d[a : a + rows][fld]
                    out[c] = _si(np.asarray(block, dtype=np.float64), self.factors[c])
                yield out


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
    channel: str,
    stated: str | None,
    gyro_unit: str | None,
    accel_unit: str | None,
    warnings: list[str],
    source: str,
) -> tuple[str, float]:
    kind = channel.split("_")[0]
    override = gyro_unit if kind == "gyro" else accel_unit
    table = GYRO_UNITS if kind == "gyro" else ACCEL_UNITS
    if override is not None:
        key = normalise_unit(override, kind)
        if key is None:
            raise OptionError(
                f"--{kind}-unit {override!r} is not known; use one of {', '.join(table)}"
            )
        return key, table[key]
    if stated is not None:
        return stated, table[stated]
    default = "rad/s" if kind == "gyro" else "m/s^2"
    warnings.append(f"{source}: no unit stated for {channel}; assumed {default}")
    return default, table[default]


def _rate_from_time(
    t: np.ndarray,
    unit: str | None,
    time_unit: str | None,
    source: str,
    rate_hz: float | None = None,
) -> float:
    """Rate as :func:`assemble_logs` finds it: 1/median step rounded to 9 digits."""
    if t.size < 2:
        raise InputError(f"{source}: fewer than 2 rows; cannot find the sample rate")
    step = float(np.median(np.diff(t.astype(np.float64))))
    if not step > 0:
        raise InputError(f"{source}: time stamps do not increase; check the time column")
    key = time_unit or unit
    factor = None
    if key is not None:
        factor = TIME_UNITS[normalise_unit(key, "time") or key]
    else:
        for k in ("s", "ms", "us", "ns"):
            if PLAUSIBLE_RATE_HZ[0] <= 1.0 / (step * TIME_UNITS[k]) <= PLAUSIBLE_RATE_HZ[1]:
                factor = TIME_UNITS[k]
                break
    if factor is None:
        raise InputError(f"{source}: time step {step:g} gives no plausible rate; give --time-unit")
    med_dt = float(np.median(np.diff(t.astype(np.float64)) * factor))
    rate = float(f"{1.0 / med_dt:.9g}")
    if rate_hz is not None:
        if abs(med_dt * float(rate_hz) - 1.0) > 0.01:
            raise OptionError(
                f"--rate {rate_hz:g} Hz disagrees with the time stamps of {source} ({rate:g} Hz);"
                " drop --rate or fix it"
            )
        return float(rate_hz)
    return rate


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
    channels: tuple[str, ...] | list[str] | None = None,
    gyro_unit: str | None = None,
    accel_unit: str | None = None,
    time_unit: str | None = None,
) -> ChunkedLog:
    """Open a (possibly huge) IMU log for chunked reading.

    Parameters are those of :func:`imubounds.io.read_imu`; for binary
    arrays without names ``channels`` names the columns in order.

    Raises
    ------
    InputError, OptionError
        Unreadable file, no IMU column, missing rate, bad option.
    """
    p = Path(path)
    if not p.is_file():
        raise InputError(f"no such file: {p}; check the path")
    if p.stat().st_size == 0:
        raise InputError(f"{p} is empty; give a file with data")
    suf = _suffix(p)
    chans = None if channels is None else tuple(channels)
    warnings: list[str] = []
    cols = dict(columns) if columns else None

    def finish(
        fmt: str,
        plan_ch: dict[str, Any],
        stated: dict[str, str | None],
        rate: float,
        n: int | None,
        rereadable: bool,
        sources: dict[str, Any],
        extra: dict[str, Any] | None = None,
    ) -> ChunkedLog:
        units, factors = {}, {}
        for c in plan_ch:
            units[c], factors[c] = _unit_factor(
                c, stated.get(c), gyro_unit, accel_unit, warnings, str(p)
            )
        return ChunkedLog(
            p,
            fmt,
            list(plan_ch),
            rate,
            n,
            units,
            factors,
            rereadable,
            warnings,
            sources,
            extra or {},
        )

    if suf.endswith((".csv", ".tsv", ".txt", ".dat", ".gz")):
        import pandas as pd

        gz = suf.endswith(".gz")
        try:
            with (
                gzip.open(p, "rt", encoding="utf-8-sig") if gz else open(p, encoding="utf-8-sig")
            ) as f:
                header_line = f.readline()
                head_rows = [f.readline() for _ in range(200)]
        except (OSError, EOFError, UnicodeDecodeError, zlib.error) as err:
            raise InputError(f"{p}: cannot read the header ({err})") from err
        sep: str = r"\s+"
        for cand in (",", ";", "\t"):
            if cand in header_line:
                sep = cand
                break
        header = [
            h.strip()
            for h in (header_line.strip().split(sep) if sep != r"\s+" else header_line.split())
        ]
        plan = plan_columns(header, str(p), columns=cols, channels=chans)
        stated = {c: s.unit for c, s in plan.channels.items()}
        if plan.time is not None:
            import io

            body = "".join(r for r in head_rows if r.strip())
            df = pd.read_csv(io.StringIO(header_line + body), sep=sep, skipinitialspace=True)
            t = df.iloc[:, plan.time.index].to_numpy(np.float64)
            rate = _rate_from_time(t, plan.time.unit, time_unit, str(p), rate_hz)
        else:
            rate = _check_rate(rate_hz, str(p))
        return finish(
            "text",
            dict(plan.channels),
            stated,
            rate,
            None,
            False,
            {},
            {"plan": plan, "gz": gz, "sep": sep},
        )

    if suf in (".parquet", ".pq", ".parq"):
        import pyarrow as pa
        import pyarrow.parquet as pq

        try:
            pf = pq.ParquetFile(p)
            header = list(pf.schema_arrow.names)
            n = int(pf.metadata.num_rows)
        except (pa.ArrowException, OSError) as err:
            raise InputError(f"{p}: not a readable Parquet file ({str(err)[:120]})") from err
        plan = plan_columns(header, str(p), columns=cols, channels=chans)
        if plan.time is not None:
            first = pf.read_row_group(0, columns=[plan.time.source]).column(0)
            t = (
                first.cast(pa.int64()).to_numpy()
                if pa.types.is_timestamp(first.type)
                else first.to_numpy()
            )
            unit = first.type.unit if pa.types.is_timestamp(first.type) else plan.time.unit
            rate = _rate_from_time(np.asarray(t[:100_000]), unit, time_unit, str(p), rate_hz)
        else:
            rate = _check_rate(rate_hz, str(p))
        srcs = {c: s.source for c, s in plan.channels.items()}
        return finish(
            "parquet",
            dict(plan.channels),
            {c: s.unit for c, s in plan.channels.items()},
            rate,
            n,
            True,
            {"columns": srcs},
        )

    if suf in (".npy", ".f64", ".bin", ".raw", ".f32"):
        if suf == ".npy":
            try:
                arr = np.load(p, mmap_mode="r")
            except (ValueError, OSError) as err:
                raise InputError(f"{p}: not a readable .npy file ({err})") from err
        else:
            dt = np.dtype("<f4") if suf == ".f32" else np.dtype("<f8")
            arr = np.memmap(p, dtype=dt, mode="r")
        if arr.dtype.names:
            header = list(arr.dtype.names)
            plan = plan_columns(header, str(p), columns=cols, channels=chans)
            if plan.time is not None:
                t = np.asarray(arr[plan.time.source][:100_000], dtype=np.float64)
                rate = _rate_from_time(t, plan.time.unit, time_unit, str(p), rate_hz)
            else:
                rate = _check_rate(rate_hz, str(p))
            srcs: dict[str, Any] = {c: s.source for c, s in plan.channels.items()}
            return finish(
                "npy",
                dict(plan.channels),
                {c: s.unit for c, s in plan.channels.items()},
                rate,
                int(arr.shape[0]),
                True,
                {"array": arr, "columns": srcs},
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
        if arr.ndim not in (1, 2):
            raise InputError(f"{p}: array of shape {arr.shape}; expected (N,) or (N, C)")
        rate = _check_rate(rate_hz, str(p))
        srcs = {c: (i if arr.ndim == 2 else 0) for i, c in enumerate(names)}
        order = {c: srcs[c] for c in IMU_CHANNELS if c in srcs}
        return finish(
            "npy" if suf == ".npy" else "raw",
            dict.fromkeys(order),
            {},
            rate,
            int(arr.shape[0]),
            True,
            {"array": arr, "columns": order},
        )

    # HDF5
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
        plan = plan_columns(header, str(p), columns=cols, channels=chans)
        used = [found[s.index] for s in plan.channels.values()]
        lengths = {n for _, _, _, n in used}
        if len(lengths) != 1:
            raise InputError(f"{p}: the channel datasets have different lengths {sorted(lengths)}")
        n = lengths.pop()
        if plan.time is not None:
            _, dset, fld, _ = found[plan.time.index]
            d = f[dset]
            t = d[:100_000] if fld is None else d[:100_000][fld]
            rate = _rate_from_time(
                np.asarray(t, dtype=np.float64), plan.time.unit, time_unit, str(p), rate_hz
            )
        else:
            rate = _check_rate(rate_hz, str(p))
        srcs = {c: (found[s.index][1], found[s.index][2]) for c, s in plan.channels.items()}
    return finish(
        "hdf5",
        dict(plan.channels),
        {c: s.unit for c, s in plan.channels.items()},
        rate,
        n,
        True,
        {"columns": srcs},
    )
