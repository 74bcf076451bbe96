"""Fleet statistics: the spread of the noise terms across units, outliers, drift
(docs/fleet.md, "statistics in fleet.json").

For every channel (``gyro_x`` ... ``accel_z``) and term (N, B, K), across the
units of a fleet that were analysed:

* the distribution: median, 25th and 75th percentiles, IQR and the robust
  spread ``1.4826 * MAD`` (the standard deviation for normal data), in SI and
  IEEE 952 units;
* a robust z-score per unit. Noise terms are scale parameters (a unit twice as
  noisy is as far off as one half as noisy), so z is taken on the logarithm::

      z = (ln v - median(ln v)) / s,    s = max(1.4826 * MAD(ln v), u)

  where ``u`` is the median over units of the 1-sigma statistical uncertainty
  of ``ln v`` from each unit's own confidence interval: a fleet of identical
  units is not flagged for its estimation noise. ``exp(z * s)`` is the unit's
  ratio to the fleet median (exactly so for an odd number of units).
  A unit is an outlier on a term when ``|z| > threshold`` (default 3.5, the
  modified-z rule of Iglewicz and Hoaglin); z is not given with fewer than
  3 units;
* with a previous fleet run, each unit's drift: ratio and difference of each
  term to the previous value (SI and IEEE units) and a z-score of the change
  on the log scale against both characterisations' statistical uncertainty::

      z = ln(v / w) / sqrt(u_v^2 + u_w^2)

  with ``u`` the 1-sigma uncertainty of ``ln v`` from each run's confidence
  interval; a change is flagged (``drifted``) when ``|z| > threshold`` (default
  3.5). Whether the two confidence intervals are disjoint (``beyond_ci``) is
  also given, but it is no test: two 1-sigma intervals of the same unchanged
  unit are disjoint about 16 % of the time.

Only terms the log resolved (status ``resolved`` in the fleet table) enter the
statistics and the drift: an unresolved term's value is a fit's 0 or a share too
small to read, and its interval is only an upper bound.

Nothing here reads or writes files except :func:`read_previous`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from imubounds.errors import InputError, OptionError

__all__ = [
    "DEFAULT_DRIFT_Z",
    "DEFAULT_OUTLIER_Z",
    "MAD_SCALE",
    "STAT_TERMS",
    "FleetStatistics",
    "compare_fleets",
    "fleet_statistics",
    "log_sigma",
    "previous_confidence",
    "read_previous",
    "resolved_values",
]

STAT_TERMS: tuple[str, ...] = ("N", "B", "K")
DEFAULT_OUTLIER_Z = 3.5
#: |z| of a change since the previous run above which a unit's term has drifted.
DEFAULT_DRIFT_Z = 3.5
#: 1.4826 * MAD estimates the standard deviation of normal data.
MAD_SCALE = 1.482602218505602
MIN_UNITS_FOR_Z = 3


@dataclass
class FleetStatistics:
    """Output of :func:`fleet_statistics`.

    ``table``: one row per channel and term (distribution, SI and IEEE units);
    ``scores``: the fleet table's index with ``{term}_z`` and ``{term}_outlier``
    columns; ``outliers``: one row per flagged (unit, channel, term);
    ``threshold``: the ``|z|`` above which a unit is flagged.
    """

    table: Any
    scores: Any
    outliers: Any
    threshold: float

    def to_json(self) -> dict[str, Any]:
        """The ``statistics`` block of ``fleet.json`` (records with their units)."""
        return {
            "threshold_z": self.threshold,
            "z_definition": "(ln v - median(ln v)) / max(1.4826 MAD(ln v), median CI 1-sigma)",
            "terms": _records(self.table),
            "outliers": _records(self.outliers),
            "units_outlying": sorted(set(self.outliers["unit"])) if len(self.outliers) else [],
        }


def _records(df: Any) -> list[dict[str, Any]]:
    out = []
    for rec in df.to_dict("records"):
        out.append({k: (None if isinstance(v, float) and not math.isfinite(v) else v)
                    for k, v in rec.items()})  # fmt: skip
    return out


def _units(kind: str, term: str) -> tuple[str, float, str]:
    from imubounds.units import IEEE_UNITS, SI_UNITS

    ieee, conv = IEEE_UNITS[kind][term]  # type: ignore[index]
    return SI_UNITS[kind][term], conv, ieee  # type: ignore[index]


def resolved_values(df: Any, term: str) -> Any:
    """Boolean mask of the rows whose ``term`` was resolved: status ``resolved`` (in a
    table with ``{term}_status``; older tables: any) and a finite value > 0."""
    v = df[term].to_numpy(dtype=np.float64)
    ok = np.isfinite(v) & (v > 0)
    col = f"{term}_status"
    if col in df:
        ok &= (df[col] == "resolved").to_numpy()
    return ok


def log_sigma(value: float, lo: float, hi: float, confidence: float) -> float:
    """1-sigma uncertainty of ``ln value`` from its confidence interval ``(lo, hi)`` at
    ``confidence`` (the half-width on the log scale; the upper side when ``lo`` is 0);
    nan when the interval says nothing."""
    z = _sigma_factor(confidence)
    if not (math.isfinite(value) and value > 0 and math.isfinite(hi) and hi > value):
        return math.nan
    if math.isfinite(lo) and 0 < lo < value:
        return 0.5 * math.log(hi / lo) / z
    return math.log(hi / value) / z


def _sigma_factor(confidence: float) -> float:
    from scipy.stats import norm

    return float(norm.ppf(0.5 + 0.5 * confidence))


def fleet_statistics(
    table: Any,
    threshold: float = DEFAULT_OUTLIER_Z,
    confidence: float = 0.683,
    terms: Sequence[str] = STAT_TERMS,
) -> FleetStatistics:
    """Per channel and term: distribution across units, robust z-scores and outliers.

    Parameters
    ----------
    table : pandas.DataFrame
        The fleet table (one row per unit and channel; columns ``unit``,
        ``channel``, ``kind``, ``status`` and, per term, the SI value ``{t}``
        with its confidence interval ``{t}_lo``, ``{t}_hi``).
    threshold : float
        Units with ``|z| > threshold`` are flagged.
    confidence : float
        Confidence level of the intervals in ``table`` (to turn them into 1 sigma).
    """
    import pandas as pd

    if not (math.isfinite(threshold) and threshold > 0):
        raise OptionError(f"outlier threshold must be a positive number, got {threshold}")
    ok_mask = (table["status"] == "ok") if "status" in table else pd.Series(False, table.index)
    ok = table[ok_mask]
    zc = _sigma_factor(confidence)
    scores = pd.DataFrame(index=table.index)
    for t in terms:
        scores[f"{t}_z"] = np.nan
        scores[f"{t}_outlier"] = False
    rows: list[dict[str, Any]] = []
    flagged: list[dict[str, Any]] = []
    channels = list(dict.fromkeys(ok["channel"])) if len(ok) else []
    for ch in channels:
        sub = ok[ok["channel"] == ch]
        kind = str(sub["kind"].iloc[0])
        for t in terms:
            if t not in sub:
                continue
            unit_si, conv, unit_ieee = _units(kind, t)
            v = sub[t].to_numpy(dtype=np.float64)
            valid = resolved_values(sub, t)
            vv = v[valid]
            rec: dict[str, Any] = {"kind": kind, "channel": ch, "term": t, "n": int(vv.size),
                                   "unit_si": unit_si, "unit_ieee": unit_ieee,
                                   "n_outliers": 0}  # fmt: skip
            if vv.size == 0:
                rows.append(rec)
                continue
            med = float(np.median(vv))
            p25, p75 = (float(q) for q in np.percentile(vv, [25, 75]))
            spread = MAD_SCALE * float(np.median(np.abs(vv - med)))
            lv = np.log(vv)
            lmed = float(np.median(lv))
            lmad = MAD_SCALE * float(np.median(np.abs(lv - lmed)))
            floor = math.nan
            if f"{t}_lo" in sub and f"{t}_hi" in sub:
                lo = sub[f"{t}_lo"].to_numpy(dtype=np.float64)[valid]
                hi = sub[f"{t}_hi"].to_numpy(dtype=np.float64)[valid]
                good = np.isfinite(lo) & np.isfinite(hi) & (lo > 0) & (hi > lo)
                if good.any():
                    floor = float(np.median(0.5 * np.log(hi[good] / lo[good]))) / zc
            s = max(lmad, floor) if math.isfinite(floor) else lmad
            rec.update({
                "median": med, "p25": p25, "p75": p75, "iqr": p75 - p25, "spread": spread,
                "median_ieee": med * conv, "p25_ieee": p25 * conv, "p75_ieee": p75 * conv,
                "iqr_ieee": (p75 - p25) * conv, "spread_ieee": spread * conv,
                "log_spread": s, "log_mad": lmad, "log_ci_sigma": floor, "n_outliers": 0,
            })  # fmt: skip
            if vv.size >= MIN_UNITS_FOR_Z and s > 0:
                idx = sub.index[valid]
                z = (lv - lmed) / s
                scores.loc[idx, f"{t}_z"] = z
                out = np.abs(z) > threshold
                scores.loc[idx, f"{t}_outlier"] = out
                rec["n_outliers"] = int(out.sum())
                for i, zi, vi in zip(idx[out], z[out], vv[out], strict=True):
                    flagged.append({
                        "unit": table.at[i, "unit"], "channel": ch, "kind": kind, "term": t,
                        "value": float(vi), "median": med, "ratio_to_median": float(vi / med),
                        "z": float(zi), "value_ieee": float(vi) * conv, "median_ieee": med * conv,
                        "unit_si": unit_si, "unit_ieee": unit_ieee,
                    })  # fmt: skip
            rows.append(rec)
    cols = ["kind", "channel", "term", "n", "median", "p25", "p75", "iqr", "spread", "unit_si",
            "median_ieee", "p25_ieee", "p75_ieee", "iqr_ieee", "spread_ieee", "unit_ieee",
            "log_spread", "log_mad", "log_ci_sigma", "n_outliers"]  # fmt: skip
    ocols = ["unit", "channel", "kind", "term", "value", "median", "ratio_to_median", "z",
             "value_ieee", "median_ieee", "unit_si", "unit_ieee"]  # fmt: skip
    stats = pd.DataFrame(rows, columns=cols)
    outliers = pd.DataFrame(flagged, columns=ocols)
    if len(outliers):
        outliers = outliers.sort_values(["unit", "channel", "term"], ignore_index=True)
    return FleetStatistics(stats, scores, outliers, float(threshold))


def read_previous(path: str | Path) -> Any:
    """The table of a previous fleet run: ``DIR/fleet.parquet`` (or the file itself).

    Raises
    ------
    InputError
        When there is no readable fleet table there.
    """
    import pandas as pd

    p = Path(path)
    f = p / "fleet.parquet" if p.is_dir() else p
    if not f.is_file():
        raise InputError(
            f"{p}: no fleet.parquet there; give --compare the -o directory of a previous fleet run"
        )
    try:
        df = pd.read_parquet(f)
    except Exception as err:  # noqa: BLE001 - pyarrow raises many types for a bad file
        msg = " ".join(str(err).split())[:120]
        raise InputError(f"{f}: not a readable fleet table ({msg})") from err
    need = {"unit", "channel", "status", *STAT_TERMS}
    missing = sorted(need - set(df.columns))
    if missing:
        raise InputError(
            f"{f}: not a fleet table (no column {', '.join(missing)}); "
            "give --compare the -o directory of a previous fleet run"
        )
    return df


def previous_confidence(path: str | Path) -> float | None:
    """The confidence level of a previous fleet run's intervals, from the ``fleet.json``
    beside its ``fleet.parquet`` (``None`` when it cannot be read)."""
    import json

    p = Path(path)
    d = p if p.is_dir() else p.parent
    try:
        doc = json.loads((d / "fleet.json").read_text(encoding="utf-8"))
        c = float(doc["settings"]["confidence"])
    except (OSError, ValueError, KeyError, TypeError):
        return None
    return c if 0 < c < 1 else None


def compare_fleets(
    table: Any,
    previous: Any,
    terms: Sequence[str] = STAT_TERMS,
    *,
    confidence: float = 0.683,
    previous_confidence: float | None = None,
    threshold: float = DEFAULT_DRIFT_Z,
) -> tuple[Any, list[str], list[str]]:
    """Drift of each unit's terms since a previous fleet run.

    Returns ``(drift, new_units, missing_units)``: ``drift`` has one row per
    unit, channel and term present (and analysed) in both runs: value,
    previous, ratio (value / previous), diff (value - previous) in SI and
    IEEE units, ``z`` (the change on the log scale over both runs' 1-sigma
    uncertainty), ``drifted`` (``|z| > threshold``) and ``beyond_ci`` (the two
    confidence intervals are disjoint: no test, see the module docstring).
    Ratio, difference and z are nan unless the term was resolved in both runs.
    ``confidence`` is that of ``table``'s intervals, ``previous_confidence``
    that of ``previous`` (default the same). ``new_units`` are only in
    ``table``, ``missing_units`` only in ``previous``.
    """
    import pandas as pd

    if not (math.isfinite(threshold) and threshold > 0):
        raise OptionError(f"drift threshold must be a positive number, got {threshold}")
    pconf = confidence if previous_confidence is None else previous_confidence

    cur = table[table["status"] == "ok"]
    prev = previous[previous["status"] == "ok"]
    cur_units, prev_units = set(cur["unit"]), set(prev["unit"])
    res_cur = {t: resolved_values(cur, t) for t in terms if t in cur}
    res_prev = {t: resolved_values(prev, t) for t in terms if t in prev}
    pidx = {(r["unit"], r["channel"]): (j, r) for j, r in enumerate(prev.to_dict("records"))}
    rows = []
    for i, r in enumerate(cur.to_dict("records")):
        hit = pidx.get((r["unit"], r["channel"]))
        if hit is None:
            continue
        j, q = hit
        for t in terms:
            if t not in res_cur or t not in res_prev:
                continue
            unit_si, conv, unit_ieee = _units(str(r["kind"]), t)
            v, w = float(r[t]), float(q[t])
            lo, hi = float(r.get(f"{t}_lo", math.nan)), float(r.get(f"{t}_hi", math.nan))
            plo, phi = float(q.get(f"{t}_lo", math.nan)), float(q.get(f"{t}_hi", math.nan))
            both = bool(res_cur[t][i] and res_prev[t][j])
            beyond = both and bool(
                all(math.isfinite(x) for x in (lo, hi, plo, phi)) and (lo > phi or hi < plo)
            )
            z = math.nan
            if both:
                u = math.hypot(log_sigma(v, lo, hi, confidence), log_sigma(w, plo, phi, pconf))
                if math.isfinite(u) and u > 0:
                    z = math.log(v / w) / u
            ratio, diff = (v / w, v - w) if both else (math.nan, math.nan)
            rows.append({
                "unit": r["unit"], "channel": r["channel"], "kind": r["kind"], "term": t,
                "value": v, "previous": w, "ratio": ratio, "diff": diff,
                "value_ieee": v * conv, "previous_ieee": w * conv, "diff_ieee": diff * conv,
                "unit_si": unit_si, "unit_ieee": unit_ieee, "z": z,
                "drifted": bool(abs(z) > threshold), "beyond_ci": beyond,
            })  # fmt: skip
    cols = ["unit", "channel", "kind", "term", "value", "previous", "ratio", "diff", "value_ieee",
            "previous_ieee", "diff_ieee", "unit_si", "unit_ieee", "z", "drifted",
            "beyond_ci"]  # fmt: skip
    drift = pd.DataFrame(rows, columns=cols)
    return drift, sorted(cur_units - prev_units), sorted(prev_units - cur_units)
