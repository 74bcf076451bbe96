"""Datasheet presets of IMUs: the one place where a sensor's published figures live.

Each preset gives, per sensor kind (``gyro``, ``accel``), the datasheet figures
in SI units:

``N``
    white-noise density (rad/s/sqrt(Hz) = rad/s^0.5; m/s^2/sqrt(Hz) = m/s^1.5),
    the angle / velocity random walk coefficient;
``B``
    in-run bias stability (rad/s; m/s^2), the flicker floor of the Allan deviation
    as datasheets quote it;
``K`` (optional)
    rate random walk (rad/s^1.5; m/s^2.5);
``turn_on_bias`` (optional)
    bias repeatability from one switch-on to the next (rad/s; m/s^2);
``scale_factor`` (optional)
    scale-factor error bound as a fraction (0.01 = 1 %);
``misalignment_rad`` (optional)
    axis misalignment / mounting alignment error (rad).

The noise simulator (:mod:`imubounds.stationary.noise_sim`), the trip simulator
(:mod:`imubounds.dynamic.scenario`) and the dynamic estimator all read their
presets from here.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

from imubounds.errors import OptionError
from imubounds.units import DEG, G0

_MG = G0 * 1e-3  # one milli-g in m/s^2


@dataclass(frozen=True)
class ImuPreset:
    """A sensor's datasheet figures in SI (see the module docstring for the keys)."""

    key: str
    name: str
    gyro: Mapping[str, float]
    accel: Mapping[str, float]
    aliases: tuple[str, ...] = field(default=())

    def kind(self, kind: str) -> dict[str, float]:
        """The figures of one sensor kind (``"gyro"`` or ``"accel"``) as a new dict."""
        return dict(self.gyro if kind == "gyro" else self.accel)

    def noise_mapping(self) -> dict[str, object]:
        """The preset as a noise-simulator mapping (N, B and K where given, with units)."""
        gyro = {
            "N": f"{self.gyro['N'] / DEG:g} deg/s/sqrt(Hz)",
            "B": f"{self.gyro['B'] / DEG:g} deg/s",
        }
        accel = {
            "N": f"{self.accel['N']:g} m/s^2/sqrt(Hz)",
            "B": f"{self.accel['B']:g} m/s^2",
        }
        if "K" in self.gyro:
            gyro["K"] = f"{self.gyro['K'] / DEG:g} deg/s^1.5"
        if "K" in self.accel:
            accel["K"] = f"{self.accel['K']:g} m/s^2.5"
        return {"name": self.name, "gyro": gyro, "accel": accel}


def _p(
    key: str,
    name: str,
    gyro: dict[str, float],
    accel: dict[str, float],
    aliases: tuple[str, ...] = (),
) -> ImuPreset:
    return ImuPreset(key, name, MappingProxyType(gyro), MappingProxyType(accel), aliases)


#: Xsens MTx (the paper's sensor, METHOD.md 3.5): accelerometer 0.002 m/s^2/sqrt(Hz),
#: bias stability 0.02 m/s^2; gyro 0.05 deg/s/sqrt(Hz), bias stability 1 deg/s;
#: alignment error 0.1 deg.
XSENS_MTX = _p(
    "xsens-mtx",
    "Xsens MTx datasheet (METHOD.md 3.5)",
    gyro={"N": 0.05 * DEG, "B": 1.0 * DEG, "misalignment_rad": 0.1 * DEG},
    accel={"N": 0.002, "B": 0.02, "misalignment_rad": 0.1 * DEG},
    aliases=("mtx",),
)

#: VectorNav VN-100 datasheet: accelerometer 0.14 mg/sqrt(Hz), in-run bias stability
#: 0.04 mg; gyro 0.0035 deg/s/sqrt(Hz), 10 deg/h.
VN100 = _p(
    "vn100",
    "VectorNav VN-100 datasheet",
    gyro={"N": 0.0035 * DEG, "B": 10.0 * DEG / 3600.0},
    accel={"N": 0.14 * _MG, "B": 0.04 * _MG},
    aliases=("vn-100",),
)

# Representative sensor grades (not one product each): the known-truth tests of the
# stationary analysis simulate them. N and B are typical datasheet figures of the
# grade; K is chosen so that the rate random walk overtakes the flicker floor
# (K^2 tau/3 = (2 ln2/pi) B^2) at a stated tau, within a 1-3 h log for the
# industrial and consumer grades and near its end for the tactical one.

#: Tactical-grade MEMS IMU: gyro ARW 0.04 deg/sqrt(h), bias instability 0.45 deg/h,
#: K overtakes B at 3000 s; accelerometer VRW 0.03 m/s/sqrt(h), 25 ug, K at 1000 s.
TACTICAL = _p(
    "tactical",
    "tactical-grade MEMS IMU (representative figures)",
    gyro={"N": 0.04 * DEG / 60.0, "B": 0.45 * DEG / 3600.0, "K": 4.583e-08},
    accel={"N": 0.03 / 60.0, "B": 25e-6 * G0, "K": 8.92e-06},
)

#: Industrial-grade MEMS IMU: gyro ARW 0.15 deg/sqrt(h), 3 deg/h, K at 200 s;
#: accelerometer VRW 0.04 m/s/sqrt(h), 25 ug, K at 300 s.
INDUSTRIAL = _p(
    "industrial",
    "industrial-grade MEMS IMU (representative figures)",
    gyro={"N": 0.15 * DEG / 60.0, "B": 3.0 * DEG / 3600.0, "K": 1.183e-06},
    accel={"N": 0.04 / 60.0, "B": 25e-6 * G0, "K": 1.629e-05},
)

#: Consumer-grade MEMS IMU (phone / drone class): gyro 0.014 deg/s/sqrt(Hz), 20 deg/h,
#: K at 150 s; accelerometer 150 ug/sqrt(Hz), 40 ug, K at 400 s.
CONSUMER = _p(
    "consumer",
    "consumer-grade MEMS IMU (representative figures)",
    gyro={"N": 0.014 * DEG, "B": 20.0 * DEG / 3600.0, "K": 9.109e-06},
    accel={"N": 150e-6 * G0, "B": 40e-6 * G0, "K": 2.257e-05},
)

PRESETS: Mapping[str, ImuPreset] = MappingProxyType(
    {p.key: p for p in (XSENS_MTX, VN100, TACTICAL, INDUSTRIAL, CONSUMER)}
)


def get_preset(name: str) -> ImuPreset:
    """A preset by key or alias (case-insensitive); :class:`OptionError` names the choices."""
    key = name.strip().lower()
    for p in PRESETS.values():
        if key == p.key or key in p.aliases:
            return p
    names = sorted({*PRESETS, *(a for p in PRESETS.values() for a in p.aliases)})
    raise OptionError(f"unknown IMU preset {name!r}; available: {', '.join(names)}")


def preset_names() -> list[str]:
    """Keys and aliases of every preset."""
    return sorted({*PRESETS, *(a for p in PRESETS.values() for a in p.aliases)})


assert math.isclose(XSENS_MTX.gyro["N"], 0.05 * math.pi / 180.0)
