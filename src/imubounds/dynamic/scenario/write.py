"""Write a simulated trip: the generic drive layout, ``compass_cal.csv`` and ``scenario.json``."""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd
import yaml

from imubounds.dynamic.scenario.core import SimResult
from imubounds.frames import axes_matrix, is_identity_axes
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
    if not is_identity_axes(res.config.imu_axes):
        _rotate_written_imu(d, res.config.imu_axes)
    doc = to_jsonable(res.to_json())
    (d / "scenario.json").write_text(json.dumps(doc, indent=1, allow_nan=False))
    return d


def _rotate_written_imu(d: Path, imu_axes: tuple[str, str, str]) -> None:
    """Rewrite ``imu.csv`` in the sensor's axes (``v_sensor = R^T v_body``, R from
    ``imu_axes``) and state ``imu_axes`` in ``drive.yaml``, so that a reader rotates it
    back to the body axes (a unit mounted on its side, upside down, backwards...)."""
    rot = axes_matrix(imu_axes)
    df = pd.read_csv(d / "imu.csv", float_precision="round_trip")
    for kind, unit in (("gyro", "rads"), ("accel", "mps2")):
        cols = [f"{kind}_{ax}_{unit}" for ax in "xyz"]
        body = df[cols].to_numpy(dtype=float)
        df[cols] = body @ rot  # row-wise R^T v
    df.to_csv(d / "imu.csv", index=False)
    text = (d / "drive.yaml").read_text(encoding="utf-8")
    head = "".join(line + "\n" for line in text.splitlines() if line.startswith("#"))
    doc = yaml.safe_load(text)
    doc["imu_axes"] = list(imu_axes)
    notes = list(doc.get("notes") or [])
    notes.append(
        f"simulated mount: imu.csv is in the sensor's axes, imu_axes {list(imu_axes)} "
        "maps them to the body"
    )
    doc["notes"] = notes
    (d / "drive.yaml").write_text(
        head + yaml.safe_dump(doc, sort_keys=False, allow_unicode=True), encoding="utf-8"
    )
