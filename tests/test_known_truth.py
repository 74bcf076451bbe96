"""Known truth: simulated logs of four sensor grades, every estimator (issue 13).

Each grade (presets tactical, industrial, consumer and the Xsens MTx
datasheet) is simulated for 3 h at 100 Hz with flicker over 0.05 s .. 2e4 s
(a flat bias-instability floor wherever the log can see it). Every estimator
must give: N within 10 %, B within 30 %, K within 50 % where the analysis says
the term is resolved; an upper bound at or above the truth where it says it
is not; never 0 for a term whose truth is not 0.
"""

from __future__ import annotations

import pytest

from imubounds.stationary.allan import ESTIMATORS, allan
from imubounds.stationary.noise_sim import preset, simulate
from imubounds.stationary.terms import analyse_curve

RATE = 100.0
HOURS = 3.0
TOL = {"N": 0.10, "B": 0.30, "K": 0.50}
#: What the design of each grade makes resolvable in 3 h (checked on the overlapping curve).
EXPECT = {
    ("tactical", "gyro_x"): {"N": "resolved", "B": "resolved", "K": "upper_bound"},
    ("tactical", "accel_x"): {"N": "resolved", "B": "resolved"},
    ("industrial", "gyro_x"): {"N": "resolved", "B": "resolved", "K": "resolved"},
    ("industrial", "accel_x"): {"N": "resolved", "B": "resolved", "K": "resolved"},
    ("consumer", "gyro_x"): {"N": "resolved", "B": "resolved", "K": "resolved"},
    ("consumer", "accel_x"): {"N": "resolved", "B": "resolved", "K": "resolved"},
    ("mtx", "gyro_x"): {"N": "upper_bound", "B": "resolved"},  # N hidden under 1 deg/s
    ("mtx", "accel_x"): {"N": "resolved", "B": "resolved"},
}


@pytest.mark.slow  # ~10 s per grade: a 3 h, two-channel simulation and 12 curves
@pytest.mark.parametrize("grade", ["tactical", "industrial", "consumer", "mtx"])
def test_known_truth_for_every_estimator(grade: str) -> None:
    spec = preset(grade, bias_tau_range_s=(0.05, 2e4))
    log = simulate(spec, RATE, HOURS * 3600.0, seed=0, channels=["gyro_x", "accel_x"])
    failures: list[str] = []
    for ch in ("gyro_x", "accel_x"):
        axis = spec.channels[ch]
        truth = {"N": axis.N, "B": axis.B, "K": axis.K}
        for est in ESTIMATORS:
            _, _, sel = analyse_curve(allan(log.channels[ch], RATE, "octave", est))
            for t, true in truth.items():
                if true == 0:
                    continue
                v, status = sel.value(t), sel.status(t)
                where = f"{grade} {ch} {est} {t}: {status} {v:.4g} vs truth {true:.4g}"
                if v <= 0:
                    failures.append(where + " (zero)")
                elif status == "resolved" and abs(v / true - 1) > TOL[t]:
                    failures.append(where + f" (off by {v / true - 1:+.0%})")
                elif status == "upper_bound" and v < true:
                    failures.append(where + " (upper bound below the truth)")
            if est == "overlapping":
                for t, want in EXPECT[(grade, ch)].items():
                    if sel.status(t) != want:
                        failures.append(f"{grade} {ch} {t}: {sel.status(t)}, designed {want}")
    assert not failures, "\n".join(failures)
