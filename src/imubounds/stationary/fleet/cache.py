"""The fleet's cache of unit results, by content.

The key of a unit (:func:`content_key`) is the SHA-256 of the log's content, of the
analysis settings, of the imubounds version and of the version of the cached rows; a
finished unit's result is stored as ``DIR/.cache/<key>.json`` (:class:`UnitCache`), and
a rerun analyses only the units without an entry. The client hashes the files and owns
the cache, so remote workers need only read the logs.
"""

from __future__ import annotations

import hashlib
import json
import math
from pathlib import Path
from typing import Any

from imubounds.stationary.fleet.settings import FleetSettings
from imubounds.stationary.fleet.sources import check_regular_file, is_url, url_fs
from imubounds.version import __version__

__all__ = [
    "CACHE_ROWS",
    "STRONG_VALIDATORS",
    "UnitCache",
    "content_key",
    "remote_fingerprint",
]

#: Version of a cached unit result's rows, in the cache key: a result cached before the
#: rows gained a column (2: each term's status and upper bound) is not reused.
CACHE_ROWS = 2

#: Fields of an fsspec ``info`` (lower-cased) that change whenever the object's bytes do:
#: strong validators (S3 ETag and VersionId, GCS md5Hash, crc32c and generation, Azure
#: etag, an HTTP server's ETag). A modification time is not one: a log rewritten within
#: the same second with the same size would keep its key.
STRONG_VALIDATORS = frozenset({"etag", "e_tag", "md5", "md5hash", "content_md5", "crc32c",
                               "checksum", "versionid", "version_id", "generation"})  # fmt: skip


#: URLs whose bytes are always hashed for the cache key: local and in-memory files, and
#: web servers, whose ETag is often the modification second and size (nginx), not the
#: content.
_HASHED_URLS = ("file://", "memory://", "http://", "https://")


def remote_fingerprint(fs: Any, path: str) -> str | None:
    """The store's own fingerprint of a remote object: its strong validators
    (:data:`STRONG_VALIDATORS`) with its size and fsspec ``ukey``; ``None`` when the
    store gives none: then only the bytes can say whether the object changed."""
    info = fs.info(path)
    marks = {str(k): str(v) for k, v in info.items()
             if str(k).lower() in STRONG_VALIDATORS and v not in (None, "")}  # fmt: skip
    if not marks:
        return None
    try:
        marks["ukey"] = str(fs.ukey(path))
    except (NotImplementedError, OSError, ValueError):
        pass
    marks["size"] = str(info.get("size"))
    return json.dumps(marks, sort_keys=True)


def content_key(source: str | Path, settings: FleetSettings) -> str:
    """SHA-256 (hex) of the log's content, the settings, the imubounds version and the
    version of the cached rows (:data:`CACHE_ROWS`).

    The content is the file's bytes for a local path or a ``file://``, ``memory://``,
    ``http://`` or ``https://`` URL (a web server's ETag is often only the
    modification second and the size). For object stores it is the store's own
    fingerprint of the object (:func:`remote_fingerprint`: the ETag on S3, the
    MD5/CRC on GCS, ...), so that a remote fleet is not downloaded twice; an object
    without one is read and its bytes hashed, since a modification time and a size
    do not show every change. Raises OSError or InputError when the log cannot be
    read (:func:`~imubounds.stationary.fleet.sources.check_regular_file`).
    """
    src = str(source)
    if is_url(src):
        h = hashlib.sha256()
        fs, path = url_fs(src)
        mark = None if src.startswith(_HASHED_URLS) else remote_fingerprint(fs, path)
        if mark is None:
            with fs.open(path, "rb") as f:
                while chunk := f.read(1 << 22):
                    h.update(chunk)
        else:
            h.update(f"{src}\0{mark}".encode())
    else:
        check_regular_file(src)  # a FIFO would block the open
        with open(src, "rb") as f:  # into one reused buffer: half the time of read() chunks
            h = hashlib.file_digest(f, "sha256")
    h.update(json.dumps(settings.to_json(), sort_keys=True, default=str).encode())
    h.update(__version__.encode())
    h.update(f"rows/{CACHE_ROWS}".encode())
    return h.hexdigest()


def jsonable_result(res: dict[str, Any]) -> dict[str, Any]:
    """A unit result with its curves as float lists (for the cache)."""
    out = dict(res)
    out["curves"] = {ch: {k: [float(v) for v in c[k]] for k in ("tau", "adev")}
                     for ch, c in res.get("curves", {}).items()}  # fmt: skip
    return out


class UnitCache:
    """The folder ``DIR/.cache`` of finished units' results, one ``<key>.json`` each."""

    def __init__(self, folder: Path) -> None:
        self.folder = folder

    def load(self, key: str, source: str, unit: str) -> dict[str, Any] | None:
        """The cached result of ``key`` named as ``source`` and ``unit``; ``None`` when there
        is none or it cannot be read (then the unit is analysed again)."""
        hit = self.folder / f"{key}.json"
        if not hit.is_file():
            return None
        try:
            res: dict[str, Any] = json.loads(hit.read_text(encoding="utf-8"))
            res["path"], res["unit"] = source, unit
            # JSON has no NaN: the cache holds null for an unresolved term
            res["rows"] = [{k: math.nan if v is None else v for k, v in row.items()}
                           for row in res["rows"]]  # fmt: skip
        except (OSError, ValueError):
            return None
        return res

    def store(self, key: str, result: dict[str, Any]) -> None:
        """Keep a finished unit's result (atomically written)."""
        from imubounds.io.outputs import write_json

        write_json(self.folder / f"{key}.json", jsonable_result(result), indent=None)
