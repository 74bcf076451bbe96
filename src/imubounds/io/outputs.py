"""Atomic writing of result files and of whole result sets.

Every file is first written next to its destination under a temporary name and
then moved into place with :func:`os.replace`, so an interrupted run never
leaves a half-written ``noise.json`` or figure behind. :class:`OutputSet`
does the same for a directory of results: staged beside the target, moved in
at the end, listed in ``run.json`` (written last), never overwriting a file
imubounds did not write.
"""

from __future__ import annotations

import json
import math
import os
import tempfile
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import IO, Any

import numpy as np

from imubounds.errors import OptionError, OutputError


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


# ----------------------------------------------------------------------------- output sets

RUN_RECORD = "run.json"
LOCK_NAME = ".imubounds.lock"


def _written_by_imubounds(target: Path) -> set[str]:
    """Relative names that the last complete imubounds run in ``target`` lists in run.json."""
    try:
        rec = json.loads((target / RUN_RECORD).read_text())
    except (OSError, ValueError):
        return set()
    files = rec.get("files") if isinstance(rec, dict) else None
    names = {str(f) for f in files} if isinstance(files, list) else set()
    return names | {RUN_RECORD} if names else names


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


class OutputSet:
    """A set of result files that lands in a directory complete or not at all.

    Files are written into a staging directory beside ``target``; on success
    they are moved into ``target`` and ``run.json`` (written last) lists them:
    a directory whose ``run.json`` lists a file set is complete. Rules:

    * a file in ``target`` that imubounds did not write (not listed in the
      previous ``run.json``), or an input of the same run, is never
      overwritten unless ``force``: :class:`OutputError` names it, and nothing
      is written;
    * another run writing the same directory holds ``target/.imubounds.lock``:
      :class:`OutputError` names its process;
    * on an exception (Ctrl-C included) before the commit, the staging
      directory is removed and ``target`` is untouched (``committed`` stays
      False, so the caller can say so truthfully).

    Usage::

        with OutputSet(out_dir, inputs=[log_path], force=args.force) as out:
            write_json(out.path("noise.json"), doc)
            out.record(argv, command_name="static")
    """

    def __init__(
        self,
        target: str | os.PathLike[str],
        *,
        force: bool = False,
        inputs: Iterable[str | os.PathLike[str]] = (),
    ) -> None:
        self.target = Path(target)
        self.force = force
        self.inputs = {Path(p).resolve() for p in inputs if str(p)}
        self.committed = False
        self._record: dict[str, Any] | None = None
        self._staging: Path | None = None
        self._lock: Path | None = None
        self._created_target = False

    # -- context --------------------------------------------------------------
    def __enter__(self) -> OutputSet:
        t = self.target
        if t.exists() and not t.is_dir():
            raise OutputError(f"output path {t} exists and is not a directory; choose another -o")
        if t.resolve() in self.inputs:
            raise OutputError(f"output directory {t} is an input of this run; choose another -o")
        try:
            if not t.exists():
                t.mkdir(parents=True)
                self._created_target = True
            self._take_lock()
            self._staging = Path(
                tempfile.mkdtemp(prefix=f".{t.resolve().name}.imubounds-", dir=t.resolve().parent)
            )
        except OSError as err:
            self._release()
            raise OutputError(f"cannot write to {t}: {err.strerror or err}") from err
        return self

    def __exit__(self, exc_type: Any, exc: Any, tb: Any) -> None:
        try:
            if exc_type is None:
                self._commit()
        finally:
            self._release()

    # -- API ------------------------------------------------------------------
    @property
    def staging(self) -> Path:
        if self._staging is None:
            raise RuntimeError("OutputSet used outside its with-block")
        return self._staging

    def path(self, name: str) -> Path:
        """Where to write ``name`` (relative, may contain sub-directories) for this set."""
        p = self.staging / name
        p.parent.mkdir(parents=True, exist_ok=True)
        return p

    def check(self, names: Iterable[str]) -> None:
        """Fail early if writing ``names`` would overwrite something it must not."""
        problems = self._conflicts(list(names))
        if problems:
            raise OutputError(problems[0])

    def record(self, argv: list[str] | None, **extra: Any) -> None:
        """Write ``run.json`` (command, version, platform) now; the commit rewrites it last,
        with the list of files, so that a directory with a ``run.json`` is complete."""
        self._record = {"argv": argv, **extra}
        write_run_record(self.staging, argv, complete=False, **extra)

    # -- internals ------------------------------------------------------------
    def _take_lock(self) -> None:
        lock = self.target / LOCK_NAME
        for _ in range(2):
            try:
                fd = os.open(lock, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
            except FileExistsError:
                try:
                    pid = int(lock.read_text().strip() or "0")
                except (OSError, ValueError):
                    pid = 0
                if pid and _pid_alive(pid) and pid != os.getpid():
                    raise OutputError(
                        f"another imubounds run (process {pid}) is writing {self.target}; "
                        "wait for it or choose another -o"
                    ) from None
                lock.unlink(missing_ok=True)  # stale: its process is gone
                continue
            with os.fdopen(fd, "w") as f:
                f.write(str(os.getpid()))
            self._lock = lock
            return
        raise OutputError(f"cannot lock {self.target} for writing")

    def _release(self) -> None:
        if self._staging is not None:
            import shutil

            shutil.rmtree(self._staging, ignore_errors=True)
            self._staging = None
        if self._lock is not None:
            self._lock.unlink(missing_ok=True)
            self._lock = None
        if self._created_target and not self.committed:
            try:
                self.target.rmdir()  # only if still empty
            except OSError:
                pass

    def _staged(self) -> list[str]:
        root = self.staging
        names = (str(p.relative_to(root)) for p in root.rglob("*") if p.is_file())
        return sorted(n for n in names if n != RUN_RECORD)

    def _conflicts(self, names: list[str]) -> list[str]:
        ours = _written_by_imubounds(self.target)
        out: list[str] = []
        for name in names:
            dest = self.target / name
            if dest.resolve() in self.inputs:
                out.append(
                    f"{dest} is an input of this run; imubounds will not overwrite it "
                    "(choose another -o)"
                )
            elif dest.exists() and name not in ours and not self.force:
                what = "a directory" if dest.is_dir() else "a file imubounds did not write"
                out.append(
                    f"{dest} exists and is {what}; imubounds will not overwrite it "
                    "(choose another -o, or pass --force)"
                )
        return out

    def _commit(self) -> None:
        import signal
        import threading

        names = self._staged()
        if not names and self._record is None:
            return  # nothing was produced: the directory keeps its previous set
        if self._record is not None:
            names_all = [*names, RUN_RECORD]
        else:
            names_all = names
        problems = self._conflicts(names_all)
        if problems:
            raise OutputError(problems[0])
        # Ctrl-C is held back for the few renames of the commit, so that the set is
        # either the old one or the new one, and the message can say which.
        main = threading.current_thread() is threading.main_thread()
        pending: list[int] = []
        old = signal.getsignal(signal.SIGINT) if main else None
        if main:
            signal.signal(signal.SIGINT, lambda s, f: pending.append(s))
        try:
            (self.target / RUN_RECORD).unlink(missing_ok=True)  # the old set is no longer complete
            for name in names:
                dest = self.target / name
                dest.parent.mkdir(parents=True, exist_ok=True)
                os.replace(self.staging / name, dest)
            if self._record is not None:
                extra = dict(self._record)
                argv = extra.pop("argv", None)
                write_run_record(self.target, argv, files=names, complete=True, **extra)
            self.committed = True
        except OSError as err:
            raise OutputError(f"cannot write to {self.target}: {err.strerror or err}") from err
        finally:
            if main:
                signal.signal(signal.SIGINT, old)
        if pending:
            raise KeyboardInterrupt
