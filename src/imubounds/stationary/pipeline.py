"""The stationary pipeline: spikes -> Allan curves -> noise terms -> models -> bounds.

:func:`analyse_static` takes an :class:`~imubounds.io.log.ImuLog` (SI units) and
returns a :class:`StaticResult`, whose :meth:`~StaticResult.to_json` is the
content of ``noise.json`` and whose :meth:`~StaticResult.kalibr_yaml` is
``imu.yaml``. Nothing here prints or writes files; see
:mod:`imubounds.cli.static` for that.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any, Literal

import numpy as np

from imubounds.errors import AnalysisError, InputError, OptionError
from imubounds.io.log import ImuLog
from imubounds.stationary import bounds
from imubounds.stationary.allan import AllanResult, allan_channels
from imubounds.stationary.allan_grammar import DEFAULT_TAU_POINTS, parse_tau_spec
from imubounds.stationary.contamination import DEFAULT_THRESHOLD, SpikeReport, detect_spikes
from imubounds.stationary.record_length import channel_record_length
from imubounds.stationary.record_length import describe as describe_record_length
from imubounds.stationary.stationarity import Stationarity, stationarity, warmup_cuts
from imubounds.stationary.terms import NoiseTerms, Selection, analyse_curve
from imubounds.stationary.timing import stamp_stats, timing_check, timing_messages
from imubounds.stationary.white_level import WhiteLevel, white_level
from imubounds.units import DEG, SI_UNITS, SQRT_HOUR, SensorKind, sensor_kind, si_unit_of_signal
from imubounds.version import __version__

FORMAT = "imubounds.stationary.terms/1"
#: Fewest samples a channel is characterised from (an Allan curve of five octaves and
#: eight stationarity windows of eight samples); fewer: refused, naming file and channel.
MIN_SAMPLES = 64
TermSource = Literal["fit", "slope"]
Progress = Callable[[str, int, int], None]


@dataclass(frozen=True)
class StaticSettings:
    """Settings of a stationary analysis.

    ``taus`` is a grid spec understood by :func:`imubounds.stationary.allan.tau_grid`
    ("octave", "decade", "all", an int for N log-spaced points, or τ values in s; default
    40 log-spaced points, :data:`~imubounds.stationary.allan_grammar.DEFAULT_TAU_GRID`).
    ``averaging_time_s`` is the t of σ_c (the log length when ``None``);
    ``run_hours`` is the T of the random-walk growth (the log length when ``None``).
    ``terms_from`` selects which estimate (fit or slope read-off) is preferred
    for the selected terms that feed σ_c, the random-walk growth and imu.yaml.
    ``robust`` computes the outlier-resistant Allan curve (and keeps the plain
    one for comparison); ``spike_threshold`` is the robust z of the spike
    detector; ``ar_max_order`` the largest AR order tried.
    """

    taus: str | int | Sequence[float] = DEFAULT_TAU_POINTS
    estimator: str = "overlapping"
    confidence: float = 0.683
    k_sigma: float = bounds.DEFAULT_K
    averaging_time_s: float | None = None
    run_hours: float | None = None
    terms_from: TermSource = "fit"
    models: tuple[str, ...] = ()
    robust: bool = False
    spike_threshold: float = DEFAULT_THRESHOLD
    ar_max_order: int = 20
    cut_warmup: bool = False

    def __post_init__(self) -> None:
        # one spelling per grid: "points:40" and 40 are the same settings (and noise.json)
        if isinstance(self.taus, str):
            object.__setattr__(self, "taus", parse_tau_spec(self.taus))

    def to_json(self) -> dict[str, Any]:
        taus = self.taus if isinstance(self.taus, str | int) else [float(t) for t in self.taus]
        return {
            "taus": taus,
            "estimator": self.estimator,
            "confidence": self.confidence,
            "k_sigma": self.k_sigma,
            "averaging_time_s": self.averaging_time_s,
            "run_hours": self.run_hours,
            "terms_from": self.terms_from,
            "models": list(self.models),
            "robust": self.robust,
            "spike_threshold": self.spike_threshold,
            "ar_max_order": self.ar_max_order,
            "cut_warmup": self.cut_warmup,
        }


@dataclass
class ChannelResult:
    """Everything computed for one channel.

    ``allan`` is the curve the terms come from (the robust one with
    ``--robust``; ``allan_plain`` is then the plain curve). ``selected`` holds
    the terms used downstream; ``terms_used`` their N and B (SI).
    ``level_95`` is the paper's 95 % random-walk growth ``1.96·N·√T``, in rad
    (gyro) or m/s (accelerometer): the integrated quantity, not a rate.
    ``warnings`` are counted warnings for the user, ``notes`` remarks.
    ``start_s`` and ``n_samples``: the part of the log analysed (``--cut-warmup`` cuts
    each channel at its own warm-up).
    """

    name: str
    allan: AllanResult
    slope: NoiseTerms
    fit: NoiseTerms
    selected: Selection
    sigma_c: float
    bound: float
    level_95: float
    run_hours: float
    averaging_time_s: float
    terms_used: dict[str, float]
    k_sigma: float = bounds.DEFAULT_K
    notes: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    models: Any = None
    allan_plain: AllanResult | None = None
    spikes: SpikeReport | None = None
    record_length: dict[str, Any] | None = None
    stationarity: Stationarity | None = None
    timing: dict[str, Any] | None = None
    white_level: WhiteLevel | None = None
    start_s: float = 0.0
    n_samples: int | None = None

    @property
    def kind(self) -> SensorKind:
        """``"gyro"`` or ``"accel"``."""
        return sensor_kind(self.name)

    def __repr__(self) -> str:
        unit = si_unit_of_signal(self.kind)
        return (
            f"ChannelResult(name={self.name!r}, unit={unit!r}, N={self.terms_used['N']:.3g}, "
            f"B={self.terms_used['B']:.3g}, sigma_c={self.sigma_c:.3g}, "
            f"bound={self.bound:.3g} (k={self.k_sigma:g}), warnings={len(self.warnings)})"
        )

    def to_json(self, k_sigma: float | None = None) -> dict[str, Any]:
        kind = self.kind
        unit = si_unit_of_signal(kind)
        k = self.k_sigma if k_sigma is None else k_sigma
        sel = self.selected
        status = {t: sel.status(t) for t in ("N", "B")}
        rw_unit, rw_ds_unit, rw_factor = (
            ("rad", "deg", 1.0 / DEG) if kind == "gyro" else ("m/s", "m/s", 1.0)
        )
        n = self.n_samples if self.n_samples is not None else int(self.allan.n_samples)
        out: dict[str, Any] = {
            "unit": unit,
            "analysed": {
                "start_s": self.start_s,
                "n_samples": n,
                "duration_s": n / self.allan.rate_hz,
            },
            "allan": allan_json(self.allan),
        }
        if self.allan_plain is not None:
            out["allan_plain"] = allan_json(self.allan_plain)
        out["noise"] = {
            "slope": self.slope.to_json(kind),
            "fit": self.fit.to_json(kind),
            "selected": sel.to_json(kind),
        }
        if self.white_level is not None:
            out["noise"]["white_level"] = self.white_level.to_dict()
        out["spikes"] = (
            self.spikes.to_dict()
            if self.spikes is not None
            else {"checked": False, "reason": "no samples in memory (out-of-core path)"}
        )
        out["sigma_c"] = self.sigma_c
        out["bound"] = {
            "value": self.bound,
            "unit": unit,
            "k": k,
            "sigma_c": self.sigma_c,
            "formula": "bound = k * sigma_c, sigma_c = N/sqrt(dt) + sqrt(dt/t)*B (per sample)",
            "terms_status": status,
        }
        out["stationary"] = {
            "unit": unit,
            "k_sigma": k,
            "sigma_c": self.sigma_c,
            "bound_half_width": self.bound,
            "N": self.terms_used["N"],
            "B": self.terms_used["B"],
            "N_status": status["N"],
            "B_status": status["B"],
            "averaging_time_s": self.averaging_time_s,
            "formula": "sigma_c = N/sqrt(dt) + sqrt(dt/t)*B; bound = k*sigma_c",
        }
        out["random_walk_95"] = {
            "value": self.level_95,
            "unit": rw_unit,
            "datasheet": {"value": self.level_95 * rw_factor, "unit": rw_ds_unit},
            "T_hours": self.run_hours,
            "z": bounds.Z95,
            "rw_per_sqrt_h": self.terms_used["N"] * SQRT_HOUR,
            "rw_per_sqrt_h_unit": f"{rw_unit}/h^0.5",
            "formula": "1.96 * N[per sqrt(h)] * sqrt(T[h]): the 95 % growth of the integrated "
            f"error ({'angle' if kind == 'gyro' else 'velocity'}) over the run "
            "(paper, section IV)",
        }
        if self.models is not None:
            out["models"] = self.models.to_dict()
        if self.record_length is not None:
            out["record_length"] = self.record_length
        if self.stationarity is not None:
            out["stationarity"] = self.stationarity.to_dict()
        if self.timing is not None:
            out["timing"] = self.timing
        if self.warnings:
            out["warnings"] = list(self.warnings)
        if self.notes:
            out["notes"] = list(self.notes)
        return out

    def to_dict(self) -> dict[str, Any]:
        """``channels.<name>`` of noise.json as plain JSON types (nan -> None)."""
        from imubounds.io.outputs import to_jsonable

        out: dict[str, Any] = to_jsonable(self.to_json())
        return out

    def to_frame(self) -> Any:
        """The selected terms of this channel, one row per term (see
        :meth:`imubounds.stationary.terms.Selection.to_frame`), with a ``channel`` column."""
        df = self.selected.to_frame()
        df.insert(0, "channel", self.name)
        return df

    def plot(self, ax: Any = None) -> Any:
        """This channel's curve with CI bars, the selected term lines, the fitted sum,
        σ_min and the valid models (gyro in deg/h, accelerometer in m/s²).
        Returns the :class:`matplotlib.figure.Figure` (a new one unless ``ax`` is given)."""
        from imubounds.report.static_plots import channel_figure

        return channel_figure(self, ax=ax)


@dataclass
class StaticResult:
    """The result of :func:`analyse_static` (and :func:`imubounds.characterize`).

    ``channels`` maps each analysed channel to its :class:`ChannelResult`;
    :meth:`to_dict` is the content of ``noise.json``, :meth:`to_frame` the selected
    terms of every channel, :meth:`plot` the Allan figure of ``imubounds static``.
    """

    log: ImuLog
    settings: StaticSettings
    channels: dict[str, ChannelResult]
    notes: list[str] = field(default_factory=list)

    def __repr__(self) -> str:
        return (
            f"StaticResult(source={self.log.source!r}, channels={list(self.channels)}, "
            f"rate_hz={self.log.rate_hz:g}, duration_s={self.log.duration_s:g}, "
            f"estimator={self.settings.estimator!r})"
        )

    def to_dict(self) -> dict[str, Any]:
        """The content of ``noise.json`` as plain JSON types (nan -> None)."""
        from imubounds.io.outputs import to_jsonable

        out: dict[str, Any] = to_jsonable(self.to_json())
        return out

    def to_frame(self) -> Any:
        """The selected terms of every channel: one row per channel and term, columns
        ``channel``, ``term``, ``value`` (SI), ``unit``, ``status``, ``source``,
        ``ci_lower``, ``ci_upper``, ``tau_s``, ``ieee_value``, ``ieee_unit``,
        ``datasheet_value``, ``datasheet_unit`` (a :class:`pandas.DataFrame`)."""
        import pandas as pd

        return pd.concat([ch.to_frame() for ch in self.channels.values()], ignore_index=True)

    def plot(self, ax: Any = None, channel: str | None = None) -> Any:
        """The Allan figure: one panel per channel (gyros above accelerometers).

        Parameters
        ----------
        ax : matplotlib.axes.Axes, optional
            Draw one channel there (``channel``, or the only one analysed).
        channel : str, optional
            The channel to draw (default: all in a new figure, or the only one).

        Returns
        -------
        matplotlib.figure.Figure
            A new figure (no pyplot, the backend is left alone) or that of ``ax``.
        """
        if ax is None and channel is None:
            from imubounds.report.static_plots import allan_figure

            return allan_figure(self)
        if channel is None:
            if len(self.channels) != 1:
                raise OptionError(
                    "one Axes holds one channel: give channel= (one of "
                    f"{', '.join(self.channels)})"
                )
            channel = next(iter(self.channels))
        if channel not in self.channels:
            raise OptionError(
                f"no channel {channel!r} in this result; available: {', '.join(self.channels)}"
            )
        return self.channels[channel].plot(ax=ax)

    def to_json(self) -> dict[str, Any]:
        return {
            "format": FORMAT,
            "imubounds_version": __version__,
            "input": {
                "path": self.log.source,
                "sample_rate_hz": self.log.rate_hz,
                "duration_s": self.log.duration_s,
                "n_samples": self.log.n_samples,
                "input_units": dict(self.log.input_units),
                "frame": self.log.frame,
                "warnings": list(self.log.warnings),
            },
            "settings": self.settings.to_json(),
            "channels": {name: ch.to_json() for name, ch in self.channels.items()},
            "kalibr": self.kalibr(),
            "notes": list(self.notes),
        }

    def kalibr(self) -> dict[str, Any]:
        """Kalibr IMU noise keys from the selected terms, taking the worst (largest) axis.

        Kalibr wants one value per sensor, each > 0. A term the curve does not
        resolve enters as its upper bound (never 0), and a note says so.
        """
        out: dict[str, Any] = {"update_rate": self.log.rate_hz}
        notes: list[str] = []
        for kind, prefix in (("gyro", "gyroscope"), ("accel", "accelerometer")):
            chans = [c for c in self.channels.values() if c.kind == kind]
            if not chans:
                continue
            for term, key in (("N", "noise_density"), ("K", "random_walk")):
                best: tuple[float, str, str] | None = None
                for ch in chans:
                    v = ch.selected.terms[term].value
                    if v is not None and v > 0 and (best is None or v > best[0]):
                        best = (float(v), ch.name, ch.selected.status(term))
                if best is None:
                    notes.append(f"{prefix}_{key}: no axis gave a positive {term}; not written")
                    continue
                out[f"{prefix}_{key}"] = best[0]
                out[f"{prefix}_{key}_axis"] = best[1]
                out[f"{prefix}_{key}_status"] = best[2]
                if best[2] != "resolved":
                    notes.append(
                        f"{prefix}_{key}: {term} is not resolved by the log ({best[1]}); its "
                        "upper bound is written (conservative)"
                    )
        out["notes"] = notes
        return out

    def kalibr_yaml(self, doc: Mapping[str, Any] | None = None) -> str:
        """Text of ``imu.yaml`` in Kalibr's format (``imubounds export --format kalibr``'s
        text; a key no channel gives is named in a comment). ``doc``: this result's
        :meth:`to_json`, when already made."""
        from imubounds.export import filter_noise, kalibr_text

        return kalibr_text(filter_noise(doc if doc is not None else self.to_json()),
                           strict=False)


STATISTIC = {
    "overlapping": "overlapping Allan deviation",
    "non-overlapping": "non-overlapping Allan deviation",
    "modified": "modified Allan deviation",
    "hadamard": "overlapping Hadamard deviation",
    "non-overlapping-hadamard": "non-overlapping Hadamard deviation",
    "total": "total deviation",
}


def allan_json(curve: AllanResult) -> dict[str, Any]:
    """The ``allan`` block of noise.json: ``tau_s``, ``adev``, ``ci_lower``, ``ci_upper`` (SI),
    ``edf``, ``alpha`` and ``noise_type`` (the noise identified at each τ)."""
    d = curve.to_dict()
    d["tau_s"] = d.pop("tau")
    d["adev"] = d.pop("dev")
    d["statistic"] = STATISTIC.get(curve.estimator, curve.estimator)
    if curve.robust:
        d["statistic"] = "robust " + d["statistic"]
    return d


def analyse_static(
    log: ImuLog,
    settings: StaticSettings | None = None,
    *,
    channels: Sequence[str] | None = None,
    progress: Progress | None = None,
    curves: Mapping[str, AllanResult] | None = None,
) -> StaticResult:
    """Run the stationary characterisation on every (or the selected) channel.

    ``progress(stage, done, total)`` is called as work advances (the library
    never prints). ``curves`` supplies Allan curves computed elsewhere (the
    out-of-core path, :mod:`imubounds.stationary.stream`); they must match
    ``settings``, and then the samples are not looked at (no spike check, no
    robust curve).
    """
    settings = settings or StaticSettings()
    if settings.terms_from not in ("fit", "slope"):
        raise OptionError(f"terms_from must be 'fit' or 'slope', got {settings.terms_from!r}")
    names = list(channels) if channels else log.channel_names()
    missing = [n for n in names if n not in log.channels]
    if missing:
        raise OptionError(
            f"channel(s) {', '.join(missing)} not in {log.source}; "
            f"available: {', '.join(log.channel_names())}"
        )
    imu_names = [n for n in names if n.startswith(("gyro", "accel"))]
    if not imu_names:
        raise AnalysisError(f"{log.source} has no gyro or accelerometer channel to analyse")
    if curves is not None and settings.robust:
        raise OptionError("the robust Allan variance needs the samples in memory (not out-of-core)")
    if curves is None:
        _check_length(log, imu_names)

    def allan_progress(done: int, total: int) -> None:
        if progress is not None:
            progress("allan", done, total)

    spikes: dict[str, SpikeReport] = {}
    plain: Mapping[str, AllanResult] = {}
    stat: dict[str, Stationarity] = {}
    cuts: dict[str, int] = {}
    data: dict[str, Any] = {n: log.channels[n] for n in imu_names}
    if curves is None:
        curves, plain, stat, cuts, data = _curves_in_memory(log, imu_names, settings,
                                                            allan_progress)  # fmt: skip
        for name in imu_names:
            spikes[name] = detect_spikes(
                np.asarray(data[name]),
                log.rate_hz,
                threshold=settings.spike_threshold,
                name=name,
                t=np.asarray(log.t)[cuts.get(name, 0) :],
            )
    for name in imu_names:  # a curve read out of core: its numeric edges, named
        dev = np.asarray(curves[name].dev, dtype=float)
        if dev.size and not np.isfinite(dev).all():
            raise InputError(
                f"{log.source}: {name}: the Allan deviation overflows (samples too large to "
                "square in double precision): the channel is corrupt or scaled wrongly"
            )
        if dev.size and not np.any(dev > 0):
            raise InputError(
                f"{log.source}: {name}: the Allan deviation is 0 at every tau: the channel is "
                "constant (stuck or not recorded) or too small to square; check the channel"
            )
    results: dict[str, ChannelResult] = {}
    model_fits = _fit_models(data, log.rate_hz, imu_names, settings, progress, curves)
    stamps: dict[str, Any] | None = None
    for name in imu_names:
        curve = curves[name]
        cut_s = cuts.get(name, 0) / log.rate_hz
        duration_s = log.duration_s - cut_s
        t_avg = settings.averaging_time_s or duration_s
        run_hours = settings.run_hours or duration_s / 3600.0
        fit, slope, sel = analyse_curve(
            curve, prefer=settings.terms_from, confidence=settings.confidence
        )
        kind = sensor_kind(name)
        fit, slope = replace(fit, kind=kind), replace(slope, kind=kind)
        sel = replace(sel, kind=kind, fit=fit, slope=slope)
        notes: list[str] = []
        warnings: list[str] = []
        rep = spikes.get(name)
        msg = rep.warning(settings.robust) if rep is not None else None
        if msg:
            warnings.append(msg)
        st = stat.get(name)
        if st is not None:
            unit = si_unit_of_signal(sensor_kind(name))
            warnings.extend(f"{name}: {m}" for m in st.messages(unit, cut=cut_s > 0))
            absorbed = [t for t in ("R", "K") if sel.status(t) == "resolved"]
            trend = st.trend_message(absorbed, unit)
            if trend:
                warnings.append(f"{name}: {trend}")
        if cut_s > 0:
            notes.append(
                f"the first {cut_s:.4g} s (its warm-up) were cut before the analysis of this "
                "channel (--cut-warmup: each channel at its own warm-up)"
            )
        elif settings.cut_warmup and st is not None:
            notes.append("--cut-warmup: no warm-up found on this channel; nothing cut")
        elif settings.cut_warmup:
            warnings.append(
                f"{name}: --cut-warmup: nothing cut: the warm-up and drift checks need the "
                "samples in memory and are not run out of core (raise --max-memory)"
            )
        timing = None
        if st is not None:  # the samples are in memory: so are their stamps
            stamps = stamps if stamps is not None else stamp_stats(log.t)
            timing = timing_check(
                log.t, curve.tau, curve.dev, curve.ci_lower, curve.ci_upper, stamps
            )
            warnings.extend(f"{name}: {m}" for m in timing_messages(timing))
        used = {t: sel.value(t) for t in ("N", "B")}
        wl = white_level(curve, fit, slope, selected=used["N"])
        msg = wl.message(name, SI_UNITS[kind]["N"]) if wl is not None else None
        if msg:
            warnings.append(msg)
        for t in ("N", "B"):
            if sel.status(t) == "upper_bound":
                warnings.append(
                    f"{name}: {t} is not resolved by the curve; sigma_c and the bound use its "
                    f"upper bound {used[t]:.4g} {SI_UNITS[sensor_kind(name)][t]} (conservative)"
                )
        if sel.status("K") == "upper_bound":
            notes.append(
                f"K is not resolved; imu.yaml and noise.selected carry its upper bound "
                f"{sel.value('K'):.4g} {SI_UNITS[sensor_kind(name)]['K']}"
            )
        rec = channel_record_length(curve, fit, sel, duration_s / 3600.0, settings.confidence)
        notes.append(describe_record_length("", rec))
        sc = bounds.sigma_c(used["N"], used["B"], log.dt, t_avg)
        results[name] = ChannelResult(
            name=name,
            allan=curve,
            slope=slope,
            fit=fit,
            selected=sel,
            sigma_c=sc,
            bound=settings.k_sigma * sc,
            level_95=bounds.level_95_si(used["N"], run_hours * 3600.0),
            run_hours=run_hours,
            averaging_time_s=t_avg,
            terms_used=used,
            k_sigma=settings.k_sigma,
            notes=notes,
            warnings=warnings,
            models=model_fits.get(name),
            allan_plain=plain.get(name),
            spikes=rep,
            record_length=rec,
            stationarity=st,
            timing=timing,
            white_level=wl,
            start_s=cut_s,
            n_samples=int(np.size(data[name])) if name in data else log.n_samples,
        )
    return StaticResult(log=log, settings=settings, channels=results)


def _check_length(log: ImuLog, names: list[str]) -> None:
    """Refuse channels with fewer than :data:`MIN_SAMPLES` samples, naming them."""
    short = [n for n in names if np.size(log.channels[n]) < MIN_SAMPLES]
    if short:
        k = int(np.size(log.channels[short[0]]))
        raise InputError(
            f"{log.source}: {', '.join(short)}: {k} sample(s) ({k / log.rate_hz:.3g} s at "
            f"{log.rate_hz:g} Hz) are too few for a static characterisation (at least "
            f"{MIN_SAMPLES}: an Allan curve of five octaves and the stationarity windows); "
            "record a longer log"
        )


def _curves_in_memory(
    log: ImuLog,
    names: list[str],
    settings: StaticSettings,
    progress: Callable[[int, int], None],
) -> tuple[dict[str, AllanResult], dict[str, AllanResult], dict[str, Stationarity],
           dict[str, int], dict[str, Any]]:  # fmt: skip
    """The Allan curves, the stationarity checks (with the curves as their noise model)
    and, with ``settings.cut_warmup``, each channel cut at its own warm-up and its curve
    computed again: (curves, plain curves, stationarity, samples cut, samples)."""
    from imubounds.stationary.allan import check_magnitude

    for name in names:  # numeric edges named before any estimator meets them
        check_magnitude(np.asarray(log.channels[name]), f"{log.source}: {name}")
    data: dict[str, Any] = {n: log.channels[n] for n in names}
    kw: dict[str, Any] = {"taus": settings.taus, "estimator": settings.estimator,
                          "confidence": settings.confidence}  # fmt: skip
    curves = allan_channels(data, log.rate_hz, progress=progress, robust=settings.robust, **kw)
    stat = {n: stationarity(data[n], log.rate_hz, curve=curves[n]) for n in names}
    cuts = warmup_cuts(stat, log.rate_hz) if settings.cut_warmup else {}
    again = [n for n in names if cuts.get(n, 0) > 0]
    for n in again:
        data[n] = np.asarray(data[n])[cuts[n] :]
    if again:
        curves.update(allan_channels({n: data[n] for n in again}, log.rate_hz,
                                     robust=settings.robust, **kw))  # fmt: skip
    plain: dict[str, AllanResult] = {}
    if settings.robust:
        plain = allan_channels(data, log.rate_hz, **kw)
    return curves, plain, stat, cuts, data


def _fit_models(
    data: Mapping[str, Any],
    rate_hz: float,
    names: list[str],
    settings: StaticSettings,
    progress: Progress | None,
    curves: Mapping[str, AllanResult],
) -> dict[str, Any]:
    """Fit the stochastic models asked for, checked against each channel's curve."""
    if not settings.models:
        return {}
    from imubounds.stationary.models import fit_models

    out: dict[str, Any] = {}
    for i, name in enumerate(names):
        if progress is not None:
            progress("models", i, len(names))
        out[name] = fit_models(
            np.asarray(data[name]),
            rate_hz,
            settings.models,
            ar_order_max=settings.ar_max_order,
            name=name,
            unit=si_unit_of_signal(sensor_kind(name)),
            curve=curves[name],
        )
    if progress is not None:
        progress("models", len(names), len(names))
    return out
