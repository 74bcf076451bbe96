import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from imubounds.errors import OptionError
from imubounds.stationary import bounds


def test_paper_worked_levels() -> None:
    # METHOD.md 1.4: 1.96*0.108*sqrt(0.22) = 0.099 m/s^2, 1.96*0.12*sqrt(0.22) = 0.11 m/s^2,
    # 1.96*6*sqrt(0.22) = 5.52 deg/s.
    assert round(bounds.level_95(0.108, 0.22), 3) == 0.099
    assert round(bounds.level_95(0.12, 0.22), 2) == 0.11
    assert round(bounds.level_95(6.0, 0.22), 2) == 5.52


def test_level_95_si_matches_per_sqrt_hour() -> None:
    # 0.002 m/s^2/sqrt(Hz) (MTx datasheet) is 0.12 m/s/sqrt(h).
    assert bounds.level_95_si(0.002, 0.22 * 3600) == pytest.approx(bounds.level_95(0.12, 0.22))


def test_sigma_c_formula() -> None:
    N, B, dt, t = 0.002, 0.02, 0.01, 7200.0
    expected = N / math.sqrt(dt) + math.sqrt(dt / t) * B
    assert bounds.sigma_c(N, B, dt, t) == pytest.approx(expected, rel=1e-15)
    assert bounds.interval_halfwidth(N, B, dt, t) == pytest.approx(3 * expected)
    assert bounds.interval_halfwidth(N, B, dt, t, k=2.5) == pytest.approx(2.5 * expected)


@given(
    st.floats(0, 10),
    st.floats(0, 10),
    st.floats(1e-4, 10),
    st.floats(1, 1e6),
)
def test_sigma_c_monotone_in_N_and_B(N: float, B: float, dt: float, t: float) -> None:
    base = bounds.sigma_c(N, B, dt, t)
    assert bounds.sigma_c(N * 2, B, dt, t) >= base
    assert bounds.sigma_c(N, B * 2, dt, t) >= base


@pytest.mark.parametrize(
    "args", [(-1.0, 0.0, 0.01, 1.0), (1.0, 0.0, 0.0, 1.0), (1.0, 0.0, 0.01, math.nan)]
)
def test_sigma_c_rejects_bad_input(args: tuple[float, float, float, float]) -> None:
    with pytest.raises(OptionError):
        bounds.sigma_c(*args)
