"""``drive.yaml`` of a drive layout: every key typed and range-checked against the documented
set (docs/drive-layout.md), YAML aliases refused before they expand, paths resolved beside the
file; and the settings written back (:func:`settings_to_dict`). The tables of the layout are
read by :mod:`imubounds.io.drive.layout`.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from imubounds.errors import InputError, OptionError
from imubounds.frames import axes_matrix
from imubounds.io.drive import DriveSettings
from imubounds.io.validate import check_input_path

SETTINGS_FILE = "drive.yaml"

# Allowed values of the text settings, and range checks of the numeric ones:
# (lower bound, lower bound inclusive, upper bound or None).
_CHOICES: dict[str, tuple[str, ...]] = {
    "heading.sensor": ("compass", "gnss", "ahrs"),
    "heading.reference": ("magnetic", "true"),
    "heading.fit": ("auto", "ellipse", "swing", "gnss-course", "none"),
    "heading.use": ("auto", "heading", "mag", "attitude"),
    "heading.errors": ("estimate", "stated"),
    "vehicle.kind": ("ground", "marine", "air"),
}
_RANGES: dict[str, tuple[float, bool, float | None]] = {
    "gnss.cep_m": (0.0, False, None),
    "gnss.default_hdop": (0.0, False, None),
    "gnss.vel_sigma_mps": (0.0, False, None),
    "gnss.vertical_sigma_ratio": (0.0, False, None),
    "gnss.time_offset_s": (-60.0, True, 60.0),
    "gnss.time_offset_bound_s": (0.0, True, 60.0),
    "heading.time_offset_s": (-60.0, True, 60.0),
    "heading.time_offset_bound_s": (0.0, True, 60.0),
    "velocity.bound_mps": (0.0, True, None),
    "velocity.scale": (0.0, True, 1.0),
    "heading.deviation_deg": (0.0, True, 180.0),
    "heading.declination_deg": (-180.0, True, 180.0),
    "heading.noise_deg": (0.0, True, 90.0),
    "heading.alignment_deg": (0.0, True, 180.0),
    "attitude.bound_deg": (0.0, True, 90.0),
    "vehicle.max_speed_mps": (0.0, False, None),
    "vehicle.max_accel_mps2": (0.0, False, None),
    "vehicle.max_jerk_mps3": (0.0, False, None),
    "vehicle.max_yaw_rate_dps": (0.0, False, None),
    "vehicle.max_tilt_deg": (0.0, True, 90.0),
    "vehicle.lateral_speed_bound_mps": (0.0, True, None),
    "vehicle.vertical_speed_bound_mps": (0.0, True, None),
    "imu.accel_nd": (0.0, True, None),
    "imu.accel_bs": (0.0, True, None),
    "imu.gyro_nd": (0.0, True, None),
    "imu.gyro_bs": (0.0, True, None),
    "imu.accel_turn_on_mps2": (0.0, True, None),
    "imu.gyro_turn_on_dps": (0.0, True, None),
    "imu.scale_factor": (0.0, True, 1.0),
    "imu.misalignment_deg": (0.0, True, 90.0),
    "imu.accel_rrw": (0.0, True, None),
    "imu.gyro_rrw": (0.0, True, None),
    "imu.accel_bias_drift_mps2": (0.0, True, None),
    "imu.gyro_bias_drift_dps": (0.0, True, None),
    "imu.bias_drift_window_s": (0.0, False, None),
}
_CHOICES["imu.sample_time"] = ("end", "centre", "start")


def setting_range(key: str) -> tuple[float, bool, float | None]:
    """(lower bound, lower bound inclusive, upper bound or None) of a numeric drive.yaml
    setting (``"heading.deviation_deg"``): the one range a command-line option that
    overrides it is checked against too."""
    return _RANGES.get(key, (-math.inf, True, None))


#: Settings that are texts: file names (resolved against drive.yaml's folder) and names.
_PATH_KEYS = ("imu.noise_json", "heading.calibration")
_TEXT_KEYS = ("imu.preset",)
_INFO_KEYS = ("converted_from", "notes")
#: drive.yaml larger than this is refused unread (a settings file is a few hundred bytes).
SETTINGS_MAX_BYTES = 1 << 20


def _check_value(key: str, value: Any, default: Any, where: str) -> Any:
    """One ``drive.yaml`` value, typed by the key table: a choice of :data:`_CHOICES`, a
    text of :data:`_PATH_KEYS`/:data:`_TEXT_KEYS`, else a finite number (range of
    :data:`_RANGES` where given). A new numeric key needs only its dataclass field (and a
    range row); anything else is an :class:`InputError` naming the key."""
    if value is None:
        if default is not None:  # a setting that cannot be "not stated"
            raise InputError(
                f"{where}: {key} has no value (null); give one, or leave the key out for its "
                f"default {default!r}"
            )
        return None
    if key in _CHOICES:
        if not isinstance(value, str):
            raise InputError(
                f"{where}: {key} is {value!r}; use one of {', '.join(_CHOICES[key])}"
            )
        text = value.strip().lower()
        if key == "imu.sample_time" and text == "center":
            text = "centre"
        if text not in _CHOICES[key]:
            raise InputError(
                f"{where}: {key} is {value!r}; use one of {', '.join(_CHOICES[key])}"
            )
        return text
    if key in _PATH_KEYS or key in _TEXT_KEYS:
        if isinstance(value, np.ndarray) and key == "heading.calibration":
            return value  # swing pairs held in memory (a simulated drive)
        if not isinstance(value, str) or not value.strip():
            raise InputError(
                f"{where}: {key} must be a text (a file name or preset name), got {value!r}"
            )
        return value.strip()
    if isinstance(value, bool) or not isinstance(value, int | float):
        kind = "a text" if isinstance(value, str) else type(value).__name__
        raise InputError(
            f"{where}: {key} must be a number, got {value!r} ({kind}); write it without "
            "quotes, in the unit of its name"
        )
    x = float(value)
    lo, inclusive, hi = _RANGES.get(key, (-math.inf, True, None))
    if not math.isfinite(x) or x < lo or (x == lo and not inclusive):
        rel = ">=" if inclusive else ">"
        what = f" {rel} {lo:g}" if math.isfinite(lo) else ""
        raise InputError(f"{where}: {key} must be a finite number{what}, got {value!r}")
    if hi is not None and x > hi:
        raise InputError(f"{where}: {key} must be at most {hi:g}, got {value!r}")
    return x


def _section(
    cls: type, data: Any, name: str, where: str, assumed: list[str], defaulted: list[str]
) -> Any:
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise InputError(f"{where}: {name} must be a mapping of settings (key: value lines)")
    proto = cls()
    names = {f.name for f in dataclasses.fields(cls)}
    for k in data:
        if k not in names:
            raise InputError(
                f"{where}: unknown key {name}.{k}; known in {name}: {', '.join(sorted(names))}"
            )
    kw = {
        k: _check_value(f"{name}.{k}", v, getattr(proto, k), where) for k, v in data.items()
    }
    obj = cls(**kw)
    for f in dataclasses.fields(cls):
        if f.name in data:
            continue
        defaulted.append(f"{name}.{f.name}")
        value = getattr(obj, f.name)
        if value is not None:
            assumed.append(f"{name}.{f.name} = {value!r} (default)")
    return obj


def _axes(value: Any, key: str, where: str) -> tuple[str, str, str]:
    if isinstance(value, str):
        value = [v for v in value.replace(",", " ").split() if v]
    if (
        not isinstance(value, list | tuple)
        or len(value) != 3
        or not all(isinstance(a, str) for a in value)
    ):
        shown = repr(value)
        shown = shown if len(shown) <= 60 else shown[:57] + "..."
        raise InputError(f"{where}: {key} must be a list like [x, -z, y], got {shown}")
    try:
        axes_matrix([str(a) for a in value])
    except InputError as err:
        raise InputError(f"{where}: {key}: {err}") from None
    return tuple(str(a).strip() for a in value)  # type: ignore[return-value]


def parse_settings(
    data: Any, where: str = SETTINGS_FILE, base_dir: str | Path | None = None
) -> DriveSettings:
    """``drive.yaml`` contents -> :class:`DriveSettings`.

    Unknown keys and out-of-range values are an :class:`InputError` naming the
    key; keys left out take their documented default and are listed in
    ``assumed`` (words) and ``defaulted`` (dotted keys). File names
    (``imu.noise_json``, ``heading.calibration``) are resolved against
    ``base_dir`` (the directory of the yaml) and must exist; ``imu.preset``
    must be a known preset.
    """
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise InputError(f"{where}: must be a mapping (key: value lines)")
    known = {f.name for f in dataclasses.fields(DriveSettings)} - {"assumed", "defaulted"}
    for k in data:
        if k not in known and k not in _INFO_KEYS:
            raise InputError(f"{where}: unknown key {k!r}; known: {', '.join(sorted(known))}")
    assumed: list[str] = []
    defaulted: list[str] = []
    kw: dict[str, Any] = {}
    for f in dataclasses.fields(DriveSettings):
        if f.name in ("assumed", "defaulted", "imu_axes", "mag_axes", "lever_arm_m"):
            continue
        cls = type(getattr(DriveSettings(), f.name))
        kw[f.name] = _section(cls, data.get(f.name), f.name, where, assumed, defaulted)
    if "imu_axes" in data:
        kw["imu_axes"] = _axes(data["imu_axes"], "imu_axes", where)
    else:
        defaulted.append("imu_axes")
        assumed.append("imu_axes = [x, y, z] (the IMU's axes are the body axes; default)")
    if data.get("mag_axes") is not None:
        kw["mag_axes"] = _axes(data["mag_axes"], "mag_axes", where)
    lever = data.get("lever_arm_m")
    if lever is not None:
        if (
            not isinstance(lever, list | tuple)
            or len(lever) != 3
            or not all(isinstance(x, int | float) and not isinstance(x, bool) for x in lever)
            or not all(math.isfinite(float(x)) for x in lever)
        ):
            raise InputError(
                f"{where}: lever_arm_m must be a list of three finite numbers [x, y, z] in m, "
                f"got {lever!r}"
            )
        kw["lever_arm_m"] = tuple(float(x) for x in lever)
    s = DriveSettings(**kw, assumed=assumed, defaulted=defaulted)
    _resolve_imu_noise(s, where, base_dir)
    if isinstance(s.heading.calibration, str):
        s.heading.calibration = _resolve(s.heading.calibration, "heading.calibration", where,
                                         base_dir)
        _check_calibration(s.heading.calibration, where)
    if s.heading.deviation_deg is None:
        assumed.append("heading.deviation_deg: from the compass calibration's residual (default)")
    return s


def _resolve(value: str, key: str, where: str, base_dir: str | Path | None) -> str:
    p = Path(value)
    if not p.is_absolute() and base_dir is not None:
        p = Path(base_dir) / p
    try:
        check_input_path(p, what=key)
    except InputError as err:
        raise InputError(f"{where}: {key}: {err}") from None
    return str(p.absolute())  # absolute: it must not be joined to the drive's folder again


def _check_calibration(path: str, where: str) -> None:
    """Every (measured_deg, reference_deg) pair of a swing calibration must be finite: a
    NaN or empty cell is an error naming the row (the fit would drop it silently)."""
    check_input_path(path, what="compass calibration file")
    try:
        data = pd.read_csv(path, comment="#", skipinitialspace=True)
    except (OSError, ValueError, UnicodeDecodeError, pd.errors.ParserError):
        return  # unreadable: the calibration reader says why, naming the file
    data.columns = [str(c).strip() for c in data.columns]
    for name in ("measured_deg", "reference_deg"):
        if name not in data.columns:
            continue
        v = pd.to_numeric(data[name], errors="coerce").to_numpy(float)
        bad = ~np.isfinite(v)
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise InputError(
                f"{where}: heading.calibration {path}: {name} is {str(data[name].iloc[i])!r} "
                f"at data "
                f"row {i + 1}; every calibration pair must be finite degrees (remove the row)"
            )


def check_calibration(path: str | Path) -> None:
    """A swing-calibration CSV given on its own (``--compass-cal``): a special file is
    refused unopened, a NaN or empty pair is an error naming the row."""
    _check_calibration(str(path), "compass calibration")


def check_noise_json(path: str | Path, where: str = "") -> None:
    """A noise.json of ``imubounds static`` for the dynamic analysis: UTF-8 JSON with a
    ``channels`` object that has figures for the accelerometers *and* the gyros (with one
    kind only, the other would silently take the default IMU's figures)."""
    import json

    lead = f"{where}: " if where else ""
    try:
        p = check_input_path(path, what="noise.json")
    except InputError as err:
        raise InputError(f"{lead}noise.json: {err}") from None
    try:
        data = json.loads(p.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError) as err:
        first = (str(err).splitlines() or [type(err).__name__])[0][:120]
        raise InputError(
            f"{lead}{p}: cannot read as the noise.json of 'imubounds static' ({first})"
        ) from err
    chans = data.get("channels") if isinstance(data, dict) else None
    if not isinstance(chans, dict) or not chans:
        raise InputError(
            f"{lead}{p}: no 'channels' object; give the noise.json of 'imubounds static'"
        )
    kinds = {str(c).split("_")[0] for c in chans}
    missing = [k for k in ("accel", "gyro") if k not in kinds]
    if missing:
        raise InputError(
            f"{lead}{p}: noise.json has no {missing[0]} channel (only "
            f"{', '.join(sorted(map(str, chans)))}); the {missing[0]}s would take the default "
            f"IMU's figures: characterise a log with {missing[0]} columns, or give every "
            "figure with --imu-spec / drive.yaml imu"
        )


def _resolve_imu_noise(s: DriveSettings, where: str, base_dir: str | Path | None) -> None:
    imu = s.imu
    if imu.noise_json is not None and imu.preset is not None:
        raise InputError(f"{where}: give imu.noise_json or imu.preset, not both")
    if imu.noise_json is not None:
        imu.noise_json = _resolve(imu.noise_json, "imu.noise_json", where, base_dir)
        check_noise_json(imu.noise_json, f"{where}: imu.noise_json")
    if imu.preset is not None:
        from imubounds.presets import get_preset

        try:
            get_preset(imu.preset)
        except OptionError as err:
            raise InputError(f"{where}: imu.preset: {err}") from None
    datasheet = ("accel_nd", "accel_bs", "gyro_nd", "gyro_bs")
    given = [k for k in datasheet if getattr(imu, k) is not None]
    if given and not any(getattr(imu, k) for k in given):
        raise InputError(
            f"{where}: imu.{', imu.'.join(given)} are all 0: no IMU is noiseless; give the "
            "datasheet's figures or leave them out"
        )
    if imu.noise_json is None and imu.preset is None and all(
        getattr(imu, k) is None for k in datasheet
    ):
        s.assumed.append(
            "imu: no noise_json, preset or datasheet figures: the estimator's default IMU applies"
        )


def settings_to_dict(s: DriveSettings, *, keep_defaults: bool = False) -> dict[str, Any]:
    """:class:`DriveSettings` -> a mapping ``drive.yaml`` can hold.

    Settings listed in ``defaulted`` are left out (unless ``keep_defaults``),
    so that reading the file back lists them as assumed again; ``None`` values
    are left out.
    """
    skip = set() if keep_defaults else set(s.defaulted)
    out: dict[str, Any] = {}
    if "imu_axes" not in skip:
        out["imu_axes"] = list(s.imu_axes)
    if s.mag_axes is not None:
        out["mag_axes"] = list(s.mag_axes)
    for f in dataclasses.fields(DriveSettings):
        if f.name in ("assumed", "defaulted", "imu_axes", "mag_axes", "lever_arm_m"):
            continue
        sec = getattr(s, f.name)
        d = {
            k: v
            for k, v in dataclasses.asdict(sec).items()
            if v is not None and f"{f.name}.{k}" not in skip
        }
        if d:
            out[f.name] = d
    if s.lever_arm_m is not None:
        out["lever_arm_m"] = list(s.lever_arm_m)
    return out


# ----------------------------------------------------------------------------- tables


def read_settings_with_info(d: Path) -> tuple[DriveSettings, dict[str, Any]]:
    """``d/drive.yaml`` -> (settings, informational keys ``converted_from`` and ``notes``)."""
    p = d / SETTINGS_FILE
    if not p.exists():
        s = parse_settings({}, str(p))
        s.assumed.insert(0, f"{p} is absent: every setting is its documented default")
        return s, {}
    check_input_path(p, what="drive settings")
    data = load_settings_yaml(p)
    info: dict[str, Any] = {}
    if isinstance(data, dict):
        for k in _INFO_KEYS:
            if k in data:
                info[k] = data.pop(k)
        notes = info.get("notes")
        if isinstance(notes, str):  # one note written as a text
            info["notes"] = [notes] if notes.strip() else []
        elif notes is None:
            info.pop("notes", None)
        elif not isinstance(notes, list) or any(
            isinstance(n, dict | list) for n in notes
        ):
            raise InputError(f"{p}: notes must be a text or a list of texts, got {notes!r:.60}")
    return parse_settings(data, str(p), base_dir=d), info


def load_settings_yaml(p: Path) -> Any:
    """The contents of a ``drive.yaml`` (plain YAML: mappings, lists, numbers, texts).

    YAML aliases (``*name``) are refused before they are expanded (an alias bomb
    would otherwise take minutes and all memory), and so is a file larger than
    :data:`SETTINGS_MAX_BYTES`; anything unreadable is an :class:`InputError`."""
    import yaml

    class _NoAliasLoader(yaml.SafeLoader):
        def compose_node(self, parent: Any, index: Any) -> Any:
            if self.check_event(yaml.events.AliasEvent):
                event = self.peek_event()
                mark = event.start_mark
                raise InputError(
                    f"{p}, line {mark.line + 1}: YAML alias *{event.anchor} is not allowed in "
                    "drive settings; write the value out"
                )
            return super().compose_node(parent, index)

    try:
        size = p.stat().st_size
        if size > SETTINGS_MAX_BYTES:
            raise InputError(
                f"{p}: {size} bytes is far too large for drive settings (at most "
                f"{SETTINGS_MAX_BYTES} bytes); check the file"
            )
        text = p.read_text(encoding="utf-8")
        return yaml.load(text, Loader=_NoAliasLoader)  # noqa: S506 (a SafeLoader)
    except (OSError, UnicodeDecodeError, yaml.YAMLError, RecursionError) as err:
        first = (str(err).splitlines() or [type(err).__name__])[0]
        raise InputError(f"{p}: cannot read as YAML ({first})") from err


def read_settings(d: Path) -> DriveSettings:
    """``d/drive.yaml`` -> :class:`DriveSettings` (defaults, listed as assumed, if absent)."""
    return read_settings_with_info(Path(d))[0]
