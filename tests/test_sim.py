"""IMU noise simulator (library and ``imubounds simulate-noise``), issue 3."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from imubounds import cli
from imubounds.errors import InputError, OptionError
from imubounds.io import read_imu
from imubounds.stationary import noise_sim as sim
from imubounds.stationary.allan import allan
from imubounds.stationary.models import GaussMarkovModel, fit_models
from imubounds.stationary.terms import B_FACTOR, fit_terms
from imubounds.units import DEG, G0

# ---------------------------------------------------------------------------
# units of datasheet figures


@pytest.mark.parametrize(
    ("text", "kind", "term", "si"),
    [
        ("0.05 deg/s/sqrt(Hz)", "gyro", "N", 0.05 * DEG),
        ("0.3 deg/sqrt(h)", "gyro", "N", 0.3 * DEG / 60.0),
        ("0.3 deg/h^0.5", "gyro", "N", 0.3 * DEG / 60.0),
        ("0.3 °/√h", "gyro", "N", 0.3 * DEG / 60.0),
        ("10 deg/h", "gyro", "B", 10 * DEG / 3600.0),
        ("1 dps", "gyro", "B", DEG),
        ("2 deg/h/sqrt(h)", "gyro", "K", 2 * DEG / 3600.0 / 60.0),
        ("0.01 deg", "gyro", "Q", 0.01 * DEG),
        ("60 ug/sqrt(Hz)", "accel", "N", 60e-6 * G0),
        ("0.002 m/s^2/sqrt(Hz)", "accel", "N", 0.002),
        ("0.002 m/s2/rtHz", "accel", "N", 0.002),
        ("0.05 m/s/sqrt(h)", "accel", "N", 0.05 / 60.0),
        ("20 ug", "accel", "B", 20e-6 * G0),
        ("3 mg", "accel", "B", 3e-3 * G0),
        ("1e-4 m/s^2.5", "accel", "K", 1e-4),
        ("0.001", "gyro", "N", 0.001),
        ({"value": 2, "unit": "deg/h"}, "gyro", "B", 2 * DEG / 3600.0),
        (0.5, "accel", "B", 0.5),
    ],
)
def test_parse_quantity(text: object, kind: str, term: str, si: float) -> None:
    assert sim.parse_quantity(text, kind, term) == pytest.approx(si, rel=1e-12)


def test_parse_quantity_rejects_wrong_dimensions_and_unknown_units() -> None:
    with pytest.raises(OptionError, match="does not fit a gyro N"):
        sim.parse_quantity("0.3 deg/h", "gyro", "N")
    with pytest.raises(OptionError, match="does not fit a accel B"):
        sim.parse_quantity("1 deg/s", "accel", "B")
    with pytest.raises(OptionError, match="unknown unit 'furlong'"):
        sim.parse_quantity("1 furlong/s", "accel", "B")
    with pytest.raises(OptionError, match="cannot read"):
        sim.parse_quantity("fast", "accel", "B")


def test_parse_duration() -> None:
    assert sim.parse_duration("7200") == 7200.0
    assert sim.parse_duration("2h") == 7200.0
    assert sim.parse_duration("90 min") == 5400.0
    assert sim.parse_duration("1.5e2s") == 150.0
    with pytest.raises(OptionError):
        sim.parse_duration("two hours")


# ---------------------------------------------------------------------------
# components


def test_flicker_approximation_is_flat_at_the_bias_instability_level() -> None:
    gms = sim.flicker_gm_terms(2.0, (0.5, 500.0))
    tau = np.logspace(np.log10(0.5), np.log10(500.0), 200)
    dev = np.sqrt(sum(g.avar(tau) for g in gms))
    assert np.allclose(dev, B_FACTOR * 2.0, rtol=0.01)
    # falls off outside the range
    far = np.sqrt(sum(g.avar(np.array([1e-3, 1e6])) for g in gms))
    assert np.all(far < 0.5 * B_FACTOR * 2.0)
    assert sim.flicker_gm_terms(0.0) == ()
    with pytest.raises(OptionError):
        sim.flicker_gm_terms(1.0, (10.0, 1.0))


def test_ramp_and_quantization_are_exact() -> None:
    rate = 10.0
    ramp = sim.simulate_axis(sim.AxisNoise(R=0.02), 1000, rate, seed=0)
    assert np.allclose(ramp, 0.02 * np.arange(1000) / rate)
    res = allan(ramp, rate, taus=[0.1, 1.0, 10.0])
    assert np.allclose(res.dev, 0.02 * res.tau / math.sqrt(2), rtol=1e-6)
    q = sim.simulate_axis(sim.AxisNoise(Q=0.01), 400_000, rate, seed=1)
    res = allan(q, rate, taus=[0.1, 1.0, 10.0, 100.0], confidence=0.99)
    theory = math.sqrt(3) * 0.01 / res.tau
    assert np.all((theory >= res.ci_lower) & (theory <= res.ci_upper))


def test_white_plus_random_walk_plus_flicker_match_the_theory() -> None:
    ax = sim.AxisNoise(N=1e-3, B=1e-4, K=2e-6, bias_tau_range_s=(1.0, 100.0))
    y = sim.simulate_axis(ax, 20 * 7200, 20.0, seed=3)
    # simultaneous 99 % over the curve's (at most 20) points (Bonferroni): every point in
    res = allan(y, 20.0, confidence=1 - 0.01 / 20)
    assert res.tau.size <= 20
    inside = (ax.adev(res.tau, 20.0) >= res.ci_lower) & (ax.adev(res.tau, 20.0) <= res.ci_upper)
    assert inside.all(), (res.tau[~inside], inside.mean())


def test_bias_and_turn_on_bias() -> None:
    y = sim.simulate_axis(sim.AxisNoise(bias=0.5), 100, 10.0, seed=0)
    assert np.all(y == 0.5)
    draws = [
        sim.simulate_axis(sim.AxisNoise(bias_sigma=2.0), 3, 10.0, seed=s)[0] for s in range(500)
    ]
    assert np.std(draws) == pytest.approx(2.0, rel=0.15)


def test_seeded_reproducible_and_components_independent() -> None:
    spec = sim.preset("xsens-mtx")
    a = sim.simulate(spec, 50.0, 60.0, seed=7)
    b = sim.simulate(spec, 50.0, 60.0, seed=7)
    c = sim.simulate(spec, 50.0, 60.0, seed=8)
    for ch in a.channels:
        assert np.array_equal(a.channels[ch], b.channels[ch])
        assert not np.array_equal(a.channels[ch], c.channels[ch])
    # selecting channels does not change a channel's stream
    only = sim.simulate(spec, 50.0, 60.0, seed=7, channels=["accel_y"])
    assert np.array_equal(only.channels["accel_y"], a.channels["accel_y"])
    # adding a component does not change the others
    n_only = sim.simulate_axis(sim.AxisNoise(N=1.0), 500, 10.0, seed=4)
    k_only = sim.simulate_axis(sim.AxisNoise(K=1.0), 500, 10.0, seed=4)
    both = sim.simulate_axis(sim.AxisNoise(N=1.0, K=1.0), 500, 10.0, seed=4)
    assert np.allclose(both, n_only + k_only)
    # channels are independent streams
    assert abs(np.corrcoef(a.channels["gyro_x"], a.channels["gyro_y"])[0, 1]) < 0.1


def test_xsens_mtx_preset_in_si() -> None:
    spec = sim.preset("xsens-mtx")
    assert set(spec.channels) == {"gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z"}
    g, a = spec.channels["gyro_z"], spec.channels["accel_x"]
    assert g.N == pytest.approx(0.05 * DEG) and g.B == pytest.approx(DEG)
    assert a.N == pytest.approx(0.002) and a.B == pytest.approx(0.02)
    with pytest.raises(OptionError, match="available: .*xsens-mtx"):
        sim.preset("nope")


@pytest.mark.parametrize("grade", ["tactical", "industrial", "consumer"])
def test_grade_presets_carry_their_rate_random_walk(grade: str) -> None:
    from imubounds.presets import get_preset

    p = get_preset(grade)
    spec = sim.preset(grade)
    for kind in ("gyro", "accel"):
        axis = spec.channels[f"{kind}_x"]
        for term in ("N", "B", "K"):
            assert getattr(axis, term) == pytest.approx(p.kind(kind)[term], rel=1e-5), (kind, term)
        # K is chosen to overtake the flicker floor inside a long log: 100 s .. 1 h
        tau_k = 3.0 * (2 * math.log(2) / math.pi) * axis.B**2 / axis.K**2
        assert 100.0 <= tau_k <= 3600.0, (kind, tau_k)


def test_datasheet_white_noise_gives_the_datasheet_density() -> None:
    spec = sim.preset("xsens-mtx")
    log = sim.simulate(spec, 100.0, 600.0, seed=1, channels=["gyro_x", "accel_x"])
    # per-sample std of white noise = density * sqrt(rate); B adds a little
    assert np.std(np.diff(log.channels["accel_x"])) / math.sqrt(2) == pytest.approx(
        0.002 * 10.0, rel=0.05
    )
    assert log.rate_hz == 100.0 and log.n_samples == 60_000
    assert log.t[1] - log.t[0] == pytest.approx(0.01)


def test_spec_mapping_with_units_per_axis_and_gauss_markov() -> None:
    spec = sim.NoiseSpec.from_mapping(
        {
            "name": "my imu",
            "rate_hz": 200,
            "gyro": {"N": "0.2 deg/sqrt(h)", "B": "3 deg/h", "bias_tau_range_s": [1, 100]},
            "gyro_z": {"N": "0.4 deg/sqrt(h)"},
            "accel": {
                "N": "50 ug/sqrt(Hz)",
                "gauss_markov": [{"sigma": "100 ug", "correlation_time_s": 300}],
            },
        }
    )
    assert spec.rate_hz == 200 and spec.name == "my imu"
    assert spec.channels["gyro_x"].N == pytest.approx(0.2 * DEG / 60)
    assert spec.channels["gyro_z"].N == pytest.approx(0.4 * DEG / 60)
    assert spec.channels["gyro_z"].B == pytest.approx(3 * DEG / 3600)
    gm = spec.channels["accel_y"].gauss_markov[0]
    assert gm.correlation_time_s == pytest.approx(300) and gm.sigma == pytest.approx(1e-4 * G0)
    # the resolved spec (SI) reads back to the same thing
    again = sim.NoiseSpec.from_mapping(json.loads(json.dumps(spec.to_dict())))
    assert again.channels["gyro_z"] == spec.channels["gyro_z"]
    assert again.channels["accel_y"].gauss_markov[0].beta == pytest.approx(gm.beta)
    with pytest.raises(InputError, match="unknown key"):
        sim.NoiseSpec.from_mapping({"gyros": {"N": 1}})
    with pytest.raises(InputError, match="unknown field"):
        sim.NoiseSpec.from_mapping({"gyro": {"ARW": 1}})


def _fake_noise_json() -> dict:
    def term(v: float | None) -> dict:
        return {"value": v, "unit": "x", "ieee": {"value": v, "unit": "y"}}

    ch = {
        "unit": "rad/s",
        "noise": {
            "slope": {
                "Q": term(None),
                "N": term(2e-3),
                "B": term(1e-4),
                "K": term(None),
                "R": term(None),
            },
            "fit": {
                "Q": term(0.0),
                "N": term(1e-3),
                "B": term(float("nan")),
                "K": term(1e-5),
                "R": term(None),
            },
            "selected": {
                "Q": term(1e-6),
                "N": term(1e-3),
                "B": term(2e-4),
                "K": term(1e-5),
                "R": term(None),
            },
        },
        "models": {
            "gauss_markov": GaussMarkovModel(
                beta=0.01, sigma=1e-3, white_density=1e-3, fitted_rate_hz=1.0
            ).to_dict(),
            "ar": {"coefficients": [-0.5], "noise_variance": 1e-6, "rate_hz": 1.0},
        },
    }
    return {
        "format": "imubounds.stationary.terms/1",
        "input": {"sample_rate_hz": 50.0, "duration_s": 10},
        "channels": {"gyro_x": ch, "time": {}},
    }


def test_from_noise_json_takes_fit_or_slope_terms_and_models() -> None:
    data = _fake_noise_json()
    fit = sim.NoiseSpec.from_noise_json(data)
    ax = fit.channels["gyro_x"]
    assert (ax.Q, ax.N, ax.B, ax.K, ax.R) == (0.0, 1e-3, 0.0, 1e-5, 0.0)
    assert fit.rate_hz == 50.0 and set(fit.channels) == {"gyro_x"}
    slope = sim.NoiseSpec.from_noise_json(data, terms="slope").channels["gyro_x"]
    assert (slope.N, slope.B, slope.K) == (2e-3, 1e-4, 0.0)
    # the selected terms: upper bounds where the log did not resolve a term, never 0
    sel = sim.NoiseSpec.from_noise_json(data, terms="selected").channels["gyro_x"]
    assert (sel.Q, sel.N, sel.B, sel.K) == (1e-6, 1e-3, 2e-4, 1e-5)
    mod = sim.NoiseSpec.from_noise_json(data, terms="none", models=("gm", "ar"))
    ax = mod.channels["gyro_x"]
    assert ax.N == 0 and ax.gauss_markov[0].beta == 0.01 and ax.ar is not None
    with pytest.raises(OptionError, match="12 Hz"):  # the AR model is tied to 1 Hz
        sim.simulate(mod, 12.0, 10.0)
    log = sim.simulate(mod, 1.0, 100.0, seed=0)
    assert log.n_samples == 100
    with pytest.raises(InputError, match="imubounds.stationary.terms/1"):
        sim.NoiseSpec.from_noise_json({"channels": {}})


def test_csv_round_trip_through_the_reader(tmp_path: Path) -> None:
    spec = sim.preset("xsens-mtx")
    log = sim.simulate(spec, 100.0, 30.0, seed=2, t0=5.0)
    for name in ("imu.csv", "imu.csv.gz"):
        path = sim.write_csv(log, tmp_path / name)
        back = read_imu(path)
        assert back.rate_hz == pytest.approx(100.0)
        assert back.channel_names() == log.channel_names()
        for ch in log.channels:
            assert np.allclose(back.channels[ch], log.channels[ch], rtol=1e-9, atol=0)
        assert back.t[0] == pytest.approx(5.0)
    header = (tmp_path / "imu.csv").read_text().splitlines()[0]
    assert header == ",".join(["time_s", *sim.CSV_COLUMNS.values()])


def test_simulate_errors() -> None:
    spec = sim.preset("xsens-mtx")
    with pytest.raises(OptionError, match="rate"):
        sim.simulate(spec, None, 10.0)
    with pytest.raises(OptionError, match="duration"):
        sim.simulate(spec, 10.0, None)
    with pytest.raises(OptionError, match="not in the noise spec"):
        sim.simulate(
            sim.NoiseSpec.from_datasheet(gyro=sim.AxisNoise(N=1.0)),
            10.0,
            10.0,
            channels=["accel_x"],
        )
    with pytest.raises(OptionError, match=">= 0"):
        sim.AxisNoise(N=-1.0)


# ---------------------------------------------------------------------------
# the command


@pytest.fixture()
def run_cli(monkeypatch: pytest.MonkeyPatch):  # type: ignore[no-untyped-def]
    if "simulate_noise" not in cli.COMMAND_MODULES:  # until the lead wires it in
        monkeypatch.setattr(cli, "COMMAND_MODULES", (*cli.COMMAND_MODULES, "simulate_noise"))

    def run(*argv: str) -> int:
        return cli.main(list(argv))

    return run


def test_cli_datasheet_figures(run_cli, tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    out = tmp_path / "imu.csv.gz"
    code = run_cli(
        "simulate-noise",
        "--gyro",
        "N=0.3 deg/sqrt(h),B=5 deg/h",
        "--accel",
        "N=60 ug/sqrt(Hz)",
        "--rate",
        "200",
        "--duration",
        "1min",
        "--seed",
        "3",
        "-o",
        str(out),
        "--save-spec",
        str(tmp_path / "spec.json"),
    )
    assert code == 0
    log = read_imu(out)
    assert log.n_samples == 12_000 and log.rate_hz == pytest.approx(200.0)
    saved = json.loads((tmp_path / "spec.json").read_text())
    assert saved["channels"]["gyro_y"]["N"] == pytest.approx(0.3 * DEG / 60)
    # same seed, same file content
    out2 = tmp_path / "again.csv.gz"
    run_cli(
        "simulate-noise",
        "--gyro",
        "N=0.3 deg/sqrt(h),B=5 deg/h",
        "--accel",
        "N=60 ug/sqrt(Hz)",
        "--rate",
        "200",
        "--duration",
        "1min",
        "--seed",
        "3",
        "-o",
        str(out2),
        "-q",
    )
    again = read_imu(out2)
    assert np.array_equal(again.channels["accel_z"], log.channels["accel_z"])


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--rate", "10", "--duration", "10"], "nothing to simulate"),
        (
            ["--preset", "xsens-mtx", "--spec", "x.yaml", "--rate", "10", "--duration", "10"],
            "only one of",
        ),
        (["--gyro", "N=1 deg/h", "--rate", "10", "--duration", "10"], "does not fit a gyro N"),
        (["--gyro", "ARW=1", "--rate", "10", "--duration", "10"], "unknown term"),
        (["--preset", "xsens-mtx", "--duration", "10"], "sample rate"),
        (["--preset", "xsens-mtx", "--rate", "10"], "length of the run"),
        (["--preset", "xsens-mtx", "--rate", "10", "--duration", "soon"], "--duration"),
        (["--preset", "mtx9", "--rate", "10", "--duration", "10"], "unknown IMU preset"),
        (["--from-noise", "missing.json", "--rate", "10", "--duration", "10"], "cannot read"),
        (
            ["--preset", "xsens-mtx", "--models", "gm", "--rate", "10", "--duration", "10"],
            "only with --from-noise",
        ),
    ],
)
def test_cli_errors_are_one_line(run_cli, tmp_path: Path, capsys, argv, message) -> None:  # type: ignore[no-untyped-def]
    code = run_cli("simulate-noise", "-o", str(tmp_path / "x.csv"), *argv)
    err = capsys.readouterr().err
    assert code == 2
    assert message in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "x.csv").exists()


def test_cli_spec_file(run_cli, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    spec = tmp_path / "imu.yaml"
    spec.write_text("rate_hz: 20\ngyro:\n  N: 0.1 deg/sqrt(h)\n  bias: 0.01 deg/s\n")
    out = tmp_path / "s.csv"
    assert (
        run_cli("simulate-noise", "--spec", str(spec), "--samples", "100", "-o", str(out), "-q")
        == 0
    )
    log = read_imu(out)
    assert log.channel_names() == ["gyro_x", "gyro_y", "gyro_z"]
    assert np.mean(log.channels["gyro_x"]) == pytest.approx(0.01 * DEG, rel=0.1)


# ---------------------------------------------------------------------------
# round trips: simulate from known coefficients → the static analysis recovers them

# rate 20 Hz, 12 h (K then scatters by ~3 % between seeds);
# Q dominates below 0.3 s, N to 3 s, B to 30 s, K beyond
KNOWN = {"Q": 6.3e-5, "N": 2e-4, "B": 1.74e-4, "K": 3.65e-5}


@pytest.mark.slow  # ~15 s: two 12 h logs through CSV
def test_round_trip_terms_through_the_static_command(run_cli, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    figures = ",".join(f"{k}={v}" for k, v in KNOWN.items())
    csv = tmp_path / "sim.csv"
    assert (
        run_cli(
            "simulate-noise",
            "--gyro",
            figures,
            "--bias-tau-range",
            "0.5,50",
            "--rate",
            "20",
            "--duration",
            "12h",
            "--seed",
            "0",
            "--channels",
            "gyro_x,gyro_y",
            "-o",
            str(csv),
            "-q",
        )
        == 0
    )
    out = tmp_path / "out"
    assert run_cli("static", str(csv), "-o", str(out), "--no-plot", "-q") == 0
    noise = json.loads((out / "noise.json").read_text())
    for ch in ("gyro_x", "gyro_y"):
        fit = noise["channels"][ch]["noise"]["fit"]
        for term, true in KNOWN.items():
            tol = 0.2 if term == "B" else 0.1
            assert fit[term]["value"] == pytest.approx(true, rel=tol), (ch, term)
    # and simulating again from that noise.json reproduces the terms
    csv2 = tmp_path / "again.csv"
    assert (
        run_cli(
            "simulate-noise",
            "--from-noise",
            str(out / "noise.json"),
            "--bias-tau-range",
            "0.5,50",
            "--duration",
            "12h",
            "--seed",
            "1",
            "-o",
            str(csv2),
            "-q",
        )
        == 0
    )
    log = read_imu(csv2)
    assert log.rate_hz == pytest.approx(20.0)
    terms = fit_terms(allan(log.channels["gyro_x"], log.rate_hz))
    for term, true in KNOWN.items():
        tol = 0.25 if term == "B" else 0.15
        assert terms.value(term) == pytest.approx(true, rel=tol), term


def test_round_trip_gauss_markov_beta(run_cli, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    spec = tmp_path / "gm.yaml"
    spec.write_text(
        "accel:\n  N: 0.01 m/s^2/sqrt(Hz)\n"
        "  gauss_markov: [{sigma: 0.002 m/s^2, correlation_time_s: 100}]\n"
    )
    csv = tmp_path / "gm.csv"
    assert (
        run_cli(
            "simulate-noise",
            "--spec",
            str(spec),
            "--rate",
            "10",
            "--duration",
            "40000",
            "--channels",
            "accel_x",
            "-o",
            str(csv),
            "-q",
        )
        == 0
    )
    log = read_imu(csv)
    res = fit_models(log.channels["accel_x"], log.rate_hz, ("gm",), name="accel_x")
    gm = res.gauss_markov
    assert gm is not None
    assert gm.beta == pytest.approx(0.01, rel=0.2)
    assert gm.sigma == pytest.approx(0.002, rel=0.2)
    assert gm.white_density == pytest.approx(0.01, rel=0.1)


def test_cli_list_presets_needs_no_output(capsys: pytest.CaptureFixture[str]) -> None:
    from imubounds.cli import main

    assert main(["simulate-noise", "--list-presets"]) == 0
    assert "xsens-mtx" in capsys.readouterr().out
    assert main(["simulate-noise", "--preset", "xsens-mtx", "--duration", "10"]) == 2
    err = capsys.readouterr().err.strip()
    assert "-o/--out" in err and len(err.splitlines()) == 1
