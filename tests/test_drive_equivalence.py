"""Issue 12's equivalences, checked on the dynamic result itself (not only on the Drive):

* a drive written with a rotated IMU and the matching ``imu_axes`` gives the same margins,
  verdicts and bias intervals as the drive in body axes;
* ``imubounds convert`` then ``dynamic`` on the converted layout gives the same result as
  ``dynamic`` on the source.
"""

from __future__ import annotations

import shutil
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest
import yaml

from imubounds.cli import main
from imubounds.dynamic.estimator import dynamic_margins
from imubounds.dynamic.scenario import make_trip
from imubounds.io import read_drive
from imubounds.io.drive.layout import write_layout


def _essence(d: dict[str, Any]) -> dict[str, Any]:
    """What a user reads off a dynamic result (paths and file names left out)."""
    return {k: d.get(k) for k in ("margins", "verdict", "bias", "enclosure", "budget")}


def _assert_same(a: dict[str, Any], b: dict[str, Any]) -> None:
    ea, eb = _essence(a), _essence(b)
    assert ea["verdict"] == eb["verdict"]
    assert set(ea["margins"]) == set(eb["margins"])
    for ch, rows in ea["margins"].items():
        other = eb["margins"][ch]
        assert len(rows) == len(other), ch
        for ra, rb in zip(rows, other, strict=True):
            for key in ("tau_s", "halfwidth_median", "halfwidth_max", "stationary"):
                va, vb = ra.get(key), rb.get(key)
                if va is None or vb is None:
                    assert va == vb, (ch, key)
                else:
                    np.testing.assert_allclose(va, vb, rtol=1e-9, err_msg=f"{ch} {key}")
    assert ea["bias"].keys() == eb["bias"].keys()
    for ch in ea["bias"]:
        np.testing.assert_allclose(
            ea["bias"][ch]["constant_part"], eb["bias"][ch]["constant_part"], rtol=1e-9,
            err_msg=ch,
        )


def test_rotated_mount_gives_the_same_margins(tmp_path: Path) -> None:
    sim = make_trip("paper", seed=4, duration_s=200.0, distance_m=2000.0)
    body = write_layout(sim.drive, tmp_path / "body")
    rot = tmp_path / "rot"
    shutil.copytree(body, rot)
    imu_file = next(p for p in rot.iterdir() if p.name.startswith("imu."))
    imu = pd.read_csv(imu_file)
    # mounted with IMU y along body -z and IMU z along body y: imu_axes [x, -z, y] says
    # "body x = IMU x, body y = -IMU z, body z = IMU y"; the readings in IMU axes are then
    for kind in ("accel", "gyro"):
        unit = "mps2" if kind == "accel" else "rads"
        bx, by, bz = (imu[f"{kind}_{a}_{unit}"].to_numpy() for a in "xyz")
        imu[f"{kind}_x_{unit}"], imu[f"{kind}_y_{unit}"], imu[f"{kind}_z_{unit}"] = bx, bz, -by
    imu.to_csv(imu_file, index=False, float_format="%.17g")
    settings_file = rot / "drive.yaml"
    doc = yaml.safe_load(settings_file.read_text()) or {}
    doc["imu_axes"] = ["x", "-z", "y"]
    settings_file.write_text(yaml.safe_dump(doc, sort_keys=False))
    a = dynamic_margins(read_drive(body)).to_dict()
    b = dynamic_margins(read_drive(rot)).to_dict()
    _assert_same(a, b)
    # the rotation did reach the IMU table: read with body axes it gives other margins
    doc["imu_axes"] = ["x", "y", "z"]
    settings_file.write_text(yaml.safe_dump(doc, sort_keys=False))
    c = dynamic_margins(read_drive(rot)).to_dict()
    with pytest.raises(AssertionError):
        _assert_same(a, c)


@pytest.mark.slow
def test_convert_then_dynamic_equals_dynamic_on_the_source(
    shared_data: Path, tmp_path: Path
) -> None:
    src = shared_data / "dynamic" / "comma2k19_example1"
    out = tmp_path / "layout"
    assert main(["convert", str(src), "-o", str(out), "-q"]) == 0
    a = dynamic_margins(read_drive(src)).to_dict()
    b = dynamic_margins(read_drive(out)).to_dict()
    _assert_same(a, b)
    assert a["enclosure"]["position"] == b["enclosure"]["position"] == 1.0


def test_paper_mode_on_a_simulated_drive_in_memory_equals_its_layout(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The simulator's drive carries its swing calibration as (n, 2) pairs in memory;
    mode paper reads them as it reads compass_cal.csv from the written layout."""
    sim = make_trip("paper", seed=5, duration_s=200.0, distance_m=2000.0)
    assert isinstance(sim.drive.settings.heading.calibration, np.ndarray)
    mem = dynamic_margins(sim.drive, mode="paper").to_dict()
    # a relative path, as `make demo` gives (the calibration file was joined to the
    # drive's folder twice: out/sim/out/sim/compass_cal.csv)
    monkeypatch.chdir(tmp_path)
    write_layout(sim.drive, Path("drive"))
    disk = dynamic_margins(read_drive(Path("drive")), mode="paper").to_dict()
    assert mem["guaranteed"] is False and "not guaranteed" in mem["statement"]
    assert mem["verdict"] == disk["verdict"]
    for ch, rows in mem["margins"].items():
        for ra, rb in zip(rows, disk["margins"][ch], strict=True):
            np.testing.assert_allclose(ra["halfwidth_median"], rb["halfwidth_median"],
                                       rtol=1e-6, err_msg=ch)
