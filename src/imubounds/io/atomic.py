"""Atomic writing of one file: a temporary name beside the destination, then
:func:`os.replace`, so that an interrupted run never leaves a half-written file; and the
JSON cleaner every result file goes through (numpy to Python, NaN and infinity to null:
a JSON file imubounds writes never carries ``NaN`` or ``Infinity``).

The rules of which files imubounds may overwrite, and result sets, are in
:mod:`imubounds.io.outputs` (which re-exports these functions).
"""

from __future__ import annotations

import json
import math
import os
import tempfile
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import IO, Any

import numpy as np

from imubounds.errors import OptionError


def umask_mode() -> int:
    """File mode an ordinary ``open()`` would give (0o666 less the umask)."""
    mask = os.umask(0)
    os.umask(mask)
    return 0o666 & ~mask


def ensure_dir(path: str | os.PathLike[str]) -> Path:
    """Create ``path`` (and parents) if needed; a clear error if it is a file."""
    p = Path(path)
    if p.exists() and not p.is_dir():
        raise OptionError(f"output path {p} exists and is not a directory; choose another -o")
    try:
        p.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise OptionError(f"cannot create output directory {p}: {err.strerror}") from err
    return p


@contextmanager
def atomic_path(dest: str | os.PathLike[str]) -> Iterator[Path]:
    """Yield a temporary path beside ``dest``; move it onto ``dest`` on success."""
    dest = Path(dest)
    fd, tmp = tempfile.mkstemp(prefix=f".{dest.name}.", suffix=".part", dir=dest.parent)
    os.close(fd)
    tmp_path = Path(tmp)
    try:
        yield tmp_path
        os.chmod(tmp_path, umask_mode())
        os.replace(tmp_path, dest)
    finally:
        if tmp_path.exists():
            tmp_path.unlink()


@contextmanager
def atomic_open(dest: str | os.PathLike[str], mode: str = "w") -> Iterator[IO[Any]]:
    """Open a temporary file beside ``dest`` for writing; replace ``dest`` on success."""
    with atomic_path(dest) as tmp, open(tmp, mode, encoding=None if "b" in mode else "utf-8") as f:
        yield f


def clean_json(obj: Any) -> Any:
    """Make numpy scalars/arrays JSON-able and turn non-finite floats into None."""
    if isinstance(obj, dict):
        return {str(k): clean_json(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [clean_json(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return clean_json(obj.tolist())
    if isinstance(obj, np.generic):
        return clean_json(obj.item())
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, Path):
        return str(obj)
    return obj


def to_jsonable(obj: Any) -> Any:
    """Public form of the JSON cleaner (numpy -> Python, nan/inf -> null)."""
    return clean_json(obj)


def write_json(dest: str | os.PathLike[str], data: Any, *, indent: int | None = 2) -> Path:
    """Write ``data`` as JSON (nan/inf become null) atomically: indented, or compact
    with ``indent=None`` (a cache file: the C encoder, several times faster)."""
    text = json.dumps(clean_json(data), indent=indent, allow_nan=False,
                      separators=None if indent is not None else (",", ":"))  # fmt: skip
    with atomic_open(dest) as f:
        f.write(text)
        f.write("\n")
    return Path(dest)


def write_text(dest: str | os.PathLike[str], text: str) -> Path:
    with atomic_open(dest) as f:
        f.write(text)
    return Path(dest)


def write_with(dest: str | os.PathLike[str], writer: Callable[[Path], None]) -> Path:
    """Call ``writer(tmp_path)`` and move the result onto ``dest`` atomically.

    The temporary path keeps ``dest``'s suffix so that writers choosing a
    format by extension (matplotlib's ``savefig``) do the right thing.
    """
    dest = Path(dest)
    fd, tmp = tempfile.mkstemp(prefix=f".{dest.stem}.", suffix=dest.suffix, dir=dest.parent)
    os.close(fd)
    tmp_path = Path(tmp)
    try:
        writer(tmp_path)
        os.chmod(tmp_path, umask_mode())
        os.replace(tmp_path, dest)
    finally:
        if tmp_path.exists():
            tmp_path.unlink()
    return dest
