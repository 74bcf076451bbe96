"""Benchmark: mode full on a 1 h trip (100 Hz IMU, 10 Hz GNSS position + velocity, 1 Hz
compass, attitude), smoothed to the fixpoint with margins for every tau, against the
one-pass mode paper on the same drive, in the same run.

The trip comes from the project's trip simulator when it offers
``imubounds.dynamic.scenario.make_trip`` (variant ``gnss10``), else from the test
suite's generator ``tests/trips.py``. Times are wall-clock seconds of the analysis
alone (the drive is built first), best of ``--repeat`` after one warm-up run that
compiles or loads the numba caches; on a shared machine they vary with the load.

Usage: ``python benchmarks/bench_estimator.py [--hours H] [--repeat R]``. The last line
is ``full_seconds <t> paper_seconds <t> ratio <full/paper>``.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[1]


def make_drive(hours: float) -> Any:
    duration = 3600.0 * hours
    distance = 12.0 * duration
    try:
        from imubounds.dynamic.scenario import make_trip as sim_trip  # the simulator

        res = sim_trip("gnss10", seed=1, duration_s=duration, distance_m=distance,
                       aiding=("gnss", "gnss-vel", "compass", "attitude"))
        return res.drive, "imubounds.dynamic.scenario (gnss10)"
    except (ImportError, TypeError, ValueError):
        sys.path.insert(0, str(REPO))
        from tests.trips import make_trip

        drive, _ = make_trip("gnss10", 1, duration_s=duration, distance_m=distance)
        return drive, "tests/trips.py (gnss10)"


def best_of(fn: Any, repeat: int) -> tuple[float, Any]:
    out = fn()  # warm-up: compile or load the numba caches
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--hours", type=float, default=1.0)
    ap.add_argument("--repeat", type=int, default=2)
    args = ap.parse_args()
    from imubounds.dynamic.estimator import dynamic_margins

    t0 = time.perf_counter()
    drive, src = make_drive(args.hours)
    print(f"trip: {src}, {args.hours:g} h, {drive.imu.t.size} IMU samples, "
          f"{drive.gnss.t.size} GNSS fixes (built in {time.perf_counter() - t0:.1f} s)")
    t_full, full = best_of(lambda: dynamic_margins(drive).to_dict(), args.repeat)
    t_paper, _ = best_of(lambda: dynamic_margins(drive, mode="paper").to_dict(), args.repeat)
    sm = full["smoother"]
    n_win = sum(r["n_windows"] for rows in full["margins"].values() for r in rows)
    print(f"mode full: {sm['epochs']} epochs, {sm['sweeps']} sweeps to the fixpoint "
          f"(tol {sm['tolerance']:g}), {n_win} windows over "
          f"{len(next(iter(full['margins'].values())))} tau levels, "
          f"{full['empty_intersections']['count']} empty intersections")
    print(f"full_seconds {t_full:.2f} paper_seconds {t_paper:.2f} ratio {t_full / t_paper:.1f}")


if __name__ == "__main__":
    main()
