"""The simulated IMU's noise per axis: from a datasheet preset or from a static noise.json.

With ``ScenarioConfig.imu_noise`` (``imubounds simulate --imu-noise NOISE_JSON``) the
trip's IMU has the noise ``imubounds static`` measured, per axis, built exactly as
``imubounds simulate-noise --from-noise`` builds it
(:meth:`imubounds.stationary.noise_sim.NoiseSpec.from_noise_json`, the fit's terms):
white noise N, bias instability B as flicker over ``bias_tau_range_s``, rate random
walk K, and quantization Q / rate ramp R where the fit kept them. A term the noise.json
gives only as an upper bound (its ``noise.selected`` status ``upper_bound``) is
simulated with the fit's value, or not at all when the fit removed it; the notes say
which, and the trip's ``drive.yaml`` names the noise.json so that the estimator bounds
with its selected terms (the upper bounds included).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from imubounds.errors import InputError
from imubounds.stationary.noise_sim import TERMS, AxisNoise, NoiseSpec

if TYPE_CHECKING:
    from imubounds.dynamic.scenario.config import ScenarioConfig

CHANNELS: tuple[str, ...] = ("accel_x", "accel_y", "accel_z", "gyro_x", "gyro_y", "gyro_z")


@dataclass(frozen=True)
class ImuNoise:
    """Per channel the simulated :class:`AxisNoise` (SI), where it came from, and notes."""

    axes: dict[str, AxisNoise]
    source: str
    notes: tuple[str, ...] = ()


def _read(path: str) -> dict[str, Any]:
    p = Path(path)
    try:
        doc = json.loads(p.read_text())
    except OSError as err:
        raise InputError(
            f"--imu-noise {p}: cannot read ({err.strerror}); give the noise.json of "
            "'imubounds static'"
        ) from None
    except json.JSONDecodeError as err:
        raise InputError(
            f"--imu-noise {p}: not valid JSON ({err.msg}, line {err.lineno})"
        ) from None
    if not isinstance(doc, dict):
        raise InputError(f"--imu-noise {p}: not a noise.json of 'imubounds static'")
    return doc


def _upper_bound_notes(doc: dict[str, Any], spec: NoiseSpec) -> list[str]:
    """What was simulated for each term the noise.json gives only as an upper bound."""
    notes = []
    for ch, ax in spec.channels.items():
        sel = ((doc["channels"].get(ch) or {}).get("noise") or {}).get("selected") or {}
        for t in TERMS:
            e = sel.get(t) or {}
            if e.get("status") != "upper_bound" or not e.get("value"):
                continue
            used = getattr(ax, t)
            what = (
                f"simulated with the fit's value {used:.3g}" if used > 0
                else "not simulated (the fit removed it)"
            )
            notes.append(
                f"{ch} {t}: the noise.json gives only an upper bound ({float(e['value']):.3g} "
                f"{e.get('unit', 'SI')}): {what}; the estimator bounds with the upper bound"
            )
    return notes


def load_imu_noise(cfg: ScenarioConfig) -> ImuNoise:
    """The noise of ``cfg.imu_noise`` per channel (:class:`InputError` names the file)."""
    assert cfg.imu_noise is not None
    path = str(cfg.imu_noise)
    doc = _read(path)
    try:
        spec = NoiseSpec.from_noise_json(
            doc, terms="fit", bias_tau_range_s=cfg.bias_tau_range_s, source=path
        )
    except InputError as err:
        raise InputError(f"--imu-noise {err}") from None
    missing = [c for c in CHANNELS if c not in spec.channels]
    if missing:
        raise InputError(
            f"--imu-noise {path}: no noise for {', '.join(missing)}; characterise a log with "
            "all six channels (gyro and accel x, y, z)"
        )
    empty = [c for c in CHANNELS if spec.channels[c].N <= 0]
    if empty:
        raise InputError(f"--imu-noise {path}: {', '.join(empty)} has no white noise N")
    notes = _upper_bound_notes(doc, spec)
    rate = spec.rate_hz
    if rate and not math.isclose(rate, cfg.rate_hz, rel_tol=1e-6):
        notes.append(
            f"the noise.json was measured at {rate:g} Hz, the trip's IMU runs at "
            f"{cfg.rate_hz:g} Hz: the noise densities are kept (white noise per sample "
            "scales with sqrt(rate))"
        )
    return ImuNoise(
        axes={c: spec.channels[c] for c in CHANNELS},
        source=f"noise.json {path} (fit terms, flicker band {cfg.bias_tau_range_s[0]:g}-"
        f"{cfg.bias_tau_range_s[1]:g} s)",
        notes=tuple(notes),
    )


def preset_noise(cfg: ScenarioConfig) -> ImuNoise:
    """The preset's figures on the three axes of each sensor (N, B, K; no Q or R)."""
    from imubounds.presets import get_preset

    p = get_preset(cfg.imu_preset)
    axes = {}
    for ch in CHANNELS:
        f = p.kind(ch.split("_")[0])
        axes[ch] = AxisNoise(
            N=f["N"], B=f["B"], K=f.get("K", 0.0), bias_tau_range_s=cfg.bias_tau_range_s
        )
    return ImuNoise(axes=axes, source=f"preset {p.key} ({p.name})")
