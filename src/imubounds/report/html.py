"""One self-contained HTML report of a run directory.

:func:`build_report` collects what the commands wrote into a directory (or
its ``static/``, ``dynamic/`` and ``sim/`` sub-directories): ``noise.json``,
``dynamic.json``, ``run.json`` and the PNG figures, and returns one HTML page
with every figure embedded (base64), the noise table in SI and IEEE units,
the stochastic models, the dynamic intervals and verdict, the warnings and
the exact commands that reproduce the run. No external resource is loaded,
so the file can be mailed or archived as it is.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterator
from contextlib import contextmanager
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from imubounds.errors import InputError
from imubounds.report._html_checks import checks_block, summary_line
from imubounds.report._html_fleet import _fleet_section
from imubounds.report._html_parts import _e, _img, _listed, _load_json, _num, _table, _term_cell
from imubounds.version import __version__

CSS = """
body{font-family:system-ui,-apple-system,Segoe UI,Roboto,sans-serif;margin:0;color:#1d2433;
background:#f6f7f9}
header{background:#1f3a5f;color:#fff;padding:18px 32px}
header h1{margin:0;font-size:1.5em} header p{margin:4px 0 0;opacity:.85}
main{max-width:1200px;margin:0 auto;padding:16px 32px 48px}
section{background:#fff;border:1px solid #dde2ea;border-radius:8px;padding:16px 20px;margin:18px 0}
h2{margin-top:0;font-size:1.2em;color:#1f3a5f} h3{font-size:1em;margin:14px 0 6px}
table{border-collapse:collapse;font-size:.86em;margin:6px 0 10px}
th,td{border:1px solid #dde2ea;padding:4px 8px;text-align:right}
th{background:#eef1f6} td.l,th.l{text-align:left}
figure{margin:10px 0} figure img{max-width:100%;border:1px solid #eee}
figcaption{font-size:.85em;color:#555}
.warn{background:#fff6e0;border-left:4px solid #e0a800;padding:6px 10px;margin:4px 0;font-size:.9em}
.ok{color:#1a7f37;font-weight:600} .bad{color:#b42318;font-weight:600}
code,pre{background:#f0f2f5;border-radius:4px;padding:2px 5px;font-size:.88em}
details>summary{cursor:pointer;list-style:none} details>summary h2{display:inline}
details>summary::before{content:"▸ ";color:#1f3a5f} details[open]>summary::before{content:"▾ "}
#summary table{font-size:.92em}
pre{padding:8px 10px;overflow-x:auto}
.muted{color:#666;font-size:.85em}
.fragile{color:#9a4d00;font-weight:600;background:#fff1e0;padding:0 3px;border-radius:3px}
#figures figure img{max-width:100%}
"""

TERM_ORDER = ("Q", "N", "B", "K", "R")


def _real_root(root: Path) -> Path:
    """The folder a run writes to: a command stages its outputs in
    ``.NAME.imubounds-PID-XXXX`` beside ``NAME`` and renames it at the end."""
    name = root.name
    if name.startswith(".") and ".imubounds-" in name:
        return root.parent / name[1:].split(".imubounds-")[0]
    return root


def _find(root: Path, name: str, subdirs: tuple[str, ...]) -> Path | None:
    for d in (root, *(root / s for s in subdirs)):
        if (d / name).is_file():
            return d
    return None


def _run_block(d: Path) -> str:
    run = _load_json(d / "run.json")
    if not run:
        return ""
    return (
        f"<p class='muted'>Reproduce with <code>{_e(run.get('command', ''))}</code> "
        f"(imubounds {_e(run.get('imubounds_version', '?'))}, Python {_e(run.get('python', '?'))},"
        f" finished {_e(run.get('finished_utc', '?'))})</p>"
    )


def _units_text(inp: dict[str, Any]) -> str:
    units = inp.get("input_units") or {}
    if not units:
        return "?"
    groups: dict[str, list[str]] = {}
    for ch, u in units.items():
        groups.setdefault(str(u), []).append(str(ch))
    return "; ".join(f"{', '.join(chs)} in {u}" for u, chs in groups.items()) + " (SI inside)"


def _fits(model: dict[str, Any]) -> str:
    adq = model.get("adequacy")
    if not model or not adq:
        return "—"
    if adq.get("adequate"):
        return "<span class='ok'>yes</span>"
    ratio = adq.get("worst_ratio")
    where = f" (×{_num(ratio, 3)} at τ = {_num(adq.get('worst_tau_s'), 3)} s)" if ratio else ""
    return f"<span class='bad'>no</span>{_e(where)}"


def _selected_table(channels: dict[str, Any]) -> str:
    """The terms used for bounds and imu.yaml, with status, IEEE 952 and datasheet units."""
    rows = []
    for name, ch in channels.items():
        sel = ch.get("noise", {}).get("selected")
        if not sel:
            continue
        cells = [f"<td class='l'>{_e(name)}</td>"]
        for t in ("N", "B", "K"):
            e = sel.get(t, {})
            mark = "≤ " if e.get("status") == "upper_bound" else ""
            ieee, ds = e.get("ieee", {}), e.get("datasheet", {})
            cells.append(
                f"<td>{mark}{_num(ieee.get('value'))} {_e(ieee.get('unit', ''))}</td>"
                f"<td>{mark}{_num(ds.get('value'))} {_e(ds.get('unit', ''))}</td>"
                f"<td class='l'>{_e(str(e.get('status', '?')).replace('_', ' '))}"
                f" <span class='muted'>({_e(e.get('from', ''))})</span></td>"
            )
        sm = sel.get("sigma_min", {})
        smd = sm.get("datasheet", {})
        cells.append(
            f"<td>{_num(smd.get('value'))} {_e(smd.get('unit', ''))} at τ = "
            f"{_num(sm.get('tau_s'), 3)} s</td>"
        )
        adev1 = sel.get("N", {}).get("adev_at_1s", {}).get("datasheet", {})
        cells.append(f"<td>{_num(adev1.get('value'))} {_e(adev1.get('unit', ''))}</td>")
        rows.append("<tr>" + "".join(cells) + "</tr>")
    if not rows:
        return ""
    head = "".join(
        f"<th>{t} (IEEE 952)</th><th>{t} (datasheet)</th><th class='l'>{t} status</th>"
        for t in ("N", "B", "K")
    )
    return (
        "<h3>Selected terms (used for the bounds and imu.yaml)</h3><table><tr>"
        f"<th class='l'>channel</th>{head}<th>σ_min (bias stability)</th>"
        "<th>N as ADEV at τ = 1 s</th></tr>" + "".join(rows) + "</table>"
        "<p class='muted'>'≤' marks an upper bound from the curve's intervals where the log "
        "does not resolve the term (never 0). σ_min is the lowest point of the curve with "
        "EDF ≥ 10, as datasheets quote 'bias stability'; B is the IEEE 952 bias instability, "
        "σ_min/0.664 on an Allan curve (the fit uses each estimator's own factor).</p>"
    )


def _static_section(d: Path, noise: dict[str, Any]) -> tuple[str, list[str], list[str]]:
    inp = noise.get("input", {})
    settings = noise.get("settings", {})
    channels: dict[str, Any] = noise.get("channels", {})
    warnings = [str(w) for w in inp.get("warnings", [])]
    commands = []
    run = _load_json(d / "run.json")
    if run and run.get("command"):
        commands.append(str(run["command"]))
    parts = ["<section id='static'><details><summary><h2>Stationary characterisation</h2>"
             "</summary>"]
    parts.append(
        "<table><tr><th class='l'>input</th><td class='l'>"
        f"{_e(inp.get('path', '?'))}</td></tr>"
        "<tr><th class='l'>sample rate</th>"
        f"<td class='l'>{_num(inp.get('sample_rate_hz'))} Hz</td></tr>"
        f"<tr><th class='l'>duration</th><td class='l'>{_num(inp.get('duration_s'))} s "
        f"({_num((inp.get('duration_s') or 0) / 3600, 3)} h), {inp.get('n_samples', '?')} samples"
        "</td></tr>"
        f"<tr><th class='l'>input units</th><td class='l'>{_e(_units_text(inp))}</td></tr>"
        f"<tr><th class='l'>body frame</th><td class='l'>{_e(inp.get('frame', '?'))}</td></tr>"
        f"<tr><th class='l'>estimator</th><td class='l'>{_e(settings.get('estimator', '?'))}, "
        f"τ grid {_e(settings.get('taus', '?'))}, "
        f"CI level {_num(settings.get('confidence'))}</td></tr>"
        f"<tr><th class='l'>terms feeding the bounds</th><td class='l'>"
        f"{_e(settings.get('terms_from', '?'))}; k = {_num(settings.get('k_sigma'))}; "
        f"averaging time {_e(settings.get('averaging_time_s') or 'log length')}; "
        f"run length T {_e(settings.get('run_hours') or 'log length')}</td></tr>"
        f"<tr><th class='l'>stochastic models</th><td class='l'>"
        f"{_e(', '.join(settings.get('models') or []) or 'none')}</td></tr></table>"
    )
    for note in noise.get("notes", []):
        warnings.append(str(note))
    parts.append(_selected_table(channels))
    for method, title in (
        ("fit", "robust weighted least-squares fit"),
        ("slope", "IEEE 952 slope read-off, each term where it dominates"),
    ):
        parts.append(f"<h3>Noise terms — {title}</h3><table><tr><th class='l'>channel</th>")
        for t in TERM_ORDER:
            parts.append(f"<th>{t} (IEEE)</th><th>{t} (SI)</th>")
        parts.append("</tr>")
        for name, ch in channels.items():
            terms = ch.get("noise", {}).get(method, {})
            parts.append(f"<tr><td class='l'>{_e(name)}</td>")
            for t in TERM_ORDER:
                e = terms.get(t, {})
                ieee = e.get("ieee", {})
                ci = ieee.get("ci")
                ci_txt = (
                    f" <span class='muted'>[{_num(ci[0], 3)}, {_num(ci[1], 3)}]</span>"
                    if ci
                    else ""
                )
                where = f" <span class='muted'>τ={_num(e['tau_s'], 3)} s</span>" if (
                    method == "slope" and e.get("tau_s") is not None
                ) else ""
                st = e.get("status")
                st_txt = f" <span class='muted'>({_e(st.replace('_', ' '))})</span>" if (
                    st and st != "resolved"
                ) else ""
                parts.append(
                    f"<td>{_num(ieee.get('value'))} {_e(ieee.get('unit', ''))}{ci_txt}{where}"
                    f"{st_txt}</td><td>{_num(e.get('value'))} {_e(e.get('unit', ''))}</td>"
                )
            parts.append("</tr>")
        parts.append("</table>")
    parts.append(
        "<h3>Stationary bounds</h3><table><tr><th class='l'>channel</th><th>σ_c</th>"
        "<th>k</th><th>k·σ_c (per-sample half-width)</th><th>95 % random-walk growth over T"
        "</th><th>T (h)</th><th>spikes</th></tr>"
    )
    for name, ch in channels.items():
        rw = ch.get("random_walk_95", {})
        bound = ch.get("bound", {})
        unit = _e(ch.get("unit", ""))
        ds = rw.get("datasheet", {})
        spikes = ch.get("spikes", {})
        sp = spikes.get("events", "not checked") if spikes.get("checked", True) else "not checked"
        parts.append(
            f"<tr><td class='l'>{_e(name)}</td><td>{_num(ch.get('sigma_c'))} {unit}</td>"
            f"<td>{_num(bound.get('k'))}</td><td>{_num(bound.get('value'))} {unit}</td>"
            f"<td>{_num(rw.get('value'))} {_e(rw.get('unit', ''))}"
            f" ({_num(ds.get('value'))} {_e(ds.get('unit', ''))})</td>"
            f"<td>{_num(rw.get('T_hours'), 3)}</td><td>{_e(sp)}</td></tr>"
        )
        for w in ch.get("warnings", []):
            warnings.append(str(w))
        for note in ch.get("notes", []):
            warnings.append(f"{name}: {note}")
    parts.append(
        "</table><p class='muted'>σ_c = N/√δt + √(δt/t)·B from the selected N and B (an upper "
        "bound where a term is not resolved); per-sample interval [y − kσ_c, y + kσ_c]; "
        "random-walk growth 1.96·N·√T is the 95 % spread of the integrated error (angle or "
        "velocity) over the run (paper, section IV; METHOD.md 1.4).</p>"
    )
    models_rows = []
    for name, ch in channels.items():
        m = ch.get("models")
        if not m:
            continue
        gm = m.get("gauss_markov") or {}
        ar = m.get("ar") or {}
        models_rows.append(
            f"<tr><td class='l'>{_e(name)}</td><td>{_num(gm.get('correlation_time_s'))} s</td>"
            f"<td>{_num(gm.get('sigma'))}</td><td>{_num(gm.get('white_sigma'))}</td>"
            f"<td>{_num(gm.get('fitted_rate_hz'))} Hz</td><td>{_fits(gm)}</td>"
            f"<td>{_e(ar.get('order', '—'))}</td><td>{_e(ar.get('criterion', '—'))}</td>"
            f"<td>{_num(ar.get('rate_hz', m.get('effective_rate_hz')))} Hz</td>"
            f"<td>{_fits(ar)}</td></tr>"
        )
        for note in m.get("notes", []):
            warnings.append(f"{name} models: {note}")
    if models_rows:
        parts.append(
            "<h3>Stochastic models</h3><table><tr><th class='l'>channel</th><th>GM correlation time"
            "</th><th>GM σ (SI)</th><th>white σ (SI)</th><th>GM fit rate</th><th>GM follows the "
            "curve</th><th>AR order</th><th>criterion</th><th>AR fit rate</th><th>AR follows the "
            "curve</th></tr>" + "".join(models_rows) + "</table><p class='muted'>A model follows "
            "the curve when its curve lies in the measured 95 % interval (widened by 10 %) at "
            "90 % of the points where it is valid (τ ≥ its fit sample period) and is nowhere "
            "off by more than ×1.5; the fit rate and AR order are chosen to achieve that.</p>"
        )
    if _listed(d, "allan.png"):
        parts.append(ABOVE.format(name="allan.png"))
    parts.append(checks_block(d, channels))
    parts.append(_run_block(d))
    parts.append("</details></section>")
    return "".join(parts), warnings, commands


DYN_FIGURES = (
    (
        "margins",
        "Mode full: half-width of the guaranteed interval of the window-mean IMU error "
        "against the averaging time τ (solid: median window, dotted: worst), and the "
        "stationary band of the noise budget (dashed, shaded), like an Allan plot.",
    ),
    (
        "motion",
        "In motion, on the Allan axes: the stationary Allan deviation (grey), the stationary "
        "prediction (dashed) and the guaranteed in-motion bound (red; dots: resolved τ), "
        "both divided by k to read as one-sigma deviations; F is the in-motion factor.",
    ),
    (
        "windows",
        "Mode full: the guaranteed intervals of the window-mean error over the trip at one τ "
        "per channel against the stationary band (green): decided windows dark, undecided "
        "ones (aided interval wider than the band) light and dotted, fragile ones (their "
        "test turns with the band 5 % narrower or wider) orange; red marks: windows that "
        "lie entirely outside the band.",
    ),
    ("trajectory", "Mode full: GNSS boxes, smoothed position boxes and the truth where known."),
    (
        "intervals",
        "Mode paper (NOT guaranteed): the paper's per-step aided intervals (its Figs. 5-6).",
    ),
)


#: The figures the reader must look at, shown open under "Figures" after the summary (the
#: first dynamic run's; the static run's Allan figure): the verdicts' windows and the
#: in-motion figures. The details refer to them instead of repeating them.
KEY_DYNAMIC_FIGURES = ("windows", "motion")
ALLAN_CAPTION = ("Allan deviation per channel with confidence intervals, the noise-term lines "
                 "and the fitted curve (and fitted stochastic models where asked).")
ABOVE = "<p class='muted'>{name}: shown under <a href='#figures'>Figures</a>, at the top.</p>"


def _figures_section(static_dir: Path | None, dyn_dir: Path | None) -> str:
    """The key figures, open: the Allan curves, the windows of the verdicts (decided,
    undecided and fragile windows marked apart) and the in-motion figures."""
    figs = []
    if static_dir is not None and _listed(static_dir, "allan.png"):
        figs.append(_img(static_dir / "allan.png", ALLAN_CAPTION))
    if dyn_dir is not None:
        captions = dict(DYN_FIGURES)
        for stem in KEY_DYNAMIC_FIGURES:
            if _listed(dyn_dir, f"{stem}.png"):
                figs.append(_img(dyn_dir / f"{stem}.png", captions[stem]))
    if not figs:
        return ""
    return "<section id='figures'><h2>Figures</h2>" + "".join(figs) + "</section>"


def _kv_table(items: dict[str, Any], per_row: int = 1) -> str:
    """Key/value table, ``per_row`` pairs per row (compact settings)."""
    cells = []
    for k, v in items.items():
        if isinstance(v, dict | list):
            v = json.dumps(v, default=str)
            if len(v) > 160:
                v = v[:157] + "..."
        cells.append(f"<th class='l'>{_e(k)}</th><td class='l'>{_e(v)}</td>")
    rows = ["".join(cells[i : i + per_row]) for i in range(0, len(cells), per_row)]
    return "<table>" + "".join(f"<tr>{r}</tr>" for r in rows) + "</table>"


def _interval(iv: Any, factor: float = 1.0, digits: int = 4) -> str:
    if not isinstance(iv, list | tuple) or len(iv) != 2 or None in iv:
        return "—"
    return f"[{_num(iv[0] * factor, digits)}, {_num(iv[1] * factor, digits)}]"


def _ch_factor(ch: str) -> tuple[float, str]:
    return (180.0 / math.pi, "deg/s") if ch.startswith("gyro") else (1.0, "m/s^2")


def _verdict_class(v: str | None, det: dict[str, Any]) -> str:
    """decided verdicts green/red; undecided, not analysed and fragile ones apart."""
    if det.get("fragile"):
        return "fragile"
    return "ok" if v == "consistent" else "bad" if v == "exceeds" else "muted"


def _verdict_text(v: str | None, det: dict[str, Any]) -> str:
    return f"{v or 'not analysed'} — FRAGILE (not decided)" if det.get("fragile") else (
        v or "not analysed")


def _verdict_items(mode: dict[str, Any]) -> str:
    items = []
    for ch, v in (mode.get("verdict") or {}).items():
        f, unit = _ch_factor(ch)
        rows = [r for r in (mode.get("margins") or {}).get(ch) or []
                if r.get("halfwidth_median") is not None]
        dec = [r for r in rows if (r.get("decidable_fraction") or 0) > 0]
        extra = ""
        if dec:
            r = min(dec, key=lambda x: x["halfwidth_median"])
            extra = (
                f": tightest at τ = {_num(r['tau_s'], 3)} s, median ±"
                f"{_num(r['halfwidth_median'] * f, 3)} {unit} against a stationary band of "
                f"±{_num(r['stationary'] * f, 3)} {unit}"
            )
        det = (mode.get("verdict_detail") or {}).get(ch) or {}
        detail = det.get("reason", "")
        cls = _verdict_class(v, det)
        fragile = (f" <span class='fragile'>{_e(det.get('fragile_detail', 'FRAGILE'))}</span>"
                   if det.get("fragile") else "")
        items.append(
            f"<li><b>{_e(ch)}</b>: <span class='{cls}'>{_e(_verdict_text(v, det))}</span>"
            f"{_e(extra)}{fragile}"
            + (f" <span class='muted'>({_e(detail)})</span>" if detail else "")
            + "</li>"
        )
    return "<ul>" + "".join(items) + "</ul>"


def _margins_table(mode: dict[str, Any]) -> str:
    rows = []
    for ch, lst in (mode.get("margins") or {}).items():
        f, unit = _ch_factor(ch)
        for r in lst:
            if not r.get("decidable_fraction") and r.get("aided_from") == "vehicle bounds":
                continue
            rows.append([
                _e(ch),
                _num(r.get("tau_s"), 4),
                f"{_num((r.get('halfwidth_median') or math.nan) * f, 3)}",
                f"{_num((r.get('halfwidth_max') or math.nan) * f, 3)}",
                f"{_num((r.get('stationary') or math.nan) * f, 3)}",
                f"{_num(100 * (r.get('decidable_fraction') or 0), 3)} %",
                f"{_num(100 * (r.get('exceeds_fraction') or 0), 3)} %",
                _change_cell(r, f),
                _e(unit),
            ])
    return _table(
        ["channel", "τ [s]", "median half-width", "worst half-width", "stationary band",
         "decidable", "exceeds", "change: median half-width / band / exceeds", "unit"],
        rows,
    )


def _change_cell(r: dict[str, Any], f: float) -> str:
    """The change test between adjacent windows (turn-on cancels) of one tau row."""
    if not r.get("n_changes"):
        return "—"
    return (
        f"{_num((r.get('change_halfwidth_median') or math.nan) * f, 3)} / "
        f"{_num((r.get('change_stationary') or math.nan) * f, 3)} / "
        f"{_num(100 * (r.get('change_exceeds_fraction') or 0), 3)} %"
    )


def _full_block(mode: dict[str, Any], warnings: list[str]) -> str:
    from imubounds.dynamic.estimator.result import applied_corrections

    viol = mode.get("violations") or []
    head = (
        "<h3 id='full'>Mode full — guaranteed</h3>"
        if not viol
        else "<h3 id='full'>Mode full — NOT guaranteed: "
        f"{len(viol)} assumption check(s) failed</h3>"
        + _table(
            ["stream", "from (s)", "to (s)", "test", "detail"],
            [[_e(v["stream"]), _num(v["t_start_s"]), _num(v["t_end_s"]), _e(v["test"]),
              _e(v["detail"])] for v in viol[:50]],
        )
    )
    parts = [
        head,
        f"<p>{_e(mode.get('statement', ''))}.</p>",
        *(f"<p><b>{_e(line[:1].upper() + line[1:])}</b></p>" for line in applied_corrections(mode)),
        "<h3 id='verdict'>Verdicts: the IMU error during the trip vs the stationary band</h3>",
        _verdict_items(mode),
    ]
    nota = mode.get("channels_not_analysed") or {}
    if nota:
        parts.append(
            "<p class='muted'>Not analysed: "
            + "; ".join(f"{_e(k)} ({_e(v)})" for k, v in nota.items())
            + "</p>"
        )
    parts.append("<h3>Margins per averaging time (aided windows)</h3>" + _margins_table(mode))
    enc = mode.get("enclosure")
    if enc:
        rows = [[_e(k), f"{_num(100 * v, 5)} %"] for k, v in enc.items()
                if isinstance(v, int | float) and k != "epochs"]
        parts.append("<h3>Truth inside the intervals (share of epochs)</h3>"
                     + _table(["quantity", "enclosed"], rows))
    bias = mode.get("bias") or {}
    if bias:
        rows = []
        for ch, b in bias.items():
            f, unit = _ch_factor(ch)
            rows.append([_e(ch), _interval(b.get("constant_part"), f),
                         _interval(b.get("over_trip"), f), _e(unit), _e(b.get("source", ""))])
        parts.append(
            "<h3>Bias of each channel (guaranteed)</h3>"
            + _table(["channel", "constant part", "over the whole trip", "unit", "from"], rows)
        )
    ca = mode.get("contracted_aiding") or {}
    if ca:
        rows = [
            [_e(k), _num(v.get("input_halfwidth_median")), _num(v.get("input_halfwidth_p95")),
             _num(v.get("contracted_halfwidth_median")), _num(v.get("contracted_halfwidth_p95")),
             _e(v.get("unit"))]
            for k, v in ca.items()
        ]
        parts.append(
            "<h3>Aiding sensors: input vs contracted half-widths</h3>"
            + _table(["sensor", "input median", "input p95", "contracted median",
                      "contracted p95", "unit"], rows)
        )
    ei = mode.get("empty_intersections") or {}
    parts.append(
        f"<h3>Empty intersections: {_e(ei.get('count', 0))}</h3>"
        f"<p class='muted'>{_e(ei.get('rule', ''))}</p>"
    )
    dropped = ei.get("dropped") or []
    if dropped:
        rows = [[_num(x.get("t_s"), 10), _e(x.get("sensor")), _num(x.get("miss")),
                 _e(x.get("unit")), _e(x.get("reason"))] for x in dropped[:60]]
        parts.append(_table(["t [s]", "dropped", "missed by", "unit", "why"], rows))
        for sensor, n in (ei.get("by_sensor") or {}).items():
            warnings.append(f"mode full: {n} {sensor} measurement(s) dropped (q-relaxed)")
    budget = mode.get("budget") or {}
    if budget:
        parts.append("<h3>Error budget of the IMU channels</h3>" + _budget_table(budget))
    aid = mode.get("aiding_budget") or {}
    if aid:
        rows = [[_e(sensor), _e(r.get("term")), _num(r.get("value")), _e(r.get("unit")),
                 _e(r.get("source")), _e(r.get("assumption"))]
                for sensor, rows_ in aid.items() for r in rows_]
        parts.append("<h3>Error budget of the aiding sensors</h3>"
                     + _table(["sensor", "term", "value", "unit", "source", "assumption"], rows))
    fam = ((mode.get("alpha") or {}).get("families")) or {}
    if fam:
        rows = [[_e(k), _e(v.get("count")), _num(v.get("alpha")), _num(v.get("k")),
                 _e(v.get("what"))] for k, v in fam.items()]
        parts.append("<h3>Whole-trip probability split</h3>"
                     + _table(["family", "count", "alpha", "k", "bounds"], rows))
    assum = mode.get("assumptions") or []
    if assum:
        parts.append("<h3>Assumptions</h3><ul>" + "".join(f"<li>{_e(a)}</li>" for a in assum)
                     + "</ul>")
    for n in mode.get("notes") or []:
        warnings.append(f"mode full: {n}")
    return "".join(parts)


def _motion_table(motion: dict[str, Any]) -> str:
    """motion.json per channel and tau: the guaranteed in-motion bound beside the
    stationary prediction, their ratio (the inflation factor) and the floor."""
    rows = []
    for ch, c in motion["channels"].items():
        f, unit = _ch_factor(ch)
        for r in c.get("rows", []):
            infl = r.get("inflation")
            cls = "bad" if infl is not None and infl > 1 else "ok"
            rows.append([
                _e(ch), _num(r.get("tau_s"), 3),
                _num(None if r.get("bound") is None else r["bound"] * f),
                _num(None if r.get("stationary") is None else r["stationary"] * f),
                f"<span class='{cls}'>{_num(infl, 3)}</span>",
                _num(None if r.get("floor") is None else r["floor"] * f),
                "yes" if r.get("resolved") else "no", _e(unit),
            ])
    return (
        "<h3>In motion: guaranteed bound vs stationary prediction (motion.json)</h3>"
        + _table(["channel", "τ [s]", "in-motion bound", "stationary prediction",
                  "inflation", "floor", "resolved", "unit"], rows)
        + "<p class='muted'>bound: the largest |window-mean error| the trip allows; "
        "inflation = bound / stationary prediction (above 1 exactly where the bound exceeds "
        "it; where the τ is not resolved the aiding, not the IMU, sets the bound); floor: "
        "some window's error is at least this.</p>"
    )


def _budget_table(budget: dict[str, Any]) -> str:
    """One table: a row per budget term, a column per channel (value and unit)."""
    chans = list(budget)
    terms: list[str] = []
    cells: dict[tuple[str, str], str] = {}
    notes: dict[str, str] = {}
    for ch, rows_ in budget.items():
        for r in rows_:
            t = str(r.get("term"))
            if t not in terms:
                terms.append(t)
                notes[t] = f"{r.get('source', '')}: {r.get('assumption', '')}"
            cells[(t, ch)] = f"{_num(r.get('value'))} {_e(r.get('unit', ''))}"
    rows = [[_e(t), *(cells.get((t, ch), "—") for ch in chans), _e(notes[t])] for t in terms]
    return _table(["term", *chans, "source: assumption (first channel)"], rows)


def _paper_block(mode: dict[str, Any], warnings: list[str]) -> str:
    parts = [
        "<h3 id='paper'>Mode paper — NOT guaranteed</h3>",
        f"<p class='bad'>{_e(mode.get('statement', ''))}.</p>",
    ]
    rows = []
    for ch, lst in (mode.get("margins") or {}).items():
        for r in lst:
            rows.append([
                _e(ch), _num(r.get("tau_s")), _num(r.get("halfwidth_median")),
                _num(r.get("halfwidth_max")), f"{_num(r.get('stationary'))} "
                f"{_e(r.get('stationary_unit', ''))}", _e(r.get("unit")),
                _e((mode.get("verdict") or {}).get(ch, "")),
            ])
    parts.append(_table(["channel", "step [s]", "median half-width", "worst half-width",
                         "paper's 95 % level (its own unit)", "unit", "verdict (paper)"], rows))
    enc = mode.get("enclosure") or {}
    if enc:
        rows = [[_e(k), f"{_num(100 * v, 4)} %"] for k, v in enc.items()
                if isinstance(v, int | float) and k not in ("steps",)]
        parts.append("<h3>Truth inside (mode paper)</h3>" + _table(["quantity", "share"], rows))
    ei = mode.get("empty_intersections") or {}
    if ei.get("count"):
        warnings.append(
            f"mode paper: {ei['count']} empty intersection(s) settled by the rule "
            f"'{ei.get('rule', '?')}' ({ei.get('by_flag', {})})"
        )
    return "".join(parts)


def _dynamic_section(
    d: Path, dyn: dict[str, Any], label: str = ""
) -> tuple[str, list[str], list[str]]:
    inp = dyn.get("input") or {}
    warnings = [str(w) for w in (inp.get("warnings") or dyn.get("warnings") or [])]
    commands = []
    run = _load_json(d / "run.json")
    if run and run.get("command"):
        commands.append(str(run["command"]))
    sid = "dynamic" if not label else f"dynamic-{label}"
    title = "Dynamic error margins" + (f" — {_e(label)}" if label else "")
    parts = [f"<section id='{sid}'><details><summary><h2>{title}</h2></summary>"]
    modes = dyn.get("modes") or {}
    if not isinstance(modes, dict) or not modes:
        parts.append("<p class='muted'>dynamic.json has no mode results.</p>")
    if isinstance(modes.get("full"), dict):
        parts.append(_full_block(modes["full"], warnings))
    motion = _load_json(d / "motion.json")
    if motion and motion.get("channels"):
        parts.append(_motion_table(motion))
    shown = set()
    for stem, caption in DYN_FIGURES:
        if _listed(d, f"{stem}.png"):
            key = not label and stem in KEY_DYNAMIC_FIGURES  # shown open, under Figures
            parts.append(ABOVE.format(name=f"{stem}.png") if key else _img(d / f"{stem}.png",
                                                                            caption))
            shown.add(stem)
    if isinstance(modes.get("paper"), dict):
        parts.append(_paper_block(modes["paper"], warnings))
    for png in sorted(d.glob("*.png")):
        if png.stem not in shown and png.stem != "allan" and _listed(d, png.name):
            parts.append(_img(png, png.stem.replace("_", " ")))
    if inp:
        parts.append(
            "<h3>Inputs</h3>" + _kv_table({k: v for k, v in inp.items() if k != "warnings"})
        )
    parts.append(_run_block(d))
    parts.append("</details></section>")
    return "".join(parts), warnings, commands


def _duration(seconds: float) -> str:
    if seconds >= 3600:
        return f"{_num(seconds / 3600, 3)} h"
    return f"{_num(seconds / 60, 3)} min" if seconds >= 120 else f"{_num(seconds, 3)} s"


def _summary_section(
    noise: dict[str, Any] | None, static_dir: Path | None, dyn_dirs: list[Path], root: Path
) -> str:
    """The answer first: the IMU's noise terms, its in-motion verdicts and factors, the
    filter parameters and what is not guaranteed (one IMU: the static log's)."""
    inp = (noise or {}).get("input") or {}
    file, sep, topic = str(inp.get("path", "")).partition(":/")  # a bag's topic
    imu = (Path(file).name + (f":/{topic}" if sep else "")) if file else (
        dyn_dirs[0].name if dyn_dirs else "?")
    parts = [f"<section id='summary'><h2>Summary — {_e(imu)}</h2>"]
    not_guaranteed: list[str] = []
    channels = (noise or {}).get("channels") or {}
    dyn_dir = dyn_dirs[0] if dyn_dirs else None
    dyn = _load_json(dyn_dir / "dynamic.json") if dyn_dir is not None else None
    motion = _load_json(dyn_dir / "motion.json") if dyn_dir is not None else None
    mchans = (motion or {}).get("channels") or {}
    same_imu = True  # the dynamic analysis used this static log's noise.json (--static)
    if dyn is not None and channels:
        full0 = (dyn.get("modes") or {}).get("full") or {}
        same_imu = any(r.get("source") == "noise.json"
                       for rows_ in (full0.get("budget") or {}).values() for r in rows_)
    if channels:
        conf = ((noise or {}).get("settings") or {}).get("confidence")
        dur = inp.get("duration_s") or 0
        parts.append(
            f"<p>Static log: {_duration(dur)} at {_num(inp.get('sample_rate_hz'))} Hz. "
            f"Noise terms in datasheet units with their {_num(100 * (conf or 0.95), 3)} % "
            "intervals; '≤': not resolved by the log, its upper bound.</p>"
        )
        rows = []
        for ch, c in channels.items():
            sel = ((c or {}).get("noise") or {}).get("selected") or {}
            rows.append([_e(ch), *(_term_cell(sel.get(t) or {}) for t in ("N", "B", "K"))])
            for t in ("N", "B", "K"):
                if (sel.get(t) or {}).get("status") == "upper_bound":
                    not_guaranteed.append(
                        f"{ch} {t}: not resolved by the static log (only its upper bound is known)"
                    )
        parts.append(_table(["channel", "N (white noise)", "B (bias instability)",
                             "K (rate random walk)"], rows))
        parts.append(summary_line(channels))
    if dyn is not None:
        full = (dyn.get("modes") or {}).get("full") or {}
        verdicts = full.get("verdict") or {}
        src = Path(str((dyn.get("input") or {}).get("source", dyn_dir))).name
        alpha = ((full.get("alpha") or {}).get("alpha"))
        parts.append(
            f"<h3>In motion: {_e(src)} (guaranteed with probability ≥ "
            f"{_num(1 - (alpha or 0.01), 4)})</h3>"
        )
        if not same_imu:
            parts.append(
                "<p class='warn'>This dynamic analysis did not use the static log's noise.json "
                "(no --static): its verdicts and factors are for the noise model it was given "
                "(a datasheet preset or drive.yaml), not for the IMU above.</p>"
            )
            not_guaranteed.append(
                f"the in-motion results of {src} are for its own noise model, not this IMU's"
            )
        rows = []
        for ch in [*verdicts, *(c for c in (full.get("channels_not_analysed") or {})
                               if c not in verdicts)]:
            v = verdicts.get(ch)
            mc = mchans.get(ch) or {}
            F = mc.get("F")
            res = [r for r in mc.get("rows", []) if r.get("resolved")]
            infl = [r["bound_resolved"] / r["stationary"] for r in res
                    if r.get("bound_resolved") is not None and r.get("stationary")]
            det = (full.get("verdict_detail") or {}).get(ch) or {}
            cls = _verdict_class(v, det)
            sel = (((channels.get(ch) or {}).get("noise") or {}).get("selected") or {})
            if det.get("fragile"):
                not_guaranteed.append(f"{ch}: {det.get('fragile_detail', 'fragile verdict')}")
            rows.append([
                _e(ch),
                f"<span class='{cls}'>{_e(_verdict_text(v, det))}</span>",
                _num(F, 3) if F is not None else "—",
                (f"{_num(min(infl), 3)} – {_num(max(infl), 3)}" if infl else "—"),
                (f"{_num(res[0]['tau_s'], 3)} – {_num(res[-1]['tau_s'], 3)} s" if res else "—"),
                _term_cell(sel.get("N") or {}, F) if F is not None and sel and same_imu else "—",
            ])
            if v is None:
                why = (full.get("channels_not_analysed") or {}).get(ch, "")
                not_guaranteed.append(f"{ch}: not analysed in motion ({why})")
            elif F is None:
                not_guaranteed.append(
                    f"{ch}: the trip's aiding is coarser than the stationary band at every "
                    "averaging time: its in-motion noise is not bounded tightly (verdict "
                    f"{v})"
                )
        parts.append(_table(["channel", "verdict", "in-motion factor F",
                             "bound / stationary (resolved τ)", "resolved τ",
                             "N in motion = F·N"], rows))
        parts.append(
            "<p class='muted'>F: the smallest factor (≥ 1) by which the stationary prediction "
            "must grow to contain the guaranteed in-motion error of every resolved window "
            "(aided interval no wider than the stationary band); details in motion.json and "
            "the Filter parameters page of the documentation.</p>"
        )
    if channels:
        parts.append(_filter_block(noise or {}, motion if same_imu else None))
    if dyn is not None and "paper" in (dyn.get("modes") or {}):
        not_guaranteed.append("mode paper (the paper's per-step method) is not guaranteed")
    not_guaranteed.append(
        "the filter parameters: a white-noise and random-walk model fitted to the bounds; a "
        "filter given them is not thereby guaranteed consistent"
    )
    parts.append("<h3>What is not guaranteed</h3><ul>"
                 + "".join(f"<li>{_e(x)}</li>" for x in not_guaranteed) + "</ul>")
    parts.append("<p class='muted'>The details follow, collapsed: click a heading to open "
                 "it.</p></section>")
    return "".join(parts)


def _filter_block(noise: dict[str, Any], motion: dict[str, Any] | None) -> str:
    """Kalibr's four densities, stationary and in motion (the worst axis of each sensor)."""
    from imubounds.errors import ImuboundsError
    from imubounds.export import KALIBR_KEYS, filter_noise, kalibr_values

    try:
        stat = kalibr_values(filter_noise(noise))
        mot = kalibr_values(filter_noise(noise, motion=motion)) if motion else None
    except ImuboundsError as err:
        return f"<h3>Filter parameters</h3><p class='muted'>not exported: {_e(err)}</p>"
    units = {
        "gyroscope_noise_density": "rad/s/√Hz", "gyroscope_random_walk": "rad/s²/√Hz",
        "accelerometer_noise_density": "m/s²/√Hz", "accelerometer_random_walk": "m/s³/√Hz",
    }

    def moving(k: str) -> str:
        if mot is None or k not in mot:
            return "—"
        v, ax = mot[k]
        # an axis the trip gave no in-motion factor keeps its stationary figure: say so
        note = (" <span class='muted'>(no in-motion factor)</span>"
                if ax.motion_F is None else "")
        return _num(v) + note

    rows = [[_e(k), _num(stat[k][0]) if k in stat else "—", moving(k), _e(units[k])]
            for k, *_ in KALIBR_KEYS]
    rate = (noise.get("input") or {}).get("sample_rate_hz")
    return (
        "<h3>Filter parameters (Kalibr / OpenVINS, continuous time, worst axis)</h3>"
        + _table(["key", "stationary", "in motion", "unit"], rows)
        + f"<p class='muted'>update_rate {_num(rate)} Hz. Every format "
        "(kalibr, openvins, vins, gtsam, ros) with its units and conversions: "
        "<code>imubounds export STATIC_DIR --format F [--motion DYNAMIC_DIR] -o FILE</code>"
        " (the demo wrote them to filter/).</p>"
    )


def _commands(root: Path, found: list[str]) -> list[str]:
    """Every command of the run, in the order they ran: the commands a run.json of the
    folder lists (``imubounds demo`` records its steps: static, simulate, dynamic and every
    export), else the command of each run.json in the folder and its sub-folders
    (static, sim, dynamic, ...) by the time they finished, and those of the sections."""
    top = _load_json(root / "run.json")
    if isinstance(top, dict) and top.get("commands"):
        return [str(top.get("command", "")), *(str(c) for c in top["commands"])]
    runs = []
    for d in (root, *sorted(p for p in root.iterdir() if p.is_dir() and p.name[:1] != ".")):
        try:
            rec = _load_json(d / "run.json")
        except InputError:  # a folder that is not an imubounds output: not a command
            continue
        if isinstance(rec, dict) and rec.get("command"):
            runs.append((str(rec.get("finished_utc", "")), str(rec["command"])))
    out = [c for _, c in sorted(runs)]
    return out + [c for c in found if c not in out]


def _result_json(path: Path) -> dict[str, Any]:
    """A result file written by imubounds (a JSON object with an imubounds ``format``)."""
    data = _load_json(path)
    fmt = data.get("format") if isinstance(data, dict) else None
    if not isinstance(data, dict) or not str(fmt or "").startswith("imubounds"):
        raise InputError(
            f"{path}: not a result file written by imubounds (no imubounds 'format' in it); "
            "rerun the command that writes it, or move the file away"
        )
    return data


@contextmanager
def _unexpected(path: Path) -> Iterator[None]:
    """A result file whose structure is not what imubounds writes: one-line InputError."""
    try:
        yield
    except (AttributeError, TypeError, KeyError, IndexError, ValueError) as err:
        if isinstance(err, InputError):
            raise
        raise InputError(
            f"{path}: unexpected content ({type(err).__name__}: {str(err)[:80]}); it was "
            "edited or not written by this version of imubounds: rerun the command that wrote it"
        ) from err


def build_report(directory: str | Path, commands: list[str] | None = None) -> str:
    """Return the HTML text of the report for ``directory``; ``commands``: every command
    of the run, when the caller knows them (``imubounds demo``; otherwise they are read
    from the run.json files)."""
    root = Path(directory)
    commands_given = commands
    if not root.is_dir():
        raise InputError(f"{root}: not a directory; give the -o directory of a previous run")
    sections: list[str] = []
    warnings: list[str] = []
    found: list[str] = []
    static_dir = _find(root, "noise.json", ("static",))
    dyn_dirs = [root] if (root / "dynamic.json").is_file() else []
    dyn_dirs += sorted(p for p in root.iterdir() if p.is_dir() and (p / "dynamic.json").is_file())
    fleet_json = root / "fleet.json"
    if static_dir is None and not dyn_dirs and not fleet_json.is_file():
        raise InputError(
            f"{root}: no noise.json or dynamic.json found (also looked in static/ and dynamic/), "
            "nor fleet.json; run 'imubounds static', 'dynamic' or 'fleet' with -o there first"
        )
    if fleet_json.is_file():
        fleet = _result_json(fleet_json)
        with _unexpected(fleet_json):
            html_f, w = _fleet_section(root, fleet)
        sections.append(html_f)
        warnings += w
    if static_dir is not None:
        noise = _result_json(static_dir / "noise.json")
        with _unexpected(static_dir / "noise.json"):
            html_s, w, c = _static_section(static_dir, noise)
        sections.append(html_s)
        warnings += w
        found += c
    for i, dyn_dir in enumerate(dyn_dirs):
        dyn = _result_json(dyn_dir / "dynamic.json")
        label = "" if i == 0 else dyn_dir.name
        with _unexpected(dyn_dir / "dynamic.json"):
            html_d, w, c = _dynamic_section(dyn_dir, dyn, label)
        sections.append(html_d)
        warnings += [f"{dyn_dir.name}: {x}" if label else x for x in w]
        found += c
    warn_html = (
        "".join(f"<div class='warn'>{_e(w)}</div>" for w in warnings)
        if warnings
        else "<p class='ok'>No warnings.</p>"
    )
    commands = list(commands_given) if commands_given is not None else _commands(root, found)
    cmd_html = (
        "<pre>" + "\n".join(_e(c) for c in commands) + "</pre>"
        if commands
        else "<p class='muted'>No run.json found; commands unknown.</p>"
    )
    if static_dir is not None or dyn_dirs:
        noise_doc = _load_json(static_dir / "noise.json") if static_dir is not None else None
        with _unexpected(root):
            at = 1 if fleet_json.is_file() else 0
            sections.insert(at, _summary_section(noise_doc, static_dir, dyn_dirs, root))
            sections.insert(at + 1, _figures_section(static_dir, dyn_dirs[0] if dyn_dirs
                                                     else None))  # fmt: skip
    now = datetime.now(UTC).isoformat(timespec="seconds")
    shown = _real_root(root)
    return (
        "<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'>"
        "<meta name='viewport' content='width=device-width, initial-scale=1'>"
        f"<title>imubounds report — {_e(shown.name)}</title><style>{CSS}</style></head><body>"
        f"<header><h1>imubounds report</h1><p>{_e(shown.resolve())} · imubounds {__version__} · "
        f"generated {now}</p></header><main>"
        + "".join(sections)
        + f"<section id='warnings'><h2>Warnings</h2>{warn_html}</section>"
        + f"<section id='reproduce'><h2>How to reproduce</h2>{cmd_html}"
        f"<p class='muted'>imubounds {__version__} is not on the package index: install it "
        "from its source tree (<code>pip install -e .</code> in the repository) to rerun "
        "these commands.</p></section>"
        "</main></body></html>\n"
    )


def write_report(
    directory: str | Path, dest: str | Path | None = None, commands: list[str] | None = None
) -> Path:
    """Write the report of ``directory`` to ``dest`` (default ``directory/report.html``)
    atomically and return its path (``commands``: see :func:`build_report`)."""
    from imubounds.io.outputs import write_text

    root = Path(directory)
    return write_text(Path(dest) if dest is not None else root / "report.html",
                      build_report(root, commands))
