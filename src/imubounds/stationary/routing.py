"""Which path a static log takes (in memory or out of core) and the memory setting.

Light on purpose (no numba, no Allan kernels): the command line reads ``--max-memory``
and routes the log while the analysis modules are imported in another thread.
:mod:`imubounds.stationary.stream` re-exports every name.
"""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Any

from imubounds.errors import OptionError
from imubounds.io.chunked import ChunkedLog, open_chunked

#: Default memory setting, bytes.
DEFAULT_MEMORY: int = 1 << 30

_SIZE_UNITS = {
    "": 1, "b": 1, "k": 1000, "kb": 1000, "m": 10**6, "mb": 10**6, "g": 10**9, "gb": 10**9,
    "t": 10**12, "tb": 10**12, "kib": 1 << 10, "mib": 1 << 20, "gib": 1 << 30, "tib": 1 << 40,
}  # fmt: skip


def parse_memory(text: str | int | float, option: str = "memory setting") -> int:
    """Bytes from ``"1GiB"``, ``"512MB"``, ``"2e9"`` or a number; ``option`` names the
    setting in messages (``"--task-size"``).

    Raises
    ------
    OptionError
        Unreadable, or below 64 KiB (too small to work).
    """
    if isinstance(text, (int, float)) and not isinstance(text, bool):
        value = float(text)
    else:
        m = re.fullmatch(r"\s*([0-9]*\.?[0-9]+(?:[eE][-+]?[0-9]+)?)\s*([A-Za-z]*)\s*", str(text))
        if not m or m.group(2).lower() not in _SIZE_UNITS:
            raise OptionError(f"{option} {text!r} is not a size; write e.g. 1GiB, 512MB or 2e9")
        value = float(m.group(1)) * _SIZE_UNITS[m.group(2).lower()]
    if not math.isfinite(value) or value < 64 * 1024:
        raise OptionError(f"{option} {text!r} is too small; give at least 64KiB")
    return int(value)


def format_bytes(n: float) -> str:
    """``1.5 GiB`` style text."""
    for unit in ("B", "KiB", "MiB", "GiB", "TiB"):
        if abs(n) < 1024 or unit == "TiB":
            return f"{n:.3g} {unit}"
        n /= 1024.0
    return f"{n:.3g} TiB"  # pragma: no cover


def route_outofcore(
    path: str | Path,
    memory_limit: int | str = DEFAULT_MEMORY,
    *,
    force: bool = False,
    **open_kwargs: Any,
) -> ChunkedLog | None:
    """The opened log when it should take the out-of-core path, else ``None``.

    Out-of-core when ``force``, when no in-memory reader handles the file
    (``.npy``, raw binary), or when the in-memory path would need more than
    ``memory_limit`` bytes (:meth:`ChunkedLog.bytes_in_memory`). When not
    forced, a file the chunked reader cannot open goes to the in-memory reader
    (which gives the detailed message).
    """
    from imubounds.errors import ImuboundsError
    from imubounds.io import find_reader

    mem = parse_memory(memory_limit)
    if force:
        return open_chunked(path, **open_kwargs)
    try:
        find_reader(path)
        in_memory_ok = True
    except ImuboundsError:
        in_memory_ok = False
    if in_memory_ok and _small_text(Path(path), mem):
        return None  # the decision below, from the size alone (no header or time read)
    try:
        log = open_chunked(path, **open_kwargs)
    except ImuboundsError:
        if in_memory_ok:
            return None
        raise
    if not in_memory_ok or log.bytes_in_memory() > mem:
        return log
    return None


def _small_text(path: Path, mem: int) -> bool:
    """Whether ``path`` is a text log whose in-memory need is under ``mem`` bytes
    whatever its columns (:func:`imubounds.io.chunked.text_bytes_bound`)."""
    from imubounds.io.chunked import text_bytes_bound

    try:
        bound = text_bytes_bound(path)
    except OSError:
        return False
    return bound is not None and bound <= mem
