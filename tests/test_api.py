"""The curated Python API (``import imubounds``): arrays and tables in, result objects out.

The names here are checked by mypy in strict mode (``[tool.mypy]`` files include this
test), so the public signatures are typed the way a user's script sees them.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from matplotlib.figure import Figure

import imubounds as ib
from imubounds.stationary.allan import allan as allan_estimator

RATE_HZ = 100.0
N_TRUE = 1e-3  # rad/s/sqrt(Hz): white rate noise of the synthetic gyro
A_TRUE = 2e-3  # m/s^2/sqrt(Hz): white noise of the synthetic accelerometer


def white(n: int, density: float, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return rng.standard_normal(n) * density * math.sqrt(RATE_HZ)


@pytest.fixture(scope="module")
def table() -> pd.DataFrame:
    n = 36_000  # 6 min at 100 Hz
    return pd.DataFrame(
        {
            "time_s": np.arange(n) / RATE_HZ,
            "gyro_z_rads": white(n, N_TRUE, 1),
            "accel_x_mps2": 9.80665 + white(n, A_TRUE, 2),
        }
    )


@pytest.fixture(scope="module")
def static(table: pd.DataFrame) -> ib.StaticResult:
    return ib.characterize(table, models=())


def test_public_names_resolve_and_are_listed() -> None:
    for name in ib.__all__:
        assert getattr(ib, name) is not None, name
        assert name in dir(ib), name
    assert issubclass(ib.InputError, ValueError) and issubclass(ib.OptionError, ValueError)
    with pytest.raises(AttributeError, match="no attribute 'not_a_name'"):
        ib.not_a_name  # noqa: B018


def test_allan_of_an_array_equals_the_estimator_and_carries_its_unit() -> None:
    x = white(20_000, N_TRUE, 3)
    res = ib.allan(x, RATE_HZ, unit="rad/s")
    ref = allan_estimator(x, RATE_HZ, taus=40)  # ib.allan's grid: characterize's, 40 points
    np.testing.assert_array_equal(res.dev, ref.dev)
    np.testing.assert_array_equal(res.ci_upper, ref.ci_upper)
    assert res.unit == "rad/s" and ref.unit is None
    same = ib.allan(x, rate=RATE_HZ, estimator="modified", taus=[0.1, 1.0])
    np.testing.assert_allclose(same.tau, [0.1, 1.0])
    assert same.estimator == "modified"


def test_allan_of_a_series_uses_its_name_in_errors() -> None:
    s = pd.Series([0.0, 1.0, float("nan"), 2.0] * 100, name="gyro_q")
    with pytest.raises(ib.InputError, match="gyro_q: sample 2"):
        ib.allan(s, RATE_HZ)


@pytest.mark.parametrize(
    ("kwargs", "error", "needle"),
    [
        ({}, ib.OptionError, "sample rate is needed"),
        ({"rate_hz": 100.0, "rate": 50.0}, ib.OptionError, "give the sample rate once"),
        ({"rate_hz": 100.0, "unit": "deg/s"}, ib.OptionError, "works in SI"),
        ({"rate_hz": -1.0}, ib.OptionError, "rate"),
        ({"rate_hz": 100.0, "estimator": "fast"}, ib.OptionError, "unknown Allan estimator"),
    ],
)
def test_allan_bad_arguments_raise_clear_errors(
    kwargs: dict[str, object], error: type[Exception], needle: str
) -> None:
    with pytest.raises(error, match=needle):
        ib.allan(np.ones(1000), **kwargs)  # type: ignore[arg-type]


def test_allan_refuses_a_table() -> None:
    with pytest.raises(ib.InputError, match="one signal"):
        ib.allan(pd.DataFrame({"a": np.zeros(100)}), RATE_HZ)


def test_allan_frame_and_dict_have_units_and_are_json() -> None:
    res = ib.allan(white(10_000, N_TRUE, 4), RATE_HZ, unit="rad/s")
    df = res.to_frame()
    assert list(df.columns[:5]) == ["tau_s", "m", "dev", "ci_lower", "ci_upper"]
    assert set(df["unit"]) == {"rad/s"}
    np.testing.assert_array_equal(df["dev"].to_numpy(), res.dev)
    d = res.to_dict()
    assert json.loads(json.dumps(d)) == d and d["unit"] == "rad/s"
    fig = res.plot()
    assert isinstance(fig, Figure) and "rad/s" in fig.axes[0].get_ylabel()


def test_noise_terms_recover_white_noise_and_say_its_unit() -> None:
    res = ib.allan(white(60_000, N_TRUE, 5), RATE_HZ, unit="rad/s")
    sel = ib.noise_terms(res)
    n = sel.terms["N"]
    assert n.status == "resolved"
    assert n.value == pytest.approx(N_TRUE, rel=0.05), f"N = {n.value} vs {N_TRUE}"
    df = sel.to_frame()
    row = df.set_index("term").loc["N"]
    assert row["unit"] == "rad/s^0.5" and row["ieee_unit"] == "deg/h^0.5"
    assert row["value"] == pytest.approx(n.value)
    assert sel.to_dict()["N"]["status"] == "resolved"
    assert isinstance(sel.plot(), Figure)


def test_noise_terms_need_to_know_the_sensor() -> None:
    res = ib.allan(white(10_000, N_TRUE, 6), RATE_HZ)
    with pytest.raises(ib.OptionError, match="which sensor"):
        ib.noise_terms(res)
    assert ib.noise_terms(res, sensor="accel").to_dict()["N"]["unit"] == "m/s^1.5"
    with pytest.raises(ib.OptionError, match="the unit of a gyro"):
        ib.noise_terms(ib.allan(white(10_000, N_TRUE, 6), RATE_HZ, unit="rad/s"), sensor="accel")
    with pytest.raises(ib.InputError, match="AllanResult"):
        ib.noise_terms([1.0, 2.0])  # type: ignore[arg-type]


def test_noise_terms_equal_the_selected_terms_of_characterize(
    table: pd.DataFrame, static: ib.StaticResult
) -> None:
    curve = ib.allan(table["gyro_z_rads"], RATE_HZ, unit="rad/s")
    sel = ib.noise_terms(curve)
    assert sel.to_dict() == static.channels["gyro_z"].selected.to_dict()


def test_characterize_a_table_a_dict_and_a_log_agree(
    table: pd.DataFrame, static: ib.StaticResult
) -> None:
    cols = {k: table[k].to_numpy() for k in ("gyro_z_rads", "accel_x_mps2")}
    from_dict = ib.characterize(cols, rate_hz=RATE_HZ, models=())
    log = ib.read_frame(table)
    from_log = ib.characterize(log, models=())
    a, b, c = static.to_dict(), from_dict.to_dict(), from_log.to_dict()
    for d in (a, b, c):
        d.pop("input")
    assert a == b == c


def test_static_result_converts_to_json_frame_and_figure(static: ib.StaticResult) -> None:
    d = static.to_dict()
    assert json.loads(json.dumps(d, allow_nan=False)) == d
    assert d["channels"]["gyro_z"]["unit"] == "rad/s"
    df = static.to_frame()
    assert len(df) == 5 * len(static.channels)
    assert set(df["channel"]) == {"gyro_z", "accel_x"}
    n = df[(df.channel == "gyro_z") & (df.term == "N")].iloc[0]
    assert n["value"] == pytest.approx(N_TRUE, rel=0.1) and n["unit"] == "rad/s^0.5"
    assert isinstance(static.plot(), Figure)
    fig = Figure()
    ax = fig.add_subplot()
    assert static.plot(ax=ax, channel="accel_x") is fig
    with pytest.raises(ib.OptionError, match="give channel="):
        static.plot(ax=ax)
    assert isinstance(static.channels["gyro_z"].plot(), Figure)


def test_characterize_an_array_with_named_columns_equals_the_table(
    table: pd.DataFrame, static: ib.StaticResult
) -> None:
    arr = table[["gyro_z_rads", "accel_x_mps2"]].to_numpy()
    res = ib.characterize(arr, rate_hz=RATE_HZ, channels=["gyro_z", "accel_x"], models=())
    a, b = res.to_dict(), static.to_dict()
    assert a["channels"] == b["channels"]
    assert a["input"]["path"] == "<array>"


def test_characterize_refuses_unnamed_arrays_and_bad_models() -> None:
    with pytest.raises(ib.InputError, match="name the channels of an array"):
        ib.characterize(np.zeros(1000), rate_hz=RATE_HZ)
    with pytest.raises(ib.InputError, match="2 channel name"):
        ib.characterize(np.zeros(1000), rate_hz=RATE_HZ, channels=["gyro_x", "gyro_y"])
    with pytest.raises(ib.OptionError, match="distinct names"):
        ib.characterize(np.zeros((1000, 2)), rate_hz=RATE_HZ, channels=["gyro_x", "wx"])
    with pytest.raises(ib.OptionError, match="models"):
        ib.characterize({"gyro_z_rads": np.zeros(10)}, rate_hz=RATE_HZ, models="gm")
    with pytest.raises(ib.InputError, match="got list"):
        ib.characterize([1.0, 2.0], rate_hz=RATE_HZ)  # type: ignore[arg-type]


def test_fit_and_read_off_convert_like_the_selection(static: ib.StaticResult) -> None:
    ch = static.channels["gyro_z"]
    noise = static.to_dict()["channels"]["gyro_z"]["noise"]
    assert ch.fit.to_dict() == noise["fit"] and ch.slope.to_dict() == noise["slope"]
    df = ch.fit.to_frame()
    assert list(df["term"]) == ["Q", "N", "B", "K", "R"]
    assert df.set_index("term").loc["N", "unit"] == "rad/s^0.5"
    assert ch.selected.fit is ch.fit


def test_results_have_short_reprs(static: ib.StaticResult) -> None:
    texts = [repr(static), repr(static.channels["gyro_z"]), repr(static.log),
             repr(static.channels["gyro_z"].allan), repr(static.channels["gyro_z"].selected)]
    for text in texts:
        assert len(text) < 400 and "array(" not in text, text
    assert "N=" in texts[1] and "rad/s" in texts[1]
    assert "rad/s^0.5" in texts[4]


def test_read_frame_round_trips_an_imulog(table: pd.DataFrame) -> None:
    log = ib.read_frame(table)
    assert log.rate_hz == pytest.approx(RATE_HZ)
    back = ib.read_frame(log.to_frame())
    for name in log.channels:
        np.testing.assert_array_equal(back.channels[name], log.channels[name])
    assert log.to_dict()["channels"]["gyro_z"] == {"unit": "rad/s", "input_unit": "rad/s"}


def test_read_frame_converts_units_and_takes_a_datetime_index() -> None:
    n = 1000
    idx = pd.date_range("2024-01-01", periods=n, freq="10ms")
    df = pd.DataFrame({"gyro_z_dps": np.full(n, 1.0)}, index=idx)
    log = ib.read_frame(df)
    assert log.rate_hz == pytest.approx(100.0)
    assert log.channels["gyro_z"][0] == pytest.approx(math.pi / 180)


@pytest.mark.parametrize(
    ("data", "kwargs", "error", "needle"),
    [
        ({"gyro_z_rads": np.zeros(100)}, {}, ib.InputError, "no time column.*rate_hz="),
        ({"gyro_z_rads": [0.0, np.nan, 1.0]}, {"rate_hz": 10.0}, ib.InputError, "missing"),
        ({"x": np.zeros(10)}, {"rate_hz": 10.0}, ib.InputError, "IMU"),
        ([1, 2, 3], {"rate_hz": 10.0}, ib.InputError, "DataFrame"),
    ],
)
def test_read_frame_bad_input(
    data: object, kwargs: dict[str, float], error: type[Exception], needle: str
) -> None:
    with pytest.raises(error, match=needle):
        ib.read_frame(data, **kwargs)  # type: ignore[arg-type]


def test_read_log_reads_a_csv_like_the_cli(tmp_path: Path, table: pd.DataFrame) -> None:
    p = tmp_path / "log.csv"
    table.iloc[:2000].to_csv(p, index=False)
    log = ib.read_log(p)
    assert log.n_samples == 2000 and set(log.channels) == {"gyro_z", "accel_x"}
    with pytest.raises(ib.InputError):
        ib.read_log(tmp_path / "missing.csv")


def test_dynamic_margins_wants_a_drive() -> None:
    with pytest.raises(ib.InputError, match="takes a Drive"):
        ib.dynamic_margins("drive/")  # type: ignore[arg-type]
    with pytest.raises(ib.OptionError, match="mode"):
        ib.dynamic_margins(ib.Drive(), mode="fast")


def test_drive_and_dynamic_result_convert(tmp_path: Path) -> None:
    from imubounds.io.drive import GnssStream, HeadingStream, ImuStream

    n = 61
    t = np.arange(n, dtype=float)
    drive = ib.Drive(
        imu=ImuStream(t=t, accel=np.zeros((n, 3)), gyro=np.zeros((n, 3))),
        gnss=GnssStream(t=t, lat_deg=23.5 + 10.0 * t / 111_000.0, lon_deg=np.full(n, 88.0),
                        hdop=np.full(n, 0.8)),  # fmt: skip
        heading=HeadingStream(t=t, heading_rad=np.zeros(n)),
    )
    info = drive.to_dict()
    assert json.loads(json.dumps(info)) == info
    assert info["streams"]["gnss"] == {"samples": n, "t_first_s": 0.0, "t_last_s": 60.0}
    assert info["imu_rate_hz"] == pytest.approx(1.0)
    assert "array(" not in repr(drive)
    res = ib.dynamic_margins(drive, mode="paper")
    d = res.to_dict()
    assert json.loads(json.dumps(d, allow_nan=False)) == d
    assert d["guaranteed"] is False and "not guaranteed" in repr(res)
    df = res.to_frame()
    assert {"channel", "tau_s", "unit"} <= set(df.columns)
    with pytest.raises(ib.AnalysisError, match="mode full"):
        res.states_frame()


def test_frames_say_their_units_as_the_readme_does(table: pd.DataFrame,
                                                   static: ib.StaticResult) -> None:  # fmt: skip
    """README: a column whose values share a unit says it in its name; where the rows mix
    units (the terms) a unit column gives each row's, matching the value's unit."""
    log = ib.read_frame(table)
    assert all(c.endswith(("_s", "_rads", "_mps2")) for c in log.to_frame().columns)
    df = static.to_frame()
    for _, row in df.iterrows():
        sel = static.channels[row["channel"]].selected.to_dict()[row["term"]]
        assert row["unit"] == sel["unit"] and row["ieee_unit"] == sel["ieee"]["unit"]
    assert df.groupby("channel")["unit"].nunique().min() > 1  # the rows do mix units
    curve = ib.allan(table["gyro_z_rads"], RATE_HZ, unit="rad/s").to_frame()
    assert "tau_s" in curve.columns and set(curve["unit"]) == {"rad/s"}
