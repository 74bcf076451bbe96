"""``imubounds static LOG``: stationary noise characterisation of a static IMU log."""

from __future__ import annotations

import argparse
import atexit
import gc
import importlib
import json
import math
import os
import sys
import threading
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
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
    positive_int,
    probability,
    read_log_from_args,
    tau_grid,
)

MODELS = ("gm", "ar")


def register(sub: Any) -> None:
    from imubounds.stationary.allan_grammar import ESTIMATORS, TAU_GRAMMAR

    p = sub.add_parser(
        "static",
        help="Allan variance, noise terms and stationary bounds of a static log",
        description="Characterise a static IMU log: Allan-family deviation with confidence "
        "intervals and the noise identified at each tau, IEEE 952 noise terms (Q, N, B, K, R) "
        "by a robust weighted fit and by the slope read-off (each term where it lives), the "
        "terms selected for bounds (an unresolved term enters as its upper bound, never 0), "
        "sigma_min and B in both conventions, spike detection, Gauss-Markov and AR models "
        "checked against the curve, and the stationary per-sample bound and random-walk "
        "growth. Writes noise.json, imu.yaml, allan.png/.svg and report.html into the "
        "output directory.",
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
        metavar="GRID",
        help=f"tau grid: {TAU_GRAMMAR} (default: octave)",
    )
    p.add_argument(
        "--estimator",
        choices=ESTIMATORS,
        default="overlapping",
        help="Allan-family estimator (default: overlapping); the terms use its own factors",
    )
    p.add_argument(
        "--robust",
        action="store_true",
        help="outlier-resistant Allan curve (spikes interpolated, clipped mean of the "
        "squared differences); the plain curve is kept in noise.json for comparison",
    )
    p.add_argument(
        "--spike-threshold",
        type=positive_float,
        default=8.0,
        metavar="Z",
        help="robust z above which a sample counts as a spike (default 8)",
    )
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
        help="factor k of the per-sample bound k*sigma_c (default 3)",
    )
    p.add_argument(
        "--avg-time",
        type=positive_float,
        metavar="S",
        help="averaging time t of sigma_c in s (default: log length)",
    )
    p.add_argument(
        "--run-hours",
        type=positive_float,
        metavar="H",
        help="run length T of the 95%% random-walk growth in hours (default: log length)",
    )
    p.add_argument(
        "--terms-from",
        choices=("fit", "slope"),
        default="fit",
        help="estimate preferred for the selected terms (bounds, imu.yaml); default fit",
    )
    p.add_argument("--models", default="gm,ar", help="stochastic models to fit: gm,ar (or 'none')")
    p.add_argument(
        "--ar-max-order",
        type=positive_int,
        default=20,
        metavar="P",
        help="largest AR order tried when looking for an AR model that follows the curve "
        "(default 20)",
    )
    p.add_argument(
        "--cut-warmup",
        action="store_true",
        help="drop the warm-up (a bias settling exponentially after power-on, detected per "
        "channel) before the analysis: each channel from the end of its own warm-up "
        "(the upper end of its interval); channels without one are not cut",
    )
    p.add_argument("--channels", help="only these channels, e.g. gyro_z,accel_x")
    p.add_argument("--no-plot", action="store_true", help="skip the figures")
    p.add_argument("--no-report", action="store_true", help="skip DIR/report.html")
    p.add_argument("--json", action="store_true", help="print the summary as JSON on stdout")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress or messages on stderr")
    add_outofcore_options(p)
    add_log_options(p)
    p.add_argument(
        "--allow-unusual-rate",
        action="store_true",
        help="accept a sample rate outside 0.5 Hz..100 kHz (refused by default: a time "
        "column in ms or us labelled s gives such a rate)",
    )
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
        "unusual_rate": args.allow_unusual_rate,
    }


def _later_imports(args: argparse.Namespace) -> list[str]:
    """The heavy modules the analysis and the outputs import after the log is read."""
    mods = ["imubounds.stationary.pipeline", "scipy.optimize", "imubounds.stationary.models"]
    if not args.no_plot:
        mods += ["matplotlib.figure", "matplotlib.backends.backend_agg",
                 "imubounds.report.static_plots"]  # fmt: skip
    if not args.no_report:
        mods.append("imubounds.report.html")
    return mods


@contextmanager
def _importing(modules: Sequence[str]) -> Iterator[None]:
    """Import ``modules`` in another thread while the body runs (routing and reading
    the log: decompressing and parsing release the GIL), about a second of imports
    that would otherwise wait for the read; the thread is joined on leaving.

    The reader's modules are imported before (``_run``). An import that fails in the
    thread is left to fail again, with its error, where the module is used. Two
    threads importing the same module wait for each other, which cannot deadlock as
    the package has no import cycle (tests/test_structure.py).
    """

    def work() -> None:
        for name in modules:
            try:
                importlib.import_module(name)
            except Exception:  # noqa: BLE001 - raised again at the real import
                return
        _warm_numba()

    thread = threading.Thread(target=work, name="imubounds-imports", daemon=True)
    thread.start()
    try:
        yield
    finally:
        thread.join()


_FREEZE_AT_EXIT: list[bool] = []  # whether gc.freeze is registered with atexit


@contextmanager
def _frozen_heap() -> Iterator[None]:
    """The cyclic garbage collector off while the modules are imported and the log is
    read, and the objects alive then (modules, numba's and matplotlib's tables) kept
    out of its later passes (:func:`gc.freeze`, again before the figures).

    Without this its full passes walked the ~10^6 objects of the imported libraries
    (0.2-0.4 CPU s of a run of ``imubounds static``), in the forked child of
    :func:`in_parallel` too; the objects made by the analysis and the figures are
    collected as before. Restored on leaving (collector on; objects unfrozen unless the
    caller had frozen some: a freeze cannot be undone in part).

    At the interpreter's exit the heap is frozen again (``atexit``, which runs before
    the interpreter's own final passes over every object: 0.25-0.35 CPU s of the
    command): what is left is freed by reference counting or by the exit itself.
    """
    if not _FREEZE_AT_EXIT:
        atexit.register(gc.freeze)
        _FREEZE_AT_EXIT.append(True)
    was_enabled, was_frozen = gc.isenabled(), gc.get_freeze_count() > 0
    gc.disable()
    try:
        yield
    finally:
        if not was_frozen:
            gc.unfreeze()
        if was_enabled:
            gc.enable()


def _freeze_heap() -> None:
    """Move the objects alive now out of the collector's passes and turn it on."""
    gc.freeze()
    gc.enable()


def _warm_numba() -> None:
    """Call one compiled kernel on one sample, in the import thread: numba's first call
    loads its CPU target (type registries, lowering, ~0.2 s), which then overlaps the
    read instead of starting the analysis; the kernel's machine code comes from
    numba's cache as at its real first call. A failure is left to the real call."""
    try:
        from imubounds.stationary.allan import warm_kernels

        warm_kernels()
    except Exception:  # noqa: BLE001 - raised again, if at all, where the kernels run
        return


def save_figures(result: Any, outdir: Path) -> list[str]:
    """allan.png, allan.svg and (when a channel is flagged) stationarity.png, two at a
    time on a machine with two cores (:func:`in_parallel`); returns the names written."""
    from imubounds.report.static_plots import (
        allan_figure,
        needs_stationarity_figure,
        save_figure,
        stationarity_figure,
    )

    fig = allan_figure(result)
    if needs_stationarity_figure(result):
        in_parallel(
            lambda: save_figure(fig, outdir / "allan"),
            lambda: save_figure(stationarity_figure(result), outdir / "stationarity", ("png",)),
        )
        return ["allan.png", "allan.svg", "stationarity.png"]
    in_parallel(
        lambda: save_figure(fig, outdir / "allan", ("png",)),
        lambda: save_figure(fig, outdir / "allan", ("svg",)),
    )
    return ["allan.png", "allan.svg"]


def in_parallel(first: Callable[[], object], second: Callable[[], object]) -> None:
    """Run ``second`` in a forked child while ``first`` runs here, then wait for it.

    Drawing a figure is single-threaded Python (matplotlib), so two figures take two
    cores only in two processes; they write their own files, and the child returns
    nothing else. Without ``fork``, on one core, or with other Python threads alive
    (a fork copies only the calling thread), the two run one after the other. A child
    that fails is run again here, so that its error is raised with its traceback.
    """
    if not hasattr(os, "fork") or (os.cpu_count() or 1) < 2 or threading.active_count() > 1:
        first()
        second()
        return
    sys.stdout.flush()
    sys.stderr.flush()
    pid = os.fork()
    if pid == 0:  # the child: draw, write, leave without running the parent's cleanup
        code = 1
        try:
            second()
            code = 0
        finally:
            os._exit(code)
    try:
        first()
    finally:
        _, status = os.waitpid(pid, 0)
    if status != 0:
        second()


def summary(result: Any) -> dict[str, Any]:
    """A compact summary per channel: the selected terms (SI, IEEE 952 and datasheet
    units, status), sigma_min, the per-sample bound with its k and the random-walk growth."""
    out: dict[str, Any] = {}
    for name, ch in result.channels.items():
        js = ch.to_json()
        sel = js["noise"]["selected"]
        out[name] = {
            "unit": js["unit"],
            **{
                t: {
                    k: sel[t][k]
                    for k in ("value", "unit", "status", "from", "ieee", "datasheet")
                    if k in sel[t]
                }
                for t in ("Q", "N", "B", "K", "R")
            },
            "sigma_min": sel["sigma_min"],
            "sigma_c": ch.sigma_c,
            "bound": js["bound"],
            "random_walk_95": js["random_walk_95"],
            "spikes": js["spikes"].get("events"),
        }
    return out


def _fmt(v: float | None, status: str | None = None) -> str:
    if v is None or not math.isfinite(v):
        return "-"
    mark = {"upper_bound": "<", "not_observed": "?"}.get(status or "", "")
    return f"{mark}{v:.3g}"


def table_lines(result: Any) -> list[str]:
    """The terminal table: selected N, B, K (IEEE 952 and datasheet units), sigma_min,
    the per-sample bound and the random-walk growth; '<' marks an upper bound."""
    rows = []
    for name, ch in result.channels.items():
        js = ch.to_json()
        sel = js["noise"]["selected"]
        cells = [name]
        for t in ("N", "B", "K"):
            e = sel[t]
            cells.append(_fmt(e["ieee"]["value"], e["status"]))
            cells.append(_fmt(e["datasheet"]["value"], e["status"]))
        sm = sel["sigma_min"]
        cells.append(f"{_fmt(sm['datasheet']['value'])} @{sm['tau_s']:.3g}s")
        cells.append(_fmt(js["bound"]["value"]))
        cells.append(_fmt(js["random_walk_95"]["datasheet"]["value"]))
        rows.append((ch.kind, cells))
    out: list[str] = []
    for kind in ("gyro", "accel"):
        krows = [c for k, c in rows if k == kind]
        if not krows:
            continue
        ch0 = next(c for c in result.channels.values() if c.kind == kind).to_json()
        sel0 = ch0["noise"]["selected"]
        head = ["channel"]
        for t in ("N", "B", "K"):
            head += [f"{t} [{sel0[t]['ieee']['unit']}]", f"{t} [{sel0[t]['datasheet']['unit']}]"]
        head.append(f"sigma_min [{sel0['sigma_min']['datasheet']['unit']}]")
        head.append(f"{ch0['bound']['k']:g}*sigma_c [{ch0['unit']}]")
        head.append(f"RW95 [{ch0['random_walk_95']['datasheet']['unit']}]")
        widths = [max(len(h), *(len(r[i]) for r in krows)) for i, h in enumerate(head)]
        out.append("  ".join(h.rjust(w) if i else h.ljust(w) for i, (h, w) in
                             enumerate(zip(head, widths, strict=True))))  # fmt: skip
        for r in krows:
            out.append("  ".join(c.rjust(w) if i else c.ljust(w) for i, (c, w) in
                                 enumerate(zip(r, widths, strict=True))))  # fmt: skip
        out.append("")
    est = result.settings.estimator
    out.append(
        f"selected terms (preferring the {result.settings.terms_from}) from the {est} curve; "
        "'<' = upper bound (not resolved); sigma_min = lowest point of the curve; "
        "RW95 = 1.96*N*sqrt(T) over the run (integrated error)"
    )
    return out


def print_table(result: Any) -> None:
    print("\n".join(table_lines(result)))


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
    with _frozen_heap():
        return _analyse_and_write(args, outset)


def _analyse_and_write(args: argparse.Namespace, outset: Any) -> list[str]:
    import imubounds.io.table  # noqa: F401 - the reader, before the import thread starts
    from imubounds.io.outputs import write_json, write_text
    from imubounds.stationary.routing import format_bytes, parse_memory, route_outofcore

    rep = Reporter(args.quiet)
    models = (
        ()
        if args.models.strip().lower() in ("", "none")
        else parse_list(args.models, MODELS, "--models")
    )
    taus = parse_taus(args.tau)
    channels = [c.strip() for c in args.channels.split(",")] if args.channels else None
    with _importing(_later_imports(args)):  # while the log is routed and read
        big = route_outofcore(
            args.log, args.max_memory, force=args.out_of_core, channels=channels,
            **_open_kwargs(args),
        )  # fmt: skip
        log = read_log_from_args(args.log, args) if big is None else None
    _freeze_heap()
    from imubounds.stationary.pipeline import StaticSettings, analyse_static

    settings = StaticSettings(
        taus=taus,
        estimator=args.estimator,
        confidence=args.confidence,
        k_sigma=args.k_sigma,
        averaging_time_s=args.avg_time,
        run_hours=args.run_hours,
        terms_from=args.terms_from,
        models=models,
        robust=args.robust,
        spike_threshold=args.spike_threshold,
        ar_max_order=args.ar_max_order,
        cut_warmup=args.cut_warmup,
    )
    if big is not None and args.robust:
        from imubounds.errors import OptionError

        raise OptionError(
            "--robust needs the samples in memory; this log takes the out-of-core path "
            "(raise --max-memory or drop --robust)"
        )
    if big is not None:
        from imubounds.stationary.stream import analyse_static_outofcore

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
        assert log is not None
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
        gc.freeze()  # the result too: the figures' passes skip it (and the forked child's)
        written += save_figures(result, outdir)
    for name, ch in result.channels.items():
        for w in ch.warnings:
            rep.warn(w)
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
