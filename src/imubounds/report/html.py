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

import base64
import html
import json
import math
from collections.abc import Iterator
from contextlib import contextmanager
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from imubounds import __version__
from imubounds.errors import InputError

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
pre{padding:8px 10px;overflow-x:auto}
.muted{color:#666;font-size:.85em}
"""

TERM_ORDER = ("Q", "N", "B", "K", "R")


def _e(text: Any) -> str:
    return html.escape(str(text))


def _num(v: Any, digits: int = 4) -> str:
    if v is None:
        return "—"
    try:
        f = float(v)
    except (TypeError, ValueError):
        return _e(v)
    if not math.isfinite(f):
        return "—"
    return f"{f:.{digits}g}"


def _load_json(path: Path) -> dict[str, Any] | None:
    if not path.is_file():
        return None
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError, RecursionError) as err:  # JSON and UTF-8 errors are ValueErrors
        reason = " ".join(str(err).split())[:120]
        raise InputError(
            f"{path}: not readable JSON ({reason}); rerun the command that wrote it"
        ) from err
    return data if isinstance(data, dict) else None


def _listed(d: Path, name: str) -> bool:
    """Whether ``d/name`` is a file of the complete set in ``d`` (any file if no run.json
    lists one): a figure left over from an earlier run is not shown with newer results."""
    if not (d / name).is_file():
        return False
    run = _load_json(d / "run.json")
    files = run.get("files") if run else None
    return not isinstance(files, list) or name in files


def _img(path: Path, caption: str) -> str:
    try:
        data = base64.b64encode(path.read_bytes()).decode("ascii")
    except OSError as err:
        raise InputError(f"{path}: cannot read ({err.strerror or err})") from err
    return (
        f'<figure><img alt="{_e(caption)}" src="data:image/png;base64,{data}">'
        f"<figcaption>{_e(caption)}</figcaption></figure>"
    )


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
    parts = ["<section id='static'><h2>Stationary characterisation</h2>"]
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
        parts.append(
            _img(
                d / "allan.png",
                "Allan deviation per channel with confidence intervals, the noise-term lines and "
                "the fitted curve (and fitted stochastic models where asked).",
            )
        )
    parts.append(_run_block(d))
    parts.append("</section>")
    return "".join(parts), warnings, commands


DYN_FIGURES = (
    (
        "intervals",
        "Dynamic error intervals per step: the aided interval of each quantity "
        "minus the measured value, with the stationary 95 % level for comparison.",
    ),
    ("trajectory", "Trajectory in the local ENU frame: GPS boxes and contracted position boxes."),
    (
        "comparison",
        "Mean dynamic error intervals of the paper and full kinematic modes against "
        "the stationary 95 % levels.",
    ),
)


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


def _mode_table(mode: str, summ: dict[str, Any]) -> str:
    chans = summ.get("channels") or {}
    parts = [
        f"<h3>Dynamic error margins — {_e(mode)} kinematics "
        f"({_e(summ.get('n_steps', '?'))} steps of {_num(summ.get('step_s'))} s)</h3>"
        "<table><tr><th class='l'>channel</th><th>mean error interval (SI)</th>"
        "<th>mean error interval (°/s)</th><th>mean midpoint</th><th>aided mean width</th>"
        "<th>stationary 95 % level</th><th>ratio</th><th>measurement inside aided</th>"
        "<th class='l'>verdict</th></tr>"
    ]
    for ch, c in chans.items():
        if not isinstance(c, dict):
            continue
        unit = str(c.get("unit", ""))
        deg = (
            _interval(c.get("dynamic_error_mean_interval"), 180.0 / math.pi)
            if unit == ("rad/s")
            else "—"
        )
        inside = c.get("measurement_inside_aided")
        verdict = str(c.get("verdict", "—"))
        cls = "bad" if "superset" in verdict else "ok"
        parts.append(
            f"<tr><td class='l'>{_e(ch)}</td>"
            f"<td>{_interval(c.get('dynamic_error_mean_interval'))} {_e(unit)}</td>"
            f"<td>{deg}</td><td>{_num(c.get('dynamic_error_mean_midpoint'))}</td>"
            f"<td>{_num(c.get('aided_mean_width'))}</td>"
            f"<td>{_num(c.get('stationary_level_95'))} {_e(unit)}</td>"
            f"<td>{_num(c.get('ratio_to_stationary_95'), 3)}</td>"
            f"<td>{_num(100 * inside, 3) + ' %' if isinstance(inside, int | float) else '—'}</td>"
            f"<td class='l {cls}'>{_e(verdict)}</td></tr>"
        )
    parts.append("</table>")
    extra = {
        k: v
        for k, v in summ.items()
        if k
        in (
            "empty_rule",
            "position_box_mean_width_m",
            "gps_box_mean_width_m",
            "enclosure",
            "counts",
        )
    }
    if extra:
        parts.append(_kv_table(extra))
    return "".join(parts)


def _modes_explained(modes: dict[str, Any]) -> str:
    """Why the ``paper`` and ``full`` kinematic modes differ, with this run's numbers."""
    paper, full = modes.get("paper"), modes.get("full")
    if not (isinstance(paper, dict) and isinstance(full, dict)):
        return ""

    def empties(summ: dict[str, Any]) -> int:
        flags = summ.get("flags") or {}
        return sum(int(v.get("count", 0)) for k, v in flags.items() if "empty" in k)

    def share(summ: dict[str, Any], key: str) -> str:
        enc = summ.get("enclosure") or {}
        v = enc.get(key)
        return "—" if v is None else f"{100 * float(v):.1f} %"

    rows = "".join(
        f"<tr><td class='l'>{name}</td><td>{empties(summ)}</td>"
        f"<td>{share(summ, 'position_box')}</td><td>{share(summ, 'v')}</td></tr>"
        for name, summ in (("paper", paper), ("full", full))
    )
    return (
        "<h3 id='modes'>Why the paper and full kinematics differ</h3>"
        "<p>The paper's mechanisation (mode <code>paper</code>) integrates the accelerometer "
        "readings as if they were u̇ and v̇. In a rotating body frame an accelerometer measures "
        "a<sub>x</sub> = u̇ − r·v and a<sub>y</sub> = v̇ + r·u, so in a turn the centripetal "
        "term r·u (metres per second squared in a car) is read as lateral acceleration: the "
        "predicted lateral velocity drifts, the predicted position box misses the GPS box "
        "(an empty intersection) and the neglected term lands in the 'dynamic error'. Mode "
        "<code>full</code> keeps the transport terms. On straight segments the two agree.</p>"
        "<table><tr><th class='l'>mode</th><th>empty intersections</th>"
        "<th>truth in position box</th><th>truth in lateral-velocity interval</th></tr>"
        f"{rows}</table>"
    )


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
    parts = [f"<section id='{sid}'><h2>{title}</h2>"]
    modes = dyn.get("modes") or {}
    primary = str(dyn.get("primary_mode") or next(iter(modes), ""))
    if primary in modes:
        chans = (modes[primary] or {}).get("channels") or {}
        items = []
        for ch, c in chans.items():
            if isinstance(c, dict) and "verdict" in c:
                cls = "bad" if "superset" in str(c["verdict"]) else "ok"
                items.append(
                    f"<li><b>{_e(ch)}</b>: mean dynamic error "
                    f"{_interval(c.get('dynamic_error_mean_interval'))} {_e(c.get('unit', ''))} "
                    f"vs stationary 95 % level ±{_num(c.get('stationary_level_95'))}: "
                    f"<span class='{cls}'>{_e(c['verdict'])}</span></li>"
                )
        parts.append(
            f"<h3 id='verdict'>Verdict: dynamic vs stationary ({_e(primary)} mode)</h3>"
            f"<ul>{''.join(items)}</ul>"
        )
    parts.append(_modes_explained(modes))
    for mode, summ in modes.items():
        if isinstance(summ, dict):
            parts.append(_mode_table(str(mode), summ))
            for flag, v in (summ.get("flags") or {}).items():
                if isinstance(v, dict) and v.get("count"):
                    first = v.get("first_times_s") or []
                    warnings.append(
                        f"{mode} mode: {flag.replace('_', ' ')} at {v['count']} step(s)"
                        + (f" (first at t = {_num(first[0])} s)" if first else "")
                        + f"; rule: {summ.get('empty_rule', '?')}"
                    )
    # Older or other layouts: a flat summary and verdict.
    if not modes and isinstance(dyn.get("summary"), dict):
        parts.append(_kv_table(dyn["summary"]))
    if dyn.get("verdict") and not modes:
        parts.append(f"<h3>Dynamic vs stationary</h3><p>{_e(dyn['verdict'])}</p>")
    if dyn.get("with_model_error"):
        parts.append(
            "<h3>With the scenario's model-error bounds</h3>"
            + _kv_table(dyn["with_model_error"].get("bounds") or {})
        )
    shown = set()
    for stem, caption in DYN_FIGURES:
        if _listed(d, f"{stem}.png"):
            parts.append(_img(d / f"{stem}.png", caption))
            shown.add(stem)
    for png in sorted(d.glob("*.png")):
        if png.stem not in shown and png.stem != "allan" and _listed(d, png.name):
            parts.append(_img(png, png.stem.replace("_", " ")))
    if inp:
        parts.append(
            "<h3>Inputs</h3>" + _kv_table({k: v for k, v in inp.items() if k != "warnings"})
        )
    settings = dyn.get("settings") or {}
    if settings:
        parts.append("<h3>Settings</h3>" + _kv_table(settings, per_row=3))
    bounds = dyn.get("imu_bounds") or {}
    half = bounds.get("halfwidth_per_step") or {}
    if half:
        units = bounds.get("unit") or {}
        parts.append(
            f"<h3>Stationary IMU bounds used (source: {_e(bounds.get('source', '?'))})</h3>"
            "<table><tr><th class='l'>channel</th><th>half-width per step</th></tr>"
            + "".join(
                f"<tr><td class='l'>{_e(k)}</td><td>{_num(v)} {_e(units.get(k, ''))}</td></tr>"
                for k, v in half.items()
            )
            + "</table>"
        )
    parts.append(_run_block(d))
    parts.append("</section>")
    return "".join(parts), warnings, commands


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


def build_report(directory: str | Path) -> str:
    """Return the HTML text of the report for ``directory``."""
    root = Path(directory)
    if not root.is_dir():
        raise InputError(f"{root}: not a directory; give the -o directory of a previous run")
    sections: list[str] = []
    warnings: list[str] = []
    commands: list[str] = []
    static_dir = _find(root, "noise.json", ("static",))
    dyn_dirs = [root] if (root / "dynamic.json").is_file() else []
    dyn_dirs += sorted(p for p in root.iterdir() if p.is_dir() and (p / "dynamic.json").is_file())
    if static_dir is None and not dyn_dirs:
        raise InputError(
            f"{root}: no noise.json or dynamic.json found (also looked in static/ and dynamic/); "
            "run 'imubounds static' or 'imubounds dynamic' with -o there first"
        )
    if static_dir is not None:
        noise = _result_json(static_dir / "noise.json")
        with _unexpected(static_dir / "noise.json"):
            html_s, w, c = _static_section(static_dir, noise)
        sections.append(html_s)
        warnings += w
        commands += c
    for i, dyn_dir in enumerate(dyn_dirs):
        dyn = _result_json(dyn_dir / "dynamic.json")
        label = "" if i == 0 else dyn_dir.name
        with _unexpected(dyn_dir / "dynamic.json"):
            html_d, w, c = _dynamic_section(dyn_dir, dyn, label)
        sections.append(html_d)
        warnings += [f"{dyn_dir.name}: {x}" if label else x for x in w]
        commands += c
    warn_html = (
        "".join(f"<div class='warn'>{_e(w)}</div>" for w in warnings)
        if warnings
        else "<p class='ok'>No warnings.</p>"
    )
    cmd_html = (
        "<pre>" + "\n".join(_e(c) for c in commands) + "</pre>"
        if commands
        else "<p class='muted'>No run.json found; commands unknown.</p>"
    )
    now = datetime.now(UTC).isoformat(timespec="seconds")
    return (
        "<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'>"
        "<meta name='viewport' content='width=device-width, initial-scale=1'>"
        f"<title>imubounds report — {_e(root.name)}</title><style>{CSS}</style></head><body>"
        f"<header><h1>imubounds report</h1><p>{_e(root.resolve())} · imubounds {__version__} · "
        f"generated {now}</p></header><main>"
        + "".join(sections)
        + f"<section id='warnings'><h2>Warnings</h2>{warn_html}</section>"
        + f"<section id='reproduce'><h2>How to reproduce</h2>{cmd_html}"
        f"<p class='muted'>pip install imubounds=={__version__}</p></section>"
        "</main></body></html>\n"
    )


def write_report(directory: str | Path, dest: str | Path | None = None) -> Path:
    """Write the report of ``directory`` to ``dest`` (default ``directory/report.html``)
    atomically and return its path."""
    from imubounds.io.outputs import write_text

    root = Path(directory)
    return write_text(Path(dest) if dest is not None else root / "report.html", build_report(root))
