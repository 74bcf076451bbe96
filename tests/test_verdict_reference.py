"""The reference verdicts are judged against (issue 24, item 5): without noise figures the
margins are given but the verdicts are ``no reference``; the bias table says
"contracted" only where the interval is narrower than its prior."""

from __future__ import annotations

import dataclasses

import pytest

from imubounds.dynamic.estimator import dynamic_margins
from imubounds.dynamic.estimator.verdicts import NO_REFERENCE
from imubounds.dynamic.scenario import make_trip

SHORT = {"duration_s": 200.0, "distance_m": 2400.0, "rate_hz": 50.0}


@pytest.fixture(scope="module")
def bare_drive():  # type: ignore[no-untyped-def]
    """The simulated paper trip with every IMU noise figure removed from drive.yaml."""
    drive = make_trip("paper", seed=8, **SHORT).drive
    imu = drive.settings.imu
    blank = {f.name: None for f in dataclasses.fields(imu)
             if f.name.startswith(("accel_", "gyro_")) or f.name in ("preset", "noise_json")}
    drive.settings = dataclasses.replace(
        drive.settings, imu=dataclasses.replace(imu, **blank)
    )
    return drive


def test_no_noise_figures_no_verdict(bare_drive) -> None:  # type: ignore[no-untyped-def]
    d = dynamic_margins(bare_drive).to_dict()
    for ch in ("accel_x", "accel_y", "gyro_z"):
        assert d["verdict"][ch] == NO_REFERENCE, ch
        det = d["verdict_detail"][ch]
        assert "--static noise.json" in det["reason"] and "--imu-spec" in det["reason"]
        assert det["verdict_against_default_band"] in ("consistent", "exceeds", "undecided")
        assert any(r["halfwidth_median"] is not None for r in d["margins"][ch])  # still given


def test_a_named_preset_is_a_reference(bare_drive) -> None:  # type: ignore[no-untyped-def]
    d = dynamic_margins(bare_drive, imu_spec="mtx").to_dict()
    assert NO_REFERENCE not in d["verdict"].values()
    for ch, b in d["bias"].items():
        narrower = b["constant_part"][1] - b["constant_part"][0] < (
            b["constant_part_prior"][1] - b["constant_part_prior"][0]
        ) * (1 - 1e-9)
        assert narrower == b["source"].startswith("contracted"), (ch, b)
