"""Column-name recognition, unit parsing and --columns maps, with properties."""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from imubounds.errors import OptionError
from imubounds.io import parse_column_map, read_imu, recognise
from imubounds.io.columns import (
    ACCEL_BASES,
    ACCEL_UNIT_SYNONYMS,
    GYRO_BASES,
    GYRO_UNIT_SYNONYMS,
    MAP_KEYS,
    TIME_UNIT_SYNONYMS,
    normalise_unit,
    split_bracket_unit,
)
from imubounds.io.log import IMU_CHANNELS
from imubounds.units import ACCEL_UNITS, GYRO_UNITS

# --- examples --------------------------------------------------------------


@pytest.mark.parametrize(
    ("name", "canonical", "unit"),
    [
        ("gyro_x", "gyro_x", None),
        ("gyro_x_dps", "gyro_x", "deg/s"),
        ("Gyro_Y_rads", "gyro_y", "rad/s"),
        ("gyro_z_rad_s", "gyro_z", "rad/s"),
        ("accel_x_g", "accel_x", "g"),
        ("accel_y_mps2", "accel_y", "m/s^2"),
        ("acc_z_ms2", "accel_z", "m/s^2"),
        ("acc_x", "accel_x", None),
        ("w_RS_S_x [rad s^-1]", "gyro_x", "rad/s"),
        ("a_RS_S_z [m s^-2]", "accel_z", "m/s^2"),
        ("omega_y", "gyro_y", "rad/s"),
        ("alpha_z", "accel_z", "m/s^2"),
        ("field.angular_velocity.x", "gyro_x", None),
        ("field.linear_acceleration.z", "accel_z", None),
        ("gyroX", "gyro_x", None),
        ("accel_x (m/s²)", "accel_x", "m/s^2"),
        ("gyro_x [°/s]", "gyro_x", "deg/s"),
        ("gyro_x_mrad_s", "gyro_x", "mrad/s"),
        ("accel_x_mg", "accel_x", "mg"),
        ("time", "time", None),
        ("time_s", "time", "s"),
        ("t", "time", None),
        ("t_ms", "time", "ms"),
        ("timestamp_us", "time", "us"),
        ("time_ns", "time", "ns"),
        ("#timestamp [ns]", "time", "ns"),
        ("%time", "time", "ns"),
        ("field.header.stamp", "time", "ns"),
    ],
)
def test_recognise_examples(name: str, canonical: str, unit: str | None) -> None:
    rec = recognise(name)
    assert rec is not None, name
    assert (rec.canonical, rec.unit) == (canonical, unit)


@pytest.mark.parametrize(
    "name",
    ["gx", "ax", "wx", "gyro_x_bias", "gyro_x_raw", "gyro_bias_x", "mag_x", "gyro_w",
     "accelerator", "temperature", "gyro_x_g", "accel_x_dps", "time_of_day", "frame_id", ""],
)
def test_not_recognised(name: str) -> None:
    assert recognise(name) is None


def test_layouts() -> None:
    assert recognise("omega_x").layout == "kalibr"  # type: ignore[union-attr]
    assert recognise("w_RS_S_x [rad s^-1]").layout == "euroc"  # type: ignore[union-attr]
    assert recognise("gyro_x").layout == "generic"  # type: ignore[union-attr]


@pytest.mark.parametrize(
    ("text", "kind", "key"),
    [
        ("rad s^-1", "gyro", "rad/s"),
        ("rad/s", "gyro", "rad/s"),
        ("deg/s", "gyro", "deg/s"),
        ("°/s", "gyro", "deg/s"),
        ("DPS", "gyro", "deg/s"),
        ("deg/h", "gyro", "deg/h"),
        ("m s^-2", "accel", "m/s^2"),
        ("m/s/s", "accel", "m/s^2"),
        ("m/s²", "accel", "m/s^2"),
        ("G", "accel", "g"),
        ("µs", "time", "us"),
        ("nsec", "time", "ns"),
        ("furlong", "gyro", None),
        ("g", "gyro", None),
    ],
)
def test_normalise_unit(text: str, kind: str, key: str | None) -> None:
    assert normalise_unit(text, kind) == key


def test_split_bracket_unit() -> None:
    assert split_bracket_unit("w_RS_S_x [rad s^-1]") == ("w_RS_S_x", "rad s^-1")
    assert split_bracket_unit("gyro_x") == ("gyro_x", None)


# --- parse_column_map ----------------------------------------------------------


def test_parse_column_map() -> None:
    assert parse_column_map("gyro_x=wx, gyro_y = wy ,time=stamp") == {
        "gyro_x": "wx", "gyro_y": "wy", "time": "stamp"}
    assert parse_column_map("t=w_RS_S_x [rad s^-1]") == {"time": "w_RS_S_x [rad s^-1]"}


@pytest.mark.parametrize(
    ("text", "word"),
    [
        ("", "empty"),
        ("gyro_x", "no '='"),
        ("gyro_x=wx,,gyro_y=wy", "empty item"),
        ("speed=v", "not known"),
        ("gyro_x=", "no source"),
        ("gyro_x=a,gyro_x=b", "twice"),
        ("gyro_x=a,gyro_y=a", "both"),
    ],
)
def test_parse_column_map_errors(text: str, word: str) -> None:
    with pytest.raises(OptionError) as err:
        parse_column_map(text)
    assert word in str(err.value) and "\n" not in str(err.value)


# --- properties ------------------------------------------------------------------

_seps = st.sampled_from(["_", ".", " ", "-"])
_axis = st.sampled_from("xyz")


def _case(draw: st.DrawFn, s: str) -> str:
    flips = draw(st.lists(st.booleans(), min_size=len(s), max_size=len(s)))
    return "".join(c.upper() if f else c for c, f in zip(s, flips, strict=True))


@st.composite
def sensor_names(draw: st.DrawFn) -> tuple[str, str, str | None]:
    kind = draw(st.sampled_from(["gyro", "accel"]))
    bases = GYRO_BASES if kind == "gyro" else ACCEL_BASES
    base = draw(st.sampled_from(bases))
    axis = draw(_axis)
    sep = draw(_seps)
    name = base.replace("_", draw(_seps)) + sep + axis
    table = GYRO_UNIT_SYNONYMS if kind == "gyro" else ACCEL_UNIT_SYNONYMS
    unit = None
    style = draw(st.sampled_from(["none", "suffix", "bracket"]))
    if style == "suffix":
        spelling = draw(st.sampled_from([u for u in table if "/" not in u and "^" not in u]))
        name = f"{name}_{spelling}"
        unit = table[spelling]
    elif style == "bracket":
        spelling = draw(st.sampled_from(list(table)))
        name = f"{name} [{spelling}]"
        unit = table[spelling]
    if unit is None and base in ("omega", "alpha"):
        unit = "rad/s" if kind == "gyro" else "m/s^2"
    prefix = draw(st.sampled_from(["", "field.", "imu/", "#"]))
    return prefix + _case(draw, name), f"{kind}_{axis}", unit


@given(sensor_names())
@settings(max_examples=400, deadline=None)
def test_recognise_generated(case: tuple[str, str, str | None]) -> None:
    name, canonical, unit = case
    rec = recognise(name)
    assert rec is not None, name
    assert rec.canonical == canonical
    assert rec.unit == unit


@given(st.sampled_from(["time", "t", "timestamp", "stamp", "ts", "time_stamp"]),
       st.sampled_from(sorted(TIME_UNIT_SYNONYMS)), st.booleans())
def test_recognise_time_generated(base: str, spelling: str, bracket: bool) -> None:
    name = f"{base} [{spelling}]" if bracket else f"{base}_{spelling}"
    rec = recognise(name)
    assert rec is not None and rec.canonical == "time"
    assert rec.unit == TIME_UNIT_SYNONYMS[spelling]


@given(st.text(alphabet="abcdefhijklmnopqrsuvw0123456789_", min_size=1, max_size=12))
def test_random_names_without_sensor_words_are_not_channels(name: str) -> None:
    rec = recognise(name)
    assert rec is None or rec.canonical == "time"


@given(st.dictionaries(st.sampled_from(MAP_KEYS),
                       st.text(alphabet="abcXYZ_[] 019/^-", min_size=1, max_size=10)
                       .map(str.strip).filter(bool),
                       min_size=1))
def test_parse_column_map_round_trip(mapping: dict[str, str]) -> None:
    if len(set(mapping.values())) < len(mapping):
        with pytest.raises(OptionError):
            parse_column_map(",".join(f"{k}={v}" for k, v in mapping.items()))
        return
    assert parse_column_map(",".join(f"{k}={v}" for k, v in mapping.items())) == mapping


_finite = st.floats(min_value=-1e6, max_value=1e6, allow_nan=False, allow_subnormal=False)


@given(
    data=st.data(),
    n=st.integers(min_value=2, max_value=25),
    rate=st.sampled_from([1.0, 50.0, 100.0, 200.0, 400.0, 1000.0]),
    gyro_unit=st.sampled_from(sorted(GYRO_UNITS)),
    accel_unit=st.sampled_from(sorted(ACCEL_UNITS)),
    delim=st.sampled_from([",", "\t", ";"]),
)
@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])
def test_csv_round_trip(data: st.DataObject, n: int, rate: float, gyro_unit: str,
                        accel_unit: str, delim: str) -> None:
    """Write numbers in some unit, read back: same numbers times the SI factor."""
    vals = np.array(data.draw(st.lists(st.lists(_finite, min_size=6, max_size=6),
                                       min_size=n, max_size=n)))
    t_ns = np.arange(n, dtype=np.int64) * int(round(1e9 / rate)) + 1_600_000_000_000_000_000
    header = ["time [ns]"] + [f"{c} [{gyro_unit if c.startswith('gyro') else accel_unit}]"
                              for c in IMU_CHANNELS]
    lines = [delim.join(header)]
    for k in range(n):
        lines.append(delim.join([str(t_ns[k]), *(repr(float(v)) for v in vals[k])]))
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "rt.csv"
        p.write_text("\n".join(lines) + "\n")
        log = read_imu(p)
    assert log.rate_hz == pytest.approx(rate, rel=1e-9)
    for j, c in enumerate(IMU_CHANNELS):
        factor = GYRO_UNITS[gyro_unit] if c.startswith("gyro") else ACCEL_UNITS[accel_unit]
        np.testing.assert_array_equal(log.channels[c], vals[:, j] * factor)
        kind = "gyro" if c.startswith("gyro") else "accel"
        given_unit = gyro_unit if kind == "gyro" else accel_unit
        assert log.input_units[c] == normalise_unit(given_unit, kind)
    # absolute epoch time in float64 (1.6e9 s) resolves 2.4e-7 s
    assert log.t[0] == 1_600_000_000.0
    np.testing.assert_allclose(log.t - log.t[0], (t_ns - t_ns[0]) * 1e-9, rtol=0, atol=3e-7)
