"""Invalidate a package's numba on-disk cache when any source it depends on changes.

numba validates a cached function only against the file it is defined in, not
against the modules whose ``@njit`` functions it calls and inlines. After an
edit of the interval rules, cached contractors or estimator loops would keep
the old rules silently. A fingerprint of all the given sources guards that.
"""

from __future__ import annotations

import hashlib
from collections.abc import Iterable
from pathlib import Path


def refresh(package_dir: Path, extra_dirs: Iterable[Path] = ()) -> None:
    """Drop ``package_dir/__pycache__``'s numba files if the sources' fingerprint changed.

    The fingerprint covers every ``*.py`` in ``package_dir`` and ``extra_dirs``.
    A read-only install is left alone (numba then caches elsewhere).
    """
    cache = package_dir / "__pycache__"
    try:
        srcs = sorted(package_dir.glob("*.py"))
        for d in extra_dirs:
            srcs += sorted(Path(d).glob("*.py"))
        digest = hashlib.sha1(b"".join(p.read_bytes() for p in srcs)).hexdigest()
        stamp = cache / "numba_sources.sha1"
        if stamp.is_file() and stamp.read_text() == digest:
            return
        cache.mkdir(exist_ok=True)
        for f in list(cache.glob("*.nbi")) + list(cache.glob("*.nbc")):
            f.unlink(missing_ok=True)
        stamp.write_text(digest)
    except OSError:
        return


def refresh_all() -> None:
    """Refresh the caches of every package whose compiled code inlines the interval rules.

    Called by the command-line entry point only (importing the library touches no files);
    the test suite calls it once at start-up.
    """
    root = Path(__file__).resolve().parent.parent
    interval = root / "interval"
    refresh(interval)
    refresh(root / "dynamic" / "estimator", [interval])
