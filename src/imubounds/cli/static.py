"""``imubounds static LOG``: stationary noise characterisation of a static IMU log."""

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
    existing_dir,
    memory_size,
    parse_list,
    parse_taus,
    positive_float,
    probability,
    read_log_from_args,
    tau_grid,
)

ESTIMATORS = ("overlapping", "non-overlapping", "modified", "hadamard", "total")
MODELS = ("gm", "ar")


def register(sub: Any) -> None:
    p = sub.add_parser(
        "static",
        help="Allan variance, noise terms and stationary bounds of a static log",
        description="Characterise a static IMU log: Allan deviation with confidence intervals, "
        "IEEE 952 noise terms (Q, N, B, K, R) by slope read-off and by weighted fit, "
        "stationary per-sample bounds and 95 %% levels. Writes noise.json, imu.yaml, "
        "allan.png/.svg into the output directory.",
    )
    p.add_argument("log", help="static IMU log (CSV, CSV.gz, Parquet, ...)")
    p.add_argument(
        "-o", "--out", default="out", metavar="DIR", help="output directory (default: out)"
    )
    add_force_option(p)
    p.add_argument(
        "--tau",
        type=tau_grid,
        default="octave",
        help="tau grid: octave, decade, N log-spaced, or seconds '0.1,1,10'",
    )
    p.add_argument("--estimator", choices=ESTIMATORS, default="overlapping", help="Allan estimator")
    p.add_argument(
        "--confidence",
        type=probability,
        default=0.683,
        help="confidence level of the CIs (default 0.683)",
    )
    p.add_argument(
        "--k-sigma",
        type=positive_float,
        default=3.0,
        help="factor k of the per-sample bound k*sigma_c",
    )
    p.add_argument(
        "--avg-time",
        type=positive_float,
        metavar="S",
        help="averaging time t of sigma_c (default: log length)",
    )
    p.add_argument(
        "--run-hours",
        type=positive_float,
        metavar="H",
        help="run length T of the 95%% level (default: log length)",
    )
    p.add_argument(
        "--terms-from",
        choices=("fit", "slope"),
        default="fit",
        help="which estimate feeds bounds and imu.yaml",
    )
    p.add_argument("--models", default="gm,ar", help="stochastic models to fit: gm,ar (or 'none')")
    p.add_argument("--channels", help="only these channels, e.g. gyro_z,accel_x")
    p.add_argument("--no-plot", action="store_true", help="skip the figures")
    p.add_argument("--no-report", action="store_true", help="skip DIR/report.html")
    p.add_argument("--json", action="store_true", help="print the summary as JSON on stdout")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress or messages on stderr")
    add_outofcore_options(p)
    add_log_options(p)
    p.set_defaults(func=run)


def add_outofcore_options(p: argparse.ArgumentParser) -> None:
    """``--max-memory``, ``--out-of-core`` and ``--tmpdir`` (shared with ``fleet``)."""
    g = p.add_argument_group("large logs")
    g.add_argument(
        "--max-memory",
        type=memory_size,
        default="1GiB",
        metavar="SIZE",
        help="memory setting, e.g. 1GiB, 512MB: logs that would need more are analysed "
        "out-of-core, with data buffers bounded by SIZE (default 1GiB)",
    )
    g.add_argument(
        "--out-of-core", action="store_true", help="force the out-of-core (chunked) Allan path"
    )
    g.add_argument(
        "--tmpdir",
        type=existing_dir,
        metavar="DIR",
        help="where out-of-core phase files go (default: system temp)",
    )


def _open_kwargs(args: argparse.Namespace) -> dict[str, Any]:
    from imubounds.io import parse_column_map

    return {
        "rate_hz": args.rate,
        "columns": parse_column_map(args.columns) if args.columns else None,
        "gyro_unit": args.gyro_unit,
        "accel_unit": args.accel_unit,
        "time_unit": args.time_unit,
        "on_gap": args.on_gap,
        "gap_tolerance": args.gap_tolerance,
    }


def summary(result: Any) -> dict[str, Any]:
    """A compact summary: per channel the terms used, in SI and IEEE units, and the bounds."""
    out: dict[str, Any] = {}
    for name, ch in result.channels.items():
        js = ch.to_json(result.settings.k_sigma)
        terms = js["noise"][result.settings.terms_from]
        out[name] = {
            "unit": js["unit"],
            **{
                t: {"value": terms[t]["value"], "unit": terms[t]["unit"], "ieee": terms[t]["ieee"]}
                for t in ("Q", "N", "B", "K", "R")
            },
            "sigma_c": ch.sigma_c,
            "bound_3sigma": ch.bound,
            "level_95": ch.level_95,
        }
    return out


def _fmt(v: float | None) -> str:
    return "—" if v is None or not math.isfinite(v) else f"{v:.4g}"


def print_table(result: Any) -> None:
    terms_from = result.settings.terms_from
    print(f"noise terms ({terms_from}), IEEE 952 units; bounds in SI")
    header = (
        f"{'channel':<9}"
        + "".join(f"{t:>22}" for t in ("N", "B", "K"))
        + f"{'k*sigma_c':>14}{'95% level':>12}"
    )
    print(header)
    for name, ch in result.channels.items():
        js = ch.to_json(result.settings.k_sigma)["noise"][terms_from]
        cells = "".join(
            f"{_fmt(js[t]['ieee']['value']) + ' ' + js[t]['ieee']['unit']:>22}"
            for t in ("N", "B", "K")
        )
        unit = "rad/s" if name.startswith("gyro") else "m/s^2"
        print(f"{name:<9}{cells}{_fmt(ch.bound):>9} {unit:<5}{_fmt(ch.level_95):>11}")


def run(args: argparse.Namespace) -> int:
    from imubounds.io.outputs import OutputSet

    # The output directory is locked and checked before the analysis, not after it;
    # the results land in it complete or not at all.
    with OutputSet(args.out, force=args.force, inputs=[args.log]) as outset:
        outset.check(["noise.json", "imu.yaml", "allan.png", "allan.svg", "report.html"])
        written = _run(args, outset)
    Reporter(args.quiet).info(f"wrote {', '.join(written)} to {args.out}")
    return 0


def _run(args: argparse.Namespace, outset: Any) -> list[str]:
    from imubounds.io.outputs import write_json, write_text
    from imubounds.stationary.pipeline import StaticSettings, analyse_static
    from imubounds.stationary.stream import (
        analyse_static_outofcore,
        format_bytes,
        parse_memory,
        route_outofcore,
    )

    rep = Reporter(args.quiet)
    models = (
        ()
        if args.models.strip().lower() in ("", "none")
        else parse_list(args.models, MODELS, "--models")
    )
    settings = StaticSettings(
        taus=parse_taus(args.tau),
        estimator=args.estimator,
        confidence=args.confidence,
        k_sigma=args.k_sigma,
        averaging_time_s=args.avg_time,
        run_hours=args.run_hours,
        terms_from=args.terms_from,
        models=models,
    )
    channels = [c.strip() for c in args.channels.split(",")] if args.channels else None
    big = route_outofcore(
        args.log, args.max_memory, force=args.out_of_core, channels=channels, **_open_kwargs(args)
    )
    if big is not None:
        rep.info(
            f"out-of-core: {big.source}, channels {', '.join(big.channels)} at {big.rate_hz:g} Hz,"
            f" data buffers <= {format_bytes(parse_memory(args.max_memory))}"
        )
        with rep.session() as progress:
            result = analyse_static_outofcore(
                big,
                settings,
                channels=channels,
                memory_limit=args.max_memory,
                tmpdir=args.tmpdir,
                progress=progress,
            )
        for w in big.warnings:
            rep.warn(w)
        for note in result.notes:
            rep.info(note)
    else:
        log = read_log_from_args(args.log, args)
        for w in log.warnings:
            rep.warn(w)
        rep.info(
            f"read {log.source}: {log.n_samples} samples at {log.rate_hz:g} Hz "
            f"({log.duration_s / 3600:.3g} h), channels {', '.join(log.channel_names())}"
        )
        with rep.session() as progress:
            result = analyse_static(log, settings, channels=channels, progress=progress)
    outdir = outset.staging
    write_json(outdir / "noise.json", result.to_json())
    write_text(outdir / "imu.yaml", result.kalibr_yaml())
    outset.record(getattr(args, "argv", None), command_name="static")
    written = ["noise.json", "imu.yaml", "run.json"]
    if not args.no_plot:
        from imubounds.report.static_plots import allan_figure, save_figure

        save_figure(allan_figure(result), outdir / "allan")
        written += ["allan.png", "allan.svg"]
    for name, ch in result.channels.items():
        for note in ch.notes + ch.slope.notes + ch.fit.notes:
            rep.info(f"{name}: {note}")
        if ch.models is not None:
            for note in getattr(ch.models, "notes", []):
                rep.info(f"{name}: {note}")
    if args.json:
        json.dump(summary(result), sys.stdout, indent=2, default=float)
        print()
    elif not args.quiet:
        print_table(result)
    if not args.no_report:
        from imubounds.report.html import write_report

        write_report(outdir)
        written.append("report.html")
    return written
