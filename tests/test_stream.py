"""Out-of-core Allan variance (issue 7): equality with the in-memory path."""

from __future__ import annotations

import json
from pathlib import Path

import h5py  # noqa: F401  (before codac, see conftest)
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from imubounds.errors import InputError, OptionError
from imubounds.io.chunked import open_chunked
from imubounds.stationary import _allan_kernels as _k
from imubounds.stationary.allan import ESTIMATORS, allan, max_cluster_size
from imubounds.stationary.stream import (
    EtaTracker,
    PhaseFile,
    _phase_block,
    _phase_block_ref,
    allan_outofcore,
    block_size,
    parse_memory,
    phase_to_file,
    route_outofcore,
    sumsq_file,
)

RATE = 100.0


@pytest.fixture(scope="module")
def signal() -> np.ndarray:
    rng = np.random.default_rng(7)
    n = 60_001
    # white noise + random walk + a large mean (like accel_z), so the mean matters
    return rng.normal(0.0, 0.02, n) + np.cumsum(rng.normal(0.0, 1e-4, n)) + 9.81


@pytest.fixture(scope="module")
def npy_path(tmp_path_factory: pytest.TempPathFactory, signal: np.ndarray) -> Path:
    p = tmp_path_factory.mktemp("ooc") / "one.npy"
    np.save(p, signal)
    return p


def _assert_same(a, b, rtol: float = 1e-12) -> None:  # noqa: ANN001
    np.testing.assert_array_equal(a.m, b.m)
    np.testing.assert_array_equal(a.n_terms, b.n_terms)
    np.testing.assert_array_equal(a.alpha, b.alpha)
    np.testing.assert_allclose(a.dev, b.dev, rtol=rtol, atol=0)
    np.testing.assert_allclose(a.ci_lower, b.ci_lower, rtol=rtol, atol=0)
    np.testing.assert_allclose(a.ci_upper, b.ci_upper, rtol=rtol, atol=0)
    np.testing.assert_allclose(a.edf, b.edf, rtol=1e-12, atol=0)


@pytest.mark.parametrize("estimator", ESTIMATORS)
@pytest.mark.parametrize("memory", ["64KiB", "4MiB"])
def test_outofcore_equals_in_memory(
    npy_path: Path, signal: np.ndarray, estimator: str, memory: str
) -> None:
    """The must-show test: a small memory setting forces every chunked code path."""
    ref = allan(signal, RATE, 40, estimator)  # dense grid: small and large m
    got = allan_outofcore(
        npy_path, 40, estimator, memory_limit=memory, rate_hz=RATE, channels=["accel_z"]
    )["accel_z"]
    _assert_same(got, ref)


def test_small_memory_really_takes_the_large_m_paths(npy_path: Path) -> None:
    # 64 KiB -> blocks of 1024 values: m up to ~30000 exceeds them by far
    assert block_size(parse_memory("64KiB")) == 1024
    assert block_size(parse_memory("1GiB")) == (1 << 30) // 64
    assert block_size(parse_memory("1GiB")) % _k.CHUNK == 0


@settings(max_examples=25, deadline=None)
@given(
    n=st.integers(20, 400),
    block=st.integers(1, 50),
    est=st.sampled_from(ESTIMATORS),
    seed=st.integers(0, 2**16),
)
def test_sumsq_file_matches_numpy_reference(
    tmp_path_factory: pytest.TempPathFactory, n: int, block: int, est: str, seed: int
) -> None:
    rng = np.random.default_rng(seed)
    y = rng.normal(size=n)
    x = _k.phase_from_rate(y, 0.01)
    p = tmp_path_factory.mktemp("ph") / "x.f64"
    x.tofile(p)
    m_max = max_cluster_size(n, est)
    ms = np.unique(np.linspace(1, m_max, 6).astype(np.int64))
    with PhaseFile(p, n) as ph:
        got = sumsq_file(ph, est, ms, block)
    ref = np.array([_k.sumsq_ref(x, est, int(m)) for m in ms])
    np.testing.assert_allclose(got, ref, rtol=1e-11, atol=1e-300)


@settings(max_examples=30, deadline=None)
@given(
    n=st.integers(1, 3000), cuts=st.lists(st.integers(0, 3000), max_size=6),
    seed=st.integers(0, 2**16),
)  # fmt: skip
def test_streamed_phase_is_bit_identical(
    tmp_path_factory: pytest.TempPathFactory, n: int, cuts: list[int], seed: int
) -> None:
    rng = np.random.default_rng(seed)
    y = rng.normal(5.0, 1.0, n)
    edges = sorted({0, n, *[c % (n + 1) for c in cuts]})
    blocks = [y[a:b] for a, b in zip(edges[:-1], edges[1:], strict=True)]
    p = tmp_path_factory.mktemp("ph") / "x.f64"
    assert phase_to_file(blocks, float(np.mean(y)), 0.01, p) == n
    got = np.fromfile(p, dtype=np.float64)
    np.testing.assert_array_equal(got, _k.phase_from_rate(y, 0.01))


def test_phase_block_numba_matches_python_reference() -> None:
    y = np.random.default_rng(3).normal(1.0, 1.0, 500)
    a, b = np.empty(500), np.empty(500)
    sa = _phase_block(y, 0.9, 0.01, 0.3, 1e-17, a)
    sb = _phase_block_ref(y, 0.9, 0.01, 0.3, 1e-17, b)
    assert sa == sb
    np.testing.assert_array_equal(a, b)


def _write_formats(tmp: Path, data: dict[str, np.ndarray]) -> dict[str, Path]:
    import pandas as pd

    n = len(next(iter(data.values())))
    t = np.arange(n) / RATE
    df = pd.DataFrame({"time_s": t, **{f"{k}_dps" if k.startswith("gyro") else f"{k}_g": v
                                       for k, v in data.items()}})  # fmt: skip
    out = {"csv": tmp / "log.csv", "csvgz": tmp / "log.csv.gz", "parquet": tmp / "log.parquet"}
    df.to_csv(out["csv"], index=False, float_format="%.17g")
    df.to_csv(out["csvgz"], index=False, float_format="%.17g")
    df.to_parquet(out["parquet"], row_group_size=5000)
    out["h5"] = tmp / "log.h5"
    with h5py.File(out["h5"], "w") as f:
        g = f.create_group("imu")
        g["time_s"] = t
        for col in df.columns[1:]:
            g[col] = df[col].to_numpy()
    arr = np.stack([df[c].to_numpy() for c in df.columns[1:]], axis=1)
    out["f64"] = tmp / "log.f64"
    arr.astype("<f8").tofile(out["f64"])
    return out


def test_every_chunked_format_gives_the_same_curve(tmp_path: Path) -> None:
    from imubounds.units import DEG, G0

    rng = np.random.default_rng(11)
    n = 20_000
    data = {"gyro_z": rng.normal(0, 0.5, n), "accel_x": rng.normal(0.1, 0.01, n)}
    files = _write_formats(tmp_path, data)
    ref = {
        "gyro_z": allan(data["gyro_z"] * DEG, RATE, "octave"),
        "accel_x": allan(data["accel_x"] * G0, RATE, "octave"),
    }
    for fmt, p in files.items():
        kw = {"rate_hz": RATE}
        if fmt == "f64":
            kw.update(channels=["gyro_z", "accel_x"], gyro_unit="deg/s", accel_unit="g")
            log = open_chunked(p, **kw)
        else:
            log = open_chunked(p)
        assert log.rate_hz == RATE, fmt
        got = allan_outofcore(log, "octave", memory_limit="128KiB")
        for c in ("gyro_z", "accel_x"):
            _assert_same(got[c], ref[c], rtol=1e-12)


def test_cli_static_out_of_core_writes_the_same_noise_json(tmp_path: Path) -> None:
    from imubounds.cli import main
    from imubounds.stationary.noise_sim import NoiseSpec, simulate, write_csv

    spec = NoiseSpec.from_mapping(
        {"gyro": {"N": "0.5 deg/sqrt(h)", "B": "20 deg/h"},
         "accel": {"N": "0.05 m/s/sqrt(h)", "B": "0.5 mg"}}
    )  # fmt: skip
    log = simulate(spec, RATE, 900.0, seed=5)
    src = tmp_path / "u.csv.gz"
    write_csv(log, src)
    common = ["static", str(src), "--models", "none", "--no-plot", "--no-report", "-q"]
    assert main([*common, "-o", str(tmp_path / "mem")]) == 0
    assert main([*common, "-o", str(tmp_path / "ooc"), "--out-of-core",
                 "--max-memory", "256KiB"]) == 0  # fmt: skip
    a = json.loads((tmp_path / "mem" / "noise.json").read_text())
    b = json.loads((tmp_path / "ooc" / "noise.json").read_text())
    assert a["input"]["n_samples"] == b["input"]["n_samples"]
    assert a["input"]["sample_rate_hz"] == b["input"]["sample_rate_hz"]
    assert any("out-of-core" in n for n in b["notes"])
    for ch, ca in a["channels"].items():
        cb = b["channels"][ch]
        np.testing.assert_allclose(cb["allan"]["adev"], ca["allan"]["adev"], rtol=1e-12)
        np.testing.assert_allclose(cb["allan"]["ci_upper"], ca["allan"]["ci_upper"], rtol=1e-12)
        for method in ("fit", "slope"):
            for t in ("Q", "N", "B", "K", "R"):
                va, vb = ca["noise"][method][t]["value"], cb["noise"][method][t]["value"]
                if va is None:
                    assert vb is None
                else:
                    assert vb == pytest.approx(va, rel=1e-9, abs=1e-300), (ch, method, t)
        assert cb["sigma_c"] == pytest.approx(ca["sigma_c"], rel=1e-9)


def test_interrupt_leaves_no_temporary_files(npy_path: Path, tmp_path: Path) -> None:
    calls = []

    def progress(stage: str, done: int, total: int) -> None:
        calls.append(stage)
        if stage == "allan" and done > 0:
            raise KeyboardInterrupt

    work = tmp_path / "tmp"
    work.mkdir()
    with pytest.raises(KeyboardInterrupt):
        allan_outofcore(npy_path, "octave", tmpdir=work, progress=progress,
                        memory_limit="64KiB", rate_hz=RATE, channels=["gyro_x"])  # fmt: skip
    assert list(work.iterdir()) == []
    assert "read" in calls and "phase" in calls


def test_non_finite_sample_is_named(tmp_path: Path) -> None:
    y = np.zeros(5000)
    y[1234] = np.nan
    p = tmp_path / "bad.npy"
    np.save(p, y)
    with pytest.raises(InputError, match=r"data row 1235, column 'gyro_z': value is NaN"):
        allan_outofcore(p, rate_hz=RATE, channels=["gyro_z"], memory_limit="64KiB")


def test_parse_memory_and_errors() -> None:
    assert parse_memory("1GiB") == 1 << 30
    assert parse_memory("512MB") == 512_000_000
    assert parse_memory("2e9") == 2_000_000_000
    assert parse_memory(1 << 20) == 1 << 20
    for bad in ("lots", "10", "1 XB"):
        with pytest.raises(OptionError):
            parse_memory(bad)


def test_eta_tracker() -> None:
    now = [0.0]
    eta = EtaTracker(clock=lambda: now[0])
    assert eta.update(0, 100) is None
    now[0] = 10.0
    assert eta.update(20, 100) == pytest.approx(40.0)


def test_route_outofcore(npy_path: Path, tmp_path: Path) -> None:
    import pandas as pd

    # .npy has no in-memory reader: always out-of-core
    assert route_outofcore(npy_path, "1GiB", rate_hz=RATE, channels=["gyro_x"]) is not None
    small = tmp_path / "s.csv"
    pd.DataFrame({"time_s": np.arange(100) / RATE, "gyro_x": np.zeros(100)}).to_csv(small)
    assert route_outofcore(small, "1GiB") is None
    assert route_outofcore(small, "64KiB", force=True) is not None
    big = tmp_path / "b.csv"
    pd.DataFrame({"time_s": np.arange(20000) / RATE, "gyro_x": np.zeros(20000)}).to_csv(big)
    assert route_outofcore(big, "64KiB") is not None


def test_text_size_bound_routes_as_the_opened_log(tmp_path: Path) -> None:
    """route_outofcore decides a small text log from its size alone: the bound is never
    below what the opened log says, for plain and gzip CSV of any column count."""
    import gzip

    import pandas as pd

    from imubounds.io.chunked import open_chunked, text_bytes_bound

    for ncol in (1, 6, 12):
        for n in (5, 300, 30000):
            df = pd.DataFrame({"time_s": np.arange(n) / RATE})
            for j in range(ncol):
                df[f"gyro_{'xyz'[j % 3]}{j // 3 or ''}"] = np.sin(np.arange(n) * (j + 1))
            plain = tmp_path / f"t{ncol}_{n}.csv"
            df.to_csv(plain, index=False)
            gz = tmp_path / f"t{ncol}_{n}.csv.gz"
            gz.write_bytes(gzip.compress(plain.read_bytes()))
            for p in (plain, gz):
                opened = open_chunked(p).bytes_in_memory()
                bound = text_bytes_bound(p)
                assert bound is not None and opened <= bound <= 3 * opened + 40_000, (p, opened)
                for mem in {max(65536, m) for m in (opened - 1, opened, bound)}:
                    want = None if opened <= mem else "out-of-core"
                    got = route_outofcore(p, mem)
                    assert (got is None) == (want is None), (p, mem)
    assert text_bytes_bound(tmp_path / "x.npy") is None
