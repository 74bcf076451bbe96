"""In-motion figures on a simulated trip whose IMU errors are known sample by sample.

The simulator keeps every error term it drew (white noise, turn-on bias, bias drift),
so the true mean IMU error of every window the dynamic analysis evaluates is known;
the in-motion bound must contain it at every averaging time, and the inflation factor
must exceed 1 exactly where the bound exceeds the stationary prediction.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import imubounds as ib
from imubounds.motion import motion_figures, plot_motion, read_motion


@pytest.fixture(scope="module")
def trip() -> tuple[Any, Any]:
    sim = ib.simulate_trip("paper", seed=3, duration_s=200, distance_m=2400)
    res = ib.dynamic_margins(sim.drive, mode="full")
    return sim, res


def _true_window_errors(sim: Any, res: Any, ch: str) -> list[np.ndarray]:
    """Per tau level: the true kernel-mean IMU error of each window, from the drawn errors."""
    from imubounds.dynamic.estimator.inputs import PiecewiseSignal
    from imubounds.dynamic.scenario.imu import CHANNELS

    j = CHANNELS.index(ch)
    err = sim.imu_errors
    e = err.white[:, j] + err.turn_on[j] + err.drift[:, j] + err.fault[:, j]
    run = res.full
    sig = PiecewiseSignal(run.ctx.imu.bnd, e)
    plans = [p for p in run.ctx.plans[ch].levels if p.n]
    out = []
    for lp in plans:
        km = sig.kernel_mean(lp.a1, lp.b1, lp.a2, lp.b2, lp.tau)
        out.append(0.5 * (np.asarray(km.lo) + np.asarray(km.hi)))
    return out


def test_motion_figures_contain_the_true_in_motion_error(trip: tuple[Any, Any]) -> None:
    sim, res = trip
    assert sim.config.scale_error == 0 and sim.config.misalignment_deg == 0  # errors above only
    fig = motion_figures(res)
    assert fig["channels"], "no channel analysed in motion"
    sides = set()
    for ch, c in fig["channels"].items():
        truth = _true_window_errors(sim, res, ch)
        assert len(truth) == len(c["rows"]), ch
        levels = res.full.margins[ch].levels
        for row, e, lv in zip(c["rows"], truth, levels, strict=True):
            worst = float(np.max(np.abs(e)))
            assert row["bound"] is not None, (ch, row["tau_s"])
            # the guaranteed bound contains the true in-motion error at every tau
            assert worst <= row["bound"], (ch, row["tau_s"], worst, row["bound"])
            # ... and the guaranteed floor is below the true largest error
            assert row["floor"] <= worst * (1 + 1e-6) + 1e-12, (ch, row["tau_s"], worst, row)
            sides.add(row["inflation"] > 1.0)
            # inflation > 1 exactly where the bound exceeds the stationary prediction
            assert (row["inflation"] > 1.0) == (row["bound"] > row["stationary"]), (ch, row)
            assert row["inflation"] == pytest.approx(row["bound"] / row["stationary"])
            if c["F"] is not None and row["resolved"]:
                # F x the stationary prediction bounds the true error of every resolved
                # window (aided interval no wider than its band) at every resolved tau
                ok = 0.5 * (lv.x_hi - lv.x_lo) <= lv.band
                assert ok.sum() == row["n_resolved"]
                w = float(np.max(np.abs(e[ok])))
                assert w <= row["bound_resolved"] <= c["F"] * row["stationary"] * (1 + 1e-12)
        if c["F"] is not None:
            assert c["F"] >= 1.0
            assert c["N_motion"] == pytest.approx(c["F"] * c["N_static"])
    assert sides == {True, False}  # both cases of the 'exactly where' occur on this trip


def test_motion_json_round_trip_and_plot(trip: tuple[Any, Any], tmp_path: Path) -> None:
    _, res = trip
    doc = json.loads(json.dumps(motion_figures(res)))
    (tmp_path / "motion.json").write_text(json.dumps(doc))
    assert read_motion(tmp_path) == doc
    fig = plot_motion(doc)
    assert len(fig.axes) == len(doc["channels"])
    with pytest.raises(ib.InputError, match="no motion.json"):
        read_motion(tmp_path / "elsewhere")


def test_windows_figure_marks_the_exceeding_windows_at_the_tau_shown() -> None:
    """A gyro bias step the noise budget does not allow: windows.png shows the tau with
    the exceeding windows and marks them; every planar channel has its panel."""
    from imubounds.dynamic.scenario import parse_fault
    from imubounds.report.dynamic_plots import plot_windows

    sim = ib.simulate_trip("paper", seed=3, duration_s=200, distance_m=2400,
                           faults=(parse_fault("gyro_z:bias=0.3@100"),))  # fmt: skip
    res = ib.dynamic_margins(sim.drive, mode="full")
    assert res.verdicts["gyro_z"] == "exceeds"
    fig = plot_windows(res)
    titles = [ax.get_title(loc="left") for ax in fig.axes]
    # a panel per analysed channel (all six with the attitude states), in channel order
    shown = [t.split(":")[0] for t in titles]
    analysed = [c for c in ("accel_x", "accel_y", "accel_z", "gyro_x", "gyro_y", "gyro_z")
                if c in res.full.margins]
    assert shown == analysed and {"accel_x", "accel_y", "gyro_z"} <= set(shown), shown
    gz = fig.axes[shown.index("gyro_z")]
    n_ex = max(int(np.sum(lv.exceeds)) for lv in res.full.margins["gyro_z"].levels)
    marks = [ln for ln in gz.get_lines() if ln.get_marker() == "v"]
    assert len(marks) == 1 and len(marks[0].get_xdata()) == n_ex
    lo, hi = gz.get_ylim()  # the marked windows are in view
    assert all(lo <= y <= hi for y in marks[0].get_ydata())
    if len(shown) < 6:  # a channel without margins is named on the figure
        assert any("not analysed" in t.get_text() for t in fig.texts)
    # trajectory.png: the whole trip and a zoom where the boxes are drawn (at most ~20 of
    # each, the smoothed ones at the GNSS epochs); the legend is the figure's, off the data
    from imubounds.report.dynamic_plots import plot_trajectory

    tf = plot_trajectory(res, sim.drive)
    whole, zoom = tf.axes
    assert not whole.collections and whole.get_legend() is None and zoom.get_legend() is None
    assert len(tf.legends) == 1
    gnss_boxes, smoothed = zoom.collections
    assert 0 < len(gnss_boxes.get_paths()) <= 20 and 0 < len(smoothed.get_paths()) <= 20
    x0, x1 = zoom.get_xlim()
    assert x1 - x0 < 0.5 * np.ptp(whole.get_xlim())  # a zoom, where 10 m boxes are visible
