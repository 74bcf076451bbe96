"""The heading as a sensor (METHOD.md 2.1; docs/dynamic-method.md, section 3): a compass or
dual-antenna heading stream, a magnetometer (hard and soft iron), an AHRS yaw, or the GNSS
course; the deviation and its calibration, the check against the GNSS course, and the
heading stream of mode full with its intervals.

The surface of the heading sensor; the implementation by concept beside it:

* :mod:`._compass` -- the compass error model and :func:`compass_heading`, the one
  function that turns a drive's heading sources into a corrected heading with its bounds;
* :mod:`._course_check` -- the check against the GNSS course and the compass error model
  estimated from it;
* :mod:`._magcal` -- the magnetometer's hard- and soft-iron calibration.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from imubounds.constants import ROUND_REL
from imubounds.dynamic.estimator.budget import Term
from imubounds.dynamic.estimator.inputs import lateral_h_bound
from imubounds.dynamic.sensors._compass import (
    FITS,
    UNCALIBRATED_DEVIATION_DEG,
    USES,
    ZERO_DEVIATION,
    CompassDeviation,
    CompassHeading,
    compass_heading,
    fit_deviation,
    heading_from_magnetometer,
    heading_intervals,
    k_sigma,
    read_calibration,
    swing_deviation,
)
from imubounds.dynamic.sensors._course_check import (
    ALPHA_FAMILIES_MAX,
    COURSE_CHECK_MIN_SPEED,
    COURSE_CHECK_SHARE,
    DEFAULT_HEADING_CLOCK_BOUND_S,
    HeadingModel,
    check_against_course,
    course_noise,
    estimate_heading_model,
)
from imubounds.dynamic.sensors._magcal import MagCalibration, fit_magnetometer
from imubounds.errors import AnalysisError, InputError
from imubounds.frames import compass_to_model
from imubounds.interval.rounding import up as _up
from imubounds.units import DEG

if TYPE_CHECKING:
    from imubounds.dynamic.estimator.budget import AlphaPlan
    from imubounds.dynamic.estimator.inputs import Aiding, Vehicle
    from imubounds.dynamic.estimator.options import FullOptions

__all__ = [
    "ALPHA_FAMILIES_MAX",
    "COURSE_CHECK_MIN_SPEED",
    "COURSE_CHECK_SHARE",
    "DEFAULT_HEADING_CLOCK_BOUND_S",
    "FITS",
    "UNCALIBRATED_DEVIATION_DEG",
    "USES",
    "ZERO_DEVIATION",
    "CompassDeviation",
    "CompassHeading",
    "HeadingInput",
    "HeadingModel",
    "MagCalibration",
    "check_against_course",
    "course_heading",
    "compass_heading",
    "course_noise",
    "estimate_heading_model",
    "fit_deviation",
    "fit_magnetometer",
    "heading_from_magnetometer",
    "heading_boxes",
    "heading_input",
    "heading_intervals",
    "k_sigma",
    "read_calibration",
    "swing_deviation",
]


@dataclass
class HeadingInput:
    """A heading stream ready for intervals: compass heading (rad, clockwise from north)
    after deviation correction, with its deviation bound and noise sigma."""

    t: np.ndarray
    heading_rad: np.ndarray
    deviation_bound_rad: float
    noise_sigma_rad: float
    source: str
    deviation_source: str = ""
    noise_source: str = ""
    noise_gain: float = 1.0
    independent_of_gnss: bool = True
    independent_of_imu: bool = True
    notes: list[str] = field(default_factory=list)
    #: the signed check against the GNSS course (course_check.check_against_course)
    course_check: dict[str, Any] | None = None
    #: the compass error model estimated against the GNSS course
    #: (course_check.estimate_heading_model; HeadingModel.to_dict), None when not estimated
    model: dict[str, Any] | None = None


def heading_input(drive: Any, opts: FullOptions) -> HeadingInput | None:
    """The heading source of a drive, through the one compass function
    :func:`imubounds.dynamic.sensors._compass.compass_heading` (calibration, declination
    and deviation bound from ``drive.yaml: heading``; ``--declination``,
    ``--heading-deviation`` and ``--heading-noise`` override).

    A heading that cannot be calibrated with the default settings (a magnetometer whose
    drive turns too little for an ellipse fit, say) leaves the drive without a heading
    sensor, with a note saying why; asked for explicitly (``heading.fit`` or
    ``heading.use`` in ``drive.yaml``) the error is the user's to see.
    """
    att = drive.attitude
    ahrs_yaw = att is not None and getattr(att, "yaw_rad", None) is not None
    if drive.heading is None and drive.mag is None and not ahrs_yaw:
        return None
    st = drive.settings.heading
    cal = opts.compass_cal
    if cal is not None:
        from imubounds.io.validate import check_input_path

        cal = str(check_input_path(cal, what="compass calibration", option="--compass-cal"))
    try:
        ch = compass_heading(
            drive,
            fit=opts.compass_fit,
            calibration=cal,
            declination_deg=opts.declination_deg,
            deviation_deg=opts.heading_deviation_deg,
            alpha=float(opts.alpha),
        )
    except (InputError, AnalysisError) as exc:
        explicit = (
            cal is not None
            or opts.compass_fit is not None
            or not {"heading.fit", "heading.use"} <= set(drive.settings.defaulted)
        )
        if explicit:
            raise
        return HeadingInput(
            t=np.zeros(0),
            heading_rad=np.zeros(0),
            deviation_bound_rad=0.0,
            noise_sigma_rad=0.0,
            source="none",
            notes=[f"heading sensor not used: {exc}"],
        )
    noise = opts.heading_noise_deg
    noise_rad = float(noise) * DEG if noise is not None else float(ch.noise_sigma_rad)
    gain = 1.0
    for key in ("swing", "gnss_course"):
        cal = ch.detail.get(key)
        if isinstance(cal, dict) and "B_rad" in cal and "C_rad" in cal:
            # the correction is evaluated at the noisy reading
            gain = 1.0 + abs(float(cal["B_rad"])) + abs(float(cal["C_rad"]))
    model = ch.detail.get("heading_model")
    if isinstance(model, dict) and model.get("applied"):
        # the estimated correction is evaluated at the noisy reading too
        gain *= float(model["noise_gain"])
    dev_src = f"compass_heading() ({ch.calibration})"
    if opts.heading_deviation_deg is not None:
        dev_src = "option"
    elif st.deviation_deg is not None:
        dev_src = "drive.yaml"
    return HeadingInput(
        t=np.asarray(ch.t, dtype=float),
        heading_rad=np.asarray(ch.heading_rad, dtype=float),
        deviation_bound_rad=float(ch.deviation_bound_rad),
        noise_sigma_rad=noise_rad,
        source=str(ch.source),
        deviation_source=dev_src,
        noise_source="option" if noise is not None else "compass_heading()",
        noise_gain=gain,
        independent_of_gnss=bool(ch.independent_of_gnss),
        independent_of_imu=bool(ch.independent_of_imu),
        notes=list(ch.notes) + list(ch.assumed),
        course_check=ch.detail.get("gnss_course_check"),
        model=model if isinstance(model, dict) else None,
    )


# ---------------------------------------------------------------------- the boxes


def heading_boxes(ag: Aiding, heading: Any, alpha: AlphaPlan, t0: float) -> None:
    """Heading intervals: deviation bound + k x noise at each heading epoch."""
    k = alpha.k("heading")
    ag.head_t = np.asarray(heading.t, dtype=float) - t0
    cen = np.unwrap(np.asarray(compass_to_model(heading.heading_rad), dtype=float))
    ag.head_c = cen
    half = heading.deviation_bound_rad + k * heading.noise_sigma_rad * heading.noise_gain
    ag.head_h = _up(np.full(cen.size, half) * (1 + ROUND_REL))
    ag.head_sig = heading.noise_sigma_rad * heading.noise_gain
    ag.head_det = heading.deviation_bound_rad
    ag.head_source = heading.source
    ag.head_independent_of_imu = heading.independent_of_imu
    ag.budget["heading"] = [
        Term(
            "deviation bound",
            heading.deviation_bound_rad / DEG,
            "deg",
            heading.deviation_source,
            "after the one-cycle deviation correction",
        ),
        Term(
            "noise sigma",
            heading.noise_sigma_rad / DEG,
            "deg",
            heading.noise_source,
            "Gaussian; x (1 + |B| + |C|) for the correction evaluated at the noisy reading",
        ),
        Term("k", k, "", "alpha plan", f"Bonferroni over {cen.size} heading epochs"),
        Term("half-width", half / DEG, "deg", "computed", "deviation + k x noise"),
    ]


def course_heading(ag: Aiding, vehicle: Vehicle, opts: FullOptions) -> None:
    """Heading from the GNSS course when there is no heading sensor: with the lateral
    velocity bound ``vl`` and a vehicle that does not reverse (the horizontal velocity
    points forward), ``|psi - chi| <= asin(vl / S)``; with the velocity radius ``R``,
    ``S >= |Vm| - R`` and ``|chi - chi_m| <= asin(R / |Vm|)``. Epochs slower than
    ``R + vl`` give no heading. Holds on the GNSS-velocity event (no extra probability)."""
    vh = lateral_h_bound(vehicle)
    if vh is None:
        ag.notes.append("no heading sensor and no lateral velocity bound: no heading")
        return
    if opts.reverses:
        ag.notes.append("the vehicle may reverse (--reverses): no heading from the GNSS course")
        return
    ok = ag.gvel_ok
    ve, vn, R = ag.gvel_e, ag.gvel_n, ag.gvel_hi
    s = np.hypot(np.nan_to_num(ve), np.nan_to_num(vn))
    use = ok & (s * (1 - 1e-9) > R + vh)
    if not np.any(use):
        ag.notes.append("no GNSS velocity fast enough for a heading from the course")
        return
    s_u, R_u = s[use], R[use]
    e_chi = np.arcsin(np.minimum(1.0, R_u / s_u))
    d = np.arcsin(np.minimum(1.0, vh / ((s_u - R_u) * (1 - ROUND_REL))))
    half = _up((e_chi + d) * (1 + 1e-9) + 1e-15)
    chi = np.arctan2(vn[use], ve[use])
    ag.head_t = ag.gnss_t[use]
    ag.head_c = np.unwrap(chi)
    ag.head_h = half
    ag.head_source = "GNSS course"
    ag.head_independent_of_imu = True
    ag.head_from_course = True
    ag.budget["heading"] = [
        Term(
            "lateral velocity bound",
            vh,
            "m/s",
            vehicle.sources.get("lateral_speed_bound_mps", "default"),
            "|horizontal lateral velocity| (vehicle bound, plus sin(max tilt) x vertical bound)",
        ),
        Term(
            "median half-width",
            float(np.median(half)) / DEG,
            "deg",
            "computed",
            "asin(R / |Vm|) + asin(vl / (|Vm| - R)) at fixes faster than R + vl",
        ),
    ]
    ag.notes.append(
        f"heading from the GNSS course at {int(use.sum())} of {int(ok.sum())} velocity "
        "fixes: assumes the vehicle does not reverse and the lateral velocity bound "
        "(--reverses turns it off)"
    )
