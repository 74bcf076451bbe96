"""Figures of the dynamic analysis, in the paper's style (its Figs. 5 and 6).

* :func:`plot_intervals`: per channel, grey bars of the aided interval of the
  estimated quantity over time, the measured value in red (and the truth in
  black where known); accelerations in m/s², turn rate in °/s.
* :func:`plot_trajectory`: the local ENU track with the GPS boxes and the
  contracted position boxes (and the truth where known), in m.
* :func:`plot_comparison`: the dynamic error margins (mean interval) next to
  the stationary 95 % level per channel.

Each figure is written as PNG and SVG atomically.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.collections import LineCollection, PatchCollection
from matplotlib.figure import Figure
from matplotlib.patches import Rectangle

from imubounds.dynamic.estimator.core import CHANNELS, EstimatorResult
from imubounds.io.outputs import write_with

LABELS = {
    "accel_x": ("forward acceleration $\\dot u$", "m/s²", 1.0),
    "accel_y": ("lateral acceleration $\\dot v$", "m/s²", 1.0),
    "gyro_z": ("turn rate $r$", "°/s", 180.0 / math.pi),
}


def _save(fig: Figure, out_dir: Path, stem: str) -> list[Path]:
    paths = []
    for ext in ("png", "svg"):
        dest = out_dir / f"{stem}.{ext}"
        write_with(dest, lambda p, e=ext: fig.savefig(p, format=e, dpi=130))
        paths.append(dest)
    plt.close(fig)
    return paths


def plot_intervals(res: EstimatorResult, out_dir: Path, title: str = "") -> list[Path]:
    """Grey interval bars of the aided estimate, measured value in red (per channel)."""
    st = res.steps
    t = st.t[1:] - st.t[0]
    fig, axes = plt.subplots(len(CHANNELS), 1, figsize=(10, 8.5), sharex=True)
    for ax, (c, ch) in zip(axes, enumerate(CHANNELS), strict=True):
        name, unit, f = LABELS[ch]
        lo, hi = res.A[1:, 2 * c] * f, res.A[1:, 2 * c + 1] * f
        meas = st.meas[1:, c] * f
        fin = np.isfinite(lo) & np.isfinite(hi)
        segs = np.stack(
            [np.column_stack([t[fin], lo[fin]]), np.column_stack([t[fin], hi[fin]])], axis=1
        )
        lw = max(0.6, min(4.0, 500.0 / max(t.size, 1)))
        ax.add_collection(
            LineCollection(segs, colors="0.6", linewidths=lw, label="estimated interval (aided)")
        )
        ax.plot(t, meas, ".", color="red", ms=2.5, label="measured")
        if st.truth is not None:
            key = {"accel_x": "accel_x", "accel_y": "accel_y", "gyro_z": "r"}[ch]
            if key in st.truth:
                ax.plot(t, st.truth[key][1:] * f, "-", color="black", lw=0.6, label="truth")
        # keep the measured values readable: clip the axis to the bulk of the bars
        if fin.any():
            span = np.concatenate([lo[fin], hi[fin], meas])
            a, b = np.percentile(span, [2, 98])
            pad = 0.1 * (b - a) + 1e-9
            ax.set_ylim(a - pad, b + pad)
        ax.set_ylabel(f"{name} [{unit}]")
        ax.grid(alpha=0.3)
        ax.legend(loc="upper right", fontsize=7, ncol=3)
    axes[-1].set_xlabel("time since start [s]")
    axes[0].set_xlim(t[0] - 1, t[-1] + 1)
    fig.suptitle(title or "Estimated intervals (grey) and measured values (red)", fontsize=11)
    fig.tight_layout()
    return _save(fig, out_dir, "intervals")


def _draw_boxes(ax: Any, res: EstimatorResult, idx: np.ndarray, lw: float) -> None:
    st, S = res.steps, res.S
    g = st.gps
    cb = [Rectangle((S[i, 0], S[i, 2]), S[i, 1] - S[i, 0], S[i, 3] - S[i, 2]) for i in idx]
    ax.add_collection(
        PatchCollection(cb, facecolor="tab:orange", edgecolor="tab:red", lw=lw, alpha=0.3, zorder=1)
    )
    gi = [i for i in idx if np.isfinite(g[i, 0])]
    gb = [Rectangle((g[i, 0], g[i, 2]), g[i, 1] - g[i, 0], g[i, 3] - g[i, 2]) for i in gi]
    ax.add_collection(
        PatchCollection(gb, facecolor="none", edgecolor="tab:blue", lw=lw, alpha=0.7, zorder=2)
    )


def plot_trajectory(res: EstimatorResult, out_dir: Path, title: str = "") -> list[Path]:
    """Track in the local ENU frame with GPS boxes (blue) and contracted boxes (orange).

    Left: the whole drive (axes limited to the GPS boxes, so a wide prediction at a
    step without GPS does not hide the track); right: a zoom on 12 steps around the
    sharpest turn.
    """
    st = res.steps
    g = st.gps
    ok = np.isfinite(g[:, 0])
    # boxes of steps with a GPS fix (a step without one keeps the wide INS prediction)
    fin = np.all(np.isfinite(res.S[:, 0:4]), axis=1) & ok
    fig, axes = plt.subplots(1, 2, figsize=(13, 6.5))
    n = st.t.size
    turn = int(np.argmax(np.where(ok, np.abs(st.meas[:, 2]), -1.0))) if n > 1 else 0
    lo_i = max(0, min(turn - 6, n - 12))
    zoom = np.arange(lo_i, min(n, lo_i + 12))
    for ax, idx, lw in (
        (axes[0], np.flatnonzero(fin)[:: max(1, int(fin.sum() // 300))], 0.4),
        (axes[1], zoom[fin[zoom]], 0.8),
    ):
        _draw_boxes(ax, res, idx, lw)
        sel = idx[ok[idx]]
        ax.plot(
            st.gps_centre[sel, 0],
            st.gps_centre[sel, 1],
            ".-",
            color="tab:blue",
            lw=0.5,
            ms=2,
            label="GPS fixes; blue squares: GPS boxes",
            zorder=3,
        )
        ax.plot([], [], "s", color="tab:orange", alpha=0.5, label="contracted position boxes")
        if st.truth is not None:
            te, tn = st.truth["east"], st.truth["north"]
            ax.plot(te[idx], tn[idx], "-", color="black", lw=0.8, label="truth", zorder=4)
        if sel.size:
            x0, x1 = np.min(g[sel, 0]), np.max(g[sel, 1])
            y0, y1 = np.min(g[sel, 2]), np.max(g[sel, 3])
            pad = 0.05 * max(x1 - x0, y1 - y0)
            ax.set_xlim(x0 - pad, x1 + pad)
            ax.set_ylim(y0 - pad, y1 + pad)
        ax.set_aspect("equal", adjustable="box")
        ax.set_xlabel("east [m]")
        ax.set_ylabel("north [m]")
        ax.grid(alpha=0.3)
    axes[0].plot(st.gps_centre[0, 0], st.gps_centre[0, 1], "k^", label="start", zorder=5)
    axes[0].legend(loc="best", fontsize=8)
    axes[0].set_title("whole drive", fontsize=10)
    t0 = st.t[zoom[0]] - st.t[0]
    axes[1].set_title(
        f"zoom: steps at t = {t0:.0f}..{t0 + st.dt * (zoom.size - 1):.0f} s (sharpest turn)",
        fontsize=10,
    )
    fig.suptitle(title or "Trajectory: GPS boxes and contracted boxes", fontsize=11)
    fig.tight_layout()
    return _save(fig, out_dir, "trajectory")


def plot_comparison(summaries: dict[str, dict[str, Any]], out_dir: Path) -> list[Path]:
    """Dynamic mean error interval vs stationary 95 % level, per channel and mode."""
    fig, axes = plt.subplots(1, len(CHANNELS), figsize=(11, 4))
    modes = list(summaries)
    for ax, ch in zip(axes, CHANNELS, strict=True):
        name, unit, f = LABELS[ch]
        x = np.arange(len(modes) + 1)
        lows, highs = [], []
        for m in modes:
            lo, hi = summaries[m]["channels"][ch]["dynamic_error_mean_interval"]
            lows.append((lo or 0.0) * f)
            highs.append((hi or 0.0) * f)
        L = summaries[modes[0]]["channels"][ch]["stationary_level_95"] * f
        lows.append(-L)
        highs.append(L)
        colors = ["0.55"] * len(modes) + ["tab:green"]
        ax.bar(x, np.array(highs) - np.array(lows), bottom=lows, color=colors, width=0.6)
        ax.axhline(0, color="k", lw=0.5)
        ax.set_xticks(x, [f"dynamic\n({m})" for m in modes] + ["stationary\n95 %"], fontsize=8)
        ax.set_ylabel(f"error interval [{unit}]")
        ax.set_title(name, fontsize=9)
        if max(highs) > 20 * L > 0:
            ax.set_yscale("symlog", linthresh=L)
        ax.grid(alpha=0.3, axis="y")
    fig.suptitle("Dynamic error margins (mean interval) vs stationary 95 % level", fontsize=11)
    fig.tight_layout()
    return _save(fig, out_dir, "comparison")
