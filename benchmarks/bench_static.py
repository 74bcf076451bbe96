"""Benchmark: the whole ``imubounds static`` against allantools' OADEV octave curves.

One run measures, on the same log and interleaved (the shared host's speed drifts,
so the two are paired run by run):

* ``imubounds static LOG -o DIR -q`` as a subprocess: everything the user waits for,
  from the interpreter start to the last file (reading, Allan curves, terms, GM and
  AR models, the figure as PNG and SVG, stationarity.png when a channel is flagged,
  noise.json, imu.yaml, report.html);
* a script that reads the CSV with ``pandas.read_csv`` and computes
  ``allantools.oadev(..., taus="octave")`` for every channel, also as a subprocess
  (interpreter start and imports included, as for imubounds).

Both wall time and CPU time (user + system of the child) are reported; the ratio
is the median over the runs of imubounds / allantools, run by run. The components
of the imubounds side (stages timed in this process, CPU seconds) are printed too.

Usage: ``python benchmarks/bench_static.py [LOG] [--runs 3]``; default LOG is
/work/shared/data/static/adis16405_imu1.csv.gz (1e6 samples x 6 channels). The last
line is ``static_ratio_vs_allantools <wall ratio>``.
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

DEFAULT_LOG = "/work/shared/data/static/adis16405_imu1.csv.gz"

ALLANTOOLS_SCRIPT = """
import sys, time
t0 = time.perf_counter()
import allantools, pandas as pd
df = pd.read_csv(sys.argv[1])
t1 = time.perf_counter()
rate = 1.0 / float(df.iloc[1, 0] - df.iloc[0, 0])
for c in df.columns[1:]:
    allantools.oadev(df[c].to_numpy(), rate=rate, data_type="freq", taus="octave")
t2 = time.perf_counter()
print(f"{t1 - t0} {t2 - t1}")
"""


def _child(cmd: list[str], env: dict[str, str]) -> tuple[float, float, str]:
    """Wall and CPU seconds (user + sys of the child) of one subprocess, and its stdout."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t = time.perf_counter()
    res = subprocess.run(cmd, env=env, capture_output=True, text=True, check=True)
    wall = time.perf_counter() - t
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu, res.stdout


def _stages(log_path: str) -> dict[str, float]:
    """CPU seconds of the stages of ``imubounds static`` run in this process (with one
    OpenBLAS thread, as the command sets before numpy is loaded)."""
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    from imubounds.io.outputs import write_json
    from imubounds.io.registry import read_imu
    from imubounds.report.html import write_report
    from imubounds.report.static_plots import (
        allan_figure,
        needs_stationarity_figure,
        save_figure,
        stationarity_figure,
    )
    from imubounds.stationary.pipeline import StaticSettings, analyse_static

    out: dict[str, float] = {}
    t = time.process_time()
    log = read_imu(log_path)
    out["read"] = time.process_time() - t
    full = StaticSettings(models=("gm", "ar"))  # as the CLI
    analyse_static(log, full)  # warm-up: numba cache loads, lazy tables
    t = time.process_time()
    analyse_static(log, StaticSettings(models=()))
    out["allan + terms + bounds"] = time.process_time() - t
    t = time.process_time()
    res = analyse_static(log, full)
    out["models (GM, AR)"] = time.process_time() - t - out["allan + terms + bounds"]
    with tempfile.TemporaryDirectory() as tmp:
        t = time.process_time()
        save_figure(allan_figure(res), Path(tmp) / "allan")
        out["figure (PNG + SVG)"] = time.process_time() - t
        if needs_stationarity_figure(res):
            t = time.process_time()
            save_figure(stationarity_figure(res), Path(tmp) / "stationarity", ("png",))
            out["stationarity.png"] = time.process_time() - t
        t = time.process_time()
        write_json(Path(tmp) / "noise.json", res.to_json())
        write_report(Path(tmp))
        out["noise.json + report"] = time.process_time() - t
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("log", nargs="?", default=DEFAULT_LOG)
    ap.add_argument("--runs", type=int, default=3)
    args = ap.parse_args()
    env = dict(os.environ)
    src = str(Path(__file__).resolve().parents[1] / "src")
    env["PYTHONPATH"] = src + os.pathsep + env.get("PYTHONPATH", "")
    walls: list[tuple[float, float]] = []
    cpus: list[tuple[float, float]] = []
    parts: list[tuple[float, float]] = []
    with tempfile.TemporaryDirectory() as tmp:
        # one warm-up of each (file cache, numba cache)
        _child([sys.executable, "-c", ALLANTOOLS_SCRIPT, args.log], env)
        static = [sys.executable, "-m", "imubounds", "static", args.log, "-o", tmp, "-q", "--force"]
        _child(static, env)
        for _ in range(max(1, args.runs)):
            aw, ac, out = _child([sys.executable, "-c", ALLANTOOLS_SCRIPT, args.log], env)
            read_s, oadev_s = (float(v) for v in out.split())
            parts.append((read_s, oadev_s))
            iw, ic, _ = _child(static, env)
            walls.append((iw, aw))
            cpus.append((ic, ac))
    print(f"log: {args.log}")
    for k, ((iw, aw), (ic, ac), (rd, od)) in enumerate(zip(walls, cpus, parts, strict=True)):
        print(
            f"run {k + 1}: imubounds static {iw:.2f} s wall ({ic:.2f} s CPU); allantools script "
            f"{aw:.2f} s wall ({ac:.2f} s CPU: import + read_csv {rd:.2f} s, oadev {od:.2f} s)"
        )
    stage = _stages(args.log)
    print("imubounds stages in this process (CPU s): "
          + ", ".join(f"{k} {v:.2f}" for k, v in stage.items()))  # fmt: skip
    ratio_cpu = statistics.median(i / a for i, a in cpus)
    ratio = statistics.median(i / a for i, a in walls)
    print(f"static_cpu_ratio_vs_allantools {ratio_cpu:.2f}")
    print(f"static_ratio_vs_allantools {ratio:.2f}")


if __name__ == "__main__":
    main()
