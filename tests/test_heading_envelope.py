"""The heading between its epochs (aided/positions._envelope_integrals,
aided/heading.heading_mean): psi_dot_abs bounds the MEAN |psi'| over a span, not the
rate at each time, so an envelope with that slope misses a heading that turns early and
comes back late within one gap. Both are checked against headings built here: a
plateau (rise, hold, return within one fix gap: twice the old envelope's integral) and
hypothesis-drawn piecewise-linear headings within the rate cap, their integral of |psi'|
and their end boxes."""

from __future__ import annotations

import math
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import imubounds.dynamic.estimator.aided.heading as H
import imubounds.dynamic.estimator.aided.positions as P
from imubounds.interval import IntervalArray as IA

MAX_RATE = math.radians(90.0)
TILT = math.radians(10.0)
CAP = MAX_RATE / math.cos(TILT)


def _profile(knots_t: np.ndarray, knots_psi: np.ndarray, n: int = 20001) -> tuple[Any, ...]:
    """A piecewise-linear heading on [0, 1]: fine samples, its integral of |psi'|."""
    t = np.linspace(0.0, 1.0, n)
    psi = np.interp(t, knots_t, knots_psi)
    return t, psi, float(np.sum(np.abs(np.diff(knots_psi))))


def _stub(monkeypatch: Any, module: Any, t_end: float, psi_a: IA, psi_b: IA,
          integral: float) -> Any:
    """w with the vehicle's rate cap; heading_at gives the end boxes, psi_dot_abs the
    MEAN |psi'| over [a, b] (integral / length: what it bounds)."""
    def heading_at(w: Any, t: np.ndarray, own_q: bool = True) -> IA:
        t = np.asarray(t, float)
        lo = np.where(t <= 0.0, psi_a.lo, psi_b.lo)
        hi = np.where(t <= 0.0, psi_a.hi, psi_b.hi)
        return IA(lo, hi)

    def psi_dot_abs(w: Any, a: np.ndarray, b: np.ndarray, own_q: bool = True) -> np.ndarray:
        a, b = np.asarray(a, float), np.asarray(b, float)
        return np.full(a.shape, integral * (1 + 1e-12) / max(t_end, 1e-300))

    monkeypatch.setattr(module, "heading_at", heading_at)
    monkeypatch.setattr(module, "psi_dot_abs", psi_dot_abs)
    return SimpleNamespace(veh=SimpleNamespace(max_rate=MAX_RATE, max_tilt=TILT), cache={})


def _check(kt: np.ndarray, kp: np.ndarray, h: float, psi0: float) -> None:
    t, psi, integral = _profile(kt, kp)
    pa = IA(np.array([psi[0] - h]), np.array([psi[0] + h]))
    pb = IA(np.array([psi[-1] - h]), np.array([psi[-1] + h]))
    with pytest.MonkeyPatch.context() as mp:
        w = _stub(mp, P, 1.0, pa, pb, integral)
        i1, i2 = P._envelope_integrals(w, np.array([0.0]), np.array([1.0]),
                                       np.array([psi0]))
    dev = psi - psi0
    true1 = float(np.trapezoid(np.abs(dev), t))
    true2 = float(np.trapezoid(dev * dev, t))
    assert true1 <= i1[0] * (1 + 1e-6) + 1e-9, (true1, i1[0])
    assert true2 <= i2[0] * (1 + 1e-6) + 1e-9, (true2, i2[0])


def test_plateau_within_one_gap_is_enclosed() -> None:
    """Rise to 0.1 rad at the rate cap, hold, return at the end of the gap: the integral
    of |psi - 0| is 0.094 rad s, where an envelope of slope mean|psi'| (0.2 rad/s) gives
    0.05; the envelope with the rate cap and the integral's cap encloses it."""
    rise = 0.1 / CAP
    kt = np.array([0.0, rise, 1.0 - rise, 1.0])
    kp = np.array([0.0, 0.1, 0.1, 0.0])
    t, psi, _ = _profile(kt, kp)
    assert float(np.trapezoid(psi, t)) > 0.09  # twice the old envelope's 0.05
    _check(kt, kp, 0.0, 0.0)


@settings(max_examples=200, deadline=None)
@given(
    st.lists(st.floats(-0.3, 0.3), min_size=2, max_size=7),
    st.floats(0.0, 0.05),
    st.floats(-0.2, 0.2),
    st.randoms(use_true_random=False),
)
def test_envelope_encloses_any_heading_within_its_bounds(
    values: list[float], h: float, psi0: float, rnd: Any
) -> None:
    """Piecewise-linear headings whose slopes stay within the rate cap (the knots'
    times spaced to keep every slope <= CAP), any end boxes of half-width h."""
    kp = np.array(values)
    need = np.abs(np.diff(kp)) / CAP  # the least time each piece takes at the cap
    if need.sum() > 1.0:
        kp = kp * (0.99 / need.sum())
        need = np.abs(np.diff(kp)) / CAP
    spare = 1.0 - need.sum()
    cuts = np.array([rnd.random() for _ in range(need.size)])
    dur = need + spare * cuts / max(cuts.sum(), 1e-12)
    kt = np.concatenate([[0.0], np.cumsum(dur)])
    kt[-1] = 1.0
    _check(kt, kp, h, psi0)


def test_heading_mean_holds_an_excursion_between_heading_epochs(monkeypatch: Any) -> None:
    """heading_mean over [0, 10] with heading epochs at 0, 1, ..., 10 (boxes +-0.01 about
    0): a 0.1 rad plateau inside one gap ([4, 5]) while the heading is still elsewhere:
    the hull must reach 0.1 although the mean |psi'| over the window is 0.02 rad/s."""
    ht = np.arange(0.0, 11.0)
    integ = {(4.0, 5.0): 0.2}

    def psi_dot_abs(w: Any, a: np.ndarray, b: np.ndarray, own_q: bool = True) -> np.ndarray:
        a, b = np.asarray(a, float), np.asarray(b, float)
        out = np.zeros(a.shape)
        for (s0, s1), v in integ.items():  # the integral of |psi'| that falls in [a, b]
            out += v * np.clip((np.minimum(b, s1) - np.maximum(a, s0)) / (s1 - s0), 0, 1)
        return out * (1 + 1e-12) / np.maximum(b - a, 1e-300)

    def heading_at(w: Any, t: np.ndarray, own_q: bool = True) -> IA:
        t = np.asarray(t, float)
        return IA(np.full(t.shape, -0.01), np.full(t.shape, 0.01))

    monkeypatch.setattr(H, "psi_dot_abs", psi_dot_abs)
    monkeypatch.setattr(H, "heading_at", heading_at)
    ag = SimpleNamespace(head_t=ht, head_c=np.zeros(ht.size), head_h=np.full(ht.size, 0.01))
    w = SimpleNamespace(ag=ag, cache={}, veh=SimpleNamespace(max_rate=MAX_RATE,
                                                             max_tilt=TILT))
    hull = H.heading_mean(w, np.array([0.0, 0.0]), np.array([10.0, 3.0]))
    assert hull.hi[0] >= 0.1 - 1e-12 and hull.lo[0] <= -0.01  # the window holding [4, 5]
    assert hull.hi[1] < 0.02  # a window without the excursion stays tight
