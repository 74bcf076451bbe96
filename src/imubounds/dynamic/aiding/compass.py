"""Compass error model and heading intervals (METHOD.md 2.1).

Conventions
-----------
* A *compass heading* ``psi_c`` is clockwise from north (what a compass, a
  GPS course over ground or a yaw output reports).
* The *model heading* ``psi`` used by the estimator is counter-clockwise from
  east: ``psi = pi/2 - psi_c``. :func:`compass_to_model` and
  :func:`model_to_compass` are the only conversions.
* All angles are in rad. Intervals of a heading are given as a centre and a
  half-width, so that the wrap at ±pi is handled by the consumer (the
  estimator unwraps centres before building intervals).

The hard-iron (one-cycle) deviation is ``psi_err(psi) = A + B sin psi + C cos psi``
with ``psi`` the *measured* compass heading and ``psi_err = measured - reference``
(wrapped to (-pi, pi]).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from imubounds.errors import AnalysisError, InputError, OptionError
from imubounds.frames import TWO_PI, compass_to_model, wrap_pi


@dataclass(frozen=True)
class CompassDeviation:
    """Fitted one-cycle deviation ``psi_err = A + B sin psi + C cos psi`` (rad).

    Attributes
    ----------
    A, B, C:
        Coefficients in rad.
    residual_bound:
        max |residual| of the fit in rad (half-width of the corrected mode).
    residual_rms:
        RMS of the residuals in rad.
    n:
        Number of (measured, reference) pairs used.
    source:
        Where the pairs came from (a file, or "gps-course").
    """

    A: float
    B: float
    C: float
    residual_bound: float
    residual_rms: float
    n: int
    source: str = "<memory>"

    def error(self, psi_c: np.ndarray | float) -> np.ndarray:
        """Deviation in rad at measured compass headings ``psi_c`` (rad, clockwise from north)."""
        p = np.asarray(psi_c, dtype=float)
        return self.A + self.B * np.sin(p) + self.C * np.cos(p)

    def to_dict(self) -> dict[str, float | int | str]:
        return {
            "A_rad": self.A,
            "B_rad": self.B,
            "C_rad": self.C,
            "residual_bound_rad": self.residual_bound,
            "residual_rms_rad": self.residual_rms,
            "n": self.n,
            "source": self.source,
        }


#: A deviation of zero (no calibration): every mode then uses the floor half-width.
ZERO_DEVIATION = CompassDeviation(0.0, 0.0, 0.0, 0.0, 0.0, 0, "none")


def fit_deviation(
    measured: np.ndarray, reference: np.ndarray, source: str = "<memory>"
) -> CompassDeviation:
    """Least-squares fit of the one-cycle deviation.

    Parameters
    ----------
    measured, reference:
        Compass headings in rad (clockwise from north) of the same instants.
    source:
        Label for reports.
    """
    m = np.asarray(measured, dtype=float)
    r = np.asarray(reference, dtype=float)
    if m.shape != r.shape or m.ndim != 1:
        raise InputError(f"{source}: measured and reference headings must be 1-D of equal length")
    ok = np.isfinite(m) & np.isfinite(r)
    m, r = m[ok], r[ok]
    if m.size < 3:
        raise AnalysisError(
            f"{source}: the compass fit needs at least 3 (measured, reference) pairs, got {m.size}"
        )
    err = np.asarray(wrap_pi(m - r))
    design = np.column_stack([np.ones_like(m), np.sin(m), np.cos(m)])
    coef, *_ = np.linalg.lstsq(design, err, rcond=None)
    resid = err - design @ coef
    return CompassDeviation(
        float(coef[0]),
        float(coef[1]),
        float(coef[2]),
        float(np.max(np.abs(resid))),
        float(np.sqrt(np.mean(resid**2))),
        int(m.size),
        source,
    )


def read_calibration(path: str) -> CompassDeviation:
    """Fit the deviation from a CSV file with columns ``measured_deg,reference_deg``.

    Headings in degrees clockwise from north; ``#`` lines are comments.
    """
    import pandas as pd

    try:
        data = pd.read_csv(path, comment="#")
    except (OSError, ValueError) as err:
        raise InputError(f"{path}: cannot read compass calibration file ({err})") from err
    names = list(data.columns)
    if "measured_deg" not in names or "reference_deg" not in names:
        raise InputError(
            f"{path}: compass calibration needs columns measured_deg,reference_deg; found {names}"
        )
    return fit_deviation(
        np.radians(pd.to_numeric(data["measured_deg"], errors="coerce").to_numpy(float)),
        np.radians(pd.to_numeric(data["reference_deg"], errors="coerce").to_numpy(float)),
        source=path,
    )


def heading_intervals(
    psi_c: np.ndarray,
    deviation: CompassDeviation,
    mode: str = "corrected",
    floor_rad: float = 0.0,
    margin: float = 1.0,
) -> tuple[np.ndarray, np.ndarray]:
    """Heading intervals in the *model* convention, as (centre, half-width), rad.

    Parameters
    ----------
    psi_c:
        Measured compass headings in rad, clockwise from north.
    deviation:
        Fitted deviation.
    mode:
        ``"paper"``: centre psi_c, half-width |psi_err(psi_c)| (the printed
        interval, with the sign fixed). ``"corrected"``: centre
        psi_c - psi_err(psi_c), half-width ``margin·residual_bound``.
    floor_rad:
        Lower limit of the half-width in rad (compass resolution / noise);
        the paper's mode can otherwise produce zero-width intervals.
    margin:
        Factor (>= 1) on the residual bound of the corrected mode.

    Returns
    -------
    (centre, halfwidth):
        ``centre`` is CCW from east in [-pi, pi); ``halfwidth`` >= 0.
    """
    p = np.asarray(psi_c, dtype=float)
    e = deviation.error(p)
    if mode == "paper":
        centre_c = p
        half = np.abs(e)
    elif mode == "corrected":
        if margin < 1.0:
            raise OptionError(f"compass margin must be >= 1, got {margin!r}")
        centre_c = p - e
        half = np.full_like(p, margin * deviation.residual_bound)
    else:
        raise OptionError(f"--compass-mode must be 'paper' or 'corrected', got {mode!r}")
    half = np.maximum(half, floor_rad)
    return np.asarray(compass_to_model(centre_c)), half


def heading_from_magnetometer(
    mx: np.ndarray,
    my: np.ndarray,
    frame: str = "FLU",
    declination_rad: float = 0.0,
) -> np.ndarray:
    """Compass heading (rad, clockwise from true north) of a level magnetometer.

    Parameters
    ----------
    mx, my:
        Horizontal field components in the body frame (any unit).
    frame:
        ``"FLU"`` (x forward, y left) or ``"FRD"`` (x forward, y right).
    declination_rad:
        Magnetic declination in rad, east positive (true = magnetic + D).
    """
    if frame == "FLU":
        right = -np.asarray(my, dtype=float)
    elif frame == "FRD":
        right = np.asarray(my, dtype=float)
    else:
        raise OptionError(f"magnetometer frame must be FLU or FRD, got {frame!r}")
    # The field points north: in body axes its forward part is cos(psi_c),
    # its rightward part is -sin(psi_c).
    return (np.arctan2(-right, np.asarray(mx, dtype=float)) + declination_rad) % TWO_PI


def course_over_ground(
    t: np.ndarray, east: np.ndarray, north: np.ndarray, min_speed: float = 3.0
) -> tuple[np.ndarray, np.ndarray]:
    """Course over ground (rad, clockwise from north) from consecutive ENU fixes.

    Returns ``(t_mid, course)`` at the midpoints of fix pairs whose speed is at
    least ``min_speed`` m/s (slower pairs give unreliable courses and are dropped).
    """
    t = np.asarray(t, dtype=float)
    de, dn, dt = np.diff(east), np.diff(north), np.diff(t)
    with np.errstate(divide="ignore", invalid="ignore"):
        speed = np.hypot(de, dn) / dt
    ok = np.isfinite(speed) & (speed >= min_speed)
    return 0.5 * (t[1:] + t[:-1])[ok], np.arctan2(de, dn)[ok] % TWO_PI
