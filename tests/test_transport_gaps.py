"""accel_y's transport term cut at the heading epochs: the compiled per-window sums
(aided/gap_sums.py, the gaps between heading epochs computed once per run) against the
plain vectorised reference that materialises every window's knots
(tests/transport_gaps_reference.py): equal but for the order of the additions (numpy
sums pairwise), on every aided level of the aiding sets that use it (a velocity sensor
and a heading: GNSS velocity, DVL, wheel speed, the heading sparser than the velocity or
not, sharp corners)."""

from __future__ import annotations

import numpy as np
import pytest

from imubounds.dynamic.estimator.aided.form_tables import shared_bounds
from imubounds.dynamic.estimator.aided.transport_gaps import transport_by_gaps
from imubounds.dynamic.estimator.aided.velocity import body_velocity
from imubounds.dynamic.estimator.full import build_context
from imubounds.dynamic.estimator.windows import MarginBuilder
from imubounds.dynamic.scenario import make_trip
from imubounds.interval.rounding import nearest
from tests.transport_gaps_reference import transport_by_gaps as reference


@pytest.mark.parametrize(
    "aiding,seed,kw",
    [
        (("gnss", "gnss-vel", "compass"), 3, {}),
        (("dvl", "compass"), 4, {}),
        (("wheel", "gnss", "compass"), 5, {"corner_length_m": 20.0}),
        (("gnss", "gnss-vel", "compass"), 6, {"gps_rate_hz": 10.0, "duration_s": 300.0,
                                               "distance_m": 3600.0}),
    ],
    ids=["gnss-vel", "dvl", "wheel-corners", "gnss10"],
)
def test_compiled_sums_equal_the_reference(aiding: tuple[str, ...], seed: int,
                                           kw: dict) -> None:
    res = make_trip("paper", seed=seed, aiding=aiding, **kw)
    with nearest():
        ctx = build_context(res.drive, None, {})
        mb = MarginBuilder(ctx)
        w = mb  # the builder is the WindowContext
        bv = body_velocity(w)
        assert bv is not None and w.ag.has_heading
        plan = ctx.plans["accel_y"]
        n_levels = 0
        for lp in plan.levels:
            if lp.kind != "aided" or lp.a1.size == 0:
                continue
            tau = lp.tau
            w.p_window = 1e-6
            r_mag, q_mean = shared_bounds(w, lp, tau, [], w.p_window)
            got = transport_by_gaps(w, lp, tau, bv, r_mag, q_mean)
            want = reference(w, lp, tau, bv, r_mag, q_mean)
            for g, r in ((got.lo, want.lo), (got.hi, want.hi)):
                assert np.array_equal(np.isfinite(g), np.isfinite(r))
                fin = np.isfinite(r)
                # the order of the additions differs (numpy's reduceat sums pairwise): the
                # radius carries the rounding of either order ((nk + 6) 4 eps x mag)
                np.testing.assert_allclose(g[fin], r[fin], rtol=1e-12, atol=1e-15)
            n_levels += 1
    assert n_levels >= 5
