"""Small HTML pieces shared by the report's sections (:mod:`imubounds.report.html`)."""

from __future__ import annotations

import base64
import html
import json
import math
from pathlib import Path
from typing import Any

from imubounds.errors import InputError


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


def _table(head: list[str], rows: list[list[str]]) -> str:
    h = "".join(f"<th class='l'>{_e(x)}</th>" if i == 0 else f"<th>{_e(x)}</th>"
                for i, x in enumerate(head))
    body = "".join(
        "<tr>" + "".join(
            f"<td class='l'>{c}</td>" if i == 0 else f"<td>{c}</td>" for i, c in enumerate(r)
        ) + "</tr>"
        for r in rows
    )
    return f"<table><tr>{h}</tr>{body}</table>"


def _term_cell(e: dict[str, Any], factor: float = 1.0) -> str:
    """A selected term in datasheet units with its CI; '≤' for an upper bound."""
    ds = e.get("datasheet") or {}
    if ds.get("value") is None:
        return "—"
    mark = "≤ " if e.get("status") == "upper_bound" else ""
    ci = ds.get("ci")
    ci_txt = ""
    if ci and e.get("status") != "upper_bound":
        lo, hi = _num(ci[0] * factor, 3), _num(ci[1] * factor, 3)
        ci_txt = f" <span class='muted'>[{lo}, {hi}]</span>"
    return f"{mark}{_num(ds['value'] * factor, 3)} {_e(ds.get('unit', ''))}{ci_txt}"
