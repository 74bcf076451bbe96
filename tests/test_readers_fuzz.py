"""Property-based fuzzing of the CSV and NMEA readers (issue 16).

Whatever the bytes, reading gives either a valid log (finite SI samples,
strictly increasing time) or a one-line :class:`ImuboundsError`: never another
exception, never a hang (a per-example timer), never a change to a file that
was there before (the input itself and a bystander file are checked).
The CSV examples go through the in-memory reader and the out-of-core reader.
"""

from __future__ import annotations

import gzip
import signal
import tempfile
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from imubounds.errors import ImuboundsError
from imubounds.io import read_imu
from imubounds.io.chunked import open_chunked

#: Seconds one example may take before it counts as a hang.
EXAMPLE_TIMEOUT_S = 20


@contextmanager
def _deadline(seconds: float) -> Iterator[None]:
    def hang(signum: int, frame: object) -> None:
        raise TimeoutError(f"reading took more than {seconds} s (a hang?)")

    old = signal.signal(signal.SIGALRM, hang)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)


def _files(d: Path) -> dict[str, tuple[bytes, int]]:
    return {p.name: (p.read_bytes(), p.stat().st_mtime_ns) for p in d.iterdir() if p.is_file()}


def _check_log(log: object) -> None:
    t = log.t  # type: ignore[attr-defined]
    assert t.size >= 1 and np.all(np.isfinite(t))
    assert np.all(np.diff(t) > 0), "time must increase strictly"
    for v in log.channels.values():  # type: ignore[attr-defined]
        assert v.shape == t.shape and v.dtype == np.float64 and np.all(np.isfinite(v))
    assert np.isfinite(log.rate_hz) and log.rate_hz > 0  # type: ignore[attr-defined]


def _read_everything(path: Path, on_gap: str) -> None:
    """Both readers; each must succeed with a valid result or raise a one-line user error."""
    try:
        _check_log(read_imu(path, on_gap=on_gap))  # type: ignore[arg-type]
    except ImuboundsError as err:
        assert str(err) and "\n" not in str(err), repr(err)
    try:
        log = open_chunked(path, on_gap="ignore" if on_gap == "split" else on_gap)
        assert np.isfinite(log.rate_hz) and log.rate_hz > 0
        for block in log.iter_chunks(7):
            for v in block.values():
                assert v.dtype == np.float64 and np.all(np.isfinite(v))
    except ImuboundsError as err:
        assert str(err) and "\n" not in str(err), repr(err)


def _fuzz_file(suffix: str, data: bytes, reader: Callable[[Path], None]) -> None:
    with tempfile.TemporaryDirectory() as d:
        root = Path(d)
        (root / "bystander.json").write_text('{"keep": true}\n')
        p = root / f"log{suffix}"
        p.write_bytes(data)
        before = _files(root)
        with _deadline(EXAMPLE_TIMEOUT_S):
            reader(p)
        assert _files(root) == before, "a file that was there before was changed"


# ----------------------------------------------------------------------------- CSV
HEADERS = [
    ["time_s", "gyro_x_dps", "gyro_y_dps", "accel_z_g"],
    ["t", "gyro_x", "accel_x", "accel_y", "accel_z"],
    ["timestamp", "omega_x", "alpha_z"],
    ["#timestamp [ns]", "w_RS_S_x [rad s^-1]", "a_RS_S_x [m s^-2]"],
    ["time_us", "gyro_z_rads"],
    ["time", "gyro_x [deg/s]", "time"],
    ["gyro_x_dps", "gyro_x"],
    ["ts", "gyro_x_bias", "acc_x_mg"],
    ["", "gyro_x_dps"],
    ["time_s"],
]
CELLS = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True, width=32).map(repr),
    st.integers(min_value=-(2**70), max_value=2**70).map(str),
    st.decimals(min_value=-1000, max_value=1000, places=3).map(str),
    st.decimals(min_value=0, max_value=100, places=2).map(lambda x: str(x).replace(".", ",")),
    st.sampled_from(["", " ", "nan", "NaN", "inf", "-inf", "1e999", "abc", '"1.5"', "0x10",
                     "2024-05-01T12:00:00.010", "2024-05-01T12:00:00Z", "s", "deg/s", "#",
                     "1,5", "--", "1e-320", "\u00b0", "\x00"]),
)
LINE_ENDS = st.sampled_from(["\n", "\r\n", "\r"])


TIME_PATTERNS = ["regular", "regular", "gap", "duplicate", "swap", "restart", "jitter"]


def _times(pattern: str, n: int, rate: float, k: int) -> list[float]:
    t = [i / rate for i in range(n)]
    k = min(max(k, 1), max(n - 1, 1))
    if n < 3:
        return t
    if pattern == "gap":
        t = [x + (10.0 / rate if i >= k else 0.0) for i, x in enumerate(t)]
    elif pattern == "duplicate":
        t.insert(k, t[k - 1])
        t.pop()
    elif pattern == "swap":
        t[k - 1], t[k] = t[k], t[k - 1]
    elif pattern == "restart":
        t = [(i % k) / rate for i in range(n)]
    elif pattern == "jitter":
        t = [x + 0.2 * ((i * 7919) % 11 - 5) / 5 / rate for i, x in enumerate(t)]
    return t


@st.composite
def csv_texts(draw: st.DrawFn) -> str:
    """Mostly well-formed logs with a few damaged rows, some thoroughly broken ones."""
    sep = draw(st.sampled_from([",", ",", ";", "\t", " ", "|"]))
    header = draw(st.sampled_from(HEADERS[:5] * 4 + HEADERS[5:]))
    n = len(header)
    end = draw(LINE_ENDS)
    lines = [sep.join(header)]
    if draw(st.integers(0, 5)) == 0:
        lines.insert(0, "# " + draw(st.text(max_size=20)).replace("\n", " "))
    if draw(st.integers(0, 6)) == 0:
        lines.append(sep.join(draw(st.sampled_from(["s", "deg/s", "g", "", "m/s^2"]))
                              for _ in range(n)))
    rate = draw(st.sampled_from([100.0, 100.0, 0.01, 1e6, 7.0]))
    nrows = draw(st.integers(0, 60))
    times = _times(draw(st.sampled_from(TIME_PATTERNS)), nrows, rate, draw(st.integers(1, 50)))
    chaos = draw(st.integers(0, 5)) == 0
    damaged: set[int] = set()
    if draw(st.integers(0, 2)) == 0:
        damaged = set(draw(st.lists(st.integers(0, max(nrows - 1, 0)), max_size=3)))
    for i in range(nrows):
        if chaos or i in damaged:
            width = draw(st.sampled_from([n, n, n, n - 1, n + 1, 1]))
            cells = [draw(CELLS) for _ in range(max(width, 0))]
        else:
            cells = [f"{times[i]:.9g}"] + [
                f"{0.01 * ((i * 7 + 3 * k) % 5) - 0.02:.4f}" for k in range(n - 1)
            ]
        line = sep.join(cells)
        if i in damaged and draw(st.booleans()):
            line = draw(st.sampled_from(["", "# comment", "   ", line + sep, line[:-1]]))
        lines.append(line)
    return end.join(lines) + draw(st.sampled_from([end, ""]))


@given(text=csv_texts(), suffix=st.sampled_from([".csv", ".csv.gz", ".txt", ".tsv"]),
       on_gap=st.sampled_from(["refuse", "split", "ignore"]), cut=st.integers(0, 30))
@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
def test_csv_reader_never_crashes_hangs_or_writes(
    text: str, suffix: str, on_gap: str, cut: int
) -> None:
    data = text.encode("utf-8", "surrogatepass")
    if suffix.endswith(".gz"):
        data = gzip.compress(data)
        if cut:  # a truncated download
            data = data[: max(1, len(data) - cut)]
    _fuzz_file(suffix, data, lambda p: _read_everything(p, on_gap))


UNIT_TOKENS = st.sampled_from(["s", "ms", "rad/s", "deg/s", "[deg/s]", "(g)", "m/s^2", "mg",
                                "", "-", "units", "furlong"])


@given(units=st.lists(UNIT_TOKENS, min_size=3, max_size=3), nrows=st.integers(20, 60),
       sep=st.sampled_from([",", ";", "\t"]), ooc=st.booleans())
@settings(max_examples=40, deadline=None)
def test_a_units_row_is_named_and_never_read_as_data(
    units: list[str], nrows: int, sep: str, ooc: bool
) -> None:
    """Issue 36: a row of units under the header was read silently. Whatever its
    tokens: the read fails with one line, or the log has exactly the data rows and, when
    the row was taken as units, a warning names its line."""
    lines = [sep.join(["time", "gyro_x", "accel_z"]), sep.join(units)]
    lines += [sep.join([f"{i / 100:.2f}", f"{0.01 * (i % 7):.3f}", f"{9.8 + 0.01 * (i % 3):.3f}"])
              for i in range(nrows)]
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "log.csv"
        p.write_text("\n".join(lines) + "\n")
        try:
            log = open_chunked(p) if ooc else read_imu(p)
        except ImuboundsError as err:
            assert "\n" not in str(err)
            return
        warnings = list(log.warnings)
        if ooc:
            n = sum(next(iter(b.values())).size for b in log.iter_chunks(7))
        else:
            n = log.t.size
        assert n == nrows, "the units row was read as data (or a row was lost)"
        assert any("line 2 under the header is a row of units" in w for w in warnings), warnings


@given(data=st.binary(max_size=300), suffix=st.sampled_from([".csv", ".dat", ".log"]))
@settings(max_examples=60, deadline=None)
def test_arbitrary_bytes_never_crash_the_readers(data: bytes, suffix: str) -> None:
    _fuzz_file(suffix, data, lambda p: _read_everything(p, "refuse"))


# ----------------------------------------------------------------------------- NMEA
def _checksum(body: str) -> str:
    c = 0
    for ch in body:
        c ^= ord(ch)
    return f"{c:02X}"


NMEA_FIELDS = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True, width=32).map(lambda x: f"{x:+.3f}"),
    st.sampled_from(["", "nan", "inf", "abc", "+000.000", "-9.800", "1e999", "*", "$", ","]),
)


@st.composite
def nmea_texts(draw: st.DrawFn) -> str:
    lines = []
    t = draw(st.sampled_from([1763590170.0, 0.0, -5.0]))
    step = draw(st.sampled_from([0.025, 0.0, -0.025, 1000.0]))
    for i in range(draw(st.integers(0, 30))):
        kind = draw(st.sampled_from(["VNYMR", "VNYMR", "VNYMR", "GPGGA", "GPRMC", "HEHDT",
                                     "junk"]))
        if kind == "junk":
            lines.append(draw(st.text(max_size=30)))
            continue
        nfields = 12 if kind == "VNYMR" else draw(st.integers(0, 14))
        if draw(st.integers(0, 8)) == 0:
            nfields += draw(st.sampled_from([-3, -1, 1]))
        if draw(st.integers(0, 3)):
            fields = [f"{0.01 * ((i + k) % 7):+.4f}" for k in range(max(nfields, 0))]
        else:
            fields = [draw(NMEA_FIELDS) for _ in range(max(nfields, 0))]
        body = ",".join([kind, *fields])
        star = draw(st.sampled_from(["good", "good", "bad", "none"]))
        sentence = "$" + body + {"good": "*" + _checksum(body), "bad": "*00", "none": ""}[star]
        prefix = draw(st.sampled_from(["host", "host", "none", "space"]))
        stamp = f"{t + i * step:.3f}"
        lines.append({"host": f"{stamp},{sentence}", "space": f"{stamp} {sentence}",
                      "none": sentence}[prefix])
    return "\n".join(lines) + "\n"


@given(text=nmea_texts(), on_bad=st.sampled_from(["error", "skip"]),
       on_gap=st.sampled_from(["refuse", "split", "ignore"]),
       rate=st.sampled_from([None, 40.0]))
@settings(max_examples=150, deadline=None)
def test_nmea_reader_never_crashes_hangs_or_writes(
    text: str, on_bad: str, on_gap: str, rate: float | None
) -> None:
    def read(p: Path) -> None:
        try:
            _check_log(read_imu(p, on_gap=on_gap, rate_hz=rate,  # type: ignore[arg-type]
                                format_options={"on_bad_checksum": on_bad}))
        except ImuboundsError as err:
            assert str(err) and "\n" not in str(err), repr(err)

    _fuzz_file(".nmea", text.encode("utf-8", "surrogatepass"), read)


# ------------------------------------------------- in memory and out of core agree
@st.composite
def clean_logs(draw: st.DrawFn) -> tuple[str, int]:
    """Well-formed logs whose only faults are in the time stamps or a non-finite value."""
    sep = draw(st.sampled_from([",", ";", "\t"]))
    n = draw(st.integers(3, 400))
    times = _times(draw(st.sampled_from(TIME_PATTERNS)), n, 100.0, draw(st.integers(1, n - 1)))
    values = draw(st.lists(st.floats(-10, 10, allow_nan=False, width=32), min_size=n,
                           max_size=n))
    if draw(st.integers(0, 5)) == 0:
        values[draw(st.integers(0, n - 1))] = draw(st.sampled_from([np.nan, np.inf]))
    rows = [f"{t:.9g}{sep}{v!r}{sep}{9.8 + 0.001 * (i % 3):.4f}"
            for i, (t, v) in enumerate(zip(times, values, strict=True))]
    return sep.join(["time_s", "gyro_x_rads", "accel_z_mps2"]) + "\n" + "\n".join(rows) + "\n", n


@given(log=clean_logs(), on_gap=st.sampled_from(["refuse", "ignore"]))
@settings(max_examples=80, deadline=None)
def test_in_memory_and_out_of_core_readers_agree(log: tuple[str, int], on_gap: str) -> None:
    """The same checks, the same samples: the out-of-core reader is not a laxer path."""
    text, _ = log
    with tempfile.TemporaryDirectory() as d, _deadline(EXAMPLE_TIMEOUT_S):
        p = Path(d) / "log.csv"
        p.write_text(text)
        try:
            mem = read_imu(p, on_gap=on_gap)  # type: ignore[arg-type]
        except ImuboundsError as err:
            mem_err: ImuboundsError | None = err
        else:
            mem_err = None
        try:
            chunked = open_chunked(p, on_gap=on_gap)
            blocks = list(chunked.iter_chunks(16))
        except ImuboundsError as err:
            assert mem_err is not None, f"only the out-of-core reader refused: {err}"
            assert type(err) is type(mem_err), (err, mem_err)
            return
        assert mem_err is None, f"only the in-memory reader refused: {mem_err}"
        for c in mem.channels:
            got = np.concatenate([b[c] for b in blocks])
            np.testing.assert_array_equal(got, mem.channels[c])
        assert chunked.rate_hz == mem.rate_hz
