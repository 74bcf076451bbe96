"""Fleet characterisation on a real Dask LocalCluster (issue 7)."""

from __future__ import annotations

import json
import os
import shutil
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
    from dask.distributed import Client

    from imubounds.stationary.fleet import local_cluster

    c = local_cluster(2, 1)
    client = Client(c)
    yield client
    client.close()
    c.close()


def test_local_cluster_workers_get_the_fleet_process_settings(cluster) -> None:  # noqa: ANN001
    """Dask's MALLOC_TRIM_THRESHOLD_=65536 costs ~25 % CPU per unit: local_cluster's
    workers get imubounds.runtime.MALLOC_SETTINGS instead (freed memory kept for reuse),
    no statistical profiler and slow housekeeping ticks, a core each; the other
    pre-spawn settings (OMP_NUM_THREADS=1) stay."""
    import os

    import dask

    from imubounds.runtime import MALLOC_SETTINGS

    for key, value in MALLOC_SETTINGS.items():
        env = cluster.run(os.environ.get, key)
        assert len(env) == 2 and set(env.values()) == {os.environ.get(key, str(value))}, env
    assert set(cluster.run(os.environ.get, "OMP_NUM_THREADS").values()) == {"1"}
    prof = cluster.run(dask.config.get, "distributed.worker.profile.enabled")
    assert set(prof.values()) == {False}
    assert set(cluster.run(dask.config.get, "distributed.admin.tick.interval").values()) == {"1s"}
    # the settings were scoped to the cluster's start: this process's config is as it was
    assert dask.config.get("distributed.worker.profile.enabled") is True
    # each worker pinned to a core of its own when the cores allow (2 workers here)
    masks = [frozenset(m) for m in cluster.run(os.sched_getaffinity, 0).values()]
    if len(os.sched_getaffinity(0)) >= 2:
        assert all(len(m) == 1 for m in masks) and len(set(masks)) == 2, masks
    else:
        assert set(masks) == {frozenset(os.sched_getaffinity(0))}


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


def test_cached_units_are_not_sent_and_an_all_cached_fleet_starts_no_cluster(
    fleet_dir: Path, tmp_path: Path, cluster  # noqa: ANN001
) -> None:
    """The client hashes unit by unit and submits only the units not cached (the hashing
    of later units overlaps the analysis); a fleet found all cached starts no cluster."""
    units = tmp_path / "units"
    units.mkdir()
    for i in range(3):
        shutil.copy(fleet_dir / f"unit{i:02d}.csv.gz", units / f"unit{i:02d}.csv.gz")
    out = tmp_path / "out"
    first = run_fleet([str(units / "*.csv.gz")], out, n_workers=0, plot=False)
    assert first.ok and first.n_cached == 0
    # every unit cached: no cluster is started (n_workers=2 would start one)
    again = run_fleet([str(units / "*.csv.gz")], out, n_workers=2, plot=False)
    assert again.scheduler == "(all cached)" and again.n_tasks == 0 and again.n_cached == 3
    # one unit changed (another unit's bytes): only it goes to the workers
    shutil.copy(fleet_dir / "unit03.csv.gz", units / "unit01.csv.gz")
    third = run_fleet([str(units / "*.csv.gz")], out, client=cluster, plot=False)
    assert third.n_cached == 2 and third.n_tasks == 1 and third.ok
    t1, t3 = first.table.set_index(["unit", "channel"]), third.table.set_index(["unit", "channel"])
    for u in ("unit00", "unit02"):
        assert (t3.loc[u, "N"] == t1.loc[u, "N"]).all()
    assert not np.allclose(t3.loc["unit01", "N"], t1.loc["unit01", "N"])
    # one unit to analyse (here a broken log: failures are not cached, every rerun
    # analyses it again) and no cluster given: this process, no local cluster started
    shutil.copy(fleet_dir / "unit_corrupt.csv.gz", units / "unit00.csv.gz")
    for _ in range(2):
        fourth = run_fleet([str(units / "*.csv.gz")], out, n_workers=2, plot=False)
        assert fourth.scheduler == "this process (one unit to analyse)"
        assert fourth.n_cached == 2 and fourth.n_tasks == 1
        assert [f["unit"] for f in fourth.failed] == ["unit00"]


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


def test_cli_fleet_scheduler_address_exits_1_when_a_unit_fails(
    fleet_dir: Path, tmp_path: Path, capsys, cluster  # noqa: ANN001
) -> None:
    from imubounds.cli import main

    out = tmp_path / "cli"
    code = main(["fleet", str(fleet_dir / "unit0[01].csv.gz"), str(fleet_dir / "unit_c*"),
                 "-o", str(out), "--json", "-q", "--no-plot",
                 "--scheduler", cluster.scheduler.address])  # fmt: skip
    assert code == 1, "a failed unit must give a non-zero exit"
    cap = capsys.readouterr()
    assert "1 of 3 units failed" in cap.err
    assert "unit_corrupt: " in cap.err and "gzip" in cap.err
    summ = json.loads(cap.out)
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
    if len(tasks) < len(sizes) and all(s == sizes[0] for s in sizes):
        assert len(tasks) % w == 0, "equal units: every worker gets as many tasks"


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


# --------------------------------------------------------------------------
# issue 15: unit names, exit status, version in the cache key, channel parts
# --------------------------------------------------------------------------
def test_content_key_depends_on_the_imubounds_version(
    fleet_dir: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import imubounds.stationary.fleet.cache as fleet_cache

    src = fleet_dir / "unit00.csv.gz"
    k = content_key(src, FleetSettings())
    monkeypatch.setattr(fleet_cache, "__version__", "999.0")
    assert content_key(src, FleetSettings()) != k


def test_unit_names_are_paths_relative_to_the_common_folder(tmp_path: Path) -> None:
    from imubounds.stationary.fleet import unit_names

    a, b = tmp_path / "siteA" / "unit1.csv.gz", tmp_path / "siteB" / "deep" / "unit1.csv.gz"
    assert unit_names([a, b]) == ["siteA/unit1", "siteB/deep/unit1"]
    assert unit_names([a]) == ["unit1"]
    # two files differing only in their suffixes keep their whole names
    c = tmp_path / "siteA" / "unit1.csv"
    assert unit_names([a, c]) == ["unit1.csv.gz", "unit1.csv"]
    assert unit_names(["memory://x/siteA/u.csv", "memory://x/siteB/u.csv"]) == [
        "siteA/u", "siteB/u"]  # fmt: skip


def test_same_named_units_in_two_folders_stay_separate(fleet_dir: Path, tmp_path: Path) -> None:
    logs = tmp_path / "logs"
    for site, src in (("siteA", "unit00"), ("siteB", "unit03")):
        (logs / site).mkdir(parents=True)
        (logs / site / "unit1.csv.gz").write_bytes((fleet_dir / f"{src}.csv.gz").read_bytes())
    res = run_fleet([str(logs / "*" / "*.csv.gz")], tmp_path / "out", n_workers=0, plot=False)
    ok = res.table[res.table.status == "ok"]
    assert sorted(set(ok.unit)) == ["siteA/unit1", "siteB/unit1"]
    assert len(ok) == 12
    n = ok[ok.channel == "gyro_x"].set_index("unit")["N"] * 60 / DEG
    assert n["siteA/unit1"] == pytest.approx(0.5, rel=0.1)
    assert n["siteB/unit1"] == pytest.approx(1.5, rel=0.1), "unit03 is the 1.5 deg/sqrt(h) one"
    assert set(res.curves) == {"siteA/unit1", "siteB/unit1"}
    # the result draws its figure (report/fleet_plots): two bundles, N B K per kind
    import matplotlib.pyplot as plt

    fig = res.plot()
    assert len(fig.axes) == 2 + 2 * 3 and "Fleet of 2 units: 2 analysed" in fig._suptitle.get_text()
    plt.close(fig)


def test_cli_exits_1_with_a_failure_summary_even_when_quiet(
    fleet_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from imubounds.cli import main

    code = main(["fleet", str(fleet_dir / "unit00.csv.gz"), str(fleet_dir / "unit_c*"),
                 "-o", str(tmp_path / "o"), "--workers", "0", "-q", "--no-plot"])  # fmt: skip
    err = capsys.readouterr().err
    assert code == 1
    assert "1 of 2 units failed (exit 1)" in err and "unit_corrupt" in err
    assert "Traceback" not in err


def test_cli_fleet_writes_run_json_last_and_the_report_shows_the_command(
    fleet_dir: Path, tmp_path: Path
) -> None:
    """As every command: run.json (command, version, the files written) completes the set;
    the report says how to reproduce it; files of an earlier run there stay imubounds'."""
    from imubounds.cli import main

    out = tmp_path / "o"
    argv = ["static", str(fleet_dir / "unit00.csv.gz"), "-o", str(out), "--models", "none",
            "--no-plot", "--no-report", "-q"]  # fmt: skip
    assert main(argv) == 0  # an earlier run of another command in the same folder
    argv = ["fleet", str(fleet_dir / "unit0[01].csv.gz"), "-o", str(out), "--workers", "0",
            "-q", "--no-plot"]  # fmt: skip
    assert main(argv) == 2  # another command's results there: refused, unless --overwrite
    assert main([*argv, "--overwrite"]) == 0
    run = json.loads((out / "run.json").read_text())
    assert run["command_name"] == "fleet" and run["complete"] is True
    assert run["command"].startswith("imubounds fleet ") and "--workers 0" in run["command"]
    assert set(run["files"]) == {"fleet.parquet", "fleet.json", "report.html", "run.json"}
    assert run["n_units"] == 2 and run["n_failed"] == 0
    assert set(run["earlier_files"]) == {"noise.json", "imu.yaml"}
    assert "imubounds fleet " in (out / "report.html").read_text()
    # a library call writes no run.json of its own
    lib = tmp_path / "lib"
    run_fleet([str(fleet_dir / "unit00.csv.gz")], lib, n_workers=0, plot=False)
    assert not (lib / "run.json").exists()


@pytest.mark.parametrize("missing", ["no/such/unit.csv", "no_such_dir/*.csv.gz"])
def test_a_pattern_matching_nothing_is_an_error_among_others(
    fleet_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], missing: str
) -> None:
    """A missing path or an empty glob is a one-line error (exit 2), also when the other
    patterns match: a fleet never leaves units out unnoticed, and nothing is written."""
    from imubounds.cli import main

    out = tmp_path / "o"
    code = main(["fleet", str(fleet_dir / "unit00.csv.gz"), str(tmp_path / missing),
                 "-o", str(out), "-q", "--workers", "0"])  # fmt: skip
    err = capsys.readouterr().err.strip()
    assert code == 2
    assert "no log file matches" in err and missing in err and len(err.splitlines()) == 1, err
    assert "1 file(s) matched the other patterns" in err
    assert not (out / "fleet.json").exists()


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--outlier-z", "0"], "--outlier-z"),
        (["--compare", "no/such/dir"], "no fleet.parquet"),
        (["--workers", "-1"], "--workers"),
    ],
)
def test_cli_bad_fleet_options_are_one_line_errors(
    fleet_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], args: list[str],
    message: str,
) -> None:
    from imubounds.cli import main

    with pytest.raises(SystemExit) as exc:  # argparse exits; ImuboundsError returns 2
        code = main(["fleet", str(fleet_dir / "unit00.csv.gz"), "-o", str(tmp_path / "o"),
                     "-q", *args])  # fmt: skip
        raise SystemExit(code)
    assert exc.value.code == 2
    err = capsys.readouterr().err.strip()
    assert message in err and len(err.splitlines()) == 1, err


def test_channel_parts_together_are_the_whole_unit(fleet_dir: Path) -> None:
    from imubounds.stationary.fleet import plan_work
    from imubounds.stationary.fleet.unit import merge_parts

    src = str(fleet_dir / "unit01.csv.gz")
    whole = analyse_unit(src, FleetSettings())
    for n in (2, 3, 6):
        parts = [analyse_unit(src, FleetSettings(), (i, n)) for i in range(n)]
        merged = merge_parts(parts)
        assert [r["channel"] for r in merged["rows"]] == [r["channel"] for r in whole["rows"]]
        assert merged["rows"] == whole["rows"]
        for ch, c in whole["curves"].items():
            np.testing.assert_array_equal(merged["curves"][ch]["adev"], c["adev"])
    # one long log on 2 workers is split by channel; as many units as workers are not
    assert plan_work([10 << 20], 2) == [(0, (0, 2)), (0, (1, 2))]
    assert plan_work([10 << 20], 4) == [(0, (j, 6)) for j in range(6)]
    assert plan_work([10 << 20] * 2, 4) == [(i, (j, 2)) for i in range(2) for j in range(2)]
    assert plan_work([10 << 20] * 3, 2) == [(i, None) for i in range(3)]
    assert plan_work([1000], 2) == [(0, None)], "a short log is not worth splitting"
    assert plan_work([10 << 20], 1) == [(0, None)]


def test_a_long_log_split_by_channel_gives_the_whole_units_table(
    fleet_dir: Path, tmp_path: Path
) -> None:
    from dask.distributed import Client, LocalCluster

    src = [str(fleet_dir / "unit02.csv.gz")]
    whole = run_fleet(src, tmp_path / "a", n_workers=0, plot=False)
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=False,
                      dashboard_address=":0") as lc, Client(lc) as client:  # fmt: skip
        split = run_fleet(src, tmp_path / "b", client=client, plot=False, split_channels=True,
                          min_split_bytes=0)  # fmt: skip
    assert whole.n_tasks == 1 and split.n_tasks == 2
    pd.testing.assert_frame_equal(split.table, whole.table)
    # the cache holds the whole unit, not a part
    again = run_fleet(src, tmp_path / "b", n_workers=0, plot=False)
    assert again.n_cached == 1
    pd.testing.assert_frame_equal(again.table, whole.table)


# --------------------------------------------------------------------------
# issue 15: fsspec inputs
# --------------------------------------------------------------------------
def _put_in_memory(fleet_dir: Path, root: str) -> None:
    import fsspec

    fs = fsspec.filesystem("memory")
    for site, src in (("siteA", "unit00"), ("siteB", "unit01")):
        fs.pipe(f"{root}/{site}/unit.csv.gz", (fleet_dir / f"{src}.csv.gz").read_bytes())
    fs.pipe(f"{root}/siteB/broken.csv.gz", b"\x1f\x8b\x08\x00 not really gzip")


def _expected_n(fleet_dir: Path, unit: str) -> float:
    """gyro_x's N from the static pipeline on the local file (not from the fleet's own
    analyse_unit, which the URL runs go through)."""
    from imubounds.io import read_imu
    from imubounds.stationary.pipeline import StaticSettings, analyse_static

    alone = analyse_static(read_imu(fleet_dir / f"{unit}.csv.gz"), StaticSettings(models=()))
    return float(alone.channels["gyro_x"].fit.value("N"))


def test_fsspec_memory_urls_serial_in_process(fleet_dir: Path, tmp_path: Path) -> None:
    _put_in_memory(fleet_dir, "/imubounds-test-serial")
    res = run_fleet(["memory:///imubounds-test-serial/**/*.csv.gz"], tmp_path / "o",
                    n_workers=0, plot=False)  # fmt: skip
    ok = res.table[res.table.status == "ok"]
    assert sorted(set(res.table.unit)) == ["siteA/unit", "siteB/broken", "siteB/unit"]
    gx = ok[ok.channel == "gyro_x"].set_index("unit")["N"]
    assert gx["siteA/unit"] == pytest.approx(_expected_n(fleet_dir, "unit00"), rel=1e-12)
    assert gx["siteB/unit"] == pytest.approx(_expected_n(fleet_dir, "unit01"), rel=1e-12)
    # the failure names the URL, not the temporary local copy
    (bad,) = res.failed
    assert bad["error"].startswith("memory:///imubounds-test-serial/siteB/broken.csv.gz")
    # cached by content on the rerun
    res2 = run_fleet(["memory:///imubounds-test-serial/**/*.csv.gz"], tmp_path / "o",
                     n_workers=0, plot=False)  # fmt: skip
    assert res2.n_cached == 2


def test_fsspec_memory_urls_on_a_threads_dask_cluster(fleet_dir: Path, tmp_path: Path) -> None:
    """memory:// lives in one process: this covers the Dask path with in-process workers."""
    from dask.distributed import Client, LocalCluster

    _put_in_memory(fleet_dir, "/imubounds-test-dask")
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=False,
                      dashboard_address=":0") as lc, Client(lc) as client:  # fmt: skip
        res = run_fleet(["memory:///imubounds-test-dask/*/unit.csv.gz"], tmp_path / "o",
                        client=client, plot=False)  # fmt: skip
    assert res.ok
    gx = res.table[res.table.channel == "gyro_x"].set_index("unit")["N"]
    assert gx["siteB/unit"] == pytest.approx(_expected_n(fleet_dir, "unit01"), rel=1e-12)


def test_fsspec_file_urls_read_by_process_workers(
    fleet_dir: Path, tmp_path: Path, cluster  # noqa: ANN001
) -> None:
    """file:// URLs go through fsspec in separate worker processes (as s3:// would)."""
    url = f"file://{fleet_dir.as_posix()}/unit0[12].csv.gz"
    res = run_fleet([url], tmp_path / "o", client=cluster, plot=False)
    assert res.ok and sorted(set(res.table.unit)) == ["unit01", "unit02"]
    assert all(p.startswith("file://") for p in res.table.path)
    gx = res.table[res.table.channel == "gyro_x"].set_index("unit")["N"]
    assert gx["unit02"] == pytest.approx(_expected_n(fleet_dir, "unit02"), rel=1e-12)


class _StubStore:
    """An fsspec file system's ``info``/``ukey``, as a remote store would answer."""

    def __init__(self, info: dict[str, object]) -> None:
        self._info = info

    def info(self, path: str) -> dict[str, object]:
        return dict(self._info, name=path)

    def ukey(self, path: str) -> str:
        return "same-for-every-version"  # as fsspec's HTTPFileSystem: the URL only


def test_remote_fingerprint_takes_strong_validators_only() -> None:
    from imubounds.stationary.fleet import remote_fingerprint

    s3 = remote_fingerprint(_StubStore({"size": 10, "ETag": '"abc"'}), "b/u.csv")
    assert s3 is not None and "abc" in s3
    assert remote_fingerprint(_StubStore({"size": 10, "ETag": '"abd"'}), "b/u.csv") != s3
    gcs = _StubStore({"size": 10, "md5Hash": "q1==", "crc32c": "x", "updated": "t"})
    assert remote_fingerprint(gcs, "b/u.csv") is not None
    # a modification time (one-second steps) and a size do not show every change
    http = _StubStore({"size": 10, "Last-Modified": "Wed, 25 Nov 2026 19:10:08 GMT"})
    assert remote_fingerprint(http, "h/u.csv") is None
    assert remote_fingerprint(_StubStore({"size": 10, "ETag": ""}), "h/u.csv") is None


@pytest.fixture()
def http_root(tmp_path: Path):  # noqa: ANN201 - yields (folder, base URL)
    """A local HTTP server that sends Last-Modified and an ETag made as nginx makes it
    (modification second and size, not the content). fsspec's http:// needs aiohttp:
    the test extra installs it."""
    import functools
    import threading
    from http.server import SimpleHTTPRequestHandler, ThreadingHTTPServer

    class Quiet(SimpleHTTPRequestHandler):
        def log_message(self, format: str, *args: object) -> None:  # noqa: A002
            pass

        def end_headers(self) -> None:
            f = Path(self.translate_path(self.path))
            if f.is_file():
                st = f.stat()
                self.send_header("ETag", f'"{int(st.st_mtime):x}-{st.st_size:x}"')
            super().end_headers()

    root = tmp_path / "www"
    root.mkdir()
    server = ThreadingHTTPServer(("127.0.0.1", 0),
                                 functools.partial(Quiet, directory=str(root)))  # fmt: skip
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        yield root, f"http://127.0.0.1:{server.server_address[1]}"
    finally:
        server.shutdown()
        server.server_close()


def test_http_urls_globbed_analysed_and_cached_by_content(
    fleet_dir: Path, tmp_path: Path, http_root: tuple[Path, str]
) -> None:
    """http(s):// through fsspec from a real server; a log replaced by one of the same
    size within the same second (same Last-Modified and ETag) is analysed again, not
    taken from the cache."""
    import gzip

    root, base = http_root
    for site, src in (("siteA", "unit00"), ("siteB", "unit01")):
        (root / site).mkdir()
        (root / site / "unit.csv").write_bytes(gzip.decompress(
            (fleet_dir / f"{src}.csv.gz").read_bytes()))  # fmt: skip
    res = run_fleet([f"{base}/site*/unit.csv"], tmp_path / "o", n_workers=0, plot=False)
    assert res.ok and sorted(set(res.table.unit)) == ["siteA/unit", "siteB/unit"]
    gx = res.table[res.table.channel == "gyro_x"].set_index("unit")["N"]
    assert gx["siteA/unit"] == pytest.approx(_expected_n(fleet_dir, "unit00"), rel=1e-12)
    assert gx["siteB/unit"] == pytest.approx(_expected_n(fleet_dir, "unit01"), rel=1e-12)
    # same bytes again: both from the cache
    res2 = run_fleet([f"{base}/site*/unit.csv"], tmp_path / "o", n_workers=0, plot=False)
    assert res2.n_cached == 2
    # siteA's log rewritten with the same size: 100 gyro_x samples change their last digit
    p = root / "siteA" / "unit.csv"
    stamp = p.stat().st_mtime_ns
    lines = p.read_text().splitlines(keepends=True)
    for i in range(10, 1010, 10):
        f = lines[i].split(",")
        f[1] = f[1][:-1] + ("7" if f[1][-1] != "7" else "3")
        lines[i] = ",".join(f)
    p.write_text("".join(lines))
    os.utime(p, ns=(stamp, stamp))  # the same Last-Modified and ETag too
    res3 = run_fleet([f"{base}/site*/unit.csv"], tmp_path / "o", n_workers=0, plot=False)
    assert res3.n_cached == 1
    gx3 = res3.table[res3.table.channel == "gyro_x"].set_index("unit")["N"]
    assert gx3["siteA/unit"] != gx["siteA/unit"] and gx3["siteB/unit"] == gx["siteB/unit"]


def test_unknown_url_protocol_is_a_one_line_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from imubounds.cli import main

    code = main(["fleet", "nosuchproto://bucket/*.csv", "-o", str(tmp_path / "o"), "-q"])
    err = capsys.readouterr().err.strip()
    assert code == 2 and "nosuchproto://bucket/*.csv" in err and len(err.splitlines()) == 1


# --------------------------------------------------------------------------
# issue 15: fleet statistics, outliers, drift
# --------------------------------------------------------------------------
NOISY_UNIT, NOISY_FACTOR, N_STATS_UNITS = 5, 3.0, 8
GYRO_N, ACCEL_N = 0.5, 0.05  # deg/sqrt(h), m/s/sqrt(h)


def _stats_unit(i: int, factor: float, path: Path) -> None:
    from imubounds.stationary.noise_sim import NoiseSpec, simulate, write_csv

    spec = NoiseSpec.from_mapping(
        {"gyro": {"N": f"{GYRO_N * factor} deg/sqrt(h)", "B": "10 deg/h"},
         "accel": {"N": f"{ACCEL_N * factor} m/s/sqrt(h)", "B": "0.05 mg"}}
    )  # fmt: skip
    write_csv(simulate(spec, RATE, 300.0, seed=500 + i), path)


@pytest.fixture(scope="module")
def stats_fleet(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """8 units of 5 min; unit 5's white noise (N, gyro and accel) is 3x the others';
    a first run (previous) and a second run in which unit 2 became twice as noisy."""
    d = tmp_path_factory.mktemp("stats")
    for i in range(N_STATS_UNITS):
        _stats_unit(i, NOISY_FACTOR if i == NOISY_UNIT else 1.0, d / f"u{i}.csv.gz")
    (d / "spec.yaml").write_text("gyro:\n  N: 1.0 deg/sqrt(h)\n")
    prev = d / "run1"
    run_fleet([str(d / "u*.csv.gz")], prev, n_workers=0, spec=d / "spec.yaml", plot=False)
    _stats_unit(2, 2.0, d / "u2.csv.gz")
    return d, prev


def test_noisier_unit_is_the_only_outlier_on_n(stats_fleet: tuple[Path, Path]) -> None:
    _, prev = stats_fleet  # run1, before unit 2 changed
    table = pd.read_parquet(prev / "fleet.parquet")
    summ = json.loads((prev / "fleet.json").read_text())
    stats = summ["statistics"]
    assert stats["threshold_z"] == 3.5
    n_out = [o for o in stats["outliers"] if o["term"] == "N"]
    assert {o["unit"] for o in n_out} == {f"u{NOISY_UNIT}"}, n_out
    assert {o["channel"] for o in n_out} == {"gyro_x", "gyro_y", "gyro_z",
                                              "accel_x", "accel_y", "accel_z"}  # fmt: skip
    # the parquet carries the same flags; every other unit's |z| on N is below the threshold
    noisy = table.unit == f"u{NOISY_UNIT}"
    assert table[noisy]["N_outlier"].all() and not table[~noisy]["N_outlier"].any()
    assert (table[~noisy]["N_z"].abs() < 3.5).all()
    # z is consistent with the factor: value / median = exp(z * log_spread) ~ 3 (gyro)
    terms = {(r["channel"], r["term"]): r for r in stats["terms"]}
    for o in n_out:
        s = terms[(o["channel"], "N")]["log_spread"]
        # (equal for an odd count; for 8 units the median is the mean of the middle two)
        assert np.exp(o["z"] * s) == pytest.approx(o["ratio_to_median"], rel=1e-3)
        if o["kind"] == "gyro":
            assert o["ratio_to_median"] == pytest.approx(NOISY_FACTOR, rel=0.1)
            assert o["z"] > np.log(NOISY_FACTOR * 0.9) / s
    gx = terms[("gyro_x", "N")]
    assert gx["unit_ieee"] == "deg/h^0.5" and gx["unit_si"] == "rad/s^0.5"
    assert gx["median_ieee"] == pytest.approx(GYRO_N, rel=0.1)
    assert gx["n"] == N_STATS_UNITS and gx["spread"] > 0 and gx["iqr"] > 0
    # and against the datasheet: only the noisy unit fails N < 1 deg/sqrt(h)
    assert summ["spec"]["units_failing"] == [f"u{NOISY_UNIT}"]


def test_rerecorded_units_with_the_same_noise_do_not_drift(tmp_path: Path) -> None:
    """Every unit recorded again (new noise, same spec) and unit r0 at 2x white noise:
    only r0 drifts. Disjoint 1-sigma intervals alone would flag unchanged units about
    16 % of the time (a seed change is enough)."""
    from imubounds.stationary.noise_sim import NoiseSpec, simulate, write_csv

    def record(i: int, factor: float, seed: int) -> None:
        spec = NoiseSpec.from_mapping(
            {"gyro": {"N": f"{GYRO_N * factor} deg/sqrt(h)", "B": "10 deg/h"},
             "accel": {"N": f"{ACCEL_N * factor} m/s/sqrt(h)", "B": "0.05 mg"}}
        )  # fmt: skip
        write_csv(simulate(spec, RATE, 300.0, seed=seed), tmp_path / f"r{i}.csv.gz")

    for i in range(4):
        record(i, 1.0, 900 + i)
    first = run_fleet([str(tmp_path / "r*.csv.gz")], tmp_path / "run1", n_workers=0, plot=False)
    for i in range(4):
        record(i, 2.0 if i == 0 else 1.0, 950 + i)
    res = run_fleet([str(tmp_path / "r*.csv.gz")], tmp_path / "run2", n_workers=0, plot=False,
                    compare=tmp_path / "run1")  # fmt: skip
    d = res.drift
    assert res.n_cached == 0 and first.n_cached == 0
    assert res.summary()["drift"]["units_drifted"] == ["r0"]
    moved = d[d.drifted]
    assert set(moved.term) == {"N"} and set(moved.unit) == {"r0"} and len(moved) == 6
    assert np.allclose(moved.ratio, 2.0, rtol=0.1) and (moved.z > 10).all()
    same = d[(d.unit != "r0") & d.z.notna()]
    assert len(same) >= 18 and (same.z.abs() < 3.5).all()
    # the intervals alone (disjoint 1-sigma CIs) flag unchanged units here
    assert set(d[d.beyond_ci].unit) > {"r0"}
    # the table carries each unit's z and flag per term
    assert {"N_drift_z", "N_drifted"} <= set(res.table.columns)


def test_unresolved_terms_are_not_values() -> None:
    """A term the log did not resolve: no 'pass' on a fit's 0, a pass only when its upper
    bound is within the limit; left out of the fleet statistics."""
    from imubounds.stationary.fleet import FleetSpec, check_spec
    from imubounds.stationary.fleet_stats import fleet_statistics

    lim = 10.0 * DEG / 3600.0  # 10 deg/h
    rows = []
    for u, (b, status, ub) in enumerate([
        (3e-5, "resolved", 4e-5),       # resolved, below the limit: pass
        (9e-5, "resolved", 1e-4),       # resolved, above: fail
        (0.0, "upper_bound", 2e-5),     # not resolved, bound below the limit: pass
        (0.0, "upper_bound", 2e-4),     # not resolved, bound above: undetermined
        (1e-5, "upper_bound", 3e-4),    # kept by the fit but not resolved: undetermined
    ]):  # fmt: skip
        rows.append({"unit": f"u{u}", "channel": "gyro_x", "kind": "gyro", "status": "ok",
                     "N": 1e-4, "N_lo": 0.9e-4, "N_hi": 1.1e-4, "N_status": "resolved",
                     "B": b, "B_lo": 0.0 if status != "resolved" else 0.8 * b,
                     "B_hi": 1.2 * b if b else 1e-6, "B_status": status, "B_ub": ub,
                     "K": 0.0, "K_lo": 0.0, "K_hi": 1e-6, "K_status": "upper_bound",
                     "K_ub": 1e-6})  # fmt: skip
    table = pd.DataFrame(rows)
    pf = check_spec(table, FleetSpec(limits={"gyro": {"B": lim}}))
    got = dict(zip(pf.unit, pf.status, strict=True))
    assert got == {"u0": "pass", "u1": "fail", "u2": "pass", "u3": "undetermined",
                   "u4": "undetermined"}, got  # fmt: skip
    assert list(pf.basis) == ["value", "value", "upper_bound", "upper_bound", "upper_bound"]
    assert pf.value.iloc[2] == 2e-5  # the bound, not the fit's 0
    stats = fleet_statistics(table).table.set_index("term")
    assert stats.loc["B", "n"] == 2 and stats.loc["K", "n"] == 0 and stats.loc["N", "n"] == 5


def test_settings_every_unit_would_fail_on_are_refused_first(
    fleet_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from imubounds.cli import main

    with pytest.raises(OptionError, match="confidence"):
        run_fleet([str(fleet_dir / "unit0*.csv.gz")], tmp_path / "o", FleetSettings(confidence=1.5),
                  n_workers=0, plot=False)  # fmt: skip
    assert not (tmp_path / "o" / "fleet.parquet").exists()
    for args, needle in ((["--confidence", "1.5"], "--confidence"),
                         (["--task-size", "banana"], "--task-size 'banana' is not a size"),
                         (["--drift-z", "0"], "--drift-z")):  # fmt: skip
        code = main(["fleet", str(fleet_dir / "unit0*.csv.gz"), "-o", str(tmp_path / "c"),
                     "--workers", "0", "-q", *args])  # fmt: skip
        err = capsys.readouterr().err.strip()
        assert code == 2 and needle in err and len(err.splitlines()) == 1, err


def test_command_line_and_python_share_the_cache(fleet_dir: Path) -> None:
    """Read options at their default do not change the cache key."""
    s = FleetSettings()
    src = fleet_dir / "unit00.csv.gz"
    assert FleetSettings(read={"on_gap": "refuse"}).to_json() == s.to_json()
    # the command line passes on_gap="refuse" explicitly; Python leaves it out: one key
    assert content_key(src, FleetSettings(read={"on_gap": "refuse"})) == content_key(src, s)
    assert FleetSettings(read={"on_gap": "ignore"}).to_json() != s.to_json()
    assert content_key(src, FleetSettings(read={"on_gap": "ignore"})) != content_key(src, s)


def test_outlier_threshold_is_an_option(stats_fleet: tuple[Path, Path], tmp_path: Path) -> None:
    d, prev = stats_fleet
    # the noisy unit's gyro z is ~ln(3)/spread; a threshold above it flags nothing
    summ = json.loads((prev / "fleet.json").read_text())
    zmax = max(abs(o["z"]) for o in summ["statistics"]["outliers"])
    res = run_fleet([str(d / "u*.csv.gz")], tmp_path / "o", n_workers=0, plot=False,
                    outlier_z=zmax * 1.01)  # fmt: skip
    assert res.stats.outliers.empty and not res.table["outlier"].any()


def test_drift_since_the_previous_run(stats_fleet: tuple[Path, Path], tmp_path: Path) -> None:
    from imubounds.cli import main

    d, prev = stats_fleet
    out = tmp_path / "run2"
    code = main(["fleet", str(d / "u*.csv.gz"), "-o", str(out), "--workers", "0", "-q",
                 "--compare", str(prev), "--spec", str(d / "spec.yaml")])  # fmt: skip
    assert code == 0
    summ = json.loads((out / "fleet.json").read_text())
    drift = pd.DataFrame(summ["drift"]["rows"])
    n = drift[drift.term == "N"]
    changed = n[n.unit == "u2"]
    assert len(changed) == 6
    gyro = changed[changed.kind == "gyro"]
    assert np.allclose(gyro.ratio, 2.0, rtol=0.1), gyro.ratio
    np.testing.assert_allclose(gyro.diff_ieee, gyro.value_ieee - gyro.previous_ieee)
    assert (gyro.unit_ieee == "deg/h^0.5").all()
    # the other units' files did not change: ratio exactly 1, within the CIs
    same = drift[drift.unit != "u2"]
    known = same.ratio.notna()  # a term the short logs do not resolve has no ratio
    assert known[same.term == "N"].all()
    assert (same.ratio[known] == 1.0).all() and not same.beyond_ci.any()
    assert summ["drift"]["units_beyond_ci"] == ["u2"]
    table = pd.read_parquet(out / "fleet.parquet")
    for col in ("N_prev", "N_ratio", "N_diff", "N_z", "N_outlier", "B_z", "K_z", "outlier"):
        assert col in table.columns
    # the HTML report has the statistics, outlier and drift tables and both figures
    html = (out / "report.html").read_text()
    for text in ("Noise terms across units", "Outliers", "Drift since", "deg/h^0.5",
                 "box: quartiles", f"u{NOISY_UNIT}"):  # fmt: skip
        assert text in html, text
    assert html.count("data:image/png;base64") == 2


# --------------------------------------------------------------------------
# issue 25: matches that cannot be read, a scheduler option that is no address
# --------------------------------------------------------------------------
def test_a_dangling_link_or_a_fifo_among_the_matches_is_a_failed_unit(
    fleet_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Case 6: neither silently dropped ("2 units: 2 analysed") nor waited on (opening a
    FIFO blocks until a writer comes): each is a failed unit naming the file and why."""
    import threading

    from imubounds.cli import main

    units = tmp_path / "units"
    units.mkdir()
    for i in range(2):
        shutil.copy(fleet_dir / f"unit0{i}.csv.gz", units / f"u{i}.csv.gz")
    os.mkfifo(units / "pipe.csv.gz")
    (units / "link.csv.gz").symlink_to(tmp_path / "gone" / "u9.csv.gz")
    (units / "folder.csv.gz").mkdir()  # a folder is no log: not a unit
    got: dict[str, int] = {}
    run = threading.Thread(target=lambda: got.update(code=main(
        ["fleet", str(units / "*.csv.gz"), "-o", str(tmp_path / "o"), "--workers", "0", "-q",
         "--no-plot", "--no-report"])), daemon=True)  # fmt: skip
    run.start()
    run.join(120)
    assert not run.is_alive(), "the fleet blocked on the FIFO"
    err = capsys.readouterr().err
    assert got["code"] == 1, err
    assert "2 of 4 units failed" in err, err
    assert f"link: {units / 'link.csv.gz'}: cannot read: a symbolic link to " in err, err
    assert "which does not exist" in err, err
    assert f"pipe: {units / 'pipe.csv.gz'} is a named pipe (FIFO), not a regular file" in err
    summ = json.loads((tmp_path / "o" / "fleet.json").read_text())
    assert summ["n_units"] == 4 and summ["n_ok"] == 2, summ
    assert sorted(f["unit"] for f in summ["failed"]) == ["link", "pipe"]


@pytest.mark.parametrize("address", ["notaurl", "tcp://host", "127.0.0.1:port",
                                     "http://127.0.0.1:8786", "tcp://:8786"])  # fmt: skip
def test_a_scheduler_that_is_no_address_is_a_one_line_error(
    fleet_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], address: str
) -> None:
    """Case 19: not Dask's "missing port number" (exit 70) but exit 2 naming the option and
    the form expected, before anything is read or written."""
    from imubounds.cli import main

    code = main(["fleet", str(fleet_dir / "unit00.csv.gz"), "-o", str(tmp_path / "o"), "-q",
                 "--scheduler", address])  # fmt: skip
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1, err
    assert f"--scheduler {address!r}" in err and "tcp://host:port" in err, err
    assert not (tmp_path / "o").exists()


def test_scheduler_addresses_dask_takes_pass_the_check() -> None:
    from imubounds.stationary.fleet.execute import check_scheduler_address

    for address in ("tcp://127.0.0.1:8786", "127.0.0.1:8786", "tls://sched.example:8786",
                    "tcp://[::1]:8786", "inproc://10.0.0.1/123/1"):  # fmt: skip
        check_scheduler_address(address)  # no error
    with pytest.raises(OptionError, match="tcp://host:port"):
        check_scheduler_address("tcp://127.0.0.1:99999")
