"""``imubounds fleet GLOB... -o DIR``: characterise many units on Dask.

Exit codes: 0 when every unit was analysed; 1 when at least one unit failed
(the others are analysed and written, and a failure summary is printed on
stderr); 2 for bad input or options, as every command.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from typing import Any

from imubounds.cli._common import (
    Reporter,
    add_force_option,
    add_log_options,
    nonneg_int,
    parse_taus,
    positive_float,
    positive_int,
    probability,
)
from imubounds.stationary.allan_grammar import DEFAULT_TAU_GRID

#: Exit code when some units failed (the rest were analysed and written).
EXIT_UNITS_FAILED = 1

ESTIMATORS = ("overlapping", "non-overlapping", "modified", "hadamard", "total")


def register(sub: Any) -> None:
    p = sub.add_parser(
        "fleet",
        help="characterise a fleet of units (many static logs) on Dask",
        description="Run the static pipeline (Allan deviation, noise terms) over many logs on "
        "a Dask cluster (local by default) and write DIR/fleet.parquet (one row per unit and "
        "channel), DIR/fleet.json, DIR/fleet.png and, with --spec, DIR/passfail.csv. Units "
        "already done (same file content, settings and imubounds version) are taken from "
        "DIR/.cache. Logs may be local paths or fsspec URLs (s3://, gs://, https://, file://; "
        "s3fs/gcsfs/aiohttp needed for those). Units are named by their path relative to the "
        "common folder of all logs. fleet.json, fleet.parquet and report.html hold the "
        "spread of N, B, K across units, robust-z outliers and, with --compare, each unit's "
        "drift since a previous run.",
        epilog="exit status: 0 every unit analysed; 1 some unit failed (the others are "
        "written; a failure summary is printed); 2 bad input or options",
    )
    p.add_argument("logs", nargs="+", metavar="GLOB", help="log files or glob patterns")
    p.add_argument("-o", "--out", default="fleet", metavar="DIR", help="output directory")
    add_force_option(p)
    p.add_argument("--scheduler", metavar="ADDRESS", help="running dask scheduler, tcp://h:8786")
    p.add_argument(
        "--workers", type=nonneg_int, default=2,
        help="local cluster workers (default 2); 0 runs the units in this process, no Dask",
    )  # fmt: skip
    p.add_argument("--threads-per-worker", type=positive_int, default=1, help="default 1")
    p.add_argument(
        "--spec", metavar="YAML",
        help="datasheet limits (max Q, N, B, K, R per kind; format in docs/fleet.md)",
    )  # fmt: skip
    p.add_argument("--tau", default=DEFAULT_TAU_GRID,
                   help=f"tau grid (as for static; default {DEFAULT_TAU_GRID})")
    p.add_argument("--estimator", choices=ESTIMATORS, default="overlapping")
    p.add_argument(
        "--confidence", type=probability, default=0.683,
        help="confidence level of the terms' intervals (default 0.683, 1 sigma)",
    )  # fmt: skip
    p.add_argument("--terms-from", choices=("fit", "slope"), default="fit")
    p.add_argument(
        "--max-memory", default="1GiB", metavar="SIZE",
        help="per-unit memory setting: larger logs take the out-of-core path",
    )  # fmt: skip
    p.add_argument(
        "--task-size", default="4MiB", metavar="SIZE",
        help="group small logs into tasks of about SIZE of input (default 4MiB)",
    )  # fmt: skip
    p.add_argument(
        "--split-channels", action="store_true",
        help="with fewer logs than worker threads, split each log by channel across workers "
        "(each part parses the whole log: pays only when the analysis outweighs the reading)",
    )  # fmt: skip
    p.add_argument(
        "--outlier-z", type=positive_float, default=3.5, metavar="Z",
        help="flag a unit whose robust z-score of a term (on the log scale) exceeds Z "
        "(default 3.5)",
    )  # fmt: skip
    p.add_argument(
        "--compare", metavar="PREVIOUS_DIR",
        help="output directory of a previous fleet run: drift of each unit's terms",
    )  # fmt: skip
    p.add_argument(
        "--drift-z", type=positive_float, default=3.5, metavar="Z",
        help="with --compare, flag a term whose change since the previous run exceeds Z "
        "times the two runs' combined uncertainty (log scale; default 3.5)",
    )  # fmt: skip
    p.add_argument("--no-plot", action="store_true", help="skip the figures")
    p.add_argument("--no-report", action="store_true", help="skip report.html")
    p.add_argument("--json", action="store_true", help="print fleet.json on stdout")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress or messages")
    add_log_options(p)
    p.set_defaults(func=run)


def _g(v: Any) -> str:
    return "—" if v is None or (isinstance(v, float) and not math.isfinite(v)) else f"{v:.4g}"


def run(args: argparse.Namespace) -> int:
    from imubounds.io import parse_column_map
    from imubounds.stationary.fleet import FleetSettings, run_fleet
    from imubounds.stationary.stream import parse_memory

    rep = Reporter(args.quiet)
    read: dict[str, Any] = {
        "rate_hz": args.rate,
        "columns": parse_column_map(args.columns) if args.columns else None,
        "gyro_unit": args.gyro_unit,
        "accel_unit": args.accel_unit,
        "time_unit": args.time_unit,
        "on_gap": args.on_gap,
        "gap_tolerance": args.gap_tolerance,
    }
    taus = parse_taus(args.tau)
    settings = FleetSettings(
        taus=tuple(taus) if isinstance(taus, list) else taus,
        estimator=args.estimator,
        confidence=args.confidence,
        terms_from=args.terms_from,
        memory_limit=args.max_memory,
        read={k: v for k, v in read.items() if v is not None},
    )
    parse_memory(args.max_memory, "--max-memory")
    task_bytes = parse_memory(args.task_size, "--task-size")
    from imubounds.io.outputs import check_output_folder

    # the fleet writes in place: the same rule as a result set (its own earlier results,
    # the cache of every earlier run, or --overwrite); a re-run with more units is its own
    check_output_folder(args.out, command="fleet", force=args.force, source=[],
                        subsets=(".cache",))  # fmt: skip
    with rep.session() as progress:
        res = run_fleet(
            args.logs, args.out, settings, scheduler=args.scheduler, n_workers=args.workers,
            threads_per_worker=args.threads_per_worker, spec=args.spec,
            target_task_bytes=task_bytes, plot=not args.no_plot,
            outlier_z=args.outlier_z, compare=args.compare, report=not args.no_report,
            drift_z=args.drift_z,
            split_channels=args.split_channels,
            progress=progress, argv=getattr(args, "argv", None),
        )  # fmt: skip
    summ = res.summary()
    if args.json:
        from imubounds.io.outputs import to_jsonable

        json.dump(to_jsonable(summ), sys.stdout, indent=2, allow_nan=False)
        print()
    elif not args.quiet:
        print(
            f"{summ['n_units']} units: {summ['n_ok']} analysed ({summ['n_cached']} from cache), "
            f"{summ['n_failed']} failed; {res.n_tasks} task{'s' * (res.n_tasks != 1)} on "
            f"{res.scheduler}, "
            f"{res.seconds:.1f} s"
        )
        for kind, terms in summ["terms_ieee"].items():
            for t in ("N", "B", "K"):
                s = terms.get(t, {})
                if s.get("n"):
                    print(
                        f"  {kind:<5} {t}: median {_g(s['median'])} {s['unit_ieee']}"
                        f"  (5-95 %: {_g(s['p05'])} .. {_g(s['p95'])}, {s['n']} axes)"
                    )
        stats = summ.get("statistics") or {}
        if stats.get("outliers"):
            print(f"outliers (|z| > {stats['threshold_z']:g}):")
            for o in stats["outliers"]:
                print(f"  {o['unit']} {o['channel']} {o['term']}: z={o['z']:+.1f} "
                      f"(x{o['ratio_to_median']:.3g} the median)")  # fmt: skip
        if "drift" in summ:
            d = summ["drift"]
            print(
                f"drift since {d['compared_with']}: {d['n_units_compared']} units compared, "
                f"{len(d['units_drifted'])} drifted (|z| > {d['threshold_z']:g})"
                + (f": {', '.join(d['units_drifted'])}" if d["units_drifted"] else "")
                + (f"; new: {', '.join(d['new_units'])}" if d["new_units"] else "")
                + (f"; gone: {', '.join(d['missing_units'])}" if d["missing_units"] else "")
            )
        if "spec" in summ:
            sp = summ["spec"]
            print(
                f"spec {sp['name']} ({sp['criterion']}): {sp['n_pass']} pass, {sp['n_fail']} fail"
                + (f" ({', '.join(sp['units_failing'])})" if sp["units_failing"] else "")
                + (f", {sp['n_undetermined']} undetermined (a term not resolved, its upper "
                   f"bound above the limit: {', '.join(sp['units_undetermined'])})"
                   if sp["units_undetermined"] else "")
            )
    rep.info(f"wrote {', '.join(res.files.values())} to {args.out}")
    if res.failed:
        # the failure summary is printed even with --quiet: the exit status alone says little
        print(f"imubounds: {len(res.failed)} of {summ['n_units']} units failed "
              f"(exit {EXIT_UNITS_FAILED}):", file=sys.stderr)  # fmt: skip
        for f in res.failed:
            print(f"  {f['unit']}: {f['error']}", file=sys.stderr)
        return EXIT_UNITS_FAILED
    return 0
