"""Fleet characterisation on a real Dask LocalCluster (issue 7)."""

from __future__ import annotations

import json
from pathlib import Path

import h5py  # noqa: F401  (before codac, see conftest)
import numpy as np
import pandas as pd
import pytest
from hypothesis import given
from hypothesis import strategies as st

from imubounds.errors import OptionError
from imubounds.stationary.fleet import (
    FleetSettings,
    analyse_unit,
    content_key,
    load_spec,
    parse_spec,
    plan_tasks,
    run_fleet,
)
from imubounds.units import DEG

RATE = 100.0
N_UNITS = 4


@pytest.fixture(scope="module")
def fleet_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    from imubounds.stationary.noise_sim import NoiseSpec, simulate, write_csv

    d = tmp_path_factory.mktemp("fleet")
    for i in range(N_UNITS):
        # unit 3 is noisier: it must fail the gyro N limit below
        n_gyro = "1.5 deg/sqrt(h)" if i == 3 else "0.5 deg/sqrt(h)"
        spec = NoiseSpec.from_mapping(
            {"gyro": {"N": n_gyro, "B": "20 deg/h"},
             "accel": {"N": "0.05 m/s/sqrt(h)", "B": "0.5 mg"}}
        )  # fmt: skip
        write_csv(simulate(spec, RATE, 400.0, seed=100 + i), d / f"unit{i:02d}.csv.gz")
    (d / "unit_corrupt.csv.gz").write_bytes(b"\x1f\x8b\x08\x00 not really gzip")
    (d / "spec.yaml").write_text(
        "name: test datasheet\n"
        "gyro:\n  N: 1.0 deg/sqrt(h)\n  B: 100 deg/h\n"
        "accel:\n  N: {value: 0.2, unit: m/s/sqrt(h)}\n  B: 5 mg\n"
    )
    return d


@pytest.fixture(scope="module")
def cluster():  # noqa: ANN201
    from dask.distributed import Client, LocalCluster

    c = LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0")
    client = Client(c)
    yield client
    client.close()
    c.close()


def test_fleet_with_a_corrupt_unit(fleet_dir: Path, tmp_path: Path, cluster) -> None:  # noqa: ANN001
    """The must-show test: the report names the corrupt file; the rest are right."""
    out = tmp_path / "out"
    res = run_fleet([str(fleet_dir / "unit*.csv.gz")], out, client=cluster,
                    spec=fleet_dir / "spec.yaml")  # fmt: skip
    summ = json.loads((out / "fleet.json").read_text())
    assert summ["format"] == "imubounds.stationary.fleet/1"
    assert summ["n_units"] == N_UNITS + 1
    assert summ["n_ok"] == N_UNITS and summ["n_failed"] == 1
    assert summ["failed"][0]["unit"] == "unit_corrupt"
    assert "unit_corrupt.csv.gz" in summ["failed"][0]["error"]
    assert "gzip" in summ["failed"][0]["error"]
    for f in ("fleet.parquet", "fleet.png", "fleet.svg", "passfail.csv"):
        assert (out / f).is_file()
    table = pd.read_parquet(out / "fleet.parquet")
    ok = table[table.status == "ok"]
    assert len(ok) == N_UNITS * 6
    assert set(ok.channel) == {"gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z"}
    # the rest are right: the same numbers as the static pipeline on each file alone
    from imubounds.io import read_imu
    from imubounds.stationary.pipeline import StaticSettings, analyse_static

    for unit in sorted(set(ok.unit)):
        alone = analyse_static(read_imu(fleet_dir / f"{unit}.csv.gz"), StaticSettings(models=()))
        for ch, cr in alone.channels.items():
            row = ok[(ok.unit == unit) & (ok.channel == ch)].iloc[0]
            # Curves are bit-identical; the least-squares fit goes through LAPACK,
            # whose threaded summation order may differ between a Dask worker and
            # the main thread in the last ulp: compare the fit to 1e-12 relative.
            for t in ("Q", "N", "B", "K", "R"):
                assert row[f"{t}_fit"] == pytest.approx(cr.fit.value(t), rel=1e-12, abs=1e-300)
                assert row[t] == pytest.approx(cr.fit.value(t), rel=1e-12, abs=1e-300)
                s = cr.slope.value(t)
                assert (np.isnan(row[f"{t}_slope"]) and np.isnan(s)) or row[f"{t}_slope"] == s
            lo, hi = cr.fit.ci["N"]
            assert (row["N_fit_lo"], row["N_fit_hi"]) == pytest.approx((lo, hi), rel=1e-12)
            np.testing.assert_array_equal(res.curves[unit][ch]["adev"], cr.allan.dev)
    # true gyro N is 0.5 deg/sqrt(h) for units 0-2
    good = ok[(ok.kind == "gyro") & (ok.unit != "unit03")]
    assert np.allclose(good["N"] * 60 / DEG, 0.5, rtol=0.1)
    # pass/fail with margins: only unit03 (N = 1.5 > 1.0 deg/sqrt(h)) fails
    pf = pd.read_csv(out / "passfail.csv")
    assert summ["spec"]["units_failing"] == ["unit03"]
    assert summ["spec"]["n_pass"] == N_UNITS - 1
    bad = pf[(pf.unit == "unit03") & (pf.term == "N") & (pf.kind == "gyro")]
    assert (bad.status == "fail").all() and (bad.margin < -0.3).all()
    okm = pf[(pf.unit == "unit00") & (pf.term == "N") & (pf.kind == "gyro")]
    assert (okm.margin > 0.3).all() and (okm.margin < 0.7).all()
    np.testing.assert_allclose(okm.margin, 1 - okm.value / okm.limit)

    # rerun, connecting by scheduler address (as --scheduler does): every good unit comes
    # from the cache; the corrupt one is retried and reported again
    res2 = run_fleet(
        [str(fleet_dir / "unit*.csv.gz")], out, scheduler=cluster.scheduler.address, plot=False
    )
    assert res2.scheduler == cluster.scheduler.address
    assert res2.n_tasks == 1
    assert res2.n_cached == N_UNITS
    assert [f["unit"] for f in res2.failed] == ["unit_corrupt"]
    t2 = pd.read_parquet(out / "fleet.parquet")
    pd.testing.assert_frame_equal(t2[t2.status == "ok"].reset_index(drop=True),
                                  ok.reset_index(drop=True))  # fmt: skip


def test_same_numbers_as_the_static_command(fleet_dir: Path, tmp_path: Path) -> None:
    from imubounds.cli import main

    src = fleet_dir / "unit01.csv.gz"
    assert main(["static", str(src), "-o", str(tmp_path / "s"), "--models", "none",
                 "--no-plot", "--no-report", "-q"]) == 0  # fmt: skip
    noise = json.loads((tmp_path / "s" / "noise.json").read_text())
    unit = analyse_unit(str(src), FleetSettings())
    assert unit["status"] == "ok"
    for row in unit["rows"]:
        js = noise["channels"][row["channel"]]["noise"]
        for t in ("N", "B", "K"):
            assert row[f"{t}_fit"] == pytest.approx(js["fit"][t]["value"], rel=1e-12, abs=1e-300)
            sigma_c = noise["channels"][row["channel"]]["sigma_c"]
            assert row["sigma_c"] == pytest.approx(sigma_c, rel=1e-12)


def test_cli_fleet_scheduler_address(fleet_dir: Path, tmp_path: Path, capsys, cluster) -> None:  # noqa: ANN001, E501
    from imubounds.cli import main

    out = tmp_path / "cli"
    code = main(["fleet", str(fleet_dir / "unit0[01].csv.gz"), str(fleet_dir / "unit_c*"),
                 "-o", str(out), "--json", "-q", "--no-plot",
                 "--scheduler", cluster.scheduler.address])  # fmt: skip
    assert code == 0
    summ = json.loads(capsys.readouterr().out)
    assert summ["n_ok"] == 2 and summ["n_failed"] == 1
    assert summ["terms_ieee"]["gyro"]["N"]["unit_ieee"] == "deg/h^0.5"
    assert summ["scheduler"] == cluster.scheduler.address
    assert not (out / "fleet.png").exists()


def test_content_key_depends_on_bytes_and_settings(fleet_dir: Path, tmp_path: Path) -> None:
    src = fleet_dir / "unit00.csv.gz"
    k = content_key(src, FleetSettings())
    copy = tmp_path / "other_name.csv.gz"
    copy.write_bytes(src.read_bytes())
    assert content_key(copy, FleetSettings()) == k
    assert content_key(src, FleetSettings(estimator="hadamard")) != k
    copy.write_bytes(src.read_bytes() + b"\n")
    assert content_key(copy, FleetSettings()) != k


@given(sizes=st.lists(st.integers(1, 10**9), min_size=0, max_size=60), w=st.integers(1, 8))
def test_plan_tasks_covers_every_unit_once(sizes: list[int], w: int) -> None:
    tasks = plan_tasks(sizes, w, target_task_bytes=10**8)
    flat = sorted(i for t in tasks for i in t)
    assert flat == list(range(len(sizes)))
    assert len(tasks) >= min(len(sizes), 4 * w)
    assert len(tasks) <= max(len(sizes), 0)


def test_spec_parsing(fleet_dir: Path) -> None:
    spec = load_spec(fleet_dir / "spec.yaml")
    assert spec.limits["gyro"]["N"] == pytest.approx(1.0 * DEG / 60.0)
    assert spec.limits["accel"]["B"] == pytest.approx(5e-3 * 9.80665)
    with pytest.raises(OptionError, match="gyro.N"):
        parse_spec({"gyro": {"N": "3 m/s"}})
    with pytest.raises(OptionError, match="unknown key"):
        parse_spec({"gyros": {"N": 1}})
    with pytest.raises(OptionError, match="not a noise term"):
        parse_spec({"gyro": {"X": 1}})
    with pytest.raises(OptionError, match="criterion"):
        parse_spec({"gyro": {"N": 1}, "criterion": "max"})


def test_large_unit_goes_out_of_core_with_the_same_terms(fleet_dir: Path) -> None:
    src = str(fleet_dir / "unit02.csv.gz")
    mem = analyse_unit(src, FleetSettings())
    ooc = analyse_unit(src, FleetSettings(memory_limit="64KiB"))  # forces the chunked path
    assert mem["status"] == ooc["status"] == "ok"
    for a, b in zip(mem["rows"], ooc["rows"], strict=True):
        assert a["channel"] == b["channel"]
        for t in ("N", "B", "K"):
            assert b[t] == pytest.approx(a[t], rel=1e-9, abs=1e-300)
    np.testing.assert_allclose(ooc["curves"]["gyro_x"]["adev"], mem["curves"]["gyro_x"]["adev"],
                               rtol=1e-12)  # fmt: skip
