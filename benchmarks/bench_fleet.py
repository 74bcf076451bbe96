"""Benchmark: fleet throughput on Dask vs a serial loop (issues 7 and 15).

Simulates ``--units`` static logs (``--minutes`` at ``--rate`` Hz, six axes,
CSV.gz) under ``benchmarks/_data/fleet/`` (git-ignored), then times

* **serial**: a loop of :func:`imubounds.stationary.fleet.analyse_unit` over every
  unit in this process, after :func:`~imubounds.stationary.fleet.warm_up` (imports
  and numba kernels loaded: the same state as a warm worker). The serial loop
  keeps numba's default thread count (all cores) for the Allan kernels and runs
  with the same malloc settings as the fleet's workers and the CLI
  (:func:`imubounds.runtime.tune_malloc`), so that the ratio is the parallel gain
  alone; its CPU time / wall time says how many cores it kept busy. "serial
  cold" adds the process's warm-up. The same loop in a plain Python process
  (glibc's default malloc: a notebook user's loop) is also timed, in a
  subprocess;
* **Dask cold**: a new local cluster (:func:`~imubounds.stationary.fleet.local_cluster`,
  ``--workers`` single-threaded worker processes) started, warmed (the worker
  plugin) and the fleet run, cache emptied first; the start-up and warm-up are
  also given on their own;
* **Dask warm**: a cluster already up and warm (as with ``--scheduler`` of a
  running cluster), run ``--repeat`` times with the cache emptied; the median
  is reported (the ``--workers`` row of the scaling table);
* a **scaling table** for 1, 2 and 4 workers (warm clusters, median of
  ``--repeat`` runs): speed-up over the serial loop and over 1 worker, and the
  parallel efficiency ``T(1 worker) / (w * T(w workers))``;
* **paired** runs: the serial loop and a warm ``--workers`` Dask run alternately,
  ``--pairs`` times; the median of the per-pair ratios is the figure least
  disturbed by load from elsewhere on a shared machine;
* **the fleet command in one process** (``run_fleet(..., n_workers=0)``, what
  ``imubounds fleet --workers 0`` runs): the serial loop plus the fleet's own
  work (hashing for the cache, cache files, tables, statistics), the same
  outputs as a Dask run;
* **the machine's ceiling**: two independent plain processes (no Dask), set up
  as the fleet's workers (tuned malloc, one thread each, a core each, warmed),
  each analysing half of the units at the same time, alternately with one such
  process analysing all of them and with the serial loop (paired: a shared
  host's speed drifts over minutes, so only ratios of neighbouring runs are
  compared across phases). No scheduler can do better than these two
  processes on this machine: their time, against the serial loop, is the
  highest speed-up the fleet could show here, and the Dask run is given as a
  share of it. On a virtual machine whose cores are shared (or SMT siblings on
  the host), two busy processes run slower each than one alone;
* a cached rerun and, optionally, a loop of ``imubounds static FILE`` processes.

Every Dask result is compared with the serial loop: all noise terms, CIs and
sigma_c to 1e-12 relative, the Allan curves exactly. The machine's load average
before and after is printed: on a shared machine timings are noisy; repeat.

Usage::

    .venv/bin/python benchmarks/bench_fleet.py --units 16 --minutes 30
"""

from __future__ import annotations

import argparse
import json
import math
import os
import shutil
import statistics
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
DATA = HERE / "_data"


def _make_fleet(units: int, minutes: float, rate: float) -> list[str]:
    from imubounds.stationary.fleet import expand_globs
    from imubounds.stationary.noise_sim import NoiseSpec, simulate, write_csv

    DATA.mkdir(exist_ok=True)
    (DATA / ".gitignore").write_text("*\n")
    d = DATA / f"fleet_{units}x{minutes:g}min_{rate:g}Hz"
    d.mkdir(exist_ok=True)
    spec = NoiseSpec.from_mapping(
        {"gyro": {"N": "0.5 deg/sqrt(h)", "B": "20 deg/h"},
         "accel": {"N": "0.05 m/s/sqrt(h)", "B": "0.5 mg"}}
    )  # fmt: skip
    t0 = time.perf_counter()
    for i in range(units):
        p = d / f"unit{i:04d}.csv.gz"
        if not p.exists():
            write_csv(simulate(spec, rate, minutes * 60.0, seed=1000 + i), p)
    size = sum(p.stat().st_size for p in d.glob("*.csv.gz")) / 1e6
    print(f"{units} units of {minutes:g} min at {rate:g} Hz ({size:.0f} MB CSV.gz), "
          f"ready in {time.perf_counter() - t0:.0f} s", flush=True)  # fmt: skip
    return expand_globs([str(d / "unit*.csv.gz")])[:units]


def _plain_process_loop(paths: list[str], repeat: int) -> list[float]:
    """Wall times of the serial loop in a new plain Python process (glibc's default
    malloc, numba's default threads), after its warm-up."""
    code = (
        "import json, sys, time\n"
        "import h5py\n"
        "from imubounds.stationary.fleet import FleetSettings, analyse_unit, warm_up\n"
        "paths, repeat = json.loads(sys.argv[1]), int(sys.argv[2])\n"
        "s = FleetSettings(); warm_up(s); out = []\n"
        "for _ in range(repeat):\n"
        "    t0 = time.perf_counter(); [analyse_unit(p, s) for p in paths]\n"
        "    out.append(time.perf_counter() - t0)\n"
        "print(json.dumps(out))\n"
    )
    env = {k: v for k, v in os.environ.items() if not k.startswith("MALLOC_")}
    done = subprocess.run([sys.executable, "-c", code, json.dumps(paths), str(repeat)],
                          check=True, capture_output=True, text=True, env=env)  # fmt: skip
    return [float(x) for x in json.loads(done.stdout.strip().splitlines()[-1])]


def _independent_process(conn: Any, core: int | None) -> None:
    """One plain process set up as a fleet worker (tuned malloc, one thread, a core),
    analysing the batches it is sent; replies with (wall s, CPU s) per batch."""
    if core is not None and hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {core})
    from imubounds.runtime import tune_malloc

    tune_malloc()
    from imubounds.stationary.fleet import analyse_batch, warm_up

    settings = conn.recv()
    warm_up(settings)
    analyse_batch([], settings, numba_threads=1)  # numba and pyarrow: one thread each
    conn.send("ready")
    while (items := conn.recv()) is not None:
        t0, c0 = time.perf_counter(), time.process_time()
        res = analyse_batch(items, settings, numba_threads=1)
        ok = all(r["status"] == "ok" for r in res)
        conn.send((time.perf_counter() - t0, time.process_time() - c0, ok))


def _machine_ceiling(
    paths: list[str], settings: Any, repeat: int, serial: Any = None
) -> dict[str, Any]:
    """Two independent processes, each half of the units at once, alternately with one
    process doing all units and (``serial``, a callable) the serial loop in this
    process: the speed-up the machine itself gives this workload, paired run by run
    (a shared host's speed drifts over minutes)."""
    import multiprocessing as mp

    from imubounds.stationary.fleet import unit_names

    ctx = mp.get_context("spawn")
    cores = sorted(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else []
    pipes, procs = [], []
    for k in range(2):
        here, there = ctx.Pipe()
        core = cores[k] if len(cores) >= 2 else None
        pr = ctx.Process(target=_independent_process, args=(there, core), daemon=True)
        pr.start()
        here.send(settings)
        pipes.append(here)
        procs.append(pr)
    try:
        for c in pipes:
            if c.recv() != "ready":
                raise RuntimeError("an independent process did not start")
        items = [(p, n, None) for p, n in zip(paths, unit_names(paths), strict=True)]
        halves = [items[0::2], items[1::2]]
        one, two, cpu_two, ser = [], [], [], []
        for _ in range(repeat):
            if serial is not None:
                t0 = time.perf_counter()
                serial()
                ser.append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            pipes[0].send(items)
            _, _, ok = pipes[0].recv()
            one.append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            for c, h in zip(pipes, halves, strict=True):
                c.send(h)
            got = [c.recv() for c in pipes]
            two.append(time.perf_counter() - t0)
            cpu_two.append(sum(g[1] for g in got))
            if not (ok and all(g[2] for g in got)):
                raise RuntimeError("a unit failed in an independent process")
    finally:
        for c in pipes:
            c.send(None)
        for pr in procs:
            pr.join(timeout=30)
    paired = ({"serial_runs_s": ser,
               "serial_over_two_paired": statistics.median(
                   a / b for a, b in zip(ser, two, strict=True))} if ser else {})  # fmt: skip
    return {**paired, "one_process_runs_s": one, "two_processes_runs_s": two,
            "one_process_s": statistics.median(one), "two_processes_s": statistics.median(two),
            "two_processes_cpu_s": statistics.median(cpu_two),
            "gain_two_vs_one": statistics.median(a / b for a, b in zip(one, two, strict=True)),
            "pinned": len(cores) >= 2}  # fmt: skip


def _same(serial: list[dict[str, Any]], res: Any) -> tuple[bool, float]:
    """Whether a fleet result equals the serial loop: terms to 1e-12 relative, curves exact.
    Returns (identical, largest relative difference seen)."""
    import numpy as np

    t = res.table
    worst = 0.0
    ok = True
    for r in serial:
        sub = t[t.unit == r["unit"]].set_index("channel")
        for row in r["rows"]:
            got = sub.loc[row["channel"]]
            for k, v in row.items():
                if isinstance(v, float):
                    g = float(got[k])
                    if math.isnan(v) and math.isnan(g):
                        continue
                    rel = abs(g - v) / max(abs(v), 1e-300)
                    worst = max(worst, rel)
                    ok &= rel <= 1e-12
            c = res.curves[r["unit"]][row["channel"]]
            ok &= bool(np.array_equal(np.asarray(c["adev"]), r["curves"][row["channel"]]["adev"]))
    return ok, worst


def main() -> None:
    import h5py  # noqa: F401  (import order, see tests/conftest.py)

    from imubounds.stationary.fleet import (
        FleetSettings,
        analyse_unit,
        local_cluster,
        run_fleet,
        warm_up,
    )
    from imubounds.stationary.fleet._dask import ensure_warm

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--units", type=int, default=16)
    ap.add_argument("--minutes", type=float, default=30.0)
    ap.add_argument("--rate", type=float, default=100.0)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--scaling", default="1,2,4", help="worker counts of the scaling table")
    ap.add_argument("--repeat", type=int, default=3, help="runs per warm measurement")
    ap.add_argument("--pairs", type=int, default=5,
                    help="alternate serial / warm Dask runs this many times (paired ratio)")
    ap.add_argument("--cli-units", type=int, default=0, help="units timed for the CLI loop")
    ap.add_argument("--long-minutes", type=float, default=0.0,
                    help="also time one unit this long, split by channel across the workers "
                    "(--split-channels) and as one task")
    a = ap.parse_args()
    load0 = os.getloadavg()
    paths = _make_fleet(a.units, a.minutes, a.rate)
    settings = FleetSettings()
    out = DATA / "fleet_out"

    import numba

    from imubounds.runtime import tune_malloc

    untuned = _plain_process_loop(paths, a.repeat)
    print(f"serial loop in a plain process (default malloc): "
          f"{', '.join(f'{t:.2f}' for t in untuned)} s", flush=True)  # fmt: skip
    tune_malloc()
    t0 = time.perf_counter()
    t_warm_serial = warm_up(settings)
    t_serial_runs, cpu_serial = [], []
    serial: list[dict[str, Any]] = []
    for _ in range(a.repeat):
        t0, c0 = time.perf_counter(), time.process_time()
        serial = [analyse_unit(p, settings) for p in paths]
        t_serial_runs.append(time.perf_counter() - t0)
        cpu_serial.append(time.process_time() - c0)
    assert all(r["status"] == "ok" for r in serial)
    t_serial = statistics.median(t_serial_runs)
    print(f"serial loop (numba threads {numba.get_num_threads()}): "
          f"{', '.join(f'{t:.2f}' for t in t_serial_runs)} s; CPU/wall "
          f"{statistics.median(cpu_serial) / t_serial:.2f} cores; warm-up {t_warm_serial:.1f} s",
          flush=True)  # fmt: skip

    # ---- the fleet command in one process: the same outputs as a Dask run
    t_fleet_serial_runs = []
    for _ in range(a.repeat):
        shutil.rmtree(out, ignore_errors=True)
        t0 = time.perf_counter()
        run_fleet(paths, out, settings, n_workers=0, plot=False)
        t_fleet_serial_runs.append(time.perf_counter() - t0)
    t_fleet_serial = statistics.median(t_fleet_serial_runs)
    print(f"fleet command in one process (--workers 0, same outputs): "
          f"{', '.join(f'{t:.2f}' for t in t_fleet_serial_runs)} s", flush=True)  # fmt: skip

    # ---- the machine's ceiling: two independent processes, no Dask
    ceiling = _machine_ceiling(paths, settings, a.repeat,
                               serial=lambda: [analyse_unit(p, settings) for p in paths])
    print(f"paired with the serial loop ({', '.join(f'{t:.2f}' for t in ceiling['serial_runs_s'])}"
          f" s): serial / two processes {ceiling['serial_over_two_paired']:.2f}x", flush=True)
    print(f"independent processes (no Dask), one thread each: one process "
          f"{', '.join(f'{t:.2f}' for t in ceiling['one_process_runs_s'])} s; two at once "
          f"{', '.join(f'{t:.2f}' for t in ceiling['two_processes_runs_s'])} s; gain "
          f"{ceiling['gain_two_vs_one']:.2f}x", flush=True)  # fmt: skip

    from dask.distributed import Client

    def worker_cpu(client: Any) -> float:
        return float(sum(client.run(time.process_time).values()))

    def fresh_run(client: Any) -> tuple[float, Any, float]:
        """Wall time, result and CPU seconds of the workers plus this process (the client)."""
        shutil.rmtree(out, ignore_errors=True)
        c0 = worker_cpu(client) + time.process_time()
        t0 = time.perf_counter()
        res = run_fleet(paths, out, settings, client=client, plot=False)
        t = time.perf_counter() - t0
        return t, res, worker_cpu(client) + time.process_time() - c0

    # ---- cold: start a cluster, warm it, run
    t0 = time.perf_counter()
    cluster = local_cluster(a.workers, 1)
    client = Client(cluster)
    t_start = time.perf_counter() - t0
    t0 = time.perf_counter()
    ensure_warm(client, settings)
    t_warmup = time.perf_counter() - t0
    t_first, res, _ = fresh_run(client)
    t_cold = t_start + t_warmup + t_first
    same, worst = _same(serial, res)
    print(f"dask cold, {a.workers} workers: start {t_start:.1f} s + warm-up {t_warmup:.1f} s "
          f"+ run {t_first:.2f} s = {t_cold:.1f} s; identical {same}", flush=True)  # fmt: skip
    client.close()
    cluster.close()

    # ---- warm clusters: the scaling table (the --workers row is "Dask warm")
    table = []
    for w in sorted({int(x) for x in a.scaling.split(",")} | {a.workers}):
        with local_cluster(w, 1) as lc, Client(lc) as cl:
            ensure_warm(cl, settings)
            runs, cpus = [], []
            for _ in range(a.repeat):
                t, res, cpu = fresh_run(cl)
                runs.append(t)
                cpus.append(cpu)
                s, wr = _same(serial, res)
                same &= s
                worst = max(worst, wr)
            table.append({"workers": w, "runs_s": runs, "median_s": statistics.median(runs),
                          "min_s": min(runs), "cpu_s": statistics.median(cpus),
                          "tasks": res.n_tasks})  # fmt: skip
            print(f"dask warm, {w} workers: {', '.join(f'{t:.2f}' for t in runs)} s "
                  f"({res.n_tasks} tasks, CPU {statistics.median(cpus):.1f} s)",
                  flush=True)  # fmt: skip
    # ---- paired: serial loop and warm Dask run alternately, so that load from elsewhere
    # on a shared machine falls on both alike; the median of the per-pair ratios
    pairs = []
    with local_cluster(a.workers, 1) as lc, Client(lc) as cl:
        ensure_warm(cl, settings)
        for _ in range(a.pairs):
            t0 = time.perf_counter()
            serial = [analyse_unit(p, settings) for p in paths]
            ts = time.perf_counter() - t0
            td, res, _ = fresh_run(cl)
            s, wr = _same(serial, res)
            same &= s
            worst = max(worst, wr)
            pairs.append({"serial_s": ts, "dask_s": td, "ratio": ts / td})
            print(f"pair: serial {ts:.2f} s, dask {a.workers} workers {td:.2f} s, "
                  f"{ts / td:.2f}x", flush=True)  # fmt: skip
    paired_ratio = statistics.median(p["ratio"] for p in pairs) if pairs else math.nan

    t1 = next(r["median_s"] for r in table if r["workers"] == 1) if any(
        r["workers"] == 1 for r in table) else math.nan  # fmt: skip
    for r in table:
        r["speedup_vs_serial_best"] = min(t_serial_runs) / r["min_s"]
        r["speedup_vs_serial"] = t_serial / r["median_s"]
        r["speedup_vs_1_worker"] = t1 / r["median_s"]
        r["efficiency"] = t1 / (r["workers"] * r["median_s"])
    t_warm = next(r["median_s"] for r in table if r["workers"] == a.workers)

    t0 = time.perf_counter()
    res2 = run_fleet(paths, out, settings, n_workers=0, plot=False)
    t_cached = time.perf_counter() - t0

    long_case: dict[str, Any] = {}
    if a.long_minutes > 0:
        (lp,) = _make_fleet(1, a.long_minutes, a.rate)
        lserial: list[float] = []
        lruns: list[float] = []
        for _ in range(a.repeat):
            t0 = time.perf_counter()
            one = analyse_unit(lp, settings)
            lserial.append(time.perf_counter() - t0)
        with local_cluster(a.workers, 1) as lc, Client(lc) as cl:
            ensure_warm(cl, settings)
            lwhole: list[float] = []
            for _ in range(a.repeat):
                for split, runs in ((True, lruns), (False, lwhole)):
                    shutil.rmtree(out, ignore_errors=True)
                    t0 = time.perf_counter()
                    lres = run_fleet([lp], out, settings, client=cl, plot=False,
                                     split_channels=split)  # fmt: skip
                    runs.append(time.perf_counter() - t0)
                    lsame, lworst = _same([one], lres)
                    same &= lsame
                    worst = max(worst, lworst)
        ls, lsp, lwh = (statistics.median(x) for x in (lserial, lruns, lwhole))
        long_case = {"minutes": a.long_minutes, "serial_s": ls, "dask_split_s": lsp,
                     "dask_whole_s": lwh, "speedup_split": ls / lsp,
                     "speedup_whole": ls / lwh}  # fmt: skip
        print(f"one unit of {a.long_minutes:g} min: serial {long_case['serial_s']:.2f} s; "
              f"{a.workers} workers split by channel {long_case['dask_split_s']:.2f} s "
              f"({long_case['speedup_split']:.2f}x), one task {long_case['dask_whole_s']:.2f} s "
              f"({long_case['speedup_whole']:.2f}x)", flush=True)  # fmt: skip

    t_cli = math.nan
    if a.cli_units > 0:
        n_cli = min(a.cli_units, len(paths))
        t0 = time.perf_counter()
        for p in paths[:n_cli]:
            subprocess.run(
                [sys.executable, "-m", "imubounds", "static", p, "-o", str(DATA / "cli_out"),
                 "--models", "none", "--no-plot", "--no-report", "-q"], check=True,
            )  # fmt: skip
        t_cli = (time.perf_counter() - t0) * len(paths) / n_cli

    summary = {
        "units": a.units, "minutes": a.minutes, "rate_hz": a.rate, "workers": a.workers,
        "cpu_count": os.cpu_count(), "load_avg_before": load0, "load_avg_after": os.getloadavg(),
        "serial_numba_threads": numba.get_num_threads(),
        "serial_s": t_serial, "serial_runs_s": t_serial_runs,
        "serial_plain_process_s": statistics.median(untuned),
        "serial_plain_process_runs_s": untuned,
        "speedup_warm_vs_plain_process_serial": statistics.median(untuned) / t_warm,
        "serial_cpu_per_wall": statistics.median(cpu_serial) / t_serial,
        "serial_cpu_s": statistics.median(cpu_serial),
        "serial_cold_s": t_serial + t_warm_serial,
        "dask_cold_s": t_cold, "dask_cluster_start_s": t_start, "dask_warmup_s": t_warmup,
        "dask_first_run_s": t_first, "dask_warm_s": t_warm,
        "speedup_warm": t_serial / t_warm, "speedup_cold": t_serial / t_cold,
        "scaling": table, "cached_rerun_s": t_cached, "n_cached_rerun": res2.n_cached,
        "paired": pairs, "paired_ratio_median": paired_ratio,
        "fleet_serial_s": t_fleet_serial, "fleet_serial_runs_s": t_fleet_serial_runs,
        "speedup_warm_vs_fleet_serial": t_fleet_serial / t_warm,
        "machine_ceiling": ceiling,
        "ceiling_vs_serial": t_serial / ceiling["two_processes_s"],
        "ceiling_vs_serial_paired": ceiling["serial_over_two_paired"],
        "dask_share_of_ceiling": ceiling["two_processes_s"] / t_warm,
        "long_unit": long_case,
        "cli_loop_s_extrapolated": t_cli,
        "identical_to_serial": same, "largest_relative_difference": worst,
    }  # fmt: skip
    print(json.dumps(summary, indent=2))
    print(f"\n{'workers':>7} {'median s':>9} {'best s':>7} {'vs serial':>9} {'best/best':>9} "
          f"{'vs 1 worker':>11} {'efficiency':>10} {'CPU s':>6}")  # fmt: skip
    print(f"{'serial':>7} {t_serial:>9.2f} {min(t_serial_runs):>7.2f} {'':>9} {'':>9} {'':>11} "
          f"{'':>10} {statistics.median(cpu_serial):>6.1f}")  # fmt: skip
    for r in table:
        print(f"{r['workers']:>7} {r['median_s']:>9.2f} {r['min_s']:>7.2f} "
              f"{r['speedup_vs_serial']:>8.2f}x {r['speedup_vs_serial_best']:>8.2f}x "
              f"{r['speedup_vs_1_worker']:>10.2f}x {r['efficiency']:>10.2f} "
              f"{r['cpu_s']:>6.1f}")  # fmt: skip
    print(f"serial loop in a plain process (default malloc) {statistics.median(untuned):.2f} s: "
          f"Dask {a.workers} workers warm {statistics.median(untuned) / t_warm:.2f}x")  # fmt: skip
    print(f"fleet command in one process (--workers 0) {t_fleet_serial:.2f} s: "
          f"Dask {a.workers} workers warm {t_fleet_serial / t_warm:.2f}x")  # fmt: skip
    t2p = ceiling["two_processes_s"]
    print(f"machine ceiling: two independent processes {t2p:.2f} s = "
          f"{t_serial / t2p:.2f}x the serial loop (one process alone "
          f"{ceiling['one_process_s']:.2f} s, gain {ceiling['gain_two_vs_one']:.2f}x); "
          f"Dask {a.workers} workers warm {t_warm:.2f} s = {t2p / t_warm:.0%} of it")  # fmt: skip
    print(f"paired (each against the serial loop run just before it): two bare processes "
          f"{ceiling['serial_over_two_paired']:.2f}x, Dask {a.workers} workers "
          f"{paired_ratio:.2f}x = {paired_ratio / ceiling['serial_over_two_paired']:.0%} of "
          f"the paired ceiling")  # fmt: skip
    print(f"serial {t_serial:.2f} s; Dask {a.workers} workers warm {t_warm:.2f} s "
          f"({t_serial / t_warm:.2f}x), cold {t_cold:.1f} s ({t_serial / t_cold:.2f}x); "
          f"paired serial/Dask ratio, median of {len(pairs)}: {paired_ratio:.2f}x; "
          f"identical to serial (1e-12): {same}")  # fmt: skip
    (DATA / "bench_fleet.json").write_text(json.dumps(summary, indent=2))


if __name__ == "__main__":
    main()
