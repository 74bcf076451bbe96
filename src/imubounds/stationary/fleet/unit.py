"""One unit of a fleet: the static pipeline on one log (or on a slice of its channels),
as ``imubounds static`` would run it without models; never raises.

A unit's result is a plain dict (it travels to and from Dask workers and into the
cache): ``{"path", "unit", "status": "ok"|"failed", "error", "rows", "curves",
"seconds"}``.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from imubounds.errors import ImuboundsError
from imubounds.stationary.fleet.settings import TERMS, FleetSettings
from imubounds.stationary.fleet.sources import local_copy, unit_names

__all__ = [
    "analyse_batch",
    "analyse_unit",
    "failed_result",
    "merge_parts",
    "warm_up",
]


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
        with local_copy(src) as copy:
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


def merge_parts(parts: list[dict[str, Any]]) -> dict[str, Any]:
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


def failed_result(source: str, unit: str, error: str) -> dict[str, Any]:
    """The result of a unit that could not be analysed (or not even read)."""
    return {"path": source, "unit": unit, "status": "failed", "error": error, "rows": [],
            "curves": {}, "seconds": 0.0}  # fmt: skip
