"""The fleet section of the report (:mod:`imubounds.report.html`)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from imubounds.report._html_parts import _e, _img, _listed, _num, _table

FLEET_FIGURES = (
    ("fleet", "Allan deviation of every unit (faint) with the fleet median; histograms of N, B, K"),
    ("fleet_stats", "N, B, K across units per channel (box: quartiles); outliers in red"),
)


def _fleet_section(d: Path, summ: dict[str, Any]) -> tuple[str, list[str]]:
    """The fleet section: counts, failures, term statistics, outliers, spec, drift."""
    warnings: list[str] = []
    parts = ["<section id='fleet'><h2>Fleet</h2>"]
    parts.append(
        f"<p>{_num(summ.get('n_units'))} units: {_num(summ.get('n_ok'))} analysed "
        f"({_num(summ.get('n_cached'))} from the cache), {_num(summ.get('n_failed'))} failed; "
        f"terms from the {_e(summ.get('terms_from', 'fit'))}, "
        f"{_e(summ.get('scheduler', ''))}, {_num(summ.get('seconds'), 3)} s.</p>"
    )
    failed = summ.get("failed") or []
    if failed:
        warnings += [f"unit {f.get('unit')} failed: {f.get('error')}" for f in failed]
        parts.append("<h3>Failed units</h3>" + _table(
            ["unit", "error"],
            [[_e(f.get("unit")), _e(f.get("error"))]
             for f in failed]))  # fmt: skip
    for stem, caption in FLEET_FIGURES:
        if _listed(d, f"{stem}.png"):
            parts.append(_img(d / f"{stem}.png", caption))
    stats = summ.get("statistics") or {}
    if stats.get("terms"):
        thr = stats.get("threshold_z")
        parts.append(
            "<h3>Noise terms across units</h3><p class='muted'>Per channel: median, quartiles, "
            "IQR and robust spread (1.4826 MAD) in IEEE units; a unit is an outlier when "
            f"|z| &gt; {_num(thr)}, z = {_e(stats.get('z_definition', ''))}.</p>"
        )
        rows = []
        for r in stats["terms"]:
            rows.append([
                _e(r.get("channel")), _e(r.get("term")), _num(r.get("n")),
                _num(r.get("median_ieee")), _num(r.get("p25_ieee")), _num(r.get("p75_ieee")),
                _num(r.get("iqr_ieee")), _num(r.get("spread_ieee")), _e(r.get("unit_ieee", "")),
                _num(r.get("n_outliers")),
            ])  # fmt: skip
        parts.append(_table(["channel", "term", "units resolving it", "median", "p25", "p75",
                             "IQR", "spread", "IEEE unit", "outliers"], rows))  # fmt: skip
        outl = stats.get("outliers") or []
        if outl:
            parts.append("<h3>Outliers</h3>" + _table(
                ["unit", "channel", "term", "value", "fleet median", "IEEE unit", "× median",
                 "z"],
                [[_e(o.get("unit")), _e(o.get("channel")), _e(o.get("term")),
                  _num(o.get("value_ieee")), _num(o.get("median_ieee")),
                  _e(o.get("unit_ieee", "")), _num(o.get("ratio_to_median"), 3),
                  _num(o.get("z"), 3)] for o in outl]))  # fmt: skip
            units = ", ".join(map(str, stats.get("units_outlying") or []))
            warnings.append(f"fleet: outlying unit(s) {units} (|z| > {_num(thr)})")
        else:
            parts.append(f"<p class='ok'>No unit outlying (|z| &gt; {_num(thr)}).</p>")
    sp = summ.get("spec")
    if isinstance(sp, dict):
        cls = "ok" if not sp.get("n_fail") else "bad"
        failing = ", ".join(map(str, sp.get("units_failing") or []))
        parts.append(
            f"<h3>Datasheet spec {_e(sp.get('name', ''))}</h3><p class='{cls}'>"
            f"{_num(sp.get('n_pass'))} pass, {_num(sp.get('n_fail'))} fail "
            f"(criterion {_e(sp.get('criterion', ''))})"
            + (f": {_e(failing)}" if failing else "")
            + (f"; undetermined (a term not resolved, its upper bound above the limit): "
               f"{_e(', '.join(map(str, sp.get('units_undetermined') or [])))}"
               if sp.get("units_undetermined") else "") + "</p>"
        )
    drift = summ.get("drift")
    if isinstance(drift, dict):
        parts.append(
            f"<h3>Drift since {_e(drift.get('compared_with', ''))}</h3><p>"
            f"{_num(drift.get('n_units_compared'))} units compared; drifted (|z| &gt; "
            f"{_num(drift.get('threshold_z'))}, the change on the log scale over both runs' "
            f"combined uncertainty): {_e(', '.join(drift.get('units_drifted') or []) or 'none')}"
            + (f"; new units: {_e(', '.join(drift['new_units']))}" if drift.get("new_units")
               else "")
            + (f"; units gone: {_e(', '.join(drift['missing_units']))}"
               if drift.get("missing_units") else "") + "</p>"
        )  # fmt: skip
        rows = []
        for r in drift.get("rows") or []:
            moved = bool(r.get("drifted"))
            rows.append([
                _e(r.get("unit")), _e(r.get("channel")), _e(r.get("term")),
                _num(r.get("previous_ieee")), _num(r.get("value_ieee")),
                _num(r.get("diff_ieee")), _e(r.get("unit_ieee", "")), _num(r.get("ratio"), 3),
                _num(r.get("z"), 2),
                f"<span class='{'bad' if moved else 'ok'}'>{'yes' if moved else 'no'}</span>",
            ])  # fmt: skip
        parts.append(_table(["unit", "channel", "term", "previous", "now", "difference",
                             "IEEE unit", "ratio", "z", "drifted"], rows))  # fmt: skip
    parts.append("</section>")
    return "".join(parts), warnings


# ----------------------------------------------------------------------- the summary
