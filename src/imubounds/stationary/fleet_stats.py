"""Fleet statistics: the spread of the noise terms across units, outliers, drift (issue 15).

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
  term to the previous value (SI and IEEE units), and whether the two
  confidence intervals are disjoint (a change beyond the statistical
  uncertainty of either characterisation).

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
    "DEFAULT_OUTLIER_Z",
    "MAD_SCALE",
    "STAT_TERMS",
    "FleetStatistics",
    "compare_fleets",
    "fleet_statistics",
    "read_previous",
]

STAT_TERMS: tuple[str, ...] = ("N", "B", "K")
DEFAULT_OUTLIER_Z = 3.5
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
            valid = np.isfinite(v) & (v > 0)
            vv = v[valid]
            rec: dict[str, Any] = {"kind": kind, "channel": ch, "term": t, "n": int(vv.size),
                                   "unit_si": unit_si, "unit_ieee": unit_ieee}  # fmt: skip
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


def compare_fleets(
    table: Any, previous: Any, terms: Sequence[str] = STAT_TERMS
) -> tuple[Any, list[str], list[str]]:
    """Drift of each unit's terms since a previous fleet run.

    Returns ``(drift, new_units, missing_units)``: ``drift`` has one row per
    unit, channel and term present (and analysed) in both runs: value,
    previous, ratio (value / previous), diff (value - previous) in SI and
    IEEE units, and ``beyond_ci`` (the two confidence intervals are disjoint);
    ``new_units`` are only in ``table``, ``missing_units`` only in ``previous``.
    """
    import pandas as pd

    cur = table[table["status"] == "ok"]
    prev = previous[previous["status"] == "ok"]
    cur_units, prev_units = set(cur["unit"]), set(prev["unit"])
    pidx = {(r["unit"], r["channel"]): r for r in prev.to_dict("records")}
    rows = []
    for r in cur.to_dict("records"):
        q = pidx.get((r["unit"], r["channel"]))
        if q is None:
            continue
        for t in terms:
            if t not in r or t not in q:
                continue
            unit_si, conv, unit_ieee = _units(str(r["kind"]), t)
            v, w = float(r[t]), float(q[t])
            lo, hi = float(r.get(f"{t}_lo", math.nan)), float(r.get(f"{t}_hi", math.nan))
            plo, phi = float(q.get(f"{t}_lo", math.nan)), float(q.get(f"{t}_hi", math.nan))
            beyond = bool(
                all(math.isfinite(x) for x in (lo, hi, plo, phi)) and (lo > phi or hi < plo)
            )
            rows.append({
                "unit": r["unit"], "channel": r["channel"], "kind": r["kind"], "term": t,
                "value": v, "previous": w, "ratio": v / w if w != 0 else math.nan,
                "diff": v - w, "value_ieee": v * conv, "previous_ieee": w * conv,
                "diff_ieee": (v - w) * conv, "unit_si": unit_si, "unit_ieee": unit_ieee,
                "beyond_ci": beyond,
            })  # fmt: skip
    cols = ["unit", "channel", "kind", "term", "value", "previous", "ratio", "diff", "value_ieee",
            "previous_ieee", "diff_ieee", "unit_si", "unit_ieee", "beyond_ci"]  # fmt: skip
    drift = pd.DataFrame(rows, columns=cols)
    return drift, sorted(cur_units - prev_units), sorted(prev_units - cur_units)
