"""Real-vehicle drives end to end (issue 24, "done when"): ``imubounds simulate`` writes a
drive the way a real logger would (the IMU in its own rotated axes with ``imu_axes`` in
drive.yaml, a wheel odometry whose stamps lag 0.3 s, an AHRS attitude stream with yaw),
then ``imubounds dynamic`` reads it back.

* ground robot (GNSS position + velocity, wheel odometry, AHRS roll/pitch/yaw): accel_x
  median half-width <= 1 m/s^2 at tau ~ 10 s, no exceedance on the clean drive; +1 m/s^2
  on accel_x or +0.05 rad/s on gyro_z from mid-log gives ``exceeds`` on that channel
  only;
* quadrotor-like trip (kind ``air``, pitch up to 13 deg, no stated tilt: the default of
  10 deg is exceeded): runs, and every channel's margins are finite.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest

import imubounds.cli as cli

#: a small ground robot: 450 m in 300 s (1.5 m/s), sharp 20 m corners
ROBOT = [
    "--duration", "300", "--distance", "450", "--corner-length", "20",
    "--aiding", "gnss,gnss-vel,wheel,attitude", "--attitude-yaw", "0.5",
    "--imu-axes", "x,-z,y", "--velocity-lag", "0.3", "--imu-preset", "industrial",
]


@pytest.fixture()
def main(monkeypatch: pytest.MonkeyPatch):  # type: ignore[no-untyped-def]
    mods = tuple(dict.fromkeys((*cli.COMMAND_MODULES, "dynamic", "simulate")))
    monkeypatch.setattr(cli, "COMMAND_MODULES", mods)
    return cli.main


def _run(main: Any, tmp: Path, sim_args: list[str], edit: Any = None) -> dict[str, Any]:
    drive = tmp / "drive"
    assert main(["simulate", "-o", str(drive), "-q", *sim_args]) == 0
    if edit is not None:
        edit(drive)
    out = tmp / "out"
    assert main(["dynamic", str(drive), "--mode", "full", "-o", str(out), "--no-report"]) == 0
    doc = json.loads((out / "dynamic.json").read_text())
    full: dict[str, Any] = doc["modes"]["full"]
    return full


def _at(full: dict[str, Any], ch: str, tau: float) -> dict[str, Any]:
    rows = full["margins"][ch]
    row: dict[str, Any] = min(rows, key=lambda r: abs(math.log(r["tau_s"] / tau)))
    return row


def test_rotated_imu_is_written_in_sensor_axes(main, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    """The simulated robot's imu.csv is in the sensor's axes (gravity on +y for
    imu_axes x,-z,y) and its odometry stamps are 0.3 s late."""
    d = tmp_path / "drive"
    short = [*ROBOT, "--duration", "100", "--distance", "150"]
    assert main(["simulate", "-o", str(d), "-q", *short]) == 0
    imu = pd.read_csv(d / "imu.csv")
    assert abs(float(imu["accel_y_mps2"].median()) - 9.8) < 0.2
    assert abs(float(imu["accel_z_mps2"].median())) < 0.5
    assert "- -z" in (d / "drive.yaml").read_text()
    scen = json.loads((d / "scenario.json").read_text())
    assert scen["true_values"]["aiding"]["velocity"]["lag_s"] == 0.3
    assert any(f["kind"] == "lag" for f in scen["record"]["faults"])  # not a clean record
    vel = pd.read_csv(d / "velocity.csv")
    assert float(vel["time_s"].iloc[0]) == pytest.approx(0.3)
    # the same drive with imu_axes left out of drive.yaml: the rotated mount does not pass
    # silently (the input warnings name the imu_axes that fits; not guaranteed)
    y = d / "drive.yaml"
    lines = y.read_text().splitlines(True)
    i = next(k for k, x in enumerate(lines) if x.startswith("imu_axes:"))
    y.write_text("".join(lines[:i] + lines[i + 4:]))
    out = tmp_path / "out"
    assert main(["dynamic", str(d), "--mode", "full", "-o", str(out), "--no-report"]) == 0
    doc = json.loads((out / "dynamic.json").read_text())
    assert any("imu_axes [x, -z, y]" in w for w in doc["input"]["warnings"])
    assert doc["modes"]["full"]["guaranteed"] is False


def test_ground_robot_clean(main, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    full = _run(main, tmp_path, ROBOT)
    row = _at(full, "accel_x", 10.0)
    assert row["halfwidth_median"] <= 1.0, row
    assert "exceeds" not in full["verdict"].values(), full["verdict"]
    assert full["enclosure"]["heading"] == 1.0
    assert full["enclosure"]["u"] == 1.0
    # the AHRS yaw serves as the heading and is flagged as not independent of the gyro
    assert any("AHRS" in n for n in full["notes"])


@pytest.mark.slow
@pytest.mark.parametrize("ch, value", [("accel_x", 1.0), ("gyro_z", 0.05)])
def test_ground_robot_fault_from_mid_log(main, tmp_path: Path, ch: str, value: float) -> None:  # type: ignore[no-untyped-def]
    full = _run(main, tmp_path, [*ROBOT, "--fault", f"{ch}:bias={value}@150"])
    assert full["verdict"][ch] == "exceeds", full["verdict"]
    others = {k: v for k, v in full["verdict"].items() if k != ch}
    assert "exceeds" not in others.values(), full["verdict"]


@pytest.mark.slow
def test_lagging_odometry_on_a_fast_vehicle_is_found(main, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    """On the robot the 0.3 s lag moves the speed by < 0.02 m/s (inside the odometry's
    bound); on a 10 m/s vehicle braking for 20 m corners it is ~0.6 m/s. The braking
    pins the odometry's clock (sensors/_speed_clock.py): the offset is estimated within
    0.05 s, its interval holds 0.3 s, it is applied and its remainder budgeted, and the
    truth is inside at every epoch of the guaranteed run. The control without the lag:
    its interval holds 0, nothing is applied."""
    fast = [*ROBOT, "--distance", "3000"]
    full = _run(main, tmp_path / "lag", fast)
    tv = full["timing"]["velocity"]
    lo, hi = tv["interval_s"]
    assert tv["applied"] is True and abs(tv["estimate_s"] - 0.3) <= 0.05, tv
    assert lo <= 0.3 <= hi and hi - lo < 0.1, tv
    assert tv["offset_s"] == tv["estimate_s"] and tv["remainder_s"] <= hi - lo
    assert full["guaranteed"] is True, full["violations"]
    assert all(full["enclosure"][k] == 1.0 for k in ("position", "heading", "u", "v"))
    ok = _run(main, tmp_path / "no_lag", [*fast, "--velocity-lag", "0"])  # the control
    tv = ok["timing"]["velocity"]
    assert tv["applied"] is False and tv["interval_s"][0] <= 0.0 <= tv["interval_s"][1]
    assert ok["guaranteed"] is True
    assert ok["enclosure"]["u"] == 1.0


def _drop_stated_tilt(d: Path) -> None:
    y = d / "drive.yaml"
    y.write_text("".join(x for x in y.read_text().splitlines(True) if "max_tilt_deg" not in x))


def test_quadrotor_pitch_beyond_the_tilt_cap(main, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    """Pitch up to 13 deg with no stated tilt (the default is 10 deg): no internal error,
    the tilt bound comes from the attitude stream, finite margins on every channel."""
    args = [
        "--variant", "hills", "--duration", "120", "--distance", "300",
        "--corner-length", "20", "--hill-amplitude", "1.0", "--rate", "50",
        "--aiding", "gnss,gnss-vel,attitude", "--attitude-yaw", "0.5",
        "--vehicle-kind", "air", "--imu-preset", "industrial",
    ]
    full = _run(main, tmp_path, args, edit=_drop_stated_tilt)
    assert full["vehicle"]["kind"] == "air"
    assert full["vehicle"]["sources"]["max_tilt"] == "data: attitude stream"
    assert full["vehicle"]["max_tilt_deg"] > 12.0
    for ch, rows in full["margins"].items():
        assert rows, ch
        hw = np.array([r["halfwidth_median"] for r in rows])
        assert np.all(np.isfinite(hw)), ch


# ------------------------------------------------------------------------- comma2k19


def _comma_pitch(d: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """From ``global_pose`` alone (no imubounds code): the phone's pitch (its x axis above
    the local horizontal), the elevation of its velocity, and the times."""

    def load(rel: str) -> np.ndarray:
        with open(d / rel, "rb") as fh:
            return np.asarray(np.load(fh, allow_pickle=False), dtype=float)

    t = load("global_pose/frame_times")
    pos = load("global_pose/frame_positions")
    vel = load("global_pose/frame_velocities")
    w, x, y, z = load("global_pose/frame_orientations").T  # (w, x, y, z), body -> ECEF
    fwd = np.stack([1 - 2 * (y * y + z * z), 2 * (x * y + w * z), 2 * (x * z - w * y)], -1)
    up = pos / np.linalg.norm(pos, axis=1)[:, None]  # local vertical (sphere: < 0.2 deg)
    pitch = np.arcsin(np.einsum("ij,ij->i", fwd, up))
    v_up = np.einsum("ij,ij->i", vel, up)
    v_h = np.linalg.norm(vel - v_up[:, None] * up, axis=1)
    return t, pitch, np.arctan2(v_up, v_h)


@pytest.mark.slow
def test_comma2k19_tilt_bound_and_what_bounds_accel_x(shared_data: Path) -> None:
    """comma2k19 (issue 24's "done when": accel_x <= 0.5 m/s^2 at tau = 10 s): the tilt
    bound used encloses the phone's true pitch at every epoch, the accel_x interval at
    tau ~ 10 s is gravity through the default tilt plus ~0.2 m/s^2 plus the q w term, and
    the notes name the
    default tilt as the dominant term. The truth shows why the data cannot give a tighter
    tilt: the phone sits ~3.75 deg nose-down against its velocity (a constant the
    accelerometer cannot tell from its bias), so a zero-centred bound needs >= 6 deg,
    and 0.5 m/s^2 would need the pitch to +-1.76 deg at every epoch."""
    from imubounds.cli.dynamic import load_drive
    from imubounds.dynamic.estimator import dynamic_margins

    d = shared_data / "dynamic" / "comma2k19_example1"
    t, pitch, elev = _comma_pitch(d)
    beta = pitch - elev
    assert -4.5 < float(np.degrees(beta.mean())) < -3.0  # the mount, not the road
    assert float(np.degrees(np.abs(pitch).max())) > 6.0
    full = dynamic_margins(load_drive([str(d)])).to_dict()
    tilt = math.radians(full["vehicle"]["max_tilt_deg"])
    assert np.all(np.abs(pitch) <= tilt)  # the tilt input encloses the truth
    row = _at(full, "accel_x", 10.0)
    grav = 9.84 * math.sin(tilt)
    # q w: the reader's vertical bound (the phone's mount pitch x speed) x mean|gyro_y|
    qw = 0.25 * full["vehicle"]["vertical_speed_bound_mps"]
    assert grav <= row["halfwidth_median"] <= grav + 0.3 + qw, row
    notes = full["verdict_detail"]["accel_x"]["notes"]
    assert any("default maximum tilt" in n and "mount pitch" in n for n in notes), notes
    for q in ("position", "heading", "speed", "u", "v"):
        assert full["enclosure"][q] == 1.0, q


def test_simulator_mount_options_are_checked() -> None:
    from imubounds.dynamic.scenario import ScenarioConfig
    from imubounds.errors import OptionError

    with pytest.raises(OptionError, match="imu-axes"):
        ScenarioConfig(imu_axes=("x", "x", "z")).check()
    with pytest.raises(OptionError, match="vehicle kind"):
        ScenarioConfig(vehicle_kind="boat").check()
    with pytest.raises(OptionError, match="velocity_lag_s"):
        ScenarioConfig(velocity_lag_s=-0.1).check()
    ScenarioConfig(imu_axes=("x", "-z", "y"), vehicle_kind="air", velocity_lag_s=0.3).check()


# --------------------------------------------------------------------------- VN-100


@pytest.mark.slow
def test_vn100_what_dominates_accel_x(shared_data: Path) -> None:
    """The bundled VN-100 drive (a car circling, 1 Hz GNSS of +-11.8 m, AHRS at 40 Hz):
    accel_x is the vehicle-only level (+-10.2 m/s^2) because nothing bounds the side slip;
    the notes say so, and a car's lateral bound (0.5 m/s, stated) brings it under
    2.5 m/s^2 at tau ~ 12.6 s. The AHRS's roll/pitch bound is the default, and said."""
    from imubounds.cli.dynamic import load_drive
    from imubounds.dynamic.estimator import dynamic_margins

    d = shared_data / "dynamic" / "vn100_bu353_circle"
    full = dynamic_margins(load_drive([str(d)])).to_dict()
    assert _at(full, "accel_x", 12.6)["halfwidth_median"] > 8.0
    notes = full["verdict_detail"]["accel_x"]["notes"]
    assert any("lateral_speed_bound_mps" in n for n in notes), notes
    assert full["aiding_budget"]["attitude"][0]["source"] == "default"
    # gyro_x's psi' sin(pitch) from the heading's mean rate: +-0.013 rad/s (was +-0.032)
    assert _at(full, "gyro_x", 12.6)["halfwidth_median"] < 0.02
    car = dynamic_margins(load_drive([str(d)]), lateral_speed_bound_mps=0.5).to_dict()
    assert _at(car, "accel_x", 12.6)["halfwidth_median"] < 2.5
    for ch, rows in car["margins"].items():
        assert all(math.isfinite(r["halfwidth_median"]) for r in rows), ch
