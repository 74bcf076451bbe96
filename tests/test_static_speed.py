"""What made ``imubounds static`` faster keeps the same answers (issue 28 item 2).

No timing is asserted: the parser of one command equals the full parser's, the
static path imports neither the trip simulator, pandas, scipy.stats nor scipy.signal,
and the replacements of scipy.stats and lfilter give the values they replaced.
"""

from __future__ import annotations

import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy import signal, stats

from imubounds.cli import COMMAND_MODULES, build_parser
from imubounds.stationary.ar_model import ar_autocovariance
from imubounds.stationary.edf import chi2_ppf, norm_cdf, norm_pdf, norm_ppf


def _help(parser: object, command: str) -> str:
    sub = next(a for a in parser._actions if a.__class__.__name__ == "_SubParsersAction")  # type: ignore[attr-defined]
    return str(sub.choices[command].format_help())


@pytest.mark.parametrize("module", COMMAND_MODULES)
def test_parser_of_one_command_equals_the_full_one(module: str) -> None:
    command = module.replace("_", "-")
    full = build_parser()
    one = build_parser([command, "--help"])
    assert _help(one, command) == _help(full, command)
    with_debug = build_parser(["--debug", command])
    assert _help(with_debug, command) == _help(full, command)


def test_parser_without_a_command_has_every_command() -> None:
    for argv in ([], ["--help"], ["--version"], ["stat"]):
        sub = next(a for a in build_parser(argv)._actions
                   if a.__class__.__name__ == "_SubParsersAction")  # fmt: skip
        assert len(sub.choices) == len(COMMAND_MODULES), argv


def test_static_path_imports_no_simulator_pandas_or_scipy_stats(tmp_path: object) -> None:
    code = (
        "import sys\n"
        "from imubounds.cli import main\n"
        "from imubounds.io import bundled_static_log\n"
        f"rc = main(['static', str(bundled_static_log()), '-o', {str(tmp_path)!r}, '-q',"
        " '--models', 'none', '--no-report'])\n"
        "bad = [m for m in ('imubounds.dynamic.scenario', 'pandas', 'scipy.stats',"
        " 'scipy.signal') if m in sys.modules]\n"
        "print(rc, bad)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip().splitlines()[-1] == "0 []", out.stdout + out.stderr


def test_special_function_quantiles_equal_scipy_stats() -> None:
    df = np.array([0.7, 1.0, 3.5, 20.0, 1e4])
    for q in (0.0001, 0.1585, 0.5, 0.8415, 0.9999):
        np.testing.assert_allclose(chi2_ppf(q, df), stats.chi2.ppf(q, df), rtol=1e-14)
    assert np.isnan(chi2_ppf(0.5, np.array([0.0, -1.0]))).all()
    x = np.array([-4.0, -1.0, 0.0, 0.5, 3.0])
    np.testing.assert_allclose(norm_cdf(x), stats.norm.cdf(x), rtol=1e-15)
    np.testing.assert_allclose(norm_cdf(-x), stats.norm.sf(x), rtol=1e-15)
    np.testing.assert_allclose(norm_pdf(x), stats.norm.pdf(x), rtol=1e-15)
    np.testing.assert_allclose(norm_ppf(0.841), stats.norm.ppf(0.841), rtol=1e-15)


def test_ar_autocovariance_tail_equals_lfilter() -> None:
    rng = np.random.default_rng(3)
    for p in (1, 2, 7, 20):
        a = np.zeros(0)
        for k in rng.uniform(-0.8, 0.8, p):  # a stable AR(p) from reflection coefficients
            a = np.concatenate((a - k * a[::-1], [-k]))
        r = ar_autocovariance(a, 0.3, 500)
        den = np.concatenate(([1.0], a))
        zi = signal.lfiltic([1.0], den, r[: p + 1][::-1][:p])
        tail, _ = signal.lfilter([1.0], den, np.zeros(500 - p - 1), zi=zi)
        np.testing.assert_allclose(r[p + 1 :], tail, rtol=0, atol=1e-13 * r[0])


def test_log_axis_labels_are_plain_text() -> None:
    from matplotlib.figure import Figure

    from imubounds.report.static_plots import PlainLogFormatter, log_axes

    fig = Figure()
    ax = fig.add_subplot(1, 1, 1)
    ax.plot([1e-3, 1e2], [2e-3, 7e-3])
    log_axes(ax)
    fig.canvas.draw()
    labels = [t.get_text() for t in ax.get_xticklabels() + ax.get_yticklabels() if t.get_text()]
    assert labels and not any("$" in s for s in labels), labels
    assert "10⁻³" in labels
    fmt = PlainLogFormatter()
    assert fmt._num_to_string(2e-3, 1e-3, 1e-2) == "2×10⁻³"
    assert fmt._num_to_string(100.0, 1.0, 1e3) == "10²"


def test_minor_ticks_only_on_log_axes_of_few_decades() -> None:
    """Minor ticks (2 and 5 of each decade) where an axis spans at most
    MINOR_MAX_DECADES decades (they help read it), none on a wider one (the τ axis)."""
    from matplotlib.figure import Figure

    from imubounds.report.static_plots import MINOR_MAX_DECADES, log_axes

    fig = Figure()
    ax = fig.add_subplot(1, 1, 1)
    ax.plot([1e-2, 1e4], [2e-3, 7e-3])  # x: 6 decades, y: under one
    log_axes(ax)
    ax.set_xlim(1e-2, 1e4)
    fig.canvas.draw()
    assert MINOR_MAX_DECADES < 6
    assert len(ax.xaxis.get_minorticklocs()) == 0
    ys = ax.yaxis.get_minorticklocs()
    lo, hi = ax.get_ylim()
    assert any(abs(v - 5e-3) < 1e-12 for v in ys) and all(lo <= v <= hi for v in ys)


def test_in_parallel_runs_both_and_raises_a_failure_here(tmp_path: Path) -> None:
    """The figures are drawn two at a time (a forked child draws one): both files are
    written, and a child that fails is run again in this process, raising its error."""
    from imubounds.cli.static import in_parallel

    a, b = tmp_path / "a.txt", tmp_path / "b.txt"
    in_parallel(lambda: a.write_text("first"), lambda: b.write_text("second"))
    assert a.read_text() == "first" and b.read_text() == "second"

    calls = tmp_path / "calls.txt"

    def failing() -> None:
        with calls.open("a") as f:
            f.write("x")
        raise ValueError("drawing failed")

    with pytest.raises(ValueError, match="drawing failed"):
        in_parallel(lambda: None, failing)
    assert calls.read_text() in ("x", "xx")  # in the child (when forked), then here


def test_static_command_runs_with_one_openblas_thread() -> None:
    """`imubounds static` sets OPENBLAS_NUM_THREADS=1 before numpy loads OpenBLAS (its
    idle threads spun after every small BLAS call: ~0.5 CPU s on the ADIS log), unless
    the user set it; other commands leave it alone."""
    code = (
        "import os, sys, contextlib, io\n"
        "from imubounds.cli import main\n"
        "with contextlib.redirect_stdout(io.StringIO()):\n"
        "    main(sys.argv[1:])\n"
        "print(os.environ.get('OPENBLAS_NUM_THREADS'))\n"
    )
    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_NUM_THREADS"}
    out = subprocess.run([sys.executable, "-c", code, "static", "--help"], env=env,
                         capture_output=True, text=True, check=True).stdout.split()  # fmt: skip
    assert out == ["1"], out
    env["OPENBLAS_NUM_THREADS"] = "3"
    out = subprocess.run([sys.executable, "-c", code, "static", "--help"], env=env,
                         capture_output=True, text=True, check=True).stdout.split()  # fmt: skip
    assert out[0] == "3"
    env.pop("OPENBLAS_NUM_THREADS")
    out = subprocess.run([sys.executable, "-c", code, "simulate", "--help"], env=env,
                         capture_output=True, text=True, check=True).stdout.split()  # fmt: skip
    assert out[0] == "None"


@pytest.mark.parametrize("fail", [False, True])
def test_static_run_leaves_the_collector_as_it_found_it(tmp_path: Path, fail: bool) -> None:
    """``imubounds static`` turns the cyclic collector off and freezes the heap while it
    runs (cli.static._frozen_heap); an in-process caller gets it back on and unfrozen,
    on success and on error (the heap is frozen again only at the interpreter's exit)."""
    import gc

    from imubounds.cli import main

    t = np.arange(2000) / 100.0
    rng = np.random.default_rng(3)
    cols = [t] + [rng.normal(0, 1e-3, t.size) for _ in range(6)]
    path = tmp_path / "log.csv"
    head = "time_s,gyro_x,gyro_y,gyro_z,accel_x,accel_y,accel_z"
    np.savetxt(path, np.column_stack(cols), delimiter=",", header=head, comments="")
    if fail:
        path.write_text(path.read_text() + "1e9,x,y,z,1,2,3\n")
    assert gc.isenabled()
    gc.collect()
    frozen = gc.get_freeze_count()
    code = main(["static", str(path), "-o", str(tmp_path / "out"), "--quiet", "--no-plot",
                 "--models", "none"])  # fmt: skip
    assert (code != 0) == fail
    assert gc.isenabled()
    assert gc.get_freeze_count() == frozen
    from imubounds.cli import static

    assert static._FREEZE_AT_EXIT == [True]  # registered once, frozen only at the exit


def test_edf_with_misfit_equals_the_polygamma_newton_bit_for_bit() -> None:
    """record_length's ψ₁/ψ₂ from scipy.special.zeta give polygamma's values exactly."""
    from scipy import special

    from imubounds.stationary.record_length import _edf_with_misfit

    def reference(edf: np.ndarray, eta: float) -> np.ndarray:
        target = special.polygamma(1, edf / 2.0) + eta**2
        x = 1.0 / target + 0.5
        for _ in range(30):
            step = (special.polygamma(1, x) - target) / special.polygamma(2, x)
            x = np.maximum(x - step, x / 10.0)
        return np.asarray(2.0 * x, dtype=np.float64)

    edf = np.geomspace(0.5, 1e6, 200)
    for eta in (1e-4, 0.03, 0.3, 2.0):
        got = _edf_with_misfit(edf, eta)
        assert np.array_equal(got, reference(edf, eta))
        assert np.all(got < edf)  # a misfit lowers the EDF


@pytest.mark.parametrize(("lo", "hi"), [(0.01, 1e4), (2e-4, 3e-2), (0.3, 0.9), (1.0, 10.0)])
def test_view_log_locators_keep_every_tick_matplotlib_draws(lo: float, hi: float) -> None:
    """The log locators of the figures return only ticks in view: the ticks drawn
    (locations and labels) are those of matplotlib's own locators."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.ticker import LogLocator

    from imubounds.report.static_plots import MINOR_MAX_DECADES, log_axes

    def drawn(trim: bool) -> list[tuple[float, str]]:
        fig = Figure()
        FigureCanvasAgg(fig)
        ax = fig.add_subplot()
        ax.plot([lo, hi], [lo, hi])
        log_axes(ax)
        ax.set_xlim(lo, hi)
        ax.set_ylim(lo, hi)
        if not trim:  # matplotlib's own: every decade and sub-tick, one beyond each end
            for axis in (ax.xaxis, ax.yaxis):
                axis.set_major_locator(LogLocator())
                if math.log10(hi / lo) <= MINOR_MAX_DECADES:  # else no minor ticks at all
                    axis.set_minor_locator(LogLocator(subs=(2.0, 5.0)))
        fig.canvas.draw()
        out = []
        for axis in (ax.xaxis, ax.yaxis):
            out += [(t.get_loc(), t.label1.get_text()) for t in axis._update_ticks()]
        return out

    trimmed, full = drawn(True), drawn(False)
    assert trimmed == full
    assert len(trimmed) >= 2


@pytest.mark.parametrize(
    ("lo", "hi"), [(-1843.2, -1051.7), (0.0, 163.0), (-9.991, -9.934), (1e-9, 3e-9)]
)
def test_view_auto_locator_keeps_every_tick_matplotlib_draws(lo: float, hi: float) -> None:
    """The linear axes of stationarity.png: the ticks drawn (locations, labels, offset
    text) are those of matplotlib's AutoLocator."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.ticker import AutoLocator

    from imubounds.report.static_plots import ViewAutoLocator

    def drawn(locator: AutoLocator) -> tuple[list[tuple[float, str]], str]:
        fig = Figure()
        FigureCanvasAgg(fig)
        ax = fig.add_subplot()
        ax.plot([0, 1], [lo, hi])
        ax.yaxis.set_major_locator(locator)
        fig.canvas.draw()
        ticks = [(t.get_loc(), t.label1.get_text()) for t in ax.yaxis._update_ticks()]
        return ticks, ax.yaxis.get_offset_text().get_text()

    trimmed, full = drawn(ViewAutoLocator()), drawn(AutoLocator())
    assert trimmed == full
    assert len(trimmed[0]) >= 2
