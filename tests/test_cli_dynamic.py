"""``imubounds dynamic`` end to end: drive layouts, real drives, outputs, bad input."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import imubounds.cli as cli
from imubounds.io.drive.layout import write_layout
from tests.trips import make_trip


@pytest.fixture()
def main(monkeypatch: pytest.MonkeyPatch):  # type: ignore[no-untyped-def]
    mods = tuple(dict.fromkeys((*cli.COMMAND_MODULES, "dynamic", "simulate")))
    monkeypatch.setattr(cli, "COMMAND_MODULES", mods)
    return cli.main


@pytest.fixture(scope="module")
def layout_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    drive, _ = make_trip("paper", 7, duration_s=240.0, distance_m=2600.0, corner_m=80.0,
                         imu_hz=50.0)
    return write_layout(drive, tmp_path_factory.mktemp("drive") / "trip")


#: Verdicts known on the simulated trip (layout_dir): every input lies within its stated
#: bound, so mode full finds every channel consistent (a sound margin cannot exceed, and
#: the aided windows are decidable); mode paper's per-step margins are tens of times its
#: stationary level (1.96 N sqrt(T)): supersets of it, ``exceeds``.
TRIP_VERDICTS = {"full": "consistent", "paper": "exceeds"}


def _schema(doc: dict, modes: set[str], verdicts: dict[str, str] | None = None) -> None:
    """The document's shape; with ``verdicts`` (mode -> expected verdict), every channel's
    verdict in that mode."""
    assert doc["schema_version"] == "imubounds-dynamic/3"
    assert set(doc["modes"]) == modes
    for name, m in doc["modes"].items():
        assert {"margins", "verdict", "budget"} <= set(m)
        if verdicts is not None:
            assert set(m["verdict"].values()) == {verdicts[name]}, (name, m["verdict"])
        for ch in ("accel_x", "accel_y", "gyro_z"):
            assert m["verdict"][ch] in ("consistent", "exceeds", "undecided")
            for row in m["margins"][ch]:
                assert {"tau_s", "halfwidth_max", "halfwidth_median", "stationary",
                        "exceeds_fraction"} <= set(row)
            assert m["budget"][ch], name
        assert m["guaranteed"] is (name == "full")


def test_dynamic_on_a_drive_layout(main, layout_dir: Path, tmp_path: Path,  # type: ignore[no-untyped-def]
                                   capsys: pytest.CaptureFixture) -> None:
    out = tmp_path / "out"
    assert main(["dynamic", str(layout_dir), "-o", str(out), "--no-report"]) == 0
    names = {p.name for p in out.iterdir()}
    for n in ("dynamic.json", "margins.csv", "states.csv", "steps.csv", "run.json",
              "margins.png", "windows.png", "trajectory.png", "intervals.png"):
        assert n in names, n
    assert not [n for n in names if n.startswith(".")]  # no temporary leftovers
    doc = json.loads((out / "dynamic.json").read_text())
    _schema(doc, {"full", "paper"}, TRIP_VERDICTS)
    full = doc["modes"]["full"]
    for q in ("position", "heading", "u", "v", "bias_accel_x", "bias_gyro_z"):
        assert full["enclosure"][q] == 1.0, (q, full["enclosure"])
    margins = pd.read_csv(out / "margins.csv")
    assert set(margins["channel"]) == set(full["margins"])
    states = pd.read_csv(out / "states.csv")
    assert {"time_s", "east_lo_m", "east_hi_m", "heading_lo_rad", "u_lo_mps"} <= set(states.columns)
    assert len(states) == full["smoother"]["epochs"]
    out_text = capsys.readouterr().out  # the summary is on stdout, as static's
    assert "mode full (guaranteed" in out_text and "mode paper (NOT guaranteed)" in out_text
    motion = json.loads((out / "motion.json").read_text())
    assert motion["format"] == "imubounds.motion/1" and set(motion["channels"]) <= set(
        full["margins"])


def test_dynamic_mode_full_only_and_json(main, layout_dir: Path, tmp_path: Path,  # type: ignore[no-untyped-def]
                                         capsys: pytest.CaptureFixture) -> None:
    out = tmp_path / "o"
    code = main(["dynamic", str(layout_dir), "-o", str(out), "--mode", "full", "--no-plot",
                 "--no-report", "--json", "-q", "--lateral-speed-bound", "0.2", "--alpha", "0.05"])
    assert code == 0
    doc = json.loads(capsys.readouterr().out)
    _schema(doc, {"full"}, TRIP_VERDICTS)
    assert not (out / "steps.csv").exists()
    assert doc["modes"]["full"]["alpha"]["alpha"] == 0.05
    # one setting, one name: --lateral-speed-bound is vehicle.lateral_speed_bound_mps
    assert doc["modes"]["full"]["vehicle"]["lateral_speed_bound_mps"] == 0.2
    assert doc["modes"]["full"]["vehicle"]["sources"]["lateral_speed_bound_mps"] == "option"


def test_dynamic_static_noise_json(main, layout_dir: Path, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    noise = {
        "channels": {
            ch: {"stationary": {"N": n, "B": b}}
            for ch, n, b in (("accel_x", 0.004, 0.03), ("accel_y", 0.005, 0.03),
                             ("accel_z", 0.004, 0.03), ("gyro_x", 0.001, 0.02),
                             ("gyro_y", 0.001, 0.02), ("gyro_z", 0.001, 0.02))
        }
    }
    nj = tmp_path / "noise.json"
    nj.write_text(json.dumps(noise))
    out = tmp_path / "o"
    assert main(["dynamic", str(layout_dir), "--static", str(nj), "-o", str(out), "-q",
                 "--no-plot", "--no-report", "--mode", "full"]) == 0
    doc = json.loads((out / "dynamic.json").read_text())
    rows = {r["term"]: r for r in doc["modes"]["full"]["budget"]["accel_y"]}
    assert rows["white noise density N"]["value"] == 0.005
    assert rows["white noise density N"]["source"] == "noise.json"


def test_dynamic_vn100(main, shared_data: Path, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    out = tmp_path / "vn"
    d = shared_data / "dynamic" / "vn100_bu353_circle"
    assert main(["dynamic", str(d), "-o", str(out), "-q", "--no-report"]) == 0
    doc = json.loads((out / "dynamic.json").read_text())
    _schema(doc, {"full", "paper"})
    assert any("mounted backwards" in w for w in doc["input"]["warnings"])
    files = sorted(str(p) for p in d.glob("*.csv"))  # the two CSV files work too
    assert main(["dynamic", *files, "-o", str(tmp_path / "vn2"), "-q", "--no-plot",
                 "--no-report", "--mode", "paper"]) == 0


def test_dynamic_vn100_console_says_why_undecided(main, shared_data: Path, tmp_path: Path,  # type: ignore[no-untyped-def]
                                                   capsys: pytest.CaptureFixture) -> None:
    """A channel whose margins are wider than its band at every tau is not a bare
    'undecided' on the console: the line gives the margin closest to the band, and the
    dominant term's note says what to state (the VN-100 car: no lateral-velocity bound)."""
    out = tmp_path / "vn"
    d = shared_data / "dynamic" / "vn100_bu353_circle"
    assert main(["dynamic", str(d), "-o", str(out), "--mode", "full", "--no-report",
                 "--no-plot"]) == 0
    text = capsys.readouterr().out
    doc = json.loads((out / "dynamic.json").read_text())
    full = doc["modes"]["full"]
    lines = {ln.split()[0]: ln for ln in text.splitlines()
             if ln.startswith("    ") and ln.split() and ln.split()[0] in full["verdict"]}
    nothing = [ch for ch, rows in full["margins"].items()
               if rows and not any(r.get("decidable_fraction", 0) > 0 for r in rows)]
    assert "accel_x" in nothing  # the transport term takes the speed bound
    for ch in nothing:
        assert "wider than the band at every tau" in lines[ch], lines[ch]
        assert "closest at tau" in lines[ch]
    assert "vehicle.lateral_speed_bound_mps" in text.split(lines["accel_x"])[1].splitlines()[1]


def test_dynamic_comma2k19_encloses_truth(main, shared_data: Path, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    out = tmp_path / "c"
    d = shared_data / "dynamic" / "comma2k19_example1"
    assert main(["dynamic", str(d), "-o", str(out), "-q", "--no-report", "--no-plot"]) == 0
    doc = json.loads((out / "dynamic.json").read_text())
    enc = doc["modes"]["full"]["enclosure"]
    assert (enc["position"], enc["speed"], enc["heading"]) == (1.0, 1.0, 1.0), enc
    assert len(doc["modes"]["full"]["margins"]["gyro_z"]) >= 8


def test_dynamic_simulator_directory(main, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    """The directory written by imubounds simulate (the demo) runs."""
    sim = tmp_path / "sim"
    assert main(["simulate", "-o", str(sim), "--duration", "100", "--distance", "1000",
                 "-q"]) == 0
    out = tmp_path / "o"
    assert main(["dynamic", str(sim), "-o", str(out), "-q", "--no-plot", "--no-report"]) == 0
    doc = json.loads((out / "dynamic.json").read_text())
    assert doc["input"]["layout"] == "generic"
    assert doc["modes"]["full"]["enclosure"]["position"] == 1.0


def test_bad_inputs(main, shared_data: Path, tmp_path: Path,  # type: ignore[no-untyped-def]
                    capsys: pytest.CaptureFixture) -> None:
    assert main(["dynamic", str(tmp_path / "nope"), "-o", str(tmp_path / "o")]) == 2
    assert "no such file or directory" in capsys.readouterr().err
    # GPS all missing on the VN-100 layout
    vn = tmp_path / "vn"
    vn.mkdir()
    src = shared_data / "dynamic" / "vn100_bu353_circle"
    shutil.copy(src / "circle_data_0_imu.csv", vn / "a_imu.csv")
    g = pd.read_csv(src / "circle_data_0_gps.csv")
    g["latitude"] = np.nan
    g.to_csv(vn / "a_gps.csv", index=False)
    assert main(["dynamic", str(vn), "-o", str(tmp_path / "o")]) == 2
    assert "no usable GPS fix" in capsys.readouterr().err
    for argv, msg in (
        (["--alpha", "2"], "--alpha"),
        (["--max-tilt", "-1"], "--max-tilt"),
        (["--imu-spec", "x=1"], "--imu-spec"),
        (["--gps-box", "p=2"], "--gps-box"),
        (["--static", str(tmp_path / "none.json")], "noise.json"),
    ):
        try:
            code = main(["dynamic", str(src), "-o", str(tmp_path / "o"), "--no-plot", *argv])
        except SystemExit as exc:  # argparse refuses a bad option value at parse time
            code = exc.code
        assert code == 2, argv
        err = capsys.readouterr().err
        assert msg in err, (argv, err)
        assert "Traceback" not in err


def test_dynamic_console_names_the_corrections_applied(main, tmp_path: Path,  # type: ignore[no-untyped-def]
                                                        capsys: pytest.CaptureFixture) -> None:
    """A compass 3 deg off and GNSS stamps 0.3 s late, as a user's files would have them:
    the console says, before the verdicts, what mode full estimated from the data and took
    off (the compass offset with its interval, the GNSS clock offset), and the clean trip
    says nothing of the kind."""
    sim = tmp_path / "sim"
    assert main(["simulate", "-o", str(sim), "--aiding", "gnss,gnss-vel,compass", "--seed",
                 "4", "-q"]) == 0
    out = tmp_path / "clean"
    assert main(["dynamic", str(sim), "-o", str(out), "--no-plot", "--no-report"]) == 0
    assert "applied:" not in capsys.readouterr().out
    h = pd.read_csv(sim / "heading.csv")
    h["heading_deg"] = (h["heading_deg"] + 3.0) % 360.0
    h.to_csv(sim / "heading.csv", index=False)
    g = pd.read_csv(sim / "gnss.csv")
    g["time_s"] += 0.3
    g.to_csv(sim / "gnss.csv", index=False)
    out = tmp_path / "faulty"
    assert main(["dynamic", str(sim), "-o", str(out), "--no-plot"]) == 0
    text = capsys.readouterr().out
    full = text.split("mode full")[1].split("mode paper")[0]
    lines = [ln.strip() for ln in full.splitlines() if ln.strip().startswith("applied:")]
    assert len(lines) == 2, full
    # the heading clock, whose default allowance the turn test cannot check with the GNSS
    # stamps late, is bounded from the data: said, not counted as a correction
    assert all(ln.strip().startswith(("applied:", "bounded:")) for ln in full.splitlines()
               if "clock offset" in ln), full
    gnss = next(ln for ln in lines if "gnss clock offset" in ln)
    lo, hi = (float(x) for x in gnss.split("[")[1].split("]")[0].split(","))
    assert lo <= 0.3 <= hi, gnss
    comp = next(ln for ln in lines if "compass error" in ln)
    lo, hi = (float(x) for x in comp.split("offset ")[1].split("[")[1].split("]")[0].split(","))
    assert lo <= 3.0 <= hi, comp
    doc = json.loads((out / "dynamic.json").read_text())
    assert doc["modes"]["full"]["guaranteed"] is True
    assert doc["modes"]["full"]["enclosure"]["heading"] == 1.0
    html = (out / "report.html").read_text()  # the report says it too, above the verdicts
    assert html.index("Applied: compass error") < html.index("id='verdict'")
    assert "Applied: gnss clock offset" in html
