"""Read IMU logs from files into :class:`imubounds.io.log.ImuLog` (SI units).

``read_imu`` dispatches on the file type through a small registry: each
format is a function ``read(path: Path, opts: ReadOptions) -> list[ImuLog]``
registered with the file suffixes it owns and, optionally, a test on the
first bytes of the file (for files with an unexpected suffix). New formats
(ROS bags, ULog, HDF5, NMEA) plug in with :func:`register_reader`, which also
accepts ``"module:function"`` strings so that optional dependencies are only
imported when such a file is read.

A format that also holds a whole drive (ROS bags, ULog, NMEA captures) registers its
drive reader in the same entry (``read_drive``): :func:`imubounds.io.read_drive` finds
it here by the detected layout instead of importing the format module, so no format
reader and the drive assembly import each other.

Every reader hands its raw columns to
:func:`imubounds.io.assemble.assemble_logs`, so unit conversion, time
checks and gap handling behave the same for every format.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any

from imubounds.errors import InputError
from imubounds.io.log import ImuLog

from .assemble import OnGap, ReadOptions, assemble_logs
from .columns import parse_column_map, recognise
from .magic import is_bag, is_gzip, is_hdf5, is_parquet, is_ulog
from .validate import check_input_path

__all__ = [
    "ReadOptions",
    "ReaderEntry",
    "ReaderFunc",
    "assemble_logs",
    "bundled_static_log",
    "find_reader",
    "parse_column_map",
    "read_imu",
    "read_imu_segments",
    "reader_entry",
    "recognise",
    "register_reader",
    "registered_readers",
    "unregister_reader",
]

ReaderFunc = Callable[[Path, ReadOptions], list[ImuLog]]
SniffFunc = Callable[[bytes], bool]
SniffDirFunc = Callable[[Path], bool]
#: ``read_drive(files, settings, options) -> Drive``: ``files`` as
#: :func:`imubounds.io.drive.readers.detect_layout` found them, the drive's
#: :class:`~imubounds.io.drive.DriveSettings`, and the format's options of
#: :func:`imubounds.io.read_drive` (``topics``, ``imu_frame``, ...).
DriveReaderFunc = Callable[[Mapping[str, Any], Any, Mapping[str, Any]], Any]

#: File name of the bundled 45-minute extract of the ADIS16405 static log.
BUNDLED_STATIC_LOG = "adis16405_imu1_extract.csv.gz"


@dataclass(frozen=True)
class ReaderEntry:
    """A registered format.

    Attributes
    ----------
    name:
        Short format name (``"csv"``, ``"parquet"``, ...).
    suffixes:
        Lower-case file name endings it owns (``".csv.gz"``, ``".parquet"``).
    read:
        The reader, or ``"module:function"`` to import on first use.
    sniff:
        Optional test on the first 64 bytes, used when no suffix matches.
    sniff_dir:
        Optional test of a directory (formats stored as a folder, such as a
        ROS 2 bag); without it directories are refused.
    read_drive:
        Optional drive reader of the format (:data:`DriveReaderFunc`, or
        ``"module:function"``), for :func:`imubounds.io.read_drive`.
    """

    name: str
    suffixes: tuple[str, ...]
    read: ReaderFunc | str
    sniff: SniffFunc | None = None
    sniff_dir: SniffDirFunc | None = None
    read_drive: DriveReaderFunc | str | None = None

    def load(self) -> ReaderFunc:
        """The reader function (importing it if registered by name)."""
        if callable(self.read):
            return self.read
        module, _, func = self.read.partition(":")
        reader: ReaderFunc = getattr(importlib.import_module(module), func)
        return reader

    def load_drive(self) -> DriveReaderFunc:
        """The drive reader (importing it if registered by name)."""
        if self.read_drive is None:
            raise InputError(f"the {self.name} format holds no drive")
        if callable(self.read_drive):
            return self.read_drive
        module, _, func = self.read_drive.partition(":")
        reader: DriveReaderFunc = getattr(importlib.import_module(module), func)
        return reader


_REGISTRY: dict[str, ReaderEntry] = {}


def register_reader(
    name: str,
    read: ReaderFunc | str,
    *,
    suffixes: Iterable[str] = (),
    sniff: SniffFunc | None = None,
    sniff_dir: SniffDirFunc | None = None,
    read_drive: DriveReaderFunc | str | None = None,
    replace: bool = False,
) -> ReaderEntry:
    """Register a file format for :func:`read_imu`.

    Parameters
    ----------
    name:
        Format name; must be new unless ``replace``.
    read:
        ``read(path, opts) -> list[ImuLog]`` or ``"module:function"``.
    suffixes:
        File name endings, e.g. ``(".bag",)``; matched case-insensitively,
        longest first.
    sniff:
        ``sniff(first_64_bytes) -> bool`` for files whose suffix is unknown.
    sniff_dir:
        ``sniff_dir(directory) -> bool`` for formats stored as a directory.
    read_drive:
        The format's drive reader (:data:`DriveReaderFunc` or ``"module:function"``).
    replace:
        Allow replacing an existing registration.
    """
    if name in _REGISTRY and not replace:
        raise ValueError(f"reader {name!r} is already registered")
    entry = ReaderEntry(name, tuple(s.lower() for s in suffixes), read, sniff, sniff_dir,
                        read_drive)
    _REGISTRY[name] = entry
    return entry


def unregister_reader(name: str) -> None:
    """Remove a registered format (no error if it is not registered)."""
    _REGISTRY.pop(name, None)


def registered_readers() -> list[ReaderEntry]:
    """All registered formats, in registration order."""
    return list(_REGISTRY.values())


def reader_entry(name: str) -> ReaderEntry:
    """The registered format ``name`` (``"rosbag"``, ``"nmea"``, ...)."""
    try:
        return _REGISTRY[name]
    except KeyError:
        raise InputError(
            f"no reader {name!r} is registered (registered: {', '.join(_REGISTRY)})"
        ) from None


def _sniff_text(head: bytes) -> bool:
    if is_gzip(head):
        return True
    try:
        head.decode("utf-8")
    except UnicodeDecodeError:
        # The 64-byte cut may split a multi-byte character.
        try:
            head[:-3].decode("utf-8")
        except UnicodeDecodeError:
            return False
    return b"\x00" not in head


register_reader(
    "parquet",
    "imubounds.io.table:read_parquet",
    suffixes=(".parquet", ".pq", ".parq"),
    sniff=is_parquet,
)
register_reader(
    "rosbag",
    "imubounds.io.rosbag:read_rosbag",
    suffixes=(".bag", ".db3", ".mcap"),
    sniff=is_bag,
    sniff_dir=lambda d: (d / "metadata.yaml").is_file(),
    read_drive="imubounds.io.rosbag:drive_from_files",
)
register_reader(
    "ulog",
    "imubounds.io.ulog:read_ulog",
    suffixes=(".ulg", ".ulog"),
    sniff=is_ulog,
    read_drive="imubounds.io.ulog:drive_from_files",
)
register_reader(
    "hdf5",
    "imubounds.io.hdf5:read_hdf5",
    suffixes=(".h5", ".hdf5", ".hdf", ".he5"),
    sniff=is_hdf5,
)
register_reader(
    "nmea",
    "imubounds.io.nmea:read_nmea_imu",
    suffixes=(".nmea", ".nmea.txt"),
    read_drive="imubounds.io.nmea:drive_from_files",
)
register_reader(
    "table",
    "imubounds.io.table:read_text_table",
    suffixes=(".csv", ".csv.gz", ".tsv", ".tsv.gz", ".txt", ".txt.gz", ".dat", ".dat.gz"),
    sniff=_sniff_text,
)


def find_reader(path: str | Path) -> ReaderEntry:
    """The registered format for ``path``: by suffix, else by its first bytes.

    Raises
    ------
    InputError
        Missing file, a directory, a named pipe or device (refused before
        opening: :func:`imubounds.io.validate.check_input_path`), or an unknown
        format.
    """
    p = check_input_path(path, allow_dir=True)
    if p.is_dir():
        for entry in _REGISTRY.values():
            if entry.sniff_dir is not None and entry.sniff_dir(p):
                return entry
        raise InputError(f"{p} is a directory; give an IMU log file (or a ROS 2 bag directory)")
    lower = p.name.lower()
    best: tuple[int, ReaderEntry] | None = None
    for entry in _REGISTRY.values():
        for suf in entry.suffixes:
            if lower.endswith(suf) and (best is None or len(suf) > best[0]):
                best = (len(suf), entry)
    if best is not None:
        return best[1]
    try:
        with open(p, "rb") as f:
            head = f.read(64)
    except OSError as err:
        raise InputError(f"cannot open {p}: {err.strerror}") from err
    if not head:
        raise InputError(f"{p} is empty; give a file with a header line and data rows")
    # Binary formats first: their magic bytes are specific.
    for entry in sorted(_REGISTRY.values(), key=lambda e: e.name == "table"):
        if entry.sniff is not None and entry.sniff(head):
            return entry
    known = sorted({s for e in _REGISTRY.values() for s in e.suffixes})
    raise InputError(f"{p}: unknown file type; supported: {', '.join(known)}")


def read_imu_segments(
    path: str | Path,
    *,
    rate_hz: float | None = None,
    columns: Mapping[str, str] | None = None,
    gyro_unit: str | None = None,
    accel_unit: str | None = None,
    time_unit: str | None = None,
    gap_tolerance: float | None = None,
    on_gap: OnGap = "split",
    channels: Iterable[str] | None = None,
    format_options: Mapping[str, object] | None = None,
    unusual_rate: bool = False,
) -> list[ImuLog]:
    """Read an IMU log and return its contiguous segments (split at gaps).

    Same parameters as :func:`read_imu`, but ``on_gap`` defaults to
    ``"split"``; with ``"ignore"`` or no gaps the list has one log.
    """
    opts = ReadOptions(
        rate_hz=rate_hz,
        columns=columns,
        gyro_unit=gyro_unit,
        accel_unit=accel_unit,
        time_unit=time_unit,
        gap_tolerance=gap_tolerance,
        on_gap=on_gap,
        channels=None if channels is None else tuple(channels),
        extra=dict(format_options or {}),
        unusual_rate=bool(unusual_rate),
    ).validated()
    entry = find_reader(path)
    p = Path(path)
    if p.is_file() and p.stat().st_size == 0:
        raise InputError(f"{p} is empty; give a file with a header line and data rows")
    return entry.load()(p, opts)


def read_imu(
    path: str | Path,
    *,
    rate_hz: float | None = None,
    columns: Mapping[str, str] | None = None,
    gyro_unit: str | None = None,
    accel_unit: str | None = None,
    time_unit: str | None = None,
    gap_tolerance: float | None = None,
    on_gap: OnGap = "refuse",
    channels: Iterable[str] | None = None,
    format_options: Mapping[str, object] | None = None,
    unusual_rate: bool = False,
) -> ImuLog:
    """Read an IMU log file into an :class:`ImuLog` in SI units.

    Parameters
    ----------
    path:
        CSV/TSV/TXT (optionally ``.gz``), Parquet, HDF5, ROS 1 bag, ROS 2 bag
        (directory or ``.db3``), MCAP, PX4 ULog or NMEA (``$VNYMR``) file;
        other formats once registered.
    rate_hz:
        Sample rate in Hz. Required when the file has no time column; when it
        has one, the median time step must agree within 1 %.
    columns:
        ``{canonical: source_column}`` for columns whose names are not
        recognised; keys ``gyro_x`` ... ``accel_z`` and ``time``. See
        :func:`parse_column_map` for the CLI form.
    gyro_unit, accel_unit:
        Override the input unit (``rad/s``, ``deg/s``, ``dps``, ``deg/h``,
        ``mrad/s``; ``m/s^2``, ``g``, ``mg``, ``ug``). Default: the unit in the
        column name, else rad/s and m/s^2 (recorded in ``ImuLog.warnings``).
    time_unit:
        Override the time unit (``s``, ``ms``, ``us``, ``ns``). Default: the
        unit in the column name, else s (ns for Kalibr's ``timestamp``; a
        spacing implausible in s is re-read in ms/us/ns with a warning).
    gap_tolerance:
        A step longer than this multiple of the nominal period is a gap
        (default automatic: 1.5, more for jittery stamps).
    on_gap:
        ``"refuse"`` (default; raises :class:`InputError`), ``"split"``
        (return the longest segment, saying in ``ImuLog.warnings`` how many
        segments were found and which was taken; :func:`read_imu_segments`
        returns all of them) or ``"ignore"`` (keep all
        samples, warning in ``ImuLog.warnings``).
    channels:
        Only these canonical channels (all recognised ones by default).
    format_options:
        Options of one format: ``topic`` (ROS bag topic, ULog topic
        ``sensor_combined``/``vehicle_imu``), ``dataset`` (HDF5 path of the
        table), ``on_bad_checksum`` (NMEA: ``error``/``skip``). Unused keys
        are ignored.
    unusual_rate:
        Accept a sample rate outside 0.5 Hz..100 kHz (``--allow-unusual-rate``);
        without it such a rate (a time column in ms or us labelled s, ``rate_hz=1e-9``)
        is an error.

    Returns
    -------
    ImuLog
        SI data (rad/s, m/s^2), time in s, nominal rate from the median step.

    Raises
    ------
    InputError
        Anything wrong with the file (one line naming file, row/line, column).
    OptionError
        Invalid or inconsistent options.
    """
    segments = read_imu_segments(
        path,
        rate_hz=rate_hz,
        columns=columns,
        gyro_unit=gyro_unit,
        accel_unit=accel_unit,
        time_unit=time_unit,
        gap_tolerance=gap_tolerance,
        on_gap=on_gap,
        channels=channels,
        format_options=format_options,
        unusual_rate=unusual_rate,
    )
    if len(segments) == 1:
        return segments[0]
    k = max(range(len(segments)), key=lambda i: segments[i].n_samples)
    best = segments[k]
    msg = (
        f"{path}: {len(segments)} contiguous segments found; using segment {k + 1} "
        f"(the longest, {best.n_samples} samples from t={best.t[0]:.6g} s); "
        "read_imu_segments returns all of them"
    )
    best.warnings.insert(0, msg)
    return best


def bundled_static_log() -> Path:
    """Path of the bundled 45-minute ADIS16405 static extract (demo data).

    The file is ``imubounds/data/adis16405_imu1_extract.csv.gz``: 270000 rows
    at 100 Hz, columns ``time_s, gyro_*_dps, accel_*_g``. Licence CC BY-NC-SA
    4.0, University of Calgary via SMAC-Group/imudata (see the README beside it).
    """
    res = resources.files("imubounds") / "data" / BUNDLED_STATIC_LOG
    path = Path(str(res))
    if not path.is_file():
        raise InputError(f"the bundled demo log {path} is missing; reinstall imubounds")
    return path
