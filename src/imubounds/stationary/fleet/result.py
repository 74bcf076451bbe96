"""What a fleet run produced: :class:`FleetResult` (the table of every unit and channel,
the curves, statistics, drift and pass/fail) and its summary, the content of
``fleet.json``."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from imubounds.stationary.fleet.settings import TERMS, FleetSettings
from imubounds.stationary.fleet.spec import FleetSpec
from imubounds.stationary.fleet_stats import DEFAULT_DRIFT_Z
from imubounds.version import __version__

__all__ = ["FORMAT", "FleetResult", "rows_frame"]

FORMAT = "imubounds.stationary.fleet/1"


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

    def plot(self) -> Any:
        """The fleet figure (Allan-curve bundles and term histograms), a matplotlib Figure:
        :func:`imubounds.report.fleet_plots.fleet_figure`."""
        from imubounds.report.fleet_plots import fleet_figure

        return fleet_figure(self)

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


def rows_frame(results: list[dict[str, Any]]) -> Any:
    """The fleet table: one row per unit and channel, one row for a failed unit."""
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
