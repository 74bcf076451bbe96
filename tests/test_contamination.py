"""Spikes in a static log: detection, the robust Allan variance and ``static --robust``."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from imubounds.cli import main
from imubounds.errors import OptionError
from imubounds.stationary.allan import ESTIMATORS, allan
from imubounds.stationary.contamination import (
    despike,
    detect_spikes,
    median,
    median_and_quantile,
    order_statistics,
)
from imubounds.stationary.noise_sim import AxisNoise, NoiseSpec, simulate, write_csv
from imubounds.stationary.terms import analyse_curve

RATE = 100.0
TRUTH = {"N": 2e-3, "B": 3e-4, "K": 2e-5}
N_SPIKES = 120


def _noise() -> AxisNoise:
    return AxisNoise(**TRUTH, bias_tau_range_s=(0.05, 2e4))


def _contaminate(y: np.ndarray, seed: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """N_SPIKES single-sample spikes of 50 sample sigmas (random sign, random place)."""
    rng = np.random.default_rng(seed)
    pos = np.sort(rng.choice(np.arange(10, y.size - 10), N_SPIKES, replace=False))
    out = y.copy()
    out[pos] += rng.choice([-1.0, 1.0], N_SPIKES) * 50.0 * TRUTH["N"] * np.sqrt(RATE)
    return out, pos


@pytest.fixture(scope="module")
def logs() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    spec = NoiseSpec(channels={"gyro_x": _noise()})
    y = simulate(spec, RATE, 3 * 3600.0, seed=11).channels["gyro_x"]
    dirty, pos = _contaminate(y)
    return y, dirty, pos


def test_clean_gaussian_log_has_no_spike(logs: tuple[np.ndarray, ...]) -> None:
    y = logs[0]
    rep = detect_spikes(y, RATE, name="gyro_x")
    assert rep.events == 0 and rep.warning() is None, rep
    assert rep.max_z < 8.0


def test_injected_spikes_are_found_and_counted(logs: tuple[np.ndarray, ...]) -> None:
    _, dirty, pos = logs
    rep = detect_spikes(dirty, RATE, name="gyro_x")
    assert rep.events == N_SPIKES, f"found {rep.events} of {N_SPIKES}"
    assert rep.first_index == list(pos[: len(rep.first_index)])
    assert rep.first_time_s[0] == pytest.approx(pos[0] / RATE)
    assert rep.variance_share > 0.1
    msg = rep.warning()
    assert msg is not None and f"{N_SPIKES} spike(s)" in msg and "--robust" in msg
    assert "\n" not in msg
    d = rep.to_dict()
    assert d["events"] == N_SPIKES and d["fraction"] < 1e-3
    cleaned = despike(dirty, rep)
    assert np.max(np.abs(cleaned - logs[0])) < 10 * TRUTH["N"] * np.sqrt(RATE)


def test_robust_curve_equals_the_plain_one_on_clean_data(logs: tuple[np.ndarray, ...]) -> None:
    y = logs[0]
    for e in ("overlapping", "modified", "total"):
        plain = allan(y, RATE, "octave", e)
        rob = allan(y, RATE, "octave", e, robust=True)
        assert rob.robust and not plain.robust
        ratio = rob.dev / plain.dev
        assert np.all(np.abs(ratio - 1.0) < 0.02), (e, np.round(ratio, 3))


@pytest.mark.slow  # six estimators, plain and robust, on a 3 h log: ~10 s
@pytest.mark.parametrize("estimator", ESTIMATORS)
def test_robust_recovers_n_and_b_where_the_plain_curve_fails(
    logs: tuple[np.ndarray, ...], estimator: str
) -> None:
    dirty = logs[1]
    _, _, plain = analyse_curve(allan(dirty, RATE, "octave", estimator))
    _, _, rob = analyse_curve(allan(dirty, RATE, "octave", estimator, robust=True))
    n_plain = plain.value("N") / TRUTH["N"]
    assert n_plain > 1.10, f"the spikes should inflate N (got x{n_plain:.3f})"
    assert rob.value("N") == pytest.approx(TRUTH["N"], rel=0.10), rob.value("N")
    assert rob.status("B") == "resolved"
    assert rob.value("B") == pytest.approx(TRUTH["B"], rel=0.30), rob.value("B")


def test_detector_options_are_checked() -> None:
    with pytest.raises(OptionError, match="threshold"):
        detect_spikes(np.zeros(10), RATE, threshold=0.0)
    assert detect_spikes(np.zeros(100), RATE).events == 0  # constant: nothing to flag
    q = np.round(np.random.default_rng(0).normal(size=10_000) * 0.3)  # mostly one level
    assert detect_spikes(q, RATE).events == 0


def test_static_robust_end_to_end(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A contaminated CSV: the warning counts the spikes, --robust keeps the plain curve."""
    spec = NoiseSpec(channels={"gyro_x": _noise(), "accel_x": AxisNoise(N=1e-3, B=2e-4)})
    log = simulate(spec, RATE, 1800.0, seed=5)
    log.channels["gyro_x"], _ = _contaminate(log.channels["gyro_x"], seed=2)
    path = write_csv(log, tmp_path / "dirty.csv")
    out = tmp_path / "out"
    code = main(["static", str(path), "-o", str(out), "--robust", "--no-plot", "--no-report",
                 "--models", "none"])  # fmt: skip
    assert code == 0
    err = capsys.readouterr().err
    found = re.search(r"warning: gyro_x: (\d+) spike\(s\)", err)
    assert found, err
    # 120 spikes in 180 000 samples: two may fall within two samples and count as one
    assert N_SPIKES - 3 <= int(found.group(1)) <= N_SPIKES
    doc = json.loads((out / "noise.json").read_text())
    ch = doc["channels"]["gyro_x"]
    assert ch["spikes"]["events"] == int(found.group(1))
    assert doc["settings"]["robust"] is True
    assert ch["allan"]["robust"] is True and ch["allan_plain"]["robust"] is False
    assert ch["allan"]["statistic"].startswith("robust")
    assert ch["allan_plain"]["adev"][0] > 1.1 * ch["allan"]["adev"][0]
    assert doc["channels"]["accel_x"]["spikes"]["events"] == 0


@pytest.mark.parametrize("n", [1, 2, 5, 1000, 1001, 100_000])
def test_median_and_quantile_are_numpys_bit_for_bit(n: int) -> None:
    """One partition gives np.median and np.quantile exactly (the spike scale and
    the trim cut of detect_spikes, hence its reports, do not change)."""
    rng = np.random.default_rng(n)
    for a in (
        rng.normal(size=n),
        np.round(rng.normal(size=n) * 2) / 2,  # quantised: ties
        np.abs(rng.standard_cauchy(n)),
    ):
        for q in (0.999, 0.9, 0.5, 0.0, 1.0):
            med, quant = median_and_quantile(a, q)
            assert med == float(np.median(a))
            assert quant == float(np.quantile(a, q))
        assert median(a) == float(np.median(a))
        ranks = sorted({0, n // 2, n - 1, (n - 1) // 3, max(n - 2, 0)})
        stats = order_statistics(a, ranks)
        assert [stats[k] for k in ranks] == [float(v) for v in np.sort(a)[ranks]]


def test_detect_spikes_scale_equals_the_plain_numpy_formula() -> None:
    """The in-place second differences and MAD give the plain expressions' scale and
    z bit for bit (the same ufuncs on the same operands)."""
    rng = np.random.default_rng(11)
    for y in (rng.normal(size=20_001), np.round(rng.normal(size=20_000) * 3) / 3):
        y[[50, 9000]] += 40.0
        d = y[1:-1] - 0.5 * (y[:-2] + y[2:])
        a = np.abs(d - np.median(d))
        cut = np.quantile(a, 0.999)
        central = a[a <= cut]
        scale = max(1.482602218505602 * float(np.median(a)),
                    float(np.sqrt(np.mean(central * central))))  # fmt: skip
        rep = detect_spikes(y, 100.0)
        assert rep.scale == scale
        assert rep.max_z == float((a / scale).max())
        assert rep.events >= 2
