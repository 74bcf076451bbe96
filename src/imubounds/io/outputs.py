"""Atomic writing of result files.

Every file is first written next to its destination under a temporary name and
then moved into place with :func:`os.replace`, so an interrupted run never
leaves a half-written ``noise.json`` or figure behind.
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


def _umask_mode() -> int:
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
        os.chmod(tmp_path, _umask_mode())
        os.replace(tmp_path, dest)
    finally:
        if tmp_path.exists():
            tmp_path.unlink()


@contextmanager
def atomic_open(dest: str | os.PathLike[str], mode: str = "w") -> Iterator[IO[Any]]:
    """Open a temporary file beside ``dest`` for writing; replace ``dest`` on success."""
    with atomic_path(dest) as tmp, open(tmp, mode, encoding=None if "b" in mode else "utf-8") as f:
        yield f


def _clean(obj: Any) -> Any:
    """Make numpy scalars/arrays JSON-able and turn non-finite floats into None."""
    if isinstance(obj, dict):
        return {str(k): _clean(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_clean(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _clean(obj.tolist())
    if isinstance(obj, np.generic):
        return _clean(obj.item())
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, Path):
        return str(obj)
    return obj


def to_jsonable(obj: Any) -> Any:
    """Public form of the JSON cleaner (numpy -> Python, nan/inf -> null)."""
    return _clean(obj)


def write_json(dest: str | os.PathLike[str], data: Any) -> Path:
    """Write ``data`` as indented JSON (nan/inf become null) atomically."""
    with atomic_open(dest) as f:
        json.dump(_clean(data), f, indent=2, allow_nan=False)
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
        os.chmod(tmp_path, _umask_mode())
        os.replace(tmp_path, dest)
    finally:
        if tmp_path.exists():
            tmp_path.unlink()
    return dest


def write_run_record(outdir: str | os.PathLike[str], argv: list[str] | None, **extra: Any) -> Path:
    """Write ``run.json``: the exact command, package version and platform, for reproduction."""
    import platform
    import shlex
    import sys
    from datetime import UTC, datetime

    from imubounds import __version__

    record = {
        "command": "imubounds " + shlex.join(argv or []),
        "imubounds_version": __version__,
        "python": sys.version.split()[0],
        "platform": platform.platform(),
        "cwd": os.getcwd(),
        "finished_utc": datetime.now(UTC).isoformat(timespec="seconds"),
        **extra,
    }
    return write_json(Path(outdir) / "run.json", record)
