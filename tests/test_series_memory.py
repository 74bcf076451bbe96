"""The memory-light sample series of mode full (issue 27) against their plain references:
checkpointed prefix sums and the block range-extremum table bit for bit, and the
preintegration in chunks equal to one call over the whole trip."""

from __future__ import annotations

import numpy as np
import pytest

from imubounds.dynamic.estimator import series_kernels as SK
from imubounds.dynamic.estimator.inputs import PiecewiseSignal, RangeExt
from tests.series_reference import SparseTable, prefix_arrays


def _series(n: int, seed: int, gaps: bool) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    ln = rng.uniform(0.005, 0.015, n)
    if gaps:
        ln[rng.integers(0, n, n // 50)] = 0.0  # repeated boundaries
        ln[rng.integers(0, n, 5)] = 3.0
    bnd = np.concatenate([[12.5], 12.5 + np.cumsum(ln)])
    y = rng.standard_normal(n) * 10.0 ** rng.integers(-3, 3, n)
    y[rng.integers(0, n, 7)] = -0.0
    return bnd, y


@pytest.mark.parametrize("n,seed,gaps", [(1, 0, False), (63, 1, True), (1000, 2, True),
                                         (4097, 3, False)])
def test_prefix_sums_bit_for_bit(n: int, seed: int, gaps: bool) -> None:
    bnd, y = _series(n, seed, gaps)
    ref = prefix_arrays(bnd, y)
    ck = SK.checkpoints(bnd, y, SK.CHECKPOINT, SK.CHECKPOINT_Z)
    idx = np.arange(n + 1, dtype=np.int64)
    got = SK.prefix_at(bnd, y, *ck, SK.CHECKPOINT, SK.CHECKPOINT_Z, idx, True)
    for r, g in zip(ref, got, strict=True):
        np.testing.assert_array_equal(np.signbit(g), np.signbit(r))
        np.testing.assert_array_equal(g, r)
    # strided y (a column of the drive's (n, 3) array) gives the same sums
    y3 = np.stack([y, -y, y], -1)
    ck3 = SK.checkpoints(bnd, y3[:, 2], SK.CHECKPOINT, SK.CHECKPOINT_Z)
    got3 = SK.prefix_at(bnd, y3[:, 2], *ck3, SK.CHECKPOINT, SK.CHECKPOINT_Z, idx, False)
    np.testing.assert_array_equal(got3[0], ref[0])
    np.testing.assert_array_equal(got3[1], ref[1])


def test_signal_queries_unchanged() -> None:
    """cum, zcum, integral, mean_cum and abs_integral as with the full arrays."""
    bnd, y = _series(3000, 5, True)
    unknown = np.zeros(y.size, bool)
    unknown[100:140] = True
    sig = PiecewiseSignal(bnd, y, unknown, 7.0)
    S, A, Z, ZA = prefix_arrays(bnd, np.where(unknown, 0.0, y))
    rng = np.random.default_rng(9)
    t = np.sort(rng.uniform(bnd[0] - 1, bnd[-1] + 1, 500))
    t[:20] = bnd[rng.integers(0, bnd.size, 20)]  # on boundaries
    val, err, _ = sig.cum(t)
    tc = np.clip(t, bnd[0], bnd[-1])
    i = np.clip(np.searchsorted(bnd, tc, side="right") - 1, 0, bnd.size - 2)
    part = tc - bnd[i]
    yy = sig.y[i]
    np.testing.assert_array_equal(val, S[i] + yy * part)
    np.testing.assert_array_equal(err, 1.01 * 2.0**-53 * ((i + 3) * A[i] + 3 * np.abs(yy * part)))
    zval, zerr = sig.zcum(t)
    inc = S[i] * part + 0.5 * yy * part * part
    np.testing.assert_array_equal(zval, Z[i] + inc)
    np.testing.assert_array_equal(
        zerr, 1.01 * 2.0**-53 * ((i + 4) * ZA[i] + 4 * np.abs(inc) + (i + 3) * A[i] * part)
    )
    a, b = t[:-1], t[1:]
    AB = np.concatenate([[0.0], np.cumsum(np.abs(sig.y) * np.diff(bnd))])
    ia, ib = i[:-1], i[1:]
    np.testing.assert_array_equal(
        sig.abs_integral(a, b), (AB[ib + 1] - AB[ia]) * (1 + 1e-12) + sig.unknown_len(a, b) * 7.0
    )


@pytest.mark.parametrize("n", [1, 2, 15, 16, 17, 300, 5000])
def test_range_extrema_match_sparse_table(n: int) -> None:
    rng = np.random.default_rng(n)
    lo = rng.standard_normal(n)
    hi = lo + rng.uniform(0, 1, n)
    if n > 20:
        lo[rng.integers(0, n, 3)] = np.nan
        hi[rng.integers(0, n, 3)] = -np.inf
    ref = SparseTable(lo, hi)
    got = RangeExt(lo, hi)
    i = rng.integers(0, n, 2000)
    j = np.minimum(i + rng.integers(0, max(1, n // 3), 2000) ** rng.integers(1, 3, 2000), n - 1)
    j[:50] = i[:50]
    j[50:80] = np.maximum(i[50:80] - 1, 0)  # j < i: the extremum of the two ends
    for a, b in zip(ref.query(i, j), got.query(i, j), strict=True):
        np.testing.assert_array_equal(a, b)
    with pytest.raises(IndexError):
        got.query(np.array([0]), np.array([n]))


def test_preintegration_in_chunks_equals_one_call(monkeypatch: pytest.MonkeyPatch) -> None:
    from imubounds.dynamic.estimator import full as F
    from imubounds.dynamic.scenario import make_trip

    drive = make_trip("paper", seed=2, duration_s=200.0, distance_m=2000.0,
                      aiding=("gnss", "gnss-vel", "compass", "attitude")).drive
    ctx = F.build_context(drive, None, {})
    beta0 = np.array([[-0.01, 0.02], [-0.02, 0.01], [-1e-3, 2e-3]])
    whole = F._link_errors(ctx, beta0)
    for chunk in (1, 37, 1000):
        monkeypatch.setattr(F, "PREINTEGRATE_CHUNK", chunk)
        part = F._link_errors(ctx, beta0)
        for k in whole:
            np.testing.assert_array_equal(part[k], whole[k])


def test_locator_cache_stays_within_its_byte_budget(monkeypatch: pytest.MonkeyPatch) -> None:
    from imubounds.dynamic.estimator import inputs as I

    monkeypatch.setattr(I, "LOCATOR_CACHE_BYTES", 1 << 16)
    bnd = np.arange(0.0, 1000.0, 0.01)
    loc = I.Locator(bnd)
    rng = np.random.default_rng(1)
    for size in (10, 300, 3000, 300, 10):
        for _ in range(20):
            t = rng.uniform(-1.0, 1001.0, size)
            ref = np.clip(np.searchsorted(bnd, t, side="right") - 1, 0, bnd.size - 2)
            np.testing.assert_array_equal(loc.locate(t), ref)
            np.testing.assert_array_equal(loc.locate(t.copy()), ref)  # from the cache
            held = sum(len(k) + v.nbytes for k, v in loc._cache.items())
            assert held == loc._bytes <= 1 << 16
