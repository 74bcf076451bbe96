"""Filter parameters from the noise terms: Kalibr, OpenVINS, VINS, GTSAM and ROS files.

:func:`export_noise` turns a static result (``noise.json``, optionally with the
in-motion figures of ``motion.json``) into the text of one file a filter reads. Each
number is written with its unit and the conversion that made it, in YAML comments on
the lines before it (never beside a value: OpenCV's FileStorage, the reader of OpenVINS
and VINS, would read such a comment into a text value).

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
(the IMU block of a VINS-Mono/Fusion config: ``acc_n = sqrt(2)*N*sqrt(f)`` and
``acc_w = K*sqrt(f)``, derived from its mid-point propagation, :data:`VINS_WHITE_FACTOR`),
``gtsam``
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
#
# Every comment sits on a line of its own, before the key it explains: OpenCV's
# FileStorage (the reader of OpenVINS and VINS) reads an unquoted text value up to the end
# of its line, so a comment beside ``rostopic: /imu0`` would become part of the topic.


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


class _Doc:
    """YAML lines with every comment on its own line (none inside a value)."""

    def __init__(self) -> None:
        self.lines: list[str] = []

    def comment(self, text: str, indent: str = "") -> None:
        self.lines.append(f"{indent}# {text}" if text else f"{indent}#")

    def key(self, key: str, value: str, *comments: str, indent: str = "") -> None:
        for c in comments:
            self.comment(c, indent)
        self.lines.append(f"{indent}{key}: {value}")

    def text(self) -> str:
        return "\n".join(self.lines) + "\n"


def _header(doc: _Doc, fn: FilterNoise, title: str, yaml_directive: bool = False) -> None:
    from imubounds.version import __version__

    if yaml_directive:  # OpenCV's FileStorage wants its YAML files to say so
        doc.lines += ["%YAML 1.0", "---"]
    doc.comment(title)
    doc.comment(f"written by imubounds {__version__} from {fn.source}")
    doc.comment(f"update_rate f = {fn.rate_hz:g} Hz (the log's sample rate; dt = 1/f = "
                f"{1.0 / fn.rate_hz:g} s)")
    doc.comment("N = white-noise density (Allan: sigma(1 s) of the white part), K = rate random "
                "walk (continuous time);")
    doc.comment("B (bias instability) has no parameter here: it is listed at the end as a "
                "comment.")
    if fn.motion:
        doc.comment("IN MOTION: N and K are the stationary ones times the channel's motion "
                    "factor F (motion.json): F x the stationary band contains the guaranteed "
                    "in-motion error")


def _tail(doc: _Doc, fn: FilterNoise) -> None:
    b_lines = []
    for kind, _name, unit in _KINDS:
        for ax in fn.axes(kind):
            if ax.B is not None:
                b_lines.append(
                    f"  B {ax.channel}: {_e(ax.B)} {unit} ({ax.B_status.replace('_', ' ')}); "
                    "not a random walk: a filter modelling the bias as a random walk uses K"
                )
    if b_lines:
        doc.comment("bias instability (not exported, for reference):")
        for ln in b_lines:
            doc.comment(ln)
    for n in fn.notes:
        doc.comment(f"note: {n}")


def _need(fn: FilterNoise, kind: str, term: str, key: str) -> tuple[float, AxisTerms]:
    w = fn.worst(kind, term)
    if w is None:
        raise InputError(
            f"noise.json has no positive {term} for the {kind} channels; {key} cannot be "
            "written (analyse all six channels with 'imubounds static')"
        )
    return w


def _kalibr_keys(doc: _Doc, fn: FilterNoise, indent: str = "", strict: bool = True) -> None:
    """The four continuous-time densities of Kalibr's imu.yaml (also OpenVINS's)."""
    sq = math.sqrt(fn.rate_hz)
    for kind, name, unit in _KINDS:
        du = "m/s^3" if kind == "accel" else "rad/s^2"
        for term, key, what in (("N", f"{name}_noise_density", "noise density"),
                                ("K", f"{name}_random_walk", "bias random walk")):
            if not strict and fn.worst(kind, term) is None:
                doc.comment(f"{key}: not written (no {kind} channel gave a positive {term})",
                            indent)
                continue
            v, ax = _need(fn, kind, term, key)
            if term == "N":
                conv = (f"per sample sigma_d = sigma*sqrt(f) = {_e(v * sq)} {unit}")
                u = f"{unit}/sqrt(Hz)"
            else:
                conv = (f"per sample the bias steps by sigma_bd = sigma_b/sqrt(f) = "
                        f"{_e(v / sq)} {unit}")
                u = f"{du}/sqrt(Hz)"
            doc.key(key, _e(v), f"[{u}] {what} = {term} of axis {ax.channel} (largest axis), "
                    f"{_status(ax, term)}; {conv}", indent=indent)


#: Kalibr's four keys: (key, kind, term, SI unit)
KALIBR_KEYS: tuple[tuple[str, str, str, str], ...] = (
    ("gyroscope_noise_density", "gyro", "N", "rad/s/sqrt(Hz)"),
    ("gyroscope_random_walk", "gyro", "K", "rad/s^2/sqrt(Hz)"),
    ("accelerometer_noise_density", "accel", "N", "m/s^2/sqrt(Hz)"),
    ("accelerometer_random_walk", "accel", "K", "m/s^3/sqrt(Hz)"),
)


def kalibr_values(fn: FilterNoise) -> dict[str, tuple[float, AxisTerms]]:
    """Kalibr's (and OpenVINS's) four densities as written: per key the value (SI) and the
    axis it comes from (the largest); a key no channel gives is left out."""
    out = {}
    for key, kind, term, _unit in KALIBR_KEYS:
        w = fn.worst(kind, term)
        if w is not None:
            out[key] = w
    return out


def kalibr_text(fn: FilterNoise, strict: bool = True) -> str:
    """Kalibr's imu.yaml; with ``strict=False`` a key no channel can give is named in a
    comment instead of refused (``imubounds static`` on a subset of the channels)."""
    doc = _Doc()
    _header(doc, fn, "Kalibr IMU noise model (imu.yaml): continuous-time densities")
    doc.comment("Kalibr (ImuParameters): sigma_d = sigma/sqrt(dt) per measurement; the bias is "
                "a random walk of density sigma_b")
    _kalibr_keys(doc, fn, strict=strict)
    doc.key("rostopic", "/imu0", "set to your IMU topic")
    doc.key("update_rate", f"{fn.rate_hz:g}", "[Hz]")
    _tail(doc, fn)
    return doc.text()


def _kalibr(fn: FilterNoise) -> str:
    return kalibr_text(fn)


def _matrix(rows: list[list[float]]) -> str:
    """A matrix as nested rows (a YAML sequence of sequences: OpenVINS reads m[r][c])."""
    return "[" + ", ".join("[" + ", ".join(_num(x) for x in r) + "]" for r in rows) + "]"


def _num(x: float) -> str:
    return "0.0" if x == 0 else ("1.0" if x == 1 else _e(x))


_I3 = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
_Z3 = [[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]]


def _openvins(fn: FilterNoise) -> str:
    doc = _Doc()
    _header(doc, fn, "OpenVINS kalibr_imu_chain.yaml: continuous-time densities", True)
    doc.comment("OpenVINS propagation: discrete covariance sigma^2/dt for the white noise and "
                "sigma_b^2*dt for the bias random walk")
    doc.lines.append("imu0:")
    doc.key("T_i_b", _matrix([[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0],
                              [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]]), indent="  ")
    _kalibr_keys(doc, fn, indent="  ")
    doc.key("model", '"kalibr"', indent="  ")
    doc.key("rostopic", "/imu0", "set to your IMU topic", indent="  ")
    doc.key("time_offset", "0.0", indent="  ")
    doc.key("update_rate", f"{fn.rate_hz:g}", "[Hz]", indent="  ")
    doc.comment("IMU intrinsics are not estimated by imubounds: identity (no correction), "
                "3x3 as nested rows", "  ")
    for key in ("Tw", "R_IMUtoGYRO", "Ta", "R_IMUtoACC"):
        doc.key(key, _matrix(_I3), indent="  ")
    doc.key("Tg", _matrix(_Z3), indent="  ")
    _tail(doc, fn)
    return doc.text()


#: VINS's mid-point propagation (IntegrationBase::midPointIntegration) enters each sample's
#: noise twice per step with weight dt/2, as if independent: velocity variance
#: 2 * (acc_n * dt/2)^2 = acc_n^2 dt^2 / 2 per step, acc_n^2 dt / 2 per second. The
#: continuous model gives N^2 per second: acc_n = sqrt(2) * N * sqrt(f) (gyr_n alike).
VINS_WHITE_FACTOR = math.sqrt(2.0)

#: The g_norm written into the VINS block: standard gravity (imubounds measures no local
#: gravity); the comment says to replace it.
STANDARD_GRAVITY = 9.80665


def _vins(fn: FilterNoise) -> str:
    f = fn.rate_hz
    sq = math.sqrt(f)
    doc = _Doc()
    _header(doc, fn, "VINS-Mono / VINS-Fusion IMU block (merge into your config)", True)
    doc.comment("VINS's IntegrationBase (mid-point rule) takes acc_n^2 as the variance of each "
                "of the two samples of a step, weighted dt/2 each:")
    doc.comment("velocity variance per step 2*(acc_n*dt/2)^2 = acc_n^2*dt^2/2, so over 1 s "
                "acc_n^2*dt/2; the continuous model gives N^2*(1 s):")
    doc.comment("acc_n = sqrt(2)*N*sqrt(f) (gyr_n alike, for the angle). The bias step "
                "(acc_w*dt)^2 gives acc_w^2*dt per second = K^2: acc_w = K*sqrt(f).")
    doc.key("imu", "1", "VINS reads the IMU block only with imu: 1")
    doc.key("imu_topic", '"/imu0"', "set to your IMU topic")
    names = {"accel": ("acc_n", "acc_w", "m/s^2", "m/s^3"),
             "gyro": ("gyr_n", "gyr_w", "rad/s", "rad/s^2")}
    for kind, _name, _unit in _KINDS:
        kn, kw, un, uw = names[kind]
        n, ax = _need(fn, kind, "N", kn)
        doc.key(kn, _e(VINS_WHITE_FACTOR * n * sq),
                f"[{un}] = sqrt(2)*N*sqrt(f) = sqrt(2) x {_e(n)} {un}/sqrt(Hz) x sqrt({f:g} Hz);"
                f" N of axis {ax.channel} (largest axis), {_status(ax, 'N')}")
        k, ax = _need(fn, kind, "K", kw)
        doc.key(kw, _e(k * sq),
                f"[{uw}] = K*sqrt(f) = {_e(k)} {uw}/sqrt(Hz) x sqrt({f:g} Hz); K of axis "
                f"{ax.channel} (largest axis), {_status(ax, 'K')}")
    doc.key("g_norm", f"{STANDARD_GRAVITY:g}",
            "[m/s^2] standard gravity: imubounds does not measure the local gravity; put yours")
    _tail(doc, fn)
    return doc.text()


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


def _diag(vals: list[float]) -> list[list[float]]:
    return [[v if r == c else 0.0 for c in range(3)] for r, v in enumerate(vals)]


def _gtsam(fn: FilterNoise) -> str:
    doc = _Doc()
    _header(doc, fn, "GTSAM PreintegrationCombinedParams: continuous-time covariances")
    doc.comment("GTSAM PreintegrationParams: accelerometerCovariance / gyroscopeCovariance are "
                "continuous-time, sigma in m/s^2/sqrt(Hz) | rad/s/sqrt(Hz): cov = N^2 per axis;")
    doc.comment("PreintegrationCombinedParams: biasAccCovariance / biasOmegaCovariance = K^2 "
                "(continuous bias random walk). Python:")
    doc.comment("  p = gtsam.PreintegrationCombinedParams.MakeSharedU(g)")
    doc.comment("  p.setAccelerometerCovariance(np.array(d['accelerometerCovariance'])) ...")
    doc.comment("integrationCovariance is a modelling choice of yours (not measured here)")
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
        doc.key(key, _matrix(_diag([v * v for v in vals])),
                f"[{unit}] {key} = diag({term}^2), {term} = {why}")
    _tail(doc, fn)
    return doc.text()


def _ros(fn: FilterNoise) -> str:
    f = fn.rate_hz
    doc = _Doc()
    _header(doc, fn, "sensor_msgs/Imu covariances (robot_localization reads them per message)")
    doc.comment("row-major 3x3, per-sample variance at the log's rate: sigma_d^2 = "
                f"(N*sqrt(f))^2 = N^2 * {f:g} Hz; a driver publishing at another rate f' uses "
                "N^2 * f'")
    doc.comment("the bias (B, K) is not a per-sample noise: it is not in these covariances")
    doc.lines.append("imu:")
    for key, kind, unit in (
        ("angular_velocity_covariance", "gyro", "(rad/s)^2"),
        ("linear_acceleration_covariance", "accel", "(m/s^2)^2"),
    ):
        vals, axes = _axis_values(fn, kind, "N", key)
        var = [v * v * f for v in vals]
        why = ", ".join(
            f"{a.channel}: N {_e(v)} ({_status(a, 'N')})" for v, a in zip(vals, axes, strict=True)
        )
        flat = [var[0], 0.0, 0.0, 0.0, var[1], 0.0, 0.0, 0.0, var[2]]
        doc.key(key, "[" + ", ".join(_num(x) for x in flat) + "]",
                f"[{unit}] {key} = N^2*f; {why}", indent="  ")
    doc.key("orientation_covariance", "[-1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]",
            "no orientation estimate: orientation_covariance[0] = -1 (sensor_msgs/Imu)",
            indent="  ")
    _tail(doc, fn)
    return doc.text()


_WRITERS = {"kalibr": _kalibr, "openvins": _openvins, "vins": _vins, "gtsam": _gtsam, "ros": _ros}


def written_values(text: str) -> list[str]:
    """The ``key: value`` lines of an exported file with the unit its comment gives
    (``[unit]``), comments and directives left out: what ``imubounds export`` prints after
    writing it."""
    out = []
    unit = ""
    for ln in text.splitlines():
        s = ln.strip()
        if s.startswith("#"):
            body = s.lstrip("# ")
            if body.startswith("[") and "]" in body:
                unit = body[: body.index("]") + 1]
            continue
        if not s or s.startswith(("%", "---")):
            continue
        out.append(ln.rstrip() + (f"  {unit}" if unit and not s.endswith(":") else ""))
        unit = ""
    return out


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
        YAML text; every number has its unit and conversion in comments on the lines
        before it (none inside a value).

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
