"""The fleet driver: :func:`run_fleet` looks every unit up in the cache, plans the rest
into tasks, runs them on an executor (serial or Dask), and assembles and writes the
fleet's outputs (see :mod:`imubounds.stationary.fleet`)."""

from __future__ import annotations

import math
import time
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

from imubounds.errors import InputError, OptionError
from imubounds.stationary.fleet.cache import UnitCache, content_key
from imubounds.stationary.fleet.execute import Task, check_scheduler_address, open_executor
from imubounds.stationary.fleet.plan import plan_tasks, plan_work
from imubounds.stationary.fleet.result import FleetResult, rows_frame
from imubounds.stationary.fleet.settings import FleetSettings, Progress
from imubounds.stationary.fleet.sources import expand_globs, source_size, unit_names
from imubounds.stationary.fleet.spec import FleetSpec, check_spec, load_spec
from imubounds.stationary.fleet.unit import failed_result, merge_parts
from imubounds.stationary.fleet_stats import DEFAULT_DRIFT_Z, DEFAULT_OUTLIER_Z, STAT_TERMS

__all__ = ["REPORT_ADVICE", "run_fleet"]

REPORT_ADVICE = "move it away or use --no-report"


class _Units:
    """The units of one run: their content keys and cache lookups (client side, once per
    unit, as the run needs them), their results as they arrive, and the counts the
    progress shows."""

    def __init__(
        self,
        sources: list[str],
        names: list[str],
        settings: FleetSettings,
        cache: UnitCache,
        progress: Progress,
    ) -> None:
        self.sources = sources
        self.names = names
        self.settings = settings
        self.cache = cache
        self.progress = progress
        self.results: dict[int, dict[str, Any]] = {}
        self.keys: dict[int, str | None] = {}
        self.parts: dict[int, list[dict[str, Any] | None]] = {}
        self.counts = {"hashed": 0, "cached": 0, "failed": 0, "done": 0}

    def __len__(self) -> int:
        return len(self.sources)

    def lookup(self, i: int) -> bool:
        """Content key and cache lookup of unit ``i`` (once); whether it needs analysis."""
        if i in self.keys:
            return i not in self.results
        src = self.sources[i]
        try:
            key: str | None = content_key(src, self.settings)
        except (OSError, InputError) as err:
            key = None
            if isinstance(err, InputError):  # names the source and what is wrong
                error = str(err)
            else:
                error = f"{src}: cannot read ({err.strerror or err})"
            self.results[i] = failed_result(src, self.names[i], error)
            self.counts["failed"] += 1
        self.keys[i] = key
        if key is not None:
            hit = self.cache.load(key, src, self.names[i])
            if hit is not None:
                self.results[i] = hit
                self.counts["cached"] += 1
        self.counts["hashed"] += 1
        self.progress("hash", self.counts["hashed"], len(self.sources))
        return i not in self.results

    def to_do(self) -> int:
        """Units to analyse, as far as known (a pipelined total can still fall)."""
        return len(self.sources) - self.counts["cached"] - self.counts["failed"]

    def collect(self, items: list[tuple[int, int]], batch: list[dict[str, Any]]) -> None:
        """Take a task's results; a unit whose parts are all in is merged, kept and, when
        analysed, cached."""
        for (i, k), res in zip(items, batch, strict=True):
            self.parts[i][k] = res
            if all(r is not None for r in self.parts[i]):
                whole = merge_parts([r for r in self.parts[i] if r is not None])
                whole["unit"] = self.names[i]
                self.results[i] = whole
                self.counts["done"] += 1
                ckey = self.keys[i]
                if whole["status"] == "ok" and ckey is not None:
                    self.cache.store(ckey, whole)
        self.progress("units", self.counts["done"], self.to_do())

    def tasks(
        self, groups: list[list[int]], work: list[tuple[int, tuple[int, int] | None]],
        units: list[int],
    ) -> Iterator[Task]:  # fmt: skip
        """The tasks of ``groups`` (of ``work`` items over ``units``), each with the items
        still to analyse (looked up as the task is formed); tasks left empty are skipped."""
        for g in groups:
            items: list[tuple[int, int]] = []
            args: list[tuple[str, str, tuple[int, int] | None]] = []
            for w in g:
                j, part = work[w]
                i = units[j]
                if not self.lookup(i):
                    continue
                self.parts.setdefault(i, [None] * (part[1] if part else 1))
                items.append((i, part[0] if part is not None else 0))
                args.append((self.sources[i], self.names[i], part))
            if items:
                yield items, args

    def ordered(self) -> list[dict[str, Any]]:
        """Every unit's result in source order, named."""
        ordered = [self.results[i] for i in range(len(self.sources))]
        for i, r in enumerate(ordered):
            r["unit"] = self.names[i]
        return ordered


def _look_ahead(units: _Units, local: bool, pipelined: bool) -> tuple[bool, bool]:
    """``(need, lone)``: whether any unit needs analysis, and whether exactly one does and
    would otherwise start a local cluster (then it runs in this process).

    Pipelined (Dask without channel splits), units are looked up only up to the first
    ones to analyse: the client hashes the later ones while the workers analyse; a fleet
    all cached starts no cluster, and a local cluster is started for two units or more
    only (one unit gains nothing from it and would wait seconds for the workers'
    start-up). Otherwise every unit is looked up first."""
    if not pipelined:
        return any([units.lookup(i) for i in range(len(units))]), False  # noqa: C419
    misses = 0
    for i in range(len(units)):
        misses += units.lookup(i)
        if misses >= (2 if local else 1):
            return True, False
    return misses > 0, local and misses == 1


def _analyse(
    units: _Units,
    settings: FleetSettings,
    *,
    client: Any,
    scheduler: str | None,
    n_workers: int,
    threads_per_worker: int,
    target_task_bytes: int,
    split_channels: bool,
    min_split_bytes: int,
    numba_threads: int | None,
) -> tuple[str, int]:
    """Analyse the units not cached (units, or channel parts of long logs, grouped into
    tasks); returns ``(where they ran, number of tasks)``; ``("", 0)`` when none was."""
    serial = client is None and not scheduler and n_workers == 0
    local = client is None and not scheduler  # a local cluster would be started here
    pipelined = not serial and not split_channels
    need, lone = _look_ahead(units, local, pipelined)
    if not need:
        return "", 0
    with open_executor(settings, serial=serial or lone, lone=lone, client=client,
                       scheduler=scheduler, n_workers=n_workers,
                       threads_per_worker=threads_per_worker,
                       numba_threads=numba_threads) as executor:  # fmt: skip
        # pipelined: tasks planned over every unit, a cached one dropped from its task
        todo = [i for i in range(len(units)) if pipelined or i not in units.results]
        sizes = [source_size(units.sources[i]) for i in todo]
        work: list[tuple[int, tuple[int, int] | None]] = [(j, None) for j in range(len(sizes))]
        if split_channels:
            work = plan_work(sizes, executor.workers, min_split_bytes)
        wsizes = [sizes[j] // (p[1] if p else 1) for j, p in work]
        groups = plan_tasks(wsizes, executor.workers, target_task_bytes)
        n_tasks = executor.run(units.tasks(groups, work, todo), units.collect)
        return executor.name, n_tasks


def _check_options(
    spec: FleetSpec | str | Path | None, outlier_z: float, drift_z: float, n_workers: int,
    scheduler: str | None,
) -> FleetSpec | None:  # fmt: skip
    """The spec read, and the thresholds, worker count and scheduler address checked,
    before any work."""
    if spec is not None and not isinstance(spec, FleetSpec):
        spec = load_spec(spec)
    if not (math.isfinite(outlier_z) and outlier_z > 0):
        raise OptionError(f"outlier threshold must be a positive number, got {outlier_z}")
    if not (math.isfinite(drift_z) and drift_z > 0):
        raise OptionError(f"drift threshold must be a positive number, got {drift_z}")
    if n_workers < 0:
        raise OptionError(f"number of workers must be >= 0, got {n_workers}")
    if scheduler:
        check_scheduler_address(scheduler)
    return spec


def _add_drift_columns(table: Any, drift: Any) -> None:
    """Each term's previous value, ratio, difference, z and flag as columns of the table."""
    for t in STAT_TERMS:
        sub = drift[drift["term"] == t].set_index(["unit", "channel"])
        rows_key = list(zip(table["unit"], table["channel"], strict=True))
        for col, src_col in ((f"{t}_prev", "previous"), (f"{t}_ratio", "ratio"),
                             (f"{t}_diff", "diff"), (f"{t}_drift_z", "z")):  # fmt: skip
            m = sub[src_col].to_dict()
            table[col] = [m.get(k, math.nan) for k in rows_key]
        flags = sub["drifted"].to_dict()
        table[f"{t}_drifted"] = [bool(flags.get(k, False)) for k in rows_key]


def _assemble(
    ordered: list[dict[str, Any]],
    settings: FleetSettings,
    spec: FleetSpec | None,
    *,
    outlier_z: float,
    drift_z: float,
    compare: str | Path | None,
    previous: Any,
) -> FleetResult:
    """The fleet table with its statistics, outliers, drift and pass/fail."""
    from imubounds.stationary.fleet_stats import (
        compare_fleets,
        fleet_statistics,
        previous_confidence,
    )

    table = rows_frame(ordered)
    stats = fleet_statistics(table, outlier_z, settings.confidence)
    for col in stats.scores.columns:
        table[col] = stats.scores[col]
    table["outlier"] = stats.scores[[f"{t}_outlier" for t in STAT_TERMS]].any(axis=1)
    drift = None
    new_units: list[str] = []
    missing_units: list[str] = []
    if previous is not None and compare is not None:
        drift, new_units, missing_units = compare_fleets(
            table, previous, confidence=settings.confidence,
            previous_confidence=previous_confidence(compare), threshold=drift_z,
        )  # fmt: skip
        _add_drift_columns(table, drift)
    curves = {r["unit"]: r.get("curves", {}) for r in ordered if r["status"] == "ok"}
    passfail = check_spec(table, spec) if spec is not None else None
    return FleetResult(
        table=table, curves=curves, settings=settings, passfail=passfail, spec=spec,
        stats=stats, drift=drift, compared_with=str(compare) if compare is not None else "",
        new_units=new_units, missing_units=missing_units, drift_z=float(drift_z),
    )  # fmt: skip


def _write_outputs(
    result: FleetResult,
    out: Path,
    *,
    plot: bool,
    report: bool,
    argv: Sequence[str] | None,
    t_start: float,
    n_units: int,
) -> None:
    """Write the fleet's files into ``out`` (``fleet.json`` and, for a command,
    ``run.json`` last)."""
    from imubounds.io.outputs import write_json, write_with

    table, passfail, drift = result.table, result.passfail, result.drift
    files = {"table": "fleet.parquet", "summary": "fleet.json"}
    if argv is not None:  # the old set is no longer complete (its files stay imubounds')
        from imubounds.io.outputs import listed_files, record_written_files

        earlier = listed_files(out)
        (out / "run.json").unlink(missing_ok=True)
    write_with(out / "fleet.parquet", lambda p: table.to_parquet(p, index=False))
    if passfail is not None:
        write_with(out / "passfail.csv", lambda p: passfail.to_csv(p, index=False))
        files["passfail"] = "passfail.csv"
    if drift is not None:
        write_with(out / "drift.csv", lambda p: drift.to_csv(p, index=False))
        files["drift"] = "drift.csv"
    if plot and result.curves:
        from imubounds.report.fleet_plots import save_fleet_figures

        files.update(save_fleet_figures(result, out))
    if report:
        files["report"] = "report.html"
    result.files = files
    result.seconds = time.perf_counter() - t_start
    write_json(out / "fleet.json", result.summary())
    record: dict[str, Any] = {"command_name": "fleet", "n_units": n_units,
              "n_failed": len(result.failed)}  # fmt: skip
    if report:
        from imubounds.io.outputs import output_file
        from imubounds.report.html import build_report

        if argv is not None:  # the report shows the command (not yet a complete set)
            record_written_files(out, argv, [*files.values(), "run.json"], earlier=earlier,
                                 complete=False, **record)  # fmt: skip
        text = build_report(out)
        with output_file(out / "report.html", option="-o", advice=REPORT_ADVICE) as tmp:
            tmp.write_text(text, encoding="utf-8")
    if argv is not None:
        record_written_files(out, argv, [*files.values(), "run.json"], earlier=earlier,
                             **record)  # fmt: skip


def run_fleet(
    patterns: Sequence[str | Path],
    outdir: str | Path,
    settings: FleetSettings | None = None,
    *,
    scheduler: str | None = None,
    client: Any = None,
    n_workers: int = 2,
    threads_per_worker: int = 1,
    spec: FleetSpec | str | Path | None = None,
    target_task_bytes: int = 4 << 20,
    split_channels: bool = False,
    min_split_bytes: int = 4 << 20,
    numba_threads: int | None = None,
    outlier_z: float = DEFAULT_OUTLIER_Z,
    drift_z: float = DEFAULT_DRIFT_Z,
    compare: str | Path | None = None,
    plot: bool = True,
    report: bool = False,
    progress: Progress | None = None,
    argv: Sequence[str] | None = None,
) -> FleetResult:
    """Characterise every log matching ``patterns``; write the fleet outputs.

    Parameters
    ----------
    patterns : sequence of str
        Glob patterns, paths or fsspec URLs (``s3://bucket/units/*.csv.gz``) of
        the unit logs (one unit per file). Units are named by their path
        relative to the common folder of all (:func:`unit_names`).
    outdir : path
        Output directory (``fleet.parquet``, ``fleet.json``, ``fleet.png``,
        ``fleet_stats.png``, ``passfail.csv``, ``drift.csv``, ``.cache/``).
    settings : FleetSettings
        Analysis settings.
    scheduler : str, optional
        Address of a running ``dask.distributed`` scheduler; default a new
        ``LocalCluster(n_workers, threads_per_worker)``, closed on return.
    client : dask.distributed.Client, optional
        Use this client (takes precedence over ``scheduler``).
    n_workers : int
        Workers of the local cluster; ``0`` runs the units one after the other
        in this process, without Dask.
    spec : FleetSpec or path, optional
        Datasheet limits for the pass/fail table.
    target_task_bytes : int
        Task sizing (:func:`plan_tasks`).
    split_channels : bool
        With fewer units than workers, split logs of at least ``min_split_bytes``
        by channel (:func:`plan_work`). Off by default: each part parses the whole
        log again, and parsing (multi-threaded already) is over half of a long
        CSV.gz unit's time: measured slower than one task (0.66-0.83x, a 4 h
        log on 2 workers). It can pay with many workers per unit.
    numba_threads : int, optional
        Threads of the Allan kernels in each task; on Dask by default the cores
        of this machine shared among the worker threads when all workers run
        here, else 1 (the fleet is parallel across units: more kernel threads
        than cores only contend); numba's default in-process.
    outlier_z : float
        ``|z|`` above which a unit is flagged (:mod:`.fleet_stats`).
    drift_z : float
        ``|z|`` of a change since ``compare`` above which a unit's term has drifted.
    compare : path, optional
        Directory (or ``fleet.parquet``) of a previous fleet run: drift table.
    report : bool
        Also write ``report.html`` (:func:`imubounds.report.html.write_report`).
    progress : callable(stage, done, total), optional
        ``"hash"`` then ``"units"`` (interleaved on Dask).
    argv : sequence of str, optional
        The command line (``imubounds`` arguments) that asked for this run: then
        ``run.json`` (command, version, platform, the files written) is written
        last, as by every command (the library call alone writes none).

    Returns
    FleetResult
    """
    from imubounds.io.outputs import ensure_dir
    from imubounds.stationary.fleet_stats import read_previous

    t_start = time.perf_counter()
    settings = settings or FleetSettings()
    settings.check()
    spec = _check_options(spec, outlier_z, drift_z, n_workers, None if client else scheduler)
    previous = read_previous(compare) if compare is not None else None
    sources = expand_globs([str(p) for p in patterns])
    names = unit_names(sources)
    out = ensure_dir(outdir)
    if report:  # a report.html imubounds did not write is refused before the long run
        from imubounds.io.outputs import check_output_file

        check_output_file(out / "report.html", option="-o", advice=REPORT_ADVICE)
    units = _Units(sources, names, settings, UnitCache(ensure_dir(out / ".cache")),
                   progress or (lambda _s, _d, _t: None))  # fmt: skip
    sched_name, n_tasks = _analyse(
        units, settings, client=client, scheduler=scheduler, n_workers=n_workers,
        threads_per_worker=threads_per_worker, target_task_bytes=target_task_bytes,
        split_channels=split_channels, min_split_bytes=min_split_bytes,
        numba_threads=numba_threads,
    )  # fmt: skip
    result = _assemble(units.ordered(), settings, spec, outlier_z=outlier_z, drift_z=drift_z,
                       compare=compare, previous=previous)  # fmt: skip
    result.n_cached = units.counts["cached"]
    result.scheduler = sched_name or "(all cached)"
    result.n_tasks = n_tasks
    _write_outputs(result, out, plot=plot, report=report, argv=argv, t_start=t_start,
                   n_units=len(sources))  # fmt: skip
    return result
