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

Tasks are sized to under a second of work: units are grouped by file size into
tasks of about ``target_task_bytes`` (4 MiB; a 30 min, 100 Hz CSV.gz log is
7 MB, a task of its own; longest first onto the lightest task), with at least
4 tasks per worker when there are enough units; with ``split_channels`` and
fewer units than workers, long logs are split by channel (:func:`plan_work`).
Each Dask worker is warmed once (imports, numba kernels) by a worker plugin;
local clusters (:func:`local_cluster`) share the cores among the workers'
Allan kernels and start workers without Dask's ``MALLOC_TRIM_THRESHOLD_``.

Spec format (YAML)::

    name: ADIS16405 datasheet          # optional
    criterion: value                   # or ci_upper (compare the CI's upper end)
    gyro:                              # per sensor kind: gyro and/or accel
      N: 2.0 deg/sqrt(h)               # max angle random walk
      B: 25 deg/h                      # max bias instability
      K: 10 deg/h/sqrt(h)              # max rate random walk (optional)
    accel:
      N: 0.2 m/s/sqrt(h)
      B: 0.5 mg
      K: 0.05 m/s/h/sqrt(h)

Quantities are parsed with :func:`imubounds.stationary.noise_sim.parse_quantity` (a bare
number is SI). Margin = ``1 - value/limit`` (fraction of the limit unused;
negative when failing).
"""

from __future__ import annotations

import hashlib
import json
import math
import re
import time
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import asdict, dataclass, field
from pathlib import Path, PurePosixPath
from typing import Any

import numpy as np

from imubounds import __version__
from imubounds.errors import ImuboundsError, InputError, OptionError
from imubounds.io.validate import is_url
from imubounds.stationary.fleet_stats import DEFAULT_DRIFT_Z, DEFAULT_OUTLIER_Z, STAT_TERMS

__all__ = [
    "CACHE_ROWS",
    "FORMAT",
    "STRONG_VALIDATORS",
    "FleetResult",
    "FleetSettings",
    "FleetSpec",
    "TERMS",
    "analyse_batch",
    "analyse_unit",
    "check_spec",
    "content_key",
    "expand_globs",
    "fleet_figure",
    "fleet_stats_figure",
    "is_url",
    "load_spec",
    "local_cluster",
    "parse_spec",
    "plan_tasks",
    "plan_work",
    "remote_fingerprint",
    "run_fleet",
    "unit_names",
    "warm_up",
]

FORMAT = "imubounds.stationary.fleet/1"
#: Version of a cached unit result's rows, in the cache key: a result cached before the
#: rows gained a column (2: each term's status and upper bound) is not reused.
CACHE_ROWS = 2
REPORT_ADVICE = "move it away or use --no-report"
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
        """The settings as JSON (also the cache key's part): read options at their default
        (``on_gap="refuse"``) are left out, so that the command line and Python share it."""
        from dataclasses import fields

        from imubounds.io.assemble import ReadOptions

        defaults = {f.name: f.default for f in fields(ReadOptions)}
        d = asdict(self)
        d["read"] = {k: v for k, v in dict(self.read).items()
                     if v is not None and not (k in defaults and v == defaults[k])}  # fmt: skip
        if isinstance(self.taus, tuple):
            d["taus"] = list(self.taus)
        return d

    def check(self) -> None:
        """Refuse, before any unit is read, settings every unit would fail on.

        Raises
        ------
        OptionError
            A confidence outside (0, 1), an unknown estimator or ``terms_from``, an
            unreadable memory setting.
        """
        from imubounds.stationary.allan import ESTIMATORS
        from imubounds.stationary.stream import parse_memory

        c = self.confidence
        if isinstance(c, bool) or not isinstance(c, (int, float)) or not 0 < c < 1:
            raise OptionError(f"confidence must be between 0 and 1 (exclusive), got {c!r}")
        if self.estimator not in ESTIMATORS:
            raise OptionError(
                f"unknown estimator {self.estimator!r}; use one of {', '.join(ESTIMATORS)}"
            )
        if self.terms_from not in ("fit", "slope"):
            raise OptionError(f"terms_from must be 'fit' or 'slope', got {self.terms_from!r}")
        parse_memory(self.memory_limit, "memory_limit")

    def static_settings(self) -> Any:
        from imubounds.stationary.pipeline import StaticSettings

        return StaticSettings(
            taus=self.taus,
            estimator=self.estimator,
            confidence=self.confidence,
            terms_from=self.terms_from,  # type: ignore[arg-type]
            models=(),
        )


_GLOB_MAGIC = re.compile(r"[*?\[]")
#: Suffixes taken off a file name to name its unit (in this order, each at most once).
UNIT_SUFFIXES = (".gz", ".bz2", ".xz", ".zst", ".csv", ".tsv", ".txt", ".parquet", ".npy",
                 ".h5", ".hdf5", ".bin", ".ulg", ".bag", ".mcap")  # fmt: skip


def _url_fs(url: str) -> tuple[Any, str]:
    """``(filesystem, path)`` of an fsspec URL; a one-line InputError when it cannot be."""
    try:
        import fsspec
    except ImportError as err:  # pragma: no cover - fsspec comes with the fleet extra (dask)
        raise InputError(
            f"{url}: reading URLs needs fsspec; pip install 'imubounds[fleet]'"
        ) from err
    try:
        return fsspec.core.url_to_fs(url)
    except ImportError as err:  # the protocol's package (s3fs, gcsfs, aiohttp) is missing
        msg = " ".join(str(err).split())
        raise InputError(f"{url}: {msg}") from err
    except (ValueError, OSError) as err:  # unknown protocol, bad URL, no credentials
        msg = " ".join(str(err).split())
        raise InputError(f"{url}: cannot open ({msg})") from err


def _expand_url(pat: str) -> list[str]:
    fs, path = _url_fs(pat)
    try:
        hits = sorted(fs.glob(path)) if _GLOB_MAGIC.search(path) else [path]
        files = [h for h in hits if fs.isfile(h) and not PurePosixPath(h).name.startswith(".")]
    except (OSError, ValueError) as err:
        msg = " ".join(str(err).split())
        raise InputError(f"{pat}: cannot list ({msg})") from err
    return [fs.unstrip_protocol(h) for h in files]


def expand_globs(patterns: Iterable[str | Path]) -> list[str]:
    """Sources matching the patterns, sorted, unique: local paths or fsspec URLs.

    A local pattern is expanded with :mod:`glob` (``**`` recursive; a plain path
    matches itself). A URL (``s3://bucket/units/**/*.csv.gz``, ``memory://...``,
    ``file://...``) is expanded with the glob of its fsspec file system; the
    URL's protocol package (``s3fs``, ``gcsfs``, ...) must be installed. Hidden
    files (``.name``) are skipped.

    Raises
    ------
    InputError
        When any pattern matches no file (a missing path or an empty glob would
        otherwise leave units out of the fleet unnoticed; all such patterns are
        named), or a URL cannot be listed.
    """
    import glob

    out: dict[str, str] = {}
    empty: list[str] = []
    for pat in map(str, patterns):
        if is_url(pat):
            files = _expand_url(pat)
            keys = files
        else:
            hits = sorted(glob.glob(pat, recursive=True))
            if not hits and Path(pat).exists():
                hits = [pat]
            files = [h for h in hits if Path(h).is_file() and not Path(h).name.startswith(".")]
            keys = [str(Path(h).resolve()) for h in files]
        if not files:
            empty.append(pat)
        for k, h in zip(keys, files, strict=True):
            out.setdefault(k, h)
    if empty:
        what = "no log file matches" if len(empty) == 1 else "no log files match"
        raise InputError(
            f"{what} {', '.join(map(repr, empty))}; check the pattern"
            + (f" ({len(out)} file(s) matched the other patterns)" if out else "")
        )
    return [out[k] for k in sorted(out)]


def _components(source: str) -> list[str]:
    """Path components of a source, the URL's protocol first (``s3:``)."""
    if is_url(source):
        proto = source.split("://", 1)[0]
        _, path = _url_fs(source)
        return [f"{proto}:", *[c for c in path.split("/") if c]]
    return list(Path(source).resolve().parts)


def _strip_suffixes(name: str) -> str:
    for suf in UNIT_SUFFIXES:
        if name.lower().endswith(suf) and len(name) > len(suf):
            name = name[: -len(suf)]
    return name


def unit_names(sources: Sequence[str | Path]) -> list[str]:
    """Unit names: each source's path relative to the common folder of all, without the
    file-type suffixes, ``/``-separated (``siteA/unit1.csv.gz`` and ``siteB/unit1.csv.gz``
    are the units ``siteA/unit1`` and ``siteB/unit1``). Two files that differ only in
    their suffixes (``u.csv`` and ``u.csv.gz``) keep their whole file names.
    """
    parts = [_components(str(s)) for s in sources]
    if not parts:
        return []
    common = 0
    dirs = [p[:-1] for p in parts]
    while all(len(d) > common for d in dirs) and len({d[common] for d in dirs}) == 1:
        common += 1
    rel = [p[common:] for p in parts]
    names = ["/".join([*r[:-1], _strip_suffixes(r[-1])]) for r in rel]
    counts: dict[str, int] = {}
    for n in names:
        counts[n] = counts.get(n, 0) + 1
    return [n if counts[n] == 1 else "/".join(r) for n, r in zip(names, rel, strict=True)]


def source_size(source: str) -> int:
    """Size in bytes of a local file or URL (0 when unknown)."""
    try:
        if is_url(source):
            fs, path = _url_fs(source)
            return int(fs.size(path) or 0)
        return Path(source).stat().st_size
    except (OSError, ValueError, TypeError, InputError):
        return 0


#: Fields of an fsspec ``info`` (lower-cased) that change whenever the object's bytes do:
#: strong validators (S3 ETag and VersionId, GCS md5Hash, crc32c and generation, Azure
#: etag, an HTTP server's ETag). A modification time is not one: a log rewritten within
#: the same second with the same size would keep its key.
STRONG_VALIDATORS = frozenset({"etag", "e_tag", "md5", "md5hash", "content_md5", "crc32c",
                               "checksum", "versionid", "version_id", "generation"})  # fmt: skip


#: URLs whose bytes are always hashed for the cache key: local and in-memory files, and
#: web servers, whose ETag is often the modification second and size (nginx), not the
#: content.
_HASHED_URLS = ("file://", "memory://", "http://", "https://")


def remote_fingerprint(fs: Any, path: str) -> str | None:
    """The store's own fingerprint of a remote object: its strong validators
    (:data:`STRONG_VALIDATORS`) with its size and fsspec ``ukey``; ``None`` when the
    store gives none: then only the bytes can say whether the object changed."""
    info = fs.info(path)
    marks = {str(k): str(v) for k, v in info.items()
             if str(k).lower() in STRONG_VALIDATORS and v not in (None, "")}  # fmt: skip
    if not marks:
        return None
    try:
        marks["ukey"] = str(fs.ukey(path))
    except (NotImplementedError, OSError, ValueError):
        pass
    marks["size"] = str(info.get("size"))
    return json.dumps(marks, sort_keys=True)


def content_key(source: str | Path, settings: FleetSettings) -> str:
    """SHA-256 (hex) of the log's content, the settings, the imubounds version and the
    version of the cached rows (:data:`CACHE_ROWS`).

    The content is the file's bytes for a local path or a ``file://``, ``memory://``,
    ``http://`` or ``https://`` URL (a web server's ETag is often only the
    modification second and the size). For object stores it is the store's own
    fingerprint of the object (:func:`remote_fingerprint`: the ETag on S3, the
    MD5/CRC on GCS, ...), so that a remote fleet is not downloaded twice; an object
    without one is read and its bytes hashed, since a modification time and a size
    do not show every change. Raises OSError when the log cannot be read.
    """
    src = str(source)
    if is_url(src):
        h = hashlib.sha256()
        fs, path = _url_fs(src)
        mark = None if src.startswith(_HASHED_URLS) else remote_fingerprint(fs, path)
        if mark is None:
            with fs.open(path, "rb") as f:
                while chunk := f.read(1 << 22):
                    h.update(chunk)
        else:
            h.update(f"{src}\0{mark}".encode())
    else:
        with open(src, "rb") as f:  # into one reused buffer: half the time of read() chunks
            h = hashlib.file_digest(f, "sha256")
    h.update(json.dumps(settings.to_json(), sort_keys=True, default=str).encode())
    h.update(__version__.encode())
    h.update(f"rows/{CACHE_ROWS}".encode())
    return h.hexdigest()


def plan_tasks(
    sizes: Sequence[int], n_workers: int, target_task_bytes: int = 4 << 20
) -> list[list[int]]:
    """Group units (by index) into tasks of about ``target_task_bytes`` each.

    At least ``min(len(sizes), 4 * n_workers)`` tasks, so that every worker
    has work, and a multiple of ``n_workers`` when there are units enough (16
    equal units on 2 workers: 16 tasks, not 15 with one of two units that the
    other worker waits for); longest-processing-time-first assignment.
    """
    n = len(sizes)
    if n == 0:
        return []
    total = int(sum(sizes))
    w = max(1, n_workers)
    k = max(math.ceil(total / max(1, target_task_bytes)), min(n, 4 * w))
    k = min(math.ceil(k / w) * w, n)
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
            row[f"{t}_{method}_status"] = str(terms.status.get(t, ""))
    for t in TERMS:
        for suffix in ("", "_lo", "_hi", "_status"):
            row[f"{t}{suffix}"] = row[f"{t}_{settings.terms_from}{suffix}"]
    for t in TERMS:  # the upper bound used downstream when the term is not resolved
        sel = ch.selected.terms[t]
        if sel.status == "upper_bound" and sel.value is not None:
            row[f"{t}_ub"] = float(sel.value)
        elif sel.status == "resolved" and sel.ci is not None:
            row[f"{t}_ub"] = float(sel.ci[1])
        else:
            row[f"{t}_ub"] = math.nan
    row["sigma_c"] = ch.sigma_c
    row["bound"] = ch.bound
    row["level_95"] = ch.level_95
    return row


@contextmanager
def _local_copy(source: str) -> Iterator[Path]:
    """A local path holding the log: the path itself, or a URL copied to a temporary file
    (with the URL's file name, so that the readers recognise the format)."""
    if not is_url(source):
        yield Path(source)
        return
    import shutil
    import tempfile

    fs, path = _url_fs(source)
    with tempfile.TemporaryDirectory(prefix="imubounds-fleet-") as tmp:
        local = Path(tmp) / (PurePosixPath(path).name or "log")
        try:
            with fs.open(path, "rb") as src, open(local, "wb") as dst:
                shutil.copyfileobj(src, dst, 1 << 22)
        except (OSError, ValueError) as err:
            msg = " ".join(str(err).split())
            raise InputError(f"{source}: cannot read ({msg})") from err
        yield local


def _channel_part(names: Sequence[str], part: tuple[int, int] | None) -> list[str] | None:
    """The ``part = (i, n)``-th of ``n`` contiguous slices of the IMU channels (all: None)."""
    if part is None or part[1] <= 1:
        return None
    imu = [c for c in names if c.startswith(("gyro", "accel"))]
    i, n = part
    lo, hi = (len(imu) * i) // n, (len(imu) * (i + 1)) // n
    return imu[lo:hi]


def analyse_unit(
    path: str | Path,
    settings: FleetSettings,
    part: tuple[int, int] | None = None,
    *,
    unit: str | None = None,
) -> dict[str, Any]:
    """Analyse one log as ``imubounds static`` would (no models); never raises.

    ``path`` is a local path or an fsspec URL (copied to a temporary file first).
    ``part = (i, n)`` analyses only the ``i``-th of ``n`` contiguous slices of the
    IMU channels (a long log split across workers; the parts' rows and curves
    together are those of the whole unit). Returns ``{"path", "unit",
    "status": "ok"|"failed", "error", "rows", "curves", "seconds"}``; ``rows``
    are per-channel dicts (SI values), ``curves`` maps channel -> ``{"tau",
    "adev"}`` (float64 arrays, s and signal units).
    """
    t0 = time.perf_counter()
    src = str(path)
    out: dict[str, Any] = {"path": src, "unit": unit or unit_names([src])[0], "status": "ok",
                           "error": "", "rows": [], "curves": {}}  # fmt: skip
    local = ""
    try:
        with _local_copy(src) as copy:
            local = str(copy)
            _analyse_local(copy, settings, part, out)
    except ImuboundsError as err:
        out.update(status="failed", error=str(err))
    except Exception as err:  # noqa: BLE001 - a bad unit must not stop the fleet
        out.update(status="failed", error=f"{src}: {type(err).__name__}: {err}")
    if local and local != src and out["error"]:
        out["error"] = out["error"].replace(local, src)  # name the URL, not the copy
    out["seconds"] = time.perf_counter() - t0
    return out


def _analyse_local(
    p: Path, settings: FleetSettings, part: tuple[int, int] | None, out: dict[str, Any]
) -> None:
    from imubounds.io import read_imu
    from imubounds.stationary.pipeline import analyse_static
    from imubounds.stationary.stream import analyse_static_outofcore, route_outofcore

    read = {k: v for k, v in dict(settings.read).items() if v is not None}
    open_kw = {k: read[k] for k in ("rate_hz", "columns", "gyro_unit", "accel_unit",
                                    "time_unit") if k in read}  # fmt: skip
    big = route_outofcore(p, settings.memory_limit, **open_kw)
    if big is not None:
        chans = _channel_part(list(big.channels), part)
        res = analyse_static_outofcore(
            big, settings.static_settings(), channels=chans, memory_limit=settings.memory_limit
        )
    else:
        log = read_imu(p, **read)
        chans = _channel_part(log.channel_names(), part)
        res = analyse_static(log, settings.static_settings(), channels=chans)
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
            "tau": np.asarray(ch.allan.tau, dtype=np.float64),
            "adev": np.asarray(ch.allan.dev, dtype=np.float64),
        }


def analyse_batch(
    items: Sequence[tuple[str, str, tuple[int, int] | None]],
    settings: FleetSettings,
    numba_threads: int | None = None,
) -> list[dict[str, Any]]:
    """One task: :func:`analyse_unit` of each ``(source, unit, part)``.

    ``numba_threads`` caps the threads of the parallel Allan kernels and of the
    CSV parser (pyarrow) in this task (on Dask workers by default the cores
    shared among the worker threads: the fleet is parallel across units, and
    workers x threads beyond the cores only contend). The sums do not
    depend on the thread count (fixed task split, ``math.fsum`` reduction).
    """
    if numba_threads:
        import numba
        import pyarrow

        cap = int(numba.config.NUMBA_NUM_THREADS)  # type: ignore[attr-defined]
        numba.set_num_threads(max(1, min(int(numba_threads), cap)))
        pyarrow.set_cpu_count(max(1, int(numba_threads)))  # the CSV parser's threads
    return [analyse_unit(src, settings, part, unit=unit) for src, unit, part in items]


def warm_up(settings: FleetSettings | None = None) -> float:
    """Load (or compile) the numba kernels and import everything a unit needs, once per
    process, by analysing a 30 s simulated log written as CSV.gz; returns seconds taken.

    The fleet's Dask workers run it at start (a worker plugin), so that no unit's
    time includes the imports and kernel loading.
    """
    import tempfile

    from imubounds.stationary.noise_sim import NoiseSpec, simulate, write_csv

    t0 = time.perf_counter()
    settings = settings or FleetSettings()
    spec = NoiseSpec.from_mapping({"gyro": {"N": 1e-3, "B": 1e-4}, "accel": {"N": 1e-3}})
    with tempfile.TemporaryDirectory(prefix="imubounds-warm-") as tmp:
        p = write_csv(simulate(spec, 100.0, 30.0, seed=0), Path(tmp) / "warm.csv.gz")
        warm = FleetSettings(taus=settings.taus if isinstance(settings.taus, str) else "octave",
                             estimator=settings.estimator, confidence=settings.confidence,
                             terms_from=settings.terms_from)  # fmt: skip
        analyse_unit(str(p), warm)
    return time.perf_counter() - t0


def _merge_parts(parts: list[dict[str, Any]]) -> dict[str, Any]:
    """One unit's result from the results of its channel parts (in part order)."""
    if len(parts) == 1:
        return parts[0]
    out = dict(parts[0])
    out["rows"] = [r for p in parts for r in p["rows"]]
    out["curves"] = {k: v for p in parts for k, v in p["curves"].items()}
    out["seconds"] = float(sum(p.get("seconds", 0.0) for p in parts))
    bad = [p for p in parts if p["status"] != "ok"]
    if bad:
        out.update(status="failed", error=bad[0]["error"], rows=[], curves={})
    return out


def _jsonable_result(res: dict[str, Any]) -> dict[str, Any]:
    """A unit result with its curves as float lists (for the cache)."""
    out = dict(res)
    out["curves"] = {ch: {k: [float(v) for v in c[k]] for k in ("tau", "adev")}
                     for ch, c in res.get("curves", {}).items()}  # fmt: skip
    return out


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

    A resolved term is compared by its value (criterion ``value``) or the upper
    end of its confidence interval (``ci_upper``): ``pass`` or ``fail``. A term
    the log did not resolve has no value, only an upper bound (``{term}_ub``, the
    curve's bound from its 99 % intervals as ``imubounds static`` uses it): it
    passes when that bound is within the limit, else it is ``undetermined``
    (never ``pass`` on a fit's 0, never ``fail`` on a bound).

    Columns: unit, channel, kind, term, value (the quantity compared, SI), basis
    (``value``, ``ci_upper`` or ``upper_bound``), term_status, limit (SI),
    margin (``1 - value/limit``), value_ieee, limit_ieee, unit_ieee, status
    (``pass``/``fail``/``undetermined``).
    """
    import pandas as pd

    from imubounds.units import to_ieee

    def num(x: Any) -> float:
        try:
            return float(x)
        except (TypeError, ValueError):
            return math.nan

    rows = []
    ok = df[df["status"] == "ok"]
    for rec in ok.to_dict("records"):
        kind = rec["kind"]
        for term, lim in spec.limits.get(kind, {}).items():
            # tables without per-term status (older runs): a positive value counts
            tstat = str(rec.get(f"{term}_status") or
                        ("resolved" if num(rec[term]) > 0 else "upper_bound"))  # fmt: skip
            hi = num(rec.get(f"{term}_hi"))
            if tstat == "resolved":
                basis = "ci_upper" if spec.criterion == "ci_upper" else "value"
                v = hi if basis == "ci_upper" else num(rec[term])
                ok_v = math.isfinite(v)
                status = ("pass" if v <= lim else "fail") if ok_v else "undetermined"
            else:  # the selection's bound: the curve's 99 % one (older tables: the CI's end)
                ub = num(rec.get(f"{term}_ub"))
                basis, v = "upper_bound", ub if math.isfinite(ub) else hi
                status = "pass" if math.isfinite(v) and v <= lim else "undetermined"
            margin = 1.0 - v / lim if math.isfinite(v) else math.nan
            iv, iu = to_ieee(kind, term, v)  # type: ignore[arg-type]
            rows.append({
                "unit": rec["unit"], "channel": rec["channel"], "kind": kind, "term": term,
                "value": v, "basis": basis, "term_status": tstat, "limit": lim,
                "margin": margin, "value_ieee": iv,
                "limit_ieee": to_ieee(kind, term, lim)[0], "unit_ieee": iu,  # type: ignore[arg-type]
                "status": status,
            })  # fmt: skip
    cols = ["unit", "channel", "kind", "term", "value", "basis", "term_status", "limit",
            "margin", "value_ieee", "limit_ieee", "unit_ieee", "status"]  # fmt: skip
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
    stats: Any = None  # fleet_stats.FleetStatistics
    drift: Any = None  # pandas.DataFrame (compare_fleets) or None
    compared_with: str = ""
    new_units: list[str] = field(default_factory=list)
    missing_units: list[str] = field(default_factory=list)
    drift_z: float = DEFAULT_DRIFT_Z

    @property
    def ok(self) -> bool:
        """Whether every unit was analysed."""
        return not self.failed

    def to_frame(self) -> Any:
        """The fleet table (one row per unit and channel)."""
        return self.table

    @property
    def failed(self) -> list[dict[str, str]]:
        bad = self.table[self.table["status"] == "failed"]
        return [{"unit": r["unit"], "path": r["path"], "error": r["error"]}
                for r in bad.to_dict("records")]  # fmt: skip

    def summary(self) -> dict[str, Any]:
        """The content of ``fleet.json``: counts, failures, term statistics, pass/fail."""
        from imubounds.stationary.fleet_stats import resolved_values
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
                # resolved terms only (as the statistics): an unresolved one is no value
                good = resolved_values(sub, term)
                v = sub[term].to_numpy(dtype=np.float64)[good]
                unit = to_ieee(kind, term, 1.0)[1]  # type: ignore[arg-type]
                if v.size == 0:
                    stats[kind][term] = {"n": 0, "n_unresolved": int(good.size), "unit_ieee": unit}
                    continue
                q = np.percentile(v, [0, 5, 50, 95, 100])
                conv = to_ieee(kind, term, 1.0)[0]  # type: ignore[arg-type]
                stats[kind][term] = {
                    "n": int(v.size),
                    "n_unresolved": int(good.size - v.size),
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
        if self.stats is not None:
            out["statistics"] = self.stats.to_json()
        if self.drift is not None:
            d = self.drift
            largest = {}
            for (kind, term), g in d.groupby(["kind", "term"]):
                r = g["ratio"].to_numpy(dtype=np.float64)
                r = r[np.isfinite(r) & (r > 0)]
                if r.size:
                    worst = r[np.argmax(np.abs(np.log(r)))]
                    largest[f"{kind}.{term}"] = float(worst)
            out["drift"] = {
                "compared_with": self.compared_with,
                "n_units_compared": int(d["unit"].nunique()) if len(d) else 0,
                "new_units": list(self.new_units),
                "missing_units": list(self.missing_units),
                "threshold_z": self.drift_z,
                "z_definition": "ln(value / previous) / sqrt(u^2 + u_previous^2), u the 1-sigma "
                                "uncertainty of ln(value) from its confidence interval",
                "units_drifted": sorted(set(d[d["drifted"]]["unit"])) if len(d) else [],
                "units_beyond_ci": sorted(set(d[d["beyond_ci"]]["unit"])) if len(d) else [],
                "largest_ratio": largest,
                "rows": [{k: (None if isinstance(v, float) and not math.isfinite(v) else v)
                          for k, v in rec.items()} for rec in d.to_dict("records")],
            }  # fmt: skip
        if self.spec is not None and self.passfail is not None:
            pf = self.passfail
            failing = sorted(set(pf[pf["status"] == "fail"]["unit"]))
            checked = sorted(set(pf["unit"]))
            # a unit with no failure but a term neither passed nor failed: undetermined
            open_ = sorted(set(pf[pf["status"] == "undetermined"]["unit"]) - set(failing))
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
                "n_pass": len([u for u in checked if u not in failing and u not in open_]),
                "n_fail": len(failing),
                "n_undetermined": len(open_),
                "units_failing": failing,
                "units_undetermined": open_,
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


def plan_work(
    sizes: Sequence[int], n_workers: int, min_split_bytes: int = 4 << 20
) -> list[tuple[int, tuple[int, int] | None]]:
    """Units of work: ``(unit index, channel part)``; a unit whole (part ``None``) or,
    when there are fewer units than workers, a log of at least ``min_split_bytes`` split
    by channel into ``(i, n)`` parts (n of 2, 3 or 6 contiguous slices of the six IMU
    channels, the fewest that give every worker a part).

    Each part reads the whole log again (reading a CSV.gz is about 40 % of a unit's
    time), so a split pays only when workers would otherwise be idle: 3 units on 2
    workers are not split (6 parts would read 6 logs for 3 units' analysis)."""
    n = len(sizes)
    w = max(1, n_workers)
    items: list[tuple[int, tuple[int, int] | None]] = []
    for i, size in enumerate(sizes):
        parts = 1
        if 0 < n < w and size >= min_split_bytes:
            parts = next((k for k in (2, 3, 6) if k >= math.ceil(w / n)), 6)
        if parts == 1:
            items.append((i, None))
        else:
            items.extend((i, (j, parts)) for j in range(parts))
    return items


def _failed_result(source: str, unit: str, error: str) -> dict[str, Any]:
    return {"path": source, "unit": unit, "status": "failed", "error": error, "rows": [],
            "curves": {}, "seconds": 0.0}  # fmt: skip


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
    -------
    FleetResult
    """
    from imubounds.io.outputs import ensure_dir, write_json, write_with
    from imubounds.stationary.fleet_stats import (
        compare_fleets,
        fleet_statistics,
        previous_confidence,
        read_previous,
    )

    t_start = time.perf_counter()
    settings = settings or FleetSettings()
    settings.check()
    report_progress = progress or (lambda _s, _d, _t: None)
    if spec is not None and not isinstance(spec, FleetSpec):
        spec = load_spec(spec)
    if not (math.isfinite(outlier_z) and outlier_z > 0):
        raise OptionError(f"outlier threshold must be a positive number, got {outlier_z}")
    if not (math.isfinite(drift_z) and drift_z > 0):
        raise OptionError(f"drift threshold must be a positive number, got {drift_z}")
    if n_workers < 0:
        raise OptionError(f"number of workers must be >= 0, got {n_workers}")
    previous = read_previous(compare) if compare is not None else None
    sources = expand_globs([str(p) for p in patterns])
    names = unit_names(sources)
    out = ensure_dir(outdir)
    if report:  # a report.html imubounds did not write is refused before the long run
        from imubounds.io.outputs import check_output_file

        check_output_file(out / "report.html", option="-o", advice=REPORT_ADVICE)
    cache = ensure_dir(out / ".cache")

    # ---- content keys and cache lookup (client side), one unit at a time: on Dask
    # (without channel splits) the client hashes the next task's logs while the
    # workers analyse the tasks already submitted, instead of hashing all logs first
    results: dict[int, dict[str, Any]] = {}
    keys: dict[int, str | None] = {}
    counts = {"hashed": 0, "cached": 0, "failed": 0, "done": 0}

    def lookup(i: int) -> bool:
        """Content key and cache lookup of unit ``i`` (once); whether it needs analysis."""
        if i in keys:
            return i not in results
        src = sources[i]
        try:
            key: str | None = content_key(src, settings)
        except (OSError, InputError) as err:
            key = None
            why = getattr(err, "strerror", None) or str(err)
            results[i] = _failed_result(src, names[i], f"{src}: cannot read ({why})")
            counts["failed"] += 1
        keys[i] = key
        hit = cache / f"{key}.json" if key is not None else None
        if hit is not None and hit.is_file():
            try:
                res = json.loads(hit.read_text(encoding="utf-8"))
                res["path"], res["unit"] = src, names[i]
                # JSON has no NaN: the cache holds null for an unresolved term
                res["rows"] = [{k: math.nan if v is None else v for k, v in row.items()}
                               for row in res["rows"]]  # fmt: skip
                results[i] = res
                counts["cached"] += 1
            except (OSError, ValueError):
                pass
        counts["hashed"] += 1
        report_progress("hash", counts["hashed"], len(sources))
        return i not in results

    serial = client is None and not scheduler and n_workers == 0
    local = client is None and not scheduler  # a local cluster would be started here
    pipelined = not serial and not split_channels
    lone = False  # one unit to analyse: this process, not a local cluster
    if pipelined:
        # hash up to the first units to analyse: a fleet all cached starts no cluster, and
        # a local cluster is started for two units or more only (one unit gains nothing
        # from it and would wait seconds for the workers' start-up)
        misses = 0
        for i in range(len(sources)):
            misses += lookup(i)
            if misses >= (2 if local else 1):
                break
        else:  # every unit looked up: one left to analyse runs here
            lone = local and misses == 1
        need = misses > 0
        serial = serial or lone
    else:
        need = any([lookup(i) for i in range(len(sources))])  # noqa: C419 - hash every unit

    # ---- analysis: units (or channel parts of long logs) grouped into tasks
    sched_name = ""
    n_tasks = 0
    if need:
        from contextlib import ExitStack

        with ExitStack() as stack:
            if serial:
                workers = 1
                sched_name = ("this process (one unit to analyse)" if lone
                              else "serial (this process)")  # fmt: skip
            else:
                client = client or stack.enter_context(
                    _open_client(scheduler, n_workers, threads_per_worker)
                )
                from imubounds.stationary._fleet_dask import ensure_warm

                ensure_warm(client, settings)
                sched_name = str(client.scheduler.address)
                info = list(client.scheduler_info().get("workers", {}).values())
                workers = sum(int(w.get("nthreads", 1)) for w in info) or max(1, n_workers)
                if numba_threads is None:
                    numba_threads = _kernel_threads(info)
            # pipelined: tasks planned over every unit, a cached one dropped from its task
            units = [i for i in range(len(sources)) if pipelined or i not in results]
            sizes = [source_size(sources[i]) for i in units]
            work = (plan_work(sizes, workers, min_split_bytes) if split_channels
                    else [(j, None) for j in range(len(sizes))])  # fmt: skip
            wsizes = [sizes[j] // (p[1] if p else 1) for j, p in work]
            groups = plan_tasks(wsizes, workers, target_task_bytes)
            parts: dict[int, list[dict[str, Any] | None]] = {}

            def to_do() -> int:
                """Units to analyse, as far as known (a pipelined total can still fall)."""
                return len(sources) - counts["cached"] - counts["failed"]

            def collect(items: list[tuple[int, int]], batch: list[dict[str, Any]]) -> None:
                for (i, k), res in zip(items, batch, strict=True):
                    parts[i][k] = res
                    if all(r is not None for r in parts[i]):
                        whole = _merge_parts([r for r in parts[i] if r is not None])
                        whole["unit"] = names[i]
                        results[i] = whole
                        counts["done"] += 1
                        ckey = keys[i]
                        if whole["status"] == "ok" and ckey is not None:
                            write_json(cache / f"{ckey}.json", _jsonable_result(whole),
                                       indent=None)  # fmt: skip
                report_progress("units", counts["done"], to_do())

            def task(g: list[int]) -> tuple[list[tuple[int, int]], list[Any]]:
                """The work items of group ``g`` still to analyse, and their arguments."""
                items: list[tuple[int, int]] = []
                args: list[tuple[str, str, tuple[int, int] | None]] = []
                for w in g:
                    j, part = work[w]
                    i = units[j]
                    if not lookup(i):
                        continue
                    parts.setdefault(i, [None] * (part[1] if part else 1))
                    items.append((i, part[0] if part is not None else 0))
                    args.append((sources[i], names[i], part))
                return items, args

            if serial:
                for g in groups:
                    items, args = task(g)
                    if items:
                        n_tasks += 1
                        collect(items, analyse_batch(args, settings, numba_threads))
            else:
                from dask.distributed import as_completed

                futures: dict[Any, list[tuple[int, int]]] = {}
                running = as_completed()

                def finish(fut: Any) -> None:
                    items = futures.pop(fut)
                    try:
                        batch = fut.result()
                    except Exception as err:  # noqa: BLE001 - worker died; report, go on
                        batch = [_failed_result(sources[i], names[i], f"task failed: {err}")
                                 for i, _ in items]  # fmt: skip
                    collect(items, batch)

                for g in groups:
                    items, args = task(g)
                    if not items:
                        continue
                    fut = client.submit(analyse_batch, args, settings, numba_threads,
                                        pure=False)  # fmt: skip
                    futures[fut] = items
                    running.add(fut)
                    n_tasks += 1
                    while running.has_ready():
                        finish(next(running))
                for fut in running:
                    finish(fut)

    ordered = [results[i] for i in range(len(sources))]
    for i, r in enumerate(ordered):
        r["unit"] = names[i]
    table = _rows_frame(ordered)
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
        for t in STAT_TERMS:
            sub = drift[drift["term"] == t].set_index(["unit", "channel"])
            rows_key = list(zip(table["unit"], table["channel"], strict=True))
            for col, src_col in ((f"{t}_prev", "previous"), (f"{t}_ratio", "ratio"),
                                 (f"{t}_diff", "diff"), (f"{t}_drift_z", "z")):  # fmt: skip
                m = sub[src_col].to_dict()
                table[col] = [m.get(k, math.nan) for k in rows_key]
            flags = sub["drifted"].to_dict()
            table[f"{t}_drifted"] = [bool(flags.get(k, False)) for k in rows_key]
    curves = {r["unit"]: r.get("curves", {}) for r in ordered if r["status"] == "ok"}
    passfail = check_spec(table, spec) if isinstance(spec, FleetSpec) else None
    result = FleetResult(
        table=table, curves=curves, settings=settings, passfail=passfail,
        spec=spec if isinstance(spec, FleetSpec) else None, n_cached=counts["cached"],
        scheduler=sched_name or "(all cached)", n_tasks=n_tasks, stats=stats, drift=drift,
        compared_with=str(compare) if compare is not None else "", new_units=new_units,
        missing_units=missing_units, drift_z=float(drift_z),
    )  # fmt: skip

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
    if plot and curves:
        from imubounds.report.static_plots import save_figure

        save_figure(fleet_figure(result), out / "fleet")
        files["plot"] = "fleet.png"
        files["plot_svg"] = "fleet.svg"
        save_figure(fleet_stats_figure(result), out / "fleet_stats")
        files["stats_plot"] = "fleet_stats.png"
        files["stats_plot_svg"] = "fleet_stats.svg"
    if report:
        files["report"] = "report.html"
    result.files = files
    result.seconds = time.perf_counter() - t_start
    write_json(out / "fleet.json", result.summary())
    record: dict[str, Any] = {"command_name": "fleet", "n_units": len(sources),
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
    return result


def _kernel_threads(workers: Sequence[Mapping[str, Any]]) -> int:
    """Threads for the Allan kernels in each task: the cores of this machine shared among
    the worker threads when every worker runs here (a local cluster), else 1."""
    import os
    import socket

    hosts = {str(w.get("host", "")) for w in workers}
    local = {"127.0.0.1", "localhost", "::1", socket.gethostname()}
    if workers and hosts <= local:
        threads = sum(int(w.get("nthreads", 1)) for w in workers)
        return max(1, (os.cpu_count() or 1) // max(1, threads))
    return 1


@contextmanager
def _open_client(scheduler: str | None, n_workers: int, threads_per_worker: int) -> Iterator[Any]:
    """A client of the scheduler at ``scheduler``, or of a new local cluster (closed after)."""
    from dask.distributed import Client

    if scheduler:
        try:
            client = Client(scheduler, timeout="20s")
        except (OSError, TimeoutError) as err:
            raise OptionError(
                f"cannot connect to the Dask scheduler at {scheduler!r} ({err}); "
                "check the address or omit --scheduler for a local cluster"
            ) from err
        with client:
            yield client
        return
    with local_cluster(n_workers, threads_per_worker) as cluster, Client(cluster) as client:
        yield client


#: Dask's nanny sets MALLOC_TRIM_THRESHOLD_=65536 in workers (to return memory to the
#: system early). Setting it makes glibc keep its mmap threshold at 128 KiB, so every
#: array of a unit is mapped and zero-filled afresh: measured 30x the page faults and
#: about 25 % more CPU per unit than the same analysis in a plain process. The
#: fleet's workers get :data:`imubounds.runtime.MALLOC_SETTINGS` instead.
_DASK_TRIM = ("MALLOC_TRIM_THRESHOLD_", "65536")

#: Worker settings of a fleet's local cluster: no statistical profiler (it samples
#: the task thread's stack every 10 ms under the GIL) and slower housekeeping ticks
#: (the event loop woke about 10 000 times a second, each time taking the GIL from
#: the analysis). A fleet task is seconds long; these only feed the dashboard.
FLEET_WORKER_CONFIG: dict[str, Any] = {
    "distributed.worker.profile.enabled": False,
    "distributed.admin.tick.interval": "1s",
    "distributed.admin.system-monitor.interval": "2s",
    "distributed.worker.memory.monitor-interval": "1s",
}


def local_cluster(
    n_workers: int = 2, threads_per_worker: int = 1, *, pin: bool = True, **kwargs: Any
) -> Any:
    """A ``dask.distributed.LocalCluster`` of worker processes set up for fleets.

    As ``LocalCluster(n_workers, threads_per_worker, processes=True)`` but with
    glibc malloc settings that keep freed memory for reuse
    (:data:`imubounds.runtime.MALLOC_SETTINGS`, instead of Dask's
    ``MALLOC_TRIM_THRESHOLD_=65536``, see :data:`_DASK_TRIM`; a value the user set
    in the environment is kept) and the quieter worker housekeeping of
    :data:`FLEET_WORKER_CONFIG`. With ``pin`` (default) and no more worker threads
    than cores, each worker is pinned to cores of its own (:func:`_pin_workers`).
    The caller closes it.
    """
    import os

    import dask
    from dask.distributed import LocalCluster

    from imubounds.runtime import malloc_environment

    name, dask_value = _DASK_TRIM
    inherited = os.environ.get(name)
    if inherited == dask_value:  # left by an earlier Dask nanny in this process
        del os.environ[name]
    environ = malloc_environment()
    try:
        with dask.config.set({
            **FLEET_WORKER_CONFIG,
            **{f"distributed.nanny.pre-spawn-environ.{k}": v for k, v in environ.items()},
        }):  # fmt: skip
            cluster = LocalCluster(
                n_workers=max(1, n_workers),
                threads_per_worker=max(1, threads_per_worker),
                processes=True,
                dashboard_address=kwargs.pop("dashboard_address", ":0"),
                **kwargs,
            )
    finally:
        if inherited is not None:
            os.environ[name] = inherited
    if pin:
        _pin_workers(cluster, max(1, threads_per_worker))
    return cluster


def _pin_workers(cluster: Any, threads_per_worker: int) -> list[set[int]]:
    """Pin worker ``i`` of a local cluster (every thread of its process) to cores
    ``i*t .. i*t+t-1`` of this process's allowed cores, when the workers' threads fit
    (Linux; else nothing). Returns the sets given.

    Measured on 2 cores, 16 units on 2 workers: 8 % less wall time (3.89 s against
    4.26 s, median of 9 runs): unpinned, the two workers and the client's scheduler
    thread migrate between the cores and the workers lose their caches. A restarted
    worker is not pinned again (it runs, unpinned).
    """
    import os

    if not hasattr(os, "sched_setaffinity"):
        return []
    cpus = sorted(os.sched_getaffinity(0))
    procs = [getattr(getattr(n, "process", None), "process", None)
             for n in getattr(cluster, "workers", {}).values()]  # fmt: skip
    pids = [int(p.pid) for p in procs if p is not None and p.pid]
    if len(pids) < 2 or len(pids) * threads_per_worker > len(cpus):
        return []
    given = []
    for i, pid in enumerate(pids):
        mine = set(cpus[i * threads_per_worker : (i + 1) * threads_per_worker])
        try:
            for tid in os.listdir(f"/proc/{pid}/task"):
                os.sched_setaffinity(int(tid), mine)
        except OSError:  # the worker went away, or no permission: leave it free
            continue
        given.append(mine)
    return given


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


def fleet_stats_figure(result: FleetResult) -> Any:
    """Box plots of N, B, K across units, one box per channel, in IEEE units (log scale).

    One row per sensor kind, one column per term. Each unit is a dot; units
    flagged as outliers (``|z|`` above the threshold) are red and labelled;
    the spec limit is a dashed red line when given.
    """
    import matplotlib.pyplot as plt

    from imubounds.units import to_ieee

    t = result.table
    ok = t[t["status"] == "ok"]
    kinds = [k for k in ("gyro", "accel") if (ok["kind"] == k).any()] or ["gyro"]
    fig, axes = plt.subplots(len(kinds), len(STAT_TERMS), figsize=(13, 3.6 * len(kinds)),
                             layout="constrained", squeeze=False)  # fmt: skip
    rng = np.random.default_rng(0)
    thr = result.stats.threshold if result.stats is not None else DEFAULT_OUTLIER_Z
    for r, kind in enumerate(kinds):
        sub = ok[ok["kind"] == kind]
        chans = list(dict.fromkeys(sub["channel"]))
        for c, term in enumerate(STAT_TERMS):
            ax = axes[r, c]
            conv, unit = to_ieee(kind, term, 1.0)  # type: ignore[arg-type]
            data, pos = [], []
            for j, ch in enumerate(chans):
                g = sub[sub["channel"] == ch]
                v = g[term].to_numpy(dtype=np.float64) * conv
                good = np.isfinite(v) & (v > 0)
                if not good.any():
                    continue
                data.append(v[good])
                pos.append(j)
                flag = g.get(f"{term}_outlier", False)
                flag = np.asarray(flag, dtype=bool)[good] if np.ndim(flag) else np.zeros(
                    good.sum(), dtype=bool)  # fmt: skip
                x = j + rng.uniform(-0.15, 0.15, v[good].size)
                ax.scatter(x[~flag], v[good][~flag], s=10, color="0.3", zorder=3)
                if flag.any():
                    ax.scatter(x[flag], v[good][flag], s=28, color="red", zorder=4,
                               label=f"outlier (|z| > {thr:g})")  # fmt: skip
                    names = g["unit"].to_numpy()[good][flag]
                    for xi, yi, u in zip(x[flag], v[good][flag], names, strict=True):
                        ax.annotate(str(u), (xi, yi), fontsize=7, color="red",
                                    xytext=(4, 2), textcoords="offset points")  # fmt: skip
            if data:
                ax.boxplot(data, positions=pos, widths=0.5, showfliers=False)
                ax.set_yscale("log")
            else:
                ax.text(0.5, 0.5, f"no {kind} {term} value", ha="center",
                        transform=ax.transAxes)  # fmt: skip
            ax.set_xticks(range(len(chans)), chans, fontsize=8)
            if result.spec is not None and term in result.spec.limits.get(kind, {}):
                ax.axhline(result.spec.limits[kind][term] * conv, color="red", ls="--", lw=1.2,
                           label="spec limit")  # fmt: skip
            ax.set_ylabel(f"{kind} {term} [{unit}]")
            ax.set_title(f"{kind} {term} across units ({result.settings.terms_from})")
            ax.grid(True, which="both", axis="y", alpha=0.3)
            handles, labels = ax.get_legend_handles_labels()
            if handles:
                uniq = dict(zip(labels, handles, strict=True))
                ax.legend(uniq.values(), uniq.keys(), fontsize=7)
    n_out = len(set(result.stats.outliers["unit"])) if result.stats is not None else 0
    fig.suptitle(f"Noise terms across {len(set(ok['unit']))} units: box = quartiles, "
                 f"whiskers 1.5 IQR; {n_out} unit(s) flagged")  # fmt: skip
    return fig
