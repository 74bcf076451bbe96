"""Figures of a fleet run (:mod:`imubounds.stationary.fleet`): the Allan-curve bundles
with term histograms (:func:`fleet_figure`) and the terms across units
(:func:`fleet_stats_figure`); :func:`save_fleet_figures` writes both as PNG and SVG."""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from imubounds.stationary.fleet_stats import DEFAULT_OUTLIER_Z, STAT_TERMS
from imubounds.units import G0

if TYPE_CHECKING:
    from imubounds.stationary.fleet.result import FleetResult

__all__ = ["fleet_figure", "fleet_stats_figure", "save_fleet_figures"]


def _median_curve(curves: list[tuple[np.ndarray, np.ndarray]]) -> tuple[np.ndarray, np.ndarray]:
    """Pointwise median in log-log on a common tau grid (where >= half the curves exist)."""
    lo = min(float(t[0]) for t, _ in curves)
    hi = max(float(t[-1]) for t, _ in curves)
    grid = np.logspace(math.log10(lo), math.log10(hi), 60)
    vals = np.full((len(curves), grid.size), np.nan)
    for i, (t, d) in enumerate(curves):
        ok = (grid >= t[0] * (1 - 1e-9)) & (grid <= t[-1] * (1 + 1e-9)) & np.all(d > 0)
        vals[i, ok] = np.interp(np.log(grid[ok]), np.log(t), np.log(d))
    count = np.sum(np.isfinite(vals), axis=0)
    keep = count >= max(1, len(curves) // 2)
    med = np.full(grid.size, np.nan)
    med[keep] = np.exp(np.nanmedian(vals[:, keep], axis=0))
    return grid[keep], med[keep]


def fleet_figure(result: FleetResult) -> Any:
    """Fleet plot: Allan-curve bundles with the median, and term distributions.

    Top row: every unit's Allan deviation of every gyro (left) and accelerometer
    (right) axis as faint lines, the pointwise median bold. Lower rows:
    histograms of N, B, K (the ``terms_from`` estimate) per sensor kind, in
    IEEE units, with the spec limit as a dashed red line when given.
    """
    import matplotlib.pyplot as plt

    from imubounds.units import DEG, to_ieee

    t = result.table
    ok = t[t["status"] == "ok"]
    kinds = [k for k in ("gyro", "accel") if (ok["kind"] == k).any()]
    fig = plt.figure(figsize=(13, 4.2 + 3.0 * len(kinds)), layout="constrained")
    gs = fig.add_gridspec(1 + len(kinds), 6)
    ylab = {"gyro": "Allan deviation [deg/h]", "accel": "Allan deviation [mg]"}
    scale = {"gyro": 3600.0 / DEG, "accel": 1.0 / (G0 * 1e-3)}
    n_units = len(result.curves)
    for col, kind in enumerate(("gyro", "accel")):
        ax = fig.add_subplot(gs[0, 3 * col : 3 * col + 3])
        bundle = []
        for unit_curves in result.curves.values():
            for ch, c in unit_curves.items():
                if not ch.startswith(kind):
                    continue
                tau = np.asarray(c["tau"])
                dev = np.asarray(c["adev"]) * scale[kind]
                bundle.append((tau, dev))
                ax.loglog(tau, dev, color="0.35", alpha=0.12, lw=0.8, rasterized=True)
        if bundle:
            g, med = _median_curve(bundle)
            ax.loglog(g, med, color="C3" if kind == "gyro" else "C0", lw=2.4,
                      label=f"median of {len(bundle)} axes")  # fmt: skip
            ax.legend(loc="upper right", fontsize=8)
        else:
            ax.text(0.5, 0.5, f"no {kind} channel", ha="center", transform=ax.transAxes)
        ax.set_xlabel("averaging time τ [s]")
        ax.set_ylabel(ylab[kind])
        ax.set_title(f"{kind}: {n_units} units, every axis (faint) and the median")
        ax.grid(True, which="both", alpha=0.3)
    for row, kind in enumerate(kinds, start=1):
        sub = ok[ok["kind"] == kind]
        for j, term in enumerate(("N", "B", "K")):
            ax = fig.add_subplot(gs[row, 2 * j : 2 * j + 2])
            conv, unit = to_ieee(kind, term, 1.0)  # type: ignore[arg-type]
            v = sub[term].to_numpy(dtype=np.float64) * conv
            v = v[np.isfinite(v)]
            if v.size:
                ax.hist(v, bins=min(30, max(5, v.size // 2)), color="C0" if kind == "accel"
                        else "C3", alpha=0.75, edgecolor="white")  # fmt: skip
                ax.axvline(float(np.median(v)), color="k", lw=1.2, label="median")
            if result.spec is not None and term in result.spec.limits.get(kind, {}):
                lim = result.spec.limits[kind][term] * conv
                ax.axvline(lim, color="red", ls="--", lw=1.5, label="spec limit")
            ax.set_xlabel(f"{kind} {term} [{unit}]")
            ax.set_ylabel("axes (units × channels)")
            ax.set_title(f"{kind} {term} ({result.settings.terms_from})")
            if v.size or result.spec is not None:
                ax.legend(fontsize=8)
    nf = len(result.failed)
    fig.suptitle(
        f"Fleet of {n_units + nf} units: {n_units} analysed, {nf} failed "
        f"({result.settings.estimator} Allan deviation)"
    )
    return fig


def fleet_stats_figure(result: FleetResult) -> Any:
    """Box plots of N, B, K across units, one box per channel, in IEEE units (log scale).

    One row per sensor kind, one column per term. Each unit is a dot; units
    flagged as outliers (``|z|`` above the threshold) are red and labelled;
    the spec limit is a dashed red line when given.
    """
    import matplotlib.pyplot as plt

    from imubounds.units import to_ieee

    t = result.table
    ok = t[t["status"] == "ok"]
    kinds = [k for k in ("gyro", "accel") if (ok["kind"] == k).any()] or ["gyro"]
    fig, axes = plt.subplots(len(kinds), len(STAT_TERMS), figsize=(13, 3.6 * len(kinds)),
                             layout="constrained", squeeze=False)  # fmt: skip
    rng = np.random.default_rng(0)
    thr = result.stats.threshold if result.stats is not None else DEFAULT_OUTLIER_Z
    for r, kind in enumerate(kinds):
        sub = ok[ok["kind"] == kind]
        chans = list(dict.fromkeys(sub["channel"]))
        for c, term in enumerate(STAT_TERMS):
            ax = axes[r, c]
            conv, unit = to_ieee(kind, term, 1.0)  # type: ignore[arg-type]
            data, pos = [], []
            for j, ch in enumerate(chans):
                g = sub[sub["channel"] == ch]
                v = g[term].to_numpy(dtype=np.float64) * conv
                good = np.isfinite(v) & (v > 0)
                if not good.any():
                    continue
                data.append(v[good])
                pos.append(j)
                flag = g.get(f"{term}_outlier", False)
                flag = np.asarray(flag, dtype=bool)[good] if np.ndim(flag) else np.zeros(
                    good.sum(), dtype=bool)  # fmt: skip
                x = j + rng.uniform(-0.15, 0.15, v[good].size)
                ax.scatter(x[~flag], v[good][~flag], s=10, color="0.3", zorder=3)
                if flag.any():
                    ax.scatter(x[flag], v[good][flag], s=28, color="red", zorder=4,
                               label=f"outlier (|z| > {thr:g})")  # fmt: skip
                    names = g["unit"].to_numpy()[good][flag]
                    for xi, yi, u in zip(x[flag], v[good][flag], names, strict=True):
                        ax.annotate(str(u), (xi, yi), fontsize=7, color="red",
                                    xytext=(4, 2), textcoords="offset points")  # fmt: skip
            if data:
                ax.boxplot(data, positions=pos, widths=0.5, showfliers=False)
                ax.set_yscale("log")
            else:
                ax.text(0.5, 0.5, f"no {kind} {term} value", ha="center",
                        transform=ax.transAxes)  # fmt: skip
            ax.set_xticks(range(len(chans)), chans, fontsize=8)
            if result.spec is not None and term in result.spec.limits.get(kind, {}):
                ax.axhline(result.spec.limits[kind][term] * conv, color="red", ls="--", lw=1.2,
                           label="spec limit")  # fmt: skip
            ax.set_ylabel(f"{kind} {term} [{unit}]")
            ax.set_title(f"{kind} {term} across units ({result.settings.terms_from})")
            ax.grid(True, which="both", axis="y", alpha=0.3)
            handles, labels = ax.get_legend_handles_labels()
            if handles:
                uniq = dict(zip(labels, handles, strict=True))
                ax.legend(uniq.values(), uniq.keys(), fontsize=7)
    n_out = len(set(result.stats.outliers["unit"])) if result.stats is not None else 0
    fig.suptitle(f"Noise terms across {len(set(ok['unit']))} units: box = quartiles, "
                 f"whiskers 1.5 IQR; {n_out} unit(s) flagged")  # fmt: skip
    return fig


def save_fleet_figures(result: FleetResult, out: Path) -> dict[str, str]:
    """Write ``fleet.png``/``.svg`` and ``fleet_stats.png``/``.svg`` into ``out``; returns
    the files written by role (``plot``, ``plot_svg``, ``stats_plot``, ``stats_plot_svg``)."""
    from imubounds.report.static_plots import save_figure

    save_figure(fleet_figure(result), out / "fleet")
    save_figure(fleet_stats_figure(result), out / "fleet_stats")
    return {"plot": "fleet.png", "plot_svg": "fleet.svg", "stats_plot": "fleet_stats.png",
            "stats_plot_svg": "fleet_stats.svg"}  # fmt: skip
