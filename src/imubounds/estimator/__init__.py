"""The interval INS/GPS/compass estimator of dynamic error margins (METHOD.md 3)."""

import hashlib
from pathlib import Path


def _refresh_numba_cache() -> None:
    """Drop this package's numba cache when it or the interval rules it calls changed.

    numba validates a cached function only against its own source file; the
    compiled loop inlines :mod:`imubounds.interval` rules, so an edit there
    must invalidate it too.
    """
    here = Path(__file__).resolve().parent
    cache = here / "__pycache__"
    try:
        srcs = sorted(here.glob("*.py")) + sorted((here.parent / "interval").glob("*.py"))
        digest = hashlib.sha1(b"".join(p.read_bytes() for p in srcs)).hexdigest()
        stamp = cache / "numba_sources.sha1"
        if stamp.is_file() and stamp.read_text() == digest:
            return
        cache.mkdir(exist_ok=True)
        for f in list(cache.glob("*.nbi")) + list(cache.glob("*.nbc")):
            f.unlink(missing_ok=True)
        stamp.write_text(digest)
    except OSError:  # read-only install: numba then caches elsewhere
        return


_refresh_numba_cache()

from imubounds.estimator.core import (  # noqa: E402
    CHANNELS,
    EstimatorConfig,
    EstimatorResult,
    ImuSpec,
    StepData,
    config_dict,
    config_for_log,
    prepare_steps,
    run,
    scenario_model_error,
    summarize,
)

__all__ = [
    "CHANNELS",
    "EstimatorConfig",
    "EstimatorResult",
    "ImuSpec",
    "StepData",
    "config_dict",
    "config_for_log",
    "scenario_model_error",
    "prepare_steps",
    "run",
    "summarize",
]
