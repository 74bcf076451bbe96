"""Figures of the stationary analysis (Allan-family deviation with noise-term lines).

Gyro curves are drawn in deg/h, accelerometer curves in m/s^2 (the usual
reading units); every axis is labelled with its unit. Every function returns a
:class:`matplotlib.figure.Figure` made without pyplot, so no backend is chosen
and nothing is shown or written (the command line picks Agg and saves with
:func:`save_figure`):

* :func:`allan_figure` -- a whole :class:`~imubounds.stationary.pipeline.StaticResult`;
* :func:`channel_figure` -- one channel (``ChannelResult.plot``);
* :func:`plot_terms` -- a :class:`~imubounds.stationary.terms.Selection` with its curve;
* :func:`plot_allan` -- a bare :class:`~imubounds.stationary.allan.AllanResult`.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from matplotlib import rc_context
from matplotlib.figure import Figure
from matplotlib.ticker import AutoLocator, LogFormatter, LogLocator

from imubounds.io.outputs import write_with
from imubounds.stationary import theory
from imubounds.stationary.terms import READ_TAU
from imubounds.units import DEG, HOUR

if TYPE_CHECKING:
    from imubounds.stationary.allan import AllanResult
    from imubounds.stationary.pipeline import ChannelResult, StaticResult
    from imubounds.stationary.terms import Selection

TERM_STYLE: dict[str, tuple[str, str]] = {
    "Q": ("tab:purple", "Q (slope −1)"),
    "N": ("tab:blue", "N (slope −½)"),
    "B": ("tab:green", "B (slope 0)"),
    "K": ("tab:orange", "K (slope +½)"),
    "R": ("tab:red", "R (slope +1)"),
}
MODEL_STYLE = {"gauss_markov": ("tab:brown", "Gauss–Markov model"), "ar": ("tab:pink", "AR model")}
STAT_LABEL = {
    "overlapping": "Allan deviation",
    "non-overlapping": "Allan deviation (non-overlapping)",
    "modified": "modified Allan deviation",
    "hadamard": "Hadamard deviation",
    "non-overlapping-hadamard": "Hadamard deviation (non-overlapping)",
    "total": "total deviation",
}


_SUPERSCRIPT = str.maketrans("-0123456789", "⁻⁰¹²³⁴⁵⁶⁷⁸⁹")


class PlainLogFormatter(LogFormatter):
    """Log-axis labels as plain text, ``10⁻³`` and ``2×10⁻³``, not mathtext.

    Matplotlib's default (``$10^{-3}$``) parses every label with mathtext, a fifth of
    the time of a figure; which ticks get a label is decided as by the default.
    """

    def _num_to_string(self, x: float, vmin: float, vmax: float) -> str:
        exponent = math.floor(math.log10(x) + 1e-10)
        coeff = x / 10.0**exponent
        decade = "10" + str(exponent).translate(_SUPERSCRIPT)
        if abs(coeff - 1.0) < 1e-9:
            return decade
        return f"{coeff:.3g}×{decade}"


#: zlib level of the PNG files (1: fastest; matplotlib's default is 6).
PNG_COMPRESS_LEVEL = 1

#: A log axis spanning more decades than this gets no minor ticks (nor minor grid).
MINOR_MAX_DECADES = 4.0


def in_view(locs: Any, vmin: float, vmax: float) -> Any:
    """The tick locations of a log axis within its view ``[vmin, vmax]`` (a margin of
    1e-6 of the view in log10, wider than the 1e-10 within which matplotlib draws a
    tick): matplotlib builds, places and labels a tick for every location the
    locator returns, one decade beyond each end included, and draws only those in
    view, so the ticks dropped here are never drawn."""
    arr = np.asarray(locs, dtype=np.float64)
    lo, hi = min(vmin, vmax), max(vmin, vmax)
    if arr.size == 0 or not (lo > 0 and math.isfinite(hi)):
        return locs
    a, b = math.log10(lo), math.log10(hi)
    slack = (b - a) * 1e-6
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.log10(arr)
    keep = (t >= a - slack) & (t <= b + slack)
    return arr[keep]


class ViewLogLocator(LogLocator):
    """Matplotlib's log locator (the major ticks of a log axis) returning only the
    ticks in view (:func:`in_view`)."""

    def tick_values(self, vmin: float, vmax: float) -> Any:
        return in_view(super().tick_values(vmin, vmax), vmin, vmax)


class ViewAutoLocator(AutoLocator):
    """Matplotlib's locator of a linear axis returning only the ticks in view (a
    margin of 1e-6 of the view, wider than matplotlib's 1e-10): it returns one
    step beyond each end, built and labelled by matplotlib, never drawn."""

    def tick_values(self, vmin: float, vmax: float) -> Any:
        locs = np.asarray(super().tick_values(vmin, vmax), dtype=np.float64)
        lo, hi = min(vmin, vmax), max(vmin, vmax)
        slack = (hi - lo) * 1e-6
        return locs[(locs >= lo - slack) & (locs <= hi + slack)]


class SparseLogLocator(LogLocator):
    """Minor ticks at 2 and 5 of each decade, none on an axis spanning more than
    :data:`MINOR_MAX_DECADES` decades: there the decades carry the labels and the
    grid, and every tick is an object matplotlib builds and draws (the minor ticks
    of the τ axes were a fifth of the time of the figures)."""

    def __init__(self) -> None:
        super().__init__(subs=(2.0, 5.0))

    def tick_values(self, vmin: float, vmax: float) -> Any:
        lo, hi = min(vmin, vmax), max(vmin, vmax)
        if lo > 0 and math.log10(hi / lo) > MINOR_MAX_DECADES:
            return np.array([])
        return in_view(super().tick_values(vmin, vmax), vmin, vmax)


def log_axes(ax: Any, x: bool = True, y: bool = True) -> None:
    """Log scale on ``ax``'s x and/or y axis, labelled by :class:`PlainLogFormatter`,
    minor ticks at 2 and 5 (a third of the default's) on an axis of at most
    :data:`MINOR_MAX_DECADES` decades, labelled only where an axis spans too few
    decades to carry labels at the decades."""
    for on, axis, set_scale in ((x, ax.xaxis, ax.set_xscale), (y, ax.yaxis, ax.set_yscale)):
        if not on:
            continue
        set_scale("log")
        axis.set_major_locator(ViewLogLocator())
        axis.set_major_formatter(PlainLogFormatter())
        axis.set_minor_locator(SparseLogLocator())
        axis.set_minor_formatter(PlainLogFormatter(labelOnlyBase=False))


def display_scale(kind: str) -> tuple[float, str]:
    """Factor from SI to the plotted unit, and that unit."""
    return (1.0 / DEG * HOUR, "deg/h") if kind == "gyro" else (1.0, "m/s²")


def term_line(
    term: str,
    value: float,
    tau: np.ndarray,
    estimator: str = "overlapping",
    rate_hz: float | None = None,
    n_samples: int | None = None,
) -> np.ndarray:
    """Deviation of a single term (SI) over ``tau`` in the statistic of ``estimator``."""
    return np.asarray(
        value * np.sqrt(theory.response(term, estimator, tau, rate_hz=rate_hz, n_samples=n_samples))
    )


def _format_terms(ch: ChannelResult) -> str:
    kind = ch.kind
    js = ch.selected.to_json(kind)
    parts = []
    for t in ("N", "B", "K"):
        e = js[t]
        if e["value"] is None:
            continue
        mark = "≤ " if e["status"] == "upper_bound" else "= "
        parts.append(f"{t} {mark}{e['ieee']['value']:.3g} {e['ieee']['unit']}")
    sm = js["sigma_min"]
    f, unit = display_scale(kind)  # in the axis's unit (deg/h for gyros), not the datasheet's
    parts.append(f"σ_min = {sm['value'] * f:.3g} {unit} "
                 f"at τ = {sm['tau_s']:.3g} s")  # fmt: skip
    return "\n".join(parts)


def plot_channel(ax: Any, ch: ChannelResult, terms_from: str = "fit") -> None:
    """Draw one channel's curve with CI bars, the selected term lines (dotted where only
    an upper bound is known), the fitted sum, σ_min, and the stochastic models where
    they are valid (dash-dot where they follow the curve, thin dotted where not)."""
    kind = ch.kind
    scale, unit = display_scale(kind)
    a = ch.allan
    tau = np.asarray(a.tau)
    dev = np.asarray(a.dev) * scale
    lo = np.asarray(a.ci_lower) * scale
    hi = np.asarray(a.ci_upper) * scale
    if ch.allan_plain is not None:
        ax.plot(
            np.asarray(ch.allan_plain.tau),
            np.asarray(ch.allan_plain.dev) * scale,
            "s",
            ms=3,
            color="0.6",
            mfc="none",
            label="plain curve (before --robust)",
            zorder=2,
        )
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
        label=f"measured ({'robust ' if a.robust else ''}{a.estimator})",
        zorder=3,
    )
    est, rate, n_s = a.estimator, a.rate_hz, a.n_samples
    tt = np.logspace(np.log10(tau[0]), np.log10(tau[-1]), 200)
    ymin, ymax = np.nanmin(lo[lo > 0]) if np.any(lo > 0) else dev.min(), np.nanmax(hi)
    sel = ch.selected
    for t, (color, label) in TERM_STYLE.items():
        v = sel.terms[t].value
        if v is None or not (math.isfinite(v) and v > 0):
            continue
        bound = sel.status(t) == "upper_bound"
        if bound and t in ("Q", "R"):
            continue  # bounds of absent Q and R only clutter the figure
        ax.plot(
            tt,
            term_line(t, v, tt, est, rate, n_s) * scale,
            ":" if bound else "--",
            color=color,
            lw=0.9 if bound else 1.0,
            label=label + (" (upper bound)" if bound else ""),
        )
        if t in READ_TAU and not bound and tt[0] <= READ_TAU[t] <= tt[-1]:
            rt = np.array([READ_TAU[t]])
            ax.plot(rt, term_line(t, v, rt, est, rate, n_s) * scale, "x", color=color, ms=6)
    terms = ch.fit if terms_from == "fit" else ch.slope
    ax.plot(
        tt, terms.adev(tt) * scale, "-", color="tab:cyan", lw=1.8, label=f"terms ({terms.method})"
    )
    sm = sel.sigma_min
    ax.plot([sm["tau_s"]], [sm["value"] * scale], "*", color="tab:green", ms=10,
            label="σ_min", zorder=4)  # fmt: skip
    if ch.models is not None:
        adq = getattr(ch.models, "adequacy", {})
        for key, model in getattr(ch.models, "models", {}).items():
            color, label = MODEL_STYLE.get(key, ("tab:gray", key))
            valid = tt >= getattr(model, "valid_from_tau_s", 0.0) * (1 - 1e-9)
            if not np.any(valid):
                continue
            try:
                curve = np.sqrt(model.variance(tt[valid], a.estimator, rate_hz=a.rate_hz)) * scale
            except Exception:  # a model that cannot predict: leave it out of the plot
                continue
            fits = bool(adq.get(key, {}).get("adequate", False))
            ax.plot(
                tt[valid],
                curve,
                "-." if fits else ":",
                color=color,
                lw=1.4 if fits else 1.0,
                label=label + ("" if fits else " (does not fit)"),
            )
    log_axes(ax)
    ax.set_ylim(ymin / 3.0, ymax * 3.0)
    # at the top of the axes, where matplotlib's automatic placement puts it above
    # bottom ticks and log axes (no offset text): placing it measures every y tick
    ax.set_title(ch.name, y=1.0)
    ax.set_xlabel("averaging time τ (s)")
    ax.set_ylabel(f"{STAT_LABEL.get(a.estimator, 'Allan deviation')} ({unit})")
    ax.grid(True, which="both", alpha=0.3)
    # the terms below the axes, off the data
    ax.text(
        0.0,
        -0.2,
        _format_terms(ch),
        transform=ax.transAxes,
        fontsize=7,
        va="top",
        bbox={"boxstyle": "round", "fc": "white", "alpha": 0.8, "lw": 0.5},
    )


def allan_figure(result: StaticResult) -> Figure:
    """One panel per channel: gyros on the first row, accelerometers on the second."""
    names = list(result.channels)
    gyros = [n for n in names if n.startswith("gyro")]
    accels = [n for n in names if n.startswith("accel")]
    rows = [r for r in (gyros, accels) if r]
    ncols = max(len(r) for r in rows)
    fig = Figure(figsize=(4.6 * ncols, 4.9 * len(rows)))
    axes = fig.subplots(len(rows), ncols, squeeze=False)
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
        f"{STAT_LABEL.get(est, 'Allan deviation')} — {Path(result.log.source).name}, "
        f"{result.log.rate_hz:g} Hz, "
        f"{result.log.duration_s / 3600:.2f} h ({est}, {conf:.1%} CI)"
    )
    # fixed margins (inches) instead of tight_layout: laying out measures every tick
    # label, which took a third of the time of the figure
    width, height = fig.get_size_inches()
    legend_rows = math.ceil(len(labels) / min(max(len(labels), 1), 5))
    fig.subplots_adjust(
        left=0.8 / width,
        right=1.0 - 0.15 / width,
        bottom=(1.45 + 0.2 * legend_rows) / height,
        top=1.0 - 0.6 / height,
        wspace=0.3,
        hspace=0.75,
    )
    return fig


def _new_axes(ax: Any, size: tuple[float, float] = (5.5, 4.4)) -> tuple[Figure, Any]:
    if ax is not None:
        return ax.figure, ax
    fig = Figure(figsize=size)
    return fig, fig.add_subplot(1, 1, 1)


def channel_figure(ch: ChannelResult, ax: Any = None, terms_from: str = "fit") -> Figure:
    """One channel drawn by :func:`plot_channel` on ``ax`` or on a new Figure."""
    fig, a = _new_axes(ax, (5.5, 6.2))
    plot_channel(a, ch, terms_from)
    a.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.02, 1.0), frameon=False)
    if ax is None:
        fig.tight_layout()
    return fig


def plot_terms(sel: Selection, ax: Any = None, name: str = "") -> Figure:
    """A :class:`~imubounds.stationary.terms.Selection` over its curve, drawn like a
    channel of ``imubounds static`` (no models); ``sel.kind`` and ``sel.curve`` are
    required."""
    from types import SimpleNamespace

    kind = sel.kind or "gyro"
    view = SimpleNamespace(
        kind=kind,
        name=name or f"{kind} ({sel.estimator})",
        allan=sel.curve,
        allan_plain=None,
        selected=sel,
        fit=sel.fit,
        slope=sel.slope,
        models=None,
    )
    return channel_figure(view, ax=ax)  # type: ignore[arg-type]


def plot_allan(curve: AllanResult, ax: Any = None, label: str | None = None) -> Figure:
    """A bare Allan-family curve with its confidence bars, in the unit of its input
    (``curve.unit``), log-log, on ``ax`` or on a new Figure."""
    fig, a = _new_axes(ax)
    tau = np.asarray(curve.tau)
    dev = np.asarray(curve.dev)
    lo, hi = np.asarray(curve.ci_lower), np.asarray(curve.ci_upper)
    a.errorbar(
        tau,
        dev,
        yerr=[np.clip(dev - lo, 0, None), np.clip(hi - dev, 0, None)],
        fmt="o-",
        ms=3,
        lw=1.0,
        capsize=2,
        label=label
        or f"{'robust ' if curve.robust else ''}{curve.estimator} ({curve.confidence:.1%} CI)",
    )
    log_axes(a)
    a.set_xlabel("averaging time τ (s)")
    a.set_ylabel(
        f"{STAT_LABEL.get(curve.estimator, 'Allan deviation')} ({curve.unit or 'input unit'})"
    )
    a.grid(True, which="both", alpha=0.3)
    a.legend(fontsize=8)
    if ax is None:
        fig.tight_layout()
    return fig


def save_figure(
    fig: Figure, dest_stem: Path, formats: tuple[str, ...] = ("png", "svg")
) -> list[Path]:
    """Save ``fig`` as ``dest_stem.png`` / ``.svg`` atomically.

    The layout (constrained or tight) is computed for the first format and kept for
    the others: computing it again measures every tick label anew, about a
    quarter of the time of each further save. The figure's layout engine is
    restored afterwards.
    """
    out = []
    engine = fig.get_layout_engine()
    try:
        for k, fmt in enumerate(formats):
            dest = dest_stem.with_suffix(f".{fmt}")

            def save(p: Path, fmt: str = fmt) -> None:
                # SVG text as text (not one path per glyph): a third faster, smaller;
                # PNG with zlib's fastest level: the same pixels, 5-15 % larger,
                # a fifth of the time of a save
                kw: dict[str, Any] = (
                    {"pil_kwargs": {"compress_level": PNG_COMPRESS_LEVEL}} if fmt == "png" else {}
                )
                with rc_context({"svg.fonttype": "none"}):
                    fig.savefig(p, format=fmt, dpi=130, **kw)

            out.append(write_with(dest, save))
            if k == 0 and engine is not None:
                fig.set_layout_engine("none")  # positions as laid out for the first save
    finally:
        if engine is not None and fig.get_layout_engine() is not engine:
            try:
                fig.set_layout_engine(engine)
            except RuntimeError:  # an engine that cannot come back (colorbars): keep the positions
                pass
    return out


def needs_stationarity_figure(result: StaticResult) -> bool:
    """Whether any channel has a warm-up or fails the stationarity test."""
    return any(
        ch.stationarity is not None
        and (ch.stationarity.warmup is not None or not ch.stationarity.stationary)
        for ch in result.channels.values()
    )


def stationarity_figure(result: StaticResult) -> Figure:
    """Per channel: the block means with the fitted warm-up (top) and the Allan
    deviation of each window at three τ with its CI against time (bottom)."""
    names = [n for n, ch in result.channels.items() if ch.stationarity is not None]
    fig = Figure(figsize=(3.4 * max(len(names), 1), 7.6))
    axes = fig.subplots(2, max(len(names), 1), squeeze=False)
    for j, name in enumerate(names):
        ch = result.channels[name]
        st = ch.stationarity
        assert st is not None
        scale, unit = display_scale(ch.kind)
        top, bottom = axes[0][j], axes[1][j]
        top.plot(st.block_t / 60.0, st.block_mean * scale, ",", color="0.3")
        w = st.warmup
        if w is not None:
            top.axvspan(w.start_s / 60.0, w.end_s / 60.0, color="tab:orange", alpha=0.2,
                        label=f"warm-up to {w.end_s / 60:.3g} min")  # fmt: skip
            top.legend(fontsize=7, loc="upper left", bbox_to_anchor=(0.0, -0.18),
                       frameon=False)
        top.xaxis.set_major_locator(ViewAutoLocator())
        top.yaxis.set_major_locator(ViewAutoLocator())
        bottom.xaxis.set_major_locator(ViewAutoLocator())
        top.set_title(f"{name}" + ("" if st.stationary else " (not stationary)"))
        top.set_xlabel("time (min)")
        top.set_ylabel(f"block mean ({unit})")
        mid = (st.window_start_s + st.window_s / 2.0) / 60.0
        picks = sorted({0, st.tau_s.size // 2, st.tau_s.size - 1})
        for k in picks:
            dev = st.adev[:, k] * scale
            lo = np.clip(dev - st.ci_lower[:, k] * scale, 0, None)
            hi = np.clip(st.ci_upper[:, k] * scale - dev, 0, None)
            bottom.errorbar(mid, dev, yerr=[lo, hi], fmt="o-", ms=3, capsize=2,
                            label=f"τ = {st.tau_s[k]:.3g} s")  # fmt: skip
        log_axes(bottom, x=False)
        bottom.set_xlabel("window centre (min)")
        bottom.set_ylabel(f"Allan deviation ({unit})")
        bottom.legend(fontsize=7, loc="upper left", bbox_to_anchor=(0.0, -0.2), ncol=1,
                      frameon=False)
        bottom.grid(True, which="major", alpha=0.3)
    first = result.channels[names[0]].stationarity if names else None
    win = f" (windows of {first.window_s / 60:.3g} min)" if first is not None else ""
    fig.suptitle(f"Stationarity — {Path(result.log.source).name}{win}")
    fig.subplots_adjust(left=0.07, right=0.98, bottom=0.17, top=0.9, wspace=0.35, hspace=0.75)
    return fig
