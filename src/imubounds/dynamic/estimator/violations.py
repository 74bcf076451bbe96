"""The scope of mode full's guarantee: every failed check of an assumption.

The guarantee of mode full holds when every stated assumption holds. Some of them are
checked on the data (the two-sided consistency of every measurement with the IMU's
predictions, the windows' agreement on one constant bias, the heading sensor against the
GNSS course, the vehicle bounds on the body velocity, the change test). A failed check
is a :class:`Violation`: the guarantee is withdrawn over its span and ``guaranteed``
becomes false. Nothing is repaired silently: a measurement left out because it
contradicts the others is a failed check, because a contradiction means that some
assumption (that measurement's error bound, or the IMU's budget, or a clock) is false,
and the data cannot tell which.

Span: the smoother couples every epoch of the trip through the IMU links, so an input
outside its assumptions can move every interval. A violation found by a check that
involves the smoother or a whole-trip constant therefore withdraws the whole trip
(``t_start_s`` .. ``t_end_s`` = the smoother's first and last epoch); where the check
found it is in ``evidence_s``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np


@dataclass
class Violation:
    """One failed check of an assumption of mode full."""

    stream: str
    t_start_s: float
    t_end_s: float
    test: str
    detail: str
    evidence_s: tuple[float, float] | None = None

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "stream": self.stream,
            "t_start_s": self.t_start_s,
            "t_end_s": self.t_end_s,
            "test": self.test,
            "detail": self.detail,
        }
        if self.evidence_s is not None:
            out["evidence_s"] = [self.evidence_s[0], self.evidence_s[1]]
        return out


#: share of the trip's alpha given to the residual checks (residual_checks.py); the check
#: against the GNSS course has another (compass.COURSE_CHECK_SHARE); the drops and bias
#: disagreements fail only when a bound of the guarantee fails (its alpha): a clean trip
#: raises a false violation with probability at most 1.5 alpha
CHECK_SHARE = 0.25

#: test names (dynamic.json ``violations[].test``)
TEST_TWO_SIDED = "two-sided consistency with the IMU predictions"
TEST_GNSS_NEIGHBOURS = "GNSS fix against its neighbours"
TEST_BIAS_WINDOWS = "one constant bias for every window"
TEST_BIAS_LINKS = "one constant bias for every smoother link"
TEST_VEHICLE = "vehicle bounds on the body velocity"
TEST_VERDICT = "IMU error within the stated budget (window verdict)"
TEST_FIXPOINT = "non-empty fixpoint"
TEST_HEADING_CLOCK = "heading clock within its default allowance (tested by the data)"
TEST_HEADING_COURSE = (
    "heading sensor against the GNSS course (signed mean, per heading bin, turns, harmonics)"
)


def collect(run: Any, t_span: tuple[float, float]) -> list[Violation]:
    """Every failed check of a :class:`~imubounds.dynamic.estimator.full.FullRun`."""
    a, b = t_span
    out: list[Violation] = []
    sm = run.smoother
    if sm is not None:
        for d in sm.dropped:
            test = TEST_GNSS_NEIGHBOURS if d.reason.startswith("GNSS-only") else TEST_TWO_SIDED
            miss = "" if not math.isfinite(d.miss) else f" by {d.miss:.3g} {d.unit}"
            out.append(
                Violation(
                    d.sensor,
                    a,
                    b,
                    test,
                    f"t = {d.t_s:.3f} s: {d.reason}{miss}; left out of the smoother",
                    (d.t_s, d.t_s),
                )
            )
        if sm.beta_note:
            test = TEST_FIXPOINT if "fixpoint still met" in sm.beta_note else TEST_BIAS_LINKS
            out.append(Violation("imu", a, b, test, sm.beta_note))
    for note in run.check_failures:
        out.append(Violation(note[0], a, b, note[1], note[2], note[3]))
    for ch, m in run.margins.items():
        if getattr(m, "verdict", None) == "exceeds":
            out.append(
                Violation(
                    f"imu {ch}",
                    a,
                    b,
                    TEST_VERDICT,
                    f"{ch}: some window's error lies outside the stationary band (the "
                    "verdict stands: it is the finding); the budget the states, links and "
                    "bias intervals are built from does not hold for this channel",
                )
            )
    for v in getattr(run.ctx, "violations", []):
        out.append(v)
    return out


def epoch_mask(viol: list[Any], t_abs: np.ndarray) -> np.ndarray:
    """True at the epochs inside the span of some violation (:class:`Violation` or its
    dict)."""
    m = np.zeros(t_abs.size, dtype=bool)
    for v in viol:
        d = v.to_dict() if isinstance(v, Violation) else v
        m |= (t_abs >= d["t_start_s"] - 1e-9) & (t_abs <= d["t_end_s"] + 1e-9)
    return m
