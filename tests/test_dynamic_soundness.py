"""Soundness of mode full over 200 trips of the product's simulator (issue 11, issue 12).

The trips come from :func:`imubounds.dynamic.scenario.make_trip`, the simulator behind
``imubounds simulate``: realistic biased Gaussian noise (turn-on bias, flicker bias
instability, white noise; every third trip also a scale-factor error and a cross-axis
misalignment), GNSS outliers in the ``outliers`` variant, and the estimator's default
options. The simulator's :class:`~imubounds.dynamic.scenario.Record` says which inputs
fell outside the bounds its ``drive.yaml`` states. Every trip whose record is clean must
be enclosed at every step for every quantity (position, heading, u, v, speed, each
channel's bias, and each window mean of the true signal), and at least 99 % of all trips;
a trip whose truth leaves its intervals must say ``guaranteed: false`` (issue 27), and a
clean trip may raise a false violation only as often as the checks' level allows.

The IMU runs at 50 Hz (the truth at the same rate, so that every window mean can be
checked) and the trips last 5 minutes (:data:`TRIP_S`), to keep the 200 trips within a
few minutes on two cores.
"""

from __future__ import annotations

import pytest

from imubounds.dynamic.estimator import dynamic_margins
from imubounds.dynamic.scenario import VARIANTS, make_trip
from tests.test_dynamic_full import enclosed_everywhere

TRIPS_PER_VARIANT = 25  # 8 x 25 = 200 trips
#: 5-minute trips at the simulator's default speed (9400 m in 792 s), for the suite's CI
#: budget: about half the default 13-minute trip's time (gnss10's 25 trips 159 -> 77 s)
TRIP_S = 300.0
SPEED_MPS = 9400.0 / 792.0
#: (the sharp corners' trip keeps the default 13 minutes: its slow corners and speed
#: ramps leave too little time for a shorter plan, which the simulator refuses)


def run_trip(variant: str, seed: int) -> tuple[bool, list[str], str, bool]:
    """(record clean, quantities whose truth left the intervals, record summary,
    guaranteed)."""
    extra = {"scale_error": 0.002, "misalignment_deg": 0.1} if seed % 3 == 0 else {}
    if variant != "corners":
        extra |= {"duration_s": TRIP_S, "distance_m": TRIP_S * SPEED_MPS}
    res = make_trip(variant, seed=seed, rate_hz=50.0, truth_rate_hz=50.0, **extra)
    d = dynamic_margins(res.drive).to_dict()
    assert d["guaranteed"] is (not d["violations"])
    # the window means are checked against the true signal, for every analysed channel
    assert set(d["margins"]) <= set(d["margins_truth"]), sorted(d["margins_truth"])
    return res.record.clean, enclosed_everywhere(d), res.record.summary(), d["guaranteed"]


def test_variants_are_the_issue_list() -> None:
    """The 8 variants: the paper trip, hills, sharp corners, 10 Hz GNSS, GNSS position
    only, position + velocity, DVL + heading only, 2 % GNSS outliers."""
    assert set(VARIANTS) == {
        "paper", "hills", "corners", "gnss10", "gnss-pos", "gnss-posvel", "dvl-heading",
        "outliers",
    }  # fmt: skip


@pytest.mark.slow
@pytest.mark.parametrize("variant", sorted(VARIANTS))
def test_soundness_200_trips(variant: str) -> None:
    """25 trips of one variant (8 variants: 200 trips in all). A clean trip must be
    enclosed everywhere; a trip with inputs outside their bounds (GNSS outliers, an IMU
    sample or a fix beyond its whole-trip level) may fail, but only the outlier variant
    may lose a trip at all, and at most one in 25 (so that the 200 trips stay >= 99 %
    enclosed)."""
    failures = []
    unclean_failures = []
    false_violations = []
    n_clean = 0
    for seed in range(TRIPS_PER_VARIANT):
        clean, bad, rec, guaranteed = run_trip(variant, 1000 + seed)
        n_clean += clean
        if bad and clean:
            failures.append(f"seed {1000 + seed}: truth outside {bad} (record clean)")
        elif bad and guaranteed:
            unclean_failures.append(f"seed {1000 + seed}: truth outside {bad}; {rec}")
        if clean and not guaranteed:
            false_violations.append(seed)
    assert not failures, failures
    # a trip whose truth leaves the intervals withdraws its guarantee (issue 27) but
    # for at most one silent miss of the outlier variant
    allowed = 1 if variant == "outliers" else 0
    assert len(unclean_failures) <= allowed, unclean_failures
    # the checks' level is alpha = 0.01 per trip: more than 2 of 25 clean trips with a
    # false violation has probability < 0.3 %
    assert len(false_violations) <= 2, false_violations
    if variant != "outliers":
        # the stated bounds hold at the whole-trip level (99 %): most trips are clean
        assert n_clean >= TRIPS_PER_VARIANT - 3, n_clean
