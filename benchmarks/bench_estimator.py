"""Benchmark: mode full on a 1 h trip (100 Hz IMU, 10 Hz GNSS position + velocity, 1 Hz
compass, attitude), smoothed to the fixpoint with margins for every tau, against the
one-pass mode paper on the same drive, in the same run.

``--workload positions``: the paper's kind of trip with GNSS positions only and the
compass (``imubounds simulate --scenario paper --seed 7 --duration 3600 --rate 100
--gps-rate 10``; positions-only forms of accel_y's transport term, the costliest; the
target is mode full within 5 s on the 2-core machine).

The trip comes from the project's trip simulator when it offers
``imubounds.dynamic.scenario.make_trip`` (variant ``gnss10``), else from the test
suite's generator ``tests/trips.py``. Times are wall-clock seconds of the analysis
alone (the drive is built first), best of ``--repeat`` after one warm-up run that
compiles or loads the numba caches; on a shared machine they vary with the load.

Usage: ``python benchmarks/bench_estimator.py [--hours H] [--repeat R] [--baseline SRC]
[--workload gnss10|positions]``.
The last line is ``full_seconds <t> paper_seconds <t> ratio <full/paper>``; with
``--baseline SRC`` (the ``src`` directory of the previous version, e.g. a checkout of
main) the same trip is analysed by that version in a subprocess in the same run and the
line ``baseline_full_seconds <t> ratio_to_baseline <this/previous>`` follows. Peak
memory (max RSS of the process, MiB) is printed too; it includes the simulator's peak
(printed after the trip is built): benchmarks/bench_long_trip.py measures the analysis
alone, in fresh processes, for trips of 1 to 24 h.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[1]


def make_drive(hours: float, workload: str = "gnss10") -> Any:
    duration = 3600.0 * hours
    if workload == "positions":
        from imubounds.dynamic.scenario import make_trip as sim_trip

        res = sim_trip("paper", seed=7, duration_s=duration, rate_hz=100.0, gps_rate_hz=10.0)
        return res.drive, "imubounds.dynamic.scenario (paper, seed 7, positions + compass)"
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


#: CPU seconds of the best run of the last :func:`best_of` (less sensitive than the wall
#: time to the other processes of a shared machine)
CPU = {"last": 0.0}


def best_of(fn: Any, repeat: int) -> tuple[float, Any]:
    out = fn()  # warm-up: compile or load the numba caches
    best = float("inf")
    for _ in range(repeat):
        t0, c0 = time.perf_counter(), time.process_time()
        out = fn()
        if time.perf_counter() - t0 < best:
            best = time.perf_counter() - t0
            CPU["last"] = time.process_time() - c0
    return best, out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--hours", type=float, default=1.0)
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--baseline", default=None, help="src directory of the previous version")
    ap.add_argument("--workload", choices=("gnss10", "positions"), default="gnss10",
                    help="gnss10: positions + velocity + compass + attitude; positions: "
                    "the paper trip's positions + compass at 10 Hz")
    ap.add_argument("--full-only", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    from imubounds.dynamic.estimator import dynamic_margins

    t0 = time.perf_counter()
    drive, src = make_drive(args.hours, args.workload)
    print(f"trip: {src}, {args.hours:g} h, {drive.imu.t.size} IMU samples, "
          f"{drive.gnss.t.size} GNSS fixes (built in {time.perf_counter() - t0:.1f} s, "
          f"peak RSS so far {_peak_mib():.0f} MiB: the simulator's)")
    t_full, full = best_of(lambda: dynamic_margins(drive).to_dict(), args.repeat)
    cpu_full = CPU["last"]
    if args.full_only:
        print(f"full_seconds {t_full:.2f} peak_rss_mib {_peak_mib():.0f} "
              f"cpu_seconds {CPU['last']:.2f}")
        return
    t_paper, _ = best_of(lambda: dynamic_margins(drive, mode="paper").to_dict(), args.repeat)
    sm = full["smoother"]
    n_win = sum(r["n_windows"] for rows in full["margins"].values() for r in rows)
    print(f"mode full: {sm['epochs']} epochs, {sm['sweeps']} sweeps to the fixpoint "
          f"(tol {sm['tolerance']:g}), {n_win} windows over "
          f"{len(next(iter(full['margins'].values())))} tau levels, "
          f"{full['empty_intersections']['count']} empty intersections")
    print(f"peak_rss_mib {_peak_mib():.0f}")
    print(f"full_seconds {t_full:.2f} paper_seconds {t_paper:.2f} ratio {t_full / t_paper:.1f}"
          f" full_cpu_seconds {cpu_full:.2f}")
    if args.baseline:
        import os
        import subprocess

        env = {**os.environ, "PYTHONPATH": str(Path(args.baseline).resolve())}
        cmd = [sys.executable, __file__, "--hours", str(args.hours), "--repeat",
               str(args.repeat), "--workload", args.workload, "--full-only"]
        out = subprocess.run(cmd, env=env, capture_output=True, text=True, check=True).stdout
        last = out.strip().splitlines()[-1].split()
        t_base = float(last[1])
        c_base = float(last[5]) if len(last) > 5 else float("nan")
        print(f"baseline_full_seconds {t_base:.2f} baseline_peak_rss_mib {last[3]} "
              f"ratio_to_baseline {t_full / t_base:.2f} baseline_cpu_seconds {c_base:.2f} "
              f"cpu_ratio_to_baseline {cpu_full / c_base:.2f}")


def _peak_mib() -> float:
    import resource

    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


if __name__ == "__main__":
    main()
