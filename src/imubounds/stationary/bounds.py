"""Stationary bounds for one sample and 95 % levels over a run (METHOD.md 1.4).

All inputs and outputs are SI unless a name says otherwise:

* ``N`` — random-walk coefficient (angle/velocity random walk) in
  rad/s^0.5 (gyro) or m/s^1.5 (accelerometer), i.e. the white-noise density.
* ``B`` — bias instability in rad/s or m/s^2.
* ``dt`` — sample period in s; ``t`` — averaging time in s.
"""

from __future__ import annotations

import math

from imubounds.errors import OptionError
from imubounds.units import SQRT_HOUR

#: The paper's interval factor: [y - 3 sigma_c, y + 3 sigma_c].
DEFAULT_K = 3.0
#: Two-sided 95 % quantile of the normal distribution, as in the paper.
Z95 = 1.96


def _positive(name: str, value: float) -> float:
    if not (math.isfinite(value) and value > 0.0):
        raise OptionError(f"{name} must be a positive finite number, got {value!r}")
    return float(value)


def _non_negative(name: str, value: float) -> float:
    if not (math.isfinite(value) and value >= 0.0):
        raise OptionError(f"{name} must be a non-negative finite number, got {value!r}")
    return float(value)


def sigma_c(N: float, B: float, dt: float, t: float) -> float:
    """Combined white-noise-equivalent deviation of one sample (the paper's σ_c).

    ``σ_c = N/√δt + √(δt/t)·B``, in the unit of the measured signal
    (rad/s or m/s^2).

    Parameters
    ----------
    N:
        Random-walk coefficient, SI (rad/s^0.5 or m/s^1.5).
    B:
        Bias instability, SI (rad/s or m/s^2).
    dt:
        Sample period δt in s.
    t:
        Averaging time in s (the log length unless set otherwise).
    """
    N = _non_negative("N", N)
    B = _non_negative("B", B)
    dt = _positive("dt", dt)
    t = _positive("t", t)
    return N / math.sqrt(dt) + math.sqrt(dt / t) * B


def interval_halfwidth(N: float, B: float, dt: float, t: float, k: float = DEFAULT_K) -> float:
    """Half-width ``k·σ_c`` of the per-sample stationary interval ``[y - kσ_c, y + kσ_c]``."""
    k = _positive("k", k)
    return k * sigma_c(N, B, dt, t)


def level_95(rw_per_sqrt_hour: float, T_hours: float, z: float = Z95) -> float:
    """The paper's 95 % stationary level over a run of ``T_hours``: ``z·RW·√T``.

    ``rw_per_sqrt_hour`` is the random-walk coefficient expressed per √hour
    (e.g. m/s/√h or °/√h). The result carries the unit of RW times √h; the
    paper compares it directly with accelerations (m/s^2) and rates (°/s).
    With the paper's numbers: ``level_95(0.108, 0.22) == 0.0993`` and
    ``level_95(6, 0.22) == 5.516``.
    """
    rw = _non_negative("random-walk coefficient", rw_per_sqrt_hour)
    T_hours = _positive("run duration T (hours)", T_hours)
    z = _positive("z", z)
    return z * rw * math.sqrt(T_hours)


def level_95_si(N_si: float, T_s: float, z: float = Z95) -> float:
    """:func:`level_95` from an SI random-walk coefficient and a duration in s.

    ``N_si`` in rad/s^0.5 (or m/s^1.5) is converted to per-√hour by ×60 and
    ``T_s`` to hours, so the value is in rad (or m/s) — the unit the paper
    reads as rad/s (m/s^2).
    """
    return level_95(N_si * SQRT_HOUR, _positive("T", T_s) / 3600.0, z)
