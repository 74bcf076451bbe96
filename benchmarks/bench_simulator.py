"""Benchmark: simulate 200 paper-length trips (8 variants in turn) in memory.

Run: ``python benchmarks/bench_simulator.py [--trips N]``. Prints the wall and CPU time
per trip and in total, and how many trips have a clean record. The target (issue 11):
200 trips well under a minute.
"""

from __future__ import annotations

import argparse
import time

from imubounds.dynamic.scenario import VARIANTS, make_trip


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--trips", type=int, default=200)
    args = p.parse_args()
    names = list(VARIANTS)
    make_trip("paper", seed=0)  # imports and caches
    wall, cpu = time.perf_counter(), time.process_time()
    clean = 0
    for i in range(args.trips):
        clean += make_trip(names[i % len(names)], seed=i).record.clean
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    print(
        f"{args.trips} trips ({len(names)} variants, 792 s at 100 Hz): {wall:.1f} s wall, "
        f"{cpu:.1f} s CPU; {wall / args.trips * 1e3:.0f} ms per trip; clean records: {clean}"
    )


if __name__ == "__main__":
    main()
