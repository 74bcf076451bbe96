"""Process-wide settings for processes that imubounds owns: the command line and the
fleet's local Dask workers. The library never applies them by itself (importing
imubounds changes nothing); a notebook user may call :func:`tune_malloc` once.

glibc's malloc returns freed memory to the system early: above a 128 KiB
threshold (raised dynamically up to 32 MiB) arrays get their own mapping, and
the top of the heap is trimmed as soon as a few MiB are free. An analysis makes
many short-lived arrays of a log's length (1.4 MB for 30 min at 100 Hz), so each
one is mapped, zero-filled and faulted in afresh: measured 27 000 page faults per
unit of the fleet benchmark. With :data:`MALLOC_SETTINGS` (up to 256 MiB of freed
memory kept for reuse) there were 25 times fewer, and about 20 % less CPU per
unit, with the same results.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import os
import sys

#: glibc malloc settings (environment names, as the glibc tunables read at start):
#: arrays under 64 MiB from the heap, up to 256 MiB of free heap kept, 64 MiB of
#: padding when the heap grows.
MALLOC_SETTINGS: dict[str, int] = {
    "MALLOC_MMAP_THRESHOLD_": 64 << 20,
    "MALLOC_TRIM_THRESHOLD_": 256 << 20,
    "MALLOC_TOP_PAD_": 64 << 20,
}

# mallopt parameter numbers (glibc malloc.h)
_MALLOPT = {"MALLOC_TRIM_THRESHOLD_": -1, "MALLOC_TOP_PAD_": -2, "MALLOC_MMAP_THRESHOLD_": -3}


def malloc_environment() -> dict[str, str]:
    """The malloc environment a new process should get: :data:`MALLOC_SETTINGS`, with
    the value of this process's environment where the user set one (a user's value
    wins; given explicitly, so that a launcher's own default cannot replace it)."""
    return {k: os.environ.get(k, str(v)) for k, v in MALLOC_SETTINGS.items()}


def tune_malloc() -> bool:
    """Apply :data:`MALLOC_SETTINGS` to this process with ``mallopt`` (glibc only; a
    setting the user gave in the environment is kept). Returns whether it applied."""
    if not sys.platform.startswith("linux"):
        return False
    name = ctypes.util.find_library("c") or "libc.so.6"
    try:
        libc = ctypes.CDLL(name)
        mallopt = libc.mallopt
    except (OSError, AttributeError):  # musl or another libc: nothing to do
        return False
    mallopt.argtypes = [ctypes.c_int, ctypes.c_int]
    mallopt.restype = ctypes.c_int
    ok = True
    for key, value in MALLOC_SETTINGS.items():
        if key in os.environ:
            continue
        ok &= bool(mallopt(_MALLOPT[key], value))
    return ok
