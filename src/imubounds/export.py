"""Filter parameters from the noise terms: Kalibr, OpenVINS, VINS, GTSAM and ROS files.

:func:`export_noise` turns a static result (``noise.json``, optionally with the
in-motion figures of ``motion.json``) into the text of one file a filter reads. Each
number is written with its unit and the conversion that made it, as a YAML comment.

The conventions (``update_rate`` = the log's sample rate ``f`` in Hz, ``dt = 1/f``):

* the white-noise density ``N`` of the Allan analysis (rad/s/sqrt(Hz) = rad/s^0.5;
  m/s^2/sqrt(Hz)) *is* the continuous-time noise density ``sigma`` of Kalibr,
  OpenVINS and GTSAM; a per-sample standard deviation is ``sigma_d = N * sqrt(f)``;
* the rate random walk ``K`` (rad/s^2/sqrt(Hz) = rad/s^1.5; m/s^3/sqrt(Hz)) *is* the
  continuous-time bias random walk ``sigma_b``; per sample the bias steps by
  ``sigma_bd = K * sqrt(dt) = K / sqrt(f)``;
* the bias instability ``B`` (the flicker floor) has no place in these models (none
  of them has a flicker or Gauss-Markov bias); it is written as a comment only. A
  ``K`` the log did not resolve enters as its upper bound, flagged ``upper bound``;
* Kalibr / OpenVINS / VINS take one number per sensor: the largest (worst) axis;
  GTSAM and ROS take per-axis diagonals.

Formats: ``kalibr`` (imu.yaml), ``openvins`` (kalibr_imu_chain.yaml), ``vins``
(the IMU block of a VINS-Mono/Fusion config: per-sample ``acc_n = N*sqrt(f)`` and
``acc_w = K*sqrt(f)``, as its IntegrationBase uses them), ``gtsam``
(``PreintegrationCombinedParams`` covariances ``N^2`` and ``K^2``) and ``ros``
(``sensor_msgs/Imu`` covariances ``(N*sqrt(f))^2``, for robot_localization).
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from imubounds.errors import InputError, OptionError

FORMATS: tuple[str, ...] = ("kalibr", "openvins", "vins", "gtsam", "ros")

_KINDS = (("accel", "accelerometer", "m/s^2"), ("gyro", "gyroscope", "rad/s"))
_AXES = ("x", "y", "z")


@dataclass
class AxisTerms:
    """N and K of one channel in SI (continuous time), with their status."""

    channel: str
    N: float | None
    N_status: str
    K: float | None
    K_status: str
    B: float | None
    B_status: str
    motion_F: float | None = None
    #: an in-motion export with no factor for this axis (not analysed, or unresolved)
    motion_missing: bool = False


@dataclass
class FilterNoise:
    """What the exports are made of: per channel N, K (and B for the notes), the rate."""

    rate_hz: float
    source: str
    channels: dict[str, AxisTerms]
    motion: bool = False
    notes: list[str] = field(default_factory=list)

    def axes(self, kind: str) -> list[AxisTerms]:
        return [self.channels[f"{kind}_{a}"] for a in _AXES if f"{kind}_{a}" in self.channels]

    def worst(self, kind: str, term: str) -> tuple[float, AxisTerms] | None:
        """The largest positive value of ``term`` (``N`` or ``K``) over the kind's axes."""
        best: tuple[float, AxisTerms] | None = None
        for ax in self.axes(kind):
            v = getattr(ax, term)
            if v is not None and v > 0 and (best is None or v > best[0]):
                best = (float(v), ax)
        return best


def _load(path: str | Path, name: str) -> dict[str, Any]:
    p = Path(path)
    if p.is_dir():
        p = p / name
    if not p.is_file():
        raise InputError(f"{p}: not found; give an 'imubounds static' output folder or its {name}")
    try:
        doc = json.loads(p.read_text(encoding="utf-8"))
    except (OSError, ValueError) as err:
        raise InputError(f"{p}: cannot read as JSON ({err})") from None
    if not isinstance(doc, dict):
        raise InputError(f"{p}: not a {name} document")
    return doc


def filter_noise(results: Any, motion: Any = None) -> FilterNoise:
    """The per-channel N, K, B (SI) of a static result, optionally inflated in motion.

    ``results``: a :class:`~imubounds.stationary.pipeline.StaticResult`, a loaded
    noise.json document, a noise.json path or an ``imubounds static`` folder.
    ``motion``: ``motion.json`` (a loaded document, a path, or an ``imubounds dynamic``
    folder); each channel with an in-motion factor ``F`` gets ``N*F`` and ``K*F``.
    """
    if hasattr(results, "to_json") and not isinstance(results, Mapping):
        doc = results.to_json()
    elif isinstance(results, Mapping):
        doc = dict(results)
    else:
        doc = _load(results, "noise.json")
    if "channels" not in doc or "input" not in doc:
        raise InputError("not a noise.json document from 'imubounds static' (no 'channels')")
    rate = (doc.get("input") or {}).get("sample_rate_hz")
    if not rate or not math.isfinite(float(rate)) or float(rate) <= 0:
        raise InputError("noise.json: input.sample_rate_hz is missing; re-run 'imubounds static'")
    chans: dict[str, AxisTerms] = {}
    for ch, c in (doc.get("channels") or {}).items():
        sel = ((c or {}).get("noise") or {}).get("selected") or {}

        def term(t: str, sel: Mapping[str, Any] = sel) -> tuple[float | None, str]:
            d = sel.get(t) or {}
            v = d.get("value")
            return (float(v) if v is not None else None), str(d.get("status", "not_observed"))

        n, ns = term("N")
        k, ks = term("K")
        b, bs = term("B")
        chans[ch] = AxisTerms(ch, n, ns, k, ks, b, bs)
    out = FilterNoise(float(rate), str((doc.get("input") or {}).get("path", "?")), chans)
    if motion is not None:
        mdoc = motion if isinstance(motion, Mapping) else _motion_doc(motion)
        out.motion = True
        for ch, mc in (mdoc.get("channels") or {}).items():
            ax = chans.get(ch)
            F = mc.get("F")
            if ax is None:
                continue
            n_used = mc.get("N_static")
            if n_used is not None and ax.N is not None and not math.isclose(
                float(n_used), ax.N, rel_tol=1e-9
            ):
                raise InputError(
                    f"motion.json {ch}: its in-motion figures were computed for N = "
                    f"{float(n_used):.6g}, not this noise.json's {ax.N:.6g}; run 'imubounds "
                    "dynamic ... --static' with this noise.json, then export again"
                )
            if F is None:
                ax.motion_missing = True
                out.notes.append(
                    f"{ch}: the trip did not resolve an in-motion factor (the aiding is "
                    "coarser than the stationary band at every tau): stationary figures kept"
                )
                continue
            ax.motion_F = float(F)
            ax.N = None if ax.N is None else ax.N * float(F)
            ax.K = None if ax.K is None else ax.K * float(F)
        missing = [c for c in chans if c not in (mdoc.get("channels") or {})]
        for c in missing:
            chans[c].motion_missing = True
        if missing:
            out.notes.append(
                f"{', '.join(missing)}: not analysed in motion (stationary figures kept)"
            )
    return out


def _motion_doc(path: Any) -> Mapping[str, Any]:
    from imubounds.motion import read_motion

    return read_motion(path)


# ---------------------------------------------------------------- the formats


def _e(x: float) -> str:
    return f"{x:.6e}"


def _status(ax: AxisTerms, term: str) -> str:
    st = str(getattr(ax, f"{term}_status"))
    txt: str = {"resolved": "resolved", "upper_bound": "UPPER BOUND (not resolved by the log)"}.get(
        st, st.replace("_", " ")
    )
    if ax.motion_F is not None:
        txt += f"; in motion: stationary x F = {ax.motion_F:.3g}"
    elif ax.motion_missing:
        txt += (f"; in motion: NO FACTOR for {ax.channel} (not analysed or unresolved by the "
                "trip): the stationary figure, not an in-motion bound")
    return txt


def _header(fn: FilterNoise, title: str) -> list[str]:
    from imubounds import __version__

    lines = [
        f"# {title}",
        f"# written by imubounds {__version__} from {fn.source}",
        f"# update_rate f = {fn.rate_hz:g} Hz (the log's sample rate; dt = 1/f = "
        f"{1.0 / fn.rate_hz:g} s)",
        "# N = white-noise density (Allan: sigma(1 s) of the white part), K = rate random "
        "walk (continuous time);",
        "# B (bias instability) has no parameter here: it is listed below as a comment.",
    ]
    if fn.motion:
        lines.append(
            "# IN MOTION: N and K are the stationary ones times the channel's motion factor F "
            "(motion.json): F x the stationary band contains the guaranteed in-motion error"
        )
    return lines


def _b_notes(fn: FilterNoise) -> list[str]:
    out = []
    for kind, _name, unit in _KINDS:
        for ax in fn.axes(kind):
            if ax.B is not None:
                out.append(
                    f"#   B {ax.channel}: {_e(ax.B)} {unit} ({ax.B_status.replace('_', ' ')}); "
                    "not a random walk: a filter modelling the bias as a random walk uses K"
                )
    return ["# bias instability (not exported, for reference):", *out] if out else []


def _tail(fn: FilterNoise) -> list[str]:
    return [*_b_notes(fn), *(f"# note: {n}" for n in fn.notes)]


def _need(fn: FilterNoise, kind: str, term: str, key: str) -> tuple[float, AxisTerms]:
    w = fn.worst(kind, term)
    if w is None:
        raise InputError(
            f"noise.json has no positive {term} for the {kind} channels; {key} cannot be "
            "written (analyse all six channels with 'imubounds static')"
        )
    return w


def _kalibr_lines(fn: FilterNoise, indent: str = "") -> list[str]:
    f = fn.rate_hz
    sq = math.sqrt(f)
    lines = []
    for kind, name, unit in _KINDS:
        n, ax = _need(fn, kind, "N", f"{name}_noise_density")
        lines.append(
            f"{indent}{name}_noise_density: {_e(n)}  # [{unit}/sqrt(Hz)] sigma = N of "
            f"{ax.channel} (largest axis), {_status(ax, 'N')}; per sample sigma_d = sigma*sqrt(f)"
            f" = {_e(n * sq)} {unit}"
        )
        k, ax = _need(fn, kind, "K", f"{name}_random_walk")
        du = "m/s^3" if kind == "accel" else "rad/s^2"
        lines.append(
            f"{indent}{name}_random_walk: {_e(k)}  # [{du}/sqrt(Hz)] sigma_b = K of "
            f"{ax.channel} (largest axis), {_status(ax, 'K')}; per sample the bias steps by "
            f"sigma_bd = sigma_b/sqrt(f) = {_e(k / sq)} {unit}"
        )
    return lines


def _kalibr(fn: FilterNoise) -> str:
    lines = _header(fn, "Kalibr IMU noise model (imu.yaml): continuous-time densities")
    lines.append(
        "# Kalibr wiki 'IMU Noise Model': sigma_d = sigma/sqrt(dt), sigma_bd = sigma_b*sqrt(dt)"
    )
    lines += _kalibr_lines(fn)
    lines.append("rostopic: /imu0  # set to your IMU topic")
    lines.append(f"update_rate: {fn.rate_hz:g}  # [Hz]")
    return "\n".join(lines + _tail(fn)) + "\n"


_IDENT = "[1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]"


def _openvins(fn: FilterNoise) -> str:
    lines = ["%YAML 1.0", "---"]
    lines += _header(fn, "OpenVINS kalibr_imu_chain.yaml: continuous-time densities")
    lines.append(
        "# OpenVINS propagation: discrete covariance sigma^2/dt for the white noise and "
        "sigma_b^2*dt for the bias random walk"
    )
    lines.append("imu0:")
    lines.append("  T_i_b: [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], "
                 "[0.0, 0.0, 0.0, 1.0]]")
    lines += _kalibr_lines(fn, indent="  ")
    lines.append('  model: "kalibr"')
    lines.append("  rostopic: /imu0  # set to your IMU topic")
    lines.append("  time_offset: 0.0")
    lines.append(f"  update_rate: {fn.rate_hz:g}  # [Hz]")
    lines.append("  # IMU intrinsics are not estimated by imubounds: identity (no correction)")
    for key in ("Tw", "R_IMUtoGYRO", "Ta", "R_IMUtoACC"):
        lines.append(f"  {key}: {_IDENT}")
    lines.append("  Tg: [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]")
    return "\n".join(lines + _tail(fn)) + "\n"


def _vins(fn: FilterNoise) -> str:
    f = fn.rate_hz
    sq = math.sqrt(f)
    lines = ["%YAML 1.0", "---"]
    lines += _header(fn, "VINS-Mono / VINS-Fusion IMU noise block (merge into your config)")
    lines.append(
        "# VINS's IntegrationBase puts acc_n^2 into the noise of each sample and acc_w^2*dt^2 "
        "into each bias step: acc_n is a per-sample sigma_d = N*sqrt(f), acc_w = K*sqrt(f)"
    )
    lines.append(
        "# (its mid-point rule averages two samples per step: with acc_n = N*sqrt(f) the "
        "velocity variance per step is N^2*dt/2; x sqrt(2) matches the continuous N^2*dt)"
    )
    names = {"accel": ("acc_n", "acc_w", "m/s^2", "m/s^3"),
             "gyro": ("gyr_n", "gyr_w", "rad/s", "rad/s^2")}
    for kind, _name, _unit in _KINDS:
        kn, kw, un, uw = names[kind]
        n, ax = _need(fn, kind, "N", kn)
        lines.append(
            f"{kn}: {_e(n * sq)}  # [{un}] = N*sqrt(f) = {_e(n)} {un}/sqrt(Hz) x "
            f"sqrt({f:g} Hz); N of {ax.channel} (largest axis), {_status(ax, 'N')}"
        )
        k, ax = _need(fn, kind, "K", kw)
        lines.append(
            f"{kw}: {_e(k * sq)}  # [{uw}] = K*sqrt(f) = {_e(k)} {uw}/sqrt(Hz) x "
            f"sqrt({f:g} Hz); K of {ax.channel} (largest axis), {_status(ax, 'K')}"
        )
    lines.append("# g_norm (local gravity) is not measured here; keep your config's value")
    return "\n".join(lines + _tail(fn)) + "\n"


def _diag(vals: list[float]) -> str:
    rows = []
    for i, v in enumerate(vals):
        row = [0.0, 0.0, 0.0]
        row[i] = v
        rows.append("[" + ", ".join(_e(x) if x else "0.0" for x in row) + "]")
    return "[" + ", ".join(rows) + "]"


def _axis_values(
    fn: FilterNoise, kind: str, term: str, key: str
) -> tuple[list[float], list[AxisTerms]]:
    axes = fn.axes(kind)
    if len(axes) != 3 or any(getattr(a, term) is None or getattr(a, term) <= 0 for a in axes):
        w = _need(fn, kind, term, key)
        fn.notes.append(
            f"{key}: not every {kind} axis has a positive {term}; the largest ({w[1].channel}) "
            "is used on all three"
        )
        return [w[0]] * 3, [w[1]] * 3
    return [float(getattr(a, term)) for a in axes], axes


def _gtsam(fn: FilterNoise) -> str:
    lines = _header(fn, "GTSAM PreintegrationCombinedParams: continuous-time covariances")
    lines.append(
        "# GTSAM PreintegrationParams: accelerometerCovariance / gyroscopeCovariance are "
        "continuous-time, sigma in m/s^2/sqrt(Hz) | rad/s/sqrt(Hz): cov = N^2 per axis;"
    )
    lines.append(
        "# PreintegrationCombinedParams: biasAccCovariance / biasOmegaCovariance = K^2 "
        "(continuous bias random walk). Python:"
    )
    lines.append("#   p = gtsam.PreintegrationCombinedParams.MakeSharedU(g)")
    lines.append("#   p.setAccelerometerCovariance(np.array(d['accelerometerCovariance'])) ...")
    lines.append("#   integrationCovariance is a modelling choice of yours (not measured here)")
    spec = (
        ("accelerometerCovariance", "accel", "N", "(m/s^2)^2/Hz"),
        ("gyroscopeCovariance", "gyro", "N", "(rad/s)^2/Hz"),
        ("biasAccCovariance", "accel", "K", "(m/s^3)^2/Hz"),
        ("biasOmegaCovariance", "gyro", "K", "(rad/s^2)^2/Hz"),
    )
    for key, kind, term, unit in spec:
        vals, axes = _axis_values(fn, kind, term, key)
        why = ", ".join(
            f"{a.channel} {_e(v)} ({_status(a, term)})" for v, a in zip(vals, axes, strict=True)
        )
        lines.append(f"# {key}: diag({term}^2) [{unit}], {term} = {why}")
        lines.append(f"{key}: {_diag([v * v for v in vals])}")
    return "\n".join(lines + _tail(fn)) + "\n"


def _ros(fn: FilterNoise) -> str:
    f = fn.rate_hz
    lines = _header(fn, "sensor_msgs/Imu covariances (robot_localization reads them per message)")
    lines.append(
        "# row-major 3x3, per-sample variance at the log's rate: sigma_d^2 = (N*sqrt(f))^2 "
        f"= N^2 * {f:g} Hz; a driver publishing at another rate f' uses N^2 * f'"
    )
    lines.append(
        "# the bias (B, K) is not a per-sample noise: it is not in these covariances"
    )
    lines.append("imu:")
    for key, kind, unit in (
        ("angular_velocity_covariance", "gyro", "(rad/s)^2"),
        ("linear_acceleration_covariance", "accel", "(m/s^2)^2"),
    ):
        vals, axes = _axis_values(fn, kind, "N", key)
        var = [v * v * f for v in vals]
        why = ", ".join(
            f"{a.channel}: N {_e(v)} ({_status(a, 'N')})" for v, a in zip(vals, axes, strict=True)
        )
        lines.append(f"  # {key} [{unit}] = N^2*f; {why}")
        flat = [var[0], 0.0, 0.0, 0.0, var[1], 0.0, 0.0, 0.0, var[2]]
        lines.append(f"  {key}: [" + ", ".join(_e(x) if x else "0.0" for x in flat) + "]")
    lines.append("  # no orientation estimate: orientation_covariance[0] = -1 (sensor_msgs/Imu)")
    lines.append("  orientation_covariance: [-1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]")
    return "\n".join(lines + _tail(fn)) + "\n"


_WRITERS = {"kalibr": _kalibr, "openvins": _openvins, "vins": _vins, "gtsam": _gtsam, "ros": _ros}


def export_noise(results: Any, format: str = "kalibr", *, motion: Any = None) -> str:
    """The text of a filter's IMU noise file from the noise terms.

    Parameters
    ----------
    results : StaticResult, mapping or path
        A static result, a loaded noise.json, its path or an ``imubounds static`` folder.
    format : {"kalibr", "openvins", "vins", "gtsam", "ros"}
        Kalibr imu.yaml; OpenVINS kalibr_imu_chain.yaml; VINS-Mono/Fusion's acc_n,
        gyr_n, acc_w, gyr_w; GTSAM PreintegrationCombinedParams covariances;
        sensor_msgs/Imu (robot_localization) covariances.
    motion : mapping or path, optional
        ``motion.json`` or an ``imubounds dynamic`` output folder: the in-motion
        figures (N and K times each channel's motion factor F).

    Returns
    -------
    str
        YAML text; every number has its unit and conversion in a comment.

    Raises
    ------
    OptionError
        An unknown format.
    InputError
        The results cannot give the format's numbers (the message names the key).
    """
    key = str(format).lower()
    if key not in _WRITERS:
        raise OptionError(f"unknown export format {format!r}; choose one of {', '.join(FORMATS)}")
    return _WRITERS[key](filter_noise(results, motion=motion))
