"""The logs of a fleet: glob patterns and fsspec URLs expanded to sources, unit names,
sizes, and a local copy of a remote log for the readers."""

from __future__ import annotations

import os
import re
from collections.abc import Iterable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path, PurePosixPath
from typing import Any

from imubounds.errors import InputError
from imubounds.io.validate import check_input_path, is_url

__all__ = [
    "UNIT_SUFFIXES",
    "check_regular_file",
    "expand_globs",
    "is_url",
    "local_copy",
    "source_size",
    "unit_names",
    "url_fs",
]

_GLOB_MAGIC = re.compile(r"[*?\[]")
#: Suffixes taken off a file name to name its unit (in this order, each at most once).
UNIT_SUFFIXES = (".gz", ".bz2", ".xz", ".zst", ".csv", ".tsv", ".txt", ".parquet", ".npy",
                 ".h5", ".hdf5", ".bin", ".ulg", ".bag", ".mcap")  # fmt: skip


def url_fs(url: str) -> tuple[Any, str]:
    """``(filesystem, path)`` of an fsspec URL; a one-line InputError when it cannot be."""
    try:
        import fsspec
    except ImportError as err:  # pragma: no cover - fsspec comes with the fleet extra (dask)
        raise InputError(
            f"{url}: reading URLs needs fsspec; pip install 'imubounds[fleet]'"
        ) from err
    try:
        return fsspec.core.url_to_fs(url)
    except ImportError as err:  # the protocol's package (s3fs, gcsfs, aiohttp) is missing
        msg = " ".join(str(err).split())
        raise InputError(f"{url}: {msg}") from err
    except (ValueError, OSError) as err:  # unknown protocol, bad URL, no credentials
        msg = " ".join(str(err).split())
        raise InputError(f"{url}: cannot open ({msg})") from err


def _expand_url(pat: str) -> list[str]:
    fs, path = url_fs(pat)
    try:
        hits = sorted(fs.glob(path)) if _GLOB_MAGIC.search(path) else [path]
        files = [h for h in hits if fs.isfile(h) and not PurePosixPath(h).name.startswith(".")]
    except (OSError, ValueError) as err:
        msg = " ".join(str(err).split())
        raise InputError(f"{pat}: cannot list ({msg})") from err
    return [fs.unstrip_protocol(h) for h in files]


def expand_globs(patterns: Iterable[str | Path]) -> list[str]:
    """Sources matching the patterns, sorted, unique: local paths or fsspec URLs.

    A local pattern is expanded with :mod:`glob` (``**`` recursive; a plain path
    matches itself). A URL (``s3://bucket/units/**/*.csv.gz``, ``memory://...``,
    ``file://...``) is expanded with the glob of its fsspec file system; the
    URL's protocol package (``s3fs``, ``gcsfs``, ...) must be installed. Hidden
    files (``.name``) are skipped.

    Raises
    ------
    InputError
        When any pattern matches no file (a missing path or an empty glob would
        otherwise leave units out of the fleet unnoticed; all such patterns are
        named), or a URL cannot be listed.
    """
    import glob

    out: dict[str, str] = {}
    empty: list[str] = []
    for pat in map(str, patterns):
        if is_url(pat):
            files = _expand_url(pat)
            keys = files
        else:
            hits = sorted(glob.glob(pat, recursive=True))
            if not hits and Path(pat).exists():
                hits = [pat]
            # every match but folders and hidden files: one that cannot be read (a dangling
            # link, a FIFO) is a unit that fails with the reason, never left out unnoticed
            files = [h for h in hits if not Path(h).is_dir() and not Path(h).name.startswith(".")]
            keys = [str(Path(h).resolve()) for h in files]
        if not files:
            empty.append(pat)
        for k, h in zip(keys, files, strict=True):
            out.setdefault(k, h)
    if empty:
        what = "no log file matches" if len(empty) == 1 else "no log files match"
        raise InputError(
            f"{what} {', '.join(map(repr, empty))}; check the pattern"
            + (f" ({len(out)} file(s) matched the other patterns)" if out else "")
        )
    return [out[k] for k in sorted(out)]


def _components(source: str) -> list[str]:
    """Path components of a source, the URL's protocol first (``s3:``)."""
    if is_url(source):
        proto = source.split("://", 1)[0]
        _, path = url_fs(source)
        return [f"{proto}:", *[c for c in path.split("/") if c]]
    # as matched, not resolved: a link names its unit (a dangling one has no target)
    return list(Path(os.path.abspath(source)).parts)


def _strip_suffixes(name: str) -> str:
    for suf in UNIT_SUFFIXES:
        if name.lower().endswith(suf) and len(name) > len(suf):
            name = name[: -len(suf)]
    return name


def unit_names(sources: Sequence[str | Path]) -> list[str]:
    """Unit names: each source's path relative to the common folder of all, without the
    file-type suffixes, ``/``-separated (``siteA/unit1.csv.gz`` and ``siteB/unit1.csv.gz``
    are the units ``siteA/unit1`` and ``siteB/unit1``). Two files that differ only in
    their suffixes (``u.csv`` and ``u.csv.gz``) keep their whole file names.
    """
    parts = [_components(str(s)) for s in sources]
    if not parts:
        return []
    common = 0
    dirs = [p[:-1] for p in parts]
    while all(len(d) > common for d in dirs) and len({d[common] for d in dirs}) == 1:
        common += 1
    rel = [p[common:] for p in parts]
    names = ["/".join([*r[:-1], _strip_suffixes(r[-1])]) for r in rel]
    counts: dict[str, int] = {}
    for n in names:
        counts[n] = counts.get(n, 0) + 1
    return [n if counts[n] == 1 else "/".join(r) for n, r in zip(names, rel, strict=True)]


def source_size(source: str) -> int:
    """Size in bytes of a local file or URL (0 when unknown)."""
    try:
        if is_url(source):
            fs, path = url_fs(source)
            return int(fs.size(path) or 0)
        return Path(source).stat().st_size
    except (OSError, ValueError, TypeError, InputError):
        return 0


def check_regular_file(path: str) -> None:
    """Refuse a local match that is no regular file before it is opened (opening a FIFO
    would wait for a writer forever): :func:`imubounds.io.validate.check_input_path`, and
    a symbolic link whose target does not exist named as such.

    Raises
    ------
    InputError
        Naming the file and what it is (a dangling link, a FIFO, a socket, a device, a
        folder, unreadable).
    """
    if os.path.islink(path) and not os.path.exists(path):
        raise InputError(
            f"{path}: cannot read: a symbolic link to {os.readlink(path)}, which does not "
            "exist; fix or remove the link"
        )
    check_input_path(path, what="unit log")


@contextmanager
def local_copy(source: str) -> Iterator[Path]:
    """A local path holding the log: the path itself, or a URL copied to a temporary file
    (with the URL's file name, so that the readers recognise the format)."""
    if not is_url(source):
        check_regular_file(source)
        yield Path(source)
        return
    import shutil
    import tempfile

    fs, path = url_fs(source)
    with tempfile.TemporaryDirectory(prefix="imubounds-fleet-") as tmp:
        local = Path(tmp) / (PurePosixPath(path).name or "log")
        try:
            with fs.open(path, "rb") as src, open(local, "wb") as dst:
                shutil.copyfileobj(src, dst, 1 << 22)
        except (OSError, ValueError) as err:
            msg = " ".join(str(err).split())
            raise InputError(f"{source}: cannot read ({msg})") from err
        yield local
