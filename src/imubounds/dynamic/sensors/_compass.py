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

:func:`compass_heading` is the one function that turns a drive's heading
sources into a corrected heading with its bounds (:class:`CompassHeading`):
a compass or dual-antenna heading stream, or the raw magnetometer calibrated
by an ellipse fit (:mod:`imubounds.dynamic.sensors._magcal`), or an AHRS yaw;
corrected by a swing calibration file, the ellipse fit, or (only when asked
explicitly) a fit against the GNSS course, in which case the heading is no
longer independent of the GNSS and says so.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from imubounds.dynamic.sensors._course_check import (  # noqa: F401 (re-exported)
    COURSE_CHECK_BINS,
    COURSE_CHECK_HARMONICS,
    COURSE_CHECK_MIN_SPEED,
    COURSE_CHECK_SHARE,
    COURSE_CHECK_TESTS,
    COURSE_CHORD,
    TURN_MIN_DPS,
    HeadingModel,
    _interp_heading,
    _velocity_course,
    against_course,
    apply_heading_model,
    check_against_course,
    course_noise,
    estimate_heading_model,
    harmonic_fit,
)
from imubounds.errors import AnalysisError, InputError, OptionError
from imubounds.frames import TWO_PI, compass_to_model, wrap_pi
from imubounds.geodesy import course_over_ground
from imubounds.io.validate import check_input_path


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

    check_input_path(path, what="compass calibration file")
    try:
        data = pd.read_csv(path, comment="#", skipinitialspace=True)
    except pd.errors.EmptyDataError:
        raise InputError(
            f"{path}: the compass calibration file is empty; it needs columns "
            "measured_deg,reference_deg and at least 3 rows"
        ) from None
    except (OSError, ValueError, pd.errors.ParserError) as err:
        first = (str(err).splitlines() or [type(err).__name__])[0]
        raise InputError(f"{path}: cannot read compass calibration file ({first})") from err
    data.columns = [str(c).strip() for c in data.columns]
    names = list(data.columns)
    if "measured_deg" not in names or "reference_deg" not in names:
        raise InputError(
            f"{path}: compass calibration needs columns measured_deg,reference_deg; found {names}"
        )
    cols = []
    for name in ("measured_deg", "reference_deg"):
        v = pd.to_numeric(data[name], errors="coerce")
        bad = v.isna() & data[name].notna()
        if bad.any():
            i = int(np.flatnonzero(bad.to_numpy())[0])
            raise InputError(
                f"{path}: column {name}, data row {i + 1}: {data[name].iloc[i]!r} is not a number"
            )
        cols.append(np.radians(v.to_numpy(float)))
    n_ok = int((np.isfinite(cols[0]) & np.isfinite(cols[1])).sum())
    if n_ok < 3:
        raise InputError(
            f"{path}: the compass calibration has {n_ok} complete (measured_deg, reference_deg) "
            "row(s); at least 3 are needed for the deviation fit"
        )
    return fit_deviation(cols[0], cols[1], source=str(path))


def swing_deviation(calibration: str | Path | np.ndarray) -> CompassDeviation:
    """The deviation fitted to a swing calibration: a CSV file (:func:`read_calibration`)
    or the (measured_deg, reference_deg) pairs as an (n, 2) array."""
    if not isinstance(calibration, np.ndarray):
        return read_calibration(str(calibration))
    pairs = np.asarray(calibration, dtype=float)
    if pairs.ndim != 2 or pairs.shape[1] != 2:
        raise InputError(
            "heading.calibration given as an array must be (n, 2) pairs "
            f"(measured_deg, reference_deg); got shape {pairs.shape}"
        )
    return fit_deviation(
        np.radians(pairs[:, 0]), np.radians(pairs[:, 1]), source="swing pairs (memory)"
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


# ----------------------------------------------------------------------------- one heading

#: Deviation bound (deg) assumed for an uncalibrated compass when drive.yaml gives none.
UNCALIBRATED_DEVIATION_DEG = 10.0
FITS = ("auto", "ellipse", "swing", "gnss-course", "none")
USES = ("auto", "heading", "mag", "attitude")


@dataclass
class CompassHeading:
    """A corrected heading with its bounds, ready for an estimator.

    Attributes
    ----------
    t:
        Time stamps (s, the drive's clock).
    heading_rad:
        Corrected heading, clockwise from **true** north (declination applied to
        magnetic sources), in [0, 2 pi).
    deviation_bound_rad:
        Deterministic bound of the systematic error (calibration residual
        model, the stated alignment allowance, or ``heading.deviation_deg``).
    noise_sigma_rad:
        1-sigma of the random error per sample; the estimator's half-width for
        a sample is ``deviation_bound_rad + k * noise_sigma_rad`` at its level
        (:meth:`halfwidth_rad`).
    independent_of_gnss, independent_of_imu:
        False when the heading used the GNSS (a fit against the course, a
        dual-antenna heading) or the IMU's gyros (an AHRS yaw).
    source:
        ``"compass"``, ``"gnss"``, ``"magnetometer"`` or ``"ahrs"``.
    calibration:
        ``"ellipse"``, ``"swing"``, ``"gnss-course"``, ``"deviation_deg"`` or
        ``"none"``.
    notes, assumed:
        What an output must repeat: assumptions and defaults, checks.
    detail:
        The fitted calibration (a mapping).
    """

    t: np.ndarray
    heading_rad: np.ndarray
    deviation_bound_rad: float
    noise_sigma_rad: float
    independent_of_gnss: bool
    independent_of_imu: bool
    source: str
    calibration: str
    notes: list[str] = field(default_factory=list)
    assumed: list[str] = field(default_factory=list)
    detail: dict[str, Any] = field(default_factory=dict)
    #: the part of ``deviation_bound_rad`` that bounds a constant offset (the alignment
    #: allowance, or the half-width of the offset estimated against the GNSS course)
    constant_bound_rad: float = 0.0

    def halfwidth_rad(self, k: float) -> float:
        """Half-width of one sample's heading interval at ``k`` sigma of the noise."""
        return self.deviation_bound_rad + k * self.noise_sigma_rad

    def to_dict(self) -> dict[str, Any]:
        return {
            "n": int(self.t.size),
            "deviation_bound_deg": math.degrees(self.deviation_bound_rad),
            "noise_sigma_deg": math.degrees(self.noise_sigma_rad),
            "independent_of_gnss": self.independent_of_gnss,
            "independent_of_imu": self.independent_of_imu,
            "source": self.source,
            "calibration": self.calibration,
            "notes": list(self.notes),
            "assumed": list(self.assumed),
            "detail": self.detail,
        }


def k_sigma(alpha: float, n: int) -> float:
    """k with P(|w| > k sigma for any of n Gaussian samples) <= alpha (Sidak/Bonferroni)."""
    from scipy.stats import norm

    if not 0 < alpha < 1:
        raise OptionError(f"alpha must be between 0 and 1, got {alpha}")
    return float(norm.isf(alpha / (2.0 * max(n, 1))))


def _gnss_course(drive: Any, min_speed: float) -> tuple[np.ndarray, np.ndarray] | None:
    """(t, course rad clockwise from true north) of the GNSS while moving faster than
    ``min_speed``: the receiver's velocity if it has one, else consecutive positions."""
    from imubounds.geodesy import geodetic_to_enu

    g = drive.gnss
    if g is None:
        return None
    ok = g.usable()
    vel = _velocity_course(g, ok, min_speed)
    if vel is not None:
        return vel[0], vel[1]
    if ok.sum() < 3:
        return None
    e, n, _ = geodetic_to_enu(g.lat_deg[ok], g.lon_deg[ok])
    tm, cog = course_over_ground(g.t[ok], e, n, min_speed=min_speed)
    return (tm, cog) if tm.size >= 3 else None


def compass_heading(
    drive: Any,
    *,
    fit: str | None = None,
    calibration: str | Path | np.ndarray | None = None,
    use: str | None = None,
    declination_deg: float | None = None,
    deviation_deg: float | None = None,
    alignment_deg: float | None = None,
    alpha: float = 0.01,
    min_speed_mps: float = 3.0,
    estimate_errors: bool | None = None,
) -> CompassHeading:
    """The drive's heading, corrected, with a deterministic bound and a noise level.

    Every argument left ``None`` comes from ``drive.settings.heading``
    (``drive.yaml``); the arguments are the command-line overrides.

    Parameters
    ----------
    drive:
        A :class:`imubounds.io.drive.Drive`.
    fit:
        ``"auto"`` (a swing file if given; else an ellipse fit for a
        magnetometer; else ``deviation_deg``; else none), ``"ellipse"``,
        ``"swing"``, ``"gnss-course"`` (explicit only: the heading is then not
        independent of the GNSS) or ``"none"``.
    calibration:
        Swing-calibration CSV (``measured_deg,reference_deg``), or those pairs as an
        (n, 2) array in degrees.
    use:
        Which stream: ``"auto"`` (an independent heading stream, else the
        magnetometer, else an AHRS heading or the attitude yaw), ``"heading"``,
        ``"mag"``, ``"attitude"``.
    declination_deg:
        Magnetic declination (east positive), added to magnetic headings.
    deviation_deg:
        Deterministic deviation bound (deg) that replaces the calibration's.
    alignment_deg:
        Allowance (deg) for the constant offset no self-calibration sees.
    alpha:
        Probability, for the whole drive, that some sample's noise exceeds
        ``k * noise_sigma_rad`` (sets the k used to turn the largest residual
        of an ellipse fit into a noise level).
    min_speed_mps:
        GNSS course is used (fit or check) only above this speed.
    estimate_errors:
        Estimate the compass error model (constant offset, harmonics 1 and 2) against
        the GNSS course and take what the data detect off the headings
        (:func:`~imubounds.dynamic.sensors._course_check.estimate_heading_model`); False:
        the stated bound only, checked. None: ``heading.errors`` of drive.yaml
        (``"estimate"`` by default, or ``"stated"``).
    """
    hs = drive.settings.heading
    if estimate_errors is None:
        estimate_errors = hs.errors != "stated"
    fit = hs.fit if fit is None else fit
    use = hs.use if use is None else use
    if fit not in FITS:
        raise OptionError(f"compass fit {fit!r}: use one of {', '.join(FITS)}")
    if use not in USES:
        raise OptionError(f"compass source {use!r}: use one of {', '.join(USES)}")
    calibration = hs.calibration if calibration is None else calibration
    decl = hs.declination_deg if declination_deg is None else float(declination_deg)
    dev_given = hs.deviation_deg if deviation_deg is None else float(deviation_deg)
    align = hs.alignment_deg if alignment_deg is None else float(alignment_deg)
    for name, v in (("declination", decl), ("deviation", dev_given), ("alignment", align)):
        if v is not None and not math.isfinite(v):
            raise OptionError(f"compass {name} must be a finite number of degrees, got {v}")
    if dev_given is not None and dev_given < 0 or align < 0:
        raise OptionError("compass deviation and alignment bounds must be >= 0 deg")
    notes: list[str] = []
    assumed: list[str] = []
    src = _pick_source(drive, use)
    detail: dict[str, Any] = {}
    independent_of_imu = src != "ahrs" and src != "attitude"
    independent_of_gnss = src != "gnss"
    if fit == "auto":
        fit = (
            "swing" if calibration is not None
            else "ellipse" if src == "mag"
            else "none"
        )
    if fit == "ellipse" and src != "mag":
        raise OptionError(
            "an ellipse fit calibrates a raw magnetometer; this drive's heading comes from "
            f"its {src} stream (choose the magnetometer with use=mag, or another fit)"
        )
    if fit == "swing" and calibration is None:
        raise OptionError("a swing calibration needs a file (heading.calibration or --compass-cal)")
    # ---- the measured heading
    if src == "mag":
        t, meas, magnetic, noise_sigma, dev_bound = _mag_heading(drive, fit, alpha, detail, notes)
    else:
        t, meas, magnetic = _stream_heading(drive, src)
        noise_sigma = math.radians(hs.noise_deg)
        dev_bound = 0.0
        if "heading.noise_deg" in drive.settings.defaulted:
            assumed.append(f"heading noise 1-sigma {hs.noise_deg:g} deg (default)")
    corrected = meas
    # ---- calibrations against a reference
    if fit == "swing":
        dev = swing_deviation(calibration)
        if isinstance(calibration, np.ndarray):
            calibration = f"({calibration.shape[0]} swing pairs in memory)"
        corrected = np.mod(meas - dev.error(meas), TWO_PI)
        dev_bound = dev.residual_bound
        detail["swing"] = dev.to_dict()
        notes.append(f"compass corrected by the swing calibration {calibration} (residual bound "
                     f"{math.degrees(dev.residual_bound):.2f} deg on its {dev.n} pairs)")
    elif fit == "gnss-course":
        gc = _gnss_course(drive, min_speed_mps)
        if gc is None:
            raise AnalysisError(
                f"{drive.source}: no GNSS course while moving faster than {min_speed_mps:g} m/s: "
                "cannot fit the compass to the GNSS"
            )
        m_at = _interp_heading(t, gc[0], meas)
        ref = np.mod(gc[1] - (math.radians(decl) if magnetic else 0.0), TWO_PI)
        dev = fit_deviation(m_at, ref, source="gnss-course")
        corrected = np.mod(meas - dev.error(meas), TWO_PI)
        dev_bound = dev.residual_bound
        independent_of_gnss = False
        detail["gnss_course"] = dev.to_dict()
        notes.append(
            "the compass deviation was fitted against the GNSS course over ground: the heading "
            "is NOT independent of the GNSS (it cannot check it)"
        )
    # ---- the deterministic bound
    calib_name = fit if fit != "none" else ("deviation_deg" if dev_given is not None else "none")
    if dev_given is not None:
        dev_bound = math.radians(dev_given)
        notes.append(f"heading deviation bound {dev_given:g} deg from the drive settings")
    elif fit == "none":
        if src in ("compass", "heading") or src == "attitude" and magnetic:
            dev_bound = math.radians(UNCALIBRATED_DEVIATION_DEG)
            assumed.append(
                f"uncalibrated heading: deviation bound {UNCALIBRATED_DEVIATION_DEG:g} deg "
                "(default; give heading.deviation_deg or a swing calibration)"
            )
        else:
            assumed.append(f"{src} heading: no deviation beyond the noise (default)")
    if align > 0:
        dev_bound += math.radians(align)
        notes.append(f"alignment allowance {align:g} deg added to the deviation bound")
    elif src == "mag" or src == "compass":
        assumed.append(
            "heading.alignment_deg = 0: the magnetometer's yaw is aligned with the vehicle and "
            "the soft iron has no rotational part (a constant offset that no self-calibration "
            "can see; default)"
        )
    # ---- true north
    if magnetic:
        corrected = np.mod(corrected + math.radians(decl), TWO_PI)
        if "heading.declination_deg" in drive.settings.defaulted and declination_deg is None:
            assumed.append("magnetic declination 0 deg (default; heading.declination_deg)")
    out = CompassHeading(
        t=t,
        heading_rad=corrected,
        deviation_bound_rad=float(dev_bound),
        noise_sigma_rad=float(noise_sigma),
        independent_of_gnss=independent_of_gnss,
        independent_of_imu=independent_of_imu,
        source={"mag": "magnetometer", "attitude": "ahrs"}.get(src, src),
        calibration=calib_name,
        notes=notes,
        assumed=assumed,
        detail=detail,
        constant_bound_rad=math.radians(align),
    )
    if not independent_of_imu:
        notes.append("the heading is an AHRS yaw: it uses the IMU's gyros and is not "
                     "independent of the IMU")
    if fit != "gnss-course":
        against_course(drive, out, alpha, min_speed_mps, math.radians(align), estimate_errors)
    return out


def _pick_source(drive: Any, use: str) -> str:
    h, m, a = drive.heading, drive.mag, drive.attitude
    if use == "heading":
        if h is None:
            raise InputError(f"{drive.source}: no heading stream (heading.csv heading_deg)")
        return {"gnss": "gnss", "ahrs": "ahrs"}.get(h.source, "compass")
    if use == "mag":
        if m is None:
            raise InputError(f"{drive.source}: no magnetometer (heading.csv mag_x/y/z_<unit>)")
        return "mag"
    if use == "attitude":
        if a is None or a.yaw_rad is None:
            raise InputError(f"{drive.source}: no attitude yaw (attitude.csv yaw_deg)")
        return "attitude"
    if h is not None and h.source in ("compass", "gnss"):
        return h.source
    if m is not None:
        return "mag"
    if h is not None:
        return "ahrs"
    if a is not None and a.yaw_rad is not None:
        return "attitude"
    raise InputError(
        f"{drive.source}: no heading source: give heading.csv (heading_deg or mag_x/y/z_<unit>) "
        "or an attitude yaw"
    )


def _stream_heading(drive: Any, src: str) -> tuple[np.ndarray, np.ndarray, bool]:
    if src == "attitude":
        a = drive.attitude
        return a.t, np.mod(a.yaw_rad, TWO_PI), True
    h = drive.heading
    return h.t, np.mod(h.heading_rad, TWO_PI), not h.true_north


def _mag_heading(
    drive: Any, fit: str, alpha: float, detail: dict[str, Any], notes: list[str]
) -> tuple[np.ndarray, np.ndarray, bool, float, float]:
    from imubounds.dynamic.sensors._magcal import fit_magnetometer

    m = drive.mag
    a = drive.attitude
    roll = pitch = None
    if a is not None:
        roll = np.interp(m.t, a.t, a.roll_rad)
        pitch = np.interp(m.t, a.t, a.pitch_rad)
        inside = (m.t >= a.t[0]) & (m.t <= a.t[-1])
        if not inside.all():
            notes.append(f"{int((~inside).sum())} magnetometer sample(s) outside the attitude "
                         "stream: its end values are used for their tilt")
    if fit == "ellipse":
        from imubounds.dynamic.sensors._magcal import MIN_COVERAGE_DEG

        turn = _imu_turn_deg(drive, m.t[0], m.t[-1])
        if turn is not None and turn < MIN_COVERAGE_DEG:
            raise AnalysisError(
                f"{drive.source}: the drive turns through {turn:.0f} deg of heading only (the "
                f"IMU's yaw over the magnetometer's time); an ellipse fit of the magnetometer "
                f"needs {MIN_COVERAGE_DEG:.0f} deg or more: give a swing calibration file, "
                "heading.deviation_deg, or fit to the GNSS course explicitly"
            )
        cal = fit_magnetometer(m.mag, roll, pitch)
        k = k_sigma(alpha, cal.n)
        sigma = cal.residual_sigma
        radial = cal.residual(m.mag, roll, pitch)
        keep = np.abs(radial) <= k * sigma
        heading = cal.heading(m.mag, roll, pitch)
        # parameter error of the fit (10 parameters), at 3 sigma
        fit_term = 3.0 * sigma * math.sqrt(10.0 / max(cal.n, 1))
        detail["ellipse"] = cal.to_dict()
        detail["ellipse"]["disturbed_samples"] = int((~keep).sum())
        notes.append(
            f"magnetometer calibrated by an ellipse fit ("
            f"{'tilt-compensated with the attitude' if cal.levelled else 'level assumed'}; "
            f"hard and soft iron) on {cal.n} samples covering {cal.coverage_deg:.0f} deg: "
            f"residual {100 * sigma:.1f} % (robust sigma), {100 * cal.residual_max:.1f} % max "
            "of the horizontal field"
        )
        notes.append(
            "heading noise from the fit's radial residual, assuming the disturbance of the field "
            "is as large across it as along it (isotropic)"
        )
        if not keep.all():
            notes.append(
                f"{int((~keep).sum())} magnetometer sample(s) with a disturbed field (radial "
                f"residual beyond {k:.1f} sigma) dropped"
            )
        notes.extend(cal.notes)
        return (m.t[keep], heading[keep], True, math.asin(min(1.0, sigma)),
                math.asin(min(1.0, fit_term)))
    # a swing file or a GNSS fit of the raw levelled magnetometer (hard iron as one-cycle)
    from imubounds.frames import level_vectors

    v = m.mag if roll is None else level_vectors(m.mag, roll, pitch)  # type: ignore[arg-type]
    heading = heading_from_magnetometer(v[:, 0], v[:, 1], "FLU")
    notes.append("magnetometer heading from the raw field (levelled when the attitude is known)")
    return m.t, heading, True, math.radians(drive.settings.heading.noise_deg), 0.0


def _imu_turn_deg(drive: Any, t0: float, t1: float) -> float | None:
    """Range of the heading the IMU's gyro z turns through over [t0, t1] (deg), a check of
    whether a magnetometer self-calibration can work; None without a gyro z."""
    imu = drive.imu
    if imu is None or not np.isfinite(imu.gyro[:, 2]).all():
        return None
    sel = (imu.t >= t0) & (imu.t <= t1)
    if sel.sum() < 2:
        return None
    t, gz = imu.t[sel], imu.gyro[sel, 2]
    psi = np.concatenate(([0.0], np.cumsum(0.5 * (gz[1:] + gz[:-1]) * np.diff(t))))
    return float(np.degrees(np.ptp(psi)))
