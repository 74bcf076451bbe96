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
by an ellipse fit (:mod:`imubounds.dynamic.aiding.magcal`), or an AHRS yaw;
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


def _velocity_course(
    g: Any, ok: np.ndarray, min_speed: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """(t, course rad clockwise from true north, speed m/s) from the receiver's velocity
    where usable and faster than ``min_speed``; None without velocity or with fewer than
    three such fixes."""
    ne = g.velocity_ne()
    if ne is None:
        return None
    vn, ve = ne
    sp = np.hypot(vn, ve)
    keep = ok & np.isfinite(sp) & (sp >= min_speed)
    if keep.sum() < 3:
        return None
    return g.t[keep], np.mod(np.arctan2(ve[keep], vn[keep]), TWO_PI), sp[keep]


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


def _interp_heading(t: np.ndarray, tq: np.ndarray, h: np.ndarray) -> np.ndarray:
    return np.mod(np.interp(tq, t, np.unwrap(h)), TWO_PI)


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
    """
    hs = drive.settings.heading
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
    )
    if not independent_of_imu:
        notes.append("the heading is an AHRS yaw: it uses the IMU's gyros and is not "
                     "independent of the IMU")
    if fit != "gnss-course":
        _check_against_course(drive, out, alpha, min_speed_mps)
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
    from imubounds.dynamic.aiding.magcal import fit_magnetometer

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
        from imubounds.dynamic.aiding.magcal import MIN_COVERAGE_DEG

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


#: heading bins of the check against the GNSS course (the deviation's shape)
COURSE_CHECK_BINS = 12
#: the check against the GNSS course uses epochs at least this fast (m/s) and this many
#: times the lateral speed bound (the sideslip bound asin(lateral / speed) stays small)
COURSE_CHECK_MIN_SPEED = 5.0
#: share of the trip's alpha given to the check against the GNSS course (the residual
#: checks get another quarter; dynamic-method.md 5b)
COURSE_CHECK_SHARE = 0.25
#: turns for the signed test of the check against the GNSS course: |yaw rate| at least
#: this (deg/s) and half the trip's 99th percentile
TURN_MIN_DPS = 2.0
#: fixes spanned by one chord of the course from positions (no receiver velocity)
COURSE_CHORD = 5
#: harmonics of the deviation tested by the check against the GNSS course (cycles 1 and 2:
#: the cos and sin coefficient of each, one test each)
COURSE_CHECK_HARMONICS = 2
#: tests of the check against the GNSS course: the mean, the turns, the heading bins and
#: the 2 x COURSE_CHECK_HARMONICS coefficients (Bonferroni within COURSE_CHECK_SHARE)
COURSE_CHECK_TESTS = 2 + COURSE_CHECK_BINS + 2 * COURSE_CHECK_HARMONICS


def course_noise(
    drive: Any, min_speed: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None:
    """(t, course rad clockwise from north, 1-sigma of the course rad, a lower bound of
    the speed m/s at 3 sigma) of the GNSS while faster than ``min_speed``: from the
    receiver's velocity (sigma = vel sigma / speed) or from chords of
    :data:`COURSE_CHORD` fixes (sigma = sqrt(2) x position sigma per axis / length),
    the GNSS errors being isotropic Gaussian (drive.yaml gnss: cep_m, vel_sigma_mps)."""
    from imubounds.geodesy import geodetic_to_enu

    g = drive.gnss
    if g is None:
        return None
    st = drive.settings.gnss
    ok = g.usable()
    vel = _velocity_course(g, ok, min_speed)
    if vel is not None:
        sv = float(st.vel_sigma_mps)
        return vel[0], vel[1], sv / vel[2], vel[2] - 3.0 * sv
    if ok.sum() < 3:
        return None
    e, n, _ = geodetic_to_enu(g.lat_deg[ok], g.lon_deg[ok])
    t = g.t[ok]
    hd = g.hdop[ok].astype(float) if g.hdop is not None else np.full(e.size, np.nan)
    hd = np.where(np.isfinite(hd) & (hd > 0), hd, float(st.default_hdop))
    s_ax = hd * float(st.cep_m) / math.sqrt(2.0 * math.log(2.0))
    # chords of COURSE_CHORD fixes (not overlapping): the chord of an arc points along
    # its tangent at the middle, and its noise is COURSE_CHORD times smaller
    c = COURSE_CHORD
    i0 = np.arange(0, e.size - c, c)
    i1 = i0 + c
    de, dn = e[i1] - e[i0], n[i1] - n[i0]
    dt = t[i1] - t[i0]
    dist = np.hypot(de, dn)
    med = float(np.median(np.diff(t))) if t.size > 1 else 1.0
    with np.errstate(divide="ignore", invalid="ignore"):
        speed = dist / dt
    keep = np.isfinite(speed) & (speed >= min_speed) & (dt <= 1.5 * c * med)
    if keep.sum() < 3:
        return None
    s_d = np.hypot(s_ax[i0], s_ax[i1])[keep]
    return (
        0.5 * (t[i0] + t[i1])[keep],
        np.arctan2(de, dn)[keep] % TWO_PI,
        s_d / dist[keep],
        speed[keep] - 3.0 * s_d / dt[keep],
    )


def harmonic_test(
    psi: np.ndarray,
    d: np.ndarray,
    sig2: np.ndarray,
    bound: np.ndarray,
    k: float,
    rate: np.ndarray | None = None,
    psi_var: float = 0.0,
) -> list[dict[str, Any]]:
    """The deviation's harmonics in ``d = heading - course`` (rad), one test per coefficient.

    ``c = W d`` the weighted least-squares coefficients (weights ``1/sig2``) of the basis
    ``1, cos psi, sin psi, ..., cos(H psi), sin(H psi)`` (H = :data:`COURSE_CHECK_HARMONICS`)
    and, when ``rate`` is given, the yaw rate (a clock offset between the two streams shows
    as offset x rate: its column takes it out of the harmonics, to first order). With
    ``d_i = e_i + n_i``, ``|e_i| <= bound_i`` (deviation bound + sideslip bound, any sign)
    and ``n_i`` independent Gaussian of variance ``sig2_i``, every coefficient of a
    harmonic obeys ``|c_j| <= sum_i |W_ji| bound_i + k sqrt(sum_i W_ji^2 sig2_i)`` but
    with the probability of a Gaussian beyond k sigma: a larger ``|c_j|`` is a deviation
    the bound does not cover. The weights are taken at the measured ``psi``, whose noise
    (variance ``psi_var``, rad^2) is part of ``d``'s: to second order it biases ``c_j`` by
    ``psi_var sum_i dW_ji/dpsi_i``, whose absolute values are added to the bound. Returns,
    per harmonic coefficient, ``{cycle, term, coef, limit, det, sd}`` (rad); empty when
    the design is singular (headings not spread)."""
    cols, dcols = [np.ones_like(psi)], [np.zeros_like(psi)]
    for m in range(1, COURSE_CHECK_HARMONICS + 1):
        cols += [np.cos(m * psi), np.sin(m * psi)]
        dcols += [-m * np.sin(m * psi), m * np.cos(m * psi)]
    if rate is not None:
        cols.append(rate)
        dcols.append(np.zeros_like(psi))
    a, da = np.column_stack(cols), np.column_stack(dcols)
    w = 1.0 / sig2
    nrm = a.T @ (a * w[:, None])
    if a.shape[0] <= a.shape[1] or np.linalg.cond(nrm) > 1e8:
        return []
    wm = np.linalg.solve(nrm, (a * w[:, None]).T)  # rows: the coefficients' weights
    coef = wm @ d
    # dW_:,i/dpsi_i = M^-1 a'_i w_i (1 - h_i) - W_:,i w_i a'_i.M^-1 a_i (M = A'wA, h_i the
    # leverage w_i a_i.M^-1 a_i): the derivative of the column W_:,i = M^-1 a_i w_i
    dm = np.linalg.solve(nrm, (da * w[:, None]).T)
    lev = np.einsum("ij,ji->i", a, wm)
    cross = np.einsum("ij,ji->i", da, wm)
    dwm = dm * (1.0 - lev) - wm * cross
    out: list[dict[str, Any]] = []
    for j in range(1, 1 + 2 * COURSE_CHECK_HARMONICS):
        det = float(np.abs(wm[j]) @ bound) + psi_var * float(np.sum(np.abs(dwm[j])))
        sd = math.sqrt(float(wm[j] ** 2 @ sig2))
        out.append({"cycle": (j + 1) // 2, "term": "cos" if j % 2 else "sin",
                    "coef": float(coef[j]), "limit": det + k * sd, "det": det, "sd": sd})
    return out


def _check_against_course(drive: Any, ch: CompassHeading, alpha: float, min_speed: float) -> None:
    """Compare (never fit) the corrected heading with the GNSS course, signed.

    ``d = heading - course`` at the GNSS epochs faster than :data:`COURSE_CHECK_MIN_SPEED`
    (and 5 x the lateral speed bound). With the stated assumptions (a compass error
    within its deviation bound plus white Gaussian noise, the sideslip within
    asin(lateral bound / speed) at the speed's 3-sigma lower bound, isotropic Gaussian
    GNSS errors), the mean of ``d`` over all the epochs and over each of
    :data:`COURSE_CHECK_BINS` heading bins, and of ``d`` x sign(yaw rate) over the turns
    (a clock offset between the streams), lies within the deviation bound + the mean
    sideslip bound + k sigma_mean; and each cos / sin coefficient of the deviation's
    harmonics 1 to :data:`COURSE_CHECK_HARMONICS` (least squares of ``d`` on the harmonics,
    a constant and the yaw rate, :func:`harmonic_test`) lies within ``sum_i |W_ji|
    (deviation bound + sideslip bound_i) + k sd_j``; k two-sided at level ``alpha`` x
    :data:`COURSE_CHECK_SHARE` split over the :data:`COURSE_CHECK_TESTS` tests. A larger
    signed mean is a constant offset (mount, declination), a deviation shape the bound
    does not cover or a clock offset: ``detail['gnss_course_check']['passed']`` is False
    and the check says which.
    """
    veh = drive.settings.vehicle
    lat = veh.lateral_speed_bound_mps
    vmin = max(min_speed, COURSE_CHECK_MIN_SPEED, 5.0 * (lat or 0.0))
    gc = course_noise(drive, vmin)
    if gc is None:
        return
    tc, course, sig_c, v_lo = gc
    inside = (tc >= ch.t[0]) & (tc <= ch.t[-1])
    if inside.sum() < 10:
        return
    tc, course, sig_c, v_lo = tc[inside], course[inside], sig_c[inside], v_lo[inside]
    h = _interp_heading(ch.t, tc, ch.heading_rad)
    d = np.asarray(wrap_pi(h - course), dtype=float)
    if lat is None:
        ch.detail["gnss_course_check"] = {
            "n": int(d.size),
            "mean_diff_deg": math.degrees(float(np.mean(d))),
            "passed": None,
            "rule": "not tested: no lateral speed bound (the sideslip is not bounded)",
        }
        return
    sig2 = sig_c**2 + ch.noise_sigma_rad**2
    # the course's own noise is large at a single epoch: the test is on means
    slip = np.arcsin(np.minimum(1.0, lat / np.maximum(v_lo, 1e-9)))
    from scipy.stats import norm

    level = alpha * COURSE_CHECK_SHARE
    k = float(norm.isf(level / (2.0 * COURSE_CHECK_TESTS)))
    dev = ch.deviation_bound_rad

    def test(sel: np.ndarray, sign: np.ndarray | None = None) -> tuple[float, float]:
        x = d[sel] if sign is None else d[sel] * sign[sel]
        m = float(np.mean(x))
        noise = k * math.sqrt(float(np.sum(sig2[sel]))) / int(sel.sum())
        lim = dev + float(np.mean(slip[sel])) + noise
        return m, lim

    m_all, lim_all = test(np.ones(d.size, dtype=bool))
    # in the turns, signed by the turn: a clock offset between the two streams shows
    # as offset x yaw rate (the yaw rate from the IMU's gyro, independent of d's noise)
    turn: dict[str, float] | None = None
    imu = drive.imu
    r = None
    if imu is not None and np.isfinite(imu.gyro[:, 2]).all() and imu.t.size > 1:
        r = np.interp(tc, imu.t, imu.gyro[:, 2])
        thr = max(math.radians(TURN_MIN_DPS), 0.5 * float(np.percentile(np.abs(r), 99)))
        sel_t = np.abs(r) >= thr
        if sel_t.sum() >= 5:
            m_t, lim_t = test(sel_t, np.sign(r))
            turn = {"mean_diff_deg": math.degrees(m_t), "limit_deg": math.degrees(lim_t),
                    "n": int(sel_t.sum()), "mean_rate_dps": math.degrees(
                        float(np.mean(np.abs(r[sel_t]))))}
    worst: list[tuple[float, float, float]] = []
    bins = np.floor(np.mod(h, TWO_PI) / (TWO_PI / COURSE_CHECK_BINS)).astype(int)
    for b in range(COURSE_CHECK_BINS):
        sel = bins == b
        if sel.sum() >= 3:
            m, lim = test(sel)
            if abs(m) > lim:
                worst.append((b * 360.0 / COURSE_CHECK_BINS, m, lim))
    turn_failed = turn is not None and abs(turn["mean_diff_deg"]) > turn["limit_deg"]
    # the deviation's harmonics, least squares over every epoch (the bins' power pooled)
    harm = harmonic_test(h, d, sig2, dev + slip, k, r, ch.noise_sigma_rad**2)
    harm_failed = [c for c in harm if abs(c["coef"]) > c["limit"]]
    passed = abs(m_all) <= lim_all and not worst and not turn_failed and not harm_failed
    ch.detail["gnss_course_check"] = {
        "n": int(d.size),
        "mean_diff_deg": math.degrees(m_all),
        "limit_deg": math.degrees(lim_all),
        "bins_failed": [
            {"heading_from_deg": a, "mean_diff_deg": math.degrees(m), "limit_deg": math.degrees(li)}
            for a, m, li in worst
        ],
        "turns": turn,
        "harmonics": [
            {"cycle": c["cycle"], "term": c["term"], "coef_deg": math.degrees(c["coef"]),
             "limit_deg": math.degrees(c["limit"]), "bound_part_deg": math.degrees(c["det"]),
             "sd_deg": math.degrees(c["sd"])}
            for c in harm
        ],
        "passed": passed,
        "rule": (
            f"signed mean of heading - GNSS course (speed >= {vmin:g} m/s) within deviation "
            f"bound + sideslip bound + k sigma of the mean, k = {k:.3g} (two-sided, level "
            f"{level:g} over 1 + {COURSE_CHECK_BINS} heading bins + the turns signed by the "
            f"yaw rate + the cos and sin coefficients of the deviation's harmonics 1 to "
            f"{COURSE_CHECK_HARMONICS} (least squares with the yaw rate, limit sum|W| x "
            "(deviation + sideslip bound) + k sd))"
        ),
    }
    if abs(m_all) > lim_all:
        ch.notes.append(
            f"check failed: the corrected heading differs from the GNSS course by a mean "
            f"{math.degrees(m_all):+.2f} deg, beyond the {math.degrees(lim_all):.2f} deg its "
            "bounds allow: a constant heading offset (declination, mount, "
            "heading.alignment_deg)"
        )
    elif turn_failed and turn is not None:
        lag = turn["mean_diff_deg"] / max(turn["mean_rate_dps"], 1e-9)
        ch.notes.append(
            f"check failed: in the turns the corrected heading differs from the GNSS course "
            f"by a mean {turn['mean_diff_deg']:+.2f} deg signed by the turn, beyond the "
            f"{turn['limit_deg']:.2f} deg its bounds allow: a clock offset between the "
            f"heading and the GNSS (about {lag:+.2f} s at the mean turn rate "
            f"{turn['mean_rate_dps']:.1f} deg/s), or a deviation the bound does not cover"
        )
    elif worst:
        ch.notes.append(
            f"check failed: in {len(worst)} heading bin(s) the corrected heading differs "
            f"from the GNSS course by more than its bounds allow (worst mean "
            f"{math.degrees(max(abs(w[1]) for w in worst)):.2f} deg): the compass deviation "
            "is larger than heading.deviation_deg or has more cycles than the calibration"
        )
    elif harm_failed:
        c = max(harm_failed, key=lambda c: abs(c["coef"]) - c["limit"])
        ch.notes.append(
            f"check failed: the {c['term']} coefficient of the heading's {c['cycle']}-cycle "
            f"deviation against the GNSS course is {math.degrees(c['coef']):+.2f} deg, beyond "
            f"the {math.degrees(c['limit']):.2f} deg its bounds allow: the compass deviation "
            "is larger than heading.deviation_deg or has more cycles than the calibration"
        )
