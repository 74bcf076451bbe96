"""Write a simulated trip: the generic drive layout, ``compass_cal.csv`` and ``scenario.json``."""

from __future__ import annotations

import json
from pathlib import Path

from imubounds.dynamic.scenario.core import SimResult
from imubounds.io.drive.layout import write_layout
from imubounds.io.outputs import to_jsonable

#: Files a simulation may write (the drive layout's, the calibration, the scenario).
OUTPUT_FILES: tuple[str, ...] = (
    "imu.csv",
    "gnss.csv",
    "velocity.csv",
    "heading.csv",
    "attitude.csv",
    "truth.csv",
    "drive.yaml",
    "compass_cal.csv",
    "imu_noise.json",
    "scenario.json",
)


def write_scenario(res: SimResult, out_dir: str | Path) -> Path:
    """Write ``res`` into the directory ``out_dir`` (created if needed): the drive layout
    (:func:`imubounds.io.drive.layout.write_layout`), the compass swing calibration that
    ``drive.yaml: heading.calibration`` names, and ``scenario.json`` (configuration, seed,
    conventions, every true error term, the record of inputs outside their bounds).

    Callers that need the set to land complete or not at all write into an
    :class:`imubounds.io.outputs.OutputSet` staging directory.
    """
    d = Path(out_dir)
    write_layout(res.drive, d)  # with the compass swing calibration
    doc = to_jsonable(res.to_json())
    (d / "scenario.json").write_text(json.dumps(doc, indent=1, allow_nan=False))
    return d
