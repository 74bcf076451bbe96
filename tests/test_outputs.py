"""Output sets: complete or nothing, never over a file imubounds did not write."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest

from imubounds.errors import OutputError
from imubounds.io.outputs import LOCK_NAME, OutputSet, write_text


def _run(target: Path, names: list[str], **kw: object) -> None:
    with OutputSet(target, **kw) as out:  # type: ignore[arg-type]
        for n in names:
            write_text(out.path(n), n)
        out.record(["test"], command_name="test")


def test_set_lands_with_a_run_record_listing_it(tmp_path: Path) -> None:
    _run(tmp_path / "o", ["a.txt", "sub/b.txt"])
    rec = json.loads((tmp_path / "o" / "run.json").read_text())
    assert rec["files"] == ["a.txt", "sub/b.txt"] and rec["complete"] is True
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]


def test_foreign_file_is_not_overwritten_without_force(tmp_path: Path) -> None:
    (tmp_path / "a.txt").write_text("mine")
    with pytest.raises(OutputError, match="did not write"):
        _run(tmp_path, ["a.txt"])
    assert (tmp_path / "a.txt").read_text() == "mine"
    assert not (tmp_path / "run.json").exists()
    _run(tmp_path, ["a.txt"], force=True)
    assert (tmp_path / "a.txt").read_text() == "a.txt"


def test_rerun_overwrites_its_own_files_and_keeps_others(tmp_path: Path) -> None:
    _run(tmp_path, ["a.txt"])
    (tmp_path / "notes.md").write_text("user")
    _run(tmp_path, ["a.txt", "b.txt"])
    assert (tmp_path / "notes.md").read_text() == "user"
    assert json.loads((tmp_path / "run.json").read_text())["files"] == ["a.txt", "b.txt"]


def test_input_of_the_run_is_never_overwritten(tmp_path: Path) -> None:
    src = tmp_path / "noise.json"
    src.write_text("{}")
    with pytest.raises(OutputError, match="input of this run"):
        _run(tmp_path, ["noise.json"], inputs=[src], force=True)
    assert src.read_text() == "{}"


def test_exception_leaves_the_directory_untouched(tmp_path: Path) -> None:
    _run(tmp_path, ["a.txt"])
    before = {p.name: p.read_text() for p in tmp_path.iterdir()}
    with pytest.raises(KeyboardInterrupt), OutputSet(tmp_path) as out:
        write_text(out.path("a.txt"), "half")
        raise KeyboardInterrupt
    assert {p.name: p.read_text() for p in tmp_path.iterdir()} == before


def test_second_writer_is_refused_while_the_first_holds_the_lock(tmp_path: Path) -> None:
    (tmp_path / LOCK_NAME).write_text(str(os.getppid()))  # a live process
    with pytest.raises(OutputError, match="another imubounds run"):
        _run(tmp_path, ["a.txt"])
    (tmp_path / LOCK_NAME).write_text("999999999")  # stale lock of a dead process
    _run(tmp_path, ["a.txt"])
    assert not (tmp_path / LOCK_NAME).exists()


def test_output_path_that_is_a_file_is_refused(tmp_path: Path) -> None:
    f = tmp_path / "f"
    f.write_text("x")
    with pytest.raises(OutputError, match="not a directory"):
        _run(f, ["a.txt"])
