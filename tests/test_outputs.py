"""Output sets: complete or nothing, never over a file imubounds did not write."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
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
    _run(tmp_path, ["a.txt", "c.txt"])  # its own files only: no question asked
    (tmp_path / "notes.md").write_text("user")
    with pytest.raises(OutputError, match=r"did not write: notes.md; .*--overwrite"):
        _run(tmp_path, ["a.txt", "b.txt"])
    _run(tmp_path, ["a.txt", "b.txt"], force=True)  # --overwrite: written beside them
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


# ----------------------------------------------------------------------------- single files
def test_output_file_records_what_it_wrote_and_refuses_the_rest(tmp_path: Path) -> None:
    from imubounds.io.outputs import FILES_RECORD, output_file, written_by_imubounds

    dest = tmp_path / "x.csv"
    with output_file(dest) as tmp:
        tmp.write_text("1")
    assert dest.read_text() == "1" and written_by_imubounds(dest)
    assert (tmp_path / FILES_RECORD).is_file()
    with output_file(dest) as tmp:  # its own file: replaced
        tmp.write_text("2")
    assert dest.read_text() == "2"
    dest.write_text("edited by the user")  # changed since: no longer imubounds'
    with pytest.raises(OutputError, match="did not write it"), output_file(dest) as tmp:
        tmp.write_text("3")
    assert dest.read_text() == "edited by the user"
    src = tmp_path / "in.json"
    src.write_text("{}")
    with pytest.raises(OutputError, match="input of this run"), output_file(
        src, inputs=[src], force=True
    ) as tmp:
        tmp.write_text("4")
    assert src.read_text() == "{}"
    assert sorted(p.name for p in tmp_path.iterdir()) == [FILES_RECORD, "in.json", "x.csv"]


def test_output_file_interrupted_leaves_nothing(tmp_path: Path) -> None:
    from imubounds.io.outputs import output_file

    dest = tmp_path / "x.csv"
    with pytest.raises(KeyboardInterrupt), output_file(dest) as tmp:
        tmp.write_text("half")
        raise KeyboardInterrupt
    assert list(tmp_path.iterdir()) == []


# ------------------------------------------------------- a run killed in the middle of its commit
def _set(target: Path, tag: str, names: list[str], force: bool = False) -> None:
    with OutputSet(target, force=force) as out:
        for n in names:
            write_text(out.path(n), f"{tag}:{n}")
        out.record(["test", tag], command_name="test")


def _check_complete_or_absent(target: Path, tags: dict[str, list[str]]) -> str | None:
    """If run.json is there, every file it lists is there and from its run; its tag."""
    rec_path = target / "run.json"
    if not rec_path.exists():
        return None
    rec = json.loads(rec_path.read_text())
    assert rec["complete"] is True
    tag = rec["command"].split()[-1]
    assert rec["files"] == sorted(tags[tag])
    for n in rec["files"]:
        assert (target / n).read_text() == f"{tag}:{n}", f"{n} is not from run {tag}"
    return tag


def test_kill_at_every_step_of_a_commit_never_leaves_a_set_that_looks_complete(
    tmp_path: Path,
) -> None:
    """SIGKILL simulated at each file-system step of the commit (os._exit: no clean-up)."""
    tags = {"old": ["a.txt", "b.txt"], "new": ["a.txt", "b.txt", "c.txt"]}
    steps = 0
    real_replace = os.replace

    def counting(*a: object) -> None:
        nonlocal steps
        steps += 1
        real_replace(*a)  # type: ignore[arg-type]

    probe = tmp_path / "probe"
    _set(probe, "old", tags["old"])
    os.replace = counting  # type: ignore[assignment]
    try:
        _set(probe, "new", tags["new"])
    finally:
        os.replace = real_replace
    assert steps >= 5  # commit record, three files, run.json

    for k in range(steps + 1):
        target = tmp_path / f"t{k}"
        _set(target, "old", tags["old"])
        (target / "notes.md").write_text("the user's notes")
        pid = os.fork()
        if pid == 0:  # the child dies at step k of writing the new set
            calls = 0

            def dying(*a: object, k: int = k) -> None:
                nonlocal calls
                calls += 1
                if calls > k:
                    os._exit(9)
                real_replace(*a)  # type: ignore[arg-type]

            os.replace = dying  # type: ignore[assignment]
            try:
                _set(target, "new", tags["new"], force=True)
            finally:
                os._exit(0)
        os.waitpid(pid, 0)
        tag = _check_complete_or_absent(target, tags)
        assert (target / "notes.md").read_text() == "the user's notes"
        assert tag in (None, "old", "new"), k
        # the next run recognises every file of both runs: no refusal, a clean directory
        _set(target, "again", tags["new"], force=True)
        assert _check_complete_or_absent(target, {**tags, "again": tags["new"]}) == "again"
        hidden = sorted(p.name for p in target.iterdir() if p.name.startswith("."))
        assert hidden == [], (k, hidden)
        assert not [p for p in tmp_path.iterdir() if p.name.startswith(f".t{k}.")], k


# --------------------------------------------- real runs killed with SIGINT and SIGKILL
def _start(argv: list[str]) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [sys.executable, "-m", "imubounds", *argv],
        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
    )


def _wait_for(cond: Callable[[], bool], proc: subprocess.Popen[str], limit: float = 120.0) -> None:
    t0 = time.monotonic()
    while not cond() and proc.poll() is None and time.monotonic() - t0 < limit:
        time.sleep(0.005)


def _kill_runs(
    tmp_path: Path,
    argv_of: Callable[[str], list[str]],
    target: Path,
    check_set: Callable[[str], None],
    plan: list[tuple[int, float]],
) -> None:
    """Run ``argv_of(tag)`` into ``target``, first to the end (timing the part after its
    run record is staged), then killed per ``plan`` (signal, fraction of that time); after
    each kill the target holds its previous set or one complete new set, and an unrelated
    file is untouched; after SIGINT the message says truthfully which."""
    target.mkdir(exist_ok=True)
    (target / "notes.md").write_text("the user's notes")
    parent = target.parent
    window = None
    for i, (sig, fraction) in enumerate([(0, 0.0), *plan]):
        tag = "a" if i % 2 else "b"
        before = (target / "run.json").read_text() if (target / "run.json").exists() else None
        proc = _start(argv_of(tag))
        staging = f".{target.name}.imubounds-{proc.pid}-"

        def recorded(staging: str = staging) -> bool:
            return any((d / "run.json").exists() for d in parent.iterdir()
                       if d.name.startswith(staging))

        _wait_for(recorded, proc)
        t0 = time.monotonic()
        if window is None:  # the first run goes to the end: how long is the interesting part?
            proc.wait(timeout=300)
            window = time.monotonic() - t0
        else:
            time.sleep(fraction * window)
            if proc.poll() is None:
                proc.send_signal(sig)
        _, err = proc.communicate(timeout=300)
        assert "Traceback" not in err, err
        assert (target / "notes.md").read_text() == "the user's notes"
        now = (target / "run.json").read_text() if (target / "run.json").exists() else None
        if i == 0:
            assert proc.returncode == 0 and now is not None, err
        if now is not None:
            rec = json.loads(now)
            assert rec["complete"] is True
            for n in rec["files"]:
                assert (target / n).is_file(), f"run.json lists {n} but it is not there"
            check_set(rec["command"])
        if sig == signal.SIGINT and proc.returncode == 130:
            if "nothing was written" in err:
                assert now == before, "said nothing was written, but the set changed"
            else:
                assert f"complete results had been written to {target}" in err, err
                assert now is not None and now != before
    # a last run: nothing of the interrupted runs is left over beside its set
    final = subprocess.run([sys.executable, "-m", "imubounds", *argv_of("a")],
                           capture_output=True, text=True, check=False)
    assert final.returncode == 0, final.stderr
    rec = json.loads((target / "run.json").read_text())
    check_set(rec["command"])
    assert (target / "notes.md").read_text() == "the user's notes"
    left = {str(p.relative_to(target)) for p in target.rglob("*") if p.is_file()}
    assert left == {*rec["files"], "run.json", "notes.md"}, left
    assert not [p for p in target.iterdir() if p.name.startswith(".imubounds")]
    assert not [p for p in parent.iterdir() if p.name.startswith(f".{target.name}.imubounds-")]


#: (signal, when): fractions of the time a run spends between staging its run record
#: and exiting (figures, report, the commit, the last message).
KILL_PLAN = [
    (signal.SIGINT, 0.5),
    (signal.SIGKILL, 0.9),
    (signal.SIGINT, 0.97),
    (signal.SIGKILL, 1.0),
]


@pytest.mark.slow  # 6 runs of `imubounds static` in subprocesses (~45 s on 2 busy cores)
def test_static_killed_at_random_points_leaves_old_set_or_new_set(tmp_path: Path) -> None:
    rng = np.random.default_rng(3)
    for tag in ("a", "b"):
        t = np.arange(20_000) / 100.0
        g = rng.normal(0.0, 0.01, t.size)
        text = "time_s,gyro_x_rads,gyro_y_rads\n" + "".join(
            f"{a:.2f},{b:.6f},{-b:.6f}\n" for a, b in zip(t, g, strict=True)
        )
        (tmp_path / f"log_{tag}.csv").write_text(text)
    target = tmp_path / "out"

    def argv_of(tag: str) -> list[str]:
        return ["static", str(tmp_path / f"log_{tag}.csv"), "-o", str(target), "-q",
                "--models", "none", "--overwrite"]  # beside the user's notes

    def check_set(command: str) -> None:
        tag = "a" if "log_a.csv" in command else "b"
        noise = json.loads((target / "noise.json").read_text())
        assert noise["input"]["path"].endswith(f"log_{tag}.csv"), "noise.json of another run"
        other = "b" if tag == "a" else "a"
        assert f"log_{other}.csv" not in (target / "report.html").read_text()

    _kill_runs(tmp_path, argv_of, target, check_set, KILL_PLAN)


@pytest.mark.slow  # 5 runs of `imubounds simulate` in subprocesses (~20 s on 2 busy cores)
def test_simulate_killed_at_random_points_leaves_old_set_or_new_set(tmp_path: Path) -> None:
    target = tmp_path / "sim"

    def argv_of(tag: str) -> list[str]:
        return ["simulate", "--seed", "1" if tag == "a" else "2", "--duration", "200",
                "--distance", "2000", "-o", str(target), "-q", "--overwrite"]

    def check_set(command: str) -> None:
        seed = 1 if "--seed 1" in command else 2
        scen = json.loads((target / "scenario.json").read_text())
        assert scen["config"]["seed"] == seed, "scenario.json of another run"

    _kill_runs(tmp_path, argv_of, target, check_set, KILL_PLAN[:3])


# ------------------------------------- Ctrl-C injected at every step of the commit sequence
class _InterruptAt:
    """Patch the file-system calls of a commit (rename, unlink, open, mkdir, rmdir) so
    that call number ``k`` raises KeyboardInterrupt (once), as a Ctrl-C at that instant
    would if nothing held it back; ``k = 0`` only counts."""

    NAMES = ("replace", "unlink", "open", "mkdir", "rmdir")

    def __init__(self, monkeypatch: pytest.MonkeyPatch, k: int) -> None:
        self.k, self.calls = k, 0
        for name in self.NAMES:
            real = getattr(os, name)
            monkeypatch.setattr(os, name, self._wrap(real))

    def _wrap(self, real: Callable[..., object]) -> Callable[..., object]:
        def call(*a: object, **kw: object) -> object:
            self.calls += 1
            if self.calls == self.k:
                raise KeyboardInterrupt
            return real(*a, **kw)
        return call


def _tree(d: Path) -> dict[str, str]:
    return {str(p.relative_to(d)): p.read_text() for p in sorted(d.rglob("*")) if p.is_file()}


def _set_of(d: Path) -> dict[str, str]:
    """The files of ``d`` with run.json reduced to its command and file list."""
    out = _tree(d)
    if "run.json" in out:
        rec = json.loads(out["run.json"])
        out["run.json"] = f"{rec['command']} {rec['files']} {rec['complete']}"
    return out


def test_ctrl_c_at_every_step_of_a_commit_leaves_old_or_new_set_and_no_lock(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The old set has a.txt, sub/b.txt, c.txt; the new one rewrites a.txt and sub/b.txt,
    adds d.txt and supersedes c.txt. A KeyboardInterrupt at any single file-system call,
    from taking the lock to removing it, leaves exactly the old set or exactly the new
    one, the user's file, no lock, no staging or backup folder, and a message-worthy
    ``committed`` flag that says which."""
    def setup(target: Path) -> None:
        _set(target, "old", ["a.txt", "sub/b.txt", "c.txt"])
        (target / "notes.md").write_text("the user's notes")

    probe = tmp_path / "probe"
    setup(probe)
    old = _set_of(probe)
    with monkeypatch.context() as m:
        counter = _InterruptAt(m, 0)
        _set(probe, "new", ["a.txt", "sub/b.txt", "d.txt"], force=True)
    new = _set_of(probe)
    assert "c.txt" not in new and new["d.txt"] == "new:d.txt"
    assert counter.calls > 15
    seen = set()
    for k in range(1, counter.calls + 1):
        target = tmp_path / f"t{k}"
        setup(target)
        out = None
        with monkeypatch.context() as m:
            _InterruptAt(m, k)
            try:
                out = OutputSet(target, force=True)
                with out:
                    for n in ("a.txt", "sub/b.txt", "d.txt"):
                        write_text(out.path(n), f"new:{n}")
                    out.record(["test", "new"], command_name="test")
            except KeyboardInterrupt:
                pass
        now = _set_of(target)
        base = {n: v for n, v in now.items() if n != "notes.md"}
        want = old if not (out is not None and out.committed) else new
        assert base == {n: v for n, v in want.items() if n != "notes.md"}, k
        seen.add("new" if want is new else "old")
        assert now["notes.md"] == "the user's notes"
        assert not (target / LOCK_NAME).exists(), f"lock left at step {k}"
        hidden = [p.name for p in target.iterdir() if p.name.startswith(".")]
        assert hidden == [], (k, hidden)
        assert not [p for p in tmp_path.iterdir() if p.name.startswith(f".t{k}.")], k
    assert seen == {"old", "new"}


def test_ctrl_c_at_every_step_of_a_single_file_leaves_old_or_new_and_no_lock(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
) -> None:
    from imubounds.io.outputs import FILES_RECORD, output_file

    def write(dest: Path, text: str) -> None:
        with output_file(dest) as tmp:
            tmp.write_text(text)

    probe = tmp_path / "probe"
    probe.mkdir()
    write(probe / "x.yaml", "old")
    with monkeypatch.context() as m:
        counter = _InterruptAt(m, 0)
        write(probe / "x.yaml", "new")
    for k in range(1, counter.calls + 1):
        d = tmp_path / f"t{k}"
        d.mkdir()
        write(d / "x.yaml", "old")
        with monkeypatch.context() as m:
            _InterruptAt(m, k)
            try:
                write(d / "x.yaml", "new")
            except KeyboardInterrupt:
                pass
        assert (d / "x.yaml").read_text() in ("old", "new"), k
        names = sorted(p.name for p in d.iterdir())
        assert names == [FILES_RECORD, "x.yaml"], (k, names)
        write(d / "x.yaml", "again")  # still recognised as imubounds' own file
        assert (d / "x.yaml").read_text() == "again"


def test_a_set_is_refused_beside_other_files_other_commands_and_other_inputs(
    tmp_path: Path,
) -> None:
    """What an output folder may hold without --overwrite: only the same command's
    earlier results of the same input, unchanged."""
    log_a, log_b = tmp_path / "a.csv", tmp_path / "b.csv"
    log_a.write_text("a")
    log_b.write_text("b")
    out = tmp_path / "out"

    def run(cmd: str, log: Path, names: list[str], force: bool = False) -> None:
        with OutputSet(out, command=cmd, inputs=[log], force=force) as o:
            for n in names:
                write_text(o.path(n), f"{cmd}:{log.name}:{n}")
            o.record(["test", cmd, str(log)])

    run("static", log_a, ["noise.json", "fig.png"])
    run("static", log_a, ["noise.json"])  # a re-run: fig.png superseded, no question
    assert sorted(p.name for p in out.iterdir()) == ["noise.json", "run.json"]
    before = _tree(out)
    with pytest.raises(OutputError, match=r"other results: noise.json \(the results of .imub"):
        run("static", log_b, ["noise.json"])  # another log's results
    with pytest.raises(OutputError, match=r"holds other results: noise.json"):
        run("simulate", log_a, ["imu.csv"])  # another command's results
    (out / "noise.json").write_text("edited by the user")
    before = _tree(out)
    with pytest.raises(OutputError, match=r"changed since imubounds wrote them: noise.json"):
        run("static", log_a, ["noise.json"])  # a result the user edited is the user's
    assert _tree(out) == before
    run("static", log_b, ["noise.json", "x.txt"], force=True)
    assert (out / "noise.json").read_text() == "static:b.csv:noise.json"
    for junk in (".DS_Store", "Thumbs.db"):  # what an operating system leaves is no file
        (out / junk).write_text("")
    run("static", log_b, ["noise.json"])
    assert not (out / "x.txt").exists()
