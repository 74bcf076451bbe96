"""Benchmark: fleet throughput on Dask vs a serial loop (issue 7).

Simulates ``--units`` static logs (``--minutes`` at ``--rate`` Hz, six axes,
CSV.gz) under ``benchmarks/_data/fleet/`` (git-ignored), then times

* a serial loop of :func:`imubounds.stationary.fleet.analyse_unit` in this process;
* :func:`imubounds.stationary.fleet.run_fleet` on a fresh ``LocalCluster`` with
  ``--workers`` single-threaded worker processes (cluster start-up included),
  cache emptied first;
* the same again (everything from the cache);
* a loop of ``imubounds static FILE`` processes (the first ``--cli-units``
  timed, extrapolated to all units).

Usage::

    .venv/bin/python benchmarks/bench_fleet.py --units 16 --minutes 30
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
DATA = HERE / "_data"


def main() -> None:
    import h5py  # noqa: F401  (import order, see tests/conftest.py)
    import pandas as pd

    from imubounds.stationary.fleet import FleetSettings, analyse_unit, expand_globs, run_fleet
    from imubounds.stationary.noise_sim import NoiseSpec, simulate, write_csv

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--units", type=int, default=16)
    ap.add_argument("--minutes", type=float, default=30.0)
    ap.add_argument("--rate", type=float, default=100.0)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--cli-units", type=int, default=4, help="units timed for the CLI loop")
    a = ap.parse_args()
    DATA.mkdir(exist_ok=True)
    (DATA / ".gitignore").write_text("*\n")
    d = DATA / "fleet"
    d.mkdir(exist_ok=True)
    spec = NoiseSpec.from_mapping(
        {"gyro": {"N": "0.5 deg/sqrt(h)", "B": "20 deg/h"},
         "accel": {"N": "0.05 m/s/sqrt(h)", "B": "0.5 mg"}}
    )  # fmt: skip
    t0 = time.perf_counter()
    for i in range(a.units):
        p = d / f"unit{i:04d}.csv.gz"
        if not p.exists():
            write_csv(simulate(spec, a.rate, a.minutes * 60.0, seed=1000 + i), p)
    print(f"{a.units} units of {a.minutes:g} min at {a.rate:g} Hz "
          f"({sum(p.stat().st_size for p in d.glob('*.csv.gz')) / 1e6:.0f} MB), "
          f"ready in {time.perf_counter() - t0:.0f} s", flush=True)  # fmt: skip
    paths = expand_globs([str(d / "unit*.csv.gz")])[: a.units]
    settings = FleetSettings()

    t0 = time.perf_counter()
    serial = [analyse_unit(str(p), settings) for p in paths]
    t_serial = time.perf_counter() - t0
    assert all(r["status"] == "ok" for r in serial)

    out = DATA / "fleet_out"
    shutil.rmtree(out, ignore_errors=True)
    t0 = time.perf_counter()
    res = run_fleet([str(p) for p in paths], out, settings, n_workers=a.workers)
    t_dask = time.perf_counter() - t0
    t0 = time.perf_counter()
    res2 = run_fleet([str(p) for p in paths], out, settings, plot=False)
    t_cached = time.perf_counter() - t0
    # a cluster that is already up and warm (imports and numba caches loaded), as with
    # --scheduler ADDRESS of a running scheduler
    from dask.distributed import Client, LocalCluster

    with LocalCluster(n_workers=a.workers, threads_per_worker=1, dashboard_address=":0") as lc:
        with Client(lc) as client:
            client.gather(client.map(analyse_unit, [str(p) for p in paths[:a.workers]],
                                     settings=settings, pure=False))  # fmt: skip
            shutil.rmtree(out, ignore_errors=True)
            t0 = time.perf_counter()
            run_fleet([str(p) for p in paths], out, settings, client=client)
            t_warm = time.perf_counter() - t0
    cols = [c for c in res.table.columns if c not in ("unit", "path", "status", "error")]
    same = all(
        pd.DataFrame(r["rows"])[cols].equals(
            res.table[res.table.unit == r["unit"]][cols].reset_index(drop=True)
        )
        for r in serial
    )
    # the user's alternative: one `imubounds static` process per file
    t0 = time.perf_counter()
    n_cli = max(1, min(a.cli_units, len(paths)))
    for p in paths[:n_cli]:
        subprocess.run(
            [sys.executable, "-m", "imubounds", "static", str(p), "-o", str(DATA / "cli_out"),
             "--models", "none", "--no-plot", "--no-report", "-q"], check=True,
        )  # fmt: skip
    t_cli = (time.perf_counter() - t0) * len(paths) / n_cli
    summary = {
        "units": a.units, "minutes": a.minutes, "rate_hz": a.rate, "workers": a.workers,
        "serial_s": t_serial, "dask_s": t_dask, "cached_rerun_s": t_cached,
        "cli_loop_s_extrapolated": t_cli,
        "serial_units_per_s": a.units / t_serial, "dask_units_per_s": a.units / t_dask,
        "dask_warm_cluster_s": t_warm, "speedup_warm": t_serial / t_warm,
        "speedup": t_serial / t_dask, "speedup_vs_cli_loop": t_cli / t_dask,
        "tasks": res.n_tasks, "n_cached_rerun": res2.n_cached,
        "identical_to_serial": same,
    }  # fmt: skip
    print(json.dumps(summary, indent=2))
    (DATA / "bench_fleet.json").write_text(json.dumps(summary, indent=2))


if __name__ == "__main__":
    main()
