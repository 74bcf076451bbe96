"""Fleet characterisation: the stationary pipeline over many logs on Dask (issue 7).

:func:`run_fleet` runs :func:`imubounds.stationary.pipeline.analyse_static` (the same
reading and settings as ``imubounds static``, out-of-core for large logs) on
every log of a fleet of units, on a ``dask.distributed`` cluster (a
``LocalCluster`` by default, or a running scheduler by address), and collects:

* ``DIR/fleet.parquet`` - one row per unit and channel: status, size, and the
  five IEEE 952 terms Q, N, B, K, R in SI from the fit and from the slope
  read-off, with their confidence intervals (columns ``N_fit``,
  ``N_fit_lo``, ``N_fit_hi``, ``N_slope``, ...; ``N``, ``N_lo``, ``N_hi`` are
  those of ``terms_from``). A unit that failed has one row with
  ``status="failed"`` and the error message.
* ``DIR/passfail.csv`` - with a datasheet spec (:func:`load_spec`), one row per
  unit, channel and term: value, limit, margin, pass.
* ``DIR/fleet.png`` / ``.svg`` - :func:`fleet_figure`.
* ``DIR/fleet.json`` - :meth:`FleetResult.summary` (for reports).

Units are cached by content: the key is the SHA-256 of the file bytes and of
the analysis settings, and a finished unit's result is stored as
``DIR/.cache/<key>.json``; a rerun submits only units without a cache entry.
The client hashes the files and owns the cache, so remote workers need only
read the logs (the paths must be valid on the workers).

Tasks are sized to seconds of work: units are grouped by file size into tasks
of about ``target_task_bytes`` (longest-first onto the lightest task), with at
least 4 tasks per worker when there are enough units.

Spec format (YAML)::

    name: ADIS16405 datasheet          # optional
    criterion: value                   # or ci_upper (compare the CI's upper end)
    gyro:                              # per sensor kind: gyro and/or accel
      N: 2.0 deg/sqrt(h)               # max angle random walk
      B: 25 deg/h                      # max bias instability
      K: 0.1 deg/s/sqrt(s)             # max rate random walk (optional)
    accel:
      N: 0.2 m/s/sqrt(h)
      B: 0.5 mg
      K: 0.01 m/s^2/sqrt(s)

Quantities are parsed with :func:`imubounds.stationary.noise_sim.parse_quantity` (a bare
number is SI). Margin = ``1 - value/limit`` (fraction of the limit unused;
negative when failing).
"""

from __future__ import annotations

import hashlib
import json
import math
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from imubounds import __version__
from imubounds.errors import ImuboundsError, InputError, OptionError

__all__ = [
    "FORMAT",
    "FleetResult",
    "FleetSettings",
    "FleetSpec",
    "TERMS",
    "analyse_unit",
    "check_spec",
    "content_key",
    "expand_globs",
    "fleet_figure",
    "load_spec",
    "parse_spec",
    "plan_tasks",
    "run_fleet",
]

FORMAT = "imubounds.stationary.fleet/1"
TERMS: tuple[str, ...] = ("Q", "N", "B", "K", "R")
Progress = Callable[[str, int, int], None]


# --------------------------------------------------------------------------
# settings and units of work
# --------------------------------------------------------------------------
@dataclass(frozen=True)
class FleetSettings:
    """How each unit is analysed (the ``imubounds static`` settings that matter).

    ``read`` holds the keyword arguments of :func:`imubounds.io.read_imu`
    (``rate_hz``, ``columns``, ``gyro_unit``, ...); ``memory_limit`` routes a
    log larger than it through the out-of-core path, as ``imubounds static``.
    """

    taus: str | int | tuple[float, ...] = "octave"
    estimator: str = "overlapping"
    confidence: float = 0.683
    terms_from: str = "fit"
    memory_limit: str | int = "1GiB"
    read: Mapping[str, Any] = field(default_factory=dict)

    def to_json(self) -> dict[str, Any]:
        d = asdict(self)
        d["read"] = {k: v for k, v in dict(self.read).items() if v is not None}
        if isinstance(self.taus, tuple):
            d["taus"] = list(self.taus)
        return d

    def static_settings(self) -> Any:
        from imubounds.stationary.pipeline import StaticSettings

        return StaticSettings(
            taus=self.taus,
            estimator=self.estimator,
            confidence=self.confidence,
            terms_from=self.terms_from,  # type: ignore[arg-type]
            models=(),
        )


def expand_globs(patterns: Iterable[str]) -> list[Path]:
    """Files matching the patterns (a plain path matches itself), sorted, unique.

    Raises
    ------
    InputError
        When nothing matches.
    """
    import glob

    out: dict[str, Path] = {}
    empty: list[str] = []
    for pat in patterns:
        hits = sorted(glob.glob(pat, recursive=True))
        if not hits and Path(pat).exists():
            hits = [pat]
        files = [h for h in hits if Path(h).is_file() and not Path(h).name.startswith(".")]
        if not files:
            empty.append(pat)
        for h in files:
            out.setdefault(str(Path(h).resolve()), Path(h))
    if not out:
        raise InputError(f"no log file matches {', '.join(map(repr, empty))}; check the pattern")
    return [out[k] for k in sorted(out)]


def content_key(path: str | Path, settings: FleetSettings) -> str:
    """SHA-256 (hex) of the file bytes, the settings and the imubounds version."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        while chunk := f.read(1 << 22):
            h.update(chunk)
    h.update(json.dumps(settings.to_json(), sort_keys=True, default=str).encode())
    h.update(__version__.encode())
    return h.hexdigest()


def plan_tasks(
    sizes: Sequence[int], n_workers: int, target_task_bytes: int = 32 << 20
) -> list[list[int]]:
    """Group units (by index) into tasks of about ``target_task_bytes`` each.

    At least ``min(len(sizes), 4 * n_workers)`` tasks, so that every worker
    has work; longest-processing-time-first assignment.
    """
    n = len(sizes)
    if n == 0:
        return []
    total = int(sum(sizes))
    k = max(math.ceil(total / max(1, target_task_bytes)), min(n, 4 * max(1, n_workers)))
    k = min(k, n)
    loads = [0] * k
    tasks: list[list[int]] = [[] for _ in range(k)]
    for i in sorted(range(n), key=lambda i: -sizes[i]):
        j = min(range(k), key=lambda j: loads[j])
        tasks[j].append(i)
        loads[j] += int(sizes[i])
    return [sorted(t) for t in tasks if t]


def _terms_row(ch: Any, settings: FleetSettings) -> dict[str, Any]:
    row: dict[str, Any] = {}
    for method, terms in (("fit", ch.fit), ("slope", ch.slope)):
        for t in TERMS:
            v = terms.value(t)
            lo, hi = terms.ci.get(t, (math.nan, math.nan))
            row[f"{t}_{method}"] = v
            row[f"{t}_{method}_lo"] = float(lo)
            row[f"{t}_{method}_hi"] = float(hi)
    for t in TERMS:
        for suffix in ("", "_lo", "_hi"):
            row[f"{t}{suffix}"] = row[f"{t}_{settings.terms_from}{suffix}"]
    row["sigma_c"] = ch.sigma_c
    row["bound"] = ch.bound
    row["level_95"] = ch.level_95
    return row


def analyse_unit(path: str, settings: FleetSettings) -> dict[str, Any]:
    """Analyse one log as ``imubounds static`` would (no models); never raises.

    Returns ``{"path", "unit", "status": "ok"|"failed", "error", "rows",
    "curves", "seconds"}``; ``rows`` are per-channel dicts (SI values),
    ``curves`` maps channel -> ``{"tau": [...], "adev": [...]}``.
    """
    from imubounds.io import read_imu
    from imubounds.stationary.pipeline import analyse_static
    from imubounds.stationary.stream import analyse_static_outofcore, route_outofcore

    t0 = time.perf_counter()
    p = Path(path)
    out: dict[str, Any] = {"path": str(path), "unit": _unit_name(p), "status": "ok",
                           "error": "", "rows": [], "curves": {}}  # fmt: skip
    try:
        read = {k: v for k, v in dict(settings.read).items() if v is not None}
        open_kw = {k: read[k] for k in ("rate_hz", "columns", "gyro_unit", "accel_unit",
                                        "time_unit") if k in read}  # fmt: skip
        big = route_outofcore(p, settings.memory_limit, **open_kw)
        if big is not None:
            res = analyse_static_outofcore(
                big, settings.static_settings(), memory_limit=settings.memory_limit
            )
        else:
            log = read_imu(p, **read)
            res = analyse_static(log, settings.static_settings())
        for name, ch in res.channels.items():
            row = {
                "channel": name,
                "kind": ch.kind,
                "n_samples": int(res.log.n_samples),
                "rate_hz": float(res.log.rate_hz),
                "duration_s": float(res.log.duration_s),
            }
            row.update(_terms_row(ch, settings))
            out["rows"].append(row)
            out["curves"][name] = {
                "tau": [float(v) for v in ch.allan.tau],
                "adev": [float(v) for v in ch.allan.dev],
            }
    except ImuboundsError as err:
        out.update(status="failed", error=str(err))
    except Exception as err:  # noqa: BLE001 - a bad unit must not stop the fleet
        out.update(status="failed", error=f"{path}: {type(err).__name__}: {err}")
    out["seconds"] = time.perf_counter() - t0
    return out


def _analyse_many(paths: list[str], settings: FleetSettings) -> list[dict[str, Any]]:
    return [analyse_unit(p, settings) for p in paths]


def _unit_name(p: Path) -> str:
    name = p.name
    for suf in (".gz", ".csv", ".tsv", ".txt", ".parquet", ".npy", ".h5", ".hdf5"):
        name = name.removesuffix(suf)
    return name


# --------------------------------------------------------------------------
# spec
# --------------------------------------------------------------------------
@dataclass(frozen=True)
class FleetSpec:
    """Datasheet limits: ``limits[kind][term]`` in SI; ``criterion`` value|ci_upper."""

    limits: dict[str, dict[str, float]]
    criterion: str = "value"
    name: str = "spec"


def parse_spec(data: Mapping[str, Any], where: str = "spec") -> FleetSpec:
    """A :class:`FleetSpec` from the YAML mapping (see the module docstring)."""
    from imubounds.stationary.noise_sim import parse_quantity

    if not isinstance(data, Mapping):
        raise OptionError(f"{where}: expected a mapping with 'gyro' and/or 'accel' limits")
    unknown = [k for k in data if k not in ("name", "criterion", "gyro", "accel")]
    if unknown:
        raise OptionError(
            f"{where}: unknown key(s) {', '.join(map(repr, unknown))}; use name, criterion, "
            "gyro, accel"
        )
    criterion = str(data.get("criterion", "value"))
    if criterion not in ("value", "ci_upper"):
        raise OptionError(f"{where}: criterion must be 'value' or 'ci_upper', got {criterion!r}")
    limits: dict[str, dict[str, float]] = {}
    for kind in ("gyro", "accel"):
        block = data.get(kind)
        if block is None:
            continue
        if not isinstance(block, Mapping):
            raise OptionError(f"{where}: {kind} must map terms (N, B, K, ...) to limits")
        limits[kind] = {}
        for term, value in block.items():
            if term not in TERMS:
                raise OptionError(
                    f"{where}: {kind}.{term} is not a noise term; use {', '.join(TERMS)}"
                )
            lim = parse_quantity(value, kind, term, where=f"{where}: {kind}.")
            if not lim > 0:
                raise OptionError(f"{where}: {kind}.{term} must be > 0, got {value!r}")
            limits[kind][term] = lim
    if not limits:
        raise OptionError(f"{where}: no limits; give a 'gyro' and/or 'accel' block")
    return FleetSpec(limits, criterion, str(data.get("name", Path(where).stem)))


def load_spec(path: str | Path) -> FleetSpec:
    """Read a datasheet spec YAML file."""
    import yaml

    p = Path(path)
    try:
        data = yaml.safe_load(p.read_text(encoding="utf-8"))
    except OSError as err:
        raise OptionError(f"cannot read spec {p}: {err.strerror}") from err
    except yaml.YAMLError as err:
        raise OptionError(f"{p}: not valid YAML ({str(err).splitlines()[0]})") from err
    return parse_spec(data, where=str(p))


def check_spec(df: Any, spec: FleetSpec) -> Any:
    """Pass/fail table: one row per (unit, channel, term) with a limit.

    Columns: unit, channel, kind, term, value, limit (SI), margin
    (``1 - value/limit``), value_ieee, limit_ieee, unit_ieee, status
    (``pass``/``fail``/``undetermined``).
    """
    import pandas as pd

    from imubounds.units import to_ieee

    rows = []
    ok = df[df["status"] == "ok"]
    for rec in ok.to_dict("records"):
        kind = rec["kind"]
        for term, lim in spec.limits.get(kind, {}).items():
            v = rec[f"{term}_hi"] if spec.criterion == "ci_upper" else rec[term]
            v = float(v) if v is not None else math.nan
            if math.isfinite(v):
                margin = 1.0 - v / lim
                status = "pass" if v <= lim else "fail"
            else:
                margin, status = math.nan, "undetermined"
            iv, iu = to_ieee(kind, term, v)  # type: ignore[arg-type]
            rows.append({
                "unit": rec["unit"], "channel": rec["channel"], "kind": kind, "term": term,
                "value": v, "limit": lim, "margin": margin, "value_ieee": iv,
                "limit_ieee": to_ieee(kind, term, lim)[0], "unit_ieee": iu,  # type: ignore[arg-type]
                "status": status,
            })  # fmt: skip
    cols = ["unit", "channel", "kind", "term", "value", "limit", "margin", "value_ieee",
            "limit_ieee", "unit_ieee", "status"]  # fmt: skip
    return pd.DataFrame(rows, columns=cols)


# --------------------------------------------------------------------------
# result
# --------------------------------------------------------------------------
@dataclass
class FleetResult:
    """Everything :func:`run_fleet` produced."""

    table: Any  # pandas.DataFrame, one row per unit and channel
    curves: dict[str, dict[str, dict[str, list[float]]]]  # unit -> channel -> tau/adev
    settings: FleetSettings
    passfail: Any = None  # pandas.DataFrame or None
    spec: FleetSpec | None = None
    n_cached: int = 0
    seconds: float = 0.0
    scheduler: str = ""
    n_tasks: int = 0
    files: dict[str, str] = field(default_factory=dict)

    @property
    def failed(self) -> list[dict[str, str]]:
        bad = self.table[self.table["status"] == "failed"]
        return [{"unit": r["unit"], "path": r["path"], "error": r["error"]}
                for r in bad.to_dict("records")]  # fmt: skip

    def summary(self) -> dict[str, Any]:
        """The content of ``fleet.json``: counts, failures, term statistics, pass/fail."""
        from imubounds.units import to_ieee

        t = self.table
        ok = t[t["status"] == "ok"]
        stats: dict[str, Any] = {}
        for kind in ("gyro", "accel"):
            sub = ok[ok["kind"] == kind]
            if sub.empty:
                continue
            stats[kind] = {}
            for term in TERMS:
                v = sub[term].to_numpy(dtype=np.float64)
                v = v[np.isfinite(v)]
                unit = to_ieee(kind, term, 1.0)[1]  # type: ignore[arg-type]
                if v.size == 0:
                    stats[kind][term] = {"n": 0, "unit_ieee": unit}
                    continue
                q = np.percentile(v, [0, 5, 50, 95, 100])
                conv = to_ieee(kind, term, 1.0)[0]  # type: ignore[arg-type]
                stats[kind][term] = {
                    "n": int(v.size),
                    "unit_ieee": unit,
                    "min": q[0] * conv, "p05": q[1] * conv, "median": q[2] * conv,
                    "p95": q[3] * conv, "max": q[4] * conv,
                }  # fmt: skip
        units = sorted(set(t["unit"]))
        out: dict[str, Any] = {
            "format": FORMAT,
            "imubounds_version": __version__,
            "n_units": len(units),
            "n_ok": int(len(set(ok["unit"]))),
            "n_failed": len(self.failed),
            "n_cached": self.n_cached,
            "failed": self.failed,
            "settings": self.settings.to_json(),
            "terms_from": self.settings.terms_from,
            "terms_ieee": stats,
            "scheduler": self.scheduler,
            "n_tasks": self.n_tasks,
            "seconds": self.seconds,
            "files": dict(self.files),
        }
        if self.spec is not None and self.passfail is not None:
            pf = self.passfail
            failing = sorted(set(pf[pf["status"] == "fail"]["unit"]))
            checked = sorted(set(pf["unit"]))
            worst = {}
            for (kind, term), g in pf.groupby(["kind", "term"]):
                m = g["margin"].to_numpy(dtype=np.float64)
                m = m[np.isfinite(m)]
                if m.size:
                    worst[f"{kind}.{term}"] = float(m.min())
            out["spec"] = {
                "name": self.spec.name,
                "criterion": self.spec.criterion,
                "limits_si": self.spec.limits,
                "n_checked": len(checked),
                "n_pass": len([u for u in checked if u not in failing]),
                "n_fail": len(failing),
                "units_failing": failing,
                "worst_margin": worst,
            }
        return out


# --------------------------------------------------------------------------
# the driver
# --------------------------------------------------------------------------
def _rows_frame(results: list[dict[str, Any]]) -> Any:
    import pandas as pd

    rows = []
    for r in results:
        if r["status"] == "ok" and r["rows"]:
            for row in r["rows"]:
                rows.append({"unit": r["unit"], "path": r["path"], "status": "ok", "error": "",
                             **row})  # fmt: skip
        else:
            rows.append({"unit": r["unit"], "path": r["path"], "status": "failed",
                         "error": r["error"] or "no channel analysed"})  # fmt: skip
    df = pd.DataFrame(rows)
    for col in ("channel", "kind"):
        if col not in df:
            df[col] = None
    return df


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
    target_task_bytes: int = 32 << 20,
    plot: bool = True,
    progress: Progress | None = None,
) -> FleetResult:
    """Characterise every log matching ``patterns``; write the fleet outputs.

    Parameters
    ----------
    patterns : sequence of str
        Glob patterns or paths of the unit logs (one unit per file).
    outdir : path
        Output directory (``fleet.parquet``, ``fleet.json``, ``fleet.png``,
        ``passfail.csv``, ``.cache/``).
    settings : FleetSettings
        Analysis settings.
    scheduler : str, optional
        Address of a running ``dask.distributed`` scheduler; default a new
        ``LocalCluster(n_workers, threads_per_worker)``, closed on return.
    client : dask.distributed.Client, optional
        Use this client (takes precedence over ``scheduler``).
    spec : FleetSpec or path, optional
        Datasheet limits for the pass/fail table.
    progress : callable(stage, done, total), optional
        ``"hash"`` then ``"units"``.

    Returns
    -------
    FleetResult
    """
    from imubounds.io.outputs import ensure_dir, write_json, write_with

    t_start = time.perf_counter()
    settings = settings or FleetSettings()
    report = progress or (lambda _s, _d, _t: None)
    if spec is not None and not isinstance(spec, FleetSpec):
        spec = load_spec(spec)
    paths = expand_globs([str(p) for p in patterns])
    out = ensure_dir(outdir)
    cache = ensure_dir(out / ".cache")

    # ---- content keys and cache lookup (client side)
    keys: list[str | None] = []
    results: dict[int, dict[str, Any]] = {}
    n_cached = 0
    for i, p in enumerate(paths):
        try:
            key = content_key(p, settings)
        except OSError as err:
            keys.append(None)
            results[i] = {"path": str(p), "unit": _unit_name(p), "status": "failed",
                          "error": f"{p}: cannot read ({err.strerror})", "rows": [],
                          "curves": {}}  # fmt: skip
            continue
        keys.append(key)
        hit = cache / f"{key}.json"
        if hit.is_file():
            try:
                res = json.loads(hit.read_text(encoding="utf-8"))
                res["path"], res["unit"] = str(p), _unit_name(p)
                results[i] = res
                n_cached += 1
            except (OSError, ValueError):
                pass
        report("hash", i + 1, len(paths))
    todo = [i for i in range(len(paths)) if i not in results]

    # ---- distributed analysis
    sched_name = ""
    n_tasks = 0
    if todo:
        from dask.distributed import Client, LocalCluster, as_completed

        own_cluster = None
        own_client = None
        try:
            if client is None:
                if scheduler:
                    try:
                        own_client = Client(scheduler, timeout="20s")
                    except (OSError, TimeoutError) as err:
                        raise OptionError(
                            f"cannot connect to the Dask scheduler at {scheduler!r} ({err}); "
                            "check the address or omit --scheduler for a local cluster"
                        ) from err
                else:
                    own_cluster = LocalCluster(
                        n_workers=n_workers,
                        threads_per_worker=threads_per_worker,
                        processes=True,
                        dashboard_address=":0",
                    )
                    own_client = Client(own_cluster)
                client = own_client
            sched_name = str(client.scheduler.address)
            workers = max(1, len(client.scheduler_info().get("workers", {})) or n_workers)
            sizes = [paths[i].stat().st_size for i in todo]
            groups = plan_tasks(sizes, workers, target_task_bytes)
            n_tasks = len(groups)
            futures = {}
            for g in groups:
                idx = [todo[j] for j in g]
                fut = client.submit(_analyse_many, [str(paths[i]) for i in idx], settings,
                                    pure=False)  # fmt: skip
                futures[fut] = idx
            done = 0
            for fut in as_completed(list(futures)):
                idx = futures[fut]
                try:
                    batch = fut.result()
                except Exception as err:  # noqa: BLE001 - worker died; report, go on
                    batch = [{"path": str(paths[i]), "unit": _unit_name(paths[i]),
                              "status": "failed", "error": f"task failed: {err}", "rows": [],
                              "curves": {}} for i in idx]  # fmt: skip
                for i, res in zip(idx, batch, strict=True):
                    results[i] = res
                    ckey = keys[i]
                    if res["status"] == "ok" and ckey is not None:
                        write_json(cache / f"{ckey}.json", res)
                done += len(idx)
                report("units", done, len(todo))
        finally:
            if own_client is not None:
                own_client.close()
            if own_cluster is not None:
                own_cluster.close()

    ordered = [results[i] for i in range(len(paths))]
    table = _rows_frame(ordered)
    curves = {r["unit"]: r.get("curves", {}) for r in ordered if r["status"] == "ok"}
    passfail = check_spec(table, spec) if isinstance(spec, FleetSpec) else None
    result = FleetResult(
        table=table, curves=curves, settings=settings, passfail=passfail,
        spec=spec if isinstance(spec, FleetSpec) else None, n_cached=n_cached,
        scheduler=sched_name or "(all cached)", n_tasks=n_tasks,
    )  # fmt: skip

    files = {"table": "fleet.parquet", "summary": "fleet.json"}
    write_with(out / "fleet.parquet", lambda p: table.to_parquet(p, index=False))
    if passfail is not None:
        write_with(out / "passfail.csv", lambda p: passfail.to_csv(p, index=False))
        files["passfail"] = "passfail.csv"
    if plot and curves:
        from imubounds.report.static_plots import save_figure

        save_figure(fleet_figure(result), out / "fleet")
        files["plot"] = "fleet.png"
        files["plot_svg"] = "fleet.svg"
    result.files = files
    result.seconds = time.perf_counter() - t_start
    write_json(out / "fleet.json", result.summary())
    return result


# --------------------------------------------------------------------------
# figure
# --------------------------------------------------------------------------
def _median_curve(curves: list[tuple[np.ndarray, np.ndarray]]) -> tuple[np.ndarray, np.ndarray]:
    """Pointwise median in log-log on a common tau grid (where >= half the curves exist)."""
    lo = min(float(t[0]) for t, _ in curves)
    hi = max(float(t[-1]) for t, _ in curves)
    grid = np.logspace(math.log10(lo), math.log10(hi), 60)
    vals = np.full((len(curves), grid.size), np.nan)
    for i, (t, d) in enumerate(curves):
        ok = (grid >= t[0] * (1 - 1e-9)) & (grid <= t[-1] * (1 + 1e-9)) & np.all(d > 0)
        vals[i, ok] = np.interp(np.log(grid[ok]), np.log(t), np.log(d))
    count = np.sum(np.isfinite(vals), axis=0)
    keep = count >= max(1, len(curves) // 2)
    med = np.full(grid.size, np.nan)
    med[keep] = np.exp(np.nanmedian(vals[:, keep], axis=0))
    return grid[keep], med[keep]


def fleet_figure(result: FleetResult) -> Any:
    """Fleet plot: Allan-curve bundles with the median, and term distributions.

    Top row: every unit's Allan deviation of every gyro (left) and accelerometer
    (right) axis as faint lines, the pointwise median bold. Lower rows:
    histograms of N, B, K (the ``terms_from`` estimate) per sensor kind, in
    IEEE units, with the spec limit as a dashed red line when given.
    """
    import matplotlib.pyplot as plt

    from imubounds.units import DEG, to_ieee

    t = result.table
    ok = t[t["status"] == "ok"]
    kinds = [k for k in ("gyro", "accel") if (ok["kind"] == k).any()]
    fig = plt.figure(figsize=(13, 4.2 + 3.0 * len(kinds)), layout="constrained")
    gs = fig.add_gridspec(1 + len(kinds), 6)
    ylab = {"gyro": "Allan deviation [deg/h]", "accel": "Allan deviation [mg]"}
    scale = {"gyro": 3600.0 / DEG, "accel": 1.0 / (9.80665e-3)}
    n_units = len(result.curves)
    for col, kind in enumerate(("gyro", "accel")):
        ax = fig.add_subplot(gs[0, 3 * col : 3 * col + 3])
        bundle = []
        for unit_curves in result.curves.values():
            for ch, c in unit_curves.items():
                if not ch.startswith(kind):
                    continue
                tau = np.asarray(c["tau"])
                dev = np.asarray(c["adev"]) * scale[kind]
                bundle.append((tau, dev))
                ax.loglog(tau, dev, color="0.35", alpha=0.12, lw=0.8, rasterized=True)
        if bundle:
            g, med = _median_curve(bundle)
            ax.loglog(g, med, color="C3" if kind == "gyro" else "C0", lw=2.4,
                      label=f"median of {len(bundle)} axes")  # fmt: skip
            ax.legend(loc="upper right", fontsize=8)
        else:
            ax.text(0.5, 0.5, f"no {kind} channel", ha="center", transform=ax.transAxes)
        ax.set_xlabel("averaging time τ [s]")
        ax.set_ylabel(ylab[kind])
        ax.set_title(f"{kind}: {n_units} units, every axis (faint) and the median")
        ax.grid(True, which="both", alpha=0.3)
    for row, kind in enumerate(kinds, start=1):
        sub = ok[ok["kind"] == kind]
        for j, term in enumerate(("N", "B", "K")):
            ax = fig.add_subplot(gs[row, 2 * j : 2 * j + 2])
            conv, unit = to_ieee(kind, term, 1.0)  # type: ignore[arg-type]
            v = sub[term].to_numpy(dtype=np.float64) * conv
            v = v[np.isfinite(v)]
            if v.size:
                ax.hist(v, bins=min(30, max(5, v.size // 2)), color="C0" if kind == "accel"
                        else "C3", alpha=0.75, edgecolor="white")  # fmt: skip
                ax.axvline(float(np.median(v)), color="k", lw=1.2, label="median")
            if result.spec is not None and term in result.spec.limits.get(kind, {}):
                lim = result.spec.limits[kind][term] * conv
                ax.axvline(lim, color="red", ls="--", lw=1.5, label="spec limit")
            ax.set_xlabel(f"{kind} {term} [{unit}]")
            ax.set_ylabel("axes (units × channels)")
            ax.set_title(f"{kind} {term} ({result.settings.terms_from})")
            if v.size or result.spec is not None:
                ax.legend(fontsize=8)
    nf = len(result.failed)
    fig.suptitle(
        f"Fleet of {n_units + nf} units: {n_units} analysed, {nf} failed "
        f"({result.settings.estimator} Allan deviation)"
    )
    return fig
