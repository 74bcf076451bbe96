"""Bad input gives a one-line InputError/OptionError naming file, row/line, column."""

from __future__ import annotations

import gzip
import shutil
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from imubounds.errors import ImuboundsError, InputError, OptionError
from imubounds.io import read_imu, read_imu_segments

HEADER = "time_s,gyro_x_dps,gyro_y_dps,gyro_z_dps,accel_x_g,accel_y_g,accel_z_g\n"
DATA = Path(__file__).parent / "data"


def _rows(n: int, rate: float = 100.0, start: int = 0) -> list[str]:
    return [
        f"{(start + k) / rate:.2f},0.05,-0.1,0.2,0.001,-0.002,-1.0\n" for k in range(n)
    ]


def _write(tmp_path: Path, text: str, name: str = "log.csv") -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


def _one_line(err: pytest.ExceptionInfo[ImuboundsError]) -> str:
    msg = str(err.value)
    assert "\n" not in msg
    assert msg
    return msg


def test_missing_file(tmp_path: Path) -> None:
    with pytest.raises(InputError) as err:
        read_imu(tmp_path / "nope.csv")
    assert "no such file" in _one_line(err) and "nope.csv" in str(err.value)


def test_directory(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="directory"):
        read_imu(tmp_path)


@pytest.mark.parametrize("text", ["", "\n\n  \n", "# just a comment\n"])
def test_empty_file(tmp_path: Path, text: str) -> None:
    with pytest.raises(InputError) as err:
        read_imu(_write(tmp_path, text))
    msg = _one_line(err)
    assert "log.csv" in msg
    assert "empty" in msg or "comment" in msg


def test_empty_gzip(tmp_path: Path) -> None:
    p = tmp_path / "log.csv.gz"
    with gzip.open(p, "wb"):
        pass
    with pytest.raises(InputError, match="empty"):
        read_imu(p)


def test_header_only(tmp_path: Path) -> None:
    with pytest.raises(InputError) as err:
        read_imu(_write(tmp_path, HEADER))
    assert "no data rows" in _one_line(err)


def test_single_row_needs_rate(tmp_path: Path) -> None:
    p = _write(tmp_path, HEADER + _rows(1)[0])
    with pytest.raises(InputError, match="only 1 data row"):
        read_imu(p)
    assert read_imu(p, rate_hz=100.0).n_samples == 1


def test_data_without_header(tmp_path: Path) -> None:
    with pytest.raises(InputError) as err:
        read_imu(_write(tmp_path, "".join(_rows(5))))
    assert "no header" in _one_line(err) and "line 1" in str(err.value)


def test_no_imu_channel(tmp_path: Path) -> None:
    p = _write(tmp_path, "time,foo,bar\n0,1,2\n0.01,1,2\n")
    with pytest.raises(InputError) as err:
        read_imu(p)
    msg = _one_line(err)
    assert "no IMU channel" in msg and "'foo'" in msg and "--columns" in msg


def test_one_letter_names_need_columns(tmp_path: Path) -> None:
    p = _write(tmp_path, "t,gx,gy,gz\n0,1,2,3\n0.01,1,2,3\n")
    with pytest.raises(InputError, match="--columns"):
        read_imu(p)
    log = read_imu(p, columns={"gyro_x": "gx", "gyro_y": "gy", "gyro_z": "gz"})
    assert log.channel_names() == ["gyro_x", "gyro_y", "gyro_z"]


def test_mapped_column_missing(tmp_path: Path) -> None:
    p = _write(tmp_path, HEADER + "".join(_rows(3)))
    with pytest.raises(OptionError) as err:
        read_imu(p, columns={"gyro_x": "wx"})
    msg = _one_line(err)
    assert "'wx'" in msg and "gyro_x" in msg and "time_s" in msg


def test_requested_channel_missing(tmp_path: Path) -> None:
    p = _write(tmp_path, "time_s,gyro_x_dps\n0,1\n0.01,1\n")
    with pytest.raises(InputError, match="accel_z not found"):
        read_imu(p, channels=["gyro_x", "accel_z"])


def test_ambiguous_channel(tmp_path: Path) -> None:
    p = _write(tmp_path, "t,gyro_x_dps,gyro_x_rads\n0,1,2\n0.01,1,2\n")
    with pytest.raises(InputError) as err:
        read_imu(p)
    assert "--columns gyro_x=NAME" in _one_line(err)
    log = read_imu(p, columns={"gyro_x": "gyro_x_rads"})
    assert log.channels["gyro_x"][0] == 2.0


def test_non_numeric_cell(tmp_path: Path) -> None:
    rows = _rows(50)
    rows[36] = rows[36].replace("-0.1", "abc")
    p = _write(tmp_path, "# comment\n" + HEADER + "".join(rows))
    with pytest.raises(InputError) as err:
        read_imu(p)
    msg = _one_line(err)
    # line 1 comment, line 2 header, data row k (0-based) on line k + 3
    assert "line 39" in msg and "'gyro_y_dps'" in msg and "'abc'" in msg


def test_non_numeric_time(tmp_path: Path) -> None:
    rows = _rows(20)
    rows[4] = "12:00:00" + rows[4][rows[4].index(","):]
    p = _write(tmp_path, HEADER + "".join(rows))
    with pytest.raises(InputError) as err:
        read_imu(p)
    assert "line 6" in _one_line(err) and "'time_s'" in str(err.value)


def test_empty_cell(tmp_path: Path) -> None:
    rows = _rows(20)
    rows[9] = rows[9].replace(",0.2,", ",,")
    p = _write(tmp_path, HEADER + "".join(rows))
    with pytest.raises(InputError) as err:
        read_imu(p)
    assert "line 11" in _one_line(err) and "'gyro_z_dps'" in str(err.value)
    assert "empty" in str(err.value)


def test_short_row(tmp_path: Path) -> None:
    rows = _rows(20)
    rows[-1] = "0.19,0.05,-0.1\n"  # a file cut in the middle of a row
    p = _write(tmp_path, HEADER + "".join(rows))
    with pytest.raises(InputError) as err:
        read_imu(p)
    assert "line 21" in _one_line(err) and "3 field(s)" in str(err.value)


@pytest.mark.parametrize("bad", ["nan", "NaN", "inf", "-inf"])
def test_non_finite(tmp_path: Path, bad: str) -> None:
    rows = _rows(30)
    rows[12] = rows[12].replace("-1.0", bad)
    p = _write(tmp_path, HEADER + "".join(rows))
    with pytest.raises(InputError) as err:
        read_imu(p)
    msg = _one_line(err)
    assert "line 14" in msg and "data row 13" in msg and "'accel_z_g'" in msg
    assert "finite" in msg


def test_truncated_gzip(tmp_path: Path) -> None:
    full = gzip.compress((HEADER + "".join(_rows(20000))).encode())
    p = tmp_path / "log.csv.gz"
    p.write_bytes(full[: len(full) // 2])
    with pytest.raises(InputError) as err:
        read_imu(p)
    assert "truncated or corrupt" in _one_line(err) and "log.csv.gz" in str(err.value)


def test_truncated_small_gzip(tmp_path: Path) -> None:
    full = gzip.compress((HEADER + "".join(_rows(50))).encode())
    p = tmp_path / "log.csv.gz"
    p.write_bytes(full[:-12])
    with pytest.raises(InputError, match="truncated or corrupt"):
        read_imu(p)


def test_corrupt_parquet(tmp_path: Path) -> None:
    good = (DATA / "adis.parquet").read_bytes()
    p = tmp_path / "bad.parquet"
    p.write_bytes(good[:-100])
    with pytest.raises(InputError) as err:
        read_imu(p)
    assert "Parquet" in _one_line(err) and "bad.parquet" in str(err.value)
    q = tmp_path / "text.parquet"
    q.write_text(HEADER)
    with pytest.raises(InputError, match="Parquet"):
        read_imu(q)
    r = tmp_path / "mid.parquet"
    r.write_bytes(good[:4] + bytes(200) + good[204:])
    with pytest.raises(InputError, match="Parquet"):
        read_imu(r)


def test_parquet_nulls_and_text(tmp_path: Path) -> None:
    import pyarrow as pa
    import pyarrow.parquet as pq

    t = pa.table({"time_s": [0.0, 0.01, 0.02], "gyro_x_dps": [1.0, None, 2.0]})
    pq.write_table(t, tmp_path / "n.parquet")
    with pytest.raises(InputError, match="data row 2, column 'gyro_x_dps'"):
        read_imu(tmp_path / "n.parquet")
    t = pa.table({"time_s": [0.0, 0.01], "gyro_x_dps": ["a", "b"]})
    pq.write_table(t, tmp_path / "s.parquet")
    with pytest.raises(InputError, match="not numeric"):
        read_imu(tmp_path / "s.parquet")


@pytest.mark.parametrize(("swap", "word"), [(True, "goes backwards"), (False, "repeats")])
def test_non_monotonic_time(tmp_path: Path, swap: bool, word: str) -> None:
    rows = _rows(40)
    if swap:
        rows[20], rows[21] = rows[21], rows[20]
    else:
        rows[21] = rows[20]
    p = _write(tmp_path, HEADER + "".join(rows))
    with pytest.raises(InputError) as err:
        read_imu(p)
    msg = _one_line(err)
    assert word in msg and "'time_s'" in msg
    # 0-based data row 21 is on line 23 (header on line 1) in both cases
    assert "line 23 (data row 22)" in msg


def _gappy(tmp_path: Path) -> Path:
    rows = _rows(300) + _rows(100, start=350) + _rows(500, start=460)
    return _write(tmp_path, HEADER + "".join(rows))


def test_gap_refused(tmp_path: Path) -> None:
    with pytest.raises(InputError) as err:
        read_imu(_gappy(tmp_path))
    msg = _one_line(err)
    assert "2 gap(s)" in msg and "--on-gap" in msg
    assert "data row 301" in msg and "a 0.51 s step" in msg and "50 missing" in msg


def test_gap_split(tmp_path: Path) -> None:
    p = _gappy(tmp_path)
    segs = read_imu_segments(p)
    assert [s.n_samples for s in segs] == [300, 100, 500]
    assert all(s.rate_hz == pytest.approx(100.0) for s in segs)
    assert segs[1].t[0] == pytest.approx(3.5)
    log = read_imu(p, on_gap="split")
    assert log.n_samples == 500 and log.t[0] == pytest.approx(4.6)
    assert "3 contiguous segments found; using segment 3" in log.warnings[0]
    assert "(the longest, 500 samples from t=4.6 s)" in log.warnings[0]


def test_gap_ignored(tmp_path: Path) -> None:
    log = read_imu(_gappy(tmp_path), on_gap="ignore")
    assert log.n_samples == 900
    assert any("2 gap(s)" in w and "ignored" in w for w in log.warnings)


def test_gap_tolerance_option(tmp_path: Path) -> None:
    rows = _rows(100) + _rows(100, start=101)  # one missing sample: a 2 x dt step
    p = _write(tmp_path, HEADER + "".join(rows))
    with pytest.raises(InputError, match="1 gap"):
        read_imu(p)
    assert read_imu(p, gap_tolerance=2.5).n_samples == 200


def test_jittery_stamps_are_not_gaps(tmp_path: Path) -> None:
    rng = np.random.default_rng(1)
    t = np.cumsum(0.025 * (1 + 0.25 * rng.uniform(-1, 1, 2000)))
    text = "t,gyro_x\n" + "".join(f"{x:.6f},0.1\n" for x in t)
    log = read_imu(_write(tmp_path, text))
    assert log.rate_hz == pytest.approx(40.0, rel=0.05)


def test_inconsistent_rate(tmp_path: Path) -> None:
    p = _write(tmp_path, HEADER + "".join(_rows(100)))
    with pytest.raises(OptionError) as err:
        read_imu(p, rate_hz=200.0)
    msg = _one_line(err)
    assert "--rate 200 Hz" in msg and "100 Hz" in msg and "'time_s'" in msg
    assert read_imu(p, rate_hz=100.5).rate_hz == 100.5  # within 1 %


def test_no_time_and_no_rate(tmp_path: Path) -> None:
    p = _write(tmp_path, "gyro_x_dps,gyro_y_dps\n1,2\n3,4\n")
    with pytest.raises(InputError) as err:
        read_imu(p)
    assert "--rate" in _one_line(err)
    log = read_imu(p, rate_hz=50.0)
    np.testing.assert_allclose(log.t, [0.0, 0.02])


@pytest.mark.parametrize(
    ("kwargs", "word"),
    [
        ({"rate_hz": -1.0}, "--rate"),
        ({"rate_hz": float("nan")}, "--rate"),
        ({"on_gap": "skip"}, "--on-gap"),
        ({"gap_tolerance": 0.5}, "--gap-tolerance"),
        ({"gyro_unit": "furlongs"}, "--gyro-unit"),
        ({"accel_unit": "dps"}, "--accel-unit"),
        ({"time_unit": "fortnight"}, "--time-unit"),
        ({"channels": ["gyro_w"]}, "gyro_w"),
        ({"columns": {"speed": "v"}}, "speed"),
    ],
)
def test_bad_options(tmp_path: Path, kwargs: dict, word: str) -> None:
    p = _write(tmp_path, HEADER + "".join(_rows(5)))
    with pytest.raises(OptionError) as err:
        read_imu(p, **kwargs)
    assert word in _one_line(err)


def test_unknown_binary_type(tmp_path: Path) -> None:
    p = tmp_path / "log.bin"
    p.write_bytes(bytes(range(256)))
    with pytest.raises(InputError, match="unknown file type"):
        read_imu(p)


def test_binary_with_csv_suffix(tmp_path: Path) -> None:
    p = tmp_path / "log.csv"
    p.write_bytes(b"\xff\xfe" + bytes(range(256)))
    with pytest.raises(InputError, match="not a text table"):
        read_imu(p)


def test_wrong_suffix_is_sniffed(tmp_path: Path) -> None:
    src = DATA / "adis.parquet"
    p = tmp_path / "log.data"
    shutil.copyfile(src, p)
    assert read_imu(p).n_samples == 2000
    q = tmp_path / "log.export"
    q.write_text(HEADER + "".join(_rows(10)))
    assert read_imu(q).n_samples == 10


# --- property: damaged files give a user error or a valid log, never a crash ----

_VALID = HEADER + "".join(_rows(30))


@given(
    edits=st.lists(
        st.tuples(
            st.integers(min_value=0, max_value=len(_VALID) - 1),
            st.sampled_from(["", "x", ",", "\n", "#", "nan", "-", "1e999", '"', "\t", "  "]),
            st.integers(min_value=0, max_value=6),
        ),
        min_size=1,
        max_size=4,
    ),
    suffix=st.sampled_from([".csv", ".csv.gz", ".txt"]),
)
@settings(max_examples=120, deadline=None)
def test_damaged_csv_never_crashes(edits: list[tuple[int, str, int]], suffix: str) -> None:
    text = _VALID
    for pos, insert, cut in edits:
        pos = min(pos, len(text))
        text = text[:pos] + insert + text[pos + cut:]
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / f"log{suffix}"
        data = text.encode()
        p.write_bytes(gzip.compress(data) if suffix.endswith(".gz") else data)
        try:
            log = read_imu(p, on_gap="ignore")
        except ImuboundsError as err:
            assert "\n" not in str(err) and str(err)
            return
    assert log.n_samples >= 2
    assert np.all(np.diff(log.t) > 0)
    for v in log.channels.values():
        assert v.shape == log.t.shape and np.all(np.isfinite(v))


# --- the streaming checks see what the whole-log checks see, across block edges ----
@pytest.mark.parametrize("block", [1, 2, 3, 7, 64, 1000])
def test_stream_checker_matches_whole_log_checks_at_any_block_size(block: int) -> None:
    from imubounds.io.validate import StreamChecker, spike_warnings

    rng = np.random.default_rng(4)
    n = 600
    t = np.arange(n, dtype=np.int64) * 10_000_000  # ns at 100 Hz
    g = rng.normal(0.0, 0.01, n)
    g[[63, 127, 300]] += 5.0  # isolated spikes (at a block edge for several sizes)
    t_dup = np.insert(t, 200, t[199])  # a duplicated row...
    g_dup = np.insert(g, 200, g[199])
    t_gap = np.where(np.arange(t_dup.size) > 400, t_dup + 50_000_000, t_dup)  # ...and a gap
    checker = StreamChecker("x.csv", column="t", time_factor=1e-9, median_step=10_000_000,
                            gap_factor=1.5, on_gap="ignore")
    kept = []
    for a in range(0, t_gap.size, block):
        keep = checker.feed(t_gap[a:a + block], {"gyro_x": g_dup[a:a + block]})
        kept.append(g_dup[a:a + block] if keep is None else g_dup[a:a + block][keep])
    notes = checker.finish()
    np.testing.assert_array_equal(np.concatenate(kept), g)
    assert any("1 duplicated row(s)" in w and "data row 201" in w for w in notes), notes
    assert any("1 gap(s)" in w and "data row 402" in w for w in notes), notes
    whole = spike_warnings({"gyro_x": g}, source="x.csv")
    assert whole and "3 isolated" in whole[0]
    assert any("gyro_x has 3 isolated one-sample spike(s)" in w and "data row 64" in w
               for w in notes), notes
