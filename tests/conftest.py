"""Shared fixtures: where the real recorded logs live."""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path

import pytest
from hypothesis import settings

# h5py must be imported before codac: in this environment importing codac first
# and h5py afterwards segfaults (both bundle native libraries).
try:
    import h5py  # noqa: F401
except ImportError:  # pragma: no cover
    pass

# Tests never assert timings: no hypothesis deadlines. In CI the examples are
# derandomized so that a run is reproducible from its commit alone.
settings.register_profile("default", deadline=None)
settings.register_profile("ci", deadline=None, derandomize=True)
settings.load_profile("ci" if os.environ.get("CI") else "default")

# The library touches no files at import; the test run, like the CLI, drops numba
# caches compiled from interval rules that have changed since.
from imubounds.cli import numba_cache  # noqa: E402

numba_cache.refresh_all()

REPO = Path(__file__).resolve().parents[1]
SHARED_DATA = REPO.parent / "shared" / "data"


@pytest.fixture(scope="session")
def shared_data() -> Path:
    """``../shared/data`` beside the repository (always present in CI)."""
    if not SHARED_DATA.is_dir():
        pytest.skip(f"real data folder {SHARED_DATA} is not beside the repository")
    return SHARED_DATA


@pytest.fixture(scope="session")
def adis_log_path(shared_data: Path) -> Path:
    return shared_data / "static" / "adis16405_imu1.csv.gz"


@pytest.fixture
def no_hang() -> Iterator[None]:
    """Fail (instead of hanging the test run) if the test blocks for 60 s (a FIFO, a YAML
    alias bomb); a module opts in with ``pytestmark = pytest.mark.usefixtures("no_hang")``."""
    import signal

    def hang(signum: int, frame: object) -> None:
        raise TimeoutError("the command blocked for 60 s")

    old = signal.signal(signal.SIGALRM, hang)
    signal.alarm(60)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)
