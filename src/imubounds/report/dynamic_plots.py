"""Figures of the dynamic analysis. Every function returns a matplotlib Figure and writes
nothing; :func:`save` writes one as PNG and SVG atomically.

* :func:`plot_margins` -- mode full: the guaranteed half-width of the window-mean IMU
  error against the averaging time tau (median and worst window), with the stationary
  band, log-log, like an Allan plot (accelerometers in m/s^2, gyros in deg/s);
* :func:`plot_windows` -- mode full: the guaranteed intervals of the window-mean error
  over the trip at one tau per channel, with the stationary band (the paper's Figs. 5-6
  in the unit-correct form);
* :func:`plot_trajectory` -- mode full: GNSS boxes, smoothed position boxes, truth;
* :func:`plot_intervals` -- mode paper: the paper's Figs. 5-6 (aided interval per step,
  measured value, truth).
"""

from __future__ import annotations

import math
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.collections import LineCollection, PatchCollection
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Rectangle

from imubounds.io.outputs import write_with

DEG = 180.0 / math.pi
COLORS = {
    "accel_x": "tab:blue",
    "accel_y": "tab:orange",
    "accel_z": "tab:green",
    "gyro_x": "tab:red",
    "gyro_y": "tab:purple",
    "gyro_z": "tab:brown",
}


def _savefig(fig: Figure, ext: str, path: Path) -> None:
    fig.savefig(path, format=ext, dpi=130)


def save(fig: Figure, out_dir: Path, stem: str) -> list[Path]:
    """Write ``fig`` as ``stem.png`` and ``stem.svg`` in ``out_dir`` (atomically)."""
    paths = []
    for ext in ("png", "svg"):
        dest = Path(out_dir) / f"{stem}.{ext}"
        write_with(dest, partial(_savefig, fig, ext))
        paths.append(dest)
    return paths


def _factor(ch: str) -> tuple[float, str]:
    return (DEG, "deg/s") if ch.startswith("gyro") else (1.0, "m/s²")


def plot_margins(summary: dict[str, Any], ax: Any = None, title: str = "") -> Figure:
    """Margins vs tau of mode full (see the module docstring). With ``ax`` (one Axes),
    every channel is drawn there in its own unit; otherwise a new Figure with the
    accelerometers and the gyros side by side."""
    margins = summary.get("margins") or {}
    if ax is None:
        fig = Figure(figsize=(12, 5.8))
        axes = {"accel": fig.add_subplot(1, 2, 1), "gyro": fig.add_subplot(1, 2, 2)}
    else:
        fig = ax.figure
        axes = {"accel": ax, "gyro": ax}
    verdicts = summary.get("verdict") or {}
    bands: list[tuple[Any, np.ndarray, np.ndarray, str]] = []
    for ch, rows in margins.items():
        rows = [r for r in rows if r.get("halfwidth_median") is not None]
        if not rows:
            continue
        f, unit = _factor(ch)
        a = axes["gyro" if ch.startswith("gyro") else "accel"]
        tau = np.array([r["tau_s"] for r in rows])
        med = np.array([r["halfwidth_median"] for r in rows]) * f
        mx = np.array([r["halfwidth_max"] for r in rows]) * f
        band = np.array([r["stationary"] for r in rows]) * f
        c = COLORS.get(ch, "k")
        lab = f"{ch} ({verdicts.get(ch, '?')})" + (f" [{unit}]" if ax is not None else "")
        a.loglog(tau, med, "o-", color=c, ms=3.5, lw=1.4, label=f"{lab}: median window")
        a.loglog(tau, mx, ":", color=c, lw=1.0)
        bands.append((a, tau, band, c))
        a.loglog(tau, band, "--", color=c, lw=1.0)
    for a, tau, band, c in bands:
        lo = a.get_ylim()[0]
        a.fill_between(tau, lo, band, color=c, alpha=0.07)
        a.set_ylim(bottom=lo)
    for kind, a in axes.items():
        unit = "deg/s" if kind == "gyro" else "m/s²"
        a.set_xlabel("averaging time τ [s]")
        if ax is None:
            a.set_ylabel(f"half-width of the guaranteed window-mean error [{unit}]")
            a.set_title(
                "gyros" if kind == "gyro" else "accelerometers", fontsize=10
            )
        a.grid(True, which="both", alpha=0.3)
        handles, labels = a.get_legend_handles_labels()
        handles += [Line2D([], [], color="0.3", lw=1.0, ls=":"),
                    Line2D([], [], color="0.3", lw=1.0, ls="--")]
        labels += ["worst window", "stationary band (shaded below)"]
        # below the axes, off the data (the plateaus sit at the top left)
        a.legend(handles, labels, fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.16),
                 ncol=2, frameon=False)
        if ax is not None:
            break
    fig.suptitle(
        (title + ": " if title else "")
        + "guaranteed margins vs τ (solid: median window, dotted: worst; dashed/shaded: "
        "stationary band)",
        fontsize=10,
    )
    fig.tight_layout()
    return fig


def plot_windows(result: Any, title: str = "", tau_target: float = 10.0) -> Figure:
    """Mode full: intervals of the window-mean error over the trip at one tau per channel,
    with the stationary band (green). The tau shown is the one with the most windows
    entirely outside the band (marked red) if any, else the decidable tau nearest
    ``tau_target``. Every channel of the analysis has a panel; one without windows, or
    whose intervals are all unbounded, says why in its panel."""
    run = result.full
    summary = getattr(result, "summary", {}) or {}
    nota = summary.get("channels_not_analysed") or {}
    every = ("accel_x", "accel_y", "accel_z", "gyro_x", "gyro_y", "gyro_z")
    has = {ch for ch, m in run.margins.items() if m.levels}
    # a panel per analysed channel and per channel of the planar analysis (which says why
    # it has no windows); the others not analysed are named in one line below
    chans = [ch for ch in every if ch in has or ch in ("accel_x", "accel_y", "gyro_z")]
    others = [ch for ch in every if ch not in chans]
    fig = Figure(figsize=(11, 2.3 * max(1, len(chans)) + 0.8))
    t_end = 0.0
    for i, ch in enumerate(chans):
        ax = fig.add_subplot(len(chans), 1, i + 1)
        m = run.margins.get(ch)
        f, unit = _factor(ch)
        ax.set_ylabel(f"{ch} [{unit}]", fontsize=8)
        ax.grid(alpha=0.3)
        if m is None or not m.levels:
            why = nota.get(ch, "no windows")
            ax.text(0.5, 0.5, f"{ch}: not analysed ({why})", transform=ax.transAxes,
                    ha="center", va="center", fontsize=8, wrap=True)
            ax.set_yticks([])
            continue
        with_ex = [lv for lv in m.levels if np.any(lv.exceeds)]
        if with_ex:
            lv = max(with_ex, key=lambda x: int(np.sum(x.exceeds)))
        else:
            levels = [lv for lv in m.levels if np.any(lv.decidable)] or m.levels
            lv = min(levels, key=lambda x: abs(math.log(x.tau_s / tau_target)))
        t = lv.t_start + 0.5 * lv.tau
        t_end = max(t_end, float(np.max(lv.t_start + lv.tau)))
        lo, hi = lv.e_lo * f, lv.e_hi * f
        fin = np.isfinite(lo) & np.isfinite(hi)
        ax.fill_between(t, -lv.band * f, lv.band * f, color="tab:green", alpha=0.25, step="mid",
                        label="stationary band")
        for sign in (-1.0, 1.0):  # its edges, which the windows are judged against
            ax.step(t, sign * lv.band * f, where="mid", color="tab:green", lw=0.8)
        if fin.any():
            _window_segments(ax, t, lo, hi, fin, lv)
            span = np.concatenate([lo[fin], hi[fin], lv.band * f, -lv.band * f])
            a, b = np.percentile(span, [1, 99])
            pad = 0.1 * (b - a) + 1e-12
            ax.set_ylim(a - pad, b + pad)
        else:
            ax.text(0.5, 0.8, "every interval unbounded at this τ", transform=ax.transAxes,
                    ha="center", fontsize=8)
        ex = lv.exceeds & fin
        if ex.any():
            ax.plot(t[ex], np.where(lo[ex] > 0, lo[ex], hi[ex]), "v", color="tab:red", ms=5,
                    label=f"outside the band ({int(ex.sum())})")
            y0, y1 = ax.get_ylim()  # the exceeding windows are wholly in view
            pad = 0.05 * (y1 - y0)
            ax.set_ylim(min(y0, float(np.min(lo[ex])) - pad), max(y1, float(np.max(hi[ex])) + pad))
        if not np.any(lv.decidable):
            ax.text(0.01, 0.05, "undecided: the aided interval is wider than the band",
                    transform=ax.transAxes, fontsize=7, color="0.3")
        ax.set_xlim(float(np.min(lv.t_start)), float(np.max(lv.t_start + lv.tau)))
        verdict = m.verdict + (", FRAGILE" if m.fragile else "")
        ax.set_title(f"{ch}: windows of τ = {lv.tau_s:.3g} s ({verdict})", fontsize=8,
                     loc="left")
        # above the panel, off the data
        ax.legend(fontsize=7, loc="lower right", bbox_to_anchor=(1.0, 1.0), ncol=5,
                  frameon=False, borderaxespad=0.1)
    if chans:
        fig.axes[-1].set_xlabel("time [s] (window centre, relative to the first IMU sample)")
    bottom = 0.0
    if others:
        why = "; ".join(sorted({str(nota.get(ch, "no windows")) for ch in others}))
        fig.text(0.01, 0.005, f"not analysed: {', '.join(others)} ({why})", fontsize=7,
                 color="0.3", wrap=True)
        bottom = 0.03
    fig.suptitle(
        (title + ": " if title else "")
        + "guaranteed intervals of the window-mean IMU error (decided dark, undecided dotted, "
        "fragile orange) and stationary band (green)",
        fontsize=10,
    )
    fig.tight_layout(rect=(0, bottom, 1, 1))
    return fig


def _window_segments(ax: Any, t: np.ndarray, lo: np.ndarray, hi: np.ndarray,
                     fin: np.ndarray, lv: Any) -> None:
    """The windows' intervals in three kinds, each with its count in the legend: decided
    (dark), undecided (the aided interval wider than the band: light, dotted) and fragile
    (the window's test turns with the band 5 % narrower or wider: orange)."""
    fragile = np.asarray(lv.fragile) & fin
    undecided = ~np.asarray(lv.decidable) & fin & ~fragile
    decided = fin & ~fragile & ~undecided
    for mask, color, lw, ls, what in (
        (decided, "0.25", 1.2, "solid", "decided"),
        (undecided, "0.65", 0.9, "dotted", "undecided (aiding wider than the band)"),
        (fragile, "tab:orange", 1.5, "solid", "fragile (±5 % of the band)"),
    ):
        if not mask.any():
            continue
        segs = np.stack([np.column_stack([t[mask], lo[mask]]),
                         np.column_stack([t[mask], hi[mask]])], 1)
        ax.add_collection(LineCollection(list(segs), colors=color, linewidths=lw,
                                         linestyles=ls, label=f"{what}: {int(mask.sum())}"))


def plot_trajectory(result: Any, drive: Any, title: str = "") -> Figure:
    """Mode full: the whole trip (left: GNSS fixes, smoothed centre, truth) and a zoom on a
    stretch of it (right) where the boxes are visible: GNSS boxes (blue) and the smoothed
    position boxes at the same GNSS epochs (orange), so that like is compared with like.
    The legend sits below the panels, off the data."""
    from imubounds.dynamic.estimator import smoother as SM
    from imubounds.dynamic.estimator.result import truth_at

    run = result.full
    sm = run.smoother
    ag = run.ctx.aiding
    fig = Figure(figsize=(12, 6.2))
    ax, zx = fig.add_subplot(1, 2, 1), fig.add_subplot(1, 2, 2)
    X = sm.X
    fin = np.all(np.isfinite(X[:, [SM.E, SM.N], :].reshape(len(X), -1)), axis=1)
    with np.errstate(invalid="ignore"):  # unbounded epochs (+-inf) are not drawn
        ce = np.where(fin, 0.5 * (X[:, SM.E, 0] + X[:, SM.E, 1]), np.nan)
        cn = np.where(fin, 0.5 * (X[:, SM.N, 0] + X[:, SM.N, 1]), np.nan)
    tr = None
    if drive.truth is not None:
        tr = truth_at(drive, sm.te + run.ctx.imu.t0, ag.origin)
    # the zoom: a square of ~4 GNSS box widths around the epoch of the median box; the
    # whole trip where that is smaller
    with np.errstate(invalid="ignore"):
        half = 0.5 * np.where(fin, np.maximum(X[:, SM.E, 1] - X[:, SM.E, 0],
                                              X[:, SM.N, 1] - X[:, SM.N, 0]), np.nan)
    gh = np.asarray(ag.gnss_h, dtype=float) if ag.has_gnss else np.zeros(0)
    ref = gh[np.isfinite(gh)] if gh.size else half[fin]
    half_ref = float(np.median(ref)) if ref.size else 10.0
    i0 = 0
    if fin.any():
        k_fin = np.flatnonzero(fin)
        i0 = int(k_fin[np.argmin(np.abs(half[fin] - np.median(half[fin])))])
    w = max(4.0 * half_ref, 20.0)
    box = (ce[i0] - w, ce[i0] + w, cn[i0] - w, cn[i0] + w)
    if fin.any() and max(np.ptp(ce[fin]), np.ptp(cn[fin])) < 2 * w:
        mid_e, mid_n = 0.5 * (np.min(ce[fin]) + np.max(ce[fin])), 0.5 * (
            np.min(cn[fin]) + np.max(cn[fin]))
        w = 0.5 * max(np.ptp(ce[fin]), np.ptp(cn[fin])) + 2.5 * half_ref
        box = (mid_e - w, mid_e + w, mid_n - w, mid_n + w)

    def inside(e: Any, n: Any, pad: float = 0.0) -> Any:
        return ((e > box[0] - pad) & (e < box[1] + pad) & (n > box[2] - pad) & (n < box[3] + pad))

    for a in (ax, zx):
        if ag.has_gnss:
            a.plot(ag.gnss_e, ag.gnss_n, ".", color="tab:blue", ms=2 if a is ax else 4)
        a.plot(ce[fin], cn[fin], "-", color="tab:orange", lw=0.8)
        if tr is not None:
            a.plot(tr["east"], tr["north"], "-", color="k", lw=0.8)
    # boxes in the zoom only: the smoothed boxes at the GNSS epochs, and the GNSS boxes
    if ag.has_gnss:
        gt = np.asarray(ag.gnss_t, dtype=float)
        gh = np.where(np.isfinite(gh), gh, 0.0)
        j = np.clip(np.searchsorted(sm.te, gt), 0, sm.te.size - 1)
        j = np.where((j > 0) & (np.abs(sm.te[j - 1] - gt) < np.abs(sm.te[j] - gt)), j - 1, j)
        same = np.abs(sm.te[j] - gt) <= 1e-6 * max(1.0, float(np.max(np.abs(gt))))
        ge, gn = np.asarray(ag.gnss_e), np.asarray(ag.gnss_n)
        sel = np.flatnonzero(inside(ge, gn, 2 * half_ref))
        sel = sel[:: max(1, math.ceil(sel.size / 20))]  # at most ~20 pairs of boxes: readable
        zx.add_collection(PatchCollection(
            [Rectangle((ge[i] - gh[i], gn[i] - gh[i]), 2 * gh[i], 2 * gh[i]) for i in sel],
            facecolor="none", edgecolor="tab:blue", lw=0.9))
        ks = [int(j[i]) for i in sel if same[i] and fin[j[i]]]
    else:
        ks = [int(k) for k in np.flatnonzero(fin & inside(ce, cn, 2 * half_ref))]
        ks = ks[:: max(1, math.ceil(len(ks) / 20))]
    zx.add_collection(PatchCollection(
        [Rectangle((X[k, SM.E, 0], X[k, SM.N, 0]), X[k, SM.E, 1] - X[k, SM.E, 0],
                   X[k, SM.N, 1] - X[k, SM.N, 0]) for k in ks],
        facecolor="tab:orange", edgecolor="tab:red", lw=0.6, alpha=0.3))
    zx.set_xlim(box[0], box[1])
    zx.set_ylim(box[2], box[3])
    ax.add_patch(Rectangle((box[0], box[2]), box[1] - box[0], box[3] - box[2],
                           facecolor="none", edgecolor="tab:red", lw=1.2))
    if fin.any():
        pad = 0.03 * max(np.ptp(ce[fin]), np.ptp(cn[fin]), 1.0)
        ax.set_xlim(np.min(ce[fin]) - pad, np.max(ce[fin]) + pad)
        ax.set_ylim(np.min(cn[fin]) - pad, np.max(cn[fin]) + pad)
    for a, name in ((ax, "whole trip (red square: the zoom)"),
                    (zx, f"zoom (±{w:.0f} m): GNSS boxes and smoothed boxes at the same "
                         "epochs (at most 20)")):
        a.set_aspect("equal", adjustable="box")
        a.set_xlabel("east [m]")
        a.set_ylabel("north [m]")
        a.grid(alpha=0.3)
        a.set_title(name, fontsize=9)
    handles = [
        Line2D([], [], marker=".", ls="none", color="tab:blue", label="GNSS fixes"),
        Rectangle((0, 0), 1, 1, facecolor="none", edgecolor="tab:blue", label="GNSS boxes"),
        Line2D([], [], color="tab:orange", label="smoothed position (centre)"),
        Rectangle((0, 0), 1, 1, facecolor="tab:orange", alpha=0.3, edgecolor="tab:red",
                  label="smoothed position boxes"),
    ]
    if tr is not None:
        handles.append(Line2D([], [], color="k", label="truth"))
    fig.legend(handles=handles, loc="lower center", ncol=len(handles), fontsize=8,
               frameon=False)
    fig.suptitle((title + ": " if title else "") + "trajectory", fontsize=10)
    fig.tight_layout(rect=(0, 0.06, 1, 1))
    return fig


PAPER_LABELS = {
    "accel_x": ("forward acceleration", "m/s²", 1.0),
    "accel_y": ("lateral acceleration", "m/s²", 1.0),
    "gyro_z": ("turn rate r", "°/s", DEG),
}


def plot_intervals(res: Any, title: str = "") -> Figure:
    """Mode paper (its Figs. 5-6): per step the aided interval (grey), the measured value
    (red) and the truth (black) where known."""
    from imubounds.dynamic.estimator.paper import CHANNELS

    st = res.steps
    t = st.t[1:] - st.t[0]
    fig = Figure(figsize=(10, 8.5))
    for c, ch in enumerate(CHANNELS):
        ax = fig.add_subplot(len(CHANNELS), 1, c + 1)
        name, unit, f = PAPER_LABELS[ch]
        lo, hi = res.A[1:, 2 * c] * f, res.A[1:, 2 * c + 1] * f
        meas = st.meas[1:, c] * f
        fin = np.isfinite(lo) & np.isfinite(hi)
        segs = np.stack([np.column_stack([t[fin], lo[fin]]), np.column_stack([t[fin], hi[fin]])], 1)
        lw = max(0.6, min(4.0, 500.0 / max(t.size, 1)))
        ax.add_collection(
            LineCollection(list(segs), colors="0.6", linewidths=lw, label="aided interval")
        )
        ax.plot(t, meas, ".", color="red", ms=2.5, label="measured")
        key = {"accel_x": "accel_x", "accel_y": "accel_y", "gyro_z": "r"}[ch]
        if st.truth is not None and key in st.truth:
            ax.plot(t, st.truth[key][1:] * f, "-", color="black", lw=0.6, label="truth")
        if fin.any():
            span = np.concatenate([lo[fin], hi[fin], meas])
            a, b = np.percentile(span, [2, 98])
            pad = 0.1 * (b - a) + 1e-9
            ax.set_ylim(a - pad, b + pad)
        ax.set_ylabel(f"{name} [{unit}]", fontsize=8)
        ax.grid(alpha=0.3)
        ax.legend(loc="lower right", bbox_to_anchor=(1.0, 1.0), fontsize=7, ncol=3,
                  frameon=False, borderaxespad=0.1)  # above the panel, off the data
        ax.set_xlim(t[0] - 1, t[-1] + 1)
    fig.axes[-1].set_xlabel("time since start [s]")
    fig.suptitle(
        (title + ": " if title else "")
        + "mode paper (NOT guaranteed): aided intervals (grey), measured (red)",
        fontsize=10,
    )
    fig.tight_layout()
    return fig
