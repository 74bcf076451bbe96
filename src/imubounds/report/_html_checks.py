"""The report's checks of a static log (:mod:`imubounds.report.html`): where the five terms
leave the curve (``noise.selected.misfit``), whether the white level is the same at
every τ where N dominates (``noise.white_level``), how long to record (``record_length``), is
the log stationary and did it warm up (``stationarity``, ``stationarity.png``), and what
assuming a constant sample rate costs (``timing``). The shapes are those of
docs/schemas.md (noise.json)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from imubounds.report._html_parts import _e, _img, _listed, _num, _table

_TERMS = ("N", "B", "K")


def _hours(h: Any) -> str:
    if h is None:
        return "—"
    try:
        x = float(h)
    except (TypeError, ValueError):
        return _e(h)
    if x < 1 / 60:
        return "< 1 min"
    return f"{_num(x * 60, 2)} min" if x < 1 else f"{_num(x, 3)} h"


def _misfit_rows(channels: dict[str, Any]) -> list[list[str]]:
    rows = []
    for ch, c in channels.items():
        sel = ((c or {}).get("noise") or {}).get("selected") or {}
        for m in sel.get("misfit") or []:
            lo, hi = (m.get("tau_range_s") or [None, None])[:2]
            rows.append([
                _e(ch),
                f"{_num(lo, 3)} – {_num(hi, 3)} s",
                _e(m.get("side", "?")),
                f"{_num(m.get('worst_ratio'), 3)} at τ = {_num(m.get('worst_tau_s'), 3)} s",
                _e(", ".join(m.get("terms") or []) or "—"),
                _e(m.get("points", "?")),
            ])
    return rows


def _record_rows(channels: dict[str, Any]) -> tuple[list[str], list[list[str]]]:
    hours: list[Any] = []
    rows = []
    for ch, c in channels.items():
        rl = (c or {}).get("record_length")
        if not isinstance(rl, dict):
            continue
        hours = hours or list(rl.get("hours") or [])
        width = rl.get("rel_ci_width") or {}
        need = rl.get("hours_needed") or {}
        never = set(rl.get("never_reached") or [])
        status = rl.get("term_status") or {}
        for t in _TERMS:
            ws = list(width.get(t) or [])
            cells = [f"{_num(100 * w, 3)} %" if w is not None else "—" for w in ws]
            cells += ["—"] * (len(hours) - len(cells))
            needed = "never (the misfit keeps it wider)" if t in never else _hours(need.get(t))
            st = status.get(t)
            label = f"{ch} {t}" + (f" ({st.replace('_', ' ')})" if st and st != "resolved"
                                   else "")
            rows.append([_e(label), *cells[: len(hours)], needed,
                         _hours(rl.get("recorded_hours"))])
    head = ["channel, term", *(f"{_hours(h)}" for h in hours),
            "needed for a 20 % width", "this log"]
    return head, rows


def _stationarity_rows(channels: dict[str, Any]) -> list[list[str]]:
    rows = []
    for ch, c in channels.items():
        st = (c or {}).get("stationarity")
        if not isinstance(st, dict):
            continue
        ok = st.get("stationary")
        verdict = (
            "<span class='ok'>stationary</span>" if ok
            else "<span class='bad'>not stationary</span>" if ok is False else "—"
        )
        d = st.get("drift")
        if isinstance(d, dict):
            verdict += (
                f" (drift {_num(d.get('change_over_log'), 3)} {_e((c or {}).get('unit', ''))}"
                f" over the log, z = {_num(d.get('z'), 3)})"
            )
        w = st.get("warmup")
        warm = "none found"
        if isinstance(w, dict):
            warm = (
                f"<span class='warn'>{_num(w.get('start_s'), 3)} – {_num(w.get('end_s'), 4)} s"
                f"</span> (T = {_num(w.get('time_constant_s'), 3)} s, 68 % "
                f"{_num((w.get('time_constant_ci_s') or [None])[0], 3)} – "
                f"{_num((w.get('time_constant_ci_s') or [None, None])[1], 3)} s; amplitude "
                f"{_num(w.get('amplitude'), 3)} {_e((c or {}).get('unit', ''))} = "
                f"{_num(w.get('amplitude_over_adev'), 3)} × the settled deviation)"
            )
        rows.append([_e(ch), verdict, _num(st.get("p_value"), 3),
                     f"{_num(st.get('window_s'), 4)} s × {len(st.get('window_start_s') or [])}",
                     warm])
    return rows


def _white_rows(channels: dict[str, Any]) -> list[list[str]]:
    rows = []
    for ch, c in channels.items():
        noise = (c or {}).get("noise") or {}
        wl = noise.get("white_level")
        if not isinstance(wl, dict):
            continue
        unit = ((noise.get("fit") or {}).get("N") or {}).get("unit", "")
        lo, hi = wl.get("low") or {}, wl.get("high") or {}
        rows.append([
            _e(ch),
            f"{_num(wl.get('fit'), 4)} {_e(unit)}",
            f"{_num(wl.get('read_off'), 4)} (τ = {_num(wl.get('read_off_tau_s'), 3)} s)",
            f"{_num(lo.get('value'), 4)} (τ = {_num(lo.get('tau_s'), 3)} s) – "
            f"{_num(hi.get('value'), 4)} (τ = {_num(hi.get('tau_s'), 3)} s)",
            "constant" if wl.get("constant") else _e(wl.get("use", "")),
        ])
    return rows


def _timing_rows(channels: dict[str, Any]) -> list[list[str]]:
    rows = []
    for ch, c in channels.items():
        tm = (c or {}).get("timing")
        if not isinstance(tm, dict):
            continue
        if not tm.get("checked"):
            rows.append([_e(ch), f"not checked ({_e(tm.get('reason', '?'))})", "—", "—", "—"])
            continue
        bad = tm.get("unreliable_tau_s") or []
        gaps = f"{_e(tm.get('gaps', 0))} ({_num(tm.get('missing_s'), 3)} s missing)"
        if bad:
            gaps += f"; unreliable from τ = {_num(min(bad), 3)} s"
        rows.append([
            _e(ch),
            f"{_num(tm.get('median_step_s'), 4)} s",
            f"{_num(100 * float(tm.get('jitter_rel') or 0.0), 3)} %",
            f"{_num(100 * float(tm.get('bound_rel_max') or 0.0), 3)} %",
            gaps,
        ])
    return rows


def checks_block(d: Path, channels: dict[str, Any]) -> str:
    """The details: misfit, record length, stationarity (and its figure) and timing; the
    parts a noise.json does not hold (an older file, the out-of-core path) are left out."""
    parts: list[str] = []
    rows = _misfit_rows(channels)
    if rows or any("misfit" in (((c or {}).get("noise") or {}).get("selected") or {})
                   for c in channels.values()):
        parts.append("<h3>Where the five terms leave the curve</h3>")
        parts.append(
            _table(["channel", "τ range", "side", "worst model/curve ratio", "terms there",
                    "points"], rows)
            if rows else "<p>The fitted terms follow the curve within its intervals at "
            "every τ.</p>"
        )
        parts.append("<p class='muted'>Ranges of τ where the fitted five-term model lies "
                     "outside the curve's intervals: structure the terms cannot follow "
                     "(noise.selected.misfit).</p>")
    rows = _white_rows(channels)
    if rows:
        parts.append("<h3>White-noise level across τ (N)</h3>" + _table(
            ["channel", "N from the fit", "N read off", "level implied by the curve",
             "which to believe"], rows))
        parts.append(
            "<p class='muted'>The level N(τ) the curve implies where N dominates, once the "
            "other fitted terms are taken out (noise.white_level). Constant within its "
            "intervals and 10 %: the fit and the read-off agree. Otherwise a filter or a "
            "correlated process changes it with τ, and noise at a time scale follows the "
            "level read there.</p>"
        )
    head, rows = _record_rows(channels)
    if rows:
        parts.append("<h3>How long to record</h3>" + _table(head, rows))
        parts.append(
            "<p class='muted'>Relative width (hi − lo)/value of each term's interval "
            "predicted from the EDFs for a log of each length, and the length needed for a "
            "20 % width (record_length).</p>"
        )
    rows = _stationarity_rows(channels)
    if rows:
        parts.append("<h3>Stationarity and warm-up</h3>" + _table(
            ["channel", "verdict", "p-value", "windows", "warm-up (start – end)"], rows))
    if _listed(d, "stationarity.png"):
        parts.append(_img(d / "stationarity.png",
                          "The Allan deviation at four τ in consecutive windows of the log "
                          "with their intervals, and the warm-up where one was found."))
    rows = _timing_rows(channels)
    if rows:
        parts.append("<h3>Time stamps</h3>" + _table(
            ["channel", "median step", "jitter (of the step)",
             "bound of the constant-rate error (deviation, worst τ)", "gaps"], rows))
        parts.append(
            "<p class='muted'>The Allan deviation assumes a constant rate (the median "
            "step); the bound |slope|·jitter/√m + jitter²/2 is the relative error that "
            "assumption may cause (timing).</p>"
        )
    return "".join(parts)


def summary_line(channels: dict[str, Any]) -> str:
    """One line for the summary when a warm-up or a misfit was found (else empty)."""
    warm, mis_ch, taus = [], [], []
    for ch, c in channels.items():
        w = ((c or {}).get("stationarity") or {}).get("warmup")
        if isinstance(w, dict):
            warm.append(f"{ch} {_num(w.get('start_s'), 3)} – {_num(w.get('end_s'), 4)} s")
        found = (((c or {}).get("noise") or {}).get("selected") or {}).get("misfit") or []
        for m in found:
            taus += [float(x) for x in (m.get("tau_range_s") or []) if x is not None]
        if found:
            mis_ch.append(ch)
    bits = []
    if warm:
        bits.append("warm-up " + "; ".join(warm))
    if mis_ch:
        where = f" within τ {_num(min(taus), 3)} – {_num(max(taus), 3)} s" if taus else ""
        bits.append(f"the fitted terms leave the curve on {', '.join(mis_ch)}{where}")
    if not bits:
        return ""
    return ("<p class='warn'>Static log: " + _e("; ".join(bits)) +
            " (see Stationary characterisation).</p>")
