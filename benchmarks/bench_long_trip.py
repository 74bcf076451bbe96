"""Benchmark: peak memory and time of mode full on long trips (issue 27: a 24 h trip at
100 Hz within 2 GiB peak memory and 60 s).

The trip: the simulator's closed ``paper`` loop (IMU 100 Hz; GNSS position and velocity
at ``--gps-rate`` Hz, 1 by default; compass 1 Hz; attitude 10 Hz) simulated for one
hour and repeated back to back (``tile_drive``: every stream's times shifted by the
hour, the last instant of each hour dropped) to the requested length. The simulator
holds about 0.3 GB per hour of trip while it draws one, too much for 24 h; a repeated
hour has the same rates, samples and epochs per hour as a simulated day (the IMU bias
drift restarts each hour, within the day's drift bound). Built once per length and
rate in ``benchmarks/_data/`` (git-ignored).

Each measurement runs in a fresh process that loads the drive and runs
``dynamic_margins(drive, mode="full").to_dict()`` once (numba caches compiled or
loaded by one warm-up run on the 1 h trip first): wall time of the analysis, the process's peak RSS
(``ru_maxrss``) and its RSS with the drive loaded before the analysis. With
``--baseline SRC`` (the ``src`` of the previous version, e.g. ``git archive main src``)
the same trips are analysed by that version in the same run, up to
``--baseline-max-hours`` (the previous version needs about 0.35 GB per hour).

With ``--cli`` each trip is also written once as a drive-layout directory of Parquet
files (``write_layout``, next to the pickle) and analysed from the files by the command
line (``imubounds dynamic DIR --mode full --no-plot --no-report -q -o OUT``, in a fresh
process): the line ``version this-cli`` gives its wall time (reading included), its peak
RSS and ``read_rss_mib``, the RSS after ``read_drive`` alone in another fresh process.

Usage: ``python benchmarks/bench_long_trip.py [--hours 1,4,24] [--gps-rate 1]
[--baseline SRC] [--baseline-max-hours 4] [--cli]``. One line per trip and version::

    hours 24 version this samples 8640000 seconds 31.2 peak_rss_mib 1502 drive_rss_mib 690
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import pickle
import resource
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

HERE = Path(__file__).resolve().parent
DATA = HERE / "_data"
HOUR = 3600.0


def tile_drive(drive: Any, period: float, copies: int) -> Any:
    """The drive repeated ``copies`` times back to back, every time shifted by
    ``period`` (s); samples at or after ``period`` in each copy dropped."""

    def tile(stream: Any) -> Any:
        if stream is None:
            return None
        t = np.asarray(stream.t, float)
        t0 = float(t[0])
        keep = (t - t0) < period
        n = t.size

        def rep(v: Any, is_t: bool) -> Any:
            if isinstance(v, np.ndarray) and v.ndim >= 1 and v.shape[0] == n:
                parts = [v[keep] + (k * period if is_t else 0) for k in range(copies)]
                return np.concatenate(parts)
            if isinstance(v, dict):
                return {kk: rep(vv, False) for kk, vv in v.items()}
            return v

        ch = {f.name: rep(getattr(stream, f.name), f.name == "t")
              for f in dataclasses.fields(stream)}
        return dataclasses.replace(stream, **ch)

    names = ("imu", "gnss", "velocity", "heading", "mag", "attitude", "truth")
    return dataclasses.replace(drive, **{nm: tile(getattr(drive, nm)) for nm in names},
                               source=f"{drive.source}, repeated {copies} x {period:g} s")


def build(hours: float, gps_rate: float) -> Path:
    """The trip's pickle in benchmarks/_data/ (built once)."""
    DATA.mkdir(exist_ok=True)
    path = DATA / f"long_trip_{hours:g}h_gps{gps_rate:g}.pkl"
    if path.exists():
        return path
    from imubounds.dynamic.scenario import make_trip

    unit = min(hours, 1.0) * HOUR
    res = make_trip("paper", seed=1, duration_s=unit, distance_m=12.0 * unit,
                    aiding=("gnss", "gnss-vel", "compass", "attitude"), gps_rate_hz=gps_rate)
    drive = res.drive
    del res
    copies = int(round(hours * HOUR / unit))
    if copies > 1:
        drive = tile_drive(drive, unit, copies)
    tmp = path.with_suffix(".part")
    with open(tmp, "wb") as f:
        pickle.dump(drive, f, protocol=5)
    tmp.replace(path)
    return path


def layout_dir(path: Path) -> Path:
    """The trip's drive-layout directory of Parquet files (written once from the pickle,
    in a fresh process: the writer's memory is not the reader's)."""
    out = path.with_name(path.stem + "_parquet")
    if not (out / "imu.parquet").exists():
        code = ("import pickle, sys; from imubounds.io.drive.layout import write_layout; "
                "d = pickle.load(open(sys.argv[1], 'rb')); write_layout(d, sys.argv[2], "
                "fmt='parquet')")
        env = {**os.environ, "PYTHONPATH": str(HERE.parent / "src")}
        subprocess.run([sys.executable, "-c", code, str(path), str(out)], env=env, check=True)
    return out


def child_cli(directory: str, read_only: bool) -> None:
    """The command line on the drive-layout directory (or ``read_drive`` alone), one
    JSON line: wall time, peak RSS, RSS at the end."""
    import tempfile

    t0 = time.perf_counter()
    if read_only:
        from imubounds.io.drive.readers import read_drive

        drive = read_drive(directory)
        n = 0 if drive.imu is None else int(drive.imu.t.size)
    else:
        from imubounds.cli import main as cli_main

        with tempfile.TemporaryDirectory() as tmp:
            rc = cli_main(["dynamic", directory, "--mode", "full", "--no-plot", "--no-report",
                           "-q", "--force", "-o", tmp])
            with open(Path(tmp) / "dynamic.json") as f:
                out = json.load(f)
        n = int(out.get("samples", 0) or 0) if isinstance(out, dict) else 0
        if rc != 0:
            raise SystemExit(f"imubounds dynamic exited with {rc}")
    sec = time.perf_counter() - t0
    print(json.dumps({
        "samples": n, "seconds": sec, "rss_mib": _rss_mib(),
        "peak_rss_mib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
    }))


def _rss_mib() -> float:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20


def child(path: str) -> None:
    """Load the drive, run mode full once, print one JSON line."""
    from imubounds.dynamic.estimator import dynamic_margins

    with open(path, "rb") as f:
        drive = pickle.load(f)
    drive_rss = _rss_mib()
    t0 = time.perf_counter()
    out = dynamic_margins(drive, mode="full").to_dict()
    sec = time.perf_counter() - t0
    sm = out.get("smoother", {})
    print(json.dumps({
        "samples": int(drive.imu.t.size), "seconds": sec, "drive_rss_mib": drive_rss,
        "peak_rss_mib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
        "epochs": sm.get("epochs"), "sweeps": sm.get("sweeps"),
        "empty": out.get("empty_intersections", {}).get("count"),
    }))


def run(src: str, path: Path, how: str = "--child") -> dict[str, Any]:
    env = {**os.environ, "PYTHONPATH": src}
    cmd = [sys.executable, __file__, how, str(path)]
    res = subprocess.run(cmd, env=env, capture_output=True, text=True)
    if res.returncode != 0:
        return {"error": (res.stderr.strip().splitlines() or ["?"])[-1]}
    out: dict[str, Any] = json.loads(res.stdout.strip().splitlines()[-1])
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--hours", default="1,4,24")
    ap.add_argument("--gps-rate", type=float, default=1.0)
    ap.add_argument("--baseline", default=None, help="src directory of the previous version")
    ap.add_argument("--baseline-max-hours", type=float, default=4.0)
    ap.add_argument("--cli", action="store_true",
                    help="also the command line on the trip written as Parquet files")
    ap.add_argument("--child", default=None, help=argparse.SUPPRESS)
    ap.add_argument("--child-cli", default=None, help=argparse.SUPPRESS)
    ap.add_argument("--child-read", default=None, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        child(args.child)
        return
    if args.child_cli or args.child_read:
        child_cli(args.child_cli or args.child_read, read_only=bool(args.child_read))
        return
    this = str(HERE.parent / "src")
    versions = [("this", this)] + ([("baseline", str(Path(args.baseline).resolve()))]
                                   if args.baseline else [])
    warm = build(1.0, args.gps_rate)  # compiles (or loads) every numba cache the runs use
    for _, src in versions:
        run(src, warm)
    for h in (float(x) for x in args.hours.split(",")):
        t0 = time.perf_counter()
        path = build(h, args.gps_rate)
        print(f"# {h:g} h trip: {path.name} ({time.perf_counter() - t0:.0f} s to build or load)",
              flush=True)
        res: dict[str, dict[str, Any]] = {}
        for name, src in versions:
            if name == "baseline" and h > args.baseline_max_hours:
                continue
            r = res[name] = run(src, path)
            if "error" in r:
                print(f"hours {h:g} version {name} error {r['error']}", flush=True)
                continue
            print(f"hours {h:g} version {name} samples {r['samples']} seconds {r['seconds']:.1f} "
                  f"peak_rss_mib {r['peak_rss_mib']:.0f} drive_rss_mib {r['drive_rss_mib']:.0f} "
                  f"epochs {r['epochs']} sweeps {r['sweeps']} empty {r['empty']}", flush=True)
        if args.cli:
            for name, src in versions:
                if name == "baseline" and h > args.baseline_max_hours:
                    continue
                d = layout_dir(path)
                r = run(src, d, "--child-cli")
                rd = run(src, d, "--child-read")
                if "error" in r or "error" in rd:
                    print(f"hours {h:g} version {name}-cli error {r.get('error', rd.get('error'))}",
                          flush=True)
                    continue
                print(f"hours {h:g} version {name}-cli seconds {r['seconds']:.1f} peak_rss_mib "
                      f"{r['peak_rss_mib']:.0f} read_rss_mib {rd['rss_mib']:.0f} read_peak_mib "
                      f"{rd['peak_rss_mib']:.0f} read_seconds {rd['seconds']:.1f}", flush=True)
        a, b = res.get("this", {}), res.get("baseline", {})
        if "seconds" in a and "seconds" in b:
            print(f"hours {h:g} ratio_to_baseline seconds {a['seconds'] / b['seconds']:.2f} "
                  f"peak_rss {a['peak_rss_mib'] / b['peak_rss_mib']:.2f}", flush=True)


if __name__ == "__main__":
    main()
