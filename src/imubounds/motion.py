"""In-motion noise figures: how much larger the IMU's error is while it moves.

Mode ``full`` of the dynamic analysis gives, for each channel, each averaging time
``tau`` and each window ``w`` of the trip, a guaranteed interval ``[e_lo, e_hi]`` of
the window's mean IMU error (IMU mean minus the aided truth). From these this module
derives, per channel and ``tau``:

``bound``
    the guaranteed upper bound of the in-motion error: ``max_w max(|e_lo|, |e_hi|)``
    (with the trip's probability ``1 - alpha`` the true ``|e|`` of every window is at
    most this);
``floor``
    the guaranteed lower bound of the largest in-motion error:
    ``max_w dist(0, [e_lo, e_hi])`` (some window's error is at least this);
``stationary``
    the stationary prediction at the same ``tau``: the median of the windows'
    stationary bands (``k`` sigma of the noise budget, turn-on bias and deterministic
    terms included), as in ``dynamic.json``'s ``margins``;
``inflation``
    ``bound / stationary``: the motion inflation factor. It exceeds 1 where, and only
    where, the guaranteed in-motion bound exceeds the stationary prediction. Where the
    aiding is coarse (the aided interval is wider than the band) it is an upper bound
    that says little; ``inflation_at_least = floor / stationary`` exceeding 1 proves
    that the IMU itself is worse in motion (the ``exceeds`` verdict).

The in-motion noise parameters: a window is *resolved* where its aided interval is
no wider than its stationary band (the IMU, not the aiding, sets its bound), a
``tau`` where at least half of its windows are. ``bound_resolved`` is the bound over
the resolved windows; the factor ``F`` is the largest ``bound_resolved /
stationary`` over the resolved averaging times, and at least 1. ``F`` times the
stationary prediction contains the guaranteed in-motion error of every resolved
window at every resolved ``tau``; the in-motion ``N`` and ``K`` are ``F`` times the
stationary ones (the band's noise part is linear in them). Where no ``tau`` is
resolved, no in-motion parameters are given (``F`` is ``None``) and the stationary
ones are not confirmed in motion.

``motion.json`` (written by ``imubounds dynamic`` next to ``dynamic.json``) is
:func:`motion_figures`'s result; nothing here prints.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from imubounds.errors import InputError

FORMAT = "imubounds.motion/1"

_DEG = 180.0 / math.pi


def _levels_rows(level: Any) -> dict[str, Any]:
    import numpy as np

    e_lo = np.asarray(level.e_lo, dtype=float)
    e_hi = np.asarray(level.e_hi, dtype=float)
    band = np.asarray(level.band, dtype=float)
    x_half = 0.5 * (np.asarray(level.x_hi, dtype=float) - np.asarray(level.x_lo, dtype=float))
    fin = np.isfinite(e_lo) & np.isfinite(e_hi)
    stat = float(np.median(band)) if band.size else None
    row: dict[str, Any] = {
        "tau_s": float(level.tau_s), "bound": None, "floor": None, "stationary": stat,
        "inflation": None, "inflation_at_least": None, "resolved": False,
        "bound_resolved": None, "n_resolved": 0, "k": float(level.k),
        "n_windows": int(band.size),
    }
    if not fin.any() or stat is None or stat <= 0:
        return row
    mag = np.maximum(np.abs(e_lo), np.abs(e_hi))
    dist = np.where((e_lo <= 0) & (e_hi >= 0), 0.0, np.minimum(np.abs(e_lo), np.abs(e_hi)))
    # a window is resolved where the aided interval is no wider than its stationary band
    res_w = fin & (x_half <= band) & (level.kind != "vehicle")
    row["bound"] = float(mag[fin].max())
    row["floor"] = float(dist[fin].max())
    row["inflation"] = row["bound"] / stat
    row["inflation_at_least"] = row["floor"] / stat
    row["n_resolved"] = int(res_w.sum())
    row["resolved"] = bool(res_w.sum() * 2 >= band.size)
    if res_w.any():
        row["bound_resolved"] = float(mag[res_w].max())
    return row


def motion_figures(
    result: Any, noise: Mapping[str, Any] | str | Path | None = None
) -> dict[str, Any]:
    """The in-motion figures (``motion.json``) of a mode-``full``
    :class:`~imubounds.dynamic.estimator.result.DynamicResult`.

    Parameters
    ----------
    result : DynamicResult
        Mode ``full`` (its per-window intervals are read; ``dynamic.json`` holds only
        their half-widths).
    noise : mapping or path, optional
        The noise.json the analysis used (``--static``); its ``N`` and ``K`` per
        channel are scaled by ``F`` into the in-motion parameters. Without it the
        noise figures the analysis used (its budget) are scaled.

    Returns
    -------
    dict
        ``{format, statement, channels: {ch: {unit, rows[], F, resolved_taus[],
        N_static, K_static, N_motion, K_motion, verdict, derivation}}}`` in SI.
    """
    run = getattr(result, "full", None)
    if run is None or not getattr(run, "margins", None):
        raise InputError("in-motion figures need mode full's margins (run mode full)")
    summary = getattr(result, "summary", {}) or {}
    noise_doc = _load_noise(noise) if noise is not None else None
    chans: dict[str, Any] = {}
    for ch, m in run.margins.items():
        levels = list(getattr(m, "levels", []) or [])
        if not levels:
            continue
        rows = [_levels_rows(lv) for lv in levels]
        res = [r for r in rows if r["resolved"] and r["bound_resolved"] is not None]
        F = max(1.0, max(r["bound_resolved"] / r["stationary"] for r in res)) if res else None
        n_s, k_s = _static_terms(ch, noise_doc, summary)
        chans[ch] = {
            "unit": getattr(m, "unit", "rad/s" if ch.startswith("gyro") else "m/s^2"),
            "verdict": getattr(m, "verdict", None),
            "rows": rows,
            "resolved_taus": [r["tau_s"] for r in res],
            "F": F,
            "N_static": n_s,
            "K_static": k_s,
            "N_motion": None if F is None or n_s is None else F * n_s,
            "K_motion": None if F is None or k_s is None else F * k_s,
            "derivation": (
                "F = max(1, max over resolved tau of bound_resolved/stationary); "
                "N_motion = F*N, K_motion = F*K: F times the stationary prediction "
                "contains the guaranteed in-motion error of every resolved window at "
                "every resolved tau"
                if F is not None
                else "no tau resolved (the aided interval is wider than the stationary "
                "band at every tau): no in-motion parameters; the stationary ones are "
                "not confirmed in motion"
            ),
        }
    return {
        "format": FORMAT,
        "statement": summary.get("statement"),
        "definitions": {
            "bound": "guaranteed upper bound of |tau-mean IMU error| over the trip's windows",
            "floor": "guaranteed lower bound of the largest |tau-mean IMU error|",
            "stationary": "median stationary band at the same tau (k sigma, as in margins)",
            "inflation": "bound / stationary (> 1 exactly where bound > stationary)",
            "resolved": "at least half of the windows are resolved: their aided interval "
            "is no wider than their stationary band (the IMU, not the aiding, sets the "
            "bound)",
            "bound_resolved": "the bound over the resolved windows only",
        },
        "channels": chans,
    }


def _load_noise(noise: Mapping[str, Any] | str | Path) -> Mapping[str, Any]:
    if isinstance(noise, Mapping):
        return noise
    import json

    p = Path(noise)
    if p.is_dir():
        p = p / "noise.json"
    try:
        doc = json.loads(p.read_text(encoding="utf-8"))
    except (OSError, ValueError) as err:
        raise InputError(f"{p}: cannot read noise.json ({err})") from None
    if not isinstance(doc, Mapping):
        raise InputError(f"{p}: not a noise.json document")
    return doc


def _static_terms(
    ch: str, noise_doc: Mapping[str, Any] | None, summary: Mapping[str, Any]
) -> tuple[float | None, float | None]:
    """N and K (SI) of ``ch``: from noise.json's selected terms, else the budget rows."""
    if noise_doc is not None:
        sel = (((noise_doc.get("channels") or {}).get(ch) or {}).get("noise") or {}).get(
            "selected"
        ) or {}
        n = (sel.get("N") or {}).get("value")
        k = (sel.get("K") or {}).get("value")
        return (float(n) if n else None, float(k) if k else None)
    n_v: float | None = None
    k_v: float | None = None
    for row in (summary.get("budget") or {}).get(ch, []):
        term = str(row.get("term", ""))
        if term.startswith("white noise density") and row.get("value"):
            n_v = float(row["value"])
        if term.startswith("rate random walk") and row.get("value"):
            k_v = float(row["value"])
    return n_v, k_v


def read_motion(path: str | Path) -> dict[str, Any]:
    """``motion.json`` from an ``imubounds dynamic`` output folder (or the file itself)."""
    import json

    p = Path(path)
    if p.is_dir():
        p = p / "motion.json"
    elif p.name == "dynamic.json":
        p = p.with_name("motion.json")
    if not p.is_file():
        raise InputError(
            f"{p}: no motion.json; run 'imubounds dynamic ... -o DIR' (mode full) with this "
            "version and give DIR"
        )
    try:
        doc = json.loads(p.read_text(encoding="utf-8"))
    except (OSError, ValueError) as err:
        raise InputError(f"{p}: cannot read ({err})") from None
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        raise InputError(f"{p}: not an imubounds motion.json ({FORMAT})")
    return doc


def plot_motion(motion: Mapping[str, Any], noise: Mapping[str, Any] | None = None) -> Any:
    """The Allan plot with the in-motion figures: per channel the stationary Allan
    deviation (from noise.json), the stationary prediction and the guaranteed in-motion
    bound divided by ``k`` (so that they read as one-sigma deviations on the Allan axes).
    Gyros in deg/s, accelerometers in m/s^2. Returns a new Figure (no pyplot)."""
    from matplotlib.figure import Figure

    chans = list((motion.get("channels") or {}).items())
    n = max(1, len(chans))
    fig = Figure(figsize=(5.0 * min(n, 3), 3.8 * math.ceil(n / 3)), layout="constrained")
    for i, (ch, c) in enumerate(chans):
        ax = fig.add_subplot(math.ceil(n / 3), min(n, 3), i + 1)
        f, unit = (_DEG, "deg/s") if ch.startswith("gyro") else (1.0, "m/s^2")
        rows = [r for r in c["rows"] if r.get("bound") is not None and r.get("k")]
        if noise is not None:
            al = (((noise.get("channels") or {}).get(ch) or {}).get("allan")) or {}
            if al.get("tau_s"):
                ax.loglog(al["tau_s"], [v * f for v in al["adev"]], color="0.3",
                          label="stationary Allan deviation")
        if rows:
            t = [r["tau_s"] for r in rows]
            ax.loglog(t, [r["stationary"] / r["k"] * f for r in rows], "--", color="tab:blue",
                      label="stationary prediction / k")
            ax.loglog(t, [r["bound"] / r["k"] * f for r in rows], "-", color="tab:red",
                      label="in-motion bound / k (guaranteed)")
            rt = [r for r in rows if r["resolved"]]
            if rt:
                ax.loglog([r["tau_s"] for r in rt], [r["bound"] / r["k"] * f for r in rt],
                          "o", color="tab:red", ms=4, label="resolved tau")
        title = f"{ch}: F = {c['F']:.3g}" if c.get("F") else f"{ch}: F not resolved"
        ax.set_title(title, fontsize=9)
        ax.set_xlabel("tau [s]")
        ax.set_ylabel(f"deviation [{unit}]")
        ax.grid(True, which="both", alpha=0.3)
    handles, labels = [], []
    for ax in fig.axes:  # one legend for the figure, below the panels (off the data)
        for h, lab in zip(*ax.get_legend_handles_labels(), strict=True):
            if lab not in labels:
                handles.append(h)
                labels.append(lab)
    if handles:
        fig.legend(handles, labels, loc="outside lower center", ncol=len(labels), fontsize=8,
                   frameon=False)
    return fig
