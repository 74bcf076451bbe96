"""Input and output: one reader registry, the log models and atomic output writing.

* :mod:`.registry` -- the reader registry and format sniffing (:func:`read_imu`,
  :func:`find_reader`, :func:`register_reader`);
* :mod:`.log` -- :class:`ImuLog`, a static IMU log in SI units;
* :mod:`.drive` -- :class:`Drive`, a multi-sensor drive log in SI units, and its settings;
* :mod:`.drive.readers` -- :func:`read_drive`, the one entry point for drive logs (the
  generic layout of :mod:`.drive.layout`, VN-100, comma2k19, ROS bags, ULog, NMEA, CSV
  through a column map), validated by :mod:`.drive.validate`; the mount and the time
  matching every drive reader shares in :mod:`.drive.mount`;
* :mod:`.magic` -- the first bytes of every binary format, for sniffing;
* :mod:`.table`, :mod:`.columns`, :mod:`.assemble` -- CSV/TSV/Parquet and the
  shared column recognition, unit conversion and assembly into logs;
* :mod:`.validate` -- the one validation layer every reader goes through (special
  files refused before reading, finite values, time order, duplicates, restarts,
  gaps, unit plausibility, spikes; in memory and block by block);
* :mod:`.chunked` -- out-of-core readers;
* :mod:`.rosbag`, :mod:`.ulog`, :mod:`.nmea`, :mod:`.hdf5` -- other formats;
* :mod:`.outputs` -- atomic writes of result files and sets, and how imubounds
  recognises the files it wrote.
"""

from importlib import import_module
from typing import TYPE_CHECKING, Any

from imubounds.io.registry import (
    ReaderEntry,
    ReaderFunc,
    ReadOptions,
    assemble_logs,
    bundled_static_log,
    find_reader,
    parse_column_map,
    read_imu,
    read_imu_segments,
    recognise,
    register_reader,
    registered_readers,
    unregister_reader,
)

__all__ = [
    "Drive",
    "DriveSettings",
    "ReadOptions",
    "ReaderEntry",
    "ReaderFunc",
    "assemble_logs",
    "bundled_static_log",
    "find_reader",
    "parse_column_map",
    "read_drive",
    "read_imu",
    "read_imu_segments",
    "read_layout",
    "recognise",
    "register_reader",
    "registered_readers",
    "unregister_reader",
    "write_layout",
]

#: The drive side, imported on first use (PEP 562): it needs pandas, which a static
#: log read through the registry does not (about 0.3 s of every ``imubounds static``).
_LAZY: dict[str, str] = {
    "Drive": "imubounds.io.drive",
    "DriveSettings": "imubounds.io.drive",
    "read_layout": "imubounds.io.drive.layout",
    "write_layout": "imubounds.io.drive.layout",
    "read_drive": "imubounds.io.drive.readers",
}

if TYPE_CHECKING:
    from imubounds.io.drive import Drive, DriveSettings
    from imubounds.io.drive.layout import read_layout, write_layout
    from imubounds.io.drive.readers import read_drive


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'imubounds.io' has no attribute {name!r}")
    value = getattr(import_module(module), name)
    globals()[name] = value
    return value
