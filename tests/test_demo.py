"""``imubounds demo`` (what ``make demo`` runs) end to end, from a relative output folder
as a user types it: one story about one IMU (the bundled ADIS16405: characterised,
a trip simulated with its noise, bounded in motion, filter parameters exported), and the
report's first screen (1400x900 in headless chromium) shows that IMU's summary."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest
import yaml

from imubounds.cli import main
from imubounds.export import FORMATS
from imubounds.io import bundled_static_log

FIRST_SCREEN_PROBE = """<script>
window.addEventListener('load', function () {
  var s = document.getElementById('summary');
  var r = s.getBoundingClientRect();
  var tables = Array.prototype.slice.call(s.querySelectorAll('table')).map(function (t) {
    var q = t.getBoundingClientRect(); return [Math.round(q.top), Math.round(q.bottom)];
  });
  var h2 = s.querySelector('h2');
  var details = Array.prototype.slice.call(document.querySelectorAll('details'));
  console.log('FIRST ' + JSON.stringify({
    top: Math.round(r.top), title: h2.textContent,
    title_bottom: Math.round(h2.getBoundingClientRect().bottom), tables: tables,
    open: details.filter(function (d) { return d.open; }).length,
    details: details.length, width: window.innerWidth, height: window.innerHeight}));
});
</script>"""


@pytest.mark.slow  # the whole story on the bundled data: about half a minute
def test_demo_tells_one_story_and_its_report_answers_first(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.chdir(tmp_path)
    code = main(["demo", "-o", "out", "-q"])
    err = capsys.readouterr().err
    assert code == 0, err
    out = Path("out")
    for f in ("static/noise.json", "sim/drive.yaml", "dynamic/dynamic.json",
              "dynamic/motion.json", "report.html", "run.json"):  # fmt: skip
        assert (out / f).is_file(), f
    assert not (out / "dynamic_vn100").exists()  # one IMU, not three
    # the trip's IMU has the noise measured from the bundled log, and the bounds use it
    scen = json.loads((out / "sim" / "scenario.json").read_text())
    assert Path(scen["config"]["imu_noise"]) == out / "static" / "noise.json"
    assert scen["true_values"]["imu"]["figures"]["preset"] == "noise.json"
    drive = yaml.safe_load((out / "sim" / "drive.yaml").read_text())
    assert drive["imu"]["noise_json"] == "imu_noise.json"
    assert (out / "sim" / "imu_noise.json").read_bytes() == (
        out / "static" / "noise.json"
    ).read_bytes()
    dyn = json.loads((out / "dynamic" / "dynamic.json").read_text())
    assert dyn["modes"]["full"]["guaranteed"] is True
    budget = dyn["modes"]["full"]["budget"]["gyro_z"]
    assert any(r["source"] == "noise.json" for r in budget)
    motion = json.loads((out / "dynamic" / "motion.json").read_text())
    assert motion["channels"]
    for fmt in FORMATS:  # every format, stationary and in motion, loads as YAML
        for name in (f"{fmt}.yaml", f"{fmt}_motion.yaml"):
            assert isinstance(yaml.safe_load((out / "filter" / name).read_text()), dict), name
    # one set of defaults: the demo's noise figures are a plain 'imubounds static''s
    plain = Path("plain")
    assert main(["static", str(bundled_static_log()), "-o", str(plain), "--no-plot",
                 "--no-report", "-q"]) == 0  # fmt: skip
    demo_doc = json.loads((out / "static" / "noise.json").read_text())
    plain_doc = json.loads((plain / "noise.json").read_text())
    assert demo_doc["settings"] == plain_doc["settings"]
    assert json.dumps(demo_doc["channels"], sort_keys=True) == json.dumps(
        plain_doc["channels"], sort_keys=True)
    # a verdict within 5 % of its band is marked fragile, in dynamic.json and the report
    full = dyn["modes"]["full"]
    for ch in full["fragile_verdicts"]:
        assert full["verdict_detail"][ch]["fragile_detail"].startswith("FRAGILE")
    html = (out / "report.html").read_text()
    for ch in full["fragile_verdicts"]:
        assert f"{full['verdict'][ch]} — FRAGILE (not decided)" in html
    # every command of the run, the simulation and each export included
    reproduce = html[html.index("id='reproduce'"):]
    for step in ("imubounds demo", "imubounds static", "imubounds simulate",
                 "imubounds dynamic"):  # fmt: skip
        assert step in reproduce, step
    assert reproduce.count("imubounds export") == 2 * len(FORMATS)
    from imubounds.report.html import build_report

    again = build_report(out)  # 'imubounds report out' later: the commands from run.json
    assert again[again.index("id='reproduce'"):].count("imubounds export") == 2 * len(FORMATS)
    assert "Summary — adis16405_imu1_extract.csv.gz" in html
    assert "Stationary characterisation" in html and "Dynamic error margins" in html
    assert html.count("<section id='dynamic") == 1
    assert "did not use the static log" not in html  # the trip was bounded with its noise

    # the first screen at 1400x900 in headless chromium: the summary of this one IMU
    from PIL import Image

    from tests.test_report import _render

    probed = tmp_path / "first.html"
    probed.write_text(html.replace("</body>", FIRST_SCREEN_PROBE + "</body>"))
    lines = _render(probed, tmp_path / "first.png", tmp_path / "profile", size="1400,900")
    probe = [ln for ln in lines if "FIRST " in ln]
    assert len(probe) == 1, lines
    info = json.loads(re.search(r"FIRST (\{.*\})", probe[0]).group(1))  # type: ignore[union-attr]
    # the viewport of a 1400x900 window (headless chromium keeps room for its own bars)
    assert info["width"] == 1400 and 600 < info["height"] <= 900, info
    screen = info["height"]
    assert info["title"].startswith("Summary — adis16405")
    assert 0 <= info["top"] < 200 and info["title_bottom"] < 300
    # the noise-term table (N, B, K of every channel) lies wholly on the first screen,
    # and the in-motion table starts on it
    assert info["tables"][0][1] <= screen, info
    assert info["tables"][1][0] < screen, info
    assert info["open"] == 0 and info["details"] >= 2  # the details wait, collapsed
    shot = np.asarray(Image.open(tmp_path / "first.png").convert("RGB"), dtype=float)
    assert shot.shape == (900, 1400, 3)
    assert (shot < 128).mean() > 0.01  # text rendered, not a blank page
