"""The first bytes of every binary format imubounds recognises, in one place.

The reader registry (:mod:`.registry`) sniffs a file by these when its suffix says
nothing, the drive reader (:mod:`.drive.readers`) tells bags from ULogs by them, and
the text readers (:mod:`.table`, :mod:`.chunked`) see gzip by them.
"""

from __future__ import annotations

from pathlib import Path

GZIP_MAGIC = b"\x1f\x8b"
PARQUET_MAGIC = b"PAR1"
ROS1_MAGIC = b"#ROSBAG V2.0"
MCAP_MAGIC = b"\x89MCAP"
SQLITE_MAGIC = b"SQLite format 3\x00"
ULOG_MAGIC = b"ULog\x01\x12\x35"
HDF5_MAGIC = b"\x89HDF\r\n\x1a\n"


def is_gzip(head: bytes) -> bool:
    """True for the first bytes of a gzip stream."""
    return head[:2] == GZIP_MAGIC


def is_parquet(head: bytes) -> bool:
    """True for the first bytes of a Parquet file."""
    return head[:4] == PARQUET_MAGIC


def is_bag(head: bytes) -> bool:
    """True for the first bytes of a ROS 1 bag, an MCAP file or a ROS 2 sqlite3 file."""
    return head.startswith((ROS1_MAGIC, MCAP_MAGIC, SQLITE_MAGIC))


def is_ulog(head: bytes) -> bool:
    """True for the first bytes of a ULog file."""
    return head.startswith(ULOG_MAGIC)


def is_hdf5(head: bytes) -> bool:
    """True for the first bytes of an HDF5 file (at offset 0; no user block)."""
    return head.startswith(HDF5_MAGIC)


def file_is_gzip(path: Path) -> bool:
    """True when the file at ``path`` starts as a gzip stream."""
    with open(path, "rb") as f:
        return is_gzip(f.read(2))
