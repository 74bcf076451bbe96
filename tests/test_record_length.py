"""How long to record (issue 28 item 4): the CI widths predicted from the first
30 min of a log against those measured on 1, 2 and 4 h of it."""

from __future__ import annotations

import json
import math

import numpy as np

from imubounds.stationary.allan import allan
from imubounds.stationary.record_length import (
    channel_record_length,
    describe,
    hours_for_width,
    predicted_widths,
)
from imubounds.stationary.terms import analyse_curve

from .synthetic import five_term_signal

RATE = 2.0  # Hz: a 4 h log is 28 800 samples
TRUE = {"N": 3e-4, "B": 2e-4, "K": 3e-5}  # all three visible within 30 min
HOURS = (1.0, 2.0, 4.0)
SEEDS = range(10)


def _rel_width(est, t: str) -> float | None:
    if est.status.get(t) != "resolved":
        return None
    lo, hi = est.ci[t]
    return (hi - lo) / est.value(t)


def test_prediction_from_30_min_matches_the_widths_measured_at_1_2_4_h() -> None:
    ratios: dict[str, dict[float, list[float]]] = {t: {h: [] for h in HOURS} for t in TRUE}
    for seed in SEEDS:
        y = five_term_signal(int(4 * 3600 * RATE), RATE, 0.0, *TRUE.values(), 0.0, seed)
        fit30, _, sel30 = analyse_curve(allan(y[: int(1800 * RATE)], RATE))
        block = channel_record_length(allan(y[: int(1800 * RATE)], RATE), fit30, sel30, 0.5)
        pred = {t: dict(zip(block["hours"], block["rel_ci_width"][t], strict=True)) for t in TRUE}
        for h in HOURS:
            fit, _, _ = analyse_curve(allan(y[: int(h * 3600 * RATE)], RATE))
            for t in TRUE:
                w = _rel_width(fit, t)
                if w is not None and pred[t][h] is not None:
                    ratios[t][h].append(pred[t][h] / w)
    for t in TRUE:
        for h in HOURS:
            r = ratios[t][h]
            assert len(r) >= 5, (t, h, len(r))
            med = float(np.median(r))
            assert 0.75 <= med <= 1.25, f"{t} at {h} h: predicted/measured median {med:.2f}"


def test_widths_shrink_with_length_and_the_needed_length_is_reached() -> None:
    values = {"Q": 0.0, "N": 3e-4, "B": 2e-4, "K": 3e-5, "R": 0.0}
    hours = [0.5, 1.0, 2.0, 4.0, 8.0]
    w = predicted_widths(values, "overlapping", RATE, hours)
    for t in ("B", "K"):
        ws = [v for v in w[t] if v is not None]
        assert len(ws) == len(hours) and all(a > b for a, b in zip(ws, ws[1:], strict=False))
        target = ws[2]  # the width at 2 h is reached at 2 h
        assert math.isclose(hours_for_width(hours, w[t], target) or 0.0, 2.0, rel_tol=1e-6)
        # a target between two lengths lies between them
        mid = hours_for_width(hours, w[t], 0.5 * (ws[1] + ws[2]))
        assert mid is not None and 1.0 < mid < 2.0


def test_block_is_json_and_the_console_line_names_each_term() -> None:
    y = five_term_signal(int(1800 * RATE), RATE, 0.0, *TRUE.values(), 0.0, 1)
    curve = allan(y, RATE)
    fit, _, sel = analyse_curve(curve)
    block = channel_record_length(curve, fit, sel, 0.5)
    assert json.loads(json.dumps(block, allow_nan=False)) == block
    assert 0.5 in block["hours"] and block["target_rel_width"] == 0.2
    line = describe("gyro_x", block)
    assert line.startswith("gyro_x: recording length") and all(f" {t} " in line for t in "NBK")
