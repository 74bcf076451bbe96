"""Bad input never costs a user data, a traceback or a silently wrong number (issue 16).

One table per class of the issue: each row is an input, the command, the expected
exit code and the words the one-line message must contain. Every row also checks
that no file that existed before the command was changed or removed, that no
traceback was printed, and that an error is exactly one line on stderr.
Commands run in-process (``imubounds.cli.main``); a SIGALRM guard turns a hang
(a named pipe read by mistake) into a failure instead of a stuck test run.
"""

from __future__ import annotations

import errno
import json
import os
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest

from imubounds.cli import main

FORMATS = Path(__file__).parent / "data" / "formats"
N_ROWS = 3000
RATE = 100.0
OOC = ["--out-of-core", "--max-memory", "64KiB"]  # force the out-of-core reader
FAST = ["-q", "--models", "none", "--no-plot", "--no-report"]


#: every case fails (instead of hanging the run) if it blocks for 60 s (conftest.no_hang)
pytestmark = pytest.mark.usefixtures("no_hang")


# ----------------------------------------------------------------------------- inputs
def _rows(n: int = N_ROWS, *, t: Callable[[int], str] | None = None, sep: str = ",",
          gyro: Callable[[int, float], str] | None = None) -> list[str]:
    rng = np.random.default_rng(1)
    g = rng.normal(0.0, 0.01, n)
    a = 9.8 + rng.normal(0.0, 0.01, n)
    out = []
    for i in range(n):
        ti = t(i) if t else f"{i / RATE:.2f}"
        gi = gyro(i, g[i]) if gyro else f"{g[i]:.6f}"
        out.append(f"{ti}{sep}{gi}{sep}{a[i]:.6f}")
    return out


def _log(d: Path, name: str = "log.csv", *, header: str = "time_s,gyro_x_rads,accel_z_mps2",
         rows: list[str] | None = None) -> Path:
    p = d / name
    p.write_text("\n".join([header, *(rows if rows is not None else _rows())]) + "\n")
    return p


def _fifo(d: Path, name: str = "pipe.csv") -> Path:
    p = d / name
    os.mkfifo(p)
    return p


def _iso(i: int) -> str:
    return np.datetime_as_string(
        np.datetime64("2024-05-01T12:00:00") + np.timedelta64(10 * i, "ms"), unit="ms"
    )


# ----------------------------------------------------------------------------- checking
def _snapshot(d: Path) -> dict[str, tuple[bytes, int] | str]:
    out: dict[str, tuple[bytes, int] | str] = {}
    for p in sorted(d.rglob("*")):
        rel = str(p.relative_to(d))
        if p.is_fifo():
            out[rel] = "fifo"
        elif p.is_file():
            out[rel] = (p.read_bytes(), p.stat().st_mtime_ns)
        elif p.is_dir():
            out[rel] = "dir"
    return out


@dataclass
class Case:
    """One row of a table: ``make(tmp)`` writes the inputs and returns the argv."""

    name: str
    make: Callable[[Path], list[str]]
    code: int
    needles: tuple[str, ...]
    warning: bool = False  # code 0 with a counted warning naming the needles
    extra: Callable[[Path], None] | None = field(default=None)


def _run_case(case: Case, tmp: Path, capsys: pytest.CaptureFixture[str]) -> str:
    argv = case.make(tmp)
    before = _snapshot(tmp)
    code = main(argv)
    err = capsys.readouterr().err
    assert "Traceback" not in err, err
    assert code == case.code, f"{case.name}: exit {code}, expected {case.code}: {err}"
    after = _snapshot(tmp)
    changed = [k for k, v in before.items() if after.get(k) != v and v != "dir"]
    assert not changed, f"{case.name}: pre-existing {changed} changed or removed"
    if case.code:  # a refused run writes nothing, not even a hidden file or a lock
        added = sorted(set(after) - set(before))
        assert not added, f"{case.name}: a refused run left {added}"
    lines = [ln for ln in err.splitlines() if ln.strip()]
    if case.code:
        # counted warnings (e.g. a term the short log does not resolve) may precede the error
        errors = [ln for ln in lines if not ln.startswith("imubounds: warning:")]
        assert len(errors) == 1, f"{case.name}: not one line: {err}"
        text = errors[0]
    else:
        text = "\n".join(ln for ln in lines if ln.startswith("imubounds: warning:"))
        if case.warning:
            assert text, f"{case.name}: no warning printed: {err}"
    for needle in case.needles:
        assert needle.lower() in text.lower(), f"{case.name}: {needle!r} not in {text!r}"
    if case.extra is not None:
        case.extra(tmp)
    return text


def _table(cases: list[Case]) -> pytest.MarkDecorator:
    return pytest.mark.parametrize("case", cases, ids=[c.name for c in cases])


def _noise_rate(out: Path, rate: float = RATE, n: int = N_ROWS) -> Callable[[Path], None]:
    def check(tmp: Path) -> None:
        doc = json.loads((tmp / out / "noise.json").read_text())
        assert doc["input"]["sample_rate_hz"] == pytest.approx(rate)
        assert doc["input"]["n_samples"] == n

    return check


# ============================================================================ 1. outputs
def _user_file(d: Path, name: str, text: str = "the user's own file\n") -> Path:
    p = d / name
    p.parent.mkdir(parents=True, exist_ok=True)
    p.write_text(text)
    return p


SIM = ["simulate-noise", "--preset", "xsens-mtx", "--rate", "50", "--duration", "20", "-q"]

OUTPUT_CASES = [
    Case("simulate-noise -o a file imubounds did not write",
         lambda d: [*SIM, "-o", str(_user_file(d, "mine.csv"))], 2,
         ("did not write", "--overwrite")),
    Case("simulate-noise -o a directory",
         lambda d: [*SIM, "-o", str(d) + "/"], 2, ("does not end in .csv",)),
    Case("simulate-noise -o an existing directory named like a CSV",
         lambda d: [*SIM, "-o", str(_mkdir(d / "x.csv"))], 2, ("is a directory",)),
    Case("simulate-noise -o .", lambda d: [*SIM, "-o", "."], 2, ("does not end in .csv",)),
    Case("simulate-noise -o in a folder that does not exist",
         lambda d: [*SIM, "-o", str(d / "nowhere" / "x.csv")], 2, ("does not exist",)),
    Case("simulate-noise --save-spec over its own --from-noise input",
         lambda d: ["simulate-noise", "--from-noise", str(_user_file(d, "n.json", "{}")),
                    "--duration", "10", "-o", str(d / "x.csv"), "--save-spec", str(d / "n.json")],
         2, ("input of this run",)),
    Case("simulate-noise -o and --save-spec the same file",
         lambda d: [*SIM, "-o", str(d / "x.csv"), "--save-spec", str(d / "x.csv")],
         2, ("another output of this run",)),
    Case("simulate-noise --save-spec over a file imubounds did not write",
         lambda d: [*SIM, "-o", str(d / "x.csv"), "--save-spec", str(_user_file(d, "s.json"))],
         2, ("did not write",)),
    Case("static: a log named noise.json with -o its own folder",
         lambda d: ["static", str(_log(d, "noise.json")), "-o", str(d), *FAST],
         2, ("noise.json (an input of this run)",)),
    Case("static -o an existing file",
         lambda d: ["static", str(_log(d)), "-o", str(_user_file(d, "res")), *FAST],
         2, ("not a directory",)),
    Case("static -o a folder holding the user's noise.json",
         lambda d: ["static", str(_log(d)), "-o", str(_user_file(d, "o/noise.json").parent),
                    *FAST], 2, ("did not write: noise.json", "--overwrite")),
    Case("static -o under a file",
         lambda d: ["static", str(_log(d)), "-o", str(_user_file(d, "f") / "sub"), *FAST],
         2, ("cannot write to",)),
    Case("static -o an over-long path",
         lambda d: ["static", str(_log(d)), "-o", str(d / ("x" * 300)), *FAST],
         2, ("too long",)),
    Case("report over a report.html imubounds did not write",
         lambda d: _report_dir(d, user_report=True), 2, ("did not write", "--overwrite")),
    # issue 36: a result set lands only in a new or empty folder, or over the same command's
    # results of the same input; everything else is named and refused without --overwrite
    Case("simulate -o a folder holding the user's notes and a real log",
         lambda d: [*DRIVE_SIM, "-o", str(_notes_and_log(d / "mine"))], 2,
         ("did not write: log.csv, notes.md", "--overwrite")),
    Case("simulate -o a folder of static results",
         lambda d: [*DRIVE_SIM, "-o", str(_static_results(d))], 2,
         ("other results: imu.yaml, noise.json", "the results of 'imubounds static",
          "--overwrite")),
    Case("static -o a folder holding another log's results and the user's files",
         lambda d: ["static", str(_log(d, "other.csv")), "-o",
                    str(_user_file(_static_results(d), "notes.md").parent), *FAST], 2,
         ("did not write and other results", "notes.md", "--overwrite")),
    Case("static -o a folder holding another log's results",
         lambda d: ["static", str(_log(d, "other.csv")), "-o", str(_static_results(d)),
                    *FAST], 2, ("other results: imu.yaml, noise.json", "log.csv")),
    Case("static -o a folder holding its results, edited by the user",
         lambda d: ["static", str(d / "log.csv"), "-o", str(_edited(_static_results(d))),
                    *FAST], 2, ("changed since imubounds wrote them: noise.json",)),
    Case("dynamic -o a folder of static results",
         lambda d: ["dynamic", str(d), "-o", str(_static_results(d)), "-q"], 2,
         ("other results", "noise.json")),
    Case("export DIR -o DIR/noise.json (its own input)",
         lambda d: ["export", str(_static_results(d)), "--format", "kalibr", "-o",
                    str(d / "res" / "noise.json"), "--overwrite"], 2,
         ("noise.json is an input of this run",)),
    Case("export -o DIR/run.json",
         lambda d: ["export", str(_static_results(d)), "--format", "kalibr", "-o",
                    str(d / "res" / "run.json")], 2, ("run.json is imubounds' record",)),
]

DRIVE_SIM = ["simulate", "--duration", "150", "--distance", "1500", "-q"]


def _notes_and_log(d: Path) -> Path:
    _user_file(d, "notes.md")
    _log(d)
    return d


def _static_results(d: Path) -> Path:
    res = d / "res"
    assert main(["static", str(_log(d)), "-o", str(res), *FAST]) == 0
    return res


def _edited(res: Path) -> Path:
    doc = json.loads((res / "noise.json").read_text())
    doc["my_note"] = "checked by hand"
    (res / "noise.json").write_text(json.dumps(doc))
    return res


def _mkdir(p: Path) -> Path:
    p.mkdir(parents=True)
    return p


def _report_dir(d: Path, *, user_report: bool = False, noise: str | None = None) -> list[str]:
    run = d / "run"
    if noise is None:
        assert main(["static", str(_log(d)), "-o", str(run), *FAST]) == 0
    else:
        run.mkdir()
        (run / "noise.json").write_text(noise)
    if user_report:
        _user_file(run, "report.html", "<html>the user's notes</html>")
    return ["report", str(run), "-q"]


@_table(OUTPUT_CASES)
def test_outputs_never_cost_the_user_a_file(
    case: Case, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    _run_case(case, tmp_path, capsys)


def test_simulate_into_the_current_folder_is_refused_unless_overwrite(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)
    _user_file(tmp_path, "notes.md")
    case = Case("simulate -o .", lambda d: [*DRIVE_SIM, "-o", "."], 2,
                ("output directory . holds files imubounds did not write: notes.md",))
    _run_case(case, tmp_path, capsys)
    assert main([*DRIVE_SIM, "-o", ".", "--overwrite"]) == 0  # as asked: beside the notes
    assert (tmp_path / "notes.md").read_text() == "the user's own file\n"
    assert (tmp_path / "imu.csv").is_file()
    assert main([*DRIVE_SIM, "-o", ".", "--seed", "3", "--force"]) == 0  # the old name


def test_rerun_overwrites_only_what_imubounds_wrote(tmp_path: Path) -> None:
    out = tmp_path / "x.csv"
    assert main([*SIM, "-o", str(out), "--save-spec", str(tmp_path / "s.json")]) == 0
    first = out.read_bytes()
    # the same command again may replace its own files ...
    assert main([*SIM, "--seed", "1", "-o", str(out), "--save-spec", str(tmp_path / "s.json")]) == 0
    assert out.read_bytes() != first
    # ... but not once the user has changed one of them
    out.write_text(out.read_text() + "# my note\n")
    assert main([*SIM, "-o", str(out)]) == 2
    assert out.read_text().endswith("# my note\n")
    assert main([*SIM, "-o", str(out), "--force"]) == 0


def test_report_rewrites_its_own_page_and_force_replaces_the_users(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    argv = _report_dir(tmp_path)
    run = Path(argv[1])
    assert main(argv) == 0 and main(argv) == 0  # its own report.html, twice
    (run / "report.html").write_text("user")
    assert main(argv) == 2 and (run / "report.html").read_text() == "user"
    assert main([*argv, "--force"]) == 0 and "imubounds report" in (run / "report.html").read_text()


# ============================================================================ 2. inputs
BAD_LOGS: list[tuple[str, Callable[[Path], Path], tuple[str, ...]]] = [
    ("a named pipe", lambda d: _fifo(d), ("named pipe", "pipe.csv")),
    ("a device", lambda d: Path("/dev/null"), ("device",)),
    ("a directory", lambda d: _mkdir(d / "logs"), ("is a directory",)),
    ("a missing file", lambda d: d / "nope.csv", ("no such file", "nope.csv")),
    ("an empty file", lambda d: _user_file(d, "e.csv", ""), ("empty",)),
    ("a header only", lambda d: _log(d, rows=[]), ("no data rows",)),
    ("mixed separators", lambda d: _log(d, rows=[r.replace(",", ";") if i >= 1000 else r
                                                  for i, r in enumerate(_rows())]),
     ("line 1002", "separated by ';'")),
    ("a text time column", lambda d: _log(d, rows=_rows(t=lambda i: f"t{i}")),
     ("line 2", "'t0' is not a number")),
    ("a ragged row", lambda d: _log(d, rows=[r + (",7" if i == 2000 else "")
                                             for i, r in enumerate(_rows())]),
     ("line 2002", "4 field(s) but the header has 3")),
    ("a NaN sample", lambda d: _log(d, rows=_rows(gyro=lambda i, g: "nan" if i == 2500
                                                   else f"{g:.6f}")),
     ("line 2502", "nan", "not a gap", "gyro_x")),
    ("an infinite sample", lambda d: _log(d, rows=_rows(gyro=lambda i, g: "-inf" if i == 7
                                                         else f"{g:.6f}")),
     ("line 9", "-inf")),
    ("a gap", lambda d: _log(d, rows=[r for i, r in enumerate(_rows()) if not 1500 < i < 1510]),
     ("gap", "t=15.1 s", "--on-gap")),
    ("a duplicated row", lambda d: _log(d, rows=_dup(_rows(), 1500)),
     ("duplicated row", "line 1503")),
    ("one stamp, two samples", lambda d: _log(d, rows=_dup(_rows(), 1500, change=True)),
     ("repeats with different values", "line 1503")),
    ("rows out of order", lambda d: _log(d, rows=_swap(_rows(), 100)),
     ("goes backwards", "data row 102", "sort the rows")),
    ("a restart of the recording", lambda d: _log(d, rows=_rows(t=_restart)),
     ("time restarts", "line 2002", "2 recordings")),
    ("time_us holding seconds", lambda d: _log(d, header="time_us,gyro_x_rads,accel_z_mps2"),
     ("time_us", "impossible", "--time-unit s")),
]


def _accel_in_g() -> list[str]:
    rng = np.random.default_rng(2)
    a = rng.normal(0.0, 0.001, (N_ROWS, 3)) + [0.01, -0.02, 1.0]
    return [f"{i / RATE:.2f},{x:.5f},{y:.5f},{z:.5f}" for i, (x, y, z) in enumerate(a)]


def _restart(i: int) -> str:
    return f"{(i % 2000) / 100:.2f}"


def _deg_in_rads(i: int, g: float) -> str:
    return f"{90 * np.sin(i / 50):.4f}"


def _dup(rows: list[str], i: int, change: bool = False) -> list[str]:
    extra = rows[i].rsplit(",", 1)[0] + ",1.0" if change else rows[i]
    return [*rows[: i + 1], extra, *rows[i + 1:]]


def _swap(rows: list[str], i: int) -> list[str]:
    rows = list(rows)
    rows[i], rows[i + 1] = rows[i + 1], rows[i]
    return rows


def _static_on(mk: Callable[[Path], Path], ooc: bool) -> Callable[[Path], list[str]]:
    return lambda d: ["static", str(mk(d)), "-o", str(d / "o"), *FAST, *(OOC if ooc else [])]


INPUT_CASES = [
    Case(f"static on {what}{' (out of core)' if ooc else ''}", _static_on(mk, ooc), 2, needles)
    for what, mk, needles in BAD_LOGS
    for ooc in (False, True)
]
INPUT_CASES += [
    Case("static on a URL (only the fleet reads URLs)",
         lambda d: ["static", "https://example.com/units/u1.csv.gz", "-o", str(d / "o"), *FAST],
         2, ("https://example.com/units/u1.csv.gz: a URL", "imubounds fleet", "download it")),
    Case("dynamic on a URL",
         lambda d: ["dynamic", "s3://bucket/drive/", "-o", str(d / "o")], 2,
         ("s3://bucket/drive/: a URL", "download it")),
    Case("simulate-noise --from-noise a named pipe",
         lambda d: ["simulate-noise", "--from-noise", str(_fifo(d, "n.json")), "--duration",
                    "10", "-o", str(d / "x.csv")], 2, ("--from-noise", "named pipe")),
    Case("simulate-noise --spec a device",
         lambda d: ["simulate-noise", "--spec", "/dev/zero", "--duration", "10", "-o",
                    str(d / "x.csv")], 2, ("--spec", "device")),
    Case("simulate-noise --from-noise missing",
         lambda d: ["simulate-noise", "--from-noise", str(d / "n.json"), "--duration", "10",
                    "-o", str(d / "x.csv")], 2, ("cannot read", "no such file")),
    Case("report on a named pipe", lambda d: ["report", str(_fifo(d, "dir"))], 2,
         ("not a directory",)),
    Case("report on a noise.json that is not JSON", lambda d: _report_dir(d, noise="{not json"),
         2, ("noise.json", "not readable JSON")),
    Case("report on a noise.json that is a list", lambda d: _report_dir(d, noise="[1, 2]"),
         2, ("noise.json", "not a result file written by imubounds")),
    Case("report on a noise.json of another program",
         lambda d: _report_dir(d, noise='{"channels": {}}'), 2, ("not a result file",)),
    Case("report on a noise.json with a malformed channel",
         lambda d: _report_dir(
             d, noise='{"format": "imubounds.stationary.terms/1", "channels": {"gyro_x": 5}}'),
         2, ("noise.json", "unexpected content")),
    Case("report on binary noise.json", lambda d: _report_dir(d, noise="\x00\xff\x01garbage"),
         2, ("not readable JSON",)),
]


@_table(INPUT_CASES)
def test_bad_input_is_one_line_naming_file_and_row(
    case: Case, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    _run_case(case, tmp_path, capsys)
    assert not (tmp_path / "o" / "noise.json").exists()


GOOD_ODD_LOGS: list[tuple[str, Callable[[Path], Path]]] = [
    ("ISO 8601 time stamps", lambda d: _log(d, header="time,gyro_x_rads,accel_z_mps2",
                                            rows=_rows(t=_iso))),
    ("a units row", lambda d: _log(d, header="time,gyro_x,accel_z\ns,rad/s,m/s^2")),
    ("decimal commas with ;", lambda d: _log(
        d, header="time_s;gyro_x_rads;accel_z_mps2",
        rows=[r.replace(",", ";").replace(".", ",") for r in _rows()])),
    ("quoted fields", lambda d: _log(
        d, header='"time_s","gyro_x_rads","accel_z_mps2"',
        rows=['"' + r.replace(",", '","') + '"' for r in _rows()])),
    ("a comment line inside the data", lambda d: _log(
        d, rows=[*_rows()[:1000], "# logger paused and resumed", *_rows()[1000:]])),
]


@pytest.mark.parametrize("ooc", [False, True], ids=["in memory", "out of core"])
@pytest.mark.parametrize(("what", "make"), GOOD_ODD_LOGS, ids=[w for w, _ in GOOD_ODD_LOGS])
def test_odd_but_valid_logs_are_read_the_same_in_memory_and_out_of_core(
    what: str, make: Callable[[Path], Path], ooc: bool, tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    case = Case(what, lambda d: ["static", str(make(d)), "-o", str(d / "o"), *FAST,
                                 *(OOC if ooc else [])], 0, (), extra=_noise_rate(Path("o")))
    _run_case(case, tmp_path, capsys)


WARNING_CASES = [
    Case("deg/s values in a _rads column",
         lambda d: ["static", str(_log(d, rows=_rows(gyro=_deg_in_rads))),
                    "-o", str(d / "o"), *FAST], 0, ("look like deg/s", "gyro_x"), warning=True),
    Case("deg/s values in a _rads column (out of core)",
         lambda d: ["static", str(_log(d, rows=_rows(gyro=_deg_in_rads))),
                    "-o", str(d / "o"), *FAST, *OOC], 0, ("look like deg/s",), warning=True),
    Case("an accelerometer in g in a m/s^2 column",
         lambda d: ["static", str(_log(d, header="time_s,accel_x_mps2,accel_y_mps2,accel_z_mps2",
                                       rows=_accel_in_g())),
                    "-o", str(d / "o"), *FAST], 0, ("look like g", "--accel-unit g"),
         warning=True),
    Case("an isolated spike",
         lambda d: ["static", str(_log(d, rows=_rows(gyro=lambda i, g: "2.5" if i == 777
                                                       else f"{g:.6f}"))),
                    "-o", str(d / "o"), *FAST], 0, ("1 isolated one-sample spike", "line 779"),
         warning=True),
    Case("an isolated spike (out of core)",
         lambda d: ["static", str(_log(d, rows=_rows(gyro=lambda i, g: "2.5" if i == 777
                                                       else f"{g:.6f}"))),
                    "-o", str(d / "o"), *FAST, *OOC], 0, ("spike", "line 779"), warning=True),
    Case("duplicated rows with --on-gap ignore",
         lambda d: ["static", str(_log(d, rows=_dup(_dup(_rows(), 2000), 1000))), "-o",
                    str(d / "o"), *FAST, "--on-gap", "ignore"], 0,
         ("2 duplicated row(s)", "dropped", "line 1003"), warning=True,
         extra=_noise_rate(Path("o"))),
    Case("a truncated ULog",
         lambda d: ["static", str(_cut_ulog(d)), "-o", str(d / "o"), *FAST], 0,
         ("truncated",), warning=True),
    *(Case(f"a units row under the header{' (out of core)' if ooc else ''}",
           lambda d, ooc=ooc: ["static", str(_log(d, header="time,gyro_x,accel_z", rows=[
               "s,rad/s,m/s^2", *_rows()])), "-o", str(d / "o"), *FAST, *(OOC if ooc else [])],
           0, ("log.csv", "line 2 under the header is a row of units (s, rad/s, m/s^2)",
               "not as data"), warning=True, extra=_noise_rate(Path("o")))
      for ooc in (False, True)),
]


def _cut_ulog(d: Path) -> Path:
    src = (FORMATS / "adis_px4.ulg").read_bytes()
    p = d / "cut.ulg"
    p.write_bytes(src[: len(src) - 5])
    return p


@_table(WARNING_CASES)
def test_implausible_values_give_a_counted_warning(
    case: Case, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    _run_case(case, tmp_path, capsys)


def test_restart_split_analyses_each_recording(tmp_path: Path) -> None:
    from imubounds.io import read_imu_segments

    log = _log(tmp_path, rows=_rows(t=_restart))
    segs = read_imu_segments(log, on_gap="split")
    assert [s.n_samples for s in segs] == [2000, 1000], [s.n_samples for s in segs]
    assert any("restarts 1 time(s)" in w for w in segs[0].warnings)


# ============================================================================ 3. options
def _opts(*argv: str) -> Callable[[Path], list[str]]:
    def make(d: Path) -> list[str]:
        cmd, *rest = argv
        if cmd == "static":
            return ["static", str(_log(d)), "-o", str(d / "o"), *FAST, *rest]
        return [cmd, "-o", str(d / "x.csv"), *rest]

    return make


OPTION_CASES = [
    Case(" ".join(args), _opts(*args), 2, (f"argument {args[1]}", needle))
    for args, needle in [
        (("static", "--k-sigma", "-3"), "> 0"),
        (("static", "--k-sigma", "nan"), "not a finite number"),
        (("static", "--confidence", "1.5"), "between 0 and 1"),
        (("static", "--avg-time", "0"), "> 0"),
        (("static", "--run-hours", "-1"), "> 0"),
        (("static", "--rate", "0"), "> 0"),
        (("static", "--rate", "abc"), "not a number"),
        (("static", "--gap-tolerance", "0.5"), "> 1"),
        (("static", "--time-unit", "fortnight"), "unknown time unit"),
        (("static", "--gyro-unit", "furlong/s"), "unknown gyro unit"),
        (("static", "--accel-unit", "dps"), "unknown accel unit"),
        (("static", "--max-memory", "10"), "too small"),
        (("static", "--max-memory", "lots"), "not a size"),
        (("static", "--tmpdir", "/nonexistent/tmp"), "does not exist"),
        (("static", "--tau", "0.1,-1"), "positive"),
        (("static", "--tau", "1,inf"), "finite"),
        (("static", "--tau", "1"), "ambiguous"),
        (("simulate-noise", "--seed", "-1", "--preset", "xsens-mtx"), ">= 0"),
        (("simulate-noise", "--samples", "1", "--preset", "xsens-mtx"), "at least 2"),
        (("simulate-noise", "--duration", "0", "--preset", "xsens-mtx"), "positive"),
        (("simulate-noise", "--duration", "1e999", "--preset", "xsens-mtx"), "finite"),
        (("simulate-noise", "--t0", "nan", "--preset", "xsens-mtx"), "finite"),
        (("simulate-noise", "--rate", "-5", "--preset", "xsens-mtx"), "> 0"),
        (("simulate-noise", "--bias-tau-range", "10,1", "--preset", "xsens-mtx"), "LO < HI"),
        (("simulate-noise", "--bias-tau-range", "1,inf", "--preset", "xsens-mtx"), "finite"),
    ]
]


@_table(OPTION_CASES)
def test_numeric_options_are_range_checked_when_parsed(
    case: Case, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    _run_case(case, tmp_path, capsys)
    assert not (tmp_path / "o").exists() and not (tmp_path / "x.csv").exists()


# ============================================================================ 4. errors
def _raise(exc: BaseException) -> Callable[..., object]:
    def f(*a: object, **k: object) -> object:
        raise exc

    return f


ERROR_CASES: list[tuple[str, str, BaseException, int, tuple[str, ...]]] = [
    ("permission denied", "imubounds.stationary.pipeline.analyse_static",
     PermissionError(errno.EACCES, "Permission denied", "/data/imu.csv"), 2,
     ("permission denied: /data/imu.csv", "check the permissions")),
    ("disk full", "imubounds.stationary.pipeline.analyse_static",
     OSError(errno.ENOSPC, "No space left on device", "/tmp/x"), 2, ("the disk is full",)),
    ("read-only file system", "tempfile.mkdtemp",
     OSError(errno.EROFS, "Read-only file system", "/mnt/ro"), 2,
     ("cannot write to", "read-only file system")),
    ("out of memory", "imubounds.stationary.pipeline.analyse_static", MemoryError(), 2,
     ("out of memory", "--max-memory")),
    ("a bug", "imubounds.stationary.pipeline.analyse_static", ZeroDivisionError("oops"), 70,
     ("internal error", "ZeroDivisionError", "--debug")),
]


@pytest.mark.parametrize(("what", "target", "exc", "code", "needles"), ERROR_CASES,
                         ids=[c[0] for c in ERROR_CASES])
def test_os_and_memory_errors_are_one_line(
    what: str, target: str, exc: BaseException, code: int, needles: tuple[str, ...],
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch,
) -> None:
    log = _log(tmp_path)
    monkeypatch.setattr(target, _raise(exc))
    case = Case(what, lambda d: ["static", str(log), "-o", str(d / "o"), *FAST], code, needles)
    _run_case(case, tmp_path, capsys)
    assert not (tmp_path / "o").exists()


def test_unreadable_log_is_named(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    log = _log(tmp_path)
    real = os.access
    monkeypatch.setattr(os, "access", lambda p, mode: False if Path(p) == log else real(p, mode))
    case = Case("unreadable", lambda d: ["static", str(log), "-o", str(d / "o"), *FAST], 2,
                ("log.csv", "permission denied"))
    _run_case(case, tmp_path, capsys)


def test_debug_shows_the_traceback(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["static", str(tmp_path / "nope.csv"), "-o", str(tmp_path / "o")]) == 2
    assert "Traceback" not in capsys.readouterr().err
    for argv in (["--debug", "static", str(tmp_path / "nope.csv")],
                 ["static", str(tmp_path / "nope.csv"), "--debug"]):
        assert main([*argv, "-o", str(tmp_path / "o")]) == 2
        err = capsys.readouterr().err
        assert "Traceback" in err and err.rstrip().endswith("check the path")


# ====================================================================== 5. interruptions
def test_ctrl_c_during_the_analysis_says_nothing_was_written(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    log = _log(tmp_path)
    out = tmp_path / "o"
    assert main(["static", str(log), "-o", str(out), *FAST]) == 0
    before = _snapshot(tmp_path)
    monkeypatch.setattr("imubounds.stationary.pipeline.analyse_static",
                        _raise(KeyboardInterrupt()))
    assert main(["static", str(log), "-o", str(out), *FAST]) == 130
    err = "\n".join(
        ln for ln in capsys.readouterr().err.splitlines() if "imubounds: warning:" not in ln
    ).strip()
    assert err == "imubounds: interrupted (Ctrl-C); nothing was written (outputs are as they were)"
    assert _snapshot(tmp_path) == before
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]


def test_ctrl_c_after_one_file_names_what_was_written(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr("imubounds.stationary.noise_sim.NoiseSpec.to_dict",
                        _raise(KeyboardInterrupt()))
    csv, spec = tmp_path / "x.csv", tmp_path / "s.json"
    assert main([*SIM, "-o", str(csv), "--save-spec", str(spec)]) == 130
    err = capsys.readouterr().err.strip()
    assert f"complete results had been written to {csv}; nothing else was written" in err
    assert csv.is_file() and not spec.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == [".imubounds-files.json", "x.csv"]


def _interrupt_when(monkeypatch: pytest.MonkeyPatch, when: Callable[[str, str], bool]) -> None:
    """KeyboardInterrupt at the first ``os.replace(src, dst)`` for which ``when`` holds (a
    Ctrl-C at that instant that nothing held back)."""
    real = os.replace
    fired = []

    def replace(src: object, dst: object) -> None:
        if not fired and when(os.fspath(src), os.fspath(dst)):  # type: ignore[arg-type]
            fired.append(1)
            raise KeyboardInterrupt
        real(src, dst)  # type: ignore[arg-type]

    monkeypatch.setattr(os, "replace", replace)


@pytest.mark.parametrize("moment", ["as the old noise.json is set aside",
                                    "as the new noise.json moves in",
                                    "as run.json is written"])
def test_ctrl_c_at_the_commit_of_static_leaves_the_old_set_or_the_new_and_no_lock(
    moment: str, tmp_path: Path, capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Issue 36: Ctrl-C just as noise.json is replaced left a mix of old and new figures,
    just as it appeared a .imubounds.lock. Now: the old set or the new one, whole, the
    message says which, no lock, nothing hidden left."""
    out = tmp_path / "o"
    old_log, new_log = _log(tmp_path, "a.csv"), _log(tmp_path, "b.csv", rows=_rows(2000))
    assert main(["static", str(old_log), "-o", str(out), "-q", "--models", "none"]) == 0
    capsys.readouterr()
    before = _snapshot(out)
    when = {
        "as the old noise.json is set aside": lambda s, d: s.endswith("/o/noise.json"),
        "as the new noise.json moves in": lambda s, d: d.endswith("/o/noise.json"),
        "as run.json is written": lambda s, d: d.endswith("/o/run.json") and ".part" in s,
    }[moment]
    _interrupt_when(monkeypatch, when)
    code = main(["static", str(new_log), "-o", str(out), "-q", "--models", "none",
                 "--overwrite"])
    err = capsys.readouterr().err
    assert code == 130, err
    assert "nothing was written (outputs are as they were)" in err
    assert _snapshot(out) == before, "not the old set"
    assert not (out / ".imubounds.lock").exists()
    assert not [p for p in tmp_path.rglob(".*") if "imubounds" in p.name]
    monkeypatch.undo()
    assert main(["static", str(new_log), "-o", str(out), *FAST, "--overwrite"]) == 0
    rec = json.loads((out / "run.json").read_text())
    assert "b.csv" in rec["command"] and set(rec["files"]) <= {p.name for p in out.iterdir()}


def test_ctrl_c_just_after_the_commit_says_what_was_written_and_leaves_no_lock(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch,
) -> None:
    import shutil

    out = tmp_path / "o"
    real = shutil.rmtree

    def rmtree(p: object, *a: object, **k: object) -> None:
        if ".imubounds-" in str(p):  # the clean-up right after noise.json appeared
            monkeypatch.setattr(shutil, "rmtree", real)
            real(p, *a, **k)  # type: ignore[arg-type]
            raise KeyboardInterrupt
        real(p, *a, **k)  # type: ignore[arg-type]

    monkeypatch.setattr(shutil, "rmtree", rmtree)
    assert main(["static", str(_log(tmp_path)), "-o", str(out), *FAST]) == 130
    assert f"complete results had been written to {out}" in capsys.readouterr().err
    assert (out / "noise.json").is_file() and not (out / ".imubounds.lock").exists()
    assert not [p for p in tmp_path.rglob(".*") if "imubounds" in p.name]
