"""The stationary pipeline: Allan curves -> noise terms -> bounds, for every channel.

:func:`analyse_static` takes an :class:`~imubounds.io.log.ImuLog` (SI units) and
returns a :class:`StaticResult`, whose :meth:`~StaticResult.to_json` is the
content of ``noise.json`` and whose :meth:`~StaticResult.kalibr_yaml` is
``imu.yaml``. Nothing here prints or writes files; see
:mod:`imubounds.cli.static` for that.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

from imubounds import __version__
from imubounds.errors import AnalysisError, OptionError
from imubounds.io.log import ImuLog
from imubounds.stationary import bounds
from imubounds.stationary.allan import AllanResult, allan_channels
from imubounds.stationary.terms import NoiseTerms, fit_slopes, fit_terms
from imubounds.units import SQRT_HOUR, sensor_kind, si_unit_of_signal

FORMAT = "imubounds.stationary.terms/1"
TermSource = Literal["fit", "slope"]
Progress = Callable[[str, int, int], None]


@dataclass(frozen=True)
class StaticSettings:
    """Settings of a stationary analysis.

    ``taus`` is a grid spec understood by :func:`imubounds.stationary.allan.tau_grid`
    ("octave", "decade", an int for N log-spaced points, or τ values in s).
    ``averaging_time_s`` is the t of σ_c (the log length when ``None``);
    ``run_hours`` is the T of the 95 % level (the log length when ``None``).
    ``terms_from`` selects which estimate (fit or slope read-off) feeds σ_c,
    the 95 % level and imu.yaml.
    """

    taus: str | int | Sequence[float] = "octave"
    estimator: str = "overlapping"
    confidence: float = 0.683
    k_sigma: float = bounds.DEFAULT_K
    averaging_time_s: float | None = None
    run_hours: float | None = None
    terms_from: TermSource = "fit"
    models: tuple[str, ...] = ()

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
        }


@dataclass
class ChannelResult:
    """Everything computed for one channel."""

    name: str
    allan: AllanResult
    slope: NoiseTerms
    fit: NoiseTerms
    sigma_c: float
    bound: float
    level_95: float
    run_hours: float
    averaging_time_s: float
    terms_used: dict[str, float]
    notes: list[str] = field(default_factory=list)
    models: Any = None

    @property
    def kind(self) -> str:
        return sensor_kind(self.name)

    def to_json(self, k_sigma: float) -> dict[str, Any]:
        kind = sensor_kind(self.name)
        unit = si_unit_of_signal(kind)
        out: dict[str, Any] = {
            "unit": unit,
            "allan": allan_json(self.allan),
            "noise": {"slope": self.slope.to_json(kind), "fit": self.fit.to_json(kind)},
            "sigma_c": self.sigma_c,
            "bound_3sigma": self.bound,
            "stationary": {
                "unit": unit,
                "k_sigma": k_sigma,
                "sigma_c": self.sigma_c,
                "bound_half_width": self.bound,
                "N": self.terms_used["N"],
                "B": self.terms_used["B"],
                "averaging_time_s": self.averaging_time_s,
                "formula": "sigma_c = N/sqrt(dt) + sqrt(dt/t)*B; bound = k*sigma_c",
            },
            "level_95": {
                "value": self.level_95,
                "unit": unit,
                "T_hours": self.run_hours,
                "rw_per_sqrt_h": self.terms_used["N"] * SQRT_HOUR,
                "formula": "1.96 * RW[per sqrt(h)] * sqrt(T[h]) (paper, section IV)",
            },
        }
        if self.models is not None:
            out["models"] = self.models.to_dict()
        if self.notes:
            out["notes"] = list(self.notes)
        return out


@dataclass
class StaticResult:
    """The result of :func:`analyse_static` for a whole log."""

    log: ImuLog
    settings: StaticSettings
    channels: dict[str, ChannelResult]
    notes: list[str] = field(default_factory=list)

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
            "channels": {
                name: ch.to_json(self.settings.k_sigma) for name, ch in self.channels.items()
            },
            "kalibr": self.kalibr(),
            "notes": list(self.notes),
        }

    def kalibr(self) -> dict[str, Any]:
        """Kalibr IMU noise keys, taking the worst (largest) axis of each sensor.

        Kalibr wants one value per sensor; each value must be > 0. Where the
        chosen estimate has no random-walk (K) term, the upper end of its
        confidence interval is used and the fallback is stated.
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
                    value, how = _positive_term(ch, term, self.settings.terms_from)
                    if value is not None and (best is None or value > best[0]):
                        best = (value, ch.name, how)
                if best is None:
                    notes.append(f"{prefix}_{key}: no axis gave a positive {term}; not written")
                    continue
                out[f"{prefix}_{key}"] = best[0]
                out[f"{prefix}_{key}_axis"] = best[1]
                if best[2]:
                    notes.append(f"{prefix}_{key}: {best[2]} ({best[1]})")
        out["notes"] = notes
        return out

    def kalibr_yaml(self) -> str:
        """Text of ``imu.yaml`` in Kalibr's format, with comments saying which axis was taken."""
        k = self.kalibr()
        lines = [
            "# IMU noise model for Kalibr, written by imubounds "
            f"{__version__} from {self.log.source}",
            "# Each value is the worst (largest) axis of its sensor; units as Kalibr expects.",
        ]
        units = {
            "accelerometer_noise_density": "m/s^2/sqrt(Hz)",
            "accelerometer_random_walk": "m/s^3/sqrt(Hz)",
            "gyroscope_noise_density": "rad/s/sqrt(Hz)",
            "gyroscope_random_walk": "rad/s^2/sqrt(Hz)",
        }
        for key, unit in units.items():
            if key in k:
                lines.append(f"{key}: {k[key]:.6e}  # {unit}, axis {k[key + '_axis']}")
        lines.append("rostopic: /imu0")
        lines.append(f"update_rate: {k['update_rate']:.6g}  # Hz")
        for note in k["notes"]:
            lines.append(f"# note: {note}")
        return "\n".join(lines) + "\n"


STATISTIC = {
    "overlapping": "overlapping Allan deviation",
    "non-overlapping": "non-overlapping Allan deviation",
    "modified": "modified Allan deviation",
    "hadamard": "overlapping Hadamard deviation",
    "total": "total deviation",
}


def allan_json(curve: AllanResult) -> dict[str, Any]:
    """The ``allan`` block of noise.json: ``tau_s``, ``adev``, ``ci_lower``, ``ci_upper`` (SI)."""
    d = curve.to_dict()
    d["tau_s"] = d.pop("tau")
    d["adev"] = d.pop("dev")
    d["statistic"] = STATISTIC.get(curve.estimator, curve.estimator)
    return d


def _positive_term(ch: ChannelResult, term: str, prefer: TermSource) -> tuple[float | None, str]:
    first, second = (ch.fit, ch.slope) if prefer == "fit" else (ch.slope, ch.fit)
    for terms, label in ((first, prefer), (second, "slope" if prefer == "fit" else "fit")):
        v = terms.value(term)  # type: ignore[arg-type]
        if math.isfinite(v) and v > 0:
            return v, "" if label == prefer else f"{term} taken from the {label} estimate"
    for terms, label in ((first, prefer), (second, "other")):
        if term in terms.ci and terms.ci[term][1] > 0:
            return terms.ci[term][1], f"{term} not resolved; upper CI bound of the {label} used"
    return None, ""


def _terms_for_bounds(
    slope: NoiseTerms, fit: NoiseTerms, prefer: TermSource, notes: list[str]
) -> dict[str, float]:
    first, second = (fit, slope) if prefer == "fit" else (slope, fit)
    used: dict[str, float] = {}
    for term in ("N", "B"):
        v = first.value(term)  # type: ignore[arg-type]
        if not (math.isfinite(v) and v > 0):
            alt = second.value(term)  # type: ignore[arg-type]
            if math.isfinite(alt) and alt > 0:
                notes.append(f"{term} from the {second.method} estimate ({prefer} gave none)")
                v = alt
            else:
                notes.append(f"{term} not determined by either estimate; taken as 0 in sigma_c")
                v = 0.0
        used[term] = v
    return used


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
    out-of-core path, :mod:`imubounds.stationary.stream`); they must match ``settings``.
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

    def allan_progress(done: int, total: int) -> None:
        if progress is not None:
            progress("allan", done, total)

    if curves is None:
        curves = allan_channels(
            {n: log.channels[n] for n in imu_names},
            log.rate_hz,
            taus=settings.taus,
            estimator=settings.estimator,
            confidence=settings.confidence,
            progress=allan_progress,
        )
    t_avg = settings.averaging_time_s or log.duration_s
    run_hours = settings.run_hours or log.duration_s / 3600.0
    results: dict[str, ChannelResult] = {}
    model_fits = _fit_models(log, imu_names, settings, progress)
    for name in imu_names:
        curve = curves[name]
        slope = fit_slopes(curve)
        fit = fit_terms(curve, confidence=settings.confidence)
        notes: list[str] = []
        used = _terms_for_bounds(slope, fit, settings.terms_from, notes)
        sc = bounds.sigma_c(used["N"], used["B"], log.dt, t_avg)
        results[name] = ChannelResult(
            name=name,
            allan=curve,
            slope=slope,
            fit=fit,
            sigma_c=sc,
            bound=settings.k_sigma * sc,
            level_95=bounds.level_95_si(used["N"], run_hours * 3600.0),
            run_hours=run_hours,
            averaging_time_s=t_avg,
            terms_used=used,
            notes=notes,
            models=model_fits.get(name),
        )
    return StaticResult(log=log, settings=settings, channels=results)


def _fit_models(
    log: ImuLog, names: list[str], settings: StaticSettings, progress: Progress | None
) -> dict[str, Any]:
    """Fit the stochastic models asked for (issue 3); empty when none are asked."""
    if not settings.models:
        return {}
    from imubounds.stationary.models import fit_models

    out: dict[str, Any] = {}
    for i, name in enumerate(names):
        if progress is not None:
            progress("models", i, len(names))
        out[name] = fit_models(
            np.asarray(log.channels[name]),
            log.rate_hz,
            settings.models,
            name=name,
            unit=si_unit_of_signal(sensor_kind(name)),
        )
    if progress is not None:
        progress("models", len(names), len(names))
    return out
