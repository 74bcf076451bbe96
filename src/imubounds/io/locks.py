"""Process locks of output folders and holding Ctrl-C back for a few renames.

A lock is a file holding the process id of its holder; a lock whose process is gone is
stale and taken over. :func:`signals_held` defers SIGINT and SIGTERM (main thread only)
and delivers them when the block ends, so that a sequence of renames completes or is
rolled back as a whole (:class:`imubounds.io.outputs.OutputSet`).
"""

from __future__ import annotations

import os
import signal
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from imubounds.errors import OutputError


def pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def lock_owner(lock: Path) -> int:
    """Process id of a live holder of ``lock`` other than this process, else 0."""
    try:
        pid = int(lock.read_text().strip() or "0")
    except (OSError, ValueError):
        return 0
    return pid if pid and pid != os.getpid() and pid_alive(pid) else 0


def acquire_lock(lock: Path, what: Path, *, wait_s: float = 0.0) -> None:
    """Create ``lock`` holding this process id; a stale lock (dead process) is taken over."""
    deadline = time.monotonic() + wait_s
    for _ in range(10_000):
        try:
            fd = os.open(lock, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
        except FileExistsError:
            pid = lock_owner(lock)
            if pid:
                if time.monotonic() < deadline:
                    time.sleep(0.05)
                    continue
                raise OutputError(
                    f"another imubounds run (process {pid}) is writing {what}; "
                    "wait for it or choose another -o"
                ) from None
            lock.unlink(missing_ok=True)  # stale: its process is gone
            continue
        with os.fdopen(fd, "w") as f:
            f.write(str(os.getpid()))
        return
    raise OutputError(f"cannot lock {what} for writing")


@contextmanager
def signals_held() -> Iterator[None]:
    """Hold Ctrl-C (and SIGTERM) back for a few renames; deliver it afterwards."""
    main = threading.current_thread() is threading.main_thread()
    pending: list[int] = []
    held = (signal.SIGINT, signal.SIGTERM)
    old = {s: signal.getsignal(s) for s in held} if main else {}
    if main:
        for s in held:
            signal.signal(s, lambda num, frame: pending.append(num))
    try:
        yield
    finally:
        for s, h in old.items():
            signal.signal(s, h if h is not None else signal.SIG_DFL)
    if pending:
        signal.raise_signal(pending[0])
