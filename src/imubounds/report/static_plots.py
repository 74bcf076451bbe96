"""Figures of the stationary analysis (Allan deviation with noise-term lines).

Gyro curves are drawn in deg/h, accelerometer curves in m/s^2 (the usual
reading units); every axis is labelled with its unit. Figures are made
without choosing a backend (the command line picks Agg).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING, Any

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure

from imubounds.io.outputs import write_with
from imubounds.stationary.terms import B_FACTOR, READ_TAU, NoiseTerms
from imubounds.units import DEG, HOUR, to_ieee

if TYPE_CHECKING:
    from imubounds.stationary.pipeline import ChannelResult, StaticResult

TERM_STYLE: dict[str, tuple[str, str]] = {
    "Q": ("tab:purple", "Q (slope −1)"),
    "N": ("tab:blue", "N (slope −½)"),
    "B": ("tab:green", "B (slope 0)"),
    "K": ("tab:orange", "K (slope +½)"),
    "R": ("tab:red", "R (slope +1)"),
}
MODEL_STYLE = {"gauss_markov": ("tab:brown", "Gauss–Markov model"), "ar": ("tab:pink", "AR model")}


def display_scale(kind: str) -> tuple[float, str]:
    """Factor from SI to the plotted unit, and that unit."""
    return (1.0 / DEG * HOUR, "deg/h") if kind == "gyro" else (1.0, "m/s²")


def term_line(term: str, value: float, tau: np.ndarray) -> np.ndarray:
    """Allan deviation of a single term (SI) over ``tau``."""
    if term == "Q":
        return math.sqrt(3.0) * value / tau
    if term == "N":
        return value / np.sqrt(tau)
    if term == "B":
        return np.full_like(tau, B_FACTOR * value)
    if term == "K":
        return value * np.sqrt(tau / 3.0)
    return value * tau / math.sqrt(2.0)


def _format_terms(terms: NoiseTerms, kind: str) -> str:
    parts = []
    for t in ("Q", "N", "B", "K", "R"):
        v = terms.value(t)  # type: ignore[arg-type]
        if math.isfinite(v) and v > 0:
            iv, unit = to_ieee(kind, t, v)  # type: ignore[arg-type]
            parts.append(f"{t} = {iv:.3g} {unit}")
    return "\n".join(parts) if parts else "no term resolved"


def plot_channel(ax: Any, ch: ChannelResult, terms_from: str = "fit") -> None:
    """Draw one channel's Allan deviation, CI bars, term lines and model curves."""
    kind = ch.kind
    scale, unit = display_scale(kind)
    a = ch.allan
    tau = np.asarray(a.tau)
    dev = np.asarray(a.dev) * scale
    lo = np.asarray(a.ci_lower) * scale
    hi = np.asarray(a.ci_upper) * scale
    ax.errorbar(
        tau,
        dev,
        yerr=[np.clip(dev - lo, 0, None), np.clip(hi - dev, 0, None)],
        fmt="o",
        ms=3,
        color="black",
        ecolor="0.55",
        elinewidth=1,
        capsize=2,
        label=f"measured ({a.estimator})",
        zorder=3,
    )
    terms = ch.fit if terms_from == "fit" else ch.slope
    tt = np.logspace(np.log10(tau[0]), np.log10(tau[-1]), 200)
    ymin, ymax = np.nanmin(lo[lo > 0]) if np.any(lo > 0) else dev.min(), np.nanmax(hi)
    for t, (color, label) in TERM_STYLE.items():
        v = terms.value(t)  # type: ignore[arg-type]
        if not (math.isfinite(v) and v > 0):
            continue
        ax.plot(tt, term_line(t, v, tt) * scale, "--", color=color, lw=1, label=label)
        if t in READ_TAU:
            ax.plot(
                [READ_TAU[t]],
                [term_line(t, v, np.array([READ_TAU[t]]))[0] * scale],
                "x",
                color=color,
                ms=6,
            )
    ax.plot(
        tt, terms.adev(tt) * scale, "-", color="tab:cyan", lw=1.8, label=f"terms ({terms.method})"
    )
    if ch.models is not None:
        for key, model in getattr(ch.models, "models", {}).items():
            color, label = MODEL_STYLE.get(key, ("tab:gray", key))
            try:
                curve = np.asarray(model.adev(tt)) * scale
            except Exception:  # a model that cannot predict: leave it out of the plot
                continue
            ax.plot(tt, curve, "-.", color=color, lw=1.4, label=label)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_ylim(ymin / 3.0, ymax * 3.0)
    ax.set_title(ch.name)
    ax.set_xlabel("averaging time τ (s)")
    ax.set_ylabel(f"Allan deviation ({unit})")
    ax.grid(True, which="both", alpha=0.3)
    ax.text(
        0.03,
        0.03,
        _format_terms(terms, kind),
        transform=ax.transAxes,
        fontsize=7,
        va="bottom",
        bbox={"boxstyle": "round", "fc": "white", "alpha": 0.8, "lw": 0.5},
    )


def allan_figure(result: StaticResult) -> Figure:
    """One panel per channel: gyros on the first row, accelerometers on the second."""
    names = list(result.channels)
    gyros = [n for n in names if n.startswith("gyro")]
    accels = [n for n in names if n.startswith("accel")]
    rows = [r for r in (gyros, accels) if r]
    ncols = max(len(r) for r in rows)
    fig, axes = plt.subplots(
        len(rows), ncols, figsize=(4.6 * ncols, 4.0 * len(rows)), squeeze=False
    )
    for i, row in enumerate(rows):
        for j in range(ncols):
            ax = axes[i][j]
            if j < len(row):
                plot_channel(ax, result.channels[row[j]], result.settings.terms_from)
            else:
                ax.set_visible(False)
    handles, labels = [], []
    for ax in axes.flat:
        if not ax.get_visible():
            continue
        for h, lab in zip(*ax.get_legend_handles_labels(), strict=True):
            if lab not in labels:
                handles.append(h)
                labels.append(lab)
    fig.legend(handles, labels, loc="lower center", ncol=min(len(labels), 5), fontsize=8)
    est = result.settings.estimator
    conf = result.settings.confidence
    fig.suptitle(
        f"Allan deviation — {Path(result.log.source).name}, {result.log.rate_hz:g} Hz, "
        f"{result.log.duration_s / 3600:.2f} h ({est}, {conf:.1%} CI)"
    )
    fig.tight_layout(rect=(0, 0.07, 1, 0.96))
    return fig


def save_figure(
    fig: Figure, dest_stem: Path, formats: tuple[str, ...] = ("png", "svg")
) -> list[Path]:
    """Save ``fig`` as ``dest_stem.png`` / ``.svg`` atomically and close it."""
    out = []
    for fmt in formats:
        dest = dest_stem.with_suffix(f".{fmt}")
        out.append(write_with(dest, lambda p, fmt=fmt: fig.savefig(p, format=fmt, dpi=130)))
    plt.close(fig)
    return out
