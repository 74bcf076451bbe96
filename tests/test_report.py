"""The HTML report: content of ``imubounds report DIR`` on a real static + dynamic run,
and the page in a real headless browser (Debian chromium).

The run: ``imubounds static`` on the ROS 2 bag sample (600 real ADIS16405
samples) and the dynamic estimator on the real VN-100/BU-353N drive.
"""

from __future__ import annotations

import argparse
import base64
import json
import os
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from imubounds import __version__
from imubounds.cli import main as cli_main
from imubounds.report.html import build_report

FORMATS = Path(__file__).parent / "data" / "formats"
VN100 = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "dynamic" / (
    "vn100_bu353_circle")
CHROMIUM_NAMES = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")
CHROMIUM_FLAGS = (
    "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
    "--disable-background-networking", "--disable-component-update", "--disable-sync",
    "--enable-logging=stderr", "--v=0",
)


def _run_dynamic(out: Path) -> None:
    from imubounds.cli import dynamic

    p = argparse.ArgumentParser()
    dynamic.register(p.add_subparsers())
    argv = ["dynamic", str(VN100), "-o", str(out), "-q"]
    args = p.parse_args(argv)
    args.argv = argv
    assert args.func(args) == 0


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("run")
    code = cli_main(["static", str(FORMATS / "adis_ros2"), "-o", str(root / "static"), "-q",
                     "--tau", "points:20", "--no-report"])
    assert code == 0
    if VN100.is_dir():
        _run_dynamic(root / "dynamic")
    code = cli_main(["report", str(root), "-q"])
    assert code == 0
    return root


@pytest.fixture(scope="module")
def page(run_dir: Path) -> str:
    return (run_dir / "report.html").read_text(encoding="utf-8")


def test_static_content(run_dir: Path, page: str) -> None:
    noise = json.loads((run_dir / "static" / "noise.json").read_text())
    assert "<section id='static'>" in page
    assert "adis_ros2:/imu/data" in page  # the input (a ROS 2 bag topic)
    assert "FLU" in page and "in rad/s" in page  # frame and input units
    assert "overlapping" in page and "weighted least-squares fit" in page
    # the noise table in IEEE and SI units, with the numbers of noise.json
    assert "deg/h^0.5" in page and "rad/s^0.5" in page and "m/s/h^0.5" in page
    n_ieee = noise["channels"]["gyro_z"]["noise"]["fit"]["N"]["ieee"]["value"]
    assert f"{n_ieee:.4g} deg/h^0.5" in page
    n_si = noise["channels"]["accel_x"]["noise"]["fit"]["N"]["value"]
    assert f"{n_si:.4g} m/s^1.5" in page
    assert "Stochastic models" in page and "GM correlation time" in page
    assert "Stationary bounds" in page and "95 % level" in page


@pytest.mark.skipif(not VN100.is_dir(), reason="real VN-100 drive not beside the repository")
def test_dynamic_content(run_dir: Path, page: str) -> None:
    dyn = json.loads((run_dir / "dynamic" / "dynamic.json").read_text())
    assert "<section id='dynamic'>" in page
    assert "Mode full — guaranteed" in page and "Mode paper — NOT guaranteed" in page
    assert "Verdicts: the IMU error during the trip vs the stationary band" in page
    full = dyn["modes"]["full"]
    for ch, v in full["verdict"].items():
        assert f"<b>{ch}</b>: <span" in page and v in page
    # the budget tables, the contracted aiding bounds and the probability split are shown
    # one budget table for the IMU channels (not one per channel), one for the aiding
    assert page.count("Error budget of the IMU channels") == 1
    assert "Error budget — " not in page and "turn-on bias (1 sigma)" in page
    assert "Error budget of the aiding sensors" in page
    # the in-motion figures per tau (motion.json) beside the stationary prediction
    motion = json.loads((run_dir / "dynamic" / "motion.json").read_text())
    assert "In motion: guaranteed bound vs stationary prediction" in page
    ch, c = next(iter(motion["channels"].items()))
    assert f"{c['rows'][-1]['inflation']:.3g}" in page
    assert "Aiding sensors: input vs contracted half-widths" in page
    assert "Whole-trip probability split" in page
    assert f"Empty intersections: {full['empty_intersections']['count']}" in page
    assert "mounted backwards" in page  # reader warnings reach the warnings section


def test_figures_embedded_and_self_contained(run_dir: Path, page: str) -> None:
    imgs = re.findall(r'src="data:image/png;base64,([A-Za-z0-9+/=]+)"', page)
    # the key figures first, open (Figures), then the details' figures once each
    expected = [run_dir / "static" / "allan.png"]
    if VN100.is_dir():
        expected += [run_dir / "dynamic" / f"{s}.png" for s in ("windows", "motion")]
    if (run_dir / "static" / "stationarity.png").is_file():
        expected.append(run_dir / "static" / "stationarity.png")
    if VN100.is_dir():
        expected += [run_dir / "dynamic" / f"{s}.png" for s in
                     ("margins", "trajectory", "intervals")]
    assert len(imgs) == len(expected)
    for data, path in zip(imgs, expected, strict=True):
        assert base64.b64decode(data) == path.read_bytes()
    # nothing is fetched from elsewhere
    assert not re.search(r"""(src|href)\s*=\s*["']?(https?:|//|file:)""", page)
    assert "<link" not in page and "@import" not in page


def test_warnings_and_reproduce(run_dir: Path, page: str) -> None:
    assert "<section id='warnings'>" in page and "<section id='reproduce'>" in page
    run = json.loads((run_dir / "static" / "run.json").read_text())
    assert run["command"].startswith("imubounds static ")
    assert run["command"].replace("/", "&#x2F;") in page or run["command"] in page
    # the version is not on the package index: install from the source tree
    assert f"imubounds=={__version__}" not in page and "pip install -e ." in page


def test_report_errors_are_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert cli_main(["report", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no noise.json or dynamic.json found" in err[0]
    (tmp_path / "noise.json").write_text("{not json")
    assert cli_main(["report", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "noise.json: not readable JSON" in err[0]


def test_report_only_dynamic(run_dir: Path, tmp_path: Path) -> None:
    if not VN100.is_dir():
        pytest.skip("real VN-100 drive not beside the repository")
    shutil.copytree(run_dir / "dynamic", tmp_path / "d")
    html = build_report(tmp_path / "d")
    assert "<section id='dynamic'>" in html and "<section id='static'>" not in html


# ----------------------------------------------------------------------------- browser
def _chromium() -> str:
    for name in CHROMIUM_NAMES:
        path = shutil.which(name)
        if path:
            return path
    msg = ("headless browser test needs Debian chromium: apt-get install -y chromium "
           f"(none of {', '.join(CHROMIUM_NAMES)} on PATH)")
    if os.environ.get("CI", "").lower() in ("1", "true", "yes"):
        pytest.fail(msg)
    pytest.skip(msg)


def _render(html: Path, shot: Path, profile: Path, size: str = "1280,4000") -> list[str]:
    """Load ``html`` in headless chromium, write a screenshot (1280x4000); console lines."""
    cmd = [_chromium(), *CHROMIUM_FLAGS, f"--user-data-dir={profile}",
           "--virtual-time-budget=5000", f"--screenshot={shot}", f"--window-size={size}",
           "--hide-scrollbars", html.resolve().as_uri()]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=120, check=False)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert shot.is_file(), proc.stderr[-2000:]
    return [line for line in proc.stderr.splitlines() if ":CONSOLE" in line]


# the details are collapsed as written: open them all to see every figure
OPEN_ALL = """<script>
document.querySelectorAll('details').forEach(function (d) { d.open = true; });
</script>"""

PROBE = """<script>
window.addEventListener('load', function () {
  var imgs = Array.prototype.slice.call(document.images);
  var rects = imgs.map(function (i) {
    var r = i.getBoundingClientRect();
    return [Math.round(r.left), Math.round(r.top), Math.round(r.width), Math.round(r.height),
            i.complete && i.naturalWidth > 0 ? 1 : 0];
  });
  console.log('PROBE ' + JSON.stringify(rects));
});
</script>"""


def test_page_in_headless_chromium(run_dir: Path, tmp_path: Path) -> None:
    from PIL import Image

    # 1. The report as written: no console output at all (no errors, no warnings).
    shot = tmp_path / "report.png"
    console = _render(run_dir / "report.html", shot, tmp_path / "profile1")
    assert console == [], console
    keep = os.environ.get("IMUBOUNDS_KEEP_SCREENSHOT")
    if keep:
        shutil.copy(shot, keep)
    # 2. The same page with a probe script: every image decoded, and where it is.
    probed = tmp_path / "probed.html"
    probed.write_text((run_dir / "report.html").read_text().replace(
        "</body>", OPEN_ALL + PROBE + "</body>"))
    lines = _render(probed, tmp_path / "probed.png", tmp_path / "profile2")
    probe = [ln for ln in lines if "PROBE " in ln]
    assert len(probe) == 1 and len(lines) == 1, lines
    rects = json.loads(re.search(r"PROBE (\[.*\])", probe[0]).group(1))  # type: ignore[union-attr]
    n_figs = (run_dir / "report.html").read_text().count("<img")
    assert n_figs >= (4 if VN100.is_dir() else 1)
    assert len(rects) == n_figs
    assert all(r[4] == 1 and r[2] > 400 and r[3] > 150 for r in rects), rects
    # 3. The screenshot shows the figures: inside each visible image rectangle the pixels
    #    vary and include plot colours (not a blank or broken-image box).
    img = np.asarray(Image.open(tmp_path / "probed.png").convert("RGB"), dtype=float)
    assert img.shape == (4000, 1280, 3)
    seen = 0
    for left, top, width, height, _ in rects:
        if top + 50 >= img.shape[0]:
            continue
        box = img[top: min(top + height, img.shape[0]), left: left + width]
        sat = box.max(axis=2) - box.min(axis=2)
        assert box.std() > 20.0
        assert (sat > 60).mean() > 0.002, "no coloured plot lines in the figure area"
        seen += 1
    assert seen >= 1
    # the page is not blank outside the figures either (tables rendered)
    assert (img < 128).mean() > 0.01


def test_every_dynamic_directory_gets_a_section(run_dir: Path, tmp_path: Path) -> None:
    import shutil

    from imubounds.report.html import build_report

    root = tmp_path / "run"
    shutil.copytree(run_dir, root)
    if not (root / "dynamic").is_dir():
        pytest.skip("no dynamic run in the fixture (real VN-100 drive not beside the repository)")
    shutil.copytree(root / "dynamic", root / "dynamic_second")
    page = build_report(root)
    assert "<section id='dynamic'>" in page
    assert "<section id='dynamic-dynamic_second'>" in page
    assert "Dynamic error margins — dynamic_second" in page


def test_save_figure_lays_out_once_and_restores_the_engine(tmp_path: Path) -> None:
    """PNG then SVG with the layout of the first save; the figure's engine comes back."""
    from matplotlib.figure import Figure

    from imubounds.report.static_plots import save_figure

    fig = Figure(layout="constrained")
    ax = fig.subplots()
    ax.set_xscale("log")
    ax.plot([1.0, 10.0, 100.0], [3.0, 2.0, 1.0])
    ax.set_ylabel("Allan deviation (deg/h)")
    engine = fig.get_layout_engine()
    paths = save_figure(fig, tmp_path / "f")
    assert [p.suffix for p in paths] == [".png", ".svg"]
    assert all(p.stat().st_size > 1000 for p in paths)
    assert "<svg" in (tmp_path / "f.svg").read_text()
    assert fig.get_layout_engine() is engine
    pos = ax.get_position().bounds
    fig.savefig(tmp_path / "again.png", dpi=130)  # laid out anew by the engine
    assert np.allclose(ax.get_position().bounds, pos)


def test_summary_first_and_details_collapsed(run_dir: Path, page: str) -> None:
    """The answer first: a summary of the static log's IMU, then the details collapsed."""
    main_part = page[page.index("<main>"):]
    assert main_part.startswith("<main><section id='summary'><h2>Summary — ")
    summary = main_part[: main_part.index("</section>")]
    noise = json.loads((run_dir / "static" / "noise.json").read_text())
    for ch, c in noise["channels"].items():
        n = c["noise"]["selected"]["N"]["datasheet"]
        assert f"<td class='l'>{ch}</td>" in summary
        assert f"{n['value']:.3g} {n['unit']}" in summary  # N in datasheet units
    assert "What is not guaranteed" in summary and "Filter parameters" in summary
    assert "gyroscope_noise_density" in summary
    if VN100.is_dir():
        assert "In motion" in summary and "in-motion factor F" in summary
        # the VN-100 drive was bounded with its datasheet preset, not this noise.json:
        # the summary says so rather than pass its verdicts off as this IMU's
        assert "did not use the static log's noise.json" in summary
    # every detail section is collapsed (a <details> without 'open')
    for sid in ("static", "dynamic"):
        if f"<section id='{sid}'>" in page:
            assert f"<section id='{sid}'><details><summary>" in page
    assert "<details open" not in page
    # the title names the run folder, never a staging folder
    assert ".imubounds-" not in page[: page.index("</header>")]


def test_title_is_the_output_folder_not_the_staging_folder(run_dir: Path, tmp_path: Path) -> None:
    staged = tmp_path / ".out.imubounds-1234-abcd1234"
    shutil.copytree(run_dir / "static", staged)
    html = build_report(staged)
    assert "<title>imubounds report — out</title>" in html


def test_allan_labels_sigma_min_in_the_axis_unit() -> None:
    """allan.png: σ_min is written in the unit of its axis (deg/h for gyros), not deg/s."""
    import math

    import imubounds as ib
    from imubounds.report.static_plots import _format_terms

    res = ib.characterize(ib.read_log(FORMATS / "adis_ros2"), taus=20, models=())
    ch = res.channels["gyro_z"]
    label = _format_terms(ch).splitlines()[-1]
    sm = ch.selected.sigma_min
    want = sm["value"] * 180 / math.pi * 3600  # rad/s -> deg/h
    assert label.startswith(f"σ_min = {want:.3g} deg/h"), label
    assert "deg/s" not in label


def test_static_checks_misfit_record_length_stationarity_timing(tmp_path: Path) -> None:
    """The noise.json's misfit, record_length, stationarity (with a warm-up and its
    figure) and timing blocks are shown in the details, with one summary line."""
    from PIL import Image

    import imubounds as ib
    from imubounds.io import bundled_static_log
    from imubounds.io.outputs import to_jsonable
    from imubounds.stationary.stationarity import Warmup

    doc = to_jsonable(ib.characterize(bundled_static_log(), models=()).to_dict())
    chans = doc["channels"]
    for block in ("record_length", "stationarity", "timing"):
        assert all(block in c for c in chans.values()), block
    static = tmp_path / "run" / "static"
    static.mkdir(parents=True)

    def page(d: dict) -> str:
        (static / "noise.json").write_text(json.dumps(d))
        return build_report(tmp_path / "run")

    clean = json.loads(json.dumps(doc))
    for c in clean["channels"].values():
        c["noise"]["selected"]["misfit"] = []
        c["stationarity"]["warmup"] = None
    html = page(clean)
    assert "leave the curve on" not in html and "warm-up " not in html.split("id='static'")[0]
    assert "The fitted terms follow the curve within its intervals at every τ." in html
    assert html.count("none found") == len(chans)

    warm = Warmup(0.0, 812.0, 271.0, 0.0123, 0.0004, 30.75).to_dict()
    chans["accel_y"]["stationarity"]["warmup"] = warm
    chans["accel_y"]["stationarity"]["stationary"] = False
    Image.new("RGB", (8, 8), "white").save(static / "stationarity.png")
    html = page(doc)
    summary, details = html.split("<section id='static'>")
    # one summary line: the warm-up and the channels whose terms leave the curve
    mis = [ch for ch, c in chans.items() if c["noise"]["selected"]["misfit"]]
    assert mis  # the bundled log has structure the five terms cannot follow
    line = re.search(r"<p class='warn'>Static log: (.*?)</p>", summary)
    assert line is not None
    assert "warm-up accel_y 0 – 812 s" in line.group(1)
    assert f"leave the curve on {', '.join(mis)}" in line.group(1)
    # details: every misfit range with its side
    for ch in mis:
        for m in chans[ch]["noise"]["selected"]["misfit"]:
            lo, hi = m["tau_range_s"]
            assert f"<td class='l'>{ch}</td><td>{lo:.3g} – {hi:.3g} s</td><td>{m['side']}" in (
                details
            )
    # record length: the relative widths at each length and the hours needed
    rl = chans["gyro_y"]["record_length"]
    assert "How long to record" in details and "needed for a 20 % width" in details
    assert f"{100 * rl['rel_ci_width']['B'][-1]:.3g} %" in details
    need = rl["hours_needed"]["B"]
    shown = f"{need * 60:.2g} min" if need < 1 else f"{need:.3g} h"
    assert re.search(rf"gyro_y B</td>(<td>[^<]*</td>)+<td>{re.escape(shown)}</td>", details)
    # stationarity: the verdict, the warm-up's start and end, and the figure
    assert "<span class='bad'>not stationary</span>" in details
    assert "<span class='warn'>0 – 812 s</span> (T = 271 s" in details
    assert details.count("none found") == len(chans) - 1
    assert "consecutive windows of the log" in details  # stationarity.png embedded
    # timing: the step, the jitter, the bound of the constant-rate error and the gaps
    tm = chans["gyro_z"]["timing"]
    assert "Time stamps" in details
    assert (f"<td class='l'>gyro_z</td><td>{tm['median_step_s']:.4g} s</td><td>"
            f"{100 * tm['jitter_rel']:.3g} %</td><td>{100 * tm['bound_rel_max']:.3g} %</td>"
            f"<td>{tm['gaps']} (") in details


SUMMARY_PROBE = """<script>
window.addEventListener('load', function () {
  function box(el) { var r = el.getBoundingClientRect();
    return [Math.round(r.top), Math.round(r.bottom), Math.round(r.height)]; }
  var s = document.getElementById('summary');
  var f = document.getElementById('figures');
  var imgs = f ? Array.prototype.slice.call(f.querySelectorAll('img')).map(box) : [];
  console.log('SUMMARY ' + JSON.stringify({
    first: document.querySelector('main > section').id, summary: box(s),
    table: box(s.querySelector('table')), figures: f ? box(f) : null, imgs: imgs,
    open: document.querySelectorAll('details[open]').length,
    height: window.innerHeight}));
});
</script>"""


def test_browser_shows_the_summary_first_and_the_key_figures_open(
    run_dir: Path, tmp_path: Path
) -> None:
    """A 1400x900 screenshot of the report as written: the summary is the first section,
    at the top, its N/B/K table wholly on the first screen; the key figures (Allan curves,
    the verdicts' windows, the in-motion figures) come next, laid out without a click;
    the details stay collapsed."""
    from PIL import Image

    probed = tmp_path / "summary.html"
    probed.write_text((run_dir / "report.html").read_text().replace(
        "</body>", SUMMARY_PROBE + "</body>"))
    lines = _render(probed, tmp_path / "first.png", tmp_path / "profile", size="1400,900")
    probe = [ln for ln in lines if "SUMMARY " in ln]
    assert len(probe) == 1, lines
    info = json.loads(re.search(r"SUMMARY (\{.*\})", probe[0]).group(1))  # type: ignore[union-attr]
    assert info["first"] == "summary", info
    assert 0 <= info["summary"][0] < 200 and info["table"][1] <= info["height"], info
    assert info["figures"] is not None and info["figures"][0] >= info["summary"][1], info
    assert len(info["imgs"]) == (3 if VN100.is_dir() else 1), info
    assert all(h > 150 for _, _, h in info["imgs"]), info  # drawn open, not collapsed
    assert info["open"] == 0
    shot = np.asarray(Image.open(tmp_path / "first.png").convert("RGB"), dtype=float)
    assert shot.shape == (900, 1400, 3)
    top = shot[info["summary"][0]: info["table"][1]]
    assert (top < 128).mean() > 0.01  # the summary's text is on the first screen
