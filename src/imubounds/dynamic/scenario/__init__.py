"""Trip simulator with ground truth (METHOD.md 3.5).

:func:`simulate` turns a :class:`ScenarioConfig` into a :class:`SimResult`: the
trip as a :class:`~imubounds.io.drive.Drive` (IMU at 100 Hz in the body frame,
aiding streams, truth, and ``DriveSettings`` stating every bound the data were
drawn against) and a :class:`Record` of the inputs that fell outside those
bounds. :func:`write_scenario` writes it in the generic drive layout
(:mod:`imubounds.io.drive.layout`) with ``compass_cal.csv`` and ``scenario.json``;
``imubounds simulate`` does so from the command line.

* :mod:`.trajectory` -- 3-D rigid-body truth (path, speed, hills, attitude, body
  rate and specific force) and the IMU's period means;
* :mod:`.imu` -- IMU errors (turn-on bias, flicker bias drift, white noise, scale,
  misalignment, faults) and their stated bounds;
* :mod:`.aiding` -- GNSS position and velocity, compass, magnetometer, attitude,
  DVL and wheel speed;
* :mod:`.record` -- the out-of-bound record and its definitions;
* :mod:`.config` -- settings, named variants (:data:`VARIANTS`) and faults;

Example::

    from imubounds.dynamic.scenario import make_trip
    res = make_trip("hills", seed=3)
    res.drive            # the Drive the estimator consumes
    res.record.clean     # every input within its stated bound?
"""

from __future__ import annotations

from typing import Any

from imubounds.dynamic.scenario.config import (
    AIDING_STREAMS,
    DEFAULT_AIDING,
    VARIANTS,
    Fault,
    ScenarioConfig,
    parse_fault,
)
from imubounds.dynamic.scenario.core import CONVENTIONS, SimResult, simulate
from imubounds.dynamic.scenario.record import Check, Record
from imubounds.dynamic.scenario.write import OUTPUT_FILES, write_scenario


def make_trip(variant: str = "paper", seed: int = 0, **overrides: Any) -> SimResult:
    """Simulate the named variant (:data:`VARIANTS`) with ``seed`` and any other settings."""
    return simulate(ScenarioConfig.for_variant(variant, seed=seed, **overrides))


def closure_error(res: SimResult) -> float:
    """Horizontal distance (m) between the true start and end points of a trip."""
    return res.closure_error_m()


__all__ = [
    "AIDING_STREAMS",
    "CONVENTIONS",
    "Check",
    "DEFAULT_AIDING",
    "Fault",
    "OUTPUT_FILES",
    "Record",
    "ScenarioConfig",
    "SimResult",
    "VARIANTS",
    "closure_error",
    "make_trip",
    "parse_fault",
    "simulate",
    "write_scenario",
]
