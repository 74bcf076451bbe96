"""Which files imubounds may write, and result sets that land complete or not at all.

Every file is first written next to its destination under a temporary name and
then moved into place with :func:`os.replace` (:mod:`imubounds.io.atomic`), so an
interrupted run never leaves a half-written ``noise.json`` or figure behind.

How imubounds recognises the files it wrote (and so may overwrite; the records are read in
:mod:`imubounds.io.records`):

* a **result set** (:class:`OutputSet`: ``static``, ``dynamic``, ``simulate``,
  ``convert``, ``demo``) is staged beside its directory, moved in at the end and
  listed in the directory's ``run.json`` (written last, with each file's size and
  modification time, the command and its inputs): a directory whose ``run.json``
  lists its files is complete. A set is written only into a new or empty
  directory, or one that holds the earlier results of the *same* command on the
  same input as imubounds left them; anything else there (the user's notes, a
  log, another command's or another log's results, a result the user edited) is
  refused unless ``--overwrite`` (then kept; only files of the names the set
  writes are replaced). A later run of the same command removes the files the
  earlier run listed and it did not rewrite (a report and figures beside a
  ``--no-plot`` run's results), so that a folder holds one run's results; files
  of another command stay, as ``earlier_files``. The commit puts the old files
  aside in a backup folder before moving the new ones in and undoes everything
  on any exception (Ctrl-C held back meanwhile); a run killed in the middle
  leaves ``.imubounds-commit.json``, from which the next run restores the old set;
* a **single file** (:func:`output_file`: ``simulate-noise -o FILE``,
  ``--save-spec``, ``export -o FILE``, ``report DIR``'s ``report.html``) is
  recorded with its size and modification time in ``.imubounds-files.json`` in
  its folder; a file counts as imubounds' only while both still match (a file
  the user edited since is the user's).

Anything else (a file imubounds did not write, or one the user changed) is
never overwritten without ``--overwrite`` (``--force`` is the same option), and
an input of the same run never, even with ``--overwrite``. Another run writing
the same directory holds ``.imubounds.lock`` there; it is taken and removed with
Ctrl-C held back, so that no lock is left behind. :func:`committed_outputs` lists
what this process has committed, so that an interrupted command can say
truthfully what was written.
"""

from __future__ import annotations

import glob
import os
import shutil
import tempfile
from collections.abc import Iterable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from imubounds.errors import OutputError
from imubounds.io.atomic import (
    atomic_open,
    atomic_path,
    ensure_dir,
    to_jsonable,
    umask_mode,
    write_json,
    write_text,
    write_with,
)
from imubounds.io.locks import acquire_lock, lock_owner, pid_alive, signals_held
from imubounds.io.records import (
    BACKUP_PREFIX,
    BOOKKEEPING,
    COMMIT_RECORD,
    FILES_LOCK,
    FILES_RECORD,
    LOCK_NAME,
    RUN_RECORD,
    committed_outputs,
    files_record,
    files_under,
    fingerprint,
    fingerprints,
    is_input,
    journal,
    listed_files,
    names_written,
    read_json,
    recorded_files,
    remove_stale_parts,
    reset_committed_outputs,
    unchanged,
    written_by_imubounds,
)

__all__ = [
    "BOOKKEEPING", "COMMIT_RECORD", "FILES_RECORD", "LOCK_NAME", "RUN_RECORD", "OutputSet",
    "atomic_open", "atomic_path", "check_output_file", "check_output_folder",
    "committed_outputs", "ensure_dir",
    "listed_files", "output_file", "record_written_files", "recorded_files",
    "reset_committed_outputs", "to_jsonable", "write_json", "write_run_record", "write_text",
    "write_with", "written_by_imubounds",
]


def write_run_record(outdir: str | os.PathLike[str], argv: list[str] | None, **extra: Any) -> Path:
    """Write ``run.json``: the exact command, package version and platform, for reproduction."""
    import platform
    import shlex
    import sys
    from datetime import UTC, datetime

    from imubounds.version import __version__

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
    if d.name in BOOKKEEPING:
        raise OutputError(f"{who}: {d.name} is imubounds' record of a folder's results; "
                          f"{advice}")
    parent = d.parent
    try:
        if not parent.is_dir():
            what = "is not a folder" if parent.exists() else "does not exist"
            raise OutputError(f"{who}: folder {parent} {what}; create it or {advice}")
        if not os.access(parent, os.W_OK | os.X_OK):
            raise OutputError(f"{who}: folder {parent} is not writable; {advice}")
        if is_input(d, [Path(i) for i in inputs if os.fspath(i)]):
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
                    f"imubounds will not overwrite it ({advice}, or pass --overwrite)"
                )
        pid = lock_owner(parent / LOCK_NAME)
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
        os.chmod(tmp_path, umask_mode())
        folder = d.parent
        lock = folder / FILES_LOCK
        with signals_held():  # taken and removed with Ctrl-C held back: never left behind
            acquire_lock(lock, folder, wait_s=10.0)
        try:
            remove_stale_parts(folder, (FILES_RECORD,))
            check_output_file(d, force=force, inputs=inputs, option=option, advice=advice)
            with signals_held():
                _replace_recorded(tmp_path, d)
                journal(str(d))
        except OSError as err:
            raise OutputError(f"{who}: cannot be written ({err.strerror or err})") from err
        finally:
            with signals_held():
                _remove_file(lock)
    finally:
        if tmp_path.exists():
            tmp_path.unlink()


def _replace_recorded(tmp: Path, d: Path) -> None:
    """Move ``tmp`` onto ``d`` and record it in the folder's single-file record, as one
    step: the old ``d`` is set aside first and put back if anything fails."""
    folder = d.parent
    bak = None
    if d.exists() or d.is_symlink():
        fd, name = tempfile.mkstemp(prefix=f".{d.name}.", suffix=".old.part", dir=folder)
        os.close(fd)
        bak = Path(name)
    aside = placed = False
    try:
        if bak is not None:
            os.replace(d, bak)
            aside = True
        os.replace(tmp, d)
        placed = True
        rec = {k: v for k, v in files_record(folder).items() if (folder / k).is_file()}
        rec[d.name] = fingerprint(d)
        write_json(folder / FILES_RECORD, {"format": "imubounds.files/1", "files": rec})
    except BaseException:
        if placed:
            os.replace(d, tmp)  # the new file back where it came from
        if aside and bak is not None:
            os.replace(bak, d)
        raise
    finally:
        if bak is not None:
            _remove_file(bak)


# ----------------------------------------------------------------------------- output sets
class OutputSet:
    """A set of result files that lands in a directory complete or not at all.

    Files are written into a staging directory beside ``target``; on success
    they are moved into ``target`` and ``run.json`` (written last) lists them
    with their sizes and modification times: a directory whose ``run.json``
    lists a file set is complete. Rules:

    * ``target`` must be new, empty, or hold only the results of an earlier run of
      the same ``command`` on the same ``source`` (its inputs by default) as
      imubounds left them; anything else (the user's files, another command's or
      another input's results, a result the user edited) is refused when the set
      is opened, naming a few, unless ``force`` (``--overwrite``): then they are
      kept, and only files of the names this set writes are replaced;
    * an input of the run is never overwritten, even with ``force``;
    * another run writing the same directory holds ``target/.imubounds.lock``:
      :class:`OutputError` names its process; the lock is taken and removed with
      Ctrl-C held back, so that it is never left behind;
    * on an exception (Ctrl-C included) before the commit, the staging
      directory is removed and ``target`` is untouched (``committed`` stays
      False, so the caller can say so truthfully). The commit moves the old
      versions of the files it replaces or supersedes into a backup folder inside
      ``target``, then the new files in, then writes ``run.json``; an exception at
      any step moves everything back (the old set, complete), and Ctrl-C is held
      back until the commit is done or undone;
    * a run killed outright (SIGKILL, power loss) leaves at worst a hidden
      staging directory (removed by the next run into ``target``) or, in the
      middle of the commit, a directory without ``run.json`` and its
      ``.imubounds-commit.json``: the next run into ``target`` restores the old
      set from the backup first.

    Usage::

        with OutputSet(out_dir, command="static", inputs=[log_path], force=args.force) as out:
            write_json(out.path("noise.json"), doc)
            out.record(argv)

    ``subsets``: top-level sub-folders that other commands of the same run write as
    their own sets (``demo``): not judged here.
    """

    def __init__(
        self,
        target: str | os.PathLike[str],
        *,
        force: bool = False,
        inputs: Iterable[str | os.PathLike[str]] = (),
        command: str | None = None,
        source: Iterable[str | os.PathLike[str]] | None = None,
        subsets: Iterable[str] = (),
    ) -> None:
        self._empty = not os.fspath(target).strip()  # Path("") would be "." silently
        self.target = Path(target)
        self.force = force
        self.inputs = [Path(p) for p in inputs if os.fspath(p)]
        self.command = command
        src = self.inputs if source is None else [Path(p) for p in source if os.fspath(p)]
        self.source = sorted(str(p.resolve()) for p in src)
        self.subsets = tuple(subsets)
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
            if t.exists() and is_input(t, self.inputs):
                raise OutputError(
                    f"output directory {t} is an input of this run; choose another -o"
                )
            if not t.exists():
                t.mkdir(parents=True)
                self._created_target = True
            with signals_held():  # the lock is held exactly when self._lock says so
                acquire_lock(t / LOCK_NAME, t)
                self._lock = t / LOCK_NAME
            self._restore_interrupted_commit()
            self._remove_stale_staging()
            remove_stale_parts(t, (RUN_RECORD, COMMIT_RECORD))
            if not self.force:
                self._refuse_others()
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
        if self.command is not None:
            extra.setdefault("command_name", self.command)
        self._record = {"argv": argv, **extra, "inputs": self.source}
        write_run_record(self.staging, argv, complete=False, **extra)

    # -- internals ------------------------------------------------------------
    def _parent(self) -> Path:
        return self.target.resolve().parent

    def _staging_prefix(self, pid: int) -> str:
        return f".{self.target.resolve().name}.imubounds-{pid}-"

    def _remove_stale_staging(self) -> None:
        """Staging directories of runs into this target whose process is gone (killed)."""
        head = f".{self.target.resolve().name}.imubounds-"
        for d in self._parent().glob(glob.escape(head) + "*"):
            pid_text = d.name[len(head):].split("-", 1)[0]
            if d.is_dir() and pid_text.isdigit() and not pid_alive(int(pid_text)):
                shutil.rmtree(d, ignore_errors=True)

    def _release(self) -> None:
        with signals_held():  # a second Ctrl-C here must not leave the lock behind
            try:
                if self._staging is not None:
                    staging, self._staging = self._staging, None
                    _remove_tree(staging)
            finally:
                if self._lock is not None:
                    lock, self._lock = self._lock, None
                    _remove_file(lock)
                if self._created_target and not self.committed:
                    try:
                        self.target.rmdir()  # only if still empty
                    except OSError:
                        pass

    def _staged(self) -> list[str]:
        root = self.staging
        names = (str(p.relative_to(root)) for p in root.rglob("*") if p.is_file())
        return sorted(n for n in names if n != RUN_RECORD)

    def _own_files(self) -> set[str]:
        """Files in ``target`` that the earlier run of this command on this source wrote
        and nobody changed since (all files imubounds listed, for a set without a
        ``command``)."""
        rec = read_json(self.target / RUN_RECORD)
        if self.command is None:
            return names_written(self.target) | set(files_record(self.target))
        if not isinstance(rec, dict) or rec.get("command_name") != self.command:
            return set()
        if isinstance(rec.get("inputs"), list) and sorted(map(str, rec["inputs"])) != self.source:
            return set()
        files = rec.get("files")
        names = [str(f) for f in files] if isinstance(files, list) else []
        return {n for n in names if unchanged(self.target, n, rec)}

    def _refuse_others(self) -> None:
        """:class:`OutputError` if ``target`` holds anything but this command's own earlier
        results (see the class docstring)."""
        own = self._own_files()
        others: list[str] = []
        for name in files_under(self.target, skip=self.subsets):
            if name not in own:
                others.append(name)
                if len(others) >= 200:  # enough to say what is there
                    break
        if not others:
            return
        rec = read_json(self.target / RUN_RECORD)
        listed = names_written(self.target) | set(files_record(self.target))
        changed = [n for n in others if n in listed and not written_by_imubounds(
            self.target / n)]
        theirs = [n for n in others if n in listed and n not in changed]
        kinds = [k for k, there in (
            ("files imubounds did not write", len(theirs) + len(changed) < len(others)),
            ("files changed since imubounds wrote them", bool(changed)),
            ("other results", bool(theirs))) if there]
        run = ""
        if theirs and isinstance(rec, dict) and rec.get("command"):
            cmd = str(rec["command"])
            ins = rec.get("inputs")
            if rec.get("command_name") and isinstance(ins, list):
                on = ", ".join(Path(str(x)).name for x in ins[:2]) + (", ..." if len(ins) > 2
                                                                      else "")
                run = f" (the results of 'imubounds {rec['command_name']}'" + (
                    f" on {on})" if on else ")")
            else:
                run = f" (the results of '{cmd if len(cmd) <= 70 else cmd[:67] + '...'}')"
        first = [n for n in others if n not in listed] + changed + theirs  # the user's first
        shown = ", ".join(
            n + (" (an input of this run)" if is_input(self.target / n, self.inputs) else "")
            for n in first[:3]) + (", ..." if len(first) > 3 else "")
        raise OutputError(
            f"output directory {self.target} holds {' and '.join(kinds)}: {shown}{run}; "
            "imubounds writes its results only into a new or empty folder or over its own "
            "earlier results of the same command and input: choose another -o, or pass "
            "--overwrite (the files there are kept; those of the names this run writes are "
            "replaced)"
        )

    def _conflicts(self, names: list[str]) -> list[str]:
        listed = bool(names_written(self.target))
        out: list[str] = []
        for name in names:
            dest = self.target / name
            if not (dest.exists() or dest.is_symlink()):
                continue
            if is_input(dest, self.inputs):
                out.append(
                    f"{dest} is an input of this run; imubounds will not overwrite it "
                    "(choose another -o)"
                )
            elif not self.force and not (
                (name == RUN_RECORD and listed) or written_by_imubounds(dest)
            ):
                what = "a directory" if dest.is_dir() else "a file imubounds did not write"
                out.append(
                    f"{dest} exists and is {what} (or was changed since); imubounds will not "
                    "overwrite it (choose another -o, or pass --overwrite)"
                )
        return out

    def _superseded(self, names: list[str]) -> list[str]:
        """Files the previous complete run of the *same command* on the same source listed
        that this set does not rewrite (a report and figures beside a later ``--no-plot``
        run's results) and that nobody changed since: removed at the commit, so that the
        folder holds one run's results. Files of another command or source, changed
        files, inputs of this run and files not listed are never removed."""
        rec = read_json(self.target / RUN_RECORD)
        mine = (self._record or {}).get("command_name", self.command)
        if not isinstance(rec, dict) or mine is None or rec.get("command_name") != mine:
            return []
        if isinstance(rec.get("inputs"), list) and sorted(map(str, rec["inputs"])) != self.source:
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
                or is_input(dest, self.inputs)
                or not unchanged(self.target, name, rec)
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
        old = sorted(names_written(self.target))
        superseded = self._superseded(names_all)
        # Ctrl-C is held back for the renames of the commit, and any exception undoes
        # them, so that the set is either the old one or the new one, and the message
        # can say which.
        try:
            with signals_held():
                self._swap(names, superseded, old, names_all)
        except OSError as err:
            raise OutputError(f"cannot write to {self.target}: {err.strerror or err}") from err

    def _swap(self, names: list[str], superseded: list[str], old: list[str],
              names_all: list[str]) -> None:
        t = self.target
        backup = Path(tempfile.mkdtemp(prefix=f"{BACKUP_PREFIX}{os.getpid()}-", dir=t))
        moved_out: list[str] = []
        moved_in: list[str] = []
        try:
            write_json(t / COMMIT_RECORD, {"pid": os.getpid(), "old": old, "new": names_all,
                                           "backup": backup.name})  # fmt: skip
            for name in [RUN_RECORD, *names, *superseded]:  # the old set aside, whole
                src = t / name
                if src.is_file() or src.is_symlink():
                    (backup / name).parent.mkdir(parents=True, exist_ok=True)
                    os.replace(src, backup / name)
                    moved_out.append(name)
            for name in names:
                dest = t / name
                dest.parent.mkdir(parents=True, exist_ok=True)
                os.replace(self.staging / name, dest)
                moved_in.append(name)
            if self._record is not None:
                extra = dict(self._record)
                argv = extra.pop("argv", None)
                # files of earlier runs that this set did not replace stay imubounds'
                # (overwritable later) without being part of this complete set
                earlier = sorted(n for n in old if n not in names_all and (t / n).is_file())
                write_run_record(t, argv, files=names, complete=True,
                                 fingerprints=fingerprints(t, [*names, *earlier]),
                                 **({"earlier_files": earlier} if earlier else {}), **extra)
            (t / COMMIT_RECORD).unlink()
        except BaseException:
            self._undo(backup, moved_in, moved_out)
            raise
        self.committed = True
        journal(str(t))
        _remove_tree(backup)

    def _undo(self, backup: Path, moved_in: list[str], moved_out: list[str]) -> None:
        """Put the old set back after a failed commit (the new files go back to the
        staging directory); if that fails too, the commit record stays for the next run
        (:meth:`_restore_interrupted_commit`)."""
        t = self.target
        try:
            for name in moved_in:
                os.replace(t / name, self.staging / name)
                _prune(t, name)
            if RUN_RECORD in moved_out:  # then any run.json there is the new one
                (t / RUN_RECORD).unlink(missing_ok=True)
            for name in moved_out:
                (t / name).parent.mkdir(parents=True, exist_ok=True)
                os.replace(backup / name, t / name)
            (t / COMMIT_RECORD).unlink(missing_ok=True)
            shutil.rmtree(backup, ignore_errors=True)
        except OSError:
            pass

    def _restore_interrupted_commit(self) -> None:
        """A commit killed outright (its ``.imubounds-commit.json`` and backup folder are
        still there, and its process is gone, since this one holds the lock): take its new
        files out and put the old set back from the backup. A backup folder without a
        commit record is what a killed run left after its commit: removed."""
        t = self.target
        intent = read_json(t / COMMIT_RECORD)
        backup = t / str(intent.get("backup", "")) if isinstance(intent, dict) else None
        if backup is not None and backup.name.startswith(BACKUP_PREFIX) and backup.is_dir():
            for name in (intent or {}).get("new") or []:
                p = t / str(name)
                if ".." not in Path(str(name)).parts and (p.is_file() or p.is_symlink()):
                    p.unlink()
                    _prune(t, str(name))
            for p in sorted(backup.rglob("*")):
                if p.is_file() or p.is_symlink():
                    dest = t / p.relative_to(backup)
                    dest.parent.mkdir(parents=True, exist_ok=True)
                    os.replace(p, dest)
            (t / COMMIT_RECORD).unlink(missing_ok=True)
        for d in t.glob(glob.escape(BACKUP_PREFIX) + "*"):
            if d.is_dir() and not d.is_symlink():
                shutil.rmtree(d, ignore_errors=True)


def check_output_folder(
    target: str | os.PathLike[str],
    *,
    command: str,
    force: bool = False,
    inputs: Iterable[str | os.PathLike[str]] = (),
    source: Iterable[str | os.PathLike[str]] | None = None,
    subsets: Iterable[str] = (),
) -> None:
    """The rule of :class:`OutputSet` for a command that writes its files in place
    (``fleet``): :class:`OutputError` if ``target`` holds anything but that command's own
    earlier results of ``source``, unless ``force``."""
    if force or not Path(target).is_dir():
        return
    OutputSet(target, inputs=inputs, command=command, source=source,
              subsets=subsets)._refuse_others()  # fmt: skip


def _remove_tree(p: Path) -> None:
    """``shutil.rmtree`` that finishes even when an exception interrupts it (re-raised)."""
    try:
        shutil.rmtree(p, ignore_errors=True)
    except BaseException:
        shutil.rmtree(p, ignore_errors=True)
        raise


def _remove_file(p: Path) -> None:
    """``unlink`` that is done even when an exception interrupts it (re-raised)."""
    try:
        p.unlink(missing_ok=True)
    except BaseException:
        p.unlink(missing_ok=True)
        raise


def _prune(root: Path, name: str) -> None:
    """Remove the folders of ``name`` under ``root`` that are now empty."""
    p = (root / name).parent
    while p != root and root in p.parents:
        try:
            p.rmdir()
        except OSError:
            return
        p = p.parent
