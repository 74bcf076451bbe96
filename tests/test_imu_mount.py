"""A rotated IMU mount never passes silently (issue 24, item 3): ``convert`` and
``dynamic`` say when gravity is not on body +z and which ``imu_axes`` fits."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import imubounds.cli as cli
from imubounds.dynamic.imu_mount import fitting_axes, mount_warning
from imubounds.frames import axes_matrix, rotate_axes
from imubounds.io.drive.layout import write_layout
from tests.trips import make_trip


@pytest.fixture()
def main(monkeypatch: pytest.MonkeyPatch):  # type: ignore[no-untyped-def]
    mods = tuple(dict.fromkeys((*cli.COMMAND_MODULES, "dynamic", "convert")))
    monkeypatch.setattr(cli, "COMMAND_MODULES", mods)
    return cli.main


@pytest.mark.parametrize(
    "axes",
    [("x", "-z", "y"), ("x", "z", "-y"), ("z", "y", "-x"), ("-y", "x", "z"), ("y", "x", "-z")],
)
def test_fitting_axes_puts_gravity_up(axes: tuple[str, str, str]) -> None:
    """Body specific force mostly +z; the sensor sees it through a mount ``axes``
    (v_body = R v_sensor): the fitted axes bring it back onto +z."""
    f_body = np.array([[0.3, -0.2, 9.8]])
    sensor = f_body @ axes_matrix(axes)  # R^T v_body
    mean_seen = sensor[0]  # read with imu_axes = identity
    fit = fitting_axes(mean_seen, ("x", "y", "z"))
    back = rotate_axes(sensor, axes_matrix(fit))[0]
    assert back[2] == pytest.approx(9.8)
    assert np.linalg.det(axes_matrix(fit)) == pytest.approx(1.0)


def test_convert_and_dynamic_name_the_fitting_axes(
    main, tmp_path: Path, capsys: pytest.CaptureFixture  # type: ignore[no-untyped-def]
) -> None:
    drive, _ = make_trip("paper", 3, duration_s=120.0, distance_m=1300.0, corner_m=60.0,
                         imu_hz=20.0)
    src = write_layout(drive, tmp_path / "trip")
    assert mount_warning(drive) is None  # the body-frame drive passes
    # the IMU on its side: body z along IMU +y, body y along IMU -z (imu_axes [x, -z, y])
    imu = pd.read_csv(src / "imu.csv")
    for kind in ("accel", "gyro"):
        cols = [c for c in imu.columns if c.startswith(kind)]
        body = imu[cols].to_numpy()
        imu[cols] = body @ axes_matrix(("x", "-z", "y"))
    imu.to_csv(src / "imu.csv", index=False)
    out = tmp_path / "conv"
    assert main(["convert", str(src), "-o", str(out)]) == 0
    err = capsys.readouterr().err
    assert "warning" in err and "imu_axes [x, -z, y] puts gravity on body +z" in err
    # dynamic reads the drive through load_drive: the warning goes to dynamic.json's
    # input.warnings and the console with the drive's other warnings
    from imubounds.cli.dynamic import load_drive

    warned = load_drive([str(src)]).warnings
    assert any("imu_axes [x, -z, y] puts gravity on body +z" in w for w in warned)
