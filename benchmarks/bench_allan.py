"""Benchmark: overlapping Allan deviation of 1e7 white-noise samples at 92 tau.

Compares, in one run and on the same tau list,

* ``imubounds.stationary.allan.allan`` (full call: phase, all sums, noise identification,
  EDF and confidence intervals) and its sum-of-squares stage alone;
* ``allantools.oadev(..., data_type="freq", taus=...)``;
* ``allan_variance.compute_avar`` (PyPI ``allan-variance``). It has no tau-list
  argument: it takes ``tau_min``, ``tau_max`` and ``n_clusters`` and rounds a
  log grid itself, so the common tau list *is* its grid (tau_min = 1 sample,
  tau_max = its default N/10 samples, n_clusters chosen to give 92 unique
  cluster sizes). Its estimator integrates without a leading zero, so it
  averages the N-2m terms k = 1..N-2m (ours and allantools': N-2m+1 terms,
  k = 0..N-2m); the script compares it both with our standard curve and with
  our kernel evaluated on exactly its terms.

numba compile time is excluded from the timings (a warm-up call runs first)
and reported separately, both as the warm-up in this process (cache load if
the on-disk cache exists) and as a cold compile in a subprocess with an empty
cache directory.

Usage: ``python benchmarks/bench_allan.py [--n 10000000] [--points 92]``.
The last line is ``allan_speedup_vs_allantools <ratio>``.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from typing import TypeVar

import numpy as np

T = TypeVar("T")


def _cluster_sizes_like_allan_variance(n: int, points: int) -> tuple[np.ndarray, int]:
    from allan_variance import avar as av

    n_clusters = points
    while True:
        ms = av._compute_cluster_sizes(n, 1.0, None, None, n_clusters)
        if ms.size >= points:
            return ms, n_clusters
        n_clusters += 1


def _best(fn: Callable[[], T], repeat: int) -> tuple[float, T]:
    best = float("inf")
    outs: list[T] = []
    for _ in range(max(1, repeat)):
        t = time.perf_counter()
        outs = [fn()]
        best = min(best, time.perf_counter() - t)
    return best, outs[0]


def _cold_compile_seconds() -> float:
    code = (
        "import time, numpy as np; t = time.perf_counter();"
        "from imubounds.stationary.allan import allan;"
        "from imubounds.stationary.allan import ESTIMATORS;"
        "[allan(np.random.default_rng(0).normal(size=5000), 10.0, 8, e) for e in ESTIMATORS];"
        "print(time.perf_counter() - t)"
    )
    with tempfile.TemporaryDirectory() as tmp:
        env = dict(os.environ, NUMBA_CACHE_DIR=tmp)
        res = subprocess.run(
            [sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True
        )
    return float(res.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=10_000_000)
    ap.add_argument("--points", type=int, default=92)
    ap.add_argument("--rate", type=float, default=100.0)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--no-cold", action="store_true", help="skip the cold-compile subprocess")
    args = ap.parse_args()

    import allantools
    import numba
    from allan_variance import avar as av

    from imubounds.stationary import _allan_kernels as K
    from imubounds.stationary.allan import allan

    n, rate = args.n, args.rate
    dt = 1.0 / rate
    y = np.random.default_rng(12345).normal(0.0, 0.01, size=n)
    ms, n_clusters = _cluster_sizes_like_allan_variance(n, args.points)
    taus = ms * dt
    print(f"N = {n}, rate = {rate} Hz, {ms.size} tau from {taus[0]:g} s to {taus[-1]:g} s")
    print(f"numba threads: {numba.get_num_threads()}, CPU count: {os.cpu_count()}")

    # warm-up (JIT compile or cache load)
    t = time.perf_counter()
    allan(y[:10000], rate, 8)
    warm = time.perf_counter() - t

    t_ours, res = _best(lambda: allan(y, rate, taus), args.repeat)
    t_ours_fixed, res_fixed = _best(lambda: allan(y, rate, taus, noise=0), args.repeat)

    def kernel_only() -> np.ndarray:
        x = K.phase_from_rate(y, dt)
        return K.sumsq_tasks(x, "overlapping", ms)

    t_kernel, _ = _best(kernel_only, args.repeat)
    threads = numba.get_num_threads()
    numba.set_num_threads(1)
    t_kernel_1, _ = _best(kernel_only, args.repeat)
    numba.set_num_threads(threads)

    t_at, at_out = _best(lambda: allantools.oadev(y, rate=rate, data_type="freq", taus=taus), 1)
    at_taus, at_dev = at_out[0], at_out[1]
    t_av, av_out = _best(
        lambda: av.compute_avar(y, dt, tau_min=dt, tau_max=None, n_clusters=n_clusters), 1
    )
    av_tau, av_var = av_out
    assert np.array_equal(np.rint(av_tau / dt).astype(np.int64), ms)
    assert np.allclose(at_taus, res.tau)

    # allan-variance's convention: terms k = 1..N-2m, divided by N-2m
    x = K.phase_from_rate(y, dt)
    same_terms = np.array(
        [
            K.adev_sumsq(x, int(m), 1, n - 2 * int(m) + 1, 1) / (2.0 * (m * dt) ** 2 * (n - 2 * m))
            for m in ms
        ]
    )

    d_at = np.max(np.abs(res.dev / at_dev - 1.0))
    d_av_std = np.max(np.abs(np.sqrt(av_var) / res.dev - 1.0))
    d_av_same = np.max(np.abs(np.sqrt(av_var) / np.sqrt(same_terms) - 1.0))
    d_fixed = np.max(np.abs(res_fixed.dev / res.dev - 1.0))

    print()
    print(f"{'tool':58s} {'time [s]':>10s} {'vs allantools':>14s}")
    rows = [
        ("allantools.oadev", t_at),
        ("allan_variance.compute_avar", t_av),
        ("imubounds allan() full (noise='auto', EDF, CI)", t_ours),
        ("imubounds allan() with fixed noise alpha=0", t_ours_fixed),
        (f"imubounds phase + sums only ({threads} threads)", t_kernel),
        ("imubounds phase + sums only (1 thread)", t_kernel_1),
    ]
    for name, tt in rows:
        print(f"{name:58s} {tt:10.3f} {t_at / tt:13.1f}x")
    print()
    print(f"max rel diff imubounds vs allantools.oadev:               {d_at:.2e}")
    print(f"max rel diff allan_variance vs imubounds (standard):      {d_av_std:.2e}")
    print(f"max rel diff allan_variance vs imubounds (its N-2m terms): {d_av_same:.2e}")
    print(f"(noise='auto' vs alpha=0 deviations identical:            {d_fixed:.1e})")
    print(f"numba warm-up in this process (cache load or compile): {warm:.2f} s")
    if not args.no_cold:
        cold = _cold_compile_seconds()
        print(f"numba cold compile of all estimators (empty cache): {cold:.2f} s")
    print(f"allan_speedup_vs_allantools {t_at / t_ours:.1f}")


if __name__ == "__main__":
    main()
