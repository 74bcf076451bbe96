"""The options of mode full as a frozen dataclass (FullOptions), checked once at the
boundary (check_options: dynamic_margins' keywords, the command line)."""

from __future__ import annotations

import dataclasses
import re
from types import SimpleNamespace

import pytest

from imubounds.dynamic.estimator.options import (
    FULL_OPTION_NAMES,
    FullOptions,
    check_options,
)
from imubounds.errors import OptionError


def test_defaults_none_and_frozen() -> None:
    o = check_options({})
    assert o == FullOptions() and o.alpha == 0.01 and o.imu_stamp == "end"
    assert o.use_gnss is True and o.max_windows == 2048 and o.gnss_cep_m is None
    # None is the default (as a keyword left out), also when built directly
    assert check_options({"tol": None, "use_gnss": None}) == o
    assert FullOptions(tol=None, use_gnss=None) == o  # type: ignore[arg-type]
    with pytest.raises(dataclasses.FrozenInstanceError):
        o.alpha = 0.5  # type: ignore[misc]
    assert check_options(o) is o


@pytest.mark.parametrize(
    ("given", "message"),
    [
        ({"bogus": 1}, "unknown option(s) for mode full: bogus; known: accel_turn_on"),
        ({"alpha": 1.5}, "--alpha must lie in (0, 1), got 1.5"),
        ({"max_speed": -1.0}, "--max-speed must be positive, got -1.0"),
        ({"velocity_bound": float("nan")}, "--velocity-bound must be >= 0, got nan"),
        ({"scale": 0.5}, "--scale is a fraction (0.01 = 1 %) below 0.5"),
        ({"imu_stamp": "middle"}, "--imu-stamp must be end, start or centre, got 'middle'"),
        ({"max_windows": 0}, "max_windows and max_sweeps must be >= 1"),
    ],
)
def test_bad_options_are_refused_naming_them(given: dict[str, object], message: str) -> None:
    with pytest.raises(OptionError, match=re.escape(message)):
        check_options(given)
    if "bogus" not in given:  # the same checks when built directly
        with pytest.raises(OptionError, match=re.escape(message)):
            FullOptions(**given)  # type: ignore[arg-type]


def test_imu_stamp_from_drive_yaml_unless_given() -> None:
    st = SimpleNamespace(imu=SimpleNamespace(sample_time="start"))
    assert check_options({}, st).imu_stamp == "start"
    assert check_options({"imu_stamp": "centre"}, st).imu_stamp == "centre"
    assert check_options({}, SimpleNamespace(imu=SimpleNamespace(sample_time=None))).imu_stamp \
        == "end"


def test_every_field_is_documented_with_its_unit() -> None:
    doc = FullOptions.__doc__ or ""
    missing = [n for n in FULL_OPTION_NAMES if f"``{n}``" not in doc]
    assert not missing, missing


def test_options_object_and_keywords_do_not_mix() -> None:
    import imubounds as ib

    drive = ib.read_drive(ib.bundled_drive_log())
    with pytest.raises(OptionError, match="options= \\(a FullOptions\\) is for mode full"):
        ib.dynamic_margins(drive, options=FullOptions(), alpha=0.05)
    with pytest.raises(OptionError, match="is for mode full"):
        ib.dynamic_margins(drive, mode="paper", options=FullOptions())
