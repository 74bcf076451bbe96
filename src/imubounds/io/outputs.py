"""Atomic writing of result files and of whole result sets.

Every file is first written next to its destination under a temporary name and
then moved into place with :func:`os.replace`, so an interrupted run never
leaves a half-written ``noise.json`` or figure behind.

How imubounds recognises the files it wrote (and so may overwrite):

* a **result set** (:class:`OutputSet`: ``static``, ``dynamic``, ``simulate``,
  ``demo``) is staged beside its directory, moved in at the end and listed in
  the directory's ``run.json``, written last: a directory whose ``run.json``
  lists its files is complete, and the files it lists are imubounds' (and so
  are those of earlier runs it did not replace, listed apart as
  ``earlier_files``: never part of the complete set). A later run of the *same*
  command removes the files the earlier run listed and it did not rewrite (a
  report and figures beside a ``--no-plot`` run's results), so that a folder
  holds one run's results; files of another command stay, as ``earlier_files``.
  While a
  set is being moved in, ``.imubounds-commit.json`` lists the old and the new
  set, so that a run killed in the middle of the move is still recognised
  (the directory has no ``run.json`` then: it does not look complete);
* a **single file** (:func:`output_file`: ``simulate-noise -o FILE``,
  ``--save-spec``, ``report DIR``'s ``report.html``) is recorded with its size
  and modification time in ``.imubounds-files.json`` in its folder; a file
  counts as imubounds' only while both still match (a file the user edited
  since is the user's).

Anything else (a file imubounds did not write, or one the user changed) is
never overwritten without ``--force``, and an input of the same run never,
even with ``--force``. Another run writing the same directory holds
``.imubounds.lock`` there. :func:`committed_outputs` lists what this process
has committed, so that an interrupted command can say truthfully what was
written.
"""

from __future__ import annotations

import glob
import json
import math
import os
import signal
import tempfile
import threading
import time
from collections.abc import Callable, Iterable, Iterator, Sequence
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


def write_json(dest: str | os.PathLike[str], data: Any, *, indent: int | None = 2) -> Path:
    """Write ``data`` as JSON (nan/inf become null) atomically: indented, or compact
    with ``indent=None`` (a cache file: the C encoder, several times faster)."""
    text = json.dumps(_clean(data), indent=indent, allow_nan=False,
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


def listed_files(target: str | os.PathLike[str]) -> set[str]:
    """Relative names of the files the last imubounds run in ``target`` listed as its own
    (its ``run.json``, and an interrupted commit's record)."""
    return _written_by_imubounds(Path(target))


def recorded_files(folder: str | os.PathLike[str]) -> set[str]:
    """Names of the files an imubounds run recorded in ``folder`` as its own (its
    ``run.json`` and the single-file record), whether or not they still exist."""
    return _written_by_imubounds(Path(folder)) | set(_files_record(Path(folder)))


def record_written_files(
    target: str | os.PathLike[str],
    argv: Sequence[str] | None,
    files: Iterable[str],
    *,
    earlier: Iterable[str] = (),
    complete: bool = True,
    **extra: Any,
) -> Path:
    """Write ``target/run.json`` for files a command wrote in place (each atomically, not
    as an :class:`OutputSet`: the fleet, whose cache fills as units finish): the command,
    version and platform, and ``files``. ``earlier`` names files of earlier runs
    (:func:`listed_files`, read before this run removed their ``run.json``): those still
    there and not rewritten stay imubounds' (``earlier_files``)."""
    t = Path(target)
    names = sorted({str(f) for f in files})
    old = sorted(n for n in set(earlier)
                 if n not in names and n != RUN_RECORD and (t / n).is_file())  # fmt: skip
    return write_run_record(t, list(argv) if argv is not None else None, files=names,
                            complete=complete, **({"earlier_files": old} if old else {}),
                            **extra)  # fmt: skip


# ----------------------------------------------------------------------------- records
RUN_RECORD = "run.json"
LOCK_NAME = ".imubounds.lock"
#: Written before a result set is moved in, removed after its run.json is written.
COMMIT_RECORD = ".imubounds-commit.json"
#: Single files imubounds wrote in a folder, with their size and modification time.
FILES_RECORD = ".imubounds-files.json"
FILES_LOCK = ".imubounds-files.lock"

_JOURNAL: list[str] = []


def committed_outputs() -> list[str]:
    """What this process has written completely so far (directories and files)."""
    return list(_JOURNAL)


def reset_committed_outputs() -> None:
    """Forget :func:`committed_outputs` (the CLI does this at the start of a command)."""
    _JOURNAL.clear()


def _read_json(path: Path) -> Any:
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None


def _written_by_imubounds(target: Path) -> set[str]:
    """Relative names that the last imubounds run in ``target`` wrote: those its run.json
    lists, and those of a commit that was interrupted (``.imubounds-commit.json``)."""
    names: set[str] = set()
    rec = _read_json(target / RUN_RECORD)
    for key in ("files", "earlier_files"):
        files = rec.get(key) if isinstance(rec, dict) else None
        if isinstance(files, list):
            names |= {str(f) for f in files}
    intent = _read_json(target / COMMIT_RECORD)
    if isinstance(intent, dict):
        for key in ("old", "new"):
            if isinstance(intent.get(key), list):
                names |= {str(f) for f in intent[key]}
    return names | {RUN_RECORD} if names else names


def _fingerprint(path: Path) -> list[int]:
    st = path.stat()
    return [int(st.st_size), int(st.st_mtime_ns)]


def _files_record(folder: Path) -> dict[str, list[int]]:
    rec = _read_json(folder / FILES_RECORD)
    files = rec.get("files") if isinstance(rec, dict) else None
    if not isinstance(files, dict):
        return {}
    return {
        str(k): [int(x) for x in v]
        for k, v in files.items()
        if isinstance(v, list) and len(v) == 2 and all(isinstance(x, int) for x in v)
    }


def written_by_imubounds(path: str | os.PathLike[str]) -> bool:
    """True when ``path`` is a file imubounds wrote (see the module docstring)."""
    p = Path(path)
    if not p.is_file():
        return False
    if p.name in _written_by_imubounds(p.parent):
        return True
    rec = _files_record(p.parent).get(p.name)
    try:
        return rec is not None and rec == _fingerprint(p)
    except OSError:
        return False


def _same_file(a: Path, b: Path) -> bool:
    try:
        return os.path.samefile(a, b)
    except OSError:
        return a.resolve() == b.resolve()


def _is_input(path: Path, inputs: Iterable[Path]) -> bool:
    return any(_same_file(path, i) for i in inputs)


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def _lock_owner(lock: Path) -> int:
    """Process id of a live holder of ``lock`` other than this process, else 0."""
    try:
        pid = int(lock.read_text().strip() or "0")
    except (OSError, ValueError):
        return 0
    return pid if pid and pid != os.getpid() and _pid_alive(pid) else 0


def _acquire(lock: Path, what: Path, *, wait_s: float = 0.0) -> None:
    """Create ``lock`` holding this process id; a stale lock (dead process) is taken over."""
    deadline = time.monotonic() + wait_s
    for _ in range(10_000):
        try:
            fd = os.open(lock, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
        except FileExistsError:
            pid = _lock_owner(lock)
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


def _remove_stale_parts(folder: Path, names: Iterable[str]) -> None:
    """Temporary files of ``names`` (``.NAME.XXXX.part``) left by a killed run; only
    called while holding the lock under which they are written."""
    for name in names:
        for p in folder.glob(glob.escape(f".{name}.") + "*.part"):
            p.unlink(missing_ok=True)


@contextmanager
def _sigint_held() -> Iterator[None]:
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


# ----------------------------------------------------------------------------- single files
def check_output_file(
    dest: str | os.PathLike[str],
    *,
    force: bool = False,
    inputs: Iterable[str | os.PathLike[str]] = (),
    option: str | None = "-o",
    others: Iterable[str | os.PathLike[str]] = (),
    advice: str = "choose another name",
) -> Path:
    """Fail early, with :class:`OutputError`, if ``dest`` cannot or must not be written.

    Refused: a directory or special file, a missing or read-only folder, an
    input of the run (even with ``force``), another output of the same run
    (``others``), an existing file imubounds did not write or that changed
    since (unless ``force``), a folder another run is writing. ``option``
    names the option in messages; ``advice`` says what to do instead.
    """
    text = os.fspath(dest)
    d = Path(text)
    who = f"{option} {text}" if option else text
    if any(Path(o).resolve() == d.resolve() for o in others if os.fspath(o)):
        raise OutputError(f"{who} is also another output of this run; give two names")
    if not text:
        raise OutputError(f"{option} is empty; give a file name")
    if text.endswith(("/", os.sep)) or d.is_dir():
        raise OutputError(f"{who} is a directory; give a file name inside it")
    parent = d.parent
    try:
        if not parent.is_dir():
            what = "is not a folder" if parent.exists() else "does not exist"
            raise OutputError(f"{who}: folder {parent} {what}; create it or {advice}")
        if not os.access(parent, os.W_OK | os.X_OK):
            raise OutputError(f"{who}: folder {parent} is not writable; {advice}")
        if _is_input(d, [Path(i) for i in inputs if os.fspath(i)]):
            raise OutputError(
                f"{who} is an input of this run; imubounds will not overwrite it ({advice})"
            )
        if d.exists() or d.is_symlink():
            if not d.is_file():
                raise OutputError(
                    f"{who} exists and is not a regular file; imubounds will not replace it "
                    f"({advice})"
                )
            if not force and not written_by_imubounds(d):
                raise OutputError(
                    f"{who} exists and imubounds did not write it (or it was changed since); "
                    f"imubounds will not overwrite it ({advice}, or pass --force)"
                )
        pid = _lock_owner(parent / LOCK_NAME)
    except OSError as err:  # an over-long name, a loop of links ...
        raise OutputError(f"{who}: cannot be written ({err.strerror or err})") from err
    if pid:
        raise OutputError(
            f"another imubounds run (process {pid}) is writing {parent}; wait for it or {advice}"
        )
    return d


@contextmanager
def output_file(
    dest: str | os.PathLike[str],
    *,
    force: bool = False,
    inputs: Iterable[str | os.PathLike[str]] = (),
    option: str | None = "-o",
    advice: str = "choose another name",
) -> Iterator[Path]:
    """Write one result file: yield a temporary path beside ``dest`` (same suffix).

    On success the file replaces ``dest`` and is recorded in the folder's
    ``.imubounds-files.json``; on an exception (Ctrl-C included) it is removed
    and ``dest`` is untouched. The checks of :func:`check_output_file` are
    made before and again at the end.
    """
    inputs = [Path(i) for i in inputs if os.fspath(i)]
    d = check_output_file(dest, force=force, inputs=inputs, option=option, advice=advice)
    who = f"{option} {d}" if option else str(d)
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{d.stem}.", suffix=d.suffix, dir=d.parent)
    except OSError as err:
        raise OutputError(f"{who}: cannot be written ({err.strerror or err})") from err
    os.close(fd)
    tmp_path = Path(tmp)
    try:
        yield tmp_path
        os.chmod(tmp_path, _umask_mode())
        folder = d.parent
        lock = folder / FILES_LOCK
        _acquire(lock, folder, wait_s=10.0)
        try:
            _remove_stale_parts(folder, (FILES_RECORD,))
            check_output_file(d, force=force, inputs=inputs, option=option, advice=advice)
            with _sigint_held():
                os.replace(tmp_path, d)
                rec = {
                    k: v for k, v in _files_record(folder).items() if (folder / k).is_file()
                }
                rec[d.name] = _fingerprint(d)
                write_json(folder / FILES_RECORD, {"format": "imubounds.files/1", "files": rec})
                _JOURNAL.append(str(d))
        except OSError as err:
            raise OutputError(f"{who}: cannot be written ({err.strerror or err})") from err
        finally:
            lock.unlink(missing_ok=True)
    finally:
        if tmp_path.exists():
            tmp_path.unlink()


# ----------------------------------------------------------------------------- output sets
class OutputSet:
    """A set of result files that lands in a directory complete or not at all.

    Files are written into a staging directory beside ``target``; on success
    they are moved into ``target`` and ``run.json`` (written last) lists them:
    a directory whose ``run.json`` lists a file set is complete. Rules:

    * a file in ``target`` that imubounds did not write (not listed in the
      previous ``run.json``), or an input of the same run, is never
      overwritten unless ``force`` (an input never): :class:`OutputError`
      names it, and nothing is written;
    * another run writing the same directory holds ``target/.imubounds.lock``:
      :class:`OutputError` names its process;
    * on an exception (Ctrl-C included) before the commit, the staging
      directory is removed and ``target`` is untouched (``committed`` stays
      False, so the caller can say so truthfully); Ctrl-C during the commit
      is held back until the set is complete;
    * a run killed outright (SIGKILL, power loss) leaves at worst a hidden
      staging directory (removed by the next run into ``target``) or, in the
      middle of the commit, a directory without ``run.json`` whose files the
      next run still recognises (``.imubounds-commit.json``).

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
        self._empty = not os.fspath(target).strip()  # Path("") would be "." silently
        self.target = Path(target)
        self.force = force
        self.inputs = [Path(p) for p in inputs if os.fspath(p)]
        self.committed = False
        self._record: dict[str, Any] | None = None
        self._staging: Path | None = None
        self._lock: Path | None = None
        self._created_target = False

    # -- context --------------------------------------------------------------
    def __enter__(self) -> OutputSet:
        t = self.target
        if self._empty:
            raise OutputError("-o is empty; give an output directory (use -o . for this one)")
        try:
            if t.exists() and not t.is_dir():
                raise OutputError(
                    f"output path {t} exists and is not a directory; choose another -o"
                )
            if t.exists() and _is_input(t, self.inputs):
                raise OutputError(
                    f"output directory {t} is an input of this run; choose another -o"
                )
            if not t.exists():
                t.mkdir(parents=True)
                self._created_target = True
            self._take_lock()
            self._remove_stale_staging()
            _remove_stale_parts(t, (RUN_RECORD, COMMIT_RECORD))
            self._staging = Path(
                tempfile.mkdtemp(prefix=self._staging_prefix(os.getpid()), dir=self._parent())
            )
        except OSError as err:
            self._release()
            raise OutputError(f"cannot write to {t}: {err.strerror or err}") from err
        except BaseException:
            self._release()
            raise
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
    def _parent(self) -> Path:
        return self.target.resolve().parent

    def _staging_prefix(self, pid: int) -> str:
        return f".{self.target.resolve().name}.imubounds-{pid}-"

    def _remove_stale_staging(self) -> None:
        """Staging directories of runs into this target whose process is gone (killed)."""
        import shutil

        head = f".{self.target.resolve().name}.imubounds-"
        for d in self._parent().glob(glob.escape(head) + "*"):
            pid_text = d.name[len(head):].split("-", 1)[0]
            if d.is_dir() and pid_text.isdigit() and not _pid_alive(int(pid_text)):
                shutil.rmtree(d, ignore_errors=True)

    def _take_lock(self) -> None:
        lock = self.target / LOCK_NAME
        _acquire(lock, self.target)
        self._lock = lock

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
            if dest.exists() and _is_input(dest, self.inputs):
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

    def _superseded(self, names: list[str]) -> list[str]:
        """Files the previous complete run of the *same command* listed in ``run.json`` that
        this set does not rewrite (a report and figures beside a later ``--no-plot`` run's
        results): removed at the commit, so that the folder holds one run's results. Files
        of another command, inputs of this run and files not listed are never removed."""
        rec = _read_json(self.target / RUN_RECORD)
        mine = (self._record or {}).get("command_name")
        if not isinstance(rec, dict) or mine is None or rec.get("command_name") != mine:
            return []
        files = rec.get("files")
        if not isinstance(files, list):
            return []
        out = []
        for f in files:
            name = str(f)
            dest = self.target / name
            if (
                name in names
                or name == RUN_RECORD
                or Path(name).is_absolute()
                or ".." in Path(name).parts
                or not dest.is_file()
                or dest.is_symlink()
                or _is_input(dest, self.inputs)
            ):
                continue
            out.append(name)
        return sorted(out)

    def _commit(self) -> None:
        names = self._staged()
        if not names and self._record is None:
            return  # nothing was produced: the directory keeps its previous set
        names_all = [*names, RUN_RECORD] if self._record is not None else names
        problems = self._conflicts(names_all)
        if problems:
            raise OutputError(problems[0])
        old = sorted(_written_by_imubounds(self.target))
        superseded = self._superseded(names_all)
        # Ctrl-C is held back for the few renames of the commit, so that the set is
        # either the old one or the new one, and the message can say which.
        try:
            with _sigint_held():
                write_json(self.target / COMMIT_RECORD,
                           {"pid": os.getpid(), "old": old, "new": names_all})
                (self.target / RUN_RECORD).unlink(missing_ok=True)  # the old set is incomplete
                for name in names:
                    dest = self.target / name
                    dest.parent.mkdir(parents=True, exist_ok=True)
                    os.replace(self.staging / name, dest)
                for name in superseded:  # the earlier run's report and figures
                    (self.target / name).unlink(missing_ok=True)
                if self._record is not None:
                    extra = dict(self._record)
                    argv = extra.pop("argv", None)
                    # files of earlier runs that this set did not replace stay imubounds'
                    # (overwritable later) without being part of this complete set
                    earlier = sorted(
                        n for n in old
                        if n not in names_all and (self.target / n).is_file()
                    )
                    write_run_record(self.target, argv, files=names, complete=True,
                                     **({"earlier_files": earlier} if earlier else {}), **extra)
                (self.target / COMMIT_RECORD).unlink(missing_ok=True)
                self.committed = True
                _JOURNAL.append(str(self.target))
        except OSError as err:
            raise OutputError(f"cannot write to {self.target}: {err.strerror or err}") from err
