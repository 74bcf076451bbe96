"""Benchmark: out-of-core Allan deviation of a huge single-axis log (issue 7).

Generates (once) a single-axis gyro log of ``--samples`` float64 values
(default 1e9 = 8 GB) as ``benchmarks/_data/ooc_<N>.npy`` (git-ignored; not
committed): white noise plus a small random walk, written block by block.
Then, each in a fresh subprocess so that peak RSS is its own:

* the out-of-core path (:func:`imubounds.stationary.stream.allan_outofcore`, memory
  setting ``--memory``): wall time, samples/s, peak RSS;
* the in-memory path (:func:`imubounds.stationary.allan.allan` on the loaded array) at
  the largest size that fits (``--in-memory-samples``, default the smaller of
  ``--samples`` and what 40 % of the available RAM allows), and the
  out-of-core path at that same size, for ratios.

Usage::

    .venv/bin/python benchmarks/bench_outofcore.py                # 1e9 samples
    .venv/bin/python benchmarks/bench_outofcore.py --samples 2e8 --keep
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
DATA = HERE / "_data"


def generate(path: Path, n: int, rate: float, seed: int = 1, block: int = 1 << 24) -> float:
    """Write an (n,) float64 .npy of gyro samples in rad/s, block by block."""
    if path.exists() and path.stat().st_size >= 8 * n:
        return 0.0
    t0 = time.perf_counter()
    rng = np.random.default_rng(seed)
    tmp = path.with_suffix(".part")
    walk = 0.0
    with open(tmp, "wb") as f:
        np.lib.format.write_array_header_1_0(
            f, {"descr": "<f8", "fortran_order": False, "shape": (n,)}
        )
        for a in range(0, n, block):
            k = min(block, n - a)
            # N = 1e-3 rad/s/sqrt(Hz) white noise, K = 1e-6 rad/s^2/sqrt(Hz) random walk
            w = rng.standard_normal(k) * (1e-3 * np.sqrt(rate))
            rw = np.cumsum(rng.standard_normal(k) * (1e-6 / np.sqrt(rate))) + walk
            walk = float(rw[-1])
            (w + rw + 0.01).tofile(f)
    tmp.replace(path)
    return time.perf_counter() - t0


def _peak_rss_mib() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def child(mode: str, path: str, n: int, rate: float, memory: str) -> None:
    import h5py  # noqa: F401  (import order, see tests/conftest.py)

    from imubounds.stationary.allan import allan
    from imubounds.stationary.stream import OutOfCoreStats, allan_outofcore

    base = _peak_rss_mib()
    t0 = time.perf_counter()
    if mode == "ooc":
        st = OutOfCoreStats()
        res = allan_outofcore(path, "octave", rate_hz=rate, channels=["gyro_z"],
                              memory_limit=memory, stats=st)["gyro_z"]  # fmt: skip
        extra = {"bytes_read_gb": st.bytes_read / 1e9, "block_values": st.block_values}
    else:
        y = np.load(path, mmap_mode="r")[:n]
        y = np.array(y)  # really in memory
        res = allan(y, rate, "octave")
        extra = {}
    dt = time.perf_counter() - t0
    print(json.dumps({
        "mode": mode, "n": int(res.n_samples), "seconds": dt,
        "samples_per_s": res.n_samples / dt, "peak_rss_mib": _peak_rss_mib(),
        "rss_after_imports_mib": base, "dev": [float(v) for v in res.dev], **extra,
    }))  # fmt: skip


def run_child(mode: str, path: Path, n: int, rate: float, memory: str) -> dict:
    out = subprocess.run(
        [sys.executable, __file__, "--child", mode, str(path), str(n), str(rate), memory],
        capture_output=True, text=True, check=True,
    )  # fmt: skip
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=float, default=1e9)
    ap.add_argument("--rate", type=float, default=1000.0)
    ap.add_argument("--memory", default="1GiB")
    ap.add_argument("--in-memory-samples", type=float, default=None)
    ap.add_argument("--keep", action="store_true", help="keep the generated log")
    ap.add_argument("--child", nargs=5, help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.child:
        mode, path, n, rate, memory = a.child
        child(mode, path, int(n), float(rate), memory)
        return
    n = int(a.samples)
    DATA.mkdir(exist_ok=True)
    (DATA / ".gitignore").write_text("*\n")
    big = DATA / f"ooc_{n}.npy"
    gen_s = generate(big, n, a.rate)
    print(f"log: {big} ({8 * n / 1e9:.2f} GB), generated in {gen_s:.0f} s", flush=True)
    ooc = run_child("ooc", big, n, a.rate, a.memory)
    print(f"out-of-core  N={n:.3g}: {ooc['seconds']:.1f} s, {ooc['samples_per_s'] / 1e6:.2f} "
          f"Msamples/s, peak RSS {ooc['peak_rss_mib']:.0f} MiB "
          f"(after imports {ooc['rss_after_imports_mib']:.0f} MiB)", flush=True)  # fmt: skip
    avail = os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    n_mem = int(a.in_memory_samples or min(n, int(0.4 * avail / (8 * 3))))
    small = DATA / f"ooc_{n_mem}.npy"
    if n_mem != n:
        generate(small, n_mem, a.rate)
    mem = run_child("mem", small, n_mem, a.rate, a.memory)
    ooc2 = ooc if n_mem == n else run_child("ooc", small, n_mem, a.rate, a.memory)
    rel = max(abs(x / y - 1) for x, y in zip(ooc2["dev"], mem["dev"], strict=True))
    print(
        f"in-memory    N={n_mem:.3g}: {mem['seconds']:.1f} s, "
        f"{mem['samples_per_s'] / 1e6:.2f} Msamples/s, peak RSS {mem['peak_rss_mib']:.0f} MiB"
    )
    print(
        f"out-of-core  N={n_mem:.3g}: {ooc2['seconds']:.1f} s, "
        f"{ooc2['samples_per_s'] / 1e6:.2f} Msamples/s, peak RSS {ooc2['peak_rss_mib']:.0f} MiB"
    )
    print(
        f"ratios out-of-core/in-memory at N={n_mem:.3g}: time "
        f"{ooc2['seconds'] / mem['seconds']:.2f}, peak RSS "
        f"{ooc2['peak_rss_mib'] / mem['peak_rss_mib']:.3f}; max |rel diff| of ADEV {rel:.1e}"
    )
    summary = {
        "n": n,
        "memory": a.memory,
        "ooc": {k: v for k, v in ooc.items() if k != "dev"},
        "n_in_memory": n_mem,
        "mem": {k: v for k, v in mem.items() if k != "dev"},
        "ooc_same_n": {k: v for k, v in ooc2.items() if k != "dev"},
        "max_rel_diff": rel,
    }
    (DATA / f"bench_outofcore_{n}.json").write_text(json.dumps(summary, indent=2))  # fmt: skip
    if not a.keep:
        for p in {big, small}:
            p.unlink(missing_ok=True)


if __name__ == "__main__":
    main()
