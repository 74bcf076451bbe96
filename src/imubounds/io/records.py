"""The records by which imubounds recognises the files it wrote in a folder (see
:mod:`imubounds.io.outputs`): a result set's ``run.json`` (its files, their sizes and
modification times, the command and its inputs), an interrupted commit's
``.imubounds-commit.json``, the single-file record ``.imubounds-files.json``; the names of
imubounds' bookkeeping files; and the journal of what this process has written.
"""

from __future__ import annotations

import glob
import json
import os
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import Any

RUN_RECORD = "run.json"
LOCK_NAME = ".imubounds.lock"
#: Written before a result set is moved in, removed after its run.json is written.
COMMIT_RECORD = ".imubounds-commit.json"
#: Single files imubounds wrote in a folder, with their size and modification time.
FILES_RECORD = ".imubounds-files.json"
FILES_LOCK = ".imubounds-files.lock"
#: Prefix of the folder (inside the target) that holds the old set during a commit.
BACKUP_PREFIX = ".imubounds-old-"
#: imubounds' own bookkeeping, and files an operating system puts in any folder: never
#: counted as the user's files of an output folder.
BOOKKEEPING = frozenset({RUN_RECORD, LOCK_NAME, COMMIT_RECORD, FILES_RECORD, FILES_LOCK})
OS_FILES = frozenset({".DS_Store", "Thumbs.db", "desktop.ini"})

_JOURNAL: list[str] = []


def journal(entry: str) -> None:
    """Note that ``entry`` (a directory or file) has been written completely."""
    _JOURNAL.append(entry)


def committed_outputs() -> list[str]:
    """What this process has written completely so far (directories and files)."""
    return list(_JOURNAL)


def reset_committed_outputs() -> None:
    """Forget :func:`committed_outputs` (the CLI does this at the start of a command)."""
    _JOURNAL.clear()


def read_json(path: Path) -> Any:
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None


def names_written(target: Path) -> set[str]:
    """Relative names that the last imubounds run in ``target`` wrote: those its run.json
    lists, and those of a commit that was interrupted (``.imubounds-commit.json``)."""
    names: set[str] = set()
    rec = read_json(target / RUN_RECORD)
    for key in ("files", "earlier_files"):
        files = rec.get(key) if isinstance(rec, dict) else None
        if isinstance(files, list):
            names |= {str(f) for f in files}
    intent = read_json(target / COMMIT_RECORD)
    if isinstance(intent, dict):
        for key in ("old", "new"):
            if isinstance(intent.get(key), list):
                names |= {str(f) for f in intent[key]}
    return names | {RUN_RECORD} if names else names


def fingerprint(path: Path) -> list[int]:
    st = path.lstat()
    return [int(st.st_size), int(st.st_mtime_ns)]


def fingerprints(folder: Path, names: Iterable[str]) -> dict[str, list[int]]:
    out = {}
    for n in names:
        try:
            out[n] = fingerprint(folder / n)
        except OSError:
            continue
    return out


def files_record(folder: Path) -> dict[str, list[int]]:
    rec = read_json(folder / FILES_RECORD)
    files = rec.get("files") if isinstance(rec, dict) else None
    if not isinstance(files, dict):
        return {}
    return {
        str(k): [int(x) for x in v]
        for k, v in files.items()
        if isinstance(v, list) and len(v) == 2 and all(isinstance(x, int) for x in v)
    }


def unchanged(folder: Path, name: str, rec: Any) -> bool:
    """``folder/name`` is as imubounds left it: its fingerprint in ``rec`` (a run.json)
    or in the folder's single-file record matches (a run.json without fingerprints,
    written by an older version, is taken at its word)."""
    prints = rec.get("fingerprints") if isinstance(rec, dict) else None
    try:
        now = fingerprint(folder / name)
    except OSError:
        return False
    if not isinstance(prints, dict) or name not in prints:
        return not isinstance(prints, dict) or files_record(folder).get(name) == now
    return prints[name] == now or files_record(folder).get(name) == now


def written_by_imubounds(path: str | os.PathLike[str]) -> bool:
    """True when ``path`` is a file imubounds wrote and nobody changed since (see the
    module docstring)."""
    p = Path(path)
    if not p.is_file():
        return False
    if p.name in names_written(p.parent):
        return unchanged(p.parent, p.name, read_json(p.parent / RUN_RECORD))
    rec = files_record(p.parent).get(p.name)
    try:
        return rec is not None and rec == fingerprint(p)
    except OSError:
        return False


def same_file(a: Path, b: Path) -> bool:
    try:
        return os.path.samefile(a, b)
    except OSError:
        return a.resolve() == b.resolve()


def is_input(path: Path, inputs: Iterable[Path]) -> bool:
    return any(same_file(path, i) for i in inputs)


def remove_stale_parts(folder: Path, names: Iterable[str]) -> None:
    """Temporary files of ``names`` (``.NAME.XXXX.part``) left by a killed run; only
    called while holding the lock under which they are written."""
    for name in names:
        for p in folder.glob(glob.escape(f".{name}.") + "*.part"):
            p.unlink(missing_ok=True)


def files_under(root: Path, skip: Iterable[str] = ()) -> Iterator[str]:
    """Relative names of the files (and links, special files) under ``root``, without
    following links, leaving out imubounds' bookkeeping, operating-system files and the
    top-level entries ``skip``."""
    skipped = set(skip)
    stack = [(root, "")]
    while stack:
        folder, rel = stack.pop()
        try:
            entries = sorted(os.scandir(folder), key=lambda e: e.name)
        except OSError:
            continue
        for e in entries:
            name = f"{rel}{e.name}"
            if (not rel and e.name in skipped) or e.name in BOOKKEEPING or e.name in OS_FILES:
                continue
            if e.name.startswith(BACKUP_PREFIX):
                continue
            if e.is_dir(follow_symlinks=False):
                stack.append((Path(e.path), f"{name}/"))
            else:
                yield name



def listed_files(target: str | os.PathLike[str]) -> set[str]:
    """Relative names of the files the last imubounds run in ``target`` listed as its own
    (its ``run.json``, and an interrupted commit's record)."""
    return names_written(Path(target))


def recorded_files(folder: str | os.PathLike[str]) -> set[str]:
    """Names of the files an imubounds run recorded in ``folder`` as its own (its
    ``run.json`` and the single-file record), whether or not they still exist."""
    return names_written(Path(folder)) | set(files_record(Path(folder)))
