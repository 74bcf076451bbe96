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
    from imubounds.stationary.allan_grammar import DEFAULT_TAU_GRID, ESTIMATORS, TAU_GRAMMAR

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
        default=DEFAULT_TAU_GRID,
        metavar="GRID",
        help=f"tau grid: {TAU_GRAMMAR} (default: {DEFAULT_TAU_GRID})",
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
    p.add_argument("-v", "--verbose", action="store_true",
                   help="also print every note of the analysis (by default their count and "
                   "where they are: noise.json and report.html)")
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


def _aligned(head: list[str], rows: list[list[str]]) -> list[str]:
    widths = [max(len(h), *(len(r[i]) for r in rows)) for i, h in enumerate(head)]
    return ["  ".join(c.rjust(w) if i else c.ljust(w)
                      for i, (c, w) in enumerate(zip(r, widths, strict=True)))
            for r in [head, *rows]]


def table_lines(result: Any, flagged: set[str] | frozenset[str] = frozenset()) -> list[str]:
    """The answer: per sensor kind, the selected N, B, K of each channel in datasheet and
    SI units ('<' an upper bound); ``flagged`` channels get a '!' (a warning below)."""
    out: list[str] = []
    for kind in ("gyro", "accel"):
        chans = [(n, c.to_json()) for n, c in result.channels.items() if c.kind == kind]
        if not chans:
            continue
        sel0 = chans[0][1]["noise"]["selected"]
        head = [kind]
        for t in ("N", "B", "K"):
            head += [f"{t} [{sel0[t]['datasheet']['unit']}]", f"{t} [{sel0[t]['unit']}]"]
        rows = []
        for name, js in chans:
            sel = js["noise"]["selected"]
            cells = [name + (" !" if name in flagged else "")]
            for t in ("N", "B", "K"):
                e = sel[t]
                cells += [_fmt(e["datasheet"]["value"], e["status"]), _fmt(e["value"], e["status"])]
            rows.append(cells)
        out += _aligned(head, rows)
    return out


def kalibr_lines(doc: dict[str, Any]) -> list[str]:
    """The filter parameters of imu.yaml (Kalibr / OpenVINS: the worst axis, SI), one line
    per sensor after a title line."""
    from imubounds.export import KALIBR_KEYS, filter_noise, kalibr_values

    fn = filter_noise(doc)
    vals = kalibr_values(fn)
    out = [f"filter parameters (imu.yaml: Kalibr, OpenVINS; the worst axis; update_rate "
           f"{fn.rate_hz:g} Hz; every format: imubounds export):"]
    for kind in ("gyro", "accel"):
        cells = []
        for key, k, term, unit in KALIBR_KEYS:
            if k == kind and key in vals:
                v, ax = vals[key]
                cells.append(f"{key} {_fmt(v, getattr(ax, f'{term}_status'))} {unit} "
                             f"({ax.channel})")
        if cells:
            out.append("  " + "   ".join(cells))
    return out


def bounds_lines(result: Any) -> list[str]:
    """The same terms in IEEE 952 units, sigma_min, the per-sample bound and the 95 %
    random-walk growth over the run."""
    out: list[str] = []
    for kind in ("gyro", "accel"):
        chans = [(n, c.to_json()) for n, c in result.channels.items() if c.kind == kind]
        if not chans:
            continue
        js0 = chans[0][1]
        sel0 = js0["noise"]["selected"]
        head = [kind] + [f"{t} [{sel0[t]['ieee']['unit']}]" for t in ("N", "B", "K")]
        head += [f"sigma_min [{sel0['sigma_min']['datasheet']['unit']}]",
                 f"{js0['bound']['k']:g}*sigma_c [{js0['unit']}]",
                 f"RW95 [{js0['random_walk_95']['datasheet']['unit']}]"]
        rows = []
        for name, js in chans:
            sel = js["noise"]["selected"]
            sm = sel["sigma_min"]
            rows.append([name, *(_fmt(sel[t]["ieee"]["value"], sel[t]["status"])
                                 for t in ("N", "B", "K")),
                         f"{_fmt(sm['datasheet']['value'])} @{sm['tau_s']:.3g}s",
                         _fmt(js["bound"]["value"]),
                         _fmt(js["random_walk_95"]["datasheet"]["value"])])
        out += _aligned(head, rows)
    return out


def answer_lines(result: Any, doc: dict[str, Any], flagged: set[str]) -> list[str]:
    """What ``imubounds static`` prints first: the N/B/K table, the filter parameters and
    the legend; then the IEEE 952 units and the bounds."""
    est = result.settings.estimator
    legend = (f"selected terms ({result.settings.terms_from} preferred) of the {est} curve; "
              "'<' = upper bound (not resolved by the log)"
              + ("; '!' = see the warnings below" if flagged else ""))
    return [*table_lines(result, flagged), *kalibr_lines(doc), legend, "",
            *bounds_lines(result),
            "sigma_min = lowest point of the curve; RW95 = 1.96*N*sqrt(T) over the run "
            "(integrated error)"]


def print_table(result: Any) -> None:
    print("\n".join(answer_lines(result, result.to_json(), set())))


class Console:
    """What ``imubounds static`` prints, in the order a reader wants it: the answer (the
    N/B/K table and the filter parameters, stdout), then the warnings and the notes
    (stderr: every warning; the notes counted, all of them with ``--verbose``), then the
    files written. Collected while the work runs (a progress line may be on the terminal)
    and printed when it is done; the warnings also when it fails."""

    def __init__(self, args: argparse.Namespace) -> None:
        self.args = args
        self.info: list[str] = []  # before the answer: what was read
        self.answer: list[str] = []
        self.warnings: list[str] = []
        self.notes: list[str] = []

    def flush(self, written: list[str] | None) -> None:
        a = self.args
        rep = Reporter(a.quiet)
        for line in self.info:
            rep.info(line)
        if a.json:
            pass  # the JSON summary is already on stdout
        elif not a.quiet and self.answer:
            print("\n".join(self.answer))
        for w in self.warnings:
            rep.warn(w)
        if a.verbose:
            for n in self.notes:
                rep.info(n)
        elif self.notes:
            rep.info(f"{len(self.notes)} note(s) on the analysis (how each term was read, "
                     "fits, decimation, models) in noise.json (channels.<ch>.notes, "
                     "noise.fit.notes, noise.slope.notes, models.notes) and report.html; "
                     "--verbose prints them")
        if written is not None:
            rep.info(f"wrote {', '.join(written)} to {a.out}")


def run(args: argparse.Namespace) -> int:
    from imubounds.io.outputs import OutputSet

    con = Console(args)
    written: list[str] | None = None
    try:
        # The output directory is locked and checked before the analysis, not after it;
        # the results land in it complete or not at all.
        with OutputSet(args.out, force=args.force, inputs=[args.log], command="static") as outset:
            outset.check(["noise.json", "imu.yaml", "allan.png", "allan.svg", "report.html"])
            written = _run(args, outset, con)
    finally:
        con.flush(written)
    return 0


def _step_names(args: argparse.Namespace) -> list[str]:
    return ["reading the log", "analysing", "writing noise.json and imu.yaml",
            *([] if args.no_plot else ["drawing the figures"]),
            *([] if args.no_report else ["writing the report"])]


def _run(args: argparse.Namespace, outset: Any, con: Console) -> list[str]:
    with _frozen_heap(), Reporter(args.quiet).steps(
        "imubounds static", len(_step_names(args))
    ) as steps:
        return _analyse_and_write(args, outset, con, steps)


def _settings(args: argparse.Namespace) -> Any:
    from imubounds.stationary.pipeline import StaticSettings

    models = (
        ()
        if args.models.strip().lower() in ("", "none")
        else parse_list(args.models, MODELS, "--models")
    )
    return StaticSettings(
        taus=parse_taus(args.tau),
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


def _analyse_and_write(
    args: argparse.Namespace, outset: Any, con: Console, steps: Any
) -> list[str]:
    import imubounds.io.table  # noqa: F401 - the reader, before the import thread starts
    from imubounds.io.outputs import write_json, write_text
    from imubounds.stationary.routing import format_bytes, parse_memory, route_outofcore

    parse_taus(args.tau)  # a bad grid is refused before the log is read
    channels = [c.strip() for c in args.channels.split(",")] if args.channels else None
    steps.step("reading the log")
    with _importing(_later_imports(args)):  # while the log is routed and read
        big = route_outofcore(
            args.log, args.max_memory, force=args.out_of_core, channels=channels,
            **_open_kwargs(args),
        )  # fmt: skip
        log = read_log_from_args(args.log, args) if big is None else None
    _freeze_heap()
    from imubounds.stationary.pipeline import analyse_static

    settings = _settings(args)
    if big is not None and args.robust:
        from imubounds.errors import OptionError

        raise OptionError(
            "--robust needs the samples in memory; this log takes the out-of-core path "
            "(raise --max-memory or drop --robust)"
        )
    steps.step("analysing")
    if big is not None:
        from imubounds.stationary.stream import analyse_static_outofcore

        con.info.append(
            f"out-of-core: {big.source}, channels {', '.join(big.channels)} at {big.rate_hz:g} Hz,"
            f" data buffers <= {format_bytes(parse_memory(args.max_memory))}"
        )
        result = analyse_static_outofcore(
            big, settings, channels=channels, memory_limit=args.max_memory,
            tmpdir=args.tmpdir, progress=steps.sub,
        )  # fmt: skip
        con.warnings += list(big.warnings)  # after the pass: the stream's checks add to them
        con.notes += list(result.notes)
    else:
        assert log is not None
        con.warnings += list(log.warnings)
        con.info.append(
            f"read {log.source}: {log.n_samples} samples at {log.rate_hz:g} Hz "
            f"({log.duration_s / 3600:.3g} h), channels {', '.join(log.channel_names())}"
        )
        result = analyse_static(log, settings, channels=channels, progress=steps.sub)
    steps.step("writing noise.json and imu.yaml")
    outdir = outset.staging
    doc = result.to_json()
    write_json(outdir / "noise.json", doc)
    write_text(outdir / "imu.yaml", result.kalibr_yaml(doc))
    outset.record(getattr(args, "argv", None), command_name="static")
    written = ["noise.json", "imu.yaml", "run.json"]
    if not args.no_plot:
        steps.step("drawing the figures")
        gc.freeze()  # the result too: the figures' passes skip it (and the forked child's)
        with steps.paused():  # one thread: the figures are drawn in a forked child
            written += save_figures(result, outdir)
    flagged: set[str] = set()
    for name, ch in result.channels.items():
        if ch.warnings:
            flagged.add(name)
        con.warnings += list(ch.warnings)
        con.notes += [f"{name}: {n}" for n in ch.notes + ch.slope.notes + ch.fit.notes]
        if ch.models is not None:
            con.notes += [f"{name}: {n}" for n in getattr(ch.models, "notes", [])]
    flagged |= {n for n in result.channels for w in con.warnings if w.startswith(f"{n}:")}
    if args.json:
        from imubounds.io.outputs import to_jsonable

        json.dump(to_jsonable(summary(result)), sys.stdout, indent=2, allow_nan=False)
        print()
    else:
        con.answer = answer_lines(result, doc, flagged)
    if not args.no_report:
        steps.step("writing the report")
        from imubounds.report.html import write_report

        write_report(outdir)
        written.append("report.html")
    return written
